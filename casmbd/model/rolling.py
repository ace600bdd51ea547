"""Rolling without slipping: the planar rolling disc, the knife edge and the rolling sphere.

Three joint kinds between a *support* ``body1`` (the ground, or any body carrying the line or
plane) and a *rolling* ``body2``; points and directions are global at the initial (design)
pose and turned into body-fixed vectors once, as for every joint.

``rolling_disc`` in the plane (``dimension = 2``)
    A disc of radius R (centre ``point``, on body2) rolls on the line through ``origin`` with
    unit normal ``normal`` (both on body1), on the side the normal points to.  In the plane the
    rolling condition integrates (the contact point's relative velocity along the line,
    (ṙ_c − ṙ_o)·t + R (ω₂ − ω₁) = 0, is d/dt of s + R (θ₂ − θ₁) with s = (r_c − r_o)·t the
    centre's abscissa along the line; Greenwood, *Advanced Dynamics*, 2003, §3.1), so both
    rows are position constraints (holonomic, no special need)::

        contact   (r_c − r_o)·n − R = 0
        rolling   R · wrap[(θ₂ − θ₁) − (θ₂ − θ₁)⁰ + (s − s⁰)/R] = 0

    with t = (n_y, −n_x) (rolling towards +t turns the disc clockwise about +z when n is
    +y) and ``wrap`` the residual of :meth:`~casmbd.system.context.Context.angle_residual`
    (exactly linear in the angles when they are coordinates, regular through any number of
    turns otherwise).  Coordinates: ``translation`` s − s⁰ and ``angle`` θ₂ − θ₁ (motors,
    springs, drivers and measures use them).  The spatial ``rolling_disc``
    (:mod:`casmbd.model.rolling_disc`) shares the scene keys (``point``, ``radius``,
    ``origin``, ``normal``; ``axis``, the axle, is the plane's normal z in 2-D: accepted when
    given along ±z).

``knife_edge`` (planar and spatial; Chaplygin's sleigh)
    The material point P of body2 (``point``) has no velocity, relative to body1, across the
    blade ``axis`` fixed on body2 (Neimark & Fufaev, *Dynamics of Nonholonomic Systems*,
    1972, ch. 1; Bloch, *Nonholonomic Mechanics and Control*, 2003, §1.7)::

        lateral   W = (v_P − v_P¹)·l = 0,   l = ⊥(A₂ ā)  (plane),   l = n₁ × A₂ ā  (space)

    v_P¹ the velocity of body1's material point at P; in space ``normal`` (body1, default
    +z) is the normal of the plane the blade slides on and l lies in that plane (|l| = 1
    while the blade lies in the plane; W is |n × a| times the lateral slip velocity
    otherwise).  One non-holonomic row.

``rolling_sphere`` (spatial)
    A sphere of radius R (centre ``point`` on body2) rolls on the plane through ``origin``
    with normal ``normal`` (on body1) without slipping; it may spin about the normal
    (Neimark & Fufaev ch. 3 §2; Routh's ball)::

        contact   (r_c − r_o)·n − R = 0                                (holonomic)
        slip_1    t₁·(ṙ_c − R ω₂ × n − v_P¹) = 0                        (non-holonomic)
        slip_2    t₂·(ṙ_c − R ω₂ × n − v_P¹) = 0

    P = r_c − R n the contact point, (t₁, t₂, n) a right-handed triad fixed on body1.

The non-holonomic rows use the velocity-row protocol of :class:`casmbd.system.equations.System`
(``velocity_equations``: W(q, v, t) affine in v for every row of the joint, zero on its
position rows; ``equations`` zero on its velocity rows); ``velocity_labels`` names the
velocity rows.  The kinds with velocity rows declare the need ``"velocity_constraints"``
(:mod:`casmbd.model.needs`).

This module is the three kinds: it registers ``"rolling_disc"`` (dimension 2),
``"knife_edge"`` (2 and 3) and ``"rolling_sphere"`` (3).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND, scalar, unit_vector, vector
from casmbd.model.joints import Joint
from casmbd.model.registry import register_joint

__all__ = ["KnifeEdge", "PlanarRollingDisc", "RollingSphere", "material_point",
           "material_velocity", "plane_triad"]

#: largest |(point − origin)·n − radius| accepted, relative to max(1, radius): the centre
#: given at the initial pose must be one radius above the plane (line)
HEIGHT_TOLERANCE = 1e-6


def material_velocity(ctx, body: str, at: ca.SX) -> ca.SX:
    """Global velocity of the material point of ``body`` that is at the global position ``at``
    (an expression): ṙ_G + ω × (at − r_G) (in the plane ω × r = ω (−r_y, r_x)); zero for the
    ground."""
    dim = ctx.dimension
    if body == GROUND:
        return ca.SX.zeros(dim)
    com = ctx.centre_of_mass(body)
    r = at - com
    omega = ctx.angular_velocity(body)
    turn = omega * ca.vertcat(-r[1], r[0]) if dim == 2 else ca.cross(omega, r)
    return ca.jtimes(com, ctx.q, ctx.v) + turn


def material_point(ctx, body: str, frozen: ca.SX) -> ca.SX:
    """Position of the material point of ``body`` that is at ``frozen`` (an expression frozen
    at the unperturbed pose, ``ctx.resolve``): r_G + A A₀ᵀ (frozen − r_G₀).  Written with a
    perturbed context (:meth:`~casmbd.system.context.Context.perturbed`) its derivative by the
    virtual displacement e = (δr_G, δθ) of ``body`` is δr_G + δθ × (frozen − r_G): the
    coefficients of the material point's velocity (the constant ``frozen`` for the ground)."""
    if body == GROUND:
        return frozen
    com, rot = ctx.centre_of_mass(body), ctx.rotation(body)
    local = ca.mtimes(ctx.resolve(rot).T, frozen - ctx.resolve(com))
    return com + ca.mtimes(rot, local)


def plane_triad(normal) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (t₁, t₂) of the plane with unit ``normal`` n, (t₁, t₂, n)
    right-handed; t₁ along the global axis least aligned with n, projected."""
    n = np.asarray(normal, float)
    trial = np.zeros(3)
    trial[int(np.argmin(np.abs(n)))] = 1.0
    t1 = trial - n * float(n @ trial)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def _positive_radius(value, where: str) -> float:
    radius = scalar(value, where)
    if radius <= 0.0:
        raise ModelError(f"{where}: must be > 0, got {radius}")
    return radius


def _check_height(name: str, point, origin, normal, radius: float) -> None:
    """The centre ``point`` must be one radius above the plane (line) at the initial pose."""
    height = float(np.dot(np.asarray(point) - np.asarray(origin), normal))
    if abs(height - radius) > HEIGHT_TOLERANCE * max(1.0, radius):
        raise ModelError(f"joint '{name}' field 'point': the centre is at height {height:.9g} "
                         f"above the plane through 'origin' along 'normal', but 'radius' is "
                         f"{radius:.9g} (put the centre one radius above the plane, on the "
                         "side the normal points to)")


def _moving(name: str, body2: str, what: str) -> None:
    """body2 is the rolling body: not the ground."""
    if body2 == GROUND:
        raise ModelError(f"joint '{name}' field 'body2': {what} must be a moving body (the "
                         "support, body1, may be the ground)")


def _planar_axis(name: str, axis) -> None:
    """A planar disc's axle is z: ``axis`` may be given, as a 3-vector along ±z."""
    if axis is None:
        return
    where = f"joint '{name}' field 'axis'"
    try:
        unit = unit_vector(axis, where, 3)
    except ModelError:
        raise ModelError(f"{where}: in the plane the axle is the z axis; give [0, 0, 1] (or "
                         f"omit it), got {axis!r}") from None
    if abs(abs(unit[2]) - 1.0) > 1e-9:
        raise ModelError(f"{where}: in the plane the axle must be along z ([0, 0, 1]), got "
                         f"{axis!r}")


def _support_frame(ctx, body: str, origin, normal):
    """(r_o, n) of the support line/plane fixed on ``body``, as expressions."""
    o = ctx.point(body, ctx.local(body, origin))
    n = ctx.direction(body, ctx.local_direction(body, normal))
    return o, n


@register_joint
@dataclass
class PlanarRollingDisc(Joint):
    """A disc rolling without slipping on a line in the plane (module docstring): two
    position rows, ``contact`` and ``rolling``; coordinates ``translation`` and ``angle``."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special (holonomic)
    needs: ClassVar[frozenset[str]] = frozenset()

    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    radius: float = 1.0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(2))
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))
    labels: tuple[str, ...] = ("contact", "rolling")
    coordinate_names: tuple[str, ...] = ("translation", "angle")

    kind = "rolling_disc"
    title = "rolling disc"
    dimensions = (2,)
    scene_keys = frozenset({"point", "axis", "radius", "origin", "normal"})

    @classmethod
    def create(cls, mech, name: str, body1: str, body2: str, point, axis=None, radius=None,
               origin=(0.0, 0.0), normal=(0.0, 1.0)) -> PlanarRollingDisc:
        """Check the fields (naming the joint and the field) and build the joint; the
        arguments are in the order of the spatial ``rolling_disc`` (``axis`` optional here:
        give ``radius`` by keyword)."""
        mech._new_joint(name, body1, body2)
        _moving(name, body2, "the disc")
        _planar_axis(name, axis)
        if radius is None:
            raise ModelError(f"joint '{name}' field 'radius': missing")
        return cls(name, body1, body2, point=point, radius=radius, origin=origin,
                   normal=normal)

    @classmethod
    def from_scene(cls, mech, e) -> PlanarRollingDisc:
        name = e.string("name")
        axis = e.vector("axis", 3, required=False) if e.has("axis") else None
        return mech.add("rolling_disc", name, e.string("body1"), e.string("body2"),
                        e.vector("point", 2), axis, e.number("radius"),
                        origin=e.vector("origin", 2, default=[0.0, 0.0]),
                        normal=e.vector("normal", 2, default=[0.0, 1.0]))

    def __post_init__(self):
        where = f"joint '{self.name}' field"
        self.point = vector(self.point, f"{where} 'point'", 2)
        self.origin = vector(self.origin, f"{where} 'origin'", 2)
        self.normal = unit_vector(self.normal, f"{where} 'normal'", 2)
        self.radius = _positive_radius(self.radius, f"{where} 'radius'")
        _check_height(self.name, self.point, self.origin, self.normal, self.radius)

    @property
    def tangent(self) -> np.ndarray:
        """t = (n_y, −n_x) at the initial pose: the direction of rolling."""
        return np.array([self.normal[1], -self.normal[0]])

    def _abscissa(self, ctx) -> tuple[ca.SX, ca.SX]:
        """(height (r_c − r_o)·n, abscissa change (r_c − r_o)·t − s⁰)."""
        o, n = _support_frame(ctx, self.body1, self.origin, self.normal)
        c = ctx.point(self.body2, ctx.local(self.body2, self.point))
        d = c - o
        t = ca.vertcat(n[1], -n[0])
        s0 = float(np.dot(self.point - self.origin, self.tangent))
        return ca.dot(d, n), ca.dot(d, t) - s0

    def _start(self, ctx) -> float:
        return float(ctx.initial_angle(self.body2) - ctx.initial_angle(self.body1))

    def equations(self, ctx) -> ca.SX:
        height, ds = self._abscissa(ctx)
        target = self._start(ctx) - ds / self.radius
        return ca.vertcat(height - self.radius,
                          self.radius * ctx.angle_residual(self.body1, self.body2, target))

    def initial_coordinate(self, ctx, which: str | None = None) -> float:
        return self._start(ctx) if self._which(which) == "angle" else 0.0

    def coordinate(self, ctx, which: str | None = None) -> ca.SX:
        if self._which(which) == "angle":
            return ctx.relative_angle(self.body1, self.body2)
        return self._abscissa(ctx)[1]

    def driver_residual(self, ctx, target, which: str | None = None) -> ca.SX:
        if self._which(which) == "angle":
            return ctx.angle_residual(self.body1, self.body2, target)
        return self.coordinate(ctx, which) - target

    def reaction_point(self) -> np.ndarray:
        """The centre (the reaction's moment is about it, as for the spatial disc)."""
        return self.point


@register_joint
@dataclass
class KnifeEdge(Joint):
    """A knife edge (Chaplygin's sleigh): no velocity of body2's point across its blade,
    relative to body1 (module docstring); one non-holonomic row, ``lateral``."""
    #: what it needs from an analysis (casmbd.model.needs): a velocity row
    needs: ClassVar[frozenset[str]] = frozenset({"velocity_constraints"})

    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0]))
    normal: np.ndarray | None = None
    dimension: int = 2
    labels: tuple[str, ...] = ("lateral",)

    kind = "knife_edge"
    title = "knife edge"
    dimensions = (2, 3)
    scene_keys = frozenset({"point", "axis", "normal"})
    #: labels of the rows written by :meth:`velocity_equations` (non-holonomic)
    velocity_labels: ClassVar[tuple[str, ...]] = ("lateral",)

    @classmethod
    def create(cls, mech, name: str, body1: str, body2: str, point, axis,
               normal=None) -> KnifeEdge:
        """Check the fields (naming the joint and the field) and build the joint."""
        mech._new_joint(name, body1, body2)
        _moving(name, body2, "the body carrying the blade")
        if mech.dimension == 2 and normal is not None:
            raise ModelError(f"joint '{name}' field 'normal': a planar knife edge slides in "
                             "the plane (no normal to give)")
        return cls(name, body1, body2, point=point, axis=axis,
                   normal=None if mech.dimension == 2 else
                   (normal if normal is not None else (0.0, 0.0, 1.0)),
                   dimension=mech.dimension)

    @classmethod
    def from_scene(cls, mech, e) -> KnifeEdge:
        dim = mech.dimension
        name = e.string("name")
        normal = e.vector("normal", dim, required=False) if e.has("normal") else None
        return mech.add("knife_edge", name, e.string("body1"), e.string("body2"),
                        e.vector("point", dim), e.vector("axis", dim), normal=normal)

    def __post_init__(self):
        where = f"joint '{self.name}' field"
        dim = self.dimension
        self.point = vector(self.point, f"{where} 'point'", dim)
        self.axis = unit_vector(self.axis, f"{where} 'axis'", dim)
        if dim == 3:
            self.normal = unit_vector(self.normal, f"{where} 'normal'", 3)
            if np.linalg.norm(np.cross(self.normal, self.axis)) < 1e-6:
                raise ModelError(f"{where} 'axis': the blade is along the plane's normal "
                                 f"{self.normal.tolist()} (it has no sideways direction in "
                                 "the plane)")

    def equations(self, ctx) -> ca.SX:
        return ca.SX.zeros(1)

    def velocity_equations(self, ctx) -> ca.SX:
        """W = (v_P − v_P¹)·l, affine in v (the rows C_q v + C_t of W = 0)."""
        p = ctx.point(self.body2, ctx.local(self.body2, self.point))
        rel = ca.jtimes(p, ctx.q, ctx.v) - material_velocity(ctx, self.body1, p)
        return ca.dot(rel, self._lateral(ctx))

    def _lateral(self, ctx) -> ca.SX:
        a = ctx.direction(self.body2, ctx.local_direction(self.body2, self.axis))
        if self.dimension == 2:
            return ca.vertcat(-a[1], a[0])
        n = ctx.direction(self.body1, ctx.local_direction(self.body1, self.normal))
        return ca.cross(n, a)

    def virtual_equations(self, ctx) -> ca.SX:
        """l₀·(X₂ − X₁): X_i the material point of body i at P, l and P frozen at the
        unperturbed pose; its derivative by a virtual rigid displacement of either body is the
        coefficient of that body's twist in W (the joint reactions' virtual work)."""
        p = ctx.point(self.body2, ctx.local(self.body2, self.point))
        moved = p - material_point(ctx, self.body1, ctx.resolve(p))
        return ca.dot(ctx.resolve(self._lateral(ctx)), moved)

    def reaction_point(self) -> np.ndarray:
        return self.point


@register_joint
@dataclass
class RollingSphere(Joint):
    """A sphere rolling without slipping on a plane (module docstring): the holonomic row
    ``contact`` and the non-holonomic rows ``slip_1``, ``slip_2``."""
    #: what it needs from an analysis (casmbd.model.needs): two velocity rows
    needs: ClassVar[frozenset[str]] = frozenset({"velocity_constraints"})

    point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    radius: float = 1.0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    labels: tuple[str, ...] = ("contact", "slip_1", "slip_2")

    kind = "rolling_sphere"
    title = "rolling sphere"
    dimensions = (3,)
    scene_keys = frozenset({"point", "radius", "origin", "normal"})
    #: labels of the rows written by :meth:`velocity_equations` (non-holonomic)
    velocity_labels: ClassVar[tuple[str, ...]] = ("slip_1", "slip_2")

    @classmethod
    def create(cls, mech, name: str, body1: str, body2: str, point, radius,
               origin=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)) -> RollingSphere:
        """Check the fields (naming the joint and the field) and build the joint."""
        mech._new_joint(name, body1, body2)
        _moving(name, body2, "the sphere")
        return cls(name, body1, body2, point=point, radius=radius, origin=origin,
                   normal=normal)

    @classmethod
    def from_scene(cls, mech, e) -> RollingSphere:
        name = e.string("name")
        return mech.add("rolling_sphere", name, e.string("body1"), e.string("body2"),
                        e.vector("point", 3), e.number("radius"),
                        origin=e.vector("origin", 3, default=[0.0, 0.0, 0.0]),
                        normal=e.vector("normal", 3, default=[0.0, 0.0, 1.0]))

    def __post_init__(self):
        where = f"joint '{self.name}' field"
        self.point = vector(self.point, f"{where} 'point'", 3)
        self.origin = vector(self.origin, f"{where} 'origin'", 3)
        self.normal = unit_vector(self.normal, f"{where} 'normal'", 3)
        self.radius = _positive_radius(self.radius, f"{where} 'radius'")
        _check_height(self.name, self.point, self.origin, self.normal, self.radius)

    def _centre(self, ctx) -> ca.SX:
        return ctx.point(self.body2, ctx.local(self.body2, self.point))

    def equations(self, ctx) -> ca.SX:
        o, n = _support_frame(ctx, self.body1, self.origin, self.normal)
        return ca.vertcat(ca.dot(self._centre(ctx) - o, n) - self.radius, ca.SX.zeros(2))

    def velocity_equations(self, ctx) -> ca.SX:
        """(0, t₁·v_slip, t₂·v_slip), v_slip = ṙ_c − R ω₂ × n − v_P¹ (the contact point's
        velocity relative to the support), affine in v."""
        n = ctx.direction(self.body1, ctx.local_direction(self.body1, self.normal))
        c = self._centre(ctx)
        contact = c - self.radius * n
        slip = (ca.jtimes(c, ctx.q, ctx.v)
                - self.radius * ca.cross(ctx.angular_velocity(self.body2), n)
                - material_velocity(ctx, self.body1, contact))
        t1, t2 = (ctx.direction(self.body1, ctx.local_direction(self.body1, t))
                  for t in plane_triad(self.normal))
        return ca.vertcat(ca.SX(0.0), ca.dot(t1, slip), ca.dot(t2, slip))

    def virtual_equations(self, ctx) -> ca.SX:
        """The contact row and t_k₀·(X₂ − X₁), X_i the material point of body i at the contact
        point P = r_c − R n (P, t_k frozen at the unperturbed pose): their derivatives by a
        virtual rigid displacement are the coefficients of the rows (the joint reactions)."""
        o, n = _support_frame(ctx, self.body1, self.origin, self.normal)
        c = self._centre(ctx)
        contact = ctx.resolve(c - self.radius * n)
        moved = material_point(ctx, self.body2, contact) - \
            material_point(ctx, self.body1, contact)
        rows = [ca.dot(c - o, n) - self.radius]
        for t in plane_triad(self.normal):
            rows.append(ca.dot(ctx.resolve(ctx.direction(
                self.body1, ctx.local_direction(self.body1, t))), moved))
        return ca.vertcat(*rows)

    def reaction_point(self) -> np.ndarray:
        """The centre (the reaction's moment is about it, as for the spatial disc)."""
        return self.point
