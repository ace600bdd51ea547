"""Redundant constraints in every analysis (issue 30, item 4a): the Cardan shaft.

examples/cardan_shaft.toml: an input shaft on a revolute bearing (about x), a universal joint,
an output shaft on a revolute bearing bent by β = 30°.  Its 14 joint equations (+ 2
Euler-parameter normalisations in absolute coordinates) leave 1 degree of freedom: 3 are
redundant, and every analysis removes the same three (``out_bearing`` y, axis f, axis g, the
later equations in declaration order), names them and runs on the rest.  References:

* kinematics — Hooke's joint: tan φ₂ = tan φ₁ / cos β, ω₂/ω₁ = r(φ₁) = cos β /
  (1 − sin²β cos²φ₁) (φ₁ from the input yoke in the plane of the shafts);
* inverse dynamics — power balance: T₁ ω₁ = T_L ω₂ + d/dt(½ J₁ω₁² + ½ J₂ω₂²) with the axial
  inertias J₁ = J₂ = 2e-3 (centres of mass on the fixed axes: gravity does no work);
* statics — virtual work: T₁ = T_L r(φ₁); with a torsional spring k on the output bearing and
  no driver, φ₂ = −T_L / k;
* linearize — about that equilibrium ω_n² = k r² / (J₁ + J₂ r²) (V'' = k r² + (kφ₂ + T_L) φ₂''
  and kφ₂ + T_L = 0);
* reactions — finite everywhere; the components a self-stress of the loop cannot move equal
  those of a non-redundant model of the same machine (the output bearing an in-line joint, its
  equations a subset of the revolute's), and the multipliers are the minimum-norm ones
  (Nᵀλ = 0, C_qᵀ N = 0).
"""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import casmbd
from casmbd.analysis.instant.undetermined_reactions import multiplier_null_space
from casmbd.io.scene import loads_scene

# the undetermined reactions warn (checked once, in test_simulate_reactions_finite)
pytestmark = pytest.mark.filterwarnings("ignore:joint reactions cannot be determined")

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCENE = ROOT / "examples" / "cardan_shaft.toml"
TEXT = SCENE.read_text()
BETA = np.pi / 6
J_AXIAL = 2e-3
LOAD, OMEGA = 2.0, 3.0
REMOVED = ["joint 'out_bearing' equation 'y'", "joint 'out_bearing' equation 'axis f'",
           "joint 'out_bearing' equation 'axis g'"]


def cardan(coordinates: str = "absolute", driven: bool = True, spring: float | None = None,
           bearing: str = "revolute") -> casmbd.Mechanism:
    """The example, optionally without its driver, with a torsional spring on the output
    bearing, or with the output bearing an in-line joint (non-redundant)."""
    text = TEXT
    if not driven:
        text = text[:text.index("[[drivers]]")] + text[text.index("[[forces]]"):]
    if spring is not None:
        text += ('\n[[forces]]\nname = "spring"\ntype = "rotational_spring_damper"\n'
                 f'joint = "out_bearing"\nstiffness = {spring!r}\n')
    if bearing == "inline":
        head, tail = text.split('name = "out_bearing"\ntype = "revolute"')
        text = head + 'name = "out_bearing"\ntype = "inline"' + tail
    mech = loads_scene(text, str(SCENE))
    mech.coordinates = coordinates
    mech.name = f"cardan_{coordinates}_{driven}_{spring}_{bearing}"
    return mech


def ratio(phi1):
    """ω₂/ω₁ of Hooke's joint."""
    return np.cos(BETA) / (1.0 - np.sin(BETA) ** 2 * np.cos(phi1) ** 2)


def ratio_slope(phi1):
    """d(ω₂/ω₁)/dφ₁."""
    s2 = np.sin(BETA) ** 2
    return -np.cos(BETA) * 2.0 * s2 * np.cos(phi1) * np.sin(phi1) / (
        1.0 - s2 * np.cos(phi1) ** 2) ** 2


def _wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


@pytest.mark.parametrize("coordinates,n_c", [("absolute", 17), ("joint", 5)])
def test_info_names_three_redundant_equations(coordinates, n_c):
    data = casmbd.info(cardan(coordinates))
    assert data["n_constraints"] == n_c and data["rank"] == n_c - 3
    # joint coordinates: both bearings are tree joints and the universal joint closes the
    # loop; its centre lies on both fixed axes, so its point equations are identically
    # satisfied (rows of C_q that are rounding noise, ~3e-17, count as zero)
    assert [(r["joint"], r["equation"]) for r in data["redundant_equations"]] == (
        [("out_bearing", "y"), ("out_bearing", "axis f"), ("out_bearing", "axis g")]
        if coordinates == "absolute" else [("cross", "x"), ("cross", "y"), ("cross", "z")])


@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
def test_kinematics_hookes_joint(coordinates):
    """tan φ₂ = tan φ₁ / cos β and ω₂ = r(φ₁) ω₁ over 1.5 input turns, to 1e-9."""
    res = casmbd.kinematics(cardan(coordinates), t_end=3.0, steps=60)
    assert res.stats["redundancy"] == "removed"
    assert len(res.stats["redundant_equations"]) == 3
    if coordinates == "absolute":
        assert res.stats["redundant_equations"] == REMOVED
    joints = res.names["joints"]
    phi1 = res["joint_positions"][:, joints.index("in_bearing")]
    phi2 = res["joint_positions"][:, joints.index("out_bearing")]
    w1 = res["joint_velocities"][:, joints.index("in_bearing")]
    w2 = res["joint_velocities"][:, joints.index("out_bearing")]
    assert np.allclose(phi1, OMEGA * res.t, atol=1e-12) and phi1[-1] > 2.5 * np.pi
    hooke = np.arctan2(np.sin(phi1), np.cos(BETA) * np.cos(phi1))  # tan φ₂ = tan φ₁ / cos β
    assert np.max(np.abs(_wrap(phi2 - hooke))) < 1e-9
    assert np.max(np.abs(w2 - ratio(phi1) * w1)) < 1e-9
    # every equation holds, the removed ones included
    assert np.max(res["constraint_violation"]) < 1e-10


@pytest.fixture(scope="module")
def inverse():
    return casmbd.inverse_dynamics(cardan(), t_end=2.0, steps=40)


def test_inverse_dynamics_power_balance(inverse):
    """T₁ = (T_L ω₂ + J₂ ω₂ α₂) / ω₁, α₂ = r'(φ₁) ω₁² (ω₁ constant), to 1e-9 N m."""
    res = inverse
    phi1 = OMEGA * res.t
    w2, a2 = ratio(phi1) * OMEGA, ratio_slope(phi1) * OMEGA ** 2
    expected = (LOAD * w2 + J_AXIAL * w2 * a2) / OMEGA
    effort = res["driver_efforts"][:, 0]
    assert np.max(np.abs(effort - expected)) < 1e-9
    assert np.ptp(effort) > 0.5     # 2 / cos β − 2 cos β = 0.577 N m of torque fluctuation
    assert res.stats["redundant_equations"] == REMOVED
    # kinetic energy ½ J (ω₁² + ω₂²)
    assert np.max(np.abs(res["kinetic_energy"] - 0.5 * J_AXIAL * (OMEGA ** 2 + w2 ** 2))) < 1e-12


def _null(model, q, t):
    return multiplier_null_space(model.constraint_jacobian(q, float(t)))


def test_inverse_reactions_finite_minimum_norm_and_exact(inverse):
    """No NaN; λ is the minimum-norm multiplier (Nᵀλ = 0); the determined components equal
    the non-redundant (in-line output bearing) model's to 1e-9."""
    res = inverse
    reac = res["joint_reactions"]
    assert np.all(np.isfinite(reac)) and np.all(np.isfinite(res["lambda"]))
    assert res.stats["reactions"] == "minimum_norm"
    flagged = res.stats["undetermined_reactions"]
    assert set(flagged) == {"in_bearing", "cross", "out_bearing"}
    model = casmbd.NumericModel(cardan(), "kinematics", mode="vm")
    for k in (0, 7, 23):
        null = _null(model, res["q"][k], res.t[k])
        assert null.shape[1] == 3
        lam = res["lambda"][k]
        assert np.max(np.abs(null.T @ lam)) < 1e-10 * (1 + np.max(np.abs(lam)))
    ref = casmbd.inverse_dynamics(cardan(bearing="inline"), t_end=2.0, steps=40)
    assert ref.stats["redundant_equations"] == [] and ref.stats["reactions"] == "determined"
    assert np.max(np.abs(ref["driver_efforts"] - res["driver_efforts"])) < 1e-9
    mask = np.ones(reac.shape[1:], dtype=bool)
    for j, comps in flagged.items():
        mask[res.names["all_joints"].index(j), comps] = False
    assert mask.sum() >= 4          # in_bearing Mx, the cross's three moments
    assert np.max(np.abs(reac[:, mask] - ref["joint_reactions"][:, mask])) < 1e-9
    # the cross transmits the input torque: its moment about x is T₁ (the driver's effort)
    cross = res.names["all_joints"].index("cross")
    assert np.max(np.abs(np.abs(reac[:, cross, 3]) - res["driver_efforts"][:, 0])) < 1e-9


@pytest.mark.parametrize("t", [0.0, 0.2, 0.45])
def test_statics_input_torque_by_virtual_work(t):
    """A driven, loaded shaft held at φ₁ = ω t: T₁ = T_L r(φ₁)."""
    eq = casmbd.static_equilibrium(cardan(), t=t)
    assert eq.stats["redundant_equations"] == REMOVED
    assert eq.stats["reactions"] == "minimum_norm"
    assert np.all(np.isfinite(eq.joint_reactions))
    effort = -eq.lagrange_multipliers[-1]     # the driver's row is the last
    assert abs(effort - LOAD * ratio(OMEGA * t)) < 1e-9


K_SPRING = 50.0


@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
def test_statics_spring_and_linearize(coordinates):
    """No driver, a torsional spring k on the output bearing: φ₂ = −T_L / k, tan φ₂ = tan φ₁ /
    cos β; the natural frequency about it √(k r² / (J₁ + J₂ r²)) / 2π, to 1e-9 relative."""
    mech = cardan(coordinates, driven=False, spring=K_SPRING)
    eq = casmbd.static_equilibrium(mech)
    assert len(eq.stats["redundant_equations"]) == 3 and eq.stable
    names = eq.names["joints"]
    phi1 = eq.joint_coordinates[names.index("in_bearing")]
    phi2 = eq.joint_coordinates[names.index("out_bearing")]
    assert abs(phi2 + LOAD / K_SPRING) < 1e-10
    assert abs(np.tan(phi2) - np.tan(phi1) / np.cos(BETA)) < 1e-10
    lin = casmbd.linearize(mech, at="equilibrium")
    assert lin.stats["redundant_equations"] and lin.stats["redundancy"] == "removed"
    assert lin.n_dof == 1
    r = ratio(phi1)
    omega_n = np.sqrt(K_SPRING * r ** 2 / (J_AXIAL + J_AXIAL * r ** 2))
    fn = np.ravel(lin.natural_frequencies_hz)
    assert abs(fn[0] - omega_n / (2 * np.pi)) < 1e-9 * fn[0]


def test_simulate_reactions_finite():
    """The driven shaft simulated (default formulation, redundant rows kept): reactions finite,
    the minimum-norm distribution said so, and the driver's effort that of inverse dynamics."""
    with pytest.warns(RuntimeWarning, match="minimum-norm distribution is reported"):
        res = casmbd.simulate(cardan(), t_end=0.5, steps=10, rtol=1e-10)
    assert res.stats["redundant_equations"] == REMOVED
    assert res.stats["reactions"] == "minimum_norm"
    assert np.all(np.isfinite(res["joint_reactions"]))
    phi1 = OMEGA * res.t
    w2, a2 = ratio(phi1) * OMEGA, ratio_slope(phi1) * OMEGA ** 2
    # measured 6e-10 N m at rtol 1e-10
    assert np.max(np.abs(res["driver_efforts"][:, 0] - (LOAD * w2 + J_AXIAL * w2 * a2) / OMEGA)) \
        < 1e-8


def test_minimum_norm_option_refused_by_name():
    with pytest.raises(casmbd.AnalysisError, match="simulate's formulations"):
        casmbd.kinematics(cardan(), t_end=1.0, steps=2, redundancy="minimum_norm")


@pytest.mark.parametrize("verb", ["kinematics", "inverse", "statics"])
def test_cli_json(verb):
    """One JSON object on stdout, exit 0, the removed equations named."""
    args = [sys.executable, "-m", "casmbd", verb, str(SCENE), "--json"]
    if verb != "statics":
        args += ["--t-end", "1", "--steps", "10"]
    out = subprocess.run(args, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["stats"]["redundant_equations"] == REMOVED
    assert data["stats"]["redundancy"] == "removed"


def _doubly_driven(rate2: str) -> casmbd.Mechanism:
    """A pendulum on a pin with two drivers on its angle: ``t`` and ``rate2``."""
    m = casmbd.Mechanism(f"two_drivers_{rate2.replace(' ', '')}", gravity=(0.0, -9.81))
    m.add_body("rod", 1.0, 1.0 / 12.0, (0.5, 0.0))
    m.add_revolute("pin", "ground", "rod", (0.0, 0.0))
    m.add_driver("first", "t", joint="pin")
    m.add_driver("second", rate2, joint="pin")
    return m


def test_consistent_duplicate_driver_is_removed_and_named():
    """Two drivers that say the same thing: the second is redundant, removed and named; the
    effort is shared in the least-norm way (half each: λ ⟂ (1, −1)) and sums to the one
    driver's, m g (L/2) cos θ + J_O θ̈ = 4.905 cos t (θ̈ = 0)."""
    res = casmbd.inverse_dynamics(_doubly_driven("t"), t_end=1.0, steps=4)
    assert res.stats["redundant_equations"] == ["driver 'second' equation 'coordinate'"]
    efforts = res["driver_efforts"]
    expected = 9.81 * 0.5 * np.cos(res.t)
    assert np.max(np.abs(efforts.sum(axis=1) - expected)) < 1e-12
    assert np.max(np.abs(efforts[:, 0] - efforts[:, 1])) < 1e-12


def test_contradicting_drivers_are_named_not_ignored():
    """θ = t and θ = 2t agree at t = 0 only: the second, removed as redundant there, is violated
    at the next time and named — the analysis does not return a motion that ignores it."""
    with pytest.raises(casmbd.RedundantConstraintError, match=r"kinematics at t = 0\.25.*"
                       r"driver 'second'"):
        casmbd.kinematics(_doubly_driven("2 * t"), t_end=1.0, steps=4)


@pytest.mark.parametrize("method", ["dense", "sparse"])
def test_rounding_noise_rows_are_no_equations(method):
    """C_q of the joint-coordinate shaft at the start: the universal joint's point rows are 0,
    0 and −2.8e-17 (its centre lies on both fixed axes).  Equilibrated to unit norm the noise
    row looked independent and the driver's row was named redundant instead; rows at most
    1e-12 of the largest count as zero, in both sweeps."""
    from casmbd.analysis.instant.redundancy import rank_report

    cq = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, -2.7755575615628914e-17],
                   [1.0, -0.8660254037844386], [1.0, 0.0]])
    rep = rank_report(cq, method=method)
    assert rep.rank == 2 and rep.dependent_rows == [0, 1, 2]
    # a small but genuine row (a mechanism in micrometres) is kept
    rep = rank_report(np.array([[1e-9, 0.0], [0.0, 1.0]]), method=method)
    assert rep.rank == 2 and rep.dependent_rows == []


def test_inverse_dynamics_with_an_actuator(inverse):
    """The drivers describe the motion, a motor on the input bearing produces it (the least-
    squares [C_qᵀ −B] solve with redundant rows): its torque is the driver's effort and the
    reactions are those of the driven shaft (1e-12)."""
    mech = cardan()
    mech.name = "cardan_motor"
    mech.add_actuator("motor", joint="in_bearing")
    res = casmbd.inverse_dynamics(mech, t_end=2.0, steps=40)
    assert res.stats["redundant_equations"] == REMOVED
    assert np.max(np.abs(res["actuator_efforts"][:, 0] - inverse["driver_efforts"][:, 0])) \
        < 1e-12
    assert np.all(np.isfinite(res["joint_reactions"]))
    assert np.max(np.abs(res["joint_reactions"] - inverse["joint_reactions"])) < 1e-12
