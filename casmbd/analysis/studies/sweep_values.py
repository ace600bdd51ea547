"""Points and outputs of a parameter sweep: ``--param`` values, the grid or list of points,
and the named scalar outputs ``"REDUCTION:COLUMN"`` evaluated on each point's result
(:mod:`casmbd.analysis.studies.sweep`).
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from casmbd.errors import AnalysisError, CasmbdError
from casmbd.limits import MAX_SWEEP_POINTS, check_count
from casmbd.results import Result

#: reductions of a named output ``"REDUCTION:COLUMN"`` over the time grid
REDUCTIONS = {"initial": lambda x: x[0], "final": lambda x: x[-1], "min": np.min,
              "max": np.max, "mean": np.mean, "max_abs": lambda x: np.max(np.abs(x)),
              "range": lambda x: np.max(x) - np.min(x)}
#: named outputs without a reduction
SPECIAL_OUTPUTS = ("energy_drift", "max_constraint_violation")


# ====================================================================== point values
def parse_values(text: str) -> tuple[str, list[float]]:
    """``name=a:b:n`` (n values from a to b inclusive, ``numpy.linspace``), ``name=a,b,c`` or
    ``name=a`` -> ``(name, values)`` (the CLI's ``--param``).

    Raises
    ------
    AnalysisError
        Naming the text when it is not of one of these forms.
    """
    name, sep, rhs = text.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier() or not rhs.strip():
        raise AnalysisError(f"--param {text!r}: expected NAME=A:B:N, NAME=A,B,C or NAME=A")
    try:
        if ":" in rhs:
            parts = rhs.split(":")
            if len(parts) != 3:
                raise ValueError
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
            if n < 1:
                raise ValueError
            check_count(f"--param {text!r}: points", n, MAX_SWEEP_POINTS,
                        "use fewer points (before any value is generated)")
            values = np.linspace(a, b, n).tolist()
        else:
            values = [float(x) for x in rhs.split(",")]
    except ValueError:
        raise AnalysisError(f"--param {text!r}: expected NAME=A:B:N (N >= 1 points from A to B "
                            "inclusive), NAME=A,B,C or NAME=A with numbers") from None
    if not all(math.isfinite(v) for v in values):
        raise AnalysisError(f"--param {text!r}: values must be finite numbers")
    return name, values


def sweep_points(params: Mapping[str, Iterable[float]] | None,
                 points: Sequence[Mapping[str, float]] | None) -> list[dict[str, float]]:
    """The grid product of ``params`` (first name slowest) or the given ``points``."""
    if (params is None) == (points is None):
        raise AnalysisError("sweep: give either params={name: values} (grid product) or "
                            "points=[{name: value}, ...]")
    if params is not None:
        names = list(params)
        if not names:
            raise AnalysisError("sweep: params is empty")
        lists = []
        for name in names:
            vals = np.atleast_1d(np.asarray(params[name], dtype=float)).ravel()
            if vals.size == 0:
                raise AnalysisError(f"sweep: parameter '{name}' has no values")
            lists.append(vals.tolist())
        sizes = " × ".join(f"{n} {len(v)}" for n, v in zip(names, lists, strict=True))
        check_count(f"sweep: grid points ({sizes})", math.prod(len(v) for v in lists),
                    MAX_SWEEP_POINTS, "use fewer values per parameter or a points= list")
        out = [dict(zip(names, combo, strict=True)) for combo in itertools.product(*lists)]
    else:
        if hasattr(points, "__len__"):
            check_count("sweep: points", len(points), MAX_SWEEP_POINTS, "split the sweep")
        out = [{str(k): float(v) for k, v in dict(p).items()} for p in points]
        if not out:
            raise AnalysisError("sweep: points is empty")
        names = list(out[0])
        for i, p in enumerate(out):
            if list(p) != names and set(p) != set(names):
                raise AnalysisError(f"sweep: point {i} sets {sorted(p)}, point 0 sets "
                                    f"{sorted(names)}; every point must set the same names")
    for i, p in enumerate(out):
        for k, v in p.items():
            if not math.isfinite(v):
                raise AnalysisError(f"sweep: point {i}: parameter '{k}' = {v!r} is not finite")
    return out


# ====================================================================== outputs
_BODY = re.compile(r"^(body|marker|joint)\.([^.]+)\.([A-Za-z_]+)(?:\.([A-Za-z0-9_]+))?$")


def check_outputs(outputs, named: Sequence[str] = ()) -> None:
    """Refuse an ``outputs`` that is neither None, a callable nor a list of known output
    names (:class:`~casmbd.errors.AnalysisError` naming the output); ``named`` are the
    analysis's own scalar outputs (:attr:`Sweepable.outputs
    <casmbd.analysis.studies.sweep_registry.Sweepable.outputs>`)."""
    if outputs is None or callable(outputs):
        return
    if isinstance(outputs, str) or not all(isinstance(o, str) for o in outputs):
        raise AnalysisError("sweep: outputs must be a list of names such as "
                            "'final:q[crank.angle]', or a callable result -> {name: number}")
    for name in outputs:
        if name in SPECIAL_OUTPUTS or name in named:
            continue
        red, sep, col = name.partition(":")
        if not sep or red not in REDUCTIONS or not col:
            raise AnalysisError(f"sweep: output {name!r}: expected REDUCTION:COLUMN with "
                                f"REDUCTION one of {', '.join(REDUCTIONS)} (e.g. "
                                f"'final:q[crank.angle]', 'max:body.crank.angle'), or one of "
                                f"{', '.join((*SPECIAL_OUTPUTS, *named))}")


def _series(result: Result, column: str, where: str) -> np.ndarray:
    """A scalar series of the result: a CSV column label (``q[block.x]``, ``total_energy``) or
    ``body.NAME.FIELD[.AXIS]``, ``marker.NAME.FIELD.AXIS``, ``joint.NAME.FIELD``."""
    m = _BODY.match(column)
    if m:
        kind, name, fld, axis = m.groups()
        try:
            data = getattr(result, kind)(name)
        except (KeyError, ValueError):
            known = result.names.get({"body": "bodies", "marker": "markers",
                                      "joint": "all_joints"}[kind], [])
            raise AnalysisError(f"{where}: unknown {kind} '{name}' (known: "
                                f"{', '.join(known) or 'none'})") from None
        if fld not in data:
            raise AnalysisError(f"{where}: {kind} '{name}' has no '{fld}' (has: "
                                f"{', '.join(data)})")
        arr = np.asarray(data[fld], float)
        if arr.ndim == 1 and axis is None:
            return arr
        axes = "wxyz" if fld == "quaternion" else "xyz"
        if arr.ndim == 2 and axis is not None:
            idx = int(axis) if axis.isdigit() else axes.find(axis)
            if 0 <= idx < arr.shape[1]:
                return arr[:, idx]
        if arr.ndim == 1:
            raise AnalysisError(f"{where}: '{fld}' of {kind} '{name}' is a scalar series; "
                                f"drop '.{axis}'")
        raise AnalysisError(f"{where}: '{fld}' of {kind} '{name}' has components "
                            f"{list(axes[:arr.shape[-1]]) if arr.ndim == 2 else arr.shape[1:]};"
                            " name one: .x, .y, .z (quaternion .w, .x, .y, .z) or .0, .1 …")
    columns = dict(result.csv_columns())
    if column in columns:
        return columns[column]
    pose = _absolute_alias(result, column)
    if pose is not None:
        return pose
    known = [c for c in columns if "[" not in c or c.startswith("q[")]
    raise AnalysisError(f"{where}: unknown column '{column}' (e.g. {', '.join(known[:12])}; "
                        "or body.NAME.FIELD[.AXIS], joint.NAME.FIELD)")


#: absolute-coordinate column names -> (body field by derivative order, component)
_ALIASES = {"x": 0, "y": 1, "z": 2, "angle": None, "e0": 0, "e1": 1, "e2": 2, "e3": 3}
_ALIAS = re.compile(r"^([qva])\[([^\]]+)\.(x|y|z|angle|e0|e1|e2|e3)\]$")


def _absolute_alias(result: Result, column: str) -> np.ndarray | None:
    """``q[NAME.x]``, ``q[NAME.angle]``, ``q[NAME.e0]`` … of a body when the result is in other
    coordinates (the automatic choice takes joint coordinates for trees and few loops): the
    body's pose, which *is* its absolute coordinates when the reference point is the centre of
    mass (``v[…]``/``a[…]`` of the position and planar angle likewise; Euler parameters only
    as positions).  Keeps sweep outputs written for absolute coordinates working."""
    m = _ALIAS.match(column)
    if m is None or m.group(2) not in result.names.get("bodies", []):
        return None
    order, name, coord = m.groups()
    data = result.body(name)
    if coord.startswith("e"):
        if order != "q" or "quaternion" not in data:
            return None
        return np.asarray(data["quaternion"], float)[:, _ALIASES[coord]]
    fld = {"q": "position", "v": "velocity", "a": "acceleration"}[order]
    if coord == "angle":
        fld = {"q": "angle", "v": "angular_velocity", "a": "angular_acceleration"}[order]
        arr = np.asarray(data.get(fld, np.zeros((0, 0))), float)
        return arr if arr.ndim == 1 else None
    arr = np.asarray(data[fld], float)
    return arr[:, _ALIASES[coord]] if _ALIASES[coord] < arr.shape[1] else None


def check_output_names(runner, spec: dict, values: Mapping[str, float]) -> None:
    """Evaluate the named outputs on a probe run at the first point — one output step over
    1e-6 of the time span (statics: the point itself) — so that an unknown column, body or
    joint is an :class:`~casmbd.errors.AnalysisError` naming the output before any point
    runs.  A probe run that fails leaves the check to the points (their failure is
    recorded)."""
    t_end = spec["t_end"]
    if spec["sweepable"].time_grid:
        t_start = runner.run_options.get("t_start", 0.0)
        t_end = t_start + 1e-6 * (t_end - t_start)
    try:
        probe = runner.run(values, t_end, 1)
    except CasmbdError:
        return
    evaluate_outputs(spec["outputs"], probe, spec["sweepable"])


def evaluate_outputs(outputs, result: Result, kind) -> dict[str, float]:
    """The named outputs (or the callable's) of one point's ``result`` as floats; ``kind`` is
    the analysis's :class:`~casmbd.analysis.studies.sweep_registry.Sweepable` (its default
    outputs and its own named outputs, read from ``result.stats``)."""
    if callable(outputs):
        raw = outputs(result)
        if not isinstance(raw, Mapping):
            raise AnalysisError(f"sweep: the outputs callable returned {type(raw).__name__}, "
                                "expected a mapping name -> number")
        out = {}
        for key, val in raw.items():
            arr = np.asarray(val, dtype=float)
            if arr.size != 1:
                raise AnalysisError(f"sweep: output '{key}' of the callable is not a scalar "
                                    f"(shape {arr.shape})")
            out[str(key)] = float(arr.reshape(()))
        return out
    names = kind.default_outputs(result) if outputs is None else list(outputs)
    out = {}
    for name in names:
        where = f"sweep: output {name!r}"
        if name == "energy_drift":
            e = result["total_energy"] if "total_energy" in result.arrays else None
            if e is None:
                raise AnalysisError(f"{where}: the {result.kind} result has no energies")
            out[name] = float(e[-1] - e[0])
        elif name == "max_constraint_violation":
            cv = result.arrays.get("constraint_violation", np.zeros(1))
            out[name] = float(np.max(cv)) if cv.size else 0.0
        elif name in kind.outputs:
            out[name] = float(result.stats.get(name, math.nan))
        else:
            red, _, col = name.partition(":")
            series = _series(result, col, where)
            out[name] = float(REDUCTIONS[red](series)) if len(series) else math.nan
    return out
