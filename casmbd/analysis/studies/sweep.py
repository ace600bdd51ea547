"""Parameter sweeps: one analysis of one mechanism at many values of its named parameters.

The scene's ``[parameters]`` are the runtime inputs p of every compiled Function
(:attr:`casmbd.compiled.model.NumericModel.p`), so a sweep builds the compiled library once —
in the calling process, which leaves the disk cache (``$CASMBD_CACHE_DIR``) warm — and every
worker only loads it from the cache, then sets p point by point: no code generation changes
and no compiler run per point.  ``SweepResult.stats`` reports this from the workers' own build
reports (``worker_compiler_runs``, ``worker_cache_hits``).

Workers receive the scene text and a dictionary of parameter values, never CasADi objects, so
the same point function runs serially, on local processes (``concurrent.futures`` with the
``spawn`` start method) or on a Dask cluster (``dask.distributed``, optional extra
``casmbd[sweep]``).  Every point is checked first by loading the scene with its values
(``mass = "m"`` with m ≤ 0 is a :class:`~casmbd.errors.SceneError`); a point that fails — in
the scene, the assembly or the integrator — is recorded with its message and the others are
kept (and saved, ``out_dir/point_XXX.npz``).

A scene with impact contacts, joint stops or stick-slip friction runs every point through
:func:`~casmbd.analysis.dynamics.simulate.simulate` itself (the event-driven run, its phase
simulators
kept per process in a :class:`~casmbd.analysis.dynamics.simulate.Simulators`), and a statics sweep
of such a scene through :func:`~casmbd.analysis.statics.statics.static_equilibrium` of the mechanism
(the active set of closed gaps): a point is what the verb gives at that value.

Parameters that fix *load-time* numbers of the scene (positions, points, axes, initial
velocities are evaluated when the scene is read, ``docs/scene-format.md``) cannot change at run
time; a sweep over one of them is refused with an :class:`~casmbd.errors.AnalysisError` naming
it.  Numbers of the method chosen at build time from the default values (the augmented
Lagrangian's penalty, the redundancy plan) are kept for every point.
"""

from __future__ import annotations

import copy
import hashlib
import math
import os
import pickle
import socket
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from casmbd import interrupts
from casmbd.analysis.studies.sweep_analyses import statics_as_result
from casmbd.analysis.studies.sweep_registry import SWEEPABLE, Engine, Sweepable, sweepable
from casmbd.analysis.studies.sweep_result import SweepResult, load_sweep, structured_table
from casmbd.analysis.studies.sweep_values import (
    REDUCTIONS,
    check_output_names,
    check_outputs,
    evaluate_outputs,
    parse_values,
    sweep_points,
)
from casmbd.compiled import codegen
from casmbd.errors import (
    AnalysisError,
    CasmbdError,
    ModelError,
)
from casmbd.limits import check_steps
from casmbd.model import Mechanism
from casmbd.model.needs import check
from casmbd.results import Result

__all__ = ["REDUCTIONS", "SWEEPABLE", "SweepResult", "load_sweep", "parse_values",
           "statics_as_result", "sweep"]


# ====================================================================== the worker side
class _Runner:
    """One analysis of one mechanism, built once per process and run at many p (its
    :class:`~casmbd.analysis.studies.sweep_registry.Sweepable`, ``spec["sweepable"]``)."""

    def __init__(self, spec: dict, mechanism=None):
        before = codegen.COMPILE_COUNT
        t0 = time.perf_counter()
        if mechanism is not None:  # a mechanism that cannot be pickled (serial sweeps)
            mech = copy.copy(mechanism)
            mech.parameters = dict(mechanism.parameters)  # the caller's values stay
        elif spec["scenes"] is not None:  # the scene's reader (casmbd.io) rebuilds it
            mech = spec["scenes"].mechanism()
        else:
            mech = pickle.loads(spec["mechanism"])
        self.mechanism = mech
        self.names = list(mech.parameters)
        self.defaults = dict(mech.parameters)
        self.analysis = spec["analysis"]
        self.kind: Sweepable = spec["sweepable"]
        opts = spec["options"]
        build = {k: opts[k] for k in self.kind.build_options if k in opts}
        self.run_options = {k: opts[k] for k in self.kind.run_options if k in opts}
        self.engine: Engine = self.kind.build(mech, spec["mode"], **build)
        self.model = self.engine.model
        report = self.model.report_dict if self.model is not None else {
            "compiled": False, "cache_hit": False, "mode": "nothing compiled"}
        self.report = {k: v for k, v in report.items()
                       if k in ("compiled", "cache_hit", "mode")}
        self.report["compiler_runs"] = codegen.COMPILE_COUNT - before
        self.report["build_seconds"] = time.perf_counter() - t0

    def run(self, values: Mapping[str, float], t_end, steps) -> Result:
        p = {**self.defaults, **values}
        # the runtime inputs of every Function: NumericModel.p is the one source of truth
        # (initial velocities in joint coordinates are evaluated at it too)
        if self.model is not None:
            self.model.p[:] = [p[n] for n in self.names]
        return self.kind.run(self.engine, p, t_end, steps, **self.run_options)


#: most runners (compiled engines) kept per process
MAX_RUNNERS = 4
#: runners of this process by spec key (a worker builds its runner at its first point)
_RUNNERS: dict[str, _Runner] = {}


def _runner(spec: dict) -> tuple[_Runner, bool]:
    key = spec["key"]
    if key in _RUNNERS:
        return _RUNNERS[key], False
    runner = _Runner(spec)
    while len(_RUNNERS) >= MAX_RUNNERS:  # oldest first
        _RUNNERS.pop(next(iter(_RUNNERS)))
    _RUNNERS[key] = runner
    return runner, True


def _evaluate(spec: dict, index: int, values: dict[str, float], scene: str | None) -> dict:
    """Run one point; never raises (a failure is recorded with its message)."""
    t0 = time.perf_counter()
    before = codegen.COMPILE_COUNT
    rec = {"index": index, "status": "ok", "error": "", "outputs": {}, "file": None,
           "worker": f"{socket.gethostname()}:{os.getpid()}", "runner_built": False}
    try:
        runner, built = _runner(spec)
        rec.update(runner_built=built, build=dict(runner.report))
        try:
            result = runner.run(values, spec["t_end"], spec["steps"])
        except CasmbdError as exc:
            interrupts.reraise_interrupt(exc)
            partial = getattr(exc, "partial", None)
            if partial is not None and spec["out_dir"]:
                _save_point(partial, spec, index, values, scene, failure=str(exc))
            raise
        rec["outputs"] = evaluate_outputs(spec["outputs"], result, spec["sweepable"])
        if spec["out_dir"]:
            rec["file"] = _save_point(result, spec, index, values, scene)
        rec["solve_seconds"] = float(result.stats.get("solve_seconds", math.nan))
    except Exception as exc:  # recorded, the other points go on
        interrupts.reraise_interrupt(exc)
        rec["status"] = "failed"
        kind = type(exc).__name__
        rec["error"] = f"{kind}: {exc}" if isinstance(exc, CasmbdError) else \
            f"internal error ({kind}): {exc}"
    rec["compiler_runs"] = codegen.COMPILE_COUNT - before
    rec["seconds"] = time.perf_counter() - t0
    return rec


def _point_name(spec: dict, index: int) -> str:
    return f"point_{index:0{spec['digits']}d}"


def _save_point(result: Result, spec: dict, index: int, values, scene, failure=None) -> str:
    result.stats["sweep_index"] = index
    result.stats["sweep_point"] = dict(values)
    if failure:
        result.stats["failure"] = failure
    if scene is not None:
        result.scene = scene
    suffix = "_partial.npz" if failure else ".npz"
    path = Path(spec["out_dir"]) / (_point_name(spec, index) + suffix)
    result.save(path)
    return str(path)


# ====================================================================== executors
def _progress(total: int, enabled: bool | None):
    """A tqdm bar on a terminal's stderr (tqdm optional), else None."""
    if enabled is False or (enabled is None and not sys.stderr.isatty()):
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc="sweep", unit="point", file=sys.stderr)


def _run_serial(spec, tasks, bar) -> list[dict]:
    out = []
    for task in tasks:
        out.append(_evaluate(spec, *task))
        if bar is not None:
            bar.update(1)
    return out


def _run_processes(spec, tasks, workers: int, bar) -> list[dict]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    out = []
    ctx = multiprocessing.get_context("spawn")  # no CasADi state forked into the workers
    # Ctrl-C: the workers ignore it; the parent cancels the points and ends the workers
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                             initializer=interrupts.ignore_sigint) as pool:
        try:
            with interrupts.sigint_blocked():  # the workers start here
                futures = {pool.submit(_evaluate, spec, *task): task for task in tasks}
            for fut in as_completed(futures):
                try:
                    out.append(fut.result())
                except Exception as exc:  # a worker died (e.g. killed): record, keep others
                    index = futures[fut][0]
                    out.append({"index": index, "status": "failed", "outputs": {},
                                "file": None, "error": f"worker process failed "
                                f"({type(exc).__name__}): {exc}", "worker": "?",
                                "runner_built": False})
                if bar is not None:
                    bar.update(1)
        except KeyboardInterrupt:
            interrupts.stop_process_pool(pool)
            _remove_partial_files(spec)
            raise
    return out


def _remove_partial_files(spec: dict) -> None:
    """The temporary files of point results a terminated worker was writing."""
    if spec["out_dir"]:
        for tmp in Path(spec["out_dir"]).glob(".tmp_*.npz"):
            tmp.unlink(missing_ok=True)


def _require_dask(executor) -> None:
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise AnalysisError(f"executor {executor!r} is a Dask scheduler address but "
                            "dask.distributed is not installed (pip install 'casmbd[sweep]' or "
                            "pip install \"dask[distributed]\")") from None


def _dask_client(executor):
    """(client, owned) for a scheduler address or an existing ``distributed.Client``."""
    if not isinstance(executor, str):
        return executor, False
    _require_dask(executor)
    from distributed import Client

    try:
        return Client(executor, timeout="20s"), True
    except (OSError, TimeoutError) as exc:
        raise AnalysisError(f"cannot connect to the Dask scheduler {executor!r}: {exc}") \
            from None


def _run_dask(spec, tasks, executor, bar) -> list[dict]:
    from distributed import as_completed

    client, owned = _dask_client(executor)
    futures: dict = {}
    try:
        spec["_dask_workers"] = len(client.scheduler_info().get("workers", {}))
        spec_future = client.scatter(spec, broadcast=True)
        futures = {client.submit(_evaluate, spec_future, *task, pure=False,
                                 key=f"casmbd-sweep-{spec['key'][:12]}-{task[0]}-"
                                     f"{time.time_ns()}"): task for task in tasks}
        out = []
        for fut in as_completed(list(futures)):
            try:
                out.append(fut.result())
            except Exception as exc:  # a worker died: record, keep the others
                index = futures[fut][0]
                out.append({"index": index, "status": "failed", "outputs": {}, "file": None,
                            "error": f"Dask task failed ({type(exc).__name__}): {exc}",
                            "worker": "?", "runner_built": False})
            if bar is not None:
                bar.update(1)
        return out
    except KeyboardInterrupt:  # the points not finished are cancelled on the cluster
        if futures:
            client.cancel(list(futures))
        raise
    finally:
        if owned:
            client.close()


# ====================================================================== entry point
def sweep(mechanism, params: Mapping[str, Iterable[float]] | None = None, *,
          points: Sequence[Mapping[str, float]] | None = None, analysis: str = "simulate",
          t_end: float | None = None, steps: int | None = None,
          outputs: Sequence[str] | Callable[[Result], Mapping[str, float]] | None = None,
          executor="serial", workers: int | None = None,
          out_dir: str | os.PathLike | None = None, mode: str = "auto",
          progress: bool | None = None, **options) -> SweepResult:
    """Run one analysis at every point of a parameter grid or list.

    Parameters
    ----------
    mechanism : Mechanism
        One read from a scene file (:func:`casmbd.load_scene`) carries its scene: every point's
        scene is checked and saved with the point's values; one built in Python is pickled to
        the worker processes.  Reading files is the caller's job (the CLI reads the scene).
    params : mapping name -> values, optional
        Grid product of the values (the first name varies slowest).
    points : sequence of mappings name -> value, optional
        The points themselves (instead of ``params``).
    analysis : str
        A verb of :data:`~casmbd.analysis.studies.sweep_registry.SWEEPABLE`: "simulate",
        "kinematics", "inverse", "statics" or one registered from user code.
    t_end, steps : float, int
        Output grid of the time-domain analyses (``steps + 1`` times).
    outputs : list of str or callable, optional
        Named scalar outputs ``"REDUCTION:COLUMN"`` — REDUCTION one of :data:`REDUCTIONS`,
        COLUMN a CSV column label of the result (``q[block.x]``, ``total_energy``,
        ``joint_positions[slide]``) or ``body.NAME.FIELD[.AXIS]`` / ``joint.NAME.FIELD`` /
        ``marker.NAME.FIELD.AXIS`` — and ``"energy_drift"`` (E(t_end) − E(0)),
        ``"max_constraint_violation"``; or a callable ``Result -> {name: number}`` (a
        module-level function for process and Dask executors).  Default: the final q, the
        largest constraint violation and, for simulations, the energy drift.
    executor : "serial", "processes", a Dask scheduler address or a ``distributed.Client``
    workers : int, optional
        Processes of the ``"processes"`` executor (default ``os.cpu_count()``).
    out_dir : str or PathLike, optional
        Folder for ``point_XXX.npz`` (each point's :class:`Result`, its scene with the point's
        parameter values embedded; a failed simulation's partial results as
        ``point_XXX_partial.npz``), ``sweep.csv`` and ``sweep.npz``.
    mode : {"auto", "compiled", "vm"}
        Compilation mode (:class:`~casmbd.compiled.model.NumericModel`).
    progress : bool, optional
        A tqdm bar (if tqdm is installed); default: when stderr is a terminal.
    **options
        Options of the analysis: ``formulation``, ``integrator``, ``rtol``, ``atol``,
        ``inputs``, ``projection``, ``step``, ``max_steps``, ``redundancy``,
        ``formulation_options``, ``t_start`` (simulate); ``t_start`` (kinematics, inverse);
        ``t``, ``method``, ``tol``, ``max_iter``, ``stable`` (statics).

    Returns
    -------
    SweepResult

    Raises
    ------
    ModelError
        An unknown parameter name (the message names it and the known ones).
    AnalysisError
        Bad options, a parameter that fixes load-time numbers of the scene, a missing
        dask.distributed for a scheduler address.
    """
    t_wall = time.perf_counter()
    kind = sweepable(analysis)  # an unknown analysis: AnalysisError naming the known ones
    check(mechanism, kind.handling(options))
    allowed = set(kind.build_options) | set(kind.run_options)
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise AnalysisError(f"sweep: option(s) {', '.join(unknown)} do not apply to "
                            f"{analysis} (allowed: {', '.join(sorted(allowed)) or 'none'})")
    if kind.time_grid:
        if t_end is None or steps is None:
            raise AnalysisError(f"sweep: the {analysis} analysis needs t_end and steps")
        if not (isinstance(steps, (int, np.integer)) and steps >= 1):
            raise AnalysisError(f"sweep: steps must be an integer >= 1, got {steps!r}")
        if not (math.isfinite(t_end) and t_end > options.get("t_start", 0.0)):
            raise AnalysisError(f"sweep: t_end must be finite and > t_start, got {t_end!r}")
    check_outputs(outputs, kind.outputs)
    pts = sweep_points(params, points)
    if isinstance(executor, str) and executor not in ("serial", "processes"):
        _require_dask(executor)

    # ---- the mechanism and its scene text
    if not isinstance(mechanism, Mechanism):
        raise AnalysisError(f"sweep: expected a Mechanism, got {type(mechanism).__name__} "
                            f"{mechanism!r}; read a scene file with casmbd.load_scene(path)")
    mech = mechanism
    scenes = getattr(mech, "scene_points", None)  # set by casmbd.io.scene for a scene's model
    if scenes is not None and not scenes.describes(mech):  # changed in Python since it was
        scenes = None                                      # read: the points run that object
    text = scenes.text if scenes is not None else None
    if kind.time_grid:  # one point's result must fit (LimitError before any build)
        check_steps(f"sweep ({analysis}) at each point", int(steps), mech)
    known = list(mech.parameters)
    for name in pts[0]:
        if name not in known:
            raise ModelError(f"sweep: unknown parameter '{name}' (known: "
                             f"{', '.join(known) or 'none; add a [parameters] table'})")

    # ---- per-point scenes: validated with the point's values, checked for load-time use
    if scenes is not None:
        point_scenes, pre_failed = scenes.point_scenes(pts)
    else:
        point_scenes, pre_failed = [None] * len(pts), {}
    tasks = [(i, p, point_scenes[i]) for i, p in enumerate(pts) if i not in pre_failed]

    digits = max(3, len(str(len(pts) - 1)))
    mech_bytes = None
    key_src = text
    if text is None:
        try:
            mech_bytes = pickle.dumps(mech)
        except Exception as exc:
            if executor != "serial":
                raise AnalysisError(f"sweep: mechanism '{mech.name}' cannot be sent to worker "
                                    f"processes ({type(exc).__name__}: {exc}); load it from a "
                                    "scene file or use executor='serial'") from None
            mech_bytes = None
        key_src = hashlib.sha256(mech_bytes).hexdigest() if mech_bytes else f"id{id(mech)}"
    spec = {"scenes": scenes, "mechanism": mech_bytes, "analysis": analysis, "sweepable": kind,
            "options": dict(options), "mode": mode, "t_end": t_end, "steps": steps,
            "outputs": outputs, "out_dir": None if out_dir is None else str(out_dir),
            "digits": digits}
    # the cache folder is part of the key: a runner built against another cache would leave
    # the workers' cache cold
    spec["key"] = hashlib.sha256(repr((key_src, analysis, sorted(
        (k, repr(v)) for k, v in options.items()), mode, str(codegen.cache_dir()),
        os.environ.get("CASMBD_COMPILE", ""))).encode()).hexdigest()

    # ---- build once here: the disk cache is warm for the workers
    if text is None and mech_bytes is None:
        _RUNNERS[spec["key"]] = _Runner(spec, mechanism=mech)
    runner, _ = _runner(spec)
    parent_build = dict(runner.report)
    if outputs is not None and not callable(outputs):
        check_output_names(runner, spec, pts[0])  # before any point runs or file is written
    if out_dir is not None:
        Path(out_dir).mkdir(parents=True, exist_ok=True)

    # ---- run
    if executor == "serial":
        kind, n_workers = "serial", 1
    elif executor == "processes":
        kind, n_workers = "processes", int(workers or os.cpu_count() or 1)
        if n_workers < 1:
            raise AnalysisError(f"sweep: workers must be >= 1, got {workers!r}")
    elif isinstance(executor, str) or hasattr(executor, "submit"):
        kind, n_workers = "dask", None
    else:
        raise AnalysisError(f"sweep: executor must be 'serial', 'processes', a Dask scheduler "
                            f"address or a distributed.Client, got {executor!r}")
    bar = _progress(len(pts), progress)
    try:
        if kind == "serial":
            records = _run_serial(spec, tasks, bar)
        elif kind == "processes":
            records = _run_processes(spec, tasks, n_workers, bar)
        else:
            records = _run_dask(spec, tasks, executor, bar)
            n_workers = spec.pop("_dask_workers", None)
    finally:
        if bar is not None:
            bar.close()
    for i, msg in pre_failed.items():
        records.append({"index": i, "status": "failed", "error": msg, "outputs": {},
                        "file": None, "worker": "parent (scene check)", "runner_built": False,
                        "compiler_runs": 0})
    records.sort(key=lambda r: r["index"])

    # ---- the table
    out_names: list[str] = [] if outputs is None or callable(outputs) else list(outputs)
    for rec in records:
        for k in rec["outputs"]:
            if k not in out_names:
                out_names.append(k)
    status = np.array([r["status"] for r in records], dtype="<U6")
    here = f"{socket.gethostname()}:{os.getpid()}"
    remote = [r for r in records if r.get("worker") not in (here, "?", "parent (scene check)")]
    built = [r for r in remote if r.get("runner_built")]
    stats = {"executor": kind, "workers": n_workers, "points": len(pts),
             "failed": int(np.sum(status != "ok")), "parent_build": parent_build,
             "worker_processes": sorted({r["worker"] for r in remote}),
             "worker_builds": len(built),
             "worker_cache_hits": sum(bool(r["build"].get("cache_hit")) for r in built),
             "worker_compiler_runs": sum(int(r.get("compiler_runs", 0)) for r in records),
             "point_seconds": float(sum(r.get("seconds", 0.0) for r in records)),
             "wall_seconds": 0.0}
    point_stats = [{k: r.get(k) for k in ("index", "worker", "seconds", "runner_built",
                                           "build", "compiler_runs", "solve_seconds")}
                   for r in records]
    res = SweepResult(analysis, structured_table(list(pts[0]), pts),
                      structured_table(out_names, [r["outputs"] for r in records]),
                      status, [r["error"] for r in records], [r["file"] for r in records],
                      stats, point_stats, None if out_dir is None else str(out_dir))
    stats["wall_seconds"] = time.perf_counter() - t_wall
    if out_dir is not None:
        res.to_csv(Path(out_dir) / "sweep.csv")
        res.save(Path(out_dir) / "sweep.npz")
    return res
