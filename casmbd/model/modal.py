"""Modal data of a flexible body: a finite-element model and its reduction to a few modes.

A flexible body in the floating frame of reference (seed 002, "Equations of Motion with
Flexible Bodies", eqs. 5–26 to 5–34) moves a point of reference position ``x_i`` (body frame)
to ``x_i + Φ_t,i η`` and turns its node frame by the small rotation ``Φ_r,i η``, where η are
the modal coordinates and the columns of Φ are the component-mode-synthesis base vectors.
Seed 002 decomposes the mass matrix and right-hand side into invariants computed once, "with
a lumped mass approach": sums over the nodes of ``m_i``, ``m_i x_i``, ``m_i Φ_t,i``,
``m_i x̃_i Φ_t,i``, ``m_i Φ̃_t,i Φ_t,i``, ... and of the nodal rotary inertias ``J_i`` with
``Φ_r,i``.  :class:`ModalData` carries exactly what those sums need, per node.

This module holds the two data classes (:class:`FEModel`, the full model; :class:`ModalData`,
the reduced one) and the cache key; the reductions (Craig–Bampton, free-interface normal
modes) are in :mod:`casmbd.model.modal_reduction`, the built-in beam in
:mod:`casmbd.model.fe_beam`, the ``.npz`` import in :mod:`casmbd.model.fe_import`.
numpy/scipy only.

Conventions
-----------
* Degrees of freedom are numbered node by node: node ``i`` owns ``i*d ... i*d + d - 1`` with
  ``d = dofs_per_node``.  Plane (``dimension == 2``): ``d = 3`` → ``(u, v, θ)``, ``d = 2`` →
  ``(u, v)``.  Space (``dimension == 3``): ``d = 6`` → ``(u, v, w, θx, θy, θz)``, ``d = 3`` →
  ``(u, v, w)``.  Translations in metres along the body axes, rotations in radians (small
  rotation vector components along the body axes).
* Nodes without rotational dofs (solid meshes) have zero rotational mode shapes and zero
  nodal rotary inertia.
* Modes are mass-normalised: ``Φᵀ M Φ = I`` (to rounding), ``Φᵀ K Φ = diag(ω²)``, so η has
  units of kg^½·m and a modal damping ratio ζ_k gives the modal damping ``2 ζ_k ω_k``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import ModelError
from casmbd.lazy import lazy_module

sp = lazy_module("scipy.sparse")

__all__ = ["FEModel", "ModalData", "cache_key", "rotational_dofs", "translational_dofs"]


def translational_dofs(dimension: int, dofs_per_node: int) -> tuple[int, ...]:
    """Local indices of a node's translational dofs: ``(0, 1)`` in the plane, ``(0, 1, 2)``
    in space."""
    del dofs_per_node
    return tuple(range(dimension))


def rotational_dofs(dimension: int, dofs_per_node: int) -> tuple[int, ...]:
    """Local indices of a node's rotational dofs: ``(2,)`` (plane, 3 dofs per node),
    ``(3, 4, 5)`` (space, 6 dofs per node), ``()`` for translation-only nodes."""
    if dimension == 2:
        return (2,) if dofs_per_node == 3 else ()
    return (3, 4, 5) if dofs_per_node == 6 else ()


def check_node_layout(dimension: int, dofs_per_node: int, where: str) -> None:
    """Refuse node coordinates that are not 2 (plane) or 3 (space) columns, or a count of
    degrees of freedom per node that does not fit them (ModelError naming ``where``)."""
    allowed = {2: (2, 3), 3: (3, 6)}
    if dimension not in allowed:
        raise ModelError(f"{where}: node coordinates must have 2 (plane) or 3 (space) columns, "
                         f"got {dimension}")
    if dofs_per_node not in allowed[dimension]:
        raise ModelError(f"{where}: dofs_per_node must be one of {allowed[dimension]} for "
                         f"{'plane' if dimension == 2 else 'space'} nodes, got {dofs_per_node}")


@dataclass(frozen=True, eq=False)
class FEModel:
    """A finite-element model before reduction (built-in beam or imported ``.npz``).

    Attributes
    ----------
    mass_matrix, stiffness_matrix : numpy.ndarray or scipy.sparse.csr_matrix, (n_dof, n_dof)
        Symmetric M [kg, kg·m, kg·m²] and K [N/m, N, N·m] in the dof order of the module
        docstring (body axes).  M positive definite on the dofs that carry mass; K positive
        semi-definite (its null space holds the rigid-body modes of a free structure).
    positions : numpy.ndarray, (n_nodes, dimension)
        Reference (undeformed) node positions in the body frame [m].
    dofs_per_node : int
        2 or 3 (plane), 3 or 6 (space).
    masses : numpy.ndarray, (n_nodes,)
        Lumped nodal masses [kg] (seed 002's lumped-mass invariants).
    inertias : numpy.ndarray, (n_nodes,) plane or (n_nodes, 3, 3) space
        Lumped nodal rotary inertias about the node, body axes [kg·m²].
    node_names : dict[str, int]
        Named nodes (``root``, ``tip``, ...) → node index.
    source : str
        What the model was built from, used in error messages (``"beam 'link'"``, a file name).
    inputs : dict
        The data the model was built from (numbers, arrays), hashed by :func:`cache_key`.
    """

    mass_matrix: np.ndarray | sp.csr_matrix
    stiffness_matrix: np.ndarray | sp.csr_matrix
    positions: np.ndarray
    dofs_per_node: int
    masses: np.ndarray
    inertias: np.ndarray
    node_names: dict[str, int] = field(default_factory=dict)
    source: str = "finite-element model"
    inputs: dict = field(default_factory=dict)

    @property
    def dimension(self) -> int:
        """2 (plane) or 3 (space)."""
        return int(self.positions.shape[1])

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return int(self.positions.shape[0])

    @property
    def n_dof(self) -> int:
        """Number of degrees of freedom ``n_nodes * dofs_per_node``."""
        return self.n_nodes * self.dofs_per_node

    def node(self, name: str) -> int:
        """Index of a named node; ModelError naming the known names otherwise."""
        if name not in self.node_names:
            raise ModelError(f"{self.source}: no node named {name!r}; named nodes: "
                             f"{sorted(self.node_names)}")
        return self.node_names[name]

    def node_dofs(self, node: int) -> np.ndarray:
        """Global dof indices of a node."""
        d = self.dofs_per_node
        return np.arange(node * d, node * d + d)


@dataclass(frozen=True, eq=False)
class ModalData:
    """Reduced modal data of one flexible body: what the floating-frame equations need.

    With ``n`` nodes, ``m`` modes and ``dim`` = 2 (plane) or 3 (space), a node ``i`` of the
    deformed body sits, in the body frame, at ``positions[i] + phi_t[i] @ η`` and its frame
    is turned by the small rotation ``phi_r[i] @ η`` (plane: an angle about z; space: a
    rotation vector in body axes).  The body frame is

    * ``reduction == "craig_bampton"``: the undeformed frame of the *reference node*
      ``reference`` (the first interface): every mode has zero translation and rotation there
      (the node is clamped in the body frame; the rigid motion of the whole body is carried by
      the floating frame, and the constraint modes of the reference node — which together
      with the others span the rigid-body modes — are left out).  If the reference node has
      no rotational dofs (solid meshes) the constraint modes of the other interfaces span
      rigid rotations about it; those are dropped and the kept modes are mass-orthogonal to
      them (the frame's rotation then follows the linearised mean rotation);
    * ``reduction == "free"``: free-interface normal modes mass-orthogonal to the rigid-body
      modes (``R_kᵀ M Φ = 0``, linearised mean-axis conditions); ``reference`` is ``None`` and
      every node, node 0 included, may move in the body frame.

    In both cases the origin of the body frame is the origin of ``positions`` (node 0 of the
    built-in beam) and its axes are the FE model's axes.

    Attributes
    ----------
    dimension : int
        2 (plane) or 3 (space).
    positions : numpy.ndarray, (n, dim)
        Reference node positions in the body frame [m].
    masses : numpy.ndarray, (n,)
        Lumped nodal masses [kg] (seed 002, eqs. 5–29 to 5–34, lumped-mass invariants).
    inertias : numpy.ndarray, (n,) plane or (n, 3, 3) space
        Lumped nodal rotary inertias about the node, body axes [kg·m²] (zero for nodes without
        rotational dofs).
    phi_t : numpy.ndarray, (n, dim, m)
        Nodal translations per unit modal coordinate, body axes [m / (kg^½·m)].
    phi_r : numpy.ndarray, (n, m) plane or (n, 3, m) space
        Nodal small rotations per unit modal coordinate, body axes [rad / (kg^½·m)].
    mass : numpy.ndarray, (m, m)
        Reduced mass matrix ``Φᵀ M Φ`` with the FE mass matrix M used for the reduction
        (the identity to rounding: the modes are mass-normalised).
    stiffness : numpy.ndarray, (m, m)
        Reduced stiffness matrix ``Φᵀ K Φ`` (``diag(ω²)`` to rounding) [1/s²].
    frequencies : numpy.ndarray, (m,)
        Natural circular frequencies ω_k of the retained modes, ascending [rad/s].
    node_names : dict[str, int]
        Named nodes → index into ``positions``.
    reduction : str
        ``"craig_bampton"`` or ``"free"``.
    reference : int or None
        Index of the node clamped in the body frame (Craig–Bampton), ``None`` for free modes.
    rigid_mass : numpy.ndarray, (3, 3) plane or (6, 6) space
        ``Rᵀ M R``: the rigid-body mass matrix about the body-frame origin from the FE mass
        matrix, with R the rigid-body modes (plane: x, y translation, rotation about z; space:
        x, y, z translations, rotations about x, y, z).  Its blocks are the total mass, the
        first moment ``m x̃_G`` and the inertia tensor about the origin (exact for the
        consistent beam mass matrix, where the lumped sums are O(h²) approximations).
    rigid_coupling : numpy.ndarray, (3, m) plane or (6, m) space, or None
        ``Rᵀ M Φ``: the coupling of the rigid-body modes R (as in ``rigid_mass``) with the
        modes through the FE mass matrix — the consistent first moments ``S1`` (translation
        rows) and rotation–deformation couplings (rotation rows) that
        ``flexible_mass = "reduced"`` uses (zero for free-interface modes, which are
        mass-orthogonal to R).  ``None`` for modal data not computed from an FE mass matrix.
    source : str
        What the modes were computed from (for messages).
    key : str
        SHA-256 digest of the inputs (FE data, reduction, modes, interfaces): the cache key.
    """

    dimension: int
    positions: np.ndarray
    masses: np.ndarray
    inertias: np.ndarray
    phi_t: np.ndarray
    phi_r: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    frequencies: np.ndarray
    node_names: Mapping[str, int]
    reduction: str
    reference: int | None
    rigid_mass: np.ndarray
    rigid_coupling: np.ndarray | None = None
    source: str = "modal data"
    key: str = ""

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return int(self.positions.shape[0])

    @property
    def n_modes(self) -> int:
        """Number of modal coordinates η."""
        return int(self.phi_t.shape[-1])

    def node(self, name: str) -> int:
        """Index of a named node; ModelError naming the known names otherwise."""
        if name not in self.node_names:
            raise ModelError(f"{self.source}: no node named {name!r}; named nodes: "
                             f"{sorted(self.node_names)}")
        return int(self.node_names[name])

    def total_mass(self) -> float:
        """Sum of the lumped nodal masses [kg]."""
        return float(np.sum(self.masses))


def _digest_update(h, value) -> None:
    if isinstance(value, Mapping):
        h.update(b"{")
        for k in sorted(value, key=str):
            h.update(repr(str(k)).encode())
            _digest_update(h, value[k])
        h.update(b"}")
    elif sp.issparse(value):
        c = sp.csr_matrix(value)
        c.sum_duplicates()
        c.sort_indices()
        h.update(f"sparse{c.shape}".encode())
        for a in (c.indptr, c.indices, c.data):
            _digest_update(h, np.asarray(a))
    elif isinstance(value, np.ndarray):
        a = np.ascontiguousarray(value)
        if a.dtype.kind in "fc":
            a = a.astype(np.float64 if a.dtype.kind == "f" else np.complex128)
        elif a.dtype.kind in "iub":
            a = a.astype(np.int64)
        h.update(f"array{a.shape}{a.dtype.str}".encode())
        h.update(a.tobytes())
    elif isinstance(value, list | tuple):
        h.update(b"[")
        for v in value:
            _digest_update(h, v)
        h.update(b"]")
    else:
        h.update(repr(value).encode())
    h.update(b";")


def cache_key(*parts) -> str:
    """SHA-256 hex digest of modal-data inputs (numbers, strings, arrays, sparse matrices,
    mappings with sorted keys, sequences), so the modes can be cached with compiled code.

    Arrays are hashed by shape, dtype (floats as float64) and bytes; sparse matrices in
    canonical CSR form, so the same matrix saved dense or sparse gives different keys but the
    same sparse matrix in any format gives one key.
    """
    h = hashlib.sha256(b"casmbd-modal-data-v1;")
    for p in parts:
        _digest_update(h, p)
    return h.hexdigest()
