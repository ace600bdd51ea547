"""Command-line interface: ``casmbd VERB SCENE [options]``.

Verbs: ``info`` (coordinates, constraints, degrees of freedom, dependent equations),
``kinematics`` (positions, velocities and accelerations on a time grid), ``simulate`` (forward
dynamics), ``inverse`` (driver and actuator efforts), ``statics`` (equilibrium and its
stability), ``linearize`` (frequencies, damping ratios, state space) and ``sweep`` (one
analysis at many parameter values).  Every verb prints a
readable summary, or with ``--json`` exactly one JSON object on stdout; ``--out FILE.npz`` saves
every array.  Errors end with a non-zero exit status and one ``error: …`` line on stderr
(a traceback only with ``--debug``).

The package: this module holds the parser and :func:`main`; the verbs live in
:mod:`casmbd.cli.info`, :mod:`casmbd.cli.analyses` (kinematics … linearize),
:mod:`casmbd.cli.workbench` (plot, animate, sweep, sensitivity) and :mod:`casmbd.cli.optimal`
(ocp, bench) and are imported when their verb runs (:data:`VERBS`); the parsers of the last
two in :mod:`casmbd.cli.verbs`, the shared helpers in :mod:`casmbd.cli.common`.  The CLI is
the top layer: it loads scene files (casmbd.io) and hands Mechanisms to the analyses.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import importlib
import json
import os
import sys
import time
import warnings
from collections.abc import Sequence

from casmbd import __version__, interrupts
from casmbd.analysis.formulations import FORMULATIONS
from casmbd.analysis.integrators.kinds import INTEGRATORS
from casmbd.cli.common import (
    CommandParser,
    UsageError,
    add_mode_flag,
    add_output_flags,
    finite_json,
    nonnegative_float,
    positive_float,
    positive_int,
)
from casmbd.cli.registry import VERB_PARSERS, VERBS, register_verb
from casmbd.cli.verbs import (
    add_bench_verb,
    add_sensitivity_verb,
    add_sweep_verb,
    add_view_verb,
    add_workbench_verbs,
)
from casmbd.errors import CasmbdError

EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT

#: verb -> (module, function): the module is imported when its verb runs (lazy loading, as
#: in ``casmbd/__init__``), so ``casmbd info`` loads neither the OCP, the sweeps nor the plots
_HANDLERS = {"info": ("info", "_cmd_info"), "kinematics": ("analyses", "_cmd_kinematics"),
             "simulate": ("analyses", "_cmd_simulate"), "inverse": ("analyses", "_cmd_inverse"),
             "statics": ("analyses", "_cmd_statics"),
             "linearize": ("analyses", "_cmd_linearize"), "ocp": ("optimal", "_cmd_ocp"),
             "plot": ("workbench", "_cmd_plot"), "sensitivity": ("workbench", "_cmd_sensitivity"),
             "bench": ("optimal", "_cmd_bench"), "animate": ("workbench", "_cmd_animate"),
             "sweep": ("workbench", "_cmd_sweep"), "view": ("view", "_cmd_view")}


def _verb(module: str, name: str):
    """The function ``name`` of ``casmbd.cli.<module>``, imported on its first call."""
    def run(args):
        return getattr(importlib.import_module(f"casmbd.cli.{module}"), name)(args)
    run.__name__ = run.__qualname__ = name
    return run


for _name, _where in _HANDLERS.items():  # the shipped verbs (casmbd.cli.registry.VERBS)
    register_verb(_name, _verb(*_where), builtin=True)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``casmbd`` command."""
    parser = CommandParser(prog="casmbd",
                           description="Dynamics of constrained mechanisms on CasADi.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="verb", parser_class=CommandParser)

    def common(p):
        p.add_argument("scene", help="scene file (TOML)")
        add_output_flags(p)
        add_mode_flag(p)

    def grid(p):
        p.add_argument("--t-end", type=positive_float, required=True, help="final time [s]")
        p.add_argument("--steps", type=positive_int, required=True,
                       help="number of output intervals (N + 1 output times from 0 to T)")
        p.add_argument("--out", help="save every array to this .npz file, or one column per "
                                     "scalar series to this .csv file (the suffix decides)")

    p = sub.add_parser("info", help="coordinates, constraints, degrees of freedom")
    common(p)
    def redundancy(p):  # simulate's option; "minimum_norm" (keep every row) is simulate's
        p.add_argument("--redundancy", choices=("auto", "remove"), default="auto",
                       help="redundant constraint equations: removed and named (both choices; "
                            "reactions they leave undetermined are the minimum-norm ones)")

    p = sub.add_parser("kinematics", help="kinematic analysis of a driven mechanism")
    common(p)
    grid(p)
    redundancy(p)

    p = sub.add_parser("inverse", help="inverse dynamics: driver efforts and reactions")
    common(p)
    grid(p)
    redundancy(p)

    p = sub.add_parser("statics", help="static equilibrium, reactions and stability")
    common(p)
    redundancy(p)
    p.add_argument("--method", choices=("augmented", "reduced"), default="augmented",
                   help="Newton on (q, lambda) (default) or on the independent coordinates")
    p.add_argument("--stable", action="store_true",
                   help="find a stable equilibrium (descend the potential energy) instead of "
                        "the one nearest the initial configuration, stable or not")

    p = sub.add_parser("simulate", help="forward dynamics")
    common(p)
    grid(p)
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
    p = sub.add_parser("linearize", help="natural frequencies, linearized equations and "
                                         "stability about the initial configuration, the "
                                         "static equilibrium or a stored state")
    common(p)
    redundancy(p)
    where = p.add_mutually_exclusive_group()
    where.add_argument("--at-equilibrium", action="store_true",
                       help="find the static equilibrium (as the statics verb) and linearize "
                            "there")
    where.add_argument("--from", dest="from_result", metavar="RESULT.npz", default=None,
                       help="linearize about the state stored in this result (of the same "
                            "scene) at the output time nearest --time")
    p.add_argument("--time", type=float, default=None,
                   help="with --from: the time of the stored state (nearest output time)")
    p.add_argument("--stable", action="store_true",
                   help="with --at-equilibrium: about a stable equilibrium (as statics "
                        "--stable) instead of the one nearest the initial configuration")
    p = sub.add_parser("ocp", help="trajectory optimisation: the scene's [ocp] table")
    common(p)
    p.add_argument("--out", help="save the solution (t, q, v, u, statistics) to this .npz "
                                 "file, or its result on the mesh nodes to this .csv file")
    p.add_argument("--intervals", type=positive_int, default=None,
                   help="number of control intervals (overrides the table)")
    p.add_argument("--transcription", choices=("radau", "legendre", "multiple_shooting"),
                   default=None, help="overrides the table")
    p.add_argument("--no-replay", action="store_true",
                   help="skip the forward replay of the optimal controls")
    p.add_argument("--plot", default=None, help="save a figure of coordinates and controls")
    add_workbench_verbs(sub)
    add_sweep_verb(sub)
    add_sensitivity_verb(sub)
    add_bench_verb(sub)
    add_view_verb(sub)
    for name, spec in VERB_PARSERS.items():  # registered verbs (casmbd.cli.registry)
        p = sub.add_parser(name, help=spec.help)
        if spec.scene:
            common(p)
        else:
            add_output_flags(p)
        if spec.add_arguments is not None:
            spec.add_arguments(p)
    for p in sub.choices.values():
        if not any("--verbose" in a.option_strings for a in p._actions):
            p.add_argument("--verbose", action="store_true",
                           help="print the solver statistics after the summary")
    return parser


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


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """A warning on the command line: ``warning: …`` (the source line only with ``--debug``)."""
    return f"warning: {message}\n"


def _flush_c_stdio() -> None:
    """Flush the C library's stdio buffers (``fflush(NULL)``): text that C code (IPOPT,
    LAPACK's XERBLA, a compiler driver) wrote with ``printf`` sits there until flushed."""
    with contextlib.suppress(Exception):  # no C library to call: nothing buffered there
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def _stdout_to_stderr():
    """File descriptor 1 points at file descriptor 2 inside the block, and back after it.

    With ``--json`` stdout carries exactly one JSON object: whatever the work prints —
    Python's ``print``, C libraries writing to fd 1 (IPOPT's banner, LAPACK's "On entry to
    DTRSV parameter number 6 had an illegal value", CasADi's messages) — goes to stderr, and
    the JSON is written to the real stdout afterwards.  Where sys.stdout has no file
    descriptor (a test's capture object) Python-level output is redirected only.
    """
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, ValueError, OSError):
        fd = None
    if fd is None:
        with contextlib.redirect_stdout(sys.stderr):
            yield
        return
    sys.stdout.flush()
    _flush_c_stdio()
    saved = os.dup(fd)
    try:
        os.dup2(sys.stderr.fileno(), fd)
        yield
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
        _flush_c_stdio()  # C text buffered during the work goes to stderr, not the JSON
        os.dup2(saved, fd)
        os.close(saved)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``casmbd`` command; returns the exit status.

    Warnings print as one ``warning: …`` line each (Python's form, with the file and source
    line, with ``--debug``), each notice once per command (:func:`_once_per_run`).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    saved, saved_show = warnings.formatwarning, warnings.showwarning
    if "--debug" not in argv:
        warnings.formatwarning = _one_line_warning
    warnings.showwarning = _once_per_run(saved_show)
    try:
        return _run(argv)
    finally:
        warnings.formatwarning, warnings.showwarning = saved, saved_show


def _once_per_run(show):
    """``warnings.showwarning`` that says each notice (category and text) once per command:
    a scene read again by a verb (the result's embedded scene, an animation's frames) would
    otherwise repeat its loader's warnings (a URDF's ignored <visual>/<collision> elements were
    said three times per ``animate``; Python's default filter repeats a warning raised from
    another line)."""
    said: set = set()

    def once(message, category, filename, lineno, file=None, line=None):
        key = (category, str(message))
        if key not in said:
            said.add(key)
            show(message, category, filename, lineno, file, line)
    return once


def _run(argv: list[str]) -> int:
    """:func:`main` after the warning format is set."""
    debug = "--debug" in argv
    interrupts.install()  # Ctrl-C is remembered even where CasADi turns it into an error
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except UsageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.version:
        print(__version__)
        return 0
    if not args.verb:
        print("error: missing verb (one of: " + ", ".join(VERBS) + "); see casmbd --help",
              file=sys.stderr)
        return EXIT_USAGE
    if getattr(args, "json", False):
        os.environ["CASMBD_PROGRESS"] = "0"  # one JSON object: no progress bars
    t0, started = time.perf_counter(), time.time()
    quiet = _stdout_to_stderr() if getattr(args, "json", False) else contextlib.nullcontext()
    try:
        with quiet:
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
        shown = getattr(exc, "cli_output", None)  # what the verb found before it failed
        if shown is not None:
            _print_output(args, *shown)
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
    _print_output(args, data, text)
    return 0


def _print_output(args, data: dict, text: str) -> None:
    """The verb's one JSON object (``--json``) or its text summary on stdout (after the work:
    with ``--json`` the real stdout again, see :func:`_stdout_to_stderr`).  A verb that
    fails after finding something (``info`` of a mechanism that cannot be assembled) hands it
    here as ``exc.cli_output = (data, text)``."""
    try:
        if args.json:
            # numpy -> builtins, NaN -> null, without copying the result's lists; the text
            # and its newline written apart (no third copy of the text)
            sys.stdout.write(json.dumps(finite_json(data), allow_nan=False))
            sys.stdout.write("\n")
        else:
            if text:
                print(text)
            if getattr(args, "verbose", False) and isinstance(data.get("stats"), dict):
                print(_verbose_stats(data["stats"]))
        sys.stdout.flush()
    except BrokenPipeError:  # `casmbd … | head`: the reader left; not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


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
