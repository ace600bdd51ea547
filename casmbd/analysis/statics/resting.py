"""Static equilibrium with contacts and joint stops: the active set of closed gaps (issue 24).

A body resting on a contact (a ball on the floor, a pendulum against its stop) is in
equilibrium with the contact closed and pushing; statics of a mechanism with unilateral
elements of the impact model (:mod:`casmbd.model.contacts`) therefore looks for the set of
closed gaps — each a bilateral constraint g_k(q) = 0 (:class:`~casmbd.model.contacts.GapClosure`)
— in which no open gap penetrates and no closed one pulls (its normal force −λ_k ≥ 0), the
complementarity conditions g ≥ 0, F_n ≥ 0, g F_n = 0 of a unilateral contact (Pfeiffer &
Glocker, 1996, ch. 4).
"""

from __future__ import annotations

import copy

import numpy as np

from casmbd.analysis.events.event_rows import EventRows, closure
from casmbd.errors import AnalysisError
from casmbd.model.contact_models import acts_at_events
from casmbd.system import System

__all__ = ["resting_equilibrium"]


def resting_equilibrium(mechanism, t: float, method: str, tol: float, max_iter: int,
                        mode: str, solve, stable: bool = False):
    """Statics with unilateral elements of the impact model: an active set.  Gaps touching at
    the start (|g| ≤ 1e-9) are closed (bilateral constraints g = 0); after each solution the
    gaps that penetrate are closed and those whose normal force −λ pulls are opened, until
    neither happens (at most 2 n_gaps + 3 rounds; after a set without equilibrium — a ball in
    the air falls — every gap is closed).  A body resting on a contact: the contact
    carries its weight.  The result's ``contacts`` give each gap's force (0 when open) and
    value.  ``stable`` is handed to every solve (the equilibrium nearest the start, or a
    stable one).  ``solve`` is :func:`casmbd.analysis.statics.statics.static_equilibrium` (handed
    in: that module calls this one)."""
    elements = [c for c in mechanism.contacts.values() if acts_at_events(c)]
    gaps = EventRows(System(mechanism), elements)
    p = np.array(list(mechanism.parameters.values()), dtype=float)
    q0 = System(mechanism).initial_coordinates()
    g0 = gaps(q0, np.zeros_like(q0), t, p)[0]
    closed = {i for i in range(len(g0)) if g0[i] <= 1e-9}
    for _ in range(2 * len(g0) + 3):
        variant = copy.copy(mechanism)
        variant.contacts = {}
        # exact stick-slip friction exerts nothing at rest (σ = 0): friction at rest is not
        # needed for an equilibrium, and the variant must not come back here (it recursed
        # without end on a joint with stick-slip friction)
        variant.forces = {name: force for name, force in mechanism.forces.items()
                          if not getattr(force, "stick_slip", False)}
        variant.joints = dict(mechanism.joints)
        names = {}
        for i in sorted(closed):
            joint = closure(mechanism, *gaps.rows[i])
            variant.joints[joint.name] = joint
            names[i] = f"joint '{joint.name}' equation 'gap'"
        try:
            res = solve(variant, t, method, tol, max_iter, mode, stable=stable)
        except AnalysisError:
            if closed == set(range(len(g0))):
                raise
            # no equilibrium with these gaps open (a ball in the air falls): put the bodies
            # on all their contacts; the pulling ones open in the next rounds
            closed = set(range(len(g0)))
            continue
        labels = [str(lab) for lab in System(variant).constraint_labels]
        g = gaps(res.q, np.zeros_like(res.q), t, p)[0]
        force = {i: -float(res.lagrange_multipliers[labels.index(names[i])]) for i in closed}
        scale = 1.0 + max((abs(f) for f in force.values()), default=0.0)
        penetrating = {i for i in range(len(g)) if i not in closed and g[i] < -1e-9}
        pulling = {i for i in closed if force[i] < -tol * scale}
        if not penetrating and not pulling:
            res.contacts = {gaps.label(i): {"normal_force": force.get(i, 0.0),
                                            "gap": float(g[i])} for i in range(len(g))}
            return res
        closed = (closed | penetrating) - pulling
    raise AnalysisError(f"statics at t = {t:g}: no consistent set of closed contacts "
                        f"({', '.join(gaps.label(i) for i in range(len(g0)))})")
