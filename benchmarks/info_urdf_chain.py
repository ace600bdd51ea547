"""Time of ``casmbd info`` on a URDF chain of N revolute links (issue 31, item 7).

Each size is written as a URDF (:func:`chain_urdf`: N links, each on a revolute joint about
y, 0.1 m apart) and ``casmbd info URDF --json`` is run on it in a **fresh subprocess** with
an empty compile cache; the wall time of the whole command is measured around it and the
degrees of freedom it prints are checked (= N).

Run ``python -m benchmarks.info_urdf_chain [--sizes 1000 5000] [--update-docs]``;
``--render`` rewrites the docs section from ``benchmarks/results/info_urdf_chain.json``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.docs import run_study, study_parser
from benchmarks.info_scaling import before_now_table

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "info_urdf_chain.json"
DOC = ROOT / "docs" / "robots.md"
HEAD = "## `casmbd info` on a large URDF"
#: the issue's figure (27 s) before the linear-time spanning tree
BEFORE = {5000: 27.0}


def chain_urdf(n: int) -> str:
    """URDF text of N links (1 kg) on revolute joints about y, stacked 0.1 m apart."""
    parts = ['<robot name="chain">', '<link name="base"/>']
    for i in range(n):
        parts.append(f'<link name="l{i}"><inertial><origin xyz="0 0 0.05"/>'
                     '<mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" '
                     'ixz="0" iyz="0"/></inertial></link>')
        parent = "base" if i == 0 else f"l{i - 1}"
        parts.append(f'<joint name="j{i}" type="revolute"><parent link="{parent}"/>'
                     f'<child link="l{i}"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
                     '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>')
    parts.append("</robot>")
    return "\n".join(parts)


def time_info(n: int) -> dict:
    """Wall time of ``casmbd info --json`` on an N-link URDF in a fresh process and cache."""
    with tempfile.TemporaryDirectory() as tmp:
        urdf = Path(tmp) / f"chain{n}.urdf"
        urdf.write_text(chain_urdf(n))
        env = dict(os.environ, CASMBD_CACHE_DIR=str(Path(tmp) / "cache"))
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "casmbd", "info", str(urdf), "--json"],
                              capture_output=True, text=True, env=env, check=False)
        seconds = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(f"casmbd info failed on {n} links: {proc.stderr.strip()}")
    data = json.loads(proc.stdout)
    return {"n": n, "seconds": seconds, "dof": data["degrees_of_freedom"]}


def measure(sizes) -> dict:
    """Run :func:`time_info` for each size (printing as it goes)."""
    rows = []
    for n in sizes:
        row = time_info(n)
        print(f"N = {n}: {row['seconds']:.1f} s, dof {row['dof']}", file=sys.stderr)
        if row["dof"] != n:
            raise SystemExit(f"wrong degrees of freedom for {n} links: {row['dof']}")
        rows.append(row)
    return {"rows": rows, "machine": os.uname().machine, "cpus": os.cpu_count()}


def markdown(data: dict) -> str:
    """The docs section: a table of N, time before (issue 31) and now."""
    text = ("Wall time of `casmbd info chain.urdf --json` (fresh process, empty cache) on a "
            "URDF chain of N revolute links (joint coordinates, N degrees of freedom), written "
            "by `python -m benchmarks.info_urdf_chain --update-docs`. *Before* is the figure "
            "of issue 31. The spanning tree scanned every joint for every body (O(N²), now "
            "an incidence list), validation built CasADi symbols for every plain number, and "
            "the check whether the articulated recursion applies wrote every body's gravity "
            "term; what is left is reading the URDF and building the mechanism.")
    return before_now_table(HEAD, text, data["rows"], BEFORE)


def main(argv=None) -> int:
    """Command line: ``--sizes`` and the shared study options."""
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 5000])
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, lambda: measure(args.sizes), markdown, DOC, HEAD)


if __name__ == "__main__":
    sys.exit(main())
