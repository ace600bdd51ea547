"""Spatial joints, each a few lines over the three basic constraints of seed 001.

The basic constraints ("Spatial joints", seed 001), written with the context's body points and
body-fixed directions so that they hold for any body description:

* dot-1, h_i · h_j = 0: two body-fixed vectors stay perpendicular (one equation);
* dot-2, h_i · d_ij = 0: a body-fixed vector stays perpendicular to the vector d_ij from a
  point on body i to a point on body j (one equation);
* spherical, r_P^i − r_P^j = 0: two body points coincide (three equations).

A joint is defined at the initial (design) pose by a global point and global axes, turned into
body-fixed points and directions once.  Every joint is then a composition:

==============  ==========================================================  ======  =========
joint           constraints                                                 eqs.    DOF
==============  ==========================================================  ======  =========
spherical       spherical                                                   3       3
revolute        spherical + dot-1 (f1, h2) + dot-1 (g1, h2)                 5       1
cylindrical     dot-1 (f1, h2), dot-1 (g1, h2), dot-2 (f1, d), dot-2 (g1, d)  4       2
prismatic       cylindrical + dot-1 (f1, g2) (no rotation about the axis)   5       1
universal       spherical + dot-1 (a1, a2)                                  4       2
in-line         dot-2 (f1, d) + dot-2 (g1, d)                               2       4
rigid / fixed   spherical + dot-1 (f1, g2), (f1, h2), (g1, h2)              6       0
==============  ==========================================================  ======  =========

with (f, g, h) a right-handed orthonormal triad whose h is the joint axis, the index telling on
which body the vector is fixed.  The distance joint is shared with the plane
(:class:`casmbd.model.joints.Distance`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import unit_vector, vector
from casmbd.model.joints import (
    Joint,
    axis_from_scene,
    create_fixed,
    fixed_from_scene,
    revolute_from_scene,
    rigid_from_scene,
)
from casmbd.model.registry import register_joint
from casmbd.model.rotations import E_matrix, rotation_matrix


def _unit(value, where: str) -> np.ndarray:
    return unit_vector(value, where, 3)  # scale-safe: [1, 1e300] is the y axis


def triad(axis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A right-handed orthonormal triad (f, g, h) with h along ``axis``."""
    h = np.asarray(axis, float) / np.linalg.norm(axis)
    trial = np.zeros(3)
    trial[int(np.argmin(np.abs(h)))] = 1.0
    f = trial - h * np.dot(trial, h)
    f /= np.linalg.norm(f)
    return f, np.cross(h, f), h


# ------------------------------------------------------------------------- basic constraints
def body_vector(ctx, body: str, direction) -> ca.SX:
    """A direction given globally at the initial pose, fixed on ``body``, as an expression."""
    return ctx.direction(body, ctx.local_direction(body, direction))


def body_point(ctx, body: str, point) -> ca.SX:
    """A point given globally at the initial pose, fixed on ``body``, as an expression."""
    return ctx.point(body, ctx.local(body, point))


def dot1(ctx, body1: str, a1, body2: str, a2) -> ca.SX:
    """Dot-1 constraint (A1 ā1)·(A2 ā2) = 0, the vectors given globally at the initial pose."""
    return ca.dot(body_vector(ctx, body1, a1), body_vector(ctx, body2, a2))


def dot2(ctx, body1: str, a1, point1, body2: str, point2) -> ca.SX:
    """Dot-2 constraint (A1 ā1)·(r_P2 − r_P1) = 0."""
    d = body_point(ctx, body2, point2) - body_point(ctx, body1, point1)
    return ca.dot(body_vector(ctx, body1, a1), d)


def spherical(ctx, body1: str, body2: str, point) -> ca.SX:
    """Spherical constraint r_P1 − r_P2 = 0 at a common point (three equations)."""
    return body_point(ctx, body1, point) - body_point(ctx, body2, point)


# ------------------------------------------------------------------------- joints
@dataclass
class _PointJoint(Joint):
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()
    point: np.ndarray = field(default_factory=lambda: np.zeros(3))

    dimensions = (3,)

    @classmethod
    def create(cls, mech, name, body1, body2, point, **axes):
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, point=point, **axes)

    def __post_init__(self):
        self.point = vector(self.point, f"joint '{self.name}' field 'point'", 3)


@dataclass
class AxisJoint(_PointJoint):
    """A joint at a point with a unit axis (the base of revolute, cylindrical, in-line and
    planar joints)."""
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self):
        super().__post_init__()
        self.axis = _unit(self.axis, f"joint '{self.name}' field 'axis'")
        self.f, self.g, self.h = triad(self.axis)

    @classmethod
    def create(cls, mech, name, body1, body2, point, axis):
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, point=point, axis=axis)

    def _parallel_axes(self, ctx) -> list[ca.SX]:
        b1, b2 = self.body1, self.body2
        return [dot1(ctx, b1, self.f, b2, self.h), dot1(ctx, b1, self.g, b2, self.h)]

    def _translation(self, ctx) -> ca.SX:
        d = body_point(ctx, self.body2, self.point) - body_point(ctx, self.body1, self.point)
        return ca.dot(body_vector(ctx, self.body1, self.h), d)

    def _angle(self, ctx) -> ca.SX:
        return ctx.relative_angle(self.body1, self.body2, self.axis)


@register_joint
@dataclass
class Spherical(_PointJoint):
    """Ball joint: a common point (3 equations, 3 rotational degrees of freedom).

    In joint coordinates its tree coordinates are the Euler parameters of the child relative
    to the parent (one normalization equation)."""

    labels: tuple[str, ...] = ("x", "y", "z")

    kind = "spherical"
    scene_keys = frozenset({"point"})
    tree_joint = True
    euler_parameters = True

    @classmethod
    def from_scene(cls, mech, e):
        name = e.string("name")
        b1, b2 = e.string("body1"), e.string("body2")
        return mech.add("spherical", name, b1, b2, e.vector("point", 3))

    def tree_layout(self):
        return ("e0", "e1", "e2", "e3"), (False,) * 4

    def tree_initial(self):
        return np.array([1.0, 0.0, 0.0, 0.0])

    def tree_motion(self, tree, q, v=None):
        omega = 2.0 * ca.mtimes(E_matrix(q), v) if v is not None else None
        return rotation_matrix(q), ca.SX.zeros(3), omega

    def equations(self, ctx):
        return spherical(ctx, self.body1, self.body2, self.point)


@register_joint
@dataclass
class SpatialRevolute(AxisJoint):
    """Revolute joint: a common point and a common axis (5 equations).

    Coordinate ``angle``: the rotation of body2 relative to body1 about the axis since the
    initial pose (right-hand rule), wrapped to (−π, π]; a driver on it uses the
    wrapped residual atan2(sin(φ − f), cos(φ − f)) and turns without limit.
    """

    labels: tuple[str, ...] = ("x", "y", "z", "axis f", "axis g")
    coordinate_names: tuple[str, ...] = ("angle",)

    kind = "revolute"
    scene_keys = frozenset({"point", "axis"})
    tree_joint = True
    gear_substitutable = True
    from_scene = classmethod(revolute_from_scene)

    @classmethod
    def create(cls, mech, name, body1, body2, point, axis=None):
        mech._new_joint(name, body1, body2)
        if axis is None:
            raise ModelError(f"joint '{name}' field 'axis': a spatial revolute joint needs "
                             "its axis")
        return cls(name, body1, body2, point=point, axis=axis)

    def tree_layout(self):
        return ("angle",), (False,)

    def tree_motion(self, tree, q, v=None):
        h = np.asarray(self.axis, float)
        omega = ca.DM(h) * v[0] if v is not None else None
        return tree.rodrigues(h, q[0]), ca.SX.zeros(3), omega

    def equations(self, ctx):
        return ca.vertcat(spherical(ctx, self.body1, self.body2, self.point),
                          *self._parallel_axes(ctx))

    def coordinate(self, ctx, which=None):
        self._which(which)
        return self._angle(ctx)

    def driver_residual(self, ctx, target, which=None):
        self._which(which)
        return ctx.angle_residual(self.body1, self.body2, target, self.axis)


@register_joint
@dataclass
class Cylindrical(AxisJoint):
    """Cylindrical joint: body2 slides along and turns about the axis of body1 (4 equations).

    Coordinates ``translation`` (along the axis, zero at the initial pose) and ``angle``.
    """

    labels: tuple[str, ...] = ("axis f", "axis g", "offset f", "offset g")
    coordinate_names: tuple[str, ...] = ("translation", "angle")

    kind = "cylindrical"
    scene_keys = frozenset({"point", "axis"})
    drawing = "slide"
    tree_joint = True
    from_scene = classmethod(axis_from_scene)

    def tree_layout(self):
        return ("translation", "angle"), (True, False)

    def tree_motion(self, tree, q, v=None):
        h = np.asarray(self.axis, float)
        omega = ca.DM(h) * v[1] if v is not None else None
        return tree.rodrigues(h, q[1]), q[0] * ca.DM(h), omega

    def _offsets(self, ctx) -> list[ca.SX]:
        b1, b2, p = self.body1, self.body2, self.point
        return [dot2(ctx, b1, self.f, p, b2, p), dot2(ctx, b1, self.g, p, b2, p)]

    def equations(self, ctx):
        return ca.vertcat(*self._parallel_axes(ctx), *self._offsets(ctx))

    def coordinate(self, ctx, which=None):
        which = self._which(which)
        return self._translation(ctx) if which == "translation" else self._angle(ctx)

    def driver_residual(self, ctx, target, which=None):
        if self._which(which) == "angle":
            return ctx.angle_residual(self.body1, self.body2, target, self.axis)
        return self._translation(ctx) - target


@register_joint
@dataclass
class SpatialPrismatic(Cylindrical):
    """Prismatic joint: a cylindrical joint that cannot turn (5 equations).

    Coordinate ``translation`` along the axis, zero at the initial pose.
    """

    labels: tuple[str, ...] = ("axis f", "axis g", "offset f", "offset g", "twist")
    coordinate_names: tuple[str, ...] = ("translation",)

    kind = "prismatic"
    gear_substitutable = True

    def tree_layout(self):
        return ("translation",), (True,)

    def tree_motion(self, tree, q, v=None):
        return ca.SX.eye(3), q[0] * ca.DM(np.asarray(self.axis, float)), ca.SX.zeros(3)

    def equations(self, ctx):
        twist = dot1(ctx, self.body1, self.f, self.body2, self.g)
        return ca.vertcat(*self._parallel_axes(ctx), *self._offsets(ctx), twist)


@register_joint
@dataclass
class Universal(_PointJoint):
    """Universal (Hooke) joint: a common point, ``axis1`` fixed on body1 stays perpendicular
    to ``axis2`` fixed on body2 (4 equations); the axes must be perpendicular initially."""

    axis1: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    axis2: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    labels: tuple[str, ...] = ("x", "y", "z", "cross")

    kind = "universal"
    scene_keys = frozenset({"point", "axes", "axis1", "axis2"})
    tree_joint = True

    @classmethod
    def from_scene(cls, mech, e):
        name = e.string("name")
        b1, b2 = e.string("body1"), e.string("body2")
        if e.has("axes"):
            for key in ("axis1", "axis2"):
                if e.has(key):
                    raise e.error(key, "give 'axes' or 'axis1' and 'axis2', not both")
            axis1, axis2 = e.vectors("axes", 2, 3)
        elif e.has("axis1") or e.has("axis2"):
            axis1, axis2 = e.vector("axis1", 3), e.vector("axis2", 3)
        else:
            raise e.error("axes", "missing required key (axes = [[axis on body1], [axis on "
                          "body2]], or 'axis1' and 'axis2')")
        return mech.add("universal", name, b1, b2, e.vector("point", 3), axis1, axis2)

    @classmethod
    def create(cls, mech, name, body1, body2, point, axis1, axis2):
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, point=point, axis1=axis1, axis2=axis2)

    def tree_layout(self):
        return ("angle1", "angle2"), (False, False)

    def tree_motion(self, tree, q, v=None):
        """Rotation about the parent's axis, then about the child's."""
        parent_is_body1 = self.body1 == tree.parent
        a_p, a_c = (self.axis1, self.axis2) if parent_is_body1 else (self.axis2, self.axis1)
        first = tree.rodrigues(a_p, q[0])
        rot = ca.mtimes(first, tree.rodrigues(a_c, q[1]))
        omega = None
        if v is not None:
            omega = ca.DM(a_p) * v[0] + ca.mtimes(first, ca.DM(a_c)) * v[1]
        return rot, ca.SX.zeros(3), omega

    def __post_init__(self):
        super().__post_init__()
        self.axis1 = _unit(self.axis1, f"joint '{self.name}' field 'axis1'")
        self.axis2 = _unit(self.axis2, f"joint '{self.name}' field 'axis2'")
        if abs(float(np.dot(self.axis1, self.axis2))) > 1e-9:
            raise ModelError(f"joint '{self.name}' fields 'axis1', 'axis2': the axes of a "
                             f"universal joint must be perpendicular (cosine "
                             f"{float(np.dot(self.axis1, self.axis2)):.3g})")

    def equations(self, ctx):
        return ca.vertcat(spherical(ctx, self.body1, self.body2, self.point),
                          dot1(ctx, self.body1, self.axis1, self.body2, self.axis2))


@register_joint
@dataclass
class InLine(AxisJoint):
    """In-line (point-on-line) joint: the point of body2 stays on the line of body1 through
    ``point`` along ``axis`` (2 equations, dot-2 (f1, d) and dot-2 (g1, d) with d = r_P2 − r_P1;
    seed 001, "Spatial joints").

    Body2 keeps its three rotations and the translation along the line (4 degrees of freedom).
    It is the non-redundant closure of a planar loop written in space: of the five equations of
    a revolute joint closing such a loop only the two in-plane conditions are independent (seed
    002, "Redundant constraint equations", the crankshaft), and these are the two equations of
    an in-line joint along the revolute's axis.
    """

    labels: tuple[str, ...] = ("offset f", "offset g")

    kind = "inline"
    title = "in-line"
    scene_keys = frozenset({"point", "axis"})
    from_scene = classmethod(axis_from_scene)

    def equations(self, ctx):
        b1, b2, p = self.body1, self.body2, self.point
        return ca.vertcat(dot2(ctx, b1, self.f, p, b2, p), dot2(ctx, b1, self.g, p, b2, p))


@register_joint
@dataclass
class SpatialRigid(Joint):
    """Weld: body2 keeps its initial pose relative to body1 (6 equations)."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    point: np.ndarray | None = None
    labels: tuple[str, ...] = ("x", "y", "z", "x.y", "x.z", "y.z")

    kind = "rigid"
    dimensions = (3,)
    scene_keys = frozenset({"point"})
    tree_joint = True
    from_scene = classmethod(rigid_from_scene)

    @classmethod
    def create(cls, mech, name, body1, body2, point=None):
        mech._new_joint(name, body1, body2)
        return cls(name, body1, body2, point=point)

    def __post_init__(self):
        if self.point is not None:
            self.point = vector(self.point, f"joint '{self.name}' field 'point'", 3)

    def equations(self, ctx):
        point = self.point if self.point is not None else ctx.initial_position(self.body2)
        ex, ey, ez = np.eye(3)
        b1, b2 = self.body1, self.body2
        return ca.vertcat(spherical(ctx, b1, b2, point), dot1(ctx, b1, ex, b2, ey),
                          dot1(ctx, b1, ex, b2, ez), dot1(ctx, b1, ey, b2, ez))

    def reaction_point(self):
        return self.point


@register_joint
@dataclass
class SpatialFixed(SpatialRigid):
    """Fix a body to the ground in its initial pose (a weld with ground as body1)."""

    kind = "fixed"
    scene_keys = frozenset({"point", "body"})
    from_scene = classmethod(fixed_from_scene)
    create = classmethod(create_fixed)
