"""The augmented Lagrangian's refinement near singular poses and the four-bar at error 1e-9
(issue 22, item 2).

Near a singular pose a constraint direction with singular value σ → 0 converges at the rate
1/(1 + α σ²/m) per correction, so ten corrections leave q̈ off by ≈ σ Δλ where that direction
carries load.  On the unit parallelogram four-bar in joint coordinates (the cut joint C carries
the coupler's centripetal load along the collinear links) the default right-hand side, on the
exact trajectory 1e-3 rad from the collinear pose, is 3e-3 rad/s² off the closed form
φ̈ = −(6 g / 5 L) cos φ; the crank error at t = 10 s then floors at 1.2e-8 – 1.8e-8 rad for
rtol 1e-12 … 1e-14 (Adams, DOPRI5 and RK4 alike).  ``refine`` adds corrections only where the
iteration says it is not done, at consistent states (drift ≤ ``REFINE_DRIFT``); by default.
Reference: :func:`benchmarks.references.four_bar_angle_at_time`
(elliptic integral, checked against DOP853 at rtol 1e-13 to 6.6e-12 rad).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

import casmbd
from benchmarks.al_accuracy import acceleration, consistent_states
from benchmarks.references import four_bar_rate_squared, load_reference
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.formulations import build
from casmbd.analysis.formulations.augmented_lagrangian import REFINE, REFINE_DRIFT, al_solver
from casmbd.errors import ModelError
from casmbd.system.equations import System

G = 9.81


def _fourbar(coordinates: str = "joint"):
    mech = casmbd.load_scene("examples/parallelogram.toml")
    mech.coordinates = coordinates
    return mech


def _on_branch(phi: float):
    """Joint coordinates (A, B, D relative to the design pose, crank vertical), rates and the
    exact accelerations of the parallelogram branch at crank angle ``phi``."""
    rate = math.sqrt(four_bar_rate_squared(phi))
    acc = -(6.0 * G / 5.0) * math.cos(phi)
    s = phi - math.pi / 2
    return (np.array([s, -s, s]), np.array([rate, -rate, rate]),
            np.array([acc, -acc, acc]))


@pytest.mark.parametrize("offset", [-1e-3, 1e-3, 2e-3])
def test_refine_removes_the_bias_near_the_collinear_pose(offset):
    """On the exact trajectory near φ = π, q̈ without refinement is > 1e-5 off (the bias the
    refinement exists for: 3e-3 at 1e-3 rad, 7e-5 at 2e-3 rad); by default (refine = REFINE,
    the state consistent) within 1e-12 relative of the closed form (measured ≤ 4e-15)."""
    system = System(_fourbar())
    q, v, exact = _on_branch(math.pi + offset)
    plain = acceleration(system, build(system, "augmented_lagrangian", refine=0), q, v)
    refined = acceleration(system, build(system, "augmented_lagrangian"), q, v)
    assert np.max(np.abs(plain - exact)) > 1e-5
    assert np.max(np.abs(refined - exact)) <= 1e-12 * np.max(np.abs(exact))


@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
def test_refine_is_idle_at_regular_poses(coordinates):
    """Away from singular poses ten corrections have converged, the switch keeps q̈: the same
    numbers bit for bit at random consistent states."""
    system = System(_fourbar(coordinates))
    plain = build(system, "augmented_lagrangian", refine=0)
    refined = build(system, "augmented_lagrangian", refine=REFINE, refine_drift=None)
    assert build(system, "augmented_lagrangian").options["refine"] == REFINE
    for q, v in consistent_states(system, 0.3, 4):
        assert np.array_equal(acceleration(system, plain, q, v),
                              acceleration(system, refined, q, v))


def test_solver_refines_only_a_slow_iteration():
    """``al_solver`` against the textbook iteration in numpy: with a direction of tiny singular
    value (rate ≈ 1 − 1e-3 per correction) it equals iterations + refine corrections; with a
    regular C_q it equals the plain iterations."""
    rng = np.random.default_rng(5)
    n, nc, alpha, iterations, refine = 5, 3, 1.0, 10, 40
    root = rng.standard_normal((n, n))
    m = root @ root.T + n * np.eye(n)
    forces, gamma = rng.standard_normal(n), rng.standard_normal(nc)

    def textbook(cq, count):
        lam, k_mat = np.zeros(nc), m + alpha * cq.T @ cq
        for _ in range(count):
            acc = np.linalg.solve(k_mat, forces - cq.T @ lam + alpha * cq.T @ gamma)
            lam = lam + alpha * (cq @ acc - gamma)
        return acc

    u, _, vt = np.linalg.svd(rng.standard_normal((nc, n)), full_matrices=False)
    for sigmas, count in (([3.0, 2.0, 0.1], iterations + refine),
                          ([30.0, 20.0, 10.0], iterations)):
        cq = u @ np.diag(sigmas) @ vt
        solver = al_solver(ca.Sparsity.dense(n, n), ca.Sparsity.dense(nc, n), alpha,
                           iterations, refine)
        got = np.asarray(solver(m, forces, cq, gamma)).ravel()
        want = textbook(cq, count)
        assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want))
        if count > iterations:  # the refinement changed q̈: the case discriminates
            plain = textbook(cq, iterations)
            assert np.max(np.abs(got - plain)) > 1e-6 * np.max(np.abs(want))


def test_fourbar_reaches_1e_9_on_the_default_path():
    """The default path (nothing chosen: joint coordinates, augmented Lagrangian, Adams) at
    rtol = atol = 1e-13: crank angle at t = 10 s within 1e-9 rad of the closed form through its
    ten collinear passes (measured 2.3e-10; without the refinement 1.8e-8)."""
    phi_ref = float(load_reference("parallelogram_four_bar")["results"]["phi_end"])
    sim = Simulator(_fourbar("auto"))
    res = sim.run(10.0, 1, rtol=1e-13, atol=1e-13)
    assert (res.stats["coordinates"], res.stats["formulation"], res.stats["integrator"]) == (
        "joint", "augmented_lagrangian", "adams")
    diff = res.body("crank")["angle"][-1] - phi_ref
    assert abs((diff + math.pi) % (2 * math.pi) - math.pi) <= 1e-9


def test_fourbar_in_absolute_coordinates_has_no_floor():
    """Absolute coordinates, default augmented Lagrangian (no refinement), DOPRI5 at
    rtol = atol = 1e-12: crank angle at t = 10 s within 1e-9 rad of the closed form (measured
    3.9e-11; the singular direction carries no load there)."""
    phi_ref = float(load_reference("parallelogram_four_bar")["results"]["phi_end"])
    sim = Simulator(_fourbar("absolute"), "augmented_lagrangian")
    res = sim.run(10.0, 1, integrator="dopri5", rtol=1e-12, atol=1e-12)
    assert abs(res.body("crank")["angle"][-1] - phi_ref) <= 1e-9


@pytest.mark.parametrize("offset", [1e-8, 1e-12])
def test_refinement_only_at_consistent_states(offset):
    """The drift gate: 1e-3 rad from the pose with the rocker moved off the loop by ``offset``
    (drift ≈ offset), q̈ equals the unrefined one bit for bit above ``REFINE_DRIFT`` and the
    ungated refined one below it."""
    system = System(_fourbar())
    q, v, _ = _on_branch(math.pi + 1e-3)
    q = q + np.array([0.0, 0.0, offset])
    got = acceleration(system, build(system, "augmented_lagrangian"), q, v)
    plain = acceleration(system, build(system, "augmented_lagrangian", refine=0), q, v)
    forced = acceleration(system, build(system, "augmented_lagrangian", refine=REFINE,
                                        refine_drift=None), q, v)
    same, other = (plain, forced) if offset > REFINE_DRIFT else (forced, plain)
    assert np.array_equal(got, same)
    assert np.max(np.abs(got - other)) > 1e-6


@pytest.mark.parametrize("refine", [-1, 2.5, "9"])
def test_bad_refine_is_refused(refine):
    with pytest.raises(ModelError, match="refine must be an integer >= 0"):
        build(System(_fourbar()), "augmented_lagrangian", refine=refine)


@pytest.mark.parametrize("drift", [0.0, -1e-9, float("nan"), "1e-9"])
def test_bad_refine_drift_is_refused(drift):
    with pytest.raises(ModelError, match="refine_drift must be a number > 0 or None"):
        build(System(_fourbar()), "augmented_lagrangian", refine_drift=drift)
