"""The data classes of the 3-D view (:mod:`casmbd.viz.view_model`): what is drawn, on one
time grid, as plain numpy arrays.  The contract between the view model and its renderer
(:mod:`casmbd.viz.view_server`); field names and meanings are fixed, fields are only added."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Frame", "Plane", "Series", "Shape", "ViewModel"]


@dataclass
class Shape:
    """One drawn solid, fixed in a body frame (or in the ground when ``body`` is "ground").

    kind: "box" (size = (lx, ly, lz)), "sphere" (size = (r,)), "cylinder" (size = (r, length),
    axis along local z), "capsule" (size = (r, length), axis along local z: rods between joint
    points), "ellipsoid" (size = semi-axes (a, b, c)), "mesh" (vertices (n,3), faces (m,3) int,
    already scaled, in the shape's local frame).
    position, wxyz: pose of the shape in its body frame (body frame origin = the body's
    centre of mass as stored in results; rotation = the body's rotation).
    color: RGB in 0..255.  source: where it came from ("urdf-visual", "inertia", "joints",
    "contact") for the docs/tests.
    opacity: 1 opaque (a URDF material's alpha; derived shapes 1).  [addition to the contract]
    """

    name: str
    body: str
    kind: str
    size: tuple[float, ...] = ()
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    wxyz: np.ndarray = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))
    color: tuple[int, int, int] = (160, 160, 170)
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    source: str = ""
    opacity: float = 1.0


@dataclass
class Frame:
    """A joint frame or marker frame drawn as axes: fixed in ``body`` at position/wxyz
    (body-frame), ``axis`` (unit, body frame) for joints with an axis (drawn as an arrow)."""

    name: str
    body: str
    position: np.ndarray
    wxyz: np.ndarray
    axis: np.ndarray | None = None
    kind: str = "joint"          # "joint" or "marker"


@dataclass
class Plane:
    """A contact plane / floor: point, unit normal, half-size of the drawn square [m]."""

    name: str
    point: np.ndarray
    normal: np.ndarray
    half_size: float


@dataclass
class Series:
    """One plotted quantity for the side panel: values (n_t,) on ViewModel.times."""

    name: str
    unit: str
    values: np.ndarray


@dataclass
class ViewModel:
    """Everything the 3-D view shows, on one time grid.

    times: (n_t,) [s]; a mechanism alone (no result) gives n_t = 1 at t = 0 (initial pose).
    body_positions: body -> (n_t, 3) centre of mass; body_wxyz: body -> (n_t, 4).  The node
    frames ``"<body>@<node>"`` of flexible bodies that carry a joint or marker frame are
    listed too (the deformed node's position and rotation), so that those frames move with
    their node.  [addition to the contract]
    shapes, frames, planes: static geometry (see classes).
    traces: marker name -> (n_t, 3) global path of the marker point.
    flexible: flexible body name -> (n_t, n_nodes, 3) deformed global node positions (with
    ``deformation_scale`` applied), plus flexible_edges: body -> (k, 2) int node pairs drawn
    as lines (beam segments).
    forces: name -> ((n_t, 3) application point, (n_t, 3) force vector [N]) (optional arrows;
    empty unless asked).
    events: list of (time, label) (impacts, stick/slip changes) from the result.
    series: side-panel plots (a concise default set: e.g. energy, first joint coordinates,
    outputs requested in the scene).
    planar: True for a planar scene.  length_scale: a characteristic size of the mechanism
    [m] (for axes length, arrow scaling, camera).  title: scene name.
    notes: what the view could not show as asked (a mesh file that did not load, forces
    that the result does not hold), one line each.  [addition to the contract]
    links: spring-dampers and distance links, name -> (n_t, 2, 3) global end points, drawn
    as lines between the bodies they join.  [addition to the contract]
    """

    times: np.ndarray
    body_positions: dict[str, np.ndarray]
    body_wxyz: dict[str, np.ndarray]
    shapes: list[Shape] = field(default_factory=list)
    frames: list[Frame] = field(default_factory=list)
    planes: list[Plane] = field(default_factory=list)
    traces: dict[str, np.ndarray] = field(default_factory=dict)
    flexible: dict[str, np.ndarray] = field(default_factory=dict)
    flexible_edges: dict[str, np.ndarray] = field(default_factory=dict)
    forces: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    events: list[tuple[float, str]] = field(default_factory=list)
    series: list[Series] = field(default_factory=list)
    planar: bool = False
    length_scale: float = 1.0
    title: str = ""
    notes: list[str] = field(default_factory=list)
    links: dict[str, np.ndarray] = field(default_factory=dict)
