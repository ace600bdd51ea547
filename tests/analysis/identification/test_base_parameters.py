"""Base parameters by QR with column pivoting (casmbd.analysis.identification.base_parameters).

Closed-form counts (derivation in docs/identification.md, "The regressor and base
parameters"): the planar 2R arm, parameters about the joints, has 4 base inertial parameters
in a horizontal plane (ZZ1 + l1² m2, MX2, MY2, ZZ2) and 6 in a vertical plane (with MX1 +
l1 m2 and MY1); the four-bar 3 + 3 + 3 − 1 = 8; the UR-type 6R arm 60 − 6·3 − 6 = 36
(Gautier & Khalil's rules: M, MZ and YY of every link regrouped, link 1 on a vertical axis
keeping only its ZZR), each with 2 friction parameters per joint more.  Y_b π_b = Y π at
fresh random states to 1e-12 on the arm, the four-bar, the Delta robot and a floating body.
"""

from __future__ import annotations

import importlib.util
import pathlib
import sys

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.analysis.identification.base_parameters import (
    RANK_TOLERANCE,
    base_parameters,
    random_states,
)
from casmbd.analysis.identification.regressor import joint_torque_regressor
from casmbd.errors import ModelError
from casmbd.io.urdf import load_urdf

ROOT = pathlib.Path(__file__).resolve().parents[3]
UR5 = ROOT / "tests" / "scenes" / "ur5_arm.urdf"
UR_LIKE = ROOT / "tests" / "scenes" / "ur_like.toml"
FOUR_BAR = ROOT / "examples" / "four_bar.toml"
#: Y_b π_b against Y π, relative to the largest effort
RTOL = 1e-12
#: link 1 of the planar arm (joint to joint)
L1 = 0.5

_spec = importlib.util.spec_from_file_location("delta_robot_example",
                                               ROOT / "examples" / "delta_robot.py")
delta = sys.modules.setdefault(_spec.name, importlib.util.module_from_spec(_spec))
_spec.loader.exec_module(delta)

_cache = private_cache("cache_base_parameters", scope="module")


def planar_2r(gravity: bool) -> casmbd.Mechanism:
    """Two links in the plane, joints at (0, 0) and (L1, 0), link 1's body x axis from joint to
    joint; centres of mass off the links' lines (so that no first moment vanishes by
    symmetry)."""
    mech = casmbd.Mechanism("arm2r", dimension=2, gravity=(0.0, -9.81 if gravity else 0.0))
    mech.add_body("link1", 2.0, 0.05, [0.22, 0.03], angle=0.0)  # body x along the link
    mech.add_body("link2", 1.2, 0.02, [L1 + 0.18, -0.02], angle=-0.2)
    mech.add_revolute("shoulder", "ground", "link1", [0.0, 0.0])
    mech.add_revolute("elbow", "link1", "link2", [L1, 0.0])
    return mech


def _check_reconstruction(reg, base, seed: int = 99, states: int = 8) -> None:
    """Y_b π_b = Y π at fresh states (not those of the QR)."""
    qs, vs, accs = random_states(reg, states, seed)
    full = reg.stacked(qs, vs, accs)
    tau = full @ reg.parameters.values
    assert np.max(np.abs(base.regressor(full) @ base.values() - tau)) <= RTOL * np.max(
        np.abs(tau))


@pytest.mark.parametrize(("gravity", "friction", "count"), [
    (False, (), 4), (True, (), 6), (True, ("viscous", "coulomb"), 10)])
def test_planar_2r_closed_form_count(gravity, friction, count):
    """4 (horizontal), 6 (vertical), + 2 friction parameters per joint."""
    reg = joint_torque_regressor(planar_2r(gravity), friction, frame="joint", mode="vm")
    assert len(reg.names) == 8 + 2 * len(friction)
    base = base_parameters(reg)
    assert base.rank == count
    assert base.gap > 1e8  # kept and dropped |R_ii| far apart: the count is not a tolerance
    _check_reconstruction(reg, base)
    # the regrouped inertia of link 1 about the shoulder: ZZ1 + l1² m2 (Khalil & Dombre)
    row = base.names.index("link1.Izz") if "link1.Izz" in base.names else base.names.index(
        "link2.m")
    k = base.K[row]
    assert k[reg.parameters.index("link1.Izz")] == pytest.approx(1.0, abs=1e-12)
    assert k[reg.parameters.index("link2.m")] == pytest.approx(L1**2, abs=1e-12)
    assert np.count_nonzero(np.abs(k) > 1e-12) == 2
    assert "link1.m" not in base.names  # the mass of link 1 never acts
    if gravity:
        row = next(i for i, e in enumerate(base.expressions) if "link1.mcx" in e)
        # MX1 + l1 m2 (the elbow on link 1's x axis); MY1 alone
        assert base.K[row, reg.parameters.index("link2.m")] == pytest.approx(L1, abs=1e-12)
        row = next(i for i, e in enumerate(base.expressions) if "link1.mcy" in e)
        assert np.count_nonzero(np.abs(base.K[row]) > 1e-12) == 1


@pytest.mark.parametrize(("arm", "friction", "count"), [
    ("ur_like", (), 36), ("ur_like", ("viscous", "coulomb"), 48), ("ur5_urdf", (), 36)])
def test_ur_type_arm_count(arm, friction, count):
    """36 base inertial parameters (+ 12 friction) of the UR-type arm."""
    mech = casmbd.load_scene(UR_LIKE) if arm == "ur_like" else load_urdf(UR5)
    reg = joint_torque_regressor(mech, friction, mode="vm")
    base = base_parameters(reg)
    assert base.rank == count and base.gap > 1e8
    assert base.tolerance == RANK_TOLERANCE
    # K has the identity on the base columns; the nominal π_b is K π
    assert np.array_equal(base.K[:, base.indices], np.eye(base.rank))
    assert np.array_equal(base.values(), base.K @ reg.parameters.values)
    _check_reconstruction(reg, base)
    # another set of random states finds the same number and the same space
    other = base_parameters(reg, seed=7, samples=40)
    assert other.rank == count
    stacked = np.vstack([base.K, other.K])
    assert np.linalg.matrix_rank(stacked, tol=1e-8 * np.abs(stacked).max()) == count


def test_closed_chains_and_floating_body():
    """Y_b π_b = Y π on the four-bar (driver effort), the Delta robot (shoulders actuated,
    joint coordinates) and a floating body (all 10 parameters identifiable)."""
    four_bar = joint_torque_regressor(casmbd.load_scene(FOUR_BAR), mode="vm")
    base = base_parameters(four_bar)
    # 3 + 3 + 3 − 1 = 8: crank and rocker about their ground pins (ZZ, MX, MY each; their
    # masses never act), the coupler about B (its mass a point mass of the crank), less its
    # first moment along BC (point masses at C on the rocker and at B on the crank)
    assert base.rank == 8 and base.gap > 1e8
    _check_reconstruction(four_bar, base)

    mech = delta.delta_robot(actuators=False)
    mech.coordinates = "joint"
    reg = joint_torque_regressor(mech, actuated=["shoulder1.angle", "shoulder2.angle",
                                                 "shoulder3.angle"], mode="vm")
    base = base_parameters(reg)
    assert 0 < base.rank < 70 and base.gap > 1e8
    _check_reconstruction(reg, base, states=4)

    free = casmbd.Mechanism("free_box", gravity=(0.0, 0.0, -9.81))
    free.add_body("box", 2.5, [0.3, 0.2, 0.25, 0.01, -0.02, 0.015], [0.1, 0.2, 0.3],
                  reference_point=[0.1, -0.2, 0.05])
    reg = joint_torque_regressor(free, mode="vm")
    base = base_parameters(reg)
    assert base.rank == 10
    _check_reconstruction(reg, base)


def test_base_regressor_function_and_errors():
    """The symbolic Y_b(q, v, a) equals the base columns of Y; bad options are named."""
    reg = joint_torque_regressor(planar_2r(True), mode="vm")
    base = base_parameters(reg)
    qs, vs, accs = random_states(reg, 3, 1)
    for q, v, a in zip(qs, vs, accs, strict=True):
        assert np.array_equal(np.asarray(base.symbolic(q, v, a), float),
                              base.regressor(reg(q, v, a)))
    with pytest.raises(ModelError, match="tolerance"):
        base_parameters(reg, tolerance=2.0)
    with pytest.raises(ModelError, match="samples"):
        base_parameters(reg, samples=0)
    with pytest.raises(ModelError, match="apply when a mechanism is given"):
        base_parameters(reg, friction="viscous")
    # a mechanism directly: its regressor built with the options
    assert base_parameters(planar_2r(False), mode="vm", frame="joint").rank == 4
