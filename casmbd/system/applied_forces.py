"""Applied forces of a :class:`~casmbd.system.equations.System`: Q_e, B = ∂Q_e/∂u and V.

Every force contributes by virtual work (seed 000, eqs. 6.40–6.48): a term acting with weight w
along a measure s(q) gives Q = (∂s/∂q)ᵀ w, a torque T on a body gives Q = (∂ω/∂q̇)ᵀ T.  Force
element kinds write their own terms (:class:`casmbd.model.forces.ForceElement`); this module
collects them with gravity, user forces and actuators.  The reactions
(:mod:`casmbd.system.joint_reactions`) reuse the same terms written with a perturbed context.

Reaction-proportional joint friction (:mod:`casmbd.model.joint_friction`, ``mu`` > 0) writes
its Coulomb level with a symbol N_f per element (``kit.normal``).  Q_e is affine in N, so
:attr:`AppliedForces.applied_forces` is Q_e at N = 0 and :attr:`AppliedForces.
friction_directions` is G = ∂Q_e/∂N: Q_e(N) = Q_e(0) + G N.  :attr:`AppliedForces.
friction_normals` is N = |R_⊥(q, λ)| per element, the joint's constraint force transverse to
its axis, −(∂C_j/∂e)ᵀ λ_j on body2 (body1 when body2 is the ground) as in
:meth:`~casmbd.system.joint_reactions.Reactions.reactions_function`.  Analyses that do not solve for
N call :meth:`AppliedForces.refuse_reaction_friction`.

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
        Q = (∂ω/∂q̇)ᵀ T for a torque (seed 000, eqs. 6.40–6.48).  Reaction-proportional
        friction enters at N = 0; its part G N is :attr:`friction_directions` (module
        docstring).
        """
        normals = self.friction_normal_symbols
        if not normals:
            return self._applied_forces_n
        return ca.substitute(self._applied_forces_n, ca.vertcat(*normals.values()),
                             ca.DM.zeros(len(normals)))

    # ------------------------------------------------------------ reaction-proportional friction
    @cached_property
    def friction_normal_symbols(self) -> dict[str, ca.SX]:
        """Element name -> the symbol N of its transverse reaction magnitude, for the force
        elements with a :meth:`reaction_joint` (joint friction with ``mu`` > 0)."""
        out: dict[str, ca.SX] = {}
        for force in self.mechanism.forces.values():
            joint = getattr(force, "reaction_joint", lambda: None)()
            if joint is None:
                continue
            if joint in self.tree_joints:  # tree reactions come from Newton–Euler, not λ
                # (a loop joint's — a closed contact's — are its multipliers' in any
                # coordinates)
                raise ModelError(
                    f"force '{force.name}' field 'mu': the reaction of joint '{joint}' is not "
                    f"given by the multipliers in {self.coordinates} coordinates; use "
                    "coordinates = 'absolute' (or 'natural') for reaction-proportional friction")
            out[force.name] = ca.SX.sym(f"N_{force.name}")
        return out

    @property
    def reaction_friction_joints(self) -> dict[str, str]:
        """Element name -> joint of every reaction-proportional friction element."""
        return {name: self.mechanism.forces[name].reaction_joint()
                for name in self.friction_normal_symbols}

    def refuse_reaction_friction(self, what: str) -> None:
        """Raise :class:`~casmbd.errors.ModelError` naming the joints when ``what`` (an
        analysis or formulation) cannot solve the reaction-proportional friction."""
        joints = self.reaction_friction_joints
        if joints:
            names = ", ".join(f"'{j}' (force '{f}')" for f, j in joints.items())
            raise ModelError(
                f"joint {names}: the Coulomb friction level mu·|reaction| depends on the joint "
                f"reaction (the multipliers), which {what} does not solve for; use the "
                "formulation 'index1' (or 'ggl'), or inverse dynamics")

    @cached_property
    def friction_directions(self) -> ca.SX:
        """G = ∂Q_e/∂N (n_q × n_f): Q_e = Q_e(N = 0) + G N exactly (Q_e is affine in N)."""
        normals = self.friction_normal_symbols
        if not normals:
            return ca.SX(self.nq, 0)
        return ca.jacobian(self._applied_forces_n, ca.vertcat(*normals.values()))

    @cached_property
    def lam(self) -> ca.SX:
        """Symbols of the multipliers λ (n_c), an input of :attr:`friction_normals`."""
        return ca.SX.sym("lambda", self.nc)

    @cached_property
    def friction_normals(self) -> ca.SX:
        """N(q, t, p, λ) = |R_⊥| per reaction-proportional friction element (module
        docstring): in the plane the whole force of a revolute; otherwise the force minus
        its component along the joint axis (global, from body1)."""
        return self.friction_normals_of(self.lam)

    def friction_normals_of(self, lam: ca.SX) -> ca.SX:
        """:attr:`friction_normals` with the multipliers ``lam`` (a formulation's symbols)."""
        out = []
        ctx, dim = self.ctx, self.dimension
        for joint_name in self.reaction_friction_joints.values():
            joint = self.mechanism.joints[joint_name]
            attach = joint.body2 if joint.body2 != GROUND else joint.body1
            wrench = self._constraint_wrench(ctx.owner(attach), lam, self.joint_rows[joint_name])
            force = wrench[:dim]
            if getattr(joint, "axis", None) is not None:
                axis = ctx.direction(joint.body1, ctx.local_direction(joint.body1, joint.axis))
                force = force - ca.dot(force, axis) * axis
            square = ca.dot(force, force)
            # |R| with a zero (not NaN) derivative at R = 0
            out.append(ca.if_else(square > 0, ca.sqrt(square), 0.0))
        return ca.vertcat(*out) if out else ca.SX(0, 1)

    @cached_property
    def _applied_forces_n(self) -> ca.SX:
        """Q_e with the symbols N of reaction-proportional friction (module docstring)."""
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
        """Forces a body's description exerts on its own coordinates: the elastic and damping
        forces −K η − C η̇ of flexible bodies (internal forces: no work in a rigid motion of the
        body, so the reactions do not see them)."""
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
                               user_terms=self._user_terms,
                               normal=lambda name: self.friction_normal_symbols[name])

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

