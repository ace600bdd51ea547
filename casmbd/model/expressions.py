"""Safe parsing of expression strings from scene files into CasADi expressions.

Scene files contain expressions such as ``"0.1*sin(2*pi*t) + k/2"``.  They are turned into
CasADi expressions without ``eval``, ``exec`` or compiling code: the text is parsed with
:func:`ast.parse` (``mode="eval"``) and the syntax tree is walked with a strict whitelist of
node types, operators, names and functions.  Everything else raises
:class:`~casmbd.errors.ExpressionError` with a message naming where the expression came from,
the offending fragment and the reason.

Allowed syntax
--------------
* numeric literals (``2``, ``0.5``, ``1e-3``), parentheses;
* names given in ``symbols`` (for example ``t`` and scene parameters) and the constants
  :data:`CONSTANTS` (``pi``, ``e``); a symbol of the same name shadows a constant;
* binary ``+ - * / **`` and unary ``+ -`` with Python's precedence (``-2**2 == -4``);
* calls of :data:`ALLOWED_FUNCTIONS` with the right number of positional arguments.

Pathological input cannot hang or crash the interpreter: text longer than
:data:`MAX_LENGTH` characters or nested deeper than :data:`MAX_DEPTH` levels is rejected, and
the errors :func:`ast.parse` raises on absurd input (``RecursionError``, ``MemoryError``, ...)
are turned into :class:`~casmbd.errors.ExpressionError`.  Evaluation is iterative, so long
chains such as ``1+1+...+1`` do not exhaust the Python stack either.

The whitelist and the checks of the syntax tree are in :mod:`casmbd.model.expression_rules`;
this module parses, evaluates and re-exports the public tables.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import casadi

from casmbd.errors import ModelError
from casmbd.model.expression_rules import (
    ALLOWED_FUNCTIONS,
    BINARY_OPERATORS,
    CONSTANTS,
    FUNCTION_ARITY,
    HELPER_ARITY,
    HELPER_FUNCTIONS,
    MAX_DEPTH,
    MAX_LENGTH,
    MEASURE_ARITY,
    ExpressionValue,
    check_tree,
    expression_error,
    is_real_number,
    max_bracket_depth,
    normalize_symbols,
    parse_to_ast,
    shorten,
)

__all__ = [
    "ALLOWED_FUNCTIONS",
    "CONSTANTS",
    "FUNCTION_ARITY",
    "HELPER_ARITY",
    "HELPER_FUNCTIONS",
    "MAX_DEPTH",
    "MAX_LENGTH",
    "MEASURE_ARITY",
    "depends_on",
    "evaluate_number",
    "parse_expression",
]

#: no measure calls (the default of the evaluation helpers)
_NO_CALLS: Mapping[str, Any] = MappingProxyType({})


def _is_measure(node: ast.AST, calls: Mapping[str, Any]) -> bool:
    """Whether a checked node is a call of a measure (its arguments are quoted names)."""
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id in calls)


def _children(node: ast.AST, calls: Mapping[str, Any] = _NO_CALLS) -> list[ast.AST]:
    """Return the operands of a checked node, in evaluation order."""
    if isinstance(node, ast.BinOp):
        return [node.left, node.right]
    if isinstance(node, ast.UnaryOp):
        return [node.operand]
    if isinstance(node, ast.Call) and not _is_measure(node, calls):
        return list(node.args)
    return []


def _apply(node: ast.AST, operands: list[Any]) -> Any:
    """Apply the operation of a checked node to its evaluated operands."""
    if isinstance(node, ast.BinOp):
        return BINARY_OPERATORS[type(node.op)](operands[0], operands[1])
    if isinstance(node, ast.UnaryOp):
        return -operands[0] if isinstance(node.op, ast.USub) else operands[0]
    assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
    function = ALLOWED_FUNCTIONS.get(node.func.id) or HELPER_FUNCTIONS[node.func.id]
    return function(*operands)


def _measure(node: ast.Call, calls: Mapping[str, Any], source: str, where: str) -> Any:
    """The value of a measure call: its resolver applied to the quoted names; a
    :class:`~casmbd.errors.ModelError` of the resolver (an unknown joint, ...) becomes an
    :class:`~casmbd.errors.ExpressionError` naming ``where`` and the call."""
    assert isinstance(node.func, ast.Name)
    names = [argument.value for argument in node.args]  # checked: string constants
    try:
        return calls[node.func.id][1](*names)
    except ModelError as error:
        raise expression_error(where, ast.get_source_segment(source, node) or source,
                               str(error)) from None


def _evaluate(tree: ast.Expression, symbols: Mapping[str, ExpressionValue],
              calls: Mapping[str, Any] = _NO_CALLS, source: str = "",
              where: str = "expression") -> Any:
    """Evaluate a checked tree without recursion (post-order with an explicit stack)."""
    values: list[Any] = []
    stack: list[tuple[ast.AST, bool]] = [(tree.body, False)]
    while stack:
        node, operands_ready = stack.pop()
        if isinstance(node, ast.Constant):
            values.append(float(node.value))
        elif isinstance(node, ast.Name):
            values.append(symbols[node.id] if node.id in symbols else CONSTANTS[node.id])
        elif _is_measure(node, calls):
            values.append(_measure(node, calls, source, where))
        elif operands_ready:
            count = len(_children(node, calls))
            operands = values[len(values) - count :]
            del values[len(values) - count :]
            values.append(_apply(node, operands))
        else:
            stack.append((node, True))
            stack.extend((child, False) for child in reversed(_children(node, calls)))
    (result,) = values
    return result


def parse_expression(
    text: str | float,
    symbols: Mapping[str, casadi.SX | casadi.MX | float],
    where: str = "expression",
    calls: Mapping[str, tuple[int, Any]] | None = None,
) -> casadi.SX | casadi.MX | float:
    """Turn an expression string of a scene file into a CasADi expression.

    No Python code is evaluated: the text is parsed with :func:`ast.parse` and the syntax tree
    is interpreted with a whitelist (numbers, names in ``symbols`` or :data:`CONSTANTS`,
    ``+ - * / **``, unary ``+ -``, parentheses, positional calls of
    :data:`ALLOWED_FUNCTIONS`).

    Parameters
    ----------
    text : str or int or float
        Expression text such as ``"0.1*sin(2*pi*t) + k/2"``, or a plain number.
    symbols : mapping of str to casadi.SX, casadi.MX or float
        Names usable in the expression (e.g. ``"t"`` and parameter names) and their values.
        A symbol shadows a constant of the same name.  Names starting with ``_`` can never
        be used.
    where : str, optional
        Human-readable location of the expression, e.g.
        ``"[[drivers]] 'crank' key 'position'"``; it starts every error message.
    calls : mapping of str to (int, callable), optional
        Measures usable here (:data:`MEASURE_ARITY`; :mod:`casmbd.model.measures`): name →
        (number of quoted names, resolver called with the names and returning the value).
        ``angle("J1")`` is then the resolver of ``"angle"`` called with ``"J1"``; its
        :class:`~casmbd.errors.ModelError` becomes an ``ExpressionError`` naming ``where``.
        Without it a measure is refused as a state-dependent value.

    Returns
    -------
    casadi.SX or casadi.MX or float
        The expression; a ``float`` when it does not involve any CasADi symbol.

    Raises
    ------
    ExpressionError
        If the text is empty, too long (more than :data:`MAX_LENGTH` characters), nested
        deeper than :data:`MAX_DEPTH` levels, not valid syntax, or uses anything outside the
        whitelist (unknown names or functions, attributes, subscripts, strings, keyword
        arguments, comparisons, ``^``, ...), if a number is not finite or a boolean, or if
        CasADi cannot combine the operands.  The message names ``where``, the offending
        fragment and the reason.

    Examples
    --------
    >>> import casadi
    >>> t = casadi.SX.sym("t")
    >>> parse_expression("0.1*sin(2*pi*t)", {"t": t})
    SX((0.1*sin((6.28319*t))))
    >>> parse_expression("k/2", {"k": 3.0})
    1.5
    """
    if isinstance(text, bool):
        raise expression_error(where, repr(text),
                               "booleans are not allowed; expected a number or expression")
    if is_real_number(text):
        number = float(text)
        if not math.isfinite(number):
            raise expression_error(where, repr(text), "number is not finite")
        return number
    if not isinstance(text, str):
        raise expression_error(
            where,
            shorten(repr(text)),
            f"expected an expression string or a number, got {type(text).__name__}",
        )
    if len(text) > MAX_LENGTH:
        raise expression_error(
            where,
            text,
            f"expression is too long ({len(text)} characters, at most {MAX_LENGTH} allowed)",
        )
    # Line breaks (TOML multi-line strings) are plain white space in an expression.
    source = text.replace("\r", " ").replace("\n", " ").replace("\t", " ").strip()
    if not source:
        raise expression_error(where, text, "expression is empty")
    if max_bracket_depth(source) > MAX_DEPTH:
        raise expression_error(
            where,
            source,
            f"expression is too deeply nested (more than {MAX_DEPTH} levels of brackets)",
        )
    table = normalize_symbols(symbols, where)
    tree = parse_to_ast(source, where)
    check_tree(tree, source, table, where, calls)
    try:
        result = _evaluate(tree, table, calls or _NO_CALLS, source, where)
    except (RuntimeError, TypeError, ValueError, NotImplementedError, ArithmeticError) as error:
        raise expression_error(where, source, f"cannot evaluate expression: {error}") from None
    if isinstance(result, casadi.DM):
        return float(result) if result.is_scalar() else result
    if is_real_number(result):
        return float(result)
    return result


def evaluate_number(
    text: str | float,
    values: Mapping[str, float],
    where: str = "expression",
) -> float:
    """Evaluate an expression to a finite number.

    Parameters
    ----------
    text : str or int or float
        Expression text (same rules as :func:`parse_expression`) or a plain number.
    values : mapping of str to float
        Numeric values of the names usable in the expression.
    where : str, optional
        Human-readable location of the expression; it starts every error message.

    Returns
    -------
    float
        The finite value of the expression.

    Raises
    ------
    ExpressionError
        If the expression is invalid (see :func:`parse_expression`), a value is not a real
        number, or the result is not finite (e.g. ``"log(0)"`` or ``"1/0"``).

    Examples
    --------
    >>> evaluate_number("2*L + 1", {"L": 0.5})
    2.0
    """
    numeric: dict[str, float] = {}
    for name, value in values.items():
        if not is_real_number(value):
            raise expression_error(
                where,
                str(name),
                f"value of {name!r} must be a real number, got {type(value).__name__}",
            )
        numeric[name] = float(value)
    result = parse_expression(text, numeric, where)
    if not is_real_number(result):  # pragma: no cover - only numbers were supplied
        raise expression_error(where, str(text), "expression does not evaluate to a number")
    number = float(result)
    if not math.isfinite(number):
        raise expression_error(
            where,
            str(text),
            f"expression evaluates to {number}, which is not a finite number",
        )
    return number


def depends_on(expr: casadi.SX | casadi.MX | float, sym: casadi.SX | casadi.MX) -> bool:
    """Tell whether an expression depends on a symbol.

    Parameters
    ----------
    expr : casadi.SX or casadi.MX or float
        Expression, e.g. a result of :func:`parse_expression`.
    sym : casadi.SX or casadi.MX
        Purely symbolic expression (e.g. ``casadi.SX.sym("t")``).

    Returns
    -------
    bool
        ``False`` for plain numbers, otherwise ``casadi.depends_on(expr, sym)``.

    Examples
    --------
    >>> import casadi
    >>> t = casadi.SX.sym("t")
    >>> depends_on(parse_expression("2*t", {"t": t}), t), depends_on(1.0, t)
    (True, False)
    """
    if is_real_number(expr) or isinstance(expr, casadi.DM):
        return False
    return bool(casadi.depends_on(expr, sym))
