"""A contact shape registered from user code: a sphere on a body against a fixed dome.

The gap of a sphere of radius r centred at the body point P against a ground sphere (a dome)
of centre c and radius R is the distance of the surfaces::

    g(q) = |r_P(q) − c| − (r + R)

(frictionless here: no tangent directions are declared).  Everything about the shape is in the
class below — its scene ``type`` and keys, how it reads them from a ``[[contacts]]`` entry and
builds itself, its gap written with the context's ``ctx.position`` — and its one
:func:`~casmbd.model.contacts.register_contact_shape`; the impacts (Newton's restitution at the
event), the compliant model, the events and the analyses are the contacts' own, the same for
every shape.

The demonstration: a ball dropped onto the top of a dome, from Python and from a scene.

Run it with ``python examples/custom_contact.py``;
``tests/architecture/test_custom_registries.py`` runs it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

import casmbd
from casmbd.errors import ModelError
from casmbd.model.bodies import scalar, vector
from casmbd.model.contacts import Unilateral, register_contact_shape


@register_contact_shape(replace=True)  # replace: the script may run twice in one session
@dataclass
class DomeContact(Unilateral):
    """A sphere (``radius``) at the global ``point`` on ``body`` against the fixed sphere of
    ``centre`` and ``dome_radius``."""

    shape: ClassVar[str] = "dome"
    scene_keys: ClassVar[frozenset[str]] = frozenset({"centre", "dome_radius"})
    body_keys: ClassVar[tuple[str, ...]] = ()

    body: str = ""
    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    radius: float = 0.0
    centre: np.ndarray = field(default_factory=lambda: np.zeros(2))
    dome_radius: float = 0.0
    dimension: int = 2

    def __post_init__(self):
        self._check()
        where = f"contact '{self.name}' field"
        self.point = vector(self.point, f"{where} 'point'", self.dimension)
        self.centre = vector(self.centre, f"{where} 'centre'", self.dimension)
        self.radius = scalar(self.radius, f"{where} 'radius'")
        self.dome_radius = scalar(self.dome_radius, f"{where} 'dome_radius'")
        if self.radius < 0.0 or self.dome_radius <= 0.0:
            raise ModelError(f"{where} 'dome_radius': radii must be >= 0 and the dome's > 0")
        if self.friction:
            raise ModelError(f"{where} 'friction': the dome contact is frictionless")

    @staticmethod
    def scene_args(e, dim: int) -> dict:
        return {"centre": e.vector("centre", dim), "dome_radius": e.number("dome_radius")}

    @classmethod
    def create(cls, name, restitution, friction, model, body, point, radius, dim,
               centre=None, dome_radius=0.0, **ignored) -> DomeContact:
        if centre is None:
            raise ModelError(f"contact '{name}' field 'centre': a dome contact needs its centre")
        return cls(name, restitution, friction, model, body, point, radius, centre,
                   dome_radius, dim)

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body,)

    def spheres(self):
        return [(self.body, self.point, self.radius)]

    def gaps(self, ctx) -> ca.SX:
        d = ctx.position(self.body, self.point) - ca.DM(self.centre)
        return ca.sqrt(ca.dot(d, d)) - (self.radius + self.dome_radius)


SCENE = """
[scene]
name = "ball_on_dome"
gravity = [0.0, -9.81]

[[bodies]]
name = "ball"
mass = 0.5
inertia = 0.002
position = [0.0, 2.0]

[[contacts]]
name = "dome"
type = "dome"
body = "ball"
point = [0.0, 2.0]
radius = 0.1
centre = [0.0, 0.0]
dome_radius = 1.0
restitution = 0.5
"""


def python_mechanism() -> casmbd.Mechanism:
    """The scene above built in Python."""
    mech = casmbd.Mechanism("ball_on_dome", gravity=[0.0, -9.81])
    mech.add_body("ball", mass=0.5, inertia=0.002, position=[0.0, 2.0])
    mech.add_contact("dome", "ball", [0.0, 2.0], radius=0.1, shape="dome",
                     centre=[0.0, 0.0], dome_radius=1.0, restitution=0.5)
    return mech


if __name__ == "__main__":
    res = casmbd.simulate(casmbd.loads_scene(SCENE), t_end=0.6, steps=60)
    print("impacts at", [round(e["time"], 6) for e in res.events if e["kind"] == "impact"],
          "s; closed form", round(float(np.sqrt(2 * 0.9 / 9.81)), 6), "s")
