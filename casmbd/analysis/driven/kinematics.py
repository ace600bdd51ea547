"""Kinematic analysis of a kinematically driven mechanism over a time grid.

With drivers for every degree of freedom, C(q, t) = 0 determines q(t); at each time the
positions are found by Newton-Raphson from a second-order prediction, the velocities from
C_q q̇ = −C_t and the accelerations from C_q q̈ = γ (seed 000, "Inverse dynamics": the
kinematic analysis that precedes the computation of driving forces).
"""

from __future__ import annotations

import time

import numpy as np

from casmbd.analysis.driven.orientation_start import check_half_turns
from casmbd.analysis.formulations import FORMULATIONS, default_formulation
from casmbd.analysis.instant.assembly import accelerations, assemble, velocities
from casmbd.analysis.instant.independent import (
    IndependentRows,
    check_option,
    check_removed,
    find_redundant,
)
from casmbd.analysis.instant.redundancy import rank_report
from casmbd.analysis.integrators.kinds import INTEGRATORS
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NumericModel
from casmbd.compiled.workspace import Workspace
from casmbd.errors import AnalysisError, AssemblyError, CasmbdError, RedundantConstraintError
from casmbd.lazy import lazy_module
from casmbd.limits import check_steps
from casmbd.model.flexible_bodies import rigidified
from casmbd.model.measures import result_names
from casmbd.model.needs import ALL_NEEDS, Handling, check
from casmbd.results import Result

scipy_integrate = lazy_module("scipy.integrate")


def _model(mechanism_or_model, analysis: str, mode: str, rigid: bool = True,
           data: Workspace | None = None) -> NumericModel:
    """The numeric model of a mechanism (with ``rigid``, its flexible bodies rigidified:
    kinematics prescribes the rigid motion, :func:`casmbd.model.flexible_bodies.rigidified`)
    or the model given, evaluating through ``data`` (default: a workspace of its own, so that
    the run shares no buffers with other users of the model)."""
    if isinstance(mechanism_or_model, NumericModel):
        return mechanism_or_model.with_data(data)
    mech = rigidified(mechanism_or_model) if rigid else mechanism_or_model
    model = compile_model(mech, analysis, mode=mode)  # its own: its data is the run's
    return model if data is None else model.with_data(data)  # raises: another model's


def check_result_size(mechanism_or_model, steps: int, what: str) -> None:
    """Refuse (:class:`~casmbd.errors.LimitError`) a time grid of ``steps`` intervals whose
    result would not fit the memory budget of :mod:`casmbd.limits`, before anything is built:
    the bytes per output time from the element counts (:func:`casmbd.limits.memory_per_time`
    of :func:`casmbd.limits.result_counts`), the same for a mechanism and its model."""
    mech = mechanism_or_model.mechanism if isinstance(mechanism_or_model, NumericModel) \
        else mechanism_or_model
    check_steps(what, int(steps), mech)


def dependent_equations(model: NumericModel, q: np.ndarray, t: float) -> list[dict]:
    """Rows of C_q that depend on earlier rows, as ``{"kind", "joint", "equation"}`` dicts."""
    labels = model.constraint_labels
    rep = rank_report(model.constraint_jacobian(q, t))
    return [{"kind": labels[i].kind, "joint": labels[i].element, "equation": labels[i].label}
            for i in rep.dependent_rows]


def check_rank(model: NumericModel, q: np.ndarray, t: float):
    """Raise :class:`RedundantConstraintError` naming the dependent equations, if any."""
    rep = rank_report(model.constraint_jacobian(q, t))
    if rep.dependent_rows:
        labels = model.constraint_labels
        dep = [(labels[i].element, labels[i].label) for i in rep.dependent_rows]
        joints = sorted({labels[i].element for i in rep.dependent_rows})
        text = ", ".join(f"{labels[i]}" for i in rep.dependent_rows)
        raise RedundantConstraintError(
            f"the constraint Jacobian is rank deficient at t = {t:g} (rank {rep.rank} of "
            f"{rep.n_equations} equations): dependent equations of {', '.join(joints)}: {text}",
            dep)
    return rep


def info(mechanism_or_model, mode: str = "auto", *, data: Workspace | None = None) -> dict:
    """Coordinates, constraints, degrees of freedom and dependent equations of a mechanism.

    ``degrees_of_freedom`` is n_q − rank C_q over every row: the free velocities.  With rows
    written at the velocity level (rolling without slipping) ``velocity_rows`` names them and
    ``configuration_degrees_of_freedom`` = n_q − rank of the position rows counts the
    configuration's freedoms, more than the velocities' (a wheel at rest on a plane can be
    put anywhere, but rolls only where it points).

    The rank is evaluated at the assembled initial configuration.  If the mechanism cannot
    be assembled, ``"assembled"`` is False, ``"assembly_error"`` says why (most likely culprit
    first) and ``"assembly_culprits"`` ranks the elements (dicts of
    :class:`~casmbd.analysis.instant.culprits.Culprit`); the rank and degrees of freedom are then
    those at the initial guess and ``"rank_reliable"`` is False, and the redundancy analysis is
    skipped (``"redundant_equations"`` empty): at a pose that violates the constraints a
    contradicting element would look "redundant".  Never raises for redundancy or assembly
    (the CLI turns a failed assembly into a non-zero exit status).
    ``mode="auto"`` runs C and C_q on CasADi's virtual machine: info evaluates them a handful
    of times, and compiling them costs far more (25 s for a 500-body chain) than it saves.
    """
    # the mechanism as it moves: a flexible body's modes are degrees of freedom here
    model = _model(mechanism_or_model, "info", "vm" if mode == "auto" else mode, rigid=False,
                   data=data)
    mech = model.mechanism
    q = model.initial_coordinates()
    out: dict = {"name": mech.name, "dimension": mech.dimension}
    try:
        q = assemble(model, q, 0.0).q
        out["assembled"] = True
    except AssemblyError as exc:
        out["assembled"] = False
        out["assembly_error"] = str(exc)
        out["assembly_culprits"] = [c.to_dict() for c in exc.culprits]
    out["rank_reliable"] = out["assembled"]
    rep = rank_report(model.constraint_jacobian(q, 0.0))
    dependent = rep.dependent_rows if out["assembled"] else []
    labels = model.constraint_labels
    out.update({
        "bodies": list(mech.bodies), "joints": list(mech.joints), "drivers": list(mech.drivers),
        "forces": list(mech.forces), "actuators": list(mech.actuators),
        "markers": list(mech.markers), "parameters": model.parameters,
        "coordinates": model.coordinate_names,
        "coordinate_choice": model.system.coordinates,
        "coordinate_reason": model.system.coordinate_reason,
        "constraints": [{"kind": lab.kind, "joint": lab.element, "equation": lab.label}
                        for lab in labels],
        "n_coordinates": model.nq, "n_constraints": model.nc, "rank": rep.rank,
        "degrees_of_freedom": rep.degrees_of_freedom,
        "redundant_equations": [{"kind": labels[i].kind, "joint": labels[i].element,
                                 "equation": labels[i].label} for i in dependent],
        "initial_coordinates": q.tolist(),
        "stats": model.report_dict,
        **default_path(model.system),
    })
    if model.velocity_rows:  # non-holonomic: fewer velocities than configuration freedoms
        hol = model.holonomic_rows
        jac = model.constraint_jacobian(q, 0.0)
        out["velocity_rows"] = [f"{labels[i].element}.{labels[i].label}"
                                for i in model.velocity_rows]
        out["configuration_degrees_of_freedom"] = \
            model.nq - (rank_report(jac[hol, :]).rank if hol else 0)
    return out


def default_path(system) -> dict:
    """What ``simulate`` does when nothing is chosen: the formulation and integrator it takes
    for ``system`` and why (the coordinates are the system's own, :mod:`casmbd.system.choice`)."""
    name = default_formulation(system)
    kind = FORMULATIONS[name]
    why = ("a tree in joint coordinates: the articulated-body recursion (O(N))"
           if name == "articulated" else
           f"{system.nc} constraint equations: the default for constrained systems (stays on "
           "its branch at singular poses, keeps redundant equations)")
    integ = INTEGRATORS[kind.default_integrator]
    stiff = integ.stiff_alternative
    how = f"{kind.default_integrator} ({integ.label})" + (
        f"; {stiff} ({INTEGRATORS[stiff].label}) instead when the start is stiff" if stiff
        else "")
    return {"default_formulation": name, "formulation_reason": why,
            "default_integrator": kind.default_integrator, "integrator_reason": how}


#: relative and absolute tolerance of the integration of q̇ = v(q, t) between output times
#: of a mechanism with rows written at the velocity level (DOP853)
CARRY_RTOL = 1e-12


def carried_positions(model, q: np.ndarray, t0: float, t1: float, tol: float) -> np.ndarray:
    """q at ``t1`` from q at ``t0`` by integrating q̇ = v(q, t), the velocities of the driven
    mechanism (C_q v = −C_t over every row, the velocity-level ones included).

    With rows A(q) v + b = 0 written at the velocity level (rolling without slipping, a knife
    edge) the position equations leave n − m_h coordinates open and the path decides them:
    a disc driven along a closed curve ends displaced.  The velocity analysis is regular
    (C_q square of full rank), so q̇ = v(q, t) is an ODE, integrated by DOP853 (Hairer,
    Nørsett & Wanner, *Solving ODEs I*, II.5) to :data:`CARRY_RTOL`; the caller then
    assembles the holonomic rows from this guess (a minimum-norm correction of its drift).
    """
    def rates(t, y):
        return velocities(model, y, t)
    sol = scipy_integrate.solve_ivp(rates, (float(t0), float(t1)), np.asarray(q, float),
                              method="DOP853", rtol=CARRY_RTOL,
                              atol=max(CARRY_RTOL, tol))
    if not sol.success:
        raise AnalysisError(f"kinematics at t = {t1:g}: the integration of q̇ = v(q, t) of "
                            f"the velocity-level rows failed ({sol.message})")
    return sol.y[:, -1]


#: what the kinematic analysis handles (casmbd.model.needs): every need but impacts
HANDLING = Handling(
    "kinematics", ALL_NEEDS - {"events"},
    why={"events": "it prescribes the motion by drivers and neither detects contact nor "
                   "applies impacts"},
    instead={"events": "simulate (the event-driven run), or model = 'compliant' (a force)"},
    notes={"modal_coordinates": "flexible bodies move rigidly (η = 0)",
           "reaction_forces": "forces do not enter the kinematic analysis",
           "stick_slip": "forces do not enter the kinematic analysis",
           "contact_friction": "forces do not enter the kinematic analysis",
           "inputs": "forces do not enter the kinematic analysis",
           "velocity_constraints": "its rows count as velocity equations (a driver for "
                                   "every degree of freedom of the velocities); the "
                                   "positions they leave open follow from q̇ = v(q, t), "
                                   "integrated between output times (DOP853, 1e-12)"})


def kinematics(mechanism_or_model, t_end: float, steps: int, t_start: float = 0.0,
               mode: str = "auto", tol: float = 1e-12, redundancy: str = "auto", *,
               data: Workspace | None = None) -> Result:
    """Positions, velocities and accelerations of a fully driven mechanism on a time grid.

    Redundant constraint equations (rows of C_q that depend on earlier ones at the assembled
    start, in declaration order, as :func:`info` finds them) are removed and the analysis runs
    on the independent rows (:mod:`casmbd.analysis.instant.independent`); ``stats`` name them
    (``redundant_equations``, ``redundancy``, ``constraint_rank``) and
    ``constraint_violation`` is that of every equation.

    Parameters
    ----------
    mechanism_or_model : Mechanism or NumericModel
    t_end : float
        Final time; the grid has ``steps + 1`` points from ``t_start`` to ``t_end`` inclusive.
    steps : int
        Number of intervals (>= 1).
    mode : str
        Compilation mode of the equations ("auto", "compiled", "vm").
    redundancy : {"auto", "remove"}
        Both remove the redundant equations ("minimum_norm" is simulate's and is refused).
    data : Workspace, optional
        The buffers the run evaluates in (``model.workspace()`` of the NumericModel given);
        default: a workspace of its own.

    Raises
    ------
    LimitError
        When ``steps`` exceeds :data:`casmbd.limits.MAX_STEPS` or the result would not fit
        the memory budget (checked before anything is built).
    AnalysisError
        When the drivers leave degrees of freedom free.
    RedundantConstraintError
        When an equation removed as redundant at the start is violated later (it was not a
        consequence of the others: e.g. two contradicting drivers that agree at the start).
    AssemblyError, SingularConfigurationError
        When a position cannot be found or C_q becomes singular (with the time).
    """
    if not (isinstance(steps, (int, np.integer)) and steps >= 1):
        raise AnalysisError(f"steps must be an integer >= 1, got {steps!r}")
    if not (np.isfinite(t_end) and np.isfinite(t_start) and t_end > t_start):
        raise AnalysisError(f"t_end must be finite and > t_start = {t_start}, got {t_end!r}")
    check(mechanism_or_model, HANDLING)
    check_option(redundancy, "kinematics")
    check_result_size(mechanism_or_model, steps, "kinematics")
    full = _model(mechanism_or_model, "kinematics", mode, data=data)
    mech = full.mechanism
    t0 = time.perf_counter()
    grid = np.linspace(t_start, t_end, int(steps) + 1)
    q = assemble(full, full.initial_coordinates(), grid[0], tol=tol).q
    check_half_turns(full, q, grid[0])  # orientation drivers: not half a turn away
    plan = find_redundant(full, q, grid[0])
    model = IndependentRows(full, plan.kept_rows) if plan.removes else full
    rep = check_rank(model, q, grid[0])
    if rep.degrees_of_freedom > 0:
        raise AnalysisError(
            f"kinematic analysis needs a driver for every degree of freedom: mechanism "
            f"'{mech.name}' has {rep.degrees_of_freedom} free degree(s) of freedom "
            f"({model.nq} coordinates, {rep.rank} independent constraints)")
    n = len(grid)
    qs, vs, as_ = (np.zeros((n, model.nq)) for _ in range(3))
    violation = np.zeros(n)
    newton = 0
    v = a = np.zeros(model.nq)
    for k, t in enumerate(grid):
        if k > 0:
            h = t - grid[k - 1]
            guess = q + h * v + 0.5 * h * h * a
            try:
                if model.velocity_rows:  # positions the path decides: q̇ = v(q, t)
                    guess = carried_positions(model, q, grid[k - 1], t, tol)
                res = assemble(model, guess, t, tol=tol)
            except CasmbdError as exc:
                message = str(exc)  # an AssemblyError ranks its culprits here
                wrapped = type(exc)(message if f"at t = {t:g}" in message
                                    else f"kinematics at t = {t:g}: {message}")
                wrapped.__dict__.update(exc.__dict__)  # culprits, dependent equations, …
                raise wrapped from None
            q = res.q
            newton += res.iterations
        v = velocities(model, q, t)
        a = accelerations(model, q, v, t)
        qs[k], vs[k], as_[k] = q, v, a
        violation[k] = float(np.max(np.abs(full.constraints(q, t)))) if full.nc else 0.0
        check_removed(full, plan, q, float(t), "kinematics")
    solve_seconds = time.perf_counter() - t0
    outputs = model.outputs(qs, vs, as_, grid)
    names = {"coordinates": model.coordinate_names, "bodies": model.body_names,
             "markers": list(mech.markers), "joints": model.joint_coordinate_names,
             "all_joints": list(mech.joints), **result_names(mech)}  # requests, forces
    stats = {"solve_seconds": solve_seconds, "newton_iterations": newton, "steps": int(steps),
             **plan.stats(), **model.report_dict}
    return Result("kinematics", grid, {"q": qs, "v": vs, "a": as_, **outputs,
                                       "constraint_violation": violation}, names,
                  stats).attach_scene(mech)
