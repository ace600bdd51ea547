"""Symbolic kinematics of the bodies, handed to joints, drivers and forces while assembling.

The context owns the symbols q, v, t, u, p and writes body-point positions
r_P = r_G(q) + A(θ) u_P, with r_G = R − A(θ) s for a body whose reference point R is offset by s
from its centre of mass (seed 000, eq. 6.16).  Sines and cosines are created once per body so
that every element shares them.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND, rotation


class Context:
    """Symbols and per-body kinematic expressions of a planar mechanism."""

    def __init__(self, mechanism, q, v, t, u, p):
        self.mechanism = mechanism
        self.q, self.v, self.t = q, v, t
        self.u = {name: u[i] for i, name in enumerate(mechanism.actuators)}
        self.p = {name: p[i] for i, name in enumerate(mechanism.parameters)}
        self.index = {name: 3 * i for i, name in enumerate(mechanism.bodies)}
        self._rot: dict[str, ca.SX] = {}

    # ---------------------------------------------------------------- coordinates
    def coordinates(self, body: str) -> ca.SX:
        """(x_R, y_R, θ) of a moving body."""
        i = self.index[body]
        return self.q[i:i + 3]

    def angle(self, body: str):
        """Rotation angle θ of the body frame (0 for the ground)."""
        if body == GROUND:
            return ca.SX(0.0)
        return self.q[self.index[body] + 2]

    def rotation(self, body: str) -> ca.SX:
        """A(θ) of a body, built once."""
        if body not in self._rot:
            th = self.angle(body)
            c, s = ca.cos(th), ca.sin(th)
            self._rot[body] = ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))
        return self._rot[body]

    def centre_of_mass(self, body: str) -> ca.SX:
        """Global centre-of-mass position r_G = R − A(θ) s."""
        i = self.index[body]
        ref = self.q[i:i + 2]
        s = self.mechanism.bodies[body].reference_point
        if not np.any(s):
            return ref
        return ref - self.rotation(body) @ ca.DM(s)

    # ---------------------------------------------------------------- points and directions
    def point(self, body: str, local) -> ca.SX:
        """Global position of the body point with body-frame coordinates ``local`` (about G)."""
        local = np.asarray(local, float)
        if body == GROUND:
            return ca.SX(ca.DM(local))
        if not np.any(local):
            return self.centre_of_mass(body)
        return self.centre_of_mass(body) + self.rotation(body) @ ca.DM(local)

    def direction(self, body: str, local) -> ca.SX:
        """Global components A(θ) a of a body-fixed direction."""
        local = np.asarray(local, float)
        if body == GROUND:
            return ca.SX(ca.DM(local))
        return self.rotation(body) @ ca.DM(local)

    def local(self, body: str, point_global) -> np.ndarray:
        """Body-frame coordinates (about G) of a global point at the initial pose."""
        if body == GROUND:
            return np.asarray(point_global, float)
        return self.mechanism.bodies[body].local(point_global)

    def local_direction(self, body: str, direction_global) -> np.ndarray:
        """Body-frame components of a global direction at the initial pose."""
        if body == GROUND:
            return np.asarray(direction_global, float)
        return rotation(self.mechanism.bodies[body].angle).T @ np.asarray(direction_global, float)

    def initial_angle(self, body: str) -> float:
        """Angle of a body at its initial pose."""
        return 0.0 if body == GROUND else self.mechanism.bodies[body].angle

    def initial_position(self, body: str) -> np.ndarray:
        """Centre-of-mass position of a body at its initial pose."""
        return np.zeros(2) if body == GROUND else self.mechanism.bodies[body].position

    # ---------------------------------------------------------------- user-facing helpers
    def _known(self, body: str) -> None:
        if body != GROUND and body not in self.mechanism.bodies:
            raise ModelError(f"unknown body '{body}' in a user expression")

    def position(self, body: str, point=None) -> ca.SX:
        """Global position of a body point given globally at the initial pose (default G)."""
        self._known(body)
        if point is None:
            return self.point(body, np.zeros(2)) if body != GROUND else ca.SX.zeros(2)
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
