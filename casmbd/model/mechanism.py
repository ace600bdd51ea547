"""The mechanism builder: the user's symbolic description of bodies, joints, forces, drivers.

``Mechanism`` only *describes* a mechanism (like Pinocchio's ``Model`` before ``Data``): it holds
names, numbers and expressions and validates them.  :class:`casmbd.system.System` turns it into
CasADi equations, :mod:`casmbd.compiled` into compiled functions, and the analyses use those.

Example
-------
>>> m = Mechanism("pendulum", gravity=(0.0, -9.81))
>>> _ = m.add_body("rod", mass=1.0, inertia=1 / 12, position=(0.5, 0.0))
>>> _ = m.add_revolute("pivot", "ground", "rod", point=(0.0, 0.0))
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND, Body, Marker, vector2
from casmbd.model.drivers import Driver
from casmbd.model.forces import (
    Actuator,
    PointForce,
    RotationalSpringDamper,
    SpringDamper,
    Torque,
    UserForce,
)
from casmbd.model.joints import Distance, Fixed, Joint, Prismatic, Revolute, Rigid
from casmbd.model.values import Value, check_value, numeric


class Mechanism:
    """A planar mechanism: bodies in absolute coordinates, joints, drivers, forces, actuators.

    Parameters
    ----------
    name : str
        Name of the mechanism (used for compiled-code file names).
    gravity : sequence of 2 floats
        Gravitational acceleration vector, default zero.
    """

    dimension = 2

    def __init__(self, name: str = "mechanism", gravity: Sequence[float] = (0.0, 0.0)):
        self.name = str(name)
        self.gravity = vector2(gravity, "mechanism field 'gravity'")
        self.parameters: dict[str, float] = {}
        self.bodies: dict[str, Body] = {}
        self.markers: dict[str, Marker] = {}
        self.joints: dict[str, Joint] = {}
        self.drivers: dict[str, Driver] = {}
        self.forces: dict[str, object] = {}
        self.actuators: dict[str, Actuator] = {}

    # ------------------------------------------------------------------ helpers
    def _unique(self, table: dict, kind: str, name: str) -> str:
        if not isinstance(name, str) or not name:
            raise ModelError(f"{kind} name must be a non-empty string, got {name!r}")
        if kind == "body" and name == GROUND:
            raise ModelError(f"body name '{GROUND}' is reserved for the ground")
        if name in table:
            raise ModelError(f"duplicate {kind} name '{name}'")
        return name

    def _body(self, name: str, where: str) -> str:
        if not isinstance(name, str):
            raise ModelError(f"{where}: expected a body name (string), got {name!r}")
        if name != GROUND and name not in self.bodies:
            known = ", ".join([GROUND, *self.bodies]) or GROUND
            raise ModelError(f"{where}: unknown body '{name}' (known: {known})")
        return name

    def _joint(self, name: str, where: str, coordinate: bool = True) -> Joint:
        if not isinstance(name, str):
            raise ModelError(f"{where}: expected a joint name (string), got {name!r}")
        if name not in self.joints:
            known = ", ".join(self.joints) or "none"
            raise ModelError(f"{where}: unknown joint '{name}' (known: {known})")
        joint = self.joints[name]
        if coordinate and not joint.has_coordinate:
            raise ModelError(f"{where}: joint '{name}' ({type(joint).__name__.lower()}) has no "
                             "joint coordinate")
        return joint

    def _pair(self, body1: str, body2: str, where: str) -> None:
        self._body(body1, f"{where} field 'body1'")
        self._body(body2, f"{where} field 'body2'")
        if body1 == body2:
            raise ModelError(f"{where}: body1 and body2 are the same body '{body1}'")

    @staticmethod
    def _nonnegative(name: str, **values) -> None:
        for key, value in values.items():
            value = check_value(value, f"force '{name}' field '{key}'")
            if isinstance(value, float) and value < 0.0:
                raise ModelError(f"force '{name}' field '{key}': must be >= 0, got {value}")

    # ------------------------------------------------------------------ parameters
    def add_parameter(self, name: str, value: float) -> str:
        """Declare a named symbolic parameter p with a default value."""
        self._unique(self.parameters, "parameter", name)
        if not name.isidentifier() or name.startswith("_") or name in ("t", "pi", "e"):
            raise ModelError(f"parameter '{name}': not a valid parameter name")
        try:
            val = float(value)
        except (TypeError, ValueError, OverflowError):
            raise ModelError(f"parameter '{name}': expected a number, got {value!r}") from None
        if isinstance(value, bool) or not math.isfinite(val):
            raise ModelError(f"parameter '{name}': must be a finite number, got {value!r}")
        self.parameters[name] = val
        return name

    # ------------------------------------------------------------------ bodies
    def add_body(self, name: str, mass: Value, inertia: Value, position: Sequence[float],
                 angle: float = 0.0, velocity: Sequence[float] = (0.0, 0.0),
                 angular_velocity: float = 0.0,
                 reference_point: Sequence[float] = (0.0, 0.0)) -> Body:
        """Add a planar rigid body (centre of mass at ``position``); see :class:`Body`."""
        self._unique(self.bodies, "body", name)
        body = Body(name, mass, inertia, position, angle, velocity, angular_velocity,
                    reference_point)
        for key in ("mass", "inertia"):
            value = getattr(body, key)
            if isinstance(value, float) and value <= 0.0:
                raise ModelError(f"body '{name}' field '{key}': must be > 0, got {value}")
        self.bodies[name] = body
        return body

    def add_marker(self, name: str, body: str, point: Sequence[float]) -> Marker:
        """Add a named point on ``body`` at the global location ``point`` (initial pose)."""
        self._unique(self.markers, "marker", name)
        self._body(body, f"marker '{name}' field 'body'")
        marker = Marker(name, body, point)
        self.markers[name] = marker
        return marker

    # ------------------------------------------------------------------ joints
    def _add_joint(self, joint: Joint) -> Joint:
        self.joints[joint.name] = joint
        return joint

    def add_revolute(self, name: str, body1: str, body2: str, point: Sequence[float]) -> Joint:
        """Revolute (pin) joint at the global ``point``; coordinate θ2 − θ1."""
        self._unique(self.joints, "joint", name)
        self._pair(body1, body2, f"joint '{name}'")
        return self._add_joint(Revolute(name, body1, body2, point=point))

    def add_prismatic(self, name: str, body1: str, body2: str, point: Sequence[float],
                      axis: Sequence[float]) -> Joint:
        """Prismatic (translational) joint along the global ``axis`` through ``point``."""
        self._unique(self.joints, "joint", name)
        self._pair(body1, body2, f"joint '{name}'")
        return self._add_joint(Prismatic(name, body1, body2, point=point, axis=axis))

    def add_rigid(self, name: str, body1: str, body2: str,
                  point: Sequence[float] | None = None) -> Joint:
        """Weld body2 to body1 in their initial relative pose."""
        self._unique(self.joints, "joint", name)
        self._pair(body1, body2, f"joint '{name}'")
        return self._add_joint(Rigid(name, body1, body2, point=point))

    def add_fixed(self, name: str, body: str, point: Sequence[float] | None = None) -> Joint:
        """Fix ``body`` to the ground in its initial pose."""
        self._unique(self.joints, "joint", name)
        self._pair(GROUND, body, f"joint '{name}'")
        return self._add_joint(Fixed(name, GROUND, body, point=point))

    def add_distance(self, name: str, body1: str, body2: str, point1: Sequence[float],
                     point2: Sequence[float], length: float | None = None) -> Joint:
        """Massless link between two points; ``length`` defaults to the initial distance."""
        self._unique(self.joints, "joint", name)
        self._pair(body1, body2, f"joint '{name}'")
        return self._add_joint(Distance(name, body1, body2, point1=point1, point2=point2,
                                        length=length))

    # ------------------------------------------------------------------ drivers
    def add_driver(self, name: str, position: Value, joint: str | None = None,
                   body: str | None = None, coordinate: str | None = None) -> Driver:
        """Prescribe a joint coordinate or a body coordinate (x, y, angle) as f(t)."""
        self._unique(self.drivers, "driver", name)
        driver = Driver(name, position, joint=joint, body=body, coordinate=coordinate)
        if joint is not None:
            self._joint(joint, f"driver '{name}' field 'joint'")
        else:
            if body == GROUND:
                raise ModelError(f"driver '{name}' field 'body': the ground cannot be driven")
            self._body(body, f"driver '{name}' field 'body'")
        self.drivers[name] = driver
        return driver

    # ------------------------------------------------------------------ forces
    def _add_force(self, force):
        self.forces[force.name] = force
        return force

    def add_force(self, name: str, body: str, value: Sequence[Value],
                  point: Sequence[float] | None = None, frame: str = "global") -> PointForce:
        """Point force (2 components, ``frame`` 'global' or 'body') at ``point`` of ``body``
        (default: its centre of mass)."""
        self._unique(self.forces, "force", name)
        self._body(body, f"force '{name}' field 'body'")
        return self._add_force(PointForce(name, body, value, point=point, frame=frame))

    def add_torque(self, name: str, body: str, value: Value) -> Torque:
        """Torque on ``body``."""
        self._unique(self.forces, "force", name)
        self._body(body, f"force '{name}' field 'body'")
        return self._add_force(Torque(name, body, value))

    def add_spring_damper(self, name: str, body1: str, body2: str, point1: Sequence[float],
                          point2: Sequence[float], stiffness: Value = 0.0, damping: Value = 0.0,
                          free_length: Value | None = None,
                          actuator: Value = 0.0) -> SpringDamper:
        """Translational spring-damper-actuator between two points (tension positive)."""
        self._unique(self.forces, "force", name)
        self._pair(body1, body2, f"force '{name}'")
        self._nonnegative(name, stiffness=stiffness, damping=damping)
        return self._add_force(SpringDamper(name, body1, body2, point1, point2, stiffness,
                                            damping, free_length, actuator))

    def add_rotational_spring_damper(self, name: str, joint: str, stiffness: Value = 0.0,
                                     damping: Value = 0.0, free_angle: Value = 0.0,
                                     actuator: Value = 0.0) -> RotationalSpringDamper:
        """Rotational spring-damper-actuator on the coordinate of a revolute joint."""
        self._unique(self.forces, "force", name)
        self._nonnegative(name, stiffness=stiffness, damping=damping)
        joint_obj = self._joint(joint, f"force '{name}' field 'joint'")
        if not isinstance(joint_obj, Revolute):
            raise ModelError(f"force '{name}' field 'joint': joint '{joint}' is not revolute")
        return self._add_force(RotationalSpringDamper(name, joint, stiffness, damping,
                                                      free_angle, actuator))

    def add_user_force(self, name: str, function: Callable, body: str | None = None,
                       point: Sequence[float] | None = None) -> UserForce:
        """A force written as CasADi expressions of (q, v, t, u, p); see :class:`UserForce`."""
        self._unique(self.forces, "force", name)
        if body is not None:
            self._body(body, f"force '{name}' field 'body'")
        return self._add_force(UserForce(name, function, body=body, point=point))

    def add_actuator(self, name: str, joint: str) -> Actuator:
        """A generalized-force input u along the coordinate of ``joint``."""
        self._unique(self.actuators, "actuator", name)
        self._joint(joint, f"actuator '{name}' field 'joint'")
        actuator = Actuator(name, joint)
        self.actuators[name] = actuator
        return actuator

    # ------------------------------------------------------------------ checks
    def validate(self) -> None:
        """Check what can only be checked once everything is declared (expression values)."""
        if not self.bodies:
            raise ModelError(f"mechanism '{self.name}' has no moving body")
        for body in self.bodies.values():
            for key in ("mass", "inertia"):
                where = f"body '{body.name}' field '{key}'"
                value = numeric(getattr(body, key), self.parameters, where)
                if value <= 0.0:
                    raise ModelError(f"{where}: must be > 0, got {value}")
        for force in self.forces.values():
            for key in ("stiffness", "damping"):
                if hasattr(force, key):
                    check_value(getattr(force, key), f"force '{force.name}' field '{key}'")

    def initial_coordinates(self) -> np.ndarray:
        """Stacked q from the bodies' initial poses (approximate, before assembly)."""
        return np.concatenate([b.initial_coordinates() for b in self.bodies.values()])

    def initial_velocities(self) -> np.ndarray:
        """Stacked q̇ from the bodies' initial velocities."""
        return np.concatenate([b.initial_velocities() for b in self.bodies.values()])

    def __repr__(self) -> str:
        return (f"Mechanism({self.name!r}: {len(self.bodies)} bodies, {len(self.joints)} joints, "
                f"{len(self.drivers)} drivers, {len(self.forces)} forces, "
                f"{len(self.actuators)} actuators)")
