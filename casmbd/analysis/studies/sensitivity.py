"""Exact sensitivities of simulation outputs with respect to scene parameters.

The forward dynamics are integrated as the semi-explicit index-1 DAE (seed 000, eq. 6.138)

    q̇ = v,   v̇ = a,   0 = M(q, p) a + C_qᵀ λ − Q(q, v, t, u, p),   0 = C_q a − γ,

by IDAS, with the outputs written as

* **final values** g(q, v, a, λ, t_end, p) — a marker position, a joint angle at ``t_end``;
* **integrals** ∫ h(q, v, a, λ, t, p) dt — of a reaction, a driver effort, a power — as IDAS
  quadratures.

Their derivatives with respect to the chosen parameters come from CasADi's differentiation of
the integrator: *forward* sensitivity equations (one extra DAE per parameter, IDAS ``fsens``,
included in the error test) or the *adjoint* DAE integrated backwards from ``t_end`` with
checkpointing (one backward solve per output) — Hindmarsh et al., "SUNDIALS: Suite of
nonlinear and differential/algebraic equation solvers", ACM TOMS 31 (2005), §5.  Forward
mode pays per parameter, adjoint mode per output.

The consistent initial state depends on the parameters through the constraints: with the
scene's nominal state (q_n, v_n) held fixed, q₀(p) is the point of C(q, p) = 0 reached by the
minimum-norm Newton correction of the assembly, to first order
q₀ = q* − C_qᵀ (C_q C_qᵀ)⁻¹ C(q*, p) about the assembled q*, and v₀(p) is the mass-orthogonal
projection of v_n onto C_q v + C_t = 0 (``casmbd.analysis.instant.kkt.project_velocities``), written
symbolically so that its derivative is exact.  The nominal values themselves (initial positions
and velocities given as numbers in the scene) are not functions of the parameters.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from casmbd.analysis.dynamics.build_cache import input_expression
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.events.events import has_events
from casmbd.analysis.instant.kkt import consistent_state
from casmbd.analysis.integrators.option_ranges import check_integrator_options
from casmbd.analysis.integrators.sundials import CapturedOutput
from casmbd.analysis.studies.sensitivity_events import (
    ADJOINT_OPTIONS,
    check_event_elements,
    event_sensitivity,
    index1_ode,
)
from casmbd.errors import AnalysisError, IntegratorError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.contact_models import CONTACT_MODELS
from casmbd.model.expressions import parse_expression
from casmbd.model.needs import ALL_NEEDS, Handling, check
from casmbd.system.named_quantities import identifier, quantities

METHODS = ("forward", "adjoint")
_AXES = ("x", "y", "z")


@dataclass
class SensitivityResult:
    """Outputs of one simulation and their derivatives with respect to parameters.

    Attributes
    ----------
    outputs : list of str
        Output specifications as given (``"tip_x"``, ``"integral: O_M"``).
    parameters : list of str
        Parameter names, the columns of ``jacobian``.
    values : ndarray, shape (n_outputs,)
        The outputs at the nominal parameter values.
    jacobian : ndarray, shape (n_outputs, n_parameters)
        ∂ output_i / ∂ p_j.
    method : str
        ``"forward"`` or ``"adjoint"``.
    stats : dict
        Tolerances, times, parameter values.
    """

    outputs: list[str]
    parameters: list[str]
    values: np.ndarray
    jacobian: np.ndarray
    method: str
    stats: dict = field(default_factory=dict)

    def derivative(self, output: str, parameter: str) -> float:
        """∂ ``output`` / ∂ ``parameter`` by name."""
        for names, key, what in ((self.outputs, output, "output"),
                                 (self.parameters, parameter, "parameter")):
            if key not in names:
                raise AnalysisError(f"sensitivity: unknown {what} '{key}' (known: "
                                    f"{', '.join(names)})")
        return float(self.jacobian[self.outputs.index(output), self.parameters.index(parameter)])

    def to_json(self) -> dict:
        """JSON view: values and the Jacobian by output and parameter name."""
        return {"method": self.method, "parameters": list(self.parameters),
                "outputs": {o: {"value": float(self.values[i]),
                                "derivatives": {p: float(self.jacobian[i, j])
                                                for j, p in enumerate(self.parameters)}}
                            for i, o in enumerate(self.outputs)},
                "stats": self.stats}


def output_names(system, a: ca.SX, lam: ca.SX, u: ca.SX,
                 kept_rows: Sequence[int] | None = None) -> dict[str, ca.SX]:
    """Names usable in sensitivity outputs, as SX of (q, v, t, p, a, λ).

    Everything of :func:`casmbd.system.named_quantities.quantities` (joint coordinates and rates,
    marker and body positions and velocities, generalized coordinates, parameters, ``t``,
    actuator inputs), plus ``<coordinate>_ddot`` (q̈), the joint reactions
    ``<joint>_Fx``, ``_Fy`` (``_Fz``), ``_M`` in the plane or ``_Mx``, ``_My``, ``_Mz`` in
    space (action of body1 on body2 at the joint point, global components) and
    ``<driver>_effort`` (−λ of the driver's row).
    """
    names = quantities(system)
    if system.u.numel():
        names = {k: ca.substitute(v, system.u, u) for k, v in names.items()}
    for k, cname in enumerate(system.coordinate_names):
        names.setdefault(identifier(f"{cname}_ddot"), a[k])
    nc = system.nc
    if kept_rows is not None and len(kept_rows) != nc:
        return names  # redundant rows removed: reactions along them are undetermined
    lam_full = lam
    mech = system.mechanism
    if mech.joints:
        reac = system.reactions_function()(system.q, system.v, a, system.t, u, system.p,
                                           lam_full)
        comps = ([f"F{ax}" for ax in _AXES[:2]] + ["M"]) if system.dimension == 2 else \
            [f"F{ax}" for ax in _AXES] + [f"M{ax}" for ax in _AXES]
        for j, jname in enumerate(mech.joints):
            for c, comp in enumerate(comps):
                names.setdefault(identifier(f"{jname}_{comp}"), reac[c, j])
    for dname in mech.drivers:
        names.setdefault(identifier(f"{dname}_effort"), -lam_full[system.driver_rows[dname]])
    return names


def _load_time(mechanism, chosen: Sequence[str]) -> list[str]:
    """The parameters of ``chosen`` that fix load-time numbers of the scene (positions,
    points, axes, initial velocities, radii are evaluated when the scene is read), whose
    derivative would miss that effect.  Found by reading the scene again with the parameter
    moved (``mech.scene_points``, set by the scene reader; a mechanism built in Python has
    none and is not checked)."""
    scenes = getattr(mechanism, "scene_points", None)
    if scenes is None:
        return []
    declared = scenes.mechanism().parameters  # a parameter added in Python is not the text's
    fixed = []
    for name in (n for n in chosen if n in declared):
        value = float(mechanism.parameters[name])
        try:
            scenes.point_scenes([{name: value + 1e-3 * (1.0 + abs(value))}])
        except AnalysisError:
            fixed.append(name)
    return fixed


def _check_runtime(mechanism, chosen: Sequence[str]) -> None:
    """Refuse parameters that fix load-time numbers of the scene (:func:`_load_time`)."""
    fixed = _load_time(mechanism, chosen)
    if fixed:
        raise AnalysisError(
            f"sensitivity: parameter(s) {', '.join(repr(n) for n in fixed)} fix load-time "
            f"numbers of {mechanism.scene_points.source} (positions, points, axes, initial "
            "velocities and contact radii are evaluated when the scene is read), so their "
            "derivative would miss that effect; differentiate with respect to parameters of "
            "masses, inertias, forces, springs, drivers, restitution coefficients or stops, "
            "or use finite differences of runs of scene files written with the moved value")


def _split(spec: str) -> tuple[str, str]:
    text = str(spec).strip()
    for kind in ("integral", "final"):
        if text.startswith(kind + ":"):
            return kind, text[len(kind) + 1:].strip()
    return "final", text


#: what sensitivities handle (casmbd.model.needs): impacts with the jump of the sensitivity
#: at each event; no switching friction
HANDLING = Handling(
    "sensitivity", ALL_NEEDS - {"stick_slip", "contact_friction"},
    why={"stick_slip": "the jump of the sensitivity at a stick-slip switch is not built",
         "contact_friction": "the jump of the sensitivity at a slide-stick switch of a "
                             "closed contact is not built"},
    instead={"stick_slip": "finite differences of whole runs (casmbd sweep), or the "
                           "regularised law (stick_slip = false)",
             "contact_friction": "finite differences of whole runs (casmbd sweep), or "
                                 "model = 'compliant'"},
    notes={"events": "the sensitivity jumps at each impact (saltation matrix); a gap that "
                     "closes after accumulated bounces, simultaneous or grazing impacts and "
                     "friction at impacts are refused by name",
           "reaction_forces": "the index-1 DAE solves λ with the accelerations",
           "velocity_constraints": "the index-1 DAE holds them at the acceleration level; "
                                   "the start's q₀(p) corrects the holonomic rows only and "
                                   "v₀(p) is projected onto every row"})


def sensitivity(mechanism, outputs: Sequence[str] | str, parameters: Sequence[str] | None = None,
                t_end: float = 1.0, *, t_start: float = 0.0, method: str = "forward",
                rtol: float = 1e-10, atol: float | None = None,
                inputs: Mapping | None = None, max_steps: int = 500_000) -> SensitivityResult:
    """Derivatives of scalar simulation outputs with respect to scene parameters.

    Parameters
    ----------
    mechanism : Mechanism
        With the parameters declared (``[parameters]`` of a scene, ``add_parameter``).
    outputs : str or sequence of str
        Each an expression of the names of :func:`output_names`, evaluated at ``t_end``
        (optionally prefixed ``"final:"``), or ``"integral: EXPR"`` for ∫ EXPR dt over
        [t_start, t_end].
    parameters : sequence of str, optional
        The parameters to differentiate with respect to (default: all that enter at run
        time; those that fix load-time numbers of a scene are left out and listed in
        ``stats["skipped_parameters"]``).
    t_end, t_start : float
        The horizon.
    method : {"forward", "adjoint"}
        IDAS forward sensitivities (cost grows with the number of parameters) or the adjoint
        DAE (cost grows with the number of outputs).
    rtol, atol : float
        IDAS tolerances (the sensitivities are included in the error test).
    inputs : mapping, optional
        Actuator inputs as for :func:`casmbd.simulate`.

    Returns
    -------
    SensitivityResult

    Raises
    ------
    AnalysisError
        Unknown parameters, no parameters, an unknown method, a bad horizon or an output that
        is not a scalar expression of the known names.
    IntegratorError
        When IDAS fails (with its message).
    """
    if method not in METHODS:
        raise AnalysisError(f"sensitivity: method must be one of {', '.join(METHODS)}, "
                            f"got {method!r}")
    if not (np.isfinite(t_end) and np.isfinite(t_start) and t_end > t_start):
        raise AnalysisError(f"sensitivity: t_end must be finite and > t_start = {t_start}, "
                            f"got {t_end!r}")
    atol = rtol if atol is None else atol
    check_integrator_options(t_end, 1, t_start=t_start, rtol=rtol, atol=atol)  # by meaning
    outputs = [outputs] if isinstance(outputs, str) else list(outputs)
    if not outputs:
        raise AnalysisError("sensitivity: no outputs given")
    check(mechanism, HANDLING)
    events = has_events(mechanism)
    if events:  # before any work: the event elements whose jump is not handled
        check_event_elements(mechanism)
    t0 = time.perf_counter()
    sim = Simulator(mechanism, "index1", inputs=inputs)
    system, dsys = sim.system, sim._dyn_system
    known = list(system.mechanism.parameters)
    if not known:
        raise AnalysisError(f"sensitivity: mechanism '{system.mechanism.name}' declares no "
                            "parameters")
    chosen = list(known if parameters is None else parameters)
    skipped = _load_time(mechanism, chosen) if parameters is None else []
    if skipped and len(skipped) < len(chosen):  # "all": those with a derivative
        chosen = [n for n in chosen if n not in skipped]
    for name in chosen:
        if name not in known:
            raise AnalysisError(f"sensitivity: unknown parameter '{name}' (known: "
                                f"{', '.join(known)})")
    if not chosen:
        raise AnalysisError("sensitivity: no parameters given")
    _check_runtime(mechanism, chosen)
    u_expr = input_expression(system, inputs)
    kept = sim.redundancy.get("kept_rows")

    # --- the DAE with its quadratures, in SX
    nq, nc = dsys.nq, dsys.nc
    t, q, v, p = system.t, system.q, system.v, system.p
    a = ca.SX.sym("a", nq)
    lam = ca.SX.sym("lambda", nc)
    lam_full = lam
    if kept is not None and len(kept) != system.nc:
        lam_full = ca.SX.zeros(system.nc)
        lam_full[list(kept)] = lam
    names = output_names(system, a, lam_full, u_expr,
                         None if kept is None else list(kept))
    finals, integrals, order = [], [], []
    for spec in outputs:
        kind, text = _split(spec)
        try:
            expr = ca.SX(parse_expression(text, names, where=f"sensitivity output '{spec}'"))
        except Exception as exc:  # ExpressionError names the fragment
            raise AnalysisError(str(exc)) from None
        if expr.numel() != 1:
            raise AnalysisError(f"sensitivity output '{spec}': not a scalar ({expr.shape})")
        (integrals if kind == "integral" else finals).append(expr)
        order.append((kind, len(integrals if kind == "integral" else finals) - 1))
    f = sim.formulation.function
    x = ca.vertcat(q, v)
    z = ca.vertcat(a, lam)
    ode, alg = f(t, x, z, p, ca.SX(0, 1))[:2]
    dae = {"t": t, "x": x, "z": z, "p": p, "ode": ode, "alg": alg}
    if integrals:
        dae["quad"] = ca.vertcat(*integrals)
    # (q̈, λ) out of the error test (suppress_algebraic): in an index-1 DAE they follow from
    # (q, v), whose error and sensitivities are tested; with them in the test IDAS failed at
    # the onset of a compliant contact (IDA_TOO_MUCH_WORK at t = 0.3675 for a ball on a
    # Hunt-Crossley floor, rtol 1e-8 … 1e-11), which now matches finite differences.  The
    # quadratures (integral outputs) and their sensitivities in it (quad_err_con): without,
    # they were integrated with the states' steps, huge where the motion is a polynomial —
    # ∂(∫ y dt)/∂F of a pushed ball over 0.3 s came out −0.005122 instead of −T³/6 = −0.0045
    # Only there: elsewhere the test on (q̈, λ) keeps the values at the tolerance (the crane of
    # the tutorial: 1.9e-8 relative off at rtol 1e-10 without it, 2.8e-10 with it)
    compliant = any(CONTACT_MODELS[c.model].force is not None  # a penalty force
                    for c in system.mechanism.contacts.values())
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": max_steps, "calc_ic": True,
            "fsens_err_con": True, "quad_err_con": True, "suppress_algebraic": compliant,
            "print_stats": False, "show_eval_warnings": False,
            "disable_internal_warnings": False}
    integ = ca.integrator("sensitivity_dae", "idas", dae, float(t_start), [float(t_end)], opts)

    # --- the consistent start as a function of p (exact first derivatives)
    q_nom = system.initial_coordinates()
    v_nom = system.initial_velocities()
    st = consistent_state(sim.model, q_nom, v_nom, t_start, sim.inputs_at(t_start))
    ps = ca.SX.sym("p_all", system.p.numel())
    cons = ca.Function("c", [q, t, p], [dsys.constraints, dsys.constraint_jacobian,
                                        dsys.constraint_time_derivative, dsys.mass_matrix])
    c_s, cq_s, _, _ = cons(st.q, t_start, ps)
    hol = list(getattr(dsys, "holonomic_rows", range(nc)))
    if len(hol) < nc:  # rows written at the velocity level correct no position (C ≡ 0)
        c_s, cq_s = c_s[hol], ca.Function("ch", [q, t, p], [dsys.position_jacobian[hol, :]])(
            st.q, t_start, ps)
    q0 = st.q - ca.mtimes(cq_s.T, ca.solve(ca.mtimes(cq_s, cq_s.T), c_s)) if hol else \
        ca.SX(st.q)
    _, cq0, ct0, m0 = cons(q0, t_start, ps)
    if nc:
        kkt = ca.blockcat([[m0, cq0.T], [cq0, ca.SX(nc, nc)]])
        v0 = ca.solve(kkt, ca.vertcat(ca.mtimes(m0, v_nom), -ct0))[:nq]
    else:
        v0 = ca.SX(v_nom)
    start_fun = ca.Function("sensitivity_start", [ps], [ca.vertcat(q0, v0)])

    # --- outputs as an MX function of the chosen parameters, differentiated
    p_nom = np.asarray(sim.model.p, dtype=float)
    idx = [known.index(n) for n in chosen]
    psel = ca.MX.sym("p_sel", len(idx))
    p_all = ca.MX(ca.DM(p_nom))
    for k, i in enumerate(idx):
        p_all[i] = psel[k]
    if events:  # impacts and stops: phase by phase, with the jump at each event
        build = time.perf_counter() - t0
        t1 = time.perf_counter()
        val, jac_v, extra = event_sensitivity(
            mechanism, sim, system, dsys, finals, integrals, order, start_fun, p_nom, idx,
            t_start, t_end, rtol, atol, inputs, max_steps, t, x, z, p, method, tuple(chosen))
        return _result(outputs, chosen, val, jac_v, method, idx, p_nom, t_start, t_end, rtol,
                       atol, build, time.perf_counter() - t1, extra, skipped)
    if method == "forward":
        lam0 = np.asarray(st.lam, dtype=float)
        if kept is not None and lam0.size != nc:  # the multipliers of the kept rows only
            lam0 = lam0[list(kept)]
        res = integ(x0=start_fun(p_all), z0=np.concatenate([st.a, lam0]), p=p_all)
    else:  # the adjoint through CVODES on the ODE with (q̈, λ) eliminated (index1_ode)
        build_ode = index1_ode(t, x, z, p, ode, alg, dae.get("quad", ca.SX(0, 1)))
        tm, xm, pm = ca.MX.sym("t"), ca.MX.sym("x", x.numel()), ca.MX.sym("p", p.numel())
        _, ode_m, quad_m = build_ode(tm, xm, pm)
        ode_dae = {"t": tm, "x": xm, "p": pm, "ode": ode_m, **({"quad": quad_m} if integrals
                                                               else {})}
        ode_integ = ca.integrator("sensitivity_ode", "cvodes", ode_dae, float(t_start),
                                  [float(t_end)], {"reltol": rtol, "abstol": atol,
                                                   "max_num_steps": max_steps,
                                                   **ADJOINT_OPTIONS})
        res = dict(ode_integ(x0=start_fun(p_all), p=p_all))
        res["zf"] = build_ode(ca.MX(float(t_end)), res["xf"], p_all)[0]
    final_fun = ca.Function("finals", [t, x, z, p], [ca.vertcat(*finals)]) if finals else None
    fin = final_fun(float(t_end), res["xf"], res["zf"], p_all) if finals else ca.MX(0, 1)
    values = []
    for kind, k in order:
        values.append(res["qf"][k] if kind == "integral" else fin[k])
    out = ca.vertcat(*values)
    if method == "forward":
        jac = ca.jtimes(out, psel, ca.DM.eye(len(idx)))
    else:
        jac = ca.jtimes(out, psel, ca.DM.eye(len(values)), True).T
    fun = ca.Function("sensitivity", [psel], [out, jac])
    build = time.perf_counter() - t0
    t1 = time.perf_counter()
    # SUNDIALS prints its diagnostics (and CasADi the failed Function's inputs) on stderr:
    # captured, the "At t = …" line goes into the error, and an interrupt prints nothing
    captured = CapturedOutput()
    try:
        with captured:
            val, jac_v = fun(p_nom[idx])
    except RuntimeError as exc:
        reraise_interrupt(exc)
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "failed"
        when = [ln.strip() for ln in captured.text.splitlines() if ln.startswith("At t")]
        raise IntegratorError(f"sensitivity: IDAS ({method}) failed over [{t_start:g}, "
                              f"{t_end:g}]: {msg}" + (f" ({when[0]})" if when else ""),
                              float("nan"), "IDA_FAILURE") from None
    val = np.asarray(val.full(), dtype=float).ravel()
    jac_v = np.asarray(jac_v.full(), dtype=float).reshape(len(values), len(idx))
    return _result(outputs, chosen, val, jac_v, method, idx, p_nom, t_start, t_end, rtol, atol,
                   build, time.perf_counter() - t1, {}, skipped)


def _result(outputs, chosen, val, jac_v, method, idx, p_nom, t_start, t_end, rtol, atol,
            build, solve, extra, skipped=()) -> SensitivityResult:
    stats = {"rtol": rtol, "atol": atol, "t_start": float(t_start), "t_end": float(t_end),
             "build_seconds": build, "solve_seconds": solve,
             "parameter_values": {n: float(p_nom[i]) for n, i in zip(chosen, idx)},
             "formulation": "index1", "integrator": "idas", **extra}
    if skipped:
        stats["skipped_parameters"] = {n: "fixes load-time numbers of the scene"
                                       for n in skipped}
    if not (np.all(np.isfinite(val)) and np.all(np.isfinite(jac_v))):
        raise IntegratorError("sensitivity: non-finite outputs or derivatives at t_end = "
                              f"{t_end:g}", float(t_end), "NON_FINITE")
    return SensitivityResult(outputs, chosen, val, jac_v, method, stats)
