"""Atomic file writes and the sweep of the temporary files an interrupted write leaves.

Every file casmbd writes — results (npz, CSV), figures, animations, OCP solutions, and the
records and modal data of the compiled cache — goes through :func:`atomic_write`: a temporary
file in the target's folder, then one :func:`os.replace`, so a reader sees the old file or the
complete new one.  A process killed during the write (SIGKILL, power loss: no ``finally``
runs) cannot remove its temporary file; every write first removes the stale ones of its folder
(:func:`remove_stale_temporaries`).  The helpers sit below every layer so that the compiled
cache (layer 3) and the result files (layer 4) share them.
"""

from __future__ import annotations

import os
import re
import socket
import tempfile
import time
import zlib
from collections.abc import Callable
from pathlib import Path

__all__ = ["OLD_TEMP_PATTERN", "STALE_TEMP_SECONDS", "TEMP_PREFIX", "atomic_write",
           "remove_stale_temporaries"]

#: Prefix of :func:`atomic_write`'s temporary files: ``.tmp_casmbd-HOST-PID-XXXX.suffix``
#: (HOST: 8 hex digits of a hash of the host name, PID: the writing process).
TEMP_PREFIX = ".tmp_casmbd-"
#: A temporary file of :func:`atomic_write` older than this is stale whoever wrote it [s].
STALE_TEMP_SECONDS = 24 * 3600.0
#: The name older versions gave their temporary files (``tempfile.mkstemp(prefix=".tmp_",
#: suffix=<target's suffix>)``: ``.tmp_`` + 8 characters of :mod:`tempfile`'s alphabet + the
#: suffix of a file casmbd writes).  They carry no host or process, so only their age
#: (> :data:`STALE_TEMP_SECONDS`) makes them stale; any other name — a suffix-less
#: ``.tmp_XXXXXXXX`` too, as other programs use it — is not touched.
OLD_TEMP_PATTERN = re.compile(r"\.tmp_[a-z0-9_]{8}\.(npz|csv|png|pdf|svg|gif|mp4)")


def _host_tag() -> str:
    return f"{zlib.crc32(socket.gethostname().encode('utf-8', 'replace')):08x}"


def _process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host (signal 0 checks without sending)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):  # exists, another user's (or cannot tell: keep)
        return True
    return True


def remove_stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporary files that :func:`atomic_write` left in ``folder`` when its process
    was killed during a save (SIGKILL, power loss: no ``finally`` runs); returns them.

    A file ``.tmp_casmbd-HOST-PID-*`` is stale when it was written on this host by a process
    that no longer exists, or (any host, e.g. a shared network folder) when it is older than
    :data:`STALE_TEMP_SECONDS`.  A file named as older versions named theirs
    (:data:`OLD_TEMP_PATTERN`, e.g. ``.tmp_k3x9_a2b.npz``) is stale when older than
    :data:`STALE_TEMP_SECONDS`.  Files of a live process (a save in progress), young files of
    the old pattern and every other name are left alone.  On Windows, where signal 0 cannot
    probe a process, only the age counts.
    """
    removed: list[Path] = []
    host, now = _host_tag(), time.time()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        ours = entry.name.startswith(TEMP_PREFIX)
        if not ours and not OLD_TEMP_PATTERN.fullmatch(entry.name):
            continue
        parts = entry.name[len(TEMP_PREFIX):].split("-", 2)
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            age = now - entry.stat(follow_symlinks=False).st_mtime
            stale = age > STALE_TEMP_SECONDS
            if not stale and ours and os.name != "nt" and len(parts) == 3 \
                    and parts[0] == host and parts[1].isdigit():
                stale = not _process_alive(int(parts[1]))
            if stale:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:  # removed meanwhile, or not ours to remove: not this save's problem
            continue
    return removed


def atomic_write(path: str | os.PathLike, write: Callable[[str], None]) -> Path:
    """Write a file atomically: ``write(tmp)`` fills a temporary file in the target's folder,
    which then replaces ``path`` in one ``os.replace`` (readers see the old file or the
    complete new one, never a partial one; the temporary file is removed on failure, Ctrl-C
    included).

    The temporary name keeps the target's suffix (``.tmp_casmbd-HOST-PID-XXXX.png``) so that
    writers which infer the format from the name (matplotlib, Pillow) behave as for the
    target.  A process killed during the write cannot remove its temporary file: every save
    first removes those of dead processes in its folder (:func:`remove_stale_temporaries`).
    Creates the parent folder when missing.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f"{TEMP_PREFIX}{_host_tag()}-{os.getpid()}-",
                               suffix="".join(path.suffixes[-1:]), dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 -> what open() would have given
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
