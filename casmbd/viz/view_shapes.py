"""The static geometry of the 3-D view (:mod:`casmbd.viz.view_model`): shapes fixed in the
bodies, joint and marker frames, contact planes, and the force arrows on the grid.

Shapes, per rigid body (colour of the body's index in a ten-colour cycle):

* its URDF ``<visual>`` elements (:class:`casmbd.model.visuals.Visual`, kept by
  :mod:`casmbd.io.urdf`): boxes, cylinders, spheres, and meshes loaded by
  :func:`casmbd.viz.meshes.load_mesh`; a mesh file that does not load is named in a warning
  and the body falls back to the derived shapes below (the view still opens);
* otherwise shapes derived from the scene: a sphere of the radius of each contact sphere on
  the body (plane and sphere contacts, impact or compliant); rods (capsules of radius
  :data:`ROD_RADIUS` × the length scale) joining the body's attachment points (joints,
  markers, force elements) in the order of the 2-D stick figures
  (:class:`casmbd.viz.geometry.Geometry`); and, for a body without a contact sphere, its
  inertia: in space the *equivalent-inertia box* of the body's mass m in principal axes,

      l_1 = √(6 (I_2 + I_3 − I_1) / m)   (and cyclically),

  the homogeneous box with the same principal moments, I_1 = m (l_2² + l_3²) / 12 (a box edge
  below :data:`MIN_BOX_RATIO` of the longest, a thin rod's, is drawn at that ratio); in the
  plane, for a body with fewer than two distinct attachment points, the disc (cylinder along
  z) of the same polar moment, r = √(2 I / m).

Flexible bodies get no shape: they are drawn through their deformed nodes.
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np

from casmbd.errors import CasmbdError
from casmbd.model.bodies import GROUND
from casmbd.model.contacts import PlaneContact, Unilateral
from casmbd.model.inertia import inertia_tensor
from casmbd.model.rotations import rotation_matrix
from casmbd.model.spatial_joints import triad
from casmbd.model.values import numeric
from casmbd.viz.geometry import Geometry, point_trajectory
from casmbd.viz.meshes import load_mesh
from casmbd.viz.view_types import Frame, Plane, Shape

#: rod radius as a fraction of the view's length scale
ROD_RADIUS = 0.012
#: the shortest edge of an inertia box relative to its longest (thin rods stay visible)
MIN_BOX_RATIO = 0.05
#: body colours (matplotlib's tab10, RGB 0..255)
PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
           (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


def _quat(rot: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of one 3x3 rotation (Shepperd, as in :mod:`casmbd.viz.view_model`)."""
    m = np.asarray(rot, float)
    cand = [1 + m[0, 0] + m[1, 1] + m[2, 2], 1 + m[0, 0] - m[1, 1] - m[2, 2],
            1 - m[0, 0] + m[1, 1] - m[2, 2], 1 - m[0, 0] - m[1, 1] + m[2, 2]]
    k = int(np.argmax(cand))
    s = 2.0 * math.sqrt(max(cand[k], 1e-300))
    if k == 0:
        q = [s / 4, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif k == 1:
        q = [(m[2, 1] - m[1, 2]) / s, s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif k == 2:
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s]
    else:
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def _pad(u) -> np.ndarray:
    u = np.asarray(u, float).reshape(-1)
    return np.concatenate([u, [0.0]]) if u.size == 2 else u.copy()


def _z_to(direction: np.ndarray) -> np.ndarray:
    """A rotation (3x3) whose z column is the unit ``direction``."""
    f, g, h = triad(direction)
    return np.column_stack([f, g, h])


def _initial_rotation(frame) -> np.ndarray:
    """The 3x3 design-pose rotation of a body or node frame (plane: about z by its angle)."""
    rot = getattr(frame, "initial_rotation", None)
    if rot is not None and np.shape(rot) == (3, 3):
        return np.asarray(rot, float)
    angle = float(getattr(frame, "angle", 0.0))
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _frame(mech, name: str):
    """The body or node frame ``name`` of ``mech`` (None for the ground)."""
    if name == GROUND:
        return None
    if name in mech.bodies:
        return mech.bodies[name]
    return mech.node_frame(name)


def _local(mech, name: str, point) -> np.ndarray:
    """Body-frame (3,) of a global design-pose point on ``name`` (the point itself on the
    ground)."""
    frame = _frame(mech, name)
    return _pad(point) if frame is None else _pad(frame.local(np.asarray(point, float)))


def _number(value, mech, where: str) -> float | None:
    try:
        return float(numeric(value, dict(mech.parameters), where))
    except (CasmbdError, TypeError, ValueError):
        return None


# ---------------------------------------------------------------------- shapes
def _contact_elements(mech) -> list:
    """Plane and sphere contacts of ``mech``: its unilateral elements and the elements of its
    compliant contact forces."""
    out = list(getattr(mech, "contacts", {}).values())
    out += [f.element for f in mech.forces.values()
            if isinstance(getattr(f, "element", None), Unilateral)]
    return out


def _contact_spheres(mech, length: float) -> list[Shape]:
    out = []
    for c in _contact_elements(mech):
        pairs = c.spheres()  # each contact shape names the spheres it draws
        for k, (body, point, radius) in enumerate(pairs):
            if body != GROUND and body in mech.bodies and _is_flexible(mech.bodies[body]):
                continue
            r = float(radius) if radius and radius > 0 else 0.02 * length
            name = c.name if len(pairs) == 1 else f"{c.name}.{k + 1}"
            out.append(Shape(name, body, "sphere", (r,), _local(mech, body, point),
                             source="contact"))
    return out


def _is_flexible(body) -> bool:
    return getattr(body, "drawing", "polyline") == "nodes"


def _rods(body: str, geo: Geometry, radius: float) -> list[Shape]:
    """Capsules between consecutive attachment points of the stick-figure outline."""
    pts = geo.points.get(body, [])
    order = geo.outline.get(body, [])
    out = []
    for a, b in itertools.pairwise(order):
        if geo.frames[body][a] != body or geo.frames[body][b] != body:
            continue
        ua, ub = _pad(pts[a][1]), _pad(pts[b][1])
        d = ub - ua
        length = float(np.linalg.norm(d))
        if length <= 1e-9:
            continue
        out.append(Shape(f"{body}.rod{len(out) + 1}", body, "capsule", (radius, length),
                         0.5 * (ua + ub), _quat(_z_to(d / length)), source="joints"))
    return out


def inertia_box(body, mech) -> Shape | None:
    """The equivalent-inertia box of a spatial rigid body (module docstring), or None when
    its mass or inertia is zero or not a number."""
    where = f"body '{body.name}'"
    mass = _number(body.mass, mech, f"{where} field 'mass'")
    values = [_number(v, mech, f"{where} field 'inertia'") for v in body.inertia]
    if mass is None or mass <= 0.0 or any(v is None for v in values):
        return None
    try:
        tensor = inertia_tensor(values)
    except CasmbdError:
        return None
    moments, axes = np.linalg.eigh(tensor)
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    total = float(np.sum(moments))
    if total <= 0.0:
        return None
    sizes = np.array([math.sqrt(max(6.0 * (total - 2.0 * moments[i]) / mass, 0.0))
                      for i in range(3)])
    sizes = np.maximum(sizes, MIN_BOX_RATIO * sizes.max())
    return Shape(f"{body.name}.inertia", body.name, "box", tuple(float(x) for x in sizes),
                 np.zeros(3), _quat(axes), source="inertia")


def inertia_disc(body, mech, length: float) -> Shape | None:
    """The disc of a planar body's polar moment: r = √(2 I / m), along z."""
    where = f"body '{body.name}'"
    mass = _number(body.mass, mech, f"{where} field 'mass'")
    inertia = _number(body.inertia, mech, f"{where} field 'inertia'")
    if mass is None or inertia is None or mass <= 0.0 or inertia <= 0.0:
        return Shape(f"{body.name}.point", body.name, "sphere", (0.03 * length,),
                     source="inertia")
    r = math.sqrt(2.0 * inertia / mass)
    return Shape(f"{body.name}.inertia", body.name, "cylinder", (r, 0.2 * r), source="inertia")


def visual_shapes(body: str, visuals, notes: list[str],
                  color: tuple[int, int, int] = (160, 160, 170)) -> list[Shape] | None:
    """The shapes of a body's URDF visuals; None when a mesh does not load (the reason, naming
    the file, appended to ``notes``: the body then takes the derived shapes)."""
    out = []
    default = color
    for k, vis in enumerate(visuals):
        color, opacity = default, 1.0
        if vis.rgba is not None:
            color = tuple(round(255 * min(max(c, 0.0), 1.0)) for c in vis.rgba[:3])
            opacity = float(min(max(vis.rgba[3], 0.0), 1.0))
        name = vis.name or f"visual{k + 1}"
        name = name if name.startswith(f"{body}.") else f"{body}.{name}"
        wxyz = _quat(vis.rotation)
        if vis.kind == "mesh":
            try:
                vertices, faces = load_mesh(vis.filename, vis.scale, vis.uri)
            except CasmbdError as exc:
                instead = ("not drawn" if body == GROUND else
                           "the body is drawn with the shapes derived from the scene")
                notes.append(f"body '{body}': {exc}; {instead}")
                return None
            out.append(Shape(name, body, "mesh", (), vis.position.copy(), wxyz, color,
                             vertices, faces, "urdf-visual", opacity))
        else:
            out.append(Shape(name, body, vis.kind, tuple(vis.size), vis.position.copy(), wxyz,
                             color, source="urdf-visual", opacity=opacity))
    return out


def shapes(mech, geo: Geometry, vm) -> list[Shape]:
    """Every shape of the view (module docstring)."""
    length = vm.length_scale
    visuals = getattr(mech, "visuals", {}) or {}
    spheres = _contact_spheres(mech, length)
    known = len(vm.notes)
    out = [s for s in spheres if s.body == GROUND]
    if visuals.get(GROUND):  # links welded to the ground (a robot's base)
        out += visual_shapes(GROUND, visuals[GROUND], vm.notes) or []
    for i, (name, body) in enumerate(mech.bodies.items()):
        if _is_flexible(body):
            continue
        color = PALETTE[i % len(PALETTE)]
        own = (visual_shapes(name, visuals[name], vm.notes, color) if visuals.get(name)
               else None)
        if not own:
            own = [s for s in spheres if s.body == name]
            rods = _rods(name, geo, ROD_RADIUS * length)
            own += rods
            if not any(s.source == "contact" for s in own):
                if geo.dimension == 3:
                    box = inertia_box(body, mech)
                    if box is not None:
                        box.opacity = 0.6 if rods else 1.0
                        own.append(box)
                elif not rods:
                    own.append(inertia_disc(body, mech, length))
            for s in own:
                s.color = color
        out += own
    failed = vm.notes[known:]
    if failed:  # one warning for the view, however many meshes failed
        more = f" (and {len(failed) - 3} more)" if len(failed) > 3 else ""
        warnings.warn(f"{len(failed)} visual(s) not drawn as given: "
                      + " | ".join(failed[:3]) + more, RuntimeWarning, stacklevel=3)
    return out


# ---------------------------------------------------------------------- frames
def frames(mech, geo: Geometry) -> list[Frame]:
    """A frame per joint with a point (z along its axis when it has one: revolute,
    prismatic, cylindrical; a planar revolute joint's axis is z) and per marker (its own
    orientation, else its body's).  The body axes themselves are the renderer's (every body
    is a frame of the scene at its centre of mass)."""
    out = []
    for name, (on, u) in geo.joints.items():
        joint = mech.joints[name]
        axis = getattr(joint, "axis", None)
        if axis is None and geo.dimension == 2 and getattr(joint, "drawing", "") == "point":
            axis = (0.0, 0.0, 1.0)
        frame = _frame(mech, on)
        base = np.eye(3) if frame is None else _initial_rotation(frame)
        local_axis = None
        rot = np.eye(3)
        if axis is not None:
            a = _pad(axis)
            norm = float(np.linalg.norm(a))
            if norm > 0.0:
                local_axis = base.T @ (a / norm)
                rot = _z_to(local_axis)
        out.append(Frame(name, on, _pad(u), _quat(rot), local_axis, "joint"))
    for name, marker in mech.markers.items():
        frame = _frame(mech, marker.body)
        if frame is None:
            offset = np.eye(3) if marker.orientation is None or geo.dimension == 2 else None
            if offset is None:
                offset = rotation_matrix(marker.orientation)
        else:
            offset = marker.offset(frame)
        if np.ndim(offset) == 0:  # plane: an angle about z
            c, s = math.cos(float(offset)), math.sin(float(offset))
            offset = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        out.append(Frame(name, marker.body, _local(mech, marker.body, marker.point),
                         _quat(np.asarray(offset, float)), None, "marker"))
    return out


def planes(mech, length: float) -> list[Plane]:
    """The ground planes of the plane contacts, each drawn once (contacts on the same plane
    share it), half-size the length scale."""
    out: list[Plane] = []
    for c in _contact_elements(mech):
        if not isinstance(c, PlaneContact):
            continue
        point, normal = _pad(c.origin), _pad(c.normal)
        normal = normal / np.linalg.norm(normal)
        if any(np.allclose(p.normal, normal, atol=1e-12)
               and abs(float(np.dot(p.normal, point - p.point))) <= 1e-12 * max(1.0, length)
               for p in out):
            continue
        out.append(Plane(c.name, point, normal, float(length)))
    return out


# ---------------------------------------------------------------------- forces
def force_arrows(result, mech, geo: Geometry, pos: dict, rot: dict,
                 notes: list[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Application point and force vector (n_t, 3) of the force elements whose reports give
    their force: point forces and expression forces on a body (global components
    ``fx``, ``fy`` (, ``fz``) at their point, the centre of mass without one), and
    spring-damper-actuators (the tension f along the line, as the force on each end:
    f (r_2 − r_1)/|r_2 − r_1| on body1 at r_1 and its opposite on body2 at r_2, keys
    ``<name>@<body>``), and the normal force N n of each plane contact at its touching point
    r_c − r n (the result's ``contact_forces`` of an event-driven run or a statics point, or
    the ``normal_force`` a compliant contact reports; key the contact's name).  Elements
    without a force vector (torques, joint forces) are listed in one line of ``notes``; the
    friction forces of contacts are not drawn."""
    labels = list(result.names.get("force_outputs", []))
    values = result.arrays.get("force_outputs")
    n_t, dim = len(result.t), geo.dimension
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    column = {label: k for k, label in enumerate(labels)}
    without = []
    shown = _contact_arrows(result, mech, pos, rot, column, values, out)
    for name, force in mech.forces.items():
        if name in shown:
            continue
        comps = [f"{name}.f{a}" for a in "xyz"[:dim]]
        body = getattr(force, "body", None)
        if values is not None and all(c in column for c in comps) and body not in (None, GROUND):
            point = getattr(force, "point", None)
            u = np.zeros(dim) if point is None else _frame(mech, body).local(
                np.asarray(point, float))
            where = point_trajectory(pos, rot, body, u, n_t)
            vec = values[:, [column[c] for c in comps]]
            out[name] = (_pad3(where), _pad3(vec))
            continue
        if values is not None and f"{name}.force" in column and hasattr(force, "point1") \
                and hasattr(force, "body1"):
            link = next((lk for lk in geo.links if lk[0] == name), None)
            if link is not None:
                _, b1, u1, b2, u2, _ = link
                r1 = point_trajectory(pos, rot, b1, u1, n_t)
                r2 = point_trajectory(pos, rot, b2, u2, n_t)
                d = r2 - r1
                dist = np.linalg.norm(d, axis=1, keepdims=True)
                unit = np.divide(d, dist, out=np.zeros_like(d), where=dist > 0)
                tension = values[:, column[f"{name}.force"]][:, None]
                for b, r, sign in ((b1, r1, 1.0), (b2, r2, -1.0)):
                    if b != GROUND:
                        out[f"{name}@{b}"] = (_pad3(r), _pad3(sign * tension * unit))
                continue
        without.append(name)
    if without:
        notes.append("forces: no arrow for " + ", ".join(without) + " (torques and forces "
                     "along a joint coordinate have no point of application"
                     + ("; this result holds no force reports" if values is None else "")
                     + ")")
    return out


def _contact_arrows(result, mech, pos, rot, column, values, out) -> set[str]:
    """Normal-force arrows of plane contacts into ``out``; the names of the force elements
    (compliant contacts) drawn."""
    n_t = len(result.t)
    stored = result.arrays.get("contact_forces")
    names = list(result.names.get("contacts", []))
    compliant = {f.element.name: name for name, f in mech.forces.items()
                 if isinstance(getattr(f, "element", None), PlaneContact)}
    shown = set()
    for c in _contact_elements(mech):
        if not isinstance(c, PlaneContact) or c.body not in mech.bodies \
                or _is_flexible(mech.bodies[c.body]):
            continue
        if stored is not None and c.name in names and stored.shape[1] == len(names):
            normal_force = stored[:, names.index(c.name)]
        elif values is not None and f"{compliant.get(c.name)}.normal_force" in column:
            normal_force = values[:, column[f"{compliant[c.name]}.normal_force"]]
            shown.add(compliant[c.name])
        else:
            continue
        n = np.asarray(c.normal, float)
        centre = point_trajectory(pos, rot, c.body, mech.bodies[c.body].local(c.point), n_t)
        out[c.name] = (_pad3(centre - float(c.radius) * n),
                       _pad3(normal_force[:, None] * n[None, :]))
    return shown


def _pad3(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, float)
    if a.shape[-1] == 3:
        return a.copy()
    return np.concatenate([a, np.zeros((*a.shape[:-1], 1))], axis=-1)
