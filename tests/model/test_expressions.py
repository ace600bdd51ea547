"""Tests of casmbd.model.expressions: safe parsing of scene-file expressions into CasADi."""

from __future__ import annotations

import math
import sys

import casadi
import numpy as np
import pytest

from casmbd.errors import ExpressionError, SceneError
from casmbd.model.expressions import (
    ALLOWED_FUNCTIONS,
    CONSTANTS,
    MAX_DEPTH,
    MAX_LENGTH,
    depends_on,
    evaluate_number,
    parse_expression,
)

WHERE = "[[drivers]] 'crank' key 'position'"


def sx_value(text: str, **values: float) -> float:
    """Parse ``text`` with SX symbols for ``values`` and evaluate it numerically."""
    names = sorted(values)
    symbols = {name: casadi.SX.sym(name) for name in names}
    expr = parse_expression(text, symbols, WHERE)
    function = casadi.Function("f", [symbols[name] for name in names], [expr])
    return float(function(*[values[name] for name in names]))


# --------------------------------------------------------------------------- arithmetic


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("1 + 2*3", 7.0),
        ("(1 + 2)*3", 9.0),
        ("10 - 4 - 3", 3.0),
        ("12/4/3", 1.0),
        ("2**3**2", 512.0),
        ("-2**2", -4.0),
        ("(-2)**2", 4.0),
        ("2**-1", 0.5),
        ("-+-3", 3.0),
        ("1e-3*2", 0.002),
        ("7/2", 3.5),
        ("2*3**2/6 - 1", 2.0),
    ],
)
def test_arithmetic_precedence_matches_python(text: str, expected: float) -> None:
    assert evaluate_number(text, {}, WHERE) == pytest.approx(expected, abs=1e-15)
    assert parse_expression(text, {}, WHERE) == pytest.approx(expected, abs=1e-15)


def test_numbers_are_returned_as_float() -> None:
    for value in (3, 2.5, "4", " 5 "):
        result = parse_expression(value, {}, WHERE)
        assert isinstance(result, float)
        assert result == pytest.approx(float(value), abs=0.0)
    assert isinstance(parse_expression(np.float64(1.5), {}, WHERE), float)


def test_sample_expression_with_time_evaluates_exactly() -> None:
    t = casadi.SX.sym("t")
    expr = parse_expression("0.1*sin(2*pi*t)", {"t": t}, WHERE)
    assert isinstance(expr, casadi.SX)
    value = float(casadi.Function("f", [t], [expr])(0.3))
    assert abs(value - 0.1 * math.sin(0.6 * math.pi)) <= 1e-15


def test_parameters_and_time() -> None:
    value = sx_value("0.1*sin(2*pi*t) + k/2", t=0.3, k=3.0)
    assert value == pytest.approx(0.1 * math.sin(0.6 * math.pi) + 1.5, abs=1e-15)


def test_float_parameters_are_folded_into_symbolic_expression() -> None:
    t = casadi.SX.sym("t")
    expr = parse_expression("L*t + L**2", {"t": t, "L": 0.5}, WHERE)
    value = float(casadi.Function("f", [t], [expr])(2.0))
    assert value == pytest.approx(0.5 * 2.0 + 0.25, abs=1e-15)


def test_mx_symbols_are_supported() -> None:
    t = casadi.MX.sym("t")
    expr = parse_expression("exp(-t)*cos(t)", {"t": t}, WHERE)
    assert isinstance(expr, casadi.MX)
    value = float(casadi.Function("f", [t], [expr])(0.7))
    assert value == pytest.approx(math.exp(-0.7) * math.cos(0.7), abs=1e-15)


def test_constants() -> None:
    assert CONSTANTS == {"pi": math.pi, "e": math.e}
    assert evaluate_number("pi", {}, WHERE) == pytest.approx(math.pi, abs=1e-15)
    assert evaluate_number("e", {}, WHERE) == pytest.approx(math.e, abs=1e-15)
    assert evaluate_number("2*pi*e", {}, WHERE) == pytest.approx(2 * math.pi * math.e, abs=1e-14)


def test_symbols_shadow_constants() -> None:
    assert evaluate_number("e + pi", {"e": 2.0}, WHERE) == pytest.approx(2.0 + math.pi, abs=1e-15)
    assert sx_value("2*pi", pi=3.0) == pytest.approx(6.0, abs=1e-15)


def test_multiline_text_is_accepted() -> None:
    assert evaluate_number("1 +\n  2*k", {"k": 3.0}, WHERE) == pytest.approx(7.0, abs=1e-15)


def test_long_flat_sum_does_not_exhaust_the_stack() -> None:
    text = "+".join(["t"] * 500)
    assert sx_value(text, t=0.01) == pytest.approx(5.0, abs=1e-12)


# --------------------------------------------------------------------------- functions

UNARY_REFERENCE = {
    "sin": (0.4, math.sin),
    "cos": (0.4, math.cos),
    "tan": (0.4, math.tan),
    "exp": (0.4, math.exp),
    "log": (0.4, math.log),
    "sqrt": (0.4, math.sqrt),
    "abs": (-0.4, abs),
    "asin": (0.4, math.asin),
    "acos": (0.4, math.acos),
    "atan": (0.4, math.atan),
    "sinh": (0.4, math.sinh),
    "cosh": (0.4, math.cosh),
    "tanh": (0.4, math.tanh),
    "floor": (-1.4, math.floor),
    "ceil": (-1.4, math.ceil),
    "sign": (-0.4, np.sign),
}

BINARY_REFERENCE = {
    "atan2": ((0.3, -0.8), math.atan2),
    "min": ((0.3, -0.8), min),
    "max": ((0.3, -0.8), max),
    "pow": ((1.7, 2.3), math.pow),
}


def test_reference_tables_cover_every_allowed_function() -> None:
    assert set(UNARY_REFERENCE) | set(BINARY_REFERENCE) == set(ALLOWED_FUNCTIONS)


@pytest.mark.parametrize("name", sorted(UNARY_REFERENCE))
def test_unary_function(name: str) -> None:
    x, reference = UNARY_REFERENCE[name]
    expected = float(reference(x))
    assert sx_value(f"{name}(x)", x=x) == pytest.approx(expected, abs=1e-14)
    assert evaluate_number(f"{name}(x)", {"x": x}, WHERE) == pytest.approx(expected, abs=1e-14)


@pytest.mark.parametrize("name", sorted(BINARY_REFERENCE))
def test_binary_function(name: str) -> None:
    (x, y), reference = BINARY_REFERENCE[name]
    expected = float(reference(x, y))
    assert sx_value(f"{name}(x, y)", x=x, y=y) == pytest.approx(expected, abs=1e-14)
    value = evaluate_number(f"{name}(x, y)", {"x": x, "y": y}, WHERE)
    assert value == pytest.approx(expected, abs=1e-14)


def test_nested_calls() -> None:
    expected = math.sqrt(1 + math.cos(0.2) ** 2) * max(0.1, math.atan2(1.0, 2.0))
    value = sx_value("sqrt(1 + cos(x)**2)*max(0.1, atan2(1, 2))", x=0.2)
    assert value == pytest.approx(expected, abs=1e-15)


# --------------------------------------------------------------------------- depends_on


def test_depends_on() -> None:
    t = casadi.SX.sym("t")
    k = casadi.SX.sym("k")
    expr = parse_expression("k*sin(t)", {"t": t, "k": k}, WHERE)
    assert depends_on(expr, t) is True
    only_k = parse_expression("2*k", {"t": t, "k": k}, WHERE)
    assert depends_on(only_k, t) is False
    constant = parse_expression("2*pi", {"t": t}, WHERE)
    assert isinstance(constant, float)
    assert depends_on(constant, t) is False
    assert depends_on(3.0, t) is False


# --------------------------------------------------------------------------- rejection


REJECTED = [
    ("__import__('os')", ["unknown function '__import__'", "__import__('os')"]),
    ("os.system('ls')", ["attribute", "os.system"]),
    ("().__class__", ["attribute", "().__class__"]),
    ("[1,2]", ["list", "[1,2]"]),
    ("x if 1 else 2", ["conditional", "x if 1 else 2"]),
    ("lambda: 1", ["lambda", "lambda: 1"]),
    ("'abc'", ["string", "abc"]),
    ("f(x=1)", ["keyword", "f(x=1)"]),
    ("sin(t=1)", ["keyword", "sin(t=1)"]),
    ("1 < 2", ["comparison", "1 < 2"]),
    ("2^3", ["'^'", "'**'", "2^3"]),
    ("t + q", ["unknown name 'q'", "t, ", "pi"]),
    ("sin(1,2)", ["'sin'", "1 argument", "got 2", "sin(1,2)"]),
    ("atan2(1)", ["'atan2'", "2 arguments", "atan2(1)"]),
    ("foo(t)", ["unknown function 'foo'", "foo(t)"]),
    ("_t", ["'_'", "_t"]),
    ("t[0]", ["subscript", "t[0]"]),
    ("[x for x in t]", ["comprehension", "[x for x in t]"]),
    ("True", ["boolean", "True"]),
    ("1 and 2", ["and", "1 and 2"]),
    ("(1, 2)", ["tuple", "1, 2"]),
    ("not t", ["'not'", "not t"]),
    ("7 % 2", ["'%'", "7 % 2"]),
    ("1j", ["complex", "1j"]),
    ("1e999", ["finite", "1e999"]),
    ("sin", ["function", "sin"]),
    ("2 *", ["syntax error", "2 *"]),
    ("sin(*t)", ["unpacking", "sin(*t)"]),
    ("(a := 1)", ["':='", "a := 1"]),
    ("f'{t}'", ["string", "f'{t}'"]),
]


@pytest.mark.parametrize(("text", "fragments"), REJECTED, ids=[text for text, _ in REJECTED])
def test_rejected_input(text: str, fragments: list[str]) -> None:
    t = casadi.SX.sym("t")
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, {"t": t, "k": 1.0}, WHERE)
    message = str(info.value)
    assert message.startswith(WHERE)
    for fragment in fragments:
        assert fragment.lower() in message.lower(), (fragment, message)


def test_error_class_hierarchy() -> None:
    with pytest.raises(SceneError):
        parse_expression("os.system('ls')", {}, WHERE)


def test_unknown_name_lists_allowed_names_and_unshadowed_constants() -> None:
    with pytest.raises(ExpressionError) as info:
        parse_expression("omega*t", {"t": 0.0, "k": 1.0, "_hidden": 2.0, "e": 1.0}, WHERE)
    message = str(info.value)
    assert WHERE in message and "'omega'" in message
    assert "k, t" in message and "pi" in message
    assert "_hidden" not in message


def test_underscore_symbol_is_rejected_even_if_given() -> None:
    with pytest.raises(ExpressionError, match="'_'") as info:
        parse_expression("_secret + 1", {"_secret": 1.0}, WHERE)
    assert WHERE in str(info.value) and "_secret" in str(info.value)


@pytest.mark.parametrize("text", ["", "   ", "\n\t"])
def test_empty_expression(text: str) -> None:
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, {}, WHERE)
    assert WHERE in str(info.value) and "empty" in str(info.value)


def test_overly_long_expression() -> None:
    text = "1+" * 10_000
    assert len(text) == 20_000 > MAX_LENGTH
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, {}, WHERE)
    message = str(info.value)
    assert WHERE in message and "too long" in message and "20000" in message
    assert "1+1+1+" in message


def test_deeply_nested_parentheses() -> None:
    text = "(" * 1000 + "t" + ")" * 1000
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, {"t": 1.0}, WHERE)
    message = str(info.value)
    assert WHERE in message and "nested" in message and "((((" in message


def test_nesting_limit_boundary() -> None:
    ok = "(" * MAX_DEPTH + "1" + ")" * MAX_DEPTH
    assert parse_expression(ok, {}, WHERE) == pytest.approx(1.0, abs=0.0)
    deep = "(" * (MAX_DEPTH + 1) + "1" + ")" * (MAX_DEPTH + 1)
    with pytest.raises(ExpressionError, match="nested"):
        parse_expression(deep, {}, WHERE)


@pytest.mark.parametrize(
    "text",
    [
        "-" * 150 + "1",
        "-" * 9_999 + "1",
        "~" * 9_999 + "1",
        "2**" * 3_000 + "1",
        "1+" * 4_999 + "1",
        "sin(" * 2_000 + "1" + ")" * 2_000,
        "9" * 5_000,
        "1\x00",
    ],
    ids=["unary150", "unary9999", "invert9999", "pow3000", "sum5000", "sin2000", "digits", "nul"],
)
def test_pathological_input_raises_expression_error(text: str) -> None:
    limit = sys.getrecursionlimit()
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, {}, WHERE)
    assert str(info.value).startswith(WHERE)
    assert repr(text[:20])[1:-1] in str(info.value)
    assert sys.getrecursionlimit() == limit


@pytest.mark.parametrize("value", [True, None, [1.0], float("nan"), float("inf")])
def test_rejected_non_string_values(value: object) -> None:
    with pytest.raises(ExpressionError) as info:
        parse_expression(value, {}, WHERE)  # type: ignore[arg-type]
    assert WHERE in str(info.value) and repr(value) in str(info.value)


def test_bad_symbol_value_is_rejected() -> None:
    with pytest.raises(ExpressionError) as info:
        parse_expression("k", {"k": "abc"}, WHERE)  # type: ignore[dict-item]
    assert WHERE in str(info.value) and "'k'" in str(info.value)


def test_default_where() -> None:
    with pytest.raises(ExpressionError, match=r"^expression: "):
        parse_expression("q", {})


# --------------------------------------------------------------------------- evaluate_number


@pytest.mark.parametrize("text", ["log(0)", "1/0", "0**-1", "sqrt(-1)", "exp(1000)", "10**400"])
def test_evaluate_number_rejects_non_finite_results(text: str) -> None:
    with pytest.raises(ExpressionError) as info:
        evaluate_number(text, {}, WHERE)
    message = str(info.value)
    assert WHERE in message and "finite" in message and text in message


def test_evaluate_number_division_by_zero_parameter() -> None:
    with pytest.raises(ExpressionError, match="finite"):
        evaluate_number("1/k", {"k": 0.0}, WHERE)


def test_evaluate_number_with_values() -> None:
    value = evaluate_number("2*L*cos(phi) + 1", {"L": 0.5, "phi": 0.3}, WHERE)
    assert isinstance(value, float)
    assert value == pytest.approx(math.cos(0.3) + 1.0, abs=1e-15)
    assert evaluate_number(4, {}, WHERE) == pytest.approx(4.0, abs=0.0)


def test_evaluate_number_rejects_symbolic_values() -> None:
    with pytest.raises(ExpressionError) as info:
        evaluate_number("t", {"t": casadi.SX.sym("t")}, WHERE)  # type: ignore[dict-item]
    assert WHERE in str(info.value) and "'t'" in str(info.value)
