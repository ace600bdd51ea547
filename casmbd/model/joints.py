"""Planar joints: holonomic constraint equations C(q) = 0 between two bodies.

Each joint is defined at the initial (design) configuration by global points and axes, which
are turned into body-fixed vectors once, then written as CasADi expressions of the coordinates.
The constraint equations follow seed 000, "Kinematic constraints" (revolute joint eq. 6.96:
R_i + A_i u_i^P − R_j − A_j u_j^P = 0; prismatic joint: relative angle and a normal distance).
Every equation carries a label so that residuals and redundancies can be named.

A joint *kind* is one class that owns everything about it (see :mod:`casmbd.model.registry`):
its scene type name and keys, how it is built from the Python API (:meth:`Joint.create`) and
from a scene entry (:meth:`Joint.from_scene`), its constraint equations in any coordinate
choice (written with the context's helpers), its tree motion in joint coordinates
(:meth:`Joint.tree_layout`, :meth:`Joint.tree_motion`), its coordinates and its drawing hint.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND, scalar, unit_vector, vector, vector2
from casmbd.model.registry import joint_kinds, register_joint


def __getattr__(name: str):
    """``JOINT_TYPES``: the registered joint type names, read from the registry (kept for
    compatibility; it used to be a hand-kept tuple)."""
    if name == "JOINT_TYPES":
        return tuple(joint_kinds())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _perp(vec):
    """Rotate a planar vector by +90 degrees."""
    return ca.vertcat(-vec[1], vec[0]) if isinstance(vec, ca.SX) else np.array([-vec[1], vec[0]])


def _relative_rotation(ctx, body1: str, body2: str) -> ca.SX:
    """Planar relative rotation since the initial pose: linear in the angles when they are
    coordinates, its sine otherwise (natural coordinates)."""
    if ctx.has_angle(body1) and ctx.has_angle(body2):
        rel0 = ctx.initial_angle(body2) - ctx.initial_angle(body1)
        return ctx.angle(body2) - ctx.angle(body1) - rel0
    return ctx.relative_rotation(body1, body2)[0]


@dataclass
class Joint:
    """Base class: a named connection between ``body1`` and ``body2`` (either may be ground)."""

    name: str
    body1: str
    body2: str

    #: labels of the constraint equations, in order
    labels: tuple[str, ...] = ()
    #: names of the joint's coordinates (drivers, actuators, springs); the first is the default
    coordinate_names: tuple[str, ...] = ()

    #: scene type name (``[[joints]] type``); empty for an abstract base
    kind: ClassVar[str] = ""
    #: the kind's name in messages when it differs from ``kind`` ("in-line")
    title: ClassVar[str] = ""
    #: mechanism dimensions the class serves
    dimensions: ClassVar[tuple[int, ...]] = (2,)
    #: its one tree coordinate is its coordinate c − c⁰ (same sense, zero at the design pose)
    #: when it carries its ``body2``: joint coordinates substitute a gear on it
    #: (:func:`casmbd.system.tree.substitute_mimics`)
    gear_substitutable: ClassVar[bool] = False
    #: scene keys every entry of the kind takes, and those of the kind itself
    scene_common: ClassVar[frozenset[str]] = frozenset({"name", "type", "body1", "body2",
                                                        "description"})
    scene_keys: ClassVar[frozenset[str]] = frozenset()
    #: drawing hint for :mod:`casmbd.viz.geometry`: "point" (a pin at ``point``), "slide" (a
    #: guide line along ``axis`` when attached to the ground), "link" (a bar from ``point1`` to
    #: ``point2``) or "none"
    drawing: ClassVar[str] = "point"
    #: True when the joint can carry a body in the spanning tree of joint coordinates
    tree_joint: ClassVar[bool] = False
    #: True when its tree coordinates are Euler parameters (a normalization equation, four
    #: coordinates for three rates: outside the articulated-body recursion)
    euler_parameters: ClassVar[bool] = False

    @property
    def has_coordinate(self) -> bool:
        """True when the joint defines at least one joint coordinate."""
        return bool(self.coordinate_names)

    @property
    def bodies(self) -> tuple[str, ...]:
        """Every body whose pose enters the joint's equations (the ground included): the
        reactions on a body are found from the equations of the joints that list it."""
        return (self.body1, self.body2)

    # ------------------------------------------------------------------ construction
    @classmethod
    def create(cls, mech, name: str, body1: str, body2: str, **fields) -> Joint:
        """Validate the arguments of ``mech.add(kind, ...)`` and build the joint.

        The default checks a unique name and two distinct known bodies; kinds with more rules
        (a planar revolute has no axis, ...) override it and raise
        :class:`~casmbd.errors.ModelError` naming the joint and the field.
        """
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, **fields)

    @classmethod
    def from_scene(cls, mech, entry) -> Joint:
        """Add the joint of one ``[[joints]]`` entry to ``mech`` and return it.

        ``entry`` is the scene loader's reader of the entry (methods ``string``, ``vector``,
        ``number``, ``has``, ``error``); the parsing stays in :mod:`casmbd.io.scene`, the
        knowledge of which keys build which arguments lives here.
        """
        raise NotImplementedError(f"joint kind '{cls.kind}' cannot be read from a scene")

    # ------------------------------------------------------------------ joint coordinates
    def tree_layout(self) -> tuple[tuple[str, ...], tuple[bool, ...]]:
        """Names of the tree coordinates the joint gives its child body in joint coordinates,
        and whether each is a length (empty for a weld)."""
        return (), ()

    def tree_initial(self) -> np.ndarray:
        """Tree coordinates at the design pose (zero: the motion is measured from it)."""
        return np.zeros(len(self.tree_layout()[0]))

    def tree_motion(self, tree, q: ca.SX, v: ca.SX | None = None):
        """(ΔR, Δd, ω_rel): the joint's motion of the child in the design frame, as a function
        of its tree coordinates ``q`` (and rates ``v``: ω_rel only when given).

        ``tree`` is the tree description of the child (:mod:`casmbd.system.tree`), which hands
        in ``dimension``, ``parent`` and the symbolic helpers ``rodrigues(axis, angle)`` and
        ``planar_rotation(angle)``, so the model layer does not import the system layer.  The
        default keeps the child welded (ΔR = I, Δd = 0).
        """
        dim = tree.dimension
        return ca.SX.eye(dim), ca.SX.zeros(dim), ca.SX(0.0) if dim == 2 else ca.SX.zeros(3)

    def tree_angle(self, q: ca.SX):
        """Planar rotation of the child relative to the parent carried by the tree
        coordinates ``q`` (0 for a joint that does not turn)."""
        return 0.0

    def initial_coordinate(self, ctx, which: str | None = None) -> float:
        """Value of coordinate ``which`` at the design pose (zero unless the kind says
        otherwise)."""
        self._which(which)
        return 0.0

    def equations(self, ctx) -> ca.SX:
        """Constraint vector C_joint(q) as a column (same order as ``labels``)."""
        raise NotImplementedError

    def _which(self, which: str | None) -> str:
        if not self.coordinate_names:
            raise ModelError(f"joint '{self.name}' ({type(self).__name__}) has no joint "
                             "coordinate")
        if which is None:
            return self.coordinate_names[0]
        if which not in self.coordinate_names:
            raise ModelError(f"joint '{self.name}' has no coordinate '{which}' (known: "
                             f"{', '.join(self.coordinate_names)})")
        return which

    def coordinate(self, ctx, which: str | None = None) -> ca.SX:
        """Joint coordinate ``which`` (default: the first) as an expression of q."""
        self._which(which)
        raise NotImplementedError

    def driver_residual(self, ctx, target, which: str | None = None) -> ca.SX:
        """Residual of the driving constraint coordinate = target (unit slope at the root)."""
        return self.coordinate(ctx, which) - target

    def reaction_point(self) -> np.ndarray | None:
        """Global location (initial pose) at which reactions are reported."""
        return getattr(self, "point", None)


def revolute_from_scene(cls, mech, e) -> Joint:
    """Scene reader of "revolute" (both dimensions): ``point``, and ``axis`` in space."""
    name, dim = e.string("name"), mech.dimension
    b1, b2 = e.string("body1"), e.string("body2")
    if dim == 2 and e.has("axis"):
        raise e.error("axis", "a planar revolute joint has no axis (it turns about z)")
    axis = e.vector("axis", 3) if dim == 3 else None
    return mech.add("revolute", name, b1, b2, e.vector("point", dim), axis=axis)


def axis_from_scene(cls, mech, e) -> Joint:
    """Scene reader of the kinds with a ``point`` and an ``axis`` (prismatic, cylindrical,
    in-line)."""
    name, dim = e.string("name"), mech.dimension
    b1, b2 = e.string("body1"), e.string("body2")
    return mech.add(cls.kind, name, b1, b2, e.vector("point", dim), e.vector("axis", dim))


def rigid_from_scene(cls, mech, e) -> Joint:
    """Scene reader of "rigid" (both dimensions): an optional ``point``."""
    name, dim = e.string("name"), mech.dimension
    b1, b2 = e.string("body1"), e.string("body2")
    return mech.add("rigid", name, b1, b2, e.vector("point", dim, required=False))


def fixed_from_scene(cls, mech, e) -> Joint:
    """Scene reader of "fixed": ``body`` (or ``body1`` and ``body2``, one of them the ground;
    two moving bodies make a weld) and an optional ``point``."""
    name, dim = e.string("name"), mech.dimension
    if e.has("body"):
        body = e.string("body")
        return mech.add("fixed", name, body,
                        point=e.vector("point", dim, default=None, required=False))
    if not (e.has("body1") and e.has("body2")):
        raise e.error("body", "missing required key (or give 'body1' and 'body2')")
    b1, b2 = e.string("body1"), e.string("body2")
    point = e.vector("point", dim, required=False)
    if GROUND in (b1, b2):
        return mech.add("fixed", name, b2 if b1 == GROUND else b1, point=point)
    return mech.add("rigid", name, b1, b2, point=point)


def create_fixed(cls, mech, name: str, body: str, point=None) -> Joint:
    """``mech.add("fixed", name, body, point=None)``: a weld of ``body`` to the ground."""
    mech._new_joint(name, GROUND, body)
    return cls(name, GROUND, body, point=point)


@register_joint
@dataclass
class Revolute(Joint):
    """Pin joint at a global point; coordinate θ2 − θ1 (continuous)."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    labels: tuple[str, ...] = ("x", "y")
    coordinate_names: tuple[str, ...] = ("angle",)

    kind = "revolute"
    dimensions = (2,)
    scene_keys = frozenset({"point", "axis"})
    tree_joint = True
    gear_substitutable = True
    from_scene = classmethod(revolute_from_scene)

    def __post_init__(self):
        self.point = vector2(self.point, f"joint '{self.name}' field 'point'")

    @classmethod
    def create(cls, mech, name, body1, body2, point, axis=None):
        mech._new_joint(name, body1, body2)
        if axis is not None:
            raise ModelError(f"joint '{name}' field 'axis': a planar revolute joint has no axis")
        return cls(name, body1, body2, point=point)

    def tree_layout(self):
        return ("angle",), (False,)

    def tree_motion(self, tree, q, v=None):
        omega = v[0] if v is not None else None
        return tree.planar_rotation(q[0]), ca.SX.zeros(2), omega

    def tree_angle(self, q):
        return q[0]

    def initial_coordinate(self, ctx, which=None):
        self._which(which)
        return float(ctx.initial_angle(self.body2) - ctx.initial_angle(self.body1))

    def equations(self, ctx):
        p1 = ctx.point(self.body1, ctx.local(self.body1, self.point))
        p2 = ctx.point(self.body2, ctx.local(self.body2, self.point))
        return p1 - p2

    def coordinate(self, ctx, which=None):
        self._which(which)
        return ctx.relative_angle(self.body1, self.body2)

    def driver_residual(self, ctx, target, which=None):
        self._which(which)
        return ctx.angle_residual(self.body1, self.body2, target)


@register_joint
@dataclass
class Prismatic(Joint):
    """Translational joint along ``axis`` (global at the initial pose) through ``point``.

    Equations: the relative angle stays at its initial value and the normal component of the
    vector from body1's joint point to body2's vanishes.  Coordinate: the component along the
    axis (zero at the initial pose).
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0]))
    labels: tuple[str, ...] = ("angle", "normal")
    coordinate_names: tuple[str, ...] = ("translation",)

    kind = "prismatic"
    dimensions = (2,)
    scene_keys = frozenset({"point", "axis"})
    drawing = "slide"
    tree_joint = True
    gear_substitutable = True
    from_scene = classmethod(axis_from_scene)

    @classmethod
    def create(cls, mech, name, body1, body2, point, axis):
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, point=point, axis=axis)

    def tree_layout(self):
        return ("translation",), (True,)

    def tree_motion(self, tree, q, v=None):
        return ca.SX.eye(2), q[0] * ca.DM(np.asarray(self.axis, float)), ca.SX(0.0)

    def __post_init__(self):
        self.point = vector2(self.point, f"joint '{self.name}' field 'point'")
        self.axis = unit_vector(self.axis, f"joint '{self.name}' field 'axis'", 2)

    def _separation(self, ctx):
        p1 = ctx.point(self.body1, ctx.local(self.body1, self.point))
        p2 = ctx.point(self.body2, ctx.local(self.body2, self.point))
        axis = ctx.direction(self.body1, ctx.local_direction(self.body1, self.axis))
        return p2 - p1, axis

    def equations(self, ctx):
        d, axis = self._separation(ctx)
        return ca.vertcat(_relative_rotation(ctx, self.body1, self.body2),
                          ca.dot(_perp(axis), d))

    def coordinate(self, ctx, which=None):
        self._which(which)
        d, axis = self._separation(ctx)
        return ca.dot(axis, d)


@register_joint
@dataclass
class Rigid(Joint):
    """Weld: body2 keeps its initial pose relative to body1 (three equations)."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    point: np.ndarray | None = None
    labels: tuple[str, ...] = ("x", "y", "angle")

    kind = "rigid"
    dimensions = (2,)
    scene_keys = frozenset({"point"})
    tree_joint = True
    from_scene = classmethod(rigid_from_scene)

    @classmethod
    def create(cls, mech, name, body1, body2, point=None):
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, point=point)

    def __post_init__(self):
        if self.point is not None:
            self.point = vector2(self.point, f"joint '{self.name}' field 'point'")

    def equations(self, ctx):
        point = self.point if self.point is not None else ctx.initial_position(self.body2)
        p1 = ctx.point(self.body1, ctx.local(self.body1, point))
        p2 = ctx.point(self.body2, ctx.local(self.body2, point))
        return ca.vertcat(p1 - p2, _relative_rotation(ctx, self.body1, self.body2))

    def reaction_point(self):
        return self.point


@register_joint
@dataclass
class Fixed(Rigid):
    """Fix a body to the ground at its initial pose (a weld with ground as body1)."""

    kind = "fixed"
    scene_keys = frozenset({"point", "body"})
    from_scene = classmethod(fixed_from_scene)
    create = classmethod(create_fixed)


@register_joint
@dataclass
class Distance(Joint):
    """Massless link of fixed length between point1 on body1 and point2 on body2.

    Equation (|d|² − L²)/(2L) = 0, scaled so that the residual is a length; coordinate |d|.
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    point1: np.ndarray = field(default_factory=lambda: np.zeros(2))
    point2: np.ndarray = field(default_factory=lambda: np.zeros(2))
    length: float | None = None
    labels: tuple[str, ...] = ("length",)
    coordinate_names: tuple[str, ...] = ("length",)
    dimension: int = 2

    kind = "distance"
    dimensions = (2, 3)
    scene_keys = frozenset({"point1", "point2", "length"})
    drawing = "link"

    @classmethod
    def create(cls, mech, name, body1, body2, point1, point2, length=None):
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, point1=point1, point2=point2, length=length,
                   dimension=mech.dimension)

    @classmethod
    def from_scene(cls, mech, e):
        name, dim = e.string("name"), mech.dimension
        b1, b2 = e.string("body1"), e.string("body2")
        length = e.number("length", required=False)
        return mech.add("distance", name, b1, b2, e.vector("point1", dim),
                        e.vector("point2", dim), length=length)

    def initial_coordinate(self, ctx, which=None):
        self._which(which)
        return float(np.linalg.norm(self.point2 - self.point1))

    def __post_init__(self):
        where = f"joint '{self.name}' field"
        self.point1 = vector(self.point1, f"{where} 'point1'", self.dimension)
        self.point2 = vector(self.point2, f"{where} 'point2'", self.dimension)
        if self.length is None:
            self.length = float(np.linalg.norm(self.point2 - self.point1))
        self.length = scalar(self.length, f"joint '{self.name}' field 'length'")
        if self.length <= 0.0:
            raise ModelError(f"joint '{self.name}' field 'length': must be > 0, got "
                             f"{self.length} (coincident points? use a revolute joint)")

    def _separation(self, ctx):
        p1 = ctx.point(self.body1, ctx.local(self.body1, self.point1))
        p2 = ctx.point(self.body2, ctx.local(self.body2, self.point2))
        return p2 - p1

    def equations(self, ctx):
        d = self._separation(ctx)
        return (ca.dot(d, d) - self.length**2) / (2.0 * self.length)

    def coordinate(self, ctx, which=None):
        self._which(which)
        d = self._separation(ctx)
        return ca.sqrt(ca.dot(d, d))

    def reaction_point(self):
        return self.point2
