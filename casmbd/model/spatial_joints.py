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

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import vector
from casmbd.model.joints import Joint


def _unit(value, where: str) -> np.ndarray:
    axis = vector(value, where, 3)
    norm = float(np.linalg.norm(axis))
    if norm == 0.0:
        raise ModelError(f"{where}: must not be the zero vector")
    return axis / norm


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
    point: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        self.point = vector(self.point, f"joint '{self.name}' field 'point'", 3)


@dataclass
class _AxisJoint(_PointJoint):
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self):
        super().__post_init__()
        self.axis = _unit(self.axis, f"joint '{self.name}' field 'axis'")
        self.f, self.g, self.h = triad(self.axis)

    def _parallel_axes(self, ctx) -> list[ca.SX]:
        b1, b2 = self.body1, self.body2
        return [dot1(ctx, b1, self.f, b2, self.h), dot1(ctx, b1, self.g, b2, self.h)]

    def _translation(self, ctx) -> ca.SX:
        d = body_point(ctx, self.body2, self.point) - body_point(ctx, self.body1, self.point)
        return ca.dot(body_vector(ctx, self.body1, self.h), d)

    def _angle(self, ctx) -> ca.SX:
        return ctx.relative_angle(self.body1, self.body2, self.axis)


@dataclass
class Spherical(_PointJoint):
    """Ball joint: a common point (3 equations, 3 rotational degrees of freedom)."""

    labels: tuple[str, ...] = ("x", "y", "z")

    def equations(self, ctx):
        return spherical(ctx, self.body1, self.body2, self.point)


@dataclass
class SpatialRevolute(_AxisJoint):
    """Revolute joint: a common point and a common axis (5 equations).

    Coordinate ``angle``: the rotation of body2 relative to body1 about the axis since the
    initial pose (right-hand rule), wrapped to (−π, π]; a driver on it uses the
    wrapped residual atan2(sin(φ − f), cos(φ − f)) and turns without limit.
    """

    labels: tuple[str, ...] = ("x", "y", "z", "axis f", "axis g")
    coordinate_names: tuple[str, ...] = ("angle",)

    def equations(self, ctx):
        return ca.vertcat(spherical(ctx, self.body1, self.body2, self.point),
                          *self._parallel_axes(ctx))

    def coordinate(self, ctx, which=None):
        self._which(which)
        return self._angle(ctx)

    def driver_residual(self, ctx, target, which=None):
        self._which(which)
        return ctx.angle_residual(self.body1, self.body2, target, self.axis)


@dataclass
class Cylindrical(_AxisJoint):
    """Cylindrical joint: body2 slides along and turns about the axis of body1 (4 equations).

    Coordinates ``translation`` (along the axis, zero at the initial pose) and ``angle``.
    """

    labels: tuple[str, ...] = ("axis f", "axis g", "offset f", "offset g")
    coordinate_names: tuple[str, ...] = ("translation", "angle")

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


@dataclass
class SpatialPrismatic(Cylindrical):
    """Prismatic joint: a cylindrical joint that cannot turn (5 equations).

    Coordinate ``translation`` along the axis, zero at the initial pose.
    """

    labels: tuple[str, ...] = ("axis f", "axis g", "offset f", "offset g", "twist")
    coordinate_names: tuple[str, ...] = ("translation",)

    def equations(self, ctx):
        twist = dot1(ctx, self.body1, self.f, self.body2, self.g)
        return ca.vertcat(*self._parallel_axes(ctx), *self._offsets(ctx), twist)


@dataclass
class Universal(_PointJoint):
    """Universal (Hooke) joint: a common point, ``axis1`` fixed on body1 stays perpendicular
    to ``axis2`` fixed on body2 (4 equations); the axes must be perpendicular initially."""

    axis1: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    axis2: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    labels: tuple[str, ...] = ("x", "y", "z", "cross")

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


@dataclass
class InLine(_AxisJoint):
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

    def equations(self, ctx):
        b1, b2, p = self.body1, self.body2, self.point
        return ca.vertcat(dot2(ctx, b1, self.f, p, b2, p), dot2(ctx, b1, self.g, p, b2, p))


@dataclass
class SpatialRigid(Joint):
    """Weld: body2 keeps its initial pose relative to body1 (6 equations)."""

    point: np.ndarray | None = None
    labels: tuple[str, ...] = ("x", "y", "z", "x.y", "x.z", "y.z")

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


@dataclass
class SpatialFixed(SpatialRigid):
    """Fix a body to the ground in its initial pose (a weld with ground as body1)."""
