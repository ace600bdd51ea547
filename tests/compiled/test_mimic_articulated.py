"""The articulated-body recursion with substituted mimic followers (issue 34, item 2).

A leader and followers whose joints share one parent link (a gripper's fingers) are one joint
of one coordinate on several children (:meth:`SpatialTree.forward_dynamics
<casmbd.compiled.spatial_recursions.SpatialTree.forward_dynamics>`).  On a 3-axis arm with a
gripper written here — a prismatic leader finger with a child, its mirror follower (ratio −1,
offset 0.01 m), a revolute follower of ratio 2 (offset 0.1 rad) on the same leader, and a
coupled pair of root joints (the group under the ground) — q̈ at random states is compared
with (1) the dense LDLᵀ of the same tree's M and b (1e-12 relative), (2) the former global-
component tree path (``robot.SPATIAL_RECURSIONS = False``, its own M and dense solve: 1e-12)
and (3) the gear kept as a constraint equation (``substitute_gears = False``, 9 coordinates,
the KKT solve, the followers at r q_l + δ: 1e-9).  A follower on another parent than its
leader's keeps the dense path (same numbers as before, 1e-12).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import casmbd
from casmbd.compiled import robot
from casmbd.compiled.robot import ldl_solve
from casmbd.compiled.spatial_recursions import SpatialTree
from casmbd.system.equations import System

TOL = 1e-12


def _link(name: str, mass: float, com, inertia) -> str:
    ixx, iyy, izz, ixy, ixz, iyz = inertia
    return (f'<link name="{name}"><inertial><origin xyz="{com[0]} {com[1]} {com[2]}" '
            f'rpy="0.1 -0.2 0.3"/><mass value="{mass}"/><inertia ixx="{ixx}" ixy="{ixy}" '
            f'ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/></inertial></link>')


def _joint(name, kind, parent, child, xyz, axis, mimic=None) -> str:
    limit = '<limit lower="-3" upper="3" effort="100" velocity="5"/>' if kind != "fixed" \
        else ""
    ax = f'<axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>' if kind != "fixed" else ""
    mim = "" if mimic is None else (f'<mimic joint="{mimic[0]}" multiplier="{mimic[1]}" '
                                    f'offset="{mimic[2]}"/>')
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" '
            f'rpy="0.1 0.2 -0.1"/>{ax}{limit}{mim}</joint>')


def gripper_urdf(non_sibling: bool = False) -> str:
    """A 3-axis arm with a gripper and a coupled root pair; ``non_sibling`` adds a follower of
    the second arm joint at the leader finger's tip (another parent than its leader's)."""
    rng = np.random.default_rng(34)
    links, joints = ['<link name="base"/>'], []

    def body(name, parent, kind, axis, xyz, mimic=None):
        d = rng.uniform(0.03, 0.05, 3)
        links.append(_link(name, float(rng.uniform(0.2, 3.0)), rng.uniform(-0.05, 0.05, 3),
                           (*d, *rng.uniform(-0.002, 0.002, 3))))
        joints.append(_joint(f"{name}_joint", kind, parent, name, xyz, axis, mimic))

    body("arm1", "base", "revolute", (0, 0, 1), (0.0, 0.0, 0.3))
    body("arm2", "arm1", "revolute", (0, 1, 0), (0.0, 0.05, 0.3))
    body("arm3", "arm2", "revolute", (0, 0.6, 0.8), (0.02, 0.0, 0.4))
    body("hand", "arm3", "fixed", (0, 0, 1), (0.0, 0.0, 0.1))
    body("finger_l", "hand", "prismatic", (0, 1, 0), (0.0, 0.02, 0.05))
    body("finger_r", "hand", "prismatic", (0, 1, 0), (0.0, -0.02, 0.05),
         ("finger_l_joint", -1.0, 0.01))
    body("thumb", "hand", "revolute", (1, 0, 0), (0.03, 0.0, 0.04),
         ("finger_l_joint", 2.0, 0.1))
    body("tip", "finger_l", "revolute", (0, 0, 1), (0.0, 0.01, 0.03))
    # two root joints coupled (the group's parent is the ground)
    body("wheel_a", "base", "revolute", (0, 1, 0), (0.2, 0.1, 0.0))
    body("wheel_b", "base", "revolute", (0, 1, 0), (0.2, -0.1, 0.0),
         ("wheel_a_joint", 0.5, -0.2))
    if non_sibling:
        body("pad", "finger_l", "revolute", (1, 0, 0), (0.0, 0.0, 0.02),
             ("arm2_joint", 0.7, 0.05))
    return '<robot name="gripper">' + "".join(links + joints) + "</robot>"


def _mechanism(non_sibling: bool = False):
    return casmbd.loads_urdf(gripper_urdf(non_sibling), "gripper.urdf")


def _functions(system: System):
    """(q̈ by the spatial ABA or None, q̈ by the dense LDLᵀ of the same tree's M and b)."""
    q, v, p = system.q, system.v, system.p
    tau = ca.SX.sym("tau", system.nq)
    tree = SpatialTree(system, q)
    bias = tree.inverse_dynamics(v, ca.SX.zeros(system.nq))
    dense = ca.Function("dense", [q, v, tau, p], [ldl_solve(tree.mass_matrix(), tau - bias)])
    aba = (ca.Function("aba", [q, v, tau, p], [tree.forward_dynamics(v, tau)])
           if tree.articulated else None)
    return tree, aba, dense


def _rel(x, y) -> float:
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    return float(np.max(np.abs(x - y)) / np.max(np.abs(y)))


def _states(n: int, count: int = 4, seed: int = 3):
    rng = np.random.default_rng(seed)
    return [tuple(rng.uniform(-1.0, 1.0, n) for _ in range(3)) for _ in range(count)]


def test_sibling_followers_take_the_articulated_recursion():
    system = System(_mechanism(), coordinates="joint")
    tree, aba, dense = _functions(system)
    assert tree.mimic and tree.articulated
    groups = sorted(sorted(g) for g in tree.groups.values() if len(g) > 1)
    assert groups == [["finger_l", "finger_r", "thumb"], ["wheel_a", "wheel_b"]]
    assert system.nq == 6 and system.nc == 0
    for q, v, tau in _states(system.nq):
        assert _rel(aba(q, v, tau, system.parameter_values),
                    dense(q, v, tau, system.parameter_values)) < TOL


def test_compiled_model_uses_the_grouped_recursion(monkeypatch):
    """casmbd.compile writes q̈ by the grouped ABA; it agrees with the former global-component
    path (its own M, b and dense LDLᵀ)."""
    calls = []
    original = SpatialTree.forward_dynamics

    def spy(self, v, tau):
        calls.append(self.articulated)
        return original(self, v, tau)

    monkeypatch.setattr(SpatialTree, "forward_dynamics", spy)
    new = casmbd.compile(_mechanism(), mode="vm")
    assert calls == [True]
    monkeypatch.setattr(robot, "SPATIAL_RECURSIONS", False)
    old = casmbd.compile(_mechanism(), mode="vm")
    assert new.coordinate_names == old.coordinate_names
    states = _states(new.nq, seed=8)
    for q, v, tau in states:
        assert _rel(new.forward_dynamics(q, v, tau), old.forward_dynamics(q, v, tau)) < TOL
    batch = new.forward_dynamics_batch(*(np.array(x) for x in zip(*states)))
    for k, (q, v, tau) in enumerate(states):
        assert _rel(batch[k], old.forward_dynamics(q, v, tau)) < TOL


def test_grouped_recursion_against_the_gear_constraint():
    """The followers as gear equations (q_f = r q_l + δ kept as constraints, KKT solve): the
    leaders' q̈ equal the substituted model's, the followers' are r q̈_l."""
    sub = casmbd.compile(_mechanism(), mode="vm")
    mech = _mechanism()
    mech.substitute_gears = False
    con = casmbd.compile(mech, mode="vm")
    assert con.nc == 3 and con.nq == 9
    names = [n.rpartition(".")[0] for n in sub.coordinate_names]
    cnames = [n.rpartition(".")[0] for n in con.coordinate_names]
    follow = {"finger_r_joint": ("finger_l_joint", -1.0, 0.01),
              "thumb_joint": ("finger_l_joint", 2.0, 0.1),
              "wheel_b_joint": ("wheel_a_joint", 0.5, -0.2)}
    for q, v, tau in _states(sub.nq, seed=11):
        qc, vc, tc = np.zeros(9), np.zeros(9), np.zeros(9)
        for k, name in enumerate(cnames):
            lead, r, d = follow.get(name, (name, 1.0, 0.0))
            j = names.index(lead)
            qc[k], vc[k] = r * q[j] + d, r * v[j]
            tc[k] = tau[j] if name not in follow else 0.0
        mine = sub.forward_dynamics(q, v, tau)
        ref = con.forward_dynamics(qc, vc, tc)
        expect = np.array([follow.get(n, (n, 1.0))[1] * mine[names.index(
            follow.get(n, (n,))[0])] for n in cnames])
        assert _rel(expect, ref) < 1e-9


def test_non_sibling_follower_keeps_the_dense_path(monkeypatch):
    system = System(_mechanism(non_sibling=True), coordinates="joint")
    tree, aba, dense = _functions(system)
    assert tree.mimic and not tree.articulated and aba is None
    with pytest.raises(ValueError, match="another parent"):
        tree.forward_dynamics(system.v, ca.SX.sym("tau", system.nq))
    new = casmbd.compile(_mechanism(non_sibling=True), mode="vm")
    monkeypatch.setattr(robot, "SPATIAL_RECURSIONS", False)
    old = casmbd.compile(_mechanism(non_sibling=True), mode="vm")
    for q, v, tau in _states(system.nq, seed=5):
        ref = dense(q, v, tau, system.parameter_values)
        assert _rel(new.forward_dynamics(q, v, tau), ref) < TOL
        assert _rel(old.forward_dynamics(q, v, tau), ref) < TOL
