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
(ocp, bench) and are imported when their verb runs (:data:`VERBS`); every verb is registered
here with its help and its arguments (:mod:`casmbd.cli.verbs`,
:func:`casmbd.cli.registry.register_verb`), the shared helpers in :mod:`casmbd.cli.common`.
The CLI is the top layer: it loads scene files (casmbd.io) and hands Mechanisms to the analyses.
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
from casmbd.cli import verbs
from casmbd.cli.common import (
    CommandParser,
    UsageError,
    add_mode_flag,
    add_output_flags,
    finite_json,
)
from casmbd.cli.registry import VERB_PARSERS, VERBS, register_verb
from casmbd.errors import CasmbdError

EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT


def _verb(module: str, name: str):
    """The function ``name`` of ``casmbd.cli.<module>``, imported on its first call (lazy
    loading, as in ``casmbd/__init__``: ``casmbd info`` loads neither the OCP, the sweeps nor
    the plots)."""
    def run(args):
        return getattr(importlib.import_module(f"casmbd.cli.{module}"), name)(args)
    run.__name__ = run.__qualname__ = name
    run.handler = (f"casmbd.cli.{module}", name)  # where it lives (test_startup.py)
    return run


# the shipped verbs, in the order of ``casmbd --help``: each one its handler (imported when it
# runs), its help and its arguments (casmbd.cli.verbs)
register_verb("info", _verb("info", "_cmd_info"),
              help="coordinates, constraints, degrees of freedom")
register_verb("kinematics", _verb("analyses", "_cmd_kinematics"),
              help="kinematic analysis of a driven mechanism",
              add_arguments=verbs.kinematics_arguments)
register_verb("inverse", _verb("analyses", "_cmd_inverse"),
              help="inverse dynamics: driver efforts and reactions",
              add_arguments=verbs.kinematics_arguments)
register_verb("statics", _verb("analyses", "_cmd_statics"),
              help="static equilibrium, reactions and stability",
              add_arguments=verbs.statics_arguments)
register_verb("simulate", _verb("analyses", "_cmd_simulate"), help="forward dynamics",
              add_arguments=verbs.simulate_arguments)
register_verb("linearize", _verb("analyses", "_cmd_linearize"),
              help="natural frequencies, linearized equations and stability about the initial "
                   "configuration, the static equilibrium or a stored state",
              add_arguments=verbs.linearize_arguments)
register_verb("ocp", _verb("optimal", "_cmd_ocp"),
              help="trajectory optimisation: the scene's [ocp] table",
              add_arguments=verbs.ocp_arguments)
register_verb("plot", _verb("workbench", "_cmd_plot"),
              help="figures of a saved result against time",
              add_arguments=verbs.plot_arguments, shared=False)
register_verb("animate", _verb("workbench", "_cmd_animate"),
              help="animation (.gif, .mp4 with ffmpeg) or still frame (.png) of a scene or a "
                   "saved result",
              add_arguments=verbs.animate_arguments, shared=False)
register_verb("sweep", _verb("workbench", "_cmd_sweep"),
              help="parameter sweep: one analysis at many values of the scene's [parameters]",
              add_arguments=verbs.sweep_arguments, shared=False)
register_verb("sensitivity", _verb("workbench", "_cmd_sensitivity"),
              help="exact derivatives of simulation outputs with respect to scene parameters "
                   "(IDAS)",
              add_arguments=verbs.sensitivity_arguments, shared=False)
register_verb("bench", _verb("optimal", "_cmd_bench"),
              help="run the benchmark suite of a casmbd checkout (python -m benchmarks)",
              add_arguments=verbs.bench_arguments, shared=False)
register_verb("view", _verb("view", "_cmd_view"),
              help="3-D view of a scene, result or OCP solution in the browser (live server "
                   "on 127.0.0.1, or --html FILE)",
              add_arguments=verbs.view_arguments, shared=False)
register_verb("identify", _verb("identify", "_cmd_identify"),
              help="identify masses, centres of mass, inertias and friction from measured "
                   "joint data (base parameters by weighted least squares, then physically "
                   "consistent ones)",
              add_arguments=verbs.identify_arguments)
register_verb("export", _verb("export", "_cmd_export"),
              help="the dynamics as a standalone C99 library (sources, header, README, "
                   "example)",
              add_arguments=verbs.export_arguments, shared=False)
register_verb("excite", _verb("excite", "_cmd_excite"),
              help="excitation trajectory for identification: periodic Fourier series "
                   "minimising the condition number of the base regressor under joint limits",
              add_arguments=verbs.excite_arguments)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``casmbd`` command: one sub-parser per registered verb
    (:data:`casmbd.cli.registry.VERB_PARSERS`), in registration order."""
    parser = CommandParser(prog="casmbd",
                           description="Dynamics of constrained mechanisms on CasADi.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="verb", parser_class=CommandParser)
    for name, spec in VERB_PARSERS.items():
        p = sub.add_parser(name, help=spec.help)
        if spec.shared and spec.scene:
            p.add_argument("scene", help="scene file (TOML)")
            p.add_argument("--floating-base", action="store_true",
                           help="a bare .urdf: its root link floats free (as [scene] "
                                "floating_base = true)")
            add_output_flags(p)
            add_mode_flag(p)
        elif spec.shared:
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
