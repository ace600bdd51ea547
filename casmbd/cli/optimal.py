"""The ``ocp`` verb (the scene's ``[ocp]`` table) and the ``bench`` verb (the benchmark suite of
a source checkout); the ``bench`` parser is in :mod:`casmbd.cli.verbs`.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from casmbd.cli.common import load_scene_for, save_result
from casmbd.errors import AnalysisError, OptimizationError, SceneError
from casmbd.io.ocp_table import ocp_from_scene
from casmbd.viz.plots import plot_result


def _cmd_ocp(args) -> tuple[dict, str]:
    """Solve the scene's ``[ocp]`` table; replay the controls with the forward simulator."""
    mech = load_scene_for(args)
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
            _save_solution(exc.solution, args.out)
        raise
    if not args.no_replay:
        sol.replay()
    if args.out:
        _save_solution(sol, args.out)
    notes = []
    if args.plot:  # the plot verb's default: states, controls with their bounds, max |C|
        notes = plot_result(sol.to_result(), out=args.plot, mechanism=mech).casmbd_notes
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
             f"  dynamics {s.get('dynamics')} ({s.get('dynamics_choice')})",
             f"  setup {s['setup_seconds']:.3g} s, NLP solve {s['solve_seconds']:.3g} s"]
    for name in sol.controls:
        u = sol.control(name)
        lines.append(f"  control {name:12s} [{u.min():+.4g}, {u.max():+.4g}]")
    lines += [f"  saved {f}" for f in (args.out, args.plot) if f]
    lines += [f"  note: {n}" for n in notes]
    return data, "\n".join(lines)


def _save_solution(sol, out: str) -> None:
    """``--out``: the solution file (``.npz``, with the controls per interval) or the CSV of its
    result on the mesh nodes (``.csv``, :meth:`~casmbd.results.Result.to_csv`)."""
    if Path(out).suffix.lower() == ".csv":
        save_result(sol.to_result(), out)
    else:
        try:
            sol.save(out)
        except OSError as exc:
            raise AnalysisError(f"cannot write --out '{out}': {exc.strerror or exc}") from None


def _cmd_bench(args) -> tuple[dict, str]:
    """Run ``python -m benchmarks`` in the checkout that holds this casmbd.

    Only the checkout of the running package is used, never the current directory: a
    ``benchmarks/`` folder in a downloaded directory must not become code that ``casmbd bench``
    runs.  The suite is not installed with the package (``pip install -e .`` keeps it beside).
    """
    root = Path(__file__).resolve().parents[2]  # casmbd/cli/optimal.py -> checkout
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

