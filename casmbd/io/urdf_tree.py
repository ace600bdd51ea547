"""URDF reading: the defensive XML parse into links and joints, frames and the fixed-joint merge.

The loader (:mod:`casmbd.io.urdf`) builds a :class:`~casmbd.model.Mechanism` from these.
Conventions of the URDF specification (wiki.ros.org/urdf/XML):

* ``<origin xyz rpy>``: the child frame in the parent frame, T = (R, p) with
  R = Rz(yaw) Ry(pitch) Rx(roll) (fixed-axis X-Y-Z);
* ``<axis xyz>`` (default 1 0 0) in the joint frame, which is the child link's frame;
* ``<inertial>``: mass, the centre-of-mass frame ``<origin>`` in the link frame and the inertia
  tensor ``ixx ixy ixz iyy iyz izz`` about the centre of mass in that frame (tensor elements:
  ixy = −∫xy dm), so in link axes I_link = R I Rᵀ;
* ``<visual>``: an ``<origin>`` in the link frame, one ``<geometry>`` (``box size``,
  ``cylinder radius length`` along z, ``sphere radius``, ``mesh filename scale``) and an optional
  ``<material>`` (inline ``<color rgba>``, or a name defined by a top-level ``<material>``); kept
  as :class:`LinkVisual` for the 3-D view.  A visual that cannot be read (no or an unknown
  geometry, a malformed attribute) is left out with a warning naming the link: it changes
  nothing that is computed.  ``<collision>`` elements are counted and not used.

The merge of rigidly joined links into one body adds masses, centres of mass
c = Σ mᵢ cᵢ / Σ mᵢ and inertia tensors (global axes) by the parallel-axis theorem
I = Σ [Rᵢ Iᵢ Rᵢᵀ + mᵢ (|dᵢ|² 1 − dᵢ dᵢᵀ)], dᵢ = cᵢ − c.
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import SceneError
from casmbd.limits import MAX_BODIES, MAX_ELEMENTS, check_count

#: joint types of the URDF specification
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: joint types with one coordinate
MOVING = ("revolute", "continuous", "prismatic")


def rpy_matrix(rpy) -> np.ndarray:
    """R = Rz(y) Ry(p) Rx(r): URDF's fixed-axis roll-pitch-yaw."""
    r, p, y = (float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), \
        math.cos(y), math.sin(y)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def axis_rotation(axis, angle: float) -> np.ndarray:
    """Rodrigues: rotation by ``angle`` about the unit ``axis``."""
    k = np.asarray(axis, float)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * kx @ kx


@dataclass
class LinkVisual:
    """A URDF ``<visual>``: its frame (R, p) in the link frame, the geometry kind and size
    (box (lx, ly, lz), cylinder (radius, length), sphere (radius,), mesh ()), a mesh's
    filename as written and scale, the material colour (rgba 0..1) and the name."""

    rotation: np.ndarray
    origin: np.ndarray
    kind: str
    size: tuple = ()
    filename: str = ""
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    rgba: tuple | None = None
    name: str = ""


@dataclass
class Link:
    """A URDF link: mass, centre of mass and inertia tensor (about it) in link axes, and its
    visuals."""

    name: str
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    visuals: list[LinkVisual] = field(default_factory=list)


@dataclass
class UrdfJoint:
    """A URDF joint: the child frame in the parent frame at q = 0, the axis in the child frame."""

    name: str
    type: str
    parent: str
    child: str
    rotation: np.ndarray
    origin: np.ndarray
    axis: np.ndarray
    limits: dict = field(default_factory=dict)
    dynamics: dict = field(default_factory=dict)
    mimic: tuple[str, float, float] | None = None

    def motion(self, value: float) -> tuple[np.ndarray, np.ndarray]:
        """(R, p) of the child in the parent frame at joint position ``value``."""
        if self.type == "prismatic":
            return self.rotation, self.origin + self.rotation @ (self.axis * value)
        if self.type in ("revolute", "continuous"):
            return self.rotation @ axis_rotation(self.axis, value), self.origin
        return self.rotation, self.origin


@dataclass
class Robot:
    """The parsed URDF: links, joints (in file order), the root link, the number of
    ``<collision>`` elements (not used) and the source (the file's path, for the visuals'
    relative mesh filenames)."""

    name: str
    links: dict[str, Link]
    joints: dict[str, UrdfJoint]
    root: str
    collisions: int = 0
    source: str = ""

    def parent_joint(self) -> dict[str, UrdfJoint]:
        return {j.child: j for j in self.joints.values()}

    def order(self) -> list[UrdfJoint]:
        """Joints from the root outwards (breadth first)."""
        children: dict[str, list[UrdfJoint]] = {}
        for joint in self.joints.values():
            children.setdefault(joint.parent, []).append(joint)
        out, queue = [], [self.root]
        while queue:
            link = queue.pop(0)
            for joint in children.get(link, []):
                out.append(joint)
                queue.append(joint.child)
        return out

    def frames(self, values: dict[str, float]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Global (R, p) of every link frame with joint positions ``values`` (default 0)."""
        poses = {self.root: (np.eye(3), np.zeros(3))}
        for joint in self.order():
            rot_p, pos_p = poses[joint.parent]
            rot, pos = joint.motion(values.get(joint.name, 0.0))
            poses[joint.child] = (rot_p @ rot, pos_p + rot_p @ pos)
        return poses


# ---------------------------------------------------------------------- parsing
def _numbers(elem, attr: str, count: int, where: str, default=None) -> np.ndarray:
    text = elem.get(attr) if elem is not None else None
    if text is None:
        if default is None:
            raise SceneError(f"{where}: missing attribute '{attr}'")
        return np.array(default, float)
    try:
        vals = np.array([float(x) for x in text.split()], float)
    except ValueError:
        raise SceneError(f"{where} attribute '{attr}': expected {count} numbers, got "
                         f"{text[:60]!r}") from None
    if vals.size != count or not np.all(np.isfinite(vals)):
        raise SceneError(f"{where} attribute '{attr}': expected {count} finite numbers, got "
                         f"{text[:60]!r}")
    return vals


def _number(elem, attr: str, where: str, default: float | None = None) -> float:
    return float(_numbers(elem, attr, 1, where, None if default is None else [default])[0])


def _origin(elem, where: str) -> tuple[np.ndarray, np.ndarray]:
    origin = elem.find("origin")
    where = f"{where} <origin>"
    return (rpy_matrix(_numbers(origin, "rpy", 3, where, [0.0, 0.0, 0.0])),
            _numbers(origin, "xyz", 3, where, [0.0, 0.0, 0.0]))


def _name(elem, what: str, index: int) -> str:
    name = elem.get("name")
    if not name:
        raise SceneError(f"{what} number {index + 1}: missing attribute 'name'")
    return name


def _link(elem, index: int) -> Link:
    name = _name(elem, "<link>", index)
    where = f"link '{name}'"
    inertial = elem.find("inertial")
    if inertial is None:
        return Link(name)
    mass_el = inertial.find("mass")
    if mass_el is None:
        raise SceneError(f"{where} <inertial>: missing <mass>")
    mass = _number(mass_el, "value", f"{where} <mass>")
    if mass < 0.0:
        raise SceneError(f"{where} <mass> attribute 'value': must be >= 0, got {mass}")
    rot, com = _origin(inertial, f"{where} <inertial>")
    ine = inertial.find("inertia")
    if ine is None:
        raise SceneError(f"{where} <inertial>: missing <inertia>")
    vals = {k: _number(ine, k, f"{where} <inertia>") for k in
            ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    tensor = np.array([[vals["ixx"], vals["ixy"], vals["ixz"]],
                       [vals["ixy"], vals["iyy"], vals["iyz"]],
                       [vals["ixz"], vals["iyz"], vals["izz"]]])
    return Link(name, mass, com, rot @ tensor @ rot.T)


def _materials(root) -> dict[str, tuple]:
    """Top-level ``<material name><color rgba/></material>`` definitions: name → rgba."""
    out = {}
    for el in root.findall("material"):
        name, color = el.get("name"), el.find("color")
        if name and color is not None:
            try:
                out[name] = tuple(_numbers(color, "rgba", 4, f"<material '{name}'> <color>"))
            except SceneError as exc:
                warnings.warn(f"URDF: {exc}; the material is not used", RuntimeWarning,
                              stacklevel=4)
    return out


def _visual(elem, where: str, materials: dict) -> LinkVisual:
    """One ``<visual>`` (SceneError naming the element and attribute when malformed)."""
    rot, pos = _origin(elem, where)
    geometry = elem.find("geometry")
    shapes = [] if geometry is None else list(geometry)
    if len(shapes) != 1:
        raise SceneError(f"{where} <geometry>: expected one of box, cylinder, sphere, mesh")
    shape = shapes[0]
    tag = shape.tag
    filename, scale, size = "", np.ones(3), ()
    if tag == "box":
        size = tuple(_numbers(shape, "size", 3, f"{where} <box>"))
    elif tag == "cylinder":
        size = (_number(shape, "radius", f"{where} <cylinder>"),
                _number(shape, "length", f"{where} <cylinder>"))
    elif tag == "sphere":
        size = (_number(shape, "radius", f"{where} <sphere>"),)
    elif tag == "mesh":
        filename = shape.get("filename") or ""
        if not filename:
            raise SceneError(f"{where} <mesh>: missing attribute 'filename'")
        scale = _numbers(shape, "scale", 3, f"{where} <mesh>", [1.0, 1.0, 1.0])
    else:
        raise SceneError(f"{where} <geometry>: unknown geometry <{tag}> (box, cylinder, "
                         "sphere, mesh)")
    if any(x < 0.0 for x in size):
        raise SceneError(f"{where} <{tag}>: sizes must be >= 0, got {list(size)}")
    rgba = None
    material = elem.find("material")
    if material is not None:
        color = material.find("color")
        if color is not None:
            rgba = tuple(_numbers(color, "rgba", 4, f"{where} <material> <color>"))
        else:
            rgba = materials.get(material.get("name", ""))
    return LinkVisual(rot, pos, tag, size, filename, scale, rgba, elem.get("name") or "")


def _visuals(el, name: str, materials: dict) -> list[LinkVisual]:
    """The readable visuals of a link; each unreadable one is left out with a warning."""
    out = []
    for k, vis in enumerate(el.findall("visual")):
        try:
            out.append(_visual(vis, f"link '{name}' <visual> number {k + 1}", materials))
        except SceneError as exc:
            warnings.warn(f"URDF: {exc}; this visual is not drawn", RuntimeWarning,
                          stacklevel=4)
    return out


def _joint(elem, index: int, links: dict) -> UrdfJoint:
    name = _name(elem, "<joint>", index)
    where = f"joint '{name}'"
    kind = elem.get("type")
    if kind not in JOINT_TYPES:
        raise SceneError(f"{where} attribute 'type': unknown joint type {kind!r} (URDF types: "
                         f"{', '.join(JOINT_TYPES)})")
    ends = []
    for tag in ("parent", "child"):
        sub = elem.find(tag)
        link = sub.get("link") if sub is not None else None
        if not link:
            raise SceneError(f"{where} <{tag}>: missing attribute 'link'")
        if link not in links:
            raise SceneError(f"{where} <{tag}> attribute 'link': unknown link '{link}'")
        ends.append(link)
    rot, pos = _origin(elem, where)
    axis = _numbers(elem.find("axis"), "xyz", 3, f"{where} <axis>", [1.0, 0.0, 0.0])
    scale = float(np.max(np.abs(axis)))  # |[1, 1e300]|² overflows: scale first
    norm = scale * float(np.linalg.norm(axis / scale)) if scale > 0 else 0.0
    if kind in (*MOVING, "planar") and norm < 1e-12:
        raise SceneError(f"{where} <axis> attribute 'xyz': zero axis")
    axis = axis / norm if norm > 0 else axis
    limits, dynamics, mimic = {}, {}, None
    lim = elem.find("limit")
    if lim is not None:
        limits = {k: _number(lim, k, f"{where} <limit>", 0.0)
                  for k in ("lower", "upper", "effort", "velocity") if k in lim.attrib}
    if kind == "revolute" and lim is None:  # as Pinocchio: loaded, unlimited
        warnings.warn(f"URDF: {where}: a revolute joint without <limit> (the URDF "
                      "specification requires one) is loaded without limits, like "
                      "'continuous'", RuntimeWarning, stacklevel=4)
    dyn = elem.find("dynamics")
    if dyn is not None:
        dynamics = {k: _number(dyn, k, f"{where} <dynamics>") for k in ("damping", "friction")
                    if k in dyn.attrib}
    mim = elem.find("mimic")
    if mim is not None:
        leader = mim.get("joint")
        if not leader:
            raise SceneError(f"{where} <mimic>: missing attribute 'joint'")
        mimic = (leader, _number(mim, "multiplier", f"{where} <mimic>", 1.0),
                 _number(mim, "offset", f"{where} <mimic>", 0.0))
    return UrdfJoint(name, kind, ends[0], ends[1], rot, pos, axis, limits, dynamics, mimic)


def parse_urdf(text: str, source: str) -> Robot:
    """Parse URDF text defensively.

    Raises
    ------
    SceneError
        A DTD or entity declaration (refused, so no entity expansion), malformed XML, a missing
        or malformed attribute, an unknown joint type, a joint naming an unknown link, a link
        with two parent joints, several roots or a cycle: naming the link/joint and attribute.
    """
    upper = text.upper()
    if "<!DOCTYPE" in upper or "<!ENTITY" in upper:
        raise SceneError(f"{source}: a DOCTYPE or ENTITY declaration is refused in URDF files "
                         "(no entity expansion)")
    try:
        parser = ET.XMLParser()
        parser.feed(text)
        root = parser.close()
    except ET.ParseError as exc:
        raise SceneError(f"{source}: malformed XML: {exc}") from None
    if root.tag != "robot":
        raise SceneError(f"{source}: the root element is <{root.tag}>, expected <robot>")
    link_els, joint_els = root.findall("link"), root.findall("joint")
    check_count(f"{source}: links", len(link_els), MAX_BODIES)
    check_count(f"{source}: joints", len(joint_els), MAX_ELEMENTS)
    links: dict[str, Link] = {}
    collisions = 0
    materials = _materials(root)
    for i, el in enumerate(link_els):
        link = _link(el, i)
        if link.name in links:
            raise SceneError(f"{source}: duplicate link name '{link.name}'")
        link.visuals = _visuals(el, link.name, materials)
        links[link.name] = link
        collisions += len(el.findall("collision"))
    joints: dict[str, UrdfJoint] = {}
    parent_of: dict[str, str] = {}
    for i, el in enumerate(joint_els):
        joint = _joint(el, i, links)
        if joint.name in joints:
            raise SceneError(f"{source}: duplicate joint name '{joint.name}'")
        if joint.child in parent_of:
            raise SceneError(f"joint '{joint.name}' <child> attribute 'link': link "
                             f"'{joint.child}' already has the parent joint "
                             f"'{parent_of[joint.child]}' (a URDF is a tree)")
        parent_of[joint.child] = joint.name
        joints[joint.name] = joint
    if not links:
        raise SceneError(f"{source}: no <link>")
    roots = [n for n in links if n not in parent_of]
    if len(roots) > 1:
        raise SceneError(f"{source}: several root links ({', '.join(roots[:5])}): a URDF has "
                         "exactly one link without a parent joint")
    if not roots:
        raise SceneError(f"{source}: the joints form a cycle (no root link)")
    robot = Robot(root.get("name") or "robot", links, joints, roots[0], collisions, source)
    reached = {robot.root} | {j.child for j in robot.order()}
    if len(reached) != len(links):
        lost = sorted(set(links) - reached)
        raise SceneError(f"{source}: the joints form a cycle through link '{lost[0]}'")
    return robot  # a <mimic> of an unknown joint: casmbd.io.urdf_checks (ignore_mimic)


# ---------------------------------------------------------------------- merging
def merge(parts: list[tuple[float, np.ndarray, np.ndarray]]):
    """Mass, centre of mass and inertia tensor (about it, global axes) of rigidly joined parts.

    ``parts``: (mᵢ, cᵢ, Iᵢ) with Iᵢ about cᵢ in global axes.  Parallel-axis theorem:
    I = Σ [Iᵢ + mᵢ (|dᵢ|² 1 − dᵢ dᵢᵀ)], dᵢ = cᵢ − c, c = Σ mᵢ cᵢ / m.
    """
    mass = sum(m for m, _, _ in parts)
    if mass <= 0.0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = sum(m * c for m, c, _ in parts) / mass
    tensor = np.zeros((3, 3))
    for m, c, inertia in parts:
        d = c - com
        tensor += inertia + m * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, tensor
