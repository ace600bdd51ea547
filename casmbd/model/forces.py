"""Force elements and actuators; each gives its generalized force by virtual work.

For a force F applied at a body point P and a torque T on a body, δW = Fᵀ δr_P + T δθ, so the
generalized force is Q = (∂r_P/∂q)ᵀ F + (∂θ/∂q)ᵀ T (seed 000, "Generalized forces", eqs.
6.40–6.48).  A force element acting along a scalar measure s(q) (the length of a spring, a joint
coordinate) with magnitude f resisting an increase of s gives Q = −f (∂s/∂q)ᵀ.  The Jacobians
are taken by CasADi's algorithmic differentiation, never by hand.

Each force element kind is one class (a :class:`ForceElement`) registered by its scene type
name (:data:`casmbd.model.registry.FORCE_KINDS`): it declares its scene keys, how it is built
from the Python API (:meth:`ForceElement.create`, behind ``Mechanism.add``) and from a scene
entry (:meth:`ForceElement.from_scene`), its virtual-work terms (:meth:`ForceElement.terms`)
and its potential energy, and its drawing hint.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND, vector
from casmbd.model.registry import FORCE_KINDS, register_force
from casmbd.model.values import Value, check_value

FRAMES = ("global", "body")


def __getattr__(name: str):
    """``FORCE_TYPES``: the registered force element names, read from the registry."""
    if name == "FORCE_TYPES":
        return tuple(FORCE_KINDS)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class ForceElement:
    """Base of the force element kinds (no fields: each kind is a dataclass).

    ``kit`` in :meth:`terms` and :meth:`potential` is handed in by the system (so the model
    layer does not import it): ``kit.ctx`` the system's context (weights are written with it),
    ``kit.value(value, where)`` turns a number or expression into CasADi, ``kit.term(kind,
    expr, weight, body=None, name="")`` builds a virtual-work term — ``"measure"``
    (Q = (∂expr/∂q)ᵀ weight), ``"torque"`` (weight a torque on ``body``) or ``"generalized"``
    — and ``kit.user_terms(force, ctx)`` gives a user force's terms.
    """

    #: scene type name (``[[forces]] type``)
    kind: ClassVar[str] = ""
    #: scene keys besides name, type and description; None: not available in scenes
    scene_keys: ClassVar[frozenset[str] | None] = None
    #: drawing hint for :mod:`casmbd.viz.geometry`: "spring" (a line from ``point1`` on
    #: ``body1`` to ``point2`` on ``body2``) or "none"
    drawing: ClassVar[str] = "none"

    @classmethod
    def create(cls, mech, name: str, *args, **fields) -> ForceElement:
        """Validate the arguments of ``mech.add(kind, ...)`` and build the element (the
        default checks a unique name and calls the class; kinds with bodies or joints check
        them and raise :class:`~casmbd.errors.ModelError` naming the field)."""
        mech._unique(mech.forces, "force", name)
        return cls(name, *args, **fields)

    @classmethod
    def from_scene(cls, mech, entry) -> ForceElement:
        """Add the element of one ``[[forces]]`` entry to ``mech`` (see
        :meth:`casmbd.model.joints.Joint.from_scene`)."""
        raise NotImplementedError(f"force kind '{cls.kind}' cannot be read from a scene")

    def terms(self, kit, ctx) -> list:
        """Virtual-work terms, measures written with ``ctx`` (the system's context or a
        perturbed copy for reactions), weights with ``kit.ctx``."""
        raise NotImplementedError

    def potential(self, kit) -> ca.SX | None:
        """Potential energy (None: the element's work is not in V)."""
        return None

    def energy_exchange(self) -> str | None:
        """How the element changes the total energy T + V: ``None`` when all its work is in
        V (a spring), ``"damper"`` when it dissipates, ``"force"`` when it does work that V
        does not hold (the default: point forces, torques, user forces)."""
        return "force"

    def wound_joint(self) -> str | None:
        """The joint whose coordinate the element winds (a rotational spring's φ − φ0 counts
        whole turns, so statics must not reduce that angle to its principal range)."""
        return None

    def report_names(self, dimension: int) -> tuple[tuple[str, str], ...]:
        """(quantity, unit) of the measures the element reports on every result grid
        (:mod:`casmbd.system.requests`; ``force_outputs``).  Default: an element acting on one
        joint coordinate (``joint`` and ``coordinate`` fields, e.g. joint friction) reports
        ``force``, the generalized force it applies along that coordinate; others nothing."""
        return (("force", coordinate_force_unit(self.coordinate)),) if _on_coordinate(self) else ()

    def reports(self, kit) -> list[ca.SX]:
        """The values of :meth:`report_names`, written with ``kit.ctx`` (default: the sum of
        the weights of the element's terms along its joint coordinate)."""
        if not _on_coordinate(self):
            return []
        return [sum((ca.vec(term.weight)[0] for term in self.terms(kit, kit.ctx)
                     if term.kind == "measure"), ca.SX(0.0))]


def _on_coordinate(force) -> bool:
    """An element acting on one joint coordinate that the default reports describe (not one
    whose level depends on a joint reaction, unknown on the output grid's inputs)."""
    reaction = getattr(force, "reaction_joint", None)
    return (isinstance(getattr(force, "joint", None), str)
            and isinstance(getattr(force, "coordinate", None), str)
            and (reaction is None or reaction() is None))


def coordinate_force_unit(coordinate: str | None) -> str:
    """Unit of a generalized force along a joint coordinate: N m on an angle, else N."""
    return "N m" if str(coordinate).startswith("angle") else "N"


def may_be_nonzero(value: Value) -> bool:
    """Whether a value may differ from zero (an expression or a parameter may)."""
    return not (isinstance(value, (int, float)) and not isinstance(value, bool) and value == 0)


def _spring_exchange(force) -> str | None:
    """:meth:`ForceElement.energy_exchange` of a spring-damper-actuator: its spring is in V,
    its damper dissipates, its actuator does work."""
    if may_be_nonzero(force.damping):
        return "damper"
    return "force" if may_be_nonzero(force.actuator) else None


def point_vector(value, where: str) -> np.ndarray:
    """A point of 2 (plane) or 3 (space) numbers; the mechanism checks which."""
    size = len(value) if hasattr(value, "__len__") and len(value) in (2, 3) else 2
    return vector(value, where, size)


@register_force
@dataclass
class PointForce(ForceElement):
    """A force (2 or 3 values, global or body frame) applied at a body point."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    body: str
    value: tuple[Value, Value]
    point: np.ndarray | None = None
    frame: str = "global"

    kind = "force"
    scene_keys = frozenset({"body", "point", "value", "frame"})

    @classmethod
    def create(cls, mech, name, body, value, point=None, frame="global"):
        mech._unique(mech.forces, "force", name)
        mech._body(body, f"force '{name}' field 'body'")
        force = cls(name, body, value, point=point, frame=frame)
        mech._dimension_of(name, "value", len(force.value))
        if force.point is not None:
            mech._dimension_of(name, "point", len(force.point))
        return force

    @classmethod
    def from_scene(cls, mech, e):
        name, dim = e.string("name"), mech.dimension
        value = e.values("value", (dim,))
        return mech.add("force", name, e.string("body"), value,
                        point=e.vector("point", dim, required=False),
                        frame=e.string("frame", default="global"))

    def terms(self, kit, ctx):
        if self.body == GROUND:
            return []
        base = kit.ctx
        value = ca.vertcat(*[kit.value(v, f"force '{self.name}' field 'value'")
                             for v in self.value])
        if self.frame == "body":
            value = ca.mtimes(base.rotation(self.body), value)
        local = np.zeros(base.dimension) if self.point is None else \
            base.local(self.body, self.point)
        return [kit.term("measure", ctx.point(self.body, local), value)]

    def __post_init__(self):
        where = f"force '{self.name}'"
        if not isinstance(self.value, (list, tuple)) or len(self.value) not in (2, 3):
            raise ModelError(f"{where} field 'value': expected 2 (plane) or 3 (space) "
                             f"components, got {self.value!r}")
        self.value = tuple(check_value(v, f"{where} field 'value'") for v in self.value)
        if self.point is not None:
            self.point = point_vector(self.point, f"{where} field 'point'")
        if self.frame not in FRAMES:
            raise ModelError(f"{where} field 'frame': expected 'global' or 'body', "
                             f"got {self.frame!r}")

    def report_names(self, dimension):
        """The global force components ``fx``, ``fy`` (, ``fz``) [N]."""
        return tuple((f"f{a}", "N") for a in "xyz"[:dimension])

    def reports(self, kit):
        if self.body == GROUND:
            return [ca.SX(0.0)] * len(self.value)
        (term,) = self.terms(kit, kit.ctx)
        return [ca.vec(term.weight)[k] for k in range(len(self.value))]


@register_force
@dataclass
class Torque(ForceElement):
    """A torque on a body: one value in the plane (counter-clockwise positive), three in space
    (global or body frame).  Its generalized force is (∂ω/∂q̇)ᵀ T (virtual rotation)."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    body: str
    value: Value | tuple
    frame: str = "global"

    kind = "torque"
    scene_keys = frozenset({"body", "value", "frame"})

    @classmethod
    def create(cls, mech, name, body, value, frame="global"):
        mech._unique(mech.forces, "force", name)
        mech._body(body, f"force '{name}' field 'body'")
        torque = cls(name, body, value, frame=frame)
        size = 1 if mech.dimension == 2 else 3
        if len(torque.value) != size:
            raise ModelError(f"force '{name}' field 'value': a torque has {size} component(s) "
                             f"in {mech.dimension} dimensions, got {len(torque.value)}")
        return torque

    @classmethod
    def from_scene(cls, mech, e):
        name = e.string("name")
        value = e.value("value") if mech.dimension == 2 else e.values("value", (3,))
        return mech.add("torque", name, e.string("body"), value,
                        frame=e.string("frame", default="global"))

    def terms(self, kit, ctx):
        base = kit.ctx
        value = ca.vertcat(*[kit.value(v, f"force '{self.name}' field 'value'")
                             for v in self.value])
        if self.frame == "body" and self.body != GROUND:
            value = ca.mtimes(base.rotation(self.body), value)
        return [kit.term("torque", None, value, self.body)]

    def __post_init__(self):
        where = f"force '{self.name}' field"
        values = self.value if isinstance(self.value, (list, tuple)) else (self.value,)
        if len(values) not in (1, 3):
            raise ModelError(f"{where} 'value': expected 1 (plane) or 3 (space) components, "
                             f"got {self.value!r}")
        self.value = tuple(check_value(v, f"{where} 'value'") for v in values)
        if self.frame not in FRAMES:
            raise ModelError(f"{where} 'frame': expected 'global' or 'body', got {self.frame!r}")

    def report_names(self, dimension):
        """``torque`` [N m] in the plane; global ``tx``, ``ty``, ``tz`` in space."""
        return (("torque", "N m"),) if dimension == 2 else \
            tuple((f"t{a}", "N m") for a in "xyz")

    def reports(self, kit):
        (term,) = self.terms(kit, kit.ctx)
        return [ca.vec(term.weight)[k] for k in range(len(self.value))]


@register_force
@dataclass
class SpringDamper(ForceElement):
    """Translational spring-damper-actuator between point1 (body1) and point2 (body2).

    Tension f = k (l − l0) + c l̇ + a(t) pulls the points together; potential ½ k (l − l0)²
    (seed 000 / 001, "Spring-damper-actuator elements").
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    body1: str
    body2: str
    point1: np.ndarray
    point2: np.ndarray
    stiffness: Value = 0.0
    damping: Value = 0.0
    free_length: Value | None = None
    actuator: Value = 0.0

    kind = "spring_damper"
    scene_keys = frozenset({"body1", "body2", "point1", "point2", "stiffness", "damping",
                            "free_length", "actuator"})
    drawing = "spring"

    @classmethod
    def create(cls, mech, name, body1, body2, point1, point2, stiffness=0.0, damping=0.0,
               free_length=None, actuator=0.0):
        mech._unique(mech.forces, "force", name)
        mech._pair(body1, body2, f"force '{name}'")
        mech._nonnegative(name, stiffness=stiffness, damping=damping,
                          **({} if free_length is None else {"free_length": free_length}))
        force = cls(name, body1, body2, point1, point2, stiffness, damping, free_length,
                    actuator)
        mech._dimension_of(name, "point1", len(force.point1))
        mech._dimension_of(name, "point2", len(force.point2))
        return force

    @classmethod
    def from_scene(cls, mech, e):
        name, dim = e.string("name"), mech.dimension
        return mech.add("spring_damper", name, e.string("body1"), e.string("body2"),
                        e.vector("point1", dim), e.vector("point2", dim),
                        stiffness=e.nonnegative("stiffness"), damping=e.nonnegative("damping"),
                        free_length=e.value("free_length", required=False),
                        actuator=e.value("actuator", 0.0))

    def length(self, ctx) -> ca.SX:
        """Distance between the two points, written with ``ctx``."""
        p1 = ctx.point(self.body1, ctx.local(self.body1, self.point1))
        p2 = ctx.point(self.body2, ctx.local(self.body2, self.point2))
        d = p2 - p1
        return ca.sqrt(ca.dot(d, d))

    def _state(self, kit) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Length l, rate l̇ and tension f = k (l − l0) + c l̇ + a(t), with ``kit.ctx``."""
        base, where = kit.ctx, f"force '{self.name}' field"
        length = self.length(base)
        rate = ca.jtimes(length, base.q, base.v)
        tension = (kit.value(self.stiffness, f"{where} 'stiffness'")
                   * (length - kit.value(self.free_length, f"{where} 'free_length'"))
                   + kit.value(self.damping, f"{where} 'damping'") * rate
                   + kit.value(self.actuator, f"{where} 'actuator'"))
        return length, rate, tension

    def terms(self, kit, ctx):
        tension = self._state(kit)[2]
        return [kit.term("measure", self.length(ctx), -tension)]

    def report_names(self, dimension):
        """``length`` [m], its ``rate`` [m/s] and the ``force`` [N] (tension, positive when
        it pulls the points together)."""
        return (("length", "m"), ("rate", "m/s"), ("force", "N"))

    def reports(self, kit):
        return list(self._state(kit))

    def potential(self, kit):
        where = f"force '{self.name}' field"
        stretch = self.length(kit.ctx) - kit.value(self.free_length, f"{where} 'free_length'")
        return 0.5 * kit.value(self.stiffness, f"{where} 'stiffness'") * stretch**2

    def __post_init__(self):
        where = f"force '{self.name}'"
        self.point1 = point_vector(self.point1, f"{where} field 'point1'")
        self.point2 = point_vector(self.point2, f"{where} field 'point2'")
        if self.free_length is None:
            self.free_length = float(np.linalg.norm(self.point2 - self.point1))
        if np.allclose(self.point1, self.point2):
            raise ModelError(f"{where} fields 'point1', 'point2': the points coincide, so the "
                             "line of action is undefined (use a rotational spring or offset "
                             "the points)")
        for key in ("stiffness", "damping", "free_length", "actuator"):
            setattr(self, key, check_value(getattr(self, key), f"{where} field '{key}'"))

    def energy_exchange(self) -> str | None:
        return _spring_exchange(self)


@register_force
@dataclass
class RotationalSpringDamper(ForceElement):
    """Rotational spring-damper-actuator at a joint with an angle coordinate φ (revolute,
    cylindrical).

    Moment T = k (φ − φ0) + c φ̇ + a(t) resisting an increase of φ; potential ½ k (φ − φ0)².
    ``free_angle`` defaults to 0.
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    joint: str
    stiffness: Value = 0.0
    damping: Value = 0.0
    free_angle: Value = 0.0
    actuator: Value = 0.0
    coordinate: str | None = None

    kind = "rotational_spring_damper"
    scene_keys = frozenset({"joint", "stiffness", "damping", "free_angle", "actuator"})

    @classmethod
    def create(cls, mech, name, joint, stiffness=0.0, damping=0.0, free_angle=0.0,
               actuator=0.0):
        mech._unique(mech.forces, "force", name)
        mech._nonnegative(name, stiffness=stiffness, damping=damping)
        joint_obj = mech._joint(joint, f"force '{name}' field 'joint'")
        if "angle" not in joint_obj.coordinate_names:
            raise ModelError(f"force '{name}' field 'joint': joint '{joint}' is not revolute")
        return cls(name, joint, stiffness, damping, free_angle, actuator, coordinate="angle")

    @classmethod
    def from_scene(cls, mech, e):
        name = e.string("name")
        return mech.add("rotational_spring_damper", name, e.string("joint"),
                        stiffness=e.nonnegative("stiffness"), damping=e.nonnegative("damping"),
                        free_angle=e.value("free_angle", 0.0), actuator=e.value("actuator", 0.0))

    def _state(self, kit) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Angle φ, rate φ̇ and moment T = k (φ − φ0) + c φ̇ + a(t), with ``kit.ctx``."""
        base, where = kit.ctx, f"force '{self.name}' field"
        joint = base.mechanism.joints[self.joint]
        phi = joint.coordinate(base, self.coordinate)
        rate = ca.jtimes(phi, base.q, base.v)
        moment = (kit.value(self.stiffness, f"{where} 'stiffness'")
                  * (phi - kit.value(self.free_angle, f"{where} 'free_angle'"))
                  + kit.value(self.damping, f"{where} 'damping'") * rate
                  + kit.value(self.actuator, f"{where} 'actuator'"))
        return phi, rate, moment

    def terms(self, kit, ctx):
        moment = self._state(kit)[2]
        joint = kit.ctx.mechanism.joints[self.joint]
        return [kit.term("measure", joint.coordinate(ctx, self.coordinate), -moment)]

    def report_names(self, dimension):
        """``angle`` [rad], its ``rate`` [rad/s] and the ``moment`` [N m] (resisting an
        increase of the angle)."""
        return (("angle", "rad"), ("rate", "rad/s"), ("moment", "N m"))

    def reports(self, kit):
        return list(self._state(kit))

    def potential(self, kit):
        where = f"force '{self.name}' field"
        base = kit.ctx
        stretch = (base.mechanism.joints[self.joint].coordinate(base, self.coordinate)
                   - kit.value(self.free_angle, f"{where} 'free_angle'"))
        return 0.5 * kit.value(self.stiffness, f"{where} 'stiffness'") * stretch**2

    def __post_init__(self):
        where = f"force '{self.name}'"
        for key in ("stiffness", "damping", "free_angle", "actuator"):
            setattr(self, key, check_value(getattr(self, key), f"{where} field '{key}'"))

    def energy_exchange(self) -> str | None:
        return _spring_exchange(self)

    def wound_joint(self) -> str | None:
        return self.joint


@register_force
@dataclass
class UserForce(ForceElement):
    """A force given as CasADi expressions of the state.

    ``function(ctx)`` receives the assembly context (CasADi symbols ``ctx.q``, ``ctx.v``,
    ``ctx.t``; dicts by name ``ctx.u`` and ``ctx.p``; and helpers ``ctx.position(body, point)``,
    ``ctx.velocity(body, point)``, ``ctx.angle(body)``, ``ctx.joint_coordinate(name)``).
    With ``body`` given it returns the force (2-vector, global) at ``point`` — or a pair
    (force, torque); without ``body`` it returns a generalized force vector of length n_q.
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    function: Callable
    body: str | None = None
    point: np.ndarray | None = None

    kind = "user"

    @classmethod
    def create(cls, mech, name, function, body=None, point=None):
        mech._unique(mech.forces, "force", name)
        if body is not None:
            mech._body(body, f"force '{name}' field 'body'")
        return cls(name, function, body=body, point=point)

    def terms(self, kit, ctx):
        return kit.user_terms(self, ctx)

    def __post_init__(self):
        if not callable(self.function):
            raise ModelError(f"force '{self.name}' field 'function': expected a callable")
        if self.point is not None:
            self.point = point_vector(self.point, f"force '{self.name}' field 'point'")


@dataclass
class Actuator:
    """A generalized force input u along a joint coordinate (for inverse dynamics and control)."""

    #: what it needs from an analysis (casmbd.model.needs)
    needs: ClassVar[frozenset[str]] = frozenset({"inputs"})

    name: str
    joint: str
    bounds: tuple[float, float] = field(default_factory=lambda: (-np.inf, np.inf))
    coordinate: str | None = None
