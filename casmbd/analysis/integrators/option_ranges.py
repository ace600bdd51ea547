"""Meaningful ranges of the integrator options (issue 31, item 4).

A tolerance or an output interval can be a valid float and still make no sense: ``rtol =
1e-300`` asks for an accuracy 1e284 times finer than the machine's (the step underflows at
t = 0), ``t_end = 1e-320`` gives output intervals of subnormal length.  These are refused
before anything is built, naming the option (``--rtol`` on the command line) and the range.

Ranges (docs/hostile_input.md, "Integrator options"):

``rtol`` in [:data:`RTOL_MIN`, :data:`RTOL_MAX`]
    The local error estimate of an embedded pair is a difference of two solutions; below about
    100 ε (ε = 2.2e-16) it is rounding noise and the step size shrinks until it underflows
    (SUNDIALS raises such an rtol itself, with a warning, in some versions; DOPRI5 fails).
    Above 0.5 the estimate allows an error as large as half the state: no digit is right.
``atol`` in [:data:`ATOL_MIN`, :data:`ATOL_MAX`]
    Absolute, so unit-dependent; the bounds only catch what no SI unit of a coordinate can
    mean (1e-30 m is 15 orders below a nucleus, 1e6 m or rad of absolute error is no error
    control at all).
output interval (t_end − t_start) / steps ≥ max(:data:`INTERVAL_MIN`, 1e-12 · |t|)
    1 fs is the time step of molecular dynamics; no mechanism needs finer output.  The relative
    floor keeps t_start + k · interval distinct in double precision.
``step`` (fixed-step) ≥ the same floor.
``max_steps`` ≤ :data:`MAX_STEPS_PER_INTERVAL`
    more would run for hours before the failure is reported.
"""

from __future__ import annotations

import math

from casmbd.errors import AnalysisError

__all__ = ["ATOL_MAX", "ATOL_MIN", "INTERVAL_MIN", "MAX_STEPS_PER_INTERVAL", "RTOL_MAX",
           "RTOL_MIN", "check_integrator_options"]

#: smallest relative tolerance (about 45 ε)
RTOL_MIN = 1e-14
#: largest relative tolerance
RTOL_MAX = 0.5
#: smallest absolute tolerance
ATOL_MIN = 1e-30
#: largest absolute tolerance
ATOL_MAX = 1e6
#: smallest output interval and fixed step [s]
INTERVAL_MIN = 1e-15
#: relative floor of the output interval and of the fixed step (to |t_start|, |t_end|)
INTERVAL_REL_MIN = 1e-12
#: most steps per output interval of the variable-step integrators
MAX_STEPS_PER_INTERVAL = 10_000_000  # the CLI bound of --max-steps too


def _number(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)) \
        or hasattr(value, "__float__")


def check_integrator_options(t_end: float, steps: int, *, t_start: float = 0.0,
                             rtol: float | None = None, atol: float | None = None,
                             step: float | None = None, max_steps: int | None = None) -> None:
    """Refuse integrator options outside their meaningful ranges (module docstring).

    Raises
    ------
    AnalysisError
        Naming the option (with its command-line flag), the value and the range.
    """
    for key, flag, val, lo, hi in (("rtol", "--rtol", rtol, RTOL_MIN, RTOL_MAX),
                                   ("atol", "--atol", atol, ATOL_MIN, ATOL_MAX)):
        if val is None:
            continue
        v = float(val)
        if not (math.isfinite(v) and lo <= v <= hi):
            raise AnalysisError(
                f"{key} ({flag}) = {v:g} is outside [{lo:g}, {hi:g}]: "
                + ("below about 45 machine epsilons the error estimate is rounding noise and "
                   "the step size underflows" if key == "rtol" and v < lo else
                   "above 0.5 no digit of the result is controlled" if key == "rtol" else
                   "no unit of a coordinate makes this an absolute tolerance")
                + " (casmbd.analysis.integrators.option_ranges)")
    try:
        t0, t1, n = float(t_start), float(t_end), int(steps)
    except (TypeError, ValueError, OverflowError):
        return  # the callers' own checks name a wrong type
    if n >= 1 and math.isfinite(t0) and math.isfinite(t1) and t1 > t0:
        interval = (t1 - t0) / n
        floor = max(INTERVAL_MIN, INTERVAL_REL_MIN * max(abs(t0), abs(t1)))
        if interval < floor:
            raise AnalysisError(
                f"output interval (t_end (--t-end) {t1:g} − t_start {t0:g}) / steps (--steps) "
                f"{n} = {interval:.3g} s is below the floor of {floor:.3g} s (1 fs, or 1e-12 of "
                f"|t|): give a longer --t-end or fewer --steps "
                f"(casmbd.analysis.integrators.option_ranges)")
        if step is not None and _number(step):
            h = float(step)
            if math.isfinite(h) and 0 < h < floor:
                raise AnalysisError(
                    f"fixed step (--step) {h:g} s is below the floor of {floor:.3g} s (1 fs, or "
                    f"1e-12 of |t|) (casmbd.analysis.integrators.option_ranges)")
    if max_steps is not None and int(max_steps) > MAX_STEPS_PER_INTERVAL:
        raise AnalysisError(
            f"max_steps (--max-steps) = {int(max_steps):,} exceeds {MAX_STEPS_PER_INTERVAL:,} "
            f"steps per output interval: the run would take hours before failing; use an "
            f"implicit integrator or more output steps (casmbd.analysis.integrators.option_ranges)")
