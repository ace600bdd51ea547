"""Planar rigid bodies in absolute coordinates, the ground and markers.

A moving body i carries the generalized coordinates q_i = (x_R, y_R, θ): the global position of
its reference point R and the rotation angle of its body frame (seed 000, "Generalized inertia",
eq. 6.16: r = R + A(θ) u).  By default R is the centre of mass (centroidal frame, constant diagonal
mass matrix); with ``reference_point = s`` (body-frame offset of R from the centre of mass) the
centre of mass is at R − A(θ) s and the mass matrix couples translation and rotation (eqs.
6.22–6.23), with a non-zero quadratic-velocity vector (eqs. 6.34–6.37).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import ModelError
from casmbd.model.values import Value, check_value

GROUND = "ground"


def rotation(theta: float) -> np.ndarray:
    """Planar rotation matrix A(θ) (seed 000, eq. 6.2)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def vector2(value, where: str) -> np.ndarray:
    """Validate a finite 2-vector."""
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"{where}: expected a vector of 2 numbers, got {value!r}") from None
    if arr.shape != (2,):
        raise ModelError(f"{where}: expected a vector of 2 numbers, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{where}: must be finite, got {value!r}")
    return arr


def scalar(value, where: str) -> float:
    """Validate a finite number."""
    if isinstance(value, bool):
        raise ModelError(f"{where}: expected a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"{where}: expected a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ModelError(f"{where}: must be finite, got {value!r}")
    return out


@dataclass
class Body:
    """A planar rigid body.

    Parameters
    ----------
    name : str
        Unique name.
    mass : Value
        Mass m > 0 (number, or expression of parameters).
    inertia : Value
        Moment of inertia about the centre of mass, > 0.
    position : array_like
        Global position of the centre of mass (initial guess for assembly).
    angle : float
        Rotation angle of the body frame (initial guess).
    velocity, angular_velocity :
        Initial velocity of the centre of mass and angular velocity.
    reference_point : array_like
        Body-frame offset s of the reference point R from the centre of mass.
    """

    name: str
    mass: Value
    inertia: Value
    position: np.ndarray
    angle: float = 0.0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    angular_velocity: float = 0.0
    reference_point: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self):
        where = f"body '{self.name}'"
        self.mass = check_value(self.mass, f"{where} field 'mass'")
        self.inertia = check_value(self.inertia, f"{where} field 'inertia'")
        self.position = vector2(self.position, f"{where} field 'position'")
        self.angle = scalar(self.angle, f"{where} field 'angle'")
        self.velocity = vector2(self.velocity, f"{where} field 'velocity'")
        self.angular_velocity = scalar(self.angular_velocity, f"{where} field 'angular_velocity'")
        self.reference_point = vector2(self.reference_point, f"{where} field 'reference_point'")

    @property
    def is_centroidal(self) -> bool:
        """True when the reference point is the centre of mass."""
        return not np.any(self.reference_point)

    def local(self, point_global) -> np.ndarray:
        """Body-frame coordinates (about G) of a global point at the initial pose."""
        return rotation(self.angle).T @ (np.asarray(point_global, float) - self.position)

    def initial_coordinates(self) -> np.ndarray:
        """q_i = (x_R, y_R, θ) at the initial pose: R = r_G + A(θ) s."""
        ref = self.position + rotation(self.angle) @ self.reference_point
        return np.array([ref[0], ref[1], self.angle])

    def initial_velocities(self) -> np.ndarray:
        """Time derivative of q_i at the initial state: Ṙ = ṙ_G + ω × (A s)."""
        a_s = rotation(self.angle) @ self.reference_point
        ref_vel = self.velocity + self.angular_velocity * np.array([-a_s[1], a_s[0]])
        return np.array([ref_vel[0], ref_vel[1], self.angular_velocity])


@dataclass
class Marker:
    """A named point fixed on a body, given by its global location at the initial pose."""

    name: str
    body: str
    point: np.ndarray

    def __post_init__(self):
        self.point = vector2(self.point, f"marker '{self.name}' field 'point'")
