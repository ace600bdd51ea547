"""casmbd against Pinocchio on two arms of example-robot-data (issue 21, item 5).

The quick run of ``benchmarks/robots_vs_pinocchio.py``: the UR5 and the Franka Panda (its
mimic finger pair locked at 0 in both), read by :func:`casmbd.load_urdf` in joint coordinates
and by ``pinocchio.buildModelFromUrdf``; at random states every link frame (1e-12 m, rotation
1e-12), M against ``crba`` (1e-12 relative), τ against ``rnea`` (1e-10) and q̈ against ``aba``
(1e-9); the same in absolute coordinates (the state mapped from joint coordinates: C(q_a),
frames, Tᵀ M_a T and the body accelerations, see ``check_absolute``).  Skipped without
Pinocchio or without the ``example-robot-data`` files (the ``[bench]`` extra).
"""

from __future__ import annotations

import pytest

pytest.importorskip("pinocchio")

from benchmarks.robots_vs_pinocchio import (
    ABSOLUTE_TOLERANCES,
    QUICK,
    TOLERANCES,
    check_robot,
    robots_dir,
)

ROOT = robots_dir()
pytestmark = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed")


@pytest.mark.parametrize("robot", QUICK)
def test_arm_agrees_with_pinocchio(robot):
    rec = check_robot(ROOT / robot, states=3, seed=1, absolute=True)
    assert rec.get("casmbd"), rec.get("error")
    assert rec["compared"], rec.get("error")
    assert rec["frames"] >= rec["nv"] + 1  # every moving link and the root were compared
    for key, tol in TOLERANCES.items():
        assert rec["errors"][key] <= tol, (key, rec["errors"])
    assert rec["passed"]
    absolute = rec["absolute"]
    assert "errors" in absolute, absolute.get("error")
    assert absolute["nc"] > 0 and absolute["frames"] == rec["frames"]
    for key, tol in ABSOLUTE_TOLERANCES.items():
        assert absolute["errors"][key] <= tol, (key, absolute["errors"])


def test_a_wrong_model_is_detected():
    """The comparison can fail: a UR5 whose Pinocchio inertia is perturbed by 1e-9 relative
    is reported (M, τ beyond their tolerances)."""
    import pinocchio as pin

    path = ROOT / QUICK[0]
    original = pin.buildModelFromUrdf

    def perturbed(p, *args):
        model = original(p, *args)
        inertia = model.inertias[3]
        model.inertias[3] = pin.Inertia(inertia.mass * (1 + 1e-9), inertia.lever,
                                        inertia.inertia)
        return model

    pin.buildModelFromUrdf = perturbed
    try:
        rec = check_robot(path, states=2, seed=2)
    finally:
        pin.buildModelFromUrdf = original
    assert rec["compared"] and not rec["passed"]
    assert rec["errors"]["crba"] > TOLERANCES["crba"]
