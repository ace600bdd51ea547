"""Modelling layer: the user's description of a mechanism (no analysis imports here).

Every element kind registers in :mod:`casmbd.model.registry` in its own module; this package
imports each of those modules (joints, spatial joints, planar joint, gear; forces, expression
force, joint friction, contacts; rigid and flexible bodies), so ``JOINT_KINDS``,
``FORCE_KINDS`` and ``BODY_KINDS`` are complete whenever any ``casmbd.model`` module is
imported (``tests/architecture/test_layers.py`` checks it in a fresh process).
"""

from casmbd.model.bodies import GROUND, Body, Marker, SpatialBody
from casmbd.model.contacts import CompliantContact, ContactSlide
from casmbd.model.drivers import Driver
from casmbd.model.expression_force import ExpressionForce
from casmbd.model.flexible_bodies import PlanarFlexibleBody, SpatialFlexibleBody
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
from casmbd.model.rolling import KnifeEdge, PlanarRollingDisc, RollingSphere
from casmbd.model.rolling_disc import RollingDisc
from casmbd.model.spatial_joints import (
    Cylindrical,
    SpatialFixed,
    SpatialPrismatic,
    SpatialRevolute,
    SpatialRigid,
    Spherical,
    Universal,
)
from casmbd.model.velocity_constraint import VelocityConstraint

__all__ = ["BODY_KINDS", "FORCE_KINDS", "GROUND", "JOINT_KINDS", "Actuator", "Body",
           "CompliantContact", "ContactSlide", "Cylindrical", "Distance", "Driver",
           "ExpressionForce", "Fixed", "ForceElement", "Gear", "Joint", "JointFriction",
           "KnifeEdge", "Marker", "Mechanism", "Planar", "PlanarFlexibleBody", "PlanarRollingDisc",
           "PointForce", "Prismatic", "Revolute", "Rigid", "RollingDisc", "RollingSphere",
           "RotationalSpringDamper", "SpatialBody", "SpatialFixed", "SpatialFlexibleBody",
           "SpatialPrismatic", "SpatialRevolute", "SpatialRigid", "Spherical", "SpringDamper",
           "Torque", "Universal", "UserForce", "VelocityConstraint", "register_body",
           "register_force", "register_joint"]
