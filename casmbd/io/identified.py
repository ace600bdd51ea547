"""Write identified parameters back into the model file: a URDF or a scene (TOML).

Both writers take the file the mechanism was read from, the standard parameters π (names as
:func:`casmbd.analysis.identification.parameters.standard_parameters`: each body's m, m c and
inertia about its origin O, each joint's viscous and Coulomb coefficients) with each body's
origin O (relative to its centre of mass in the model, body axes) and write a copy in which
only the identified quantities change, atomically (:func:`casmbd.atomic.atomic_write`).

For a body, c = h / m is the centre of mass relative to O and I_C = I_O − m (|c|² 1 − c cᵀ)
the inertia about it in the body axes; the new centre of mass in world coordinates at the
design pose is r_G' = r_G + A₀ (o + c), with r_G, A₀ the model's centre of mass and body
rotation there and o the origin O relative to r_G.

* **URDF** (:func:`write_urdf`): the text is kept byte for byte except each identified
  body's ``<inertial>`` element — replaced by one in the body's first link frame
  (``<origin xyz="R_lᵀ (r_G' − p_l)" rpy="0 0 0"/>``, the mass, and the six tensor entries of
  I_C in the link axes, which are the body axes of a URDF body, :mod:`casmbd.io.urdf`) — and
  each identified joint's ``<dynamics>`` (``damping`` = viscous, ``friction`` = Coulomb;
  other attributes kept; added when absent).  Links merged into a body through fixed joints
  lose their ``<inertial>`` (the body's identified inertia is written whole into its first
  link).  Reload with ``load_urdf(path, damping=True, friction=True)`` to apply the
  friction.
* **Scene** (:func:`write_scene`): each identified body's ``mass``, ``inertia`` (six
  entries [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about the centre of mass in body axes; the scalar
  I_zz in the plane) and ``position`` (the centre of mass) lines of its ``[[bodies]]`` entry
  are replaced (multi-line arrays included); each joint's ``friction = {…}`` inline table in
  its ``[[joints]]`` entry gets the identified ``viscous`` and ``coulomb`` (its other keys
  kept; the key is added when absent), or the ``damping``/``friction`` keys of a
  ``[[forces]]`` entry of type ``joint_friction`` on that joint.  Comments and every other
  line are kept.  A body with a ``reference_point`` keeps it (relative to the new centre of
  mass: the coordinates of the reference point in a joint-coordinate model do not change;
  in absolute coordinates the reference point moves with the centre of mass).  A scene that
  reads its bodies from a URDF (``[scene] urdf``) is refused: write the URDF.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
import xml.parsers.expat
from pathlib import Path

import numpy as np

from casmbd.analysis.identification.consistent import body_inertials, friction_values
from casmbd.atomic import atomic_write
from casmbd.errors import IdentificationError, SceneError
from casmbd.io.files import read_text
from casmbd.io.urdf_tree import parse_urdf

__all__ = ["identified_bodies", "write_scene", "write_urdf"]


def _num(x: float) -> str:
    """17 significant digits: the value reads back exactly."""
    return repr(float(x)) if math.isfinite(x) else "nan"


def identified_bodies(mechanism, names, values, origins) -> dict:
    """Body → (m, r_G' world at the design pose, I_C in body axes), module docstring."""
    out = {}
    for body, (m, c, inertia) in body_inertials(list(names), values).items():
        if body not in mechanism.bodies:
            raise IdentificationError(f"identified body '{body}' is not in the model")
        b = mechanism.bodies[body]
        origin = np.asarray(origins.get(body, np.zeros(len(c))), float)
        rot = np.asarray(b.initial_rotation, float)
        out[body] = (m, np.asarray(b.position, float) + rot @ (origin + c), inertia)
    return out


# ---------------------------------------------------------------------------------- URDF
class _Span:
    __slots__ = ("children", "close", "end", "name", "start", "tag", "tag_end")

    def __init__(self, tag, name, start, tag_end):
        self.tag, self.name, self.start, self.tag_end = tag, name, start, tag_end
        self.end = self.close = None
        self.children: dict[str, _Span] = {}


def _tag_end(data: bytes, start: int) -> int:
    """Index just past the '>' of the tag starting at ``start`` (quotes skipped)."""
    quote = None
    for k in range(start, len(data)):
        ch = data[k:k + 1]
        if quote:
            if ch == quote:
                quote = None
        elif ch in (b'"', b"'"):
            quote = ch
        elif ch == b">":
            return k + 1
    raise IdentificationError("URDF: unterminated tag")


def _urdf_spans(data: bytes, source: str) -> dict[tuple[str, str], _Span]:
    """(tag, name) → span of each top-level ``<link>`` and ``<joint>`` with its
    ``<inertial>``/``<dynamics>`` child (byte offsets: start, end, and ``close``, the start of
    the closing tag, None for a self-closing element)."""
    parser = xml.parsers.expat.ParserCreate()
    stack: list[_Span] = []
    found: dict[tuple[str, str], _Span] = {}

    def start(tag, attrs):
        at = parser.CurrentByteIndex
        span = _Span(tag, attrs.get("name", ""), at, _tag_end(data, at))
        if len(stack) == 1 and tag in ("link", "joint"):
            found[(tag, span.name)] = span
        elif len(stack) == 2 and stack[1].tag in ("link", "joint") and tag in (
                "inertial", "dynamics"):
            stack[1].children[tag] = span
        stack.append(span)

    def end(tag):
        at = parser.CurrentByteIndex
        span = stack.pop()
        if data[span.tag_end - 2:span.tag_end] == b"/>":
            span.end = span.tag_end
        else:
            span.close = at
            span.end = _tag_end(data, at)

    parser.StartElementHandler, parser.EndElementHandler = start, end
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as exc:
        raise SceneError(f"URDF '{source}': malformed XML: {exc}") from None
    return found


def _indent(data: bytes, at: int) -> str:
    line = data.rfind(b"\n", 0, at) + 1
    lead = data[line:at]
    return lead.decode() if not lead.strip() else ""


def _inertial_xml(mass: float, com, tensor, indent: str, step: str) -> str:
    t = np.asarray(tensor, float)
    return (f"<inertial>\n{indent}{step}<origin xyz=\"{_num(com[0])} {_num(com[1])} "
            f"{_num(com[2])}\" rpy=\"0 0 0\"/>\n{indent}{step}<mass value=\"{_num(mass)}\"/>\n"
            f"{indent}{step}<inertia ixx=\"{_num(t[0, 0])}\" ixy=\"{_num(t[0, 1])}\" "
            f"ixz=\"{_num(t[0, 2])}\" iyy=\"{_num(t[1, 1])}\" iyz=\"{_num(t[1, 2])}\" "
            f"izz=\"{_num(t[2, 2])}\"/>\n{indent}</inertial>")


def _set_attributes(tag: str, values: dict[str, float]) -> str:
    """A start tag with ``values`` set (replaced in place when present, else appended)."""
    closing = "/>" if tag.rstrip().endswith("/>") else ">"
    body = tag.rstrip()[:-len(closing)].rstrip()
    for key, value in values.items():
        pattern = re.compile(rf"(\s{key}\s*=\s*)(\"[^\"]*\"|'[^']*')")
        if pattern.search(body):
            body = pattern.sub(lambda m, v=value: f"{m.group(1)}\"{_num(v)}\"", body, count=1)
        else:
            body += f" {key}=\"{_num(value)}\""
    return body + closing


def write_urdf(source: str | os.PathLike, out: str | os.PathLike, mechanism, names, values,
               origins) -> Path:
    """Write the URDF ``source`` with the identified inertials and joint dynamics to ``out``
    (module docstring).  Returns the path written."""
    text = read_text(Path(source), "URDF")
    data = text.encode("utf-8")
    robot = parse_urdf(text, str(source))
    design = robot.frames({})
    spans = _urdf_spans(data, str(source))
    renamed = getattr(mechanism, "urdf_renamed", {}) or {}
    urdf_name = {v: k for k, v in renamed.items()}
    edits: list[tuple[int, int, str]] = []
    bodies = identified_bodies(mechanism, names, values, origins)
    for body, (mass, com, inertia) in bodies.items():
        if np.ndim(inertia) == 0:
            raise IdentificationError(f"body '{body}': a URDF holds spatial bodies only")
        link = urdf_name.get(body, body)
        if link not in design or ("link", link) not in spans:
            raise IdentificationError(f"body '{body}': no link '{link}' in '{source}'")
        rot, pos = design[link]
        com_link = np.asarray(rot).T @ (com - np.asarray(pos))
        span = spans[("link", link)]
        indent = _indent(data, span.start)
        step = "  "
        old = span.children.get("inertial")
        if old is not None:
            inner = _indent(data, old.start)
            step = inner[len(indent):] or "  "
            edits.append((old.start, old.end, _inertial_xml(mass, com_link, inertia, inner,
                                                            step)))
        elif span.close is None:  # <link name="x"/>: open it
            tag = data[span.start:span.end].decode()
            opened = tag.rstrip()[:-2].rstrip() + ">"
            edits.append((span.start, span.end, opened + f"\n{indent}{step}" + _inertial_xml(
                mass, com_link, inertia, indent + step, step) + f"\n{indent}</link>"))
        else:
            edits.append((span.close, span.close, f"{step}" + _inertial_xml(
                mass, com_link, inertia, indent + step, step) + f"\n{indent}"))
        for marker, mk in getattr(mechanism, "markers", {}).items():
            merged = urdf_name.get(marker, marker)
            if mk.body == body and merged != link and ("link", merged) in spans:
                drop = spans[("link", merged)].children.get("inertial")
                if drop is not None:
                    line = data.rfind(b"\n", 0, drop.start)
                    cut = line if not data[line + 1:drop.start].strip() else drop.start
                    edits.append((cut, drop.end, ""))
    keys = {"viscous": "damping", "coulomb": "friction"}
    for joint, laws in friction_values(list(names), values).items():
        joint_name = urdf_name.get(joint, joint)
        if ("joint", joint_name) not in spans:
            raise IdentificationError(f"joint '{joint}': no joint '{joint_name}' in "
                                      f"'{source}'")
        span = spans[("joint", joint_name)]
        attrs = {keys[k]: v for k, v in laws.items()}
        dyn = span.children.get("dynamics")
        if dyn is not None:
            tag = data[dyn.start:dyn.tag_end].decode()
            edits.append((dyn.start, dyn.tag_end, _set_attributes(tag, attrs)))
        else:
            indent = _indent(data, span.start)
            new = "<dynamics " + " ".join(f"{k}=\"{_num(v)}\"" for k, v in attrs.items()) \
                + "/>"
            if span.close is None:
                tag = data[span.start:span.end].decode()
                edits.append((span.start, span.end, tag.rstrip()[:-2].rstrip() + ">\n"
                              + f"{indent}  {new}\n{indent}</joint>"))
            else:
                edits.append((span.close, span.close, f"  {new}\n{indent}"))
    out_bytes = _apply(data, edits)
    return atomic_write(out, lambda tmp: Path(tmp).write_bytes(out_bytes))


def _apply(data: bytes, edits: list[tuple[int, int, str]]) -> bytes:
    out, at = [], 0
    for start, end, new in sorted(edits, key=lambda e: (e[0], e[1])):
        if start < at:
            raise IdentificationError("overlapping edits of the model file")
        out += [data[at:start], new.encode("utf-8")]
        at = end
    out.append(data[at:])
    return b"".join(out)


# ---------------------------------------------------------------------------------- scene
_HEADER = re.compile(r"^\s*\[\[?\s*([A-Za-z0-9_.\"' -]+?)\s*\]\]?\s*(#.*)?$")


def _sections(lines: list[str]) -> list[tuple[str, int, int]]:
    """(table name, first line, end line) of each header's section (``[[bodies]]`` →
    ``"bodies"``); multi-line arrays and strings are not headers."""
    heads = []
    depth = 0
    for k, line in enumerate(lines):
        if depth == 0:
            m = _HEADER.match(line)
            if m:
                heads.append((m.group(1).strip(), k))
                continue
        depth = max(depth + _bracket_balance(line), 0)
    return [(name, k, heads[i + 1][1] if i + 1 < len(heads) else len(lines))
            for i, (name, k) in enumerate(heads)]


def _bracket_balance(line: str) -> int:
    """Net [ minus ] of a line outside strings and comments."""
    depth, quote, k = 0, None, 0
    while k < len(line):
        ch = line[k]
        if quote:
            if ch == "\\" and quote == '"':
                k += 1
            elif ch == quote:
                quote = None
        elif ch in "\"'":
            quote = ch
        elif ch == "#":
            break
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        k += 1
    return depth


def _key_lines(lines: list[str], first: int, end: int, key: str) -> tuple[int, int] | None:
    """The lines [k, k_end) holding ``key = …`` in a section (a multi-line value
    included), or None."""
    pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
    for k in range(first + 1, end):
        if pattern.match(lines[k]):
            stop, depth = k, _bracket_balance(lines[k])
            while depth > 0 and stop + 1 < end:
                stop += 1
                depth += _bracket_balance(lines[stop])
            return k, stop + 1
    return None


def _entry_name(lines: list[str], first: int, end: int) -> str | None:
    span = _key_lines(lines, first, end, "name")
    if span is None:
        return None
    try:
        return tomllib.loads("".join(lines[span[0]:span[1]])).get("name")
    except tomllib.TOMLDecodeError:
        return None


def _set_key(lines: list[str], first: int, end: int, key: str, value: str) -> None:
    """Replace (or add after the entry's last key line) ``key = value`` in place."""
    span = _key_lines(lines, first, end, key)
    if span is not None:
        k0, k1 = span
        indent = re.match(r"^\s*", lines[k0]).group(0)
        comment = ""
        if k1 == k0 + 1:
            m = re.search(r"(\s+#[^\"'\]]*)$", lines[k0].rstrip("\n"))
            comment = m.group(1) if m else ""
        lines[k0:k1] = [f"{indent}{key} = {value}{comment}\n"] + [""] * (k1 - k0 - 1)
    else:
        last = first
        for k in range(first + 1, end):
            if lines[k].strip() and not lines[k].lstrip().startswith("#"):
                last = k
        lines[last] = lines[last].rstrip("\n") + f"\n{key} = {value}\n"


def _array(values) -> str:
    return "[" + ", ".join(_num(v) for v in values) + "]"


def write_scene(source: str | os.PathLike, out: str | os.PathLike, mechanism, names, values,
                origins) -> Path:
    """Write the scene ``source`` with the identified bodies and joint friction to ``out``
    (module docstring).  Returns the path written."""
    text = read_text(Path(source), "scene")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: malformed TOML: {exc}") from None
    if isinstance(data.get("scene"), dict) and ("urdf" in data["scene"]
                                                or "mjcf" in data["scene"]):
        raise IdentificationError(f"{source}: the bodies come from a robot file ([scene] urdf "
                                  "or mjcf); identify the .urdf file itself to write it")
    lines = text.splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines[-1] += "\n"
    sections = _sections(lines)

    def entry(table: str, name: str):
        for tname, first, end in sections:
            if tname == table and _entry_name(lines, first, end) == name:
                return first, end
        return None

    for body, (mass, com, inertia) in identified_bodies(mechanism, names, values,
                                                        origins).items():
        where = entry("bodies", body)
        if where is None:
            raise IdentificationError(f"{source}: no [[bodies]] entry named '{body}' to write "
                                      "its identified inertia into")
        if np.ndim(inertia) == 0:
            inertia_text = _num(float(inertia))
        else:
            t = np.asarray(inertia, float)
            inertia_text = _array([t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]])
        _set_key(lines, *where, "mass", _num(mass))
        _set_key(lines, *where, "inertia", inertia_text)
        _set_key(lines, *where, "position", _array(com))
    keys = {"viscous": "damping", "coulomb": "friction"}
    for joint, laws in friction_values(list(names), values).items():
        forces = [(f, e) for f, e in ((n, entry("forces", n)) for n in _force_names(data, joint))
                  if e is not None]
        if forces:
            for _, where in forces:
                for law, v in laws.items():
                    _set_key(lines, *where, keys[law], _num(v))
            continue
        where = entry("joints", joint)
        if where is None:
            raise IdentificationError(f"{source}: no [[joints]] entry named '{joint}' to write "
                                      "its identified friction into")
        table = next((dict(j.get("friction") or {}) for j in data.get("joints", [])
                      if isinstance(j, dict) and j.get("name") == joint), {})
        table.pop("preload", None)
        table.update(laws)
        inline = "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in table.items()) + " }"
        _set_key(lines, *where, "friction", inline)
    new_text = "".join(lines)
    return atomic_write(out, lambda tmp: Path(tmp).write_text(new_text, encoding="utf-8"))


def _force_names(data: dict, joint: str) -> list[str]:
    return [f.get("name") for f in data.get("forces", []) if isinstance(f, dict)
            and f.get("type") == "joint_friction" and f.get("joint") == joint]


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return _num(v)
    return '"' + str(v).replace("\\", "\\\\").replace('"', '\\"') + '"'
