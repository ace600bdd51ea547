"""Forward dynamics: closed forms, conservation laws and agreement between formulations."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from conftest import private_cache
from scipy.special import ellipk

import casmbd
from casmbd.analysis.dynamics.simulate import Simulator, simulate
from casmbd.errors import AnalysisError, IntegratorError

G = 9.81


_cache = private_cache("cache_dynamics", scope="module")


def pendulum(length: float = 1.0, mass: float = 1.0) -> casmbd.Mechanism:
    """Slender rod pinned at one end to the ground, released horizontally."""
    m = casmbd.Mechanism("pendulum", gravity=(0.0, -G))
    m.add_body("rod", mass, mass * length**2 / 12, (length / 2, 0.0))
    m.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
    return m


def double_pendulum() -> casmbd.Mechanism:
    return casmbd.load_scene("examples/double_pendulum.toml")


def physical_pendulum_period(length: float = 1.0) -> float:
    """T = 4 sqrt(l_eq / g) K(k²=1/2) for release from the horizontal, l_eq = 2L/3."""
    return 4.0 * np.sqrt((2.0 * length / 3.0) / G) * ellipk(0.5)


def _crossing_time(t, angle):
    """Time at which the angle comes back up through 0 (the end of the first period)."""
    k = np.flatnonzero((angle[:-1] < 0.0) & (angle[1:] >= 0.0))[-1]
    # cubic Hermite would need rates; a secant on a fine grid around the root is enough here
    return t[k] - angle[k] * (t[k + 1] - t[k]) / (angle[k + 1] - angle[k])


CASES = [("index1", "idas"), ("kkt_ode", "adams"), ("kkt_ode", "cvodes"),
         ("augmented_lagrangian", "adams"), ("kkt_ode", "rk4"), ("kkt_ode", "abm"),
         ("partitioning", "adams"), ("nullspace", "adams")]


@pytest.mark.parametrize(("formulation", "integrator"), CASES)
def test_pendulum_period_elliptic_integral(formulation, integrator):
    """Released horizontally, the rod passes the bottom at T/4 and 3T/4, T = 4 sqrt(l/g) K.

    At the bottom the angular velocity is largest (ω² = 3g/L), so the angle error there turns
    into a time error δt = δθ / ω; the period must hold to 1e-8 relative.
    """
    period = physical_pendulum_period()
    sim = Simulator(pendulum(), formulation)
    res = sim.run(period, 4, integrator=integrator, rtol=1e-12, atol=1e-12,
                  step=period / 8000)
    angle = res.body("rod")["angle"]
    omega_bottom = np.sqrt(3 * G / 1.0)
    for k in (1, 3):
        time_error = abs(angle[k] + np.pi / 2) / omega_bottom
        assert time_error / period <= 1e-8, (k, time_error)
    assert abs(res.body("rod")["angular_velocity"][-1]) <= 1e-7


def four_bar_undriven() -> casmbd.Mechanism:
    """The crank-rocker example without its driver: a conservative one-DOF loop."""
    m = casmbd.load_scene("examples/four_bar.toml")
    m.drivers.clear()
    m.bodies["crank"].angular_velocity = 3.0
    return m


@pytest.mark.parametrize("scene", ["pendulum", "four_bar"])
def test_energy_drift_conservative(scene):
    """Default formulation, 10 s at rtol 1e-10 (atol 1e-12): energy drift <= 1e-8 relative.

    The scale is the larger of |E(0)| and the largest kinetic energy.  (The drift of every
    formulation is tabulated in docs/performance.md.)
    """
    mech = pendulum() if scene == "pendulum" else four_bar_undriven()
    res = simulate(mech, 10.0, 200, rtol=1e-10, atol=1e-12)
    energy = res["total_energy"]
    scale = max(abs(energy[0]), np.max(res["kinetic_energy"]))
    assert np.max(np.abs(energy - energy[0])) / scale <= 1e-8


def test_energy_drift_chaotic_double_pendulum():
    """The chaotic double pendulum drifts more: <= 1e-7 of m g L over 10 s at 1e-10."""
    res = simulate(double_pendulum(), 10.0, 200, formulation="kkt_ode", rtol=1e-10,
                   atol=1e-10)
    energy = res["total_energy"]
    assert np.max(np.abs(energy - energy[0])) / (2 * G) <= 1e-7


@pytest.mark.parametrize("coordinates, bound", [("absolute", 1e-10), ("auto", 3e-10)])
def test_free_two_rods_conserve_momentum(coordinates, bound):
    """Two rods joined by a frictionless pin move freely (seed 003, §5.1): P and H constant.

    Measured drifts over 5 s at rtol 1e-12 (kkt_ode, adams): absolute coordinates P 7.8e-16
    (a linear invariant of the coordinates, kept exactly by the multistep method), H 8.7e-11;
    the automatic choice (joint coordinates: a free planar base and the pin angle, in which P
    and H are nonlinear) P 1.1e-10, H 1.2e-10 — the integration error, hence its bound 3e-10."""
    m = casmbd.Mechanism("two_rods", coordinates=coordinates)
    m.add_body("a", 1.0, 1 / 12, (0.5, 0.0), velocity=(0.3, -0.2), angular_velocity=2.0)
    m.add_body("b", 2.0, 2 * 0.25 / 12, (1.25, 0.0), angle=0.0, velocity=(-0.1, 0.4),
               angular_velocity=-1.0)
    m.add_revolute("pin", "a", "b", (1.0, 0.0))
    res = simulate(m, 5.0, 100, formulation="kkt_ode", rtol=1e-12, atol=1e-12)
    masses = np.array([1.0, 2.0])
    inertias = np.array([1 / 12, 2 * 0.25 / 12])
    pos = res["body_positions"].reshape(len(res.t), 2, 2)
    vel = res["body_velocities"].reshape(len(res.t), 2, 2)
    omega = res["angle_velocities"]
    momentum = np.einsum("b,tbi->ti", masses, vel)
    ang = (np.einsum("b,tb->t", masses, pos[:, :, 0] * vel[:, :, 1] - pos[:, :, 1] * vel[:, :, 0])
           + omega @ inertias)
    assert np.max(np.abs(momentum - momentum[0])) <= bound
    assert np.max(np.abs(ang - ang[0])) <= bound


def test_hanging_pendulum_reaction_equals_weight():
    """At rest hanging down the pin carries m g upwards, no moment: 1e-10."""
    m = casmbd.Mechanism("hanging", gravity=(0.0, -G))
    m.add_body("rod", 2.5, 2.5 / 12, (0.0, -0.5), angle=-np.pi / 2)
    m.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
    res = simulate(m, 1.0, 10, rtol=1e-10)
    reaction = res["joint_reactions"][:, 0, :]
    assert np.max(np.abs(reaction[:, 0])) <= 1e-10
    assert np.max(np.abs(reaction[:, 1] - 2.5 * G)) <= 1e-10
    assert np.max(np.abs(reaction[:, 2])) <= 1e-10


def test_formulations_agree_on_double_pendulum():
    """Every formulation reproduces the same motion at tight tolerance (1e-7)."""
    ref = simulate(double_pendulum(), 2.0, 20, formulation="kkt_ode", integrator="adams",
                   rtol=1e-12, atol=1e-12)
    for formulation, integrator in [("index1", "idas"), ("augmented_lagrangian", "adams"),
                                    ("kkt_ode", "cvodes"), ("kkt_ode", "rk4")]:
        res = simulate(double_pendulum(), 2.0, 20, formulation=formulation,
                       integrator=integrator, rtol=1e-11, atol=1e-11, step=1e-4)
        assert np.max(np.abs(res["q"] - ref["q"])) <= 1e-7, formulation


def test_driver_effort_of_driven_crank_matches_inverse_balance():
    """A rod driven at constant speed in gravity: effort = m g (L/2) cos θ (no inertia)."""
    m = casmbd.Mechanism("driven", gravity=(0.0, -G))
    m.add_body("rod", 1.5, 1.5 / 12, (0.5, 0.0))
    m.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
    m.add_driver("motor", "2*t", joint="pivot")
    res = simulate(m, 1.0, 20, rtol=1e-10)
    theta = 2.0 * res.t
    assert np.max(np.abs(res["driver_efforts"][:, 0] - 1.5 * G * 0.5 * np.cos(theta))) < 1e-8


def test_consistent_start_projects_velocities():
    """An inconsistent initial velocity is projected (mass-orthogonally) and reported
    (absolute coordinates: the start changes v).  The automatic choice (joint coordinates)
    maps the body velocity onto the pivot rate by the same kinetic-energy metric: the same
    start, ω = (m L/2 · 1) / (m L²/4 + J) = 1.5 rad/s, ṙ_G = (0, 0.75) (it used to be the
    unweighted least squares, 0.4 rad/s)."""
    m = pendulum()
    m.coordinates = "absolute"
    m.bodies["rod"].velocity = np.array([1.0, 1.0])  # not tangent to the circle
    res = simulate(m, 0.1, 2, rtol=1e-10)
    assert res.stats["start_velocity_change"] > 0.1
    assert res["velocity_violation"][0] < 1e-12
    m.coordinates = "auto"
    auto = simulate(m, 0.1, 2, rtol=1e-10)
    for r in (res, auto):
        assert abs(r.body("rod")["angular_velocity"][0] - 1.5) <= 1e-12
        np.testing.assert_allclose(r.body("rod")["velocity"][0], [0.0, 0.75], rtol=0,
                                   atol=1e-12)


def test_incompatible_start_velocity_is_the_same_in_both_choices_in_space():
    """The heavy top (a spherical joint) given a centre velocity and an angular velocity the
    joint does not allow: joint coordinates (kinetic-energy least squares) start with the same
    body velocities as absolute ones (mass-orthogonal projection) to 1e-9 (measured equal to
    the printed digits: ṙ_G = (0.5222, -0.0568, -0.0176), ω = (0.595, -3.306, 28.36))."""
    starts = {}
    for coordinates in ("absolute", "joint"):
        m = casmbd.load_scene("examples/heavy_top.toml")
        m.coordinates, m.name = coordinates, f"top_start_{coordinates}"
        body = next(iter(m.bodies.values()))
        body.velocity = np.array([0.3, -0.2, 0.5])
        body.angular_velocity = np.array([1.0, 2.0, 30.0])
        res = simulate(m, 0.01, 1, rtol=1e-10, mode="vm")
        starts[coordinates] = np.concatenate([res.body(body.name)["velocity"][0],
                                              res.body(body.name)["angular_velocity"][0]])
    assert np.max(np.abs(starts["absolute"][:3] - [0.3, -0.2, 0.5])) > 0.1  # it was changed
    np.testing.assert_allclose(starts["joint"], starts["absolute"], rtol=0, atol=1e-9)


def test_integrator_failure_keeps_partial_results(tmp_path):
    res = None
    with pytest.raises(IntegratorError) as info:
        simulate(double_pendulum(), 5.0, 50, formulation="kkt_ode", integrator="adams",
                 rtol=1e-10, max_steps=60)
    err = info.value
    assert err.flag == "CV_TOO_MUCH_WORK"
    assert 0.0 < err.time < 5.0
    assert "t = " in str(err)
    res = err.partial
    assert res is not None and 1 <= len(res.t) < 51
    # the time is SUNDIALS' own ("At t = …, mxstep steps taken"), captured also when
    # sys.stderr is replaced (as here, under pytest): strictly inside the next interval
    assert res.t[-1] < err.time < res.t[-1] + 0.1
    assert f"At t = {err.time:g}"[:12] in str(err) or "mxstep" in str(err)
    path = res.save(tmp_path / "partial.npz")
    assert np.array_equal(casmbd.load(path)["q"], res["q"])


def test_bad_options_raise():
    with pytest.raises(AnalysisError, match="integrator 'rk4'"):
        simulate(pendulum(), 1.0, 2, formulation="index1", integrator="rk4")
    with pytest.raises(AnalysisError, match="formulation 'magic'"):
        simulate(pendulum(), 1.0, 2, formulation="magic")
    with pytest.raises(AnalysisError, match="rtol"):
        simulate(pendulum(), 1.0, 2, rtol=-1.0)
    with pytest.raises(AnalysisError, match="unknown actuator 'nope'"):
        simulate(pendulum(), 1.0, 2, inputs={"nope": 1.0})


def test_actuator_input_expression():
    """A constant torque T on a free rotor: θ = T t² / (2 I) (1e-9)."""
    m = casmbd.Mechanism("rotor")
    m.add_body("disc", 1.0, 0.5, (0.0, 0.0))
    m.add_revolute("axle", "ground", "disc", (0.0, 0.0))
    m.add_actuator("motor", "axle")
    res = simulate(m, 1.0, 10, inputs={"motor": "0.25"}, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(res.body("disc")["angle"] - 0.25 * res.t**2 / (2 * 0.5))) < 1e-9


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10])
def test_parallelogram_stays_on_branch_default_formulation(rtol):
    """Unit parallelogram, 10 s: ten collinear (singular) passes, the coupler never rotates.

    On the anti-parallelogram branch the coupler angle and crank − rocker are O(1) radians, so
    1e-3 separates the branches with a wide margin at every tolerance.
    """
    res = simulate(casmbd.load_scene("examples/parallelogram.toml"), 10.0, 1000, rtol=rtol)
    crank = res.body("crank")["angle"]
    rocker = res.body("rocker")["angle"]
    coupler = res.body("coupler")["angle"]
    passes = np.count_nonzero(np.diff(np.floor(crank / np.pi)) != 0)
    assert passes == 10
    assert np.max(np.abs(coupler)) <= 1e-3
    assert np.max(np.abs(crank - rocker)) <= 1e-3


def test_ggl_pendulum_period():
    """The GGL index-2 DAE on IDAS also gives the elliptic-integral period (at rtol 1e-10;
    tighter tolerances fail inside IDAS, see docs/dynamics.md)."""
    period = physical_pendulum_period()
    res = Simulator(pendulum(), "ggl").run(period, 4, rtol=1e-10, atol=1e-10)
    angle = res.body("rod")["angle"]
    for k in (1, 3):
        assert abs(angle[k] + np.pi / 2) / np.sqrt(3 * G) / period <= 1e-8


@pytest.mark.parametrize(("formulation", "integrator", "rtol", "bound"), [
    ("augmented_lagrangian", "adams", 1e-11, 1e-8),
    ("kkt_ode", "adams", 1e-11, 1e-7),
    ("index1", "idas", 1e-11, 1e-7),
    ("kkt_ode", "rk4", 1e-8, 1e-8),
])
def test_chain8_tip_matches_minimal_coordinate_reference(formulation, integrator, rtol, bound):
    """8-rod chain, tip at t = 2 s against the independent Lagrange reference (1e-13)."""
    from benchmarks.chains import pendulum_chain
    from benchmarks.references import load_reference

    tip_ref = np.array(load_reference("pendulum_chain_n8")["results"]["tip_position"])
    res = simulate(pendulum_chain(8), 2.0, 4, formulation=formulation, integrator=integrator,
                   rtol=rtol, atol=rtol, step=2.5e-4)
    assert np.linalg.norm(res.marker("tip")["position"][-1] - tip_ref) <= bound


def test_parallelogram_crank_angle_matches_closed_form():
    """Default formulation at rtol 1e-12: crank angle at t = 10 s within 1e-7 of the
    elliptic-integral solution on the parallelogram branch."""
    from benchmarks.references import load_reference

    phi_ref = load_reference("parallelogram_four_bar")["results"]["phi_end"]
    res = simulate(casmbd.load_scene("examples/parallelogram.toml"), 10.0, 10, rtol=1e-12,
                   atol=1e-12)
    assert abs(res.body("crank")["angle"][-1] - phi_ref) <= 1e-7


def test_fixed_step_blow_up_is_reported_with_partial_results():
    """ABM with a far too large step on the parallelogram diverges: NON_FINITE, outputs kept."""
    with pytest.raises(IntegratorError) as info:
        simulate(casmbd.load_scene("examples/parallelogram.toml"), 10.0, 100,
                 formulation="kkt_ode", integrator="abm", step=0.01)
    err = info.value
    assert err.flag == "NON_FINITE"
    assert err.partial is not None and len(err.partial.t) >= 2
    assert err.partial.t[-1] < err.time <= 10.0
    assert np.all(np.isfinite(err.partial["q"]))


def test_failure_at_the_start_keeps_the_initial_state():
    """GGL on IDAS at rtol 1e-12 fails at t = 0 (IDA_CONV_FAIL, h → 1e-19) on the 2-rod chain:
    the error names t = 0, keeps the one initial output and advises index1 or a looser
    tolerance.  Run in a subprocess: re-running
    the integrator on an empty output grid had crashed the interpreter (segmentation fault)."""
    import subprocess
    import sys

    code = ("import sys; sys.path.insert(0, '.')\n"
            "from benchmarks.work_precision import problem\n"
            "from casmbd.analysis.dynamics.simulate import Simulator\n"
            "from casmbd.errors import IntegratorError\n"
            "mech, t_end, _, _ = problem('chain2', 'absolute')\n"
            "try:\n"
            "    Simulator(mech, 'ggl').run(t_end, 1, integrator='idas', rtol=1e-12, "
            "atol=1e-12)\n"
            "except IntegratorError as e:\n"
            "    print(\"'index1'\" in str(e), e.flag, e.time, len(e.partial.t))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600, cwd=str(pathlib.Path(__file__).resolve().parents[3]))
    assert proc.returncode == 0, proc.stderr[-500:]
    hint, flag, when, kept = proc.stdout.split()[-4:]
    assert flag == "IDA_CONV_FAIL" and float(when) == 0.0 and kept == "1"
    assert hint == "True"  # the message points to index1 (GGL's corrector limit)
