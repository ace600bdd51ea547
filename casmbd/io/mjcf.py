"""Robots from MJCF (MuJoCo XML) files: :func:`load_mjcf` builds a spatial
:class:`~casmbd.model.Mechanism` from the model MuJoCo itself compiles.

The file is read by MuJoCo's own parser and compiler (``mujoco.MjModel.from_xml_path``, the
optional extra ``casmbd[mjcf]``), so ``<default>`` classes, ``childclass``, ``<include>``,
orientations (``quat``, ``euler`` with ``<compiler eulerseq>``, ``axisangle``, ``xyaxes``,
``zaxis``, degrees or radians), inertias computed from geoms (``inertiafromgeom``,
``<inertial>`` and ``fullinertia``) and joint references (``ref``) are resolved exactly as
MuJoCo resolves them.  This module reads the compiled arrays (``body_mass``,
``body_inertia``, ``jnt_type``, ``dof_damping``, ``actuator_gear``, ``eq_data`` …) and the
design pose from MuJoCo's forward kinematics at ``qpos0`` (``xpos``, ``xquat``, ``xipos``,
``ximat``, ``xanchor``, ``xaxis``).

Mapping (see docs/robots.md, "MJCF"):

* the design pose is MuJoCo's ``qpos0`` (every hinge and slide at its ``ref``, balls at the
  identity, free bodies where the file puts them); casmbd's joint coordinate of a hinge or
  slide is ``qpos − qpos0`` (rad or m);
* a body that carries joints is a casmbd body named like it, its frame the MuJoCo body frame
  moved to the centre of mass (``xipos``; casmbd bodies are centroidal), its inertia tensor
  Rᵢ diag(``body_inertia``) Rᵢᵀ in body axes (Rᵢ = ``body_iquat``); a body without joints is
  welded to its parent: merged into the parent's casmbd body (masses, centres of mass and
  tensors by the parallel-axis theorem, :func:`casmbd.io.urdf_tree.merge`) and kept as a
  marker at its frame origin with its frame's orientation; ``worldbody`` and what is welded
  to it is the ground.  Sites are markers (``site_xpos``, ``site_xquat``);
* ``hinge`` → ``revolute`` through ``xanchor`` about ``xaxis``; ``slide`` → ``prismatic``
  along ``xaxis``; ``ball`` → ``spherical`` at ``xanchor``; ``free`` → no joint: a floating
  root (position of the centre of mass and Euler parameters of the body frame, global).  A body
  with k > 1 joints gets k − 1 massless frames ``<body>__<joint>`` chained in MuJoCo's order
  (each later joint's axis turns with the earlier ones, as in MuJoCo's ``mj_kinematics``);
* ``<equality connect>`` → a ``spherical`` joint at the anchor, ``<equality weld>`` → a
  ``rigid`` joint (a weld of two bodies), both loop closures (never joints of the spanning
  tree: MuJoCo's tree is casmbd's); both must hold at ``qpos0`` (gap ≤
  :data:`CLOSURE_TOLERANCE`), else they are refused with the gap: casmbd joints are defined
  in the design pose, MuJoCo's soft equalities pull a model together over time.  Inactive
  equalities (``active="false"``) are left out with a warning;
* ``damping`` → a ``joint_friction`` element ``<joint>_damping`` (Q = −d q̇);
* ``armature`` a of a hinge or slide (MuJoCo adds a to the diagonal of qM: T += ½ a q̇²) → a
  rotor ``<joint>__rotor`` on the ground geared 1:1 to the joint (gear ``<joint>__armature``,
  joint ``<joint>__rotor_joint``): a disc of inertia (a, a/2, a/2) about the global x axis
  for a hinge, a point mass a sliding normal to gravity for a slide, so its kinetic energy is
  ½ a q̇² exactly, with no gravity or gyroscopic term (:func:`_armature`).  casmbd has no
  mass-matrix element kind; this uses existing kinds, at the price of one coordinate and one
  gear equation per joint with armature;
* an actuator on a hinge or slide joint with a fixed gain and no bias or activation dynamics
  (``motor``, ``general`` with ``gainprm``) → an actuator on that joint; its input u is the
  joint force gear·gain·ctrl (casmbd actuators are generalized forces), the ratio kept as
  ``actuator.mjcf_gear``, ``ctrlrange``/``forcerange`` as the bounds of u.

Anything else that changes the dynamics is refused by name, the element and the attribute:
tendons, flex, composites (compiled into tendons or flex), site-, body-, tendon- and
slider-crank-transmission actuators, servo actuators (``position``, ``velocity``: a bias),
activation dynamics, ``armature`` of ball and free joints, joint ``stiffness`` and
``frictionloss``, gravity
compensation, mocap bodies, fluid forces (``density``, ``viscosity``), plugins, and other
equality types.  Geoms give mass and inertia (MuJoCo's compiler) and the visuals of the 3-D
view (:func:`_geom_visuals`), no contact; contacts, joint limits
(kept as ``joint.mjcf_range``) and solver parameters are MuJoCo's constraint solver and are not
modelled.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from casmbd.errors import CasmbdError, ModelError, SceneError
from casmbd.io.urdf_tree import merge
from casmbd.model import Mechanism
from casmbd.model.bodies import GROUND
from casmbd.model.rotations import quaternion_from_matrix, rotation_matrix
from casmbd.model.visuals import Visual

#: how closely an equality's two sides must meet at ``qpos0`` (m, and rad for a weld)
CLOSURE_TOLERANCE = 1e-9


@dataclass
class MjcfJoint:
    """A MuJoCo joint as loaded: its type, the casmbd joint (None for a free joint: a floating
    root), the casmbd body it moves, its ``qpos``/``qvel`` addresses, ``qpos0``, the body
    frame's rotation A₀ at ``qpos0`` and the body's centre of mass u in the body frame."""

    kind: str
    joint: str | None
    body: str
    qposadr: int
    dofadr: int
    qpos0: np.ndarray
    frame: np.ndarray
    offset: np.ndarray
    #: the coordinate of its armature's rotor (hinge, slide), geared 1:1 to the joint
    rotor: str | None = None


def _mujoco():
    """The ``mujoco`` module, or a SceneError naming the extra that installs it."""
    try:
        import mujoco
    except ImportError:
        raise SceneError("MJCF files are read by MuJoCo's own parser: install the extra "
                         "'casmbd[mjcf]' (pip install mujoco)") from None
    return mujoco


def _name(model, obj, index: int, prefix: str, mujoco) -> str:
    name = mujoco.mj_id2name(model, obj, index)
    return name if name else f"{prefix}{index}"


def _refuse(where: str, what: str) -> SceneError:
    return SceneError(f"MJCF {where}: {what} cannot be mapped to casmbd (see docs/robots.md, "
                      "'MJCF')")


def _check_model(model, mujoco, names: dict) -> None:
    """Refuse, by name, the parts of a compiled model casmbd cannot represent."""
    obj = mujoco.mjtObj
    if model.ntendon:
        raise _refuse(f"tendon '{_name(model, obj.mjOBJ_TENDON, 0, 'tendon', mujoco)}'",
                      "a tendon (<tendon>, or one a <composite> made)")
    if model.nflex:
        raise _refuse(f"flex '{_name(model, obj.mjOBJ_FLEX, 0, 'flex', mujoco)}'",
                      "a deformable <flex> (or <flexcomp>/<composite>)")
    if model.nplugin:
        raise _refuse("<plugin>", "an engine plugin")
    if model.nmocap:
        body = int(np.flatnonzero(model.body_mocapid >= 0)[0])
        raise _refuse(f"body '{names['body'][body]}' attribute 'mocap'", "a mocap body")
    for key in ("density", "viscosity"):
        if float(getattr(model.opt, key)) != 0.0:
            raise _refuse(f"<option> attribute '{key}'", "a fluid force")
    for b in np.flatnonzero(model.body_gravcomp != 0.0):
        raise _refuse(f"body '{names['body'][b]}' attribute 'gravcomp'", "gravity compensation")
    for j in range(model.njnt):
        dof = int(model.jnt_dofadr[j])
        ndof = {0: 6, 1: 3}.get(int(model.jnt_type[j]), 1)
        where = f"joint '{names['joint'][j]}' attribute"
        if ndof > 1 and np.any(model.dof_armature[dof:dof + ndof] != 0.0):
            raise _refuse(f"{where} 'armature'", "armature on a ball or free joint")
        if np.any(model.dof_frictionloss[dof:dof + ndof] != 0.0):
            raise _refuse(f"{where} 'frictionloss'", "dry friction (a MuJoCo constraint)")
        if float(model.jnt_stiffness[j]) != 0.0:
            raise _refuse(f"{where} 'stiffness'", "a joint spring")
        if ndof > 1 and np.any(model.dof_damping[dof:dof + ndof] != 0.0):
            raise _refuse(f"{where} 'damping'", "damping of a ball or free joint")


def _design_pose(model, mujoco):
    """MuJoCo's forward kinematics at ``qpos0``: the design pose."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    mujoco.mj_kinematics(model, data)
    return data


def _joint_kind(jtype: int) -> str:
    return {0: "free", 1: "ball", 2: "slide", 3: "hinge"}[jtype]


def build_mjcf(model, mujoco, source: str = "<model>", coordinates: str = "joint",
               damping: bool = True, gravity: Sequence[float] | None = None,
               name: str | None = None) -> Mechanism:
    """The :class:`Mechanism` of a compiled ``mujoco.MjModel`` (see :func:`load_mjcf`)."""
    obj = mujoco.mjtObj
    names = {"body": [_name(model, obj.mjOBJ_BODY, i, "body", mujoco)
                      for i in range(model.nbody)],
             "joint": [_name(model, obj.mjOBJ_JOINT, i, "joint", mujoco)
                       for i in range(model.njnt)]}
    names["body"][0] = GROUND
    for i, bname in enumerate(names["body"][1:], 1):
        if bname == GROUND:
            raise SceneError(f"MJCF body '{bname}' (number {i}): the name '{GROUND}' is "
                             "reserved for casmbd's ground (MuJoCo's worldbody)")
    _check_model(model, mujoco, names)
    data = _design_pose(model, mujoco)
    off = mujoco.mjtDisableBit  # <option><flag gravity="disable" damper="disable"/>
    file_gravity = (np.zeros(3) if model.opt.disableflags & off.mjDSBL_GRAVITY
                    else model.opt.gravity)
    damping = damping and not model.opt.disableflags & off.mjDSBL_DAMPER
    grav = tuple(float(g) for g in (file_gravity if gravity is None else gravity))
    mech = Mechanism(name or Path(source).stem or "mjcf", gravity=grav, dimension=3,
                     coordinates=coordinates)

    def guarded(where: str, action, *args, **kwargs):
        try:
            return action(*args, **kwargs)
        except SceneError:
            raise
        except CasmbdError as exc:
            raise SceneError(f"MJCF {where}: {exc}") from None

    # rigid groups: a body without joints belongs to its parent's group
    group = {0: GROUND}
    for b in range(1, model.nbody):
        parent = int(model.body_parentid[b])
        group[b] = group[parent] if model.body_jntnum[b] == 0 else names["body"][b]
    parts: dict[str, list] = {}
    for b in range(1, model.nbody):
        rot_i = data.ximat[b].reshape(3, 3)
        parts.setdefault(group[b], []).append(
            (float(model.body_mass[b]), data.xipos[b].copy(),
             rot_i @ np.diag(model.body_inertia[b]) @ rot_i.T))
    taken = set(names["body"]) | set(names["joint"])
    chains: dict[int, list[str]] = {}  # body id -> casmbd bodies its joints connect
    poses = {GROUND: (np.eye(3), np.zeros(3))}  # casmbd body -> rotation, centre of mass
    for b in range(1, model.nbody):
        if model.body_jntnum[b] == 0:
            continue
        bname = names["body"][b]
        rot, origin = data.xmat[b].reshape(3, 3), data.xpos[b].copy()
        mass, com, tensor = merge(parts[bname])
        if mass <= 0.0:  # massless: at its frame origin (forward dynamics checks M)
            com, tensor = origin, sum(p[2] for p in parts[bname])
        local = rot.T @ tensor @ rot
        first = int(model.body_jntadr[b])
        joints = range(first, first + int(model.body_jntnum[b]))
        frames = []
        for j in list(joints)[:-1]:  # massless frames between chained joints
            fname = f"{bname}__{names['joint'][j]}"
            if fname in taken:
                raise SceneError(f"MJCF body '{bname}': the frame name '{fname}' of its "
                                 f"joint '{names['joint'][j]}' is taken")
            taken.add(fname)
            guarded(f"body '{bname}'", mech.add_body, fname, 0.0, [0.0] * 6, origin,
                    orientation=quaternion_from_matrix(rot))
            frames.append(fname)
        guarded(f"body '{bname}'", mech.add_body, bname, mass,
                [local[0, 0], local[1, 1], local[2, 2], local[0, 1], local[0, 2], local[1, 2]],
                com, orientation=quaternion_from_matrix(rot))
        chains[b] = [*frames, bname]
        poses[bname] = (rot, com)
    if not mech.bodies:
        raise SceneError(f"MJCF file '{source}': no body moves (every body is welded to the "
                         "world: give one a joint or a <freejoint>)")
    for b in range(1, model.nbody):
        if group[b] != names["body"][b]:
            bname = names["body"][b]
            guarded(f"body '{bname}'", mech.add_marker, bname, group[b], data.xpos[b].copy(),
                    orientation=data.xquat[b].copy())
    for s in range(model.nsite):
        sname = _name(model, obj.mjOBJ_SITE, s, "site", mujoco)
        body = int(model.site_bodyid[s])
        guarded(f"site '{sname}'", mech.add_marker, sname, group[body],
                data.site_xpos[s].copy(),
                orientation=quaternion_from_matrix(data.site_xmat[s].reshape(3, 3)))

    mech.visuals = _geom_visuals(model, mujoco, data, group, poses)
    mech.mjcf_joints = {}  # MuJoCo joint name -> MjcfJoint, in MuJoCo's joint order
    for b, chain in chains.items():
        parent = group[int(model.body_parentid[b])]
        first = int(model.body_jntadr[b])
        for k, j in enumerate(range(first, first + int(model.body_jntnum[b]))):
            jname, kind = names["joint"][j], _joint_kind(int(model.jnt_type[j]))
            body1 = parent if k == 0 else chain[k - 1]
            adr = int(model.jnt_qposadr[j])
            nq = {"free": 7, "ball": 4}.get(kind, 1)
            qpos0 = model.qpos0[adr:adr + nq].copy()
            rot = data.xmat[b].reshape(3, 3).copy()
            entry = MjcfJoint(kind, jname, chain[k], adr, int(model.jnt_dofadr[j]), qpos0, rot,
                              rot.T @ (mech.bodies[chain[-1]].position - data.xpos[b]))
            mech.mjcf_joints[jname] = entry
            if kind == "free":
                if model.body_jntnum[b] != 1:
                    raise SceneError(f"MJCF joint '{jname}': a free joint must be its body's "
                                     "only joint")
                entry.joint = None
                continue
            point, axis = data.xanchor[j].copy(), data.xaxis[j].copy()
            if kind == "ball":
                made = guarded(f"joint '{jname}'", mech.add, "spherical", jname, body1,
                               chain[k], point)
            else:
                made = guarded(f"joint '{jname}'", mech.add,
                               "revolute" if kind == "hinge" else "prismatic", jname, body1,
                               chain[k], point, axis=axis)
                if model.jnt_limited[j]:
                    made.mjcf_range = tuple(float(x) for x in model.jnt_range[j])
                dof = int(model.jnt_dofadr[j])
                if damping and model.dof_damping[dof] > 0.0:
                    guarded(f"joint '{jname}' attribute 'damping'", mech.add,
                            "joint_friction", f"{jname}_damping", jname,
                            damping=float(model.dof_damping[dof]))
                if model.dof_armature[dof] > 0.0:
                    entry.rotor = _armature(mech, jname, kind, float(model.dof_armature[dof]),
                                            guarded, taken)
            made.mjcf_type = kind
    # MuJoCo's kinematic tree is the spanning tree (an equality always closes a loop)
    mech.tree = [j for e in mech.mjcf_joints.values()
                 for j in (e.joint, e.rotor and e.rotor.split(".")[0]) if j is not None]
    _equalities(model, mujoco, data, mech, group, names, guarded)
    _actuators(model, mujoco, mech, names, guarded)
    return mech


#: MuJoCo geom type -> (visual kind, size from MuJoCo's size: half-sizes, radius, half-length)
_GEOM_VISUALS = {
    "SPHERE": ("sphere", lambda z: (z[0],)),
    "BOX": ("box", lambda z: (2 * z[0], 2 * z[1], 2 * z[2])),
    "CYLINDER": ("cylinder", lambda z: (z[0], 2 * z[1])),
    "CAPSULE": ("cylinder", lambda z: (z[0], 2 * (z[1] + z[0]))),  # drawn as its hull
    "ELLIPSOID": ("box", lambda z: (2 * z[0], 2 * z[1], 2 * z[2])),  # drawn as its box
}


def _geom_visuals(model, mujoco, data, group, poses) -> dict:
    """Geoms as visuals for the 3-D view (body name or ``"ground"`` → tuple of
    :class:`~casmbd.model.visuals.Visual`), posed in the body frame at ``qpos0``:
    u = Aᵀ (``geom_xpos`` − r_G), axes Aᵀ ``geom_xmat``.  Spheres, boxes and cylinders as they
    are; a capsule as the cylinder that holds it, an ellipsoid as its box; planes, meshes,
    height fields and SDFs are not drawn.  Geoms change nothing computed (MuJoCo's compiler
    already folded their mass into the bodies)."""
    out: dict[str, list] = {}
    for g in range(model.ngeom):
        kind = mujoco.mjtGeom(int(model.geom_type[g])).name.removeprefix("mjGEOM_")
        if kind not in _GEOM_VISUALS:
            continue
        body = group[int(model.geom_bodyid[g])]
        rot, com = poses[body]
        shape, size = _GEOM_VISUALS[kind]
        gname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        out.setdefault(body, []).append(Visual(
            shape, tuple(float(x) for x in size(model.geom_size[g])),
            rot.T @ (data.geom_xpos[g] - com), rot.T @ data.geom_xmat[g].reshape(3, 3),
            None, "", np.ones(3), tuple(float(c) for c in model.geom_rgba[g]), gname,
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY,
                              int(model.geom_bodyid[g])) or GROUND))
    return {body: tuple(v) for body, v in out.items()}


def _armature(mech, joint: str, kind: str, armature: float, guarded, taken: set) -> str:
    """MuJoCo's armature a of a hinge or slide (T += ½ a q̇², M_jj += a) from existing kinds:
    a body ``<joint>__rotor`` on the ground geared 1:1 to the joint (gear
    ``<joint>__armature``).  A hinge's rotor turns about the global x axis through the origin
    (revolute ``<joint>__rotor_joint``), mass 0 and inertia (a, a/2, a/2): its centre does not
    move and it spins about a principal axis, so T = ½ a q̇² with no gravity or gyroscopic
    term.  A slide's is a point mass a sliding along a fixed axis normal to gravity (prismatic
    ``<joint>__rotor_joint``): T = ½ a q̇², and its weight does no work.  Returns the rotor's
    coordinate name (``<joint>__rotor_joint.angle`` or ``.translation``)."""
    rotor, guide = f"{joint}__rotor", f"{joint}__rotor_joint"
    for made in (rotor, guide, f"{joint}__armature"):
        if made in taken:
            raise SceneError(f"MJCF joint '{joint}' attribute 'armature': the name '{made}' "
                             "of its rotor is taken")
        taken.add(made)
    where = f"joint '{joint}' attribute 'armature'"
    origin = [0.0, 0.0, 0.0]
    if kind == "hinge":
        guarded(where, mech.add_body, rotor, 0.0, [armature, armature / 2, armature / 2],
                origin)
        guarded(where, mech.add, "revolute", guide, GROUND, rotor, origin, axis=[1, 0, 0])
    else:
        gravity = np.asarray(mech.gravity, float)
        axis = np.cross(gravity, [1.0, 0.0, 0.0]) if np.any(gravity) else np.array([1.0, 0, 0])
        if np.linalg.norm(axis) < 1e-9 * max(1.0, np.linalg.norm(gravity)):
            axis = np.cross(gravity, [0.0, 1.0, 0.0])
        guarded(where, mech.add_body, rotor, armature, [0.0, 0.0, 0.0], origin)
        guarded(where, mech.add, "prismatic", guide, GROUND, rotor, origin,
                axis=axis / np.linalg.norm(axis))
    guarded(where, mech.add_gear, f"{joint}__armature", joint, guide, ratio=1.0)
    coordinate = mech.joints[guide].coordinate_names[0]
    return f"{guide}.{coordinate}"


def _equalities(model, mujoco, data, mech, group, names, guarded) -> None:
    """``connect`` → spherical joint, ``weld`` → fixed joint (loop closures)."""
    eq, obj = mujoco.mjtEq, mujoco.mjtObj
    for e in range(model.neq):
        ename = _name(model, obj.mjOBJ_EQUALITY, e, "equality", mujoco)
        etype = int(model.eq_type[e])
        if etype not in (eq.mjEQ_CONNECT, eq.mjEQ_WELD):
            kind = eq(etype).name.removeprefix("mjEQ_").lower()
            raise _refuse(f"equality '{ename}'", f"an equality of type '{kind}'")
        if not model.eq_active0[e]:
            warnings.warn(f"MJCF equality '{ename}' is inactive (active=\"false\"): left out",
                          RuntimeWarning, stacklevel=4)
            continue
        objtype = getattr(model, "eq_objtype", None)  # MuJoCo ≥ 3.1: bodies or sites
        if objtype is not None and int(objtype[e]) != obj.mjOBJ_BODY:
            raise _refuse(f"equality '{ename}' attribute 'site1'", "an equality between sites")
        b1, b2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        g1, g2 = group[b1], group[b2]
        if g1 == g2:
            raise SceneError(f"MJCF equality '{ename}': bodies '{names['body'][b1]}' and "
                             f"'{names['body'][b2]}' are already rigidly joined")
        rot1, pos1 = data.xmat[b1].reshape(3, 3), data.xpos[b1]
        rot2, pos2 = data.xmat[b2].reshape(3, 3), data.xpos[b2]
        d = model.eq_data[e]
        if etype == eq.mjEQ_CONNECT:
            p1, p2 = pos1 + rot1 @ d[0:3], pos2 + rot2 @ d[3:6]
            gap = float(np.linalg.norm(p1 - p2))
            if gap > CLOSURE_TOLERANCE:
                raise SceneError(f"MJCF equality '{ename}' (connect): the anchors on "
                                 f"'{names['body'][b1]}' and '{names['body'][b2]}' are "
                                 f"{gap:.3g} m apart at qpos0; casmbd closes loops in the "
                                 "design pose (assemble the model at qpos0)")
            made = guarded(f"equality '{ename}'", mech.add, "spherical", ename, g1, g2, p1)
        else:
            # weld (MuJoCo's mj_instantiateEquality): the anchor d[0:3] in body2's frame sits
            # at d[3:6] in body1's frame, and body2's orientation is body1's times d[6:10]
            point = pos2 + rot2 @ d[0:3]
            gap = max(float(np.linalg.norm(pos1 + rot1 @ d[3:6] - point)),
                      float(np.linalg.norm(rot1 @ _quat_matrix(d[6:10]) - rot2)))
            if gap > CLOSURE_TOLERANCE:
                raise SceneError(f"MJCF equality '{ename}' (weld): body "
                                 f"'{names['body'][b2]}' is {gap:.3g} (m or rad) off its "
                                 f"relative pose to '{names['body'][b1]}' (relpose) at qpos0; "
                                 "casmbd closes loops in the design pose")
            if float(d[10]) != 1.0:  # torquescale
                raise _refuse(f"equality '{ename}' attribute 'torquescale'",
                              "a weld with torquescale other than 1")
            made = guarded(f"equality '{ename}'", mech.add, "rigid", ename, g1, g2,
                           point=point)
        made.tree_joint = False  # a loop closure, as in MuJoCo: never a joint of the tree
        made.mjcf_type = "connect" if etype == eq.mjEQ_CONNECT else "weld"


def _quat_matrix(quat) -> np.ndarray:
    """A of MuJoCo's quaternion [w, x, y, z], normalised first (MuJoCo normalises too)."""
    quat = np.asarray(quat, float)
    return np.asarray(rotation_matrix(quat / np.linalg.norm(quat)), float)


def _actuators(model, mujoco, mech, names, guarded) -> None:
    """Joint actuators with a fixed gain, no bias, no activation dynamics."""
    trn, obj = mujoco.mjtTrn, mujoco.mjtObj
    for a in range(model.nu):
        aname = _name(model, obj.mjOBJ_ACTUATOR, a, "actuator", mujoco)
        where = f"actuator '{aname}'"
        ttype = int(model.actuator_trntype[a])
        if ttype not in (trn.mjTRN_JOINT, trn.mjTRN_JOINTINPARENT):
            kind = trn(ttype).name.removeprefix("mjTRN_").lower()
            raise _refuse(f"{where} attribute '{kind}'", f"a {kind} transmission")
        if int(model.actuator_dyntype[a]) != mujoco.mjtDyn.mjDYN_NONE:
            raise _refuse(f"{where} attribute 'dyntype'", "activation dynamics")
        if int(model.actuator_gaintype[a]) != mujoco.mjtGain.mjGAIN_FIXED:
            raise _refuse(f"{where} attribute 'gaintype'", "a state-dependent gain")
        if int(model.actuator_biastype[a]) != mujoco.mjtBias.mjBIAS_NONE:
            raise _refuse(f"{where} attribute 'biastype'",
                          "a servo (position/velocity feedback bias)")
        for key in ("armature", "damping"):
            values = getattr(model, f"actuator_{key}", None)
            if values is not None and np.any(np.asarray(values[a]) != 0.0):
                raise _refuse(f"{where} attribute '{key}'", f"an actuator {key}")
        j = int(model.actuator_trnid[a, 0])
        jname = names["joint"][j]
        if int(model.jnt_type[j]) not in (2, 3):
            raise _refuse(f"{where} attribute 'joint'", f"an actuator on the "
                          f"{_joint_kind(int(model.jnt_type[j]))} joint '{jname}'")
        ratio = float(model.actuator_gear[a, 0]) * float(model.actuator_gainprm[a, 0])
        lo, hi = -np.inf, np.inf
        if model.actuator_ctrllimited[a]:
            lo, hi = sorted(ratio * model.actuator_ctrlrange[a])
        if model.actuator_forcelimited[a]:
            flo, fhi = float(model.actuator_gear[a, 0]) * model.actuator_forcerange[a]
            flo, fhi = sorted((flo, fhi))
            lo, hi = max(lo, flo), min(hi, fhi)
        made = guarded(where, mech.add_actuator, aname, jname)
        made.bounds = (float(lo), float(hi))
        made.mjcf_gear = ratio


def load_mjcf(path: str | os.PathLike, coordinates: str = "joint", damping: bool = True,
              gravity: Sequence[float] | None = None, name: str | None = None) -> Mechanism:
    """Build a spatial :class:`Mechanism` from an MJCF (MuJoCo XML) file.

    The file is compiled by MuJoCo (``mujoco.MjModel.from_xml_path``; install
    ``casmbd[mjcf]``) and mapped as the module docstring says.

    Parameters
    ----------
    path : path-like
        The ``.xml`` file (with its ``<include>`` files and assets, as MuJoCo reads them).
    coordinates : {"joint", "absolute", "natural"}
        The mechanism's default coordinates.
    damping : bool
        Apply the joints' ``damping`` as viscous joint forces (default True, as MuJoCo does
        unless the file's ``<flag damper="disable">``).
    gravity : 3 floats, optional
        Default: the file's ``<option gravity>`` (MuJoCo's default (0, 0, −9.81); zero with
        ``<flag gravity="disable">``).
    name : str, optional
        Mechanism name, default the file's stem.

    Raises
    ------
    SceneError
        MuJoCo's own message for a file it cannot read; otherwise a part that cannot be mapped
        (named: body, joint, actuator, equality, tendon … and the attribute).
    """
    mujoco = _mujoco()
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"MJCF file '{path}': not found")
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise SceneError(f"MJCF file '{path}': {str(exc).strip()}") from None
    return build_mjcf(model, mujoco, str(path), coordinates=coordinates, damping=damping,
                      gravity=gravity, name=name)


def mjcf_scene(data: dict, source: str, name: str, coordinates: str, gravity) -> Mechanism:
    """The mechanism of a scene's ``[scene] mjcf = "path"`` (relative to the scene file), with
    the optional switch ``damping`` (default true) and ``gravity`` (default the file's)."""
    rel = data["mjcf"]
    if not isinstance(rel, str) or not rel:
        raise SceneError(f"[scene] key 'mjcf': expected a file path, got {rel!r}")
    if "urdf" in data:
        raise SceneError("[scene] keys 'mjcf' and 'urdf': give one robot file")
    for key in ("initial", "locked", "friction", "inertia", "links", "ignore_mimic",
                "floating_base", "base"):  # URDF import options: never silently dropped
        if key in data:
            raise SceneError(f"[scene] key '{key}': not available with 'mjcf' (only with "
                             "'urdf'" + ("; an MJCF body floats with its own <freejoint>)"
                                         if key == "floating_base" else ")"))
    switch = data.get("damping", True)
    if not isinstance(switch, bool):
        raise SceneError(f"[scene] key 'damping': expected true or false, got {switch!r}")
    base = Path(source).parent if source and not source.startswith("<") else Path(".")
    try:
        return load_mjcf(base / rel, coordinates=coordinates, damping=switch, gravity=gravity,
                         name=name)
    except SceneError as exc:
        raise SceneError(f"[scene] key 'mjcf' ('{rel}'): {exc}") from None


def _left(e) -> np.ndarray:
    """L(e): e ⊗ x = L(e) x for quaternions [w, x, y, z]."""
    w, x, y, z = e
    return np.array([[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]])


def from_mujoco(mech: Mechanism, coordinate_names: Sequence[str], qpos, qvel,
                velocity_map=None):
    """MuJoCo's state (``qpos``, ``qvel``) in casmbd's joint coordinates of a loaded model.

    Returns (q, v, B, c) with v = B qvel and q̈ = B qacc + c, so that MuJoCo's quantities
    are M_mj = Bᵀ M B, b_mj = Bᵀ (M c + b) and qacc = B⁺ (q̈ − c) (B has full column rank).
    Without ``velocity_map`` v, B and c are in coordinate rates (v = q̇, as the analyses
    integrate); with the per-call API's map (``CompiledModel.velocity_map``, where a free
    body takes the free-flyer velocity, :mod:`casmbd.compiled.free_flyer`) they are in its
    velocity v (n_v entries): v = G⁺ q̇, v̇ = G⁺ (q̈ − Ġ v), so the same relations hold with
    the per-call M, b and forward dynamics.
    Per joint (A the body rotation, u its centre of mass in body axes, e ⊗ the quaternion
    product, A₀ the body frame at ``qpos0``):

    * hinge, slide: q = qpos − qpos0, v = qvel;
    * ball (qpos a unit quaternion Q in the body frame, qvel = ω in body axes): casmbd's
      Euler parameters of the relative rotation in the design frame, e = (Q_w, A₀ Q_xyz),
      ė = ½ e ⊗ (0, A₀ ω), c = −¼ |ω|² e;
    * free (qpos = [x y z qw qx qy qz] the body frame's origin and orientation, qvel = [v, ω]
      with v the velocity of the body frame's origin in global axes and ω in body axes):
      the centre of mass r = x + A u and e = (qw, qx, qy, qz), ṙ = v + A (ω × u),
      ė = ½ e ⊗ (0, ω); c = (A (ω × (ω × u)), −¼ |ω|² e).

    ``coordinate_names``: the compiled model's (``CompiledModel.coordinate_names``).
    """
    joints = getattr(mech, "mjcf_joints", None)
    if joints is None:
        raise ModelError(f"from_mujoco: mechanism '{mech.name}' was not loaded from MJCF")
    qpos, qvel = np.asarray(qpos, float).ravel(), np.asarray(qvel, float).ravel()
    nq = sum({"free": 7, "ball": 4}.get(e.kind, 1) for e in joints.values())
    nv = sum({"free": 6, "ball": 3}.get(e.kind, 1) for e in joints.values())
    if qpos.size != nq or qvel.size != nv:
        raise ModelError(f"from_mujoco: expected qpos of length nq = {nq} and qvel of length "
                         f"nv = {nv}, got {qpos.size} and {qvel.size}")
    index = {n: i for i, n in enumerate(coordinate_names)}
    n = len(coordinate_names)
    want = [f"{e.joint}.{'angle' if e.kind == 'hinge' else 'translation'}"
            for e in joints.values() if e.kind in ("hinge", "slide")]
    missing = [c for c in want if c not in index]
    if missing:
        raise ModelError(f"from_mujoco: coordinate '{missing[0]}' is not among the model's "
                         "(compile the mechanism in joint coordinates)")
    q, bmat, c = np.zeros(n), np.zeros((n, nv)), np.zeros(n)
    for e in joints.values():
        a, d = e.qposadr, e.dofadr
        if e.kind in ("hinge", "slide"):
            i = index[f"{e.joint}.{'angle' if e.kind == 'hinge' else 'translation'}"]
            q[i], bmat[i, d] = qpos[a] - e.qpos0[0], 1.0
            if e.rotor is not None and e.rotor in index:  # the rotor turns with the joint (1:1;
                # in joint coordinates the gear is substituted: the rotor has no coordinate)
                i = index[e.rotor]
                q[i], bmat[i, d] = qpos[a] - e.qpos0[0], 1.0
            continue
        if e.kind == "ball":
            quat = qpos[a:a + 4] / np.linalg.norm(qpos[a:a + 4])
            eul = np.concatenate([[quat[0]], e.frame @ quat[1:]])
            rows = [index[f"{e.joint}.e{k}"] for k in range(4)]
            q[rows] = eul
            bmat[np.ix_(rows, range(d, d + 3))] = 0.5 * _left(eul)[:, 1:] @ e.frame
            omega = qvel[d:d + 3]
            c[rows] = -0.25 * (omega @ omega) * eul
            continue
        quat = qpos[a + 3:a + 7] / np.linalg.norm(qpos[a + 3:a + 7])
        rot = _quat_matrix(quat)
        pos_rows = [index[f"{e.body}.{k}"] for k in "xyz"]
        rot_rows = [index[f"{e.body}.e{k}"] for k in range(4)]
        u = e.offset
        q[pos_rows], q[rot_rows] = qpos[a:a + 3] + rot @ u, quat
        cross_u = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
        bmat[np.ix_(pos_rows, range(d, d + 3))] = np.eye(3)
        bmat[np.ix_(pos_rows, range(d + 3, d + 6))] = -rot @ cross_u
        bmat[np.ix_(rot_rows, range(d + 3, d + 6))] = 0.5 * _left(quat)[:, 1:]
        omega = qvel[d + 3:d + 6]
        c[pos_rows] = rot @ np.cross(omega, np.cross(omega, u))
        c[rot_rows] = -0.25 * (omega @ omega) * quat
    if velocity_map is None or velocity_map.identity:
        return q, bmat @ qvel, bmat, c
    # the per-call velocity: G⁺ is linear for a fixed q (exact on tangent rates)
    to_v = np.column_stack([velocity_map.velocity_from_rates(q, col) for col in
                            np.eye(len(q))])
    v = to_v @ (bmat @ qvel)
    drift = velocity_map.rate_accelerations(q, v, np.zeros(velocity_map.nv))  # Ġ v
    return q, v, to_v @ bmat, to_v @ (c - drift)
