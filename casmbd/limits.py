"""The stated limits on the size of inputs, in one place (issue 18, item 3).

Absurd sizes used to end in an internal error, or worse, in a process that fills the memory
until the kernel kills it (``--steps 1000000`` on a 200-body scene wanted more than 24 GB).
Every analysis and reader checks its inputs against these limits *before* it builds equations,
compiles code or allocates results, and refuses with :class:`~casmbd.errors.LimitError`
naming the quantity, its value, the limit and what to do instead (a TOML file nested too
deeply is a :class:`~casmbd.errors.SceneError`).  The limits are generous: a scene of a
thousand bodies and ten thousand output times runs; what they refuse could not have finished.

The memory a run will need is the number of output times times the peak bytes per output time
(:func:`memory_per_time`: the result's arrays, the transient copy of the kinematic outputs,
and on the command line the Python objects of ``to_json`` and the JSON text; the counts from
the mechanism's elements, :func:`result_counts`), compared with :func:`memory_budget`:
``$CASMBD_MEMORY_BUDGET`` (bytes, or with a suffix ``K``, ``M``, ``G``, ``T``: ``"16G"``) or
half the physical memory.

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
    "MAX_MEASUREMENT_BYTES",
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
    "memory_per_time",
    "output_values",
    "read_bounded",
    "result_counts",
]

#: Largest scene file (or TOML text) read, in bytes; a 5000-body chain takes 0.6 MB.
MAX_SCENE_BYTES = 64 * 2**20
#: Largest measurement file (a CSV of sampled joint data for ``casmbd identify``) read, in
#: bytes: 10⁶ samples of a 6-axis arm's q and τ at 17 digits a value take ~ 0.25 GB.
MAX_MEASUREMENT_BYTES = 256 * 2**20
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
#: Most rows of one generic velocity constraint (:mod:`casmbd.model.velocity_constraint`;
#: each row is parsed and probed for linearity in the velocities when it is added).
MAX_VELOCITY_ROWS = 1_000
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


#: Bytes of one float of a result array.
FLOAT_BYTES = 8
#: Bytes a value of ``Result.to_json`` takes in Python: a float object (24) and its slot in a
#: list (8).
JSON_FLOAT_BYTES = 32
#: Bytes of a row list of ``to_json`` (``[x, y]`` of a position, a reaction's components):
#: the list object with its GC header (56) and its slot in the outer list (8).
JSON_ROW_BYTES = 64
#: Characters of one value in the JSON text: ``repr`` of a float64 (up to 17 significant
#: digits, sign, point, exponent) and ``", "``; measured 22.6 on a 50-body chain.
JSON_TEXT_BYTES = 23
#: Copies of the JSON text at the peak of ``--json``: the C encoder's accumulated pieces and
#: the joined string (then the string and its UTF-8 bytes while it is written).
JSON_TEXT_COPIES = 2
#: Copies of the mapped kinematic outputs at the peak: the CasADi result (a DM) and its
#: numpy conversion, alive together in :meth:`casmbd.compiled.model.NumericModel.outputs`.
OUTPUT_COPIES = 2


def result_counts(mechanism) -> dict[str, int]:
    """Values per output time of a time-domain run, from the element counts only.

    No equations are built.  Returns

    * ``outputs``: the mapped kinematic outputs (``NumericModel.outputs``): position,
      velocity and acceleration of every body's centre of mass and orientation (plane: 3 × 3;
      space: 3 × 3 + rotation matrix 9 + ω 3 + α 3 = 24), of every marker (6; space 18 with
      its rotation matrix), of every joint's coordinate (3) and the position, deflection and
      rotation of every named node of a flexible body (5; space 9);
    * ``values``: every float the :class:`~casmbd.results.Result` stores: the outputs, q, v,
      a (absolute coordinates, the most generous description: 3 per body in the plane, 7 in
      space, plus the modal coordinates of flexible bodies), λ (one per joint equation and
      driver, and one Euler-parameter normalisation per spatial body), the joint reactions
      (3 or 6), driver efforts, actuator inputs, two values per contact, and 6 scalars
      (energies, violations, conditioning);
    * ``json_floats`` and ``json_rows``: the values of ``Result.to_json`` (body position,
      orientation, velocity, angular velocity; marker position and orientation; joint
      coordinate, rate, reaction; efforts, energies and t) and its row lists;
    * ``nq``, ``nc``: the coordinates and equations assumed.
    """
    d = int(getattr(mechanism, "dimension", 2))
    n = {name: len(getattr(mechanism, name, ()) or ())
         for name in ("bodies", "markers", "joints", "drivers", "actuators", "contacts")}
    joints = (getattr(mechanism, "joints", None) or {})
    equations = sum(len(getattr(j, "labels", ()) or ()) for j in
                    (joints.values() if isinstance(joints, dict) else joints))
    bodies = getattr(mechanism, "bodies", None) or {}
    flexible = [b for b in (bodies.values() if isinstance(bodies, dict) else bodies)
                if getattr(b, "modal", None) is not None]
    modes = sum(len(np.ravel(getattr(b.modal, "frequencies", ()))) for b in flexible)
    nodes = sum(len(getattr(b, "nodes", None) or ()) for b in flexible)
    nq = n["bodies"] * (3 if d == 2 else 7) + modes
    nc = equations + n["drivers"] + (n["bodies"] if d == 3 else 0)
    node_values = nodes * (5 if d == 2 else 9)  # position, deflection (d), rotation (1 | 3)
    outputs = (n["bodies"] * (9 if d == 2 else 24) + n["markers"] * (6 if d == 2 else 18)
               + 3 * n["joints"] + node_values)
    reaction = 3 if d == 2 else 6
    values = (outputs + 3 * nq + nc + reaction * n["joints"] + n["drivers"] + n["actuators"]
              + 2 * n["contacts"] + 6)
    # to_json: body position (d), angle 1 | quaternion 4, velocity (d), angular velocity 1 | 3
    json_floats = (n["bodies"] * (6 if d == 2 else 13) + n["markers"] * (2 if d == 2 else 7)
                   + n["joints"] * (2 + reaction) + n["drivers"] + n["actuators"]
                   + n["contacts"] + 4 + modes + node_values)
    json_rows = (n["bodies"] * (2 if d == 2 else 4) + n["markers"] * (1 if d == 2 else 2)
                 + n["joints"] + len(flexible) + nodes * (2 if d == 2 else 3))
    return {"outputs": outputs, "values": values, "json_floats": json_floats,
            "json_rows": json_rows, "nq": nq, "nc": nc}


def memory_per_time(counts: dict[str, int], output: str = "result") -> int:
    """Peak bytes a run holds per output time: the one estimate of the memory guard.

    .. math::

        b = 8 n_v + 2 \\cdot 8 n_o
            \\;[+\\; 32 n_j + 64 n_r]_{\\text{cli}}
            \\;[+\\; 2 \\cdot 23 n_j]_{\\text{json}}

    with ``counts`` from :func:`result_counts`: n_v the result's values (8 bytes each), n_o the
    mapped kinematic outputs held twice while converted (:data:`OUTPUT_COPIES`), n_j and n_r
    the values and row lists of ``Result.to_json`` as Python objects
    (:data:`JSON_FLOAT_BYTES`, :data:`JSON_ROW_BYTES`; the command line builds them for its
    summary too) and, with ``--json``, the JSON text (:data:`JSON_TEXT_BYTES` per value,
    :data:`JSON_TEXT_COPIES` copies).  Measured against peak RSS in
    ``benchmarks/memory_guard.py`` (docs/cli.md, "Memory of a run").

    Parameters
    ----------
    counts : dict
        :func:`result_counts` of the mechanism.
    output : {"result", "cli", "json"}
        What the run builds: a :class:`~casmbd.results.Result` (the Python API, ``--out``),
        plus ``to_json`` (the command line), plus the JSON text (``--json``).
    """
    if output not in ("result", "cli", "json"):
        raise ValueError(f"output must be 'result', 'cli' or 'json', got {output!r}")
    need = FLOAT_BYTES * (max(int(counts["values"]), 1) + OUTPUT_COPIES * counts["outputs"])
    if output in ("cli", "json"):
        need += JSON_FLOAT_BYTES * counts["json_floats"] + JSON_ROW_BYTES * counts["json_rows"]
    if output == "json":
        need += JSON_TEXT_COPIES * JSON_TEXT_BYTES * counts["json_floats"]
    return int(need)


def check_memory(what: str, times: int, per_time: int, hint: str = "") -> int:
    """Refuse a run of ``times`` output times of ``per_time`` bytes each beyond the budget.

    ``per_time`` comes from :func:`memory_per_time`.  Returns the estimated bytes.  The
    message names the analysis, the number of output times, the estimate, the budget and its
    source, the most steps that fit (``times - 1`` output intervals: that many steps are
    accepted by the same comparison, one more is refused), and ``hint``.
    """
    per_time = max(int(per_time), 1)
    need = int(times) * per_time
    budget, source = memory_budget()
    if need > budget:
        fit = budget // per_time - 1  # steps: fit + 1 output times × per_time <= budget
        raise LimitError(
            f"{what}: {times:,} output times × {format_bytes(per_time)} per output time = "
            f"{format_bytes(need)} exceeds the memory budget of {format_bytes(budget)} "
            f"({source}): use at most {max(fit, 0):,} steps{', ' + hint if hint else ''}"
            f", or raise ${MEMORY_ENV} (e.g. {MEMORY_ENV}=64G)")
    return need


def output_values(mechanism) -> int:
    """Values a time-domain result stores per output time (``result_counts(…)["values"]``)."""
    return result_counts(mechanism)["values"]


def check_steps(what: str, steps: int, mechanism, hint: str = "", output: str = "result",
                extra_values: int = 0) -> int:
    """:func:`check_count` of ``steps`` against :data:`MAX_STEPS`, then :func:`check_memory`
    of the ``steps + 1`` output times at :func:`memory_per_time` of the mechanism's
    :func:`result_counts` (plus ``extra_values`` floats per time); returns the estimated
    bytes.  Every analysis and the command line call this one function, so that the refusal
    and its advice come from one estimate."""
    check_count(f"{what}: steps", int(steps), MAX_STEPS, "use fewer steps")
    counts = dict(result_counts(mechanism))
    counts["values"] += int(extra_values)
    return check_memory(what, int(steps) + 1, memory_per_time(counts, output), hint)


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
