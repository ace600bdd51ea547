"""``casmbd view … --html FILE``: one self-contained HTML file that plays the view offline.

The scene of :mod:`casmbd.viz.view_scene` is built on a private viser server (loopback, no
client), recorded by viser's scene serializer frame by frame — the first frame, then for each
output time a pause of the output step (``insert_sleep``) and the new poses — and written with
the viser client inlined (``StateSerializer.as_html``: JavaScript, styles and the recording as
base64 in one file; no network needed).  Opening the file shows viser's player: a time slider,
play/pause and speed; the recording's clock is the result's time (1x plays in real time).
viser records the scene only, so the file gets a side panel of our own after viser's client
(:mod:`casmbd.viz.view_panel`): an SVG chart per plotted quantity with a cursor that follows
the player's time, and the event list (clicking an event sets the player's time).  Events also
appear as a label in the scene at their time (for a twentieth of the time span).

The file is written atomically (:func:`casmbd.results.atomic_write`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from casmbd.errors import AnalysisError
from casmbd.results import atomic_write
from casmbd.viz.view_panel import inject_panel, panel_html
from casmbd.viz.view_scene import (
    ViewScene,
    free_port,
    require_viser,
    start_server,
    stop_server,
    view_summary,
)
from casmbd.viz.view_types import ViewModel


def check_html_file(path: str | Path) -> Path:
    """Refuse an ``--html`` path that cannot be written (a folder, a missing folder, a suffix
    other than .html/.htm) before any work."""
    path = Path(path)
    if path.is_dir():
        raise AnalysisError(f"--html '{path}' is a directory; give a file name such as "
                            "view.html")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise AnalysisError(f"--html '{path}': folder '{parent}' does not exist")
    if path.suffix.lower() not in (".html", ".htm"):
        raise AnalysisError(f"--html '{path}': the file name must end in .html")
    return path


def render_html(vm: ViewModel, *, forces: bool = True, dark_mode: bool = False) -> str:
    """The self-contained HTML text of the recorded view of ``vm``."""
    viser = require_viser()
    with _QuietServer(viser) as server:
        scene = ViewScene(server, vm, forces=forces)
        scene.set_visible("body_frames", False)
        serializer = server.get_scene_serializer()
        times = np.asarray(vm.times, float)
        for i in range(1, len(times)):
            serializer.insert_sleep(max(float(times[i] - times[i - 1]), 0.0))
            scene.show_frame(i)
        if len(times) == 1:
            serializer.insert_sleep(0.0)
        page = serializer.as_html(dark_mode=dark_mode)
    return inject_panel(page, panel_html(vm, dark_mode=dark_mode))


class _QuietServer:
    """A viser server on a free loopback port without its banner, stopped on exit."""

    def __init__(self, viser):
        self.viser = viser

    def __enter__(self):
        self.server = start_server(self.viser, free_port())
        return self.server

    def __exit__(self, *exc) -> None:
        stop_server(self.server)


def write_html(vm: ViewModel, path: str | Path, *, forces: bool = True,
               dark_mode: bool = False) -> dict:
    """Write the view of ``vm`` to the HTML file ``path`` (atomically).

    Returns ``{"file", "bytes", "frames", "bodies", …}`` (:func:`view_summary`).
    """
    path = check_html_file(path)
    text = render_html(vm, forces=forces, dark_mode=dark_mode)
    try:
        atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    except OSError as exc:
        raise AnalysisError(f"cannot write --html '{path}': {exc.strerror or exc}") from None
    return {"file": str(path), "bytes": path.stat().st_size, **view_summary(vm)}
