"""Which element made a time integration fail: stiffness, damping and time singularities.

A variable-step integrator reports *how* it failed (DOPRI5's TOO_SMALL_STEP or TOO_MUCH_WORK,
CVODES' CV_TOO_MUCH_WORK, CV_CONV_FAILURE, CV_ERR_FAILURE, right-hand-side errors) but not
*why*.  The usual cause is one element far stiffer than the rest (a spring of 1e300 N/m, an FE
mass in tonnes read as kilograms, a stiffness ``1/(t − 0.25)``): an explicit method is stable
only for steps h ≲ c/ω_max (c ≈ 3.3 for DOPRI5, 2.8 for RK4; Hairer & Wanner, *Solving ODEs
II*, IV.2), and a stiff one needs Newton iterations that converge.

:func:`diagnose_stiffness` runs after such a failure at time t with the last kept state (q, v).
For each force element (springs, dampers, expression and user forces, compliant contacts,
torques) and each flexible body's elastic and damping forces it forms, by CasADi's algorithmic
differentiation of the element's generalized force Q_e(q, v, t) (the virtual-work terms of
:mod:`casmbd.system.applied_forces`),

    K_e = −∂Q_e/∂q,   C_e = −∂Q_e/∂v,

restricts them and the mass matrix M to the independent motions (an orthonormal basis N of the
null space of C_q(q, t), by SVD: K_r = Nᵀ K_e N, M_r = Nᵀ M N) and takes the largest
generalized eigenvalue magnitudes

    ω_e² = max |λ(K_r, M_r)|,   σ_e = max |λ(C_r, M_r)|,

the element's highest natural frequency [rad/s] and fastest damping rate [1/s] with the
mass of the whole mechanism.  The element with the largest max(ω_e, σ_e) is named with its
time scale, the step an explicit method would need and the advice.  An element whose force or
stiffness is not finite at t, or whose frequency at t exceeds the one at the start by more than
:data:`GROWTH` (a time singularity such as ``1/(t − 0.25)`` or a growth ``exp(100 t)``), is named
first.  Dense linear algebra: above :data:`MAX_COORDINATES` coordinates the eigenvalues are
skipped and the message says so.

:func:`check_plausible_elements` refuses, before a run, what no unit makes sensible: a spring or
compliant contact whose stiffness gives sqrt(k/m) above :data:`OMEGA_MAX` with the masses it
connects, and a spring free length beyond :data:`FREE_LENGTH_MAX`.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from casmbd.errors import CasmbdError, ModelError
from casmbd.interrupts import reraise_interrupt
from casmbd.lazy import lazy_module
from casmbd.model.bodies import GROUND
from casmbd.model.values import numeric

sla = lazy_module("scipy.linalg")

__all__ = ["FREE_LENGTH_MAX", "GROWTH", "MAX_COORDINATES", "MAX_ELEMENTS", "OMEGA_MAX",
           "check_plausible_elements", "diagnose_stiffness"]

#: above this many coordinates the dense eigenvalue diagnosis is skipped
MAX_COORDINATES = 300
#: above this many force elements and flexible bodies the diagnosis is skipped (one
#: CasADi Function with two Jacobians each)
MAX_ELEMENTS = 200
#: an element's frequency growing by more than this factor from the start to the failure
#: time is named as a time singularity / growth
GROWTH = 1e3
#: largest plausible implied frequency sqrt(k/m) of a spring or contact [rad/s]: 1e15 rad/s is
#: an optical frequency (a molecular bond vibrates at ~1e14 rad/s); DOPRI5 would need 1e15
#: steps per second of simulated time
OMEGA_MAX = 1e15
#: largest plausible free length of a spring [m] (1000 km)
FREE_LENGTH_MAX = 1e6
#: explicit stability bound h ω ≲ STABILITY (DOPRI5 ≈ 3.3, RK4 ≈ 2.8)
STABILITY = 3.0


# ---------------------------------------------------------------------- before the run
def _number(value, mech) -> float | None:
    """A time-independent value with the parameters' values (None when it depends on time or
    cannot be evaluated: the run's own checks name that)."""
    if value is None or isinstance(value, bool):
        return None
    try:
        return numeric(value, dict(getattr(mech, "parameters", {}) or {}), "value")
    except (CasmbdError, RuntimeError, TypeError, ValueError):
        return None


def _mass(mech, body: str) -> float | None:
    """The numeric mass of ``body`` (None for the ground, a time-dependent or a zero mass)."""
    if body == GROUND or body not in mech.bodies:
        return None
    mass = _number(getattr(mech.bodies[body], "mass", None), mech)
    return mass if mass is not None and mass > 0 else None


def check_plausible_elements(mechanism) -> None:
    """Refuse stiffness and free-length values no unit makes sensible (module docstring).

    Only numeric fields are checked (an expression or a parameter is evaluated at run time,
    where :func:`diagnose_stiffness` names it if the run fails).

    Raises
    ------
    ModelError
        Naming the element, the field, the value, the implied frequency and the range.
    """
    for force in mechanism.forces.values():
        element = getattr(force, "element", None)  # compliant contacts: their contact
        if element is not None:
            bodies = element.bodies() if callable(element.bodies) else element.bodies
            where, bodies = f"contact '{element.name}'", tuple(bodies)
        elif hasattr(force, "body1") and hasattr(force, "body2"):
            where, bodies = f"force '{force.name}'", (force.body1, force.body2)
        else:
            continue
        length = _number(getattr(force, "free_length", None), mechanism)
        if length is not None and abs(length) > FREE_LENGTH_MAX:
            raise ModelError(f"{where} field 'free_length': {length:g} m is beyond the plausible "
                             f"{FREE_LENGTH_MAX:g} m (a wrong unit or a typo; "
                             "casmbd.analysis.integrators.stiffness_culprit.FREE_LENGTH_MAX)")
        k = _number(getattr(force, "stiffness", None), mechanism)
        masses = [m for m in (_mass(mechanism, b) for b in bodies) if m is not None]
        if k is None or k <= 0 or not masses:
            continue
        m = 1.0 / sum(1.0 / x for x in masses)  # the reduced mass of the bodies it connects
        omega = math.sqrt(k / m) if k / m < math.inf else math.inf
        if omega > OMEGA_MAX:
            raise ModelError(
                f"{where} field 'stiffness': {k:g} with the mass {m:g} kg it connects implies a "
                f"natural frequency sqrt(k/m) = {omega:.3g} rad/s, beyond the plausible "
                f"{OMEGA_MAX:g} rad/s (a wrong unit or a typo; no integrator could resolve a "
                f"period of {2 * math.pi / omega:.3g} s; "
                "casmbd.analysis.integrators.stiffness_culprit.OMEGA_MAX)")


# ---------------------------------------------------------------------- after a failure
def _element_forces(system) -> list[tuple[str, str, ca.SX]]:
    """(label, advice field, Q_e) of every force element and flexible body (symbolic)."""
    out = []
    mech = system.mechanism
    normals = {}
    try:  # reaction-proportional friction: its normal-force symbols at 0 here
        normals = dict(system.friction_normal_symbols)
    except Exception as exc:  # a diagnosis never hides the integrator's error
        reraise_interrupt(exc)
    zero_n = [(s, ca.SX.zeros(s.shape)) for s in normals.values()]
    for force in mech.forces.values():
        try:
            total = ca.SX.zeros(system.nq)
            for term in system._element_terms(force, system.ctx):
                if term.kind == "measure":
                    total += ca.jtimes(ca.vec(term.expr), system.q, ca.vec(term.weight), True)
                elif term.kind == "torque":
                    if term.body != GROUND:
                        omega = system.ctx.angular_velocity(term.body)
                        total += ca.jtimes(omega, system.v, ca.vec(term.weight), True)
                else:
                    total += term.weight
            if zero_n:
                total = ca.substitute([total], [s for s, _ in zero_n],
                                      [z for _, z in zero_n])[0]
        except Exception as exc:
            reraise_interrupt(exc)
            continue
        element = getattr(force, "element", None)
        label = (f"contact '{element.name}'" if element is not None
                 else f"force '{force.name}'")
        fields = [k for k in ("stiffness", "damping", "free_length", "value", "exponent")
                  if getattr(force, k, None) is not None]
        out.append((label, ", ".join(f"'{k}'" for k in fields), total))
    offset = 0
    for name in system.body_names:
        desc = system.descriptions[name]
        size = int(desc.size)
        hook = getattr(desc, "body_forces", None)
        if hook is not None:
            try:
                part = hook(system.ctx.coordinates(name), system.ctx.rates(name))
                total = ca.vertcat(ca.SX.zeros(offset), part,
                                   ca.SX.zeros(system.nq - offset - size))
                out.append((f"body '{name}' (its elastic and damping forces)",
                            "mass and stiffness ('rhoA', 'EA', 'EI' of a beam; the M and K "
                            "matrices of an FE file)", total))
            except Exception as exc:
                reraise_interrupt(exc)
        offset += size
    return out


def _basis(model, q, t: float, n: int) -> np.ndarray:
    """Orthonormal basis of the independent motions: the null space of C_q(q, t)."""
    if not model.nc:
        return np.eye(n)
    cq = model.constraint_jacobian(q, t)
    cq = cq.toarray() if hasattr(cq, "toarray") else np.asarray(cq, float)
    if not np.all(np.isfinite(cq)):
        return np.eye(n)
    return sla.null_space(cq)


def _largest(a: np.ndarray, m: np.ndarray) -> float:
    """max |λ| of the pencil (a, m), finite eigenvalues only (0 if none)."""
    if not a.size or not np.any(a):
        return 0.0
    try:
        lam = sla.eigvals(a, m)
    except (ValueError, np.linalg.LinAlgError):
        return math.inf
    lam = np.abs(lam[np.isfinite(lam)])
    return float(lam.max()) if lam.size else math.inf


def _rates(fun, model, q, v, t, u, basis, m_r) -> tuple[float, float, bool, float]:
    """(ω, σ, finite, |Q|) of one element at (q, v, t)."""
    q_e, dq, dv = (np.asarray(x, float) for x in fun(q, v, t, u, model.p))
    finite = bool(np.all(np.isfinite(q_e)) and np.all(np.isfinite(dq))
                  and np.all(np.isfinite(dv)))
    if not finite:
        return math.inf, math.inf, False, math.inf
    with np.errstate(all="ignore"):
        k_r = basis.T @ (-dq) @ basis
        c_r = basis.T @ (-dv) @ basis
        omega = math.sqrt(_largest(k_r, m_r))
        sigma = _largest(c_r, m_r)
    return omega, sigma, True, float(np.max(np.abs(q_e), initial=0.0))


def diagnose_stiffness(model, t: float, q, v, *, t_start: float | None = None, q0=None,
                       v0=None, rtol: float | None = None, t_end: float | None = None,
                       u=None) -> str:
    """The element behind an integrator failure at time ``t`` (module docstring), as text to
    append to the IntegratorError (empty when nothing stands out or the model is too large).

    Parameters
    ----------
    model : NumericModel
        With ``system`` (symbolic), ``mass_matrix``, ``constraint_jacobian``, ``p``.
    t, q, v :
        The failure time and the last kept state (the state at the failure is lost with the
        integrator's work space).
    t_start, q0, v0 :
        The start, to tell an element whose frequency grew with time.
    rtol, t_end :
        For the advice (steps needed to t_end).
    """
    try:
        return _diagnose(model, float(t), np.asarray(q, float).ravel(),
                         np.asarray(v, float).ravel(), t_start, q0, v0, rtol, t_end, u)
    except Exception as exc:  # never hide the integrator's own error
        reraise_interrupt(exc)
        return ""


def _diagnose(model, t, q, v, t_start, q0, v0, rtol, t_end, u) -> str:
    system = getattr(model, "system", None)
    if system is None or not math.isfinite(t):
        return ""
    n = int(model.nq)
    if n > MAX_COORDINATES:
        return (f"; no stiffness diagnosis above {MAX_COORDINATES} coordinates ({n}): dense "
                "eigenvalues would be too dear")
    count = len(system.mechanism.forces) + sum(
        getattr(system.descriptions[name], "body_forces", None) is not None
        for name in system.body_names)
    if count > MAX_ELEMENTS:
        return (f"; no stiffness diagnosis above {MAX_ELEMENTS} force elements and bodies "
                f"({count})")
    elements = _element_forces(system)
    if not elements:
        return ""
    u = np.zeros(int(getattr(model, "nu", 0))) if u is None else np.asarray(u, float)
    m_full = model.mass_matrix(q)
    m_full = m_full.toarray() if hasattr(m_full, "toarray") else np.asarray(m_full, float)
    basis = _basis(model, q, t, n)
    m_r = basis.T @ m_full @ basis
    found = []
    for label, fields, expr in elements:
        fun = ca.Function("element", [system.q, system.v, system.t, system.u, system.p],
                          [expr, ca.jacobian(expr, system.q), ca.jacobian(expr, system.v)])
        now = _rates(fun, model, q, v, t, u, basis, m_r)
        before = later = None
        if t_start is not None and q0 is not None and t_start < t:
            # the start state at the start time and at t: a change is the time's alone (a
            # state that diverged is no singularity of the element)
            q0a, v0a = np.asarray(q0, float).ravel(), np.asarray(v0, float).ravel()
            b0 = _basis(model, q0a, t_start, n)
            m0 = model.mass_matrix(q0a)
            m0 = m0.toarray() if hasattr(m0, "toarray") else np.asarray(m0, float)
            before = _rates(fun, model, q0a, v0a, t_start, u, b0, b0.T @ m0 @ b0)
            later = _rates(fun, model, q0a, v0a, t, u, b0, b0.T @ m0 @ b0)
        found.append((label, fields, now, before, later))
    # 1. not finite at t (with the state reached or the start state)
    for label, fields, now, _, later in found:
        if not now[2] or (later is not None and not later[2]):
            return (f"; {label}: its force or stiffness is not finite at t = {t:.6g} (check "
                    f"its {fields} for a singularity in t or q)")
    # 2. grown with time alone by orders of magnitude: 1/(t − 0.25), exp(100 t)
    for label, fields, _, before, later in found:
        if before is None or not before[2]:
            continue
        rate0, rate1 = max(before[0], before[1]), max(later[0], later[1])
        if rate1 > GROWTH * max(rate0, 1e-300) and rate1 * max(t - t_start, 1e-300) > 1e3:
            return (f"; {label}: at the same state its stiffness grows with time alone from a "
                    f"rate of {rate0:.3g} 1/s at t = {t_start:.6g} to {rate1:.3g} 1/s at t = "
                    f"{t:.6g} (a singularity or a growth in time of its {fields}; an explicit "
                    f"step would need h < {STABILITY / rate1:.3g} s): check its {fields}")
        if later[3] > GROWTH * max(before[3], 1e-300) and later[3] > 1e6:
            return (f"; {label}: at the same state its force grows with time alone from "
                    f"{before[3]:.3g} at t = {t_start:.6g} to {later[3]:.3g} at t = {t:.6g} "
                    f"(a singularity or a growth in time): check its {fields}")
    # 3. the element with the fastest rate at the state reached
    label, fields, now, _, _ = max(found, key=lambda e: max(e[2][0], e[2][1]))
    omega, sigma = now[0], now[1]
    rate = max(omega, sigma)
    if not rate > 0:
        return ""
    scale = 1.0 / rate
    what = (f"natural frequency {omega:.4g} rad/s (period {2 * math.pi / omega:.3g} s)"
            if omega >= sigma else f"damping rate {sigma:.3g} 1/s (time constant {scale:.3g} s)")
    h = STABILITY / rate
    text = f"; the fastest element at t = {t:.6g} is {label}: {what} with the mechanism's masses"
    span = (t_end - t) if t_end is not None and t_end > t else None
    text += f"; an explicit step must stay below about {h:.3g} s"
    if span:
        steps = span / h
        text += f" ({steps:.3g} steps to t_end)"
    text += (f": check the units and values of its {fields}, or use an implicit integrator "
             "(--integrator cvodes or idas)")
    if rtol is not None and rtol > 1e-3:
        text += f", or a smaller --rtol than {rtol:g}"
    return text
