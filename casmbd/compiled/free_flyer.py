"""Free-flyer velocities of floating bases: v of size n_v, ``integrate`` and ``difference``.

A spatial body without a tree joint in joint coordinates (a *floating root*: a URDF robot
loaded with ``floating_base=True``, or any free body of a scene) carries seven coordinates
q_b = (x, y, z, e0, e1, e2, e3): the global position r of its reference point (the root link
frame's origin for a URDF floating base) and the unit quaternion p = (e0, e1, e2, e3) of its
axes, A = A(p) (seed 001, "Transformation matrix").  The analyses (simulate, statics,
linearize …) use their time derivatives q̇_b (seven rates, with the normalization
½ (pᵀp − 1) = 0 as a constraint equation).  The per-call API
(:class:`casmbd.compiled.robot.CompiledModel`) uses six velocities instead, Pinocchio's
free-flyer convention (``JointModelFreeFlyer``):

    v_b = (v, ω'),   v = Aᵀ ṙ,   ω' = Aᵀ ω        (both in the body's own axes)

— the velocity of the reference point and the angular velocity, body components, i.e. the
body twist in Pinocchio's ``LOCAL`` frame.  The coordinate rates follow as

    ṙ = A(p) v,   ṗ = ½ p ⊗ (0, ω') = ½ G(p)ᵀ ω'          (:func:`rates`)

(G of seed 001 eqs. 80–83, G Gᵀ = I for a unit p), and v_b is the time derivative of
nothing: the coordinates are updated on the Lie group SE(3) by :func:`integrate`,

    (A₁, r₁) = (A₀, r₀) · exp(v_b Δt):  A₁ = A₀ exp([ω' Δt]),  r₁ = r₀ + A₀ V(ω' Δt) v Δt,

    V(φ) = I + (1 − cos θ)/θ² [φ] + (θ − sin θ)/θ³ [φ]²,   θ = |φ|

(Murray, Li & Sastry, *A Mathematical Introduction to Robotic Manipulation*, 1994, eq. 2.36;
Pinocchio's ``exp6``), the quaternion as p₁ = p₀ ⊗ (cos θ/2, sin θ/2 φ/θ), renormalised; and
:func:`difference` is its inverse, v_b Δt = log((A₀, r₀)⁻¹ (A₁, r₁)) with
V(φ)⁻¹ = I − ½ [φ] + (1 − θ sin θ / (2 (1 − cos θ)))/θ² [φ]² (Pinocchio's ``log6``; the
shorter of the two quaternions ±p).  Every other coordinate (joint angles, prismatic
displacements, a planar floating body's x, y, θ, a ball joint's Euler parameters) keeps
v = q̇ and ``integrate`` adds v Δt.

Pinocchio's configuration of the same free-flyer is (x, y, z, qx, qy, qz, qw) — the same
numbers with the scalar part last — and its velocity is exactly v_b.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.rotations import (
    G_matrix,
    quaternion_conjugate,
    quaternion_multiply,
    rotation_matrix,
    skew,
)
from casmbd.system.descriptions import SpatialAbsolute

__all__ = ["FloatingBlock", "VelocityMap", "difference_blocks", "integrate_blocks",
           "velocity_functions"]

#: below this rotation angle (rad) the series forms are used (truncation below 1e-18; the
#: closed forms lose digits to cancellation at small angles)
SMALL_ANGLE = 1e-2


@dataclass(frozen=True)
class FloatingBlock:
    """One floating root: its body, the start of its 7 coordinates in q and 6 velocities
    in v."""

    body: str
    q: int
    v: int


class VelocityMap:
    """The map q̇ = G(q) v between the per-call velocities v (n_v) and the coordinate rates q̇
    (n_q) of a system (module docstring); the identity when no body floats in space.

    Attributes
    ----------
    blocks : list of FloatingBlock
    nq, nv : int
    """

    def __init__(self, system):
        self.nq = system.nq
        self.blocks: list[FloatingBlock] = []
        if system.coordinates == "joint" and system.dimension == 3:
            shift = 0
            for name, desc in system.descriptions.items():
                if desc.joint is None and isinstance(desc, SpatialAbsolute):
                    start = system.ctx.index[name]
                    self.blocks.append(FloatingBlock(name, start, start - shift))
                    shift += 1
        self.nv = self.nq - len(self.blocks)
        # the scalar coordinates: q index -> v index
        floating = {b.q + k for b in self.blocks for k in range(7)}
        self._scalar_q = np.array([i for i in range(self.nq) if i not in floating], dtype=int)
        self._scalar_v = np.array([self.v_index(i) for i in self._scalar_q], dtype=int)
        self.bodies = {b.body for b in self.blocks}

    @property
    def identity(self) -> bool:
        """True when v = q̇ (no floating spatial body)."""
        return not self.blocks

    def v_index(self, i: int) -> int:
        """The index in v of the scalar coordinate q[i] (not inside a floating block)."""
        return i - sum(1 for b in self.blocks if b.q < i)

    def velocity_names(self, coordinate_names: list[str]) -> list[str]:
        """Names of the entries of v: a floating block's ``<body>.vx, vy, vz, wx, wy, wz``
        (body axes), the others the coordinate names."""
        out = list(coordinate_names)
        for b in reversed(self.blocks):
            out[b.q:b.q + 7] = [f"{b.body}.{s}" for s in ("vx", "vy", "vz", "wx", "wy", "wz")]
        return out

    # ------------------------------------------------------------------ symbolic
    def rates(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """q̇ = G(q) v as expressions (ṙ = A(p) v_lin, ṗ = ½ G(p)ᵀ ω')."""
        if self.identity:
            return v
        out = [None] * self.nq
        for i, j in zip(self._scalar_q, self._scalar_v):
            out[i] = v[int(j)]
        for b in self.blocks:
            p = q[b.q + 3:b.q + 7]
            lin = ca.mtimes(rotation_matrix(p), v[b.v:b.v + 3])
            ang = 0.5 * ca.mtimes(G_matrix(p).T, v[b.v + 3:b.v + 6])
            for k in range(3):
                out[b.q + k] = lin[k]
            for k in range(4):
                out[b.q + 3 + k] = ang[k]
        return ca.vertcat(*out)

    def rates_matrix(self, q: ca.SX) -> ca.SX:
        """G(q), n_q × n_v, with q̇ = G(q) v."""
        v = ca.SX.sym("v_free", self.nv)
        return ca.jacobian(self.rates(q, v), v)

    # ------------------------------------------------------------------ numeric
    def _conversions(self) -> ca.Function:
        """(q, v, a, q̇) ↦ (G v, G a + Ġ v, v of q̇), compiled once (CasADi's VM)."""
        if getattr(self, "_convert", None) is None:
            q, v, a = (ca.SX.sym(n, k) for n, k in (("q", self.nq), ("v", self.nv),
                                                    ("a", self.nv)))
            qd = ca.SX.sym("qd", self.nq)
            rates = self.rates(q, v)
            acc = ca.mtimes(ca.jacobian(rates, v), a) + ca.jtimes(rates, q, rates)
            back = [None] * self.nv
            for i, j in zip(self._scalar_q, self._scalar_v):
                back[int(j)] = qd[int(i)]
            for b in self.blocks:
                p, pd = q[b.q + 3:b.q + 7], qd[b.q + 3:b.q + 7]
                lin = ca.mtimes(rotation_matrix(p).T, qd[b.q:b.q + 3])
                ang = 2.0 * ca.mtimes(G_matrix(p), pd)  # ω' = 2 G(p) ṗ
                for k in range(3):
                    back[b.v + k], back[b.v + 3 + k] = lin[k], ang[k]
            self._convert = ca.Function("free_flyer_conversions", [q, v, a, qd],
                                        [rates, acc, ca.vertcat(*back)])
        return self._convert

    def rates_from_velocity(self, q, v) -> np.ndarray:
        """q̇ = G(q) v: the coordinate rates the analyses integrate (``simulate``'s v)."""
        q, v = self._check(q, self.nq, "q"), self._check(v, self.nv, "v")
        return np.asarray(self._conversions()(q, v, np.zeros(self.nv), np.zeros(self.nq))[0],
                          float).ravel()

    def velocity_from_rates(self, q, qdot) -> np.ndarray:
        """v from q̇ (v = Aᵀ ṙ, ω' = 2 G(p) ṗ on a floating block; exact when q̇ is tangent,
        pᵀṗ = 0)."""
        q, qdot = self._check(q, self.nq, "q"), self._check(qdot, self.nq, "qdot")
        return np.asarray(self._conversions()(q, np.zeros(self.nv), np.zeros(self.nv),
                                              qdot)[2], float).ravel()

    def rate_accelerations(self, q, v, a) -> np.ndarray:
        """q̈ = G(q) a + Ġ v from the velocity v and its rate a = v̇."""
        q = self._check(q, self.nq, "q")
        v, a = self._check(v, self.nv, "v"), self._check(a, self.nv, "a")
        return np.asarray(self._conversions()(q, v, a, np.zeros(self.nq))[1], float).ravel()

    def integrate(self, q, v, dt: float = 1.0) -> np.ndarray:
        """q ⊕ v Δt (module docstring)."""
        q, v = self._check(q, self.nq, "q"), self._check(v, self.nv, "v")
        return integrate_blocks(q, v, dt, self.blocks, self._scalar_q, self._scalar_v)

    def difference(self, q0, q1) -> np.ndarray:
        """v with q1 = integrate(q0, v, 1) (module docstring)."""
        q0, q1 = self._check(q0, self.nq, "q0"), self._check(q1, self.nq, "q1")
        return difference_blocks(q0, q1, self.blocks, self._scalar_q, self._scalar_v, self.nv)

    @staticmethod
    def _check(x, n: int, what: str) -> np.ndarray:
        arr = np.asarray(x, dtype=float)
        if arr.shape != (n,):
            raise ModelError(f"{what}: expected a vector of length {n}, got shape "
                             f"{arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ModelError(f"{what}: expected finite values, got {arr.tolist()}")
        return arr


def _unit(p: np.ndarray, where: str) -> np.ndarray:
    norm = float(np.linalg.norm(p))
    if not norm > 0.0:
        raise ModelError(f"{where}: the quaternion is zero")
    return p / norm


def exp_so3_quaternion(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion of the rotation by the vector φ: (cos θ/2, sin θ/2 φ/θ)."""
    theta = float(np.linalg.norm(phi))
    half = 0.5 * theta
    # sin(θ/2)/θ, series 1/2 − θ²/48 + θ⁴/3840 below SMALL_ANGLE
    t2 = theta * theta
    k = 0.5 - t2 / 48.0 + t2 * t2 / 3840.0 if theta < SMALL_ANGLE else np.sin(half) / theta
    return np.concatenate([[np.cos(half)], k * phi])


def log_so3_quaternion(p: np.ndarray) -> np.ndarray:
    """φ with exp(φ) = p, |φ| ≤ π (the shorter of ±p)."""
    if p[0] < 0.0:
        p = -p
    s = float(np.linalg.norm(p[1:]))
    theta = 2.0 * np.arctan2(s, p[0])
    # θ / sin(θ/2), series 2 + θ²/12 + 7 θ⁴/2880 below SMALL_ANGLE
    t2 = theta * theta
    k = (2.0 + t2 / 12.0 + 7.0 * t2 * t2 / 2880.0 if theta < SMALL_ANGLE
         else theta / np.sin(0.5 * theta))
    return k * p[1:]


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """V(φ) = I + (1 − cos θ)/θ² [φ] + (θ − sin θ)/θ³ [φ]² (module docstring)."""
    theta2 = float(phi @ phi)
    theta = np.sqrt(theta2)
    if theta < SMALL_ANGLE:
        a = 0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0
        b = 1.0 / 6.0 - theta2 / 120.0 + theta2 * theta2 / 5040.0
    else:  # 1 − cos θ = 2 sin²(θ/2) without cancellation
        a = 2.0 * np.sin(0.5 * theta) ** 2 / theta2
        b = (theta - np.sin(theta)) / (theta2 * theta)
    w = skew(phi)
    return np.eye(3) + a * w + b * (w @ w)


def left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """V(φ)⁻¹ = I − ½ [φ] + (1 − θ sin θ / (2 (1 − cos θ)))/θ² [φ]², the coefficient as
    (1 − (θ/2) cot(θ/2))/θ² (series 1/12 + θ²/720 + θ⁴/30240 at small θ)."""
    theta2 = float(phi @ phi)
    theta = np.sqrt(theta2)
    if theta < SMALL_ANGLE:
        c = 1.0 / 12.0 + theta2 / 720.0 + theta2 * theta2 / 30240.0
    else:
        half = 0.5 * theta
        c = (1.0 - half * np.cos(half) / np.sin(half)) / theta2
    w = skew(phi)
    return np.eye(3) - 0.5 * w + c * (w @ w)


def integrate_blocks(q, v, dt, blocks, scalar_q, scalar_v) -> np.ndarray:
    """q ⊕ v Δt: scalars q + v Δt, floating blocks on SE(3) (module docstring)."""
    out = np.array(q, dtype=float)
    out[scalar_q] = q[scalar_q] + dt * v[scalar_v]
    for b in blocks:
        p0 = _unit(q[b.q + 3:b.q + 7], f"integrate: body '{b.body}'")
        lin, phi = dt * v[b.v:b.v + 3], dt * v[b.v + 3:b.v + 6]
        out[b.q:b.q + 3] = q[b.q:b.q + 3] + rotation_matrix(p0) @ (left_jacobian(phi) @ lin)
        p1 = quaternion_multiply(p0, exp_so3_quaternion(phi))
        out[b.q + 3:b.q + 7] = p1 / np.linalg.norm(p1)
    return out


def difference_blocks(q0, q1, blocks, scalar_q, scalar_v, nv) -> np.ndarray:
    """v with q1 = q0 ⊕ v: scalars q1 − q0, floating blocks log((A₀, r₀)⁻¹ (A₁, r₁))."""
    out = np.zeros(nv)
    out[scalar_v] = q1[scalar_q] - q0[scalar_q]
    for b in blocks:
        p0 = _unit(q0[b.q + 3:b.q + 7], f"difference: body '{b.body}'")
        p1 = _unit(q1[b.q + 3:b.q + 7], f"difference: body '{b.body}'")
        rel = quaternion_multiply(quaternion_conjugate(p0), p1)
        phi = log_so3_quaternion(rel)
        local = rotation_matrix(p0).T @ (q1[b.q:b.q + 3] - q0[b.q:b.q + 3])
        out[b.v:b.v + 3] = left_jacobian_inverse(phi) @ local
        out[b.v + 3:b.v + 6] = phi
    return out


def is_normalization(label, bodies) -> bool:
    """True for the normalization row ½ (pᵀp − 1) = 0 of a floating block (the free-flyer
    velocities keep it identically: pᵀ G(p)ᵀ = 0)."""
    return label.kind == "body" and label.element in bodies and label.label == "normalization"


def velocity_functions(system, vmap: VelocityMap, fns: list, chunk: int, solve):
    """The per-call Functions of :class:`~casmbd.compiled.robot.CompiledModel` in the
    free-flyer velocities v (n_v) from those in the coordinate rates q̇ (module docstring).

    With q̇ = G v and q̈ = G v̇ + Ġ v (Ġ v = ∂(G v)/∂q · G v), the principle of virtual power
    gives M_v = Gᵀ M G, b_v = Gᵀ (M Ġ v + b(q, G v)), τ_v = Gᵀ f(q, G v, G a + Ġ v) with
    f = M q̈ + b; a frame's Jacobian J_v = J G; a constraint row C_q q̈ = γ becomes
    (C_q G) a = γ − C_q Ġ v.  The normalization rows of the floating blocks are dropped
    (identically satisfied), so a floating-base tree has no constraint equations: its forward
    dynamics is the LDLᵀ solve ``solve(M_v, τ − b_v)`` compiled in the library.

    Returns the new list of Functions (same names) and the kept constraint rows.
    """
    by = {f.name(): f for f in fns}
    q, p, nv = system.q, system.p, vmap.nv
    vel, acc, tau = ca.SX.sym("v", nv), ca.SX.sym("a", nv), ca.SX.sym("tau", nv)
    qd = vmap.rates(q, vel)
    g = ca.jacobian(qd, vel)
    gdot = ca.jtimes(qd, q, qd)
    mass_q = by["robot_mass_matrix"](q, p)
    mass = ca.densify(ca.mtimes([g.T, mass_q, g]))
    bias = ca.densify(ca.mtimes(g.T, ca.mtimes(mass_q, gdot) + by["robot_bias"](q, qd, p)))
    rows = [i for i, lab in enumerate(system.constraint_labels)
            if not is_normalization(lab, vmap.bodies)]
    out = [ca.Function("robot_mass_matrix", [q, p], [mass], ["q", "p"], ["M"]),
           ca.Function("robot_bias", [q, vel, p], [bias], ["q", "v", "p"], ["b"])]
    qdd = ca.mtimes(g, acc) + gdot
    if "robot_id" in by:
        force_q = by["robot_id"](q, qd, qdd, p)
    else:
        force_q = by["robot_id_terms"](q, qd, qdd, p)[0]
    force = ca.densify(ca.mtimes(g.T, force_q))
    if not rows:
        qdd = ca.densify(solve(mass, tau - bias))
        # Σ v̇ᵢ, finite iff v̇ is (a zero pivot: the per-call named error, robot.py)
        fd = ca.Function("robot_fd", [q, vel, tau, p], [qdd, ca.sum1(qdd)],
                         ["q", "v", "tau", "p"], ["a", "sum"])
        ind = ca.Function("robot_id", [q, vel, acc, p], [force], ["q", "v", "a", "p"],
                          ["tau"])
        out += [fd, ind, fd.map("robot_fd_batch", "serial", chunk, [3], []),
                ind.map("robot_id_batch", "serial", chunk, [3], [])]
    else:
        kkt = by["robot_kkt"](q, qd, ca.SX.zeros(system.nq), p)
        cq_full = kkt[2][rows, :]
        cq = ca.densify(ca.mtimes(cq_full, g))
        gamma = ca.densify(kkt[3][rows] - ca.mtimes(cq_full, gdot))
        out.append(ca.Function("robot_kkt", [q, vel, tau, p],
                               [mass, ca.densify(tau - bias), cq, gamma],
                               ["q", "v", "tau", "p"], ["M", "r", "Cq", "gamma"]))
        out.append(ca.Function("robot_id_terms", [q, vel, acc, p], [force, cq, gamma],
                               ["q", "v", "a", "p"], ["f", "Cq", "gamma"]))
    for f in fns:
        name = f.name()
        if name == "robot_fk":
            out.append(f)
        elif name.startswith("robot_jacobian_"):
            out.append(ca.Function(name, [q, p], [ca.densify(ca.mtimes(f(q, p), g))],
                                   ["q", "p"], ["J"]))
    return out, rows
