"""Semi-explicit DAE formulations for IDAS: ``index1`` and ``ggl``.

* ``index1`` — semi-explicit index-1 DAE: differential x = (q, v), algebraic z = (q̈, λ) from
  the sparse KKT rows; optional Baumgarte terms replace γ by γ − 2α(C_q v + C_t) − β² C
  (seed 000, eqs. 6.214–6.217).
  Reaction-proportional joint friction uses λ directly: Q_e(q, v, λ) (IDAS's Newton solves
  the algebraic equations with it).
* ``ggl`` — Gear–Gupta–Leimkuhler stabilised index-2 DAE: q̇ = v − C_qᵀ μ, v̇ = q̈,
  M q̈ + C_qᵀ λ = Q, C = 0, C_q v + C_t = 0 (z = (q̈, λ, μ)).  A row written at the velocity
  level (non-holonomic, C ≡ 0) keeps C_q v + C_t = 0 and has no position correction: its μ is
  held at 0 and q̇ = v − (∂C/∂q)ᵀ μ takes the position Jacobian of the holonomic rows.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.analysis.formulations.base import (
    Formulation,
    FormulationKind,
    baumgarte_acceleration_rhs,
    dae_function,
    generalized_forces,
    symbolic_arguments,
)
from casmbd.errors import AnalysisError
from casmbd.model.needs import ALL_NEEDS, EVENT_NEEDS
from casmbd.system.equations import System


def index1(system: System, alpha: float = 0.0, beta: float = 0.0,
           inputs: ca.SX | None = None) -> Formulation:
    """Semi-explicit index-1 DAE: x = (q, v), z = (q̈, λ)."""
    t, q, v, pu = symbolic_arguments(system)
    a = ca.SX.sym("a", system.nq)
    lam = ca.SX.sym("lambda", system.nc)
    alg = ca.vertcat(
        ca.mtimes(system.mass_matrix, a) + ca.mtimes(system.constraint_jacobian.T, lam)
        - generalized_forces(system, inputs, lam),
        ca.mtimes(system.constraint_jacobian, a) - baumgarte_acceleration_rhs(system, alpha, beta))
    f = dae_function("dyn_index1", t, ca.vertcat(q, v), ca.vertcat(a, lam), pu,
                     ca.vertcat(v, a), alg)
    return Formulation("index1", "dae", f, system.nq, system.nq + system.nc, [f.jacobian()],
                       {"alpha": alpha, "beta": beta})


def ggl(system: System, inputs: ca.SX | None = None) -> Formulation:
    """Gear–Gupta–Leimkuhler index-2 DAE: x = (q, v), z = (q̈, λ, μ)."""
    t, q, v, pu = symbolic_arguments(system)
    a = ca.SX.sym("a", system.nq)
    lam = ca.SX.sym("lambda", system.nc)
    mu = ca.SX.sym("mu", system.nc)
    cq = system.constraint_jacobian
    # the position rows: C = 0 with the correction −(∂C/∂q)ᵀ μ; a row written at the velocity
    # level (C ≡ 0, non-holonomic) has no position to correct: its μ is 0
    position = system.constraints
    velocity_rows = list(getattr(system, "velocity_rows", ()))
    if velocity_rows:
        mask = np.ones(system.nc)
        mask[velocity_rows] = 0.0
        position = position + ca.mtimes(ca.diag(ca.DM(1.0 - mask)), mu)
    alg = ca.vertcat(
        ca.mtimes(system.mass_matrix, a) + ca.mtimes(cq.T, lam)
        - generalized_forces(system, inputs, lam),
        position,
        ca.mtimes(cq, v) + system.constraint_time_derivative)
    correction = system.position_jacobian if velocity_rows else cq
    ode = ca.vertcat(v - ca.mtimes(correction.T, mu), a)
    f = dae_function("dyn_ggl", t, ca.vertcat(q, v), ca.vertcat(a, lam, mu), pu, ode, alg)
    return Formulation("ggl", "dae", f, system.nq, system.nq + 2 * system.nc, [f.jacobian()])


class Index1(FormulationKind):
    """Semi-explicit index-1 DAE (KKT rows as algebraic equations), integrated by IDAS."""

    name = "index1"
    handles = ALL_NEEDS
    kind = "dae"
    layout = "x = (q, v), z = (q̈, λ)"
    default_integrator = "idas"

    def preferred_for(self, system: System) -> bool:
        """The default where friction follows the joint reactions (Adams-style μ |R|): its
        level is a function of λ, which the index-1 DAE has as algebraic variables (the ODE
        formulations refuse it)."""
        return bool(system.friction_normal_symbols)

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        return index1(system, inputs=inputs, **options)


class Ggl(FormulationKind):
    """Gear–Gupta–Leimkuhler stabilised index-2 DAE, integrated by IDAS."""

    name = "ggl"
    handles = ALL_NEEDS - EVENT_NEEDS
    refuses = dict.fromkeys(EVENT_NEEDS, "its index-2 start cannot be made consistent after an "
                            "impact by IDAS")
    instead = dict.fromkeys(EVENT_NEEDS, "formulation 'index1' (or the default)")
    kind = "dae"
    layout = "x = (q, v), z = (q̈, λ, μ)"
    default_integrator = "idas"

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        return ggl(system, inputs=inputs, **options)

    def refuse_events(self) -> None:
        """No event-driven run: after an impact IDAS cannot make the index-2 start
        consistent."""
        raise AnalysisError(f"formulation '{self.name}': its index-2 start cannot be made "
                            "consistent after an impact by IDAS; with contacts and stops use "
                            "'index1' (or the default)")

    def initial_algebraic(self, a: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """(q̈, λ, μ) with μ = 0: the velocity correction vanishes at a consistent start."""
        return np.concatenate([a, lam, np.zeros_like(lam)])

    def failure_hint(self, flag: str, rtol: float) -> str:
        """The index-2 corrector's limit: IDAS's Newton matrix of the GGL system grows like
        1/h² as the steps shrink, so at tight tolerances the corrector stops converging
        (pendulum chains: chain2 fails at t = 0 and chain8 at t ≈ 1.1 s at rtol 1e-12, both
        integrate at 1e-10; measured 2026-11-25)."""
        if flag == "IDA_CONV_FAIL" and rtol < 1e-10:
            return (f"; the GGL index-2 corrector does not converge at rtol = {rtol:g} (its "
                    "iteration matrix grows like 1/h² as the steps shrink): use the "
                    "formulation 'index1' or rtol >= 1e-10")
        return ""
