"""The trust-region step of the statics iterations (pure linear algebra, no model).

In m independent (tangent) coordinates z, scaled so that a unit of z is about a radian of
rotation or one characteristic length of the mechanism, the net force is g = Nᵀ Q_e (= −∇V
for conservative forces) and the stiffness H = Nᵀ K N.  The step minimises the quadratic model
of the potential energy

    m(dz) = −gᵀ dz + ½ dzᵀ H_s dz,     ‖dz‖ ≤ Δ        (H_s = ½ (H + Hᵀ))

exactly (Moré & Sorensen 1983, via the eigen-decomposition of H_s — m is the number of
degrees of freedom, small): dz = (H_s + ν I)⁻¹ g with the smallest ν ≥ max(0, −μ_min) that
keeps ‖dz‖ ≤ Δ, plus a component along the lowest eigenvector in the "hard case".  When H_s is
positive semidefinite and the Newton step fits in the trust region, ν = 0 and the step is
Newton's (for a non-symmetric H the true Newton step H⁻¹ g); eigenvalues with
|μ| ≤ :data:`RANK_RTOL` · max|μ| (or below a noise level, see :func:`trust_region_step`)
are cut off (a least-squares, minimum-norm step) when the net force along them is negligible
(below 1e-3 ‖g‖) — otherwise (a pendulum released horizontally, where the stiffness vanishes but
the force does not) the boundary step moves along the force.  Never a step longer than Δ:
the minimum-norm Newton step of 1e11 rad at a singular stiffness cannot happen.

:func:`least_squares_step` is the step of the residual globalisation (the default search of
the statics analysis, which looks for the equilibrium nearest the start, stable or not): it
minimises the Gauss–Newton model ½‖b − A dz‖² of ½‖F‖² instead of the potential, so an
indefinite stiffness (an unstable equilibrium nearby) takes Newton's step towards it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: relative singular-value (eigenvalue) cut-off of the least-squares fallback
RANK_RTOL = 1e-10
#: net force left along cut-off directions, relative to ‖g‖, still treated as a Newton step
DROPPED_FORCE_RTOL = 1e-3


@dataclass
class Step:
    """A trust-region step: ``dz``, the shift ``nu`` (0 for Newton), the predicted decrease of
    the model ``predicted`` = gᵀdz − ½ dzᵀH_s dz and whether it is the (rank-cut) Newton step."""

    dz: np.ndarray
    nu: float
    predicted: float
    newton: bool


def trust_region_step(g: np.ndarray, h: np.ndarray, radius: float, noise: float = 0.0,
                      rtol: float = RANK_RTOL) -> Step:
    """Minimise −gᵀdz + ½ dzᵀ H_s dz subject to ‖dz‖ ≤ ``radius`` (module docstring).

    Eigenvalues with |μ| ≤ max(``rtol`` · max|μ|, ``noise``) count as zero; a zero mode along
    which the net force is negligible (≤ :data:`DROPPED_FORCE_RTOL` ‖g‖) is left out of the
    step.  The statics iteration passes ``noise`` = ‖g‖: off an equilibrium the reduced
    stiffness is known only to O(‖g‖) (the curvature of the constraint manifold and of the
    coordinates times the net force), which gives the exactly neutral directions of an arm
    (a vertical base axis) spurious eigenvalues of either sign that would otherwise send the
    step along them.
    """
    g = np.asarray(g, float)
    m = g.size
    if m == 0:
        return Step(np.zeros(0), 0.0, 0.0, True)
    hs = 0.5 * (h + h.T)
    mu, vec = np.linalg.eigh(hs)
    gt = vec.T @ g
    gnorm = float(np.linalg.norm(g))
    zero = np.abs(mu) <= max(rtol * float(np.max(np.abs(mu))), noise)
    keep = ~(zero & (np.abs(gt) <= DROPPED_FORCE_RTOL * gnorm))
    mu, vec, gt = np.where(zero, 0.0, mu)[keep], vec[:, keep], gt[keep]

    def predicted(dz):
        return float(g @ dz - 0.5 * dz @ hs @ dz)

    if gnorm == 0.0 or mu.size == 0:
        return Step(np.zeros(m), 0.0, 0.0, True)
    if np.all(mu > 0.0):  # Newton's step, or its least-squares fallback if modes were cut
        if mu.size == m and np.max(np.abs(h - hs)) > 0.0:
            dz = np.linalg.solve(h, g)  # the true Newton step of a non-symmetric H
        else:
            dz = vec @ (gt / mu)
        if np.linalg.norm(dz) <= radius:
            return Step(dz, 0.0, predicted(dz), True)

    def size(nu):
        with np.errstate(over="ignore", divide="ignore"):
            return float(np.linalg.norm(gt / (mu + nu)))

    lo = max(0.0, -float(np.min(mu)))
    eps = max(1e-12 * float(np.max(np.abs(mu))), 1e-300)
    if size(lo + eps) <= radius:  # hard case: g has no component along the lowest mode
        nu = lo
        shifted = mu + nu
        coef = np.where(shifted > eps, gt / np.where(shifted > eps, shifted, 1.0), 0.0)
        dz = vec @ coef
        tau = np.sqrt(max(radius**2 - float(dz @ dz), 0.0))
        low = vec[:, int(np.argmin(mu))]
        dz = dz + (tau if float(g @ low) >= 0.0 else -tau) * low
        return Step(dz, nu, predicted(dz), False)
    hi = lo + gnorm / radius + float(np.max(np.abs(mu))) + eps
    while size(hi) > radius:
        hi *= 2.0
    from scipy.optimize import brentq  # deferred: scipy.optimize costs ~0.2 s at start-up

    nu = brentq(lambda x: size(x) - radius, lo + eps, hi, xtol=1e-14 * hi, rtol=1e-12)
    dz = vec @ (gt / (mu + nu))
    return Step(dz, float(nu), predicted(dz), False)


def least_squares_step(b: np.ndarray, a: np.ndarray, radius: float, noise: float = 0.0,
                       rtol: float = RANK_RTOL, shift: float | None = None) -> Step:
    """Minimise the Gauss–Newton model ½‖b − A dz‖² subject to ‖dz‖ ≤ ``radius``.

    The Levenberg–Marquardt trust-region step (Moré 1978, "The Levenberg–Marquardt algorithm:
    implementation and theory"; Nocedal & Wright 2006, §10.3): with the singular value
    decomposition A = U Σ Vᵀ and b̂ = Uᵀ b,

        dz(ν) = Σ_i v_i σ_i b̂_i / (σ_i² + ν),

    ν = 0 (the Gauss–Newton step, A⁻¹ b for a regular A of any definiteness) when it fits in
    the trust region, else the ν > 0 with ‖dz(ν)‖ = ``radius`` (the function is decreasing in
    ν).  Singular values σ_i ≤ max(``rtol`` · σ_max, ``noise``) along which the residual is
    negligible (|b̂_i| ≤ :data:`DROPPED_FORCE_RTOL` ‖b‖) are left out of the step (a neutral
    direction whose stiffness is known only to the noise level), as in
    :func:`trust_region_step`.  ``predicted`` is the decrease ½‖b‖² − ½‖b − A dz‖² of the
    model; it is zero at a stationary point of ‖b − A dz‖ (Aᵀ b = 0, e.g. a pendulum released
    horizontally, where the stiffness vanishes and the force does not), which the caller must
    leave by another step.  ``shift``: the step dz(ν) for this ν, whatever its length (the
    second-order correction of the statics iteration re-uses the shift of the step it
    corrects).
    """
    b = np.asarray(b, float)
    a = np.atleast_2d(np.asarray(a, float))
    m = a.shape[1] if a.size else b.size
    bnorm = float(np.linalg.norm(b))
    if m == 0 or bnorm == 0.0:
        return Step(np.zeros(m), 0.0, 0.0, True)
    u, s, vt = np.linalg.svd(a)
    bt = (u.T @ b)[:s.size]
    zero = s <= max(rtol * float(np.max(s)), noise)
    keep = ~(zero & (np.abs(bt) <= DROPPED_FORCE_RTOL * bnorm)) & (s > 0.0)
    s, bt, v = s[keep], bt[keep], vt[keep].T

    def predicted(dz):
        r = b - a @ dz
        return float(0.5 * (b @ b - r @ r))

    if s.size == 0:
        return Step(np.zeros(m), 0.0, 0.0, False)
    if shift is not None:
        dz = v @ (s * bt / (s**2 + shift))
        return Step(dz, float(shift), predicted(dz), shift == 0.0)
    dz = v @ (bt / s)
    if np.linalg.norm(dz) <= radius:
        return Step(dz, 0.0, predicted(dz), True)

    def size(nu):
        return float(np.linalg.norm(s * bt / (s**2 + nu)))

    hi = float(np.max(s * np.abs(bt))) * np.sqrt(s.size) / radius  # size(hi) <= radius
    from scipy.optimize import brentq  # deferred: scipy.optimize costs ~0.2 s at start-up

    nu = brentq(lambda x: size(x) - radius, 0.0, hi, xtol=1e-14 * hi, rtol=1e-12)
    dz = v @ (s * bt / (s**2 + nu))
    return Step(dz, float(nu), predicted(dz), False)
