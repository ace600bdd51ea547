"""The panels of :func:`casmbd.viz.plots.plot_result`: one quantity group with one unit each.

Every plot kind is split into panels whose lines share a unit, so that every y axis carries
one (``positions [m]``, ``angles [rad]``, ``forces [N]``, ``torques [N m]`` …):

* ``coordinates`` — positions [m] and angle coordinates [rad] of q; Euler parameters and the
  unit-vector components of natural coordinates are not drawn: in space each body's Euler
  angles (sequence ``euler``) take their place, in the plane the body angle;
* ``joints`` — joint translations [m] and joint angles [rad];
* ``efforts`` — driver and actuator forces [N] and torques [N m];
* ``reactions`` — joint reaction forces [N] and moments [N m];
* ``energy`` — kinetic, potential and total energy [J], then total − total(0) [J], labelled
  numerical drift only for a conservative mechanism (else the work of the named dampers,
  drivers, actuators and forces, :func:`casmbd.viz.column_units.energy_change_label`);
* ``drift`` — max |C| and max |C_q v + C_t| (log scale; mixed units of the equations);
* ``outputs`` — the requests (``[[outputs]]``, by their ``unit``) and what every force element
  reports (a spring's length [m], rate [m/s] and force [N], …), one panel per unit named by
  its lines (``tip_height [m]``);
* ``flexible`` — a flexible body's modal coordinates η [kg^½ m] and node deflections [m];
* ``contacts`` — contact and joint-limit forces [N].

Angles are drawn continuous: the result's joint angles are unwrapped already
(:meth:`casmbd.compiled.model.NumericModel.outputs`), Euler angles are unwrapped here.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import AnalysisError
from casmbd.viz.column_units import coordinate_unit, effort_units, energy_change_label, joint_units

#: Euler-angle sequences offered (:meth:`casmbd.results.Result.euler_angles`)
EULER_SEQUENCES = ("xyz", "zxz")
_EULER_NAMES = ("phi", "theta", "psi")
_QUANTITY = {"m": "positions", "rad": "angles"}


@dataclass
class Line:
    """One series: legend label, values on the result's grid, element index (colour) and
    component index (line style)."""

    label: str
    y: np.ndarray
    element: int = 0
    component: int = 0


@dataclass
class Panel:
    """One axes: y label (with the unit in brackets), lines, log scale, a note drawn inside.

    ``unit`` is the unit of every line (for the noise test of
    :func:`casmbd.viz.plot_select.noise`), ``health`` marks a panel whose small values are the
    message (max |C|, the change of the total energy: never dropped as noise), ``bounds`` are
    horizontal lines ``(label, value)`` (an OCP's control bounds) and ``steps`` draws the
    lines piecewise constant (controls per interval)."""

    ylabel: str
    lines: list[Line] = field(default_factory=list)
    log: bool = False
    note: str = ""
    unit: str = ""
    health: bool = False
    bounds: list[tuple[str, float]] = field(default_factory=list)
    steps: bool = False
    kind: str = ""


def _selected(name: str, elements) -> bool:
    return elements is None or name in elements


def by_unit(columns, what: dict[str, str]) -> list[Panel]:
    """Group ``(label, y, unit, element, component)`` by unit, panels in order of appearance;
    ``what`` names the quantity of each unit (``{"m": "joint translations", …}``)."""
    panels: dict[str, Panel] = {}
    for label, y, unit, element, component in columns:
        if unit not in panels:
            panels[unit] = Panel(f"{what.get(unit, 'values')} [{unit}]", unit=unit)
        panels[unit].lines.append(Line(label, y, element, component))
    return list(panels.values())


def _named(panels: list[Panel], longest: int = 40) -> list[Panel]:
    """Name each panel by its lines (``tip_height [m]``, ``tie.length, brace.length [m]``)
    when the names fit in ``longest`` characters; else keep the quantity name and the legend."""
    for panel in panels:
        names = ", ".join(line.label for line in panel.lines)
        if len(panel.lines) <= 3 and len(names) <= longest:
            panel.ylabel = f"{names} [{panel.unit}]"
    return panels


def _element_index():
    """A function giving each element name a colour index, in order of first appearance."""
    index: dict[str, int] = {}
    return lambda name: index.setdefault(name, len(index))


def coordinates(result, elements=None, euler: str = "xyz", mechanism=None) -> list[Panel]:
    """Positions [m] and angles [rad] of q; Euler angles of spatial bodies instead of
    quaternions (or natural coordinates' unit vectors), body angles for planar natural
    coordinates."""
    q = result.arrays["q"]
    names = result.names.get("coordinates") or [f"q{k}" for k in range(q.shape[1])]
    colour = _element_index()
    columns, unitless = [], []
    for k, name in enumerate(names):
        prefix, _, coord = name.rpartition(".")
        if not _selected(prefix or name, elements):
            continue
        unit = coordinate_unit(name)
        if coord.startswith("eta") and coord[3:].isdigit():
            continue  # a flexible body's modal coordinate: the ``flexible`` kind draws it
        if unit == "-":
            if prefix not in unitless:
                unitless.append(prefix)
            continue
        columns.append((name, q[:, k], unit, colour(prefix), max("xyz".find(coord), 0)))
    panels = by_unit(columns, {"m": "positions", "rad": "angles"})
    bodies = [b for b in result.names.get("bodies", []) if _selected(b, elements)]
    if result.dimension == 3 and "rotation_matrices" in result.arrays and bodies:
        panels.append(euler_panel(result, bodies, euler))
    elif unitless and "angle_positions" in result.arrays:  # planar natural coordinates
        all_bodies = result.names.get("bodies", [])
        angle = next((p for p in panels if p.ylabel.startswith("angles")), None)
        if angle is None:
            angle = Panel("angles [rad]", unit="rad")
            panels.append(angle)
        for body in unitless:
            if body in all_bodies and f"{body}.angle" not in names:
                y = np.unwrap(result.arrays["angle_positions"][:, all_bodies.index(body)])
                angle.lines.append(Line(f"{body}.angle", y, colour(body), 0))
    return panels


def bodies(result, elements=None, euler: str = "xyz", mechanism=None) -> list[Panel]:
    """The selected bodies' centre positions [m] and angles [rad] (planar angle, or Euler
    angles in space) from the body outputs: the motion of a body selected by name when q
    holds joint coordinates."""
    names = [b for b in result.names.get("bodies", []) if _selected(b, elements)]
    if not names or elements is None or "body_positions" not in result.arrays:
        return []
    columns = []
    for i, body in enumerate(names):
        frame = result.body(body)
        for c in range(result.dimension):
            columns.append((f"{body}.{'xyz'[c]}", frame["position"][:, c], "m", i, c))
        if result.dimension == 2 and "angle" in frame:
            columns.append((f"{body}.angle", np.unwrap(frame["angle"]), "rad", i, 0))
    panels = by_unit(columns, {"m": "positions", "rad": "angles"})
    if result.dimension == 3 and "rotation_matrices" in result.arrays:
        panels.append(euler_panel(result, names, euler))
    return panels


def euler_panel(result, bodies: list[str], sequence: str) -> Panel:
    """Euler angles (unwrapped) of spatial bodies; a singular pass is named in the panel."""
    if sequence not in EULER_SEQUENCES:
        raise AnalysisError(f"unknown Euler sequence {sequence!r} (choices: "
                            f"{', '.join(EULER_SEQUENCES)})")
    panel = Panel(f"Euler angles {sequence.upper()} [rad]", unit="rad")
    singular = []
    for i, body in enumerate(bodies):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            angles = np.unwrap(result.euler_angles(body, sequence), axis=0)
        if caught:
            singular.append(body)
        for c, label in enumerate(_EULER_NAMES):
            panel.lines.append(Line(f"{body}.{label}", angles[:, c], i, c))
    if singular:
        other = next(s for s in EULER_SEQUENCES if s != sequence)
        panel.note = (f"{sequence.upper()} singular for {', '.join(singular)} (phi, psi split "
                      f"arbitrarily there; the {other} sequence is regular there)")
    return panel


def joints(result, elements=None, mechanism=None) -> list[Panel]:
    """Joint translations [m] and joint angles [rad]."""
    c = result.arrays["joint_positions"]
    names = result.names.get("joints", [])
    units = joint_units(result, mechanism)
    colour = _element_index()
    columns = [(name, c[:, k], units[k], colour(name.partition(".")[0]), 0)
               for k, name in enumerate(names) if _selected(name.partition(".")[0], elements)]
    return by_unit(columns, {"m": "joint translations", "rad": "joint angles",
                              "m or rad": "joint coordinates"})


def efforts(result, elements=None, mechanism=None) -> list[Panel]:
    """Driver and actuator efforts (or inputs when the efforts were not computed): forces [N]
    and torques [N m]."""
    columns = []
    n = 0
    for key, group in (("driver_efforts", "drivers"), ("actuator_efforts", "actuators"),
                       ("actuator_inputs", "actuators")):
        if key not in result.arrays or (key == "actuator_inputs"
                                        and "actuator_efforts" in result.arrays):
            continue
        units = effort_units(result, group, mechanism)
        what = " input" if key == "actuator_inputs" else ""
        for k, name in enumerate(result.names.get(group, [])):
            if _selected(name, elements):
                columns.append((f"{group[:-1]} {name}{what}", result.arrays[key][:, k],
                                units[k], n, 0))
            n += 1
    return by_unit(columns, {"N": "forces", "N m": "torques", "N or N m": "efforts"})


def reactions(result, elements=None, mechanism=None) -> list[Panel]:
    """Joint reaction forces [N] and moments [N m], one colour per joint."""
    lam = result.arrays["joint_reactions"]
    labels = ("Fx", "Fy", "M") if lam.shape[2] == 3 else ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
    forces = Panel("reaction forces [N]", unit="N")
    moments = Panel("reaction moments [N m]", unit="N m")
    for j, name in enumerate(result.names.get("all_joints", [])):
        if not _selected(name, elements):
            continue
        for c, label in enumerate(labels):
            panel = forces if label.startswith("F") else moments
            panel.lines.append(Line(f"{name}.{label}", lam[:, j, c], j, c % 3))
    undetermined = result.stats.get("undetermined_reactions") or {}
    shown = [j for j in undetermined if _selected(j, elements)]
    if shown:  # redundant constraints: one distribution of many (flag_undetermined)
        forces.note = (f"minimum-norm distribution: undetermined at {', '.join(shown[:4])}"
                       + (" …" if len(shown) > 4 else ""))
    return [p for p in (forces, moments) if p.lines]


def energy(result, elements=None, mechanism=None) -> list[Panel]:
    """Kinetic, potential and total energy [J]; then total − total(0) [J], named drift only
    for a conservative mechanism (else the work, friction work and impact losses that change
    it, :func:`casmbd.viz.column_units.energy_change_label`)."""
    total = result.arrays["total_energy"]
    first = Panel("energy [J]", [Line(key, result.arrays[f"{key}_energy"], k, 0)
                                 for k, key in enumerate(("kinetic", "potential", "total"))],
                  unit="J")
    label, drift = energy_change_label(result, mechanism)
    second = Panel("total − total(0) [J]", [Line(label, total - total[0], 3, 0)], unit="J",
                   health=True)
    if not drift:
        second.note = "physical: work done on or by the mechanism, not a conservation error"
    return [first, second]


def drift(result, elements=None, mechanism=None) -> list[Panel]:
    """Constraint violation per output time (log scale; exact zeros are left out: a panel
    that is zero at every output time is empty, :func:`casmbd.viz.plot_select.empty`)."""
    panels = [Panel("max |C| [m, rad or 1]", [Line("position max|C|",
                                                  result.arrays["constraint_violation"])],
                    log=True, health=True)]
    if "velocity_violation" in result.arrays:
        panels.append(Panel("max |C_q v + C_t| [m/s, rad/s or 1/s]",
                            [Line("velocity max|C_q v + C_t|",
                                  result.arrays["velocity_violation"])], log=True,
                            health=True))
    loops = "constraints" not in result.names or bool(result.names["constraints"])
    for panel in panels:
        values = panel.lines[0].y
        panel.lines[0].y = np.where(values > 0, values, np.nan)
        if not np.any(values > 0):
            panel.note = "zero at every output time" + ("" if loops else
                                                        ": no constraint equations")
    return panels


#: quantity names of the units of requests and force reports (a panel of more lines than fit
#: in its y label keeps these and a legend)
_OUTPUT_QUANTITIES = {"m": "lengths", "m/s": "rates", "rad": "angles", "rad/s": "angular rates",
                      "N": "forces", "N m": "torques", "J": "energies", "W": "powers",
                      "-": "values"}


def outputs(result, elements=None, mechanism=None) -> list[Panel]:
    """Requests (``[[outputs]]``) and force-element reports (``force_outputs``:
    ``element.quantity``), each group in panels of one unit named by the lines themselves
    (``tip_height [m]``; more than fit: ``lengths [m]`` with a legend); ``elements`` selects
    requests and force elements by name."""
    return requests(result, elements, mechanism) + force_reports(result, elements, mechanism)


def requests(result, elements=None, mechanism=None) -> list[Panel]:
    """The ``[[outputs]]`` requests under their own names and units."""
    return _output_panels(result, "outputs", "output_units", elements)


def force_reports(result, elements=None, mechanism=None) -> list[Panel]:
    """What every force element reports (a spring's length, rate and force …)."""
    return _output_panels(result, "force_outputs", "force_output_units", elements)


def _output_panels(result, key: str, units_key: str, elements) -> list[Panel]:
    if key not in result.arrays:
        return []
    columns = []
    colour = _element_index()
    names = result.names.get(key, [])
    units = result.names.get(units_key) or ["-"] * len(names)
    for k, (label, unit) in enumerate(zip(names, units, strict=True)):
        element = label.rpartition(".")[0] if key == "force_outputs" else label
        if _selected(element, elements):
            y = result.arrays[key][:, k]
            columns.append((label, y, unit, colour(element), 0))
    return _named(by_unit(columns, _OUTPUT_QUANTITIES))


def flexible(result, elements=None, mechanism=None) -> list[Panel]:
    """A flexible body's modal coordinates η [kg^½ m] (mass-normalised modes,
    :mod:`casmbd.model.modal`) and its named nodes' deflections Φ_i η [m] in body axes."""
    panels = []
    names = result.names.get("coordinates", [])
    modal = Panel("modal coordinates η [kg^½ m]", unit="kg^½ m")
    colour = _element_index()
    for k, name in enumerate(names):
        body, _, coord = name.rpartition(".")
        if coord.startswith("eta") and coord[3:].isdigit() and _selected(body, elements):
            modal.lines.append(Line(name, result.arrays["q"][:, k], colour(body),
                                    int(coord[3:]) - 1))
    if modal.lines:
        panels.append(modal)
    if "node_deflections" in result.arrays:
        dim = result.dimension
        deflections = Panel("node deflections Φ_i η [m]", unit="m")
        colour = _element_index()
        for i, node in enumerate(result.names.get("nodes", [])):
            if not _selected(node.partition("@")[0], elements):
                continue
            for c in range(dim):
                deflections.lines.append(Line(f"{node}.{'xyz'[c]}",
                                              result.arrays["node_deflections"][:, dim * i + c],
                                              colour(node), c))
        if deflections.lines:
            panels.append(deflections)
    return panels


def contacts(result, elements=None, mechanism=None) -> list[Panel]:
    """Normal (and friction) forces [N] of the contacts and joint limits."""
    forces = result.arrays["contact_forces"]
    panel = Panel("contact forces [N]", unit="N")
    seen: list[str] = []
    colour = _element_index()
    for k, name in enumerate(result.names.get("contacts", [])):
        if _selected(name, elements) and k < forces.shape[1]:
            label = f"{name} friction" if name in seen else f"{name} normal"
            panel.lines.append(Line(label, forces[:, k], colour(name), int(name in seen)))
        seen.append(name)
    impacts = sum(e.get("kind") in ("impact", "limit") for e in result.events or [])
    if impacts:  # an impact's impulse is an event, not a force on the grid
        panel.note = (f"impacts are impulses at events ({impacts} here), not forces on the "
                      "output grid")
    return [panel] if panel.lines else []
