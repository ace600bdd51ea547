"""``augmented_lagrangian``: ODE x = (q, v) by the augmented-Lagrangian iteration.

Bayo and García de Jalón (seed 003, mass-orthogonal projections): (M + α C_qᵀ C_q) q̈ = Q −
C_qᵀ λ_i + α C_qᵀ γ_b, λ_{i+1} = λ_i + α (C_q q̈ − γ_b), with Baumgarte-stabilised γ_b, four
iterations.  The matrix stays positive definite at singular configurations and with redundant
constraints, so the multipliers stay in the range of C_q (minimum-norm multipliers).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.system.equations import System
from casmbd.system.formulations.base import (
    Formulation,
    FormulationKind,
    _baumgarte_gamma,
    _dyn,
    _forces,
    _sym_inputs,
)
from casmbd.system.formulations.kkt_ode import kkt_ode


def augmented_lagrangian(system: System, penalty: float | None = None, iterations: int = 4,
                         alpha: float = 20.0, beta: float = 20.0,
                         inputs: ca.SX | None = None) -> Formulation:
    """ODE on (q, v) by the augmented-Lagrangian iteration with Baumgarte terms.

    ``penalty`` defaults to 1e5 times the ratio of the mean mass-matrix diagonal to the mean
    diagonal of C_qᵀ C_q at the initial guess, so that it is unit-consistent.  Measured
    trade-off (docs/performance.md): a larger penalty converges in fewer iterations but makes
    M + α C_qᵀC_q ill-conditioned (cond ≈ α), which puts noise of ≈ cond·ε into every
    right-hand side; a smaller one leaves weakly constrained modes unconverged.  At rtol 1e-12:
    1e7 with 3 iterations floored the 8-rod chain's tip error at 6e-10 (25 000 Adams steps);
    1e4 with 4 floored the 32-rod chain at 5e-7; 1e5 with 4 reaches 8e-12 (8 rods) and 1e-10
    (32 rods).
    """
    t, q, v, pu = _sym_inputs(system)
    if system.nc == 0:
        return kkt_ode(system, inputs=inputs)
    cq = system.constraint_jacobian
    if penalty is None:
        penalty = _default_penalty(system)
    if not (np.isfinite(penalty) and penalty > 0):
        raise ModelError(f"augmented_lagrangian: penalty must be > 0, got {penalty}")
    gamma_b = _baumgarte_gamma(system, alpha, beta)
    k_mat = system.mass_matrix + penalty * ca.mtimes(cq.T, cq)
    parts = ca.Function("al_parts", [t, q, v, pu], [k_mat, _forces(system, inputs), cq, gamma_b])
    tm, qm, vm, pm = (ca.MX.sym(n, s.sparsity()) for n, s in
                      (("t", t), ("q", q), ("v", v), ("p", pu)))
    k_x, f_x, cq_x, g_x = parts(tm, qm, vm, pm)
    solver = ca.Linsol("al_ldl", "ldl", k_mat.sparsity())
    lam = ca.MX.zeros(system.nc)
    acc = None
    for _ in range(iterations):
        acc = solver.solve(k_x, f_x - ca.mtimes(cq_x.T, lam) + penalty * ca.mtimes(cq_x.T, g_x))
        lam = lam + penalty * (ca.mtimes(cq_x, acc) - g_x)
    f = _dyn("dyn_augmented_lagrangian", tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm,
             ca.vertcat(vm, acc), ca.MX(0, 1))
    return Formulation("augmented_lagrangian", "ode", f, system.nq, 0, [],
                       {"penalty": penalty, "iterations": iterations, "alpha": alpha,
                        "beta": beta})


def _default_penalty(system: System) -> float:
    q0 = system.initial_coordinates()
    f = ca.Function("scale", [system.q, system.t, system.p],
                    [ca.diag(system.mass_matrix), ca.sum1(system.constraint_jacobian**2).T])
    m_diag, c_diag = (np.asarray(x).ravel() for x in f(q0, 0.0, system.parameter_values))
    if not m_diag.size:  # no coordinates (every body welded, joint coordinates): K is 0 × 0
        return 1.0
    c_mean = float(np.mean(c_diag[c_diag > 0])) if np.any(c_diag > 0) else 1.0
    with np.errstate(all="ignore"):
        penalty = 1e5 * float(np.mean(m_diag)) / c_mean
    if not (np.isfinite(penalty) and penalty > 0):
        # absurd masses, inertias or positions (1e308): name the coordinates that carry them
        names = system.coordinate_names
        i, j = int(np.argmax(np.abs(m_diag))), int(np.argmax(np.abs(c_diag)))
        raise ModelError(f"augmented_lagrangian: no usable penalty ({penalty:g}) from the "
                         f"initial pose: mass-matrix diagonal up to {m_diag[i]:g} (coordinate "
                         f"'{names[i]}'), C_q^T C_q diagonal up to {c_diag[j]:g} (coordinate "
                         f"'{names[j]}'); a mass, inertia or position is out of range")
    return penalty


class AugmentedLagrangian(FormulationKind):
    """Augmented-Lagrangian ODE; keeps redundant equations (minimum-norm multipliers)."""

    name = "augmented_lagrangian"
    kind = "ode"
    default_integrator = "adams"
    keeps_redundant = True
    kept_redundancy = "minimum-norm multipliers"

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        return augmented_lagrangian(system, inputs=inputs, **options)
