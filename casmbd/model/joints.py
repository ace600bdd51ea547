"""Planar joints: holonomic constraint equations C(q) = 0 between two bodies.

Each joint is defined at the initial (design) configuration by global points and axes, which
are turned into body-fixed vectors once, then written as CasADi expressions of the coordinates.
The constraint equations follow seed 000, "Kinematic constraints" (revolute joint eq. 6.96:
R_i + A_i u_i^P − R_j − A_j u_j^P = 0; prismatic joint: relative angle and a normal distance).
Every equation carries a label so that residuals and redundancies can be named.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import scalar, vector, vector2

JOINT_TYPES = ("revolute", "prismatic", "rigid", "distance", "fixed")


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

    @property
    def has_coordinate(self) -> bool:
        """True when the joint defines at least one joint coordinate."""
        return bool(self.coordinate_names)

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


@dataclass
class Revolute(Joint):
    """Pin joint at a global point; coordinate θ2 − θ1 (continuous)."""

    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    labels: tuple[str, ...] = ("x", "y")
    coordinate_names: tuple[str, ...] = ("angle",)

    def __post_init__(self):
        self.point = vector2(self.point, f"joint '{self.name}' field 'point'")

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


@dataclass
class Prismatic(Joint):
    """Translational joint along ``axis`` (global at the initial pose) through ``point``.

    Equations: the relative angle stays at its initial value and the normal component of the
    vector from body1's joint point to body2's vanishes.  Coordinate: the component along the
    axis (zero at the initial pose).
    """

    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0]))
    labels: tuple[str, ...] = ("angle", "normal")
    coordinate_names: tuple[str, ...] = ("translation",)

    def __post_init__(self):
        self.point = vector2(self.point, f"joint '{self.name}' field 'point'")
        axis = vector2(self.axis, f"joint '{self.name}' field 'axis'")
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise ModelError(f"joint '{self.name}' field 'axis': must not be the zero vector")
        self.axis = axis / norm

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


@dataclass
class Rigid(Joint):
    """Weld: body2 keeps its initial pose relative to body1 (three equations)."""

    point: np.ndarray | None = None
    labels: tuple[str, ...] = ("x", "y", "angle")

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


@dataclass
class Fixed(Rigid):
    """Fix a body to the ground at its initial pose (a weld with ground as body1)."""


@dataclass
class Distance(Joint):
    """Massless link of fixed length between point1 on body1 and point2 on body2.

    Equation (|d|² − L²)/(2L) = 0, scaled so that the residual is a length; coordinate |d|.
    """

    point1: np.ndarray = field(default_factory=lambda: np.zeros(2))
    point2: np.ndarray = field(default_factory=lambda: np.zeros(2))
    length: float | None = None
    labels: tuple[str, ...] = ("length",)
    coordinate_names: tuple[str, ...] = ("length",)
    dimension: int = 2

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
