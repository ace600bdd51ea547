"""The generic velocity constraint (casmbd.model.velocity_constraint, issue 37).

* Written with the same row as the knife edge — the velocity of the blade point P across the
  body axis, −sin θ ẋ_P + cos θ ẏ_P — it reproduces the ``knife_edge`` run (Chaplygin's
  sleigh) to round-off.
* A rheonomic row, b(q, t) ≠ 0: a body whose centre G is made to slip sideways at the
  prescribed velocity w(t) = c sin Ωt (the blade at G).  The constraint force acts at G
  across the axis, so (body frame, no applied force) I ω̇ = 0 and m (u̇ − ω w) = 0:

      ω = ω₀,  θ = ω₀ t,  u(t) = u₀ + ω₀ c (1 − cos Ωt)/Ω,

  and the centre moves with ẋ = u cos θ − w sin θ, ẏ = u sin θ + w cos θ (integrated here by
  adaptive quadrature, an independent route).
* Rows that are not affine in the velocities, or free of them, are refused naming the joint,
  the row and the term.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

import casmbd
from casmbd.errors import ExpressionError, ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.model import Mechanism
from casmbd.model.velocity_constraint import VelocityConstraint, additive_terms
from casmbd.system.equations import System

COORDINATES = ("absolute", "natural", "joint")
M, INERTIA, A = 2.0, 0.3, 0.4
U0, W0 = 1.0, 2.0
LATERAL = "-sin(angle_of('sleigh'))*vx('P') + cos(angle_of('sleigh'))*vy('P')"


def sleigh(coordinates: str, generic: bool) -> Mechanism:
    mech = Mechanism("sleigh", dimension=2, coordinates=coordinates)
    mech.add_body("sleigh", M, INERTIA, [0.0, 0.0], velocity=[U0, A * W0],
                  angular_velocity=W0)
    if generic:
        mech.add_marker("P", "sleigh", [-A, 0.0])
        mech.add("velocity", "blade", "ground", "sleigh", rows=[LATERAL], labels=["lateral"])
    else:
        mech.add("knife_edge", "blade", "ground", "sleigh", point=[-A, 0.0], axis=[1.0, 0.0])
    return mech


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_generic_row_reproduces_the_knife_edge(coordinates):
    """Same motion (q and v) and multiplier as the knife edge: identical where the angle is
    a coordinate (absolute, joint), to 1e-9 in natural coordinates (angle_of is an atan2
    there, the knife edge a rotated direction: the same function written differently)."""
    runs = [casmbd.simulate(sleigh(coordinates, generic), 3.0, 30, rtol=1e-11, atol=1e-12,
                            mode="vm") for generic in (False, True)]
    tol = 1e-9 if coordinates == "natural" else 1e-12
    for key in ("q", "v", "lambda"):
        assert np.max(np.abs(runs[0].arrays[key] - runs[1].arrays[key])) < tol, key
    # the same reaction force; its moment about G (the generic kind has no point) is the
    # knife edge's (about P, zero) plus (P − G) × F
    knife, generic = (r.arrays["joint_reactions"][:, 0, :] for r in runs)
    assert np.max(np.abs(knife[:, :2] - generic[:, :2])) < 1e-9
    th = runs[0].body("sleigh")["angle"]
    arm = -A * np.column_stack([np.cos(th), np.sin(th)])
    moment = arm[:, 0] * knife[:, 1] - arm[:, 1] * knife[:, 0]
    assert np.max(np.abs(generic[:, 2] - moment)) < 1e-9
    assert np.max(np.abs(knife[:, :2])) > 1.0


C, OMEGA = 0.3, 2.5


def slip_closed_form(t: float) -> tuple[float, float, float]:
    """u(t), w(t), θ(t) of the centre slipping at the prescribed w = c sin Ωt."""
    return (U0 + W0 * C * (1.0 - np.cos(OMEGA * t)) / OMEGA, C * np.sin(OMEGA * t), W0 * t)


def centre_path(t: float) -> np.ndarray:
    """x(t), y(t) of the centre by adaptive quadrature of ẋ, ẏ (1e-13)."""
    def rate(s, k):
        u, w, th = slip_closed_form(s)
        return (u * np.cos(th) - w * np.sin(th)) if k == 0 else (u * np.sin(th) + w * np.cos(th))
    return np.array([quad(rate, 0.0, t, args=(k,), epsabs=1e-13, epsrel=1e-13)[0]
                     for k in (0, 1)])


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_prescribed_slip_velocity_follows_its_closed_form(coordinates):
    """u, ω, θ to 1e-8 and the centre's path to 1e-8 over 3 s; the row (lateral velocity
    minus c sin Ωt, with c and Ω scene parameters) holds to 1e-9."""
    mech = Mechanism("slider", dimension=2, coordinates=coordinates)
    mech.add_parameter("c", C)
    mech.add_parameter("Om", OMEGA)
    mech.add_body("sleigh", M, INERTIA, [0.0, 0.0], velocity=[U0, 0.0], angular_velocity=W0)
    mech.add("velocity", "blade", "ground", "sleigh", rows=[
        "-sin(angle_of('sleigh'))*vx('sleigh') + cos(angle_of('sleigh'))*vy('sleigh')"
        " - c*sin(Om*t)"])
    res = casmbd.simulate(mech, 3.0, 30, rtol=1e-11, atol=1e-12, mode="vm")
    body = res.body("sleigh")
    th, vel = body["angle"], body["velocity"]
    u = vel[:, 0] * np.cos(th) + vel[:, 1] * np.sin(th)
    w = -vel[:, 0] * np.sin(th) + vel[:, 1] * np.cos(th)
    ref = np.array([slip_closed_form(t) for t in res.t])
    assert np.max(np.abs(u - ref[:, 0])) < 1e-8
    assert np.max(np.abs(w - ref[:, 1])) < 1e-9
    assert np.max(np.abs(th - ref[:, 2])) < 1e-8
    assert np.max(np.abs(body["angular_velocity"] - W0)) < 1e-8
    path = np.array([centre_path(t) for t in res.t])
    assert np.max(np.abs(body["position"] - path)) < 1e-8
    assert np.ptp(ref[:, 0]) > 0.4  # the slip drives the forward speed


def test_additive_terms_keep_their_signs():
    assert additive_terms("a*vx('P') - (b - c) + -d") == ["a * vx('P')", "-b", "c", "-d"]
    assert additive_terms("-(x('P')) * vy('P')") == ["-x('P') * vy('P')"]


def planar_mech() -> Mechanism:
    mech = Mechanism("m", dimension=2)
    mech.add_body("sleigh", 1.0, 0.1, [0.0, 0.0])
    mech.add_marker("P", "sleigh", [-0.2, 0.0])
    return mech


@pytest.mark.parametrize(("row", "message"), [
    ("vx('P')*vy('P')", "the term \"vx('P') * vy('P')\""),
    ("cos(angle_of('sleigh'))*vy('P') + abs(vx('P'))", "the term \"abs(vx('P'))\""),
    ("speed('P')", "the term \"speed('P')\""),
    ("sign(vx('P'))", "the term \"sign(vx('P'))\""),
    ("3*vy('P') - vx('P')**2", "the term \"-vx('P') ** 2\""),
    ("vy('P')/vx('P')", "the term \"vy('P') / vx('P')\""),
    ("x('P') - 0.1*t", "involves no velocity"),
    ("0.5", "involves no velocity"),
])
def test_a_row_not_affine_in_the_velocities_is_refused(row, message):
    mech = planar_mech()
    with pytest.raises(ModelError) as err:
        mech.add("velocity", "v", "ground", "sleigh", rows=["vy('P')", row],
                 labels=["along", "bad"])
    text = str(err.value)
    assert "joint 'v' field 'rows' row 2 ('bad')" in text and message in text, text
    assert "v" not in mech.joints


def test_affine_rows_with_positions_time_and_parameters_are_accepted():
    mech = planar_mech()
    mech.add_parameter("k", 2.0)
    joint = mech.add("velocity", "v", "ground", "sleigh", rows=[
        "x('P')**2*vx('P') + exp(-t)*vy('P')/k - sin(t)*y('P')",
        "omega_of('sleigh') - 3*t"])
    assert joint.labels == ("row_1", "row_2") == joint.velocity_labels
    assert joint.needs == frozenset({"velocity_constraints"})
    assert set(joint.bodies) == {"ground", "sleigh"}


def test_the_system_build_checks_affinity_again():
    """A row that escaped the check at add (built directly) is refused when the system
    writes it with the coordinates."""
    mech = planar_mech()
    mech.joints["v"] = VelocityConstraint("v", "ground", "sleigh", labels=("bad",),
                                          rows=("vx('P')*vy('P')",),
                                          involved=("ground", "sleigh"))
    with pytest.raises(ModelError, match=r"joint 'v' field 'rows' row 1 \('bad'\): not affine"):
        System(mech).constraint_jacobian  # noqa: B018


SCENE = """
[scene]
dimension = 2
[parameters]
c = 0.1
[[bodies]]
name = "sleigh"
mass = 1.0
inertia = 0.1
position = [0.0, 0.0]
[[markers]]
name = "P"
body = "sleigh"
point = [-0.2, 0.0]
[[joints]]
name = "blade"
type = "velocity"
{keys}
"""


def test_scene_reads_rows_labels_and_parameters():
    mech = loads_scene(SCENE.format(keys='body2 = "sleigh"\nrows = "vy(\'P\') - c"\n'
                                         'labels = ["lateral"]\npoint = [-0.2, 0.0]'))
    joint = mech.joints["blade"]
    assert joint.rows == ("vy('P') - c",) and joint.labels == ("lateral",)
    assert joint.body1 == "ground" and joint.reaction_point().tolist() == [-0.2, 0.0]


@pytest.mark.parametrize(("keys", "message"), [
    ('body2 = "sleigh"', "key 'rows': missing"),
    ('rows = ["vy(\'P\')"]', "key 'body2': missing"),
    ('body2 = "sleigh"\nrows = []', "field 'rows': expected"),
    ('body2 = "sleigh"\nrows = [1.0]', "field 'rows' row 1 ('row_1'): expected an expression"),
    ('body2 = "sleigh"\nrows = ["vy(\'Q\')"]', "row 1 ('row_1'): unknown marker or body 'Q'"),
    ('body2 = "sleigh"\nrows = ["vy(\'P\') + q"]', "row 1 ('row_1'): unknown name 'q'"),
    ('body2 = "sleigh"\nrows = ["vy(\'P\')", "vx(\'P\')"]\nlabels = ["a"]', "field 'labels'"),
    ('body2 = "sleigh"\nrows = ["vy(\'P\')", "vx(\'P\')"]\nlabels = ["a", "a"]',
     "field 'labels': must be distinct"),
    ('body2 = "sleigh"\nrows = ["vy(\'P\')"]\nlabels = ["not a name"]', "field 'labels'"),
    ('body2 = "sleigh"\nrows = ["vy(\'P\')*vx(\'P\')"]', "row 1 ('row_1'): not affine"),
    ('body2 = "sleigh"\nrows = ["vy(\'P\')"]\naxis = [0.0, 0.0]', "key 'axis': unknown key"),
    ('body2 = "sleigh"\nrows = ["vy(\'P\')"]\npoint = [0.0]', "key 'point'"),
    ('body1 = "sleigh"\nbody2 = "sleigh"\nrows = ["vy(\'P\')"]', "body1 and body2"),
])
def test_scene_errors_name_the_joint_and_key(keys, message):
    with pytest.raises(SceneError) as err:
        loads_scene(SCENE.format(keys=keys))
    text = str(err.value)
    assert "'blade'" in text and message in text, text


def test_row_count_is_limited():
    from casmbd.errors import LimitError
    from casmbd.limits import MAX_VELOCITY_ROWS
    with pytest.raises(LimitError, match="joint 'v' field 'rows': 1,001 exceeds the limit"):
        planar_mech().add("velocity", "v", "ground", "sleigh",
                          rows=["vx('P')"] * (MAX_VELOCITY_ROWS + 1))


def ball(generic: bool, coordinates: str = "absolute") -> Mechanism:
    """A ball (R = 0.1) on level ground, pulled by two springs, rolling and spinning: the
    ``rolling_sphere`` or the same no-slip rows written by hand with the spatial angular
    velocity measures (ṙ_c − R ω × e_z = 0: vx − R wy, vy + R wx) and the height as a velocity
    row (vz = 0)."""
    mech = Mechanism("ball", gravity=(0.0, 0.0, -9.81), coordinates=coordinates)
    mech.add_parameter("R", 0.1)
    mech.add_body("ball", mass=1.0, inertia=[0.004] * 3, position=(0.0, 0.0, 0.1),
                  velocity=(0.2, 0.1, 0.0), angular_velocity=(-1.0, 2.0, 0.5))
    if generic:
        mech.add("velocity", "roll", "ground", "ball",
                 rows=["vz('ball')", "vx('ball') - R*wy('ball')", "vy('ball') + R*wx('ball')"],
                 labels=["height", "slip_x", "slip_y"])
    else:
        mech.add("rolling_sphere", "roll", "ground", "ball", point=(0.0, 0.0, 0.1), radius=0.1)
    mech.add_spring_damper("x_spring", "ground", "ball", (-0.5, 0.0, 0.1), (0.0, 0.0, 0.1),
                           stiffness=20.0, free_length=0.4)
    mech.add_spring_damper("y_spring", "ground", "ball", (0.0, -0.5, 0.1), (0.0, 0.0, 0.1),
                           stiffness=20.0, free_length=0.2)
    return mech


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_generic_rows_with_angular_velocities_reproduce_the_rolling_sphere(coordinates):
    """Over 2 s (the ball oscillates on its springs while it spins): body positions and
    angular velocities to 1e-8 (the generic kind holds the height at velocity level only);
    the contact reactions (force, moment about the centre) to 1e-8."""
    res = [casmbd.simulate(ball(generic, coordinates), 2.0, 20, rtol=1e-11, atol=1e-12,
                           mode="vm") for generic in (False, True)]
    runs = [r.body("ball") for r in res]
    for key in ("position", "velocity", "angular_velocity"):
        assert np.max(np.abs(runs[0][key] - runs[1][key])) < 1e-8, key
    assert np.ptp(runs[0]["position"][:, 0]) > 0.05  # it moves
    reactions = [r.arrays["joint_reactions"][:, 0, :] for r in res]
    assert np.max(np.abs(reactions[0] - reactions[1])) < 1e-8


def test_angular_velocity_measures_are_spatial():
    mech = planar_mech()
    with pytest.raises(ExpressionError, match=r"wx\(...\) needs a spatial mechanism"):
        mech.add("velocity", "v", "ground", "sleigh", rows=["wx('sleigh')"])
    joint = mech.add("velocity", "v", "ground", "sleigh", rows=["wz('P') - 0.1"])
    assert joint.rows == ("wz('P') - 0.1",)
