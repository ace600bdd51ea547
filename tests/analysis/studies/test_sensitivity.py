"""Exact sensitivities through IDAS (issue 10, item 6).

Checked against a closed form (the driven slider-crank's slider position), against central
finite differences of the simulation itself (``Simulator.run`` with the parameter moved by
±h, IDAS at rtol 1e-12) to 1e-6 relative, and forward against adjoint mode.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import Mechanism
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.studies.sensitivity import sensitivity
from casmbd.errors import AnalysisError

ROOT = pathlib.Path(__file__).resolve().parents[3]
SLIDER_CRANK = ROOT / "examples" / "slider_crank.toml"
T_CRANK = 0.3


_cache = private_cache("cache_sens")


def parametric_chain() -> Mechanism:
    """Three 1 m rods pinned end to end, released horizontally under gravity; the rod masses
    m0, m1, m2 (inertias m L²/12 follow) and a rotational spring-damper k, c at the middle pin
    are parameters."""
    m = Mechanism("sens_chain", gravity=(0.0, -9.81))
    for name, value in (("m0", 1.0), ("m1", 0.7), ("m2", 1.3), ("k", 20.0), ("c", 0.5)):
        m.add_parameter(name, value)
    prev = "ground"
    for i in range(3):
        m.add_body(f"rod{i}", mass=f"m{i}", inertia=f"m{i} / 12", position=(i + 0.5, 0.0))
        m.add_revolute(f"pin{i}", prev, f"rod{i}", point=(float(i), 0.0))
        prev = f"rod{i}"
    m.add_rotational_spring_damper("spring", "pin1", stiffness="k", damping="c")
    m.add_marker("tip", "rod2", (3.0, 0.0))
    return m


NOMINAL = {"m0": 1.0, "m1": 0.7, "m2": 1.3, "k": 20.0, "c": 0.5}


def slider_x(omega: float, t: float, r: float = 0.1, length: float = 0.3) -> float:
    th = omega * t
    return r * math.cos(th) + math.sqrt(length**2 - (r * math.sin(th)) ** 2)


@pytest.fixture(scope="module")
def crank():
    mech = casmbd.load_scene(SLIDER_CRANK)
    out = ["slider_x", "slider_vx", "integral: crank_speed_effort", "integral: O_Fx"]
    return mech, out, {m: sensitivity(mech, out, ["omega"], T_CRANK, method=m, rtol=1e-12)
                       for m in ("forward", "adjoint")}


def test_slider_crank_against_closed_form(crank):
    """x(T) = r cos ωT + √(l² − r² sin² ωT): value and ∂x/∂ω = T dx/dθ to 1e-9 (measured
    3e-13 and 6e-10 relative; the crank angle is a driver constraint of the DAE)."""
    _, _, res = crank
    omega = 2.0 * math.pi
    h = 1e-6
    exact = (slider_x(omega + h, T_CRANK) - slider_x(omega - h, T_CRANK)) / (2 * h)
    for r in res.values():
        assert r.values[0] == pytest.approx(slider_x(omega, T_CRANK), abs=1e-9)
        assert r.derivative("slider_x", "omega") == pytest.approx(exact, rel=1e-7, abs=1e-9)


def test_slider_crank_integrals_against_finite_differences(crank):
    """∂/∂ω of ∫ driver effort dt and ∫ F_x(O) dt against central differences (h = 1e-4 ω) of
    the simulation's arrays in an independent formulation (KKT ODE, CVODES, rtol = atol =
    1e-12) integrated by Simpson's rule on 2 400 intervals: 1e-6 relative (measured 1e-8)."""
    from scipy.integrate import simpson

    mech, _, res = crank
    sim = Simulator(mech, "kkt_ode")

    def integrals(omega):
        sim.model.set_parameters(omega=omega)
        r = sim.run(T_CRANK, 2400, rtol=1e-12, atol=1e-12)
        return np.array([simpson(r["driver_efforts"][:, 0], x=r.t),
                         simpson(r["joint_reactions"][:, 0, 0], x=r.t)])

    omega, h = 2.0 * math.pi, 2.0 * math.pi * 1e-4
    fd = (integrals(omega + h) - integrals(omega - h)) / (2 * h)
    val = integrals(omega)
    for r in res.values():
        np.testing.assert_allclose(r.values[2:], val, rtol=1e-8)
        np.testing.assert_allclose(r.jacobian[2:, 0], fd, rtol=1e-6)


@pytest.fixture(scope="module")
def chain():
    mech = parametric_chain()
    out = ["tip_x", "tip_y", "rod1_angle", "integral: pin0_Fy", "integral: rod2_vx * rod2_vx"]
    return mech, out, {m: sensitivity(mech, out, None, 1.0, method=m, rtol=1e-12)
                       for m in ("forward", "adjoint")}


def test_chain_against_finite_differences_of_the_simulation(chain):
    """Every output × every parameter (m0, m1, m2, k, c) against central differences of
    ``Simulator.run`` in an independent formulation (the KKT ODE on CVODES, rtol = atol =
    1e-12, h = 1e-4 relative; IDAS's step selection makes differences with h ≤ 1e-5 noisy at
    the 1e-5 level), final values from the result, integrals by Simpson on 2 000 intervals:
    1e-6 relative (measured 2.5e-8).  The sensitivities take the automatic choice (joint
    coordinates, the chain is a tree); the differences are taken in absolute coordinates, also
    independent of it: in joint coordinates the adaptive steps of the ±h runs differ (464, 488,
    535 steps at rtol 1e-12, against 502 for all three in absolute coordinates) and the
    difference quotient of ∫ pin0_Fy dt is off by 2e-6 relative (8e-6 for ∫ vx² dt) — noise
    of the reference, not of the sensitivities (7e-8 at rtol 1e-13)."""
    from scipy.integrate import simpson

    _, _, res = chain
    reference = parametric_chain()
    reference.coordinates = "absolute"
    sim = Simulator(reference, "kkt_ode")
    names = res["forward"].parameters
    nominal = {n: NOMINAL[n] for n in names}

    def outputs(values):
        sim.model.set_parameters(**values)
        r = sim.run(1.0, 2000, rtol=1e-12, atol=1e-12)
        tip = r.marker("tip")["position"][-1]
        vx = r.body("rod2")["velocity"][:, 0]
        return np.array([tip[0], tip[1], r.body("rod1")["angle"][-1],
                         simpson(r["joint_reactions"][:, 0, 1], x=r.t),
                         simpson(vx * vx, x=r.t)])

    base = outputs(nominal)
    for r in res.values():
        np.testing.assert_allclose(r.values, base, rtol=1e-8, atol=1e-10)
    for j, name in enumerate(names):
        h = 1e-4 * nominal[name]
        up = outputs({**nominal, name: nominal[name] + h})
        down = outputs({**nominal, name: nominal[name] - h})
        fd = (up - down) / (2 * h)
        for r in res.values():
            np.testing.assert_allclose(r.jacobian[:, j], fd, rtol=1e-6,
                                       atol=1e-6 * np.max(np.abs(fd)),
                                       err_msg=f"d/d{name} ({r.method})")
    sim.model.set_parameters(**nominal)


def test_forward_and_adjoint_agree(chain):
    """The two IDAS modes solve different equations (forward sensitivity DAE, backward
    adjoint DAE with checkpointing): they agree to 1e-7 relative (measured 1.3e-11)."""
    _, _, res = chain
    fwd, adj = res["forward"].jacobian, res["adjoint"].jacobian
    np.testing.assert_allclose(adj, fwd, rtol=1e-7, atol=1e-9 * np.max(np.abs(fwd)))


def test_mass_scaling_law(chain):
    """Scaling every mass, k and c by s leaves the motion unchanged and scales the forces by s
    (Euler's theorem on homogeneous functions): Σ_j p_j ∂y/∂p_j = 0 for the kinematic outputs
    and = y for the reaction integral, to 1e-8 relative (measured 3e-15 and 2e-13)."""
    _, out, res = chain
    r = res["forward"]
    p = np.array([NOMINAL[n] for n in r.parameters])
    euler = r.jacobian @ p
    scale = np.abs(r.jacobian) @ p
    kinematic = [i for i, o in enumerate(out) if "pin0_Fy" not in o]
    assert np.all(np.abs(euler[kinematic]) <= 1e-8 * scale[kinematic])
    i = out.index("integral: pin0_Fy")
    assert euler[i] == pytest.approx(r.values[i], rel=1e-8)


def test_bad_input_is_named():
    mech = parametric_chain()
    with pytest.raises(AnalysisError, match=r"unknown parameter 'g'.*known: m0, m1"):
        sensitivity(mech, "tip_x", ["g"], 0.1)
    with pytest.raises(AnalysisError, match="method must be one of"):
        sensitivity(mech, "tip_x", ["k"], 0.1, method="reverse")
    with pytest.raises(AnalysisError, match="tipx"):
        sensitivity(mech, "tipx", ["k"], 0.1)
    with pytest.raises(AnalysisError, match="t_end"):
        sensitivity(mech, "tip_x", ["k"], 0.0)
    with pytest.raises(AnalysisError, match="declares no parameters"):
        sensitivity(casmbd.load_scene(ROOT / "examples" / "four_bar.toml"), "t", None, 0.1)


def test_cli_sensitivity_json_and_table(capsys):
    """``casmbd sensitivity``: the JSON holds the value and d/dω of the slider position, equal
    to the closed form to 1e-9; the text table names the output and the parameter."""
    from casmbd import cli

    args = ["sensitivity", str(SLIDER_CRANK), "--output", "slider_x", "--output",
            "integral: crank_speed_effort", "--param", "omega", "--t-end", str(T_CRANK)]
    assert cli.main([*args, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    omega, h = 2.0 * math.pi, 1e-6
    exact = (slider_x(omega + h, T_CRANK) - slider_x(omega - h, T_CRANK)) / (2 * h)
    assert data["method"] == "forward" and data["parameters"] == ["omega"]
    assert data["outputs"]["slider_x"]["derivatives"]["omega"] == pytest.approx(exact,
                                                                                   rel=1e-7)
    assert cli.main([*args, "--method", "adjoint", "--verbose"]) == 0
    text = capsys.readouterr().out
    assert "d/domega" in text and "slider_x" in text and "adjoint" in text
    assert "statistics:" in text and "solve_seconds" in text
    assert cli.main(["sensitivity", str(SLIDER_CRANK), "--output", "slider_x", "--param",
                     "speed", "--t-end", "0.1"]) == cli.EXIT_ERROR
    err = capsys.readouterr().err
    assert "unknown parameter 'speed'" in err and "omega" in err


def test_redundant_constraints_against_finite_differences():
    """Bricard's mechanism (one redundant constraint equation: the DAE keeps the independent
    rows) used to end in a bare CasADi dimension error (the start's multipliers had every
    row); ∂(rod1 x at 0.1 s)/∂a = 1.9225e-6 against central differences (h = 1e-3 a) of
    ``Simulator.run`` (KKT ODE, CVODES, rtol = atol = 1e-12): 1e-4 relative (measured 7e-8;
    the difference quotient itself carries ~1e-12 of rounding at h = 1e-4 a)."""
    path = pathlib.Path(__file__).resolve().parents[3] / "examples" / "bricard.toml"
    mech = casmbd.load_scene(path)
    res = sensitivity(mech, ["rod1_x"], ["a"], 0.1, rtol=1e-12)
    sim = Simulator(casmbd.load_scene(path), "kkt_ode")
    a = float(mech.parameters["a"])

    def x_end(value: float) -> float:
        sim.model.set_parameters(a=value)
        return float(sim.run(0.1, 10, rtol=1e-12, atol=1e-12).body("rod1")["position"][-1, 0])

    h = 1e-3 * a
    fd = (x_end(a + h) - x_end(a - h)) / (2 * h)
    assert abs(fd) > 1e-7  # a sensitivity to compare, not rounding
    assert res.values[0] == pytest.approx(x_end(a), abs=1e-9)
    assert res.jacobian[0, 0] == pytest.approx(fd, rel=1e-4)
