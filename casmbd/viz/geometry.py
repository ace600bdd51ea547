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
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import AnalysisError, CasmbdError
from casmbd.io import scene as _scene  # noqa: F401  (registers the reader of Result.mechanism)
from casmbd.model.bodies import GROUND


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
        Per joint with a point: the body it is drawn on (body2 unless that is the ground) and
        the body-fixed vector of the point (a global point for a joint between ground and
        ground, which does not occur).
    """

    dimension: int
    points: dict[str, list[tuple[str, np.ndarray]]] = field(default_factory=dict)
    outline: dict[str, list[int]] = field(default_factory=dict)
    ground: list[tuple[str, np.ndarray]] = field(default_factory=list)
    guides: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    links: list[tuple] = field(default_factory=list)
    joints: dict[str, tuple[str, np.ndarray]] = field(default_factory=dict)

    @classmethod
    def from_mechanism(cls, mechanism) -> Geometry:
        """Collect the attachment points of every body of ``mechanism``."""
        bodies = mechanism.bodies
        geo = cls(int(mechanism.dimension), {name: [] for name in bodies})

        def local(body: str, point) -> np.ndarray:
            point = np.asarray(point, float)
            return point if body == GROUND else bodies[body].local(point)

        def attach(body: str, label: str, point) -> None:
            if body == GROUND:
                geo.ground.append((label, np.asarray(point, float)))
            else:
                geo.points[body].append((label, local(body, point)))

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
        for body, pts in geo.points.items():
            geo.outline[body] = _outline([u for _, u in pts])
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
        return result.mechanism().name
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


def _place(pos, rot, body: str, u: np.ndarray, n_t: int) -> np.ndarray:
    """r_G + A u on the grid, (n_t, dim); a ground point stays where it is."""
    if body == GROUND:
        return np.broadcast_to(np.asarray(u, float), (n_t, len(u))).copy()
    return pos[body] + np.einsum("kij,j->ki", rot[body], u)


def _geometry(result, mechanism) -> Geometry:
    if isinstance(mechanism, Geometry):
        return mechanism
    mech = mechanism if mechanism is not None else result.mechanism()
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
    geo = _geometry(result, mechanism)
    pos, rot = body_poses(result)
    n_t = len(result.t)
    return {body: (np.stack([_place(pos, rot, body, u, n_t) for _, u in pts], axis=1)
                   if pts else np.empty((n_t, 0, geo.dimension)))
            for body, pts in geo.points.items()}


def joint_points(result, mechanism=None) -> dict[str, np.ndarray]:
    """Global position (n_t, dim) of every joint point on the grid, r_G + A u of the joint's
    second body (its first when the second is the ground); for a distance link the point on
    that body."""
    geo = _geometry(result, mechanism)
    pos, rot = body_poses(result)
    return {name: _place(pos, rot, body, u, len(result.t))
            for name, (body, u) in geo.joints.items()}
