"""The simulator's cache keyed by what the model is (casmbd.compiled.modelkey, issue 22 item 3).

A second Simulator of the same description loads the compiled libraries and the recorded
metadata without building a System; every change of the description or of the options is
another key (a miss that builds and compiles); the hit's result equals the miss's.
"""

from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest
from conftest import private_cache

from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.compiled import codegen, modelkey
from casmbd.model import Mechanism

needs_compiler = pytest.mark.skipif(codegen.find_compiler() is None,
                                    reason="no C compiler available")


def two_rods(mass: float = 1.0, point: float = 1.0, stiffness: float = 2.0) -> Mechanism:
    """Two pinned rods with a parameter (spring stiffness) and an actuated joint."""
    mech = Mechanism("cachechain", gravity=[0.0, -9.81], coordinates="absolute")
    mech.add_parameter("k", stiffness)
    mech.add_body("a", mass, mass / 12, [0.5, 0.0])
    mech.add_body("b", 1.0, 1.0 / 12, [1.5, 0.0])
    mech.add_revolute("pin0", "ground", "a", [0.0, 0.0])
    mech.add_revolute("pin1", "a", "b", [point, 0.0])
    mech.add_rotational_spring_damper("spring", "pin1", stiffness="k", damping=0.1)
    mech.add_actuator("motor", "pin0")
    mech.add_marker("tip", "b", [2.0, 0.0])
    return mech


INPUTS = {"motor": "0.5*sin(3*t)"}


def build(mech=None, **options) -> Simulator:
    return Simulator(two_rods() if mech is None else mech, inputs=INPUTS, mode="compiled",
                     **options)


def from_record(sim: Simulator) -> bool:
    """True when ``sim`` was made from a model record (no System built)."""
    return "system" not in sim.model.__dict__ and sim.model.report.cache_hit


cache = private_cache(autouse=False, CASMBD_PROGRESS="0", CASMBD_COMPILE=None,
                      CASMBD_CFLAGS=None)


def test_canonical_is_exact_and_ordered():
    one, other = two_rods(), two_rods(mass=1.0 + 2.0 ** -52)
    assert modelkey.canonical(one) == modelkey.canonical(two_rods())
    assert modelkey.canonical(one) != modelkey.canonical(other)  # one ulp is another model
    assert modelkey.canonical({"a": 1, "b": 2}) != modelkey.canonical({"b": 2, "a": 1})
    with pytest.raises(modelkey.UnkeyableError):
        modelkey.canonical({"motor": lambda t: t})
    mech = two_rods()
    mech.scene_text = "# a comment"  # the embedded scene text is not what is built
    mech.scene_data = {"simulate": {"t_end": 3.0}}  # nor the scene's analysis settings
    assert modelkey.canonical(mech) == modelkey.canonical(two_rods())
    mech.gravity = mech.gravity * 1.01  # but the description is
    assert modelkey.canonical(mech) != modelkey.canonical(two_rods())


@needs_compiler
def test_changes_miss_identical_descriptions_hit(cache):
    first = build()
    assert first.model.report.compiled and not from_record(first)
    again = build()
    assert from_record(again) and not again.model.report.compiled
    for changed in (build(two_rods(mass=1.25)),                  # a mass
                    build(two_rods(point=1.0 + 1e-9)),           # a joint's point
                    build(two_rods(stiffness=3.0)),              # a parameter's default
                    build(formulation_options={"alpha": 10.0}),  # a formulation option
                    build(formulation="kkt_ode")):               # the formulation
        assert not from_record(changed)
    assert from_record(build(two_rods(mass=1.25)))
    mech = two_rods()
    mech.add_marker("middle", "a", [0.5, 0.0])                   # an element more
    assert modelkey.model_key(mech, "simulator", {}) != \
        modelkey.model_key(two_rods(), "simulator", {})
    assert modelkey.model_key(two_rods(), "simulator", {"inputs": {"motor": np.sin}}) is None


@needs_compiler
def test_hit_equals_miss(cache):
    miss = build()
    res_miss = miss.run(1.5, 30, rtol=1e-9)
    hit = build()
    assert from_record(hit)
    res_hit = hit.run(1.5, 30, rtol=1e-9)
    assert from_record(hit)  # the run itself needed no System either
    assert set(res_hit.arrays) == set(res_miss.arrays)
    for name, arr in res_miss.arrays.items():
        np.testing.assert_allclose(res_hit[name], arr, rtol=0, atol=1e-14, err_msg=name)
    assert res_hit.names == res_miss.names
    assert res_hit.stats["formulation"] == res_miss.stats["formulation"]
    # the symbolic parts are still there when an analysis needs them (built on first use)
    assert hit.formulation.function.name() == miss.formulation.function.name()
    assert hit.system.nq == miss.system.nq and not from_record(hit)


@needs_compiler
def test_tampered_library_is_rebuilt(cache):
    build()
    record = next(cache.glob("*.model.json"))
    library = cache / json.loads(record.read_text())["libraries"][0]["file"]
    # truncated (a new file: this process has the old one mapped): never dlopen'ed
    truncated = library.with_name("truncated.tmp")
    truncated.write_bytes(library.read_bytes()[:-8])
    os.replace(truncated, library)
    with pytest.warns(RuntimeWarning, match="not used"):
        sim = build()
    assert not from_record(sim) and sim.model.report.compiled
    record.write_text("{not json")
    with pytest.warns(RuntimeWarning, match="cannot be read"):
        assert not from_record(build())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert from_record(build())  # the rebuild wrote a good record again
