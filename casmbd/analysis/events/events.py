"""Event-driven forward dynamics with unilateral elements: impacts, contact, detach (issue 24).

A mechanism with contacts or joint limits of the ``"impact"`` model
(:mod:`casmbd.model.contacts`) is integrated phase by phase (Pfeiffer & Glocker, *Multibody
Dynamics with Unilateral Contacts*, 1996, ch. 6–7; the event-driven scheme of Adams' and
Simpack's non-smooth contacts):

1. **Smooth phase.** The mechanism with the *closed* gaps as bilateral constraints (a
   :class:`~casmbd.model.contacts.GapClosure` joint each; one compiled
   :class:`~casmbd.analysis.dynamics.simulate.Simulator` per set of closed gaps, built once) is
   integrated in sub-intervals of the output grid (``substeps`` per interval; a variable-step
   SUNDIALS integrator on the time-scaled dynamics h f(t0 + h s, x), s ∈ [0, 1], so one
   compiled integrator serves every step length).
2. **Events.** After each sub-interval: an open gap g_k(q) < 0 is an *impact* (``limit`` for a
   joint stop), a closed gap whose normal force −λ_k turned negative a *detach*.  The event
   time is found by the Illinois variant of regula falsi on g_k(x(t)) (or λ_k), integrating
   from the sub-interval's start, to |Δt| ≤ 1e-13 (1 + |t|) — the first event of the
   sub-interval wins.
3. **Impact.** The post-impact velocity v⁺ solves Newton's law on the active gaps I with the
   bilateral constraints (impulses P ≥ 0, μ):

       [M  C_qᵀ G_Iᵀ] [v⁺]   [M v⁻       ]
       [C_q 0    0  ] [μ ] = [−C_t       ]
       [G_I 0    0  ] [P ]   [−e G_I v⁻  ]

   G = ∂g/∂q.  A gap with P_k < 0 leaves the set and the system is solved again.  With
   friction μ_f at a contact, the tangential impulse first sticks (T v⁺ = 0 added); if
   |P_t| > μ_f P_n the contact slips and P_t = −μ_f P_n sign(T v⁻) (the impulse direction
   becomes G − μ_f sign(v_t) T) — Coulomb's law on the impulse level.  Events ``stick`` or
   ``slip`` follow the impact of a frictional contact.
4. **Rest.** A gap whose rebound speed G_k v⁺ is below ``rest_velocity`` (default
   sqrt(2 g_r 1e-9 m): a bounce lower than a nanometre) closes — Zeno's infinite sequence of
   ever smaller bounces is cut there — and stays closed until its normal force vanishes
   (``contact`` then ``detach``).

The result carries ``events`` (time, element, kind), ``contact_forces`` (the closed gaps'
normal forces, zero when open, n_t × n_gaps) and every array of a smooth run.
"""

from __future__ import annotations

import copy
import math
import re
import sys
import time
import warnings

import casadi as ca
import numpy as np

from casmbd.analysis.events.buffered import Buffered
from casmbd.analysis.events.event_rows import EventRows, SlideRow, StickRow, closure
from casmbd.analysis.events.impulses import impact, project
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.checks import check_mass_matrix, check_start, diagnose_failure
from casmbd.analysis.instant.joint_friction import has_reaction_friction
from casmbd.analysis.instant.kkt import accelerations_and_multipliers, consistent_state
from casmbd.analysis.integrators import kinds as integ
from casmbd.analysis.integrators import sundials as sun
from casmbd.analysis.integrators.stiffness_culprit import diagnose_stiffness
from casmbd.errors import AnalysisError, CasmbdError, IntegratorError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.contact_models import CONTACT_MODELS, acts_at_events
from casmbd.model.contacts import SLIP_VELOCITY, ContactSlide, slides
from casmbd.model.needs import EVENT_NEEDS, requirements
from casmbd.results import Result
from casmbd.system import System

__all__ = ["MAX_EVENTS", "MAX_EVENTS_LIMIT", "SIMULATION_KEYS", "compliant_events", "has_events",
           "periodic_overrun", "simulate_events", "zeno_guard"]

#: default sub-intervals per output interval in which gaps are checked
SUBSTEPS = 4
#: sub-intervals integrated in one call (one solver history) between events
WINDOW = 32
#: rebound height below which a contact closes instead of bouncing again (m)
REST_HEIGHT = 1e-9
#: default bound on the number of events of one run
MAX_EVENTS = 10_000
#: trial times h 2⁻ᵏ (k = 1 … DYADIC) of :func:`_inside`, screened in one integrator call
DYADIC = 60
#: Zeno guard (:func:`zeno_guard`): impact intervals of one gap that shrink geometrically
ZENO_IMPACTS = 10
#: … with their mean ratio at most this (1: the equal intervals of e = 1 bounces)
ZENO_RATIO = 0.999
#: … and every ratio within this fraction of their mean
ZENO_SPREAD = 0.1
#: … and the last interval below this fraction of a rebound's at the default rest velocity
ZENO_FRACTION = 0.01
#: event-count projection (:func:`periodic_overrun`): made after this many events …
PROJECT_AFTER = 1000
#: … when the last ZENO_IMPACTS + 1 impact intervals of one gap agree to this (relative)
PERIODIC_SPREAD = 1e-6
#: the largest ``max_events`` accepted (scene, CLI, API)
MAX_EVENTS_LIMIT = 10_000_000
#: keys of a scene's ``[simulation]`` table (options of the event-driven run)
SIMULATION_KEYS = ("max_events", "rest_velocity")
#: a line of a Python warning, as printed by ``warnings`` or the CLI
_WARNING_LINE = re.compile(r"^warning: |\b[A-Z]\w*Warning: ")
#: the SUNDIALS flag in a CasADi error message
_FLAG = re.compile(r'returned "([A-Z_]+)"')
#: advice per SUNDIALS flag of a failure inside the event loop
_ADVICE = {
    "CV_TOO_MUCH_WORK": "a force or driver that grows without bound there (a singularity "
                        "in time or state), or raise --max-steps",
    "IDA_TOO_MUCH_WORK": "a force or driver that grows without bound there (a singularity "
                         "in time or state), or raise --max-steps",
    "CV_FIRST_RHSFUNC_ERR": "the equations of motion are not finite at the start of the "
                            "step: check masses, inertias, forces and gravity",
    "CV_RHSFUNC_FAIL": "the equations of motion are not finite: check masses, inertias, "
                       "forces and gravity",
    "CV_ILL_INPUT": "values too large for the integrator (a mass, force or gravity near the "
                    "floating-point limit?): give the model in sensible units",
    "NO_PROGRESS": "the step size fell to zero: values too large for the integrator (a mass, "
                   "force or gravity near the floating-point limit?): give the model in "
                   "sensible units",
    "IDA_ILL_INPUT": "values too large for the integrator (a mass, force or gravity near the "
                     "floating-point limit?): give the model in sensible units",
}


def zeno_guard(times: list[float], t: float, interval: float) -> tuple[float, str] | None:
    """Record an impact of one gap at ``t`` in ``times``; the accumulation point and a
    description when its impacts accumulate (Zeno behaviour), else None.

    Impacts accumulate when the last :data:`ZENO_IMPACTS` + 1 intervals Δ_k = t_k − t_(k−1)
    shrink geometrically, Δ_(k+1) = r Δ_k, every ratio within :data:`ZENO_SPREAD` of their
    mean r ≤ :data:`ZENO_RATIO` < 1 (a ball of restitution e under constant gravity: r = e),
    and the last interval is below ``interval``.  The impacts then end at the limit of the
    geometric series, t* = t + Δ r / (1 − r) (the bouncing ball's Zeno time t₁ (1 + e)/(1 − e)
    from its first impact); without a rest velocity an event-driven run would locate ever
    closer impacts there, until the event bound or the limits of the event location.
    """
    times.append(float(t))
    del times[:-(ZENO_IMPACTS + 2)]
    if len(times) < ZENO_IMPACTS + 2:
        return None
    gaps = np.diff(times)
    if gaps[-1] >= interval or np.any(gaps <= 0.0):
        return None
    ratios = gaps[1:] / gaps[:-1]
    r = float(np.mean(ratios))
    if not (0.0 < r <= ZENO_RATIO) or np.max(np.abs(ratios / r - 1.0)) > ZENO_SPREAD:
        return None
    t_star = float(t) + float(gaps[-1]) * r / (1.0 - r)
    return t_star, (f"the last {ZENO_IMPACTS + 1} intervals shrink by the ratio {r:.3g}, the "
                    f"last {gaps[-1]:.3g} s")


def periodic_overrun(times: list[float], t_end: float, budget: int) -> tuple[float, int] | None:
    """(period, impacts to come) when the impacts of one gap (``times``, the last ones, as
    kept by :func:`zeno_guard`) repeat with a constant period and at that period more than
    ``budget`` impacts would come before ``t_end``, else None.

    Constant period: the last :data:`ZENO_IMPACTS` + 1 intervals within
    :data:`PERIODIC_SPREAD` of their mean Δ (a ball of restitution 1 under gravity, a rod
    between elastic stops); the impacts to come are ⌊(t_end − t)/Δ⌋.  The event bound would
    be reached for certain were the motion to stay periodic: the event loop then stops at
    once instead of locating the remaining events of the budget one by one (10 000 events
    of the e = 1 ball took 160 s; issue 31).  O(1) per impact (at most ZENO_IMPACTS + 2
    times are kept).
    """
    if len(times) < ZENO_IMPACTS + 2:
        return None
    gaps = np.diff(times)
    period = float(np.mean(gaps))
    if not period > 0.0 or np.max(np.abs(gaps - period)) > PERIODIC_SPREAD * period:
        return None
    coming = math.floor((t_end - times[-1]) / period)
    return (period, coming) if coming > budget else None


class _StepError(RuntimeError):
    """An integrator call of the event loop failed between ``t_lo`` (state ``x_lo``, the
    last one reached) and ``t_hi``."""

    def __init__(self, message: str, t_lo: float, t_hi: float, x_lo: np.ndarray):
        super().__init__(message)
        self.t_lo, self.t_hi, self.x_lo = float(t_lo), float(t_hi), np.array(x_lo, float)


def has_events(mechanism) -> bool:
    """True when the mechanism has unilateral elements of the impact model or joint friction
    with the exact (stick-slip) Coulomb law."""
    return any(r.need in EVENT_NEEDS for r in requirements(mechanism))


def compliant_events(result: Result, mechanism) -> None:
    """Contact and detach of compliant contacts and stops, read off the result grid: where a
    reported gap (``force_outputs`` "<element>.force.gap", "….lower_gap" …) changes sign, at
    the time of the linear interpolation between the two samples (the grid's resolution: the
    compliant model has no event detection of its own).  Appended to ``result.events``."""
    names = result.names.get("force_outputs", [])
    out = result.arrays.get("force_outputs")
    if out is None:
        return
    found = []
    for c in getattr(mechanism, "contacts", {}).values():
        if CONTACT_MODELS[c.model].force is None:  # no force element reporting its gaps
            continue
        prefix = f"{c.name}.force."
        for k, col in enumerate(names):
            if not (col.startswith(prefix) and col.endswith("gap")):
                continue
            g = out[:, k]
            label = c.name if col == prefix + "gap" else \
                f"{c.name}.{col[len(prefix):].removesuffix('_gap')}"
            for m in np.flatnonzero((g[:-1] > 0.0) != (g[1:] > 0.0)):
                frac = g[m] / (g[m] - g[m + 1]) if g[m] != g[m + 1] else 0.0
                when = float(result.t[m] + frac * (result.t[m + 1] - result.t[m]))
                found.append({"time": when, "element": label,
                              "kind": "contact" if g[m] > 0.0 else "detach"})
    if found:
        result.events = sorted(result.events + found, key=lambda e: e["time"])
        result.stats["event_times"] = "compliant contacts: interpolated on the output grid"


def _scaled(dyn: ca.Function) -> ca.Function:
    """g(s, x, z, [p; t0; h], u) = (h f(t0 + h s, …), alg): the dynamics on s ∈ [0, 1]."""
    s = ca.MX.sym("t")
    x = ca.MX.sym("x", dyn.sparsity_in("x"))
    z = ca.MX.sym("z", dyn.sparsity_in("z"))
    p = ca.MX.sym("p", dyn.size1_in("p") + 2)
    u = ca.MX.sym("u", dyn.sparsity_in("u"))
    h = p[-1]
    out = dyn(t=p[-2] + h * s, x=x, z=z, p=p[:-2], u=u)
    return ca.Function("scaled", [s, x, z, p, u],
                       [h * out["ode"], out["alg"], h * out["quad"], out["zero"]],
                       ca.dyn_in(), ca.dyn_out())


def _progress(stats: dict, t0: float, h: float, x, end: float = 1.0) -> None:
    """Raise :class:`_StepError` when a SUNDIALS call returned without reaching the end of
    its interval (scaled time ``end``: 1, ½ for :meth:`_Phase.advance_dyadic`): with a step
    size of zero (values near the floating-point limit, e.g. gravity 1e308) CVODES warns
    "t + h = t on the next step" and returns the start state unchanged instead of failing."""
    reached = stats.get("tcur", 1.0)
    if isinstance(reached, float) and math.isfinite(reached) and reached < end * (1.0 - 1e-9):
        raise _StepError(f'the integrator returned "NO_PROGRESS": step size '
                         f'{stats.get("hcur", 0.0):.3g} at t = {t0 + reached * h:.6g}',
                         t0, t0 + h, x)


def _solve(solver, x, z, p) -> tuple[np.ndarray, np.ndarray]:
    """(xf, zf) of one integrator call, as arrays (columns: output times): a
    :class:`Buffered` CasADi integrator, a CasADi integrator (called with a dict: its
    keyword call costs ~80 µs more), or a
    :class:`~casmbd.analysis.integrators.sundials.ConsistentStart` called by keywords."""
    if isinstance(solver, Buffered):
        out = solver(x0=x, z0=z, p=p)
        return out[0], out[1]
    if isinstance(solver, ca.Function):
        r = solver.call({"x0": x, "z0": z, "p": p})
        return r["xf"].full(), r["zf"].full()
    r = solver(x0=x, z0=z, p=p)
    return np.asarray(r["xf"], float), np.asarray(r["zf"], float)


class _Phase:
    """A Simulator of the mechanism with a set of closed gaps, and its step integrators."""

    def __init__(self, sim, closed: frozenset, closure_rows: list[int], name, rtol, atol,
                 max_steps, pairs: dict[int, int] | None = None):
        self.sim, self.closed, self.closure_rows = sim, closed, closure_rows
        #: closed rows (by position in ``closure_rows``) whose closure has a second row (a
        #: contact stuck in space, two tangential rows): their value is |λ_t|
        self.pairs = pairs or {}
        #: the phase integrates an independent subset of its rows (redundant closures):
        #: multipliers are taken with the minimum norm (:func:`_minimum_norm`)
        self.redundant = getattr(sim, "redundancy", {}).get("kept_rows") is not None
        #: every row of the closures (a pair's second rows included)
        self.all_rows = list(closure_rows) + list(self.pairs.values())
        self._scaled = _scaled(sim.dyn)
        self.name, self.rtol, self.atol, self.max_steps = name, rtol, atol, max_steps
        self._many: dict[tuple, object] = {}
        self._mapped: bool | None = None  # the post-processing serves λ (no N-friction)
        self._post_maps: dict[int, ca.Function] = {}
        self.integrator = Buffered.of(sun.sundials(self._scaled, name, 0.0, [1.0], rtol,
                                                     atol, max_steps))
        self._dyadic = None  # outputs at h 2⁻ᵏ, k = DYADIC … 1 (:meth:`advance_dyadic`)
        #: integrator steps and right-hand sides over every call (root finding included)
        self.steps = self.rhs_evaluations = 0

    def advance_many(self, x, z, t0: float, times: np.ndarray):
        """States at ``times`` (increasing, after t0) from (x, z) at t0 in one integrator call:
        one solver history over the window (a restart per sub-interval lost accuracy on dense
        output grids).  Integrators are cached by the relative output times."""
        span = float(times[-1] - t0)
        rel = tuple(np.round((np.asarray(times) - t0) / span, 12))
        solver = self._many.get(rel)
        if solver is None:
            if len(self._many) > 64:
                self._many.clear()
            # a window after an event has output times of its own (the event inside a
            # sub-interval), used once: called as built (a buffer costs more than it saves
            # on one call); a window of the uniform grid is used again: buffered then
            solver = self._many[rel] = sun.sundials(self._scaled, self.name, 0.0,
                                                      list(rel), self.rtol, self.atol,
                                                      self.max_steps)
        elif isinstance(solver, ca.Function):
            solver = self._many[rel] = Buffered.of(solver)
        try:
            xf, zf = _solve(solver, x, z, np.concatenate([self.sim.model.p, [t0, span]]))
        except RuntimeError as exc:
            reraise_interrupt(exc)
            # the states before the failure, sub-interval by sub-interval: the event loop
            # checks them as usual, and its next call from the last one raises _StepError
            # naming the failing sub-interval
            kept_x, kept_z, t_prev = [], [], t0
            try:
                for tk in times:
                    x, z = self.advance(x, z, t_prev, float(tk) - t_prev)
                    kept_x.append(x)
                    kept_z.append(z)
                    t_prev = float(tk)
            except _StepError as sub:
                if not kept_x:  # the first sub-interval fails: the window's flag, its times
                    message = str(exc) if _FLAG.search(str(exc)) else str(sub)
                    raise _StepError(message, sub.t_lo, sub.t_hi, sub.x_lo) from None
            return np.array(kept_x), np.array(kept_z).reshape(len(kept_x), len(z))
        st = solver.stats()
        _progress(st, t0, span, x)
        self.steps += int(st.get("nsteps", 0))
        self.rhs_evaluations += int(st.get("nfevals", 0))
        xs = xf.reshape(len(x), -1)
        zs = zf.reshape(len(z), -1) if len(z) else np.zeros((0, xs.shape[1]))
        return xs.T, zs.T

    def advance(self, x, z, t0, h):
        try:
            xf, zf = _solve(self.integrator, x, z,
                            np.concatenate([self.sim.model.p, [t0, h]]))
        except RuntimeError as exc:
            reraise_interrupt(exc)
            raise _StepError(str(exc), t0, t0 + h, x) from None
        st = self.integrator.stats()
        _progress(st, t0, h, x)
        self.steps += int(st.get("nsteps", 0))
        self.rhs_evaluations += int(st.get("nfevals", 0))
        return xf.ravel(), zf.ravel()

    def advance_dyadic(self, x, z, t0: float, h: float):
        """States at t0 + h 2⁻ᵏ, k = 1 … :data:`DYADIC` (rows, k ascending) from (x, z) at t0
        in one integrator call (one integrator per phase, built once): the trial times of
        :func:`_inside`, screened at once instead of one integrator call each."""
        if self._dyadic is None:
            self._dyadic = Buffered.of(sun.sundials(
                self._scaled, self.name, 0.0, [2.0 ** -k for k in range(DYADIC, 0, -1)],
                self.rtol, self.atol, self.max_steps))
        xf, zf = _solve(self._dyadic, x, z, np.concatenate([self.sim.model.p, [t0, h]]))
        st = self._dyadic.stats()
        _progress(st, t0, h, x, end=0.5)
        self.steps += int(st.get("nsteps", 0))
        self.rhs_evaluations += int(st.get("nfevals", 0))
        xs = xf.reshape(len(x), -1).T[::-1]
        zs = zf.reshape(len(z), -1).T[::-1] if len(z) else np.zeros((DYADIC, 0))
        return xs, zs

    def multipliers_many(self, qs: np.ndarray, vs: np.ndarray, ts: np.ndarray) -> np.ndarray:
        """λ of the closure rows at many states (rows), by the formulation's compiled
        post-processing mapped over them (one call per window); a state whose KKT residual
        is not small (a singular pose) and a mechanism whose friction follows the reactions
        take the exact per-state solve."""
        n = len(ts)
        if not self.closure_rows:
            return np.zeros((n, 0))
        model = self.sim.model
        if self._mapped is None:
            self._mapped = not has_reaction_friction(model)
        if self._mapped:
            p_all = np.tile(model.p[:, None], (1, n))
            if n not in self._post_maps:  # one mapped Function per window size, built once
                self._post_maps[n] = model.function("post").map(n)
            try:
                post = self._post_maps[n](qs.T, vs.T, ts[None, :], p_all)
            except RuntimeError as exc:  # the virtual machine's solve of a singular
                reraise_interrupt(exc)   # (redundant) KKT: every state by the exact solve
                self._mapped = False
                return self.multipliers_many(qs, vs, ts)
            acc = np.asarray(post[0], float).T
            lam = np.asarray(post[1], float).T.reshape(n, -1)
            residual = np.asarray(post[2], float).ravel()
            scale = 1.0 + np.max(np.abs(np.concatenate([acc, lam], axis=1)), axis=1,
                                 initial=0.0)
            bad = ~np.isfinite(residual) | (residual > 1e-8 * scale) | \
                ~np.all(np.isfinite(lam), axis=1)
        else:
            lam = np.zeros((n, model.nc))
            bad = np.ones(n, dtype=bool)
        for k in np.flatnonzero(bad):
            lam[k] = accelerations_and_multipliers(model, qs[k], vs[k], ts[k],
                                                   self.sim.inputs_at(ts[k]))[1]
        if self.redundant:
            lam = _minimum_norm(model, qs, ts, lam, self.all_rows)
        return self._closed(lam)

    def _closed(self, lam: np.ndarray) -> np.ndarray:
        """The closed rows' multipliers from all of λ (rows of states); a pair: |λ_t|."""
        out = lam[..., self.closure_rows]
        for m, second in self.pairs.items():
            out[..., m] = np.hypot(lam[..., self.closure_rows[m]], lam[..., second])
        return out

    def tangent_multipliers(self, q, v, t, m: int) -> np.ndarray:
        """λ_t (two components) of the closed row at position m, a contact stuck in space."""
        lam = self._all(q, v, t)
        return np.array([lam[self.closure_rows[m]], lam[self.pairs[m]]])

    def _all(self, q, v, t) -> np.ndarray:
        """λ of every row at one state (minimum norm when the phase is redundant)."""
        lam = accelerations_and_multipliers(self.sim.model, q, v, t, self.sim.inputs_at(t))[1]
        if self.redundant:
            lam = _minimum_norm(self.sim.model, q[None, :], np.array([t]), lam[None, :],
                                self.all_rows)[0]
        return lam

    def multipliers(self, q, v, t):
        """λ of the closure rows (the closed gaps' constraint multipliers)."""
        return self._closed(self._all(q, v, t)) if self.closure_rows else np.zeros(0)

    def z0(self, q, v, t):
        return self.sim.algebraic_state_at(q, v, t)


#: a value of an event row that counts as clearly inside (away from its surface) when the
#: motion starts on the surface: above the rounding of a gap that starts at zero (a body put
#: down touching a tilted plane starts at g ≈ 1e-17 m, not an impact 2 ns later)
INSIDE = 1e-14


def _minimum_norm(model, qs: np.ndarray, ts: np.ndarray, lam: np.ndarray,
                  rows: list[int]) -> np.ndarray:
    """Multipliers (rows of states) with the constraint forces C_qᵀ λ of ``lam`` and the least
    norm on the closure rows ``rows``: a phase whose closures are redundant (a box on four
    corners) integrates an independent subset, whose multipliers are one admissible split
    among many; the forces checked against μ N and reported are the least-norm split of the
    contacts, as the reactions of redundant joints are.  λ = λ₀ + Z y over the null space Z of
    C_qᵀ, y minimising |S λ|² (S the closure rows; the other rows — an Euler-parameter
    normalisation, whose multiplier a self-equilibrated squeeze of the contacts would also
    move — are not weighed)."""
    out = np.array(lam, dtype=float, copy=True)
    for k in range(len(ts)):
        cq = model.constraint_jacobian(qs[k], ts[k])
        cq = cq.toarray() if hasattr(cq, "toarray") else np.asarray(cq).reshape(model.nc, -1)
        _, sing, vt = np.linalg.svd(cq.T)
        rank = int(np.sum(sing > 1e-10 * max(sing[0] if sing.size else 0.0, 1e-300)))
        null = vt[rank:].T  # columns: C_qᵀ z = 0
        if null.shape[1] == 0:
            continue
        y = np.linalg.lstsq(null[rows], -out[k][rows], rcond=None)[0]
        out[k] = out[k] + null @ y
    return out


def _inside(value, h: float, screen=None) -> tuple[float | None, float]:
    """The largest τ = h 2⁻ᵏ (k = 1 … :data:`DYADIC`) with value(τ) > :data:`INSIDE`, and
    that value (None: none).

    ``screen(h)``, when given, returns the values at all :data:`DYADIC` trial times from one
    integrator call (dense output, :meth:`_Phase.advance_dyadic`); a trial time it finds
    inside is confirmed by ``value`` (the same integration from the start as without the
    screen, so the root finding that follows starts from the same bracket), and when the
    screen fails (an integrator failure) the trial times are tried one by one.  The screen
    saves about 11 of the 13 integrator calls a bounce shorter than the sub-interval took
    (the bouncing ball of e = 1 on a coarse grid: 22 → 10 calls per event)."""
    screened = None
    if screen is not None:
        try:
            screened = np.asarray(screen(h), float)
        except (RuntimeError, _StepError) as exc:
            reraise_interrupt(exc)
            screened = None
    if screened is not None:
        for k in np.flatnonzero(screened > INSIDE):
            tau = h * 0.5 ** (int(k) + 1)
            f = value(tau)
            if f > INSIDE:
                return tau, f
        return None, 0.0
    tau = h
    for _ in range(DYADIC):
        tau *= 0.5
        f = value(tau)
        if f > INSIDE:
            return tau, f
    return None, 0.0


def _illinois(f, lo: float, hi: float, f_lo: float, f_hi: float, tol: float) -> float:
    """A root of f in (lo, hi) with f(lo) > 0 > f(hi) (Illinois regula falsi)."""
    side = 0
    for _ in range(200):
        mid = hi - f_hi * (hi - lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
        if not lo < mid < hi:
            mid = 0.5 * (lo + hi)
        f_mid = f(mid)
        if f_mid <= 0.0:
            hi, f_hi = mid, f_mid
            if side == -1:
                f_lo *= 0.5
            side = -1
        else:
            lo, f_lo = mid, f_mid
            if side == 1:
                f_hi *= 0.5
            side = 1
        if hi - lo <= tol or f_mid == 0.0:
            break
    return hi


def simulate_events(mechanism, t_end: float, steps: int, *, simulator_factory,
                    integrator: str | None = None, rtol: float = 1e-8,
                    atol: float | None = None, t_start: float = 0.0,
                    substeps: int = SUBSTEPS, rest_velocity: float | None = None,
                    max_events: int = MAX_EVENTS, max_steps: int | None = None) -> Result:
    """Forward dynamics with impacts, contact and detach (module docstring).

    Parameters are those of :func:`casmbd.analysis.dynamics.simulate.simulate`
    (``simulator_factory(mechanism)`` builds its
    :class:`~casmbd.analysis.dynamics.simulate.Simulator`
    with the caller's formulation and options); ``substeps`` the
    sub-intervals of an output interval in which gaps are checked (an event shorter than one
    can be missed), ``rest_velocity`` the rebound speed below which a gap closes, and
    ``max_events`` a bound on the number of events.

    Raises
    ------
    IntegratorError
        When an integrator call inside the event loop fails (flag ``CV_…``/``IDA_…``, the
        time, the culprit when a model value is not finite there, advice) or the run exceeds
        ``max_events`` (flag ``MAX_EVENTS``); ``partial`` holds the results up to the last
        state reached: the output times passed and that state.
    """
    if not (isinstance(max_events, (int, np.integer)) and not isinstance(max_events, bool)
            and 1 <= max_events <= MAX_EVENTS_LIMIT):
        raise AnalysisError(f"max_events must be an integer in [1, {MAX_EVENTS_LIMIT}], got "
                            f"{max_events!r}")
    if rest_velocity is not None and not (isinstance(rest_velocity, (int, float, np.floating))
                                          and math.isfinite(rest_velocity)
                                          and rest_velocity >= 0.0):
        raise AnalysisError(f"rest_velocity must be a finite number >= 0 (m/s), got "
                            f"{rest_velocity!r}")
    record: dict = {}
    # SUNDIALS' own lines ("At t = …, mxstep steps taken") are part of the error, not stray
    # lines on the terminal: captured, and passed on (all of it after a good run, the
    # warnings after a failure)
    captured = sun.CapturedOutput()
    try:
        with captured:
            result = _march(mechanism, t_end, steps, simulator_factory=simulator_factory,
                            integrator=integrator, rtol=rtol, atol=atol, t_start=t_start,
                            substeps=substeps, rest_velocity=rest_velocity,
                            max_events=max_events, max_steps=max_steps, record=record)
    except (RuntimeError, IntegratorError) as exc:
        _pass_on(captured.text, warnings_only=True)
        reraise_interrupt(exc)
        if not record or (isinstance(exc, IntegratorError) and exc.partial is not None):
            raise
        raise _failure(exc, record, rtol) from None
    except BaseException:
        _pass_on(captured.text, warnings_only=True)
        raise
    _pass_on(captured.text, warnings_only=False)
    return result


def _pass_on(text: str, warnings_only: bool) -> None:
    """Write captured output to ``sys.stderr`` (only the warnings' lines after a failure)."""
    if warnings_only:  # Python's warnings ("…: RuntimeWarning: …", the CLI's "warning: …"),
        # not SUNDIALS' ("The above warning has been issued mxhnil times …")
        text = "".join(line for line in text.splitlines(keepends=True)
                       if _WARNING_LINE.search(line))
    if text:
        sys.stderr.write(text)


def _failure(exc: Exception, rec: dict, rtol: float) -> IntegratorError:
    """The IntegratorError of a run stopped inside the event loop, with the results up to the
    last state reached (the output times passed, then that state)."""
    t_now, x_now, closed_now, p_now = rec["now"]()
    samples, grid, base = list(rec["samples"]), rec["grid"], rec["base"]
    if isinstance(exc, _StepError) and exc.t_lo > t_now:
        t_now, x_now = exc.t_lo, exc.x_lo
    tol = 1e-12 * (1.0 + abs(t_now))
    if t_now > samples[-1][0] + tol and np.all(np.isfinite(x_now)):
        samples.append((t_now, np.array(x_now, float), closed_now, np.array(p_now, float)))
    nq = base.model.nq
    times = np.array([s_[0] for s_ in samples])
    events = [e for e in rec["events"] if e["time"] <= times[-1] + tol]
    partial = None
    try:
        partial = _assemble_result(
            base, rec["phase_of"], rec["gaps"], times,
            np.array([s_[1][:nq] for s_ in samples]), np.array([s_[1][nq:] for s_ in samples]),
            samples, events, time.perf_counter() - rec["clock"], rec["name"], rtol,
            rec["atol"], rec["default_p"])
        partial.stats["failure_time"] = float(times[-1])
    except (RuntimeError, CasmbdError, ValueError, FloatingPointError):
        partial = None  # the post-processing itself fails at the states: nothing to keep
    n_out = int(np.sum(times[:, None] == grid[None, :])) if len(times) else 0
    kept = (f"results kept up to t = {times[-1]:.6g} ({n_out} of {len(grid)} output times"
            + (f" and the state at t = {times[-1]:.6g})" if n_out < len(times) else ")"))
    if not partial:
        kept = "no results kept (the post-processing fails at the states reached)"
    if isinstance(exc, IntegratorError):  # the event bound (or a Zeno stop)
        return IntegratorError(f"{exc}; {kept}", exc.time, exc.flag, partial)
    match = _FLAG.search(str(exc))
    flag = match.group(1) if match else type(exc).__name__
    if isinstance(exc, _StepError):
        t_lo, t_hi = exc.t_lo, exc.t_hi
    else:
        t_lo = t_hi = t_now
    model = base.model
    culprits = diagnose_failure(model, t_hi) or diagnose_failure(model, t_lo)
    where = f"at t = {t_lo:.6g}" if t_hi <= t_lo else \
        f"between t = {t_lo:.6g} and t = {t_hi:.6g}"
    text = (f"integrator '{rec['name']}' ({base.formulation_name}, event-driven) failed {where} "
            f"with {flag}; {kept}")
    stiff = "" if culprits or not np.all(np.isfinite(x_now)) else diagnose_stiffness(
        model, t_now, x_now[:nq], x_now[nq:], t_start=float(samples[0][0]),
        q0=samples[0][1][:nq], v0=samples[0][1][nq:], rtol=rtol, t_end=float(grid[-1]))
    if culprits:
        text += "; " + "; ".join(culprits[:3])
    elif stiff:  # the element whose stiffness or time singularity stopped the run
        text += stiff + (f"; {_ADVICE[flag]}" if flag in _ADVICE else "")
    elif flag in _ADVICE:
        text += f"; {_ADVICE[flag]}"
    elif not match:
        lines = str(exc).strip().splitlines()
        text += f" ({lines[-1] if lines else flag})"
    text += base.kind.failure_hint(flag, rtol)
    return IntegratorError(text, t_lo, flag, partial)


def _march(mechanism, t_end: float, steps: int, *, simulator_factory, integrator, rtol, atol,
           t_start, substeps, rest_velocity, max_events, max_steps, record: dict) -> Result:
    """The event loop of :func:`simulate_events`; ``record`` receives what a failure inside
    the loop needs to keep the results so far (:func:`_failure`)."""
    t_clock = time.perf_counter()
    atol = rtol if atol is None else atol
    if not (isinstance(substeps, int) and substeps >= 1):
        raise AnalysisError(f"substeps must be an integer >= 1, got {substeps!r}")
    elements = [c for c in mechanism.contacts.values() if acts_at_events(c)]
    elements += [StickRow(f) for f in mechanism.forces.values()
                 if getattr(f, "stick_slip", False)]
    elements += [SlideRow(c) for c in mechanism.contacts.values() if slides(c)]
    base = simulator_factory(mechanism)
    base.kind.refuse_events()  # GGL's index-2 restart, numeric right-hand sides
    name = integrator or base.kind.event_integrator
    if not EVENT_NEEDS <= getattr(integ.INTEGRATORS.get(name), "handles", frozenset()):
        raise AnalysisError(f"integrator '{name}': the event-driven run uses a variable-step "
                            "SUNDIALS integrator (cvodes, adams, idas)")
    gaps = EventRows(System(mechanism), elements)
    n_gaps = len(gaps.rows)
    g_acc = math.hypot(*map(float, mechanism.gravity)) or 9.81  # no overflow of |g|²
    v_rest = rest_velocity if rest_velocity is not None else math.sqrt(2 * g_acc * REST_HEIGHT)
    # per gap: a contact's own rest velocity (its [[contacts]] key) wins over the run's
    v_rests = np.array([v_rest if getattr(gaps.rows[i][0], "rest_velocity", None) is None
                        else gaps.rows[i][0].rest_velocity for i in range(n_gaps)])
    phases: dict[frozenset, _Phase] = {}

    def phase_of(closed: frozenset) -> _Phase:
        if closed not in phases:
            if closed:
                variant = copy.copy(mechanism)
                # the phase's states are the base's: its coordinates, never a new automatic
                # choice (closures count as loop joints and could tip it to absolute)
                variant.coordinates = base.model.coordinates
                variant.joints = dict(mechanism.joints)
                variant.forces = dict(mechanism.forces)
                for i in sorted(closed):
                    joint = closure(mechanism, *gaps.rows[i])
                    variant.joints[joint.name] = joint
                for i in range(n_gaps):  # closed, sliding frictional contacts: −μ N σ
                    row = gaps.rows[i][0]
                    if isinstance(row, SlideRow) and row.gap_row in closed and \
                            i not in closed:
                        slide = ContactSlide(f"{row.name}.slide", row.contact,
                                             closure(mechanism, *gaps.rows[row.gap_row]).name)
                        variant.forces[slide.name] = slide
                sim = simulator_factory(variant)
                labels = [str(lab) for lab in sim.model.constraint_labels]
                rows = [labels.index(f"joint '{closure(mechanism, *gaps.rows[i]).name}' "
                                     "equation 'gap'") for i in sorted(closed)]
                pairs = {m: labels.index(f"joint '{closure(mechanism, *gaps.rows[i]).name}' "
                                         "equation 'gap_2'")
                         for m, i in enumerate(sorted(closed))
                         if len(closure(mechanism, *gaps.rows[i]).labels) == 2}
            else:
                sim, rows, pairs = base, [], {}
            phases[closed] = _Phase(sim, closed, rows, name, rtol, atol,
                                    max_steps or 500_000, pairs)
        return phases[closed]

    # the parameters of the phase (stick-slip: the sliding sign σ and the stuck position), set
    # on every phase's model before it is used
    p = np.array(base.model.p, dtype=float)
    default_p = p.copy()
    pnames = list(base.model.parameter_names)

    def use(phase_: _Phase) -> _Phase:
        phase_.sim.model.p[:] = p
        return phase_

    grid = np.linspace(t_start, t_end, int(steps) + 1)
    q0, v0 = base.model.initial_coordinates(), base.model.initial_velocities()
    u0 = base.inputs_at(t_start)
    # the pre-run checks of a smooth run: a NaN's culprit, the bodies without mass
    ode_acc = base._ode_accelerations(t_start)  # a model without compiled forces: its ODE
    check_start(base.model, q0, v0, t_start, u0, what="simulation",
                every=ode_acc is not None and not np.all(np.isfinite(ode_acc(q0, v0))))
    check_mass_matrix(base.model, assemble(base.model, q0, t_start).q, t_start)
    start = consistent_state(base.model, q0, v0, t_start, u0)
    nq = base.model.nq
    x = np.concatenate([start.q, start.v])
    g0, _, _ = gaps(start.q, start.v, t_start, p)
    if n_gaps and np.min(g0) < -1e-9:
        k = int(np.argmin(g0))
        what = "contact" if gaps.rows[k][0].event_kind == "impact" else "joint limit"
        bodies = [b for b in (getattr(gaps.rows[k][0], key, None)
                              for key in ("body", "body1", "body2")) if isinstance(b, str)]
        where = f" (body {', '.join(repr(b) for b in bodies)}: check its 'position' and the " \
            f"{what}'s points)" if bodies else ""
        raise AnalysisError(f"{what} '{gaps.label(k)}': the initial pose penetrates by "
                            f"{-g0[k]:.3g} (gap < 0 at t = {t_start:g}){where}; start it open "
                            "or touching")
    closed: frozenset = frozenset()
    events: list[dict] = []
    impact_times: dict[str, list[float]] = {}  # per gap, for the Zeno guard
    # the impact interval of a rebound at the default rest velocity under the gravity, 2 v / g:
    # accumulating impacts far below it are beyond what the event location resolves
    zeno_interval = ZENO_FRACTION * 2.0 * math.sqrt(2 * g_acc * REST_HEIGHT) / g_acc

    def settle(i, q_s, v_s, t_s, closed_s):
        """A sliding joint or contact at zero speed (or at the start, or a contact just
        closed): stuck if the friction that holds it stays within its level (F_c, or μ N),
        else sliding in the direction the other forces push."""
        row = gaps.rows[i][0]
        p[pnames.index(row.stuck_at)] = 0.0
        p[pnames.index(row.stuck_at)] = float(gaps.positions(q_s, v_s, t_s, p)[i])
        trial = closed_s | {i}
        stuck = use(phase_of(trial))
        v_p = project(stuck.sim.model, gaps, trial, q_s, v_s, t_s, p)
        p[pnames.index(row.sign)] = 0.0
        use(stuck)
        lams = dict(zip(sorted(trial), stuck.multipliers(q_s, v_p, t_s), strict=True))
        lam = float(lams[i])
        if gaps.closed_value(i, lams) >= 0.0:
            events.append({"time": float(t_s), "element": row.name, "kind": "stick"})
            return v_p, trial
        if slides_in_space(row):  # it slips along λ_t (the friction force −λ_t is too big)
            lam_t = stuck.tangent_multipliers(q_s, v_p, t_s, sorted(trial).index(i))
            start_slide(row, lam_t)
            events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
            return v_p, closed_s
        p[pnames.index(row.sign)] = float(np.sign(lam))
        events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
        return v_p, closed_s

    def stopped(i, q_s, v_s, t_s, closed_s) -> bool:
        """A sliding friction row (joint or closed contact) whose slip is zero at t_s: it
        stopped together with the one located (a box sliding on several contacts)."""
        row = gaps.rows[i][0]
        if not gaps.stick[i] or i in closed_s or not gaps.active(i, closed_s) or \
                p[pnames.index(row.sign)] == 0.0:
            return False
        if slides_in_space(row):
            return float(np.linalg.norm(gaps.slip_velocity(i, q_s, v_s, t_s, p))) <= 1e-8
        return abs(float(gaps(q_s, v_s, t_s, p)[0][i])) <= 1e-8

    def settle_group(group, q_s, v_s, t_s, closed_s):
        """Rows that stopped at one instant: all stuck together if each holding force stays
        within its level (a box on several contacts: the statically indeterminate holding
        forces are the minimum-norm ones); else one by one, the others released (σ = 0) until
        their turn."""
        if len(group) == 1:
            return settle(group[0], q_s, v_s, t_s, closed_s)
        group = sorted(group)  # row order, whichever was located first
        for i in group:
            row = gaps.rows[i][0]
            p[pnames.index(row.sign)] = 0.0
            p[pnames.index(row.stuck_at)] = 0.0
        positions = gaps.positions(q_s, v_s, t_s, p)
        for i in group:
            p[pnames.index(gaps.rows[i][0].stuck_at)] = float(positions[i])
        trial = closed_s | set(group)
        stuck = use(phase_of(trial))
        v_p = project(stuck.sim.model, gaps, trial, q_s, v_s, t_s, p)
        lams = dict(zip(sorted(trial), stuck.multipliers(q_s, v_p, t_s), strict=True))
        if all(gaps.closed_value(i, lams) >= 0.0 for i in group):
            events.extend({"time": float(t_s), "element": gaps.rows[i][0].name,
                           "kind": "stick"} for i in group)
            return v_p, trial
        for i in group:
            v_s, closed_s = settle(i, q_s, v_s, t_s, closed_s)
        return v_s, closed_s

    def slides_in_space(row) -> bool:
        return isinstance(row, SlideRow) and row.dimension == 3

    def start_slide(row, direction) -> None:
        """A contact in space slides (σ = 1) along the unit ``direction`` (tangent basis)."""
        p[pnames.index(row.sign)] = 1.0
        d = np.asarray(direction, float)
        d = d / max(float(np.linalg.norm(d)), 1e-300)
        for par, value in zip(row.direction, d, strict=True):
            p[pnames.index(par)] = float(value)

    def reanchor(q_s, v_s, t_s) -> None:
        """The stored direction ŝ of a sliding contact in space follows its slip (each window
        of sub-intervals; the friction's direction (v_t + δ ŝ)/|v_t + δ ŝ| is v_t/|v_t| to
        δ sin∠(ŝ, v_t)/|v_t|, and the row ŝ·v_t must not cross zero while it still slips) —
        once the slip is well above δ (a slide just started from rest keeps the ŝ of λ_t)."""
        for i in range(n_gaps):
            row = gaps.rows[i][0]
            if slides_in_space(row) and p[pnames.index(row.sign)] != 0.0:
                vt = gaps.slip_velocity(i, q_s, v_s, t_s, p)
                speed = float(np.linalg.norm(vt))
                stored = np.array([p[pnames.index(par)] for par in row.direction])
                if speed > 100.0 * SLIP_VELOCITY and \
                        float(np.linalg.norm(vt / speed - stored)) > 1e-9:
                    start_slide(row, vt)

    def held(i, q_s, t_s, closed_s) -> bool:
        """A friction row whose slip the closed rows already fix — a stick-slip joint on a
        closed stop of its joint, the tip of a pinned rod resting on a frictional floor: its
        slip direction lies in the row space of the phase's C_q.  Friction at rest there is
        statically indeterminate; the closures carry the load and σ = 0 (no friction force)
        until the set of closed rows changes."""
        if not closed_s:
            return False
        row = gaps.rows[i][0]
        _, gq, tv = gaps(q_s, np.zeros(nq), t_s, p)
        if slides_in_space(row):
            idx, ts = gaps.tangent_of[row.gap_row], gaps.tangent_size
            dirs = tv[idx * ts:(idx + 1) * ts]
        else:
            dirs = gq[i:i + 1]
        cq = use(phase_of(closed_s)).sim.model.constraint_jacobian(q_s, t_s)
        cq = cq.toarray() if hasattr(cq, "toarray") else np.asarray(cq).reshape(-1, nq)
        for d in dirs:
            x_d = np.linalg.lstsq(cq.T, d, rcond=None)[0]
            if np.linalg.norm(cq.T @ x_d - d) > 1e-8 * max(np.linalg.norm(d), 1e-300):
                return False
        return True

    def engage(q_s, v_s, t_s, closed_s):
        """After an event.  Slide rows of frictional contacts that just closed: stick or
        slide; of contacts that opened: released (σ = 0).  Sliding stick-slip joints whose
        velocity an impact reversed: σ follows (``slip``).  Friction rows whose slip the
        closed rows fix (:func:`held`: a joint on its closed stop, a pinned rod's tip on the
        floor): σ = 0; released: stick or slide."""
        for i in range(n_gaps):
            row = gaps.rows[i][0]
            if isinstance(row, StickRow) and i not in closed_s:
                k_sign = pnames.index(row.sign)
                if held(i, q_s, t_s, closed_s):
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
                        v_s, closed_s = settle(i, q_s, v_s, t_s, closed_s)
                elif sigma * rate < -1e-12:  # an impact reversed the sliding direction
                    p[k_sign] = -sigma
                    events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
                continue
            if not isinstance(row, SlideRow):
                continue
            if row.gap_row not in closed_s:
                closed_s = closed_s - {i}
                p[pnames.index(row.sign)] = 0.0
            elif i not in closed_s and held(i, q_s, t_s, closed_s):
                p[pnames.index(row.sign)] = 0.0
            elif i not in closed_s and p[pnames.index(row.sign)] != 0.0:
                # sliding: an impact elsewhere may have reversed (turned) the slip — the force
                # follows it (``slip``), never the stuck trial of a stop
                if slides_in_space(row):
                    vt = gaps.slip_velocity(i, q_s, v_s, t_s, p)
                    stored = np.array([p[pnames.index(par)] for par in row.direction])
                    if float(np.linalg.norm(vt)) > 1e-12 and float(stored @ vt) <= 0.0:
                        start_slide(row, vt)
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
                    start_slide(row, vt)
                    events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
                else:
                    v_s, closed_s = settle(i, q_s, v_s, t_s, closed_s)
            elif i not in closed_s and p[pnames.index(row.sign)] == 0.0:
                p[pnames.index(row.sign)] = 1.0
                rate = float(gaps(q_s, v_s, t_s, p)[0][i])
                if abs(rate) > 1e-12:
                    p[pnames.index(row.sign)] = float(np.sign(rate))
                    events.append({"time": float(t_s), "element": row.name, "kind": "slip"})
                else:
                    v_s, closed_s = settle(i, q_s, v_s, t_s, closed_s)
        return v_s, closed_s

    for i in [i for i in range(n_gaps) if gaps.stick[i] and
              not isinstance(gaps.rows[i][0], SlideRow)]:  # the start of stick-slip joints
        row = gaps.rows[i][0]
        p[pnames.index(row.sign)] = 1.0
        rate = float(gaps(x[:nq], x[nq:], t_start, p)[0][i])
        if abs(rate) > 1e-12:
            p[pnames.index(row.sign)] = float(np.sign(rate))
        else:
            v_s, closed = settle(i, x[:nq], x[nq:], t_start, closed)
            x = np.concatenate([x[:nq], v_s])
    phase = use(phase_of(closed))
    z = phase.z0(x[:nq], x[nq:], t_start)
    samples = [(t_start, x.copy(), closed, p.copy())]
    t = t_start
    record.update(base=base, phase_of=phase_of, gaps=gaps, grid=grid, samples=samples,
                  events=events, name=name, atol=atol, default_p=default_p, clock=t_clock,
                  now=lambda: (t, x, closed, p.copy()))
    tol_t = 1e-13

    # every sub-interval end of the run; states come in windows of WINDOW of them from one
    # integrator call, restarted only after an event
    sub_all = np.concatenate([np.linspace(grid[k], grid[k + 1], substeps + 1)[1:]
                              for k in range(len(grid) - 1)])
    window: dict[float, tuple] = {}
    for k_out in range(len(grid) - 1):
        sub = np.linspace(grid[k_out], grid[k_out + 1], substeps + 1)
        j = 0
        while j < substeps:
            t_b = sub[j + 1]
            h = t_b - t
            if h <= tol_t * (1 + abs(t)):
                j += 1
                continue
            if t_b not in window:
                reanchor(x[:nq], x[nq:], t)
                first = int(np.searchsorted(sub_all, t_b - 0.5 * tol_t * (1 + abs(t_b))))
                times = sub_all[first:first + WINDOW]
                xs_w, zs_w = phase.advance_many(x, z, t, times)
                times = times[:len(xs_w)]  # up to a failure (advance_many)
                g_w = gaps.values_many(xs_w[:, :nq], xs_w[:, nq:], times, p)
                lam_w = phase.multipliers_many(xs_w[:, :nq], xs_w[:, nq:], times)
                window = {float(tk): (xs_w[m], zs_w[m], g_w[m], lam_w[m])
                          for m, tk in enumerate(times)}
            x_b, z_b, g_b, lam_b = window[float(t_b)]
            open_hit = [i for i in range(n_gaps) if i not in closed and
                        gaps.active(i, closed) and g_b[i] < -1e-13]
            order = sorted(closed)
            lams_b = dict(zip(order, lam_b, strict=True))
            # contact force along +∇g is −λ (Q_c = −C_qᵀ λ): detach when −λ < 0; a stuck
            # joint slips when |λ| > F_c, a stuck contact when |λ| > μ N
            pulls = [i for i in order if gaps.closed_value(i, lams_b) < 0.0]
            if not open_hit and not pulls:
                x, z, t = x_b, z_b, t_b
                j += 1
                continue
            # locate the first event in (t, t_b]
            x_a, z_a, t_a = x, z, t
            best = (t_b, None, None)
            pressed: set[int] = set()
            released: set[int] = set()
            for i in open_hit + pulls:
                is_detach = i in closed

                def value(tau, i=i, is_detach=is_detach, phase=phase, x_a=x_a, z_a=z_a,
                          t_a=t_a, order=order):
                    xt, _ = phase.advance(x_a, z_a, t_a, tau)
                    if is_detach:
                        lam = phase.multipliers(xt[:nq], xt[nq:], t_a + tau)
                        return gaps.closed_value(i, dict(zip(order, lam, strict=True)))
                    return float(gaps.values(xt[:nq], xt[nq:], t_a + tau, p)[i])

                def screen(h_, i=i, is_detach=is_detach, phase=phase, x_a=x_a, z_a=z_a,
                           t_a=t_a, order=order):
                    xs_d, _ = phase.advance_dyadic(x_a, z_a, t_a, h_)
                    ts_d = t_a + h_ * 0.5 ** np.arange(1, DYADIC + 1)
                    if is_detach:
                        lam = phase.multipliers_many(xs_d[:, :nq], xs_d[:, nq:], ts_d)
                        return [gaps.closed_value(i, dict(zip(order, row, strict=True)))
                                for row in lam]
                    return gaps.values_many(xs_d[:, :nq], xs_d[:, nq:], ts_d, p)[:, i]

                if is_detach:
                    lam_a = phase.multipliers(x_a[:nq], x_a[nq:], t_a)
                    f_lo = max(gaps.closed_value(i, dict(zip(order, lam_a, strict=True))),
                               1e-300)
                else:
                    f_lo = float(gaps.values(x_a[:nq], x_a[nq:], t_a, p)[i])
                f_hi = gaps.closed_value(i, lams_b) if is_detach \
                    else float(g_b[i])
                lo, hi = 0.0, h
                if f_lo <= 1e-12 * (1.0 + abs(f_hi)):
                    # the sub-interval starts at the event surface (just after an impact or a
                    # detach): the motion leaves it and may come back within the interval (a
                    # bounce shorter than the interval) — find an inside time where it is open
                    lo, f_lo = _inside(value, h, screen)
                    if lo is None:
                        if is_detach and not gaps.stick[i]:
                            # a closed gap whose normal force falls through zero at t_a (a
                            # box lifted evenly off two contacts: the second one, after the
                            # first detached): it opens at t_a, with every other such gap
                            released.add(i)
                            if t_a < best[0]:
                                best = (t_a, i, True)
                        if not is_detach:
                            # an open gap pressed in from t_a on (a body put down touching
                            # at the start): it closes at t_a (impact if it approaches), with
                            # every other gap pressed in at t_a (a box put down on 4 corners)
                            pressed.add(i)
                            if t_a < best[0]:
                                best = (t_a, i, False)
                        continue  # a closed gap stays at its surface: no new event
                    hi, f_hi = 2.0 * lo, value(2.0 * lo) if 2.0 * lo < h else f_hi
                    hi = min(hi, h)
                tau = _illinois(value, lo, hi, f_lo, f_hi, tol_t * (1 + abs(t_b)))
                if t_a + tau < best[0]:
                    best = (t_a + tau, i, is_detach)
            t_ev, i_ev, is_detach = best
            if i_ev is None:
                x, z, t = x_b, z_b, t_b
                j += 1
                continue
            x_ev, _ = phase.advance(x_a, z_a, t_a, t_ev - t_a) if t_ev > t_a else (x_a, z_a)
            q_ev, v_ev = x_ev[:nq], x_ev[nq:]
            element = gaps.rows[i_ev][0]
            if is_detach and gaps.stick[i_ev]:  # the holding force reached F_c: it slips
                lam_ev = float(phase.multipliers(q_ev, v_ev, t_ev)[order.index(i_ev)])
                v_new = v_ev
                if slides_in_space(element):  # along λ_t, from v_t = 0 exactly (the index-1
                    # drift of the stuck phase, ~1e-9 m/s, would set a direction of its own)
                    start_slide(element, phase.tangent_multipliers(q_ev, v_ev, t_ev,
                                                                   order.index(i_ev)))
                    v_new = project(phase.sim.model, gaps, closed, q_ev, v_ev, t_ev, p)
                else:
                    p[pnames.index(element.sign)] = float(np.sign(lam_ev))
                closed = closed - {i_ev}
                events.append({"time": float(t_ev), "element": element.name, "kind": "slip"})
            elif slides_in_space(element) and float(np.linalg.norm(gaps.slip_velocity(
                    i_ev, q_ev, v_ev, t_ev, p))) > 1e-7:
                # ŝ·v_t crossed zero but the contact still slips (its slip turned): follow it
                start_slide(element, gaps.slip_velocity(i_ev, q_ev, v_ev, t_ev, p))
                v_new = v_ev
            elif gaps.stick[i_ev]:  # a sliding joint stopped: stick, or slide back
                v_new, closed = settle_group(
                    [i_ev] + [k for k in range(n_gaps) if k != i_ev and
                              stopped(k, q_ev, v_ev, t_ev, closed)],
                    q_ev, v_ev, t_ev, closed)
            elif is_detach:
                opened = sorted(released) if i_ev in released else [i_ev]
                closed = closed - set(opened)
                events += [{"time": float(t_ev), "element": gaps.label(i), "kind": "detach"}
                           for i in opened]
                v_new = v_ev
            else:
                hit = impact(phase_of(closed).sim.model, gaps, closed, i_ev, q_ev, v_ev, t_ev,
                              p, v_rests)
                if hit is None and i_ev in pressed:  # resting: closes with no impulse
                    v_new = project(phase_of(closed).sim.model, gaps, closed | pressed,
                                     q_ev, v_ev, t_ev, p)
                    closed = closed | pressed
                    events += [{"time": float(t_ev), "element": gaps.label(i),
                                "kind": "contact"} for i in sorted(pressed)]
                elif hit is None:  # grazing: the gap touches zero without closing in on it
                    v_new = v_ev
                else:
                    v_new, closed, struck = hit  # the gaps struck (i_ev among them), …
                    events += [{"time": float(t_ev), "element": lab, "kind": kind}
                               for lab, kind in struck]
                    for lab, kind in struck:
                        if kind == "impact":
                            zeno = zeno_guard(impact_times.setdefault(lab, []), t_ev,
                                              zeno_interval)
                            if zeno:
                                raise IntegratorError(
                                    f"Zeno behaviour: the impacts of '{lab}' accumulate at t ≈ "
                                    f"{zeno[0]:.9g} ({zeno[1]}); stopped at the impact at t = "
                                    f"{t_ev:.9g} after {len(events)} events. A rest velocity "
                                    f"closes the contact before (now {v_rest:.3g} m/s: "
                                    "--rest-velocity, or rest_velocity in the scene's "
                                    "[simulation])", t_ev, "ZENO", None)
                            over = periodic_overrun(impact_times[lab], t_end,
                                                    max_events - len(events)) \
                                if len(events) >= PROJECT_AFTER else None
                            if over:
                                raise IntegratorError(
                                    f"more than {max_events} events by t_end = {t_end:g}: "
                                    f"the impacts of '{lab}' repeat every {over[0]:.6g} s "
                                    f"(the last {ZENO_IMPACTS + 1} intervals equal to within "
                                    f"{PERIODIC_SPREAD:g}), {over[1]} more to come; stopped "
                                    f"at the impact at t = {t_ev:.6g} after {len(events)} "
                                    f"events (raise max_events, or the rest velocity "
                                    f"{v_rest:.3g} m/s: [simulation] max_events / "
                                    "rest_velocity in the scene, --max-events / "
                                    "--rest-velocity)", t_ev, "MAX_EVENTS", None)
            if len(events) > max_events:
                raise IntegratorError(
                    f"more than {max_events} events by t = {t_ev:.6g} (raise max_events, or "
                    f"the rest velocity {v_rest:.3g} m/s: [simulation] max_events / "
                    "rest_velocity in the scene, --max-events / --rest-velocity)", t_ev,
                    "MAX_EVENTS", None)
            v_new, closed = engage(q_ev, v_new, t_ev, closed)
            phase = use(phase_of(closed))
            x = np.concatenate([q_ev, v_new])
            z = phase.z0(q_ev, v_new, t_ev)
            t = t_ev
            window = {}
            if abs(t_ev - samples[-1][0]) <= tol_t * (1 + abs(t_ev)):  # at an output time:
                samples[-1] = (samples[-1][0], x.copy(), closed, p.copy())  # the state after
        samples.append((t, x.copy(), closed, p.copy()))
    qs = np.array([s[1][:nq] for s in samples])
    vs = np.array([s[1][nq:] for s in samples])
    result = _assemble_result(base, phase_of, gaps, grid, qs, vs, samples, events,
                              time.perf_counter() - t_clock, name, rtol, atol, default_p)
    result.stats["steps"] = sum(ph.steps for ph in phases.values())
    result.stats["rhs_evaluations"] = sum(ph.rhs_evaluations for ph in phases.values())
    result.stats["phases"] = len(phases)
    return result


def _assemble_result(base, phase_of, gaps, grid, qs, vs, samples, events, seconds, name,
                     rtol, atol, default) -> Result:
    """Post-process the samples of each phase (closed rows and parameters) with the simulator
    of that phase; arrays of the base model's shape (the closed rows' multipliers go to
    ``contact_forces``: normal forces of contacts and stops, friction forces of stick-slip
    joints — −F_c σ while they slide)."""
    base.model.p[:] = default
    result = base.post.outputs(grid, qs, vs, {})
    n_gaps = len(gaps.rows)
    forces = np.zeros((len(grid), n_gaps))
    base_labels = [str(lab) for lab in base.model.constraint_labels]
    groups: dict[tuple, list[int]] = {}
    pnames = list(base.model.parameter_names)
    for k, (_, _, closed, pk) in enumerate(samples):
        for i in range(n_gaps):  # sliding stick-slip joints: −F_c σ (contacts: below)
            row = gaps.rows[i][0]
            if gaps.stick[i] and i not in closed and not isinstance(row, SlideRow):
                forces[k, i] = -row.level * pk[pnames.index(row.sign)]
        if closed or not np.array_equal(pk, default):
            groups.setdefault((closed, tuple(pk)), []).append(k)
    for (closed, pk), idx in groups.items():
        phase = phase_of(closed)
        phase.sim.model.p[:] = pk
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RuntimeWarning)
            sub = phase.sim.post.outputs(grid[idx], qs[idx], vs[idx], {})
        for w in caught:  # the closures' own reactions (undetermined when redundant) are not
            # reported: only a warning naming a joint of the mechanism is passed on
            if any(f"'{j}'" in str(w.message) for j in base.model.mechanism.joints):
                warnings.warn(str(w.message), RuntimeWarning, stacklevel=3)
        for key, arr in result.arrays.items():
            other = sub.arrays.get(key)
            if other is None or key in ("lambda", "joint_reactions"):
                continue
            if other.shape[1:] == arr.shape[1:]:
                arr[idx] = other
        labels = [str(lab) for lab in phase.sim.model.constraint_labels]
        lam = sub.arrays["lambda"]
        if phase.redundant:
            lam = _minimum_norm(phase.sim.model, qs[idx], grid[idx], lam, phase.all_rows)
        result.arrays["lambda"][idx] = lam[:, [labels.index(lab) for lab in base_labels]]
        reac = sub.arrays.get("joint_reactions")
        if reac is not None and "joint_reactions" in result.arrays:
            width = result.arrays["joint_reactions"].shape[1]
            result.arrays["joint_reactions"][idx] = reac[:, :width]
        for m, i in enumerate(sorted(closed)):
            forces[idx, i] = -lam[:, phase.closure_rows[m]] if m not in phase.pairs else \
                np.hypot(lam[:, phase.closure_rows[m]], lam[:, phase.pairs[m]])
    for k, (_, _, closed, pk) in enumerate(samples):  # sliding contacts: −μ N σ
        for i in range(n_gaps):
            row = gaps.rows[i][0]
            if isinstance(row, SlideRow) and i not in closed and row.gap_row in closed:
                sigma = pk[pnames.index(row.sign)]
                forces[k, i] = row.mu * forces[k, row.gap_row] * (
                    abs(sigma) if row.dimension == 3 else -sigma)  # space: |F_t|
    result.arrays["contact_forces"] = forces
    result.names["contacts"] = [gaps.label(i) for i in range(n_gaps)]
    # one entry per (instant, element, kind): an impact's stick and the closed contact's
    # stick at the same instant are one event
    result.events = [dict(zip(("time", "element", "kind"), key, strict=True)) for key in
                     dict.fromkeys((e["time"], e["element"], e["kind"]) for e in events)]
    # what the CLI summary and a smooth run's stats carry (formulation, build time, mode)
    result.stats.update({k: v for k, v in base.model.report_dict.items()
                         if k != "build_seconds"})
    result.stats.update({"coordinates": base.model.coordinates,
                         "formulation": base.formulation_name,
                         "build_seconds": base.build_seconds})
    result.stats.update({"integrator": name, "rtol": rtol, "atol": atol,
                         "events": len(events), "solve_seconds": seconds,
                         "event_driven": True})
    return result
