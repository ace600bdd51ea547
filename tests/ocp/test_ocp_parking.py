"""Parallel parking of a differential-drive robot (issue 37): ``ocp/parallel_parking.toml``.

A chassis on a planar joint, two driven wheels on revolute axles, a knife edge at the axle's
midpoint and two rolling rows (a ``velocity`` joint): three rows written at the velocity level,
two free velocities for five coordinates.  IPOPT solves the minimum-effort manoeuvre from the
linear guess (Radau collocation: the rolling rows are path constraints C_q q̇ + C_t = 0 at the
mesh nodes and C_q q̈ = γ at the collocation points); the optimal controls replayed by
``simulate`` (index-1 DAE on IDAS at rtol 1e-12, another formulation) end at the target and
keep the rows:

* replay end pose within 1e-6 m and 1e-6 rad of (−0.8, 0.6, 0) (replay_error measured
  1.6e-9);
* the rolling rows hold along the replay to 1e-8 m/s (measured 8.6e-11) and at every node
  of the solution to 1e-8 (the NLP's tolerance; measured 5e-12);
* the controls stay within ±0.15 N m and the wheel speeds within ±3 rad/s (1e-6), both
  bounds active in the optimum (0.15 and 3.0 reached to 2e-6);
* the robot turns to move sideways (|heading| > 0.1 rad on the way: a differential drive has
  no lateral velocity).
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from casmbd.compiled.build import compile_model
from casmbd.io.ocp_table import load_ocp
from casmbd.system.equations import System

OCP = pathlib.Path(__file__).resolve().parents[2] / "ocp" / "parallel_parking.toml"


@pytest.fixture(scope="module")
def parked():
    ocp = load_ocp(OCP)
    ocp.compile = False
    sol = ocp.solve()
    replay = sol.replay(rtol=1e-12)
    return ocp, sol, replay


def test_the_robot_parks_and_the_replay_ends_at_the_target(parked):
    _, sol, replay = parked
    assert sol.success
    chassis = replay.body("chassis")
    assert np.max(np.abs(chassis["position"][-1, :2] - [-0.8, 0.6])) <= 1e-6
    assert replay.names["coordinates"][2] == "base.angle"
    heading = replay["q"][:, 2]
    assert abs(heading[-1]) <= 1e-6
    assert np.max(np.abs(heading)) > 0.1  # it turns to move sideways
    assert sol.stats["replay_error"] <= 1e-6


def test_the_rolling_rows_hold(parked):
    ocp, sol, replay = parked
    assert np.max(np.abs(replay["velocity_violation"])) <= 1e-8
    model = compile_model(System(ocp.mechanism), "kinematics", mode="vm")
    assert len(model.velocity_rows) == 3 and model.holonomic_rows == []
    rows = [model.constraint_jacobian(q, t) @ v + model.constraint_time_derivative(q, t)
            for q, v, t in zip(sol.q, sol.v, sol.t, strict=True)]
    assert np.max(np.abs(rows)) <= 1e-8


def test_controls_and_wheel_speeds_within_bounds(parked):
    sol = parked[1]
    for name in ("tau_l", "tau_r"):
        assert 0.15 - 1e-5 <= np.max(np.abs(sol.control(name))) <= 0.15 + 1e-6
    speeds = np.abs(sol.v[:, 3:5])
    assert 3.0 - 1e-3 <= np.max(speeds) <= 3.0 + 1e-6
