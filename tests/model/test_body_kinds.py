"""Body kinds own their behaviour (issue 20, item 1): the registry's rules name the culprit, the
scene loader reads ``[[bodies]] type`` through it, and a body kind registered from test code (a
slender rod given its length, which computes I = m L²/12 itself) works from a scene string and
from Python in absolute, natural and joint coordinates, equal to the plain rigid body with that
inertia to 1e-12."""

from __future__ import annotations

from typing import ClassVar

import casadi as ca
import numpy as np
import pytest

from casmbd.errors import ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.model import BODY_KINDS, Body, Mechanism, SpatialBody, register_body
from casmbd.model.bodies import scalar
from casmbd.system.descriptions import (
    DESCRIPTIONS,
    PlanarAbsolute,
    describe,
    register_description,
)
from casmbd.system.equations import System

MASS, LENGTH = 2.0, 0.8


class SlenderRod(Body):
    """A planar uniform slender rod: ``length`` instead of ``inertia`` (I = m L²/12)."""

    kind: ClassVar[str] = "slender_rod"
    scene_keys: ClassVar[frozenset[str]] = frozenset(
        {"name", "type", "mass", "length", "position", "angle", "velocity",
         "angular_velocity", "description"})

    @classmethod
    def create(cls, mech, name, mass, length, position, angle=0.0, velocity=None,
               angular_velocity=None):
        length = scalar(length, f"body '{name}' field 'length'")
        if length <= 0.0:
            raise ModelError(f"body '{name}' field 'length': must be > 0, got {length}")
        mass = scalar(mass, f"body '{name}' field 'mass'")
        body = super().create(mech, name, mass, mass * length**2 / 12.0, position, angle,
                              velocity, angular_velocity)
        body.length = length
        return body

    @classmethod
    def from_scene(cls, mech, e):
        e.positive("mass", e.value("mass"))
        return mech.add(cls.kind, e.string("name"), mass=e.number("mass"),
                        length=e.number("length"), position=e.vector("position"),
                        angle=e.number("angle", 0.0),
                        angular_velocity=e.number("angular_velocity", 0.0))


@pytest.fixture(autouse=True)
def _slender_rod():
    """Register the user kind for each test and leave the registry as it was."""
    register_body(SlenderRod, replace=True)
    yield
    BODY_KINDS.pop("slender_rod", None)


def _chain(rod: bool) -> Mechanism:
    """rod1 pinned to the ground, rod2 pinned to rod1's end, rod3 free (a floating root in
    joint coordinates), all slender rods of mass 2 kg and length 0.8 m."""
    m = Mechanism("rods", gravity=(0.0, -9.81))
    inertia = MASS * LENGTH**2 / 12.0
    poses = {"rod1": ((0.4, 0.0), 0.0), "rod2": ((0.8, -0.4), -np.pi / 2),
             "rod3": ((2.0, 1.0), 0.3)}
    for name, (pos, angle) in poses.items():
        if rod:
            m.add("slender_rod", name, mass=MASS, length=LENGTH, position=pos, angle=angle,
                  angular_velocity=0.5)
        else:
            m.add_body(name, mass=MASS, inertia=inertia, position=pos, angle=angle,
                       angular_velocity=0.5)
    m.add_revolute("pin1", "ground", "rod1", (0.0, 0.0))
    m.add_revolute("pin2", "rod1", "rod2", (0.8, 0.0))
    return m


SCENE = """
[scene]
name = "rods"
gravity = [0.0, -9.81]
[[bodies]]
name = "rod1"
type = "{kind}"
mass = 2.0
{size}
position = [0.4, 0.0]
angular_velocity = 0.5
[[bodies]]
name = "rod2"
type = "{kind}"
mass = 2.0
{size}
position = [0.8, -0.4]
angle = -1.5707963267948966
angular_velocity = 0.5
[[bodies]]
name = "rod3"
type = "{kind}"
mass = 2.0
{size}
position = [2.0, 1.0]
angle = 0.3
angular_velocity = 0.5
[[joints]]
name = "pin1"
type = "revolute"
body1 = "ground"
body2 = "rod1"
point = [0.0, 0.0]
[[joints]]
name = "pin2"
type = "revolute"
body1 = "rod1"
body2 = "rod2"
point = [0.8, 0.0]
"""


def _scene(rod: bool) -> Mechanism:
    size = "length = 0.8" if rod else f"inertia = {MASS * LENGTH**2 / 12.0!r}"
    return loads_scene(SCENE.format(kind="slender_rod" if rod else "rigid", size=size))


def _evaluate(mech: Mechanism, coordinates: str) -> dict[str, np.ndarray]:
    """M, Q_e, Q_v, C, C_q, γ, T and the outputs at a perturbed state."""
    s = System(mech, coordinates)
    rng = np.random.default_rng(1)
    args = {"q": s.initial_coordinates() + 0.05 * rng.standard_normal(s.nq),
            "v": rng.standard_normal(s.nq), "a": rng.standard_normal(s.nq), "t": 0.2,
            "u": np.zeros(0), "p": s.parameter_values}
    out = {"q0": s.initial_coordinates(), "v0": s.initial_velocities()}
    for name in ("mass_matrix", "applied_forces", "quadratic_velocity_forces", "constraints",
                 "constraint_jacobian", "acceleration_rhs", "kinetic_energy", "outputs"):
        f = s.function(name)
        res = f.call({n: args[n] for n in f.name_in()})
        out.update({f"{name}.{k}": np.array(ca.DM(v)) for k, v in res.items()})
    return out


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "joint"])
@pytest.mark.parametrize("build", [_chain, _scene])
def test_user_body_kind_matches_the_plain_body(build, coordinates):
    """Every equation and output of the slender-rod build equals the plain-body build to
    1e-12 (the same numbers are computed: measured 0), in every coordinate choice."""
    rods, plain = _evaluate(build(True), coordinates), _evaluate(build(False), coordinates)
    assert rods.keys() == plain.keys()
    for key, val in rods.items():
        assert val.shape == plain[key].shape, key
        assert np.max(np.abs(val - plain[key]), initial=0.0) <= 1e-12, key


def test_the_kind_computes_its_inertia():
    """I = m L²/12 = 0.10666… kg m², and in absolute coordinates the rotational diagonal of M
    of a centroidal rod is that number (closed form, 1e-15)."""
    mech = _chain(True)
    assert isinstance(mech.bodies["rod3"], SlenderRod)
    assert mech.bodies["rod3"].inertia == pytest.approx(MASS * LENGTH**2 / 12.0, abs=1e-15)
    s = System(mech, "absolute")
    mass = np.array(ca.DM(s.function("mass_matrix")(s.initial_coordinates(),
                                                    s.parameter_values)))
    assert np.allclose(np.diag(mass), [MASS, MASS, MASS * LENGTH**2 / 12.0] * 3,
                       rtol=0, atol=1e-15)


def test_floating_root_uses_the_kinds_description():
    """In joint coordinates the free rod is a floating root described by the class its kind
    names (planar_floating: x, y, θ), the others by their tree joints."""
    s = System(_chain(True), "joint")
    desc = s.descriptions["rod3"]
    assert type(desc) is DESCRIPTIONS[SlenderRod.descriptions["joint"]]
    assert [n for n in s.coordinate_names if n.startswith("rod3")] == \
        ["rod3.x", "rod3.y", "rod3.angle"]


def test_add_dispatches_body_kinds():
    """``add("body:rigid", ...)`` is what add_body does; unknown kinds are named."""
    m = Mechanism("m", gravity=(0.0, 0.0, -9.81))
    body = m.add("body:rigid", "b", 1.0, [0.1, 0.2, 0.3], (0.0, 0.0, 0.0))
    assert isinstance(body, SpatialBody) and m.bodies["b"] is body
    with pytest.raises(ModelError, match=r"body 'c': unknown body type 'elastic' "
                                         r"\(allowed: rigid, .*slender_rod"):
        m.add("body:elastic", "c", 1.0, 1.0, (0.0, 0.0, 0.0))
    with pytest.raises(ModelError, match=r"body 'r': a slender_rod body needs a planar "
                                         r"mechanism \(dimension = 2\)"):
        m.add("slender_rod", "r", mass=1.0, length=1.0, position=(0.0, 0.0, 0.0))
    with pytest.raises(ModelError, match=r"element 'x': unknown kind 'nope' .*bodies: "
                                         r"body:rigid, body:flexible, body:slender_rod"):
        m.add("nope", "x")
    with pytest.raises(ModelError, match=r"body 'r' field 'length': must be > 0, got -1.0"):
        Mechanism("p").add("slender_rod", "r", mass=1.0, length=-1.0, position=(0, 0))


def test_scene_errors_name_the_entry():
    """An unknown body type names the entry and lists the kinds; a kind's own keys rule."""
    text = SCENE.format(kind="rigid", size="inertia = 0.1")
    bad = text.replace('type = "rigid"', 'type = "elastic"', 1)
    with pytest.raises(SceneError, match=r"\[\[bodies\]\] entry 1 \('rod1'\) key 'type': "
                                         r"unknown body type 'elastic' \(allowed: rigid, flexible, "
                                         r"slender_rod\)"):
        loads_scene(bad)
    rod_with_inertia = text.replace('type = "rigid"', 'type = "slender_rod"', 1)
    with pytest.raises(SceneError, match=r"entry 1 \('rod1'\) key 'inertia': unknown key "
                                         r"\(allowed: angle, angular_velocity, description, "
                                         r"length, mass, name, position, type, velocity\)"):
        loads_scene(rod_with_inertia)
    spatial = SCENE.format(kind="slender_rod", size="length = 0.8").replace(
        "gravity = [0.0, -9.81]", "dimension = 3\ngravity = [0.0, 0.0, -9.81]")
    with pytest.raises(SceneError, match=r"entry 1 \('rod1'\) key 'type': a slender_rod body "
                                         r"needs a planar scene \(\[scene\] dimension = 2\)"):
        loads_scene(spatial)
    negative = SCENE.format(kind="slender_rod", size="length = -0.8")
    with pytest.raises(SceneError, match=r"entry 1 \('rod1'\): body 'rod1' field 'length': "
                                         r"must be > 0, got -0.8"):
        loads_scene(negative)


def test_registry_rules_name_the_class():
    class Nameless(Body):
        kind: ClassVar[str] = "not a name"

    class NoDescriptions(Body):
        kind: ClassVar[str] = "half_done"
        descriptions: ClassVar[dict[str, str]] = {"absolute": "planar_absolute"}

    class Other(Body):
        kind: ClassVar[str] = "rigid"

    with pytest.raises(ModelError, match=r"body kind Nameless: class attribute 'kind' must "
                                         r"be an identifier"):
        register_body(Nameless)
    with pytest.raises(ModelError, match=r"body kind 'half_done' \(NoDescriptions\).*missing: "
                                         r"natural, joint"):
        register_body(NoDescriptions)
    with pytest.raises(ModelError, match=r"body kind 'rigid' in 2 dimensions is already "
                                         r"registered \(Body\)"):
        register_body(Other)
    assert BODY_KINDS["rigid"] == {2: Body, 3: SpatialBody}


def test_description_registry():
    """A kind naming an unregistered description fails when the system is built, naming the
    body, the key and the coordinate choice; the description registry refuses duplicates."""

    class Orphan(Body):
        kind: ClassVar[str] = "orphan"
        descriptions: ClassVar[dict[str, str]] = {"absolute": "planar_orphan",
                                                  "natural": "planar_natural",
                                                  "joint": "planar_floating"}

    register_body(Orphan)
    try:
        m = Mechanism("o")
        m.add("orphan", "b", 1.0, 0.1, (0.0, 0.0))
        with pytest.raises(ModelError, match=r"body 'b' \(orphan\): unknown description "
                                             r"'planar_orphan' in absolute coordinates"):
            System(m, "absolute")
        assert type(describe(m.bodies["b"], "natural")).__name__ == "PlanarNatural"
    finally:
        BODY_KINDS.pop("orphan")
    with pytest.raises(ModelError, match=r"description 'planar_absolute' is already "
                                         r"registered \(PlanarAbsolute\)"):
        register_description("planar_absolute", type("Copy", (PlanarAbsolute,), {}))
    with pytest.raises(ModelError, match=r"description 'x': expected a Description subclass"):
        register_description("x", int)
    assert "x" not in DESCRIPTIONS
