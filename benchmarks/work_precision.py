"""Work-precision harness for forward dynamics: solve time against error.

For each problem × formulation × integrator × tolerance it records the wall time of the
integration alone (best of ``--repeat`` warm runs, the cold first run apart: the fair rules of
:mod:`benchmarks.fair`; the build and the integrator set-up are reported apart), the error
against an independent minimal-coordinate reference
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
import math
import sys
from pathlib import Path

import numpy as np

import casmbd
from benchmarks import fair
from benchmarks.chains import body_name, joint_name, pendulum_chain
from benchmarks.peers import _curves
from benchmarks.references import load_reference
from benchmarks.work_precision_docs import (  # noqa: F401 (machine: used by other studies)
    CHOICES,
    DEFAULT,
    machine,
    markdown,
    update_docs,
)
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.formulations import FORMULATIONS
from casmbd.errors import CasmbdError
from casmbd.model import Mechanism

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
#: tolerances per problem kind: the four-bar's error at t = 10 s is ~1e2-1e4 × rtol with
#: Adams (made at its ten singular passes; DOPRI5 and RK4 converge cleanly on the same
#: right-hand side), so the sweep goes on to 1e-14 to pass error 1e-9
#: (docs/hard_cases.md, "Parallelogram four-bar at error 1e-9")
SWEEP = {"chain": TOLERANCES, "fourbar": [*TOLERANCES, 1e-13, 1e-14]}
#: fixed-step sizes used in place of tolerances (same count, coarse to fine)
STEPS = {"chain": [1e-2, 5e-3, 2.5e-3, 1e-3, 2.5e-4, 6.25e-5],
         "fourbar": [1e-2, 2.5e-3, 6.25e-4, 1.5625e-4]}
PROBLEMS = ["chain2", "chain8", "chain32", "fourbar", "chain8_3d"]
#: coordinate choices run by default for each problem
COORDINATES = {name: (*CHOICES, DEFAULT) for name in PROBLEMS}

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
    """One case under the fair rule (:func:`benchmarks.fair.timed`): the cold first run in
    ``cold_seconds``, the best of ``repeat`` warm runs in ``solve_seconds`` (the solve alone;
    the integrator set-up in ``setup_seconds``), and the accuracy figures."""

    def run():
        res = sim.run(t_end, 1, integrator=integrator, rtol=tol, atol=tol, step=step)
        return res.stats["solve_seconds"], {
            "error": error(res), "integrator": res.stats.get("integrator", integrator),
            "drift": float(res["constraint_violation"][-1]),
            "velocity_drift": float(res["velocity_violation"][-1]),
            "steps": res.stats.get("steps", 0),
            "rhs_evaluations": res.stats.get("rhs_evaluations", 0),
            "setup_seconds": res.stats.get("setup_seconds", 0.0)}

    return fair.timed(run, repeat)


def sweep(problems, methods, repeat: int, quick: bool,
          coordinates: list[str] | None = None) -> list[dict]:
    """Run every case; a failure is recorded with its message, never hidden."""
    rows = []
    cases = [(pname, coords) for pname in problems
             for coords in (coordinates or COORDINATES.get(pname, ("absolute",)))]
    for pname, coords in cases:
        default = coords == DEFAULT  # the default path: nothing chosen
        mech, t_end, error, _ = problem(pname, "auto" if default else coords)
        kind = "chain" if pname.startswith("chain") else "fourbar"
        tag = pname if coords == "absolute" else f"{pname}/{coords[:3]}"
        if coords != "absolute":
            mech.name = f"{mech.name}_{coords}"
        for formulation, integrator in ([(None, None)] if default else methods):
            try:
                sim = Simulator(mech, formulation)
            except CasmbdError as exc:
                print(f"{tag:12s} {formulation}/{integrator}: not applicable: "
                      f"{str(exc).splitlines()[0][:120]}", file=sys.stderr)
                continue
            # the formulation actually built (augmented_lagrangian without constraint
            # equations builds kkt_ode; the registry renames it after the kind asked for)
            built = sim.formulation.function.name().removeprefix("dyn_")
            built = built if built in FORMULATIONS else sim.formulation.name
            if not default and built != formulation and (built, integrator) in methods:
                print(f"{tag:12s} {formulation}/{integrator}: builds {built} (measured as "
                      "such)", file=sys.stderr)
                continue
            fixed = integrator in ("rk4", "abm")
            levels = STEPS[kind] if fixed else SWEEP[kind]
            if quick:
                levels = levels[1:3]
            errors: list[float] = []  # this method's errors so far (fair.floor_reached)
            for level in levels:
                if fair.floor_reached(errors):
                    break  # below 1e-9 or at its floor: finer levels add nothing
                tol, step = (1e-8, level) if fixed else (level, None)
                row = {"problem": pname, "coordinates": coords, "formulation": built,
                       "integrator": integrator or sim.kind.default_integrator,
                       "tolerance": "" if fixed else tol,
                       "step": step or "", "build_seconds": sim.build_seconds,
                       "nq": sim.system.nq, "nc": sim.system.nc,
                       "chosen_coordinates": sim.system.coordinates}
                try:
                    # numeric right-hand sides run in Python: one timed run is enough
                    reps = 1 if FORMULATIONS[built].numeric else repeat
                    row.update(run_case(sim, integrator, t_end, tol, step, error, reps))
                    row["status"] = "ok"
                except CasmbdError as exc:
                    row.update({"status": "failed", "message": str(exc).splitlines()[0][:200]})
                rows.append(row)
                if row["status"] == "ok":
                    errors.append(row["error"])
                write_csv(rows, RESULTS / "work_precision.partial.csv")  # survives a kill
                label = f"h={step:.3g}" if fixed else f"tol={tol:.0e}"
                print(f"{tag:12s} {built:21s} {row['integrator']:6s} {label:10s} "
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
            "rhs_evaluations", "setup_seconds", "build_seconds", "nq", "nc", "message",
            "chosen_coordinates", "cold_seconds", "repeats", "load"]
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
                        "setup_seconds", "build_seconds", "cold_seconds", "load"):
                row[key] = float(row[key]) if row.get(key) not in (None, "") else ""
            for key in ("steps", "rhs_evaluations", "nq", "nc"):
                row[key] = int(float(row[key])) if row.get(key) not in (None, "") else 0
            rows.append(row)
    return rows


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


def main(argv=None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=PROBLEMS)
    parser.add_argument("--methods", nargs="+", default=None,
                        help="formulation/integrator pairs, e.g. kkt_ode/adams")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="two tolerances per method")
    parser.add_argument("--coordinates", nargs="+", default=None,
                        choices=[*CHOICES, DEFAULT],
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
    if args.update_docs:  # the figures belong with the docs section (a subset run to
        plot(rows, problems, peer_rows)  # another CSV must not overwrite them)
        args_text = [a for a in (argv if argv is not None else sys.argv[1:])
                     if a != "--from-csv"]
        command = "python -m benchmarks.work_precision " + " ".join(args_text)
        update_docs(markdown(rows, problems, command.strip(), peer_rows))
    bad = [r for r in rows if r["status"] == "ok" and not math.isfinite(r["error"])]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
