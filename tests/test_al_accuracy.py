"""Accelerations of the ODE formulations against an exact dense KKT solve (issue 22, item 2).

At random consistent states (q on C = 0 by Newton's method from a perturbed design pose, q̇ on
C_q q̇ + C_t = 0) the augmented-Lagrangian and KKT-ODE right-hand sides must give the q̈ of

    [M  C_qᵀ] [q̈]   [Q]
    [C_q  0 ] [λ] = [γ_b],

solved here independently by numpy (least squares, then iterative refinement with the residual
accumulated in extended precision), with γ_b the formulation's own right-hand side (Baumgarte
terms α = β = 20 for the augmented Lagrangian, none for ``kkt_ode``; at a state with C ≈ 1e-15
the Baumgarte terms are not negligible at this accuracy).  Bound: 1e-12 relative to max |q̈|.
Before the residual (correction) form of the augmented-Lagrangian iteration the error was
≈ 1e-11 (rounding of cond(M + α C_qᵀC_q) ≈ 1e5) on the four-bar and the chains and 1e-6 on the
spatial chain (four iterations left its slowest constraint direction, α s = 26, unconverged).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import casmbd
from benchmarks.chains import pendulum_chain
from benchmarks.work_precision import chain_in_space
from casmbd.errors import ModelError
from casmbd.system.equations import System
from casmbd.system.formulations import build
from casmbd.system.formulations.augmented_lagrangian import al_solver
from casmbd.system.formulations.base import _baumgarte_gamma, _forces
from tests.mechanisms import triple_crank

BOUND = 1e-12
STATES = 6


def _fourbar(coordinates):
    mech = casmbd.load_scene("examples/parallelogram.toml")
    mech.coordinates = coordinates
    return mech


def _chain(coordinates):
    mech = pendulum_chain(5)
    mech.coordinates = coordinates
    return mech


CASES = {
    "fourbar-absolute": (lambda: _fourbar("absolute"), 0.3),
    "fourbar-joint": (lambda: _fourbar("joint"), 0.3),
    "fourbar-natural": (lambda: _fourbar("natural"), 0.3),
    "chain5-absolute": (lambda: _chain("absolute"), 0.3),
    "chain5-natural": (lambda: _chain("natural"), 0.3),
    "spatial-chain4-euler": (lambda: chain_in_space(4, "absolute"), 0.05),
    "triple-crank-redundant": (lambda: triple_crank("absolute"), 0.3),
}


def _rank(cq: np.ndarray) -> int:
    sv = np.linalg.svd(cq, compute_uv=False)
    return int(np.sum(sv > 1e-2 * sv[0]))


def consistent_states(system: System, scale: float, count: int, seed: int = 7):
    """``count`` states (q, q̇) with |C| ≤ 1e-13 and C_q q̇ + C_t = 0 (least squares), away
    from singular poses: C_q has as many singular values above 1e-2 of the largest as at the
    design pose.  Near a singular pose (σ → 0) the exact q̈ answers the part of γ_b along the
    vanishing direction with O(1/σ), while the augmented Lagrangian converges that direction
    at the rate 1/(1 + α σ²/m) per iteration — the regularisation that keeps it on its branch
    there.  Measured on the redundant triple crank (default penalty, 10 iterations): 6.7e-12
    relative at a state with σ/σ_max ≈ 1e-8 beside the redundant zero, 17 relative at one
    with 1.6e-4; tests/test_dynamics.py and tests/test_singular_chains.py cover those poses."""
    rng = np.random.default_rng(seed)
    parts = ca.Function("c", [system.q, system.t, system.p],
                        [system.constraints, system.constraint_jacobian,
                         system.constraint_time_derivative])
    p = system.parameter_values

    def assemble(q):
        for _ in range(50):
            c, cq, _ = (np.asarray(x) for x in parts(q, 0.0, p))
            q = q - np.linalg.lstsq(cq, c.ravel(), rcond=None)[0]
        return q

    rank = _rank(np.asarray(parts(assemble(system.initial_coordinates()), 0.0, p)[1]))
    states = []
    while len(states) < count:
        q = assemble(system.initial_coordinates() + scale * rng.standard_normal(system.nq))
        c, cq, ct = (np.asarray(x) for x in parts(q, 0.0, p))
        if not (np.all(np.isfinite(q)) and np.max(np.abs(c)) <= 1e-13 and _rank(cq) == rank):
            continue
        v = rng.standard_normal(system.nq)
        v = v - np.linalg.lstsq(cq, cq @ v + ct.ravel(), rcond=None)[0]
        states.append((q, v))
    return states


def exact_acceleration(system: System, q, v, baumgarte: float) -> np.ndarray:
    """q̈ of the dense KKT system (least squares + refinement in extended precision)."""
    f = ca.Function("kkt", [system.q, system.v, system.t, system.p],
                    [system.mass_matrix, _forces(system, None), system.constraint_jacobian,
                     _baumgarte_gamma(system, baumgarte, baumgarte)])
    m, forces, cq, gamma = (np.asarray(x) for x in f(q, v, 0.0, system.parameter_values))
    nc = system.nc
    kkt = np.block([[m, cq.T], [cq, np.zeros((nc, nc))]])
    rhs = np.concatenate([forces.ravel(), gamma.ravel()])
    x = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
    wide = kkt.astype(np.longdouble)
    for _ in range(3):
        residual = (wide @ x.astype(np.longdouble) - rhs.astype(np.longdouble)).astype(float)
        x = x - np.linalg.lstsq(kkt, residual, rcond=None)[0]
    return x[:system.nq]


def _acceleration(system: System, form, q, v) -> np.ndarray:
    out = form.function(0.0, np.concatenate([q, v]), [], system.parameter_values, [])[0]
    return np.asarray(out).ravel()[system.nq:]


def _relative_errors(name, formulation, baumgarte, **options):
    make, scale = CASES[name]
    system = System(make())
    form = build(system, formulation, **options)
    errors = []
    for q, v in consistent_states(system, scale, STATES):
        exact = exact_acceleration(system, q, v, baumgarte)
        got = _acceleration(system, form, q, v)
        errors.append(np.max(np.abs(got - exact)) / np.max(np.abs(exact)))
    return np.array(errors)


@pytest.mark.parametrize("name", list(CASES))
def test_augmented_lagrangian_matches_exact_kkt(name):
    """Default penalty and iterations: q̈ within 1e-12 relative of the exact KKT solution
    (measured ≤ 1e-15 on these cases; redundant equations included)."""
    errors = _relative_errors(name, "augmented_lagrangian", 20.0)
    assert np.max(errors) <= BOUND, errors


@pytest.mark.parametrize("name", [n for n in CASES if "redundant" not in n])
def test_kkt_ode_matches_exact_kkt(name):
    """The Schur-complement ODE (no Baumgarte terms): q̈ within 1e-12 relative."""
    errors = _relative_errors(name, "kkt_ode", 0.0)
    assert np.max(errors) <= BOUND, errors


def test_unconverged_iterations_are_detected():
    """The comparison discriminates: two iterations on the spatial chain leave its slowest
    constraint direction (α s ≈ 26) unconverged by far more than the bound."""
    errors = _relative_errors("spatial-chain4-euler", "augmented_lagrangian", 20.0,
                              iterations=2)
    assert np.max(errors) > 1e3 * BOUND


def test_solver_is_the_augmented_lagrangian_fixed_point():
    """``al_solver`` with k iterations equals k steps of the textbook iteration
    (M + α CᵀC) q̈ = Q − Cᵀλ + α Cᵀγ, λ ← λ + α (C q̈ − γ), done in numpy with a small
    penalty (where rounding is negligible) on a random SPD M and a rank-deficient C."""
    rng = np.random.default_rng(3)
    n, nc, alpha = 6, 4, 0.7
    root = rng.standard_normal((n, n))
    m = root @ root.T + n * np.eye(n)
    cq = rng.standard_normal((nc, n))
    cq[3] = cq[0] + cq[1]  # a redundant row
    forces, gamma = rng.standard_normal(n), rng.standard_normal(nc)
    gamma[3] = gamma[0] + gamma[1]
    for iterations in (1, 3, 7):
        lam, acc = np.zeros(nc), None
        k_mat = m + alpha * cq.T @ cq
        for _ in range(iterations):
            acc = np.linalg.solve(k_mat, forces - cq.T @ lam + alpha * cq.T @ gamma)
            lam = lam + alpha * (cq @ acc - gamma)
        solver = al_solver(ca.Sparsity.dense(n, n), ca.Sparsity.dense(nc, n), alpha,
                           iterations)
        got = np.asarray(solver(m, forces, cq, gamma)).ravel()
        assert np.max(np.abs(got - acc)) <= 1e-12 * np.max(np.abs(acc))


@pytest.mark.parametrize("iterations", [0, 2.5, "4"])
def test_bad_iteration_count_is_refused(iterations):
    with pytest.raises(ModelError, match="iterations must be an integer >= 1"):
        build(System(_fourbar("absolute")), "augmented_lagrangian", iterations=iterations)
