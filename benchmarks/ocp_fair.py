"""casmbd's OCP against the fair hand-written CasADi baseline, in one process (issue 36 item 3).

The baseline (:mod:`benchmarks.ocp_handwritten`) gets IPOPT's simple bounds as bounds
(``detect_simple_bounds``) and the same IPOPT options as casmbd's problem file.  For each problem
the two solves alternate in this process ``--repeat`` times from the same guess, so that a change
of load on the shared machine hits both alike; reported per side: the best and the median wall
time and the best process CPU time of the solver call, the part of it spent in the NLP's
callbacks (CasADi's ``t_wall_nlp_*`` timers: f, g, ∇f, J_g, ∇²L; the rest is IPOPT and MUMPS),
iterations, objective, and the set-up (ours: ``load_ocp`` + derivative functions (loaded from the
compile cache after the first solve) + guess; the baseline's: the Opti problem and ``nlpsol``
with ``expand=True``).  Cold set-up in a fresh cache: :mod:`benchmarks.ocp_problems`.

Problems: the pendulums with the baseline's transcription (degree-3 Radau, one element per
interval, N = 50; casmbd's default ``dynamics`` and ``compile``) and the UR5 minimum-time problem
as in its file (implicit degree-4 Radau, 12 intervals) with the default derivatives (virtual
machine) and compiled per-element derivatives.

    python -m benchmarks.ocp_fair --repeat 7 --update-docs
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import statistics
import sys
import time

import casadi as ca

from benchmarks import fair
from benchmarks import ocp_handwritten as hw
from benchmarks.docs import replace_section

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "ocp_fair.json"
PERF_DOC = ROOT / "docs" / "performance.md"
HEAD = "## Trajectory optimisation against the fair hand-written baseline (issue 36)"
TARGET = 0.8
SAME = {"subintervals": 1, "degree": 3}
#: (problem, label, Ocp overrides, solves per side relative to --repeat)
CASES = [
    ("cart_pole", "baseline's transcription, defaults", SAME, 1.0),
    ("double_pendulum_swingup", "baseline's transcription, defaults", SAME, 1.0),
    ("double_pendulum_min_time", "baseline's transcription, defaults", SAME, 1.0),
    ("ur5_min_time", "as in the file, defaults", {}, 0.3),
    ("ur5_min_time", "as in the file, compiled elements", {"compile": "elements"}, 0.3),
]


def _callbacks(stats: dict) -> float:
    return sum(float(v) for k, v in stats.items() if k.startswith("t_wall_nlp_"))


def measure_case(problem: str, overrides: dict, repeat: int) -> dict:
    """Alternate baseline and casmbd solves ``repeat`` times (figures JSON-able)."""
    from casmbd.io.ocp_table import load_ocp

    t0 = time.perf_counter()
    opti, _ = hw.build(problem)
    extra = hw.UR5_OPTIONS if problem == "ur5_min_time" else {}
    solver = ca.nlpsol("baseline", "ipopt", {"x": opti.x, "f": opti.f, "g": opti.g},
                       {**hw.IPOPT_OPTIONS, **extra, "record_time": True})
    arg = {"x0": opti.value(opti.x, opti.initial()), "lbg": ca.evalf(opti.lbg),
           "ubg": ca.evalf(opti.ubg)}
    base_setup = time.perf_counter() - t0
    base, ours = [], []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        out = solver(**arg)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        st = solver.stats()
        base.append({"wall": wall, "cpu": cpu, "callbacks": _callbacks(st),
                     "iterations": int(st["iter_count"]), "objective": float(out["f"]),
                     "success": bool(st["success"])})
        w0 = time.perf_counter()
        ocp = load_ocp(ROOT / "ocp" / f"{problem}.toml")
        for key, value in overrides.items():
            setattr(ocp, key, value)
        sol = ocp.solve()
        total = time.perf_counter() - w0
        s = sol.stats
        ours.append({"wall": s["solve_seconds"], "cpu": s["solve_cpu_seconds"],
                     "callbacks": _callbacks(s.get("timings", {})),
                     "iterations": sol.iterations, "objective": sol.objective,
                     "success": sol.success, "setup": total - s["solve_seconds"],
                     "derivatives": s.get("derivatives"), "dynamics": s.get("dynamics"),
                     "variables": s.get("variables"), "constraints": s.get("constraints")})

    def summary(runs: list[dict]) -> dict:
        best = min(runs, key=lambda r: r["wall"])
        return {"wall_min_s": best["wall"],
                "wall_median_s": statistics.median(r["wall"] for r in runs),
                "cpu_min_s": min(r["cpu"] for r in runs),
                "callbacks_s": best["callbacks"], "iterations": runs[-1]["iterations"],
                "objective": runs[-1]["objective"], "success": runs[-1]["success"],
                "solves": len(runs)}

    o, b = summary(ours), summary(base)
    o.update({k: ours[-1][k] for k in ("derivatives", "dynamics", "variables", "constraints")})
    o["setup_first_s"], o["setup_cached_s"] = ours[0]["setup"], min(r["setup"] for r in ours[1:]
                                                                    or ours)
    b["setup_s"] = base_setup
    b["variables"], b["constraints"] = int(opti.nx), int(opti.ng)
    return {"ours": o, "baseline": b,
            "ratio_wall": o["wall_min_s"] / b["wall_min_s"],
            "ratio_cpu": o["cpu_min_s"] / b["cpu_min_s"],
            "objective_rel_diff": (o["objective"] - b["objective"]) / abs(b["objective"])}


def measure(repeat: int, only: list[str] | None) -> dict:
    load0 = os.getloadavg()
    rows = []
    for problem, label, overrides, share in CASES:
        if only and problem not in only:
            continue
        n = max(2, round(repeat * share))
        print(f"{problem}: {label} ({n} solves each)", file=sys.stderr, flush=True)
        row = {"problem": problem, "label": label, "overrides": overrides,
               "load_before": os.getloadavg()}
        row.update(measure_case(problem, overrides, n))
        row["load_after"] = os.getloadavg()
        print(f"  ratio wall {row['ratio_wall']:.2f}, cpu {row['ratio_cpu']:.2f}, iterations "
              f"{row['ours']['iterations']} / {row['baseline']['iterations']}",
              file=sys.stderr, flush=True)
        rows.append(row)
    return {"rows": rows, "repeat": repeat, "load_start": load0, "load_end": os.getloadavg(),
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "casadi": ca.__version__, "python": platform.python_version(),
            "versions": fair.versions(),
            "command": "python -m benchmarks.ocp_fair " + " ".join(sys.argv[1:])}


def _ms(x: float) -> str:
    return f"{x * 1e3:.3g} ms" if x < 1 else f"{x:.3g} s"


def markdown(data: dict) -> str:
    lines = [HEAD, "",
             "Generated by `benchmarks/ocp_fair.py`; do not edit by hand, re-run:", "", "```",
             data["command"], "```", "",
             "casmbd against the hand-written CasADi baseline made fair (issue 36): the "
             "baseline's simple bounds (controls, final time, boundary states) go to IPOPT as "
             "bounds (`detect_simple_bounds`), both sides use the problem file's IPOPT options, "
             "MUMPS, the same guess. The two solves alternate in one process (best of the "
             "solves per side; CPU time of the solver call less sensitive to other jobs); "
             "*callbacks*: the part of the solve in the NLP's functions (f, g, ∇f, J_g, ∇²L; "
             "the rest is IPOPT and MUMPS); *set-up*: ours cached (derivatives loaded from the "
             "compile cache; the first in brackets), the baseline's Opti problem and `nlpsol` "
             "(`expand=True`). Cold set-up in a fresh cache: the section above. "
             f"Machine: 2 shared cores; load average {data['load_start'][0]:.1f} at the start, "
             f"{data['load_end'][0]:.1f} at the end; {data['date']}; CasADi {data['casadi']}.",
             "",
             "| problem | ours: derivatives, dynamics | iter. ours / hw | solve ours / hw "
             "(best; median) | callbacks ours / hw | IPOPT ours / hw | per iteration ours / hw "
             "| CPU ours / hw | set-up ours (first) / hw | objective ours − hw (rel.) "
             "| ours / hw wall; CPU |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    missed = []
    for r in data["rows"]:
        o, b = r["ours"], r["baseline"]
        lines.append("| " + " | ".join([
            f"`{r['problem']}` ({r['label']})", f"{o['derivatives']}, {o['dynamics']}",
            f"{o['iterations']} / {b['iterations']}",
            f"{_ms(o['wall_min_s'])} / {_ms(b['wall_min_s'])} ({_ms(o['wall_median_s'])} / "
            f"{_ms(b['wall_median_s'])})",
            f"{_ms(o['callbacks_s'])} / {_ms(b['callbacks_s'])}",
            f"{_ms(o['wall_min_s'] - o['callbacks_s'])} / "
            f"{_ms(b['wall_min_s'] - b['callbacks_s'])}",
            f"{_ms(o['wall_min_s'] / o['iterations'])} / "
            f"{_ms(b['wall_min_s'] / b['iterations'])}",
            f"{_ms(o['cpu_min_s'])} / {_ms(b['cpu_min_s'])}",
            f"{_ms(o['setup_cached_s'])} ({_ms(o['setup_first_s'])}) / {_ms(b['setup_s'])}",
            f"{r['objective_rel_diff']:+.1e}",
            f"{r['ratio_wall']:.2f}; {r['ratio_cpu']:.2f}"]) + " |")
        if min(r["ratio_wall"], r["ratio_cpu"]) > TARGET:
            why = []
            if o["iterations"] > b["iterations"]:
                why.append(f"{o['iterations']} against {b['iterations']} IPOPT iterations")
            per = (o["wall_min_s"] / o["iterations"]) / (b["wall_min_s"] / b["iterations"])
            if per > 1:
                why.append(f"each iteration {per:.2f}× the baseline's")
            elif o["iterations"] <= b["iterations"]:
                why.append(f"each iteration only {per:.2f}× the baseline's (a smaller KKT "
                           "system, IPOPT's own work per iteration most of the time)")
            missed.append(f"`{r['problem']}` ({r['label']}) at {r['ratio_wall']:.2f}× wall, "
                          f"{r['ratio_cpu']:.2f}× CPU: " + (", ".join(why) or "timing noise"))
    same = [r for r in data["rows"] if abs(r["objective_rel_diff"]) <= 1e-6]
    other = [r for r in data["rows"] if abs(r["objective_rel_diff"]) > 1e-6]
    lines += ["", f"**Verdict (≤ {TARGET:g}× the fair baseline, wall or CPU; solves of "
              "10–50 ms on the shared 2-core machine move by up to ±30 % between runs of "
              "this script).** "
              + ("Met on every row." if not missed else "Missed: " + "; ".join(missed) + ".")
              + (" Same optimum (objectives within 1e-6 relative): "
                 + ", ".join(f"`{r['problem']}`" for r in dict((x['problem'], x) for x in
                                                                 same).values()) + "."
                 if same else "")
              + (" Another local optimum: " + ", ".join(
                  f"`{r['problem']}` ({r['objective_rel_diff']:+.1e})" for r in
                  dict((x['problem'], x) for x in other).values())
                 + " — the hand-written UR5 NLP is satisfied by casmbd's optimum to 1.1e-13 "
                 "(same feasible set), but its IPOPT run from the linear guess takes hundreds "
                 "of iterations to a worse local optimum, and started from casmbd's optimum "
                 "it leaves it and stops at max_iter (3000) near 0.52998 s, its velocity limits "
                 "as bounds with `bound_relax_factor = 0`; with them as rows "
                 "(`detect_simple_bounds` off) it reaches 0.528549 s in 267 iterations "
                 "(11.1 s, measured once)." if other else ""),
              "",
              "**Why a row is slower or faster.** On the pendulums most of a solve is IPOPT's "
              "own work (the KKT factorisations); casmbd's NLP is smaller (the last Radau point "
              "is the next mesh node: 704 variables and 600 rows against 904 and 800 for the "
              "swing-up), so an iteration is cheaper, but IPOPT's inertia correction δ_w I "
              "acts on different variables and its path differs: the same NLP without the "
              "shared point takes exactly the baseline's iterations (swing-up 21, minimum time "
              "26) at a dearer iteration. casmbd's accelerations of the double pendulum (the "
              "articulated-body recursion, built from absolute orientations) depend "
              "structurally on θ₁ (2200 Hessian nonzeros against the closed form's 1600 for "
              "the swing-up), but substituting the closed form changes the solve by 0–10 % "
              "(measured: swing-up 33 iterations either way, minimum time 37 → 34 ms CPU): "
              "the swing-up's gap is IPOPT's path. On the UR5 the "
              "callbacks dominate in the virtual machine; compiled per-element derivatives cut "
              "them at the price of a cold compilation (tens of seconds, once per cache)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--problems", nargs="*")
    parser.add_argument("--update-docs", action="store_true")
    parser.add_argument("--render-only", action="store_true")
    args = parser.parse_args(argv)
    if args.render_only:
        data = json.loads(RESULTS.read_text())
    else:
        data = measure(args.repeat, args.problems)
        RESULTS.write_text(json.dumps(data, indent=1))
    text = markdown(data)
    print(text)
    if args.update_docs:
        replace_section(PERF_DOC, HEAD, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
