"""Rigid bodies (planar and spatial), the ground and markers.

A moving body i carries the generalized coordinates q_i = (x_R, y_R, θ): the global position of
its reference point R and the rotation angle of its body frame (seed 000, "Generalized inertia",
eq. 6.16: r = R + A(θ) u).  By default R is the centre of mass (centroidal frame, constant diagonal
mass matrix); with ``reference_point = s`` (body-frame offset of R from the centre of mass) the
centre of mass is at R − A(θ) s and the mass matrix couples translation and rotation (eqs.
6.22–6.23), with a non-zero quadratic-velocity vector (eqs. 6.34–6.37).

Each body class is a *body kind* registered in :data:`casmbd.model.registry.BODY_KINDS` (both
rigid bodies under the scene type ``"rigid"``): it declares its scene keys, how it is built from
the Python API (:meth:`Body.create`) and from a ``[[bodies]]`` entry (:meth:`Body.from_scene`),
its drawing hint and, per coordinate choice, the key of the description that turns its pose into
generalized coordinates (:data:`casmbd.system.descriptions.DESCRIPTIONS`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from casmbd.errors import ModelError
from casmbd.model.inertia import inertia_tensor
from casmbd.model.registry import register_body
from casmbd.model.rotations import euler_zxz_to_quaternion, rotation_matrix
from casmbd.model.values import Value, check_value

GROUND = "ground"


def rotation(theta: float) -> np.ndarray:
    """Planar rotation matrix A(θ) (seed 000, eq. 6.2)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def vector(value, where: str, size: int) -> np.ndarray:
    """Validate a finite vector of ``size`` numbers."""
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"{where}: expected a vector of {size} numbers, got {value!r}") from None
    if arr.shape != (size,):
        raise ModelError(f"{where}: expected a vector of {size} numbers, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{where}: must be finite, got {value!r}")
    return arr


def unit_vector(value, where: str, size: int) -> np.ndarray:
    """The direction n / |n| of a finite non-zero vector of ``size`` numbers, scale-safely:
    divided by its largest |entry| first (|[1, 1e300]|² overflows to inf and n / inf is the
    zero vector; |[1e-200, 0]|² underflows to 0).  ModelError naming ``where`` when it is not
    finite or zero."""
    vec = vector(value, where, size)
    scale = float(np.max(np.abs(vec)))
    if scale == 0.0:
        raise ModelError(f"{where}: must not be the zero vector, got {value!r}")
    vec = vec / scale
    return vec / float(np.linalg.norm(vec))


def vector2(value, where: str) -> np.ndarray:
    """Validate a finite 2-vector."""
    return vector(value, where, 2)


def unit_quaternion(value, where: str) -> np.ndarray:
    """A quaternion [w, x, y, z] of norm 1 ± 1e-3, normalised (ModelError naming ``where``)."""
    quat = vector(value, where, 4)
    norm = float(np.linalg.norm(quat))
    if abs(norm - 1.0) > 1e-3:
        raise ModelError(f"{where}: a unit quaternion [w, x, y, z] is expected, got norm "
                         f"{norm:.6g}")
    return quat / norm


def scalar(value, where: str) -> float:
    """Validate a finite number."""
    if isinstance(value, bool):
        raise ModelError(f"{where}: expected a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"{where}: expected a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ModelError(f"{where}: must be finite, got {value!r}")
    return out


#: the keys of a rigid ``[[bodies]]`` entry (planar and spatial share them: a key of the other
#: dimension is refused by name, e.g. "planar bodies take 'angle'")
RIGID_SCENE_KEYS = frozenset({"name", "type", "mass", "inertia", "position", "angle",
                              "velocity", "angular_velocity", "reference_point", "orientation",
                              "euler_zxz", "description"})


#: plausible non-zero masses [kg]: a picogram (a MEMS proof mass is ~1e-9 kg) to 1e15 kg (a
#: mountain); beyond, the mass matrix spans more than 30 orders with any other body and the
#: integrators fail far from the cause (mass 1e300: "position constraints violated at t = 0.5").
#: Other units (g, t) still fit: the range is 30 orders wide.
MASS_RANGE = (1e-15, 1e15)
#: largest plausible moment of inertia [kg m²]: 1e15 kg at a radius of gyration of 100 km
INERTIA_MAX = 1e25
#: largest plausible distance of a body's centre of mass from the origin [m]: at 1e9 m a
#: double resolves 1e-7 m, and a body-fixed offset u = r_P − r_G of its points (joints,
#: contacts) loses every digit beyond (a ball at y = 1e300 with its contact sphere at y = 1.1:
#: u = −1e300, the sphere's centre computed at 0, "penetrates by 0.1")
POSITION_MAX = 1e9


def check_positive(body) -> None:
    """Reject a position farther than :data:`POSITION_MAX` from the origin, a numeric mass < 0
    (and, in the plane, a moment of inertia < 0; spatial
    moments are checked by :func:`check_inertia`), a non-zero mass outside
    :data:`MASS_RANGE` and a moment of inertia above :data:`INERTIA_MAX`.  Zero mass and inertia
    are accepted here: whether the mass matrix of the chosen coordinates is positive definite
    is checked at the start of forward dynamics
    (:func:`casmbd.analysis.instant.checks.check_mass_matrix`)."""
    distance = float(np.max(np.abs(np.asarray(body.position, dtype=float))))
    if distance > POSITION_MAX:
        raise ModelError(f"body '{body.name}' field 'position': a coordinate of {distance:g} m "
                         f"is beyond the plausible {POSITION_MAX:g} m from the origin (a wrong "
                         "unit or a typo; casmbd.model.bodies.POSITION_MAX)")
    values = [body.mass] + (list(body.inertia) if body.dimension == 3 else [body.inertia])
    for key, value in zip(["mass"] + ["inertia"] * (len(values) - 1), values, strict=True):
        if isinstance(value, float) and value < 0.0 and (key == "mass" or body.dimension == 2):
            raise ModelError(f"body '{body.name}' field '{key}': must be >= 0, got {value}")
        if not isinstance(value, float) or value == 0.0:
            continue
        lo, hi = MASS_RANGE if key == "mass" else (0.0, INERTIA_MAX)
        if not lo <= abs(value) <= hi:
            unit = "kg" if key == "mass" else "kg m²"
            limit = "MASS_RANGE" if key == "mass" else "INERTIA_MAX"
            raise ModelError(
                f"body '{body.name}' field '{key}': {value:g} {unit} is outside the plausible "
                f"range {'0 or ' if key == 'mass' else ''}[{lo:g}, {hi:g}] {unit} (a wrong unit "
                f"or a typo; casmbd.model.bodies.{limit})")


#: principal moments above -INERTIA_ROUNDING kg m² count as zero (rounding in published robot
#: files, e.g. -5.4e-20 in iCub's URDF), whatever the tensor's size
INERTIA_ROUNDING = 1e-15


def check_inertia(values: Sequence[float]) -> np.ndarray:
    """The inertia tensor of ``values`` ([Ixx, Iyy, Izz(, Ixy, Ixz, Iyz)]), positive
    semi-definite.

    A positive definite tensor must satisfy the triangle inequalities (seed 001, eq. 105;
    :func:`casmbd.model.inertia.inertia_tensor`).  A singular positive semi-definite tensor is
    accepted as it is: the zero tensor of a point mass or frame link, or ``[0, I, I]`` of a
    thin rod along x.  Negative principal moments (below -1e-12 of their sum, and below
    -:data:`INERTIA_ROUNDING`) are refused.

    Raises
    ------
    ModelError
        A value is not finite or the tensor has a negative principal moment.
    """
    v = np.asarray(values, dtype=float).reshape(-1)
    if v.size in (3, 6) and np.all(np.isfinite(v)):
        off = v[3:] if v.size == 6 else np.zeros(3)
        J = np.array([[v[0], off[0], off[1]], [off[0], v[1], off[2]], [off[1], off[2], v[2]]])
        eig = np.linalg.eigvalsh(J)
        # rounding in published files: iCub's r_hip_2 has a principal moment of -5.4e-20 kg m²
        tol = max(1e-12 * float(np.sum(np.abs(eig))), INERTIA_ROUNDING)
        if eig[0] < -tol:
            raise ModelError(f"inertia tensor is not positive semi-definite: smallest "
                             f"principal moment {eig[0]:.6g} (principal moments "
                             f"{eig.tolist()}, values {v.tolist()})")
        if eig[0] <= tol:  # singular PSD (zero, thin rod): no triangle inequality
            return J
    return inertia_tensor(v)


def _nonnegative(e, key: str, val) -> None:
    """Reject a scene value of ``key`` < 0 (an expression evaluated with the parameters)."""
    num = e.evaluate(val, key)
    if num < 0.0:
        raise e.error(key, f"must be >= 0, got {num:g}" + (f" ({val!r})"
                                                          if isinstance(val, str) else ""))


@register_body
@dataclass
class Body:
    """A planar rigid body.

    Parameters
    ----------
    name : str
        Unique name.
    mass : Value
        Mass m >= 0 (number, or expression of parameters).
    inertia : Value
        Moment of inertia about the centre of mass, >= 0.
    position : array_like
        Global position of the centre of mass (initial guess for assembly).
    angle : float
        Rotation angle of the body frame (initial guess).
    velocity, angular_velocity :
        Initial velocity of the centre of mass and angular velocity.
    reference_point : array_like
        Body-frame offset s of the reference point R from the centre of mass.
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    mass: Value
    inertia: Value
    position: np.ndarray
    angle: float = 0.0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    angular_velocity: float = 0.0
    reference_point: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self):
        where = f"body '{self.name}'"
        self.mass = check_value(self.mass, f"{where} field 'mass'")
        self.inertia = check_value(self.inertia, f"{where} field 'inertia'")
        self.position = vector2(self.position, f"{where} field 'position'")
        self.angle = scalar(self.angle, f"{where} field 'angle'")
        self.velocity = vector2(self.velocity, f"{where} field 'velocity'")
        self.angular_velocity = scalar(self.angular_velocity, f"{where} field 'angular_velocity'")
        self.reference_point = vector2(self.reference_point, f"{where} field 'reference_point'")

    dimension = 2
    #: scene type name (``[[bodies]] type``) and the mechanism dimensions the class serves
    kind: ClassVar[str] = "rigid"
    dimensions: ClassVar[tuple[int, ...]] = (2,)
    #: the keys of its ``[[bodies]]`` entries
    scene_keys: ClassVar[frozenset[str]] = RIGID_SCENE_KEYS
    #: drawing hint for :mod:`casmbd.viz.geometry`: "polyline" (a line through the body's
    #: attachment points, its centre of mass alone when it has none)
    drawing: ClassVar[str] = "polyline"
    #: coordinate choice → key of its description in :data:`casmbd.system.descriptions.
    #: DESCRIPTIONS` ("joint": the body as a floating root; a tree joint describes the others)
    descriptions: ClassVar[dict[str, str]] = {"absolute": "planar_absolute",
                                              "natural": "planar_natural",
                                              "joint": "planar_floating"}

    @classmethod
    def create(cls, mech, name: str, mass: Value, inertia, position: Sequence[float],
               angle: float = 0.0, velocity: Sequence[float] | None = None,
               angular_velocity=None, reference_point: Sequence[float] | None = None,
               orientation: Sequence[float] | None = None,
               euler_zxz: Sequence[float] | None = None) -> Body:
        """Validate the arguments of ``mech.add_body`` (``mech.add("body:rigid", ...)``) and
        build the body; the mechanism stores it."""
        mech._unique(mech.bodies, "body", name)
        for key, value in (("orientation", orientation), ("euler_zxz", euler_zxz)):
            if value is not None:
                raise ModelError(f"body '{name}' field '{key}': planar bodies have an "
                                 "'angle'")
        zeros = (0.0, 0.0)
        body = cls(name, mass, inertia, position, angle,
                   zeros if velocity is None else velocity,
                   0.0 if angular_velocity is None else angular_velocity,
                   zeros if reference_point is None else reference_point)
        check_positive(body)
        return body

    @classmethod
    def from_scene(cls, mech, e) -> Body:
        """Add the body of one ``[[bodies]]`` entry to ``mech`` and return it.

        ``e`` is the scene loader's reader of the entry (``string``, ``value``, ``vector``,
        ``number``, ``has``, ``error``, ``positive``); the parsing stays in
        :mod:`casmbd.io.scene`, which keys build which arguments lives here.
        """
        for key in ("orientation", "euler_zxz"):
            if e.has(key):
                raise e.error(key, "planar bodies take 'angle' (spatial scenes: dimension = 3)")
        for key in ("mass", "inertia"):
            _nonnegative(e, key, e.value(key))
        return mech.add(
            f"body:{cls.kind}", e.string("name"), mass=e.value("mass"),
            inertia=e.value("inertia"), position=e.vector("position"),
            angle=e.number("angle", 0.0), velocity=e.vector("velocity", default=[0.0, 0.0]),
            angular_velocity=e.number("angular_velocity", 0.0),
            reference_point=e.vector("reference_point", default=[0.0, 0.0]))

    @property
    def is_centroidal(self) -> bool:
        """True when the reference point is the centre of mass."""
        return not np.any(self.reference_point)

    @property
    def initial_rotation(self) -> np.ndarray:
        """A(θ) at the initial pose."""
        return rotation(self.angle)

    def local(self, point_global) -> np.ndarray:
        """Body-frame coordinates (about G) of a global point at the initial pose."""
        return rotation(self.angle).T @ (np.asarray(point_global, float) - self.position)


@dataclass
class Marker:
    """A named point fixed on a body, given by its global location at the initial pose, with
    an optional frame: ``orientation`` is its global orientation at the design pose (a unit
    quaternion [w, x, y, z] in space, an angle in the plane); None means the body's own.

    The marker's rotation is A_marker(q) = A_body(q) Aᵦᵀ A_m (space; Aᵦ, A_m the body's and the
    marker's rotations at the design pose), θ_marker = θ_body + θ_m − θᵦ in the plane.
    """

    name: str
    body: str
    point: np.ndarray
    dimension: int = 2
    orientation: np.ndarray | float | None = None

    def __post_init__(self):
        where = f"marker '{self.name}' field 'orientation'"
        self.point = vector(self.point, f"marker '{self.name}' field 'point'", self.dimension)
        if self.orientation is None:
            return
        if self.dimension == 2:
            self.orientation = scalar(self.orientation, where)
            return
        quat = vector(self.orientation, where, 4)
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > 1e-3:
            raise ModelError(f"{where}: a unit quaternion [w, x, y, z] is expected, got norm "
                             f"{norm:.6g}")
        self.orientation = quat / norm

    def offset(self, body) -> np.ndarray | float:
        """The marker's fixed rotation relative to ``body`` (its Body, None for the ground):
        Aᵦᵀ A_m (3x3) in space, θ_m − θᵦ in the plane; identity / 0 without an orientation."""
        if self.dimension == 2:
            if self.orientation is None:
                return 0.0
            return float(self.orientation) - float(getattr(body, "angle", 0.0))
        if self.orientation is None:
            return np.eye(3)
        own = rotation_matrix(self.orientation)
        base = getattr(body, "initial_rotation", None)
        return own if base is None else np.asarray(base, float).T @ own


@register_body
@dataclass
class SpatialBody:
    """A spatial rigid body.

    Its pose is the global position of the centre of mass and the unit quaternion (Euler
    parameters) ``orientation = [e0, e1, e2, e3]`` of the body frame: a body point with
    body-frame coordinates u (about G) is at r = r_G + A(p) u (seed 001, eq. 1).  How the pose is
    turned into generalized coordinates (Euler parameters, natural coordinates, joint
    coordinates) is the system's choice, not the body's.

    Parameters
    ----------
    name : str
        Unique name.
    mass : Value
        Mass m > 0.
    inertia : sequence of Value
        [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], the inertia tensor about the centre of
        mass in body axes (seed 001, eq. 102; products are the tensor elements).
    position : array_like, 3
        Global position of the centre of mass (initial guess for assembly).
    orientation : array_like, 4
        Unit quaternion [w, x, y, z] of the initial pose (normalised here; a norm far from 1 is
        an error).
    velocity, angular_velocity : array_like, 3
        Initial velocity of the centre of mass and angular velocity, global components.
    reference_point : array_like, 3
        Body-frame offset s of the coordinates' reference point R from the centre of mass.
    start_position, start_orientation : array_like (3 and 4), optional
        Where the body *starts* when that differs from the pose above, which stays the design
        pose (the pose the joints, markers and joint coordinates are defined in): centre of
        mass and unit quaternion, both or neither (:meth:`set_start`).  Absolute and natural
        coordinates (and a floating root of joint coordinates) start there; a URDF robot given
        non-zero initial joint positions is built this way (:mod:`casmbd.io.urdf`).  The
        velocities are those at the start pose.
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    mass: Value
    inertia: tuple
    position: np.ndarray
    orientation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    reference_point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    start_position: np.ndarray | None = None
    start_orientation: np.ndarray | None = None

    dimension = 3
    kind: ClassVar[str] = "rigid"
    dimensions: ClassVar[tuple[int, ...]] = (3,)
    scene_keys: ClassVar[frozenset[str]] = RIGID_SCENE_KEYS
    drawing: ClassVar[str] = "polyline"
    descriptions: ClassVar[dict[str, str]] = {"absolute": "spatial_absolute",
                                              "natural": "spatial_natural",
                                              "joint": "spatial_floating"}

    @classmethod
    def create(cls, mech, name: str, mass: Value, inertia, position: Sequence[float],
               angle: float = 0.0, velocity: Sequence[float] | None = None,
               angular_velocity=None, reference_point: Sequence[float] | None = None,
               orientation: Sequence[float] | None = None,
               euler_zxz: Sequence[float] | None = None) -> SpatialBody:
        """Validate the arguments of ``mech.add_body`` in space and build the body: the
        orientation is a unit quaternion ``orientation`` or Z-X-Z Euler angles ``euler_zxz``."""
        mech._unique(mech.bodies, "body", name)
        if angle:
            raise ModelError(f"body '{name}' field 'angle': spatial bodies take "
                             "'orientation' (quaternion) or 'euler_zxz'")
        if orientation is not None and euler_zxz is not None:
            raise ModelError(f"body '{name}': give 'orientation' or 'euler_zxz', not both")
        if euler_zxz is not None:
            angles = vector(euler_zxz, f"body '{name}' field 'euler_zxz'", 3)
            orientation = euler_zxz_to_quaternion(*angles)
        zeros = (0.0, 0.0, 0.0)
        body = cls(name, mass, inertia, position,
                   (1.0, 0.0, 0.0, 0.0) if orientation is None else orientation,
                   zeros if velocity is None else velocity,
                   zeros if angular_velocity is None else angular_velocity,
                   zeros if reference_point is None else reference_point)
        check_positive(body)
        return body

    @classmethod
    def from_scene(cls, mech, e) -> SpatialBody:
        """Add the body of one ``[[bodies]]`` entry of a spatial scene: inertia [Ixx, Iyy,
        Izz(, Ixy, Ixz, Iyz)] about the centre of mass in body axes, orientation a unit
        quaternion [w, x, y, z] or Z-X-Z Euler angles (see :meth:`Body.from_scene`)."""
        if e.has("angle"):
            raise e.error("angle", "spatial bodies take 'orientation' (unit quaternion [w, x, "
                          "y, z]) or 'euler_zxz' ([phi, theta, psi])")
        if e.has("orientation") and e.has("euler_zxz"):
            raise e.error("orientation", "give 'orientation' or 'euler_zxz', not both")
        mass = e.value("mass")
        _nonnegative(e, "mass", mass)
        inertia = e.values("inertia", (3, 6), what="moments (and products) of inertia")
        for val in inertia[:3]:
            _nonnegative(e, "inertia", val)
        try:
            check_inertia([e.evaluate(v, "inertia") for v in inertia])
        except ModelError as exc:
            raise e.error("inertia", str(exc)) from None
        orientation = e.vector("orientation", 4, required=False)
        if orientation is not None:
            norm = math.sqrt(sum(x * x for x in orientation))
            if abs(norm - 1.0) > 1e-3:
                raise e.error("orientation", f"expected a unit quaternion [w, x, y, z], got "
                              f"norm {norm:.6g}")
        zeros = [0.0, 0.0, 0.0]
        name = e.string("name")
        return mech.add(
            f"body:{cls.kind}", name, mass=mass, inertia=inertia,
            position=e.vector("position", 3), orientation=orientation,
            euler_zxz=e.vector("euler_zxz", 3, required=False),
            velocity=e.vector("velocity", 3, default=zeros),
            angular_velocity=e.vector("angular_velocity", 3, default=zeros),
            reference_point=e.vector("reference_point", 3, default=zeros))

    def __post_init__(self):
        where = f"body '{self.name}' field"
        self.mass = check_value(self.mass, f"{where} 'mass'")
        inertia = self.inertia
        if isinstance(inertia, (int, float)) or not hasattr(inertia, "__len__") \
                or len(inertia) not in (3, 6):
            raise ModelError(f"{where} 'inertia': expected [Ixx, Iyy, Izz] or "
                             f"[Ixx, Iyy, Izz, Ixy, Ixz, Iyz], got {inertia!r}")
        self.inertia = tuple(check_value(v, f"{where} 'inertia'") for v in inertia)
        self.position = vector(self.position, f"{where} 'position'", 3)
        self.orientation = unit_quaternion(self.orientation, f"{where} 'orientation'")
        self.velocity = vector(self.velocity, f"{where} 'velocity'", 3)
        self.angular_velocity = vector(self.angular_velocity, f"{where} 'angular_velocity'", 3)
        self.reference_point = vector(self.reference_point, f"{where} 'reference_point'", 3)
        if self.start_position is not None or self.start_orientation is not None:
            self.set_start(self.start_position, self.start_orientation)

    def set_start(self, position, orientation) -> None:
        """Start the body at centre of mass ``position`` and unit quaternion ``orientation``
        instead of its design pose (both None: at the design pose)."""
        where = f"body '{self.name}' field"
        if position is None and orientation is None:
            self.start_position = self.start_orientation = None
            return
        if position is None or orientation is None:
            raise ModelError(f"{where} 'start_position': give the start position and "
                             "orientation together")
        self.start_position = vector(position, f"{where} 'start_position'", 3)
        self.start_orientation = unit_quaternion(orientation, f"{where} 'start_orientation'")

    @property
    def is_centroidal(self) -> bool:
        """True when the reference point is the centre of mass."""
        return not np.any(self.reference_point)

    @property
    def initial_rotation(self) -> np.ndarray:
        """A(p) at the initial (design) pose."""
        return rotation_matrix(self.orientation)

    def start_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """(r_G, p): centre of mass and unit quaternion where the body starts (the design
        pose unless :meth:`set_start` moved the start)."""
        if self.start_position is None:
            return self.position, self.orientation
        return self.start_position, self.start_orientation

    def local(self, point_global) -> np.ndarray:
        """Body-frame coordinates (about G) of a global point at the initial pose."""
        return self.initial_rotation.T @ (np.asarray(point_global, float) - self.position)
