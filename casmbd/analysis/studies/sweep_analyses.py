"""The shipped sweepable analyses — :data:`SIMULATE`, :data:`KINEMATICS`, :data:`INVERSE` and
:data:`STATICS` — each a :class:`~casmbd.analysis.studies.sweep_registry.Sweepable`: how a
parameter sweep builds it once per process, runs it at one point, its options and its default
outputs.  The registry (:data:`casmbd.analysis.studies.sweep_registry.SWEEPABLE`) names them;
:mod:`casmbd.analysis.studies.sweep` runs whichever it names, so an analysis verb from user
code is swept like these (``examples/custom_verb.py``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from casmbd.analysis.driven.inverse import HANDLING as INVERSE_HANDLING
from casmbd.analysis.driven.inverse import inverse_dynamics
from casmbd.analysis.driven.kinematics import HANDLING as KINEMATICS_HANDLING
from casmbd.analysis.driven.kinematics import kinematics
from casmbd.analysis.dynamics.simulate import (
    Simulator,
    Simulators,
    event_formulation,
    simulate,
    simulate_handling,
)
from casmbd.analysis.events.events import compliant_events, has_events
from casmbd.analysis.statics.statics import HANDLING as STATICS_HANDLING
from casmbd.analysis.statics.statics import STATICS_NEEDS, static_equilibrium, statics_functions
from casmbd.analysis.studies.sweep_registry import Engine, Sweepable
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NEEDS
from casmbd.model import Mechanism
from casmbd.model.needs import Handling
from casmbd.results import Result
from casmbd.system.equations import System

__all__ = ["INVERSE", "KINEMATICS", "SIMULATE", "STATICS", "statics_as_result"]


def _final_q(result: Result) -> list[str]:
    return [f"final:q[{c}]" for c in result.names.get("coordinates", [])]


# ---------------------------------------------------------------------- simulate
def _build_simulate(mech: Mechanism, mode: str, **build) -> Engine:
    if has_events(mech):
        # every point through simulate() itself: phase by phase with its events, the phase
        # simulators kept across points
        simulators = Simulators(event_formulation(mech, build.get("formulation")),
                                build.get("inputs"), mode, build.get("formulation_options"),
                                build.get("redundancy", "auto"))
        return Engine(mech, simulators(mech).model, mode, simulators)  # the base phase
    engine = Simulator(mech, mode=mode, **build)
    return Engine(mech, engine.model, mode, engine)


def _run_simulate(engine: Engine, p: dict, t_end, steps, **opts) -> Result:
    if isinstance(engine.state, Simulators):  # the same entry as simulate(), at these values
        engine.mechanism.parameters = p
        return simulate(engine.mechanism, t_end, steps, simulators=engine.state, **opts)
    result = engine.state.run(t_end, steps, **opts)
    compliant_events(result, engine.mechanism)  # as simulate() does
    return result


def _simulate_handling(options: Mapping) -> Handling:
    return simulate_handling(options.get("formulation"), options.get("integrator"),
                             options.get("projection", False), options.get("step"))


def _simulate_outputs(result: Result) -> list[str]:
    return [*_final_q(result), "max_constraint_violation", "energy_drift"]


SIMULATE = Sweepable(
    _build_simulate, _run_simulate, _simulate_outputs, _simulate_handling,
    build_options=("formulation", "inputs", "formulation_options", "redundancy"),
    run_options=("integrator", "rtol", "atol", "t_start", "projection", "step", "max_steps"))


# ---------------------------------------------------------------------- kinematics, inverse
def _build_kinematics(mech: Mechanism, mode: str) -> Engine:
    return Engine(mech, compile_model(mech, "kinematics", mode=mode), mode)


def _run_kinematics(engine: Engine, p: dict, t_end, steps, **opts) -> Result:
    return kinematics(engine.model, t_end=t_end, steps=steps, **opts)


def _kinematics_outputs(result: Result) -> list[str]:
    return [*_final_q(result), "max_constraint_violation"]


def _kinematics_handling(options: Mapping) -> Handling:
    return KINEMATICS_HANDLING


KINEMATICS = Sweepable(_build_kinematics, _run_kinematics, _kinematics_outputs,
                       _kinematics_handling, run_options=("t_start",))


def _build_inverse(mech: Mechanism, mode: str) -> Engine:
    return Engine(mech, compile_model(mech, NEEDS["dynamics"], mode=mode), mode)


def _run_inverse(engine: Engine, p: dict, t_end, steps, **opts) -> Result:
    return inverse_dynamics(engine.model, t_end=t_end, steps=steps, **opts)


def _inverse_outputs(result: Result) -> list[str]:
    return [*_final_q(result), "max_constraint_violation",
            *(f"max_abs:driver_efforts[{d}.effort]" for d in result.names.get("drivers", []))]


def _inverse_handling(options: Mapping) -> Handling:
    return INVERSE_HANDLING


INVERSE = Sweepable(_build_inverse, _run_inverse, _inverse_outputs, _inverse_handling,
                    run_options=("t_start",))


# ---------------------------------------------------------------------- statics
def _build_statics(mech: Mechanism, mode: str) -> Engine:
    system = System(mech)
    model = compile_model(system, STATICS_NEEDS, mode=mode, extra=statics_functions(system))
    # with impact contacts or stops: each point through static_equilibrium of the mechanism
    # itself (the active set of closed gaps, statics.resting)
    return Engine(mech, model, mode, has_events(mech))


def _run_statics(engine: Engine, p: dict, t_end, steps, **opts) -> Result:
    if engine.state:  # resting: the same entry as the statics verb, at these values
        engine.mechanism.parameters = p
        return statics_as_result(static_equilibrium(engine.mechanism, mode=engine.mode,
                                                    **opts))
    return statics_as_result(static_equilibrium(engine.model, **opts))


def _statics_outputs(result: Result) -> list[str]:
    return [*_final_q(result), "residual", "min_stiffness_eigenvalue"]


def _statics_handling(options: Mapping) -> Handling:
    return STATICS_HANDLING


STATICS = Sweepable(
    _build_statics, _run_statics, _statics_outputs, _statics_handling,
    run_options=("t", "method", "tol", "max_iter", "stable"), time_grid=False,
    outputs=("residual", "min_stiffness_eigenvalue"))


def statics_as_result(res) -> Result:
    """A :class:`~casmbd.analysis.statics.report.StaticsResult` as a one-time :class:`Result` (so
    that it is saved, reloaded and reduced like the others)."""
    names = {k: list(v) for k, v in res.names.items()}
    eig = np.asarray(res.eigenvalues, float)
    arrays = {"q": np.asarray(res.q, float)[None, :],
              "lambda": np.asarray(res.lagrange_multipliers, float)[None, :],
              "joint_reactions": np.asarray(res.joint_reactions, float)[None, :, :],
              "potential_energy": np.array([res.potential_energy]),
              "stiffness_eigenvalues": eig[None, :],
              # the bodies' poses, so that body.NAME.… outputs and the absolute-coordinate
              # names q[NAME.x] … read them whatever coordinates were chosen
              "body_positions": np.asarray(res.body_positions, float).reshape(1, -1),
              "marker_positions": np.asarray(res.marker_positions, float).reshape(1, -1)}
    nodes = res.reports.get("nodes", {})  # flexible bodies' named nodes (statics.state_reports)
    for key in ("position", "deflection", "rotation") if nodes else ():
        arrays[f"node_{key}s"] = np.concatenate(
            [np.ravel(node[key]) for node in nodes.values()]).reshape(1, -1)
    if res.contacts:  # closed contacts and stops: their normal forces (0 when open)
        names["contacts"] = list(res.contacts)
        arrays["contact_forces"] = np.array([[c["normal_force"] for c in res.contacts.values()]])
    if len(res.body_quaternions):
        arrays["rotation_matrices"] = _rotation_rows(np.asarray(res.body_quaternions, float))
    else:
        arrays["angle_positions"] = np.asarray(res.body_angles, float)[None, :]
    stats = {**res.stats, "iterations": int(res.iterations), "residual": float(res.residual),
             "stable": res.stable, "method": res.method,
             "min_stiffness_eigenvalue": float(eig.min()) if eig.size else math.nan}
    return Result("statics", np.array([float(res.t)]), arrays, names, stats)


def _rotation_rows(quats: np.ndarray) -> np.ndarray:
    """(1, 9 n) rotation matrices, row by row, of n unit quaternions [w, x, y, z]:
    A = (w² − eᵀe) I + 2 e eᵀ + 2 w ẽ (seed 001, Euler parameters)."""
    w, e = quats[:, 0], quats[:, 1:]
    skew = np.zeros((len(quats), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -e[:, 2], e[:, 1], -e[:, 0]
    skew -= skew.transpose(0, 2, 1)
    mats = ((w**2 - np.sum(e * e, axis=1))[:, None, None] * np.eye(3)
            + 2.0 * e[:, :, None] * e[:, None, :] + 2.0 * w[:, None, None] * skew)
    return mats.reshape(1, -1)
