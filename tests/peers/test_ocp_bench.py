"""The hand-written CasADi baseline of benchmarks/ocp_handwritten.py solves the same problem as
casmbd: objectives, not timings."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks.ocp_handwritten import PROBLEMS, radau_matrices, solve
from casmbd.io.ocp_table import load_ocp

OCP_DIR = Path(__file__).resolve().parents[2] / "ocp"


def test_radau_matrices_differentiate_cubics_exactly():
    """Degree-3 Radau: the Lagrange basis through 0 and the 3 points differentiates any cubic
    exactly (C) and Radau IIA ends at its last point (D = e_4); checked on p(τ) = 1 + τ − 2τ³."""
    tau, c, d = radau_matrices(3)
    assert tau[-1] == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(d, [0, 0, 0, 1], atol=1e-12)
    p = 1 + tau - 2 * tau**3
    dp = 1 - 6 * tau**2
    np.testing.assert_allclose(p @ c, dp, atol=1e-12)


def test_cart_pole_baseline_matches_casmbd():
    """Cart-pole swing-up (ocp/cart_pole.toml): the hand-written Opti problem (closed-form
    Lagrangian, explicit accelerations) and casmbd's (the default dynamics="auto": explicit
    accelerations, the last Radau point shared with the next node) with the same transcription
    (one degree-3 Radau element per interval, N = 50) have the same optimum: measured
    53.664762661923 for both (difference 3e-14 relative), asserted to 1e-9 relative (IPOPT's
    tolerance 1e-8 on the scaled KKT conditions, a converged solution of two algebraically
    equivalent NLPs).  The issue quotes 53.66 (1e-3 relative)."""
    base = solve("cart_pole")
    assert base.success
    ocp = load_ocp(OCP_DIR / "cart_pole.toml")
    ocp.compile, ocp.subintervals, ocp.degree = False, 1, 3
    ours = ocp.solve()
    assert abs(base.objective - ours.objective) < 1e-9 * ours.objective
    assert abs(base.objective - PROBLEMS["cart_pole"]) < 1e-3 * PROBLEMS["cart_pole"]
    assert math.isfinite(base.solve_seconds) and base.iterations > 0


def test_short_solves_are_repeated_until_half_a_second():
    """benchmarks.ocp_problems.enough: ``--repeat`` solves at least, and with ``--repeat`` > 1
    more until they add up to MIN_SOLVE_SECONDS (0.5 s) or MAX_SOLVES (25) — a cold run
    (``--repeat 1``) solves once."""
    from benchmarks.ocp_problems import MAX_SOLVES, MIN_SOLVE_SECONDS, enough

    assert MIN_SOLVE_SECONDS == 0.5 and MAX_SOLVES == 25
    assert not enough([], 1) and enough([0.01], 1)
    assert not enough([0.2, 0.2], 3) and enough([0.2, 0.2, 0.2], 3)
    assert not enough([0.1] * 3, 3) and enough([0.1] * 5, 3)
    assert not enough([0.01] * 24, 3) and enough([0.01] * 25, 3)


def test_ur5_baseline_dynamics_match_pinocchio_and_casmbd():
    """The UR5 baseline's hand-written recursive Newton–Euler τ(q, q̇, q̈) equals
    Pinocchio's ``rnea`` on the same URDF (measured 1.4e-14 N m) and casmbd's implicit
    equations-of-motion residual of ``ocp/ur5_min_time.toml`` vanishes at u = τ (measured
    3e-15) at three random states; asserted to 1e-10 N m."""
    import casadi as ca

    from benchmarks.ocp_handwritten import UR5_URDF, ur5_inverse_dynamics
    from casmbd.ocp.transcription import Transcription

    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    data = model.createData()
    q, v, a = (ca.SX.sym(n, 6) for n in "qva")
    rnea = ca.Function("rnea", [q, v, a], [ur5_inverse_dynamics()(q, v, a)])
    tr = Transcription(load_ocp(OCP_DIR / "ur5_min_time.toml"))
    rng = np.random.default_rng(7)
    for _ in range(3):
        qq, vv, aa = rng.normal(size=(3, 6))
        tau = np.asarray(rnea(qq, vv, aa)).ravel()
        q_pin = np.concatenate([qq[:5], [np.cos(qq[5]), np.sin(qq[5])]])  # continuous joint
        assert np.max(np.abs(tau - pin.rnea(model, data, q_pin, vv, aa))) < 1e-10
        res = tr.res(ca.DM(qq), ca.DM(vv), ca.DM(aa), ca.DM.zeros(0), ca.DM(tau), 0.0, tr.p)[0]
        assert np.max(np.abs(np.asarray(ca.evalf(res)))) < 1e-10
