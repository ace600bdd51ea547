"""Cost of the compiled equations of an N-link pendulum chain as N grows.

For every size N of :func:`benchmarks.chains.pendulum_chain` this measures

* **build** — ``System(mechanism)`` plus creating every Function of :data:`FUNCTION_NAMES`;
* **codegen / compile / load** — :func:`casmbd.compiled.codegen.compile_functions` into a fresh
  temporary ``CASMBD_CACHE_DIR`` (so it really compiles), with the library's default flags
  and with each entry of :data:`FLAG_VARIANTS`; then a second call that must load the library
  from the cache without compiling;
* **one library per Function** — every Function compiled into its own library, one after the
  other (which Function dominates the compile time) and on all cores at once;
* **µs per call** of every compiled Function and of the CasADi virtual-machine Function, with
  random numpy inputs, in two ways: ``call`` is the ordinary Python call ``f(q, v, ...)``
  (what :class:`casmbd.compiled.NumericModel` does), ``eval`` goes through
  ``casadi.Function.buffer()`` on the same numpy arrays without conversions, i.e. the cost of
  the evaluation itself;
* the size of the generated C source and the structural non-zeros of M and Cq.

Run ``python -m benchmarks.bench_equations --help`` for the options; ``--update-docs`` rewrites
the section :data:`DOC_SECTION` of ``docs/performance.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import datetime as _dt
import math
import os
import pathlib
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import casadi
import numpy as np

from benchmarks.chains import pendulum_chain
from casmbd.compiled import codegen
from casmbd.compiled.buffered import BufferedFunction
from casmbd.compiled.codegen import compile_functions
from casmbd.system import System

REPO_ROOT = pathlib.Path(__file__).resolve().parent.parent
DEFAULT_CSV = REPO_ROOT / "benchmarks" / "results" / "equations.csv"
DOCS_FILE = REPO_ROOT / "docs" / "performance.md"
DOC_SECTION = "## Compiled equations: build, compile and evaluation cost"

#: Every Function a System can build, in the order they are compiled into one library.
FUNCTION_NAMES: tuple[str, ...] = (
    "mass_matrix",
    "applied_forces",
    "quadratic_velocity_forces",
    "constraints",
    "constraint_jacobian",
    "constraint_time_derivative",
    "acceleration_rhs",
    "kinetic_energy",
    "potential_energy",
    "outputs",
)

#: Label -> flags passed to compile_functions; None is the library default (``-O2``).
FLAG_VARIANTS: dict[str, tuple[str, ...] | None] = {"O2": None, "O1": ("-O1",), "O0": ("-O0",)}
DEFAULT_VARIANT = "O2"
#: Label of the CasADi virtual machine in the timing columns.
VM = "vm"
VARIANTS = (*FLAG_VARIANTS, VM)

#: Columns of the CSV file: one row per (n, function); function "ALL" holds whole-model figures.
CSV_COLUMNS: tuple[str, ...] = (
    "n", "function", "nq", "nc", "n_instructions", "nnz_out", "nnz_M", "nnz_Cq",
    "build_s", "codegen_s", "source_bytes",
    *(f"compile_s_{v}" for v in FLAG_VARIANTS),
    "load_s_cache", "cache_hit_total_s",
    "compile_s_own_lib", "split_serial_wall_s", "split_parallel_wall_s", "single_lib_wall_s",
    *(f"call_us_{v}" for v in VARIANTS),
    *(f"eval_us_{v}" for v in VARIANTS),
)


@dataclass
class FunctionResult:
    """Figures of one Function of one chain."""

    name: str
    n_instructions: int
    nnz_out: int
    compile_s_own_lib: float = math.nan
    call_us: dict[str, float] = field(default_factory=dict)
    eval_us: dict[str, float] = field(default_factory=dict)


@dataclass
class SizeResult:
    """Figures of one chain of ``n`` rods."""

    n: int
    nq: int
    nc: int
    nnz_m: int
    nnz_cq: int
    build_s: float
    codegen_s: float = math.nan
    source_bytes: int = 0
    compile_s: dict[str, float] = field(default_factory=dict)
    load_s_cache: float = math.nan
    cache_hit_total_s: float = math.nan
    single_lib_wall_s: float = math.nan
    split_serial_wall_s: float = math.nan
    split_parallel_wall_s: float = math.nan
    functions: dict[str, FunctionResult] = field(default_factory=dict)

    def total_eval_us(self, variant: str) -> float:
        """Sum over all Functions of the evaluation µs/call of ``variant``."""
        return sum(f.eval_us[variant] for f in self.functions.values())

    def total_call_us(self, variant: str) -> float:
        """Sum over all Functions of the Python-call µs/call of ``variant``."""
        return sum(f.call_us[variant] for f in self.functions.values())


# ---------------------------------------------------------------------------------- helpers
def log(message: str) -> None:
    """Progress message on stderr."""
    print(message, file=sys.stderr, flush=True)


@contextlib.contextmanager
def fresh_cache() -> Iterator[pathlib.Path]:
    """Point ``CASMBD_CACHE_DIR`` to a new empty temporary directory for the duration."""
    old = os.environ.get("CASMBD_CACHE_DIR")
    with tempfile.TemporaryDirectory(prefix="casmbd_bench_") as tmp:
        os.environ["CASMBD_CACHE_DIR"] = tmp
        try:
            yield pathlib.Path(tmp)
        finally:
            if old is None:
                os.environ.pop("CASMBD_CACHE_DIR", None)
            else:
                os.environ["CASMBD_CACHE_DIR"] = old


def random_inputs(function: casadi.Function, rng: np.random.Generator) -> list[np.ndarray]:
    """One dense random float64 numpy vector per input of ``function`` (empty for size 0)."""
    return [rng.standard_normal(function.nnz_in(i)) for i in range(function.n_in())]


def time_per_call(fn: Callable[[], object], repeat: int, min_seconds: float = 0.02) -> float:
    """Median over ``repeat`` timeit runs of the µs per call of ``fn``.

    Each run calls ``fn`` a number of times chosen so that one run lasts at least
    ``min_seconds``.
    """
    timer = timeit.Timer(fn)
    number = 1
    while True:
        elapsed = timer.timeit(number)
        if elapsed >= min_seconds:
            break
        number = max(number * 2, int(number * min_seconds / max(elapsed, 1e-9) * 1.2))
    runs = timer.repeat(repeat, number)
    return 1e6 * statistics.median(runs) / number


def buffer_evaluator(function: casadi.Function, args: list[np.ndarray]) -> tuple:
    """Zero-copy evaluation through ``Function.buffer()`` with the library's own wrapper
    (:class:`~casmbd.compiled.buffered.BufferedFunction`): ``args`` bound to the inputs;
    returns ``(trigger, outputs)``, the trigger keeping the buffer alive."""
    bound = BufferedFunction(function, args)
    bound.evaluate.buffer_owner = bound
    return bound.evaluate, bound.outputs


def nonzeros(result) -> list[np.ndarray]:
    """Non-zeros of every output of a Python Function call (one DM or a list of DMs)."""
    results = result if isinstance(result, (list, tuple)) else [result]
    return [np.asarray(casadi.DM(r).nonzeros(), dtype=float) for r in results]


def time_functions(
    functions: dict[str, casadi.Function],
    inputs: dict[str, list[np.ndarray]],
    reference: dict[str, list[np.ndarray]],
    repeat: int,
) -> tuple[dict[str, float], dict[str, float]]:
    """µs per Python call and per buffer evaluation of every Function; check the values."""
    call_us, eval_us = {}, {}
    for name, function in functions.items():
        args = inputs[name]
        got = nonzeros(function(*args))
        evaluate, outputs = buffer_evaluator(function, args)
        evaluate()
        for ref, a, b in zip(reference[name], got, outputs):
            if not (np.allclose(a, ref, rtol=1e-9, atol=1e-9)
                    and np.allclose(b, ref, rtol=1e-9, atol=1e-9)):
                raise AssertionError(f"{name}: compiled result differs from the virtual machine")
        call_us[name] = time_per_call(lambda f=function, a=args: f(*a), repeat)
        eval_us[name] = time_per_call(evaluate, repeat)
    return call_us, eval_us


def compile_split(
    functions: Sequence[casadi.Function], name: str, workers: int
) -> tuple[float, dict[str, float]]:
    """Compile every Function into its own library with ``workers`` threads.

    Returns the wall time and the compile seconds of each Function (fresh cache).
    """
    def one(function: casadi.Function) -> tuple[str, float]:
        _, report = compile_functions(
            [function], name=f"{name}_{function.name()}", mode="compiled"
        )
        assert report.compiled, "split build unexpectedly hit the cache"
        return function.name(), report.compile_seconds

    with fresh_cache():
        start = time.perf_counter()
        with ThreadPoolExecutor(max_workers=workers) as pool:
            seconds = dict(pool.map(one, functions))
        wall = time.perf_counter() - start
    return wall, seconds


# ---------------------------------------------------------------------------------- benchmark
def _nanmin(old: float, new: float) -> float:
    """``min(old, new)`` where a nan ``old`` means "no value yet"."""
    return new if math.isnan(old) else min(old, new)


def bench_size(n: int, repeat: int, compile_repeat: int = 1, seed: int = 0) -> SizeResult:
    """Measure everything for a chain of ``n`` rods.

    Compile figures are the minimum over ``compile_repeat`` builds, each in a fresh cache;
    timings are medians over ``repeat`` timeit runs.
    """
    mechanism = pendulum_chain(n)
    start = time.perf_counter()
    system = System(mechanism)
    symbolic = {name: system.function(name) for name in FUNCTION_NAMES}
    build_s = time.perf_counter() - start

    result = SizeResult(
        n=n, nq=system.nq, nc=system.nc,
        nnz_m=symbolic["mass_matrix"].nnz_out(0),
        nnz_cq=symbolic["constraint_jacobian"].nnz_out(0),
        build_s=build_s,
    )
    for name, function in symbolic.items():
        result.functions[name] = FunctionResult(
            name, function.n_instructions(), sum(function.nnz_out(i)
                                                 for i in range(function.n_out())))

    rng = np.random.default_rng(seed)
    inputs = {name: random_inputs(f, rng) for name, f in symbolic.items()}
    reference = {name: nonzeros(f(*inputs[name])) for name, f in symbolic.items()}
    functions = list(symbolic.values())
    model_name = f"chain{n}"

    for variant, flags in FLAG_VARIANTS.items():
        for attempt in range(compile_repeat):
            log(f"  N={n}: compiling all functions into one library, -{variant} "
                f"({attempt + 1}/{compile_repeat})")
            with fresh_cache():
                start = time.perf_counter()
                compiled, report = compile_functions(functions, model_name, mode="compiled",
                                                     flags=flags)
                wall = time.perf_counter() - start
                assert report.compiled and not report.cache_hit, "first build must compile"
                _, again = compile_functions(functions, model_name, mode="compiled",
                                             flags=flags)
                assert again.compiled is False, "second build must load from the cache"
                assert again.cache_hit, "second build must be a cache hit"
                result.compile_s[variant] = min(result.compile_s.get(variant, math.inf),
                                                report.compile_seconds)
                if variant == DEFAULT_VARIANT:
                    result.codegen_s = _nanmin(result.codegen_s, report.codegen_seconds)
                    result.load_s_cache = _nanmin(result.load_s_cache, again.load_seconds)
                    result.cache_hit_total_s = _nanmin(
                        result.cache_hit_total_s, again.codegen_seconds + again.load_seconds)
                    result.single_lib_wall_s = _nanmin(result.single_lib_wall_s, wall)
                    source = pathlib.Path(str(report.library)).with_suffix(".c")
                    result.source_bytes = source.stat().st_size
                if attempt == compile_repeat - 1:
                    log(f"  N={n}: timing compiled -{variant}")
                    call_us, eval_us = time_functions(compiled, inputs, reference, repeat)
                    for name in FUNCTION_NAMES:
                        result.functions[name].call_us[variant] = call_us[name]
                        result.functions[name].eval_us[variant] = eval_us[name]

    log(f"  N={n}: timing the virtual machine")
    call_us, eval_us = time_functions(symbolic, inputs, reference, repeat)
    for name in FUNCTION_NAMES:
        result.functions[name].call_us[VM] = call_us[name]
        result.functions[name].eval_us[VM] = eval_us[name]

    workers = os.cpu_count() or 1
    for attempt in range(compile_repeat):
        log(f"  N={n}: one library per function, serial ({attempt + 1}/{compile_repeat})")
        wall, seconds = compile_split(functions, model_name, workers=1)
        result.split_serial_wall_s = _nanmin(result.split_serial_wall_s, wall)
        for name, value in seconds.items():
            f = result.functions[name]
            f.compile_s_own_lib = _nanmin(f.compile_s_own_lib, value)
        log(f"  N={n}: one library per function, {workers} in parallel "
            f"({attempt + 1}/{compile_repeat})")
        wall, _ = compile_split(functions, model_name, workers=workers)
        result.split_parallel_wall_s = _nanmin(result.split_parallel_wall_s, wall)
    return result


# ---------------------------------------------------------------------------------- output
def csv_rows(results: Sequence[SizeResult]) -> list[dict[str, object]]:
    """Rows of the CSV file (see :data:`CSV_COLUMNS`)."""
    rows: list[dict[str, object]] = []
    for r in results:
        base = {"n": r.n, "nq": r.nq, "nc": r.nc}
        whole: dict[str, object] = {
            **base, "function": "ALL",
            "n_instructions": sum(f.n_instructions for f in r.functions.values()),
            "nnz_M": r.nnz_m, "nnz_Cq": r.nnz_cq, "build_s": r.build_s,
            "codegen_s": r.codegen_s, "source_bytes": r.source_bytes,
            "load_s_cache": r.load_s_cache, "cache_hit_total_s": r.cache_hit_total_s,
            "split_serial_wall_s": r.split_serial_wall_s,
            "split_parallel_wall_s": r.split_parallel_wall_s,
            "single_lib_wall_s": r.single_lib_wall_s,
            "compile_s_own_lib": sum(f.compile_s_own_lib for f in r.functions.values()),
        }
        for v in FLAG_VARIANTS:
            whole[f"compile_s_{v}"] = r.compile_s[v]
        for v in VARIANTS:
            whole[f"call_us_{v}"] = r.total_call_us(v)
            whole[f"eval_us_{v}"] = r.total_eval_us(v)
        rows.append(whole)
        for f in r.functions.values():
            row: dict[str, object] = {
                **base, "function": f.name, "n_instructions": f.n_instructions,
                "nnz_out": f.nnz_out, "compile_s_own_lib": f.compile_s_own_lib,
            }
            for v in VARIANTS:
                row[f"call_us_{v}"] = f.call_us[v]
                row[f"eval_us_{v}"] = f.eval_us[v]
            rows.append(row)
    return rows


def write_csv(results: Sequence[SizeResult], path: pathlib.Path) -> None:
    """Write :func:`csv_rows` to ``path`` (parent directories are created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(CSV_COLUMNS), restval="")
        writer.writeheader()
        for row in csv_rows(results):
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v)
                             for k, v in row.items()})


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A GitHub markdown table; the first column is left-aligned, the others right-aligned."""
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join([" --- "] + [" ---: "] * (len(header) - 1)) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _s(value: float) -> str:
    """Seconds, 3 significant digits."""
    return "–" if math.isnan(value) else f"{value:.3g}"


def _us(value: float) -> str:
    """Microseconds: 2 decimals below 10, else 3 significant digits."""
    if math.isnan(value):
        return "–"
    return f"{value:.2f}" if value < 10 else f"{value:.3g}"


def build_table(results: Sequence[SizeResult]) -> str:
    """Whole-model table: sizes, build, codegen, compile (per flags), cache load, split."""
    header = ["N", "nq", "nc", "nnz M", "nnz Cq", "C source (bytes)", "build (s)",
              "codegen (s)", *(f"compile -{v} (s)" for v in FLAG_VARIANTS),
              "cache load (s)", "cache hit total (s)", "1 lib wall (s)",
              "per-fn libs serial (s)", f"per-fn libs ×{os.cpu_count() or 1} (s)"]
    rows = [[r.n, r.nq, r.nc, r.nnz_m, r.nnz_cq, r.source_bytes, _s(r.build_s), _s(r.codegen_s),
             *(_s(r.compile_s[v]) for v in FLAG_VARIANTS), _s(r.load_s_cache),
             _s(r.cache_hit_total_s), _s(r.single_lib_wall_s), _s(r.split_serial_wall_s),
             _s(r.split_parallel_wall_s)] for r in results]
    return markdown_table(header, rows)


def timing_table(results: Sequence[SizeResult]) -> str:
    """Per-function table: instructions, own-library compile time, µs per call and per eval."""
    header = ["function", "N", "SX instr.", "own lib compile (s)",
              *(f"call {v}" for v in (DEFAULT_VARIANT, VM)),
              *(f"eval {v}" for v in VARIANTS)]
    rows = []
    for name in FUNCTION_NAMES:
        for r in results:
            f = r.functions[name]
            rows.append([name, r.n, f.n_instructions, _s(f.compile_s_own_lib),
                         *(_us(f.call_us[v]) for v in (DEFAULT_VARIANT, VM)),
                         *(_us(f.eval_us[v]) for v in VARIANTS)])
    for r in results:
        rows.append(["**all 10**", r.n, sum(f.n_instructions for f in r.functions.values()),
                     _s(sum(f.compile_s_own_lib for f in r.functions.values())),
                     *(_us(r.total_call_us(v)) for v in (DEFAULT_VARIANT, VM)),
                     *(_us(r.total_eval_us(v)) for v in VARIANTS)])
    return markdown_table(header, rows)


def growth_exponent(xs: Sequence[float], ys: Sequence[float]) -> float:
    """Exponent k of y ∝ N^k between the last two points (nan if not computable)."""
    if len(xs) < 2 or ys[-1] <= 0 or ys[-2] <= 0 or xs[-1] == xs[-2]:
        return math.nan
    return math.log(ys[-1] / ys[-2]) / math.log(xs[-1] / xs[-2])


def print_tables(results: Sequence[SizeResult]) -> None:
    """Print both tables to stdout."""
    print("\nWhole model (all 10 functions in one library unless stated)\n")
    print(build_table(results))
    print("\nPer function: µs per call (Python call with numpy arrays) and per evaluation "
          "(Function.buffer, no conversion)\n")
    print(timing_table(results))
    print()
    for line in growth_lines(results):
        print(line)


def growth_lines(results: Sequence[SizeResult]) -> list[str]:
    """Bullet points with the growth exponents between the two largest sizes."""
    if len(results) < 2:
        return ["- (growth rates need at least two sizes)"]
    ns = [r.n for r in results]
    a, b = results[-2], results[-1]

    def k(values: Sequence[float]) -> str:
        return f"{growth_exponent(ns, values):.2f}"

    lines = [
        f"- Growth exponents k (quantity ∝ N^k) between N = {a.n} and N = {b.n}:",
        f"  C source {k([r.source_bytes for r in results])}, "
        f"build {k([r.build_s for r in results])}, "
        f"codegen {k([r.codegen_s for r in results])}, "
        + ", ".join(f"compile -{v} {k([r.compile_s[v] for r in results])}"
                    for v in FLAG_VARIANTS) + ".",
        f"  Evaluation of all functions (eval, -{DEFAULT_VARIANT}) "
        f"{k([r.total_eval_us(DEFAULT_VARIANT) for r in results])}, "
        f"VM {k([r.total_eval_us(VM) for r in results])}; Python call of all functions "
        f"(-{DEFAULT_VARIANT}) {k([r.total_call_us(DEFAULT_VARIANT) for r in results])}.",
    ]
    return lines


# ---------------------------------------------------------------------------------- docs
def machine_info() -> dict[str, str]:
    """CPU model, cores, Python, CasADi, NumPy and C compiler versions, date."""
    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    compiler = shlex.split(os.environ.get("CC", "").strip() or "cc")
    try:
        out = subprocess.run([*compiler, "--version"], capture_output=True, text=True,
                             check=False, timeout=30).stdout
        cc_version = out.splitlines()[0] if out else "unknown"
    except (OSError, subprocess.TimeoutExpired):
        cc_version = "not found"
    return {
        "CPU": cpu,
        "cores": str(os.cpu_count()),
        "OS": f"{platform.system()} {platform.release()} {platform.machine()}",
        "Python": platform.python_version(),
        "CasADi": casadi.__version__,
        "NumPy": np.__version__,
        "C compiler": f"`{shlex.join(compiler)}`: {cc_version}",
        "default flags": " ".join(codegen.DEFAULT_FLAGS),
        "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "load average at start": " ".join(f"{x:.2f}" for x in os.getloadavg()),
    }


def analysis_lines(results: Sequence[SizeResult]) -> list[str]:
    """Findings computed from the measurements (largest N), as markdown paragraphs."""
    big = results[-1]
    lines: list[str] = []
    own = sorted(big.functions.values(), key=lambda f: f.compile_s_own_lib, reverse=True)
    own_total = sum(f.compile_s_own_lib for f in own)
    top = ", ".join(f"`{f.name}` {f.compile_s_own_lib:.2f} s "
                    f"({100 * f.compile_s_own_lib / own_total:.0f} %)" for f in own[:4])
    o2, o1, o0 = (big.compile_s[v] for v in ("O2", "O1", "O0"))
    e2, e1, e0 = (big.total_eval_us(v) for v in ("O2", "O1", "O0"))
    c2, c0, cvm = (big.total_call_us(v) for v in ("O2", "O0", VM))
    evm = big.total_eval_us(VM)
    ct = big.functions["constraint_time_derivative"]
    share = [f.compile_s_own_lib / own_total for f in own]
    if share[0] > 0.5:
        verdict = f"`{own[0].name}` dominates."
    else:
        verdict = (f"No single function dominates: the top three make "
                   f"{100 * sum(share[:3]):.0f} % and the time follows the length of each "
                   "function's straight-line code (`SX instr.` column).")
    mm = big.functions["mass_matrix"]
    serial, single = big.split_serial_wall_s, big.single_lib_wall_s
    parallel_gain = single / big.split_parallel_wall_s
    if serial > 1.15 * single:
        split_verdict = "Separate libraries cost more in total (one compiler run per library)"
    elif serial < 0.85 * single:
        split_verdict = "Separate libraries are cheaper even one after the other"
    else:
        split_verdict = "The compiler's time is about additive over functions"
    if parallel_gain > 1.1:
        split_verdict += f"; compiled on all cores they finish {parallel_gain:.2f}× sooner"
    else:
        split_verdict += "; compiled on all cores they do not finish sooner"
    lines += [
        f"**Which function dominates compile time (N = {big.n}, each in its own library, "
        f"-O2).** {top}; total {own_total:.2f} s. {verdict} The constant `mass_matrix` "
        f"({mm.nnz_out} stores of three constants) takes {mm.compile_s_own_lib:.2f} s.",
        "",
        f"**Compiler flags (N = {big.n}, whole library).** compile -O2 {o2:.2f} s, "
        f"-O1 {o1:.2f} s, -O0 {o0:.2f} s; evaluating all 10 functions once costs "
        f"{e2:.1f} µs (-O2), {e1:.1f} µs (-O1), {e0:.1f} µs (-O0) and {evm:.1f} µs in the "
        f"virtual machine, so -O0 compiles {o2 / o0:.1f}× faster than -O2 and evaluates "
        f"{e0 / e2:.1f}× slower. Through the ordinary Python call with numpy arrays the "
        f"same 10 calls cost {c2:.0f} µs (-O2), {c0:.0f} µs (-O0) and {cvm:.0f} µs (VM): "
        f"the empty `constraint_time_derivative` alone costs {ct.call_us['O2']:.1f} µs per "
        f"call against {ct.eval_us['O2']:.2f} µs through a buffer, so the optimisation "
        "level is invisible behind the call overhead.",
        "",
        f"**One library or one per function (N = {big.n}, -O2).** One library: "
        f"{single:.2f} s wall (codegen + compile + load); one library per function, one "
        f"after the other: {serial:.2f} s; the same on {os.cpu_count()} cores: "
        f"{big.split_parallel_wall_s:.2f} s. {split_verdict}.",
    ]
    return lines


FINDINGS = """\
**Findings of the profiling** (one-off investigation with `gcc -ftime-report` and scratch
copies of the library, gcc 12.2, on the machine above; not re-measured by the command).

* *Compile time is super-linear in N although the source grows linearly.* CasADi writes each
  Function as one straight-line C function in which every output store is
  `if (res[0]!=0) res[0][k]=…;` and every input load `a=arg[0]? arg[0][k] : 0;`: one basic
  block and one reload of `res[0]`/`arg[0]` per non-zero. At -O2 the time goes to *alias
  stmt walking* (each reload is checked against all earlier stores) and *tree SLP
  vectorization* (≈ 20 % and 16 % of the N = 128 library), both quadratic in the length of
  a function. In a library of its own, `constraint_jacobian` compiles in 0.56 s, 1.83 s,
  6.97 s and the constant `mass_matrix` in 0.50 s, 1.53 s, 4.78 s for N = 64, 128, 256; the
  whole library at N = 256 takes 22.6 s at -O2 and 3.9 s at -O0 (N^1.6 for -O2 between 128
  and 256). `-fno-tree-slp-vectorize` saves only ≈ 3 %.
* *-O1 is not a safe cheaper default*: for `outputs` (12 outputs, so 12 `res[i]` pointers)
  gcc -O1 spends its time in *tree SSA incremental*: 17.4 s at N = 256 against 4.9 s at -O2.
  Loading `arg[i]`/`res[i]` once into local pointers at the top of each generated function
  (a text transformation of the generated source) removes that case (5.5 s) and cuts the
  N = 128 library at -O1 from 6.2 s to 3.6 s, with unchanged evaluation times; it does not
  help -O2.
* *The mass matrix has 9 N structural non-zeros instead of 3 N*: `System.mass_matrix`
  (`casmbd/system/equations.py`) adds the dense `DM` outer product e_θ e_θᵀ, which turns
  every 3×3 block dense with 6 explicit zeros. With
  `e_theta = ca.DM(ca.Sparsity.triplet(3, 1, [2], [0]), 1.0)` M has 384 non-zeros at
  N = 128 (same values), its own-library compile time drops from 1.71 s to 0.28 s and its
  evaluation from 0.25 µs to 0.13 µs.
* *The Python call dominates evaluation.* Converting a numpy argument to a CasADi `DM` costs
  ≈ 20 µs plus ≈ 0.2 µs per element and a `Function` call with `DM` arguments ≈ 12 µs,
  whereas `casadi.Function.buffer()` evaluates on the numpy arrays directly.
  `NumericModel` (`casmbd/compiled/model.py`) calls `f(q, t, self.p)` with numpy arrays for
  every evaluation; evaluating through a cached buffer with preallocated inputs (copy in,
  evaluate, copy the output) made `NumericModel.constraints` 54 → 2.0 µs (N = 2) and
  105 → 5.0 µs (N = 128) and `acceleration_rhs` 70 → 2.4 µs and 151 → 4.7 µs; with the CSC
  index arrays of the pattern also cached (instead of `sparsity.row()`/`colind()` per call)
  `constraint_jacobian` went 107 → 20 µs and 295 → 28 µs (the rest is `scipy.sparse`).
"""


def recommendation_lines(results: Sequence[SizeResult]) -> list[str]:
    """Recommendations, with the figures of the largest N filled in."""
    big = results[-1]
    o2, o1, o0 = big.compile_s["O2"], big.compile_s["O1"], big.compile_s["O0"]
    e2, e0 = big.total_eval_us("O2"), big.total_eval_us("O0")
    ct = big.functions["constraint_time_derivative"]
    overhead = ct.call_us["O2"] - ct.eval_us["O2"]
    own_total = sum(f.compile_s_own_lib for f in big.functions.values())
    mm_share = big.functions["mass_matrix"].compile_s_own_lib / own_total
    return [
        "**Recommendations.**",
        "",
        f"1. Keep `-O2` as the default: at N = {big.n} it compiles in {o2:.1f} s and evaluates "
        f"{e0 / e2:.1f}× faster than -O0. -O1 ({o1:.1f} s here) is not a safe cheaper "
        "default because of the pathological `outputs` case above (3.5× slower than -O2 at "
        "N = 256). Document `CASMBD_CFLAGS=-O0` (or "
        f'`flags=("-O0",)`) for very large models and interactive iteration: {o2 / o0:.1f}× '
        "faster to compile, still faster than the virtual machine.",
        "2. Evaluate compiled Functions in `NumericModel` through `Function.buffer()` with "
        "preallocated numpy arrays and cached CSC index arrays: the Python call costs "
        f"≈ {overhead:.0f} µs more than the evaluation of an empty function, while -O2 "
        f"instead of -O0 saves {e0 - e2:.1f} µs for all 10 functions together at "
        f"N = {big.n}.",
        "3. Build the mass matrix with a structurally sparse e_θ (3 N non-zeros instead of "
        f"9 N): `mass_matrix` takes {100 * mm_share:.0f} % of the -O2 compile time at "
        f"N = {big.n} (own-library figures) and most of it goes to the explicit zeros.",
        "4. To cut the compile wall time, write one translation unit per Function and compile "
        "them in parallel (`cc -c` each, largest first, then one `cc -shared` link): one "
        "library and one cache entry, and every core is used. Tried in a scratch script at "
        "N = 128 on the 2 cores above: 6.9–7.6 s for the single source against 4.0 s "
        "including the link, same values.",
    ]


def render_section(results: Sequence[SizeResult], command: str, info: dict[str, str]) -> str:
    """The markdown section written by ``--update-docs`` (ends with a newline)."""
    parts = [
        DOC_SECTION,
        "",
        "Generated by `benchmarks/bench_equations.py`; do not edit by hand, re-run:",
        "",
        "```",
        command,
        "```",
        "",
        "Model: `benchmarks.chains.pendulum_chain(N)`, N slender rods pinned end to end "
        "(nq = 3N, nc = 2N). All 10 Functions of `System` (mass_matrix, applied_forces, "
        "quadratic_velocity_forces, constraints, constraint_jacobian, "
        "constraint_time_derivative, acceleration_rhs, kinetic_energy, potential_energy, "
        "outputs) are compiled by `casmbd.compiled.codegen.compile_functions` into one library "
        "in a fresh temporary `CASMBD_CACHE_DIR`; a second call loads it from the cache "
        "(checked: `report.compiled is False`).",
        "",
        "Machine (a load average above 0 means other processes shared the cores during "
        "the run; compile figures are the minimum over `--compile-repeat` fresh builds):",
        "",
        *(f"- {k}: {v}" for k, v in info.items()),
        "",
        "### Build, code generation and compilation",
        "",
        "*build*: `System(mech)` and the 10 Functions; *codegen*: C generation and hashing; "
        "*compile -Ox*: the C compiler only (`-O2` is the library default); *cache load*: "
        "`casadi.external` of the cached library; *cache hit total*: codegen + load of the "
        "second call (a cache hit still generates the code to compute its key); *1 lib wall*: "
        "the whole first `compile_functions` call; *per-fn libs*: every Function in its own "
        "library (fresh cache), one after the other and on all cores.",
        "",
        build_table(results),
        "",
        "### Evaluation cost per function",
        "",
        "µs per call, median of the `--repeat` timeit runs, random numpy inputs. *call*: "
        "`f(q, v, …)` from Python with numpy arrays (what `NumericModel` does); *eval*: the "
        "same Function evaluated through `casadi.Function.buffer()` on the same numpy arrays, "
        "without argument conversion (≈ the cost of the code itself); *vm*: the symbolic "
        "Function in CasADi's virtual machine. *own lib compile*: -O2 compile seconds of the "
        "function in a library of its own.",
        "",
        timing_table(results),
        "",
        "### Growth, trade-offs and structure",
        "",
        *growth_lines(results),
        "",
        *analysis_lines(results),
        "",
        FINDINGS,
        *recommendation_lines(results),
    ]
    return "\n".join(parts).rstrip("\n") + "\n"


def update_docs(path: pathlib.Path, section: str) -> None:
    """Replace (or append) the :data:`DOC_SECTION` section of ``path``, creating the file."""
    if path.exists():
        text = path.read_text(encoding="utf-8")
    else:
        text = "# Performance\n\nMeasured costs of casmbd; each section names its command.\n"
    lines = text.splitlines(keepends=True)
    start = next((i for i, line in enumerate(lines) if line.rstrip() == DOC_SECTION), None)
    if start is None:
        new = text.rstrip("\n") + "\n\n" + section
    else:
        end = next((i for i in range(start + 1, len(lines))
                    if lines[i].startswith("## ")), len(lines))
        tail = "".join(lines[end:])
        new = "".join(lines[:start]) + section + ("\n" + tail if tail else "")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(new, encoding="utf-8")


# ---------------------------------------------------------------------------------- main
def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.bench_equations",
        description="Build, code generation, compile and evaluation cost of the equations "
                    "of an N-link pendulum chain.")
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 8, 32, 128],
                        help="chain sizes N (default: 2 8 32 128)")
    parser.add_argument("--repeat", type=int, default=7,
                        help="timeit runs per timing; the median is reported (default 7)")
    parser.add_argument("--compile-repeat", type=int, default=1,
                        help="fresh builds per compile figure; the minimum is reported "
                             "(default 1; use more on a busy machine)")
    parser.add_argument("--csv", type=pathlib.Path, default=DEFAULT_CSV,
                        help=f"CSV output (default {DEFAULT_CSV.relative_to(REPO_ROOT)})")
    parser.add_argument("--update-docs", action="store_true",
                        help=f"rewrite the section '{DOC_SECTION[3:]}' of docs/performance.md")
    args = parser.parse_args(argv)
    if any(n < 1 for n in args.sizes):
        parser.error("sizes must be positive")
    if args.repeat < 1 or args.compile_repeat < 1:
        parser.error("--repeat and --compile-repeat must be at least 1")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark; return the exit status."""
    args = parse_args(argv)
    argv = list(sys.argv[1:] if argv is None else argv)
    command = shlex.join(["python", "-m", "benchmarks.bench_equations", *argv])
    info = machine_info()
    if os.environ.pop("CASMBD_CFLAGS", None) is not None:
        log("note: ignoring $CASMBD_CFLAGS to measure the library default flags")
    sizes = sorted(set(args.sizes))
    results = []
    for n in sizes:
        log(f"N = {n}")
        results.append(bench_size(n, args.repeat, args.compile_repeat))
    info["load average at end"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print_tables(results)
    write_csv(results, args.csv)
    log(f"wrote {args.csv}")
    if args.update_docs:
        update_docs(DOCS_FILE, render_section(results, command, info))
        log(f"updated {DOCS_FILE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
