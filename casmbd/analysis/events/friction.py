"""Friction in the event loop: stick-slip joints and frictional contacts stick, slip, turn.

A stick-slip joint (:class:`~casmbd.analysis.events.event_rows.StickRow`) or a frictional
contact's slide row (:class:`~casmbd.analysis.events.event_rows.SlideRow`) slides with the
friction force −F_c σ (−μ N σ) of its sign σ, a parameter of the run, or sticks: its row closed
(a closure at the stuck position) while the holding force stays within F_c (μ N).  The Coulomb
law at an event (Pfeiffer & Glocker, *Multibody Dynamics with Unilateral Contacts*, 1996,
ch. 7): a row whose slip stops sticks if the force that holds it stays within its level, else
slides where the other forces push (:meth:`Friction.settle`); after an impact or a change of
the closed set the signs follow the slip (:meth:`Friction.engage`).
"""

from __future__ import annotations

import numpy as np

from casmbd.analysis.events.event_rows import SlideRow, StickRow
from casmbd.analysis.events.impulses import project
from casmbd.analysis.events.phases import PhaseSet, with_parameters
from casmbd.model.contacts import SLIP_VELOCITY

__all__ = ["Friction", "slides_in_space"]


def slides_in_space(row) -> bool:
    """A frictional contact in space (two tangential directions, a slip direction ŝ)."""
    return isinstance(row, SlideRow) and row.dimension == 3


class Friction:
    """The friction state of one event-driven run: the run's parameters ``p`` (σ, stuck
    positions and slip directions, by ``pnames``), written in place, and the ``events`` list
    the friction events (``stick``, ``slip``) are appended to."""

    def __init__(self, gaps, p: np.ndarray, pnames: list[str], events: list[dict],
                 phases: PhaseSet, nq: int):
        self.gaps, self.p, self.pnames, self.events = gaps, p, pnames, events
        self.phases, self.nq = phases, nq
        self.n_gaps = len(gaps.rows)

    def start(self, x: np.ndarray, t_start: float, closed: frozenset):
        """The start of the stick-slip joints: sliding in the direction of their rate, or at
        rest (stick or slip, :meth:`settle`); the state (its velocities projected when one
        sticks) and the closed set."""
        gaps, p, pnames, nq = self.gaps, self.p, self.pnames, self.nq
        for i in [i for i in range(self.n_gaps) if gaps.stick[i] and
                  not isinstance(gaps.rows[i][0], SlideRow)]:
            row = gaps.rows[i][0]
            p[pnames.index(row.sign)] = 1.0
            rate = float(gaps(x[:nq], x[nq:], t_start, p)[0][i])
            if abs(rate) > 1e-12:
                p[pnames.index(row.sign)] = float(np.sign(rate))
            else:
                v_s, closed = self.settle(i, x[:nq], x[nq:], t_start, closed)
                x = np.concatenate([x[:nq], v_s])
        return x, closed

    def settle(self, i, q_s, v_s, t_s, closed_s):
        """A sliding joint or contact at zero speed (or at the start, or a contact just
        closed): stuck if the friction that holds it stays within its level (F_c, or μ N),
        else sliding in the direction the other forces push."""
        gaps, p, pnames, events = self.gaps, self.p, self.pnames, self.events
        row = gaps.rows[i][0]
        p[pnames.index(row.stuck_at)] = 0.0
        p[pnames.index(row.stuck_at)] = float(gaps.positions(q_s, v_s, t_s, p)[i])
        trial = closed_s | {i}
        stuck = with_parameters(self.phases(trial), p)
        v_p = project(stuck.sim.model, gaps, trial, q_s, v_s, t_s, p)
        p[pnames.index(row.sign)] = 0.0
        with_parameters(stuck, p)
        lams = dict(zip(sorted(trial), stuck.multipliers(q_s, v_p, t_s), strict=True))
        lam = float(lams[i])
        if gaps.closed_value(i, lams) >= 0.0:
            events.append({"time": float(t_s), "element": row.name, "kind": "stick"})
            return v_p, trial
        if slides_in_space(row):  # it slips along λ_t (the friction force −λ_t is too big)
            lam_t = stuck.tangent_multipliers(q_s, v_p, t_s, sorted(trial).index(i))
            self.start_slide(row, lam_t)
            events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
            return v_p, closed_s
        p[pnames.index(row.sign)] = float(np.sign(lam))
        events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
        return v_p, closed_s

    def stopped(self, i, q_s, v_s, t_s, closed_s) -> bool:
        """A sliding friction row (joint or closed contact) whose slip is zero at t_s: it
        stopped together with the one located (a box sliding on several contacts)."""
        gaps, p, pnames = self.gaps, self.p, self.pnames
        row = gaps.rows[i][0]
        if not gaps.stick[i] or i in closed_s or not gaps.active(i, closed_s) or \
                p[pnames.index(row.sign)] == 0.0:
            return False
        if slides_in_space(row):
            return float(np.linalg.norm(gaps.slip_velocity(i, q_s, v_s, t_s, p))) <= 1e-8
        return abs(float(gaps(q_s, v_s, t_s, p)[0][i])) <= 1e-8

    def settle_group(self, group, q_s, v_s, t_s, closed_s):
        """Rows that stopped at one instant: all stuck together if each holding force stays
        within its level (a box on several contacts: the statically indeterminate holding
        forces are the minimum-norm ones); else one by one, the others released (σ = 0) until
        their turn."""
        gaps, p, pnames, events = self.gaps, self.p, self.pnames, self.events
        if len(group) == 1:
            return self.settle(group[0], q_s, v_s, t_s, closed_s)
        group = sorted(group)  # row order, whichever was located first
        for i in group:
            row = gaps.rows[i][0]
            p[pnames.index(row.sign)] = 0.0
            p[pnames.index(row.stuck_at)] = 0.0
        positions = gaps.positions(q_s, v_s, t_s, p)
        for i in group:
            p[pnames.index(gaps.rows[i][0].stuck_at)] = float(positions[i])
        trial = closed_s | set(group)
        stuck = with_parameters(self.phases(trial), p)
        v_p = project(stuck.sim.model, gaps, trial, q_s, v_s, t_s, p)
        lams = dict(zip(sorted(trial), stuck.multipliers(q_s, v_p, t_s), strict=True))
        if all(gaps.closed_value(i, lams) >= 0.0 for i in group):
            events.extend({"time": float(t_s), "element": gaps.rows[i][0].name,
                           "kind": "stick"} for i in group)
            return v_p, trial
        for i in group:
            v_s, closed_s = self.settle(i, q_s, v_s, t_s, closed_s)
        return v_s, closed_s

    def start_slide(self, row, direction) -> None:
        """A contact in space slides (σ = 1) along the unit ``direction`` (tangent basis)."""
        p, pnames = self.p, self.pnames
        p[pnames.index(row.sign)] = 1.0
        d = np.asarray(direction, float)
        d = d / max(float(np.linalg.norm(d)), 1e-300)
        for par, value in zip(row.direction, d, strict=True):
            p[pnames.index(par)] = float(value)

    def reanchor(self, q_s, v_s, t_s) -> None:
        """The stored direction ŝ of a sliding contact in space follows its slip (each window
        of sub-intervals; the friction's direction (v_t + δ ŝ)/|v_t + δ ŝ| is v_t/|v_t| to
        δ sin∠(ŝ, v_t)/|v_t|, and the row ŝ·v_t must not cross zero while it still slips) —
        once the slip is well above δ (a slide just started from rest keeps the ŝ of λ_t)."""
        gaps, p, pnames = self.gaps, self.p, self.pnames
        for i in range(self.n_gaps):
            row = gaps.rows[i][0]
            if slides_in_space(row) and p[pnames.index(row.sign)] != 0.0:
                vt = gaps.slip_velocity(i, q_s, v_s, t_s, p)
                speed = float(np.linalg.norm(vt))
                stored = np.array([p[pnames.index(par)] for par in row.direction])
                if speed > 100.0 * SLIP_VELOCITY and \
                        float(np.linalg.norm(vt / speed - stored)) > 1e-9:
                    self.start_slide(row, vt)

    def held(self, i, q_s, t_s, closed_s) -> bool:
        """A friction row whose slip the closed rows already fix — a stick-slip joint on a
        closed stop of its joint, the tip of a pinned rod resting on a frictional floor: its
        slip direction lies in the row space of the phase's C_q.  Friction at rest there is
        statically indeterminate; the closures carry the load and σ = 0 (no friction force)
        until the set of closed rows changes."""
        gaps, p = self.gaps, self.p
        if not closed_s:
            return False
        row = gaps.rows[i][0]
        _, gq, tv = gaps(q_s, np.zeros(self.nq), t_s, p)
        if slides_in_space(row):
            idx, ts = gaps.tangent_of[row.gap_row], gaps.tangent_size
            dirs = tv[idx * ts:(idx + 1) * ts]
        else:
            dirs = gq[i:i + 1]
        cq = with_parameters(self.phases(closed_s), p).sim.model.constraint_jacobian(q_s, t_s)
        cq = cq.toarray() if hasattr(cq, "toarray") else np.asarray(cq).reshape(-1, self.nq)
        for d in dirs:
            x_d = np.linalg.lstsq(cq.T, d, rcond=None)[0]
            if np.linalg.norm(cq.T @ x_d - d) > 1e-8 * max(np.linalg.norm(d), 1e-300):
                return False
        return True

    def engage(self, q_s, v_s, t_s, closed_s):
        """After an event.  Slide rows of frictional contacts that just closed: stick or
        slide; of contacts that opened: released (σ = 0).  Sliding stick-slip joints whose
        velocity an impact reversed: σ follows (``slip``).  Friction rows whose slip the
        closed rows fix (:meth:`held`: a joint on its closed stop, a pinned rod's tip on the
        floor): σ = 0; released: stick or slide."""
        gaps, p, pnames, events = self.gaps, self.p, self.pnames, self.events
        for i in range(self.n_gaps):
            row = gaps.rows[i][0]
            if isinstance(row, StickRow) and i not in closed_s:
                k_sign = pnames.index(row.sign)
                if self.held(i, q_s, t_s, closed_s):
                    p[k_sign] = 0.0
                    continue
                sigma = p[k_sign]
                p[k_sign] = 1.0
                rate = float(gaps(q_s, v_s, t_s, p)[0][i])  # q̇_j
                p[k_sign] = sigma
                if sigma == 0.0:  # released by its stop
                    if abs(rate) > 1e-12:
                        p[k_sign] = float(np.sign(rate))
                        events.append({"time": float(t_s), "element": row.name,
                                       "kind": "slip"})
                    else:
                        v_s, closed_s = self.settle(i, q_s, v_s, t_s, closed_s)
                elif sigma * rate < -1e-12:  # an impact reversed the sliding direction
                    p[k_sign] = -sigma
                    events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
                continue
            if not isinstance(row, SlideRow):
                continue
            if row.gap_row not in closed_s:
                closed_s = closed_s - {i}
                p[pnames.index(row.sign)] = 0.0
            elif i not in closed_s and self.held(i, q_s, t_s, closed_s):
                p[pnames.index(row.sign)] = 0.0
            elif i not in closed_s and p[pnames.index(row.sign)] != 0.0:
                # sliding: an impact elsewhere may have reversed (turned) the slip — the force
                # follows it (``slip``), never the stuck trial of a stop
                if slides_in_space(row):
                    vt = gaps.slip_velocity(i, q_s, v_s, t_s, p)
                    stored = np.array([p[pnames.index(par)] for par in row.direction])
                    if float(np.linalg.norm(vt)) > 1e-12 and float(stored @ vt) <= 0.0:
                        self.start_slide(row, vt)
                        events.append({"time": float(t_s), "element": row.name,
                                       "kind": "slip"})
                else:
                    sigma = p[pnames.index(row.sign)]
                    rate = float(gaps(q_s, v_s, t_s, p)[0][i])  # σ ṡ
                    if rate < -1e-12:
                        p[pnames.index(row.sign)] = -sigma
                        events.append({"time": float(t_s), "element": row.name,
                                       "kind": "slip"})
            elif i not in closed_s and p[pnames.index(row.sign)] == 0.0 and \
                    slides_in_space(row):
                vt = gaps.slip_velocity(i, q_s, v_s, t_s, p)
                if float(np.linalg.norm(vt)) > 1e-12:
                    self.start_slide(row, vt)
                    events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
                else:
                    v_s, closed_s = self.settle(i, q_s, v_s, t_s, closed_s)
            elif i not in closed_s and p[pnames.index(row.sign)] == 0.0:
                p[pnames.index(row.sign)] = 1.0
                rate = float(gaps(q_s, v_s, t_s, p)[0][i])
                if abs(rate) > 1e-12:
                    p[pnames.index(row.sign)] = float(np.sign(rate))
                    events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
                else:
                    v_s, closed_s = self.settle(i, q_s, v_s, t_s, closed_s)
        return v_s, closed_s
