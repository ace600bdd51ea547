"""``articulated``: ODE x = (q, v) of a tree in joint coordinates by the articulated-body
recursion (:mod:`casmbd.system.articulated_body`), O(N) operations."""

from __future__ import annotations

from typing import ClassVar

import casadi as ca

from casmbd.analysis.formulations.base import (
    Formulation,
    FormulationKind,
    dae_function,
    symbolic_arguments,
)
from casmbd.errors import AnalysisError
from casmbd.system import chain_fold, chain_motion, chain_pivots, chain_reactions
from casmbd.system.articulated_body import articulated_accelerations, supported
from casmbd.system.equations import System

#: the fewest bodies for which ``fold="auto"`` folds a chain: measured (same process, gcc 12,
#: -O2, µs per right-hand side through ``Function.buffer``) folded / unrolled 1.31 / 0.66 at
#: N = 8, 2.82 / 2.96 at N = 32, 19.3 / 12.8 at N = 100 with first builds of 5.0 s against
#: 20.2 s (load 6-7 on 2 cores): below 32 bodies the fold's loop costs more than it saves
FOLD_MIN_BODIES = 32


def folds(system: System, fold: bool | str = "auto") -> bool:
    """True when :func:`articulated` folds the recursion of ``system`` over its bodies."""
    if fold not in (True, False, "auto"):
        raise AnalysisError(f"formulation 'articulated': option 'fold' must be True, False "
                            f"or 'auto', got {fold!r}")
    size_ok = fold is True or (fold == "auto" and len(system.body_names) >= FOLD_MIN_BODIES)
    return size_ok and chain_fold.supported(system) is None


def articulated(system: System, inputs: ca.SX | None = None, fold: bool | str = "auto"
                ) -> Formulation:
    """ODE on (q, v) of a tree in joint coordinates by the articulated-body recursion, O(N)
    operations (:mod:`casmbd.system.articulated_body`).

    ``fold``: a planar serial chain of revolute joints loaded by gravity alone
    (:func:`casmbd.system.chain_fold.supported`) gets the recursion written once per body
    and folded over the bodies (:mod:`casmbd.system.chain_fold`: an MX Function whose
    arithmetic is generated once; 0.34 MB of C at 1000 rods, mostly index tables, where the
    unrolled right-hand side is 5.7 MB) —
    with ``"auto"`` (default) from :data:`FOLD_MIN_BODIES` bodies on, with ``True`` at any
    size; ``False`` unrolls it as for every other tree."""
    if folds(system, fold):
        t, x = ca.MX.sym("t"), ca.MX.sym("x", 2 * system.nq)
        p = ca.MX.sym("p", system.p.numel())
        q, v = x[:system.nq], x[system.nq:]
        acc = chain_fold.folded_accelerations(system, q, v, p)
        f = dae_function("dyn_articulated", t, x, ca.MX(0, 1), p, ca.vertcat(v, acc),
                         ca.MX(0, 1))
        return Formulation("articulated", "ode", f, system.nq, 0)
    t, q, v, pu = symbolic_arguments(system)
    acc = articulated_accelerations(system)
    if system.u.numel():
        u_expr = ca.SX.zeros(system.u.numel()) if inputs is None else inputs
        acc = ca.substitute(acc, system.u, u_expr)
    f = dae_function("dyn_articulated", t, ca.vertcat(q, v), ca.SX(0, 1), pu, ca.vertcat(v, acc),
             ca.SX(0, 1))
    return Formulation("articulated", "ode", f, system.nq, 0)


class Articulated(FormulationKind):
    """Articulated-body recursion; the default for trees in joint coordinates without
    constraint equations (measured faster than the KKT/LDLᵀ path: docs/dynamics.md).

    Its default integrator is DOPRI5 in compiled blocks (:mod:`casmbd.analysis.integrators.dopri`),
    measured faster than CVODES-Adams at errors 1e-6 and 1e-9 on the pendulum chains
    (docs/dynamics.md, "Dormand–Prince: compiled adaptive steps"); BDF when the start is stiff.
    """

    name = "articulated"
    handles = frozenset({"inputs"})
    refuses: ClassVar[dict] = {
        need: "it integrates an unconstrained tree in joint coordinates" for need in
               ("events", "stick_slip", "contact_friction", "reaction_forces",
                "modal_coordinates", "drivers", "velocity_constraints")}
    instead: ClassVar[dict] = {need: "the default formulation" for need in refuses}
    kind = "ode"
    default_integrator = "dopri5"

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        return articulated(system, inputs=inputs, **options)

    def model_functions(self, system: System, fold: bool | str = "auto",
                        **options) -> list[ca.Function]:
        """With the recursion folded, the outputs, energies, joint reactions and mass
        matrix folded too (:mod:`casmbd.system.chain_motion`,
        :mod:`casmbd.system.chain_reactions`): unrolled, they were 12.5 of the 13.6 MB of C
        of a 1000-rod chain and most of its cold build."""
        if not folds(system, fold) or chain_motion.supported(system) is not None:
            return []
        return [chain_motion.folded_outputs(system), *chain_motion.folded_energies(system),
                chain_reactions.folded_reactions(system),
                chain_reactions.folded_mass_matrix(system),
                chain_pivots.folded_pivots(system)]  # the cheap test of M > 0 (run start)

    def default_reason(self, system: System) -> str:
        return "default: the articulated-body recursion (a tree in joint coordinates)"

    def preferred_for(self, system: System) -> bool:
        return system.coordinates == "joint" and supported(system) is None
