"""Built-in Euler–Bernoulli beam finite elements along the body x axis (numpy/scipy only).

Two-node elements of length ``h`` with linear axial (and torsional) and cubic Hermite bending
shape functions, as in Przemieniecki, *Theory of Matrix Structural Analysis* (1968), ch. 5 and
11, or Cook et al., *Concepts and Applications of Finite Element Analysis* (4th ed., 2002),
§2.4 and §11.3.  Nodal dofs:

* plane: ``(u, v, θ)`` — axial displacement, transverse displacement, rotation about z
  (``θ = dv/dx``);
* space: ``(u, v, w, θx, θy, θz)`` — axial, the two transverse displacements, torsion and the
  two bending rotations (``θz = dv/dx``, ``θy = −dw/dx``, right-handed).

Element stiffness (bending in the x–y plane, dofs ``v1, θ1, v2, θ2``; axial ``u1, u2``)::

    K_b = EI/h³ [[12, 6h, −12, 6h], [6h, 4h², −6h, 2h²], [−12, −6h, 12, −6h], [6h, 2h², −6h, 4h²]]
    K_a = EA/h [[1, −1], [−1, 1]]             (torsion: GJ/h [[1, −1], [−1, 1]])

consistent mass (the same shape functions)::

    M_b = ρA h/420 [[156, 22h, 54, −13h], [22h, 4h², 13h, −3h²], [54, 13h, 156, −22h],
                    [−13h, −3h², −22h, 4h²]]
    M_a = ρA h/6 [[2, 1], [1, 2]]             (torsion: ρIp h/6 [[2, 1], [1, 2]])

In the x–z plane (``w, θy``) the signs of the terms coupling a displacement with a rotation
flip, because ``θy = −dw/dx``.  Cubic elements make the static nodal displacements of a
beam loaded at the nodes exact (the tip deflection ``P L³/(3 EI)`` of a cantilever is exact
with one element).  Shear deformation and the rotary inertia of the cross-section in bending
are neglected (Euler–Bernoulli).

Lumped-mass description (seed 002's invariants are "approximated using a lumped mass
approach"): each node gets the mass of its tributary half-elements, ``m_i = Σ ρA h/2``, and
the rotary inertia of those half-elements about the node, ``ρA (h/2)³/3`` per half-element
about each bending axis and ``ρIp h/2`` about the beam axis (torsion).  The lumped sums
reproduce the total mass and first moment exactly and the rigid-body inertia to O(h²)
(h the element length); :attr:`casmbd.model.modal.ModalData.rigid_mass` holds the exact
rigid-body mass matrix from the consistent matrix.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from casmbd.errors import ModelError
from casmbd.lazy import lazy_module
from casmbd.limits import MAX_BEAM_ELEMENTS, check_count
from casmbd.model.modal import FEModel

sp = lazy_module("scipy.sparse")

__all__ = ["beam_model", "planar_element_matrices", "spatial_element_matrices"]


def _bending(h: float, EI: float, rhoA: float, sign: float = 1.0) -> tuple[np.ndarray, ...]:
    """Hermite bending stiffness and consistent mass for ``(v1, θ1, v2, θ2)``; ``sign = −1``
    for the x–z plane (``θy = −dw/dx``)."""
    s = np.diag([1.0, sign, 1.0, sign])
    k = EI / h**3 * np.array([[12.0, 6 * h, -12.0, 6 * h],
                              [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                              [-12.0, -6 * h, 12.0, -6 * h],
                              [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    m = rhoA * h / 420.0 * np.array([[156.0, 22 * h, 54.0, -13 * h],
                                     [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                     [54.0, 13 * h, 156.0, -22 * h],
                                     [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    return s @ k @ s, s @ m @ s


def _bar(h: float, stiff: float, inertia: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear bar (axial or torsion) stiffness ``c/h [[1, −1], [−1, 1]]`` and consistent mass
    ``μ h/6 [[2, 1], [1, 2]]``."""
    return (stiff / h * np.array([[1.0, -1.0], [-1.0, 1.0]]),
            inertia * h / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]]))


def _place(target: np.ndarray, block: np.ndarray, idx: Sequence[int]) -> None:
    target[np.ix_(idx, idx)] += block


def planar_element_matrices(h: float, EA: float, EI: float,
                            rhoA: float) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass (6x6) of a plane beam element, dofs
    ``(u1, v1, θ1, u2, v2, θ2)`` (module docstring; Przemieniecki 1968, eqs. 5.116, 11.32)."""
    K, M = np.zeros((6, 6)), np.zeros((6, 6))
    ka, ma = _bar(h, EA, rhoA)
    kb, mb = _bending(h, EI, rhoA)
    _place(K, ka, [0, 3])
    _place(M, ma, [0, 3])
    _place(K, kb, [1, 2, 4, 5])
    _place(M, mb, [1, 2, 4, 5])
    return K, M


def spatial_element_matrices(h: float, EA: float, EIy: float, EIz: float, GJ: float,
                             rhoA: float, rhoIp: float) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass (12x12) of a space beam element, dofs
    ``(u, v, w, θx, θy, θz)`` at each node.

    ``EIz`` is the bending stiffness about z (deflection v, x–y plane), ``EIy`` about y
    (deflection w, x–z plane), ``GJ`` the torsional stiffness, ``rhoIp`` the polar mass moment
    of inertia per unit length (torsion).  Przemieniecki (1968), eqs. 5.116 and 11.32.
    """
    K, M = np.zeros((12, 12)), np.zeros((12, 12))
    for (c, mu), (a, b) in (((EA, rhoA), (0, 6)), ((GJ, rhoIp), (3, 9))):
        kk, mm = _bar(h, c, mu)
        _place(K, kk, [a, b])
        _place(M, mm, [a, b])
    kz, mz = _bending(h, EIz, rhoA, 1.0)
    _place(K, kz, [1, 5, 7, 11])
    _place(M, mz, [1, 5, 7, 11])
    ky, my = _bending(h, EIy, rhoA, -1.0)
    _place(K, ky, [2, 4, 8, 10])
    _place(M, my, [2, 4, 8, 10])
    return K, M


def _per_element(name: str, value, n: int, source: str, *, required: bool = True,
                 positive: bool = True) -> np.ndarray | None:
    """A property as one value per element (scalar broadcast), finite and positive."""
    if value is None:
        if required:
            raise ModelError(f"{source}: property {name} is required")
        return None
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{source}: property {name} must be a number or one number per "
                         f"element, got {value!r}") from exc
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ModelError(f"{source}: property {name} must be a number or a list of {n} "
                         f"numbers (one per element), got shape {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a) | ((a <= 0.0) if positive else (a < 0.0)))
    if bad.size:
        raise ModelError(f"{source}: property {name} must be finite and "
                         f"{'positive' if positive else 'non-negative'}; element {int(bad[0])} "
                         f"has {float(a[bad[0]])!r}")
    return a


def _named_nodes(nodes: Mapping[str, float] | None, x: np.ndarray, length: float,
                 source: str) -> dict[str, int]:
    """Named nodes by arc length, each on an element boundary (relative tolerance 1e-9)."""
    if nodes is None:
        nodes = {"root": 0.0, "tip": length}
    if not isinstance(nodes, Mapping):
        raise ModelError(f"{source}: nodes must map names to arc lengths, got {nodes!r}")
    out: dict[str, int] = {}
    tol = 1e-9 * length
    for name, s in nodes.items():
        if not isinstance(name, str) or not name:
            raise ModelError(f"{source}: node names must be non-empty strings, got {name!r}")
        try:
            s = float(s)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"{source}: node {name!r}: arc length must be a number, "
                             f"got {s!r}") from exc
        if not np.isfinite(s) or s < -tol or s > length + tol:
            raise ModelError(f"{source}: node {name!r} at arc length {s!r} lies outside the "
                             f"beam [0, {length:g}]")
        i = int(np.argmin(np.abs(x - s)))
        if abs(x[i] - s) > tol:
            lo = x[x <= s].max() if np.any(x <= s) else x[0]
            hi = x[x >= s].min() if np.any(x >= s) else x[-1]
            raise ModelError(f"{source}: node {name!r} at arc length {s:g} is not on an element "
                             f"boundary; the nearest nodes are at {lo:g} and {hi:g} (change "
                             "the arc length, the number of elements or the element lengths)")
        out[name] = i
    return out


#: Plausible ranges of a beam's properties, SI units (low, high, unit).  Outside them the
#: element matrices overflow or underflow (EI·12/h³ with h = 1e-301 m is infinite) or give
#: frequencies no integrator can step: almost always a unit or exponent error (mm for m, MPa
#: for Pa, 1e308 for 1e8).  Wide on purpose: a MEMS cantilever (EI ~ 1e-14 N·m², L ~ 1e-6 m)
#: and a bridge girder (EI ~ 1e12 N·m², L ~ 1e3 m) are well inside.
PLAUSIBLE_BEAM = {"length": (1e-9, 1e6, "m"), "element_lengths": (1e-12, 1e6, "m"),
                  "EA": (1e-30, 1e20, "N"), "EI": (1e-30, 1e20, "N·m²"),
                  "EIy": (1e-30, 1e20, "N·m²"), "EIz": (1e-30, 1e20, "N·m²"),
                  "GJ": (1e-30, 1e20, "N·m²"), "rhoA": (1e-20, 1e10, "kg/m"),
                  "rhoIp": (1e-30, 1e10, "kg·m")}
#: Highest plausible angular frequency of an element [rad/s] (ω² ≤ 1e30): a femtosecond
#: period, beyond any structure and any time step.
PLAUSIBLE_OMEGA = 1e15


def _check_plausible(src: str, field: str, values: np.ndarray) -> None:
    """Refuse a property outside :data:`PLAUSIBLE_BEAM`, naming the field and the range."""
    low, high, unit = PLAUSIBLE_BEAM[field]
    bad = np.flatnonzero((values < low) | (values > high))
    if bad.size:
        at = "" if field == "length" or np.all(values == values[0]) else \
            f" (element {int(bad[0])})"
        raise ModelError(f"{src}: field '{field}' = {float(values[bad[0]]):.6g} {unit}{at} is "
                         f"outside the plausible range [{low:g}, {high:g}] {unit}: check its "
                         "unit and exponent")


def _check_frequencies(src: str, le: np.ndarray, rho: np.ndarray,
                       stiff: dict[str, np.ndarray]) -> None:
    """Refuse elements whose highest frequency exceeds :data:`PLAUSIBLE_OMEGA`.

    Per element of length h: axial and torsional ω² = 12 S/(ρ h²) (S = EA with ρ = rhoA, GJ
    with ρ = rhoIp), bending ω² = 8400 EI/(ρA h⁴) — the largest eigenvalues of the free
    consistent rod and Hermite-cubic element pairs (K, M) of :func:`planar_element_matrices`
    (the rod: mode [1, −1], λ = (2 EA/h)/(ρA h/6)) — in logarithms so that nothing
    overflows.
    """
    for field, (values, rho_e, power, factor) in stiff.items():
        log_w2 = np.log10(factor * values) - np.log10(rho_e) - power * np.log10(le)
        worst = int(np.argmax(log_w2))
        if log_w2[worst] > 2 * np.log10(PLAUSIBLE_OMEGA):
            density = "rhoIp" if field == "GJ" else "rhoA"
            raise ModelError(
                f"{src}: field '{field}' = {float(values[worst]):.6g} with {density} = "
                f"{float(rho_e[worst]):.6g} and element length {float(le[worst]):.6g} m gives "
                f"frequencies up to ω ≈ 1e{log_w2[worst] / 2:.0f} rad/s, beyond the plausible "
                f"{PLAUSIBLE_OMEGA:g} rad/s: check the units of the stiffness, the mass per "
                "length and the length")


def beam_model(length: float, elements: int, *, EA, rhoA, EI=None, EIy=None, EIz=None,
               GJ=None, rhoIp=None, dimension: int = 2,
               nodes: Mapping[str, float] | None = None, element_lengths=None,
               mass: str = "consistent", name: str = "beam") -> FEModel:
    """Assemble an Euler–Bernoulli beam along the body x axis, node 0 at the origin.

    Parameters
    ----------
    length : float
        Beam length L [m].
    elements : int
        Number of elements (equal lengths ``L/elements`` unless ``element_lengths`` is given).
    EA, rhoA : float or sequence of float (one per element)
        Axial stiffness [N] and mass per unit length [kg/m].
    EI : float or sequence
        Plane: bending stiffness [N·m²].
    EIy, EIz, GJ, rhoIp : float or sequence
        Space: bending stiffness about y (deflection w) and about z (deflection v) [N·m²],
        torsional stiffness [N·m²], polar mass moment of inertia per unit length [kg·m].
    dimension : int
        2 (plane) or 3 (space).
    nodes : mapping str → float, optional
        Named nodes by arc length (default ``{"root": 0, "tip": L}``); each must fall on an
        element boundary (relative tolerance 1e-9), otherwise ModelError naming the node and
        the nearest node positions.
    element_lengths : sequence of float, optional
        Element lengths summing to ``length`` (relative 1e-9).
    mass : str
        ``"consistent"`` (default) or ``"lumped"``: the mass matrix of the model (the lumped
        one is the diagonal of the nodal masses and rotary inertias, the same numbers as the
        lumped-mass description, so that ``Φᵀ M Φ`` equals the lumped invariant sums).
    name : str
        Used in messages: ``beam 'name'``.

    Returns
    -------
    FEModel
        Sparse (CSR) M and K, positions ``(elements + 1, dimension)``, lumped masses and
        inertias, the named nodes.
    """
    src = f"beam {name!r}"
    try:
        L = float(length)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{src}: length must be a number, got {length!r}") from exc
    if not np.isfinite(L) or L <= 0.0:
        raise ModelError(f"{src}: length must be finite and positive, got {length!r}")
    if isinstance(elements, bool) or not isinstance(elements, int | np.integer) or elements < 1:
        raise ModelError(f"{src}: elements must be a positive integer, got {elements!r}")
    n = int(elements)
    check_count(f"{src}: elements", n, MAX_BEAM_ELEMENTS,
                "use fewer elements (a modal reduction converges with tens)")
    if dimension not in (2, 3):
        raise ModelError(f"{src}: dimension must be 2 (plane) or 3 (space), got {dimension!r}")
    if mass not in ("consistent", "lumped"):
        raise ModelError(f"{src}: mass must be 'consistent' or 'lumped', got {mass!r}")
    if element_lengths is None:
        le = np.full(n, L / n)
    else:
        le = _per_element("element_lengths", element_lengths, n, src)
        if abs(le.sum() - L) > 1e-9 * L:
            raise ModelError(f"{src}: element_lengths sum to {le.sum():g}, not the length {L:g}")
    _check_plausible(src, "length", np.array([L]))
    _check_plausible(src, "element_lengths", le)
    x = np.concatenate([[0.0], np.cumsum(le)])
    x[-1] = L
    ea = _per_element("EA", EA, n, src)
    rho = _per_element("rhoA", rhoA, n, src)
    if dimension == 2:
        if any(v is not None for v in (EIy, EIz, GJ)):
            raise ModelError(f"{src}: a plane beam takes EI (EIy, EIz, GJ are for space)")
        ei = _per_element("EI", EI, n, src)
        d = 3
    else:
        if EI is not None:
            raise ModelError(f"{src}: a space beam takes EIy and EIz (not EI)")
        eiy = _per_element("EIy", EIy, n, src)
        eiz = _per_element("EIz", EIz, n, src)
        gj = _per_element("GJ", GJ, n, src)
        rip = _per_element("rhoIp", rhoIp, n, src)
        d = 6
    props = {"EA": ea, "rhoA": rho}
    if dimension == 2:
        props["EI"] = ei
    else:
        props.update(EIy=eiy, EIz=eiz, GJ=gj, rhoIp=rip)
    for field, values in props.items():
        _check_plausible(src, field, values)
    stiff = {"EA": (ea, rho, 2, 12.0)}
    stiff.update({k: (props[k], rho, 4, 8400.0) for k in ("EI", "EIy", "EIz") if k in props})
    if dimension == 3:
        stiff["GJ"] = (gj, rip, 2, 12.0)
    _check_frequencies(src, le, rho, stiff)
    names = _named_nodes(nodes, x, L, src)
    rows, cols, kv, mv = [], [], [], []
    masses = np.zeros(n + 1)
    rot = np.zeros((n + 1, 3))          # lumped rotary inertia about x, y, z
    for e in range(n):
        h = le[e]
        if dimension == 2:
            ke, me = planar_element_matrices(h, ea[e], ei[e], rho[e])
        else:
            ke, me = spatial_element_matrices(h, ea[e], eiy[e], eiz[e], gj[e], rho[e], rip[e])
        idx = np.arange(e * d, e * d + 2 * d)
        r, c = np.meshgrid(idx, idx, indexing="ij")
        rows.append(r.ravel())
        cols.append(c.ravel())
        kv.append(ke.ravel())
        mv.append(me.ravel())
        half_rot = rho[e] * (h / 2.0) ** 3 / 3.0
        for node in (e, e + 1):
            masses[node] += rho[e] * h / 2.0
            rot[node, 1:] += half_rot
            if dimension == 3:
                rot[node, 0] += rip[e] * h / 2.0
    ndof = (n + 1) * d
    rows_a, cols_a = np.concatenate(rows), np.concatenate(cols)
    K = sp.csr_matrix((np.concatenate(kv), (rows_a, cols_a)), shape=(ndof, ndof))
    positions = np.zeros((n + 1, dimension))
    positions[:, 0] = x
    if dimension == 2:
        inertias = rot[:, 2].copy()
        diag = np.column_stack([masses, masses, inertias]).ravel()
    else:
        inertias = np.zeros((n + 1, 3, 3))
        for k in range(3):
            inertias[:, k, k] = rot[:, k]
        diag = np.column_stack([masses, masses, masses, rot]).ravel()
    if mass == "consistent":
        M = sp.csr_matrix((np.concatenate(mv), (rows_a, cols_a)), shape=(ndof, ndof))
    else:
        M = sp.diags(diag).tocsr()
    inputs = {"kind": "beam", "dimension": dimension, "element_lengths": le, "mass": mass,
              "nodes": dict(names), **props}
    return FEModel(mass_matrix=M, stiffness_matrix=K, positions=positions, dofs_per_node=d,
                   masses=masses, inertias=inertias, node_names=names, source=src,
                   inputs=inputs)
