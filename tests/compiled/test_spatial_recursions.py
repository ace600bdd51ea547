"""Featherstone's recursions in local body frames against the global-component tree path.

:mod:`casmbd.compiled.spatial_recursions` writes the per-call Functions of a tree of
revolute and prismatic joints (M by the composite-rigid-body algorithm, τ and b by
Newton–Euler, q̈ by the articulated-body algorithm, the world placements of every frame and
the frame Jacobians) from constant joint placements and constant spatial inertias in body
frames.  Each is compared, at random states, with the former path
(``robot.SPATIAL_RECURSIONS = False``: the recursions on :mod:`casmbd.system.tree`'s global
kinematics, themselves checked against dense formulations in test_tree_recursions.py) to
1e-12 relative to the largest entry, on the branched 12-joint tree with a prismatic lift,
skew axes, fixed links and tool markers, a UR5 and a 7-axis arm with a gripper.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_tree_recursions import tree_urdf

import casmbd
from casmbd.compiled import robot
from casmbd.compiled.spatial_recursions import unsupported
from casmbd.system.equations import System

TOL = 1e-12
SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _mechanism(which: str, tmp_path):
    if which == "tree":
        path = tmp_path / "tree.urdf"
        path.write_text(tree_urdf())
    else:
        path = SCENES / which
    return casmbd.load_urdf(path)


def _close(new, old) -> float:
    new, old = np.asarray(new), np.asarray(old)
    assert new.shape == old.shape
    return float(np.max(np.abs(new - old)) / max(1.0, float(np.max(np.abs(old)))))


@pytest.mark.parametrize("which", ["tree", "ur5_arm.urdf", "arm7_gripper.urdf"])
def test_spatial_recursions_match_tree_path(which, tmp_path, monkeypatch):
    mech = _mechanism(which, tmp_path)
    assert unsupported(System(mech, coordinates="joint")) is None
    new = casmbd.compile(mech)
    monkeypatch.setattr(robot, "SPATIAL_RECURSIONS", False)
    old = casmbd.compile(mech, mode="vm")
    assert new.frame_names == old.frame_names
    rng = np.random.default_rng(7)
    n = new.nq
    for _ in range(3):
        q, v, a, tau = (rng.uniform(-1.5, 1.5, n) for _ in range(4))
        assert _close(new.mass_matrix(q), old.mass_matrix(q)) < TOL
        assert _close(new.bias_forces(q, v), old.bias_forces(q, v)) < TOL
        assert _close(new.inverse_dynamics(q, v, a), old.inverse_dynamics(q, v, a)) < TOL
        assert _close(new.forward_dynamics(q, v, tau),
                      old.forward_dynamics(q, v, tau)) < TOL
        for got, want in zip(new.forward_kinematics(q), old.forward_kinematics(q)):
            assert _close(got, want) < TOL
        for frame in new.frame_names:
            assert _close(new.jacobian(q, frame), old.jacobian(q, frame)) < TOL
    qs, vs, ts = (rng.uniform(-1, 1, (5, n)) for _ in range(3))
    assert _close(new.forward_dynamics_batch(qs, vs, ts),
                  old.forward_dynamics_batch(qs, vs, ts)) < TOL
    assert _close(new.inverse_dynamics_batch(qs, vs, ts),
                  old.inverse_dynamics_batch(qs, vs, ts)) < TOL


def test_spatial_recursions_leave_other_trees_to_the_tree_path(tmp_path):
    """Floating roots and applied forces other than gravity (joint damping) are named."""
    mech = casmbd.load_urdf(SCENES / "arm7_gripper.urdf", floating_base=True)
    assert unsupported(System(mech, coordinates="joint")) is not None  # the free-flyer root
    mech = casmbd.load_urdf(SCENES / "ur5_arm.urdf", damping=True)
    assert "applied forces" in unsupported(System(mech, coordinates="joint"))


def test_spatial_recursions_with_a_rigid_tree_joint_and_skew_gravity(monkeypatch):
    """A tree joint of kind 'rigid' (a weld kept as its own body), skew joint axes, general
    body orientations and gravity off the z axis: the same quantities to 1e-12."""
    mech = casmbd.Mechanism("welded", dimension=3, gravity=[0.3, -0.2, -9.81])
    mech.add_body("a", 2.0, [0.1, 0.2, 0.15, 0.01, -0.02, 0.005], [0.3, 0.1, 0.2],
                  euler_zxz=[0.3, 0.5, -0.2])
    mech.add_body("b", 1.5, [0.05, 0.07, 0.06], [0.6, 0.2, 0.1], euler_zxz=[-0.4, 0.2, 0.9])
    mech.add_body("c", 0.8, [0.02, 0.03, 0.025, 0.001, 0.0, 0.002], [0.9, 0.0, 0.3],
                  euler_zxz=[1.0, -0.3, 0.1])
    mech.add("revolute", "j1", "ground", "a", [0.0, 0.0, 0.2], [0.2, 0.3, 0.9])
    mech.add("rigid", "weld", "a", "b")
    mech.add("prismatic", "j2", "b", "c", [0.7, 0.1, 0.2], [0.6, -0.2, 0.3])
    assert unsupported(System(mech, coordinates="joint")) is None
    new = casmbd.compile(mech, mode="vm")
    monkeypatch.setattr(robot, "SPATIAL_RECURSIONS", False)
    old = casmbd.compile(mech, mode="vm")
    rng = np.random.default_rng(2)
    for _ in range(3):
        q, v, a = (rng.uniform(-1, 1, new.nq) for _ in range(3))
        assert _close(new.mass_matrix(q), old.mass_matrix(q)) < TOL
        assert _close(new.inverse_dynamics(q, v, a), old.inverse_dynamics(q, v, a)) < TOL
        assert _close(new.forward_dynamics(q, v, a), old.forward_dynamics(q, v, a)) < TOL
        for got, want in zip(new.forward_kinematics(q), old.forward_kinematics(q)):
            assert _close(got, want) < TOL
        for frame in new.frame_names:
            assert _close(new.jacobian(q, frame), old.jacobian(q, frame)) < TOL
