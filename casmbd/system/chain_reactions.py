"""Joint reactions and the mass matrix of a planar revolute chain by a backward
Newton–Euler pass folded over the bodies (tip to root), on the folded forward kinematics of
:mod:`casmbd.system.chain_motion`.

Written out body by body (:meth:`casmbd.system.joint_reactions.Reactions.reactions_function`,
:attr:`casmbd.system.equations.System.mass_matrix`) a 1000-rod chain gives 3.8 MB and
2.1 MB of C; folded, one step is generated.

Body k takes from its child (carry) the child's joint wrench at the child's joint point,
(F_c, M_c), and the child's ρ_c = J_c − r_Gk; with the body's r̈_G, α, e = r_G − J:

    F = m r̈_G − m g + F_c,   M_G = J α + M_c + ρ_c × F_c,   M_J = M_G + e × F,

(F, M_J) is the action of the parent on body k at its joint point (seed 002, "Joint Forces
Calculation"; seed 004), reported with the sign of the joint's body order (the action of
body1 on body2).  The joint torque is M_J (S = (0, 0, 1) at the joint point), so the
column j of M is M_J of every joint for q̇ = 0, q̈ = e_j, g = 0 (Walker and Orin, 1982,
method 1: the inverse dynamics of unit accelerations), mapped over the columns.
``tests/system/test_chain_motion.py`` checks both against the unrolled Functions to 1e-12.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.system.chain_fold import chain_order
from casmbd.system.chain_motion import mass_rows, motion

__all__ = ["folded_mass_matrix", "folded_reactions"]


def _cross(w, d):
    return ca.vertcat(-w * d[1], w * d[0])


def _backward_step(gravity: np.ndarray) -> ca.Function:
    """One body of the pass (module notes): the child's (F, M_J, ρ) in, the body's out."""
    carry = ca.SX.sym("child", 5)  # F_c (2), M_c at the child's joint point, ρ_c (2)
    data = ca.SX.sym("data", 10)  # m, J, r̈_G (2), α, ρ (2), e (2), sign
    mass, inertia, acc, alpha = data[0], data[1], data[2:4], data[4]
    rho, e, sign = data[5:7], data[7:9], data[9]
    f_c, m_c, rho_c = carry[0:2], carry[2], carry[3:5]
    force = mass * (acc - ca.DM(gravity)) + f_c
    moment_g = inertia * alpha + m_c + (rho_c[0] * f_c[1] - rho_c[1] * f_c[0])
    moment_j = moment_g + (e[0] * force[1] - e[1] * force[0])
    return ca.Function("chain_newton_euler", [carry, data],
                       [ca.vertcat(force, moment_j, rho),
                        sign * ca.vertcat(force, moment_j)])


def _wrenches(system, q, v, a, p, gravity, signed: bool = True) -> ca.MX:
    """The joint wrenches (F_x, F_y, M_J), a column per body in chain order: the action of
    the parent on the body, or with ``signed`` of each joint's body1 on its body2."""
    order = chain_order(system)
    mech = system.mechanism
    sign = [1.0 if not signed or mech.joints[system.descriptions[b].joint.name].body2 == b
            else -1.0 for b in order]
    moving = motion(system, q, v, a)
    mass, inertia = mass_rows(system, p)
    data = ca.vertcat(mass, inertia, moving[8:10, :], moving[12, :], moving[13:17, :],
                      ca.DM(sign).T)
    reverse = list(range(len(order) - 1, -1, -1))
    fold = _backward_step(gravity).mapaccum("chain_newton_euler_fold", len(order))
    _, out = fold(ca.DM.zeros(5), data[:, reverse])
    return out[:, reverse]


def folded_reactions(system) -> ca.Function:
    """``joint_reactions(q, v, a, t, u, p, lambda)`` of a chain
    (:func:`casmbd.system.chain_motion.supported`): one column (F_x, F_y, M) per joint in
    declaration order, as :meth:`~casmbd.system.joint_reactions.Reactions.reactions_function`."""
    order = chain_order(system)
    q, v, a = (ca.MX.sym(s, system.nq) for s in ("q", "v", "a"))
    t, u = ca.MX.sym("t"), ca.MX.sym("u", system.u.numel())
    p, lam = ca.MX.sym("p", system.p.numel()), ca.MX.sym("lambda", system.nc)
    wrench = _wrenches(system, q, v, a, p, np.asarray(system.mechanism.gravity, float))
    body_of = {system.descriptions[b].joint.name: k for k, b in enumerate(order)}
    cols = [body_of[name] for name in system.mechanism.joints]
    return ca.Function("joint_reactions", [q, v, a, t, u, p, lam], [wrench[:, cols]],
                       ["q", "v", "a", "t", "u", "p", "lambda"], ["reactions"])


def folded_mass_matrix(system) -> ca.Function:
    """``mass_matrix(q, p) -> M`` of a chain: the joint torques of unit accelerations
    without gravity or rates (module notes), the column pass mapped over the N columns."""
    order = chain_order(system)
    index = [system.ctx.index[name] for name in order]
    q, p = ca.MX.sym("q", system.nq), ca.MX.sym("p", system.p.numel())
    j = ca.MX.sym("j")
    # e_j built from its index at run time: a mapped identity would be stored as N²
    # constants in the C (4.3 MB at N = 1000), and a fold over the columns takes 9 s to build
    rows = np.arange(system.nq, dtype=float)
    a = ca.eq(ca.DM(rows), j)
    torque = ca.MX.zeros(system.nq)
    torque[index] = _wrenches(system, q, ca.MX.zeros(system.nq), a, p, np.zeros(2),
                              signed=False)[2, :].T
    column = ca.Function("chain_mass_column", [q, p, j], [torque])
    m = column.map(system.nq)(q, p, ca.DM(rows).T)
    return ca.Function("mass_matrix", [q, p], [m], ["q", "p"], ["M"])
