"""Symbolic kinematics of the bodies, handed to joints, drivers and forces while assembling.

The context owns the symbols q, v, t, u, p and, for each body, its description
(:mod:`casmbd.system.descriptions`): which block of q it owns, its reference point R(q_i) and
rotation matrix A(q_i).  Body points are r_P = r_G + A u_P with r_G = R − A s (seed 000, eq.
6.16; seed 001, eq. 1); directions are A a.  Joints, drivers and forces are written only with
these helpers, so the same element serves planar and spatial bodies in absolute or natural
coordinates.  Rotation matrices are created once per body and shared by every element.
"""

from __future__ import annotations

import copy

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND


class Context:
    """Symbols and per-body kinematic expressions of a mechanism.

    Parameters
    ----------
    mechanism : casmbd.model.Mechanism
    descriptions : dict of str to Description
        One description per moving body, in the order of ``mechanism.bodies``.
    q, v, t, u, p : casadi.SX
        Coordinates, velocities, time, actuator inputs and parameters.
    """

    def __init__(self, mechanism, descriptions, q, v, t, u, p):
        self.mechanism = mechanism
        self.dimension = mechanism.dimension
        self.descriptions = descriptions
        self.q, self.v, self.t = q, v, t
        self.u = {name: u[i] for i, name in enumerate(mechanism.actuators)}
        self.p = {name: p[i] for i, name in enumerate(mechanism.parameters)}
        self.index: dict[str, int] = {}
        offset = 0
        for name, desc in descriptions.items():
            self.index[name] = offset
            offset += desc.size
        self.nq = offset
        self._frames: dict[str, tuple[ca.SX, ca.SX]] = {}
        self._angles: dict[str, ca.SX] = {}
        #: node frames of flexible bodies (``"<body>@<node>"``), made from the body's frame
        self._node_frames: dict[str, tuple[ca.SX, ca.SX]] = {}

    # ---------------------------------------------------------------- coordinates
    def block(self, body: str) -> slice:
        """Slice of q owned by a moving body."""
        i = self.index[body]
        return slice(i, i + self.descriptions[body].size)

    def coordinates(self, body: str) -> ca.SX:
        """q_i of a moving body (a substituted mimic follower: r q_l + δ from its leader's
        block, :mod:`casmbd.system.tree`)."""
        desc = self.descriptions[body]
        if getattr(desc, "mimic", None) is not None:
            return desc.followed(self.coordinates(desc.mimic[1]))
        return self.q[self.block(body)]

    def rates(self, body: str) -> ca.SX:
        """v_i = q̇_i of a moving body (a substituted mimic follower: r q̇_l)."""
        desc = self.descriptions[body]
        if getattr(desc, "mimic", None) is not None:
            return desc.followed(self.rates(desc.mimic[1]), rate=True)
        return self.v[self.block(body)]

    def _frame(self, body: str) -> tuple[ca.SX, ca.SX]:
        if body in self.mechanism.nodes:
            return self._node_frame(body)
        if body not in self._frames:
            self._frames[body] = self.descriptions[body].pose(self, body)
        return self._frames[body]

    def frame_of(self, body: str) -> tuple[ca.SX, ca.SX]:
        """(R, A) of a moving body: its reference point and rotation matrix."""
        return self._frame(body)

    def _node_frame(self, name: str) -> tuple[ca.SX, ca.SX]:
        """(position, rotation) of a node frame ``"<body>@<node>"`` of a flexible body: the
        deformed node r = R + A (u0 + Φ η) and its turned frame (the body's description)."""
        if name not in self._node_frames:
            node = self.mechanism.nodes[name]
            self._node_frames[name] = self.descriptions[node.body].node_frame(
                self, node.body, node.index)
        return self._node_frames[name]

    def owner(self, body: str) -> str:
        """The moving body (or ground) an attachment name belongs to."""
        node = self.mechanism.nodes.get(body)
        return body if node is None else node.body

    def rotation(self, body: str) -> ca.SX:
        """A(q_i) of a body (identity for the ground), built once."""
        if body == GROUND:
            return ca.SX.eye(self.dimension)
        return self._frame(body)[1]

    def reference(self, body: str) -> ca.SX:
        """Global position of the body's reference point R."""
        return self._frame(body)[0]

    def mass_centre(self, body: str) -> ca.SX:
        """Where the body's weight acts: r_G, or the deformed centre of mass of a flexible
        body (its description's ``mass_centre``)."""
        hook = getattr(self.descriptions[body], "mass_centre", None)
        return self.centre_of_mass(body) if hook is None else hook(self, body)

    def centre_of_mass(self, body: str) -> ca.SX:
        """Global centre-of-mass position r_G = R − A s (a node frame: the node's position)."""
        if body == GROUND:
            return ca.SX.zeros(self.dimension)
        if body in self.mechanism.nodes:
            return self._node_frame(body)[0]
        ref, rot = self._frame(body)
        s = self.descriptions[body].offset
        if not np.any(s):
            return ref
        return ref - ca.mtimes(rot, ca.DM(s))

    def angle(self, body: str) -> ca.SX:
        """Planar rotation angle θ of the body frame (0 for the ground)."""
        if self.dimension != 2:
            raise ModelError(f"body '{body}': a rotation angle exists only in the plane")
        if body == GROUND:
            return ca.SX(0.0)
        node = self.mechanism.nodes.get(body)
        if node is not None:
            return self.descriptions[node.body].node_angle(self, node.body, node.index)
        if body not in self._angles:
            self._angles[body] = self.descriptions[body].planar_angle(self, body)
        return self._angles[body]

    def has_angle(self, body: str) -> bool:
        """True when the planar angle of ``body`` is a coordinate (or the body is ground)."""
        if body in self.mechanism.nodes:  # θ + Ψ η: continuous, as a coordinate
            return self.has_angle(self.mechanism.nodes[body].body)
        return body == GROUND or self.descriptions[body].has_angle

    def angular_velocity(self, body: str) -> ca.SX:
        """Global angular velocity (a scalar in the plane), linear in v."""
        if body == GROUND:
            return ca.SX.zeros(1 if self.dimension == 2 else 3)
        node = self.mechanism.nodes.get(body)
        if node is not None:
            return self.descriptions[node.body].node_angular_velocity(self, node.body,
                                                                      node.index)
        return self.descriptions[body].omega(self, body)

    def perturbed(self, body: str) -> tuple[Context, ca.SX]:
        """A copy in which ``body`` alone is displaced by a virtual twist e = (δr_G, δθ).

        The centre of mass moves by δr_G and the rotation becomes (I + δθ̃) A (δθ a scalar in
        the plane), every other body keeping its pose.  An expression written with the copy
        and differentiated with respect to e at e = 0 gives the virtual displacement of that
        expression under a rigid motion of ``body``: the force (first ``dimension`` entries)
        and the moment about the centre of mass (the rest) that ``body`` feels from a term
        whose generalized force is (∂expr/∂q)ᵀ w are (∂expr/∂e)ᵀ w (principle of virtual work,
        seed 000 eqs. 6.40–6.48; seed 001, virtual rotations).

        In the copy every pose (R, A and the planar angle) is a placeholder symbol standing
        for the frozen pose of this context, so that an expression of the copy holds only
        the few operations of the element itself: differentiating it costs O(1) per body,
        not a pass over the body's ancestors (which made reactions and the articulated
        recursion of an N-body chain O(N²) to build).  :meth:`resolve` puts e = 0 and the
        poses back.
        """
        if not getattr(self, "_frozen", False):  # every pose built once: e moves one body
            for name in self.descriptions:
                self._frame(name)
                if self.dimension == 2:
                    self.angle(name)
            self._frozen = True
        dim = self.dimension
        e = ca.SX.sym(f"e_{body}", dim + (1 if dim == 2 else 3))
        other = copy.copy(self)
        other._frames = _Placeholders(self._frames, _frame_symbols)
        other._angles = _Placeholders(self._angles, _angle_symbols)
        other._node_frames = {}  # nodes follow their (perhaps perturbed) body
        other._perturbation = e
        ref0, rot = other._frame(body)
        dth = e[dim:]
        if dim == 2:
            spin = ca.vertcat(ca.horzcat(0, -dth[0]), ca.horzcat(dth[0], 0))
            other._angles[body] = other.angle(body) + dth[0]
        else:
            spin = ca.vertcat(ca.horzcat(0, -dth[2], dth[1]), ca.horzcat(dth[2], 0, -dth[0]),
                              ca.horzcat(-dth[1], dth[0], 0))
        moved = rot + ca.mtimes(spin, rot)
        s = self.descriptions[body].offset
        com = (ref0 - ca.mtimes(rot, ca.DM(s)) if np.any(s) else ref0) + e[:dim]
        ref = com + ca.mtimes(moved, ca.DM(s)) if np.any(s) else com
        other._frames[body] = (ref, moved)
        return other, e

    def resolve(self, expr: ca.SX) -> ca.SX:
        """``expr`` of a :meth:`perturbed` copy at e = 0 with the placeholder poses replaced
        by the poses they stand for (identity on a context that is no perturbed copy)."""
        e = getattr(self, "_perturbation", None)
        if e is None:
            return expr
        syms, values = [e], [ca.SX.zeros(e.numel())]
        for table in (self._frames, self._angles):
            for sym, value in table.pairs():
                syms.append(sym)
                values.append(value)
        return ca.substitute(expr, ca.vertcat(*syms), ca.vertcat(*values))

    # ---------------------------------------------------------------- points and directions
    def point(self, body: str, local) -> ca.SX:
        """Global position of the body point with body-frame coordinates ``local`` (about G)."""
        local = np.asarray(local, float)
        if body == GROUND:
            return ca.SX(ca.DM(local))
        if not np.any(local):
            return self.centre_of_mass(body)
        return self.centre_of_mass(body) + ca.mtimes(self.rotation(body), ca.DM(local))

    def direction(self, body: str, local) -> ca.SX:
        """Global components A a of a body-fixed direction."""
        local = np.asarray(local, float)
        if body == GROUND:
            return ca.SX(ca.DM(local))
        return ca.mtimes(self.rotation(body), ca.DM(local))

    def _element(self, body: str):
        """The model object of a body or node frame (initial pose, ``local``)."""
        node = self.mechanism.nodes.get(body)
        return self.mechanism.bodies[body] if node is None else node

    def initial_rotation(self, body: str) -> np.ndarray:
        """A of a body (or node frame) at its initial pose."""
        if body == GROUND:
            return np.eye(self.dimension)
        return self._element(body).initial_rotation

    def local(self, body: str, point_global) -> np.ndarray:
        """Body-frame coordinates (about G; about the node for a node frame) of a global point
        at the initial pose."""
        if body == GROUND:
            return np.asarray(point_global, float)
        return self._element(body).local(point_global)

    def local_direction(self, body: str, direction_global) -> np.ndarray:
        """Body-frame components of a global direction at the initial pose."""
        return self.initial_rotation(body).T @ np.asarray(direction_global, float)

    def initial_angle(self, body: str) -> float:
        """Planar angle of a body at its initial pose."""
        return 0.0 if body == GROUND else self._element(body).angle

    def initial_position(self, body: str) -> np.ndarray:
        """Centre-of-mass position of a body at its initial pose."""
        if body == GROUND:
            return np.zeros(self.dimension)
        return self._element(body).position

    # ---------------------------------------------------------------- relative rotation
    def relative_rotation(self, body1: str, body2: str, axis=None) -> tuple[ca.SX, ca.SX]:
        """(sin φ, cos φ) of the rotation of body2 relative to body1 since the initial pose.

        In the plane φ is (θ2 − θ1) − (θ2 − θ1)₀; in space it is the rotation about the
        global ``axis`` (given at the initial pose, fixed on body1), measured with a unit
        vector f normal to the axis: sin φ = (A1 f̄1 × A2 f̄2)·(A1 h̄1), cos φ = (A1 f̄1)·(A2 f̄2),
        f̄1 and f̄2 being the body-frame components of f on each body at the initial pose.
        """
        if self.dimension == 2:
            f = np.array([1.0, 0.0])
            f1 = self.direction(body1, self.local_direction(body1, f))
            f2 = self.direction(body2, self.local_direction(body2, f))
            return f1[0] * f2[1] - f1[1] * f2[0], ca.dot(f1, f2)
        h = np.asarray(axis, float)
        f = normal_to(h)
        h1 = self.direction(body1, self.local_direction(body1, h))
        f1 = self.direction(body1, self.local_direction(body1, f))
        f2 = self.direction(body2, self.local_direction(body2, f))
        return ca.dot(ca.cross(f1, f2), h1), ca.dot(f1, f2)

    def relative_angle(self, body1: str, body2: str, axis=None) -> ca.SX:
        """Rotation angle of body2 relative to body1.

        In the plane: θ2 − θ1 (continuous when both angles are coordinates; otherwise the
        initial value plus the change, wrapped to (−π, π]).  In space: the rotation about
        ``axis`` since the initial pose, wrapped to (−π, π].
        """
        if self.dimension == 2 and self.has_angle(body1) and self.has_angle(body2):
            return self.angle(body2) - self.angle(body1)
        sin, cos = self.relative_rotation(body1, body2, axis)
        start = 0.0
        if self.dimension == 2:
            start = self.initial_angle(body2) - self.initial_angle(body1)
        return start + ca.atan2(sin, cos)

    def angle_residual(self, body1: str, body2: str, target: ca.SX, axis=None) -> ca.SX:
        """Residual of the driving constraint φ = target.

        φ − target when φ is a difference of coordinates; otherwise the wrapped difference
        atan2(sin(φ − target), cos(φ − target)) with sin(φ − target) = sin φ cos target −
        cos φ sin target and cos(φ − target) = cos φ cos target + sin φ sin target (the angle
        driver of natural coordinates and Euler parameters).  It is free of the wrap of
        atan2(sin φ, cos φ) (its cut lies half a turn away from the solution, so it stays
        regular through any number of turns), has unit slope at the solution (its multiplier is
        the driving torque, as in absolute coordinates) and is insensitive to the scale of
        (sin φ, cos φ) off the rigid-body constraints.  The bare sin(φ − target) has a second,
        spurious root at φ = target + π, where Newton's method converges from a guess more than
        a quarter turn off (a crank started opposite its driver, a coarse kinematic grid) and
        the driving torque changes sign.
        """
        if self.dimension == 2 and self.has_angle(body1) and self.has_angle(body2):
            return self.angle(body2) - self.angle(body1) - target
        sin, cos = self.relative_rotation(body1, body2, axis)
        if self.dimension == 2:
            target = target - (self.initial_angle(body2) - self.initial_angle(body1))
        c, s = ca.cos(target), ca.sin(target)
        return ca.atan2(sin * c - cos * s, cos * c + sin * s)

    # ---------------------------------------------------------------- user-facing helpers
    def _known(self, body: str) -> None:
        if body != GROUND and body not in self.mechanism.bodies and \
                body not in self.mechanism.nodes:
            raise ModelError(f"unknown body '{body}' in a user expression")

    def position(self, body: str, point=None) -> ca.SX:
        """Global position of a body point given globally at the initial pose (default G)."""
        self._known(body)
        if point is None:
            return self.centre_of_mass(body)
        return self.point(body, self.local(body, point))

    def velocity(self, body: str, point=None) -> ca.SX:
        """Global velocity of a body point: ∂r_P/∂q · v."""
        return ca.jtimes(self.position(body, point), self.q, self.v)

    def time_derivative(self, expr) -> ca.SX:
        """d/dt of an expression of (q, t): ∂e/∂q v + ∂e/∂t."""
        return ca.jtimes(expr, self.q, self.v) + ca.jacobian(expr, self.t)

    def joint_coordinate(self, name: str) -> ca.SX:
        """Coordinate of a joint (θ2 − θ1 for revolute, displacement for prismatic, ...)."""
        if name not in self.mechanism.joints:
            raise ModelError(f"unknown joint '{name}' in a user expression")
        return self.mechanism.joints[name].coordinate(self)


def normal_to(axis) -> np.ndarray:
    """A unit vector normal to ``axis`` (deterministic: from the axis' smallest component)."""
    h = np.asarray(axis, float)
    h = h / np.linalg.norm(h)
    trial = np.zeros(3)
    trial[int(np.argmin(np.abs(h)))] = 1.0
    f = trial - h * np.dot(trial, h)
    return f / np.linalg.norm(f)


def _frame_symbols(body: str, frame: tuple[ca.SX, ca.SX]) -> tuple[tuple, list]:
    """Placeholder (R, A) of a frozen frame and the (symbol, value) pairs to put it back."""
    ref, rot = frame
    r_s = ca.SX.sym(f"R_{body}", ref.numel())
    a_s = ca.SX.sym(f"A_{body}", rot.size1(), rot.size2())
    return (r_s, a_s), [(r_s, ca.densify(ca.vec(ref))), (ca.vec(a_s), ca.densify(ca.vec(rot)))]


def _angle_symbols(body: str, angle: ca.SX) -> tuple[ca.SX, list]:
    """Placeholder θ of a frozen planar angle and its (symbol, value) pair."""
    th = ca.SX.sym(f"theta_{body}")
    return th, [(th, ca.densify(ca.SX(angle)))]


class _Placeholders:
    """A pose table of a perturbed context: a frozen entry is read as a placeholder symbol,
    made on first use; an entry set on the copy (the perturbed body) is kept as given."""

    def __init__(self, frozen: dict, make) -> None:
        self._frozen, self._make = frozen, make
        self._own: dict = {}
        self._pairs: list = []

    def __contains__(self, body: str) -> bool:
        return body in self._own or body in self._frozen

    def __getitem__(self, body: str):
        if body not in self._own:
            value, pairs = self._make(body, self._frozen[body])
            self._own[body] = value
            self._pairs += pairs
        return self._own[body]

    def __setitem__(self, body: str, value) -> None:
        self._own[body] = value

    def pairs(self) -> list:
        """(placeholder, frozen value) of every placeholder made so far."""
        return list(self._pairs)
