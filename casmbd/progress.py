"""Progress bars for long loops (tqdm, optional).

A bar appears only when tqdm is installed, standard error was a terminal when casmbd was
imported, ``$CASMBD_PROGRESS``
is not ``0`` (the CLI sets it in ``--json`` mode) and the loop has run for more than a second
(tqdm's ``delay``), so short runs, pipes, notebooks' captured output and JSON stay clean.
``$CASMBD_PROGRESS=1`` forces bars even without a terminal.
"""

from __future__ import annotations

import atexit
import os

#: the process's standard error as it was when casmbd was imported: solver runs capture
#: sys.stderr and file descriptor 2 (their diagnostics become error messages), so bars drawn
#: during a run write to this duplicate instead
try:
    _IS_TTY = os.isatty(2)
    _TERMINAL = os.fdopen(os.dup(2), "w", buffering=1)
except OSError:  # no file descriptor 2
    _IS_TTY, _TERMINAL = False, None
else:
    atexit.register(_TERMINAL.close)


class _Silent:
    """The do-nothing bar."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def enabled() -> bool:
    """Whether bars are shown (see the module docstring)."""
    flag = os.environ.get("CASMBD_PROGRESS", "").strip()
    if flag == "0":
        return False
    if _TERMINAL is None or (flag != "1" and not _IS_TTY):
        return False
    try:
        import tqdm  # noqa: F401
    except ImportError:
        return False
    return True


def bar(total: int, desc: str, unit: str = "it"):
    """A tqdm bar over ``total`` units on stderr, or a silent stand-in."""
    if not enabled():
        return _Silent()
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=_TERMINAL, delay=1.0,
                leave=False, dynamic_ncols=True)
