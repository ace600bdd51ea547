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

from casmbd.errors import ModelError

Value = float | int | str | Callable | ca.SX


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
    if isinstance(value, str) or callable(value) or isinstance(value, ca.SX):
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
