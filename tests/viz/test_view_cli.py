"""``casmbd view`` without a browser: the missing ``[view]`` extra, bad ``--html`` and
``--port`` values, and the HTML file's contents (viser's client and the recording inlined).
The browser checks are in tests/viz/test_view_browser.py."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "examples" / "spatial_slider_crank.toml"
HAVE_VISER = all(importlib.util.find_spec(m) for m in ("viser", "trimesh"))


def run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)


def test_missing_viser_names_the_extra(tmp_path):
    """Without viser the verb fails with one line naming ``pip install "casmbd[view]"`` and
    writes nothing; ``casmbd.view`` raises the same AnalysisError."""
    out = tmp_path / "v.html"
    proc = run("import sys; sys.modules['viser'] = None\n"
               "from casmbd.cli import main\n"
               f"sys.exit(main(['view', {str(SCENE)!r}, '--html', {str(out)!r}]))")
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert 'pip install "casmbd[view]"' in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()
    proc = run("import sys; sys.modules['viser'] = None\n"
               "import casmbd\n"
               "try:\n"
               f"    casmbd.view(casmbd.load_scene({str(SCENE)!r}))\n"
               "except casmbd.AnalysisError as exc:\n"
               "    print('refused:', exc)")
    assert proc.stdout.startswith("refused:") and "casmbd[view]" in proc.stdout


@pytest.mark.parametrize("args, message", [
    (["--port", "70000"], "must be a TCP port"),
    (["--port", "0"], "must be"),
])
def test_bad_port_is_a_usage_error(args, message):
    proc = subprocess.run([sys.executable, "-m", "casmbd", "view", str(SCENE), *args],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 2 and message in proc.stderr


@pytest.mark.skipif(not HAVE_VISER, reason='viser/trimesh missing: pip install "casmbd[view]"')
@pytest.mark.parametrize("name, message", [
    ("missing/v.html", "does not exist"),
    ("v.txt", "must end in .html"),
    (".", "is a directory"),
])
def test_bad_html_file_is_refused_before_the_work(tmp_path, capsys, name, message):
    """A missing folder, a suffix other than .html, a directory: one error line naming
    --html, nothing written."""
    from casmbd.cli import main

    target = tmp_path / name
    assert main(["view", str(SCENE), "--html", str(target)]) == 1
    err = capsys.readouterr().err
    assert "--html" in err and message in err
    assert not (tmp_path / "v.txt").exists()


@pytest.mark.skipif(not HAVE_VISER, reason='viser/trimesh missing: pip install "casmbd[view]"')
def test_html_file_is_self_contained(tmp_path):
    """The file holds viser's client and the recording (base64) and loads nothing from the
    network: no http(s) script or stylesheet source; the recording holds every frame."""
    import re

    from casmbd.viz.view_html import write_html
    from casmbd.viz.view_types import Shape, ViewModel

    t = np.linspace(0.0, 1.0, 11)
    pos = np.stack([t, 0 * t, 0 * t], axis=1)
    wxyz = np.tile([1.0, 0, 0, 0], (11, 1))
    vm = ViewModel(times=t, body_positions={"b": pos}, body_wxyz={"b": wxyz},
                   shapes=[Shape("s", "b", "box", (0.1, 0.1, 0.1))],
                   events=[(0.5, "impact")], title="t")
    info = write_html(vm, tmp_path / "v.html")
    text = (tmp_path / "v.html").read_text()
    assert (info["frames"], info["bodies"], info["shapes"], info["events"]) == (11, 1, 1, 1)
    assert "window.__VISER_EMBED_DATA__=" in text
    assert not re.search(r"<(script|link)[^>]+(src|href)=\"https?://", text)
    assert not list(tmp_path.glob(".tmp_casmbd*"))  # the atomic write left nothing behind


@pytest.mark.skipif(not HAVE_VISER, reason='viser/trimesh missing: pip install "casmbd[view]"')
def test_view_html_of_a_result_an_ocp_solution_and_a_urdf(tmp_path):
    """``casmbd view X --html F --json`` from a result file (its time grid: steps + 1 frames),
    an OCP solution file (its nodes) and a URDF robot with meshes (one frame, every link)."""
    import json

    from casmbd.io.ocp_table import load_ocp

    def view(source) -> dict:
        out = tmp_path / f"{Path(source).stem}.html"
        proc = subprocess.run([sys.executable, "-m", "casmbd", "view", str(source), "--html",
                               str(out), "--json"], capture_output=True, text=True,
                              timeout=180, cwd=ROOT)
        assert proc.returncode == 0, proc.stderr
        data = json.loads(proc.stdout)
        assert data["bytes"] == out.stat().st_size
        return data

    result = tmp_path / "run.npz"
    proc = subprocess.run([sys.executable, "-m", "casmbd", "simulate", str(SCENE), "--t-end",
                           "0.2", "--steps", "8", "--mode", "vm", "--out", str(result)],
                          capture_output=True, text=True, timeout=180, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    data = view(result)
    assert (data["frames"], data["bodies"]) == (9, 3)
    ocp = load_ocp(ROOT / "ocp" / "double_pendulum_swingup.toml")
    ocp.intervals, ocp.subintervals, ocp.compile = 10, 1, False
    solution = tmp_path / "swing.npz"
    ocp.solve().save(solution)
    data = view(solution)
    assert data["frames"] >= 11 and data["bodies"] == 2
    data = view(ROOT / "tests" / "robots" / "mesh_arm" / "mesh_arm.urdf")
    assert data["frames"] == 1 and data["bodies"] >= 3
