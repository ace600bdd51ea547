"""The commands of docs/tutorial.md on the overhead crane (examples/crane.toml,
ocp/crane_transfer.toml), run in-process through ``casmbd.cli.main`` and checked against
closed forms, balance laws and finite differences.

The crane: cart M = 5 kg on a rail, load m = 2 kg (inertia I = m (0.1² + 0.1²)/12 about its
centre of mass) on a rigid massless rope L = 0.5 m, hinge damping c = 0.05 N m s/rad.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import pathlib

import numpy as np
import pytest
from scipy.integrate import simpson

import casmbd
from casmbd import cli
from casmbd.ocp import Ocp

ROOT = pathlib.Path(__file__).resolve().parents[2]
CRANE = str(ROOT / "examples" / "crane.toml")
TRANSFER = str(ROOT / "ocp" / "crane_transfer.toml")
M_CART, M_LOAD, C_HINGE, L, G = 5.0, 2.0, 0.05, 0.5, 9.81
I_LOAD = M_LOAD * (0.1**2 + 0.1**2) / 12
HANGING = [0, 0, 0, 0, -L, 0]  # cart.x, cart.y, cart.angle, load.x, load.y, load.angle


def run(*argv: str) -> dict:
    """``casmbd ARGV --json`` in-process: exit status 0 and the parsed JSON object."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = cli.main([*argv, "--json"])
    assert status == 0, (argv, out.getvalue()[-2000:])
    return json.loads(out.getvalue())


def tutorial_commands() -> list[list[str]]:
    """The ``$ casmbd …`` command lines of docs/tutorial.md (continuation lines joined)."""
    import shlex

    text = (ROOT / "docs" / "tutorial.md").read_text().replace("\\\n", " ")
    return [shlex.split(line[2:]) for line in text.splitlines() if line.startswith("$ casmbd")]


def test_tutorial_writes_only_into_the_ignored_out_folder():
    """Every file the tutorial's commands (and its Python) write or read back lies under
    ``out/``, which .gitignore ignores: nothing lands in the repository root."""
    commands = tutorial_commands()
    outs = [argv[argv.index("--out") + 1] for argv in commands if "--out" in argv]
    assert len(outs) >= 4, outs  # simulate, plot, animate, sweep
    assert all(path.startswith("out/") for path in outs), outs
    read = [a for argv in commands for a in argv[1:] if a.endswith((".npz", ".gif", ".png"))]
    assert all(path.startswith("out/") for path in read), read
    text = (ROOT / "docs" / "tutorial.md").read_text()
    assert 'load_result("out/crane.npz")' in text
    assert "out/" in (ROOT / ".gitignore").read_text().split()


def test_scene_info():
    """Step 1: 6 absolute coordinates (the scene pins them), 4 joint equations of full rank,
    2 degrees of freedom; left to the automatic choice, the tree's 2 joint coordinates."""
    info = run("info", CRANE)
    assert info["degrees_of_freedom"] == 2
    assert (info["n_coordinates"], info["n_constraints"], info["rank"]) == (6, 4, 4)
    assert info["coordinate_choice"] == "absolute" and info["coordinate_reason"] == "given"
    crane = casmbd.load_scene(CRANE)
    crane.coordinates = "auto"
    auto = casmbd.info(crane, mode="vm")
    assert auto["coordinates"] == ["rail.translation", "hinge.angle"]
    assert (auto["n_constraints"], auto["degrees_of_freedom"]) == (0, 2)
    assert info["redundant_equations"] == []
    assert info["parameters"] == {"m_cart": M_CART, "m_load": M_LOAD, "c_hinge": C_HINGE}


def test_simulate_plot_animate(tmp_path):
    """Step 2.  Two balance laws of the free swing from 0.3 rad, measured on the saved result:
    * no horizontal external force, so the horizontal centre of mass
      (M x_cart + m x_load)/(M + m) stays at its start, m L sin 0.3 /(M + m) (measured 1e-12 m,
      bound 1e-8 m at rtol 1e-8);
    * the energy lost equals the work of the hinge damper, E(0) − E(T) = ∫ c θ̇² dt, the
      integral by Simpson's rule on the 251 output times (measured 2e-7 relative, bound 1e-5).
    """
    npz = tmp_path / "crane.npz"
    run("simulate", CRANE, "--t-end", "5", "--steps", "250", "--out", str(npz))
    res = casmbd.load_result(npz)
    x_cart = res.body("cart")["position"][:, 0]
    x_load = res.body("load")["position"][:, 0]
    com = (M_CART * x_cart + M_LOAD * x_load) / (M_CART + M_LOAD)
    assert np.max(np.abs(com - M_LOAD * L * math.sin(0.3) / (M_CART + M_LOAD))) < 1e-8
    energy = res["total_energy"]
    dissipated = simpson(C_HINGE * res["joint_velocities"][:, 1] ** 2, x=res.t)
    assert energy[0] - energy[-1] == pytest.approx(dissipated, rel=1e-5)
    assert energy[0] == pytest.approx(-M_LOAD * G * L * math.cos(0.3), rel=1e-12)
    png, gif = tmp_path / "crane.png", tmp_path / "crane.gif"
    assert run("plot", str(npz), "--kind", "joints", "--kind", "energy", "--out", str(png),
               "--dpi", "40")["kinds"] == ["joints", "energy"]
    assert run("animate", str(npz), "--trace", "hook", "--max-frames", "4", "--dpi", "30",
               "--out", str(gif))["frames"] == 4
    assert png.stat().st_size > 0 and gif.stat().st_size > 0


def test_linearized_frequency_against_closed_form():
    """Step 3.  About the hanging rest state, with the cart free: eliminating the cart by the
    conservation of horizontal momentum leaves J θ̈ + c θ̇ + m g L θ = 0 with
    J = I + m L² M/(M + m), so ω_n² = m g L / J (for I = 0: g (M + m)/(M L)) and
    ζ = c / (2 √(J m g L)).  Bound 1e-9 relative (measured 2e-16 and 3e-15)."""
    lin = casmbd.linearize(casmbd.load_scene(CRANE), q=HANGING)
    assert lin.n_dof == 2 and lin.stable
    inertia = I_LOAD + M_LOAD * L**2 * M_CART / (M_CART + M_LOAD)
    omega = math.sqrt(M_LOAD * G * L / inertia)
    zeta = C_HINGE / (2 * math.sqrt(inertia * M_LOAD * G * L))
    assert lin.natural_frequencies_hz[0] < 1e-6  # the cart's free translation
    assert lin.natural_frequencies_hz[1] == pytest.approx(omega / (2 * math.pi), rel=1e-9)
    assert lin.damping_ratios[1] == pytest.approx(zeta, rel=1e-9)
    assert lin.frequencies_hz[1] == pytest.approx(
        omega * math.sqrt(1 - zeta**2) / (2 * math.pi), rel=1e-9)


def test_driven_cart_force():
    """Step 4: the cart driven along x = 10 s³ − 15 s⁴ + 6 s⁵, s = min(t/2, 1), the load free.
    One degree of freedom remains; the cart ends at 1 m; the driver effort is the only
    horizontal external force, so it equals M ẍ_cart + m ẍ_load at every output time (bound
    1e-9 N, measured 2e-15 N: a wrong sign, unit or row of the effort fails it)."""
    crane = casmbd.load_scene(CRANE)
    s = "min(t / 2, 1)"
    crane.add_driver("move", joint="rail", position=f"10*{s}**3 - 15*{s}**4 + 6*{s}**5")
    assert casmbd.info(crane)["degrees_of_freedom"] == 1
    res = casmbd.Simulator(crane).run(t_end=4.0, steps=400, q0=HANGING)
    assert res["joint_positions"][-1, 0] == pytest.approx(1.0, abs=1e-9)
    force = res["driver_efforts"][:, 0]
    a_cart = res.body("cart")["acceleration"][:, 0]
    a_load = res.body("load")["acceleration"][:, 0]
    assert np.max(np.abs(force - (M_CART * a_cart + M_LOAD * a_load))) < 1e-9
    assert np.max(np.abs(force)) > 10.0  # the load's swing adds to (M + m) ẍ ≤ 10.1 N


def test_sensitivity_against_finite_differences():
    """Step 5: ∂(hinge at 2 s)/∂p and ∂(∫ hinge_Fy dt)/∂p for p = m_cart, m_load, c_hinge
    against central differences (h = 1e-4 p) of an independent simulation: the KKT ODE on
    fixed-step RK4 (h = 1 ms, so that the difference is free of step-selection noise), the
    integral by Simpson's rule on 2 000 intervals.  Values to 1e-8, derivatives to 1e-6
    relative (measured 1.7e-7)."""
    data = run("sensitivity", CRANE, "--output", "hinge", "--output", "integral: hinge_Fy",
               "--t-end", "2")
    assert data["parameters"] == ["m_cart", "m_load", "c_hinge"]
    outs = data["outputs"]
    values = np.array([outs["hinge"]["value"], outs["integral: hinge_Fy"]["value"]])
    sim = casmbd.Simulator(casmbd.load_scene(CRANE), "kkt_ode")
    nominal = {"m_cart": M_CART, "m_load": M_LOAD, "c_hinge": C_HINGE}

    def outputs(params):
        sim.model.set_parameters(**params)
        r = sim.run(2.0, 2000, integrator="rk4", step=1e-3)
        return np.array([r["joint_positions"][-1, 1],
                         simpson(r["joint_reactions"][:, 1, 1], x=r.t)])

    np.testing.assert_allclose(outputs(nominal), values, rtol=1e-8)
    for name, p in nominal.items():
        h = 1e-4 * p
        fd = (outputs({**nominal, name: p + h}) - outputs({**nominal, name: p - h})) / (2 * h)
        exact = [outs["hinge"]["derivatives"][name],
                 outs["integral: hinge_Fy"]["derivatives"][name]]
        np.testing.assert_allclose(exact, fd, rtol=1e-6, err_msg=f"d/d{name}")


def test_damping_sweep(tmp_path):
    """Step 6: five dampings, every point ok; the undamped point keeps its energy (drift
    2e-7 J of 9.4 J at the default rtol 1e-8, bound 1e-5 J); every point's energy loss is its
    damper's work ∫ c θ̇² dt (Simpson on the point's saved result) to 1e-5 J, about 1e-6 of
    |E(0)| = 9.4 J (measured 4.3e-6 J, the integrator's error at rtol 1e-8: 2e-9 J at
    rtol 1e-11), and grows with c."""
    data = run("sweep", CRANE, "--param", "c_hinge=0:0.2:5", "--t-end", "5", "--steps", "250",
               "--output", "energy_drift", "--output", "min:joint_positions[hinge]",
               "--out", str(tmp_path / "sweep"))
    points = data["points"]
    assert data["failed"] == 0 and len(points) == 5
    assert all(p["status"] == "ok" for p in points)
    drift = [p["outputs"]["energy_drift"] for p in points]
    assert abs(drift[0]) < 1e-5
    assert np.all(np.diff(drift) < 0)
    for p in points[1:]:
        res = casmbd.load_result(p["file"])
        c = p["parameters"]["c_hinge"]
        work = simpson(c * res["joint_velocities"][:, 1] ** 2, x=res.t)
        assert -p["outputs"]["energy_drift"] == pytest.approx(work, abs=1e-5)


@pytest.fixture(scope="module")
def transfer():
    """Step 7 in Python: the problem of ocp/crane_transfer.toml built with casmbd.ocp.Ocp."""
    ocp = Ocp(casmbd.load_scene(TRANSFER), horizon=2.0, intervals=50)
    ocp.control_bounds("force", -9.0, 9.0)
    ocp.initial(rail=0, hinge=0, rail_dot=0, hinge_dot=0)
    ocp.final(rail=1, hinge=0, rail_dot=0, hinge_dot=0)
    ocp.path("hinge", lower=-0.2, upper=0.2)
    ocp.minimize("effort")
    sol = ocp.solve()
    return sol, sol.replay()


def test_anti_sway_transfer(transfer, tmp_path):
    """Step 7: the optimum meets the final conditions (rail 1 m, hinge 0, both at rest) to
    1e-6 at the last node and in the forward replay of its controls (replay error ≤ 1e-4,
    measured 1.3e-8); the swing and force bounds hold (both are reached); the command line
    solves the same problem to the same objective (1e-8 relative)."""
    sol, replay = transfer
    assert sol.success
    for name, target in (("rail", 1.0), ("hinge", 0.0), ("rail_dot", 0.0), ("hinge_dot", 0.0)):
        assert sol.value(name)[-1] == pytest.approx(target, abs=1e-6), name
    assert sol.stats["replay_error"] <= 1e-4
    np.testing.assert_allclose(replay["joint_positions"][-1], [1.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(replay["joint_velocities"][-1], [0.0, 0.0], atol=1e-6)
    hinge, force = sol.value("hinge"), sol.control("force")
    assert np.max(np.abs(hinge)) <= 0.2 + 1e-6 and np.max(np.abs(force)) <= 9.0 + 1e-6
    assert np.max(np.abs(hinge)) > 0.2 - 1e-4 and np.max(np.abs(force)) > 9.0 - 1e-4

    data = run("ocp", TRANSFER, "--out", str(tmp_path / "transfer.npz"))
    assert data["success"] and data["replay_error"] <= 1e-4
    assert data["constraint_violation"] < 1e-6
    assert data["objective"] == pytest.approx(sol.objective, rel=1e-8)
    assert data["coordinates"]["rail.translation"][-1] == pytest.approx(1.0, abs=1e-6)
    assert (tmp_path / "transfer.npz").exists()
