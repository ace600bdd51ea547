"""Orientation drivers: a spatial body's rotation prescribed as A_d(t) (issue 34, item 1).

(a) A free rigid body driven along x, y, z(t) and Z-X-Z Euler angles (t): kinematics gives
    A = A_d(t) (1e-12), ω and ω̇ against central differences of A_d(t) (ω̃ = Ȧ Aᵀ, 1e-7);
    inverse dynamics gives the Newton–Euler wrench F = m (a − g), M = J ω̇ + ω × J ω (global
    axes, about the centre of mass; 1e-10 relative); the rpy and quaternion forms give the same
    motion as the equivalent Euler angles.
(b) The UR5 with a floating base, base x, y, z + orientation and every joint driven: joint
    torques and base wrench against the per-call ``casmbd.compile(mech).inverse_dynamics``
    (free-flyer v, the base wrench in the root's own axes) at the same states (1e-9 relative),
    in joint and absolute coordinates.
(c) Bad input named.
"""

from __future__ import annotations

import numpy as np
import pytest

import casmbd
from casmbd.errors import (
    AssemblyError,
    CasmbdError,
    ModelError,
    RedundantConstraintError,
    SceneError,
)
from casmbd.model.rotations import euler_zxz_to_quaternion, rotation_matrix

MASS = 2.0
INERTIA = [0.2, 0.25, 0.3, 0.01, -0.02, 0.03]  # Ixx, Iyy, Izz, Ixy, Ixz, Iyz
J_BODY = np.array([[0.2, 0.01, -0.02], [0.01, 0.25, 0.03], [-0.02, 0.03, 0.3]])
GRAVITY = np.array([0.0, 0.0, -9.81])
POSITION = ("0.1 + t", "0.5*t*t", "sin(t)")
ANGLES = ("0.3 + 0.8*sin(2*t)", "0.5 + 0.4*t", "-0.2 + 1.5*t*t")


def _angles(t):
    return np.array([0.3 + 0.8 * np.sin(2 * t), 0.5 + 0.4 * t, -0.2 + 1.5 * t * t])


def _rot(t):
    return rotation_matrix(euler_zxz_to_quaternion(*_angles(t)))


def _acc(t):
    return np.array([0.0, 1.0, -np.sin(t)])


def _free_body(coordinates="auto", **orientation):
    mech = casmbd.Mechanism("free", gravity=list(GRAVITY), dimension=3, coordinates=coordinates)
    mech.add_body("b", MASS, INERTIA, [0.1, 0.0, 0.0],
                  orientation=euler_zxz_to_quaternion(*_angles(0.0)))
    for axis, expr in zip("xyz", POSITION):
        mech.add_driver(f"d{axis}", expr, body="b", coordinate=axis)
    mech.add_driver("rot", body="b", coordinate="orientation",
                    **(orientation or {"euler_zxz": list(ANGLES)}))
    return mech


def _omega(t, h=1e-5):
    """ω (global) from ω̃ = Ȧ Aᵀ, Ȧ by central differences of A_d(t)."""
    w = (_rot(t + h) - _rot(t - h)) / (2 * h) @ _rot(t).T
    return np.array([w[2, 1], w[0, 2], w[1, 0]])


@pytest.fixture(scope="module")
def free_inverse():
    return casmbd.inverse_dynamics(_free_body(), 1.0, 8, mode="vm")


def test_kinematics_reproduces_the_prescribed_rotation(free_inverse):
    res = free_inverse
    assert res.names["drivers"] == ["dx", "dy", "dz", "rot.x", "rot.y", "rot.z"]
    worst_a = worst_w = worst_dw = 0.0
    for k, t in enumerate(res.t):
        rot = res["rotation_matrices"][k, :9].reshape(3, 3)
        worst_a = max(worst_a, np.max(np.abs(rot - _rot(t))))
        worst_w = max(worst_w, np.max(np.abs(res["angular_velocities"][k, :3] - _omega(t))))
        dw = (_omega(t + 1e-4) - _omega(t - 1e-4)) / 2e-4
        worst_dw = max(worst_dw, np.max(np.abs(res["angular_accelerations"][k, :3] - dw)))
    assert worst_a <= 1e-12, worst_a
    assert worst_w <= 1e-7, worst_w
    assert worst_dw <= 1e-6, worst_dw  # a second difference of a first difference (h = 1e-4)
    # the check can fail: A_d a hundredth of a second late is far off
    assert np.max(np.abs(res["rotation_matrices"][4, :9].reshape(3, 3) - _rot(res.t[4] - 0.01))) \
        > 1e-3


def test_inverse_gives_the_newton_euler_wrench(free_inverse):
    """F = m (a − g) at the centre of mass and M = J ω̇ + ω × J ω, global, J = A J' Aᵀ."""
    res = free_inverse
    eff = res["driver_efforts"]
    for k, t in enumerate(res.t):
        force = MASS * (_acc(t) - GRAVITY)
        a = _rot(t)
        j = a @ J_BODY @ a.T
        w = res["angular_velocities"][k, :3]
        dw = res["angular_accelerations"][k, :3]
        moment = j @ dw + np.cross(w, j @ w)
        assert np.max(np.abs(eff[k, :3] - force)) <= 1e-10 * np.max(np.abs(force))
        assert np.max(np.abs(eff[k, 3:] - moment)) <= 1e-10 * np.max(np.abs(moment)), (t, eff[k],
                                                                                       moment)
    # the moment is not a body-axes one: A' M differs
    assert np.max(np.abs(eff[-1, 3:] - _rot(res.t[-1]).T @ eff[-1, 3:])) > 1e-2


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "joint"])
def test_every_coordinate_choice_drives_the_same_motion(free_inverse, coordinates):
    res = casmbd.inverse_dynamics(_free_body(coordinates), 1.0, 8, mode="vm")
    assert np.max(np.abs(res["rotation_matrices"] - free_inverse["rotation_matrices"])) <= 1e-12
    assert np.max(np.abs(res["driver_efforts"] - free_inverse["driver_efforts"])) <= 1e-9


def test_rpy_and_quaternion_forms():
    """rpy [r, p, y] = A_Z(y) A_Y(p) A_X(r) and a quaternion [w, x, y, z] (unnormalised)
    prescribe the rotation they name."""
    rpy = ("0.2*t", "0.3 - 0.5*t", "1 + t*t")
    res = casmbd.kinematics(_free_body(rpy=list(rpy)), 1.0, 4, mode="vm")
    quat = ("2*cos(t)", "0.4", "2*sin(t)", "0.6*t")
    resq = casmbd.kinematics(_free_body(quaternion=list(quat)), 1.0, 4, mode="vm")

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    for k, t in enumerate(res.t):
        expected = rz(1 + t * t) @ ry(0.3 - 0.5 * t) @ rx(0.2 * t)
        assert np.max(np.abs(res["rotation_matrices"][k, :9].reshape(3, 3) - expected)) <= 1e-12
        p = np.array([2 * np.cos(t), 0.4, 2 * np.sin(t), 0.6 * t])
        expected = rotation_matrix(p / np.linalg.norm(p))
        assert np.max(np.abs(resq["rotation_matrices"][k, :9].reshape(3, 3) - expected)) <= 1e-12


def test_a_floating_base_robot_is_driven_and_its_base_wrench_reported():
    """UR5 with a floating base: every degree of freedom driven; joint torques and base
    wrench against the per-call inverse dynamics at the same states."""
    path = "tests/scenes/ur5_arm.urdf"

    def driven(coordinates):
        mech = casmbd.load_urdf(path, floating_base=True)
        mech.coordinates = coordinates
        mech.add_driver("bx", "0.1*sin(t)", body="world", coordinate="x")
        mech.add_driver("by", "0.2*t", body="world", coordinate="y")
        mech.add_driver("bz", "0.5 + 0.3*t*t", body="world", coordinate="z")
        mech.add_driver("brot", body="world", coordinate="orientation",
                        euler_zxz=["0.3*t", "0.2*sin(2*t)", "-0.1*t"])
        for k, joint in enumerate(mech.joints):
            mech.add_driver(f"d_{joint}", f"{0.1 * (k + 1)}*sin({k + 1}*t)", joint=joint)
        return mech

    robot = casmbd.compile(casmbd.load_urdf(path, floating_base=True), mode="vm")
    vmap = robot.velocity_map
    res = casmbd.inverse_dynamics(driven("joint"), 1.0, 4, mode="vm")
    assert res["q"].shape[1] == robot.nq == 13 and res["driver_efforts"].shape[1] == 12
    worst = 0.0
    for k in range(len(res.t)):
        q, qd, qdd = res["q"][k], res["v"][k], res["a"][k]
        v = vmap.velocity_from_rates(q, qd)
        # v̇ from q̈ = G v̇ + Ġ v (G of full column rank)
        g = np.column_stack([vmap.rates_from_velocity(q, e) for e in np.eye(robot.nv)])
        a = np.linalg.lstsq(g, qdd - vmap.rate_accelerations(q, v, np.zeros(robot.nv)),
                            rcond=None)[0]
        tau = robot.inverse_dynamics(q, v, a)
        rot = rotation_matrix(q[3:7])
        eff = res["driver_efforts"][k]
        ours = np.concatenate([rot.T @ eff[0:3], rot.T @ eff[3:6], eff[6:]])
        worst = max(worst, np.max(np.abs(ours - tau)) / np.max(np.abs(tau)))
    assert worst <= 1e-9, worst
    # absolute coordinates: the same efforts
    absolute = casmbd.inverse_dynamics(driven("absolute"), 1.0, 4, mode="vm")
    scale = np.max(np.abs(res["driver_efforts"]))
    assert np.max(np.abs(absolute["driver_efforts"] - res["driver_efforts"])) <= 1e-9 * scale


SCENE = """
[scene]
urdf = "{urdf}"
floating_base = true
coordinates = "{coordinates}"
[[drivers]]
name = "bx"
body = "world"
coordinate = "x"
position = "0.1*sin(t)"
[[drivers]]
name = "by"
body = "world"
coordinate = "y"
position = "0.2*t"
[[drivers]]
name = "bz"
body = "world"
coordinate = "z"
position = "0.5 + 0.3*t*t"
[[drivers]]
name = "brot"
body = "world"
coordinate = "orientation"
{orientation}
"""


def _scene(orientation='euler_zxz = ["0.3*t", "0.2*sin(2*t)", "-0.1*t"]', joints=True,
           coordinates="joint"):
    import pathlib

    urdf = pathlib.Path("tests/scenes/ur5_arm.urdf").resolve()
    text = SCENE.format(urdf=urdf, orientation=orientation, coordinates=coordinates)
    if joints:
        for k, joint in enumerate(("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                   "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")):
            text += (f'[[drivers]]\nname = "d_{joint}"\njoint = "{joint}"\n'
                     f'position = "{0.1 * (k + 1)}*sin({k + 1}*t)"\n')
    return casmbd.loads_scene(text, "fb.toml")


def test_scene_orientation_driver_matches_the_python_one():
    """[[drivers]] coordinate = "orientation" + euler_zxz: the same efforts as
    ``mech.add_driver(..., coordinate="orientation", euler_zxz=...)`` (exactly: the same
    model)."""
    res = casmbd.inverse_dynamics(_scene(), 1.0, 4, mode="vm")
    mech = casmbd.load_urdf("tests/scenes/ur5_arm.urdf", floating_base=True)
    mech.add_driver("bx", "0.1*sin(t)", body="world", coordinate="x")
    mech.add_driver("by", "0.2*t", body="world", coordinate="y")
    mech.add_driver("bz", "0.5 + 0.3*t*t", body="world", coordinate="z")
    mech.add_driver("brot", body="world", coordinate="orientation",
                    euler_zxz=["0.3*t", "0.2*sin(2*t)", "-0.1*t"])
    for k, joint in enumerate(mech.joints):
        mech.add_driver(f"d_{joint}", f"{0.1 * (k + 1)}*sin({k + 1}*t)", joint=joint)
    ref = casmbd.inverse_dynamics(mech, 1.0, 4, mode="vm")
    assert np.max(np.abs(res["driver_efforts"] - ref["driver_efforts"])) <= 1e-12 * np.max(
        np.abs(ref["driver_efforts"]))


@pytest.mark.parametrize("orientation, words", [
    ('euler_zxz = ["t", "0"]', ["'brot'", "euler_zxz", "3 expressions"]),
    ('rpy = ["t", "0", "q("]', ["'brot'", "rpy"]),
    ('position = "t"', ["'brot'", "'position'", "euler_zxz"]),
    ("", ["'brot'", "exactly one of"]),
    ('euler_zxz = [0, 0, 0]\nangles = [0, 0, 0]', ["'brot'", "angles", "unknown key"]),
])
def test_bad_scene_orientation_driver_is_named(orientation, words):
    with pytest.raises(SceneError) as err:
        _scene(orientation, joints=False)
    for word in words:
        assert word in str(err.value), str(err.value)


def test_a_floating_base_without_joint_drivers_counts_the_free_joints():
    """Base fully driven, joints not: the count check names the 6 free joint coordinates."""
    with pytest.raises(CasmbdError, match="6 free degree"):
        casmbd.kinematics(_scene(joints=False), 1.0, 2, mode="vm")


# ---------------------------------------------------------------------------- bad input
def _body_mech(dimension=3):
    mech = casmbd.Mechanism("m", dimension=dimension)
    inertia = INERTIA if dimension == 3 else 0.1
    mech.add_body("b", 1.0, inertia, [0.0] * dimension)
    return mech


@pytest.mark.parametrize("kwargs, words", [
    ({"euler_zxz": ["t", "0"]}, ["'rot'", "euler_zxz", "3 expressions"]),
    ({"quaternion": ["1", "0", "0"]}, ["'rot'", "quaternion", "4 expressions"]),
    ({"euler_zxz": ["t", "0", None]}, ["'rot'", "euler_zxz", "[2]"]),
    ({}, ["'rot'", "exactly one of"]),
    ({"euler_zxz": ["t", 0, 0], "rpy": [0, 0, 0]}, ["'rot'", "exactly one of"]),
    ({"position": "t", "euler_zxz": [0, 0, 0]}, ["'rot'", "position"]),
])
def test_bad_orientation_driver_is_named(kwargs, words):
    with pytest.raises(ModelError) as err:
        _body_mech().add_driver("rot", body="b", coordinate="orientation", **kwargs)
    for word in words:
        assert word in str(err.value), str(err.value)


def test_unknown_coordinate_and_planar_body_are_named():
    with pytest.raises(ModelError, match="'spin'"):
        _body_mech().add_driver("d", "t", body="b", coordinate="spin")
    with pytest.raises(ModelError, match=r"'rot'.*plane.*'angle'"):
        _body_mech(2).add_driver("rot", body="b", coordinate="orientation",
                                 euler_zxz=[0, 0, 0])
    with pytest.raises(ModelError, match="applies to coordinate = 'orientation'"):
        _body_mech().add_driver("rot", body="b", coordinate="x", euler_zxz=[0, 0, 0])
    with pytest.raises(ModelError, match="'nobody'"):
        _body_mech().add_driver("rot", body="nobody", coordinate="orientation",
                                euler_zxz=[0, 0, 0])
    mech = _body_mech()
    mech.add_driver("rot", body="b", coordinate="orientation", euler_zxz=[0, 0, 0])
    with pytest.raises(ModelError, match=r"'rot\.x'"):  # a user name may not hold the rows' "."
        mech.add_driver("rot.x", "t", body="b", coordinate="x")


def test_an_orientation_a_joint_already_fixes_is_redundant():
    """A body welded to the ground and driven in orientation: the driver's rows repeat the
    weld's. Held where the weld holds it they are removed as redundant (named in the stats);
    turning it is a contradiction that the redundancy check names (the row about z)."""
    def welded(phi):
        mech = _body_mech()
        mech.add_rigid("weld", "ground", "b", [0.0, 0.0, 0.0])
        mech.add_driver("rot", body="b", coordinate="orientation", euler_zxz=[phi, 0, 0])
        return mech

    res = casmbd.kinematics(welded(0.0), 1.0, 2, mode="vm")
    assert res.stats["redundant_equations"] == [
        f"driver 'rot.{r}' equation 'orientation'" for r in "xyz"]
    with pytest.raises(RedundantConstraintError, match=r"driver 'rot\.z'"):
        casmbd.kinematics(welded("0.1*t"), 1.0, 2, mode="vm")


def _spinning(phi):
    mech = _body_mech()
    for axis in "xyz":
        mech.add_driver(f"d{axis}", "0", body="b", coordinate=axis)
    mech.add_driver("rot", body="b", coordinate="orientation", euler_zxz=[phi, "0.3", 0])
    return mech


def test_many_turns_and_a_start_near_half_a_turn_are_driven():
    """The base may turn any number of times (only the error rotation enters C): φ = 7t
    passes 400°; a start 172° from A_d(0) (φ = 3) still assembles onto A_d."""
    for phi, at in (("7*t", lambda t: 7 * t), ("3.0", lambda t: 3.0)):
        res = casmbd.kinematics(_spinning(phi), 1.0, 8, mode="vm")
        for k, t in enumerate(res.t):
            expected = rotation_matrix(euler_zxz_to_quaternion(at(t), 0.3, 0.0))
            assert np.max(np.abs(res["rotation_matrices"][k, :9].reshape(3, 3) - expected)) \
                <= 1e-12


def test_a_start_half_a_turn_away_is_named():
    """Exactly half a turn the equations read 0/0: refused naming the driver, the body and
    the angle instead of a spurious 'solution'."""
    with pytest.raises(AssemblyError, match=r"driver 'rot' at t = 0: body 'b' starts 180\.0°"):
        casmbd.kinematics(_spinning("pi"), 1.0, 2, mode="vm")


def test_simulate_with_the_rotation_prescribed(free_inverse):
    """Only the rotation driven, the body falls freely: the simulated rotation follows A_d
    (1e-6, the integrator's rtol 1e-8) and the orientation efforts are the inverse-dynamics
    moment (the centre of mass decouples; 1e-5 relative)."""
    mech = casmbd.Mechanism("free", gravity=list(GRAVITY), dimension=3)
    mech.add_body("b", MASS, INERTIA, [0.1, 0.0, 0.0],
                  orientation=euler_zxz_to_quaternion(*_angles(0.0)))
    mech.add_driver("rot", body="b", coordinate="orientation", euler_zxz=list(ANGLES))
    res = casmbd.simulate(mech, 1.0, 8, mode="vm")
    assert np.max(np.abs(res["rotation_matrices"] - free_inverse["rotation_matrices"])) <= 1e-6
    moment = free_inverse["driver_efforts"][:, 3:]
    assert np.max(np.abs(res["driver_efforts"] - moment)) <= 1e-5 * np.max(np.abs(moment))
    assert np.max(np.abs(res["body_positions"][-1, :3] - [0.1, 0.0, 0.5 * GRAVITY[2]])) <= 1e-6
