"""Rolling disc in space: a thin wheel of body2 rolls without slipping on a plane of body1.

The wheel is a disc of radius R about its centre c (the point of body2 at ``point`` at the
initial pose) with axle unit vector a (fixed on body2, ``axis``); the plane passes through O
(``origin``) with unit normal n (``normal``), both fixed on body1 (the ground, or a moving
body carrying the plane: a treadmill, a platform).  The downward in-plane direction of the
disc and its lowest point are

    w = n − (n·a) a,   u = w / |w|,   P = c − R u,

|w| = √(1 − (n·a)²) = cos φ, φ the lean of the disc from the upright (Neimark & Fufaev,
*Dynamics of Nonholonomic Systems*, AMS 1972; O'Reilly, "The dynamics of rolling disks and
sliding disks", Nonlinear Dynamics 10 (1996) 287–305).  The joint has three rows:

* ``contact`` (holonomic): the lowest point lies on the plane, n·(P − O) = n·(c − O) − R |w| = 0;
* ``longitudinal`` and ``lateral`` (non-holonomic, :meth:`RollingDisc.velocity_equations`):
  the material point of the wheel at P does not slip on body1,

      W = T (v₂(P) − v₁(P)) = 0,   v_i(P) = ṙ_Gi + ω_i × (P − r_Gi)   (v₂(P) = ṙ_c − R ω₂ × u),

  with the tangent basis t₁ = (a × n)/|a × n| (the direction of rolling: +x for an axle along
  +y on a plane of normal +z) and t₂ = n × t₁ (lateral, the axle's projection on the plane).

The velocity rows (named by ``velocity_labels``) are affine in the velocities and not
integrable; their position rows are 0 and the system takes C_q = ∂W/∂v, C_t = W(v = 0) on them
(:meth:`casmbd.system.equations.System._velocity_rows`); the velocity of the contact row is
n·(v₂(P) − v₁(P)) as well (the gap rate of the lowest point equals the normal velocity of the
material point there), so the three multipliers are the components of one contact force at P:
with Q = −C_qᵀ λ, the force of body1 on the wheel is

    F = −(λ_contact n + λ_longitudinal t₁ + λ_lateral t₂),

its normal load N = −λ_contact and its tyre forces F_long = −λ_longitudinal,
F_lat = −λ_lateral.  The joint's reaction (the action of
body1 on body2) is reported at the wheel centre: the force F and the moment (P − c) × F.

The kind declares ``needs = {"velocity_constraints"}``: an analysis that cannot take
non-holonomic rows refuses it by name (:mod:`casmbd.model.needs`).  It is never a tree joint: in
joint coordinates the wheel is a floating body (or hangs on a tree) and the three rows close
the loop, as in absolute coordinates.

Scene keys (``[[joints]] type = "rolling_disc"``): ``body1`` (``"ground"`` or the body carrying
the plane), ``body2`` (the wheel), ``point`` (wheel centre, global at the initial pose),
``axis`` (axle direction, global at the initial pose), ``radius``, ``origin`` (a point of the
plane, default [0, 0, 0]) and ``normal`` (the plane's normal, pointing to the wheel's side;
default [0, 0, 1], as the rolling sphere's).
Directions are normalised; the zero vector, an axle along the normal (a disc lying flat on
the plane: the lowest point is undefined), a radius ≤ 0 and a centre that is not at the
height R cos φ above the plane (the gap is stated) are refused by name.
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

__all__ = ["FLAT_TOLERANCE", "GAP_TOLERANCE", "RollingDisc"]

#: smallest |a × n| (sine of the angle between axle and normal) of a disc that is not flat
FLAT_TOLERANCE = 1e-6
#: largest gap |n·(P − O)| at the initial pose, relative to the radius
GAP_TOLERANCE = 1e-6


def _dm(value) -> ca.DM:
    return ca.DM(np.asarray(value, float))


@register_joint
@dataclass
class RollingDisc(Joint):
    """A thin wheel of ``body2`` rolling without slipping on a plane of ``body1`` (module
    docstring: equations, multipliers and keys)."""

    #: what it needs from an analysis (casmbd.model.needs): non-holonomic rows
    needs: ClassVar[frozenset[str]] = frozenset({"velocity_constraints"})

    point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    radius: float = 1.0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    labels: tuple[str, ...] = ("contact", "longitudinal", "lateral")

    kind = "rolling_disc"
    title = "rolling disc"
    dimensions = (3,)
    scene_keys = frozenset({"point", "axis", "radius", "origin", "normal"})
    drawing = "point"

    #: the rows that are velocity rows (the others are position rows)
    velocity_labels: ClassVar[tuple[str, ...]] = ("longitudinal", "lateral")

    # ------------------------------------------------------------------ construction
    @classmethod
    def create(cls, mech, name: str, body1: str, body2: str, point, axis, radius: float,
               origin=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)) -> RollingDisc:
        """``mech.add("rolling_disc", name, body1, body2, point, axis, radius, origin,
        normal)``: check the bodies (body2, the wheel, is not the ground) and the geometry."""
        mech._new_joint(name, body1, body2)
        if body2 == GROUND:
            raise ModelError(f"joint '{name}' field 'body2': the wheel must be a moving body, "
                             "not the ground (body1 carries the plane)")
        return cls(name, body1, body2, point=point, axis=axis, radius=radius, origin=origin,
                   normal=normal)

    @classmethod
    def from_scene(cls, mech, e) -> RollingDisc:
        name = e.string("name")
        return mech.add("rolling_disc", name, e.string("body1"), e.string("body2"),
                        point=e.vector("point", 3), axis=e.vector("axis", 3),
                        radius=e.number("radius"),
                        origin=e.vector("origin", 3, default=[0.0, 0.0, 0.0]),
                        normal=e.vector("normal", 3, default=[0.0, 0.0, 1.0]))

    def __post_init__(self):
        where = f"joint '{self.name}' field"
        self.point = vector(self.point, f"{where} 'point'", 3)
        self.origin = vector(self.origin, f"{where} 'origin'", 3)
        self.axis = unit_vector(self.axis, f"{where} 'axis'", 3)
        self.normal = unit_vector(self.normal, f"{where} 'normal'", 3)
        self.radius = scalar(self.radius, f"{where} 'radius'")
        if not self.radius > 0.0:
            raise ModelError(f"{where} 'radius': must be > 0, got {self.radius:g}")
        sine = float(np.linalg.norm(np.cross(self.axis, self.normal)))
        if sine < FLAT_TOLERANCE:
            raise ModelError(f"{where} 'axis': the axle {self.axis.tolist()} is along the "
                             f"plane's normal {self.normal.tolist()} (|a × n| = {sine:.3g}): "
                             "a disc lying flat on the plane has no lowest point")
        height = float(self.normal @ (self.point - self.origin))
        gap = height - self.radius * sine
        if abs(gap) > GAP_TOLERANCE * self.radius:
            raise ModelError(
                f"{where} 'point': the wheel centre is {height:.6g} above the plane, not "
                f"R cos(lean) = {self.radius * sine:.6g} (radius {self.radius:g}, lean "
                f"{np.degrees(np.arccos(min(1.0, sine))):.4g} deg): the lowest point is "
                f"{gap:.3g} {'above' if gap > 0 else 'below'} the plane (tolerance "
                f"{GAP_TOLERANCE:g} R)")

    # ------------------------------------------------------------------ geometry
    def frame(self, ctx) -> dict[str, ca.SX]:
        """The contact geometry written with ``ctx``: wheel centre ``c``, axle ``a``, plane
        normal ``n`` and origin ``O`` (fixed on body1), downward direction ``u``, lowest point
        ``P``, tangents ``t1`` (longitudinal) and ``t2`` (lateral), and ``cos_lean`` = |w|."""
        b1, b2 = self.body1, self.body2
        c = ctx.point(b2, ctx.local(b2, self.point))
        a = ctx.direction(b2, ctx.local_direction(b2, self.axis))
        n = ctx.direction(b1, ctx.local_direction(b1, self.normal))
        o = ctx.point(b1, ctx.local(b1, self.origin))
        w = n - ca.dot(n, a) * a
        size = ca.sqrt(ca.dot(w, w))
        u = w / size
        t1 = ca.cross(a, n)
        t1 = t1 / ca.sqrt(ca.dot(t1, t1))
        return {"c": c, "a": a, "n": n, "O": o, "u": u, "P": c - self.radius * u,
                "t1": t1, "t2": ca.cross(n, t1), "cos_lean": size}

    def _slip(self, ctx, geo) -> ca.SX:
        """v₂(P) − v₁(P): the velocity of the wheel's material point at P relative to body1's."""
        b1, b2 = self.body1, self.body2
        vel = ca.jtimes(geo["c"], ctx.q, ctx.v) + \
            ca.cross(ctx.angular_velocity(b2), geo["P"] - geo["c"])
        if b1 != GROUND:
            g1 = ctx.centre_of_mass(b1)
            vel = vel - ca.jtimes(g1, ctx.q, ctx.v) - \
                ca.cross(ctx.angular_velocity(b1), geo["P"] - g1)
        return vel

    # ------------------------------------------------------------------ equations
    def equations(self, ctx) -> ca.SX:
        """C: the contact row n·(P − O) and zeros on the two velocity rows."""
        geo = self.frame(ctx)
        return ca.vertcat(ca.dot(geo["n"], geo["P"] - geo["O"]), 0.0, 0.0)

    def velocity_equations(self, ctx) -> ca.SX:
        """W(q, v) = (0, t₁·s, t₂·s), s = v₂(P) − v₁(P): the non-holonomic rows (0 on the
        holonomic contact row, which the system differentiates itself)."""
        geo = self.frame(ctx)
        slip = self._slip(ctx, geo)
        return ca.vertcat(0.0, ca.dot(geo["t1"], slip), ca.dot(geo["t2"], slip))

    def virtual_equations(self, ctx) -> ca.SX:
        """Rows whose derivatives by a virtual rigid displacement e of one body
        (:meth:`casmbd.system.context.Context.perturbed`) are the constraint's virtual work:
        the contact row, and t_k·(X₂ − X₁) with X_i the material point of body i at the contact
        point, P and t_k frozen at e = 0 (``ctx.resolve``) — ∂/∂e gives t_k·(δr_G + δθ × (P −
        r_G)), the coefficients of the velocity rows.  Used by the joint reactions."""
        geo = self.frame(ctx)
        frozen_p = ctx.resolve(geo["P"])
        rows = [ca.dot(geo["n"], geo["P"] - geo["O"])]
        moved = self._material(ctx, self.body2, frozen_p)
        if self.body1 != GROUND:
            moved = moved - self._material(ctx, self.body1, frozen_p)
        for key in ("t1", "t2"):
            rows.append(ca.dot(ctx.resolve(geo[key]), moved))
        return ca.vertcat(*rows)

    @staticmethod
    def _material(ctx, body: str, frozen_point: ca.SX) -> ca.SX:
        """Position of the material point of ``body`` at ``frozen_point`` (its body-frame
        coordinates frozen at e = 0, its pose that of ``ctx``)."""
        g, rot = ctx.centre_of_mass(body), ctx.rotation(body)
        local = ca.mtimes(ctx.resolve(rot).T, frozen_point - ctx.resolve(g))
        return g + ca.mtimes(rot, local)

    def reaction_point(self) -> np.ndarray:
        """The wheel centre (the reaction's moment is about it)."""
        return self.point
