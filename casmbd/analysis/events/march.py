"""The march of an event-driven run: phase by phase over the output grid, event by event.

:class:`March` holds the state of one run (time, state, closed gaps, the run's parameters,
the events so far) and takes it over the output grid in sub-intervals (``substeps`` per
output interval; their states come in windows of :data:`WINDOW` from one integrator call):
after each sub-interval it looks for an open gap that closed in (an impact) or a closed gap
whose force turned (a detach, a stuck row that slips), locates the first such event
(:func:`~casmbd.analysis.events.roots.locate`), applies it (impact impulses, detach, stick or
slip) and restarts the phase of the new set of closed gaps from there.
"""

from __future__ import annotations

import math
import time

import numpy as np

from casmbd.analysis.events.event_rows import EventRows, SlideRow, StickRow
from casmbd.analysis.events.friction import Friction, slides_in_space
from casmbd.analysis.events.guards import (
    PERIODIC_SPREAD,
    PROJECT_AFTER,
    REST_HEIGHT,
    ZENO_FRACTION,
    ZENO_IMPACTS,
    periodic_overrun,
    zeno_guard,
)
from casmbd.analysis.events.impulses import impact, project
from casmbd.analysis.events.phases import PhaseSet, with_parameters
from casmbd.analysis.events.roots import locate
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.checks import check_mass_matrix, check_start
from casmbd.analysis.instant.kkt import consistent_state
from casmbd.analysis.integrators import kinds as integ
from casmbd.errors import AnalysisError, IntegratorError
from casmbd.model.contact_models import acts_at_events
from casmbd.model.contacts import slides
from casmbd.model.needs import EVENT_NEEDS
from casmbd.system import System

__all__ = ["WINDOW", "March"]

#: sub-intervals integrated in one call (one solver history) between events
WINDOW = 32


class March:
    """One event-driven run of ``mechanism`` from ``t_start`` to ``t_end`` (``steps`` output
    intervals); the options are those of
    :func:`~casmbd.analysis.events.events.simulate_events`.  Built: the base simulator, the
    event rows, the consistent start (checked); :meth:`run` marches."""

    def __init__(self, mechanism, t_end: float, steps: int, *, simulator_factory, integrator,
                 rtol, atol, t_start, substeps, rest_velocity, max_events, max_steps):
        self.clock = time.perf_counter()
        self.atol = rtol if atol is None else atol
        if not (isinstance(substeps, int) and substeps >= 1):
            raise AnalysisError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.mechanism, self.t_end, self.t_start = mechanism, t_end, t_start
        self.rtol, self.substeps, self.max_events = rtol, substeps, max_events
        self._build(simulator_factory, integrator)
        self._rest_velocities(rest_velocity)
        self.phases = PhaseSet(mechanism, self.base, self.gaps, simulator_factory, self.name,
                               rtol, self.atol, max_steps)
        # the parameters of the phase (stick-slip: the sliding sign σ and the stuck
        # position), set on every phase's model before it is used
        self.p = np.array(self.base.model.p, dtype=float)
        self.default_p = self.p.copy()
        self.pnames = list(self.base.model.parameter_names)
        self.grid = np.linspace(t_start, t_end, int(steps) + 1)
        self._start()
        self.closed: frozenset = frozenset()
        self.events: list[dict] = []
        self.impact_times: dict[str, list[float]] = {}  # per gap, for the Zeno guard
        # the impact interval of a rebound at the default rest velocity under the gravity,
        # 2 v / g: accumulating impacts far below it are beyond what the event location
        # resolves
        self.zeno_interval = ZENO_FRACTION * 2.0 * math.sqrt(2 * self.g_acc * REST_HEIGHT) / \
            self.g_acc
        self.friction = Friction(self.gaps, self.p, self.pnames, self.events, self.phases,
                                 self.nq)
        self.tol_t = 1e-13

    def _build(self, simulator_factory, integrator) -> None:
        """The base simulator (no gap closed), the integrator's name and the event rows."""
        mechanism = self.mechanism
        elements = [c for c in mechanism.contacts.values() if acts_at_events(c)]
        elements += [StickRow(f) for f in mechanism.forces.values()
                     if getattr(f, "stick_slip", False)]
        elements += [SlideRow(c) for c in mechanism.contacts.values() if slides(c)]
        base = self.base = simulator_factory(mechanism)
        base.kind.refuse_events()  # GGL's index-2 restart, numeric right-hand sides
        name = self.name = integrator or base.kind.event_integrator
        if not EVENT_NEEDS <= getattr(integ.INTEGRATORS.get(name), "handles", frozenset()):
            raise AnalysisError(f"integrator '{name}': the event-driven run uses a "
                                "variable-step SUNDIALS integrator (cvodes, adams, idas)")
        self.gaps = EventRows(System(mechanism), elements)
        self.n_gaps = len(self.gaps.rows)
        self.nq = base.model.nq

    def _rest_velocities(self, rest_velocity) -> None:
        """The run's rest velocity (default: a rebound of :data:`REST_HEIGHT` under the
        gravity) and each gap's (a contact's own rest velocity wins over the run's)."""
        self.g_acc = math.hypot(*map(float, self.mechanism.gravity)) or 9.81  # no overflow
        self.v_rest = rest_velocity if rest_velocity is not None else \
            math.sqrt(2 * self.g_acc * REST_HEIGHT)
        rows = self.gaps.rows
        self.v_rests = np.array([self.v_rest if getattr(rows[i][0], "rest_velocity", None)
                                 is None else rows[i][0].rest_velocity
                                 for i in range(self.n_gaps)])

    def _start(self) -> None:
        """The consistent start state ``x``, after the pre-run checks of a smooth run (a
        NaN's culprit, the bodies without mass); refused when a gap starts penetrated."""
        base, t_start, gaps = self.base, self.t_start, self.gaps
        q0, v0 = base.model.initial_coordinates(), base.model.initial_velocities()
        u0 = base.inputs_at(t_start)
        ode_acc = base._ode_accelerations(t_start)  # a model without compiled forces: its ODE
        check_start(base.model, q0, v0, t_start, u0, what="simulation",
                    every=ode_acc is not None and not np.all(np.isfinite(ode_acc(q0, v0))))
        check_mass_matrix(base.model, assemble(base.model, q0, t_start).q, t_start)
        start = consistent_state(base.model, q0, v0, t_start, u0)
        self.x = np.concatenate([start.q, start.v])
        g0, _, _ = gaps(start.q, start.v, t_start, self.p)
        if self.n_gaps and np.min(g0) < -1e-9:
            k = int(np.argmin(g0))
            what = "contact" if gaps.rows[k][0].event_kind == "impact" else "joint limit"
            bodies = [b for b in (getattr(gaps.rows[k][0], key, None)
                                  for key in ("body", "body1", "body2")) if isinstance(b, str)]
            where = f" (body {', '.join(repr(b) for b in bodies)}: check its 'position' and " \
                f"the {what}'s points)" if bodies else ""
            raise AnalysisError(f"{what} '{gaps.label(k)}': the initial pose penetrates by "
                                f"{-g0[k]:.3g} (gap < 0 at t = {t_start:g}){where}; start it "
                                "open or touching")

    def run(self, record: dict) -> list[tuple]:
        """March to the end; the samples (t, x, closed gaps, parameters) at the output times
        (an event at an output time: the state after it).  ``record`` receives what a failure
        inside the loop needs to keep the results so far
        (:func:`~casmbd.analysis.events.events.simulate_events`)."""
        nq, t_start, grid, substeps = self.nq, self.t_start, self.grid, self.substeps
        self.x, self.closed = self.friction.start(self.x, t_start, self.closed)
        self.phase = with_parameters(self.phases(self.closed), self.p)
        self.z = self.phase.z0(self.x[:nq], self.x[nq:], t_start)
        self.samples = [(t_start, self.x.copy(), self.closed, self.p.copy())]
        self.t = t_start
        record.update(base=self.base, phase_of=self.phases, gaps=self.gaps, grid=grid,
                      samples=self.samples, events=self.events, name=self.name,
                      atol=self.atol, default_p=self.default_p, clock=self.clock,
                      now=lambda: (self.t, self.x, self.closed, self.p.copy()))
        # every sub-interval end of the run; states come in windows of WINDOW of them from
        # one integrator call, restarted only after an event
        self.sub_all = np.concatenate([np.linspace(grid[k], grid[k + 1], substeps + 1)[1:]
                                       for k in range(len(grid) - 1)])
        self.window: dict[float, tuple] = {}
        for k_out in range(len(grid) - 1):
            sub = np.linspace(grid[k_out], grid[k_out + 1], substeps + 1)
            j = 0
            while j < substeps:
                if self._sub_interval(sub[j + 1]):
                    j += 1
            self.samples.append((self.t, self.x.copy(), self.closed, self.p.copy()))
        return self.samples

    def _sub_interval(self, t_b) -> bool:
        """Advance to the sub-interval's end ``t_b``, or to its first event (then restart
        there): True when ``t_b`` is reached."""
        gaps, closed, t = self.gaps, self.closed, self.t
        h = t_b - t
        if h <= self.tol_t * (1 + abs(t)):
            return True
        if t_b not in self.window:
            self._fill_window(t_b)
        x_b, z_b, g_b, lam_b = self.window[float(t_b)]
        open_hit = [i for i in range(self.n_gaps) if i not in closed and
                    gaps.active(i, closed) and g_b[i] < -1e-13]
        order = sorted(closed)
        lams_b = dict(zip(order, lam_b, strict=True))
        # contact force along +∇g is −λ (Q_c = −C_qᵀ λ): detach when −λ < 0; a stuck
        # joint slips when |λ| > F_c, a stuck contact when |λ| > μ N
        pulls = [i for i in order if gaps.closed_value(i, lams_b) < 0.0]
        if not open_hit and not pulls:
            self.x, self.z, self.t = x_b, z_b, t_b
            return True
        (t_ev, i_ev, is_detach), pressed, released = locate(
            self.phase, gaps, self.p, self.nq, self.x, self.z, t, h, t_b, open_hit + pulls,
            closed, lams_b, g_b, self.tol_t)
        if i_ev is None:
            self.x, self.z, self.t = x_b, z_b, t_b
            return True
        self._apply(t_ev, i_ev, is_detach, pressed, released)
        return False

    def _fill_window(self, t_b) -> None:
        """The states, gaps and closed rows' multipliers at the next :data:`WINDOW`
        sub-interval ends from ``t_b`` on, from one integrator call (up to a failure)."""
        nq, x, t, tol_t = self.nq, self.x, self.t, self.tol_t
        self.friction.reanchor(x[:nq], x[nq:], t)
        first = int(np.searchsorted(self.sub_all, t_b - 0.5 * tol_t * (1 + abs(t_b))))
        times = self.sub_all[first:first + WINDOW]
        xs_w, zs_w = self.phase.advance_many(x, self.z, t, times)
        times = times[:len(xs_w)]  # up to a failure (advance_many)
        g_w = self.gaps.values_many(xs_w[:, :nq], xs_w[:, nq:], times, self.p)
        lam_w = self.phase.multipliers_many(xs_w[:, :nq], xs_w[:, nq:], times)
        self.window = {float(tk): (xs_w[m], zs_w[m], g_w[m], lam_w[m])
                       for m, tk in enumerate(times)}

    def _apply(self, t_ev, i_ev, is_detach, pressed, released) -> None:
        """The event of gap ``i_ev`` at ``t_ev`` located from the current state: a stuck row
        that slips, a slip that turned, a sliding row that stopped, a detach, an impact (or
        a resting contact, a grazing touch); then the restart after it."""
        nq, gaps, friction, p = self.nq, self.gaps, self.friction, self.p
        x_a, z_a, t_a, phase = self.x, self.z, self.t, self.phase
        x_ev, _ = phase.advance(x_a, z_a, t_a, t_ev - t_a) if t_ev > t_a else (x_a, z_a)
        q_ev, v_ev = x_ev[:nq], x_ev[nq:]
        element = gaps.rows[i_ev][0]
        if is_detach and gaps.stick[i_ev]:  # the holding force reached F_c: it slips
            order = sorted(self.closed)
            lam_ev = float(phase.multipliers(q_ev, v_ev, t_ev)[order.index(i_ev)])
            v_new = v_ev
            if slides_in_space(element):  # along λ_t, from v_t = 0 exactly (the index-1
                # drift of the stuck phase, ~1e-9 m/s, would set a direction of its own)
                friction.start_slide(element, phase.tangent_multipliers(q_ev, v_ev, t_ev,
                                                                        order.index(i_ev)))
                v_new = project(phase.sim.model, gaps, self.closed, q_ev, v_ev, t_ev, p)
            else:
                p[self.pnames.index(element.sign)] = float(np.sign(lam_ev))
            self.closed = self.closed - {i_ev}
            self.events.append({"time": float(t_ev), "element": element.name, "kind": "slip"})
        elif slides_in_space(element) and float(np.linalg.norm(gaps.slip_velocity(
                i_ev, q_ev, v_ev, t_ev, p))) > 1e-7:
            # ŝ·v_t crossed zero but the contact still slips (its slip turned): follow it
            friction.start_slide(element, gaps.slip_velocity(i_ev, q_ev, v_ev, t_ev, p))
            v_new = v_ev
        elif gaps.stick[i_ev]:  # a sliding joint stopped: stick, or slide back
            v_new, self.closed = friction.settle_group(
                [i_ev] + [k for k in range(self.n_gaps) if k != i_ev and
                          friction.stopped(k, q_ev, v_ev, t_ev, self.closed)],
                q_ev, v_ev, t_ev, self.closed)
        elif is_detach:
            opened = sorted(released) if i_ev in released else [i_ev]
            self.closed = self.closed - set(opened)
            self.events += [{"time": float(t_ev), "element": gaps.label(i), "kind": "detach"}
                            for i in opened]
            v_new = v_ev
        else:
            v_new = self._impact(i_ev, q_ev, v_ev, t_ev, pressed)
        if len(self.events) > self.max_events:
            raise IntegratorError(
                f"more than {self.max_events} events by t = {t_ev:.6g} (raise max_events, or "
                f"the rest velocity {self.v_rest:.3g} m/s: [simulation] max_events / "
                "rest_velocity in the scene, --max-events / --rest-velocity)", t_ev,
                "MAX_EVENTS", None)
        self._restart(q_ev, v_new, t_ev)

    def _impact(self, i_ev, q_ev, v_ev, t_ev, pressed) -> np.ndarray:
        """v⁺ after gap ``i_ev`` reached zero at ``t_ev``: the impact's (every gap struck,
        guarded against Zeno behaviour and a periodic overrun), a resting contact's (closes
        with no impulse, with every gap pressed in at that instant) or, grazing, v⁻."""
        gaps, p = self.gaps, self.p
        hit = impact(self.phases(self.closed).sim.model, gaps, self.closed, i_ev, q_ev, v_ev,
                     t_ev, p, self.v_rests)
        if hit is None and i_ev in pressed:  # resting: closes with no impulse
            v_new = project(self.phases(self.closed).sim.model, gaps, self.closed | pressed,
                            q_ev, v_ev, t_ev, p)
            self.closed = self.closed | pressed
            self.events += [{"time": float(t_ev), "element": gaps.label(i),
                             "kind": "contact"} for i in sorted(pressed)]
            return v_new
        if hit is None:  # grazing: the gap touches zero without closing in on it
            return v_ev
        v_new, self.closed, struck = hit  # the gaps struck (i_ev among them), …
        self.events += [{"time": float(t_ev), "element": lab, "kind": kind}
                        for lab, kind in struck]
        for lab, kind in struck:
            if kind == "impact":
                self._guard(lab, t_ev)
        return v_new

    def _guard(self, lab: str, t_ev: float) -> None:
        """Stop at an impact of ``lab`` when its impacts accumulate (Zeno) or repeat so that
        more than ``max_events`` would come by t_end (:mod:`~casmbd.analysis.events.guards`)."""
        events, v_rest, max_events = self.events, self.v_rest, self.max_events
        zeno = zeno_guard(self.impact_times.setdefault(lab, []), t_ev, self.zeno_interval)
        if zeno:
            raise IntegratorError(
                f"Zeno behaviour: the impacts of '{lab}' accumulate at t ≈ "
                f"{zeno[0]:.9g} ({zeno[1]}); stopped at the impact at t = "
                f"{t_ev:.9g} after {len(events)} events. A rest velocity "
                f"closes the contact before (now {v_rest:.3g} m/s: "
                "--rest-velocity, or rest_velocity in the scene's "
                "[simulation])", t_ev, "ZENO", None)
        over = periodic_overrun(self.impact_times[lab], self.t_end,
                                max_events - len(events)) \
            if len(events) >= PROJECT_AFTER else None
        if over:
            raise IntegratorError(
                f"more than {max_events} events by t_end = {self.t_end:g}: "
                f"the impacts of '{lab}' repeat every {over[0]:.6g} s "
                f"(the last {ZENO_IMPACTS + 1} intervals equal to within "
                f"{PERIODIC_SPREAD:g}), {over[1]} more to come; stopped "
                f"at the impact at t = {t_ev:.6g} after {len(events)} "
                f"events (raise max_events, or the rest velocity "
                f"{v_rest:.3g} m/s: [simulation] max_events / "
                "rest_velocity in the scene, --max-events / "
                "--rest-velocity)", t_ev, "MAX_EVENTS", None)

    def _restart(self, q_ev, v_new, t_ev) -> None:
        """The friction after the event (:meth:`Friction.engage`), then the phase of the new
        set of closed gaps from (q_ev, v_new) at ``t_ev``; an event at an output time gives
        that output the state after it."""
        tol_t = self.tol_t
        v_new, self.closed = self.friction.engage(q_ev, v_new, t_ev, self.closed)
        self.phase = with_parameters(self.phases(self.closed), self.p)
        self.x = np.concatenate([q_ev, v_new])
        self.z = self.phase.z0(q_ev, v_new, t_ev)
        self.t = t_ev
        self.window = {}
        samples = self.samples
        if abs(t_ev - samples[-1][0]) <= tol_t * (1 + abs(t_ev)):  # at an output time:
            samples[-1] = (samples[-1][0], self.x.copy(), self.closed, self.p.copy())
