"""The phases of an event-driven run: one Simulator per set of closed gaps, and its integrators.

A phase is the mechanism with its closed gaps as bilateral constraints (a
:class:`~casmbd.model.contacts.GapClosure` joint each), one compiled
:class:`~casmbd.analysis.dynamics.simulate.Simulator` built once per set (:class:`PhaseSet`),
integrated on the time-scaled dynamics h f(t0 + h s, x), s ∈ [0, 1] (one compiled SUNDIALS
integrator serves every step length).  A phase also gives the multipliers of its closure rows
(the closed gaps' normal and friction forces), the least-norm ones when the closures are
redundant (:func:`minimum_norm`).
"""

from __future__ import annotations

import copy
import math
import re

import casadi as ca
import numpy as np

from casmbd.analysis.events.event_rows import SlideRow, closure
from casmbd.analysis.instant.kkt import accelerations_and_multipliers
from casmbd.analysis.instant.reaction_friction import has_reaction_friction
from casmbd.analysis.integrators import sundials as sun
from casmbd.compiled.buffered import BufferedFunction
from casmbd.interrupts import reraise_interrupt
from casmbd.model.contacts import ContactSlide

__all__ = ["DYADIC", "Phase", "PhaseSet", "StepError", "minimum_norm", "with_parameters"]

#: trial times h 2⁻ᵏ (k = 1 … DYADIC) of :func:`~casmbd.analysis.events.roots.inside`,
#: screened in one integrator call
DYADIC = 60
#: the SUNDIALS flag in a CasADi error message
FLAG = re.compile(r'returned "([A-Z_]+)"')


class StepError(RuntimeError):
    """An integrator call of the event loop failed between ``t_lo`` (state ``x_lo``, the
    last one reached) and ``t_hi``."""

    def __init__(self, message: str, t_lo: float, t_hi: float, x_lo: np.ndarray):
        super().__init__(message)
        self.t_lo, self.t_hi, self.x_lo = float(t_lo), float(t_hi), np.array(x_lo, float)



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
    """Raise :class:`StepError` when a SUNDIALS call returned without reaching the end of
    its interval (scaled time ``end``: 1, ½ for :meth:`Phase.advance_dyadic`): with a step
    size of zero (values near the floating-point limit, e.g. gravity 1e308) CVODES warns
    "t + h = t on the next step" and returns the start state unchanged instead of failing."""
    reached = stats.get("tcur", 1.0)
    if isinstance(reached, float) and math.isfinite(reached) and reached < end * (1.0 - 1e-9):
        raise StepError(f'the integrator returned "NO_PROGRESS": step size '
                         f'{stats.get("hcur", 0.0):.3g} at t = {t0 + reached * h:.6g}',
                         t0, t0 + h, x)


def _solve(solver, x, z, p) -> tuple[np.ndarray, np.ndarray]:
    """(xf, zf) of one integrator call, as arrays (columns: output times): a CasADi
    integrator as a :class:`~casmbd.compiled.buffered.BufferedFunction`, a CasADi integrator
    (called with a dict: its keyword call costs ~80 µs more), or a
    :class:`~casmbd.analysis.integrators.sundials.ConsistentStart` called by keywords."""
    if isinstance(solver, BufferedFunction):
        out = solver.all(x0=x, z0=z, p=p)
        return out[0], out[1]
    if isinstance(solver, ca.Function):
        r = solver.call({"x0": x, "z0": z, "p": p})
        return r["xf"].full(), r["zf"].full()
    r = solver(x0=x, z0=z, p=p)
    return np.asarray(r["xf"], float), np.asarray(r["zf"], float)


class Phase:
    """A Simulator of the mechanism with a set of closed gaps, and its step integrators."""

    def __init__(self, sim, closed: frozenset, closure_rows: list[int], name, rtol, atol,
                 max_steps, pairs: dict[int, int] | None = None):
        self.sim, self.closed, self.closure_rows = sim, closed, closure_rows
        #: closed rows (by position in ``closure_rows``) whose closure has a second row (a
        #: contact stuck in space, two tangential rows): their value is |λ_t|
        self.pairs = pairs or {}
        #: the phase integrates an independent subset of its rows (redundant closures):
        #: multipliers are taken with the minimum norm (:func:`minimum_norm`)
        self.redundant = getattr(sim, "redundancy", {}).get("kept_rows") is not None
        #: every row of the closures (a pair's second rows included)
        self.all_rows = list(closure_rows) + list(self.pairs.values())
        self._scaled = _scaled(sim.dyn)
        self.name, self.rtol, self.atol, self.max_steps = name, rtol, atol, max_steps
        self._many: dict[tuple, object] = {}
        self._mapped: bool | None = None  # the post-processing serves λ (no N-friction)
        self._post_maps: dict[int, ca.Function] = {}
        self.integrator = BufferedFunction.of(sun.sundials(self._scaled, name, 0.0, [1.0], rtol,
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
            solver = self._many[rel] = BufferedFunction.of(solver)
        try:
            xf, zf = _solve(solver, x, z, np.concatenate([self.sim.model.p, [t0, span]]))
        except RuntimeError as exc:
            reraise_interrupt(exc)
            # the states before the failure, sub-interval by sub-interval: the event loop
            # checks them as usual, and its next call from the last one raises StepError
            # naming the failing sub-interval
            kept_x, kept_z, t_prev = [], [], t0
            try:
                for tk in times:
                    x, z = self.advance(x, z, t_prev, float(tk) - t_prev)
                    kept_x.append(x)
                    kept_z.append(z)
                    t_prev = float(tk)
            except StepError as sub:
                if not kept_x:  # the first sub-interval fails: the window's flag, its times
                    message = str(exc) if FLAG.search(str(exc)) else str(sub)
                    raise StepError(message, sub.t_lo, sub.t_hi, sub.x_lo) from None
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
            raise StepError(str(exc), t0, t0 + h, x) from None
        st = self.integrator.stats()
        _progress(st, t0, h, x)
        self.steps += int(st.get("nsteps", 0))
        self.rhs_evaluations += int(st.get("nfevals", 0))
        return xf.ravel(), zf.ravel()

    def advance_dyadic(self, x, z, t0: float, h: float):
        """States at t0 + h 2⁻ᵏ, k = 1 … :data:`DYADIC` (rows, k ascending) from (x, z) at t0
        in one integrator call (one integrator per phase, built once): the trial times of
        :func:`~casmbd.analysis.events.roots.inside`, screened at once instead of one
        integrator call each."""
        if self._dyadic is None:
            self._dyadic = BufferedFunction.of(sun.sundials(
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
            lam = minimum_norm(model, qs, ts, lam, self.all_rows)
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
            lam = minimum_norm(self.sim.model, q[None, :], np.array([t]), lam[None, :],
                                self.all_rows)[0]
        return lam

    def multipliers(self, q, v, t):
        """λ of the closure rows (the closed gaps' constraint multipliers)."""
        return self._closed(self._all(q, v, t)) if self.closure_rows else np.zeros(0)

    def z0(self, q, v, t):
        return self.sim.algebraic_state_at(q, v, t)



def minimum_norm(model, qs: np.ndarray, ts: np.ndarray, lam: np.ndarray,
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


def with_parameters(phase: Phase, p: np.ndarray) -> Phase:
    """``phase`` with the run's parameters ``p`` set on its model (stick-slip: the sliding
    signs σ and the stuck positions), before it is used."""
    phase.sim.model.p[:] = p
    return phase


class PhaseSet:
    """The phases of one run, by set of closed gaps, each built on first use (called with
    the set): a variant of the mechanism with a closure joint per closed gap and a sliding
    friction force per closed, sliding frictional contact, simulated by
    ``simulator_factory`` with the base's coordinates."""

    def __init__(self, mechanism, base, gaps, simulator_factory, name: str, rtol: float,
                 atol: float, max_steps: int | None):
        self.mechanism, self.base, self.gaps = mechanism, base, gaps
        self.simulator_factory = simulator_factory
        self.name, self.rtol, self.atol, self.max_steps = name, rtol, atol, max_steps
        #: the phases built so far, by set of closed gaps
        self.built: dict[frozenset, Phase] = {}

    def __call__(self, closed: frozenset) -> Phase:
        if closed not in self.built:
            if closed:
                sim, rows, pairs = self._variant(closed)
            else:
                sim, rows, pairs = self.base, [], {}
            self.built[closed] = Phase(sim, closed, rows, self.name, self.rtol, self.atol,
                                       self.max_steps or 500_000, pairs)
        return self.built[closed]

    def _variant(self, closed: frozenset):
        """The Simulator of the mechanism with the gaps ``closed`` closed, the positions of
        their 'gap' rows among its constraint rows, and of the second rows of the pairs."""
        mechanism, gaps = self.mechanism, self.gaps
        variant = copy.copy(mechanism)
        # the phase's states are the base's: its coordinates, never a new automatic
        # choice (closures count as loop joints and could tip it to absolute)
        variant.coordinates = self.base.model.coordinates
        variant.joints = dict(mechanism.joints)
        variant.forces = dict(mechanism.forces)
        for i in sorted(closed):
            joint = closure(mechanism, *gaps.rows[i])
            variant.joints[joint.name] = joint
        for i in range(len(gaps.rows)):  # closed, sliding frictional contacts: −μ N σ
            row = gaps.rows[i][0]
            if isinstance(row, SlideRow) and row.gap_row in closed and \
                    i not in closed:
                slide = ContactSlide(f"{row.name}.slide", row.contact,
                                     closure(mechanism, *gaps.rows[row.gap_row]).name)
                variant.forces[slide.name] = slide
        sim = self.simulator_factory(variant)
        labels = [str(lab) for lab in sim.model.constraint_labels]
        rows = [labels.index(f"joint '{closure(mechanism, *gaps.rows[i]).name}' "
                             "equation 'gap'") for i in sorted(closed)]
        pairs = {m: labels.index(f"joint '{closure(mechanism, *gaps.rows[i]).name}' "
                                 "equation 'gap_2'")
                 for m, i in enumerate(sorted(closed))
                 if len(closure(mechanism, *gaps.rows[i]).labels) == 2}
        return sim, rows, pairs
