"""Spatial rotation utilities on numpy arrays and CasADi SX/MX symbols.

Every function that has a closed form works on both kinds of input: if any argument is (or
contains) a CasADi ``SX`` or ``MX`` symbol the result is built with ``casadi`` operations
(an ``SX``/``MX`` column vector or matrix), otherwise with numpy (a float ``ndarray``).
Functions that need branching on numbers (:func:`quaternion_from_matrix`, the Euler-angle
extraction) are numpy only; :func:`inertia_tensor` lives in :mod:`casmbd.model.inertia`
(re-exported here).

Conventions
-----------
* Euler parameters (unit quaternion) ``p = [e0, e1, e2, e3] = [w, x, y, z]``, ``e = [e1, e2, e3]``;
  Hamilton product, so that ``A(p ⊗ q) = A(p) A(q)``.
* The transformation matrix ``A`` maps body-frame components to global components,
  ``r = R + A u`` (seed 001, "Rigid body kinematics", eqs. 1 and 33).
* ``ω`` is the angular velocity in global components, ``ω'`` (``omega_body``) in body
  components: ``ω̃ = Ȧ Aᵀ`` and ``ω̃' = Aᵀ Ȧ`` (seed 001, "Angular velocity", eqs. 39–42 and
  47–53), so ``ω = A ω'``.

The seed covers direction cosines, orthogonality (eq. 18), Euler angles (eqs. 28–32), the
angular-velocity relations (eqs. 38–53, 70 and 80–83) and the inertia tensor (eqs. 102–105);
it defers Euler parameters to "the following chapter", so the Euler-parameter formulas here
(``A(p)``, ``E``, ``G``) are the standard ones (Nikravesh; Shabana, ch. 7) and are verified in
``tests/model/test_rotations.py`` against the seed's relations (orthogonality, ``ω̃ = Ȧ Aᵀ``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from casmbd.model.inertia import inertia_tensor

__all__ = [
    "E_matrix",
    "G_matrix",
    "angular_velocity_body",
    "angular_velocity_global",
    "euler_xyz_to_quaternion",
    "euler_zxz_to_quaternion",
    "inertia_tensor",
    "quaternion_conjugate",
    "quaternion_from_axis_angle",
    "quaternion_from_matrix",
    "quaternion_multiply",
    "quaternion_rate",
    "quaternion_to_euler_xyz",
    "quaternion_to_euler_zxz",
    "rotation_matrix",
    "skew",
]

#: An array-like of numbers, or a CasADi SX/MX expression (or a sequence of them).
ArrayOrSym = Any

#: |sin θ| (zxz) or |cos θ| (xyz) below which the Euler-angle extraction is singular.
SINGULARITY_TOL = 1e-6

_SYMBOLIC = (ca.SX, ca.MX)


# ----------------------------------------------------------------------------------- helpers
def _is_sym(*args: Any) -> bool:
    """True if any argument is, or (for sequences) contains, a CasADi SX/MX expression."""
    for a in args:
        if isinstance(a, _SYMBOLIC):
            return True
        if isinstance(a, (list, tuple)) and any(isinstance(x, _SYMBOLIC) for x in a):
            return True
    return False


def _vector(x: ArrayOrSym, n: int, name: str, sym: bool) -> Any:
    """Return ``x`` as an ``n``-vector: a CasADi column (``sym``) or a 1-D float array."""
    if sym:
        if isinstance(x, (list, tuple)):
            x = ca.vertcat(*x)
        elif isinstance(x, ca.DM | np.ndarray | float | int):
            x = ca.DM(np.asarray(x, dtype=float).reshape(-1))
        if x.numel() != n:
            raise ValueError(f"{name} must have {n} elements, got shape {x.shape}")
        if x.size2() != 1:
            x = ca.reshape(x, n, 1)
        return x
    v = np.asarray(x, dtype=float).reshape(-1)
    if v.size != n:
        raise ValueError(f"{name} must have {n} elements, got {v.size}")
    return v


def _stack(rows: Sequence[Sequence[Any]], sym: bool) -> Any:
    """Build a matrix from a list of rows of scalar entries."""
    if sym:
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])
    return np.array(rows, dtype=float)


def _column(items: Sequence[Any], sym: bool) -> Any:
    """Build a vector from scalar entries (CasADi column or 1-D numpy array)."""
    if sym:
        return ca.vertcat(*items)
    return np.array(items, dtype=float)


def _mtimes(a: Any, b: Any, sym: bool) -> Any:
    return ca.mtimes(a, b) if sym else a @ b


def _quat(p: ArrayOrSym, sym: bool) -> Any:
    return _vector(p, 4, "Euler parameters p", sym)


def _as_matrix3(A: ArrayOrSym) -> np.ndarray:
    M = np.asarray(A, dtype=float)
    if M.shape != (3, 3):
        raise ValueError(f"rotation matrix must be 3x3, got shape {M.shape}")
    err = np.max(np.abs(M.T @ M - np.eye(3)))
    if err > 1e-6 or np.linalg.det(M) <= 0.0:
        raise ValueError(
            f"matrix is not a proper rotation (|AᵀA − I|max = {err:.3g}, det = "
            f"{np.linalg.det(M):.6g}); seed 001 eq. 18 requires AᵀA = I, det A = +1"
        )
    return M


# --------------------------------------------------------------------------- basic algebra
def skew(a: ArrayOrSym) -> Any:
    """Skew-symmetric (cross-product) matrix ``ã`` with ``ã b = a × b``.

    Parameters
    ----------
    a : array_like or casadi.SX/MX, 3 elements
        The vector ``a = [a1, a2, a3]``.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 3x3
        ``[[0, −a3, a2], [a3, 0, −a1], [−a2, a1, 0]]`` — seed 001, "Angular velocity",
        eq. 40 (the form of ``ω̃``) and eq. 69 (``ũ``).
    """
    sym = _is_sym(a)
    v = _vector(a, 3, "a", sym)
    a1, a2, a3 = v[0], v[1], v[2]
    return _stack([[0.0, -a3, a2], [a3, 0.0, -a1], [-a2, a1, 0.0]], sym)


def quaternion_conjugate(p: ArrayOrSym) -> Any:
    """Conjugate ``p* = [e0, −e1, −e2, −e3]``; for a unit ``p``, ``A(p*) = A(p)ᵀ``.

    Parameters
    ----------
    p : array_like or casadi.SX/MX, 4 elements
        Euler parameters ``[e0, e1, e2, e3]``.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 4 elements
        The conjugate (the inverse rotation, cf. the orthogonality of seed 001 eq. 18).
    """
    sym = _is_sym(p)
    q = _quat(p, sym)
    return _column([q[0], -q[1], -q[2], -q[3]], sym)


def quaternion_multiply(p: ArrayOrSym, q: ArrayOrSym) -> Any:
    """Hamilton product ``p ⊗ q``, with ``A(p ⊗ q) = A(p) A(q)``.

    This is the Euler-parameter form of the composition of successive transformations,
    ``A31 = A21 A32`` (seed 001, "Successive rotations", eqs. 22–27).

    Parameters
    ----------
    p, q : array_like or casadi.SX/MX, 4 elements
        Euler parameters ``[w, x, y, z]``.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 4 elements
        ``[p0 q0 − p·q, p0 q + q0 p + p × q]``.
    """
    sym = _is_sym(p, q)
    a, b = _quat(p, sym), _quat(q, sym)
    a0, a1, a2, a3 = a[0], a[1], a[2], a[3]
    b0, b1, b2, b3 = b[0], b[1], b[2], b[3]
    return _column(
        [
            a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
        ],
        sym,
    )


def rotation_matrix(p: ArrayOrSym) -> Any:
    """Transformation matrix ``A(p)`` of the Euler parameters (body → global).

    ``A = (2 e0² − 1) I + 2 (e eᵀ + e0 ẽ)``, the Euler-parameter form of the direction-cosine
    matrix of seed 001, "Transformation matrix", eq. 15 (``r = R + A u``, eq. 1).  It is
    orthogonal (eq. 18) when ``p`` has unit norm; ``p`` is not normalized here.

    Parameters
    ----------
    p : array_like or casadi.SX/MX, 4 elements
        Euler parameters ``[e0, e1, e2, e3]``.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 3x3
        The matrix ``A``.
    """
    sym = _is_sym(p)
    q = _quat(p, sym)
    e0, e1, e2, e3 = q[0], q[1], q[2], q[3]
    d = 2.0 * e0 * e0 - 1.0
    return _stack(
        [
            [d + 2.0 * e1 * e1, 2.0 * (e1 * e2 - e0 * e3), 2.0 * (e1 * e3 + e0 * e2)],
            [2.0 * (e1 * e2 + e0 * e3), d + 2.0 * e2 * e2, 2.0 * (e2 * e3 - e0 * e1)],
            [2.0 * (e1 * e3 - e0 * e2), 2.0 * (e2 * e3 + e0 * e1), d + 2.0 * e3 * e3],
        ],
        sym,
    )


def quaternion_from_axis_angle(axis: ArrayOrSym, angle: ArrayOrSym) -> Any:
    """Euler parameters of a rotation ``angle`` about ``axis``: ``[cos(θ/2), sin(θ/2) v]``.

    The elementary rotations of seed 001, "Simple rotations", eqs. 19–21 (about Z, Y, X) are the
    special cases ``axis = k, j, i``.

    Parameters
    ----------
    axis : array_like or casadi.SX/MX, 3 elements
        Rotation axis (normalized here; must be non-zero).
    angle : float or casadi.SX/MX
        Rotation angle in radians (right-hand rule).

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 4 elements
        Unit Euler parameters.

    Raises
    ------
    ValueError
        If a numeric axis has zero length.
    """
    sym = _is_sym(axis, angle)
    v = _vector(axis, 3, "axis", sym)
    if sym:
        v = v / ca.norm_2(v)
        h = angle / 2
        return ca.vertcat(ca.cos(h), ca.sin(h) * v)
    n = float(np.linalg.norm(v))
    if not n > 0.0 or not math.isfinite(n):
        raise ValueError(f"rotation axis must be a finite non-zero vector, got {v.tolist()}")
    h = 0.5 * float(angle)
    return np.concatenate(([math.cos(h)], math.sin(h) * v / n))


def quaternion_from_matrix(A: ArrayOrSym) -> np.ndarray:
    """Euler parameters of a rotation matrix by Shepperd's method (numpy only).

    The largest of ``4 e0² = 1 + tr A`` and ``4 ek² = 1 + 2 A_kk − tr A`` is used for the square
    root; the other parameters follow from the (anti)symmetric parts of ``A`` — numerically
    stable for every rotation.  Inverts :func:`rotation_matrix` (seed 001 eq. 15).

    Parameters
    ----------
    A : array_like, 3x3
        A proper orthogonal matrix (``AᵀA = I``, seed 001 eq. 18, and ``det A = 1``).

    Returns
    -------
    numpy.ndarray, 4 elements
        Unit Euler parameters with ``e0 ≥ 0``.

    Raises
    ------
    ValueError
        If ``A`` is not 3x3 or not a proper rotation within 1e-6.
    """
    M = _as_matrix3(A)
    tr = M[0, 0] + M[1, 1] + M[2, 2]
    k = int(np.argmax([tr, M[0, 0], M[1, 1], M[2, 2]]))
    if k == 0:
        e0 = 0.5 * math.sqrt(max(1.0 + tr, 0.0))
        f = 0.25 / e0
        p = [e0, f * (M[2, 1] - M[1, 2]), f * (M[0, 2] - M[2, 0]), f * (M[1, 0] - M[0, 1])]
    elif k == 1:
        e1 = 0.5 * math.sqrt(max(1.0 + 2.0 * M[0, 0] - tr, 0.0))
        f = 0.25 / e1
        p = [f * (M[2, 1] - M[1, 2]), e1, f * (M[0, 1] + M[1, 0]), f * (M[0, 2] + M[2, 0])]
    elif k == 2:
        e2 = 0.5 * math.sqrt(max(1.0 + 2.0 * M[1, 1] - tr, 0.0))
        f = 0.25 / e2
        p = [f * (M[0, 2] - M[2, 0]), f * (M[0, 1] + M[1, 0]), e2, f * (M[1, 2] + M[2, 1])]
    else:
        e3 = 0.5 * math.sqrt(max(1.0 + 2.0 * M[2, 2] - tr, 0.0))
        f = 0.25 / e3
        p = [f * (M[1, 0] - M[0, 1]), f * (M[0, 2] + M[2, 0]), f * (M[1, 2] + M[2, 1]), e3]
    q = np.array(p)
    q /= np.linalg.norm(q)
    return -q if q[0] < 0.0 else q


# ------------------------------------------------------------------------------ Euler angles
_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _body_sequence(axes, angles) -> Any:
    """Euler parameters of successive rotations about the current (body) axes."""
    p = quaternion_from_axis_angle(axes[0], angles[0])
    for axis, angle in zip(axes[1:], angles[1:]):
        p = quaternion_multiply(p, quaternion_from_axis_angle(axis, angle))
    return p


def euler_zxz_to_quaternion(phi: ArrayOrSym, theta: ArrayOrSym, psi: ArrayOrSym) -> Any:
    """Euler parameters of the Z–X–Z Euler angles ``(φ, θ, ψ)``.

    ``A = A1(φ) A2(θ) A3(ψ)``: rotation ``φ`` about Z, ``θ`` about the line of nodes (current
    X), ``ψ`` about the current Z (seed 001, "Euler angles", eqs. 28–32).  Works on numbers and
    on CasADi symbols.

    Parameters
    ----------
    phi, theta, psi : float or casadi.SX/MX
        The three Euler angles in radians.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 4 elements
        Unit Euler parameters (``e0`` not sign-normalized).
    """
    return _body_sequence((_Z, _X, _Z), (phi, theta, psi))


def quaternion_to_euler_zxz(p: ArrayOrSym) -> tuple[float, float, float]:
    """Z–X–Z Euler angles ``(φ, θ, ψ)`` of Euler parameters (numpy only).

    From the elements of ``A`` of seed 001 eq. 32: ``A33 = cos θ``, ``(A13, A23) =
    sin θ (sin φ, −cos φ)`` and ``(A31, A32) = sin θ (sin ψ, cos ψ)``.  The result has
    ``θ ∈ [0, π]`` and ``φ, ψ ∈ (−π, π]``.

    Parameters
    ----------
    p : array_like, 4 elements
        Euler parameters (normalized here).

    Returns
    -------
    tuple of float
        ``(phi, theta, psi)`` in radians.

    Warns
    -----
    RuntimeWarning
        If ``|sin θ| < 1e-6``: the singularity of the Z–X–Z set (seed 001, end of "Angular
        velocity in terms of Euler angles": rotations φ and ψ about the same axis).  Only
        ``φ ± ψ`` is then defined; ``ψ`` is set to 0 and ``φ`` carries the whole rotation (exact
        at ``sin θ = 0``; next to it the returned angles reproduce ``A`` to ``O(|sin θ|)``).
    """
    q = np.asarray(p, dtype=float).reshape(-1)
    A = rotation_matrix(q / np.linalg.norm(q))
    s = math.hypot(A[0, 2], A[1, 2])
    theta = math.atan2(s, A[2, 2])
    if s < SINGULARITY_TOL:
        warnings.warn(
            f"Z-X-Z Euler angles are singular: sin(theta) = {s:.3g} (theta = {theta:.6g} rad); "
            "phi and psi rotate about the same axis, psi is set to 0",
            RuntimeWarning,
            stacklevel=2,
        )
        return math.atan2(A[1, 0], A[0, 0]), theta, 0.0
    phi = math.atan2(A[0, 2], -A[1, 2])
    psi = math.atan2(A[2, 0], A[2, 1])
    return phi, theta, psi


def euler_xyz_to_quaternion(phi: ArrayOrSym, theta: ArrayOrSym, psi: ArrayOrSym) -> Any:
    """Euler parameters of the X–Y–Z (Cardan/Bryant) angles ``(φ, θ, ψ)``.

    ``A = A_X(φ) A_Y(θ) A_Z(ψ)``: rotation ``φ`` about X, ``θ`` about the current Y and ``ψ``
    about the current Z — the same construction as seed 001 eq. 31 with the elementary
    matrices of eqs. 19–21 in the sequence X, Y, Z.  Works on numbers and on CasADi symbols.

    Parameters
    ----------
    phi, theta, psi : float or casadi.SX/MX
        The three Cardan angles in radians.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 4 elements
        Unit Euler parameters (``e0`` not sign-normalized).
    """
    return _body_sequence((_X, _Y, _Z), (phi, theta, psi))


def quaternion_to_euler_xyz(p: ArrayOrSym) -> tuple[float, float, float]:
    """X–Y–Z (Cardan/Bryant) angles ``(φ, θ, ψ)`` of Euler parameters (numpy only).

    From ``A = A_X(φ) A_Y(θ) A_Z(ψ)``: ``A13 = sin θ``, ``(A23, A33) = cos θ (−sin φ, cos φ)``
    and ``(A11, A12) = cos θ (cos ψ, −sin ψ)``.  The result has ``θ ∈ [−π/2, π/2]`` and
    ``φ, ψ ∈ (−π, π]``.

    Parameters
    ----------
    p : array_like, 4 elements
        Euler parameters (normalized here).

    Returns
    -------
    tuple of float
        ``(phi, theta, psi)`` in radians.

    Warns
    -----
    RuntimeWarning
        If ``|cos θ| < 1e-6`` (``θ = ±π/2``, gimbal lock): the singularity of this set, where the
        X and Z rotation axes coincide (seed 001, end of "Angular velocity in terms of Euler
        angles").  ``ψ`` is then set to 0 and ``φ`` carries the combined rotation (exact at
        ``cos θ = 0``; next to it the returned angles reproduce ``A`` to ``O(|cos θ|)``).
    """
    q = np.asarray(p, dtype=float).reshape(-1)
    A = rotation_matrix(q / np.linalg.norm(q))
    c = math.hypot(A[0, 0], A[0, 1])
    theta = math.atan2(A[0, 2], c)
    if c < SINGULARITY_TOL:
        warnings.warn(
            f"X-Y-Z (Cardan) angles are singular: cos(theta) = {c:.3g} (theta = {theta:.6g} "
            "rad); phi and psi rotate about the same axis, psi is set to 0",
            RuntimeWarning,
            stacklevel=2,
        )
        return math.atan2(A[2, 1], A[1, 1]), theta, 0.0
    phi = math.atan2(-A[1, 2], A[2, 2])
    psi = math.atan2(-A[0, 1], A[0, 0])
    return phi, theta, psi


# --------------------------------------------------------------------------- angular velocity
def E_matrix(p: ArrayOrSym) -> Any:  # noqa: N802 - name of the matrix in the literature
    """The 3x4 matrix ``E(p) = [−e, ẽ + e0 I]``.

    With it ``A = E Gᵀ``, ``E Eᵀ = I`` (unit ``p``), ``E p = 0`` and the global angular
    velocity is ``ω = 2 E ṗ`` — the Euler-parameter counterpart of ``ω = G θ̇`` of seed 001
    eq. 70 (derived from ``ω̃ = Ȧ Aᵀ``, eq. 39).

    Parameters
    ----------
    p : array_like or casadi.SX/MX, 4 elements
        Euler parameters.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 3x4
    """
    sym = _is_sym(p)
    q = _quat(p, sym)
    e0, e1, e2, e3 = q[0], q[1], q[2], q[3]
    return _stack([[-e1, e0, -e3, e2], [-e2, e3, e0, -e1], [-e3, -e2, e1, e0]], sym)


def G_matrix(p: ArrayOrSym) -> Any:  # noqa: N802 - name of the matrix in the literature
    """The 3x4 matrix ``G(p) = [−e, −ẽ + e0 I]``.

    With it ``A = E Gᵀ``, ``G Gᵀ = I`` (unit ``p``), ``G p = 0`` and the body-frame angular
    velocity is ``ω' = 2 G ṗ`` — the Euler-parameter counterpart of ``ω' = Ḡ θ̇`` of seed 001
    eqs. 80–83 (from ``ω̃' = Aᵀ Ȧ``, eqs. 50–52).

    Parameters
    ----------
    p : array_like or casadi.SX/MX, 4 elements
        Euler parameters.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 3x4
    """
    sym = _is_sym(p)
    q = _quat(p, sym)
    e0, e1, e2, e3 = q[0], q[1], q[2], q[3]
    return _stack([[-e1, e0, e3, -e2], [-e2, -e3, e0, e1], [-e3, e2, -e1, e0]], sym)


def angular_velocity_global(p: ArrayOrSym, pdot: ArrayOrSym) -> Any:
    """Angular velocity in global components, ``ω = 2 E(p) ṗ``.

    Equivalent to ``ω̃ = Ȧ Aᵀ`` (seed 001, "Angular velocity", eqs. 39–41).

    Parameters
    ----------
    p, pdot : array_like or casadi.SX/MX, 4 elements
        Euler parameters and their time derivatives.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 3 elements
    """
    sym = _is_sym(p, pdot)
    return 2.0 * _mtimes(E_matrix(_quat(p, sym)), _vector(pdot, 4, "pdot", sym), sym)


def angular_velocity_body(p: ArrayOrSym, pdot: ArrayOrSym) -> Any:
    """Angular velocity in body components, ``ω' = 2 G(p) ṗ = Aᵀ ω``.

    Equivalent to ``ω̃' = Aᵀ Ȧ`` (seed 001, "Angular velocity", eqs. 47 and 50–52).

    Parameters
    ----------
    p, pdot : array_like or casadi.SX/MX, 4 elements
        Euler parameters and their time derivatives.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 3 elements
    """
    sym = _is_sym(p, pdot)
    return 2.0 * _mtimes(G_matrix(_quat(p, sym)), _vector(pdot, 4, "pdot", sym), sym)


def quaternion_rate(p: ArrayOrSym, omega_global: ArrayOrSym) -> Any:
    """Euler-parameter rates of a global angular velocity, ``ṗ = ½ E(p)ᵀ ω``.

    The inverse of :func:`angular_velocity_global` for unit ``p`` (``E Eᵀ = I``, ``E p = 0``);
    the result satisfies ``pᵀ ṗ = 0``, the derivative of the normalization constraint.  This is
    what makes the orientation integrable, unlike ``ω`` itself (seed 001, eqs. 87–91).

    Parameters
    ----------
    p : array_like or casadi.SX/MX, 4 elements
        Euler parameters.
    omega_global : array_like or casadi.SX/MX, 3 elements
        Angular velocity ``ω`` in global components.

    Returns
    -------
    numpy.ndarray or casadi.SX/MX, 4 elements
    """
    sym = _is_sym(p, omega_global)
    E = E_matrix(_quat(p, sym))
    w = _vector(omega_global, 3, "omega_global", sym)
    return 0.5 * _mtimes(E.T, w, sym)
