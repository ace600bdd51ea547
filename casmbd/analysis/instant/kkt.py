"""Accelerations and Lagrange multipliers from the sparse KKT system at one state.

Seed 000, eq. 6.138::

    [ M    C_qᵀ ] [ q̈ ]   [ Q_e + Q_v ]
    [ C_q   0   ] [ λ  ] = [ γ         ]

solved by sparse LU; when the matrix is singular (redundant constraints, singular poses) the
minimum-norm least-squares solution is used, which gives the right q̈ and one admissible λ.
The consistent start of a simulation (:func:`consistent_state`) assembles q, projects the
initial velocities mass-orthogonally onto C_q q̇ = −C_t (seed 003, "mass-orthogonal
projections"), and solves this system for q̈ and λ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.reaction_friction import has_reaction_friction, solve_normals
from casmbd.lazy import lazy_module

sla = lazy_module("scipy.linalg")
sp = lazy_module("scipy.sparse")
spla = lazy_module("scipy.sparse.linalg")

#: relative singular-value cut of the minimum-norm KKT solve with redundant equations
TRUNCATE_RTOL = 1e-10
#: KKT systems up to this size (n_q + n_c) are solved dense: assembling a sparse matrix costs
#: more than the factorisation there (the event loop solves one per sub-interval)
DENSE_LIMIT = 80


def _solve_saddle(top_left: sp.spmatrix, cq: sp.spmatrix, rhs: np.ndarray,
                  redundant: bool = False) -> np.ndarray:
    """Solve [A C_qᵀ; C_q 0] x = rhs: sparse LU when regular; with ``redundant`` (or when LU
    fails) the minimum-norm least-squares solution with singular values below
    :data:`TRUNCATE_RTOL` × the largest cut, so that a nearly dependent row does not amplify
    its small inconsistency into the solution."""
    n, m = top_left.shape[0], cq.shape[0]
    if 0 < m and n + m <= DENSE_LIMIT:  # small: dense LAPACK, no sparse assembly (1.7 ms)
        return _solve_dense(top_left, cq, rhs, redundant)
    kkt = sp.bmat([[top_left, cq.T], [cq, None]], format="csc")
    if m == 0:
        return spla.spsolve(sp.csc_matrix(top_left), rhs).reshape(-1)
    if redundant:
        sol, *_ = sla.lstsq(kkt.toarray(), rhs, cond=TRUNCATE_RTOL, lapack_driver="gelsd")
        return sol
    try:
        with np.errstate(all="ignore"):
            sol = spla.splu(kkt).solve(rhs)
        if np.all(np.isfinite(sol)) and np.linalg.norm(kkt @ sol - rhs) <= \
                1e-8 * max(1.0, np.linalg.norm(rhs)):
            return sol
    except RuntimeError:
        pass
    sol, *_ = sla.lstsq(kkt.toarray(), rhs, lapack_driver="gelsd")
    del n
    return sol


def _solve_dense(top_left, cq, rhs: np.ndarray, redundant: bool) -> np.ndarray:
    """:func:`_solve_saddle` for small systems: the same answers (LU, checked residual, the
    truncated minimum-norm solution with ``redundant`` or where LU fails) on dense arrays."""
    top = top_left.toarray() if sp.issparse(top_left) else np.asarray(top_left, float)
    c = cq.toarray() if sp.issparse(cq) else np.asarray(cq, float)
    m = c.shape[0]
    kkt = np.block([[top, c.T], [c, np.zeros((m, m))]])
    if redundant:
        sol, *_ = sla.lstsq(kkt, rhs, cond=TRUNCATE_RTOL, lapack_driver="gelsd")
        return sol
    try:
        with np.errstate(all="ignore"):
            sol = np.linalg.solve(kkt, rhs)
        if np.all(np.isfinite(sol)) and np.linalg.norm(kkt @ sol - rhs) <= \
                1e-8 * max(1.0, np.linalg.norm(rhs)):
            return sol
    except np.linalg.LinAlgError:
        pass
    sol, *_ = sla.lstsq(kkt, rhs, lapack_driver="gelsd")
    return sol


def accelerations_and_multipliers(model, q, v, t: float, u=None, redundant: bool = False
                                  ) -> tuple[np.ndarray, np.ndarray]:
    """q̈ and λ of the augmented equations at (q, v, t) with actuator inputs ``u``
    (``redundant``: truncated minimum-norm solve, see :func:`_solve_saddle`)."""
    m_mat = model.mass_matrix(q)
    force = model.applied_forces(q, v, t, u) + model.quadratic_velocity_forces(q, v)
    if model.nc == 0:
        return spla.spsolve(sp.csc_matrix(m_mat), force).reshape(-1), np.zeros(0)
    cq = model.constraint_jacobian(q, t)
    rhs = np.concatenate([force, model.acceleration_rhs(q, v, t)])
    sol = _solve_saddle(m_mat, cq, rhs, redundant)
    if has_reaction_friction(model):  # Q_e(0) + G N(λ): both solved together
        pad = np.zeros(model.nc)
        sol, _, _ = solve_normals(
            model, q, v, t, u,
            lambda f: _solve_saddle(m_mat, cq, rhs + np.concatenate([f, pad]), redundant),
            lambda x: x[model.nq:], f"the accelerations at t = {t:g}")
    return sol[:model.nq], sol[model.nq:]


def project_velocities(model, q, v, t: float) -> np.ndarray:
    """Mass-orthogonal projection: argmin (v* − v)ᵀ M (v* − v) subject to C_q v* = −C_t."""
    if model.nc == 0:
        return np.array(v, dtype=float)
    m_mat = model.mass_matrix(q)
    cq = model.constraint_jacobian(q, t)
    rhs = np.concatenate([m_mat @ v, -model.constraint_time_derivative(q, t)])
    return _solve_saddle(m_mat, cq, rhs)[:model.nq]


@dataclass
class ConsistentState:
    """A state that satisfies the constraints at position, velocity and acceleration level."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lam: np.ndarray
    position_change: float
    velocity_change: float
    assembly_iterations: int


def consistent_state(model, q0, v0, t: float = 0.0, u=None, fixed=None,
                     accelerations=None) -> ConsistentState:
    """Assemble q, project v and compute q̈, λ; report how much q and v were changed.

    ``accelerations(q, v)``, for a system without constraint equations, gives q̈ from an
    ODE right-hand side (the articulated recursion) instead of solving M q̈ = Q.
    """
    q0 = np.asarray(q0, dtype=float)
    v0 = np.asarray(v0, dtype=float)
    rep = assemble(model, q0, t, fixed=fixed)
    v = project_velocities(model, rep.q, v0, t)
    if accelerations is not None and model.nc == 0:
        a, lam = np.asarray(accelerations(rep.q, v), float), np.zeros(0)
    else:
        a, lam = accelerations_and_multipliers(model, rep.q, v, t, u)
    return ConsistentState(rep.q, v, a, lam, float(np.max(np.abs(rep.q - q0), initial=0.0)),
                           float(np.max(np.abs(v - v0), initial=0.0)), rep.iterations)
