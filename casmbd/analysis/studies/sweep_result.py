"""The table of a parameter sweep: :class:`SweepResult` (one row per point: parameter values,
named outputs, status, error message, result file) and its files
(:mod:`casmbd.analysis.studies.sweep`).
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from casmbd.errors import AnalysisError, ResultFileError
from casmbd.results import Result, atomic_write, json_default, load, read_npz


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
                   "meta": np.array(json.dumps(meta, default=json_default))}

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


def structured_table(names: list[str], rows: list[dict]) -> np.ndarray:
    """The rows as a structured array with one float field per name (NaN where a row has no
    value for it)."""
    arr = np.full(len(rows), np.nan, dtype=[(n, float) for n in names])
    for i, row in enumerate(rows):
        for n in names:
            arr[n][i] = row.get(n, math.nan)
    return arr
