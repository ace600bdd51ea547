"""Stability of an equilibrium from its reduced (tangent) stiffness matrix: one classification.

An equilibrium of a mechanism with conservative forces is a stationary point of the potential
energy V on the constraint manifold.  With N a basis of the tangent space (the null space of
C_q) the second variation is δzᵀ K̄ δz with the reduced stiffness

    K̄ = Nᵀ K N,      K = −∂(Q_e − C_qᵀλ)/∂q  at fixed λ

(the Hessian of the Lagrangian V + λᵀC; the λ term is the geometric stiffness of the
constraints).  :func:`classify_stability` turns K̄ into one verdict:

``"stable"``    every eigenvalue > tol (a strict minimum of V on the manifold);
``"unstable"``  some eigenvalue < −tol (V decreases along that direction);
``"neutral"``   no eigenvalue < −tol but some |eigenvalue| ≤ tol: the second variation does
                not decide (a vertical joint axis about which gravity does no work, a body
                whose centre of mass lies on its joint axis); the null directions are named.

with tol = ``rtol`` · max |eigenvalue| (default :data:`STABILITY_RTOL` = 1e-8, far above the
roundoff of the eigenvalues, ~1e-15 relative, and far below any physical stiffness ratio of
the scenes we know).  For non-conservative forces K̄ is not symmetric; the real parts of its
eigenvalues are judged (divergence, not flutter).  A mechanism without degrees of freedom is
stable.  Both :func:`casmbd.analysis.statics.statics.static_equilibrium` and
:func:`casmbd.analysis.statics.linearize.linearize` (at an equilibrium; away from one it gives no
verdict) use this function, on the same K̄ and with the same named directions, so that they
never disagree.  Why K̄ and not the eigenvalues of the linearized system: a stable
conservative system has purely imaginary eigenvalues ±iω and a neutral direction a double
zero that round-off splits into ±ε, so a spectral test cannot tell neutral from stable (or
from unstable) robustly, while the sign pattern of K̄ is exactly the static question; see
the module docstring of :mod:`casmbd.analysis.statics.linearize` for damping.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

#: relative eigenvalue tolerance: |μ| ≤ STABILITY_RTOL · max|μ| counts as zero
STABILITY_RTOL = 1e-8
#: a named coordinate is listed for a null direction when its weight is at least this fraction
#: of the direction's largest weight
DOMINANT_FRACTION = 0.1
VERDICTS = ("stable", "unstable", "neutral")


@dataclass
class Stability:
    """The verdict of :func:`classify_stability`.

    Attributes
    ----------
    verdict : {"stable", "unstable", "neutral"}
    eigenvalues : ndarray
        Eigenvalues of the reduced stiffness (real parts if it is not symmetric), ascending.
    tolerance : float
        Absolute eigenvalue tolerance used, ``rtol`` · max |eigenvalue|.
    null_directions : list of dict
        For a neutral verdict, one entry per zero eigenvalue: ``{"dominant": name,
        "weights": {name: weight}}`` with the weights of the named coordinates (largest = 1 in
        magnitude, those below :data:`DOMINANT_FRACTION` left out).  The directions span the
        null space and are rotated so that each is led by a different coordinate (a pivoted
        elimination), not the arbitrary eigenvectors of a repeated zero eigenvalue.
    """

    verdict: str
    eigenvalues: np.ndarray
    tolerance: float
    null_directions: list = field(default_factory=list)

    @property
    def stable(self) -> bool | None:
        """True (stable), False (unstable) or None (neutral)."""
        return {"stable": True, "unstable": False, "neutral": None}[self.verdict]

    def null_coordinates(self) -> list[str]:
        """The coordinate leading each null direction (empty unless neutral)."""
        return [d["dominant"] for d in self.null_directions]

    def to_json(self) -> dict:
        return {"verdict": self.verdict, "tolerance": float(self.tolerance),
                "eigenvalues": [float(x) for x in self.eigenvalues],
                "null_directions": [{"dominant": d["dominant"],
                                     "weights": {k: float(v) for k, v in d["weights"].items()}}
                                    for d in self.null_directions]}


def classify_stability(stiffness: np.ndarray, directions: np.ndarray | None = None,
                       names: list[str] | None = None,
                       rtol: float = STABILITY_RTOL) -> Stability:
    """Classify an equilibrium from its reduced stiffness K̄ (see the module docstring).

    Parameters
    ----------
    stiffness : ndarray (m, m)
        Reduced (tangent) stiffness K̄ = Nᵀ K N in m independent coordinates.
    directions : ndarray (k, m), optional
        Maps an independent-coordinate vector δz to k named coordinates (e.g. the joint-angle
        rates J_j N, or N itself for the generalized coordinates); default the identity.
    names : list of str, optional
        Names of the k rows of ``directions`` (default ``z0, z1, …``).
    rtol : float
        Relative eigenvalue tolerance (default :data:`STABILITY_RTOL`).

    Returns
    -------
    Stability
    """
    k = np.atleast_2d(np.asarray(stiffness, float))
    m = k.shape[0] if k.size else 0
    if m == 0:
        return Stability("stable", np.zeros(0), 0.0)
    sym = 0.5 * (k + k.T)
    scale = float(np.max(np.abs(k)))
    if np.max(np.abs(k - k.T), initial=0.0) <= 1e-10 * max(scale, 1e-300):
        eig, vec = np.linalg.eigh(sym)
    else:  # non-conservative forces: judge by the real parts
        eig_c, vec_c = np.linalg.eig(k)
        order = np.argsort(eig_c.real)
        eig, vec = eig_c.real[order], vec_c[:, order]
    tol = rtol * max(float(np.max(np.abs(eig))), 1e-300)
    if np.all(eig > tol):
        return Stability("stable", eig, tol)
    if np.any(eig < -tol):
        return Stability("unstable", eig, tol)
    null = np.abs(eig) <= tol
    basis = vec[:, null]
    if np.iscomplexobj(basis):  # a complex pair: its real and imaginary parts span it
        basis = sla.orth(np.hstack([basis.real, basis.imag]))
    d = np.eye(m) if directions is None else np.asarray(directions, float)
    labels = list(names) if names is not None else [f"z{i}" for i in range(d.shape[0])]
    return Stability("neutral", eig, tol, _named_directions(d @ basis, labels))


def _named_directions(z: np.ndarray, names: list[str]) -> list[dict]:
    """Rotate the null basis Z (k × r) so that each column is led by one named coordinate.

    Pivoted QR of Zᵀ picks the r coordinates that are most independent across the null space;
    Z (Z[pivots])⁻¹ is then 1 on its own pivot and 0 on the others'.
    """
    r = z.shape[1]
    if r == 0 or z.shape[0] == 0:
        return []
    _, _, piv = sla.qr(z.T, pivoting=True, mode="economic")
    piv = piv[:r]
    sub = z[piv, :]
    if np.linalg.matrix_rank(sub) < r:  # the named coordinates do not see the direction
        rot = z
    else:
        rot = z @ np.linalg.inv(sub)
    out = []
    for j in range(r):
        col = rot[:, j]
        big = float(np.max(np.abs(col)))
        if big == 0.0:
            continue
        col = col / col[int(np.argmax(np.abs(col)))]
        keep = np.flatnonzero(np.abs(col) >= DOMINANT_FRACTION)
        keep = keep[np.argsort(-np.abs(col[keep]))]
        out.append({"dominant": names[keep[0]],
                    "weights": {names[i]: float(col[i]) for i in keep}})
    return out
