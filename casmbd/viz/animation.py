"""Still frames and animations of planar and spatial mechanisms (matplotlib, Agg-safe).

Each body is a polyline through its joint, marker and force-element points (a triangle or
polygon for a body with three or more non-collinear points, see
:class:`~casmbd.viz.geometry.Geometry`), with its centre of mass as a dot; a flexible body is
the polyline through all its deformed nodes in their numbering order (a built-in beam: root
to tip), with its deformed centre of mass Σ m_i r_i / Σ m_i (lumped nodal masses) as the dot;
``deformation_scale`` magnifies the elastic displacements (the clock says so).  Joints are open
circles, ground attachments black triangles, ground slides dashed lines, springs and distance
links thin lines.  Spatial mechanisms are drawn in a 3-D projection (matplotlib ``mplot3d``)
with equal axis scales.  Positions come from the result (centres of mass and rotations) and the
body-fixed points from the mechanism (:mod:`casmbd.viz.geometry`).

By default an animation plays in real time at no more than :data:`FPS_CAP` frames per second
and holds at most :data:`FRAME_BUDGET` frames (:func:`~casmbd.viz.playback.plan_frames`): a
10 s result of 1001 output times becomes 301 frames, about 0.5 MB of GIF at the default size
and dpi, written in a few seconds.  GIF files are written with Pillow from blitted frames
(only the moving artists are redrawn, one colour palette for every frame), with per-frame
delays that keep real time although a GIF stores delays in hundredths of a second; MP4 only
when ffmpeg is installed.
In a notebook, ``notebook_animation(result)`` returns the ``FuncAnimation``; show it with
``IPython.display.HTML(anim.to_jshtml())`` (a player with a frame slider, no extra package),
or use :func:`time_slider` when ipywidgets is installed.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from casmbd import progress
from casmbd.errors import AnalysisError, CasmbdError, LimitError
from casmbd.limits import MAX_FPS, MAX_FRAMES, check_count
from casmbd.results import atomic_write
from casmbd.viz.geometry import (
    Geometry,
    flexible_nodes,
    flexible_states,
    frame_poses,
    geometry_of,
    point_trajectory,
    scene_name,
)
from casmbd.viz.playback import FPS_CAP, FRAME_BUDGET, GIF_MAX_FPS, FramePlan, plan_frames
from casmbd.viz.plots import check_figure_size, new_figure, save_figure


class _Drawing:
    """The artists of one mechanism drawing and their update for output step ``k``."""

    def __init__(self, result, mechanism=None, ax=None, trace=None, figsize=None,
                 view=(22.0, -60.0), deformation_scale: float = 1.0):
        from matplotlib import colormaps

        self.result = result
        self.geo: Geometry = geometry_of(result, mechanism)
        self.dim = self.geo.dimension
        if result.dimension != self.dim:
            raise AnalysisError(f"the mechanism is {self.dim}-D but the result "
                                f"{result.dimension}-D")
        scale = _deformation_scale(deformation_scale)
        self.scale = scale
        states = flexible_states(result, self.geo)
        pos, rot = frame_poses(result, self.geo, scale, states)
        n_t = len(result.t)
        self.nodes = flexible_nodes(result, self.geo, scale, states)
        self.com = {b: pos[b] for b in self.geo.points}
        for b, nodes in self.nodes.items():  # the deformed centre of mass (lumped masses)
            m = self.geo.flexible[b].masses
            self.com[b] = np.einsum("i,kia->ka", m, nodes) / m.sum()
        self.pts = {b: [point_trajectory(pos, rot, f, u, n_t)
                        for (_, u), f in zip(p, self.geo.frames[b])]
                    for b, p in self.geo.points.items()}
        self.links = [(point_trajectory(pos, rot, b1, u1, n_t),
                       point_trajectory(pos, rot, b2, u2, n_t), kind)
                      for _, b1, u1, b2, u2, kind in self.geo.links]
        self.joint_xy = [point_trajectory(pos, rot, b, u, n_t) for b, u in self.geo.joints.values()]
        markers = list(result.names.get("markers", []))
        if trace in (None, False):
            trace = []
        elif trace is True or trace == "all":
            trace = markers
        elif isinstance(trace, str):
            trace = [trace]
        unknown = [m for m in trace if m not in markers]
        if unknown:
            raise AnalysisError(f"trace: unknown marker(s) {', '.join(unknown)} (markers: "
                                f"{', '.join(markers) or 'none'})")
        self.traces = {m: result.marker(m)["position"] for m in trace}

        if ax is None:
            figsize = figsize or ((5.6, 4.6) if self.dim == 3 else (5.6, 4.2))
            if self.dim == 3:
                fig, _ = new_figure(figsize=figsize)
                fig.clear()
                ax = fig.add_subplot(projection="3d")
            else:
                fig, ax = new_figure(figsize=figsize)
        self.ax, self.fig = ax, ax.figure
        self._limits()
        if self.dim == 3:
            ax.view_init(*view)
        else:
            ax.set_aspect("equal", adjustable="box")
        colours = colormaps["tab10"]
        # static parts: ground points and slide guides
        span = float(np.max(self.hi - self.lo))
        for point, axis in self.geo.guides:
            seg = np.array([point - 2 * span * axis, point + 2 * span * axis])
            ax.plot(*seg.T, ls="--", lw=0.8, color="0.55", zorder=1)
        if self.geo.ground:
            g = np.array([p for _, p in self.geo.ground])
            ax.plot(*g.T, ls="none", marker="^", ms=9, color="k", zorder=2)
        self._restore_limits()
        self.body_lines, self.com_dots = {}, {}
        for i, body in enumerate(self.geo.points):
            colour = colours(i % 10)
            single = not self.geo.outline[body] and body not in self.nodes
            block = {"marker": "s", "ms": 11} if single else {}  # a body of one point
            self.body_lines[body] = ax.plot(*self._empty(), lw=2.6, color=colour,
                                            solid_capstyle="round", label=body, zorder=3,
                                            **block)[0]
            self.com_dots[body] = ax.plot(*self._empty(), ls="none", marker="o", ms=4,
                                          color=colour, zorder=4)[0]
        self.link_lines = [ax.plot(*self._empty(), lw=1.0, color="0.3",
                                   ls=":" if kind == "spring" else "-", zorder=2)[0]
                           for *_, kind in self.links]
        self.joint_dots = ax.plot(*self._empty(), ls="none", marker="o", ms=5, mfc="white",
                                  mec="k", mew=0.8, zorder=5)[0]
        self.trace_lines = {m: ax.plot(*self._empty(), lw=0.8, color="0.2", zorder=2)[0]
                            for m in self.traces}
        if self.dim == 3:
            self.clock = ax.text2D(0.02, 0.95, "", transform=ax.transAxes, fontsize=9)
        else:
            self.clock = ax.text(0.02, 0.95, "", transform=ax.transAxes, fontsize=9)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if self.dim == 3:
            ax.set_zlabel("z [m]")
        if len(self.geo.points) <= 10:
            ax.legend(fontsize=7, loc="upper right")

    def _empty(self):
        return ([],) * self.dim

    def _limits(self) -> None:
        """Equal-scale limits holding every drawn point over the whole run (8 % margin)."""
        clouds = [self.com[b] for b in self.com] + [p for pts in self.pts.values() for p in pts]
        clouds += list(self.nodes.values())
        clouds += [p for a, b, _ in self.links for p in (a, b)]
        clouds += list(self.traces.values())
        if self.geo.ground:
            clouds.append(np.array([p for _, p in self.geo.ground]))
        clouds += [np.atleast_2d(point) for point, _ in self.geo.guides]  # a contact's plane
        allp = np.concatenate([c.reshape(-1, self.dim) for c in clouds])
        allp = allp[np.all(np.isfinite(allp), axis=1)]
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        half = 0.5 * max(float(np.max(hi - lo)), 1e-3) * 1.08
        mid = 0.5 * (lo + hi)
        if self.dim == 2:  # keep the plane's own extents, equal aspect does the rest
            span = max(float(np.max(hi - lo)), 1e-3)
            pad = 0.08 * span
            # no sliver: each extent at least half the other (a ball bouncing straight up)
            widen = np.maximum(0.5 * span - (hi - lo), 0.0) / 2
            self.lo, self.hi = lo - pad - widen, hi + pad + widen
        else:
            self.lo, self.hi = mid - half, mid + half
        self._restore_limits()

    def _restore_limits(self) -> None:
        ax = self.ax
        ax.set_xlim(self.lo[0], self.hi[0])
        ax.set_ylim(self.lo[1], self.hi[1])
        if self.dim == 3:
            ax.set_zlim(self.lo[2], self.hi[2])
            ax.set_box_aspect((1, 1, 1))

    def _set(self, line, xyz: np.ndarray) -> None:
        xyz = np.asarray(xyz).reshape(-1, self.dim)
        if self.dim == 3:
            line.set_data_3d(xyz[:, 0], xyz[:, 1], xyz[:, 2])
        else:
            line.set_data(xyz[:, 0], xyz[:, 1])

    def update(self, k: int):
        """Move every artist to output step ``k``; returns the artists."""
        for body, line in self.body_lines.items():
            order = self.geo.outline[body]
            pts = self.pts[body]
            if body in self.nodes:  # a flexible body: its deformed nodes
                self._set(line, self.nodes[body][k])
            elif order:
                self._set(line, np.array([pts[i][k] for i in order]))
            else:  # a body with one attachment point: join it to the centre of mass
                self._set(line, np.array([p[k] for p in pts] + [self.com[body][k]]))
            self._set(self.com_dots[body], self.com[body][k])
        for line, (a, b, _) in zip(self.link_lines, self.links):
            self._set(line, np.array([a[k], b[k]]))
        if self.joint_xy:
            self._set(self.joint_dots, np.array([p[k] for p in self.joint_xy]))
        for m, line in self.trace_lines.items():
            self._set(line, self.traces[m][:k + 1])
        scaled = f", deformation x{self.scale:g}" if self.nodes and self.scale != 1 else ""
        self.clock.set_text(f"t = {self.result.t[k]:.3f} s{scaled}")
        return [*self.body_lines.values(), *self.com_dots.values(), *self.link_lines,
                self.joint_dots, *self.trace_lines.values(), self.clock]


def _deformation_scale(scale) -> float:
    """A finite positive deformation scale.

    Raises
    ------
    AnalysisError
        For anything else (naming the value).
    """
    if isinstance(scale, bool) or not isinstance(scale, int | float | np.number) or not (
            np.isfinite(scale) and scale > 0):
        raise AnalysisError(f"deformation_scale must be a finite number > 0, got {scale!r}")
    return float(scale)


def _index(result, index: int | None, time: float | None) -> int:
    n_t = len(result.t)
    if n_t == 0:
        raise AnalysisError(f"the {result.kind} result has no output times")
    if time is not None:
        return int(np.argmin(np.abs(np.asarray(result.t) - time)))
    k = -1 if index is None else int(index)
    if not -n_t <= k < n_t:
        raise AnalysisError(f"frame index {k} outside the {n_t} output times")
    return k % n_t


def draw_frame(result, index: int | None = None, mechanism=None, *, time: float | None = None,
               ghosts: int = 0, trace=None, ax=None, out: str | os.PathLike | None = None,
               dpi: float = 100, figsize=None, view=(22.0, -60.0), title: str | None = None,
               deformation_scale: float = 1.0):
    """Draw the mechanism at one output time (a still frame).

    Parameters
    ----------
    result : Result
        With body positions and orientations (every kinematics, simulation or inverse result).
    index : int, optional
        Output step (default the last); or give ``time`` (the nearest output time).
    mechanism : Mechanism or Geometry, optional
        Default: the scene text embedded in the result.
    ghosts : int
        Also draw this many earlier poses, evenly spread over the run, faded (a stroboscopic
        picture of the motion).
    trace : str, list of str, True or None
        Marker name(s) whose paths up to the frame are drawn (True: every marker).
    ax : Axes, optional
        Draw into this axes (3-D axes for a spatial mechanism) instead of a new figure.
    out : path, optional
        Save the figure there (atomically).
    deformation_scale : float
        Magnify the elastic displacements of flexible bodies by this factor (their nodes
        r_i = R + A (u_i0 + s Φ_i η), :mod:`casmbd.viz.geometry`); rigid bodies and the traced
        marker paths are drawn as computed.

    Returns
    -------
    matplotlib.figure.Figure
    """
    k = _index(result, index, time)
    drawing = _Drawing(result, mechanism, ax=ax, trace=trace, figsize=figsize, view=view,
                       deformation_scale=deformation_scale)
    if ghosts > 0:
        for g in np.unique(np.linspace(0, k, ghosts + 2).round().astype(int))[:-1]:
            drawing.update(int(g))
            for line in drawing.body_lines.values():
                data = line.get_data_3d() if drawing.dim == 3 else line.get_data()
                drawing.ax.plot(*data, lw=1.4, color=line.get_color(), alpha=0.25, zorder=2)
    drawing.update(k)
    if title is None:
        title = scene_name(result)
    if title:
        drawing.ax.set_title(title, fontsize=10)
    if out is not None:
        save_figure(drawing.fig, out, dpi)
    return drawing.fig


def frame_indices(n_t: int, max_frames: int | None) -> np.ndarray:
    """Output steps shown by an animation: all, or ``max_frames`` evenly spread ones (first
    and last included)."""
    if max_frames is None or max_frames >= n_t:
        return np.arange(n_t)
    if max_frames < 1:
        raise AnalysisError(f"max_frames must be >= 1, got {max_frames}")
    return np.unique(np.linspace(0, n_t - 1, max_frames).round().astype(int))


def animate(result, mechanism=None, *, max_frames: int | None = None, fps: float | None = None,
            speed: float = 1.0, trace=None, figsize=None, view=(22.0, -60.0),
            title: str | None = None, deformation_scale: float = 1.0):
    """A ``matplotlib.animation.FuncAnimation`` of the mechanism playing in real time.

    Parameters
    ----------
    result : Result
    mechanism : Mechanism or Geometry, optional
        Default: the scene text embedded in the result.
    max_frames : int, optional
        Show at most this many output steps (default :data:`FRAME_BUDGET`).
    fps : float, optional
        Highest frame rate (default :data:`FPS_CAP`); fewer frames when the result has
        fewer output times.
    speed : float
        Playback speed factor: 1 plays in real time, 2 twice as fast.
    trace : str, list of str, True or None
        Marker paths to draw (see :func:`draw_frame`).
    deformation_scale : float
        Magnification of the elastic displacements of flexible bodies (see
        :func:`draw_frame`).

    Returns
    -------
    matplotlib.animation.FuncAnimation
        With ``casmbd_plan`` (the :class:`FramePlan` of :func:`plan_frames`),
        ``casmbd_fps`` (its mean frame rate) and ``casmbd_choice`` (the line saying what
        was chosen); :func:`save_animation` writes it.
    """
    from matplotlib.animation import FuncAnimation

    if fps is not None:
        check_fps(fps)
    plan = plan_frames(result.t, max_frames, fps, speed)
    frames = plan.indices
    check_count("animation: frames", len(frames), MAX_FRAMES,
                "give max_frames (--max-frames) to show evenly spread output steps")
    drawing = _Drawing(result, mechanism, trace=trace, figsize=figsize, view=view,
                       deformation_scale=deformation_scale)
    fps = plan.fps
    if title is None:
        title = scene_name(result)
    if title:
        drawing.ax.set_title(title, fontsize=10)
    drawing.update(int(frames[0]))
    drawing.fig.draw_without_rendering()  # lay out once, then keep the layout for every frame
    drawing.fig.set_layout_engine("none")
    anim = FuncAnimation(drawing.fig, lambda k: drawing.update(int(k)), frames=list(frames),
                         interval=1000.0 / fps, blit=False, repeat=True)
    anim.casmbd_plan = plan
    anim.casmbd_choice = plan.describe()
    anim.casmbd_fps = fps
    anim.casmbd_frames = len(frames)
    anim.casmbd_frame_list = [int(k) for k in frames]
    anim.casmbd_drawing = drawing
    return anim


def check_fps(fps: float) -> None:
    """Refuse a frame rate that is not a finite number in (0, MAX_FPS].

    A GIF stores frame durations in 10 ms units: 1e308 fps used to be written silently as
    frames of duration 0.

    Raises
    ------
    AnalysisError
        For a non-finite or non-positive rate; :class:`LimitError` above ``MAX_FPS``.
    """
    if not (isinstance(fps, (int, float, np.number)) and np.isfinite(fps) and fps > 0):
        raise AnalysisError(f"animation: fps (--fps) must be a finite number > 0, got {fps!r}")
    if fps > MAX_FPS:
        raise LimitError(f"animation: fps (--fps) {fps:g} exceeds the limit of {MAX_FPS:g} "
                         "(casmbd.limits): a GIF cannot show frames shorter than 10 ms")


def check_animation_file(out: str | os.PathLike) -> None:
    """Fail early unless ``out`` is a ``.gif``, or an ``.mp4`` with ffmpeg installed.

    Raises
    ------
    AnalysisError
        Naming the file and what to use instead.
    """
    from matplotlib import animation

    suffix = Path(out).suffix.lower()
    if suffix == ".mp4" and not animation.writers.is_available("ffmpeg"):
        raise AnalysisError(f"cannot write '{out}': MP4 needs ffmpeg, which is not "
                            "installed; write a .gif instead")
    if suffix not in (".gif", ".mp4"):
        raise AnalysisError(f"cannot write animation '{out}': unknown suffix '{suffix}' "
                            "(use .gif, or .mp4 with ffmpeg)")


def _blitted_frames(drawing: _Drawing, frames, dpi: float):
    """RGB images of ``frames``: the static parts drawn once, then per frame only the moving
    artists (matplotlib's blitting; about 3 ms a frame instead of 30 for a full draw)."""
    from PIL import Image

    fig, canvas = drawing.fig, drawing.fig.canvas
    moving = sorted(drawing.update(int(frames[0])), key=lambda a: a.get_zorder())
    old_dpi = fig.dpi
    try:
        for artist in moving:
            artist.set_animated(True)  # left out of the background
        fig.set_dpi(dpi)
        canvas.draw()
        background = canvas.copy_from_bbox(fig.bbox)
        for k in frames:
            drawing.update(int(k))
            canvas.restore_region(background)
            for artist in moving:
                drawing.ax.draw_artist(artist)
            yield Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba(),
                                   "raw", "RGBA", 0, 1).convert("RGB")
    finally:
        for artist in moving:
            artist.set_animated(False)
        fig.set_dpi(old_dpi)


def _write_gif(drawing: _Drawing, frames, delays_ms, path: str, dpi: float, bar) -> None:
    """A looping GIF of ``frames`` shown for ``delays_ms`` each, in the colours of the first
    frame (one palette: quantising each frame on its own costs 20 ms a frame)."""
    from PIL import Image

    images, palette = [], None
    for image in _blitted_frames(drawing, frames, dpi):
        if palette is None:
            palette = image.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        images.append(image.quantize(palette=palette, dither=Image.Dither.NONE))
        bar.update()
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:],
                   duration=[round(d) for d in delays_ms], loop=0)


def save_animation(anim, out: str | os.PathLike, fps: float | None = None,
                   dpi: float = 80) -> Path:
    """Write an animation atomically: ``.gif`` with Pillow, ``.mp4`` with ffmpeg.

    An :func:`animate` animation is drawn once per planned frame, with a progress bar; its GIF
    shows every frame until the next one's time (divided by the speed; the last one for the
    mean delay), rounded to the GIF's hundredths of a second without drifting, so it plays in
    real time.  ``fps`` given here overrides that with a constant frame rate.

    Raises
    ------
    AnalysisError
        For another suffix, ``.mp4`` when ffmpeg is not installed (use ``.gif``), or a GIF
        faster than :data:`GIF_MAX_FPS`.
    """
    from matplotlib import animation

    plan = None if fps else getattr(anim, "casmbd_plan", None)
    fps = fps or getattr(anim, "casmbd_fps", 20.0)
    gif = Path(out).suffix.lower() == ".gif"
    try:
        check_fps(fps)
        check_animation_file(out)
        drawing = getattr(anim, "casmbd_drawing", None)
        if drawing is not None:
            check_figure_size(tuple(float(x) for x in drawing.fig.get_size_inches()), dpi,
                              f"animation '{out}'")
        if gif and fps > GIF_MAX_FPS:
            raise AnalysisError(
                f"cannot write '{out}' at {fps:.3g} frames/s: a GIF plays at most "
                f"{GIF_MAX_FPS:g} (its delays are whole hundredths of a second); give "
                "--fps 50 or less, a lower --speed or fewer --max-frames")
    except CasmbdError:
        anim._draw_was_started = True  # not rendered on purpose: no deletion warning
        raise
    drawing = getattr(anim, "casmbd_drawing", None)
    if drawing is None:  # any other FuncAnimation
        writer = animation.PillowWriter(fps=fps) if gif else animation.FFMpegWriter(fps=fps)
        return atomic_write(out, lambda tmp: anim.save(tmp, writer=writer, dpi=dpi))
    frames = anim.casmbd_frame_list
    if plan is not None:
        delays = plan.delays_ms(tick=10.0)
    else:
        delays = np.full(len(frames), max(10.0, round(100.0 / fps) * 10.0))

    def write(tmp: str) -> None:
        with progress.bar(len(frames), f"animate {Path(out).name}", "frame") as bar:
            if gif:
                _write_gif(drawing, frames, delays, tmp, dpi, bar)
                return
            writer = animation.FFMpegWriter(fps=fps)
            with writer.saving(drawing.fig, tmp, dpi):  # one draw per frame
                for k in frames:
                    drawing.update(int(k))
                    writer.grab_frame()
                    bar.update()

    path = atomic_write(out, write)
    anim._draw_was_started = True  # rendered: no "deleted without rendering" warning
    return path


def notebook_animation(result, mechanism=None, **kwargs):
    """The :func:`animate` ``FuncAnimation`` for a notebook.

    Show it with ``IPython.display.HTML(anim.to_jshtml())``: matplotlib's JavaScript player
    with play/pause buttons and a frame slider (no extra package needed).
    """
    return animate(result, mechanism, **kwargs)


def time_slider(result, mechanism=None, **kwargs):
    """An ipywidgets time slider redrawing the mechanism (only when ipywidgets is installed).

    Returns the ``ipywidgets`` widget; raises :class:`AnalysisError` without ipywidgets (use
    :func:`notebook_animation` and ``to_jshtml()`` instead).
    """
    try:
        import ipywidgets
    except ImportError:
        raise AnalysisError("time_slider needs ipywidgets, which is not installed; use "
                            "notebook_animation(result) and anim.to_jshtml()") from None
    drawing = _Drawing(result, mechanism, **kwargs)
    image = ipywidgets.Image(format="png")

    def show(k: int) -> None:
        import io

        drawing.update(int(k))
        buf = io.BytesIO()
        drawing.fig.savefig(buf, format="png", dpi=80)
        image.value = buf.getvalue()

    slider = ipywidgets.IntSlider(value=0, min=0, max=len(result.t) - 1,
                                  description="step")
    slider.observe(lambda change: show(change["new"]), names="value")
    show(0)
    return ipywidgets.VBox([slider, image])


__all__ = ["FPS_CAP", "FRAME_BUDGET", "GIF_MAX_FPS", "FramePlan", "animate",
           "check_animation_file", "draw_frame", "frame_indices", "notebook_animation",
           "plan_frames", "save_animation", "time_slider"]
