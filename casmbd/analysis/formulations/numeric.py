"""Numeric formulations: the system-layer half of ``partitioning`` and ``nullspace``.

The kinds (name, state layout, redundancy policy) are declared here and registered with the
symbolic ones by :mod:`casmbd.analysis.formulations`, so :data:`FORMULATIONS` is complete as soon
as that package is imported; their numeric right-hand sides live in the analysis layer
(:data:`casmbd.analysis.dynamics.numeric_run.RIGHT_HAND_SIDES`, keyed by these classes), which is
the only layer that evaluates them.
"""

from __future__ import annotations

from typing import ClassVar

import casadi as ca

from casmbd.analysis.formulations.base import Formulation, FormulationKind
from casmbd.analysis.formulations.kkt_ode import kkt_ode
from casmbd.system.equations import System


class NumericFormulation(FormulationKind):
    """A formulation whose right-hand side the analysis layer evaluates numerically.

    The symbolic KKT ODE is compiled alongside (fixed-step references, the stiffness
    probe).  The right-hand sides of the built-in kinds :class:`Partitioning` and
    :class:`Nullspace` are supplied by the analysis layer
    (:mod:`casmbd.analysis.formulations.partitioning`,
    :mod:`casmbd.analysis.formulations.nullspace`, looked up by
    :mod:`casmbd.analysis.dynamics.numeric_run`), so the system layer never imports the analysis
    layer; a user's numeric kind overrides :meth:`right_hand_side`.
    """

    kind = "numeric"
    keeps_redundant = True
    removes_redundant = False
    #: numeric right-hand sides are ~100x dearer: fail in seconds, not minutes
    max_steps = 20_000

    def integrate(self, runs, name: str, grid, x0, z0, rtol: float, atol: float,
                  projection: bool, step, max_steps: int):
        """Output interval by output interval on this right-hand side
        (:mod:`casmbd.analysis.dynamics.numeric_run`, through the simulator ``runs``)."""
        return runs.integrate_numeric(name, grid, x0, rtol, atol, max_steps, projection)

    def keep_partial(self, runs, name: str, grid, x0, z0, rtol: float, atol: float, step,
                     max_steps: int, solver_text: str, projection: bool):
        """The intervals before the failure (the run's times are shifted: the integrator's
        message names no absolute failure time)."""
        return runs.partial_numeric(name, grid, x0, rtol, atol, max_steps)

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        form = kkt_ode(system, inputs=inputs)
        form.kind = "numeric"
        return form

    def right_hand_side(self, sim, equations, x0, t0: float):
        """The numeric ODE the analysis layer integrates for the simulator ``sim``.

        Overridden by a user's numeric kind (the built-in kinds' right-hand sides are the
        analysis layer's :data:`~casmbd.analysis.dynamics.numeric_run.RIGHT_HAND_SIDES`); the object
        has the interface of :class:`casmbd.analysis.integrators.numeric_rhs.NumericOde` (state
        size,
        ``reduce``/``expand`` between the full (q, v) and its own state, ``__call__(t, y)``,
        statistics).
        """
        raise NotImplementedError(f"formulation '{self.name}': no numeric right-hand side")


class Partitioning(NumericFormulation):
    """Generalized coordinate partitioning: ODE in the independent coordinates (seed 000,
    eqs. 6.200–6.205; right-hand side :mod:`casmbd.analysis.formulations.partitioning`)."""

    name = "partitioning"
    layout = "y = (q_i, v_i), independent coordinates chosen by LU with full pivoting"
    refuses: ClassVar[dict] = {
        **NumericFormulation.refuses,
        "velocity_constraints": "with rows A(q) v + b = 0 the independent velocities are "
                                "fewer than the independent positions, and the dependent "
                                "positions are no function of the independent ones (they "
                                "follow from the path), so its state y = (q_i, v_i) cannot "
                                "hold the motion"}
    instead: ClassVar[dict] = {**NumericFormulation.instead,
                               "velocity_constraints": "formulation 'nullspace' (the same "
                               "elimination of the multipliers on the full state) or the "
                               "default"}


class Nullspace(NumericFormulation):
    """Null-space (embedding) formulation: ODE in x = (q, v), no multipliers (seed 000,
    "Elimination of Lagrange multipliers"; right-hand side
    :mod:`casmbd.analysis.formulations.nullspace`)."""

    name = "nullspace"
    layout = "x = (q, v), accelerations in the SVD null space of C_q"
    #: rows written at the velocity level enter as any row of C_q q̈ = γ (the null space of
    #: all rows), and the projection assembles the holonomic rows only
    handles = NumericFormulation.handles | {"velocity_constraints"}
