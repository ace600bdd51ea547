"""The mechanism builder: the user's symbolic description of bodies, joints, forces, drivers.

``Mechanism`` only *describes* a mechanism (like Pinocchio's ``Model`` before ``Data``): it holds
names, numbers and expressions and validates them.  :class:`casmbd.system.System` turns it into
CasADi equations, :mod:`casmbd.compiled` into compiled functions, and the analyses use those.

Example
-------
>>> m = Mechanism("pendulum", gravity=(0.0, -9.81))
>>> _ = m.add_body("rod", mass=1.0, inertia=1 / 12, position=(0.5, 0.0))
>>> _ = m.add_revolute("pivot", "ground", "rod", point=(0.0, 0.0))
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from casmbd.errors import ModelError
from casmbd.limits import MAX_BODIES, MAX_ELEMENTS, check_count
from casmbd.model.bodies import GROUND, Body, Marker, SpatialBody, check_inertia, scalar, vector
from casmbd.model.contact_models import CONTACT_MODELS, acts_at_events, models_where
from casmbd.model.contacts import (
    JointLimit,
    Unilateral,
    contact_shape,
    slide_direction_parameters,
    slide_parameters,
    slides,
)
from casmbd.model.drivers import (
    BODY_COORDINATES,
    ORIENTATION,
    ORIENTATION_FORMS,
    Driver,
    OrientationDriver,
    orientation_rows,
)
from casmbd.model.flexible_bodies import NodeFrame, is_flexible, node_attachment
from casmbd.model.forces import (
    Actuator,
    ForceElement,
    PointForce,
    RotationalSpringDamper,
    SpringDamper,
    Torque,
    UserForce,
)
from casmbd.model.joints import Joint
from casmbd.model.measures import Output, add_output
from casmbd.model.registry import BODY_KINDS, FORCE_KINDS, JOINT_KINDS, body_kind, joint_kind
from casmbd.model.rotations import euler_zxz_to_quaternion
from casmbd.model.values import Value, check_value, numeric

#: characters that never appear in a declared name, and what they mean in the scene syntax
#: largest plausible gravity component [m/s²] (10⁷ g: an ultracentrifuge reaches 10⁶ g); a
#: component of 1e300 made the kinetic energy inf at t = 0.1 without naming the gravity
GRAVITY_MAX = 1e8

RESERVED_CHARACTERS = {
    "@": "it attaches to a node of a flexible body, '<body>@<node>'",
    ".": "it separates an element from a generated part, as in '<joint>.limit', "
         "'<contact>.force', '<body>.eta1'",
}
#: names an expression already gives a meaning (time and the constants)
RESERVED_PARAMETERS = {"t": "the time", "time": "the time", "pi": "the constant π",
                       "e": "the constant e"}


class Mechanism:
    """A planar or spatial mechanism: bodies, joints, drivers, forces, actuators.

    Parameters
    ----------
    name : str
        Name of the mechanism (used for compiled-code file names).
    gravity : sequence of 2 or 3 floats
        Gravitational acceleration vector, default zero.
    dimension : {2, 3}, optional
        Planar or spatial; by default the length of ``gravity`` (2 when it is not given).
    coordinates : {"auto", "absolute", "natural", "joint"}
        Default choice of generalized coordinates of the systems built from it
        (:mod:`casmbd.system.descriptions`); a description property, not a model one.
        ``"auto"`` (default): joint coordinates for trees and few loops, else absolute
        (:mod:`casmbd.system.choice`).
    """

    def __init__(self, name: str = "mechanism", gravity: Sequence[float] | None = None,
                 dimension: int | None = None, coordinates: str = "auto"):
        self.name = str(name)
        if dimension is None:
            dimension = 2 if gravity is None else len(gravity)
        if dimension not in (2, 3):
            raise ModelError(f"mechanism field 'dimension': expected 2 or 3, got {dimension!r}")
        self.dimension = int(dimension)
        if coordinates not in ("auto", "absolute", "natural", "joint"):
            raise ModelError(f"mechanism field 'coordinates': expected 'auto', 'absolute', "
                             f"'natural' or 'joint', got {coordinates!r}")
        self.coordinates = coordinates
        #: joints that must belong to the spanning tree of joint coordinates (optional)
        self.tree: list[str] = []
        #: in joint coordinates, substitute the follower of a gear between two single-
        #: coordinate tree joints (q_f = r q_l + δ, casmbd.system.tree); False keeps every
        #: gear a constraint equation
        self.substitute_gears: bool = True
        gravity = np.zeros(self.dimension) if gravity is None else gravity
        self.gravity = vector(gravity, "mechanism field 'gravity'", self.dimension)
        if float(np.max(np.abs(self.gravity), initial=0.0)) > GRAVITY_MAX:
            raise ModelError(f"mechanism field 'gravity': {self.gravity.tolist()} has a component "
                             f"beyond the plausible {GRAVITY_MAX:g} m/s² (10⁷ g, an "
                             "ultracentrifuge; a wrong unit or a typo; "
                             "casmbd.model.mechanism.GRAVITY_MAX)")
        self.parameters: dict[str, float] = {}
        self.bodies: dict[str, Body] = {}
        self.markers: dict[str, Marker] = {}
        #: unilateral elements (contacts, joint limits) by name, :mod:`casmbd.model.contacts`
        self.contacts: dict[str, Unilateral] = {}
        #: node frames of flexible bodies by attachment name ``"<body>@<node>"``
        self.nodes: dict[str, NodeFrame] = {}
        self.joints: dict[str, Joint] = {}
        self.drivers: dict[str, Driver] = {}
        self.forces: dict[str, object] = {}
        self.actuators: dict[str, Actuator] = {}
        #: requests: named expressions of measures reported on result grids (``[[outputs]]``)
        self.outputs: dict[str, Output] = {}
        #: what the bodies look like in the 3-D view (body name or "ground" -> tuple of
        #: :class:`casmbd.model.visuals.Visual`, body frame; URDF ``<visual>``); no analysis
        #: reads it and the model key of a build skips it
        self.visuals: dict[str, tuple] = {}
        #: names the mechanism makes itself ("<joint>.limit", "<contact>.force",
        #: "<joint>.friction"), the only ones that may hold a reserved character (a dict, in
        #: order: the model key canonicalises the mechanism and takes no sets)
        self._generated: dict[str, None] = {}

    # ------------------------------------------------------------------ helpers
    def _generate(self, name: str) -> str:
        """Mark ``name`` as made by casmbd itself (``"<joint>.limit"``, ``"<contact>.force"``,
        ``"<joint>.friction"``): the reserved characters of :data:`RESERVED_CHARACTERS` are
        allowed in it, never in a name the user declares."""
        self._generated[name] = None
        return name

    def _conventional(self, kind: str, name: str) -> bool:
        """Whether ``name`` is the name casmbd itself gives such an element: a joint's
        friction ``"<joint>.friction"`` (a force), its stops ``"<joint>.limit"`` (a contact)
        or the compliant force ``"<contact>.force"`` of a contact, for an existing joint or
        contact (code may name them so, as the scene reader does)."""
        owner, _, part = name.rpartition(".")
        if "@" in name or not owner:
            return False
        if (kind == "force" and part == "friction") or (kind == "contact" and part == "limit"):
            return owner in self.joints
        return kind == "force" and part == "force" and owner in self.contacts

    def _unique(self, table: dict, kind: str, name: str) -> str:
        if not isinstance(name, str) or not name:
            raise ModelError(f"{kind} name must be a non-empty string, got {name!r}")
        if kind == "body" and name == GROUND:
            raise ModelError(f"body name '{GROUND}' is reserved for the ground")
        if name not in self._generated and not self._conventional(kind, name):
            for char, meaning in RESERVED_CHARACTERS.items():
                if char in name:
                    raise ModelError(f"{kind} name '{name}': must not contain '{char}' "
                                     f"({meaning})")
        if kind == "body" and name in self.markers:
            raise ModelError(f"body name '{name}': a marker has this name (measures such as "
                             f"y(\"{name}\") would be ambiguous)")
        if name in table:
            raise ModelError(f"duplicate {kind} name '{name}'")
        check_count(f"mechanism '{self.name}': {kind} '{name}' would be number {len(table) + 1}",
                    len(table) + 1, MAX_BODIES if kind == "body" else MAX_ELEMENTS)
        return name

    def _body(self, name: str, where: str) -> str:
        if not isinstance(name, str):
            raise ModelError(f"{where}: expected a body name (string), got {name!r}")
        if node_attachment(name) is not None:
            self.node_frame(name, where)
            return name
        if name != GROUND and name not in self.bodies:
            known = ", ".join([GROUND, *self.bodies]) or GROUND
            raise ModelError(f"{where}: unknown body '{name}' (known: {known})")
        return name

    def node_frame(self, name: str, where: str = "") -> NodeFrame:
        """The frame of the node attachment ``"<body>@<node>"`` (a named node of a flexible
        body, :mod:`casmbd.model.flexible_bodies`), made once.

        Raises
        ------
        ModelError
            Not an attachment name, an unknown body, a rigid body, or no such node.
        """
        if name in self.nodes:
            return self.nodes[name]
        where = where or f"attachment '{name}'"
        parts = node_attachment(name)
        if parts is None:
            raise ModelError(f"{where}: '{name}' is not a node attachment ('<body>@<node>')")
        body, node = parts
        if body not in self.bodies:
            known = ", ".join(self.bodies) or "none"
            raise ModelError(f"{where}: unknown body '{body}' of node '{node}' (known: {known})")
        if not is_flexible(self.bodies[body]):
            raise ModelError(f"{where}: body '{body}' is rigid; nodes ('node', 'node1', "
                             "'node2') belong to flexible bodies")
        try:
            frame = self.bodies[body].node_frame(node)
        except ModelError as exc:
            raise ModelError(f"{where}: {exc}") from None
        self.nodes[name] = frame
        return frame

    def attachment(self, name: str):
        """The model object of an attachment name: a body, the :class:`NodeFrame` of
        ``"<body>@<node>"``, or None for the ground (its initial pose: ``initial_rotation``,
        ``angle``, ``position``)."""
        if node_attachment(name) is not None:
            return self.node_frame(name)
        return self.bodies.get(name)

    def owner(self, name: str) -> str:
        """The body an attachment name belongs to (itself for a body or the ground)."""
        parts = node_attachment(name)
        return name if parts is None else parts[0]

    def _joint(self, name: str, where: str, coordinate: bool = True) -> Joint:
        if not isinstance(name, str):
            raise ModelError(f"{where}: expected a joint name (string), got {name!r}")
        if name not in self.joints:
            known = ", ".join(self.joints) or "none"
            raise ModelError(f"{where}: unknown joint '{name}' (known: {known})")
        joint = self.joints[name]
        if coordinate and not joint.has_coordinate:
            raise ModelError(f"{where}: joint '{name}' ({type(joint).__name__.lower()}) has no "
                             "joint coordinate")
        return joint

    def _vec(self, value, where: str) -> np.ndarray:
        return vector(value, where, self.dimension)

    def _pair(self, body1: str, body2: str, where: str) -> None:
        self._body(body1, f"{where} field 'body1'")
        self._body(body2, f"{where} field 'body2'")
        if body1 == body2:
            raise ModelError(f"{where}: body1 and body2 are the same body '{body1}'")

    @staticmethod
    def _nonnegative(name: str, **values) -> None:
        for key, value in values.items():
            value = check_value(value, f"force '{name}' field '{key}'")
            if isinstance(value, float) and value < 0.0:
                raise ModelError(f"force '{name}' field '{key}': must be >= 0, got {value}")

    # ------------------------------------------------------------------ parameters
    def add_parameter(self, name: str, value: float) -> str:
        """Declare a named symbolic parameter p with a default value."""
        self._unique(self.parameters, "parameter", name)
        if name in RESERVED_PARAMETERS:
            raise ModelError(f"parameter '{name}': the name is reserved "
                             f"({RESERVED_PARAMETERS[name]} in expressions)")
        if not name.isidentifier() or name.startswith("_"):
            raise ModelError(f"parameter '{name}': not a valid parameter name")
        try:
            val = float(value)
        except (TypeError, ValueError, OverflowError):
            raise ModelError(f"parameter '{name}': expected a number, got {value!r}") from None
        if isinstance(value, bool) or not math.isfinite(val):
            raise ModelError(f"parameter '{name}': must be a finite number, got {value!r}")
        self.parameters[name] = val
        return name

    # ------------------------------------------------------------------ bodies
    def add_body(self, name: str, mass: Value, inertia, position: Sequence[float],
                 angle: float = 0.0, velocity: Sequence[float] | None = None,
                 angular_velocity=None, reference_point: Sequence[float] | None = None,
                 orientation: Sequence[float] | None = None,
                 euler_zxz: Sequence[float] | None = None) -> Body | SpatialBody:
        """Add a rigid body with its centre of mass at ``position`` (the body kind ``"rigid"``:
        ``add("body:rigid", ...)``).

        In the plane: ``inertia`` is the moment of inertia about the centre of mass, ``angle``
        the orientation (:class:`~casmbd.model.bodies.Body`).  In space: ``inertia`` is
        [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about the centre of mass in body axes,
        the orientation a unit quaternion ``orientation`` [w, x, y, z] or Euler angles
        ``euler_zxz`` [φ, θ, ψ] (rad), velocities in global components
        (:class:`~casmbd.model.bodies.SpatialBody`).
        """
        return self.add("body:rigid", name, mass, inertia, position, angle=angle,
                        velocity=velocity, angular_velocity=angular_velocity,
                        reference_point=reference_point, orientation=orientation,
                        euler_zxz=euler_zxz)

    def add_marker(self, name: str, body: str, point: Sequence[float] | None = None,
                   orientation: Sequence[float] | None = None,
                   euler_zxz: Sequence[float] | None = None,
                   angle: float | None = None, node: str | None = None) -> Marker:
        """Add a named point on ``body`` at the global location ``point`` (initial pose), with
        an optional frame: its global orientation at the design pose as a unit quaternion
        ``orientation`` or Z-X-Z Euler angles ``euler_zxz`` (space), or ``angle`` (plane);
        default the body's orientation (see :class:`~casmbd.model.bodies.Marker`).

        ``node`` attaches the marker to a named node of the flexible body ``body`` (the same
        as ``body = "<body>@<node>"``): it moves and turns with the deformed node frame,
        r_P = R + A (u_i0 + Φ_i η) + A_i(η) A_i0ᵀ (P − r_i0) with A_i the node frame's rotation
        (seed 002, eq. 5–26); ``point`` defaults to the node's undeformed position.
        """
        if node is not None:
            if not isinstance(node, str) or not node.strip() or "@" in node:
                raise ModelError(f"marker '{name}' field 'node': expected a node name, got "
                                 f"{node!r}")
            if not isinstance(body, str) or node_attachment(body) is not None:
                raise ModelError(f"marker '{name}' field 'body': expected a flexible body's "
                                 f"name with 'node', got {body!r}")
            body = f"{body}@{node}"
        self._unique(self.markers, "marker", name)
        if name == GROUND or name in self.bodies:
            raise ModelError(f"marker name '{name}': "
                             + ("the ground" if name == GROUND else "a body") + " has this "
                             f"name (measures such as "
                             f"y(\"{name}\") would be ambiguous)")
        self._body(body, f"marker '{name}' field 'body'")
        if point is None:
            if node_attachment(body) is None:
                raise ModelError(f"marker '{name}' field 'point': missing (give the marker's "
                                 "global point, or 'node' of a flexible body)")
            point = self.node_frame(body).position
        given = [k for k, v in (("orientation", orientation), ("euler_zxz", euler_zxz),
                                ("angle", angle)) if v is not None]
        if len(given) > 1:
            raise ModelError(f"marker '{name}': give one of {given}, not several")
        if given and (given[0] == "angle") != (self.dimension == 2):
            raise ModelError(f"marker '{name}' field '{given[0]}': "
                             + ("planar markers take 'angle'" if self.dimension == 2 else
                                "spatial markers take 'orientation' or 'euler_zxz'"))
        if euler_zxz is not None:
            orientation = euler_zxz_to_quaternion(
                *vector(euler_zxz, f"marker '{name}' field 'euler_zxz'", 3))
        marker = Marker(name, body, point, self.dimension,
                        angle if self.dimension == 2 else orientation)
        self.markers[name] = marker
        return marker

    # ------------------------------------------------------------------ joints
    def _add_joint(self, joint: Joint) -> Joint:
        self.joints[joint.name] = joint
        return joint

    def _new_joint(self, name: str, body1: str, body2: str) -> None:
        self._unique(self.joints, "joint", name)
        self._pair(body1, body2, f"joint '{name}'")

    def add(self, kind: str, name: str, *args, **fields) -> Joint | ForceElement | object:
        """Add an element of a registered kind: ``m.add("revolute", "pin", "ground", "rod",
        point=(0, 0))``, ``m.add("gear", "g", joint1="a", joint2="b", ratio=2.0)``,
        ``m.add("spring_damper", "s", "ground", "rod", p1, p2, stiffness=100.0)``.

        The kind (:data:`~casmbd.model.registry.JOINT_KINDS`,
        :data:`~casmbd.model.registry.FORCE_KINDS`) validates its own arguments
        (``create``); user kinds registered with
        :func:`~casmbd.model.registry.register_joint` or
        :func:`~casmbd.model.registry.register_force` are added the same way.  The
        ``add_revolute``, ``add_spring_damper``, … methods are thin wrappers of this one.
        Body kinds (:data:`~casmbd.model.registry.BODY_KINDS`,
        :func:`~casmbd.model.registry.register_body`) are added as ``"body:<type>"``
        (``m.add("body:rigid", "rod", mass=1.0, inertia=0.1, position=(0.5, 0))``, what
        :meth:`add_body` does), or by their bare type name when no joint or force element kind
        has it (``"rigid"`` is also a joint kind).

        Raises
        ------
        ModelError
            An unknown kind (listing the registered ones), a kind not available in this
            dimension, or an invalid argument (naming the element and the field).
        """
        if isinstance(kind, str) and (kind.startswith("body:") or (
                kind in BODY_KINDS and kind not in JOINT_KINDS and kind not in FORCE_KINDS)):
            cls = body_kind(kind.removeprefix("body:"), self.dimension, f"body '{name}'")
            body = cls.create(self, name, *args, **fields)
            self.bodies[body.name] = body
            if is_flexible(body):  # each named node reports its pose as a marker
                for node in body.nodes:
                    frame = self.node_frame(f"{body.name}@{node}", f"body '{body.name}'")
                    if frame.name not in self.markers:
                        self.add_marker(self._generate(frame.name), frame.name,
                                        frame.position)
            return body
        if not isinstance(kind, str) or (kind not in JOINT_KINDS and kind not in FORCE_KINDS):
            raise ModelError(f"element '{name}': unknown kind {kind!r} (joints: "
                             f"{', '.join(JOINT_KINDS)}; force elements: "
                             f"{', '.join(FORCE_KINDS)}; bodies: "
                             f"{', '.join('body:' + k for k in BODY_KINDS)})")
        if kind in FORCE_KINDS:
            force = FORCE_KINDS[kind].create(self, name, *args, **fields)
            self.forces[force.name] = force
            return force
        cls = joint_kind(kind, self.dimension, f"joint '{name}'")
        return self._add_joint(cls.create(self, name, *args, **fields))

    def add_revolute(self, name: str, body1: str, body2: str, point: Sequence[float],
                     axis: Sequence[float] | None = None) -> Joint:
        """Revolute (pin) joint at the global ``point``; in space about the global ``axis``.

        Coordinate: θ2 − θ1 in the plane; the rotation about the axis since the initial pose
        in space.
        """
        return self.add("revolute", name, body1, body2, point, axis=axis)

    def add_prismatic(self, name: str, body1: str, body2: str, point: Sequence[float],
                      axis: Sequence[float]) -> Joint:
        """Prismatic (translational) joint along the global ``axis`` through ``point``."""
        return self.add("prismatic", name, body1, body2, point, axis)

    def add_cylindrical(self, name: str, body1: str, body2: str, point: Sequence[float],
                        axis: Sequence[float]) -> Joint:
        """Cylindrical joint (slide along and turn about ``axis``); coordinates
        ``translation`` and ``angle``.  Spatial only."""
        return self.add("cylindrical", name, body1, body2, point, axis)

    def add_spherical(self, name: str, body1: str, body2: str, point: Sequence[float]) -> Joint:
        """Spherical (ball) joint at ``point``.  Spatial only."""
        return self.add("spherical", name, body1, body2, point)

    def add_universal(self, name: str, body1: str, body2: str, point: Sequence[float],
                      axis1: Sequence[float], axis2: Sequence[float]) -> Joint:
        """Universal joint at ``point``: ``axis1`` on body1 ⟂ ``axis2`` on body2.  Spatial
        only."""
        return self.add("universal", name, body1, body2, point, axis1, axis2)

    def add_inline(self, name: str, body1: str, body2: str, point: Sequence[float],
                   axis: Sequence[float]) -> Joint:
        """In-line joint: the point of body2 at the global ``point`` stays on the line of body1
        through ``point`` along the global ``axis`` (2 equations).  Spatial only."""
        return self.add("inline", name, body1, body2, point, axis)

    def add_rigid(self, name: str, body1: str, body2: str,
                  point: Sequence[float] | None = None) -> Joint:
        """Weld body2 to body1 in their initial relative pose."""
        return self.add("rigid", name, body1, body2, point=point)

    def add_fixed(self, name: str, body: str, point: Sequence[float] | None = None) -> Joint:
        """Fix ``body`` to the ground in its initial pose."""
        return self.add("fixed", name, body, point=point)

    def add_distance(self, name: str, body1: str, body2: str, point1: Sequence[float],
                     point2: Sequence[float], length: float | None = None) -> Joint:
        """Massless link between two points; ``length`` defaults to the initial distance."""
        return self.add("distance", name, body1, body2, point1, point2, length=length)

    def add_gear(self, name: str, joint1: str, joint2: str, ratio: float = 1.0,
                 coordinate1: str | None = None, coordinate2: str | None = None,
                 offset: float = 0.0) -> Joint:
        """Gear (coupler) between two joint coordinates: c2 − c2⁰ = ratio (c1 − c1⁰) + offset
        (:class:`~casmbd.model.gear.Gear`)."""
        return self.add("gear", name, joint1=joint1, joint2=joint2, ratio=ratio,
                        coordinate1=coordinate1, coordinate2=coordinate2, offset=offset)

    # ------------------------------------------------------------------ drivers
    def add_rolling_disc(self, name: str, body1: str, body2: str, point: Sequence[float],
                         radius: float, axis: Sequence[float] | None = None,
                         origin: Sequence[float] | None = None,
                         normal: Sequence[float] | None = None) -> Joint:
        """A wheel of ``body2`` (centre ``point``, ``radius``, axle ``axis``) rolling without
        slipping on the plane of ``body1`` through ``origin`` with ``normal``
        (:mod:`casmbd.model.rolling_disc`)."""
        keys = {k: v for k, v in (("axis", axis), ("origin", origin), ("normal", normal))
                if v is not None}
        return self.add("rolling_disc", name, body1, body2, point=point, radius=radius, **keys)

    def add_knife_edge(self, name: str, body1: str, body2: str, point: Sequence[float],
                       axis: Sequence[float], normal: Sequence[float] | None = None) -> Joint:
        """A knife edge (Chaplygin's sleigh): ``body2``'s ``point`` has no velocity across the
        blade ``axis``, relative to ``body1``; in space ``normal`` is the plane's
        (:mod:`casmbd.model.rolling`)."""
        return self.add("knife_edge", name, body1, body2, point=point, axis=axis,
                        normal=normal)

    def add_rolling_sphere(self, name: str, body1: str, body2: str, point: Sequence[float],
                           radius: float, origin: Sequence[float] = (0.0, 0.0, 0.0),
                           normal: Sequence[float] = (0.0, 0.0, 1.0)) -> Joint:
        """A sphere of ``body2`` (centre ``point``) rolling without slipping on the plane of
        ``body1`` through ``origin`` with ``normal`` (:mod:`casmbd.model.rolling`)."""
        return self.add("rolling_sphere", name, body1, body2, point=point, radius=radius,
                        origin=origin, normal=normal)

    def add_velocity_constraint(self, name: str, body1: str, body2: str, rows,
                                labels=None, point: Sequence[float] | None = None) -> Joint:
        """Velocity rows A(q, t) v + b(q, t) = 0 written as expressions of measures, each
        checked for linearity in the velocities (:mod:`casmbd.model.velocity_constraint`)."""
        return self.add("velocity", name, body1, body2, rows=rows, labels=labels, point=point)

    def add_driver(self, name: str, position: Value | None = None, joint: str | None = None,
                   body: str | None = None, coordinate: str | None = None, *,
                   euler_zxz: Sequence[Value] | None = None, rpy: Sequence[Value] | None = None,
                   quaternion: Sequence[Value] | None = None
                   ) -> Driver | tuple[OrientationDriver, ...]:
        """Prescribe a joint coordinate (``coordinate`` picks one of a multi-coordinate joint)
        or a body coordinate (x, y, angle in the plane; x, y, z in space) as f(t).

        ``coordinate="orientation"`` with ``body`` (space) prescribes the body's rotation as
        ``euler_zxz`` [φ, θ, ψ], ``rpy`` [roll, pitch, yaw] or ``quaternion`` [w, x, y, z] of t:
        three drivers ``<name>.x``, ``<name>.y``, ``<name>.z`` whose efforts are the moment
        about the global axes (:class:`~casmbd.model.drivers.OrientationDriver`); returns them.
        """
        self._unique(self.drivers, "driver", name)
        forms = {k: v for k, v in (("euler_zxz", euler_zxz), ("rpy", rpy),
                                   ("quaternion", quaternion)) if v is not None}
        if coordinate == ORIENTATION or forms:
            return self._add_orientation_driver(name, body, coordinate, position, joint, forms)
        if position is None:
            raise ModelError(f"driver '{name}' field 'position': missing")
        driver = Driver(name, position, joint=joint, body=body, coordinate=coordinate)
        if joint is not None:
            joint_obj = self._joint(joint, f"driver '{name}' field 'joint'")
            if coordinate is not None and coordinate not in joint_obj.coordinate_names:
                raise ModelError(f"driver '{name}' field 'coordinate': joint '{joint}' has "
                                 f"coordinates {', '.join(joint_obj.coordinate_names)}, not "
                                 f"{coordinate!r}")
        else:
            if coordinate not in BODY_COORDINATES[self.dimension]:
                raise ModelError(f"driver '{name}' field 'coordinate': expected one of "
                                 f"{', '.join(BODY_COORDINATES[self.dimension])}, got "
                                 f"{coordinate!r}")
            if body == GROUND:
                raise ModelError(f"driver '{name}' field 'body': the ground cannot be driven")
            self._body(body, f"driver '{name}' field 'body'")
        self.drivers[name] = driver
        return driver

    def _add_orientation_driver(self, name, body, coordinate, position, joint, forms):
        where = f"driver '{name}'"
        if coordinate != ORIENTATION:
            raise ModelError(f"{where} field '{next(iter(forms))}': applies to coordinate = "
                             f"'{ORIENTATION}', not {coordinate!r}")
        if joint is not None or body is None:
            raise ModelError(f"{where}: an orientation driver takes 'body' (a spatial body), "
                             "not 'joint'")
        if self.dimension != 3:
            raise ModelError(f"{where} field 'coordinate': 'orientation' drives a spatial "
                             f"body; in the plane drive body '{body}' coordinate 'angle'")
        if position is not None:
            raise ModelError(f"{where} field 'position': an orientation driver takes "
                             f"{' or '.join(ORIENTATION_FORMS)}, not 'position'")
        if len(forms) != 1:
            raise ModelError(f"{where}: give exactly one of {', '.join(ORIENTATION_FORMS)} "
                             f"(got {', '.join(forms) or 'none'})")
        if body == GROUND:
            raise ModelError(f"{where} field 'body': the ground cannot be driven")
        self._body(body, f"{where} field 'body'")
        (form, angles), = forms.items()
        rows = orientation_rows(name, body, form, angles)
        for row in rows:
            self._unique(self.drivers, "driver", self._generate(row.name))
        for row in rows:
            self.drivers[row.name] = row
        return tuple(rows)

    # ------------------------------------------------------------------ forces
    def add_force(self, name: str, body: str, value: Sequence[Value],
                  point: Sequence[float] | None = None, frame: str = "global") -> PointForce:
        """Point force (2 or 3 components, ``frame`` 'global' or 'body') at ``point`` of
        ``body`` (default: its centre of mass)."""
        return self.add("force", name, body, value, point=point, frame=frame)

    def add_torque(self, name: str, body: str, value, frame: str = "global") -> Torque:
        """Torque on ``body``: one value in the plane, three (global or body ``frame``) in
        space."""
        return self.add("torque", name, body, value, frame=frame)

    def _dimension_of(self, name: str, key: str, size: int) -> None:
        if size != self.dimension:
            raise ModelError(f"force '{name}' field '{key}': expected {self.dimension} "
                             f"components, got {size}")

    def add_spring_damper(self, name: str, body1: str, body2: str, point1: Sequence[float],
                          point2: Sequence[float], stiffness: Value = 0.0, damping: Value = 0.0,
                          free_length: Value | None = None,
                          actuator: Value = 0.0) -> SpringDamper:
        """Translational spring-damper-actuator between two points (tension positive)."""
        return self.add("spring_damper", name, body1, body2, point1, point2,
                        stiffness=stiffness, damping=damping, free_length=free_length,
                        actuator=actuator)

    def add_rotational_spring_damper(self, name: str, joint: str, stiffness: Value = 0.0,
                                     damping: Value = 0.0, free_angle: Value = 0.0,
                                     actuator: Value = 0.0) -> RotationalSpringDamper:
        """Rotational spring-damper-actuator on the angle of a revolute (or cylindrical)
        joint."""
        return self.add("rotational_spring_damper", name, joint, stiffness=stiffness,
                        damping=damping, free_angle=free_angle, actuator=actuator)

    def add_user_force(self, name: str, function: Callable, body: str | None = None,
                       point: Sequence[float] | None = None) -> UserForce:
        """A force written as CasADi expressions of (q, v, t, u, p); see :class:`UserForce`."""
        return self.add("user", name, function, body=body, point=point)

    def add_actuator(self, name: str, joint: str, coordinate: str | None = None) -> Actuator:
        """A generalized-force input u along a coordinate of ``joint`` (default its first)."""
        self._unique(self.actuators, "actuator", name)
        joint_obj = self._joint(joint, f"actuator '{name}' field 'joint'")
        if coordinate is not None and coordinate not in joint_obj.coordinate_names:
            raise ModelError(f"actuator '{name}' field 'coordinate': joint '{joint}' has "
                             f"coordinates {', '.join(joint_obj.coordinate_names)}, not "
                             f"{coordinate!r}")
        actuator = Actuator(name, joint, coordinate=coordinate)
        self.actuators[name] = actuator
        return actuator

    # ------------------------------------------------------------------ unilateral elements
    def add_contact(self, name: str, body: str, point: Sequence[float], radius: float = 0.0,
                    origin: Sequence[float] | None = None, normal: Sequence[float] | None = None,
                    model: str = "impact", restitution: float = 0.0, friction: float = 0.0,
                    body2: str | None = None, point2: Sequence[float] | None = None,
                    radius2: float = 0.0, shape: str | None = None, **keys) -> Unilateral:
        """A sphere (``radius``; 0: a point) at the global ``point`` on ``body`` against the
        ground plane through ``origin`` with ``normal`` (shape ``"plane"``) or, with ``body2``,
        against a sphere (``radius2``) at ``point2`` on ``body2`` (``"sphere"``), or any
        registered ``shape`` (:data:`casmbd.model.contacts.CONTACT_SHAPES`: its own keys
        among ``keys``); ``model`` "impact" (events and restitution) or "compliant"
        (``stiffness``, ``exponent``, ``damping``, ``penetration``, ``friction_velocity``).
        See :mod:`casmbd.model.contacts`."""
        self._unique(self.contacts, "contact", name)
        self._body(body, f"contact '{name}' field 'body'")
        kind = contact_shape(shape if shape is not None else
                             "plane" if body2 is None else "sphere", f"contact '{name}'")
        own = {k: keys.pop(k) for k in list(keys) if k in getattr(kind, "scene_keys", ())}
        args = {"origin": origin, "normal": normal, "body2": body2, "point2": point2,
                "radius2": radius2, **own}
        for key in getattr(kind, "body_keys", ()):
            if args.get(key) is not None:
                self._body(args[key], f"contact '{name}' field '{key}'")
        element = kind.create(name, restitution, friction, model, body, point, radius,
                              self.dimension, **args)
        return self._unilateral(element, keys)

    def add_joint_limit(self, joint: str, lower: float | None = None,
                        upper: float | None = None, restitution: float = 0.0,
                        coordinate: str | None = None, model: str = "impact",
                        **compliant) -> Unilateral:
        """Stops ``lower`` ≤ q ≤ ``upper`` on a joint coordinate (the element
        ``"<joint>.limit"``; restitution e of Newton's law at the stop)."""
        joint_obj = self._joint(joint, f"joint '{joint}' field 'lower'")
        if coordinate is not None:
            joint_obj._which(coordinate)
        name = self._unique(self.contacts, "contact", self._generate(f"{joint}.limit"))
        return self._unilateral(JointLimit(name, restitution, 0.0, model, joint, coordinate,
                                           lower, upper), compliant)

    def _unilateral(self, element: Unilateral, compliant: dict) -> Unilateral:
        element.check_values(self.parameters)  # expressions at the parameters' defaults
        rest = compliant.pop("rest_velocity", None)
        if rest is not None:  # the element's own rest velocity (events; m/s)
            where = f"contact '{element.name}' field 'rest_velocity'"
            rest = scalar(rest, where)
            if rest < 0.0 or not acts_at_events(element):
                raise ModelError(f"{where}: must be >= 0, got {rest}" if rest < 0.0 else
                                 f"{where}: applies to model = "
                                 f"{models_where(lambda m: m.events)}")
            element.rest_velocity = rest
        force = CONTACT_MODELS[element.model].force  # how the model enters the equations
        if force is not None:
            self.add(force, self._generate(f"{element.name}.force"), element, **compliant)
        elif compliant:
            raise ModelError(f"contact '{element.name}': {', '.join(compliant)} apply to "
                             f"model = {models_where(lambda m: m.force is not None)}")
        if slides(element):  # its closed phases: sliding sign and stuck position
            for param in slide_parameters(element.name):
                self.add_parameter(param, 0.0)
            if self.dimension == 3:  # and the sliding direction in the tangent plane
                for param in slide_direction_parameters(element.name):
                    self.add_parameter(param, 0.0)
        self.contacts[element.name] = element
        return element

    # ------------------------------------------------------------------ checks
    def add_output(self, name: str, value: float | str, unit: str = "-") -> Output:
        """Add a request: ``value``, an expression of measures (``angle("J")``, ``x("tip")``,
        … :mod:`casmbd.model.measures`), reported as ``outputs`` on the result grid of every
        analysis with one; ``unit`` labels its plot axis."""
        return add_output(self, name, value, unit)

    def validate(self) -> None:
        """Check what can only be checked once everything is declared (expression values)."""
        if not self.bodies:
            raise ModelError(f"mechanism '{self.name}' has no moving body")
        for body in self.bodies.values():
            where = f"body '{body.name}' field"
            mass = numeric(body.mass, self.parameters, f"{where} 'mass'")
            if mass < 0.0:
                raise ModelError(f"{where} 'mass': must be >= 0, got {mass}")
            if body.dimension == 2:
                inertia = numeric(body.inertia, self.parameters, f"{where} 'inertia'")
                if inertia < 0.0:
                    raise ModelError(f"{where} 'inertia': must be >= 0, got {inertia}")
            else:
                values = [numeric(v, self.parameters, f"{where} 'inertia'")
                          for v in body.inertia]
                try:
                    check_inertia(values)
                except ModelError as exc:
                    raise ModelError(f"{where} 'inertia': {exc}") from None
        for force in self.forces.values():
            for key in ("stiffness", "damping"):
                if hasattr(force, key):
                    check_value(getattr(force, key), f"force '{force.name}' field '{key}'")

    def __repr__(self) -> str:
        return (f"Mechanism({self.name!r}: {len(self.bodies)} bodies, {len(self.joints)} joints, "
                f"{len(self.drivers)} drivers, {len(self.forces)} forces, "
                f"{len(self.actuators)} actuators)")
