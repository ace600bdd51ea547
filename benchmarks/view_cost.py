"""Cost of ``casmbd view`` on a 1000-output spatial result (issue 32, item 1): time to open and
playback rate, live and ``--html``, in headless Chromium.

The result: the UR5 arm of the examples (``examples/ur5_arm.urdf``, 6 bodies, 12 shapes),
simulated for 5 s with 1000 output intervals (1001 output times).  Each measurement opens a new
page (a new browser context) in one headless Chromium (Debian's, software WebGL: SwiftShader,
``--disable-gpu``), with tests/browser_probe.py's hooks:

* **open** — milliseconds from the navigation's start to the first animation frame after the
  one in which the three.js scene holds every shape's mesh (measured in the page:
  ``performance.now()``, polled once per animation frame from the page's first script);
* **play** — playing at 1x: animation frames per second (``requestAnimationFrame``
  callbacks) in the first 5 s after the opening and in the next 5 s (software WebGL compiles
  its shaders and viser's client adapts its pixel ratio in the first seconds), and frames per
  second in which a body's mesh actually moved (its world matrix changed) in the next 5 s.
  Live: after a click on the panel's Play button (the server sends new poses at up to 60
  updates per second); ``--html``: the file plays on opening (viser's player applies
  the recorded poses every animation frame).

On a machine shared with other jobs the wall-clock rates are what the browser got of the
CPU; the CPU time of the whole process tree (this Python process with the live server,
playwright's driver, Chromium's processes) during the second window gives a rate that does
not depend on the others' load: *CPU per frame* and *fps per core* = frames / CPU seconds.
The page's viewport is 960 x 600 CSS pixels.  Also reported: the time to write the
``--html`` file (Python, ``write_html``) and its size.  This is a measurement, not a test;
the machine's load average is recorded with it.

Run ``python -m benchmarks.view_cost [--repeat N] [--update-docs]`` (``--render`` rewrites the
docs section of docs/view.md from ``benchmarks/results/view_cost.json``).
"""

from __future__ import annotations

import os
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from benchmarks.docs import run_study, study_parser

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "view_cost.json"
DOC = ROOT / "docs" / "view.md"
HEAD = "## Cost: open and play a 1000-output result"
SCENE = ROOT / "examples" / "ur5_arm.urdf"
#: the issue's targets: open in at most 2 s, play at 30 fps or more
OPEN_BOUND, FPS_BOUND = 2.0, 30.0


def _result(tmp: Path, t_end: float = 5.0, steps: int = 1000) -> Path:
    import casmbd

    mech = casmbd.load_scene(SCENE)
    res = casmbd.simulate(mech, t_end=t_end, steps=steps)
    res.attach_scene(mech)
    path = tmp / "ur5.npz"
    res.save(path)
    return path


def _colored(vm):
    """Each shape in a colour of its own (to find the meshes in the page)."""
    for k, s in enumerate(vm.shapes):
        s.color = (20 + 7 * k, 200 - 9 * k, 90 + 5 * k)
    return vm


def measure_once(b, vm, html: Path) -> dict:
    """One live and one --html measurement in browser ``b``."""
    from casmbd.viz.view_server import serve
    from tests import browser_probe as bp

    colors = {bp.hex_color(s.color): 3 if s.kind == "capsule" else 1 for s in vm.shapes}
    moving = bp.hex_color(vm.shapes[-1].color)  # a shape of the last body of the chain
    row = {}
    with serve(vm) as handle:
        page = bp.Page(b, handle.url, watch=colors)
        row["live_open_s"] = bp.open_ms(page) / 1000.0
        page.page.get_by_role("button", name="Play").click()
        first, steady = bp.play_rate(page, moving, 5.0), bp.play_cost(page, moving, 5.0)
        row.update(live_fps_first=first["fps"], live_fps=steady["fps"],
                   live_changes_per_s=steady["changes_per_s"], live_cpu_ms=steady["cpu_ms"],
                   live_fps_per_core=steady["fps_per_core"])
        row["live_errors"] = len(page.errors)
        page.close()
    page = bp.Page(b, html.as_uri(), offline=True, watch=colors)
    row["html_open_s"] = bp.open_ms(page) / 1000.0
    first, steady = bp.play_rate(page, moving, 5.0), bp.play_cost(page, moving, 5.0)
    row.update(html_fps_first=first["fps"], html_fps=steady["fps"],
               html_changes_per_s=steady["changes_per_s"], html_cpu_ms=steady["cpu_ms"],
               html_fps_per_core=steady["fps_per_core"])
    row["html_errors"] = len(page.errors)
    page.close()
    return row


def measure(repeat: int = 3) -> dict:
    """``repeat`` live and --html measurements (printing as they go)."""
    from casmbd.viz.view_html import write_html
    from casmbd.viz.view_server import make_view_model
    from tests import browser_probe as bp

    reason = bp.unavailable()
    if reason:
        raise SystemExit(f"view_cost: {reason}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        vm = _colored(make_view_model(_result(tmp)))
        html = tmp / "ur5.html"
        t0 = time.perf_counter()
        info = write_html(vm, html)
        write_s = time.perf_counter() - t0
        rows = []
        with bp.browser() as b:
            for k in range(repeat):
                row = measure_once(b, vm, html)
                row["load_average"] = os.getloadavg()[0]
                print(f"run {k + 1}: " + ", ".join(f"{key} {val:.3g}" for key, val in
                                                   row.items()), file=sys.stderr)
                rows.append(row)
    return {"rows": rows, "frames": info["frames"], "bodies": info["bodies"],
            "shapes": info["shapes"], "html_bytes": info["bytes"], "html_write_s": write_s,
            "cpus": os.cpu_count(), "machine": os.uname().machine,
            "viewport": "960x600"}


def _median(rows, key) -> float:
    vals = sorted(r[key] for r in rows)
    return vals[len(vals) // 2]


def markdown(data: dict) -> str:
    """The docs section: the command, a table of the runs, their medians against the targets."""
    rows = data["rows"]
    text = (f"The UR5 arm of the examples simulated for 5 s with {data['frames']} output times "
            f"({data['bodies']} bodies, {data['shapes']} shapes), measured in headless "
            "Chromium (software WebGL, SwiftShader, viewport "
            f"{data['viewport']}) on a {data['cpus']}-core machine shared with other jobs "
            "(its 1-minute load average is given per run) by `python -m benchmarks.view_cost "
            "--update-docs`. *Open*: from the navigation's start to the first rendered frame "
            "with every shape (measured in the page). *fps*: animation frames per second "
            "while playing at 1x, in the first 5 s (*first*; software WebGL compiles its "
            "shaders and viser adapts its pixel ratio then) and the next 5 s; *moves/s*: "
            "frames per second in which a body actually moved, in the next 5 s. The live "
            "server sends poses at up to 60 updates per second. *CPU/frame*: the CPU time of "
            "every process of the view (Python with the live server, playwright, Chromium's "
            "browser, GPU and renderer processes) per animation frame in the next 5 s, and "
            "*fps/core* = frames per CPU second: the rate one idle core would sustain, which "
            "does not depend on the other jobs' load. The `--html` file is "
            f"{data['html_bytes'] / 1e6:.2f} MB, written in {data['html_write_s']:.2f} s. "
            f"Targets of issue 32: open in at most {OPEN_BOUND:g} s, play at "
            f"{FPS_BOUND:g} fps or more.")
    out = [HEAD, "", *textwrap.wrap(text, 95), "",
           "| view | run | load avg | open [s] | fps first / next | moves/s | "
           "CPU/frame [ms] | fps/core |",
           "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for mode in ("live", "html"):
        for k, r in enumerate(rows):
            out.append(f"| {mode} | {k + 1} | {r['load_average']:.1f} | "
                       f"{r[mode + '_open_s']:.2f} | {r[mode + '_fps_first']:.1f} / "
                       f"{r[mode + '_fps']:.1f} | {r[mode + '_changes_per_s']:.1f} | "
                       f"{r.get(mode + '_cpu_ms', float('nan')):.1f} | "
                       f"{r.get(mode + '_fps_per_core', float('nan')):.1f} |")
    med = {k: _median(rows, k) for k in ("live_open_s", "live_fps", "html_open_s", "html_fps",
                                         "live_fps_per_core", "html_fps_per_core")}
    verdict = []
    for mode in ("live", "html"):
        ok_open = med[f"{mode}_open_s"] <= OPEN_BOUND
        ok_fps = med[f"{mode}_fps"] >= FPS_BOUND
        verdict.append(f"{mode}: open {med[f'{mode}_open_s']:.2f} s "
                       f"({'meets' if ok_open else 'misses'} the {OPEN_BOUND:g} s target), "
                       f"{med[f'{mode}_fps']:.1f} fps after the first 5 s "
                       f"({'meets' if ok_fps else 'misses'} the "
                       f"{FPS_BOUND:g} fps target), {med[f'{mode}_fps_per_core']:.0f} fps per "
                       "idle core")
    out += ["", *textwrap.wrap("Medians — " + "; ".join(verdict) + ".", 95), ""]
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    """Command line: the shared study options (``--repeat``, ``--update-docs``, ``--render``)."""
    parser = study_parser(__doc__.splitlines()[0], RESULTS)
    args = parser.parse_args(argv)
    repeat = getattr(args, "repeat", None) or 3
    return run_study(args, RESULTS, lambda: measure(repeat), markdown, DOC, HEAD)


if __name__ == "__main__":
    sys.exit(main())
