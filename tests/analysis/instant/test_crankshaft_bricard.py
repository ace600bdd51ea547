"""Over-constrained spatial loops (issue 7, item 4): seed 002's all-revolute crankshaft and
Bricard's mechanism simulate correctly with their redundant equations present.

* Crankshaft (examples/crankshaft.py): the rank check names exactly the three redundant
  equations of the P1/P2 joint; with those equations removed, and with all kept and minimum-norm
  multipliers, the motion follows non-redundant models of the same machine (an in-line joint at
  P; a spherical joint at the crank pin and a universal joint at P) to 1e-8; the reactions that
  a self-stress of the loop can change (z force, x and y moments) are flagged and reported for
  the minimum-norm multipliers (finite, issue 30), and the others equal the non-redundant
  model's.
* Bricard (examples/bricard.toml): Grübler's count is 0, the rank gives mobility 1 with one
  redundant equation; over 1 s the motion of two descriptions and formulations (absolute
  coordinates with the default augmented Lagrangian keeping the redundant row, joint
  coordinates with kkt_ode and the row removed) converges to one reference to 1e-7; the energy
  is conserved.
"""

from __future__ import annotations

import importlib.util
import pathlib
import sys
import warnings

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.io.scene import load_scene

ROOT = pathlib.Path(__file__).resolve().parents[3]
_spec = importlib.util.spec_from_file_location("crankshaft_example",
                                               ROOT / "examples" / "crankshaft.py")
crank = sys.modules.setdefault(_spec.name, importlib.util.module_from_spec(_spec))
_spec.loader.exec_module(crank)

T_CRANK = 1.0      # about two crank turns
T_BRICARD = 1.0    # P3 travels from x = 1 to x = 0.27 m
P_REDUNDANT = [("P", "z"), ("P", "axis f"), ("P", "axis g")]
#: reaction components (force x, y, z, moment x, y, z) that a self-stress of the planar loop
#: moves: z force, x and y moments
OUT_OF_PLANE = [2, 3, 4]


_cache = private_cache("cache_loops", scope="module")


def _quiet(fn, *args, **kwargs):
    """Run a simulation whose undetermined reactions warn (checked separately)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return fn(*args, **kwargs)


# ------------------------------------------------------------------------------ crankshaft
@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
def test_info_names_the_three_equations_of_the_p1_p2_joint(coordinates):
    data = casmbd.info(crank.crankshaft(coordinates))
    assert [(r["joint"], r["equation"]) for r in data["redundant_equations"]] == P_REDUNDANT
    assert data["degrees_of_freedom"] == 1
    assert data["rank"] == data["n_constraints"] - 3


def test_closures_at_p():
    """In-line at P and the RSUP variant are non-redundant; a universal joint (spherical + one
    dot-1) at P alone is not: its z equation and its cross condition repeat the other joints."""
    for closure, expected in (("inline", []), ("rsup", []),
                              ("universal", [("P", "z"), ("P", "cross")])):
        data = casmbd.info(crank.crankshaft("joint", closure))
        assert [(r["joint"], r["equation"]) for r in data["redundant_equations"]] == expected
        assert data["degrees_of_freedom"] == 1


def test_scene_is_the_joint_coordinate_builder():
    scene = casmbd.System(load_scene(ROOT / "examples" / "crankshaft.toml"))
    built = casmbd.System(crank.crankshaft("joint"))
    assert scene.coordinate_names == built.coordinate_names
    assert np.allclose(scene.initial_coordinates(), built.initial_coordinates(), atol=1e-14)
    assert np.allclose(scene.initial_velocities(), built.initial_velocities(), atol=1e-13)


@pytest.fixture(scope="module")
def inline():
    """Non-redundant reference: the loop closed by an in-line joint at P."""
    return casmbd.simulate(crank.crankshaft("joint", "inline"), t_end=T_CRANK, steps=20,
                           rtol=1e-12)


@pytest.fixture(scope="module")
def redundant():
    """The all-revolute model: coordinates × option -> result (warnings recorded)."""
    out = {}
    for coords in ("absolute", "joint"):
        for option in ("remove", "minimum_norm"):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                res = casmbd.simulate(crank.crankshaft(coords), t_end=T_CRANK, steps=20,
                                      rtol=1e-12, redundancy=option)
            out[coords, option] = (res, [str(w.message) for w in caught
                                         if issubclass(w.category, RuntimeWarning)])
    return out


def _pose_difference(a, b) -> float:
    return max(float(np.max(np.abs(a["body_positions"] - b["body_positions"]))),
               float(np.max(np.abs(a["rotation_matrices"] - b["rotation_matrices"]))))


def test_rsup_and_inline_models_agree(inline):
    """The two non-redundant models are the same machine: same motion to 1e-8 over 1 s."""
    rsup = casmbd.simulate(crank.crankshaft("absolute", "rsup"), t_end=T_CRANK, steps=20,
                           rtol=1e-12)
    assert rsup.stats["redundant_equations"] == []
    assert _pose_difference(rsup, inline) < 1e-8
    # the crank turned about two revolutions
    pin = inline["marker_positions"][:, :2]
    turned = np.unwrap(np.arctan2(pin[:, 1], pin[:, 0]))
    assert turned[-1] - turned[0] > 3.5 * np.pi and np.all(np.diff(turned) > 0)


@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
@pytest.mark.parametrize("option", ["remove", "minimum_norm"])
def test_redundant_model_follows_the_non_redundant_one(redundant, inline, coordinates, option):
    res, _ = redundant[coordinates, option]
    labels = [f"joint 'P' equation '{eq}'" for _, eq in P_REDUNDANT]
    assert res.stats["redundant_equations"] == labels
    assert res.stats["redundancy"] == {"remove": "removed",
                                       "minimum_norm": "minimum-norm multipliers"}[option]
    assert _pose_difference(res, inline) < 1e-8
    assert np.max(np.abs(res["constraint_violation"])) < 1e-9
    # no damping: the energy is conserved (measured drift 1e-9 .. 5e-9 J of 13.6 J)
    energy = res["total_energy"]
    assert np.max(np.abs(energy - energy[0])) < 5e-8


def _check_reactions(res, caught, inline):
    joints = ["O", "A", "slide", "P"]
    assert res.stats["undetermined_reactions"] == {j: OUT_OF_PLANE for j in joints}
    assert res.stats["reactions"] == "minimum_norm"
    assert any("cannot be determined" in m for m in caught)
    reac, ref = res["joint_reactions"], inline["joint_reactions"]
    undetermined = np.zeros(6, dtype=bool)
    undetermined[OUT_OF_PLANE] = True
    assert np.all(np.isfinite(reac))
    determined = reac[:, :, ~undetermined]
    # force x, y and moment z of every joint as in the in-line model (P: the in-plane force)
    scale = 1.0 + np.max(np.abs(ref))
    assert np.max(np.abs(determined - ref[:, :, ~undetermined])) < 1e-8 * scale


@pytest.mark.parametrize("option", ["remove", "minimum_norm"])
def test_undetermined_reactions_joint_coordinates(redundant, inline, option):
    """P1/P2's z force and moments (and, by the loop's self-stress, those of O, A and slide)
    are flagged (minimum-norm values); the in-plane components equal the non-redundant
    model's."""
    _check_reactions(*redundant["joint", option], inline)


@pytest.mark.parametrize("option", ["remove", "minimum_norm"])
def test_undetermined_reactions_absolute_coordinates(redundant, inline, option):
    _check_reactions(*redundant["absolute", option], inline)


# ------------------------------------------------------------------------------ Bricard
def bricard(coordinates: str = "absolute") -> casmbd.Mechanism:
    """The example in ``coordinates`` (set explicitly: the scene leaves the choice to casmbd,
    which takes joint coordinates for its single loop)."""
    mech = load_scene(ROOT / "examples" / "bricard.toml")
    mech.coordinates = coordinates
    if coordinates != "absolute":
        mech.name = f"bricard_{coordinates}"
    return mech


@pytest.mark.parametrize("coordinates,n_q,n_c,redundant", [
    ("absolute", 35, 35, ("E", "axis g")),     # 5 bodies × 7; 6 joints × 5 + 5 normalisations
    ("joint", 5, 5, ("C", "axis g"))])         # a chain of five joint angles, loop joint C
def test_bricard_mobility_from_the_rank(coordinates, n_q, n_c, redundant):
    """Grübler: 6 × 5 bodies − 5 × 6 joint equations = 0; the rank says 1."""
    data = casmbd.info(bricard(coordinates))
    assert (data["n_coordinates"], data["n_constraints"]) == (n_q, n_c)
    assert data["degrees_of_freedom"] == 1
    assert data["rank"] == n_c - 1
    assert [(r["joint"], r["equation"]) for r in data["redundant_equations"]] == [redundant]


@pytest.fixture(scope="module")
def bricard_runs():
    """{(label, rtol): result}: absolute/default and joint/kkt_ode with the row removed."""
    out = {}
    for label, coords, formulation, option in (
            ("absolute default", "absolute", None, "auto"),
            ("joint kkt_ode", "joint", "kkt_ode", "remove")):
        sim = casmbd.Simulator(bricard(coords), formulation, redundancy=option)
        for rtol in (1e-10, 1e-12):
            out[label, rtol] = _quiet(sim.run, T_BRICARD, 20, rtol=rtol)
    return out


def test_bricard_motion_converges(bricard_runs):
    """Reference: the default formulation at rtol 1e-12.  The second description and
    formulation agrees with it to 1e-9 at the same tolerance (self-converged), and both runs at
    rtol 1e-10 to 1e-7 — on the trajectory of P3 and on every body position."""
    ref = bricard_runs["absolute default", 1e-12]
    assert ref.stats["redundancy"] == "minimum-norm multipliers"
    assert bricard_runs["joint kkt_ode", 1e-12].stats["redundancy"] == "removed"
    p3 = ref["marker_positions"]
    assert p3[-1, 0] < 0.5                      # it really moves
    for (label, rtol), res in bricard_runs.items():
        tol = 1e-9 if rtol == 1e-12 else 1e-7
        assert np.max(np.abs(res["marker_positions"] - p3)) < tol, (label, rtol)
        assert np.max(np.abs(res["body_positions"] - ref["body_positions"])) < tol, (label, rtol)


def test_bricard_energy_and_constraints(bricard_runs):
    """No damping: |E(t) − E(0)| < 2e-9 J at rtol 1e-12 (measured 1.2e-10 and 3.2e-10 J of a
    4.1 J exchange between potential and kinetic energy) and < 2e-7 J at rtol 1e-10 (2.0e-9,
    3.6e-8 J: kkt_ode has no constraint stabilisation); the joints stay closed."""
    for (label, rtol), res in bricard_runs.items():
        energy = res["total_energy"]
        tight = rtol == 1e-12
        assert np.max(np.abs(energy - energy[0])) < (2e-9 if tight else 2e-7), (label, rtol)
        assert np.max(res["constraint_violation"]) < (1e-10 if tight else 1e-8), (label, rtol)
        assert np.ptp(res["potential_energy"]) > 4.0     # a real exchange of energy


def test_bricard_reactions_are_undetermined(bricard_runs):
    """One self-stress of the loop: the reaction components it moves are listed and reported
    for the minimum-norm multipliers (finite: issue 30); λ has no component along the
    self-stress."""
    res = bricard_runs["absolute default", 1e-12]
    flagged = res.stats["undetermined_reactions"]
    assert set(flagged) == {"O", "A", "B", "C", "D", "E"}
    assert flagged["O"] == [0, 1, 2, 3, 5] and flagged["E"] == [0, 1, 2, 4, 5]
    reac = res["joint_reactions"][1:]
    assert res.stats["reactions"] == "minimum_norm" and np.all(np.isfinite(reac))
    from casmbd.analysis.instant.undetermined_reactions import multiplier_null_space
    from casmbd.compiled.model import NumericModel

    model = NumericModel(bricard("absolute"), "info", mode="vm")
    for k in (3, 11, 20):
        null = multiplier_null_space(model.constraint_jacobian(res["q"][k], float(res.t[k])))
        lam = res["lambda"][k]
        assert null.shape[1] == 1
        assert abs(float(null[:, 0] @ lam)) < 1e-8 * (1 + np.max(np.abs(lam)))
    # a revolute joint to the ground transmits no moment about its fixed axis, O (y) and E (x):
    # zero up to λ times the constraint violation (measured 2e-9 N m)
    assert np.max(np.abs(reac[:, 0, 4])) < 1e-7 and np.max(np.abs(reac[:, 5, 3])) < 1e-7


def _truncated_accelerations(model, q, v, t) -> np.ndarray:
    """q̈ from the KKT system with C_q replaced by its rank-r part U_rᵀ C_q (singular values
    below 1e-8 σ_max dropped, as the rank check does): the q̈ of the independent equations."""
    m_mat = model.mass_matrix(q)
    m_mat = m_mat.toarray() if hasattr(m_mat, "toarray") else np.asarray(m_mat)
    force = model.applied_forces(q, v, t) + model.quadratic_velocity_forces(q, v)
    cq = model.constraint_jacobian(q, t).toarray()
    u, sigma, _ = np.linalg.svd(cq)
    r = int(np.sum(sigma > 1e-8 * sigma[0]))
    c_r, g_r = u[:, :r].T @ cq, u[:, :r].T @ model.acceleration_rhs(q, v, t)
    kkt = np.block([[m_mat, c_r.T], [c_r, np.zeros((r, r))]])
    return np.linalg.solve(kkt, np.concatenate([force, g_r]))[:len(q)]


def test_bricard_reported_accelerations(bricard_runs):
    """The reported q̈ is the unique acceleration of the independent equations (to 1e-8)."""
    sim = casmbd.Simulator(bricard("joint"), "kkt_ode", redundancy="remove")
    res = bricard_runs["joint kkt_ode", 1e-12]
    worst = max(float(np.max(np.abs(res["a"][k] - _truncated_accelerations(
        sim.model, res["q"][k], res["v"][k], float(res.t[k]))))) for k in range(len(res.t)))
    assert worst < 1e-8
