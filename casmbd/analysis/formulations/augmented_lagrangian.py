"""``augmented_lagrangian``: ODE x = (q, v) by the augmented-Lagrangian iteration.

Bayo and García de Jalón (seed 003, mass-orthogonal projections): (M + α C_qᵀ C_q) q̈ = Q −
C_qᵀ λ_i + α C_qᵀ γ_b, λ_{i+1} = λ_i + α (C_q q̈ − γ_b), with Baumgarte-stabilised γ_b, four
iterations.  The matrix stays positive definite at singular configurations and with redundant
constraints, so the multipliers stay in the range of C_q (minimum-norm multipliers).

K = M + α C_qᵀC_q is factorised once (symbolic sparse LDLᵀ, :func:`casadi.ldl`) and every
iteration after the first is written as a correction driven by the residual of the KKT rows
(iterative refinement with K as the preconditioner)::

    q̈₀ = K⁻¹ (Q + α C_qᵀ γ_b),    λ₀ = 0,
    λᵢ = λᵢ₋₁ + α (C_q q̈ᵢ₋₁ − γ_b),
    q̈ᵢ = q̈ᵢ₋₁ + K⁻¹ (Q − M q̈ᵢ₋₁ − C_qᵀ λᵢ − α C_qᵀ (C_q q̈ᵢ₋₁ − γ_b)),

which is the same iteration in exact arithmetic.  Solving for q̈ itself puts the rounding
error of the factorisation, ≈ cond(K) ε ≈ 1e5 ε, into every right-hand side (measured 1e-11
relative on the four-bar and the 8-rod chain); the correction form only solves for the
shrinking corrections, so q̈ matches the exact KKT solution to ≈ 1e-14 relative.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.analysis.formulations.base import (
    Formulation,
    FormulationKind,
    baumgarte_acceleration_rhs,
    dae_function,
    generalized_forces,
    symbolic_arguments,
)
from casmbd.analysis.formulations.kkt_ode import kkt_ode
from casmbd.errors import ModelError
from casmbd.model.needs import ALL_NEEDS
from casmbd.system.equations import System

#: extra corrections near singular poses (``refine``; the four-bar's crank error at rtol
#: 1e-13: 1.8e-8 → 2.3e-10, docs/hard_cases.md) and the error left by the regular
#: iterations, relative to max |q̈|, above which they run
REFINE = 290
REFINE_TOLERANCE = 1e-14
#: the refinement runs only at states this consistent: max(‖C‖∞, ‖Ċ‖∞ / (2 α_B + 1)) ≤ it
REFINE_DRIFT = 1e-10


def augmented_lagrangian(system: System, penalty: float | None = None,
                         iterations: int | None = None, refine: int | None = None,
                         refine_drift: float | None = REFINE_DRIFT,
                         alpha: float = 20.0, beta: float = 20.0,
                         inputs: ca.SX | None = None) -> Formulation:
    """ODE on (q, v) by the augmented-Lagrangian iteration with Baumgarte terms.

    ``penalty`` defaults to 1e5 times the ratio of the mean mass-matrix diagonal to the mean
    diagonal of C_qᵀ C_q at the initial guess, so that it is unit-consistent.  A constraint
    direction with singular value σ of C_q converges at the rate 1/(1 + α σ²/m) per
    iteration; ``iterations`` defaults to 10 when K is factorised once (one factorisation,
    then cheap corrections: the module docstring), which converges every benchmark problem at
    regular poses to the exact KKT q̈ within ≈ 1e-15 relative
    (tests/analysis/formulations/test_al_accuracy.py; the
    spatial 8-rod chain, whose slowest direction has α σ²/m ≈ 26, was still 1e-6 off with 4),
    and to 4 when K is too large for the straight-line factorisation and every solve
    re-factorises it (:data:`SYMBOLIC_LIMIT`).  Near a singular pose
    σ → 0 and that direction stays unconverged: the regularisation that keeps the motion on
    its branch (docs/dynamics.md, "Accuracy of the right-hand side").  Where that direction
    carries load (the four-bar in joint coordinates: the cut joint's force along the
    collinear links), q̈ is off by ≈ σ Δλ within |σ| ≲ √(m/α) — 3e-3 m/s² on the exact
    trajectory 1e-3 rad from the pose — and the motion gains ≈ 1.7e-9 J per pass whatever
    the tolerance.  ``refine`` more corrections (default :data:`REFINE` with the shared
    factorisation, 0 when every solve re-factorises) run where the last two say the
    iteration is not done (:func:`_refined`) and the state is consistent,
    max(‖C‖∞, ‖Ċ‖∞/(2α + 1)) ≤ ``refine_drift`` (:data:`REFINE_DRIFT`; ``None``: at any
    state): the window narrows by √(1 + refine/10) (290: below 1e-13 at 1e-3 rad, 1.2e-3 at
    1e-4 rad) and the four-bar's default path reaches 2.3e-10 at rtol 1e-13 (1.8e-8 without).
    The gate matters: refined at any state, the narrower window is a sharper feature of the
    right-hand side and loose-tolerance runs leave their accuracy (median crank error at
    rtol 1e-6 over eight runs: 1.6 rad against 2.6e-2 unrefined, 1.8e-2 gated), since a
    state that far off the constraints carries errors the unconverged direction must not
    resolve.  At regular poses the switch is idle and q̈ bit-identical
    (tests/analysis/formulations/test_al_refine.py).

    Raises
    ------
    ModelError
        For a penalty that is not a positive finite number, ``iterations`` < 1,
        ``refine`` < 0 or a ``refine_drift`` that is not a positive number.
    """
    t, q, v, pu = symbolic_arguments(system)
    if system.nc == 0:
        return kkt_ode(system, inputs=inputs)
    cq = system.constraint_jacobian
    if penalty is None:
        penalty = _default_penalty(system)
    if not (np.isfinite(penalty) and penalty > 0):
        raise ModelError(f"augmented_lagrangian: penalty must be > 0, got {penalty}")
    if not (iterations is None or (isinstance(iterations, (int, np.integer))
            and iterations >= 1)):
        raise ModelError(f"augmented_lagrangian: iterations must be an integer >= 1, got "
                         f"{iterations!r}")
    if not (refine is None or (isinstance(refine, (int, np.integer)) and refine >= 0)):
        raise ModelError(f"augmented_lagrangian: refine must be an integer >= 0, got "
                         f"{refine!r}")
    if not (refine_drift is None or (isinstance(refine_drift, (int, float, np.floating))
                                     and np.isfinite(refine_drift) and refine_drift > 0)):
        raise ModelError(f"augmented_lagrangian: refine_drift must be a number > 0 or None, "
                         f"got {refine_drift!r}")
    gamma_b = baumgarte_acceleration_rhs(system, alpha, beta)
    cdot = ca.mtimes(cq, system.v) + system.constraint_time_derivative
    drift = ca.fmax(ca.norm_inf(system.constraints), ca.norm_inf(cdot) / (2.0 * alpha + 1.0))
    parts = ca.Function("al_parts", [t, q, v, pu],
                        [system.mass_matrix, generalized_forces(system, inputs), cq, gamma_b,
                          drift])
    tm, qm, vm, pm = (ca.MX.sym(n, s.sparsity()) for n, s in
                      (("t", t), ("q", q), ("v", v), ("p", pu)))
    solver = al_solver(system.mass_matrix.sparsity(), cq.sparsity(), penalty, iterations,
                       refine, refine_drift)
    iterations, refine, refine_drift = solver.iterations, solver.refine, solver.refine_drift
    pieces = parts(tm, qm, vm, pm)
    acc = solver(*pieces[:solver.n_in()])
    f = dae_function("dyn_augmented_lagrangian", tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm,
             ca.vertcat(vm, acc), ca.MX(0, 1))
    return Formulation("augmented_lagrangian", "ode", f, system.nq, 0, [],
                       {"penalty": penalty, "iterations": iterations, "refine": refine,
                        "refine_drift": refine_drift,
                        "alpha": alpha,
                        "beta": beta})


#: largest factorisation of K (SX instructions of :func:`casadi.ldl`) generated as
#: straight-line C and shared by the iterations.  Above it every solve calls CasADi's sparse
#: LDLᵀ routine, which re-factorises K (compact code, 4 iterations by default): the
#: straight-line code grows like the factorisation's operations, ~2.5× the former right-hand
#: side's C (chain of 32 rods: 277 kB against 128 kB, gcc -O2 3.9 s against 1.0 s; 128 rods,
#: 16 500 instructions: 1.2 MB, beyond the size compiled at -O2, casmbd.compiled.units).
SYMBOLIC_LIMIT = 12_000


def al_solver(m_sparsity: ca.Sparsity, cq_sparsity: ca.Sparsity, penalty: float,
              iterations: int | None = None, refine: int | None = 0,
              refine_drift: float | None = None) -> ca.Function:
    """The augmented-Lagrangian solve ``al_solve(M, Q, C_q, γ_b) -> q̈`` (an MX Function).

    K = M + α C_qᵀC_q is factorised once by a sparse LDLᵀ with an approximate-minimum-degree
    ordering (:func:`casadi.ldl`, symbolic, code-generable; K is symmetric positive definite
    for α > 0 whenever M is, also for a rank-deficient C_q), then ``iterations`` solves in the
    residual (correction) form of the module docstring.  Two SX Functions — the
    factorisation and one correction — are generated once each and the correction is called
    ``iterations`` times (the first call, from q̈ = 0 and λ = α γ_b, is the first solve), so
    the C code does not grow with the iteration count.  When the factorisation exceeds
    :data:`SYMBOLIC_LIMIT` instructions, the corrections use ``casadi.Linsol("ldl")`` instead,
    which re-factorises K at every solve.  The returned Function has an ``iterations``
    attribute (the count used).

    Parameters
    ----------
    m_sparsity, cq_sparsity : casadi.Sparsity
        Patterns of M (n × n, symmetric) and C_q (m × n).
    penalty : float
        α > 0.
    iterations : int, optional
        Solves with K (≥ 1); the multipliers are updated between them.  Default: 10 with
        the shared factorisation, 4 when every solve re-factorises.
    refine : int or None, optional
        More corrections where the iteration has not converged (:func:`_refined`); ``None``:
        :data:`REFINE` with the shared factorisation, 0 otherwise.
    refine_drift : float, optional
        With it the Function takes a fifth input, the state's drift, and refines only where
        that is at most ``refine_drift``.
    """
    n, nc = m_sparsity.size1(), cq_sparsity.size1()
    m_mat = ca.SX.sym("M", m_sparsity)
    forces = ca.SX.sym("Q", n)
    cq = ca.SX.sym("Cq", cq_sparsity)
    gamma = ca.SX.sym("gamma", nc)
    k_mat = m_mat + penalty * ca.mtimes(cq.T, cq)
    d, lt, perm = ca.ldl(k_mat, True)
    factor = ca.Function("al_factor", [m_mat, cq], [d, lt])
    shared = factor.n_instructions() <= SYMBOLIC_LIMIT
    if iterations is None:
        iterations = 10 if shared else 4
    if refine is None:
        refine = REFINE if shared else 0
    if not refine:
        refine_drift = None
    d_s, lt_s = ca.SX.sym("D", d.sparsity()), ca.SX.sym("LT", lt.sparsity())
    acc, lam = ca.SX.sym("a", n), ca.SX.sym("lambda", nc)
    violation = ca.mtimes(cq, acc) - gamma
    lam_next = lam + penalty * violation
    residual = (forces - ca.mtimes(m_mat, acc) - ca.mtimes(cq.T, lam_next)
                - penalty * ca.mtimes(cq.T, violation))
    drift_m = ca.MX.sym("drift")
    mm, fm, cm, gm = (ca.MX.sym(name, x.sparsity()) for name, x in
                      (("M", m_mat), ("Q", forces), ("Cq", cq), ("gamma", gamma)))
    # from q̈ = 0, λ = α γ_b the first correction is the first solve K⁻¹ (Q + α C_qᵀ γ_b), λ = 0
    acc_x, lam_x = ca.MX.zeros(n), penalty * gm
    if shared:
        correct = ca.Function("al_correct", [acc, lam, m_mat, forces, cq, gamma, d_s, lt_s],
                              [acc + ca.ldl_solve(residual, d_s, lt_s, perm), lam_next])
        factors = list(factor(mm, cm))

        def corrections(a, lam_, data, count):
            for _ in range(count):
                a, lam_ = correct(a, lam_, *data)
            return a, lam_
    else:
        step = ca.Function("al_residual", [acc, lam, m_mat, forces, cq, gamma],
                           [residual, lam_next])
        linsol = ca.Linsol("al_ldl", "ldl", k_mat.sparsity())
        factors = [mm + penalty * ca.mtimes(cm.T, cm)]

        def corrections(a, lam_, data, count):
            for _ in range(count):
                res_x, lam_ = step(a, lam_, *data[:4])
                a = a + linsol.solve(data[4], res_x)
            return a, lam_
    data = [mm, fm, cm, gm, *factors]
    if refine and nc and iterations >= 2:
        acc_x, lam_x = corrections(acc_x, lam_x, data, iterations - 2)
        before, (acc_x, lam_x) = acc_x, corrections(acc_x, lam_x, data, 1)
        last, (acc_x, lam_x) = acc_x, corrections(acc_x, lam_x, data, 1)
        acc_x = _refined(acc_x, lam_x, [last - before, acc_x - last], data, corrections,
                         refine, None if refine_drift is None else (drift_m, refine_drift))
    else:
        acc_x, lam_x = corrections(acc_x, lam_x, data, iterations)
    ins, names = [mm, fm, cm, gm], ["M", "Q", "Cq", "gamma"]
    if refine_drift is not None:
        ins, names = [*ins, drift_m], [*names, "drift"]
    solver = ca.Function("al_solve", ins, [acc_x], names, ["a"])
    solver.iterations = iterations
    solver.refine, solver.refine_drift = refine, refine_drift
    return solver


def _refined(acc: ca.MX, lam: ca.MX, changes: list, data: list, corrections,
             refine: int, gate=None) -> ca.MX:
    """``refine`` more corrections when the iteration has not converged: with the changes
    d₉, d₁₀ of the last two corrections (max norm) and their ratio ρ = d₁₀/d₉ (the slowest
    contraction rate 1/(1 + α σ²/m)), the error left is ≈ d₁₀ ρ/(1 − ρ); more corrections
    run when that exceeds :data:`REFINE_TOLERANCE` of max |q̈| — near a singular pose, where
    σ → 0 and ρ → 1.  At regular poses ρ ≤ 0.04 and the test costs three norms.  The branch
    is a Switch with explicit inputs (:meth:`casadi.Function.conditional`), evaluated only
    when taken."""
    syms = [ca.MX.sym(f"x{i}", x.sparsity()) for i, x in enumerate([acc, lam, *data])]
    more = ca.Function("al_refine", syms, [corrections(syms[0], syms[1], syms[2:], refine)[0]])
    done = ca.Function("al_done", syms, [syms[0]])
    # case 0: more corrections, default: q̈ as it is (explicit inputs, so that neither branch
    # recomputes the iterations before it)
    switch = ca.Function.conditional("al_refine_switch", [more], done)
    previous, change = (ca.norm_inf(c) for c in changes)
    bound = REFINE_TOLERANCE * ca.norm_inf(acc)
    # geometric tail: with the rate ρ = change / previous, the error left is ≈ change ρ/(1 − ρ)
    slow = ca.logic_and(change > bound, change * change > bound * (previous - change))
    if gate is not None:
        slow = ca.logic_and(slow, gate[0] <= gate[1])
    return switch(1 - slow, acc, lam, *data)


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
    handles = ALL_NEEDS - {"reaction_forces", "contact_friction"}
    refuses = dict.fromkeys(("reaction_forces", "contact_friction"), "an ODE formulation does "
                            "not solve for the multipliers the friction level needs")
    instead = dict.fromkeys(("reaction_forces", "contact_friction"),
                            "formulation 'index1' (or 'ggl')")
    kind = "ode"
    default_integrator = "adams"
    keeps_redundant = True
    kept_redundancy = "minimum-norm multipliers"

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        return augmented_lagrangian(system, inputs=inputs, **options)

    def built_from_values(self, options: dict) -> bool:
        """The default penalty is computed from the parameter values at build time."""
        return "penalty" not in options
