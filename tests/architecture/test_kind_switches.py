"""Formulation and integrator kinds own their behaviour (issue 33, item 3): the simulator, its
stepping, post-processing, build cache, numeric driver and event run hold no switch on a
formulation's or integrator's kind, flag or name; a kind registered from user code is run
by the simulator without touching it."""

from __future__ import annotations

import pathlib
import re
from dataclasses import dataclass

import numpy as np
import pytest

from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.integrators import kinds as integ
from casmbd.io.scene import loads_scene

ANALYSIS = pathlib.Path(__file__).resolve().parents[2] / "casmbd" / "analysis"
#: the simulator and the files sharing its ``self`` or driving its runs (found by name, so
#: that the check follows them into subpackages)
SIMULATOR_FILES = ("simulate.py", "stepping.py", "build_cache.py", "postprocess.py",
                   "numeric_run.py", "events.py")
_NAMES = "|".join(("idas", "cvodes", "adams", "rk4", "abm", "dopri5", "index1", "ggl",
                   "kkt_ode", "augmented_lagrangian", "articulated", "nullspace",
                   "partitioning"))
#: a switch on a kind: its ``kind`` string, its flags, or a registered name compared
SWITCHES = {
    "a formulation's kind string compared": re.compile(
        r"(?<!dtype)\.kind\s*(==|!=|\bnot\s+in\b|\bin\b)"),
    "a kind's flag read": re.compile(
        r"\.kind\.(numeric|kind)\b|(\]|\bkind)\.(fixed_step|compiled|dae|ode|numeric)\b"),
    "a formulation or integrator name compared": re.compile(
        rf"""(formulation_name|integrator|name)\s*(==|!=|\bnot\s+in\b|\bin\b)\s*\(?\s*"""
        rf"""["']({_NAMES})["']"""),
}


def _simulator_files() -> list[pathlib.Path]:
    found = [p for name in SIMULATOR_FILES for p in ANALYSIS.rglob(name)]
    assert {p.name for p in found} == set(SIMULATOR_FILES), "a simulator file was not found"
    return found


@pytest.mark.parametrize("what", sorted(SWITCHES))
def test_no_switch_on_kinds_in_the_simulator(what):
    hits = [f"{p.relative_to(ANALYSIS.parent.parent)}:{n}: {line.strip()}"
            for p in _simulator_files()
            for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
            if SWITCHES[what].search(line.split("#")[0])]
    assert not hits, f"{what} (move the branch into the kind's method):\n" + "\n".join(hits)


def test_the_patterns_catch_the_old_switches():
    """The checks see the switches this refactor removed (a check that cannot fail is none)."""
    old = ['max_steps = 20_000 if self.formulation.kind == "numeric" else 500_000',
           'if base.formulation.kind not in ("ode", "dae"):',
           "if integ.INTEGRATORS[name].fixed_step:",
           "if integ.INTEGRATORS[name].compiled:  # DOPRI5",
           "hot=None if self.kind.numeric else hot",
           'if name not in ("cvodes", "idas", "adams"):',
           'if base.formulation_name == "ggl":']
    for line in old:
        assert any(p.search(line) for p in SWITCHES.values()), line
    assert not any(p.search("arr.dtype.kind != 'f'") for p in SWITCHES.values())


FALL = """
[scene]
name = "fall"
dimension = 2
gravity = [0.0, -9.81]
[[bodies]]
name = "ball"
mass = 2.0
inertia = 0.1
position = [0.0, 1.0]
"""


@dataclass(frozen=True)
class ExplicitEuler(integ.IntegratorKind):
    """A user's integrator: explicit Euler, ``substeps`` steps per output interval, on the
    compiled dynamics of the simulator that calls it."""

    substeps: int = 4

    def integrate(self, runs, grid, x0, z0, rtol, atol, projection, step, max_steps):
        x, xs, p = np.array(x0, float), [np.array(x0, float)], runs.model.p
        for k in range(len(grid) - 1):
            h = (grid[k + 1] - grid[k]) / self.substeps
            for j in range(self.substeps):
                t = grid[k] + j * h
                x = x + h * np.asarray(runs.dyn(t, x, np.zeros(0), p, np.zeros(0))[0],
                                       float).ravel()
            xs.append(x)
        return np.vstack(xs), {"steps": (len(grid) - 1) * self.substeps}


def test_a_user_integrator_is_run_by_its_kind():
    """Free fall by explicit Euler: v_n = −g n h exactly and y_n = y0 − g h² n (n − 1) / 2
    (the position lags the velocity by one step), to rounding (1e-12), at every output;
    the simulator knows nothing of the method."""
    kind = integ.register_integrator(ExplicitEuler("user_euler", "explicit Euler"))
    try:
        sim = Simulator(loads_scene(FALL), "kkt_ode", mode="vm")
        res = sim.run(0.5, 5, integrator="user_euler")
    finally:
        integ.INTEGRATORS.pop(kind.name)
    n = np.arange(0, 21, kind.substeps)
    h = 0.5 / 20
    assert res.stats["steps"] == 20 and res.stats["integrator"] == "user_euler"
    y = res["q"][:, 1]
    vy = res["v"][:, 1]
    np.testing.assert_allclose(vy, -9.81 * n * h, rtol=0, atol=1e-12)
    np.testing.assert_allclose(y, 1.0 - 9.81 * h**2 * n * (n - 1) / 2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res["q"][:, [0, 2]], 0.0, atol=1e-15)
