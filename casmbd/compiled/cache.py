"""The on-disk cache of compiled libraries: where it is, and how an entry is trusted.

Every library ``<stem>.so`` of the cache has a record ``<stem>.so.json`` beside it::

    {"format": 1, "key": "<build key>", "sha256": "<hex digest of the .so bytes>",
     "size": <bytes>, "functions": {"<name>": {"in": [[rows, cols, nnz, hash], ...],
                                               "out": [...], "name_in": [...], ...}}}

A library is used only when its record exists, names the same build key, gives the size and
SHA-256 of the bytes on disk and lists the signatures (names, numbers of inputs and outputs,
sparsity of each) of the functions being built.  All of this is checked *before* the library
is opened with ``dlopen``: a truncated library would otherwise crash the process (SIGBUS) and a
library of another model would give wrong numbers without a word.  Both files are written to
temporary names and renamed (:func:`os.replace`), the record first, under an exclusive lock of
the cache directory, so a concurrent reader sees a complete pair or no library at all.

The cache directory must be a writable directory; when it is not (read-only, a file, not
creatable) a private temporary directory (:func:`tempfile.mkdtemp`, once per process and
configured path) is used instead with one :class:`RuntimeWarning` naming the path and the
reason — compiling still works, so ``mode="compiled"`` does not fail for it.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import json
import os
import pathlib
import shutil
import stat
import tempfile
import warnings
from collections.abc import Iterable, Iterator

import casadi

from casmbd import limits
from casmbd.atomic import atomic_write
from casmbd.errors import CasmbdError

try:  # POSIX only; without it writers are not serialised (the checks still hold)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

__all__ = ["cache_dir", "check_entry", "entry_lock", "file_sha256", "read_record_text",
           "record_path", "signature", "signatures", "write_atomic", "write_record"]

#: Version of the record format; a record of another version is not trusted.
RECORD_FORMAT = 1
RECORD_SUFFIX = ".json"

# configured path -> private temporary cache used instead (one per process and path)
_FALLBACK: dict[str, pathlib.Path] = {}


def configured_cache_dir() -> pathlib.Path:
    """``$CASMBD_CACHE_DIR``, else ``$XDG_CACHE_HOME/casmbd``, else ``~/.cache/casmbd``."""
    env = os.environ.get("CASMBD_CACHE_DIR")
    if env:
        return pathlib.Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = pathlib.Path(xdg).expanduser() if xdg else pathlib.Path.home() / ".cache"
    return base / "casmbd"


def _unusable(path: pathlib.Path) -> str | None:
    """Why ``path`` cannot hold the cache (None when it can): it is created if missing and a
    file is created and removed in it, which also catches read-only mounts for root."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        return "it exists and is not a directory"
    except OSError as exc:
        return f"it cannot be created ({exc.strerror or exc})"
    if not path.is_dir():
        return "it is not a directory"
    try:
        fd, probe = tempfile.mkstemp(dir=path, prefix=".casmbd-probe-")
    except OSError as exc:
        return f"it is not writable ({exc.strerror or exc})"
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)
    return None


def cache_dir() -> pathlib.Path:
    """Return the directory of compiled libraries, creating it if needed.

    Returns
    -------
    pathlib.Path
        ``$CASMBD_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/casmbd``, else
        ``~/.cache/casmbd``; when that path is not a writable directory, a private temporary
        directory of this process (with one :class:`RuntimeWarning` naming path and reason).
    """
    path = configured_cache_dir()
    reason = _unusable(path)
    if reason is None:
        return path
    fallback = _FALLBACK.get(str(path))
    if fallback is None or not fallback.is_dir():
        fallback = pathlib.Path(tempfile.mkdtemp(prefix="casmbd-cache-"))
        atexit.register(shutil.rmtree, fallback, ignore_errors=True)
        _FALLBACK[str(path)] = fallback
        warnings.warn(f"casmbd: the cache directory {path} cannot be used ({reason}); "
                      f"compiled code is kept in the private temporary directory {fallback} "
                      "for this process (set CASMBD_CACHE_DIR to a writable directory)",
                      RuntimeWarning, stacklevel=3)
    return fallback


def read_record_text(path: str | os.PathLike) -> str:
    """The text of a cache record (JSON), read as a bounded regular file.

    :func:`casmbd.limits.read_bounded` with :data:`casmbd.limits.MAX_RECORD_BYTES`: a record
    that is a FIFO, a device or a directory is never opened, one larger than the limit is not
    read.  Such damage is reported as ``OSError`` (``FileNotFoundError`` when missing), the
    way callers already treat an unreadable record: the entry is rebuilt.
    """
    try:
        data = limits.read_bounded(path, "cache record", limits.MAX_RECORD_BYTES)
    except CasmbdError as exc:
        if not os.path.lexists(path):
            raise FileNotFoundError(2, "No such file or directory", str(path)) from None
        raise OSError(str(exc)) from None
    return data.decode("utf-8")


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes (about 1 ms per MB)."""
    with open(path, "rb") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def _sparsity(sp: casadi.Sparsity) -> list[int]:
    return [sp.size1(), sp.size2(), sp.nnz(), int(sp.hash())]


def signature(function: casadi.Function) -> dict:
    """Names, input/output names and sparsity patterns of a Function (JSON-ready)."""
    return {"name": function.name(),
            "name_in": list(function.name_in()), "name_out": list(function.name_out()),
            "in": [_sparsity(function.sparsity_in(i)) for i in range(function.n_in())],
            "out": [_sparsity(function.sparsity_out(i)) for i in range(function.n_out())]}


def signatures(functions: Iterable[casadi.Function]) -> dict[str, dict]:
    """:func:`signature` of each function, by name."""
    return {f.name(): signature(f) for f in functions}


def differences(actual: dict[str, dict], expected: dict[str, dict]) -> str | None:
    """A description of how two signature tables differ, or None when they agree."""
    if set(actual) != set(expected):
        return (f"functions {sorted(actual)} instead of {sorted(expected)}")
    for name in sorted(expected):
        if actual[name] != expected[name]:
            what = [k for k in expected[name] if actual[name].get(k) != expected[name][k]]
            return f"function '{name}' differs in {', '.join(what)}"
    return None


def record_path(library: pathlib.Path) -> pathlib.Path:
    """The record (hash and signatures) kept beside ``library``."""
    return library.with_name(library.name + RECORD_SUFFIX)


def write_atomic(path: pathlib.Path, text: str) -> None:
    """Write ``text`` to ``path`` through :func:`casmbd.atomic.atomic_write` (a temporary file
    renamed into place; the stale temporaries of killed writers in the folder are removed)."""
    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as handle:
            handle.write(text)

    atomic_write(path, write)


def write_record(library: pathlib.Path, built: pathlib.Path, record: dict) -> None:
    """Write the record of ``library`` for the file ``built`` (not yet renamed to it)."""
    data = {"format": RECORD_FORMAT, **record, "sha256": file_sha256(built),
            "size": os.path.getsize(built)}
    write_atomic(record_path(library), json.dumps(data, sort_keys=True))


@contextlib.contextmanager
def entry_lock(directory: pathlib.Path) -> Iterator[None]:
    """Exclusive lock of the cache directory while a library and its record are renamed in,
    so that two writers never leave the record of one beside the library of the other."""
    if fcntl is None:  # pragma: no cover - Windows
        yield
        return
    fd = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def check_entry(library: pathlib.Path, key: str, expected: dict[str, dict] | None
                ) -> str | None:
    """Why the existing ``library`` must not be opened (None when it may be).

    Checks, without opening the library: the record exists and parses, names the build
    ``key``, gives the size and SHA-256 of the bytes on disk and (unless ``expected`` is None)
    the signatures ``expected``.
    """
    rec_path = record_path(library)
    try:
        record = json.loads(read_record_text(rec_path))
    except FileNotFoundError:
        return f"no hash record {rec_path.name} beside it"
    except (OSError, ValueError) as exc:
        return f"its hash record {rec_path.name} cannot be read ({exc})"
    if not isinstance(record, dict) or record.get("format") != RECORD_FORMAT:
        return f"its hash record {rec_path.name} has an unknown format"
    if record.get("key") != key:
        return f"its hash record is for another build (key {str(record.get('key'))[:16]})"
    try:
        if not stat.S_ISREG(os.stat(library).st_mode):  # a FIFO would block file_sha256
            return "it is not a regular file"
        size = os.path.getsize(library)
        if size != record.get("size"):
            return f"it is {size} bytes, its record says {record.get('size')} (truncated?)"
        if file_sha256(library) != record.get("sha256"):
            return "its SHA-256 differs from its record (the file was changed)"
    except OSError as exc:
        return f"it cannot be read ({exc})"
    if expected is not None:
        diff = differences(record.get("functions") or {}, expected)
        if diff:
            return f"its record lists other functions: {diff}"
    return None


def read_record(library: pathlib.Path) -> dict:
    """The record of ``library`` (after :func:`check_entry` accepted it)."""
    return json.loads(read_record_text(record_path(library)))
