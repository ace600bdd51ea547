"""Floating bases against Pinocchio's free-flyer (issue 34, item 1).

The quick run of ``benchmarks/floating_base_vs_pinocchio.py`` (its docstring has the mapping
of the conventions and the measures): solo12 (a quadruped) and bolt (a small biped) loaded
with ``casmbd.load_urdf(path, floating_base=True)`` and by
``pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())``, compared at 3 random
states: every link frame (1e-12 m, rotation 1e-12), M against ``crba`` (1e-12 relative), τ
against ``rnea`` (1e-10 relative), v̇ against ``aba`` (1e-9 relative, condition-scaled), each
frame's Jacobian against ``getFrameJacobian(…, LOCAL_WORLD_ALIGNED)`` (1e-12 relative) and
``integrate``/``difference`` against Pinocchio's (1e-12).  Skipped without Pinocchio or
example-robot-data.
"""

from __future__ import annotations

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from benchmarks.floating_base_vs_pinocchio import (  # noqa: E402
    TOL,
    _mapping,
    _models,
    _random_state,
    _rel,
    compare,
)
from benchmarks.robots_vs_pinocchio import robots_dir  # noqa: E402

ROOT = robots_dir()
pytestmark = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed")

#: a quadruped and a small biped (fast to compile); the long list is in the benchmark
ROBOTS = ("solo_description/robots/solo12.urdf", "bolt_description/robots/bolt.urdf")


@pytest.mark.parametrize("robot", ROBOTS)
def test_floating_base_agrees_with_pinocchio_free_flyer(robot):
    worst = compare(ROOT / robot, states=3, seed=3)
    assert worst["frames"] >= 5 and worst["nv"] >= 12
    for key, tol in TOL.items():
        assert worst[key] <= tol, (key, worst)


def test_the_comparison_sees_the_velocity_convention():
    """The check can fail: the base velocity given in world axes (LOCAL_WORLD_ALIGNED)
    instead of Pinocchio's LOCAL body axes changes τ far beyond the tolerance."""
    pm, ours = _models(ROOT / ROBOTS[0])
    to_pin, perm = _mapping(pm, ours)
    data = pm.createData()
    q, v, a = _random_state(np.random.default_rng(7), ours)
    rot = pin.Quaternion(*to_pin(q)[[6, 3, 4, 5]]).toRotationMatrix()
    world = v.copy()
    world[0:3], world[3:6] = rot @ v[0:3], rot @ v[3:6]
    tau = ours.inverse_dynamics(q, v, a)[perm]
    assert _rel(tau, pin.rnea(pm, data, to_pin(q), v[perm], a[perm])) <= TOL["rnea"]
    assert _rel(tau, pin.rnea(pm, data, to_pin(q), world[perm], a[perm])) > 1e-3
