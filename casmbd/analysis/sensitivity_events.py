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

Handled: impacts of frictionless contacts and joint stops (``impact`` model) that rebound —
one gap per event.  Refused by name (:class:`~casmbd.errors.AnalysisError`, with what to use
instead): a gap that closes (the ball at rest), a detach, stick-slip joint friction, friction
at an impact, simultaneous impacts, a grazing impact, the adjoint method.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from casmbd.analysis.event_rows import EventRows
from casmbd.analysis.integrators import CapturedOutput
from casmbd.analysis.joint_friction import has_reaction_friction
from casmbd.analysis.kkt import accelerations_and_multipliers
from casmbd.analysis.simulate import simulate
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
    """Δ(q, v⁻, t, p) -> (v⁺, g, g_q, g_t, g_p) of gap ``k`` of ``element``."""
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
    tol_t = 1e-9 * (1.0 + abs(t_end))
    for m, ev in enumerate(events):
        if ev["kind"] not in EVENT_KINDS:
            what = {"contact": "closes (comes to rest on it)", "detach": "detaches",
                    "stick": "sticks", "slip": "slips"}.get(ev["kind"], ev["kind"])
            raise AnalysisError(
                f"sensitivity: '{ev['element']}' {what} at t = {ev['time']:.6g}: a closed gap "
                "(contact held by a force, or a stuck friction element) is not handled by the "
                f"sensitivity across events; end the horizon before t = {ev['time']:.6g}, or "
                + _INSTEAD)
        if m and abs(ev["time"] - events[m - 1]["time"]) <= tol_t:
            raise AnalysisError(
                f"sensitivity: '{events[m - 1]['element']}' and '{ev['element']}' impact "
                f"together at t = {ev['time']:.6g}: simultaneous impacts have no unique "
                f"sensitivity jump; {_INSTEAD}")
    if events and abs(events[-1]["time"] - t_end) <= tol_t:
        raise AnalysisError(f"sensitivity: '{events[-1]['element']}' impacts at t_end = "
                            f"{t_end:g}, where the output jumps; choose another t_end")
    elements = [c for c in mechanism.contacts.values() if c.model == "impact"]
    rows = EventRows(system, elements)
    label_of = {rows.label(i): i for i in range(len(rows.rows))}
    maps = {}
    for ev in events:
        i = label_of[ev["element"]]
        if i not in maps:
            maps[i] = _impact_map(system, *rows.rows[i], dsys)

    # ---- the phase flow: IDAS on the time-scaled index-1 DAE, with its Jacobians
    f = sim.formulation.function
    ode, alg = f(t_x, x_sym, z_sym, p_sym, ca.SX(0, 1))[:2]
    s = ca.SX.sym("s")
    t0h = ca.SX.sym("t0h", 2)
    scaled_t = t0h[0] + t0h[1] * s
    ode_s = ca.substitute(t0h[1] * ode, t_x, scaled_t)
    alg_s = ca.substitute(alg, t_x, scaled_t)
    pe = ca.vertcat(p_sym, t0h)
    dae = {"t": s, "x": x_sym, "z": z_sym, "p": pe, "ode": ode_s, "alg": alg_s}
    n_int = len(integrals)
    if n_int:
        dae["quad"] = ca.substitute(t0h[1] * ca.vertcat(*integrals), t_x, scaled_t)
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": max_steps, "calc_ic": True,
            "fsens_err_con": True, "print_stats": False, "show_eval_warnings": False}
    integ = ca.integrator("phase_dae", "idas", dae, 0.0, [1.0], opts)
    xm, zm = ca.MX.sym("x", x_sym.numel()), ca.MX.sym("z", z_sym.numel())
    pm, th = ca.MX.sym("p", p_sym.numel()), ca.MX.sym("th", 2)
    res = integ(x0=xm, z0=zm, p=ca.vertcat(pm, th))
    outs = [res["xf"], res["zf"], res["qf"] if n_int else ca.MX(0, 1)]
    jacs = [ca.jacobian(o, a) for o in outs for a in (xm, pm)]
    flow = ca.Function("phase_flow", [xm, zm, pm, th], outs + jacs)
    rhs = ca.Function("rhs", [t_x, x_sym, z_sym, p_sym], [ode])
    h_fun = ca.Function("integrands", [t_x, x_sym, z_sym, p_sym],
                        [ca.vertcat(*integrals) if n_int else ca.SX(0, 1)])
    fin = ca.vertcat(*finals) if finals else ca.SX(0, 1)
    fin_fun = ca.Function("finals", [t_x, x_sym, z_sym, p_sym],
                          [fin, ca.jacobian(fin, x_sym), ca.jacobian(fin, z_sym),
                           ca.jacobian(fin, p_sym)])
    nq = dsys.nq
    model = sim.model

    def z_of(x, t):
        q, v = x[:nq], x[nq:]
        a, lam = accelerations_and_multipliers(model, q, v, t, sim.inputs_at(t))
        return np.asarray(sim._z0(q, a, lam), float)

    def advance(x, t, h):
        got = flow(x, z_of(x, t), p_nom, [t, h])
        return [_dense(g) for g in got]

    # ---- phase by phase
    model.p[:] = p_nom
    x = np.asarray(start_fun(p_nom), float).ravel()
    s_mat = _start_jacobian(start_fun, p_nom)  # ∂x/∂p (every parameter; chosen at the end)
    integral = np.zeros(n_int)
    d_integral = np.zeros((n_int, len(p_nom)))
    t = float(t_start)
    captured = CapturedOutput()
    try:
        with captured:
            for ev in [*events, None]:
                t_next = float(t_end) if ev is None else float(ev["time"])
                h = t_next - t
                got = advance(x, t, h) if h > 0 else None
                if ev is not None:  # land on the gap: Newton on g(x(t + h)) = 0
                    i = label_of[ev["element"]]
                    for _ in range(4):
                        xf = got[0].ravel()
                        v_plus, g, gq, g_t, g_p = maps[i](xf[:nq], xf[nq:], t + h, p_nom)
                        zf = got[1].ravel()
                        f_minus = np.asarray(rhs(t + h, xf, zf, p_nom), float).ravel()
                        rate = float(_dense(gq).ravel() @ f_minus[:nq]) + _scalar(g_t)
                        if abs(_scalar(g)) <= 1e-15 or rate == 0.0:
                            break
                        h -= _scalar(g) / rate
                        got = advance(x, t, h)
                xf, zf, qf, jxx, jxp, jzx, jzp, jqx, jqp = got if got is not None else (
                    x[:, None], z_of(x, t)[:, None], np.zeros((n_int, 1)), np.eye(len(x)),
                    np.zeros((len(x), len(p_nom))), None, None,
                    np.zeros((n_int, len(x))), np.zeros((n_int, len(p_nom))))
                xf, zf = xf.ravel(), zf.ravel()
                s_minus = jxx @ s_mat + jxp
                if n_int:
                    integral += qf.ravel()
                    d_integral += jqx @ s_mat + jqp
                if ev is None:  # t_end: the final values
                    val, fx, fz, fp = (_dense(a) for a in
                                       fin_fun(t_end, xf, zf, p_nom))
                    dz = (jzx @ s_mat + jzp) if jzx is not None else np.zeros(
                        (len(zf), len(p_nom)))
                    d_fin = fx @ s_minus + fz @ dz + fp
                    break
                # the jump at the impact (module docstring)
                t_e = t + h
                i = label_of[ev["element"]]
                gq_fun = maps[i]
                v_plus, g, gq, g_t, g_p = (_dense(a) for a in
                                           gq_fun(xf[:nq], xf[nq:], t_e, p_nom))
                f_minus = np.asarray(rhs(t_e, xf, zf, p_nom), float).ravel()
                g_x = np.concatenate([gq.ravel(), np.zeros(nq)])
                rate = float(g_x @ f_minus) + _scalar(g_t)
                if rate > -1e-9 * (1.0 + np.linalg.norm(f_minus[:nq])):
                    raise AnalysisError(
                        f"sensitivity: '{ev['element']}' is reached grazing at t = {t_e:.6g} "
                        f"(approach speed {rate:.3g}): the event time is not differentiable; "
                        + _INSTEAD)
                tau = -(g_x @ s_minus + g_p.ravel()) / rate  # dt_e/dp
                x_plus = np.concatenate([xf[:nq], v_plus.ravel()])
                d_x, d_t, d_p = _jump_jacobians(gq_fun, xf, t_e, p_nom, nq)
                z_plus = z_of(x_plus, t_e)
                f_plus = np.asarray(rhs(t_e, x_plus, z_plus, p_nom), float).ravel()
                s_mat = (d_x @ (s_minus + np.outer(f_minus, tau)) + np.outer(d_t, tau) + d_p
                         - np.outer(f_plus, tau))
                if n_int:
                    h_minus = np.asarray(h_fun(t_e, xf, zf, p_nom), float).ravel()
                    h_plus = np.asarray(h_fun(t_e, x_plus, z_plus, p_nom), float).ravel()
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
             "event_seconds": time.perf_counter() - t0}
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
