"""The stated limits on the size of inputs, in one place (issue 18, item 3).

Absurd sizes used to end in an internal error, or worse, in a process that fills the memory
until the kernel kills it (``--steps 1000000`` on a 200-body scene wanted more than 24 GB).
Every analysis and reader checks its inputs against these limits *before* it builds equations,
compiles code or allocates results, and refuses with :class:`~casmbd.errors.LimitError`
naming the quantity, its value, the limit and what to do instead (a TOML file nested too
deeply is a :class:`~casmbd.errors.SceneError`).  The limits are generous: a scene of a
thousand bodies and ten thousand output times runs; what they refuse could not have finished.

The memory a result will need is estimated from the number of output times times the values
stored per time (:func:`output_values`, a lower bound from the mechanism's element counts)
times 8 bytes, and compared with :func:`memory_budget`: ``$CASMBD_MEMORY_BUDGET`` (bytes,
or with a suffix ``K``, ``M``, ``G``, ``T``: ``"16G"``) or half the physical memory.

Files (issue 31): every file casmbd reads goes through :func:`check_regular_file` (``os.stat``
before any open: a FIFO or a device such as ``/dev/zero`` is refused, never opened) and, for
text, :func:`read_bounded` (at most the limit plus one byte is read); the arrays of an ``.npz``
file are checked from their ``.npy`` headers by :func:`check_npz` before any is allocated.

This module sits below everything else (of casmbd it imports only :mod:`casmbd.errors`).
"""

from __future__ import annotations

import os
import re
import stat
import zipfile
from collections.abc import Iterable
from math import prod

import numpy as np
from numpy.lib import format as npy_format

from casmbd.errors import CasmbdError, LimitError

__all__ = [
    "MAX_BEAM_ELEMENTS",
    "MAX_BODIES",
    "MAX_DPI",
    "MAX_ELEMENTS",
    "MAX_EXPRESSION_DEPTH",
    "MAX_EXPRESSION_LENGTH",
    "MAX_FE_DOFS",
    "MAX_FE_NODES",
    "MAX_FIGURE_INCHES",
    "MAX_FIXED_STEPS",
    "MAX_FPS",
    "MAX_FRAMES",
    "MAX_MESH_BYTES",
    "MAX_MESH_FACES",
    "MAX_MODES",
    "MAX_NPZ_BYTES",
    "MAX_OCP_INTERVALS",
    "MAX_OCP_UNKNOWNS",
    "MAX_PIXELS",
    "MAX_RECORD_BYTES",
    "MAX_SCENE_BYTES",
    "MAX_STEPS",
    "MAX_SWEEP_POINTS",
    "MAX_TOML_DEPTH",
    "MEMORY_ENV",
    "check_count",
    "check_memory",
    "check_npz",
    "check_regular_file",
    "check_steps",
    "format_bytes",
    "memory_budget",
    "output_values",
    "read_bounded",
]

#: Largest scene file (or TOML text) read, in bytes; a 5000-body chain takes 0.6 MB.
MAX_SCENE_BYTES = 64 * 2**20
#: Largest mesh file (STL, OBJ, DAE of a URDF ``<visual>``) read by the 3-D view, in bytes; a
#: robot's visual meshes take 0.1-5 MB each.
MAX_MESH_BYTES = 64 * 2**20
#: Most triangles of one mesh drawn by the 3-D view (a finer mesh is refused with its name).
MAX_MESH_FACES = 2_000_000
#: Largest cache record (``*.model.json`` and the like) read, in bytes; records take a few KB.
MAX_RECORD_BYTES = 16 * 2**20
#: Largest total size of the arrays of an ``.npz`` file (a result, a sweep, an OCP solution,
#: an FE model) that is read, in bytes: the sizes the members' ``.npy`` headers declare,
#: checked before any array is allocated (only the members used count).
MAX_NPZ_BYTES = 4 * 2**30
#: Most nodes of an imported FE model.
MAX_FE_NODES = 1_000_000
#: Most degrees of freedom of an imported FE model (nodes × DOFs per node); a modal reduction
#: of more would not finish.
MAX_FE_DOFS = 1_000_000
#: Most elements of a built-in beam (``elements``): 10,000 take 1 s to build, 100,000 take 10 s
#: (before the modal reduction); ten million wanted more than 3.4 GB.
MAX_BEAM_ELEMENTS = 100_000
#: Most modes (normal or static) of a flexible body's reduction.
MAX_MODES = 1_000
#: Deepest nesting of arrays and inline tables in a TOML scene (scenes need 3; Python's TOML
#: reader recurses once per level and fails near 500).
MAX_TOML_DEPTH = 32
#: Most bodies of one mechanism (``info`` on 5000 bodies takes seconds).
MAX_BODIES = 20_000
#: Most joints, markers, drivers, forces, actuators or parameters of one mechanism, each.
MAX_ELEMENTS = 100_000
#: Longest expression string, in characters (:mod:`casmbd.model.expressions`).
MAX_EXPRESSION_LENGTH = 10_000
#: Deepest nesting of an expression (:mod:`casmbd.model.expressions`).
MAX_EXPRESSION_DEPTH = 100
#: Most output intervals (``steps``) of a time-domain analysis, whatever the memory (also the
#: largest integer the command line accepts for ``--steps``, ``--max-steps``, ``--intervals``).
MAX_STEPS = 10_000_000
#: Most steps of a fixed-step simulation (``--step``), all output intervals together: a
#: billion RK4 steps take tens of minutes even compiled (``--step 1e-300`` used to run forever).
MAX_FIXED_STEPS = 1_000_000_000
#: Highest frame rate of an animation (a GIF stores frame durations in 10 ms units, so
#: anything faster is written as a duration of 0).
MAX_FPS = 1_000.0
#: Most intervals of an optimal-control transcription.
MAX_OCP_INTERVALS = 100_000
#: Most collocation unknowns of an optimal-control problem: intervals × (degree + 1) ×
#: (states + inputs); IPOPT's memory grows faster than this count.
MAX_OCP_UNKNOWNS = 10_000_000
#: Most points of a parameter sweep (the product of the values of all parameters).
MAX_SWEEP_POINTS = 1_000_000
#: Most frames of an animation.
MAX_FRAMES = 100_000
#: Highest resolution of a figure or animation, in dots per inch.
MAX_DPI = 2_400
#: Largest width or height of a figure, in inches.
MAX_FIGURE_INCHES = 200.0
#: Most pixels of one figure or animation frame (width × height × dpi²).
MAX_PIXELS = 100_000_000
#: Environment variable overriding :func:`memory_budget` (bytes or ``"16G"``).
MEMORY_ENV = "CASMBD_MEMORY_BUDGET"
#: Budget when the physical memory is unknown.
FALLBACK_MEMORY_BUDGET = 4 * 2**30
#: Fraction of the physical memory a result may take by default.
MEMORY_FRACTION = 0.5

_SUFFIX = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def format_bytes(count: float) -> str:
    """``count`` bytes as a short human-readable figure (``"43.2 GB"``; powers of 1024)."""
    for unit in ("B", "KB", "MB", "GB", "TB"):
        if abs(count) < 1024 or unit == "TB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1024
    return f"{count:.1f} PB"  # pragma: no cover  (the loop returns at TB)


def memory_budget() -> tuple[int, str]:
    """Bytes a result may take, and where that figure comes from.

    ``$CASMBD_MEMORY_BUDGET`` (a number of bytes, optionally with a suffix K, M, G or T —
    powers of 1024) wins; otherwise half the physical memory (``os.sysconf``), or 4 GiB when
    the system does not tell.

    Raises
    ------
    LimitError
        When the environment variable is not a positive size.
    """
    text = os.environ.get(MEMORY_ENV, "").strip()
    if text:
        match = re.fullmatch(r"(\d+(?:\.\d*)?)\s*([KMGT]?)i?B?", text.upper())
        value = float(match.group(1)) * _SUFFIX[match.group(2)] if match else 0.0
        if not value >= 1:
            raise LimitError(f"${MEMORY_ENV} = {text!r}: expected a positive size in bytes, "
                             "optionally with a suffix K, M, G or T (e.g. 16G)")
        return int(value), f"${MEMORY_ENV}"
    try:
        physical = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, OSError, ValueError):
        physical = -1
    if physical <= 0:
        return FALLBACK_MEMORY_BUDGET, "the default budget (physical memory unknown)"
    return int(MEMORY_FRACTION * physical), "half the physical memory"


def check_count(what: str, value: int, limit: int | float, hint: str = "") -> None:
    """Raise :class:`LimitError` when ``value`` exceeds ``limit``.

    Parameters
    ----------
    what : str
        The quantity and its culprit, e.g. ``"sweep grid (k × c)"``.
    value, limit : int
        The asked-for size and the largest one allowed.
    hint : str
        What to do instead (appended after a colon).
    """
    if value > limit:
        raise LimitError(f"{what}: {_number(value)} exceeds the limit of {_number(limit)} "
                         f"(casmbd.limits){': ' + hint if hint else ''}")


def _number(value: float) -> str:
    """``1,000,000`` for whole numbers, ``2.5e+06`` style otherwise."""
    return f"{int(value):,}" if float(value).is_integer() else f"{value:,g}"


def check_memory(what: str, times: int, values_per_time: int, hint: str = "") -> int:
    """Refuse a result of ``times`` × ``values_per_time`` floats larger than the budget.

    Returns the estimated number of bytes.  The message names the analysis, the number of
    output times, the estimate, the budget and its source, the most output times that fit,
    and ``hint``.
    """
    need = 8 * int(times) * max(int(values_per_time), 1)
    budget, source = memory_budget()
    if need > budget:
        fit = budget // (8 * max(int(values_per_time), 1))
        raise LimitError(
            f"{what}: {times:,} output times × {values_per_time:,} values × 8 bytes = "
            f"{format_bytes(need)} exceeds the memory budget of {format_bytes(budget)} "
            f"({source}): use at most {max(fit - 1, 0):,} steps{', ' + hint if hint else ''}"
            f", or raise ${MEMORY_ENV} (e.g. {MEMORY_ENV}=64G)")
    return need


def output_values(mechanism) -> int:
    """A lower bound of the values a time-domain result stores per output time.

    From the element counts only (no equations are built): centre-of-mass position, velocity
    and acceleration and the angles (plane) or rotation matrix, angular velocity and angular
    acceleration (space) of every body, marker positions, velocities and accelerations, the
    reaction of every joint, one effort per driver and actuator, and the coordinates q, v, a of
    the least generous description (joint coordinates: one per body).  Results also hold the
    multipliers and the absolute or natural coordinates, so the true figure is larger.
    """
    d = int(getattr(mechanism, "dimension", 2))
    per_body = 9 if d == 2 else 24
    per_marker, per_joint = 3 * d, 3 if d == 2 else 6
    count = lambda name: len(getattr(mechanism, name, ()) or ())  # noqa: E731
    return (count("bodies") * (per_body + 3) + count("markers") * per_marker
            + count("joints") * per_joint + count("drivers") + count("actuators") + 6)


def check_steps(what: str, steps: int, values_per_time: int, hint: str = "") -> int:
    """:func:`check_count` of ``steps`` against :data:`MAX_STEPS`, then :func:`check_memory`
    of the ``steps + 1`` output times; returns the estimated bytes."""
    check_count(f"{what}: steps", int(steps), MAX_STEPS, "use fewer steps")
    return check_memory(what, int(steps) + 1, values_per_time, hint)


def check_regular_file(path: str | os.PathLike, what: str, limit: int,
                       error: type[CasmbdError] = LimitError) -> int:
    """Size of ``path`` after checking that it is a regular file of at most ``limit`` bytes.

    Only ``os.stat`` runs: a FIFO, a device (``/dev/zero``), a socket or a directory is never
    opened (opening a FIFO blocks, reading ``/dev/zero`` never ends).

    Raises
    ------
    error
        The file is missing or not a regular file (naming ``what`` file and the path).
    LimitError
        The file is larger than ``limit`` (naming the file, its size and the limit).
    """
    where = f"{what} file '{os.fspath(path)}'"
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{where} not found") from None
    except (OSError, ValueError) as exc:
        raise error(f"{where} cannot be read: {exc}") from None
    if not stat.S_ISREG(st.st_mode):
        kind = ("a directory" if stat.S_ISDIR(st.st_mode) else
                "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else
                "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else
                "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise error(f"{where} is {kind}: casmbd reads regular files only")
    if st.st_size > limit:
        raise LimitError(f"{where}: {format_bytes(st.st_size)} exceeds the limit of "
                         f"{format_bytes(limit)} (casmbd.limits)")
    return int(st.st_size)


def read_bounded(path: str | os.PathLike, what: str, limit: int,
                 error: type[CasmbdError] = LimitError) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them.

    :func:`check_regular_file` first (no open of a FIFO or device); then at most
    ``limit + 1`` bytes are read, so a file that grows after the check is still refused.
    Errors as :func:`check_regular_file`; an unreadable file raises ``error``.
    """
    check_regular_file(path, what, limit, error)
    where = f"{what} file '{os.fspath(path)}'"
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
                     | getattr(os, "O_NOCTTY", 0))
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):  # replaced since the stat
                raise error(f"{where} is not a regular file: casmbd reads regular files only")
            data = fh.read(limit + 1)
    except FileNotFoundError:
        raise error(f"{where} not found") from None
    except OSError as exc:
        raise error(f"{where} cannot be read: {exc}") from None
    if len(data) > limit:
        raise LimitError(f"{where}: more than {format_bytes(limit)} (the limit, "
                         "casmbd.limits)")
    return data


def check_npz(zf: zipfile.ZipFile, where: str, keys: Iterable[str] | None = None,
              limit: int | None = None,
              error: type[CasmbdError] = LimitError) -> dict[str, tuple[tuple[int, ...], str]]:
    """Check the ``.npy`` headers of an npz archive's members before any array is read.

    For each member ``key + ".npy"`` (all members when ``keys`` is None; missing keys are
    skipped), the header is parsed (``numpy.lib.format.read_magic`` and
    ``read_array_header_1_0/2_0``, a few hundred bytes); the declared size
    ``prod(shape) × itemsize`` must not exceed the member's uncompressed size (a header that
    declares more data than the member holds is a forged or truncated file) and the declared
    sizes together must not exceed ``limit`` (default: the smaller of :data:`MAX_NPZ_BYTES`
    and :func:`memory_budget`).  Object arrays
    are refused (unpickling them could run code).

    Returns
    -------
    dict
        ``{key: (shape, dtype string)}`` of the members checked.

    Raises
    ------
    error
        A member whose header is unreadable, declares more than it holds, or is an object
        array (naming the member).
    LimitError
        The declared sizes exceed ``limit`` (naming the member that crosses it and the limit).
    """
    if limit is None:
        budget, source = memory_budget()
        limit = min(MAX_NPZ_BYTES, budget)
        source = ("casmbd.limits.MAX_NPZ_BYTES" if limit == MAX_NPZ_BYTES
                  else f"the memory budget, {source}")
    else:
        limit, source = int(limit), "casmbd.limits.MAX_NPZ_BYTES"
    infos = {info.filename: info for info in zf.infolist()}
    names = (list(infos) if keys is None
             else [k + ".npy" for k in keys if k + ".npy" in infos])
    total, out = 0, {}
    for name in names:
        info = infos[name]
        key = name[:-4] if name.endswith(".npy") else name
        try:
            with zf.open(info) as fh:
                version = npy_format.read_magic(fh)
                if version == (1, 0):
                    shape, _, dtype = npy_format.read_array_header_1_0(fh)
                elif version == (2, 0):
                    shape, _, dtype = npy_format.read_array_header_2_0(fh)
                else:
                    shape, _, dtype = npy_format._read_array_header(fh, version)
                header = fh.tell()
        except (ValueError, OSError, EOFError, KeyError, TypeError, SyntaxError,
                zipfile.BadZipFile, NotImplementedError) as exc:
            raise error(f"{where}: member {key!r} has no readable .npy header "
                        f"({exc or type(exc).__name__})") from None
        dtype = np.dtype(dtype)
        if dtype.hasobject:
            raise error(f"{where}: member {key!r} holds Python objects (object arrays are "
                        "refused: they could run code when read)")
        nbytes = prod(int(s) for s in shape) * dtype.itemsize
        if nbytes > max(info.file_size - header, 0):
            raise error(f"{where}: member {key!r} declares shape {tuple(shape)} of {dtype} "
                        f"({format_bytes(nbytes)}) but holds {format_bytes(info.file_size)}"
                        " (forged or truncated)")
        total += nbytes
        if total > limit:
            raise LimitError(f"{where}: member {key!r} (shape {tuple(shape)}, {dtype}) brings "
                             f"the arrays to {format_bytes(total)}, over the limit of "
                             f"{format_bytes(limit)} ({source})")
        out[key] = (tuple(int(s) for s in shape), dtype.str)
    return out
