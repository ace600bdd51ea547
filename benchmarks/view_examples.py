"""``casmbd view --html`` of every shipped example (and the mesh_arm URDF robot of the tests),
each opened offline in headless Chromium: console errors and the meshes in the scene.

Run ``python -m benchmarks.view_examples [--update-docs]`` (a section of docs/view.md).  Each
scene is shown at its initial pose (``casmbd view SCENE --html F --json`` in a fresh process);
a file is opened from ``file://`` with the network off and inspected 2.5 s after its first
three.js scene appeared.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.docs import run_study, study_parser

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "view_examples.json"
DOC = ROOT / "docs" / "view.md"
HEAD = "## Every example"


def scenes() -> list[Path]:
    ex = ROOT / "examples"
    return [*sorted(ex.glob("*.toml")), *sorted(ex.glob("*.urdf")),
            ROOT / "tests" / "robots" / "mesh_arm" / "mesh_arm.urdf"]


def measure() -> dict:
    from tests import browser_probe as bp

    reason = bp.unavailable()
    if reason:
        raise SystemExit(f"view_examples: {reason}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp, bp.browser() as b:
        for scene in scenes():
            html = Path(tmp) / f"{scene.stem}.html"
            proc = subprocess.run([sys.executable, "-m", "casmbd", "view", str(scene),
                                   "--html", str(html), "--json"], capture_output=True,
                                  text=True, timeout=600, cwd=ROOT)
            row = {"scene": str(scene.relative_to(ROOT)), "status": proc.returncode}
            if proc.returncode == 0:
                info = json.loads(proc.stdout)
                row.update(bodies=info["bodies"], shapes=info["shapes"], bytes=info["bytes"])
                page = bp.Page(b, html.as_uri(), offline=True)
                page.page.wait_for_function("window.__scenes.length > 0", timeout=60_000)
                time.sleep(2.5)
                row.update(meshes=len(page.meshes()), errors=page.errors)
                page.close()
            else:
                row["error"] = proc.stderr.strip().splitlines()[-1:]
            print(row, file=sys.stderr)
            rows.append(row)
    return {"rows": rows}


def markdown(data: dict) -> str:
    out = [HEAD, "", "`casmbd view SCENE --html F` of every shipped example at its initial "
           "pose, opened offline in headless Chromium (`python -m benchmarks.view_examples "
           "--update-docs`); *meshes*: three.js meshes in the scene (shapes, joint frames, "
           "axes, planes).", "",
           "| scene | status | bodies | shapes | meshes | console errors |",
           "|---|---:|---:|---:|---:|---:|"]
    for r in data["rows"]:
        if r["status"] == 0:
            out.append(f"| {r['scene']} | ok | {r['bodies']} | {r['shapes']} | {r['meshes']} "
                       f"| {len(r['errors'])} |")
        else:
            out.append(f"| {r['scene']} | failed: {' '.join(r.get('error', []))} | | | | |")
    out.append("")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, measure, markdown, DOC, HEAD)


if __name__ == "__main__":
    sys.exit(main())
