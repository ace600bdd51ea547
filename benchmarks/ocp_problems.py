"""Trajectory-optimisation problems of ``ocp/`` against hand-written CasADi baselines.

For every problem file ``ocp/*.toml`` (a scene with an ``[ocp]`` table) and every script
``ocp/*.py`` (run as ``python ocp/NAME.py --json``, which must print the JSON contract of
``casmbd ocp --json``) this measures, each problem in a fresh empty ``CASMBD_CACHE_DIR``:

* **set-up cold** — in a first process: loading the scene, building the problem, its
  derivative functions (per element, or generated and compiled C for the compiled variants)
  and the initial guess, i.e. the wall time of ``load_ocp(path)`` + ``ocp.solve()`` minus the
  NLP solve;
* **set-up cached** — the same in a second process on the same cache (a compiled library is
  loaded, nothing is compiled);
* **NLP solve** — the median over ``--repeat`` solves (more when they are short:
  :data:`MIN_SOLVE_SECONDS`) in the second process of the wall time
  (and of the process CPU time) of the solver call (IPOPT, MUMPS);
* iterations, objective (T for minimum time), the largest NLP constraint violation and the
  replay error (``OcpSolution.replay``: the controls forward-simulated on IDAS, largest state
  difference over the mesh nodes).

Every problem is solved with the default derivatives (``Ocp.compile = "auto"``: per-element
functions in the virtual machine) and with compiled per-element functions
(``compile="elements"``).  Problems with a hand-written baseline
(:mod:`benchmarks.ocp_handwritten`: CasADi Opti, ``expand=True``, IPOPT/MUMPS, N = 50, degree-3
Radau collocation, linear guess) are also run with the baseline's transcription (degree 3, one
collocation element per control interval) in each derivative mode (the whole NLP compiled,
``compile="nlp"``, too) and with the library default (degree 4, one element) where the file
chooses otherwise, and the cart-pole with RK4 multiple shooting;
the baselines are solved in the same run (own process each) and the objectives compared.

Run ``python -m benchmarks.ocp_problems --help``; ``--update-docs`` rewrites the section
:data:`DOC_SECTION` of ``docs/performance.md`` and the table of ``## Problems and figures`` in
``docs/ocp.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

from benchmarks.ocp_report import (
    DOC_SECTION,
    OCP_DOC,
    PERF_DOC,
    SAME,
    SCRIPT_RUNS,
    Row,
    comment_lines,
    perf_table,
    render_perf,
    update_ocp_doc,
    write_csv,
)

REPO_ROOT = pathlib.Path(__file__).resolve().parent.parent
OCP_DIR = REPO_ROOT / "ocp"
DEFAULT_CSV = REPO_ROOT / "benchmarks" / "results" / "ocp_problems.csv"

#: Extra variants (label -> Ocp attribute overrides) run for problems with a baseline: the
#: baseline's transcription with each way of building the derivatives (``Ocp.compile``).
BASELINE_VARIANTS: dict[str, dict] = {
    SAME: {"subintervals": 1, "degree": 3},
    f"{SAME}, virtual machine": {"subintervals": 1, "degree": 3, "compile": False},
    f"{SAME}, whole NLP compiled": {"subintervals": 1, "degree": 3, "compile": "nlp"},
    f"{SAME}, implicit dynamics": {"subintervals": 1, "degree": 3, "dynamics": "implicit"},
    "degree 4, 1 element (the library default)": {"subintervals": 1, "degree": 4}}
#: The problems whose baseline shares the pendulum transcription of
#: :mod:`benchmarks.ocp_handwritten` (the UR5's is its own file's: implicit, degree 4, 12×1).
SAME_TRANSCRIPTION = ("cart_pole", "double_pendulum_swingup", "double_pendulum_min_time")
#: The derivative modes the default may choose, for every other problem file (a mode the
#: default row already used is not run again).
ELEMENTS = {"virtual machine": {"compile": False}, "compiled elements": {"compile": "elements"}}
#: ``stats["derivatives"]`` of each forced mode, to skip variants that repeat the default.
FORCED = {False: "structured, virtual machine", "elements": "structured, compiled elements"}
#: Further variants of single problems.
EXTRA_VARIANTS: dict[str, dict[str, dict]] = {
    "cart_pole": {"RK4 multiple shooting, 4 steps": {"transcription": "multiple_shooting",
                                                      "integrator": "rk4", "steps": 4}},
}
#: Command-line variants of the ``ocp/*.py`` scripts (label -> arguments besides --json);
#: a script not listed runs with its defaults.
SCRIPT_VARIANTS: dict[str, dict[str, list[str]]] = {
    "delta_pick_and_place": {
        "min time, 10×1, degree 3": ["--variant", "time", "--intervals", "10",
                                     "--subintervals", "1", "--degree", "3"],
        "min energy over the obstacle, 10×1": ["--variant", "energy", "--obstacle",
                                               "--intervals", "10", "--subintervals", "1"],
    },
}
def log(message: str) -> None:
    """Progress on stderr."""
    print(message, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------- workers
def _describe(ocp) -> str:
    """A short description of a problem from its Ocp (objective, horizon, bounds, loops)."""
    kinds = []
    for term in ocp._terms:
        kinds.append({"effort": "min effort", "time": "min time", "energy": "min energy",
                      "tracking": "tracking"}.get(term.kind, f"min {term.kind}"))
    parts = [", ".join(dict.fromkeys(kinds)) or "feasibility"]
    if ocp.free_time:
        parts.append(f"free T ∈ [{ocp.horizon.lower:g}, {ocp.horizon.upper:g}] s")
    else:
        parts.append(f"T = {ocp.horizon:g} s")
    bounds = {}
    for name, (lo, hi) in ocp._control_bounds.items():
        key = f"\\|·\\| ≤ {hi:g}" if lo == -hi else f"[{lo:g}, {hi:g}]"
        bounds.setdefault(key, []).append(name)
    for key, names in bounds.items():
        parts.append(key.replace("·", ", ".join(names)) if "·" in key
                     else f"{', '.join(names)} ∈ {key}")
    if ocp.system.nc:
        parts.append(f"closed loop ({ocp.system.nc} constraints)")
    if ocp._path:
        parts.append(f"{len(ocp._path)} path constraint{'s' * (len(ocp._path) > 1)}")
    return ", ".join(parts)


def _transcription_label(stats: dict) -> str:
    t = stats.get("transcription", "?")
    if t == "multiple_shooting":
        return "multiple shooting"
    return (f"{t} d={stats.get('degree')}, {stats.get('intervals')}×"
            f"{stats.get('subintervals')}, {stats.get('dynamics')}")


#: With ``--repeat`` above 1, short solves are repeated until they add up to this many
#: seconds (at most :data:`MAX_SOLVES` solves), ours and the baselines alike: the median of
#: 3 solves of 20 ms on a shared machine is too noisy to compare.
MIN_SOLVE_SECONDS = 0.5
MAX_SOLVES = 25


def enough(solves: list[float], repeat: int) -> bool:
    """Whether ``solves`` (seconds) suffice for ``--repeat repeat``
    (see :data:`MIN_SOLVE_SECONDS`)."""
    return len(solves) >= max(1, repeat) and (
        repeat <= 1 or sum(solves) >= MIN_SOLVE_SECONDS or len(solves) >= MAX_SOLVES)


def worker(path: str, overrides: dict, repeat: int, replay: bool) -> dict:
    """Solve one problem ``repeat`` times in this process, more when the solves are short
    (:func:`enough`; JSON-able figures)."""
    from casmbd.io.ocp_table import load_ocp

    setups, setup_cpus, solves, cpus, compiled, callbacks = [], [], [], [], [], []
    sol = ocp = None
    while not enough(solves, repeat):
        start, cpu0 = time.perf_counter(), _cpu()
        ocp = load_ocp(path)
        for key, value in overrides.items():
            setattr(ocp, key, value)
        sol = _solve(ocp)
        total, cpu_total = time.perf_counter() - start, _cpu() - cpu0
        setup_cpus.append(cpu_total - sol.stats.get("solve_cpu_seconds", math.nan))
        solves.append(sol.stats["solve_seconds"])
        cpus.append(sol.stats.get("solve_cpu_seconds", math.nan))
        callbacks.append(sum(v for k, v in sol.stats.get("timings", {}).items()
                             if k.startswith("t_wall_nlp_")))
        setups.append(total - sol.stats["solve_seconds"])
        compiled.append({"compiled": sol.stats.get("compiled"),
                         "cache_hit": sol.stats.get("cache_hit"),
                         "compile_seconds": sol.stats.get("compile_seconds")})
    out = {"description": _describe(ocp), "setups": setups, "setup_cpus": setup_cpus,
           "solves": solves, "cpus": cpus, "callbacks": callbacks,
           "compiled": compiled, "derivatives": sol.stats.get("derivatives"),
           "dynamics": sol.stats.get("dynamics")}
    s = sol.stats
    if replay and s.get("success"):
        try:
            sol.replay()
        except Exception as exc:  # reported, not fatal for the benchmark
            out["replay_failure"] = f"{type(exc).__name__}: {exc}"
    out.update({"success": bool(s.get("success")), "status": s.get("return_status"),
                "objective": sol.objective, "iterations": sol.iterations,
                "final_time": float(sol.t[-1] - sol.t[0]),
                "constraint_violation": s.get("constraint_violation"),
                "replay_error": sol.stats.get("replay_error"),
                "variables": s.get("variables"), "constraints": s.get("constraints"),
                "transcription": _transcription_label(s)})
    return out


def _cpu() -> float:
    """CPU seconds of this process and its finished children (the C compiler)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _solve(ocp):
    """``ocp.solve()`` returning the solution also when IPOPT fails."""
    from casmbd.errors import OptimizationError

    try:
        return ocp.solve()
    except OptimizationError as exc:
        if exc.solution is None:
            raise
        return exc.solution


def baseline_worker(name: str, repeat: int) -> dict:
    """Solve one hand-written baseline (JSON-able figures)."""
    from dataclasses import asdict

    from benchmarks.ocp_handwritten import solve

    return asdict(solve(name, repeat=repeat))


def _run(args: list[str], cache: str, timeout: float = 1800) -> tuple[dict, float]:
    """Run a worker process with ``CASMBD_CACHE_DIR=cache``; its last stdout line is JSON."""
    env = dict(os.environ, CASMBD_CACHE_DIR=cache)
    start = time.perf_counter()
    proc = subprocess.run(args, capture_output=True, text=True, env=env, cwd=REPO_ROOT,
                          timeout=timeout, check=False)
    wall = time.perf_counter() - start
    lines = [line for line in proc.stdout.splitlines() if line.strip()]
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        raise RuntimeError(f"{' '.join(args[-4:])}: exit {proc.returncode}: "
                           + " | ".join(tail))
    try:
        return json.loads(lines[-1]), wall
    except json.JSONDecodeError:
        return json.loads(proc.stdout), wall  # a script printing indented JSON


# ---------------------------------------------------------------------------------- bench
def discover(names: list[str] | None) -> list[pathlib.Path]:
    """Problem files: ``ocp/*.toml`` and ``ocp/*.py``, or the named ones (stem or path)."""
    found = sorted(OCP_DIR.glob("*.toml")) + sorted(p for p in OCP_DIR.glob("*.py")
                                                    if not p.name.startswith("_"))
    if not names:
        return found
    out = []
    for name in names:
        path = pathlib.Path(name)
        match = [p for p in found if p.stem == name or p.name == name]
        if match:
            out += match
        elif path.exists():
            out.append(path.resolve())
        else:
            raise SystemExit(f"unknown problem '{name}' (known: "
                             f"{', '.join(p.stem for p in found)})")
    return out


def measure_toml(path: pathlib.Path, variant: str, overrides: dict, repeat: int) -> Row:
    """Cold process (fresh cache) then cached process with ``repeat`` solves and a replay."""
    row = Row(path.stem, variant, "toml")
    base = [sys.executable, "-m", "benchmarks.ocp_problems", "--worker", str(path),
            "--overrides", json.dumps(overrides)]
    with tempfile.TemporaryDirectory(prefix="casmbd_ocp_bench_") as cache:
        try:
            cold, cold_wall = _run([*base, "--repeat", "1"], cache)
            warm, warm_wall = _run([*base, "--repeat", str(repeat), "--replay"], cache)
        except (RuntimeError, subprocess.TimeoutExpired) as exc:
            row.figures["error"] = str(exc)[:300]
            return row
    first = cold["compiled"][0]
    again = warm["compiled"][0]
    if first["compiled"] and (first["cache_hit"] or not again["cache_hit"]):
        row.figures["error"] = "cache: cold run hit the cache or cached run missed it"
    row.figures.update({k: warm[k] for k in (
        "description", "success", "status", "objective", "iterations", "final_time",
        "constraint_violation", "replay_error", "variables", "constraints", "transcription",
        "derivatives")})
    row.figures["dynamics"] = warm.get("dynamics")
    if "replay_failure" in warm:
        row.figures["error"] = warm["replay_failure"][:300]
    row.figures.update({
        "setup_cold_s": cold["setups"][0], "compile_s": first["compile_seconds"],
        "setup_cached_s": warm["setups"][0],
        "setup_cold_cpu_s": cold["setup_cpus"][0], "setup_cached_cpu_s": warm["setup_cpus"][0],
        "solve_median_s": statistics.median(warm["solves"]),
        "solve_cpu_median_s": statistics.median(warm["cpus"]),
        "callback_median_s": statistics.median(warm.get("callbacks") or [math.nan]),
        "solve_min_s": min(warm["solves"]),
        "solve_all_s": " ".join(f"{x:.4g}" for x in warm["solves"]),
        "process_cold_s": cold_wall, "process_cached_s": warm_wall / len(warm["solves"]),
    })
    return row


def measure_script(path: pathlib.Path, variant: str, extra: list[str], repeat: int) -> Row:
    """``python ocp/NAME.py [extra] --json``: a cold process, then cached processes (at most
    :data:`SCRIPT_RUNS` in all)."""
    row = Row(path.stem, variant, "py")
    cmd = [sys.executable, str(path), *extra, "--json"]
    with tempfile.TemporaryDirectory(prefix="casmbd_ocp_bench_") as cache:
        try:
            cold, cold_wall = _run(cmd, cache)
            warm = [_run(cmd, cache) for _ in range(max(1, min(repeat, SCRIPT_RUNS - 1)))]
        except (RuntimeError, subprocess.TimeoutExpired, json.JSONDecodeError) as exc:
            row.figures["error"] = str(exc)[:300]
            return row
    data = warm[-1][0]
    stats = data.get("stats", {})
    solves = [w[0].get("stats", {}).get("solve_seconds", math.nan) for w in warm]
    mode = "compiled" if stats.get("compiled") else "virtual machine"
    row.figures.update({
        "description": f"`{' '.join([path.name, *extra])}`, {mode}",
        "success": data.get("success"),
        "status": stats.get("return_status"), "objective": data.get("objective"),
        "iterations": data.get("iterations"), "final_time": data.get("final_time"),
        "constraint_violation": data.get("constraint_violation"),
        "replay_error": data.get("replay_error"), "variables": stats.get("variables"),
        "constraints": stats.get("constraints"), "transcription": _transcription_label(stats),
        "setup_cold_s": cold.get("stats", {}).get("setup_seconds"),
        "compile_s": cold.get("stats", {}).get("compile_seconds"),
        "setup_cached_s": stats.get("setup_seconds"),
        "solve_median_s": statistics.median(solves), "solve_min_s": min(solves),
        "solve_cpu_median_s": statistics.median(
            w[0].get("stats", {}).get("solve_cpu_seconds", math.nan) for w in warm),
        "derivatives": stats.get("derivatives"),
        "solve_all_s": " ".join(f"{x:.4g}" for x in solves),
        "process_cold_s": cold_wall,
        "process_cached_s": statistics.median(w[1] for w in warm),
    })
    if "min time" in variant or data.get("final_time") == data.get("objective"):
        row.figures["description"] += ", min time"
    return row


def measure_baseline(name: str, repeat: int) -> dict:
    """The hand-written baseline in its own process."""
    with tempfile.TemporaryDirectory(prefix="casmbd_ocp_bench_") as cache:
        data, _ = _run([sys.executable, "-m", "benchmarks.ocp_problems", "--baseline-worker",
                        name, "--repeat", str(repeat)], cache)
    return data


def _same_as_file(path: pathlib.Path, overrides: dict) -> bool:
    """Whether a variant only restates the file's own transcription (then it is not run)."""
    import tomllib

    from casmbd.ocp import Ocp

    table = tomllib.loads(path.read_text(encoding="utf-8")).get("ocp", {})
    defaults = {f.name: f.default for f in Ocp.__dataclass_fields__.values()}
    return all(table.get(k, defaults.get(k)) == v for k, v in overrides.items())


def _baseline(name: str, repeat: int) -> dict | None:
    """The baseline ``name`` measured (None if it failed, logged)."""
    log(f"baseline {name}")
    try:
        b = measure_baseline(name, repeat)
    except (RuntimeError, subprocess.TimeoutExpired) as exc:
        log(f"  baseline failed: {exc}")
        return None
    log(f"  objective {b['objective']}, {b['iterations']} iterations, "
        f"solve {b['solve_seconds']:.4g} s")
    return b


def _attach(rows: list[Row], name: str, runs: list[dict]) -> None:
    """Compare the rows of ``name`` with its baseline, measured just before and just after
    them (times: the mean of the two medians, so that a change of load during the problem's
    variants affects both sides alike)."""
    b = dict(runs[0])
    for key in ("solve_seconds", "solve_cpu_seconds", "setup_seconds", "ipopt_wall_seconds",
                "callback_seconds"):
        b[key] = statistics.mean(r.get(key, math.nan) for r in runs)
    for row in rows:
        if row.problem != name or "objective" not in row.figures:
            continue
        ours = row.figures["objective"]
        row.figures.update({
            "baseline_objective": b["objective"],
            "baseline_iterations": b["iterations"],
            "baseline_setup_s": b["setup_seconds"],
            "baseline_solve_s": b["solve_seconds"],
            "baseline_solve_cpu_s": b.get("solve_cpu_seconds", math.nan),
            "ratio_cpu": row.figures.get("solve_cpu_median_s", math.nan)
            / b.get("solve_cpu_seconds", math.nan),
            "baseline_ipopt_wall_s": b["ipopt_wall_seconds"],
            "baseline_callback_s": b["callback_seconds"],
            "baseline_variables": b["variables"],
            "objective_rel_diff": (ours - b["objective"]) / abs(b["objective"]),
            "ratio_solve": row.figures["solve_median_s"] / b["solve_seconds"],
        })


def run(paths: list[pathlib.Path], repeat: int, baselines: bool) -> list[Row]:
    """Every problem and variant; a problem with a hand-written baseline has it measured just
    before and just after its variants, and the comparison attached."""
    from benchmarks.ocp_handwritten import PROBLEMS

    rows: list[Row] = []
    for path in paths:
        if path.suffix == ".py":
            for label, extra in SCRIPT_VARIANTS.get(path.stem, {"defaults": []}).items():
                log(f"{path.name}: {label}")
                rows.append(measure_script(path, label, extra, repeat))
                f = rows[-1].figures
                log(f"  objective {f.get('objective')}, {f.get('iterations')} iterations, "
                    f"solve {f.get('solve_median_s')} s"
                    + (f", ERROR {f['error']}" if "error" in f else ""))
            continue
        compare = baselines and path.stem in PROBLEMS
        runs = [b for b in [_baseline(path.stem, repeat) if compare else None] if b]
        variants = {"as in the file": {}}
        if path.stem in SAME_TRANSCRIPTION:
            variants.update(BASELINE_VARIANTS)
        else:
            variants.update(ELEMENTS)
        variants.update(EXTRA_VARIANTS.get(path.stem, {}))
        for label, overrides in variants.items():
            if overrides and _same_as_file(path, overrides):
                continue
            default = next((r for r in rows if r.problem == path.stem
                            and r.variant == "as in the file"), None)
            if set(overrides) == {"compile"} and default is not None \
                    and default.figures.get("derivatives") == FORCED.get(overrides["compile"]):
                continue
            log(f"{path.name}: {label}")
            rows.append(measure_toml(path, label, overrides, repeat))
            f = rows[-1].figures
            log(f"  objective {f.get('objective')}, {f.get('iterations')} iterations, "
                f"set-up {f.get('setup_cold_s')} / {f.get('setup_cached_s')} s, solve "
                f"{f.get('solve_median_s')} s, replay {f.get('replay_error')}"
                + (f", ERROR {f['error']}" if "error" in f else ""))
        if compare:
            runs += [b for b in [_baseline(path.stem, repeat)] if b]
            if runs:
                _attach(rows, path.stem, runs)
    return rows


# ---------------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--problems", nargs="*", help="stems or paths (default: all of ocp/)")
    parser.add_argument("--repeat", type=int, default=3, help="cached solves per problem")
    parser.add_argument("--csv", type=pathlib.Path, default=DEFAULT_CSV)
    parser.add_argument("--no-baselines", action="store_true")
    parser.add_argument("--update-docs", action="store_true")
    parser.add_argument("--render-only", action="store_true",
                        help="re-render from the .json next to --csv without measuring")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--overrides", default="{}", help=argparse.SUPPRESS)
    parser.add_argument("--replay", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--baseline-worker", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args.worker, json.loads(args.overrides), args.repeat,
                                args.replay)))
        return 0
    if args.baseline_worker:
        print(json.dumps(baseline_worker(args.baseline_worker, args.repeat)))
        return 0

    from benchmarks.bench_equations import machine_info
    from benchmarks.docs import replace_section

    if args.render_only:
        saved = json.loads(args.csv.with_suffix(".json").read_text(encoding="utf-8"))
        info, info_end, command = saved["info"], saved["info_end"], saved["command"]
        rows = [Row(**r) for r in saved["rows"]]
    else:
        info = machine_info()
        info.pop("default flags", None)
        paths = discover(args.problems)
        rows = run(paths, args.repeat, not args.no_baselines)
        info_end = " ".join(f"{x:.2f}" for x in os.getloadavg())
        command = "python -m benchmarks.ocp_problems" + "".join(
            f" {a}" for a in (argv if argv is not None else sys.argv[1:]))
        write_csv(rows, args.csv)
        args.csv.with_suffix(".json").write_text(json.dumps(
            {"info": info, "info_end": info_end, "command": command,
             "rows": [vars(r) for r in rows]}, indent=1), encoding="utf-8")
        log(f"wrote {args.csv} and its .json")
    print(perf_table(rows))
    for line in comment_lines(rows):
        print("\n" + line)
    if args.update_docs:
        if "--update-docs" not in command:
            command = command.replace(" --render-only", "") + " --update-docs"
        replace_section(PERF_DOC, DOC_SECTION, render_perf(rows, command, info, info_end),
                        preamble="# Performance\n\nMeasured costs of casmbd; each section "
                                 "names its command.\n")
        update_ocp_doc(rows, command)
        log(f"updated {PERF_DOC} and {OCP_DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
