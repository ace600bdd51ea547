"""Time of ``casmbd info`` on planar pendulum chains of N = 500 … 5000 rods (issue 18, item 3).

Every size is written as a scene file (:func:`chain_scene`: N rods pinned end to end, absolute
coordinates set in the scene — the default ``auto`` would pick joint coordinates for this
tree, N coordinates and no equation, and the study is about the rank and assembly of large
constraint Jacobians) and ``casmbd info`` is run on it in a **fresh subprocess** with an
empty compile cache, the wall time of the whole command (Python start, scene parsing,
validation, System, equations, compilation or virtual machine, assembly, rank) measured
around it.  The degrees of freedom it prints are checked (= N).

Run ``python -m benchmarks.info_scaling [--sizes 500 1000 2000 5000] [--update-docs]``;
``--render`` rewrites the docs section from ``benchmarks/results/info_scaling.json``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from benchmarks.docs import run_study, study_parser

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "info_scaling.json"
DOC = ROOT / "docs" / "performance.md"
HEAD = "## `casmbd info` on large scenes"
#: the issue's figures before the linear-time checks (same machine class, same command)
BEFORE = {500: 18.0, 1000: 61.0, 2000: 158.0, 5000: 643.0}


def chain_scene(n: int, name: str | None = None, coordinates: str | None = None) -> str:
    """TOML text of N slender rods (1 m, 1 kg) pinned end to end, hanging from the origin.

    Rod ``i`` (``rod{i}``) lies along +x with its centre at (i + 0.5, 0); revolute ``pin0``
    pins it to the ground at the origin, ``pin{i}`` joins ``rod{i-1}`` and ``rod{i}`` at
    (i, 0).  ``coordinates`` (``[scene] coordinates``) None leaves the choice to casmbd's
    default ``auto`` (joint coordinates for this tree: N coordinates, no equation);
    ``"absolute"`` gives 3 N coordinates and 2 N equations.  N degrees of freedom.
    """
    lines = ["[scene]", f'name = "{name or f"chain{n}"}"', "dimension = 2",
             "gravity = [0.0, -9.81]"]
    lines += [f'coordinates = "{coordinates}"', ""] if coordinates else [""]
    for i in range(n):
        lines += ["[[bodies]]", f'name = "rod{i}"', "mass = 1.0", f"inertia = {1 / 12!r}",
                  f"position = [{i + 0.5!r}, 0.0]", ""]
    for i in range(n):
        body1 = "ground" if i == 0 else f"rod{i - 1}"
        lines += ["[[joints]]", f'name = "pin{i}"', 'type = "revolute"', f'body1 = "{body1}"',
                  f'body2 = "rod{i}"', f"point = [{float(i)!r}, 0.0]", ""]
    return "\n".join(lines)


def time_info(n: int, mode: str = "auto") -> dict:
    """Wall time of ``casmbd info --json`` on an N-rod chain in a fresh process and cache."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / f"chain{n}.toml"
        scene.write_text(chain_scene(n, coordinates="absolute"))
        env = dict(os.environ, CASMBD_CACHE_DIR=str(Path(tmp) / "cache"))
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "casmbd", "info", str(scene), "--json",
                               "--mode", mode], capture_output=True, text=True, env=env,
                              check=False)
        seconds = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(f"casmbd info failed on {n} rods: {proc.stderr.strip()}")
    data = json.loads(proc.stdout)
    return {"n": n, "mode": mode, "seconds": seconds, "dof": data["degrees_of_freedom"],
            "rank": data["rank"], "compiled": data["stats"].get("compiled"),
            "build_seconds": data["stats"].get("build_seconds")}


def measure(sizes, mode: str = "auto") -> dict:
    """Run :func:`time_info` for each size (printing as it goes)."""
    rows = []
    for n in sizes:
        row = time_info(n, mode)
        print(f"N = {n}: {row['seconds']:.1f} s, dof {row['dof']}", file=sys.stderr)
        if row["dof"] != n:
            raise SystemExit(f"wrong degrees of freedom for {n} rods: {row['dof']}")
        rows.append(row)
    return {"rows": rows, "machine": os.uname().machine, "cpus": os.cpu_count(),
            "load": [round(x, 2) for x in os.getloadavg()],
            "command": "python -m benchmarks.info_scaling " + " ".join(sys.argv[1:])}


def markdown(data: dict) -> str:
    """The docs section: a table of N, time before (issue 18) and now."""
    text = ("Wall time of `casmbd info chain.toml --json` (fresh process, empty cache, default "
            "`--mode auto`) on a planar chain of N rods pinned end to end in absolute "
            "coordinates, set in the scene (`coordinates = \"absolute\"`: 3N coordinates, "
            "2N equations, N degrees of freedom; the default `auto` would pick joint "
            "coordinates for this tree — N coordinates, no equation — and this study is "
            "about the rank and the assembly of large constraint Jacobians), written by "
            "`python -m benchmarks.info_scaling --update-docs`. *Before* are the figures of "
            "issue 18. Three steps were super-linear: compiling C and C_q to C (25 s at "
            "N = 500; `info` now evaluates them on the virtual machine under `auto`), the "
            "dense SVD of C_q for the rank (cubic: 76 s at N = 2000; now a Q-less sparse "
            "Givens QR of C_qᵀ above 2.5·10⁵ entries, `redundancy.sparse_rank_report`, 0.1 s "
            "at N = 5000, same rank and dependent rows) and, when the start must be "
            "assembled, dense least-squares Newton steps (70 s for a driven 500-rod chain; now "
            "a sparse augmented system, 2.3 s). What is left grows linearly: reading the "
            "scene, building the expressions, the CasADi Functions.")
    if "load" in data:
        text += (f" Load average {' '.join(f'{x:.2f}' for x in data['load'])} at the end of "
                 f"the run (2 cores; above about 1 the times are upper bounds); command "
                 f"`{data['command'].strip()}`.")
    return before_now_table(HEAD, text, data["rows"], BEFORE)


def before_now_table(head: str, text: str, rows: list[dict], before: dict) -> str:
    """A docs section: ``head``, the wrapped ``text`` and a table of N, the time before (from
    ``before``, N -> s) and now, and the degrees of freedom of each row."""
    out = [head, "", *textwrap.wrap(text, 95), "",
           "| N | before [s] | now [s] | degrees of freedom |", "|---:|---:|---:|---:|"]
    for row in rows:
        then = before.get(row["n"])
        out.append(f"| {row['n']} | {then if then is not None else '–'} | "
                   f"{row['seconds']:.1f} | {row['dof']} |")
    out.append("")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    """Command line: ``--sizes``, ``--mode`` and the shared study options."""
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--sizes", type=int, nargs="+", default=[500, 1000, 2000, 5000])
    parser.add_argument("--mode", default="auto", choices=["auto", "compiled", "vm"])
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, lambda: measure(args.sizes, args.mode), markdown, DOC, HEAD)


if __name__ == "__main__":
    sys.exit(main())
