"""Modelling layer: the user's description of a mechanism (no analysis imports here)."""

from casmbd.model.bodies import GROUND, Body, Marker, SpatialBody
from casmbd.model.drivers import Driver
from casmbd.model.expression_force import ExpressionForce
from casmbd.model.forces import (
    Actuator,
    ForceElement,
    PointForce,
    RotationalSpringDamper,
    SpringDamper,
    Torque,
    UserForce,
)
from casmbd.model.gear import Gear
from casmbd.model.joint_friction import JointFriction
from casmbd.model.joints import Distance, Fixed, Joint, Prismatic, Revolute, Rigid
from casmbd.model.mechanism import Mechanism
from casmbd.model.planar_joint import Planar
from casmbd.model.registry import (
    BODY_KINDS,
    FORCE_KINDS,
    JOINT_KINDS,
    register_body,
    register_force,
    register_joint,
)
from casmbd.model.spatial_joints import (
    Cylindrical,
    SpatialFixed,
    SpatialPrismatic,
    SpatialRevolute,
    SpatialRigid,
    Spherical,
    Universal,
)

__all__ = ["BODY_KINDS", "FORCE_KINDS", "GROUND", "JOINT_KINDS", "Actuator", "Body",
           "Cylindrical", "Distance", "Driver", "ExpressionForce",
           "Fixed", "ForceElement", "Gear", "Joint",
           "JointFriction", "Marker", "Mechanism", "Planar", "PointForce", "Prismatic", "Revolute",
           "Rigid",
           "RotationalSpringDamper", "SpatialBody", "SpatialFixed", "SpatialPrismatic",
           "SpatialRevolute", "SpatialRigid", "Spherical", "SpringDamper", "Torque", "Universal",
           "UserForce",
           "register_body", "register_force", "register_joint"]
