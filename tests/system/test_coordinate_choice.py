"""The automatic choice of coordinates (``coordinates = "auto"``, the default; system/choice.py).

* trees and few loops get joint coordinates (a tree: no constraint equation, the
  articulated-body recursion), many loops and mechanisms without a spanning tree absolute ones,
  each with its reason in ``System.coordinate_reason``, ``info`` and the simulation stats;
* an explicit choice (scene, Mechanism, System argument) always wins;
* the automatic choice does not change the physics: the four-bar and the double pendulum
  simulated in the chosen joint coordinates and in absolute coordinates give the same body
  positions (rtol 1e-10 runs, agreement 1e-7 m).
"""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import casmbd
from benchmarks.chains import pendulum_chain
from casmbd.system import System
from casmbd.system.choice import JOINT_LIMIT, choose_coordinates

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _scene(name):
    return casmbd.load_scene(ROOT / "examples" / name)


def test_trees_and_few_loops_get_joint_coordinates():
    tree = System(_scene("double_pendulum.toml"))
    assert (tree.coordinates, tree.nq, tree.nc) == ("joint", 2, 0)
    assert "a tree" in tree.coordinate_reason
    loop = System(_scene("four_bar.toml"))
    assert (loop.coordinates, loop.nq) == ("joint", 3)
    assert "1 loop joint (C) with 2 equations on 3 tree coordinates" in loop.coordinate_reason


def _overbraced_mechanism():
    """Two bars hinged to the ground and to each other, each also pinned to the ground a
    second time: 2 tree coordinates, 2 loop joints with 4 equations — many loops."""
    mech = casmbd.Mechanism("braced", gravity=[0.0, -9.81])
    mech.add_body("a", 1.0, 0.1, [0.5, 0.0])
    mech.add_body("b", 1.0, 0.1, [1.5, 0.0])
    mech.add_revolute("ga", "ground", "a", [0.0, 0.0])
    mech.add_revolute("ab", "a", "b", [1.0, 0.0])
    mech.add_revolute("ga2", "ground", "a", [0.0, 0.0])
    mech.add_revolute("gb", "ground", "b", [2.0, 0.0])
    return mech


def test_many_loops_and_no_tree_get_absolute_coordinates():
    braced = System(_overbraced_mechanism())
    assert braced.coordinates == "absolute" and braced.nq == 6
    assert "2 loop joints with 4 equations on 2 tree coordinates" in braced.coordinate_reason
    free = casmbd.Mechanism("tethered", gravity=[0.0, -9.81])
    free.add_body("bob", 1.0, 0.1, [1.0, 0.0])
    free.add_distance("rope", "ground", "bob", [0.0, 0.0], [1.0, 0.0])
    system = System(free)  # the bob floats as a root of the tree, the rope closes a loop
    assert (system.coordinates, system.nq, system.nc) == ("joint", 3, 1)
    assert system.coordinate_reason == "1 loop joint (rope) with 1 equation on 3 tree coordinates"
    free.tree = ["rope"]  # a distance joint has no tree coordinates: no spanning tree
    system = System(free)
    assert system.coordinates == "absolute"
    assert system.coordinate_reason.startswith("no spanning tree of joint coordinates (tree: "
                                               "joint 'rope' (Distance) cannot be a tree joint")


def _looped_chain(n: int):
    """The n-rod chain with its last rod tied to the ground by a distance (one loop)."""
    mech = pendulum_chain(n)
    last = list(mech.bodies)[-1]
    mech.add_distance("rope", "ground", last, [0.0, -5.0], list(mech.bodies[last].position))
    return mech


def test_large_trees_keep_joint_coordinates_large_loops_get_absolute():
    """A tree of any size takes joint coordinates: the articulated-body recursion, outputs,
    reactions and the mass-matrix function are O(N) code.  Past JOINT_LIMIT tree coordinates
    with loops the joint-coordinate code (dense joint-space M of the KKT path) grows like N²
    (a 300-rod chain took over 300 s): the automatic choice takes absolute coordinates; at
    the limit it still takes joint coordinates."""
    big_tree = choose_coordinates(pendulum_chain(4 * JOINT_LIMIT))
    assert big_tree.coordinates == "joint"
    assert big_tree.reason == f"a tree: {4 * JOINT_LIMIT} joint coordinates, no loop equations"
    at_limit = choose_coordinates(_looped_chain(JOINT_LIMIT))
    assert at_limit.coordinates == "joint"
    beyond = choose_coordinates(_looped_chain(JOINT_LIMIT + 1))
    assert beyond.coordinates == "absolute"
    assert beyond.reason.startswith(f"{JOINT_LIMIT + 1} tree coordinates > {JOINT_LIMIT}")
    explicit = _looped_chain(JOINT_LIMIT + 1)
    explicit.coordinates = "joint"
    assert System(explicit).coordinates == "joint"


def test_an_explicit_choice_wins():
    mech = _scene("four_bar.toml")
    mech.coordinates = "absolute"
    assert System(mech).coordinates == "absolute" and System(mech).coordinate_reason == "given"
    assert System(_scene("four_bar.toml"), coordinates="natural").coordinates == "natural"
    text = (ROOT / "examples" / "double_pendulum.toml").read_text()
    assert 'coordinates = "absolute"' not in text
    given = casmbd.loads_scene(text.replace("[scene]", '[scene]\ncoordinates = "absolute"', 1))
    assert System(given).coordinates == "absolute"
    with pytest.raises(casmbd.ModelError, match="'auto'"):
        casmbd.Mechanism("m", coordinates="relative")


@pytest.mark.parametrize("scene", ["four_bar.toml", "double_pendulum.toml"])
def test_the_choice_keeps_the_physics(scene):
    runs = {}
    for coords in ("auto", "absolute"):
        mech = _scene(scene)
        mech.drivers.clear()
        mech.coordinates = coords
        runs[coords] = casmbd.simulate(mech, t_end=0.5, steps=10, rtol=1e-10, atol=1e-10)
    auto, absolute = runs["auto"], runs["absolute"]
    assert auto.stats["coordinates"] == "joint" and absolute.stats["coordinates"] == "absolute"
    assert auto.stats["coordinate_choice"] == "joint" and auto.stats["coordinate_reason"] != "given"
    assert absolute.stats["coordinate_reason"] == "given"
    for body in _scene(scene).bodies:
        assert np.max(np.abs(auto.body(body)["position"] - absolute.body(body)["position"])) \
            < 1e-7


def test_info_reports_the_choice():
    out = subprocess.run([sys.executable, "-m", "casmbd", "info", "--json",
                          str(ROOT / "examples" / "four_bar.toml")],
                         capture_output=True, text=True, check=True, timeout=300)
    data = json.loads(out.stdout)
    assert data["coordinate_choice"] == "joint"
    assert data["coordinate_reason"].startswith("1 loop joint (C)")
    assert data["coordinates"] == ["A.angle", "B.angle", "D.angle"]
    assert data["default_formulation"] == "augmented_lagrangian"
    assert data["default_integrator"] == "adams" and "BDF" in data["integrator_reason"]
    out = subprocess.run([sys.executable, "-m", "casmbd", "info", "--json",
                          str(ROOT / "examples" / "double_pendulum.toml")],
                         capture_output=True, text=True, check=True, timeout=300)
    assert json.loads(out.stdout)["default_formulation"] == "articulated"
