"""Helpers shared by the verbs: argument types, ``--out`` checks, scene loading and the
summary lines every analysis verb prints.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import numpy as np

from casmbd.errors import AnalysisError
from casmbd.io.scene import load_scene
from casmbd.limits import MAX_STEPS
from casmbd.results import json_default
from casmbd.viz.column_units import joint_units


class UsageError(Exception):
    """A command line the parser refuses (one ``error: …`` line, the usage exit status)."""


class CommandParser(argparse.ArgumentParser):
    """ArgumentParser that reports one ``error: …`` line instead of usage + exit."""

    def error(self, message: str):
        raise UsageError(message)


def positive_int(text: str) -> int:
    try:
        val = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if not 1 <= val <= MAX_STEPS:
        raise argparse.ArgumentTypeError(f"must be between 1 and {MAX_STEPS}, got {text}")
    return val


def positive_float(text: str) -> float:
    try:
        val = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(val) or val <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return val


def nonnegative_float(text: str) -> float:
    try:
        val = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(val) or val < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return val


def add_output_flags(p: argparse.ArgumentParser) -> None:
    """``--json`` and ``--debug``, which every verb takes."""
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")


def add_mode_flag(p: argparse.ArgumentParser) -> None:
    """``--mode``: equations compiled to C or evaluated by CasADi's virtual machine."""
    p.add_argument("--mode", choices=("auto", "compiled", "vm"), default="auto",
                   help="compile equations to C (default auto) or use CasADi's VM")


def add_dpi_flag(p: argparse.ArgumentParser, default: float) -> None:
    """``--dpi`` of a figure or an animation."""
    p.add_argument("--dpi", type=positive_float, default=default,
                   help=f"resolution (default {default:g})")


#: ``--out`` suffix -> format of the verbs that save results (``Result.save``/``to_csv``)
OUT_FORMATS = {".npz": "npz", ".csv": "csv"}
_RESULT_VERBS = ("kinematics", "simulate", "inverse", "ocp")


def _same_file(a, b) -> bool:
    """Whether the paths ``a`` and ``b`` name one file (symbolic and hard links, ``..``, a
    relative and an absolute spelling): ``os.path.samefile`` when both exist, else the
    resolved paths."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
        return Path(a).resolve() == Path(b).resolve()
    except (OSError, RuntimeError, ValueError):
        return False


def _outputs(args) -> list[tuple[str, str]]:
    """The files the verb will write: ``(option, path)`` for ``--out``, ``ocp --plot`` and
    ``view --html``."""
    return [(opt, val) for opt, val in (("--out", getattr(args, "out", None)),
                                        ("--plot", getattr(args, "plot", None)),
                                        ("--html", getattr(args, "html", None))) if val]


def check_not_input(args, inputs) -> None:
    """Refuse an output file that is one of the ``inputs`` ``(what, path)`` (the scene, its URDF
    or FE files, a result read) or the other output: it would be replaced."""
    outs = _outputs(args)
    for opt, out in outs:
        for what, path in inputs:
            if path and _same_file(out, path):
                raise AnalysisError(f"{opt} '{out}' is the {what} '{path}' this command "
                                    "reads; give another file name (nothing written)")
    if len(outs) == 2 and _same_file(outs[0][1], outs[1][1]):
        raise AnalysisError(f"--out and --plot name the same file '{outs[0][1]}'")


def check_out_path(args) -> None:
    """Fail before the analysis when ``--out`` cannot be written, would replace a file given
    on the command line, or has a suffix the verb cannot write (``.npz`` or ``.csv``)."""
    check_not_input(args, [(what, getattr(args, key, None)) for key, what in
                            (("scene", "scene file"), ("result", "result file"),
                             ("source", "input file"), ("from_result", "result file"))])
    out = getattr(args, "out", None)
    if not out:
        return
    path = Path(out)
    if path.is_dir():
        raise AnalysisError(f"--out '{out}' is a directory; give a file name such as run.npz")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise AnalysisError(f"--out '{out}': folder '{parent}' does not exist")
    if getattr(args, "verb", None) in _RESULT_VERBS and path.suffix.lower() not in OUT_FORMATS:
        raise AnalysisError(f"--out '{out}': unknown suffix '{path.suffix}' (the suffix decides "
                            "the format: .npz for every array, .csv for one column per scalar "
                            "series)")


def scene_files(mech, scene: str) -> list[tuple[str, str]]:
    """The files a loaded scene read besides itself: ``[scene] urdf`` and every flexible
    body's ``[bodies.fe] file`` (relative to the scene file, as the loader resolves them)."""
    data = getattr(mech, "scene_data", None) or {}
    base = Path(scene).parent
    files = []
    urdf = (data.get("scene") or {}).get("urdf") if isinstance(data.get("scene"), dict) else None
    if isinstance(urdf, str) and urdf:
        files.append(("URDF file", str(base / urdf)))
    mjcf = (data.get("scene") or {}).get("mjcf") if isinstance(data.get("scene"), dict) else None
    if isinstance(mjcf, str) and mjcf:
        files.append(("MJCF file", str(base / mjcf)))
    for body in data.get("bodies") or []:
        fe = body.get("fe") if isinstance(body, dict) else None
        if isinstance(fe, dict) and isinstance(fe.get("file"), str):
            files.append((f"FE model of body '{body.get('name')}'", str(base / fe["file"])))
    return files


def save_result(result, out: str) -> None:
    """Write ``result`` to ``--out``: ``.csv`` by ``to_csv``, else the npz file."""
    try:
        if Path(out).suffix.lower() == ".csv":
            result.to_csv(out)
        else:
            result.save(out)
    except OSError as exc:
        raise AnalysisError(f"cannot write --out '{out}': {exc.strerror or exc}") from None


def load_scene_for(args):
    """The Mechanism of ``args.scene``, after checking that ``--out`` (and the other outputs)
    can be written and replace none of the scene's files."""
    check_out_path(args)
    mech = load_scene(args.scene, floating_base=getattr(args, "floating_base", False))
    if _outputs(args):
        check_not_input(args, scene_files(mech, args.scene))
    return mech


def timing_line(stats: dict, digits: int = 3) -> str:
    """The build/solve line every verb prints."""
    origin = "cache hit" if stats.get("cache_hit") else stats.get("mode", "")
    return (f"  build {stats['build_seconds']:.3f} s ({origin}), "
            f"solve {stats['solve_seconds']:.{digits}f} s")


def range_line(label: str, values: np.ndarray, unit: str = "") -> str:
    """``label [min, max] unit`` of ``values`` (4 significant digits)."""
    unit = f" {unit}" if unit else ""
    return f"{label} [{values.min():+.4g}, {values.max():+.4g}]{unit}"


def summary_table(result, mech=None) -> list[str]:
    """One line per body (coordinate ranges of the centre of mass in m, and the angle range
    in rad in the plane or the final quaternion in space), per joint coordinate (m or
    rad, from the joint's kind), per named node of a flexible body (its deflection) and per
    request (``[[outputs]]``)."""
    lines = []
    spatial = result.dimension == 3
    for name in result.names["bodies"]:
        b = result.body(name)
        pos = b["position"]
        parts = [range_line(axis, pos[:, k], "m") for k, axis in enumerate("xyz"[:pos.shape[1]])]
        if spatial and "quaternion" in b and len(b["quaternion"]):
            quat = ", ".join(f"{x:+.4f}" for x in b["quaternion"][-1])
            parts.append(f"final quaternion [{quat}]")
        elif "angle" in b:
            parts.append(range_line("angle", b["angle"], "rad"))
        lines.append(f"  body {name:<14} " + "  ".join(parts))
    units = joint_units(result, mech) if result.names["joints"] else []
    for name, unit in zip(result.names["joints"], units):
        c = result["joint_positions"][:, result.names["joints"].index(name)]
        lines.append(f"  joint {name:<13} {range_line('coordinate', c, unit)}")
    return lines + _node_lines(result) + _output_lines(result)


#: rows of one table of a text summary (requests, nodes); the rest are counted and left to
#: --json / --out
SUMMARY_ROWS = 20


def _number(x, fmt: str = "+.6g") -> str:
    """A summary's number (``-`` for a missing extreme, ``nan`` as is, no ``-0``)."""
    return "-" if x is None else format(float(x) + 0.0, fmt)


def _vector(values, fmt: str = "+.6g") -> str:
    """``[x, y(, z)]`` with components below 1e-9 of the largest printed as 0 (round-off of
    a deflection along the beam axis, not a stretch)."""
    values = np.asarray(values, dtype=float)
    scale = float(np.max(np.abs(values), initial=0.0))
    return "[" + ", ".join(_number(x if abs(x) > 1e-9 * scale else 0.0, fmt)
                           for x in values) + "]"


def _table(header: list[str], rows: list[list[str]], more: str,
           limit: int = SUMMARY_ROWS) -> list[str]:
    """Lines of an aligned table (the first column, units and vectors left-aligned, the
    numbers right-aligned), at most ``limit`` rows, then one line
    ``… N more, see <more>``."""
    if not rows:
        return []
    shown = rows[:limit]
    widths = [max(len(r[k]) for r in [header, *shown]) for k in range(len(header))]
    left = {0} | {k for k, h in enumerate(header) if h == "unit" or "body axes" in h}

    def line(cells):
        return "  " + "  ".join(c.ljust(w) if k in left else c.rjust(w)
                                for k, (c, w) in enumerate(zip(cells, widths))).rstrip()

    out = [line(header), *(line(r) for r in shown)]
    if len(rows) > limit:
        out.append(f"  … {len(rows) - limit} more, see {more}")
    return out


def _unit(unit: str) -> str:
    return "-" if unit in ("", "-", None) else unit


def _node_lines(result) -> list[str]:
    """The table of named nodes of flexible bodies: the magnitude |u_i| of each node's
    elastic displacement relative to its undeformed position in the body frame (start, end,
    max and its time) and its final components in body axes (``Result.summary``)."""
    nodes = result.summary().get("node_deflections", {})
    rows = []
    for name, s in nodes.items():
        rows.append([name, _number(s["start"], ".6g"), _number(s["end"], ".6g"),
                     _number(s["max"], ".6g"), _number(s["t_max"], ".4g"),
                     _vector(result.node(name)["deflection"][-1], "+.4g")])
    return _table(["node deflection |u| [m]", "start", "end", "max", "t_max [s]",
                   "end (body axes)"], rows, "--json 'summary' / --out")


def _output_lines(result) -> list[str]:
    """The table of requests (``[[outputs]]``): start, end, min and max with the times they
    are reached, in the request's unit (``Result.summary``)."""
    outputs = result.summary().get("outputs", {})
    rows = [[name, _number(s["start"]), _number(s["end"]), _number(s["min"]),
             _number(s["t_min"], ".4g"), _number(s["max"]), _number(s["t_max"], ".4g"),
             _unit(s["unit"])] for name, s in outputs.items()]
    return _table(["output", "start", "end", "min", "t_min [s]", "max", "t_max [s]", "unit"],
                  rows, "--json 'summary' / --out")


def state_lines(summary: dict) -> list[str]:
    """The tables of the requests and the named nodes at one state (an equilibrium, an
    operating point): ``state_summary`` of :mod:`casmbd.analysis.statics.report`."""
    outputs = summary.get("outputs", {})
    lines = _table(["output", "value", "unit"],
                   [[name, _number(s["value"]), _unit(s["unit"])]
                    for name, s in outputs.items()], "--json 'summary'")
    nodes = summary.get("node_deflections", {})
    rows = [[name, _number(s["value"], ".6g"), _vector(s["deflection"])]
            for name, s in nodes.items()]
    return lines + _table(["node deflection", "|u| [m]", "u (body axes) [m]"], rows,
                          "--json 'summary'")


def finite_json(obj):
    """``obj`` with numpy values as Python ones (:func:`casmbd.results.json_default`) and
    NaN/inf (e.g. reactions that cannot be determined) as null: strict JSON.

    A list or dict whose items need no change is returned itself, not copied: a result's
    ``to_json`` holds one Python float object per value (32 bytes each with its list slot),
    and the copies made here before (a ``json.loads(json.dumps(…))`` round trip, then a
    rebuilt tree) doubled the memory of ``--json`` (:func:`casmbd.limits.memory_per_time`).
    """
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, (str, int, bool)) or obj is None:
        return obj
    if isinstance(obj, dict):
        out = {k: finite_json(v) for k, v in obj.items()}
        return obj if all(out[k] is v for k, v in obj.items()) else out
    if isinstance(obj, (list, tuple)):
        if all(type(v) is float for v in obj) and all(map(math.isfinite, obj)):
            return obj  # a row of finite floats (tolist): the common case, no copy
        out = [finite_json(v) for v in obj]
        return obj if isinstance(obj, list) and all(a is b for a, b in zip(out, obj)) else out
    return finite_json(json_default(obj))  # numpy arrays and scalars; others: TypeError

