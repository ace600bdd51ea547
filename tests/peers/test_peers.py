"""Peer models of benchmarks/peers.py against the independent references (numbers, no timings).

Each peer test runs only when the peer is installed (``pip install casmbd[bench]``); the
bounds are a few times the errors measured with Exudyn 1.13.6 and MuJoCo 4.0.0 (quoted per
test), so a modelling mismatch (axis sign, inertia, initial angle: errors of order 0.1-1) fails.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import peers
from benchmarks.references import chain_mass_matrix, chain_rhs


def test_best_peer_time_interpolates_log_log_and_takes_the_fastest_method():
    # the fair rule (benchmarks.fair.time_to_error), the same for casmbd and the peers:
    # each method's time at the level interpolated log-log between its sweep points around
    # it; MuJoCo at 1e-6: halfway in log error between (1e-4, 1 ms) and (1e-8, 10 ms), so
    # 10^0.5 ms = 3.162 ms, faster than Exudyn's single point (1e-7, 5 ms)
    rows = [
        {"problem": "p", "formulation": "mujoco", "integrator": "rk4", "status": "ok",
         "step": h, "tolerance": "", "error": e, "solve_seconds": s}
        for h, e, s in [(1e-2, 1e-4, 1e-3), (1e-3, 1e-8, 1e-2)]
    ] + [{"problem": "p", "formulation": "exudyn_kinematictree", "integrator": "dopri5",
          "status": "ok", "step": "", "tolerance": 1e-6, "error": 1e-7, "solve_seconds": 5e-3}]
    seconds, name = peers.best_peer_time(rows, "p", 1e-6)
    assert name == "MuJoCo RK4" and seconds == pytest.approx(10**-2.5, rel=1e-12)
    assert peers.best_peer_time(rows, "p", 1e-4) == (1e-3, "MuJoCo RK4")
    seconds, name = peers.best_peer_time(rows, "p", 1e-8)
    assert name == "MuJoCo RK4" and seconds == pytest.approx(1e-2, rel=1e-12)
    assert peers.best_peer_time(rows, "p", 1e-12) is None


def test_mujoco_chain_equations_match_reference():
    # MuJoCo's mass matrix and accelerations of the 4-rod chain at a random state against the
    # hand-derived absolute-angle equations of benchmarks.references (φ = T q, T lower
    # triangular ones: M_q = Tᵀ M_φ T, q̈ = T⁻¹ φ̈); agreement to 1e-12
    mujoco = pytest.importorskip("mujoco")
    n = 4
    model = mujoco.MjModel.from_xml_string(peers.mujoco_chain_xml(n, "RK4", 1e-3))
    peers.check_mujoco_model(model)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    data.qpos[:] = rng.uniform(-2.0, 2.0, n)
    data.qvel[:] = rng.uniform(-2.0, 2.0, n)
    mujoco.mj_forward(model, data)
    t = np.tril(np.ones((n, n)))
    y = np.concatenate([t @ data.qpos, t @ data.qvel])
    phi_ddot = chain_rhs(n)(0.0, y)[n:]
    full = np.zeros((n, n))
    try:  # MuJoCo 4: mj_fullM(m, d, dst); MuJoCo 3: mj_fullM(m, dst, d.qM)
        mujoco.mj_fullM(model, data, full)
    except TypeError:
        mujoco.mj_fullM(model, full, data.qM)
    assert np.allclose(full, t.T @ chain_mass_matrix(y[:n]) @ t, rtol=0.0, atol=1e-12)
    assert np.allclose(data.qacc, np.linalg.solve(t, phi_ddot), rtol=0.0, atol=1e-11)


def test_mujoco_model_check_rejects_wrong_inertia():
    # a rod inertia of 1/3 (about the end, not the centre) must be caught
    mujoco = pytest.importorskip("mujoco")
    xml = peers.mujoco_chain_xml(2).replace(repr(1.0 / 12.0), repr(1.0 / 3.0))
    with pytest.raises(RuntimeError, match="inertia"):
        peers.check_mujoco_model(mujoco.MjModel.from_xml_string(xml))


def test_mujoco_chain2_tip_error():
    # RK4, h = 1.25e-3: measured tip error 6.1e-10 at t = 2; implicitfast is first order:
    # 2.46e-3 at h = 1e-3 and 2.45e-4 at h = 1e-4 (ratio 10 for a tenfold step)
    pytest.importorskip("mujoco")
    (rk4,) = peers.mujoco_run("chain2", "rk4", levels=[1.25e-3], repeat=1)
    assert rk4["status"] == "ok" and rk4["error"] < 1e-8
    coarse, fine = peers.mujoco_run("chain2", "implicitfast", levels=[1e-3, 1e-4], repeat=1)
    assert fine["error"] < 5e-4
    assert 8.0 < coarse["error"] / fine["error"] < 12.0


def test_mujoco_fourbar_stiffened_constraint():
    # implicitfast with the stiffened connect, h = 1e-4: measured crank-angle error 3.6e-7 at
    # t = 10 (through ten collinear passes) and a gap of 1.1e-11 at the end, 7e-11 at most
    pytest.importorskip("mujoco")
    (row,) = peers.mujoco_run("fourbar", "implicitfast", stiff=True, levels=[1e-4], repeat=1)
    assert row["status"] == "ok"
    assert row["error"] < 1e-6
    assert row["drift"] < 1e-10 and row["drift_max"] < 1e-9


def test_exudyn_chain2_tip_error():
    # generalized-α (redundant coordinates), h = 1e-4: measured 1.10e-6 (second order: 1.1e-4
    # at h = 1e-3), joint gaps at round-off; KinematicTree DOPRI5 at tol 1e-10: 1.5e-10,
    # RK44 at h = 1.25e-3: 6.1e-10
    pytest.importorskip("exudyn")
    (ga,) = peers.exudyn_generalized_alpha("chain2", levels=[1e-4], repeat=1)
    assert ga["status"] == "ok" and ga["error"] < 3e-6
    assert ga["drift"] < 1e-10
    (dopri,) = peers.exudyn_tree("chain2", "dopri5", levels=[1e-10], repeat=1)
    assert dopri["status"] == "ok" and dopri["error"] < 1e-8
    (rk,) = peers.exudyn_tree("chain2", "rk44", levels=[1.25e-3], repeat=1)
    assert rk["status"] == "ok" and rk["error"] < 1e-8


def test_exudyn_fourbar_generalized_alpha():
    # h = 1e-3: measured crank-angle error 6.0e-5 at t = 10 (parallelogram branch kept through
    # the ten collinear passes), joint gaps at round-off
    pytest.importorskip("exudyn")
    (row,) = peers.exudyn_generalized_alpha("fourbar", levels=[1e-3], repeat=1)
    assert row["status"] == "ok" and row["error"] < 1.5e-4
    assert row["drift"] < 1e-10


@pytest.mark.parametrize("spatial", [False, True])
def test_pinocchio_aba_gives_casmbd_accelerations(spatial):
    """benchmarks/pinocchio_aba.py first checks that Pinocchio's ABA and casmbd's compiled
    articulated right-hand side give the same accelerations of the 8-rod chain at a random
    state (relative 1e-9; measured 1e-15): the timed computations are the same."""
    pytest.importorskip("pinocchio")
    from benchmarks.pinocchio_aba import measure

    r = measure(8, spatial)
    assert r["accel_rel_diff"] < 1e-9
