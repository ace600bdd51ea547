"""Andrews' squeezing mechanism (issue 7; ``examples/andrews.toml``).

Published data (kept here independently of the scene file): the Test Set for IVP Solvers
(Mazzia, Magherini, Iavernaro, Univ. Bari; problem "andrews", ``src/problems/andrews.f``), after
Hairer & Wanner, *Solving ODEs II*, section VII.7: initial angles (30 digits), initial
accelerations and multipliers, and the reference solution at t = 0.03 s (PSIDE at rtol = atol =
1e-14 in Cray double precision).  The scene uses absolute body angles; the published angles are

    beta = a1, Theta = a2 - a1, gamma = a3, Phi = a4 - a5, delta = a5, Omega = a6 - a7,
    epsilon = a7                                    (a_k: the angle of body k),

and the published multipliers (lambda1, lambda2), (lambda3, lambda4), (lambda5, lambda6) are the
forces of body 2 on bodies 3, 4, 6 at E (joints E23, E24, E26; M q'' = f - G^T lambda with
g = E(body 2) - E(body k)).  Checks, each with its tolerance (measured values in brackets):

* initial configuration: the scene's pose gives the published angles to 1e-15 rad [2.8e-17];
  assembly (Newton, body 1 held at beta0) from a guess perturbed by up to 2 mm and 0.05 rad
  returns the published Theta..epsilon to 1e-12 rad [2e-14];
* initial accelerations (published beta'' = 14222.44..., Theta'' = -10666.83..., the other five
  0) to 1e-9 relative to |beta''| [6e-13], and the E23 reaction equals the published
  (lambda1, lambda2) = (98.566..., -6.122...) N to 1e-9 relative [8e-15];
* at t = 0.03 with the default formulation at rtol 1e-12: the seven angles to 1e-8 rad [1.4e-9];
  the angular velocities to 1e-8 relative to the largest (|beta'| = 1140 rad/s) [3.6e-10]; the
  multipliers to 1e-6 relative to the largest [7.4e-8];
* energy balance: no damping, so E(t) - E(0) = mom (beta(t) - beta(0)) to 1e-9 J on the
  output grid [5e-11; E(0.03) - E(0) = 0.524 J];
* self-convergence of the default formulation: the error of the angles against the reference
  falls by at least 10x for each 100x tighter rtol from 1e-4 to 1e-10 [79x, 58x, 68x] and is
  below 1e-7 at 1e-10 [5.2e-8];
* independent formulations: kkt_ode/adams and index1/idas at rtol 1e-10 give the reference
  angles to 1e-6 [5.0e-8, 1.3e-7];
* an independent solution of the published seven-angle equations (numpy long double, RK4 with
  Richardson extrapolation, ``benchmarks/andrews.py``: Q_IND below) differs from the published
  reference by 1.43e-9 rad in Theta and 1.15e-9 in beta (the floor every formulation reaches
  against the published values); kkt_ode/adams at rtol 1e-13 matches it to 1e-10 rad [1.8e-11]
  and the default formulation at rtol 1e-12 to 1e-9 [1.1e-10]: the scene and the published
  equations give the same motion far below the published reference's own error.
"""

from __future__ import annotations

import itertools
import pathlib

import numpy as np
import pytest
from conftest import private_cache

from casmbd import info
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.instant.assembly import assemble
from casmbd.io.scene import load_scene
from casmbd.system.equations import System

SCENE = pathlib.Path(__file__).resolve().parents[3] / "examples" / "andrews.toml"
T_END = 0.03
BODIES = [f"body{k}" for k in range(1, 8)]

# Test set andrews.f: initial angles (beta, Theta, gamma, Phi, delta, Omega, epsilon) ...
Q0 = np.array([-0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
               0.222668390165885884674473185609, 0.487364979543842550225598953530,
               -0.222668390165885884674473185609, 1.23054744454982119249735015568])
# ... initial accelerations and multipliers ...
A0 = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415,
               0.0, 0.0, 0.0, 0.0, 0.0])
LAMBDA0 = np.array([98.5668703962410896057654982170, -6.12268834425566265503114393122,
                    0.0, 0.0, 0.0, 0.0])
# ... and the reference solution at t = 0.03: angles, angular velocities, multipliers
Q_REF = np.array([0.1581077119629904e+2, -0.1575637105984298e+2, 0.4082224013073101e-1,
                  -0.5347301163226948e+0, 0.5244099658805304e+0, 0.5347301163226948e+0,
                  0.1048080741042263e+1])
V_REF = np.array([0.1139920302151208e+4, -0.1424379294994111e+4, 0.1103291221937134e+2,
                  0.1929337464421385e+2, 0.5735699284790808e+0, -0.1929337464421385e+2,
                  0.3231791658026955e+0])
LAMBDA_REF = np.array([0.1991753333731910e+3, -0.2975531228015052e+2, 0.2306654119098399e+2,
                       0.3145271365475927e+2, 0.2264249232082739e+2, 0.1161740700019673e+2])
MOM = 0.033
# independent reference at t = 0.03: benchmarks/andrews.py, long_double_reference (RK4 on 8000
# and 16000 steps in long double, Richardson-extrapolated; error estimate below 1e-12)
Q_IND = np.array([15.81077119515372763, -15.756371058411865772, 0.0408222401196461018,
                  -0.5347301163420790809, 0.5244099658799540384, 0.5347301163420790813,
                  1.0480807410419380374])


_cache = private_cache("cache_andrews", scope="module", CASMBD_COMPILE=None)


def published(absolute: np.ndarray) -> np.ndarray:
    """Published joint angles (or their rates) from the absolute body angles a1..a7 (last
    axis)."""
    a = np.moveaxis(np.asarray(absolute, float), -1, 0)
    return np.stack([a[0], a[1] - a[0], a[2], a[3] - a[4], a[4], a[5] - a[6], a[6]], axis=-1)


def angles(res, key: str = "angle") -> np.ndarray:
    """(n_t, 7) published angles (key "angle"), rates or accelerations of a result."""
    return published(np.stack([res.body(b)[key] for b in BODIES], axis=-1))


def multipliers(res) -> np.ndarray:
    """(n_t, 6) published multipliers: forces of body 2 on bodies 3, 4, 6 at E."""
    joints = res.names["joints"]
    reac = res["joint_reactions"]
    return np.concatenate([reac[:, joints.index(j), :2] for j in ("E23", "E24", "E26")], axis=1)


@pytest.fixture(scope="module")
def sim():
    return Simulator(load_scene(SCENE))


@pytest.fixture(scope="module")
def tight(sim):
    """Default formulation, rtol 1e-12, outputs at t = 0, 0.01, 0.02, 0.03."""
    return sim.run(T_END, 3, rtol=1e-12)


def test_mechanism():
    data = info(load_scene(SCENE))
    assert data["degrees_of_freedom"] == 1
    assert data["redundant_equations"] == []


def test_initial_configuration(sim):
    """(a) The scene's pose and an assembly from a perturbed guess give the published angles."""
    names = sim.system.coordinate_names
    q0 = sim.system.initial_coordinates()
    body_angles = q0[[names.index(f"{b}.angle") for b in BODIES]]
    assert np.max(np.abs(published(body_angles) - Q0)) < 1e-15
    assert np.max(np.abs(sim.model.constraints(q0, 0.0))) < 1e-15
    rng = np.random.default_rng(7)
    spread = np.array([0.05 if n.endswith(".angle") else 2e-3 for n in names])
    guess = q0 + spread * rng.uniform(-1.0, 1.0, q0.size)
    guess[names.index("body1.angle")] = q0[names.index("body1.angle")]
    rep = assemble(sim.model, guess, 0.0, fixed=["body1.angle"], tol=1e-15)
    assert np.max(np.abs(guess - q0)) > 1e-2            # the guess is really off
    assembled = published(rep.q[[names.index(f"{b}.angle") for b in BODIES]])
    assert np.max(np.abs(assembled - Q0)) < 1e-12
    # the scene pins absolute coordinates; the automatic choice would take joint coordinates
    mech = load_scene(SCENE)
    assert sim.system.coordinates == "absolute" and sim.system.coordinate_reason == "given"
    mech.coordinates = "auto"
    auto = System(mech)
    assert (auto.coordinates, auto.nq, auto.nc) == ("joint", 7, 6), auto.coordinate_reason


def test_initial_accelerations_and_multipliers(tight):
    assert tight.stats["start_position_change"] < 1e-15
    a0 = angles(tight, "angular_acceleration")[0]
    assert np.max(np.abs(a0 - A0)) < 1e-9 * abs(A0[0])
    lam0 = multipliers(tight)[0]
    assert np.max(np.abs(lam0 - LAMBDA0)) < 1e-9 * abs(LAMBDA0[0])


def test_reference_solution(tight):
    """(b) Angles, angular velocities and multipliers at t = 0.03 against the test set."""
    assert tight.stats["formulation"] == "augmented_lagrangian"
    assert tight.t[-1] == pytest.approx(T_END, abs=1e-15)
    assert np.max(np.abs(angles(tight)[-1] - Q_REF)) < 1e-8
    v = angles(tight, "angular_velocity")[-1]
    assert np.max(np.abs(v - V_REF)) < 1e-8 * np.max(np.abs(V_REF))
    lam = multipliers(tight)[-1]
    assert np.max(np.abs(lam - LAMBDA_REF)) < 1e-6 * np.max(np.abs(LAMBDA_REF))
    # beta turns 2.5 times in 0.03 s
    assert angles(tight)[-1, 0] - Q0[0] > 5 * np.pi


def test_energy_balance(tight):
    """Kinetic + spring energy grows by the work of the constant drive torque."""
    energy = tight["total_energy"]
    beta = angles(tight)[:, 0]
    work = MOM * (beta - beta[0])
    assert work[-1] == pytest.approx(0.5238, abs=1e-3)
    assert np.max(np.abs(energy - energy[0] - work)) < 1e-9


def test_self_convergence(sim):
    """(c) The error at t = 0.03 shrinks at least 10x for each 100x tighter rtol."""
    errors = []
    for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
        res = sim.run(T_END, 1, rtol=rtol)
        errors.append(float(np.max(np.abs(angles(res)[-1] - Q_REF))))
    for loose, tight_err in itertools.pairwise(errors):
        assert tight_err < loose / 10.0, errors
    assert errors[-1] < 1e-7, errors


@pytest.fixture(scope="module")
def kkt():
    return Simulator(load_scene(SCENE), "kkt_ode")


def test_other_formulations(kkt):
    res = kkt.run(T_END, 1, rtol=1e-10, integrator="adams")
    assert res.stats["formulation"] == "kkt_ode"
    assert np.max(np.abs(angles(res)[-1] - Q_REF)) < 1e-6
    res = Simulator(load_scene(SCENE), "index1").run(T_END, 1, rtol=1e-10, integrator="idas")
    assert res.stats["formulation"] == "index1"
    assert np.max(np.abs(angles(res)[-1] - Q_REF)) < 1e-6


def test_independent_reference(kkt, tight):
    """Against an independent solution of the published equations the scene converges far
    below the published reference's own error (1.4e-9 rad in beta and Theta)."""
    res = kkt.run(T_END, 1, rtol=1e-13, integrator="adams")
    assert np.max(np.abs(angles(res)[-1] - Q_IND)) < 1e-10
    assert np.max(np.abs(angles(tight)[-1] - Q_IND)) < 1e-9
