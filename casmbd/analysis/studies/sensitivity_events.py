"""Forward sensitivities across impacts: the jump of the sensitivity at an event.

Between events the state x = (q, v) of the event-driven run (:mod:`casmbd.analysis.events.events`)
follows the index-1 DAE of :mod:`casmbd.analysis.studies.sensitivity`; its sensitivity S = ∂x/∂p is
propagated phase by phase by IDAS (the phase's flow map and its Jacobians with respect to the
start state and to p).  At an impact of gap g_i at t_e the state jumps, x⁺ = Δ(x⁻, t_e, p)
(Newton's restitution law with the bilateral constraints, :mod:`casmbd.analysis.events.impulses`):

    [M   −C_qᵀ −G_iᵀ] [v⁺]   [ M v⁻      ]
    [C_q  0     0   ] [μ ] = [ −C_t      ]        q⁺ = q⁻,
    [G_i  0     0   ] [P ]   [ −e G_i v⁻ ]

and the event time moves with p: from g_i(x(t_e(p), p), p) = 0,

    τ = dt_e/dp = −(g_x S⁻ + g_p) / (g_x f⁻ + g_t).

The sensitivity just after the event (the saltation matrix of hybrid systems; Aizerman &
Gantmacher, 1958; Hiskens & Pai, "Trajectory sensitivity analysis of hybrid systems", IEEE
TCAS-I 47 (2000), eq. 13) is

    S⁺ = Δ_x (S⁻ + f⁻ τ) + Δ_t τ + Δ_p − f⁺ τ,

with f⁻, f⁺ the right-hand sides before and after, Δ_p including the derivative with respect to
a restitution coefficient or a stop given by a parameter.  An integral output gains
(h⁻ − h⁺) τ at each event (the moving limits of its phases).

Closed gaps: a *plastic* impact (e = 0) closes its gap — the same jump, then a phase whose
DAE has the gap as a constraint (the closure joint of the event-driven run); a gap closed at
the start (a body put down touching) changes nothing at the fixed start time; at a *detach*
the multiplier is zero, so q̈ and with it S are continuous (f⁻ = f⁺: no jump).

The jump is affine in S — S⁺ = A S⁻ + B, an integral gains C_x S⁻ + C_p — so the *forward*
method carries S through it and the *adjoint* method carries each output's costate L back
through its transpose: L⁻ = L⁺ A + μ C_x, ∂/∂p += L⁺ B + μ C_p (μ the integrals' seeds),
through each phase by reverse mode on the phase's ODE (:func:`index1_ode`).

Handled: impacts of frictionless contacts and joint stops (``impact`` model), one gap per
event, rebounding or plastic; closed phases; detaching.  Refused by name
(:class:`~casmbd.errors.AnalysisError`, with what to use instead): a gap that closes because
its rebounds fell below the rest velocity (e > 0: Zeno's accumulation, cut at a threshold that
has no derivative), a gap that closes at zero approach speed during the run, stick-slip joint
friction, friction at an impact contact, simultaneous events, a grazing impact, a derivative
with respect to the restitution of a plastic impact that closes its gap (one-sided).
"""

from __future__ import annotations

import copy
import time

import casadi as ca
import numpy as np

from casmbd.analysis.dynamics.simulate import Simulator, simulate
from casmbd.analysis.events.event_rows import EventRows, closure
from casmbd.analysis.instant.kkt import accelerations_and_multipliers
from casmbd.analysis.instant.reaction_friction import has_reaction_friction
from casmbd.analysis.integrators.sundials import CapturedOutput
from casmbd.errors import AnalysisError, IntegratorError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.contact_models import acts_at_events
from casmbd.model.contacts import slides

__all__ = ["EVENT_KINDS", "EVENT_STEPS", "check_event_elements", "event_sensitivity"]

#: the events whose sensitivity jump is handled
EVENT_KINDS = ("impact", "limit")
#: output intervals of the event-driven run that finds the events (each checked in 4
#: sub-intervals)
EVENT_STEPS = 200

_INSTEAD = ("use finite differences of whole runs (a sweep over the parameter), or the "
            "compliant model (model = 'compliant'), whose forces are smooth")


def check_event_elements(mechanism) -> None:
    """Refuse, before any work, the event elements whose sensitivity jump is not handled
    beyond what the composition check refuses (impact friction that does not slide in the
    plane, friction that follows the reactions together with impacts).

    Raises
    ------
    AnalysisError
        Naming the element, the analysis, why, and what to use instead.
    """
    # stick-slip joint friction and sliding contacts: refused by the composition check
    # (casmbd.model.needs) before this is called
    for contact in getattr(mechanism, "contacts", {}).values():
        if acts_at_events(contact) and contact.friction > 0.0:
            kind = "sliding contact" if slides(contact) else "contact with friction"
            raise AnalysisError(
                f"sensitivity: contact '{contact.name}' ({kind}, friction {contact.friction:g}) "
                "is not handled: the stick/slip decision of its tangential impulse has no "
                f"sensitivity jump here; {_INSTEAD}")
    if has_reaction_friction(_Probe(mechanism)):
        raise AnalysisError("sensitivity: joint friction that follows the reactions, with "
                            "impact contacts or stops, is not handled across impacts; "
                            + _INSTEAD)


class _Probe:
    """What :func:`has_reaction_friction` reads of a model: its mechanism."""

    def __init__(self, mechanism):
        self.mechanism = mechanism


def _impact_map(system, element, k: int, dsys) -> ca.Function:
    """Δ(q, v⁻, t, p) -> (v⁺, g, g_q, g_t, g_p) of gap ``k`` of ``element``, with the
    bilateral constraints of ``dsys`` (a phase's: closed gaps included)."""
    q, v, t, p = system.q, system.v, system.t, system.p
    g = ca.vec(element.gaps(system.ctx))[k]
    gq = ca.jacobian(g, q)
    m_mat = dsys.mass_matrix
    nq, nc = dsys.nq, dsys.nc
    e = element.restitution_at(system.ctx)  # a parameter expression: Δ_p includes ∂/∂e
    if nc:
        cq = dsys.constraint_jacobian
        lower = ca.vertcat(cq, gq)
        rhs = ca.vertcat(ca.mtimes(m_mat, v), -dsys.constraint_time_derivative,
                         -e * ca.mtimes(gq, v))
    else:
        lower = gq
        rhs = ca.vertcat(ca.mtimes(m_mat, v), -e * ca.mtimes(gq, v))
    kk = lower.size1()
    saddle = ca.blockcat([[m_mat, -lower.T], [lower, ca.SX(kk, kk)]])
    v_plus = ca.solve(saddle, rhs)[:nq]
    return ca.Function("impact_map", [q, v, t, p],
                       [v_plus, g, gq, ca.jacobian(g, t), ca.jacobian(g, p)])


#: CVODES options of the adjoint: the parameter adjoints are backward quadratures, which
#: must be in the error test — without it CasADi 3.8 integrates them with the steps of the
#: backward states, huge where those are polynomials: ∂y(0.3)/∂p of ÿ = p − g came out 0.0801
#: (CVODES) or 0.0543 (IDAS) instead of 0.045; with it, 0.045.
ADJOINT_OPTIONS = {"quad_err_con": True, "print_stats": False, "show_eval_warnings": False}


def index1_ode(t, x, z, p, ode, alg, quad):
    """The index-1 DAE with its algebraic states eliminated, for the adjoint: z = (q̈, λ)
    solves the linear equations alg = A(t, x, p) z − b(t, x, p) = 0, so ẋ = ode(t, x, z(t, x,
    p), p) is an ODE integrated by CVODES, whose adjoint CasADi differentiates reliably.
    (Through IDAS, CasADi 3.8's adjoint of a DAE is unreliable: its parameter adjoints, the
    backward quadratures, fail IDAS's error test when put into it (IDA_TOO_MUCH_WORK) and are
    wrong without it — 0.0551 for ∂y/∂F = T²/2 = 0.045 of a pushed ball at T = 0.3 s; see
    :data:`ADJOINT_OPTIONS`; casadi/casadi#3104 for the backward initialisation.)  Returns
    ``build(t, x, p) -> (z, ẋ, quadratures)`` in MX."""
    a_mat = ca.jacobian(alg, z)
    if ca.depends_on(a_mat, z):
        raise AnalysisError("sensitivity: method 'adjoint' needs the index-1 equations linear "
                            "in (q̈, λ) (friction that follows the reactions makes them "
                            "nonlinear); use method='forward'")
    b = -ca.substitute(alg, z, ca.SX.zeros(z.shape))
    parts = ca.Function("index1_parts", [t, x, p], [a_mat, b])
    rhs = ca.Function("index1_rhs", [t, x, z, p], [ode, quad])

    def build(tm, xm, pm):
        a_m, b_m = parts(tm, xm, pm)
        zm = ca.solve(a_m, b_m)
        ode_m, quad_m = rhs(tm, xm, zm, pm)
        return zm, ode_m, quad_m
    return build


class _Phase:
    """The index-1 DAE of the mechanism with a set of closed gaps (closure joints added, as in
    the event-driven run), its IDAS flow with Jacobians, and its outputs in the layout of the
    base mechanism's (q̈, λ)."""

    def __init__(self, sim, base_labels: list[str], nq: int, syms, finals, integrals,
                 opts: dict, p_nom: np.ndarray):
        t_x, x_sym, z_base, p_sym = syms
        self.sim, self.nq, self.p_nom = sim, nq, p_nom
        sim.model.p[:] = p_nom
        labels = [str(lab) for lab in sim.model.constraint_labels]
        self.system, self.dsys = sim.system, sim._dyn_system
        rows = [labels.index(lab) for lab in base_labels]
        #: rows of this phase's z = (q̈, λ) that make the base layout
        self.select = list(range(nq)) + [nq + r for r in rows]
        z = ca.SX.sym("z", nq + len(labels))
        z_as_base = z[self.select]
        ode, alg = sim.formulation.function(t_x, x_sym, z, p_sym, ca.SX(0, 1))[:2]
        integ_expr = ca.substitute(ca.vertcat(*integrals), z_base, z_as_base) if integrals \
            else ca.SX(0, 1)
        fin = ca.substitute(ca.vertcat(*finals), z_base, z_as_base) if finals else ca.SX(0, 1)
        s = ca.SX.sym("s")
        t0h = ca.SX.sym("t0h", 2)
        scaled_t = t0h[0] + t0h[1] * s
        dae = {"t": s, "x": x_sym, "z": z, "p": ca.vertcat(p_sym, t0h),
               "ode": ca.substitute(t0h[1] * ode, t_x, scaled_t),
               "alg": ca.substitute(alg, t_x, scaled_t)}
        self.n_int = len(integrals)
        if self.n_int:
            dae["quad"] = ca.substitute(t0h[1] * integ_expr, t_x, scaled_t)
        integ = ca.integrator("phase_dae", "idas", dae, 0.0, [1.0], opts)
        xm, zm = ca.MX.sym("x", x_sym.numel()), ca.MX.sym("z", z.numel())
        pm, th = ca.MX.sym("p", p_sym.numel()), ca.MX.sym("th", 2)
        res = integ(x0=xm, z0=zm, p=ca.vertcat(pm, th))
        outs = [res["xf"], res["zf"], res["qf"] if self.n_int else ca.MX(0, 1)]
        jacs = [ca.jacobian(o, a) for o in outs for a in (xm, pm)]
        self.flow = ca.Function("phase_flow", [xm, zm, pm, th], outs + jacs)
        self._value = ca.Function("phase_value", [xm, zm, pm, th], outs)
        self._io = (xm, zm, pm, th, outs)
        self._ode = (index1_ode(t_x, x_sym, z, p_sym, ode, alg, integ_expr),
                     {k: opts[k] for k in ("reltol", "abstol", "max_num_steps")})
        self.nz = z.numel()
        self._vjps: dict[int, ca.Function] = {}
        self.rhs = ca.Function("rhs", [t_x, x_sym, z, p_sym], [ode])
        self.h_fun = ca.Function("integrands", [t_x, x_sym, z, p_sym], [integ_expr])
        self.fin_fun = ca.Function("finals", [t_x, x_sym, z, p_sym],
                                   [fin, ca.jacobian(fin, x_sym), ca.jacobian(fin, z),
                                    ca.jacobian(fin, p_sym)])
        self._maps: dict[int, ca.Function] = {}

    def impact_map(self, rows: EventRows, i: int) -> ca.Function:
        if i not in self._maps:
            self._maps[i] = _impact_map(self.system, *rows.rows[i], self.dsys)
        return self._maps[i]

    def z_of(self, x: np.ndarray, t: float) -> np.ndarray:
        """The consistent algebraic state (q̈, λ) at (x, t)."""
        q, v = x[:self.nq], x[self.nq:]
        a, lam = accelerations_and_multipliers(self.sim.model, q, v, t, self.sim.inputs_at(t))
        return np.asarray(self.sim._z0(q, a, lam), float)

    def advance(self, x: np.ndarray, t: float, h: float) -> list[np.ndarray]:
        """x, z, quadratures at t + h and their Jacobians with respect to x(t) and p."""
        return [_dense(g) for g in self.flow(x, self.z_of(x, t), self.p_nom, [t, h])]

    def value(self, x: np.ndarray, t: float, h: float):
        """x, z and the quadratures at t + h (no derivatives)."""
        xf, zf, qf = self._value(x, self.z_of(x, t), self.p_nom, [t, h])
        return _dense(xf).ravel(), _dense(zf).ravel(), _dense(qf).ravel()

    def vjp(self, x: np.ndarray, t: float, h: float, seed_x, seed_z, seed_q):
        """Rows L_x = s_x ∂x_f/∂x₀ + s_z ∂z_f/∂x₀ + s_q ∂Q/∂x₀ and L_p (the same with
        respect to p) for each row of the seeds: reverse mode through CVODES on the phase's
        ODE (:func:`index1_ode`; the adjoint ODE integrated backwards with checkpointing,
        one backward solve per row)."""
        n_dir = seed_x.shape[0]
        if n_dir not in self._vjps:
            build, opts = self._ode
            xm = ca.MX.sym("x", len(x))
            pm, th, s = ca.MX.sym("p", len(self.p_nom)), ca.MX.sym("th", 2), ca.MX.sym("s")
            _, ode_m, quad_m = build(th[0] + th[1] * s, xm, pm)
            dae = {"t": s, "x": xm, "p": ca.vertcat(pm, th), "ode": th[1] * ode_m}
            if self.n_int:
                dae["quad"] = th[1] * quad_m
            integ = ca.integrator("phase_ode", "cvodes", dae, 0.0, [1.0],
                                  {**opts, **ADJOINT_OPTIONS})
            res = integ(x0=xm, p=ca.vertcat(pm, th))
            zf = build(th[0] + th[1], res["xf"], pm)[0]
            outs = [res["xf"], zf, res["qf"] if self.n_int else ca.MX(0, 1)]
            seeds = [ca.MX.sym(f"seed{k}", o.numel(), n_dir) for k, o in enumerate(outs)]
            back = ca.jtimes(ca.vertcat(*outs), ca.vertcat(xm, pm), ca.vertcat(*seeds), True)
            self._vjps[n_dir] = ca.Function("phase_vjp", [xm, pm, th, *seeds], [back])
        back = _dense(self._vjps[n_dir](x, self.p_nom, [t, h], np.asarray(seed_x).T,
                                        np.asarray(seed_z).T,
                                        np.asarray(seed_q).T.reshape(self.n_int, n_dir))).T
        return back[:, :len(x)], back[:, len(x):]

    def f(self, x: np.ndarray, z: np.ndarray, t: float) -> np.ndarray:
        return _dense(self.rhs(t, x, z, self.p_nom)).ravel()


def _steps(events: list[dict], rows: EventRows, p_nom: np.ndarray, t_start: float,
           tol_t: float) -> list[tuple]:
    """The events as steps (time, kind, gap index): "impact" (rebound, or a plastic impact
    that closes the gap: kind "close"), "start" (a gap closed at the start), "detach";
    anything else is refused by name (module docstring)."""
    label_of = {rows.label(i): i for i in range(len(rows.rows))}
    steps: list[tuple] = []
    m = 0
    while m < len(events):
        ev = events[m]
        group = [e for e in events[m:] if abs(e["time"] - ev["time"]) <= tol_t]
        m += len(group)
        names = {e["element"] for e in group}
        when = f"t = {ev['time']:.6g}"
        if len(names) > 1:
            raise AnalysisError(
                f"sensitivity: {', '.join(repr(n) for n in sorted(names))} act together at "
                f"{when}: simultaneous events have no unique sensitivity jump; {_INSTEAD}")
        kinds = [e["kind"] for e in group]
        i = label_of[ev["element"]]
        if kinds in (["impact"], ["limit"]):
            steps.append((ev["time"], "impact", i))
        elif kinds in (["impact", "contact"], ["limit", "contact"]):
            e_i = rows.restitution(i, ev["time"], p_nom)
            if e_i != 0.0:
                raise AnalysisError(
                    f"sensitivity: '{ev['element']}' closes (comes to rest on it) at {when} "
                    f"after its impacts accumulate (restitution {e_i:g} > 0: the rebound fell "
                    "below the rest velocity, a threshold that has no derivative); end the "
                    f"horizon before {when}, or {_INSTEAD}")
            steps.append((ev["time"], "close", i))
        elif kinds == ["contact"] and abs(ev["time"] - t_start) <= tol_t:
            steps.append((ev["time"], "start", i))
        elif kinds == ["detach"]:
            steps.append((ev["time"], "detach", i))
        else:
            what = {"contact": "closes without an impact (reached at zero approach speed)",
                    "stick": "sticks", "slip": "slips"}.get(kinds[0], " then ".join(kinds))
            raise AnalysisError(
                f"sensitivity: '{ev['element']}' {what} at {when}: not handled by the "
                f"sensitivity across events; {_INSTEAD}")
    return steps


def event_sensitivity(mechanism, sim, system, dsys, finals: list, integrals: list,
                      order: list, start_fun: ca.Function, p_nom: np.ndarray, idx: list[int],
                      t_start: float, t_end: float, rtol: float, atol: float, inputs,
                      max_steps: int, t_x, x_sym, z_sym, p_sym, method: str = "forward",
                      chosen_names: tuple = ()):
    """Values and sensitivities (``method`` "forward" or "adjoint") of the outputs of an
    event-driven run (module docstring).  Returns (values, jacobian, stats)."""
    t0 = time.perf_counter()
    if sim.redundancy.get("kept_rows") is not None:
        raise AnalysisError(
            "sensitivity: redundant constraint equations "
            f"({', '.join(sim.redundancy['redundant_equations'])}) with impacts are not "
            f"handled (the impulse law needs independent equations); {_INSTEAD}")
    # ---- the events, from the event-driven run itself (the same entry as simulate)
    run = simulate(mechanism, t_end, EVENT_STEPS, formulation="index1", rtol=rtol, atol=atol,
                   t_start=t_start, inputs=inputs, max_steps=max_steps)
    events = list(run.events)
    elements = [c for c in mechanism.contacts.values() if acts_at_events(c)]
    rows = EventRows(system, elements)
    tol_t = 1e-9 * (1.0 + abs(t_end))
    steps = _steps(events, rows, p_nom, t_start, tol_t)
    if steps and abs(steps[-1][0] - t_end) <= tol_t:
        raise AnalysisError(f"sensitivity: '{rows.label(steps[-1][2])}' acts at t_end = "
                            f"{t_end:g}, where the output jumps; choose another t_end")

    # the algebraic states (q̈, λ) out of the error test: their derivatives are not known at
    # a phase's start (IDAS takes 0), and a multiplier that changes from the start — a
    # resting body lifted by a growing force — fails the error test at every step size
    # (measured: "error test failed repeatedly" at t = 0, h = 3.8e-9); in an index-1 DAE they
    # follow from the differential states, whose error (and their sensitivities') is tested
    # (quadratures in the error test as in sensitivity.py: quad_err_con)
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": max_steps, "calc_ic": True,
            "fsens_err_con": True, "quad_err_con": True, "suppress_algebraic": True,
            "print_stats": False, "show_eval_warnings": False}
    nq = dsys.nq
    base_labels = [str(lab) for lab in sim.model.constraint_labels]
    syms = (t_x, x_sym, z_sym, p_sym)
    phases: dict[frozenset, _Phase] = {}

    def phase_of(closed: frozenset) -> _Phase:
        if closed not in phases:
            if closed:
                variant = copy.copy(mechanism)
                variant.joints = dict(mechanism.joints)
                for i in sorted(closed):
                    joint = closure(mechanism, *rows.rows[i])
                    variant.joints[joint.name] = joint
                phase_sim = Simulator(variant, "index1", inputs=inputs)
                if phase_sim.redundancy.get("kept_rows") is not None:
                    names = ", ".join(rows.label(i) for i in sorted(closed))
                    raise AnalysisError(
                        f"sensitivity: closing {names} makes constraint equations redundant "
                        f"({', '.join(phase_sim.redundancy['redundant_equations'])}): not "
                        f"handled across events; {_INSTEAD}")
            else:
                phase_sim = sim
            phases[closed] = _Phase(phase_sim, base_labels, nq, syms, finals, integrals,
                                    opts, p_nom)
        return phases[closed]

    # ---- the run, phase by phase: states, landing on the gaps, and the linear jumps
    sim.model.p[:] = p_nom
    x = _dense(start_fun(p_nom)).ravel()
    s_start = _start_jacobian(start_fun, p_nom)  # ∂x₀/∂p (every parameter; chosen at the end)
    n_int, n_x, n_p = len(integrals), len(x), len(p_nom)
    integral = np.zeros(n_int)
    segments: list[tuple] = []  # (phase, x at its start, t, h, x⁻, z⁻)
    jumps: list[tuple] = []  # (A, B, C_x, C_p): S⁺ = A S⁻ + B, ∫ gains C_x S⁻ + C_p
    t = float(t_start)
    closed: frozenset = frozenset()
    captured = CapturedOutput()
    try:
        with captured:
            for step in [*steps, None]:
                phase = phase_of(closed)
                t_next = float(t_end) if step is None else float(step[0])
                h = t_next - t
                if h > 0.0:
                    xf, zf, qf = phase.value(x, t, h)
                    if step is not None and step[1] in ("impact", "close"):
                        # land on the gap: Newton on g(x(t + h)) = 0
                        imap = phase.impact_map(rows, step[2])
                        for _ in range(4):
                            _, g, gq, g_t, _ = imap(xf[:nq], xf[nq:], t + h, p_nom)
                            rate = float(_dense(gq).ravel() @ phase.f(xf, zf, t + h)[:nq]) \
                                + _scalar(g_t)
                            if abs(_scalar(g)) <= 1e-15 or rate == 0.0:
                                break
                            h -= _scalar(g) / rate
                            xf, zf, qf = phase.value(x, t, h)
                    integral += qf
                else:  # an event at the start
                    xf, zf = x, phase.z_of(x, t)
                segments.append((phase, x, t, h, xf, zf))
                if step is None:
                    break
                t_e, kind, i = float(t + h), step[1], step[2]
                label = rows.label(i)
                if kind == "detach":  # q̈ continuous at −λ = 0: S continuous
                    jumps.append((np.eye(n_x), np.zeros((n_x, n_p)), np.zeros((n_int, n_x)),
                                  np.zeros((n_int, n_p))))
                    x, t = xf, t_e
                    closed = closed - {i}
                    continue
                # another open gap touching and approaching takes an impulse too (the impact
                # law's active set): no single-gap jump
                g_all, gq_all, _ = rows(xf[:nq], xf[nq:], t_e, p_nom)
                also = [rows.label(j) for j in range(len(rows.rows)) if j != i and
                        j not in closed and abs(g_all[j]) < 1e-9 and
                        gq_all[j] @ xf[nq:] < 0.0]
                if also:
                    raise AnalysisError(
                        f"sensitivity: '{label}' and {', '.join(repr(n) for n in also)} impact "
                        f"together at t = {t_e:.6g}: simultaneous impacts have no unique "
                        f"sensitivity jump; {_INSTEAD}")
                # the jump at an impact (module docstring); a plastic impact closes the gap
                imap = phase.impact_map(rows, i)
                v_plus, g, gq, g_t, g_p = (_dense(a) for a in
                                           imap(xf[:nq], xf[nq:], t_e, p_nom))
                g_x = np.concatenate([gq.ravel(), np.zeros(nq)])
                g_p = g_p.ravel()
                f_minus = phase.f(xf, zf, t_e)
                x_plus = np.concatenate([xf[:nq], v_plus.ravel()])
                d_x, d_t, d_p = _jump_jacobians(imap, xf, t_e, p_nom, nq)
                if kind == "close":  # e = 0 here; for e > 0 the gap would not close
                    de_dp = _dense(rows.restitution_jacobian(t_e, p_nom)).reshape(
                        len(rows.rows), n_p)[i, idx]
                    if np.any(de_dp != 0.0):
                        names = [str(n) for n, d in zip(chosen_names, de_dp) if d != 0.0]
                        raise AnalysisError(
                            f"sensitivity: the restitution of '{label}' (e = 0: the impact "
                            f"at t = {t_e:.6g} closes it) depends on {', '.join(names)}: for "
                            "e > 0 the gap would bounce instead of closing, so the derivative "
                            f"is one-sided; {_INSTEAD}")
                if kind in ("close", "start"):
                    closed = closed | {i}
                after = phase_of(closed)
                z_plus = after.z_of(x_plus, t_e)
                if kind == "start":  # closed at the fixed start time: no event time to move
                    moved = g_x @ s_start + g_p
                    if np.max(np.abs(moved), initial=0.0) > 1e-12:
                        raise AnalysisError(
                            f"sensitivity: '{label}' touches at the start and its gap moves "
                            "with the parameters (it would open or penetrate): not "
                            f"differentiable; {_INSTEAD}")
                    jumps.append((d_x, d_p, np.zeros((n_int, n_x)), np.zeros((n_int, n_p))))
                else:
                    rate = float(g_x @ f_minus) + _scalar(g_t)
                    if rate > -1e-9 * (1.0 + np.linalg.norm(f_minus[:nq])):
                        raise AnalysisError(
                            f"sensitivity: '{label}' is reached grazing at t = {t_e:.6g} "
                            f"(approach speed {rate:.3g}): the event time is not "
                            f"differentiable; {_INSTEAD}")
                    # τ = dt_e/dp = −(g_x S⁻ + g_p)/rate; S⁺ = Δ_x S⁻ + Δ_p + w τ
                    w = d_x @ f_minus + d_t - after.f(x_plus, z_plus, t_e)
                    jump_h = np.zeros(n_int)
                    if n_int:
                        jump_h = _dense(phase.h_fun(t_e, xf, zf, p_nom)).ravel() - \
                            _dense(after.h_fun(t_e, x_plus, z_plus, p_nom)).ravel()
                    jumps.append((d_x - np.outer(w, g_x) / rate, d_p - np.outer(w, g_p) / rate,
                                  -np.outer(jump_h, g_x) / rate, -np.outer(jump_h, g_p) / rate))
                x, t = x_plus, t_e
            last, _, _, _, x_end, z_end = segments[-1]
            val, fx, fz, fp = (_dense(a) for a in last.fin_fun(t_end, x_end, z_end, p_nom))
            if method == "forward":
                d_fin, d_integral = _forward(segments, jumps, s_start, fx, fz, fp, n_int)
            else:
                d_fin, d_integral = _adjoint(segments, jumps, s_start, fx, fz, fp, n_int)
    except RuntimeError as exc:
        reraise_interrupt(exc)
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "failed"
        raise IntegratorError(f"sensitivity: IDAS failed in the phase from t = {t:.6g}: {msg}",
                              float(t), "IDA_FAILURE") from None
    values, jac = [], []
    val = np.asarray(val, float).ravel()
    for kind, k in order:
        if kind == "integral":
            values.append(integral[k])
            jac.append(d_integral[k, idx])
        else:
            values.append(val[k])
            jac.append(d_fin[k, idx])
    stats = {"events": [dict(e) for e in events], "event_driven": True,
             "event_sensitivity": f"saltation (jump of S at each event), {method}",
             "phases": len(phases), "event_seconds": time.perf_counter() - t0}
    return np.array(values, float), np.array(jac, float).reshape(len(values), len(idx)), stats


def _forward(segments, jumps, s_start, fx, fz, fp, n_int):
    """S = ∂x/∂p carried forward: through each phase by IDAS's forward sensitivities (the
    flow's Jacobians), through each event by its jump."""
    s_mat = s_start
    n_p = s_start.shape[1]
    d_integral = np.zeros((n_int, n_p))
    for k, (phase, x0, t0, h, _, zf) in enumerate(segments):
        if h > 0.0:
            _, _, _, jxx, jxp, jzx, jzp, jqx, jqp = phase.advance(x0, t0, h)
            s_minus = jxx @ s_mat + jxp
            dz = jzx @ s_mat + jzp
            if n_int:
                d_integral += jqx @ s_mat + jqp
        else:
            s_minus, dz = s_mat, np.zeros((len(zf), n_p))
        if k == len(segments) - 1:
            return fx @ s_minus + fz @ dz + fp, d_integral
        a_mat, b_mat, c_x, c_p = jumps[k]
        d_integral += c_x @ s_minus + c_p
        s_mat = a_mat @ s_minus + b_mat
    raise AssertionError("no final segment")


def _adjoint(segments, jumps, s_start, fx, fz, fp, n_int):
    """The costate of every output carried backwards: through each phase by IDAS's adjoint
    (vector-Jacobian products of the flow, one backward solve per output), through each event
    by the transposed jump: L⁻ = L⁺ A + μ C_x, and ∂/∂p gains L⁺ B + μ C_p."""
    n_f, n_x = fx.shape[0], s_start.shape[0]
    n_out = n_f + n_int
    mu = np.zeros((n_out, n_int))  # the quadrature seeds: one per integral output
    mu[n_f:, :] = np.eye(n_int)
    d_p = np.zeros((n_out, s_start.shape[1]))
    d_p[:n_f] = fp
    seed_x = np.zeros((n_out, n_x))
    seed_x[:n_f] = fx
    seed_z = np.zeros((n_out, fz.shape[1]))
    seed_z[:n_f] = fz
    costate = None
    for k in range(len(segments) - 1, -1, -1):
        phase, x0, t0, h, _, _ = segments[k]
        if k < len(segments) - 1:  # the event after this phase, transposed
            a_mat, b_mat, c_x, c_p = jumps[k]
            d_p += costate @ b_mat + mu @ c_p
            seed_x = costate @ a_mat + mu @ c_x
            seed_z = np.zeros((n_out, phase.nz))
        if h > 0.0:
            l_x, l_p = phase.vjp(x0, t0, h, seed_x, seed_z, mu)
            d_p += l_p
            costate = l_x
        else:
            costate = seed_x
    d_p += costate @ s_start
    return d_p[:n_f], d_p[n_f:]


def _dense(a) -> np.ndarray:
    """A CasADi matrix as a dense float array (structural zeros as 0)."""
    return np.asarray(ca.DM(a).full(), float)


def _scalar(a) -> float:
    return float(_dense(a).ravel()[0])


def _start_jacobian(start_fun: ca.Function, p_nom: np.ndarray) -> np.ndarray:
    """∂x₀/∂p of the consistent start (every parameter)."""
    ps = ca.MX.sym("p", len(p_nom))
    jac = ca.Function("start_jac", [ps], [ca.jacobian(start_fun(ps), ps)])
    return _dense(jac(p_nom))


def _jump_jacobians(impact_map: ca.Function, x_minus: np.ndarray, t_e: float,
                    p_nom: np.ndarray, nq: int):
    """Δ_x, Δ_t, Δ_p of x⁺ = (q⁻, v⁺(q⁻, v⁻, t, p)) at the impact."""
    q = ca.MX.sym("q", nq)
    v = ca.MX.sym("v", len(x_minus) - nq)
    t = ca.MX.sym("t")
    p = ca.MX.sym("p", len(p_nom))
    x_plus = ca.vertcat(q, impact_map(q, v, t, p)[0])
    x = ca.vertcat(q, v)
    jac = ca.Function("jump", [q, v, t, p], [ca.jacobian(x_plus, x), ca.jacobian(x_plus, t),
                                             ca.jacobian(x_plus, p)])
    d_x, d_t, d_p = (_dense(a) for a in
                     jac(x_minus[:nq], x_minus[nq:], t_e, p_nom))
    return d_x, d_t.ravel(), d_p
