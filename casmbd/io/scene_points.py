"""A scene at other parameter values: the per-point scenes of a parameter sweep.

A mechanism read from a scene file carries a :class:`ScenePoints` (``mech.scene_points``, set
by :func:`casmbd.io.scene.loads_scene`): the scene text, its source name and the reader.  The
sweep (:mod:`casmbd.analysis.studies.sweep`, a lower layer that never parses scene text) asks it for
each point's scene — the ``[parameters]`` entries rewritten, comments and layout kept —
checks that the scene still loads with the point's values, and refuses a parameter that fixes
*load-time* numbers (positions, points, axes, initial velocities are evaluated when the scene
is read and cannot change at run time).  Worker processes receive the ScenePoints (plain text
and a module-level function, so it pickles) and rebuild the mechanism with :meth:`mechanism`.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from casmbd.errors import AnalysisError, SceneError

_TABLE = re.compile(r"^\s*\[")
_KEY_LINE = re.compile(r"^(\s*)([A-Za-z_][A-Za-z0-9_-]*|\"[^\"]*\")(\s*=\s*)([^#\r\n]*?)"
                       r"(\s*(?:#[^\r\n]*)?)(\r?\n)?$")
#: attributes of a mechanism that are not load-time numbers
_SKIP = {"parameters", "scene_text", "scene_data", "scene_points", "scene_reader"}


def scene_with(text: str, values: Mapping[str, float], source: str) -> str:
    """The scene text with the ``[parameters]`` entries in ``values`` replaced (comments and
    layout kept), verified by reading it back.

    Raises
    ------
    AnalysisError
        When the table cannot be rewritten line by line (the message names ``source``).
    """
    lines = text.splitlines(keepends=True)
    inside = False
    for i, line in enumerate(lines):
        if _TABLE.match(line):
            inside = line.split("#", 1)[0].strip() == "[parameters]"
            continue
        m = _KEY_LINE.match(line) if inside else None
        if m and m.group(2).strip('"') in values:
            lines[i] = (m.group(1) + m.group(2) + m.group(3)
                        + repr(float(values[m.group(2).strip('"')])) + m.group(5)
                        + (m.group(6) or ""))
    out = "".join(lines)
    try:
        got = tomllib.loads(out).get("parameters", {})
        same = all(float(got.get(k, math.nan)) == float(v) for k, v in values.items())
    except (tomllib.TOMLDecodeError, TypeError, ValueError):
        same = False
    if not same:
        raise AnalysisError(f"sweep: cannot rewrite the [parameters] table of {source} (write "
                            "one 'name = number' line per parameter)")
    return out


def fingerprint(obj) -> object:
    """Every load-time number of a mechanism (positions, points, axes, velocities …), the
    parameter values and the scene text left out: equal fingerprints mean the parameters
    enter only the symbolic values (runtime inputs p)."""
    if isinstance(obj, (str, bool, int, float, type(None))):
        return obj
    if isinstance(obj, np.ndarray):
        return ("array", obj.shape, tuple(np.ravel(obj).tolist()))
    if isinstance(obj, Mapping):
        return tuple((str(k), fingerprint(v)) for k, v in obj.items() if k not in _SKIP)
    if isinstance(obj, (list, tuple)):
        return tuple(fingerprint(v) for v in obj)
    if hasattr(obj, "__dict__"):
        return (type(obj).__name__, fingerprint(vars(obj)))
    return (type(obj).__name__, str(obj))


@dataclass(frozen=True)
class ScenePoints:
    """The scene of a mechanism and how to read it again at other parameter values.

    Attributes
    ----------
    text : str
        The scene text as read.
    source : str
        Its name in messages (the file path, or ``<string>``).
    loads : callable ``(text, source) -> Mechanism``
        The scene reader (:func:`casmbd.io.scene.loads_scene`, a module-level function, so
        that the object pickles to worker processes).
    """

    text: str
    source: str
    loads: Callable

    def mechanism(self, scene: str | None = None, source: str | None = None):
        """The mechanism of ``scene`` (default: the original text)."""
        return self.loads(self.text if scene is None else scene,
                          source=self.source if source is None else source)

    def describes(self, mechanism) -> bool:
        """Whether ``mechanism`` is still what the text builds: not changed in Python after
        it was read (an element, a number or a parameter value added or changed).  Only
        then may a sweep or a sensitivity read the text again at other parameter values."""
        built = self.mechanism()
        return (fingerprint(built) == fingerprint(mechanism)
                and dict(built.parameters) == dict(mechanism.parameters))

    def point_scenes(self, points: Sequence[Mapping[str, float]]
                     ) -> tuple[list[str | None], dict[int, str]]:
        """Each point's scene text, and the points whose scene does not load (index ->
        ``"SceneError: message"``; their scene is ``None``).

        Raises
        ------
        AnalysisError
            When a parameter fixes load-time numbers of the scene (the message names it).
        """
        base = fingerprint(self.mechanism())
        scenes: list[str | None] = []
        failed: dict[int, str] = {}
        for i, p in enumerate(points):
            scene = scene_with(self.text, p, self.source)
            try:
                point_mech = self.mechanism(scene, f"{self.source} at point {i}")
            except SceneError as exc:
                failed[i] = f"{type(exc).__name__}: {exc}"
                scenes.append(None)
                continue
            if fingerprint(point_mech) != base:
                culprits = [n for n in p if fingerprint(self.mechanism(
                    scene_with(self.text, {n: p[n]}, self.source))) != base]
                raise AnalysisError(
                    f"sweep: parameter(s) {', '.join(repr(n) for n in culprits or p)} fix "
                    f"load-time numbers of {self.source} (positions, points, axes or initial "
                    "velocities are evaluated when the scene is read) and cannot change at run "
                    "time; sweep only parameters used in masses, inertias, forces, springs, "
                    "drivers, or sweep separate scene files")
            scenes.append(scene)
        return scenes, failed
