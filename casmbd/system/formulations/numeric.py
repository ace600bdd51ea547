"""Numeric formulations: the system-layer half of ``partitioning`` and ``nullspace``."""

from __future__ import annotations

import casadi as ca

from casmbd.system.equations import System
from casmbd.system.formulations.base import Formulation, FormulationKind
from casmbd.system.formulations.kkt_ode import kkt_ode


class NumericFormulation(FormulationKind):
    """A formulation whose right-hand side the analysis layer evaluates numerically.

    The symbolic KKT ODE is compiled alongside (fixed-step references, the stiffness
    probe); the analysis layer subclasses this with the right-hand side and its runner
    (:mod:`casmbd.analysis.partitioning`, :mod:`casmbd.analysis.nullspace`), so the system
    layer never imports the analysis layer.
    """

    kind = "numeric"
    keeps_redundant = True
    removes_redundant = False

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        form = kkt_ode(system, inputs=inputs)
        form.kind = "numeric"
        return form

    def right_hand_side(self, sim, equations, x0, t0: float):
        """The numeric ODE the analysis layer integrates for the simulator ``sim``.

        Implemented by the analysis layer's subclasses; the object has the interface of
        :class:`casmbd.analysis.numeric_rhs.NumericOde` (state size, ``reduce``/``expand``
        between the full (q, v) and its own state, ``__call__(t, y)``, statistics).
        """
        raise NotImplementedError(f"formulation '{self.name}': no numeric right-hand side")
