"""casmbd's joint-torque regressor against Pinocchio's ``computeJointTorqueRegressor`` (issue 38).

The UR5 arm of ``tests/scenes/ur5_arm.urdf`` read by :func:`casmbd.load_urdf` and by
``pinocchio.buildModelFromUrdf``.  Pinocchio's regressor has 10 columns per joint, the
parameters of the joint's body about the *joint frame* (for a URDF, the child link frame) in
the order (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)
(``Inertia::toDynamicParameters``); casmbd's ``frame="joint"`` puts each body's origin at
its joint's point, axes the link frame's, in the order (…, I_xx, I_xy, I_xz, I_yy, I_yz,
I_zz).  After that permutation: the nominal parameters agree (1e-12 relative:
``dynamicParameters`` against ``standard_parameters``) and Y agrees at random states (1e-12
relative to the largest entry), on a fixed base and on a free-flyer base (its first six rows
the base wrench in the base frame, ``LOCAL``).  The continuous ``wrist_3_joint`` is
(cos θ, sin θ) in Pinocchio's q.

Skipped without Pinocchio (the ``[peers]`` extra) — a failure in CI, where
``CASMBD_REQUIRE_PEERS`` is set (``tests/peer_policy.py``).
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from conftest import private_cache  # noqa: E402

from casmbd.analysis.identification.base_parameters import random_states  # noqa: E402
from casmbd.analysis.identification.regressor import joint_torque_regressor  # noqa: E402
from casmbd.io.urdf import load_urdf  # noqa: E402

UR5 = pathlib.Path(__file__).resolve().parents[1] / "scenes" / "ur5_arm.urdf"
#: Pinocchio's position of casmbd's (m, mcx, mcy, mcz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz) in its
#: (m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz)
ORDER = np.array([0, 1, 2, 3, 4, 5, 7, 6, 8, 9])
RTOL = 1e-12

_cache = private_cache("cache_regressor_pinocchio", scope="module")


def _pinocchio_q(model, names: list[str], q: np.ndarray, floating: bool) -> np.ndarray:
    """Pinocchio's configuration from casmbd's: joint angles (cos, sin for a continuous
    joint); a free-flyer (x, y, z, qx, qy, qz, qw) from casmbd's (x, y, z, w, x, y, z)."""
    out = np.zeros(model.nq)
    if floating:  # casmbd's floating block comes first in q (the root body)
        out[:3] = q[:3]
        out[3:6], out[6] = q[4:7], q[3]
    for j in range(2 if floating else 1, model.njoints):
        k = names.index(model.names[j])
        idx, nq = model.joints[j].idx_q, model.joints[j].nq
        if nq == 2:
            out[idx:idx + 2] = np.cos(q[k]), np.sin(q[k])
        else:
            out[idx] = q[k]
    return out


def _columns(reg, model, floating: bool) -> np.ndarray:
    """casmbd's column of each of Pinocchio's."""
    cols = []
    for j in range(1, model.njoints):
        body = (reg.parameters.bodies[0] if floating and j == 1 else
                next(b for b in reg.parameters.bodies
                     if model.frames[model.getFrameId(b)].parentJoint == j))
        block = reg.parameters.body_block(body)
        cols += [block.start + int(k) for k in ORDER]
    return np.array(cols)


@pytest.mark.parametrize("floating", [False, True])
def test_regressor_agrees_with_pinocchio(floating):
    model = (pin.buildModelFromUrdf(str(UR5), pin.JointModelFreeFlyer()) if floating
             else pin.buildModelFromUrdf(str(UR5)))
    data = model.createData()
    mech = load_urdf(UR5, floating_base=floating)
    reg = joint_torque_regressor(mech, frame="joint", mode="vm")
    assert reg.floating_blocks == ([0] if floating else [])  # the base's q first
    cols = _columns(reg, model, floating)
    assert sorted(cols) == list(range(len(reg.names)))
    # the nominal parameters: Pinocchio's link inertias about the joint frames
    ours = reg.parameters.values[cols]
    theirs = np.concatenate([model.inertias[j].toDynamicParameters()
                             for j in range(1, model.njoints)])
    assert np.max(np.abs(ours - theirs)) <= RTOL * np.max(np.abs(theirs))
    names = [n.rpartition(".")[0] for n in reg.coordinate_names]
    qs, vs, accs = random_states(reg, 5, 3)
    for q, v, a in zip(qs, vs, accs, strict=True):
        y_pin = pin.computeJointTorqueRegressor(model, data, _pinocchio_q(model, names, q,
                                                                           floating), v, a)
        y = reg(q, v, a)[:, cols]
        assert y.shape == y_pin.shape
        assert np.max(np.abs(y - y_pin)) <= RTOL * np.max(np.abs(y_pin))
        # and both give Pinocchio's rnea with the nominal parameters
        tau = pin.rnea(model, data, _pinocchio_q(model, names, q, floating), v, a)
        assert np.max(np.abs(y @ theirs - tau)) <= RTOL * np.max(np.abs(tau))
