"""The event rows of the event-driven integrator (:mod:`casmbd.analysis.events.events`).

A *row* is one scalar that must keep its sign while the motion is smooth: the gap g_k(q) ≥ 0
of a contact or joint stop (:mod:`casmbd.model.contacts`), or the sliding velocity σ q̇_j > 0
of a joint with exact Coulomb friction (:class:`StickRow`).  A row is *open* (its value is
watched) or *closed* (its closure equation is a bilateral constraint of the phase — g_k = 0,
q_j − q_stuck = 0 — and its multiplier is watched instead).  :class:`EventRows` evaluates all
rows numerically from a System; :func:`closure` makes the closure joint of a row.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.compiled.buffered import BufferedFunction
from casmbd.model.bodies import GROUND
from casmbd.model.contacts import (
    GapClosure,
    RollingClosure,
    TangentClosure,
    slide_direction_parameters,
    slide_parameters,
    tangential_position,
)
from casmbd.model.joint_friction import stick_slip_parameters

__all__ = ["EventRows", "SlideRow", "StickRow", "closure"]


class StickRow:
    """A joint-friction element with the exact Coulomb law seen as an event row: stuck, it is
    closed by the constraint q_j − q_stuck = 0 (its multiplier −λ the friction force, which
    must stay within F_c); sliding, its open value σ q̇_j must stay positive."""

    event_kind = "stick"
    restitution = 0.0
    friction = 0.0
    labels = ("stick",)

    def __init__(self, element):
        self.element, self.name = element, element.name
        self.joint, self.coordinate = element.joint, element.coordinate
        self.level = float(element.friction)
        self.sign, self.stuck_at = stick_slip_parameters(element.name)

    def gaps(self, ctx) -> ca.SX:
        coord = ctx.mechanism.joints[self.joint].coordinate(ctx, self.coordinate)
        return coord - ctx.p[self.stuck_at]

    def rate(self, ctx) -> ca.SX:
        coord = ctx.mechanism.joints[self.joint].coordinate(ctx, self.coordinate)
        return ctx.p[self.sign] * ca.jtimes(coord, ctx.q, ctx.v)

    def tangential_velocity(self, ctx, k: int):
        return None


class SlideRow:
    """The tangential row of a closed frictional plane contact: active while the contact's
    gap row is closed.  In the plane: stuck, it is closed by s(q) − s_stuck = 0
    (:class:`~casmbd.model.contacts.TangentClosure`; −λ the friction force, within μ N with N
    the gap row's normal force); sliding, σ ṡ must stay positive (the force −μ N σ is the
    contact's :class:`~casmbd.model.contacts.ContactSlide` element).  In space: stuck, the
    touching point's velocity v_t = 0 (two rows, :class:`~casmbd.model.contacts.
    RollingClosure`; |λ_t| within μ N); sliding, the force −μ N v_t/|v_t| and the row
    σ ŝ·v_t must stay positive (ŝ the slip direction)."""

    event_kind = "stick"
    restitution = 0.0
    friction = 0.0
    labels = ("stick",)

    def __init__(self, contact):
        self.contact, self.name = contact, contact.name
        self.mu = float(contact.friction)
        self.sign, self.stuck_at = slide_parameters(contact.name)
        #: 2 (plane) or 3 (space: the slip is a 2-D velocity in the tangent plane)
        self.dimension = contact.dimension
        #: space: the parameters of the sliding direction ŝ (tangent basis)
        self.direction = slide_direction_parameters(contact.name) \
            if contact.dimension == 3 else ()
        #: index of the contact's gap row (set by :class:`EventRows`)
        self.gap_row = -1

    def gaps(self, ctx) -> ca.SX:
        if self.dimension == 3:  # stuck in space: a velocity constraint, no position
            return ca.SX.zeros(1)
        return tangential_position(self.contact, ctx) - ctx.p[self.stuck_at]

    def rate(self, ctx) -> ca.SX:
        """σ ṡ in the plane; in space σ ŝ·v_t, the slip velocity along the direction ŝ the
        slide started with (re-anchored by the integrator while the slip turns)."""
        if self.dimension == 3:
            stored = ca.vertcat(*[ctx.p[par] for par in self.direction])
            return ctx.p[self.sign] * ca.dot(stored, self.contact.tangential_velocity(ctx))
        return ctx.p[self.sign] * ca.jtimes(tangential_position(self.contact, ctx), ctx.q,
                                            ctx.v)

    def tangential_velocity(self, ctx, k: int):
        return None


class EventRows:
    """Numeric gap functions of the impact elements (and stick rows), from a System: the
    open-state values (g, or σ q̇_j of a sliding joint), the Jacobians of the closure
    equations and the contacts' tangential-velocity Jacobians."""

    def __init__(self, system, elements):
        ctx = system.ctx
        self.rows: list[tuple] = []
        gaps, positions, tangent_rows, tangent_of = [], [], [], []
        for element in elements:
            g = ca.vec(element.gaps(ctx))
            for k in range(g.numel()):
                self.rows.append((element, k))
                positions.append(g[k])
                gaps.append(element.rate(ctx) if hasattr(element, "rate") else g[k])
                vt = element.tangential_velocity(ctx, k) if element.friction else None
                tangent_of.append(len(tangent_rows) if vt is not None else None)
                if vt is not None:
                    tangent_rows.append(ca.vec(vt))
        g = ca.vertcat(*gaps) if gaps else ca.SX(0, 1)
        pos = ca.vertcat(*positions) if positions else ca.SX(0, 1)
        vt = ca.vertcat(*tangent_rows) if tangent_rows else ca.SX(0, 1)
        self.tangent_of = tangent_of
        self.tangent_size = 1 if system.dimension == 2 else 2
        #: True for the rows of stick-slip friction (joints, closed contacts): never an impact
        self.stick = [isinstance(e, StickRow | SlideRow) for e, _ in self.rows]
        for element, _ in self.rows:  # a slide row's companion: its contact's gap row
            if isinstance(element, SlideRow):
                element.gap_row = next(i for i, (e, _) in enumerate(self.rows)
                                       if e is element.contact)
        self._maps: dict[int, ca.Function] = {}
        # Newton's restitution of each row, at the run's parameters (an expression string
        # of a contact or stop is evaluated at run time; stick rows: 0)
        rest = [element.restitution_at(ctx) if hasattr(element, "restitution_at")
                else ca.SX(element.restitution) for element, _ in self.rows]
        rest = ca.vertcat(*rest) if rest else ca.SX(0, 1)
        self._restitution = BufferedFunction.of(ca.Function("restitution", [system.t, system.p],
                                                    [ca.densify(rest)]))
        #: ∂e/∂p of every row (a restitution given by a parameter; sensitivities)
        self.restitution_jacobian = ca.Function("restitution_jacobian", [system.t, system.p],
                                                [ca.jacobian(rest, system.p)])
        self.fun = ca.Function("gaps", [system.q, system.v, system.t, system.p],
                               [ca.densify(g), ca.densify(ca.jacobian(pos, system.q)),
                                ca.densify(ca.jacobian(vt, system.v)), ca.densify(pos)])
        #: the same, called through its buffer (per event: impacts, projections, engage)
        self._fun = BufferedFunction.of(self.fun)
        #: the open-state values alone (the root finding's per-trial evaluation)
        self._values = BufferedFunction.of(ca.Function(
            "gap_values", [system.q, system.v, system.t, system.p], [ca.densify(g)]))

    def __call__(self, q, v, t, p):
        g, gq, tv, _ = self._fun.all(q, v, t, p)
        return (np.asarray(g, float).ravel(), np.asarray(gq, float),
                np.asarray(tv, float))

    def values(self, q, v, t, p) -> np.ndarray:
        """The open-state values at one state (the first output of :meth:`__call__`), by
        the Function's buffer (a few µs instead of the wrapper's ~85)."""
        return np.asarray(self._values.all(q, v, t, p)[0], float).ravel()

    def values_many(self, qs: np.ndarray, vs: np.ndarray, ts: np.ndarray,
                    p: np.ndarray) -> np.ndarray:
        """The open-state values at many states (rows), in one mapped call."""
        n = len(ts)
        if n not in self._maps:
            self._maps[n] = self.fun.map(n)
        out = self._maps[n](qs.T, vs.T, np.asarray(ts)[None, :], np.tile(p[:, None], (1, n)))
        return np.asarray(out[0], float).reshape(-1, n).T

    def restitution(self, i: int, t: float, p) -> float:
        """Newton's restitution e of row i at the parameters ``p``."""
        return float(np.asarray(self._restitution.all(t, p)[0], float).ravel()[i])

    def positions(self, q, v, t, p) -> np.ndarray:
        """The closure equations' values (a stick row: q_j − q_stuck)."""
        return np.asarray(self._fun.all(q, v, t, p)[3], float).ravel()

    def closed_value(self, i: int, lams: dict) -> float:
        """What must stay ≥ 0 while row i is closed (``lams``: the multipliers of the closed
        rows by row): the normal force −λ of a contact or stop, F_c − |λ| of a stuck joint,
        μ N − |λ| of a stuck contact (N = −λ of its gap row)."""
        element, lam = self.rows[i][0], lams[i]
        if isinstance(element, SlideRow):
            return element.mu * max(-lams.get(element.gap_row, 0.0), 0.0) - abs(lam)
        return element.level - abs(lam) if self.stick[i] else -lam

    def active(self, i: int, closed) -> bool:
        """A slide row counts only while its contact is closed."""
        element = self.rows[i][0]
        return not isinstance(element, SlideRow) or element.gap_row in closed

    def slip_velocity(self, i: int, q, v, t, p) -> np.ndarray:
        """v_t of slide row i's contact: the tangential velocity of its touching point in the
        tangent basis (1 component in the plane, 2 in space)."""
        idx = self.tangent_of[self.rows[i][0].gap_row]
        ts = self.tangent_size
        return self(q, v, t, p)[2][idx * ts:(idx + 1) * ts] @ np.asarray(v, float)

    def label(self, i: int) -> str:
        element, k = self.rows[i]
        return element.name if len(element.labels) == 1 else \
            f"{element.name}.{element.labels[k]}"


def closure(mechanism, element, k: int) -> GapClosure | TangentClosure | RollingClosure:
    """The bilateral constraint g_k = 0 of a closed gap, between the bodies it touches (the
    ground first for a contact with the ground plane; a limit's joint's bodies); a stuck
    contact's tangential closure."""
    if isinstance(element, SlideRow):
        return TangentClosure(element.contact) if element.dimension == 2 else \
            RollingClosure(element.contact)
    if hasattr(element, "joint"):
        joint = mechanism.joints[element.joint]
        return GapClosure(element, k, joint.body1, joint.body2)
    bodies = tuple(element.bodies)
    return GapClosure(element, k, *((GROUND, *bodies) if len(bodies) == 1 else bodies))
