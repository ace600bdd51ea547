"""Locating an event in a sub-interval: the first time a gap closes or a closed gap pulls.

The event time is found by the Illinois variant of regula falsi on g_k(x(t)) (an open gap) or
λ_k (a closed gap's normal or holding force), integrating from the sub-interval's start, to
|Δt| ≤ 1e-13 (1 + |t|); the first event of the sub-interval wins.  A sub-interval that starts
on the event surface (just after an impact or a detach) is first searched for a time inside
(:func:`inside`, dyadic trial times screened in one integrator call).
"""

from __future__ import annotations

import numpy as np

from casmbd.analysis.events.phases import DYADIC, StepError
from casmbd.interrupts import reraise_interrupt

__all__ = ["INSIDE", "illinois", "inside", "locate"]

#: a value of an event row that counts as clearly inside (away from its surface) when the
#: motion starts on the surface: above the rounding of a gap that starts at zero (a body put
#: down touching a tilted plane starts at g ≈ 1e-17 m, not an impact 2 ns later)
INSIDE = 1e-14

def inside(value, h: float, screen=None) -> tuple[float | None, float]:
    """The largest τ = h 2⁻ᵏ (k = 1 … :data:`DYADIC`) with value(τ) > :data:`INSIDE`, and
    that value (None: none).

    ``screen(h)``, when given, returns the values at all :data:`DYADIC` trial times from one
    integrator call (dense output,
    :meth:`~casmbd.analysis.events.phases.Phase.advance_dyadic`); a trial time it finds
    inside is confirmed by ``value`` (the same integration from the start as without the
    screen, so the root finding that follows starts from the same bracket), and when the
    screen fails (an integrator failure) the trial times are tried one by one.  The screen
    saves about 11 of the 13 integrator calls a bounce shorter than the sub-interval took
    (the bouncing ball of e = 1 on a coarse grid: 22 → 10 calls per event)."""
    screened = None
    if screen is not None:
        try:
            screened = np.asarray(screen(h), float)
        except (RuntimeError, StepError) as exc:
            reraise_interrupt(exc)
            screened = None
    if screened is not None:
        for k in np.flatnonzero(screened > INSIDE):
            tau = h * 0.5 ** (int(k) + 1)
            f = value(tau)
            if f > INSIDE:
                return tau, f
        return None, 0.0
    tau = h
    for _ in range(DYADIC):
        tau *= 0.5
        f = value(tau)
        if f > INSIDE:
            return tau, f
    return None, 0.0


def illinois(f, lo: float, hi: float, f_lo: float, f_hi: float, tol: float) -> float:
    """A root of f in (lo, hi) with f(lo) > 0 > f(hi) (Illinois regula falsi)."""
    side = 0
    for _ in range(200):
        mid = hi - f_hi * (hi - lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
        if not lo < mid < hi:
            mid = 0.5 * (lo + hi)
        f_mid = f(mid)
        if f_mid <= 0.0:
            hi, f_hi = mid, f_mid
            if side == -1:
                f_lo *= 0.5
            side = -1
        else:
            lo, f_lo = mid, f_mid
            if side == 1:
                f_hi *= 0.5
            side = 1
        if hi - lo <= tol or f_mid == 0.0:
            break
    return hi


def locate(phase, gaps, p: np.ndarray, nq: int, x, z, t: float, h: float, t_b: float,
           candidates: list[int], closed: frozenset, lams_b: dict, g_b: np.ndarray,
           tol_t: float) -> tuple[tuple, set[int], set[int]]:
    """The first event in the sub-interval (t, t_b], h = t_b − t, of the phase ``phase`` from
    the state (x, z) at t: ((time, gap, detach) — gap None when no candidate crosses — the
    open gaps pressed in from t on, the closed gaps released at t).

    ``candidates`` are the gaps found open and negative (``g_b``), or closed and pulling
    (``lams_b``, the closed rows' multipliers by gap), at t_b; ``p`` the run's parameters;
    ``tol_t`` the relative time tolerance of the root.
    """
    order = sorted(closed)
    x_a, z_a, t_a = x, z, t
    best = (t_b, None, None)
    pressed: set[int] = set()
    released: set[int] = set()
    for i in candidates:
        is_detach = i in closed

        def value(tau, i=i, is_detach=is_detach, phase=phase, x_a=x_a, z_a=z_a,
                  t_a=t_a, order=order):
            xt, _ = phase.advance(x_a, z_a, t_a, tau)
            if is_detach:
                lam = phase.multipliers(xt[:nq], xt[nq:], t_a + tau)
                return gaps.closed_value(i, dict(zip(order, lam, strict=True)))
            return float(gaps.values(xt[:nq], xt[nq:], t_a + tau, p)[i])

        def screen(h_, i=i, is_detach=is_detach, phase=phase, x_a=x_a, z_a=z_a,
                   t_a=t_a, order=order):
            xs_d, _ = phase.advance_dyadic(x_a, z_a, t_a, h_)
            ts_d = t_a + h_ * 0.5 ** np.arange(1, DYADIC + 1)
            if is_detach:
                lam = phase.multipliers_many(xs_d[:, :nq], xs_d[:, nq:], ts_d)
                return [gaps.closed_value(i, dict(zip(order, row, strict=True)))
                        for row in lam]
            return gaps.values_many(xs_d[:, :nq], xs_d[:, nq:], ts_d, p)[:, i]

        if is_detach:
            lam_a = phase.multipliers(x_a[:nq], x_a[nq:], t_a)
            f_lo = max(gaps.closed_value(i, dict(zip(order, lam_a, strict=True))),
                       1e-300)
        else:
            f_lo = float(gaps.values(x_a[:nq], x_a[nq:], t_a, p)[i])
        f_hi = gaps.closed_value(i, lams_b) if is_detach \
            else float(g_b[i])
        lo, hi = 0.0, h
        if f_lo <= 1e-12 * (1.0 + abs(f_hi)):
            # the sub-interval starts at the event surface (just after an impact or a
            # detach): the motion leaves it and may come back within the interval (a
            # bounce shorter than the interval) — find an inside time where it is open
            lo, f_lo = inside(value, h, screen)
            if lo is None:
                if is_detach and not gaps.stick[i]:
                    # a closed gap whose normal force falls through zero at t_a (a
                    # box lifted evenly off two contacts: the second one, after the
                    # first detached): it opens at t_a, with every other such gap
                    released.add(i)
                    if t_a < best[0]:
                        best = (t_a, i, True)
                if not is_detach:
                    # an open gap pressed in from t_a on (a body put down touching
                    # at the start): it closes at t_a (impact if it approaches), with
                    # every other gap pressed in at t_a (a box put down on 4 corners)
                    pressed.add(i)
                    if t_a < best[0]:
                        best = (t_a, i, False)
                continue  # a closed gap stays at its surface: no new event
            hi, f_hi = 2.0 * lo, value(2.0 * lo) if 2.0 * lo < h else f_hi
            hi = min(hi, h)
        tau = illinois(value, lo, hi, f_lo, f_hi, tol_t * (1 + abs(t_b)))
        if t_a + tau < best[0]:
            best = (t_a + tau, i, is_detach)
    return best, pressed, released
