"""The analysis verbs: ``kinematics``, ``simulate``, ``inverse``, ``statics`` and ``linearize``
(one scene in, a summary or one JSON object out; ``info`` is in :mod:`casmbd.cli.info`).
"""

from __future__ import annotations

from casmbd.analysis.driven.inverse import inverse_dynamics
from casmbd.analysis.driven.kinematics import kinematics
from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.statics.linearize import linearize
from casmbd.analysis.statics.statics import static_equilibrium
from casmbd.cli.common import (
    load_scene_for,
    range_line,
    save_result,
    state_lines,
    summary_table,
    timing_line,
)
from casmbd.errors import AnalysisError, IntegratorError
from casmbd.io.scene import load_result
from casmbd.limits import check_steps
from casmbd.viz.column_units import effort_units, energy_terms, joint_coordinate_unit


def _redundancy_lines(s: dict) -> list[str]:
    """The removed redundant equations and the reaction components they leave undetermined."""
    lines = []
    if s.get("redundant_equations"):
        lines.append(f"  redundant equations ({s['redundancy']}): "
                     + ", ".join(s["redundant_equations"]))
    if s.get("undetermined_reactions"):
        lines.append("  undetermined reaction components (minimum-norm distribution): "
                     + ", ".join(f"{j} {c}" for j, c in s["undetermined_reactions"].items()))
    return lines


def _check_memory(args, mech, what: str) -> None:
    """The memory guard with what the command line adds to a result: its ``to_json`` objects
    and, with ``--json``, the JSON text (:func:`casmbd.limits.memory_per_time`); before any
    build, one estimate for the refusal and its advice."""
    if isinstance(args.steps, int) and args.steps >= 1:
        check_steps(what, args.steps, mech, output="json" if args.json else "cli")


def _cmd_kinematics(args) -> tuple[dict, str]:
    mech = load_scene_for(args)
    _check_memory(args, mech, "kinematics")
    result = kinematics(mech, t_end=args.t_end, steps=args.steps, mode=args.mode,
                        redundancy=args.redundancy)
    result.scene = getattr(mech, "scene_text", "")
    if args.out:
        save_result(result, args.out)
    data = result.to_json()
    s = result.stats
    lines = [f"kinematics of '{mech.name}': {len(result.t)} times from {result.t[0]:g} to "
             f"{result.t[-1]:g} s",
             *summary_table(result, mech),
             f"  max constraint violation {data['constraint_violation']:.3g}",
             *_redundancy_lines(s), timing_line(s)]
    if args.out:
        lines.append(f"  saved {args.out}")
    return data, "\n".join(lines)


def _cmd_simulate(args) -> tuple[dict, str]:
    mech = load_scene_for(args)
    _check_memory(args, mech, "simulation")
    try:
        result = simulate(mech, t_end=args.t_end, steps=args.steps, formulation=args.formulation,
                          integrator=args.integrator, rtol=args.rtol, atol=args.atol,
                          projection=args.projection, step=args.step, mode=args.mode,
                          max_steps=args.max_steps, redundancy=args.redundancy,
                          max_events=args.max_events, rest_velocity=args.rest_velocity)
    except IntegratorError as exc:
        if args.out and exc.partial is not None:
            exc.partial.scene = getattr(mech, "scene_text", "")
            exc.partial.stats["failure"] = str(exc)
            save_result(exc.partial, args.out)
            raise IntegratorError(f"{exc} (partial results saved to {args.out})", exc.time,
                                  exc.flag, exc.partial) from None
        raise
    result.scene = getattr(mech, "scene_text", "")
    if args.out:
        save_result(result, args.out)
    data = result.to_json()
    s = result.stats
    energy = result["total_energy"]
    lines = [f"simulation of '{mech.name}': {len(result.t)} times from {result.t[0]:g} to "
             f"{result.t[-1]:g} s, {s['formulation']} on {s['integrator']}",
             *summary_table(result, mech),
             f"  energy: start {energy[0]:.6g} J, end {energy[-1]:.6g} J "
             f"({_energy_change(result, mech)})",
             f"  max constraint violation: position {data['constraint_violation']:.3g}, "
             f"velocity {data['velocity_violation']:.3g}",
             *([_events_line(result)] if result.events else []),
             f"  steps {s.get('steps', 0)}, rhs evaluations {s.get('rhs_evaluations', 0)}",
             timing_line(s, 4)]
    if s.get("start_position_change", 0) > 1e-12 or s.get("start_velocity_change", 0) > 1e-12:
        lines.append(f"  consistent start changed q by {s['start_position_change']:.3g} and v by "
                     f"{s['start_velocity_change']:.3g}")
    lines += _redundancy_lines(s)
    if s.get("near_singular_times"):
        times = s["near_singular_times"]
        lines.append(f"  passed {len(times)} near-singular poses (conditioning < 1e-4) at t ≈ "
                     + ", ".join(f"{t:.4g}" for t in times[:8]) + (" …" if len(times) > 8
                                                                     else ""))
    if args.out:
        lines.append(f"  saved {args.out}")
    return data, "\n".join(lines)


def _events_line(result) -> str:
    """How many events of each kind, and the first and last times."""
    counts: dict[str, int] = {}
    for event in result.events:
        counts[event["kind"]] = counts.get(event["kind"], 0) + 1
    times = [e["time"] for e in result.events]
    return (f"  events: {', '.join(f'{n} {k}' for k, n in counts.items())} (t = "
            f"{min(times):.6g} … {max(times):.6g} s; the list: --json 'events')")


def _energy_change(result, mech) -> str:
    """total − total(0): "drift" for a conservative mechanism, else what changes it (work of
    dampers, drivers, actuators and forces, friction work, impact losses; not a conservation
    error), the phrases of the plots' energy panel
    (:func:`casmbd.viz.column_units.energy_terms`)."""
    energy = result["total_energy"]
    delta = f"{energy[-1] - energy[0]:+.3g} J"
    terms = energy_terms(result, mech)
    if terms == []:
        return f"drift {delta}"
    if terms is None:
        return f"change {delta}; numerical drift only if nothing does work"
    return f"change {delta}: {', '.join(terms)}, not numerical drift"


def _cmd_inverse(args) -> tuple[dict, str]:
    mech = load_scene_for(args)
    _check_memory(args, mech, "inverse dynamics")
    result = inverse_dynamics(mech, t_end=args.t_end, steps=args.steps, mode=args.mode,
                              redundancy=args.redundancy)
    result.scene = getattr(mech, "scene_text", "")
    if args.out:
        save_result(result, args.out)
    data = result.to_json()
    lines = [f"inverse dynamics of '{mech.name}': {len(result.t)} times from {result.t[0]:g} "
             f"to {result.t[-1]:g} s", *summary_table(result, mech)]
    for group, key, width in (("drivers", "driver_efforts", 12),
                              ("actuators", "actuator_efforts", 10)):
        units = effort_units(result, group, mech)
        for k, name in enumerate(result.names.get(group, [])):
            eff = result[key][:, k]
            lines.append(f"  {group[:-1]} {name:<{width}} {range_line('effort', eff, units[k])}")
    s = result.stats
    lines += _redundancy_lines(s)
    lines.append(timing_line(s))
    if args.out:
        lines.append(f"  saved {args.out}")
    return data, "\n".join(lines)


def _cmd_statics(args) -> tuple[dict, str]:
    mech = load_scene_for(args)
    result = static_equilibrium(mech, method=args.method, mode=args.mode,
                                redundancy=args.redundancy,
                                stable=getattr(args, "stable", False))
    data = result.to_json()
    stable = {True: "stable", False: "unstable", None: "neutral"}[result.stable]
    if result.stability is not None and result.stability.null_directions:
        stable += f" (null directions: {', '.join(result.stability.null_coordinates())})"
    search = ("a stable one asked for" if result.search == "stable"
              else "the nearest to the initial configuration")
    lines = [f"static equilibrium of '{mech.name}' ({search}; {result.method} Newton, "
             f"{result.iterations} iterations, residual {result.residual:.3g}): {stable}"]
    lines += [f"  note: {note}" for note in result.notes]
    for name, b in data["bodies"].items():
        pos = "  ".join(f"{axis} {x:+.6g} m" for axis, x in zip("xyz", b["position"]))
        if "quaternion" in b:
            orient = "quaternion [" + ", ".join(f"{x:+.6f}" for x in b["quaternion"]) + "]"
        else:
            orient = f"angle {b['angle']:+.6g} rad"
        lines.append(f"  body {name:<14} {pos}  {orient}")
    labels = ("Fx", "Fy", "M") if len(mech.gravity) == 2 else ("Fx", "Fy", "Fz", "Mx", "My",
                                                               "Mz")
    for name, j in data["joints"].items():
        coords = "".join(
            f"{key} {j[key]:+.6g} "
            f"{joint_coordinate_unit(mech, name, None if key == 'coordinate' else key)}  "
            for key in j if key != "reaction")
        reaction = "  ".join(f"{label} {x + 0.0:+.6g} {'N' if label[0] == 'F' else 'N m'}"
                             for label, x in zip(labels, j["reaction"]))  # no "-0"
        lines.append(f"  joint {name:<13} {coords}reaction {reaction}")
    lines += state_lines(data.get("summary", {}))  # requests and nodes at the equilibrium
    eig = ", ".join(f"{e:.4g}" for e in result.eigenvalues) or "none (no degrees of freedom)"
    lines.append(f"  stiffness eigenvalues: {eig}")
    s = result.stats
    lines += _redundancy_lines(s)
    lines.append(timing_line(s))
    return data, "\n".join(lines)


def _steady_motion(mech, args) -> tuple[dict, str]:
    """``linearize --steady-motion``: the eigenvalues of the reduced system, the modes named
    by the remaining coordinates."""
    lin = linearize(mech, mode=args.mode, steady_motion=True)
    data = lin.to_json()
    s = lin.stats
    lines = [f"linearization of '{mech.name}' about the steady motion from its initial state: "
             f"cyclic {', '.join(lin.cyclic) or 'none'}; symmetries "
             f"{', '.join(lin.symmetries) or 'none'}; {s['reduced_dimension']} states remain "
             f"({'stable' if lin.stable else 'unstable'})"]
    for mode in lin.modes:
        re, im = mode["eigenvalue"]
        lines.append(f"  eigenvalue {re:+.10g} {im:+.10g}i   mode {mode['coordinate']}")
    lines.append(timing_line(s))
    return data, "\n".join(lines)


def _cmd_linearize(args) -> tuple[dict, str]:
    """Linearize about the initial configuration at rest, the static equilibrium
    (``--at-equilibrium``) or a stored state (``--from RESULT.npz --time T``).

    The verdict is the statics verb's (one classification of the reduced stiffness); about a
    state that is not an equilibrium there is none (the matrices are still the first-order
    expansion there).
    """
    if (args.time is None) != (args.from_result is None):
        raise AnalysisError("linearize: --from RESULT.npz and --time T go together")
    if getattr(args, "stable", False) and not args.at_equilibrium:
        raise AnalysisError("linearize: --stable goes with --at-equilibrium")
    mech = load_scene_for(args)
    if getattr(args, "steady_motion", False):
        return _steady_motion(mech, args)
    if args.at_equilibrium:
        lin = linearize(mech, mode=args.mode, at="equilibrium", redundancy=args.redundancy,
                        stable=getattr(args, "stable", False))
        where = (f"the static equilibrium ({lin.stats['statics_iterations']} statics "
                 f"iterations, residual {lin.stats['statics_residual']:.3g})")
    elif args.from_result is not None:
        result = load_result(args.from_result)
        try:
            lin = linearize(mech, mode=args.mode, at=result, at_time=args.time,
                            redundancy=args.redundancy)
        except AnalysisError as exc:  # name the result file and the scene (issue 31)
            text = str(exc)
            if not text.startswith("linearize: the result"):
                raise
            raise AnalysisError(f"linearize: result file '{args.from_result}'" + text[len(
                                    "linearize: the result"):].replace(
                                    "this scene", f"scene '{args.scene}' ('{mech.name}')", 1)
                                ) from None
        where = (f"the state of '{args.from_result}' at t = {lin.t:.6g} (output "
                 f"{lin.stats['state_index']}, nearest to {args.time:g})")
    else:
        lin = linearize(mech, mode=args.mode, redundancy=args.redundancy)
        where = "the initial configuration (v = 0)"
    data = lin.to_json()
    s = lin.stats
    verdict = lin.verdict
    if lin.stability is not None and lin.stability.null_directions:
        verdict += f" (null directions: {', '.join(lin.stability.null_coordinates())})"
    lines = [f"linearization of '{mech.name}' about {where}: "
             f"{lin.n_dof} degree{'' if lin.n_dof == 1 else 's'} of freedom, {verdict}"]
    for k, (fn, fd, z) in enumerate(zip(lin.natural_frequencies_hz,
                                        lin.damped_frequencies_hz, lin.damping_ratios)):
        lines.append(f"  mode {k + 1:<3} natural frequency {fn:.6g} Hz  damped frequency "
                     f"{fd:.6g} Hz  damping ratio {z + 0.0:.4g}")  # no "-0"
    lines += state_lines(data.get("summary", {}))  # requests and nodes at that state
    if lin.stability is not None:
        eig = ", ".join(f"{e:.4g}" for e in lin.stability.eigenvalues)
        lines.append(f"  stiffness eigenvalues: {eig or 'none (no degrees of freedom)'}")
    else:
        lines.append(f"  not an equilibrium ({lin.why_not_equilibrium()}): no stability "
                     "verdict, the modes describe perturbations about this state only; "
                     "--at-equilibrium linearizes at the static equilibrium")
    lines += _redundancy_lines(s)
    lines.append(timing_line(s))
    return data, "\n".join(lines)

