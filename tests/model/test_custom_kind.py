"""A joint kind registered from user code (examples/custom_joint.py): it works from a scene
string and from Python in absolute, natural and joint coordinates, and the registry's rules
name the culprit."""

from __future__ import annotations

import pathlib
import runpy
from dataclasses import dataclass

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.errors import ModelError, SceneError
from casmbd.model import JOINT_KINDS, Joint, register_joint
from casmbd.model import joints as joints_module
from casmbd.model.forces import ForceElement
from casmbd.model.registry import FORCE_KINDS, register_force

EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples" / "custom_joint.py"


_cache = private_cache("cache_kind")


@pytest.fixture(scope="module")
def example():
    """The example's namespace and its runs (1 s, 100 intervals, every choice, both builds)."""
    space = runpy.run_path(str(EXAMPLE), run_name="custom_joint_example")
    return space, space["main"]()


def test_the_kind_is_registered(example):
    space, _ = example
    assert JOINT_KINDS["point_on_line"] == {2: space["PointOnLine"]}
    assert "point_on_line" in joints_module.JOINT_TYPES


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "joint"])
def test_scene_and_python_builds_agree(example, coordinates):
    """The scene build and the Python build move identically (1e-12 m)."""
    _, runs = example
    py, sc = runs[coordinates, "python"], runs[coordinates, "scene"]
    assert np.max(np.abs(py["body_positions"] - sc["body_positions"])) < 1e-12


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "joint"])
def test_constraint_energy_and_motion(example, coordinates):
    """The rod's end stays on y = 0 to 1e-9 m (measured ≤ 8e-12), energy is constant to
    1e-7 J (measured ≤ 1e-8) while the crank falls by more than 1 rad, and every coordinate
    choice gives the absolute motion to 1e-8 m."""
    space, runs = example
    res = runs[coordinates, "python"]
    assert np.max(np.abs(space["rod_end_height"](res))) < 1e-9
    assert np.ptp(res["total_energy"]) < 1e-7
    assert np.ptp(res["angle_positions"][:, 0]) > 1.0
    ref = runs["absolute", "python"]
    assert np.max(np.abs(res["body_positions"] - ref["body_positions"])) < 1e-8


def test_scene_errors_of_a_user_kind(example):
    """An unknown key lists the kind's keys; a planar kind in a spatial scene is named."""
    space, _ = example
    text = space["SCENE"].format(coordinates="absolute")
    # (every joint entry also allows the keys of issue 24: friction, lower, upper, ...)
    with pytest.raises(SceneError, match=r"\('slide'\) key 'length': unknown key \(allowed: "
                                         r"axis, body1, body2, description, (\w+, )*name, "
                                         r"node1, node2, point, (\w+, )*type"):
        casmbd.loads_scene(text + "length = 2.0\n")  # the slide is the last entry
    spatial = ('[scene]\ndimension = 3\n[[bodies]]\nname = "b"\nmass = 1.0\n'
               'inertia = [1.0, 1.0, 1.0]\nposition = [0.0, 0.0, 0.0]\n[[joints]]\n'
               'name = "s"\ntype = "point_on_line"\nbody1 = "ground"\nbody2 = "b"\n'
               'point = [0.0, 0.0]\n')
    with pytest.raises(SceneError, match=r"\('s'\) key 'type': a point_on_line joint needs a "
                                         r"planar scene \(\[scene\] dimension = 2\)"):
        casmbd.loads_scene(spatial)
    mech = casmbd.Mechanism("m", gravity=(0.0, 0.0, -9.81))
    mech.add_body("b", mass=1.0, inertia=[1.0, 1.0, 1.0], position=(0.0, 0.0, 0.0))
    with pytest.raises(ModelError, match=r"joint 's': a point-on-line joint needs a planar "
                                         r"mechanism \(dimension = 2\)"):
        mech.add("point_on_line", "s", "ground", "b", point=(0.0, 0.0))
    with pytest.raises(ModelError, match=r"element 's': unknown kind 'hinge' \(joints: "
                                         r"revolute, .*point_on_line; force elements: force, "
                                         r"torque, spring_damper"):
        mech.add("hinge", "s", "ground", "b")


def test_registry_rules():
    """A class without a scene name, or a second class under a taken name, is refused."""

    @dataclass
    class Nameless(Joint):
        pass

    with pytest.raises(ModelError, match=r"joint kind Nameless: class attribute 'kind'"):
        register_joint(Nameless)

    @dataclass
    class Hinge(Joint):
        kind = "revolute"

    with pytest.raises(ModelError, match=r"joint kind 'revolute' in 2 dimensions is already "
                                         r"registered \(Revolute\)"):
        register_joint(Hinge)
    assert JOINT_KINDS["revolute"][2].__name__ == "Revolute"


TORSION_SCENE = """
[scene]
name = "torsion_{variant}"
[[bodies]]
name = "rod"
mass = 2.0
inertia = 0.5
position = [0.5, 0.0]
angular_velocity = 1.0
velocity = [0.0, 0.5]
[[joints]]
name = "pivot"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
"""


@pytest.fixture
def torsion():
    """A user force kind: a torsion spring k φ on a joint coordinate, registered for one
    test and removed afterwards."""

    @register_force
    @dataclass
    class Torsion(ForceElement):
        name: str
        joint: str
        stiffness: float = 0.0

        kind = "torsion"
        scene_keys = frozenset({"joint", "stiffness"})

        @classmethod
        def from_scene(cls, mech, e):
            return mech.add("torsion", e.string("name"), e.string("joint"),
                            stiffness=e.number("stiffness"))

        def terms(self, kit, ctx):
            phi = kit.ctx.mechanism.joints[self.joint].coordinate(kit.ctx)
            return [kit.term("measure", ctx.mechanism.joints[self.joint].coordinate(ctx),
                             -self.stiffness * phi)]

        def potential(self, kit):
            phi = kit.ctx.mechanism.joints[self.joint].coordinate(kit.ctx)
            return 0.5 * self.stiffness * phi**2

    yield Torsion
    del FORCE_KINDS["torsion"]


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "joint"])
def test_user_force_kind_matches_the_built_in_spring(torsion, coordinates):
    """A rod (I about the pivot = 0.5 + 2·0.5² = 1) on a torsion spring k = 4 registered
    from user code, from a scene and from Python: the motion of the built-in rotational
    spring (1e-12 rad), φ = sin(2t)/2 (1e-8 rad), energy constant (1e-9 J)."""
    builtin = casmbd.loads_scene(
        TORSION_SCENE.format(variant="builtin") + '[[forces]]\nname = "spring"\n'
        'type = "rotational_spring_damper"\njoint = "pivot"\nstiffness = 4.0\n')
    scene = casmbd.loads_scene(TORSION_SCENE.format(variant="user") + '[[forces]]\n'
                               'name = "spring"\ntype = "torsion"\njoint = "pivot"\n'
                               'stiffness = 4.0\n')
    python = casmbd.loads_scene(TORSION_SCENE.format(variant="python"))
    python.add("torsion", "spring", "pivot", stiffness=4.0)
    assert type(scene.forces["spring"]) is torsion
    runs = []
    for mech in (builtin, scene, python):
        mech.coordinates = coordinates
        mech.name = f"{mech.name}_{coordinates}"
        runs.append(casmbd.simulate(mech, t_end=2.0, steps=40, rtol=1e-12))
    ref = runs[0]["joint_positions"][:, 0]
    for res in runs[1:]:
        assert np.max(np.abs(res["joint_positions"][:, 0] - ref)) < 1e-12
        assert np.ptp(res["total_energy"]) < 1e-9
    assert np.max(np.abs(ref - 0.5 * np.sin(2.0 * runs[0].t))) < 1e-8
