"""Scalar values of a model: numbers, expression strings or callables of time and parameters.

A *value* is what a user passes for a driver position, a force magnitude or a stiffness:

* a number;
* a string, parsed by :func:`casmbd.model.expressions.parse_expression` over ``t``, ``pi`` and the
  model's parameters (no Python ``eval``);
* a callable ``f(t)`` or ``f(t, p)`` returning a CasADi expression, ``p`` being a dict that maps
  parameter names to their symbols.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.model.expressions import parse_expression

#: how a :class:`Samples` trajectory continues outside its sample times
EXTRAPOLATIONS = ("hold", "linear", "error")


class Samples:
    """A sampled trajectory f(t) (times, values), interpolated by a cubic B-spline (C²).

    The spline is CasADi's ``bspline`` interpolant, which interpolates the samples and has
    continuous first and second derivatives, as drivers need for velocities and accelerations
    (γ contains ∂²C/∂t²).

    Outside [first, last sample time] CasADi's interpolant drops to 0, so the trajectory is
    continued explicitly, by ``extrapolate``:

    * ``"hold"`` (default): the end value is kept (f(t) = f(t_last) after the last sample,
      f(t_first) before the first); velocity and acceleration are 0 there, so the velocity
      jumps to 0 at the last sample unless the samples end at rest;
    * ``"linear"``: the end value and slope continue (f and ḟ continuous, f̈ = 0 outside);
    * ``"error"``: f is NaN outside, which every analysis reports as a non-finite driver
      position naming the driver and the time.
    """

    def __init__(self, times, values, name: str = "samples", extrapolate: str = "hold"):
        t = np.asarray(times, dtype=float).ravel()
        v = np.asarray(values, dtype=float).ravel()
        if t.size != v.size:
            raise ModelError(f"{name}: {t.size} times but {v.size} values")
        if t.size < 4:
            raise ModelError(f"{name}: a cubic spline needs at least 4 samples, got {t.size}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ModelError(f"{name}: times and values must be finite")
        if np.any(np.diff(t) <= 0):
            raise ModelError(f"{name}: times must be strictly increasing")
        if extrapolate not in EXTRAPOLATIONS:
            raise ModelError(f"{name}: extrapolate must be one of {', '.join(EXTRAPOLATIONS)}, "
                             f"got {extrapolate!r}")
        self.times, self.values, self.name = t, v, name
        self.extrapolate = extrapolate
        self._function = ca.interpolant(name.replace(" ", "_").replace("'", ""), "bspline",
                                        [t], v)
        # end values and slopes of the spline, for the linear continuation
        tau = ca.SX.sym("tau")
        slope = ca.Function("slope", [tau], [ca.jacobian(self._function(tau), tau)])
        self._ends = [(float(t[k]), float(self._function(t[k])), float(slope(t[k])))
                      for k in (0, -1)]

    def __call__(self, t):
        # if_else, not fmin/fmax: their derivative at a tie is the mean of both sides, which
        # would halve the velocity at the first and last sample
        first, last = self.times[0], self.times[-1]
        inside = self._function(t)
        if self.extrapolate == "error":
            return inside + ca.if_else(ca.logic_or(t < first, t > last), np.nan * t, 0.0)
        (t0, f0, d0), (t1, f1, d1) = self._ends
        if self.extrapolate == "hold":
            d0 = d1 = 0.0
        return ca.if_else(t > last, f1 + d1 * (t - t1),
                          ca.if_else(t < first, f0 + d0 * (t - t0), inside))

    def __repr__(self) -> str:
        return (f"Samples({self.times.size} points on [{self.times[0]:g}, "
                f"{self.times[-1]:g}], extrapolate={self.extrapolate!r})")


Value = float | int | str | Callable | ca.SX | Samples


def check_value(value: Value, where: str) -> Value:
    """Reject values that cannot be a scalar expression (None, NaN, inf, bool, lists)."""
    if isinstance(value, bool) or value is None:
        raise ModelError(f"{where}: expected a number, an expression string or a callable, "
                         f"got {value!r}")
    if isinstance(value, (int, float)):
        try:
            out = float(value)
        except OverflowError:
            out = math.inf
        if not math.isfinite(out):
            raise ModelError(f"{where}: value must be a finite number, got {str(value)[:40]}")
        return out
    if isinstance(value, (str, ca.SX, Samples)) or callable(value):
        return value
    raise ModelError(f"{where}: expected a number, an expression string or a callable, "
                     f"got {type(value).__name__}")


def resolve(value: Value, t: ca.SX, params: Mapping[str, ca.SX], where: str) -> ca.SX:
    """Turn a value into a CasADi expression of ``t`` and the parameters."""
    if isinstance(value, (int, float)):
        return ca.SX(float(value))
    if isinstance(value, ca.SX):
        return value
    if isinstance(value, Samples):
        return ca.SX(value(t))
    if isinstance(value, str):
        symbols = dict(params)
        symbols["t"] = t
        return ca.SX(parse_expression(value, symbols, where=where))
    if callable(value):
        try:
            n_args = len(inspect.signature(value).parameters)
        except (TypeError, ValueError):
            n_args = 1
        out = value(t, dict(params)) if n_args >= 2 else value(t)
        out = ca.SX(out)
        if out.numel() != 1:
            raise ModelError(f"{where}: the callable returned {out.shape}, expected a scalar")
        return out
    raise ModelError(f"{where}: cannot interpret {value!r}")


def numeric(value: Value, params: Mapping[str, float], where: str) -> float:
    """Evaluate a time-independent value with the parameters' default values."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        out = float(value)  # a plain number: no symbols to build (a 5000-body robot: 70 000)
        if not math.isfinite(out):
            raise ModelError(f"{where}: evaluates to {out}")
        return out
    t = ca.SX.sym("t")
    psyms = {name: ca.SX.sym(name) for name in params}
    expr = resolve(value, t, psyms, where)
    if ca.depends_on(expr, t):
        raise ModelError(f"{where}: must not depend on time t")
    f = ca.Function("f", [t, *psyms.values()], [expr])
    out = float(f(0.0, *params.values()))
    if not math.isfinite(out):
        raise ModelError(f"{where}: evaluates to {out}")
    return out
