"""The event loop's economies (issue 31) change no number, and the event-count projection.

* the trial times of the root finding screened in one integrator call, and the integrators
  and gap values called through CasADi FunctionBuffers: the bouncing ball (e = 0.8) on a
  coarse grid — every bounce inside one sub-interval, the case these serve — against the
  closed form t_1 = sqrt(2 h/g),
  t_(k+1) = t_k + 2 e^k sqrt(2 h g)/g, and the same run without the screen (identical events);
* :func:`~casmbd.analysis.events.guards.periodic_overrun` on constructed impact times, and the ball
  of restitution 1 with t_end far beyond its event bound: stopped early (after
  :data:`~casmbd.analysis.events.guards.PROJECT_AFTER` events), named, the results kept.

No timing is asserted (the per-event cost is in benchmarks/contact_events.py).  The virtual
machine (``CASMBD_COMPILE=0``).
"""

from __future__ import annotations

import math
import pathlib

import casadi as ca
import numpy as np
import pytest
from conftest import private_cache

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.events.guards import PROJECT_AFTER, periodic_overrun
from casmbd.analysis.events.phases import Phase
from casmbd.analysis.integrators import sundials as sun
from casmbd.compiled.buffered import BufferedFunction
from casmbd.errors import IntegratorError
from casmbd.io.scene import loads_scene

_vm = private_cache("cache_events_speed", CASMBD_COMPILE="0")

BALL = (pathlib.Path(__file__).resolve().parents[3] / "examples" /
        "bouncing_ball.toml").read_text()
G = 9.81
T1 = math.sqrt(2.0 / G)  # the first impact, h = 1 m


def closed_form(count: int, e: float, h: float = 1.0) -> np.ndarray:
    """t_1 = sqrt(2 h/g), t_(k+1) = t_k + 2 e^k sqrt(2 h g)/g."""
    times = [math.sqrt(2.0 * h / G)]
    for k in range(1, count):
        times.append(times[-1] + 2.0 * e ** k * math.sqrt(2.0 * h * G) / G)
    return np.array(times)


def impacts(result) -> np.ndarray:
    return np.array([e["time"] for e in result.events if e["kind"] == "impact"])


@pytest.fixture(scope="module")
def coarse():
    """e = 0.8 on one output interval of 5 s (4 sub-intervals of 1.25 s)."""
    return simulate(loads_scene(BALL), t_end=5.0, steps=1, rtol=1e-13, mode="vm")


def test_coarse_grid_impacts_match_the_closed_form(coarse):
    found = impacts(coarse)
    # the rest cut, as on the fine grid (tests/analysis/events/test_contacts.py)
    assert len(found) == 47
    err = np.abs(found - closed_form(len(found), 0.8))
    assert err[:20].max() < 1e-9  # measured 1.1e-10 s
    assert err.max() < 1e-7  # the late, tiny bounces: position-limited (measured 2e-8 s)


def test_screen_changes_no_event(coarse, monkeypatch):
    """Without the one-call screen (every trial time integrated on its own, as before issue
    31) the events are the same to the last bit: the screen only picks the trial time,
    which is then integrated as before."""
    def refuse(*args, **kwargs):
        raise RuntimeError("screen off")

    monkeypatch.setattr(Phase, "advance_dyadic", refuse)
    plain = simulate(loads_scene(BALL), t_end=5.0, steps=1, rtol=1e-13, mode="vm")
    assert [(e["time"], e["kind"]) for e in plain.events] == \
        [(e["time"], e["kind"]) for e in coarse.events]
    np.testing.assert_array_equal(plain["q"], coarse["q"])


def test_buffered_integrator_equals_the_function_call():
    x = ca.MX.sym("x", 2)
    s = ca.MX.sym("t")
    p = ca.MX.sym("p", 3)
    f = ca.Function("f", [s, x, ca.MX.sym("z", 0), p, ca.MX.sym("u", 0)],
                    [p[-1] * ca.vertcat(x[1], -G * ca.cos(x[0])), ca.MX(0, 1), ca.MX(0, 1),
                     ca.MX(0, 1)], ca.dyn_in(), ca.dyn_out())
    solver = sun.sundials(f, "adams", 0.0, [0.25, 0.5, 1.0], 1e-10, 1e-10, 10_000)
    args = {"x0": [0.3, -1.0], "p": [0.0, 0.0, 2.0]}
    direct = solver(**args)
    steps = solver.stats()["nsteps"]
    wrapped = BufferedFunction.of(solver)
    buffered = wrapped.all(**args)
    np.testing.assert_array_equal(buffered[0], np.asarray(direct["xf"]))  # exact: same code
    assert buffered[0].shape == (2, 3)
    assert wrapped.stats()["nsteps"] == steps > 10  # the statistics of its own call
    wrapped.all(x0=[0.3, -1.0], p=[0.0, 0.0, 0.5])  # a quarter of the span: fewer steps
    assert 0 < wrapped.stats()["nsteps"] < steps


@pytest.mark.parametrize("times, t_end, budget, expected", [
    (list(0.9 * np.arange(12)), 100.0, 50, (0.9, 98)),  # floor((100 - 9.9)/0.9) = 100
    (list(0.9 * np.arange(12)), 100.0, 200, None),  # within the budget
    (list(0.9 * np.arange(11)), 100.0, 50, None),  # too few impacts to judge
    (list(np.cumsum(0.8 ** np.arange(12))), 100.0, 50, None),  # shrinking (Zeno)
    (list(0.9 * np.arange(12) + 1e-3 * (np.arange(12) % 2)), 100.0, 50, None),  # jitter
])
def test_periodic_overrun(times, t_end, budget, expected):
    found = periodic_overrun(times, t_end, budget)
    if expected is None:
        assert found is None
    else:
        assert found[0] == pytest.approx(expected[0], rel=1e-12)
        assert found[1] == math.floor((t_end - times[-1]) / found[0])
        assert found[1] > budget


def test_elastic_ball_stops_when_the_projection_exceeds_max_events():
    """e = 1 to t_end = 1e4 s: ~11 000 impacts, max_events 5000 — stopped at the impact that
    makes PROJECT_AFTER events, named; the impacts before it at (2k − 1) t_1, kept."""
    mech = loads_scene(BALL.replace("restitution = 0.8", "restitution = 1.0"))
    with pytest.raises(IntegratorError) as exc:
        simulate(mech, t_end=1e4, steps=2, mode="vm", max_events=5000)
    err = exc.value
    assert err.flag == "MAX_EVENTS"
    text = str(err)
    for fragment in ("more than 5000 events", "'floor' repeat every 0.903", "max_events",
                     "results kept"):
        assert fragment in text, (fragment, text)
    found = impacts(err.partial)  # up to the state before the stopping impact
    assert len(found) == PROJECT_AFTER - 1
    # the period drifts by 3.4e-9 relative per flight (rtol 1e-8): 3.4e-6 after 1000 flights
    assert err.time == pytest.approx((2 * PROJECT_AFTER - 1) * T1, rel=1e-5)
    np.testing.assert_allclose(found, (2 * np.arange(1, PROJECT_AFTER) - 1) * T1, rtol=1e-5)
    # below PROJECT_AFTER events the bound counts events one by one (no projection)
    with pytest.raises(IntegratorError) as small:
        simulate(mech, t_end=1e4, steps=2, mode="vm", max_events=20)
    assert "more than 20 events by t = " in str(small.value)
    assert len(impacts(small.value.partial)) == 20
