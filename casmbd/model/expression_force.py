"""A force element whose value is an expression of measures of the state (``type =
"expression"``): a nonlinear spring, a controller torque, a drag force written in the scene.

Two forms (:mod:`casmbd.model.measures` lists the measures usable in ``value``):

* on a joint coordinate s = q_j(q) (``joint``, optional ``coordinate``, default the joint's
  first): the generalized force f(q, v, t, p) along s, Q = (∂s/∂q)ᵀ f (positive f drives s
  up, as an actuator; e.g. a cubic spring ``value = "-k1*translation('J') -
  k3*translation('J')**3"`` or a PD torque ``value = "-Kp*(angle('J') - th) -
  Kd*rate('J')"``);
* on a body point (``body``, ``point`` global at the initial pose, default the centre of mass):
  a force F = [fx, fy(, fz)] (``value``) and/or a torque T (``torque``: one value in the plane,
  three in space), global components or body components with ``frame = "body"``;
  Q = (∂r_P/∂q)ᵀ F + (∂ω/∂q̇)ᵀ T.

The generalized force follows by virtual work (seed 000, "Generalized forces", eqs.
6.40–6.48); its Jacobians ∂Q/∂q, ∂Q/∂v (implicit integrators, linearisation, optimal
control) are exact, by CasADi's algorithmic differentiation of the same expressions.  Its work
is not a potential: :meth:`ExpressionForce.energy_exchange` is ``"force"`` (the total energy
changes by the work the element does).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND
from casmbd.model.forces import FRAMES, ForceElement, coordinate_force_unit, point_vector
from casmbd.model.measures import check, expression
from casmbd.model.registry import register_force

_AXES = ("x", "y", "z")


@register_force
@dataclass
class ExpressionForce(ForceElement):
    """A generalized force on a joint coordinate, or a force and/or torque on a body point,
    given by expressions of measures (module docstring).

    ``expressions`` holds the value: one entry on a joint, ``dimension`` components on a body
    (empty: torque only); ``torques`` the torque components (empty: none).  Each entry is a
    number or an expression string, kept as text and resolved when the equations are built.
    """
    #: what it needs from an analysis (casmbd.model.needs): nothing special
    needs: ClassVar[frozenset[str]] = frozenset()

    name: str
    joint: str | None = None
    coordinate: str | None = None
    body: str | None = None
    point: np.ndarray | None = None
    frame: str = "global"
    expressions: tuple = ()
    torques: tuple = ()

    kind = "expression"
    scene_keys = frozenset({"joint", "coordinate", "body", "point", "frame", "value",
                            "torque"})

    @classmethod
    def create(cls, mech, name, joint=None, value=None, coordinate=None, body=None, point=None,
               frame="global", torque=None):
        mech._unique(mech.forces, "force", name)
        where = f"force '{name}'"
        if (joint is None) == (body is None):
            raise ModelError(f"{where}: give 'joint' (a generalized force on its coordinate) "
                             "or 'body' (a force and/or torque on it), not both or neither")
        if joint is not None:
            joint_obj = mech._joint(joint, f"{where} field 'joint'")
            names = tuple(joint_obj.coordinate_names)
            if coordinate is None:
                coordinate = names[0]
            elif coordinate not in names:
                raise ModelError(f"{where} field 'coordinate': joint '{joint}' has no "
                                 f"coordinate '{coordinate}' (known: {', '.join(names)})")
            for key, given in (("point", point), ("torque", torque)):
                if given is not None:
                    raise ModelError(f"{where} field '{key}': a force on joint '{joint}' is "
                                     "one generalized force ('value'); 'point' and 'torque' "
                                     "belong to a force on a body")
            if value is None or isinstance(value, (list, tuple)):
                raise ModelError(f"{where} field 'value': expected one number or expression "
                                 f"(the generalized force on '{joint}'), got {value!r}")
            values = (check(mech, value, f"{where} field 'value'"),)
            return cls(name, joint, coordinate, expressions=values)
        mech._body(body, f"{where} field 'body'")
        if coordinate is not None:
            raise ModelError(f"{where} field 'coordinate': belongs to a force on a joint")
        if value is None and torque is None:
            raise ModelError(f"{where}: give 'value' (the force) and/or 'torque'")
        dim = mech.dimension
        values = ()
        if value is not None:
            values = _components(mech, value, dim, f"{where} field 'value'")
        torques = ()
        if torque is not None:
            size = 1 if dim == 2 else 3
            raw = torque if isinstance(torque, (list, tuple)) else [torque]
            torques = _components(mech, raw, size, f"{where} field 'torque'")
        if point is not None:
            mech._dimension_of(name, "point", len(point))
        return cls(name, None, None, body, point, frame, values, torques)

    @classmethod
    def from_scene(cls, mech, e):
        name = e.string("name")
        for key in ("value", "torque"):  # checked here to name the entry and key
            raw = e.data.get(key)
            for item in raw if isinstance(raw, list) else ([] if raw is None else [raw]):
                check(mech, item, f"{e.where} key '{key}'")
        return mech.add("expression", name, joint=e.string("joint", required=False),
                        value=e.data.get("value"),
                        coordinate=e.string("coordinate", required=False),
                        body=e.string("body", required=False),
                        point=e.vector("point", mech.dimension, required=False),
                        frame=e.string("frame", default="global"),
                        torque=e.data.get("torque"))

    def __post_init__(self):
        if self.point is not None:
            self.point = point_vector(self.point, f"force '{self.name}' field 'point'")
        if self.frame not in FRAMES:
            raise ModelError(f"force '{self.name}' field 'frame': expected 'global' or "
                             f"'body', got {self.frame!r}")
        self.expressions, self.torques = tuple(self.expressions), tuple(self.torques)

    # ------------------------------------------------------------------ values
    def _values(self, ctx, items: tuple, key: str) -> ca.SX:
        return ca.vertcat(*[expression(ctx, item, f"force '{self.name}' field '{key}'")
                            for item in items])

    def _force_torque(self, base) -> tuple[ca.SX | None, ca.SX | None]:
        """F and T in global components, written with the system's context."""
        force = self._values(base, self.expressions, "value") if self.expressions else None
        torque = self._values(base, self.torques, "torque") if self.torques else None
        if self.frame == "body" and self.body != GROUND:
            rot = base.rotation(self.body)
            if force is not None:
                force = ca.mtimes(rot, force)
            if torque is not None and base.dimension == 3:
                torque = ca.mtimes(rot, torque)
        return force, torque

    def terms(self, kit, ctx):
        base = kit.ctx
        if self.joint is not None:
            joint = base.mechanism.joints[self.joint]
            value = self._values(base, self.expressions, "value")
            return [kit.term("measure", joint.coordinate(ctx, self.coordinate), value)]
        if self.body == GROUND:
            return []
        force, torque = self._force_torque(base)
        out = []
        if force is not None:
            local = np.zeros(base.dimension) if self.point is None else \
                base.local(self.body, self.point)
            out.append(kit.term("measure", ctx.point(self.body, local), force))
        if torque is not None:
            out.append(kit.term("torque", None, torque, self.body))
        return out

    # ------------------------------------------------------------------ reports
    def report_names(self, dimension: int) -> tuple[tuple[str, str], ...]:
        """``value`` (the generalized force: N m on an angle, else N) on a joint; on a body
        the global force components ``fx``, ``fy`` (, ``fz``) [N] and the torque ``torque``
        [N m] in the plane (``tx``, ``ty``, ``tz`` in space)."""
        if self.joint is not None:
            return (("value", coordinate_force_unit(self.coordinate)),)
        out = []
        if self.expressions:
            out += [(f"f{a}", "N") for a in _AXES[:dimension]]
        if self.torques:
            out += [("torque", "N m")] if dimension == 2 else \
                [(f"t{a}", "N m") for a in _AXES]
        return tuple(out)

    def reports(self, kit) -> list[ca.SX]:
        if self.joint is not None:
            return [self._values(kit.ctx, self.expressions, "value")]
        force, torque = self._force_torque(kit.ctx)
        both = ca.vertcat(*[p for p in (force, torque) if p is not None])
        return [both[k] for k in range(both.numel())]


def _components(mech, value, size: int, where: str) -> tuple:
    """``size`` numbers or expressions of measures, each checked."""
    if not isinstance(value, (list, tuple)) or len(value) != size:
        raise ModelError(f"{where}: expected a list of {size} numbers or expressions, got "
                         f"{value!r}")
    return tuple(check(mech, item, where) for item in value)
