"""Sensitivities across impacts (issue 30, item 2): the jump of the sensitivity at an event.

The forward sensitivity of an event-driven run is propagated phase by phase with the
saltation jump at each impact (casmbd.analysis.studies.sensitivity_events) and checked against

* central finite differences of whole event-driven ``simulate`` runs (rtol 1e-12, step 1e-5:
  truncation ~1e-10, noise ~1e-12/1e-5 = 1e-7 absolute) — agreement to 1e-6 relative;
* the closed form of a ball pushed onto the floor by F under gravity: a = g + F/m,
  t₁ = sqrt(2 h0 / a), y(t) = r + e a t₁ (t − t₁) − a (t − t₁)²/2 between the first two
  impacts (its derivatives by central differences of the formula, 1e-7 relative;
  ∂y/∂e = a t₁ (t − t₁) exactly, 1e-9 relative);
* ∫ v_y dt = y(t_end) − y(0): the integral of a velocity that jumps at the impact, whose
  derivative needs the boundary term (h⁻ − h⁺) dt_e/dp (1e-7 relative).

The cases the jump does not cover are refused by name: a gap that closes (the ball at rest),
stick-slip friction, friction at an impact, the adjoint method, a load-time parameter.
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.studies.sensitivity import sensitivity
from casmbd.errors import AnalysisError
from casmbd.io.scene import loads_scene
from casmbd.io.scene_points import scene_with

REPO = pathlib.Path(__file__).resolve().parents[3]
BALL = REPO / "examples" / "bouncing_ball.toml"
STOPS = REPO / "examples" / "pendulum_stops.toml"

cache = private_cache("casmbd_cache_sensitivity_events", scope="module", autouse=True,
                      CASMBD_COMPILE=None)

#: the ball pushed down by a parameter force F (F = 5 N: impacts at 0.367 s and 0.955 s)
PUSHED_BALL = BALL.read_text().replace("[[contacts]]", """[[forces]]
name = "push"
type = "force"
body = "ball"
value = [0.0, "-F"]

[[contacts]]""").replace("h0 = 1.0 ", "F = 5.0\nh0 = 1.0 ")
#: the pendulum with a damper of rate c at its pin (one impact on the stop at 0.390 s)
DAMPED_STOPS = (STOPS.read_text() + """
[[forces]]
name = "damper"
type = "rotational_spring_damper"
joint = "pin"
damping = "c"
""").replace("m = 1.0\n", "m = 1.0\nc = 0.2\n", 1)


#: the restitution coefficients and the stop as parameters (evaluated at run time)
BALL_E = PUSHED_BALL.replace("restitution = 0.8", 'restitution = "eps"').replace(
    "F = 5.0\n", "F = 5.0\neps = 0.8\n")
STOPS_E = DAMPED_STOPS.replace("lower = -1.0 ", 'lower = "stop"').replace(
    "restitution = 0.5 ", 'restitution = "eps"').replace("c = 0.2\n",
                                                         "c = 0.2\neps = 0.5\nstop = -1.0\n")


#: the ball resting on the floor at the start, lifted by an upward force k t: it leaves the
#: floor at t_d = m g / k and rises, y(t) = r + k (t − t_d)³ / (6 m)
LIFTED_BALL = PUSHED_BALL.replace('value = [0.0, "-F"]', 'value = [0.0, "k * t"]').replace(
    "F = 5.0\n", "k = 20.0\n").replace('position = [0.0, "h0 + r"]', 'position = [0.0, "r"]'
                                          ).replace('point = [0.0, "h0 + r"]', 'point = [0.0, "r"]')


def _central(text: str, name: str, column: int, t_end: float, h: float = 1e-5) -> float:
    """∂q_column(t_end)/∂name by central differences of whole event-driven runs."""
    value = float(loads_scene(text).parameters[name])
    ends = []
    for sign in (1.0, -1.0):
        mech = loads_scene(scene_with(text, {name: value + sign * h}, "fd.toml"))
        ends.append(simulate(mech, t_end, 100, rtol=1e-12, atol=1e-12).arrays["q"][-1, column])
    return (ends[0] - ends[1]) / (2.0 * h)


def _pushed_y(m: float, f: float, t: float, h0: float = 1.0, r: float = 0.1,
              e: float = 0.8) -> float:
    a = 9.81 + f / m
    t1 = math.sqrt(2.0 * h0 / a)
    return r + e * a * t1 * (t - t1) - 0.5 * a * (t - t1) ** 2


def test_ball_across_two_impacts_matches_finite_differences_of_whole_runs():
    """∂y(1 s)/∂(m, F) across the two impacts at 0.367 s and 0.955 s: the derivatives
    −0.4766 and 0.09532 agree with central differences of simulate to 1e-6 relative."""
    mech = loads_scene(PUSHED_BALL)
    res = sensitivity(mech, ["ball_y"], ["m", "F"], 1.0, rtol=1e-12)
    assert [e["kind"] for e in res.stats["events"]] == ["impact", "impact"]
    assert res.stats["event_driven"] is True
    for j, name in enumerate(("m", "F")):
        fd = _central(PUSHED_BALL, name, 1, 1.0)
        assert abs(res.jacobian[0, j] - fd) <= 1e-6 * abs(fd), name
    assert abs(res.jacobian[0, 0] + 0.4766) < 1e-4 and abs(res.jacobian[0, 1] - 0.09532) < 1e-5


def test_ball_after_one_impact_matches_the_closed_form():
    """y(0.9 s) after one impact: value 1e-9 m, ∂y/∂m and ∂y/∂F to 1e-7 relative of the
    closed form; ∫ v_y dt over [0, 0.9] (v_y jumps at the impact) = y(0.9) − y(0) with the
    same derivatives (1e-7 relative)."""
    mech = loads_scene(PUSHED_BALL)
    res = sensitivity(mech, ["ball_y", "integral: ball_vy"], ["m", "F"], 0.9, rtol=1e-12)
    assert len(res.stats["events"]) == 1
    assert abs(res.values[0] - _pushed_y(1.0, 5.0, 0.9)) < 1e-9
    assert abs(res.values[1] - (_pushed_y(1.0, 5.0, 0.9) - 1.1)) < 1e-9
    h = 1e-6
    exact = [(_pushed_y(1.0 + h, 5.0, 0.9) - _pushed_y(1.0 - h, 5.0, 0.9)) / (2 * h),
             (_pushed_y(1.0, 5.0 + h, 0.9) - _pushed_y(1.0, 5.0 - h, 0.9)) / (2 * h)]
    for j in range(2):
        assert abs(res.jacobian[0, j] - exact[j]) <= 1e-7 * abs(exact[j])
        assert abs(res.jacobian[1, j] - exact[j]) <= 1e-7 * abs(exact[j])


def test_pendulum_on_its_stop_matches_finite_differences_of_whole_runs():
    """The damped pendulum hits its stop at −1 rad at 0.390 s and rebounds: ∂θ(0.7 s)/∂c and
    ∂θ/∂m agree with central differences of simulate to 1e-6 relative, and the angle stays
    within the stop."""
    mech = loads_scene(DAMPED_STOPS)
    res = sensitivity(mech, ["pin_angle"], ["c", "m"], 0.7, rtol=1e-12)
    assert [e["kind"] for e in res.stats["events"]] == ["limit"]
    assert res.values[0] > -1.0
    for j, name in enumerate(("c", "m")):
        fd = _central(DAMPED_STOPS, name, 0, 0.7)
        assert abs(res.jacobian[0, j] - fd) <= 1e-6 * abs(fd), name


def test_restitution_of_the_floor_matches_the_closed_form_and_whole_runs():
    """∂y(0.9 s)/∂e after one impact = a t₁ (0.9 − t₁) = 2.898183 (the restitution map's
    derivative Δ_p): closed form to 1e-9 relative, central differences of simulate to 1e-6."""
    res = sensitivity(loads_scene(BALL_E), ["ball_y"], ["eps", "F"], 0.9, rtol=1e-12)
    a = 9.81 + 5.0
    t1 = math.sqrt(2.0 / a)
    exact = a * t1 * (0.9 - t1)
    assert abs(res.jacobian[0, 0] - exact) <= 1e-9 * exact
    fd = _central(BALL_E, "eps", 1, 0.9)
    assert abs(res.jacobian[0, 0] - fd) <= 1e-6 * abs(fd)


def test_stop_position_and_restitution_match_finite_differences_of_whole_runs():
    """The pendulum's stop and restitution as parameters: ∂θ(0.7 s)/∂e = 1.0842,
    ∂θ/∂stop = 0.19751 (the gap's ∂g/∂p in dt_e/dp) and ∂θ/∂c agree with central differences
    of simulate to 1e-6 relative."""
    names = ["eps", "stop", "c"]
    res = sensitivity(loads_scene(STOPS_E), ["pin_angle"], names, 0.7, rtol=1e-12)
    for j, name in enumerate(names):
        fd = _central(STOPS_E, name, 0, 0.7)
        assert abs(res.jacobian[0, j] - fd) <= 1e-6 * abs(fd), name
    assert abs(res.jacobian[0, 0] - 1.0842) < 1e-4 and abs(res.jacobian[0, 1] - 0.19751) < 1e-5


@pytest.mark.parametrize("coordinates", ["absolute", "natural"])
def test_constrained_coordinates_give_the_same_jump(coordinates):
    """The same pendulum in absolute or natural coordinates (the pin as constraint equations:
    an index-1 DAE, the impulse law with C_q): the angle and ∫ v_x dt and their derivatives
    with respect to e, the stop and c equal those of joint coordinates (an ODE) to 1e-7
    relative."""
    names = ["eps", "stop", "c"]
    joint = sensitivity(loads_scene(STOPS_E), ["pin_angle", "integral: rod_vx"], names, 0.7,
                        rtol=1e-12)
    text = STOPS_E.replace("dimension = 2\n", f'dimension = 2\ncoordinates = "{coordinates}"\n')
    angle = "rod_angle" if coordinates == "absolute" else "pin"
    other = sensitivity(loads_scene(text), [angle, "integral: rod_vx"], names, 0.7, rtol=1e-12)
    assert other.stats["events"][0]["element"] == "pin.limit.lower"
    np.testing.assert_allclose(other.values, joint.values, rtol=1e-7)
    np.testing.assert_allclose(other.jacobian, joint.jacobian, rtol=1e-7)


@pytest.mark.parametrize("case", ["ball", "pendulum"])
def test_four_impacts_match_finite_differences_of_whole_runs(case):
    """Four jumps in a row: the ball over 2 s (∂y/∂(e, F, m)) and the pendulum on its stop
    over 1.25 s, just before its impacts accumulate at 1.312 s (∂θ/∂(e, stop, c)) — central
    differences of whole runs to 1e-6 relative (measured 2e-10 … 3e-8)."""
    text, out, col, names, t_end = {
        "ball": (BALL_E, "ball_y", 1, ["eps", "F", "m"], 2.0),
        "pendulum": (STOPS_E, "pin_angle", 0, ["eps", "stop", "c"], 1.25)}[case]
    res = sensitivity(loads_scene(text), [out], names, t_end, rtol=1e-12)
    assert len(res.stats["events"]) == 4
    for j, name in enumerate(names):
        fd = _central(text, name, col, t_end)
        assert abs(res.jacobian[0, j] - fd) <= 1e-6 * abs(fd), name


def test_a_plastic_stop_closes_and_holds():
    """e = 0 at the stop: the impact closes the gap (a closed phase with the stop as a
    constraint) — θ(0.7 s) = stop, ∂θ/∂stop = 1 and ∂θ/∂c = 0 (1e-9), ∫ θ dt gains
    ∂/∂stop = t_end − t_e (the time spent on the stop; 1e-7), and the derivatives equal
    central differences of whole runs (1e-6 relative)."""
    plastic = scene_with(STOPS_E, {"eps": 0.0}, "plastic.toml")
    res = sensitivity(loads_scene(plastic), ["pin_angle", "integral: pin_angle"],
                      ["stop", "c"], 0.7, rtol=1e-12)
    assert [e["kind"] for e in res.stats["events"]] == ["limit", "contact"]
    assert res.stats["phases"] == 2
    t_e = res.stats["events"][0]["time"]
    assert abs(res.values[0] + 1.0) < 1e-9
    assert abs(res.jacobian[0, 0] - 1.0) < 1e-9 and abs(res.jacobian[0, 1]) < 1e-9
    assert abs(res.jacobian[1, 0] - (0.7 - t_e)) < 1e-7
    fd = _central(plastic, "stop", 0, 0.7)
    assert abs(res.jacobian[0, 0] - fd) < 1e-6


@pytest.mark.parametrize("coordinates", ["absolute", "natural"])
def test_plastic_stop_in_constrained_coordinates(coordinates):
    """The plastic stop with the pin (and, closed, the stop) as constraint equations: the rod
    rests at the stop, so ∫ v_x dt = x(T) − x(0) = (L/2)(cos 1 − 1) and its derivative with
    respect to the stop is (L/2) sin 1 = 0.420735, with respect to c zero — exact to 1e-9 by
    both methods."""
    text = scene_with(STOPS_E, {"eps": 0.0}, "plastic.toml").replace(
        "dimension = 2\n", f'dimension = 2\ncoordinates = "{coordinates}"\n')
    for method in ("forward", "adjoint"):
        res = sensitivity(loads_scene(text), ["integral: rod_vx"], ["stop", "c"], 0.7,
                          rtol=1e-12, method=method)
        assert abs(res.values[0] - 0.5 * (math.cos(1.0) - 1.0)) < 1e-9
        assert abs(res.jacobian[0, 0] - 0.5 * math.sin(1.0)) < 1e-9, method
        assert abs(res.jacobian[0, 1]) < 1e-9, method


def test_a_resting_ball_lifted_off_matches_the_closed_form():
    """A ball resting on the floor (closed from the start) lifted by k t leaves it at
    t_d = m g / k (a detach: the multiplier reaches zero, q̈ continuous, S continuous):
    y(1 s) = r + k (1 − t_d)³/(6 m) (1e-9 m); ∂y/∂k = (1 − t_d)³/(6 m) + g (1 − t_d)²/(2 k)
    and ∂y/∂m = −(1 − t_d)³ k/(6 m²) − g (1 − t_d)²/(2 m) (1e-7 relative), and central
    differences of whole runs (1e-6 relative)."""
    res = sensitivity(loads_scene(LIFTED_BALL), ["ball_y"], ["k", "m"], 1.0, rtol=1e-12)
    assert [e["kind"] for e in res.stats["events"]] == ["contact", "detach"]
    k, m, g = 20.0, 1.0, 9.81
    d = 1.0 - m * g / k
    assert abs(res.values[0] - (0.1 + k * d**3 / (6 * m))) < 1e-9
    exact = [d**3 / (6 * m) + g * d**2 / (2 * k), -k * d**3 / (6 * m**2) - g * d**2 / (2 * m)]
    for j, name in enumerate(("k", "m")):
        assert abs(res.jacobian[0, j] - exact[j]) <= 1e-7 * abs(exact[j]), name
        fd = _central(LIFTED_BALL, name, 1, 1.0)
        assert abs(res.jacobian[0, j] - fd) <= 1e-6 * abs(fd), name


def test_the_compliant_alternative_matches_finite_differences():
    """The alternative the refusals name: compliant contacts and stops are forces of the
    smooth DAE.  The ball on a Hunt-Crossley floor (k = 1e5, c = 200; it failed with
    IDA_TOO_MUCH_WORK at the contact before the algebraic states left the error test) and the
    pendulum on a compliant stop: every derivative = central differences of simulate with a
    step of 1e-3 (the contact force is only C¹ in the penetration and smaller steps are
    noisy), to 5e-6 relative (measured ≤ 9e-7)."""
    ball = PUSHED_BALL.replace('model = "impact"',
                               'model = "compliant"\nstiffness = 1e5\ndamping = 200.0')
    stop = STOPS_E.replace('restitution = "eps"', 'restitution = "eps"\nlimit_model = "compliant"')
    for text, out, col, names, t_end in ((ball, "ball_y", 1, ["m", "F"], 0.9),
                                         (stop, "pin_angle", 0, ["stop", "c", "m"], 0.7)):
        res = sensitivity(loads_scene(text), [out], names, t_end, rtol=1e-12)
        assert "event_driven" not in res.stats
        for j, name in enumerate(names):
            fd = _central(text, name, col, t_end, h=1e-3)
            assert abs(res.jacobian[0, j] - fd) <= 5e-6 * abs(fd), (out, name)


ADJOINT_CASES = {
    "ball, 4 impacts": (BALL_E, ["ball_y", "ball_vy", "integral: ball_vy", "integral: ball_y"],
                        ["eps", "F", "m"], 2.0),
    "pendulum, 4 impacts": (STOPS_E, ["pin_angle", "integral: pin_angle"],
                            ["eps", "stop", "c"], 1.25),
    "plastic stop": (scene_with(STOPS_E, {"eps": 0.0}, "plastic.toml"),
                     ["pin_angle", "integral: pin_angle"], ["stop", "c"], 0.7),
    "lifted ball": (LIFTED_BALL, ["ball_y", "integral: ball_y"], ["k", "m"], 1.0)}


@pytest.mark.parametrize("case", list(ADJOINT_CASES))
def test_adjoint_across_events_equals_forward(case):
    """The adjoint: the costate of each output carried backwards through each phase (reverse
    mode through CVODES on the phase's ODE, q̈ and λ eliminated) and through each event by the
    transposed jump.  It equals the forward sensitivities (IDAS) to 1e-7 relative of the
    largest entry (measured ≤ 3e-10), final values and integrals alike; the lifted ball's
    ∂(∫ y dt)/∂k = (1 − t_d)⁴/24 + g (1 − t_d)³/(6 k) = 0.0136202 (closed form, 1e-8)."""
    text, outputs, names, t_end = ADJOINT_CASES[case]
    fwd = sensitivity(loads_scene(text), outputs, names, t_end, rtol=1e-12)
    adj = sensitivity(loads_scene(text), outputs, names, t_end, rtol=1e-12, method="adjoint")
    np.testing.assert_array_equal(adj.values, fwd.values)
    scale = np.max(np.abs(fwd.jacobian))
    np.testing.assert_allclose(adj.jacobian, fwd.jacobian, rtol=0, atol=1e-7 * scale)
    if case == "lifted ball":
        d = 1.0 - 9.81 / 20.0
        exact = d**4 / 24.0 + 9.81 * d**3 / (6.0 * 20.0)
        assert abs(fwd.jacobian[1, 0] - exact) < 1e-8 and abs(adj.jacobian[1, 0] - exact) < 1e-8


def test_smooth_integrals_and_adjoint_match_the_closed_form():
    """Without events (the ball in free flight, pushed by F): y(T) and ∫ y dt and their
    derivatives −T²/(2m), F T²/(2m²), −T³/(6m), F T³/(6m²) by both methods, to 1e-9 — the
    quadratures are in IDAS's error test now (the forward ∂(∫ y)/∂F was −0.005122, 14 % off)
    and the adjoint runs on CVODES with its quadratures tested (it gave −0.05495 for ∂y/∂F)."""
    free = PUSHED_BALL[:PUSHED_BALL.index("[[contacts]]")]
    t_end, f, m = 0.3, 5.0, 1.0
    exact = [[-t_end**2 / (2 * m), f * t_end**2 / (2 * m**2)],
             [-t_end**3 / (6 * m), f * t_end**3 / (6 * m**2)]]
    for method in ("forward", "adjoint"):
        res = sensitivity(loads_scene(free), ["ball_y", "integral: ball_y"], ["F", "m"], t_end,
                          rtol=1e-12, method=method)
        np.testing.assert_allclose(res.jacobian, exact, rtol=0, atol=1e-9, err_msg=method)


def test_what_the_jump_does_not_cover_is_refused_by_name():
    # the bounces accumulate at t₁ (1 + e)/(1 − e) = 3.307 s, where the ball comes to rest: a
    # closed contact
    with pytest.raises(AnalysisError, match=r"'floor' closes .* t = 3\.307.*finite "
                                            r"differences"):
        sensitivity(loads_scene(PUSHED_BALL), ["ball_y"], ["F"], 4.5, rtol=1e-10)
    # e = 0 closes the stop; for e > 0 it would bounce: a one-sided derivative
    with pytest.raises(AnalysisError, match=r"restitution of 'pin.limit.lower' \(e = 0.*"
                                            r"depends on eps.*one-sided"):
        sensitivity(loads_scene(scene_with(STOPS_E, {"eps": 0.0}, "p.toml")), ["pin_angle"],
                    ["eps"], 0.7)
    # load-time numbers: the drop height is the initial position, the radius a contact field
    with pytest.raises(AnalysisError, match="'h0' fix load-time numbers"):
        sensitivity(loads_scene(PUSHED_BALL), ["ball_y"], ["h0"], 1.0)
    # by default (all parameters) they are left out, and said so
    res = sensitivity(loads_scene(PUSHED_BALL), ["ball_y"], t_end=0.9)
    assert res.parameters == ["m", "F"]
    assert sorted(res.stats["skipped_parameters"]) == ["h0", "r"]
    # two balls dropped together: both gaps take an impulse at 0.4515 s (the run lists both)
    two = scene_with(PUSHED_BALL, {"F": 0.0}, "two.toml") + """
[[bodies]]
name = "ball2"
mass = "m"
inertia = "0.4 * m * r**2"
position = [1.0, "h0 + r"]

[[contacts]]
name = "floor2"
type = "plane"
body = "ball2"
point = [1.0, "h0 + r"]
radius = "r"
model = "impact"
restitution = 0.8
"""
    with pytest.raises(AnalysisError, match=r"'floor', 'floor2' act together at "
                                            r"t = 0\.451524"):
        sensitivity(loads_scene(two), ["ball_y"], ["m"], 0.9)
    rough = PUSHED_BALL.replace("friction = 0.0", "friction = 0.3")
    with pytest.raises(AnalysisError, match=r"contact 'floor' needs Coulomb friction at a "
                                            r"closed contact.*finite differences"):
        sensitivity(loads_scene(rough), ["ball_y"], ["F"], 1.0)
    stick = DAMPED_STOPS + """
[[forces]]
name = "dry"
type = "joint_friction"
joint = "pin"
friction = 0.1
stick_slip = true
"""
    with pytest.raises(AnalysisError, match="force 'dry' needs switching between sticking "
                                            "and sliding"):
        sensitivity(loads_scene(stick), ["pin_angle"], ["c"], 0.5)


def test_cli_sensitivity_across_the_stop_and_the_refusal(capsys):
    """`casmbd sensitivity examples/pendulum_stops.toml --output pin_angle --param m` crosses
    the stop (one JSON object naming the event; ∂θ/∂m = 0: m cancels, 1e-9); over 5 s the
    ball's bounces accumulate and the refusal names the floor (exit 1, no traceback)."""
    import json

    from casmbd import cli

    assert cli.main(["sensitivity", str(STOPS), "--output", "pin_angle", "--param", "m",
                     "--t-end", "0.7", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [e["element"] for e in data["stats"]["events"]] == ["pin.limit.lower"]
    assert abs(data["outputs"]["pin_angle"]["derivatives"]["m"]) < 1e-9
    assert cli.main(["sensitivity", str(BALL), "--output", "ball_y", "--param", "m",
                     "--t-end", "5"]) == 1
    err = capsys.readouterr().err
    assert "'floor' closes" in err and "Traceback" not in err
