"""Which panels a figure shows: the concise default, and the panels left out with a reason.

:func:`casmbd.viz.plots.plot_result` builds every panel of the kinds asked for
(:mod:`casmbd.viz.plot_panels`) and hands them here:

* **empty** panels — every value NaN (reactions of a run that does not compute them) or a
  log panel that is zero at every output time (max |C| of an inverse run, of a mechanism without
  constraints) — are omitted and the reason given (:func:`empty`);
* **noise** panels — every value at or below ``NOISE`` × the problem's scale of the panel's unit
  (:func:`scales`) — are omitted and named on one line: a planar revolute's reaction moment of
  1e-15 N m beside forces of 10 N, a planar body's z of 1e-24 m.  The scale of a unit class is
  the largest magnitude the result holds in that class, raised to the physical scale of the
  mechanism: L the largest distance of a body, marker or node from the origin, M g the
  weight (M the total mass, g = |gravity|), M g L for moments and energies, L/T and 1/T for
  rates (T the duration); a moment is also measured against the largest force × L and a force
  against the largest moment / L.  Health panels (max |C|, the change of the total energy:
  their small values are the message) are never dropped as noise;
* **duplicated** panels — every line equal to a line of an earlier panel of the same unit (the
  joint coordinates of a scene in joint coordinates are its q) — are omitted
  (:func:`duplicates`); a legend label drawn twice in one panel is drawn once.

The default figure (:func:`concise`) keeps at most :data:`MAX_PANELS` of the remaining panels in
priority order: the motion, the efforts, the change of the total energy and max |C| first, then
a flexible body's modal coordinates, the requests, the node deflections, contact forces, the
energies and max |C_q v + C_t|; the rest is drawn by ``--what``.
"""

from __future__ import annotations

import numpy as np

from casmbd.errors import CasmbdError
from casmbd.model.values import numeric

#: relative threshold of rounding noise: a panel whose values are all at most NOISE × the
#: scale of its unit is noise (1e-9: far above double rounding, 1e-16 relative, and far below
#: anything a mechanism shows: a 1 m mechanism's 1 nm)
NOISE = 1e-9
#: panels of the default figure at most
MAX_PANELS = 6

_FORCE, _MOMENT = ("N",), ("N m",)


def _max_abs(y) -> float:
    y = np.asarray(y, dtype=float)
    finite = y[np.isfinite(y)]
    return float(np.max(np.abs(finite))) if finite.size else 0.0


def _positions_scale(result) -> float:
    values = [_max_abs(result.arrays[k]) for k in ("body_positions", "marker_positions",
                                                   "node_positions") if k in result.arrays]
    return max(values, default=0.0)


def _weight(result, mechanism) -> float:
    """M g of the mechanism (0 when it is not known or has no gravity)."""
    if mechanism is None:
        return 0.0
    g = float(np.linalg.norm(np.asarray(getattr(mechanism, "gravity", [0.0]), dtype=float)))
    mass = 0.0
    params = dict(getattr(mechanism, "parameters", {}) or {})
    for name, body in getattr(mechanism, "bodies", {}).items():
        try:
            mass += abs(numeric(body.mass, params, f"body '{name}' mass"))
        except (CasmbdError, AttributeError, TypeError, ValueError):
            continue
    return mass * g


def scales(result, panels, mechanism=None) -> dict[str, float]:
    """The scale of every unit of ``panels`` (module docstring); 0 where none is known."""
    by_unit: dict[str, float] = {}
    for panel in panels:
        for line in panel.lines:
            by_unit[panel.unit] = max(by_unit.get(panel.unit, 0.0), _max_abs(line.y))
    length = max(_positions_scale(result), by_unit.get("m", 0.0))
    duration = float(result.t[-1] - result.t[0]) if len(result.t) > 1 else 0.0
    weight = _weight(result, mechanism)
    force = max(by_unit.get("N", 0.0), weight)
    moment = max(by_unit.get("N m", 0.0), weight * length)
    if length > 0:
        force = max(force, moment / length)
        moment = max(moment, force * length)
    physical = {"m": length, "rad": 1.0, "N": force, "N m": moment,
                "J": max(weight * length, moment),
                "m/s": length / duration if duration else 0.0,
                "rad/s": 1.0 / duration if duration else 0.0}
    return {unit: max(value, physical.get(unit, 0.0)) for unit, value in by_unit.items()}


def empty(panel) -> str | None:
    """Why a panel has nothing to draw (None: it has)."""
    if not panel.lines:
        return "no lines"
    values = [np.asarray(line.y, dtype=float) for line in panel.lines]
    if not any(np.isfinite(y).any() for y in values):
        return panel.note if panel.note.startswith("zero") else \
            "not a number at every output time (not computed by this analysis)"
    return None


def noise(panel, scale: float) -> float | None:
    """The panel's largest magnitude when it is rounding noise at ``scale`` (None: it is not,
    or the panel is a health panel, or no scale is known)."""
    if panel.health or panel.log:
        return None
    peak = max(_max_abs(line.y) for line in panel.lines)
    if peak == 0.0:
        return 0.0  # exactly zero everywhere
    if scale > 0 and peak <= NOISE * scale:
        return peak
    return None


def dedupe_lines(panel) -> None:
    """Draw a label once: a line equal to an earlier line of the same label is left out; a
    different line of the same label is numbered (``beam.angle (2)``)."""
    kept, seen = [], {}
    for line in panel.lines:
        earlier = seen.get(line.label)
        if earlier is not None:
            if np.array_equal(np.asarray(earlier.y), np.asarray(line.y), equal_nan=True):
                continue
            line.label = f"{line.label} ({sum(1 for k in kept if k.label == line.label) + 1})"
        seen.setdefault(line.label, line)
        kept.append(line)
    panel.lines = kept


def duplicates(panels) -> list[tuple[object, object]]:
    """(panel, earlier panel) for every panel each of whose lines equals a line of an earlier
    panel of the same unit."""
    out = []
    for k, panel in enumerate(panels):
        for earlier in panels[:k]:
            if earlier.unit != panel.unit or not panel.unit or panel.health:
                continue
            if all(any(np.array_equal(np.asarray(line.y), np.asarray(other.y), equal_nan=True)
                       for other in earlier.lines) for line in panel.lines):
                out.append((panel, earlier))
                break
    return out


def _short(ylabel: str) -> str:
    return ylabel.rpartition(" [")[0] or ylabel


def prune(result, panels, mechanism=None) -> tuple[list, list[str]]:
    """The panels with something to show, and at most three lines saying what was left out:
    empty panels (with the reason), panels of rounding noise (their largest value and the
    scale), duplicated panels."""
    for panel in panels:
        dedupe_lines(panel)
    notes, kept, blank = [], [], []
    for panel in panels:
        why = empty(panel)
        if why:
            blank.append(f"{_short(panel.ylabel)} ({why})")
        else:
            kept.append(panel)
    scale = scales(result, kept, mechanism)
    shown, quiet = [], []
    for panel in kept:
        peak = noise(panel, scale.get(panel.unit, 0.0))
        if peak is None:
            shown.append(panel)
        elif peak == 0.0:
            why = f"; {panel.note}" if panel.note else ""
            blank.append(f"{_short(panel.ylabel)} (zero at every output time{why})")
        else:
            quiet.append(f"{_short(panel.ylabel)} (max {peak:.2g} {panel.unit} against "
                         f"{scale.get(panel.unit, 0.0):.3g} {panel.unit})")
    twins = duplicates(shown)
    for panel, _ in twins:
        shown.remove(panel)
    if blank:
        notes.append(f"omitted {len(blank)} empty panel{'s' * (len(blank) > 1)}: "
                     + "; ".join(blank))
    if quiet:
        notes.append(f"omitted {len(quiet)} panel{'s' * (len(quiet) > 1)} of rounding noise "
                     f"(every value ≤ {NOISE:g} × the problem's scale of its unit): "
                     + "; ".join(quiet))
    if twins:
        notes.append("omitted duplicated panels: " + "; ".join(
            f"{_short(p.ylabel)} (same lines as {_short(e.ylabel)})" for p, e in twins))
    return shown, notes


#: default panel groups by priority: (kind, panel index within the kind or None for all,
#: rank); lower ranks are kept first, the figure keeps the order of :func:`concise`'s input
_RANKS = {"motion": (0, 1, 2), "efforts": (0, 2), "energy_change": (0,), "drift_position": (0,),
          "flexible_modal": (1,), "requests": (1, 3, 3), "flexible_nodes": (2,),
          "contacts": (2,), "reactions": (3,), "energy": (4,), "drift_velocity": (4,)}


def concise(groups: list[tuple[str, list]], limit: int = MAX_PANELS) -> tuple[list, list]:
    """The panels of the default figure: ``groups`` are ``(group, panels)`` in the order to
    draw; each group's panels get the ranks of :data:`_RANKS` (the last rank repeats), the
    ``limit`` lowest-ranked are kept in drawing order.  Returns (kept, left out)."""
    ranked = []
    for order, (group, panels) in enumerate(groups):
        ranks = _RANKS.get(group, (5,))
        for k, panel in enumerate(panels):
            ranked.append((ranks[min(k, len(ranks) - 1)], order, k, panel))
    chosen = sorted(ranked, key=lambda r: (r[0], r[1], r[2]))[:limit]
    keep = {id(r[3]) for r in chosen}
    kept = [r[3] for r in sorted(ranked, key=lambda r: (r[1], r[2])) if id(r[3]) in keep]
    left = [r[3] for r in sorted(ranked, key=lambda r: (r[1], r[2])) if id(r[3]) not in keep]
    return kept, left
