"""The standard dynamic parameters π of a mechanism: inertial parameters and joint friction.

The equations of motion are linear in each rigid body's ten *standard inertial parameters*
about a body-fixed origin O (Atkeson, An & Hollerbach, "Estimation of inertial parameters of
manipulator loads and links", Int. J. Robotics Research 5(3), 1986; Khalil & Dombre,
*Modeling, Identification and Control of Robots*, 2002, §9.3),

    π_b = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz),

with c = r_G − r_O the centre of mass relative to O and I_O = I_G + m (|c|² 1 − c cᵀ) the
inertia tensor about O (parallel-axis theorem), both in the body axes.  A planar body has four,
(m, m c_x, m c_y, I_zz) — its motion in the plane involves no other combination.  The joint
friction law of casmbd (:mod:`casmbd.model.joint_friction`), Q_j = −F_v q̇_j − F_c
tanh(q̇_j / v_s), is linear in the viscous coefficient F_v and the Coulomb level F_c at a fixed
regularisation velocity v_s, which adds up to two parameters per joint coordinate.

Names: ``"<body>.m"``, ``"<body>.mcx"``, ``"<body>.mcy"``, ``"<body>.mcz"``, ``"<body>.Ixx"``,
``"<body>.Ixy"``, ``"<body>.Ixz"``, ``"<body>.Iyy"``, ``"<body>.Iyz"``, ``"<body>.Izz"`` (planar:
``m``, ``mcx``, ``mcy``, ``Izz``), ``"<joint>.viscous"`` and ``"<joint>.coulomb"`` (a joint with
several coordinates: ``"<joint>.<coordinate>.viscous"``).

The body frame (where O is and which axes the components refer to):

* ``frame="body"`` (default): O is the body's *reference point* — the point whose position
  the body's coordinates are (its ``reference_point``, the centre of mass unless one is
  given, so c = 0 at the nominal values but m c still a parameter) — and the axes are the
  body axes (``orientation``);
* ``frame="joint"``: O is the point of the joint that carries the body (the one joint whose
  ``body2`` it is, its ``point`` at the design pose), axes the body axes.  For a robot read by
  :func:`casmbd.io.urdf.load_urdf` the body axes are the link frame's, and the joint's point is
  the link frame's origin: π is then the URDF link's inertial parameters about its own frame
  — Pinocchio's ``dynamicParameters`` (in another order: Pinocchio lists I_xx, I_xy, I_yy,
  I_xz, I_yz, I_zz).  A free body (no joint carries it: a floating base) takes its
  reference point, which for a URDF floating base is the root link frame's origin — the
  free-flyer joint frame of Pinocchio.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND
from casmbd.model.joint_friction import REGULARIZATION, JointFriction
from casmbd.model.values import numeric

#: the inertial parameter names of one spatial body (the order of π_b)
SPATIAL_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
#: those of a planar body
PLANAR_NAMES = ("m", "mcx", "mcy", "Izz")
#: the friction laws, in the order of their parameters per joint coordinate
FRICTION_LAWS = ("viscous", "coulomb")
#: where the body-fixed origin O of the inertial parameters is
FRAMES = ("body", "joint")


@dataclass(frozen=True)
class FrictionCoordinate:
    """One joint coordinate with friction parameters: the joint, its coordinate, the laws
    (a subset of :data:`FRICTION_LAWS`) and the Coulomb regularisation velocity v_s."""

    joint: str
    coordinate: str
    prefix: str
    regularization: float


@dataclass(frozen=True)
class StandardParameters:
    """The standard parameter vector π of a mechanism (module docstring).

    Attributes
    ----------
    names : list of str
        One name per entry of π.
    values : ndarray
        The mechanism's own values (nominal π).
    bodies : list of str
        The moving bodies, in the order of their blocks in π.
    origins : dict of str to ndarray
        Body-axes coordinates of each body's origin O relative to its centre of mass at the
        nominal values (c = −origin).
    frame : str
        ``"body"`` or ``"joint"`` (module docstring).
    friction : tuple of str
        The friction laws included (``"viscous"``, ``"coulomb"``).
    friction_coordinates : list of FrictionCoordinate
        The joint coordinates with friction parameters, in the order of their blocks.
    dimension : int
        2 (4 inertial parameters per body) or 3 (10).
    """

    names: list[str]
    values: np.ndarray
    bodies: list[str]
    origins: dict[str, np.ndarray]
    frame: str
    friction: tuple[str, ...]
    friction_coordinates: list[FrictionCoordinate] = field(default_factory=list)
    dimension: int = 3

    def __len__(self) -> int:
        return len(self.names)

    @property
    def per_body(self) -> int:
        """Inertial parameters per body: 4 in the plane, 10 in space."""
        return 4 if self.dimension == 2 else 10

    def index(self, name: str) -> int:
        """Position of the parameter ``name`` in π (a :class:`ModelError` naming the known
        ones when unknown)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ModelError(f"unknown standard parameter '{name}' (known: "
                             f"{', '.join(self.names)})") from None

    def body_block(self, body: str) -> slice:
        """The slice of π holding ``body``'s inertial parameters."""
        if body not in self.bodies:
            raise ModelError(f"unknown body '{body}' (bodies: {', '.join(self.bodies)})")
        k = self.bodies.index(body) * self.per_body
        return slice(k, k + self.per_body)

    def as_dict(self, values: Sequence[float] | None = None) -> dict[str, float]:
        """Name → value of ``values`` (default the nominal π)."""
        vals = self.values if values is None else np.asarray(values, float)
        return {n: float(x) for n, x in zip(self.names, vals, strict=True)}


def inertial_parameters(mass: float, com, inertia_com, dimension: int) -> np.ndarray:
    """π_b from the mass, the centre of mass c relative to O and the inertia about the centre
    of mass (all in the body axes): (m, m c, I_O) with I_O = I_G + m (|c|² 1 − c cᵀ).

    ``inertia_com``: a 3 × 3 tensor in space, the scalar I_zz in the plane.
    """
    c = np.asarray(com, float)
    if dimension == 2:
        return np.array([mass, mass * c[0], mass * c[1], float(inertia_com) + mass * (c @ c)])
    i_o = np.asarray(inertia_com, float) + mass * ((c @ c) * np.eye(3) - np.outer(c, c))
    return np.array([mass, *(mass * c), i_o[0, 0], i_o[0, 1], i_o[0, 2], i_o[1, 1],
                     i_o[1, 2], i_o[2, 2]])


def centroidal(pi_b: Sequence[float], dimension: int) -> tuple[float, np.ndarray, np.ndarray]:
    """(m, c, I_G) of one body's π_b: the inverse of :func:`inertial_parameters` (m > 0)."""
    pi_b = np.asarray(pi_b, float)
    mass = float(pi_b[0])
    if mass <= 0.0:
        raise ModelError(f"the centroidal inertia needs a positive mass, got {mass}")
    c = pi_b[1:dimension + 1] / mass
    if dimension == 2:
        return mass, c, np.array(pi_b[3] - mass * (c @ c))
    i_o = np.array([[pi_b[4], pi_b[5], pi_b[6]], [pi_b[5], pi_b[7], pi_b[8]],
                    [pi_b[6], pi_b[8], pi_b[9]]])
    return mass, c, i_o - mass * ((c @ c) * np.eye(3) - np.outer(c, c))


def _number(mech, value, where: str) -> float:
    return numeric(value, dict(mech.parameters), where)


def _inertia_com(mech, body) -> np.ndarray | float:
    where = f"body '{body.name}' field 'inertia'"
    if mech.dimension == 2:
        return _number(mech, body.inertia, where)
    vals = [_number(mech, v, where) for v in body.inertia]
    ixx, iyy, izz = vals[:3]
    ixy, ixz, iyz = vals[3:] if len(vals) == 6 else (0.0, 0.0, 0.0)
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def body_origin(mech, name: str, frame: str) -> np.ndarray:
    """Body-axes coordinates, relative to the centre of mass, of the origin O of ``name``'s
    inertial parameters in ``frame`` (module docstring)."""
    body = mech.bodies[name]
    if frame == "body":
        return np.asarray(getattr(body, "reference_point", np.zeros(mech.dimension)), float)
    carriers = [j for j in mech.joints.values() if j.body2 == name]
    if not carriers and not any(j.body1 == name and j.body2 == GROUND
                                for j in mech.joints.values()):  # free: its reference point
        return body_origin(mech, name, "body")
    if len(carriers) != 1 or getattr(carriers[0], "point", None) is None:
        found = ", ".join(f"'{j.name}'" for j in carriers) or "none"
        raise ModelError(f"body '{name}': frame='joint' needs exactly one joint with a point "
                         f"whose body2 is the body (found {found}); use frame='body'")
    return np.asarray(body.local(carriers[0].point), float)


def friction_coordinates(mech, laws: Sequence[str], joints: Sequence[str] | None,
                         regularization: float | None) -> list[FrictionCoordinate]:
    """The joint coordinates of ``joints`` (names) that get the friction ``laws``: a joint's
    single coordinate; of a joint with several (cylindrical, universal …) the first one and
    every other one that has its own ``joint_friction`` element.  v_s is ``regularization``,
    else the element's, else :data:`~casmbd.model.joint_friction.REGULARIZATION`."""
    if not laws:
        return []
    elements = {}
    for force in mech.forces.values():
        if isinstance(force, JointFriction):
            elements[(force.joint, force.coordinate)] = force
    out = []
    for jname in joints:
        joint = mech.joints.get(jname)
        if joint is None:
            raise ModelError(f"friction: unknown joint '{jname}' (joints: "
                             f"{', '.join(mech.joints)})")
        if not joint.coordinate_names:
            raise ModelError(f"friction: joint '{jname}' ({joint.kind}) has no coordinate "
                             "to carry friction")
        for coord in joint.coordinate_names:
            if len(joint.coordinate_names) > 1 and (jname, coord) not in elements and \
                    coord != joint.coordinate_names[0]:
                continue  # a multi-coordinate joint: its first coordinate unless given
            element = elements.get((jname, coord))
            v_s = regularization
            if v_s is None:
                v_s = REGULARIZATION if element is None else _number(
                    mech, element.regularization,
                    f"force '{element.name}' field 'regularization'")
            prefix = jname if len(joint.coordinate_names) == 1 else f"{jname}.{coord}"
            out.append(FrictionCoordinate(jname, coord, prefix, float(v_s)))
    return out


def default_friction_joints(mech, coordinate_joints: Sequence[str]) -> list[str]:
    """``coordinate_joints`` (the joints whose coordinates carry the efforts) followed by the
    other joints with a ``joint_friction`` element, each once."""
    names = list(coordinate_joints)
    for force in mech.forces.values():
        if isinstance(force, JointFriction) and force.joint not in names:
            names.append(force.joint)
    return names


def check_friction_laws(friction) -> tuple[str, ...]:
    """``friction`` as a tuple of laws: a string ``"viscous,coulomb"``, a sequence, or
    None/empty for none; unknown laws are a :class:`ModelError`."""
    if friction is None:
        return ()
    if isinstance(friction, str):
        friction = [f.strip() for f in friction.split(",") if f.strip()]
    laws = tuple(friction)
    unknown = [f for f in laws if f not in FRICTION_LAWS]
    if unknown:
        raise ModelError(f"friction: unknown law(s) {', '.join(map(str, unknown))} (known: "
                         f"{', '.join(FRICTION_LAWS)})")
    return tuple(f for f in FRICTION_LAWS if f in laws)


def standard_parameters(mechanism, friction: Sequence[str] | str | None = (),
                        frame: str = "body", friction_joints: Sequence[str] | None = None,
                        regularization: float | None = None) -> StandardParameters:
    """The standard parameter vector π of ``mechanism`` with its names and nominal values.

    Parameters
    ----------
    mechanism : Mechanism
    friction : sequence of {"viscous", "coulomb"} or str
        The friction laws to include per joint coordinate (``"viscous,coulomb"`` accepted);
        default none.
    frame : {"body", "joint"}
        Where the origin O of each body's parameters is (module docstring).
    friction_joints : sequence of str, optional
        The joints with friction parameters; default every joint that has a coordinate and
        is not welded (rigid), in the mechanism's order.  :func:`~casmbd.analysis.
        identification.regressor.joint_torque_regressor` passes the joints of the actuated
        coordinates and those with a ``joint_friction`` element.
    regularization : float, optional
        v_s of the Coulomb law; default each joint's own element's, else 1e-3
        (:data:`casmbd.model.joint_friction.REGULARIZATION`).

    Returns
    -------
    StandardParameters
        Nominal values: each body's π_b (:func:`inertial_parameters`) and each joint's
        friction element's ``damping`` (viscous) and ``friction`` (Coulomb), 0 without one.

    Raises
    ------
    ModelError
        A body that is not a rigid body (flexible), an unknown frame, law or joint, a friction
        element whose level follows the reaction (``mu``) or switches (``stick_slip``).
    """
    mech = mechanism
    if frame not in FRAMES:
        raise ModelError(f"standard_parameters: unknown frame {frame!r} (known: "
                         f"{', '.join(FRAMES)})")
    laws = check_friction_laws(friction)
    dim = mech.dimension
    per = PLANAR_NAMES if dim == 2 else SPATIAL_NAMES
    names: list[str] = []
    values: list[float] = []
    origins: dict[str, np.ndarray] = {}
    for name, body in mech.bodies.items():
        if getattr(body, "kind", "rigid") != "rigid":
            raise ModelError(f"body '{name}' ({body.kind}): the standard parameters cover "
                             "rigid bodies only")
        mass = _number(mech, body.mass, f"body '{name}' field 'mass'")
        origin = body_origin(mech, name, frame)
        origins[name] = origin
        names += [f"{name}.{p}" for p in per]
        values += list(inertial_parameters(mass, -origin, _inertia_com(mech, body), dim))
    if friction_joints is None:
        friction_joints = [j.name for j in mech.joints.values()
                           if j.coordinate_names and j.kind != "rigid"]
    coords = friction_coordinates(mech, laws, friction_joints, regularization)
    elements = {(f.joint, f.coordinate): f for f in mech.forces.values()
                if isinstance(f, JointFriction)}
    for fc in coords:
        element = elements.get((fc.joint, fc.coordinate))
        if element is not None:
            check_linear_friction(element)
        for law in laws:
            names.append(f"{fc.prefix}.{law}")
            if element is None:
                values.append(0.0)
            else:
                key = "damping" if law == "viscous" else "friction"
                values.append(_number(mech, getattr(element, key),
                                      f"force '{element.name}' field '{key}'"))
    return StandardParameters(names, np.array(values, float), list(mech.bodies), origins,
                              frame, laws, coords, dim)


def check_linear_friction(element: JointFriction) -> None:
    """Refuse a friction element outside the linear law (module docstring)."""
    if element.stick_slip:
        raise ModelError(f"force '{element.name}': the exact stick-slip law switches at events; "
                         "the regressor uses the regularised law (stick_slip = false)")
    mu = element.mu
    if not (isinstance(mu, (int, float)) and mu == 0.0):
        raise ModelError(f"force '{element.name}' field 'mu': a Coulomb level following the "
                         "joint reaction is not linear in the friction parameters; the "
                         "regressor covers the viscous and constant Coulomb levels")


def parameter_vector(params: StandardParameters, values: Mapping[str, float]) -> np.ndarray:
    """π with the nominal values replaced by ``values`` (name → value; unknown names are a
    :class:`ModelError`)."""
    out = params.values.copy()
    for name, val in values.items():
        out[params.index(name)] = float(val)
    return out
