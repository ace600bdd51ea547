"""The excitation-trajectory design (casmbd.ocp.excitation): periodic Fourier series that
minimise the conditioning of the stacked base regressor under joint limits.

Numbers checked: the series' velocity and acceleration are the time derivatives of its position
(central differences, 1e-7); periodicity q, q̇, q̈ (T) = (0) to 1e-12; the optimised trajectory's
κ(W) at least 1.5× below two random feasible ones' on a planar 2R arm (observed 1.9×) and 3× below
on the UR-type arm (observed 7×), and every limit held at the constraint samples to 1e-8; torque
limits held at the regressor samples to 1e-8; the start-at-rest conditions to 1e-10; a start that
cannot excite every column is refused by name. The regressor is the Lagrangian one of
tests/excitation_regressor.py, itself checked against casmbd's inverse dynamics (Y π = τ, 1e-12
relative) and against the Newton–Euler ``joint_torque_regressor`` (the same columns by name, 1e-12
relative; observed 7e-15).
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from excitation_regressor import lagrangian_regressor

import casmbd
from casmbd import Mechanism
from casmbd.analysis.identification.regressor import joint_torque_regressor
from casmbd.errors import ModelError
from casmbd.io.scene import load_scene
from casmbd.ocp.excitation import (
    FourierTrajectory,
    base_columns,
    condition_number,
    design_excitation,
    random_feasible,
)

SCENES = pathlib.Path(__file__).resolve().parents[1] / "scenes"
LIMIT_TOL = 1e-8


def arm_2r() -> Mechanism:
    m = Mechanism("arm_2r", gravity=(0.0, -9.81), coordinates="joint")
    m.add_body("l1", mass=2.0, inertia=0.1, position=(0.5, 0.0))
    m.add_body("l2", mass=1.0, inertia=0.05, position=(1.4, 0.0))
    m.add_revolute("j1", "ground", "l1", point=(0.0, 0.0))
    m.add_revolute("j2", "l1", "l2", point=(1.0, 0.0))
    m.add("joint_friction", "f1", "j1", damping=0.3, friction=0.2)
    m.add("joint_friction", "f2", "j2", damping=0.1, friction=0.1)
    return m


@pytest.fixture(scope="module")
def planar():
    mech = arm_2r()
    y, _names, pi = lagrangian_regressor(mech, joints=["j1", "j2"])
    pi[-4:] = [0.3, 0.2, 0.1, 0.1]
    return mech, y, pi


@pytest.fixture(scope="module")
def ur():
    mech = load_scene(SCENES / "ur_like.toml")
    y, _names, pi = lagrangian_regressor(mech, joints=list(mech.joints))
    return mech, y, pi


@pytest.mark.parametrize("which", ["planar", "ur"])
def test_helper_regressor_is_inverse_dynamics(which, request):
    mech, y, pi = request.getfixturevalue(which)
    model = casmbd.compile(mech, mode="vm")
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, v, a = rng.normal(size=(3, model.nq))
        tau = model.inverse_dynamics(q, v, a)
        assert np.max(np.abs(np.array(y(q, v, a)) @ pi - tau)) <= 1e-12 * np.max(np.abs(tau))


@pytest.mark.parametrize("which", ["planar", "ur"])
def test_helper_regressor_equals_joint_torque_regressor(which, request):
    # two formulations of the same Y: Lagrange (this helper) and Newton–Euler by virtual power
    # (casmbd.analysis.identification.regressor), columns matched by name
    mech, y, _ = request.getfixturevalue(which)
    names = lagrangian_regressor(mech, joints=list(mech.joints))[1]
    reg = joint_torque_regressor(mech, ("viscous", "coulomb"), mode="vm")
    columns = [reg.names.index(name) for name in names]
    assert len(columns) == len(reg.names)
    rng = np.random.default_rng(4)
    for _ in range(3):
        q, v, a = rng.normal(size=(3, reg.nq))
        ours = np.array(y(q, v, a))
        assert np.max(np.abs(reg(q, v, a)[:, columns] - ours)) <= 1e-12 * np.max(np.abs(ours))


def test_series_derivatives_and_periodicity():
    rng = np.random.default_rng(2)
    traj = FourierTrajectory(2.5, rng.normal(size=3), rng.normal(size=(3, 4)),
                             rng.normal(size=(3, 4)))
    t, h = np.array([0.3, 1.1, 2.0]), 1e-5
    qp, vp, _ = traj.evaluate(t + h)
    qm, vm, _ = traj.evaluate(t - h)
    _, v, acc = traj.evaluate(t)
    assert np.max(np.abs((qp - qm) / (2 * h) - v)) < 1e-7
    assert np.max(np.abs((vp - vm) / (2 * h) - acc)) < 1e-7
    for x0, x1 in zip(traj.evaluate([0.0]), traj.evaluate([traj.period])):
        assert np.max(np.abs(x1 - x0)) <= 1e-12
    x = traj.vector
    again = FourierTrajectory.from_vector(x, 3, 4, 2.5)
    assert np.array_equal(again.a, traj.a) and np.array_equal(again.b, traj.b)


def _check_limits(design, lower, upper, velocity, acceleration):
    q, v, a = design.trajectory.evaluate(design.constraint_times)
    assert np.all(q >= lower - LIMIT_TOL) and np.all(q <= upper + LIMIT_TOL)
    assert np.all(np.abs(v) <= velocity + LIMIT_TOL)
    assert np.all(np.abs(a) <= acceleration + LIMIT_TOL)
    for x0, x1 in zip(design.trajectory.evaluate([0.0]),
                      design.trajectory.evaluate([design.trajectory.period])):
        assert np.max(np.abs(x1 - x0)) <= 1e-12


def test_design_planar_2r(planar):
    _, y, _ = planar
    lower, upper = np.array([-2.0, -2.5]), np.array([2.0, 2.5])
    design = design_excitation(y, period=5.0, harmonics=3, samples=30, lower=lower,
                               upper=upper, velocity=2.0, acceleration=6.0, max_iter=40)
    # 3 per link (m cx, m cy, Izz with the masses grouped in) + 4 friction (Khalil & Dombre)
    assert design.columns.size == 10
    # the baseline: the random feasible start, and another random feasible trajectory
    other = random_feasible(2, 3, 5.0, lower=lower, upper=upper, velocity=2.0,
                            acceleration=6.0, seed=7)
    other_k = condition_number(y, other, 30, design.columns)
    # the 2R arm's κ is bounded below by the spread of its columns (friction ~1 against
    # gravity ~10 at these limits): 58 and 55 at random, 30 optimised (27 after 200 iterations)
    assert design.condition * 1.5 <= min(design.initial_condition, other_k)
    _check_limits(design, lower, upper, 2.0, 6.0)


def test_design_ur_arm(ur):
    _, y, _ = ur
    columns = base_columns(y, 6)
    assert columns.size == 48  # 36 grouped inertial + 12 friction
    design = design_excitation(y, period=10.0, harmonics=3, samples=30, lower=-math.pi,
                               upper=math.pi, velocity=2.0, acceleration=4.0,
                               columns=columns, max_iter=30)
    assert design.condition * 3.0 <= design.initial_condition
    _check_limits(design, -math.pi, math.pi, 2.0, 4.0)


def test_design_torque_limits_and_rest_start(planar):
    _, y, pi = planar
    tau_max = np.array([25.0, 6.0])
    design = design_excitation(y, period=5.0, harmonics=3, samples=30, lower=-2.0, upper=2.0,
                               velocity=2.0, acceleration=6.0, torque=(pi, tau_max),
                               start_at_rest=True, start=[0.1, -0.2], max_iter=40)
    traj = design.trajectory
    q, v, a = traj.evaluate(traj.samples(design.samples))
    tau = np.array([np.array(y(q[k], v[k], a[k])) @ pi for k in range(len(q))])
    assert np.all(np.abs(tau) <= tau_max + LIMIT_TOL)
    q0, v0, a0 = traj.evaluate([0.0])
    assert np.max(np.abs(v0)) <= 1e-10 and np.max(np.abs(a0)) <= 1e-10
    assert np.max(np.abs(q0 - [0.1, -0.2])) <= 1e-10
    _check_limits(design, -2.0, 2.0, 2.0, 6.0)


def test_bad_limits_are_refused(planar):
    _, y, _ = planar
    with pytest.raises(ModelError, match=r"joint 1: 'lower' 2\.0 is not below 'upper' 1\.0"):
        design_excitation(y, period=1.0, lower=[-1.0, 2.0], upper=[1.0, 1.0])
    with pytest.raises(ModelError, match="joint 0 has no finite limit"):
        design_excitation(y, period=1.0)
    # every column of Y, the dependent ones included: A is singular at any trajectory
    with pytest.raises(ModelError, match=r"does not excite every one of the 12 base"):
        design_excitation(y, period=1.0, lower=-1.0, upper=1.0, columns=np.arange(12))
    with pytest.raises(ModelError, match="'period': must be > 0"):
        FourierTrajectory(0.0, [0.0], [[1.0]], [[1.0]])


def test_limits_hold_between_the_imposed_instants(planar):
    """The exchange method: imposed at 6 instants per period of the highest harmonic, checked
    on 40 — every limit holds on that check grid to 1e-8 (relative to the limit), and on a grid
    ten times finer within the stated 1 − cos(π/40) ≈ 0.31 % of the range (the series' excess
    between check instants), where the first grid alone leaves up to 1 − cos(π/6) ≈ 13 %."""
    from casmbd.ocp.excitation import CHECK_PER_HARMONIC

    _, y, _ = planar
    lower, upper = np.array([-2.0, -2.5]), np.array([2.0, 2.5])
    velocity, acceleration = 2.0, 6.0
    design = design_excitation(y, period=5.0, harmonics=3, samples=30, lower=lower,
                               upper=upper, velocity=velocity, acceleration=acceleration,
                               max_iter=40)
    traj = design.trajectory
    for count, tol in ((CHECK_PER_HARMONIC * 3, 1e-8), (10 * CHECK_PER_HARMONIC * 3, 3.1e-3)):
        q, v, a = traj.evaluate(traj.samples(count))
        assert np.all(q >= lower - tol * (upper - lower))
        assert np.all(q <= upper + tol * (upper - lower))
        assert np.all(np.abs(v) <= velocity * (1 + tol))
        assert np.all(np.abs(a) <= acceleration * (1 + tol))
    assert design.stats["exchange_rounds"] >= 1
    assert design.constraint_times.size >= 6 * 3
