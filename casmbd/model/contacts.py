"""Unilateral elements: contacts and joint limits (issue 24), g(q) ≥ 0.

Each element measures one or more *gaps* g_k(q) that must stay non-negative:

* :class:`PlaneContact` — a sphere (radius r ≥ 0; r = 0 a point) fixed on a body against a
  ground plane through ``origin`` with unit ``normal``: g = n·(r_c(q) − o) − r, r_c the sphere's
  centre;
* :class:`SphereContact` — two spheres on two bodies: g = |r_1 − r_2| − (r_1 + r_2);
* :class:`JointLimit` — stops on a joint coordinate q_j: g = q_j − lower and g = upper − q_j.

Two contact models, chosen per element (``model``; registered in
:mod:`casmbd.model.contact_models`, which says what each needs and how it acts):

* ``"impact"`` (non-smooth, event-driven): the integrator stops where a gap reaches zero (root
  finding on g), the velocities jump by Newton's restitution law G v⁺ = −e G v⁻ with impulses
  solved together with the bilateral constraints on the mass matrix (Pfeiffer & Glocker,
  *Multibody Dynamics with Unilateral Contacts*, 1996, ch. 6; Glocker, *Set-Valued Force Laws*,
  2001), Coulomb's law at the contact on the impulse level (stick if |P_t| ≤ μ P_n, else slip),
  and a contact that stops bouncing is closed — its gap becomes a bilateral constraint — until
  its normal force would pull (detach); see :mod:`casmbd.analysis.events.events`;
* ``"compliant"``: a penalty force F_n = k δ^e + c(δ) δ̇ on the penetration δ = −g > 0, with the
  damping c(δ) = STEP(δ, 0, 0, d_max, c) of Adams' IMPACT function (it grows from 0 to c over
  the penetration depth d_max, so the force is continuous at first contact), and regularised
  Coulomb friction μ F_n tanh(v_t / v_s) (:class:`CompliantContact`, a force element).

The elements only say what their gaps and directions are; the system layer writes them with
the context and the analyses handle events (layers point one way).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND, scalar, vector
from casmbd.model.contact_models import CONTACT_MODELS, acts_at_events, contact_model
from casmbd.model.forces import ForceElement
from casmbd.model.joints import Joint
from casmbd.model.registry import register_force
from casmbd.model.values import Value, check_value, numeric, resolve

__all__ = ["CONTACT_MODELS", "CONTACT_SHAPES", "CompliantContact", "GapClosure", "JointLimit",
           "PlaneContact",
           "RollingClosure", "SphereContact", "Unilateral", "adams_step", "contact_shape",
           "register_contact_shape"]

#: default regularisation velocity of compliant friction (m/s)
FRICTION_VELOCITY = 1e-4


def adams_step(x, x0: float, h0: float, x1: float, h1: float):
    """Adams' cubic STEP(x, x0, h0, x1, h1): h0 below x0, h1 above x1, the cubic
    h0 + (h1 − h0) s² (3 − 2 s), s = (x − x0)/(x1 − x0), in between (C¹)."""
    s = ca.fmin(ca.fmax((x - x0) / (x1 - x0), 0.0), 1.0)
    return h0 + (h1 - h0) * s * s * (3.0 - 2.0 * s)


def _unit(value, where: str, dim: int) -> np.ndarray:
    """The direction of a finite non-zero vector, n / |n| (scaled by its largest entry first:
    |[0, 1e300]|² overflows, and n / inf would be the zero vector)."""
    vec = vector(value, where, dim)  # finite, or a ModelError naming ``where``
    scale = float(np.max(np.abs(vec)))
    if scale == 0.0:
        raise ModelError(f"{where}: must be a non-zero vector, got {value!r}")
    vec = vec / scale
    return vec / float(np.linalg.norm(vec))


def tangents(normal: np.ndarray) -> np.ndarray:
    """Unit tangent directions of a plane with unit ``normal``: one (rows) in the plane, two
    orthonormal ones in space (deterministic)."""
    n = np.asarray(normal, float)
    if n.size == 2:
        return np.array([[n[1], -n[0]]])
    trial = np.zeros(3)
    trial[int(np.argmin(np.abs(n)))] = 1.0
    t1 = trial - n * float(n @ trial)
    t1 /= np.linalg.norm(t1)
    return np.array([t1, np.cross(n, t1)])


@dataclass
class Unilateral:
    """What every unilateral element has: a name, its gaps' restitution and friction, its
    model.  Subclasses write ``gaps(ctx)`` (a column of g_k(q)) and their labels."""

    name: str
    restitution: Value = 0.0
    friction: float = 0.0
    model: str = "impact"

    #: the event name of a gap reaching zero ("impact" for contacts, "limit" for stops)
    event_kind: ClassVar[str] = "impact"
    #: the rebound speed below which this element's gaps close instead of bouncing (m/s);
    #: None: the run's (``simulate(rest_velocity=)``); set by ``Mechanism.add_contact``
    rest_velocity: ClassVar[float | None] = None

    @property
    def where(self) -> str:
        return f"contact '{self.name}'" if self.event_kind == "impact" else \
            f"joint limit '{self.name}'"

    def _check(self) -> None:
        where = self.where
        self.restitution = check_value(self.restitution, f"{where} field 'restitution'")
        if isinstance(self.restitution, float) and not 0.0 <= self.restitution <= 1.0:
            raise ModelError(f"{where} field 'restitution': must be in [0, 1], got "
                             f"{self.restitution}")
        self.friction = scalar(self.friction, f"{where} field 'friction'")
        if self.friction < 0.0:
            raise ModelError(f"{where} field 'friction': must be >= 0, got {self.friction}")
        contact_model(self.model, where)  # a registered model, or a ModelError naming it

    @property
    def labels(self) -> tuple[str, ...]:
        return ("gap",)

    @property
    def needs(self) -> frozenset[str]:
        """What it needs from an analysis (:mod:`casmbd.model.needs`): its model's
        (:class:`~casmbd.model.contact_models.ContactModel`): the impact model acts at events
        (and, with friction at a closed contact, switches sliding and sticking); the compliant
        model is a force element (``"<name>.force"``) and needs nothing."""
        model = CONTACT_MODELS[self.model]
        return model.needs | model.sliding_needs if slides(self) else model.needs

    def gaps(self, ctx) -> ca.SX:
        raise NotImplementedError

    def restitution_at(self, ctx) -> ca.SX:
        """Newton's restitution e as an expression of the parameters (a number, or an
        expression string evaluated at run time: a sweep or a sensitivity may vary it)."""
        return resolve(self.restitution, ctx.t, ctx.p, f"{self.where} field 'restitution'")

    def restitution_value(self, parameters) -> float:
        """e at the parameter values ``parameters`` (name -> value)."""
        return numeric(self.restitution, parameters, f"{self.where} field 'restitution'")

    def check_values(self, parameters) -> None:
        """Check the values given as expressions at the parameters' defaults (when the
        element is added to a mechanism): e in [0, 1] (and a joint limit's lower < upper)."""
        e = self.restitution_value(parameters)
        if not 0.0 <= e <= 1.0:
            raise ModelError(f"{self.where} field 'restitution': must be in [0, 1], got {e} "
                             "at the parameters' values")

    def tangential_velocity(self, ctx, k: int) -> ca.SX | None:
        """Tangential velocity components of the contact point of gap ``k`` (None: no
        friction direction, e.g. a joint limit)."""
        return None

    @property
    def bodies(self) -> tuple[str, ...]:
        return ()

    def spheres(self) -> list[tuple[str, np.ndarray, float]]:
        """The spheres the 3-D view draws: (body, global point at the design pose, radius)."""
        return []


#: contact shapes by scene ``[[contacts]] type`` (``Mechanism.add_contact(shape=…)``), each a
#: :class:`Unilateral` subclass with ``shape``, ``scene_args(e, dim)`` (its own keys read from
#: a scene entry), ``create(name, restitution, friction, model, body, point, radius, dim,
#: **keys)`` and optionally ``body_keys`` (keys naming another body) and ``scene_keys`` (its
#: scene keys beyond the shared ones); complete when this module is imported (plane, sphere)
CONTACT_SHAPES: dict[str, type] = {}


def register_contact_shape(cls: type | None = None, *, replace: bool = False):
    """Register a contact shape class under its ``shape`` (a class decorator, bare or
    ``@register_contact_shape(replace=True)``); a taken name is a :class:`ModelError` unless
    ``replace``."""
    if cls is None:
        return lambda c: register_contact_shape(c, replace=replace)
    name = getattr(cls, "shape", "")
    if not (isinstance(cls, type) and issubclass(cls, Unilateral) and name):
        raise ModelError(f"a contact shape is a Unilateral subclass with a 'shape' name, got "
                         f"{cls!r}")
    if name in CONTACT_SHAPES and not replace:
        raise ModelError(f"contact shape '{name}' is already registered "
                         f"({CONTACT_SHAPES[name].__name__}); pass replace=True to replace it")
    CONTACT_SHAPES[name] = cls
    return cls


def contact_shape(name: str, where: str) -> type:
    """The registered shape ``name`` (a :class:`ModelError` at ``where`` listing them)."""
    if name not in CONTACT_SHAPES:
        raise ModelError(f"{where}: unknown contact shape {name!r} (allowed: "
                         f"{', '.join(CONTACT_SHAPES)})")
    return CONTACT_SHAPES[name]


@register_contact_shape
@dataclass
class PlaneContact(Unilateral):
    """A sphere of radius ``radius`` centred at the global ``point`` (initial pose) on
    ``body`` against the ground plane through ``origin`` with normal ``normal``."""

    shape: ClassVar[str] = "plane"
    body_keys: ClassVar[tuple[str, ...]] = ()
    scene_keys: ClassVar[frozenset[str]] = frozenset({"origin", "normal"})

    body: str = ""
    point: np.ndarray = field(default_factory=lambda: np.zeros(2))
    radius: float = 0.0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(2))
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))
    dimension: int = 2

    def __post_init__(self):
        self._check()
        where = f"contact '{self.name}' field"
        self.point = vector(self.point, f"{where} 'point'", self.dimension)
        self.origin = vector(self.origin, f"{where} 'origin'", self.dimension)
        self.normal = _unit(self.normal, f"{where} 'normal'", self.dimension)
        self.radius = scalar(self.radius, f"{where} 'radius'")
        if self.radius < 0.0:
            raise ModelError(f"{where} 'radius': must be >= 0, got {self.radius}")

    @staticmethod
    def scene_args(e, dim: int) -> dict:
        return {"origin": e.vector("origin", dim, default=[0.0] * dim),
                "normal": e.vector("normal", dim, required=False)}

    @classmethod
    def create(cls, name, restitution, friction, model, body, point, radius, dim,
               origin=None, normal=None, **ignored) -> PlaneContact:
        up = [0.0] * dim
        up[-1] = 1.0
        return cls(name, restitution, friction, model, body, point, radius,
                   [0.0] * dim if origin is None else origin, up if normal is None else normal,
                   dim)

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body,)

    def spheres(self) -> list[tuple[str, np.ndarray, float]]:
        return [(self.body, self.point, self.radius)]

    def centre(self, ctx) -> ca.SX:
        return ctx.position(self.body, self.point)

    def gaps(self, ctx) -> ca.SX:
        return ca.dot(ca.DM(self.normal), self.centre(ctx) - ca.DM(self.origin)) - self.radius

    def tangential_velocity(self, ctx, k: int = 0) -> ca.SX:
        """t·v_P of the touching material point P = r_c − r n: ṙ_c + ω × (−r n)."""
        vel = ca.jtimes(self.centre(ctx), ctx.q, ctx.v)
        if self.radius:
            omega = ctx.angular_velocity(self.body)
            arm = ca.DM(-self.radius * self.normal)
            vel = vel + (omega * ca.vertcat(-arm[1], arm[0]) if self.dimension == 2
                         else ca.cross(omega, arm))
        return ca.mtimes(ca.DM(tangents(self.normal)), vel)


@register_contact_shape
@dataclass
class SphereContact(Unilateral):
    """Two spheres: radius ``radius1`` at ``point1`` on ``body1``, ``radius2`` at ``point2`` on
    ``body2`` (global points at the initial pose)."""

    shape: ClassVar[str] = "sphere"
    body_keys: ClassVar[tuple[str, ...]] = ("body2",)
    scene_keys: ClassVar[frozenset[str]] = frozenset({"body2", "point2", "radius2"})

    body1: str = ""
    body2: str = ""
    point1: np.ndarray = field(default_factory=lambda: np.zeros(2))
    point2: np.ndarray = field(default_factory=lambda: np.zeros(2))
    radius1: float = 0.0
    radius2: float = 0.0
    dimension: int = 2

    def __post_init__(self):
        self._check()
        where = f"contact '{self.name}' field"
        self.point1 = vector(self.point1, f"{where} 'point1'", self.dimension)
        self.point2 = vector(self.point2, f"{where} 'point2'", self.dimension)
        for key in ("radius1", "radius2"):
            setattr(self, key, scalar(getattr(self, key), f"{where} '{key}'"))
            if getattr(self, key) < 0.0:
                raise ModelError(f"{where} '{key}': must be >= 0")
        if self.friction:
            raise ModelError(f"{where} 'friction': sphere-sphere contacts are frictionless "
                             "in this version")

    @staticmethod
    def scene_args(e, dim: int) -> dict:
        return {"body2": e.string("body2"), "point2": e.vector("point2", dim),
                "radius2": e.number("radius2", 0.0)}

    @classmethod
    def create(cls, name, restitution, friction, model, body, point, radius, dim,
               body2=None, point2=None, radius2=0.0, **ignored) -> SphereContact:
        if body2 is None:
            raise ModelError(f"contact '{name}' field 'body2': a sphere contact needs body2")
        return cls(name, restitution, friction, model, body, body2, point,
                   point2 if point2 is not None else point, radius, radius2, dim)

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body1, self.body2)

    def spheres(self) -> list[tuple[str, np.ndarray, float]]:
        return [(self.body1, self.point1, self.radius1),
                (self.body2, self.point2, self.radius2)]

    def gaps(self, ctx) -> ca.SX:
        d = ctx.position(self.body2, self.point2) - ctx.position(self.body1, self.point1)
        return ca.sqrt(ca.dot(d, d)) - (self.radius1 + self.radius2)


@dataclass
class JointLimit(Unilateral):
    """Stops ``lower`` ≤ q_j ≤ ``upper`` on a joint coordinate (either may be None)."""

    joint: str = ""
    coordinate: str | None = None
    lower: Value | None = None
    upper: Value | None = None

    event_kind: ClassVar[str] = "limit"

    def __post_init__(self):
        self._check()
        where = f"joint '{self.joint}' field"
        for key in ("lower", "upper"):
            value = getattr(self, key)
            if value is not None:  # a number, or an expression of the parameters
                setattr(self, key, check_value(value, f"{where} '{key}'"))
        if self.lower is None and self.upper is None:
            raise ModelError(f"joint '{self.joint}': a limit needs 'lower' or 'upper'")
        if isinstance(self.lower, float) and isinstance(self.upper, float) and \
                self.lower >= self.upper:
            raise ModelError(f"joint '{self.joint}' field 'upper': must be > lower "
                             f"({self.lower}), got {self.upper}")

    def check_values(self, parameters) -> None:
        super().check_values(parameters)
        if self.lower is None or self.upper is None:
            return
        where = f"joint '{self.joint}' field"
        lower = numeric(self.lower, parameters, f"{where} 'lower'")
        upper = numeric(self.upper, parameters, f"{where} 'upper'")
        if lower >= upper:
            raise ModelError(f"{where} 'upper': must be > lower ({lower}), got {upper} at the "
                             "parameters' values")

    def bound(self, ctx, key: str) -> ca.SX:
        """The stop ``key`` ("lower" or "upper") as an expression of the parameters."""
        return resolve(getattr(self, key), ctx.t, ctx.p, f"joint '{self.joint}' field '{key}'")

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(k for k in ("lower", "upper") if getattr(self, k) is not None)

    def gaps(self, ctx) -> ca.SX:
        coord = ctx.mechanism.joints[self.joint].coordinate(ctx, self.coordinate)
        rows = []
        if self.lower is not None:
            rows.append(coord - self.bound(ctx, "lower"))
        if self.upper is not None:
            rows.append(self.bound(ctx, "upper") - coord)
        return ca.vertcat(*rows)

    @property
    def bodies(self) -> tuple[str, ...]:
        return ()


def slide_parameters(name: str) -> tuple[str, str]:
    """The parameters of a closed frictional plane contact (plane scenes): its sliding
    direction σ (±1, 0 stuck) and the tangential position at which it sticks."""
    ident = re.sub(r"\W", "_", name)
    return f"{ident}_slide_sign", f"{ident}_stuck_at"


def slide_direction_parameters(name: str) -> tuple[str, str]:
    """The parameters of a closed frictional plane contact in space: the unit sliding
    direction ŝ = (ŝ_1, ŝ_2) in the contact's tangent basis (:func:`tangents`) at the start of
    the slide, the direction of the friction force while |v_t| < :data:`SLIP_VELOCITY` and the
    reference of the event row ŝ·v_t."""
    ident = re.sub(r"\W", "_", name)
    return f"{ident}_slide_dir1", f"{ident}_slide_dir2"


#: the speed δ (m/s) of the direction of friction of a contact sliding in space,
#: (v_t + δ ŝ)/|v_t + δ ŝ|: exactly v_t/|v_t| whenever the slip is along the stored direction
#: ŝ (which the integrator re-anchors to the slip as it turns), and ŝ as a slide starts from
#: rest — where v_t/|v_t| alone is singular (the direction of 1e-10 m/s of drift, a
#: perpendicular stiffness μ g/|v_t| no integrator resolves)
SLIP_VELOCITY = 1e-6


def slides(element) -> bool:
    """True for a plane contact with friction whose closed phases carry Coulomb friction:
    sliding (−μ N along the slip) or stuck (its tangential position held in the plane, the
    touching point's velocity held at zero in space)."""
    return (isinstance(element, PlaneContact) and acts_at_events(element)
            and element.friction > 0.0)


def tangential_position(element: PlaneContact, ctx) -> ca.SX:
    """s(q) with ṡ the tangential velocity of the touching material point (plane):
    s = t·r_c + r θ (t = tangents(n)[0]; a point contact: t·r_c)."""
    t = ca.DM(tangents(element.normal)[0])
    s = ca.dot(t, element.centre(ctx))
    return s + element.radius * ctx.angle(element.body) if element.radius else s


class TangentClosure(Joint):
    """A stuck frictional plane contact: s(q) − s_stuck = 0 (:func:`tangential_position`,
    s_stuck a parameter); its multiplier is the friction force that holds it.  Not a scene
    kind: made by :mod:`casmbd.analysis.events.events` for the phases in which the contact
    sticks."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, element: PlaneContact):
        self.name = f"{element.name}.stick"
        self.body1, self.body2 = GROUND, element.body
        self.element = element
        self.labels = ("gap",)
        self.coordinate_names = ()

    dimensions: ClassVar[tuple[int, ...]] = (2,)
    drawing: ClassVar[str] = "none"

    def equations(self, ctx) -> ca.SX:
        return tangential_position(self.element, ctx) - ctx.p[slide_parameters(
            self.element.name)[1]]

    def reaction_point(self):
        return None


class RollingClosure(Joint):
    """A stuck frictional plane contact in space: the touching material point does not slide,
    v_t = T (ṙ_c + ω × (−r n)) = 0 (two rows in the tangent basis T = :func:`tangents`) — for
    a sphere, rolling without slipping, a non-holonomic constraint (Pfeiffer & Glocker 1996,
    ch. 7: the sticking contact as a bilateral constraint on the relative velocity).  Its
    position rows are zero and its velocity rows are :meth:`velocity_equations` (the system
    takes C_q from ∂W/∂v); the multipliers are the friction force that holds it (−λ in the
    tangent basis).  Not a scene kind: made by :mod:`casmbd.analysis.events.events` for the phases
    in which the contact sticks."""

    def __init__(self, element: PlaneContact):
        self.name = f"{element.name}.stick"
        self.body1, self.body2 = GROUND, element.body
        self.element = element
        self.labels = ("gap", "gap_2")
        self.coordinate_names = ()

    dimensions: ClassVar[tuple[int, ...]] = (3,)
    drawing: ClassVar[str] = "none"

    def equations(self, ctx) -> ca.SX:
        return ca.SX.zeros(2)

    def velocity_equations(self, ctx) -> ca.SX:
        """W(q, v) = v_t, the rows C_q v + C_t of the non-holonomic constraint W = 0."""
        return self.element.tangential_velocity(ctx)

    def reaction_point(self):
        return None


@register_force
@dataclass
class ContactSlide(ForceElement):
    """Coulomb friction of a closed, sliding plane contact: −μ N σ along the tangential
    velocity v_t of the touching point, N the contact's normal force — the multiplier of its
    closure ``closure`` (reaction-proportional: the symbol N of :mod:`casmbd.system.applied_forces`,
    solved with λ by the DAE formulations) — and σ = ±1 the sliding direction (a parameter set
    per phase by the event-driven integrator).  Not a scene kind."""

    name: str
    contact: PlaneContact = None
    closure: str = ""

    kind = "contact_slide"
    #: friction −μ N σ from the closure's multiplier, σ switched at events
    needs: ClassVar[frozenset[str]] = frozenset({"reaction_forces", "contact_friction"})
    scene_keys = None

    @classmethod
    def create(cls, mech, name, contact, closure):
        return cls(name, contact, closure)

    def reaction_joint(self) -> str:
        return self.closure

    def terms(self, kit, ctx):
        """The friction force f_t at the touching point P = r_c − r n, as a force F at the
        sphere's centre and the torque (−r n) × F on its body — virtual work
        (∂ṙ_c/∂v)ᵀ F + (∂ω/∂v)ᵀ τ = (∂v_t/∂v)ᵀ f_t, which the joint reactions can read.  In the
        plane F = −μ N σ t; in space F = −μ N σ Tᵀ d along the 2-D tangential velocity v_t of
        P, d = (v_t + δ ŝ)/|v_t + δ ŝ| (:data:`SLIP_VELOCITY`; = v_t/|v_t| for a slip along the
        stored direction ŝ, = ŝ as a slide starts from rest), and d = ŝ where ŝ·v_t ≤ 0, past
        the instant it stops."""
        base, contact = kit.ctx, self.contact
        where = f"contact '{contact.name}' field 'friction'"
        sign = kit.value(slide_parameters(contact.name)[0], where)
        magnitude = -contact.friction * kit.normal(self.name) * sign
        basis = tangents(contact.normal)
        if contact.dimension == 2:
            force = ca.DM(basis[0]) * magnitude
            torque = contact.radius * magnitude  # (−r n) × t = r
        else:
            vt = contact.tangential_velocity(base)
            stored = ca.vertcat(*[kit.value(par, where) for par in
                                  slide_direction_parameters(contact.name)])
            # past the instant the slip stops (ŝ·v_t < 0, before the event is located) the
            # force keeps the direction ŝ, as σ does in the plane: the integrator steps
            # through the stop smoothly instead of chattering about v_t = 0
            blend = vt + SLIP_VELOCITY * stored
            direction = ca.if_else(ca.dot(stored, vt) > 0.0,
                                   blend / ca.sqrt(ca.fmax(ca.dot(blend, blend), 1e-300)),
                                   stored)
            force = ca.mtimes(ca.DM(basis.T), magnitude * direction)
            torque = ca.cross(ca.DM(-contact.radius * contact.normal), force)
        terms = [kit.term("measure", contact.centre(ctx), force)]
        if contact.radius:
            terms.append(kit.term("torque", None, torque, contact.body))
        return terms

    def report_names(self, dimension):
        return ()

    def energy_exchange(self) -> str | None:
        return "damper"


class GapClosure(Joint):
    """A closed unilateral gap as a bilateral constraint g_k(q) = 0 (the contact or stop is
    active); made by :func:`casmbd.analysis.events.events` for the phase in which the element stays
    in contact.  Not a scene kind."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, element: Unilateral, k: int, body1: str = GROUND,
                 body2: str = GROUND):
        self.name = f"{element.name}.{element.labels[k]}"
        self.body1, self.body2 = body1, body2
        self.element, self.k = element, k
        self.labels = ("gap",)
        self.coordinate_names = ()

    dimensions: ClassVar[tuple[int, ...]] = (2, 3)
    drawing: ClassVar[str] = "none"

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body1, self.body2)

    def equations(self, ctx) -> ca.SX:
        return ca.vec(self.element.gaps(ctx))[self.k]

    def reaction_point(self):
        return None


@register_force
@dataclass
class CompliantContact(ForceElement):
    """The compliant model of a unilateral element (module docstring): along each gap,
    F_n = k δ^e + STEP(δ, 0, 0, d_max, c) δ̇ for δ = −g > 0 (0 otherwise), acting by virtual
    work along g (Q = (∂g/∂q)ᵀ F_n), and friction −μ F_n tanh(v_t/v_s) along the tangential
    velocity of the contact point."""
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    element: Unilateral = None
    stiffness: float = 1e6
    exponent: float = 1.5
    damping: float = 0.0
    penetration: float = 1e-4
    friction_velocity: float = FRICTION_VELOCITY

    kind = "compliant_contact"
    scene_keys = None  # made from a [[contacts]] entry or a joint's limits

    @classmethod
    def create(cls, mech, name, element, stiffness=1e6, exponent=1.5, damping=0.0,
               penetration=1e-4, friction_velocity=FRICTION_VELOCITY):
        mech._unique(mech.forces, "force", name)
        for key, value in (("stiffness", stiffness), ("exponent", exponent),
                           ("penetration", penetration),
                           ("friction_velocity", friction_velocity)):
            if scalar(value, f"contact '{element.name}' field '{key}'") <= 0.0:
                raise ModelError(f"contact '{element.name}' field '{key}': must be > 0, got "
                                 f"{value}")
        if scalar(damping, f"contact '{element.name}' field 'damping'") < 0.0:
            raise ModelError(f"contact '{element.name}' field 'damping': must be >= 0")
        return cls(name, element, float(stiffness), float(exponent), float(damping),
                   float(penetration), float(friction_velocity))

    def _normal(self, base, gap) -> ca.SX:
        """F_n(δ, δ̇) ≥ 0 of one gap, δ = −g (module docstring)."""
        delta = ca.fmax(-gap, 0.0)
        rate = -ca.jtimes(gap, base.q, base.v)
        damp = adams_step(delta, 0.0, 0.0, self.penetration, self.damping)
        normal = ca.if_else(delta > 0.0, self.stiffness * delta ** self.exponent
                            + damp * rate, 0.0)
        return ca.fmax(normal, 0.0)  # a contact never pulls

    def report_names(self, dimension):
        """Per gap: its value and the normal force (a contact: "gap" [m], "normal_force"
        [N]; a stop: "lower_gap", "lower_force" … in the joint coordinate's units)."""
        if not hasattr(self.element, "joint"):
            return (("gap", "m"), ("normal_force", "N"))
        return tuple((f"{label}_{q}", "") for label in self.element.labels
                     for q in ("gap", "force"))

    def reports(self, kit):
        gaps = ca.vec(self.element.gaps(kit.ctx))
        out = []
        for k in range(gaps.numel()):
            out += [gaps[k], self._normal(kit.ctx, gaps[k])]
        return out

    def terms(self, kit, ctx):
        base = kit.ctx
        gaps = ca.vec(self.element.gaps(ctx))
        gaps_now = ca.vec(self.element.gaps(base))
        terms = []
        for k in range(gaps.numel()):
            normal = self._normal(base, gaps_now[k])
            terms.append(kit.term("measure", gaps[k], normal))
            vt = self.element.tangential_velocity(base, k)
            if vt is not None and self.element.friction:
                # friction opposes the slip of the contact point, by virtual work along the
                # point's tangential displacement: Q = (∂v_t/∂v)ᵀ f_t
                f_t = -self.element.friction * normal * ca.tanh(vt / self.friction_velocity)
                terms.append(kit.term("generalized", None,
                                      ca.mtimes(ca.jacobian(vt, base.v).T, f_t), None,
                                      self.name))
        return terms

    def energy_exchange(self) -> str | None:
        return "damper"
