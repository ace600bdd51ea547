"""Flexible bodies (planar and spatial): the body kind ``type = "flexible"`` and its node frames.

A flexible body is a floating frame of reference (origin R, rotation A) carrying the
component-mode-synthesis base vectors of a finite-element model: a node i sits at
r_i = R + A (u_i0 + Φ_i η) (seed 002, eq. 5–26; Shabana, *Dynamics of Multibody Systems*,
ch. 5).  The model layer holds what the body *is*: its modal data
(:class:`casmbd.model.modal.ModalData`, from the built-in beam of :mod:`casmbd.model.fe_beam`
or an ``.npz`` file read by :mod:`casmbd.model.fe_import`, reduced by
:mod:`casmbd.model.modal_reduction`), its initial pose, damping and stiffening options, and
its named nodes.  The equations (lumped-mass invariants) are written by the system layer
(:mod:`casmbd.system.floating_frame`, :mod:`casmbd.system.flexible_descriptions`).

Node frames.  Joints, forces, drivers and markers attach to a named node of a flexible body
through the *attachment name* ``"<body>@<node>"`` (scene files: ``body1 = "beam"`` with
``node1 = "tip"``).  :class:`NodeFrame` gives such a frame the few attributes a rigid body
offers the context (initial position and rotation, ``local``), so every element kind attaches
to a node without a line of its own.  Each named node is also a marker of the same name, so
results report its deformed position and frame (:meth:`casmbd.results.Result.marker`).

Scene keys (issue 23)::

    [[bodies]]
    name = "beam"
    type = "flexible"
    position = [0.0, 0.0]            # body-frame origin (node 0 of the beam model)
    angle = 0.0                      # plane; in space orientation / euler_zxz
    modes = 4
    reduction = "craig_bampton"      # or "free"
    interfaces = ["root", "tip"]
    damping_ratio = 0.0              # one number or one per mode
    stiffening = false
    [bodies.beam]                    # or [bodies.fe] file = "part.npz"
    length = 10.0
    elements = 20
    EI = 1.4e4                       # plane; in space EIy, EIz, GJ (and rhoIp)
    EA = 2.8e7
    rhoA = 1.2
    nodes = { root = 0.0, tip = 10.0 }
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import rotation, scalar, unit_quaternion, vector
from casmbd.model.fe_beam import beam_model
from casmbd.model.fe_import import load_fe_npz
from casmbd.model.modal import FEModel, ModalData, cache_key
from casmbd.model.modal_reduction import ModesError, check_units, fe_model_key, reduce
from casmbd.model.registry import register_body
from casmbd.model.rotations import euler_zxz_to_quaternion, rotation_matrix

__all__ = [
    "FLEXIBLE_SCENE_KEYS",
    "ModalStore",
    "NodeFrame",
    "PlanarFlexibleBody",
    "SpatialFlexibleBody",
    "is_flexible",
    "modal_data",
    "named_nodes",
    "node_attachment",
    "rigidified",
]

#: separator of attachment names ``"<body>@<node>"``
NODE_SEPARATOR = "@"

FLEXIBLE_SCENE_KEYS = frozenset({
    "name", "type", "position", "angle", "orientation", "euler_zxz", "velocity",
    "angular_velocity", "modes", "reduction", "interfaces", "damping_ratio", "stiffening",
    "flexible_mass", "beam", "fe", "description"})
_BEAM_KEYS = {2: {"length", "elements", "EI", "EA", "rhoA", "nodes", "element_lengths", "mass"},
              3: {"length", "elements", "EIy", "EIz", "GJ", "EA", "rhoA", "rhoIp", "nodes",
                  "element_lengths", "mass"}}
_FE_KEYS = {"file"}

#: modal data computed in this process, by FE-model key and reduction (the eigenproblem of an
#: imported model may take seconds; a scene loaded twice computes it once)
_MODES: dict[str, ModalData] = {}


#: an on-disk store of modal data: ``(load(key) -> ModalData | None, save(key, modal))``, e.g.
#: :data:`casmbd.compiled.modal_cache.DISK_STORE`; passed in by the caller (the scene reader
#: gives it to each ``[[bodies]]`` entry as ``entry.modal_store``): the model layer does not
#: import the compiled one, and nothing registers it
ModalStore = tuple[Callable[[str], ModalData | None], Callable[[str, ModalData], None]]


def modal_data(model: FEModel, reduction: str, modes: int,
               interfaces: Sequence[str] = (), store: ModalStore | None = None) -> ModalData:
    """The reduced modal data of ``model`` (:func:`casmbd.model.modal_reduction.reduce`),
    computed once for the same FE data, reduction, modes and interfaces: kept for the process
    and, when a ``store`` is given (:data:`casmbd.compiled.modal_cache.DISK_STORE`), on disk
    beside the compiled code."""
    check_units(model)  # cheap; also on a hit (a file cached by an older version)
    key = cache_key(fe_model_key(model), reduction, int(modes), list(interfaces))
    if key not in _MODES:
        stored = store[0](key) if store is not None else None
        if stored is None:
            stored = reduce(model, reduction, modes, interfaces)
            if store is not None:
                store[1](key, stored)
        _MODES[key] = stored
    return _MODES[key]


def node_attachment(name: str) -> tuple[str, str] | None:
    """(body, node) of an attachment name ``"body@node"``, None for a plain body name."""
    if not isinstance(name, str) or NODE_SEPARATOR not in name:
        return None
    body, _, node = name.rpartition(NODE_SEPARATOR)
    return body, node


@dataclass
class NodeFrame:
    """The frame of a named node of a flexible body, seen by elements as a body.

    Attributes
    ----------
    name : str
        The attachment name ``"<body>@<node>"``.
    body : str
        The flexible body.
    node : str
        The node's name.
    index : int
        The node's index in the body's modal data.
    position : numpy.ndarray
        Global position of the node at the initial (undeformed) pose.
    angle : float
        Plane: the node frame's angle at the initial pose (the body's).
    initial_rotation : numpy.ndarray
        The node frame's rotation at the initial pose (the body's).
    """

    name: str
    body: str
    node: str
    index: int
    position: np.ndarray
    initial_rotation: np.ndarray
    angle: float = 0.0
    dimension: int = 2
    reference_point: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def local(self, point_global) -> np.ndarray:
        """Node-frame coordinates of a global point at the initial pose."""
        return self.initial_rotation.T @ (np.asarray(point_global, float) - self.position)


def _evaluate(e, raw, key: str, table: str) -> float:
    """A number of a nested table (a number, or an expression of the parameters)."""
    if isinstance(raw, bool) or not isinstance(raw, int | float | str):
        raise e.error(table, f"field '{key}': expected a number, got {raw!r}")
    return e.evaluate(raw, table) if isinstance(raw, str) else scalar(
        raw, f"{e.where} key '{table}' field '{key}'")


def _per_element(e, raw, key: str, table: str):
    """A number or a list of numbers (one per element)."""
    if isinstance(raw, list):
        return [_evaluate(e, x, key, table) for x in raw]
    return _evaluate(e, raw, key, table)


def _beam_from_scene(e, dim: int, name: str) -> FEModel:
    """The FE model of a ``[bodies.beam]`` table."""
    raw = e.data["beam"]
    if not isinstance(raw, dict):
        raise e.error("beam", f"expected a table ([bodies.beam]), got {raw!r}")
    unknown = sorted(set(raw) - _BEAM_KEYS[dim])
    if unknown:
        raise e.error("beam", f"unknown field '{unknown[0]}' (allowed: "
                      f"{', '.join(sorted(_BEAM_KEYS[dim]))})")
    required = ("length", "elements", "EA", "rhoA") + (("EI",) if dim == 2 else
                                                         ("EIy", "EIz", "GJ"))
    for key in required:
        if key not in raw:
            raise e.error("beam", f"missing field '{key}'")
    elements = raw["elements"]
    if isinstance(elements, bool) or not isinstance(elements, int) or elements < 1:
        raise e.error("beam", f"field 'elements': expected a positive integer, got "
                      f"{elements!r}")
    nodes = raw.get("nodes")
    if nodes is not None:
        if not isinstance(nodes, dict) or not nodes:
            raise e.error("beam", f"field 'nodes': expected a table of name = arc length, got "
                          f"{nodes!r}")
        nodes = {k: _evaluate(e, v, f"nodes.{k}", "beam") for k, v in nodes.items()}
    props = {key: _per_element(e, raw[key], key, "beam")
             for key in ("EA", "rhoA", "EI", "EIy", "EIz", "GJ", "rhoIp") if key in raw}
    lengths = raw.get("element_lengths")
    if lengths is not None:
        lengths = [_evaluate(e, x, "element_lengths", "beam") for x in lengths] \
            if isinstance(lengths, list) else lengths
    mass = raw.get("mass", "consistent")
    try:
        return beam_model(_evaluate(e, raw["length"], "length", "beam"), elements,
                          dimension=dim, nodes=nodes, element_lengths=lengths, mass=mass,
                          name=name, **props)
    except ModelError as exc:
        raise e.error("beam", str(exc)) from None


def _fe_from_scene(e, name: str) -> FEModel:
    """The FE model of a ``[bodies.fe]`` table (an ``.npz`` file, relative to the scene)."""
    raw = e.data["fe"]
    if not isinstance(raw, dict) or set(raw) - _FE_KEYS or "file" not in raw:
        raise e.error("fe", f"expected a table with 'file' = \"part.npz\", got {raw!r}")
    file = raw["file"]
    if not isinstance(file, str) or not file.endswith(".npz"):
        raise e.error("fe", f"field 'file': expected an .npz file name, got {file!r}")
    path = Path(file)
    if not path.is_absolute():
        path = Path(getattr(e, "base_dir", ".")) / path
    try:
        return load_fe_npz(path, name=name)
    except ModelError as exc:
        raise e.error("fe", str(exc)) from None


def _modal_from_scene(e, dim: int) -> tuple[ModalData, dict]:
    """Modal data and options of a flexible ``[[bodies]]`` entry."""
    name = e.string("name")
    if e.has("beam") == e.has("fe"):
        raise e.error("beam", "a flexible body needs one of [bodies.beam] (built-in beam) or "
                      "[bodies.fe] (an .npz file)")
    model = _beam_from_scene(e, dim, name) if e.has("beam") else _fe_from_scene(e, name)
    modes = e.data.get("modes", 4)
    if isinstance(modes, bool) or not isinstance(modes, int) or modes < 0:
        raise e.error("modes", f"expected a non-negative integer, got {modes!r}")
    reduction = e.string("reduction", default="craig_bampton")
    interfaces = e.data.get("interfaces")
    if interfaces is None:
        interfaces = [n for n in ("root", "tip") if n in model.node_names] \
            if reduction == "craig_bampton" else []
    if not isinstance(interfaces, list) or not all(isinstance(n, str) for n in interfaces):
        raise e.error("interfaces", f"expected a list of node names, got {interfaces!r}")
    try:
        modal = modal_data(model, reduction, modes, interfaces,
                           store=getattr(e, "modal_store", None))
    except ModesError as exc:
        raise e.error("modes", str(exc)) from None
    except ModelError as exc:
        raise e.error("fe" if e.has("fe") else "reduction", str(exc)) from None
    ratio = e.data.get("damping_ratio", 0.0)
    ratio = [_evaluate(e, x, "damping_ratio", "damping_ratio") for x in ratio] \
        if isinstance(ratio, list) else e.number("damping_ratio", 0.0)
    stiffening = e.data.get("stiffening", False)
    if not isinstance(stiffening, bool):
        raise e.error("stiffening", f"expected true or false, got {stiffening!r}")
    options = {"damping_ratio": ratio, "stiffening": stiffening,
               "flexible_mass": e.string("flexible_mass", default="lumped")}
    return modal, options


def _rigid_properties(modal: ModalData) -> tuple[float, np.ndarray, np.ndarray]:
    """Total mass, undeformed centre of mass (body frame) and inertia about it, from the
    lumped nodes (the sums the floating-frame invariants use)."""
    m = np.asarray(modal.masses, float)
    u = np.asarray(modal.positions, float)
    total = float(m.sum())
    if total <= 0.0:
        raise ModelError(f"{modal.source}: the nodes carry no mass")
    c = m @ u / total
    r = u - c
    if modal.dimension == 2:
        inertia = float(np.sum(m * np.sum(r * r, axis=1)) + np.sum(modal.inertias))
        return total, c, np.array([inertia])
    tensor = np.einsum("i,ij->", m, r * r) * np.eye(3) - np.einsum("i,ia,ib->ab", m, r, r)
    tensor = tensor + np.sum(np.asarray(modal.inertias, float), axis=0)
    return total, c, 0.5 * (tensor + tensor.T)


class _Flexible:
    """What the planar and spatial flexible bodies share (mixin of the two dataclasses)."""

    kind: ClassVar[str] = "flexible"
    title: ClassVar[str] = "flexible"
    scene_keys: ClassVar[frozenset[str]] = FLEXIBLE_SCENE_KEYS
    #: drawn as the polyline of its deformed nodes (:mod:`casmbd.viz.geometry`)
    drawing: ClassVar[str] = "nodes"
    #: the coordinate choices the kind supports: frame coordinates + modal coordinates
    coordinate_choices: ClassVar[tuple[str, ...]] = ("absolute", "natural")
    #: what it needs from an analysis (casmbd.model.needs)
    needs: ClassVar[frozenset[str]] = frozenset({"modal_coordinates"})

    def _finish(self) -> None:
        """Mass, inertia, centre of mass and reference point from the modal data."""
        if not isinstance(self.modal, ModalData):
            raise ModelError(f"body '{self.name}' field 'modal': expected ModalData, got "
                             f"{type(self.modal).__name__}")
        if self.modal.dimension != self.dimension:
            raise ModelError(f"body '{self.name}': {self.modal.dimension}-dimensional modal "
                             f"data for a {'planar' if self.dimension == 2 else 'spatial'} "
                             "body")
        mass, centre, inertia = _rigid_properties(self.modal)
        self.mass = mass
        self.inertia = float(inertia[0]) if self.dimension == 2 else (
            *np.diag(inertia), inertia[0, 1], inertia[0, 2], inertia[1, 2])
        self.centre = centre
        # the frame origin R is the reference point: r_G = R + A c, so s = −c (bodies.py)
        self.reference_point = -centre
        self.position = self.origin + self.initial_rotation @ centre

    @property
    def nodes(self) -> dict[str, int]:
        """Named nodes → index into the modal data."""
        return dict(self.modal.node_names)

    @property
    def n_modes(self) -> int:
        """Number of modal coordinates η."""
        return int(self.modal.n_modes)

    @property
    def is_centroidal(self) -> bool:
        return False

    def node_frame(self, node: str) -> NodeFrame:
        """The :class:`NodeFrame` of a named node.

        Raises
        ------
        ModelError
            No node of that name (listing the named nodes).
        """
        if node not in self.modal.node_names:
            raise ModelError(f"body '{self.name}' has no node '{node}' (named nodes: "
                             f"{', '.join(sorted(self.modal.node_names)) or 'none'})")
        i = int(self.modal.node_names[node])
        rot = self.initial_rotation
        pos = self.origin + rot @ np.asarray(self.modal.positions[i], float)
        dim = self.dimension
        return NodeFrame(f"{self.name}{NODE_SEPARATOR}{node}", self.name, node, i, pos, rot,
                         float(getattr(self, "angle", 0.0)), dim, np.zeros(dim))

    def local(self, point_global) -> np.ndarray:
        """Body-frame coordinates (about the undeformed centre of mass) of a global point."""
        return self.initial_rotation.T @ (np.asarray(point_global, float) - self.position)


@register_body
@dataclass
class PlanarFlexibleBody(_Flexible):
    """A planar flexible body: floating frame (x, y, θ) and modal coordinates η.

    Parameters
    ----------
    name : str
    modal : ModalData
        Reduced modal data (2-dimensional).
    origin : array_like, 2
        Global position of the body-frame origin at the initial pose (scene ``position``).
    angle : float
        Initial angle of the body frame.
    velocity : array_like, 2
        Initial velocity of the frame origin.
    angular_velocity : float
    damping_ratio : float or sequence
        Modal damping ratio (one, or one per mode).
    stiffening : bool
        Geometric stiffness of every axial load from the foreshortening kinematics (beams
        along the body x axis; :mod:`casmbd.system.floating_frame`).
    flexible_mass : {"lumped", "reduced"}
    """

    name: str
    modal: ModalData
    origin: np.ndarray
    angle: float = 0.0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    angular_velocity: float = 0.0
    damping_ratio: float | Sequence[float] = 0.0
    stiffening: bool = False
    flexible_mass: str = "lumped"
    #: modal coordinates held at zero (the rigid motion: kinematics and inverse dynamics)
    locked_modes: bool = False

    dimension = 2
    dimensions: ClassVar[tuple[int, ...]] = (2,)
    descriptions: ClassVar[dict[str, str]] = {"absolute": "planar_flexible",
                                              "natural": "planar_flexible_natural"}

    def __post_init__(self):
        where = f"body '{self.name}' field"
        self.origin = vector(self.origin, f"{where} 'position'", 2)
        self.angle = scalar(self.angle, f"{where} 'angle'")
        self.velocity = vector(self.velocity, f"{where} 'velocity'", 2)
        self.angular_velocity = scalar(self.angular_velocity, f"{where} 'angular_velocity'")
        self._finish()

    @property
    def initial_rotation(self) -> np.ndarray:
        return rotation(self.angle)

    @classmethod
    def create(cls, mech, name: str, modal: ModalData, position: Sequence[float],
               angle: float = 0.0, velocity: Sequence[float] | None = None,
               angular_velocity=None, damping_ratio=0.0, stiffening: bool = False,
               flexible_mass: str = "lumped", orientation=None,
               euler_zxz=None) -> PlanarFlexibleBody:
        """Build the body of ``mech.add("body:flexible", name, modal=..., position=...)``;
        ``position`` is the body-frame origin (node 0 of a built-in beam)."""
        mech._unique(mech.bodies, "body", name)
        for key, value in (("orientation", orientation), ("euler_zxz", euler_zxz)):
            if value is not None:
                raise ModelError(f"body '{name}' field '{key}': planar bodies have an "
                                 "'angle'")
        return cls(name, modal, position, angle, (0.0, 0.0) if velocity is None else velocity,
                   0.0 if angular_velocity is None else angular_velocity, damping_ratio,
                   stiffening, flexible_mass)

    @classmethod
    def from_scene(cls, mech, e) -> PlanarFlexibleBody:
        """Add the flexible body of one ``[[bodies]]`` entry (module docstring)."""
        for key in ("orientation", "euler_zxz"):
            if e.has(key):
                raise e.error(key, "planar bodies take 'angle' (spatial scenes: dimension = 3)")
        modal, options = _modal_from_scene(e, 2)
        return mech.add(f"body:{cls.kind}", e.string("name"), modal=modal,
                        position=e.vector("position"), angle=e.number("angle", 0.0),
                        velocity=e.vector("velocity", default=[0.0, 0.0]),
                        angular_velocity=e.number("angular_velocity", 0.0), **options)


@register_body
@dataclass
class SpatialFlexibleBody(_Flexible):
    """A spatial flexible body: floating frame (x, y, z, Euler parameters) and modal
    coordinates η (parameters as :class:`PlanarFlexibleBody`; ``orientation`` a unit
    quaternion [w, x, y, z] of the initial frame, angular velocity global)."""

    name: str
    modal: ModalData
    origin: np.ndarray
    orientation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    damping_ratio: float | Sequence[float] = 0.0
    stiffening: bool = False
    flexible_mass: str = "lumped"
    #: modal coordinates held at zero (the rigid motion: kinematics and inverse dynamics)
    locked_modes: bool = False

    dimension = 3
    dimensions: ClassVar[tuple[int, ...]] = (3,)
    descriptions: ClassVar[dict[str, str]] = {"absolute": "spatial_flexible",
                                              "natural": "spatial_flexible_natural"}

    def __post_init__(self):
        where = f"body '{self.name}' field"
        self.origin = vector(self.origin, f"{where} 'position'", 3)
        self.orientation = unit_quaternion(self.orientation, f"{where} 'orientation'")
        self.velocity = vector(self.velocity, f"{where} 'velocity'", 3)
        self.angular_velocity = vector(self.angular_velocity, f"{where} 'angular_velocity'", 3)
        self._finish()

    @property
    def initial_rotation(self) -> np.ndarray:
        return rotation_matrix(self.orientation)

    @classmethod
    def create(cls, mech, name: str, modal: ModalData, position: Sequence[float],
               angle: float = 0.0, velocity=None, angular_velocity=None, damping_ratio=0.0,
               stiffening: bool = False, flexible_mass: str = "lumped", orientation=None,
               euler_zxz=None) -> SpatialFlexibleBody:
        """Build a spatial flexible body (orientation a quaternion or Z-X-Z Euler angles)."""
        mech._unique(mech.bodies, "body", name)
        if angle:
            raise ModelError(f"body '{name}' field 'angle': spatial bodies take "
                             "'orientation' (quaternion) or 'euler_zxz'")
        if orientation is not None and euler_zxz is not None:
            raise ModelError(f"body '{name}': give 'orientation' or 'euler_zxz', not both")
        if euler_zxz is not None:
            orientation = euler_zxz_to_quaternion(
                *vector(euler_zxz, f"body '{name}' field 'euler_zxz'", 3))
        zeros = (0.0, 0.0, 0.0)
        return cls(name, modal, position,
                   (1.0, 0.0, 0.0, 0.0) if orientation is None else orientation,
                   zeros if velocity is None else velocity,
                   zeros if angular_velocity is None else angular_velocity, damping_ratio,
                   stiffening, flexible_mass)

    @classmethod
    def from_scene(cls, mech, e) -> SpatialFlexibleBody:
        """Add the spatial flexible body of one ``[[bodies]]`` entry."""
        if e.has("angle"):
            raise e.error("angle", "spatial bodies take 'orientation' (unit quaternion [w, x, "
                          "y, z]) or 'euler_zxz' ([phi, theta, psi])")
        if e.has("orientation") and e.has("euler_zxz"):
            raise e.error("orientation", "give 'orientation' or 'euler_zxz', not both")
        orientation = e.vector("orientation", 4, required=False)
        if orientation is not None and abs(math.sqrt(sum(x * x for x in orientation)) - 1) > 1e-3:
            raise e.error("orientation", "expected a unit quaternion [w, x, y, z]")
        modal, options = _modal_from_scene(e, 3)
        zeros = [0.0, 0.0, 0.0]
        return mech.add(f"body:{cls.kind}", e.string("name"), modal=modal,
                        position=e.vector("position", 3), orientation=orientation,
                        euler_zxz=e.vector("euler_zxz", 3, required=False),
                        velocity=e.vector("velocity", 3, default=zeros),
                        angular_velocity=e.vector("angular_velocity", 3, default=zeros),
                        **options)


def rigidified(mechanism):
    """A shallow copy of ``mechanism`` whose flexible bodies hold their modal coordinates at
    zero (``locked_modes``: one body equation η_k = 0 per mode), or ``mechanism`` itself when
    it has none.

    Kinematics and inverse dynamics prescribe a motion with as many drivers as the rigid
    mechanism has degrees of freedom; the modes of a flexible body are free degrees of freedom
    that no driver fixes, so these analyses run on the *rigid motion* (Adams' and Simpack's
    "rigidified" flexible bodies): the coordinates keep their layout (η = 0), the node frames
    and markers their names, and the multipliers of η = 0 are the modal forces that keep each
    body undeformed along the prescribed motion.
    """
    if not any(is_flexible(b) for b in mechanism.bodies.values()):
        return mechanism
    out = copy.copy(mechanism)
    out.bodies = {name: dataclasses.replace(body, locked_modes=True) if is_flexible(body)
                  else body for name, body in mechanism.bodies.items()}
    return out


def is_flexible(body) -> bool:
    """True for a flexible body (a kind with modal data)."""
    return isinstance(body, _Flexible)


def named_nodes(mechanism) -> list[str]:
    """The attachment names ``"<body>@<node>"`` of every named node of the mechanism's flexible
    bodies, body by body in declaration order: the columns of the ``node_positions``,
    ``node_deflections`` and ``node_rotations`` of a result (:mod:`casmbd.system.requests`)."""
    return [f"{body.name}{NODE_SEPARATOR}{node}" for body in mechanism.bodies.values()
            if is_flexible(body) for node in body.nodes]
