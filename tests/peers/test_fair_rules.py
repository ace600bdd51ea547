"""The fair rules of benchmarks/fair.py (issue 36 item 1): interpolation, floors, timing rule.

Numbers only (no timing is asserted): the interpolation against closed forms on power laws,
the floor rule on constructed error sequences, the timing rule on a fake clock.
"""

from __future__ import annotations

import math

import pytest

from benchmarks import fair


def test_time_to_error_is_exact_on_a_power_law():
    # a fourth-order method: error = C h^4, time = c / h, so time = c (C / e)^(1/4): a straight
    # line in log-log; the interpolation between h = 1e-2 and 5e-3 must give it exactly
    pts = [(3.0 * h**4, 2e-5 / h) for h in (1e-2, 5e-3, 2.5e-3)]
    level = 1e-9
    want = 2e-5 * (3.0 / level) ** 0.25
    assert fair.time_to_error(pts, level) == pytest.approx(want, rel=1e-12)


def test_time_to_error_uses_the_pareto_front_and_never_extrapolates():
    # a slower, less accurate point is ignored; a level reached by the cheapest point gives
    # that point's time; an unreached level gives None
    pts = [(1e-3, 1.0), (1e-4, 2.0), (1e-3, 5.0), (1e-6, 4.0)]
    assert fair.pareto(pts) == [(1e-3, 1.0), (1e-4, 2.0), (1e-6, 4.0)]
    assert fair.time_to_error(pts, 1e-2) == 1.0
    # between (1e-4, 2) and (1e-6, 4): halfway in log error -> sqrt(2 * 4)
    assert fair.time_to_error(pts, 1e-5) == pytest.approx(math.sqrt(8.0), rel=1e-12)
    assert fair.time_to_error(pts, 1e-7) is None
    best = fair.best_time_to_error({"a": pts, "b": [(1e-5, 2.5)]}, 1e-5)
    assert best == (2.5, "b")


def test_floor_rule_stops_where_the_error_stops_falling():
    assert not fair.floor_reached([1e-3, 1e-4])
    assert not fair.floor_reached([1e-3, 1e-4, 1e-5])           # still falling
    assert fair.floor_reached([1e-3, 1e-6, 8e-7, 9e-7])         # two refinements, no halving
    assert fair.floor_reached([1e-3, 1e-10])                    # below the finest level
    assert fair.floor([3e-7, 1e-7, 2e-7]) == 1e-7


def test_sweep_stops_at_floor_and_reports_why():
    errors = {1: 1e-3, 2: 1e-5, 3: 6e-6, 4: 7e-6, 5: 1e-12}

    def measure(level):
        return {"error": errors[level], "solve_seconds": 1e-3, "status": "ok"}

    rows, stop = fair.sweep([1, 2, 3, 4, 5], measure)
    assert stop == "floor" and len(rows) == 4
    rows, stop = fair.sweep([1, 5, 2], measure)
    assert stop == "reached" and len(rows) == 2
    rows, stop = fair.sweep([1, 2], lambda lv: {"error": errors[lv], "solve_seconds": 99.0},
                            cap=10.0)
    assert stop == "time cap" and len(rows) == 1


def test_timed_keeps_the_cold_run_apart_and_takes_the_best_warm_run():
    times = iter([5.0, 0.3, 0.2, 0.4])
    out = fair.timed(lambda: (next(times), {"error": 1.0}), repeat=3, long_run=10.0)
    assert out["cold_seconds"] == 5.0 and out["solve_seconds"] == 0.2 and out["repeats"] == 3
    # a cold run above long_run leaves two warm runs
    times = iter([5.0, 0.3, 0.2])
    out = fair.timed(lambda: (next(times), {}), repeat=3, long_run=1.0)
    assert out["repeats"] == 2 and out["solve_seconds"] == 0.2
