"""Work-precision harness for forward dynamics: solve time against error.

For each problem × formulation × integrator × tolerance it records the wall time of the
integration alone (median of ``--repeat`` runs; the build and the integrator set-up are reported
apart), the error against an independent minimal-coordinate reference
(:mod:`benchmarks.references`), the constraint drift and the step counts; it writes a CSV, a
log-log plot per problem (time against error) and, with ``--update-docs``, the section of
``docs/performance.md``.

Problems
--------
``chain2``, ``chain8``, ``chain32``
    Planar chains of slender rods (1 m, 1 kg) pinned end to end, released horizontally,
    g = 9.81, t ∈ [0, 2]; error = distance of the tip from the reference tip at t = 2.
``fourbar``
    The unit parallelogram four-bar (``examples/parallelogram.toml``), crank vertical at
    +1 rad/s, t ∈ [0, 10]; error = |crank angle(10) − reference|.  It passes the collinear
    singular pose ten times; a branch jump shows as an O(1) error.

Run ``python -m benchmarks.work_precision --update-docs`` (several minutes) or ``--quick``.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import math
import os
import platform
import statistics
import sys
from pathlib import Path

import numpy as np

import casmbd
from benchmarks.chains import pendulum_chain
from benchmarks.references import load_reference
from casmbd.analysis.simulate import Simulator
from casmbd.errors import CasmbdError
from casmbd.system.formulations import NUMERIC_FORMULATIONS

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
FIGURES = ROOT / "docs" / "figures"

#: (formulation, integrator) pairs compared; fixed-step methods sweep step sizes instead
METHODS = [
    ("augmented_lagrangian", "adams"),
    ("kkt_ode", "adams"),
    ("kkt_ode", "cvodes"),
    ("index1", "idas"),
    ("ggl", "idas"),
    ("partitioning", "adams"),
    ("nullspace", "adams"),
    ("kkt_ode", "rk4"),
    ("kkt_ode", "abm"),
]
TOLERANCES = [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
#: fixed-step sizes used in place of tolerances (same count, coarse to fine)
STEPS = {"chain": [4e-3, 1e-3, 2.5e-4, 6.25e-5],
         "fourbar": [1e-2, 2.5e-3, 6.25e-4, 1.5625e-4]}
PROBLEMS = ["chain2", "chain8", "chain32", "fourbar"]

#: figures quoted in the forward-dynamics issue for the best peer on this machine class
#: (seconds to reach the error level; None: not quoted) and the issue's own targets
PEERS = {
    "chain2": {1e-6: (2.4e-3, "Exudyn KinematicTree DOPRI5"),
               1e-9: (5.4e-3, "Exudyn KinematicTree DOPRI5")},
    "chain8": {1e-6: (11.3e-3, "MuJoCo RK4"), 1e-9: (42.7e-3, "MuJoCo RK4")},
    "chain32": {1e-6: (13.8e-3, "MuJoCo RK4"), 1e-9: (71.7e-3, "MuJoCo RK4")},
    "fourbar": {1e-6: (263e-3, "MuJoCo, hand-stiffened constraints"), 1e-9: None},
}
TARGETS = {("chain8", 1e-6): 6e-3, ("chain8", 1e-9): 20e-3}


def problem(name: str):
    """(mechanism, t_end, error function, description) of a benchmark problem."""
    if name.startswith("chain"):
        n = int(name[5:])
        ref = load_reference(f"pendulum_chain_n{n}")
        tip_ref = np.asarray(ref["results"]["tip_position"], dtype=float)

        def error(res):
            return float(np.linalg.norm(res.marker("tip")["position"][-1] - tip_ref))

        return pendulum_chain(n), 2.0, error, f"{n}-rod pendulum chain, tip error at t = 2 s"
    if name == "fourbar":
        ref = load_reference("parallelogram_four_bar")
        phi_ref = float(ref["results"]["phi_end"])

        def error(res):
            return float(abs(res.body("crank")["angle"][-1] - phi_ref))

        mech = casmbd.load_scene(ROOT / "examples" / "parallelogram.toml")
        return mech, 10.0, error, "unit parallelogram four-bar, crank-angle error at t = 10 s"
    raise SystemExit(f"error: unknown problem {name!r} (known: {', '.join(PROBLEMS)})")


def run_case(sim: Simulator, integrator: str, t_end: float, tol: float, step: float | None,
             error, repeat: int) -> dict:
    """Median solve time of ``repeat`` runs (after one warm-up) and the accuracy figures."""
    times = []
    res = None
    for k in range(repeat + 1):
        res = sim.run(t_end, 1, integrator=integrator, rtol=tol, atol=tol, step=step)
        if k:
            times.append(res.stats["solve_seconds"])
    return {"solve_seconds": statistics.median(times), "error": error(res),
            "drift": float(res["constraint_violation"][-1]),
            "velocity_drift": float(res["velocity_violation"][-1]),
            "steps": res.stats.get("steps", 0),
            "rhs_evaluations": res.stats.get("rhs_evaluations", 0),
            "setup_seconds": res.stats.get("setup_seconds", 0.0)}


def sweep(problems, methods, repeat: int, quick: bool) -> list[dict]:
    """Run every case; a failure is recorded with its message, never hidden."""
    rows = []
    for pname in problems:
        mech, t_end, error, _ = problem(pname)
        kind = "chain" if pname.startswith("chain") else "fourbar"
        for formulation, integrator in methods:
            try:
                sim = Simulator(mech, formulation)
            except CasmbdError as exc:
                print(f"{pname:8s} {formulation}/{integrator}: build failed: {exc}",
                      file=sys.stderr)
                continue
            fixed = integrator in ("rk4", "abm")
            levels = STEPS[kind] if fixed else TOLERANCES
            if quick:
                levels = levels[1:3]
            for level in levels:
                tol, step = (1e-8, level) if fixed else (level, None)
                row = {"problem": pname, "formulation": formulation, "integrator": integrator,
                       "tolerance": "" if fixed else tol, "step": step or "",
                       "build_seconds": sim.build_seconds}
                try:
                    # numeric right-hand sides run in Python: one timed run is enough
                    reps = 1 if formulation in NUMERIC_FORMULATIONS else repeat
                    row.update(run_case(sim, integrator, t_end, tol, step, error, reps))
                    row["status"] = "ok"
                except CasmbdError as exc:
                    row.update({"status": "failed", "message": str(exc).splitlines()[0][:200]})
                rows.append(row)
                label = f"h={step:.3g}" if fixed else f"tol={tol:.0e}"
                print(f"{pname:8s} {formulation:21s} {integrator:6s} {label:10s} "
                      + (f"{1e3 * row['solve_seconds']:9.2f} ms  error {row['error']:.2e}  "
                         f"drift {row['drift']:.1e}  steps {row['steps']}"
                         if row["status"] == "ok" else f"FAILED {row['message'][:90]}"),
                      flush=True)
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    """All rows, one per case."""
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = ["problem", "formulation", "integrator", "tolerance", "step", "status",
            "solve_seconds", "error", "drift", "velocity_drift", "steps", "rhs_evaluations",
            "setup_seconds", "build_seconds", "message"]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def read_csv(path: Path) -> list[dict]:
    """Rows written by :func:`write_csv`, with numbers converted back."""
    rows = []
    with open(path, newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            for key in ("tolerance", "step", "solve_seconds", "error", "drift", "velocity_drift",
                        "setup_seconds", "build_seconds"):
                row[key] = float(row[key]) if row.get(key) not in (None, "") else ""
            for key in ("steps", "rhs_evaluations"):
                row[key] = int(float(row[key])) if row.get(key) not in (None, "") else 0
            rows.append(row)
    return rows


def plot(rows: list[dict], problems) -> list[Path]:
    """One log-log plot per problem: solve time against error, one line per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    paths = []
    for pname in problems:
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        for formulation, integrator in METHODS:
            pts = [(r["error"], r["solve_seconds"]) for r in rows
                   if r["problem"] == pname and r["formulation"] == formulation
                   and r["integrator"] == integrator and r["status"] == "ok"
                   and r["error"] > 0]
            if pts:
                err, sec = zip(*sorted(pts))
                ax.loglog(err, np.array(sec) * 1e3, "o-", label=f"{formulation}/{integrator}")
        ax.set_xlabel("error")
        ax.set_ylabel("solve time [ms]")
        ax.set_title(problem(pname)[3])
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = FIGURES / f"work_precision_{pname}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def best_time(rows, pname, target) -> tuple[float, str] | None:
    """Smallest solve time of any case of ``pname`` whose error is below ``target``."""
    ok = [(r["solve_seconds"], f"{r['formulation']}/{r['integrator']}") for r in rows
          if r["problem"] == pname and r["status"] == "ok" and r["error"] <= target]
    return min(ok) if ok else None


def machine() -> str:
    """CPU model, cores and versions for the record."""
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import casadi
    import scipy

    return (f"{cpu}, {os.cpu_count()} cores; Python {platform.python_version()}, "
            f"CasADi {casadi.__version__}, NumPy {np.__version__}, SciPy {scipy.__version__}")


def markdown(rows: list[dict], problems, command: str) -> str:
    """The docs section: best times per accuracy level and the full table."""
    lines = ["## Forward dynamics: work-precision", "",
             f"Measured {datetime.date.today().isoformat()} on {machine()}.", "",
             f"Command: `{command}`", "",
             "Solve time is the integration alone (median of the repeats, after a warm-up "
             "run); building and compiling the equations and setting up the integrator are "
             "excluded and reported in the CSV. Errors are against the independent "
             "minimal-coordinate references of `benchmarks/references.py` (tolerance 1e-13).",
             "", "### Fastest method reaching an error level", "",
             "| problem | error ≤ 1e-6 | error ≤ 1e-9 |", "| --- | --- | --- |"]
    for pname in problems:
        cells = []
        for target in (1e-6, 1e-9):
            best = best_time(rows, pname, target)
            cells.append(f"{1e3 * best[0]:.2f} ms ({best[1]})" if best else "not reached")
        lines.append(f"| {pname} | {cells[0]} | {cells[1]} |")
    lines += ["", "### Against the peers' figures quoted in the issue", "",
              "Peer times are the issue's figures (measured on a machine like this one, not in "
              "this run); ratio = casmbd / peer (below 1: casmbd faster).", "",
              "| problem | error | casmbd best | peer | ratio | issue target |",
              "| --- | --- | --- | --- | --- | --- |"]
    for pname in problems:
        for target in (1e-6, 1e-9):
            best = best_time(rows, pname, target)
            peer = PEERS.get(pname, {}).get(target)
            ours = f"{1e3 * best[0]:.2f} ms ({best[1]})" if best else "not reached"
            theirs = f"{1e3 * peer[0]:.1f} ms ({peer[1]})" if peer else "—"
            ratio = f"{best[0] / peer[0]:.2f}" if best and peer else "—"
            goal = TARGETS.get((pname, target))
            goal_text = (f"≤ {1e3 * goal:.0f} ms: {'met' if best and best[0] <= goal else 'missed'}"
                         if goal else "")
            lines.append(f"| {pname} | {target:.0e} | {ours} | {theirs} | {ratio} | "
                         f"{goal_text} |")
    lines += ["", "### Every case", "",
              "| problem | formulation | integrator | tol / step | time [ms] | error | drift "
              "| steps |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        level = f"h={r['step']:.3g}" if r["step"] else f"{r['tolerance']:.0e}"
        if r["status"] == "ok":
            lines.append(f"| {r['problem']} | {r['formulation']} | {r['integrator']} | {level} "
                         f"| {1e3 * r['solve_seconds']:.2f} | {r['error']:.2e} | "
                         f"{r['drift']:.1e} | {r['steps']} |")
        else:
            lines.append(f"| {r['problem']} | {r['formulation']} | {r['integrator']} | {level} "
                         f"| failed | {r['message'][:60]} | | |")
    lines += ["", *[f"![{p}](figures/work_precision_{p}.png)" for p in problems], ""]
    return "\n".join(lines)


def update_docs(section: str) -> Path:
    """Replace (or append) the work-precision section of docs/performance.md."""
    path = ROOT / "docs" / "performance.md"
    text = path.read_text(encoding="utf-8") if path.exists() else "# Performance\n"
    head = "## Forward dynamics: work-precision"
    if head in text:
        start = text.index(head)
        nxt = text.find("\n## ", start + len(head))
        text = text[:start] + section + (text[nxt + 1:] if nxt >= 0 else "")
    else:
        text = text.rstrip() + "\n\n" + section
    path.write_text(text, encoding="utf-8")
    return path


def main(argv=None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=PROBLEMS)
    parser.add_argument("--methods", nargs="+", default=None,
                        help="formulation/integrator pairs, e.g. kkt_ode/adams")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="two tolerances per method")
    parser.add_argument("--csv", default=str(RESULTS / "work_precision.csv"))
    parser.add_argument("--update-docs", action="store_true")
    parser.add_argument("--from-csv", action="store_true",
                        help="regenerate plots and docs from the CSV of an earlier run")
    args = parser.parse_args(argv)
    methods = METHODS if args.methods is None else [tuple(m.split("/")) for m in args.methods]
    if args.from_csv:
        rows = read_csv(Path(args.csv))
    else:
        rows = sweep(args.problems, methods, args.repeat, args.quick)
        write_csv(rows, Path(args.csv))
    plot(rows, args.problems)
    if args.update_docs:
        args_text = [a for a in (argv if argv is not None else sys.argv[1:])
                     if a != "--from-csv"]
        command = "python -m benchmarks.work_precision " + " ".join(args_text)
        update_docs(markdown(rows, args.problems, command.strip()))
    bad = [r for r in rows if r["status"] == "ok" and not math.isfinite(r["error"])]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
