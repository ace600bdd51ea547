"""The fixed-step runner's compiled folds (issue 22, item 5): ``count`` steps in one
:meth:`FixedStep.advance` — split over folds of 256, 64, 16, 4 and 1 steps called through
``Function.buffer()`` — are the same steps as ``count`` single-step calls, bit for bit, and
agree with the closed-form solution of a linear oscillator to the method's accuracy."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from casmbd.analysis.integrators import fixed_step as fixed

OMEGA2 = 4.0  # x'' = -omega² x


def _oscillator() -> ca.Function:
    """dyn(t, x, z, p, u) -> ode of x'' = -p x (p = omega²), in the formulation signature."""
    t, x, p = ca.SX.sym("t"), ca.SX.sym("x", 2), ca.SX.sym("p", 1)
    z, u = ca.SX.sym("z", 0), ca.SX.sym("u", 0)
    empty = ca.SX(0, 1)
    return ca.Function("dyn", [t, x, z, p, u], [ca.vertcat(x[1], -p[0] * x[0]), empty, empty,
                                                 empty], ca.dyn_in(), ca.dyn_out())


@pytest.mark.parametrize("method", ["rk4", "abm"])
def test_one_advance_equals_single_steps_bit_for_bit(method):
    """343 = 256 + 64 + 16 + 4 + 3 × 1 steps: every fold size is used once."""
    runner = fixed.FixedStep(_oscillator(), method, mode="vm")
    p, h, count = np.array([OMEGA2]), 0.01, 343
    start = runner.start([1.0, 0.0], 0.0, p)
    whole = runner.advance(start, p, h, count)
    one = start
    for _ in range(count):
        one = runner.advance(one, p, h, 1)
    np.testing.assert_array_equal(whole.s, one.s)
    assert (whole.steps, whole.rhs_evaluations) == (one.steps, one.rhs_evaluations)
    assert whole.steps == count
    assert whole.s[2] == pytest.approx(count * h, rel=1e-12)  # the time carried in the state


@pytest.mark.parametrize("method, bound", [("rk4", 5e-8), ("abm", 2e-7)])
def test_against_the_closed_form(method, bound):
    """x(t) = cos(ω t), v = −ω sin(ω t) after 500 steps of 0.01 s (ω = 2): the phase error
    of RK4 is ≈ t ω⁵ h⁴ / 120 = 1.3e-8 rad (v: ω times that), of ABM4's PECE corrector
    ≈ t ω⁵ h⁴ · 19/720 ≈ 4e-8 rad; the bounds are about twice the v error."""
    runner = fixed.FixedStep(_oscillator(), method, mode="vm")
    p, h, count = np.array([OMEGA2]), 0.01, 500
    end = runner.advance(runner.start([1.0, 0.0], 0.0, p), p, h, count)
    omega, t = np.sqrt(OMEGA2), count * h
    exact = np.array([np.cos(omega * t), -omega * np.sin(omega * t)])
    assert np.max(np.abs(end.x(2) - exact)) < bound


def test_rk4_is_its_stability_polynomial():
    """On a linear ODE x' = A x one RK4 step is x ← R(hA) x with R(Z) = I + Z + Z²/2 + Z³/6
    + Z⁴/24 (an independent formulation of the same method): 500 steps agree to rounding."""
    runner = fixed.FixedStep(_oscillator(), "rk4", mode="vm")
    p, h, count = np.array([OMEGA2]), 0.01, 500
    end = runner.advance(runner.start([1.0, 0.0], 0.0, p), p, h, count)
    z = h * np.array([[0.0, 1.0], [-OMEGA2, 0.0]])
    r = np.eye(2) + z + z @ z / 2 + z @ z @ z / 6 + z @ z @ z @ z / 24
    expected = np.linalg.matrix_power(r, count) @ np.array([1.0, 0.0])
    np.testing.assert_allclose(end.x(2), expected, rtol=0, atol=1e-12)


def test_compiled_folds_agree_with_the_virtual_machine(tmp_path, monkeypatch):
    """The folds generated to C give the virtual machine's numbers (to rounding)."""
    monkeypatch.setenv("CASMBD_CACHE_DIR", str(tmp_path))
    p, h, count = np.array([OMEGA2]), 0.01, 343
    ends = {}
    for mode in ("vm", "compiled"):
        runner = fixed.FixedStep(_oscillator(), "rk4", mode=mode, name="test_folds_rk4")
        ends[mode] = runner.advance(runner.start([1.0, 0.0], 0.0, p), p, h, count).s
    np.testing.assert_allclose(ends["compiled"], ends["vm"], rtol=1e-13, atol=1e-14)
