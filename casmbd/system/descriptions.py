"""How a rigid body's pose becomes generalized coordinates: the body descriptions.

A description turns the pose of one body into its block q_i of generalized coordinates and
writes, as CasADi expressions of q_i and v_i = q̇_i:

* the reference point R(q_i) and the rotation matrix A(q_i) (body → global), so that a body
  point with body-frame coordinates u about the centre of mass is at r = R − A s + A u, s being
  the body-frame offset of R from the centre of mass;
* the global angular velocity ω(q_i, v_i), linear in v_i (the virtual rotation of a torque);
* the kinetic energy T_i(q_i, v_i), whose Hessian in v_i is the body's mass-matrix block;
* the body's own constraint equations (normalisation of Euler parameters, rigid-body
  conditions of natural coordinates);
* the map S_i from a rigid-body twist (ṙ_G, ω) to the coordinate rates, used to express
  constraint forces as a force and a moment (reactions).

Four descriptions exist:

=================  ====  ===================================================================
description        size  coordinates
=================  ====  ===================================================================
planar absolute     3    (x, y, θ) — seed 000, eqs. 6.16, 6.22–6.23
planar natural      4    (x, y, uₓ, u_y): R and the unit vector u of the body's x axis
spatial absolute    7    (x, y, z, e0, e1, e2, e3): R and Euler parameters, |p| = 1
spatial natural    12    (x, y, z, u, v, w): R and the three body axes (columns of A)
=================  ====  ===================================================================

Natural coordinates (García de Jalón; Brauchli & Weber, seed 003, eqs. 38–45) make A linear in
q_i, so that every body point is linear in q_i, the mass matrix is constant and the rigid-body
conditions are quadratic.  Their kinetic energy is T = ½ m |ṙ_G|² + ½ tr(Ȧ J̄ Ȧᵀ) with the
pseudo-inertia J̄ = ∫ ū ūᵀ dm = ½ tr(I_G) 1 − I_G (seed 003, "affine bodies"); on the
constraint manifold (A orthogonal, Ȧ = ω̃ A) it equals ½ m |ṙ_G|² + ½ ωᵀ I ω.

For Euler parameters the rotational energy ½ ω'ᵀ J ω' with ω' = 2 G ṗ (seed 001, eqs. 80–83)
is singular along ṗ ∥ p because G p = 0.  The term ½ c (pᵀṗ)², which vanishes on the manifold
(pᵀṗ = 0 is the derivative of |p|² = 1), is added with c = (4/3) tr J: the mass matrix
4 Gᵀ J G + c p pᵀ is then positive definite and the motion is unchanged (a Lagrangian is only
ever used on the constraint manifold, where both energies agree).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.rotations import E_matrix, G_matrix, quaternion_from_matrix, rotation_matrix

COORDINATE_CHOICES = ("absolute", "natural", "joint")


def _perp(vec):
    """Rotate a planar vector by +90 degrees (ẑ × vec)."""
    return ca.vertcat(-vec[1], vec[0])


def _matrix_rate(mat: ca.SX, q: ca.SX, v: ca.SX) -> ca.SX:
    """Ȧ = Σ_j ∂A/∂q_j v_j of a matrix expression."""
    return ca.reshape(ca.jtimes(ca.vec(mat), q, v), mat.shape[0], mat.shape[1])


def _cross(a, b):
    return ca.cross(a, b) if a.numel() == 3 else a[0] * b[1] - a[1] * b[0]


class Description:
    """Base class of the body descriptions (see the module docstring)."""

    #: description name (``"planar absolute"`` …)
    kind = ""
    #: suffixes of the coordinate names, ``body.suffix``
    names: tuple[str, ...] = ()
    #: True for the coordinates that are lengths (tolerances scale with them)
    lengths: tuple[bool, ...] = ()
    #: True when the planar rotation angle is one of the coordinates
    has_angle = False
    #: prefix of the coordinate names (the body's name unless set: joint coordinates use the
    #: joint's name)
    prefix: str | None = None

    def __init__(self, body):
        self.body = body
        self.dimension = body.dimension
        self.offset = np.asarray(body.reference_point, float)

    #: True when the body's own block q_i fixes its pose (absolute and natural coordinates);
    #: False for joint coordinates, where the pose depends on the parents' coordinates too
    local = True

    @property
    def size(self) -> int:
        """Number of coordinates of the body."""
        return len(self.names)

    # -------------------------------------------------------------- context-level hooks
    def pose(self, ctx, name: str) -> tuple[ca.SX, ca.SX]:
        """(R, A) of body ``name`` in the context ``ctx`` (from its own block by default)."""
        return self.frame(ctx.coordinates(name))

    def omega(self, ctx, name: str) -> ca.SX:
        """Global angular velocity of body ``name`` in the context ``ctx``."""
        return self.angular_velocity(ctx.coordinates(name), ctx.rates(name))

    def planar_angle(self, ctx, name: str) -> ca.SX:
        """Planar rotation angle of body ``name`` in the context ``ctx``."""
        return self.angle(ctx.coordinates(name))

    # -------------------------------------------------------------- pose
    def frame(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """Reference point R and rotation matrix A as expressions of the body's q_i."""
        raise NotImplementedError

    def initial(self) -> np.ndarray:
        """q_i at the body's initial pose."""
        raise NotImplementedError

    def initial_rates(self) -> np.ndarray:
        """q̇_i from the body's initial velocity and angular velocity."""
        rot = self.body.initial_rotation
        omega = np.atleast_1d(np.asarray(self.body.angular_velocity, float))
        return self._rates_numeric(rot, np.asarray(self.body.velocity, float), omega)

    def _rates_numeric(self, rot, vel_g, omega) -> np.ndarray:
        q = ca.SX.sym("q", self.size)
        vg = ca.SX.sym("vg", self.dimension)
        om = ca.SX.sym("om", omega.size)
        f = ca.Function("rates", [q, vg, om], [self.rates(q, vg, om)])
        return np.asarray(f(self.initial(), vel_g, omega), float).ravel()

    def reference_from_com(self, rot: np.ndarray, com=None) -> np.ndarray:
        """Initial reference point R = r_G + A s (r_G: the body's position unless given)."""
        com = self.body.position if com is None else com
        return np.asarray(com, float) + rot @ self.offset

    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """(R, p) where a spatial body starts: reference point and unit quaternion of its
        start pose (:meth:`casmbd.model.bodies.SpatialBody.start_pose`; the design pose unless
        the body was given another start; a body kind without ``start_pose`` starts at its
        design pose)."""
        start_pose = getattr(self.body, "start_pose", None)
        com, quat = start_pose() if start_pose is not None else \
            (self.body.position, self.body.orientation)
        return self.reference_from_com(rotation_matrix(quat), com), np.asarray(quat, float)

    # -------------------------------------------------------------- velocities and energy
    def angular_velocity(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """Global angular velocity (scalar in the plane): ω = ½ Σ_k a_k × ȧ_k.

        For orthonormal columns a_k of A with ȧ_k = ω × a_k this is exact (Σ_k a_k × (ω × a_k)
        = 3ω − ω in space, 2ω in the plane); it is linear in v.
        """
        _, rot = self.frame(q)
        rot_dot = _matrix_rate(rot, q, v)
        total = 0
        for k in range(self.dimension):
            total = total + _cross(rot[:, k], rot_dot[:, k])
        return 0.5 * total

    def centre_of_mass(self, q: ca.SX) -> ca.SX:
        """r_G = R − A s."""
        ref, rot = self.frame(q)
        if not np.any(self.offset):
            return ref
        return ref - ca.mtimes(rot, ca.DM(self.offset))

    def kinetic_energy(self, q: ca.SX, v: ca.SX, mass, inertia) -> ca.SX:
        """T = ½ m |ṙ_G|² + ½ tr(Ȧ J̄ Ȧᵀ), J̄ the pseudo-inertia about G."""
        vel = ca.jtimes(self.centre_of_mass(q), q, v)
        _, rot = self.frame(q)
        rot_dot = _matrix_rate(rot, q, v)
        pseudo = self.pseudo_inertia(inertia)
        return 0.5 * mass * ca.dot(vel, vel) + 0.5 * ca.trace(
            ca.mtimes([rot_dot, pseudo, rot_dot.T]))

    def pseudo_inertia(self, inertia) -> ca.SX:
        """J̄ = ∫ ū ūᵀ dm about G: ½ I 1 in the plane (any J̄ with trace I gives the same
        energy for a rigid motion), ½ tr(I) 1 − I in space."""
        if self.dimension == 2:
            return 0.5 * inertia * ca.SX.eye(2)
        return 0.5 * ca.trace(inertia) * ca.SX.eye(3) - inertia

    @property
    def constant_mass(self) -> bool:
        """True when the mass-matrix block does not depend on q (Q_v is then zero)."""
        return False

    def quadratic_velocity_forces(self, q: ca.SX, v: ca.SX, mass, inertia) -> ca.SX | None:
        """A closed form of Q_v = ∂T/∂q − Ṁ q̇, or None to let the system derive it by AD."""
        return None

    # -------------------------------------------------------------- constraints
    def constraints(self, q: ca.SX) -> tuple[ca.SX, tuple[str, ...]]:
        """The body's own constraint equations and their labels (none by default)."""
        return ca.SX(0, 1), ()

    # -------------------------------------------------------------- twists
    def rates(self, q: ca.SX, vel_g: ca.SX, omega: ca.SX) -> ca.SX:
        """q̇_i of the rigid motion with centre-of-mass velocity ``vel_g`` and angular velocity
        ``omega`` (global), linear in (vel_g, omega)."""
        raise NotImplementedError

    def _reference_rate(self, rot, vel_g, omega) -> ca.SX:
        """Ṙ = ṙ_G + ω × (A s)."""
        if not np.any(self.offset):
            return vel_g
        arm = ca.mtimes(rot, ca.DM(self.offset))
        return vel_g + (omega * _perp(arm) if self.dimension == 2 else ca.cross(omega, arm))

    # -------------------------------------------------------------- planar angle
    def angle(self, q: ca.SX) -> ca.SX:
        """Planar rotation angle (wrapped to (−π, π] unless it is a coordinate)."""
        _, rot = self.frame(q)
        return ca.atan2(rot[1, 0], rot[0, 0])


# ----------------------------------------------------------------------------- planar
class PlanarAbsolute(Description):
    """(x, y, θ) of the reference point and the body frame (seed 000, eq. 6.16)."""

    kind = "planar absolute"
    names = ("x", "y", "angle")
    lengths = (True, True, False)
    has_angle = True

    def frame(self, q):
        c, s = ca.cos(q[2]), ca.sin(q[2])
        return q[0:2], ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))

    def initial(self):
        rot = self.body.initial_rotation
        ref = self.reference_from_com(rot)
        return np.array([ref[0], ref[1], self.body.angle])

    def angular_velocity(self, q, v):
        return v[2]

    def angle(self, q):
        return q[2]

    def kinetic_energy(self, q, v, mass, inertia):
        """T = ½ m |ṙ_G|² + ½ I θ̇² (seed 000, eqs. 6.22–6.23)."""
        vel = ca.jtimes(self.centre_of_mass(q), q, v)
        return 0.5 * mass * ca.dot(vel, vel) + 0.5 * inertia * v[2] ** 2

    @property
    def constant_mass(self):
        return not np.any(self.offset)

    def rates(self, q, vel_g, omega):
        _, rot = self.frame(q)
        return ca.vertcat(self._reference_rate(rot, vel_g, omega), omega)


class PlanarNatural(Description):
    """(x, y, uₓ, u_y): the reference point and the unit vector u of the body's x axis.

    A = [u, ẑ × u] is linear in q; one rigid-body condition ½ (u·u − 1) = 0.
    """

    kind = "planar natural"
    names = ("x", "y", "ux", "uy")
    lengths = (True, True, False, False)

    def frame(self, q):
        u = q[2:4]
        return q[0:2], ca.horzcat(u, _perp(u))

    def initial(self):
        rot = self.body.initial_rotation
        ref = self.reference_from_com(rot)
        return np.array([ref[0], ref[1], rot[0, 0], rot[1, 0]])

    @property
    def constant_mass(self):
        return True

    def constraints(self, q):
        u = q[2:4]
        return 0.5 * (ca.dot(u, u) - 1.0), ("unit",)

    def rates(self, q, vel_g, omega):
        _, rot = self.frame(q)
        return ca.vertcat(self._reference_rate(rot, vel_g, omega), omega * _perp(q[2:4]))


# ----------------------------------------------------------------------------- spatial
class SpatialAbsolute(Description):
    """(x, y, z, e0, e1, e2, e3): the reference point and the Euler parameters of the body frame.

    A(p) of seed 001 ("Transformation matrix"), ω = 2 E ṗ, ω' = 2 G ṗ, normalisation
    ½ (pᵀp − 1) = 0 as the body's own constraint.
    """

    kind = "spatial absolute"
    names = ("x", "y", "z", "e0", "e1", "e2", "e3")
    lengths = (True, True, True, False, False, False, False)

    def frame(self, q):
        return q[0:3], rotation_matrix(q[3:7])

    def initial(self):
        return np.concatenate(self.start())

    def angular_velocity(self, q, v):
        return 2.0 * ca.mtimes(E_matrix(q[3:7]), v[3:7])

    def kinetic_energy(self, q, v, mass, inertia):
        """T = ½ m |ṙ_G|² + ½ ω'ᵀ J ω' + ½ c (pᵀṗ)², ω' = 2 G ṗ, c = (4/3) tr J."""
        vel = ca.jtimes(self.centre_of_mass(q), q, v)
        p, pdot = q[3:7], v[3:7]
        omega_b = 2.0 * ca.mtimes(G_matrix(p), pdot)
        c = 4.0 / 3.0 * ca.trace(inertia)
        return (0.5 * mass * ca.dot(vel, vel) + 0.5 * ca.bilin(inertia, omega_b, omega_b)
                + 0.5 * c * ca.dot(p, pdot) ** 2)

    def quadratic_velocity_forces(self, q, v, mass, inertia):
        """Q_v = (0, −8 G(ṗ)ᵀ J G(p) ṗ − c |ṗ|² p) for a centroidal frame.

        With ω' = 2 G(p) ṗ = −2 G(ṗ) p (G is bilinear and antisymmetric: G(a) b = −G(b) a,
        G(a) a = 0), Lagrange's equations of the rotational energy give
        d/dt ∂T/∂ṗ − ∂T/∂p = 4 Gᵀ J G p̈ + 4 G(ṗ)ᵀ J ω', and those of ½ c (pᵀṗ)² give
        c p pᵀ p̈ + c |ṗ|² p — identities valid off the manifold too, so this equals the AD
        form exactly at a fraction of its cost.  Non-centroidal frames use the AD form.
        """
        if np.any(self.offset):
            return None
        p, pdot = q[3:7], v[3:7]
        omega_b = 2.0 * ca.mtimes(G_matrix(p), pdot)
        c = 4.0 / 3.0 * ca.trace(inertia)
        rot = -4.0 * ca.mtimes(G_matrix(pdot).T, ca.mtimes(inertia, omega_b))
        return ca.vertcat(ca.SX(3, 1), rot - c * ca.dot(pdot, pdot) * p)

    def constraints(self, q):
        p = q[3:7]
        return 0.5 * (ca.dot(p, p) - 1.0), ("normalization",)

    def rates(self, q, vel_g, omega):
        _, rot = self.frame(q)
        pdot = 0.5 * ca.mtimes(E_matrix(q[3:7]).T, omega)
        return ca.vertcat(self._reference_rate(rot, vel_g, omega), pdot)


class SpatialNatural(Description):
    """(x, y, z, u, v, w): the reference point and the three body axes, A = [u v w].

    Six quadratic rigid-body conditions: ½ (a·a − 1) = 0 for each axis and a·b = 0 for each
    pair; the mass matrix is constant.
    """

    kind = "spatial natural"
    names = ("x", "y", "z", "ux", "uy", "uz", "vx", "vy", "vz", "wx", "wy", "wz")
    lengths = (True,) * 3 + (False,) * 9

    def frame(self, q):
        return q[0:3], ca.horzcat(q[3:6], q[6:9], q[9:12])

    def initial(self):
        ref, quat = self.start()
        return np.concatenate([ref, rotation_matrix(quat).T.ravel()])

    @property
    def constant_mass(self):
        return True

    def constraints(self, q):
        u, v, w = q[3:6], q[6:9], q[9:12]
        eqs = ca.vertcat(0.5 * (ca.dot(u, u) - 1.0), 0.5 * (ca.dot(v, v) - 1.0),
                         0.5 * (ca.dot(w, w) - 1.0), ca.dot(u, v), ca.dot(u, w), ca.dot(v, w))
        return eqs, ("unit u", "unit v", "unit w", "u.v", "u.w", "v.w")

    def rates(self, q, vel_g, omega):
        _, rot = self.frame(q)
        axes = [ca.cross(omega, rot[:, k]) for k in range(3)]
        return ca.vertcat(self._reference_rate(rot, vel_g, omega), *axes)


#: description key → class; a body kind names its description per coordinate choice
#: (``Body.descriptions``, :data:`casmbd.model.registry.BODY_KINDS`) and :func:`describe` finds
#: the class here (the floating roots of joint coordinates are registered by
#: :mod:`casmbd.system.tree`)
DESCRIPTIONS: dict[str, type] = {}


def register_description(key: str, cls: type | None = None, *, replace: bool = False):
    """Register the description class ``cls`` under ``key`` (usable as
    ``@register_description("planar_absolute")``).

    Raises
    ------
    ModelError
        When ``key`` is not an identifier, ``cls`` is not a :class:`Description`, or the key is
        taken by another class (pass ``replace=True`` to override).
    """
    if cls is None:
        return lambda c: register_description(key, c, replace=replace)
    if not isinstance(key, str) or not key.isidentifier():
        raise ModelError(f"description {getattr(cls, '__name__', cls)!r}: the key must be an "
                         f"identifier, got {key!r}")
    if not (isinstance(cls, type) and issubclass(cls, Description)):
        raise ModelError(f"description '{key}': expected a Description subclass, got {cls!r}")
    old = DESCRIPTIONS.get(key)
    if old is not None and old is not cls and not replace:
        raise ModelError(f"description '{key}' is already registered ({old.__name__}); pass "
                         "replace=True to override")
    DESCRIPTIONS[key] = cls
    return cls


for _key, _cls in (("planar_absolute", PlanarAbsolute), ("planar_natural", PlanarNatural),
                   ("spatial_absolute", SpatialAbsolute), ("spatial_natural", SpatialNatural)):
    register_description(_key, _cls)


def describe(body, coordinates: str) -> Description:
    """The description of ``body`` for the coordinate choice ``coordinates``: the class its
    kind names (``type(body).descriptions[coordinates]``) in :data:`DESCRIPTIONS`.

    In joint coordinates this is the body as a floating root (a body hanging from a tree joint
    is described by :class:`casmbd.system.tree.TreeJointDescription`).

    Raises
    ------
    ModelError
        An unknown coordinate choice, a body kind naming no description for it, or a
        description key nobody registered (naming the body and the key).
    """
    if coordinates not in COORDINATE_CHOICES:
        raise ModelError(f"body '{body.name}': unknown coordinate choice {coordinates!r} "
                         f"(known: {', '.join(COORDINATE_CHOICES)})")
    key = getattr(body, "descriptions", {}).get(coordinates)
    kind = getattr(body, "kind", type(body).__name__)
    if key is None:
        raise ModelError(f"body '{body.name}' ({kind}): its kind names no description in "
                         f"{coordinates} coordinates")
    if key not in DESCRIPTIONS:
        raise ModelError(f"body '{body.name}' ({kind}): unknown description {key!r} in "
                         f"{coordinates} coordinates (registered: {', '.join(DESCRIPTIONS)})")
    return DESCRIPTIONS[key](body)


def quaternions_from_matrices(rotations: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) of rotation matrices (n, 9, row-major), sign-continuous in n.

    Natural coordinates carry A itself; the quaternion of each sample is extracted with
    Shepperd's method and its sign chosen to be closest to the previous sample's.
    """
    mats = np.asarray(rotations, float).reshape(-1, 3, 3)
    out = np.empty((mats.shape[0], 4))
    prev = None
    for k, mat in enumerate(mats):
        if not np.all(np.isfinite(mat)):
            out[k] = np.nan
            continue
        # re-orthogonalise (natural coordinates satisfy AᵀA = I only to the tolerance)
        u, _, vt = np.linalg.svd(mat)
        quat = quaternion_from_matrix(u @ vt)
        if prev is not None and float(np.dot(quat, prev)) < 0.0:
            quat = -quat
        out[k] = prev = quat
    return out
