"""Applied forces of a :class:`~casmbd.system.equations.System`: Q_e, B = ∂Q_e/∂u and V.

Every force contributes by virtual work (seed 000, eqs. 6.40–6.48): a term acting with weight w
along a measure s(q) gives Q = (∂s/∂q)ᵀ w, a torque T on a body gives Q = (∂ω/∂q̇)ᵀ T.  Force
element kinds write their own terms (:class:`casmbd.model.forces.ForceElement`); this module
collects them with gravity, user forces and actuators.  The reactions
(:mod:`casmbd.system.reactions`) reuse the same terms written with a perturbed context.

:class:`AppliedForces` is a mixin of :class:`~casmbd.system.equations.System`: it reads the
system's symbols (``q``, ``v``, ``u``, ``ctx``, ``nq``, ``dimension``, ``mechanism``,
``body_names``) and its helpers ``_value`` and ``_mass_inertia``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from types import SimpleNamespace

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.bodies import GROUND
from casmbd.model.forces import ForceElement, SpringDamper, UserForce


@dataclass
class _Term:
    """One virtual-work term of an applied force: ``measure`` (Q = (∂expr/∂q)ᵀ weight),
    ``torque`` (weight a torque on ``body``) or ``generalized`` (weight a vector of n_q)."""

    kind: str
    expr: ca.SX | None
    weight: ca.SX
    body: str | None = None
    name: str = ""




class AppliedForces:
    """Applied forces, input matrix and potential energy of a System (a mixin, see the module
    docstring for what it reads from the System)."""

    def _point_local(self, body: str, point) -> np.ndarray:
        if point is None:
            return np.zeros(self.dimension)
        return self.ctx.local(body, point)

    def _torque(self, body: str, torque: ca.SX) -> ca.SX:
        """Generalized force of a torque (global components): (∂ω/∂v)ᵀ T, seed 001 eq. on the
        virtual rotation δπ (ω linear in v, so ∂ω/∂v maps δq to the virtual rotation)."""
        if body == GROUND:
            return ca.SX.zeros(self.nq)
        omega = self.ctx.angular_velocity(body)
        return ca.mtimes(ca.jacobian(omega, self.v).T, ca.vec(torque))

    @cached_property
    def applied_forces(self) -> ca.SX:
        """Q_e(q, v, t, u, p): gravity, force elements, user forces and actuators.

        Each force contributes by virtual work, Q = (∂s/∂q)ᵀ w for a term acting with weight w
        along the measure s(q) (a point's position, a spring's length, a joint coordinate), and
        Q = (∂ω/∂q̇)ᵀ T for a torque (seed 000, eqs. 6.40–6.48).
        """
        total = ca.SX.zeros(self.nq)
        exprs, weights, omegas, torques = [], [], [], []
        for term in self._force_terms(self.ctx):
            if term.kind == "measure":
                exprs.append(ca.vec(term.expr))
                weights.append(ca.vec(term.weight))
            elif term.kind == "torque":
                if term.body != GROUND:
                    omegas.append(self.ctx.angular_velocity(term.body))
                    torques.append(ca.vec(term.weight))
            else:
                total += term.weight
        # one reverse-mode sweep for all terms: Σ (∂s_k/∂q)ᵀ w_k = (∂s/∂q)ᵀ w, linear in the
        # size of the expression graph (a Jacobian per term would cost O(N²) in a tree)
        if exprs:
            total += ca.jtimes(ca.vertcat(*exprs), self.q, ca.vertcat(*weights), True)
        if omegas:
            total += ca.jtimes(ca.vertcat(*omegas), self.v, ca.vertcat(*torques), True)
        return total + self._body_forces()

    def _body_forces(self) -> ca.SX:
        """Forces a body's description exerts on its own coordinates: the elastic, damping and
        stiffening forces −K η − C η̇ − s K_G1 η of flexible bodies (internal forces: no work
        in a rigid motion of the body, so the reactions do not see them)."""
        parts, any_force = [], False
        for name in self.body_names:
            desc = self.descriptions[name]
            hook = getattr(desc, "body_forces", None)
            if hook is None:
                parts.append(ca.SX(desc.size, 1))
                continue
            any_force = True
            parts.append(hook(self.ctx.coordinates(name), self.ctx.rates(name)))
        return ca.vertcat(*parts) if any_force else ca.SX.zeros(self.nq)

    def _force_terms(self, ctx, gravity_of: str | None = None) -> list[_Term]:
        """The virtual-work terms of every applied force, measures written with ``ctx`` (the
        system's context or a perturbed copy), weights with the system's context; with
        ``gravity_of`` the weight of that body only (a copy perturbing one body moves no
        other body's centre of mass)."""
        mech = self.mechanism
        terms: list[_Term] = []
        g = ca.DM(mech.gravity)
        if np.any(mech.gravity):
            for name in (self.body_names if gravity_of is None else [gravity_of]):
                m, _ = self._mass_inertia(mech.bodies[name])
                terms.append(_Term("measure", ctx.mass_centre(name), m * g))
        for force in mech.forces.values():
            terms += self._element_terms(force, ctx)
        for i, act in enumerate(mech.actuators.values()):
            coord = mech.joints[act.joint].coordinate(ctx, act.coordinate)
            terms.append(_Term("measure", coord, self.u[i]))
        return terms

    @cached_property
    def _force_kit(self) -> SimpleNamespace:
        """What a force element kind needs to write its terms (see
        :class:`casmbd.model.forces.ForceElement`), handed in so the model layer does not
        import this one."""
        return SimpleNamespace(ctx=self.ctx, value=self._value, term=_Term,
                               user_terms=self._user_terms)

    def _element_terms(self, force, ctx) -> list[_Term]:
        """The virtual-work terms of one force element, from its kind."""
        if not isinstance(force, ForceElement):
            raise ModelError(f"force '{force.name}': unsupported type {type(force).__name__}")
        return force.terms(self._force_kit, ctx)

    def _spring_length(self, force: SpringDamper, ctx=None) -> ca.SX:
        return force.length(ctx or self.ctx)

    @cached_property
    def _user_outputs(self) -> dict[str, tuple]:
        """What each user force function returns, called once with the system's context."""
        out = {}
        for force in self.mechanism.forces.values():
            if isinstance(force, UserForce):
                out[force.name] = self._call_user(force)
        return out

    def _call_user(self, force: UserForce) -> tuple:
        where = f"force '{force.name}'"
        try:
            out = force.function(self.ctx)
        except ModelError:
            raise
        except Exception as exc:  # a user's callable may raise anything
            reraise_interrupt(exc)
            raise ModelError(f"{where}: the user function raised {type(exc).__name__}: "
                             f"{exc}") from exc
        if force.body is None:
            vec = ca.SX(out)
            if vec.shape != (self.nq, 1):
                raise ModelError(f"{where}: generalized force must have shape ({self.nq}, 1), "
                                 f"got {vec.shape}")
            return vec, None
        torque = None
        if isinstance(out, tuple):
            out, torque = out
        vec = ca.vec(ca.SX(out))
        if vec.numel() != self.dimension:
            raise ModelError(f"{where}: the force must have {self.dimension} components, got "
                             f"{vec.shape}")
        if torque is not None:
            torque = ca.vec(ca.SX(torque))
            size = 1 if self.dimension == 2 else 3
            if torque.numel() != size:
                raise ModelError(f"{where}: the torque must have {size} component(s), got "
                                 f"{torque.shape}")
        return vec, torque

    def _user_terms(self, force: UserForce, ctx) -> list[_Term]:
        vec, torque = self._user_outputs[force.name]
        if force.body is None:
            return [_Term("generalized", None, vec, None, force.name)]
        pos = ctx.point(force.body, self._point_local(force.body, force.point))
        terms = [_Term("measure", pos, vec)]
        if torque is not None:
            terms.append(_Term("torque", None, torque, force.body))
        return terms

    @cached_property
    def input_matrix(self) -> ca.SX:
        """B = ∂Q_e/∂u: how the actuator inputs enter the generalized forces."""
        return ca.jacobian(self.applied_forces, self.u)

    @cached_property
    def potential_energy(self) -> ca.SX:
        """V(q, t, p) of gravity and springs (other forces are not conservative)."""
        ctx, mech = self.ctx, self.mechanism
        total = ca.SX(0.0)
        for name in self.body_names:
            m, _ = self._mass_inertia(mech.bodies[name])
            total -= m * ca.dot(ca.DM(mech.gravity), ctx.mass_centre(name))
            elastic = getattr(self.descriptions[name], "elastic_energy", None)
            if elastic is not None:  # ½ ηᵀ K η of a flexible body
                total += elastic(ctx.coordinates(name))
        for force in mech.forces.values():  # each kind says whether its work is in V
            energy = force.potential(self._force_kit)
            if energy is not None:
                total += energy
        return total

