"""Redundant constraint equations, locked mechanisms and singular poses (issue 7): the options
``redundancy="remove" | "minimum_norm"`` give the same motion, refused combinations fail
clearly, a locked mechanism fails at assembly naming its joints, and a failed run says how
close C_q is to losing rank."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import Mechanism
from casmbd.errors import AnalysisError, AssemblyError, IntegratorError
from tests.mechanisms import triple_crank as shared_triple_crank

G = 9.81


_cache = private_cache("cache_red")


def triple_crank() -> Mechanism:
    """Three parallel cranks under one coupler: one redundant loop equation."""
    return shared_triple_crank("absolute", name="triple_crank_red")


@pytest.fixture(scope="module")
def reference():
    with pytest.warns(RuntimeWarning):
        return casmbd.simulate(triple_crank(), t_end=0.5, steps=10, rtol=1e-12,
                               redundancy="minimum_norm")


def test_info_names_the_redundant_equation():
    data = casmbd.info(triple_crank())
    assert data["degrees_of_freedom"] == 1
    assert len(data["redundant_equations"]) == 1
    assert data["redundant_equations"][0]["joint"] in {"t2", "g2", "t1"}


@pytest.mark.parametrize("formulation,option", [
    ("augmented_lagrangian", "minimum_norm"), ("augmented_lagrangian", "remove"),
    ("kkt_ode", "auto"), ("kkt_ode", "remove"), ("index1", "auto"), ("nullspace", "auto")])
def test_options_give_the_same_motion(reference, formulation, option):
    """Every handled combination follows the minimum-norm augmented-Lagrangian reference to
    1e-8 m over 0.5 s (before the collinear singular pose at t ≈ 0.687 s)."""
    with pytest.warns(RuntimeWarning, match="cannot be determined"):
        out = casmbd.simulate(triple_crank(), t_end=0.5, steps=10, rtol=1e-11,
                              formulation=formulation, redundancy=option)
    assert out.stats["redundant_equations"] == reference.stats["redundant_equations"]
    expected = {"remove": "removed", "minimum_norm": "minimum-norm multipliers"}.get(option)
    if formulation in ("kkt_ode", "index1"):
        expected = "removed"
    if formulation == "nullspace":
        expected = "kept: independent coordinates chosen by rank"
    assert out.stats["redundancy"] == expected
    assert np.max(np.abs(out["body_positions"] - reference["body_positions"])) < 1e-8
    # the undetermined pin forces (along the cranks) are reported for the minimum-norm
    # multipliers (test_minimum_norm_multipliers): finite, flagged, the same for every option
    assert out.stats["reactions"] == "minimum_norm"
    assert np.all(np.isfinite(out["joint_reactions"]))
    np.testing.assert_allclose(out["joint_reactions"], reference["joint_reactions"], rtol=0,
                               atol=1e-6 * (1 + np.max(np.abs(reference["joint_reactions"]))))


def test_refused_combinations_fail_clearly():
    with pytest.raises(AnalysisError, match=r"kkt_ode.*regular KKT.*joint"):
        casmbd.Simulator(triple_crank(), formulation="kkt_ode", redundancy="minimum_norm")
    with pytest.raises(AnalysisError, match="redundancy must be one of"):
        casmbd.Simulator(triple_crank(), redundancy="drop")


def test_minimum_norm_multipliers(reference):
    """The reported λ satisfies C_qᵀ λ = Q − M q̈ and has no component in null(C_qᵀ)."""
    from casmbd.analysis.instant.undetermined_reactions import multiplier_null_space
    from casmbd.compiled.model import NumericModel

    model = NumericModel(triple_crank(), "dynamics")
    for k in (0, 5, 10):
        q, v, a, lam = (reference[key][k] for key in ("q", "v", "a", "lambda"))
        t = float(reference.t[k])
        cq = model.constraint_jacobian(q, t).toarray()
        force = model.applied_forces(q, v, t) + model.quadratic_velocity_forces(q, v)
        balance = cq.T @ lam - (force - model.mass_matrix(q) @ a)
        assert np.max(np.abs(balance)) < 1e-8 * (1 + np.max(np.abs(force)))
        null = multiplier_null_space(cq)
        assert null.shape[1] == 1
        assert abs(float(null[:, 0] @ lam)) < 1e-8 * (1 + np.max(np.abs(lam)))


def locked_four_bar() -> Mechanism:
    """A parallelogram with two diagonal braces of a length neither diagonal can have
    together: more independent equations than coordinates allow."""
    m = Mechanism("locked", gravity=(0.0, -G))
    m.add_body("crank", 1.0, 1.0 / 12.0, (0.0, 0.5), angle=math.pi / 2)
    m.add_body("coupler", 1.0, 1.0 / 12.0, (0.5, 1.0))
    m.add_body("rocker", 1.0, 1.0 / 12.0, (1.0, 0.5), angle=math.pi / 2)
    m.add_revolute("A", "ground", "crank", (0.0, 0.0))
    m.add_revolute("B", "crank", "coupler", (0.0, 1.0))
    m.add_revolute("C", "coupler", "rocker", (1.0, 1.0))
    m.add_revolute("D", "ground", "rocker", (1.0, 0.0))
    m.add_distance("brace", "ground", "coupler", (0.0, 0.0), (1.0, 1.0), length=1.2)
    m.add_distance("brace2", "ground", "coupler", (1.0, 0.0), (0.0, 1.0), length=1.2)
    return m


def test_locked_mechanism_fails_at_assembly_naming_joints():
    with pytest.raises(AssemblyError, match=r"locked.*'brace'.*'brace2'"):
        casmbd.simulate(locked_four_bar(), t_end=1.0, steps=10)
    data = casmbd.info(locked_four_bar())
    assert data["assembled"] is False and "locked" in data["assembly_error"]


def test_failed_run_reports_the_singular_configuration():
    """Coordinate partitioning cannot pass the collinear pose of the triple crank
    (t ≈ 0.687 s); the error gives the time, the rank and conditioning of C_q there (below
    1e-3, against 0.2 at the last output) and names a formulation that passes."""
    with pytest.raises(IntegratorError) as info:
        casmbd.simulate(triple_crank(), t_end=1.0, steps=10, formulation="partitioning",
                        rtol=1e-10)
    text = str(info.value)
    assert abs(info.value.time - 0.6871) < 1e-3
    import re

    match = re.search(r"C_q has rank (\d+) of 12 equations \(regular rank 11\), conditioning "
                      r"σ_min/σ_max = ([0-9.e+-]+): a singular configuration", text)
    assert match, text
    assert float(match.group(2)) < 1e-3
    assert "augmented_lagrangian" in text


@pytest.mark.parametrize("option", ["minimum_norm", "remove"])
def test_virtual_machine_mode_handles_redundant_equations(reference, option):
    """``mode="vm"`` (CasADi's virtual machine, whose QR refuses the singular KKT matrix of
    the post-processing) gives the compiled run's motion, accelerations and multipliers: the
    energies and residuals come from the model's own Functions and q̈, λ from the
    minimum-norm solve (measured: identical to 1e-15)."""
    runs = {}
    for mode in ("vm", "compiled"):
        with pytest.warns(RuntimeWarning, match="cannot be determined"):
            runs[mode] = casmbd.simulate(triple_crank(), t_end=0.5, steps=10, rtol=1e-12,
                                         redundancy=option, mode=mode)
    vm, comp = runs["vm"], runs["compiled"]
    for key in ("q", "a", "lambda", "total_energy", "constraint_violation"):
        np.testing.assert_allclose(vm[key], comp[key], rtol=0, atol=1e-9, err_msg=key)
    assert np.all(np.isfinite(vm["a"])) and np.all(np.isfinite(vm["total_energy"]))
    np.testing.assert_allclose(vm["q"], reference["q"], rtol=0, atol=1e-8)
