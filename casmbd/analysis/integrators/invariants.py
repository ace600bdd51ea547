"""A cheap invariant of fixed-step runs: the total energy of a conservative mechanism.

(Adaptive runs get a coarser guard, :func:`check_energy_blowup`: the error control holds
only the local error below a tolerance the user may set to 0.1, where DOPRI5 on a stiff
spring grows the energy from 5000 J to 4e31 J in 1 s and the run ended with exit 0.)

A fixed-step method has no error control: RK4 or ABM4 with a step beyond the stability limit
of the stiffest element (RK4 on the imaginary axis: |h ω| < 2√2, Hairer & Wanner, *Solving
ODEs II*, IV.2) amplifies every oscillation by a constant factor per step, and the run ends
finite but meaningless — a 1e9 N/m spring at h = 0.01 s grows its energy from 5e6 J to 9e23 J
in one step.  For a conservative mechanism (nothing but gravity, springs without damping or
actuation whose values do not depend on time, and joints without drivers) the total energy
E = T + V is constant along exact solutions, so its drift is the method's error.

The check: the run stops at the first output k with

    |E_k − E_0| > :data:`ENERGY_DRIFT` · max(max_{j≤k} T_j, 1e-9 · max_{j≤k} (T_j + |V_j|)),

the drift larger than half the largest kinetic energy reached so far (datum-free: T does not
depend on where V is zero).  A sound run keeps the ratio near the method's local error
(1e-6 and below for RK4 at a tenth of the stability limit); a diverging one has it near 1 or
far above.  The floor 1e-9 · (T + |V|) keeps round-off of a mechanism at rest from counting.

Where something does work the energy says nothing; there the state norm is watched: the run
stops at the first output k with ‖x_k‖ > :data:`STATE_GROWTH` · max(‖x_0‖, 1) and
‖x_k‖ > :data:`STEP_GROWTH` · ‖x_{k−1}‖ (x = (q, v) in SI units): a state a million times its
start that grew a thousandfold within one output interval — the geometric growth of an
unstable step, not a motion (a free fall needs 1e5 s of one output interval to do that).
"""

from __future__ import annotations

import numpy as np

from casmbd.errors import CasmbdError, IntegratorError
from casmbd.model.values import numeric
from casmbd.results import Result

#: drift of the total energy, as a fraction of the largest kinetic energy so far, above which
#: a fixed-step run of a conservative mechanism stops
ENERGY_DRIFT = 0.5
#: size of the state, relative to the start (at least 1), above which a fast growth stops a run
STATE_GROWTH = 1e6
#: growth of the state norm within one output interval that counts as a blow-up
STEP_GROWTH = 1e3


def _time_dependent(value, params: dict) -> bool:
    """Whether a value depends on time: the expression parser says so (an expression of
    ``t``, a callable of t), not a search of its text."""
    if value is None or (isinstance(value, (int, float)) and not isinstance(value, bool)):
        return False
    try:
        numeric(value, params, "energy check")  # refuses a value of time
    except (CasmbdError, TypeError, ValueError):
        return True
    return False


def _zero_at(value, params: dict) -> bool:
    """Whether a time-independent value (a number or an expression of the parameters) is 0
    at the run's parameter values."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value == 0
    try:
        return numeric(value, params, "energy check") == 0.0
    except (CasmbdError, TypeError, ValueError):
        return False  # depends on time, or not a plain value: it may do work


def force_exchange(force, params: dict) -> str | None:
    """:meth:`~casmbd.model.forces.ForceElement.energy_exchange` of ``force`` at the parameter
    values ``params``: a spring-damper whose ``damping`` and ``actuator`` are 0 there (an
    expression or a parameter set to 0) is a pure spring (None), whatever the fields' form."""
    exchange = force.energy_exchange()
    if exchange is not None and hasattr(force, "damping") and hasattr(force, "actuator") \
            and _zero_at(force.damping, params) and _zero_at(force.actuator, params):
        return None
    return exchange


def energy_exchange(mechanism, result: Result, params: dict | None = None) -> list[str]:
    """The elements through which the total energy may change physically (empty: the
    mechanism is conservative): drivers, actuators with a non-zero input, contacts and joint
    limits, force elements that are not pure springs (dampers, actuation, applied forces;
    a spring's ``damping`` and ``actuator`` that are expressions count unless they are 0 at
    the parameter values ``params``, default the mechanism's), springs whose values depend on
    time, flexible bodies with modal damping, and joints with rows at the velocity level that
    do not declare them workless (``energy_exchange()`` returning None: A v = 0, b = 0)."""
    params = dict(mechanism.parameters if params is None else params)
    out = [f"driver '{d}'" for d in mechanism.drivers]
    inputs = result.arrays.get("actuator_inputs")
    for k, name in enumerate(mechanism.actuators):
        if inputs is None or k >= inputs.shape[1] or np.any(inputs[:, k] != 0):
            out.append(f"actuator '{name}'")
    out += [f"contact '{c}'" for c in getattr(mechanism, "contacts", {})]
    for name, force in mechanism.forces.items():
        exchange = force_exchange(force, params)
        if exchange is not None:
            out.append(f"{exchange} '{name}'")
        elif any(_time_dependent(getattr(force, key, None), params)
                 for key in ("stiffness", "free_length", "free_angle")):
            out.append(f"time-dependent spring '{name}'")
    for name, joint in mechanism.joints.items():
        # rows A v + b = 0 written at the velocity level do work λᵀ b unless b = 0: a kind
        # that knows its rows are workless says so (``energy_exchange()`` → None)
        if hasattr(joint, "velocity_equations"):
            exchange = joint.energy_exchange() if hasattr(joint, "energy_exchange") \
                else "velocity rows"
            if exchange is not None:
                out.append(f"{exchange} of joint '{name}'")
    for name, body in mechanism.bodies.items():
        if np.any(np.asarray(getattr(body, "damping_ratio", 0.0), dtype=float) != 0.0):
            out.append(f"modal damping of body '{name}'")
    return out


def first_energy_growth(result: Result) -> tuple[int, float] | None:
    """The first output index whose total-energy drift breaks the bound of the module
    docstring, and the bound there; None when there is none."""
    kin = result.arrays.get("kinetic_energy")
    pot = result.arrays.get("potential_energy")
    if kin is None or pot is None or len(kin) < 2:
        return None
    total = kin + pot
    drift = np.abs(total - total[0])
    bound = ENERGY_DRIFT * np.maximum(np.maximum.accumulate(kin),
                                      1e-9 * np.maximum.accumulate(kin + np.abs(pot)))
    bad = np.flatnonzero(drift > bound)
    return (int(bad[0]), float(bound[bad[0]])) if bad.size else None


#: an adaptive run stops when the total-energy drift of a conservative mechanism exceeds both
#: ENERGY_DRIFT × the largest kinetic energy so far and this factor × the initial energy scale
#: T_0 + |V_0|: a drift a thousand times what the mechanism started with, no tolerance error
ENERGY_BLOWUP = 1e3


def first_energy_blowup(result: Result) -> int | None:
    """The first output index of an adaptive run whose total-energy drift exceeds both
    ENERGY_DRIFT × the largest kinetic energy so far (with the floor of the module docstring)
    and :data:`ENERGY_BLOWUP` × (|T_0| + |V_0|); None when there is none."""
    kin = result.arrays.get("kinetic_energy")
    pot = result.arrays.get("potential_energy")
    if kin is None or pot is None or len(kin) < 2:
        return None
    total = kin + pot
    drift = np.abs(total - total[0])
    bound = ENERGY_DRIFT * np.maximum(np.maximum.accumulate(kin),
                                      1e-9 * np.maximum.accumulate(kin + np.abs(pot)))
    scale = ENERGY_BLOWUP * (abs(float(kin[0])) + abs(float(pot[0])))
    bad = np.flatnonzero((drift > bound) & (drift > scale))
    return int(bad[0]) if bad.size else None


def check_energy_blowup(result: Result, mechanism, what: str, truncate,
                        params: dict | None = None) -> None:
    """Stop an adaptive run of a conservative mechanism whose total energy blows up
    (:func:`first_energy_blowup`, flag ``ENERGY_GROWTH``): an
    :class:`~casmbd.errors.IntegratorError` naming the energies, the time and the tolerance
    to tighten, with the results before it (``truncate(result, n)``)."""
    if energy_exchange(mechanism, result, params):
        return
    k = first_energy_blowup(result)
    if k is None:
        return
    total = result.arrays["kinetic_energy"] + result.arrays["potential_energy"]
    t = float(result.t[k])
    n_kept = max(k, 1)
    partial = truncate(result, n_kept)
    partial.stats["failure_time"] = t
    raise IntegratorError(
        f"{what}: the total energy of this conservative mechanism went from "
        f"{total[0]:.6g} J at t = {result.t[0]:.6g} to {total[k]:.6g} J at t = {t:.6g} (more "
        f"than {ENERGY_BLOWUP:g} × its initial energy scale and {ENERGY_DRIFT:g} × the "
        f"largest kinetic energy so far); results kept up to t = {result.t[n_kept - 1]:.6g} "
        f"({n_kept} of {len(result.t)} output times): the tolerance is too loose for the "
        "stiffest element (tighten --rtol/--atol, or use a stiff integrator: --integrator "
        "cvodes)", t, "ENERGY_GROWTH", partial=partial)


def first_state_growth(result: Result) -> int | None:
    """The first output index whose state norm blows up (module docstring); None if none."""
    q, v = result.arrays.get("q"), result.arrays.get("v")
    if q is None or v is None or len(q) < 2:
        return None
    norm = np.linalg.norm(np.hstack([q.reshape(len(q), -1), v.reshape(len(v), -1)]), axis=1)
    big = norm > STATE_GROWTH * max(float(norm[0]), 1.0)
    fast = np.r_[False, norm[1:] > STEP_GROWTH * norm[:-1]]
    bad = np.flatnonzero(big & fast)
    return int(bad[0]) if bad.size else None


def _stop(result: Result, k: int, truncate, message: str, flag: str):
    t = float(result.t[k])
    n_kept = max(k, 1)
    partial = truncate(result, n_kept)
    partial.stats["failure_time"] = t
    return IntegratorError(
        f"{message}; results kept up to t = {result.t[n_kept - 1]:.6g} ({n_kept} of "
        f"{len(result.t)} output times): the step is too large for the stiffest element (RK4 "
        "beyond |h ω| < 2.8 grows the energy, near it damps it; take a smaller --step, or a "
        "variable-step integrator)", t, flag, partial=partial)


def check_energy(result: Result, mechanism, what: str, truncate,
                 params: dict | None = None) -> None:
    """Stop a fixed-step run of a conservative mechanism whose total energy grows
    (:func:`first_energy_growth`, flag ``ENERGY_GROWTH``, the energies named), and any
    fixed-step run whose state norm blows up (:func:`first_state_growth`, flag
    ``STATE_GROWTH``): an :class:`~casmbd.errors.IntegratorError` naming the time and the step,
    with the results before it (``truncate(result, n)``).  The energy is not checked when
    something does work (:func:`energy_exchange`)."""
    exchange = energy_exchange(mechanism, result, params)
    found = None if exchange else first_energy_growth(result)
    if found is not None:
        k, bound = found
        total = result.arrays["kinetic_energy"] + result.arrays["potential_energy"]
        raise _stop(result, k, truncate,
                    f"{what}: the total energy of this conservative mechanism went from "
                    f"{total[0]:.6g} J at t = {result.t[0]:.6g} to {total[k]:.6g} J at t = "
                    f"{result.t[k]:.6g} (drift {abs(total[k] - total[0]):.3g} J > {bound:.3g} "
                    f"J, {ENERGY_DRIFT:g} × the largest kinetic energy so far)",
                    "ENERGY_GROWTH")
    k = first_state_growth(result)
    if k is not None:
        norm = [float(np.linalg.norm(np.r_[result.arrays["q"][j], result.arrays["v"][j]]))
                for j in (0, k - 1, k)]
        raise _stop(result, k, truncate,
                    f"{what}: the state norm ‖(q, v)‖ blew up from {norm[0]:.3g} at t = "
                    f"{result.t[0]:.6g} to {norm[2]:.3g} at t = {result.t[k]:.6g} ("
                    + (f"{norm[2] / norm[1]:.3g}× within one output interval)" if norm[1] > 0
                       else f"from {norm[1]:.3g} within one output interval)"),
                    "STATE_GROWTH")
