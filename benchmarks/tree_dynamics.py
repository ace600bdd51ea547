"""Trees in joint coordinates: the KKT/LDLᵀ path against the articulated-body recursion.

For pendulum chains of N rods in joint coordinates (N coordinates, no constraint equation),
released horizontally and integrated for 2 s with CVODES-Adams, this measures for the
``kkt_ode`` formulation (composite-rigid-body M, dense LDLᵀ) and the ``articulated``
formulation (O(N) articulated-body recursion): build + compile time (fresh cache), solve
time (median of ``--repeat`` runs after a warm-up) and steps, and the difference of the two
tip positions.

Run ``python -m benchmarks.tree_dynamics --sizes 2 8 32 --update-docs``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.chains import pendulum_chain
from benchmarks.docs import replace_section
from benchmarks.work_precision import machine

ROOT = Path(__file__).resolve().parent.parent
HEAD = "## Trees in joint coordinates: KKT path against the articulated-body recursion"


def measure(n: int, formulation: str, repeat: int, rtol: float) -> dict:
    """One chain, one formulation, in a fresh compile cache."""
    from casmbd.analysis.dynamics.simulate import Simulator

    mech = pendulum_chain(n)
    mech.coordinates = "joint"
    mech.name = f"tree_chain{n}_{formulation}"
    t0 = time.perf_counter()
    sim = Simulator(mech, formulation=formulation)
    build = time.perf_counter() - t0
    sim.run(t_end=2.0, steps=20, rtol=rtol)  # warm-up (integrator set-up)
    times, res = [], None
    for _ in range(repeat):
        res = sim.run(t_end=2.0, steps=20, rtol=rtol)
        times.append(res.stats["solve_seconds"])
    return {"n": n, "formulation": formulation, "build_seconds": build,
            "solve_seconds": statistics.median(times), "steps": res.stats["steps"],
            "tip": res.marker("tip")["position"][-1]}


def markdown(rows: list[dict], command: str) -> str:
    lines = [HEAD, "", f"Measured on {machine()}.", "", f"Command: `{command}`", "",
             "Pendulum chains of N rods in joint coordinates, 2 s from the horizontal pose, "
             "CVODES-Adams at rtol 1e-8. *build*: `Simulator(...)` including C generation and "
             "compilation in a fresh cache; *solve*: the integration alone, median of the "
             "repeats; *tip diff*: |tip(kkt_ode) − tip(articulated)| at 2 s.", "",
             "| N | kkt_ode build [s] | articulated build [s] | kkt_ode solve [ms] | "
             "articulated solve [ms] | ratio articulated / kkt_ode | steps | tip diff [m] |",
             "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    sizes = sorted({r["n"] for r in rows})
    for n in sizes:
        k = next(r for r in rows if r["n"] == n and r["formulation"] == "kkt_ode")
        a = next(r for r in rows if r["n"] == n and r["formulation"] == "articulated")
        diff = float(np.linalg.norm(k["tip"] - a["tip"]))
        lines.append(f"| {n} | {k['build_seconds']:.2f} | {a['build_seconds']:.2f} | "
                     f"{1e3 * k['solve_seconds']:.2f} | {1e3 * a['solve_seconds']:.2f} | "
                     f"{a['solve_seconds'] / k['solve_seconds']:.2f} | "
                     f"{k['steps']} / {a['steps']} | {diff:.1e} |")
    return "\n".join(lines) + "\n"


def update_docs(section: str) -> Path:
    """Replace (or append) this section of docs/performance.md."""
    return replace_section(ROOT / "docs" / "performance.md", HEAD, section)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", type=int, default=[2, 8, 32])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--rtol", type=float, default=1e-8)
    parser.add_argument("--update-docs", action="store_true")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        os.environ["CASMBD_CACHE_DIR"] = cache
        for n in args.sizes:
            for formulation in ("kkt_ode", "articulated"):
                row = measure(n, formulation, args.repeat, args.rtol)
                rows.append(row)
                print(f"N={n:4d} {formulation:12s} build {row['build_seconds']:7.2f} s  "
                      f"solve {1e3 * row['solve_seconds']:8.2f} ms  steps {row['steps']}",
                      flush=True)
    if args.update_docs:
        command = "python -m benchmarks.tree_dynamics " + " ".join(
            argv if argv is not None else sys.argv[1:])
        update_docs(markdown(rows, command.strip()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
