"""Rigid bodies (planar and spatial), the ground and markers.

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
from casmbd.model.rotations import rotation_matrix
from casmbd.model.values import Value, check_value

GROUND = "ground"


def rotation(theta: float) -> np.ndarray:
    """Planar rotation matrix A(θ) (seed 000, eq. 6.2)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def vector(value, where: str, size: int) -> np.ndarray:
    """Validate a finite vector of ``size`` numbers."""
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"{where}: expected a vector of {size} numbers, got {value!r}") from None
    if arr.shape != (size,):
        raise ModelError(f"{where}: expected a vector of {size} numbers, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{where}: must be finite, got {value!r}")
    return arr


def vector2(value, where: str) -> np.ndarray:
    """Validate a finite 2-vector."""
    return vector(value, where, 2)


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

    dimension = 2

    @property
    def is_centroidal(self) -> bool:
        """True when the reference point is the centre of mass."""
        return not np.any(self.reference_point)

    @property
    def initial_rotation(self) -> np.ndarray:
        """A(θ) at the initial pose."""
        return rotation(self.angle)

    def local(self, point_global) -> np.ndarray:
        """Body-frame coordinates (about G) of a global point at the initial pose."""
        return rotation(self.angle).T @ (np.asarray(point_global, float) - self.position)


@dataclass
class Marker:
    """A named point fixed on a body, given by its global location at the initial pose."""

    name: str
    body: str
    point: np.ndarray
    dimension: int = 2

    def __post_init__(self):
        self.point = vector(self.point, f"marker '{self.name}' field 'point'", self.dimension)


@dataclass
class SpatialBody:
    """A spatial rigid body.

    Its pose is the global position of the centre of mass and the unit quaternion (Euler
    parameters) ``orientation = [e0, e1, e2, e3]`` of the body frame: a body point with
    body-frame coordinates u (about G) is at r = r_G + A(p) u (seed 001, eq. 1).  How the pose is
    turned into generalized coordinates (Euler parameters, natural coordinates, joint
    coordinates) is the system's choice, not the body's.

    Parameters
    ----------
    name : str
        Unique name.
    mass : Value
        Mass m > 0.
    inertia : sequence of Value
        [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], the inertia tensor about the centre of
        mass in body axes (seed 001, eq. 102; products are the tensor elements).
    position : array_like, 3
        Global position of the centre of mass (initial guess for assembly).
    orientation : array_like, 4
        Unit quaternion [w, x, y, z] of the initial pose (normalised here; a norm far from 1 is
        an error).
    velocity, angular_velocity : array_like, 3
        Initial velocity of the centre of mass and angular velocity, global components.
    reference_point : array_like, 3
        Body-frame offset s of the coordinates' reference point R from the centre of mass.
    """

    name: str
    mass: Value
    inertia: tuple
    position: np.ndarray
    orientation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    reference_point: np.ndarray = field(default_factory=lambda: np.zeros(3))

    dimension = 3

    def __post_init__(self):
        where = f"body '{self.name}' field"
        self.mass = check_value(self.mass, f"{where} 'mass'")
        inertia = self.inertia
        if isinstance(inertia, (int, float)) or not hasattr(inertia, "__len__") \
                or len(inertia) not in (3, 6):
            raise ModelError(f"{where} 'inertia': expected [Ixx, Iyy, Izz] or "
                             f"[Ixx, Iyy, Izz, Ixy, Ixz, Iyz], got {inertia!r}")
        self.inertia = tuple(check_value(v, f"{where} 'inertia'") for v in inertia)
        self.position = vector(self.position, f"{where} 'position'", 3)
        quat = vector(self.orientation, f"{where} 'orientation'", 4)
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > 1e-3:
            raise ModelError(f"{where} 'orientation': a unit quaternion [w, x, y, z] is "
                             f"expected, got norm {norm:.6g}")
        self.orientation = quat / norm
        self.velocity = vector(self.velocity, f"{where} 'velocity'", 3)
        self.angular_velocity = vector(self.angular_velocity, f"{where} 'angular_velocity'", 3)
        self.reference_point = vector(self.reference_point, f"{where} 'reference_point'", 3)

    @property
    def is_centroidal(self) -> bool:
        """True when the reference point is the centre of mass."""
        return not np.any(self.reference_point)

    @property
    def initial_rotation(self) -> np.ndarray:
        """A(p) at the initial pose."""
        return rotation_matrix(self.orientation)

    def local(self, point_global) -> np.ndarray:
        """Body-frame coordinates (about G) of a global point at the initial pose."""
        return self.initial_rotation.T @ (np.asarray(point_global, float) - self.position)
