"""The Franka Panda as shipped (example-robot-data, fingers coupled by ``<mimic>``) against
Pinocchio's mimic model (issue 34, item 2).

``pinocchio.buildModelFromUrdf(path, mimic=True)`` (``JointModelMimic``: the follower finger
has no coordinate) against :func:`casmbd.load_urdf` in joint coordinates, where the follower is
substituted (q_f = r q_l + δ, :mod:`casmbd.system.tree`): both have the 8 independent
coordinates, casmbd no constraint equation, so the per-call API runs its compiled tree path.
At random states: every link frame (1e-12 m, rotation 1e-12), M against ``crba`` (1e-12
relative), τ against ``rnea`` (1e-10) and q̈ against M⁻¹ (τ − nle) from ``crba`` and
``nonLinearEffects`` (1e-9; Pinocchio 4.1's ``aba`` refuses mimic joints) — through
``benchmarks.robots_vs_pinocchio.check_coupled`` — and the compiled batch methods against a
Pinocchio loop (same tolerances).  Skipped without Pinocchio or example-robot-data.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import casmbd  # noqa: E402
from benchmarks.robots_vs_pinocchio import TOLERANCES, check_coupled, robots_dir  # noqa: E402

ROOT = robots_dir()
pytestmark = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed")
PANDA = "panda_description/urdf/panda.urdf"


def test_panda_mimic_agrees_with_pinocchio():
    rec = check_coupled(ROOT / PANDA, states=3, seed=1, mode="vm")
    assert "errors" in rec, rec.get("error")
    assert rec["followers"] == "substituted" and rec["nc"] == 0 and rec["nq"] == 8
    assert rec["coupled"] == ["panda_finger_joint2"]
    assert rec["frames"] >= 9  # every moving link frame was compared
    for key, tol in TOLERANCES.items():
        assert rec["errors"][key] <= tol, (key, rec["errors"])
    assert rec["passed"]


def test_panda_batch_agrees_with_a_pinocchio_loop():
    """The compiled ``*_batch`` methods (``Function.map``: no Python loop per sample) of the
    coupled Panda against Pinocchio's ``rnea`` and M⁻¹ (τ − nle) per sample."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ours = casmbd.compile(casmbd.load_urdf(ROOT / PANDA), mode="vm")
    assert ours.nc == 0 and "robot_fd_batch" in ours._calls
    pm = pin.buildModelFromUrdf(str(ROOT / PANDA), mimic=True)
    data = pm.createData()
    names = [n.rpartition(".")[0] for n in ours.coordinate_names]
    perm = np.array([names.index(pm.names[j]) for j in range(1, pm.njoints)
                     if pm.joints[j].nq > 0])
    assert sorted(perm) == list(range(8))
    rng = np.random.default_rng(5)
    n = 70  # two chunks of the mapped Functions
    q, v, w = (rng.uniform(-1.0, 1.0, (n, 8)) for _ in range(3))
    q[:, names.index("panda_finger_joint1")] *= 0.04
    fd = ours.forward_dynamics_batch(q, v, w)
    inv = ours.inverse_dynamics_batch(q, v, w)
    for k in range(0, n, 7):
        qp, vp, wp = q[k][perm], v[k][perm], w[k][perm]
        tau = pin.rnea(pm, data, qp, vp, wp)
        assert np.max(np.abs(inv[k][perm] - tau)) <= TOLERANCES["rnea"] * np.max(np.abs(tau))
        m = pin.crba(pm, data, qp)
        m = np.triu(m) + np.triu(m, 1).T
        ref = np.linalg.solve(m, wp - pin.nonLinearEffects(pm, data, qp, vp))
        assert np.max(np.abs(fd[k][perm] - ref)) <= TOLERANCES["aba"] * np.max(np.abs(ref))
