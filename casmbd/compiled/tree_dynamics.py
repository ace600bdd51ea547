"""Code generation of the per-call dynamics of a tree: O(N) recursions, shared subexpressions.

:class:`~casmbd.compiled.robot.CompiledModel` of a tree in joint coordinates (no constraint
equations, joints with independent rates: :func:`~casmbd.system.articulated_body.supported`)
writes each quantity by the recursion whose expression graph grows linearly with the tree:

* forward dynamics by the articulated-body algorithm
  (:func:`~casmbd.system.articulated_body.articulated_accelerations` with the efforts τ, at
  t = 0 and u = 0): O(N) operations, against the n³/6 of a dense LDLᵀ of M (for 101 joints,
  tiago_dual: 93 k SX instructions against 361 k);
* inverse dynamics and the bias b by the recursive Newton–Euler algorithm
  (:func:`~casmbd.compiled.robot.newton_euler`);
* the mass matrix by the composite-rigid-body recursion (:attr:`System.mass_matrix
  <casmbd.system.equations.System.mass_matrix>`);
* a frame's Jacobian from the joints' motion subspaces: every column of an ancestor joint j is
  the twist S_j carried rigidly to the frame's point (:func:`frame_jacobian`), instead of
  differentiating the point's position through the whole chain.

Every Function gets CasADi's common-subexpression elimination (:data:`FUNCTION_OPTIONS`,
``cse``): the recursions write the same products along different branches (a rotation times
an inertia, a transport of a motion subspace), and the elimination makes one of each.
"""

from __future__ import annotations

import casadi as ca

from casmbd.model.bodies import GROUND
from casmbd.system.articulated_body import articulated_accelerations

__all__ = ["FUNCTION_OPTIONS", "forward_dynamics", "frame_jacobian"]

#: options of every Function of a tree's per-call model: common-subexpression elimination
#: (tiago_dual, 101 joints: articulated-body forward dynamics 115.8 k → 93.3 k instructions,
#: Newton–Euler 83.8 k → 61.9 k, mass matrix 62.7 k → 53.3 k)
FUNCTION_OPTIONS: dict = {"cse": True}


def forward_dynamics(system, tau: ca.SX) -> ca.SX:
    """q̈ with ``M q̈ + b = τ`` at t = 0, u = 0, by the articulated-body recursion.

    Featherstone, Rigid Body Dynamics Algorithms (2008), §7.3, Table 7.1, in the conventions
    of :mod:`casmbd.system.articulated_body`: the applied forces (gravity, springs, dampers)
    enter as body wrenches, τ as the joint efforts ``u_i = τ_i − S_iᵀ p^A_i``.
    """
    qdd = articulated_accelerations(system, applied=True, efforts=tau)
    return ca.substitute([qdd], [system.t, system.u],
                         [ca.SX(0.0), ca.SX.zeros(system.u.numel())])[0]


def frame_jacobian(system, body: str, point: ca.SX) -> ca.SX:
    """``(dim + nw) × n_q`` J with ``(ṙ, ω) = J q̇`` of ``point`` fixed on ``body``.

    A joint's rate q̇_j moves the whole subtree below it rigidly with the twist S_j q̇_j
    (S_j = (S_ω, S_v) the motion subspace of body j at its centre of mass G_j, global
    components; :class:`~casmbd.system.tree.TreeKinematics`), so a point r of a descendant
    moves with ṙ = (S_v + S_ω × (r − r_Gj)) q̇_j and turns with ω = S_ω q̇_j (seed 001,
    eqs. 256–290, the velocity influence coefficients).  Columns of the joints off the
    path from ``body`` to the ground are zero.
    """
    ctx, dim, desc = system.ctx, system.dimension, system.descriptions
    tk = system.tree_kinematics
    nw = 1 if dim == 2 else 3
    cols = [ca.SX.zeros(dim + nw, 1) for _ in range(system.nq)]
    node = body
    while node != GROUND:
        s = tk.motion[node]
        start = system.body_slice(node).start
        arm = point - ctx.centre_of_mass(node)
        for k in range(s.size2()):
            ang, lin = s[:nw, k], s[nw:, k]
            if dim == 2:
                lin = lin + ang * ca.vertcat(-arm[1], arm[0])
            else:
                lin = lin + ca.cross(ang, arm)
            cols[start + k] = ca.vertcat(lin, ang)
        node = desc[node].parent
    return ca.horzcat(*cols) if cols else ca.SX(dim + nw, 0)
