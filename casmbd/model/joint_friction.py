"""Joint dissipation: viscous damping and smooth Coulomb friction along one joint coordinate.

A joint coordinate q_j (the angle of a revolute joint, the translation of a prismatic joint)
receives the generalized force

    Q_j = −c q̇_j − F_c tanh(q̇_j / v_s)

with c ≥ 0 the viscous coefficient, F_c ≥ 0 the Coulomb level and v_s > 0 the regularisation
velocity (default :data:`REGULARIZATION` = 1e-3 rad/s or m/s).  The tanh is a smooth stand-in
for the set-valued −F_c sign(q̇_j): it differs from it by at most F_c (1 − tanh(|q̇_j|/v_s)),
so for |q̇_j| ≫ v_s it is the Coulomb force, and through q̇_j = 0 it is a steep viscous law of
slope F_c / v_s (no stiction: a joint under a load below F_c creeps at a small velocity).  The
force acts along the measure s = q_j(q) by virtual work, Q = −f (∂s/∂q)ᵀ (seed 000,
"Generalized forces", eqs. 6.40–6.48); q̇_j = (∂q_j/∂q) v.  Its power −c q̇_j² − F_c q̇_j
tanh(q̇_j / v_s) ≤ 0 is dissipated, so the element declares ``energy_exchange() = "damper"``.

Reaction-proportional Coulomb level (Adams-style joint friction, ``mu`` > 0):

    F_c = F_0 + μ r |R_⊥|   (an angle: revolute, cylindrical rotation),
    F_c = F_0 + μ |R_⊥|     (a translation: prismatic, cylindrical translation),

with F_0 the constant level (``friction``; the scene's ``coulomb`` or ``preload``), r the
pin/bearing ``radius`` and R_⊥ the joint's constraint force transverse to its axis (the whole
force of a planar revolute; the normal force of a slide).  R_⊥ follows from the multipliers
λ, so the force enters the equations through a symbol N per element that the system replaces
by |R_⊥(q, λ)| (:mod:`casmbd.system.applied_forces`, ``friction_normals``): Q_e is affine in N,
Q_e = Q_e|_{N=0} + G N.  Inverse dynamics and the consistent start solve λ and N together by
a fixed point (:mod:`casmbd.analysis.instant.reaction_friction`); the DAE formulations (``index1``,
``ggl``) use λ directly; the ODE formulations refuse such an element, naming its joint.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import casadi as ca

from casmbd.errors import ModelError
from casmbd.model.forces import ForceElement, may_be_nonzero
from casmbd.model.registry import register_force
from casmbd.model.values import Value, check_value

#: keys of a joint entry's ``friction = {...}`` table in a scene
SCENE_FRICTION_KEYS = ("viscous", "coulomb", "regularization", "mu", "radius", "preload",
                       "stick_slip")
#: joint kinds whose reaction transverse to the axis the Coulomb level may follow
REACTION_KINDS = ("revolute", "prismatic", "cylindrical")

#: default regularisation velocity v_s of the Coulomb term (rad/s or m/s)
REGULARIZATION = 1e-3


@register_force
@dataclass
class JointFriction(ForceElement):
    """Viscous damping and smooth Coulomb friction on one joint coordinate.

    Generalized force Q_j = −c q̇_j − F_c tanh(q̇_j / v_s) (c ``damping``, F_c ``friction``,
    v_s ``regularization``, default 1e-3).  ``coordinate`` defaults to the joint's first
    coordinate (the angle of a revolute joint, the translation of a prismatic one).  With
    ``mu`` > 0 the Coulomb level is F_c = ``friction`` + μ r |R_⊥| (r ``radius``, required
    for an angle and refused for a translation, where the arm is 1; see the module
    docstring).  No potential energy.
    """

    name: str
    joint: str
    damping: Value = 0.0
    friction: Value = 0.0
    regularization: Value = REGULARIZATION
    coordinate: str | None = None
    mu: Value = 0.0
    radius: Value | None = None
    #: exact Coulomb law: stuck (the joint coordinate held, its multiplier the friction) or
    #: sliding with the force −F_c sign(q̇) — switched at events (casmbd.analysis.stick_slip)
    stick_slip: bool = False

    kind = "joint_friction"

    @property
    def needs(self) -> frozenset[str]:
        """What it needs from an analysis (:mod:`casmbd.model.needs`): the exact law switches
        at events; a level μ r |R⊥| depends on the joint reaction; else nothing special."""
        found = set()
        if self.stick_slip:
            found.add("stick_slip")
        if not (isinstance(self.mu, (int, float)) and self.mu == 0.0):
            found.add("reaction_forces")
        return frozenset(found)
    scene_keys = frozenset({"joint", "coordinate", "damping", "friction", "regularization",
                            "mu", "radius", "stick_slip"})

    @classmethod
    def create(cls, mech, name, joint, damping=0.0, friction=0.0,
               regularization=REGULARIZATION, coordinate=None, mu=0.0, radius=None,
               stick_slip=False):
        mech._unique(mech.forces, "force", name)
        mech._nonnegative(name, damping=damping, friction=friction, mu=mu)
        regularization = check_value(regularization, f"force '{name}' field 'regularization'")
        if isinstance(regularization, float) and regularization <= 0.0:
            raise ModelError(f"force '{name}' field 'regularization': must be > 0, got "
                             f"{regularization}")
        joint_obj = mech._joint(joint, f"force '{name}' field 'joint'")  # needs a coordinate
        if coordinate is None:
            coordinate = joint_obj.coordinate_names[0]
        elif coordinate not in joint_obj.coordinate_names:
            raise ModelError(f"force '{name}' field 'coordinate': joint '{joint}' has no "
                             f"coordinate '{coordinate}' (known: "
                             f"{', '.join(joint_obj.coordinate_names)})")
        _check_reaction(name, joint_obj, coordinate, mu, radius)
        if stick_slip:
            if not isinstance(stick_slip, bool):
                raise ModelError(f"force '{name}' field 'stick_slip': expected true or false")
            level = check_value(friction, f"force '{name}' field 'friction'")
            if not (isinstance(level, float) and level > 0.0) or may_be_nonzero(mu):
                raise ModelError(f"force '{name}' field 'stick_slip': the exact Coulomb law "
                                 "needs a constant level 'friction' > 0 (no 'mu')")
            for param in stick_slip_parameters(name):
                mech.add_parameter(param, 0.0)
        return cls(name, joint, damping, friction, regularization, coordinate=coordinate,
                   mu=mu, radius=radius, stick_slip=bool(stick_slip))

    @classmethod
    def from_scene(cls, mech, e):
        return mech.add("joint_friction", e.string("name"), e.string("joint"),
                        damping=e.nonnegative("damping"), friction=e.nonnegative("friction"),
                        regularization=e.value("regularization", REGULARIZATION),
                        coordinate=e.string("coordinate", required=False),
                        mu=e.nonnegative("mu"),
                        radius=e.value("radius") if e.has("radius") else None,
                        stick_slip=bool(e.data.get("stick_slip", False)))

    def reaction_joint(self) -> str | None:
        """The joint whose transverse reaction sets the Coulomb level (``mu`` > 0), else
        None (read by :mod:`casmbd.system.applied_forces`)."""
        return self.joint if may_be_nonzero(self.mu) else None

    def terms(self, kit, ctx):
        base, where = kit.ctx, f"force '{self.name}' field"
        joint = base.mechanism.joints[self.joint]
        rate = ca.jtimes(joint.coordinate(base, self.coordinate), base.q, base.v)
        resist = kit.value(self.damping, f"{where} 'damping'") * rate
        level = kit.value(self.friction, f"{where} 'friction'") if may_be_nonzero(self.friction) \
            else None
        if may_be_nonzero(self.mu):  # μ r N, N the symbol the system sets to |R_⊥(q, λ)|
            arm = 1.0 if self.radius is None else kit.value(self.radius, f"{where} 'radius'")
            slip = kit.value(self.mu, f"{where} 'mu'") * arm * kit.normal(self.name)
            level = slip if level is None else level + slip
        if level is not None and self.stick_slip:  # −F_c σ, σ = ±1 sliding, 0 stuck
            resist = resist + level * kit.value(stick_slip_parameters(self.name)[0],
                                                f"{where} 'stick_slip'")
        elif level is not None:
            resist = resist + level * ca.tanh(
                rate / kit.value(self.regularization, f"{where} 'regularization'"))
        return [kit.term("measure", joint.coordinate(ctx, self.coordinate), -resist)]

    def __post_init__(self):
        for key in ("damping", "friction", "regularization", "mu") + (
                () if self.radius is None else ("radius",)):
            setattr(self, key, check_value(getattr(self, key),
                                           f"force '{self.name}' field '{key}'"))

    def energy_exchange(self) -> str | None:
        return "damper" if any(may_be_nonzero(v) for v in (self.damping, self.friction, self.mu)) \
            else None


def stick_slip_parameters(name: str) -> tuple[str, str]:
    """The parameters of an exact stick-slip element: its sliding direction σ (±1 sliding,
    0 stuck) and the joint coordinate at which it is stuck."""
    ident = re.sub(r"\W", "_", name)
    return f"{ident}_slip_sign", f"{ident}_stuck_at"


def _check_reaction(name: str, joint, coordinate: str, mu: Value, radius: Value | None) -> None:
    """Where the Coulomb level follows the reaction: a revolute, prismatic or cylindrical
    joint; a radius (> 0) for an angle, none for a translation."""
    where = f"force '{name}'"
    if not may_be_nonzero(mu):
        if radius is not None:
            raise ModelError(f"{where} field 'radius': only used with 'mu' > 0")
        return
    if joint.kind not in REACTION_KINDS:
        raise ModelError(f"{where} field 'mu': joint '{joint.name}' is a {joint.kind} joint; "
                         f"reaction-proportional friction needs one of "
                         f"{', '.join(REACTION_KINDS)}")
    angle = coordinate == "angle"
    if angle and radius is None:
        raise ModelError(f"{where} field 'radius': the friction torque of the angle of joint "
                         f"'{joint.name}' is μ r |R| and needs the pin/bearing radius r")
    if not angle and radius is not None:
        raise ModelError(f"{where} field 'radius': the translation of joint '{joint.name}' "
                         "has the friction force μ |R| (no radius)")
    if radius is not None:
        radius = check_value(radius, f"{where} field 'radius'")
        if isinstance(radius, float) and radius <= 0.0:
            raise ModelError(f"{where} field 'radius': must be > 0, got {radius}")


def joint_friction_from_scene(mech, e) -> JointFriction:
    """The ``friction = {viscous, coulomb, regularization, mu, radius, preload}`` table of a
    ``[[joints]]`` entry ``e`` as a ``joint_friction`` element named "<joint>.friction".

    ``viscous`` is c, ``coulomb`` (or Adams' ``preload``, not both) is F_0, ``mu`` and
    ``radius`` make the level F_0 + μ r |R_⊥| (see the module docstring).  Errors name the
    entry and the key ``friction.<key>``.
    """
    raw = e.data["friction"]
    if not isinstance(raw, dict):
        raise e.error("friction", "expected a table such as { viscous = 0.1, coulomb = 0.5 } "
                      f"(keys: {', '.join(SCENE_FRICTION_KEYS)}), got {raw!r}")
    unknown = sorted(set(raw) - set(SCENE_FRICTION_KEYS))
    if unknown:
        raise e.error("friction", f"unknown key(s) {', '.join(unknown)} (allowed: "
                      f"{', '.join(SCENE_FRICTION_KEYS)})")
    if "coulomb" in raw and "preload" in raw:
        raise e.error("friction", "give 'coulomb' or 'preload' (the same constant level), "
                      "not both")
    # a view of the sub-table whose keys read "friction.<key>" in error messages
    sub = type(e)(e.table, e.index, {f"friction.{k}": v for k, v in raw.items()}, e.params)
    sub.name = e.name
    level = "friction.preload" if "preload" in raw else "friction.coulomb"
    joint = e.string("name")
    return mech.add("joint_friction", mech._generate(f"{joint}.friction"), joint,
                    damping=sub.nonnegative("friction.viscous"),
                    friction=sub.nonnegative(level),
                    regularization=sub.value("friction.regularization", REGULARIZATION),
                    mu=sub.nonnegative("friction.mu"),
                    radius=sub.value("friction.radius") if "radius" in raw else None,
                    stick_slip=raw.get("stick_slip", False))
