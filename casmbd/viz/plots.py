"""Time histories of a result and work-precision plots (matplotlib, Agg-safe).

Every function builds a :class:`matplotlib.figure.Figure` with an Agg canvas (no pyplot, so
no GUI backend and no global figure list; works on machines without a display), returns it,
and when ``out`` is given saves it atomically (temporary file + ``os.replace``).

Kinds (:data:`KINDS`): ``coordinates`` (q), ``joints`` (joint coordinates), ``efforts``
(driver efforts, actuator efforts or inputs), ``reactions`` (joint reaction forces and
moments), ``energy`` (kinetic, potential, total and the drift of the total) and ``drift``
(max |C| and max |C_q v + C_t| per output time, logarithmic).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from casmbd.errors import AnalysisError, LimitError
from casmbd.limits import MAX_DPI, MAX_FIGURE_INCHES, MAX_PIXELS, check_count
from casmbd.results import atomic_write
from casmbd.viz.geometry import scene_name

#: at most this many lines get a legend entry
MAX_LEGEND = 14


def check_figure_size(figsize=None, dpi: float | None = None, what: str = "figure") -> None:
    """Refuse (:class:`~casmbd.errors.LimitError`) a figure size or resolution beyond the
    limits of :mod:`casmbd.limits` before matplotlib allocates the canvas: width and height
    in (0, MAX_FIGURE_INCHES] inches, dpi in (0, MAX_DPI], at most MAX_PIXELS pixels."""
    if dpi is not None:
        if not (isinstance(dpi, (int, float)) and math.isfinite(dpi) and dpi > 0):
            raise LimitError(f"{what}: dpi must be a finite number > 0, got {dpi!r}")
        check_count(f"{what}: dpi", dpi, MAX_DPI, "use a lower resolution")
    if figsize is not None:
        for label, inches in zip(("width", "height"), figsize, strict=True):
            if not (isinstance(inches, (int, float)) and math.isfinite(inches) and inches > 0):
                raise LimitError(f"{what}: {label} must be a finite number of inches > 0, "
                                 f"got {inches!r}")
            check_count(f"{what}: {label} in inches", inches, MAX_FIGURE_INCHES)
        if dpi is not None:
            check_count(f"{what}: pixels ({figsize[0]:g} × {figsize[1]:g} in at {dpi:g} dpi)",
                        round(figsize[0] * figsize[1] * dpi * dpi), MAX_PIXELS,
                        "use a lower dpi")


def new_figure(nrows: int = 1, ncols: int = 1, figsize=(6.4, 3.2), **kw):
    """A Figure on an Agg canvas and its axes (squeezed like ``pyplot.subplots``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    check_figure_size(figsize)
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=True, **kw)
    return fig, axes


def save_figure(fig, out: str | os.PathLike, dpi: float = 100) -> Path:
    """Save ``fig`` atomically; the format follows the suffix of ``out`` (png, pdf, svg …)."""
    fmt = Path(out).suffix.lstrip(".").lower() or "png"
    check_figure_size(tuple(float(x) for x in fig.get_size_inches()), dpi, f"figure '{out}'")
    try:
        return atomic_write(out, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))
    except ValueError as exc:  # unknown format
        raise AnalysisError(f"cannot write figure '{out}': {exc}") from None


def _legend(ax, n_lines: int) -> None:
    if 0 < n_lines <= MAX_LEGEND:
        ax.legend(fontsize=7, ncols=1 + n_lines // 8, loc="best")


def _need(result, kind: str, *keys: str) -> np.ndarray:
    for key in keys:
        if key in result.arrays:
            return result.arrays[key]
    raise AnalysisError(f"plot kind '{kind}': the {result.kind} result holds no "
                        + " or ".join(f"'{k}'" for k in keys))


def _draw_coordinates(result, ax) -> None:
    q = _need(result, "coordinates", "q")
    names = result.names.get("coordinates") or [f"q{k}" for k in range(q.shape[1])]
    for k, name in enumerate(names):
        ax.plot(result.t, q[:, k], label=name, lw=1)
    ax.set_ylabel("coordinates q")
    _legend(ax, len(names))


def _draw_joints(result, ax) -> None:
    c = _need(result, "joints", "joint_positions")
    for k, name in enumerate(result.names.get("joints", [])):
        ax.plot(result.t, c[:, k], label=name, lw=1)
    ax.set_ylabel("joint coordinates")
    _legend(ax, c.shape[1])


def _draw_efforts(result, ax) -> None:
    n = 0
    for key, group, what in (("driver_efforts", "drivers", "effort"),
                             ("actuator_efforts", "actuators", "effort"),
                             ("actuator_inputs", "actuators", "input")):
        if key == "actuator_inputs" and "actuator_efforts" in result.arrays:
            continue
        for k, name in enumerate(result.names.get(group, []) if key in result.arrays else []):
            ax.plot(result.t, result.arrays[key][:, k], label=f"{name} {what}", lw=1)
            n += 1
    if n == 0:
        raise AnalysisError(f"plot kind 'efforts': the {result.kind} result holds no driver or "
                            "actuator efforts (no drivers or actuators, or a kinematic analysis)")
    ax.set_ylabel("effort [N or N m]")
    _legend(ax, n)


def _draw_reactions(result, ax) -> None:
    lam = _need(result, "reactions", "joint_reactions")
    labels = ("Fx", "Fy", "M") if lam.shape[2] == 3 else ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
    n = 0
    for j, name in enumerate(result.names.get("all_joints", [])):
        for c, label in enumerate(labels):
            ax.plot(result.t, lam[:, j, c], label=f"{name}.{label}", lw=1,
                    ls="-" if label.startswith("F") else "--")
            n += 1
    ax.set_ylabel("reactions [N, N m (dashed)]")
    _legend(ax, n)


def _draw_energy(result, ax) -> None:
    total = _need(result, "energy", "total_energy")
    for key in ("kinetic", "potential", "total"):
        ax.plot(result.t, result.arrays[f"{key}_energy"], label=key, lw=1)
    ax.set_ylabel("energy [J]")
    twin = ax.twinx()
    twin.plot(result.t, total - total[0], color="k", lw=0.8, ls=":", label="total − total(0)")
    twin.set_ylabel("drift of the total [J]", fontsize=8)
    lines = ax.get_lines() + twin.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], fontsize=7, loc="best")


def _draw_drift(result, ax) -> None:
    cv = _need(result, "drift", "constraint_violation")
    series = [("position max|C|", cv)]
    if "velocity_violation" in result.arrays:
        series.append(("velocity max|C_q v + C_t|", result.arrays["velocity_violation"]))
    for label, values in series:  # exact zeros (the assembled start) are left out
        ax.semilogy(result.t, np.where(values > 0, values, np.nan), label=label, lw=1)
    if not any(np.any(values > 0) for _, values in series):
        ax.set_ylim(1e-17, 1e-15)
        ax.text(0.5, 0.5, "zero at every output time", transform=ax.transAxes, ha="center")
    ax.set_ylabel("constraint violation")
    ax.legend(fontsize=7, loc="best")


#: plot kinds and the functions drawing them into one Axes
KINDS: dict[str, Callable] = {"coordinates": _draw_coordinates, "joints": _draw_joints,
                              "efforts": _draw_efforts, "reactions": _draw_reactions,
                              "energy": _draw_energy, "drift": _draw_drift}
_NEEDS = {"coordinates": ("q",), "joints": ("joint_positions",),
          "efforts": ("driver_efforts", "actuator_efforts", "actuator_inputs"),
          "reactions": ("joint_reactions",), "energy": ("total_energy",),
          "drift": ("constraint_violation",)}


def available_kinds(result) -> list[str]:
    """The kinds whose arrays the result holds, in :data:`KINDS` order."""
    out = []
    for kind, keys in _NEEDS.items():
        if any(k in result.arrays for k in keys):
            if kind == "efforts" and not (result.names.get("drivers")
                                          or result.names.get("actuators")):
                continue
            if kind == "joints" and not result.names.get("joints"):
                continue
            out.append(kind)
    return out


def plot_result(result, kinds: str | Sequence[str] | None = None,
                out: str | os.PathLike | None = None, dpi: float = 100, title: str | None = None):
    """One panel per kind against time, stacked with a shared time axis.

    Parameters
    ----------
    result : Result
    kinds : str or sequence of str, optional
        From :data:`KINDS`; default every kind the result holds (:func:`available_kinds`).
    out : path, optional
        Save the figure there (atomically; format from the suffix).
    dpi : float
    title : str, optional
        Default: the analysis kind and the scene name when the result holds a scene.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    AnalysisError
        For an unknown kind, or a kind whose arrays the result does not hold (both named).
    """
    if kinds is None:
        kinds = available_kinds(result)
    elif isinstance(kinds, str):
        kinds = [kinds]
    kinds = list(kinds)
    unknown = [k for k in kinds if k not in KINDS]
    if unknown:
        raise AnalysisError(f"unknown plot kind(s) {', '.join(map(repr, unknown))} (known: "
                            f"{', '.join(KINDS)})")
    if not kinds:
        raise AnalysisError(f"the {result.kind} result holds nothing to plot")
    fig, axes = new_figure(len(kinds), 1, figsize=(6.4, 1.0 + 2.2 * len(kinds)), sharex=True)
    axes = np.atleast_1d(axes)
    for kind, ax in zip(kinds, axes):
        KINDS[kind](result, ax)
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[-1].set_xlabel("t [s]")
    if title is None:
        name = scene_name(result)
        title = f"{name}: {result.kind}" if name else result.kind
    fig.suptitle(title, fontsize=10)
    if out is not None:
        save_figure(fig, out, dpi)
    return fig


def _one(kind: str):
    def plot(result, out: str | os.PathLike | None = None, dpi: float = 100):
        return plot_result(result, [kind], out=out, dpi=dpi)

    plot.__name__ = f"plot_{kind}"
    plot.__doc__ = (f"The ``{kind}`` panel of :func:`plot_result` alone (a Figure; saved "
                    "atomically when ``out`` is given).")
    return plot


plot_coordinates = _one("coordinates")
plot_joints = _one("joints")
plot_efforts = _one("efforts")
plot_reactions = _one("reactions")
plot_energy = _one("energy")
plot_drift = _one("drift")


# ---------------------------------------------------------------------- work-precision
def read_rows(path: str | os.PathLike) -> list[dict]:
    """Rows of a CSV file with a header line (values as strings)."""
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            return list(csv.DictReader(fh))
    except OSError as exc:
        raise AnalysisError(f"cannot read '{path}': {exc.strerror or exc}") from None


def plot_work_precision(rows: Iterable[dict] | str | os.PathLike,
                        out: str | os.PathLike | None = None, *,
                        method: str | Sequence[str] = "method", time: str = "time",
                        error: str = "error", title: str | None = None, dpi: float = 100):
    """Error against computing time on log-log axes, one line per method.

    Parameters
    ----------
    rows : iterable of dict, or path of a CSV file
        One run per row with the columns named by ``method``, ``time`` and ``error``.  Rows
        whose time or error is missing, not a number, or not positive are skipped (a failed run,
        or an exact result that a log axis cannot show).
    method : str or sequence of str
        Column(s) naming the method; several are joined with "/" (for the benchmark CSV:
        ``("coordinates", "formulation", "integrator")``).
    time, error : str
        Columns of the computing time [s] and the error.
    out : path, optional
        Save the figure there (atomically).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    AnalysisError
        When a column is missing (named) or no row is left to plot.
    """
    if isinstance(rows, (str, os.PathLike)):
        rows = read_rows(rows)
    rows = list(rows)
    cols = [method] if isinstance(method, str) else list(method)
    for col in (*cols, time, error):
        if rows and col not in rows[0]:
            raise AnalysisError(f"work-precision rows have no column '{col}' (columns: "
                                f"{', '.join(rows[0])})")
    series: dict[str, list[tuple[float, float]]] = {}
    for row in rows:
        try:
            x, y = float(row[time]), float(row[error])
        except (TypeError, ValueError):
            continue
        if not (math.isfinite(x) and math.isfinite(y) and x > 0 and y > 0):
            continue
        series.setdefault("/".join(str(row[c]) for c in cols), []).append((x, y))
    if not series:
        raise AnalysisError("no work-precision row with a positive finite time and error")
    fig, ax = new_figure(figsize=(6.4, 4.4))
    markers = "osD^v<>ph*"
    for k, (name, pts) in enumerate(series.items()):
        pts.sort()
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], marker=markers[k % len(markers)],
                  ms=4, lw=1, label=name)
    ax.set_xlabel(f"computing time [s] ({time})")
    ax.set_ylabel(f"error ({error})")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=7)
    if title:
        ax.set_title(title, fontsize=10)
    if out is not None:
        save_figure(fig, out, dpi)
    return fig
