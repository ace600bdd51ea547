"""The workbench verbs: ``plot`` and ``animate`` (figures of results), ``sweep`` (one analysis
at many parameter values) and ``sensitivity`` (derivatives with respect to parameters).

matplotlib is imported by casmbd.viz only when a figure is drawn; the verbs' command-line
parsers are in :mod:`casmbd.cli.verbs`.
"""

from __future__ import annotations

from pathlib import Path

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.studies.sensitivity import sensitivity
from casmbd.analysis.studies.sweep import parse_values, sweep
from casmbd.cli.common import check_not_input, check_out_path, load_scene_for, scene_files
from casmbd.errors import AnalysisError, ResultFileError
from casmbd.io.scene import load_result, load_scene, loads_scene
from casmbd.limits import MAX_FRAMES, check_count
from casmbd.ocp.solution import OcpSolution
from casmbd.results import Result
from casmbd.viz.animation import (
    animate,
    check_animation_file,
    check_fps,
    draw_frame,
    save_animation,
)
from casmbd.viz.plots import check_figure_size, plot_result


def load(path: str) -> Result:
    """A result file, or an OCP solution file written before OCP solutions were result files
    (:meth:`~casmbd.ocp.solution.OcpSolution.to_result`: coordinates and controls); the
    result file's error when it is neither."""
    try:
        return load_result(path)
    except ResultFileError as exc:
        try:
            return OcpSolution.load(path).to_result()
        except ResultFileError:
            raise exc from None


def _cmd_plot(args) -> tuple[dict, str]:
    """Figure of a saved result: one panel per kind against time."""
    check_out_path(args)
    check_figure_size(dpi=args.dpi, what=f"--out '{args.out}'")  # before reading the result
    result = load(args.result)
    kinds = [k.strip() for text in args.kind for k in text.split(",") if k.strip()] \
        if args.kind else None
    fig = plot_result(result, kinds, out=args.out, dpi=args.dpi, elements=args.element,
                      euler=args.euler)
    notes = getattr(fig, "casmbd_notes", [])
    panels = getattr(fig, "casmbd_panels", [])
    data = {"out": args.out, "kinds": kinds or fig.casmbd_kinds, "panels": panels,
            "result": args.result, "notes": notes}
    what = ", ".join(kinds) if kinds else f"{len(panels)} panels: {'; '.join(panels)}"
    return data, "\n".join([f"saved {args.out} ({what})", *(f"  note: {n}" for n in notes)])


def _cmd_animate(args) -> tuple[dict, str]:
    """Animate a result file, or simulate a scene (default simulator) and animate it."""
    check_out_path(args)
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
        mech = result.mechanism(loads_scene)
        source = f"result {args.source}"
    else:
        mech = load_scene(args.source)
        check_not_input(args, scene_files(mech, args.source))  # its URDF, its FE files
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
                       speed=args.speed, trace=trace, deformation_scale=args.deformation_scale)
        if not args.json:  # before the drawing: what was chosen and how to change it
            print(anim.casmbd_choice, flush=True)
        save_animation(anim, args.out, dpi=args.dpi)
        frames, fps = anim.casmbd_frames, anim.casmbd_fps
        playback = anim.casmbd_plan.playback
        lines.append(f"saved {args.out}: {frames} frames at {fps:.3g} fps ({source})")
    else:
        draw_frame(result, mechanism=mech, ghosts=8, trace=trace, out=args.out, dpi=args.dpi,
                   deformation_scale=args.deformation_scale)
        frames, fps, playback = 1, None, None
        lines.append(f"saved {args.out}: still frame at t = {result.t[-1]:g} s ({source})")
    data = {"out": args.out, "frames": frames, "fps": fps, "t_end": float(result.t[-1]),
            "output_times": len(result.t), "speed": args.speed,
            "playback_seconds": playback,
            "stats": dict(result.stats)}
    return data, "\n".join(lines)


def _cmd_sweep(args) -> tuple[dict, str]:
    """Run the analysis at every point of the --param grid (casmbd.analysis.studies.sweep)."""
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
    mech = load_scene_for(args)
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
    if res.stats.get("skipped_parameters"):
        lines.append("  left out (they fix load-time numbers of the scene: positions, points, "
                     f"radii): {', '.join(res.stats['skipped_parameters'])}")
    if res.stats.get("event_driven"):  # across impacts: the jump of S at each event
        events = res.stats["events"]
        where = ", ".join(f"{e['element']} at {e['time']:.6g} s" for e in events[:4])
        more = " …" if len(events) > 4 else ""
        lines.append(f"  across {len(events)} impact(s)" + (f" ({where}{more})" if events
                                                            else "")
                     + ": the sensitivity jumps at each (saltation matrix)")
    return data, "\n".join(lines)

