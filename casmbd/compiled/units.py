"""Translation units of a compiled library: which functions go together, at which flags, and
their parallel compilation.

gcc's optimiser is superlinear on long straight-line functions and one process compiles one
file, so a library of many large functions compiles faster as one translation unit per
function, compiled at once on every core and linked into one shared library; and the
functions an integrator calls millions of times (``hot``) are worth ``-O2`` while those
evaluated once per output time (post-processing, reactions, outputs, the constraint terms of
the start and the diagnostics) are not: they get :data:`COLD_FLAGS`.  Measured on the 100-rod
chain in absolute coordinates, augmented Lagrangian (each function alone, 2-core machine under
load): the right-hand side 376 kB of C, 15.9 s at ``-O2``; the post-processing 308 kB,
20.3 s at ``-O2``, 37.5 s at ``-O1``, 2.3 s at ``-O0``; the twelve other functions 36 s at
``-O2``, 9 s at ``-O0``.

Rules (:func:`plan`): with flags chosen by the caller or ``$CASMBD_CFLAGS`` every function gets
them; otherwise a function gets :data:`COLD_FLAGS` when ``hot`` is given and does not name it
or its C alone exceeds :data:`LARGE_SOURCE`, :data:`MEDIUM_FLAGS` when it exceeds
:data:`MEDIUM_SOURCE`, and the default flags otherwise — :data:`BULK_FLAGS` in place of the
default when ``hot`` is not given and the C of all functions exceeds :data:`BULK_SOURCE`
(tiago_dual's per-call model: 135 Functions, 7.4 MB of C, 130 of them frame Jacobians of
24–48 kB; gcc's CPU time 73 s at -O2, 38 s at ``BULK_FLAGS`` with the output guards
merged, per call unchanged).  Below :data:`SPLIT_SOURCE` bytes of C in all, one unit per
distinct flag set (the compiler's start-up dominates small builds); above it, one unit per
function, except the hot functions and the functions that call one of them (an integrator's
compiled block, the post-processing that takes q̈ from the dynamics) share one: the
dynamics' C once.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import shlex
import signal
import subprocess
import time
from collections.abc import Callable, Collection, Sequence

import casadi

from casmbd.errors import CompileError

__all__ = ["BULK_FLAGS", "BULK_SOURCE", "COLD_FLAGS", "LARGE_SOURCE", "MEDIUM_FLAGS",
           "MEDIUM_SOURCE", "SHARE_SOURCE", "SPLIT_SOURCE", "compile_objects", "plan"]

#: a hot function whose C alone exceeds this many bytes gets :data:`MEDIUM_FLAGS`: gcc's
#: ``-O2`` is superlinear on CasADi's long straight-line functions.  Measured (gcc 12, one
#: core, right-hand sides of pendulum chains): articulated, 300 rods, 1.5 MB: -O2 97.8 s /
#: 28.1 µs per call, -O1 16.4 s / 20.8 µs, -O0 2.8 s / 93.8 µs; augmented Lagrangian,
#: 300 rods, 1.5 MB: -O1 50.4 s / 311 µs, -O0 6.0 s / 1193 µs.  Below this size ``-O2`` stays
#: (augmented Lagrangian, 100 rods, 485 kB: -O2 13.0 s / 88 µs, -O1 7.8 s / 117 µs).
MEDIUM_SOURCE = 1_000_000
#: flags of the hot functions between :data:`MEDIUM_SOURCE` and :data:`LARGE_SOURCE`
MEDIUM_FLAGS: tuple[str, ...] = ("-O1",)
#: a function whose C alone exceeds this many bytes gets :data:`COLD_FLAGS` unless flags were
#: chosen (1000 rods, 5.7 MB: -O0 7.7 s; -O1 did not finish in 8 min on a loaded machine).
#: tiago_dual's per-call forward dynamics (101 joints, articulated-body recursion, 2.2 MB):
#: -O0 3.3 s / 92 µs per call, -O1 26 s / 35 µs, -O2 41 s / 33 µs (quiet machine; Pinocchio's
#: ``aba`` 22 µs): worth -O1 up to here.
LARGE_SOURCE = 3_000_000
#: flags of the functions that are not hot, and of the large ones
COLD_FLAGS: tuple[str, ...] = ("-O0",)
#: above this many bytes of C in all, one translation unit per function
SPLIT_SOURCE = 200_000
#: the functions that call a hot function share its unit (its C compiled once) only when the
#: hot functions' C exceeds this many bytes; below it each caller is its own unit at its own
#: flags and repeats the hot C at those flags.  Sharing puts the caller at the hot flags: the
#: folded 1000-rod chain's right-hand side (0.34 MB of C, mostly index tables) pulled
#: ``post`` with the unrolled energies (1.3 MB) into its -O2 unit
SHARE_SOURCE = 1_000_000
#: a library without ``hot`` functions (every Function evaluated per call, e.g. a robot's
#: per-call model) whose C in all exceeds this many bytes gets :data:`BULK_FLAGS` instead of
#: the default flags: its cost is the number of Functions, not one of them.
BULK_SOURCE = 2_000_000
#: ``-O1`` with ``-O2``'s type-based alias analysis: CasADi's straight-line code stores
#: through ``res[i]`` between loads of ``arg[i]`` and ``res[i]``; without strict aliasing each
#: store forces the pointers to be loaded again, the part of ``-O2`` that matters per call.
#: Measured (gcc 12, one core, tiago_dual's per-call Functions, output guards merged by
#: :func:`casmbd.compiled.codegen._merge_output_guards`): the deepest frame Jacobian (48 kB
#: of C) -O2 0.32 s / 0.408 µs per call, -O1 0.15 s / 0.454 µs, -O1 -fstrict-aliasing
#: 0.15 s / 0.419 µs; the mass matrix (0.94 MB) -O2 10.0 s / 7.80 µs, -O1 -fstrict-aliasing
#: 6.0 s / 7.65 µs.
BULK_FLAGS: tuple[str, ...] = ("-O1", "-fstrict-aliasing")
_STDERR_TAIL = 4000

#: a unit: the functions it holds, their C template, the optimisation flags
Unit = tuple[list[casadi.Function], str, list[str]]


def plan(functions: Sequence[casadi.Function], generate: Callable[[list], str],
         chosen: list[str] | None, default: list[str],
         hot: Collection[str] | None) -> list[Unit]:
    """The translation units of ``functions`` (see the module notes); ``generate`` gives the
    C template of a list of functions."""
    alone = {f.name(): generate([f]) for f in functions}
    if chosen is None and hot is None and sum(map(len, alone.values())) > BULK_SOURCE:
        default = list(BULK_FLAGS)

    def by_size(size: int) -> list[str]:
        return list(chosen) if chosen is not None else list(COLD_FLAGS) \
            if size > LARGE_SOURCE else list(MEDIUM_FLAGS) if size > MEDIUM_SOURCE \
            else list(default)

    flags_of = {f.name(): list(COLD_FLAGS) if chosen is None and hot is not None
                and f.name() not in hot else by_size(len(alone[f.name()]))
                for f in functions}
    if sum(map(len, alone.values())) > SPLIT_SOURCE:
        # the hot functions and their callers share one unit: an integrator's block and the
        # post-processing call the dynamics, whose C then appears (and is compiled) once
        hot_names = set(hot or ())
        # callers share the hot unit only when the hot C is worth not repeating: a folded
        # right-hand side (casmbd.system.chain_fold) is 0.34 MB at N = 1000, and its caller
        # ``post`` carries the unrolled energies (1.3 MB: 46 s of gcc at -O2, -O0 alone)
        share = sum(len(alone[f.name()]) for f in functions if f.name() in hot_names) \
            > SHARE_SOURCE
        together = [f for f in functions if f.name() in hot_names
                    or (hot_names and share and _calls(f) & hot_names)]
        if not together or (len(together) < 2 and share):
            return _with_callees(functions, alone, flags_of, generate)
        source = generate(together)  # flags by its largest hot function
        flags = by_size(max(len(alone[f.name()]) for f in together if f.name() in hot_names))
        return [(together, source, flags)] + [([f], alone[f.name()], flags_of[f.name()])
                                              for f in functions if f not in together]
    groups: dict[tuple[str, ...], list[casadi.Function]] = {}
    for f in functions:
        groups.setdefault(tuple(flags_of[f.name()]), []).append(f)
    return [(group, alone[group[0].name()] if len(group) == 1 else generate(group), list(fl))
            for fl, group in groups.items()]


def _with_callees(functions: Sequence[casadi.Function], alone: dict, flags_of: dict,
                  generate: Callable[[list], str]) -> list[Unit]:
    """One unit per function, except that a function calling exactly one other of the list
    (a ``Function.map`` batch of a per-call Function) joins that one's unit at its flags: its
    C then appears, and is compiled, once (tiago_dual's per-call model: 3.9 MB of C less)."""
    names = {f.name() for f in functions}
    owner = {}
    for f in functions:
        inner = (_callees(f) & names) - {f.name()}
        if len(inner) == 1:
            owner[f.name()] = inner.pop()
    out: list[Unit] = []
    for f in functions:
        if f.name() in owner and owner[f.name()] not in owner:
            continue
        group = [f] + [g for g in functions if owner.get(g.name()) == f.name()
                       and f.name() not in owner]
        out.append((group, alone[f.name()] if len(group) == 1 else generate(group),
                    flags_of[f.name()]))
    return out


def _callees(function: casadi.Function) -> set[str]:
    """Names of every Function ``function`` calls, at any depth (``find_functions``)."""
    try:
        return {g.name() for g in function.find_functions()}
    except (AttributeError, RuntimeError):  # pragma: no cover - CasADi before 3.6
        return _calls(function)


def _calls(function: casadi.Function) -> set[str]:
    """Names of the Functions an MX ``function`` calls (empty for SX functions)."""
    if not function.is_a("MXFunction"):
        return set()
    out = set()
    for i in range(function.n_instructions()):
        if function.instruction_id(i) == casadi.OP_CALL:
            out.add(function.instruction_MX(i).which_function().name())
    return out


def _kill(proc: subprocess.Popen) -> None:
    with contextlib.suppress(OSError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def _cpus() -> int:
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1  # pragma: no cover - not Linux


def compile_objects(commands: list[list[str]], logs: list[pathlib.Path], timeout: float,
                    workers: int | None = None) -> float:
    """Run the compiler ``commands`` (each writing one object file; its output to the file of
    ``logs``), ``workers`` at a time (default: the CPUs this process may use), each in its own
    process group; return the wall seconds.  A failure or a timeout ends the others and raises
    :class:`CompileError` with the command and the tail of its output."""
    workers = workers or _cpus()
    start = time.perf_counter()
    pending = list(zip(commands, logs, strict=True))
    running: list[tuple[subprocess.Popen, list[str], pathlib.Path, float]] = []
    try:
        while pending or running:
            while pending and len(running) < workers:
                command, log = pending.pop(0)
                try:
                    with open(log, "wb") as out:
                        proc = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT,
                                                start_new_session=True)
                except OSError as exc:
                    raise CompileError(f"cannot run the C compiler {command[0]!r}: {exc}"
                                       ) from exc
                running.append((proc, command, log, time.perf_counter()))
            time.sleep(0.01)
            for entry in list(running):
                proc, command, log, began = entry
                code = proc.poll()
                if code is None:
                    if time.perf_counter() - began > timeout:
                        raise CompileError(f"C compiler timed out after {timeout:g} s: "
                                           f"{shlex.join(command)}")
                    continue
                running.remove(entry)
                if code != 0:
                    tail = log.read_text(errors="replace")[-_STDERR_TAIL:].strip()
                    raise CompileError(f"C compiler failed with exit code {code}: "
                                       f"{shlex.join(command)}\n{tail}")
    finally:
        for proc, *_ in running:
            if proc.poll() is None:
                _kill(proc)
    return time.perf_counter() - start


def object_commands(compiler: list[str], units: list[Unit], sources: list[pathlib.Path]
                    ) -> tuple[list[list[str]], list[pathlib.Path]]:
    """``cc FLAGS -fPIC -c unit.c -o unit.o`` of each unit, and the object files."""
    objects = [src.with_suffix(".o") for src in sources]
    commands = [[*compiler, *flags, "-fPIC", "-c", str(src), "-o", str(obj)]
                for (_, _, flags), src, obj in zip(units, sources, objects, strict=True)]
    return commands, objects
