"""The Franka Panda as shipped (example-robot-data, fingers coupled by ``<mimic>``): q̈ by the
articulated-body recursion with the finger group (leader and follower on ``panda_hand``, one
joint of one coordinate on two children; :meth:`SpatialTree.forward_dynamics
<casmbd.compiled.spatial_recursions.SpatialTree.forward_dynamics>`) against the dense LDLᵀ of
the same tree's M and b (1e-12 relative to the largest entry) and against Pinocchio's coupled
model, M⁻¹ (τ − b) from ``crba`` and ``nonLinearEffects`` of ``buildModelFromUrdf(path,
mimic=True)`` (1e-10), at random states, per call and per batch sample.  Skipped without
Pinocchio or example-robot-data.
"""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import casmbd  # noqa: E402
from benchmarks.robots_vs_pinocchio import robots_dir  # noqa: E402
from casmbd.compiled.robot import ldl_solve  # noqa: E402
from casmbd.compiled.spatial_recursions import SpatialTree  # noqa: E402
from casmbd.system.equations import System  # noqa: E402

ROOT = robots_dir()
pytestmark = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed")
PANDA = "panda_description/urdf/panda.urdf"


def _rel(x, y) -> float:
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    return float(np.max(np.abs(x - y)) / np.max(np.abs(y)))


def test_panda_grouped_aba_against_dense_and_pinocchio():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = casmbd.load_urdf(ROOT / PANDA)
        system = System(mech, coordinates="joint")
        ours = casmbd.compile(mech, mode="vm")
    q, v, p = system.q, system.v, system.p
    tau = ca.SX.sym("tau", system.nq)
    tree = SpatialTree(system, q)
    assert tree.articulated and tree.groups[max(tree.groups)] == [
        "panda_leftfinger", "panda_rightfinger"]
    aba = ca.Function("aba", [q, v, tau, p], [tree.forward_dynamics(v, tau)])
    bias = tree.inverse_dynamics(v, ca.SX.zeros(system.nq))
    dense = ca.Function("dense", [q, v, tau, p], [ldl_solve(tree.mass_matrix(), tau - bias)])
    pm = pin.buildModelFromUrdf(str(ROOT / PANDA), mimic=True)
    data = pm.createData()
    names = [n.rpartition(".")[0] for n in ours.coordinate_names]
    perm = np.array([names.index(pm.names[j]) for j in range(1, pm.njoints)
                     if pm.joints[j].nq > 0])
    assert sorted(perm) == list(range(8))
    rng = np.random.default_rng(12)
    n = 6
    Q, V, W = (rng.uniform(-1.0, 1.0, (n, 8)) for _ in range(3))
    Q[:, names.index("panda_finger_joint1")] *= 0.04
    batch = ours.forward_dynamics_batch(Q, V, W)
    for k in range(n):
        mine = np.array(aba(Q[k], V[k], W[k], system.parameter_values)).ravel()
        assert _rel(mine, dense(Q[k], V[k], W[k], system.parameter_values)) < 1e-12
        qp, vp, wp = Q[k][perm], V[k][perm], W[k][perm]
        m = pin.crba(pm, data, qp)
        m = np.triu(m) + np.triu(m, 1).T
        ref = np.linalg.solve(m, wp - pin.nonLinearEffects(pm, data, qp, vp))
        assert _rel(mine[perm], ref) < 1e-10
        assert _rel(ours.forward_dynamics(Q[k], V[k], W[k])[perm], ref) < 1e-10
        assert _rel(batch[k][perm], ref) < 1e-10
