"""The text summaries and the ``"summary"`` JSON key of ``simulate``, ``inverse``, ``statics``
and ``linearize``: requests (``[[outputs]]``) and named nodes' deflections (issue 32, item 3).

References:

* a rod pendulum (m = 1 kg, L = 1 m, pinned at one end, released at θ0 = −0.3 rad): the tip
  height y_tip = L sin θ.  Statics hangs it at θ = −π/2, tip at −L (closed form, bound 1e-9);
  linearize about the initial configuration gives L sin θ0 (1e-12) and about the equilibrium
  −L (1e-9); driven by θ = θ0 + ω t (inverse dynamics) the tip height on the grid is
  L sin(θ0 + ω t_k) (1e-9);
* the summary of a run equals what the result arrays give (start, end, extremes and the times
  they are reached, by numpy on ``Result.output``): 1e-12 in the JSON, the printed digits in
  the text;
* a cantilever of Kane's beam (tests/flexible_references.py: L = 10 m, EI = 1.4e4 N m²,
  8 cubic Hermite elements, 4 Craig–Bampton modes with root and tip as interfaces) under a tip
  load P = 100 N: tip deflection |u| = P L³/(3 EI) (Timoshenko & Gere, app. G).  Hermite
  elements are exact at the nodes for a tip load and the tip's static constraint mode spans
  the static response, so the discretisation error is round-off: bound 1e-9 relative;
* a flexible pendulum (the same beam pinned at its root, released at 0.3 rad): each node's
  |u_i| = |Φ_i η| from the result's q and the body's modal data by numpy, to 1e-12.

Every analysis runs in CasADi's virtual machine (``--mode vm``) on a private cache.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import casmbd
from casmbd.cli import _once_per_run, main
from casmbd.cli.common import SUMMARY_ROWS
from casmbd.results import extremes
from tests.conftest import private_cache
from tests.flexible_references import KANE_BEAM

_cache = private_cache("cache_summaries", scope="module")

ROOT = Path(__file__).resolve().parents[2]
LENGTH, THETA0, OMEGA = 1.0, -0.3, 2.0
KEYS = ("start", "end", "min", "t_min", "max", "t_max")


def _pendulum(outputs: str = "", driver: bool = False) -> str:
    c, s = np.cos(THETA0), np.sin(THETA0)
    drive = f"""
[[drivers]]
name = "turn"
joint = "pin"
position = "{THETA0} + {OMEGA}*t"
""" if driver else ""
    return f"""
[scene]
name = "summary_pendulum"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "rod"
mass = 1.0
inertia = {1.0 / 12.0}
position = [{0.5 * LENGTH * c}, {0.5 * LENGTH * s}]
angle = {THETA0}

[[markers]]
name = "tip"
body = "rod"
point = [{LENGTH * c}, {LENGTH * s}]

[[joints]]
name = "pin"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
{drive}
[[outputs]]
name = "tip_height"
value = 'y("tip")'
unit = "m"

[[outputs]]
name = "swing"
value = 'angle("pin")'
unit = "rad"
{outputs}"""


def _run(capsys, *args) -> tuple[dict, str]:
    """The JSON object and the text summary of one verb."""
    assert main([*args, "--mode", "vm", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert main([*args, "--mode", "vm"]) == 0
    return data, capsys.readouterr().out


def _row(text: str, name: str) -> list[str]:
    """The cells of the summary table's row of ``name``."""
    return next(line for line in text.splitlines() if line.startswith(f"  {name} ")).split()


def _expected(t: np.ndarray, y: np.ndarray) -> dict:
    lo, hi = int(np.argmin(y)), int(np.argmax(y))
    return {"start": y[0], "end": y[-1], "min": y[lo], "t_min": t[lo], "max": y[hi],
            "t_max": t[hi]}


def _check_grid_summary(data: dict, text: str, res) -> None:
    """The JSON summary equals numpy on the result's arrays (1e-12) and the text row prints
    the same numbers (start, end, min, t_min, max, t_max, unit)."""
    summary = data["summary"]["outputs"]
    assert list(summary) == ["tip_height", "swing"]
    for name, unit in (("tip_height", "m"), ("swing", "rad")):
        want = _expected(res.t, res.output(name))
        got = summary[name]
        assert got["unit"] == unit
        for key in KEYS:
            assert got[key] == pytest.approx(want[key], abs=1e-12), (name, key)
        row = _row(text, name)
        assert row[1:] == [f"{want['start'] + 0.0:+.6g}", f"{want['end'] + 0.0:+.6g}",
                           f"{want['min'] + 0.0:+.6g}", f"{want['t_min']:.4g}",
                           f"{want['max'] + 0.0:+.6g}", f"{want['t_max']:.4g}", unit], row


def test_simulate_summary_lists_the_requests(tmp_path, capsys):
    """simulate: the table and ``summary.outputs`` equal the result's arrays; the request is
    the tip height (y of the centre + L/2 sin θ from the body's own arrays, 1e-12) and the
    pendulum released 0.3 rad below the horizontal passes the bottom within 1 s (min ≈ −L)."""
    scene = tmp_path / "pendulum.toml"
    scene.write_text(_pendulum())
    out = tmp_path / "run.npz"
    data, text = _run(capsys, "simulate", str(scene), "--t-end", "1", "--steps", "100",
                      "--out", str(out))
    res = casmbd.load_result(out)
    body = res.body("rod")
    tip = body["position"][:, 1] + 0.5 * LENGTH * np.sin(body["angle"])
    assert np.max(np.abs(res.output("tip_height") - tip)) <= 1e-12
    _check_grid_summary(data, text, res)
    assert data["summary"]["outputs"]["tip_height"]["start"] == pytest.approx(
        LENGTH * np.sin(THETA0), abs=1e-12)
    assert -LENGTH - 1e-9 <= data["summary"]["outputs"]["tip_height"]["min"] <= -0.99 * LENGTH
    assert data["outputs"]["tip_height"] == res.output("tip_height").tolist()  # kept as is
    assert "node deflection" not in text and "node_deflections" not in data["summary"]


def test_inverse_summary_against_the_driven_closed_form(tmp_path, capsys):
    """inverse: θ = θ0 + ω t driven, the tip height on the grid is L sin(θ0 + ω t_k): the
    summary's start, end and extremes (with their times) to 1e-9, and the result's arrays to
    1e-12."""
    scene = tmp_path / "driven.toml"
    scene.write_text(_pendulum(driver=True))
    out = tmp_path / "inverse.npz"
    data, text = _run(capsys, "inverse", str(scene), "--t-end", "2", "--steps", "40",
                      "--out", str(out))
    res = casmbd.load_result(out)
    _check_grid_summary(data, text, res)
    closed = _expected(res.t, LENGTH * np.sin(THETA0 + OMEGA * res.t))
    got = data["summary"]["outputs"]["tip_height"]
    for key in KEYS:
        assert got[key] == pytest.approx(closed[key], abs=1e-9), key
    assert got["t_max"] == pytest.approx(0.95, abs=1e-12)  # θ0 + ω t nearest π/2 on the grid
    assert got["t_min"] == pytest.approx(2.0, abs=1e-12)   # θ = 3.7 rad: sin −0.53 < sin θ0


def test_statics_and_linearize_give_the_request_at_their_state(tmp_path, capsys):
    """statics hangs the rod: tip height −L and swing −π/2 (closed form, 1e-9); linearize
    about the initial configuration: L sin θ0 (1e-12), about the equilibrium: −L (1e-9), and
    about a stored state the result's value at that time (1e-8: the state is re-assembled)."""
    scene = tmp_path / "pendulum.toml"
    scene.write_text(_pendulum())
    data, text = _run(capsys, "statics", str(scene))
    summary = data["summary"]["outputs"]
    assert summary["tip_height"] == {"unit": "m", "value": pytest.approx(-LENGTH, abs=1e-9)}
    assert summary["swing"]["value"] == pytest.approx(-np.pi / 2, abs=1e-9)
    assert data["outputs"]["tip_height"] == summary["tip_height"]["value"]  # kept as is
    assert _row(text, "tip_height")[1:] == [f"{summary['tip_height']['value'] + 0.0:+.6g}",
                                            "m"]
    assert abs(float(_row(text, "tip_height")[1]) + LENGTH) <= 1e-5  # printed: 6 digits

    data, text = _run(capsys, "linearize", str(scene))
    assert data["summary"]["outputs"]["tip_height"]["value"] == pytest.approx(
        LENGTH * np.sin(THETA0), abs=1e-12)
    assert data["outputs"]["swing"] == pytest.approx(THETA0, abs=1e-12)
    assert _row(text, "tip_height")[1] == f"{LENGTH * np.sin(THETA0):+.6g}"

    data, text = _run(capsys, "linearize", str(scene), "--at-equilibrium")
    assert data["summary"]["outputs"]["tip_height"]["value"] == pytest.approx(-LENGTH,
                                                                              abs=1e-9)
    assert _row(text, "swing")[1:] == [f"{data['outputs']['swing'] + 0.0:+.6g}", "rad"]

    out = tmp_path / "run.npz"
    assert main(["simulate", str(scene), "--t-end", "0.5", "--steps", "10", "--mode", "vm",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    res = casmbd.load_result(out)
    data, _ = _run(capsys, "linearize", str(scene), "--from", str(out), "--time", "0.3")
    k = int(np.argmin(np.abs(res.t - 0.3)))
    assert data["t"] == pytest.approx(res.t[k], abs=1e-12)
    assert data["summary"]["outputs"]["tip_height"]["value"] == pytest.approx(
        res.output("tip_height")[k], abs=1e-8)


def test_a_long_list_of_requests_is_cut(tmp_path, capsys):
    """25 requests: the table shows the first SUMMARY_ROWS (20) and one line for the rest;
    the JSON has all of them."""
    extra = "".join(f"""
[[outputs]]
name = "h{k:02d}"
value = '{k}*y("tip")'
unit = "m"
""" for k in range(23))
    scene = tmp_path / "many.toml"
    scene.write_text(_pendulum(extra))
    data, text = _run(capsys, "simulate", str(scene), "--t-end", "0.1", "--steps", "2")
    assert len(data["summary"]["outputs"]) == 25
    lines = text.splitlines()
    header = next(k for k, line in enumerate(lines) if line.startswith("  output "))
    assert lines[header + SUMMARY_ROWS + 1] == "  … 5 more, see --json 'summary' / --out"
    assert lines[header + SUMMARY_ROWS].startswith("  h17 ")
    assert "  h18 " not in text
    data, text = _run(capsys, "statics", str(scene))
    assert "  … 5 more, see --json 'summary'" in text.splitlines()


def test_extremes_skip_nan_values():
    """A request that is NaN at some times (a square root of a negative value): start and end
    as they are, the extremes over the finite values at their first time; none finite: None
    (the CLI writes null, the table '-')."""
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    got = extremes(t, np.array([np.nan, 3.0, -1.0, 3.0, np.nan]))
    assert np.isnan(got["start"]) and np.isnan(got["end"])
    assert (got["min"], got["t_min"], got["max"], got["t_max"]) == (-1.0, 1.0, 3.0, 0.5)
    got = extremes(t, np.full(5, np.nan))
    assert got["min"] is got["t_min"] is got["max"] is got["t_max"] is None


# ------------------------------------------------------------------ flexible bodies
L, EI, EA, RHOA = (KANE_BEAM[k] for k in ("length", "EI", "EA", "rhoA"))
P = 100.0  # tip load [N]
TIP = P * L**3 / (3 * EI)  # |u_tip| = 2.380952 m


def _beam(angle: float = 0.0) -> str:
    return f"""
[[bodies]]
name = "beam"
type = "flexible"
position = [0.0, 0.0]
angle = {angle}
modes = 4
interfaces = ["root", "tip"]
[bodies.beam]
length = {L}
elements = 8
EI = {EI}
EA = {EA}
rhoA = {RHOA}
nodes = {{ root = 0.0, mid = {L / 2}, tip = {L} }}
"""


_CANTILEVER = f"""
[scene]
name = "cantilever"
dimension = 2
gravity = [0.0, 0.0]
{_beam()}
[[joints]]
name = "clamp"
type = "fixed"
body = "beam"
node = "root"

[[forces]]
name = "load"
type = "force"
body = "beam"
node = "tip"
value = [0.0, {-P}]
"""

_FLEX_PENDULUM = f"""
[scene]
name = "flexible_pendulum"
dimension = 2
gravity = [0.0, -9.81]
{_beam(angle=0.3)}
[[joints]]
name = "hub"
type = "revolute"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0]
"""


def test_cantilever_tip_deflection_in_statics_and_linearize(tmp_path, capsys):
    """statics: the tip node's |u| is P L³/(3 EI) (1e-9 relative, see the module docstring),
    equal to the norm of the node's deflection in ``nodes`` (1e-12); the root does not move;
    the text row prints |u| and the components; linearize at the equilibrium gives the same."""
    scene = tmp_path / "cantilever.toml"
    scene.write_text(_CANTILEVER)
    data, text = _run(capsys, "statics", str(scene))
    nodes = data["summary"]["node_deflections"]
    assert list(nodes) == ["beam@root", "beam@mid", "beam@tip"]
    for name, node in nodes.items():
        assert node["unit"] == "m"
        assert node["value"] == pytest.approx(np.linalg.norm(data["nodes"][name]["deflection"]),
                                              abs=1e-12)
        assert node["deflection"] == data["nodes"][name]["deflection"]
    assert nodes["beam@tip"]["value"] == pytest.approx(TIP, rel=1e-9)
    assert nodes["beam@tip"]["deflection"][1] == pytest.approx(-TIP, rel=1e-9)
    assert nodes["beam@root"]["value"] <= 1e-12
    row = _row(text, "beam@tip")
    assert row[1] == f"{nodes['beam@tip']['value']:.6g}" == f"{TIP:.6g}"
    assert f"{-TIP:+.6g}]" in row[-1]

    data, text = _run(capsys, "linearize", str(scene), "--at-equilibrium")
    tip = data["summary"]["node_deflections"]["beam@tip"]
    assert tip["value"] == pytest.approx(TIP, rel=1e-9)
    assert _row(text, "beam@tip")[1] == f"{TIP:.6g}"


def test_flexible_pendulum_node_deflections_in_simulate(tmp_path, capsys):
    """simulate: each node's start, end and max |u| (with its time) equal |Φ_i η| computed by
    numpy from the result's q and the body's modal data (1e-12 in the JSON, the printed digits
    in the text); it starts undeformed and bends as it swings."""
    scene = tmp_path / "flex.toml"
    scene.write_text(_FLEX_PENDULUM)
    out = tmp_path / "flex.npz"
    data, text = _run(capsys, "simulate", str(scene), "--t-end", "0.6", "--steps", "12",
                      "--out", str(out))
    res = casmbd.load_result(out)
    modal = casmbd.loads_scene(_FLEX_PENDULUM).bodies["beam"].modal
    names = res.names["coordinates"]
    eta = res["q"][:, [k for k, n in enumerate(names) if n.startswith("beam.eta")]]
    summary = data["summary"]["node_deflections"]
    assert list(summary) == ["beam@root", "beam@mid", "beam@tip"]
    for name in summary:
        size = np.linalg.norm(eta @ modal.phi_t[modal.node_names[name.split("@")[1]]].T, axis=1)
        k = int(np.argmax(size))
        got = summary[name]
        assert got["unit"] == "m"
        for key, want in (("start", size[0]), ("end", size[-1]), ("max", size[k]),
                          ("t_max", res.t[k])):
            assert got[key] == pytest.approx(want, abs=1e-12), (name, key)
        row = _row(text, name)
        assert row[1:5] == [f"{size[0] + 0.0:.6g}", f"{size[-1]:.6g}", f"{size[k]:.6g}",
                            f"{res.t[k]:.4g}"], row
    assert summary["beam@tip"]["start"] <= 1e-12 and summary["beam@tip"]["max"] > 1e-3
    assert summary["beam@root"]["max"] <= 1e-9 * summary["beam@tip"]["max"]


# ------------------------------------------------------------------ the URDF notice
def test_a_notice_is_said_once_per_command():
    """``_once_per_run`` (installed by ``main``) lets each warning text through once, wherever
    it is raised from (Python's default filter repeats it from another line); another text
    still passes."""
    said = []
    show = _once_per_run(lambda message, *rest: said.append(str(message)))
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        saved = warnings.showwarning
        warnings.showwarning = show
        try:
            for _ in range(3):
                warnings.warn("URDF 'arm': 3 <visual>/<collision> elements ignored",
                              stacklevel=1)
            warnings.warn("URDF 'arm': 3 <visual>/<collision> elements ignored", stacklevel=1)
            warnings.warn("another notice", stacklevel=1)
        finally:
            warnings.showwarning = saved
    assert said == ["URDF 'arm': 3 <visual>/<collision> elements ignored", "another notice"]


def test_urdf_notice_at_most_once_per_animate(tmp_path):
    """``casmbd animate`` of a URDF robot with <visual>/<collision> elements loads the scene
    several times (the scene, the result's embedded scene, the animation): any notice about
    them is said at most once on stderr (it was said three times)."""
    gif = tmp_path / "ur5.gif"
    run = subprocess.run(
        [sys.executable, "-m", "casmbd", "animate", str(ROOT / "examples" / "ur5_arm.urdf"),
         "--out", str(gif), "--t-end", "0.1", "--steps", "2", "--mode", "vm"],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT), "CASMBD_PROGRESS": "0"})
    assert run.returncode == 0, run.stderr
    assert gif.is_file()
    assert run.stderr.count("<visual>") <= 1, run.stderr
    assert len([line for line in run.stderr.splitlines() if "URDF" in line]) <= 1, run.stderr
