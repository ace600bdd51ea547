"""Tables of the work-precision study for docs/performance.md (:mod:`benchmarks.work_precision`).

One rule for casmbd and the peers (:mod:`benchmarks.fair`): the time of a method at an error
level is interpolated log-log along its sweep; the best time is the fastest method's.
The *default path* rows (coordinates ``"default"``) are what a user gets without
choosing anything: ``Simulator(mechanism)`` with the scene's automatic coordinates and the
default formulation and integrator, swept over the tolerances only.
"""

from __future__ import annotations

import datetime
import os
import platform
import statistics
from pathlib import Path

import numpy as np

from benchmarks import fair
from benchmarks.docs import replace_section
from benchmarks.peers import best_peer_time

ROOT = Path(__file__).resolve().parent.parent

#: coordinate choices of the study, and the label of the default-path rows
CHOICES = ("absolute", "natural", "joint")
DEFAULT = "default"

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


def _label(row: dict) -> str:
    """``formulation/integrator``, with ``, natural`` / ``, joint`` for those rows."""
    label = f"{row['formulation']}/{row['integrator']}"
    return label if row.get("coordinates", "absolute") == "absolute" else (
        f"{label}, {row['coordinates']}")


def _method_curves(rows, pname, coordinates: str | None = None) -> dict[str, list]:
    """Each casmbd method's (error, solve time) points on ``pname`` (in ``coordinates``, or
    all)."""
    curves: dict[str, list] = {}
    for r in rows:
        if (r["problem"] == pname and r["status"] == "ok"
                and (coordinates is None or r.get("coordinates", "absolute") == coordinates)):
            curves.setdefault(_label(r), []).append((r["error"], r["solve_seconds"]))
    return curves


def best_time(rows, pname, target, coordinates: str | None = None) -> tuple[float, str] | None:
    """Fastest method of ``pname`` (in ``coordinates``, or any) at error ``target``: its time
    interpolated log-log along its sweep (:func:`benchmarks.fair.best_time_to_error`)."""
    return fair.best_time_to_error(_method_curves(rows, pname, coordinates), target)


def method_time(rows, pname, target, coordinates: str, formulation: str,
                integrator: str) -> float | None:
    """One method's time to ``target``, interpolated log-log (None: not reached)."""
    points = [(r["error"], r["solve_seconds"]) for r in rows
              if r["problem"] == pname and r["status"] == "ok"
              and r.get("coordinates", "absolute") == coordinates
              and r["formulation"] == formulation and r["integrator"] == integrator]
    return fair.time_to_error(points, target)


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
            if (coords, 1e-6) not in best or ("absolute", 1e-6) not in best:
                continue
            ratios = []
            for target in (1e-6, 1e-9):
                a, n = best.get(("absolute", target)), best[coords, target]
                ratios.append(f"{n[0] / a[0]:.2f}" if a and n else "—")
            lines.append(f"| {pname} | {coords} / absolute | | | {ratios[0]} | {ratios[1]} "
                         "| | | |")
    return lines


def best_peer(peer_rows, pname, target) -> tuple[float, str] | None:
    """Smallest solve time of any peer run of ``pname`` whose error is at most ``target``, with
    the peer's method label: :func:`benchmarks.peers.best_peer_time`, the rule
    :func:`best_time` applies to casmbd."""
    return best_peer_time(peer_rows, pname, target)


def _peer_versions(peer_rows: list[dict]) -> str:
    """" Versions: Exudyn 1.13.6, MuJoCo 4.0.0." from the peer rows (empty without)."""
    found = sorted({(r.get("peer", ""), r.get("peer_version", "")) for r in peer_rows
                    if r.get("peer")})
    return (" Versions: " + ", ".join(f"{p} {v}" for p, v in found) + ".") if found else ""


#: issue 36 item 6: the default path at most this fraction of the best peer's time
TARGET_RATIO = 0.1


def _peer_floor(peer_rows, pname) -> str:
    """The smallest error any peer method reached on ``pname`` and why its sweep stopped."""
    from benchmarks.peers import floors

    found = floors(peer_rows, pname)
    if not found:
        return "no peer run"
    name, (err, stop) = min(found.items(), key=lambda kv: kv[1][0])
    return f"best peer error {err:.1e} ({name}; sweep stopped: {stop or 'levels exhausted'})"


def _per_step(rows, keep) -> float | None:
    """Median solve seconds per step of the rows kept by ``keep``."""
    per = [float(r["solve_seconds"]) / int(r["steps"]) for r in rows
           if keep(r) and r["status"] == "ok" and r.get("steps") not in (None, "", 0)]
    return statistics.median(per) if per else None


def _why(rows, peer_rows, pname, ours: tuple[float, str], theirs: tuple[float, str]) -> str:
    """Where the time goes when the default path misses the ratio: each side's median solve
    time per step (its method's runs) and the steps its interpolated time stands for, so that
    steps ratio × cost-per-step ratio = the time ratio."""
    from benchmarks.peers import label

    mine = _per_step(rows, lambda r: r["problem"] == pname and r.get("coordinates") == DEFAULT
                     and _label(r) == ours[1])
    peer = _per_step(peer_rows, lambda r: r["problem"] == pname and label(r) == theirs[1])
    if not (mine and peer):
        return "—"
    ms, ps = ours[0] / mine, theirs[0] / peer
    return (f"about {ms:.0f} steps at {1e6 * mine:.1f} µs/step against {ps:.0f} at "
            f"{1e6 * peer:.1f} µs/step (steps {ms / ps:.2f}×, cost per step "
            f"{mine / peer:.2f}×)")


def peers_table(rows: list[dict], problems, peer_rows: list[dict]) -> list[str]:
    """The default path against the best peer measured in the same run, under the fair rules
    (issue 36 item 6: ratio ≤ :data:`TARGET_RATIO`, or the table says where and why not)."""
    lines = ["", "### Against the peers, measured in the same run", "",
             "Peers: Exudyn (RigidBody2D with generalized-α; KinematicTree with RK44 and "
             "DOPRI5 for the chains) and MuJoCo (RK4, implicitfast and implicit; the four-bar "
             "closed by a `connect` equality, default soft and stiffened, solver tolerance "
             "1e-12), `benchmarks/peers.py`, on the fair rules of `benchmarks/fair.py` "
             "(section *Fair rules* above). The spatial chain `chain8_3d` is compared with "
             "the peers' chain8 models built for it (MuJoCo and Exudyn's kinematic tree are "
             "spatial codes). Ratio = casmbd default path / best peer (below 1: casmbd "
             f"faster; issue 36's target ≤ {TARGET_RATIO:g})." + _peer_versions(peer_rows),
             "",
             "Where the default path misses the target, the verdict splits the ratio into "
             "steps and cost per step: each side's median solve time per step over its "
             "method's runs, and the steps its time at the level stands for (the per-step "
             "cost includes the integrator's own work, issue 36 item 4).", "",
             "| problem | error | casmbd default path | best peer (this run) | default / peer "
             f"| ≤ {TARGET_RATIO:g}? | casmbd best (any choice) | best / peer |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    if not peer_rows:
        lines += ["", "No peer was installed for this run (`pip install .[bench]`)."]
    for pname in problems:
        if not any(r["problem"] == pname for r in peer_rows):
            continue
        for target in (1e-6, 1e-9):
            best = best_time(rows, pname, target)
            dflt = best_time(rows, pname, target, DEFAULT)
            peer = best_peer(peer_rows, pname, target)
            theirs = (f"{_ms(peer[0])} ({peer[1]})" if peer
                      else f"not reached: {_peer_floor(peer_rows, pname)}")
            ratio = dflt[0] / peer[0] if dflt and peer else None
            if ratio is not None:
                verdict = ("yes" if ratio <= TARGET_RATIO else
                           f"no: {_why(rows, peer_rows, pname, dflt, peer)}")
            else:
                verdict = "no peer reaches it" if dflt else "default not reached"
            b_ratio = f"{best[0] / peer[0]:.3f}" if best and peer else "—"
            lines.append(
                f"| {pname} | {target:.0e} | "
                f"{_ms(dflt[0]) + ' (' + dflt[1] + ')' if dflt else 'not reached'} | "
                f"{theirs} | {f'{ratio:.3f}' if ratio is not None else '—'} | {verdict} | "
                f"{_ms(best[0]) + ' (' + best[1] + ')' if best else 'not reached'} | "
                f"{b_ratio} |")
    noise = []
    for target in (1e-6, 1e-9):
        a, b = (best_peer(peer_rows, p, target) for p in ("chain8", "chain8_3d"))
        if a and b:
            noise.append(f"{max(a[0], b[0]) / min(a[0], b[0]):.2f}× at {target:.0e}")
    if noise:
        lines += ["", "The peers' chain8 and chain8_3d runs are the same models run twice: their "
                  "best times differ by " + " and ".join(noise) + " in this run, a measure of "
                  "the timing noise on the shared machine. Where both sides run the same "
                  "method (DOPRI5 on chain2 against Exudyn's), the steps are alike and the "
                  "ratio is the cost per step, which includes casmbd's integrator overhead "
                  "(issue 36 item 4)."]
    return lines


def _run_loads(rows: list[dict], peer_rows: list[dict]) -> str:
    """"; 1-minute load average during the runs 3.1–7.9 (casmbd), …" from the rows' ``load``
    (recorded by :func:`benchmarks.fair.timed`; empty for rows written before)."""
    parts = []
    for name, group in (("casmbd", rows), ("peers", peer_rows)):
        loads = [float(r["load"]) for r in group if r.get("load") not in (None, "")]
        if loads:
            parts.append(f"{min(loads):.1f}–{max(loads):.1f} ({name})")
    return ("; 1-minute load average during the runs " + ", ".join(parts)) if parts else ""


def markdown(rows: list[dict], problems, command: str,
             peer_rows: list[dict] | None = None) -> str:
    """The docs section: best times per accuracy level, the peers of the same run and the full
    table."""
    load = os.getloadavg()
    lines = ["## Forward dynamics: work-precision", "",
             f"Measured {datetime.date.today().isoformat()} on {machine()}; load average "
             f"when the tables were written {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (above "
             "about 1 the cores were shared with other work and the times are upper bounds)"
             + _run_loads(rows, peer_rows or []) + ".",
             "",
             f"Command: `{command}`", "",
             "Solve time is the integration alone (best of the warm repeats; the cold first run "
             "is in the CSV's `cold_seconds`); building and compiling the equations and "
             "setting up the integrator are excluded and reported in the CSV. Errors are "
             "against the independent minimal-coordinate references of "
             "`benchmarks/references.py` (tolerance 1e-13). Times at an error level are "
             "interpolated log-log along each method's sweep (`benchmarks/fair.py`).",
             "", "### Fair rules", "", fair.RULES + " Module: `benchmarks/fair.py`; used "
             "by `benchmarks/peers.py`, `work_precision.py`, `flexible_exudyn.py`, "
             "`pinocchio_aba.py` and `numeric_api.py`.",
             "", "### Fastest method reaching an error level", "",
             "| problem | coordinates | error ≤ 1e-6 | error ≤ 1e-9 |", "| --- | --- | --- | --- |"]
    for pname in problems:
        for coords in (*CHOICES, DEFAULT):
            if not any(r["problem"] == pname and r.get("coordinates", "absolute") == coords
                       for r in rows):
                continue
            cells = []
            for target in (1e-6, 1e-9):
                best = best_time(rows, pname, target, coords)
                cells.append(f"{_ms(best[0])} ({best[1]})" if best else "not reached")
            if coords == DEFAULT:
                chosen = next((r.get("chosen_coordinates") for r in rows if r["problem"] == pname
                               and r.get("coordinates") == DEFAULT), "")
                coords = f"**default path** ({chosen})" if chosen else "**default path**"
                for k, target in enumerate((1e-6, 1e-9)):
                    ours = best_time(rows, pname, target, DEFAULT)
                    top = best_time(rows, pname, target)
                    if ours and top:
                        cells[k] += f"; {ours[0] / top[0]:.2f}× the fastest"
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


