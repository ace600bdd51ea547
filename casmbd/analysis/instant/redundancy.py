"""Rank of the constraint Jacobian, degrees of freedom and dependent (redundant) equations.

Seed 000 ("Coordinate partitioning", Gaussian elimination with full pivoting) and seed 002
("Redundant constraint equations"): the number of degrees of freedom is n_q − rank(C_q); rows of
C_q that are linear combinations of earlier rows are redundant.  The rank comes from the singular
values with a tolerance relative to the Jacobian's scale; the dependent rows are found by a
sequential Gram–Schmidt sweep in declaration order, so that the later of two duplicate joints is
named.

Large Jacobians (more than :data:`DENSE_MAX_ENTRIES` entries, e.g. a chain of a few hundred
bodies) are analysed without forming the dense matrix: a row-merge Givens QR of C_qᵀ (Q-less,
George and Heath) gives the same sweep in declaration order — |R_jj| is the distance of row j
from the span of the rows before it — in time and memory linear in the number of non-zeros for
chains and trees, where the dense SVD is cubic (18 s for 500 bodies, 643 s for 5000).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from casmbd.lazy import lazy_module

sp = lazy_module("scipy.sparse")

#: relative tolerance on singular values / residual norms, times the largest singular value
RANK_RTOL = 1e-8
#: C_q with at most this many entries (n_c · n_q) is analysed densely (SVD, Gram–Schmidt);
#: larger ones by the sparse Givens sweep of :func:`sparse_rank_report` (about 0.1 s at this
#: size either way; the dense cost grows with the cube of the size, the sparse one linearly)
DENSE_MAX_ENTRIES = 250_000
#: a row of C_q whose norm is at most this times the largest row norm is rounding noise (an
#: equation that no coordinate moves, e.g. the point of a universal joint on two fixed shaft
#: axes: ~3e-17 where the other rows are ~1) and counts as zero: equilibrating it to unit norm
#: would make noise an independent equation and hide a genuine one behind it
ZERO_ROW_RTOL = 1e-12
#: entries of the equilibrated factor below this are dropped in the sparse sweep (a backward
#: error far below ``RANK_RTOL``; it keeps rounding noise from filling the rows)
_DROP = 1e-15


@dataclass
class RankReport:
    """Rank analysis of C_q at one configuration."""

    n_coordinates: int
    n_equations: int
    rank: int
    dependent_rows: list[int]
    smallest_singular_value: float
    largest_singular_value: float

    @property
    def degrees_of_freedom(self) -> int:
        """n_q − rank(C_q)."""
        return self.n_coordinates - self.rank


def _dense(matrix) -> np.ndarray:
    return matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix, dtype=float)


def zero_noise_rows(a: np.ndarray) -> np.ndarray:
    """``a`` (dense) with the rows of norm at most :data:`ZERO_ROW_RTOL` times the largest set
    to zero (a copy when any is)."""
    if a.shape[0] == 0:
        return a
    norms = np.linalg.norm(a, axis=1)
    noise = (norms <= ZERO_ROW_RTOL * float(np.max(norms))) & (norms > 0.0)
    if np.any(noise):
        a = a.copy()
        a[noise] = 0.0
    return a


def rank_report(jacobian, rtol: float = RANK_RTOL, method: str = "auto") -> RankReport:
    """Numerical rank of C_q and the rows that depend on earlier rows.

    Parameters
    ----------
    jacobian : array or sparse matrix, shape (n_c, n_q)
    rtol : float
        A singular value (or Gram–Schmidt residual norm) below ``rtol * σ_max`` of the row- and
        column-equilibrated matrix counts as zero.
    method : {"auto", "dense", "sparse"}
        ``"dense"``: SVD and Gram–Schmidt on the dense matrix; ``"sparse"``:
        :func:`sparse_rank_report`; ``"auto"``: dense up to :data:`DENSE_MAX_ENTRIES` entries.
    """
    m, n = jacobian.shape
    if method not in ("auto", "dense", "sparse"):
        raise ValueError(f"rank_report: method must be 'auto', 'dense' or 'sparse', "
                         f"got {method!r}")
    if method == "sparse" or (method == "auto" and m * n > DENSE_MAX_ENTRIES):
        return sparse_rank_report(jacobian, rtol)
    a = zero_noise_rows(_dense(jacobian))
    if m == 0:
        return RankReport(n, 0, 0, [], 0.0, 0.0)
    # Equilibrate rows and columns (rank-preserving) so that mixed units — lengths and angles,
    # millimetres and kilometres — do not decide what counts as zero.
    for axis in (1, 0):
        norms = np.linalg.norm(a, axis=axis)
        norms[norms == 0.0] = 1.0
        a = a / (norms[:, None] if axis == 1 else norms[None, :])
    sigma = np.linalg.svd(a, compute_uv=False)
    smax = float(sigma[0]) if sigma.size else 0.0
    tol = rtol * max(smax, 1e-300)
    rank = int(np.sum(sigma > tol))
    smin = float(sigma[min(m, n) - 1]) if sigma.size else 0.0
    dependent: list[int] = []
    if rank < m:
        basis = np.zeros((n, rank))
        k = 0
        for i in range(m):
            r = a[i].copy()
            if k:
                r -= basis[:, :k] @ (basis[:, :k].T @ r)
                r -= basis[:, :k] @ (basis[:, :k].T @ r)
            norm = float(np.linalg.norm(r))
            if norm <= tol or k == rank:
                dependent.append(i)
            else:
                basis[:, k] = r / norm
                k += 1
    return RankReport(n, m, rank, dependent, smin, smax)


def _equilibrated_sparse(jacobian) -> sp.csr_matrix:
    """C_q with unit-norm rows, then unit-norm columns (as :func:`rank_report` does densely)."""
    a = sp.csr_matrix(jacobian, dtype=float)
    rows = np.sqrt(np.asarray(a.multiply(a).sum(axis=1)).ravel())
    if rows.size and np.any((rows > 0) & (rows <= ZERO_ROW_RTOL * float(np.max(rows)))):
        keep = np.where(rows <= ZERO_ROW_RTOL * float(np.max(rows)), 0.0, 1.0)
        a = sp.csr_matrix(sp.diags(keep) @ a)
        a.eliminate_zeros()
    for axis in (1, 0):
        norms = np.sqrt(np.asarray(a.multiply(a).sum(axis=axis)).ravel())
        norms[norms == 0.0] = 1.0
        a = sp.diags(1.0 / norms) @ a if axis == 1 else a @ sp.diags(1.0 / norms)
    return sp.csr_matrix(a)


def _largest_singular_value(a: sp.csr_matrix, iterations: int = 50) -> float:
    """σ_max by power iteration on A Aᵀ from a fixed pseudo-random start (a lower bound that
    is within a few per cent after a few dozen iterations — enough for ``rtol · σ_max``)."""
    x = np.random.default_rng(0).uniform(0.5, 1.5, a.shape[0])
    at = sp.csr_matrix(a.T)
    sigma = 0.0
    for _ in range(iterations):
        x = a @ (at @ x)
        norm = float(np.linalg.norm(x))
        if norm == 0.0:
            break
        sigma, x = math.sqrt(norm), x / norm
    return sigma


def _merge(factor: list, row: dict) -> None:
    """Rotate the sparse ``row`` ({column: value}) into the upper-triangular ``factor`` (a list
    of such rows, None where empty) by Givens rotations until it vanishes or fills a gap."""
    while row:
        k = min(row)
        pivot = factor[k]
        if pivot is None:
            factor[k] = row
            return
        a, b = pivot[k], row.pop(k)
        r = math.hypot(a, b)
        c, s = a / r, b / r
        pivot[k] = r
        rest = {}
        for j in pivot.keys() | row.keys():
            if j == k:
                continue
            u, v = pivot.get(j, 0.0), row.get(j, 0.0)
            pivot[j] = c * u + s * v
            w = c * v - s * u
            if abs(w) > _DROP:
                rest[j] = w
        row = rest


def sparse_rank_report(jacobian, rtol: float = RANK_RTOL) -> RankReport:
    """:func:`rank_report` in time linear in the non-zeros of C_q for chains and trees.

    The rows of the equilibrated C_qᵀ (one per coordinate, sorted by their first constraint)
    are merged by Givens rotations into the triangular factor R of C_qᵀ = QR (Q is never
    formed, so nothing fills beyond R, which is banded for a chain).  For every QR,
    |R_jj| <= the distance of constraint row j from the span of the rows before it, with
    equality up to the first dependent row; a row with |R_jj| <= ``rtol · σ_max`` is therefore
    declared dependent in declaration order, and its remaining entries are rotated back into
    the later rows (deleting column j of C_qᵀ), which restores equality for the rows after
    it.  ``smallest_singular_value`` is the smallest |R_jj| of the independent rows (an upper
    bound of σ_min; 0 when rows are dependent); ``largest_singular_value`` is estimated by
    power iteration.
    """
    m, n = jacobian.shape
    if m == 0:
        return RankReport(n, 0, 0, [], 0.0, 0.0)
    a = _equilibrated_sparse(jacobian)
    smax = _largest_singular_value(a)
    tol = rtol * max(smax, 1e-300)
    bt = sp.csr_matrix(a.T)
    bt.eliminate_zeros()
    rows = [dict(zip(bt.indices[bt.indptr[i]:bt.indptr[i + 1]].tolist(),
                     bt.data[bt.indptr[i]:bt.indptr[i + 1]].tolist()))
            for i in range(n) if bt.indptr[i + 1] > bt.indptr[i]]
    rows.sort(key=min)
    factor: list = [None] * m
    for row in rows:
        _merge(factor, row)
    dependent: list[int] = []
    smin = math.inf
    for j in range(m):
        row = factor[j]
        diagonal = abs(row[j]) if row is not None else 0.0
        if diagonal > tol:
            smin = min(smin, diagonal)
            continue
        dependent.append(j)
        if row is not None:
            factor[j] = None
            _merge(factor, {k: v for k, v in row.items() if k != j and abs(v) > _DROP})
    smin = 0.0 if dependent or not math.isfinite(smin) else smin
    return RankReport(n, m, m - len(dependent), dependent, smin, smax)


def null_space_basis(jacobian, rtol: float = RANK_RTOL) -> tuple[np.ndarray, int]:
    """Orthonormal basis N of ker C_q (columns) and the rank of C_q.

    Rows are normalised first (which does not change the null space) so that equations in
    different units weigh alike; a singular value counts as zero below ``rtol · σ_max``.
    """
    a = zero_noise_rows(_dense(jacobian))
    m, n = a.shape
    if m == 0:
        return np.eye(n), 0
    norms = np.linalg.norm(a, axis=1)
    norms[norms == 0.0] = 1.0
    a = a / norms[:, None]
    _, sigma, vt = np.linalg.svd(a, full_matrices=True)
    smax = float(sigma[0]) if sigma.size else 0.0
    rank = int(np.sum(sigma > rtol * max(smax, 1e-300)))
    return vt[rank:].T.copy(), rank


#: conditioning σ_r/σ_1 below which a configuration is reported as near-singular
NEAR_SINGULAR = 1e-4
#: :func:`conditioning` evaluates at most FLOP_BUDGET / (n_small² n_large) output steps
#: (about 0.1 s; never fewer than MIN_SAMPLES), evenly spaced, plus the steps it is given
FLOP_BUDGET = 1e8
MIN_SAMPLES = 50


def equilibration(jacobian) -> tuple[np.ndarray, np.ndarray]:
    """Row and column factors (r, c) that give C_q unit-norm rows, then unit-norm columns:
    diag(r) C_q diag(c)."""
    a = _dense(jacobian)
    rows = np.linalg.norm(a, axis=1)
    rows = 1.0 / np.where(rows == 0.0, 1.0, rows)
    cols = np.linalg.norm(a * rows[:, None], axis=0)
    cols = 1.0 / np.where(cols == 0.0, 1.0, cols)
    return rows, cols


def equilibrated_singular_values(jacobian, scaling=None) -> np.ndarray:
    """Singular values (descending) of diag(r) C_q diag(c).

    Without ``scaling`` the factors are C_q's own (:func:`equilibration`: unit-norm rows and
    columns).  Along a trajectory pass the factors of a regular reference configuration
    instead: a singular pose where whole rows of C_q vanish (a loop closure in joint
    coordinates with all links aligned) keeps its small singular values, whereas rescaling
    those rows to unit norm would hide the rank loss.
    """
    a = _dense(jacobian)
    rows, cols = equilibration(a) if scaling is None else scaling
    return np.linalg.svd(a * rows[:, None] * cols[None, :], compute_uv=False)


def conditioning(model, qs: np.ndarray, grid: np.ndarray, rank: int | None = None,
                 extra=()) -> np.ndarray:
    """σ_rank/σ_1 of the equilibrated C_q along a trajectory (NaN where not evaluated).

    The row and column factors are those of the first step (:func:`equilibration`, the
    regular reference configuration), the same at every step, so that rows of C_q that vanish
    at a singular pose show as a small σ (:func:`equilibrated_singular_values`).
    ``rank`` is the rank of the regular configurations (default: at the first step), so that
    redundant equations, which make C_q rank deficient everywhere, do not count as a
    singularity: the ratio measures how close the independent equations come to losing rank
    (seed 000, singular configurations of closed chains).  Small systems are checked at every
    output step, large ones on an evenly spaced subset that fits :data:`FLOP_BUDGET` plus the
    steps ``extra``.
    """
    n = len(grid)
    out = np.full(n, np.nan)
    if model.nc == 0 or n == 0:
        return out
    small, large = sorted((model.nc, model.nq))
    budget = max(MIN_SAMPLES, int(FLOP_BUDGET / (small * small * large)))
    if n <= budget:
        steps = np.arange(n)
    else:
        steps = np.unique(np.concatenate([np.linspace(0, n - 1, budget).astype(int),
                                          np.asarray(list(extra), dtype=int)]))
    steps = np.asarray(steps, dtype=int)
    rows, cols = reference_equilibration(model, qs, grid)
    for chunk in np.array_split(steps, max(1, len(steps) // 64)):
        mats = np.stack([_dense(model.constraint_jacobian(qs[k], float(grid[k])))
                         for k in chunk]) * rows[None, :, None] * cols[None, None, :]
        # σ² are the eigenvalues of the Gram matrix: one batched LAPACK call, and the ratio
        # is resolved down to ~1e-8, far below the reporting threshold
        gram = mats @ np.swapaxes(mats, 1, 2) if mats.shape[1] <= mats.shape[2] else \
            np.swapaxes(mats, 1, 2) @ mats
        sigma = np.sqrt(np.clip(np.linalg.eigvalsh(gram)[:, ::-1], 0.0, None))
        if rank is None:
            rank = int(np.sum(sigma[0] > RANK_RTOL * sigma[0, 0]))
        if rank >= 1:
            out[chunk] = sigma[:, rank - 1] / np.where(sigma[:, 0] > 0, sigma[:, 0], np.inf)
    return out


def reference_equilibration(model, qs: np.ndarray, grid: np.ndarray):
    """:func:`equilibration` of C_q at the trajectory's first step (the reference)."""
    return equilibration(model.constraint_jacobian(qs[0], float(grid[0])))


#: grid minima of the conditioning above this are not refined (a passage within one output
#: interval of a singular pose shows on the grid as a dip well below it)
REFINE_BELOW = 0.2


def near_singular_passes(model, grid: np.ndarray, qs: np.ndarray, vs: np.ndarray,
                         cond: np.ndarray, rank: int | None,
                         threshold: float = NEAR_SINGULAR) -> list[tuple[float, float]]:
    """Passages close to a singular configuration, located between output times.

    Every local minimum of ``cond`` on the output grid is refined on the cubic Hermite
    interpolant of q through its neighbours (q and q̇ at both ends, O(h⁴)) by a bounded scalar
    minimisation of the conditioning; minima below ``threshold`` are returned as (time,
    conditioning).  In a subsampled run the output steps between the evaluated neighbours of a
    minimum are evaluated first and only the two intervals around the smallest are refined
    (refining every interval cost 190 s of a 0.2 s run of the 40-window four-bar in absolute
    coordinates).  σ comes from the eigenvalues of the Gram matrix, as in
    :func:`conditioning`.  The located conditioning is an estimate limited by the interpolation
    error, so a coarse output grid reports a passage with a larger value than a fine one.
    """
    out: list[tuple[float, float]] = []
    n = len(grid)
    if n < 3 or rank is None:
        return out
    scaling = reference_equilibration(model, qs, grid)  # the factors of :func:`conditioning`

    rows, cols = scaling

    def ratio(q: np.ndarray, t: float) -> float:
        a = _dense(model.constraint_jacobian(q, float(t))) * rows[:, None] * cols[None, :]
        gram = a @ a.T if a.shape[0] <= a.shape[1] else a.T @ a
        sigma = np.sqrt(np.clip(np.linalg.eigvalsh(gram)[::-1], 0.0, None))
        return float(sigma[rank - 1] / sigma[0]) if sigma[0] > 0 else 0.0

    def at(k: int, t: float) -> float:
        return ratio(hermite(k, t), t)

    def hermite(k: int, t: float) -> np.ndarray:
        h = grid[k + 1] - grid[k]
        s = (t - grid[k]) / h
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * qs[k] + h10 * h * vs[k] + h01 * qs[k + 1] + h11 * h * vs[k + 1]

    def at_svd(k: int, t: float) -> float:
        sigma = equilibrated_singular_values(model.constraint_jacobian(hermite(k, t), t),
                                             scaling)
        return float(sigma[rank - 1] / sigma[0]) if sigma[0] > 0 else 0.0

    evaluated = np.flatnonzero(np.isfinite(cond))  # a subsampled run: minima among these
    for i, k in enumerate(evaluated):
        c = cond[k]
        left = cond[evaluated[i - 1]] if i > 0 else np.inf
        right = cond[evaluated[i + 1]] if i + 1 < len(evaluated) else np.inf
        if not (c <= left and c < right and c < REFINE_BELOW):
            continue
        lo = evaluated[i - 1] if i > 0 else k
        hi = evaluated[i + 1] if i + 1 < len(evaluated) else k
        best_t, best_c = float(grid[k]), float(c)
        if hi - lo > 2:  # subsampled: the smallest output step between the neighbours
            inner = {j: cond[j] if np.isfinite(cond[j]) else ratio(qs[j], grid[j])
                     for j in range(lo, hi + 1)}
            m = min(inner, key=inner.get)
            lo, hi = max(lo, m - 1), min(hi, m + 1)
        # here, not at the top: scipy.optimize takes 0.3 s to import and most runs refine
        # nothing (a 1000-rod chain's cached run: a fifth of the process)
        from scipy.optimize import minimize_scalar

        for j in range(lo, hi):
            res = minimize_scalar(lambda t, j=j: at(j, t), bounds=(grid[j], grid[j + 1]),
                                  method="bounded", options={"xatol": 1e-9 * (1 + abs(grid[j]))})
            if res.fun < best_c:
                best_t, best_c, best_j = float(res.x), float(res.fun), j
        if best_c < threshold:
            if best_t != grid[k]:  # the Gram matrix resolves σ to ~1e-8 σ_1: the SVD there
                best_c = at_svd(best_j, best_t)
            out.append((best_t, best_c))
    return out


def near_singular_times(grid: np.ndarray, cond: np.ndarray,
                        threshold: float = NEAR_SINGULAR) -> list[float]:
    """Times of the local minima of ``cond`` below ``threshold`` (one per passage)."""
    times = []
    for k in range(len(grid)):
        c = cond[k]
        if not (np.isfinite(c) and c < threshold):
            continue
        left = cond[k - 1] if k > 0 else np.inf
        right = cond[k + 1] if k + 1 < len(grid) else np.inf
        if c <= (left if np.isfinite(left) else np.inf) and c < (
                right if np.isfinite(right) else np.inf):
            times.append(float(grid[k]))
    return times
