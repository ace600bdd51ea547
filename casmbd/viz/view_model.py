"""What the 3-D view shows (issue 32, item 1): a :class:`ViewModel` of a mechanism, a result or
an OCP solution, on one time grid, as plain numpy arrays (the renderer,
:mod:`casmbd.viz.view_server`, turns it into a viser scene; nothing here needs viser).

Poses.  Every body's centre of mass r_G(t) and rotation A(t) come from the result
(``body_positions`` and ``angle_positions`` in the plane, ``rotation_matrices`` in space,
:func:`casmbd.viz.geometry.body_poses`); a planar scene is placed in the global x-y plane
(z = 0) with its rotations about z.  Rotations are sent as unit quaternions q = (w, x, y, z)
(scalar first) by Shepperd's method (S. W. Shepperd, "Quaternion from rotation matrix",
J. Guidance and Control 1 (1978) 223–224: the largest of 4w², 4x², 4y², 4z² from the trace
and diagonal, the others from the off-diagonal sums and differences), in the plane
q = (cos θ/2, 0, 0, sin θ/2); the sign of each sample is chosen so that consecutive samples
have q_k · q_(k−1) ≥ 0 (no flips: a renderer interpolating between frames takes the short way).
A point u fixed in a body is at r = r_G + A u (seed 001, eq. 1), the same rule as the stick
figures of :mod:`casmbd.viz.geometry`, whose body-fixed points (joints, markers, force
elements) and flexible-body nodes are reused here.

Sources.  A :class:`~casmbd.model.Mechanism` alone is shown at its assembled initial pose
(the assembly of ``casmbd info`` and ``kinematics``: Newton–Raphson on C(q, 0) = 0 from the
initial guess; a mechanism that does not assemble is shown at its initial guess with a
warning), one frame at t = 0.  A :class:`~casmbd.results.Result` of any analysis with body
poses (kinematics, simulation, inverse dynamics, an OCP's, a statics result saved by a sweep)
on its own grid; a :class:`~casmbd.analysis.statics.report.StaticsResult` (the equilibrium, one
frame; give the mechanism); an :class:`~casmbd.ocp.solution.OcpSolution` through
:meth:`~casmbd.ocp.solution.OcpSolution.to_result` (as ``casmbd animate`` reads a solution
file); a result that holds the coordinates q but no body poses (an OCP solution file written
before issue 30) gets them from the mechanism's output function evaluated at its q.  A
:class:`~casmbd.analysis.studies.sweep_result.SweepResult` is refused: view one point of it
(``sweep.result(i)``).

Shapes (:mod:`casmbd.viz.view_shapes`): URDF ``<visual>`` elements (meshes through
:mod:`casmbd.viz.meshes`, primitives), else shapes derived from the scene.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.statics.report import StaticsResult
from casmbd.analysis.studies.sweep import statics_as_result
from casmbd.analysis.studies.sweep_result import SweepResult
from casmbd.compiled.build import compile_model
from casmbd.errors import AnalysisError, AssemblyError, CasmbdError
from casmbd.io.scene import loads_scene
from casmbd.model import Mechanism
from casmbd.model.measures import result_names
from casmbd.ocp.solution import OcpSolution
from casmbd.results import Result
from casmbd.system import System
from casmbd.viz import view_shapes
from casmbd.viz.column_units import effort_units, joint_coordinate_unit
from casmbd.viz.geometry import (
    Geometry,
    flexible_nodes,
    flexible_states,
    frame_poses,
    point_trajectory,
)
from casmbd.viz.view_types import Frame, Plane, Series, Shape, ViewModel

__all__ = ["Frame", "Plane", "Series", "Shape", "ViewModel", "quaternions_from_rotations",
           "view_model"]


# ---------------------------------------------------------------------- rotations
def quaternions_from_rotations(rot: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4), (w, x, y, z), of rotation matrices (n, 3, 3), sign-continuous.

    Shepperd's method (module docstring), vectorised; a matrix that is not orthonormal to
    1e-12 (natural coordinates satisfy AᵀA = I to the solver's tolerance) is replaced by the
    nearest rotation U Vᵀ of its SVD first.  The first sample has w ≥ 0; each next one the
    sign that makes q_k · q_(k−1) ≥ 0.
    """
    m = np.asarray(rot, float).reshape(-1, 3, 3)
    if m.shape[0] == 0:
        return np.zeros((0, 4))
    gram = np.einsum("kji,kjl->kil", m, m) - np.eye(3)
    if np.max(np.abs(gram)) > 1e-12:
        u, _, vt = np.linalg.svd(m)
        m = u @ vt
    m00, m01, m02 = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2]
    m10, m11, m12 = m[:, 1, 0], m[:, 1, 1], m[:, 1, 2]
    m20, m21, m22 = m[:, 2, 0], m[:, 2, 1], m[:, 2, 2]
    cand = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22,
                     1 - m00 - m11 + m22], axis=1)
    k = np.argmax(cand, axis=1)
    s = 2.0 * np.sqrt(np.maximum(cand[np.arange(len(m)), k], 1e-300))
    q = np.empty((len(m), 4))
    rows = [np.stack([s / 4, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s], axis=1),
            np.stack([(m21 - m12) / s, s / 4, (m01 + m10) / s, (m02 + m20) / s], axis=1),
            np.stack([(m02 - m20) / s, (m01 + m10) / s, s / 4, (m12 + m21) / s], axis=1),
            np.stack([(m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, s / 4], axis=1)]
    for case in range(4):
        q[k == case] = rows[case][k == case]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return _sign_continuous(q)


def _sign_continuous(q: np.ndarray) -> np.ndarray:
    """``q`` with each sample's sign chosen for q_k · q_(k−1) ≥ 0 (the first with w ≥ 0)."""
    if len(q) == 0:
        return q
    dots = np.einsum("ki,ki->k", q[1:], q[:-1])
    flips = np.concatenate([[1.0 if q[0, 0] >= 0 else -1.0],
                            np.where(dots < 0.0, -1.0, 1.0)])
    return q * np.cumprod(flips)[:, None]


def _planar_quaternions(theta: np.ndarray) -> np.ndarray:
    """(cos θ/2, 0, 0, sin θ/2) of plane angles θ (n,), sign-continuous."""
    theta = np.asarray(theta, float)
    q = np.zeros((len(theta), 4))
    q[:, 0], q[:, 3] = np.cos(0.5 * theta), np.sin(0.5 * theta)
    return _sign_continuous(q)


def _quaternion(rot: np.ndarray) -> np.ndarray:
    """The quaternion (4,) of one rotation: a 2x2 plane rotation (about z) or a 3x3 matrix."""
    rot = np.asarray(rot, float)
    if rot.shape == (2, 2):
        return _planar_quaternions(np.array([math.atan2(rot[1, 0], rot[0, 0])]))[0]
    return quaternions_from_rotations(rot[None])[0]


def _pad3(a: np.ndarray) -> np.ndarray:
    """Planar vectors (…, 2) padded with z = 0 to (…, 3); spatial ones unchanged (copied)."""
    a = np.asarray(a, float)
    if a.shape[-1] == 3:
        return a.copy()
    return np.concatenate([a, np.zeros((*a.shape[:-1], 1))], axis=-1)


def _rotation3(rot: np.ndarray) -> np.ndarray:
    """A 3x3 rotation of a 2x2 plane rotation (about z) or a 3x3 one."""
    rot = np.asarray(rot, float)
    if rot.shape[-1] == 3:
        return rot
    out = np.zeros((*rot.shape[:-2], 3, 3))
    out[..., :2, :2] = rot
    out[..., 2, 2] = 1.0
    return out


# ---------------------------------------------------------------------- sources
def _initial_result(mech) -> Result:
    """The mechanism at its assembled initial pose as a one-time Result (t = 0)."""
    model = compile_model(mech, "info", mode="vm")
    q = model.initial_coordinates()
    try:
        q = assemble(model, q, 0.0).q
    except AssemblyError as exc:
        warnings.warn(f"mechanism '{mech.name}' does not assemble ({exc}); shown at its "
                      "initial guess", RuntimeWarning, stacklevel=3)
    try:
        v = model.initial_velocities()
    except CasmbdError:
        v = np.zeros(model.nq)
    return _outputs_result("initial", model, mech, q[None, :], v[None, :], np.zeros(1))


def _outputs_result(kind: str, model, mech, q, v, t) -> Result:
    """A Result of the model's outputs at the coordinates ``q`` (n_t, n_q) (accelerations 0:
    only positions are drawn)."""
    outputs = model.outputs(q, v, np.zeros_like(q), t)
    names = {"coordinates": list(model.coordinate_names), "bodies": list(model.body_names),
             "markers": list(mech.markers), "joints": list(model.joint_coordinate_names),
             "all_joints": list(mech.joints), "dimension": int(mech.dimension),
             **result_names(mech)}
    return Result(kind, np.asarray(t, float), {"q": q, "v": v, **outputs}, names, {},
                  getattr(mech, "scene_text", "") or "")


def _with_poses(result: Result, mech) -> Result:
    """``result`` itself when it holds body poses; else the poses computed from its
    coordinates q with the mechanism's output function (the coordinate choice whose names
    match the result's)."""
    rot_key = "angle_positions" if mech.dimension == 2 else "rotation_matrices"
    if "body_positions" in result.arrays and rot_key in result.arrays:
        return result
    names = list(result.names.get("coordinates", []))
    q = result.arrays.get("q")
    if q is None or not names:
        raise AnalysisError(f"the {result.kind} result holds neither body poses nor "
                            "coordinates q: nothing to place the bodies with")
    for choice in dict.fromkeys((mech.coordinates, "joint", "absolute", "natural")):
        if choice == "auto":
            continue
        try:
            system = System(mech, coordinates=choice)
        except CasmbdError:
            continue
        if list(system.coordinate_names) == names:
            model = compile_model(system, "outputs", mode="vm")
            v = result.arrays.get("v", np.zeros_like(q))
            out = _outputs_result(result.kind, model, mech, q, v, result.t)
            arrays = {**out.arrays, **result.arrays}
            return Result(result.kind, result.t, arrays, {**result.names, **out.names},
                          result.stats, result.scene or out.scene, list(result.events))
    raise AnalysisError(f"the {result.kind} result holds no body poses, and its coordinates "
                        f"({', '.join(names[:4])}…) are none of mechanism '{mech.name}''s "
                        "coordinate choices: cannot place the bodies")


def _resolve(source, mechanism):
    """(Result, Mechanism) of a view source."""
    if isinstance(source, Mechanism):
        mech = mechanism if mechanism is not None else source
        return _initial_result(mech), mech
    if isinstance(source, SweepResult):
        raise AnalysisError("a sweep result holds one result per point: view one of them "
                            "(sweep.result(i), or the point's file in the sweep's --out "
                            "folder)")
    if isinstance(source, StaticsResult):
        if mechanism is None:
            raise AnalysisError("a StaticsResult holds no scene: pass its mechanism "
                                "(view_model(result, mechanism))")
        return statics_as_result(source), mechanism
    if isinstance(source, OcpSolution):
        result = source.to_result()
        if mechanism is None and source.ocp is not None:
            mechanism = source.ocp.system.mechanism
        source = result
    if isinstance(source, Result):
        mech = mechanism if mechanism is not None else source.mechanism(loads_scene)
        return _with_poses(source, mech), mech
    raise AnalysisError(f"cannot view a {type(source).__name__}: give a Mechanism, a Result, "
                        "a StaticsResult or an OcpSolution")


# ---------------------------------------------------------------------- grid
def _frame_indices(t: np.ndarray, max_frames: int | None, event_times) -> np.ndarray:
    """Output steps kept: all, or ``max_frames`` evenly spread ones (the first and last
    included; 1: the first alone) plus the steps nearest each event time."""
    n = len(t)
    if max_frames is None:
        return np.arange(n)
    if isinstance(max_frames, bool) or not isinstance(max_frames, int | np.integer) \
            or max_frames < 1:
        raise AnalysisError(f"max_frames must be an integer >= 1, got {max_frames!r}")
    if max_frames >= n:
        return np.arange(n)
    keep = ({0} if max_frames == 1 else
            set(np.linspace(0, n - 1, int(max_frames)).round().astype(int).tolist()))
    for te in event_times:
        keep.add(int(np.argmin(np.abs(t - te))))
    return np.array(sorted(keep), dtype=int)


def _subset(result: Result, idx: np.ndarray) -> Result:
    """``result`` on the output steps ``idx``."""
    if len(idx) == len(result.t):
        return result
    arrays = {k: (a[idx] if isinstance(a, np.ndarray) and a.ndim >= 1
                  and a.shape[0] == len(result.t) else a) for k, a in result.arrays.items()}
    return Result(result.kind, result.t[idx], arrays, result.names, result.stats,
                  result.scene, list(result.events))


# ---------------------------------------------------------------------- view model
def _deformation_scale(scale) -> float:
    if isinstance(scale, bool) or not isinstance(scale, int | float | np.number) or not (
            np.isfinite(scale) and scale > 0):
        raise AnalysisError(f"deformation_scale must be a finite number > 0, got {scale!r}")
    return float(scale)


def view_model(source, mechanism=None, *, deformation_scale: float = 1.0,
               forces: bool = False, max_frames: int | None = None) -> ViewModel:
    """The view of ``source``: a Mechanism (initial pose), a Result (its time grid) or an
    OcpSolution (its trajectory).  ``mechanism`` overrides the one embedded in a result.
    ``max_frames`` subsamples the grid (keeping the first and last time and event times).
    Raises casmbd errors (AnalysisError/SceneError) naming what is missing; never NaN.

    Parameters
    ----------
    source : Mechanism, Result, StaticsResult or OcpSolution
        See the module docstring for what each gives.
    mechanism : Mechanism, optional
        The scene of the result (default: the scene text embedded in it; required for a
        StaticsResult and for a result built in Python without scene text).
    deformation_scale : float
        s > 0: flexible bodies' nodes at r_i = R + A (u_i0 + s Φ_i η)
        (:mod:`casmbd.viz.geometry`); rigid bodies are drawn as computed.
    forces : bool
        Also the force arrows of the force elements the result reports as vectors
        (:func:`casmbd.viz.view_shapes.force_arrows`).
    max_frames : int, optional
        Keep at most about this many output times (plus the event times).

    Raises
    ------
    AnalysisError
        A source that cannot be viewed, a result without body poses or coordinates, a
        mechanism whose bodies are not the result's, non-finite body poses (naming the body
        and the time).
    """
    scale = _deformation_scale(deformation_scale)
    result, mech = _resolve(source, mechanism)
    bodies = list(result.names.get("bodies", []))
    if bodies != list(mech.bodies):
        raise AnalysisError(f"the mechanism's bodies {list(mech.bodies)} are not the "
                            f"result's {bodies}")
    if result.dimension != mech.dimension:
        raise AnalysisError(f"the mechanism is {mech.dimension}-D but the {result.kind} "
                            f"result {result.dimension}-D")
    event_times = [float(e["time"]) for e in result.events if "time" in e]
    result = _subset(result, _frame_indices(np.asarray(result.t, float), max_frames,
                                            event_times))
    geo = Geometry.from_mechanism(mech)
    planar = mech.dimension == 2
    states = flexible_states(result, geo)
    pos, rot = frame_poses(result, geo, scale, states)
    body_positions, body_wxyz = {}, {}
    used_frames = {f for fr in geo.frames.values() for f in fr} | {
        on for on, _ in geo.joints.values()}
    for name in [*bodies, *(f for f in geo.node_frames if f in used_frames)]:
        p, r = pos[name], rot[name]
        _check_finite(name, result, p, r)
        body_positions[name] = _pad3(p)
        body_wxyz[name] = (_planar_quaternions(np.arctan2(r[:, 1, 0], r[:, 0, 0]))
                           if planar else quaternions_from_rotations(r))
    if planar and "angle_positions" in result.arrays:  # the stored angles, exactly
        for i, name in enumerate(bodies):
            body_wxyz[name] = _planar_quaternions(result.arrays["angle_positions"][:, i])
    vm = ViewModel(times=np.asarray(result.t, float).copy(), body_positions=body_positions,
                   body_wxyz=body_wxyz, planar=planar, title=mech.name)
    nodes = flexible_nodes(result, geo, scale, states)
    vm.flexible = {b: _pad3(n) for b, n in nodes.items()}
    vm.flexible_edges = {b: np.stack([np.arange(n.shape[1] - 1), np.arange(1, n.shape[1])],
                                     axis=1).astype(int) if n.shape[1] > 1
                         else np.zeros((0, 2), int) for b, n in nodes.items()}
    vm.traces = _traces(result, mech)
    n_t = len(result.t)
    vm.links = {name: np.stack([_pad3(point_trajectory(pos, rot, b1, u1, n_t)),
                                _pad3(point_trajectory(pos, rot, b2, u2, n_t))], axis=1)
                for name, b1, u1, b2, u2, _ in geo.links}
    vm.length_scale = _length_scale(vm, geo)
    vm.shapes = view_shapes.shapes(mech, geo, vm)
    vm.frames = view_shapes.frames(mech, geo)
    vm.planes = view_shapes.planes(mech, vm.length_scale)
    vm.events = _events(result)
    vm.series = _series(result, mech)
    if forces:
        vm.forces = view_shapes.force_arrows(result, mech, geo, pos, rot, vm.notes)
    return vm


def _check_finite(name: str, result: Result, p: np.ndarray, r: np.ndarray) -> None:
    bad = ~(np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(r.reshape(len(r), -1)),
                                                     axis=1))
    if np.any(bad):
        k = int(np.argmax(bad))
        raise AnalysisError(f"body '{name}': non-finite pose in the {result.kind} result at "
                            f"t = {result.t[k]:.6g} s (a failed step's NaN): nothing to draw")


def _traces(result: Result, mech) -> dict[str, np.ndarray]:
    """Every marker's global path (n_t, 3) from ``marker_positions``."""
    markers = list(result.names.get("markers", []))
    arr = result.arrays.get("marker_positions")
    dim = mech.dimension
    if arr is None or arr.shape[1] != dim * len(markers):
        return {}
    return {m: _pad3(arr[:, dim * i:dim * i + dim]) for i, m in enumerate(markers)}


def _length_scale(vm: ViewModel, geo: Geometry) -> float:
    """A characteristic size [m]: the largest extent of the centres of mass, joint points,
    ground points and flexible nodes over the run, else the largest body-fixed point
    distance, else 1."""
    pts = [p for p in vm.body_positions.values()]
    pts += [n.reshape(-1, 3) for n in vm.flexible.values()]
    pts += [_pad3(np.asarray(p, float))[None] for _, p in geo.ground]
    pts += [t for t in vm.traces.values()]
    cloud = np.concatenate([p.reshape(-1, 3) for p in pts]) if pts else np.zeros((0, 3))
    span = float(np.max(np.ptp(cloud, axis=0))) if len(cloud) else 0.0
    reach = max((float(np.linalg.norm(u)) for pts_ in geo.points.values() for _, u in pts_),
                default=0.0)
    scale = max(span, 2.0 * reach)
    return scale if np.isfinite(scale) and scale > 1e-9 else 1.0


def _events(result: Result) -> list[tuple[float, str]]:
    """(time, "element kind") of the result's events (impacts, limits, stick, slip …)."""
    out = []
    for e in result.events:
        if "time" not in e:
            continue
        label = " ".join(str(e[k]) for k in ("element", "kind") if e.get(k))
        out.append((float(e["time"]), label or "event"))
    return out


#: joint coordinates (and actuator inputs) shown by default in the side panel
SERIES_JOINTS = 3


def _series(result: Result, mech) -> list[Series]:
    """The default side-panel plots: total energy, the first :data:`SERIES_JOINTS` joint
    coordinates, the first :data:`SERIES_JOINTS` actuator inputs that are not all zero (an
    OCP's controls, N or N m), every request (``[[outputs]]``) under its own name and unit."""
    out = []
    arrays, names = result.arrays, result.names
    if "total_energy" in arrays and np.all(np.isfinite(arrays["total_energy"])):
        out.append(Series("total energy", "J", np.asarray(arrays["total_energy"], float)))
    joints = list(names.get("joints", []))
    if "joint_positions" in arrays:
        for k, column in enumerate(joints[:SERIES_JOINTS]):
            joint, _, coord = column.partition(".")
            values = np.asarray(arrays["joint_positions"][:, k], float)
            if np.all(np.isfinite(values)):
                out.append(Series(column, joint_coordinate_unit(mech, joint, coord or None),
                                  values))
    inputs = arrays.get("actuator_inputs")
    actuators = list(names.get("actuators", []))
    if inputs is not None and inputs.ndim == 2 and inputs.shape[1] == len(actuators):
        units = effort_units(result, "actuators", mech)
        for k, name in enumerate(actuators[:SERIES_JOINTS]):
            values = np.asarray(inputs[:, k], float)
            if np.all(np.isfinite(values)) and np.any(values != 0.0):
                out.append(Series(f"{name} (input)", units[k], values))
    requests = list(names.get("outputs", []))
    units = list(names.get("output_units", ["-"] * len(requests)))
    if "outputs" in arrays:
        for k, name in enumerate(requests):
            values = np.asarray(arrays["outputs"][:, k], float)
            if np.all(np.isfinite(values)):
                out.append(Series(name, units[k] if k < len(units) else "-", values))
    return out

