"""Ctrl-C (SIGINT) that survives CasADi.

When SIGINT arrives while CasADi evaluates a Function inside a solver (a SUNDIALS right-hand
side, an IPOPT callback, a rootfinder), CasADi's interrupt check consumes Python's pending
``KeyboardInterrupt`` and raises a ``RuntimeError`` instead ("... rhs failed:
KeyboardInterrupt"), and IPOPT merely stops with ``User_Requested_Stop``.  Every place that
catches CasADi's ``RuntimeError`` to fall back to something else (a partial re-run, a
minimum-norm solve, the virtual machine) would then swallow the user's Ctrl-C.  Such except
clauses call :func:`reraise_interrupt` first, which turns the error back into
``KeyboardInterrupt`` when the message says so or when :func:`install` 's handler saw SIGINT.

Around a solver call that reports Ctrl-C only by its status (IPOPT: "KeyboardInterruptException"
warning, then ``NonIpopt_Exception_Thrown`` or ``User_Requested_Stop``), :func:`watching` notes
the interrupt (and drops CasADi's warning line, so the CLI's one ``error:`` line stays the only
one) and the caller raises ``KeyboardInterrupt`` after the call with :func:`check`.

This module sits below every layer (it imports nothing from casmbd).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator

#: set by the handler of :func:`install` when SIGINT arrives; cleared by :func:`install`
_SEEN = threading.Event()


def _handler(signum, frame):
    """Python's default SIGINT behaviour (raise ``KeyboardInterrupt``), remembering it."""
    _SEEN.set()
    raise KeyboardInterrupt


def install() -> None:
    """Install the remembering SIGINT handler (the CLI does this; a library user need not).

    Only in the main thread, and only where SIGINT has Python's default handler: a process
    started with SIGINT ignored (``nohup``, a shell's background job) keeps ignoring it.
    """
    _SEEN.clear()
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _handler)


def seen() -> bool:
    """Whether SIGINT arrived since :func:`install`."""
    return _SEEN.is_set()


def is_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` is a Ctrl-C, possibly disguised by CasADi as another exception."""
    return isinstance(exc, KeyboardInterrupt) or _SEEN.is_set() or "KeyboardInterrupt" in str(exc)


def reraise_interrupt(exc: BaseException) -> None:
    """Raise ``KeyboardInterrupt`` from ``exc`` if it is a disguised Ctrl-C; else return.

    Call it first in every ``except RuntimeError`` (or broader) clause around CasADi calls,
    so a fallback never swallows Ctrl-C.
    """
    if isinstance(exc, KeyboardInterrupt):
        raise exc
    if is_interrupt(exc):
        raise KeyboardInterrupt(str(exc)) from exc


def check() -> None:
    """Raise ``KeyboardInterrupt`` if SIGINT arrived (for loops between CasADi calls whose
    own errors might have consumed it)."""
    if _SEEN.is_set():
        raise KeyboardInterrupt


class _WarningFilter:
    """``sys.stderr`` stand-in that drops CasADi's "KeyboardInterruptException" warning
    (written in pieces, so whole lines are buffered) and notes the interrupt."""

    def __init__(self, stream):
        self._stream, self._line = stream, ""

    def write(self, text: str) -> int:
        self._line += text
        while "\n" in self._line:
            line, self._line = self._line.split("\n", 1)
            self._emit(line + "\n")
        return len(text)

    def _emit(self, line: str) -> None:
        if "KeyboardInterruptException" in line:
            _SEEN.set()
        else:
            self._stream.write(line)

    def flush(self) -> None:
        if self._line:
            self._emit(self._line)
            self._line = ""
        self._stream.flush()

    def __getattr__(self, name):
        return getattr(self._stream, name)


@contextlib.contextmanager
def watching() -> Iterator[None]:
    """Note Ctrl-C during the block even where CasADi swallows it; call :func:`check` inside.

    Installs the remembering handler for the block when SIGINT has Python's default one (a
    library user's process; restored and the note cleared afterwards), and filters CasADi's
    interrupt warning out of ``sys.stderr``.
    """
    own = (threading.current_thread() is threading.main_thread()
           and signal.getsignal(signal.SIGINT) is signal.default_int_handler)
    if own:
        _SEEN.clear()
        signal.signal(signal.SIGINT, _handler)
    saved = sys.stderr
    if saved is not None:
        sys.stderr = _WarningFilter(saved)
    try:
        yield
    finally:
        if saved is not None:
            with contextlib.suppress(OSError, ValueError):
                sys.stderr.flush()
            sys.stderr = saved
        if own:
            signal.signal(signal.SIGINT, signal.default_int_handler)
            _SEEN.clear()


@contextlib.contextmanager
def sigint_blocked() -> Iterator[None]:
    """Hold SIGINT back (delivered at the end of the block) while worker processes start.

    A process started inside the block inherits the blocked signal, so Ctrl-C at a terminal
    (sent to the whole process group) reaches only the parent, which stops the workers
    itself, instead of printing a ``KeyboardInterrupt`` traceback from each worker.
    """
    if not hasattr(signal, "pthread_sigmask"):  # Windows
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def ignore_sigint() -> None:
    """Worker-process initializer: Ctrl-C is the parent's to handle (see
    :func:`stop_process_pool`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def stop_process_pool(pool) -> None:
    """End a ``concurrent.futures.ProcessPoolExecutor`` now: cancel the points not started
    and terminate the workers (a running CasADi call cannot be interrupted otherwise)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        with contextlib.suppress(OSError, ValueError):
            proc.terminate()
    for proc in processes:
        with contextlib.suppress(OSError, ValueError):
            proc.join(2.0)
