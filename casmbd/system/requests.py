"""Requests and force-element reports as outputs of a :class:`~casmbd.system.equations.System`.

These groups join the outputs Function (:meth:`casmbd.system.outputs.Outputs.outputs_function`),
so every analysis with a result grid (simulation, kinematics, inverse dynamics) reports them:

* ``outputs`` (n_out): the mechanism's requests (``[[outputs]]``, :class:`casmbd.model.measures.
  Output`), each an expression of measures of (q, v, t, p) resolved with the system's context
  (:func:`casmbd.model.measures.expression`);
* ``force_outputs``: the measures every force element reports by default
  (:meth:`casmbd.model.forces.ForceElement.reports`: a spring's length, rate and force, an
  expression force's value, joint friction's force), in the order of
  :func:`casmbd.model.measures.force_report_names`;
* ``node_positions``, ``node_deflections``, ``node_rotations``: the flexible bodies' named
  nodes, deformed position and deflection relative to the undeformed body frame
  (:func:`node_expressions`).

Their names are the model layer's (:func:`casmbd.model.measures.result_names`), so a model
loaded from the compiled cache, without a System, names its columns the same.  Accelerations
are not measures: a request is a function of the state and time, like Adams' REQUESTs of
displacements, velocities and forces.
"""

from __future__ import annotations

import casadi as ca

from casmbd.errors import ModelError
from casmbd.model.flexible_bodies import named_nodes
from casmbd.model.measures import expression, force_report_names


def _check_inputs(system, expr: ca.SX, where: str) -> None:
    """Refuse an output that depends on symbols other than (q, v, t, p) (actuator inputs, a
    joint reaction), which the outputs Function cannot evaluate."""
    inputs = [system.q, system.v, system.t, system.p]
    try:
        ca.Function("check", inputs, [expr])
    except RuntimeError:
        raise ModelError(f"{where}: depends on quantities other than the state, time and "
                         "parameters (an actuator input or a joint reaction), which cannot "
                         "be reported on a result grid") from None


def request_expressions(system) -> ca.SX:
    """The requests of ``system.mechanism.outputs`` stacked (n_out × 1)."""
    outputs = getattr(system.mechanism, "outputs", {})
    exprs = []
    for name, output in outputs.items():
        where = f"output '{name}' field 'value'"
        expr = ca.SX(expression(system.ctx, output.value, where))
        _check_inputs(system, expr, where)
        exprs.append(expr)
    return ca.vertcat(*exprs) if exprs else ca.SX(0, 1)


def force_report_expressions(system) -> ca.SX:
    """The force elements' reports stacked in the order of
    :func:`~casmbd.model.measures.force_report_names`."""
    mech, kit = system.mechanism, system._force_kit
    exprs = []
    for force in mech.forces.values():
        names = force.report_names(mech.dimension) if hasattr(force, "report_names") else ()
        if not names:
            continue
        values = force.reports(kit)
        if len(values) != len(names):
            raise ModelError(f"force '{force.name}': reports {len(values)} values for "
                             f"{len(names)} names ({', '.join(n for n, _ in names)})")
        for (quantity, _), value in zip(names, values, strict=True):
            value = ca.SX(value)
            _check_inputs(system, value, f"force '{force.name}' report '{quantity}'")
            exprs.append(value)
    assert len(exprs) == len(force_report_names(mech))
    return ca.vertcat(*exprs) if exprs else ca.SX(0, 1)


def node_expressions(system) -> list[tuple[str, ca.SX]]:
    """The named nodes of flexible bodies (:func:`~casmbd.model.flexible_bodies.named_nodes`):
    ``node_positions`` r_i = R + A (u_i0 + Φ_i η) (global, dim per node), ``node_deflections``
    Φ_i η and ``node_rotations`` ψ_i = Ψ_i η (relative to the undeformed body frame, in body
    axes: dim and 1 (plane) or 3 (space) per node); empty without named nodes."""
    mech, ctx = system.mechanism, system.ctx
    positions, deflections, rotations = [], [], []
    for name in named_nodes(mech):
        frame = mech.node_frame(name)
        positions.append(ctx.centre_of_mass(name))
        displacement, rotation = ctx.descriptions[frame.body].node_deflection(
            ctx, frame.body, frame.index)
        deflections.append(displacement)
        rotations.append(rotation)
    if not positions:
        return []
    return [("node_positions", ca.vertcat(*positions)),
            ("node_deflections", ca.vertcat(*deflections)),
            ("node_rotations", ca.vertcat(*rotations))]


def output_groups(system) -> list[tuple[str, ca.SX]]:
    """(name, expression) of the non-empty groups: ``outputs``, ``force_outputs``, and the
    ``node_*`` groups of :func:`node_expressions`."""
    out = []
    requests = request_expressions(system)
    if requests.numel():
        out.append(("outputs", requests))
    reports = force_report_expressions(system)
    if reports.numel():
        out.append(("force_outputs", reports))
    return out + node_expressions(system)
