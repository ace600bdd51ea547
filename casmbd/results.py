"""Result objects shared by the analyses: arrays on a time grid, JSON view and npz files.

A :class:`Result` keeps every array of an analysis (time as the first axis), the names needed to
read them, and statistics.  ``to_json`` gives the CLI contract (``"t"``, ``"bodies"``,
``"joints"``, ``"constraint_violation"``, ``"stats"`` …); ``save`` writes every array to an npz
file atomically (temporary file + rename), and :func:`load` reads it back.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def _list(arr: np.ndarray):
    return np.asarray(arr, dtype=float).tolist()


@dataclass
class Result:
    """Arrays of an analysis on a time grid.

    Attributes
    ----------
    kind : str
        Analysis that produced it ("kinematics", "simulation", ...).
    t : ndarray, shape (n_t,)
    arrays : dict of str to ndarray
        ``q``, ``v``, ``a`` (n_t, n_q) and named outputs (``body_positions`` (n_t, 2 n_b),
        ``body_angles`` (n_t, n_b), ``marker_positions``, ``joint_positions`` …,
        ``constraint_violation`` (n_t,)).
    names : dict of str to list of str
        ``coordinates``, ``bodies``, ``markers``, ``joints`` (joints with a coordinate).
    stats : dict
        Timings and counters (``solve_seconds``, ``build_seconds`` …).
    """

    kind: str
    t: np.ndarray
    arrays: dict[str, np.ndarray]
    names: dict[str, list[str]]
    stats: dict = field(default_factory=dict)
    scene: str = ""

    def __getitem__(self, key: str) -> np.ndarray:
        return self.t if key == "t" else self.arrays[key]

    # ------------------------------------------------------------------ accessors
    def body(self, name: str) -> dict[str, np.ndarray]:
        """Position (n_t, 2), angle, velocity, angular velocity and accelerations of a body."""
        i = self.names["bodies"].index(name)
        out = {}
        for key, src in (("position", "body_positions"), ("velocity", "body_velocities"),
                         ("acceleration", "body_accelerations")):
            if src in self.arrays:
                out[key] = self.arrays[src][:, 2 * i:2 * i + 2]
        for key, src in (("angle", "angle_positions"), ("angular_velocity", "angle_velocities"),
                         ("angular_acceleration", "angle_accelerations")):
            if src in self.arrays:
                out[key] = self.arrays[src][:, i]
        return out

    def marker(self, name: str) -> dict[str, np.ndarray]:
        """Position, velocity and acceleration (n_t, 2) of a marker."""
        i = self.names["markers"].index(name)
        return {key: self.arrays[f"marker_{src}"][:, 2 * i:2 * i + 2]
                for key, src in (("position", "positions"), ("velocity", "velocities"),
                                 ("acceleration", "accelerations"))
                if f"marker_{src}" in self.arrays}

    def joint(self, name: str) -> dict[str, np.ndarray]:
        """Coordinate, its rate and acceleration (n_t,) of a joint with a coordinate."""
        i = self.names["joints"].index(name)
        return {key: self.arrays[f"joint_{src}"][:, i]
                for key, src in (("coordinate", "positions"), ("velocity", "velocities"),
                                 ("acceleration", "accelerations"))
                if f"joint_{src}" in self.arrays}

    # ------------------------------------------------------------------ views
    def to_json(self) -> dict:
        """The JSON object of the CLI contract."""
        bodies = {}
        for name in self.names["bodies"]:
            b = self.body(name)
            bodies[name] = {"position": _list(b["position"]), "angle": _list(b["angle"])}
            if "velocity" in b:
                bodies[name]["velocity"] = _list(b["velocity"])
                bodies[name]["angular_velocity"] = _list(b["angular_velocity"])
        joints = {name: {} for name in self.names.get("all_joints", self.names["joints"])}
        for name in self.names["joints"]:
            j = self.joint(name)
            joints[name]["coordinate"] = _list(j["coordinate"])
            if "velocity" in j:
                joints[name]["velocity"] = _list(j["velocity"])
        if "joint_reactions" in self.arrays:
            for k, name in enumerate(self.names.get("all_joints", [])):
                joints[name]["reaction"] = _list(self.arrays["joint_reactions"][:, k, :])
        markers = {name: {"position": _list(self.marker(name)["position"])}
                   for name in self.names["markers"]}
        cv = self.arrays.get("constraint_violation", np.zeros(len(self.t)))
        out = {"kind": self.kind, "t": _list(self.t), "bodies": bodies, "joints": joints,
               "markers": markers,
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
        return out

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> Path:
        """Write every array, the names, stats and scene text to an npz file atomically."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        payload = {"t": self.t, **{f"array/{k}": v for k, v in self.arrays.items()}}
        payload["meta"] = np.array(json.dumps({"kind": self.kind, "names": self.names,
                                               "stats": self.stats}))
        payload["scene"] = np.array(self.scene)
        fd, tmp = tempfile.mkstemp(prefix=".tmp_", suffix=".npz", dir=path.parent)
        os.close(fd)
        try:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **payload)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return path


def load(path: str | os.PathLike) -> Result:
    """Read a result written by :meth:`Result.save`."""
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["meta"]))
        arrays = {k.split("/", 1)[1]: data[k] for k in data.files if k.startswith("array/")}
        return Result(meta["kind"], data["t"], arrays, meta["names"], meta["stats"],
                      str(data["scene"]))
