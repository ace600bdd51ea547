"""Forward sensitivities across impacts: the jump of the sensitivity at an event.

Between events the state x = (q, v) of the event-driven run (:mod:`casmbd.analysis.events`)
follows the index-1 DAE of :mod:`casmbd.analysis.sensitivity`; its sensitivity S = ∂x/∂p is
propagated phase by phase by IDAS (the phase's flow map and its Jacobians with respect to the
start state and to p).  At an impact of gap g_i at t_e the state jumps, x⁺ = Δ(x⁻, t_e, p)
(Newton's restitution law with the bilateral constraints, :mod:`casmbd.analysis.impulses`):

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

Handled: impacts of frictionless contacts and joint stops (``impact`` model), one gap per
event, rebounding or plastic; closed phases; detaching.  Refused by name
(:class:`~casmbd.errors.AnalysisError`, with what to use instead): a gap that closes because
its rebounds fell below the rest velocity (e > 0: Zeno's accumulation, cut at a threshold that
has no derivative), a gap that closes at zero approach speed during the run, stick-slip joint
friction, friction at an impact contact, simultaneous events, a grazing impact, the adjoint
method.
"""

from __future__ import annotations

import copy
import time

import casadi as ca
import numpy as np

from casmbd.analysis.event_rows import EventRows, closure
from casmbd.analysis.integrators import CapturedOutput
from casmbd.analysis.joint_friction import has_reaction_friction
from casmbd.analysis.kkt import accelerations_and_multipliers
from casmbd.analysis.simulate import Simulator, simulate
from casmbd.errors import AnalysisError, IntegratorError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.contacts import slides

__all__ = ["EVENT_KINDS", "EVENT_STEPS", "check_event_elements", "event_sensitivity"]

#: the events whose sensitivity jump is handled
EVENT_KINDS = ("impact", "limit")
#: output intervals of the event-driven run that finds the events (each checked in 4
#: sub-intervals)
EVENT_STEPS = 200

_INSTEAD = ("use finite differences of whole runs (a sweep over the parameter), or the "
            "compliant model (model = 'compliant'), whose forces are smooth")


def check_event_elements(mechanism, method: str) -> None:
    """Refuse, before any work, the event elements whose sensitivity jump is not handled.

    Raises
    ------
    AnalysisError
        Naming the element, the analysis, why, and what to use instead.
    """
    for force in mechanism.forces.values():
        if getattr(force, "stick_slip", False):
            raise AnalysisError(
                f"sensitivity: force '{force.name}' (joint friction with the exact stick-slip "
                "law) is not handled: its stick and slip events change the set of equations "
                "and their jump is not implemented; use finite differences of whole runs (a "
                "sweep over the parameter), or the regularised law (stick_slip = false)")
    for contact in getattr(mechanism, "contacts", {}).values():
        if contact.model == "impact" and contact.friction > 0.0:
            kind = "sliding contact" if slides(contact) else "contact with friction"
            raise AnalysisError(
                f"sensitivity: contact '{contact.name}' ({kind}, friction {contact.friction:g}) "
                "is not handled: the stick/slip decision of its tangential impulse has no "
                f"sensitivity jump here; {_INSTEAD}")
    if has_reaction_friction(_Probe(mechanism)):
        raise AnalysisError("sensitivity: joint friction that follows the reactions, with "
                            "impact contacts or stops, is not handled across impacts; "
                            + _INSTEAD)
    if method != "forward":
        names = [c.name for c in mechanism.contacts.values() if c.model == "impact"]
        raise AnalysisError(
            f"sensitivity: method '{method}' across impacts ({', '.join(names)}) is not "
            "implemented: the jump of the adjoint at an event is not written; use "
            "method='forward'")


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
                      max_steps: int, t_x, x_sym, z_sym, p_sym):
    """Values and forward sensitivities of the outputs of an event-driven run (module
    docstring).  Returns (values, jacobian, stats)."""
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
    elements = [c for c in mechanism.contacts.values() if c.model == "impact"]
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
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": max_steps, "calc_ic": True,
            "fsens_err_con": True, "suppress_algebraic": True, "print_stats": False,
            "show_eval_warnings": False}
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

    # ---- phase by phase
    sim.model.p[:] = p_nom
    x = _dense(start_fun(p_nom)).ravel()
    s_mat = _start_jacobian(start_fun, p_nom)  # ∂x/∂p (every parameter; chosen at the end)
    n_int = len(integrals)
    integral = np.zeros(n_int)
    d_integral = np.zeros((n_int, len(p_nom)))
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
                    got = phase.advance(x, t, h)
                    if step is not None and step[1] in ("impact", "close"):
                        # land on the gap: Newton on g(x(t + h)) = 0
                        imap = phase.impact_map(rows, step[2])
                        for _ in range(4):
                            xf, zf = got[0].ravel(), got[1].ravel()
                            _, g, gq, g_t, _ = imap(xf[:nq], xf[nq:], t + h, p_nom)
                            rate = float(_dense(gq).ravel() @ phase.f(xf, zf, t + h)[:nq]) \
                                + _scalar(g_t)
                            if abs(_scalar(g)) <= 1e-15 or rate == 0.0:
                                break
                            h -= _scalar(g) / rate
                            got = phase.advance(x, t, h)
                    xf, zf, qf, jxx, jxp, jzx, jzp, jqx, jqp = got
                    xf, zf = xf.ravel(), zf.ravel()
                    s_minus = jxx @ s_mat + jxp
                    dz = jzx @ s_mat + jzp
                    if n_int:
                        integral += qf.ravel()
                        d_integral += jqx @ s_mat + jqp
                else:  # an event at the start
                    xf, s_minus = x, s_mat
                    zf = phase.z_of(x, t)
                    dz = np.zeros((len(zf), len(p_nom)))
                if step is None:  # t_end: the final values
                    val, fx, fz, fp = (_dense(a) for a in phase.fin_fun(t_end, xf, zf, p_nom))
                    d_fin = fx @ s_minus + fz @ dz + fp
                    break
                t_e, kind, i = float(t + h), step[1], step[2]
                label = rows.label(i)
                if kind == "detach":  # q̈ continuous at −λ = 0: S continuous
                    x, s_mat, t = xf, s_minus, t_e
                    closed = closed - {i}
                    continue
                # the jump at an impact (module docstring); a plastic impact closes the gap
                imap = phase.impact_map(rows, i)
                v_plus, g, gq, g_t, g_p = (_dense(a) for a in
                                           imap(xf[:nq], xf[nq:], t_e, p_nom))
                g_x = np.concatenate([gq.ravel(), np.zeros(nq)])
                f_minus = phase.f(xf, zf, t_e)
                if kind == "start":  # closed at the fixed start time: no event time to move
                    moved = g_x @ s_minus + g_p.ravel()
                    if np.max(np.abs(moved), initial=0.0) > 1e-12:
                        raise AnalysisError(
                            f"sensitivity: '{label}' touches at the start and its gap moves "
                            "with the parameters (it would open or penetrate): not "
                            f"differentiable; {_INSTEAD}")
                    tau = np.zeros(len(p_nom))
                else:
                    rate = float(g_x @ f_minus) + _scalar(g_t)
                    if rate > -1e-9 * (1.0 + np.linalg.norm(f_minus[:nq])):
                        raise AnalysisError(
                            f"sensitivity: '{label}' is reached grazing at t = {t_e:.6g} "
                            f"(approach speed {rate:.3g}): the event time is not "
                            f"differentiable; {_INSTEAD}")
                    tau = -(g_x @ s_minus + g_p.ravel()) / rate  # dt_e/dp
                x_plus = np.concatenate([xf[:nq], v_plus.ravel()])
                d_x, d_t, d_p = _jump_jacobians(imap, xf, t_e, p_nom, nq)
                if kind in ("close", "start"):
                    closed = closed | {i}
                after = phase_of(closed)
                z_plus = after.z_of(x_plus, t_e)
                f_plus = after.f(x_plus, z_plus, t_e)
                s_mat = (d_x @ (s_minus + np.outer(f_minus, tau)) + np.outer(d_t, tau) + d_p
                         - np.outer(f_plus, tau))
                if n_int:
                    h_minus = _dense(phase.h_fun(t_e, xf, zf, p_nom)).ravel()
                    h_plus = _dense(after.h_fun(t_e, x_plus, z_plus, p_nom)).ravel()
                    d_integral += np.outer(h_minus - h_plus, tau)
                x, t = x_plus, t_e
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
             "event_sensitivity": "saltation (jump of S at each impact)",
             "phases": len(phases), "event_seconds": time.perf_counter() - t0}
    return np.array(values, float), np.array(jac, float).reshape(len(values), len(idx)), stats


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
