"""The arguments of every shipped verb of the ``casmbd`` command: one function per verb, named
in its registration (:mod:`casmbd.cli`, :func:`casmbd.cli.registry.register_verb`).  Building
the parser needs only these, not the verbs' modules, so that ``casmbd info`` does not load the
simulation, the plots, the sweeps or the OCP (the handlers are imported when their verb runs:
``casmbd.cli.registry.VERBS``).

The verbs that read a scene file get its positional ``scene``, ``--json``, ``--debug`` and
``--mode`` from the command (``shared=True``); ``plot`` … ``view`` add every argument
themselves, in their own order (``shared=False``).
"""

from __future__ import annotations

import argparse

from casmbd.analysis.formulations import FORMULATIONS
from casmbd.analysis.integrators.kinds import INTEGRATORS
from casmbd.analysis.studies.sweep_registry import SWEEPABLE
from casmbd.cli.common import (
    add_dpi_flag,
    add_mode_flag,
    add_output_flags,
    nonnegative_float,
    positive_float,
    positive_int,
)
from casmbd.viz.plots import KINDS


def _grid(p) -> None:
    """The output time grid of the time-domain verbs, and their ``--out``."""
    p.add_argument("--t-end", type=positive_float, required=True, help="final time [s]")
    p.add_argument("--steps", type=positive_int, required=True,
                   help="number of output intervals (N + 1 output times from 0 to T)")
    p.add_argument("--out", help="save every array to this .npz file, or one column per "
                                 "scalar series to this .csv file (the suffix decides)")


def _redundancy(p) -> None:
    """``--redundancy`` of the one-instant verbs ("minimum_norm", keep every row, is
    simulate's)."""
    p.add_argument("--redundancy", choices=("auto", "remove"), default="auto",
                   help="redundant constraint equations: removed and named (both choices; "
                        "reactions they leave undetermined are the minimum-norm ones)")


def kinematics_arguments(p) -> None:
    """``kinematics`` and ``inverse``: the time grid and ``--redundancy``."""
    _grid(p)
    _redundancy(p)


def statics_arguments(p) -> None:
    """``statics``: ``--redundancy``, ``--method``, ``--stable``."""
    _redundancy(p)
    p.add_argument("--method", choices=("augmented", "reduced"), default="augmented",
                   help="Newton on (q, lambda) (default) or on the independent coordinates")
    p.add_argument("--stable", action="store_true",
                   help="find a stable equilibrium (descend the potential energy) instead of "
                        "the one nearest the initial configuration, stable or not")


def simulate_arguments(p) -> None:
    """``simulate``: the time grid, the formulation, the integrator and their options."""
    _grid(p)
    p.add_argument("--rtol", type=positive_float, default=1e-8, help="relative tolerance")
    p.add_argument("--atol", type=positive_float, default=None,
                   help="absolute tolerance (default: rtol)")
    p.add_argument("--formulation", choices=FORMULATIONS, default=None,
                   help="equations of motion (default augmented_lagrangian; articulated for "
                        "constraint-free trees in joint coordinates)")
    p.add_argument("--redundancy", choices=("auto", "remove", "minimum_norm"), default="auto",
                   help="redundant constraint equations: remove the dependent rows or keep them "
                        "with minimum-norm multipliers (default: by formulation)")
    p.add_argument("--integrator", choices=INTEGRATORS, default=None,
                   help="time integrator (default per formulation)")
    p.add_argument("--projection", action="store_true",
                   help="project positions and velocities onto the constraints at every output")
    p.add_argument("--step", type=positive_float, default=None,
                   help="step size of the fixed-step integrators rk4/abm")
    p.add_argument("--max-steps", type=positive_int, default=None,
                   help="most steps per output interval of the variable-step integrators "
                        "(default 500000; 20000 for partitioning/nullspace)")
    p.add_argument("--max-events", type=positive_int, default=None,
                   help="with impacts: stop (keeping the results) after this many events "
                        "(default: the scene's [simulation] max_events, else 10000)")
    p.add_argument("--rest-velocity", type=nonnegative_float, default=None, metavar="M/S",
                   help="with impacts: a rebound slower than this closes the contact "
                        "(default: [simulation] rest_velocity, else sqrt(2 g 1e-9 m))")


def linearize_arguments(p) -> None:
    """``linearize``: where to linearize (initial pose, equilibrium, a stored state)."""
    _redundancy(p)
    where = p.add_mutually_exclusive_group()
    where.add_argument("--at-equilibrium", action="store_true",
                       help="find the static equilibrium (as the statics verb) and linearize "
                            "there")
    where.add_argument("--from", dest="from_result", metavar="RESULT.npz", default=None,
                       help="linearize about the state stored in this result (of the same "
                            "scene) at the output time nearest --time")
    where.add_argument("--steady-motion", action="store_true",
                       help="linearize about the steady motion from the initial state (a "
                            "wheel or bicycle rolling): the cyclic coordinates (position on "
                            "the plane, heading, spins) are removed, the eigenvalues of the "
                            "rest reported")
    p.add_argument("--time", type=float, default=None,
                   help="with --from: the time of the stored state (nearest output time)")
    p.add_argument("--stable", action="store_true",
                   help="with --at-equilibrium: about a stable equilibrium (as statics "
                        "--stable) instead of the one nearest the initial configuration")


def ocp_arguments(p) -> None:
    """``ocp``: the solution file, the mesh, the transcription, the replay and a figure."""
    p.add_argument("--out", help="save the solution (t, q, v, u, statistics) to this .npz "
                                 "file, or its result on the mesh nodes to this .csv file")
    p.add_argument("--intervals", type=positive_int, default=None,
                   help="number of control intervals (overrides the table)")
    p.add_argument("--transcription", choices=("radau", "legendre", "multiple_shooting"),
                   default=None, help="overrides the table")
    p.add_argument("--no-replay", action="store_true",
                   help="skip the forward replay of the optimal controls")
    p.add_argument("--plot", default=None, help="save a figure of coordinates and controls")


def plot_arguments(p) -> None:
    """``plot``: figures of a saved result."""
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


def animate_arguments(p) -> None:
    """``animate``: an animation or a still frame of a scene or a saved result."""
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


def sweep_arguments(p) -> None:
    """``sweep``: one analysis at many parameter values (casmbd.analysis.studies.sweep)."""
    p.add_argument("scene", help="scene file (TOML) with a [parameters] table")
    p.add_argument("--param", action="append", required=True, metavar="NAME=VALUES",
                   help="NAME=A:B:N (N values from A to B inclusive), NAME=A,B,C or NAME=A; "
                        "repeat for a grid product")
    p.add_argument("--analysis", choices=tuple(SWEEPABLE),  # the sweep's registry
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


def sensitivity_arguments(p) -> None:
    """``sensitivity``: exact derivatives of outputs (casmbd.analysis.studies.sensitivity)."""
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


def bench_arguments(p) -> None:
    """``bench``: the benchmark suite of a source checkout (``python -m benchmarks``)."""
    p.add_argument("--quick", action="store_true",
                   help="a few minutes: check the printed errors against their bounds")
    p.add_argument("--update-docs", action="store_true",
                   help="regenerate docs/performance.md (full suite only)")
    add_output_flags(p)


def export_arguments(p) -> None:
    """``export``: the dynamics as standalone C99 (casmbd.cli.export, docs/export.md)."""
    p.add_argument("scene", help="scene file (TOML) or robot (.urdf, .xml)")
    p.add_argument("--floating-base", action="store_true",
                   help="a bare .urdf: its root link floats free (as [scene] "
                        "floating_base = true)")
    p.add_argument("--c", required=True, metavar="DIR",
                   help="output directory of the C files (created; must be empty unless "
                        "--force)")
    p.add_argument("--functions", default=None,
                   help="comma-separated: inverse_dynamics, forward_dynamics, mass_matrix, "
                        "bias_forces, forward_kinematics, jacobian, regressor (default: all "
                        "but regressor)")
    p.add_argument("--prefix", default=None,
                   help="C prefix of the public symbols and files (default: the scene's name)")
    p.add_argument("--actuated", default=None,
                   help="closed chains: comma-separated coordinates carrying the efforts of "
                        "the inverse dynamics (default: every one, least-norm efforts)")
    p.add_argument("--frames", default=None,
                   help="jacobian: comma-separated bodies or markers whose Jacobian is "
                        "exported (default every frame)")
    p.add_argument("--friction", default="",
                   help="regressor: comma-separated friction laws whose coefficients join "
                        "its parameters (viscous, coulomb; default none)")
    p.add_argument("--parameters", choices=("constant", "input"), default="constant",
                   help="the scene's [parameters]: folded in as constants (default) or an "
                        "input (the work struct's p)")
    p.add_argument("--cmake", action="store_true", help="also write a CMakeLists.txt")
    p.add_argument("--force", action="store_true",
                   help="overwrite the files of a non-empty directory")
    add_output_flags(p)


def view_arguments(p) -> None:
    """``view``: 3-D view in the browser (casmbd.cli.view; needs casmbd[view])."""
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


def excite_arguments(p) -> None:
    """``excite``: the excitation design's period, limits, size and ``--out``."""
    p.add_argument("--period", type=positive_float, required=True,
                   help="period T of the Fourier series [s]")
    p.add_argument("--acceleration", type=positive_float, required=True,
                   help="joint acceleration limit [rad/s² or m/s²] (URDF has none)")
    p.add_argument("--harmonics", type=positive_int, default=5,
                   help="harmonics per joint (default 5)")
    p.add_argument("--samples", type=positive_int, default=60,
                   help="regressor samples per period in the objective (default 60)")
    p.add_argument("--friction", default="viscous,coulomb",
                   help="friction laws whose coefficients join the regressor: viscous, "
                        "coulomb, both comma-separated (default) or none")
    p.add_argument("--torque-limits", action="store_true",
                   help="also |tau| <= the URDF effort limits at the model's parameters")
    p.add_argument("--max-iter", type=positive_int, default=300,
                   help="IPOPT iterations (default 300)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the random feasible start (default 0)")
    p.add_argument("--rate", type=positive_float, default=100.0,
                   help="sampling rate of --out [Hz] (default 100)")
    p.add_argument("--out", help="write one period as CSV: t, q.<coordinate>, v.…, a.…")


def identify_arguments(p) -> None:
    """``identify``: the measurement file, friction laws, filter, estimator and ``--out``."""
    p.add_argument("--data", required=True,
                   help="measurement CSV: t, q.<coordinate>, tau.<coordinate> [, v.…, a.…] "
                        "(docs/identification.md)")
    p.add_argument("--friction", default="viscous,coulomb",
                   help="friction laws identified on every joint: viscous, coulomb, both "
                        "comma-separated (default) or none")
    p.add_argument("--cutoff", type=positive_float, default=None,
                   help="zero-phase Butterworth low-pass cut-off [Hz] applied to q and tau "
                        "(required when the file has no v. and a. columns)")
    p.add_argument("--decimate", type=positive_int, default=1,
                   help="keep every K-th sample after filtering (default 1)")
    p.add_argument("--ols", action="store_true",
                   help="ordinary least squares (default: weighted by each joint's residual "
                        "deviation, Gautier)")
    p.add_argument("--no-consistent", action="store_true",
                   help="skip the physically consistent standard parameters (IPOPT)")
    p.add_argument("--out", help="write the identified model: a .urdf for a URDF, a .toml "
                                 "for a scene (masses, centres of mass, inertias, friction)")
