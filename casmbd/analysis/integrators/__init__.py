"""The integrators: their kinds and registry, Dormand–Prince, the numeric right-hand-side bridge
to CVODES, the ranges of integrator options and the diagnosis of a failed integration.

* :mod:`.kinds` — :class:`~.kinds.IntegratorKind`, the registry :data:`INTEGRATORS` and the
  helpers the families share;
* :mod:`.sundials` — the SUNDIALS family (:class:`~.sundials.SundialsKind`: ``idas``,
  ``cvodes``, ``adams``);
* :mod:`.fixed_step` — the fixed-step family (:class:`~.fixed_step.FixedStepKind`: ``rk4``,
  ``abm``);
* :mod:`.dopri` — Dormand–Prince 5(4) in compiled blocks (:class:`~.dopri.DopriKind`:
  ``dopri5``);
* :mod:`.numeric_rhs` — numeric right-hand sides integrated by CVODES through a callback;
* :mod:`.option_ranges` — the meaningful ranges of the integrator options;
* :mod:`.stiffness_culprit` — which element made a time integration fail.

The registry is complete when this package is imported (which any import of one of its
modules does first): this module registers the kinds of the families, in the order of the
choices (``idas``, ``cvodes``, ``adams``, ``rk4``, ``abm``, ``dopri5``).  The family modules
import ``kinds``, never the reverse (no import circle).
"""

from casmbd.analysis.integrators.dopri import DopriKind
from casmbd.analysis.integrators.fixed_step import FixedStepKind, abm_step, rk4_step
from casmbd.analysis.integrators.kinds import (
    DEFAULT_SHOOTING_INTEGRATOR,
    INTEGRATORS,
    IntegratorKind,
    integrator_kind,
    names,
    register_integrator,
)
from casmbd.analysis.integrators.sundials import SundialsKind

register_integrator(SundialsKind(
    "idas", "BDF", dae=True, plugin="idas",
    # keep q̈ and λ out of the error test (they are determined by q and v)
    options=(("suppress_algebraic", True),)))
register_integrator(SundialsKind(
    "cvodes", "BDF", numeric=True, shooting=True, plugin="cvodes",
    options=(("linear_multistep_method", "bdf"),)))
register_integrator(SundialsKind(
    "adams", "Adams–Moulton", numeric=True, plugin="cvodes", stiff_alternative="cvodes",
    options=(("linear_multistep_method", "adams"), ("nonlinear_solver_iteration", "functional"))))
register_integrator(FixedStepKind("rk4", "RK4", shooting=True, step_builder=rk4_step,
                                  evaluations_per_step=4))
register_integrator(FixedStepKind("abm", "ABM4", step_builder=abm_step, history=3,
                                  evaluations_per_step=2))
register_integrator(DopriKind("dopri5", "Dormand–Prince 5(4)", stiff_alternative="cvodes"))

__all__ = ["DEFAULT_SHOOTING_INTEGRATOR", "INTEGRATORS", "IntegratorKind", "integrator_kind",
           "names", "register_integrator"]
