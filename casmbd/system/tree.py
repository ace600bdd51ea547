"""Joint (relative) coordinates: a spanning tree of the joint graph and its recursive kinematics.

With ``coordinates = "joint"`` a body's pose is written from its parent's pose and the
coordinates of the tree joint between them (seed 001, "Recursive methods", eqs. 256–290: the
absolute velocities and accelerations of body i follow from those of body i−1 and the joint
rates).  The joints of the spanning tree are absorbed by the coordinates and write no
equation; the remaining joints close loops and keep their constraint equations, written with
the same context helpers as in absolute coordinates (seed 002, "Closed Loop Equations of
Motion").

Each joint moves its child relative to its parent from the design pose: the joint motion in the
design frame is x ↦ J₀ + Δd + ΔR (x − J₀) about the joint point J₀ (ΔR a rotation, Δd a
translation, both functions of the joint coordinates), carried along with the parent:

    A_C = A_P A_P0ᵀ ΔR A_C0,
    r_C = r_P + A_P A_P0ᵀ (J₀ + Δd + ΔR (r_C0 − J₀) − r_P0),
    ω_C = ω_P + A_P A_P0ᵀ ω_rel,

with ω_rel the angular velocity of ΔR in the design frame.  A body with no tree joint to a
parent is a floating root: its block is an absolute description (x, y, θ in the plane; position
and Euler parameters in space).

A gear (:mod:`casmbd.model.gear`, a URDF ``<mimic>``) between two single-coordinate tree
joints (revolute or prismatic, each carrying its ``body2``) is *substituted* rather than kept
as a loop equation: the follower's tree coordinate is q_f = r q_l + δ (q̇_f = r q̇_l, q̈_f = r q̈_l;
a leader that itself follows is resolved to its own leader, ratios and offsets composed), so
the follower's body owns no coordinate and its joint moves with the leader's (as Pinocchio's
``JointModelMimic``).  With G = ∂q_full/∂q (constant) the equations are those of the full tree
projected exactly: M = Gᵀ M_f G, Q = Gᵀ Q_f; the recursions below do this body by body — the
follower's motion subspace is written on its leader's coordinate, S' = r S_f e_kᵀ
(:attr:`TreeKinematics.owner`), so the composite-body, Newton–Euler and bias recursions add
its column into the leader's row.  The gear is absorbed (it writes no equation); its reaction
is the follower joint's axial share of the tree reaction (:mod:`casmbd.system.joint_reactions`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND
from casmbd.system.descriptions import (
    Description,
    PlanarAbsolute,
    SpatialAbsolute,
    describe,
    register_description,
)


def is_tree_joint(joint) -> bool:
    """True when the joint's kind can carry a body in the tree (``tree_joint``; a distance
    joint cannot: it leaves 5 DOF; a gear couples coordinates and carries no body)."""
    return bool(getattr(joint, "tree_joint", False))


@dataclass(frozen=True)
class TreeEdge:
    """Body ``child`` hangs from ``parent`` through ``joint`` (None: a floating root)."""

    child: str
    parent: str
    joint: str | None


def _incidence(joints, names) -> dict[str, list[str]]:
    """body -> the joints of ``names`` that touch it, in the order of ``names`` (the graph
    walks below visit them in that order, as a scan of ``names`` would, in O(1) per joint)."""
    touching: dict[str, list[str]] = {}
    for name in names:
        joint = joints[name]
        for body in dict.fromkeys((joint.body1, joint.body2)):
            touching.setdefault(body, []).append(name)
    return touching


def spanning_tree(mechanism, tree=None) -> tuple[list[TreeEdge], list[str]]:
    """Choose the spanning tree of the joint graph, breadth first from the ground.

    Parameters
    ----------
    mechanism : Mechanism
    tree : sequence of str, optional
        Joints that must belong to the tree (the rest is completed automatically).

    Returns
    -------
    edges : list of TreeEdge
        One per body, parents before children.
    loop_joints : list of str
        Joints left out of the tree (loop-closing and non-tree types), declaration order.

    Raises
    ------
    ModelError
        If a named joint is unknown, cannot carry a body or would close a loop.
    """
    joints = mechanism.joints
    named = list(tree or ())
    for name in named:
        if name not in joints:
            raise ModelError(f"tree: unknown joint '{name}' (known: {', '.join(joints)})")
        if not is_tree_joint(joints[name]):
            raise ModelError(f"tree: joint '{name}' ({type(joints[name]).__name__}) cannot be a "
                             "tree joint")
    # union–find: the named joints first (they must not close a loop), then the others in
    # breadth-first order from the ground so that the tree is shallow
    root = {name: name for name in [GROUND, *mechanism.bodies]}

    def find(x: str) -> str:
        while root[x] != x:
            root[x] = root[root[x]]
            x = root[x]
        return x

    chosen: list[str] = []
    for name in named:
        a, b = find(joints[name].body1), find(joints[name].body2)
        if a == b:
            raise ModelError(f"tree: joint '{name}' would close a loop with the other named "
                             "joints; name a tree without cycles")
        root[a] = b
        chosen.append(name)
    others = [n for n, j in joints.items() if n not in named and is_tree_joint(j)]
    frontier, seen = deque([GROUND]), {GROUND}
    touching = _incidence(joints, others)
    while frontier:
        node = frontier.popleft()
        for name in touching.get(node, ()):
            joint = joints[name]
            other = joint.body2 if joint.body1 == node else joint.body1
            a, b = find(joint.body1), find(joint.body2)
            if a != b:
                root[a] = b
                chosen.append(name)
            if other not in seen:
                seen.add(other)
                frontier.append(other)
    for name in others:  # components not connected to the ground
        a, b = find(joints[name].body1), find(joints[name].body2)
        if a != b:
            root[a] = b
            chosen.append(name)
    # orient the chosen edges away from the ground (floating roots for detached components)
    parent_of: dict[str, TreeEdge] = {}
    order: list[str] = []
    reached = {GROUND}

    carrying = _incidence(joints, chosen)

    def grow(start: str) -> None:
        queue = deque([start])
        while queue:
            node = queue.popleft()
            for name in carrying.get(node, ()):
                joint = joints[name]
                other = joint.body2 if joint.body1 == node else joint.body1
                if other in reached:
                    continue
                reached.add(other)
                parent_of[other] = TreeEdge(other, node, name)
                order.append(other)
                queue.append(other)

    grow(GROUND)
    for body in mechanism.bodies:
        if body not in reached:
            reached.add(body)
            parent_of[body] = TreeEdge(body, GROUND, None)
            order.append(body)
            grow(body)
    in_tree = {e.joint for e in parent_of.values() if e.joint}
    loops = [n for n in joints if n not in in_tree]
    return [parent_of[b] for b in order], loops


#: entries of a design-pose constant (a unit axis, a rotation matrix) below this are
#: rounding of an exact zero (cos π/2 = 6.1e-17 in a URDF's rpy) and written as 0: the
#: generated code keeps the structural zeros (the Panda's inverse dynamics: 4819 → fewer
#: instructions), the model moves by less than 1e-16
ROUNDING_ZERO = 1e-15


def snap(values) -> np.ndarray:
    """``values`` with entries of magnitude below :data:`ROUNDING_ZERO` set to 0."""
    out = np.array(values, dtype=float)
    out[np.abs(out) < ROUNDING_ZERO] = 0.0
    return out


def rodrigues(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    """Rotation by ``angle`` about the unit ``axis``: I + sin φ h̃ + (1 − cos φ) h̃²."""
    axis = snap(axis)
    skew = ca.DM([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return ca.DM.eye(3) + ca.sin(angle) * skew + (1 - ca.cos(angle)) * ca.mtimes(skew, skew)


def planar_rotation(angle: ca.SX) -> ca.SX:
    """Planar rotation matrix of ``angle``."""
    c, s = ca.cos(angle), ca.sin(angle)
    return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))


class TreeJointDescription(Description):
    """The coordinates of the tree joint that carries one body (see the module docstring).

    The joint's kind owns its layout and motion (:meth:`casmbd.model.joints.Joint.tree_layout`,
    :meth:`~casmbd.model.joints.Joint.tree_motion`); this description hands it the symbolic
    helpers :meth:`rodrigues` and :meth:`planar_rotation` and composes the motion with the
    parent's pose.
    """

    local = False
    rodrigues = staticmethod(rodrigues)
    planar_rotation = staticmethod(planar_rotation)

    def __init__(self, body, edge: TreeEdge, joint, mechanism):
        super().__init__(body)
        self.offset = np.zeros(body.dimension)  # the pose is written for the centre of mass
        self.edge = edge
        self.joint = joint
        self.parent = edge.parent
        dim = body.dimension
        self.prefix = joint.name
        parent_body = mechanism.bodies.get(edge.parent)
        rot_p0 = np.eye(dim) if parent_body is None else parent_body.initial_rotation
        pos_p0 = np.zeros(dim) if parent_body is None else np.asarray(parent_body.position)
        self.rot_p0_t = snap(rot_p0.T)
        self.pos_p0 = pos_p0
        self.rot_c0 = snap(body.initial_rotation)
        self.pos_c0 = np.asarray(body.position, float)
        point = getattr(joint, "point", None)
        self.point = self.pos_c0.copy() if point is None else np.asarray(point, float)
        self.kind_name = type(joint).__name__
        self.names, self.lengths = self._layout()
        #: a substituted gear (mimic) follower: (gear, leader body, index in the leader's
        #: block, ratio r, offset δ) with q_f = r q_l + δ; None for an independent joint
        self.mimic: tuple[str, str, int, float, float] | None = None
        self.own_size = len(self.names)
        if dim == 2:
            self.has_angle = True
            angle_p0 = 0.0 if parent_body is None else parent_body.angle
            self.angle_offset = body.angle - angle_p0

    # -------------------------------------------------------------- layout
    def _layout(self) -> tuple[tuple[str, ...], tuple[bool, ...]]:
        return self.joint.tree_layout()

    def follow(self, gear: str, leader: str, index: int, ratio: float, offset: float) -> None:
        """Make this joint a substituted follower: q = ratio q_leader[index] + offset; the
        body then owns no coordinate (module docstring)."""
        self.mimic = (gear, leader, index, float(ratio), float(offset))
        self.names, self.lengths = (), ()

    def followed(self, q_leader: ca.SX, rate: bool = False) -> ca.SX:
        """The follower's own tree coordinate r q_l + δ (its rate r q̇_l with ``rate``) from
        the leader's block."""
        _, _, k, ratio, offset = self.mimic
        return ratio * q_leader[k] + (0.0 if rate else offset)

    def initial(self) -> np.ndarray:
        if self.mimic is not None:
            return np.zeros(0)
        return self.joint.tree_initial()

    def initial_rates(self) -> np.ndarray:
        raise NotImplementedError("tree rates are found for all bodies at once")

    # -------------------------------------------------------------- the joint motion
    def _motion(self, q: ca.SX, v: ca.SX | None = None):
        """(ΔR, Δd, ω_rel) in the design frame from the joint's kind; ω_rel only when ``v``
        is given."""
        return self.joint.tree_motion(self, q, v)

    def _parent_pose(self, ctx) -> tuple[ca.SX, ca.SX]:
        if self.parent == GROUND:
            return ca.SX.zeros(self.dimension), ca.SX.eye(self.dimension)
        return ctx.centre_of_mass(self.parent), ctx.rotation(self.parent)

    def pose(self, ctx, name):
        pos_p, rot_p = self._parent_pose(ctx)
        return self.compose(pos_p, rot_p, ctx.coordinates(name))

    def compose(self, pos_p: ca.SX, rot_p: ca.SX, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(r_C, A_C) from the parent's centre of mass and rotation and the joint's q."""
        rot_rel, shift, _ = self._motion(q)
        carry = ca.mtimes(rot_p, ca.DM(self.rot_p0_t))
        arm = ca.DM(self.point - self.pos_p0) + shift \
            + ca.mtimes(rot_rel, ca.DM(self.pos_c0 - self.point))
        rot = ca.mtimes(carry, ca.mtimes(rot_rel, ca.DM(self.rot_c0)))
        return pos_p + ca.mtimes(carry, arm), rot

    def omega(self, ctx, name):
        _, rot_p = self._parent_pose(ctx)
        return self.compose_omega(ctx.angular_velocity(self.parent), rot_p,
                                  ctx.coordinates(name), ctx.rates(name))

    def compose_omega(self, omega_p: ca.SX, rot_p: ca.SX, q: ca.SX, v: ca.SX) -> ca.SX:
        """ω_C = ω_P + A_P A_P0ᵀ ω_rel(q, q̇)."""
        _, _, rel = self._motion(q, v)
        if self.dimension == 2:
            return omega_p + rel
        return omega_p + ca.mtimes(ca.mtimes(rot_p, ca.DM(self.rot_p0_t)), rel)

    def planar_angle(self, ctx, name):
        rel = self.joint.tree_angle(ctx.coordinates(name))
        return ctx.angle(self.parent) + self.angle_offset + rel

    def energy(self, ctx, name, mass, inertia) -> ca.SX:
        """T = ½ m |ṙ_G|² + ½ ωᵀ (A J Aᵀ) ω (+ ½ c (pᵀṗ)² for a ball joint's parameters)."""
        vel = ca.jtimes(ctx.centre_of_mass(name), ctx.q, ctx.v)
        omega = ctx.angular_velocity(name)
        total = 0.5 * mass * ca.dot(vel, vel)
        if self.dimension == 2:
            return total + 0.5 * inertia * omega**2
        omega_b = ca.mtimes(ctx.rotation(name).T, omega)
        total += 0.5 * ca.bilin(inertia, omega_b, omega_b)
        if self.joint.euler_parameters:
            p, pdot = ctx.coordinates(name), ctx.rates(name)
            total += 0.5 * (4.0 / 3.0) * ca.trace(inertia) * ca.dot(p, pdot) ** 2
        return total

    def normalization_inertia(self, inertia) -> ca.SX | None:
        """c of the term ½ c (pᵀṗ)² for a ball joint's Euler parameters (else None)."""
        if self.joint.euler_parameters:
            return 4.0 / 3.0 * ca.trace(inertia)
        return None

    def constraints(self, q):
        if self.joint.euler_parameters and self.mimic is None:
            return 0.5 * (ca.dot(q, q) - 1.0), ("normalization",)
        return ca.SX(0, 1), ()


class FloatingRoot:
    """Mix-in giving an absolute description the joint-coordinate energy interface."""

    local = False
    parent = GROUND
    joint = None

    def normalization_inertia(self, inertia) -> ca.SX | None:
        """c of the term ½ c (pᵀṗ)² of the Euler parameters of a spatial floating body."""
        return 4.0 / 3.0 * ca.trace(inertia) if self.dimension == 3 else None

    def energy(self, ctx, name, mass, inertia) -> ca.SX:
        return self.kinetic_energy(ctx.coordinates(name), ctx.rates(name), mass, inertia)


@register_description("planar_floating")
class PlanarFloating(FloatingRoot, PlanarAbsolute):
    """A planar body without a tree joint: (x, y, θ) of its centre of mass."""


@register_description("spatial_floating")
class SpatialFloating(FloatingRoot, SpatialAbsolute):
    """A spatial body without a tree joint: position and Euler parameters."""


def tree_descriptions(mechanism, tree=None) -> tuple[dict[str, Description], list[str]]:
    """Descriptions of every body in joint coordinates, in the order of ``mechanism.bodies``,
    and the names of the joints the tree absorbs."""
    edges, _ = spanning_tree(mechanism, tree)
    by_child = {e.child: e for e in edges}
    out: dict[str, Description] = {}
    for name in [e.child for e in edges]:  # parents first: poses are built recursively
        body, edge = mechanism.bodies[name], by_child[name]
        if edge.joint is None:  # a floating root: the description its kind names
            desc = describe(body, "joint")
            # its coordinates locate the body's reference point, as in absolute coordinates
            # (a URDF floating base: the root link frame's origin, casmbd.io.urdf)
            desc.prefix = name
            out[name] = desc
        else:
            out[name] = TreeJointDescription(body, edge, mechanism.joints[edge.joint], mechanism)
    absorbed = [e.joint for e in edges if e.joint]
    absorbed += substitute_mimics(mechanism, out)
    return {name: out[name] for name in mechanism.bodies}, absorbed


def _carrier(mechanism, descriptions, joint_name: str):
    """The tree description of the body a single-coordinate joint carries as its ``body2``
    (None when the joint is not such a tree joint)."""
    joint = mechanism.joints.get(joint_name)
    if joint is None or not getattr(joint, "gear_substitutable", False):
        return None  # the kind says whether its tree coordinate is its coordinate c − c⁰
    desc = descriptions.get(joint.body2)
    if not isinstance(desc, TreeJointDescription) or desc.joint is not joint \
            or desc.own_size != 1 or len(joint.coordinate_names) != 1:
        return None
    return desc


def substitute_mimics(mechanism, descriptions: dict) -> list[str]:
    """Substitute every gear between two single-coordinate tree joints (module docstring):
    the follower's description takes q_f = r q_l + δ, resolved to an independent leader.

    Gears are taken in declaration order; a joint followed twice, a gear whose leader chain
    returns to its follower, or a gear on other joint kinds keeps its constraint equation.
    Returns the names of the substituted gears (absorbed like tree joints).
    """
    links: dict[str, tuple[str, str, float, float]] = {}  # follower body -> gear, leader…
    if not getattr(mechanism, "substitute_gears", True):
        return []
    for joint in mechanism.joints.values():
        if getattr(joint, "kind", None) != "gear" or joint.coordinate1 or joint.coordinate2 \
                or not all(isinstance(x, (int, float)) for x in (joint.ratio, joint.offset)):
            continue  # a ratio given as an expression keeps the equation
        lead = _carrier(mechanism, descriptions, joint.joint1)
        follow = _carrier(mechanism, descriptions, joint.joint2)
        if lead is None or follow is None or follow.body.name in links \
                or lead is follow:
            continue
        body, leader = follow.body.name, lead.body.name
        seen = {body}
        while leader in links and leader not in seen:  # a cycle keeps the gear a constraint
            seen.add(leader)
            leader = links[leader][1]
        if leader in seen:
            continue
        links[body] = (joint.name, lead.body.name, float(joint.ratio), float(joint.offset))

    def resolve(body: str) -> tuple[str, float, float]:
        """(independent leader, ratio, offset) of a follower through its chain."""
        _, leader, ratio, offset = links[body]
        if leader not in links:
            return leader, ratio, offset
        root, r2, d2 = resolve(leader)
        return root, ratio * r2, ratio * d2 + offset

    for body in links:
        root, ratio, offset = resolve(body)
        descriptions[body].follow(links[body][0], root, 0, ratio, offset)
    return [links[b][0] for b in links]


def _spin(omega: ca.SX, dim: int) -> ca.SX:
    """W(ω) with Ȧ = W(ω) A."""
    if dim == 2:
        w = omega[0] if omega.numel() else omega
        return ca.vertcat(ca.horzcat(0, -w), ca.horzcat(w, 0))
    return ca.vertcat(ca.horzcat(0, -omega[2], omega[1]), ca.horzcat(omega[2], 0, -omega[0]),
                      ca.horzcat(-omega[1], omega[0], 0))


class TreeKinematics:
    """Body twists, motion subspaces and velocity-product accelerations of a tree, body by body.

    Differentiating a body's pose with respect to all of q costs a pass over every ancestor;
    here each body's pose is written with local symbols for its parent's pose (r_P, A_P) and its
    joint's coordinates, differentiated locally with the parent's known rates (ṙ_P,
    Ȧ_P = W(ω_P) A_P, second rates r̈_P, Ä_P = (W(α_P) + W(ω_P)²) A_P), and composed — so every
    quantity costs O(1) new operations per body and the whole tree O(N) (seed 001, eqs.
    256–290: velocities and accelerations of body i from those of body i−1 and the joint).

    Attributes (dicts by body name)
    -------------------------------
    twist : (ω, ṙ_G), linear in q̇.
    motion : S = ∂twist/∂q̇_i, the joint's motion subspace (global components); for a
        substituted mimic follower S' = r S_f e_kᵀ on its leader's block.
    bias : (ω̇, r̈_G) at q̈ = 0, the velocity-product acceleration J̇ q̇.
    owner : the body whose block of q̇ the motion subspace multiplies (the body itself, or a
        follower's independent leader).
    """

    def __init__(self, system):
        ctx, dim = system.ctx, system.dimension
        self.system = system
        self.twist, self.motion, self.bias = {}, {}, {}
        self.owner: dict[str, str] = {}
        self.order = []
        for name in system.body_names:
            self._visit(name)
        nw = 1 if dim == 2 else 3
        for name in self.order:
            desc = system.descriptions[name]
            q_c, v_c = ctx.coordinates(name), ctx.rates(name)
            mimic = getattr(desc, "mimic", None)
            self.owner[name] = name if mimic is None else mimic[1]
            if desc.joint is None:  # floating root: its own block
                vel = ca.jtimes(ctx.centre_of_mass(name), q_c, v_c)
                twist = ca.vertcat(ctx.angular_velocity(name), vel)
                self.twist[name] = twist
                self.motion[name] = ca.jacobian(twist, v_c)
                self.bias[name] = ca.jtimes(twist, q_c, v_c)
                continue
            parent = desc.parent
            if parent == GROUND:
                r_p, a_p = ca.SX.zeros(dim), ca.SX.eye(dim)
                w_p, dr_p = ca.SX.zeros(nw), ca.SX.zeros(dim)
                alpha_p, ddr_p = ca.SX.zeros(nw), ca.SX.zeros(dim)
            else:
                r_p, a_p = ctx.centre_of_mass(parent), ctx.rotation(parent)
                w_p, dr_p = self.twist[parent][:nw], self.twist[parent][nw:]
                alpha_p, ddr_p = self.bias[parent][:nw], self.bias[parent][nw:]
            k = desc.own_size
            sym = {key: ca.SX.sym(key, *shape) for key, shape in (
                ("rp", (dim, 1)), ("ap", (dim, dim)), ("qc", (k, 1)), ("rpd", (dim, 1)),
                ("apd", (dim, dim)), ("vc", (k, 1)), ("wp", (nw, 1)), ("rpdd", (dim, 1)),
                ("apdd", (dim, dim)), ("wpd", (nw, 1)))}
            r_c, _ = desc.compose(sym["rp"], sym["ap"], sym["qc"])
            x = ca.vertcat(sym["rp"], ca.vec(sym["ap"]), sym["qc"])
            xd = ca.vertcat(sym["rpd"], ca.vec(sym["apd"]), sym["vc"])
            vel = ca.jtimes(r_c, x, xd)
            omega = desc.compose_omega(sym["wp"], sym["ap"], sym["qc"], sym["vc"])
            twist = ca.vertcat(omega, vel)
            motion = ca.jacobian(twist, sym["vc"])
            xdd = ca.vertcat(sym["rpdd"], ca.vec(sym["apdd"]), ca.SX.zeros(k))
            bias = ca.jtimes(twist, ca.vertcat(x, xd, sym["wp"]),
                             ca.vertcat(xd, xdd, sym["wpd"]))
            spin = _spin(w_p, dim)
            values = {"rp": r_p, "ap": a_p, "qc": q_c, "rpd": dr_p,
                      "apd": ca.mtimes(spin, a_p), "vc": v_c, "wp": w_p, "rpdd": ddr_p,
                      "apdd": ca.mtimes(_spin(alpha_p, dim) + ca.mtimes(spin, spin), a_p),
                      "wpd": alpha_p}
            keys = list(sym)
            twist, motion, bias = ca.substitute(
                [twist, motion, bias], [ca.vec(sym[key]) for key in keys],
                [ca.densify(ca.vec(ca.SX(values[key]))) for key in keys])
            if mimic is not None:  # S' = r S_f e_kᵀ on the leader's block
                lead = system.descriptions[mimic[1]].size
                cols = [ca.SX.zeros(motion.size1(), 1)] * lead
                cols[mimic[2]] = mimic[3] * motion
                motion = ca.horzcat(*cols)
            self.twist[name], self.motion[name], self.bias[name] = twist, motion, bias

    def _visit(self, name: str) -> None:
        if name in self.order:
            return
        parent = self.system.descriptions[name].parent
        if parent != GROUND:
            self._visit(parent)
        self.order.append(name)

    def accelerations(self, a: ca.SX) -> dict[str, ca.SX]:
        """(ω̇, r̈_G) of every body for joint accelerations ``a``: A_C = X A_P + S q̈_C + c_C,
        here as A_C = bias_C + S_C q̈_C + X (A_P − bias_P), O(1) per body."""
        ctx, dim = self.system.ctx, self.system.dimension
        nw = 1 if dim == 2 else 3
        out: dict[str, ca.SX] = {}
        for name in self.order:
            desc = self.system.descriptions[name]
            acc = self.bias[name] + ca.mtimes(self.motion[name],
                                              self.system.body_part(a, self.owner[name]))
            if desc.parent != GROUND:
                extra = out[desc.parent] - self.bias[desc.parent]
                d = ctx.centre_of_mass(name) - ctx.centre_of_mass(desc.parent)
                ang = extra[:nw]
                lin = extra[nw:] + (ca.vertcat(-ang[0] * d[1], ang[0] * d[0]) if dim == 2
                                    else ca.cross(ang, d))
                acc = acc + ca.vertcat(ang, lin)
            out[name] = acc
        return out
