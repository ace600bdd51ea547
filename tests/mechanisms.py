"""Small mechanisms shared by several test files."""

from __future__ import annotations

import math

from casmbd import Mechanism

G = 9.81


def triple_crank(coordinates: str = "absolute", name: str | None = None) -> Mechanism:
    """Three parallel unit cranks under one coupler: a parallelogram with a redundant third
    crank (one dependent loop equation, mobility 1), a torsion spring on the first crank.
    The cranks reach the horizontal (collinear, singular) pose at t ≈ 0.687 s."""
    m = Mechanism(name or f"triple_crank_{coordinates}", gravity=(0.0, -G),
                  coordinates=coordinates)
    for i in range(3):
        m.add_body(f"c{i}", mass=1.0, inertia=1.0 / 12.0, position=(float(i), 0.5),
                   angle=math.pi / 2)
    m.add_body("coupler", mass=2.0, inertia=2.0 * 4.0 / 12.0, position=(1.0, 1.0))
    for i in range(3):
        m.add_revolute(f"g{i}", "ground", f"c{i}", point=(float(i), 0.0))
        m.add_revolute(f"t{i}", f"c{i}", "coupler", point=(float(i), 1.0))
    m.add_rotational_spring_damper("spring", "g0", stiffness=10.0, damping=0.5)
    return m
