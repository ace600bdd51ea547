"""Time histories of a result and work-precision plots (matplotlib, Agg-safe).

Every function builds a :class:`matplotlib.figure.Figure` with an Agg canvas (no pyplot, so
no GUI backend and no global figure list; works on machines without a display), returns it,
and when ``out`` is given saves it atomically (temporary file + ``os.replace``).

Kinds (:data:`KINDS`): ``coordinates`` (q; Euler angles of spatial bodies instead of
quaternions), ``joints`` (joint coordinates), ``efforts`` (driver efforts, actuator efforts or
inputs), ``reactions`` (joint reaction forces and moments), ``energy`` (kinetic, potential,
total and the change of the total: drift or work of dampers/drivers) and ``drift`` (max |C|
and max |C_q v + C_t| per output time, logarithmic), ``outputs`` (requests and force-element
reports, under their own names), ``flexible`` (modal coordinates and node deflections) and
``contacts`` (contact forces).  Each kind is split into panels of one unit each, built by
:mod:`casmbd.viz.plot_panels`.  Without kinds the figure is the concise default of at most six
panels, and empty panels, panels of rounding noise and duplicated panels are left out with a
note (:mod:`casmbd.viz.plot_select`).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from casmbd.errors import AnalysisError, LimitError
from casmbd.limits import (
    MAX_DPI,
    MAX_FIGURE_INCHES,
    MAX_PIXELS,
    MAX_SCENE_BYTES,
    check_count,
    read_bounded,
)
from casmbd.results import atomic_write
from casmbd.viz import plot_panels, plot_select
from casmbd.viz.column_units import joint_units, scene_mechanism
from casmbd.viz.geometry import scene_name


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


_STYLES = ("-", "--", ":", "-.")


def _legend(ax, n_lines: int) -> None:
    """Inside the axes for a few lines, else a compact legend outside on the right."""
    if n_lines <= 6:
        ax.legend(fontsize=7, loc="best")
    else:
        ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0,
                  ncols=1 + (n_lines - 1) // 16, handlelength=2.5)


def _draw_panel(ax, t: np.ndarray, panel: plot_panels.Panel) -> None:
    colours = [f"C{k}" for k in range(10)]
    for line in panel.lines:
        style = {"color": colours[line.element % 10],
                 "ls": _STYLES[line.component % len(_STYLES)], "lw": 1, "label": line.label}
        if panel.steps:
            style["drawstyle"] = "steps-post"
        (ax.semilogy if panel.log else ax.plot)(t, line.y, **style)
    for label, value in panel.bounds:  # dashed grey lines, not in the legend
        ax.axhline(value, color="0.4", ls="--", lw=0.8, label=f"_{label}")
    if panel.bounds:
        ax.text(0.01, 0.97, "dashed: bounds", transform=ax.transAxes, va="top",
                fontsize=6, color="0.3")
    if panel.log and panel.note:
        ax.set_ylim(1e-17, 1e-15)
    ax.set_ylabel(panel.ylabel, fontsize=8)
    if panel.note:
        ax.text(0.5, 0.04 if not panel.log else 0.5, panel.note, transform=ax.transAxes,
                ha="center", fontsize=6, color="0.3")
    if len(panel.lines) > 1:
        _legend(ax, len(panel.lines))

    elif panel.lines and panel.lines[0].label not in panel.ylabel:
        ax.legend(fontsize=7, loc="best")  # one line whose label says more than the axis


#: plot kinds and the functions making their panels (:mod:`casmbd.viz.plot_panels`)
KINDS: dict[str, Callable] = {"coordinates": plot_panels.coordinates,
                              "joints": plot_panels.joints, "efforts": plot_panels.efforts,
                              "reactions": plot_panels.reactions,
                              "energy": plot_panels.energy, "drift": plot_panels.drift,
                              "outputs": plot_panels.outputs,
                              "flexible": plot_panels.flexible,
                              "contacts": plot_panels.contacts}
_NEEDS = {"coordinates": ("q",), "joints": ("joint_positions",),
          "efforts": ("driver_efforts", "actuator_efforts", "actuator_inputs"),
          "reactions": ("joint_reactions",), "energy": ("total_energy",),
          "drift": ("constraint_violation",), "outputs": ("outputs", "force_outputs"),
          "flexible": ("node_deflections",), "contacts": ("contact_forces",)}
_WHY = {"joints": "no joint coordinates (its joints are all without one: spherical, rigid, "
                  "…, or it has no joints)",
        "efforts": "no driver or actuator efforts (no drivers or actuators, or a kinematic "
                   "analysis)",
        "flexible": "no flexible body (modal coordinates, node deflections)",
        "contacts": "no contacts or joint limits"}


def _modal(result) -> bool:
    return any(c.rpartition(".")[2].startswith("eta") and c.rpartition(".")[2][3:].isdigit()
               for c in result.names.get("coordinates", []))


def available_kinds(result) -> list[str]:
    """The kinds whose arrays the result holds, in :data:`KINDS` order."""
    out = []
    for kind, keys in _NEEDS.items():
        if any(k in result.arrays for k in keys) or (kind == "flexible" and _modal(result)):
            if kind == "efforts" and not (result.names.get("drivers")
                                          or result.names.get("actuators")):
                continue
            if kind == "joints" and not result.names.get("joints"):
                continue
            if kind == "reactions" and not result.names.get("all_joints"):
                continue  # a free body, a ball on a contact: no joint to report
            if kind == "flexible" and not (_modal(result) or result.names.get("nodes")):
                continue
            if kind == "contacts" and not result.names.get("contacts"):
                continue
            out.append(kind)
    return out


def element_names(result) -> list[str]:
    """Names a plot can be restricted to: bodies, joints, drivers, actuators, requests,
    force elements with reports and contacts."""
    out: list[str] = []
    forces = [n.rpartition(".")[0] for n in result.names.get("force_outputs", [])]
    for names in (*(result.names.get(g, []) for g in ("bodies", "all_joints", "drivers",
                                                      "actuators", "outputs")), forces,
                  result.names.get("contacts", [])):
        out += [n for n in names if n not in out]
    return out


def _panels(result, kind: str, elements, euler: str, mechanism) -> list:
    """The panels of one kind, or an AnalysisError naming what the result can show."""
    what = f"{result.kind} result"
    choices = ", ".join(available_kinds(result)) or "none"
    if scene_name(result):
        choices += f" (scene '{scene_name(result)}')"
    if kind not in available_kinds(result):
        held = any(k in result.arrays for k in _NEEDS[kind])
        why = _WHY.get(kind, "") if held or kind in _WHY else ""
        why = why or "no " + " or ".join(f"'{k}'" for k in _NEEDS[kind])
        raise AnalysisError(f"plot kind '{kind}': the {what} holds {why}; kinds it can show: "
                            f"{choices}")
    if kind == "coordinates":
        panels = KINDS[kind](result, elements, euler=euler, mechanism=mechanism)
    else:
        panels = KINDS[kind](result, elements, mechanism=mechanism)
    if not panels:
        shown = ", ".join(elements or ["the result"])
        raise _EmptyKindError(f"plot kind '{kind}': nothing of {shown} to show in the {what} "
                              f"(kinds it can show: {choices})")
    if result.kind == "ocp" and kind == "efforts":
        _controls(result, panels, mechanism)
    for panel in panels:
        panel.kind = kind
    return panels


class _EmptyKindError(AnalysisError):
    """A kind with nothing to show for the selected elements (skipped when the kinds were
    not asked for by name: the default is every kind the result can show)."""


def _control_bounds(result, mechanism) -> dict[str, tuple[float, float]]:
    """The control bounds of an OCP solution: the ``[ocp.controls]`` table of its scene."""
    table = getattr(mechanism, "scene_data", {}).get("ocp") if mechanism is not None else None
    out = {}
    for name, pair in (dict(table or {}).get("controls") or {}).items():
        try:
            out[name] = (float(pair[0]), float(pair[1]))
        except (TypeError, ValueError, IndexError):
            continue  # an expression bound: not drawn
    return out


def _controls(result, panels, mechanism) -> None:
    """An OCP solution's controls: piecewise constant, named controls, bounds drawn."""
    bounds = _control_bounds(result, mechanism)
    for panel in panels:
        panel.ylabel = f"controls: {panel.ylabel}"
        panel.steps = True
        at: dict[float, list[str]] = {}
        for line in panel.lines:
            name = line.label.split(" ")[1] if " " in line.label else line.label
            line.label = f"control {name}"
            for value in bounds.get(name, ()):
                if math.isfinite(value) and name not in at.setdefault(value, []):
                    at[value].append(name)
        panel.bounds = [(f"bound of {', '.join(names)}", value) for value, names in at.items()]


def _rates(result, elements) -> list:
    """An OCP solution's joint rates (its states are q and q̇): [rad/s] and [m/s] panels."""
    if "joint_velocities" not in result.arrays or not result.names.get("joints"):
        return []
    columns = []
    units = joint_units(result, None)
    for k, name in enumerate(result.names["joints"]):
        if elements is None or name.partition(".")[0] in elements:
            columns.append((f"{name} rate", result.arrays["joint_velocities"][:, k],
                            f"{units[k]}/s", k, 1))
    panels = plot_panels.by_unit(columns, {"m/s": "joint rates", "rad/s": "joint rates"})
    for panel in panels:
        panel.kind = "joints"
    return panels


def _default_groups(result, elements, euler, mechanism) -> list[tuple[str, list]]:
    """(group, panels) of the default figure, in drawing order (:mod:`casmbd.viz.plot_select`
    keeps at most six)."""
    kinds = available_kinds(result)

    def of(kind):
        if kind not in kinds:
            return []
        try:
            return _panels(result, kind, elements, euler, mechanism)
        except _EmptyKindError:
            return []

    motion = of("joints") or of("coordinates")
    if not motion and elements:  # bodies selected by name, q of joint coordinates
        motion = plot_panels.bodies(result, elements, euler, mechanism)
        for panel in motion:
            panel.kind = "coordinates"
    if result.kind == "ocp":  # the states q and q̇, then the controls
        motion += _rates(result, elements)
        for panel in motion:
            panel.ylabel = f"states: {panel.ylabel}"
    flexible = of("flexible")
    modal = [p for p in flexible if p.unit != "m"]
    nodes = [p for p in flexible if p.unit == "m"]
    efforts, contacts = of("efforts"), of("contacts")
    undetermined = result.stats.get("undetermined_reactions")  # redundant: not the physics
    reactions = [] if (efforts or contacts or undetermined) else of("reactions")[:1]
    requests = plot_panels.requests(result, elements, mechanism)
    for panel in requests:
        panel.kind = "outputs"
    energy, drift = of("energy"), of("drift")
    return [("motion", motion), ("flexible_modal", modal), ("flexible_nodes", nodes),
            ("efforts", efforts), ("contacts", contacts), ("reactions", reactions),
            ("requests", requests), ("energy", energy[:1]), ("energy_change", energy[1:]),
            ("drift_position", drift[:1]), ("drift_velocity", drift[1:])]


def plot_result(result, kinds: str | Sequence[str] | None = None,
                out: str | os.PathLike | None = None, dpi: float = 100, title: str | None = None,
                *, elements: Sequence[str] | None = None, euler: str = "xyz", mechanism=None,
                limit: int = plot_select.MAX_PANELS):
    """Panels of a result against time, stacked with a shared time axis.

    Every kind is split into panels of one unit each (:mod:`casmbd.viz.plot_panels`), every
    y axis names its unit in brackets, every panel with more than one line has a legend
    (outside the axes beyond six lines).  Quaternions are not drawn: spatial bodies get their
    Euler angles; angles are continuous (unwrapped).  Empty panels, panels of rounding noise
    and duplicated panels are left out (:func:`casmbd.viz.plot_select.prune`) and said so in
    ``fig.casmbd_notes``.

    Parameters
    ----------
    result : Result
    kinds : str or sequence of str, optional
        From :data:`KINDS`; default the concise figure (:func:`casmbd.viz.plot_select.concise`:
        at most ``limit`` panels — the motion, the efforts, the change of the total energy and
        max |C| first, then a flexible body's modal coordinates and node deflections, the
        requests, contact forces, the energies and the velocity constraints).
    out : path, optional
        Save the figure there (atomically; format from the suffix).  Nothing is written when
        an error is raised.
    dpi : float
    title : str, optional
        Default: the analysis kind and the scene name when the result holds a scene.
    elements : sequence of str, optional
        Draw only the lines of these bodies, joints, drivers and actuators
        (:func:`element_names`).
    euler : {"xyz", "zxz"}
        Euler-angle sequence of spatial bodies (default ``"xyz"``, Cardan angles: regular at
        the identity, where most scenes start; ``"zxz"`` is singular there).
    mechanism : Mechanism, optional
        Gives the joint, driver and actuator units and the dissipative elements; default the
        scene embedded in the result (without either, joint units read "m or rad").
    limit : int
        Panels of the default figure at most (default 6).

    Returns
    -------
    matplotlib.figure.Figure
        With ``fig.casmbd_notes``: remarks (a singular Euler sequence, the panels left out and
        why), ``fig.casmbd_panels``: the y labels drawn, ``fig.casmbd_kinds``: the kinds drawn.

    Raises
    ------
    AnalysisError
        For an unknown kind, a kind the result cannot show (no joint coordinates, no
        efforts …), an unknown element or a selection leaving a kind empty — each naming the
        choices.
    """
    chosen = kinds is not None
    if isinstance(kinds, str):
        kinds = [kinds]
    kinds = list(kinds) if chosen else []
    unknown = [k for k in kinds if k not in KINDS]
    if unknown:
        raise AnalysisError(f"unknown plot kind(s) {', '.join(map(repr, unknown))} (choices: "
                            f"{', '.join(KINDS)}; this result can show "
                            f"{', '.join(available_kinds(result)) or 'none'})")
    if not (kinds or available_kinds(result)):
        raise AnalysisError(f"the {result.kind} result holds nothing to plot")
    if euler not in plot_panels.EULER_SEQUENCES:
        raise AnalysisError(f"unknown Euler sequence {euler!r} (choices: "
                            f"{', '.join(plot_panels.EULER_SEQUENCES)})")
    if elements is not None:
        elements = list(elements)
        known = element_names(result)
        bad = [e for e in elements if e not in known]
        if bad:
            raise AnalysisError(f"unknown element(s) {', '.join(map(repr, bad))} (choices: "
                                f"{', '.join(known) or 'none'})")
    mechanism = scene_mechanism(result, mechanism)
    notes: list[str] = []
    if chosen:
        panels = []
        for kind in kinds:  # a kind asked for by name must show something
            panels += _panels(result, kind, elements, euler, mechanism)
        panels, notes = plot_select.prune(result, panels, mechanism)
    else:
        groups = _default_groups(result, elements, euler, mechanism)
        everything = [p for _, group in groups for p in group]
        kept, notes = plot_select.prune(result, everything, mechanism)
        keep = {id(p) for p in kept}
        groups = [(g, [p for p in group if id(p) in keep]) for g, group in groups]
        panels, left = plot_select.concise(groups, limit)
        shown = {p.kind for p in panels}
        omitted = {p.kind for p in everything} - {p.kind for p in kept}  # empty, noise
        more = list(dict.fromkeys([*(p.kind for p in left),
                                   *(k for k in available_kinds(result)
                                     if k not in shown and k not in omitted)]))
        if left:
            notes.append(f"not drawn by default (at most {limit} panels): "
                         + ", ".join(p.ylabel for p in left))
        if more:
            notes.append("more with --what: " + ", ".join(more))
    if not panels:
        what = f" of {', '.join(kinds)}" if kinds else ""
        which = f" for {', '.join(elements)}" if elements else ""
        raise AnalysisError(f"the {result.kind} result has nothing to draw{what}{which}"
                            + (f": {'; '.join(notes)}" if notes else ""))
    wide = any(len(p.lines) > 6 for p in panels)
    fig, axes = new_figure(len(panels), 1, figsize=(8.4 if wide else 6.4,
                                                    1.0 + 1.9 * len(panels)), sharex=True)
    axes = np.atleast_1d(axes)
    for panel, ax in zip(panels, axes):
        _draw_panel(ax, result.t, panel)
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[-1].set_xlabel("t [s]")
    if title is None:
        name = scene_name(result)
        title = f"{name}: {result.kind}" if name else result.kind
    fig.suptitle(title, fontsize=10)
    fig.casmbd_notes = [p.note for p in panels if p.note and "singular" in p.note] + notes
    fig.casmbd_panels = [p.ylabel for p in panels]
    fig.casmbd_kinds = list(dict.fromkeys(p.kind for p in panels))
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
    """Rows of a CSV file with a header line (values as strings); the file must be a regular
    file of at most :data:`~casmbd.limits.MAX_SCENE_BYTES` (:func:`~casmbd.limits.read_bounded`).
    """
    data = read_bounded(path, "CSV", MAX_SCENE_BYTES, AnalysisError)
    try:
        return list(csv.DictReader(io.StringIO(data.decode("utf-8"), newline="")))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise AnalysisError(f"cannot read '{path}': {exc}") from None


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
