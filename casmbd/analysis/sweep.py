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

Parameters that fix *load-time* numbers of the scene (positions, points, axes, initial
velocities are evaluated when the scene is read, ``docs/scene-format.md``) cannot change at run
time; a sweep over one of them is refused with an :class:`~casmbd.errors.AnalysisError` naming
it.  Numbers of the method chosen at build time from the default values (the augmented
Lagrangian's penalty, the redundancy plan) are kept for every point.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import os
import pickle
import re
import socket
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from casmbd import interrupts
from casmbd.analysis.inverse import inverse_dynamics
from casmbd.analysis.kinematics import kinematics
from casmbd.analysis.simulate import Simulator
from casmbd.analysis.statics import STATICS_NEEDS, static_equilibrium, statics_functions
from casmbd.compiled import codegen
from casmbd.compiled.model import NEEDS, NumericModel
from casmbd.errors import (
    AnalysisError,
    CasmbdError,
    ModelError,
    ResultFileError,
)
from casmbd.limits import MAX_SWEEP_POINTS, check_count, check_steps, output_values
from casmbd.model import Mechanism
from casmbd.results import Result, _json_default, atomic_write, load, read_npz
from casmbd.system.equations import System

__all__ = ["ANALYSES", "REDUCTIONS", "SweepResult", "load_sweep", "parse_values", "sweep"]

#: analyses a sweep can run
ANALYSES = ("simulate", "kinematics", "inverse", "statics")
#: reductions of a named output ``"REDUCTION:COLUMN"`` over the time grid
REDUCTIONS = {"initial": lambda x: x[0], "final": lambda x: x[-1], "min": np.min,
              "max": np.max, "mean": np.mean, "max_abs": lambda x: np.max(np.abs(x)),
              "range": lambda x: np.max(x) - np.min(x)}
#: named outputs without a reduction
SPECIAL_OUTPUTS = ("energy_drift", "max_constraint_violation")

#: options of each analysis given when its engine is built (the rest go to each run)
_BUILD_OPTIONS = {"simulate": ("formulation", "inputs", "formulation_options", "redundancy")}
_RUN_OPTIONS = {"simulate": ("integrator", "rtol", "atol", "t_start", "projection", "step",
                             "max_steps"),
                "kinematics": ("t_start",), "inverse": ("t_start",),
                "statics": ("t", "method", "tol", "max_iter")}


# ====================================================================== point values
def parse_values(text: str) -> tuple[str, list[float]]:
    """``name=a:b:n`` (n values from a to b inclusive, ``numpy.linspace``), ``name=a,b,c`` or
    ``name=a`` -> ``(name, values)`` (the CLI's ``--param``).

    Raises
    ------
    AnalysisError
        Naming the text when it is not of one of these forms.
    """
    name, sep, rhs = text.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier() or not rhs.strip():
        raise AnalysisError(f"--param {text!r}: expected NAME=A:B:N, NAME=A,B,C or NAME=A")
    try:
        if ":" in rhs:
            parts = rhs.split(":")
            if len(parts) != 3:
                raise ValueError
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
            if n < 1:
                raise ValueError
            check_count(f"--param {text!r}: points", n, MAX_SWEEP_POINTS,
                        "use fewer points (before any value is generated)")
            values = np.linspace(a, b, n).tolist()
        else:
            values = [float(x) for x in rhs.split(",")]
    except ValueError:
        raise AnalysisError(f"--param {text!r}: expected NAME=A:B:N (N >= 1 points from A to B "
                            "inclusive), NAME=A,B,C or NAME=A with numbers") from None
    if not all(math.isfinite(v) for v in values):
        raise AnalysisError(f"--param {text!r}: values must be finite numbers")
    return name, values


def _points(params: Mapping[str, Iterable[float]] | None,
            points: Sequence[Mapping[str, float]] | None) -> list[dict[str, float]]:
    """The grid product of ``params`` (first name slowest) or the given ``points``."""
    if (params is None) == (points is None):
        raise AnalysisError("sweep: give either params={name: values} (grid product) or "
                            "points=[{name: value}, ...]")
    if params is not None:
        names = list(params)
        if not names:
            raise AnalysisError("sweep: params is empty")
        lists = []
        for name in names:
            vals = np.atleast_1d(np.asarray(params[name], dtype=float)).ravel()
            if vals.size == 0:
                raise AnalysisError(f"sweep: parameter '{name}' has no values")
            lists.append(vals.tolist())
        sizes = " × ".join(f"{n} {len(v)}" for n, v in zip(names, lists, strict=True))
        check_count(f"sweep: grid points ({sizes})", math.prod(len(v) for v in lists),
                    MAX_SWEEP_POINTS, "use fewer values per parameter or a points= list")
        out = [dict(zip(names, combo, strict=True)) for combo in itertools.product(*lists)]
    else:
        if hasattr(points, "__len__"):
            check_count("sweep: points", len(points), MAX_SWEEP_POINTS, "split the sweep")
        out = [{str(k): float(v) for k, v in dict(p).items()} for p in points]
        if not out:
            raise AnalysisError("sweep: points is empty")
        names = list(out[0])
        for i, p in enumerate(out):
            if list(p) != names and set(p) != set(names):
                raise AnalysisError(f"sweep: point {i} sets {sorted(p)}, point 0 sets "
                                    f"{sorted(names)}; every point must set the same names")
    for i, p in enumerate(out):
        for k, v in p.items():
            if not math.isfinite(v):
                raise AnalysisError(f"sweep: point {i}: parameter '{k}' = {v!r} is not finite")
    return out


# ====================================================================== outputs
_BODY = re.compile(r"^(body|marker|joint)\.([^.]+)\.([A-Za-z_]+)(?:\.([A-Za-z0-9_]+))?$")


def _check_outputs(outputs) -> None:
    if outputs is None or callable(outputs):
        return
    if isinstance(outputs, str) or not all(isinstance(o, str) for o in outputs):
        raise AnalysisError("sweep: outputs must be a list of names such as "
                            "'final:q[crank.angle]', or a callable result -> {name: number}")
    for name in outputs:
        if name in SPECIAL_OUTPUTS:
            continue
        red, sep, col = name.partition(":")
        if not sep or red not in REDUCTIONS or not col:
            raise AnalysisError(f"sweep: output {name!r}: expected REDUCTION:COLUMN with "
                                f"REDUCTION one of {', '.join(REDUCTIONS)} (e.g. "
                                f"'final:q[crank.angle]', 'max:body.crank.angle'), or one of "
                                f"{', '.join(SPECIAL_OUTPUTS)}")


def _series(result: Result, column: str, where: str) -> np.ndarray:
    """A scalar series of the result: a CSV column label (``q[block.x]``, ``total_energy``) or
    ``body.NAME.FIELD[.AXIS]``, ``marker.NAME.FIELD.AXIS``, ``joint.NAME.FIELD``."""
    m = _BODY.match(column)
    if m:
        kind, name, fld, axis = m.groups()
        try:
            data = getattr(result, kind)(name)
        except (KeyError, ValueError):
            known = result.names.get({"body": "bodies", "marker": "markers",
                                      "joint": "all_joints"}[kind], [])
            raise AnalysisError(f"{where}: unknown {kind} '{name}' (known: "
                                f"{', '.join(known) or 'none'})") from None
        if fld not in data:
            raise AnalysisError(f"{where}: {kind} '{name}' has no '{fld}' (has: "
                                f"{', '.join(data)})")
        arr = np.asarray(data[fld], float)
        if arr.ndim == 1 and axis is None:
            return arr
        axes = "wxyz" if fld == "quaternion" else "xyz"
        if arr.ndim == 2 and axis is not None:
            idx = int(axis) if axis.isdigit() else axes.find(axis)
            if 0 <= idx < arr.shape[1]:
                return arr[:, idx]
        if arr.ndim == 1:
            raise AnalysisError(f"{where}: '{fld}' of {kind} '{name}' is a scalar series; "
                                f"drop '.{axis}'")
        raise AnalysisError(f"{where}: '{fld}' of {kind} '{name}' has components "
                            f"{list(axes[:arr.shape[-1]]) if arr.ndim == 2 else arr.shape[1:]};"
                            " name one: .x, .y, .z (quaternion .w, .x, .y, .z) or .0, .1 …")
    columns = dict(result.csv_columns())
    if column in columns:
        return columns[column]
    known = [c for c in columns if "[" not in c or c.startswith("q[")]
    raise AnalysisError(f"{where}: unknown column '{column}' (e.g. {', '.join(known[:12])}; "
                        "or body.NAME.FIELD[.AXIS], joint.NAME.FIELD)")


def _check_output_names(runner, spec: dict, values: Mapping[str, float]) -> None:
    """Evaluate the named outputs on a probe run at the first point — one output step over
    1e-6 of the time span (statics: the point itself) — so that an unknown column, body or
    joint is an :class:`~casmbd.errors.AnalysisError` naming the output before any point
    runs.  A probe run that fails leaves the check to the points (their failure is
    recorded)."""
    t_end = spec["t_end"]
    if spec["analysis"] != "statics":
        t_start = runner.run_options.get("t_start", 0.0)
        t_end = t_start + 1e-6 * (t_end - t_start)
    try:
        probe = runner.run(values, t_end, 1)
    except CasmbdError:
        return
    _evaluate_outputs(spec["outputs"], probe, spec["analysis"])


def _default_outputs(result: Result, analysis: str) -> list[str]:
    names = [f"final:q[{c}]" for c in result.names.get("coordinates", [])]
    if analysis == "statics":
        return [*names, "residual", "min_stiffness_eigenvalue"]
    names.append("max_constraint_violation")
    if analysis == "simulate":
        names.append("energy_drift")
    if analysis == "inverse":
        names += [f"max_abs:driver_efforts[{d}.effort]" for d in result.names.get("drivers", [])]
    return names


def _evaluate_outputs(outputs, result: Result, analysis: str) -> dict[str, float]:
    if callable(outputs):
        raw = outputs(result)
        if not isinstance(raw, Mapping):
            raise AnalysisError(f"sweep: the outputs callable returned {type(raw).__name__}, "
                                "expected a mapping name -> number")
        out = {}
        for key, val in raw.items():
            arr = np.asarray(val, dtype=float)
            if arr.size != 1:
                raise AnalysisError(f"sweep: output '{key}' of the callable is not a scalar "
                                    f"(shape {arr.shape})")
            out[str(key)] = float(arr.reshape(()))
        return out
    names = _default_outputs(result, analysis) if outputs is None else list(outputs)
    out = {}
    for name in names:
        where = f"sweep: output {name!r}"
        if name == "energy_drift":
            e = result["total_energy"] if "total_energy" in result.arrays else None
            if e is None:
                raise AnalysisError(f"{where}: the {result.kind} result has no energies")
            out[name] = float(e[-1] - e[0])
        elif name == "max_constraint_violation":
            cv = result.arrays.get("constraint_violation", np.zeros(1))
            out[name] = float(np.max(cv)) if cv.size else 0.0
        elif name in ("residual", "min_stiffness_eigenvalue") and analysis == "statics":
            out[name] = float(result.stats.get(name, math.nan))
        else:
            red, _, col = name.partition(":")
            series = _series(result, col, where)
            out[name] = float(REDUCTIONS[red](series)) if len(series) else math.nan
    return out


# ====================================================================== the worker side
class _Runner:
    """One analysis of one mechanism, built once per process and run at many p."""

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
        opts = spec["options"]
        build = {k: opts[k] for k in _BUILD_OPTIONS.get(self.analysis, ()) if k in opts}
        self.run_options = {k: opts[k] for k in _RUN_OPTIONS[self.analysis] if k in opts}
        mode = spec["mode"]
        if self.analysis == "simulate":
            self.engine = Simulator(mech, mode=mode, **build)
            self.model = self.engine.model
        elif self.analysis == "kinematics":
            self.model = NumericModel(mech, "kinematics", mode=mode)
        elif self.analysis == "inverse":
            self.model = NumericModel(mech, NEEDS["dynamics"], mode=mode)
        else:
            system = System(mech)
            self.model = NumericModel(system, STATICS_NEEDS, mode=mode,
                                      extra=statics_functions(system))
        self.report = {k: v for k, v in self.model.report_dict.items()
                       if k in ("compiled", "cache_hit", "mode")}
        self.report["compiler_runs"] = codegen.COMPILE_COUNT - before
        self.report["build_seconds"] = time.perf_counter() - t0

    def run(self, values: Mapping[str, float], t_end, steps) -> Result:
        p = {**self.defaults, **values}
        # runtime inputs of every Function, and System.parameter_values (initial velocities)
        self.model.p[:] = [p[n] for n in self.names]
        self.mechanism.parameters.update(p)
        opts = self.run_options
        if self.analysis == "simulate":
            return self.engine.run(t_end, steps, **opts)
        if self.analysis == "kinematics":
            return kinematics(self.model, t_end=t_end, steps=steps, **opts)
        if self.analysis == "inverse":
            return inverse_dynamics(self.model, t_end=t_end, steps=steps, **opts)

        return _statics_result(static_equilibrium(self.model, **opts))


def _statics_result(res) -> Result:
    """A :class:`~casmbd.analysis.statics.StaticsResult` as a one-time :class:`Result` (so that
    it is saved, reloaded and reduced like the others)."""
    names = {k: list(v) for k, v in res.names.items()}
    eig = np.asarray(res.eigenvalues, float)
    arrays = {"q": np.asarray(res.q, float)[None, :],
              "lambda": np.asarray(res.lagrange_multipliers, float)[None, :],
              "joint_reactions": np.asarray(res.joint_reactions, float)[None, :, :],
              "potential_energy": np.array([res.potential_energy]),
              "stiffness_eigenvalues": eig[None, :]}
    stats = {**res.stats, "iterations": int(res.iterations), "residual": float(res.residual),
             "stable": res.stable, "method": res.method,
             "min_stiffness_eigenvalue": float(eig.min()) if eig.size else math.nan}
    return Result("statics", np.array([float(res.t)]), arrays, names, stats)


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
        rec["outputs"] = _evaluate_outputs(spec["outputs"], result, spec["analysis"])
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


# ====================================================================== the result
@dataclass
class SweepResult:
    """Outputs of a parameter sweep, one row per point.

    Attributes
    ----------
    analysis : str
    parameters : numpy structured array (n_points,)
        One float field per swept parameter.
    outputs : numpy structured array (n_points,)
        One float field per output (NaN where the point failed).
    status : ndarray of str (n_points,)
        ``"ok"`` or ``"failed"``.
    errors : list of str
        The failure message of each point (empty when it succeeded).
    files : list of str or None
        ``out_dir/point_XXX.npz`` of each successful point (None without ``out_dir``).
    stats : dict
        ``executor``, ``workers``, ``points``, ``failed``, ``wall_seconds``, ``parent_build``
        (compiled / cache_hit of the build in the calling process), ``worker_builds``,
        ``worker_compiler_runs``, ``worker_cache_hits`` (the workers' own build reports:
        ``worker_compiler_runs == 0`` means no worker compiled), ``worker_processes``.
    point_stats : list of dict
        Per point: worker (host:pid), seconds, runner_built, build report, compiler_runs.
    """

    analysis: str
    parameters: np.ndarray
    outputs: np.ndarray
    status: np.ndarray
    errors: list[str]
    files: list[str | None]
    stats: dict = field(default_factory=dict)
    point_stats: list[dict] = field(default_factory=list)
    out_dir: str | None = None

    def __len__(self) -> int:
        return len(self.status)

    @property
    def parameter_names(self) -> list[str]:
        return list(self.parameters.dtype.names or ())

    @property
    def output_names(self) -> list[str]:
        return list(self.outputs.dtype.names or ())

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask of the successful points."""
        return self.status == "ok"

    @property
    def failed(self) -> list[int]:
        """Indices of the failed points."""
        return [int(i) for i in np.flatnonzero(~self.ok)]

    def __getitem__(self, name: str) -> np.ndarray:
        """A parameter's or an output's column."""
        if name in self.parameter_names:
            return self.parameters[name]
        if name in self.output_names:
            return self.outputs[name]
        raise KeyError(f"no column '{name}' (parameters: {', '.join(self.parameter_names)}; "
                       f"outputs: {', '.join(self.output_names)})")

    def result(self, index: int) -> Result:
        """The saved :class:`Result` of point ``index`` (needs ``out_dir``)."""
        path = self.files[index]
        if path is None:
            why = self.errors[index] or "the sweep ran without out_dir"
            raise AnalysisError(f"sweep point {index} has no result file ({why})")

        return load(path)

    def to_json(self) -> dict:
        """``analysis``, ``parameters`` and ``outputs`` (names), ``points`` (one object per
        point: index, parameters, outputs, status, error, file), ``failed``, ``stats``."""
        def num(x):
            x = float(x)
            return x if math.isfinite(x) else None

        points = [{"index": i,
                   "parameters": {n: num(self.parameters[n][i]) for n in self.parameter_names},
                   "outputs": {n: num(self.outputs[n][i]) for n in self.output_names},
                   "status": str(self.status[i]), "error": self.errors[i],
                   "file": self.files[i]} for i in range(len(self))]
        return {"kind": "sweep", "analysis": self.analysis,
                "parameters": self.parameter_names, "outputs": self.output_names,
                "points": points, "failed": len(self.failed), "stats": dict(self.stats)}

    def to_csv(self, path: str | os.PathLike) -> Path:
        """One row per point: ``index``, parameters, outputs (17 significant digits, ``nan``
        where failed), ``status``, ``error``; written atomically."""
        import csv

        def write(tmp: str) -> None:
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh)
                w.writerow(["index", *self.parameter_names, *self.output_names, "status",
                            "error"])
                for i in range(len(self)):
                    w.writerow([i, *(repr(float(self.parameters[n][i]))
                                     for n in self.parameter_names),
                                *(repr(float(self.outputs[n][i])) for n in self.output_names),
                                str(self.status[i]), self.errors[i]])

        return atomic_write(path, write)

    def save(self, path: str | os.PathLike) -> Path:
        """The table (parameters, outputs, status, errors, files, stats) as an npz file,
        atomically; :func:`load_sweep` reads it back."""
        meta = {"analysis": self.analysis, "errors": self.errors, "files": self.files,
                "stats": self.stats, "point_stats": self.point_stats, "out_dir": self.out_dir}
        payload = {"parameters": self.parameters, "outputs": self.outputs,
                   "status": np.asarray(self.status, dtype=str),
                   "meta": np.array(json.dumps(meta, default=_json_default))}

        def write(tmp: str) -> None:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **payload)

        return atomic_write(path, write)

    def plot(self, x: str | None = None, y: str | Sequence[str] | None = None,
             out: str | os.PathLike | None = None, dpi: float = 100.0):
        """Outputs against one parameter (matplotlib, imported here): one panel per output
        ``y`` (default: up to four), one line per combination of the other parameters;
        failed points are left out.  Saves to ``out`` when given; returns the figure."""
        import matplotlib

        if out is not None:
            matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        x = x or self.parameter_names[0]
        if x not in self.parameter_names:
            raise AnalysisError(f"plot: x must be a parameter ({', '.join(self.parameter_names)})"
                                f", got {x!r}")
        ys = [y] if isinstance(y, str) else list(y or self.output_names[:4])
        for name in ys:
            if name not in self.output_names:
                raise AnalysisError(f"plot: unknown output {name!r} (outputs: "
                                    f"{', '.join(self.output_names)})")
        others = [n for n in self.parameter_names if n != x]
        groups: dict = {}
        for i in np.flatnonzero(self.ok):
            key = tuple(float(self.parameters[n][i]) for n in others)
            groups.setdefault(key, []).append(i)
        fig, axes = plt.subplots(len(ys), 1, figsize=(6.0, 2.2 * len(ys) + 0.6), squeeze=False,
                                 sharex=True)
        for ax, name in zip(axes[:, 0], ys, strict=True):
            for key, idx in groups.items():
                idx = sorted(idx, key=lambda i: self.parameters[x][i])
                label = ", ".join(f"{n} = {v:g}" for n, v in zip(others, key, strict=True))
                ax.plot(self.parameters[x][idx], self.outputs[name][idx], "o-", ms=3,
                        label=label or None)
            ax.set_ylabel(name, fontsize=8)
            ax.grid(True, alpha=0.3)
            if others and len(groups) <= 8:
                ax.legend(fontsize=7)
        axes[-1, 0].set_xlabel(x)
        fig.suptitle(f"{self.analysis} sweep: {int(self.ok.sum())} of {len(self)} points",
                     fontsize=9)
        fig.tight_layout()
        if out is not None:
            atomic_write(out, lambda tmp: fig.savefig(tmp, dpi=dpi))
            plt.close(fig)
        return fig


def load_sweep(path: str | os.PathLike) -> SweepResult:
    """Read a table written by :meth:`SweepResult.save`."""
    data = read_npz(path, "sweep")  # ResultFileError on a bad file, naming it
    try:
        meta = json.loads(str(data["meta"]))
        return SweepResult(meta["analysis"], data["parameters"], data["outputs"],
                           data["status"], meta["errors"], meta["files"], meta["stats"],
                           meta["point_stats"], meta["out_dir"])
    except (ValueError, KeyError, TypeError) as exc:
        raise ResultFileError(f"'{path}' is not a casmbd sweep file ({type(exc).__name__}: "
                              f"{exc})") from None


def _table(names: list[str], rows: list[dict]) -> np.ndarray:
    arr = np.full(len(rows), np.nan, dtype=[(n, float) for n in names])
    for i, row in enumerate(rows):
        for n in names:
            arr[n][i] = row.get(n, math.nan)
    return arr


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
    analysis : {"simulate", "kinematics", "inverse", "statics"}
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
        ``t``, ``method``, ``tol``, ``max_iter`` (statics).

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
    if analysis not in ANALYSES:
        raise AnalysisError(f"sweep: unknown analysis {analysis!r} (known: {', '.join(ANALYSES)})")
    allowed = set(_BUILD_OPTIONS.get(analysis, ())) | set(_RUN_OPTIONS[analysis])
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise AnalysisError(f"sweep: option(s) {', '.join(unknown)} do not apply to "
                            f"{analysis} (allowed: {', '.join(sorted(allowed)) or 'none'})")
    if analysis != "statics":
        if t_end is None or steps is None:
            raise AnalysisError(f"sweep: the {analysis} analysis needs t_end and steps")
        if not (isinstance(steps, (int, np.integer)) and steps >= 1):
            raise AnalysisError(f"sweep: steps must be an integer >= 1, got {steps!r}")
        if not (math.isfinite(t_end) and t_end > options.get("t_start", 0.0)):
            raise AnalysisError(f"sweep: t_end must be finite and > t_start, got {t_end!r}")
    _check_outputs(outputs)
    pts = _points(params, points)
    if isinstance(executor, str) and executor not in ("serial", "processes"):
        _require_dask(executor)

    # ---- the mechanism and its scene text
    if not isinstance(mechanism, Mechanism):
        raise AnalysisError(f"sweep: expected a Mechanism, got {type(mechanism).__name__} "
                            f"{mechanism!r}; read a scene file with casmbd.load_scene(path)")
    mech = mechanism
    scenes = getattr(mech, "scene_points", None)  # set by casmbd.io.scene for a scene's model
    text = scenes.text if scenes is not None else None
    if analysis != "statics":  # one point's result must fit (LimitError before any build)
        check_steps(f"sweep ({analysis}) at each point", int(steps), output_values(mech))
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
    spec = {"scenes": scenes, "mechanism": mech_bytes, "analysis": analysis,
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
        _check_output_names(runner, spec, pts[0])  # before any point runs or file is written
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
    res = SweepResult(analysis, _table(list(pts[0]), pts), _table(out_names, [r["outputs"]
                                                                              for r in records]),
                      status, [r["error"] for r in records], [r["file"] for r in records],
                      stats, point_stats, None if out_dir is None else str(out_dir))
    stats["wall_seconds"] = time.perf_counter() - t_wall
    if out_dir is not None:
        res.to_csv(Path(out_dir) / "sweep.csv")
        res.save(Path(out_dir) / "sweep.npz")
    return res
