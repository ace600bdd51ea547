"""Floating bases against Pinocchio's free-flyer (issue 34, item 1).

Robots of example-robot-data loaded with ``casmbd.load_urdf(path, floating_base=True)`` and by
``pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())``.  The conventions map
exactly (:mod:`casmbd.compiled.free_flyer`): Pinocchio's q = (x, y, z, qx, qy, qz, qw, joints)
is casmbd's (x, y, z, e0, e1, e2, e3, joints) with the scalar part last, and both velocities
are the root's body-frame (``LOCAL``) linear and angular velocity, then the joint rates.  At
random states (a random unit quaternion, joint angles in ±2 rad, v and a in ±2): every link
frame (1e-12 m, rotation 1e-12), M against ``crba`` (1e-12 relative to max |M|), τ against
``rnea`` (1e-10 relative), v̇ against ``aba`` (1e-9 relative, times cond(M)/1e4 when M is
worse conditioned), each frame's Jacobian against ``getFrameJacobian(…,
LOCAL_WORLD_ALIGNED)`` (1e-12 relative) and ``integrate``/``difference`` against
Pinocchio's (1e-12).  Skipped without Pinocchio or example-robot-data.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import casmbd  # noqa: E402
from benchmarks.robots_vs_pinocchio import _frame_errors, robots_dir  # noqa: E402

ROOT = robots_dir()
pytestmark = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed")

#: a quadruped and a small biped (fast to compile); the long list is in the benchmark
ROBOTS = ("solo_description/robots/solo12.urdf", "bolt_description/robots/bolt.urdf")
TOL = {"fk": 1e-12, "rot": 1e-12, "crba": 1e-12, "rnea": 1e-10, "aba": 1e-9, "J": 1e-12,
       "integrate": 1e-12, "difference": 1e-12}


def _rel(x, y) -> float:
    return float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300))


def _models(path):
    pm = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = casmbd.load_urdf(path, floating_base=True)
    ours = casmbd.compile(mech, mode="vm")
    return pm, ours


def _mapping(pm, ours):
    """casmbd q ↦ Pinocchio q, and the permutation of v (casmbd → Pinocchio)."""
    block = ours.velocity_map.blocks
    assert len(block) == 1 and block[0].q == 0 and block[0].v == 0
    joints = ours.coordinate_names[7:]
    names = [pm.names[j] for j in range(2, pm.njoints)]
    index = {n.rpartition(".")[0]: k for k, n in enumerate(joints)}
    assert sorted(index) == sorted(names), (joints, names)
    order = [(index[pm.names[j]], pm.joints[j].nq) for j in range(2, pm.njoints)]

    def to_pin(q):
        out = [*q[0:3], *q[4:7], q[3]]
        for k, nq in order:
            out += [np.cos(q[7 + k]), np.sin(q[7 + k])] if nq == 2 else [q[7 + k]]
        return np.array(out)
    perm = np.concatenate([np.arange(6), 6 + np.array([k for k, _ in order], dtype=int)])
    return to_pin, perm


def _random_state(rng, ours):
    quat = rng.normal(size=4)
    q = np.concatenate([rng.uniform(-1, 1, 3), quat / np.linalg.norm(quat),
                        rng.uniform(-2, 2, ours.nq - 7)])
    return q, rng.uniform(-2, 2, ours.nv), rng.uniform(-2, 2, ours.nv)


def compare(path, states: int = 3, seed: int = 0) -> dict:
    """Largest errors of casmbd against Pinocchio's free-flyer model at random states."""
    pm, ours = _models(path)
    assert ours.nq == pm.nq and ours.nv == pm.nv and ours.nc == 0
    to_pin, perm = _mapping(pm, ours)
    data = pm.createData()
    rng = np.random.default_rng(seed)
    worst = dict.fromkeys(TOL, 0.0)
    frames = {f.name: k for k, f in enumerate(pm.frames) if f.type == pin.FrameType.BODY}
    n_body = len(ours.numeric.body_names)
    for _ in range(states):
        q, v, a = _random_state(rng, ours)
        qp, vp, ap = to_pin(q), v[perm], a[perm]
        fk = ours.forward_kinematics(q)
        _frame_errors(worst, ours, fk, pm, data, qp)
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        m_ours = ours.mass_matrix(q)[np.ix_(perm, perm)]
        worst["crba"] = max(worst["crba"], _rel(m_ours, m_pin))
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["rnea"] = max(worst["rnea"], _rel(ours.inverse_dynamics(q, v, a)[perm], tau))
        tau_ours = np.empty(ours.nv)
        tau_ours[perm] = tau
        scale = max(1.0, np.linalg.cond(m_pin) / 1e4)
        worst["aba"] = max(worst["aba"], _rel(ours.forward_dynamics(q, v, tau_ours)[perm],
                                              pin.aba(pm, data, qp, vp, tau)) / scale)
        pin.computeJointJacobians(pm, data, qp)
        pin.updateFramePlacements(pm, data)
        for i, name in enumerate(ours.frame_names):
            if name not in frames:
                continue
            fid = frames[name]
            jac = pin.getFrameJacobian(pm, data, fid, pin.LOCAL_WORLD_ALIGNED)
            if i < n_body:  # casmbd's body frame is at the centre of mass: shift the point
                d = fk[0][i] - data.oMf[fid].translation
                skew = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
                jac = np.vstack([jac[:3] - skew @ jac[3:], jac[3:]])
            worst["J"] = max(worst["J"], _rel(ours.jacobian(q, name)[:, perm], jac))
        q1 = ours.integrate(q, v, 0.3)
        worst["integrate"] = max(worst["integrate"], float(np.max(np.abs(
            to_pin(q1) - pin.integrate(pm, qp, 0.3 * vp)))))
        dv = ours.difference(q, q1)
        worst["difference"] = max(worst["difference"], float(np.max(np.abs(
            dv[perm] - pin.difference(pm, qp, to_pin(q1))))))
    return worst


@pytest.mark.parametrize("robot", ROBOTS)
def test_floating_base_agrees_with_pinocchio_free_flyer(robot):
    worst = compare(ROOT / robot, states=3, seed=3)
    assert worst["frames"] >= 5
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
