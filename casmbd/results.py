"""Result objects shared by the analyses: arrays on a time grid, JSON view and npz files.

A :class:`Result` keeps every array of an analysis (time as the first axis), the names needed to
read them, and statistics.  ``to_json`` gives the CLI contract (``"t"``, ``"bodies"``,
``"joints"``, ``"constraint_violation"``, ``"stats"`` …; planar bodies report an ``"angle"``,
spatial ones a ``"quaternion"`` [w, x, y, z]); ``save`` writes every array, the names, the
statistics and the scene text to an npz file and ``to_csv`` one column per scalar series, both
atomically (temporary file in the target folder + ``os.replace``, :func:`atomic_write`);
:func:`load` (also ``Result.load`` and ``casmbd.load_result``) reads an npz file back and
``Result.mechanism`` re-loads the embedded scene.
"""

from __future__ import annotations

import csv
import json
import os
import re
import struct
import warnings
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from casmbd import limits
from casmbd.atomic import (  # noqa: F401 (re-exported: results' file helpers)
    STALE_TEMP_SECONDS,
    TEMP_PREFIX,
    atomic_write,
    remove_stale_temporaries,
)
from casmbd.errors import AnalysisError, ResultFileError
from casmbd.model import rotations
from casmbd.system.descriptions import quaternions_from_matrices


def _list(arr: np.ndarray):
    return np.asarray(arr, dtype=float).tolist()


def extremes(t: np.ndarray, values: np.ndarray) -> dict:
    """``start``, ``end``, ``min``, ``t_min``, ``max``, ``t_max`` of a series on the grid ``t``.

    The extremes are over the finite values (the first output time where each is reached);
    a series with no finite value has ``None`` extremes.  ``start`` and ``end`` are the first
    and last values as they are (a NaN there stays NaN; the CLI writes it as ``null``).
    """
    values = np.asarray(values, dtype=float)
    out = {"start": float(values[0]), "end": float(values[-1])}
    finite = np.isfinite(values)
    if not finite.any():
        return {**out, "min": None, "t_min": None, "max": None, "t_max": None}
    lo = int(np.argmin(np.where(finite, values, np.inf)))
    hi = int(np.argmax(np.where(finite, values, -np.inf)))
    return {**out, "min": float(values[lo]), "t_min": float(t[lo]),
            "max": float(values[hi]), "t_max": float(t[hi])}


def check_npz_name(path: str | os.PathLike) -> None:
    """Refuse to write an npz file under a name that does not end in ``.npz``
    (:class:`~casmbd.errors.ResultFileError` naming the file)."""
    suffix = Path(path).suffix
    if suffix.lower() != ".npz":
        given = repr(suffix) if suffix else "a name without suffix"
        raise ResultFileError(f"'{path}': a result file is written as .npz (to_csv writes "
                              f".csv), not as {given}")


#: column labels of the components of vector-valued series, by array name prefix
_AXES = {2: ("x", "y"), 3: ("x", "y", "z")}
_REACTIONS = {3: ("Fx", "Fy", "M"), 6: ("Fx", "Fy", "Fz", "Mx", "My", "Mz")}
_EQUATION = re.compile(r"^(\w+) '(.*)' equation '(.*)'$")


@dataclass
class Result:
    """Arrays of an analysis on a time grid.

    Attributes
    ----------
    kind : str
        Analysis that produced it ("kinematics", "simulation", ...).
    t : ndarray, shape (n_t,)
    arrays : dict of str to ndarray
        ``q``, ``v``, ``a`` (n_t, n_q) and named outputs (``body_positions`` (n_t, dim n_b),
        in the plane ``angle_positions`` (n_t, n_b), in space ``rotation_matrices``
        (n_t, 9 n_b, A row by row) and ``angular_velocities`` (n_t, 3 n_b, global),
        ``marker_positions``, ``joint_positions`` …, ``joint_reactions`` (n_t, n_joints, 3 in
        the plane / 6 in space), ``constraint_violation`` (n_t,); with flexible bodies'
        named nodes ``node_positions``, ``node_deflections``, ``node_rotations``).
    names : dict of str to list of str
        ``coordinates``, ``bodies``, ``markers``, ``joints`` (one entry per joint coordinate:
        the joint's name for its first, ``joint.angle`` for a cylindrical joint's second),
        ``all_joints``, ``nodes`` (``"<body>@<node>"``, :meth:`node`); optionally
        ``dimension`` (else inferred, see :attr:`dimension`).
    stats : dict
        Timings and counters (``solve_seconds``, ``build_seconds`` …).
    """

    kind: str
    t: np.ndarray
    arrays: dict[str, np.ndarray]
    names: dict[str, list[str]]
    stats: dict = field(default_factory=dict)
    scene: str = ""
    #: events of an event-driven run (contacts, joint limits: casmbd.analysis.events.events), each
    #: ``{"time": float, "element": str, "kind": str}`` (impact, limit, contact, detach,
    #: stick, slip)
    events: list = field(default_factory=list)
    #: reads :attr:`scene` into a Mechanism (``reader(text, source=...)``), given by whoever
    #: knows the scene format: scene parsing lives in :mod:`casmbd.io`, a layer above this one,
    #: so :func:`casmbd.io.scene.load_result` (``casmbd.load``) and :meth:`attach_scene` (from a
    #: mechanism read by :func:`casmbd.io.scene.loads_scene`) pass it in; nothing registers it
    scene_reader: Callable[..., object] | None = field(default=None, repr=False,
                                                       compare=False)

    def __getitem__(self, key: str) -> np.ndarray:
        return self.t if key == "t" else self.arrays[key]

    # ------------------------------------------------------------------ accessors
    @property
    def dimension(self) -> int:
        """2 (planar) or 3 (spatial): ``names["dimension"]`` when the analysis stored it, else
        read from the arrays (rotation matrices only in space, angles only in the plane, or
        the width of ``body_positions`` per body)."""
        dim = self.names.get("dimension")
        if dim in (2, 3):
            return int(dim)
        if "rotation_matrices" in self.arrays:
            return 3
        if "angle_positions" in self.arrays:
            return 2
        n_b = len(self.names.get("bodies", []))
        if n_b and "body_positions" in self.arrays:
            return int(self.arrays["body_positions"].shape[1] // n_b)
        return 2

    def body(self, name: str) -> dict[str, np.ndarray]:
        """Pose and motion of a body on the grid.

        Always ``position`` (n_t, dim) of the centre of mass and, when computed, ``velocity``
        and ``acceleration`` (n_t, dim).  In the plane ``angle``, ``angular_velocity`` and
        ``angular_acceleration`` (n_t,).  In space ``rotation`` (n_t, 3, 3), the matrix A
        taking body components to global ones (r = r_G + A u, seed 001 eq. 1), ``quaternion``
        (n_t, 4) [w, x, y, z] of A, sign-continuous in time
        (:func:`casmbd.system.descriptions.quaternions_from_matrices`), and ``angular_velocity``
        / ``angular_acceleration`` (n_t, 3) in global components.
        """
        i = self.names["bodies"].index(name)
        dim = self.dimension
        out = {}
        for key, src in (("position", "body_positions"), ("velocity", "body_velocities"),
                         ("acceleration", "body_accelerations")):
            if src in self.arrays:
                out[key] = self.arrays[src][:, dim * i:dim * i + dim]
        if dim == 2:
            for key, src in (("angle", "angle_positions"),
                             ("angular_velocity", "angle_velocities"),
                             ("angular_acceleration", "angle_accelerations")):
                if src in self.arrays:
                    out[key] = self.arrays[src][:, i]
            return out
        if "rotation_matrices" in self.arrays:
            rot = self.arrays["rotation_matrices"][:, 9 * i:9 * i + 9]
            out["rotation"] = rot.reshape(-1, 3, 3)
            out["quaternion"] = quaternions_from_matrices(rot)
        for key, src in (("angular_velocity", "angular_velocities"),
                         ("angular_acceleration", "angular_accelerations")):
            if src in self.arrays:
                out[key] = self.arrays[src][:, 3 * i:3 * i + 3]
        return out

    def euler_angles(self, name: str, sequence: str = "zxz") -> np.ndarray:
        """Euler angles (n_t, 3) of a spatial body on the grid, in radians.

        ``sequence="zxz"`` gives (φ, θ, ψ) of seed 001 eq. 32 (A = A_z(φ) A_x(θ) A_z(ψ), θ ∈
        [0, π]); ``"xyz"`` the Cardan/Bryant angles (A = A_x(φ) A_y(θ) A_z(ψ), θ ∈ [−π/2, π/2]).
        Angles are wrapped to (−π, π]; apply ``numpy.unwrap`` along axis 0 for a turning body.

        Warns
        -----
        RuntimeWarning
            Once, naming the body and the first time at which the set is singular (Z–X–Z:
            sin θ ≈ 0; X–Y–Z: cos θ ≈ 0), where only a sum or difference of φ and ψ is
            defined; there ψ is set to 0 (see :mod:`casmbd.model.rotations`).
        """
        if self.dimension != 3:
            raise AnalysisError(f"body '{name}': Euler angles exist for spatial bodies only; "
                              "a planar body has 'angle'")
        convert = {"zxz": rotations.quaternion_to_euler_zxz,
                   "xyz": rotations.quaternion_to_euler_xyz}.get(sequence)
        if convert is None:
            raise AnalysisError(f"unknown Euler sequence {sequence!r} (known: 'zxz', 'xyz')")
        quats = self.body(name).get("quaternion")
        if quats is None:
            raise AnalysisError(f"body '{name}': the result holds no orientations")
        out = np.empty((len(quats), 3))
        first = None
        for k, p in enumerate(quats):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                out[k] = convert(p)
            if caught and first is None:
                first = k
        if first is not None:
            when = f"t = {self.t[first]:.6g}"
            warnings.warn(f"body '{name}': {sequence.upper()} Euler angles pass their "
                          f"singularity (first at {when}); psi is set to 0 there",
                          RuntimeWarning, stacklevel=2)
        return out

    def marker(self, name: str) -> dict[str, np.ndarray]:
        """Position, velocity and acceleration (n_t, dim) of a marker and, when computed, its
        frame: in space ``rotation`` (n_t, 3, 3), body components to global, and
        ``quaternion`` (n_t, 4) [w, x, y, z], sign-continuous in time; in the plane ``angle``
        (n_t,).  The frame is the body's unless the marker was given an orientation
        (:class:`casmbd.model.bodies.Marker`)."""
        i, dim = self.names["markers"].index(name), self.dimension
        out = {key: self.arrays[f"marker_{src}"][:, dim * i:dim * i + dim]
               for key, src in (("position", "positions"), ("velocity", "velocities"),
                                ("acceleration", "accelerations"))
               if f"marker_{src}" in self.arrays}
        if "marker_rotations" in self.arrays:
            rot = self.arrays["marker_rotations"][:, 9 * i:9 * i + 9]
            out["rotation"] = rot.reshape(-1, 3, 3)
            out["quaternion"] = quaternions_from_matrices(rot)
        if "marker_angles" in self.arrays:
            out["angle"] = self.arrays["marker_angles"][:, i]
        return out

    def node(self, name: str) -> dict[str, np.ndarray]:
        """A flexible body's named node ``"<body>@<node>"``: ``position`` (n_t, dim), global,
        deformed; ``deflection`` (n_t, dim) Φ_i η and ``rotation`` ψ_i = Ψ_i η ((n_t,) in the
        plane, (n_t, 3) in space), relative to the undeformed body frame in body axes
        (:func:`casmbd.system.requests.node_expressions`)."""
        nodes = self.names.get("nodes", [])
        if name not in nodes:
            raise KeyError(f"no node '{name}' in this result (nodes: "
                           f"{', '.join(nodes) or 'none'})")
        i, dim = nodes.index(name), self.dimension
        rdim = 1 if dim == 2 else 3
        out = {key: self.arrays[f"node_{src}"][:, dim * i:dim * i + dim]
               for key, src in (("position", "positions"), ("deflection", "deflections"))
               if f"node_{src}" in self.arrays}
        if "node_rotations" in self.arrays:
            rot = self.arrays["node_rotations"][:, rdim * i:rdim * i + rdim]
            out["rotation"] = rot[:, 0] if dim == 2 else rot
        return out

    def joint(self, name: str) -> dict[str, np.ndarray]:
        """Coordinate, its rate and acceleration (n_t,) of a joint with a coordinate.

        A joint with a second coordinate (the angle of a cylindrical joint, column
        ``"joint.angle"`` of ``joint_positions``) also gives ``angle``, ``angle_velocity`` and
        ``angle_acceleration``; ``result.joint("joint.angle")`` reads that column alone.
        """
        columns = self.names["joints"]
        i = columns.index(name)
        out = {key: self.arrays[f"joint_{src}"][:, i]
               for key, src in (("coordinate", "positions"), ("velocity", "velocities"),
                                ("acceleration", "accelerations"))
               if f"joint_{src}" in self.arrays}
        for k, column in enumerate(columns):
            prefix, _, coord = column.rpartition(".")
            if prefix == name and column not in self._joint_names():
                for key, src in (("", "positions"), ("_velocity", "velocities"),
                                 ("_acceleration", "accelerations")):
                    if f"joint_{src}" in self.arrays:
                        out[coord + key] = self.arrays[f"joint_{src}"][:, k]
        return out

    def _joint_names(self) -> list[str]:
        """Every joint's name (``all_joints``; results without it: the first-coordinate
        columns)."""
        if "all_joints" in self.names:
            return list(self.names["all_joints"])
        return [c for c in self.names["joints"] if c.rpartition(".")[0] not in
                self.names["joints"]]

    def output(self, name: str) -> np.ndarray:
        """A request's values (n_t,) on the grid (``[[outputs]]``, :mod:`casmbd.model.measures`)."""
        return self.arrays["outputs"][:, self.names["outputs"].index(name)]

    def force(self, name: str) -> dict[str, np.ndarray]:
        """What force element ``name`` reports (n_t,) by quantity (``force_outputs``: a spring's
        ``length``, ``rate`` and ``force``, an expression force's ``value``, …; {}: nothing)."""
        return {label.rpartition(".")[2]: self.arrays["force_outputs"][:, k]
                for k, label in enumerate(self.names.get("force_outputs", []))
                if label.rpartition(".")[0] == name}

    def summary(self) -> dict:
        """What the text summaries list: each request (``[[outputs]]``) with its unit and
        :func:`extremes` (start, end, min and max with their times), and each named node of a
        flexible body with the magnitude |u_i| = |Φ_i η| of its elastic displacement relative
        to its undeformed position in the body frame (seed 002, eq. 5–26; the deflection of
        :meth:`node`): start, end, max and its time, in m.

        Returns ``{"outputs": {name: {"unit", "start", "end", "min", "t_min", "max",
        "t_max"}}, "node_deflections": {name: {"unit", "start", "end", "max", "t_max"}}}``,
        each key only when the result has such values (``{}``: none); ``to_json`` gives it as
        ``"summary"``.
        """
        out: dict = {}
        if "outputs" in self.arrays and self.names.get("outputs") and len(self.t):
            units = list(self.names.get("output_units", []))
            out["outputs"] = {
                name: {"unit": units[k] if k < len(units) else "",
                       **extremes(self.t, self.output(name))}
                for k, name in enumerate(self.names["outputs"])}
        if "node_deflections" in self.arrays and self.names.get("nodes") and len(self.t):
            nodes = {}
            for name in self.names["nodes"]:
                size = np.linalg.norm(self.node(name)["deflection"], axis=1)
                ext = extremes(self.t, size)
                nodes[name] = {"unit": "m", "start": ext["start"], "end": ext["end"],
                               "max": ext["max"], "t_max": ext["t_max"]}
            out["node_deflections"] = nodes
        return out

    # ------------------------------------------------------------------ views
    def to_json(self) -> dict:
        """The JSON object of the CLI contract."""
        bodies = {}
        orientation = "angle" if self.dimension == 2 else "quaternion"
        for name in self.names["bodies"]:
            b = self.body(name)
            bodies[name] = {"position": _list(b["position"]),
                            orientation: _list(b[orientation])}
            if "velocity" in b:
                bodies[name]["velocity"] = _list(b["velocity"])
                bodies[name]["angular_velocity"] = _list(b["angular_velocity"])
            modal = [k for k, c in enumerate(self.names.get("coordinates", []))
                     if c.startswith(f"{name}.eta")]
            if modal and "q" in self.arrays:  # a flexible body's modal coordinates η
                bodies[name]["modal_coordinates"] = _list(self.arrays["q"][:, modal])
        all_joints = self._joint_names()
        joints: dict = {name: {} for name in all_joints}
        for k, column in enumerate(self.names["joints"]):
            if column in joints:  # a joint's first coordinate
                name, key = column, "coordinate"
            else:  # a further coordinate "joint.angle" (cylindrical)
                name, _, key = column.rpartition(".")
                joints.setdefault(name, {})
            joints[name][key] = _list(self.arrays["joint_positions"][:, k])
            if "joint_velocities" in self.arrays:
                joints[name]["velocity" if key == "coordinate" else f"{key}_velocity"] = \
                    _list(self.arrays["joint_velocities"][:, k])
        if "joint_reactions" in self.arrays:
            for k, name in enumerate(self.names.get("all_joints", [])):
                joints[name]["reaction"] = _list(self.arrays["joint_reactions"][:, k, :])
        markers = {name: {"position": _list(self.marker(name)["position"])}
                   for name in self.names["markers"]}
        for name in markers:  # their frames, when computed
            frame = self.marker(name)
            for key in ("quaternion", "angle"):
                if key in frame:
                    markers[name][key] = _list(frame[key])
        nodes = {name: {k: _list(v) for k, v in self.node(name).items()}
                 for name in self.names.get("nodes", []) if "node_positions" in self.arrays}
        cv = self.arrays.get("constraint_violation", np.zeros(len(self.t)))
        out = {"kind": self.kind, "t": _list(self.t), "bodies": bodies, "joints": joints,
               "markers": markers, **({"nodes": nodes} if nodes else {}),
               "constraint_violation": float(np.max(cv)) if cv.size else 0.0,
               "stats": self.stats}
        if "driver_efforts" in self.arrays:
            out["drivers"] = {name: {"effort": _list(self.arrays["driver_efforts"][:, k])}
                              for k, name in enumerate(self.names.get("drivers", []))}
        if "actuator_efforts" in self.arrays:
            out["actuators"] = {name: {"effort": _list(self.arrays["actuator_efforts"][:, k])}
                                for k, name in enumerate(self.names.get("actuators", []))}
        elif "actuator_inputs" in self.arrays:
            out["actuators"] = {name: {"input": _list(self.arrays["actuator_inputs"][:, k])}
                                for k, name in enumerate(self.names.get("actuators", []))}
        if "kinetic_energy" in self.arrays:
            out["energy"] = {key: _list(self.arrays[f"{key}_energy"])
                             for key in ("kinetic", "potential", "total")}
        if "velocity_violation" in self.arrays:
            vv = self.arrays["velocity_violation"]
            out["velocity_violation"] = float(np.max(vv)) if vv.size else 0.0
        if "outputs" in self.arrays:  # requests, and the force elements' own measures
            out["outputs"] = {n: _list(self.output(n)) for n in self.names.get("outputs", [])}
        if "force_outputs" in self.arrays:
            out["forces"] = {e: {k: _list(v) for k, v in self.force(e).items()} for e in
                             dict.fromkeys(x.rpartition(".")[0] for x in
                                           self.names.get("force_outputs", []))}
        if self.events or self.stats.get("event_driven"):
            out["events"] = [dict(e) for e in self.events]
        summary = self.summary()
        if summary:  # requests' extremes and nodes' deflection magnitudes (text summaries)
            out["summary"] = summary
        if "contact_forces" in self.arrays:  # a frictional contact's second column: friction
            out["contacts"] = {}
            for k, name in enumerate(self.names.get("contacts", [])):
                key = "friction_force" if name in out["contacts"] else "normal_force"
                out["contacts"].setdefault(name, {})[key] = \
                    _list(self.arrays["contact_forces"][:, k])
        return out

    # ------------------------------------------------------------------ files
    def payload(self, **meta) -> dict[str, np.ndarray]:
        """The entries of the result's npz file (:meth:`save`): ``t``, ``array/NAME``, the JSON
        ``meta`` (kind, names, stats, events, and the extra ``meta`` keys given) and ``scene``.
        A file with further entries beside these (an OCP solution's ``u``) still loads as a
        result."""
        payload = {"t": self.t, **{f"array/{k}": v for k, v in self.arrays.items()}}
        payload["meta"] = np.array(json.dumps({"kind": self.kind, "names": self.names,
                                               "stats": self.stats, "events": self.events,
                                               **meta}, default=json_default))
        payload["scene"] = np.array(self.scene)
        return payload

    def save(self, path: str | os.PathLike) -> Path:
        """Write every array, the names, stats and scene text to an npz file atomically.

        Raises
        ------
        ResultFileError
            ``path`` does not end in ``.npz`` (a ``.csv`` name is :meth:`to_csv`'s: an npz
            file under another name is never written).
        """
        check_npz_name(path)
        payload = self.payload()

        def write(tmp: str) -> None:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **payload)

        return atomic_write(path, write)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Result:
        """Read a result written by :meth:`save` (same as :func:`casmbd.results.load`)."""
        return load(path)

    def mechanism(self, reader: Callable[..., object] | None = None):
        """The :class:`~casmbd.model.Mechanism` of the scene text embedded in the result.

        Parameters
        ----------
        reader : callable, optional
            ``reader(text, source=...)`` -> Mechanism, e.g. :func:`casmbd.loads_scene`;
            default :attr:`scene_reader` (set when the result was read by :func:`casmbd.load`
            or given a scene-loaded mechanism by :meth:`attach_scene`).

        Raises
        ------
        AnalysisError
            When the result holds no scene text (built in Python from a mechanism that did not
            come from a scene file; pass the mechanism explicitly instead), or when no reader
            is given nor carried (read with :func:`casmbd.results.load`: pass
            ``reader=casmbd.loads_scene`` or read it with :func:`casmbd.load`).
        """
        if not self.scene:
            raise AnalysisError(f"this {self.kind} result holds no scene text (the mechanism "
                                "was not loaded from a scene file); pass the mechanism")
        reader = reader if reader is not None else self.scene_reader
        if reader is None:
            raise AnalysisError(f"this {self.kind} result carries no scene reader: pass one "
                                "(result.mechanism(casmbd.loads_scene)) or read the file with "
                                "casmbd.load")
        return reader(self.scene, source=f"<scene embedded in the {self.kind} result>")

    def attach_scene(self, mechanism) -> Result:
        """Embed the scene text of ``mechanism`` (``mechanism.scene_text``, set by
        :func:`casmbd.load_scene`) so that :meth:`save` stores it; returns ``self``."""
        self.scene = getattr(mechanism, "scene_text", "") or self.scene
        self.scene_reader = getattr(mechanism, "scene_reader", None) or self.scene_reader
        return self

    # ------------------------------------------------------------------ CSV
    def _labels(self, key: str, arr: np.ndarray) -> list[str]:
        """Column labels ``key[element.field]`` of one array (flattened row-major)."""
        names, dim = self.names, self.dimension
        n = int(np.prod(arr.shape[1:], dtype=int))

        def per(elements, fields):
            labels = [f"{e}.{f}" for e in elements for f in fields]
            return labels if len(labels) == n else None

        groups = {"q": names.get("coordinates"), "v": names.get("coordinates"),
                  "a": names.get("coordinates")}
        labels = None
        if key in groups and groups[key] and len(groups[key]) == n:
            labels = list(groups[key])
        elif key.startswith("body_"):
            labels = per(names.get("bodies", []), _AXES[dim])
        elif key.startswith("angle_"):
            labels = per(names.get("bodies", []), ("angle",))
        elif key == "rotation_matrices":
            labels = per(names.get("bodies", []), [f"A{i}{j}" for i in range(1, 4)
                                                    for j in range(1, 4)])
        elif key.startswith("angular_"):
            labels = per(names.get("bodies", []), ("wx", "wy", "wz"))
        elif key == "marker_rotations":
            labels = per(names.get("markers", []), [f"A{i}{j}" for i in range(1, 4)
                                                     for j in range(1, 4)])
        elif key == "marker_angles":
            labels = per(names.get("markers", []), ("angle",))
        elif key.startswith("marker_"):
            labels = per(names.get("markers", []), _AXES[dim])
        elif key == "node_rotations":
            labels = per(names.get("nodes", []), ("angle",) if dim == 2 else
                         ("rx", "ry", "rz"))
        elif key.startswith("node_"):
            labels = per(names.get("nodes", []), _AXES[dim])
        elif key.startswith("joint_") and key != "joint_reactions":
            joints = names.get("joints", [])
            labels = list(joints) if len(joints) == n else None
        elif key == "joint_reactions" and arr.ndim == 3:
            labels = per(names.get("all_joints", []), _REACTIONS.get(arr.shape[2], ()))
        elif key in ("outputs", "force_outputs"):
            labels = list(names.get(key, [])) if len(names.get(key, [])) == n else None
        elif key == "driver_efforts":
            labels = per(names.get("drivers", []), ("effort",))
        elif key.startswith("actuator_"):
            labels = per(names.get("actuators", []), (key.split("_", 1)[1].rstrip("s"),))
        elif key == "lambda" and len(names.get("constraints", [])) == n:
            labels = []
            for text in names.get("constraints", []):  # none: a tree, lambda of size 0
                m = _EQUATION.match(text)
                labels.append(f"{m.group(2)}.{m.group(3)}" if m else text)
        if labels is None:
            labels = [".".join(map(str, idx)) for idx in np.ndindex(*arr.shape[1:])]
        return [f"{key}[{label}]" if arr.ndim > 1 else key for label in labels]

    def csv_columns(self) -> list[tuple[str, np.ndarray]]:
        """The scalar series of :meth:`to_csv`: ``("t", t)`` then, per array in storage order,
        one ``(label, values)`` per component (row-major), labelled ``array[element.field]``
        (``q[crank.angle]``, ``body_positions[rod.y]``, ``joint_reactions[O.Fx]``,
        ``lambda[O.x]``; a scalar series by its name, ``total_energy``).  Arrays that are not
        on the time grid are left out."""
        n_t = len(self.t)
        columns = [("t", np.asarray(self.t, float))]
        for key, arr in self.arrays.items():
            arr = np.asarray(arr)
            if arr.ndim == 0 or arr.shape[0] != n_t or not np.issubdtype(arr.dtype, np.number):
                continue
            flat = arr.reshape(n_t, -1).astype(float)
            labels = self._labels(key, arr) if arr.ndim > 1 else [key]
            columns += [(label, flat[:, k]) for k, label in enumerate(labels)]
        return columns

    def to_csv(self, path: str | os.PathLike) -> Path:
        """Write one column per scalar series (:meth:`csv_columns`) with a one-line header, values
        with 17 significant digits (they read back exactly), atomically.

        ``numpy.loadtxt(path, delimiter=",", skiprows=1)`` reads the numbers back; NaN is
        written as ``nan``.

        Raises
        ------
        ResultFileError
            ``path`` does not end in ``.csv`` (:meth:`save` writes ``.npz``).
        """
        suffix = Path(path).suffix
        if suffix.lower() != ".csv":
            given = repr(suffix) if suffix else "a name without suffix"
            raise ResultFileError(f"'{path}': to_csv writes a .csv file (save writes .npz), not "
                                  f"{given}")
        columns = self.csv_columns()
        table = np.column_stack([c for _, c in columns]) if len(self.t) else \
            np.empty((0, len(columns)))

        def write(tmp: str) -> None:
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                writer = csv.writer(fh)
                writer.writerow([label for label, _ in columns])
                for row in table:
                    writer.writerow([repr(float(x)) for x in row])

        return atomic_write(path, write)


def json_default(obj):
    """``json.dumps`` hook: numpy arrays as lists, numpy scalars as Python numbers."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()  # np.bool_ -> bool
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


#: largest total size of a result file's arrays that :func:`read_npz` reads (the sizes the
#: members' ``.npy`` headers declare; :data:`casmbd.limits.MAX_NPZ_BYTES`)
MAX_NPZ_BYTES = limits.MAX_NPZ_BYTES


def read_npz(path: str | os.PathLike, what: str = "result") -> dict[str, np.ndarray]:
    """Every array of an npz file, read eagerly, without pickle.

    The file must be a regular file of at most :data:`MAX_NPZ_BYTES` (``os.stat`` before it
    is opened: a FIFO or a device is refused, never read).  It is checked as a zip archive
    (a text file, a truncated or corrupted file and a zip of something else are named as
    such), encrypted members are refused, and every member's ``.npy`` header is read and
    checked before any array is allocated (:func:`casmbd.limits.check_npz`): the declared
    shape × item size must fit in what the member holds (a header declaring (1e6, 1e6) over a
    small member is refused as forged) and in :data:`MAX_NPZ_BYTES` and the memory budget
    (:func:`casmbd.limits.memory_budget`) together, and object
    arrays, which would run code on unpickling, are refused.  ``np.load`` then runs with
    ``allow_pickle=False``.

    Raises
    ------
    LimitError
        The file exceeds :data:`MAX_NPZ_BYTES`, or the arrays its headers declare exceed that
        or the memory budget.
    ResultFileError
        Naming the file and what is wrong with it.
    """
    where = f"{what} file '{path}'"
    if os.path.lexists(path):
        limits.check_regular_file(path, what, MAX_NPZ_BYTES, ResultFileError)
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
        if head[:2] != b"PK":
            why = "it is empty" if not head else "it is not a zip archive"
            raise ResultFileError(f"cannot read {where}: not an npz file ({why})")
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            if any(info.flag_bits & 0x1 for info in infos):
                raise ResultFileError(f"cannot read {where}: it has encrypted members")
            not_npy = [info.filename for info in infos if not info.filename.endswith(".npy")]
            if not infos or not_npy:
                raise ResultFileError(f"cannot read {where}: a zip archive but not an npz "
                                      f"file (members {', '.join(not_npy[:3]) or 'none'})")
            # every .npy header, before np.load allocates: at most MAX_NPZ_BYTES and the
            # memory budget together, and no more than each member holds
            limits.check_npz(zf, f"cannot read {where}", None, None, ResultFileError)
            bad = zf.testzip()  # reads every member: CRC of each
        if bad is not None:
            raise ResultFileError(f"cannot read {where}: member '{bad}' is corrupted "
                                  "(CRC mismatch)")
        with np.load(path, allow_pickle=False) as data:
            return {key: data[key] for key in data.files}
    except ResultFileError:
        raise
    except FileNotFoundError:
        raise ResultFileError(f"cannot read {where}: not found") from None
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error,
            NotImplementedError, struct.error) as exc:
        why = f"{exc or type(exc).__name__} (truncated or corrupted?)"
        if "allow_pickle" in why:
            why = "it holds object arrays, which are refused (they could run code when read)"
        raise ResultFileError(f"cannot read {where}: {why}") from None


def load(path: str | os.PathLike) -> Result:
    """Read a result written by :meth:`Result.save`.

    The file is validated (see :func:`read_npz`): a JSON ``meta`` entry with the kind, names
    and statistics, a finite 1-D time grid, and numeric arrays with one row per time.

    Raises
    ------
    ResultFileError
        When the file is missing, unreadable, truncated, corrupted or not a result file
        (naming the file and what is wrong); an :class:`~casmbd.errors.AnalysisError`.
    """
    data = read_npz(path)
    where = f"'{path}' is not a casmbd result file"
    if "meta" not in data:
        raise ResultFileError(f"{where} (no 'meta' entry)")
    try:
        meta = json.loads(str(data["meta"]))
    except ValueError as exc:
        raise ResultFileError(f"{where} (its 'meta' entry is not JSON: {exc})") from None
    if not isinstance(meta, dict):
        raise ResultFileError(f"{where} (its 'meta' entry is not a JSON object)")
    for key, kind in (("kind", str), ("names", dict), ("stats", dict)):
        if not isinstance(meta.get(key), kind):
            raise ResultFileError(f"{where} ('meta' has no {kind.__name__} '{key}')")
    for key, names in meta["names"].items():
        if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
            raise ResultFileError(f"{where} ('meta' names '{key}' is not a list of names)")
    if "t" not in data:
        raise ResultFileError(f"{where} (no time grid 't')")
    t = data["t"]
    if t.dtype.kind not in "iuf" or t.ndim != 1 or t.size == 0 or \
            not np.all(np.isfinite(t)):
        raise ResultFileError(f"{where} ('t' must be a non-empty 1-D array of finite numbers, "
                              f"got shape {t.shape}, dtype {t.dtype})")
    arrays = {}
    for key, arr in data.items():
        if not key.startswith("array/"):
            continue
        name = key.split("/", 1)[1]
        if arr.dtype.kind not in "biuf" or arr.ndim == 0 or arr.shape[0] != t.size:
            raise ResultFileError(f"{where} (array '{name}': expected numbers with one row per "
                                  f"time ({t.size}), got shape {arr.shape}, dtype {arr.dtype})")
        arrays[name] = arr
    scene = data.get("scene", np.array(""))
    if scene.dtype.kind != "U" or scene.ndim != 0:
        raise ResultFileError(f"{where} (its 'scene' entry is not a text)")
    events = meta.get("events", [])
    if not (isinstance(events, list) and all(
            isinstance(e, dict) and isinstance(e.get("time"), int | float)
            and isinstance(e.get("element"), str) and isinstance(e.get("kind"), str)
            for e in events)):
        raise ResultFileError(f"{where} ('meta' events must be a list of {{time, element, "
                              "kind}})")
    return Result(meta["kind"], t, arrays, meta["names"], meta["stats"], str(scene), events)


load_result = load
