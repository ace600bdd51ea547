"""Measures in scene expressions and the force kind ``type = "expression"`` (issue 24 items 1,
2 and the matching validation of item 7).

* A cubic spring m x'' = −k1 x − k3 x³ − c x' written as an expression force on a prismatic
  joint, simulated from its scene (casmbd rtol 1e-10, atol 1e-12), against
  ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-12) of the hand-written ODE, in joint and in
  absolute coordinates: bound |x − x_ref| < 1e-8 m, |x' − x'_ref| < 1e-7 m/s over 3 s
  (measured 2.4e-11 / 1.1e-10 in joint coordinates, 4.2e-10 / 2.1e-9 in absolute ones).
* A PD-controlled pendulum (I_O θ'' = −m g l cos θ − Kp (θ − θ_ref) − Kd θ'), same bounds in
  rad and rad/s (measured 4.7e-12 / 3.6e-11 joint, 3.0e-11 / 2.6e-10 absolute).
* A drag force on a body point (value = [fx, fy], frame "global") and a body-frame torque
  against their hand-written ODEs.
* The smooth helpers step (Adams' cubic STEP), smooth_sign and dead_zone in closed form.
* Bad input: unknown joint or marker, wrong arity, unquoted names, measures in a driver or in
  another force kind, a coordinate the joint lacks — each error names the entry and key.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import casmbd
from casmbd.errors import CasmbdError, ExpressionError, SceneError
from casmbd.model.expressions import parse_expression

RTOL = 1e-10
ATOL = 1e-12

CUBIC = """
[scene]
name = "cubic_spring"
dimension = 2
gravity = [0.0, 0.0]
coordinates = "{coords}"

[parameters]
k1 = 20.0
k3 = 150.0
c = 0.3

[[bodies]]
name = "slider"
mass = 1.5
inertia = 0.01
position = [0.0, 0.0]
velocity = [1.2, 0.0]

[[joints]]
name = "J"
type = "prismatic"
body1 = "ground"
body2 = "slider"
point = [0.0, 0.0]
axis = [1.0, 0.0]

[[forces]]
name = "cubic"
type = "expression"
joint = "J"
value = "-k1*translation('J') - k3*translation('J')**3 - c*rate('J')"
"""

PD = """
[scene]
name = "pd_pendulum"
dimension = 2
gravity = [0.0, -9.81]
coordinates = "{coords}"

[parameters]
Kp = 40.0
Kd = 3.0
th_ref = 0.5

[[bodies]]
name = "rod"
mass = 2.0
inertia = 0.1
position = [0.5, 0.0]

[[joints]]
name = "J"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]

[[forces]]
name = "pd"
type = "expression"
joint = "J"
value = '-Kp*(angle("J") - th_ref) - Kd*rate("J")'
"""


def _reference(rhs, y0, t):
    sol = solve_ivp(rhs, (t[0], t[-1]), y0, method="DOP853", t_eval=t, rtol=1e-12,
                    atol=1e-14)
    assert sol.success
    return sol.y.T


@pytest.mark.parametrize("coords", ["joint", "absolute"])
def test_cubic_spring_matches_the_hand_written_ode(coords: str) -> None:
    mech = casmbd.loads_scene(CUBIC.format(coords=coords))
    res = casmbd.simulate(mech, 3.0, 60, rtol=RTOL, atol=ATOL)
    m, k1, k3, c = 1.5, 20.0, 150.0, 0.3
    ref = _reference(lambda t, y: [y[1], (-k1 * y[0] - k3 * y[0] ** 3 - c * y[1]) / m],
                     [0.0, 1.2], res.t)
    joint = res.joint("J")
    assert np.max(np.abs(joint["coordinate"] - ref[:, 0])) < 1e-8
    assert np.max(np.abs(joint["velocity"] - ref[:, 1])) < 1e-7
    # the element reports its value: the generalized force along x
    x, xd = joint["coordinate"], joint["velocity"]
    np.testing.assert_allclose(res.force("cubic")["value"], -k1 * x - k3 * x**3 - c * xd,
                               rtol=0, atol=1e-10)


@pytest.mark.parametrize("coords", ["joint", "absolute"])
def test_pd_pendulum_matches_the_hand_written_ode(coords: str) -> None:
    mech = casmbd.loads_scene(PD.format(coords=coords))
    res = casmbd.simulate(mech, 3.0, 60, rtol=RTOL, atol=ATOL)
    m, inertia, length, g, kp, kd, th_ref = 2.0, 0.1, 0.5, 9.81, 40.0, 3.0, 0.5
    i_o = inertia + m * length**2

    def rhs(t, y):
        torque = -kp * (y[0] - th_ref) - kd * y[1]
        return [y[1], (-m * g * length * math.cos(y[0]) + torque) / i_o]

    ref = _reference(rhs, [0.0, 0.0], res.t)
    joint = res.joint("J")
    assert np.max(np.abs(joint["coordinate"] - ref[:, 0])) < 1e-8
    assert np.max(np.abs(joint["velocity"] - ref[:, 1])) < 1e-7


def test_drag_force_and_body_frame_torque_on_a_body() -> None:
    """A free body (no joints) with drag F = −b v at its centre of mass and a body-frame
    torque T = −kt θ − ct ω: x'' = −b/m x', θ'' = (−kt θ − ct θ')/I."""
    mech = casmbd.Mechanism("drag", gravity=(0.0, 0.0))
    mech.add_parameter("b", 0.8)
    mech.add_body("puck", mass=2.0, inertia=0.05, position=(0.0, 0.0), velocity=(1.0, 0.5),
                  angular_velocity=2.0)
    mech.add_marker("c", "puck", (0.0, 0.0))
    mech.add("expression", "drag", body="puck", value=['-b*vx("c")', '-b*vy("c")'])
    mech.add("expression", "spin", body="puck", torque='-3*angle_of("puck") - '
                                                      '0.2*omega_of("puck")', frame="body")
    res = casmbd.simulate(mech, 2.0, 20, rtol=RTOL, atol=ATOL)
    t = res.t
    ref_x = 1.0 * 2.0 / 0.8 * (1 - np.exp(-0.8 / 2.0 * t))
    body = res.body("puck")
    assert np.max(np.abs(body["position"][:, 0] - ref_x)) < 1e-8
    assert np.max(np.abs(body["position"][:, 1] - 0.5 * ref_x)) < 1e-8
    ref = _reference(lambda t, y: [y[1], (-3 * y[0] - 0.2 * y[1]) / 0.05], [0.0, 2.0], t)
    assert np.max(np.abs(body["angle"] - ref[:, 0])) < 1e-7
    reports = res.force("drag")
    np.testing.assert_allclose(reports["fx"], -0.8 * body["velocity"][:, 0], atol=1e-12)
    np.testing.assert_allclose(res.force("spin")["torque"],
                               -3 * body["angle"] - 0.2 * body["angular_velocity"],
                               atol=1e-12)


def test_smooth_helpers_in_closed_form() -> None:
    x = ca.SX.sym("x")
    f = ca.Function("f", [x], [ca.vertcat(
        parse_expression("step(x, 1, 2, 3, 6)", {"x": x}),
        parse_expression("smooth_sign(x, 0.1)", {"x": x}),
        parse_expression("dead_zone(x, -0.5, 1)", {"x": x}))])
    for value in (-2.0, 0.7, 1.0, 1.5, 2.0, 2.9, 3.0, 4.0):
        d = min(max((value - 1) / 2, 0.0), 1.0)
        step = 2 + 4 * d * d * (3 - 2 * d)
        zone = value - 1 if value > 1 else (value + 0.5 if value < -0.5 else 0.0)
        np.testing.assert_allclose(np.asarray(f(value)).ravel(),
                                   [step, math.tanh(value / 0.1), zone], atol=1e-15)
    slope = ca.Function("s", [x], [ca.jacobian(parse_expression("step(x, 1, 2, 3, 6)",
                                                                 {"x": x}), x)])
    assert float(slope(1.0)) == 0.0 and float(slope(3.0)) == 0.0  # C1 at both ends
    assert float(slope(2.0)) == pytest.approx(4 * 1.5 / 2, abs=1e-14)


# --------------------------------------------------------------------------- bad input

def _scene_with(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new)


@pytest.mark.parametrize(("old", "new", "message"), [
    ("""value = '-Kp*(angle("J")""", """value = '-Kp*(angle("K")""", "unknown joint 'K'"),
    ("""value = '-Kp*(angle("J")""", """value = '-Kp*(angle("J", "J")""",
     "takes 1 quoted name, got 2"),
    ("""value = '-Kp*(angle("J")""", """value = '-Kp*(angle(J)""", "quoted name"),
    ("""value = '-Kp*(angle("J")""", """value = '-Kp*(translation("J")""",
     "has no translation coordinate"),
    ("""value = '-Kp*(angle("J")""", """value = '-Kp*(z("rod")""", "needs a spatial"),
    ("""value = '-Kp*(angle("J")""", """value = '-Kp*(x("nowhere")""",
     "unknown marker or body 'nowhere'"),
    ("""value = '-Kp*(angle("J")""", """value = '-Kp*(angel("J")""",
     "unknown function 'angel'"),
])
def test_bad_measures_name_the_entry_and_key(old: str, new: str, message: str) -> None:
    with pytest.raises(SceneError) as info:
        casmbd.loads_scene(_scene_with(PD.format(coords="auto"), old, new))
    text = str(info.value)
    assert "[[forces]] entry 1 ('pd') key 'value'" in text
    assert message in text


def test_measures_are_refused_where_values_depend_on_time_only() -> None:
    driven = PD.format(coords="auto") + """
[[drivers]]
name = "spin"
joint = "J"
position = "0.1*angle('J')"
"""
    with pytest.raises(ExpressionError) as info:
        casmbd.loads_scene(driven)
    assert "[[drivers]] entry 1 ('spin') key 'position'" in str(info.value)
    assert "measure 'angle' depends on the state" in str(info.value)
    torque = PD.format(coords="auto").replace('type = "expression"\njoint = "J"\nvalue = ',
                                              'type = "torque"\nbody = "rod"\nvalue = ')
    with pytest.raises(ExpressionError) as info:
        casmbd.loads_scene(torque)
    assert "[[forces]] entry 1 ('pd') key 'value'" in str(info.value)
    assert "allowed only in [[outputs]] values and forces of type 'expression'" in \
        str(info.value)


def test_expression_force_arguments_are_checked() -> None:
    mech = casmbd.loads_scene(PD.format(coords="auto"))
    with pytest.raises(CasmbdError, match=r"give 'joint'.*or 'body'"):
        mech.add("expression", "both", joint="J", body="rod", value=1.0)
    with pytest.raises(CasmbdError, match="field 'coordinate': joint 'J' has no coordinate"):
        mech.add("expression", "c", joint="J", coordinate="translation", value=1.0)
    with pytest.raises(CasmbdError, match=r"field 'value': expected a list of 2"):
        mech.add("expression", "f", body="rod", value=["1", "2", "3"])
    with pytest.raises(CasmbdError, match="'point' and 'torque' belong to a force on a body"):
        mech.add("expression", "p", joint="J", value=1.0, torque=2.0)
    with pytest.raises(CasmbdError, match="give 'value'"):
        mech.add("expression", "n", body="rod")
    scene = PD.format(coords="auto").replace('joint = "J"\nvalue', 'joint = "J"\npoint = [0, 0]'
                                             '\nvalue')
    with pytest.raises(SceneError, match=r"\('pd'\).*field 'point'"):
        casmbd.loads_scene(scene)


def test_linearization_of_the_pd_pendulum_is_exact() -> None:
    """The Jacobians of the expression force are exact (AD): the eigenvalues about the static
    equilibrium are the roots of I_O s² + Kd s + (Kp − m g l sin θ*) with
    Kp (θ* − θ_ref) = −m g l cos θ*, to 1e-9."""
    mech = casmbd.loads_scene(PD.format(coords="absolute"))
    lin = casmbd.linearize(mech, at="equilibrium")
    m, length, g, kp, kd, th_ref, i_o = 2.0, 0.5, 9.81, 40.0, 3.0, 0.5, 0.6
    lo, hi = -1.0, 1.0
    for _ in range(200):  # bisection of the equilibrium condition (monotone on [-1, 1])
        mid = 0.5 * (lo + hi)
        if -m * g * length * math.cos(mid) - kp * (mid - th_ref) > 0:
            lo = mid
        else:
            hi = mid
    roots = np.roots([i_o, kd, kp - m * g * length * math.sin(lo)])
    np.testing.assert_allclose(np.sort_complex(lin.eigenvalues), np.sort_complex(roots),
                               rtol=0, atol=1e-9)


def test_pd_pendulum_reaction_is_m_a_minus_m_g() -> None:
    """The controller torque acts along the joint coordinate: the pin's reaction force on the
    rod is m a_G − m g (its moment zero), equal in joint and absolute coordinates."""
    for coords in ("joint", "absolute"):
        res = casmbd.simulate(casmbd.loads_scene(PD.format(coords=coords)), 1.0, 10,
                              rtol=RTOL, atol=ATOL)
        expected = 2.0 * res.body("rod")["acceleration"] - 2.0 * np.array([0.0, -9.81])
        np.testing.assert_allclose(res["joint_reactions"][:, 0, :2], expected, atol=1e-8)
        np.testing.assert_allclose(res["joint_reactions"][:, 0, 2], 0.0, atol=1e-8)


SPATIAL = """
[scene]
name = "spatial_measures"
dimension = 3
gravity = [0.0, 0.0, 0.0]

[[bodies]]
name = "slider"
mass = 1.5
inertia = [0.2, 0.2, 0.05]
position = [0.0, 0.0, 0.0]
velocity = [0.0, 0.0, 0.4]
angular_velocity = [0.0, 0.0, 1.0]

[[markers]]
name = "c"
body = "slider"
point = [0.0, 0.0, 0.0]

[[joints]]
name = "J"
type = "cylindrical"
body1 = "ground"
body2 = "slider"
point = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]

[[forces]]
name = "axial"
type = "expression"
body = "slider"
value = [0.0, 0.0, '-8*z("c") - 0.5*vz("c")']

[[forces]]
name = "twist"
type = "expression"
joint = "J"
coordinate = "angle"
value = '-3*angle("J") - 0.1*rate("J.angle")'

[[outputs]]
name = "height"
value = 'z("c") + 0*translation("J")'
"""


def test_spatial_body_force_and_joint_angle_coordinate() -> None:
    """A cylindrical joint: an axial body force −8 z − 0.5 ż and a torque on the joint's
    angle coordinate −3 φ − 0.1 φ̇, against their ODEs (1.5 z'' = …, 0.05 φ'' = …)."""
    res = casmbd.simulate(casmbd.loads_scene(SPATIAL), 2.0, 20, rtol=RTOL, atol=ATOL)
    ref_z = _reference(lambda t, y: [y[1], (-8 * y[0] - 0.5 * y[1]) / 1.5], [0.0, 0.4], res.t)
    ref_a = _reference(lambda t, y: [y[1], (-3 * y[0] - 0.1 * y[1]) / 0.05], [0.0, 1.0],
                       res.t)
    joint = res.joint("J")
    assert np.max(np.abs(joint["coordinate"] - ref_z[:, 0])) < 1e-8
    assert np.max(np.abs(joint["angle"] - ref_a[:, 0])) < 1e-8
    np.testing.assert_allclose(res.output("height"), joint["coordinate"], atol=1e-12)
    assert res.names["force_outputs"] == ["axial.fx", "axial.fy", "axial.fz", "twist.value"]
    np.testing.assert_allclose(res.force("twist")["value"],
                               -3 * joint["angle"] - 0.1 * joint["angle_velocity"], atol=1e-12)
