"""Rank of the constraint Jacobian, degrees of freedom and dependent (redundant) equations.

Seed 000 ("Coordinate partitioning", Gaussian elimination with full pivoting) and seed 002
("Redundant constraint equations"): the number of degrees of freedom is n_q − rank(C_q); rows of
C_q that are linear combinations of earlier rows are redundant.  The rank comes from the singular
values with a tolerance relative to the Jacobian's scale; the dependent rows are found by a
sequential Gram–Schmidt sweep in declaration order, so that the later of two duplicate joints is
named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

#: relative tolerance on singular values / residual norms, times the largest singular value
RANK_RTOL = 1e-8


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


def rank_report(jacobian, rtol: float = RANK_RTOL) -> RankReport:
    """Numerical rank of C_q and the rows that depend on earlier rows.

    Parameters
    ----------
    jacobian : array or sparse matrix, shape (n_c, n_q)
    rtol : float
        A singular value (or Gram–Schmidt residual norm) below ``rtol * σ_max`` of the row- and
        column-equilibrated matrix counts as zero.
    """
    a = _dense(jacobian)
    m, n = a.shape
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


def null_space_basis(jacobian, rtol: float = RANK_RTOL) -> tuple[np.ndarray, int]:
    """Orthonormal basis N of ker C_q (columns) and the rank of C_q.

    Rows are normalised first (which does not change the null space) so that equations in
    different units weigh alike; a singular value counts as zero below ``rtol · σ_max``.
    """
    a = jacobian.toarray() if hasattr(jacobian, "toarray") else np.asarray(jacobian, float)
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
