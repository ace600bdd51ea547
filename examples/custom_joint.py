"""A user-defined joint kind, registered from user code: a planar *point-on-line* joint.

The point of body2 that is at ``point`` in the design pose stays on the line of body1 through
``point`` along ``axis`` (one equation, n₁ · (r_P2 − r_P1) = 0 with n₁ the line's normal fixed
on body1): a massless slider.  Everything about the kind is in the class below: its scene type
name and keys, how it is built from a scene entry, and its equation written with the context's
helpers (``ctx.point``, ``ctx.direction``, ``ctx.local``, ``ctx.local_direction``), which is
all it takes to work in absolute, natural and joint coordinates (in joint coordinates a kind
that is not a tree joint closes a loop and keeps its equation).

The demonstration: a slider-crank whose slider is massless — a crank pinned to the ground, a
connecting rod pinned to the crank, its far end on the horizontal line y = 0 — released from
rest under gravity, built once from Python (``Mechanism.add``) and once from a scene string,
in every coordinate choice.

Run it with ``python examples/custom_joint.py``; ``tests/model/test_custom_kind.py`` runs it too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

import casmbd
from casmbd.errors import ModelError
from casmbd.model import Joint, register_joint
from casmbd.model.bodies import vector2


@register_joint(replace=True)  # replace: the script may be run twice in one session
@dataclass
class PointOnLine(Joint):
    """Planar point-on-line joint (1 equation, 2 degrees of freedom left between the bodies)."""

    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0]))
    labels: tuple[str, ...] = ("normal",)

    kind = "point_on_line"          # [[joints]] type = "point_on_line"
    title = "point-on-line"          # its name in messages
    dimensions = (2,)               # planar only
    scene_keys = frozenset({"point", "axis"})
    drawing = "point"               # drawn as a pin at ``point``

    def __post_init__(self):
        self.point = vector2(self.point, f"joint '{self.name}' field 'point'")
        axis = vector2(self.axis, f"joint '{self.name}' field 'axis'")
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise ModelError(f"joint '{self.name}' field 'axis': must not be the zero vector")
        self.axis = axis / norm

    # Joint.create (the default: unique name, two known distinct bodies, then the class) builds
    # it for ``mech.add("point_on_line", name, body1, body2, point=..., axis=...)``.

    @classmethod
    def from_scene(cls, mech, e):
        """Read one [[joints]] entry: body1, body2, point, axis (default along x)."""
        name = e.string("name")
        b1, b2 = e.string("body1"), e.string("body2")
        return mech.add("point_on_line", name, b1, b2, point=e.vector("point", 2),
                        axis=e.vector("axis", 2, default=[1.0, 0.0]))

    def equations(self, ctx):
        p1 = ctx.point(self.body1, ctx.local(self.body1, self.point))
        p2 = ctx.point(self.body2, ctx.local(self.body2, self.point))
        axis = ctx.direction(self.body1, ctx.local_direction(self.body1, self.axis))
        return ca.dot(ca.vertcat(-axis[1], axis[0]), p2 - p1)


CRANK, ROD, ANGLE = 1.0, 2.0, math.pi / 3
A = (CRANK * math.cos(ANGLE), CRANK * math.sin(ANGLE))      # crank pin
B = (A[0] + math.sqrt(ROD**2 - A[1] ** 2), 0.0)             # rod end on the line y = 0
ROD_ANGLE = math.atan2(B[1] - A[1], B[0] - A[0])

SCENE = f"""
[scene]
name = "massless_slider_{{coordinates}}"
gravity = [0.0, -9.81]
coordinates = "{{coordinates}}"

[[bodies]]
name = "crank"
mass = 1.0
inertia = {CRANK**2 / 12}
position = [{A[0] / 2}, {A[1] / 2}]
angle = {ANGLE}

[[bodies]]
name = "rod"
mass = 2.0
inertia = {2.0 * ROD**2 / 12}
position = [{(A[0] + B[0]) / 2}, {(A[1] + B[1]) / 2}]
angle = {ROD_ANGLE}

[[joints]]
name = "pivot"
type = "revolute"
body1 = "ground"
body2 = "crank"
point = [0.0, 0.0]

[[joints]]
name = "pin"
type = "revolute"
body1 = "crank"
body2 = "rod"
point = [{A[0]}, {A[1]}]

[[joints]]
name = "slide"
type = "point_on_line"
body1 = "ground"
body2 = "rod"
point = [{B[0]}, {B[1]}]
axis = [1.0, 0.0]
"""


def from_python(coordinates: str) -> casmbd.Mechanism:
    """The same mechanism as :data:`SCENE`, from Python with the generic ``Mechanism.add``."""
    m = casmbd.Mechanism(f"massless_slider_{coordinates}", gravity=(0.0, -9.81),
                         coordinates=coordinates)
    m.add_body("crank", mass=1.0, inertia=CRANK**2 / 12, position=(A[0] / 2, A[1] / 2),
               angle=ANGLE)
    m.add_body("rod", mass=2.0, inertia=2.0 * ROD**2 / 12,
               position=((A[0] + B[0]) / 2, (A[1] + B[1]) / 2), angle=ROD_ANGLE)
    m.add_revolute("pivot", "ground", "crank", point=(0.0, 0.0))
    m.add_revolute("pin", "crank", "rod", point=A)
    m.add("point_on_line", "slide", "ground", "rod", point=B, axis=(1.0, 0.0))
    return m


def rod_end_height(result) -> np.ndarray:
    """y of the rod's end B along the result (it should stay 0)."""
    pos = result["body_positions"][:, 2:4]
    th = result["angle_positions"][:, 1]
    half = ROD / 2
    return pos[:, 1] + half * np.sin(th)


def main(t_end: float = 1.0, steps: int = 100) -> dict:
    """Simulate both builds in every coordinate choice; print and return the results."""
    out = {}
    for coordinates in ("absolute", "natural", "joint"):
        for source in ("python", "scene"):
            mech = (from_python(coordinates) if source == "python"
                    else casmbd.loads_scene(SCENE.format(coordinates=coordinates)))
            res = casmbd.simulate(mech, t_end=t_end, steps=steps, rtol=1e-11)
            out[coordinates, source] = res
            print(f"{coordinates:>9} {source:>6}: crank angle at {t_end} s "
                  f"{res['angle_positions'][-1, 0]:+.9f} rad, |y_B| <= "
                  f"{np.max(np.abs(rod_end_height(res))):.1e} m, energy drift "
                  f"{np.ptp(res['total_energy']):.1e} J")
    return out


if __name__ == "__main__":
    main()
