"""``casmbd view`` in a real browser (issue 32, item 1): headless Chromium loads the live page
and the ``--html`` file, the scene holds the expected shapes, moving the time slider *in the
page* moves the bodies to the result's poses (read back from three.js, to 1e-6 m), and a
screenshot is not blank.

The result: the spatial slider-crank of the examples, simulated for 0.5 s (50 steps, CasADi's
virtual machine).  Each shape gets a unique colour, and a reference box of its own colour sits
at the ground origin: its world matrix in the page is the rotation viser applies to the whole
scene (z up), which the read-back removes (tests/browser_probe.py).  Expected poses: a point u
fixed in body b is at r_b + A_b u (A_b from the result's unit quaternion), a capsule's end
spheres at ±length/2 along its local z.

Skipped (with the reason) when playwright, viser/trimesh or Chromium is missing; .ci/run
installs them where it can.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests import browser_probe as bp

REASON = bp.unavailable()
pytestmark = pytest.mark.skipif(REASON is not None, reason=f"browser test: {REASON}")

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "examples" / "spatial_slider_crank.toml"
REF = (1, 2, 3)  # colour of the reference box
TOL = 1e-6  # [m] and [-] (rotation matrix entries)


def quat_matrix(q) -> np.ndarray:
    """Rotation matrix of the unit quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@pytest.fixture(scope="module")
def view():
    """The ViewModel of a 50-step simulation, shapes recoloured uniquely, plus the reference
    box; and the result's own poses to compare with."""
    import casmbd
    from casmbd.viz.view_model import view_model
    from casmbd.viz.view_types import Shape

    mech = casmbd.load_scene(SCENE)
    result = casmbd.simulate(mech, t_end=0.5, steps=50, mode="vm")
    vm = view_model(result, mech)
    for k, s in enumerate(vm.shapes):
        s.color = (20 + 7 * k, 200 - 9 * k, 90 + 5 * k)
    vm.shapes.append(Shape("reference", "ground", "box", (0.01, 0.01, 0.01), color=REF))
    return vm, result


@pytest.fixture(scope="module")
def chromium():
    """One headless Chromium for the module's pages (each page in its own context)."""
    with bp.browser() as b:
        yield b


def expected_colors(vm) -> dict[str, int]:
    """Meshes per colour: one per shape, three per capsule (cylinder and two spheres)."""
    return {bp.hex_color(s.color): 3 if s.kind == "capsule" else 1 for s in vm.shapes}


def result_pose(result, body: str, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass and rotation matrix of ``body`` at output ``i``, from the result's own
    arrays (``body_positions``, ``rotation_matrices``)."""
    k = result.names["bodies"].index(body)
    r = result.arrays["body_positions"][i, 3 * k:3 * k + 3]
    return r, result.arrays["rotation_matrices"][i, 9 * k:9 * k + 9].reshape(3, 3)


def check_poses(view, meshes, i: int) -> float:
    """Largest distance between the meshes' read-back poses and the result's at output ``i``
    ([m] for points, entries of the rotation matrices of boxes)."""
    vm, result = view
    rot = bp.reference_rotation(meshes, bp.hex_color(REF))
    worst = 0.0
    for s in vm.shapes:
        if s.body == "ground":
            continue
        r_b, a_b = result_pose(result, s.body, i)
        r = r_b + a_b @ s.position
        a = a_b @ quat_matrix(s.wxyz)
        want = [r]
        if s.kind == "capsule":
            want += [r + a[:, 2] * s.size[1] / 2, r - a[:, 2] * s.size[1] / 2]
        got = bp.positions(meshes, bp.hex_color(s.color), rot)
        for w in want:
            worst = max(worst, float(np.min(np.linalg.norm(got - w, axis=1))))
        if s.kind == "box":
            (a_got,) = bp.rotations(meshes, bp.hex_color(s.color), rot)
            worst = max(worst, float(np.max(np.abs(a_got - a))))
    return worst


def wait_pose(page, view, i: int, timeout: float = 10.0) -> float:
    """Poll the page until its meshes show output ``i`` (to TOL); the last error."""
    end = time.monotonic() + timeout
    while True:
        err = check_poses(view, page.meshes(), i)
        if err < TOL or time.monotonic() > end:
            return err
        time.sleep(0.05)


def test_view_model_poses_are_the_result_ones(view):
    """The poses sent to the page (the ViewModel's) are the result's: centres of mass to
    rounding, rotations to 1e-7 (the result's matrices are orthonormal only to the integrator's
    tolerance, rtol 1e-8; the quaternion is of the nearest rotation)."""
    vm, result = view
    for body, pos in vm.body_positions.items():
        for i in (0, len(vm.times) // 2, len(vm.times) - 1):
            r, a = result_pose(result, body, i)
            np.testing.assert_allclose(pos[i], r, atol=1e-12)
            np.testing.assert_allclose(quat_matrix(vm.body_wxyz[body][i]), a, atol=1e-7)


def test_live_page_slider_moves_bodies(view, chromium, tmp_path):
    """Live page: no console errors, every shape, the slider's End/Home/ArrowRight keys move
    the bodies to outputs n-1, 0 and 3, a screenshot with contents."""
    from casmbd.viz.view_server import serve

    vm, _ = view
    with serve(vm) as handle:
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/", handle.url)
        page = bp.Page(chromium, handle.url)
        page.wait_meshes(expected_colors(vm))
        assert wait_pose(page, view, 0) < TOL
        slider = page.page.get_by_role("slider")
        assert slider.count() == 1
        slider.focus()
        n = len(vm.times)
        for key, i in (("End", n - 1), ("Home", 0), ("ArrowRight", 1), ("ArrowRight", 2),
                       ("ArrowRight", 3)):
            page.page.keyboard.press(key)
            assert wait_pose(page, view, i) < TOL, (key, i)
            assert handle.scene.index == i
        img = page.screenshot(tmp_path / "live.png")
        assert bp.pixel_spread(img) > 5.0
        assert page.errors == []
        page.close()


def test_html_file_plays_offline(view, chromium, tmp_path):
    """The --html file, opened from file:// with the network off: no console errors, no
    request but the file itself, every shape, and setting the player's time (its time field)
    between outputs k and k+1 shows output k."""
    from casmbd.viz.view_html import write_html

    vm, _ = view
    out = tmp_path / "view.html"
    info = write_html(vm, out)
    assert info["frames"] == len(vm.times) and info["bodies"] == 3
    assert info["bytes"] == out.stat().st_size
    page = bp.Page(chromium, out.as_uri(), offline=True)
    page.wait_meshes(expected_colors(vm))
    # pause first (the file plays on opening; a time set while it plays may be advanced by
    # the player's next tick before the pause takes effect)
    page.page.locator("button:has(svg.tabler-icon-player-pause-filled)").click()
    page.page.locator("button:has(svg.tabler-icon-player-play-filled)").wait_for()
    field = page.page.locator("input[inputmode=decimal]")
    t0 = vm.times[0]
    # not the last interval: a time that the player's field rounds (to 0.1 s) up to the
    # recording's duration restarts the recording (viser's loop), showing output 0
    for k in (len(vm.times) - 3, 7, 30):
        field.fill(f"{0.5 * (vm.times[k] + vm.times[k + 1]) - t0:.9f}")
        assert wait_pose(page, view, k) < TOL, k
    img = page.screenshot(tmp_path / "html.png")
    assert bp.pixel_spread(img) > 5.0
    assert page.errors == []
    assert all(u.startswith(("file:", "data:", "blob:")) for u in page.requests), \
        page.requests
    page.close()


EVIL = '<img src=x onerror="window.__pwned=1"><script>window.__pwned=2</script>'

#: in the page: per chart, its title, the cursor's x and the x of the polyline's points
#: (SVG user units; the charts are drawn at 1:1, one unit per CSS pixel)
CHARTS_JS = """() => Array.from(document.querySelectorAll('#cmbd-panel svg.cmbd-chart'))
  .map(s => ({title: s.parentElement.querySelector('h4').textContent,
              cursor: parseFloat(s.querySelector('.cmbd-cursor').getAttribute('x1')),
              scale: s.getScreenCTM().a,
              xs: Array.from(s.querySelectorAll('polyline.cmbd-line')).flatMap(
                p => p.getAttribute('points').trim().split(/\\s+/)
                      .map(xy => parseFloat(xy.split(',')[0])))}))"""


def test_html_side_panel(view, chromium, tmp_path):
    """The --html file's side panel: one chart per series (titled "name [unit]"), the
    cursor at the x of the sample at the player's time after typing that time (to 1 px),
    clicking an event sets the player's time to it (1e-3 s; the slider's aria-valuenow) and
    shows that output's poses (1e-6 m), a series name and an event label holding markup are
    shown as text (no script ran: window.__pwned unset), the panel hides and shows, no
    console errors, no network."""
    import dataclasses

    from casmbd.viz.view_html import write_html
    from casmbd.viz.view_types import Series

    vm0, _ = view
    t, dt = vm0.times, float(vm0.times[1] - vm0.times[0])
    series = [*vm0.series, Series(EVIL, "m", np.sin(3.0 * t))]
    events = [(float(t[12] + 0.3 * dt), "impact"), (float(t[-1]), EVIL)]
    vm = dataclasses.replace(vm0, series=series, events=events)
    out = tmp_path / "panel.html"
    write_html(vm, out)
    page = bp.Page(chromium, out.as_uri(), offline=True)
    page.wait_meshes(expected_colors(vm))
    p = page.page
    p.locator("button:has(svg.tabler-icon-player-pause-filled)").click()
    p.locator("button:has(svg.tabler-icon-player-play-filled)").wait_for()
    charts = p.evaluate(CHARTS_JS)
    assert [c["title"] for c in charts] == [f"{s.name} [{s.unit}]" for s in series]
    assert all(len(c["xs"]) == len(t) for c in charts)
    assert all(abs(c["scale"] - 1.0) < 1e-9 for c in charts)
    t0 = float(t[0])
    field = p.locator("input[inputmode=decimal]")
    for k in (7, 23, 38):  # not multiples of 0.1 s (the field's shown resolution)
        field.fill(f"{t[k] - t0:.9f}")
        p.wait_for_function("([t]) => Math.abs(parseFloat(document.getElementById("
                            "'cmbd-panel').dataset.time) - t) < 1e-9", arg=[float(t[k])])
        for c in p.evaluate(CHARTS_JS):
            assert abs(c["cursor"] - c["xs"][k]) <= 1.0, (k, c["title"], c["cursor"])
    slider = p.locator("[role=slider]")
    for (te, _), k in zip(events, (12, None)):
        p.locator("button.cmbd-ev").filter(has_text=f"t = {te:.6g} s").click()
        p.wait_for_timeout(200)
        tau = float(slider.get_attribute("aria-valuenow"))
        assert abs(tau - (te - t0)) < 1e-3, (te, tau)
        if k is not None:
            assert wait_pose(page, view, k) < TOL
            assert abs(float(p.evaluate("document.getElementById('cmbd-panel')"
                                        ".dataset.time")) - te) < 1e-3
    labels = p.locator("#cmbd-panel li").all_text_contents()
    assert labels[1].endswith(EVIL) and p.locator("#cmbd-panel img").count() == 0
    assert p.evaluate("window.__pwned") is None
    toggle = p.locator("#cmbd-toggle")
    toggle.click()
    assert not p.locator("#cmbd-panel").is_visible()
    toggle.click()
    assert p.locator("#cmbd-panel").is_visible()
    assert page.errors == []
    assert all(u.startswith(("file:", "data:", "blob:")) for u in page.requests), \
        page.requests
    page.close()


def test_cli_html_json_and_refusal(tmp_path):
    """``casmbd view SCENE --html F --json``: one JSON object (file, bytes, frames, bodies);
    --html onto the input file is refused and leaves it untouched."""
    out = tmp_path / "v.html"
    cmd = [sys.executable, "-m", "casmbd", "view", str(SCENE), "--html", str(out), "--json"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert (data["frames"], data["bodies"]) == (1, 3)
    assert data["bytes"] == out.stat().st_size > 100_000
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.read_text())
    proc = subprocess.run([sys.executable, "-m", "casmbd", "view", str(scene), "--html",
                           str(scene)], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 1 and "is the input file" in proc.stderr
    assert scene.read_text() == SCENE.read_text()


def test_ctrl_c_stops_the_live_view_cleanly():
    """``casmbd view SCENE --no-browser``: the URL on stderr, Ctrl-C ends with status 0, one
    summary line and no traceback."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    # a suite started in the background by a non-interactive shell (CI) ignores SIGINT, and
    # children inherit that: restore the default, as a terminal's Ctrl-C finds it
    proc = subprocess.Popen([sys.executable, "-m", "casmbd", "view", str(SCENE),
                             "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=ROOT, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = proc.stderr.readline()
        assert re.search(r"http://127\.0\.0\.1:\d+/", line), line
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=90)  # a loaded CI machine: generous
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "Traceback" not in err and out.startswith("stopped the view at http://127.0.0.1:")
