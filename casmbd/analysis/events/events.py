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

The room, one job a module: :mod:`~casmbd.analysis.events.phases` (step 1: a phase's
simulator and integrators), :mod:`~casmbd.analysis.events.event_rows` (the gap, friction and
stop rows), :mod:`~casmbd.analysis.events.roots` (step 2: locating an event),
:mod:`~casmbd.analysis.events.impulses` (step 3: the impact law),
:mod:`~casmbd.analysis.events.friction` (stick and slip),
:mod:`~casmbd.analysis.events.guards` (step 4's Zeno guard and the event-bound projection),
:mod:`~casmbd.analysis.events.march` (the loop over the grid, event by event); this module
is the entry, the result's assembly and the report of a failure.
"""

from __future__ import annotations

import math
import re
import sys
import time
import warnings

import numpy as np

from casmbd.analysis.events.event_rows import SlideRow
from casmbd.analysis.events.march import March
from casmbd.analysis.events.phases import FLAG, StepError, minimum_norm
from casmbd.analysis.instant.checks import diagnose_failure
from casmbd.analysis.integrators import sundials as sun
from casmbd.analysis.integrators.stiffness_culprit import diagnose_stiffness
from casmbd.errors import AnalysisError, CasmbdError, IntegratorError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.contact_models import CONTACT_MODELS
from casmbd.model.needs import EVENT_NEEDS, requirements
from casmbd.results import Result

__all__ = ["MAX_EVENTS", "MAX_EVENTS_LIMIT", "SIMULATION_KEYS", "SUBSTEPS", "compliant_events",
           "has_events", "simulate_events"]

#: default sub-intervals per output interval in which gaps are checked
SUBSTEPS = 4
#: default bound on the number of events of one run
MAX_EVENTS = 10_000
#: the largest ``max_events`` accepted (scene, CLI, API)
MAX_EVENTS_LIMIT = 10_000_000
#: keys of a scene's ``[simulation]`` table (options of the event-driven run)
SIMULATION_KEYS = ("max_events", "rest_velocity")
#: a line of a Python warning, as printed by ``warnings`` or the CLI
_WARNING_LINE = re.compile(r"^warning: |\b[A-Z]\w*Warning: ")
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
    if isinstance(exc, StepError) and exc.t_lo > t_now:
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
    match = FLAG.search(str(exc))
    flag = match.group(1) if match else type(exc).__name__
    if isinstance(exc, StepError):
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
    """The event loop of :func:`simulate_events` (:class:`~casmbd.analysis.events.march.March`)
    and its result; ``record`` receives what a failure inside the loop needs to keep the
    results so far (:func:`_failure`)."""
    march = March(mechanism, t_end, steps, simulator_factory=simulator_factory,
                  integrator=integrator, rtol=rtol, atol=atol, t_start=t_start,
                  substeps=substeps, rest_velocity=rest_velocity, max_events=max_events,
                  max_steps=max_steps)
    samples = march.run(record)
    nq = march.nq
    qs = np.array([s[1][:nq] for s in samples])
    vs = np.array([s[1][nq:] for s in samples])
    result = _assemble_result(march.base, march.phases, march.gaps, march.grid, qs, vs, samples,
                              march.events, time.perf_counter() - march.clock, march.name, rtol,
                              march.atol, march.default_p)
    built = march.phases.built
    result.stats["steps"] = sum(ph.steps for ph in built.values())
    result.stats["rhs_evaluations"] = sum(ph.rhs_evaluations for ph in built.values())
    result.stats["phases"] = len(built)
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
            lam = minimum_norm(phase.sim.model, qs[idx], grid[idx], lam, phase.all_rows)
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
