"""Units and physical meaning of a result's columns, for plot labels and CLI printouts.

A :class:`~casmbd.results.Result` stores names, not units; the units follow from the kind of
each coordinate (a position in m, an angle in rad, an Euler parameter or unit-vector component
without unit) and of each joint coordinate, driver and actuator (a translation in m and a force
in N, or an angle in rad and a torque in N m).  Joint kinds come from the mechanism: the one
passed in, else the scene embedded in the result (:meth:`Result.mechanism`); without either the
unit of a joint quantity is unknown and reads ``"m or rad"`` / ``"N or N m"``.
"""

from __future__ import annotations

import numpy as np

from casmbd.analysis.integrators.invariants import force_exchange
from casmbd.errors import CasmbdError
from casmbd.io.scene import loads_scene

#: unit of a coordinate by the suffix of its name (``body.x``, ``joint.angle`` …)
_COORDINATE_UNITS = {"x": "m", "y": "m", "z": "m", "translation": "m", "length": "m",
                     "angle": "rad", "angle1": "rad", "angle2": "rad",
                     "orientation": "rad"}  # a body's orientation driver: its effort in N m
#: the effort conjugate to a coordinate of this unit
EFFORT_UNIT = {"m": "N", "rad": "N m", "m or rad": "N or N m"}


def coordinate_unit(name: str) -> str:
    """Unit of a generalized coordinate from its name: ``"m"``, ``"rad"`` or ``"-"`` (Euler
    parameters ``e0``…``e3`` and natural coordinates' unit-vector components)."""
    return _COORDINATE_UNITS.get(name.rpartition(".")[2], "-")


def scene_mechanism(result, mechanism=None):
    """``mechanism``, else the mechanism of the scene embedded in ``result``, else None (a
    result built in Python from a mechanism without scene text)."""
    if mechanism is not None or not getattr(result, "scene", ""):
        return mechanism
    try:
        return result.mechanism(loads_scene)
    except CasmbdError:  # an embedded scene that no longer loads: units stay unknown
        return None


def joint_coordinate_unit(mech, joint: str, coordinate: str | None = None) -> str:
    """Unit of a joint's coordinate (its first when ``coordinate`` is None): "m", "rad", or
    "m or rad" when the mechanism or the joint is unknown."""
    obj = None if mech is None else mech.joints.get(joint)
    names = getattr(obj, "coordinate_names", ())
    if not names:
        return "m or rad"
    return _COORDINATE_UNITS.get(coordinate or names[0], "m or rad")


def joint_units(result, mechanism=None) -> list[str]:
    """Unit of each column of ``joint_positions`` (``names["joints"]``)."""
    mech = scene_mechanism(result, mechanism)
    out = []
    for column in result.names.get("joints", []):
        joint, _, coord = column.partition(".")
        out.append(joint_coordinate_unit(mech, joint, coord or None))
    return out


def effort_units(result, group: str, mechanism=None) -> list[str]:
    """Unit of the effort of each driver (``group="drivers"``) or actuator (``"actuators"``):
    N along a length, N m about an angle."""
    mech = scene_mechanism(result, mechanism)
    out = []
    for name in result.names.get(group, []):
        elements = None if mech is None else getattr(mech, group, {})
        obj = None if elements is None else elements.get(name)
        if obj is None:
            out.append("N or N m")
        elif getattr(obj, "joint", None):
            out.append(EFFORT_UNIT[joint_coordinate_unit(mech, obj.joint, obj.coordinate)])
        else:  # a driver of a body coordinate
            out.append(EFFORT_UNIT[_COORDINATE_UNITS.get(obj.coordinate, "m or rad")])
    return out


def energy_exchange(result, mechanism=None) -> list[str] | None:
    """Elements through which the mechanism's total energy T + V may change physically:
    dampers (``damping`` ≠ 0, ``"damper 'd'"``), drivers (rheonomic constraints), actuators
    with a non-zero input, and applied forces or torques that are not in V (point forces,
    torques, user forces).  An empty list: the mechanism is conservative and any change of
    T + V is numerical drift.  None: unknown (no mechanism and no embedded scene; only the
    drivers and actuators named in the result were seen).
    """
    mech = scene_mechanism(result, mechanism)
    out = [f"driver '{d}'" for d in result.names.get("drivers", [])]
    inputs = result.arrays.get("actuator_inputs")
    for k, name in enumerate(result.names.get("actuators", [])):
        if inputs is None or k >= inputs.shape[1] or (inputs[:, k] != 0).any():
            out.append(f"actuator '{name}'")
    if mech is None:
        return out or None
    parameters = dict(getattr(mech, "parameters", {}) or {})
    for name, force in mech.forces.items():
        exchange = force_exchange(force, parameters)  # each kind says how it does work
        if exchange is not None:
            out.append(f"{exchange} '{name}'")
    return out


def _restitution(contact, parameters) -> float | None:
    try:
        return float(contact.restitution_value(parameters))
    except (CasmbdError, AttributeError, TypeError, ValueError):
        return None


def energy_terms(result, mechanism=None) -> list[str] | None:
    """What changes the total energy T + V physically, each as the phrase of a label:
    ``"work of driver 'm'"``, ``"work of damper 'd'"``, ``"friction work of 'A.friction'"``,
    ``"friction work at contact 'c'"``, ``"impact losses at contact 'floor' (3 impacts,
    restitution 0.8)"``, ``"modal damping of body 'beam'"`` … ([]: conservative, any change is
    numerical drift; None: unknown, no mechanism).

    Impacts lose ½ (1 − e²) of the normal approach energy (Newton's law with restitution e <
    1), frictional contacts and joint friction dissipate; none of it is a drift.
    """
    mech = scene_mechanism(result, mechanism)
    impacts: dict[str, int] = {}
    for event in getattr(result, "events", []) or []:
        if event.get("kind") in ("impact", "limit"):
            impacts[event.get("element", "?")] = impacts.get(event.get("element", "?"), 0) + 1
    base = energy_exchange(result, mech)
    if mech is None:
        if base is None and not impacts:
            return None
        return [*(f"work of {e}" for e in base or []),
                *(f"impact losses at '{c}' ({n} impacts)" for c, n in impacts.items())]
    out = [f"work of {e}" for e in base if e.startswith(("driver ", "actuator "))]
    parameters = dict(getattr(mech, "parameters", {}) or {})
    for name, force in mech.forces.items():
        exchange = force_exchange(force, parameters)
        if exchange is None:
            continue
        if type(force).__name__ == "JointFriction":
            out.append(f"friction work of '{name}'")
        elif type(force).__name__ == "CompliantContact":
            out.append(f"impact losses and friction of compliant contact '{name}'")
        else:
            out.append(f"work of {exchange} '{name}'")
    parameters = dict(getattr(mech, "parameters", {}) or {})
    for name, contact in getattr(mech, "contacts", {}).items():
        e = _restitution(contact, parameters)
        count = impacts.get(name, 0)
        if count and (e is None or e < 1.0):
            where = "joint limit" if type(contact).__name__ == "JointLimit" else "contact"
            out.append(f"impact losses at {where} '{name}' ({count} impact"
                       + "s" * (count > 1) + (f", restitution {e:g})" if e is not None else ")"))
        if getattr(contact, "friction", 0.0):
            out.append(f"friction work at contact '{name}'")
    for name, body in getattr(mech, "bodies", {}).items():
        ratio = getattr(body, "damping_ratio", 0.0)
        try:
            damped = bool(np.any(np.asarray(ratio, dtype=float) != 0.0))
        except (TypeError, ValueError):
            damped = True
        if damped:
            out.append(f"modal damping of body '{name}'")
    return out


def energy_change_label(result, mechanism=None) -> tuple[str, bool]:
    """A short label of total − total(0) and whether it is numerical drift.

    ``("drift of the total", True)`` for a conservative mechanism; ``("energy change: work of
    damper 'd', driver 'm' (not a drift)", False)`` when something does work, ``"energy
    change: impact losses at contact 'floor' (…) (not a drift)"`` when impacts dissipate,
    ``"… friction work of 'A.friction' …"`` for friction — so that dissipation is not called
    a drift (:func:`energy_terms`); ``("change of the total", False)`` when this cannot be
    told.
    """
    terms = energy_terms(result, mechanism)
    if terms == []:
        return "drift of the total", True
    if terms is None:
        return "change of the total (drift only if nothing does work)", False
    shown = "; ".join(terms[:3]) + (f" and {len(terms) - 3} more" if len(terms) > 3 else "")
    return f"energy change: {shown} (not a drift)", False
