"""The fair rules of every peer benchmark, in one place (issue 36 item 1).

Every study that puts casmbd beside a peer (MuJoCo, Exudyn, Pinocchio, a hand-written CasADi
baseline) measures both sides with the functions of this module:

1. **Same error, same reference.**  The error measure and the reference are the study's own
   (:mod:`benchmarks.references`, a fine casmbd run checked against a peer, …) and are applied
   to both sides unchanged.
2. **Swept to the level or to a stated floor.**  Each side's sweep (step sizes of a
   fixed-step method, tolerances of an adaptive one) goes on until its error is below the
   finest level of the table or stops falling (:func:`floor_reached`: two successive
   refinements that do not halve the best error so far); the floor is recorded
   (:func:`floor`), so "not reached" in a table means "not reached down to the stated
   floor", never "not tried".  A single run slower than :data:`RUN_CAP` seconds ends a sweep
   too, and the table says so.
3. **Time to error interpolated log-log on every side** (:func:`time_to_error`): along the
   Pareto front of a method's sweep (error against time), between the two points around the
   level.  The best of a side is the smallest such time over its methods
   (:func:`best_time_to_error`).
4. **Timed the same way** (:func:`timed`): the first (cold) run in its own column, then the
   best of ``repeat`` warm runs of the solve alone; set-up (integrator initialisation, model
   assembly) reported separately, never inside the solve.
5. **Each peer at its documented best** settings (see the studies), and **versions recorded**
   in every results file (:func:`versions`) with the load average (:func:`load`).
"""

from __future__ import annotations

import math
import os
import subprocess
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: a warm-up (cold) run longer than this [s] leaves only two warm runs to time
LONG_RUN = 1.0
#: a single run slower than this [s] ends a sweep (stated as the sweep's floor reason)
RUN_CAP = 30.0
#: error levels of the peer tables
LEVELS = (1e-6, 1e-9)

#: the rules as one paragraph for the docs (docs/performance.md, "Fair rules")
RULES = (
    "Every peer table follows `benchmarks/fair.py`: the same error measure against the same "
    "reference on both sides; each side swept until its error is below the finest level or "
    "stops falling (two refinements in a row that do not halve the best error: its *floor*, "
    f"stated), or a single run exceeds a time cap ({RUN_CAP:g} s unless the command says "
    "otherwise: `--cap`); time to an error level interpolated "
    "log-log along each method's Pareto front (error against time) between the sweep points "
    "around the level, on every side; the best of a side is its fastest method at that "
    "level; each run timed as the best of N warm solves (solve only), the set-up reported "
    "separately and the cold first run in its own column; each peer at its documented best "
    "settings; versions and the load average recorded with every results file.")


def load() -> list[float]:
    """The 1-, 5- and 15-minute load averages (recorded with every timing)."""
    return [round(x, 2) for x in os.getloadavg()]


def versions() -> dict[str, str]:
    """Versions of casmbd's stack and of every installed peer (missing peers omitted)."""
    import importlib.metadata as md

    found = {}
    for name in ("casadi", "numpy", "scipy", "mujoco", "exudyn", "pin", "example-robot-data"):
        try:
            found["pinocchio" if name == "pin" else name] = md.version(name)
        except md.PackageNotFoundError:
            continue
    try:
        found["casmbd_commit"] = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
            text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return found


def timed(run: Callable[[], tuple[float, dict]], repeat: int = 3,
          long_run: float = LONG_RUN) -> dict:
    """Time a solve under the fair rule: the cold first run apart, then best of ``repeat``.

    Parameters
    ----------
    run : callable
        One complete run, returning ``(solve_seconds, result)``: the seconds of the solve
        alone (the caller times only the integration, or only the per-call loop) and a dict
        of the run's figures (errors, steps, ``setup_seconds`` of that run, …).
    repeat : int
        Warm runs after the cold one; the reported ``solve_seconds`` is their minimum
        (best-of-N: the least disturbed run on a shared machine).  When the cold run took
        more than ``long_run`` seconds only two warm runs are made.

    Returns
    -------
    dict
        The last run's figures plus ``solve_seconds`` (best warm), ``cold_seconds`` (the
        first run's solve), ``repeats`` (warm runs made) and ``load`` (1-minute load average
        at the end).
    """
    cold, result = run()
    n = max(1, min(repeat, 2) if cold > long_run else repeat)
    warm = []
    for _ in range(n):
        seconds, result = run()
        warm.append(seconds)
    out = dict(result)
    out.update({"solve_seconds": min(warm), "cold_seconds": cold, "repeats": n,
                "load": load()[0]})
    return out


def floor_reached(errors: Sequence[float], target: float = min(LEVELS)) -> bool:
    """True once a sweep (errors coarse to fine) may stop: the last error is at most
    ``target``, or the last two refinements did not halve the best error before them (the
    error has stopped falling: the method's floor)."""
    errs = [e for e in errors if e is not None and math.isfinite(e)]
    if errs and errs[-1] <= target:
        return True
    if len(errs) < 3:
        return False
    best_before = min(errs[:-2])
    return min(errs[-2:]) > 0.5 * best_before


def floor(errors: Iterable[float]) -> float | None:
    """The smallest error a sweep reached (its floor once :func:`floor_reached`)."""
    errs = [e for e in errors if e is not None and math.isfinite(e) and e > 0]
    return min(errs) if errs else None


def sweep(levels: Iterable[float], measure: Callable[[float], dict | None],
          target: float = min(LEVELS), cap: float = RUN_CAP) -> tuple[list[dict], str]:
    """Run ``measure(level)`` over ``levels`` (coarse to fine) until the error reaches
    ``target``, stops falling (:func:`floor_reached`), or a run is slower than ``cap``.

    ``measure`` returns a row with ``error`` and ``solve_seconds`` (or ``None``/a row with
    ``status != "ok"`` for a failed run, which does not stop the sweep).  Returns the rows and
    the reason the sweep stopped (``"reached"``, ``"floor"``, ``"time cap"`` or
    ``"levels exhausted"``).
    """
    rows, errors = [], []
    for level in levels:
        row = measure(level)
        if row is None:
            continue
        rows.append(row)
        if row.get("status", "ok") != "ok":
            continue
        errors.append(float(row["error"]))
        if errors[-1] <= target:
            return rows, "reached"
        if floor_reached(errors, target):
            return rows, "floor"
        if max(float(row.get("solve_seconds", 0.0)), float(row.get("cold_seconds") or 0.0)) \
                > cap:
            return rows, "time cap"
    return rows, "levels exhausted"


def refine(start: float, factor: float = 2.0, smallest: float = 1e-7) -> list[float]:
    """Step sizes ``start, start/factor, …`` down to ``smallest`` (a sweep's finest step;
    :func:`sweep` stops earlier at the level or the floor)."""
    out, h = [], start
    while h >= smallest * (1 - 1e-9):
        out.append(h)
        h /= factor
    return out


def pareto(points: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
    """The (error, seconds) points that no other point beats on both, by increasing time."""
    front: list[tuple[float, float]] = []
    for err, sec in sorted((e, s) for e, s in points if e > 0 and math.isfinite(e)
                           and s > 0 and math.isfinite(s)):
        # sorted by error ascending: keep a point only if it is faster than all more
        # accurate ones kept so far
        if not front or sec < front[-1][1]:
            front.append((err, sec))
    return sorted(front, key=lambda p: p[1])


def time_to_error(points: Iterable[tuple[float, float]], level: float) -> float | None:
    """Seconds one method needs for an error ``level``, interpolated log-log.

    Along the Pareto front (:func:`pareto`) ordered by time, the first point with error ≤
    ``level`` and the point before it bracket the level; between them
    ``log t = log t₀ + (log e₀ − log ε) / (log e₀ − log e₁) · (log t₁ − log t₀)``.  When the
    cheapest point already reaches the level its time is returned (no extrapolation to
    cheaper runs); ``None`` when no point reaches it.
    """
    front = pareto(points)
    for k, (err, sec) in enumerate(front):
        if err <= level:
            if k == 0:
                return sec
            e0, t0 = front[k - 1]
            if err == e0:
                return sec
            w = (math.log(e0) - math.log(level)) / (math.log(e0) - math.log(err))
            return math.exp(math.log(t0) + w * (math.log(sec) - math.log(t0)))
    return None


def best_time_to_error(curves: dict[str, Iterable[tuple[float, float]]],
                       level: float) -> tuple[float, str] | None:
    """The fastest method of one side at ``level``: ``(seconds, method)`` by
    :func:`time_to_error` on each method's points, or ``None`` when none reaches it."""
    best = None
    for name, points in curves.items():
        t = time_to_error(list(points), level)
        if t is not None and (best is None or t < best[0]):
            best = (t, name)
    return best


def time_per_call(call: Callable[[], object], repeat: int = 7,
                  min_seconds: float = 0.05) -> float:
    """Microseconds per call of ``call`` under the fair rule: the first (cold) call made
    apart, then the best of ``repeat`` timeit loops, each of enough calls to last
    ``min_seconds`` (used for casmbd's and the peer's per-call figures alike)."""
    import timeit

    call()
    timer = timeit.Timer(call)
    number = 1
    while True:
        elapsed = timer.timeit(number)
        if elapsed >= min_seconds:
            break
        number = max(2 * number, int(number * min_seconds / max(elapsed, 1e-9) * 1.2))
    return 1e6 * min(timer.repeat(repeat, number)) / number


def best_per_call(fn: Callable, states: Sequence[tuple], repeats: int) -> float:
    """µs per call under the fair rule: three warm-up calls, then the best of ``repeats``
    loops of ``fn(*s)`` over ``states`` (the same loop for casmbd and the peer)."""
    import time

    for s in states[:3]:
        fn(*s)
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for s in states:
            fn(*s)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / len(states)


def best_per_sample(fn: Callable, arrays: Sequence, repeats: int) -> float:
    """µs per sample of a batch call: one warm-up, then the best of ``repeats`` calls of
    ``fn(*arrays)`` over all samples (``len(arrays[0])`` of them)."""
    import time

    fn(*arrays)
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(*arrays)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / len(arrays[0])
