"""Guards of the event loop: Zeno behaviour and a periodic run past its event bound (issue 31).

An event-driven run (:mod:`casmbd.analysis.events.march`) records, per gap, the times of its
last impacts.  :func:`zeno_guard` stops a run whose impacts accumulate at a finite time (the
bouncing ball without a rest velocity); :func:`periodic_overrun` one whose impacts repeat with
a constant period and would exceed the event bound before the end time.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PERIODIC_SPREAD", "PROJECT_AFTER", "REST_HEIGHT", "ZENO_FRACTION", "ZENO_IMPACTS",
           "periodic_overrun", "zeno_guard"]

#: rebound height below which a contact closes instead of bouncing again (m)
REST_HEIGHT = 1e-9
#: Zeno guard (:func:`zeno_guard`): impact intervals of one gap that shrink geometrically
ZENO_IMPACTS = 10
#: … with their mean ratio at most this (1: the equal intervals of e = 1 bounces)
ZENO_RATIO = 0.999
#: … and every ratio within this fraction of their mean
ZENO_SPREAD = 0.1
#: … and the last interval below this fraction of a rebound's at the default rest velocity
ZENO_FRACTION = 0.01
#: event-count projection (:func:`periodic_overrun`): made after this many events …
PROJECT_AFTER = 1000
#: … when the last ZENO_IMPACTS + 1 impact intervals of one gap agree to this (relative)
PERIODIC_SPREAD = 1e-6


def zeno_guard(times: list[float], t: float, interval: float) -> tuple[float, str] | None:
    """Record an impact of one gap at ``t`` in ``times``; the accumulation point and a
    description when its impacts accumulate (Zeno behaviour), else None.

    Impacts accumulate when the last :data:`ZENO_IMPACTS` + 1 intervals Δ_k = t_k − t_(k−1)
    shrink geometrically, Δ_(k+1) = r Δ_k, every ratio within :data:`ZENO_SPREAD` of their
    mean r ≤ :data:`ZENO_RATIO` < 1 (a ball of restitution e under constant gravity: r = e),
    and the last interval is below ``interval``.  The impacts then end at the limit of the
    geometric series, t* = t + Δ r / (1 − r) (the bouncing ball's Zeno time t₁ (1 + e)/(1 − e)
    from its first impact); without a rest velocity an event-driven run would locate ever
    closer impacts there, until the event bound or the limits of the event location.
    """
    times.append(float(t))
    del times[:-(ZENO_IMPACTS + 2)]
    if len(times) < ZENO_IMPACTS + 2:
        return None
    gaps = np.diff(times)
    if gaps[-1] >= interval or np.any(gaps <= 0.0):
        return None
    ratios = gaps[1:] / gaps[:-1]
    r = float(np.mean(ratios))
    if not (0.0 < r <= ZENO_RATIO) or np.max(np.abs(ratios / r - 1.0)) > ZENO_SPREAD:
        return None
    t_star = float(t) + float(gaps[-1]) * r / (1.0 - r)
    return t_star, (f"the last {ZENO_IMPACTS + 1} intervals shrink by the ratio {r:.3g}, the "
                    f"last {gaps[-1]:.3g} s")


def periodic_overrun(times: list[float], t_end: float, budget: int) -> tuple[float, int] | None:
    """(period, impacts to come) when the impacts of one gap (``times``, the last ones, as
    kept by :func:`zeno_guard`) repeat with a constant period and at that period more than
    ``budget`` impacts would come before ``t_end``, else None.

    Constant period: the last :data:`ZENO_IMPACTS` + 1 intervals within
    :data:`PERIODIC_SPREAD` of their mean Δ (a ball of restitution 1 under gravity, a rod
    between elastic stops); the impacts to come are ⌊(t_end − t)/Δ⌋.  The event bound would
    be reached for certain were the motion to stay periodic: the event loop then stops at
    once instead of locating the remaining events of the budget one by one (10 000 events
    of the e = 1 ball took 160 s; issue 31).  O(1) per impact (at most ZENO_IMPACTS + 2
    times are kept).
    """
    if len(times) < ZENO_IMPACTS + 2:
        return None
    gaps = np.diff(times)
    period = float(np.mean(gaps))
    if not period > 0.0 or np.max(np.abs(gaps - period)) > PERIODIC_SPREAD * period:
        return None
    coming = math.floor((t_end - times[-1]) / period)
    return (period, coming) if coming > budget else None

