"""The ``nullspace`` formulation: forward dynamics in the null space of C_q, no multipliers.

Null-space (embedding) formulation (seed 000, "Elimination of Lagrange multipliers", SVD)
---------------------------------------------------------------------------------------
The embedding technique with an orthonormal basis from the singular value decomposition of
C_q (rows equilibrated, which leaves the null space unchanged): with C_q = U Σ Vᵀ and rank r
decided by σ > ``RANK_RTOL`` · σ_max (as in :mod:`casmbd.analysis.instant.redundancy`), N = V[:,
r:] spans
the admissible accelerations, a_p = C_q⁺ γ = V_r Σ_r⁻¹ U_rᵀ γ is the minimum-norm particular
acceleration, and the reduced equations

    Nᵀ M N z̈ = Nᵀ (Q − M a_p),        q̈ = a_p + N z̈

follow from M q̈ + C_qᵀ λ = Q since Nᵀ C_qᵀ = 0.  The state is the full (q, v).  Redundant
constraints only lower r; λ never appears.  Brauchli's mass-orthogonal projection,
q̈ = a_p + (I − M⁻¹C_qᵀ(C_q M⁻¹ C_qᵀ)⁺C_q)(M⁻¹Q − a_p), gives the same q̈ (both are the unique
acceleration with C_q q̈ = γ whose residual M q̈ − Q lies in the row space of C_q).  Like the
KKT ODE it does not stabilise the position and velocity constraints: use ``projection=True``
for long runs.
"""

from __future__ import annotations

import numpy as np

from casmbd.analysis.instant.redundancy import RANK_RTOL
from casmbd.analysis.integrators.numeric_rhs import Equations, NumericOde, RhsError


def nullspace_solve(m_mat: np.ndarray, cq: np.ndarray, force: np.ndarray, gamma: np.ndarray,
                    rtol: float = RANK_RTOL) -> tuple[np.ndarray, int]:
    """q̈ of the embedded equations with an orthonormal SVD null-space basis, and rank(C_q).

    Rows of C_q (and γ) are equilibrated first: the null space and the solutions of
    C_q q̈ = γ do not change, and the rank test does not depend on the rows' units.
    """
    if cq.shape[0] == 0:
        return np.linalg.solve(m_mat, force), 0
    norms = np.linalg.norm(cq, axis=1)
    norms[norms == 0.0] = 1.0
    cq, gamma = cq / norms[:, None], gamma / norms
    u_mat, sigma, vt = np.linalg.svd(cq, full_matrices=True)
    smax = float(sigma[0]) if sigma.size else 0.0
    rank = int(np.sum(sigma > rtol * max(smax, 1e-300)))
    a_p = vt[:rank].T @ ((u_mat[:, :rank].T @ gamma) / sigma[:rank])
    basis = vt[rank:].T
    if basis.shape[1] == 0:
        return a_p, rank
    reduced_mass = basis.T @ m_mat @ basis
    z = np.linalg.solve(reduced_mass, basis.T @ (force - m_mat @ a_p))
    return a_p + basis @ z, rank


def nullspace_accelerations(model, q, v, t: float, u=None) -> np.ndarray:
    """q̈ of the null-space formulation at (q, v, t) from the model's (sparse) equations."""
    m_mat = model.mass_matrix(q).toarray()
    force = model.applied_forces(q, v, t, u) + model.quadratic_velocity_forces(q, v)
    if model.nc == 0:
        return nullspace_solve(m_mat, np.zeros((0, model.nq)), force, np.zeros(0))[0]
    return nullspace_solve(m_mat, model.constraint_jacobian(q, t).toarray(), force,
                           model.acceleration_rhs(q, v, t))[0]


class _Nullspace(NumericOde):
    """Right-hand side of the null-space ODE in x = (q, v)."""

    def __init__(self, sim, equations: Equations):
        self.eq = equations
        self.nq = sim.model.nq
        self.nx = 2 * self.nq
        self.rank = None

    def __call__(self, t: float, x: np.ndarray) -> np.ndarray:
        q, v = x[:self.nq], x[self.nq:]
        m_mat, force, gamma, cq = self.eq.dynamics(q, v, t)
        a, self.rank = nullspace_solve(m_mat, cq, force, gamma)
        if not np.all(np.isfinite(a)):
            raise RhsError(f"non-finite accelerations at t = {t:g}")
        return np.concatenate([v, a])

    def stats(self, coordinate_names) -> dict:
        return {"constraint_rank": self.rank}


def right_hand_side(sim, equations: Equations, x0, t0: float) -> _Nullspace:
    """The numeric ODE of the ``nullspace`` kind
    (:class:`casmbd.analysis.formulations.Nullspace`) for the simulator ``sim``."""
    return _Nullspace(sim, equations)
