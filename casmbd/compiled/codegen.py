"""Compile CasADi functions to a shared library and cache it on disk.

:func:`compile_functions` generates C code for a list of :class:`casadi.Function` objects with
:class:`casadi.CodeGenerator` (one source file, or for large builds one translation unit per
function compiled in parallel, :mod:`casmbd.compiled.units`), compiles it with the system C
compiler into a shared library, and loads every function back with :func:`casadi.external`. The
library is cached in :func:`cache_dir` under a name derived from a hash of the generated source,
the compiler flags, the compiler path, the CasADi version and the platform, so that a later call
(in this or another process) with the same functions loads it without compiling again. A cached
library is opened only after its SHA-256, build key and function signatures have been checked
against the record written beside it (:mod:`casmbd.compiled.cache`); one that fails a check,
cannot be loaded or loads functions of other signatures is rebuilt with a
:class:`RuntimeWarning`, never used.

Environment variables
---------------------
``CASMBD_CACHE_DIR``
    Directory of the cache (default ``$XDG_CACHE_HOME/casmbd`` or ``~/.cache/casmbd``).
``CASMBD_COMPILE``
    ``0`` makes ``mode="auto"`` fall back to the CasADi virtual machine without compiling.
``CASMBD_CFLAGS``
    Space separated optimisation flags replacing the default ``-O2``.
``CC``
    C compiler to use; when unset or not found, ``cc``, ``gcc`` and ``clang`` are tried.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pathlib
import platform
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Collection, Sequence
from dataclasses import dataclass

import casadi

from casmbd.compiled import cache, units
from casmbd.compiled.cache import cache_dir
from casmbd.errors import CompileError

__all__ = ["COMPILE_COUNT", "BuildReport", "cache_dir", "compile_functions"]

#: Number of times the C compiler has run in this process (for tests and diagnostics).
COMPILE_COUNT: int = 0

#: Flags used when neither ``flags`` nor ``$CASMBD_CFLAGS`` is given.
DEFAULT_FLAGS: tuple[str, ...] = ("-O2",)

#: Flags always added to make a loadable shared library.
SHARED_FLAGS: tuple[str, ...] = ("-shared", "-fPIC")

#: Libraries linked after the source file.
LINK_LIBS: tuple[str, ...] = ("-lm",)

#: Seconds after which a compiler run is abandoned.
COMPILE_TIMEOUT: float = 600.0

_MODES = ("auto", "compiled", "vm")
_CODEGEN_OPTIONS = {"with_header": False, "casadi_real": "double", "casadi_int": "long long int"}
# Placeholder name given to the code generator; replaced by ``{name}_{key[:16]}`` afterwards so
# that the internal C symbols are unique per model while the key is computed from the source.
_PREFIX_MARKER = "casmbdprefixf7c2e9a41d"
_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_STDERR_TAIL = 4000


@dataclass
class BuildReport:
    """What :func:`compile_functions` did.

    Attributes
    ----------
    mode : str
        ``"compiled"`` when the returned functions come from the shared library, ``"vm"`` when
        they are the original functions evaluated by the CasADi virtual machine.
    cache_hit : bool
        True when the library was loaded from the cache without compiling.
    compiled : bool
        True when this call ran the C compiler.
    codegen_seconds : float
        Time spent generating (and hashing) the C source.
    compile_seconds : float
        Time spent in the C compiler (0.0 on a cache hit).
    load_seconds : float
        Time spent loading the functions from the library.
    library : str or None
        Path of the shared library, None in ``"vm"`` mode.
    key : str
        Hex SHA-256 key of the build (empty when no code was generated).
    libraries : tuple of str
        Paths of every shared library the functions were loaded from (two when the large
        functions went to a library of their own).
    """

    mode: str
    cache_hit: bool
    compiled: bool
    codegen_seconds: float
    compile_seconds: float
    load_seconds: float
    library: str | None
    key: str
    libraries: tuple[str, ...] = ()


def find_compiler() -> list[str] | None:
    """Return the compiler command (absolute executable first) or None if there is none.

    ``$CC`` may hold a command with arguments (e.g. ``"ccache gcc"``); when it is unset or its
    executable cannot be found, ``cc``, ``gcc`` and ``clang`` are looked up on ``PATH``.
    """
    env_cc = os.environ.get("CC", "").strip()
    if env_cc:
        try:
            parts = shlex.split(env_cc)
        except ValueError:
            parts = []
        if parts:
            exe = shutil.which(parts[0])
            if exe is not None:
                return [exe, *parts[1:]]
    for candidate in ("cc", "gcc", "clang"):
        exe = shutil.which(candidate)
        if exe is not None:
            return [exe]
    return None


def resolve_flags(flags: Sequence[str] | None) -> list[str]:
    """Return the optimisation flags: ``flags``, else ``$CASMBD_CFLAGS``, else ``-O2``."""
    if flags is not None:
        if isinstance(flags, str):
            raise TypeError("flags must be a sequence of strings, not a single string")
        return [str(flag) for flag in flags]
    env = os.environ.get("CASMBD_CFLAGS")
    if env is not None and env.strip():
        return env.split()
    return list(DEFAULT_FLAGS)


def platform_tag() -> str:
    """Return a description of the platform that determines binary compatibility."""
    return f"{sys.platform}-{platform.machine()}-{platform.system()}"


def _compute_key(template: str, name: str, compiler: list[str], flags: list[str]) -> str:
    """Hash everything that determines the content of the shared library."""
    digest = hashlib.sha256()
    parts = [
        "casmbd-codegen-v1",
        name,
        "\x1f".join(compiler),
        "\x1f".join([*flags, *SHARED_FLAGS, *LINK_LIBS]),
        casadi.__version__,
        platform_tag(),
        repr(sorted(_CODEGEN_OPTIONS.items())),
    ]
    for part in parts:
        digest.update(part.encode("utf-8"))
        digest.update(b"\x00")
    digest.update(template.encode("utf-8"))
    return digest.hexdigest()


def _generate_template(functions: Sequence[casadi.Function]) -> str:
    """Generate the C source of all functions with a placeholder symbol prefix."""
    generator = casadi.CodeGenerator(f"{_PREFIX_MARKER}.c", dict(_CODEGEN_OPTIONS))
    for function in functions:
        generator.add(function)
    return _merge_output_guards(generator.dump())


#: one output store of CasADi's C: ``if (res[i]!=0) <one statement without braces>;``
_GUARD_RE = re.compile(r"^([ \t]*)if \((res\[\d+\])!=0\) ([^{}\n]*;)$", re.MULTILINE)


def _merge_output_guards(text: str) -> str:
    """CasADi's C with each run of consecutive stores to one output under one test.

    CasADi guards every store of an output entry, ``if (res[0]!=0) res[0][k]=a5;``: a dense
    output of n entries is n branches (tiago_dual's mass matrix 10 201, each frame
    Jacobian 606), which gcc's passes walk one basic block at a time.  Consecutive lines
    guarded by the same ``res[i]`` become ``if (res[i]!=0) {...}``: the same stores in the
    same order under the same (invariant) condition.  Measured (gcc 12, one core): the mass
    matrix unit 12.0 s → 10.0 s at -O2, 7.1 s → 6.0 s at -O1 -fstrict-aliasing; a frame
    Jacobian 0.21 s → 0.15 s at -O1 -fstrict-aliasing; per call unchanged.
    """
    out: list[str] = []
    run: list[str] = []
    indent = guard = ""

    def close() -> None:
        if run:
            body = run[0] if len(run) == 1 else "{" + " ".join(run) + "}"
            out.append(f"{indent}if ({guard}!=0) {body}")
            run.clear()

    for line in text.split("\n"):
        match = _GUARD_RE.match(line)
        if match is None:
            close()
            out.append(line)
        elif run and match.group(2) == guard:
            run.append(match.group(3))
        else:
            close()
            indent, guard = match.group(1), match.group(2)
            run.append(match.group(3))
    close()
    return "\n".join(out)


def _vm_report(codegen_seconds: float = 0.0, compile_seconds: float = 0.0, key: str = ""
               ) -> BuildReport:
    return BuildReport(mode="vm", cache_hit=False, compiled=False,
                       codegen_seconds=codegen_seconds, compile_seconds=compile_seconds,
                       load_seconds=0.0, library=None, key=key)


def _vm_result(
    functions: Sequence[casadi.Function], codegen_seconds: float = 0.0, key: str = ""
) -> tuple[dict[str, casadi.Function], BuildReport]:
    report = _vm_report(codegen_seconds, key=key)
    return {function.name(): function for function in functions}, report


def _rebuild_warning(library: pathlib.Path, reason: str, stacklevel: int) -> None:
    warnings.warn(f"casmbd: the cached library {library} is not used ({reason}); rebuilding "
                  "it", RuntimeWarning, stacklevel=stacklevel + 1)


def load_verified(names: list[str], library: pathlib.Path, expected: dict[str, dict]
                   ) -> tuple[dict[str, casadi.Function] | None, str | None]:
    """Load ``library`` and compare the loaded signatures with ``expected``: (functions,
    None), or (None, why they are not used)."""
    try:
        loaded = _load(names, library)
    except (RuntimeError, OSError) as exc:
        return None, f"it cannot be loaded: {exc}"
    diff = cache.differences(cache.signatures(loaded.values()), expected)
    if diff:
        return None, f"it loads other functions: {diff}"
    return loaded, None


def _load(names: list[str], library: pathlib.Path) -> dict[str, casadi.Function]:
    """Load every function of ``names`` from ``library`` with :func:`casadi.external`.

    A function compiled together with its ``jac_<name>`` companion gets exact Jacobians from
    it; otherwise derivatives fall back to finite differences (``enable_fd``), which
    integrators need only to set themselves up when no Newton iteration is used.
    """
    return {fname: casadi.external(fname, str(library), {"enable_fd": True}) for fname in names}


def _run_compiler(command: list[str], source: pathlib.Path | list[pathlib.Path],
                  library: pathlib.Path, record: dict | None = None) -> float:
    """Compile ``source`` into ``library`` atomically; return the seconds spent compiling.

    The compiler writes a temporary file of the cache directory; with ``record`` (the build key
    and function signatures) the hash record of that file is written first, then the file is
    renamed to ``library`` — both under the directory's lock, so that no process ever sees a
    half-written library or the record of another build beside it.
    """
    global COMPILE_COUNT
    try:
        fd, tmp = tempfile.mkstemp(dir=library.parent, prefix=f".{library.stem}.",
                                   suffix=".so.tmp")
    except OSError as exc:
        raise CompileError(f"cannot write in the cache directory {library.parent}: {exc}"
                           ) from exc
    os.close(fd)
    try:
        inputs = [str(p) for p in source] if isinstance(source, list) else [str(source)]
        full = [*command, *inputs, "-o", tmp, *LINK_LIBS]
        COMPILE_COUNT += 1
        start = time.perf_counter()
        try:
            # its own process group, so that a timeout also ends the compiler's children
            # (gcc's cc1 would otherwise run on as an orphan)
            proc = subprocess.Popen(full, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True, start_new_session=True)
        except OSError as exc:
            raise CompileError(f"cannot run the C compiler {command[0]!r}: {exc}") from exc
        try:
            stdout, stderr = proc.communicate(timeout=COMPILE_TIMEOUT)
        except subprocess.TimeoutExpired as exc:
            with contextlib.suppress(OSError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise CompileError(
                f"C compiler timed out after {COMPILE_TIMEOUT:g} s compiling {inputs[-1]}: "
                f"{shlex.join(full)}"
            ) from exc
        except BaseException:
            with contextlib.suppress(OSError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise
        result = subprocess.CompletedProcess(full, proc.returncode, stdout, stderr)
        elapsed = time.perf_counter() - start
        if result.returncode != 0:
            output = (result.stderr or "") + (result.stdout or "")
            tail = output[-_STDERR_TAIL:].strip()
            raise CompileError(
                f"C compiler failed with exit code {result.returncode} compiling "
                f"{pathlib.Path(inputs[-1]).name}: {shlex.join(full)}\n{tail}"
            )
        try:
            os.chmod(tmp, 0o755)
            if record is None:
                os.replace(tmp, library)
            else:
                with cache.entry_lock(library.parent):
                    cache.write_record(library, pathlib.Path(tmp), record)
                    os.replace(tmp, library)
        except OSError as exc:
            raise CompileError(f"cannot store the compiled library {library}: {exc}") from exc
        return elapsed
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _build(
    functions: Sequence[casadi.Function],
    names: list[str],
    name: str,
    flags: Sequence[str] | None,
    hot: Collection[str] | None = None,
) -> tuple[dict[str, casadi.Function], BuildReport]:
    """Generate, compile (unless cached) and load; raise CompileError on any failure.  The
    functions go into the translation units of :func:`casmbd.compiled.units.plan`, compiled
    in parallel and linked into one library."""
    compiler = find_compiler()
    if compiler is None:
        raise CompileError(
            "no C compiler found: set $CC or install cc, gcc or clang (checked $CC="
            f"{os.environ.get('CC', '')!r} and PATH)"
        )
    resolved_flags = resolve_flags(flags)
    chosen = resolved_flags if flags is not None or os.environ.get("CASMBD_CFLAGS", "").strip() \
        else None

    start = time.perf_counter()
    try:
        plan = units.plan(functions, _generate_template, chosen, resolved_flags, hot)
    except RuntimeError as exc:
        raise CompileError(f"CasADi cannot generate C code for {name!r}: {exc}") from exc
    key = _compute_key("\x1e".join(" ".join(fl) + "\x1d" + tpl for _, tpl, fl in plan),
                       name, compiler, resolved_flags)
    stem = f"{name}_{key[:16]}"
    sources = [tpl.replace(_PREFIX_MARKER, stem if len(plan) == 1 else f"{stem}_u{i}")
               for i, (_, tpl, _) in enumerate(plan)]
    codegen_seconds = time.perf_counter() - start

    directory = cache_dir()
    library = directory / f"{stem}.so"
    kept_source = directory / f"{stem}.c"

    expected = cache.signatures(functions)
    if library.exists():
        start = time.perf_counter()
        # hash, key and signatures are checked BEFORE dlopen: a truncated library would crash
        # the process, another model's would give wrong numbers
        reason = cache.check_entry(library, key, expected)
        loaded = None
        if reason is None:
            loaded, reason = load_verified(names, library, expected)
        if reason is not None:
            _rebuild_warning(library, reason, 4)  # the caller of compile_functions
        else:
            report = BuildReport(
                mode="compiled",
                cache_hit=True,
                compiled=False,
                codegen_seconds=codegen_seconds,
                compile_seconds=0.0,
                load_seconds=time.perf_counter() - start,
                library=str(library),
                key=key,
                libraries=(str(library),),
            )
            return loaded, report

    record = {"key": key, "functions": expected}
    # the translation units and objects beside the library: an interrupted build leaves
    # nothing behind, and the compiler's files are where the cache is
    try:
        with tempfile.TemporaryDirectory(dir=library.parent,
                                         prefix=f".{library.stem}.units.") as tmpdir:
            paths = [pathlib.Path(tmpdir) / f"{stem}_u{i}.c" for i in range(len(plan))]
            for path, text in zip(paths, sources, strict=True):
                path.write_text(text, encoding="utf-8")
            if len(plan) == 1:
                compile_seconds = _run_compiler([*compiler, *plan[0][2], *SHARED_FLAGS],
                                                paths[0], library, record)
            else:  # objects on every core, then one link
                commands, objects = units.object_commands(compiler, plan, paths)
                compile_seconds = units.compile_objects(
                    commands, [o.with_suffix(".log") for o in objects], COMPILE_TIMEOUT)
                compile_seconds += _run_compiler([*compiler, *SHARED_FLAGS], objects, library,
                                                 record)
    except OSError as exc:  # a full disk (ENOSPC), a quota: as a failed compile ("auto": VM)
        raise CompileError(f"cannot write in the cache directory {library.parent}: "
                           f"{exc.strerror or exc}") from exc
    with contextlib.suppress(OSError):
        cache.write_atomic(kept_source, "\n".join(sources))

    start = time.perf_counter()
    loaded, reason = load_verified(names, library, expected)
    if reason is not None:  # e.g. this process still holds an older copy of that path
        raise CompileError(f"compiled library {library} is not usable: {reason}")
    report = BuildReport(
        mode="compiled",
        cache_hit=False,
        compiled=True,
        codegen_seconds=codegen_seconds,
        compile_seconds=compile_seconds,
        load_seconds=time.perf_counter() - start,
        library=str(library),
        key=key,
        libraries=(str(library),),
    )
    return loaded, report


def compile_functions(
    functions: Sequence[casadi.Function],
    name: str = "casmbd_model",
    *,
    mode: str = "auto",
    flags: Sequence[str] | None = None,
    hot: Collection[str] | None = None,
) -> tuple[dict[str, casadi.Function], BuildReport]:
    """Compile CasADi functions into one cached shared library and load them back.

    Parameters
    ----------
    functions : sequence of casadi.Function
        Functions to compile; their names must be distinct valid C identifiers.
    name : str, optional
        Name of the model, a C identifier; it prefixes the library file and the internal C
        symbols (together with the hash key, so models never collide in one process).
    mode : {"auto", "compiled", "vm"}, optional
        ``"auto"`` compiles and falls back to the original functions with a
        :class:`RuntimeWarning` when no C compiler is found or compilation fails (and always
        when ``$CASMBD_COMPILE`` is ``0``); ``"compiled"`` compiles or raises
        :class:`~casmbd.errors.CompileError`; ``"vm"`` returns the functions unchanged.
    flags : sequence of str, optional
        Optimisation flags; default ``$CASMBD_CFLAGS`` split on spaces, else ``-O2``.
        ``-shared -fPIC`` are always added.
    hot : collection of str, optional
        Names of the functions evaluated often (an integrator's right-hand side): when no
        flags were chosen, only these get the default flags and the others
        :data:`casmbd.compiled.units.COLD_FLAGS` (``-O0``); by default every function gets
        them (by size: ``-O1`` above 1 MB of C alone, ``-O0`` above 3 MB, and
        :data:`casmbd.compiled.units.BULK_FLAGS` in place of the default when the C of all
        functions exceeds 2 MB).  Large builds are compiled as one translation unit per
        function on every core (:mod:`casmbd.compiled.units`).

    Returns
    -------
    functions : dict of str to casadi.Function
        The loaded (or original, in ``"vm"`` mode) functions keyed by their names; compiled
        functions have the same input/output names and sparsity as the originals.
    report : BuildReport
        What was done and how long it took.

    Raises
    ------
    CompileError
        In ``"compiled"`` mode when no compiler is found, code generation, compilation (stderr
        tail in the message) or loading fails, or the compiler times out.
    ValueError
        For an unknown mode, an invalid model name, no functions or duplicate names.
    TypeError
        When an element of ``functions`` is not a :class:`casadi.Function`.
    """
    if mode not in _MODES:
        raise ValueError(f"mode must be one of {', '.join(map(repr, _MODES))}, got {mode!r}")
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise ValueError(f"model name must be a C identifier, got {name!r}")
    functions = list(functions)
    if not functions:
        raise ValueError(f"compile_functions({name!r}) needs at least one function")
    names: list[str] = []
    for index, function in enumerate(functions):
        if not isinstance(function, casadi.Function):
            raise TypeError(
                f"functions[{index}] of {name!r} is {type(function).__name__}, not casadi.Function"
            )
        fname = function.name()
        if not _NAME_RE.match(fname):
            raise ValueError(f"function name {fname!r} of {name!r} is not a C identifier")
        if fname in names:
            raise ValueError(f"duplicate function name {fname!r} in {name!r}")
        names.append(fname)

    if mode == "vm":
        return _vm_result(functions)
    if mode == "auto" and os.environ.get("CASMBD_COMPILE", "").strip() == "0":
        return _vm_result(functions)

    try:
        return _build(functions, names, name, flags, hot)
    except CompileError as exc:
        if mode == "compiled":
            raise
        warnings.warn(
            f"casmbd: compiling {name!r} failed, using the CasADi virtual machine instead: {exc}",
            RuntimeWarning,
            stacklevel=2,
        )
        return _vm_result(functions)


def _nlp_load(library: pathlib.Path, name: str, plugin: str, options: dict,
              expected: dict[str, dict], sizes: list[int]
              ) -> tuple[casadi.Function | None, str | None]:
    """The solver built on ``library`` with its functions' signatures checked against
    ``expected`` and its variable/constraint sizes against ``sizes``, or (None, reason)."""
    try:
        solver = casadi.nlpsol(name, plugin, str(library), options)
    except RuntimeError as exc:
        return None, f"it cannot be loaded: {exc}"
    loaded = cache.signatures(solver.get_function(n) for n in solver.get_function())
    diff = cache.differences(loaded, expected)
    if diff:
        return None, f"it loads other functions: {diff}"
    if [solver.size1_in("x0"), solver.size1_in("lbg")] != sizes:
        return None, (f"it solves {solver.size1_in('x0')} variables and "
                      f"{solver.size1_in('lbg')} constraints, not {sizes[0]} and {sizes[1]}")
    return solver, None


def _nlp_from_cache(library, key, name, plugin, options, sizes):
    """The cached NLP solver after the checks of :func:`cache.check_entry` (before loading)
    and :func:`_nlp_load` (after), or (None, reason)."""
    reason = cache.check_entry(library, key, None)
    if reason is not None:
        return None, reason
    record = cache.read_record(library)
    if record.get("nlp") != sizes:
        return None, f"its record is for an NLP of sizes {record.get('nlp')}, not {sizes}"
    return _nlp_load(library, name, plugin, options, record.get("functions") or {}, sizes)


def compile_nlp_solver(problem: dict, plugin: str, options: dict, name: str = "casmbd_nlp",
                       flags: Sequence[str] | None = None
                       ) -> tuple[casadi.Function, BuildReport]:
    """An NLP solver whose derivative functions are compiled to C and cached on disk.

    The cache key hashes the serialized problem ``{"x", "f", "g"}`` (CasADi's own exact
    serialization of the expression graph), the plugin, the options, compiler, flags, CasADi
    version and platform.  On a hit the solver is built directly on the cached library,
    without differentiating or generating code again — after the library's SHA-256, key and
    problem sizes have been checked against its record, and the loaded functions' signatures
    against those recorded at build time (a failed check: a :class:`RuntimeWarning` and a
    rebuild); on a miss ``solver.generate_dependencies`` writes the C code of ``nlp_f``,
    ``nlp_g``, ``nlp_grad_f``, ``nlp_jac_g`` and ``nlp_hess_l``, which is compiled atomically
    into the cache.  Without a compiler (or with ``$CASMBD_COMPILE=0``), or when compiling
    fails (with a warning), the solver runs in the virtual machine.
    """
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise ValueError(f"NLP name must be a C identifier, got {name!r}")
    compiler = find_compiler()
    flags_ = resolve_flags(flags)
    start = time.perf_counter()
    if compiler is None or os.environ.get("CASMBD_COMPILE", "1") == "0":
        return casadi.nlpsol(name, plugin, problem, options), _vm_report()
    graph = casadi.Function("nlp", [problem["x"]], [problem["f"], problem["g"]])
    # an iteration callback (a progress bar) changes no generated code: not part of the key
    keyed = sorted((k, v) for k, v in options.items() if k != "iteration_callback")
    text = "\x1e".join([graph.serialize(), plugin, repr(keyed)])
    key = _compute_key(text, name, compiler, flags_)
    library = cache_dir() / f"{name}_{key[:16]}.so"
    sizes = [int(problem["x"].numel()), int(problem["g"].numel())]
    codegen = time.perf_counter() - start
    if library.exists():
        t_load = time.perf_counter()
        out, reason = _nlp_from_cache(library, key, name, plugin, options, sizes)
        if reason is None:
            return out, BuildReport(mode="compiled", cache_hit=True, compiled=False,
                                    codegen_seconds=codegen, compile_seconds=0.0,
                                    load_seconds=time.perf_counter() - t_load,
                                    library=str(library), key=key)
        _rebuild_warning(library, reason, 2)
    solver = casadi.nlpsol(name, plugin, problem, options)
    expected = cache.signatures(solver.get_function(n) for n in solver.get_function())
    with tempfile.TemporaryDirectory() as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            solver.generate_dependencies(f"{name}.c")
        finally:
            os.chdir(cwd)
        codegen = time.perf_counter() - start
        try:
            seconds = _run_compiler([*compiler, *flags_, *SHARED_FLAGS],
                                    pathlib.Path(tmp) / f"{name}.c", library,
                                    {"key": key, "functions": expected, "nlp": sizes})
        except CompileError as exc:  # as compile_functions in "auto" mode
            warnings.warn(f"casmbd: compiling the NLP {name!r} failed, using the CasADi "
                          f"virtual machine instead: {exc}", RuntimeWarning, stacklevel=2)
            return solver, _vm_report(codegen, key=key)
    t_load = time.perf_counter()
    out, reason = _nlp_load(library, name, plugin, options, expected, sizes)
    if reason is not None:  # e.g. this process still holds an older copy of that path
        warnings.warn(f"casmbd: the compiled NLP {library} is not usable ({reason}); using "
                      "the CasADi virtual machine instead", RuntimeWarning, stacklevel=2)
        return solver, _vm_report(codegen, seconds, key)
    return out, BuildReport(mode="compiled", cache_hit=False, compiled=True,
                            codegen_seconds=codegen, compile_seconds=seconds,
                            load_seconds=time.perf_counter() - t_load, library=str(library),
                            key=key)
