"""Trajectory optimisation with a flexible body (issue 23): a hub-driven beam's rest-to-rest slew.

The beam (10 m, EI = 1.4e4 N m², ρA = 1.2 kg/m, 6 elements, two Craig–Bampton modes) turns
about a revolute joint at its root node, driven by a torque; minimum effort
w ∫ τ² dt, θ: 0 → 0.5 rad in T = 4 s, at rest with the modal coordinates zero at both ends.

References and measured figures (``python -m pytest -q tests/ocp/test_ocp_flexible.py``, virtual
machine and compiled):

* **The fastest mode** of the linearised mechanism, against a hand-assembled lumped model
  (hub angle + modal coordinates; masses and rotary inertias at the nodes): 71.872 rad/s
  pinned, 22.110 rad/s clamped (the fixed-interface modes under the lumped modal mass),
  equal to 1e-12.
* **The rigid closed form.**  A rigid body of the same inertia about the hub
  (J = Σ m_i x_i² + Σ J_i = 408.33 kg m²) has the minimum-effort rest-to-rest torque
  τ(t) = J (12 θ_f / T³)(T/2 − t) (min ∫ τ² dt for J θ̈ = τ with θ, θ̇ given at both ends: the
  costate equations make τ linear in t, the four end conditions fix it) and the effort
  12 J² θ_f² / T³.  The rigid OCP meets both to 1e-3 (piecewise-constant controls: measured
  6e-4).  The flexible beam's optimal torque stays within 15 % of τ_r(0) of that line
  (measured 10.1 %: the correction that leaves no residual vibration), its effort within
  +3 % (measured +1.03 %).
* **The replay** (the optimal controls simulated): 8.4e-4 with 8 collocation elements per
  interval (ω_max h = 0.90); the modal coordinates at the end ≤ 1e-5, their rates ≤ 5e-4.
* **The problem as first posed** (one element per interval, ω_max h = 7.2) stalled in IPOPT
  for thousands of iterations (dual infeasibility 1.82e-5): MUMPS's pivot tolerance
  (:data:`casmbd.ocp.flexible_mesh.FLEXIBLE_MUMPS_PIVTOL`) now lets it converge in 8 iterations,
  and the transcription warns that the mesh does not resolve the 72 rad/s mode — its replay
  is 17 off.
"""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np
import pytest
import scipy.linalg

import casmbd
from casmbd.ocp import Ocp
from casmbd.ocp.flexible_mesh import FLEXIBLE_MUMPS_PIVTOL, fastest_mode, solver_defaults
from casmbd.system.equations import System

SCENE = """
[scene]
name = "slew"
dimension = 2
gravity = [0.0, 0.0]

[[bodies]]
name = "beam"
type = "flexible"
position = [0.0, 0.0]
modes = 2
reduction = "craig_bampton"
interfaces = ["root"]
stiffening = false
[bodies.beam]
length = 10.0
elements = 6
EI = 1.4e4
EA = 2.8e7
rhoA = 1.2
nodes = { root = 0.0, tip = 10.0 }

[[joints]]
name = "hub"
type = "JOINT"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0]
"""

ACTUATOR = """
[[actuators]]
name = "tau"
joint = "hub"
"""

RIGID = """
[scene]
name = "slew_rigid"
dimension = 2
gravity = [0.0, 0.0]

[[bodies]]
name = "beam"
mass = 12.0
inertia = {inertia}
position = [5.0, 0.0]

[[joints]]
name = "hub"
type = "revolute"
body1 = "ground"
body2 = "beam"
point = [0.0, 0.0]
""" + ACTUATOR

T, THETA_F, WEIGHT = 4.0, 0.5, 1e-4
MODAL = ("beam_eta1", "beam_eta2", "beam_eta1_dot", "beam_eta2_dot")


def _beam(joint: str = "revolute", actuated: bool = True):
    return casmbd.loads_scene(SCENE.replace("JOINT", joint) + (ACTUATOR if actuated else ""))


def _slew(mech, subintervals: int, flexible: bool = True) -> Ocp:
    ocp = Ocp(mech, horizon=T, intervals=40, subintervals=subintervals)
    ocp.control_bounds("tau", -500, 500)
    rest = dict.fromkeys(MODAL, 0.0) if flexible else {}
    ocp.initial(hub=0, hub_dot=0, **rest)
    ocp.final(hub=THETA_F, hub_dot=0, **rest)
    return ocp.minimize("effort", weight=WEIGHT)


def _lumped(mech) -> tuple[float, np.ndarray, np.ndarray]:
    """(J about the root, M, K) of the lumped model in (θ, η), assembled from the modal data."""
    md = mech.bodies["beam"].modal
    x = np.asarray(md.positions, float)
    m, jn = np.asarray(md.masses, float), np.asarray(md.inertias, float)
    phi, psi = np.asarray(md.phi_t, float), np.asarray(md.phi_r, float)
    j_hub = float(m @ np.sum(x * x, axis=1) + jn.sum())
    m_ff = np.einsum("i,ian,iam->nm", m, phi, phi) + np.einsum("i,in,im->nm", jn, psi, psi)
    m_te = (np.einsum("i,in->n", m * x[:, 0], phi[:, 1]) - np.einsum("i,in->n", m * x[:, 1],
                                                                       phi[:, 0]) + jn @ psi)
    mass = np.block([[np.array([[j_hub]]), m_te[None, :]], [m_te[:, None], m_ff]])
    stiff = scipy.linalg.block_diag([[0.0]], np.asarray(md.stiffness, float))
    return j_hub, mass, stiff


def _rigid_torque(j_hub: float, t: np.ndarray) -> np.ndarray:
    return j_hub * 12.0 * THETA_F / T**3 * (T / 2 - t)


@pytest.fixture(scope="module")
def slew():
    mech = _beam()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sol = _slew(mech, subintervals=8).solve()
    assert not any("fastest mode" in str(w.message) for w in caught)
    res = sol.replay()
    return mech, sol, res


def test_fastest_mode_against_the_lumped_model():
    _, mass, stiff = _lumped(_beam())
    pinned = np.sqrt(np.max(np.abs(scipy.linalg.eigvals(stiff, mass))))
    clamped = np.sqrt(np.max(scipy.linalg.eigvalsh(stiff[1:, 1:], mass[1:, 1:])))
    got = fastest_mode(System(_beam()))
    assert got.body == "beam"
    assert got.omega == pytest.approx(pinned, rel=1e-12)     # 71.872 rad/s
    assert fastest_mode(System(_beam("fixed", actuated=False))).omega == pytest.approx(
        clamped, rel=1e-12)                                   # 22.110 rad/s
    assert pinned == pytest.approx(71.872, abs=1e-3) and clamped == pytest.approx(22.110,
                                                                                abs=1e-3)


def test_slew_converges_and_replays(slew):
    _, sol, res = slew
    assert sol.success
    assert sol.stats["fastest_mode_omega_h"] == pytest.approx(0.898, abs=1e-3)
    assert sol.stats["replay_error"] < 5e-3                  # measured 8.4e-4
    names = sol.coordinate_names
    q_end, v_end = res["q"][-1], res["v"][-1]
    assert q_end[names.index("beam.angle")] == pytest.approx(THETA_F, abs=1e-4)
    for coord in ("beam.eta1", "beam.eta2"):
        i = names.index(coord)
        assert abs(q_end[i]) < 1e-4 and abs(v_end[i]) < 5e-3   # measured 1e-5, 5e-4
    assert abs(v_end[names.index("beam.angle")]) < 1e-3


def test_hub_torque_near_the_rigid_closed_form(slew):
    mech, sol, _ = slew
    j_hub, _, _ = _lumped(mech)
    system = sol.ocp.system
    m_sys = ca.Function("M", [system.q, system.p], [system.mass_matrix])(
        system.initial_coordinates(), system.parameter_values)
    assert float(m_sys[2, 2]) == pytest.approx(j_hub, rel=1e-12)   # 408.33 kg m²
    t_mid = sol.control_times[:-1] + 0.5 * np.diff(sol.control_times)
    rigid = _rigid_torque(j_hub, t_mid)
    dev = np.max(np.abs(sol.control("tau") - rigid))
    assert dev < 0.15 * rigid[0]                              # measured 0.101
    effort = WEIGHT * 12.0 * j_hub**2 * THETA_F**2 / T**3
    assert 1.0 <= sol.objective / effort <= 1.03              # measured 1.0103


def test_rigid_beam_of_the_same_inertia_meets_the_closed_form():
    j_hub, _, _ = _lumped(_beam())
    mech = casmbd.loads_scene(RIGID.format(inertia=j_hub - 12.0 * 25.0))
    sol = _slew(mech, subintervals=1, flexible=False).solve()
    t_mid = sol.control_times[:-1] + 0.5 * np.diff(sol.control_times)
    rigid = _rigid_torque(j_hub, t_mid)
    assert np.max(np.abs(sol.control("tau") - rigid)) < 1e-3 * rigid[0]
    effort = WEIGHT * 12.0 * j_hub**2 * THETA_F**2 / T**3
    assert sol.objective == pytest.approx(effort, rel=1e-3)


def test_coarse_mesh_converges_and_warns():
    mech = _beam()
    assert solver_defaults(System(mech), "ipopt") == {"ipopt.mumps_pivtol":
                                                      FLEXIBLE_MUMPS_PIVTOL}
    assert solver_defaults(System(casmbd.loads_scene(RIGID.format(inertia=108.0))),
                           "ipopt") == {}
    with pytest.warns(RuntimeWarning, match=r"body 'beam'.*71\.87 rad/s.*subintervals=8"):
        ocp = _slew(mech, subintervals=1)
        sol = ocp.solve()
    assert sol.success and sol.iterations < 50               # measured 8 (was: stalled)
    assert sol.stats["fastest_mode_omega_h"] == pytest.approx(7.187, abs=1e-3)
    with pytest.warns(RuntimeWarning, match="replay_error .* exceeds"):
        sol.replay()
    assert sol.stats["replay_error"] > 1.0                   # measured 17: why it warns
