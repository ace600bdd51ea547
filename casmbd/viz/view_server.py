"""``casmbd view``: the live 3-D view of a mechanism or a result in the browser (viser).

:func:`view` starts a viser server bound to the loopback interface only (127.0.0.1; the port
given, else a free one) and returns a :class:`ViewHandle` (``.url``, ``.stop()``; in a
notebook it displays as an ``<iframe>`` of the page).  The page shows the scene of
:mod:`casmbd.viz.view_scene` and a side panel:

* **Playback** — the time slider (its marks are the result's event times), play/pause, speed
  (0.25x … 4x, real time at 1x), loop, and the list of events with a "go to" choice;
* **Show** — toggles for body frames, joint frames and axes, markers, traces and force arrows,
  and the deformation scale of flexible bodies (the view is rebuilt for a new scale);
* **Plots** — one uPlot chart per :attr:`ViewModel.series`, with a dot at the shown time.

Playing advances the slider from a server thread at up to :data:`PLAY_FPS` updates per second
(wall clock × speed); every change of the slider, from the page or from the thread, moves the
scene to the nearest output time (:meth:`ViewScene.show_frame`).
"""

from __future__ import annotations

import html
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from casmbd.errors import AnalysisError, ResultFileError
from casmbd.io.scene import load_result, load_scene
from casmbd.ocp.solution import OcpSolution
from casmbd.viz.view_html import write_html
from casmbd.viz.view_model import ViewModel, view_model
from casmbd.viz.view_scene import (
    ViewScene,
    frame_interval,
    free_port,
    require_viser,
    start_server,
    stop_server,
    view_summary,
)

#: updates per second of the playing slider (the browser renders at its own rate)
PLAY_FPS = 60.0
#: playback speeds offered (factor on real time)
SPEEDS = ("0.25x", "0.5x", "1x", "2x", "4x")
#: plot updates per second while playing (the dot at the shown time)
PLOT_FPS = 8.0


def load_source(path: str | Path):
    """A scene file (TOML or URDF) as a Mechanism, or a result / OCP solution file (.npz)."""
    path = Path(path)
    if not path.is_file():
        raise AnalysisError(f"view: no file '{path}'")
    if path.suffix.lower() != ".npz":
        return load_scene(path)
    try:
        return load_result(path)
    except ResultFileError as exc:
        try:
            return OcpSolution.load(path)
        except ResultFileError:
            raise exc from None


def make_view_model(source, mechanism=None, *, deformation_scale: float = 1.0,
                    forces: bool = False, max_frames: int | None = None) -> ViewModel:
    """The :class:`ViewModel` of a Mechanism, Result, OcpSolution, file path or ViewModel."""
    if isinstance(source, ViewModel):
        return source
    if isinstance(source, (str, Path)):
        source = load_source(source)
    return view_model(source, mechanism, deformation_scale=deformation_scale, forces=forces,
                      max_frames=max_frames)


def _y_range(y: np.ndarray) -> list[float]:
    """A fixed y range of a chart: the finite values' span and 5 % on each side (uPlot's own
    auto-range loses the whole chart when the "now" series' first value is missing)."""
    finite = y[np.isfinite(y)]
    if not len(finite):
        return [-1.0, 1.0]
    lo, hi = float(finite.min()), float(finite.max())
    # at least 0.1 % of the magnitude: a quantity constant to rounding (an energy conserved
    # to 1e-9) is drawn flat, not as magnified noise
    span = max(hi - lo, 1e-3 * max(abs(lo), abs(hi)), 1e-9)
    mid = 0.5 * (lo + hi)
    return [mid - 0.55 * span, mid + 0.55 * span]


class ViewHandle:
    """A running live view: :attr:`url`, :attr:`server` (the ``viser.ViserServer``),
    :attr:`scene` (:class:`ViewScene`); :meth:`stop` ends it, :meth:`wait` blocks until
    Ctrl-C.  ``set_time(t)`` moves the view (and the slider) to the output nearest ``t``."""

    def __init__(self, server, scene: ViewScene, url: str, gui: _Gui):
        self.server, self.scene, self.url, self._gui = server, scene, url, gui
        self.stopped = False

    @property
    def view_model(self) -> ViewModel:
        return self.scene.vm

    def set_time(self, t: float) -> None:
        self._gui.slider.value = float(self.scene.vm.times[self.scene.index_at(t)])

    def play(self, playing: bool = True) -> None:
        self._gui.set_playing(playing)

    def stop(self) -> None:
        """Stop the playing thread and the server (idempotent)."""
        if self.stopped:
            return
        self.stopped = True
        self._gui.close()
        stop_server(self.server)

    def wait(self) -> None:
        """Block until Ctrl-C (KeyboardInterrupt), then stop quietly."""
        try:
            while not self.stopped:
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            self.stop()

    def __enter__(self) -> ViewHandle:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def __repr__(self) -> str:
        state = "stopped" if self.stopped else "running"
        return f"<casmbd view {state} at {self.url}>"

    def _repr_html_(self) -> str:
        """A notebook shows the live page in an iframe (the server keeps running)."""
        return (f'<iframe src="{html.escape(self.url)}" width="100%" height="560" '
                f'style="border:0"></iframe>')


class _Gui:
    """The side panel: playback, toggles, events and plots."""

    def __init__(self, server, scene: ViewScene,
                 rebuild: Callable[[float], ViewModel] | None, deformation_scale: float):
        self.server, self.scene, self.rebuild = server, scene, rebuild
        vm = scene.vm
        gui = server.gui
        self.playing = False
        self.speed = 1.0
        self._stop = threading.Event()
        self._lock = threading.RLock()
        self._last_plot = 0.0
        times = vm.times
        t0, t1 = float(times[0]), float(times[-1])
        if vm.title:
            gui.add_markdown(f"**{html.escape(vm.title)}**")
        with gui.add_folder("Playback"):
            step = frame_interval(times)
            marks = tuple((float(t), "") for t, _ in vm.events) or None
            self.slider = gui.add_slider("time [s]", min=t0, max=max(t1, t0 + step),
                                         step=step, initial_value=t0, marks=marks,
                                         disabled=len(times) < 2)
            self.slider.on_update(lambda _: self._on_time())
            self.play_button = gui.add_button("Play", disabled=len(times) < 2)
            self.play_button.on_click(lambda _: self.set_playing(not self.playing))
            self.speed_choice = gui.add_dropdown("speed", SPEEDS, initial_value="1x")
            self.speed_choice.on_update(
                lambda _: setattr(self, "speed", float(self.speed_choice.value[:-1])))
            self.loop = gui.add_checkbox("loop", initial_value=True)
            if vm.events:
                lines = [f"- t = {t:.6g} s: {html.escape(str(lab))}" for t, lab in vm.events]
                gui.add_markdown("**Events**\n\n" + "\n".join(lines[:200])
                                 + (f"\n- … {len(lines) - 200} more" if len(lines) > 200
                                    else ""))
                labels = [f"{i + 1}: t = {t:.6g} s {lab}" for i, (t, lab) in
                          enumerate(vm.events[:200])]
                self.goto = gui.add_dropdown("go to event", ("—", *labels), initial_value="—")
                self.goto.on_update(lambda _: self._goto())
        with gui.add_folder("Show"):
            for group, label, default in (("body_frames", "body frames", False),
                                          ("frames", "joint frames and axes", True),
                                          ("markers", "markers", True),
                                          ("traces", "traces", True),
                                          ("forces", "force arrows", True)):
                if not scene.groups[group]:
                    continue
                box = gui.add_checkbox(label, initial_value=default)
                scene.set_visible(group, default)
                box.on_update(lambda _, g=group, b=box: scene.set_visible(g, b.value))
            if vm.flexible and rebuild is not None:
                self.deform = gui.add_number("deformation scale", initial_value=deformation_scale,
                                             min=0.01, step=0.5)
                self.deform.on_update(lambda _: self._rescale())
        self.plots = []
        shown = [s for s in vm.series if np.isfinite(np.asarray(s.values, float)).any()]
        if shown:
            with gui.add_folder("Plots"):
                for s in shown:
                    self.plots.append((s, self._plot(s)))
        self.thread = threading.Thread(target=self._play_loop, name="casmbd-view-play",
                                       daemon=True)
        self.thread.start()

    def _plot(self, s):
        """One uPlot chart of series ``s`` with a dot at the shown time."""
        from viser import uplot

        t = np.ascontiguousarray(self.scene.vm.times, dtype=np.float64)
        y = np.ascontiguousarray(s.values, dtype=np.float64)  # uPlot reads the raw buffer
        dot = np.full_like(y, np.nan)
        dot[0] = y[0]
        label = f"{s.name} [{s.unit}]" if s.unit else s.name
        return self.server.gui.add_uplot(
            data=(t, y, dot),
            series=(uplot.Series(label="t [s]"),
                    uplot.Series(label=label, stroke="#1f77b4", width=1.5),
                    uplot.Series(label="now", stroke="#d62728", width=0,
                                 points={"show": True, "size": 8, "fill": "#d62728"})),
            scales={"x": {"time": False}, "y": {"auto": False, "range": _y_range(y)}},
            title=label, aspect=1.6)

    def _update_plots(self, force: bool = False) -> None:
        now = time.monotonic()
        if not self.plots or (not force and now - self._last_plot < 1.0 / PLOT_FPS):
            return
        self._last_plot = now
        i = self.scene.index
        t = np.ascontiguousarray(self.scene.vm.times, dtype=np.float64)
        for s, handle in self.plots:
            y = np.ascontiguousarray(s.values, dtype=np.float64)
            dot = np.full_like(y, np.nan)
            dot[i] = y[i]
            handle.data = (t, y, dot)

    def _on_time(self) -> None:
        # the page (websocket thread) and the play thread both move the slider
        with self._lock:
            i = self.scene.index_at(float(self.slider.value))
            if i != self.scene.index:
                self.scene.show_frame(i)
                self._update_plots(force=not self.playing)

    def _goto(self) -> None:
        choice = self.goto.value
        if choice == "—":
            return
        k = int(choice.split(":", 1)[0]) - 1
        self.set_playing(False)
        self.slider.value = float(self.scene.vm.times[self.scene.index_at(
            self.scene.vm.events[k][0])])

    def _rescale(self) -> None:
        scale = float(self.deform.value)
        if not np.isfinite(scale) or scale <= 0:
            return
        vm = self.rebuild(scale)
        with self._lock:
            self.scene.vm.flexible = vm.flexible
            i, self.scene.index = self.scene.index, -1
            self.scene.show_frame(i)

    def set_playing(self, playing: bool) -> None:
        times = self.scene.vm.times
        if playing and self.scene.index >= len(times) - 1:
            self.slider.value = float(times[0])  # play again from the start
        self.playing = bool(playing) and len(times) > 1
        self.play_button.label = "Pause" if self.playing else "Play"

    def _play_loop(self) -> None:
        times = self.scene.vm.times
        t0, t1 = float(times[0]), float(times[-1])
        last = time.monotonic()
        t = t0
        while not self._stop.wait(1.0 / PLAY_FPS):
            now = time.monotonic()
            dt, last = now - last, now
            if not self.playing:
                t = float(times[max(self.scene.index, 0)])
                continue
            t += dt * self.speed
            if t > t1:
                if self.loop.value:
                    t = t0
                else:
                    t = t1
                    self.set_playing(False)
            try:
                self.slider.value = t
                self._update_plots()
            except Exception:  # the server stopped under us: end the thread quietly
                return

    def close(self) -> None:
        self._stop.set()
        if self.thread.is_alive() and self.thread is not threading.current_thread():
            self.thread.join(timeout=2.0)


def serve(vm: ViewModel, *, port: int | None = None, forces: bool = True,
          rebuild: Callable[[float], ViewModel] | None = None,
          deformation_scale: float = 1.0) -> ViewHandle:
    """Start the live view of ``vm`` on 127.0.0.1:``port`` (a free port when None)."""
    viser = require_viser()
    if port is not None and not 0 < int(port) < 65536:
        raise AnalysisError(f"view: --port {port} is not a TCP port (1 … 65535)")
    port = free_port() if port is None else int(port)
    try:
        server = start_server(viser, port)
    except OSError as exc:
        raise AnalysisError(f"view: cannot listen on 127.0.0.1:{port}: "
                            f"{exc.strerror or exc}") from None
    actual = server.get_port()
    if actual != port and port is not None:
        # viser moves to the next free port when the one asked is taken; say which one
        print(f"note: port {port} is in use; the view listens on {actual}", file=sys.stderr)
    try:
        scene = ViewScene(server, vm, forces=forces)
        gui = _Gui(server, scene, rebuild, deformation_scale)
    except BaseException:
        stop_server(server)
        raise
    return ViewHandle(server, scene, f"http://127.0.0.1:{actual}/", gui)


def view(source, mechanism=None, *, port: int | None = None, deformation_scale: float = 1.0,
         forces: bool = False, max_frames: int | None = None, open_browser: bool = False,
         html_file: str | Path | None = None):
    """Show ``source`` in 3-D in the browser: a live view, or a self-contained HTML file.

    Parameters
    ----------
    source : Mechanism, Result, OcpSolution, ViewModel or path
        A mechanism at its initial pose, a result along its time grid, an OCP solution's
        trajectory, or the path of a scene (TOML, URDF) or result/solution (.npz) file.
    mechanism : Mechanism, optional
        Overrides the mechanism embedded in a result.
    port : int, optional
        TCP port on 127.0.0.1 (default: a free one).
    deformation_scale : float
        Magnification of flexible bodies' elastic displacements.
    forces : bool
        Draw force arrows.
    max_frames : int, optional
        Show at most this many output times (first, last and event times kept).
    open_browser : bool
        Open the page in the default web browser.
    html_file : path, optional
        Write one self-contained HTML file that plays offline instead of serving
        (returns the summary dict of :func:`casmbd.viz.view_html.write_html`).

    Returns
    -------
    ViewHandle
        ``.url``, ``.stop()``; in a notebook the page displays inline.
    """
    vm = make_view_model(source, mechanism, deformation_scale=deformation_scale,
                         forces=forces, max_frames=max_frames)
    if html_file is not None:
        return write_html(vm, html_file, forces=forces)
    rebuild = None
    if vm.flexible and not isinstance(source, ViewModel):
        def rebuild(scale: float) -> ViewModel:
            return make_view_model(source, mechanism, deformation_scale=scale,
                                   forces=forces, max_frames=max_frames)
    handle = serve(vm, port=port, forces=forces, rebuild=rebuild,
                   deformation_scale=deformation_scale)
    if open_browser:
        import webbrowser

        webbrowser.open(handle.url)
    return handle


__all__ = ["ViewHandle", "load_source", "make_view_model", "serve", "view", "view_summary"]
