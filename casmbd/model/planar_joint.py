"""Planar joint (space): body2 moves in a plane of body1, two translations and one rotation.

The plane passes through ``point`` normal to ``axis`` h (both global at the design pose, fixed
on body1); (f, g, h) is the right-handed triad of :func:`casmbd.model.spatial_joints.triad`, as
the cylindrical joint derives it, f and g spanning the plane.  Three equations over the basic
constraints of seed 001 ("Spatial joints"):

* dot-1 (f1, h2) = 0 and dot-1 (g1, h2) = 0: the axis fixed on body2 stays parallel to body1's
  (the two rotations out of the plane are locked);
* dot-2 (h1, d) = h1 · (r_P2 − r_P1) = 0: body2's point stays in body1's plane.

Coordinates, zero at the design pose: ``x`` = f1 · (r_P2 − r_P1), ``y`` = g1 · (r_P2 − r_P1)
(lengths along f and g fixed on body1) and ``angle``, the rotation of body2 relative to body1
about h (right-hand rule, wrapped to (−π, π]; its driver uses the wrapped residual of
:meth:`~casmbd.system.context.Context.angle_residual`).

In joint coordinates the tree motion of the child, in the design frame (see
:mod:`casmbd.system.tree`, x ↦ J₀ + Δd + ΔR (x − J₀)), is Δd = x f + y g, ΔR = Rot(h, angle),
ω_rel = h anglė: the joint point translates in the plane and the child turns about the axis
through the moved point (the URDF ``planar`` joint: origin, then the translation in the plane,
then the rotation about the axis).  Its three rates are independent, so the articulated-body
recursion applies.

This module is the whole kind: scene type ``"planar"`` (space only; keys ``point``, ``axis``)
and ``Mechanism.add("planar", name, body1, body2, point, axis)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.model.joints import axis_from_scene
from casmbd.model.registry import register_joint
from casmbd.model.spatial_joints import AxisJoint, body_point, body_vector


@register_joint
@dataclass
class Planar(AxisJoint):
    """Planar joint: body2 slides in body1's plane through ``point`` normal to ``axis`` and
    turns about the axis (3 equations, 3 degrees of freedom).

    Coordinates ``x``, ``y`` (along the in-plane directions ``f``, ``g`` fixed on body1) and
    ``angle`` (about the axis), all zero at the design pose.
    """

    labels: tuple[str, ...] = ("axis f", "axis g", "plane")
    coordinate_names: tuple[str, ...] = ("x", "y", "angle")

    kind = "planar"
    scene_keys = frozenset({"point", "axis"})
    drawing = "point"
    tree_joint = True
    from_scene = classmethod(axis_from_scene)

    def tree_layout(self) -> tuple[tuple[str, ...], tuple[bool, ...]]:
        return ("x", "y", "angle"), (True, True, False)

    def tree_motion(self, tree, q: ca.SX, v: ca.SX | None = None):
        """Δd = x f + y g, ΔR = Rot(h, angle), ω_rel = h anglė (design frame)."""
        h = np.asarray(self.axis, float)
        shift = q[0] * ca.DM(self.f) + q[1] * ca.DM(self.g)
        omega = ca.DM(h) * v[2] if v is not None else None
        return tree.rodrigues(h, q[2]), shift, omega

    def _offset(self, ctx) -> ca.SX:
        """r_P2 − r_P1, the body points at ``point``."""
        return body_point(ctx, self.body2, self.point) - body_point(ctx, self.body1, self.point)

    def equations(self, ctx) -> ca.SX:
        return ca.vertcat(*self._parallel_axes(ctx), self._translation(ctx))

    def coordinate(self, ctx, which: str | None = None) -> ca.SX:
        which = self._which(which)
        if which == "angle":
            return self._angle(ctx)
        direction = self.f if which == "x" else self.g
        return ca.dot(body_vector(ctx, self.body1, direction), self._offset(ctx))

    def driver_residual(self, ctx, target, which: str | None = None) -> ca.SX:
        if self._which(which) == "angle":
            return ctx.angle_residual(self.body1, self.body2, target, self.axis)
        return self.coordinate(ctx, which) - target
