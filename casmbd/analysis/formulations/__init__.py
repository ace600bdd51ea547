"""Forward-dynamics formulations built from the same symbolic equations, registered by name.

Every formulation is a :class:`FormulationKind` object in :data:`FORMULATIONS` (name -> kind,
like scipy's ``solve_ivp`` ``METHODS``) that builds a CasADi Function with the integrator
signature ``(t, x, z, p, u) -> (ode, alg, quad, zero)`` (``casadi.dyn_in()``/``dyn_out()``),
where ``p`` are the model parameters; the actuator inputs are substituted as expressions of
(t, p) before code generation, so the integrator calls one compiled function.  The equations
of motion are seed 000's augmented form (eq. 6.138)::

    M q̈ + C_qᵀ λ = Q_e + Q_v,     C_q q̈ = γ

Registered here, in this order (one module each):

* ``index1``, ``ggl`` — semi-explicit DAEs for IDAS (:mod:`.dae`);
* ``kkt_ode`` — ODE with λ from the sparse Schur complement (:mod:`.kkt_ode`);
* ``augmented_lagrangian`` — ODE by the augmented-Lagrangian iteration, the default
  (:mod:`.augmented_lagrangian`);
* ``articulated`` — the O(N) articulated-body recursion for trees in joint coordinates
  (:mod:`.articulated`);
* ``nullspace``, ``partitioning`` — numeric formulations (:mod:`.numeric`:
  :class:`NumericFormulation`, right-hand sides evaluated by numpy around the compiled
  equations): declared here, so the registry is complete on import, and evaluated by the
  analysis layer (:mod:`casmbd.analysis.formulations.nullspace`,
  :mod:`casmbd.analysis.formulations.partitioning`).

How to add a formulation: docs/dynamics.md.
"""

from __future__ import annotations

from casmbd.analysis.formulations.articulated import Articulated, articulated
from casmbd.analysis.formulations.augmented_lagrangian import (
    AugmentedLagrangian,
    augmented_lagrangian,
)
from casmbd.analysis.formulations.base import (
    DEFAULT_FORMULATION,
    FORMULATIONS,
    Formulation,
    FormulationKind,
    formulation_kind,
    register_formulation,
)
from casmbd.analysis.formulations.dae import Ggl, Index1, ggl, index1
from casmbd.analysis.formulations.kkt_ode import KktOde, kkt_ode
from casmbd.analysis.formulations.numeric import Nullspace, NumericFormulation, Partitioning
from casmbd.analysis.formulations.post import post_processing
from casmbd.system.equations import System

for _kind in (Index1(), Ggl(), KktOde(), AugmentedLagrangian(), Articulated(), Nullspace(),
              Partitioning()):
    register_formulation(_kind)


def build(system: System, name: str, **options) -> Formulation:
    """Build the registered formulation ``name`` (:data:`FORMULATIONS`) of ``system``."""
    return formulation_kind(name).build(system, **options)


def default_formulation(system: System) -> str:
    """The formulation used when none is named: the first registered kind that is
    :meth:`~FormulationKind.preferred_for` the system (``articulated`` for a tree in joint
    coordinates without constraint equations), else :data:`DEFAULT_FORMULATION`."""
    for name, kind in FORMULATIONS.items():
        if kind.preferred_for(system):
            return name
    return DEFAULT_FORMULATION


__all__ = ["DEFAULT_FORMULATION", "FORMULATIONS", "Articulated", "AugmentedLagrangian",
           "Formulation", "FormulationKind", "Ggl", "Index1", "KktOde", "Nullspace",
           "NumericFormulation", "Partitioning",
           "articulated", "augmented_lagrangian", "build", "default_formulation",
           "formulation_kind", "ggl", "index1", "kkt_ode", "post_processing",
           "register_formulation"]
