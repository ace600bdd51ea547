"""Robots from URDF files: :func:`load_urdf` builds a spatial :class:`~casmbd.model.Mechanism`.

Body and joint names are the URDF's.  The mechanism is built at the URDF's zero configuration
(every joint position 0), so every joint coordinate is zero there (casmbd measures a joint's
coordinate from the design pose).  Links joined by ``fixed`` joints (and joints named in
``locked``, fixed at the given value) are merged into one body (:func:`~casmbd.io.urdf_tree.merge`);
each merged link stays as a *marker* at its frame origin with the link frame's orientation,
named like the link.  The root link
is welded to the ground (its mass does not count, its frame is the global frame); a ``floating``
joint leaves its child free; a ``planar`` joint (motion in the plane normal to ``<axis>``)
becomes the planar joint kind (:mod:`casmbd.model.planar_joint`) at the child frame's origin:
coordinates ``x``, ``y`` along the in-plane directions f, g that kind derives from the axis
(:func:`casmbd.model.spatial_joints.triad` of the global axis at the URDF zero) and ``angle``
about the axis, all zero at the URDF zero (``initial`` and ``locked`` take single-coordinate
joints only).  The body frame of a merged body is the frame of its first link
with the origin moved to the centre of mass (casmbd's bodies are centroidal), so the body's
orientation at the design pose is that link's orientation and its inertia tensor, about the
centre of mass in those axes, is Rᵀ I Rᵀ with I the global tensor of the merge.

Mimic joints become gear couplings θ_follower = multiplier θ_leader + offset
(:mod:`casmbd.model.gear`, c₂ − c₂⁰ = r (c₁ − c₁⁰) + δ) written relative to the URDF zero
(c⁰ = 0 for both joints: the design pose stays the URDF zero).  A follower's initial value is
r θ_leader,0 + δ (rate r θ̇_leader,0), so the coupling holds at the initial state in every
coordinate choice; a locked leader at value v locks its follower at r v + δ.  A follower may be
named with its leader (both locked, or both initial) when the values agree
(:data:`MIMIC_TOLERANCE`); otherwise, or named alone, it is refused naming both joints.

``initial`` positions other than 0 start the robot away from its design pose: in joint
coordinates as the tree joints' initial coordinates (``Joint.tree_initial``), in absolute and
natural coordinates as every body's start pose, the link frames by forward kinematics of the
tree at those values (:meth:`casmbd.model.bodies.SpatialBody.set_start`; the design pose,
in which joints and markers are defined and joint coordinates measured, stays the URDF zero).
The two agree: the same scene starts at the same body poses and velocities in every choice.

Limits (``lower``, ``upper``, ``effort``, ``velocity``) and ``<dynamics damping friction>``
are kept on the joint objects as the dicts ``urdf_limits`` and ``urdf_dynamics``; with
``damping=True`` and/or ``friction=True`` a revolute, continuous or prismatic joint with a
nonzero value gets a ``joint_friction`` element (:mod:`casmbd.model.joint_friction`,
Q_j = −c q̇_j − F_c tanh(q̇_j / v_s), v_s = 1e-3) named ``<joint>_damping`` (or
``<joint>_friction`` when only ``friction`` is on); each switch applies only its own term.
``<visual>`` elements are kept for the 3-D view as ``mech.visuals`` (body name → tuple of
:class:`~casmbd.model.visuals.Visual`, ``"ground"`` for the links welded to the ground), each
posed in its body's frame: a visual with origin (R_v, p_v) in link l, whose frame is (R_l, p_l)
at the design pose, on a body with centre of mass c and rotation A₀ there, is at
u = A₀ᵀ (p_l + R_l p_v − c) with axes A₀ᵀ R_l R_v.  A mesh's filename is resolved here
(:func:`resolve_mesh`: relative to the URDF file, ``file://`` paths, ``package://NAME/…`` by
searching the URDF's folder and its parents for the package folder ``NAME``); the file is read
only by the view (:mod:`casmbd.viz.meshes`, bounded).  ``<collision>`` elements are not used.

Model checks run here, at load (:mod:`casmbd.io.urdf_checks`): impossible inertias of the
merged bodies (refused, or ``inertia="repair"``), per-link overrides (``links``), ignored
``<mimic>`` (``ignore_mimic``), reserved names renamed (``mech.urdf_renamed``), no moving body
(refused), massless end links (a warning).
"""

from __future__ import annotations

import functools
import os
import urllib.parse
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from casmbd.errors import CasmbdError, LimitError, SceneError
from casmbd.io.files import read_text
from casmbd.io.urdf_checks import check_built, check_inertias, prepare
from casmbd.io.urdf_tree import MOVING, Robot, merge, parse_urdf
from casmbd.limits import MAX_SCENE_BYTES, format_bytes
from casmbd.model import Mechanism
from casmbd.model.bodies import GROUND
from casmbd.model.rotations import (
    euler_zxz_to_quaternion,
    quaternion_from_matrix,
    rotation_matrix,
)
from casmbd.model.visuals import Visual

#: default gravity of a robot (URDF has none): −9.81 m/s² along global −z
GRAVITY = (0.0, 0.0, -9.81)
#: how closely a mimic follower given together with its leader (both locked, or both
#: initial) must satisfy θ_f = r θ_l + δ: relative to max(1, |r θ_l + δ|), in rad or m
MIMIC_TOLERANCE = 1e-9


def _state(value, joint: str, what: str) -> tuple[float, float]:
    """(position, velocity) from a number or a pair."""
    try:
        if isinstance(value, Sequence) and not isinstance(value, str):
            if len(value) != 2:
                raise ValueError
            pos, vel = float(value[0]), float(value[1])
        else:
            pos, vel = float(value), 0.0
    except (TypeError, ValueError):
        raise SceneError(f"{what} joint '{joint}': expected a number or [position, velocity], "
                         f"got {value!r}") from None
    if not (np.isfinite(pos) and np.isfinite(vel)):
        raise SceneError(f"{what} joint '{joint}': must be finite, got {value!r}")
    return pos, vel


def _check_names(robot: Robot, table: Mapping, what: str) -> None:
    for name in table:
        joint = robot.joints.get(name)
        if joint is None:
            raise SceneError(f"{what}: unknown joint '{name}' (joints: "
                             f"{', '.join(robot.joints) or 'none'})")
        if joint.type not in MOVING:
            raise SceneError(f"{what} joint '{name}': a {joint.type} joint has no single "
                             "position")


def _groups(robot: Robot, locked: Mapping) -> dict[str, str]:
    """Link → body name (the link heading its rigid group; GROUND for the root's group)."""
    group = {robot.root: GROUND}
    for joint in robot.order():
        rigid = joint.type == "fixed" or joint.name in locked
        group[joint.child] = group[joint.parent] if rigid else joint.child
    return group


def _twists(robot: Robot, values: dict, rates: dict, frames: dict,
            root: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """Global angular velocity ω and frame-origin velocity of every link at (q, q̇), the root
    link moving with ``root`` = (ω, origin velocity) (a floating base's start; else at rest)."""
    out = {robot.root: (np.zeros(3), np.zeros(3)) if root is None else root}
    for joint in robot.order():
        omega_p, vel_p = out[joint.parent]
        rot_c, pos_c = frames[joint.child]
        pos_p = frames[joint.parent][1]
        rate = rates.get(joint.name, 0.0)
        omega, vel = omega_p.copy(), vel_p + np.cross(omega_p, pos_c - pos_p)
        axis = rot_c @ joint.axis
        if joint.type in ("revolute", "continuous"):
            omega = omega + axis * rate
        elif joint.type == "prismatic":
            vel = vel + axis * rate
        out[joint.child] = (omega, vel)
    return out


def _mimic_order(robot: Robot, mimic_of: dict) -> list[str]:
    """Followers with every leader's value settled before its followers' (a leader may itself
    follow another joint); a cycle of <mimic> references is refused naming its joints."""
    depth: dict[str, int] = {}
    for follower in mimic_of:
        chain, joint = [], follower
        while joint in mimic_of and joint not in depth:
            if joint in chain:
                raise SceneError(f"URDF '{robot.name}': the <mimic> joints "
                                 f"{' -> '.join([*chain[chain.index(joint):], joint])} "
                                 "follow each other in a cycle")
            chain.append(joint)
            joint = mimic_of[joint][0]
        base = depth.get(joint, -1) if joint in mimic_of else -1
        for k, name in enumerate(reversed(chain)):
            depth[name] = base + 1 + k
    return sorted(mimic_of, key=depth.__getitem__)


def _consistent(given: float, expected: float) -> bool:
    return abs(given - expected) <= MIMIC_TOLERANCE * max(1.0, abs(expected))


def _couple(robot: Robot, mimic_of: dict, locked: dict, start: dict) -> None:
    """Locked and initial values of mimic followers from their leaders' (in place).

    θ_f = r θ_l + δ, θ̇_f = r θ̇_l.  A follower not named takes its leader's (locked, or
    initial when the leader has an initial value or δ ≠ 0).  A follower named together with
    its leader (both locked, or both initial) must agree with it to ``MIMIC_TOLERANCE``
    (relative to max(1, |r θ_l + δ|)); it then takes the exact value r θ_l + δ.  A follower named
    alone, or a follower and leader named in different tables, is refused naming both joints.
    """
    given_locked, given_start = set(locked), set(start)
    for follower in _mimic_order(robot, mimic_of):
        leader, ratio, offset = mimic_of[follower]
        law = (f"<mimic> couples '{follower}' = {ratio:g} * '{leader}' + {offset:g}")
        if follower in given_locked or follower in given_start:
            table = "locked" if follower in given_locked else "initial"
            other = "initial" if table == "locked" else "locked"
            if (leader in locked if table == "initial" else leader in start):
                raise SceneError(f"{table} joint '{follower}': {law}, but its leader "
                                 f"'{leader}' is {other}; give both in [{table}]")
            values = locked if table == "locked" else start
            if leader not in values:
                raise SceneError(f"{table} joint '{follower}': {law}; give '{leader}' in "
                                 f"[{table}] (the follower then follows it) or both with "
                                 "consistent values")
            lead = values[leader] if table == "locked" else values[leader][0]
            mine = values[follower] if table == "locked" else values[follower][0]
            expected = ratio * lead + offset
            if not _consistent(mine, expected):
                raise SceneError(f"{table} joints '{leader}' = {lead:.12g} and '{follower}' "
                                 f"= {mine:.12g} are inconsistent: {law} gives "
                                 f"'{follower}' = {expected:.12g}")
            if table == "locked":
                locked[follower] = expected
                continue
            rate, rate_lead = start[follower][1], start[leader][1]
            if not _consistent(rate, ratio * rate_lead):
                raise SceneError(f"initial joint velocities '{leader}' = {rate_lead:.12g} "
                                 f"and '{follower}' = {rate:.12g} are inconsistent: {law} "
                                 f"gives '{follower}' rate {ratio * rate_lead:.12g}")
            start[follower] = (expected, ratio * rate_lead)
        elif leader in locked:
            locked[follower] = ratio * locked[leader] + offset
        elif leader in start or offset != 0.0:
            pos, vel = start.get(leader, (0.0, 0.0))
            start[follower] = (ratio * pos + offset, ratio * vel)


def build_mechanism(robot: Robot, coordinates: str = "joint", locked: Mapping | None = None,
                    initial: Mapping | None = None, damping: bool = False,
                    gravity: Sequence[float] = GRAVITY, name: str | None = None,
                    friction: bool = False, inertia: str = "check",
                    links: Mapping | None = None,
                    ignore_mimic: bool | Sequence[str] = False,
                    floating_base: bool = False, base: Mapping | None = None) -> Mechanism:
    """The :class:`Mechanism` of a parsed URDF (see :func:`load_urdf`)."""
    start_base = base_start(base, floating_base, robot.name)
    robot = prepare(robot, inertia, links, ignore_mimic)  # overrides, mimic, 'ground'

    renamed = getattr(robot, "renamed", {})  # reserved names (io/urdf_checks.py)
    locked = {renamed.get(k, k): v for k, v in (locked or {}).items()}
    initial = {renamed.get(k, k): v for k, v in (initial or {}).items()}
    _check_names(robot, locked, "locked")
    _check_names(robot, initial, "initial")
    locked = {k: _state(v, k, "locked")[0] for k, v in locked.items()}
    start = {k: _state(v, k, "initial") for k, v in initial.items()}
    for key in set(start) & set(locked):
        raise SceneError(f"initial joint '{key}': the joint is also locked")
    mimic_of = {j.name: j.mimic for j in robot.joints.values() if j.mimic is not None}
    moot = sorted(f for f, (lead, _, _) in mimic_of.items() if lead in robot.joints
                  and (robot.joints[f].type == "fixed" or robot.joints[lead].type == "fixed"))
    if moot:  # as Pinocchio: a coupling of a fixed joint has nothing to couple
        warnings.warn(f"URDF '{robot.name}': <mimic> of a fixed joint ignored for "
                      f"{', '.join(moot)}", RuntimeWarning, stacklevel=3)
        mimic_of = {f: m for f, m in mimic_of.items() if f not in moot}
    for follower, (leader, _, _) in mimic_of.items():
        if robot.joints[leader].type not in MOVING or robot.joints[follower].type not in MOVING:
            raise SceneError(f"joint '{follower}' <mimic>: both joints must be revolute, "
                             "continuous or prismatic")
    _couple(robot, mimic_of, locked, start)
    group = _groups(robot, locked)
    if floating_base:  # the root's group is a free body named like the root link
        group = {k: robot.root if g == GROUND else g for k, g in group.items()}
    design = robot.frames(locked)  # the design pose: URDF zero, locked joints at their value
    robot = check_inertias(robot, group, design, inertia)  # on the merged bodies
    mech = Mechanism(name or robot.name, gravity=gravity, dimension=3, coordinates=coordinates)
    values = {**locked, **{k: p for k, (p, _) in start.items()}}
    at_start = robot.frames(values)
    moved = any(p != 0.0 for p, _ in start.values())  # else the start is the design pose
    root_twist = None
    if start_base is not None:  # the floating base's own start: every frame carried with it
        rot_b, pos_b, vel_b, omega_b = start_base
        at_start = {k: (rot_b @ rot, rot_b @ pos + pos_b) for k, (rot, pos) in at_start.items()}
        root_twist = (omega_b, vel_b)
        moved = True
    twists = _twists(robot, values, {k: v for k, (_, v) in start.items()}, at_start,
                     root_twist)

    parts: dict[str, list] = {}
    for lname, link in robot.links.items():
        rot, pos = design[lname]
        parts.setdefault(group[lname], []).append(
            (link.mass, pos + rot @ link.com, rot @ link.inertia @ rot.T))

    def guarded(where: str, action):
        try:
            return action()
        except SceneError:
            raise
        except CasmbdError as exc:
            raise SceneError(f"{where}: {exc}") from None

    frames = {GROUND: (np.eye(3), np.zeros(3))}  # body frames: rotation, centre of mass
    for body in dict.fromkeys(g for g in group.values() if g != GROUND):
        mass, com, tensor = merge(parts[body])
        if mass <= 0.0 and body == robot.root:
            freed = [j.name for j in robot.joints.values()
                     if j.type == "floating" and j.parent == body]
            hint = (f"; its floating joint '{freed[0]}' already frees the robot: load it "
                    "without floating_base" if freed else "; a free body needs one")
            raise SceneError(f"URDF '{robot.name}': floating_base: the root link '{body}' "
                             f"(with the links fixed to it) has no mass{hint}")
        if mass <= 0.0:  # a massless link: its frame origin (forward dynamics checks M)
            com, tensor = design[body][1], sum(part[2] for part in parts[body])
        rot = design[body][0]
        # a floating base's coordinates are its root link frame (origin and axes), as the
        # free-flyer of Pinocchio: reference point s = Aᵀ (origin − centre of mass)
        ref = rot.T @ (design[body][1] - com) if body == robot.root else np.zeros(3)
        frames[body] = (rot, com)
        local = rot.T @ tensor @ rot
        omega, vel0 = twists[body]
        com_start = at_start[body][0] @ (rot.T @ (com - design[body][1])) + at_start[body][1]
        vel = vel0 + np.cross(omega, com_start - at_start[body][1])
        made = guarded(f"link '{body}'", lambda body=body, mass=mass, com=com, local=local,
                       rot=rot, vel=vel, omega=omega, ref=ref: mech.add_body(
                           body, mass, [local[0, 0], local[1, 1], local[2, 2], local[0, 1],
                                        local[0, 2], local[1, 2]], com,
                           orientation=quaternion_from_matrix(rot), velocity=vel,
                           angular_velocity=omega, reference_point=ref))
        if moved:  # absolute and natural coordinates start here (joint: tree_initial)
            made.set_start(com_start, quaternion_from_matrix(at_start[body][0]))
    for lname in robot.links:
        if group[lname] != lname:
            guarded(f"link '{lname}'", lambda lname=lname: mech.add_marker(
                lname, group[lname], design[lname][1],
                orientation=quaternion_from_matrix(design[lname][0])))

    for joint in robot.order():
        if joint.type == "fixed" or joint.name in locked or joint.type == "floating":
            continue
        rot, pos = design[joint.child]
        body1, body2 = group[joint.parent], group[joint.child]
        axis = rot @ joint.axis
        kind = joint.type if joint.type in ("prismatic", "planar") else "revolute"
        made = guarded(f"joint '{joint.name}'", lambda joint=joint, body1=body1, body2=body2,
                       pos=pos, axis=axis, kind=kind: mech.add(
                           kind, joint.name, body1, body2, pos, axis=axis))
        made.urdf_type = joint.type
        made.urdf_limits = dict(joint.limits)
        made.urdf_dynamics = dict(joint.dynamics)
        if joint.name in start and start[joint.name][0] != 0.0:
            made.tree_initial = functools.partial(np.array, [start[joint.name][0]], float)
    for follower, (leader, ratio, offset) in mimic_of.items():
        if follower in locked:
            continue
        guarded(f"joint '{follower}' <mimic>", lambda f=follower, lead=leader, r=ratio,
                d=offset: mech.add_gear(f"{f}_mimic", lead, f, ratio=r, offset=d))
    if damping or friction:
        _add_damping(robot, mech, locked, damping, friction)
    mech.visuals = _body_visuals(robot, group, design, frames)
    check_built(robot, mech, locked, design)  # a moving body; massless end links
    mech.urdf_renamed = dict(renamed)  # URDF name → casmbd name of reserved names
    return mech


#: keys of ``base`` (``[scene.base]``): the start of a floating base
BASE_KEYS = ("position", "orientation", "euler_zxz", "velocity", "angular_velocity")


def base_start(base: Mapping | None, floating_base: bool, robot: str):
    """(A, r, v, ω) where a floating base starts, from ``base`` (None: no table given).

    ``position`` and ``orientation`` (unit quaternion [w, x, y, z]) or ``euler_zxz`` place
    the root link frame in the world (default: the URDF's world frame); ``velocity`` is the
    global velocity of its origin and ``angular_velocity`` the global angular velocity
    (default zero).  Refused without ``floating_base`` (a welded root cannot move) and
    for unknown keys or malformed values, naming the key.
    """
    if base is None:
        return None
    where = f"URDF '{robot}': base"
    if not isinstance(base, Mapping):
        raise SceneError(f"{where}: expected a table of {', '.join(BASE_KEYS)}")
    if not floating_base:
        raise SceneError(f"{where}: the start of the base needs floating_base = true (a "
                         "welded root stays at the world frame)")
    unknown = sorted(set(base) - set(BASE_KEYS))
    if unknown:
        raise SceneError(f"{where}: unknown key '{unknown[0]}' (keys: {', '.join(BASE_KEYS)})")
    if "orientation" in base and "euler_zxz" in base:
        raise SceneError(f"{where}: give 'orientation' or 'euler_zxz', not both")

    def vec(key: str, n: int, default) -> np.ndarray:
        value = base.get(key, default)
        try:
            out = np.array(value, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            out = np.zeros(0)
        if out.shape != (n,) or not np.all(np.isfinite(out)):
            raise SceneError(f"{where} key '{key}': expected {n} finite numbers, got {value!r}")
        return out

    if "euler_zxz" in base:
        quat = np.asarray(euler_zxz_to_quaternion(*vec("euler_zxz", 3, None)), float)
    else:
        quat = vec("orientation", 4, (1.0, 0.0, 0.0, 0.0))
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > 1e-3:
            raise SceneError(f"{where} key 'orientation': expected a unit quaternion [w, x, y, "
                             f"z], got norm {norm:.6g}")
        quat = quat / norm
    return (rotation_matrix(quat), vec("position", 3, (0.0, 0.0, 0.0)),
            vec("velocity", 3, (0.0, 0.0, 0.0)), vec("angular_velocity", 3, (0.0, 0.0, 0.0)))


def resolve_mesh(uri: str, source: str) -> str | None:
    """The file of a mesh filename of a URDF read from ``source`` (its path; a text without a
    file resolves against the working folder), or None when it cannot be found.

    ``package://NAME/REST``: the first of the URDF's folder and its parents that is the
    package folder ``NAME`` itself, or holds a folder ``NAME``, with ``REST`` there (as ROS
    finds a package in a workspace); ``file://PATH``: that path; otherwise a path relative to
    the URDF's folder (or absolute).  Nothing is opened here (the view reads the file,
    bounded, :mod:`casmbd.viz.meshes`).
    """
    base = (Path(source).resolve().parent if source and not source.startswith("<")
            else Path.cwd())
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        if not package or not rest:
            return None
        rest_path = Path(urllib.parse.unquote(rest))
        if rest_path.is_absolute() or ".." in rest_path.parts:
            return None
        for folder in (base, *base.parents):
            for root in ((folder,) if folder.name == package else ()) + (folder / package,):
                candidate = root / rest_path
                if candidate.exists():
                    return str(candidate)
        return None
    if uri.startswith("file://"):
        return urllib.parse.unquote(uri[len("file://"):]) or None
    path = Path(uri)
    return str(path if path.is_absolute() else base / path)


def _body_visuals(robot: Robot, group: dict, design: dict, frames: dict) -> dict:
    """Body (or ``"ground"``) → its links' visuals posed in the body frame (module
    docstring)."""
    out: dict[str, list[Visual]] = {}
    for lname, link in robot.links.items():
        if not link.visuals:
            continue
        body = group[lname]
        rot_l, pos_l = design[lname]
        rot_b, com = frames[body]
        for k, vis in enumerate(link.visuals):
            filename = resolve_mesh(vis.filename, robot.source) if vis.kind == "mesh" else None
            out.setdefault(body, []).append(Visual(
                vis.kind, tuple(float(x) for x in vis.size),
                rot_b.T @ (pos_l + rot_l @ vis.origin - com), rot_b.T @ rot_l @ vis.rotation,
                filename, vis.filename, np.asarray(vis.scale, float).copy(),
                None if vis.rgba is None else tuple(float(c) for c in vis.rgba),
                vis.name or f"{lname}.visual{k + 1}", lname))
    return {body: tuple(v) for body, v in out.items()}


def _add_damping(robot: Robot, mech: Mechanism, locked: Mapping, damping: bool,
                 friction: bool) -> None:
    """Viscous damping −d q̇ and smooth Coulomb friction −F_c tanh(q̇ / v_s) of the
    ``<dynamics>`` of each moving joint as ``joint_friction`` elements."""
    for joint in robot.order():
        d = joint.dynamics.get("damping", 0.0) if damping else 0.0
        f = joint.dynamics.get("friction", 0.0) if friction else 0.0
        if (d <= 0.0 and f <= 0.0) or joint.name in locked or joint.type not in MOVING:
            continue
        suffix = "damping" if damping else "friction"
        mech.add("joint_friction", f"{joint.name}_{suffix}", joint.name, damping=d,
                 friction=f)


def loads_urdf(text: str, source: str = "<string>", **options) -> Mechanism:
    """:func:`load_urdf` from URDF text."""
    from_count = len(text.encode("utf-8", "replace"))
    if from_count > MAX_SCENE_BYTES:
        raise LimitError(f"URDF '{source}': {format_bytes(from_count)} exceeds the limit of "
                         f"{format_bytes(MAX_SCENE_BYTES)} (casmbd.limits.MAX_SCENE_BYTES)")
    return build_mechanism(parse_urdf(text, source), **options)


def load_urdf(path: str | os.PathLike, coordinates: str = "joint",
              locked: Mapping[str, float] | None = None,
              initial: Mapping[str, float | Sequence[float]] | None = None,
              damping: bool = False, gravity: Sequence[float] = GRAVITY,
              name: str | None = None, friction: bool = False, inertia: str = "check",
              links: Mapping[str, Mapping] | None = None,
              ignore_mimic: bool | Sequence[str] = False,
              floating_base: bool = False, base: Mapping | None = None) -> Mechanism:
    """Build a spatial :class:`Mechanism` from a URDF file.

    Parameters
    ----------
    path : path-like
        The ``.urdf`` file (XML; DOCTYPE/ENTITY declarations are refused).
    coordinates : {"joint", "absolute", "natural"}
        The mechanism's default coordinates.
    locked : dict, optional
        Joint name → position: the joint is welded at that value (merged like a fixed joint).
    initial : dict, optional
        Joint name → position or (position, velocity): the initial state, in every coordinate
        choice (the bodies start at the forward kinematics of the tree at these values; the
        joint coordinates stay zero at the URDF zero).
    damping : bool
        Apply ``<dynamics damping>`` of revolute, continuous and prismatic joints as viscous
        joint forces −d q̇ (a ``joint_friction`` element per joint).
    gravity : 3 floats
        Default (0, 0, −9.81).
    name : str, optional
        Mechanism name, default the robot's.
    friction : bool
        Apply ``<dynamics friction>`` as smooth Coulomb joint forces −F_c tanh(q̇ / v_s),
        v_s = 1e-3 rad/s or m/s (:mod:`casmbd.model.joint_friction`).
    inertia : {"check", "repair"}
        A link inertia that no rigid body has (not positive semi-definite, or violating the
        triangle inequalities): refused (``"check"``) or replaced by the nearest physical
        tensor with a warning naming the change (``"repair"``;
        :func:`casmbd.io.urdf_checks.nearest_physical_inertia`).
    links : dict, optional
        Link name → ``{"mass": kg, "com": [x, y, z], "inertia": [Ixx, Iyy, Izz(, Ixy, Ixz,
        Iyz)]}`` replacing the file's ``<inertial>`` values (centre of mass in the link frame,
        inertia about it in the link axes); keys left out keep the file's values.
    ignore_mimic : bool or list of str
        Ignore every ``<mimic>`` (True) or those of the named follower joints: each becomes an
        independent joint, with a warning.
    floating_base : bool
        The root link (with the links fixed to it) is a free body instead of being welded to
        the ground: its coordinates are the position of the root link frame's origin and the
        unit quaternion [w, x, y, z] of its axes (a floating root in joint coordinates; the
        per-call API's free-flyer velocity, :mod:`casmbd.compiled.free_flyer`), starting at
        the URDF's world frame unless ``base`` says otherwise.
    base : dict, optional
        With ``floating_base``: where the base starts, ``{"position": [x, y, z],
        "orientation": [w, x, y, z]`` (or ``"euler_zxz": [φ, θ, ψ]``), ``"velocity": [...],
        "angular_velocity": [...]}`` — the root link frame's origin and axes in the world,
        the global velocity of that origin and the global angular velocity (defaults: the
        world frame, at rest; :func:`base_start`).  Every link starts carried with it (joint
        values from ``initial``), in every coordinate choice.

    Raises
    ------
    SceneError
        Unreadable or malformed files, unknown or malformed content (naming link/joint and
        attribute), unsupported features (``initial``/``locked`` values of planar or floating
        joints), a mimic follower given alone or inconsistent with its leader (naming both
        joints and the values), an impossible inertia (naming the link), a ``<mimic>`` of an
        unknown joint, no moving body (:mod:`casmbd.io.urdf_checks`).

    Warns
    -----
    RuntimeWarning
        A repaired inertia, an ignored ``<mimic>``, a link renamed from ``ground``, a revolute
        joint without ``<limit>``, massless end links (:mod:`casmbd.io.urdf_checks`).
    """
    path = Path(path)
    text = read_text(path, "URDF")
    return loads_urdf(text, str(path), coordinates=coordinates, locked=locked,
                      initial=initial, damping=damping, gravity=gravity, name=name,
                      friction=friction, inertia=inertia, links=links,
                      ignore_mimic=ignore_mimic, floating_base=floating_base, base=base)


def urdf_scene(data: dict, source: str, name: str, coordinates: str, gravity) -> Mechanism:
    """The mechanism of a scene's ``[scene] urdf = "path"`` (relative to the scene file) with
    optional ``[scene.initial]``, ``[scene.locked]`` (joint name = value), ``damping``,
    ``friction``, ``inertia`` ("check" or "repair"), ``ignore_mimic`` (true or a list of joint
    names), ``floating_base``, ``[scene.base]`` (the floating base's start: ``position``,
    ``orientation`` or ``euler_zxz``, ``velocity``, ``angular_velocity``) and
    ``[scene.links.NAME]`` (``mass``, ``com``, ``inertia``: :func:`load_urdf`)."""
    if gravity is None:
        raise SceneError("[scene] key 'dimension': a scene with 'urdf' is spatial "
                         "(dimension = 3)")
    rel = data["urdf"]
    if not isinstance(rel, str) or not rel:
        raise SceneError(f"[scene] key 'urdf': expected a file path, got {rel!r}")
    base = Path(source).parent if source and not source.startswith("<") else Path(".")
    tables = {}
    for key in ("initial", "locked"):
        table = data.get(key, {})
        if not isinstance(table, dict):
            raise SceneError(f"[scene.{key}]: expected a table of joint name = value")
        tables[key] = table
    switches = {}
    for key in ("damping", "friction", "floating_base"):
        switches[key] = data.get(key, False)
        if not isinstance(switches[key], bool):
            raise SceneError(f"[scene] key '{key}': expected true or false, got "
                             f"{switches[key]!r}")
    links = data.get("links", {})
    if not isinstance(links, dict):
        raise SceneError("[scene.links]: expected tables [scene.links.NAME] of mass, com, "
                         "inertia")
    try:
        return load_urdf(base / rel, coordinates=coordinates, locked=tables["locked"],
                         initial=tables["initial"], damping=switches["damping"],
                         gravity=gravity, name=name, friction=switches["friction"],
                         inertia=data.get("inertia", "check"), links=links,
                         ignore_mimic=data.get("ignore_mimic", False),
                         floating_base=switches["floating_base"], base=data.get("base"))
    except SceneError as exc:
        raise SceneError(f"[scene] key 'urdf' ('{rel}'): {exc}") from None
