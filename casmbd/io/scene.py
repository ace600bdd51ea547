"""Scene files (TOML, format version 1): validate a scene and build a :class:`Mechanism`.

The loader builds exactly the object the Python API builds.  Every error is a
:class:`~casmbd.errors.SceneError` naming the table, the entry and the key, e.g.
``[[bodies]] entry 2 ('crank') key 'mass': must be > 0, got -1.0``.  Expression strings are
parsed by :mod:`casmbd.model.expressions` (never Python ``eval``).

Contract (SI units, angles in radians; vectors have ``dimension`` components)::

    [scene]       name, dimension = 2|3, gravity = [gx, gy(, gz)], format = 1,
                  coordinates = "auto"|"absolute"|"natural"|"joint",
                  tree = ["joint", ...] (joints that must be tree joints, coordinates = "joint")
    [parameters]  k = 100.0 ...
    [[bodies]]    name, type = "rigid" (default; the keys of each type are declared by its
                  kind, casmbd.model.registry.BODY_KINDS), mass, inertia, position, velocity,
                  reference_point,
                  plane:  angle, angular_velocity (numbers)
                  space:  inertia = [Ixx, Iyy, Izz(, Ixy, Ixz, Iyz)] (centre of mass, body axes),
                          orientation = [w, x, y, z] | euler_zxz = [phi, theta, psi],
                          angular_velocity = [wx, wy, wz] (global)
    [[markers]]   name, body, point (, orientation | euler_zxz in space, angle in the plane);
                  or name, body, node (a flexible body's named node; point optional)
    [[joints]]    name, type, body1, body2, point, ...
                  plane: revolute|prismatic|rigid|distance|fixed|gear
                  space: also spherical|cylindrical|universal|inline; axis (revolute,
                  prismatic, cylindrical, inline), axes = [[...], [...]] or axis1, axis2
                  (universal); gear: joint1, joint2, ratio (no bodies).  The keys of
                  each type are declared by its kind (casmbd.model.registry.JOINT_KINDS)
    [[drivers]]   name, joint (+ coordinate for a multi-coordinate joint) |
                  body + coordinate (x|y|angle; x|y|z in space), position (expression of t) |
                  body + coordinate = "orientation" (space) + euler_zxz = [φ, θ, ψ] (or
                  rpy = [roll, pitch, yaw], quaternion = [w, x, y, z]), expressions of t
    [[forces]]    name, type = force|torque|spring_damper|rotational_spring_damper, ...
                  (torque: value number in the plane, [tx, ty, tz] + frame in space)
    [[actuators]] name, joint, coordinate (optional)
    [[outputs]]   name, value (expression of measures: angle("J"), x("marker"), ...), unit
"""

from __future__ import annotations

import json
import math
import os
import re
import tomllib
from pathlib import Path
from typing import Any

from casmbd import results
from casmbd.analysis.events.events import MAX_EVENTS_LIMIT, SIMULATION_KEYS
from casmbd.compiled.modal_cache import DISK_STORE
from casmbd.errors import CasmbdError, ExpressionError, ModelError, SceneError
from casmbd.io.files import read_text
from casmbd.io.mjcf import mjcf_scene
from casmbd.io.scene_points import ScenePoints
from casmbd.io.urdf import urdf_scene
from casmbd.limits import (
    MAX_BODIES,
    MAX_ELEMENTS,
    MAX_SCENE_BYTES,
    MAX_TOML_DEPTH,
    check_count,
)
from casmbd.model import Mechanism, measures
from casmbd.model.contacts import CONTACT_SHAPES
from casmbd.model.drivers import ORIENTATION_FORMS
from casmbd.model.expressions import evaluate_number, parse_expression
from casmbd.model.joint_friction import joint_friction_from_scene
from casmbd.model.registry import BODY_KINDS, FORCE_KINDS, JOINT_KINDS
from casmbd.model.values import EXTRAPOLATIONS, Samples

FORMAT = 1

_TABLES = {"scene", "parameters", "bodies", "markers", "joints", "drivers", "forces",
           "actuators", "outputs", "contacts", "ocp", "simulation", "meta"}
#: keys of a [[contacts]] entry (casmbd/model/contacts.py)
_CONTACT_KEYS = {"name", "type", "body", "point", "radius", "origin", "normal", "model",
                 "restitution", "friction", "body2", "point2", "radius2", "stiffness",
                 "exponent", "damping", "penetration", "friction_velocity", "description",
                 "rest_velocity"}
_COMPLIANT_KEYS = ("stiffness", "exponent", "damping", "penetration", "friction_velocity")
#: keys every [[joints]] entry may add: stops on its coordinate (issue 24)
_LIMIT_KEYS = {"lower", "upper", "restitution", "limit_model", "limit_stiffness",
               "limit_exponent", "limit_damping", "limit_penetration"}
_SCENE_KEYS = {"name", "dimension", "gravity", "format", "description", "coordinates",
               "tree", "urdf", "initial", "locked", "damping", "friction", "inertia",
               "links", "ignore_mimic", "floating_base", "base", "mjcf"}
_COORDINATES = ("auto", "absolute", "natural", "joint")
_MARKER_KEYS = {"name", "body", "point", "description", "orientation", "euler_zxz", "angle"}
_DRIVER_KEYS = {"name", "joint", "body", "coordinate", "position", "description"}
_ACTUATOR_KEYS = {"name", "joint", "coordinate", "description"}
_OUTPUT_KEYS = {"name", "value", "unit", "description"}


def _finite(val: Any) -> float | None:
    """float(val) if it is a finite real number (not bool), else None (also for huge ints)."""
    if isinstance(val, bool) or not isinstance(val, (int, float)):
        return None
    try:
        out = float(val)
    except OverflowError:
        return None
    return out if math.isfinite(out) else None


class _Entry:
    """One table entry with its location, for error messages."""

    def __init__(self, table: str, index: int | None, data: Any, params: dict[str, float]):
        self.table, self.index, self.params = table, index, params
        if not isinstance(data, dict):
            raise SceneError(f"{self.where_table}: expected a table, got {type(data).__name__}")
        self.data = data
        name = data.get("name")
        self.name = name if isinstance(name, str) else None

    @property
    def where_table(self) -> str:
        if self.index is None:
            return f"[{self.table}]"
        return f"[[{self.table}]] entry {self.index + 1}"

    @property
    def where(self) -> str:
        return self.where_table + (f" ('{self.name}')" if self.name else "")

    def error(self, key: str | None, why: str) -> SceneError:
        return SceneError(f"{self.where}" + (f" key '{key}'" if key else "") + f": {why}")

    def check_keys(self, allowed: set[str]) -> None:
        # an element attached to a body may name a node of a flexible body: 'node' with
        # 'body', 'node1' with 'body1', 'node2' with 'body2' (issue 23)
        allowed = set(allowed) | {_NODE_KEYS[k] for k in _NODE_KEYS if k in allowed}
        for key in self.data:
            if key not in allowed:
                raise self.error(key, f"unknown key (allowed: {', '.join(sorted(allowed))})")

    def has(self, key: str) -> bool:
        return key in self.data

    def require(self, key: str) -> Any:
        if key not in self.data:
            raise self.error(key, "missing required key")
        return self.data[key]

    def string(self, key: str, default: str | None = None, required: bool = True) -> str | None:
        if key in _NODE_KEYS and _NODE_KEYS[key] in self.data:
            return self._node_attachment(key)
        if key not in self.data:
            if required and default is None:
                raise self.error(key, "missing required key")
            return default
        val = self.data[key]
        if not isinstance(val, str) or not val.strip():
            raise self.error(key, f"expected a non-empty string, got {val!r}")
        return val

    def _node_attachment(self, key: str) -> str:
        """``"<body>@<node>"``: the frame of a named node of a flexible body."""
        node_key = _NODE_KEYS[key]
        body = self.data.get(key)
        node = self.data[node_key]
        if not isinstance(body, str) or not body.strip():
            raise self.error(key, f"expected a body name with '{node_key}', got {body!r}")
        if not isinstance(node, str) or not node.strip() or "@" in node:
            raise self.error(node_key, f"expected a node name, got {node!r}")
        return f"{body}@{node}"

    def number(self, key: str, default: float | None = None, required: bool = True) -> float:
        """A finite number (or an expression string of the parameters evaluated now)."""
        if key not in self.data:
            if default is None and required:
                raise self.error(key, "missing required key")
            return default
        return self._number(self.data[key], key)

    def _number(self, val: Any, key: str) -> float:
        where = f"{self.where} key '{key}'"
        if isinstance(val, bool):
            raise self.error(key, f"expected a number, got {val!r}")
        if isinstance(val, (int, float)):
            out = _finite(val)
            if out is None:
                raise self.error(key, f"must be a finite number, got {str(val)[:40]}")
            return out
        if isinstance(val, str):
            return evaluate_number(val, self.params, where=where)
        raise self.error(key, f"expected a number, got {type(val).__name__}")

    def value(self, key: str, default: Any = None, required: bool = True) -> Any:
        """A number or an expression string (kept as text, parsed when equations are built)."""
        if key not in self.data:
            if default is None and required:
                raise self.error(key, "missing required key")
            return default
        val = self.data[key]
        if isinstance(val, bool) or not isinstance(val, (int, float, str)):
            raise self.error(key, f"expected a number or an expression string, got {val!r}")
        if isinstance(val, (int, float)):
            out = _finite(val)
            if out is None:
                raise self.error(key, f"must be a finite number, got {str(val)[:40]}")
            return out
        self._check_expression(val, key)
        return val

    def _check_expression(self, text: str, key: str) -> None:
        import casadi as ca

        symbols = {name: ca.SX.sym(name) for name in self.params}
        symbols["t"] = ca.SX.sym("t")
        parse_expression(text, symbols, where=f"{self.where} key '{key}'")

    def vector(self, key: str, size: int = 2, default=None, required: bool = True):
        if key not in self.data:
            if default is None and required:
                raise self.error(key, "missing required key")
            return default
        val = self.data[key]
        if not isinstance(val, list) or len(val) != size:
            raise self.error(key, f"expected a list of {size} numbers, got {val!r}")
        return [self._number(x, key) for x in val]

    def values(self, key: str, sizes: tuple[int, ...], what: str = "numbers or expressions",
               default=None, required: bool = True) -> list | None:
        """A list of ``sizes[i]`` numbers or expression strings (kept as text)."""
        if key not in self.data:
            if default is None and required:
                raise self.error(key, "missing required key")
            return default
        raw = self.data[key]
        if not isinstance(raw, list) or len(raw) not in sizes:
            count = " or ".join(str(n) for n in sizes)
            raise self.error(key, f"expected a list of {count} {what}, got {raw!r}")
        return [self._component(x, key) for x in raw]

    def _component(self, raw: Any, key: str) -> float | str:
        if isinstance(raw, bool) or not isinstance(raw, (int, float, str)):
            raise self.error(key, f"expected a number or an expression string, got {raw!r}")
        if isinstance(raw, str):
            self._check_expression(raw, key)
            return raw
        out = _finite(raw)
        if out is None:
            raise self.error(key, f"must be a finite number, got {str(raw)[:40]}")
        return out

    def evaluate(self, val: Any, key: str) -> float:
        """The number of a raw value of ``key`` (an expression of the parameters evaluated now)."""
        return self._number(val, key)

    def positive(self, key: str, val: Any) -> None:
        """Reject a mass or moment of inertia <= 0 given as ``val`` under ``key``."""
        _positive(self, key, val)

    def nonnegative(self, key: str) -> Any:
        """A value (default 0) that must be >= 0 where it is a number or an expression of the
        parameters; one of t is checked when the equations are built."""
        return _nonneg(self, key)

    def vectors(self, key: str, count: int, size: int) -> list[list[float]]:
        """A list of ``count`` vectors of ``size`` numbers (e.g. the axes of a universal joint)."""
        val = self.require(key)
        if (not isinstance(val, list) or len(val) != count
                or any(not isinstance(v, list) or len(v) != size for v in val)):
            raise self.error(key, f"expected a list of {count} lists of {size} numbers, got "
                             f"{val!r}")
        return [[self._number(x, key) for x in v] for v in val]


#: body key → the key naming a node of that body (a flexible body's node frame)
_NODE_KEYS = {"body": "node", "body1": "node1", "body2": "node2"}


def _name(entry: _Entry) -> str:
    return entry.string("name")


def _build(data: dict, source: str) -> Mechanism:
    for key in data:
        if key not in _TABLES:
            raise SceneError(f"{source}: unknown table [{key}] (allowed: "
                             f"{', '.join(sorted(_TABLES))})")
    if "scene" not in data:
        raise SceneError(f"{source}: missing table [scene]")
    params_raw = data.get("parameters", {})
    if not isinstance(params_raw, dict):
        raise SceneError("[parameters]: expected a table of named numbers")
    params: dict[str, float] = {}
    for key, val in params_raw.items():
        num = _finite(val)
        if num is None:
            raise SceneError(f"[parameters] key '{key}': expected a finite number, got "
                             f"{str(val)[:40]!r}")
        params[key] = num

    scene = _Entry("scene", None, data["scene"], params)
    scene.check_keys(_SCENE_KEYS)
    fmt = scene.data.get("format", FORMAT)
    if isinstance(fmt, bool) or fmt != FORMAT:
        raise scene.error("format", f"unsupported format {fmt!r} (this casmbd reads {FORMAT})")
    dim = scene.data.get("dimension", 3 if "urdf" in scene.data or "mjcf" in scene.data else 2)
    if isinstance(dim, bool) or dim not in (2, 3):
        raise scene.error("dimension", f"unsupported dimension {dim!r} (2: planar, 3: spatial)")
    dim = int(dim)
    coords = scene.data.get("coordinates", "auto")
    if coords not in _COORDINATES:
        raise scene.error("coordinates", f"unsupported coordinates {coords!r} (allowed: "
                          f"{', '.join(repr(c) for c in _COORDINATES)})")
    name = scene.string("name", default=Path(source).stem or "scene")
    gravity = scene.data.get("gravity")
    if isinstance(gravity, list) and len(gravity) in (2, 3) and len(gravity) != dim:
        raise scene.error("gravity", f"expected a list of {dim} numbers with 'dimension' = "
                          f"{dim}, got {gravity!r} (planar scenes: dimension = 2, spatial "
                          "scenes: dimension = 3)")
    if "mjcf" in scene.data:  # the robot from an MJCF file, compiled by MuJoCo (io/mjcf.py)
        if dim != 3:
            raise scene.error("dimension", "a scene with 'mjcf' is spatial (dimension = 3)")
        mech = mjcf_scene(scene.data, source, name, coords, scene.vector("gravity", 3)
                          if "gravity" in scene.data else None)
    elif "urdf" in scene.data:  # the robot's bodies and joints from a URDF file (io/urdf.py)
        mech = urdf_scene(scene.data, source, name, coords, scene.vector("gravity", 3, default=[
            0.0, 0.0, -9.81]) if dim == 3 else None)
    else:
        if any(key in scene.data for key in ("initial", "locked", "damping", "friction")):
            raise scene.error("initial", "'initial', 'locked' and 'damping' need 'urdf' (so "
                              "does 'friction')")
        for key in ("inertia", "links", "ignore_mimic", "base"):  # URDF options (urdf_checks)
            if key in scene.data:
                raise scene.error(key, "needs 'urdf' (an option of the URDF import)")
        if "floating_base" in scene.data:
            raise scene.error("floating_base", "'floating_base' needs 'urdf' (a scene's own "
                              "bodies float when no joint holds them)")
        gravity = scene.vector("gravity", dim, default=[0.0] * dim)
        try:
            mech = Mechanism(name, gravity=gravity, dimension=dim, coordinates=coords)
        except ModelError as exc:  # the plausible range of gravity (issue 31)
            if "'gravity'" not in str(exc):
                raise
            raise scene.error("gravity", str(exc).split(": ", 1)[-1]) from None

    def guarded(entry: _Entry, action):
        try:
            return action()
        except SceneError:
            raise
        except CasmbdError as exc:
            raise SceneError(f"{entry.where}: {exc}") from None

    base_dir = str(Path(source).parent) if Path(source).exists() else "."
    for pname, pval in params.items():
        guarded(_Entry("parameters", None, {}, params),
                lambda pname=pname, pval=pval: mech.add_parameter(pname, pval))

    def entries(table: str):
        raw = data.get(table, [])
        if not isinstance(raw, list):
            raise SceneError(f"[[{table}]]: expected an array of tables ([[{table}]]), got "
                             f"{type(raw).__name__}")
        check_count(f"{source}: [[{table}]] entries", len(raw),
                    MAX_BODIES if table == "bodies" else MAX_ELEMENTS)
        out = [_Entry(table, i, item, params) for i, item in enumerate(raw)]
        for entry in out:  # files named by an entry (a flexible body's [bodies.fe]) are
            entry.base_dir = base_dir  # relative to the scene file
            entry.modal_store = DISK_STORE  # a flexible body's modes, cached on disk
        return out

    for e in entries("bodies"):  # each kind reads its own keys (casmbd.model.registry)
        btype = e.string("type", default="rigid")
        if btype not in BODY_KINDS:
            raise e.error("type", f"unknown body type {btype!r} (allowed: "
                          f"{', '.join(BODY_KINDS)})")
        body_kind = BODY_KINDS[btype].get(dim)
        if body_kind is None:
            space = "spatial" if dim == 2 else "planar"
            raise e.error("type", f"a {btype} body needs a {space} scene ([scene] "
                          f"dimension = {5 - dim})")
        e.check_keys(set(body_kind.scene_keys))
        guarded(e, lambda body_kind=body_kind, e=e: body_kind.from_scene(mech, e))

    for e in entries("markers"):
        e.check_keys(_MARKER_KEYS)
        guarded(e, lambda e=e: mech.add_marker(  # 'node': at a flexible body's node
            _name(e), e.string("body"), e.vector("point", dim, required=not e.has("node")),
            orientation=e.vector("orientation", 4, required=False),
            euler_zxz=e.vector("euler_zxz", 3, required=False),
            angle=e.number("angle", None) if e.has("angle") else None))

    for e in entries("joints"):  # each kind reads its own keys (casmbd.model.registry)
        jtype = e.string("type")
        if jtype not in JOINT_KINDS:
            raise e.error("type", f"unknown joint type {jtype!r} (allowed: "
                          f"{', '.join(JOINT_KINDS)})")
        kind = JOINT_KINDS[jtype].get(dim)
        if kind is None:
            space = "spatial" if dim == 2 else "planar"
            raise e.error("type", f"a {jtype} joint needs a {space} scene ([scene] "
                          f"dimension = {5 - dim})")
        e.check_keys(set(kind.scene_common | kind.scene_keys) | _LIMIT_KEYS | {"friction"})
        guarded(e, lambda kind=kind, e=e: kind.from_scene(mech, e))
        if e.has("friction"):  # joint friction "<joint>.friction" (model/joint_friction.py)
            guarded(e, lambda e=e: joint_friction_from_scene(mech, e))
        if e.has("lower") or e.has("upper"):  # stops on the joint's first coordinate
            guarded(e, lambda e=e: mech.add_joint_limit(
                e.string("name"), lower=e.value("lower", None, required=False),
                upper=e.value("upper", None, required=False),
                restitution=e.value("restitution", 0.0),
                model=e.string("limit_model", default="impact"),
                **{k.removeprefix("limit_"): e.number(k) for k in
                   ("limit_stiffness", "limit_exponent", "limit_damping", "limit_penetration")
                   if e.has(k)}))
        elif any(e.has(k) for k in _LIMIT_KEYS):
            raise e.error("restitution", "applies to joint limits: give 'lower' or 'upper'")

    for e in entries("drivers"):
        e.check_keys(_DRIVER_KEYS | set(ORIENTATION_FORMS))
        forms = {k: e.values(k, (n,), "expressions of t") for k, n in ORIENTATION_FORMS.items()
                 if e.has(k)}  # an orientation driver (casmbd.model.drivers.OrientationDriver)
        guarded(e, lambda e=e, forms=forms: mech.add_driver(
            _name(e), _position(e) if e.has("position") or not (
                forms or e.data.get("coordinate") == "orientation") else None,
            joint=e.string("joint", required=False), body=e.string("body", required=False),
            coordinate=e.string("coordinate", required=False), **forms))

    scene_forces = {n: k for n, k in FORCE_KINDS.items() if k.scene_keys is not None}
    for e in entries("forces"):  # each kind reads its own keys (casmbd.model.registry)
        ftype = e.string("type")
        if ftype not in scene_forces:
            raise e.error("type", f"unknown force type {ftype!r} (allowed: "
                          f"{', '.join(scene_forces)})")
        force_kind = scene_forces[ftype]
        e.check_keys({"name", "type", "description"} | force_kind.scene_keys)
        guarded(e, lambda force_kind=force_kind, e=e: force_kind.from_scene(mech, e))

    for e in entries("contacts"):  # each shape reads its own keys (CONTACT_SHAPES)
        e.check_keys(_CONTACT_KEYS.union(*(getattr(k, "scene_keys", ())
                                           for k in CONTACT_SHAPES.values())))
        ctype = e.string("type", default="plane")
        if ctype not in CONTACT_SHAPES:
            raise e.error("type", f"unknown contact type {ctype!r} (allowed: "
                          f"{', '.join(CONTACT_SHAPES)})")
        compliant = {k: e.number(k) for k in (*_COMPLIANT_KEYS, "rest_velocity")
                     if e.has(k)}
        other = CONTACT_SHAPES[ctype].scene_args(e, dim)
        guarded(e, lambda e=e, compliant=compliant, other=other, ctype=ctype: mech.add_contact(
            _name(e), e.string("body"), e.vector("point", dim),
            radius=e.number("radius", 0.0), model=e.string("model", default="impact"),
            restitution=e.value("restitution", 0.0), friction=e.number("friction", 0.0),
            shape=ctype, **other, **compliant))

    for e in entries("actuators"):
        e.check_keys(_ACTUATOR_KEYS)
        guarded(e, lambda e=e: mech.add_actuator(
            _name(e), e.string("joint"), coordinate=e.string("coordinate", required=False)))

    if "simulation" in data:  # options of the event-driven run (docs/contact.md)
        table = _Entry("simulation", None, data["simulation"], params)
        table.check_keys(set(SIMULATION_KEYS))
        count = table.data.get("max_events", 1)
        if isinstance(count, bool) or not isinstance(count, int) or \
                not 1 <= count <= MAX_EVENTS_LIMIT:
            raise table.error("max_events", f"expected an integer in [1, {MAX_EVENTS_LIMIT}], "
                                            f"got {count!r}")
        speed = table.data.get("rest_velocity", 0.0)
        if isinstance(speed, bool) or not isinstance(speed, (int, float)) or \
                not math.isfinite(speed) or speed < 0.0:
            raise table.error("rest_velocity", f"expected a finite number >= 0 (m/s), got "
                                               f"{speed!r}")

    for e in entries("outputs"):  # requests: expressions of measures (casmbd.model.measures)
        e.check_keys(_OUTPUT_KEYS)
        guarded(e, lambda e=e: mech.add_output(
            _name(e), measures.check(mech, e.require("value"), f"{e.where} key 'value'"),
            unit=e.string("unit", default="-")))

    if not mech.bodies:
        raise SceneError(f"{source}: the scene has no [[bodies]]")
    tree = scene.data.get("tree", list(getattr(mech, "tree", None) or []))  # mjcf: its own
    if not isinstance(tree, list) or not all(isinstance(j, str) for j in tree):
        raise scene.error("tree", f"expected a list of joint names, got {tree!r}")
    unknown = [j for j in tree if j not in mech.joints]
    if unknown:
        raise scene.error("tree", f"unknown joint(s) {', '.join(map(repr, unknown))} (known: "
                          f"{', '.join(mech.joints) or 'none'})")
    mech.tree = list(tree)
    try:
        mech.validate()
    except CasmbdError as exc:
        raise SceneError(f"{source}: {exc}") from None
    return mech


def _positive(e: _Entry, key: str, val: float | str) -> None:
    """Reject a mass or moment of inertia <= 0 (an expression is evaluated with the
    parameters' values)."""
    num = e._number(val, key)
    if num <= 0.0:
        raise e.error(key, f"must be > 0, got {num:g}" + (f" ({val!r})"
                                                         if isinstance(val, str) else ""))


def _position(e: _Entry):
    """A driver position: a number, an expression of t, or {times = [...], values = [...]}
    with an optional ``extrapolate`` ("hold", "linear" or "error"; see
    :class:`~casmbd.model.values.Samples`)."""
    raw = e.require("position")
    if isinstance(raw, dict):
        unknown = set(raw) - {"times", "values", "extrapolate"}
        if unknown or not {"times", "values"} <= set(raw):
            raise e.error("position", "a sampled trajectory needs the keys 'times' and "
                          f"'values' and optionally 'extrapolate' (got {', '.join(sorted(raw))})")
        extrapolate = raw.get("extrapolate", "hold")
        if extrapolate not in EXTRAPOLATIONS:
            raise e.error("position", f"'extrapolate' must be one of "
                          f"{', '.join(EXTRAPOLATIONS)}, got {extrapolate!r}")
        times, values = raw["times"], raw["values"]
        for key, arr in (("times", times), ("values", values)):
            if not isinstance(arr, list) or any(_finite(x) is None for x in arr):
                raise e.error("position", f"'{key}' must be a list of finite numbers")
        try:
            return Samples(times, values, name=f"driver_{e.name or e.index}",
                           extrapolate=extrapolate)
        except CasmbdError as exc:
            raise e.error("position", str(exc)) from None
    return e.value("position")


def _nonneg(e: _Entry, key: str):
    val = e.value(key, 0.0)
    try:
        num = e.number(key, 0.0)
    except ExpressionError:
        return val  # depends on t: only checked when equations are built
    if num < 0.0:
        raise e.error(key, f"must be >= 0, got {num:g}")
    return val


#: strings and comments of TOML, whose brackets do not nest (multi-line forms first)
_TOML_SKIP = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"'
                        r"|'[^'\n]*'|#[^\n]*")


def _toml_depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` outside strings and comments, in linear time (the TOML
    reader itself recurses once per level and would fail with a RecursionError)."""
    if text.count("[") + text.count("{") <= MAX_TOML_DEPTH:
        return 0
    depth = deepest = 0
    for char in re.findall(r"[\[\]{}]", _TOML_SKIP.sub("", text)):
        depth = depth + 1 if char in "[{" else max(depth - 1, 0)
        deepest = max(deepest, depth)
    return deepest


def _file_keys(data: dict) -> list[tuple[tuple, str]]:
    """(key path, value) of the file names a scene reads: ``[scene] urdf`` and each
    ``[bodies.fe] file``."""
    out = []
    scene = data.get("scene")
    for key in ("urdf", "mjcf"):
        if isinstance(scene, dict) and isinstance(scene.get(key), str):
            out.append((("scene", key), scene[key]))
    bodies = data.get("bodies")
    for i, body in enumerate(bodies if isinstance(bodies, list) else []):
        fe = body.get("fe") if isinstance(body, dict) else None
        if isinstance(fe, dict) and isinstance(fe.get("file"), str):
            out.append((("bodies", i, "fe", "file"), fe["file"]))
    return out


def _portable(text: str, data: dict, source: str) -> str:
    """The scene text with the relative file names it reads (``urdf``, ``[bodies.fe] file``)
    made absolute against the scene file's folder, so that the copy a result embeds
    (:meth:`casmbd.results.Result.mechanism`) reloads from any working folder.  The text is
    changed only where re-reading it gives the same tables with those names absolute; else
    (a name written in an unusual form) it is kept as written."""
    if not source or source.startswith("<"):
        return text
    keys = [(path, value) for path, value in _file_keys(data)
            if value and not Path(value).is_absolute()]
    if not keys:
        return text
    base = Path(source).resolve().parent
    new = text
    expected = json.loads(json.dumps(data, default=str))
    for path, value in keys:
        absolute = os.path.normpath(base / value)
        for quoted in (json.dumps(value), f"'{value}'"):
            new = new.replace(quoted, json.dumps(absolute))
        table = expected
        for key in path[:-1]:
            table = table[key]
        table[path[-1]] = absolute
    try:
        same = json.loads(json.dumps(tomllib.loads(new), default=str)) == expected
    except (tomllib.TOMLDecodeError, RecursionError):
        same = False
    return new if same else text


def loads_scene(text: str, source: str = "<string>") -> Mechanism:
    """Build a :class:`Mechanism` from TOML text.

    Raises
    ------
    SceneError
        Malformed TOML or any invalid table, entry or key (named in the message).
    """
    check_count(f"{source}: scene size in characters", len(text), MAX_SCENE_BYTES)
    depth = _toml_depth(text)
    if depth > MAX_TOML_DEPTH:
        raise SceneError(f"{source}: arrays or inline tables nested {depth} levels deep; the "
                         f"limit is {MAX_TOML_DEPTH} (casmbd.limits.MAX_TOML_DEPTH)")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: malformed TOML: {exc}") from None
    except RecursionError:  # the reader recurses per level: a depth the scan did not see
        raise SceneError(f"{source}: nested too deeply for the TOML reader (the limit is "
                         f"{MAX_TOML_DEPTH} levels)") from None
    mech = _build(data, source)
    mech.scene_text = _portable(text, data, source)
    mech.scene_data = data
    mech.scene_points = ScenePoints(text, source, loads_scene)  # sweeps re-read it per point
    mech.scene_reader = loads_scene  # a Result of this mechanism reads its scene back with it
    return mech


def load_scene(path: str | os.PathLike, floating_base: bool = False) -> Mechanism:
    """Read a scene file and build its :class:`Mechanism` (see :func:`loads_scene`).

    A ``.urdf`` file is read as the scene ``[scene] urdf = "<file>"`` with joint coordinates
    (:mod:`casmbd.io.urdf`), an ``.xml`` file as ``[scene] mjcf = "<file>"``
    (:mod:`casmbd.io.mjcf`), so results keep a scene text that reloads it; with
    ``floating_base`` (the verbs' ``--floating-base``, URDF only) the scene also says
    ``floating_base = true``.  A scene file states that itself (then ``floating_base`` here
    is an error naming the file)."""
    path = Path(path)
    if path.suffix.lower() in (".urdf", ".xml"):  # a robot file: URDF or MJCF (io/mjcf.py)
        key = "urdf" if path.suffix.lower() == ".urdf" else "mjcf"
        text = (f"[scene]\nname = {json.dumps(path.stem)}\ndimension = 3\n"
                f"coordinates = \"joint\"\n{key} = {json.dumps(str(path.resolve()))}\n"
                + ("floating_base = true\n" if floating_base else ""))
        return loads_scene(text, source=str(path))
    if floating_base:
        raise SceneError(f"{path}: --floating-base applies to a bare .urdf file; a scene "
                         "says [scene] floating_base = true next to its 'urdf'")
    text = read_text(path, "scene")
    return loads_scene(text, source=str(path))


def load_result(path: str | os.PathLike) -> results.Result:
    """Read a result file (:func:`casmbd.results.load`) with this module's scene reader, so
    that :meth:`~casmbd.results.Result.mechanism` can read the embedded scene (``results`` sits
    below ``io`` and cannot import it: the reader is passed in, never registered)."""
    result = results.load(path)
    result.scene_reader = loads_scene
    return result


#: ``casmbd.load``
load = load_result
