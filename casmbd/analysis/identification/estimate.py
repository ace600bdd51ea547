"""Least-squares estimation of the base parameters: Gautier's weighted least squares.

With the base regressor Y_b(q, q̇, q̈) (n × n_b per sample, :mod:`casmbd.analysis.
identification.base_parameters`) the samples k = 1 … N stack into the overdetermined linear
system (Gautier & Khalil 1990, "Direct calculation of minimum set of inertial parameters of
serial robots", IEEE Trans. Robot. Autom. 6(3); Gautier 1997, "Dynamic identification of
robots with power model", ICRA)

    y = W π_b + ρ,   W = [Y_b(k=1); …; Y_b(k=N)]  (N n × n_b),  y = [τ_1; …; τ_N].

1. Ordinary least squares π̂⁰ = argmin ‖y − W π_b‖² gives the residual of each joint's
   rows, ρ_j, and its variance σ_j² = ‖ρ_j‖² / (N − c_j), c_j the number of base parameters
   that appear in joint j's equations (the columns of W_j that are not zero).
2. Each joint's rows are divided by σ_j (the rows of noisier joints count less) and the
   weighted system is solved again: π̂_b = argmin ‖G (y − W π_b)‖², G = diag(1/σ_j); σ_j is
   then re-estimated from the weighted fit's residuals and the fit repeated until the weights
   change by less than 0.1 % (at most :data:`WEIGHT_PASSES` passes; σ_j floored at
   :data:`SIGMA_FLOOR` of the largest joint's RMS effort: rounding); the first, ordinary fit
   leaks the noise of heavily loaded joints into the residuals of lightly loaded ones (a
   wrist's σ_j came out 2-3 × too large on a 6-axis arm whose joint noises differ 500-fold),
   and wrong weights make the covariance below wrong by as much.
3. With ρ_G = G (y − W π̂_b), the variance of the weighted residual is
   σ² = ‖ρ_G‖² / (N n − n_b) (≈ 1 when the weights are right) and the covariance of the
   estimate Σ_π = σ² (W_Gᵀ W_G)⁻¹, W_G = G W: standard deviations σ_πᵢ = √(Σ_π)ᵢᵢ and the
   relative deviation 100 σ_πᵢ / |π̂ᵢ| % (Gautier's criterion: above ~ 10 × the smallest, a
   parameter is poorly identified).

The condition number reported is that of the unweighted W (2-norm, σ_max / σ_min), the
figure excitation design minimises (Swevers et al. 1997, "Optimal robot excitation and
identification", IEEE Trans. Robot. Autom. 13(5)).  A W of numerical rank below n_b
(σ_min ≤ :data:`RANK_TOLERANCE` σ_max) is refused naming the combinations of base parameters
the data leave undetermined (the right singular vectors of the small singular values); fewer
equations than base parameters likewise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casmbd.errors import IdentificationError

__all__ = ["RANK_TOLERANCE", "BaseEstimate", "least_squares"]

#: most passes of the weighting (each: σ_j from the residuals of the previous fit, then the
#: weighted fit); they stop when the weights change by less than 0.1 %
WEIGHT_PASSES = 10
#: smallest σ_j relative to the largest joint's RMS effort (below: rounding, not noise)
SIGMA_FLOOR = 1e-9
#: smallest singular value of the stacked base regressor, relative to the largest, below which
#: the data do not determine the base parameters
RANK_TOLERANCE = 1e-10


@dataclass
class BaseEstimate:
    """The least-squares estimate of the base parameters (module docstring).

    Attributes
    ----------
    names : list of str
        Base parameter names.
    values : ndarray (n_b,)
        π̂_b.
    std : ndarray (n_b,)
        σ_π, standard deviations.
    covariance : ndarray (n_b, n_b)
        Σ_π = σ² (W_Gᵀ W_G)⁻¹.
    joint_sigma : ndarray (n,)
        σ_j, the residual deviation per joint of the last fit: the weights are 1/σ_j.
    residual_rms : ndarray (n,)
        Root mean square of y − W π̂_b per joint (unweighted, N m or N).
    condition_number : float
        2-norm condition number of the unweighted stacked base regressor W.
    normal_matrix : ndarray (n_b, n_b)
        W_Gᵀ W_G (the information matrix up to σ²), for the consistent solve.
    samples : int
        N.
    weighted : bool
        Whether the rows were weighted (False: ordinary least squares).
    weighted_norm2 : float
        ‖G y‖², the squared norm of the weighted efforts (the scale of the consistent
        solve's objective).
    """

    names: list[str]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    joint_sigma: np.ndarray
    residual_rms: np.ndarray
    condition_number: float
    normal_matrix: np.ndarray
    samples: int
    weighted: bool
    weighted_norm2: float = 1.0

    @property
    def relative_std(self) -> np.ndarray:
        """100 σ_πᵢ / |π̂ᵢ| in % (inf where π̂ᵢ = 0)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.values != 0.0, 100.0 * self.std / np.abs(self.values),
                            np.inf)


def _combination(vector: np.ndarray, names: list[str]) -> str:
    """``+0.707 a −0.707 b`` of the entries of a unit vector above 1e-3 (at most six)."""
    big = [k for k in np.argsort(-np.abs(vector)) if abs(vector[k]) > 1e-3][:6]
    return " ".join(f"{vector[k]:+.3g} {names[k]}" for k in big)


def least_squares(regressor: np.ndarray, tau: np.ndarray, names: list[str],
                  coordinates: list[str] | None = None, weighted: bool = True,
                  source: str = "measurements", mask: np.ndarray | None = None
                  ) -> BaseEstimate:
    """Estimate the base parameters from stacked samples (module docstring).

    Parameters
    ----------
    regressor : ndarray (N, n, n_b)
        The base regressor Y_b at each sample.
    tau : ndarray (N, n)
        The measured efforts.
    names : list of str
        The n_b base parameter names (for messages and the result).
    coordinates : list of str, optional
        The n coordinate names (for messages).
    weighted : bool
        Gautier's weighting by the per-joint residual deviation (default); False: ordinary
        least squares.
    mask : ndarray (N, n) of bool, optional
        The equations (sample, joint) to use; default all.  Left-out rows count nowhere
        (the residual RMS, σ_j and the degrees of freedom are over the used rows).

    Raises
    ------
    IdentificationError
        Fewer equations than base parameters; a stacked regressor of numerical rank below
        n_b, naming the undetermined combinations.
    """
    y_b = np.asarray(regressor, dtype=float)
    tau = np.asarray(tau, dtype=float)
    n_s, n, n_b = y_b.shape
    coordinates = list(coordinates or [f"joint {j}" for j in range(n)])
    if tau.shape != (n_s, n):
        raise IdentificationError(f"{source}: τ has shape {tau.shape}, the regressor "
                                  f"{(n_s, n)} samples × joints")
    use = np.ones((n_s, n), bool) if mask is None else np.asarray(mask, bool)
    if use.shape != (n_s, n):
        raise IdentificationError(f"{source}: the row mask has shape {use.shape}, expected "
                                  f"{(n_s, n)}")
    y_b = y_b * use[:, :, None]
    tau = tau * use
    rows_j = np.sum(use, axis=0)
    if n_b == 0:
        raise IdentificationError(f"{source}: the model has no identifiable parameter")
    if int(rows_j.sum()) <= n_b:
        raise IdentificationError(
            f"{source}: {n_s} samples × {n} joints = {int(rows_j.sum())} equations for {n_b} "
            f"base parameters: at least {n_b // n + 1} samples are needed (many more for a "
            "meaningful estimate)")
    w = y_b.reshape(n_s * n, n_b)
    y = tau.reshape(n_s * n)
    pi0, _, _, sv = np.linalg.lstsq(w, y, rcond=None)
    if sv[-1] <= RANK_TOLERANCE * sv[0]:
        _, sv, vt = np.linalg.svd(w, full_matrices=False)
        small = [vt[k] for k in range(n_b) if sv[k] <= RANK_TOLERANCE * sv[0]]
        combos = "; ".join(_combination(v, names) for v in small[:4])
        raise IdentificationError(
            f"{source}: the samples do not excite every base parameter (stacked regressor of "
            f"rank {int(np.sum(sv > RANK_TOLERANCE * sv[0]))} < {n_b}, condition number "
            f"{sv[0] / sv[-1] if sv[-1] > 0 else np.inf:.3g}); undetermined combination"
            f"{'s' if len(small) > 1 else ''}: {combos}; use a richer trajectory "
            "(an excitation design) or more samples")
    condition = float(sv[0] / sv[-1])
    rho = (y - w @ pi0).reshape(n_s, n)
    scale_w = np.max(np.abs(y_b), axis=(0, 2))
    used = np.array([int(np.sum(np.max(np.abs(y_b[:, j, :]), axis=0)
                                > 1e-12 * max(scale_w[j], np.finfo(float).tiny)))
                     for j in range(n)])
    dof = np.maximum(rows_j - used, 1)
    sigma_j = np.sqrt(np.sum(rho ** 2, axis=0) / dof)
    gain = np.ones(n)
    wg, yg, pi_b = w, y, pi0
    if weighted:
        # the passes on each joint's normal equations (n_b × n_b blocks, cheap); the last
        # weighted fit by an orthogonal factorisation of the weighted rows (accurate)
        blocks = np.einsum("kji,kjl->jil", y_b, y_b)
        rhs = np.einsum("kji,kj->ji", y_b, tau)
        # σ_j floored at 1e-9 of the largest joint's RMS effort: the rounding of noise-free
        # data, which scales with the largest efforts, is not noise
        floor = max(SIGMA_FLOOR * float(np.max(np.sqrt(np.sum(tau ** 2, axis=0)
                                                         / np.maximum(rows_j, 1)))),
                    np.finfo(float).tiny)
        for _ in range(WEIGHT_PASSES):
            new_gain = 1.0 / np.maximum(sigma_j, floor)
            settled = np.max(np.abs(new_gain / gain - 1.0)) < 1e-3
            gain = new_gain
            if settled:
                break
            try:
                pi_b = np.linalg.solve(np.einsum("j,jil->il", gain ** 2, blocks),
                                       np.einsum("j,ji->i", gain ** 2, rhs))
            except np.linalg.LinAlgError:
                break
            rho = (y - w @ pi_b).reshape(n_s, n)
            sigma_j = np.sqrt(np.sum(rho ** 2, axis=0) / dof)
        wg = (y_b * gain[None, :, None]).reshape(n_s * n, n_b)
        yg = (tau * gain[None, :]).reshape(n_s * n)
        pi_b = np.linalg.lstsq(wg, yg, rcond=None)[0]
    rho_g = yg - wg @ pi_b
    sigma2 = float(rho_g @ rho_g) / (int(rows_j.sum()) - n_b)
    normal = wg.T @ wg
    cov = sigma2 * np.linalg.inv(normal)
    cov = 0.5 * (cov + cov.T)
    residual = (y - w @ pi_b).reshape(n_s, n)
    return BaseEstimate(list(names), pi_b, np.sqrt(np.maximum(np.diag(cov), 0.0)), cov,
                        sigma_j, np.sqrt(np.sum(residual ** 2, axis=0)
                                         / np.maximum(rows_j, 1)), condition,
                        normal, n_s, bool(weighted), float(yg @ yg))
