"""Per-call dynamics of a tree by Featherstone's spatial algebra in local body frames.

:class:`~casmbd.compiled.robot.CompiledModel` of a spatial tree in joint coordinates whose
joints are single-coordinate revolute or prismatic joints (or rigid: fixed links kept as
bodies) writes its per-call Functions here, as Pinocchio does (Featherstone, Rigid Body
Dynamics Algorithms, 2008, ch. 2–7), instead of from the global-component tree kinematics of
:mod:`casmbd.system.tree`:

* every body frame is the body's own (origin at its centre of mass G, the body axes), so its
  spatial inertia is constant, ``I = diag(I_G, m 1)`` (body components);
* the joint between parent P and child C is read from the design pose (:mod:`casmbd.system.
  tree`: ``A_C = A_P A_P0ᵀ ΔR A_C0``, ``r_C = r_P + A_P A_P0ᵀ (J₀ + Δd + ΔR (r_C0 − J₀) −
  r_P0)``).  With the axis in the child's axes ``h = A_C0ᵀ h₀`` and the joint point in
  the child's and parent's axes ``j_C = A_C0ᵀ (J₀ − r_C0)``, ``j_P = A_P0ᵀ (J₀ − r_P0)``,
  the child's pose in the parent's frame is

      E(q) = E₀ R_h(q),      p(q) = j_P + E₀ (q_t h − R_h(q) j_C)

  with ``E₀ = A_P0ᵀ A_C0`` constant, ``R_h`` the rotation about h (revolute; identity for a
  prismatic joint) and ``q_t`` the slide (prismatic; 0 for a revolute joint).  The motion
  subspace in the child's frame at G is constant: ``S = (h, j_C × h)`` (revolute) or
  ``(0, h)`` (prismatic), so the velocity-product term is ``c = v × S q̇`` (Featherstone
  eq. 3.40 with S̊ = 0);
* ``X = [Eᵀ 0; −Eᵀ p̃ Eᵀ]`` carries motion vectors from the parent's frame to the child's;
  its transpose carries forces back (eq. 2.25), written with 3 × 3 blocks.

The quantities are those of :class:`~casmbd.compiled.robot.CompiledModel` (same conventions):
the recursive Newton–Euler algorithm (Table 5.1) for τ and for the bias b (a = 0), gravity as a
base acceleration a₀ = −g; the composite-rigid-body algorithm (Table 6.2) for M; the
articulated-body algorithm (Table 7.1) for q̈; forward kinematics; frame Jacobians in
``LOCAL_WORLD_ALIGNED`` components at the frame's point.  Floating roots,
planar models and applied forces other than gravity are left to the existing path
(:func:`unsupported` says why).  Substituted mimic followers (q_f = r q_l + δ) are covered
by M, τ, b, the kinematics and the Jacobians (their columns add into the leader's, M = Gᵀ M_f
G).  Their q̈ is the articulated-body recursion when every follower's joint has its leader's
parent link (a gripper's fingers; :meth:`SpatialTree.forward_dynamics`, the leader and its
followers one joint of one coordinate on several children); otherwise the caller's dense
solve of M q̈ = τ − b (:attr:`SpatialTree.articulated` is False).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.model.bodies import GROUND
from casmbd.system.tree import TreeJointDescription, snap

__all__ = ["SpatialTree", "unsupported"]


def unsupported(system) -> str | None:
    """Why the spatial recursions do not cover ``system`` (None when they do)."""
    mech = system.mechanism
    if system.dimension != 3:
        return "planar"
    if system.nc:
        return "constraint equations"
    if mech.forces or mech.actuators:
        return "applied forces other than gravity"
    for name in system.body_names:
        desc = system.descriptions[name]
        if not isinstance(desc, TreeJointDescription):
            return f"body '{name}' has no tree joint (a floating root)"
        kind = getattr(desc.joint, "kind", None)
        if desc.own_size == 1 and kind in ("revolute", "prismatic"):
            continue
        if desc.own_size == 0 and kind in ("fixed", "rigid"):
            continue
        return f"joint '{desc.joint.name}' ({kind})"
    return None


def _skew(x) -> ca.SX:
    return ca.vertcat(ca.horzcat(0, -x[2], x[1]), ca.horzcat(x[2], 0, -x[0]),
                      ca.horzcat(-x[1], x[0], 0))


def _axis_rotation(h: np.ndarray, angle: ca.SX) -> ca.SX:
    """R_h(φ) = 1 + sin φ h̃ + (1 − cos φ) h̃² (Rodrigues), written [[c, −s], [s, c]] when h
    is ± a coordinate axis (most URDF joints: the fewest operations)."""
    c, s = ca.cos(angle), ca.sin(angle)
    axis = np.flatnonzero(h)
    if len(axis) == 1 and abs(abs(h[axis[0]]) - 1.0) == 0.0:
        k = int(axis[0])
        i, j = (k + 1) % 3, (k + 2) % 3
        s = s if h[k] > 0 else -s
        rot = ca.SX.eye(3)
        rot[i, i], rot[j, j], rot[i, j], rot[j, i] = c, c, -s, s
        return rot
    skew = ca.DM([[0, -h[2], h[1]], [h[2], 0, -h[0]], [-h[1], h[0], 0]])
    return ca.DM.eye(3) + s * skew + (1 - c) * ca.mtimes(skew, skew)


def _rotate_sym(e: ca.SX, a: ca.SX) -> ca.SX:
    """E A Eᵀ of a symmetric 3 × 3 A, the upper triangle computed."""
    t = ca.mtimes(e, a)
    out = ca.SX.zeros(3, 3)
    for i in range(3):
        for j in range(i, 3):
            out[i, j] = out[j, i] = sum((t[i, k] * e[j, k] for k in range(3)), ca.SX(0))
    return out


def _cross(a, b) -> ca.SX:
    return ca.vertcat(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                      a[0] * b[1] - a[1] * b[0])


class _Link:
    """One body of the tree: its constant joint data and, per state, E(q), p(q)."""

    def __init__(self, system, name: str):
        desc = system.descriptions[name]
        self.name, self.parent = name, desc.parent
        joint = desc.joint
        #: the coordinate that moves the joint, q_j = ratio q[coord] + offset (a substituted
        #: mimic follower: its leader's, :mod:`casmbd.system.tree`)
        self.ratio, self.offset = 1.0, 0.0
        if desc.mimic is not None:
            _, leader, index, self.ratio, self.offset = desc.mimic
            self.coord = system.body_slice(leader).start + index
        else:
            self.coord = system.body_slice(name).start
        self.mimic = desc.mimic is not None
        self.kind = joint.kind if desc.own_size == 1 else "fixed"
        rot_c0 = snap(desc.rot_c0)
        e0 = snap(desc.rot_p0_t @ rot_c0)
        self.e0 = e0
        self.j_c = snap(rot_c0.T @ (desc.point - desc.pos_c0))
        self.j_p = snap(desc.rot_p0_t @ (desc.point - desc.pos_p0))
        self.h = snap(rot_c0.T @ np.asarray(getattr(joint, "axis", np.zeros(3)), float))
        if self.kind == "revolute":
            self.s = np.concatenate([self.h, snap(np.cross(self.j_c, self.h))])
        elif self.kind == "prismatic":
            self.s = np.concatenate([np.zeros(3), self.h])
        else:
            self.s = None
        mass, tensor = system._mass_inertia(system.mechanism.bodies[name])
        self.mass, self.tensor = mass, tensor

    def value(self, q: ca.SX) -> ca.SX:
        """The joint's own coordinate ratio q[coord] + offset."""
        if not self.mimic:
            return q[self.coord]
        return self.ratio * q[self.coord] + self.offset

    def placement(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(E, p): the child's axes and centre of mass in the parent's frame."""
        e0 = ca.DM(self.e0)
        if self.kind == "revolute":
            rot = _axis_rotation(self.h, self.value(q))
            return ca.mtimes(e0, rot), ca.DM(self.j_p) - ca.mtimes(e0, ca.mtimes(rot,
                                                                                 self.j_c))
        shift = ca.DM(self.j_p - self.e0 @ self.j_c)
        if self.kind == "prismatic":
            shift = shift + self.value(q) * ca.DM(self.e0 @ self.h)
        return ca.SX(e0), ca.SX(shift)


class SpatialTree:
    """The recursions of a tree covered by :func:`unsupported` (module docstring).

    Parameters
    ----------
    system : System
        In joint coordinates; ``unsupported(system)`` must be None.
    q : SX
        The coordinate symbols of every expression.
    """

    def __init__(self, system, q: ca.SX):
        self.system = system
        desc = system.descriptions
        order: list[str] = []

        def visit(name: str) -> None:
            if name not in order:
                if desc[name].parent != GROUND:
                    visit(desc[name].parent)
                order.append(name)

        for name in system.body_names:
            visit(name)
        self.order = order
        self.links = {name: _Link(system, name) for name in order}
        self.nq = system.nq
        self.pose = {name: self.links[name].placement(q) for name in order}
        self.gravity = np.asarray(system.mechanism.gravity, float)
        #: substituted mimic followers present
        self.mimic = any(link.mimic for link in self.links.values())
        #: the links moved by each coordinate, in tree order (a leader and its followers)
        self.groups: dict[int, list[str]] = {}
        for name in order:
            if self.links[name].s is not None:
                self.groups.setdefault(self.links[name].coord, []).append(name)
        #: q̈ by :meth:`forward_dynamics`: every link of a coordinate has the same parent
        #: (otherwise the caller's dense solve of M q̈ = τ − b)
        self.articulated = all(len({self.links[n].parent for n in g}) == 1
                               for g in self.groups.values())

    # ------------------------------------------------------------------ spatial algebra
    def _motion_in(self, name: str, m: ca.SX) -> ca.SX:
        """X m: a parent-frame motion vector (ω, v) in the child's frame."""
        e, p = self.pose[name]
        w, v = m[:3], m[3:]
        return ca.vertcat(ca.mtimes(e.T, w), ca.mtimes(e.T, v + _cross(w, p)))

    def _force_out(self, name: str, f: ca.SX) -> ca.SX:
        """Xᵀ f: a child-frame force (n, f) in the parent's frame."""
        e, p = self.pose[name]
        lin = ca.mtimes(e, f[3:])
        return ca.vertcat(ca.mtimes(e, f[:3]) + _cross(p, lin), lin)

    def _inertia_out(self, name: str, mat: ca.SX) -> ca.SX:
        """Xᵀ I X of a symmetric 6 × 6 child-frame inertia ``[A B; Bᵀ C]`` (an articulated
        inertia), by 3 × 3 blocks and only the upper triangles of the symmetric ones: with
        A' = E A Eᵀ, B' = E B Eᵀ, C' = E C Eᵀ and L = p̃ C',
        ``Xᵀ I X = [A' + K + Kᵀ − L p̃,  B' + L;  ·,  C']``, K = p̃ B'ᵀ."""
        e, p = self.pose[name]
        a_r = _rotate_sym(e, mat[:3, :3])
        c_r = _rotate_sym(e, mat[3:, 3:])
        b_r = ca.mtimes(ca.mtimes(e, mat[:3, 3:]), e.T)
        px = _skew(p)
        k = ca.mtimes(px, b_r.T)
        low = ca.mtimes(px, c_r)
        top = ca.SX.zeros(3, 3)
        for i in range(3):
            for j in range(i, 3):
                top[i, j] = (a_r[i, j] + k[i, j] + k[j, i]
                             - sum((low[i, m] * px[m, j] for m in range(3)), ca.SX(0)))
                top[j, i] = top[i, j]
        side = b_r + low
        return ca.vertcat(ca.horzcat(top, side), ca.horzcat(side.T, c_r))

    def _rigid_out(self, name: str, m, h: ca.SX, bar: ca.SX) -> tuple:
        """A rigid-body inertia (m, h = m c, Ī about the frame origin) of the child's frame
        in the parent's (Featherstone §2.13): h' = E h + m p,
        Ī' = E Ī Eᵀ − m (p pᵀ − |p|² 1) − (h_E pᵀ + p h_Eᵀ) + 2 (p·h_E) 1, h_E = E h."""
        e, p = self.pose[name]
        h_e = ca.mtimes(e, h)
        rot = _rotate_sym(e, bar)
        pp, ph = ca.dot(p, p), ca.dot(p, h_e)
        out = ca.SX.zeros(3, 3)
        for i in range(3):
            for j in range(i, 3):
                val = rot[i, j] - m * p[i] * p[j] - h_e[i] * p[j] - p[i] * h_e[j]
                if i == j:
                    val = val + m * pp + 2 * ph
                out[i, j] = out[j, i] = val
        return h_e + m * p, out

    def _inertia(self, name: str) -> ca.SX:
        link = self.links[name]
        out = ca.SX.zeros(6, 6)
        out[:3, :3] = link.tensor
        out[3:, 3:] = link.mass * ca.SX.eye(3)
        return out

    @staticmethod
    def _times_inertia(mass, tensor, m: ca.SX) -> ca.SX:
        return ca.vertcat(ca.mtimes(tensor, m[:3]), mass * m[3:])

    @staticmethod
    def _cross_motion(v: ca.SX, m: ca.SX) -> ca.SX:
        """v ×ₘ m (eq. 2.31)."""
        return ca.vertcat(_cross(v[:3], m[:3]), _cross(v[:3], m[3:]) + _cross(v[3:], m[:3]))

    @staticmethod
    def _cross_force(v: ca.SX, f: ca.SX) -> ca.SX:
        """v ×* f (eq. 2.32)."""
        return ca.vertcat(_cross(v[:3], f[:3]) + _cross(v[3:], f[3:]), _cross(v[:3], f[3:]))

    def _joint(self, name: str, x: ca.SX) -> ca.SX:
        """S ẋ_j of a rate or acceleration x (ratio S x[coord] for a follower; zero for a
        rigid link)."""
        link = self.links[name]
        if link.s is None:
            return ca.SX.zeros(6, 1)
        return ca.DM(link.ratio * link.s) * x[link.coord]

    def _base(self) -> ca.SX:
        return ca.vertcat(ca.SX.zeros(3), ca.DM(-self.gravity))

    def _velocities(self, v: ca.SX) -> dict[str, ca.SX]:
        out = {}
        for name in self.order:
            parent = self.links[name].parent
            sv = self._joint(name, v)
            out[name] = sv if parent == GROUND else self._motion_in(
                name, out[parent]) + sv
        return out

    # ------------------------------------------------------------------ algorithms
    def inverse_dynamics(self, v: ca.SX, a: ca.SX) -> ca.SX:
        """τ = M a + b by the recursive Newton–Euler algorithm (Table 5.1), a₀ = −g."""
        vel = self._velocities(v)
        acc, force = {}, {}
        for name in self.order:
            link = self.links[name]
            sv = self._joint(name, v)
            parent_acc = self._base() if link.parent == GROUND else acc[link.parent]
            acc[name] = (self._motion_in(name, parent_acc) + self._joint(name, a)
                         + self._cross_motion(vel[name], sv))
            iv = self._times_inertia(link.mass, link.tensor, vel[name])
            force[name] = (self._times_inertia(link.mass, link.tensor, acc[name])
                           + self._cross_force(vel[name], iv))
        tau = [ca.SX(0)] * self.nq
        for name in reversed(self.order):
            link = self.links[name]
            if link.s is not None:  # a follower's share r Sᵀ f adds into its leader's
                tau[link.coord] = tau[link.coord] + ca.dot(ca.DM(link.ratio * link.s),
                                                           force[name])
            if link.parent != GROUND:
                force[link.parent] = force[link.parent] + self._force_out(name, force[name])
        return ca.vertcat(*tau)

    def mass_matrix(self) -> ca.SX:
        """M by the composite-rigid-body algorithm (Table 6.2; M_ij = S_jᵀ F_i in world
        components, as Pinocchio's ``crba``)."""
        # composite inertias as rigid-body inertias (m, h, Ī): body frames at G, h = 0
        comp = {name: (self.links[name].mass, ca.SX.zeros(3), ca.SX(self.links[name].tensor))
                for name in self.order}
        for name in reversed(self.order):
            parent = self.links[name].parent
            if parent != GROUND:
                mass, h, bar = comp[name]
                h_p, bar_p = self._rigid_out(name, mass, h, bar)
                m_q, h_q, bar_q = comp[parent]
                comp[parent] = (m_q + mass, h_q + h_p, bar_q + bar_p)
        # F_i = Ic_i S_i and every S_j in world components at the world origin (as
        # Pinocchio's crba): M_ij = S_jᵀ F_i with one transform per body, none per pair
        poses = self.world_poses()
        motion_w, force_w = {}, {}
        for name in self.order:
            link = self.links[name]
            if link.s is None:
                continue
            r, rot = poses[name]
            s_i = ca.DM(link.ratio * link.s)
            ang = ca.mtimes(rot, s_i[:3])
            motion_w[name] = ca.vertcat(ang, ca.mtimes(rot, s_i[3:]) + _cross(r, ang))
            mass, h, bar = comp[name]
            f = ca.vertcat(ca.mtimes(bar, s_i[:3]) + _cross(h, s_i[3:]),
                           mass * s_i[3:] - _cross(h, s_i[:3]))
            lin = ca.mtimes(rot, f[3:])
            force_w[name] = ca.vertcat(ca.mtimes(rot, f[:3]) + _cross(r, lin), lin)
        m = ca.SX.zeros(self.nq, self.nq)
        for name in self.order:
            link = self.links[name]
            if link.s is None:
                continue
            # M = Gᵀ M_f G: a follower's entries add into its leader's row and column
            i, f = link.coord, force_w[name]
            m[i, i] = m[i, i] + ca.dot(motion_w[name], f)
            node = name
            while self.links[node].parent != GROUND:
                node = self.links[node].parent
                other = self.links[node]
                if other.s is not None:
                    j = other.coord
                    val = ca.dot(motion_w[node], f)
                    if i == j:
                        m[i, i] = m[i, i] + 2 * val
                    else:
                        m[i, j] = m[i, j] + val
                        m[j, i] = m[i, j]
        return m

    def forward_dynamics(self, v: ca.SX, tau: ca.SX) -> ca.SX:
        """q̈ by the articulated-body algorithm (Table 7.1), a₀ = −g.

        A substituted mimic group (leader and followers, :attr:`groups`; all on one parent
        link P, :attr:`articulated`) is one joint of one coordinate q_l acting on its children
        i together: Table 7.1 with the children stacked, the subspace ``(r_i S_i)_i`` (r = 1
        for the leader) and the block-diagonal articulated inertia, gives

            U_i = IA_i r_i S_i,  D = Σ r_i² S_iᵀ IA_i S_i,  u = τ_l − Σ r_i S_iᵀ pA_i,
            Ū = Σ X_iᵀ U_i,
            IA_P += Σ X_iᵀ IA_i X_i − Ū Ūᵀ / D,
            pA_P += Σ X_iᵀ (pA_i + IA_i c_i) + Ū (u − Σ U_iᵀ c_i) / D,
            q̈_l = (u − Σ U_iᵀ (X_i a_P + c_i)) / D,   a_i = X_i a_P + c_i + r_i S_i q̈_l,

        with c_i = v_i × r_i S_i q̇_l; τ_l is the leader coordinate's force of M q̈ + b = τ
        (Gᵀ of the joint efforts, as :meth:`inverse_dynamics`); the offsets δ enter only the
        joints' placements X_i.  A single joint (the group of one) is Table 7.1 itself.
        Followers on another parent than their leader's are not covered (ValueError).
        """
        if not self.articulated:
            raise ValueError("a mimic follower's joint has another parent than its leader's: "
                             "q̈ by M q̈ = τ − b")
        vel = self._velocities(v)
        art, bias, bias_acc = {}, {}, {}
        for name in self.order:
            link = self.links[name]
            art[name] = self._inertia(name)
            iv = self._times_inertia(link.mass, link.tensor, vel[name])
            bias[name] = self._cross_force(vel[name], iv)
            bias_acc[name] = self._cross_motion(vel[name], self._joint(name, v))
        u_vec, d_inv, u_eff = {}, {}, {}
        for name in reversed(self.order):
            link = self.links[name]
            group = self.groups.get(link.coord, []) if link.s is not None else []
            if len(group) > 1:  # a mimic group: taken at its first link in tree order
                if name == group[0]:
                    self._group_backward(group, tau, art, bias, bias_acc, u_vec, d_inv,
                                         u_eff)
                continue
            ia, pa = art[name], bias[name]
            if link.s is not None:
                s = ca.DM(link.s)
                u = ca.mtimes(ia, s)
                d = ca.dot(s, u)
                eff = tau[link.coord] - ca.dot(s, pa)
                u_vec[name], d_inv[name], u_eff[name] = u, 1 / d, eff
                if link.parent != GROUND:
                    ia = ia - ca.mtimes(u, u.T) * d_inv[name]
                    pa = pa + ca.mtimes(ia, bias_acc[name]) + u * (d_inv[name] * eff)
            elif link.parent != GROUND:
                pa = pa + ca.mtimes(ia, bias_acc[name])
            if link.parent != GROUND:
                art[link.parent] = art[link.parent] + self._inertia_out(name, ia)
                bias[link.parent] = bias[link.parent] + self._force_out(name, pa)
        qdd = [ca.SX(0)] * self.nq
        acc = {}
        for name in self.order:
            if name in acc:  # a follower, set with its group
                continue
            link = self.links[name]
            parent_acc = self._base() if link.parent == GROUND else acc[link.parent]
            group = self.groups.get(link.coord, []) if link.s is not None else []
            if len(group) > 1:
                acc_in = {n: self._motion_in(n, parent_acc) + bias_acc[n] for n in group}
                x = (u_eff[name] - sum((ca.dot(u_vec[n], acc_in[n]) for n in group),
                                       ca.SX(0))) * d_inv[name]
                qdd[link.coord] = x
                for n in group:
                    acc[n] = acc_in[n] + ca.DM(self.links[n].ratio * self.links[n].s) * x
                continue
            a = self._motion_in(name, parent_acc) + bias_acc[name]
            if link.s is not None:
                x = (u_eff[name] - ca.dot(u_vec[name], a)) * d_inv[name]
                qdd[link.coord] = x
                a = a + ca.DM(link.s) * x
            acc[name] = a
        return ca.vertcat(*qdd)

    def _group_backward(self, group, tau, art, bias, bias_acc, u_vec, d_inv, u_eff) -> None:
        """The backward step of a mimic group (:meth:`forward_dynamics`): U_i, 1/D and u
        under the group's first link, IA and pA of the common parent."""
        first = group[0]
        parent = self.links[first].parent
        d, eff = ca.SX(0), tau[self.links[first].coord]
        for n in group:
            s = ca.DM(self.links[n].ratio * self.links[n].s)
            u_vec[n] = ca.mtimes(art[n], s)
            d = d + ca.dot(s, u_vec[n])
            eff = eff - ca.dot(s, bias[n])
        d_inv[first], u_eff[first] = 1 / d, eff
        if parent == GROUND:
            return
        u_bar, ia_p, pa_p, uc = ca.SX.zeros(6), ca.SX.zeros(6, 6), ca.SX.zeros(6), ca.SX(0)
        for n in group:
            ia, c = art[n], bias_acc[n]
            u_bar = u_bar + self._force_out(n, u_vec[n])
            ia_p = ia_p + self._inertia_out(n, ia)
            pa_p = pa_p + self._force_out(n, bias[n] + ca.mtimes(ia, c))
            uc = uc + ca.dot(u_vec[n], c)
        art[parent] = art[parent] + ia_p - ca.mtimes(u_bar, u_bar.T) * d_inv[first]
        bias[parent] = bias[parent] + pa_p + u_bar * ((eff - uc) * d_inv[first])

    def world_poses(self) -> dict[str, tuple[ca.SX, ca.SX]]:
        """(r_G, A) of every body in global components."""
        out: dict[str, tuple[ca.SX, ca.SX]] = {}
        for name in self.order:
            e, p = self.pose[name]
            parent = self.links[name].parent
            if parent == GROUND:
                out[name] = (ca.SX(p), ca.SX(e))
            else:
                r_p, a_p = out[parent]
                out[name] = (r_p + ca.mtimes(a_p, p), ca.mtimes(a_p, e))
        return out

    def frame_jacobian(self, poses, body: str, point: ca.SX) -> ca.SX:
        """(ṙ, ω) = J q̇ of ``point`` (global) fixed on ``body``: column j of an ancestor
        joint is ``(A_j S_v + A_j S_ω × (r − r_Gj), A_j S_ω)``."""
        cols = [ca.SX.zeros(6, 1) for _ in range(self.nq)]
        node = body
        while node != GROUND:
            link = self.links[node]
            if link.s is not None:
                r_j, a_j = poses[node]
                ang = ca.mtimes(a_j, ca.DM(link.s[:3]))
                lin = ca.mtimes(a_j, ca.DM(link.s[3:])) + _cross(ang, point - r_j)
                cols[link.coord] = cols[link.coord] + link.ratio * ca.vertcat(lin, ang)
            node = link.parent
        return ca.horzcat(*cols) if cols else ca.SX(6, 0)
