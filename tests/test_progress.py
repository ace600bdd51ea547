"""Progress bars (issue 10 item 3): shown only on a terminal (or when forced), quiet in JSON
mode, and never a change to the numbers."""

from __future__ import annotations

import io
import json
import pathlib
import time

import numpy as np
import pytest

import casmbd
from casmbd import cli, progress

ROOT = pathlib.Path(__file__).resolve().parent.parent


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
