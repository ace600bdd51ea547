"""The 3-D scene of a :class:`~casmbd.viz.view_model.ViewModel` in viser (three.js underneath).

One :class:`ViewScene` builds the scene graph once and moves it to an output time with
:meth:`ViewScene.show_frame`; the live server (:mod:`casmbd.viz.view_server`) calls it from its
time slider, the self-contained HTML writer (:mod:`casmbd.viz.view_html`) once per recorded
frame.  The scene graph:

* ``/bodies/<body>`` — one frame per body at its centre of mass and rotation (the result's
  pose, moved every frame); its shapes (``/bodies/<body>/shapes/<shape>``), joint and marker
  frames (``/bodies/<body>/frames/<frame>``) and joint axes (``…/axes/<frame>``) are its
  children, so they move with it without being sent again;
* ``/ground`` — the ground's shapes and frames; ``/planes/<plane>`` — contact planes (a grid
  and a translucent square);
* ``/traces/<marker>`` — each marker's whole path (line segments, fixed);
* ``/flexible/<body>`` — a flexible body's beam segments through its deformed nodes (moved
  every frame);
* ``/forces/<name>`` — force arrows (moved every frame; length ``0.3 L |F| / max|F|`` with L
  the mechanism's length scale);
* ``/events/label`` — the text of the latest event, shown for a short while after its time.

viser is imported lazily by :func:`require_viser`, which names the ``[view]`` extra when it is
missing.
"""

from __future__ import annotations

import contextlib
import io
import re
import socket
import threading

import numpy as np

from casmbd.errors import AnalysisError
from casmbd.viz.view_types import Shape, ViewModel

#: how to get the optional dependencies of the viewer
VIEW_EXTRA = 'pip install "casmbd[view]"'


def require_viser():
    """The ``viser`` module, or an :class:`AnalysisError` naming the ``[view]`` extra."""
    try:
        import trimesh  # noqa: F401  (viser's mesh helpers and casmbd's meshes need it)
        import viser
    except ImportError as exc:
        raise AnalysisError(f"casmbd view needs the optional packages viser and trimesh "
                            f"({exc}); install them with: {VIEW_EXTRA}") from None
    return viser


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on ``host`` now (the kernel's choice)."""
    with contextlib.closing(socket.socket(socket.AF_INET, socket.SOCK_STREAM)) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def start_server(viser, port: int):
    """A ``viser.ViserServer`` on 127.0.0.1:``port`` (loopback only), without viser's banner
    on stdout (the caller prints the URL; ``--json`` keeps stdout for its one object)."""
    with contextlib.redirect_stdout(io.StringIO()):
        return viser.ViserServer(host="127.0.0.1", port=port, verbose=False)


#: how long stopping the server may take before the caller goes on [s] (its threads are
#: daemons: a stop that hangs on a loaded machine must not keep Ctrl-C from ending the command)
STOP_TIMEOUT = 10.0


def stop_server(server) -> None:
    """Stop ``server`` without viser's "Server stopped" line on stdout, waiting at most
    :data:`STOP_TIMEOUT` seconds."""
    def stop() -> None:
        with contextlib.suppress(Exception):
            server.stop()

    with contextlib.redirect_stdout(io.StringIO()):
        stopper = threading.Thread(target=stop, name="casmbd-view-stop", daemon=True)
        stopper.start()
        stopper.join(timeout=STOP_TIMEOUT)


def node_name(name: str) -> str:
    """A scene-graph path component for ``name`` (viser separates levels by '/')."""
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", name) or "_"


def quat_z_to(normal) -> np.ndarray:
    """The unit quaternion (w, x, y, z) turning +z onto the unit vector ``normal``."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    c = float(n[2])
    if c < -1.0 + 1e-12:
        return np.array([0.0, 1.0, 0.0, 0.0])
    axis = np.cross([0.0, 0.0, 1.0], n)
    q = np.array([1.0 + c, *axis])
    return q / np.linalg.norm(q)


def _checked(vm: ViewModel) -> None:
    """Refuse a ViewModel the scene cannot show (shapes of unknown bodies, NaN poses)."""
    n_t = len(vm.times)
    if n_t < 1:
        raise AnalysisError("view: the view has no output time")
    for body, pos in vm.body_positions.items():
        wxyz = vm.body_wxyz.get(body)
        if wxyz is None or np.shape(pos) != (n_t, 3) or np.shape(wxyz) != (n_t, 4):
            raise AnalysisError(f"view: body '{body}' has no pose on the {n_t} output times")
        bad = ~(np.isfinite(pos).all(axis=1) & np.isfinite(wxyz).all(axis=1))
        if bad.any():
            raise AnalysisError(f"view: body '{body}' has a non-finite pose at "
                                f"t = {vm.times[np.argmax(bad)]:g} s")
    for s in [*vm.shapes, *vm.frames]:
        if s.body != "ground" and s.body not in vm.body_positions:
            raise AnalysisError(f"view: '{s.name}' is fixed in body '{s.body}', which has no "
                                "pose in the result")


class ViewScene:
    """The viser scene of ``vm`` on ``server`` (a ``viser.ViserServer``).

    ``forces`` draws the force arrows of ``vm.forces``.  The visibility of the groups is set
    by :meth:`set_visible` (``"body_frames"``, ``"frames"``, ``"markers"``, ``"traces"``,
    ``"forces"``).
    """

    def __init__(self, server, vm: ViewModel, *, forces: bool = True):
        _checked(vm)
        self.server, self.vm = server, vm
        self.scene = server.scene
        self.index = -1
        L = float(vm.length_scale) if vm.length_scale and vm.length_scale > 0 else 1.0
        self.L = L
        self.bodies: dict[str, object] = {}
        self.groups: dict[str, list] = {"body_frames": [], "frames": [], "markers": [],
                                        "traces": [], "forces": []}
        self.flex: dict[str, object] = {}
        self.arrows: dict[str, object] = {}
        # shadows off: the default lights' shadow maps cost one more render pass per light,
        # which software WebGL (headless browsers, remote desktops) pays on every frame
        self.scene.configure_default_lights(enabled=True, cast_shadow=False)
        self._camera()
        self._planes()
        self._bodies()
        self._shapes()
        self._frames()
        self._traces()
        self._flexible()
        if forces:
            self._forces()
        self.event_label = None
        if vm.events:
            self.event_label = self.scene.add_label(
                "/events/label", "", position=self._top(), visible=False,
                font_screen_scale=1.2)
        self.show_frame(0)

    # --- building --------------------------------------------------------------------------
    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        pts = [p for p in self.vm.body_positions.values()]
        pts += [p for p in self.vm.traces.values()]
        pts += [f.reshape(-1, 3) for f in self.vm.flexible.values()]
        if not pts:
            return np.zeros(3), np.zeros(3)
        allp = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in pts])
        return allp.min(axis=0), allp.max(axis=0)

    def _top(self) -> np.ndarray:
        lo, hi = self._bounds()
        c = 0.5 * (lo + hi)
        if self.vm.planar:
            return np.array([c[0], hi[1] + 0.3 * self.L, 0.0])
        return np.array([c[0], c[1], hi[2] + 0.3 * self.L])

    def _camera(self) -> None:
        """Planar scenes are seen from +z with +y up; spatial ones from an oblique view, z up."""
        lo, hi = self._bounds()
        centre = 0.5 * (lo + hi)
        # the whole motion in view: viser's camera has a 75° vertical field of view, a
        # distance d shows ±0.77 d; a little more for the oblique view of spatial scenes
        extent = max(float(np.max(hi - lo)), self.L)
        cam = self.server.initial_camera
        if self.vm.planar:
            self.scene.set_up_direction("+y")
            cam.look_at = tuple(centre)
            cam.position = (centre[0], centre[1], centre[2] + 1.1 * extent)
            cam.up = (0.0, 1.0, 0.0)
        else:
            self.scene.set_up_direction("+z")
            cam.look_at = tuple(centre)
            direction = np.array([1.0, -1.2, 0.8]) / np.linalg.norm([1.0, -1.2, 0.8])
            cam.position = tuple(centre + 1.4 * extent * direction)

    def _planes(self) -> None:
        for pl in self.vm.planes:
            h = float(pl.half_size)
            wxyz = quat_z_to(pl.normal)
            name = f"/planes/{node_name(pl.name)}"
            self.scene.add_grid(f"{name}/grid", width=2 * h, height=2 * h, plane="xy",
                                cell_size=max(h / 10, 1e-6), section_size=max(h / 2, 1e-6),
                                position=tuple(pl.point), wxyz=tuple(wxyz))
            self.scene.add_box(f"{name}/square", dimensions=(2 * h, 2 * h, 1e-3 * h),
                               color=(200, 205, 215), opacity=0.35,
                               position=tuple(np.asarray(pl.point) - 0.5e-3 * h
                                              * np.asarray(pl.normal) / np.linalg.norm(
                                                  pl.normal)),
                               wxyz=tuple(wxyz), cast_shadow=False)

    def _bodies(self) -> None:
        for body in self.vm.body_positions:
            h = self.scene.add_frame(f"/bodies/{node_name(body)}", show_axes=False,
                                     axes_length=0.25 * self.L, axes_radius=0.01 * self.L,
                                     origin_radius=0.02 * self.L)
            self.bodies[body] = h
            self.groups["body_frames"].append(h)

    def _parent(self, body: str) -> str:
        return "/ground" if body == "ground" else f"/bodies/{node_name(body)}"

    def _shapes(self) -> None:
        for s in self.vm.shapes:
            self._shape(s)

    def _shape(self, s: Shape) -> None:
        """One solid of the ViewModel in its body's frame."""
        path = f"{self._parent(s.body)}/shapes/{node_name(s.name)}"
        common = dict(color=tuple(int(c) for c in s.color), position=tuple(s.position),
                      wxyz=tuple(s.wxyz))
        size = tuple(float(x) for x in s.size)
        kind = s.kind
        if kind == "box":
            self.scene.add_box(path, dimensions=size, **common)
        elif kind == "sphere":
            self.scene.add_icosphere(path, radius=size[0], subdivisions=3, **common)
        elif kind == "ellipsoid":
            self.scene.add_icosphere(path, radius=1.0, subdivisions=3, scale=size, **common)
        elif kind == "cylinder":
            self.scene.add_cylinder(path, radius=size[0], height=size[1], **common)
        elif kind == "capsule":
            # a cylinder and two end spheres, all children of one frame placed at the shape
            r, length = size
            self.scene.add_frame(path, show_axes=False, position=common["position"],
                                 wxyz=common["wxyz"])
            self.scene.add_cylinder(f"{path}/body", radius=r, height=length,
                                    color=common["color"])
            for end, z in (("end_a", -0.5 * length), ("end_b", 0.5 * length)):
                self.scene.add_icosphere(f"{path}/{end}", radius=r, subdivisions=2,
                                         color=common["color"], position=(0.0, 0.0, z))
        elif kind == "mesh":
            if s.vertices is None or s.faces is None:
                raise AnalysisError(f"view: mesh shape '{s.name}' of body '{s.body}' has no "
                                    "vertices or faces")
            self.scene.add_mesh_simple(path, vertices=np.asarray(s.vertices, np.float32),
                                       faces=np.asarray(s.faces, np.uint32), **common)
        else:
            raise AnalysisError(f"view: shape '{s.name}' of body '{s.body}' has unknown kind "
                                f"'{kind}' (box, sphere, ellipsoid, cylinder, capsule, mesh)")

    def _frames(self) -> None:
        for f in self.vm.frames:
            parent = self._parent(f.body)
            group = "markers" if f.kind == "marker" else "frames"
            size = 0.06 * self.L if f.kind == "marker" else 0.09 * self.L
            h = self.scene.add_frame(f"{parent}/{group}/{node_name(f.name)}",
                                     axes_length=size, axes_radius=0.04 * size,
                                     origin_radius=0.08 * size, position=tuple(f.position),
                                     wxyz=tuple(f.wxyz))
            self.groups[group].append(h)
            if f.axis is not None and f.kind != "marker":
                tip = np.asarray(f.axis, float) * 0.16 * self.L
                a = self.scene.add_arrows(
                    f"{parent}/axes/{node_name(f.name)}",
                    points=np.array([[[0.0, 0.0, 0.0], tip]], np.float32),
                    colors=(240, 170, 0), shaft_radius=0.005 * self.L,
                    head_radius=0.012 * self.L, head_length=0.03 * self.L,
                    position=tuple(f.position))
                self.groups["frames"].append(a)

    def _traces(self) -> None:
        for name, path in self.vm.traces.items():
            p = np.asarray(path, float)
            p = p[np.isfinite(p).all(axis=1)]
            if len(p) < 2:
                continue
            segs = np.stack([p[:-1], p[1:]], axis=1).astype(np.float32)
            h = self.scene.add_line_segments(f"/traces/{node_name(name)}", points=segs,
                                             colors=(220, 60, 60), thickness=2.0,
                                             thickness_units="screen")
            self.groups["traces"].append(h)

    def _flex_segments(self, body: str, i: int) -> np.ndarray:
        nodes = np.asarray(self.vm.flexible[body][i], float)
        edges = self.vm.flexible_edges.get(body)
        if edges is None or len(edges) == 0:
            edges = np.stack([np.arange(len(nodes) - 1), np.arange(1, len(nodes))], axis=1)
        return nodes[np.asarray(edges, int)].astype(np.float32)

    def _flexible(self) -> None:
        for body in self.vm.flexible:
            self.flex[body] = self.scene.add_line_segments(
                f"/flexible/{node_name(body)}", points=self._flex_segments(body, 0),
                colors=(40, 110, 220), thickness=4.0, thickness_units="screen")

    def _forces(self) -> None:
        mags = [np.linalg.norm(np.asarray(f), axis=1).max() for _, f in self.vm.forces.values()]
        top = max([m for m in mags if np.isfinite(m)], default=0.0)
        self.force_scale = 0.3 * self.L / top if top > 0 else 0.0
        for name in self.vm.forces:
            h = self.scene.add_arrows(f"/forces/{node_name(name)}", points=self._arrow(name, 0),
                                      colors=(30, 170, 60), shaft_radius=0.01 * self.L,
                                      head_radius=0.025 * self.L, head_length=0.05 * self.L)
            self.arrows[name] = h
            self.groups["forces"].append(h)

    def _arrow(self, name: str, i: int) -> np.ndarray:
        point, force = self.vm.forces[name]
        p = np.asarray(point[i], float)
        f = np.nan_to_num(np.asarray(force[i], float)) * self.force_scale
        return np.array([[p, p + f]], np.float32)

    # --- updates ---------------------------------------------------------------------------
    def set_visible(self, group: str, visible: bool) -> None:
        """Show or hide a group of :attr:`groups` (body frames: their axes only, the body
        frame node carries the shapes)."""
        for h in self.groups.get(group, []):
            if group == "body_frames":
                h.show_axes = bool(visible)
            else:
                h.visible = bool(visible)

    def index_at(self, t: float) -> int:
        """The output index nearest the time ``t``."""
        times = self.vm.times
        i = int(np.searchsorted(times, t))
        if i <= 0:
            return 0
        if i >= len(times):
            return len(times) - 1
        return i if times[i] - t < t - times[i - 1] else i - 1

    def event_text(self, i: int) -> str | None:
        """The latest event at or before output ``i`` if it happened within a twentieth of the
        time span (at least two output steps) before it, else None."""
        t = self.vm.times[i]
        span = float(self.vm.times[-1] - self.vm.times[0])
        step = span / max(len(self.vm.times) - 1, 1)
        window = max(0.05 * span, 2.0 * step)
        past = [(te, lab) for te, lab in self.vm.events if te <= t + 1e-12 and t - te <= window]
        if not past:
            return None
        te, lab = past[-1]
        return f"t = {te:.4g} s: {lab}"

    def show_frame(self, i: int) -> None:
        """Move the bodies, flexible bodies, force arrows and event label to output ``i``."""
        vm = self.vm
        i = max(0, min(int(i), len(vm.times) - 1))
        with self.server.atomic():
            for body, h in self.bodies.items():
                h.position = tuple(float(x) for x in vm.body_positions[body][i])
                h.wxyz = tuple(float(x) for x in vm.body_wxyz[body][i])
            for body, h in self.flex.items():
                h.points = self._flex_segments(body, i)
            for name, h in self.arrows.items():
                h.points = self._arrow(name, i)
            if self.event_label is not None:
                text = self.event_text(i)
                if text is None:
                    self.event_label.visible = False
                else:
                    self.event_label.text = text
                    self.event_label.visible = True
        self.index = i


def view_summary(vm: ViewModel) -> dict:
    """What a view shows, for ``--json`` and the tests: counts of frames, bodies, shapes."""
    n_shapes = len(vm.shapes)
    return {"frames": len(vm.times), "bodies": len(vm.body_positions), "shapes": n_shapes,
            "t_start": float(vm.times[0]), "t_end": float(vm.times[-1]),
            "events": len(vm.events), "planar": bool(vm.planar), "title": vm.title,
            "notes": list(getattr(vm, "notes", []))}


def frame_interval(times: np.ndarray) -> float:
    """A typical output step [s] (the median step; 0.1 s for a single pose)."""
    d = np.diff(np.asarray(times, float))
    d = d[d > 0]
    return float(np.median(d)) if len(d) else 0.1

