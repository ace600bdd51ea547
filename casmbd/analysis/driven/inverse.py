"""Inverse dynamics of a kinematically driven mechanism: feedforward efforts and reactions.

Seed 000, "Inverse dynamics": when drivers fix every degree of freedom, the kinematic analysis
gives q, q̇, q̈ on the time grid; the equations of motion M q̈ + C_qᵀ λ = Q_e + Q_v are then
linear in the multipliers alone,

    C_qᵀ λ = Q_e + Q_v − M q̈,

with C_q square and non-singular.  The driver rows of λ give the efforts the drivers must exert
(effort = −λ_d, the generalized force along the driven coordinate, positive in the direction of
increasing coordinate); the joint rows give the reactions (eqs. 6.145–6.151).

Joint friction is part of Q_e (viscous and regularised Coulomb), so the efforts include it.
With reaction-proportional friction (``mu`` > 0) Q_e depends on λ through the transverse
reaction magnitudes N: λ and N are solved together at each time by the fixed point of
:func:`casmbd.analysis.instant.reaction_friction.solve_normals` (relative 1e-12 in N; the iterations
are ``stats["friction_iterations"]``, the largest over the grid).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse.linalg as spla

from casmbd.analysis.driven.kinematics import check_result_size, kinematics
from casmbd.analysis.instant.checks import diagnose
from casmbd.analysis.instant.independent import find_redundant, minimum_norm, scatter
from casmbd.analysis.instant.reaction_friction import has_reaction_friction, solve_normals
from casmbd.analysis.instant.tyre_forces import tyre_forces
from casmbd.analysis.instant.undetermined_reactions import flag_undetermined
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NEEDS, NumericModel
from casmbd.compiled.workspace import Workspace
from casmbd.errors import AnalysisError, ModelError, SingularConfigurationError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.flexible_bodies import rigidified
from casmbd.model.needs import ALL_NEEDS, EVENT_NEEDS, Handling, check
from casmbd.results import Result


def _scatter(values: np.ndarray, rows: list[int], size: int) -> np.ndarray:
    """A vector of ``size`` zeros with ``values`` at ``rows``."""
    out = np.zeros(size)
    out[rows] = values
    return out


def _actuator_efforts(model, grid, qs, vs, acc) -> np.ndarray:
    """Mixed case: the drivers prescribe the motion, the actuators must produce it.

    The driver multipliers are set to zero (the drivers only describe the motion) and the
    actuator inputs u join the unknowns: [C_q,jᵀ  −B] [λ_j; u] = Q_e(u = 0) + Q_v − M q̈,
    B = ∂Q_e/∂u.  Square when there are as many actuators as drivers (the classic robot case);
    otherwise the least-squares solution is returned and its residual checked.  Returns the
    efforts u and the multipliers (driver rows zero) that give the joint reactions of the
    machine driven by its actuators.
    """
    # joints and the bodies' own equations (Euler-parameter normalisation, natural coordinates)
    joint_rows = [i for i, lab in enumerate(model.constraint_labels) if lab.kind != "driver"]
    n_u = model.nu
    out = np.zeros((len(grid), n_u))
    lam = np.zeros((len(grid), model.nc))
    for k, t in enumerate(grid):
        rhs = (model.applied_forces(qs[k], vs[k], t) + model.quadratic_velocity_forces(qs[k], vs[k])
               - model.mass_matrix(qs[k]) @ acc[k])
        cq = model.constraint_jacobian(qs[k], t)[joint_rows, :]
        mat = np.hstack([cq.T.toarray(), -model.input_matrix(qs[k], vs[k], t).toarray()])
        sol, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
        if has_reaction_friction(model):  # λ and the friction together
            sol, normals, _ = solve_normals(
                model, qs[k], vs[k], t, None,
                lambda f, mat=mat, rhs=rhs: np.linalg.lstsq(mat, rhs + f, rcond=None)[0],
                lambda x: _scatter(x[:len(joint_rows)], joint_rows, model.nc),
                f"inverse dynamics at t = {t:g}")
            rhs = rhs + model.sparse("friction_directions", qs[k], vs[k], t,
                                     np.zeros(n_u), model.p) @ normals
        residual = np.max(np.abs(mat @ sol - rhs))
        if residual > 1e-8 * max(1.0, np.max(np.abs(rhs))):
            raise AnalysisError(
                f"inverse dynamics at t = {t:g}: the actuators "
                f"({', '.join(model.mechanism.actuators)}) cannot produce the prescribed "
                f"motion (residual {residual:.3g}); put them on the driven coordinates")
        out[k] = sol[len(joint_rows):]
        lam[k, joint_rows] = sol[:len(joint_rows)]
    return out, lam


#: what inverse dynamics handles (casmbd.model.needs): no event-driven elements
HANDLING = Handling(
    "inverse dynamics", ALL_NEEDS - EVENT_NEEDS,
    why={"events": "it prescribes the motion and does not solve for the impulses and "
                   "forces of impact-model contacts and stops",
         "contact_friction": "it prescribes the motion and does not solve for the forces of "
                             "impact-model contacts",
         "stick_slip": "the exact Coulomb law switches at events, which a prescribed motion "
                       "does not have"},
    instead={"events": "simulate with actuators, or model = 'compliant' (a force inverse "
                       "dynamics includes)",
             "contact_friction": "simulate, or model = 'compliant'",
             "stick_slip": "the regularised law (stick_slip = false), or simulate"},
    notes={"modal_coordinates": "flexible bodies move rigidly (η = 0)",
           "reaction_forces": "λ and the friction levels by a fixed point at each time",
           "velocity_constraints": "−λ of each row of a rolling joint reported as its "
                                   "tyre force (``tyre_forces``, named joint.row: normal "
                                   "load, longitudinal, lateral)"})


def inverse_dynamics(mechanism_or_model, t_end: float, steps: int, t_start: float = 0.0,
                     mode: str = "auto", redundancy: str = "auto", *,
                     data: Workspace | None = None) -> Result:
    """Driver efforts and joint reactions along the motion prescribed by the drivers.

    Redundant constraint equations are removed as in :func:`kinematics` (named in ``stats``):
    C_q of the independent rows is square and regular, λ of the removed rows is zero, and the
    multipliers of the full set are then made minimum-norm (λ − N Nᵀ λ, C_qᵀ N = 0): the
    determined reaction components come out exactly, the others as the minimum-norm
    distribution (``stats["reactions"] == "minimum_norm"``, ``undetermined_reactions``).

    Parameters
    ----------
    mechanism_or_model : Mechanism or NumericModel
        A mechanism whose drivers fix every degree of freedom.
    t_end, steps, t_start : float, int, float
        ``steps + 1`` output times from ``t_start`` to ``t_end`` inclusive.
    redundancy : {"auto", "remove"}
        As :func:`kinematics`.
    data : Workspace, optional
        As :func:`kinematics` (the kinematic pass and the efforts share it).

    Returns
    -------
    Result
        ``kind == "inverse_dynamics"``: the kinematic arrays plus ``lambda``,
        ``driver_efforts`` (n_t × n_drivers), ``joint_reactions`` (n_t × n_joints × 3),
        ``kinetic_energy`` and ``potential_energy``; with rows written at the velocity level
        (rolling without slipping, knife edges) ``tyre_forces`` (n_t × rows, −λ of each row:
        :func:`~casmbd.analysis.instant.tyre_forces.tyre_forces`) named in
        ``names["tyre_forces"]`` as ``"<joint>.<row>"``.

    Raises
    ------
    AnalysisError, RedundantConstraintError, AssemblyError, SingularConfigurationError
        As the kinematic analysis, and when C_qᵀ is singular at some time.
    """
    check(mechanism_or_model, HANDLING)
    if isinstance(steps, (int, np.integer)) and steps >= 1:  # kinematics checks the rest
        check_result_size(mechanism_or_model, steps, "inverse dynamics")
    if isinstance(mechanism_or_model, NumericModel):
        model = mechanism_or_model.with_data(data)  # its own buffers (or those given)
    else:
        # flexible bodies move rigidly: η = 0 (kinematics.py, _model)
        model = compile_model(rigidified(mechanism_or_model), NEEDS["dynamics"], mode=mode)
        model = model if data is None else model.with_data(data)  # raises: another model's
    kin = kinematics(model, t_end, steps, t_start=t_start, redundancy=redundancy,
                     data=model.data)
    t0 = time.perf_counter()
    grid, qs, vs, acc = kin.t, kin["q"], kin["v"], kin["a"]
    n = len(grid)
    plan = find_redundant(model, qs[0], float(grid[0]))  # kinematics' choice
    keep = plan.kept_rows
    lam = np.zeros((n, model.nc))
    kin_e = np.zeros(n)
    pot_e = np.zeros(n)
    friction, iterations = has_reaction_friction(model), 0
    for k, t in enumerate(grid):
        rhs = (model.applied_forces(qs[k], vs[k], t) + model.quadratic_velocity_forces(qs[k], vs[k])
               - model.mass_matrix(qs[k]) @ acc[k])
        if not np.all(np.isfinite(rhs)):  # name the force (element, field) and the time
            raise ModelError(f"inverse dynamics at t = {t:g}: " + "; ".join(
                diagnose(model, t, qs[k], vs[k]) or ["the generalized forces are not finite"]))
        try:
            lu = spla.splu(model.constraint_jacobian(qs[k], t)[keep, :].T.tocsc())
            lam[k] = scatter(lu.solve(rhs), keep, model.nc)
        except RuntimeError as exc:  # SuperLU, or CasADi's Jacobian evaluation
            reraise_interrupt(exc)
            raise SingularConfigurationError(
                f"inverse dynamics at t = {t:g}: the constraint Jacobian is singular") from None
        if friction:  # C_qᵀ λ = Q_e(0) + G N(λ) + Q_v − M q̈ (module docstring)
            lam[k], _, count = solve_normals(
                model, qs[k], vs[k], t, None, lambda f, lu=lu, rhs=rhs: lu.solve(rhs + f),
                lambda x: scatter(x, keep, model.nc), f"inverse dynamics at t = {t:g}")
            iterations = max(iterations, count)
        if plan.removes:  # the least-norm λ of the full set (the drivers' rows included)
            lam[k] = minimum_norm(model.constraint_jacobian(qs[k], t), lam[k])
        kin_e[k] = model.kinetic_energy(qs[k], vs[k])
        pot_e[k] = model.potential_energy(qs[k], t)
    actuators = list(model.mechanism.actuators)
    lam_reac = lam
    if actuators:  # the actuators produce the motion: reactions with their efforts
        u_eff, lam_reac = _actuator_efforts(model, grid, qs, vs, acc)
    else:
        u_eff = np.zeros((n, 0))
    n_j = len(model.mechanism.joints)
    if n_j:
        reac = np.asarray(model.function("joint_reactions").map(n)(
            qs.T, vs.T, acc.T, grid[None, :], u_eff.T, np.tile(model.p[:, None], (1, n)),
            lam_reac.T))
        reactions = reac.reshape(model.reaction_size, n, n_j).transpose(1, 2, 0)
    else:
        reactions = np.zeros((n, 0, model.reaction_size))
    reactions, flags = flag_undetermined(model, qs, vs, acc, grid, u_eff, lam_reac, reactions)
    drivers = list(model.mechanism.drivers)
    efforts = (np.column_stack([-lam[:, model.driver_rows[d]] for d in drivers])
               if drivers else np.zeros((n, 0)))
    arrays = dict(kin.arrays)
    arrays.update({"lambda": lam, "driver_efforts": efforts, "joint_reactions": reactions,
                   "actuator_efforts": u_eff,
                   "kinetic_energy": kin_e, "potential_energy": pot_e,
                   "total_energy": kin_e + pot_e})
    names = dict(kin.names)
    names["drivers"] = drivers
    names["actuators"] = actuators
    if model.velocity_rows:  # rolling and knife-edge rows: their forces, named by row
        arrays["tyre_forces"], names["tyre_forces"] = tyre_forces(model, lam)
    stats = dict(kin.stats)
    stats.update(flags)
    if friction:
        stats["friction_iterations"] = iterations
    stats["solve_seconds"] += time.perf_counter() - t0
    return Result("inverse_dynamics", grid, arrays, names, stats).attach_scene(model.mechanism)
