"""The integrators: their kinds and registry, Dormand–Prince, the numeric right-hand-side bridge
to CVODES, the ranges of integrator options and the diagnosis of a failed integration.

* :mod:`.kinds` — :class:`~.kinds.IntegratorKind`, the SUNDIALS (``idas``, ``cvodes``,
  ``adams``) and fixed-step (``rk4``, ``abm``) families, and the registry :data:`INTEGRATORS`
  with the kinds it defines;
* :mod:`.dopri` — Dormand–Prince 5(4) in compiled blocks (:class:`~.dopri.DopriKind`),
  registered here as ``dopri5``;
* :mod:`.numeric_rhs` — numeric right-hand sides integrated by CVODES through a callback;
* :mod:`.option_ranges` — the meaningful ranges of the integrator options;
* :mod:`.stiffness_culprit` — which element made a time integration fail.

The registry is complete when this package is imported (which any import of one of its
modules does first): ``kinds`` registers its own kinds, this module the kinds of the modules
that build on ``kinds``.  ``dopri`` imports ``kinds``, never the reverse (no import circle).
"""

from casmbd.analysis.integrators.dopri import DopriKind
from casmbd.analysis.integrators.kinds import (
    DEFAULT_SHOOTING_INTEGRATOR,
    INTEGRATORS,
    IntegratorKind,
    integrator_kind,
    names,
    register_integrator,
)

register_integrator(DopriKind("dopri5", "Dormand–Prince 5(4)", stiff_alternative="cvodes"))

__all__ = ["DEFAULT_SHOOTING_INTEGRATOR", "INTEGRATORS", "IntegratorKind", "integrator_kind",
           "names", "register_integrator"]
