"""Identification end to end on casmbd models: the UR-type arm (URDF) with friction on every
joint and a planar two-link arm (scene).  The "measured" torques come from casmbd's compiled
inverse dynamics of the true mechanism (the per-call API's recursions, not the regressor);
the model identified has wrong masses and no friction."""

from __future__ import annotations

import identification_models as arm
import numpy as np
import pytest

from casmbd.analysis.identification.estimate import least_squares
from casmbd.analysis.identification.identify import identification_model, identify
from casmbd.analysis.identification.measurements import Measurements
from casmbd.io.scene import loads_scene

LAWS = ("viscous", "coulomb")


@pytest.fixture(scope="module")
def ur5():
    truth, model = arm.ur5_truth(), arm.ur5_model()
    reg, base = identification_model(model, LAWS, mode="vm")
    t = np.arange(0.0, 10.0, 0.01)
    q, v, a = arm.arm_trajectory(t, 6, seed=1)
    tau = arm.inverse_dynamics(truth, q, v, a)
    return dict(truth=truth, model=model, reg=reg, base=base, t=t, q=q, v=v, a=a, tau=tau,
                pi=arm.true_parameters(truth, reg))


def test_ur5_noise_free_recovery_and_prediction(ur5):
    """Noise-free torques: π̂_b = K π_true to 1e-9 (relative to max(1, |π_b|)); the torques
    of a new trajectory predicted by Y_b π̂_b equal the true arm's inverse dynamics to 1e-9 of
    their largest value; the consistent standard set is physical and its torques are within
    1e-4 of each joint's RMS torque of the least-squares ones."""
    reg, base = ur5["reg"], ur5["base"]
    meas = Measurements(ur5["t"], ur5["q"], ur5["tau"], ur5["v"], ur5["a"],
                        coordinates=list(reg.rows))
    res = identify(ur5["model"], meas, model=(reg, base))
    truth_b = base.K @ ur5["pi"]
    assert np.max(np.abs(res.base.values - truth_b) / np.maximum(1, np.abs(truth_b))) < 1e-9
    t2 = np.arange(0.0, 5.0, 0.01)
    q2, v2, a2 = arm.arm_trajectory(t2, 6, seed=2)
    tau2 = arm.inverse_dynamics(ur5["truth"], q2, v2, a2)
    pred = base.regressor(reg.stacked(q2, v2, a2).reshape(len(t2), 6, -1)) @ res.base.values
    assert np.max(np.abs(pred - tau2)) < 1e-9 * np.max(np.abs(tau2))
    assert res.consistent.checks["consistent"] and res.consistent.polished
    assert res.consistent.regularization == pytest.approx(1e-12)
    rms = np.sqrt(np.mean(ur5["tau"] ** 2, axis=0))
    assert np.all(res.consistent_torque_rms < 1e-9 * rms), res.consistent_torque_rms / rms
    summary = res.summary()
    assert len(summary["base_parameters"]) == base.rank == 48
    assert summary["condition_number"] == pytest.approx(res.base.condition_number)


def test_ur5_monte_carlo_standard_deviations(ur5):
    """50 seeds of Gaussian torque noise (1 % of each joint's RMS torque): the errors of π̂_b
    lie within 2 σ_π (reported) in 95 % ± 5 % of the 50 × 48 cases, and the empirical
    standard deviation over the seeds is within a factor 1.4 of the mean reported σ_π for
    every base parameter (the sampling error of a standard deviation from 50 draws is 10 %;
    the weights are estimated from each draw)."""
    reg, base = ur5["reg"], ur5["base"]
    n_s = len(ur5["t"])
    y_b = base.regressor(reg.stacked(ur5["q"], ur5["v"], ur5["a"]).reshape(n_s, 6, -1))
    truth_b = base.K @ ur5["pi"]
    sigma = 0.01 * np.sqrt(np.mean(ur5["tau"] ** 2, axis=0))
    errors, stds = [], []
    for seed in range(50):
        noise = np.random.default_rng(1000 + seed).normal(0.0, 1.0, ur5["tau"].shape) * sigma
        est = least_squares(y_b, ur5["tau"] + noise, base.names)
        errors.append(est.values - truth_b)
        stds.append(est.std)
    errors, stds = np.array(errors), np.array(stds)
    inside = np.mean(np.abs(errors) <= 2.0 * stds)
    assert 0.90 <= inside <= 0.99, inside
    ratio = errors.std(axis=0, ddof=1) / stds.mean(axis=0)
    assert np.all((ratio > 1 / 1.4) & (ratio < 1.4)), ratio


def test_ur5_noisy_consistent_parameters(ur5):
    """Noise of 1 % of the RMS torques: the consistent standard set is physical (positive
    masses, centroidal inertias positive definite with the triangle inequalities, friction
    ≥ 0) and its residual against the measured torques is within 2 % of the least-squares
    residual per joint (both the noise level, within 10 %)."""
    reg, base = ur5["reg"], ur5["base"]
    sigma = 0.01 * np.sqrt(np.mean(ur5["tau"] ** 2, axis=0))
    tau = ur5["tau"] + np.random.default_rng(3).normal(0.0, 1.0, ur5["tau"].shape) * sigma
    meas = Measurements(ur5["t"], ur5["q"], tau, ur5["v"], ur5["a"], coordinates=list(reg.rows))
    res = identify(ur5["model"], meas, model=(reg, base))
    checks = res.consistent.checks
    assert checks["consistent"]
    for body in checks["bodies"].values():
        assert body["mass"] > 0 and body["principal_moments"][0] > 0
        assert body["triangle_margin"] > 0
    assert all(j["viscous"] >= 0 and j["coulomb"] >= 0 for j in checks["joints"].values())
    n_s = len(ur5["t"])
    y = reg.stacked(ur5["q"], ur5["v"], ur5["a"]).reshape(n_s, 6, -1)
    res_c = np.sqrt(np.mean((y @ res.consistent.values - tau) ** 2, axis=0))
    assert np.all(res_c <= 1.02 * res.base.residual_rms)
    np.testing.assert_allclose(res.base.residual_rms, sigma, rtol=0.1)


def test_ur5_positions_only_with_the_filter(ur5):
    """q and τ sampled at 1 kHz, no velocities or accelerations: zero-phase Butterworth at
    f_c, central differences, decimation by 5, rows near velocity reversals left out.  The
    torques of a new trajectory predicted by the estimate agree with the true arm's to
    5e-3 of each joint's RMS torque noise-free (f_c = 10 Hz), and to 2e-2 with noise of
    1e-5 rad on q and 0.02 N m on τ (f_c = 5 Hz) (what remains: the Coulomb step smeared by
    the filter outside the left-out window)."""
    reg, base = ur5["reg"], ur5["base"]
    t = np.arange(0.0, 10.0, 0.001)
    q, v, a = arm.arm_trajectory(t, 6, seed=1)
    tau = arm.inverse_dynamics(ur5["truth"], q, v, a)
    t2 = np.arange(0.0, 5.0, 0.01)
    q2, v2, a2 = arm.arm_trajectory(t2, 6, seed=2)
    tau2 = arm.inverse_dynamics(ur5["truth"], q2, v2, a2)
    y2 = base.regressor(reg.stacked(q2, v2, a2).reshape(len(t2), 6, -1))
    rms = np.sqrt(np.mean(tau2 ** 2, axis=0))
    rng = np.random.default_rng(0)
    for noise_q, noise_tau, cutoff, tol in ((0.0, 0.0, 10.0, 5e-3), (1e-5, 0.02, 5.0, 2e-2)):
        meas = Measurements(t, q + rng.normal(0, 1, q.shape) * noise_q,
                            tau + rng.normal(0, 1, tau.shape) * noise_tau,
                            coordinates=list(reg.rows))
        res = identify(ur5["model"], meas, model=(reg, base), cutoff=cutoff, decimate=5,
                       consistent=False)
        err = np.sqrt(np.mean((y2 @ res.base.values - tau2) ** 2, axis=0)) / rms
        assert np.all(err < tol), (cutoff, err)


PLANAR = """
[scene]
name = "planar_2r"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "link1"   # the first link
mass = {m1}
inertia = 0.05
position = [0.3, 0.02]

[[bodies]]
name = "link2"
mass = {m2}
inertia = 0.02
position = [0.95, -0.01]

[[joints]]
name = "shoulder"
type = "revolute"
body1 = "ground"
body2 = "link1"
point = [0.0, 0.0]
{f1}

[[joints]]
name = "elbow"
type = "revolute"
body1 = "link1"
body2 = "link2"
point = [0.7, 0.0]
{f2}
"""


def planar_scene(m1=2.0, m2=1.2, friction=True) -> str:
    f1 = "friction = { viscous = 0.3, coulomb = 0.8 }" if friction else ""
    f2 = "friction = { viscous = 0.2, coulomb = 0.5 }" if friction else ""
    return PLANAR.format(m1=m1, m2=m2, f1=f1, f2=f2)


def test_planar_two_link_scene():
    """The planar 2R scene: 10 base parameters (as the hand-written Lagrangian of
    identification_models.py), recovered to 1e-9 noise-free and predicting a new
    trajectory's torques to 1e-9."""
    truth = loads_scene(planar_scene())
    model = loads_scene(planar_scene(m1=2.5, m2=1.0, friction=False))
    reg, base = identification_model(model, LAWS, mode="vm")
    assert base.rank == 10
    t = np.arange(0.0, 10.0, 0.01)
    q, v, a = arm.arm_trajectory(t, 2, seed=4)
    tau = arm.inverse_dynamics(truth, q, v, a)
    res = identify(model, Measurements(t, q, tau, v, a, coordinates=list(reg.rows)),
                   model=(reg, base))
    truth_b = base.K @ arm.true_parameters(truth, reg)
    assert np.max(np.abs(res.base.values - truth_b) / np.maximum(1, np.abs(truth_b))) < 1e-9
    q2, v2, a2 = arm.arm_trajectory(t[:300], 2, seed=5)
    tau2 = arm.inverse_dynamics(truth, q2, v2, a2)
    pred = base.regressor(reg.stacked(q2, v2, a2).reshape(300, 2, -1)) @ res.base.values
    assert np.max(np.abs(pred - tau2)) < 1e-9 * np.max(np.abs(tau2))
    assert res.consistent.checks["consistent"]


def test_refused_mechanisms_are_named():
    """A closed chain (an undriven four-bar: the regressor's least-norm efforts are not what
    motors measure) and a driven one (efforts on the driver) are refused by name."""
    import pathlib

    from casmbd.errors import IdentificationError

    text = (pathlib.Path(__file__).resolve().parents[3] / "examples" / "four_bar.toml"
            ).read_text()
    undriven = loads_scene(text[:text.index("[[drivers]]")])
    with pytest.raises(IdentificationError, match="2 loop-closure equations"):
        identification_model(undriven, (), mode="vm")
    with pytest.raises(IdentificationError, match="efforts on crank_drive"):
        identification_model(loads_scene(text), (), mode="vm")
