"""The articulated-body recursion of a planar revolute chain written once and folded over the
bodies: its arithmetic is generated once, whatever the number of bodies (what grows with N
is the tables of indices that select each body's columns: 0.34 MB of C at N = 1000).

:func:`casmbd.system.articulated_body.articulated_accelerations` unrolls the recursion into one
SX expression per body; a 1000-rod chain gives 5.7 MB of C that gcc compiles in 8 s at
``-O0`` (``-O1`` did not finish in 8 min).  For a serial chain of revolute joints in the plane
(body k's tree joint is a revolute to body k−1, body 0's to the ground) every body runs the
same three steps, so each pass is one small SX Function applied N times by CasADi's
``mapaccum`` (a fold: the accumulator is the parent's state going out, the child's
contribution coming in); the bodies differ only by their columns of data (design frames,
joint points, mass, inertia):

1. *kinematics* (root to tip), carrying the parent's rotation A_P, centre of mass r_P and
   rate ω_P.  With the joint's design data (:class:`casmbd.system.tree.TreeJointDescription`:
   a = J₀ − r_P0, b = r_C0 − J₀, A_P0ᵀ, A_C0) and B = A_P A_P0ᵀ,

       A_C = B R(q) A_C0,   r_C = r_P + B (a + R(q) b),   ω_C = ω_P + q̇,

   exactly :meth:`TreeJointDescription.compose` for a revolute (Δd = 0, ΔR = R(q));
   with J = r_P + B a the joint point and e = r_C − J, the motion subspace is
   S = (1, −e_y, e_x), the transport from the parent's centre of mass d = r_C − r_P, and the
   velocity-product acceleration c = J̇_C q̇ − X J̇_P q̇ = (0, −ω_P² (J − r_P) − ω_C² e);
2. *inward pass* (tip to root), carrying the child's articulated inertia and bias already
   transported to this body's centre of mass (Xᵀ I^a X, Xᵀ p^a):

       I^A = I + Σ, p^A = b + Σ, U = I^A S, D = Sᵀ U, u = −Sᵀ p^A,
       I^a = I^A − U Uᵀ / D, p^a = p^A + U u / D + I^a c;

3. *outward pass* (root to tip), carrying the parent's spatial acceleration A_P:

       A' = X A_P + c, q̈ = (u − Uᵀ A') / D, A_C = A' + S q̈,

with I = diag(J, m, m), b = (0, −m g) (gravity the only applied load: the chain has no force
elements and no actuators) and X(d) the rigid transport (ω, ṙ) ↦ (ω, ṙ + ω × d)
(Featherstone, *Rigid Body Dynamics Algorithms*, 2008, Table 7.1; seed 001, eqs. 256–290; the
same equations as :mod:`casmbd.system.articulated_body`, which
``tests/system/test_chain_fold.py`` checks to 1e-12 on a 20-rod chain).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.model.bodies import GROUND
from casmbd.system.articulated_body import supported as articulated_supported

__all__ = ["chain_order", "folded_accelerations", "supported"]


def chain_order(system) -> list[str]:
    """The bodies of a serial chain from the ground out (body k's parent is body k−1)."""
    desc = system.descriptions
    children: dict[str, list[str]] = {}
    for name in system.body_names:
        children.setdefault(desc[name].parent, []).append(name)
    order, parent = [], GROUND
    while children.get(parent):
        if len(children[parent]) != 1:
            return []
        parent = children[parent][0]
        order.append(parent)
    return order if len(order) == len(system.body_names) else []


def supported(system) -> str | None:
    """None when :func:`folded_accelerations` applies to ``system``, else the reason: a
    planar serial chain of revolute joints in joint coordinates, loaded by gravity only."""
    reason = articulated_supported(system)
    if reason:
        return reason
    if system.dimension != 2:
        return "the folded chain is planar"
    mech = system.mechanism
    if mech.forces or mech.actuators:
        return "force elements or actuators (the folded chain carries gravity only)"
    if not chain_order(system):
        return "not a serial chain"
    for name in system.body_names:
        d = system.descriptions[name]
        if d.joint.kind != "revolute" or d.size != 1 or getattr(d, "mimic", None):
            return f"joint '{d.joint.name}' is not a plain revolute"
    return None


def _rot(angle):
    c, s = ca.cos(angle), ca.sin(angle)
    return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))


def _transport(d):
    """X(d): (ω, ṙ) ↦ (ω, ṙ + ω × d) in the plane."""
    return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(-d[1], 1, 0), ca.horzcat(d[0], 0, 1))


def _kinematics_step() -> ca.Function:
    carry = ca.SX.sym("parent", 7)  # vec(A_P) (4), r_P (2), ω_P
    data = ca.SX.sym("data", 14)  # q, q̇, vec(A_P0ᵀ) (4), vec(A_C0) (4), a (2), b (2)
    a_p, r_p, w_p = ca.reshape(carry[:4], 2, 2), carry[4:6], carry[6]
    q, qd = data[0], data[1]
    p0t, c0 = ca.reshape(data[2:6], 2, 2), ca.reshape(data[6:10], 2, 2)
    a, b = data[10:12], data[12:14]
    base = ca.mtimes(a_p, p0t)
    rel = _rot(q)
    joint = r_p + ca.mtimes(base, a)
    r_c = r_p + ca.mtimes(base, a + ca.mtimes(rel, b))
    a_c = ca.mtimes(base, ca.mtimes(rel, c0))
    w_c = w_p + qd
    e = r_c - joint
    c_lin = -w_p**2 * (joint - r_p) - w_c**2 * e
    out = ca.vertcat(r_c - r_p, e, c_lin)  # d (2), e (2), c (linear part, 2)
    return ca.Function("chain_kinematics", [carry, data],
                       [ca.vertcat(ca.vec(a_c), r_c, w_c), out])


def _inward_step(gravity: np.ndarray) -> ca.Function:
    carry = ca.SX.sym("child", 12)  # vec(Xᵀ I^a X) (9), Xᵀ p^a (3) of the child
    data = ca.SX.sym("data", 8)  # m, J, d (2), e (2), c (2)
    mass, inertia = data[0], data[1]
    d, e = data[2:4], data[4:6]
    c = ca.vertcat(0, data[6:8])
    s = ca.vertcat(1, -e[1], e[0])
    i_a = ca.diagcat(inertia, mass * ca.SX.eye(2)) + ca.reshape(carry[:9], 3, 3)
    p_a = ca.vertcat(0, -mass * ca.DM(gravity)) + carry[9:]
    u_mat = ca.mtimes(i_a, s)
    d_inv = 1.0 / ca.mtimes(s.T, u_mat)
    u = -ca.mtimes(s.T, p_a)
    ia_c = i_a - ca.mtimes([u_mat, d_inv, u_mat.T])
    pa_c = p_a + ca.mtimes([u_mat, d_inv, u]) + ca.mtimes(ia_c, c)
    x = _transport(d)
    return ca.Function("chain_inward", [carry, data],
                       [ca.vertcat(ca.vec(ca.mtimes([x.T, ia_c, x])), ca.mtimes(x.T, pa_c)),
                        ca.vertcat(u_mat, d_inv, u)])


def _outward_step() -> ca.Function:
    carry = ca.SX.sym("parent_acc", 3)
    data = ca.SX.sym("data", 11)  # d (2), e (2), c (2), U (3), D⁻¹, u
    d, e = data[0:2], data[2:4]
    c = ca.vertcat(0, data[4:6])
    u_mat, d_inv, u = data[6:9], data[9], data[10]
    s = ca.vertcat(1, -e[1], e[0])
    a_prime = ca.mtimes(_transport(d), carry) + c
    qdd = d_inv * (u - ca.mtimes(u_mat.T, a_prime))
    return ca.Function("chain_outward", [carry, data], [a_prime + s * qdd, qdd])


def _bake(step: ca.Function, fixed: dict[int, float]) -> ca.Function:
    """``step`` with the rows ``fixed`` of its data input replaced by their values (the
    same for every body folded over: identical rods), so that the step's expressions are
    simplified with them (products with the zeros and ones of design frames vanish); its data
    input keeps the other rows, in order."""
    free = [k for k in range(step.size1_in(1)) if k not in fixed]
    carry = ca.SX.sym("carry", step.size1_in(0))
    data = ca.SX.sym("data", len(free))
    full = ca.vertcat(*[ca.SX(fixed[k]) if k in fixed else data[free.index(k)]
                        for k in range(step.size1_in(1))])
    return ca.Function(step.name() + "_baked", [carry, data], step(carry, full))


def _uniform_rows(values: np.ndarray, rows) -> dict[int, float]:
    """The rows (index into ``rows``' numbering) whose columns of ``values`` are all equal."""
    return {row: float(values[k, 0]) for k, row in enumerate(rows)
            if values.shape[1] and np.all(values[k] == values[k, 0])}


def folded_accelerations(system, q: ca.MX, v: ca.MX, p: ca.MX) -> ca.MX:
    """q̈(q, q̇, p) of a planar revolute chain (:func:`supported`) as an MX expression of
    three folds (``mapaccum``) over the bodies (module notes); the same numbers as
    :func:`casmbd.system.articulated_body.articulated_accelerations`.

    Data that are the same for every body folded over (identical rods: design frames, joint
    points, masses and inertias given as numbers) are built into the per-body Functions as
    constants rather than passed body by body; the first body, whose joint is on the ground,
    takes the kinematics step on its own."""
    order = chain_order(system)
    n = len(order)
    desc = system.descriptions
    index = [system.ctx.index[name] for name in order]
    consts = np.array([np.concatenate([
        np.asarray(desc[k].rot_p0_t, float).ravel(order="F"),
        np.asarray(desc[k].rot_c0, float).ravel(order="F"),
        np.asarray(desc[k].point - desc[k].pos_p0, float),
        np.asarray(desc[k].pos_c0 - desc[k].point, float)]) for k in order]).T
    inertia_expr = ca.horzcat(*[ca.vertcat(*system._mass_inertia(system.mechanism.bodies[k]))
                                for k in order])
    inertias = ca.Function("chain_inertias", [system.p], [inertia_expr])
    data = ca.vertcat(q[index].T, v[index].T, ca.DM(consts))
    # kinematics: the first body alone (its parent is the ground), then a fold over the rest
    # with the rows equal for all of them built in
    generic = _kinematics_step()
    carry0, geometry0 = generic(ca.DM([1, 0, 0, 1, 0, 0, 0]), data[:, 0])
    geometry = geometry0
    if n > 1:
        fixed = _uniform_rows(consts[:, 1:], range(2, 14))
        free = [k for k in range(14) if k not in fixed]
        kin = _bake(generic, fixed).mapaccum("chain_kinematics_fold", n - 1)
        _, rest = kin(carry0, data[free, 1:])
        geometry = ca.horzcat(geometry0, rest)
    reverse = list(range(n - 1, -1, -1))
    inward_step = _inward_step(np.asarray(system.mechanism.gravity, float))
    inward_data = ca.vertcat(inertias(p), geometry)
    fixed = {}
    if not ca.depends_on(inertia_expr, system.p):
        fixed = _uniform_rows(np.asarray(ca.evalf(inertia_expr), float), range(2))
    free = [k for k in range(8) if k not in fixed]
    inward = _bake(inward_step, fixed).mapaccum("chain_inward_fold", n)
    _, factors = inward(ca.DM.zeros(12), inward_data[free, reverse])
    outward = _outward_step().mapaccum("chain_outward_fold", n)
    _, qdd = outward(ca.DM.zeros(3), ca.vertcat(geometry, factors[:, reverse]))
    out = ca.MX.zeros(system.nq, 1)
    out[index] = qdd.T
    return out
