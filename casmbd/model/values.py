"""Scalar values of a model: numbers, expression strings or callables of time and parameters.

A *value* is what a user passes for a driver position, a force magnitude or a stiffness:

* a number;
* a string, parsed by :func:`casmbd.io.expressions.parse_expression` over ``t``, ``pi`` and the
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


class Samples:
    """A sampled trajectory f(t) (times, values), interpolated by a cubic B-spline (C²).

    The spline is CasADi's ``bspline`` interpolant, which interpolates the samples and has
    continuous first and second derivatives, as drivers need for velocities and accelerations
    (γ contains ∂²C/∂t²).  Valid between the first and last sample time.
    """

    def __init__(self, times, values, name: str = "samples"):
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
        self.times, self.values, self.name = t, v, name
        self._function = ca.interpolant(name.replace(" ", "_").replace("'", ""), "bspline",
                                        [t], v)

    def __call__(self, t):
        return self._function(t)

    def __repr__(self) -> str:
        return (f"Samples({self.times.size} points on [{self.times[0]:g}, "
                f"{self.times[-1]:g}])")


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
    from casmbd.io.expressions import parse_expression

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
