"""Assemble the symbolic equations of motion of a mechanism as CasADi Functions.

From the model and CasADi's algorithmic differentiation only (seed 000, "Dynamic equations of
motion", eqs. 6.124 and 6.136–6.138):

* mass matrix M(q, p), block diagonal, M_i = m J_Gᵀ J_G + I_G e_θ e_θᵀ with J_G = ∂r_G/∂q_i
  (eqs. 6.22–6.23: for a non-centroidal frame this couples translation and rotation);
* quadratic-velocity forces Q_v(q, v, p) = −Σ m J_Gᵀ (J̇_G v) (eqs. 6.34–6.37);
* applied forces Q_e(q, v, t, u, p) by virtual work (eqs. 6.40–6.48);
* constraints C(q, t, p), Jacobian C_q, C_t and the acceleration right-hand side
  γ = −(C_q v)_q v − 2 C_qt v − C_tt, written γ = −∂(C_q v + C_t)/∂q · v − ∂(C_q v + C_t)/∂t,
  so that C_q q̈ = γ (eq. 6.138, Shabana's Q_d).

Every expression is built on demand: an analysis that needs only the constraints never builds
the mass matrix.
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
from casmbd.model.values import resolve
from casmbd.system.context import Context
from casmbd.system.descriptions import COORDINATE_CHOICES, describe
from casmbd.system.tree import TreeKinematics, tree_descriptions


@dataclass
class _Term:
    """One virtual-work term of an applied force: ``measure`` (Q = (∂expr/∂q)ᵀ weight),
    ``torque`` (weight a torque on ``body``) or ``generalized`` (weight a vector of n_q)."""

    kind: str
    expr: ca.SX | None
    weight: ca.SX
    body: str | None = None
    name: str = ""


@dataclass(frozen=True)
class Equation:
    """Label of one constraint equation: which element ('joint'/'driver') and which row."""

    kind: str
    element: str
    label: str

    def __str__(self) -> str:
        return f"{self.kind} '{self.element}' equation '{self.label}'"


#: name -> (input names, output name) of every Function the system can build
SIGNATURES: dict[str, tuple[tuple[str, ...], str]] = {
    "mass_matrix": (("q", "p"), "M"),
    "applied_forces": (("q", "v", "t", "u", "p"), "Qe"),
    "quadratic_velocity_forces": (("q", "v", "p"), "Qv"),
    "constraints": (("q", "t", "p"), "C"),
    "constraint_jacobian": (("q", "t", "p"), "Cq"),
    "constraint_time_derivative": (("q", "t", "p"), "Ct"),
    "acceleration_rhs": (("q", "v", "t", "p"), "gamma"),
    "kinetic_energy": (("q", "v", "p"), "T"),
    "potential_energy": (("q", "t", "p"), "V"),
    "input_matrix": (("q", "v", "t", "u", "p"), "B"),
}


class System:
    """Symbolic equations of a mechanism: planar or spatial, absolute or natural coordinates.

    Parameters
    ----------
    mechanism : casmbd.model.Mechanism
        The validated description.
    coordinates : {"absolute", "natural"}, optional
        How body poses become generalized coordinates (default: the mechanism's choice, see
        :mod:`casmbd.system.descriptions`).
    """

    def __init__(self, mechanism, coordinates: str | None = None):
        mechanism.validate()
        self.mechanism = mechanism
        self.dimension = mechanism.dimension
        self.coordinates = coordinates or getattr(mechanism, "coordinates", "absolute")
        if self.coordinates not in COORDINATE_CHOICES:
            raise ModelError(f"unknown coordinate choice {self.coordinates!r} (known: "
                             f"{', '.join(COORDINATE_CHOICES)})")
        self.body_names = list(mechanism.bodies)
        #: joints whose equations the coordinates satisfy identically (the spanning tree)
        self.tree_joints: list[str] = []
        if self.coordinates == "joint":
            self.descriptions, self.tree_joints = tree_descriptions(
                mechanism, getattr(mechanism, "tree", None))
        else:
            self.descriptions = {name: describe(body, self.coordinates)
                                 for name, body in mechanism.bodies.items()}
        self.nq = sum(d.size for d in self.descriptions.values())
        self.q = ca.SX.sym("q", self.nq)
        self.v = ca.SX.sym("v", self.nq)
        self.t = ca.SX.sym("t")
        self.u = ca.SX.sym("u", len(mechanism.actuators))
        self.p = ca.SX.sym("p", len(mechanism.parameters))
        self.ctx = Context(mechanism, self.descriptions, self.q, self.v, self.t, self.u, self.p)
        self.coordinate_names = [f"{d.prefix or b}.{c}" for b, d in self.descriptions.items()
                                 for c in d.names]
        self._functions: dict[str, ca.Function] = {}

    # ------------------------------------------------------------------ coordinates
    def body_slice(self, body: str) -> slice:
        """Slice of q owned by ``body``."""
        return self.ctx.block(body)

    @property
    def reaction_size(self) -> int:
        """Components of a joint reaction: (F_x, F_y, M) in the plane, force and moment (6) in
        space."""
        return 3 if self.dimension == 2 else 6

    @cached_property
    def length_indices(self) -> np.ndarray:
        """Indices of the coordinates that are lengths (positions of reference points)."""
        return np.array([self.ctx.index[b] + k for b, d in self.descriptions.items()
                         for k, is_length in enumerate(d.lengths) if is_length], dtype=int)

    def initial_coordinates(self) -> np.ndarray:
        """Stacked q from the bodies' initial poses (approximate, before assembly)."""
        return np.concatenate([d.initial() for d in self.descriptions.values()])

    def initial_velocities(self) -> np.ndarray:
        """Stacked q̇ from the bodies' initial velocities and angular velocities.

        In joint coordinates the body velocities are J(q₀) q̇ (centre-of-mass velocities and
        angular velocities of every body); q̇ is the least-squares solution, exact when the
        given velocities are compatible with the tree joints.
        """
        if self.local:
            return np.concatenate([d.initial_rates() for d in self.descriptions.values()])
        twists, given = [], []
        for name in self.body_names:
            body = self.mechanism.bodies[name]
            twists += [ca.jtimes(self.ctx.centre_of_mass(name), self.q, self.v),
                       self.ctx.angular_velocity(name)]
            given += [np.ravel(body.velocity), np.ravel(body.angular_velocity)]
        jac = ca.Function("twists", [self.q, self.p],
                          [ca.jacobian(ca.vertcat(*twists), self.v)])
        matrix = np.asarray(jac(self.initial_coordinates(), self.parameter_values))
        rates, *_ = np.linalg.lstsq(matrix, np.concatenate(given), rcond=None)
        return rates

    # ------------------------------------------------------------------ helpers
    def _value(self, value, where: str) -> ca.SX:
        return resolve(value, self.t, self.ctx.p, where)

    def _generalized(self, expr: ca.SX, weight: ca.SX) -> ca.SX:
        """(∂expr/∂q)ᵀ weight: the generalized force of ``weight`` acting along ``expr``."""
        return ca.mtimes(ca.jacobian(expr, self.q).T, weight)

    @property
    def parameter_values(self) -> np.ndarray:
        """Default values of the parameters p."""
        return np.array(list(self.mechanism.parameters.values()), dtype=float)

    # ------------------------------------------------------------------ constraints
    @cached_property
    def _constraint_parts(self) -> tuple[ca.SX, list[Equation]]:
        return self._constraints_with(self.ctx)

    def _constraints_with(self, ctx) -> tuple[ca.SX, list[Equation]]:
        """C and its labels written with ``ctx`` (the system's context or a perturbed copy)."""
        rows, labels = [], []
        for name, desc in self.descriptions.items():
            eqs, names = desc.constraints(ctx.coordinates(name))
            if names:
                rows.append(ca.vec(eqs))
                labels += [Equation("body", name, lab) for lab in names]
        for joint in self.mechanism.joints.values():
            if joint.name in self.tree_joints:
                continue  # satisfied identically by the joint coordinates
            eqs = ca.vec(joint.equations(ctx))
            if eqs.numel() != len(joint.labels):
                raise ModelError(f"joint '{joint.name}': {eqs.numel()} equations for labels "
                                 f"{joint.labels}")
            rows.append(eqs)
            labels += [Equation("joint", joint.name, lab) for lab in joint.labels]
        for driver in self.mechanism.drivers.values():
            target = self._value(driver.position, f"driver '{driver.name}' field 'position'")
            if driver.joint is not None:
                residual = self.mechanism.joints[driver.joint].driver_residual(
                    ctx, target, driver.coordinate)
            elif driver.coordinate == "angle":
                residual = ctx.angle_residual(GROUND, driver.body, target)
            else:
                k = ("x", "y", "z").index(driver.coordinate)
                residual = ctx.reference(driver.body)[k] - target
            rows.append(residual)
            labels.append(Equation("driver", driver.name, driver.coordinate or "coordinate"))
        c = ca.vertcat(*rows) if rows else ca.SX(0, 1)
        return c, labels

    @property
    def constraint_labels(self) -> list[Equation]:
        """One :class:`Equation` per row of C."""
        return self._constraint_parts[1]

    @property
    def nc(self) -> int:
        """Number of constraint equations (joints and drivers)."""
        return len(self.constraint_labels)

    @cached_property
    def constraints(self) -> ca.SX:
        """C(q, t, p)."""
        return self._constraint_parts[0]

    @cached_property
    def constraint_jacobian(self) -> ca.SX:
        """C_q = ∂C/∂q, sparse."""
        return ca.jacobian(self.constraints, self.q)

    @cached_property
    def constraint_time_derivative(self) -> ca.SX:
        """C_t = ∂C/∂t (non-zero only on rheonomic rows)."""
        return ca.jacobian(self.constraints, self.t)

    @cached_property
    def acceleration_rhs(self) -> ca.SX:
        """γ with C_q q̈ = γ: γ = −∂(C_q v + C_t)/∂q · v − ∂(C_q v + C_t)/∂t."""
        cdot = ca.mtimes(self.constraint_jacobian, self.v) + self.constraint_time_derivative
        return -(ca.jtimes(cdot, self.q, self.v) + ca.jacobian(cdot, self.t))

    # ------------------------------------------------------------------ inertia
    def _mass_inertia(self, body) -> tuple[ca.SX, ca.SX]:
        where = f"body '{body.name}' field"
        mass = self._value(body.mass, f"{where} 'mass'")
        if body.dimension == 2:
            return mass, self._value(body.inertia, f"{where} 'inertia'")
        vals = [self._value(v, f"{where} 'inertia'") for v in body.inertia]
        ixx, iyy, izz = vals[:3]
        ixy, ixz, iyz = vals[3:] if len(vals) == 6 else (0.0, 0.0, 0.0)
        tensor = ca.vertcat(ca.horzcat(ixx, ixy, ixz), ca.horzcat(ixy, iyy, iyz),
                            ca.horzcat(ixz, iyz, izz))
        return mass, tensor

    def _body_energy(self, name: str) -> ca.SX:
        body = self.mechanism.bodies[name]
        mass, inertia = self._mass_inertia(body)
        return self.descriptions[name].kinetic_energy(
            self.ctx.coordinates(name), self.ctx.rates(name), mass, inertia)

    @cached_property
    def mass_matrix(self) -> ca.SX:
        """Block-diagonal M(q, p): M_i = ∂²T_i/∂v_i² of each body's kinetic energy.

        T_i = ½ m |ṙ_G|² + rotational energy as written by the body's description (seed 000,
        eqs. 6.22–6.23 in the plane; 4 Gᵀ J G for Euler parameters, seed 001; the constant
        pseudo-inertia form of natural coordinates, seed 003).  T_i is quadratic in v_i, so the
        Hessian is exact and structurally sparse.
        """
        if not self.local:
            return self._kane[0]
        blocks = []
        for name in self.body_names:
            vi = self.ctx.rates(name)
            blocks.append(ca.hessian(self._body_energy(name), vi)[0])
        return ca.diagcat(*blocks)

    @property
    def local(self) -> bool:
        """True when every body's pose depends on its own coordinates only (block-diagonal M)."""
        return all(d.local for d in self.descriptions.values())

    @cached_property
    def _kane(self) -> tuple[ca.SX, ca.SX]:
        """M and Q_v of a coupled (joint-coordinate) system by Kane's equations.

        Each body's twist is linear in the joint rates, t_i = (ṙ_G, ω) = J_i(q) q̇ (seed 001,
        eqs. 256–290: the velocity influence matrices).  With D_i = diag(m 1, A J Aᵀ), the
        generalized inertia forces give (seed 002, "Open Loop Equations of Motion")

            M = Σ J_iᵀ D_i J_i,   Q_v = −Σ J_iᵀ (D_i J̇_i q̇ + (0, ω × (A J Aᵀ) ω)),

        with J̇_i q̇ = ∂t_i/∂q · q̇.  Q_v is formed by one reverse-mode product Jᵀ w, linear in
        the number of bodies; differentiating ½ q̇ᵀ M q̇ instead would cost O(N⁴).  Ball-joint
        Euler parameters add c p pᵀ to M and −c |ṗ|² p to Q_v (the term ½ c (pᵀṗ)², see
        :mod:`casmbd.system.descriptions`).
        """
        ctx, q, v, dim = self.ctx, self.q, self.v, self.dimension
        tk = self.tree_kinematics
        nw = 1 if dim == 2 else 3
        weights, blocks = [], []
        for name in self.body_names:
            mass, inertia = self._mass_inertia(self.mechanism.bodies[name])
            omega, alpha = tk.twist[name][:nw], tk.bias[name][:nw]
            acc = tk.bias[name][nw:]
            if dim == 2:
                tensor = inertia
                moment = tensor * alpha
            else:
                rot = ctx.rotation(name)
                tensor = ca.mtimes([rot, inertia, rot.T])
                moment = ca.mtimes(tensor, alpha) + ca.cross(omega, ca.mtimes(tensor, omega))
            weights.append(ca.vertcat(moment, mass * acc))
            blocks.append(ca.diagcat(tensor, mass * ca.SX.eye(dim)))
        mass_matrix, qv = self._composite_bodies(tk, dict(zip(self.body_names, blocks,
                                                               strict=True)),
                                                 dict(zip(self.body_names, weights, strict=True)))
        for name, desc in self.descriptions.items():
            extra = getattr(desc, "normalization_inertia", None)
            c = extra(self._mass_inertia(self.mechanism.bodies[name])[1]) if extra else None
            if c is None:
                continue
            sl = self.body_slice(name)
            p, pdot = q[sl][-4:], v[sl][-4:]
            idx = list(range(sl.stop - 4, sl.stop))
            pad = ca.SX(self.nq, 4)
            pad[idx, :] = c * ca.mtimes(p, p.T)
            mass_matrix[:, idx] = mass_matrix[:, idx] + pad
            qv[idx] = qv[idx] - c * ca.dot(pdot, pdot) * p
        return mass_matrix, qv

    @cached_property
    def tree_kinematics(self):
        """Recursive twists, motion subspaces and bias accelerations (joint coordinates)."""
        return TreeKinematics(self)

    def _force_transport(self, child: str, parent: str) -> ca.SX:
        """Xᵀ carrying a (moment, force) pair from ``child``'s centre of mass to ``parent``'s:
        the moment gains d × F, d = r_child − r_parent."""
        d = self.ctx.centre_of_mass(child) - self.ctx.centre_of_mass(parent)
        if self.dimension == 2:
            return ca.vertcat(ca.horzcat(1, -d[1], d[0]), ca.horzcat(0, 1, 0),
                              ca.horzcat(0, 0, 1))
        skew = ca.vertcat(ca.horzcat(0, -d[2], d[1]), ca.horzcat(d[2], 0, -d[0]),
                          ca.horzcat(-d[1], d[0], 0))
        return ca.vertcat(ca.horzcat(ca.SX.eye(3), skew),
                          ca.horzcat(ca.SX.zeros(3, 3), ca.SX.eye(3)))

    def _composite_bodies(self, tk, inertia: dict, weights: dict) -> tuple[ca.SX, ca.SX]:
        """M by the composite-rigid-body recursion and Q_v = −Σ J_iᵀ w_i by accumulating the
        bodies' inertia forces from the leaves (both O(1) operations per entry).

        I^c_i = I_i + Σ_c X_cᵀ I^c_c X_c; for body i, F = I^c_i S_i gives M_ii = S_iᵀ F and,
        carried to each ancestor j, M_ji = S_jᵀ F.  f_i = w_i + Σ_c X_cᵀ f_c and
        Q_v,i = −S_iᵀ f_i (Featherstone's CRBA and RNEA in global components, centre-of-mass
        reference points).
        """
        order = tk.order
        parent = {name: self.descriptions[name].parent for name in order}
        children: dict[str, list[str]] = {name: [] for name in order}
        for name in order:
            if parent[name] != GROUND:
                children[parent[name]].append(name)
        carry = {name: self._force_transport(name, parent[name])
                 for name in order if parent[name] != GROUND}
        composite, force = {}, {}
        for name in reversed(order):
            comp, f = inertia[name], weights[name]
            for child in children[name]:
                x_t = carry[child]
                comp = comp + ca.mtimes([x_t, composite[child], x_t.T])
                f = f + ca.mtimes(x_t, force[child])
            composite[name], force[name] = comp, f
        mass_matrix = ca.SX(self.nq, self.nq)
        qv = ca.SX(self.nq, 1)
        for name in order:
            s_i = tk.motion[name]
            if not s_i.size2():
                continue
            rows_i = self.body_slice(name)
            qv[rows_i] = -ca.mtimes(s_i.T, force[name])
            f_mat = ca.mtimes(composite[name], s_i)
            mass_matrix[rows_i, rows_i] = ca.mtimes(s_i.T, f_mat)
            node = name
            while parent[node] != GROUND:
                f_mat = ca.mtimes(carry[node], f_mat)
                node = parent[node]
                s_j = tk.motion[node]
                if s_j.size2():
                    block = ca.mtimes(s_j.T, f_mat)
                    mass_matrix[self.body_slice(node), rows_i] = block
                    mass_matrix[rows_i, self.body_slice(node)] = block.T
        return mass_matrix, qv

    def _twist_jacobian(self, name: str, tk) -> ca.SX:
        """∂(ω, ṙ_G)/∂q̇ of body ``name``: the column block of each ancestor joint j is its
        motion subspace carried to the body, (S_ω, S_v + S_ω × (r_i − r_j)), O(1) per entry."""
        dim = self.dimension
        nw = 1 if dim == 2 else 3
        out = ca.SX(nw + dim, self.nq)
        r_i = self.ctx.centre_of_mass(name)
        node = name
        while node != GROUND:
            s_mat = tk.motion[node]
            if s_mat.size2():
                d = r_i - self.ctx.centre_of_mass(node)
                ang = s_mat[:nw, :]
                if dim == 2:
                    lin = s_mat[nw:, :] + ca.vertcat(-d[1] * ang, d[0] * ang)
                else:
                    lin = s_mat[nw:, :] + ca.horzcat(*[ca.cross(ang[:, k], d)
                                                       for k in range(ang.size2())])
                out[:, self.body_slice(node)] = ca.vertcat(ang, lin)
            node = self.descriptions[node].parent
        return out

    @cached_property
    def _total_energy(self) -> ca.SX:
        """Σ T_i as expressions of the whole (q, v) (joint coordinates)."""
        total = ca.SX(0.0)
        for name in self.body_names:
            body = self.mechanism.bodies[name]
            total += self.descriptions[name].energy(self.ctx, name, *self._mass_inertia(body))
        return total

    @cached_property
    def quadratic_velocity_forces(self) -> ca.SX:
        """Q_v = ∂T/∂q − Ṁ q̇ from the kinetic energy T = ½ q̇ᵀ M q̇, body by body.

        Lagrange's equations give M q̈ = Q_e + Q_v with Q_v = ∂T/∂q − (∂/∂q (M q̇)) q̇
        (seed 000, eqs. 6.24 and 6.33–6.37); written this way by AD it holds for every body
        description and is structurally zero where the mass matrix is constant (centroidal
        planar frames, natural coordinates).
        """
        m = self.mass_matrix
        if not self.local:
            return self._kane[1]
        parts = []
        for name in self.body_names:
            sl = self.body_slice(name)
            desc = self.descriptions[name]
            if desc.constant_mass:
                parts.append(ca.SX(desc.size, 1))  # constant mass matrix: structurally zero
                continue
            qi, vi = self.q[sl], self.v[sl]
            closed = desc.quadratic_velocity_forces(qi, vi, *self._mass_inertia(
                self.mechanism.bodies[name]))
            if closed is not None:
                parts.append(closed)
                continue
            mv = ca.mtimes(m[sl, sl], vi)
            kinetic = 0.5 * ca.dot(vi, mv)
            parts.append(ca.jacobian(kinetic, qi).T - ca.jtimes(mv, qi, vi))
        return ca.vertcat(*parts)

    @cached_property
    def kinetic_energy(self) -> ca.SX:
        """T = ½ vᵀ M v; for joint coordinates Σ ½ (m |ṙ_G|² + ωᵀ A J Aᵀ ω) from the
        recursive twists, O(N) instead of the O(N²) quadratic form of the dense M."""
        if self.local:
            return 0.5 * ca.bilin(self.mass_matrix, self.v, self.v)
        tk, nw = self.tree_kinematics, 1 if self.dimension == 2 else 3
        total = ca.SX(0.0)
        for name in self.body_names:
            mass, inertia = self._mass_inertia(self.mechanism.bodies[name])
            omega, vel = tk.twist[name][:nw], tk.twist[name][nw:]
            if self.dimension == 2:
                spin = inertia * omega[0] ** 2
            else:
                body_omega = ca.mtimes(self.ctx.rotation(name).T, omega)
                spin = ca.bilin(inertia, body_omega, body_omega)
            total += 0.5 * (mass * ca.dot(vel, vel) + spin)
        return total

    # ------------------------------------------------------------------ forces
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
        return total

    def _force_terms(self, ctx) -> list[_Term]:
        """The virtual-work terms of every applied force, measures written with ``ctx`` (the
        system's context or a perturbed copy), weights with the system's context."""
        mech = self.mechanism
        terms: list[_Term] = []
        g = ca.DM(mech.gravity)
        if np.any(mech.gravity):
            for name in self.body_names:
                m, _ = self._mass_inertia(mech.bodies[name])
                terms.append(_Term("measure", ctx.centre_of_mass(name), m * g))
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
            total -= m * ca.dot(ca.DM(mech.gravity), ctx.centre_of_mass(name))
        for force in mech.forces.values():  # each kind says whether its work is in V
            energy = force.potential(self._force_kit)
            if energy is not None:
                total += energy
        return total

    # ------------------------------------------------------------------ outputs
    @cached_property
    def joint_coordinate_names(self) -> list[str]:
        """Joint coordinates, in declaration order: the joint's name for its first coordinate,
        ``joint.coordinate`` for further ones (the angle of a cylindrical joint)."""
        out = []
        for joint in self.mechanism.joints.values():
            for k, coord in enumerate(joint.coordinate_names):
                out.append(joint.name if k == 0 else f"{joint.name}.{coord}")
        return out

    def _joint_coordinate(self, key: str) -> ca.SX:
        name, _, coord = key.partition(".")
        return self.mechanism.joints[name].coordinate(self.ctx, coord or None)

    def outputs_function(self) -> ca.Function:
        """Body, marker and joint outputs of (q, v, a, t, p), every output a column.

        Positions are stacked per point (x0, y0, x1, y1, …); velocities are J v and
        accelerations J a + J̇ v of the same expressions.  Planar bodies give their angle
        (``angle_*``); spatial bodies their rotation matrix (``rotation_matrices``, 9 per body,
        row by row) and global angular velocity and acceleration (3 per body).
        """
        if "outputs" not in self._functions:
            ctx, mech = self.ctx, self.mechanism
            a = ca.SX.sym("a", self.nq)
            com = ca.vertcat(*[ctx.centre_of_mass(b) for b in self.body_names])
            mk = [ctx.position(m.body, m.point) for m in mech.markers.values()]
            markers = ca.vertcat(*mk) if mk else ca.SX(0, 1)
            jc = [self._joint_coordinate(j) for j in self.joint_coordinate_names]
            joints = ca.vertcat(*jc) if jc else ca.SX(0, 1)
            groups = [("body_", com)]
            if self.dimension == 2:
                groups.append(("angle_", ca.vertcat(*[ctx.angle(b) for b in self.body_names])))
            groups += [("marker_", markers), ("joint_", joints)]
            names, exprs = [], []
            for label, expr in groups:
                vel = ca.jtimes(expr, self.q, self.v)
                acc = ca.jtimes(expr, self.q, a) + ca.jtimes(vel, self.q, self.v)
                exprs += [expr, vel, acc]
                names += [label + "positions", label + "velocities", label + "accelerations"]
            if self.dimension == 3:
                rot = ca.vertcat(*[ca.vec(ctx.rotation(b).T) for b in self.body_names])
                omega = ca.vertcat(*[ctx.angular_velocity(b) for b in self.body_names])
                alpha = ca.jtimes(omega, self.q, self.v) + ca.jtimes(omega, self.v, a)
                exprs += [rot, omega, alpha]
                names += ["rotation_matrices", "angular_velocities", "angular_accelerations"]
            self._functions["outputs"] = ca.Function(
                "outputs", [self.q, self.v, a, self.t, self.p], exprs,
                ["q", "v", "a", "t", "p"], names)
        return self._functions["outputs"]

    @cached_property
    def joint_rows(self) -> dict[str, list[int]]:
        """Rows of C belonging to each joint."""
        rows: dict[str, list[int]] = {name: [] for name in self.mechanism.joints}
        for i, lab in enumerate(self.constraint_labels):
            if lab.kind == "joint":
                rows[lab.element].append(i)
        return rows

    @cached_property
    def driver_rows(self) -> dict[str, int]:
        """Row of C of each driver."""
        return {lab.element: i for i, lab in enumerate(self.constraint_labels)
                if lab.kind == "driver"}

    # ------------------------------------------------------------------ reactions
    def _cross(self, arm: ca.SX, force: ca.SX) -> ca.SX:
        if self.dimension == 2:
            return arm[0] * force[1] - arm[1] * force[0]
        return ca.cross(arm, force)

    def _perturbation(self, body: str):
        if not hasattr(self, "_perturbed"):
            self._perturbed: dict[str, tuple] = {}
        if body not in self._perturbed:
            self._perturbed[body] = self.ctx.perturbed(body)
        return self._perturbed[body]

    def _constraint_wrench(self, body: str, lam: ca.SX, rows=None) -> ca.SX:
        """Force and moment about G that constraint rows (with multipliers λ) exert on ``body``:
        −(∂C/∂e)ᵀ λ, the virtual-work counterpart of Q_c = −C_qᵀ λ (seed 000, eq. 6.145)."""
        ctx, e = self._perturbation(body)
        rows = list(range(self.nc)) if rows is None else rows
        # e moves ``body`` alone: only the equations of elements attached to it depend on e,
        # so only those are written again (all of them per body made the build O(N²))
        cons, index = self._constraints_touching(ctx, body)
        wanted = set(rows)
        keep = [k for k, r in enumerate(index) if r in wanted]
        if not keep:
            return ca.SX.zeros(e.numel())
        jac = ca.jacobian(cons[keep], e)
        lam_k = ca.vertcat(*[lam[index[k]] for k in keep])
        return ca.substitute(-ca.mtimes(jac.T, lam_k), e, ca.DM.zeros(e.numel()))

    @cached_property
    def _element_rows(self) -> dict[tuple[str, str], list[int]]:
        """Rows of C by (kind, element) in the order of :meth:`_constraints_with`."""
        out: dict[tuple[str, str], list[int]] = {}
        for i, lab in enumerate(self.constraint_labels):
            out.setdefault((lab.kind, lab.element), []).append(i)
        return out

    def _constraints_touching(self, ctx, body: str) -> tuple[ca.SX, list[int]]:
        """The equations of C that involve ``body`` (its own description's, its joints', the
        drivers of those joints or of the body) written with ``ctx``, and their row indices."""
        rows, index = [], []
        elements = self._element_rows
        desc = self.descriptions.get(body)
        if desc is not None and ("body", body) in elements:
            eqs, _ = desc.constraints(ctx.coordinates(body))
            rows.append(ca.vec(eqs))
            index += elements[("body", body)]
        touching = set()
        for joint in self.mechanism.joints.values():
            if body in joint.bodies:  # a gear involves the bodies of both its joints
                touching.add(joint.name)
                if ("joint", joint.name) in elements:
                    rows.append(ca.vec(joint.equations(ctx)))
                    index += elements[("joint", joint.name)]
        for driver in self.mechanism.drivers.values():
            if (driver.joint in touching or driver.body == body) and \
                    ("driver", driver.name) in elements:
                target = self._value(driver.position,
                                     f"driver '{driver.name}' field 'position'")
                if driver.joint is not None:
                    residual = self.mechanism.joints[driver.joint].driver_residual(
                        ctx, target, driver.coordinate)
                elif driver.coordinate == "angle":
                    residual = ctx.angle_residual(GROUND, driver.body, target)
                else:
                    k = ("x", "y", "z").index(driver.coordinate)
                    residual = ctx.reference(driver.body)[k] - target
                rows.append(ca.vec(residual))
                index += elements[("driver", driver.name)]
        return (ca.vertcat(*rows) if rows else ca.SX(0, 1)), index

    def _applied_wrench(self, body: str) -> tuple[ca.SX, list[str]]:
        """Force and moment about G of every applied force on ``body``, and the names of user
        generalized forces that cannot be attributed to bodies."""
        ctx, e = self._perturbation(body)
        total = ca.SX.zeros(e.numel())
        unknown = []
        dim = self.dimension
        for term in self._force_terms(ctx):
            if term.kind == "measure":
                total += ca.mtimes(ca.jacobian(term.expr, e).T, term.weight)
            elif term.kind == "torque":
                if term.body == body:
                    total[dim:] += term.weight
            else:
                unknown.append(term.name)
        return ca.substitute(total, e, ca.DM.zeros(e.numel())), unknown

    def _inertial_wrench(self, body: str, a: ca.SX) -> ca.SX:
        """(m a_G, Ḣ_G): Newton–Euler's rate of momentum of ``body`` (seed 001; seed 004)."""
        ctx = self.ctx
        mass, inertia = self._mass_inertia(self.mechanism.bodies[body])
        if not self.local:
            nw = 1 if self.dimension == 2 else 3
            if getattr(self, "_tree_acc", (None,))[0] is not a:
                self._tree_acc = (a, self.tree_kinematics.accelerations(a))
            full = self._tree_acc[1][body]
            omega = self.tree_kinematics.twist[body][:nw]
            alpha, acc = full[:nw], full[nw:]
        else:
            r_g = ctx.centre_of_mass(body)
            vel = ca.jtimes(r_g, self.q, self.v)
            acc = ca.jtimes(vel, self.q, self.v) + ca.jtimes(r_g, self.q, a)
            omega = ctx.angular_velocity(body)
            alpha = ca.jtimes(omega, self.q, self.v) + ca.jtimes(omega, self.v, a)
        if self.dimension == 2:
            return ca.vertcat(mass * acc, inertia * alpha)
        rot = ctx.rotation(body)
        tensor = ca.mtimes([rot, inertia, rot.T])
        h_dot = ca.mtimes(tensor, alpha) + ca.cross(omega, ca.mtimes(tensor, omega))
        return ca.vertcat(mass * acc, h_dot)

    def _reaction_point(self, joint, body: str) -> ca.SX:
        point = joint.reaction_point()
        if point is None:
            point = self.ctx.initial_position(joint.body2)
        return self.ctx.point(body, self.ctx.local(body, point))

    def reactions_function(self) -> ca.Function:
        """Joint reactions, one column per joint: the action of body1 on body2 at the joint
        point, global components — (F_x, F_y, M) in the plane, (F, M) in space.

        Joints with constraint rows (absolute and natural coordinates, loop joints of joint
        coordinates): the force and moment about G of body2 (body1 when body2 is the ground,
        with the sign changed) are −(∂C_k/∂e)ᵀ λ_k for a virtual rigid displacement e of that
        body — the virtual-work form of Q_c = −C_qᵀ λ (seed 000, eq. 6.145) — and the moment
        is carried to the joint point, M_P = M_G − (r_P − r_G) × F (eqs. 6.146–6.151).

        Joints of the spanning tree (joint coordinates) have no multipliers: their reactions
        follow from Newton–Euler body by body, from the leaves to the root (seed 002, "Joint
        Forces Calculation"): F = m a_G − F_applied − F_constraints + Σ F_children,
        M_G = Ḣ_G − M_applied − M_constraints + Σ (M_child + (r_child − r_G) × F_child).
        Driver multipliers are not included: a driver's effort is reported on its own.  A user
        generalized force that is not attached to a body makes tree reactions undeterminable
        (NaN).
        """
        if "joint_reactions" not in self._functions:
            lam = ca.SX.sym("lambda", self.nc)
            a = ca.SX.sym("a", self.nq)
            cols: dict[str, ca.SX] = {}
            mech = self.mechanism
            joint_only = [i for i, lab in enumerate(self.constraint_labels)
                          if lab.kind == "joint"]
            for name, rows in self.joint_rows.items():
                if name in self.tree_joints:
                    continue
                joint = mech.joints[name]
                body, sign = (joint.body2, 1.0) if joint.body2 != GROUND else \
                    (joint.body1, -1.0)
                wrench = sign * self._constraint_wrench(body, lam, rows)
                cols[name] = self._at_point(joint, body, wrench)
            if self.tree_joints:
                cols.update(self._tree_reactions(a, lam, joint_only))
            size = self.reaction_size
            out = ca.horzcat(*[cols[n] for n in mech.joints]) if mech.joints else \
                ca.SX(size, 0)
            self._functions["joint_reactions"] = ca.Function(
                "joint_reactions", [self.q, self.v, a, self.t, self.u, self.p, lam], [out],
                ["q", "v", "a", "t", "u", "p", "lambda"], ["reactions"])
        return self._functions["joint_reactions"]

    def _at_point(self, joint, body: str, wrench: ca.SX) -> ca.SX:
        """Carry a wrench (force, moment about G of ``body``) to the joint's point."""
        dim = self.dimension
        force, moment = wrench[:dim], wrench[dim:]
        arm = self._reaction_point(joint, body) - self.ctx.centre_of_mass(body)
        return ca.vertcat(force, moment - self._cross(arm, force))

    def _tree_reactions(self, a: ca.SX, lam: ca.SX, rows: list[int]) -> dict[str, ca.SX]:
        """Reactions of the tree joints by the recursion from the leaves (see
        :meth:`reactions_function`); ``rows`` are the loop-joint rows whose multipliers act
        on the bodies (driver rows excluded, like in absolute coordinates)."""
        dim = self.dimension
        order = [name for name in self.body_names]
        children: dict[str, list[str]] = {name: [] for name in order}
        for name in order:
            parent = self.descriptions[name].parent
            if parent != GROUND:
                children[parent].append(name)
        # bodies after their parents: reverse topological order for the recursion
        ranked, seen = [], set()

        def visit(name):
            if name in seen:
                return
            parent = self.descriptions[name].parent
            if parent != GROUND:
                visit(parent)
            seen.add(name)
            ranked.append(name)

        for name in order:
            visit(name)
        driver_rows = [i for i, lab in enumerate(self.constraint_labels) if lab.kind == "driver"]
        joint_wrench: dict[str, ca.SX] = {}  # on the body from its parent, about the joint pt
        out: dict[str, ca.SX] = {}
        for name in reversed(ranked):
            desc = self.descriptions[name]
            applied, unknown = self._applied_wrench(name)
            # drivers act inside their joints: like absolute coordinates, reactions exclude
            # the driver efforts, so driver rows count with the applied loads here
            loads = applied + self._constraint_wrench(name, lam, rows + driver_rows)
            wrench = self._inertial_wrench(name, a) - loads
            r_g = self.ctx.centre_of_mass(name)
            for child in children[name]:
                child_joint = self.mechanism.joints[self.descriptions[child].joint.name]
                on_child = joint_wrench[child]
                point = self._reaction_point(child_joint, child)
                force = on_child[:dim]
                moment = on_child[dim:] + self._cross(point - r_g, force)
                wrench = wrench + ca.vertcat(force, moment)
            if desc.joint is None:
                continue
            joint = self.mechanism.joints[desc.joint.name]
            at_point = self._at_point(joint, name, wrench)
            if unknown:
                at_point = at_point * ca.nan
            joint_wrench[name] = at_point
            out[joint.name] = at_point if joint.body2 == name else -at_point
        return out

    # ------------------------------------------------------------------ functions
    def function(self, name: str) -> ca.Function:
        """The named equation as a ``casadi.Function`` with named inputs and output."""
        if name == "outputs":
            return self.outputs_function()
        if name == "joint_reactions":
            return self.reactions_function()
        if name not in SIGNATURES:
            raise ModelError(f"unknown equation '{name}' (known: {', '.join(SIGNATURES)})")
        if name not in self._functions:
            inputs, output = SIGNATURES[name]
            syms = [getattr(self, s) for s in inputs]
            expr = getattr(self, name)
            self._functions[name] = ca.Function(name, syms, [expr], list(inputs), [output])
        return self._functions[name]
