"""The ``[ocp]`` table of a scene file: an optimal-control problem over the scene.

::

    [ocp]
    horizon = 2.0                 # or { free = true, guess = 1.0, min = 0.1, max = 5.0 }
    intervals = 50
    transcription = "radau"       # "radau" | "legendre" | "multiple_shooting"
    degree = 4                    # collocation degree
    subintervals = 1              # collocation elements per control interval
    dynamics = "implicit"         # collocation: q̈, λ as variables, or "explicit" (trees)
    integrator = "rk4"            # multiple shooting: "rk4" | "cvodes"
    steps = 4                     # RK4 steps per interval
    guess = "linear"              # "linear" | "simulation" | "inverse"
    objective = "effort"          # or ["effort", "time"], or { effort = 1.0, time = 10.0 }
    lagrange = "tip_y**2"         # optional ∫ expression dt
    mayer = "elbow**2"            # optional expression at the final time
    solver = "ipopt"
    [ocp.controls]                # actuator bounds
    tau1 = [-50.0, 50.0]
    [ocp.initial]                 # equalities at t = 0; without this table the scene's
                                  # initial state is imposed, with it (even empty) only these
    shoulder = "-pi/2"
    [ocp.final]
    shoulder = "pi/2"
    [[ocp.path]]                  # min <= expression <= max (or equal = value)
    expression = "tip_y"
    max = 2.5
    at = "all"                    # "all" | "nodes" | "control_nodes"
    [[ocp.tracking]]              # ∫ weight (expression − reference(t))² dt
    expression = "slider_x"
    reference = "0.3 + 0.05*sin(2*pi*t)"
    weight = 1.0
    [ocp.solver_options]
    "ipopt.max_iter" = 500

Names are those of :mod:`casmbd.system.named_quantities`; values may be expressions of the scene's
parameters.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from casmbd.analysis.integrators.kinds import DEFAULT_SHOOTING_INTEGRATOR
from casmbd.errors import CasmbdError, LimitError, SceneError
from casmbd.io.scene import load_scene
from casmbd.model.expressions import evaluate_number
from casmbd.ocp.options import check_solver, check_solver_options
from casmbd.ocp.problem import OBJECTIVES, FreeTime, Ocp

_KEYS = {"horizon", "intervals", "transcription", "degree", "subintervals", "dynamics",
         "integrator",
         "steps", "guess", "objective", "lagrange", "mayer", "solver", "controls", "initial",
         "final", "path", "tracking", "solver_options", "t_start"}


def _number(value, where: str, params: dict) -> float:
    if isinstance(value, bool):
        raise SceneError(f"{where}: expected a number, got {value!r}")
    if isinstance(value, (int, float)):
        out = float(value)
    elif isinstance(value, str):
        out = float(evaluate_number(value, params, where=where))
    else:
        raise SceneError(f"{where}: expected a number or an expression, got {value!r}")
    if math.isnan(out):
        raise SceneError(f"{where}: not a number")
    return out


def ocp_from_scene(mech, table: dict | None = None, source: str = "<scene>") -> Ocp:
    """Build the :class:`~casmbd.ocp.problem.Ocp` of a mechanism's ``[ocp]`` table."""
    table = table if table is not None else getattr(mech, "scene_data", {}).get("ocp")
    if not isinstance(table, dict):
        raise SceneError(f"{source}: no [ocp] table")
    for key in table:
        if key not in _KEYS:
            raise SceneError(f"{source}: [ocp] unknown key '{key}' (allowed: "
                             f"{', '.join(sorted(_KEYS))})")
    params = dict(mech.parameters)

    def num(value, key):
        return _number(value, f"{source}: [ocp] key '{key}'", params)

    horizon = table.get("horizon", 1.0)
    if isinstance(horizon, dict):
        extra = set(horizon) - {"free", "guess", "min", "max"}
        if extra or not horizon.get("free", False):
            raise SceneError(f"{source}: [ocp] key 'horizon': a table needs free = true and "
                             f"optional guess, min, max (got {sorted(horizon)})")
        horizon = FreeTime(num(horizon.get("guess", 1.0), "horizon.guess"),
                           num(horizon.get("min", 1e-3), "horizon.min"),
                           num(horizon.get("max", 1e3), "horizon.max"))
    else:
        horizon = num(horizon, "horizon")
    ints = {}
    for key, default in (("intervals", 50), ("degree", 4), ("subintervals", 1), ("steps", 4)):
        val = table.get(key, default)
        if not isinstance(val, int) or isinstance(val, bool):
            raise SceneError(f"{source}: [ocp] key '{key}': expected an integer, got {val!r}")
        ints[key] = val
    # never code from data: only known solvers and allow-listed options (casmbd.ocp.options)
    solver = check_solver(table.get("solver", "ipopt"), f"{source}: [ocp] key 'solver'",
                          SceneError)
    options = table.get("solver_options", {})
    if not isinstance(options, dict):
        raise SceneError(f"{source}: [ocp] key 'solver_options': expected a table")
    options = check_solver_options(solver, options, f"{source}: [ocp.solver_options]",
                                   SceneError)
    try:
        ocp = Ocp(mech, horizon=horizon, transcription=table.get("transcription", "radau"),
                  integrator=table.get("integrator", DEFAULT_SHOOTING_INTEGRATOR),
                  dynamics=table.get("dynamics", "auto"),
                  t_start=num(table.get("t_start", 0.0), "t_start"),
                  solver=solver, solver_options=options, **ints)
        for key, bounds in table.get("controls", {}).items():
            if not (isinstance(bounds, list) and len(bounds) == 2):
                raise SceneError(f"{source}: [ocp.controls] key '{key}': expected [min, max]")
            ocp.control_bounds(key, num(bounds[0], f"controls.{key}"),
                               num(bounds[1], f"controls.{key}"))
        for which in ("initial", "final"):
            if which not in table:
                continue  # no [ocp.initial]: the scene's initial state is imposed
            values = table[which]
            if not isinstance(values, dict):
                raise SceneError(f"{source}: [ocp] key '{which}': expected a table of values")
            getattr(ocp, which)({k: num(v, f"{which}.{k}") for k, v in values.items()})
        for i, entry in enumerate(table.get("path", [])):
            where = f"[[ocp.path]] entry {i + 1}"
            if not isinstance(entry, dict) or "expression" not in entry:
                raise SceneError(f"{source}: {where}: needs 'expression' and 'min'/'max'/'equal'")
            _known_keys(entry, ("expression", "min", "max", "equal", "at"), f"{source}: {where}")
            if not any(key in entry for key in ("min", "max", "equal")):
                raise SceneError(f"{source}: {where} ({entry['expression']!r}): needs 'min', "
                                 "'max' or 'equal' (without a bound it constrains nothing)")
            if "equal" in entry:
                lo = hi = num(entry["equal"], f"path {i + 1}.equal")
            else:
                lo = num(entry.get("min", -math.inf), f"path {i + 1}.min")
                hi = num(entry.get("max", math.inf), f"path {i + 1}.max")
            ocp.path(entry["expression"], lo, hi, at=entry.get("at", "all"))
        objective = table.get("objective", "effort")
        if isinstance(objective, str):
            objective = {objective: 1.0}
        elif isinstance(objective, list):
            objective = {name: 1.0 for name in objective}
        if not isinstance(objective, dict):
            raise SceneError(f"{source}: [ocp] key 'objective': a name, a list of names or a "
                             f"table of weights ({', '.join(OBJECTIVES)})")
        for name, weight in objective.items():
            ocp.minimize(name, num(weight, f"objective.{name}"))
        for key in ("lagrange", "mayer"):
            if key in table:
                ocp.minimize(key, expression=table[key])
        for i, entry in enumerate(table.get("tracking", [])):
            if not isinstance(entry, dict) or "expression" not in entry:
                raise SceneError(f"{source}: [[ocp.tracking]] entry {i + 1}: needs "
                                 "'expression' and 'reference'")
            _known_keys(entry, ("expression", "reference", "weight"),
                        f"{source}: [[ocp.tracking]] entry {i + 1}")
            ocp.minimize("tracking", num(entry.get("weight", 1.0), f"tracking {i + 1}.weight"),
                         expression=entry["expression"], reference=entry.get("reference", 0.0))
        ocp.guess(table.get("guess", "linear"))
    except SceneError:
        raise
    except LimitError as exc:  # keeps its class: a size limit, not a malformed table
        raise LimitError(f"{source}: [ocp]: {exc}") from None
    except CasmbdError as exc:
        raise SceneError(f"{source}: [ocp]: {exc}") from None
    return ocp


def _known_keys(entry: dict, allowed: tuple[str, ...], where: str) -> None:
    """Refuse a key of an ``[[ocp.path]]``/``[[ocp.tracking]]`` entry that is not ``allowed``
    (a misspelt ``maximum = 1`` used to leave the constraint without its bound, silently)."""
    for key in entry:
        if key not in allowed:
            raise SceneError(f"{where}: unknown key '{key}' (known: {', '.join(allowed)})")


def load_ocp(path: str | os.PathLike) -> Ocp:
    """The scene of ``path`` and its ``[ocp]`` table as an :class:`~casmbd.ocp.problem.Ocp`."""
    mech = load_scene(path)
    return ocp_from_scene(mech, source=str(Path(path)))
