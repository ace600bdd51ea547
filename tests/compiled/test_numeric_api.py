"""The per-call numeric API (``casmbd.compile``, casmbd/compiled/robot.py) against the existing
analyses and independent routes, on the UR5-like arm (tests/scenes/ur_like.toml, spatial 6R)
and the planar double pendulum (examples/double_pendulum.toml), in joint coordinates.

* forward dynamics at τ = 0 against the articulated-body right-hand side that ``simulate``
  integrates (1e-12 relative);
* M against the polarisation of the kinetic energy T(q, v) (casmbd's recursive-twist
  formula, not the Kane/CRBA mass matrix): M_ij = T(e_i + e_j) − T(e_i) − T(e_j), exact for
  a quadratic form (1e-12 relative);
* b(q, 0) against ∂V/∂q and b(q, v) − b(q, 0) against Lagrange's Ṁ v − ∂T/∂q, both by central
  differences (1e-6 relative);
* inverse dynamics: τ = M a + b against forward dynamics (round trip, 1e-12) and against the
  driver efforts of ``casmbd.inverse_dynamics`` with every joint driven (1e-12);
* forward kinematics against the ``outputs`` Function of the analyses, the Jacobian against
  central differences of forward kinematics (1e-7);
* batch == a loop of single calls (1e-14), over more samples than one chunk;
* a closed chain (four-bar): forward dynamics by the KKT system satisfies C_q q̈ = γ and
  M q̈ + b − τ ∈ range(C_qᵀ); inverse dynamics with the crank actuated gives the torque and the
  loop multipliers (round trip 1e-10, against ``casmbd.inverse_dynamics`` with a crank driver
  1e-9), with every coordinate actuated the least-norm effort (C_q τ = 0).
"""

from __future__ import annotations

import pathlib

import casadi as ca
import numpy as np
import pytest

import casmbd
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.compiled.robot import BATCH_CHUNK
from casmbd.errors import ModelError
from casmbd.system import System

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENES = {"ur_like": ROOT / "tests" / "scenes" / "ur_like.toml",
          "double_pendulum": ROOT / "examples" / "double_pendulum.toml"}


def _mechanism(name: str):
    mech = casmbd.load_scene(SCENES[name])
    mech.coordinates = "joint"
    if name == "ur_like":
        mech.add_marker("tool", "wrist_3", [-0.81725, -0.25, 0.02])
        mech.add_marker("base", "ground", [0.1, 0.2, 0.0])  # constant pose: structural zeros
        mech.add_marker("flange", "wrist_3", [-0.81725, -0.19, 0.0], euler_zxz=(0.3, 1.1, -0.4))
    else:
        mech.add_marker("turned", "rod2", [1.0, 0.0], angle=0.7)  # a frame turned against its body
    return mech


@pytest.fixture(scope="module", params=sorted(SCENES))
def case(request):
    mech = _mechanism(request.param)
    model = casmbd.compile(mech)
    system = System(_mechanism(request.param), coordinates="joint")
    return request.param, mech, model, system


def _state(model, seed=0):
    rng = np.random.default_rng(seed)
    n = model.nq
    return rng.uniform(-1.5, 1.5, n), rng.uniform(-2.0, 2.0, n), rng.uniform(-5.0, 5.0, n)


def _rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(1.0, np.max(np.abs(b))))


def test_forward_dynamics_matches_simulate_rhs(case):
    _, mech, model, _ = case
    sim = Simulator(mech, "articulated")
    p = np.asarray(sim.model.p, dtype=float)
    for seed in range(3):
        q, v, _ = _state(model, seed)
        args = [np.zeros(sim.dyn.nnz_in(i)) for i in range(sim.dyn.n_in())]
        args[1][:] = np.concatenate([q, v])
        args[3][:] = p
        rhs = np.asarray(sim.dyn.call([ca.DM(a) for a in args])[0]).ravel()
        assert _rel(model.forward_dynamics(q, v, np.zeros(model.nq)), rhs[model.nq:]) < 1e-12


def test_mass_matrix_against_kinetic_energy(case):
    _, _, model, system = case
    energy = system.function("kinetic_energy")
    p = system.parameter_values
    q, _, _ = _state(model, 1)
    n, eye = model.nq, np.eye(model.nq)

    def kin(v):
        return float(energy(q, v, p))

    ref = np.array([[kin(eye[i] + eye[j]) - kin(eye[i]) - kin(eye[j]) if i != j
                     else 2.0 * kin(eye[i]) for j in range(n)] for i in range(n)])
    m = model.mass_matrix(q)
    assert _rel(m, ref) < 1e-12
    assert np.array_equal(m, m.T)


def test_bias_forces_against_lagrange(case):
    _, _, model, system = case
    kin, pot = system.function("kinetic_energy"), system.function("potential_energy")
    p = system.parameter_values
    q, v, _ = _state(model, 2)
    n, h, eye = model.nq, 1e-5, np.eye(model.nq)
    grad_v = np.array([(float(pot(q + h * e, 0.0, p)) - float(pot(q - h * e, 0.0, p))) / (2 * h)
                       for e in eye])
    b0 = model.bias_forces(q, np.zeros(n))
    assert _rel(b0, grad_v) < 1e-6
    m_dot = (model.mass_matrix(q + h * v) - model.mass_matrix(q - h * v)) / (2 * h)
    grad_t = np.array([(float(kin(q + h * e, v, p)) - float(kin(q - h * e, v, p))) / (2 * h)
                       for e in eye])
    assert _rel(model.bias_forces(q, v) - b0, m_dot @ v - grad_t) < 1e-6


def test_inverse_dynamics_round_trip(case):
    _, _, model, _ = case
    for seed in range(3):
        q, v, tau = _state(model, seed)
        a = model.forward_dynamics(q, v, tau)
        assert _rel(model.inverse_dynamics(q, v, a), tau) < 1e-12
        assert _rel(model.mass_matrix(q) @ a + model.bias_forces(q, v), tau) < 1e-12


def test_inverse_dynamics_matches_driven_analysis():
    """``casmbd.inverse_dynamics`` with a driver on every joint: its driver efforts are the
    joint torques τ along the prescribed motion (Lagrange multipliers of C_q, KKT route)."""
    arm = casmbd.compile(_mechanism("ur_like"))
    driven = casmbd.load_scene(SCENES["ur_like"])
    driven.coordinates = "joint"
    for k, joint in enumerate(driven.joints):
        driven.add_driver(f"d_{joint}", joint=joint, position=f"{0.2 * (k + 1)}*sin({k + 1}*t)")
    res = casmbd.inverse_dynamics(driven, t_end=1.0, steps=10)
    efforts = res["driver_efforts"]
    assert _rel(arm.inverse_dynamics_batch(res["q"], res["v"], res["a"]), efforts) < 1e-12
    assert _rel(arm.forward_dynamics_batch(res["q"], res["v"], efforts), res["a"]) < 1e-12


def test_forward_kinematics_against_outputs(case):
    _, mech, model, system = case
    q, _, _ = _state(model, 3)
    pos, rot = model.forward_kinematics(q)
    out = system.outputs_function()
    res = dict(zip(out.name_out(), out(q, np.zeros(model.nq), np.zeros(model.nq), 0.0,
                                       system.parameter_values)))
    nb, d = len(system.body_names), model.dimension
    assert model.frame_names == list(system.body_names) + list(mech.markers)
    assert _rel(pos[:nb].ravel(), np.asarray(res["body_positions"]).ravel()) < 1e-14
    assert _rel(pos[nb:].ravel(), np.asarray(res["marker_positions"]).ravel()) < 1e-14
    for k in range(len(model.frame_names)):
        assert _rel(rot[k] @ rot[k].T, np.eye(d)) < 1e-13
    if d == 3:
        assert _rel(rot[:nb].ravel(), np.asarray(res["rotation_matrices"]).ravel()) < 1e-14
        # marker frames: the body's axes times the marker's own orientation offset
        assert _rel(rot[nb:].ravel(), np.asarray(res["marker_rotations"]).ravel()) < 1e-14
    else:
        angles = np.asarray(res["angle_positions"]).ravel()
        assert _rel(rot[:nb, 1, 0], np.sin(angles)) < 1e-14
        marker = np.asarray(res["marker_angles"]).ravel()
        assert _rel(rot[nb:, 1, 0], np.sin(marker)) < 1e-14
        assert _rel(rot[nb:, 0, 0], np.cos(marker)) < 1e-14


def test_jacobian_against_finite_differences(case):
    _, _, model, _ = case
    q, _, _ = _state(model, 4)
    h, d = 1e-6, model.dimension
    for k, frame in enumerate(model.frame_names):
        jac = model.jacobian(q, frame)
        assert jac.shape == ((6 if d == 3 else 3), model.nq)
        cols = []
        for e in np.eye(model.nq):
            (pp, rp), (pm, rm) = model.forward_kinematics(q + h * e), model.forward_kinematics(
                q - h * e)
            lin = (pp[k] - pm[k]) / (2 * h)
            spin = (rp[k] - rm[k]) / (2 * h) @ model.forward_kinematics(q)[1][k].T
            ang = [spin[2, 1], spin[0, 2], spin[1, 0]] if d == 3 else [spin[1, 0]]
            cols.append(np.concatenate([lin, ang]))
        assert np.max(np.abs(jac - np.column_stack(cols))) < 1e-7, frame


def test_batch_equals_loop(case):
    _, _, model, _ = case
    n = BATCH_CHUNK + 7
    rng = np.random.default_rng(5)
    qs, vs, taus = (rng.uniform(-1.0, 1.0, (n, model.nq)) for _ in range(3))
    acc = model.forward_dynamics_batch(qs, vs, taus)
    loop = np.array([model.forward_dynamics(*s) for s in zip(qs, vs, taus)])
    assert acc.shape == (n, model.nq) and np.max(np.abs(acc - loop)) <= 1e-14 * np.max(
        np.abs(loop))
    tau = model.inverse_dynamics_batch(qs, vs, acc)
    loop = np.array([model.inverse_dynamics(*s) for s in zip(qs, vs, acc)])
    assert np.max(np.abs(tau - loop)) <= 1e-14 * np.max(np.abs(loop))
    assert _rel(tau, taus) < 1e-12


def test_results_are_copies_and_errors_are_named(case):
    _, _, model, _ = case
    q, v, tau = _state(model, 6)
    a1 = model.forward_dynamics(q, v, tau)
    keep = a1.copy()
    a1[:] = 1e9
    assert np.array_equal(model.forward_dynamics(q, v, tau), keep)
    m1 = model.mass_matrix(q)
    m2 = model.mass_matrix(q + 0.1)
    assert not np.shares_memory(m1, m2) and not np.array_equal(m1, m2)
    with pytest.raises(ModelError, match="unknown frame 'nowhere'"):
        model.jacobian(q, "nowhere")
    with pytest.raises(ModelError, match="n_q"):
        model.forward_dynamics(q[:-1], v, tau)
    with pytest.raises(ModelError, match="shape"):
        model.forward_dynamics_batch(q[None, :-1], v[None, :-1], tau[None, :-1])


def test_parameters_apply_without_rebuild():
    mech = _mechanism("double_pendulum")
    model = casmbd.compile(mech)
    q, _, _ = _state(model, 7)
    m1 = model.mass_matrix(q)
    model.numeric.set_parameters(m=2.0)
    assert _rel(model.mass_matrix(q), 2.0 * m1) < 1e-14


def test_closed_chain_kkt():
    mech = casmbd.load_scene(ROOT / "examples" / "four_bar.toml")
    model = casmbd.compile(mech)
    assert model.nc > 0
    numeric = casmbd.NumericModel(System(mech, coordinates="joint"), "dynamics", mode="vm")
    q = casmbd.assemble(numeric, numeric.initial_coordinates(), 0.0).q
    v = casmbd.velocities(numeric, q, 0.0, v_guess=np.ones(model.nq))
    tau = np.random.default_rng(8).uniform(-1.0, 1.0, model.nq)
    a = model.forward_dynamics(q, v, tau)
    cq = numeric.constraint_jacobian(q, 0.0).toarray()
    assert _rel(cq @ a, numeric.acceleration_rhs(q, v, 0.0)) < 1e-10
    resid = model.mass_matrix(q) @ a + model.bias_forces(q, v) - tau
    lam = np.linalg.lstsq(cq.T, resid, rcond=None)[0]
    assert _rel(cq.T @ lam, resid) < 1e-10


def _four_bar_free():
    """The four-bar of examples/four_bar.toml without its crank driver (one degree of
    freedom, two loop-closure equations of joint C in joint coordinates)."""
    mech = casmbd.load_scene(ROOT / "examples" / "four_bar.toml")
    mech.drivers.clear()
    mech.coordinates = "joint"
    return mech


def _four_bar_state(model, seed=3):
    numeric = casmbd.NumericModel(System(_four_bar_free(), coordinates="joint"), "dynamics",
                                  mode="vm")
    q = casmbd.assemble(numeric, numeric.initial_coordinates(), 0.0).q
    rng = np.random.default_rng(seed)
    v = casmbd.velocities(numeric, q, 0.0, v_guess=rng.uniform(-2.0, 2.0, model.nq))
    return numeric, q, v


def test_closed_chain_inverse_dynamics_with_an_actuated_crank():
    """``[S −C_qᵀ] [τ_a; λ] = M a + b`` with the crank actuated: the round trip through the
    KKT forward dynamics returns the applied torque (1e-10) and the multipliers balance the
    equations of motion; against ``casmbd.inverse_dynamics`` with a driver on the crank (seed
    000's route: driver multipliers of the kinematically driven machine), 1e-9."""
    model = casmbd.compile(_four_bar_free(), actuated=["A.angle"])
    assert (model.nq, model.nc) == (3, 2)
    numeric, q, v = _four_bar_state(model)
    tau_in = np.array([0.7, 0.0, 0.0])
    a = model.forward_dynamics(q, v, tau_in)
    tau, lam = model.inverse_dynamics(q, v, a, return_multipliers=True)
    assert _rel(tau, tau_in) < 1e-10
    cq = numeric.constraint_jacobian(q, 0.0).toarray()
    lhs = model.mass_matrix(q) @ a + model.bias_forces(q, v) + cq.T @ lam
    assert _rel(lhs, tau) < 1e-10 and lam.shape == (2,)
    driven = _four_bar_free()
    driven.add_driver("crank", joint="A", position="0.4 + 3 * t + 2 * t**2")
    res = casmbd.inverse_dynamics(driven, t_end=0.5, steps=5)
    ours = model.inverse_dynamics_batch(res["q"], res["v"], res["a"])
    assert np.allclose(ours[:, 1:], 0.0, atol=0.0)
    assert _rel(ours[:, 0], res["driver_efforts"][:, 0]) < 1e-9


def test_closed_chain_least_norm_efforts_and_named_errors():
    """Every coordinate actuated (the default): τ is the least-norm effort, orthogonal to the
    constraint forces (C_q τ = 0) and it reproduces a through forward dynamics; inconsistent
    accelerations and an actuation that cannot move the loop raise ModelErrors that name the
    equation or the coordinates."""
    model = casmbd.compile(_four_bar_free())
    numeric, q, v = _four_bar_state(model, seed=5)
    a = model.forward_dynamics(q, v, np.array([0.3, -0.2, 0.5]))
    tau = model.inverse_dynamics(q, v, a)
    cq = numeric.constraint_jacobian(q, 0.0).toarray()
    assert np.max(np.abs(cq @ tau)) < 1e-10 * max(1.0, np.max(np.abs(tau)))
    assert _rel(model.forward_dynamics(q, v, tau), a) < 1e-10
    with pytest.raises(ModelError, match="joint 'C' equation"):
        model.inverse_dynamics(q, v, a + np.array([1.0, 0.0, 0.0]))
    over = casmbd.compile(_four_bar_free(), actuated=["A.angle", "B.angle", "D.angle"][:2])
    with pytest.raises(ModelError, match="not unique"):
        over.inverse_dynamics(q, v, a)
    with pytest.raises(ModelError, match=r"actuated coordinate 'E\.angle' unknown"):
        casmbd.compile(_four_bar_free(), actuated=["E.angle"], mode="vm")
