"""A generic velocity constraint written in the scene (``type = "velocity"``):
rows W_k(q, v, t) = A_k(q, t) v + b_k(q, t) = 0 given as expressions of measures.

Each row is an expression of the measures of :mod:`casmbd.model.measures` — positions (``x``,
``y``, ``z``, ``angle``, ``translation``, ``coordinate``, ``distance``, ``angle_of``),
velocities (``vx``, ``vy``, ``vz``, ``rate``, ``omega_of``, ``wx``, ``wy``, ``wz``), time ``t``
and the scene's parameters — that must be *affine in the velocities*: a velocity measure may be
multiplied by functions of the positions, time and parameters, never by another velocity
measure or put inside a nonlinear function (``speed``, ``abs(vx(...))``, ``vx(...)**2`` are
refused). The check is made when the joint is added, on the parsed rows with the measures
standing as symbols (position measures as q-symbols, velocity measures as v-symbols, ``speed``
as the norm of three v-symbols): ∂W/∂v must not depend on v, and W(v) − W(0) − (∂W/∂v) v must
vanish at random probes (which also catches ``sign``, ``floor``, ``min``/``max`` of a
velocity); the refusal names the joint, the row and the additive term at fault. When the system
is built the rows are written with the system's context and checked again (∂W/∂v free of v). A
row that involves no velocity measure is refused (a constraint on positions is a holonomic
joint or a driver).

The rows enter the equations through the velocity-row protocol of
:class:`casmbd.system.equations.System`: ``velocity_equations`` returns W, whose Jacobian
∂W/∂v is the row of C_q and W(v = 0) = b the row of C_t; γ follows from d/dt W = 0, time
dependence included (a prescribed slip velocity b(q, t)).  The joint declares the need
``"velocity_constraints"``.  Scene keys: ``rows`` (a string or a list of strings), optional
``labels`` (one identifier per row, default ``row_1``, ``row_2``, …), ``body1`` (default
``"ground"``), ``body2`` (the body whose reaction is reported) and optional ``point`` (where
the reaction's moment is taken, global at the initial pose; default body2's centre of mass);
the bodies whose poses
enter the rows are found from the measures (:attr:`VelocityConstraint.bodies`).

Example (the knife edge of a planar sleigh whose blade point is the marker ``"P"``)::

    [[joints]]
    name = "blade"
    type = "velocity"
    body2 = "sleigh"
    rows = ["-sin(angle_of('sleigh'))*vx('P') + cos(angle_of('sleigh'))*vy('P')"]
    labels = ["lateral"]
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.limits import MAX_VELOCITY_ROWS, check_count
from casmbd.model.bodies import GROUND, vector
from casmbd.model.expressions import parse_expression
from casmbd.model.joints import Joint
from casmbd.model.measures import (
    TIME_NAMES,
    MeasureRef,
    check,
    expression,
    measure_calls,
    value_of,
)
from casmbd.model.registry import register_joint

__all__ = ["VELOCITY_MEASURES", "VelocityConstraint", "additive_terms"]

#: the measures that are velocities (linear in v); every other measure is a position (or time)
VELOCITY_MEASURES = frozenset({"rate", "vx", "vy", "vz", "omega_of", "wx", "wy", "wz",
                               "speed"})
#: random probes of the affinity check and their relative tolerance
_PROBES, _PROBE_TOLERANCE = 3, 1e-9


def additive_terms(text: str) -> list[str]:
    """The additive terms of an expression text (already checked by the whitelist parser),
    each as text with its sign: ``"a*vx('P') - b"`` → ``["a*vx('P')", "-b"]``."""
    out: list[str] = []
    stack = [(ast.parse(text.strip(), mode="eval").body, "")]
    while stack:
        node, sign = stack.pop()
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)):
            flip = "-" if sign == "" else ""
            stack.append((node.right, sign if isinstance(node.op, ast.Add) else flip))
            stack.append((node.left, sign))
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            flip = "-" if sign == "" else ""
            stack.append((node.operand, flip if isinstance(node.op, ast.USub) else sign))
        else:
            out.append(sign + ast.unparse(node))
    return out


class _StandIns:
    """Measures replaced by symbols: positions by q-like symbols, velocities by v-like ones
    (``speed`` by the norm of three), one symbol per distinct measure."""

    def __init__(self, mech):
        self.mech = mech
        self.position: list[ca.SX] = []
        self.velocity: list[ca.SX] = []
        self.cache: dict[MeasureRef, ca.SX] = {}
        self.symbols = {name: ca.SX.sym(name) for name in mech.parameters}
        time = ca.SX.sym("t")
        for name in TIME_NAMES:
            self.symbols.setdefault(name, time)
        self.others = [time, *[s for n, s in self.symbols.items() if n not in TIME_NAMES]]

    def build(self, ref: MeasureRef) -> ca.SX:
        if ref not in self.cache:
            if ref.function == "speed":
                parts = ca.SX.sym(f"v{len(self.velocity)}", 3)
                self.velocity.append(parts)
                self.cache[ref] = ca.norm_2(parts)
            else:
                table = self.velocity if ref.function in VELOCITY_MEASURES else self.position
                sym = ca.SX.sym(f"m{len(table)}")
                table.append(sym)
                self.cache[ref] = sym
        return self.cache[ref]

    def parse(self, text: str, where: str) -> ca.SX:
        return ca.SX(parse_expression(text, self.symbols, where,
                                      measure_calls(self.mech, self.build)))

    def vectors(self) -> tuple[ca.SX, ca.SX]:
        vel = ca.vertcat(*self.velocity) if self.velocity else ca.SX(0, 1)
        rest = ca.vertcat(*self.position, *self.others)
        return vel, rest


def _affine(row: ca.SX, vel: ca.SX, rest: ca.SX, rng: np.random.Generator) -> bool:
    """True when ``row`` is affine in ``vel``: ∂row/∂vel free of vel, and
    row(v) − row(0) − (∂row/∂v) v = 0 at random probes."""
    if vel.numel() == 0:
        return True
    jac = ca.jacobian(row, vel)
    if ca.depends_on(jac, vel):
        return False
    defect = row - ca.substitute(row, vel, ca.DM.zeros(vel.numel())) - ca.mtimes(jac, vel)
    probe = ca.Function("probe", [vel, rest], [defect, row])
    for _ in range(_PROBES):
        v = rng.uniform(-2.0, 2.0, vel.numel())
        r = rng.uniform(0.1, 1.0, rest.numel())  # positive: sqrt/log of parameters stay real
        d, w = (float(x) for x in probe(v, r))
        if not (np.isfinite(d) and np.isfinite(w)):
            continue
        if abs(d) > _PROBE_TOLERANCE * (1.0 + abs(w)):
            return False
    return True


def _check_row(mech, text: str, where: str) -> None:
    """Refuse a row that is not affine in the velocities (naming its first non-affine term)
    or that involves no velocity."""
    stand = _StandIns(mech)
    row = stand.parse(text, where)
    vel, rest = stand.vectors()
    rng = np.random.default_rng(0)
    if vel.numel() == 0 or not ca.depends_on(row, vel):
        raise ModelError(f"{where}: the row involves no velocity (rate, vx, vy, vz, "
                         "omega_of, wx, wy, wz): a constraint on the positions is a holonomic "
                         f"joint or a driver, got {text!r}")
    if _affine(row, vel, rest, rng):
        return
    for term in additive_terms(text):
        value = stand.parse(term, where)
        if not _affine(value, vel, rest, rng):
            raise ModelError(f"{where}: not affine in the velocities: the term {term!r} "
                             "(a velocity constraint is A(q, t) v + b(q, t) = 0: velocity "
                             "measures may be multiplied by functions of positions, time and "
                             "parameters only)")
    raise ModelError(f"{where}: not affine in the velocities (a velocity constraint is "
                     f"A(q, t) v + b(q, t) = 0), got {text!r}")


def _bodies_of(mech, rows: tuple[str, ...]) -> tuple[str, ...]:
    """Every body whose pose a row reads: the measures' markers, bodies and joints."""
    found: list[str] = []

    def note(ref: MeasureRef):
        for target in ref.targets:
            kind, _, name = target.partition(":")
            if kind == "marker":
                found.append(mech.markers[name].body)
            elif kind == "body":
                found.append(name)
            else:  # a joint measure: the joint's bodies
                found.extend(mech.joints[target].bodies)
        return ca.SX.sym("m")

    symbols = {name: ca.SX.sym(name) for name in mech.parameters}
    for name in TIME_NAMES:
        symbols.setdefault(name, ca.SX.sym("t"))
    for text in rows:
        parse_expression(text, symbols, "velocity rows", measure_calls(mech, note))
    return tuple(found)


@register_joint
@dataclass
class VelocityConstraint(Joint):
    """Rows A(q, t) v + b(q, t) = 0 written as expressions of measures (module docstring)."""
    #: what it needs from an analysis (casmbd.model.needs): velocity rows
    needs: ClassVar[frozenset[str]] = frozenset({"velocity_constraints"})

    rows: tuple[str, ...] = ()
    involved: tuple[str, ...] = ()
    point: np.ndarray | None = None

    kind = "velocity"
    title = "velocity constraint"
    dimensions = (2, 3)
    scene_keys = frozenset({"rows", "labels", "point"})
    drawing = "none"

    @property
    def velocity_labels(self) -> tuple[str, ...]:
        """Every row is a velocity row."""
        return self.labels

    @property
    def bodies(self) -> tuple[str, ...]:
        return self.involved

    @classmethod
    def create(cls, mech, name: str, body1: str = GROUND, body2: str | None = None,
               rows=None, labels=None, point=None) -> VelocityConstraint:
        """Check the rows (each parses, involves a velocity and is affine in the velocities)
        and the labels, naming the joint, the field and the row."""
        if body2 is None:
            mech._unique(mech.joints, "joint", name)
            raise ModelError(f"joint '{name}' field 'body2': missing (the body whose reaction "
                             "the velocity constraint reports)")
        mech._new_joint(name, body1, body2)
        where = f"joint '{name}' field"
        texts = [rows] if isinstance(rows, str) else rows
        if not isinstance(texts, (list, tuple)) or not texts:
            raise ModelError(f"{where} 'rows': expected an expression string or a non-empty "
                             f"list of them, got {rows!r}")
        check_count(f"joint '{name}' field 'rows'", len(texts), MAX_VELOCITY_ROWS)
        if labels is None:
            labels = [f"row_{k + 1}" for k in range(len(texts))]
        elif isinstance(labels, str):
            labels = [labels]
        if not isinstance(labels, (list, tuple)) or len(labels) != len(texts) or any(
                not isinstance(lab, str) or not lab.isidentifier() for lab in labels):
            raise ModelError(f"{where} 'labels': expected {len(texts)} identifier(s), one per "
                             f"row, got {labels!r}")
        if len(set(labels)) != len(labels):
            raise ModelError(f"{where} 'labels': must be distinct, got {list(labels)!r}")
        for k, text in enumerate(texts):
            at = f"{where} 'rows' row {k + 1} ('{labels[k]}')"
            if not isinstance(text, str):
                raise ModelError(f"{at}: expected an expression string of measures, got "
                                 f"{text!r}")
            check(mech, text, at)
            _check_row(mech, text, at)
        involved = tuple(dict.fromkeys([body1, body2, *_bodies_of(mech, tuple(texts))]))
        if point is not None:
            point = vector(point, f"{where} 'point'", mech.dimension)
        return cls(name, body1, body2, labels=tuple(labels), rows=tuple(texts),
                   involved=involved, point=point)

    @classmethod
    def from_scene(cls, mech, e) -> VelocityConstraint:
        name = e.string("name")
        rows = e.data.get("rows")
        if rows is None:
            raise e.error("rows", "missing required key")
        labels = e.data.get("labels")
        return mech.add("velocity", name, e.string("body1", default=GROUND),
                        e.string("body2"), rows=rows, labels=labels,
                        point=e.vector("point", mech.dimension, required=False))

    def equations(self, ctx) -> ca.SX:
        return ca.SX.zeros(len(self.rows))

    def velocity_equations(self, ctx) -> ca.SX:
        """W(q, v, t) = A(q, t) v + b(q, t), one entry per row, written with the system's
        context (refused when ∂W/∂v depends on v)."""
        out = []
        for k, (text, label) in enumerate(zip(self.rows, self.labels, strict=True)):
            where = f"joint '{self.name}' field 'rows' row {k + 1} ('{label}')"
            row = expression(ctx, text, where)
            if ca.depends_on(ca.jacobian(row, ctx.v), ctx.v):
                raise ModelError(f"{where}: not affine in the velocities v when written with "
                                 f"the coordinates: {text!r}")
            out.append(row)
        return ca.vertcat(*out)

    def virtual_equations(self, ctx) -> ca.SX:
        """Σ_k a_k(q₀, t) s_k(q), one entry per row: W = Σ_k a_k m_k + b with m_k its velocity
        measures, a_k frozen at the unperturbed pose (``ctx.resolve``) and s_k the position
        whose rate m_k is (x for vx, the coordinate for rate, the angle for omega_of, the
        rotation vector for wx, wy, wz).  Its derivative by a virtual rigid displacement of a
        body is the coefficient of that body's twist in W: the joint reactions' virtual work."""
        out = []
        for k, (text, label) in enumerate(zip(self.rows, self.labels, strict=True)):
            where = f"joint '{self.name}' field 'rows' row {k + 1} ('{label}')"
            split = _Velocities(ctx)
            row = split.parse(text, where)
            if not split.refs:
                out.append(ca.SX(0.0))
                continue
            coeff = ctx.resolve(ca.jacobian(row, ca.vertcat(*split.slots)))
            out.append(ca.mtimes(coeff, ca.vertcat(*[_displacement(ctx, r)
                                                     for r in split.refs])))
        return ca.vertcat(*out)

    def reaction_point(self) -> np.ndarray | None:
        """``point`` (global, initial pose) when given: the reaction's moment is about it
        (default: body2's centre of mass at the initial pose)."""
        return self.point


class _Velocities:
    """A row written with ``ctx`` but its velocity measures as symbols (``slots``, one per
    distinct measure ``refs``): W = Σ a_k slot_k + b."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.refs: list[MeasureRef] = []
        self.slots: list[ca.SX] = []

    def build(self, ref: MeasureRef) -> ca.SX:
        if ref.function not in VELOCITY_MEASURES:
            return value_of(self.ctx, ref)
        if ref not in self.refs:
            self.refs.append(ref)
            self.slots.append(ca.SX.sym(f"s{len(self.slots)}"))
        return self.slots[self.refs.index(ref)]

    def parse(self, text: str, where: str) -> ca.SX:
        symbols = dict(self.ctx.p)
        for name in TIME_NAMES:
            symbols.setdefault(name, self.ctx.t)
        return ca.SX(parse_expression(text, symbols, where,
                                      measure_calls(self.ctx.mechanism, self.build)))


def _rotation_vector(ctx, body: str) -> ca.SX:
    """½ vee(S − Sᵀ), S = A A₀ᵀ (A₀ frozen): zero at the unperturbed pose, its derivative by a
    virtual rotation δθ of ``body`` is δθ."""
    rot = ctx.rotation(body)
    s = ca.mtimes(rot, ctx.resolve(rot).T)
    return 0.5 * ca.vertcat(s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1])


def _displacement(ctx, ref: MeasureRef) -> ca.SX:
    """The position whose rate the velocity measure ``ref`` is (see
    :meth:`VelocityConstraint.virtual_equations`)."""
    function = ref.function
    if function == "rate":
        return ctx.mechanism.joints[ref.targets[0]].coordinate(ctx, ref.coordinate)
    kind, _, name = ref.targets[0].partition(":")
    if function in ("vx", "vy", "vz"):
        if kind == "marker":
            marker = ctx.mechanism.markers[name]
            pos = ctx.position(marker.body, marker.point)
        else:
            pos = ctx.centre_of_mass(name)
        return pos["xyz".index(function[1])]
    body = ctx.mechanism.markers[name].body if kind == "marker" else name
    if body == GROUND:
        return ca.SX(0.0)
    if function == "omega_of" or ctx.dimension == 2:  # omega_of, wz in the plane
        return ctx.angle(body)
    return _rotation_vector(ctx, body)["xyz".index(function[1])]
