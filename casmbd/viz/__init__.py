"""Workbench: figures and animations of results (matplotlib, no pyplot state, Agg-safe).

* :mod:`casmbd.viz.plots` — time histories of a :class:`~casmbd.results.Result`
  (``plot_result``, one function per figure kind) and work-precision plots;
* :mod:`casmbd.viz.geometry` — body-fixed attachment points and their global positions on the
  time grid (numpy only);
* :mod:`casmbd.viz.animation` — still frames and animations of planar and spatial mechanisms,
  GIF (Pillow) and MP4 (only when ffmpeg is installed).

Nothing here is imported by ``import casmbd``; matplotlib is imported when a function runs.
"""

import importlib

#: public name -> defining module, imported on first use (PEP 562): ``casmbd.viz.plots``
#: alone (the CLI's ``plot --kind`` choices) does not load the animation code
_LAZY = {"animate": "animation", "draw_frame": "animation", "notebook_animation": "animation",
         "save_animation": "animation", "Geometry": "geometry", "body_points": "geometry",
         "joint_points": "geometry", "KINDS": "plots", "plot_result": "plots",
         "plot_work_precision": "plots"}

__all__ = ["KINDS", "Geometry", "animate", "body_points", "draw_frame", "joint_points",
           "notebook_animation", "plot_result", "plot_work_precision", "save_animation"]


def __getattr__(name: str):
    """Import the module of a public name on first use and keep the value."""
    if name not in _LAZY:
        raise AttributeError(f"module 'casmbd.viz' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"casmbd.viz.{_LAZY[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
