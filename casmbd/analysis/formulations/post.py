"""Post-processing Function of a simulation: q̈, λ from the sparse KKT system and
diagnostics at the output times (the same for every formulation)."""

from __future__ import annotations

import casadi as ca

from casmbd.analysis.formulations.base import generalized_forces, symbolic_arguments
from casmbd.system.equations import System


def post_processing(system: System, inputs: ca.SX | None = None,
                    dynamics: ca.Function | None = None,
                    energies: tuple[ca.Function, ca.Function] | None = None) -> ca.Function:
    """q̈, λ from the sparse KKT system and diagnostics, for mapped evaluation at outputs.

    ``post(q, v, t, p) -> (a, lambda, residual, T, V, C_max, Cdot_max)``: the KKT system of
    seed 000, eq. 6.138, solved by CasADi's code-generable sparse QR; ``residual`` is the
    max-norm of the KKT residual, so that singular points (redundant constraints, singular
    poses) can be recomputed by a minimum-norm solve.

    With ``dynamics`` — the ODE right-hand side ``(t, x, z, p, u) -> (ẋ, …)`` of a system
    without constraint equations — q̈ is the second half of ẋ = (q̇, q̈) instead of the solve
    of M q̈ = Q (the same accelerations; the residual is 0): no joint-space M enters the
    code, which stays O(N) with the articulated-body recursion (the dense M and its QR made
    the 300-rod chain's ``post`` 15.7 MB of C).  ``energies``: ``kinetic_energy(q, v, p)``
    and ``potential_energy(q, t, p)`` Functions to use there instead of the System's own
    expressions (a long chain's folded sums, :mod:`casmbd.system.chain_motion`).
    """
    if dynamics is not None and system.nc == 0:
        return _post_from_dynamics(system, dynamics, energies)
    t, q, v, p = symbolic_arguments(system)
    # reaction-proportional joint friction: Q_e at N = 0 here and a NaN residual, so that
    # every output time is recomputed by the numeric fixed point of λ and N
    # (casmbd.analysis.instant.kkt.accelerations_and_multipliers)
    friction = bool(system.friction_normal_symbols)
    forces = generalized_forces(system, inputs, ca.SX.zeros(system.nc) if friction else None)
    m_mat = system.mass_matrix
    cq = system.constraint_jacobian
    n, m = system.nq, system.nc
    if m:
        kkt = ca.blockcat([[m_mat, cq.T], [cq, ca.SX(m, m)]])
        rhs = ca.vertcat(forces, system.acceleration_rhs)
    else:
        kkt, rhs = m_mat, forces
    cdot = ca.mtimes(cq, v) + system.constraint_time_derivative
    c_max = ca.mmax(ca.fabs(system.constraints)) if m else ca.SX(0.0)
    cdot_max = ca.mmax(ca.fabs(cdot)) if m else ca.SX(0.0)
    parts = ca.Function("post_parts", [q, v, t, p],
                        [kkt, rhs, system.kinetic_energy, system.potential_energy, c_max,
                         cdot_max])
    qm, vm, tm, pm = (ca.MX.sym(name, s.sparsity()) for name, s in
                      (("q", q), ("v", v), ("t", t), ("p", p)))
    k_x, r_x, kin, pot, c_x, cd_x = parts(qm, vm, tm, pm)
    sol = ca.Linsol("post_qr", "qr", kkt.sparsity()).solve(k_x, r_x)
    residual = ca.mmax(ca.fabs(ca.mtimes(k_x, sol) - r_x)) * (float("nan") if friction else 1.0)
    lam = sol[n:] if m else ca.MX(0, 1)
    return ca.Function("post", [qm, vm, tm, pm],
                       [sol[:n], lam, residual, kin, pot, c_x, cd_x],
                       ["q", "v", "t", "p"],
                       ["a", "lambda", "residual", "T", "V", "C_max", "Cdot_max"])


def _post_from_dynamics(system: System, dynamics: ca.Function,
                        energies: tuple[ca.Function, ca.Function] | None = None
                        ) -> ca.Function:
    """``post`` of an unconstrained system with q̈ from its ODE right-hand side."""
    t, q, v, p = symbolic_arguments(system)
    qm, vm, tm, pm = (ca.MX.sym(name, s.sparsity()) for name, s in
                      (("q", q), ("v", v), ("t", t), ("p", p)))
    if energies is not None:
        kin, pot = energies[0](qm, vm, pm), energies[1](qm, tm, pm)
    else:
        parts = ca.Function("post_parts", [q, v, t, p],
                            [system.kinetic_energy, system.potential_energy])
        kin, pot = parts(qm, vm, tm, pm)
    xdot = dynamics(tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm, ca.MX(0, 1))[0]
    zero = ca.MX(1, 1)
    return ca.Function("post", [qm, vm, tm, pm],
                       [xdot[system.nq:], ca.MX(0, 1), zero, kin, pot, zero, zero],
                       ["q", "v", "t", "p"],
                       ["a", "lambda", "residual", "T", "V", "C_max", "Cdot_max"])
