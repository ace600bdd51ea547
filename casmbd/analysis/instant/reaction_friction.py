"""Reaction-proportional joint friction: the multipliers and the friction solved together.

A joint friction element with ``mu`` > 0 (:mod:`casmbd.model.joint_friction`) has the Coulomb
level F_c = F_0 + μ r |R_⊥|, R_⊥ the joint's constraint force transverse to its axis, a linear
function of the multipliers λ.  The applied forces are affine in the magnitudes N
(:mod:`casmbd.system.applied_forces`): Q_e = Q_e(N = 0) + G(q, v) N.  Every linear solve of an
analysis at one state (inverse dynamics: C_qᵀ λ = Q − M q̈; the consistent start: the KKT system) is
then affine in N, x(N) = x_0 + X N, with x_0 = S(Q_0) and the columns of X = S(G e_k) − x_0
from n_f + 1 solves with the same factors, and N is the solution of

    N = φ(N) = |R_⊥(q, λ(x_0 + X N))|   (one value per element).

:func:`solve_normals` iterates this fixed point from N_0 = 0 (it contracts with the factor
≈ μ r |∂R/∂N| — μ r times the reaction the friction force itself causes, small for real
joints), accepting N when successive iterates differ by at most :data:`TOLERANCE` relative to
max |N|, and switches to Newton's method on φ(N) − N (finite-difference Jacobian, n_f columns)
when the fixed point has not converged after :data:`FIXED_POINT_ITERATIONS`; the result is
the same to the tolerance either way, since φ is evaluated exactly.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from casmbd.errors import AnalysisError

#: relative convergence of the magnitudes N (max-norm, relative to max |N|)
TOLERANCE = 1e-12
#: fixed-point iterations before Newton's method takes over
FIXED_POINT_ITERATIONS = 60
#: Newton iterations after the fixed point
NEWTON_ITERATIONS = 30


def has_reaction_friction(model) -> bool:
    """Whether ``model`` (a NumericModel) has reaction-proportional friction elements (read
    from its mechanism: a model from the cache has no System built)."""
    return any(getattr(force, "reaction_joint", lambda: None)() is not None
               for force in model.mechanism.forces.values())


def solve_normals(model, q, v, t: float, u, solve: Callable[[np.ndarray], np.ndarray],
                  lam_of: Callable[[np.ndarray], np.ndarray], where: str
                  ) -> tuple[np.ndarray, np.ndarray, int]:
    """The solution x of a linear solve whose right-hand side contains Q_e, with the
    reaction-proportional friction consistent with its multipliers (module docstring).

    Parameters
    ----------
    model : NumericModel
    q, v, t, u : state, time and actuator inputs (u None: zeros)
    solve : callable
        ``solve(f)`` the solution with the extra generalized force ``f`` (n_q) added to Q_e
        (linear in f).
    lam_of : callable
        The multipliers λ (n_c) of a solution.
    where : str
        Context of an error (e.g. "inverse dynamics at t = 0.5").

    Returns
    -------
    x : ndarray
        The solution with Q_e = Q_e(0) + G N.
    normals : ndarray
        N, one transverse reaction magnitude per element.
    iterations : int
        Evaluations of φ used.

    Raises
    ------
    AnalysisError
        When neither the fixed point nor Newton's method converges, naming the joints.
    """
    u = np.zeros(model.nu) if u is None else u
    p = model.p
    g_mat = model.sparse("friction_directions", q, v, t, u, p).toarray()
    x0 = np.asarray(solve(np.zeros(model.nq)), float)
    cols = [np.asarray(solve(g_mat[:, k]), float) - x0 for k in range(g_mat.shape[1])]
    x_dirs = np.column_stack(cols) if cols else np.zeros((x0.size, 0))

    normals_of = model.system.function("friction_normals")  # small: the virtual machine

    def phi(normals: np.ndarray) -> np.ndarray:
        lam = lam_of(x0 + x_dirs @ normals)
        return np.asarray(normals_of(q, t, p, lam), float).ravel()

    def converged(new: np.ndarray, old: np.ndarray) -> bool:
        return bool(np.max(np.abs(new - old), initial=0.0)
                    <= TOLERANCE * max(np.max(np.abs(new), initial=0.0), 1e-300))

    normals = np.zeros(x_dirs.shape[1])
    count = 0
    for _ in range(FIXED_POINT_ITERATIONS):
        new = phi(normals)
        count += 1
        if not np.all(np.isfinite(new)):
            break
        done = converged(new, normals)
        normals = new
        if done:
            return x0 + x_dirs @ normals, normals, count
    if not np.all(np.isfinite(normals)):
        normals = np.zeros_like(normals)
    for _ in range(NEWTON_ITERATIONS):  # Newton on r(N) = φ(N) − N
        res = phi(normals) - normals
        count += 1
        jac = np.empty((normals.size, normals.size))
        for k in range(normals.size):
            step = 1e-7 * max(1.0, abs(normals[k]))
            trial = normals.copy()
            trial[k] += step
            jac[:, k] = (phi(trial) - trial - res) / step
            count += 1
        new = normals - np.linalg.lstsq(jac, res, rcond=None)[0]
        new = np.maximum(new, 0.0)  # magnitudes
        if np.all(np.isfinite(new)) and converged(new, normals):
            return x0 + x_dirs @ new, new, count
        normals = new
    joints = ", ".join(f"'{j}'" for j in model.system.reaction_friction_joints.values())
    raise AnalysisError(f"{where}: the reaction-proportional friction of joint(s) {joints} "
                        f"and the joint reactions did not converge to a consistent solution "
                        f"({count} evaluations; is mu·radius so large that friction alone "
                        "could lock the joint?)")
