"""The command-line parsers of the verbs defined outside :mod:`casmbd.cli` itself (``plot``,
``animate``, ``sweep``, ``sensitivity``, ``bench``): building the parser needs only these, not
the verbs' modules, so that ``casmbd info`` does not load the plots, the sweeps or the OCP (the
handlers are imported when their verb runs: ``casmbd.cli.VERBS``).
"""

from __future__ import annotations

import argparse

from casmbd.cli.common import (
    add_dpi_flag,
    add_mode_flag,
    add_output_flags,
    positive_float,
    positive_int,
)
from casmbd.viz.plots import KINDS


def add_workbench_verbs(sub) -> None:
    """The ``plot`` and ``animate`` verbs (figures and animations of results)."""
    p = sub.add_parser("plot", help="figures of a saved result against time")
    p.add_argument("result", help="result file (.npz) written with --out")
    p.add_argument("--what", "--kind", dest="kind", action="append", default=None,
                   metavar="KIND",
                   help=f"what to draw: {', '.join(KINDS)} (repeatable or comma-separated; "
                        "default: at most 6 panels, the motion, the efforts, the energy and "
                        "max |C|); each kind gets one panel per unit")
    p.add_argument("--element", action="append", default=None, metavar="NAME",
                   help="draw only the lines of this body, joint, driver or actuator "
                        "(repeatable)")
    p.add_argument("--euler", choices=("xyz", "zxz"), default="xyz",
                   help="Euler angles drawn for spatial bodies instead of quaternions "
                        "(default xyz, regular at the identity; zxz is singular there)")
    p.add_argument("--out", required=True, help="figure file (.png, .pdf, .svg)")
    add_dpi_flag(p, 100.0)
    add_output_flags(p)

    p = sub.add_parser("animate", help="animation (.gif, .mp4 with ffmpeg) or still frame "
                                       "(.png) of a scene or a saved result")
    p.add_argument("source", help="scene file (TOML; simulated first) or result file (.npz)")
    p.add_argument("--out", required=True,
                   help=".gif (Pillow), .mp4 (needs ffmpeg) or .png/.pdf/.svg (a still frame "
                        "with earlier poses faded)")
    p.add_argument("--t-end", type=positive_float, default=2.0,
                   help="final time of the simulation of a scene [s] (default 2)")
    p.add_argument("--steps", type=positive_int, default=50,
                   help="output intervals of the simulation of a scene (default 50)")
    p.add_argument("--max-frames", type=positive_int, default=None,
                   help="show at most this many evenly spread output steps (default 301)")
    p.add_argument("--fps", type=positive_float, default=None,
                   help="highest frame rate (default 30; a GIF plays at most 50)")
    p.add_argument("--speed", type=positive_float, default=1.0,
                   help="playback speed factor (default 1: real time; 2: twice as fast)")
    p.add_argument("--trace", action="append", default=None, metavar="MARKER",
                   help="draw the path of this marker (repeatable; 'all' for every marker)")
    p.add_argument("--deformation-scale", type=positive_float, default=1.0,
                   help="magnify the elastic displacements of flexible bodies (default 1; "
                        "the picture says so when it is not 1)")
    add_dpi_flag(p, 80.0)
    add_mode_flag(p)
    add_output_flags(p)


def add_sweep_verb(sub) -> None:
    """The ``sweep`` verb (one analysis at many parameter values, casmbd.analysis.studies.sweep)."""
    p = sub.add_parser("sweep", help="parameter sweep: one analysis at many values of the "
                                     "scene's [parameters]")
    p.add_argument("scene", help="scene file (TOML) with a [parameters] table")
    p.add_argument("--param", action="append", required=True, metavar="NAME=VALUES",
                   help="NAME=A:B:N (N values from A to B inclusive), NAME=A,B,C or NAME=A; "
                        "repeat for a grid product")
    p.add_argument("--analysis", choices=("simulate", "kinematics", "inverse", "statics"),
                   default="simulate", help="analysis run at every point (default simulate)")
    p.add_argument("--t-end", type=positive_float, default=None, help="final time [s]")
    p.add_argument("--steps", type=positive_int, default=None,
                   help="number of output intervals (N + 1 output times from 0 to T)")
    p.add_argument("--output", action="append", default=None, metavar="REDUCTION:COLUMN",
                   help="scalar output per point, e.g. final:q[crank.angle], "
                        "max:body.rod.angle, energy_drift (repeatable; default final q, "
                        "largest constraint violation, energy drift)")
    p.add_argument("--workers", type=positive_int, default=None,
                   help="local worker processes (default: serial in this process)")
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help="Dask scheduler address (needs dask.distributed: casmbd[sweep])")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder for point_XXX.npz, sweep.csv and sweep.npz")
    add_output_flags(p)
    add_mode_flag(p)


def add_sensitivity_verb(sub) -> None:
    """The ``sensitivity`` verb (casmbd.analysis.studies.sensitivity)."""
    p = sub.add_parser("sensitivity", help="exact derivatives of simulation outputs with "
                                           "respect to scene parameters (IDAS)")
    p.add_argument("scene", help="scene file (TOML) with a [parameters] table")
    p.add_argument("--output", action="append", required=True, metavar="EXPR",
                   help="output: an expression at t_end (e.g. tip_x) or 'integral: EXPR' "
                        "(e.g. 'integral: O_Fy'); repeatable")
    p.add_argument("--param", action="append", default=None, metavar="NAME",
                   help="parameter to differentiate with respect to (default: all); repeatable")
    p.add_argument("--t-end", type=positive_float, required=True, help="final time [s]")
    p.add_argument("--method", choices=("forward", "adjoint"), default="forward",
                   help="IDAS forward sensitivities (per parameter) or adjoint (per output)")
    p.add_argument("--rtol", type=positive_float, default=1e-10, help="relative tolerance")
    add_output_flags(p)


def add_bench_verb(sub) -> None:
    """The ``bench`` verb: the benchmark suite of a source checkout (``python -m benchmarks``)."""
    p = sub.add_parser("bench", help="run the benchmark suite of a casmbd checkout "
                                     "(python -m benchmarks)")
    p.add_argument("--quick", action="store_true",
                   help="a few minutes: check the printed errors against their bounds")
    p.add_argument("--update-docs", action="store_true",
                   help="regenerate docs/performance.md (full suite only)")
    add_output_flags(p)


def add_view_verb(sub) -> None:
    """The ``view`` verb: 3-D view in the browser (casmbd.cli.view; needs casmbd[view])."""
    p = sub.add_parser("view", help="3-D view of a scene, result or OCP solution in the "
                                    "browser (live server on 127.0.0.1, or --html FILE)")
    p.add_argument("source", help="scene file (TOML/URDF: the initial pose), result file or "
                                  "OCP solution file (.npz: the motion)")
    p.add_argument("--port", type=_port, default=None,
                   help="TCP port on 127.0.0.1 (default: a free one; the URL is printed on "
                        "stderr)")
    p.add_argument("--html", default=None, metavar="FILE",
                   help="write one self-contained .html file that plays offline, no server")
    p.add_argument("--no-browser", action="store_true",
                   help="do not open the page in the default browser")
    p.add_argument("--deformation-scale", type=positive_float, default=1.0,
                   help="magnify the elastic displacements of flexible bodies (default 1)")
    p.add_argument("--forces", action="store_true", help="draw force arrows")
    p.add_argument("--max-frames", type=positive_int, default=None,
                   help="show at most this many output times (first, last and events kept)")
    add_output_flags(p)


def _port(text: str) -> int:
    """A TCP port number 1 … 65535."""
    port = positive_int(text)
    if port > 65535:
        raise argparse.ArgumentTypeError(f"must be a TCP port 1 … 65535, got {text}")
    return port
