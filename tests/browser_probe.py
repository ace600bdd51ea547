"""Headless Chromium driving the pages of ``casmbd view`` (tests/viz/test_view_browser.py and
benchmarks/view_cost.py): open a page, read back the three.js scene, move the time slider.

viser's three.js objects carry no names; the page is opened with an init script that
registers a fake three.js devtools hook (``window.__THREE_DEVTOOLS__``: three.js announces each
``Scene`` to it with an ``observe`` event), so the scene graph can be traversed and every
mesh's ``matrixWorld`` read.  viser rotates its root node by the scene's up direction; the
tests place a reference box at the ground origin with a unique colour, and its world matrix is
that rotation (:func:`reference_rotation`).  Meshes are told apart by colour.

Nothing here is imported by casmbd; playwright, Chromium and viser are optional
(:func:`unavailable` says which one is missing).
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import shutil
import time
from pathlib import Path

import numpy as np

#: Debian's chromium (override with CASMBD_CHROMIUM)
CHROMIUM = os.environ.get("CASMBD_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]
VIEWPORT = {"width": 960, "height": 600}

#: before any page script: the devtools hook, and a requestAnimationFrame counter
INIT_SCRIPT = """
window.__scenes = [];
window.__THREE_DEVTOOLS__ = new EventTarget();
window.__THREE_DEVTOOLS__.addEventListener('observe', e => {
  if (e.detail && e.detail.isScene && !window.__scenes.includes(e.detail))
    window.__scenes.push(e.detail);
});
window.__t0 = performance.now();
window.__raf = 0;
(function tick() { window.__raf++; requestAnimationFrame(tick); })();
"""

#: every mesh of the captured scenes: colour, geometry type, world matrix (column-major)
MESHES_JS = """() => {
  const out = [];
  for (const s of window.__scenes) {
    s.updateMatrixWorld(true);
    s.traverse(o => {
      if (!(o.isMesh) || !o.material || !o.material.color) return;
      let vis = true;
      for (let p = o; p; p = p.parent) if (!p.visible) { vis = false; break; }
      out.push({color: o.material.color.getHexString(), type: o.type,
                geometry: o.geometry ? o.geometry.type : null, visible: vis,
                m: Array.from(o.matrixWorld.elements)});
    });
  }
  return out;
}"""


def unavailable() -> str | None:
    """Why the browser tests cannot run here, or None."""
    for mod, extra in (("playwright", "pip install playwright"),
                       ("viser", 'pip install "casmbd[view]"'),
                       ("trimesh", 'pip install "casmbd[view]"')):
        if importlib.util.find_spec(mod) is None:
            return f"{mod} is not installed ({extra})"
    if not (os.path.isfile(CHROMIUM) or shutil.which(CHROMIUM)):
        return f"no Chromium at {CHROMIUM} (apt-get install chromium, or set CASMBD_CHROMIUM)"
    return None


@contextlib.contextmanager
def browser():
    """A headless Chromium; playwright gives each launch a fresh profile in a temporary
    folder (its own --user-data-dir)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        try:
            yield b
        finally:
            b.close()


class Page:
    """A page of ``browser`` at ``url`` with its console errors collected."""

    def __init__(self, b, url: str, *, offline: bool = False,
                 watch: dict[str, int] | None = None):
        self.context = b.new_context(viewport=VIEWPORT, offline=offline)
        self.page = self.context.new_page()
        self.errors: list[str] = []
        self.requests: list[str] = []
        self.page.on("console", lambda m: m.type == "error" and self.errors.append(m.text))
        self.page.on("pageerror", lambda e: self.errors.append(f"pageerror: {e}"))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.add_init_script(INIT_SCRIPT)
        if watch is not None:  # time the opening (open_ms)
            self.page.add_init_script(f"window.__want = {json.dumps(watch)};" + OPEN_WATCH)
        self.page.goto(url)

    def close(self) -> None:
        self.context.close()

    def meshes(self) -> list[dict]:
        return self.page.evaluate(MESHES_JS)

    def wait_meshes(self, colors: dict[str, int], timeout: float = 20.0) -> float:
        """Wait until the scene holds ``colors[c]`` meshes of each colour ``c``; the time since
        the page started (ms, measured in the page)."""
        end = time.monotonic() + timeout
        while True:
            found = count_colors(self.meshes(), colors)
            if found == colors:
                return float(self.page.evaluate("performance.now() - window.__t0"))
            if time.monotonic() > end:
                raise AssertionError(f"scene meshes by colour {found}, expected {colors}")
            time.sleep(0.05)

    def screenshot(self, path: str | Path) -> np.ndarray:
        """Save a PNG and return its pixels (H, W, 3) as floats."""
        import io

        from PIL import Image

        data = self.page.screenshot(path=str(path))
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), float)


def count_colors(meshes: list[dict], colors) -> dict[str, int]:
    """How many meshes of each colour of ``colors`` the scene holds."""
    return {c: sum(1 for m in meshes if m["color"] == c) for c in colors}


def hex_color(rgb) -> str:
    return "".join(f"{int(c):02x}" for c in rgb)


def world_matrix(mesh: dict) -> np.ndarray:
    return np.asarray(mesh["m"], float).reshape(4, 4).T


def reference_rotation(meshes: list[dict], color: str) -> np.ndarray:
    """The rotation from casmbd's global frame to three.js's world: the world matrix of the
    reference box at the ground origin (columns normalised: the box may be scaled)."""
    ref = [m for m in meshes if m["color"] == color]
    assert len(ref) == 1, f"{len(ref)} reference meshes of colour {color}"
    a = world_matrix(ref[0])[:3, :3]
    return a / np.linalg.norm(a, axis=0)


def positions(meshes: list[dict], color: str, rot: np.ndarray) -> np.ndarray:
    """World positions (casmbd's frame) of the meshes of ``color`` (k, 3)."""
    pts = [rot.T @ world_matrix(m)[:3, 3] for m in meshes if m["color"] == color]
    return np.array(pts).reshape(-1, 3)


def rotations(meshes: list[dict], color: str, rot: np.ndarray) -> list[np.ndarray]:
    """Rotation matrices (casmbd's frame) of the meshes of ``color`` (scale removed)."""
    out = []
    for m in meshes:
        if m["color"] == color:
            a = world_matrix(m)[:3, :3]
            out.append(rot.T @ (a / np.linalg.norm(a, axis=0)))
    return out


def pixel_spread(img: np.ndarray) -> float:
    """Standard deviation of the grey levels of a screenshot (0 for a blank page)."""
    return float(img.mean(axis=2).std())


#: in the page, from its first script on: once per animation frame, whether the scene holds
#: ``window.__want[c]`` meshes of every colour ``c``; ``window.__openMs`` is performance.now()
#: (ms since navigation) at the next animation frame (that frame rendered them)
OPEN_WATCH = """
(function () {
  function ready() {
    if (!window.__want) return false;
    const n = {};
    for (const s of window.__scenes) s.traverse(o => {
      if (o.isMesh && o.material && o.material.color) {
        const c = o.material.color.getHexString();
        n[c] = (n[c] || 0) + 1;
      }
    });
    return Object.keys(window.__want).every(c => n[c] === window.__want[c]);
  }
  function frame() {
    if (ready()) requestAnimationFrame(() => { window.__openMs = performance.now(); });
    else requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
})();
"""

#: in the page: for ``seconds``, count animation frames and the frames in which the world
#: matrix of the (first) mesh of colour ``color`` changed
PLAY_JS = """([color, seconds]) => new Promise(resolve => {
  let frames = 0, changes = 0, last = null, t0 = null;
  function find() {
    let found = null;
    for (const s of window.__scenes) s.traverse(o => {
      if (!found && o.isMesh && o.material && o.material.color &&
          o.material.color.getHexString() === color) found = o;
    });
    return found;
  }
  function frame(now) {
    if (t0 === null) t0 = now;
    frames++;
    const m = find();
    const e = m ? m.matrixWorld.elements.join(',') : null;
    if (last !== null && e !== last) changes++;
    last = e;
    if (now - t0 < seconds * 1000) requestAnimationFrame(frame);
    else resolve({frames: frames - 1, changes, seconds: (now - t0) / 1000});
  }
  requestAnimationFrame(frame);
})"""


def open_ms(page: Page, timeout: float = 120.0) -> float:
    """Milliseconds from navigation to the first rendered frame with every mesh of the page's
    ``watch`` (in the page's clock)."""
    page.page.wait_for_function("window.__openMs !== undefined", timeout=timeout * 1000)
    return float(page.page.evaluate("window.__openMs"))


def play_rate(page: Page, color: str, seconds: float = 5.0) -> dict:
    """Animation frames per second and pose changes per second of one mesh while playing."""
    r = page.page.evaluate(PLAY_JS, [color, seconds])
    return {"fps": r["frames"] / r["seconds"], "changes_per_s": r["changes"] / r["seconds"],
            "frames": r["frames"], "changes": r["changes"], "seconds": r["seconds"]}


def tree_cpu_seconds(root: int | None = None) -> float:
    """CPU time (user + system) [s] of process ``root`` (default: this one) and all its live
    descendants (playwright's driver, Chromium's browser, GPU and renderer processes), from
    /proc (0 where /proc is missing)."""
    root = os.getpid() if root is None else root
    tick = os.sysconf("SC_CLK_TCK")
    parent, cpu = {}, {}
    for entry in Path("/proc").glob("[0-9]*"):
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        pid = int(entry.name)
        parent[pid] = int(fields[1])
        cpu[pid] = (int(fields[11]) + int(fields[12])) / tick
    total, todo = 0.0, [root]
    while todo:
        pid = todo.pop()
        total += cpu.get(pid, 0.0)
        todo += [c for c, p in parent.items() if p == pid]
    return total


def play_cost(page: Page, color: str, seconds: float = 5.0) -> dict:
    """:func:`play_rate` with the CPU time the whole process tree spent meanwhile: ``cpu_ms``
    per animation frame, and ``fps_per_core`` = frames / CPU seconds (the rate one idle core
    would sustain; a measure that holds on a machine shared with other jobs)."""
    c0 = tree_cpu_seconds()
    r = play_rate(page, color, seconds)
    cpu = tree_cpu_seconds() - c0
    r["cpu_ms"] = 1000.0 * cpu / max(r["frames"], 1)
    r["fps_per_core"] = r["frames"] / cpu if cpu > 0 else float("nan")
    return r
