"""Workbench: figures and animations of results (matplotlib, no pyplot state, Agg-safe).

* :mod:`casmbd.viz.plots` — time histories of a :class:`~casmbd.results.Result`
  (``plot_result``, one function per figure kind) and work-precision plots;
* :mod:`casmbd.viz.geometry` — body-fixed attachment points and their global positions on the
  time grid (numpy only);
* :mod:`casmbd.viz.animation` — still frames and animations of planar and spatial mechanisms,
  GIF (Pillow) and MP4 (only when ffmpeg is installed).

Nothing here is imported by ``import casmbd``; matplotlib is imported when a function runs.
"""

from casmbd.viz.animation import animate, draw_frame, notebook_animation, save_animation
from casmbd.viz.geometry import Geometry, body_points, joint_points
from casmbd.viz.plots import KINDS, plot_result, plot_work_precision

__all__ = ["KINDS", "Geometry", "animate", "body_points", "draw_frame", "joint_points",
           "notebook_animation", "plot_result", "plot_work_precision", "save_animation"]
