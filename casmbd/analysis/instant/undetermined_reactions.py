"""Joint reactions that the multipliers cannot determine.

With redundant constraint equations (a closed loop with more equations than independent
conditions, seed 002 "Redundant constraint equations"; a singular pose, seed 000) the
multipliers are not unique: every λ + N z, with the columns of N spanning the null space of
C_qᵀ (C_qᵀ N = 0), satisfies C_qᵀ λ = Q_e + Q_v − M q̈ equally.  The reactions are linear in λ,
R(λ) = R₀ + R_λ λ, so a component is determined exactly when its row of R_λ N vanishes; the
others depend on how the self-stress of the loop is shared (seed 002, "joint forces that cannot
be determined": a rigid model cannot say).  They are reported for the minimum-norm multipliers
λ − N Nᵀ λ (seed 002's orthogonalisation), listed in ``undetermined_reactions``, announced by
``reactions = "minimum_norm"`` and a ``RuntimeWarning`` — finite, never NaN, and never passed
off as determined.

R_λ N is formed column by column from the compiled reaction function itself,
R(λ + n_k) − R(λ), so no extra Function is compiled.
"""

from __future__ import annotations

import warnings

import numpy as np

from casmbd.analysis.instant.redundancy import RANK_RTOL, zero_noise_rows

#: a reaction component counts as undetermined when a unit null-space direction of the
#: multipliers changes it by more than this times the largest such change
UNDETERMINED_RTOL = 1e-8


def multiplier_null_space(jacobian, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis (n_c, k) of the null space of C_qᵀ (k = n_c − rank C_q).

    The rank decision uses the row-equilibrated matrix, as
    :func:`casmbd.analysis.instant.redundancy.rank_report` does; the basis is returned for the
    original rows (a vector z with C_qᵀ z = 0 stays one after row scaling by D: (D⁻¹ z)).
    """
    a = jacobian.toarray() if hasattr(jacobian, "toarray") else np.asarray(jacobian, dtype=float)
    a = zero_noise_rows(a)  # rounding noise is no equation (redundancy.ZERO_ROW_RTOL)
    m = a.shape[0]
    if m == 0:
        return np.zeros((0, 0))
    norms = np.linalg.norm(a, axis=1)
    norms[norms == 0.0] = 1.0
    scaled = a / norms[:, None]
    u, sigma, _ = np.linalg.svd(scaled, full_matrices=True)
    tol = rtol * max(float(sigma[0]) if sigma.size else 0.0, 1e-300)
    rank = int(np.sum(sigma > tol))
    if rank == m:
        return np.zeros((m, 0))
    # Cᵀ z = 0  ⟺  scaledᵀ (D z) = 0 with D = diag(norms): z = D⁻¹ u_null
    basis = u[:, rank:] / norms[:, None]
    q, _ = np.linalg.qr(basis)
    return q


def undetermined_mask(reaction, lam: np.ndarray, null: np.ndarray) -> np.ndarray:
    """Boolean mask of the reaction components (n_joints, size) moved by null-space λ.

    Parameters
    ----------
    reaction : callable
        λ ↦ reactions (n_joints, size) at fixed q, q̇, q̈, t, u.
    lam : ndarray (n_c,)
    null : ndarray (n_c, k), from :func:`multiplier_null_space`.
    """
    base = np.asarray(reaction(lam), dtype=float)
    if null.shape[1] == 0:
        return np.zeros(base.shape, dtype=bool)
    scale = 1.0 + float(np.max(np.abs(lam), initial=0.0))
    change = np.zeros(base.shape)
    for k in range(null.shape[1]):
        moved = np.asarray(reaction(lam + scale * null[:, k]), dtype=float)
        change = np.maximum(change, np.abs(moved - base) / scale)
    top = float(np.max(change, initial=0.0))
    return change > UNDETERMINED_RTOL * max(top, 1e-300) if top > 0 else \
        np.zeros(base.shape, dtype=bool)


def flag_undetermined(model, qs, vs, acc, grid, us, lam, reactions: np.ndarray,
                      steps=None, stacklevel: int = 3) -> tuple[np.ndarray, dict]:
    """Make λ minimum-norm where C_q is rank deficient, recompute the reactions from it, and
    name the components that are not determined.

    At every checked step with a rank-deficient C_q the multipliers ``lam`` are replaced in
    place by their minimum-norm representative λ − N Nᵀ λ (seed 002's orthogonalisation: the
    component along the null space of C_qᵀ carries no force), the reactions of that step are
    evaluated again with it (the determined components do not change; the others become the
    minimum-norm distribution), and a multiplier row with a component in that null space is
    marked undetermined (``info["undetermined_rows"]``, e.g. two drivers on one coordinate,
    whose efforts are then shared in the least-norm way).

    Parameters
    ----------
    model : NumericModel
    qs, vs, acc, us, lam : ndarray (n_t, ·)
        States, accelerations, actuator inputs and the multipliers used for ``reactions``.
    grid : ndarray (n_t,)
    reactions : ndarray (n_t, n_joints, size)
    steps : iterable of int, optional
        Output steps to check.  Default: every step when C_q is rank deficient at the first
        one (redundant equations persist), otherwise none.
    stacklevel : int
        Of the warning naming the undetermined components (3: the caller's caller).

    Returns
    -------
    reactions : ndarray
        Finite: the undetermined components those of the minimum-norm multipliers.
    info : dict
        ``"undetermined_reactions"``: {joint: [component indices]} (empty when all are
        determined), ``"reactions"``: ``"minimum_norm"`` when some are undetermined, else
        ``"determined"``, and ``"redundant_steps"``: how many steps had a rank-deficient
        C_q.
    """
    joints = list(model.mechanism.joints)
    info: dict = {"undetermined_reactions": {}, "reactions": "determined", "redundant_steps": 0,
                  "undetermined_rows": []}
    n = len(grid)
    if not joints or model.nc == 0 or n == 0:
        return reactions, info
    if steps is None:
        null0 = multiplier_null_space(model.constraint_jacobian(qs[0], float(grid[0])))
        steps = range(n) if null0.shape[1] else ()
    func = model.function("joint_reactions")
    size = model.reaction_size
    out = reactions.copy()
    flagged: dict[str, set] = {}
    for k in steps:
        null = multiplier_null_space(model.constraint_jacobian(qs[k], float(grid[k])))
        if not null.shape[1]:
            continue
        info["redundant_steps"] += 1
        if np.all(np.isfinite(lam[k])):
            lam[k] = lam[k] - null @ (null.T @ lam[k])
        rows = np.flatnonzero(np.linalg.norm(null, axis=1) > 1e-8)
        info["undetermined_rows"] = sorted(set(info["undetermined_rows"]) | set(rows.tolist()))

        def reaction(lam_k, k=k):
            return np.asarray(func(qs[k], vs[k], acc[k], grid[k], us[k], model.p,
                                   lam_k)).reshape(size, len(joints)).T

        mask = undetermined_mask(reaction, lam[k], null)
        if np.all(np.isfinite(lam[k])):
            out[k] = reaction(lam[k])  # the minimum-norm distribution
        for j, comps in zip(*np.nonzero(mask), strict=True):
            flagged.setdefault(joints[j], set()).add(int(comps))
    if flagged:
        info["undetermined_reactions"] = {j: sorted(c) for j, c in flagged.items()}
        info["reactions"] = "minimum_norm"
        detail = "; ".join(f"'{j}' components {sorted(c)}" for j, c in flagged.items())
        warnings.warn(f"joint reactions cannot be determined (redundant constraint equations "
                      f"or a singular pose; the minimum-norm distribution is reported): "
                      f"{detail}", RuntimeWarning, stacklevel=stacklevel)
    return out, info
