"""The ``info`` verb: coordinates, constraints, degrees of freedom, dependent equations (a
module of its own so that ``casmbd info`` loads only what it needs).
"""

from __future__ import annotations

from casmbd.analysis.driven.kinematics import info
from casmbd.cli.common import load_scene_for
from casmbd.errors import AssemblyError


def _cmd_info(args) -> tuple[dict, str]:
    mech = load_scene_for(args)
    data = info(mech, mode=args.mode)
    data.setdefault("coordinate_choice", mech.coordinates)
    kind = "planar" if data.get("dimension", 2) == 2 else "spatial"
    n_body_rows = sum(1 for row in data["constraints"] if row["kind"] == "body")
    body_rows = f" ({n_body_rows} of the bodies' own)" if n_body_rows else ""
    lines = [f"mechanism '{data['name']}' ({kind}, {len(data['bodies'])} bodies, "
             f"{data['coordinate_choice']} coordinates)",
             f"  coordinates ({data['n_coordinates']}): {', '.join(data['coordinates'])}",
             f"  coordinate choice: {data.get('coordinate_reason', 'given')}",
             f"  simulate by default: {data['default_formulation']} "
             f"({data['formulation_reason']}), integrator {data['integrator_reason']}",
             f"  constraints: {data['n_constraints']} equations{body_rows}, "
             f"rank {data['rank']}",
             f"  degrees of freedom: {data['degrees_of_freedom']}"
             + (f" (velocities; {data['configuration_degrees_of_freedom']} of the "
                f"configuration: rows at the velocity level "
                f"{', '.join(data['velocity_rows'])})" if data.get("velocity_rows") else "")]
    if not data["assembled"]:
        lines[-2] += " (at the initial guess: not assembled)"
        lines.append("  redundant equations: not analysed (not assembled)")
    elif data["redundant_equations"]:
        lines.append("  redundant equations: " + ", ".join(
            f"{d['joint']}.{d['equation']}" for d in data["redundant_equations"])
            + " (every analysis removes them and names them; the reactions they leave "
              "undetermined are the minimum-norm ones)")
    else:
        lines.append("  redundant equations: none")
    if not data["assembled"]:
        # the summary (or the one JSON object) on stdout, the culprit on stderr, exit 1
        exc = AssemblyError(f"mechanism '{data['name']}' cannot be assembled — "
                            f"{data['assembly_error']}", data.get("assembly_culprits"))
        exc.cli_output = (data, "\n".join(lines))  # printed by casmbd.cli.main
        raise exc
    return data, "\n".join(lines)
