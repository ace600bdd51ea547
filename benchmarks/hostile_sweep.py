"""An independent sweep of hostile inputs through the command line (issue 31's acceptance).

About 250 bad inputs -- files that never end (``/dev/zero``, FIFOs), forged ``.npy`` headers,
huge counts, absurd numbers in every numeric field of a few scenes, wrong types, missing and
unknown keys, deep nesting, self-referencing expressions, reserved names, solver options that
subvert, ``--out`` onto the inputs, bad flags -- each run as ``python -m casmbd ...`` in a fresh
temporary directory with a timeout, and classified:

``named``
    exit != 0 and the error names the culprit: no ``Traceback``, no ``internal error``, the
    planted name (file, body, joint, key or flag) in stderr, and under ``--json`` nothing but
    (at most) one JSON object on stdout.
``legal``
    exit 0 and the result is sound: under ``--json`` stdout is exactly one JSON object with no
    NaN/Infinity and no null inside a list of numbers (without ``--json`` no ``nan``/``inf``
    token in stdout), the case's own check passes (e.g. a closed form), no input was changed.
``generic``
    exit != 0 but a traceback, an ``internal error``, a message that does not name the culprit,
    or log text on stdout under ``--json``.
``silent``
    exit 0 but non-finite numbers, a failed check, more than one JSON object on stdout, or an
    input file changed (for any exit code), or a run of a memory-budget case whose peak RSS
    exceeds 1.5 x the budget (+ the interpreter's own 400 MB).
``hang``
    the case's timeout (default 30 s) passed; the process group is killed.

The cases are data (:func:`cases`): name, category, files to create, argv, env, timeout,
culprit strings (any one must appear in stderr) and an optional check of the JSON output.
Every child runs with an address-space limit (``RLIMIT_AS``, 6 GiB) so that a runaway
allocation ends as a MemoryError instead of taking the shared machine down.

Run::

    python -m benchmarks.hostile_sweep --repo /path/to/checkout --label after

The CSV goes to ``benchmarks/results/hostile_sweep_<label>.csv``; the counts are printed.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import math
import os
import re
import resource
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
VERDICTS = ("named", "legal", "generic", "silent", "hang")
AS_LIMIT = 6 << 30


@dataclass
class Case:
    name: str
    category: str
    argv: list  # after "python -m casmbd"; "{d}" is the temporary dir
    files: dict = field(default_factory=dict)  # relpath -> str | bytes | callable(path)
    culprit: tuple = ()  # any one of these (case-insensitive) in stderr -> named
    env: dict = field(default_factory=dict)
    timeout: float = 30.0
    check: object = None  # callable(json_obj, tmpdir) -> None or a failure text
    protect: tuple = ()  # files (relative) that must not change or appear
    setup: list = field(default_factory=list)  # argvs run first (their outcome ignored)
    prepare: object = None  # callable(tmpdir, env) run after setup
    budget_mb: float | None = None  # memory-budget case: peak RSS must stay near it
    compiled: bool = False  # leave CASMBD_COMPILE unset (default: the VM, faster)


# ----------------------------------------------------------------------------- scenes
SPRING = """\
[scene]
name = "spring_mass"
dimension = 2
gravity = [0.0, -9.81]

[parameters]
k = 100.0
m = 1.0
c = 0.0

[[bodies]]
name = "block"
mass = "m"
inertia = "m / 100"
position = [1.1, 0.0]

[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [1.1, 0.0]
axis = [1.0, 0.0]

[[forces]]
name = "spring"
type = "spring_damper"
body1 = "ground"
body2 = "block"
point1 = [0.0, 0.0]
point2 = [1.1, 0.0]
stiffness = "k"
damping = "c"
free_length = 1.0
"""

BALL = """\
[scene]
name = "bouncing_ball"
dimension = 2
gravity = [0.0, -9.81]

[parameters]
m = 1.0
r = 0.1
h0 = 1.0

[[bodies]]
name = "ball"
mass = "m"
inertia = "0.4 * m * r**2"
position = [0.0, "h0 + r"]

[[contacts]]
name = "floor"
type = "plane"
body = "ball"
point = [0.0, "h0 + r"]
radius = "r"
origin = [0.0, 0.0]
normal = [0.0, 1.0]
model = "impact"
restitution = 0.8
friction = 0.0
"""

PENDULUM = """\
[scene]
name = "double_pendulum"
dimension = 2
gravity = [0.0, -9.81]

[parameters]
L = 1.0
m = 1.0

[[bodies]]
name = "rod1"
mass = "m"
inertia = "m * L**2 / 12"
position = [0.5, 0.0]

[[bodies]]
name = "rod2"
mass = "m"
inertia = "m * L**2 / 12"
position = [1.5, 0.0]

[[markers]]
name = "tip"
body = "rod2"
point = [2.0, 0.0]

[[joints]]
name = "shoulder"
type = "revolute"
body1 = "ground"
body2 = "rod1"
point = [0.0, 0.0]

[[joints]]
name = "elbow"
type = "revolute"
body1 = "rod1"
body2 = "rod2"
point = [1.0, 0.0]
"""

SLIDER_CRANK = """\
[scene]
name = "slider_crank"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "crank"
mass = 1.0
inertia = 0.01
position = [0.1, 0.0]

[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.05
position = [0.4, 0.0]

[[bodies]]
name = "slider"
mass = 1.0
inertia = 0.01
position = [0.6, 0.0]

[[joints]]
name = "O"
type = "revolute"
body1 = "ground"
body2 = "crank"
point = [0.0, 0.0]

[[joints]]
name = "A"
type = "revolute"
body1 = "crank"
body2 = "rod"
point = [0.2, 0.0]

[[joints]]
name = "B"
type = "revolute"
body1 = "rod"
body2 = "slider"
point = [0.6, 0.0]

[[joints]]
name = "rail"
type = "prismatic"
body1 = "ground"
body2 = "slider"
point = [0.6, 0.0]
axis = [1.0, 0.0]

[[drivers]]
name = "motor"
joint = "O"
position = "2 * pi * t"
"""

CART_POLE = """\
[scene]
name = "cart_pole"
gravity = [0.0, -9.81]
coordinates = "joint"

[[bodies]]
name = "cart"
mass = 1.0
inertia = 0.01
position = [0.0, 0.0]

[[bodies]]
name = "bob"
mass = 0.1
inertia = 1e-6
position = [0.0, -0.5]

[[joints]]
name = "rail"
type = "prismatic"
body1 = "ground"
body2 = "cart"
point = [0.0, 0.0]
axis = [1.0, 0.0]

[[joints]]
name = "hinge"
type = "revolute"
body1 = "cart"
body2 = "bob"
point = [0.0, 0.0]

[[actuators]]
name = "force"
joint = "rail"

[ocp]
horizon = 2.0
intervals = 20
objective = "effort"

[ocp.controls]
force = [-20.0, 20.0]

[ocp.initial]
rail = 0.0
hinge = 0.0
rail_dot = 0.0
hinge_dot = 0.0

[ocp.final]
rail = 0.0
hinge = "pi"
rail_dot = 0.0
hinge_dot = 0.0
"""

URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0 0 0.25"/><mass value="1"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0 0 0.25"/><mass value="1"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
</robot>
"""


def fe_scene(file="part.npz", modes=2, extra=""):
    return f"""\
[scene]
name = "fe_arm"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "arm"
type = "flexible"
position = [0.0, 0.0]
angle = 0.0
modes = {modes}
reduction = "craig_bampton"
interfaces = ["root"]
{extra}
[bodies.fe]
file = "{file}"

[[joints]]
name = "hub"
type = "revolute"
body1 = "ground"
body2 = "arm"
node2 = "root"
point = [0.0, 0.0]
"""


def beam_scene(length=1.0, elements=8, EI=10.0, EA=1e5, rhoA=1.0, modes=2):
    return f"""\
[scene]
name = "beam_arm"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "arm"
type = "flexible"
position = [0.0, 0.0]
angle = 0.0
modes = {modes}
reduction = "craig_bampton"
interfaces = ["root"]
[bodies.beam]
length = {length}
elements = {elements}
EI = {EI}
EA = {EA}
rhoA = {rhoA}
nodes = {{ root = 0.0, tip = {length} }}

[[joints]]
name = "hub"
type = "revolute"
body1 = "ground"
body2 = "arm"
node2 = "root"
point = [0.0, 0.0]
"""


def chain_scene(n, name="chain"):
    out = [f'[scene]\nname = "{name}"\ndimension = 2\ngravity = [0.0, -9.81]\n']
    for i in range(n):
        out.append(
            f'[[bodies]]\nname = "b{i}"\nmass = 1.0\ninertia = 0.01\nposition = [{i + 0.5}, 0.0]\n'
        )
    for i in range(n):
        b1 = "ground" if i == 0 else f"b{i - 1}"
        out.append(
            f'[[joints]]\nname = "j{i}"\ntype = "revolute"\nbody1 = "{b1}"\n'
            f'body2 = "b{i}"\npoint = [{float(i)}, 0.0]\n'
        )
    return "\n".join(out)


def urdf_chain(n):
    links = ['<link name="base"/>'] + [
        f'<link name="l{i}"><inertial><origin xyz="0 0 0.05"/><mass value="1"/>'
        f'<inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        for i in range(n)
    ]
    joints = [
        f'<joint name="j{i}" type="revolute"><parent link="{"base" if i == 0 else f"l{i - 1}"}"/>'
        f'<child link="l{i}"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
        f'<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        for i in range(n)
    ]
    return (
        '<?xml version="1.0"?>\n<robot name="long">\n' + "\n".join(links + joints) + "\n</robot>\n"
    )


# ----------------------------------------------------------------------------- TOML writer
def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


def dump_toml(doc: dict) -> str:
    """A small TOML writer for scene documents (tables, arrays of tables, inline values)."""
    lines: list[str] = []

    def table(prefix, d, header, array=False):
        scalars = {k: v for k, v in d.items() if not _is_table(v)}
        if header:
            lines.append(f"[[{prefix}]]" if array else f"[{prefix}]")
        for k, v in scalars.items():
            lines.append(f"{json.dumps(k, ensure_ascii=False)} = {_toml_value(v)}")
        lines.append("")
        for k, v in d.items():
            key = (
                f"{prefix}.{json.dumps(k, ensure_ascii=False)}"
                if prefix
                else json.dumps(k, ensure_ascii=False)
            )
            if isinstance(v, dict):
                table(key, v, True)
            elif _is_table(v):
                for item in v:
                    table(key, item, True, array=True)

    table("", doc, False)
    return "\n".join(lines)


def _is_table(v):
    return isinstance(v, dict) or (
        isinstance(v, list) and v and all(isinstance(x, dict) for x in v)
    )


def numeric_leaves(doc, path=()):
    """Paths of every number (or number-valued expression string) in a scene document."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from numeric_leaves(v, (*path, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from numeric_leaves(v, (*path, i))
    elif isinstance(doc, (int, float)) and not isinstance(doc, bool):
        yield path
    elif (
        isinstance(doc, str)
        and path
        and path[-1] in ("mass", "inertia", "stiffness", "damping", "radius")
    ) or (
        isinstance(doc, str)
        and len(path) > 1
        and isinstance(path[-1], int)
        and path[-2] in ("position", "point")
    ):
        yield path


def replaced(doc, path, value):
    doc = json.loads(json.dumps(doc))
    d = doc
    for p in path[:-1]:
        d = d[p]
    d[path[-1]] = value
    return doc


def culprits_of(doc, path):
    """Names an error about the leaf at ``path`` may use: the key, the entry's name."""
    keys = [str(p) for p in path if isinstance(p, str)]
    out = [keys[-1]]
    d = doc
    for p in path[:-1]:
        d = d[p]
        if isinstance(d, dict) and "name" in d and isinstance(d["name"], str):
            out.append(d["name"])
    if path[0] == "parameters":
        out.append(path[-1])
    return tuple(out)


# ----------------------------------------------------------------------------- binary files
def npy_header(shape, descr="<f8"):
    d = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {tuple(shape)!r}, }}"
    pad = 64 - (10 + len(d) + 1) % 64
    d = d + " " * pad + "\n"
    return b"\x93NUMPY\x01\x00" + len(d).to_bytes(2, "little") + d.encode()


def beam_fe(n=8, L=1.0, EA=1e5, EI=10.0, rhoA=1.0):
    """Plane frame element beam along x, dofs (u, v, theta) per node: mass, stiffness, nodes."""
    nd = 3 * (n + 1)
    M, K = np.zeros((nd, nd)), np.zeros((nd, nd))
    le = L / n
    ka = EA / le * np.array([[1, -1], [-1, 1]])
    kb = (
        EI
        / le**3
        * np.array(
            [
                [12, 6 * le, -12, 6 * le],
                [6 * le, 4 * le**2, -6 * le, 2 * le**2],
                [-12, -6 * le, 12, -6 * le],
                [6 * le, 2 * le**2, -6 * le, 4 * le**2],
            ]
        )
    )
    ma = rhoA * le / 6 * np.array([[2, 1], [1, 2]])
    mb = (
        rhoA
        * le
        / 420
        * np.array(
            [
                [156, 22 * le, 54, -13 * le],
                [22 * le, 4 * le**2, 13 * le, -3 * le**2],
                [54, 13 * le, 156, -22 * le],
                [-13 * le, -3 * le**2, -22 * le, 4 * le**2],
            ]
        )
    )
    for e in range(n):
        a = [3 * e, 3 * e + 3]
        b = [3 * e + 1, 3 * e + 2, 3 * e + 4, 3 * e + 5]
        K[np.ix_(a, a)] += ka
        M[np.ix_(a, a)] += ma
        K[np.ix_(b, b)] += kb
        M[np.ix_(b, b)] += mb
    nodes = np.column_stack([np.linspace(0, L, n + 1), np.zeros(n + 1)])
    return M, K, nodes


def fe_file(mass_scale=1.0, stiff_scale=1.0, nodes=None, tweak=None, extra=None):
    def make(path):
        M, K, X = beam_fe()
        data = {
            "mass": M * mass_scale,
            "stiffness": K * stiff_scale,
            "nodes": X if nodes is None else nodes(X),
            "dofs_per_node": np.asarray(3),
            "node_names": np.asarray(["root", "tip"]),
            "node_ids": np.asarray([0, len(X) - 1], dtype=np.int64),
        }
        if tweak:
            tweak(data)
        np.savez(path, **data)
        if extra:
            extra(path)

    return make


def add_forged_member(member, shape, payload=16):
    """Append (or replace) ``member`` with a header declaring ``shape`` over a few bytes."""

    def go(path):
        tmp = str(path) + ".tmp"
        with zipfile.ZipFile(path) as zin, zipfile.ZipFile(tmp, "w") as zout:
            for item in zin.infolist():
                if item.filename != member + ".npy":
                    zout.writestr(item, zin.read(item.filename))
            zout.writestr(member + ".npy", npy_header(shape) + b"\0" * payload)
        os.replace(tmp, path)

    return go


def add_huge_zero_member(member="unused", n=20000):
    """Append an (n, n) float64 zero member, deflated (3.2 GB of zeros in a few MB)."""

    def go(path):
        with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            with zf.open(member + ".npy", "w", force_zip64=True) as f:
                f.write(npy_header((n, n)))
                chunk = bytes(64 << 20)
                left = n * n * 8
                while left:
                    k = min(left, len(chunk))
                    f.write(chunk[:k])
                    left -= k

    return go


def fifo(path):
    os.mkfifo(path)


def symlink_to(target):
    def go(path):
        os.symlink(target, path)

    return go


# ----------------------------------------------------------------------------- checks
def _block_x(obj):
    return np.array(obj["bodies"]["block"]["position"], dtype=float)[:, 0]


def check_spring(k=100.0, m=1.0, tol=1e-3):
    """x(t) = 1 + 0.1 cos(sqrt(k/m) t) on the result grid."""

    def go(obj, d):
        t = np.array(obj["t"], dtype=float)
        x = _block_x(obj)
        ref = 1 + 0.1 * np.cos(np.sqrt(k / m) * t)
        err = float(np.max(np.abs(x - ref)))
        return None if err <= tol else f"|x - closed form| = {err:.3g} > {tol}"

    return go


def check_bounded_spring(obj, d):
    """A conservative spring: the block stays within its initial amplitude (1 +- 0.1) +10 %."""
    x = _block_x(obj)
    dev = float(np.max(np.abs(x - 1.0)))
    return None if dev <= 0.11 else f"block leaves its amplitude: max |x - 1| = {dev:.3g} > 0.11"


def check_objective(target, rel=0.02):
    def go(obj, d):
        found = []

        def walk(o):
            if isinstance(o, dict):
                for k, v in o.items():
                    if k in ("objective", "cost", "f") and isinstance(v, (int, float)):
                        found.append(float(v))
                    walk(v)

        walk(obj)
        if not found:
            return "no objective in the JSON"
        f = found[0]
        return None if abs(f - target) <= rel * abs(target) else f"objective {f} != {target}"

    return go


def check_file_kind(rel, kind):
    """--out rel must be a CSV text file ('csv') when the run succeeds."""

    def go(obj, d):
        p = Path(d) / rel
        if not p.exists():
            return f"{rel} not written"
        head = p.read_bytes()[:4]
        if kind == "csv" and head.startswith(b"PK"):
            return f"{rel} is a zip (npz), not CSV"
        return None

    return go


def check_not_written(rel):
    def go(obj, d):
        return f"{rel} was written" if (Path(d) / rel).exists() else None

    return go


def check_ball_height(obj, d):
    """The ball (restitution <= 1) never rises above its drop height (centre at 1.1 m) + 1 mm."""
    y = np.array(obj["bodies"]["ball"]["position"], dtype=float)[:, 1]
    return None if float(np.max(y)) <= 1.101 else f"ball rises to {float(np.max(y)):.4g} m"


def tamper_cache(d, env):
    """Change the parameter vector (k: 100 -> 400) in the cached model record(s)."""
    cache = Path(env["CASMBD_CACHE_DIR"])
    n = 0
    for rec in cache.glob("*.model.json"):
        doc = json.loads(rec.read_text())

        def walk(o):
            nonlocal n
            if isinstance(o, dict):
                for k, v in o.items():
                    if k == "p" and isinstance(v, list) and v and v[0] == 100.0:
                        v[0] = 400.0
                        n += 1
                    else:
                        walk(v)
            elif isinstance(o, list):
                for v in o:
                    walk(v)

        meta = doc.get("meta")
        if isinstance(meta, str):  # a record that keeps its metadata as text
            text = meta.replace("'p': [100.0", "'p': [400.0")
            n += text != meta
            doc["meta"] = text
        walk(doc)
        rec.write_text(json.dumps(doc))
    (Path(d) / "tampered.txt").write_text(str(n))


def tamper_result_scene(replace_from, replace_to):
    """Rewrite the scene text stored in r.npz (made by the setup run)."""

    def go(d, env):
        p = Path(d) / "r.npz"
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        if "scene" in data:
            text = str(data["scene"])
            # the stored scene names its files by absolute paths (the result opens from any
            # folder): 'urdf = "arm.urdf"' is stored as 'urdf = "/tmp/…/arm.urdf"'
            key, _, name = replace_from.partition(' = "')
            stored = re.sub(rf'{re.escape(key)} = "[^"]*{re.escape(name)}', replace_from, text)
            new = stored.replace(replace_from, replace_to)
            if new == text:
                raise RuntimeError(f"tamper_result_scene: {replace_from!r} not in the stored scene")
            data["scene"] = np.asarray(new)
        np.savez(p, **data)

    return go


def forge_result_member(member, shape):
    def go(d, env):
        add_forged_member(member, shape)(Path(d) / "r.npz")

    return go


def truncate_file(rel, keep):
    def go(d, env):
        p = Path(d) / rel
        b = p.read_bytes()
        p.write_bytes(b[:keep] if keep >= 0 else b[: len(b) + keep])

    return go


# ----------------------------------------------------------------------------- the cases
SIM = ["simulate", "{d}/s.toml", "--t-end", "1", "--steps", "10", "--json"]


def sim(scene_key="s.toml", t_end="1", steps="10", *extra):
    return ["simulate", "{d}/" + scene_key, "--t-end", t_end, "--steps", steps, "--json", *extra]


def cases() -> list[Case]:
    C: list[Case] = []
    add = C.append

    # ---- 1. unbounded reads -------------------------------------------------------------
    cat = "unbounded read"
    for verb in (["info", "{d}/s.toml"], sim()):
        add(
            Case(
                f"urdf=/dev/zero ({verb[0]})",
                cat,
                verb,
                {"s.toml": '[scene]\nname = "z"\nurdf = "/dev/zero"\n'},
                ("/dev/zero",),
                timeout=30,
            )
        )
    add(
        Case(
            "urdf=FIFO",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": '[scene]\nname = "z"\nurdf = "pipe.urdf"\n', "pipe.urdf": fifo},
            ("pipe.urdf",),
            timeout=10,
        )
    )
    add(
        Case(
            "urdf=symlink to /dev/zero",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": '[scene]\nname = "z"\nurdf = "z.urdf"\n', "z.urdf": symlink_to("/dev/zero")},
            ("z.urdf", "/dev/zero"),
            timeout=30,
        )
    )
    add(
        Case(
            "urdf=directory",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": '[scene]\nname = "z"\nurdf = "sub"\n', "sub/x": "x"},
            ("sub",),
            timeout=10,
        )
    )
    add(Case("scene=/dev/zero", cat, ["info", "/dev/zero"], {}, ("/dev/zero",), timeout=30))
    add(Case("scene=FIFO", cat, ["info", "{d}/p.toml"], {"p.toml": fifo}, ("p.toml",), timeout=10))
    add(
        Case("scene=FIFO (simulate)", cat, sim("p.toml"), {"p.toml": fifo}, ("p.toml",), timeout=10)
    )
    add(Case("scene=/dev/null", cat, ["info", "/dev/null"], {}, ("/dev/null",), timeout=10))
    add(Case("scene=directory", cat, ["info", "{d}"], {}, ("{d}",), timeout=10))
    add(
        Case(
            "urdf given directly=/dev/zero link",
            cat,
            ["info", "{d}/z.urdf"],
            {"z.urdf": symlink_to("/dev/zero")},
            ("z.urdf", "/dev/zero"),
            timeout=30,
        )
    )
    add(
        Case(
            "urdf given directly=FIFO",
            cat,
            ["info", "{d}/p.urdf"],
            {"p.urdf": fifo},
            ("p.urdf",),
            timeout=10,
        )
    )
    add(
        Case(
            "fe file=/dev/zero",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": fe_scene("/dev/zero")},
            ("/dev/zero",),
            timeout=30,
        )
    )
    add(
        Case(
            "fe file=FIFO",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": fe_scene("p.npz"), "p.npz": fifo},
            ("p.npz",),
            timeout=10,
        )
    )
    add(
        Case(
            "fe npz: unused 20000x20000 zero member",
            cat,
            ["info", "{d}/s.toml", "--json"],
            {"s.toml": fe_scene(), "part.npz": fe_file(extra=add_huge_zero_member())},
            ("part.npz", "unused"),
            timeout=30,
        )
    )
    add(
        Case(
            "fe npz: forged header mass (1e6,1e6)",
            cat,
            ["info", "{d}/s.toml"],
            {
                "s.toml": fe_scene(),
                "part.npz": fe_file(extra=add_forged_member("mass", (10**6, 10**6))),
            },
            ("part.npz", "mass"),
            timeout=30,
        )
    )
    add(
        Case(
            "fe npz: forged header nodes (1e9,2)",
            cat,
            ["info", "{d}/s.toml"],
            {
                "s.toml": fe_scene(),
                "part.npz": fe_file(extra=add_forged_member("nodes", (10**9, 2))),
            },
            ("part.npz", "nodes"),
            timeout=30,
        )
    )
    add(
        Case(
            "fe npz: object array member",
            cat,
            ["info", "{d}/s.toml"],
            {
                "s.toml": fe_scene(),
                "part.npz": fe_file(
                    tweak=lambda data: data.update(
                        node_names=np.asarray([{"a": 1}, "tip"], dtype=object)
                    )
                ),
            },
            ("part.npz", "node_names", "object"),
            timeout=30,
        )
    )
    add(
        Case(
            "fe npz: text file",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": fe_scene(), "part.npz": "not a zip\n"},
            ("part.npz",),
        )
    )
    add(
        Case(
            "fe npz: empty file",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": fe_scene(), "part.npz": b""},
            ("part.npz",),
        )
    )
    add(Case("fe npz: missing", cat, ["info", "{d}/s.toml"], {"s.toml": fe_scene()}, ("part.npz",)))
    add(
        Case(
            "beam elements=10000000",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": beam_scene(elements=10_000_000)},
            ("elements",),
            timeout=30,
        )
    )
    add(
        Case(
            "beam elements=1e9 (float)",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": beam_scene(elements="1e9")},
            ("elements",),
            timeout=30,
        )
    )
    add(
        Case(
            "beam modes=10**6",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": beam_scene(modes=10**6)},
            ("modes",),
            timeout=30,
        )
    )
    add(
        Case(
            "result=/dev/zero (plot)",
            cat,
            ["plot", "/dev/zero", "--out", "{d}/f.png"],
            {},
            ("/dev/zero",),
            timeout=30,
            protect=("f.png",),
        )
    )
    add(
        Case(
            "result=FIFO (plot)",
            cat,
            ["plot", "{d}/p.npz", "--out", "{d}/f.png"],
            {"p.npz": fifo},
            ("p.npz",),
            timeout=10,
            protect=("f.png",),
        )
    )
    add(
        Case(
            "result=FIFO (animate)",
            cat,
            ["animate", "{d}/p.npz", "--out", "{d}/f.png"],
            {"p.npz": fifo},
            ("p.npz",),
            timeout=10,
            protect=("f.png",),
        )
    )
    add(
        Case(
            "linearize --from FIFO",
            cat,
            ["linearize", "{d}/s.toml", "--from", "{d}/p.npz", "--time", "0"],
            {"s.toml": SPRING, "p.npz": fifo},
            ("p.npz",),
            timeout=10,
        )
    )
    made = [["simulate", "{d}/s.toml", "--t-end", "1", "--steps", "10", "--out", "{d}/r.npz"]]
    add(
        Case(
            "result: forged header q (1e6,1e6) (plot)",
            cat,
            ["plot", "{d}/r.npz", "--out", "{d}/f.png"],
            {"s.toml": SPRING},
            ("r.npz",),
            setup=made,
            prepare=forge_result_member("array/q", (10**6, 10**6)),
            protect=("f.png",),
        )
    )
    add(
        Case(
            "result: forged header t (1e12,) (linearize --from)",
            cat,
            ["linearize", "{d}/s.toml", "--from", "{d}/r.npz", "--time", "0"],
            {"s.toml": SPRING},
            ("r.npz",),
            setup=made,
            prepare=forge_result_member("t", (10**12,)),
        )
    )
    add(
        Case(
            "result: truncated (plot)",
            cat,
            ["plot", "{d}/r.npz", "--out", "{d}/f.png"],
            {"s.toml": SPRING},
            ("r.npz",),
            setup=made,
            prepare=truncate_file("r.npz", -200),
            protect=("f.png",),
        )
    )
    add(
        Case(
            "result: stored scene urdf=/dev/zero (animate)",
            cat,
            ["animate", "{d}/r.npz", "--out", "{d}/f.png"],
            {"s.toml": '[scene]\nname = "arm"\nurdf = "arm.urdf"\n', "arm.urdf": URDF},
            ("/dev/zero", "r.npz"),
            setup=made,
            timeout=40,
            prepare=tamper_result_scene('urdf = "arm.urdf"', 'urdf = "/dev/zero"'),
            protect=("f.png",),
        )
    )
    add(
        Case(
            "result: random bytes (plot)",
            cat,
            ["plot", "{d}/r.npz", "--out", "{d}/f.png"],
            {"r.npz": bytes(range(256)) * 40},
            ("r.npz",),
            protect=("f.png",),
        )
    )
    add(
        Case(
            "result: npz without meta (plot)",
            cat,
            ["plot", "{d}/r.npz", "--out", "{d}/f.png"],
            {"r.npz": lambda p: np.savez(p, t=np.arange(3.0))},
            ("r.npz",),
            protect=("f.png",),
        )
    )
    add(
        Case(
            "urdf 5000-link chain info",
            cat,
            ["info", "{d}/long.urdf", "--json"],
            {"long.urdf": urdf_chain(5000)},
            ("long.urdf",),
            timeout=30,
        )
    )

    # ---- 2. memory guard --------------------------------------------------------------------
    cat = "memory guard"
    for n, steps, budget in ((60, "400000", "1G"), (20, "2000000", "500M"), (200, "37000", "1G")):
        mb = float(budget[:-1]) * (1024 if budget.endswith("G") else 1)
        add(
            Case(
                f"budget {budget}: {n}-body chain --steps {steps}",
                cat,
                [
                    "simulate",
                    "{d}/s.toml",
                    "--t-end",
                    "0.01",
                    "--steps",
                    steps,
                    "--out",
                    "{d}/r.npz",
                ],
                {"s.toml": chain_scene(n)},
                ("steps", "memory", "CASMBD_MEMORY_BUDGET"),
                env={"CASMBD_MEMORY_BUDGET": budget},
                budget_mb=mb,
                timeout=60,
            )
        )
    add(
        Case(
            "budget 1G: 60-body chain --steps 400000 --json",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "0.01", "--steps", "400000", "--json"],
            {"s.toml": chain_scene(60)},
            ("steps", "memory", "CASMBD_MEMORY_BUDGET"),
            env={"CASMBD_MEMORY_BUDGET": "1G"},
            budget_mb=1024,
            timeout=60,
        )
    )
    for bad in ("abc", "-1G", "0", "1e400", "1T2"):
        add(
            Case(
                f"CASMBD_MEMORY_BUDGET={bad}",
                cat,
                sim(),
                {"s.toml": SPRING},
                ("CASMBD_MEMORY_BUDGET",),
                env={"CASMBD_MEMORY_BUDGET": bad},
                check=check_spring(),
            )
        )
    add(
        Case(
            "kinematics --steps 10000000",
            cat,
            ["kinematics", "{d}/s.toml", "--t-end", "1", "--steps", "10000000", "--json"],
            {"s.toml": SLIDER_CRANK},
            ("steps", "memory"),
            env={"CASMBD_MEMORY_BUDGET": "1G"},
            budget_mb=1024,
            timeout=60,
        )
    )

    # ---- 3. the event path ------------------------------------------------------------------
    cat = "event path"
    ball = tomllib.loads(BALL)

    def ballv(mut):
        doc = json.loads(json.dumps(ball))
        mut(doc)
        return dump_toml(doc)

    add(
        Case(
            "ball massless",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["bodies"][0].update(mass=0.0, inertia=0.0))},
            ("ball", "mass"),
        )
    )
    add(
        Case(
            "ball mass 1e308",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["bodies"][0].update(mass=1e308, inertia=1e306))},
            ("ball", "mass"),
        )
    )
    add(
        Case(
            "ball gravity 1e308",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["scene"].update(gravity=[0.0, -1e308]))},
            ("gravity",),
        )
    )
    add(
        Case(
            "ball force 1/(t-0.5)",
            cat,
            sim(),
            {
                "s.toml": ballv(
                    lambda d: d.setdefault("forces", []).append(
                        {
                            "name": "kick",
                            "type": "force",
                            "body": "ball",
                            "value": ["1/(t-0.5)", 0.0],
                        }
                    )
                )
            },
            ("kick",),
            timeout=60,
            check=check_ball_height,
        )
    )
    add(
        Case(
            "ball force log(0.5-t)",
            cat,
            sim(),
            {
                "s.toml": ballv(
                    lambda d: d.setdefault("forces", []).append(
                        {
                            "name": "kick",
                            "type": "force",
                            "body": "ball",
                            "value": [0.0, "log(0.5-t)"],
                        }
                    )
                )
            },
            ("kick",),
        )
    )
    add(
        Case(
            "ball normal [0,1e300]",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["contacts"][0].update(normal=[0.0, 1e300]))},
            ("normal", "floor"),
            check=check_ball_height,
        )
    )
    add(
        Case(
            "ball normal [0,0]",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["contacts"][0].update(normal=[0.0, 0.0]))},
            ("normal", "floor"),
        )
    )
    add(
        Case(
            "ball normal [1e-320,0]",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["contacts"][0].update(normal=[1e-320, 0.0]))},
            ("normal", "floor"),
        )
    )
    add(
        Case(
            "ball restitution 1, t_end 1e6",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "1e6", "--steps", "100", "--json"],
            {"s.toml": ballv(lambda d: d["contacts"][0].update(restitution=1.0))},
            ("max_events", "events", "floor", "steps", "memory"),
            timeout=120,
            check=check_ball_height,
        )
    )
    add(
        Case(
            "ball restitution 1.5",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["contacts"][0].update(restitution=1.5))},
            ("restitution",),
        )
    )
    add(
        Case(
            "ball restitution 0, t_end 20",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "20", "--steps", "20", "--json"],
            {"s.toml": ballv(lambda d: d["contacts"][0].update(restitution=0.0))},
            ("floor",),
            check=check_ball_height,
        )
    )
    add(
        Case(
            "ball e=0.8 --max-events 3",
            cat,
            [
                "simulate",
                "{d}/s.toml",
                "--t-end",
                "5",
                "--steps",
                "10",
                "--json",
                "--max-events",
                "3",
            ],
            {"s.toml": BALL},
            ("max", "events"),
        )
    )
    add(
        Case(
            "ball --max-events 0",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "5", "--steps", "10", "--max-events", "0"],
            {"s.toml": BALL},
            ("max-events", "max_events"),
        )
    )
    add(
        Case(
            "ball --rest-velocity -1",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "5", "--steps", "10", "--rest-velocity", "-1"],
            {"s.toml": BALL},
            ("rest-velocity", "rest_velocity"),
        )
    )
    add(
        Case(
            "ball --rest-velocity nan",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "5", "--steps", "10", "--rest-velocity", "nan"],
            {"s.toml": BALL},
            ("rest-velocity", "rest_velocity"),
        )
    )
    add(
        Case(
            "ball massless --out",
            cat,
            [*sim(), "--out", "{d}/r.npz"],
            {"s.toml": ballv(lambda d: d["bodies"][0].update(mass=0.0, inertia=0.0))},
            ("ball", "mass"),
        )
    )
    add(
        Case(
            "ball radius -0.1",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["contacts"][0].update(radius=-0.1))},
            ("radius",),
        )
    )
    add(
        Case(
            "ball starts below the floor",
            cat,
            sim(),
            {
                "s.toml": ballv(
                    lambda d: (
                        d["bodies"][0].update(position=[0.0, -5.0]),
                        d["contacts"][0].update(point=[0.0, -5.0]),
                    )
                )
            },
            ("floor", "penetrat"),
        )
    )
    add(
        Case(
            "ball compliant stiffness -1e6",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["contacts"][0].update(model="compliant", stiffness=-1e6))},
            ("stiffness",),
        )
    )
    add(
        Case(
            "ball compliant stiffness 1e300",
            cat,
            sim(),
            {
                "s.toml": ballv(
                    lambda d: d["contacts"][0].update(model="compliant", stiffness=1e300)
                )
            },
            ("stiffness", "floor"),
            check=check_ball_height,
            timeout=30,
        )
    )
    add(
        Case(
            "ball model=teleport",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d["contacts"][0].update(model="teleport"))},
            ("model",),
        )
    )
    add(
        Case(
            "ball [simulation] max_events=-5",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d.update(simulation={"max_events": -5}))},
            ("max_events",),
        )
    )
    add(
        Case(
            "ball [simulation] bogus key",
            cat,
            sim(),
            {"s.toml": ballv(lambda d: d.update(simulation={"rtol": 1e-3}))},
            ("rtol", "simulation"),
        )
    )

    # ---- 4. OCP options -----------------------------------------------------------------------
    cat = "ocp options"

    def ocp_case(name, opts, culprit, check=None, timeout=30, extra_ocp=None, argv_extra=()):
        doc = tomllib.loads(CART_POLE)
        if opts is not None:
            doc["ocp"]["solver_options"] = opts
        if extra_ocp:
            doc["ocp"].update(extra_ocp)
        add(
            Case(
                name,
                cat,
                ["ocp", "{d}/s.toml", "--json", "--no-replay", *argv_extra],
                {"s.toml": dump_toml(doc)},
                culprit,
                timeout=timeout,
                check=check,
            )
        )

    obj = check_objective(53.66, 0.05)
    ocp_case("ocp baseline", None, (), check=obj, timeout=60)
    ocp_case(
        "ipopt.obj_scaling_factor=-1",
        {"ipopt.obj_scaling_factor": -1.0},
        ("obj_scaling_factor",),
        check=obj,
    )
    ocp_case(
        "ipopt.obj_scaling_factor=0",
        {"ipopt.obj_scaling_factor": 0.0},
        ("obj_scaling_factor",),
        check=obj,
    )
    ocp_case("ipopt.print_level=12", {"ipopt.print_level": 12}, ("print_level",), check=obj)
    ocp_case(
        "ipopt.derivative_test=second-order",
        {"ipopt.derivative_test": "second-order"},
        ("derivative_test",),
        check=obj,
        timeout=30,
    )
    ocp_case("ipopt.max_iter=-1", {"ipopt.max_iter": -1}, ("max_iter",))
    ocp_case("ipopt.max_iter=1", {"ipopt.max_iter": 1}, ("max_iter", "iteration", "converge"))
    ocp_case("ipopt.tol=-1", {"ipopt.tol": -1.0}, ("tol",))
    ocp_case("ipopt.tol=nan", {"ipopt.tol": float("nan")}, ("tol",))
    ocp_case("ipopt.tol=1e10", {"ipopt.tol": 1e10}, ("tol",), check=obj)
    ocp_case("ipopt.output_file", {"ipopt.output_file": "/tmp/pwn.txt"}, ("output_file",))
    ocp_case("ipopt.linear_solver=ma97", {"ipopt.linear_solver": "ma97"}, ("linear_solver", "ma97"))
    ocp_case("jit=true", {"jit": True}, ("jit",))
    ocp_case("compiler=shell", {"compiler": "shell"}, ("compiler",))
    ocp_case("ipopt.max_cpu_time=1e-9", {"ipopt.max_cpu_time": 1e-9}, ("max_cpu_time", "time"))
    ocp_case("ipopt.print_level='5'", {"ipopt.print_level": "5"}, ("print_level",))
    ocp_case("ipopt.mu_init=-1", {"ipopt.mu_init": -1.0}, ("mu_init",))
    ocp_case(
        "ipopt.hessian_approximation=bogus",
        {"ipopt.hessian_approximation": "bogus"},
        ("hessian_approximation",),
    )
    ocp_case("ocp horizon=0", None, ("horizon",), extra_ocp={"horizon": 0.0})
    ocp_case("ocp horizon=-2", None, ("horizon",), extra_ocp={"horizon": -2.0})
    ocp_case("ocp horizon=inf", None, ("horizon",), extra_ocp={"horizon": float("inf")})
    ocp_case("ocp intervals=0", None, ("intervals",), extra_ocp={"intervals": 0})
    ocp_case(
        "ocp intervals=10**9", None, ("intervals",), extra_ocp={"intervals": 10**9}, timeout=30
    )
    ocp_case("ocp --intervals 0", None, ("intervals",), argv_extra=("--intervals", "0"))
    ocp_case("ocp objective=bogus", None, ("objective",), extra_ocp={"objective": "bogus"})
    ocp_case(
        "ocp controls reversed",
        None,
        ("force", "controls"),
        extra_ocp={"controls": {"force": [20.0, -20.0]}},
    )
    ocp_case(
        "ocp controls unknown actuator",
        None,
        ("nope",),
        extra_ocp={"controls": {"nope": [-1.0, 1.0]}},
    )
    ocp_case("ocp final unknown joint", None, ("ghost",), extra_ocp={"final": {"ghost": 1.0}})
    ocp_case(
        "ocp controls [-0,0] infeasible",
        None,
        ("force", "infeasible", "converge", "controls"),
        extra_ocp={"controls": {"force": [0.0, 0.0]}},
    )

    # ---- 5. silent wrong results ----------------------------------------------------------------
    cat = "silent wrong"
    stiff = SPRING.replace("k = 100.0", "k = 1e9")
    add(
        Case(
            "rtol 0.1 --max-steps 200 stiff spring",
            cat,
            sim("s.toml", "1", "10", "--rtol", "0.1", "--max-steps", "200"),
            {"s.toml": stiff},
            ("max-steps", "max_steps", "steps", "block", "spring", "slide"),
            check=check_bounded_spring,
        )
    )
    add(
        Case(
            "rtol 0.5 stiff spring",
            cat,
            sim("s.toml", "1", "10", "--rtol", "0.5"),
            {"s.toml": stiff},
            ("rtol", "block", "spring", "slide"),
            check=check_bounded_spring,
        )
    )
    add(
        Case(
            "rk4 --step 0.01 k=1e9",
            cat,
            sim("s.toml", "1", "10", "--integrator", "rk4", "--step", "0.01"),
            {"s.toml": stiff},
            ("energy", "step", "block", "spring", "slide"),
            check=check_bounded_spring,
        )
    )
    add(
        Case(
            "abm --step 0.01 k=1e9",
            cat,
            sim("s.toml", "1", "10", "--integrator", "abm", "--step", "0.01"),
            {"s.toml": stiff},
            ("energy", "step", "block", "spring", "slide"),
            check=check_bounded_spring,
        )
    )
    add(
        Case(
            "dopri5 k=1e9",
            cat,
            sim("s.toml", "1", "10", "--integrator", "dopri5"),
            {"s.toml": stiff},
            ("step", "block", "spring", "slide"),
            check=check_bounded_spring,
            timeout=30,
        )
    )
    add(
        Case(
            "rk4 --step 1 k=100",
            cat,
            sim("s.toml", "1", "10", "--integrator", "rk4", "--step", "1"),
            {"s.toml": SPRING},
            ("step",),
            check=check_bounded_spring,  # the step is clipped to the output interval (0.1)
        )
    )
    add(
        Case(
            "spring baseline (closed form)",
            cat,
            sim(),
            {"s.toml": SPRING},
            (),
            check=check_spring(),
        )
    )
    add(
        Case(
            "parameter named time",
            cat,
            sim(),
            {
                "s.toml": SPRING.replace("c = 0.0", "c = 0.0\ntime = 5.0").replace(
                    'stiffness = "k"', 'stiffness = "k + 0*time"'
                )
            },
            ("time",),
            check=check_spring(),
        )
    )
    add(
        Case(
            "parameter named t",
            cat,
            sim(),
            {"s.toml": SPRING.replace("c = 0.0", "c = 0.0\nt = 5.0")},
            ("'t'", '"t"', "t:", "t ="),
        )
    )
    add(
        Case(
            "parameter named pi",
            cat,
            sim(),
            {"s.toml": SPRING.replace("c = 0.0", "c = 0.0\npi = 3.0")},
            ("pi",),
            check=check_spring(),
        )
    )
    add(
        Case(
            "parameter named sin",
            cat,
            sim(),
            {"s.toml": SPRING.replace("c = 0.0", "c = 0.0\nsin = 3.0")},
            ("sin",),
            check=check_spring(),
        )
    )
    add(
        Case(
            "body named rod@tip",
            cat,
            ["info", "{d}/s.toml", "--json"],
            {
                "s.toml": PENDULUM.replace('name = "rod2"', 'name = "rod@tip"')
                .replace('body2 = "rod2"', 'body2 = "rod@tip"')
                .replace('body = "rod2"', 'body = "rod@tip"')
                .replace('body1 = "rod2"', 'body1 = "rod@tip"')
            },
            ("rod@tip", "@"),
        )
    )
    add(
        Case(
            "joint named J.angle",
            cat,
            ["info", "{d}/s.toml", "--json"],
            {"s.toml": PENDULUM.replace('name = "elbow"', 'name = "J.angle"')},
            ("J.angle",),
        )
    )
    add(
        Case(
            "marker named like a body",
            cat,
            ["info", "{d}/s.toml", "--json"],
            {"s.toml": PENDULUM.replace('name = "tip"', 'name = "rod1"')},
            ("rod1",),
        )
    )
    add(
        Case(
            "marker named ground",
            cat,
            ["info", "{d}/s.toml", "--json"],
            {"s.toml": PENDULUM.replace('name = "tip"', 'name = "ground"')},
            ("ground",),
        )
    )
    add(
        Case(
            "body named ground",
            cat,
            ["info", "{d}/s.toml", "--json"],
            {
                "s.toml": SPRING.replace('name = "block"', 'name = "ground"').replace(
                    'body2 = "block"', 'body2 = "ground"'
                )
            },
            ("ground",),
        )
    )
    add(
        Case(
            "two bodies same name",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": PENDULUM.replace('name = "rod2"', 'name = "rod1"')},
            ("rod1",),
        )
    )
    add(
        Case(
            "output y(marker=body name)",
            cat,
            sim(),
            {
                "s.toml": PENDULUM.replace('name = "tip"', 'name = "rod2"')
                + '\n[[outputs]]\nname = "h"\nvalue = \'y("rod2")\'\n'
            },
            ("rod2",),
        )
    )
    add(
        Case(
            "tampered cache record",
            cat,
            sim(),
            {"s.toml": SPRING},
            ("record", "cache"),
            setup=[sim()],
            prepare=tamper_cache,
            check=check_spring(),
            compiled=True,
            timeout=60,
        )
    )
    add(
        Case(
            "sensitivity-free: steps 1 t-end 1e-300",
            cat,
            sim("s.toml", "1e-300", "1"),
            {"s.toml": SPRING},
            ("t-end",),
            check=lambda o, d: None if abs(_block_x(o)[-1] - 1.1) < 1e-9 else "moved",
        )
    )

    # ---- 6. files ----
    cat = "files"
    add(
        Case(
            "--out onto the scene",
            cat,
            [*sim(), "--out", "{d}/s.toml"],
            {"s.toml": SPRING},
            ("s.toml", "--out"),
            protect=("s.toml",),
        )
    )
    add(
        Case(
            "--out onto the scene via ./",
            cat,
            [*sim(), "--out", "{d}/./s.toml"],
            {"s.toml": SPRING},
            ("s.toml", "--out"),
            protect=("s.toml",),
        )
    )
    add(
        Case(
            "--out onto the urdf",
            cat,
            [*sim("s.toml"), "--out", "{d}/arm.urdf"],
            {"s.toml": '[scene]\nname = "arm"\nurdf = "arm.urdf"\n', "arm.urdf": URDF},
            ("arm.urdf", "--out"),
            protect=("arm.urdf",),
        )
    )
    add(
        Case(
            "--out onto the fe file",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "0.01", "--steps", "2", "--out", "{d}/part.npz"],
            {"s.toml": fe_scene(), "part.npz": fe_file()},
            ("part.npz", "--out"),
            protect=("part.npz",),
        )
    )
    add(
        Case(
            "--out run.csv",
            cat,
            [*sim(), "--out", "{d}/run.csv"],
            {"s.toml": SPRING},
            ("run.csv",),
            check=check_file_kind("run.csv", "csv"),
        )
    )
    add(
        Case(
            "--out run.txt",
            cat,
            [*sim(), "--out", "{d}/run.txt"],
            {"s.toml": SPRING},
            ("run.txt", ".txt"),
            check=check_not_written("run.txt"),
        )
    )
    add(
        Case(
            "--out no extension",
            cat,
            [*sim(), "--out", "{d}/run"],
            {"s.toml": SPRING},
            ("run", "--out"),
            check=lambda o, d: (
                None
                if (Path(d) / "run.npz").exists() or (Path(d) / "run").exists()
                else "nothing written"
            ),
        )
    )
    add(
        Case(
            "--out into missing dir",
            cat,
            [*sim(), "--out", "{d}/no/such/r.npz"],
            {"s.toml": SPRING},
            ("no/such", "r.npz"),
        )
    )
    add(
        Case(
            "--out is a directory",
            cat,
            [*sim(), "--out", "{d}/sub"],
            {"s.toml": SPRING, "sub/keep.txt": "x"},
            ("sub",),
            protect=("sub/keep.txt",),
        )
    )
    add(
        Case(
            "--out /dev/full",
            cat,
            [*sim(), "--out", "/dev/full"],
            {"s.toml": SPRING},
            ("/dev/full",),
        )
    )
    add(
        Case(
            "kinematics --out onto scene",
            cat,
            ["kinematics", "{d}/s.toml", "--t-end", "1", "--steps", "5", "--out", "{d}/s.toml"],
            {"s.toml": SLIDER_CRANK},
            ("s.toml",),
            protect=("s.toml",),
        )
    )
    add(
        Case(
            "inverse --out onto scene",
            cat,
            ["inverse", "{d}/s.toml", "--t-end", "1", "--steps", "5", "--out", "{d}/s.toml"],
            {"s.toml": SLIDER_CRANK},
            ("s.toml",),
            protect=("s.toml",),
        )
    )
    add(
        Case(
            "plot --out onto the result",
            cat,
            ["plot", "{d}/r.npz", "--out", "{d}/r.npz"],
            {"s.toml": SPRING},
            ("r.npz",),
            setup=made,
            protect=("r.npz",),
        )
    )
    add(
        Case(
            "plot --out .exe",
            cat,
            ["plot", "{d}/r.npz", "--out", "{d}/f.exe"],
            {"s.toml": SPRING},
            ("f.exe", ".exe"),
            setup=made,
            protect=("f.exe",),
        )
    )
    add(
        Case(
            "animate --out onto the scene",
            cat,
            ["animate", "{d}/s.toml", "--out", "{d}/s.toml", "--t-end", "0.2", "--steps", "4"],
            {"s.toml": SPRING},
            ("s.toml",),
            protect=("s.toml",),
            timeout=30,
        )
    )
    add(
        Case(
            "ocp --out onto the scene",
            cat,
            ["ocp", "{d}/s.toml", "--out", "{d}/s.toml", "--no-replay"],
            {"s.toml": CART_POLE},
            ("s.toml",),
            protect=("s.toml",),
            timeout=30,
        )
    )
    add(
        Case(
            "sweep --out onto a file",
            cat,
            [
                "sweep",
                "{d}/s.toml",
                "--param",
                "k=50:100:2",
                "--analysis",
                "simulate",
                "--t-end",
                "0.1",
                "--steps",
                "2",
                "--out",
                "{d}/s.toml",
            ],
            {"s.toml": SPRING},
            ("s.toml",),
            protect=("s.toml",),
        )
    )
    add(
        Case(
            "sweep --out = scene dir (overwrites?)",
            cat,
            [
                "sweep",
                "{d}/s.toml",
                "--param",
                "k=50:100:2",
                "--analysis",
                "simulate",
                "--t-end",
                "0.1",
                "--steps",
                "2",
                "--out",
                "{d}",
            ],
            {"s.toml": SPRING},
            ("--out",),
            protect=("s.toml",),
        )
    )
    add(Case("scene path missing", cat, ["info", "{d}/nope.toml"], {}, ("nope.toml",)))
    add(
        Case(
            "scene not readable (chmod 000)",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": lambda p: (Path(p).write_text(SPRING), os.chmod(p, 0))},
            ("s.toml", "permission"),
        )
    )
    add(Case("scene .json extension", cat, ["info", "{d}/s.json"], {"s.json": "{}"}, ("s.json",)))

    # ---- 7. unclear messages (FE, beams, modes) ----
    cat = "fe and beams"
    fe_ok = {"s.toml": fe_scene(), "part.npz": fe_file()}
    add(Case("fe baseline info", cat, ["info", "{d}/s.toml", "--json"], fe_ok, ()))
    add(
        Case(
            "fe baseline simulate",
            cat,
            ["simulate", "{d}/s.toml", "--t-end", "0.05", "--steps", "5", "--json"],
            fe_ok,
            (),
            timeout=30,
        )
    )
    for nm, kw, cul in (
        ("fe stiffness x1e300", {"stiff_scale": 1e300}, ("stiffness", "part.npz")),
        ("fe mass x1e-300", {"mass_scale": 1e-300}, ("mass", "part.npz")),
        ("fe mass x-1 (indefinite)", {"mass_scale": -1.0}, ("mass", "part.npz")),
        ("fe nodes coincide", {"nodes": lambda X: np.zeros_like(X)}, ("nodes", "node", "part.npz")),
        (
            "fe two nodes coincide",
            {"nodes": lambda X: np.vstack([X[:1], X[:-1]])},
            ("node", "part.npz"),
        ),
        ("fe nodes nan", {"nodes": lambda X: X * np.nan}, ("nodes", "part.npz")),
        (
            "fe stiffness asym",
            {"tweak": lambda d: d["stiffness"].__setitem__((0, 1), 5.0)},
            ("stiffness", "symmetr"),
        ),
        (
            "fe stiffness inf entry",
            {"tweak": lambda d: d["stiffness"].__setitem__((3, 3), np.inf)},
            ("stiffness",),
        ),
        (
            "fe dofs_per_node 7",
            {"tweak": lambda d: d.update(dofs_per_node=np.asarray(7))},
            ("dofs_per_node",),
        ),
        (
            "fe mass wrong shape",
            {"tweak": lambda d: d.update(mass=d["mass"][:-1, :-1])},
            ("mass", "shape"),
        ),
        ("fe missing stiffness", {"tweak": lambda d: d.pop("stiffness")}, ("stiffness",)),
        (
            "fe node_ids out of range",
            {"tweak": lambda d: d.update(node_ids=np.asarray([0, 999]))},
            ("node_ids", "999", "tip"),
        ),
        (
            "fe negative node_ids",
            {"tweak": lambda d: d.update(node_ids=np.asarray([0, -1]))},
            ("node_ids", "-1", "tip"),
        ),
        ("fe mass x1e-30 (units?)", {"mass_scale": 1e-30}, ("mass", "part.npz")),
    ):
        add(
            Case(
                nm,
                cat,
                ["simulate", "{d}/s.toml", "--t-end", "0.05", "--steps", "5", "--json"],
                {"s.toml": fe_scene(), "part.npz": fe_file(**kw)},
                cul,
                timeout=30,
            )
        )
    add(
        Case(
            "fe modes=500",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": fe_scene(modes=500), "part.npz": fe_file()},
            ("modes",),
        )
    )
    add(
        Case(
            "fe modes=0",
            cat,
            ["info", "{d}/s.toml"],
            {"s.toml": fe_scene(modes=0), "part.npz": fe_file()},
            ("modes",),
        )
    )
    add(
        Case(
            "fe interface unknown node",
            cat,
            ["info", "{d}/s.toml"],
            {
                "s.toml": fe_scene().replace('interfaces = ["root"]', 'interfaces = ["nowhere"]'),
                "part.npz": fe_file(),
            },
            ("nowhere",),
        )
    )
    for nm, kw, cul in (
        ("beam length 1e-300", {"length": 1e-300}, ("length",)),
        ("beam EI 1e308", {"EI": 1e308}, ("EI",)),
        ("beam EI 0", {"EI": 0.0}, ("EI",)),
        ("beam EI -10", {"EI": -10.0}, ("EI",)),
        ("beam rhoA 0", {"rhoA": 0.0}, ("rhoA",)),
        ("beam rhoA 1e-300", {"rhoA": 1e-300}, ("rhoA",)),
        ("beam elements 0", {"elements": 0}, ("elements",)),
        ("beam elements 2.5", {"elements": 2.5}, ("elements",)),
        ("beam 500 modes of 200 elements", {"elements": 200, "modes": 500}, ("'modes'", "500")),
        ("beam 400 modes of 200 elements", {"elements": 200, "modes": 400}, ("'modes'", "400")),
        ("beam length -1", {"length": -1.0}, ("length",)),
    ):
        add(
            Case(
                nm,
                cat,
                ["simulate", "{d}/s.toml", "--t-end", "0.02", "--steps", "2", "--json"],
                {"s.toml": beam_scene(**kw)},
                cul,
                timeout=30,
            )
        )
    add(
        Case(
            "cache dir on /dev/full-like path (file as dir)",
            cat,
            sim(),
            {"s.toml": SPRING, "cachefile": "x"},
            ("cache", "cachefile"),
            env={"CASMBD_CACHE_DIR": "{d}/cachefile"},
            compiled=True,
            check=check_spring(),
            timeout=30,
        )
    )

    # ---- 8. malformed scenes, types, names, nesting, expressions -------------------------------
    cat = "malformed scene"

    def scene_case(text, cul, verb="info", **kw):
        return add(
            Case(
                kw.pop("name"),
                cat,
                [verb, "{d}/s.toml"]
                + (
                    ["--t-end", "0.5", "--steps", "5", "--json"]
                    if verb in ("simulate", "kinematics")
                    else []
                ),
                {"s.toml": text},
                cul,
                **kw,
            )
        )

    scene_case("[scene\nname = 'x'\n", ("s.toml", "line"), name="toml: unclosed table header")
    scene_case(SPRING + "\nmass = 3\n", ("mass", "s.toml", "line"), name="toml: duplicate key")
    scene_case(
        SPRING.replace("[scene]", "[scene]\n[scene]"),
        ("scene", "s.toml"),
        name="toml: duplicate table",
    )
    scene_case("\xff\xfe garbage".encode("latin-1"), ("s.toml", "utf"), name="toml: invalid utf-8")
    scene_case(b"\0" * 1000, ("s.toml",), name="toml: NUL bytes")
    scene_case("", ("bodies", "scene", "s.toml"), name="toml: empty file")
    scene_case("[scene]\nname = 'x'\n", ("bodies", "scene"), name="scene without bodies")
    scene_case(
        SPRING.replace('[scene]\nname = "spring_mass"', "[scene]"),
        ("name",),
        name="missing scene name",
    )
    scene_case(
        SPRING.replace('name = "spring_mass"', 'name = "x" \nwhat = 1'),
        ("what",),
        name="unknown key in [scene]",
    )
    scene_case(
        SPRING.replace('mass = "m"', 'mass = "m"\nmas = 2'), ("mas",), name="unknown key in body"
    )
    scene_case(SPRING + "\n[[gadgets]]\nname = 'g'\n", ("gadgets",), name="unknown table")
    scene_case(SPRING.replace('mass = "m"\n', ""), ("mass", "block"), name="body without mass")
    scene_case(
        SPRING.replace('body2 = "block"\npoint', 'body2 = "blok"\npoint'),
        ("blok",),
        name="joint references unknown body",
    )
    scene_case(
        SPRING.replace('type = "prismatic"', 'type = "wormhole"'),
        ("wormhole",),
        name="unknown joint type",
    )
    scene_case(SPRING.replace('mass = "m"', "mass = [1, 2]"), ("mass",), name="mass is a list")
    scene_case(SPRING.replace('mass = "m"', "mass = true"), ("mass",), name="mass is a bool")
    scene_case(SPRING.replace('mass = "m"', "mass = { a = 1 }"), ("mass",), name="mass is a table")
    scene_case(SPRING.replace('mass = "m"', "mass = 1979-05-27"), ("mass",), name="mass is a date")
    scene_case(
        SPRING.replace("position = [1.1, 0.0]", "position = [1.1]"),
        ("position",),
        name="position 1 component",
    )
    scene_case(
        SPRING.replace("position = [1.1, 0.0]", "position = [1.1, 0.0, 0.0, 0.0]"),
        ("position",),
        name="position 4 components",
    )
    scene_case(
        SPRING.replace("position = [1.1, 0.0]", 'position = "1.1"'),
        ("position",),
        name="position a string",
    )
    scene_case(SPRING.replace('name = "block"', "name = 42"), ("name",), name="body name a number")
    scene_case(
        SPRING.replace('name = "block"', 'name = ""').replace('body2 = "block"', 'body2 = ""'),
        ("name",),
        name="body name empty",
    )
    scene_case(
        SPRING.replace('name = "block"', 'name = "' + "b" * 100000 + '"').replace(
            'body2 = "block"', 'body2 = "' + "b" * 100000 + '"'
        ),
        ("name", "long", "characters"),
        name="body name 100k chars",
    )
    scene_case(
        SPRING.replace('name = "block"', 'name = "bl\\u0000ck"').replace(
            'body2 = "block"', 'body2 = "bl\\u0000ck"'
        ),
        ("name",),
        name="body name with NUL",
    )
    scene_case(
        SPRING.replace('name = "block"', 'name = "блок\\u202e"').replace(
            'body2 = "block"', 'body2 = "блок\\u202e"'
        ),
        ("name",),
        verb="simulate",
        name="body name unicode + RTL override",
        check=lambda o, d: None,
    )
    scene_case(
        SPRING.replace('name = "spring_mass"', 'name = "../../../etc/x"'),
        ("name",),
        verb="simulate",
        name="scene name path traversal",
        check=check_spring(),
    )
    scene_case(
        SPRING.replace('name = "spring_mass"', 'name = "' + "n" * 5000 + '"'),
        ("name",),
        verb="simulate",
        name="scene name 5000 chars",
        check=check_spring(),
        compiled=True,
        timeout=30,
    )
    scene_case(
        SPRING.replace("m = 1.0", 'm = "' + "+".join(["1"] * 6000) + '"'),
        ("m", "characters", "expression"),
        name="expression 12k chars",
    )
    scene_case(
        SPRING.replace("m = 1.0", 'm = "' + "(" * 3000 + "1" + ")" * 3000 + '"'),
        ("m",),
        name="expression 3000 nested parens",
    )
    scene_case(SPRING.replace("m = 1.0", 'm = "m"'), ("m",), name="parameter refers to itself")
    scene_case(
        SPRING.replace("m = 1.0", 'm = "c2 + 1"\nc2 = "m"'),
        ("m", "c2"),
        name="parameters refer to each other",
    )
    scene_case(
        SPRING.replace("m = 1.0", "m = \"__import__('os')\""),
        ("m", "__import__"),
        name="expression __import__",
    )
    scene_case(SPRING.replace("m = 1.0", 'm = "1..2"'), ("m",), name="expression syntax error")
    scene_case(SPRING.replace("m = 1.0", 'm = "10**10**10"'), ("m",), name="expression 10**10**10")
    scene_case(SPRING.replace("m = 1.0", 'm = "1/0"'), ("m",), name="expression 1/0")
    scene_case(SPRING.replace("m = 1.0", 'm = "sqrt(-1)"'), ("m",), name="expression sqrt(-1)")
    scene_case(SPRING.replace("m = 1.0", 'm = "log(0)"'), ("m",), name="expression log(0)")
    scene_case(
        SPRING.replace("m = 1.0", 'm = "undefined_name"'),
        ("undefined_name",),
        name="expression unknown name",
    )
    scene_case(
        SPRING.replace("m = 1.0", 'm = "t"'), ("m", "'t'", "time"), name="parameter depends on t"
    )
    scene_case(
        SPRING.replace("m = 1.0", 'm = "angle(\\"slide\\")"'),
        ("m", "angle"),
        name="parameter uses a measure",
    )
    scene_case(SPRING.replace("m = 1.0", "m = 1e400"), ("m", "s.toml"), name="number 1e400 in TOML")
    scene_case(
        SPRING.replace("m = 1.0", "m = 123456789012345678901234567890"),
        ("m", "s.toml"),
        name="huge integer",
    )
    scene_case(
        SPRING.replace('stiffness = "k"', 'stiffness = "k*sin(t)"'),
        ("stiffness", "spring"),
        verb="simulate",
        name="time-dependent stiffness (allowed?)",
        check=lambda o, d: None,
    )
    scene_case(
        SPRING.replace('stiffness = "k"', 'stiffness = "1/(t-0.25)"'),
        ("spring", "stiffness"),
        verb="simulate",
        name="stiffness 1/(t-0.25)",
        check=check_bounded_spring,
    )
    scene_case(
        SPRING.replace('stiffness = "k"', 'stiffness = "k*exp(100*t)"'),
        ("spring", "stiffness", "block"),
        verb="simulate",
        name="stiffness exp(100 t)",
        check=lambda o, d: None,
        timeout=30,
    )
    nest = "x = " + "[" * 1000 + "]" * 1000 + "\n"
    scene_case(
        SPRING.replace("[parameters]", "[parameters]\n" + nest),
        ("nest", "s.toml", "deep"),
        name="arrays nested 1000 deep",
    )
    nest2 = "x = " + "{a = " * 600 + "1" + "}" * 600 + "\n"
    scene_case(
        SPRING.replace("[parameters]", "[parameters]\n" + nest2),
        ("nest", "s.toml", "deep"),
        name="inline tables nested 600 deep",
    )
    scene_case(
        SPRING
        + "".join(
            f'\n[[markers]]\nname = "m{i}"\nbody = "block"\npoint = [1.1, 0.0]\n'
            for i in range(20000)
        ),
        (),
        name="20000 markers (legal)",
        timeout=30,
        verb="info",
    )
    scene_case(chain_scene(21000), ("bodies", "20000", "20 000"), name="21000 bodies", timeout=30)
    scene_case(
        SPRING.replace("axis = [1.0, 0.0]", "axis = [0.0, 0.0]"),
        ("axis", "slide"),
        name="prismatic axis zero",
    )
    scene_case(
        SPRING.replace("axis = [1.0, 0.0]", "axis = [1e-320, 0.0]"),
        ("axis", "slide"),
        name="prismatic axis denormal",
    )
    scene_case(
        SPRING.replace("axis = [1.0, 0.0]", "axis = [nan, 0.0]"),
        ("axis",),
        name="prismatic axis nan",
    )
    scene_case(SPRING.replace("dimension = 2", "dimension = 4"), ("dimension",), name="dimension 4")
    scene_case(
        SPRING.replace("[scene]", '[scene]\ncoordinates = "polar"'),
        ("coordinates", "polar"),
        name="coordinates polar",
    )
    scene_case(SPRING.replace("[scene]", "[scene]\nformat = 99"), ("format",), name="format 99")
    scene_case(
        PENDULUM.replace('type = "revolute"\nbody1 = "rod1"', 'type = "revolute"\nbody1 = "rod2"'),
        ("elbow", "rod2"),
        name="joint body1 == body2",
    )
    scene_case(
        PENDULUM.replace('body1 = "ground"\nbody2 = "rod1"', 'body1 = "ground"\nbody2 = "ground"'),
        ("shoulder", "ground"),
        name="joint ground-ground",
    )
    scene_case(
        SLIDER_CRANK.replace(
            'position = "2 * pi * t"',
            'position = "2*pi*t"\n[[drivers]]\nname = "m2"\njoint = "O"\nposition = "t"',
        ),
        ("motor", "m2", "O"),
        verb="kinematics",
        name="two drivers on one joint",
    )
    scene_case(
        SLIDER_CRANK.replace("point = [0.6, 0.0]\naxis", "point = [0.6, 5.0]\naxis"),
        ("rail", "B", "rod"),
        verb="kinematics",
        name="slider rail misplaced (assembly)",
    )
    scene_case(
        SLIDER_CRANK.replace(
            'position = "2 * pi * t"',
            "position = { times = [0, 1, 0.5, 2], values = [0, 1, 2, 3] }",
        ),
        ("motor", "times"),
        verb="kinematics",
        name="spline times not increasing",
    )
    scene_case(
        SLIDER_CRANK.replace(
            'position = "2 * pi * t"', "position = { times = [0, 1], values = [0, 1] }"
        ),
        ("motor", "times"),
        verb="kinematics",
        name="spline 2 samples",
    )

    # ---- 9. every numeric field of two scenes ---------------------------------------------------
    cat = "numeric fields"
    for base, key, verb in ((SPRING, "spring", sim()), (BALL, "ball", sim())):
        doc = tomllib.loads(base)
        for path in numeric_leaves(doc):
            vector = isinstance(path[-1], int)
            if vector and (path[-1] != 1 or path[-2] in ("point1", "origin")):
                continue  # one component of each vector (the vertical one)
            values = (
                (("nan", float("nan")), ("1e300", 1e300))
                if vector
                else (
                    ("-1", -1.0),
                    ("0", 0.0),
                    ("nan", float("nan")),
                    ("inf", float("inf")),
                    ("1e300", 1e300),
                    ("'abc'", "abc"),
                )
            )
            for label, value in values:
                add(
                    Case(
                        f"{key} {'.'.join(map(str, path))}={label}",
                        cat,
                        list(verb),
                        {"s.toml": dump_toml(replaced(doc, path, value))},
                        culprits_of(doc, path),
                        timeout=30,
                    )
                )

    # ---- 10. CLI flags ----
    cat = "cli flags"

    def flag_case(nm, argv, cul, **kw):
        return add(Case(nm, cat, argv, kw.pop("files", {"s.toml": SPRING}), cul, **kw))

    for flag, vals in (
        ("--t-end", ("-1", "0", "nan", "inf", "1e-320")),
        ("--steps", ("0", "1.5", "1e12", "99999999999999999999")),
    ):
        for v in vals:
            argv = ["simulate", "{d}/s.toml", "--t-end", "1", "--steps", "10", "--json"]
            argv[argv.index(flag) + 1] = v
            flag_case(f"simulate {flag} {v}", argv, (flag,))
    for flag, vals in (
        ("--rtol", ("0", "-1", "nan", "2", "1e-300")),
        ("--atol", ("-1", "nan")),
        ("--step", ("0", "nan", "1e-12")),
        ("--max-steps", ("0", "1.5")),
        ("--integrator", ("euler",)),
        ("--formulation", ("magic",)),
        ("--mode", ("turbo",)),
    ):
        for v in vals:
            argv = [*sim(), flag, v]
            if flag == "--step":
                argv += ["--integrator", "rk4"]
            flag_case(
                f"simulate {flag} {v}", argv, (flag,), check=check_spring(tol=2e-2), timeout=30
            )
    flag_case("unknown flag --frobnicate", [*sim(), "--frobnicate"], ("--frobnicate",))
    flag_case("unknown verb", ["teleport", "{d}/s.toml"], ("teleport",))
    flag_case(
        "no scene", ["simulate", "--t-end", "1", "--steps", "2"], ("scene", "required", "argument")
    )
    flag_case(
        "--t-end missing value", ["simulate", "{d}/s.toml", "--steps", "2", "--t-end"], ("--t-end",)
    )
    flag_case(
        "sweep --param bad syntax",
        ["sweep", "{d}/s.toml", "--param", "k=a:b:c", "--t-end", "0.1", "--steps", "2"],
        ("--param", "k"),
    )
    flag_case(
        "sweep --param unknown",
        ["sweep", "{d}/s.toml", "--param", "zz=1:2:2", "--t-end", "0.1", "--steps", "2"],
        ("zz",),
    )
    flag_case(
        "sweep --param N=10**7",
        ["sweep", "{d}/s.toml", "--param", "k=1:2:10000000", "--t-end", "0.1", "--steps", "2"],
        ("--param", "k", "points"),
        timeout=60,
    )
    flag_case(
        "sweep --param N=0",
        ["sweep", "{d}/s.toml", "--param", "k=1:2:0", "--t-end", "0.1", "--steps", "2"],
        ("--param", "k"),
    )
    flag_case(
        "sweep --param k=-5:-1:3 (negative k)",
        ["sweep", "{d}/s.toml", "--param", "k=-5:-1:3", "--t-end", "0.1", "--steps", "2", "--json"],
        ("k",),
        timeout=30,
    )
    flag_case(
        "sweep --param k=nan",
        ["sweep", "{d}/s.toml", "--param", "k=nan", "--t-end", "0.1", "--steps", "2", "--json"],
        ("k", "--param"),
    )
    flag_case(
        "sweep --workers 0",
        [
            "sweep",
            "{d}/s.toml",
            "--param",
            "k=50:100:2",
            "--t-end",
            "0.1",
            "--steps",
            "2",
            "--workers",
            "0",
        ],
        ("--workers",),
    )
    flag_case(
        "sweep --workers 10000",
        [
            "sweep",
            "{d}/s.toml",
            "--param",
            "k=50:100:2",
            "--t-end",
            "0.1",
            "--steps",
            "2",
            "--workers",
            "10000",
        ],
        ("--workers",),
        timeout=30,
    )
    flag_case(
        "sweep --output bogus",
        [
            "sweep",
            "{d}/s.toml",
            "--param",
            "k=50:100:2",
            "--t-end",
            "0.1",
            "--steps",
            "2",
            "--output",
            "bogus:zz",
        ],
        ("--output", "bogus", "zz"),
    )
    flag_case(
        "sweep --scheduler bad",
        [
            "sweep",
            "{d}/s.toml",
            "--param",
            "k=50:100:2",
            "--t-end",
            "0.1",
            "--steps",
            "2",
            "--scheduler",
            "tcp://256.0.0.1:1",
        ],
        ("--scheduler", "dask", "256.0.0.1"),
        timeout=30,
    )
    flag_case(
        "linearize --from missing",
        ["linearize", "{d}/s.toml", "--from", "{d}/none.npz", "--time", "0"],
        ("none.npz",),
    )
    flag_case(
        "linearize --time without --from",
        ["linearize", "{d}/s.toml", "--time", "1"],
        ("--time", "--from"),
    )
    flag_case(
        "linearize --from other scene's result",
        ["linearize", "{d}/p.toml", "--from", "{d}/r.npz", "--time", "0"],
        ("r.npz", "p.toml", "double_pendulum", "spring_mass"),
        files={"s.toml": SPRING, "p.toml": PENDULUM},
        setup=made,
    )
    flag_case(
        "linearize --from --time nan",
        ["linearize", "{d}/s.toml", "--from", "{d}/r.npz", "--time", "nan"],
        ("--time", "time nan"),
        setup=made,
    )
    flag_case(
        "linearize --from --time 1e9",
        ["linearize", "{d}/s.toml", "--from", "{d}/r.npz", "--time", "1e9"],
        ("--time", "1e9", "1e+09", "1000000000"),
        setup=made,
    )
    flag_case(
        "plot --kind bogus",
        ["plot", "{d}/r.npz", "--kind", "bogus", "--out", "{d}/f.png"],
        ("--kind", "bogus"),
        setup=made,
        protect=("f.png",),
    )
    flag_case(
        "plot --element ghost",
        ["plot", "{d}/r.npz", "--element", "ghost", "--out", "{d}/f.png"],
        ("ghost",),
        setup=made,
        protect=("f.png",),
    )
    flag_case(
        "plot --dpi 0",
        ["plot", "{d}/r.npz", "--out", "{d}/f.png", "--dpi", "0"],
        ("--dpi",),
        setup=made,
        protect=("f.png",),
    )
    flag_case(
        "plot --dpi 1e6",
        ["plot", "{d}/r.npz", "--out", "{d}/f.png", "--dpi", "1000000"],
        ("--dpi", "dpi"),
        setup=made,
        protect=("f.png",),
        timeout=30,
    )
    flag_case(
        "animate --fps 0",
        [
            "animate",
            "{d}/s.toml",
            "--out",
            "{d}/a.gif",
            "--fps",
            "0",
            "--t-end",
            "0.2",
            "--steps",
            "4",
        ],
        ("--fps",),
        protect=("a.gif",),
    )
    flag_case(
        "animate --max-frames 0",
        [
            "animate",
            "{d}/s.toml",
            "--out",
            "{d}/a.gif",
            "--max-frames",
            "0",
            "--t-end",
            "0.2",
            "--steps",
            "4",
        ],
        ("--max-frames",),
        protect=("a.gif",),
    )
    flag_case(
        "animate --speed -1",
        [
            "animate",
            "{d}/s.toml",
            "--out",
            "{d}/a.gif",
            "--speed",
            "-1",
            "--t-end",
            "0.2",
            "--steps",
            "4",
        ],
        ("--speed",),
        protect=("a.gif",),
    )
    flag_case(
        "animate --trace ghost",
        [
            "animate",
            "{d}/s.toml",
            "--out",
            "{d}/a.png",
            "--trace",
            "ghost",
            "--t-end",
            "0.2",
            "--steps",
            "4",
        ],
        ("ghost",),
        protect=("a.png",),
    )
    flag_case(
        "animate --max-frames 1e6 --fps 1e6",
        [
            "animate",
            "{d}/s.toml",
            "--out",
            "{d}/a.gif",
            "--max-frames",
            "1000000",
            "--fps",
            "1000000",
            "--t-end",
            "1",
            "--steps",
            "4",
        ],
        ("--max-frames", "--fps", "frames"),
        timeout=30,
    )
    flag_case(
        "animate --deformation-scale nan",
        [
            "animate",
            "{d}/s.toml",
            "--out",
            "{d}/a.png",
            "--deformation-scale",
            "nan",
            "--t-end",
            "0.2",
            "--steps",
            "4",
        ],
        ("--deformation-scale",),
        protect=("a.png",),
    )
    flag_case(
        "statics --method bogus", ["statics", "{d}/s.toml", "--method", "bogus"], ("--method",)
    )
    flag_case(
        "inverse on undriven pendulum",
        ["inverse", "{d}/p.toml", "--t-end", "1", "--steps", "4", "--json"],
        ("driver", "degrees of freedom", "dof"),
        files={"p.toml": PENDULUM},
    )
    flag_case(
        "kinematics on undriven pendulum",
        ["kinematics", "{d}/p.toml", "--t-end", "1", "--steps", "4"],
        ("driver", "degrees of freedom", "dof"),
        files={"p.toml": PENDULUM},
    )
    flag_case(
        "statics of a slider crank driven (legal?)",
        ["statics", "{d}/p.toml", "--json"],
        ("motor",),
        files={"p.toml": SLIDER_CRANK},
    )
    flag_case("ocp without [ocp]", ["ocp", "{d}/s.toml"], ("ocp",))
    flag_case(
        "statics of a free falling body",
        ["statics", "{d}/s.toml", "--json"],
        ("block", "equilibrium", "free"),
        files={
            "s.toml": '[scene]\nname = "free"\ngravity = [0.0, -9.81]\n[[bodies]]\nname = "block"\n'
            "mass = 1.0\ninertia = 0.1\nposition = [0.0, 0.0]\n"
        },
    )
    return C


# ----------------------------------------------------------------------------- running
def _prepare_files(d: Path, files: dict):
    for rel, content in files.items():
        p = d / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        if callable(content):
            content(p)
        elif isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content, encoding="utf-8")


def _hash(p: Path):
    try:
        if p.is_file():
            return hashlib.sha256(p.read_bytes()).hexdigest()
        return "dir" if p.is_dir() else None
    except OSError:
        return "unreadable"


def _limit():
    os.setsid()
    resource.setrlimit(resource.RLIMIT_AS, (AS_LIMIT, AS_LIMIT))


def _run(argv, env, cwd, timeout):
    t0 = time.monotonic()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "casmbd", *argv],
            cwd=cwd,
            env=env,
            stdout=out,
            stderr=err,
            stdin=subprocess.DEVNULL,
            preexec_fn=_limit,
        )
        hung = False
        rusage = None
        while True:
            pid, status, rusage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                proc.returncode = os.waitstatus_to_exitcode(status)
                break
            if time.monotonic() - t0 > timeout:
                hung = True
                os.killpg(proc.pid, signal.SIGKILL)
                _, status, rusage = os.wait4(proc.pid, 0)
                proc.returncode = os.waitstatus_to_exitcode(status)
                break
            time.sleep(0.05)
        seconds = time.monotonic() - t0
        out.seek(0)
        err.seek(0)
        stdout = out.read(64 << 20).decode("utf-8", "replace")
        stderr = err.read(4 << 20).decode("utf-8", "replace")
    peak_mb = rusage.ru_maxrss / 1024 if rusage else 0.0
    return proc.returncode, stdout, stderr, seconds, hung, peak_mb


def _nonfinite(o, inlist=False):
    if isinstance(o, float):
        return not math.isfinite(o)
    if o is None:
        return inlist
    if isinstance(o, dict):
        return any(_nonfinite(v) for v in o.values())
    if isinstance(o, list):
        numeric = any(isinstance(x, (int, float)) and not isinstance(x, bool) for x in o) or any(
            isinstance(x, list) for x in o
        )
        return any(_nonfinite(v, numeric) for v in o)
    return False


def _one_json(stdout):
    """(object, None) if stdout is exactly one JSON object, else (None, reason)."""
    bad = []
    try:
        obj = json.loads(stdout, parse_constant=lambda c: bad.append(c) or float("nan"))
    except ValueError as exc:
        return None, f"stdout is not one JSON object ({str(exc)[:60]}; {len(stdout)} chars)"
    if not isinstance(obj, dict):
        return None, "stdout JSON is not an object"
    return obj, ("non-finite " + bad[0]) if bad else None


def classify(case: Case, code, stdout, stderr, hung, peak_mb, changed, d):
    is_json = "--json" in case.argv
    err_lines = [ln for ln in stderr.splitlines() if ln.strip()]
    if hung:
        return "hang", "timeout"
    if changed:
        return "silent", f"input changed or unwanted file written: {', '.join(changed)}"
    if case.budget_mb is not None and peak_mb > 1.5 * case.budget_mb + 400:
        return "silent", f"peak RSS {peak_mb:.0f} MB > 1.5 x budget {case.budget_mb:.0f} MB + 400"
    if code != 0:
        if "Traceback" in stderr:
            return "generic", "traceback"
        if "internal error" in stderr.lower():
            return "generic", "internal error"
        if code < 0:
            return "generic", f"killed by signal {-code}"
        if is_json and stdout.strip():
            _, why = _one_json(stdout)
            if why and why.startswith("stdout"):
                return "generic", "--json: " + why
        low = stderr.lower()
        culprits = [c.replace("{d}", str(d)).lower() for c in case.culprit]
        if culprits and not any(c in low for c in culprits):
            return "generic", "culprit not named (wanted one of: " + ", ".join(case.culprit) + ")"
        if not err_lines:
            return "generic", "no message"
        return "named", ""
    # exit 0
    obj = None
    if is_json:
        obj, why = _one_json(stdout)
        if obj is None:
            return "silent", why
        if why or _nonfinite(obj):
            return "silent", why or "null/NaN in the JSON numbers"
    elif re.search(r"(?<![\w.])[-+]?(nan|inf)(?![\w])", stdout, re.I):
        return "silent", "nan/inf in stdout"
    if case.check is not None:
        try:
            why = case.check(obj, d) if (obj is not None or not is_json) else None
        except Exception as exc:  # a check that cannot read the output is a failure
            why = f"check could not read the output ({type(exc).__name__}: {exc})"
        if why:
            return "silent", why
    return "legal", ""


def run_case(case: Case, repo: Path, cache_root: Path, base_env: dict):
    with tempfile.TemporaryDirectory(prefix="hostile_") as tmp:
        d = Path(tmp)
        env = dict(base_env)
        env["PYTHONPATH"] = str(repo)
        env["CASMBD_CACHE_DIR"] = (
            str(d / "cache")
            if (case.compiled or (case.setup and case.compiled))
            else str(cache_root)
        )
        if not case.compiled:
            env["CASMBD_COMPILE"] = "0"
        env.update({k: v.replace("{d}", str(d)) for k, v in case.env.items()})
        try:
            _prepare_files(d, case.files)
            for argv in case.setup:
                _run([a.replace("{d}", str(d)) for a in argv], env, str(d), 180)
            if case.prepare:
                case.prepare(d, env)
        except Exception as exc:
            return (
                "error",
                0,
                0.0,
                f"sweep could not prepare the case: {type(exc).__name__}: {exc}",
                "",
            )
        watched = {rel: _hash(d / rel) for rel in case.protect}
        argv = [a.replace("{d}", str(d)) for a in case.argv]
        code, stdout, stderr, seconds, hung, peak = _run(argv, env, str(d), case.timeout)
        changed = [rel for rel, h in watched.items() if _hash(d / rel) != h]
        verdict, why = classify(case, code, stdout, stderr, hung, peak, changed, d)
        lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
        first = next((ln for ln in lines if ln.startswith("error")), lines[0] if lines else "")
        if "Traceback" in stderr:
            first = [ln for ln in stderr.splitlines() if ln.strip()][-1].strip()
        first = first.replace(str(d), "{d}")[:300]
        for p in d.rglob("*"):  # chmod 000 files and the like: let TemporaryDirectory clean up
            try:
                os.chmod(p, 0o700)
            except OSError:
                pass
        return verdict, code, seconds, first, why


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repo", default=str(ROOT), help="checkout whose casmbd package runs")
    ap.add_argument("--label", default="after", help="name of the run (CSV file name)")
    ap.add_argument(
        "--only", default="", help="run only cases whose name contains this (several: a||b)"
    )
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--out", default=None, help="CSV path (default benchmarks/results/...)")
    ap.add_argument(
        "--update",
        action="store_true",
        help="rerun the --only cases and replace their rows in an existing CSV",
    )
    ap.add_argument(
        "--summary",
        nargs=2,
        metavar=("BEFORE.csv", "AFTER.csv"),
        help="print the Markdown table of two runs and exit",
    )
    ap.add_argument(
        "--slice",
        default="",
        metavar="A:B",
        help="run only the cases A..B-1 of the list (0-based, after --only)",
    )
    ap.add_argument(
        "--merge",
        nargs="+",
        metavar="PART.csv",
        help="join partial CSVs of one run into --out (case order of the list)",
    )
    ap.add_argument(
        "--failures",
        metavar="RUN.csv",
        help="list the generic/silent/hang cases of a run with their argv and exit",
    )
    args = ap.parse_args(argv)
    if args.summary:
        print(summary(Path(args.summary[0]), Path(args.summary[1])))
        return 0
    all_cases = cases()
    names = [c.name for c in all_cases]
    dup = {n for n in names if names.count(n) > 1}
    assert not dup, f"duplicate case names: {dup}"
    if args.list:
        for c in all_cases:
            print(f"{c.category:16s} {c.name}")
        print(len(all_cases), "cases")
        return 0
    chosen = [c for c in all_cases if any(o in c.name for o in args.only.split("||"))]
    if args.slice:
        a, b = (int(x) if x else None for x in args.slice.split(":"))
        chosen = chosen[a:b]
    repo = Path(args.repo).resolve()
    out = Path(args.out) if args.out else HERE / "results" / f"hostile_sweep_{args.label}.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    base_env = {k: v for k, v in os.environ.items() if not k.startswith("CASMBD_")}
    base_env.setdefault("MPLBACKEND", "Agg")
    header = ["case", "category", "verdict", "exit", "seconds", "first stderr line", "why"]
    if args.failures:
        with open(args.failures, newline="") as fh:
            bad = [r for r in csv.DictReader(fh) if r["verdict"] not in ("named", "legal")]
        by_name = {c.name: c for c in all_cases}
        for r in bad:
            c = by_name.get(r["case"])
            argv_text = " ".join(["casmbd", *c.argv]) if c else "?"
            env_text = " ".join(f"{k}={v}" for k, v in c.env.items()) + " " if c and c.env else ""
            print(
                f"- **{r['verdict']}** `{r['case']}` ({r['category']}, exit {r['exit']}, "
                f"{float(r['seconds']):.0f} s): `{env_text}{argv_text}`; "
                f"{r['why'] or 'ok'}; stderr: `{r['first stderr line'][:240]}`"
            )
        return 0
    if args.merge:
        merged: dict[str, list] = {}
        for part in args.merge:
            with open(part, newline="") as fh:
                merged.update({r[0]: r for r in list(csv.reader(fh))[1:]})
        _write(out, header, [merged[n] for n in names if n in merged])
        missing = [n for n in names if n not in merged]
        print(f"{out}: {len(merged)} cases; missing: {missing or 'none'}")
        return 0
    rows: dict[str, list] = {}
    if args.update and out.exists():
        with open(out, newline="") as fh:
            rows = {r[0]: r for r in list(csv.reader(fh))[1:]}
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="hostile_cache_") as cache_root:
        for i, c in enumerate(chosen, 1):
            verdict, code, seconds, first, why = run_case(c, repo, Path(cache_root), base_env)
            rows[c.name] = [c.name, c.category, verdict, code, f"{seconds:.2f}", first, why]
            print(
                f"[{i:3d}/{len(chosen)}] {verdict:7s} {seconds:6.1f}s {c.name}"
                + (f"  -- {why}" if why else ""),
                flush=True,
            )
            if not args.update:
                _write(out, header, [rows[n] for n in names if n in rows])
    _write(out, header, [rows[n] for n in names if n in rows])
    counts = dict.fromkeys((*VERDICTS, "error"), 0)
    for r in rows.values():
        counts[r[2]] += 1
    total = time.monotonic() - t0
    print(
        f"\n{args.label}: {len(rows)} cases ({len(chosen)} run in {total:.0f} s): "
        + ", ".join(f"{k} {v}" for k, v in counts.items() if v or k in VERDICTS)
    )
    print(f"CSV: {out}")
    return 0


def summary(before: Path, after: Path) -> str:
    """Markdown table of the verdict counts, per category, of two runs' CSVs."""

    def load(p):
        with open(p, newline="") as fh:
            return list(csv.DictReader(fh))

    runs = {"before": load(before), "after": load(after)}
    cats = list(dict.fromkeys(r["category"] for r in runs["after"]))
    head = "| category | cases | " + " | ".join(f"{v} (before → after)" for v in VERDICTS) + " |"
    lines = [head, "|" + " --- |" * (2 + len(VERDICTS))]
    for cat in [*cats, None]:
        cells = []
        for v in VERDICTS:
            n = {
                k: sum(1 for r in rs if (cat is None or r["category"] == cat) and r["verdict"] == v)
                for k, rs in runs.items()
            }
            cells.append(f"{n['before']} → {n['after']}")
        total = sum(1 for r in runs["after"] if cat is None or r["category"] == cat)
        name = "**all**" if cat is None else cat
        lines.append(f"| {name} | {total} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _write(path, header, rows):
    tmp = Path(str(path) + ".part")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    os.replace(tmp, path)


if __name__ == "__main__":
    raise SystemExit(main())
