"""The articulated-body pivots D_i and the diagonal M_ii of the mass matrix of a planar
revolute chain, folded over the bodies: the cheap test of a positive definite mass matrix.

For a tree in joint coordinates the inward pass of the articulated-body recursion is a
factorisation M = Lᵀ D L eliminated from the leaves in (Featherstone, *Rigid Body Dynamics
Algorithms*, 2008, §6.3 and §7.3): its pivots are D_i = S_iᵀ I^A_i S_i, and M is positive
definite exactly when every D_i > 0.  Scaled by the diagonal of M (the composite inertia about
the joint, M_ii = S_iᵀ I^C_i S_i) they are the pivots of the Jacobi-scaled M that
:func:`casmbd.analysis.instant.checks.check_mass_matrix` bounds by ``MASS_RTOL``.  One fold over
the N bodies (O(N)) instead of M itself (N inverse-dynamics passes, O(N²): 0.2 s for 1000 rods)
and its dense factorisation.

The step, tip to root, carrying the child's articulated and composite inertias already
transported to this body's centre of mass (Xᵀ I^a X, Xᵀ I^C X), with I = diag(J, m, m):

    I^A = I + Σ Xᵀ I^a X,  I^C = I + Σ Xᵀ I^C X,  U = I^A S,  D = Sᵀ U,
    I^a = I^A − U Uᵀ / D,   M_ii = Sᵀ I^C S,

the same kinematics (S, X) as :mod:`casmbd.system.chain_fold` (module notes there).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.system.chain_fold import chain_order

__all__ = ["folded_pivots"]


def _transport(d):
    """X(d): (ω, ṙ) ↦ (ω, ṙ + ω × d) in the plane."""
    return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(-d[1], 1, 0), ca.horzcat(d[0], 0, 1))


def _geometry_step() -> ca.Function:
    """Root to tip: the parent's rotation and centre of mass in, the child's out, with
    d = r_C − r_P and e = r_C − J (the kinematics of :mod:`casmbd.system.chain_fold`, rates
    left out)."""
    carry = ca.SX.sym("parent", 6)  # vec(A_P) (4), r_P (2)
    data = ca.SX.sym("data", 13)  # q, vec(A_P0ᵀ) (4), vec(A_C0) (4), a (2), b (2)
    a_p, r_p = ca.reshape(carry[:4], 2, 2), carry[4:6]
    angle = data[0]
    p0t, c0 = ca.reshape(data[1:5], 2, 2), ca.reshape(data[5:9], 2, 2)
    a, b = data[9:11], data[11:13]
    c, s = ca.cos(angle), ca.sin(angle)
    rel = ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))
    base = ca.mtimes(a_p, p0t)
    joint = r_p + ca.mtimes(base, a)
    r_c = r_p + ca.mtimes(base, a + ca.mtimes(rel, b))
    a_c = ca.mtimes(base, ca.mtimes(rel, c0))
    return ca.Function("chain_pivot_geometry", [carry, data],
                       [ca.vertcat(ca.vec(a_c), r_c), ca.vertcat(r_c - r_p, r_c - joint)])


def _pivot_step() -> ca.Function:
    carry = ca.SX.sym("child", 18)  # vec(Xᵀ I^a X) (9), vec(Xᵀ I^C X) (9) of the child
    data = ca.SX.sym("data", 6)  # m, J, d (2), e (2)
    mass, inertia = data[0], data[1]
    d, e = data[2:4], data[4:6]
    s = ca.vertcat(1, -e[1], e[0])
    own = ca.diagcat(inertia, mass * ca.SX.eye(2))
    i_a = own + ca.reshape(carry[:9], 3, 3)
    i_c = own + ca.reshape(carry[9:], 3, 3)
    u_mat = ca.mtimes(i_a, s)
    pivot = ca.mtimes(s.T, u_mat)
    ia_c = i_a - ca.mtimes(u_mat, u_mat.T) / pivot
    x = _transport(d)
    return ca.Function("chain_pivot", [carry, data],
                       [ca.vertcat(ca.vec(ca.mtimes([x.T, ia_c, x])),
                                   ca.vec(ca.mtimes([x.T, i_c, x]))),
                        ca.vertcat(pivot, ca.mtimes([s.T, i_c, s]))])


def folded_pivots(system) -> ca.Function:
    """``articulated_pivots(q, p) -> [D; diag M]`` (2 n_q, each in the order of the
    coordinates) of a chain of :func:`casmbd.system.chain_fold.supported`: a kinematics fold
    root to tip (:func:`_geometry_step`), then the pivot step (module notes) folded tip to
    root."""
    order = chain_order(system)
    n = len(order)
    desc = system.descriptions
    index = [system.ctx.index[name] for name in order]
    q, p = ca.MX.sym("q", system.nq), ca.MX.sym("p", system.p.numel())
    consts = np.array([np.concatenate([
        np.asarray(desc[k].rot_p0_t, float).ravel(order="F"),
        np.asarray(desc[k].rot_c0, float).ravel(order="F"),
        np.asarray(desc[k].point - desc[k].pos_p0, float),
        np.asarray(desc[k].pos_c0 - desc[k].point, float)]) for k in order]).T
    inertias = ca.Function("chain_pivot_inertias", [system.p], [ca.horzcat(*[
        ca.vertcat(*system._mass_inertia(system.mechanism.bodies[k])) for k in order])])
    data = ca.vertcat(q[index].T, ca.DM(consts))
    _, geometry = _geometry_step().mapaccum("chain_pivot_kinematics", n)(
        ca.DM([1, 0, 0, 1, 0, 0]), data)
    reverse = list(range(n - 1, -1, -1))
    step_data = ca.vertcat(inertias(p), geometry)[:, reverse]
    _, out = _pivot_step().mapaccum("chain_pivot_fold", n)(ca.DM.zeros(18), step_data)
    out = out[:, reverse]
    pivots, diagonal = ca.MX.zeros(system.nq), ca.MX.zeros(system.nq)
    pivots[index] = out[0, :].T
    diagonal[index] = out[1, :].T
    return ca.Function("articulated_pivots", [q, p], [ca.vertcat(pivots, diagonal)],
                       ["q", "p"], ["pivots"])
