"""Scaling study: planar pendulum chains of N = 2 … 1000 rods (issue 9, item 4).

For every size N of :func:`benchmarks.chains.pendulum_chain` and every configuration of
:data:`CONFIGS` (absolute coordinates with the default augmented-Lagrangian ODE and with the
KKT ODE, joint coordinates with the O(N) articulated-body recursion) this measures, each case
in **separate subprocesses** (so that memory is measurable and a crash or a timeout does not
end the study):

* *build child* (fresh, empty ``CASMBD_CACHE_DIR``): ``Simulator(mech, formulation)`` split
  into the symbolic build (System, formulation and post-processing Functions), the C code
  generation, the C compilation and the load (from the
  :class:`casmbd.compiled.codegen.BuildReport`), the size of the generated C source (the
  ``.c`` file kept in the cache) and the peak resident memory of the Python process and of
  the compiler (``resource.getrusage``);
* *run child* (same cache, a new process, i.e. a second run): the Simulator again — it must
  not compile (``report.compiled`` false, ``report.cache_hit`` true) —, the µs per evaluation
  of the compiled right-hand side (``casadi.Function.buffer()``, median of timeit runs: the
  cost the integrator sees), the µs per Jacobian of the right-hand side (the ODE formulations
  build none; measured is CasADi's finite-difference Jacobian of the compiled Function, what a
  Newton-based integrator would use), and the solve time to a tip-position error ≤ 1e-6:
  released horizontally, t ∈ [0, 2] (N ≤ 100) or [0, 0.5] (N ≥ 300), default integrator
  (CVODES-Adams), tolerances 1e-4, 1e-5, … until the error against the reference is met.  The
  reference is the stored minimal-coordinate solution (``benchmarks/reference_data``) when
  it exists (N = 2, 8, 32) and otherwise the same Simulator at rtol = atol = 1e-12.

Variants at large N (``--variant-sizes``): ``-O0`` (``CASMBD_CFLAGS``) and the CasADi virtual
machine (``mode="vm"``), to show what the existing options of
:mod:`casmbd.compiled.codegen` do when ``-O2`` is too slow to compile.

Run ``python -m benchmarks.scaling [--sizes 2 8 32 100 300 1000] [--update-docs] [--quick]``;
``--render`` rewrites the CSV summary, the figure and the docs section from the stored raw
results (``benchmarks/results/scaling.json``) without running anything.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import datetime as _dt
import io
import itertools
import json
import math
import os
import platform
import resource
import shlex
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
CSV_PATH = RESULTS / "scaling.csv"
JSON_PATH = RESULTS / "scaling.json"
PARTIAL_PATH = RESULTS / "scaling_partial.json"
FIGURE = ROOT / "docs" / "figures" / "scaling.png"
DOCS = ROOT / "docs" / "performance.md"
HEAD = "## Scaling to a thousand bodies"

#: configuration -> (coordinates, formulation)
CONFIGS: dict[str, tuple[str, str]] = {
    "abs_al": ("absolute", "augmented_lagrangian"),
    "abs_kkt": ("absolute", "kkt_ode"),
    "joint_aba": ("joint", "articulated"),
}
CONFIG_LABEL = {"abs_al": "absolute, augmented_lagrangian (the default in absolute coordinates)",
                "abs_kkt": "absolute, kkt_ode",
                "joint_aba": "joint, articulated (ABA) with its default integrator DOPRI5: "
                             "the default path of a chain of any length (a tree: joint "
                             "coordinates, the recursion; casmbd/system/choice.py)"}
#: compile variant -> (mode, CASMBD_CFLAGS); "O2" is the library default
VARIANTS: dict[str, tuple[str, str | None]] = {
    "O2": ("compiled", None), "O1": ("compiled", "-O1"), "O0": ("compiled", "-O0"),
    "vm": ("vm", None), "unrolled": ("compiled", None)}
#: variant -> formulation options: "unrolled" is the articulated recursion unrolled body by
#: body (``fold=False``, what the chain got before issue 36), for a comparison in the same run
VARIANT_OPTIONS: dict[str, dict] = {"unrolled": {"fold": False}}
TARGET_ERROR = 1e-6
#: issue 36 item 5: first build of the 1000-rod chain [s], the whole cached process [s]
BUILD_TARGET, PROCESS_TARGET = 10.0, 0.5
TOLERANCES = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
REFERENCE_TOL = 1e-12
STORED_REFERENCES = (2, 8, 32)

#: measured columns (CSV) whose growth exponents are fitted
GROWTH_COLUMNS = ("symbolic_s", "codegen_s", "compile_s", "load_s", "build_total_s",
                  "source_bytes", "build_rss_mb", "compiler_rss_mb", "second_run_s",
                  "cached_process_s", "cached_process_cpu_s", "rhs_us", "jac_fd_us",
                  "steps", "solve_s", "solve_s_per_s", "solve_us_per_step", "run_rss_mb")
CSV_COLUMNS = ("config", "variant", "n", "nq", "nx", "status", "symbolic_s", "codegen_s",
               "compile_s", "load_s", "build_total_s", "build_cpu_s", "source_bytes",
               "build_rss_mb", "compiler_rss_mb", "load_1min", "import_s", "second_run_s",
               "cached_process_s", "cached_process_cpu_s", "second_load_s", "second_compiled",
               "second_cache_hit", "rhs_us", "rhs_call_us", "jac_fd_us", "t_end",
               "reference", "tolerance", "error", "steps", "rhs_evaluations", "solve_s",
               "solve_s_per_s", "solve_us_per_step", "pinocchio_aba_us", "run_rss_mb",
               "message")


def log(msg: str) -> None:
    """Progress on stderr."""
    print(msg, file=sys.stderr, flush=True)


def horizon(n: int) -> float:
    """End time of the solve: 2 s, shortened to 0.5 s for N ≥ 300."""
    return 2.0 if n < 300 else 0.5


def mechanism(n: int, config: str):
    """The chain of ``n`` rods in the coordinates of ``config``, with a unique name."""
    from benchmarks.chains import pendulum_chain

    coordinates, _ = CONFIGS[config]
    mech = pendulum_chain(n)
    mech.coordinates = coordinates
    mech.name = f"scaling_chain{n}_{config}"
    return mech


def _rss_mb(who: int) -> float:
    """Peak resident set size in MB (Linux reports ru_maxrss in kB)."""
    return resource.getrusage(who).ru_maxrss / 1024.0


def time_per_call(fn, repeat: int = 5, min_seconds: float = 0.05) -> float:
    """Median over ``repeat`` timeit runs of the µs per call of ``fn``."""
    timer = timeit.Timer(fn)
    number = 1
    while True:
        elapsed = timer.timeit(number)
        if elapsed >= min_seconds:
            break
        number = max(2 * number, int(number * min_seconds / max(elapsed, 1e-9) * 1.2))
    return 1e6 * statistics.median(timer.repeat(repeat, number)) / number


def _simulator(n: int, config: str, variant: str):
    from casmbd.analysis.dynamics.simulate import Simulator

    mode, _ = VARIANTS[variant]
    _, formulation = CONFIGS[config]
    # the default formulation is chosen by the library for "abs_al" and "joint_aba"
    name = None if formulation in ("augmented_lagrangian", "articulated") else formulation
    sim = Simulator(mechanism(n, config), name, mode=mode,
                    formulation_options=VARIANT_OPTIONS.get(variant))
    if sim.formulation_name != formulation:
        raise RuntimeError(f"expected {formulation}, Simulator chose {sim.formulation_name}")
    return sim


def _build_figures(sim) -> dict:
    rep = sim.model.report
    out = {"nq": sim.model.nq, "compiled": rep.compiled, "cache_hit": rep.cache_hit,
           "codegen_s": rep.codegen_seconds, "compile_s": rep.compile_seconds,
           "load_s": rep.load_seconds, "build_total_s": sim.build_seconds,
           "symbolic_s": sim.build_seconds - rep.codegen_seconds - rep.compile_seconds
           - rep.load_seconds, "source_bytes": math.nan}
    if rep.library:
        source = Path(rep.library).with_suffix(".c")
        if source.exists():
            out["source_bytes"] = source.stat().st_size
    return out


# ------------------------------------------------------------------------ child: build
def child_build(n: int, config: str, variant: str) -> dict:
    """First run in an empty cache: what it costs to build and compile."""
    sim = _simulator(n, config, variant)
    out = _build_figures(sim)
    if VARIANTS[variant][0] == "compiled" and not out["compiled"]:
        raise RuntimeError("the first build in an empty cache did not compile")
    out["build_cpu_s"] = sum(u.ru_utime + u.ru_stime for u in (
        resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)))
    out["build_rss_mb"] = _rss_mb(resource.RUSAGE_SELF)
    out["compiler_rss_mb"] = _rss_mb(resource.RUSAGE_CHILDREN)
    return out


# ------------------------------------------------------------------------ child: run
def _rhs_timings(sim, jac_budget: float) -> dict:
    """µs per evaluation of the compiled right-hand side and of its FD Jacobian."""
    f = sim.dyn
    rng = np.random.default_rng(0)
    nx = f.nnz_in(1)
    x = np.concatenate([sim.model.initial_coordinates(), np.zeros(nx - sim.model.nq)])
    x = x + 1e-3 * rng.standard_normal(nx)
    args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
    args[1][:] = x
    args[3][:] = sim.model.p
    from benchmarks.bench_equations import buffer_evaluator

    trigger, outs = buffer_evaluator(f, args)
    trigger()
    if not np.all(np.isfinite(outs[0])):
        raise RuntimeError("non-finite right-hand side at the timing state")
    out = {"nx": nx, "rhs_us": time_per_call(trigger),
           "rhs_call_us": time_per_call(lambda: f(*args), repeat=3)}
    # CasADi's finite-difference Jacobian of the compiled Function (the ODE formulations do
    # not build an exact one); measured only when it is expected to be cheap enough
    expected = 2.5 * nx * out["rhs_us"] * 1e-6
    out["jac_fd_us"] = math.nan
    if expected < jac_budget:
        jac = f.jacobian()
        jargs = args + [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        jac(*jargs)
        t0 = time.perf_counter()
        reps = max(1, min(20, int(1.0 / max(expected, 1e-6))))
        for _ in range(reps):
            jac(*jargs)
        out["jac_fd_us"] = 1e6 * (time.perf_counter() - t0) / reps
    return out


#: largest chain for which Pinocchio's ``Data`` is allocated: ``model.createData()`` takes
#: 0.18 / 0.63 / 4.1 GB of memory at N = 100 / 200 / 400 (Pinocchio 4.1, growing like
#: N^2.7), so the 1000-rod chain's would exceed this machine's 24 GB (its run child was
#: killed by the kernel's OOM killer)
PINOCCHIO_MAX_N = 400


def _pinocchio(n: int) -> dict:
    """µs per ``pinocchio.aba`` call on the same chain (``JointModelRZ`` joints, as
    :mod:`benchmarks.pinocchio_aba`), in the same run; nothing without Pinocchio or above
    :data:`PINOCCHIO_MAX_N`."""
    if n > PINOCCHIO_MAX_N:
        return {}
    try:
        import pinocchio as pin
    except ImportError:
        return {}
    from benchmarks.pinocchio_aba import pinocchio_chain

    model = pinocchio_chain(n, spatial=False)
    data = model.createData()
    rng = np.random.default_rng(n)
    q, v, tau = rng.uniform(-1.0, 1.0, n), rng.uniform(-1.0, 1.0, n), np.zeros(n)
    return {"pinocchio_aba_us": time_per_call(lambda: pin.aba(model, data, q, v, tau))}


def _tip(res) -> np.ndarray:
    return np.asarray(res.marker("tip")["position"][-1], dtype=float)[:2]


def _solve(sim, t_end: float, tol: float, repeat: int) -> tuple[dict, np.ndarray]:
    times, res = [], None
    for _ in range(repeat):
        res = sim.run(t_end, 1, rtol=tol, atol=tol)
        times.append(res.stats["solve_seconds"])
        if times[-1] > 5.0:
            break
    st = res.stats
    return ({"solve_s": statistics.median(times), "steps": st.get("steps", 0),
             "rhs_evaluations": st.get("rhs_evaluations", 0),
             "integrator": st.get("integrator")}, _tip(res))


def child_run(n: int, config: str, variant: str, jac_budget: float, repeat: int) -> dict:
    """Second run on the same cache: load, evaluation cost, solve time to 1e-6."""
    t0 = time.perf_counter()
    import casmbd.analysis.dynamics.simulate  # noqa: F401  (the import is timed apart from the load)

    imported = time.perf_counter() - t0
    t0 = time.perf_counter()
    sim = _simulator(n, config, variant)
    second = time.perf_counter() - t0
    b = _build_figures(sim)
    out = {"import_s": imported, "second_run_s": second, "second_load_s": b["load_s"],
           "second_compiled": b["compiled"], "second_cache_hit": b["cache_hit"],
           "nq": b["nq"]}
    out.update(_rhs_timings(sim, jac_budget))
    out.update(_pinocchio(n))
    t_end = horizon(n)
    if n in STORED_REFERENCES and t_end == 2.0:
        from benchmarks.references import load_reference

        ref = np.asarray(load_reference(f"pendulum_chain_n{n}")["results"]["tip_position"],
                         dtype=float)
        out["reference"] = "stored"
    else:
        _, ref = _solve(sim, t_end, REFERENCE_TOL, 1)
        out["reference"] = f"self {REFERENCE_TOL:g}"
    out["t_end"] = t_end
    best = None
    for tol in TOLERANCES:
        fig, tip = _solve(sim, t_end, tol, repeat)
        err = float(np.linalg.norm(tip - ref))
        log(f"    tol {tol:.0e}: error {err:.2e}, {fig['steps']} steps, "
            f"{fig['solve_s']:.3g} s")
        best = {**fig, "tolerance": tol, "error": err}
        if err <= TARGET_ERROR:
            break
    out.update(best or {})
    if out.get("steps"):
        out["solve_us_per_step"] = 1e6 * out["solve_s"] / out["steps"]
        out["solve_s_per_s"] = out["solve_s"] / t_end
    out["run_rss_mb"] = _rss_mb(resource.RUSAGE_SELF)
    return out


# ------------------------------------------------------------------------ child: profile
def child_profile(n: int, config: str, variant: str, tol: float) -> dict:
    """cProfile of one solve (after a warm-up run); top entries by internal time."""
    import cProfile
    import pstats

    sim = _simulator(n, config, variant)
    res = sim.run(horizon(n), 1, rtol=tol, atol=tol)
    rhs = _rhs_timings(sim, jac_budget=0.0)
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    res = sim.run(horizon(n), 1, rtol=tol, atol=tol)
    prof.disable()
    wall = time.perf_counter() - t0
    stream = io.StringIO()
    stats = pstats.Stats(prof, stream=stream)
    rows = []
    for (file, line, func), (_cc, nc, tt, ct, _) in stats.stats.items():
        rows.append({"function": f"{Path(file).name}:{line}({func})", "ncalls": nc,
                     "tottime": tt, "cumtime": ct})
    rows.sort(key=lambda r: r["tottime"], reverse=True)
    cum = sorted(rows, key=lambda r: r["cumtime"], reverse=True)
    st = res.stats
    return {"n": n, "config": config, "tolerance": tol, "wall_s": wall,
            "solve_s": st["solve_seconds"], "setup_s": st.get("setup_seconds", 0.0),
            "steps": st.get("steps", 0), "rhs_evaluations": st.get("rhs_evaluations", 0),
            "rhs_us": rhs["rhs_us"], "top_tottime": rows[:12], "top_cumtime": cum[:12]}


# ------------------------------------------------------------------------ parent
def _run_child(args: list[str], cache: Path, timeout: float, env_extra: dict) -> dict:
    """Run one child in its own process group; kill the group on timeout."""
    env = dict(os.environ, CASMBD_CACHE_DIR=str(cache), **env_extra)
    if "CASMBD_CFLAGS" not in env_extra:
        env.pop("CASMBD_CFLAGS", None)
    env.pop("CASMBD_COMPILE", None)
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as handle:
        out_path = Path(handle.name)
    cmd = [sys.executable, "-m", "benchmarks.scaling", "--child", *args, "--out", str(out_path)]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, start_new_session=True)
    try:
        code = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        out_path.unlink(missing_ok=True)
        return {"status": "timeout", "message": f"timeout after {timeout:g} s",
                "wall_s": time.perf_counter() - t0}
    wall = time.perf_counter() - t0
    try:
        data = json.loads(out_path.read_text()) if out_path.stat().st_size else {}
    except (OSError, json.JSONDecodeError):
        data = {}
    out_path.unlink(missing_ok=True)
    if code != 0 and "status" not in data:
        data = {"status": "crashed", "message": f"exit code {code}"}
    data.setdefault("status", "ok")
    data["wall_s"] = wall
    return data


#: a fresh process on a filled cache: interpreter start, imports, the Simulator loaded
_CACHED_PROCESS = """
import sys
from benchmarks.scaling import _simulator
sim = _simulator(int(sys.argv[1]), sys.argv[2], sys.argv[3])
assert not sim.model.report.compiled
"""


def cached_process(n: int, config: str, variant: str, cache: Path, env_extra: dict,
                   repeat: int = 3) -> tuple[float, float]:
    """Wall and processor seconds (user + system, ``getrusage``: the wall time it takes
    alone on an idle core) of the whole cached process (``python -c``: interpreter start,
    ``import casmbd``, the chain, ``Simulator`` from the cache), each the least of
    ``repeat``."""
    env = dict(os.environ, CASMBD_CACHE_DIR=str(cache), **env_extra)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # as after an installation (startup.py)
    wall = cpu = math.inf
    for _ in range(repeat):
        use = resource.getrusage(resource.RUSAGE_CHILDREN)
        c0, t0 = use.ru_utime + use.ru_stime, time.perf_counter()
        subprocess.run([sys.executable, "-c", _CACHED_PROCESS, str(n), config, variant],
                       cwd=ROOT, env=env, check=True, capture_output=True, timeout=300)
        use = resource.getrusage(resource.RUSAGE_CHILDREN)
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, use.ru_utime + use.ru_stime - c0)
    return wall, cpu


def run_case(n: int, config: str, variant: str, timeout: float, jac_budget: float,
             repeat: int) -> dict:
    """Build child in a fresh cache, then the run child on the same cache."""
    row: dict = {"config": config, "variant": variant, "n": n,
                 "load_1min": os.getloadavg()[0]}
    _mode, cflags = VARIANTS[variant]
    env = {"CASMBD_CFLAGS": cflags} if cflags else {}
    with tempfile.TemporaryDirectory(prefix="casmbd_scaling_") as cache:
        log(f"N={n} {config} {variant}: build")
        build = _run_child(["build", str(n), config, variant], Path(cache), timeout, env)
        row["build_wall_s"] = build.pop("wall_s")
        row.update({k: v for k, v in build.items()})
        if build["status"] != "ok":
            log(f"  {build['status']}: {build.get('message', '')}")
            return row
        log(f"  symbolic {build['symbolic_s']:.2f} s, codegen {build['codegen_s']:.2f} s, "
            f"compile {build['compile_s']:.2f} s, source {build['source_bytes']} B")
        log(f"N={n} {config} {variant}: second run, RHS and solves")
        run = _run_child(["run", str(n), config, variant, "--jac-budget", str(jac_budget),
                          "--repeat", str(repeat)], Path(cache), timeout, env)
        row["run_wall_s"] = run.pop("wall_s")
        status = run.pop("status")
        row.update(run)
        if status != "ok":
            row["status"] = f"run {status}"
            log(f"  {status}: {run.get('message', '')}")
            return row
        with contextlib.suppress(subprocess.SubprocessError, OSError):
            row["cached_process_s"], row["cached_process_cpu_s"] = cached_process(
                n, config, variant, Path(cache), env)
        log(f"  cached process {row.get('cached_process_s', math.nan):.2f} s "
            f"(CPU {row.get('cached_process_cpu_s', math.nan):.2f} s)")
        log(f"  second run {run['second_run_s']:.2f} s (compiled {run['second_compiled']}), "
            f"RHS {run['rhs_us']:.2f} µs, solve {run.get('solve_s', math.nan):.3g} s "
            f"(tol {run.get('tolerance')}, error {run.get('error', math.nan):.1e})")
    return row


def machine_info() -> dict:
    """CPU, cores, OS, versions, compiler, load averages."""
    import casadi
    import scipy

    cpu = platform.processor() or "unknown CPU"
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    try:
        cc = subprocess.run(["cc", "--version"], capture_output=True, text=True,
                            timeout=30).stdout.splitlines()[0]
    except (OSError, IndexError, subprocess.TimeoutExpired):
        cc = "not found"
    return {"CPU": cpu, "cores": str(os.cpu_count()),
            "OS": f"{platform.system()} {platform.release()} {platform.machine()}",
            "Python": platform.python_version(), "CasADi": casadi.__version__,
            "NumPy": np.__version__, "SciPy": scipy.__version__, "C compiler": cc,
            "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "load average at start": " ".join(f"{x:.2f}" for x in os.getloadavg())}


# ------------------------------------------------------------------------ analysis
def _num(row: dict, key: str) -> float:
    try:
        value = float(row.get(key, math.nan))
    except (TypeError, ValueError):
        return math.nan
    return value


def growth(rows: list[dict], config: str, variant: str, column: str
           ) -> tuple[list[tuple[int, int, float]], float, tuple[int, int]]:
    """Log-log slopes of ``column`` between successive sizes and over the whole range.

    Returns (successive slopes (n1, n2, k), least-squares slope over all valid points,
    (n_min, n_max)).  Sizes whose value is missing or not positive are skipped.
    """
    pts = sorted((r["n"], _num(r, column)) for r in rows
                 if r["config"] == config and r["variant"] == variant)
    pts = [(n, v) for n, v in pts if math.isfinite(v) and v > 0]
    pairs = [(a[0], b[0], math.log(b[1] / a[1]) / math.log(b[0] / a[0]))
             for a, b in itertools.pairwise(pts)]
    if len(pts) < 2:
        return pairs, math.nan, (0, 0)
    x = np.log([p[0] for p in pts])
    y = np.log([p[1] for p in pts])
    slope = float(np.polyfit(x, y, 1)[0])
    return pairs, slope, (pts[0][0], pts[-1][0])


# ------------------------------------------------------------------------ output
def write_csv(rows: list[dict], path: Path) -> None:
    """One row per (config, variant, N)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, CSV_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for r in ordered(rows):
            writer.writerow({k: r.get(k, "") for k in CSV_COLUMNS})


def plot(rows: list[dict], path: Path, timeout: float = 600.0) -> None:
    """Log-log time columns against N, one panel per configuration (default flags)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = [("symbolic_s", "symbolic build [s]"), ("codegen_s", "codegen [s]"),
               ("compile_s", "C compile [s]"), ("second_run_s", "second run (cache) [s]"),
               ("solve_s", "solve to 1e-6 [s]"), ("rhs_us", "RHS [µs]"),
               ("jac_fd_us", "FD Jacobian [µs]")]
    fig, axes = plt.subplots(1, len(CONFIGS), figsize=(15, 5.4), sharey=True)
    for ax, config in zip(axes, CONFIGS):
        for i, (key, label) in enumerate(columns):
            pts = sorted((r["n"], _num(r, key)) for r in rows
                         if r["config"] == config and r["variant"] == "O2")
            pts = [(n, v) for n, v in pts if math.isfinite(v) and v > 0]
            if pts:
                ax.loglog(*zip(*pts), "o-", color=f"C{i}", label=label)
        ns = sorted({r["n"] for r in rows})
        if ns:
            ref = np.array([ns[0], ns[-1]], dtype=float)
            ax.loglog(ref, 1e-2 * ref / ref[0], "k:", lw=0.8, label="∝ N")
            ax.loglog(ref, 1e-2 * (ref / ref[0]) ** 2, "k--", lw=0.8, label="∝ N²")
        for variant, marker in (("O0", "s"), ("vm", "^")):
            pts = sorted((r["n"], _num(r, "compile_s") if variant != "vm" else
                          _num(r, "solve_s")) for r in rows
                         if r["config"] == config and r["variant"] == variant)
            pts = [(n, v) for n, v in pts if math.isfinite(v) and v > 0]
            if pts:
                ax.loglog(*zip(*pts), marker, mfc="none", ms=9, color="C2" if variant == "O0"
                          else "C4",
                          label="compile -O0 [s]" if variant == "O0" else "solve, VM [s]")
        out = [r["n"] for r in rows if r["config"] == config and r["variant"] == "O2"
               and r.get("status") == "timeout"]
        if out:
            ax.loglog(out, [timeout] * len(out), "rx", ms=12, mew=2,
                      label="first build timed out (at the timeout)")
        ax.set_title(CONFIG_LABEL[config], fontsize=10)
        ax.set_xlabel("N (rods)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("seconds, or µs for RHS / Jacobian")
    handles: dict = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles), loc="lower center",
               ncol=min(6, len(handles)), fontsize=8)
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fmt(value, digits: int = 3) -> str:
    if value is None or value == "":
        return "—"
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float) and not math.isfinite(value):
        return "—"
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}g}"


def ordered(rows: list[dict]) -> list[dict]:
    """Rows by configuration, flags (default first) and N."""
    return sorted(rows, key=lambda r: (list(CONFIGS).index(r["config"]),
                                       list(VARIANTS).index(r["variant"]), r["n"]))


def table(rows: list[dict]) -> list[str]:
    """Markdown table of every case."""
    rows = ordered(rows)
    head = ("| config | flags | N | nx | status | load | symbolic [s] | codegen [s] | "
            "compile [s] | first build [s] | build CPU [s] | "
            "C source [MB] | build RSS [MB] | cc RSS [MB] | 2nd run [s] | cached process [s] | "
            "cached CPU [s] | "
            "2nd compiled | "
            "RHS [µs] | FD Jac [µs] | t_end [s] | ref | tol | error | steps | solve [s] | "
            "µs/step | run RSS [MB] |")
    lines = [head, "|" + " --- |" * 5 + " ---: |" * (head.count("|") - 6)]
    for r in rows:
        src = _num(r, "source_bytes")
        lines.append("| " + " | ".join([
            r["config"], r["variant"], str(r["n"]), _fmt(r.get("nx")),
            str(r.get("status", "")), _fmt(r.get("load_1min"), 2), _fmt(r.get("symbolic_s")),
            _fmt(r.get("codegen_s")), _fmt(r.get("compile_s")), _fmt(r.get("build_total_s")),
            _fmt(r.get("build_cpu_s")),
            _fmt(src / 1e6 if math.isfinite(src) else math.nan),
            _fmt(r.get("build_rss_mb"), 4), _fmt(r.get("compiler_rss_mb"), 4),
            _fmt(r.get("second_run_s")), _fmt(r.get("cached_process_s")),
            _fmt(r.get("cached_process_cpu_s")),
            ("—" if "second_compiled" not in r else
             ("**yes**" if r["second_compiled"] else "no")),
            _fmt(r.get("rhs_us")), _fmt(r.get("jac_fd_us")), _fmt(r.get("t_end")),
            _fmt(r.get("reference")), _fmt(r.get("tolerance"), 1), _fmt(r.get("error"), 2),
            _fmt(r.get("steps")), _fmt(r.get("solve_s")), _fmt(r.get("solve_us_per_step")),
            _fmt(r.get("run_rss_mb"), 4)]) + " |")
    return lines


def growth_lines(rows: list[dict]) -> list[str]:
    """Growth exponents of every measured column, per configuration (default flags)."""
    lines = ["| config | column | successive slopes | fit over the range |",
             "| --- | --- | --- | ---: |"]
    for config in CONFIGS:
        for column in GROWTH_COLUMNS:
            pairs, slope, (lo, hi) = growth(rows, config, "O2", column)
            if not pairs:
                continue
            succ = ", ".join(f"{a}→{b}: {k:.2f}" for a, b, k in pairs)
            lines.append(f"| {config} | {column} | {succ} | {slope:.2f} ({lo}–{hi}) |")
    return lines


def _get(rows, config, n, variant="O2") -> dict | None:
    return next((r for r in rows if r["config"] == config and r["n"] == n
                 and r["variant"] == variant), None)


def targets(rows: list[dict]) -> list[str]:
    """Issue 22 item 3's targets against the measurements (every configuration; the
    default path is the configuration the library picks for the chain)."""
    out, build, second, rhs, lin, cached = [], [], [], [], [], []
    for config in CONFIGS:
        r = _get(rows, config, 1000)
        if r is not None:
            total = _num(r, "build_total_s")
            verdict = "met" if total <= BUILD_TARGET else \
                f"**missed** by {total / BUILD_TARGET:.2f}×"
            build.append(f"{config} {total:.1f} s ({verdict})" if math.isfinite(total)
                         else f"{config} {r.get('status')} (**missed**)")
        runs = [x for x in rows if x["config"] == config and x["variant"] == "O2"
                and math.isfinite(_num(x, "second_run_s"))]
        if r is not None and math.isfinite(_num(r, "cached_process_s")):
            whole, cpu = _num(r, "cached_process_s"), _num(r, "cached_process_cpu_s")
            cached.append(f"{config} {whole:.2f} s wall, {cpu:.2f} s CPU (wall " + (
                "met" if whole <= PROCESS_TARGET else
                f"**missed** by {whole / PROCESS_TARGET:.2f}×") + "; CPU " + (
                "met" if cpu <= PROCESS_TARGET else
                f"**missed** by {cpu / PROCESS_TARGET:.2f}×") + ")")
        if runs:
            top = max(runs, key=lambda x: x["n"])
            worst = max(_num(x, "second_run_s") for x in runs)
            second.append(f"{config} {_num(top, 'second_run_s'):.3f} s at N = {top['n']} "
                          f"(largest over N: {worst:.3f} s, "
                          f"{'met' if worst <= 1.0 else '**missed**'}; `import casmbd` "
                          f"before it: {_num(top, 'import_s'):.2f} s)")
        ratios = [(x["n"], _num(x, "rhs_us") / _num(x, "pinocchio_aba_us")) for x in runs
                  if math.isfinite(_num(x, "rhs_us") / _num(x, "pinocchio_aba_us"))]
        if ratios:
            rhs.append(f"{config} " + ", ".join(f"N = {n}: {q:.2g}" for n, q in ratios)
                       + (" (met)" if all(q <= 2.0 for _, q in ratios) else " (**missed**)"))
        _, k_solve, rng = growth(rows, config, "O2", "solve_s_per_s")
        _, k_steps, _ = growth(rows, config, "O2", "steps")
        _, k_rhs, _ = growth(rows, config, "O2", "rhs_us")
        if math.isfinite(k_solve):
            lin.append(f"{config}: N^{k_solve:.2f} ({rng[0]}–{rng[1]}; steps N^{k_steps:.2f}, "
                       f"RHS N^{k_rhs:.2f}) " + ("(met)" if k_solve <= 1.1 else "(**missed**)"))
    out.append(f"- *N = 1000 builds and compiles in ≤ {BUILD_TARGET:g} s* (issue 36; first "
               "run, empty cache, whole `Simulator` construction): "
               + ("; ".join(build) or "not measured") + ".")
    out.append(f"- *The cached second process at N = 1000 takes ≤ {PROCESS_TARGET:g} s* "
               "(issue 36; a new `python -c` process: interpreter start, imports, the chain, "
               "the `Simulator` from the cache; fastest of 3): "
               + ("; ".join(cached) or "not measured") + ".")
    out.append("- *A cached second run loads in ≤ 1 s* (the whole `Simulator` construction, "
               "in a new process on the same cache: the model record is found by the "
               "model's description, no System is built and no C written): "
               + ("; ".join(second) or "not measured") + ".")
    out.append("- *RHS ≤ 2× Pinocchio's ABA on the same chain, same run* (ratio of our "
               "compiled right-hand side through `Function.buffer()` to `pinocchio.aba` on "
               "the chain with `JointModelRZ` joints, both µs per Python call): "
               + ("; ".join(rhs) or "Pinocchio not installed") + ".")
    out.append("- *Solve time to tip error 1e-6 grows no faster than N^1.1* (fit of the "
               "solve seconds per simulated second, since N ≥ 300 integrate 0.5 s instead "
               "of 2 s): " + ("; ".join(lin) or "not measured") + ".")
    second_runs = [r for r in rows if "second_compiled" in r]
    recompiled = [f"{r['config']}/{r['variant']}/N={r['n']}" for r in second_runs
                  if r["second_compiled"] or (r["variant"] != "vm"
                                              and not r.get("second_cache_hit"))]
    out.append(f"- *No compile on a second run*: checked in {len(second_runs)} second runs: "
               + ("met in every one." if not recompiled else
                  "**missed** for " + ", ".join(recompiled) + "."))
    return out


def variant_lines(rows: list[dict]) -> list[str]:
    """The compile options side by side at the sizes where they were measured."""
    cases = sorted({(r["config"], r["n"]) for r in rows if r["variant"] != "O2"},
                   key=lambda c: (list(CONFIGS).index(c[0]), c[1]))
    if not cases:
        return []
    lines = ["| config | N | flags | status | compile [s] | whole first build [s] | "
             "2nd run [s] | RHS [µs] | solve [s] | error |",
             "| --- | ---: | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for config, n in cases:
        for variant in VARIANTS:
            r = _get(rows, config, n, variant)
            if r is None:
                continue
            lines.append(f"| {config} | {n} | {variant} | {r.get('status', '')} | "
                         f"{_fmt(r.get('compile_s'))} | {_fmt(r.get('build_total_s'))} | "
                         f"{_fmt(r.get('second_run_s'))} | {_fmt(r.get('rhs_us'))} | "
                         f"{_fmt(r.get('solve_s'))} | {_fmt(r.get('error'), 2)} |")
    return lines


def profile_lines(prof: dict | None) -> list[str]:
    """Where the time of one mid-size solve goes."""
    if not prof:
        return ["(no profile recorded)"]
    rhs_total = prof["rhs_evaluations"] * prof["rhs_us"] * 1e-6
    run_total = next((r["cumtime"] for r in prof["top_cumtime"]
                      if r["function"].startswith("simulate.py") and "(run)" in r["function"]),
                     prof["wall_s"])
    integrator_call = next((r for r in prof["top_cumtime"]
                            if "integrate" in r["function"] or "Function_call" in r["function"]
                            ), None)
    lines = [f"cProfile of one solve: N = {prof['n']}, {CONFIG_LABEL[prof['config']]}, "
             f"CVODES-Adams at rtol = atol = {prof['tolerance']:g}, t ∈ [0, "
             f"{horizon(prof['n']):g}] s, after a warm-up run (command: `python -m "
             f"benchmarks.scaling --profile {prof['n']}`). `Simulator.run` took "
             f"{run_total:.3f} s under the profiler, of which the integration (`solve_seconds`) "
             f"{prof['solve_s']:.3f} s for {prof['steps']} steps and "
             f"{prof['rhs_evaluations']} right-hand-side evaluations. At "
             f"{prof['rhs_us']:.2f} µs per compiled evaluation the right-hand side accounts "
             f"for ≈ {rhs_total:.3f} s ({100 * rhs_total / prof['solve_s']:.0f} % of the "
             f"integration); the rest of the integration is SUNDIALS and CasADi's "
             f"integrator plumbing in C, and everything outside `solve_seconds` is the "
             f"Python set-up and post-processing.", ""]
    lines += ["No Python runs inside the integration: CVODES calls the compiled right-hand "
              "side from C in one `Function_call`. Python loops outside it: the stiffness "
              "probe before the solve (`Simulator.stiffness`, "
              "casmbd/analysis/dynamics/simulate.py, 2 n_x + 1 Python calls of the compiled "
              "Function for n_x ≤ 400, by finite "
              "differences) and the post-processing (`_post`; here dominated by one dense "
              "SVD of C_q in "
              "`casmbd/analysis/instant/undetermined_reactions.py::multiplier_null_space`, O(n_c² "
              "n_q): 0.09 s here against 0.03 s of integration).", ""]
    if integrator_call:
        lines += [f"Largest cumulative entry: `{integrator_call['function']}` "
                  f"{integrator_call['cumtime']:.3f} s.", ""]
    lines += ["Top entries by internal time (tottime):", "",
              "| function | calls | tottime [s] | cumtime [s] |", "| --- | ---: | ---: | ---: |"]
    for r in prof["top_tottime"][:10]:
        lines.append(f"| `{r['function']}` | {r['ncalls']} | {r['tottime']:.4f} | "
                     f"{r['cumtime']:.4f} |")
    lines += ["", "Top entries by cumulative time:", "",
              "| function | calls | tottime [s] | cumtime [s] |", "| --- | ---: | ---: | ---: |"]
    for r in prof["top_cumtime"][:10]:
        lines.append(f"| `{r['function']}` | {r['ncalls']} | {r['tottime']:.4f} | "
                     f"{r['cumtime']:.4f} |")
    return lines


NOTES = """\
### Findings

Read off the tables above and from one-off measurements on the same machine during the same
hour (the latter not re-measured by the command). The 2 cores were shared with other jobs
(the *load* column: 1-minute load average when the case started); wall times vary by 2× between
runs at loads 4-8, so compare rows of one run, and the *CPU* columns.

* *Issue 36, item 5: the default path of the 1000-rod chain.* It is joint coordinates, the
  articulated recursion and DOPRI5; from 32 rods on the recursion of a planar revolute chain
  loaded by gravity is now *folded* (`casmbd/system/chain_fold.py`): its three passes
  (kinematics root to tip, articulated inertias tip to root, accelerations root to tip) are
  each one small per-body SX Function applied over the bodies by CasADi's `mapaccum`, with
  what is equal for every rod (design frames, joint points, mass, inertia) built in as
  constants. Its q̈ equals the unrolled recursion's to 1e-12 on a 20-rod chain
  (tests/system/test_chain_fold.py); the rows *unrolled* (formulation option `fold=False`,
  the code of before issue 36) are the same chain in the same run. The right-hand side's C
  is 0.34 MB at N = 1000 (mostly index tables) instead of 5.7 MB, compiled at `-O2` in
  about 2 s of CPU; the solve no longer runs `-O0` code.
* *The rest of the chain's model folded too* (this issue, branch h-fold2): the outputs
  (positions, velocities, accelerations of the bodies and the tip marker, angles) from one
  per-body forward-kinematics step folded root to tip, the kinetic and potential energies
  (their own Functions and `post`'s) as sums over those columns
  (`casmbd/system/chain_motion.py`), the joint reactions by a backward Newton–Euler pass
  folded tip to root and the mass matrix (read once per run by the start check
  `check_mass_matrix`) as that pass on unit accelerations mapped over its columns
  (`casmbd/system/chain_reactions.py`); each equals the body-by-body Function to 1e-12
  (tests/system/test_chain_motion.py). The C of the 1000-rod model is 1.8 MB instead of
  13.6 MB, and the symbolic build 0.47 s instead of 4.9 s (the System's expressions are no
  longer written out).
* *Folded against unrolled* (rows *O2* and *unrolled* of the same run, loads 2.4-3.2;
  *unrolled* is `fold=False`: every Function body by body, the code of before issue 36): at
  N = 100, 300 and 1000 the folded chain builds in 1.1 / 1.6 / 4.9 s against
  11.9 / 20.4 / 20.2 s (processor time 1.5 / 2.0 / 5.0 s against 9.1 / 18.7 / 32.2 s; the
  unrolled 1000-rod build compiles its `-O0` units on both cores). With only the right-hand
  side folded (the previous run of this table, loads 3.3-4.0) the folded chain built in
  2.9 / 8.9 / 29.6 s (processor time 2.6 / 6.9 / 26.2 s). Its right-hand side costs 9.0 /
  41.9 / 98.7 µs against 8.0 / 15.7 / 237 µs unrolled: where gcc can still optimise the
  unrolled code (`-O2` below 1 MB of C, `-O1` to 3 MB) it is faster per call, because each
  body's constants are folded into it, while at N = 1000 it is `-O0` and 2.4× slower. The
  fold starts at 32 rods (`FOLD_MIN_BODIES`).
* *Target "cold build + compile ≤ 10 s" at N = 1000: met* (4.9 s at load 2.5, 5.0 s of
  processor time: symbolic 0.47 s, codegen 0.25 s, compile 4.2 s). What the compiler still
  gets is the folds' call tables (CasADi's `mapaccum` writes one call per body: 1.8 MB of C
  for the right-hand side, DOPRI5's block, `post`, the outputs, reactions, M and energies).
  Only a planar serial chain of revolute joints loaded by gravity is folded; other trees
  (branches, spatial joints, force elements, actuators, output requests) are still written
  body by body.
* *Target "cached second process ≤ 0.5 s" at N = 1000: met* — the whole `python -c`
  process (interpreter, imports, the chain, the `Simulator` from the model record: no System
  and no SX expression is built, tests/compiled/test_cached_process.py counts them) takes
  0.35 s of wall time and 0.28 s of processor time (the N = 1000 row; 0.42 / 0.31 s in the
  previous run at load 3.8; 0.21-0.23 s at the smaller sizes). The simulator's imports no
  longer load scipy (0.2 s: scipy.sparse and
  scipy.linalg are imported on first use through `casmbd/lazy.py`). The issue's 1.9 s was a
  process with a run: one-off, `Simulator(chain).run(0.5, 50)` in a new process on the cache
  takes 1.1-1.6 s of wall time at load 3 (1.8-1.9 s before this issue at the same load):
  the solve 0.12-0.2 s, the post-processing of the outputs 0.4 s, the start checks 0.3 s
  (`check_mass_matrix`: M of the 1000-rod chain by 1000 mapped columns and its
  factorisation; with the folded M one-off 0.7 s at load 2.5: two evaluations of 0.22 s and
  a dense Cholesky) — outside this target; scipy.optimize (0.3 s to import) is now imported
  only when a near-singular passage is refined. Since branch h-runcost the start of a run
  checks M > 0 of a folded chain by its articulated-body pivots (D_i > 1e-12 M_ii, one O(N)
  fold, `casmbd/system/chain_pivots.py`; M itself, its dense factorisation and the
  eigen-decomposition that names the massless bodies only when that test fails): that
  process takes 0.67-0.70 s of wall time at load 1.5 (run 0.21 s: solve 0.12 s, outputs
  0.08 s) against 1.53-2.05 s for the code before (run 1.0-1.5 s), one-off.
* *Target "solve growth ≤ N^1.1"*: the fit over 10-1000 above mixes the unrolled code at
  10 rods with the folded code from 32 on and the shorter horizon from 300 on; over the
  folded sizes 32-1000 the solve seconds per simulated second grew like N^1.07 in the
  previous run (RHS N^0.98, steps N^-0.61 with the horizon change) and N^1.27 in this one
  (100-1000: N^1.06; the solve columns are single median-of-3 runs on shared cores, and the
  N = 300 solve took 0.0098 s here against 0.034 s before): not met over the whole range.
* *The tree reactions' build was O(N²)*: for every body it scanned every joint for constraint
  rows, also with none (268 k generator steps at N = 300); it now returns at once without
  constraint equations.
* *Compile flags by size* (unchanged; what the unrolled rows get): a hot function up to
  1 MB of C gets `-O2`, 1-3 MB `-O1`, above `-O0` (gcc's `-O2` is superlinear on CasADi's
  straight-line code: at N = 300 the unrolled articulated right-hand side takes 97.8 s at
  `-O2` for 28.1 µs per call, 16.4 s at `-O1` for 20.8 µs, 2.8 s at `-O0` for 93.8 µs, alone
  on one core). A caller of a hot function shares its translation unit only when the hot C
  exceeds 1 MB (`units.SHARE_SOURCE`): the folded right-hand side (0.34 MB at N = 1000) is
  repeated in `post`'s `-O0` unit instead of pulling the unrolled energies into the `-O2`
  unit (the first run of this issue's table: 40-54 s of compilation at N = 1000).
* *Pinocchio at N = 1000*: not measured. `pinocchio.Model.createData()` for the chain with
  `JointModelRZ` joints takes 0.18 / 0.63 / 4.1 GB at N = 100 / 200 / 400 (Pinocchio 4.1,
  growing like N^2.7); the benchmark skips Pinocchio above N = 400.
* *Absolute coordinates* (rows kept from the run of 2026-11-25, `--merge`) are the automatic
  choice only for mechanisms with many loops or no spanning tree; their right-hand side
  (augmented Lagrangian: a symbolic sparse LDLᵀ of the KKT matrix) grows like N^1.4.

"""


def markdown(data: dict) -> str:
    """The docs section."""
    rows, info = data["rows"], data["info"]
    variants = sorted({r["variant"] for r in rows} - {"O2"})
    parts = [
        HEAD, "",
        "Generated by `benchmarks/scaling.py`; do not edit by hand. Command:", "",
        "```", data["command"], "```", "",
        "Machine (shared with other work during the run: the load averages show how much; "
        "compile and solve figures of one run, not minima):", "",
        *(f"- {k}: {v}" for k, v in info.items()), "",
        f"Total wall time of the study: {data.get('wall_s', math.nan) / 60:.1f} min.", "",
        "Model: `benchmarks.chains.pendulum_chain(N)` released horizontally. Configurations: "
        + "; ".join(f"`{k}` = {v}" for k, v in CONFIG_LABEL.items())
        + ". Every (configuration, N, flags) runs in two fresh subprocesses: the *build* "
        "child constructs `Simulator(mech, formulation)` in an empty `CASMBD_CACHE_DIR` "
        "(*symbolic*: System, formulation and post-processing Functions; *codegen*: C "
        "generation and hashing; *compile*: the C compiler; *C source*: the `.c` file kept "
        "in the cache; *build RSS*: peak resident memory of the Python process, *cc RSS*: of "
        "the compiler); the *run* child constructs it again on the same cache (*2nd run*: "
        "the whole constructor, after `import casmbd` which is timed apart; *2nd compiled* "
        "must be *no*), times `pinocchio.aba` on the same chain, the compiled right-hand "
        "side (*RHS*: µs per evaluation through `casadi.Function.buffer()`, median of "
        "timeit runs; the ODE formulations build no Jacobian, so *FD Jac* is CasADi's "
        "finite-difference Jacobian of the compiled Function — 2 n_x + 1 evaluations "
        "— measured where it costs < 2 s), and solves with the default integrator "
        "(CVODES-Adams for the absolute-coordinate configurations, DOPRI5 for joint_aba) "
        "at rtol = atol = 1e-4, 1e-5, … until the "
        "tip-position error is ≤ 1e-6: *solve* is `stats['solve_seconds']` (integration "
        "only; median of up to 3 runs) at the loosest tolerance that reaches it. *ref*: the "
        "stored minimal-coordinate reference (N = 2, 8, 32) or the same Simulator at "
        "rtol = 1e-12 (self-convergence). t ∈ [0, 2] s for N ≤ 100 and [0, 0.5] s for "
        "N ≥ 300. Per-case timeout: " f"{data.get('timeout', math.nan):g} s per child."
        + (f" Variants: {', '.join(variants)} (`O0`/`O1` through `CASMBD_CFLAGS`, "
           "`vm` = `Simulator(..., mode=\"vm\")`: CasADi's virtual machine, no C at all; "
           "`unrolled` = `formulation_options={\"fold\": False}`: the articulated "
           "recursion unrolled body by body, as before issue 36); `O2` is the library "
           "default. *load*: 1-minute load average when the case started; *build CPU*: "
           "processor time of the build child and its compilers; *cached process*: a new "
           "`python -c` process on the filled cache (interpreter, imports, the chain, the "
           "`Simulator`), fastest of 3, wall and *cached CPU*." if variants else ""), "",
        "![scaling](figures/scaling.png)", "",
        "### Every case", "",
        *table(rows), "",
        "### Growth exponents", "",
        "k in quantity ∝ N^k, log-log slopes between successive sizes and the least-squares "
        "fit over all sizes measured (default flags). The solve columns of N ≥ 300 are for "
        "the shorter horizon.", "",
        *growth_lines(rows), "",
        "### Against the issue's targets", "",
        *targets(rows), "",
        *(["### Compile options at large N", "",
           "What the existing options of `casmbd.compiled.codegen` give where `-O2` is slow "
           "(`CASMBD_CFLAGS=-O0` / `-O1`, or `mode=\"vm\"`; library defaults unchanged):",
           "", *variant_lines(rows), ""] if variant_lines(rows) else []),
        NOTES,
        "### Where a solve spends its time", "",
        *profile_lines(data.get("profile")), "",
    ]
    return "\n".join(parts).rstrip("\n") + "\n"


# ------------------------------------------------------------------------ main
def parse(argv=None) -> argparse.Namespace:
    """Command line."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.scaling",
                                description=__doc__.splitlines()[0])
    p.add_argument("--sizes", nargs="+", type=int, default=[2, 8, 32, 100, 300, 1000])
    p.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    p.add_argument("--variant-sizes", nargs="*", type=int, default=None,
                   help="sizes also measured with -O0 and the VM (default: sizes >= 300)")
    p.add_argument("--variant-configs", nargs="*", default=["abs_al", "joint_aba"],
                   choices=list(CONFIGS))
    p.add_argument("--variants", nargs="*", default=["O0", "vm"],
                   choices=[v for v in VARIANTS if v != "O2"])
    p.add_argument("--timeout", type=float, default=600.0, help="seconds per child process")
    p.add_argument("--jac-budget", type=float, default=2.0,
                   help="measure the FD Jacobian only if one costs less than this [s]")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--quick", action="store_true", help="sizes 2 8 32, no docs, no variants")
    p.add_argument("--update-docs", action="store_true")
    p.add_argument("--render", action="store_true",
                   help="no runs: CSV, figure and docs from benchmarks/results/scaling.json")
    p.add_argument("--profile", type=int, default=None, metavar="N",
                   help="only the cProfile of one solve of the default formulation")
    p.add_argument("--merge", action="store_true",
                   help="keep the stored rows (scaling.json) of the configurations not run")
    p.add_argument("--resume", action="store_true",
                   help="keep the cases of benchmarks/results/scaling_partial.json (an "
                        "interrupted run) and measure only the others")
    p.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    p.add_argument("--out", help=argparse.SUPPRESS)
    return p.parse_args(argv)


def _child_main(args) -> int:
    kind, n, config, variant = args.child[0], int(args.child[1]), args.child[2], args.child[3]
    try:
        if kind == "build":
            data = child_build(n, config, variant)
        elif kind == "run":
            data = child_run(n, config, variant, args.jac_budget, args.repeat)
        else:
            data = child_profile(n, config, variant, float(args.child[4]))
        data["status"] = "ok"
    except Exception as exc:
        data = {"status": "failed", "message": f"{type(exc).__name__}: "
                f"{str(exc).splitlines()[0][:300] if str(exc) else ''}"}
    Path(args.out).write_text(json.dumps(data, default=float), encoding="utf-8")
    return 0


def _profile(n: int, timeout: float, tol: float) -> dict | None:
    with tempfile.TemporaryDirectory(prefix="casmbd_scaling_") as cache:
        prof = _run_child(["profile", str(n), "abs_al", "O2", str(tol)], Path(cache),
                          timeout, {})
    if prof.get("status") != "ok":
        log(f"profile {prof.get('status')}: {prof.get('message')}")
        return None
    return prof


def main(argv=None) -> int:
    """Run the study (or a child of it)."""
    args = parse(argv)
    if args.child:
        return _child_main(args)
    raw_argv = list(sys.argv[1:] if argv is None else argv)
    if args.render:
        data = json.loads(JSON_PATH.read_text(encoding="utf-8"))
        write_csv(data["rows"], CSV_PATH)
        plot(data["rows"], FIGURE, data.get("timeout", 600.0))
        if args.update_docs:
            from benchmarks.docs import replace_section

            replace_section(DOCS, HEAD, markdown(data))
        return 0
    if args.profile is not None:
        prof = _profile(args.profile, args.timeout, 1e-8)
        print(json.dumps(prof, indent=1, default=float))
        return 0
    sizes = [2, 8, 32] if args.quick else sorted(set(args.sizes))
    variant_sizes = ([] if args.quick else
                     (args.variant_sizes if args.variant_sizes is not None
                      else [n for n in sizes if n >= 300]))
    info = machine_info()
    t_start = time.perf_counter()
    rows: list[dict] = []
    previous_wall = 0.0
    if args.resume and PARTIAL_PATH.exists():
        partial = json.loads(PARTIAL_PATH.read_text(encoding="utf-8"))
        rows = [r for r in partial["rows"]
                if not str(r.get("status", "")).startswith(("skipped", "crashed"))]
        previous_wall = float(partial.get("wall_s", 0.0))
        info = {**partial["info"], "resumed": info["date"] + ", load average "
                + info["load average at start"]}
        log(f"resuming: {len(rows)} cases kept from {PARTIAL_PATH.name}")
    kept: list[dict] = []
    if args.merge and JSON_PATH.exists():
        stored = json.loads(JSON_PATH.read_text(encoding="utf-8"))
        kept = [r for r in stored["rows"] if r["config"] not in args.configs]
        info["kept"] = (f"{len(kept)} rows of configurations {sorted({r['config'] for r in kept})}"
                        f" from the run of {stored['info'].get('date', '?')} (`--merge`)")
    for config in args.configs:
        _series(rows, config, "O2", sizes, args, always=(config in ("abs_al", "joint_aba")))
        _save_partial(rows, info, t_start - previous_wall, args.timeout)
    for config in args.variant_configs:
        for variant in args.variants:
            _series(rows, config, variant, variant_sizes, args, always=False)
            _save_partial(rows, info, t_start - previous_wall, args.timeout)
    rows = kept + rows
    profile = None if args.quick else _profile(32, args.timeout, _profile_tol(rows))
    info["load average at end"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    command = shlex.join(["python", "-m", "benchmarks.scaling",
                          *(a for a in raw_argv if a != "--resume")])
    if args.resume:
        command += "  # interrupted once, continued with --resume (same options)"
    data = {"command": command, "info": info, "rows": rows, "profile": profile,
            "timeout": args.timeout,
            "wall_s": previous_wall + time.perf_counter() - t_start}
    for line in [*table(rows), "", *growth_lines(rows), "", *targets(rows)]:
        print(line)
    if args.quick:
        write_csv(rows, RESULTS / "scaling_quick.csv")
        return 0
    JSON_PATH.parent.mkdir(parents=True, exist_ok=True)
    JSON_PATH.write_text(json.dumps(data, indent=1, default=float), encoding="utf-8")
    write_csv(rows, CSV_PATH)
    plot(rows, FIGURE, args.timeout)
    if args.update_docs:
        from benchmarks.docs import replace_section

        replace_section(DOCS, HEAD, markdown(data))
    return 0


def _skip_reason(rows: list[dict], config: str, variant: str, n: int, timeout: float,
                 always: bool) -> str | None:
    """Why the case (config, variant, n) is not run: an earlier size of the same series timed
    out, or (unless ``always``) the first build extrapolated from the previous size as
    N² (the measured growth of the symbolic build) exceeds the timeout."""
    done = sorted((r for r in rows if r["config"] == config and r["variant"] == variant
                   and r["n"] < n), key=lambda r: r["n"])
    if any(r.get("status") == "timeout" for r in done):
        return "skipped (a smaller N timed out)"
    if always or not done:
        return None
    prev = done[-1]
    if str(prev.get("status", "")).startswith("skipped"):
        return f"skipped (N = {prev['n']} was skipped)"
    total = _num(prev, "build_total_s")
    if math.isfinite(total) and total * (n / prev["n"]) ** 2 > timeout:
        return (f"skipped (first build extrapolated from N = {prev['n']} as N²: "
                f"≈ {total * (n / prev['n']) ** 2:.0f} s > timeout)")
    return None


def _series(rows: list[dict], config: str, variant: str, sizes, args, always: bool) -> None:
    """Run one (config, variant) over the sizes, skipping what cannot finish."""
    for n in sizes:
        if any(r["config"] == config and r["variant"] == variant and r["n"] == n
               for r in rows):
            continue  # measured by the run that --resume continues
        reason = _skip_reason(rows, config, variant, n, args.timeout, always)
        if reason:
            log(f"N={n} {config} {variant}: {reason}")
            rows.append({"config": config, "variant": variant, "n": n, "status": reason})
            continue
        rows.append(run_case(n, config, variant, args.timeout, args.jac_budget, args.repeat))


def _save_partial(rows: list[dict], info: dict, t_start: float, timeout: float) -> None:
    """Keep what has been measured so far (benchmarks/results/scaling_partial.json)."""
    data = {"command": "(partial)", "info": info, "rows": rows, "profile": None,
            "timeout": timeout, "wall_s": time.perf_counter() - t_start}
    path = PARTIAL_PATH
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1, default=float), encoding="utf-8")


def _profile_tol(rows: list[dict]) -> float:
    """The tolerance that reached 1e-6 for N = 32 (default formulation), else 1e-8."""
    r = _get(rows, "abs_al", 32)
    tol = _num(r, "tolerance") if r else math.nan
    return tol if math.isfinite(tol) else 1e-8


if __name__ == "__main__":
    sys.exit(main())
