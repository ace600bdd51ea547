"""Delta robot (seed 003, §5.2) as a 3-RUU mechanism: examples/delta_robot.py.

Checks: 3 DOF without redundant equations; closed-form inverse kinematics against
casmbd.kinematics with hand drivers; drive moments against a closed-form gravity balance (at
rest) and against Lagrange's equations in the hand coordinates (in motion); the round trip
inverse → forward dynamics with the splined drive moments.
"""

from __future__ import annotations

import importlib.util
import pathlib
import sys

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.errors import AnalysisError

_PATH = pathlib.Path(__file__).resolve().parents[3] / "examples" / "delta_robot.py"
_spec = importlib.util.spec_from_file_location("delta_robot_example", _PATH)
delta = sys.modules.setdefault(_spec.name, importlib.util.module_from_spec(_spec))
_spec.loader.exec_module(delta)

#: the round-trip grid: 300 intervals on the 0.6 s path (measured hand error 5.5e-9 m)
STEPS = 300


_cache = private_cache("cache_delta", scope="module")


@pytest.fixture(scope="module")
def inv():
    return delta.inverse(STEPS)


def test_three_dof_no_redundancy():
    """7 bodies × 7 Euler coordinates, 7 + 3·(5 + 4 + 4) = 46 independent constraints."""
    out = casmbd.info(delta.delta_robot())
    assert out["assembled"]
    assert (out["n_coordinates"], out["n_constraints"], out["rank"]) == (49, 46, 46)
    assert out["degrees_of_freedom"] == 3
    assert out["redundant_equations"] == []
    # the initial pose from the closed-form IK is already assembled (no Newton correction)
    q0 = casmbd.System(delta.delta_robot()).initial_coordinates()
    assert np.max(np.abs(np.asarray(out["initial_coordinates"]) - q0)) <= 1e-12
    # the example pins absolute coordinates; the automatic choice: the tree shoulder, elbow
    # (2) per arm and the hand on one wrist (2), the other two wrists close the loops
    mech = delta.delta_robot()
    mech.coordinates = "auto"
    auto = casmbd.info(mech)
    assert auto["coordinate_choice"] == "joint"
    assert (auto["n_coordinates"], auto["n_constraints"], auto["rank"]) == (11, 8, 8)
    assert auto["degrees_of_freedom"] == 3 and auto["redundant_equations"] == []


def test_inverse_kinematics_matches_kinematics():
    """Arm angles: closed form vs Newton on the 49 coordinates, 1e-9 rad; the hand keeps its
    orientation (rotation matrix = I to 1e-9) along the whole gate path."""
    out = delta.ik_check(steps=40)
    assert out["max_angle_error"] <= 1e-9
    assert out["max_hand_rotation"] <= 1e-9
    # the path really moves the arms (the check is not comparing constants)
    assert np.ptp(out["theta_closed_form"], axis=0).min() > 0.1


def test_inverse_kinematics_geometry_and_reach():
    """Every forearm has its length at the IK angles; out of reach raises, naming the arm."""
    rng = np.random.default_rng(5)
    for p in rng.uniform([-0.2, -0.2, -0.85], [0.2, 0.2, -0.55], size=(20, 3)):
        theta = delta.inverse_kinematics(p)
        for i in range(3):
            e = delta.arm_frames(i)[0]
            length = np.linalg.norm(p + delta.GEOMETRY.b * e - delta.elbow(i, theta[i]))
            assert abs(length - delta.GEOMETRY.fore) <= 1e-13
    with pytest.raises(AnalysisError, match="out of reach of arm"):
        delta.inverse_kinematics([0.0, 0.0, -1.3])


@pytest.mark.parametrize("position", [delta.START, delta.GOAL, [0.08, -0.12, -0.62]])
def test_static_moments_match_virtual_work(position):
    """Hand at rest: inverse-dynamics drive moments = closed-form gravity balance by virtual
    work (Σ τ_i δθ_i = δV), 1e-10 N m (measured ~3e-15; moments ~0.5–1.2 N m)."""
    tau_id = delta.static_moments_inverse_dynamics(position, mode="vm")
    tau_cf = delta.static_moments_closed_form(position)
    assert np.max(np.abs(tau_id - tau_cf)) <= 1e-10
    assert np.min(np.abs(tau_cf)) > 0.05


def test_drive_moments_match_lagrange(inv):
    """Moving: drive moments = Lagrange's equations in the hand coordinates (closed-form body
    poses, CasADi AD; independent of casmbd's equations), 1e-8 N m (measured ~3e-12 on
    moments up to 3.4 N m)."""
    every = slice(None, None, 10)
    expected = delta.lagrange_drive_moments(inv.t[every])
    assert np.max(np.abs(inv["actuator_efforts"][every] - expected)) <= 1e-8
    assert np.max(np.abs(expected)) > 1.0


def test_round_trip(inv):
    """Drivers removed, moments splined on 300 intervals as actuator inputs, forward dynamics
    from the same initial state (rtol = atol = 1e-12): the hand follows the path to 1e-7 m
    (measured 5.5e-9 m); the hand does not rotate (1e-9)."""
    out = delta.round_trip(STEPS, 1e-12, inv=inv)
    assert out["max_hand_error"] <= 1e-7
    fwd = out["forward"]
    i = fwd.names["bodies"].index("hand")
    rot = fwd["rotation_matrices"][:, 9 * i:9 * i + 9]
    assert np.max(np.abs(rot - np.eye(3).ravel())) <= 1e-9
    # the hand really travels (0.32 m), so the error is small against the motion
    hand = fwd["body_positions"][:, delta.hand_index(fwd)]
    assert np.linalg.norm(hand[-1] - hand[0]) > 0.3


def test_round_trip_needs_the_moments():
    """Without the drive moments (u = 0) the robot falls: the comparison can fail."""
    sim = casmbd.Simulator(delta.delta_robot(name="delta_robot_falling"), mode="vm")
    fwd = sim.run(0.1, 10, rtol=1e-8)
    hand = fwd["body_positions"][:, delta.hand_index(fwd)]
    assert np.max(np.abs(hand - delta.START)) > 1e-3
