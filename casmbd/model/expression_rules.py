"""The whitelist of the expression parser (:mod:`casmbd.model.expressions`): the functions,
constants and operators an expression may use, the size limits, and the checks of a parsed
syntax tree against them (every rejection an :class:`~casmbd.errors.ExpressionError` naming
where the expression came from, the fragment and the reason).
"""

from __future__ import annotations

import ast
import math
import numbers
from collections.abc import Callable, Mapping
from typing import Any

import casadi

from casmbd.errors import ExpressionError
from casmbd.limits import MAX_EXPRESSION_DEPTH, MAX_EXPRESSION_LENGTH

#: Longest accepted expression text, in characters (:data:`casmbd.limits.MAX_EXPRESSION_LENGTH`).
MAX_LENGTH = MAX_EXPRESSION_LENGTH

#: Deepest accepted nesting (parentheses, calls, unary operators, right operands;
#: :data:`casmbd.limits.MAX_EXPRESSION_DEPTH`).
MAX_DEPTH = MAX_EXPRESSION_DEPTH

#: Functions that may be called in an expression, by name.
ALLOWED_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "sin": casadi.sin,
    "cos": casadi.cos,
    "tan": casadi.tan,
    "exp": casadi.exp,
    "log": casadi.log,
    "sqrt": casadi.sqrt,
    "abs": casadi.fabs,
    "asin": casadi.asin,
    "acos": casadi.acos,
    "atan": casadi.atan,
    "atan2": casadi.atan2,
    "sinh": casadi.sinh,
    "cosh": casadi.cosh,
    "tanh": casadi.tanh,
    "min": casadi.fmin,
    "max": casadi.fmax,
    "floor": casadi.floor,
    "ceil": casadi.ceil,
    "sign": casadi.sign,
    "pow": casadi.power,
}

#: Number of positional arguments each function of :data:`ALLOWED_FUNCTIONS` takes.
FUNCTION_ARITY: dict[str, int] = {
    name: (2 if name in ("atan2", "min", "max", "pow") else 1) for name in ALLOWED_FUNCTIONS
}

#: Named constants available in every expression (shadowed by symbols of the same name).
CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}


def _step(x, x0, h0, x1, h1):
    """Adams' cubic STEP: h0 for x <= x0, h1 for x >= x1, and between them
    h0 + (h1 − h0) Δ² (3 − 2 Δ) with Δ = (x − x0)/(x1 − x0) (C¹: zero slope at both ends;
    MSC Adams, "STEP" function reference)."""
    d = casadi.fmin(casadi.fmax((x - x0) / (x1 - x0), 0.0), 1.0)
    return h0 + (h1 - h0) * d * d * (3.0 - 2.0 * d)


def _smooth_sign(x, eps):
    """tanh(x/eps): a smooth sign, within 1 − tanh(1) = 0.24 of sign(x) at |x| = eps and
    2.7e-9 at |x| = 10 eps (the Coulomb law of :mod:`casmbd.model.joint_friction`)."""
    return casadi.tanh(x / eps)


def _dead_zone(x, lo, hi):
    """0 for lo <= x <= hi, x − hi above, x − lo below (continuous, slope 0 or 1)."""
    return casadi.fmin(x - lo, 0.0) + casadi.fmax(x - hi, 0.0)


#: Smooth helper functions of forces and requests, allowed in every expression (C¹ or C∞;
#: their number of arguments in :data:`HELPER_ARITY`).
HELPER_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "step": _step,
    "smooth_sign": _smooth_sign,
    "dead_zone": _dead_zone,
}
HELPER_ARITY: dict[str, int] = {"step": 5, "smooth_sign": 2, "dead_zone": 3}

#: Measures of the mechanism's state and the number of quoted names each takes
#: (:mod:`casmbd.model.measures`); callable only where the caller hands in their resolvers
#: (``calls`` of :func:`casmbd.model.expressions.parse_expression`): [[outputs]] values and
#: forces of type "expression".  Elsewhere (drivers, other forces) they are refused by name.
MEASURE_ARITY: dict[str, int] = {
    "angle": 1, "translation": 1, "coordinate": 1, "rate": 1,
    "x": 1, "y": 1, "z": 1, "vx": 1, "vy": 1, "vz": 1, "speed": 1, "distance": 2,
    "angle_of": 1, "omega_of": 1, "wx": 1, "wy": 1, "wz": 1,
}

BINARY_OPERATORS: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: casadi.plus,
    ast.Sub: casadi.minus,
    ast.Mult: casadi.times,
    ast.Div: casadi.rdivide,
    ast.Pow: casadi.power,
}

_OPERATOR_SYMBOLS: dict[type, str] = {
    ast.Mod: "%",
    ast.FloorDiv: "//",
    ast.MatMult: "@",
    ast.LShift: "<<",
    ast.RShift: ">>",
    ast.BitOr: "|",
    ast.BitAnd: "&",
    ast.BitXor: "^",
    ast.Not: "not",
    ast.Invert: "~",
}

_FORBIDDEN_NODES: dict[type, str] = {
    ast.Attribute: "attribute access is not allowed",
    ast.Subscript: "subscripts (indexing) are not allowed",
    ast.Slice: "slices are not allowed",
    ast.List: "lists are not allowed",
    ast.Tuple: "tuples are not allowed (only one value per expression)",
    ast.Set: "sets are not allowed",
    ast.Dict: "dictionaries are not allowed",
    ast.ListComp: "comprehensions are not allowed",
    ast.SetComp: "comprehensions are not allowed",
    ast.DictComp: "comprehensions are not allowed",
    ast.GeneratorExp: "comprehensions (generator expressions) are not allowed",
    ast.Lambda: "lambda functions are not allowed",
    ast.IfExp: "conditional expressions ('a if c else b') are not allowed",
    ast.Compare: "comparisons are not allowed",
    ast.BoolOp: "boolean operators ('and', 'or') are not allowed",
    ast.NamedExpr: "assignment expressions (':=') are not allowed",
    ast.JoinedStr: "strings (f-strings) are not allowed",
    ast.FormattedValue: "strings (f-strings) are not allowed",
    ast.Starred: "argument unpacking ('*') is not allowed",
    ast.Await: "'await' is not allowed",
    ast.Yield: "'yield' is not allowed",
    ast.YieldFrom: "'yield' is not allowed",
}

_FRAGMENT_LENGTH = 60

#: what a symbol of an expression stands for: a CasADi symbol or a number
ExpressionValue = casadi.SX | casadi.MX | float


def shorten(text: str, limit: int = _FRAGMENT_LENGTH) -> str:
    """Return ``text`` cut to at most ``limit`` characters, marked with ``...`` when cut."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def expression_error(where: str, fragment: str, why: str) -> ExpressionError:
    """Build the error for ``fragment`` of the expression at ``where``.

    Parameters
    ----------
    where : str
        Human-readable location of the expression, e.g. a scene table, entry and key.
    fragment : str
        The offending part of the expression text.
    why : str
        Reason the fragment is rejected.

    Returns
    -------
    ExpressionError
        The error, to be raised by the caller.
    """
    return ExpressionError(f"{where}: {why} (in {shorten(fragment)!r})")


def _fragment(source: str, node: ast.AST) -> str:
    """Return the source text of ``node`` (falling back to :func:`ast.unparse`)."""
    segment = ast.get_source_segment(source, node)
    if segment is None:
        try:
            segment = ast.unparse(node)
        except (RecursionError, ValueError):  # pragma: no cover - parsed trees unparse
            segment = source
    return segment


def is_real_number(value: object) -> bool:
    """Tell whether ``value`` is a real number (booleans are not numbers here)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def normalize_symbols(symbols: Mapping[str, Any], where: str) -> dict[str, ExpressionValue]:
    """Check the symbol table and convert plain numbers to ``float``.

    Parameters
    ----------
    symbols : mapping of str to casadi.SX, casadi.MX or float
        Names usable in the expression.
    where : str
        Location of the expression, used in error messages.

    Returns
    -------
    dict of str to casadi.SX, casadi.MX or float
        The symbols, numbers converted to ``float`` and scalar ``DM`` to ``float``.

    Raises
    ------
    ExpressionError
        If a value is neither a CasADi SX/MX expression nor a real number.
    """
    table: dict[str, ExpressionValue] = {}
    for name, value in symbols.items():
        if isinstance(value, (casadi.SX, casadi.MX)):
            table[name] = value
        elif (isinstance(value, casadi.DM) and value.is_scalar()) or is_real_number(value):
            table[name] = float(value)
        else:
            raise expression_error(
                where,
                str(name),
                f"symbol {name!r} has a value of unsupported type {type(value).__name__}",
            )
    return table


def _allowed_names(symbols: Mapping[str, Any]) -> str:
    """List the names usable in an expression, for error messages."""
    names = sorted(name for name in symbols if not name.startswith("_"))
    names += sorted(name for name in CONSTANTS if name not in symbols)
    return ", ".join(names) if names else "(none)"


def max_bracket_depth(text: str) -> int:
    """Return the deepest nesting of ``()``, ``[]`` and ``{}`` in ``text``."""
    depth = deepest = 0
    for char in text:
        if char in "([{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in ")]}":
            depth -= 1
    return deepest


def parse_to_ast(text: str, where: str) -> ast.Expression:
    """Parse ``text`` into a syntax tree, turning every parser failure into an error.

    Parameters
    ----------
    text : str
        Expression text (already stripped, not empty, not too long).
    where : str
        Location of the expression, used in error messages.

    Returns
    -------
    ast.Expression
        The syntax tree.

    Raises
    ------
    ExpressionError
        On syntax errors and on input too complex for the parser.
    """
    try:
        return ast.parse(text, mode="eval")
    except SyntaxError as error:
        detail = error.msg or "invalid syntax"
        if error.offset is not None:
            detail += f" at column {error.offset}"
        raise expression_error(where, text, f"syntax error: {detail}") from None
    except (RecursionError, MemoryError):
        raise expression_error(where, text,
                               "expression is too deeply nested or too complex") from None
    except ValueError as error:  # e.g. null bytes on some Python versions
        raise expression_error(where, text, f"invalid expression text: {error}") from None


def _check_constant(node: ast.Constant, source: str, where: str) -> None:
    """Accept only finite int/float literals."""
    value = node.value
    if isinstance(value, bool):
        raise expression_error(where, _fragment(source, node), "booleans are not allowed")
    if isinstance(value, (str, bytes)):
        raise expression_error(where, _fragment(source, node), "strings are not allowed")
    if isinstance(value, complex):
        raise expression_error(where, _fragment(source, node), "complex numbers are not allowed")
    if not isinstance(value, (int, float)):
        raise expression_error(where, _fragment(source, node), f"{value!r} is not allowed")
    try:
        number = float(value)
    except OverflowError:
        raise expression_error(where, _fragment(source, node), "number is too large") from None
    if not math.isfinite(number):
        raise expression_error(where, _fragment(source, node), "number is not finite")


def _check_name(node: ast.Name, source: str, symbols: Mapping[str, Any], where: str) -> None:
    """Accept only names of symbols and constants (never names starting with ``_``)."""
    name = node.id
    if name.startswith("_"):
        raise expression_error(
            where, _fragment(source, node), f"names beginning with '_' are not allowed: {name!r}"
        )
    if name in symbols or name in CONSTANTS:
        return
    if name in ALLOWED_FUNCTIONS:
        raise expression_error(
            where,
            _fragment(source, node),
            f"{name!r} is a function; call it like {name}(...)",
        )
    raise expression_error(
        where,
        _fragment(source, node),
        f"unknown name {name!r}; allowed names are: {_allowed_names(symbols)}",
    )


def _function_arity(name: str) -> int | None:
    """Number of arguments of an allowed or helper function (None: not one)."""
    if name in ALLOWED_FUNCTIONS:
        return FUNCTION_ARITY[name]
    return HELPER_ARITY.get(name)


def _check_call(node: ast.Call, source: str, where: str,
                calls: Mapping[str, Any] | None = None) -> bool:
    """Accept only positional calls of allowed functions with the right number of arguments,
    and calls of the measures in ``calls`` (name → (arity, resolver)) with quoted names.

    Returns
    -------
    bool
        True for a measure call (its arguments are names, not expressions to walk).
    """
    func = node.func
    if isinstance(func, ast.Attribute):
        raise expression_error(
            where,
            _fragment(source, node),
            f"attribute access is not allowed: cannot call {_fragment(source, func)!r}",
        )
    if not isinstance(func, ast.Name):
        raise expression_error(where, _fragment(source, node),
                               "only allowed functions can be called, by name")
    if node.keywords:
        keyword = node.keywords[0]
        shown = "**" if keyword.arg is None else f"{keyword.arg}="
        raise expression_error(
            where,
            _fragment(source, node),
            f"keyword arguments are not allowed (got {shown!r}); pass arguments by position",
        )
    name = func.id
    for argument in node.args:
        if isinstance(argument, ast.Starred):
            raise expression_error(where, _fragment(source, node),
                                   "argument unpacking ('*') is not allowed")
    if calls is not None and name in calls:
        expected = calls[name][0]
        plural = "" if expected == 1 else "s"
        if len(node.args) != expected:
            raise expression_error(where, _fragment(source, node),
                        f"measure {name!r} takes {expected} quoted name{plural}, "
                        f"got {len(node.args)} argument(s)")
        for argument in node.args:
            if not (isinstance(argument, ast.Constant) and isinstance(argument.value, str)
                    and argument.value.strip()):
                raise expression_error(where, _fragment(source, node),
                            f"measure {name!r} takes {expected} quoted name{plural} (a joint, "
                            f"marker or body, e.g. {name}(\"J1\")), got "
                            f"{_fragment(source, argument)!r}")
        return True
    if name in MEASURE_ARITY and name not in ALLOWED_FUNCTIONS:
        raise expression_error(
            where,
            _fragment(source, node),
            f"measure {name!r} depends on the state of the mechanism; it is allowed only in "
            "[[outputs]] values and forces of type 'expression' (here: time t and "
            "parameters only)",
        )
    expected = _function_arity(name)
    if expected is None:
        known = sorted([*ALLOWED_FUNCTIONS, *HELPER_FUNCTIONS, *(calls or {})])
        raise expression_error(
            where,
            _fragment(source, node),
            f"unknown function {name!r}; allowed functions are: " + ", ".join(known),
        )
    if len(node.args) != expected:
        plural = "" if expected == 1 else "s"
        raise expression_error(
            where,
            _fragment(source, node),
            f"function {name!r} takes {expected} argument{plural}, got {len(node.args)}",
        )
    return False


def _check_operator(op: ast.AST, node: ast.AST, source: str, where: str) -> None:
    """Accept only ``+ - * / **`` (binary) and ``+ -`` (unary)."""
    if isinstance(op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow, ast.UAdd, ast.USub)):
        return
    symbol = _OPERATOR_SYMBOLS.get(type(op), type(op).__name__)
    why = f"operator {symbol!r} is not allowed"
    if isinstance(op, ast.BitXor):
        why += "; use '**' for powers (e.g. 2**3)"
    else:
        why += "; allowed operators are + - * / **"
    raise expression_error(where, _fragment(source, node), why)


def check_tree(tree: ast.Expression, source: str, symbols: Mapping[str, Any], where: str,
                calls: Mapping[str, Any] | None = None) -> None:
    """Walk the tree iteratively, rejecting anything not whitelisted or nested too deeply.

    The depth of a node is one more than that of its parent, except for the left operand of a
    binary operator that is itself a binary operation: left-associative chains such as
    ``a + b - c + d`` count as one level.

    Parameters
    ----------
    tree : ast.Expression
        Parsed expression.
    source : str
        The text that was parsed (for error fragments).
    symbols : mapping of str to Any
        Names usable in the expression.
    where : str
        Location of the expression, used in error messages.
    calls : mapping of str to (int, callable), optional
        Measure functions usable here (name → (number of quoted names, resolver)).

    Raises
    ------
    ExpressionError
        On the first disallowed construct found (outermost first) or excessive nesting.
    """
    stack: list[tuple[ast.AST, int]] = [(tree.body, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise expression_error(
                where, source, f"expression is too deeply nested (more than {MAX_DEPTH} levels)"
            )
        if isinstance(node, ast.Constant):
            _check_constant(node, source, where)
        elif isinstance(node, ast.Name):
            _check_name(node, source, symbols, where)
        elif isinstance(node, ast.BinOp):
            _check_operator(node.op, node, source, where)
            left_depth = depth if isinstance(node.left, ast.BinOp) else depth + 1
            stack.append((node.right, depth + 1))
            stack.append((node.left, left_depth))
        elif isinstance(node, ast.UnaryOp):
            _check_operator(node.op, node, source, where)
            stack.append((node.operand, depth + 1))
        elif isinstance(node, ast.Call):
            if not _check_call(node, source, where, calls):
                stack.extend((argument, depth + 1) for argument in reversed(node.args))
        else:
            why = _FORBIDDEN_NODES.get(type(node), f"{type(node).__name__} is not allowed")
            raise expression_error(where, _fragment(source, node), why)
