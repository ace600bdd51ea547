"""The robot examples: examples/robot_feedforward.py (UR5-type arm, issue 21 item 6)."""

from __future__ import annotations

import importlib.util
import pathlib

import numpy as np
import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def feedforward():
    return _load("robot_feedforward").run(samples=31)


def test_feedforward_ik_and_line(feedforward):
    # every sample solves the 6-equation IK (position + fixed orientation) to 1e-10
    assert np.max(feedforward["ik_residual"]) <= 1e-10
    assert feedforward["line_deviation"] <= 1e-9
    assert feedforward["path_error"] <= 1e-9      # on the quintic time law, not only the line
    assert feedforward["orientation_error"] <= 1e-9
    assert len(feedforward["t"]) == 31


def test_feedforward_torques_reproduce_accelerations(feedforward):
    # forward dynamics (LDLᵀ of M) with the Newton–Euler torques gives back q̈
    assert feedforward["acc_error"] <= 1e-8
    tau = feedforward["tau"]
    assert np.all(np.isfinite(tau)) and np.max(np.abs(tau[:, 1])) > 1.0  # gravity on the lift
    assert np.all(np.max(np.abs(tau), axis=0) <= feedforward["effort_limits"])


def test_feedforward_derivatives_against_ik_differences():
    """q̇ and q̈ of the differentiated IK against central differences of three IK solutions.

    q(t ± h) solved by the example's own Newton iteration at the line points of t ± h; with
    h = 1e-3 s the truncation errors are ~h² q⁽³⁾ / 6 ≈ 1e-6 (velocity) and h² q⁽⁴⁾ / 12
    (acceleration), the rounding ~1e-13 / h and 1e-13 / h².
    """
    ff = _load("robot_feedforward")
    out = ff.run(samples=7)
    arm = ff.casmbd.compile(ff.casmbd.load_urdf(str(ff.URDF)), coordinates="joint")
    k = arm.frame_names.index(ff.FRAME)
    p0, r0 = ff.pose(arm, ff.Q_START, k)
    h = 1e-3
    for i in (1, 3, 5):
        t = out["t"][i]
        qs = [ff.solve_ik(arm, out["q"][i], p0 + ff.quintic(t + d, ff.DURATION)[0]
                          * ff.DISPLACEMENT, r0, k)[0] for d in (-h, 0.0, h)]
        np.testing.assert_allclose(qs[1], out["q"][i], atol=1e-12)
        np.testing.assert_allclose((qs[2] - qs[0]) / (2 * h), out["v"][i], atol=1e-5)
        np.testing.assert_allclose((qs[2] - 2 * qs[1] + qs[0]) / h**2, out["a"][i], atol=1e-4)
    # the move starts and ends at rest
    assert np.max(np.abs(out["v"][[0, -1]])) <= 1e-12
    assert np.max(np.abs(out["a"][[0, -1]])) <= 1e-9


def test_ur5_min_time_ocp(monkeypatch):
    """ocp/ur5_min_time.toml: solved, a limit active, the controls replayed by simulation.

    Minimum time with bounded torques is bang-bang where no velocity limit holds: some control
    sits at its effort bound, and some joint rate at its velocity limit; the replay by forward
    simulation (IDAS, rtol 1e-10) of the piecewise-constant torques stays within 1e-4.
    """
    monkeypatch.setenv("CASMBD_COMPILE", "0")  # the virtual machine: no C compile in a test
    from casmbd.io.ocp_table import load_ocp

    root = pathlib.Path(__file__).resolve().parents[2]
    sol = load_ocp(root / "ocp" / "ur5_min_time.toml").solve()
    assert sol.success
    effort = {"tau_pan": 150.0, "tau_lift": 150.0, "tau_elbow": 150.0,
              "tau_w1": 28.0, "tau_w2": 28.0, "tau_w3": 28.0}
    margins = {name: effort[name] - np.max(np.abs(sol.control(name))) for name in effort}
    assert min(margins.values()) <= 1e-6, margins                 # a torque at its bound
    assert all(m >= -1e-6 for m in margins.values()), margins     # and the bounds hold
    rates = {"shoulder_pan_joint_dot": 3.15, "shoulder_lift_joint_dot": 3.15,
             "elbow_joint_dot": 3.15, "wrist_1_joint_dot": 3.2, "wrist_2_joint_dot": 3.2,
             "wrist_3_joint_dot": 3.2}
    vmargin = {name: lim - np.max(np.abs(sol.value(name))) for name, lim in rates.items()}
    assert all(m >= -1e-6 for m in vmargin.values()), vmargin
    assert min(vmargin.values()) <= 1e-6, vmargin                 # a rate at its limit
    # the end points and the final time lie inside their ranges, at rest
    assert 0.1 < sol.t[-1] - sol.t[0] < 5.0
    np.testing.assert_allclose(sol.v[[0, -1]], 0.0, atol=1e-8)
    sol.replay()
    assert sol.stats["replay_error"] <= 1e-4
