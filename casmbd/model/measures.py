"""Measures of a mechanism's state in scene expressions, and requests (``[[outputs]]``).

A *measure* is a named scalar of the state (q, v) and time, written in an expression as a call
with quoted names, like Adams' function expressions (DX, VR, AZ, …):

==========================  ==================================================================
``angle("J")``              the angle coordinate of joint J (revolute, cylindrical, planar)
``translation("J")``        the translation coordinate of joint J (prismatic, cylindrical)
``coordinate("J")``         J's first coordinate; ``coordinate("J.angle")`` a named one
``rate("J")``               the time derivative of ``coordinate("J")`` (``rate("J.angle")``)
``x("P")``, ``y``, ``z``    global position of P: a marker (a flexible-body node
                            ``"beam@tip"`` is one), a body's centre of mass, or ``"ground"``
``vx("P")``, ``vy``, ``vz`` global velocity components of P
``speed("P")``              |v_P|
``distance("A", "B")``      |r_B − r_A|
``angle_of("B")``           planar angle of body B (or of marker B's frame)
``omega_of("B")``           its rate, the planar angular velocity
``wx("B")``, ``wy``, ``wz``   global components of the angular velocity of body B (of marker
                            B's body); ``wz`` alone in the plane (= ``omega_of``)
``t``, ``time``             time
==========================  ==================================================================

The smooth helpers ``step(x, x0, h0, x1, h1)`` (Adams' cubic STEP), ``smooth_sign(x, eps)``
= tanh(x/eps) and ``dead_zone(x, lo, hi)`` are usable in every expression
(:data:`casmbd.model.expression_rules.HELPER_FUNCTIONS`).

The model layer keeps the text and checks it here when an element is added (:func:`check`:
the same whitelist parser, every quoted name resolved against the mechanism's joints, markers
and bodies into a :class:`MeasureRef`); the system layer (:mod:`casmbd.system.requests`) turns
the references into CasADi expressions of (q, v, t, p) with its context.  A measure anywhere
else — a driver position, the value of a force of another kind — is refused by name by the
parser (those values depend on time and parameters only).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND
from casmbd.model.expression_rules import MEASURE_ARITY
from casmbd.model.expressions import parse_expression
from casmbd.model.flexible_bodies import named_nodes

#: what each measure reads: a joint coordinate, a point, two points or a body frame
_KINDS = {"angle": "joint", "translation": "joint", "coordinate": "joint", "rate": "joint",
          "x": "point", "y": "point", "z": "point", "vx": "point", "vy": "point",
          "vz": "point", "speed": "point", "distance": "point", "angle_of": "frame",
          "omega_of": "frame", "wx": "spin", "wy": "spin", "wz": "spin"}
#: names of time in an expression of measures
TIME_NAMES = ("t", "time")


@dataclass(frozen=True)
class MeasureRef:
    """A measure call resolved against a mechanism.

    ``function`` is the measure's name (:data:`~casmbd.model.expression_rules.MEASURE_ARITY`);
    for a joint measure ``targets`` is ``(joint,)`` and ``coordinate`` the joint coordinate's
    name; for a point measure ``targets`` holds one (two for ``distance``) pairs of the form
    ``"marker:<name>"`` or ``"body:<name>"`` (``"body:ground"`` the origin); for a frame
    measure ``("body:<name>",)`` or ``("marker:<name>",)``.
    """

    function: str
    targets: tuple[str, ...]
    coordinate: str | None = None


def _joint(mech, function: str, name: str) -> MeasureRef:
    """Resolve ``function("J")`` / ``function("J.coord")`` against the joints."""
    joint_name, _, coord = name.partition(".")
    joint = mech.joints.get(joint_name)
    if joint is None:
        known = ", ".join(mech.joints) or "none"
        raise ModelError(f"unknown joint '{joint_name}' in {function}(...) (known joints: "
                         f"{known})")
    names = tuple(getattr(joint, "coordinate_names", ()))
    if not names:
        raise ModelError(f"joint '{joint_name}' ({type(joint).__name__}) has no coordinate "
                         f"for {function}(...)")
    if function in ("angle", "translation"):
        if coord and coord != function:
            raise ModelError(f"{function}(\"{name}\"): use {function}(\"{joint_name}\") or "
                             f"coordinate(\"{name}\")")
        if function not in names:
            raise ModelError(f"joint '{joint_name}' has no {function} coordinate (its "
                             f"coordinates: {', '.join(names)}); use coordinate(\"{joint_name}\")")
        return MeasureRef(function, (joint_name,), function)
    if coord and coord not in names:
        raise ModelError(f"joint '{joint_name}' has no coordinate '{coord}' (its coordinates: "
                         f"{', '.join(names)})")
    return MeasureRef(function, (joint_name,), coord or names[0])


def _target(mech, function: str, name: str) -> str:
    """``"marker:<name>"`` or ``"body:<name>"`` of a point or frame name (markers first)."""
    if name in mech.markers:
        return f"marker:{name}"
    if name == GROUND or name in mech.bodies:
        return f"body:{name}"
    known = ", ".join([*mech.markers, *mech.bodies]) or "none"
    raise ModelError(f"unknown marker or body '{name}' in {function}(...) (known: {known}; a "
                     "flexible body's node is the marker 'body@node')")


def resolve(mech, function: str, names: tuple[str, ...]) -> MeasureRef:
    """The :class:`MeasureRef` of ``function(*names)`` in ``mech``.

    Raises
    ------
    ModelError
        An unknown joint, marker or body (listing the known ones), a joint without the
        coordinate asked for, ``z``/``vz``/``wx``/``wy`` in the plane or
        ``angle_of``/``omega_of`` in space.
    """
    kind = _KINDS[function]
    if kind == "joint":
        return _joint(mech, function, names[0])
    if kind == "spin":
        if function != "wz" and mech.dimension == 2:
            raise ModelError(f"{function}(...) needs a spatial mechanism (in the plane the "
                             "angular velocity is wz or omega_of)")
        if names[0] in mech.nodes:
            return MeasureRef(function, (f"body:{names[0]}",))
        return MeasureRef(function, (_target(mech, function, names[0]),))
    if function in ("z", "vz") and mech.dimension == 2:
        raise ModelError(f"{function}(...) needs a spatial mechanism (this one is planar)")
    if kind == "frame" and mech.dimension != 2:
        raise ModelError(f"{function}(...) is the planar body angle; a spatial mechanism has "
                         "no single body angle (use joint angles or marker positions)")
    if kind == "frame" and names[0] in mech.nodes:
        return MeasureRef(function, (f"body:{names[0]}",))
    return MeasureRef(function, tuple(_target(mech, function, n) for n in names))


def measure_calls(mech, build: Callable[[MeasureRef], object]) -> dict[str, tuple]:
    """The ``calls`` table of :func:`~casmbd.model.expressions.parse_expression` for ``mech``:
    every measure name → (number of quoted names, resolver) whose resolver checks the names
    (:func:`resolve`) and returns ``build(ref)``."""
    return {name: (arity, lambda *names, name=name: build(resolve(mech, name, names)))
            for name, arity in MEASURE_ARITY.items()}


def check(mech, value, where: str) -> object:
    """Check a value of measures when it is added: a finite number (returned as ``float``) or an
    expression string (returned unchanged) that parses with the mechanism's parameters,
    ``t``/``time`` and measures whose names exist.

    Raises
    ------
    ModelError
        Not a number or string, or a number that is not finite.
    ExpressionError
        Invalid syntax, an unknown name, function or element, a wrong number of arguments
        (the message starts with ``where``).
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ModelError(f"{where}: expected a number or an expression string, got {value!r}")
    if not isinstance(value, str):
        out = float(value)
        if not math.isfinite(out):
            raise ModelError(f"{where}: must be a finite number, got {value!r}")
        return out
    symbols = {name: ca.SX.sym(name) for name in mech.parameters}
    time = ca.SX.sym("t")
    for name in TIME_NAMES:
        symbols.setdefault(name, time)
    parse_expression(value, symbols, where, measure_calls(mech, lambda ref: ca.SX.sym("m")))
    return value


@dataclass
class Output:
    """A request: a named expression of measures reported on the result grid of every analysis
    that has one (``[[outputs]]``; :mod:`casmbd.system.requests`).  ``unit`` labels its plot
    axis and CSV header only."""

    name: str
    value: float | str
    unit: str = "-"


def add_output(mech, name: str, value, unit: str = "-") -> Output:
    """Add the request ``name = value`` to ``mech.outputs`` (see :class:`Output`).

    Raises
    ------
    ModelError, ExpressionError
        A duplicate or empty name, a unit that is not a string, or a value :func:`check`
        refuses (naming ``output '<name>' field 'value'``).
    """
    outputs = mech.outputs
    mech._unique(outputs, "output", name)
    if not isinstance(unit, str):
        raise ModelError(f"output '{name}' field 'unit': expected a string, got {unit!r}")
    output = Output(name, check(mech, value, f"output '{name}' field 'value'"), unit)
    outputs[name] = output
    return output


# ---------------------------------------------------------------- values with a context
def _position(ctx, target: str) -> ca.SX:
    """Global position of a ``"marker:…"`` or ``"body:…"`` target (a body: its centre of
    mass; the ground: the origin)."""
    kind, _, name = target.partition(":")
    if kind == "marker":
        marker = ctx.mechanism.markers[name]
        return ctx.position(marker.body, marker.point)
    return ctx.centre_of_mass(name)


def _frame_angle(ctx, target: str) -> ca.SX:
    """Planar angle of a body (or node) frame or of a marker's frame (θ_body + θ_m − θᵦ)."""
    kind, _, name = target.partition(":")
    if kind == "marker":
        marker = ctx.mechanism.markers[name]
        return ctx.angle(marker.body) + marker.offset(ctx.mechanism.attachment(marker.body))
    return ctx.angle(name)


def value_of(ctx, ref: MeasureRef) -> ca.SX:
    """The CasADi expression of (q, v, t) of a resolved measure, written with ``ctx`` (the
    system's :class:`~casmbd.system.context.Context`, handed in by the system layer): joint
    coordinates by the joint's own ``coordinate``, points by ``ctx.position`` /
    ``ctx.centre_of_mass``, rates as ∂s/∂q v (``casadi.jtimes``, exact)."""
    q, v = ctx.q, ctx.v
    function = ref.function
    if _KINDS[function] == "joint":
        coord = ctx.mechanism.joints[ref.targets[0]].coordinate(ctx, ref.coordinate)
        return ca.jtimes(coord, q, v) if function == "rate" else coord
    if _KINDS[function] == "spin":
        kind, _, name = ref.targets[0].partition(":")
        body = ctx.mechanism.markers[name].body if kind == "marker" else name
        omega = ctx.angular_velocity(body)
        return omega if ctx.dimension == 2 else omega["xyz".index(function[1])]
    if _KINDS[function] == "frame":
        angle = _frame_angle(ctx, ref.targets[0])
        return ca.jtimes(angle, q, v) if function == "omega_of" else angle
    if function == "distance":
        d = _position(ctx, ref.targets[1]) - _position(ctx, ref.targets[0])
        return ca.sqrt(ca.dot(d, d))
    pos = _position(ctx, ref.targets[0])
    if function in ("x", "y", "z"):
        return pos["xyz".index(function)]
    vel = ca.jtimes(pos, q, v)
    if function == "speed":
        return ca.sqrt(ca.dot(vel, vel))
    return vel["xyz".index(function[1])]


def expression(ctx, value, where: str) -> ca.SX:
    """A value of measures (a number or an expression string, checked by :func:`check`) as a
    CasADi expression of (q, v, t, p) written with ``ctx``: parameters ``ctx.p``, time
    ``ctx.t`` (``t`` or ``time``) and every measure by :func:`value_of`."""
    if not isinstance(value, str):
        return ca.SX(float(value))
    symbols = dict(ctx.p)
    for name in TIME_NAMES:
        symbols.setdefault(name, ctx.t)
    out = parse_expression(value, symbols, where,
                           measure_calls(ctx.mechanism, lambda ref: value_of(ctx, ref)))
    return ca.SX(out)


def force_report_names(mech) -> list[tuple[str, str, str]]:
    """(element, quantity, unit) of every measure the force elements report by default
    (:meth:`casmbd.model.forces.ForceElement.report_names`), in declaration order."""
    out = []
    for force in mech.forces.values():
        names = getattr(force, "report_names", None)
        for quantity, unit in (names(mech.dimension) if names is not None else ()):
            out.append((force.name, quantity, unit))
    return out


def result_names(mech) -> dict[str, list[str]]:
    """The ``names`` of a result's requests (``outputs``, ``output_units``), force reports
    (``force_outputs`` as ``"<element>.<quantity>"``, ``force_output_units``) and flexible
    bodies' named nodes (``nodes``, ``"<body>@<node>"``); only the groups the mechanism has
    (:mod:`casmbd.system.requests` builds the arrays)."""
    out: dict[str, list[str]] = {}
    outputs = getattr(mech, "outputs", {})
    if outputs:
        out["outputs"] = list(outputs)
        out["output_units"] = [o.unit for o in outputs.values()]
    reports = force_report_names(mech)
    if reports:
        out["force_outputs"] = [f"{e}.{q}" for e, q, _ in reports]
        out["force_output_units"] = [u for _, _, u in reports]
    nodes = named_nodes(mech)
    if nodes:  # flexible bodies' named nodes: position, deflection, rotation
        out["nodes"] = nodes
    return out
