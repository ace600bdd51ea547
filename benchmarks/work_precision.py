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
``chain8_3d``
    The 8-rod chain built in space: revolute joints about −y, gravity along −z, rods of
    inertia (m r²/2, m L²/12, m L²/12) about their (axial, y, z) axes, r = L/20.  The motion
    stays in the x-z plane and is the planar chain's, so the planar reference applies:
    error = |(x, z) of the tip − reference tip|.  Euler parameters: 56 coordinates, 48
    equations; natural coordinates: 96 and 88.

Coordinates
-----------
Each problem runs in the coordinate choices of :data:`COORDINATES` (``--coordinates``
overrides them): ``absolute`` (x, y, θ in the plane, Euler parameters in space),
``natural`` (a point and the unit axes, :mod:`casmbd.system.descriptions`) and ``joint``
(the spanning tree's joint coordinates, :mod:`casmbd.system.tree`; the chains have no
constraint equation at all, the four-bar keeps its loop-closing joint).  The ``articulated``
formulation (O(N) articulated-body recursion) applies to the joint-coordinate chains only; on
other cases it is skipped as "not applicable".  Natural planar
angles are wrapped, so the four-bar error in natural coordinates is taken modulo 2π (equal to
the absolute definition whenever the error is below π).

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
from benchmarks.chains import body_name, joint_name, pendulum_chain
from benchmarks.docs import replace_section
from benchmarks.references import load_reference
from casmbd.analysis.simulate import Simulator
from casmbd.errors import CasmbdError
from casmbd.model import Mechanism
from casmbd.system.formulations import FORMULATIONS

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
    ("articulated", "adams"),
    ("articulated", "rk4"),
]
TOLERANCES = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-12]
#: fixed-step sizes used in place of tolerances (same count, coarse to fine)
STEPS = {"chain": [1e-2, 5e-3, 2.5e-3, 1e-3, 2.5e-4, 6.25e-5],
         "fourbar": [1e-2, 2.5e-3, 6.25e-4, 1.5625e-4]}
PROBLEMS = ["chain2", "chain8", "chain32", "fourbar", "chain8_3d"]
#: coordinate choices run by default for each problem
CHOICES = ("absolute", "natural", "joint")
COORDINATES = {name: CHOICES for name in PROBLEMS}

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


def chain_in_space(n: int, coordinates: str = "absolute", length: float = 1.0,
                   mass: float = 1.0, gravity: float = 9.81) -> Mechanism:
    """:func:`benchmarks.chains.pendulum_chain` built in space (problem ``chain{n}_3d``).

    Rod ``i`` lies along +x with its centre at ((i + ½) L, 0, 0), revolute joints about −y
    (so that the rotation angle has the planar chain's sign) at (i L, 0, 0), gravity along −z,
    inertia (m r²/2, m L²/12, m L²/12) with r = L/20, marker ``"tip"`` at (n L, 0, 0).  Its
    motion is the planar chain's with the global y axis renamed z.
    """
    mech = Mechanism(f"chain{n}_3d", gravity=(0.0, 0.0, -gravity), coordinates=coordinates)
    radius = length / 20.0
    inertia = [mass * radius**2 / 2.0, mass * length**2 / 12.0, mass * length**2 / 12.0]
    for i in range(n):
        mech.add_body(body_name(i), mass=mass, inertia=inertia,
                      position=((i + 0.5) * length, 0.0, 0.0))
        mech.add_revolute(joint_name(i), "ground" if i == 0 else body_name(i - 1),
                          body_name(i), point=(i * length, 0.0, 0.0), axis=(0.0, -1.0, 0.0))
    mech.add_marker("tip", body_name(n - 1), (n * length, 0.0, 0.0))
    return mech


def problem(name: str, coordinates: str = "absolute"):
    """(mechanism, t_end, error function, description) of a benchmark problem."""
    if name.startswith("chain"):
        spatial = name.endswith("_3d")
        n = int(name[5:].removesuffix("_3d"))
        ref = load_reference(f"pendulum_chain_n{n}")
        tip_ref = np.asarray(ref["results"]["tip_position"], dtype=float)
        axes = [0, 2] if spatial else [0, 1]

        def error(res):
            tip = res.marker("tip")["position"][-1][axes]
            return float(np.linalg.norm(tip - tip_ref))

        if spatial:
            return (chain_in_space(n, coordinates), 2.0, error,
                    f"{n}-rod pendulum chain built in space, tip error at t = 2 s")
        mech = pendulum_chain(n)
        mech.coordinates = coordinates
        return mech, 2.0, error, f"{n}-rod pendulum chain, tip error at t = 2 s"
    if name == "fourbar":
        ref = load_reference("parallelogram_four_bar")
        phi_ref = float(ref["results"]["phi_end"])

        def error(res):
            diff = res.body("crank")["angle"][-1] - phi_ref
            if coordinates != "absolute":  # the angle may be wrapped to (-pi, pi]
                diff = (diff + math.pi) % (2.0 * math.pi) - math.pi
            return float(abs(diff))

        mech = casmbd.load_scene(ROOT / "examples" / "parallelogram.toml")
        mech.coordinates = coordinates
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


def sweep(problems, methods, repeat: int, quick: bool,
          coordinates: list[str] | None = None) -> list[dict]:
    """Run every case; a failure is recorded with its message, never hidden."""
    rows = []
    cases = [(pname, coords) for pname in problems
             for coords in (coordinates or COORDINATES.get(pname, ("absolute",)))]
    for pname, coords in cases:
        mech, t_end, error, _ = problem(pname, coords)
        kind = "chain" if pname.startswith("chain") else "fourbar"
        tag = pname if coords == "absolute" else f"{pname}/{coords[:3]}"
        if coords != "absolute":
            mech.name = f"{mech.name}_{coords}"
        for formulation, integrator in methods:
            try:
                sim = Simulator(mech, formulation)
            except CasmbdError as exc:
                print(f"{tag:12s} {formulation}/{integrator}: not applicable: "
                      f"{str(exc).splitlines()[0][:120]}", file=sys.stderr)
                continue
            fixed = integrator in ("rk4", "abm")
            levels = STEPS[kind] if fixed else TOLERANCES
            if quick:
                levels = levels[1:3]
            for level in levels:
                tol, step = (1e-8, level) if fixed else (level, None)
                row = {"problem": pname, "coordinates": coords, "formulation": formulation,
                       "integrator": integrator, "tolerance": "" if fixed else tol,
                       "step": step or "", "build_seconds": sim.build_seconds,
                       "nq": sim.system.nq, "nc": sim.system.nc}
                try:
                    # numeric right-hand sides run in Python: one timed run is enough
                    reps = 1 if FORMULATIONS[formulation].numeric else repeat
                    row.update(run_case(sim, integrator, t_end, tol, step, error, reps))
                    row["status"] = "ok"
                except CasmbdError as exc:
                    row.update({"status": "failed", "message": str(exc).splitlines()[0][:200]})
                rows.append(row)
                write_csv(rows, RESULTS / "work_precision.partial.csv")  # survives a kill
                label = f"h={step:.3g}" if fixed else f"tol={tol:.0e}"
                print(f"{tag:12s} {formulation:21s} {integrator:6s} {label:10s} "
                      + (f"{1e3 * row['solve_seconds']:9.2f} ms  error {row['error']:.2e}  "
                         f"drift {row['drift']:.1e}  steps {row['steps']}"
                         if row["status"] == "ok" else f"FAILED {row['message'][:90]}"),
                      flush=True)
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    """All rows, one per case."""
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = ["problem", "coordinates", "formulation", "integrator", "tolerance", "step",
            "status", "solve_seconds", "error", "drift", "velocity_drift", "steps",
            "rhs_evaluations", "setup_seconds", "build_seconds", "nq", "nc", "message"]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def read_csv(path: Path) -> list[dict]:
    """Rows written by :func:`write_csv`, with numbers converted back (rows of CSVs written
    before the ``coordinates`` column are absolute-coordinate runs)."""
    rows = []
    with open(path, newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            row["coordinates"] = row.get("coordinates") or "absolute"
            for key in ("tolerance", "step", "solve_seconds", "error", "drift", "velocity_drift",
                        "setup_seconds", "build_seconds"):
                row[key] = float(row[key]) if row.get(key) not in (None, "") else ""
            for key in ("steps", "rhs_evaluations", "nq", "nc"):
                row[key] = int(float(row[key])) if row.get(key) not in (None, "") else 0
            rows.append(row)
    return rows


def _label(row: dict) -> str:
    """``formulation/integrator``, with ``, natural`` / ``, joint`` for those rows."""
    label = f"{row['formulation']}/{row['integrator']}"
    return label if row.get("coordinates", "absolute") == "absolute" else (
        f"{label}, {row['coordinates']}")


def _points(rows, pname, formulation, integrator, coordinates) -> list[tuple[float, float]]:
    return sorted((r["error"], r["solve_seconds"]) for r in rows
                  if r["problem"] == pname and r["formulation"] == formulation
                  and r["integrator"] == integrator and r["status"] == "ok"
                  and r.get("coordinates", "absolute") == coordinates and r["error"] > 0)


def plot(rows: list[dict], problems, peer_rows: list[dict] | None = None) -> list[Path]:
    """One log-log plot per problem (solve time against error, one line per method, absolute
    coordinates) and, for a problem run in other coordinates too, a comparison plot
    ``work_precision_{problem}_coordinates.png`` (solid: absolute, dashed: natural, dotted:
    joint)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    paths = []
    for pname in problems:
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        for formulation, integrator in METHODS:
            pts = _points(rows, pname, formulation, integrator, "absolute")
            if pts:
                err, sec = zip(*pts)
                ax.loglog(err, np.array(sec) * 1e3, "o-", label=f"{formulation}/{integrator}")
        if peer_rows:
            from benchmarks.peers import _curves

            for name, pts in _curves(peer_rows, pname).items():
                err, sec = zip(*pts)
                ax.loglog(err, np.array(sec) * 1e3, "x--", color="0.45", linewidth=0.9,
                          markersize=4, label=f"peer: {name}")
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
        if not any(r["problem"] == pname and r.get("coordinates", "absolute") != "absolute"
                   for r in rows):
            continue
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
        for k, (formulation, integrator) in enumerate(METHODS):
            for coords, style in (("absolute", "o-"), ("natural", "s--"), ("joint", "^:")):
                pts = _points(rows, pname, formulation, integrator, coords)
                if pts:
                    err, sec = zip(*pts)
                    ax.loglog(err, np.array(sec) * 1e3, style, color=colours[k % len(colours)],
                              label=f"{formulation}/{integrator}, {coords}", markersize=4)
        ax.set_xlabel("error")
        ax.set_ylabel("solve time [ms]")
        ax.set_title(f"{problem(pname)[3]}\nabsolute (solid), natural (dashed) and joint "
                     "(dotted) coordinates", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
        fig.tight_layout()
        path = FIGURES / f"work_precision_{pname}_coordinates.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def best_time(rows, pname, target, coordinates: str | None = None) -> tuple[float, str] | None:
    """Smallest solve time of any case of ``pname`` (in ``coordinates``, or any) whose error
    is below ``target``."""
    ok = [(r["solve_seconds"], _label(r)) for r in rows
          if r["problem"] == pname and r["status"] == "ok" and r["error"] <= target
          and (coordinates is None or r.get("coordinates", "absolute") == coordinates)]
    return min(ok) if ok else None


def method_time(rows, pname, target, coordinates: str, formulation: str,
                integrator: str) -> float | None:
    """Smallest solve time of one method reaching ``target`` (None: not reached)."""
    ok = [r["solve_seconds"] for r in rows
          if r["problem"] == pname and r["status"] == "ok" and r["error"] <= target
          and r.get("coordinates", "absolute") == coordinates
          and r["formulation"] == formulation and r["integrator"] == integrator]
    return min(ok) if ok else None


def cost_per_evaluation(rows, pname, coordinates: str, formulation: str,
                        integrator: str) -> float | None:
    """Median solve time per right-hand-side evaluation [s] of one method (all its runs)."""
    per = [r["solve_seconds"] / r["rhs_evaluations"] for r in rows
           if r["problem"] == pname and r["status"] == "ok" and r["rhs_evaluations"]
           and r.get("coordinates", "absolute") == coordinates
           and r["formulation"] == formulation and r["integrator"] == integrator]
    return statistics.median(per) if per else None


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


def _ms(value: float | None) -> str:
    return f"{1e3 * value:.2f} ms" if value is not None else "not reached"


def coordinates_table(rows: list[dict], problems) -> list[str]:
    """Markdown lines comparing the coordinate choices problem by problem."""
    both = [p for p in problems
            if len({r.get("coordinates", "absolute") for r in rows if r["problem"] == p}) > 1]
    if not both:
        return []
    lines = ["", "### Absolute, natural and joint coordinates", "",
             "Best: the fastest method reaching the error level in those coordinates; the "
             "ratios are against absolute coordinates (above 1: slower). µs/eval: median solve "
             "time per right-hand-side evaluation of `kkt_ode/adams` (integrator overhead "
             "included).", "",
             "| problem | coordinates | nq | nc | best, error ≤ 1e-6 | best, error ≤ 1e-9 "
             "| kkt_ode/adams ≤ 1e-6 | augmented_lagrangian/adams ≤ 1e-9 | µs/eval |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for pname in both:
        best = {}
        for coords in CHOICES:
            if not any(r["problem"] == pname and r.get("coordinates", "absolute") == coords
                       for r in rows):
                continue
            sizes = next(((r["nq"], r["nc"]) for r in rows if r["problem"] == pname
                          and r.get("coordinates") == coords and r.get("nq") not in ("", 0)),
                         ("", ""))
            cells = []
            for target in (1e-6, 1e-9):
                found = best_time(rows, pname, target, coords)
                best[coords, target] = found
                cells.append(f"{_ms(found[0])} ({found[1].split(', ')[0]})"
                             if found else "not reached")
            kkt = method_time(rows, pname, 1e-6, coords, "kkt_ode", "adams")
            alm = method_time(rows, pname, 1e-9, coords, "augmented_lagrangian", "adams")
            per = cost_per_evaluation(rows, pname, coords, "kkt_ode", "adams")
            lines.append(f"| {pname} | {coords} | {sizes[0]} | {sizes[1]} | {cells[0]} | "
                         f"{cells[1]} | {_ms(kkt)} | {_ms(alm)} | "
                         f"{f'{1e6 * per:.1f}' if per else '—'} |")
        for coords in CHOICES[1:]:
            if (coords, 1e-6) not in best:
                continue
            ratios = []
            for target in (1e-6, 1e-9):
                a, n = best.get(("absolute", target)), best[coords, target]
                ratios.append(f"{n[0] / a[0]:.2f}" if a and n else "—")
            lines.append(f"| {pname} | {coords} / absolute | | | {ratios[0]} | {ratios[1]} "
                         "| | | |")
    return lines


def best_peer(peer_rows, pname, target) -> tuple[float, str] | None:
    """Smallest solve time of any peer case of ``pname`` whose error is below ``target`` (the
    rule :func:`best_time` applies to casmbd), with the peer's method label."""
    from benchmarks.peers import label

    ok = [(float(r["solve_seconds"]), label(r)) for r in peer_rows
          if r["problem"] == pname and r["status"] == "ok" and r["error"] != ""
          and float(r["error"]) <= target]
    return min(ok) if ok else None


def _peer_versions(peer_rows: list[dict]) -> str:
    """" Versions: Exudyn 1.13.6, MuJoCo 4.0.0." from the peer rows (empty without)."""
    found = sorted({(r.get("peer", ""), r.get("peer_version", "")) for r in peer_rows
                    if r.get("peer")})
    return (" Versions: " + ", ".join(f"{p} {v}" for p, v in found) + ".") if found else ""


def peers_table(rows: list[dict], problems, peer_rows: list[dict]) -> list[str]:
    """casmbd against the peers measured in the same run (ratio = casmbd / best peer; the
    issue's target is ≤ 0.5), with the issue's quoted figure beside it."""
    lines = ["", "### Against the peers, measured in the same run", "",
             "Peers: Exudyn (RigidBody2D with its default generalized-α; KinematicTree with RK44 "
             "and DOPRI5 for the chains) and MuJoCo (RK4 and implicitfast; the four-bar closed "
             "by a `connect` equality, default soft and stiffened), `benchmarks/peers.py`, "
             "same timing rule (solve only, median of the repeats) and the same references. "
             "Best = the fastest case whose error is at most the level, for casmbd and peers "
             "alike. Ratio = casmbd / best peer (below 1: casmbd faster; the issue's target "
             "is ≤ 0.5)." + _peer_versions(peer_rows), "",
             "| problem | error | casmbd best | best peer (this run) | ratio | target ≤ 0.5 | "
             "issue's figure for the peer |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    if not peer_rows:
        lines += ["", "No peer was installed for this run (`pip install .[bench]`)."]
    for pname in problems:
        if pname not in PEERS:
            continue
        for target in (1e-6, 1e-9):
            best = best_time(rows, pname, target)
            peer = best_peer(peer_rows, pname, target) if peer_rows else None
            quoted = PEERS.get(pname, {}).get(target)
            ours = f"{_ms(best[0])} ({best[1]})" if best else "not reached"
            theirs = f"{_ms(peer[0])} ({peer[1]})" if peer else "not reached"
            ratio = best[0] / peer[0] if best and peer else None
            verdict = ("met" if ratio <= 0.5 else "missed") if ratio is not None else \
                ("met (no peer reaches it)" if best else "—")
            issue = f"{1e3 * quoted[0]:.1f} ms ({quoted[1]})" if quoted else "—"
            lines.append(f"| {pname} | {target:.0e} | {ours} | {theirs} | "
                         f"{f'{ratio:.2f}' if ratio is not None else '—'} | {verdict} | "
                         f"{issue} |")
    return lines


def markdown(rows: list[dict], problems, command: str,
             peer_rows: list[dict] | None = None) -> str:
    """The docs section: best times per accuracy level, the peers of the same run and the full
    table."""
    load = os.getloadavg()
    lines = ["## Forward dynamics: work-precision", "",
             f"Measured {datetime.date.today().isoformat()} on {machine()}; load average "
             f"when the tables were written {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (above "
             "about 1 the cores were shared with other work and the times are upper bounds).",
             "",
             f"Command: `{command}`", "",
             "Solve time is the integration alone (median of the repeats, after a warm-up "
             "run); building and compiling the equations and setting up the integrator are "
             "excluded and reported in the CSV. Errors are against the independent "
             "minimal-coordinate references of `benchmarks/references.py` (tolerance 1e-13).",
             "", "### Fastest method reaching an error level", "",
             "| problem | coordinates | error ≤ 1e-6 | error ≤ 1e-9 |", "| --- | --- | --- | --- |"]
    for pname in problems:
        for coords in CHOICES:
            if not any(r["problem"] == pname and r.get("coordinates", "absolute") == coords
                       for r in rows):
                continue
            cells = []
            for target in (1e-6, 1e-9):
                best = best_time(rows, pname, target, coords)
                cells.append(f"{_ms(best[0])} ({best[1]})" if best else "not reached")
            lines.append(f"| {pname} | {coords} | {cells[0]} | {cells[1]} |")
    lines += coordinates_table(rows, problems)
    lines += peers_table(rows, problems, peer_rows or [])
    lines += ["", "### Every case", "",
              "| problem | coordinates | formulation | integrator | tol / step | time [ms] "
              "| error | drift | steps |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        level = f"h={r['step']:.3g}" if r["step"] else f"{r['tolerance']:.0e}"
        head = (f"| {r['problem']} | {r.get('coordinates', 'absolute')} | {r['formulation']} "
                f"| {r['integrator']} | {level} ")
        if r["status"] == "ok":
            lines.append(f"{head}| {1e3 * r['solve_seconds']:.2f} | {r['error']:.2e} | "
                         f"{r['drift']:.1e} | {r['steps']} |")
        else:
            lines.append(f"{head}| failed | {r['message'][:60]} | | |")
    figures = [f"![{p}](figures/work_precision_{p}.png)" for p in problems]
    figures += [f"![{p}, coordinates](figures/work_precision_{p}_coordinates.png)"
                for p in problems
                if any(r["problem"] == p and r.get("coordinates", "absolute") != "absolute"
                       for r in rows)]
    lines += ["", *figures, ""]
    return "\n".join(lines)


def update_docs(section: str) -> Path:
    """Replace (or append) the work-precision section of docs/performance.md."""
    return replace_section(ROOT / "docs" / "performance.md",
                           "## Forward dynamics: work-precision", section, "# Performance\n")


def main(argv=None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=PROBLEMS)
    parser.add_argument("--methods", nargs="+", default=None,
                        help="formulation/integrator pairs, e.g. kkt_ode/adams")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="two tolerances per method")
    parser.add_argument("--coordinates", nargs="+", default=None,
                        choices=list(CHOICES),
                        help="coordinate choices for every problem (default: per problem, "
                             "see COORDINATES)")
    parser.add_argument("--csv", default=str(RESULTS / "work_precision.csv"))
    parser.add_argument("--update-docs", action="store_true")
    parser.add_argument("--peers", action="store_true",
                        help="run Exudyn and MuJoCo (benchmarks.peers) in the same run, when "
                             "installed (pip install .[bench])")
    parser.add_argument("--peers-csv", default=str(RESULTS / "peers.csv"))
    parser.add_argument("--from-csv", action="store_true",
                        help="regenerate plots and docs from the CSV of an earlier run")
    args = parser.parse_args(argv)
    methods = METHODS if args.methods is None else [tuple(m.split("/")) for m in args.methods]
    peer_rows: list[dict] = []
    if args.from_csv:
        rows = read_csv(Path(args.csv))
        if args.peers and Path(args.peers_csv).is_file():
            peer_rows = read_csv(Path(args.peers_csv))
    else:
        rows = sweep(args.problems, methods, args.repeat, args.quick, args.coordinates)
        write_csv(rows, Path(args.csv))
        if args.peers:
            from benchmarks import peers

            peer_rows = peers.sweep([p for p in args.problems if p in peers.PROBLEMS],
                                    max(3, args.repeat), args.quick)
            if peer_rows:
                peers.write_csv(peer_rows, Path(args.peers_csv))
    problems = [p for p in args.problems if any(r["problem"] == p for r in rows)]
    plot(rows, problems, peer_rows)
    if args.update_docs:
        args_text = [a for a in (argv if argv is not None else sys.argv[1:])
                     if a != "--from-csv"]
        command = "python -m benchmarks.work_precision " + " ".join(args_text)
        update_docs(markdown(rows, problems, command.strip(), peer_rows))
    bad = [r for r in rows if r["status"] == "ok" and not math.isfinite(r["error"])]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
