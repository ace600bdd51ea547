"""``kkt_ode``: ODE x = (q, v) with λ from the sparse Schur complement.

λ from S = C_q M⁻¹ C_qᵀ (sparse, symmetric positive definite when C_q has full rank) with
CasADi's code-generable sparse LDLᵀ; M⁻¹ is block diagonal (3×3 blocks) in absolute and natural
coordinates, so nothing dense is ever formed; a coupled (joint-coordinate) M, or one with the
dense frame–mode blocks of flexible bodies, is factorised by a sparse LDLᵀ instead.
"""

from __future__ import annotations

import casadi as ca

from casmbd.analysis.formulations.base import (
    Formulation,
    FormulationKind,
    baumgarte_acceleration_rhs,
    dae_function,
    generalized_forces,
    symbolic_arguments,
)
from casmbd.model.needs import ALL_NEEDS
from casmbd.system.equations import System


def _block_inverse(system: System) -> ca.SX:
    """M⁻¹ block by block; diagonal blocks (centroidal planar frames) invert entry-wise."""
    m = system.mass_matrix
    blocks = []
    for name in system.body_names:
        sl = system.body_slice(name)
        block = m[sl, sl]
        if block.sparsity().is_diag():
            blocks.append(ca.diag(1.0 / ca.diag(block)))
        else:
            blocks.append(ca.inv(block))
    return ca.diagcat(*blocks)


def _flexible(system: System) -> bool:
    """True when a body block holds modal coordinates: its frame–mode block is dense and
    ill-conditioned (cond 4e5–9e6 for beams of 6–20 elements), where the symbolic inverse of
    :func:`_block_inverse` (unpivoted QR) loses cond² ε — 8e-4 in |M⁻¹M − I| — so M is
    factorised by the sparse LDLᵀ of the coupled path instead."""
    return any(getattr(d, "n_modes", 0) for d in system.descriptions.values())


def kkt_ode(system: System, alpha: float = 0.0, beta: float = 0.0,
            inputs: ca.SX | None = None) -> Formulation:
    """ODE on (q, v) with λ from the sparse Schur complement and an LDLᵀ solve."""
    t, q, v, pu = symbolic_arguments(system)
    q_dot = v
    if not system.local or _flexible(system):
        return _kkt_ode_coupled(system, alpha, beta, inputs)
    if system.nc == 0:
        a = ca.mtimes(_block_inverse(system), generalized_forces(system, inputs))
        f = dae_function("dyn_kkt_ode", t, ca.vertcat(q, v), ca.SX(0, 1), pu, ca.vertcat(q_dot, a),
                 ca.SX(0, 1))
        return Formulation("kkt_ode", "ode", f, system.nq, 0)
    minv = _block_inverse(system)
    cq = system.constraint_jacobian
    minv_q = ca.mtimes(minv, generalized_forces(system, inputs))
    minv_ct = ca.mtimes(minv, cq.T)
    schur = ca.mtimes(cq, minv_ct)
    rhs = ca.mtimes(cq, minv_q) - baumgarte_acceleration_rhs(system, alpha, beta)
    parts = ca.Function("kkt_parts", [t, q, v, pu], [schur, rhs, minv_q, minv_ct])
    tm, qm, vm, pm = (ca.MX.sym(n, s.sparsity()) for n, s in
                      (("t", t), ("q", q), ("v", v), ("p", pu)))
    s_x, r_x, mq_x, mc_x = parts(tm, qm, vm, pm)
    solver = ca.Linsol("kkt_ldl", "ldl", schur.sparsity())
    lam = solver.solve(s_x, r_x)
    acc = mq_x - ca.mtimes(mc_x, lam)
    f = dae_function("dyn_kkt_ode", tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm, ca.vertcat(vm, acc),
             ca.MX(0, 1))
    return Formulation("kkt_ode", "ode", f, system.nq, 0, [], {"alpha": alpha, "beta": beta})


def _kkt_ode_coupled(system: System, alpha: float, beta: float,
                     inputs: ca.SX | None) -> Formulation:
    """KKT ODE for a coupled (joint-coordinate) mass matrix: M⁻¹ [Q, C_qᵀ] by a sparse LDLᵀ of
    the symmetric positive definite M, then the Schur complement C_q M⁻¹ C_qᵀ for λ."""
    t, q, v, pu = symbolic_arguments(system)
    nc = system.nc
    cq = system.constraint_jacobian
    outs = [system.mass_matrix, generalized_forces(system, inputs)]
    if nc:
        outs += [cq, baumgarte_acceleration_rhs(system, alpha, beta)]
    parts = ca.Function("kkt_coupled_parts", [t, q, v, pu], outs)
    tm, qm, vm, pm = (ca.MX.sym(n, s.sparsity()) for n, s in
                      (("t", t), ("q", q), ("v", v), ("p", pu)))
    got = parts(tm, qm, vm, pm)
    m_x, f_x = got[0], got[1]
    solver = ca.Linsol("m_ldl", "ldl", system.mass_matrix.sparsity())
    if nc:
        cq_x, g_x = got[2], got[3]
        both = solver.solve(m_x, ca.horzcat(f_x, cq_x.T))
        minv_q, minv_ct = both[:, 0], both[:, 1:]
        schur = ca.mtimes(cq_x, minv_ct)
        lam = ca.solve(schur, ca.mtimes(cq_x, minv_q) - g_x)
        acc = minv_q - ca.mtimes(minv_ct, lam)
    else:
        acc = solver.solve(m_x, f_x)
    f = dae_function("dyn_kkt_ode", tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm, ca.vertcat(vm, acc),
             ca.MX(0, 1))
    return Formulation("kkt_ode", "ode", f, system.nq, 0, [], {"alpha": alpha, "beta": beta})


class KktOde(FormulationKind):
    """ODE on (q, v) with the multipliers eliminated through the Schur complement."""

    name = "kkt_ode"
    handles = ALL_NEEDS - {"reaction_forces", "contact_friction"}
    refuses = dict.fromkeys(("reaction_forces", "contact_friction"), "an ODE formulation does "
                            "not solve for the multipliers the friction level needs")
    instead = dict.fromkeys(("reaction_forces", "contact_friction"),
                            "formulation 'index1' (or 'ggl')")
    kind = "ode"
    default_integrator = "adams"
    inverts_mass = True

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        return kkt_ode(system, inputs=inputs, **options)
