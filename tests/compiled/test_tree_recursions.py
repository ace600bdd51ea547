"""The O(N) recursions of the per-call API of a tree (issue 34, item 3).

A branched 12-joint tree (a torso on a prismatic lift, two 4-joint arms with revolute joints
about skew axes, a 1-joint head, fixed links and tool markers; written below as a URDF) is
compiled by :func:`casmbd.compile`, whose tree path now writes forward dynamics by the
articulated-body recursion, inverse dynamics by Newton–Euler, M by the composite-rigid-body
recursion and each Jacobian from the motion subspaces (casmbd.compiled.tree_dynamics).  At
random states each is checked against an independent dense computation from the same
symbolic model (1e-12 relative):

* M against the Hessian of the kinetic energy ∂²T/∂v², T = Σ ½ m |ṙ_G|² + ½ ωᵀ A J Aᵀ ω with
  ṙ_G, ω differentiated through the whole chain (no recursion);
* q̈ against the dense LDLᵀ of M (``ldl_solve``, the former tree path) of τ − b, with b the
  Lagrangian bias −Q_v − Q_e (not Newton–Euler), and the residual M q̈ + b − τ;
* τ against M a + b with the same dense b;
* every frame's Jacobian against ∂r/∂q and ∂ω/∂v by automatic differentiation of the
  frame's position and angular velocity.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import casmbd
from casmbd.compiled.robot import ldl_solve
from casmbd.model.bodies import GROUND
from casmbd.system.equations import System

TOL = 1e-12


def _link(name: str, mass: float, com, inertia) -> str:
    ixx, iyy, izz, ixy, ixz, iyz = inertia
    return (f'<link name="{name}"><inertial><origin xyz="{com[0]} {com[1]} {com[2]}" '
            f'rpy="0.1 -0.2 0.3"/><mass value="{mass}"/><inertia ixx="{ixx}" ixy="{ixy}" '
            f'ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/></inertial></link>')


def _joint(name: str, kind: str, parent: str, child: str, xyz, rpy, axis) -> str:
    limit = '<limit lower="-3" upper="3" effort="100" velocity="5"/>' if kind != "fixed" \
        else ""
    ax = f'<axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" '
            f'rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>{ax}{limit}</joint>')


def tree_urdf() -> str:
    """A 12-joint branched tree with fixed links (merged) and a frame-only tool link."""
    rng = np.random.default_rng(34)
    links = ['<link name="base"/>']
    joints = []

    def body(name, parent, kind, axis, xyz, rpy=(0.0, 0.0, 0.0)):
        mass = float(rng.uniform(0.5, 3.0))
        d = rng.uniform(0.03, 0.05, 3)
        off = rng.uniform(-0.002, 0.002, 3)
        links.append(_link(name, mass, rng.uniform(-0.05, 0.05, 3), (*d, *off)))
        joints.append(_joint(f"{name}_joint", kind, parent, name, xyz, rpy, axis))

    body("lift", "base", "prismatic", (0, 0, 1), (0.0, 0.0, 0.3))
    body("torso", "lift", "revolute", (0, 0, 1), (0.05, 0.0, 0.4), (0.0, 0.1, 0.0))
    body("head", "torso", "revolute", (0, 1, 0), (0.0, 0.0, 0.35))
    for side, y in (("l", 0.2), ("r", -0.2)):
        parent = "torso"
        axes = [(0, 1, 0), (1, 0, 0), (0, 0.6, 0.8), (0, 1, 0)]
        for k, axis in enumerate(axes):
            name = f"{side}_arm{k}"
            body(name, parent, "revolute", axis, (0.02, y if k == 0 else 0.0, 0.25 if k else 0.3),
                 (0.2 * k, -0.1, 0.3))
            parent = name
        # a fixed hand (merged into the last arm link) and a frame-only tool point
        body(f"{side}_hand", parent, "fixed", (0, 0, 1), (0.0, 0.0, 0.12))
        links.append(f'<link name="{side}_tool"/>')
        joints.append(_joint(f"{side}_tool_joint", "fixed", f"{side}_hand", f"{side}_tool",
                             (0.01, 0.0, 0.08), (0.0, 0.5, 0.0), (0, 0, 1)))
    body("sensor", "lift", "revolute", (1, 0, 0), (0.0, 0.1, 0.1))
    return '<robot name="tree12">' + "".join(links + joints) + "</robot>"


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    path = tmp_path_factory.mktemp("tree") / "tree12.urdf"
    path.write_text(tree_urdf())
    mech = casmbd.load_urdf(path)
    model = casmbd.compile(mech, mode="vm")
    return mech, model, System(mech, coordinates="joint")


def _rel(x, y) -> float:
    return float(np.max(np.abs(x - y)) / np.max(np.abs(y)))


def _dense_reference(system: System):
    """M from ∂²T/∂v², b = −Q_v − Q_e, q̈ by the dense LDLᵀ: no recursion involved."""
    q, v, p = system.q, system.v, system.p
    ctx = system.ctx
    energy = 0
    for name in system.body_names:
        mass, tensor = system._mass_inertia(system.mechanism.bodies[name])
        vel = ca.mtimes(ca.jacobian(ctx.centre_of_mass(name), q), v)
        rot = ctx.rotation(name)
        omega = ctx.angular_velocity(name)
        energy += 0.5 * mass * ca.dot(vel, vel) + 0.5 * ca.mtimes(
            [omega.T, rot, tensor, rot.T, omega])
    mass_matrix = ca.hessian(energy, v)[0]
    rest = [system.t, system.u], [ca.SX(0.0), ca.SX.zeros(system.u.numel())]
    bias = -ca.substitute([system.quadratic_velocity_forces + system.applied_forces],
                          *rest)[0]
    tau = ca.SX.sym("tau", system.nq)
    qdd = ldl_solve(ca.densify(mass_matrix), tau - bias)
    return (ca.Function("m", [q, p], [mass_matrix]), ca.Function("b", [q, v, p], [bias]),
            ca.Function("fd", [q, v, tau, p], [qdd]))


def test_the_tree_takes_the_recursive_path(tree):
    _, model, system = tree
    assert model.nq == 12 and model.nc == 0
    # the tool markers, the merged hands and the bodies are all frames
    assert {"l_tool", "r_tool"} <= set(model.frame_names)
    assert len(system.body_names) == 12


def test_recursions_match_the_dense_path(tree):
    _, model, system = tree
    m_fn, b_fn, fd_fn = _dense_reference(system)
    p = model.p
    rng = np.random.default_rng(7)
    for _ in range(4):
        q, v = rng.uniform(-1.5, 1.5, 12), rng.uniform(-2.0, 2.0, 12)
        a, tau = rng.uniform(-2.0, 2.0, 12), rng.uniform(-20.0, 20.0, 12)
        m_ref = np.array(m_fn(q, p))
        b_ref = np.array(b_fn(q, v, p)).ravel()
        m = model.mass_matrix(q)
        assert _rel(m, m_ref) <= TOL
        assert _rel(model.bias_forces(q, v), b_ref) <= TOL
        qdd = model.forward_dynamics(q, v, tau)
        assert _rel(qdd, np.array(fd_fn(q, v, tau, p)).ravel()) <= TOL
        # the equation itself, scaled by its largest term
        assert np.max(np.abs(m_ref @ qdd + b_ref - tau)) <= TOL * np.max(np.abs(tau))
        assert _rel(model.inverse_dynamics(q, v, a), m_ref @ a + b_ref) <= TOL


def test_batch_uses_the_same_recursions(tree):
    _, model, _ = tree
    rng = np.random.default_rng(8)
    q, v, tau = (rng.uniform(-1.0, 1.0, (5, 12)) for _ in range(3))
    batch = model.forward_dynamics_batch(q, v, tau)
    single = np.array([model.forward_dynamics(*s) for s in zip(q, v, tau)])
    assert _rel(batch, single) <= TOL
    inv = model.inverse_dynamics_batch(q, v, batch)
    assert _rel(inv, tau) <= 1e-11


def test_jacobians_match_differentiated_kinematics(tree):
    mech, model, system = tree
    ctx, q, v = system.ctx, system.q, system.v
    frames = [(b, None) for b in system.body_names]
    frames += [(mk.body, mk.point) for mk in mech.markers.values()]
    rng = np.random.default_rng(9)
    qs = [rng.uniform(-1.5, 1.5, 12) for _ in range(3)]
    for name, (body, point) in zip(model.frame_names, frames):
        r = ctx.position(body, point)
        omega = ctx.angular_velocity(body) if body != GROUND else ca.SX.zeros(3)
        ref = ca.Function("j", [q, system.p], [ca.vertcat(ca.jacobian(r, q),
                                                          ca.jacobian(omega, v))])
        for qk in qs:
            j_ref = np.array(ref(qk, model.p))
            j = model.jacobian(qk, name)
            assert np.max(np.abs(j - j_ref)) <= TOL * max(1.0, np.max(np.abs(j_ref))), name
    # the tool point moves with its arm only: the other arm's and the head's columns vanish
    j = model.jacobian(qs[0], "l_tool")
    cols = [k for k, c in enumerate(model.coordinate_names) if c.startswith(("r_arm", "head"))]
    assert len(cols) == 5 and np.all(j[:, cols] == 0.0)
