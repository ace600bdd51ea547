"""The workbench verbs: ``plot`` and ``animate`` (figures of results), ``sweep`` (one analysis
at many parameter values) and ``sensitivity`` (derivatives with respect to parameters).

matplotlib is imported by casmbd.viz only when a figure is drawn.
"""

from __future__ import annotations

from pathlib import Path

from casmbd.analysis.sensitivity import sensitivity
from casmbd.analysis.simulate import simulate
from casmbd.analysis.sweep import parse_values, sweep
from casmbd.cli.common import _check_out, _load, _positive_float, _positive_int
from casmbd.errors import AnalysisError
from casmbd.io.scene import load_scene
from casmbd.limits import MAX_FRAMES, check_count
from casmbd.results import load
from casmbd.viz.animation import (
    animate,
    check_animation_file,
    check_fps,
    draw_frame,
    save_animation,
)
from casmbd.viz.plots import KINDS, available_kinds, check_figure_size, plot_result


def _add_workbench_verbs(sub) -> None:
    """The ``plot`` and ``animate`` verbs (figures and animations of results)."""
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


def _cmd_plot(args) -> tuple[dict, str]:
    """Figure of a saved result: one panel per kind against time."""
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
        result = load(args.source)
        mech = result.mechanism()
        source = f"result {args.source}"
    else:
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


def _cmd_sweep(args) -> tuple[dict, str]:
    """Run the analysis at every point of the --param grid (casmbd.analysis.sweep)."""
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
    res = sweep(load_scene(args.scene), params, analysis=args.analysis, t_end=args.t_end,
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


def _cmd_sensitivity(args) -> tuple[dict, str]:
    """Derivatives of the --output expressions with respect to the --param parameters."""
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

