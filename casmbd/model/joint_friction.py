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
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from casmbd.errors import ModelError
from casmbd.model.forces import ForceElement, _nonzero
from casmbd.model.registry import register_force
from casmbd.model.values import Value, check_value

#: default regularisation velocity v_s of the Coulomb term (rad/s or m/s)
REGULARIZATION = 1e-3


@register_force
@dataclass
class JointFriction(ForceElement):
    """Viscous damping and smooth Coulomb friction on one joint coordinate.

    Generalized force Q_j = −c q̇_j − F_c tanh(q̇_j / v_s) (c ``damping``, F_c ``friction``,
    v_s ``regularization``, default 1e-3).  ``coordinate`` defaults to the joint's first
    coordinate (the angle of a revolute joint, the translation of a prismatic one).  No
    potential energy.
    """

    name: str
    joint: str
    damping: Value = 0.0
    friction: Value = 0.0
    regularization: Value = REGULARIZATION
    coordinate: str | None = None

    kind = "joint_friction"
    scene_keys = frozenset({"joint", "coordinate", "damping", "friction", "regularization"})

    @classmethod
    def create(cls, mech, name, joint, damping=0.0, friction=0.0,
               regularization=REGULARIZATION, coordinate=None):
        mech._unique(mech.forces, "force", name)
        mech._nonnegative(name, damping=damping, friction=friction)
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
        return cls(name, joint, damping, friction, regularization, coordinate=coordinate)

    @classmethod
    def from_scene(cls, mech, e):
        return mech.add("joint_friction", e.string("name"), e.string("joint"),
                        damping=e.nonnegative("damping"), friction=e.nonnegative("friction"),
                        regularization=e.value("regularization", REGULARIZATION),
                        coordinate=e.string("coordinate", required=False))

    def terms(self, kit, ctx):
        base, where = kit.ctx, f"force '{self.name}' field"
        joint = base.mechanism.joints[self.joint]
        rate = ca.jtimes(joint.coordinate(base, self.coordinate), base.q, base.v)
        resist = kit.value(self.damping, f"{where} 'damping'") * rate
        if _nonzero(self.friction):
            resist = resist + kit.value(self.friction, f"{where} 'friction'") * ca.tanh(
                rate / kit.value(self.regularization, f"{where} 'regularization'"))
        return [kit.term("measure", joint.coordinate(ctx, self.coordinate), -resist)]

    def __post_init__(self):
        for key in ("damping", "friction", "regularization"):
            setattr(self, key, check_value(getattr(self, key),
                                           f"force '{self.name}' field '{key}'"))

    def energy_exchange(self) -> str | None:
        return "damper" if _nonzero(self.damping) or _nonzero(self.friction) else None
