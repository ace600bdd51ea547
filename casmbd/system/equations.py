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

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND
from casmbd.model.values import resolve
from casmbd.system.applied_forces import AppliedForces
from casmbd.system.choice import AUTO, choose_coordinates
from casmbd.system.context import Context
from casmbd.system.descriptions import COORDINATE_CHOICES, describe
from casmbd.system.joint_reactions import Reactions
from casmbd.system.orientation_residual import orientation_residual, prescribed_rotation
from casmbd.system.outputs import Outputs
from casmbd.system.tree import TreeKinematics, tree_descriptions


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
    # reaction-proportional joint friction: Q_e = Q_e(N = 0) + G N (system/applied_forces.py)
    "friction_directions": (("q", "v", "t", "u", "p"), "G"),
}


class System(AppliedForces, Outputs, Reactions):
    """Symbolic equations of a mechanism: planar or spatial, absolute or natural coordinates.

    This class keeps the core — coordinates and symbols, constraints C, C_q, C_t, γ, and the
    inertia terms M, Q_v, T — and takes one job from each mixin: applied forces, virtual work
    and potential (:mod:`casmbd.system.applied_forces`), outputs (:mod:`casmbd.system.outputs`) and
    joint reactions from the multipliers (:mod:`casmbd.system.joint_reactions`).

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
        self.coordinates = coordinates or getattr(mechanism, "coordinates", AUTO)
        #: why these coordinates: "given" or the automatic choice's reason (system/choice.py)
        self.coordinate_reason = "given"
        choice = None
        if self.coordinates == AUTO:
            choice = choose_coordinates(mechanism)
            self.coordinates, self.coordinate_reason = choice.coordinates, choice.reason
        if self.coordinates not in COORDINATE_CHOICES:
            raise ModelError(f"unknown coordinate choice {self.coordinates!r} (known: "
                             f"{', '.join(COORDINATE_CHOICES)}, {AUTO})")
        for name, body in mechanism.bodies.items():
            allowed = getattr(body, "coordinate_choices", COORDINATE_CHOICES)
            if self.coordinates not in allowed:
                raise ModelError(
                    f"body '{name}' ({getattr(body, 'kind', 'body')}): {self.coordinates} "
                    f"coordinates are not available for this kind (it supports "
                    f"{', '.join(allowed)}; use coordinates = '{allowed[0]}' or 'auto')")
        self.body_names = list(mechanism.bodies)
        #: joints whose equations the coordinates satisfy identically (the spanning tree)
        self.tree_joints: list[str] = []
        if choice is not None and choice.descriptions is not None:
            self.descriptions, self.tree_joints = choice.descriptions, choice.tree_joints
        elif self.coordinates == "joint":
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

    def body_part(self, vec: ca.SX, body: str) -> ca.SX:
        """The entries of a column ``vec`` (q, v, q̈ …) owned by ``body``, as a column — also
        for a body with none (welded to its parent in joint coordinates), where CasADi's
        empty slice is 1 × 0."""
        return ca.reshape(vec[self.body_slice(body)], -1, 1)

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

    def initial_velocities(self, p: np.ndarray | None = None) -> np.ndarray:
        """Stacked q̇ from the bodies' initial velocities and angular velocities.

        In joint coordinates the body velocities are J(q₀, p) q̇ (centre-of-mass velocities and
        angular velocities of every body); q̇ minimises the kinetic energy of the difference,
        Σ ½ (m |ṙ_G − v_G⁰|² + (ω − ω⁰)ᵀ A J Aᵀ (ω − ω⁰)), exact when the given velocities are
        compatible with the tree joints.  That is the mass-orthogonal projection absolute
        coordinates make at the start (:func:`casmbd.analysis.instant.kkt.project_velocities`), so
        an incompatible initial velocity starts the same motion in either choice (the unweighted
        least squares used before gave a rod pinned at one end, given ṙ_G = (1, 1), 0.4 rad/s
        instead of 1.5).  Without mass (a singular metric) the unweighted least squares is
        used.  ``p``: parameter values (default: the mechanism's, :attr:`parameter_values`).
        """
        if self.local:
            return np.concatenate([d.initial_rates() for d in self.descriptions.values()])
        twists, given, metric = [], [], []
        for name in self.body_names:
            body = self.mechanism.bodies[name]
            twists += [ca.jtimes(self.ctx.centre_of_mass(name), self.q, self.v),
                       self.ctx.angular_velocity(name)]
            given += [np.ravel(body.velocity), np.ravel(body.angular_velocity)]
            mass, inertia = self._mass_inertia(body)
            rot = self.ctx.rotation(name) if self.dimension == 3 else ca.SX(1.0)
            # the block of W for (ṙ_G, ω): m I and A J Aᵀ (J in the plane)
            metric += [mass, ca.vec(ca.mtimes([rot, ca.SX(inertia), rot.T]))]
        fun = ca.Function("twists", [self.q, self.p, self.t],
                          [ca.jacobian(ca.vertcat(*twists), self.v), ca.vertcat(*metric)])
        p = self.parameter_values if p is None else np.asarray(p, dtype=float)
        matrix, blocks = (np.asarray(x, dtype=float) for x in
                          fun(self.initial_coordinates(), p, 0.0))
        target = np.concatenate(given)
        nw = 1 if self.dimension == 2 else 3
        w_mat = np.zeros((matrix.shape[0], matrix.shape[0]))
        row = k = 0
        for _ in self.body_names:  # W = blockdiag(m I, A J Aᵀ) per body
            d = self.dimension
            w_mat[row:row + d, row:row + d] = blocks[k, 0] * np.eye(d)
            w_mat[row + d:row + d + nw, row + d:row + d + nw] = \
                blocks[k + 1:k + 1 + nw * nw, 0].reshape(nw, nw)
            row, k = row + d + nw, k + 1 + nw * nw
        h_mat = matrix.T @ w_mat @ matrix
        if self.nq and np.all(np.isfinite(h_mat)) and \
                np.linalg.matrix_rank(h_mat) == self.nq:
            return np.linalg.solve(h_mat, matrix.T @ w_mat @ target)
        rates, *_ = np.linalg.lstsq(matrix, target, rcond=None)
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
            rows.append(self._driver_residual(driver, ctx))
            labels.append(Equation("driver", driver.name, driver.coordinate or "coordinate"))
        c = ca.vertcat(*rows) if rows else ca.SX(0, 1)
        return c, labels

    def _driver_residual(self, driver, ctx) -> ca.SX:
        """Row of C of one driver written with ``ctx``: its joint's coordinate, a body angle or
        a reference-point coordinate minus the prescribed position."""
        if driver.orientation_row is not None:  # one of three rows (orientation_residual)
            values = [self._value(a, f"driver '{driver.orientation_row}' field "
                                     f"'{driver.form}'") for a in driver.angles]
            return orientation_residual(ctx.rotation(driver.body), prescribed_rotation(
                driver.form, values))[driver.axis]
        target = self._value(driver.position, f"driver '{driver.name}' field 'position'")
        if driver.joint is not None:
            return self.mechanism.joints[driver.joint].driver_residual(
                ctx, target, driver.coordinate)
        if driver.coordinate == "angle":
            return ctx.angle_residual(GROUND, driver.body, target)
        k = ("x", "y", "z").index(driver.coordinate)
        return ctx.reference(driver.body)[k] - target

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
    def velocity_rows(self) -> list[int]:
        """Indices of the rows of C written at the velocity level (a joint with
        ``velocity_equations``: rolling without slipping, a knife edge): their position rows
        are 0, C_q is ∂W/∂v there and C_t = W(v = 0).  Assembly, position projections and
        position stabilisation use the other rows (:attr:`holonomic_rows`) only."""
        return velocity_row_indices(self.mechanism, self.constraint_labels, self.tree_joints)

    @property
    def holonomic_rows(self) -> list[int]:
        """Indices of the rows of C that are position constraints (all but
        :attr:`velocity_rows`)."""
        vel = set(self.velocity_rows)
        return [i for i in range(self.nc) if i not in vel]

    @cached_property
    def position_jacobian(self) -> ca.SX:
        """∂C/∂q: C_q of the position constraints, zero on the :attr:`velocity_rows` (whose
        C_q is ∂W/∂v, no derivative of a position function): the Jacobian of position
        projections and the GGL correction."""
        return ca.jacobian(self.constraints, self.q)

    @cached_property
    def _velocity_rows(self) -> ca.SX | None:
        """W(q, v, t), affine in v: the rows C_q v + C_t of non-holonomic constraints (a
        joint with ``velocity_equations``, whose position rows are 0: a contact sticking in
        space, :class:`~casmbd.model.contacts.RollingClosure`), zero on the other rows; None
        when there are none."""
        joints = [j for j in self.mechanism.joints.values()
                  if hasattr(j, "velocity_equations") and j.name not in self.tree_joints]
        if not joints:
            return None
        w = ca.SX.zeros(self.nc)
        for joint in joints:
            rows = [i for i, lab in enumerate(self.constraint_labels)
                    if lab.kind == "joint" and lab.element == joint.name]
            values = ca.vec(joint.velocity_equations(self.ctx))
            for k, i in enumerate(rows):
                w[i] = values[k]
        return w

    @cached_property
    def constraint_jacobian(self) -> ca.SX:
        """C_q = ∂C/∂q, sparse (the rows of a non-holonomic constraint W = 0: ∂W/∂v)."""
        jac = ca.jacobian(self.constraints, self.q)
        return jac if self._velocity_rows is None else \
            jac + ca.jacobian(self._velocity_rows, self.v)

    @cached_property
    def constraint_time_derivative(self) -> ca.SX:
        """C_t = ∂C/∂t (non-zero only on rheonomic rows; a non-holonomic row: W at v = 0)."""
        c_t = ca.jacobian(self.constraints, self.t)
        if self._velocity_rows is None:
            return c_t
        return c_t + ca.substitute(self._velocity_rows, self.v, ca.DM.zeros(self.v.numel()))

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
            return self._composite_mass_matrix()
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
    def _kane(self) -> tuple[dict, dict]:
        """Per-body spatial inertias D_i and inertia-force weights of a coupled system.

        Each body's twist is linear in the joint rates, t_i = (ṙ_G, ω) = J_i(q) q̇ (seed 001,
        eqs. 256–290: the velocity influence matrices).  With D_i = diag(A J Aᵀ, m 1), the
        generalized inertia forces give (seed 002, "Open Loop Equations of Motion")

            M = Σ J_iᵀ D_i J_i,   Q_v = −Σ J_iᵀ w_i,   w_i = D_i J̇_i q̇ + (ω × (A J Aᵀ) ω, 0),

        with J̇_i q̇ the recursive bias acceleration.  :meth:`mass_matrix` and
        :meth:`quadratic_velocity_forces` sum them by the composite-body recursions; Q_v
        alone costs O(N), the dense M O(N²) entries.
        """
        ctx, dim = self.ctx, self.dimension
        tk = self.tree_kinematics
        nw = 1 if dim == 2 else 3
        weights, blocks = {}, {}
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
            weights[name] = ca.vertcat(moment, mass * acc)
            blocks[name] = ca.diagcat(tensor, mass * ca.SX.eye(dim))
        return blocks, weights

    def _normalization(self):
        """(rows, c, p, ṗ) of every body with Euler parameters whose description adds the
        normalisation term ½ c (pᵀṗ)² to T (ball joints: c p pᵀ in M, −c |ṗ|² p in Q_v)."""
        for name, desc in self.descriptions.items():
            extra = getattr(desc, "normalization_inertia", None)
            c = extra(self._mass_inertia(self.mechanism.bodies[name])[1]) if extra else None
            if c is None:
                continue
            sl = self.body_slice(name)
            yield list(range(sl.stop - 4, sl.stop)), c, self.q[sl][-4:], self.v[sl][-4:]

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

    def _tree_links(self) -> tuple[list[str], dict, dict, dict]:
        """Order (parents first), parents, children and force transports Xᵀ of the tree."""
        order = self.tree_kinematics.order
        parent = {name: self.descriptions[name].parent for name in order}
        children: dict[str, list[str]] = {name: [] for name in order}
        for name in order:
            if parent[name] != GROUND:
                children[parent[name]].append(name)
        carry = {name: self._force_transport(name, parent[name])
                 for name in order if parent[name] != GROUND}
        return order, parent, children, carry

    def _composite_mass_matrix(self) -> ca.SX:
        """M by the composite-rigid-body recursion (Featherstone's CRBA in global components,
        centre-of-mass reference points): I^c_i = I_i + Σ_c X_cᵀ I^c_c X_c; for body i,
        F = I^c_i S_i gives M_ii = S_iᵀ F and, carried to each ancestor j, M_ji = S_jᵀ F.
        The blocks are assembled from triplets (setting entries one by one is quadratic)."""
        tk = self.tree_kinematics
        inertia, _ = self._kane
        order, parent, children, carry = self._tree_links()
        composite = {}
        for name in reversed(order):
            comp = inertia[name]
            for child in children[name]:
                x_t = carry[child]
                comp = comp + ca.mtimes([x_t, composite[child], x_t.T])
            composite[name] = comp
        rows, cols, vals = [], [], []

        def put(rows_b: slice, cols_b: slice, block: ca.SX) -> None:
            for i, r in enumerate(range(rows_b.start, rows_b.stop)):
                for j, c in enumerate(range(cols_b.start, cols_b.stop)):
                    rows.append(r)
                    cols.append(c)
                    vals.append(block[i, j])

        for name in order:
            s_i = tk.motion[name]  # a mimic follower's on its leader's block (tree.py)
            if not s_i.size2():
                continue
            rows_i = self.body_slice(tk.owner[name])
            f_mat = ca.mtimes(composite[name], s_i)
            put(rows_i, rows_i, ca.mtimes(s_i.T, f_mat))
            node = name
            while parent[node] != GROUND:
                f_mat = ca.mtimes(carry[node], f_mat)
                node = parent[node]
                s_j = tk.motion[node]
                if s_j.size2():
                    block = ca.mtimes(s_j.T, f_mat)
                    put(self.body_slice(tk.owner[node]), rows_i, block)
                    put(rows_i, self.body_slice(tk.owner[node]), block.T)
        for idx, c, p, _ in self._normalization():
            put(slice(idx[0], idx[-1] + 1), slice(idx[0], idx[-1] + 1), c * ca.mtimes(p, p.T))
        return _from_triplets(self.nq, rows, cols, vals)

    def _composite_forces(self) -> ca.SX:
        """Q_v,i = −S_iᵀ f_i with f_i = w_i + Σ_c X_cᵀ f_c accumulated from the leaves
        (Featherstone's RNEA at q̈ = 0 without applied loads): O(1) per body."""
        tk = self.tree_kinematics
        _, weights = self._kane
        order, _, children, carry = self._tree_links()
        force = {}
        parts = {name: ca.SX(self.body_slice(name).stop - self.body_slice(name).start, 1)
                 for name in self.body_names}
        for name in reversed(order):
            f = weights[name]
            for child in children[name]:
                f = f + ca.mtimes(carry[child], force[child])
            force[name] = f
            s_i = tk.motion[name]  # a mimic follower's adds into its leader's rows
            if s_i.size2():
                parts[tk.owner[name]] = parts[tk.owner[name]] - ca.mtimes(s_i.T, f)
        qv = ca.vertcat(*[parts[name] for name in self.body_names])
        for idx, c, p, pdot in self._normalization():
            qv[idx] = qv[idx] - c * ca.dot(pdot, pdot) * p
        return qv

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
        if not self.local:
            return self._composite_forces()
        m = self.mass_matrix
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

    def _mapped_mass_matrix(self) -> ca.Function:
        """M(q, p) of a coupled (joint-coordinate) system as N columns M e_k of one O(N)
        function: M v = ∂T/∂v (T = ½ vᵀ M v, with the Euler-parameter normalisation term), so
        column k is that gradient at the unit rate e_k, mapped over k.  The generated code
        grows like N (the dense CRBA matrix of :meth:`mass_matrix` has N² entries: 13.7 MB of C
        for a 300-rod chain); evaluating it costs the O(N²) it must."""
        q, v, p = self.q, self.v, self.p
        if self.nq == 0:  # nothing moves: an empty matrix (a map over no column is refused)
            return ca.Function("mass_matrix", [q, p], [ca.SX(0, 0)], ["q", "p"], ["M"])
        product = ca.gradient(self.kinetic_energy, v)
        for idx, c, pe, _ in self._normalization():
            product[idx] = product[idx] + c * pe * ca.dot(pe, v[idx])
        k = ca.SX.sym("k")
        unit = ca.eq(ca.DM(np.arange(self.nq, dtype=float)), k)
        column = ca.Function("mass_matrix_column", [q, k, p],
                             [ca.substitute(product, v, unit)], ["q", "k", "p"], ["M_k"])
        qm, pm = ca.MX.sym("q", self.nq), ca.MX.sym("p", p.numel())
        columns = column.map(self.nq, "serial")(qm, ca.DM(np.arange(self.nq)).T, pm)
        return ca.Function("mass_matrix", [qm, pm], [columns], ["q", "p"], ["M"])

    # ------------------------------------------------------------------ functions
    def function(self, name: str) -> ca.Function:
        """The named equation as a ``casadi.Function`` with named inputs and output."""
        if name == "outputs":
            return self.outputs_function()
        if name == "joint_reactions":
            return self.reactions_function()
        if name == "friction_normals":  # N = |R_⊥(q, λ)| of reaction-proportional friction
            if name not in self._functions:
                self._functions[name] = ca.Function(
                    name, [self.q, self.t, self.p, self.lam], [self.friction_normals],
                    ["q", "t", "p", "lambda"], ["N"])
            return self._functions[name]
        if name == "mass_matrix" and not self.local and name not in self._functions:
            self._functions[name] = self._mapped_mass_matrix()
        if name not in SIGNATURES:
            raise ModelError(f"unknown equation '{name}' (known: {', '.join(SIGNATURES)})")
        if name not in self._functions:
            inputs, output = SIGNATURES[name]
            syms = [getattr(self, s) for s in inputs]
            expr = getattr(self, name)
            self._functions[name] = ca.Function(name, syms, [expr], list(inputs), [output])
        return self._functions[name]


def _from_triplets(n: int, rows: list[int], cols: list[int], vals: list) -> ca.SX:
    """An n×n SX matrix from (row, column, value) triplets (repeated entries summed), in
    one construction."""
    entries: dict[tuple[int, int], ca.SX] = {}
    for r, c, val in zip(rows, cols, vals, strict=True):
        entries[(c, r)] = entries[(c, r)] + val if (c, r) in entries else val
    if not entries:
        return ca.SX(n, n)
    keys = sorted(entries)
    sparsity = ca.Sparsity.triplet(n, n, [r for _, r in keys], [c for c, _ in keys])
    return ca.SX(sparsity, ca.vertcat(*[entries[k] for k in keys]))


def velocity_row_indices(mechanism, labels, tree_joints=()) -> list[int]:
    """Indices of the rows of C (labelled ``labels``) that a joint of ``mechanism`` writes at
    the velocity level (it has ``velocity_equations``; a tree joint writes no rows): the rows
    its ``velocity_labels`` name when it declares them (a rolling sphere's or disc's
    ``contact`` row is a position row beside its slip rows), else all its rows."""
    joints = {name: getattr(j, "velocity_labels", None)
              for name, j in mechanism.joints.items()
              if hasattr(j, "velocity_equations") and name not in tree_joints}
    return [i for i, lab in enumerate(labels) if lab.kind == "joint" and lab.element in joints
            and (joints[lab.element] is None or lab.label in joints[lab.element])]
