"""Canonical small scenes of the composition matrix: one per element variant.

Every registered element kind (joints, force elements, bodies) and every model variant of the
unilateral elements and of joint friction has a builder here, keyed by its variant name; a
builder returns a planar or spatial Mechanism with the element under test on a pendulum
(``link`` on the revolute ``pin``, 1 m, 1 kg) or on its own small mechanism, and
``driven=True`` adds a driver for every degree of freedom (for kinematics and inverse
dynamics).  ``tests/architecture/test_composition.py`` fails for a registered kind with no builder.
"""

from __future__ import annotations

import casadi as ca

import casmbd

G2, G3 = (0.0, -9.81), (0.0, -9.81, 0.0)


def _pendulum(dim: int, name: str, driven: bool = False, coordinates: str = "auto"):
    m = casmbd.Mechanism(name, gravity=G2 if dim == 2 else G3, coordinates=coordinates)
    if dim == 2:
        m.add_body("link", mass=1.0, inertia=1.0 / 12, position=(0.5, 0.0))
        m.add_revolute("pin", "ground", "link", point=(0.0, 0.0))
    else:
        m.add_body("link", mass=1.0, inertia=[0.01, 1.0 / 12, 1.0 / 12],
                   position=(0.5, 0.0, 0.0))
        m.add_revolute("pin", "ground", "link", point=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0))
    if driven:
        m.add_driver("swing", joint="pin", position="0.3*sin(2*t)")
    return m


def _with(build):
    def make(dim, driven=False, coordinates="auto"):
        m = _pendulum(dim, build.__name__, driven, coordinates)
        build(m, dim)
        return m
    make.__name__ = build.__name__
    return make


# --------------------------------------------------------------------- joints
def revolute(dim, driven=False, coordinates="auto"):
    return _pendulum(dim, "revolute", driven, coordinates)


def prismatic(dim, driven=False, coordinates="auto"):
    m = casmbd.Mechanism("prismatic", gravity=G2 if dim == 2 else G3, coordinates=coordinates)
    z = (0.0,) * (dim - 2)
    m.add_body("slider", mass=1.0, inertia=0.1 if dim == 2 else [0.1, 0.1, 0.1],
               position=(0.0, 0.0, *z))
    m.add_prismatic("slide", "ground", "slider", point=(0.0, 0.0, *z),
                    axis=(0.6, -0.8, *z))
    if driven:
        m.add_driver("push", joint="slide", position="0.1*t**2")
    return m


def _second_link(m, dim, joint):
    """A second body on ``link``, joined by ``joint(m, point)``."""
    z = (0.0,) * (dim - 2)
    m.add_body("tip", mass=0.5, inertia=0.02 if dim == 2 else [0.02, 0.02, 0.02],
               position=(1.0, 0.0, *z))
    joint(m, (1.0, 0.0, *z))


@_with
def rigid(m, dim):
    _second_link(m, dim, lambda m, p: m.add_rigid("weld", "link", "tip"))


@_with
def fixed(m, dim):
    z = (0.0,) * (dim - 2)
    m.add_body("block", mass=0.5, inertia=0.02 if dim == 2 else [0.02, 0.02, 0.02],
               position=(0.0, 1.0, *z))
    m.add_fixed("anchor", "block", point=(0.0, 1.0, *z))


@_with
def distance(m, dim):
    z = (0.0,) * (dim - 2)
    m.add_body("bob", mass=0.5, inertia=0.02 if dim == 2 else [0.02, 0.02, 0.02],
               position=(1.0, -0.5, *z))
    m.add_revolute("hinge", "link", "bob", point=(1.0, 0.0, *z),
                   **({} if dim == 2 else {"axis": (0.0, 0.0, 1.0)}))
    m.add_distance("rope", "ground", "bob", point1=(1.5, 0.0, *z), point2=(1.0, -0.5, *z))


@_with
def gear(m, dim):
    z = (0.0,) * (dim - 2)
    m.add_body("wheel", mass=1.0, inertia=0.05 if dim == 2 else [0.05, 0.05, 0.05],
               position=(0.0, 1.0, *z))
    m.add_revolute("axle", "ground", "wheel", point=(0.0, 1.0, *z),
                   **({} if dim == 2 else {"axis": (0.0, 0.0, 1.0)}))
    m.add_gear("mesh", "pin", "axle", ratio=-2.0)


def _spatial_pendulum(name, joint, driven, coordinates):
    m = casmbd.Mechanism(name, gravity=G3, coordinates=coordinates)
    m.add_body("link", mass=1.0, inertia=[0.01, 1.0 / 12, 1.0 / 12], position=(0.5, 0.0, 0.0))
    joint(m)
    if driven:  # every degree of freedom held by a body-coordinate driver is not general:
        raise NotImplementedError(name)
    return m


def spherical(dim, driven=False, coordinates="auto"):
    return _spatial_pendulum("spherical", lambda m: m.add_spherical(
        "ball", "ground", "link", point=(0.0, 0.0, 0.0)), driven, coordinates)


def universal(dim, driven=False, coordinates="auto"):
    return _spatial_pendulum("universal", lambda m: m.add_universal(
        "cross", "ground", "link", point=(0.0, 0.0, 0.0), axis1=(0.0, 0.0, 1.0),
        axis2=(0.0, 1.0, 0.0)), driven, coordinates)


def cylindrical(dim, driven=False, coordinates="auto"):
    return _spatial_pendulum("cylindrical", lambda m: m.add_cylindrical(
        "sleeve", "ground", "link", point=(0.0, 0.0, 0.0), axis=(0.6, 0.8, 0.0)),
        driven, coordinates)


def inline(dim, driven=False, coordinates="auto"):
    return _spatial_pendulum("inline", lambda m: m.add_inline(
        "rail", "ground", "link", point=(0.0, 0.0, 0.0), axis=(0.6, 0.8, 0.0)),
        driven, coordinates)


def planar(dim, driven=False, coordinates="auto"):
    return _spatial_pendulum("planar", lambda m: m.add(
        "planar", "plane", "ground", "link", point=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0)),
        driven, coordinates)


# --------------------------------------------------------------------- forces
@_with
def force(m, dim):
    m.add_force("push", "link", value=(1.0, 0.0) + (0.0,) * (dim - 2))


@_with
def torque(m, dim):
    m.add_torque("twist", "link", value=0.5 if dim == 2 else (0.0, 0.0, 0.5))


@_with
def spring_damper(m, dim):
    z = (0.0,) * (dim - 2)
    m.add_spring_damper("spring", "ground", "link", (1.0, 0.5, *z), (1.0, 0.0, *z),
                        stiffness=20.0, damping=0.5)


@_with
def rotational_spring_damper(m, dim):
    m.add_rotational_spring_damper("coil", "pin", stiffness=5.0, damping=0.2)


@_with
def user(m, dim):
    m.add_user_force("wind", lambda ctx: ca.vertcat(0.5 * ca.sin(ctx.t), *([0.0] * (dim - 1))),
                     body="link")


@_with
def expression(m, dim):
    m.add("expression", "law", joint="pin", value='-2*angle("pin")')


@_with
def joint_friction(m, dim):
    m.add("joint_friction", "pin.friction", joint="pin", damping=0.1, friction=0.05)


@_with
def joint_friction_reaction(m, dim):
    m.add("joint_friction", "pin.friction", joint="pin", friction=0.05, mu=0.1, radius=0.02)


@_with
def joint_friction_stick_slip(m, dim):
    m.add("joint_friction", "pin.friction", joint="pin", friction=0.05, stick_slip=True)


@_with
def stop_impact(m, dim):
    m.add_joint_limit("pin", lower=-1.0, upper=1.0, restitution=0.5)


@_with
def stop_compliant(m, dim):
    m.add_joint_limit("pin", lower=-1.0, upper=1.0, model="compliant", stiffness=1e4,
                      damping=10.0)


def _ball(dim, name, coordinates, **contact):
    m = casmbd.Mechanism(name, gravity=G2 if dim == 2 else (0.0, 0.0, -9.81),
                         coordinates=coordinates)
    z = (0.0,) * (dim - 2)
    m.add_body("ball", mass=1.0, inertia=0.004 if dim == 2 else [0.004] * 3,
               position=(0.0, 0.3) if dim == 2 else (0.0, 0.0, 0.3))
    normal = (0.0, 1.0) if dim == 2 else (0.0, 0.0, 1.0)
    m.add_contact("floor", "ball", point=m.bodies["ball"].position if dim == 2 else
                  (0.0, 0.0, 0.3), radius=0.1, origin=(0.0, 0.0, *z), normal=normal,
                  **contact)
    return m


def contact_impact(dim, driven=False, coordinates="auto"):
    return _ball(dim, "contact_impact", coordinates, restitution=0.5)


def contact_friction(dim, driven=False, coordinates="auto"):
    return _ball(dim, "contact_friction", coordinates, restitution=0.0, friction=0.5)


def contact_compliant(dim, driven=False, coordinates="auto"):
    return _ball(dim, "contact_compliant", coordinates, model="compliant", stiffness=1e5,
                 damping=50.0)


# --------------------------------------------------------------------- bodies
def flexible(dim, driven=False, coordinates="auto"):
    z = [0.0] * (dim - 2)
    section = ("EI = 50.0" if dim == 2 else
               "EIy = 50.0\nEIz = 50.0\nGJ = 40.0\nrhoIp = 1e-3")
    text = f"""
[scene]
name = "flexible_{dim}"
dimension = {dim}
gravity = {list(G2 if dim == 2 else G3)}
{'coordinates = "' + coordinates + '"' if coordinates != "auto" else ""}

[[bodies]]
name = "beam"
type = "flexible"
position = {[0.0, 0.0, *z]}
modes = 2
reduction = "craig_bampton"
interfaces = ["root"]
[bodies.beam]
length = 1.0
elements = 4
EA = 1e6
{section}
rhoA = 1.0
nodes = {{ root = 0.0, tip = 1.0 }}

[[joints]]
name = "pin"
type = "revolute"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = {[0.0, 0.0, *z]}
{'axis = [0.0, 0.0, 1.0]' if dim == 3 else ''}
"""
    return casmbd.loads_scene(text)


def driver(dim, driven=True, coordinates="auto"):
    return _pendulum(dim, "driver", True, coordinates)


@_with
def actuator(m, dim):
    m.add_actuator("motor", "pin")


# --------------------------------------------------------------------- rolling (issue 37)
def rolling_disc(dim, driven=False, coordinates="auto"):
    """A disc (R = 0.1) rolling on the ground line, held by a horizontal spring (in space: a
    thin wheel rolling upright on the floor, :func:`_rolling_wheel`)."""
    if dim == 3:
        return _rolling_wheel(driven, coordinates)
    m = casmbd.Mechanism("rolling_disc", gravity=G2, coordinates=coordinates)
    m.add_body("disc", mass=1.0, inertia=0.005, position=(0.0, 0.1), velocity=(0.3, 0.0),
               angular_velocity=-3.0)
    m.add("rolling_disc", "roll", "ground", "disc", point=(0.0, 0.1), radius=0.1)
    m.add_spring_damper("spring", "ground", "disc", (-0.5, 0.1), (0.0, 0.1), stiffness=20.0,
                        free_length=0.4)
    if driven:
        m.add_driver("push", joint="roll", coordinate="translation", position="0.1*sin(2*t)")
    return m


def _rolling_wheel(driven, coordinates):
    """A thin wheel (R = 0.1, axle y) rolling upright along x on the floor, held by a
    horizontal spring at its centre and kept upright by a short tether from a point 0.1 above
    its top (8 N at rest, less than its weight: its stable equilibrium is upright); driven: its
    orientation prescribed (roll-pitch-yaw: the spin as pitch, a slow yaw), the rolling then
    carrying the centre."""
    m = casmbd.Mechanism("rolling_disc", gravity=(0.0, 0.0, -9.81), coordinates=coordinates)
    m.add_body("wheel", mass=1.0, inertia=[0.0025, 0.005, 0.0025], position=(0.0, 0.0, 0.1),
               velocity=(0.3, 0.0, 0.0), angular_velocity=(0.0, 3.0, 0.0))
    m.add("rolling_disc", "roll", "ground", "wheel", point=(0.0, 0.0, 0.1), radius=0.1,
          axis=(0.0, 1.0, 0.0), normal=(0.0, 0.0, 1.0))
    m.add_spring_damper("spring", "ground", "wheel", (-0.5, 0.0, 0.1), (0.0, 0.0, 0.1),
                        stiffness=20.0, free_length=0.4)
    m.add_spring_damper("tether", "ground", "wheel", (0.0, 0.0, 0.3), (0.0, 0.0, 0.2),
                        stiffness=80.0, free_length=0.0)
    if driven:
        m.add_driver("turn", body="wheel", coordinate="orientation",
                     rpy=["0", "3*t", "0.2*sin(2*t)"])
    return m


def _sleigh(dim, name, coordinates, blade):
    """A sleigh on the horizontal plane (seen from above in the plane, held on the floor by a
    planar joint in space), pulled by two springs, its rear point on a blade ``blade(m)``."""
    z = (0.0,) * (dim - 2)
    m = casmbd.Mechanism(name, gravity=(0.0, 0.0) if dim == 2 else (0.0, 0.0, -9.81),
                         coordinates=coordinates)
    m.add_body("sleigh", mass=1.0, inertia=0.02 if dim == 2 else [0.01, 0.02, 0.02],
               position=(0.0, 0.0, *z), velocity=(0.3, -0.04, *z),
               angular_velocity=0.2 if dim == 2 else (0.0, 0.0, 0.2))
    if dim == 3:
        m.add("planar", "floor", "ground", "sleigh", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    m.add_spring_damper("front", "ground", "sleigh", (0.5, 0.5, *z), (0.2, 0.0, *z),
                        stiffness=10.0, free_length=0.2)
    m.add_spring_damper("rear", "ground", "sleigh", (-0.5, 0.5, *z), (-0.2, 0.0, *z),
                        stiffness=10.0, free_length=0.2)
    blade(m, z)
    return m


def knife_edge(dim, driven=False, coordinates="auto"):
    return _sleigh(dim, "knife_edge", coordinates, lambda m, z: m.add(
        "knife_edge", "blade", "ground", "sleigh", point=(-0.2, 0.0, *z), axis=(1.0, 0.0, *z)))


def velocity(dim, driven=False, coordinates="auto"):
    """The sleigh's blade as a generic velocity row: the rear point's velocity across the
    line from the rear to the front point (unnormalised)."""
    def blade(m, z):
        m.add_marker("rear_point", "sleigh", (-0.2, 0.0, *z))
        m.add_marker("front_point", "sleigh", (0.2, 0.0, *z))
        m.add("velocity", "blade", "ground", "sleigh", rows=[
            "-(y('front_point') - y('rear_point'))*vx('rear_point')"
            " + (x('front_point') - x('rear_point'))*vy('rear_point')"], labels=["lateral"])
    return _sleigh(dim, "velocity", coordinates, blade)


def rolling_sphere(dim, driven=False, coordinates="auto"):
    """A ball (R = 0.1) rolling on the floor, held by two horizontal springs."""
    m = casmbd.Mechanism("rolling_sphere", gravity=(0.0, 0.0, -9.81), coordinates=coordinates)
    m.add_body("ball", mass=1.0, inertia=[0.004] * 3, position=(0.0, 0.0, 0.1),
               velocity=(0.2, 0.1, 0.0), angular_velocity=(-1.0, 2.0, 0.5))
    m.add("rolling_sphere", "roll", "ground", "ball", point=(0.0, 0.0, 0.1), radius=0.1)
    m.add_spring_damper("x_spring", "ground", "ball", (-0.5, 0.0, 0.1), (0.0, 0.0, 0.1),
                        stiffness=20.0, free_length=0.4)
    m.add_spring_damper("y_spring", "ground", "ball", (0.0, -0.5, 0.1), (0.0, 0.0, 0.1),
                        stiffness=20.0, free_length=0.4)
    return m


#: variant -> (builder, dimensions, has a driven form)
VARIANTS = {
    "revolute": (revolute, (2, 3), True), "prismatic": (prismatic, (2, 3), True),
    "rigid": (rigid, (2, 3), True), "fixed": (fixed, (2, 3), True),
    "distance": (distance, (2, 3), False), "gear": (gear, (2, 3), False),
    "spherical": (spherical, (3,), False), "universal": (universal, (3,), False),
    "cylindrical": (cylindrical, (3,), False), "inline": (inline, (3,), False),
    "planar": (planar, (3,), False),
    "force": (force, (2, 3), True), "torque": (torque, (2, 3), True),
    "spring_damper": (spring_damper, (2, 3), True),
    "rotational_spring_damper": (rotational_spring_damper, (2, 3), True),
    "user": (user, (2, 3), True), "expression": (expression, (2, 3), True),
    "joint_friction": (joint_friction, (2, 3), True),
    "joint_friction_reaction": (joint_friction_reaction, (2,), True),
    "joint_friction_stick_slip": (joint_friction_stick_slip, (2, 3), True),
    "stop_impact": (stop_impact, (2, 3), True), "stop_compliant": (stop_compliant, (2, 3), True),
    "contact_impact": (contact_impact, (2, 3), False),
    "contact_friction": (contact_friction, (2, 3), False),
    "contact_compliant": (contact_compliant, (2, 3), False),
    "flexible": (flexible, (2, 3), False), "rigid_body": (revolute, (2, 3), True),
    "driver": (driver, (2, 3), True), "actuator": (actuator, (2, 3), True),
    "rolling_disc": (rolling_disc, (2, 3), True), "knife_edge": (knife_edge, (2, 3), False),
    "rolling_sphere": (rolling_sphere, (3,), False), "velocity": (velocity, (2, 3), False),
}

#: registered kind -> the variants that exercise it (a kind missing here fails the matrix)
KIND_VARIANTS = {
    **{k: (k,) for k in ("revolute", "prismatic", "rigid", "fixed", "distance", "gear",
                         "spherical", "universal", "cylindrical", "inline", "planar",
                         "force", "torque", "spring_damper", "rotational_spring_damper",
                         "user", "expression", "flexible", "rolling_disc", "knife_edge",
                         "rolling_sphere", "velocity")},
    "joint_friction": ("joint_friction", "joint_friction_reaction",
                       "joint_friction_stick_slip"),
    "compliant_contact": ("stop_compliant", "contact_compliant"),
    "contact_slide": ("contact_friction",),
    "rigid_body": ("rigid_body",),
}
