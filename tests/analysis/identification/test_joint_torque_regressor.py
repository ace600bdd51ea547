"""The joint-torque regressor Y(q, v, a) (casmbd.analysis.identification.regressor, issue 38).

Y π against casmbd's own inverse dynamics at random states (relative 1e-12 of the largest
effort): the per-call API (``casmbd.compile``, Newton–Euler / Featherstone recursions) on a
6-axis arm (the UR5 URDF and the UR-like scene), with joint friction, on a floating body and
a floating-base arm (free-flyer wrench rows), on the four-bar and the Delta robot (closed
chains: actuated coordinates, ``actuated=``); ``casmbd.inverse_dynamics`` (driver efforts
−λ_d; the actuator efforts of the mixed case) along driven motions of the four-bar and of the
Delta robot's gate path.  The columns are checked one by one against mechanisms built with
other inertial values (links overridden at load: Y(old) π(new) = τ(new)).  CasADi's virtual
machine except one compiled build (compiled = VM to 1e-14).
"""

from __future__ import annotations

import importlib.util
import pathlib
import sys

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.analysis.identification.base_parameters import random_states
from casmbd.analysis.identification.parameters import (
    centroidal,
    inertial_parameters,
    standard_parameters,
)
from casmbd.analysis.identification.regressor import joint_torque_regressor
from casmbd.errors import ModelError
from casmbd.io.urdf import load_urdf

ROOT = pathlib.Path(__file__).resolve().parents[3]
UR5 = ROOT / "tests" / "scenes" / "ur5_arm.urdf"
UR_LIKE = ROOT / "tests" / "scenes" / "ur_like.toml"
FOUR_BAR = ROOT / "examples" / "four_bar.toml"
#: Y π against the inverse dynamics, relative to the largest effort of the state
RTOL = 1e-12

_spec = importlib.util.spec_from_file_location("delta_robot_example",
                                               ROOT / "examples" / "delta_robot.py")
delta = sys.modules.setdefault(_spec.name, importlib.util.module_from_spec(_spec))
_spec.loader.exec_module(delta)

_cache = private_cache("cache_regressor", scope="module")


def _relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


def _against_compile(mech, states: int = 6, seed: int = 0, actuated=None, **options):
    """Largest relative difference of Y π and casmbd.compile's inverse dynamics (the rows of
    the actuated coordinates) at random consistent states."""
    reg = joint_torque_regressor(mech, mode="vm", actuated=actuated, **options)
    model = casmbd.compile(mech, mode="vm", actuated=actuated)
    rows = [model.velocity_names.index(n) for n in reg.rows]
    worst = 0.0
    qs, vs, accs = random_states(reg, states, seed)
    for q, v, a in zip(qs, vs, accs, strict=True):
        tau = model.inverse_dynamics(q, v, a)[rows]
        assert np.max(np.abs(tau)) > 1e-3  # a state that moves the efforts
        worst = max(worst, _relative(reg.torques(q, v, a), tau))
    return reg, worst


def test_six_axis_urdf_arm():
    """UR5 URDF: 6 rows, 60 parameters; Y π = τ of Featherstone's RNEA to 1e-12."""
    reg, err = _against_compile(load_urdf(UR5))
    assert reg.rows == [f"{j}.angle" for j in ("shoulder_pan_joint", "shoulder_lift_joint",
                                                 "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                                                 "wrist_3_joint")]
    assert len(reg.names) == 60 and reg.names[:4] == ["shoulder_link.m", "shoulder_link.mcx",
                                                      "shoulder_link.mcy", "shoulder_link.mcz"]
    assert err <= RTOL


def test_six_axis_scene_with_friction():
    """UR-like scene with viscous and Coulomb friction on every joint (72 parameters): the
    friction coefficients are read from the elements and Y π includes them."""
    mech = casmbd.load_scene(UR_LIKE)
    rng = np.random.default_rng(3)
    for joint in mech.joints:
        mech.add("joint_friction", f"{joint}_friction", joint,
                 damping=float(rng.uniform(0.1, 2.0)), friction=float(rng.uniform(0.5, 5.0)),
                 regularization=0.05)
    reg, err = _against_compile(mech, friction=("viscous", "coulomb"))
    params = reg.parameters
    assert len(params) == 72
    assert params.friction_coordinates[0].regularization == 0.05
    element = mech.forces["elbow_friction"]
    assert params.values[params.index("elbow.viscous")] == element.damping
    assert params.values[params.index("elbow.coulomb")] == element.friction
    assert err <= RTOL
    # the friction columns are the law itself: F_v q̇ and tanh(q̇ / v_s) on its own row
    q, v, a = np.zeros(6), np.linspace(-0.2, 0.3, 6), np.zeros(6)
    y = reg(q, v, a)
    k = reg.rows.index("elbow.angle")
    assert y[k, params.index("elbow.viscous")] == pytest.approx(v[k], rel=1e-15)
    assert y[k, params.index("elbow.coulomb")] == pytest.approx(np.tanh(v[k] / 0.05), rel=1e-15)
    # friction in the mechanism that π does not carry is refused, naming the element
    with pytest.raises(ModelError, match=r"shoulder_pan_friction.*friction=\("):
        joint_torque_regressor(mech, mode="vm")


def test_columns_against_other_inertial_values():
    """Each column separately: links overridden at load (mass, centre of mass, inertia) give
    a new robot whose τ is Y(old) π(new) with π in the link frames (frame="joint"); π(new)'s
    first moments are m·com of the override exactly (the link frame is the origin)."""
    rng = np.random.default_rng(11)
    links = {}
    for name in ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                 "wrist_2_link"):
        a, b, c = rng.uniform(0.01, 0.05, 3)
        tensor = np.diag([b + c, a + c, a + b])  # physical: triangle inequalities
        links[name] = {"mass": float(rng.uniform(0.5, 5.0)),
                       "com": rng.uniform(-0.1, 0.1, 3).tolist(),
                       "inertia": [*np.diag(tensor), 0.004, -0.003, 0.002]}
    old, new = load_urdf(UR5), load_urdf(UR5, links=links)
    reg = joint_torque_regressor(old, frame="joint", mode="vm")
    pi_new = standard_parameters(new, frame="joint").values
    for name, link in links.items():
        block = pi_new[reg.parameters.body_block(name)]
        assert block[0] == pytest.approx(link["mass"], rel=1e-15)
        assert np.max(np.abs(block[1:4] - link["mass"] * np.asarray(link["com"]))) <= 1e-14
    assert np.max(np.abs(pi_new - reg.parameters.values)) > 0.1  # the values did change
    model = casmbd.compile(new, mode="vm")
    qs, vs, accs = random_states(reg, 6, 4)
    for q, v, a in zip(qs, vs, accs, strict=True):
        assert _relative(reg.torques(q, v, a, pi_new), model.inverse_dynamics(q, v, a)) <= RTOL


def test_frames_give_the_same_torques():
    """frame="body" (origin at the centre of mass) and frame="joint" (at the joint) are two
    parameterisations of one robot: different π, same Y π; the parallel-axis map between
    them is inertial_parameters/centroidal."""
    mech = load_urdf(UR5)
    body = joint_torque_regressor(mech, mode="vm")
    joint = joint_torque_regressor(mech, frame="joint", mode="vm")
    blk = body.parameters.body_block("forearm_link")
    assert np.max(np.abs(body.parameters.values[blk][1:4])) == 0.0  # centroidal: m c = 0
    assert np.max(np.abs(joint.parameters.values[blk][1:4])) > 0.1
    m, c, i_g = centroidal(joint.parameters.values[blk], 3)
    assert np.max(np.abs(inertial_parameters(m, c, i_g, 3) - joint.parameters.values[blk])) \
        <= 1e-15
    for q, v, a in zip(*random_states(body, 3, 2), strict=True):
        assert _relative(joint.torques(q, v, a), body.torques(q, v, a)) <= RTOL


def test_floating_body_wrench_rows():
    """One free body with its reference point off the centre of mass: the six free-flyer rows
    (force, moment about the reference point, body axes) as casmbd.compile, 10 parameters."""
    mech = casmbd.Mechanism("free_box", gravity=(0.0, 0.0, -9.81))
    quat = np.array([0.9, 0.1, -0.3, 0.2])
    mech.add_body("box", 2.5, [0.3, 0.2, 0.25, 0.01, -0.02, 0.015], [0.1, 0.2, 0.3],
                  orientation=quat / np.linalg.norm(quat), reference_point=[0.1, -0.2, 0.05])
    reg, err = _against_compile(mech)
    assert reg.rows == ["box.vx", "box.vy", "box.vz", "box.wx", "box.wy", "box.wz"]
    assert (reg.nq, reg.nv, len(reg.names)) == (7, 6, 10)
    assert err <= RTOL


def test_floating_base_arm():
    """The UR5 on a free-flyer base: 6 wrench rows then the 6 joints, 70 parameters."""
    reg, err = _against_compile(load_urdf(UR5, floating_base=True))
    assert len(reg.rows) == 12 and len(reg.names) == 70
    assert err <= RTOL


def test_four_bar_actuated_crank():
    """Four-bar in joint coordinates, no driver, the crank angle actuated: the efforts of
    [S −C_qᵀ][τ_a; λ] = f as casmbd.compile's."""
    mech = casmbd.load_scene(FOUR_BAR)
    mech.drivers.clear()
    reg, err = _against_compile(mech, actuated=["A.angle"])
    assert reg.rows == ["A.angle"] and len(reg.names) == 12
    assert err <= RTOL


@pytest.mark.parametrize("coordinates", ["joint", "absolute", "natural"])
def test_four_bar_driver_effort_along_the_motion(coordinates):
    """The driven four-bar: the row is the driver 'crank_drive', Y π equals the driver effort
    −λ_d of casmbd.inverse_dynamics on its whole grid, in each coordinate choice (3, 9 and
    12 coordinates: the body origins, rotations and twists come from the descriptions)."""
    mech = casmbd.load_scene(FOUR_BAR)
    mech.coordinates = coordinates
    res = casmbd.inverse_dynamics(mech, 0.5, 10, mode="vm")
    reg = joint_torque_regressor(mech, coordinates=None, mode="vm")
    assert reg.rows == ["crank_drive"]
    tau = reg.stacked(res["q"], res["v"], res["a"]) @ reg.parameters.values
    assert _relative(tau, res["driver_efforts"][:, 0]) <= RTOL


def test_delta_robot_actuated_shoulders():
    """Delta robot (3-RUU) in joint coordinates (11 coordinates, 8 loop equations), the three
    shoulders actuated: 7 bodies, 70 parameters."""
    mech = delta.delta_robot(actuators=False)
    mech.coordinates = "joint"
    shoulders = ["shoulder1.angle", "shoulder2.angle", "shoulder3.angle"]
    reg, err = _against_compile(mech, actuated=shoulders, states=4)
    assert reg.rows == shoulders and len(reg.names) == 70
    assert err <= RTOL


def test_delta_robot_motor_moments_along_the_gate_path():
    """The example's mixed case (hand drivers, shoulder motors), absolute coordinates with
    Euler parameters (49 coordinates): Y π = the actuator efforts of inverse_dynamics."""
    res = delta.inverse(6, mode="vm")
    reg = joint_torque_regressor(delta.delta_robot(path=delta.gate_path), coordinates=None,
                                 mode="vm")
    assert reg.rows == ["motor1", "motor2", "motor3"] and reg.nq == 49
    tau = reg.stacked(res["q"], res["v"], res["a"]) @ reg.parameters.values
    assert _relative(tau.reshape(-1, 3), res["actuator_efforts"]) <= RTOL


def test_batch_equals_single_calls_and_compiled_equals_vm():
    """The batched Function (70 states: three chunks, the last padded) equals the per-call
    one, and the compiled C library the virtual machine (1e-14 relative)."""
    mech = load_urdf(UR5)
    vm = joint_torque_regressor(mech, friction="viscous", mode="vm")
    qs, vs, accs = random_states(vm, 70, 5)
    stacked = vm.stacked(qs, vs, accs)
    single = np.vstack([vm(q, v, a) for q, v, a in zip(qs, vs, accs, strict=True)])
    assert np.array_equal(stacked, single)
    compiled = joint_torque_regressor(mech, friction="viscous", mode="compiled")
    assert _relative(compiled.stacked(qs, vs, accs), stacked) <= 1e-14


def test_refusals_name_the_element():
    """A spring is not linear in π; unknown laws, frames and shapes are named errors."""
    mech = casmbd.load_scene(FOUR_BAR)
    mech.add_spring_damper("spring", "crank", "ground", [0.0, 0.2], [0.4, 0.0], 10.0, 0.3)
    with pytest.raises(ModelError, match="force 'spring'"):
        joint_torque_regressor(mech, mode="vm")
    mech = casmbd.load_scene(FOUR_BAR)
    mech.add("joint_friction", "pin", "B", mu=0.1, radius=0.01)
    with pytest.raises(ModelError, match="force 'pin' field 'mu'"):
        joint_torque_regressor(mech, mode="vm")
    arm = load_urdf(UR5)
    with pytest.raises(ModelError, match=r"unknown law.*stiction"):
        joint_torque_regressor(arm, friction="viscous,stiction", mode="vm")
    with pytest.raises(ModelError, match="unknown frame"):
        standard_parameters(arm, frame="world")
    with pytest.raises(ModelError, match="actuated coordinate 'x' unknown"):
        joint_torque_regressor(arm, actuated=["x"], mode="vm")
    reg = joint_torque_regressor(arm, mode="vm")
    with pytest.raises(ModelError, match="length 6"):
        reg(np.zeros(5), np.zeros(6), np.zeros(6))
    with pytest.raises(ModelError, match="shape"):
        reg.stacked(np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((2, 6)))
