"""Force elements and actuators; each gives its generalized force by virtual work.

For a force F applied at a body point P and a torque T on a body, δW = Fᵀ δr_P + T δθ, so the
generalized force is Q = (∂r_P/∂q)ᵀ F + (∂θ/∂q)ᵀ T (seed 000, "Generalized forces", eqs.
6.40–6.48).  A force element acting along a scalar measure s(q) (the length of a spring, a joint
coordinate) with magnitude f resisting an increase of s gives Q = −f (∂s/∂q)ᵀ.  The Jacobians
are taken by CasADi's algorithmic differentiation, never by hand.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import vector
from casmbd.model.values import Value, check_value

FORCE_TYPES = ("force", "torque", "spring_damper", "rotational_spring_damper", "user")
FRAMES = ("global", "body")


def _point(value, where: str) -> np.ndarray:
    """A point of 2 (plane) or 3 (space) numbers; the mechanism checks which."""
    size = len(value) if hasattr(value, "__len__") and len(value) in (2, 3) else 2
    return vector(value, where, size)


@dataclass
class PointForce:
    """A force (2 or 3 values, global or body frame) applied at a body point."""

    name: str
    body: str
    value: tuple[Value, Value]
    point: np.ndarray | None = None
    frame: str = "global"

    def __post_init__(self):
        where = f"force '{self.name}'"
        if not isinstance(self.value, (list, tuple)) or len(self.value) not in (2, 3):
            raise ModelError(f"{where} field 'value': expected 2 (plane) or 3 (space) "
                             f"components, got {self.value!r}")
        self.value = tuple(check_value(v, f"{where} field 'value'") for v in self.value)
        if self.point is not None:
            self.point = _point(self.point, f"{where} field 'point'")
        if self.frame not in FRAMES:
            raise ModelError(f"{where} field 'frame': expected 'global' or 'body', "
                             f"got {self.frame!r}")


@dataclass
class Torque:
    """A torque on a body: one value in the plane (counter-clockwise positive), three in space
    (global or body frame).  Its generalized force is (∂ω/∂q̇)ᵀ T (virtual rotation)."""

    name: str
    body: str
    value: Value | tuple
    frame: str = "global"

    def __post_init__(self):
        where = f"force '{self.name}' field"
        values = self.value if isinstance(self.value, (list, tuple)) else (self.value,)
        if len(values) not in (1, 3):
            raise ModelError(f"{where} 'value': expected 1 (plane) or 3 (space) components, "
                             f"got {self.value!r}")
        self.value = tuple(check_value(v, f"{where} 'value'") for v in values)
        if self.frame not in FRAMES:
            raise ModelError(f"{where} 'frame': expected 'global' or 'body', got {self.frame!r}")


@dataclass
class SpringDamper:
    """Translational spring-damper-actuator between point1 (body1) and point2 (body2).

    Tension f = k (l − l0) + c l̇ + a(t) pulls the points together; potential ½ k (l − l0)²
    (seed 000 / 001, "Spring-damper-actuator elements").
    """

    name: str
    body1: str
    body2: str
    point1: np.ndarray
    point2: np.ndarray
    stiffness: Value = 0.0
    damping: Value = 0.0
    free_length: Value | None = None
    actuator: Value = 0.0

    def __post_init__(self):
        where = f"force '{self.name}'"
        self.point1 = _point(self.point1, f"{where} field 'point1'")
        self.point2 = _point(self.point2, f"{where} field 'point2'")
        if self.free_length is None:
            self.free_length = float(np.linalg.norm(self.point2 - self.point1))
        if np.allclose(self.point1, self.point2):
            raise ModelError(f"{where} fields 'point1', 'point2': the points coincide, so the "
                             "line of action is undefined (use a rotational spring or offset "
                             "the points)")
        for key in ("stiffness", "damping", "free_length", "actuator"):
            setattr(self, key, check_value(getattr(self, key), f"{where} field '{key}'"))


@dataclass
class RotationalSpringDamper:
    """Rotational spring-damper-actuator at a joint with an angle coordinate φ (revolute,
    cylindrical).

    Moment T = k (φ − φ0) + c φ̇ + a(t) resisting an increase of φ; potential ½ k (φ − φ0)².
    ``free_angle`` defaults to 0.
    """

    name: str
    joint: str
    stiffness: Value = 0.0
    damping: Value = 0.0
    free_angle: Value = 0.0
    actuator: Value = 0.0
    coordinate: str | None = None

    def __post_init__(self):
        where = f"force '{self.name}'"
        for key in ("stiffness", "damping", "free_angle", "actuator"):
            setattr(self, key, check_value(getattr(self, key), f"{where} field '{key}'"))


@dataclass
class UserForce:
    """A force given as CasADi expressions of the state.

    ``function(ctx)`` receives the assembly context (CasADi symbols ``ctx.q``, ``ctx.v``,
    ``ctx.t``; dicts by name ``ctx.u`` and ``ctx.p``; and helpers ``ctx.position(body, point)``,
    ``ctx.velocity(body, point)``, ``ctx.angle(body)``, ``ctx.joint_coordinate(name)``).
    With ``body`` given it returns the force (2-vector, global) at ``point`` — or a pair
    (force, torque); without ``body`` it returns a generalized force vector of length n_q.
    """

    name: str
    function: Callable
    body: str | None = None
    point: np.ndarray | None = None

    def __post_init__(self):
        if not callable(self.function):
            raise ModelError(f"force '{self.name}' field 'function': expected a callable")
        if self.point is not None:
            self.point = _point(self.point, f"force '{self.name}' field 'point'")


@dataclass
class Actuator:
    """A generalized force input u along a joint coordinate (for inverse dynamics and control)."""

    name: str
    joint: str
    bounds: tuple[float, float] = field(default_factory=lambda: (-np.inf, np.inf))
    coordinate: str | None = None
