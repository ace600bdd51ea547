"""Independent minimal-coordinate references (:mod:`benchmarks.references`).

The hand-derived chain terms are checked against a generic Newton-Euler/Kane construction from
CasADi derivatives of the rod centres (not casmbd); energy conservation, the single pendulum's
elliptic period, the four-bar's closed form and the stored JSON files are checked as well.
"""

from __future__ import annotations

import json
import math
import pathlib
import subprocess
import sys

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import ellipk

from benchmarks import references as refs

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
L, MASS, G = 1.0, 1.0, 9.81


# --------------------------------------------------------------------------------------------
# Generic construction of the chain's equations (CasADi AD of the centre positions)
# --------------------------------------------------------------------------------------------


def _generic_chain_terms(
    n: int, length: float = L, mass: float = MASS, gravity: float = G
) -> ca.Function:
    """``(φ, φ̇) -> (M, h, Q)`` from ``M = Σ m J_iᵀJ_i + I E_i``, ``h = Σ m J_iᵀ J̇_i φ̇``.

    ``J_i = ∂r_i/∂φ`` is the Jacobian of rod ``i``'s centre and ``E_i`` selects its angle (the
    angular velocity of rod ``i`` is ``φ̇_i``); ``Q = Σ J_iᵀ (0, −m g)``.  These are Kane's
    equations, independent of the Lagrange derivation in the module.
    """
    phi = ca.SX.sym("phi", n)
    dphi = ca.SX.sym("dphi", n)
    inertia = mass * length**2 / 12.0
    m_mat = ca.SX.zeros(n, n)
    h = ca.SX.zeros(n)
    q = ca.SX.zeros(n)
    base = ca.SX.zeros(2)
    for i in range(n):
        e_i = ca.vertcat(ca.cos(phi[i]), ca.sin(phi[i]))
        centre = base + 0.5 * length * e_i
        base = base + length * e_i
        jac = ca.jacobian(centre, phi)
        jdot_dphi = ca.jtimes(ca.mtimes(jac, dphi), phi, dphi)  # J̇ φ̇
        sel = ca.SX.zeros(1, n)
        sel[0, i] = 1.0
        m_mat += mass * ca.mtimes(jac.T, jac) + inertia * ca.mtimes(sel.T, sel)
        h += mass * ca.mtimes(jac.T, jdot_dphi)
        q += ca.mtimes(jac.T, ca.vertcat(0.0, -mass * gravity))
    return ca.Function("generic_chain", [phi, dphi], [m_mat, h, q])


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8])
def test_chain_terms_match_generic_construction(n: int) -> None:
    fun = _generic_chain_terms(n)
    rng = np.random.default_rng(1234 + n)
    for _ in range(5):
        phi = rng.uniform(-math.pi, math.pi, n)
        dphi = rng.uniform(-5.0, 5.0, n)
        m_ref, h_ref, q_ref = (np.array(v, dtype=float) for v in fun(phi, dphi))
        np.testing.assert_allclose(refs.chain_mass_matrix(phi, L, MASS), m_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            refs.chain_velocity_forces(phi, dphi, L, MASS), h_ref.ravel(), rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(
            refs.chain_gravity_forces(phi, L, MASS, G), q_ref.ravel(), rtol=0, atol=1e-12
        )


def test_chain_mass_matrix_finite_differences_of_kinetic_energy() -> None:
    """``M`` is the Hessian of ``T = Σ ½ m |ṙ_i|² + ½ I φ̇_i²`` (central differences of ṙ)."""
    n = 4
    rng = np.random.default_rng(7)
    phi = rng.uniform(-math.pi, math.pi, n)
    eps = 1e-6
    jacs = np.zeros((n, 2, n))
    for k in range(n):
        step = np.zeros(n)
        step[k] = eps
        jacs[:, :, k] = (refs.chain_centres(phi + step) - refs.chain_centres(phi - step)) / (
            2 * eps
        )
    m_fd = MASS * np.einsum("iak,ial->kl", jacs, jacs) + MASS * L**2 / 12.0 * np.eye(n)
    np.testing.assert_allclose(refs.chain_mass_matrix(phi), m_fd, rtol=0, atol=1e-8)


def test_chain_coefficients_by_hand() -> None:
    np.testing.assert_allclose(
        refs.chain_coefficients(3),
        [[7 / 3, 3 / 2, 1 / 2], [3 / 2, 4 / 3, 1 / 2], [1 / 2, 1 / 2, 1 / 3]],
        rtol=0,
        atol=1e-15,
    )
    assert refs.chain_coefficients(1).tolist() == [[1 / 3]]
    with pytest.raises(ValueError, match="positive integer"):
        refs.chain_coefficients(0)


def test_chain_kinematics_initial_pose() -> None:
    phi = np.zeros(3)
    np.testing.assert_allclose(refs.chain_centres(phi), [[0.5, 0], [1.5, 0], [2.5, 0]], atol=0)
    np.testing.assert_allclose(refs.chain_tip_position(phi), [3.0, 0.0], atol=0)
    assert refs.chain_energy(phi, phi) == 0.0


# --------------------------------------------------------------------------------------------
# Chain references
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module", params=[2, 8])
def chain_ref(request: pytest.FixtureRequest) -> dict:
    return refs.pendulum_chain_reference(request.param)


def test_chain_energy_conserved(chain_ref: dict) -> None:
    res = chain_ref["results"]
    assert res["energy_initial"] == 0.0
    assert res["energy_drift_max"] < 1e-10
    assert abs(res["energy_final"]) < 1e-10


def test_chain_tolerance_check_agrees(chain_ref: dict) -> None:
    (check,) = chain_ref["checks"].values()
    assert check["tip_difference"] < 1e-11


def test_chain_recompute_matches_stored(chain_ref: dict) -> None:
    stored = refs.load_reference(chain_ref["name"])
    assert stored["model"] == chain_ref["model"]
    assert stored["settings"] == chain_ref["settings"]
    for key in ("tip_position", "angles", "rates"):
        np.testing.assert_allclose(
            chain_ref["results"][key], stored["results"][key], rtol=0, atol=1e-11
        )
    tip = refs.chain_tip_position(stored["results"]["angles"])
    np.testing.assert_allclose(tip, stored["results"]["tip_position"], rtol=0, atol=1e-14)


def test_chain_n32_stored_metadata() -> None:
    ref = refs.load_reference("pendulum_chain_n32")
    assert ref["name"] == "pendulum_chain_n32"
    assert ref["model"]["n"] == 32
    assert ref["model"]["length"] == 1.0 and ref["model"]["mass"] == 1.0
    assert ref["model"]["gravity"] == 9.81
    assert ref["settings"]["method"] == "DOP853"
    assert ref["settings"]["rtol"] == 1e-13 and ref["settings"]["atol"] == 1e-13
    assert ref["settings"]["t_end"] == 2.0
    res = ref["results"]
    assert len(res["angles"]) == len(res["rates"]) == 32
    assert math.hypot(*res["tip_position"]) < 32.0
    np.testing.assert_allclose(
        refs.chain_tip_position(res["angles"]), res["tip_position"], rtol=0, atol=1e-13
    )
    energy = refs.chain_energy(res["angles"], res["rates"])
    assert abs(energy - res["energy_final"]) < 1e-9
    assert res["energy_drift_relative"] < 1e-13
    assert len(ref["checks"]) == 2  # DOP853 at 1e-12 and Radau at 1e-13
    assert all(chk["tip_difference"] < 1e-11 for chk in ref["checks"].values())


def test_single_pendulum_period_matches_elliptic_integral() -> None:
    """A rod pivoted at its end, released horizontally: ``T = 4 √(l_eq/g) K(m = 1/2)``."""
    l_eq = 2.0 * L / 3.0
    period = 4.0 * math.sqrt(l_eq / G) * ellipk(0.5)  # amplitude π/2: k = sin(π/4), m = k²

    def rate(t: float, y: np.ndarray) -> float:
        return y[1]

    rate.direction = -1.0  # φ̇ falls through 0 when the rod is back at the horizontal
    sol = refs.simulate_chain(1, 1.5 * period, events=rate)
    times = [t for t in sol.t_events[0] if t > 0.5 * period]  # skip the rest state at t = 0
    assert abs(times[0] - period) / period < 1e-9
    back = sol.y_events[0][sol.t_events[0] > 0.5 * period][0]
    assert abs(back[0]) < 1e-10


# --------------------------------------------------------------------------------------------
# Parallelogram four-bar
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def four_bar() -> dict:
    return refs.parallelogram_four_bar_reference()


def test_four_bar_energy_conserved(four_bar: dict) -> None:
    res = four_bar["results"]
    assert res["energy"] == pytest.approx(5 / 6 + 2 * 9.81, abs=1e-14)
    assert res["energy_drift_ode"] < 1e-10


def test_four_bar_energy_relation(four_bar: dict) -> None:
    res = four_bar["results"]
    assert res["energy_relation_error_ode"] < 1e-10
    sol = refs.simulate_four_bar(10.0, t_eval=np.linspace(0.0, 10.0, 101))
    np.testing.assert_allclose(
        sol.y[1] ** 2, refs.four_bar_rate_squared(sol.y[0]), rtol=0, atol=1e-10
    )
    assert res["phidot_end"] ** 2 == pytest.approx(
        refs.four_bar_rate_squared(res["phi_end"]), abs=1e-13
    )


def test_four_bar_closed_form_matches_ode(four_bar: dict) -> None:
    res = four_bar["results"]
    assert abs(res["phi_end_ode_error"]) < 1e-10
    assert abs(res["phidot_end_ode_error"]) < 1e-10
    assert res["number_of_collinear_passes"] == res["number_of_collinear_passes_ode"] == 10
    assert res["collinear_pass_times_ode_error"] < 1e-10
    assert res["collinear_pass_angles_over_pi"] == list(range(1, 11))


def test_four_bar_time_of_angle_matches_quadrature() -> None:
    """The elliptic closed form equals ``∫ dφ / φ̇(φ)`` computed numerically."""

    def integrand(p: float) -> float:
        return 1.0 / math.sqrt(refs.four_bar_rate_squared(p))

    for phi in (1.0, 2.0, math.pi, 4.5, 7.0, 12.0):
        num, _ = quad(integrand, math.pi / 2, phi, epsabs=1e-14, epsrel=1e-13, limit=200)
        assert refs.four_bar_time_of_angle(phi) == pytest.approx(num, abs=1e-12)
    t = 7.3
    assert refs.four_bar_time_of_angle(refs.four_bar_angle_at_time(t)) == pytest.approx(
        t, abs=1e-14
    )


def test_four_bar_gravity_and_mirror_cases() -> None:
    no_g = refs.parallelogram_four_bar_reference(gravity=0.0)["results"]
    assert no_g["number_of_collinear_passes"] == 3
    assert no_g["phi_end"] == pytest.approx(math.pi / 2 + 10.0, abs=1e-13)
    assert no_g["phidot_end"] == pytest.approx(1.0, abs=1e-15)
    ccw = refs.load_reference("parallelogram_four_bar")["results"]
    cw = refs.parallelogram_four_bar_reference(omega0=-1.0)["results"]
    assert cw["number_of_collinear_passes"] == 10
    assert cw["phi_end"] == pytest.approx(math.pi - ccw["phi_end"], abs=1e-13)
    assert cw["phidot_end"] == pytest.approx(-ccw["phidot_end"], abs=1e-13)
    np.testing.assert_allclose(cw["collinear_pass_times"], ccw["collinear_pass_times"], atol=1e-13)
    with pytest.raises(ValueError, match="does not rotate"):
        refs.parallelogram_four_bar_reference(omega0=0.0)


def test_four_bar_recompute_matches_stored(four_bar: dict) -> None:
    stored = refs.load_reference("parallelogram_four_bar")
    assert stored["settings"] == four_bar["settings"]
    assert stored["model"] == four_bar["model"]
    res, ref = four_bar["results"], stored["results"]
    assert res["phi_end"] == pytest.approx(ref["phi_end"], abs=1e-13)
    assert res["phidot_end"] == pytest.approx(ref["phidot_end"], abs=1e-13)
    np.testing.assert_allclose(res["collinear_pass_times"], ref["collinear_pass_times"], atol=1e-13)
    assert ref["number_of_collinear_passes"] == 10
    assert (
        refs.load_reference("parallelogram_four_bar_no_gravity")["results"][
            "number_of_collinear_passes"
        ]
        == 3
    )


# --------------------------------------------------------------------------------------------
# Storage and command line
# --------------------------------------------------------------------------------------------


def test_json_floats_round_trip_with_17_digits() -> None:
    values = [0.1, 1.0, 1e-13, 9.81, math.pi, -1.9147466175623526, 2.0 / 3.0, 1e17 / 3.0]
    text = refs.dumps_reference({"v": values, "nested": {"x": [[1.5, 2]], "s": "a"}})
    back = json.loads(text)
    assert back["v"] == values
    assert back["nested"] == {"x": [[1.5, 2]], "s": "a"}
    assert "3.1415926535897931" in text  # 17 significant digits
    assert '"v": [0.1, 1.0, 1e-13, 9.81,' in text  # short exact forms kept
    with pytest.raises(ValueError, match="non-finite"):
        refs.dumps_reference({"x": math.nan})


def test_all_stored_references_load() -> None:
    for name in refs.REFERENCE_NAMES:
        ref = refs.load_reference(name)
        assert ref["name"] == name
        assert ref["environment"]["generator"] == "python -m benchmarks.references --write"
    with pytest.raises(KeyError, match="no stored reference"):
        refs.load_reference("does_not_exist")


def test_cli_write_and_summary(tmp_path: pathlib.Path) -> None:
    names = ["pendulum_chain_n2", "parallelogram_four_bar_no_gravity"]
    assert (
        refs.main(["--write", "--no-radau", "--names", *names, "--output-dir", str(tmp_path)]) == 0
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f"{n}.json" for n in names)
    written = refs.load_reference("pendulum_chain_n2", tmp_path)
    stored = refs.load_reference("pendulum_chain_n2")
    np.testing.assert_allclose(
        written["results"]["tip_position"], stored["results"]["tip_position"], atol=1e-11
    )
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks.references"],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert "pendulum_chain_n32: tip(t=2)" in proc.stdout
    assert "10 collinear passes" in proc.stdout
