"""Gear (coupler): one joint coordinate follows another, c₂ − c₂⁰ = r (c₁ − c₁⁰) + δ.

A gear pair, a belt, a rack and pinion (a revolute angle and a prismatic translation) or a
lead screw couple two joint coordinates linearly.  The constraint is holonomic and written with
the joints' own coordinates (:meth:`casmbd.model.joints.Joint.coordinate`), measured from their
values at the design pose c⁰ (:meth:`~casmbd.model.joints.Joint.initial_coordinate`), so one
equation serves every coordinate choice: absolute and natural coordinates write it on the
bodies' coordinates, joint coordinates on the tree coordinates (where it closes a loop like a
loop joint; it is never a tree joint itself) — unless both joints are single-coordinate tree
joints (revolute or prismatic, ratio and offset numbers): joint coordinates then substitute the
second joint's coordinate, r (c₁ − c₁⁰) + δ, and write no equation
(:func:`casmbd.system.tree.substitute_mimics`; ``mechanism.substitute_gears = False`` keeps it).

The offset δ (default 0; URDF ``<mimic offset>``, θ_follower = multiplier θ_leader + offset) is
the value of c₂ − c₂⁰ when c₁ = c₁⁰.  With δ ≠ 0 the design pose violates the equation: a
simulation or a static analysis assembles the start (Newton on C(q) = 0 from the design pose,
both joints moving), unless the initial state already satisfies it (the tree joint's initial
coordinate in joint coordinates, the bodies' start poses in absolute and natural ones, as
:func:`casmbd.io.urdf.load_urdf` sets them).

The multiplier λ of C = (c₂ − c₂⁰) − r (c₁ − c₁⁰) − δ enters the equations of motion as
Q = −C_qᵀ λ: a generalized force −λ along c₂ and +r λ along c₁.  The reaction reported for the
gear is the action on the second joint's moving body at that joint's point: a pure moment −λ
about a revolute joint (a pure force −λ along a prismatic axis), force components zero.

This module is the whole kind: it registers itself as scene type ``"gear"``
(keys ``joint1``, ``joint2``, ``ratio``, optional ``offset`` (default 0) and
``coordinate1``/``coordinate2`` for a cylindrical joint) and as ``Mechanism.add("gear", ...)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND, scalar
from casmbd.model.joints import Joint
from casmbd.model.registry import register_joint


@register_joint
@dataclass
class Gear(Joint):
    """c₂ − c₂⁰ = ratio (c₁ − c₁⁰) + offset between coordinates of ``joint1`` and ``joint2``.

    ``body1`` and ``body2`` are the moving bodies of the two joints (the second body of each
    unless it is the ground); :attr:`bodies` lists every body whose pose enters the equation.
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    joint1: str = ""
    joint2: str = ""
    ratio: float = 1.0
    offset: float = 0.0
    coordinate1: str | None = None
    coordinate2: str | None = None
    involved: tuple[str, ...] = ()
    point: np.ndarray | None = None
    labels: tuple[str, ...] = ("ratio",)

    kind = "gear"
    dimensions = (2, 3)
    scene_common = frozenset({"name", "type", "description"})
    scene_keys = frozenset({"joint1", "joint2", "ratio", "coordinate1", "coordinate2",
                            "offset"})
    drawing = "none"

    @property
    def bodies(self) -> tuple[str, ...]:
        return self.involved

    @classmethod
    def create(cls, mech, name: str, joint1: str, joint2: str, ratio: float = 1.0,
               coordinate1: str | None = None, coordinate2: str | None = None,
               offset: float = 0.0) -> Gear:
        """Check both joints exist and have the named coordinates, ratio ≠ 0 and a finite
        offset."""
        mech._unique(mech.joints, "joint", name)
        where = f"joint '{name}' field"
        pair = []
        for key, jname, coord in (("joint1", joint1, coordinate1),
                                  ("joint2", joint2, coordinate2)):
            joint = mech._joint(jname, f"{where} '{key}'")
            if coord is not None and coord not in joint.coordinate_names:
                raise ModelError(f"{where} 'coordinate{key[-1]}': joint '{jname}' has "
                                 f"coordinates {', '.join(joint.coordinate_names)}, not "
                                 f"{coord!r}")
            pair.append(joint)
        if joint1 == joint2 and coordinate1 == coordinate2:
            raise ModelError(f"{where} 'joint2': the gear couples coordinate of joint "
                             f"'{joint1}' with itself")
        ratio = scalar(ratio, f"{where} 'ratio'")
        if ratio == 0.0:
            raise ModelError(f"{where} 'ratio': must not be 0 (a gear with ratio 0 is a "
                             "lock: drive the second joint instead)")
        offset = scalar(offset, f"{where} 'offset'")
        first, second = pair
        moving1 = first.body2 if first.body2 != GROUND else first.body1
        moving2 = second.body2 if second.body2 != GROUND else second.body1
        involved = tuple(dict.fromkeys([first.body1, first.body2, second.body1,
                                        second.body2]))
        point = second.reaction_point()
        return cls(name, moving1, moving2, joint1=joint1, joint2=joint2, ratio=ratio,
                   offset=offset, coordinate1=coordinate1, coordinate2=coordinate2,
                   involved=involved,
                   point=None if point is None else np.array(point, float))

    @classmethod
    def from_scene(cls, mech, e) -> Gear:
        name = e.string("name")
        return mech.add("gear", name, joint1=e.string("joint1"), joint2=e.string("joint2"),
                        ratio=e.number("ratio", 1.0), offset=e.number("offset", 0.0),
                        coordinate1=e.string("coordinate1", required=False),
                        coordinate2=e.string("coordinate2", required=False))

    def _coordinate(self, ctx, joint_name: str, which: str | None) -> ca.SX:
        joint = ctx.mechanism.joints[joint_name]
        return joint.coordinate(ctx, which) - joint.initial_coordinate(ctx, which)

    def equations(self, ctx) -> ca.SX:
        c1 = self._coordinate(ctx, self.joint1, self.coordinate1)
        c2 = self._coordinate(ctx, self.joint2, self.coordinate2)
        return c2 - self.ratio * c1 - self.offset
