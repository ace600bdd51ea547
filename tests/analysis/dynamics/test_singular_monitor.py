"""The singular-pass monitor in joint coordinates (``stats["near_singular_times"]``).

In joint coordinates the loop-closure rows of C_q vanish as a whole at a singular pose: for
the N four-bar chain (``benchmarks/n_four_bar.py``) with the bars horizontal every link lies
on the ground line, every column of a loop joint's x-row is L sin(angle) ≈ 0.  Rescaling each
step's rows to unit norm (the old equilibration) turned those rows back into regular ones:
σ_r/σ_1 stayed at 0.286 through the passes and no pass was reported, while the unscaled ratio
fell from 0.26 to 2.6e-3 at the nearest output step.  The monitor now scales every step by the
row and column factors of the first step.  The reference for the pass times is the closed form
on the parallelogram branch (``singular_pass_times``, elliptic functions).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import private_cache

from benchmarks.n_four_bar import n_four_bar
from benchmarks.n_four_bar_reference import singular_pass_times
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.instant.redundancy import (
    conditioning,
    equilibrated_singular_values,
    equilibration,
    near_singular_passes,
)

T_END = 4.0
STEPS = 400


_cache = private_cache("cache_singular_monitor", scope="module")


def test_reference_scaling_keeps_a_vanishing_row_small():
    """J(ε) = [[ε, −ε, ε], [2, −1, 1]]: its rows are independent for ε ≠ 0 and its smallest
    singular value, with the factors of J(1), is O(ε) (σ_2/σ_1 ≤ 2ε here); J(ε)'s own
    equilibration makes the first row (1, −1, 1)/√3 and hides it (σ_2/σ_1 > 0.1)."""
    def jac(eps):
        return np.array([[eps, -eps, eps], [2.0, -1.0, 1.0]])

    scaling = equilibration(jac(1.0))
    for eps in (1e-2, 1e-4, 1e-6):
        fixed = equilibrated_singular_values(jac(eps), scaling)
        own = equilibrated_singular_values(jac(eps))
        assert fixed[1] / fixed[0] <= 2 * eps
        assert own[1] / own[0] > 0.1
    # at the reference itself both scalings agree (the first step is unchanged)
    np.testing.assert_allclose(equilibrated_singular_values(jac(1.0), scaling),
                               equilibrated_singular_values(jac(1.0)), rtol=1e-14)


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_four_bar_passes_reported_in_both_descriptions(coordinates):
    """N = 3, 4 s, rtol 1e-10: the four passes of the closed form are reported within 1e-4 s
    (measured ≤ 3e-6 s in absolute coordinates) and the located conditioning is < 1e-4, in
    joint coordinates (3 loop joints, 6 equations on 7 tree coordinates) as in absolute."""
    mech = n_four_bar(3)
    mech.coordinates = coordinates
    res = Simulator(mech).run(T_END, STEPS, rtol=1e-10)
    assert res.stats["coordinates"] == coordinates
    passes = singular_pass_times(3, T_END)
    found = np.asarray(res.stats["near_singular_times"])
    assert len(passes) == 4 and len(found) == 4
    assert np.max(np.abs(found - passes)) <= 1e-4
    assert res.stats["min_constraint_conditioning"] < 1e-4


def test_subsampled_monitor_refines_between_evaluated_steps():
    """A large model's monitor evaluates every few output steps only: with the conditioning
    of the N = 3 chain (absolute coordinates, 4 s, rtol 1e-10) kept at every 8th step, the
    passes are still located within 1e-4 s of the closed form with conditioning < 1e-4 (the
    steps between the evaluated neighbours of a minimum are evaluated, the two intervals
    around the smallest refined)."""
    mech = n_four_bar(3)
    mech.coordinates = "absolute"
    sim = Simulator(mech)
    res = sim.run(T_END, STEPS, rtol=1e-10)
    rank = sim.redundancy["constraint_rank"]
    cond = conditioning(sim.model, res["q"], res.t, rank)
    sub = np.full_like(cond, np.nan)
    sub[::8] = cond[::8]
    passes = near_singular_passes(sim.model, res.t, res["q"], res["v"], sub, rank)
    closed = singular_pass_times(3, T_END)
    assert len(passes) == 4
    assert np.max(np.abs(np.array([t for t, _ in passes]) - closed)) <= 1e-4
    assert max(c for _, c in passes) < 1e-4
