"""Gautier's weighted least squares and the log-Cholesky consistent solve, on a planar
two-link arm whose regressor is written by hand from its Lagrangian (planar_2r.py, an
independent formulation): noise-free recovery, Monte Carlo agreement of the reported standard
deviations with the spread of the estimates, physical consistency."""

from __future__ import annotations

import identification_models as arm
import numpy as np
import pytest

from casmbd.analysis.identification.consistent import (
    _spatial_pi,
    _spatial_theta_of,
    body_inertials,
    consistent_parameters,
    physical_checks,
)
from casmbd.analysis.identification.estimate import least_squares
from casmbd.errors import IdentificationError

K, P = arm.base_basis()
NAMES_B = [f"b{k}" for k in range(K.shape[0])]
T = np.arange(0.0, 10.0, 0.01)  # 1000 samples of one 10 s period
Q, V, A = arm.fourier_trajectory(T, seed=3)
Y = arm.regressor(Q, V, A)
YB = Y @ P
TAU = Y @ arm.TRUE
SIGMA = np.array([0.05, 0.02])  # N m, per joint


def test_noise_free_recovery_and_prediction():
    """π̂_b = K π_true to 1e-9 (relative to max(1, |π_b|)); the torques of another trajectory
    predicted to 1e-9 of their largest value."""
    est = least_squares(YB, TAU, NAMES_B, ["j1", "j2"])
    truth = K @ arm.TRUE
    assert np.max(np.abs(est.values - truth) / np.maximum(1.0, np.abs(truth))) < 1e-9
    q2, v2, a2 = arm.fourier_trajectory(T[:300], seed=11)
    y2 = arm.regressor(q2, v2, a2)
    tau2 = y2 @ arm.TRUE
    assert np.max(np.abs((y2 @ P) @ est.values - tau2)) < 1e-9 * np.max(np.abs(tau2))
    assert est.residual_rms.max() < 1e-10
    assert 1.0 < est.condition_number < 1e4


def test_monte_carlo_standard_deviations():
    """50 seeds of Gaussian noise (σ = 0.05, 0.02 N m): the errors of π̂_b lie within 2 σ_π
    (reported) in 95 % ± 5 % of the 500 cases (binomial sd 1 %, widened for the correlation
    of the parameters of one seed), and the empirical standard deviation over the seeds is
    within a factor 1.35 of the mean reported σ_π for every parameter (the sampling error of
    a standard deviation from 50 draws is 10 %: 3.5 sd)."""
    truth = K @ arm.TRUE
    errors, stds = [], []
    for seed in range(50):
        noise = np.random.default_rng(100 + seed).normal(0.0, 1.0, TAU.shape) * SIGMA
        est = least_squares(YB, TAU + noise, NAMES_B, ["j1", "j2"])
        errors.append(est.values - truth)
        stds.append(est.std)
        np.testing.assert_allclose(est.joint_sigma, SIGMA, rtol=0.15)
    errors, stds = np.array(errors), np.array(stds)
    inside = np.mean(np.abs(errors) <= 2.0 * stds)
    assert 0.90 <= inside <= 0.99, inside
    ratio = errors.std(axis=0, ddof=1) / stds.mean(axis=0)
    assert np.all((ratio > 1 / 1.35) & (ratio < 1.35)), ratio


def test_weighting_with_unequal_noise():
    """Joint noises in a ratio 1 : 20: the σ_j of the first (ordinary) fit find the two noise
    levels within 25 % (the ordinary fit leaks some of the noisy joint's error into the quiet
    joint's residual: 0.0119 for 0.01 here); the reported σ_π of the weighted estimate agree
    with the Gauss–Markov covariance (Wᵀ Σ⁻¹ W)⁻¹ of the true noise within 25 %, which is
    below the true covariance of the ordinary estimate (the sandwich
    (WᵀW)⁻¹ Wᵀ Σ W (WᵀW)⁻¹) for every parameter."""
    sigma = np.array([0.01, 0.2])
    noise = np.random.default_rng(5).normal(0.0, 1.0, TAU.shape) * sigma
    wls = least_squares(YB, TAU + noise, NAMES_B, ["j1", "j2"])
    np.testing.assert_allclose(wls.joint_sigma, sigma, rtol=0.25)
    w = YB.reshape(-1, YB.shape[2])
    var = np.tile(sigma ** 2, len(T))
    blue = np.linalg.inv(w.T @ (w / var[:, None]))
    inv = np.linalg.inv(w.T @ w)
    sandwich = inv @ (w.T @ (w * var[:, None])) @ inv
    np.testing.assert_allclose(wls.std, np.sqrt(np.diag(blue)), rtol=0.25)
    assert np.all(np.diag(blue) <= np.diag(sandwich) * (1 + 1e-9))
    assert wls.weighted


def test_consistent_parameters_noise_free_and_noisy():
    """Noise-free: the consistent standard set is physical and its torques equal the data to
    1e-9 of their RMS (refined pull and the exact-fit polish); with noise: physical, and its
    residual per joint within 2 % of the least-squares residual (both ≈ the noise)."""
    prior = arm.TRUE * np.r_[1.3 * np.ones(8), 0.0 * np.ones(4)]  # a wrong model, no friction
    est = least_squares(YB, TAU, NAMES_B)
    cons = consistent_parameters(arm.NAMES, K, est, prior)
    assert cons.checks["consistent"] and cons.status == "Solve_Succeeded"
    rms = np.sqrt(np.mean(TAU ** 2, axis=0))
    assert cons.polished
    assert np.all(np.sqrt(np.mean((Y @ cons.values - TAU) ** 2, axis=0)) < 1e-9 * rms)
    noise = np.random.default_rng(9).normal(0.0, 1.0, TAU.shape) * SIGMA
    est = least_squares(YB, TAU + noise, NAMES_B)
    cons = consistent_parameters(arm.NAMES, K, est, prior)
    assert cons.checks["consistent"]
    res_c = np.sqrt(np.mean((Y @ cons.values - TAU - noise) ** 2, axis=0))
    assert np.all(res_c <= 1.02 * est.residual_rms), (res_c, est.residual_rms)


def test_consistent_parameters_repair_a_nonphysical_estimate():
    """Few, very noisy samples give a least-squares estimate whose implied standard set (the
    one nearest the prior) is not physical; the consistent set is, with positive mass and
    inertia about the centre of mass and friction ≥ 0."""
    rng = np.random.default_rng(2)
    n = 40
    noise = rng.normal(0.0, 1.0, (n, 2)) * np.array([3.0, 3.0])
    est = least_squares(YB[:n], TAU[:n] + noise, NAMES_B)
    prior = arm.TRUE.copy()
    implied = prior + np.linalg.pinv(K) @ (est.values - K @ prior)
    assert not physical_checks(arm.NAMES, implied)["consistent"]
    cons = consistent_parameters(arm.NAMES, K, est, prior)
    assert cons.checks["consistent"]
    for body, (m, _, izz) in body_inertials(arm.NAMES, cons.values).items():
        assert m > 0 and izz > 0, body
    assert np.all(cons.values[8:] >= -1e-12)


def test_log_cholesky_round_trip():
    """θ of a physical pseudo-inertia gives back its ten standard parameters (1e-12): a body
    of mass 3 kg, centre of mass (0.1, −0.2, 0.05), a rotated centroidal tensor."""
    import casadi as ca

    rng = np.random.default_rng(4)
    rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    i_c = rot @ np.diag([0.02, 0.03, 0.04]) @ rot.T
    m, c = 3.0, np.array([0.1, -0.2, 0.05])
    i_o = i_c + m * (c @ c * np.eye(3) - np.outer(c, c))
    sigma = 0.5 * np.trace(i_o) * np.eye(3) - i_o
    j = np.block([[sigma, m * c[:, None]], [m * c[None, :], np.array([[m]])]])
    theta = _spatial_theta_of(j)
    x = ca.SX.sym("x", 10)
    exprs = _spatial_pi(x)
    f = ca.Function("f", [x], [ca.vertcat(*exprs.values())])
    got = dict(zip(exprs, np.asarray(f(theta)).ravel(), strict=True))
    want = {"m": m, "mcx": m * c[0], "mcy": m * c[1], "mcz": m * c[2], "Ixx": i_o[0, 0],
            "Iyy": i_o[1, 1], "Izz": i_o[2, 2], "Ixy": i_o[0, 1], "Ixz": i_o[0, 2],
            "Iyz": i_o[1, 2]}
    for key, value in want.items():
        assert got[key] == pytest.approx(value, abs=1e-12)


def test_bad_inputs_are_named():
    """Too few samples; a trajectory that excites no friction (v = 0): the undetermined
    combinations named."""
    with pytest.raises(IdentificationError, match="samples are needed"):
        least_squares(YB[:4], TAU[:4], NAMES_B)
    y0 = arm.regressor(Q, np.zeros_like(V), A) @ P
    with pytest.raises(IdentificationError, match=r"undetermined combination.*b\d"):
        least_squares(y0, y0 @ (K @ arm.TRUE), NAMES_B)
