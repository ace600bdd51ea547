"""Generalized coordinates of a flexible body: floating-frame coordinates + modal coordinates.

A flexible body (:mod:`casmbd.model.flexible_bodies`) owns the block

* plane: q_i = (x, y, θ, η_1 … η_n) — the frame origin R, the frame angle and the modal
  coordinates;
* space: q_i = (x, y, z, e0, e1, e2, e3, η_1 … η_n) — R, the Euler parameters of the frame
  (normalisation ½ (pᵀp − 1) = 0 as the body's own constraint) and η.

Its kinetic energy is T = ½ wᵀ M(A, η) w with w = (Ṙ, ω̄, η̇) and M built from the lumped-mass
invariants of seed 002 (eqs. 5–29 to 5–34; :class:`casmbd.system.floating_frame.FlexibleBody`);
in the plane ω̄ = θ̇, in space ω̄ = 2 G(p) ṗ (seed 001, eqs. 80–83) and, as for a rigid body
in Euler parameters (:class:`casmbd.system.descriptions.SpatialAbsolute`), the term
½ c (pᵀṗ)² with c = (4/3) tr J (J the undeformed inertia about the centre of mass) makes the
mass matrix M_q = Bᵀ M B + c p pᵀ (B = diag(1, 2G, 1)) positive definite without changing the
motion.  The quadratic-velocity forces are the closed forms of the invariants (Q_v,q = Bᵀ Q_v
with Ḃ q̇ = 0 for Euler parameters, minus c |ṗ|² p), the elastic and damping forces
−K η − C η̇ act on η (:meth:`FlexibleDescription.body_forces`), and gravity acts
at the deformed centre of mass R + A S(η)/m (:meth:`FlexibleDescription.mass_centre`), which
for the lumped model is exactly Σ m_i g · r_i.

With ``stiffening`` the nodes foreshorten (second-order axial kinematics,
:mod:`casmbd.system.floating_frame`): node positions carry d_i(η), S(η) carries σ(η) e_x, and T
gains ΔT(A, η, Ṙ, ω̄, η̇), whose mass matrix is the Hessian like the rest of T and whose
quadratic-velocity forces ∂ΔT/∂q − (∂²ΔT/∂q̇∂q) q̇ are added by AD in the block's own
coordinates (:meth:`FlexibleDescription.foreshortening_forces`; for Euler parameters they differ
from the Bᵀ form only along p, which the normalisation's multiplier absorbs, as for T_lin).

The frame's reference point is its origin R: the description's ``offset`` s = −c (c the
undeformed centre of mass in body axes), so that points fixed in the *frame* (not nodes) are
handled by the rigid-body code.  Nodes are handled by :meth:`node_frame`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.model.rotations import G_matrix
from casmbd.system.descriptions import (
    PlanarAbsolute,
    PlanarNatural,
    SpatialAbsolute,
    SpatialNatural,
    register_description,
)
from casmbd.system.floating_frame import FlexibleBody, invariants

__all__ = ["PlanarFlexible", "PlanarFlexibleNatural", "SpatialFlexible",
           "SpatialFlexibleNatural"]


class FlexibleDescription:
    """What the planar and spatial flexible descriptions share (a mixin placed before the rigid
    description class: frame coordinates first, then the modal coordinates η)."""

    #: number of frame coordinates (3 in the plane, 7 in space)
    frame_size = 0

    def _flexible_init(self, body) -> None:
        self.flex = FlexibleBody(invariants(
            body.modal, damping_ratio=body.damping_ratio, flexible_mass=body.flexible_mass,
            stiffening=body.stiffening, name=body.name))
        n = self.flex.n_modes
        self.names = tuple(type(self).names) + tuple(f"eta{k + 1}" for k in range(n))
        self.lengths = tuple(type(self).lengths) + (False,) * n
        self.n_modes = n

    def constraints(self, q):
        """The frame's own equations (Euler parameters: normalisation) and, with
        ``locked_modes`` (:func:`casmbd.model.flexible_bodies.rigidified`), η_k = 0."""
        eqs, labels = super().constraints(q)
        if not getattr(self.body, "locked_modes", False) or not self.n_modes:
            return eqs, labels
        eta = q[self.frame_size:]
        return (ca.vertcat(eqs, eta),
                tuple(labels) + tuple(f"eta{k + 1} locked" for k in range(self.n_modes)))

    def split(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(frame coordinates, η) of the block."""
        return q[:self.frame_size], q[self.frame_size:]

    def initial(self) -> np.ndarray:
        return np.concatenate([self._frame_initial(), np.zeros(self.n_modes)])

    def initial_rates(self) -> np.ndarray:
        """q̇ at the start: the body's ``velocity`` is that of the frame origin (its scene
        ``position``), so the centre of mass moves at v_G = v_R + ω × (A c); η̇ = 0."""
        body = self.body
        rot = body.initial_rotation
        omega = np.atleast_1d(np.asarray(body.angular_velocity, float))
        arm = rot @ np.asarray(body.centre, float)
        spin = omega[0] * np.array([-arm[1], arm[0]]) if self.dimension == 2 else \
            np.cross(omega, arm)
        return self._rates_numeric(rot, np.asarray(body.velocity, float) + spin, omega)

    def rates(self, q, vel_g, omega):
        frame = self._frame_rates(q[:self.frame_size], vel_g, omega)
        return ca.vertcat(frame, ca.SX(self.n_modes, 1))

    @property
    def constant_mass(self) -> bool:
        return False

    def _frame_velocity(self, q, v) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX, ca.SX]:
        """(A, η, Ṙ, ω̄, η̇) of the block (ω̄ in body axes)."""
        raise NotImplementedError

    def kinetic_energy(self, q, v, mass, inertia):
        """T = ½ wᵀ M(A, η) w (+ ΔT with stiffening) (module docstring)."""
        rot, eta, rdot, omega, etadot = self._frame_velocity(q, v)
        return self.flex.kinetic_energy(rot, eta, rdot, omega, etadot)

    def foreshortening_forces(self, q, v) -> ca.SX:
        """Lagrange's ∂ΔT/∂q − (∂²ΔT/∂q̇∂q) q̇ of the foreshortening energy, by AD in the block's
        coordinates (zero without stiffening)."""
        if not self.flex.stiffening:
            return ca.SX(q.numel(), 1)
        rot, eta, rdot, omega, etadot = self._frame_velocity(q, v)
        energy = self.flex.foreshortening_energy(rot, eta, rdot, omega, etadot)
        return ca.jacobian(energy, q).T - ca.jtimes(ca.gradient(energy, v), q, v)

    def body_forces(self, q, v) -> ca.SX:
        """Elastic and damping forces on the block: (0, −K η − C η̇)."""
        _, eta, _, _, etadot = self._frame_velocity(q, v)
        return ca.vertcat(ca.SX(self.frame_size, 1), self.flex.elastic_forces(eta, etadot))

    def elastic_energy(self, q) -> ca.SX:
        """V = ½ ηᵀ K η."""
        return self.flex.elastic_energy(q[self.frame_size:])

    def mass_centre(self, ctx, name: str) -> ca.SX:
        """Deformed centre of mass R + A S(η)/m (gravity acts here)."""
        ref, rot = ctx.frame_of(name)
        eta = ctx.coordinates(name)[self.frame_size:]
        first = self.flex.first_moment(eta)
        return ref + ca.mtimes(rot, first) / self.flex.inv.mass

    def node_frame(self, ctx, name: str, node: int) -> tuple[ca.SX, ca.SX]:
        """(position, rotation) of node ``node``: r = R + A (u0 + Φ η), A_node = A A(ψ)."""
        ref, rot = ctx.frame_of(name)
        eta = ctx.coordinates(name)[self.frame_size:]
        return (self.flex.node_position(node, ref, rot, eta),
                self.flex.node_rotation(node, rot, eta))

    def node_deflection(self, ctx, name: str, node: int) -> tuple[ca.SX, ca.SX]:
        """(Φ_i η (+ d_i), Ψ_i η): the node's elastic displacement and small rotation relative
        to the undeformed body frame, in body axes (seed 002, eq. 5–26: u_i = u_i0 + Φ_i η; the
        foreshortening d_i with stiffening)."""
        eta = ctx.coordinates(name)[self.frame_size:]
        shift = ca.mtimes(ca.DM(np.atleast_2d(self.flex.inv.phi_t[node])), eta)
        if self.flex.stiffening:
            shift += self.flex.node_shortening(node, eta)
        return shift, self.flex.node_rotation_vector(node, eta)

    def node_angle(self, ctx, name: str, node: int) -> ca.SX:
        """Plane: θ + Ψ_i η, the node frame's angle."""
        eta = ctx.coordinates(name)[self.frame_size:]
        return ctx.angle(name) + self.flex.node_rotation_vector(node, eta)

    def node_angular_velocity(self, ctx, name: str, node: int) -> ca.SX:
        """Global angular velocity of the node frame: ω + A Ψ_i η̇ (plane: θ̇ + Ψ_i η̇)."""
        etadot = ctx.rates(name)[self.frame_size:]
        rel = ca.mtimes(ca.DM(np.atleast_2d(self.flex.inv.phi_r[node])), etadot)
        if self.dimension == 2:
            return ctx.angular_velocity(name) + rel
        return ctx.angular_velocity(name) + ca.mtimes(ctx.rotation(name), rel)


@register_description("planar_flexible")
class PlanarFlexible(FlexibleDescription, PlanarAbsolute):
    """(x, y, θ, η): a planar flexible body (module docstring)."""

    kind = "planar flexible"
    frame_size = 3

    def __init__(self, body):
        super().__init__(body)
        self._flexible_init(body)

    def _frame_initial(self) -> np.ndarray:
        return PlanarAbsolute.initial(self)

    def _frame_rates(self, q, vel_g, omega):
        return PlanarAbsolute.rates(self, q, vel_g, omega)

    def _frame_velocity(self, q, v):
        rot = PlanarAbsolute.frame(self, q)[1]
        n = self.frame_size
        return rot, q[n:], v[0:2], v[2], v[n:]

    def quadratic_velocity_forces(self, q, v, mass, inertia):
        """Lagrange's ∂T/∂q − Ṁ q̇ of q = (R, θ, η) in closed form (the invariants), + the
        foreshortening's by AD."""
        rot, eta, _, omega, etadot = self._frame_velocity(q, v)
        qv = self.flex.quadratic_velocity_forces(rot, eta, omega, etadot)
        return qv + self.foreshortening_forces(q, v) if self.flex.stiffening else qv


@register_description("spatial_flexible")
class SpatialFlexible(FlexibleDescription, SpatialAbsolute):
    """(x, y, z, e0…e3, η): a spatial flexible body (module docstring)."""

    kind = "spatial flexible"
    frame_size = 7

    def __init__(self, body):
        super().__init__(body)
        self._flexible_init(body)
        self._c = 4.0 / 3.0 * float(sum(body.inertia[:3]))

    def _frame_initial(self) -> np.ndarray:
        return SpatialAbsolute.initial(self)

    def _frame_rates(self, q, vel_g, omega):
        return SpatialAbsolute.rates(self, q, vel_g, omega)

    def _frame_velocity(self, q, v):
        rot = SpatialAbsolute.frame(self, q)[1]
        p, pdot = q[3:7], v[3:7]
        omega = 2.0 * ca.mtimes(G_matrix(p), pdot)
        n = self.frame_size
        return rot, q[n:], v[0:3], omega, v[n:]

    def kinetic_energy(self, q, v, mass, inertia):
        """T = ½ wᵀ M(A, η) w + ½ c (pᵀṗ)² (module docstring)."""
        p, pdot = q[3:7], v[3:7]
        return (FlexibleDescription.kinetic_energy(self, q, v, mass, inertia)
                + 0.5 * self._c * ca.dot(p, pdot) ** 2)

    def quadratic_velocity_forces(self, q, v, mass, inertia):
        """Bᵀ Q_v(A, η, ω̄, η̇) − (0, c |ṗ|² p, 0) with B = diag(1, 2 G(p), 1) (module
        docstring; Ḃ q̇ = 0 because G(ṗ) ṗ = 0)."""
        rot, eta, _, omega, etadot = self._frame_velocity(q, v)
        qv = self.flex.quadratic_velocity_forces(rot, eta, omega, etadot)
        p, pdot = q[3:7], v[3:7]
        spin = 2.0 * ca.mtimes(G_matrix(p).T, qv[3:6]) - self._c * ca.dot(pdot, pdot) * p
        out = ca.vertcat(qv[0:3], spin, qv[6:])
        return out + self.foreshortening_forces(q, v) if self.flex.stiffening else out


class _NaturalFlexible(FlexibleDescription):
    """Natural frame coordinates (seed 003): A is linear in q, the rigid-body conditions c_k
    are the body's own equations.  ω̄ = Aᵀ ω with ω = ½ Σ a_k × ȧ_k (exact on the manifold).
    T_flex(w) has no energy along the rates that violate d/dt c_k = 0 (a unit vector that
    grows), so the description adds ½ c Σ_k ċ_k², ċ_k = ∂c_k/∂q q̇, with c = tr J of the
    undeformed body: it vanishes with its first derivatives on the manifold (every ∂ċ_k/∂q̇ is
    a row of C_q, so its generalized force is absorbed by the multipliers, as the Euler-parameter
    term ½ c (pᵀṗ)² is) and makes the mass matrix positive definite.  Q_v by AD."""

    def _natural_velocity(self, q, v):
        frame = q[:self.frame_size]
        rot = self.frame(frame)[1]
        omega = self.angular_velocity(frame, v[:self.frame_size])
        body_omega = omega if self.dimension == 2 else ca.mtimes(rot.T, omega)
        n = self.frame_size
        return rot, q[n:], v[0:self.dimension], body_omega, v[n:]

    def kinetic_energy(self, q, v, mass, inertia):
        """T = ½ wᵀ M(A, η) w + ½ c Σ ċ_k² (class docstring)."""
        conditions, _ = self._rigid.constraints(self, q[:self.frame_size])
        rates = ca.jtimes(conditions, q, v) if conditions.numel() else ca.SX(0, 1)
        return (FlexibleDescription.kinetic_energy(self, q, v, mass, inertia)
                + 0.5 * self._c * ca.sumsqr(rates))

    def quadratic_velocity_forces(self, q, v, mass, inertia):
        return None  # AD of ∂T/∂q − Ṁ q̇ (System.quadratic_velocity_forces)


@register_description("planar_flexible_natural")
class PlanarFlexibleNatural(_NaturalFlexible, PlanarNatural):
    """(x, y, uₓ, u_y, η): a planar flexible body in natural coordinates."""

    kind = "planar flexible natural"
    frame_size = 4
    _rigid = PlanarNatural

    def __init__(self, body):
        PlanarNatural.__init__(self, body)
        self._flexible_init(body)
        self._c = float(body.inertia)

    def _frame_initial(self) -> np.ndarray:
        return PlanarNatural.initial(self)

    def _frame_rates(self, q, vel_g, omega):
        return PlanarNatural.rates(self, q, vel_g, omega)

    def _frame_velocity(self, q, v):
        return self._natural_velocity(q, v)


@register_description("spatial_flexible_natural")
class SpatialFlexibleNatural(_NaturalFlexible, SpatialNatural):
    """(x, y, z, u, v, w, η): a spatial flexible body in natural coordinates."""

    kind = "spatial flexible natural"
    frame_size = 12
    _rigid = SpatialNatural

    def __init__(self, body):
        SpatialNatural.__init__(self, body)
        self._flexible_init(body)
        self._c = float(sum(body.inertia[:3]))

    def _frame_initial(self) -> np.ndarray:
        return SpatialNatural.initial(self)

    def _frame_rates(self, q, vel_g, omega):
        return SpatialNatural.rates(self, q, vel_g, omega)

    def _frame_velocity(self, q, v):
        return self._natural_velocity(q, v)
