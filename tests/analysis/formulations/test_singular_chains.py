"""Chains of parallelograms through their singular poses (issue 7, items 2 and 5).

The N four-bar mechanism (UDC / IFToMM benchmark A02, ``benchmarks/n_four_bar.py``): N + 1
upright bars pinned to the ground and joined at their tops by N couplers.  Whenever the bars
are horizontal every link lies on the ground line and C_q loses N ranks.  On the parallelogram
branch all bars keep one angle θ and α = θ + π/2 obeys α̈ = −k sin α,
k = 3g(3N+1)/(2L(4N+1)) (derived in the module); its elliptic-function solution and SciPy's
integration of the one-DOF equation are the independent references here.

Measured (rtol 1e-10 unless stated, 4 s, four singular passes):

* default formulation, N = 1: crank angle within 6.4e-8 rad of the closed form, bars parallel
  to 2e-12 rad, energy to 1.3e-8 relative;
* default formulation, N = 3 and 5: crank angle off by 1.7e-5 rad, bars parallel only to
  1.9e-6 / 2.7e-6 rad at the passes (decaying afterwards), energy down by ≈ 1e-5 J per pass
  (7e-7 relative after four), whatever rtol: the augmented-Lagrangian iteration (4 iterations,
  default penalty) leaves the loaded, nearly singular constraint directions unconverged
  (docs/hard_cases.md, "N four-bar chain").  The bounds below are 5–7× the measured values,
  and still far below the O(1) rad of a branch switch;
* the same formulation with the penalty ×100 and 8 iterations at rtol 1e-12: crank angle
  within 2.5e-8 rad of SciPy's one-DOF solution, bars parallel to 8e-9 rad — the issue's
  1e-7 / 1e-6 targets.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from benchmarks.n_four_bar import bar_angles, coupler_angles, n_four_bar
from benchmarks.n_four_bar_reference import (
    PUBLISHED_B0,
    b0_position,
    closed_form_angle,
    one_dof_rate,
    one_dof_reference,
    singular_pass_times,
)
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.errors import IntegratorError

T_END = 4.0
STEPS = 400


_cache = private_cache("cache_singular_chains", scope="module")


def absolute(n: int):
    """The N four-bar chain pinned to absolute coordinates (the measurements above; the
    default, ``coordinates = "auto"``, takes joint coordinates:
    tests/analysis/dynamics/test_singular_monitor.py)."""
    mech = n_four_bar(n)
    mech.coordinates = "absolute"
    return mech


@pytest.fixture(scope="module")
def default_runs():
    """Default formulation in absolute coordinates, rtol 1e-10, 4 s, for N = 1, 3, 5 (built
    and run once)."""
    return {n: Simulator(absolute(n)).run(T_END, STEPS, rtol=1e-10) for n in (1, 3, 5)}


def test_one_dof_rate_is_the_energy_of_the_chain():
    """k from T and V by hand: N = 1 is the unit parallelogram (3g·4/(2·5) = 1.2 g)."""
    assert one_dof_rate(1) == pytest.approx(1.2 * 9.81, rel=1e-15)
    assert one_dof_rate(40) == pytest.approx(3 * 9.81 * 121 / (2 * 161), rel=1e-15)


@pytest.mark.parametrize("n", [3, 40])
def test_closed_form_matches_scipy_one_dof_integration(n):
    """Elliptic-function θ(t) against DOP853 at rtol = atol = 1e-12 over 20 s: ≤ 2e-9 rad
    (measured 7.6e-10 for N = 40; the ODE's own error, rtol 1e-13 moves it by 6.5e-10)."""
    t = np.linspace(0.0, 20.0, 401)
    theta_ode, _ = one_dof_reference(t, n)
    assert np.max(np.abs(theta_ode - closed_form_angle(t, n))) <= 2e-9


def test_closed_form_matches_published_reference():
    """B0 of the N = 40 closed form against the benchmark's ADAMS history (6 digits) at the
    whole seconds: ≤ 5e-6 m (measured 2.6e-6), and 20 singular passes in 20 s."""
    t = np.array(sorted(PUBLISHED_B0))
    published = np.array([PUBLISHED_B0[x] for x in t])
    assert np.max(np.abs(b0_position(closed_form_angle(t, 40)) - published)) <= 5e-6
    assert len(singular_pass_times(40)) == 20


def test_example_scene_is_the_builder():
    """examples/n_four_bar_3.toml has the builder's coordinates, initial state and equations."""
    scene = casmbd.System(casmbd.load_scene("examples/n_four_bar_3.toml"))
    built = casmbd.System(n_four_bar(3))
    assert scene.coordinate_names == built.coordinate_names
    assert [str(x) for x in scene.constraint_labels] == [str(x) for x in built.constraint_labels]
    np.testing.assert_array_equal(scene.initial_coordinates(), built.initial_coordinates())
    np.testing.assert_array_equal(scene.initial_velocities(), built.initial_velocities())
    info = casmbd.info(casmbd.load_scene("examples/n_four_bar_3.toml"))
    assert info["degrees_of_freedom"] == 1


@pytest.mark.parametrize(("n", "branch_tol", "angle_tol", "energy_tol"), [
    (1, 1e-9, 3e-7, 1e-7),
    (3, 1e-5, 1e-4, 5e-6),
    (5, 1.5e-5, 1e-4, 5e-6),
])
def test_default_formulation_stays_on_branch(default_runs, n, branch_tol, angle_tol,
                                             energy_tol):
    """Four singular passes in 4 s, counted from the crank angle and found by the result's
    ``near_singular_times``; all bars parallel, couplers level, crank angle and energy against
    the closed form (bounds: module docstring)."""
    res = default_runs[n]
    angles = bar_angles(res, n)
    theta = angles[:, 0]
    passes = singular_pass_times(n, T_END)
    assert len(passes) == 4
    # the crank crosses a horizontal pose (sin θ changes sign) once per pass
    assert np.count_nonzero(np.diff(np.sign(np.sin(theta))) != 0) == 4
    found = np.asarray(res.stats["near_singular_times"])
    assert len(found) == 4
    assert np.max(np.abs(found - passes)) <= 1e-4  # measured ≤ 3e-6 s
    assert res.stats["min_constraint_conditioning"] < 1e-4
    # on the other branch these are O(1) radians
    assert np.max(np.abs(angles - angles[:, :1])) <= branch_tol
    assert np.max(np.abs(coupler_angles(res, n))) <= branch_tol
    assert np.max(np.abs(theta - closed_form_angle(res.t, n))) <= angle_tol
    energy = res["total_energy"]
    assert np.max(np.abs(energy - energy[0])) / energy[0] <= energy_tol


def test_tight_penalty_matches_one_dof_reference_to_1e7():
    """N = 3, augmented Lagrangian with the penalty ×100 and 8 iterations, rtol 1e-12: crank
    angle within 1e-7 rad of SciPy's one-DOF solution (measured 2.5e-8), bars parallel to
    1e-6 (measured 8e-9), energy to 1e-8 relative (measured 1.7e-9)."""
    n = 3
    mech = absolute(n)
    penalty = 100.0 * Simulator(mech).formulation.options["penalty"]
    res = Simulator(mech, "augmented_lagrangian",
                    formulation_options={"penalty": penalty, "iterations": 8}).run(
        T_END, STEPS, rtol=1e-12)
    angles = bar_angles(res, n)
    theta_ref, _ = one_dof_reference(res.t, n)
    assert np.max(np.abs(angles[:, 0] - theta_ref)) <= 1e-7
    assert np.max(np.abs(angles - angles[:, :1])) <= 1e-6
    assert np.max(np.abs(coupler_angles(res, n))) <= 1e-6
    energy = res["total_energy"]
    assert np.max(np.abs(energy - energy[0])) / energy[0] <= 1e-8


def test_index1_failure_names_the_singular_pose(capsys, monkeypatch):
    """index1 (IDAS) cannot pass a singular pose of the N = 3 chain: the error comes at a pass
    (within 1e-4 s; measured 1.233240 against 1.233250) and its message says so, with the
    rank of C_q there.  Run with pytest's capture suspended: casmbd reads the failure time
    from the solver's message on stderr, which CasADi writes through Python's ``sys.stderr``
    (captured by pytest otherwise; reported to the lead).  Compiled code, also under
    ``CASMBD_COMPILE=0``: where IDAS gives up at the pass depends on the last bits of the
    evaluation, and CasADi's virtual machine rounds differently (it passes the pose there)."""
    monkeypatch.delenv("CASMBD_COMPILE", raising=False)
    passes = singular_pass_times(3, T_END)
    with capsys.disabled(), pytest.raises(IntegratorError) as info:
        Simulator(absolute(3), "index1").run(T_END, STEPS, rtol=1e-10)
    err = info.value
    assert np.min(np.abs(passes - err.time)) <= 1e-4
    assert "singular configuration" in str(err)
    assert "C_q has rank" in str(err)
    assert err.partial is not None and err.partial.t[-1] <= err.time


def test_builder_rejects_bad_input():
    with pytest.raises(ValueError, match="positive integer"):
        n_four_bar(0)
    with pytest.raises(ValueError, match="length"):
        n_four_bar(2, length=0.0)
    assert math.isclose(float(closed_form_angle(0.0, 5)), math.pi / 2, abs_tol=1e-14)
