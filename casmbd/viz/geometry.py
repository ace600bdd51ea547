"""Where the drawn points of a mechanism are on the time grid of a result (numpy only).

A body is drawn as a polyline through its attachment points: joint points, marker points and
the points of force elements and distance links, all given globally at the design pose in the
scene and turned into body-fixed vectors once, exactly as the model does
(u_P = A₀ᵀ (r_P − r_G0), :meth:`casmbd.model.bodies.Body.local`).  On the grid a point is

    r_P(t) = r_G(t) + A(t) u_P                                   (seed 001 eq. 1)

with r_G the centre of mass (``body_positions``) and A the rotation of the body
(``angle_positions`` in the plane, ``rotation_matrices`` in space) stored in the result.  Joint
points are not stored in a result: :func:`joint_points` computes them this way from the
mechanism (the one given, or the scene text embedded in the result).

Flexible bodies (issue 23, :mod:`casmbd.model.flexible_bodies`, drawing hint ``"nodes"``) are
drawn as the polyline through all their deformed nodes,

    r_i(t) = R(t) + A(t) (u_i0 + s Φ_i η(t))                    (seed 002, eq. 5–26)

with the frame origin R, the rotation A (angle θ in the plane; A(p) of the Euler parameters p
in space, seed 001 eq. 15; in natural coordinates the body axes, A = [u, ẑ × u] or [u v w])
and the modal coordinates η read from the coordinates ``q`` of the result (``"<body>.x"`` …
``"<body>.eta1"`` …), the undeformed node positions u_i0 and the
translational base vectors Φ_i of the body's modal data, and s = 1 (a *deformation scale*
s ≠ 1 magnifies the elastic displacements for a picture).  A point attached to a named node
(``"<body>@<node>"``: joints, forces, the node markers) moves with the node frame: position
r_i and rotation A A(s ψ_i), ψ_i = Ψ_i η the node's small rotation (plane: the angle θ + s ψ_i;
space: A times the rotation of the Euler parameters (1, s ψ_i/2)/|(1, s ψ_i/2)|, the exact
form of :meth:`casmbd.system.floating_frame.FlexibleBody.node_rotation`).  A point attached to a
flexible body itself (not to a node) follows its undeformed frame, as in the model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import AnalysisError, CasmbdError
from casmbd.io.scene import loads_scene
from casmbd.model.bodies import GROUND
from casmbd.model.contacts import PlaneContact, tangents
from casmbd.model.flexible_bodies import is_flexible, node_attachment
from casmbd.system.floating_frame import foreshortening_matrices


@dataclass
class FlexibleShape:
    """What a flexible body is drawn from: arrays of its modal data
    (:class:`casmbd.model.modal.ModalData`).

    Attributes
    ----------
    positions : ndarray, (n_nodes, dim)
        Undeformed node positions u_i0 in the body frame, about the frame origin R [m].
    phi_t : ndarray, (n_nodes, dim, n_modes)
        Translational base vectors Φ_i.
    phi_r : ndarray, (n_nodes, n_modes) plane or (n_nodes, 3, n_modes) space
        Rotational base vectors Ψ_i (small node rotations).
    masses : ndarray, (n_nodes,)
        Lumped nodal masses (the deformed centre of mass Σ m_i r_i / Σ m_i).
    nodes : dict of str to int
        Named nodes → node index.
    foreshortening : ndarray, (n_nodes, n_modes, n_modes), optional
        F_i of the foreshortening d_i = −½ (ηᵀ F_i η) e_x of a body with ``stiffening``
        (:func:`casmbd.system.floating_frame.foreshortening_matrices`); None without.
    """

    positions: np.ndarray
    phi_t: np.ndarray
    phi_r: np.ndarray
    masses: np.ndarray
    nodes: dict[str, int] = field(default_factory=dict)
    foreshortening: np.ndarray | None = None

    @classmethod
    def from_body(cls, body) -> FlexibleShape:
        """The shape of a flexible body of the model layer."""
        modal = body.modal
        shortening = foreshortening_matrices(modal, body.name) \
            if getattr(body, "stiffening", False) else None
        return cls(np.asarray(modal.positions, float), np.asarray(modal.phi_t, float),
                   np.asarray(modal.phi_r, float), np.asarray(modal.masses, float),
                   dict(modal.node_names), shortening)

    def offsets(self, eta: np.ndarray, scale: float = 1.0) -> np.ndarray:
        """u_i0 + s Φ_i η (+ s² d_i(η) with stiffening: the arc length of the magnified
        shape kept) for every node, (n_t, n_nodes, dim)."""
        out = self.positions[None] + scale * np.einsum("ijm,km->kij", self.phi_t, eta)
        if self.foreshortening is not None:
            out[:, :, 0] -= 0.5 * scale**2 * np.einsum("km,iml,kl->ki", eta,
                                                       self.foreshortening, eta)
        return out

    @property
    def n_modes(self) -> int:
        """Number of modal coordinates η."""
        return int(self.phi_t.shape[2])


@dataclass
class Geometry:
    """Body-fixed drawing points of a mechanism.

    Attributes
    ----------
    dimension : int
        2 or 3.
    points : dict of str to list of (str, ndarray)
        Per body, ``(label, u)`` with ``u`` the body-fixed vector from the centre of mass
        (labels ``joint:NAME``, ``marker:NAME``, ``force:NAME``).
    outline : dict of str to list of int
        Per body, the order in which :attr:`points` are joined (the first index repeated at the
        end closes a polygon); empty for a body drawn as its centre of mass alone.
    ground : list of (str, ndarray)
        Fixed global points on the ground (joints and force elements attached to it).
    guides : list of (ndarray, ndarray)
        Point and unit direction of prismatic and cylindrical joints to the ground (drawn as
        dashed slide lines).
    links : list of (str, str, ndarray, str, ndarray, str)
        Force elements and distance links: name, body1, u1, body2, u2 (global points when the
        body is the ground) and the kind (``"spring"`` or ``"link"``).
    joints : dict of str to (str, ndarray)
        Per joint with a point: the body (or node frame) it is drawn on (body2 unless that is
        the ground) and the body-fixed vector of the point (a global point for a joint between
        ground and ground, which does not occur).
    frames : dict of str to list of str
        Per body, the frame each of its :attr:`points` is fixed in: the body, or the node
        frame ``"<body>@<node>"`` of a flexible body (``u`` then in node-frame axes).
    flexible : dict of str to FlexibleShape
        The flexible bodies, drawn through their deformed nodes (their :attr:`outline` is
        empty).
    node_frames : dict of str to (str, int)
        Node frames ``"<body>@<node>"`` → (flexible body, node index).
    """

    dimension: int
    points: dict[str, list[tuple[str, np.ndarray]]] = field(default_factory=dict)
    outline: dict[str, list[int]] = field(default_factory=dict)
    ground: list[tuple[str, np.ndarray]] = field(default_factory=list)
    guides: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    links: list[tuple] = field(default_factory=list)
    joints: dict[str, tuple[str, np.ndarray]] = field(default_factory=dict)
    frames: dict[str, list[str]] = field(default_factory=dict)
    flexible: dict[str, FlexibleShape] = field(default_factory=dict)
    node_frames: dict[str, tuple[str, int]] = field(default_factory=dict)

    @classmethod
    def from_mechanism(cls, mechanism) -> Geometry:
        """Collect the attachment points of every body of ``mechanism``."""
        bodies = mechanism.bodies
        geo = cls(int(mechanism.dimension), {name: [] for name in bodies},
                  frames={name: [] for name in bodies})
        geo.flexible = {name: FlexibleShape.from_body(body) for name, body in bodies.items()
                        if is_flexible(body)}

        def frame(body: str):
            """The body, or the node frame of an attachment name ``body@node``."""
            if body in bodies or node_attachment(body) is None:
                return bodies[body]
            node = mechanism.node_frame(body)
            geo.node_frames[body] = (node.body, int(node.index))
            return node

        def local(body: str, point) -> np.ndarray:
            point = np.asarray(point, float)
            return point if body == GROUND else frame(body).local(point)

        def attach(body: str, label: str, point) -> None:
            if body == GROUND:
                geo.ground.append((label, np.asarray(point, float)))
            else:
                u = local(body, point)
                owner = geo.node_frames[body][0] if body in geo.node_frames else body
                geo.points[owner].append((label, u))
                geo.frames[owner].append(body)

        for name, joint in mechanism.joints.items():  # each kind's ``drawing`` hint
            b1, b2 = joint.body1, joint.body2
            drawing = getattr(joint, "drawing", "point")
            if drawing == "none":
                continue
            if drawing == "link":  # a distance link
                geo.links.append((name, b1, local(b1, joint.point1), b2,
                                  local(b2, joint.point2), "link"))
                attach(b1, f"joint:{name}", joint.point1)
                attach(b2, f"joint:{name}", joint.point2)
                on = b2 if b2 != GROUND else b1
                geo.joints[name] = (on, local(on, joint.point2 if on == b2 else joint.point1))
                continue
            point = getattr(joint, "point", None)
            if point is None:  # a weld without a point
                continue
            axis = getattr(joint, "axis", None)
            sliding = drawing == "slide"
            for body in (b1, b2):
                if not (sliding and body == GROUND):  # a slide is drawn as its guide line
                    attach(body, f"joint:{name}", point)
            on = b2 if b2 != GROUND else b1
            geo.joints[name] = (on, local(on, point))
            if axis is not None and sliding and GROUND in (b1, b2):
                axis = np.asarray(axis, float)
                geo.guides.append((np.asarray(point, float), axis / np.linalg.norm(axis)))
        for name, marker in mechanism.markers.items():
            attach(marker.body, f"marker:{name}", marker.point)
        for name, force in mechanism.forces.items():  # each kind's ``drawing`` hint
            if getattr(force, "drawing", "none") == "spring":
                b1, b2 = force.body1, force.body2
                geo.links.append((name, b1, local(b1, force.point1), b2,
                                  local(b2, force.point2), "spring"))
                attach(b1, f"force:{name}", force.point1)
                attach(b2, f"force:{name}", force.point2)
        for name, contact in getattr(mechanism, "contacts", {}).items():
            # a plane contact: its sphere's centre on the body, the plane as a guide line
            if isinstance(contact, PlaneContact):
                attach(contact.body, f"contact:{name}", contact.point)
                if geo.dimension == 2:
                    geo.guides.append((np.asarray(contact.origin, float),
                                       tangents(contact.normal)[0]))
        for body, pts in geo.points.items():
            geo.outline[body] = [] if body in geo.flexible else _outline([u for _, u in pts])
        return geo


def _outline(points: list[np.ndarray], tol: float = 1e-9) -> list[int]:
    """Order in which to join a body's points: a line along the principal direction when they
    are (nearly) collinear, else a closed polygon ordered by angle about their centroid in
    their best-fit plane (a triangle for a ternary link).  Duplicates are joined once."""
    distinct: list[int] = []
    for k, u in enumerate(points):
        if all(np.linalg.norm(u - points[j]) > tol * max(1.0, np.linalg.norm(u))
               for j in distinct):
            distinct.append(k)
    if len(distinct) < 2:
        return []
    pts = np.array([points[k] for k in distinct])
    centred = pts - pts.mean(axis=0)
    _, sing, vt = np.linalg.svd(centred, full_matrices=False)
    along = centred @ vt[0]
    if len(distinct) == 2 or sing[1] <= 1e-6 * sing[0]:
        return [distinct[k] for k in np.argsort(along)]
    across = centred @ vt[1]
    order = [distinct[k] for k in np.argsort(np.arctan2(across, along))]
    return [*order, order[0]]


def scene_name(result) -> str | None:
    """Name of the mechanism in the scene text embedded in ``result`` (None without one)."""
    if not result.scene:
        return None
    try:
        return result.mechanism(loads_scene).name
    except CasmbdError:
        return None


def body_poses(result) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Centre of mass (n_t, dim) and rotation matrix (n_t, dim, dim) of every body.

    Raises
    ------
    AnalysisError
        When the result holds no body positions or orientations (naming the missing array).
    """
    dim = result.dimension
    needed = ["body_positions", "angle_positions" if dim == 2 else "rotation_matrices"]
    for key in needed:
        if key not in result.arrays:
            raise AnalysisError(f"the {result.kind} result holds no '{key}': cannot place the "
                                "bodies")
    pos, rot = {}, {}
    for i, name in enumerate(result.names["bodies"]):
        pos[name] = result.arrays["body_positions"][:, dim * i:dim * i + dim]
        if dim == 2:
            th = result.arrays["angle_positions"][:, i]
            c, s = np.cos(th), np.sin(th)
            rot[name] = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
        else:
            rot[name] = result.arrays["rotation_matrices"][:, 9 * i:9 * i + 9].reshape(-1, 3, 3)
    return pos, rot


def _rotations(theta: np.ndarray) -> np.ndarray:
    """Plane rotation matrices (n_t, 2, 2) of the angles θ (n_t,)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def _euler_rotations(p: np.ndarray) -> np.ndarray:
    """A(p) (n_t, 3, 3) of Euler parameters p (n_t, 4), not normalised: the formula of
    :func:`casmbd.model.rotations.rotation_matrix` (seed 001, "Transformation matrix",
    eq. 15), A = (2 e0² − 1) I + 2 (e eᵀ + e0 ẽ)."""
    e0, e = p[:, 0], p[:, 1:4]
    skew = np.zeros((len(p), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -e[:, 2], e[:, 1], -e[:, 0]
    skew = skew - np.swapaxes(skew, 1, 2)
    return ((2.0 * e0 * e0 - 1.0)[:, None, None] * np.eye(3)
            + 2.0 * (np.einsum("ki,kj->kij", e, e) + e0[:, None, None] * skew))


#: frame coordinates of a flexible body per dimension: absolute (angle / Euler parameters), then
#: natural (the body axes, seed 003; A = [u, ẑ × u] in the plane, [u v w] in space)
_FRAME_COORDINATES = {2: (("x", "y", "angle"), ("x", "y", "ux", "uy")),
                      3: (("x", "y", "z", "e0", "e1", "e2", "e3"),
                          ("x", "y", "z", "ux", "uy", "uz", "vx", "vy", "vz", "wx", "wy", "wz"))}


def flexible_states(result, geo: Geometry) -> dict[str, tuple[np.ndarray, ...]]:
    """Frame origin R (n_t, dim), rotation A (n_t, dim, dim) and modal coordinates η
    (n_t, n_modes) of every flexible body, read from the result's coordinates ``q`` (absolute
    or natural frame coordinates, :data:`_FRAME_COORDINATES`).

    Raises
    ------
    AnalysisError
        When the result holds no coordinates or lacks one of a flexible body's (naming it).
    """
    if not geo.flexible:
        return {}
    names = list(result.names.get("coordinates", []))
    q = result.arrays.get("q")
    if q is None or not names:
        raise AnalysisError(f"the {result.kind} result holds no coordinates 'q': cannot draw "
                            f"the flexible bodies {', '.join(geo.flexible)}")
    column = {name: k for k, name in enumerate(names)}
    dim = geo.dimension
    states = {}
    for body, shape in geo.flexible.items():
        frame = next((f for f in _FRAME_COORDINATES[dim] if f"{body}.{f[-1]}" in column),
                     _FRAME_COORDINATES[dim][0])
        wanted = [f"{body}.{c}" for c in frame] + [f"{body}.eta{k + 1}"
                                                   for k in range(shape.n_modes)]
        missing = [w for w in wanted if w not in column]
        if missing:
            raise AnalysisError(f"flexible body '{body}': the {result.kind} result has no "
                                f"coordinate '{missing[0]}' (the body's frame and modal "
                                "coordinates are needed to draw its nodes)")
        cols = q[:, [column[w] for w in wanted]]
        n = len(frame)
        if len(frame) == 3:  # plane, absolute: the angle
            rot = _rotations(cols[:, 2])
        elif len(frame) == 4:  # plane, natural: A = [u, ẑ × u]
            u = cols[:, 2:4]
            rot = np.stack([u, np.stack([-u[:, 1], u[:, 0]], axis=1)], axis=2)
        elif len(frame) == 7:  # space, absolute: Euler parameters
            rot = _euler_rotations(cols[:, 3:7])
        else:  # space, natural: A = [u v w]
            rot = cols[:, 3:12].reshape(-1, 3, 3).transpose(0, 2, 1)
        states[body] = (cols[:, 0:dim], rot, cols[:, n:])
    return states


def _node_pose(shape: FlexibleShape, state, index: int, scale: float):
    """Position r_i = R + A (u_i0 + s Φ_i η + s² d_i) (n_t, dim) and rotation (n_t, dim, dim) of
    node ``index`` (module docstring)."""
    ref, rot, eta = state
    offset = shape.positions[index] + scale * eta @ shape.phi_t[index].T
    if shape.foreshortening is not None:
        offset[:, 0] -= 0.5 * scale**2 * np.einsum("km,ml,kl->k", eta,
                                                   shape.foreshortening[index], eta)
    position = ref + np.einsum("kij,kj->ki", rot, offset)
    if shape.positions.shape[1] == 2:
        psi = scale * eta @ shape.phi_r[index]
        return position, np.einsum("kij,kjl->kil", rot, _rotations(psi))
    half = 0.5 * scale * eta @ shape.phi_r[index].T
    p = np.concatenate([np.ones((len(eta), 1)), half], axis=1)
    p = p / np.linalg.norm(p, axis=1, keepdims=True)
    return position, np.einsum("kij,kjl->kil", rot, _euler_rotations(p))


def flexible_nodes(result, geo: Geometry, scale: float = 1.0,
                   states: dict | None = None) -> dict[str, np.ndarray]:
    """Deformed node positions (n_t, n_nodes, dim) of every flexible body of ``geo``,
    r_i = R + A (u_i0 + s Φ_i η + s² d_i) (module docstring; ``scale`` is s; d_i the
    foreshortening with ``stiffening``)."""
    states = flexible_states(result, geo) if states is None else states
    nodes = {}
    for body, shape in geo.flexible.items():
        ref, rot, eta = states[body]
        nodes[body] = ref[:, None, :] + np.einsum("kab,kib->kia", rot, shape.offsets(eta, scale))
    return nodes


def frame_poses(result, geo: Geometry, scale: float = 1.0,
                states: dict | None = None) -> tuple[dict, dict]:
    """:func:`body_poses` and, for every node frame ``"<body>@<node>"`` of ``geo``, the
    deformed node position and node-frame rotation (``scale`` magnifies the deformation)."""
    pos, rot = body_poses(result)
    if geo.node_frames:
        states = flexible_states(result, geo) if states is None else states
        for name, (body, index) in geo.node_frames.items():
            pos[name], rot[name] = _node_pose(geo.flexible[body], states[body], index, scale)
    return pos, rot


def point_trajectory(pos, rot, body: str, u: np.ndarray, n_t: int) -> np.ndarray:
    """r_G + A u on the grid, (n_t, dim); a ground point stays where it is."""
    if body == GROUND:
        return np.broadcast_to(np.asarray(u, float), (n_t, len(u))).copy()
    return pos[body] + np.einsum("kij,j->ki", rot[body], u)


def geometry_of(result, mechanism) -> Geometry:
    """The drawing geometry of ``mechanism`` (a Mechanism, a Geometry, or None for the
    result's embedded scene)."""
    if isinstance(mechanism, Geometry):
        return mechanism
    mech = mechanism if mechanism is not None else result.mechanism(loads_scene)
    names = list(mech.bodies)
    if names != list(result.names["bodies"]):
        raise AnalysisError(f"the mechanism's bodies {names} are not the result's "
                            f"{list(result.names['bodies'])}")
    return Geometry.from_mechanism(mech)


def body_points(result, mechanism=None) -> dict[str, np.ndarray]:
    """Global positions (n_t, n_points, dim) of every body's drawing points, in the order of
    :attr:`Geometry.points`.

    Parameters
    ----------
    result : Result
    mechanism : Mechanism or Geometry, optional
        Default: the scene embedded in the result (:meth:`Result.mechanism`).
    """
    geo = geometry_of(result, mechanism)
    pos, rot = frame_poses(result, geo)
    n_t = len(result.t)
    return {body: (np.stack([point_trajectory(pos, rot, frame, u, n_t)
                             for (_, u), frame in zip(pts, geo.frames[body])], axis=1)
                   if pts else np.empty((n_t, 0, geo.dimension)))
            for body, pts in geo.points.items()}


def deformed_nodes(result, mechanism=None, *, scale: float = 1.0) -> dict[str, np.ndarray]:
    """Global positions (n_t, n_nodes, dim) of the nodes of every flexible body, the points
    its drawing joins: r_i = R + A (u_i0 + s Φ_i η) (module docstring).

    Parameters
    ----------
    result : Result
        With the coordinates ``q`` (every kinematics, simulation, statics or inverse result).
    mechanism : Mechanism or Geometry, optional
        Default: the scene embedded in the result (:meth:`Result.mechanism`).
    scale : float
        Deformation scale s (1: the computed deformation).
    """
    geo = geometry_of(result, mechanism)
    return flexible_nodes(result, geo, scale)


def joint_points(result, mechanism=None) -> dict[str, np.ndarray]:
    """Global position (n_t, dim) of every joint point on the grid, r_G + A u of the joint's
    second body (its first when the second is the ground; the node frame's position and
    rotation for a joint at a node of a flexible body); for a distance link the point on that
    body."""
    geo = geometry_of(result, mechanism)
    pos, rot = frame_poses(result, geo)
    return {name: point_trajectory(pos, rot, body, u, len(result.t))
            for name, (body, u) in geo.joints.items()}
