"""Dormand–Prince 5(4) in compiled blocks (casmbd.analysis.integrators.dopri).

* harmonic oscillator x'' = −ω² x against its closed form cos(ω t): the global error follows
  the tolerance (measured 4.2e-7 at rtol 1e-6, 1.5e-9 at 1e-9 over ω t = 20);
* order: the fixed-size step (controller off) halves h → error / 2⁵ (measured ratio ≈ 32);
* the double pendulum (kkt_ode) against CVODES BDF at rtol 1e-12, within the tolerance;
* the statistics: 6 right-hand sides per attempted step (FSAL) plus 2 for the first step;
  rejected steps counted (an oscillator at its stability limit rejects);
* failures name the time: non-finite start, step-size underflow, max_steps.
"""

from __future__ import annotations

import pathlib

import casadi as ca
import numpy as np
import pytest

import casmbd
from casmbd.analysis.dynamics.simulate import Simulator, simulate
from casmbd.analysis.integrators.dopri import Dopri, dopri_step
from casmbd.analysis.integrators.kinds import INTEGRATORS
from casmbd.errors import AnalysisError, IntegratorError

ROOT = pathlib.Path(__file__).resolve().parents[3]


def oscillator(rhs=None) -> ca.Function:
    """x = (position, velocity), p = (ω,): ẋ = (v, −ω² x) (or ``rhs(t, x, ω)``)."""
    t, x, p = ca.MX.sym("t"), ca.MX.sym("x", 2), ca.MX.sym("p", 1)
    z, u = ca.MX.sym("z", 0), ca.MX.sym("u", 0)
    ode = ca.vertcat(x[1], -p[0] ** 2 * x[0]) if rhs is None else rhs(t, x, p[0])
    empty = ca.MX(0, 1)
    return ca.Function("dyn", [t, x, z, p, u], [ode, empty, empty, empty],
                       ["t", "x", "z", "p", "u"], ["ode", "alg", "quad", "zero"])


def run(runner: Dopri, omega: float, tol: float, t_end: float, outputs: int,
        max_steps: int = 100_000):
    state = runner.start([1.0, 0.0], 0.0, t_end, [omega], tol, tol)
    for t_out in np.linspace(0.0, t_end, outputs + 1)[1:]:
        state = runner.advance(state, [omega], t_out, tol, tol, max_steps)
        assert state.t == t_out  # the outputs are hit exactly (steps clipped to them)
    return state


@pytest.fixture(scope="module")
def runner() -> Dopri:
    return Dopri(oscillator(), mode="vm")


def test_registered_for_odes_with_a_bdf_alternative():
    kind = INTEGRATORS["dopri5"]
    assert kind.label == "Dormand–Prince 5(4)" and kind.compiled
    assert kind.integrates("ode") and not kind.integrates("dae")
    assert not kind.integrates("numeric") and not kind.fixed_step
    assert kind.stiff_alternative == "cvodes"
    with pytest.raises(AnalysisError, match="dopri5"):
        simulate(casmbd.load_scene(ROOT / "examples" / "double_pendulum.toml"), 1.0, 2,
                 formulation="index1", integrator="dopri5", mode="vm")


@pytest.mark.parametrize("outputs", [1, 100])
def test_oscillator_error_follows_the_tolerance(runner, outputs):
    omega, t_end = 2.0, 10.0
    errors = {}
    for tol in (1e-6, 1e-9):
        x = run(runner, omega, tol, t_end, outputs).x()
        errors[tol] = max(abs(x[0] - np.cos(omega * t_end)),
                          abs(x[1] + omega * np.sin(omega * t_end)) / omega)
        assert errors[tol] <= 20 * tol, (tol, errors[tol])
    assert errors[1e-9] <= errors[1e-6] / 100  # the error scales with the tolerance


def test_fixed_step_order_is_five():
    """Controller off: N and 2N steps of the bare step over ω t = 2; ratio 2⁵ = 32."""
    step = dopri_step(oscillator())
    omega, t_end = 1.0, 2.0

    def error(n):
        x, t, h = ca.DM([1.0, 0.0]), 0.0, t_end / n
        k1 = ca.DM([0.0, -omega ** 2])
        for _ in range(n):
            x, _, k1 = step(x, t, h, k1, omega)
            t += h
        exact = ca.DM([np.cos(omega * t_end), -omega * np.sin(omega * t_end)])
        return float(ca.norm_2(x - exact))

    e1, e2, e3 = error(10), error(20), error(40)  # measured ratios 32.3, 32.1
    assert 30.0 <= e1 / e2 <= 35.0 and 30.0 <= e2 / e3 <= 34.0, (e1 / e2, e2 / e3)


def test_embedded_estimate_is_fourth_order_local():
    """The error estimate e of one step is O(h⁵): halving h divides it by about 2⁵."""
    step = dopri_step(oscillator())
    ests = [float(ca.norm_2(step([1.0, 0.0], 0.0, h, [0.0, -1.0], 1.0)[1]))
            for h in (0.2, 0.1)]
    assert 25.0 <= ests[0] / ests[1] <= 40.0, ests


def test_statistics_count_attempts_and_rejections():
    """ẋ = −1000 x: DOPRI5's stability limit (|h λ| ≲ 3.3) sets the steps, whatever the
    tolerance (measured 307 steps at rtol 1e-3, 323 at 1e-6), and the controller rejects some."""
    decay = Dopri(oscillator(lambda t, x, w: ca.vertcat(-w * x[0], -x[1])), mode="vm")
    counts = []
    for tol in (1e-3, 1e-6):
        state = run(decay, 1000.0, tol, 1.0, 1)
        st = state.stats()
        assert st["rejected"] > 0 and st["error_test_failures"] == st["rejected"]
        assert st["rhs_evaluations"] == 6 * (st["steps"] + st["rejected"]) + 2
        assert abs(state.x()[0]) <= 10 * tol  # e^-1000: zero within the tolerance
        counts.append(st["steps"])
    assert 1000.0 / 3.5 <= counts[0] <= counts[1] <= 1.2 * counts[0]


def test_double_pendulum_matches_cvodes():
    scene = ROOT / "examples" / "double_pendulum.toml"
    ref = simulate(casmbd.load_scene(scene), 2.0, 20, formulation="kkt_ode",
                   integrator="cvodes", rtol=1e-12, atol=1e-12, mode="vm")
    sim = Simulator(casmbd.load_scene(scene), "kkt_ode", mode="vm")
    for tol in (1e-6, 1e-9):
        res = sim.run(2.0, 20, integrator="dopri5", rtol=tol, atol=tol)
        err = np.max(np.abs(res["q"] - ref["q"]))
        assert err <= 50 * tol, (tol, err)
        st = res.stats
        assert st["integrator"] == "dopri5" and st["steps"] > 0
        assert st["rhs_evaluations"] == 6 * (st["steps"] + st["rejected"]) + 2
    proj = sim.run(2.0, 20, integrator="dopri5", rtol=1e-9, atol=1e-9, projection=True)
    assert np.max(np.abs(proj["q"] - ref["q"])) <= 5e-8


def test_non_finite_start_is_named(runner):
    with pytest.raises(IntegratorError, match=r"state at t = 0.5 is not finite") as info:
        runner.start([np.nan, 0.0], 0.5, 1.0, [1.0], 1e-6, 1e-6)
    assert info.value.flag == "NON_FINITE" and info.value.time == 0.5


def test_underflow_and_max_steps_name_the_time():
    # ẋ = (1/sqrt(1 − t), 0): a non-finite right-hand side past t = 1 (steps shrink to nothing)
    blow = Dopri(oscillator(lambda t, x, w: ca.vertcat(1 / ca.sqrt(1 - t), 0 * x[1])),
                 mode="vm")
    underflow = r"failed at t = 1 with TOO_SMALL_STEP \(step size underflow"
    with pytest.raises(IntegratorError, match=underflow) as info:
        run(blow, 1.0, 1e-6, 2.0, 1)
    assert info.value.flag == "TOO_SMALL_STEP" and 0.999 < info.value.time < 1
    work = r"TOO_MUCH_WORK \(more than 10 steps .* ending at t = 10\)"
    with pytest.raises(IntegratorError, match=work) as info:
        run(Dopri(oscillator(), mode="vm"), 2.0, 1e-9, 10.0, 1, max_steps=10)
    assert info.value.flag == "TOO_MUCH_WORK" and 0 < info.value.time < 10


def test_simulation_failure_keeps_earlier_outputs():
    sim = Simulator(casmbd.load_scene(ROOT / "examples" / "double_pendulum.toml"), "kkt_ode",
                    mode="vm")
    with pytest.raises(IntegratorError, match="more than 5 steps") as info:
        sim.run(2.0, 20, integrator="dopri5", rtol=1e-10, atol=1e-10, max_steps=5)
    partial = info.value.partial
    assert partial is not None and 1 <= len(partial.t) < 21
    assert partial.stats["integrator"] == "dopri5"
