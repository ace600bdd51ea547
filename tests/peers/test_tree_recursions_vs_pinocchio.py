"""The per-call tree recursions against Pinocchio on a branched tree (issue 34, item 3).

The 12-joint branched tree of tests/compiled/test_tree_recursions.py (prismatic lift, two
skew-axis arms, a head, merged fixed links, tool frames), read by :func:`casmbd.load_urdf` and
by ``pinocchio.buildModelFromXML`` from the same URDF text.  At random states: M against
``crba`` (1e-12 relative), τ against ``rnea`` (1e-10), q̈ against ``aba`` (1e-9), and the
tool frames' Jacobians against ``computeFrameJacobian`` in ``LOCAL_WORLD_ALIGNED`` (1e-12) —
the tolerances of the example-robot-data sweep.  Skipped without Pinocchio.
"""

from __future__ import annotations

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import casmbd  # noqa: E402
from benchmarks.robots_vs_pinocchio import _pin_configuration  # noqa: E402
from tests.compiled.test_tree_recursions import tree_urdf  # noqa: E402


def _rel(x, y) -> float:
    return float(np.max(np.abs(x - y)) / np.max(np.abs(y)))


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    text = tree_urdf()
    path = tmp_path_factory.mktemp("tree") / "tree12.urdf"
    path.write_text(text)
    ours = casmbd.compile(casmbd.load_urdf(path), mode="vm")
    pm = pin.buildModelFromXML(text)
    return ours, pm


def test_tree_agrees_with_pinocchio(models):
    ours, pm = models
    to_pin, perm = _pin_configuration(pm, list(ours.coordinate_names))
    data = pm.createData()
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v, a = rng.uniform(-1.5, 1.5, 12), rng.uniform(-2, 2, 12), rng.uniform(-2, 2, 12)
        qp, vp, ap = to_pin(q), v[perm], a[perm]
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        assert _rel(ours.mass_matrix(q)[np.ix_(perm, perm)], m_pin) <= 1e-12
        tau = pin.rnea(pm, data, qp, vp, ap)
        assert _rel(ours.inverse_dynamics(q, v, a)[perm], tau) <= 1e-10
        tau_ours = np.empty(12)
        tau_ours[perm] = tau
        assert _rel(ours.forward_dynamics(q, v, tau_ours)[perm],
                    pin.aba(pm, data, qp, vp, tau)) <= 1e-9
        for frame in ("l_tool", "r_tool"):
            j_pin = pin.computeFrameJacobian(pm, data, qp, pm.getFrameId(frame),
                                             pin.LOCAL_WORLD_ALIGNED)
            assert np.max(np.abs(ours.jacobian(q, frame)[:, perm] - j_pin)) <= 1e-12
