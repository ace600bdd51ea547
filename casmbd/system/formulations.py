"""Forward-dynamics formulations built from the same symbolic equations.

Every formulation is a CasADi Function with the integrator signature ``(t, x, z, p, u) ->
(ode, alg, quad, zero)`` (``casadi.dyn_in()``/``dyn_out()``), where ``p`` are the model
parameters; the actuator inputs are substituted as expressions of (t, p) before code generation,
so the integrator calls one compiled function.  The equations of motion are seed 000's
augmented form (eq. 6.138)::

    M q̈ + C_qᵀ λ = Q_e + Q_v,     C_q q̈ = γ

* ``index1`` — semi-explicit index-1 DAE for IDAS: differential x = (q, v), algebraic
  z = (q̈, λ) from the sparse KKT rows; optional Baumgarte terms replace γ by
  γ − 2α(C_q v + C_t) − β² C (seed 000, eqs. 6.214–6.217).
* ``ggl`` — Gear–Gupta–Leimkuhler stabilised index-2 DAE: q̇ = v − C_qᵀ μ, v̇ = q̈,
  M q̈ + C_qᵀ λ = Q, C = 0, C_q v + C_t = 0 (z = (q̈, λ, μ)).
* ``kkt_ode`` — ODE x = (q, v): λ from the Schur complement S = C_q M⁻¹ C_qᵀ (sparse,
  symmetric positive definite when C_q has full rank) with CasADi's code-generable sparse LDLᵀ;
  M⁻¹ is block diagonal (3×3 blocks), so nothing dense is ever formed.
* ``augmented_lagrangian`` — ODE x = (q, v) from the augmented-Lagrangian iteration of Bayo and
  García de Jalón (seed 003, mass-orthogonal projections): (M + α C_qᵀ C_q) q̈ = Q − C_qᵀ λ_i +
  α C_qᵀ γ_b, λ_{i+1} = λ_i + α (C_q q̈ − γ_b), with Baumgarte-stabilised γ_b, four
  iterations.  The matrix stays positive definite at singular configurations and with
  redundant constraints.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.system.articulated import articulated_accelerations
from casmbd.system.equations import System

FORMULATIONS = ("index1", "ggl", "kkt_ode", "augmented_lagrangian", "partitioning",
                "nullspace", "articulated")
#: formulations whose right-hand side is evaluated numerically (not a CasADi expression);
#: they are integrated by :mod:`casmbd.analysis.partitioning`
NUMERIC_FORMULATIONS = ("partitioning", "nullspace")


@dataclass
class Formulation:
    """A dynamics Function ready for an integrator, with its state layout."""

    name: str
    kind: str  # "dae" or "ode"
    function: ca.Function
    nq: int
    nz: int
    extra: list[ca.Function] = field(default_factory=list)
    options: dict = field(default_factory=dict)

    @property
    def functions(self) -> list[ca.Function]:
        """The Functions to compile: the dynamics and, for DAEs, its exact Jacobian."""
        return [self.function, *self.extra]


def _sym_inputs(system: System):
    return system.t, system.q, system.v, system.p


def _baumgarte_gamma(system: System, alpha: float, beta: float) -> ca.SX:
    gamma = system.acceleration_rhs
    if alpha == 0.0 and beta == 0.0:
        return gamma
    cdot = ca.mtimes(system.constraint_jacobian, system.v) + system.constraint_time_derivative
    return gamma - 2.0 * alpha * cdot - beta**2 * system.constraints


def _forces(system: System, inputs: ca.SX | None) -> ca.SX:
    """Q_e + Q_v with the actuator inputs u replaced by their expressions of (t, p)."""
    forces = system.applied_forces + system.quadratic_velocity_forces
    if system.u.numel() == 0:
        return forces
    u_expr = ca.SX.zeros(system.u.numel()) if inputs is None else inputs
    return ca.substitute(forces, system.u, u_expr)


def _dyn(name: str, t, x, z, p, ode, alg) -> ca.Function:
    u = ca.SX(0, 1) if isinstance(x, ca.SX) else ca.MX(0, 1)
    empty = ca.SX(0, 1) if isinstance(x, ca.SX) else ca.MX(0, 1)
    return ca.Function(name, [t, x, z, p, u], [ode, alg, empty, empty],
                       ca.dyn_in(), ca.dyn_out())


def index1(system: System, alpha: float = 0.0, beta: float = 0.0,
           inputs: ca.SX | None = None) -> Formulation:
    """Semi-explicit index-1 DAE: x = (q, v), z = (q̈, λ)."""
    t, q, v, pu = _sym_inputs(system)
    a = ca.SX.sym("a", system.nq)
    lam = ca.SX.sym("lambda", system.nc)
    alg = ca.vertcat(
        ca.mtimes(system.mass_matrix, a) + ca.mtimes(system.constraint_jacobian.T, lam)
        - _forces(system, inputs),
        ca.mtimes(system.constraint_jacobian, a) - _baumgarte_gamma(system, alpha, beta))
    f = _dyn("dyn_index1", t, ca.vertcat(q, v), ca.vertcat(a, lam), pu, ca.vertcat(v, a), alg)
    return Formulation("index1", "dae", f, system.nq, system.nq + system.nc, [f.jacobian()],
                       {"alpha": alpha, "beta": beta})


def ggl(system: System, inputs: ca.SX | None = None) -> Formulation:
    """Gear–Gupta–Leimkuhler index-2 DAE: x = (q, v), z = (q̈, λ, μ)."""
    t, q, v, pu = _sym_inputs(system)
    a = ca.SX.sym("a", system.nq)
    lam = ca.SX.sym("lambda", system.nc)
    mu = ca.SX.sym("mu", system.nc)
    cq = system.constraint_jacobian
    alg = ca.vertcat(
        ca.mtimes(system.mass_matrix, a) + ca.mtimes(cq.T, lam) - _forces(system, inputs),
        system.constraints,
        ca.mtimes(cq, v) + system.constraint_time_derivative)
    ode = ca.vertcat(v - ca.mtimes(cq.T, mu), a)
    f = _dyn("dyn_ggl", t, ca.vertcat(q, v), ca.vertcat(a, lam, mu), pu, ode, alg)
    return Formulation("ggl", "dae", f, system.nq, system.nq + 2 * system.nc, [f.jacobian()])


def _block_inverse(system: System) -> ca.SX:
    """M⁻¹ block by block; diagonal blocks (centroidal planar frames) invert entry-wise."""
    m = system.mass_matrix
    blocks = []
    for name in system.body_names:
        sl = system.body_slice(name)
        block = m[sl, sl]
        if block.sparsity().is_diag():
            blocks.append(ca.diag(1.0 / ca.diag(block)))
        else:
            blocks.append(ca.inv(block))
    return ca.diagcat(*blocks)


def kkt_ode(system: System, alpha: float = 0.0, beta: float = 0.0,
            inputs: ca.SX | None = None) -> Formulation:
    """ODE on (q, v) with λ from the sparse Schur complement and an LDLᵀ solve."""
    t, q, v, pu = _sym_inputs(system)
    q_dot = v
    if not system.local:
        return _kkt_ode_coupled(system, alpha, beta, inputs)
    if system.nc == 0:
        a = ca.mtimes(_block_inverse(system), _forces(system, inputs))
        f = _dyn("dyn_kkt_ode", t, ca.vertcat(q, v), ca.SX(0, 1), pu, ca.vertcat(q_dot, a),
                 ca.SX(0, 1))
        return Formulation("kkt_ode", "ode", f, system.nq, 0)
    minv = _block_inverse(system)
    cq = system.constraint_jacobian
    minv_q = ca.mtimes(minv, _forces(system, inputs))
    minv_ct = ca.mtimes(minv, cq.T)
    schur = ca.mtimes(cq, minv_ct)
    rhs = ca.mtimes(cq, minv_q) - _baumgarte_gamma(system, alpha, beta)
    parts = ca.Function("kkt_parts", [t, q, v, pu], [schur, rhs, minv_q, minv_ct])
    tm, qm, vm, pm = (ca.MX.sym(n, s.sparsity()) for n, s in
                      (("t", t), ("q", q), ("v", v), ("p", pu)))
    s_x, r_x, mq_x, mc_x = parts(tm, qm, vm, pm)
    solver = ca.Linsol("kkt_ldl", "ldl", schur.sparsity())
    lam = solver.solve(s_x, r_x)
    acc = mq_x - ca.mtimes(mc_x, lam)
    f = _dyn("dyn_kkt_ode", tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm, ca.vertcat(vm, acc),
             ca.MX(0, 1))
    return Formulation("kkt_ode", "ode", f, system.nq, 0, [], {"alpha": alpha, "beta": beta})


def _kkt_ode_coupled(system: System, alpha: float, beta: float,
                     inputs: ca.SX | None) -> Formulation:
    """KKT ODE for a coupled (joint-coordinate) mass matrix: M⁻¹ [Q, C_qᵀ] by a sparse LDLᵀ of
    the symmetric positive definite M, then the Schur complement C_q M⁻¹ C_qᵀ for λ."""
    t, q, v, pu = _sym_inputs(system)
    nc = system.nc
    cq = system.constraint_jacobian
    outs = [system.mass_matrix, _forces(system, inputs)]
    if nc:
        outs += [cq, _baumgarte_gamma(system, alpha, beta)]
    parts = ca.Function("kkt_coupled_parts", [t, q, v, pu], outs)
    tm, qm, vm, pm = (ca.MX.sym(n, s.sparsity()) for n, s in
                      (("t", t), ("q", q), ("v", v), ("p", pu)))
    got = parts(tm, qm, vm, pm)
    m_x, f_x = got[0], got[1]
    solver = ca.Linsol("m_ldl", "ldl", system.mass_matrix.sparsity())
    if nc:
        cq_x, g_x = got[2], got[3]
        both = solver.solve(m_x, ca.horzcat(f_x, cq_x.T))
        minv_q, minv_ct = both[:, 0], both[:, 1:]
        schur = ca.mtimes(cq_x, minv_ct)
        lam = ca.solve(schur, ca.mtimes(cq_x, minv_q) - g_x)
        acc = minv_q - ca.mtimes(minv_ct, lam)
    else:
        acc = solver.solve(m_x, f_x)
    f = _dyn("dyn_kkt_ode", tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm, ca.vertcat(vm, acc),
             ca.MX(0, 1))
    return Formulation("kkt_ode", "ode", f, system.nq, 0, [], {"alpha": alpha, "beta": beta})


def articulated(system: System, inputs: ca.SX | None = None) -> Formulation:
    """ODE on (q, v) of a tree in joint coordinates by the articulated-body recursion, O(N)
    operations (:mod:`casmbd.system.articulated`)."""
    t, q, v, pu = _sym_inputs(system)
    acc = articulated_accelerations(system)
    if system.u.numel():
        u_expr = ca.SX.zeros(system.u.numel()) if inputs is None else inputs
        acc = ca.substitute(acc, system.u, u_expr)
    f = _dyn("dyn_articulated", t, ca.vertcat(q, v), ca.SX(0, 1), pu, ca.vertcat(v, acc),
             ca.SX(0, 1))
    return Formulation("articulated", "ode", f, system.nq, 0)


def augmented_lagrangian(system: System, penalty: float | None = None, iterations: int = 4,
                         alpha: float = 20.0, beta: float = 20.0,
                         inputs: ca.SX | None = None) -> Formulation:
    """ODE on (q, v) by the augmented-Lagrangian iteration with Baumgarte terms.

    ``penalty`` defaults to 1e5 times the ratio of the mean mass-matrix diagonal to the mean
    diagonal of C_qᵀ C_q at the initial guess, so that it is unit-consistent.  Measured
    trade-off (docs/performance.md): a larger penalty converges in fewer iterations but makes
    M + α C_qᵀC_q ill-conditioned (cond ≈ α), which puts noise of ≈ cond·ε into every
    right-hand side; a smaller one leaves weakly constrained modes unconverged.  At rtol 1e-12:
    1e7 with 3 iterations floored the 8-rod chain's tip error at 6e-10 (25 000 Adams steps);
    1e4 with 4 floored the 32-rod chain at 5e-7; 1e5 with 4 reaches 8e-12 (8 rods) and 1e-10
    (32 rods).
    """
    t, q, v, pu = _sym_inputs(system)
    if system.nc == 0:
        return kkt_ode(system, inputs=inputs)
    cq = system.constraint_jacobian
    if penalty is None:
        penalty = _default_penalty(system)
    if not (np.isfinite(penalty) and penalty > 0):
        raise ModelError(f"augmented_lagrangian: penalty must be > 0, got {penalty}")
    gamma_b = _baumgarte_gamma(system, alpha, beta)
    k_mat = system.mass_matrix + penalty * ca.mtimes(cq.T, cq)
    parts = ca.Function("al_parts", [t, q, v, pu], [k_mat, _forces(system, inputs), cq, gamma_b])
    tm, qm, vm, pm = (ca.MX.sym(n, s.sparsity()) for n, s in
                      (("t", t), ("q", q), ("v", v), ("p", pu)))
    k_x, f_x, cq_x, g_x = parts(tm, qm, vm, pm)
    solver = ca.Linsol("al_ldl", "ldl", k_mat.sparsity())
    lam = ca.MX.zeros(system.nc)
    acc = None
    for _ in range(iterations):
        acc = solver.solve(k_x, f_x - ca.mtimes(cq_x.T, lam) + penalty * ca.mtimes(cq_x.T, g_x))
        lam = lam + penalty * (ca.mtimes(cq_x, acc) - g_x)
    f = _dyn("dyn_augmented_lagrangian", tm, ca.vertcat(qm, vm), ca.MX(0, 1), pm,
             ca.vertcat(vm, acc), ca.MX(0, 1))
    return Formulation("augmented_lagrangian", "ode", f, system.nq, 0, [],
                       {"penalty": penalty, "iterations": iterations, "alpha": alpha,
                        "beta": beta})


def _default_penalty(system: System) -> float:
    q0 = system.initial_coordinates()
    f = ca.Function("scale", [system.q, system.t, system.p],
                    [ca.diag(system.mass_matrix), ca.sum1(system.constraint_jacobian**2).T])
    m_diag, c_diag = (np.asarray(x).ravel() for x in f(q0, 0.0, system.parameter_values))
    c_mean = float(np.mean(c_diag[c_diag > 0])) if np.any(c_diag > 0) else 1.0
    with np.errstate(all="ignore"):
        penalty = 1e5 * float(np.mean(m_diag)) / c_mean
    if not (np.isfinite(penalty) and penalty > 0):
        # absurd masses, inertias or positions (1e308): name the coordinates that carry them
        names = system.coordinate_names
        i, j = int(np.argmax(np.abs(m_diag))), int(np.argmax(np.abs(c_diag)))
        raise ModelError(f"augmented_lagrangian: no usable penalty ({penalty:g}) from the "
                         f"initial pose: mass-matrix diagonal up to {m_diag[i]:g} (coordinate "
                         f"'{names[i]}'), C_q^T C_q diagonal up to {c_diag[j]:g} (coordinate "
                         f"'{names[j]}'); a mass, inertia or position is out of range")
    return penalty


def build(system: System, name: str, **options) -> Formulation:
    """Build the formulation ``name`` (one of :data:`FORMULATIONS`)."""
    builders = {"index1": index1, "ggl": ggl, "kkt_ode": kkt_ode,
                "augmented_lagrangian": augmented_lagrangian, "articulated": articulated}
    if name in NUMERIC_FORMULATIONS:
        # the numeric formulations use the model's equations only; the symbolic KKT ODE is
        # kept as the Function compiled alongside (used for fixed-step references)
        form = kkt_ode(system, inputs=options.get("inputs"))
        form.name = name
        form.kind = "numeric"
        return form
    if name not in builders:
        raise ModelError(f"unknown formulation '{name}' (known: {', '.join(FORMULATIONS)})")
    return builders[name](system, **options)


def post_processing(system: System, inputs: ca.SX | None = None) -> ca.Function:
    """q̈, λ from the sparse KKT system and diagnostics, for mapped evaluation at outputs.

    ``post(q, v, t, p) -> (a, lambda, residual, T, V, C_max, Cdot_max)``: the KKT system of
    seed 000, eq. 6.138, solved by CasADi's code-generable sparse QR; ``residual`` is the
    max-norm of the KKT residual, so that singular points (redundant constraints, singular
    poses) can be recomputed by a minimum-norm solve.
    """
    t, q, v, p = _sym_inputs(system)
    forces = _forces(system, inputs)
    m_mat = system.mass_matrix
    cq = system.constraint_jacobian
    n, m = system.nq, system.nc
    if m:
        kkt = ca.blockcat([[m_mat, cq.T], [cq, ca.SX(m, m)]])
        rhs = ca.vertcat(forces, system.acceleration_rhs)
    else:
        kkt, rhs = m_mat, forces
    cdot = ca.mtimes(cq, v) + system.constraint_time_derivative
    c_max = ca.mmax(ca.fabs(system.constraints)) if m else ca.SX(0.0)
    cdot_max = ca.mmax(ca.fabs(cdot)) if m else ca.SX(0.0)
    parts = ca.Function("post_parts", [q, v, t, p],
                        [kkt, rhs, system.kinetic_energy, system.potential_energy, c_max,
                         cdot_max])
    qm, vm, tm, pm = (ca.MX.sym(name, s.sparsity()) for name, s in
                      (("q", q), ("v", v), ("t", t), ("p", p)))
    k_x, r_x, kin, pot, c_x, cd_x = parts(qm, vm, tm, pm)
    sol = ca.Linsol("post_qr", "qr", kkt.sparsity()).solve(k_x, r_x)
    residual = ca.mmax(ca.fabs(ca.mtimes(k_x, sol) - r_x))
    lam = sol[n:] if m else ca.MX(0, 1)
    return ca.Function("post", [qm, vm, tm, pm],
                       [sol[:n], lam, residual, kin, pot, c_x, cd_x],
                       ["q", "v", "t", "p"],
                       ["a", "lambda", "residual", "T", "V", "C_max", "Cdot_max"])
