"""DOPRI5's fused stepping (casmbd.analysis.integrators.dopri, issue 36 item 4).

The run in blocks of 64, 16 and 4 attempts with the compiled start against the previous
path (one block size of 16 attempts, Hairer's first step in NumPy, blocks in CasADi's
virtual machine) on a 4-rod pendulum chain in joint coordinates (the articulated ODE,
DOPRI5 by default):

* the same trajectory to 1e-10 (rad, rad/s) at rtol = atol = 1e-8, with 1 and 25 outputs —
  the block sizes change the number of calls, not the steps, so the step and evaluation
  counts are equal too;
* the compiled first step equals the NumPy formula (HNW I §II.4) to 1e-13 relative;
* the statistics: 6 right-hand sides per attempted step (FSAL) plus 2 for the start, and
  fewer compiled calls than with one block size.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.chains import pendulum_chain
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.integrators.dopri import BLOCK, BLOCKS, Dopri, first_step

TOL, T_END = 1e-8, 2.0


@pytest.fixture(scope="module")
def sim() -> Simulator:
    mech = pendulum_chain(4)
    mech.coordinates = "joint"
    mech.name = "dopri_fused_chain4"
    return Simulator(mech)


def _march(runner: Dopri, sim: Simulator, outputs: int):
    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    p = sim.model.p
    state = runner.start(x0, 0.0, T_END, p, TOL, TOL)
    xs = [state.x()]
    for t_out in np.linspace(0.0, T_END, outputs + 1)[1:]:
        state = runner.advance(state, p, t_out, TOL, TOL, 100_000)
        xs.append(state.x())
    return np.array(xs), state.stats()


@pytest.mark.parametrize("outputs", [1, 25])
def test_fused_path_equals_the_previous_one(sim, outputs):
    res = sim.run(T_END, outputs, rtol=TOL, atol=TOL)
    assert res.stats["integrator"] == "dopri5"
    previous = Dopri(sim.formulation.function, mode="vm", blocks=(BLOCK,),
                     compiled_start=False)
    xs_prev, stats_prev = _march(previous, sim, outputs)
    xs = np.hstack([res["q"], res["v"]])
    assert np.max(np.abs(xs - xs_prev)) <= 1e-10
    for key in ("steps", "rejected", "rhs_evaluations"):
        assert res.stats[key] == stats_prev[key], key
    assert stats_prev["rhs_evaluations"] == 6 * (stats_prev["steps"]
                                                 + stats_prev["rejected"]) + 2


def test_compiled_start_equals_hairers_formula(sim):
    runner = Dopri(sim.formulation.function, mode="vm")
    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    x0 = x0 + 0.1  # a moving start: d1 is not zero
    p = sim.model.p
    for rtol, atol in ((1e-6, 1e-9), (1e-10, 1e-10)):
        state = runner.start(x0, 0.3, T_END, p, rtol, atol)
        f0 = runner._f(0.3, x0, p)
        h = first_step(runner._f, x0, f0, 0.3, T_END, p, rtol, atol)
        assert abs(state.h - h) <= 1e-13 * h
        np.testing.assert_allclose(state.s[runner.nx:2 * runner.nx], f0, rtol=1e-14,
                                   atol=1e-14)
        assert state.t == 0.3 and state.extra_evaluations == 2


def test_fewer_calls_than_one_block_size(sim):
    fused = Dopri(sim.formulation.function, mode="vm", blocks=BLOCKS)
    single = Dopri(sim.formulation.function, mode="vm", blocks=(BLOCK,))
    _, st_fused = _march(fused, sim, 1)
    _, st_single = _march(single, sim, 1)
    assert st_fused == st_single
    attempts = st_fused["steps"] + st_fused["rejected"]
    assert single.calls >= attempts / BLOCK + 1  # one start + ceil(attempts / 16) blocks
    assert fused.calls < single.calls
