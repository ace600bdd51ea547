"""Position, velocity and acceleration analysis at one instant.

Assembly solves C(q, t) = 0 by Newton-Raphson keeping chosen coordinates fixed: each iteration
solves the sparse system of seed 000, eq. 6.201,

    [C_q; I_d] δq = [−C; 0],

where I_d selects the fixed (independent) coordinates.  When the free part of C_q is square the
step comes from a sparse LU factorisation; otherwise (more free coordinates than equations, as
when assembling an undriven mechanism from approximate positions) it is the minimum-norm step,
so the mechanism moves as little as possible.  A backtracking line search on ‖C‖ guards against
overshooting from rough guesses.  Velocities follow from C_q q̇ = −C_t (eq. 6.204) and
accelerations from C_q q̈ = γ (eq. 6.138).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from casmbd.analysis.instant.checks import nonfinite_values
from casmbd.analysis.instant.culprits import explain as explain_culprits
from casmbd.analysis.instant.redundancy import DENSE_MAX_ENTRIES, rank_report
from casmbd.errors import AssemblyError, CasmbdError, ModelError, SingularConfigurationError
from casmbd.lazy import lazy_module

sla = lazy_module("scipy.linalg")
sp = lazy_module("scipy.sparse")
spla = lazy_module("scipy.sparse.linalg")


@dataclass
class AssemblyReport:
    """Outcome of a position analysis."""

    q: np.ndarray
    iterations: int
    residual: float
    change: np.ndarray


def coordinate_indices(model, fixed: Sequence[str | int] | None) -> np.ndarray:
    """Indices of the coordinates named ``body.x``/``body.y``/``body.angle`` (or given as ints)."""
    names = model.coordinate_names
    out = []
    for item in fixed or ():
        if isinstance(item, (int, np.integer)):
            if not 0 <= item < len(names):
                raise ModelError(f"fixed coordinate index {item} out of range 0..{len(names) - 1}")
            out.append(int(item))
        elif item in names:
            out.append(names.index(item))
        else:
            raise ModelError(f"unknown coordinate '{item}' (coordinates are named like "
                             f"'{names[0]}')")
    return np.array(sorted(set(out)), dtype=int)


def _worst_equations(model, residual: np.ndarray, count: int = 3) -> str:
    labels = model.constraint_labels
    order = np.argsort(-np.abs(residual))[:count]
    return "; ".join(f"{labels[i]} residual {residual[i]:.3g}" for i in order)


def _locked(model, q: np.ndarray, t: float, residual: np.ndarray, free: np.ndarray) -> str:
    """A sentence for an assembly failure where C_q has full column rank at the last iterate:
    no coordinate is left free, so an over-determined set of joints locks the mechanism."""
    jac = model.constraint_jacobian(q, t)[:, free]
    vel = set(getattr(model, "velocity_rows", ()))
    if vel:  # the position equations only
        jac = jac[[i for i in range(model.nc) if i not in vel], :]
    rep = rank_report(jac)
    if rep.rank < len(free) or rep.n_equations <= rep.rank:
        return ""
    labels = model.constraint_labels
    scale = float(np.max(np.abs(residual), initial=0.0))
    joints = sorted({labels[i].element for i in np.flatnonzero(np.abs(residual) > 1e-3 * scale)})
    return (f". The mechanism is locked: {rep.n_equations} equations of rank {rep.rank} = the "
            f"number of free coordinates leave no motion, and the equations of "
            f"{', '.join(repr(j) for j in joints)} cannot all be satisfied together "
            "(remove or free one of these joints)")


def _explain(model, q_start: np.ndarray, q: np.ndarray, t: float, c: np.ndarray,
             free: np.ndarray, tol: float) -> tuple[list, str]:
    """The culprit ranking (:mod:`casmbd.analysis.instant.culprits`) and the rest of the message of
    a failed assembly: most likely culprit first, then the largest residuals at the last
    iterate and, for a locked mechanism, the joints that lock it."""
    try:
        ranked, text = explain_culprits(model, q_start, q, t, free, tol)
    except (CasmbdError, np.linalg.LinAlgError, ValueError, ArithmeticError) as exc:
        ranked, text = [], f" (no culprit ranking: {exc})"
    return ranked, (f"{text}. Largest residuals at the last iterate: "
                    f"{_worst_equations(model, c)}{_locked(model, q, t, c, free)}")


def _culprits(model, t: float) -> str:
    """'': or the model values (driver positions and their derivatives) not finite at t."""
    found = nonfinite_values(model.system, t, model.p)
    return (" — " + "; ".join(found[:3])) if found else ""


def _finite_rows(model, values: np.ndarray, what: str, t: float) -> np.ndarray:
    """Return ``values`` or raise naming the constraint equations where they are not finite
    and the model value behind them."""
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        labels = model.constraint_labels
        names = "; ".join(f"{labels[i]} ({what} = {values[i]})" for i in bad[:3])
        raise AssemblyError(f"non-finite {what} at t = {t:g}: {names}{_culprits(model, t)}")
    return values


def solve_linear(matrix: sp.spmatrix, rhs: np.ndarray, what: str, t: float) -> np.ndarray:
    """Solve a square sparse system, or the minimum-norm least-squares problem otherwise."""
    m, n = matrix.shape
    if m == n:
        try:
            lu = spla.splu(sp.csc_matrix(matrix))
            x = lu.solve(rhs)
            if np.all(np.isfinite(x)):
                return x
        except RuntimeError:
            pass
        raise SingularConfigurationError(f"{what} is singular at t = {t:g}")
    return min_norm_solve(matrix, rhs)


def min_norm_solve(matrix: sp.spmatrix, rhs: np.ndarray) -> np.ndarray:
    """The minimum-norm least-squares solution of ``matrix @ x = rhs``.

    Up to :data:`~casmbd.analysis.instant.redundancy.DENSE_MAX_ENTRIES` entries by a dense SVD-based
    solve (LAPACK ``gelsd``, any rank).  Larger matrices would make that cubic (70 s for one
    Newton step of a driven 500-body chain), so they are solved through the sparse augmented
    system — [[I, Jᵀ], [J, 0]] [x; y] = [0; b] when there are fewer rows than columns (x is the
    minimum-norm solution), [[I, J], [Jᵀ, 0]] [r; x] = [b; 0] otherwise (least squares) —
    with a sparse LU; a rank-deficient J makes that singular, and LSMR (which converges to the
    minimum-norm least-squares solution) takes over.
    """
    m, n = matrix.shape
    if m * n <= DENSE_MAX_ENTRIES:
        x, *_ = sla.lstsq(sp.csc_matrix(matrix).toarray(), rhs, lapack_driver="gelsd")
        return x
    j = sp.csc_matrix(matrix)
    if m < n:
        kkt = sp.bmat([[sp.identity(n), j.T], [j, None]], format="csc")
        b, part = np.concatenate([np.zeros(n), rhs]), slice(0, n)
    else:
        kkt = sp.bmat([[sp.identity(m), j], [j.T, None]], format="csc")
        b, part = np.concatenate([rhs, np.zeros(n)]), slice(m, m + n)
    try:
        x = spla.splu(kkt).solve(b)[part]
        if np.all(np.isfinite(x)):
            return x
    except RuntimeError:  # SuperLU: "Factor is exactly singular" (no CasADi call inside)
        pass
    return spla.lsmr(j, rhs, atol=1e-15, btol=1e-15, maxiter=20 * (m + n))[0]


def assemble(model, q0: np.ndarray, t: float = 0.0, fixed: Sequence[str | int] | None = None,
             tol: float = 1e-11, max_iter: int = 50) -> AssemblyReport:
    """Newton-Raphson on C(q, t) = 0 from ``q0`` keeping the ``fixed`` coordinates.

    The rows a joint writes at the velocity level (``model.velocity_rows``: rolling without
    slipping, a knife edge) restrict no position — their C is identically 0 — and are left
    out of the Newton matrix: the step is the minimum-norm one of the holonomic rows.

    Converged when max |C| <= ``tol`` · max(1, largest |x|, |y|(, |z|)) of the iterate: relative
    to the mechanism's size (default 1e-11), never to the size of a wild guess.

    Raises
    ------
    AssemblyError
        If the iteration does not converge; the message names the most likely culprit first
        (``exc.culprits``, ranked by :func:`casmbd.analysis.instant.culprits.rank_culprits` when the
        message or the list is first used), with what to change, then the constraint equations
        with the largest residuals and the time.
    """
    q = np.array(q0, dtype=float)
    if not np.all(np.isfinite(q)):
        raise AssemblyError(f"assembly at t = {t:g}: the initial coordinates are not finite")
    idx_fixed = coordinate_indices(model, fixed)
    free = np.setdiff1d(np.arange(model.nq), idx_fixed)
    # rows written at the velocity level (rolling without slipping, a knife edge) have C = 0
    # and restrict no position: Newton on the holonomic rows only
    vel_rows = list(getattr(model, "velocity_rows", ()))
    hol_rows = [i for i in range(model.nc) if i not in set(vel_rows)]
    if model.nc == 0 or not hol_rows:
        return AssemblyReport(q, 0, 0.0, np.zeros_like(q))
    # residuals are lengths (or angles): scale the tolerance with the size of the mechanism —
    # at the current iterate, not the guess (a guess extrapolated through a singular pose can
    # be 1e14 m away, which would accept any residual)
    lengths = model.length_indices
    rtol = tol

    def tol_at(x: np.ndarray) -> float:
        return rtol * max(1.0, float(np.max(np.abs(x[lengths]), initial=0.0)))

    tol = tol_at(q)
    c = model.constraints(q, t)
    norm = float(np.max(np.abs(c)))
    it = 0
    while it < max_iter:
        if not np.all(np.isfinite(c)):
            bad = np.flatnonzero(~np.isfinite(c))
            labels = model.constraint_labels
            names = "; ".join(f"{labels[i]} (C = {c[i]})" for i in bad[:3])
            raise AssemblyError(f"assembly at t = {t:g}: constraints are not finite at iteration "
                                f"{it}: {names}{_culprits(model, t)}")
        if norm <= tol:
            break
        jac = model.constraint_jacobian(q, t)[:, free]
        rhs = -c
        if vel_rows:  # velocity-level rows (their C is 0) do not restrict positions
            jac, rhs = jac[hol_rows, :], rhs[hol_rows]
        try:
            step = solve_linear(jac, rhs, "constraint Jacobian", t)
        except SingularConfigurationError:
            step = min_norm_solve(jac, rhs)
        alpha, accepted = 1.0, False
        for _ in range(12):
            trial = q.copy()
            trial[free] += alpha * step
            c_trial = model.constraints(trial, t)
            n_trial = float(np.max(np.abs(c_trial)))
            if (np.isfinite(n_trial) and n_trial < norm * (1 - 1e-4 * alpha)) or \
                    n_trial <= tol_at(trial):
                accepted = True
                break
            alpha *= 0.5
        it += 1
        if not accepted:
            break
        q, c, norm, tol = trial, c_trial, n_trial, tol_at(trial)
    if norm > tol:
        q_start = np.array(q0, dtype=float)

        def explain() -> tuple[list, str]:
            return _explain(model, q_start, q, t, c, free, tol)

        raise AssemblyError(f"cannot assemble at t = {t:g} after {it} Newton iterations "
                            f"(max |C| = {norm:.3g})", explain=explain)
    return AssemblyReport(q, it, norm, q - np.asarray(q0, float))


def velocities(model, q: np.ndarray, t: float, v_guess: np.ndarray | None = None,
               fixed: Sequence[str | int] | None = None) -> np.ndarray:
    """Velocities satisfying C_q q̇ = −C_t closest to ``v_guess`` (fixed entries kept exactly).

    With as many independent equations as coordinates the guess is irrelevant; otherwise the
    guess is projected onto the constraint tangent space with the smallest Euclidean change.
    """
    v0 = np.zeros(model.nq) if v_guess is None else np.array(v_guess, dtype=float)
    if model.nc == 0:
        return v0
    idx_fixed = coordinate_indices(model, fixed)
    free = np.setdiff1d(np.arange(model.nq), idx_fixed)
    jac = model.constraint_jacobian(q, t)
    ct = _finite_rows(model, model.constraint_time_derivative(q, t), "C_t", t)
    residual = -ct - jac @ v0
    dv = solve_linear(jac[:, free], residual, "constraint Jacobian", t)
    v = v0.copy()
    v[free] += dv
    return v


def accelerations(model, q: np.ndarray, v: np.ndarray, t: float,
                  a_guess: np.ndarray | None = None) -> np.ndarray:
    """Accelerations satisfying C_q q̈ = γ closest to ``a_guess`` (zero by default)."""
    a0 = np.zeros(model.nq) if a_guess is None else np.array(a_guess, dtype=float)
    if model.nc == 0:
        return a0
    jac = model.constraint_jacobian(q, t)
    gamma = _finite_rows(model, model.acceleration_rhs(q, v, t), "gamma", t)
    residual = gamma - jac @ a0
    return a0 + solve_linear(jac, residual, "constraint Jacobian", t)
