"""Progress bars for long loops (tqdm, optional).

A bar appears only when tqdm is installed, standard error was a terminal when casmbd was
imported, ``$CASMBD_PROGRESS``
is not ``0`` (the CLI sets it in ``--json`` mode) and the loop has run for more than a second
(tqdm's ``delay``), so short runs, pipes, notebooks' captured output and JSON stay clean.
``$CASMBD_PROGRESS=1`` forces bars even without a terminal.

A SUNDIALS run is one integrator call over the whole output grid; :func:`integrator_clock`
gives it a bar per output interval without splitting the call (splitting would restart the
method at every piece and change its steps).
"""

from __future__ import annotations

import atexit
import os

import casadi as ca
import numpy as np

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


#: the bar's callback runs only for steps ending in this fraction of an output interval
#: (from its start; the uniform output grid of a simulation)
CLOCK_WINDOW = 0.125


class _OutputClock(ca.Callback):
    """A CasADi function of time t returning 0 that advances a bar by the output times
    ``tout`` at or before t (the integrator has passed them)."""

    def __init__(self, tout):
        ca.Callback.__init__(self)
        self._tout = np.asarray(tout, float)
        self.start(_Silent())
        self.construct("progress_clock", {})

    def start(self, pbar) -> None:
        """Count from zero into ``pbar``."""
        self.pbar, self.done = pbar, 0
        self._next = float(self._tout[0]) if len(self._tout) else np.inf

    def finish(self) -> None:
        """Count the outputs not yet counted (the run ended: it reached them all)."""
        if self.done < len(self._tout):
            self.pbar.update(len(self._tout) - self.done)
            self.done = len(self._tout)

    def get_n_in(self) -> int:
        return 1

    def get_n_out(self) -> int:
        return 1

    def has_eval_buffer(self) -> bool:
        return True  # memoryviews instead of DM objects: 2 µs a call instead of 7

    def eval_buffer(self, arg, res) -> int:
        t = memoryview(arg[0]).cast("d")[0]
        memoryview(res[0]).cast("d")[0] = 0.0
        if t >= self._next:  # one comparison per step until an output time is passed
            reached = int(np.searchsorted(self._tout, t, side="right"))
            self.pbar.update(reached - self.done)
            self.done = reached
            self._next = float(self._tout[reached]) if reached < len(self._tout) else np.inf
        return 0


def integrator_clock(dyn: ca.Function, tout) -> tuple[ca.Function, _OutputClock] | None:
    """The dynamics ``dyn`` of a CasADi integrator with a clock for a progress bar.

    The copy computes one quadrature, identically zero, through a callback that receives the
    time: SUNDIALS evaluates quadratures once per step, at the step's time, so the callback
    sees the integrator pass the output times ``tout`` (call ``clock.start(bar)`` before the
    run and ``clock.finish()`` after).  The callback (Python, about 2 µs a call: as much as a
    whole step of a small model) is called only for the steps that end in the first
    :data:`CLOCK_WINDOW` of an output interval (a test in the evaluated expression,
    ``if_else`` with short circuit): with many steps per interval every interval is still
    counted, by about one step in eight; with few, the bar catches up at the next call.
    Quadratures stay out of SUNDIALS' error test (CasADi's ``quad_err_con`` is false by
    default) and no derivative of the callback is needed, so the states, the steps and the
    statistics are those of ``dyn`` — bit for bit (tests/cli/test_progress.py).  Keep the clock
    referenced while the integrator lives: CasADi does not own it.

    Returns
    -------
    (Function, clock) or None
        None when ``dyn`` has quadratures of its own (then run without a bar).
    """
    if dyn.numel_out("quad") != 0:
        return None
    clock = _OutputClock(tout)
    args = [ca.MX.sym(dyn.name_in(i), dyn.sparsity_in(i)) for i in range(dyn.n_in())]
    out = dyn.call(dict(zip(dyn.name_in(), args)))
    t = args[dyn.index_in("t")]
    tout = np.asarray(tout, float)
    if len(tout) >= 2:  # Python only near an output time: see CLOCK_WINDOW
        period = (tout[-1] - tout[0]) / (len(tout) - 1)
        phase = (t - tout[0]) / period
        out["quad"] = ca.if_else(phase - ca.floor(phase) < CLOCK_WINDOW, clock(t), 0, True)
    else:  # one output: the bar completes at the end (clock.finish)
        out["quad"] = ca.MX(0)
    return (ca.Function(dyn.name() + "_clocked", args, [out[n] for n in dyn.name_out()],
                        dyn.name_in(), dyn.name_out()), clock)
