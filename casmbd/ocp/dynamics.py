"""The constrained equations of motion as they enter a transcription.

Collocation uses the implicit index-1 form at every collocation point (seed 000, eq. 6.138):

    M(q) q̈ + C_qᵀ λ − Q_e(q, q̇, u, t) − Q_v(q, q̇) = 0,      C_q q̈ − γ(q, q̇, t) = 0,

with q̈ and λ as NLP variables, so that no matrix is inverted symbolically.  The position and
velocity constraints C(q, t) = 0 and C_q q̇ + C_t = 0 are imposed at every mesh node; to keep
the NLP square-consistent (the index-1 dynamics preserve them only up to the discretisation
error) each interval carries projection multipliers μ, ν with

    q̇ = v + C_qᵀ μ,      v̇ = q̈ + C_qᵀ ν,

(rows written at the velocity level, A(q) q̇ + b = 0, have no position row: μ and the nodes'
C = 0 take the holonomic rows only, :func:`node_constraints`)

the collocation analogue of the Gear–Gupta–Leimkuhler stabilisation: μ and ν are of the size of
the discretisation error and vanish for the exact solution.  Shooting uses the explicit form
q̈ = f(q, q̇, u, t) from the KKT system (or the articulated-body recursion for trees).
"""

from __future__ import annotations

import casadi as ca

from casmbd.errors import AnalysisError
from casmbd.system.articulated_body import articulated_accelerations, supported


def implicit_residual(system) -> ca.Function:
    """``res(q, v, a, lam, u, t, p) -> (dyn [nq], acc [nc])`` of the index-1 equations."""
    q, v, t, u, p = system.q, system.v, system.t, system.u, system.p
    a = ca.SX.sym("a", system.nq)
    lam = ca.SX.sym("lam", system.nc)
    cq = system.constraint_jacobian
    system.refuse_reaction_friction("the optimal-control transcription")
    forces = system.applied_forces + system.quadratic_velocity_forces
    dyn = ca.mtimes(system.mass_matrix, a) - forces
    if system.nc:
        dyn = dyn + ca.mtimes(cq.T, lam)
        acc = ca.mtimes(cq, a) - system.acceleration_rhs
    else:
        acc = ca.SX(0, 1)
    return ca.Function("ocp_residual", [q, v, a, lam, u, t, p], [dyn, acc],
                       ["q", "v", "a", "lam", "u", "t", "p"], ["dyn", "acc"])


def node_constraints(system) -> ca.Function:
    """``node(q, v, t, p) -> (C_h, C_q v + C_t, C_qᵀ)`` at a mesh node.

    C_h are the position constraints — every row but those written at the velocity level
    (rolling without slipping, knife edges: their C is identically 0 and would be a 0 = 0
    row of the NLP); the velocity rows C_q v + C_t = 0 are every row, with the velocity
    projection v̇ = q̈ + C_qᵀ ν (a rolling row is a path constraint on the velocities at every
    node, and its derivative C_q q̈ = γ holds at every collocation point)."""
    q, v, t, p = system.q, system.v, system.t, system.p
    cq = system.constraint_jacobian
    rows = list(getattr(system, "holonomic_rows", range(system.nc)))
    c_h = system.constraints if len(rows) == system.nc else system.constraints[rows]
    return ca.Function("ocp_node", [q, v, t, p],
                       [c_h, ca.mtimes(cq, v) + system.constraint_time_derivative, cq.T],
                       ["q", "v", "t", "p"], ["C", "Cdot", "CqT"])


def position_projection(system) -> ca.Function:
    """``proj(q, t, p) -> C_hqᵀ``: the transposed Jacobian ∂C_h/∂q of the position rows of
    :func:`node_constraints`, which carries the position projection q̇ = v + C_hqᵀ μ (C_qᵀ
    itself when no row is written at the velocity level)."""
    q, t, p = system.q, system.t, system.p
    rows = list(getattr(system, "holonomic_rows", range(system.nc)))
    ch_q = system.constraint_jacobian if len(rows) == system.nc else \
        system.position_jacobian[rows, :]
    return ca.Function("ocp_position_projection", [q, t, p], [ch_q.T], ["q", "t", "p"],
                       ["ChT"])


def explicit_accelerations(system) -> ca.Function:
    """``acc(q, v, u, t, p) -> a``: the articulated-body recursion for a constraint-free tree,
    else the KKT system solved symbolically (small systems: the problems of ``ocp/``)."""
    q, v, t, u, p = system.q, system.v, system.t, system.u, system.p
    if system.coordinates == "joint" and supported(system) is None:
        acc = articulated_accelerations(system)
    else:
        system.refuse_reaction_friction("the optimal-control transcription")
        forces = system.applied_forces + system.quadratic_velocity_forces
        if system.nc:
            cq = system.constraint_jacobian
            kkt = ca.blockcat([[system.mass_matrix, cq.T],
                               [cq, ca.SX(system.nc, system.nc)]])
            sol = ca.solve(kkt, ca.vertcat(forces, system.acceleration_rhs))
            acc = sol[:system.nq]
        else:
            acc = ca.solve(system.mass_matrix, forces)
    return ca.Function("ocp_acc", [q, v, u, t, p], [acc], ["q", "v", "u", "t", "p"], ["a"])


#: ``dynamics="auto"`` substitutes explicit accelerations in collocation when the mechanism has
#: no constraint equations and its equations of motion M q̈ − Q hold at most this many SX
#: instructions (measured in docs/ocp.md: the two-coordinate trees of ``ocp/`` — 45 to 205
#: instructions — solve faster with q̈ substituted because the KKT system is a third smaller
#: and function evaluation is a small part of an iteration; on the UR5, 3763 instructions,
#: the articulated recursion's second derivatives make each element's Hessian 2.3× larger
#: and its solve 2× slower).
AUTO_EXPLICIT_INSTRUCTIONS = 1000


def choose_dynamics(system, requested: str, collocation: bool = True
                    ) -> tuple[bool, str, ca.Function | None, ca.Function | None]:
    """(explicit?, why, the explicit accelerations or None, the implicit residual or None)
    for ``Ocp.dynamics``.

    ``"implicit"`` and ``"explicit"`` are kept as given (explicit needs nc = 0: an
    AnalysisError otherwise); ``"auto"`` picks explicit for collocation when nc = 0 and the
    implicit residual M q̈ − Q holds at most :data:`AUTO_EXPLICIT_INSTRUCTIONS` SX
    instructions, else implicit.  Multiple shooting
    always integrates the explicit form (the choice does not apply: reported as such).
    """
    nc = system.nc
    if requested == "explicit" and nc:
        raise AnalysisError(f"ocp: dynamics='explicit' needs a mechanism without constraint "
                            f"equations; this one has {nc} (use 'implicit')")
    if not collocation:
        return False, "multiple shooting integrates q̈ = f(q, q̇, u, t)", None, None
    if requested == "explicit":
        return True, "given", explicit_accelerations(system), None
    res = implicit_residual(system)
    if requested == "implicit":
        return False, "given", None, res
    if nc:
        return False, (f"auto: implicit, the mechanism has {nc} constraint equations "
                       "(explicit accelerations would invert the KKT matrix symbolically)"), \
            None, res
    size = res.n_instructions()
    if size <= AUTO_EXPLICIT_INSTRUCTIONS:
        return True, (f"auto: explicit, no constraint equations and small equations of motion "
                      f"(M q̈ − Q: {size} <= {AUTO_EXPLICIT_INSTRUCTIONS} SX instructions)"), \
            explicit_accelerations(system), None
    return False, (f"auto: implicit, large equations of motion (M q̈ − Q: {size} > "
                   f"{AUTO_EXPLICIT_INSTRUCTIONS} SX instructions; the second derivatives of "
                   "q̈ = f(q, q̇, u, t) would dominate each iteration)"), None, res
