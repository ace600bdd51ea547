"""Command-line interface: ``casmbd VERB SCENE [options]``.

Verbs: ``info`` (coordinates, constraints, degrees of freedom, dependent equations),
``kinematics`` (positions, velocities and accelerations on a time grid), ``simulate`` (forward
dynamics), ``inverse`` (driver and actuator efforts), ``statics`` (equilibrium and its
stability), ``linearize`` (frequencies, damping ratios, state space) and ``sweep`` (one
analysis at many parameter values).  Every verb prints a
readable summary, or with ``--json`` exactly one JSON object on stdout; ``--out FILE.npz`` saves
every array.  Errors end with a non-zero exit status and one ``error: …`` line on stderr
(a traceback only with ``--debug``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from casmbd import interrupts
from casmbd.errors import AnalysisError, AssemblyError, CasmbdError, SceneError
from casmbd.limits import MAX_FRAMES, MAX_STEPS, check_count
from casmbd.results import _json_default

EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    """ArgumentParser that reports one ``error: …`` line instead of usage + exit."""

    def error(self, message: str):
        raise _UsageError(message)


def _positive_int(text: str) -> int:
    try:
        val = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if not 1 <= val <= MAX_STEPS:
        raise argparse.ArgumentTypeError(f"must be between 1 and {MAX_STEPS}, got {text}")
    return val


def _positive_float(text: str) -> float:
    try:
        val = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(val) or val <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return val


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``casmbd`` command."""
    parser = _Parser(prog="casmbd", description="Dynamics of constrained mechanisms on CasADi.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="verb", parser_class=_Parser)

    def common(p):
        p.add_argument("scene", help="scene file (TOML)")
        p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
        p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
        p.add_argument("--mode", choices=("auto", "compiled", "vm"), default="auto",
                       help="compile equations to C (default auto) or use CasADi's VM")

    def grid(p):
        p.add_argument("--t-end", type=_positive_float, required=True, help="final time [s]")
        p.add_argument("--steps", type=_positive_int, required=True,
                       help="number of output intervals (N + 1 output times from 0 to T)")
        p.add_argument("--out", help="save every array to this .npz file")

    p = sub.add_parser("info", help="coordinates, constraints, degrees of freedom")
    common(p)
    p = sub.add_parser("kinematics", help="kinematic analysis of a driven mechanism")
    common(p)
    grid(p)

    p = sub.add_parser("inverse", help="inverse dynamics: driver efforts and reactions")
    common(p)
    grid(p)

    p = sub.add_parser("statics", help="static equilibrium, reactions and stability")
    common(p)
    p.add_argument("--method", choices=("augmented", "reduced"), default="augmented",
                   help="Newton on (q, lambda) (default) or on the independent coordinates")

    from casmbd.analysis.integrators import INTEGRATORS
    from casmbd.system.formulations import FORMULATIONS

    p = sub.add_parser("simulate", help="forward dynamics")
    common(p)
    grid(p)
    p.add_argument("--rtol", type=_positive_float, default=1e-8, help="relative tolerance")
    p.add_argument("--atol", type=_positive_float, default=None,
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
    p.add_argument("--step", type=_positive_float, default=None,
                   help="step size of the fixed-step integrators rk4/abm")
    p.add_argument("--max-steps", type=_positive_int, default=None,
                   help="most steps per output interval of the variable-step integrators "
                        "(default 500000; 20000 for partitioning/nullspace)")
    p = sub.add_parser("linearize", help="natural frequencies, linearized equations and "
                                         "stability about the initial configuration, the "
                                         "static equilibrium or a stored state")
    common(p)
    where = p.add_mutually_exclusive_group()
    where.add_argument("--at-equilibrium", action="store_true",
                       help="find the static equilibrium (as the statics verb) and linearize "
                            "there")
    where.add_argument("--from", dest="from_result", metavar="RESULT.npz", default=None,
                       help="linearize about the state stored in this result (of the same "
                            "scene) at the output time nearest --time")
    p.add_argument("--time", type=float, default=None,
                   help="with --from: the time of the stored state (nearest output time)")
    p = sub.add_parser("ocp", help="trajectory optimisation: the scene's [ocp] table")
    common(p)
    p.add_argument("--out", help="save the solution (t, q, v, u, statistics) to this .npz file")
    p.add_argument("--intervals", type=_positive_int, default=None,
                   help="number of control intervals (overrides the table)")
    p.add_argument("--transcription", choices=("radau", "legendre", "multiple_shooting"),
                   default=None, help="overrides the table")
    p.add_argument("--no-replay", action="store_true",
                   help="skip the forward replay of the optimal controls")
    p.add_argument("--plot", default=None, help="save a figure of coordinates and controls")
    _add_workbench_verbs(sub)
    _add_sweep_verb(sub)
    _add_sensitivity_verb(sub)
    _add_bench_verb(sub)
    for p in sub.choices.values():
        if not any("--verbose" in a.option_strings for a in p._actions):
            p.add_argument("--verbose", action="store_true",
                           help="print the solver statistics after the summary")
    return parser


def _add_sensitivity_verb(sub) -> None:
    """The ``sensitivity`` verb (casmbd.analysis.sensitivity)."""
    p = sub.add_parser("sensitivity", help="exact derivatives of simulation outputs with "
                                           "respect to scene parameters (IDAS)")
    p.add_argument("scene", help="scene file (TOML) with a [parameters] table")
    p.add_argument("--output", action="append", required=True, metavar="EXPR",
                   help="output: an expression at t_end (e.g. tip_x) or 'integral: EXPR' "
                        "(e.g. 'integral: O_Fy'); repeatable")
    p.add_argument("--param", action="append", default=None, metavar="NAME",
                   help="parameter to differentiate with respect to (default: all); repeatable")
    p.add_argument("--t-end", type=_positive_float, required=True, help="final time [s]")
    p.add_argument("--method", choices=("forward", "adjoint"), default="forward",
                   help="IDAS forward sensitivities (per parameter) or adjoint (per output)")
    p.add_argument("--rtol", type=_positive_float, default=1e-10, help="relative tolerance")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")


def _cmd_sensitivity(args) -> tuple[dict, str]:
    """Derivatives of the --output expressions with respect to the --param parameters."""
    from casmbd.analysis.sensitivity import sensitivity

    mech = _load(args)
    res = sensitivity(mech, args.output, args.param, args.t_end, method=args.method,
                      rtol=args.rtol)
    data = res.to_json()
    width = max(len(o) for o in res.outputs)
    lines = [f"sensitivities of '{mech.name}' at t = {args.t_end:g} s ({res.method}, IDAS, "
             f"rtol {args.rtol:g}; solve {res.stats['solve_seconds']:.3g} s)",
             f"{'output':<{width}}  {'value':>14}  "
             + "  ".join(f"{'d/d' + p:>14}" for p in res.parameters)]
    for i, o in enumerate(res.outputs):
        lines.append(f"{o:<{width}}  {res.values[i]:>14.8g}  "
                     + "  ".join(f"{res.jacobian[i, j]:>14.8g}"
                                 for j in range(len(res.parameters))))
    return data, "\n".join(lines)


def _add_bench_verb(sub) -> None:
    """The ``bench`` verb: the benchmark suite of a source checkout (``python -m benchmarks``)."""
    p = sub.add_parser("bench", help="run the benchmark suite of a casmbd checkout "
                                     "(python -m benchmarks)")
    p.add_argument("--quick", action="store_true",
                   help="a few minutes: check the printed errors against their bounds")
    p.add_argument("--update-docs", action="store_true",
                   help="regenerate docs/performance.md (full suite only)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")


def _cmd_bench(args) -> tuple[dict, str]:
    """Run ``python -m benchmarks`` in the checkout that holds this casmbd.

    Only the checkout of the running package is used, never the current directory: a
    ``benchmarks/`` folder in a downloaded directory must not become code that ``casmbd bench``
    runs.  The suite is not installed with the package (``pip install -e .`` keeps it beside).
    """
    import subprocess

    root = Path(__file__).resolve().parent.parent
    if not (root / "benchmarks" / "__main__.py").is_file():
        raise AnalysisError("casmbd bench: no benchmarks/ folder next to the installed package "
                            f"({root}); install casmbd from a source checkout with "
                            "'pip install -e .' or run 'python -m benchmarks' there")
    cmd = [sys.executable, "-m", "benchmarks"] + (["--quick"] if args.quick else []) \
        + (["--update-docs"] if args.update_docs else []) + (["--json"] if args.json else [])
    proc = subprocess.run(cmd, cwd=root, capture_output=args.json, text=True)
    if proc.returncode:
        raise AnalysisError(f"casmbd bench: '{' '.join(cmd[1:])}' failed with exit status "
                            f"{proc.returncode}" + (f": {proc.stderr.strip()[-400:]}"
                                                    if args.json and proc.stderr else ""))
    if args.json:
        return json.loads(proc.stdout.strip().splitlines()[-1]), ""
    return {}, f"benchmarks finished ({' '.join(cmd[1:])}, in {root})"


def _add_sweep_verb(sub) -> None:
    """The ``sweep`` verb (one analysis at many parameter values, casmbd.analysis.sweep)."""
    p = sub.add_parser("sweep", help="parameter sweep: one analysis at many values of the "
                                     "scene's [parameters]")
    p.add_argument("scene", help="scene file (TOML) with a [parameters] table")
    p.add_argument("--param", action="append", required=True, metavar="NAME=VALUES",
                   help="NAME=A:B:N (N values from A to B inclusive), NAME=A,B,C or NAME=A; "
                        "repeat for a grid product")
    p.add_argument("--analysis", choices=("simulate", "kinematics", "inverse", "statics"),
                   default="simulate", help="analysis run at every point (default simulate)")
    p.add_argument("--t-end", type=_positive_float, default=None, help="final time [s]")
    p.add_argument("--steps", type=_positive_int, default=None,
                   help="number of output intervals (N + 1 output times from 0 to T)")
    p.add_argument("--output", action="append", default=None, metavar="REDUCTION:COLUMN",
                   help="scalar output per point, e.g. final:q[crank.angle], "
                        "max:body.rod.angle, energy_drift (repeatable; default final q, "
                        "largest constraint violation, energy drift)")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="local worker processes (default: serial in this process)")
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help="Dask scheduler address (needs dask.distributed: casmbd[sweep])")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder for point_XXX.npz, sweep.csv and sweep.npz")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    p.add_argument("--mode", choices=("auto", "compiled", "vm"), default="auto",
                   help="compile equations to C (default auto) or use CasADi's VM")


def _add_workbench_verbs(sub) -> None:
    """The ``plot`` and ``animate`` verbs (figures and animations of results)."""
    from casmbd.viz.plots import KINDS

    p = sub.add_parser("plot", help="figures of a saved result against time")
    p.add_argument("result", help="result file (.npz) written with --out")
    p.add_argument("--kind", action="append", default=None, metavar="KIND",
                   help=f"what to draw: {', '.join(KINDS)} (repeatable; default every kind "
                        "the result holds); each kind gets one panel per unit")
    p.add_argument("--element", action="append", default=None, metavar="NAME",
                   help="draw only the lines of this body, joint, driver or actuator "
                        "(repeatable)")
    p.add_argument("--euler", choices=("xyz", "zxz"), default="xyz",
                   help="Euler angles drawn for spatial bodies instead of quaternions "
                        "(default xyz, regular at the identity; zxz is singular there)")
    p.add_argument("--out", required=True, help="figure file (.png, .pdf, .svg)")
    p.add_argument("--dpi", type=_positive_float, default=100.0, help="resolution (default 100)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")

    p = sub.add_parser("animate", help="animation (.gif, .mp4 with ffmpeg) or still frame "
                                       "(.png) of a scene or a saved result")
    p.add_argument("source", help="scene file (TOML; simulated first) or result file (.npz)")
    p.add_argument("--out", required=True,
                   help=".gif (Pillow), .mp4 (needs ffmpeg) or .png/.pdf/.svg (a still frame "
                        "with earlier poses faded)")
    p.add_argument("--t-end", type=_positive_float, default=2.0,
                   help="final time of the simulation of a scene [s] (default 2)")
    p.add_argument("--steps", type=_positive_int, default=50,
                   help="output intervals of the simulation of a scene (default 50)")
    p.add_argument("--max-frames", type=_positive_int, default=None,
                   help="show at most this many evenly spread output steps (default 301)")
    p.add_argument("--fps", type=_positive_float, default=None,
                   help="highest frame rate (default 30; a GIF plays at most 50)")
    p.add_argument("--speed", type=_positive_float, default=1.0,
                   help="playback speed factor (default 1: real time; 2: twice as fast)")
    p.add_argument("--trace", action="append", default=None, metavar="MARKER",
                   help="draw the path of this marker (repeatable; 'all' for every marker)")
    p.add_argument("--dpi", type=_positive_float, default=80.0, help="resolution (default 80)")
    p.add_argument("--mode", choices=("auto", "compiled", "vm"), default="auto",
                   help="compile equations to C (default auto) or use CasADi's VM")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")


# ---------------------------------------------------------------------- verbs
def _check_out(args) -> None:
    """Fail before the analysis when ``--out`` cannot be written."""
    out = getattr(args, "out", None)
    if not out:
        return
    path = Path(out)
    if path.is_dir():
        raise AnalysisError(f"--out '{out}' is a directory; give a file name such as run.npz")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise AnalysisError(f"--out '{out}': folder '{parent}' does not exist")


def _save(result, out: str) -> None:
    try:
        result.save(out)
    except OSError as exc:
        raise AnalysisError(f"cannot write --out '{out}': {exc.strerror or exc}") from None


def _load(args):
    _check_out(args)
    from casmbd.io.scene import load_scene

    return load_scene(args.scene)


def _cmd_info(args) -> tuple[dict, str]:
    from casmbd.analysis.kinematics import info

    mech = _load(args)
    data = info(mech, mode=args.mode)
    data.setdefault("coordinate_choice", mech.coordinates)
    kind = "planar" if data.get("dimension", 2) == 2 else "spatial"
    n_body_rows = sum(1 for row in data["constraints"] if row["kind"] == "body")
    body_rows = f" ({n_body_rows} of the bodies' own)" if n_body_rows else ""
    lines = [f"mechanism '{data['name']}' ({kind}, {len(data['bodies'])} bodies, "
             f"{data['coordinate_choice']} coordinates)",
             f"  coordinates ({data['n_coordinates']}): {', '.join(data['coordinates'])}",
             f"  constraints: {data['n_constraints']} equations{body_rows}, "
             f"rank {data['rank']}",
             f"  degrees of freedom: {data['degrees_of_freedom']}"]
    if not data["assembled"]:
        lines[-2] += " (at the initial guess: not assembled)"
        lines.append("  redundant equations: not analysed (not assembled)")
    elif data["redundant_equations"]:
        lines.append("  redundant equations: " + ", ".join(
            f"{d['joint']}.{d['equation']}" for d in data["redundant_equations"]))
    else:
        lines.append("  redundant equations: none")
    if not data["assembled"]:
        # the summary (or the one JSON object) on stdout, the culprit on stderr, exit 1
        if args.json:
            sys.stdout.write(json.dumps(_finite_json(json.loads(json.dumps(
                data, default=_json_default))), allow_nan=False) + "\n")
        else:
            print("\n".join(lines))
        sys.stdout.flush()
        raise AssemblyError(f"mechanism '{data['name']}' cannot be assembled — "
                            f"{data['assembly_error']}", data.get("assembly_culprits"))
    return data, "\n".join(lines)


def _timing(stats: dict, digits: int = 3) -> str:
    """The build/solve line every verb prints."""
    origin = "cache hit" if stats.get("cache_hit") else stats.get("mode", "")
    return (f"  build {stats['build_seconds']:.3f} s ({origin}), "
            f"solve {stats['solve_seconds']:.{digits}f} s")


def _range(label: str, values: np.ndarray, unit: str = "") -> str:
    unit = f" {unit}" if unit else ""
    return f"{label} [{values.min():+.4g}, {values.max():+.4g}]{unit}"


def _summary_table(result, mech=None) -> list[str]:
    """One line per body (coordinate ranges of the centre of mass in m, and the angle range
    in rad in the plane or the final quaternion in space) and per joint coordinate (m or
    rad, from the joint's kind)."""
    from casmbd.viz.quantities import joint_units

    lines = []
    spatial = result.dimension == 3
    for name in result.names["bodies"]:
        b = result.body(name)
        pos = b["position"]
        parts = [_range(axis, pos[:, k], "m") for k, axis in enumerate("xyz"[:pos.shape[1]])]
        if spatial and "quaternion" in b and len(b["quaternion"]):
            quat = ", ".join(f"{x:+.4f}" for x in b["quaternion"][-1])
            parts.append(f"final quaternion [{quat}]")
        elif "angle" in b:
            parts.append(_range("angle", b["angle"], "rad"))
        lines.append(f"  body {name:<14} " + "  ".join(parts))
    units = joint_units(result, mech) if result.names["joints"] else []
    for name, unit in zip(result.names["joints"], units):
        c = result["joint_positions"][:, result.names["joints"].index(name)]
        lines.append(f"  joint {name:<13} {_range('coordinate', c, unit)}")
    return lines


def _cmd_kinematics(args) -> tuple[dict, str]:
    from casmbd.analysis.kinematics import kinematics

    mech = _load(args)
    result = kinematics(mech, t_end=args.t_end, steps=args.steps, mode=args.mode)
    result.scene = getattr(mech, "scene_text", "")
    if args.out:
        _save(result, args.out)
    data = result.to_json()
    s = result.stats
    lines = [f"kinematics of '{mech.name}': {len(result.t)} times from {result.t[0]:g} to "
             f"{result.t[-1]:g} s",
             *_summary_table(result, mech),
             f"  max constraint violation {data['constraint_violation']:.3g}",
             _timing(s)]
    if args.out:
        lines.append(f"  saved {args.out}")
    return data, "\n".join(lines)


def _cmd_simulate(args) -> tuple[dict, str]:
    from casmbd.analysis.simulate import simulate
    from casmbd.errors import IntegratorError

    mech = _load(args)
    try:
        result = simulate(mech, t_end=args.t_end, steps=args.steps, formulation=args.formulation,
                          integrator=args.integrator, rtol=args.rtol, atol=args.atol,
                          projection=args.projection, step=args.step, mode=args.mode,
                          max_steps=args.max_steps, redundancy=args.redundancy)
    except IntegratorError as exc:
        if args.out and exc.partial is not None:
            exc.partial.scene = getattr(mech, "scene_text", "")
            exc.partial.stats["failure"] = str(exc)
            _save(exc.partial, args.out)
            raise IntegratorError(f"{exc} (partial results saved to {args.out})", exc.time,
                                  exc.flag, exc.partial) from None
        raise
    result.scene = getattr(mech, "scene_text", "")
    if args.out:
        _save(result, args.out)
    data = result.to_json()
    s = result.stats
    energy = result["total_energy"]
    lines = [f"simulation of '{mech.name}': {len(result.t)} times from {result.t[0]:g} to "
             f"{result.t[-1]:g} s, {s['formulation']} on {s['integrator']}",
             *_summary_table(result, mech),
             f"  energy: start {energy[0]:.6g} J, end {energy[-1]:.6g} J "
             f"({_energy_change(result, mech)})",
             f"  max constraint violation: position {data['constraint_violation']:.3g}, "
             f"velocity {data['velocity_violation']:.3g}",
             f"  steps {s.get('steps', 0)}, rhs evaluations {s.get('rhs_evaluations', 0)}",
             _timing(s, 4)]
    if s.get("start_position_change", 0) > 1e-12 or s.get("start_velocity_change", 0) > 1e-12:
        lines.append(f"  consistent start changed q by {s['start_position_change']:.3g} and v by "
                     f"{s['start_velocity_change']:.3g}")
    if s.get("redundant_equations"):
        lines.append(f"  redundant equations ({s['redundancy']}): "
                     + ", ".join(s["redundant_equations"]))
    if s.get("undetermined_reactions"):
        lines.append("  undetermined reaction components (NaN): " + ", ".join(
            f"{j} {c}" for j, c in s["undetermined_reactions"].items()))
    if s.get("near_singular_times"):
        times = s["near_singular_times"]
        lines.append(f"  passed {len(times)} near-singular poses (conditioning < 1e-4) at t ≈ "
                     + ", ".join(f"{t:.4g}" for t in times[:8]) + (" …" if len(times) > 8
                                                                     else ""))
    if args.out:
        lines.append(f"  saved {args.out}")
    return data, "\n".join(lines)


def _energy_change(result, mech) -> str:
    """total − total(0): "drift" for a conservative mechanism, else the work of the dampers,
    drivers, actuators and forces that change it (not a conservation error)."""
    from casmbd.viz.quantities import energy_exchange

    energy = result["total_energy"]
    delta = f"{energy[-1] - energy[0]:+.3g} J"
    elements = energy_exchange(result, mech)
    if elements == []:
        return f"drift {delta}"
    if elements is None:
        return f"change {delta}; numerical drift only if nothing does work"
    return f"change {delta}: work of {', '.join(elements)}, not numerical drift"


def _cmd_inverse(args) -> tuple[dict, str]:
    from casmbd.analysis.inverse import inverse_dynamics
    from casmbd.viz.quantities import effort_units

    mech = _load(args)
    result = inverse_dynamics(mech, t_end=args.t_end, steps=args.steps, mode=args.mode)
    result.scene = getattr(mech, "scene_text", "")
    if args.out:
        _save(result, args.out)
    data = result.to_json()
    lines = [f"inverse dynamics of '{mech.name}': {len(result.t)} times from {result.t[0]:g} "
             f"to {result.t[-1]:g} s", *_summary_table(result, mech)]
    for group, key, width in (("drivers", "driver_efforts", 12),
                              ("actuators", "actuator_efforts", 10)):
        units = effort_units(result, group, mech)
        for k, name in enumerate(result.names.get(group, [])):
            eff = result[key][:, k]
            lines.append(f"  {group[:-1]} {name:<{width}} {_range('effort', eff, units[k])}")
    s = result.stats
    lines.append(_timing(s))
    if args.out:
        lines.append(f"  saved {args.out}")
    return data, "\n".join(lines)


def _cmd_statics(args) -> tuple[dict, str]:
    from casmbd.analysis.statics import static_equilibrium
    from casmbd.viz.quantities import joint_coordinate_unit

    mech = _load(args)
    result = static_equilibrium(mech, method=args.method, mode=args.mode)
    data = result.to_json()
    stable = {True: "stable", False: "unstable", None: "neutral"}[result.stable]
    if result.stability is not None and result.stability.null_directions:
        stable += f" (null directions: {', '.join(result.stability.null_coordinates())})"
    lines = [f"static equilibrium of '{mech.name}' ({result.method} Newton, "
             f"{result.iterations} iterations, residual {result.residual:.3g}): {stable}"]
    for name, b in data["bodies"].items():
        pos = "  ".join(f"{axis} {x:+.6g} m" for axis, x in zip("xyz", b["position"]))
        if "quaternion" in b:
            orient = "quaternion [" + ", ".join(f"{x:+.6f}" for x in b["quaternion"]) + "]"
        else:
            orient = f"angle {b['angle']:+.6g} rad"
        lines.append(f"  body {name:<14} {pos}  {orient}")
    labels = ("Fx", "Fy", "M") if len(mech.gravity) == 2 else ("Fx", "Fy", "Fz", "Mx", "My",
                                                               "Mz")
    for name, j in data["joints"].items():
        coords = "".join(
            f"{key} {j[key]:+.6g} "
            f"{joint_coordinate_unit(mech, name, None if key == 'coordinate' else key)}  "
            for key in j if key != "reaction")
        reaction = "  ".join(f"{label} {x + 0.0:+.6g} {'N' if label[0] == 'F' else 'N m'}"
                             for label, x in zip(labels, j["reaction"]))  # no "-0"
        lines.append(f"  joint {name:<13} {coords}reaction {reaction}")
    eig = ", ".join(f"{e:.4g}" for e in result.eigenvalues) or "none (no degrees of freedom)"
    lines.append(f"  stiffness eigenvalues: {eig}")
    s = result.stats
    lines.append(_timing(s))
    return data, "\n".join(lines)


VERBS = {"info": _cmd_info, "kinematics": _cmd_kinematics, "simulate": _cmd_simulate,
         "inverse": _cmd_inverse}
VERBS["statics"] = _cmd_statics


def _cmd_linearize(args) -> tuple[dict, str]:
    """Linearize about the initial configuration at rest, the static equilibrium
    (``--at-equilibrium``) or a stored state (``--from RESULT.npz --time T``).

    The verdict is the statics verb's (one classification of the reduced stiffness); about a
    state that is not an equilibrium there is none (the matrices are still the first-order
    expansion there).
    """
    from casmbd.analysis.linearize import linearize

    if (args.time is None) != (args.from_result is None):
        raise AnalysisError("linearize: --from RESULT.npz and --time T go together")
    mech = _load(args)
    if args.at_equilibrium:
        lin = linearize(mech, mode=args.mode, at="equilibrium")
        where = (f"the static equilibrium ({lin.stats['statics_iterations']} statics "
                 f"iterations, residual {lin.stats['statics_residual']:.3g})")
    elif args.from_result is not None:
        from casmbd.results import load as load_result

        result = load_result(args.from_result)
        lin = linearize(mech, mode=args.mode, at=result, at_time=args.time)
        where = (f"the state of '{args.from_result}' at t = {lin.t:.6g} (output "
                 f"{lin.stats['state_index']}, nearest to {args.time:g})")
    else:
        lin = linearize(mech, mode=args.mode)
        where = "the initial configuration (v = 0)"
    data = lin.to_json()
    s = lin.stats
    verdict = lin.verdict
    if lin.stability is not None and lin.stability.null_directions:
        verdict += f" (null directions: {', '.join(lin.stability.null_coordinates())})"
    lines = [f"linearization of '{mech.name}' about {where}: "
             f"{lin.n_dof} degree{'' if lin.n_dof == 1 else 's'} of freedom, {verdict}"]
    for k, (f, z) in enumerate(zip(lin.frequencies_hz, lin.damping_ratios)):
        lines.append(f"  mode {k + 1:<3} frequency {f:.6g} Hz  damping ratio {z:.4g}")
    if lin.stability is not None:
        eig = ", ".join(f"{e:.4g}" for e in lin.stability.eigenvalues)
        lines.append(f"  stiffness eigenvalues: {eig or 'none (no degrees of freedom)'}")
    else:
        lines.append(f"  not an equilibrium ({lin.why_not_equilibrium()}): no stability "
                     "verdict, the modes describe perturbations about this state only; "
                     "--at-equilibrium linearizes at the static equilibrium")
    lines.append(_timing(s))
    return data, "\n".join(lines)


VERBS["linearize"] = _cmd_linearize


def _cmd_ocp(args) -> tuple[dict, str]:
    """Solve the scene's ``[ocp]`` table; replay the controls with the forward simulator."""
    from casmbd.errors import OptimizationError
    from casmbd.io.ocp_table import ocp_from_scene

    mech = _load(args)
    if "ocp" not in getattr(mech, "scene_data", {}):  # --intervals alone is no problem
        raise SceneError(f"{args.scene}: no [ocp] table: the ocp verb solves the scene's "
                         "[ocp] table (see docs/ocp.md)")
    table = dict(getattr(mech, "scene_data", {}).get("ocp") or {})
    if args.intervals is not None:
        table["intervals"] = args.intervals
    if args.transcription is not None:
        table["transcription"] = args.transcription
    ocp = ocp_from_scene(mech, table, source=args.scene)
    try:
        sol = ocp.solve()
    except OptimizationError as exc:
        if args.out and exc.solution is not None:
            exc.solution.save(args.out)
        raise
    if not args.no_replay:
        sol.replay()
    if args.out:
        sol.save(args.out)
    if args.plot:
        sol.plot(args.plot)
    data = sol.to_json()
    s = sol.stats
    replay = s.get("replay_error")
    lines = [f"optimal control of '{mech.name}': {s['return_status']} after {s['iterations']} "
             f"iterations, objective {sol.objective:.8g}",
             f"  {s['transcription']}"
             + (f" degree {s['degree']}" if s.get("degree") else "")
             + f", {s['intervals']} intervals × {s['subintervals']} elements, final time "
             f"{sol.t[-1] - sol.t[0]:.6g} s, {s['variables']} variables, "
             f"{s['constraints']} constraints",
             f"  max constraint violation {s['constraint_violation']:.3g}"
             + (f", replay error {replay:.3g}" if replay is not None else ""),
             f"  setup {s['setup_seconds']:.3g} s, NLP solve {s['solve_seconds']:.3g} s"]
    for name in sol.controls:
        u = sol.control(name)
        lines.append(f"  control {name:12s} [{u.min():+.4g}, {u.max():+.4g}]")
    lines += [f"  saved {f}" for f in (args.out, args.plot) if f]
    return data, "\n".join(lines)


VERBS["ocp"] = _cmd_ocp


def _cmd_plot(args) -> tuple[dict, str]:
    """Figure of a saved result: one panel per kind against time."""
    from casmbd.results import load
    from casmbd.viz.plots import available_kinds, check_figure_size, plot_result

    _check_out(args)
    check_figure_size(dpi=args.dpi, what=f"--out '{args.out}'")  # before reading the result
    result = load(args.result)
    kinds = args.kind or available_kinds(result)
    fig = plot_result(result, kinds, out=args.out, dpi=args.dpi, elements=args.element,
                      euler=args.euler)
    notes = getattr(fig, "casmbd_notes", [])
    data = {"out": args.out, "kinds": kinds, "result": args.result, "notes": notes}
    return data, "\n".join([f"saved {args.out} ({', '.join(kinds)})",
                            *(f"  note: {n}" for n in notes)])


def _cmd_animate(args) -> tuple[dict, str]:
    """Animate a result file, or simulate a scene (default simulator) and animate it."""
    from casmbd.viz.animation import (
        animate,
        check_animation_file,
        check_fps,
        draw_frame,
        save_animation,
    )
    from casmbd.viz.plots import check_figure_size

    _check_out(args)
    suffix = Path(args.out).suffix.lower()
    if suffix not in (".gif", ".mp4", ".png", ".pdf", ".svg"):
        raise AnalysisError(f"--out '{args.out}': unknown suffix '{suffix}' (use .gif, .mp4 "
                            "with ffmpeg, or .png/.pdf/.svg for a still frame)")
    if suffix in (".gif", ".mp4"):
        check_animation_file(args.out)  # before a simulation: no ffmpeg, no MP4
    check_figure_size(dpi=args.dpi, what=f"--out '{args.out}'")  # before a simulation
    if args.fps is not None:
        check_fps(args.fps)
    if (suffix in (".gif", ".mp4") and args.max_frames is None
            and Path(args.source).suffix.lower() != ".npz"):
        check_count("animate: frames (--steps + 1)", args.steps + 1, MAX_FRAMES,
                    "give --max-frames or fewer --steps")
    lines = []
    if Path(args.source).suffix.lower() == ".npz":
        from casmbd.results import load

        result = load(args.source)
        mech = result.mechanism()
        source = f"result {args.source}"
    else:
        from casmbd.analysis.simulate import simulate
        from casmbd.io.scene import load_scene

        mech = load_scene(args.source)
        result = simulate(mech, t_end=args.t_end, steps=args.steps, mode=args.mode)
        result.attach_scene(mech)
        source = f"simulation of '{mech.name}'"
        s = result.stats
        lines.append(f"simulated '{mech.name}' to t = {args.t_end:g} s ({args.steps} steps, "
                     f"{s.get('formulation')} on {s.get('integrator')}), solve "
                     f"{s.get('solve_seconds', 0.0):.3g} s")
    trace = args.trace
    if trace and "all" in trace:
        trace = True
    if suffix in (".gif", ".mp4"):
        anim = animate(result, mech, max_frames=args.max_frames, fps=args.fps,
                       speed=args.speed, trace=trace)
        if not args.json:  # before the drawing: what was chosen and how to change it
            print(anim.casmbd_choice, flush=True)
        save_animation(anim, args.out, dpi=args.dpi)
        frames, fps = anim.casmbd_frames, anim.casmbd_fps
        playback = anim.casmbd_plan.playback
        lines.append(f"saved {args.out}: {frames} frames at {fps:.3g} fps ({source})")
    else:
        draw_frame(result, mechanism=mech, ghosts=8, trace=trace, out=args.out, dpi=args.dpi)
        frames, fps, playback = 1, None, None
        lines.append(f"saved {args.out}: still frame at t = {result.t[-1]:g} s ({source})")
    data = {"out": args.out, "frames": frames, "fps": fps, "t_end": float(result.t[-1]),
            "output_times": len(result.t), "speed": args.speed,
            "playback_seconds": playback,
            "stats": dict(result.stats)}
    return data, "\n".join(lines)


VERBS["plot"] = _cmd_plot
VERBS["sensitivity"] = _cmd_sensitivity
VERBS["bench"] = _cmd_bench
VERBS["animate"] = _cmd_animate


def _cmd_sweep(args) -> tuple[dict, str]:
    """Run the analysis at every point of the --param grid (casmbd.analysis.sweep)."""
    from casmbd.analysis.sweep import parse_values, sweep

    params: dict = {}
    for text in args.param:
        name, values = parse_values(text)
        if name in params:
            raise AnalysisError(f"--param {text!r}: parameter '{name}' given twice")
        params[name] = values
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise AnalysisError(f"--out '{args.out}' is a file; give a folder")
    if args.scheduler and args.workers:
        raise AnalysisError("give --workers (local processes) or --scheduler (Dask), not both")
    executor = args.scheduler or ("processes" if args.workers and args.workers > 1
                                  else "serial")
    res = sweep(args.scene, params, analysis=args.analysis, t_end=args.t_end,
                steps=args.steps, outputs=args.output, executor=executor,
                workers=args.workers, out_dir=args.out, mode=args.mode,
                progress=None if not args.json else False)
    if len(res) and len(res.failed) == len(res):  # nothing computed: an error, not a table
        raise AnalysisError(f"sweep of '{args.scene}': all {len(res)} points failed; point "
                            f"{res.failed[0]}: {res.errors[res.failed[0]]}"
                            + (f" (the failures are listed in {args.out}/sweep.csv)"
                               if args.out else ""))
    data = res.to_json()
    s = res.stats
    shown = res.output_names[:4]
    columns = [*res.parameter_names, *shown]
    widths = [max(12, len(n)) for n in columns]
    lines = [f"{res.analysis} sweep of '{args.scene}': {len(res)} points, {s['failed']} failed "
             f"({s['executor']}, {s['wall_seconds']:.3g} s)",
             "  " + "  ".join(f"{n:>{w}}" for n, w in zip(columns, widths)) + "  status"]
    for i in range(len(res)):
        vals = [res[n][i] for n in columns]
        lines.append("  " + "  ".join(f"{v:{w}.6g}" for v, w in zip(vals, widths))
                     + f"  {res.status[i]}")
    for i in res.failed:
        lines.append(f"  point {i}: {res.errors[i]}")
    build = s["parent_build"]
    origin = "cache hit" if build.get("cache_hit") else build.get("mode")
    lines.append(f"  built once here ({origin}); compiler runs during the points: "
                 f"{s['worker_compiler_runs']}")
    if args.out:
        lines.append(f"  saved {args.out}/point_*.npz, sweep.csv, sweep.npz")
    return data, "\n".join(lines)


VERBS["sweep"] = _cmd_sweep


def _finite_json(obj):
    """Replace NaN/inf (e.g. reactions that cannot be determined) by null: strict JSON."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_json(v) for v in obj]
    return obj


def _interrupted(args, started: float) -> int:
    """One line for Ctrl-C; exit status 130 (128 + SIGINT) like a shell's.

    Nothing is saved: every result file is written atomically after the analysis, so an
    interrupted verb leaves no ``--out`` file (an existing one is untouched); a sweep's
    ``--out DIR`` keeps only the complete ``point_*.npz`` of finished points.  The one case
    with a file: Ctrl-C after ``--out`` was written (e.g. while ``ocp`` draws ``--plot``).
    """
    out = getattr(args, "out", None)
    if args.verb == "sweep" and out:
        kept = f"kept the finished points in {out}/, no sweep.csv or sweep.npz"
    elif out and os.path.isfile(out) and os.path.getmtime(out) >= started:
        kept = f"{out} was complete before the interrupt, nothing else saved"
    elif out:
        kept = f"nothing saved ({out} not written)"
    else:
        kept = "nothing saved"
    print(f"error: interrupted (Ctrl-C) during {args.verb}; {kept}", file=sys.stderr)
    return EXIT_INTERRUPTED


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``casmbd`` command; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    interrupts.install()  # Ctrl-C is remembered even where CasADi turns it into an error
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.version:
        from casmbd import __version__

        print(__version__)
        return 0
    if not args.verb:
        print("error: missing verb (one of: " + ", ".join(VERBS) + "); see casmbd --help",
              file=sys.stderr)
        return EXIT_USAGE
    if getattr(args, "json", False):
        os.environ["CASMBD_PROGRESS"] = "0"  # one JSON object: no progress bars
    t0, started = time.perf_counter(), time.time()
    try:
        data, text = VERBS[args.verb](args)
    except KeyboardInterrupt:
        if debug:
            raise
        return _interrupted(args, started)
    except CasmbdError as exc:
        if debug:
            raise
        if interrupts.seen():  # a failure that Ctrl-C caused is still an interrupt
            return _interrupted(args, started)
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except Exception as exc:  # an unexpected failure still gets one clear line
        if debug:
            raise
        print(f"error: internal error ({type(exc).__name__}): {exc}; rerun with --debug",
              file=sys.stderr)
        return EXIT_ERROR
    if isinstance(data.get("stats"), dict):
        data["stats"]["total_seconds"] = time.perf_counter() - t0
    try:
        if args.json:
            data = json.loads(json.dumps(data, default=_json_default))  # numpy -> builtins
            sys.stdout.write(json.dumps(_finite_json(data), allow_nan=False) + "\n")
        else:
            if text:
                print(text)
            if getattr(args, "verbose", False) and isinstance(data.get("stats"), dict):
                print(_verbose_stats(data["stats"]))
        sys.stdout.flush()
    except BrokenPipeError:  # `casmbd … | head`: the reader left; not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def _verbose_stats(stats: dict) -> str:
    """The solver statistics, one ``key: value`` per line (``--verbose``)."""
    lines = ["statistics:"]
    for key in sorted(stats):
        val = stats[key]
        if isinstance(val, float):
            val = f"{val:.6g}"
        elif isinstance(val, (list, tuple)) and len(val) > 8:
            val = f"[{', '.join(map(str, val[:8]))}, … ({len(val)} items)]"
        lines.append(f"  {key}: {val}")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
