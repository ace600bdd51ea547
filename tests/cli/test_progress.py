"""Progress bars (issue 10 item 3): shown only on a terminal (or when forced), quiet in JSON
mode, and never a change to the numbers."""

from __future__ import annotations

import io
import json
import pathlib
import time
from typing import ClassVar

import numpy as np
import pytest

import casmbd
from casmbd import cli, progress

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_bar_draws_after_a_second_when_forced(monkeypatch):
    pytest.importorskip("tqdm")
    sink = io.StringIO()
    monkeypatch.setattr(progress, "_TERMINAL", sink)
    monkeypatch.setenv("CASMBD_PROGRESS", "1")
    with progress.bar(3, "loop", "step") as bar:
        for _ in range(3):
            time.sleep(0.45)
            bar.update()
    assert "loop" in sink.getvalue() and "3/3" in sink.getvalue()


def test_quiet_when_disabled_or_short(monkeypatch):
    sink = io.StringIO()
    monkeypatch.setattr(progress, "_TERMINAL", sink)
    monkeypatch.setenv("CASMBD_PROGRESS", "0")
    assert not progress.enabled()
    with progress.bar(3, "loop") as bar:
        bar.update(3)
    monkeypatch.setenv("CASMBD_PROGRESS", "1")
    with progress.bar(3, "short") as bar:  # under tqdm's one-second delay: nothing drawn
        bar.update(3)
    assert sink.getvalue() == ""


def test_progress_does_not_change_results(monkeypatch):
    """A fixed-step and a projected run with bars forced on equal the runs without, bit for
    bit."""
    monkeypatch.setattr(progress, "_TERMINAL", io.StringIO())
    mech = casmbd.load_scene(ROOT / "examples" / "double_pendulum.toml")
    runs = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("CASMBD_PROGRESS", flag)
        runs[flag] = (casmbd.simulate(mech, 0.5, 20, integrator="rk4", step=1e-3),
                      casmbd.simulate(mech, 0.5, 20, projection=True))
    for a, b in zip(runs["0"], runs["1"]):
        np.testing.assert_array_equal(a["q"], b["q"])


def test_json_mode_turns_bars_off(monkeypatch, capsys):
    monkeypatch.setenv("CASMBD_PROGRESS", "1")
    assert cli.main(["info", str(ROOT / "examples" / "slider_crank.toml"), "--json"]) == 0
    json.loads(capsys.readouterr().out)
    import os

    assert os.environ["CASMBD_PROGRESS"] == "0"


def test_ocp_solve_shows_ipopt_iterations_and_keeps_its_optimum(monkeypatch):
    """An OCP solve longer than a second draws a bar of IPOPT iterations (through IPOPT's
    iteration callback, forced on here) and reaches the same optimum as without it (1e-12
    relative; the callback is not part of the compiled NLP's cache key)."""
    pytest.importorskip("tqdm")
    from casmbd.io.ocp_table import load_ocp

    sink = io.StringIO()
    monkeypatch.setattr(progress, "_TERMINAL", sink)
    sols = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("CASMBD_PROGRESS", flag)
        ocp = load_ocp(ROOT / "ocp" / "double_pendulum_swingup.toml")
        ocp.compile, ocp.intervals, ocp.subintervals = False, 20, 1
        ocp.solver_options = {"ipopt.max_iter": 40}
        if flag == "1":
            # make every iteration slow enough for tqdm's one-second delay
            def slow_bar(total, desc, unit="it", original=progress.bar):
                bar = original(total, desc, unit)
                update = bar.update

                def update_slowly(n=1):
                    time.sleep(0.1)
                    update(n)
                bar.update = update_slowly
                return bar
            monkeypatch.setattr(progress, "bar", slow_bar)
        sols[flag] = ocp.solve()
    text = sink.getvalue()
    assert "IPOPT" in text and "iter" in text and "objective" in text
    assert abs(sols["1"].objective - sols["0"].objective) < 1e-12 * sols["0"].objective
    assert sols["1"].iterations == sols["0"].iterations


class _Recorder:
    """A stand-in for progress.bar recording its total and every update."""

    made: ClassVar[list] = []

    def __init__(self, total, desc, unit="it"):
        self.total, self.desc, self.unit, self.updates = total, desc, unit, []
        _Recorder.made.append(self)

    def update(self, n=1):
        self.updates.append(n)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


@pytest.mark.parametrize("scene, integrator, formulation", [
    ("double_pendulum.toml", "adams", None),     # CVODES Adams (the default is DOPRI5)
    ("double_pendulum.toml", "cvodes", None),    # CVODES BDF
    ("slider_crank.toml", "idas", "index1"),     # IDAS on a DAE
])
def test_sundials_bar_counts_outputs_and_keeps_results(monkeypatch, scene, integrator,
                                                       formulation):
    """A SUNDIALS run with the bar forced on (one integrator call whose dynamics carry a
    zero quadrature clocked by the step times) equals the run without it bit for bit:
    states, step counts, right-hand-side evaluations; the bar counts the 40 output
    intervals as the integrator passes them (most one by one), while its Python callback
    runs only for the steps that end in the first eighth of an output interval (fewer than
    half of the steps)."""
    monkeypatch.setenv("CASMBD_COMPILE", "0")
    monkeypatch.setattr(progress, "_TERMINAL", io.StringIO())
    calls = []
    clock_eval = progress._OutputClock.eval_buffer

    def counted(self, arg, res):
        calls.append(1)
        return clock_eval(self, arg, res)

    monkeypatch.setattr(progress._OutputClock, "eval_buffer", counted)
    mech = casmbd.load_scene(ROOT / "examples" / scene)
    runs = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("CASMBD_PROGRESS", flag)
        _Recorder.made = []
        monkeypatch.setattr(progress, "bar", _Recorder)
        runs[flag] = casmbd.simulate(mech, 2.0, 40, integrator=integrator,
                                     formulation=formulation)
        bars = list(_Recorder.made)
        if flag == "0":
            assert bars == []  # no bar: the plain one-call path
    assert len(bars) == 1 and bars[0].total == 40 and bars[0].unit == "output"
    assert sum(bars[0].updates) == 40 and len(bars[0].updates) >= 20, bars[0].updates
    assert 20 <= len(calls) < 0.5 * runs["1"].stats["steps"], (len(calls), runs["1"].stats)
    a, b = runs["0"], runs["1"]
    for key in ("q", "v", "a"):
        np.testing.assert_array_equal(a[key], b[key])
    for key in ("steps", "rhs_evaluations", "error_test_failures", "integrator"):
        assert a.stats[key] == b.stats[key]


def test_sundials_bar_keeps_the_failure_time(monkeypatch):
    """A run that fails (CV_TOO_MUCH_WORK after 60 steps) fails at the same SUNDIALS time
    and keeps the same outputs with the bar forced on (exactly)."""
    from casmbd.errors import IntegratorError

    monkeypatch.setenv("CASMBD_COMPILE", "0")
    monkeypatch.setattr(progress, "_TERMINAL", io.StringIO())
    mech = casmbd.load_scene(ROOT / "examples" / "double_pendulum.toml")
    errors = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("CASMBD_PROGRESS", flag)
        with pytest.raises(IntegratorError) as info:
            casmbd.simulate(mech, 5.0, 50, formulation="kkt_ode", integrator="adams",
                            rtol=1e-10, max_steps=60)
        errors[flag] = info.value
    a, b = errors["0"], errors["1"]
    assert a.flag == b.flag == "CV_TOO_MUCH_WORK"
    assert a.time == b.time and 0.0 < a.time < 5.0
    np.testing.assert_array_equal(a.partial["q"], b.partial["q"])
