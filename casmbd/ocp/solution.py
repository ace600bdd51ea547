"""The solution of an optimal-control problem: sample, interpolate, replay, plot, save."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import casadi as ca
import numpy as np

from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.instant.kkt import accelerations_and_multipliers
from casmbd.compiled.build import compile_model
from casmbd.errors import AnalysisError, CasmbdError, IntegratorError, ResultFileError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.measures import result_names
from casmbd.results import Result, atomic_write, check_npz_name, read_npz

#: Tolerance at which :meth:`OcpSolution.replay` repeats a replay whose integrator failed at a
#: tighter one (near round-off, on fast elastic modes).
REPLAY_FALLBACK_RTOL = 1e-10
#: ``replay_error`` relative to the state scale max(1, |q|, |q̇|) above which a replay warns:
#: the optimal controls do not reproduce the optimal trajectory (a mesh too coarse for the
#: dynamics, or a problem so loosely posed that it rides a chaotic passive motion).  Sound
#: solutions replay far below it: the double-pendulum swing-up (two elements per interval)
#: to 4.4e-7 (scale 8.6), the flexible slew to 8.4e-4; the coarse flexible mesh replays to
#: 16.9 (scale 5.1), a free-elbow swing-up to 8.55 (scale 24.3: elbow free at the start,
#: one control unbounded).
REPLAY_WARNING_RATIO = 1e-2


class OcpSolution:
    """States on the mesh, piecewise-constant controls and the solver's statistics.

    Attributes
    ----------
    t : ndarray (N S + 1,)
        Mesh times (S = ``stats["subintervals"]`` collocation elements per control interval).
    q, v : ndarray (N S + 1, n_q)
        Coordinates and velocities at the mesh nodes.
    u : ndarray (N, n_u)
        Control on each interval (actuator order of the mechanism).
    objective : float
    stats : dict
        ``success``, ``return_status``, ``iterations``, ``constraint_violation``,
        ``solve_seconds`` (NLP solver wall time), ``setup_seconds``, sizes, and after
        :meth:`replay` ``replay_error``.
    scene : str
        The scene text of the problem's mechanism (empty when built in Python), saved with the
        solution so that ``casmbd animate`` can draw it.
    """

    def __init__(self, t, q, v, u, stats, controls, coordinate_names, ocp=None, w=None,
                 names=None, scene: str = "", arrays: dict | None = None,
                 result_names: dict | None = None):
        self.t = np.asarray(t, dtype=float)
        self.q = np.asarray(q, dtype=float)
        self.v = np.asarray(v, dtype=float)
        self.u = np.asarray(u, dtype=float)
        self.stats = dict(stats)
        self.controls = list(controls)
        self.coordinate_names = list(coordinate_names)
        self.ocp = ocp
        self.w = w
        self.names = names
        self.scene = scene or (getattr(ocp.system.mechanism, "scene_text", "") or ""
                               if ocp is not None else "")
        #: node arrays and their names read from a file (:meth:`to_result` without the problem)
        self._arrays = dict(arrays or {})
        self._result_names = dict(result_names or {})

    @classmethod
    def from_transcription(cls, tr, x: np.ndarray, info: dict, lam_g, g) -> OcpSolution:
        b = tr.b
        offsets = np.cumsum([0] + [r * c for r, c in b.shapes])

        def block(index: int) -> np.ndarray:
            rows, cols = b.shapes[index]
            return x[offsets[index]:offsets[index + 1]].reshape(cols, rows)

        T = float(block(tr.T_block)[0, 0]) if tr.T_block is not None else float(tr.ocp.horizon)
        t = tr.ocp.t_start + np.linspace(0.0, T, tr.M + 1)
        xs = block(tr.X_block)
        us = block(tr.U_block)
        info = dict(info)
        info["final_time"] = T
        info["subintervals"] = tr.S
        return cls(t, xs[:, :tr.nq], xs[:, tr.nq:], us, info, tr.ocp.controls,
                   tr.system.coordinate_names, tr.ocp, x, list(b.names))

    # ------------------------------------------------------------------ access
    @property
    def subintervals(self) -> int:
        """Collocation elements per control interval."""
        return int(self.stats.get("subintervals", 1))

    @property
    def control_times(self) -> np.ndarray:
        """Boundaries (N + 1,) of the control intervals."""
        return self.t[::self.subintervals]

    @property
    def success(self) -> bool:
        return bool(self.stats.get("success"))

    @property
    def objective(self) -> float:
        return float(self.stats["objective"])

    @property
    def iterations(self) -> int:
        return int(self.stats["iterations"])

    def control(self, name: str) -> np.ndarray:
        """Values (N,) of one actuator input on the intervals."""
        if name not in self.controls:
            raise AnalysisError(f"unknown actuator '{name}' (known: {', '.join(self.controls)})")
        return self.u[:, self.controls.index(name)]

    def value(self, expression) -> np.ndarray:
        """A named expression (string or callable of the quantities) at every mesh node; the
        control at node k is that of interval min(k, N − 1)."""
        if self.ocp is None:
            raise AnalysisError("this solution was loaded from a file; rebuild the problem to "
                                "evaluate expressions")
        system = self.ocp.system
        expr = self.ocp.expression(expression, "value")
        f = ca.Function("value", [system.q, system.v, system.t, system.u, system.p], [expr])
        n = len(self.t)
        u = self.u[np.minimum(np.arange(n) // self.subintervals, len(self.u) - 1)]
        out = f.map(n)(self.q.T, self.v.T, self.t[None, :], u.T,
                       np.tile(system.parameter_values[:, None], (1, n)))
        return np.asarray(out).ravel()

    sample = value

    def interpolate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, v, u) at times ``t``: cubic Hermite on (q, q̇) between nodes, u piecewise
        constant."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        ku = np.minimum(k // self.subintervals, len(self.u) - 1)
        h = self.t[k + 1] - self.t[k]
        s = ((t - self.t[k]) / h)[:, None]
        h = h[:, None]
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        q = h00 * self.q[k] + h10 * h * self.v[k] + h01 * self.q[k + 1] + h11 * h * self.v[k + 1]
        v = (self.v[k] * (1 - s) + self.v[k + 1] * s)
        return q, v, self.u[ku]

    def inputs(self) -> dict:
        """Actuator inputs for :func:`casmbd.simulate`: piecewise-constant callables of t."""
        knots = ca.DM(list(self.control_times[1:-1]))

        def piecewise(vals):
            return lambda t: ca.pw_const(t, knots, ca.DM(vals))

        return {name: piecewise([float(x) for x in self.u[:, i]]) if knots.numel()
                else float(self.u[0, i]) for i, name in enumerate(self.controls)}

    # ------------------------------------------------------------------ replay
    def replay(self, rtol: float = 1e-12, formulation: str = "index1",
               integrator: str | None = None, steps_per_interval: int = 1):
        """Forward-simulate the optimal controls from the optimal initial state.

        The default is the index-1 DAE on IDAS (BDF, which restarts cleanly at the jumps of
        the piecewise-constant controls; CVODES-Adams carries the jumps into its multistep
        history: 5e-4 instead of 3e-5 on the double-pendulum swing-up).  Returns the simulation
        :class:`~casmbd.results.Result` and stores ``stats["replay_error"]``: the largest
        |q − q_ocp| and |q̇ − q̇_ocp| over the mesh nodes (a measure of the transcription's
        discretisation error, amplified by the dynamics); above :data:`REPLAY_WARNING_RATIO`
        × max(1, |q|, |q̇|) it warns (``RuntimeWarning``, ``stats["replay_warning"]``).
        The default tolerance 1e-12 keeps the integrator's own error out of that figure: at
        1e-10 the double-pendulum swing-up (two elements per interval) replayed to 1.5e-4, at
        1e-12 to 6.4e-7.  Where the
        integrator fails at a tolerance below :data:`REPLAY_FALLBACK_RTOL` the replay is
        repeated at that tolerance and ``stats["replay_rtol"]`` says so: IDAS's corrector
        stops converging near round-off on fast elastic modes (the hub-driven flexible beam
        of ``tests/ocp/test_ocp_flexible.py``, 72 rad/s with modal rates of 54/s: IDA_CONV_FAIL
        with h ≈ 1e-22 at 1e-12; 1e-11 and 1e-10 replay it to the same 1.56e-2).
        """
        if self.ocp is None:
            raise AnalysisError("replay needs the problem (solution loaded from a file)")
        sim = Simulator(self.ocp.system, formulation, inputs=self.inputs())
        steps = steps_per_interval * (len(self.t) - 1)  # output at every mesh node
        try:
            res = sim.run(self.t[-1], steps, t_start=self.t[0], integrator=integrator,
                          rtol=rtol, atol=rtol, q0=self.q[0], v0=self.v[0])
        except IntegratorError:
            if rtol >= REPLAY_FALLBACK_RTOL:
                raise
            rtol = REPLAY_FALLBACK_RTOL
            res = sim.run(self.t[-1], steps, t_start=self.t[0], integrator=integrator,
                          rtol=rtol, atol=rtol, q0=self.q[0], v0=self.v[0])
        self.stats["replay_rtol"] = rtol
        idx = np.arange(0, steps + 1, steps_per_interval)
        err = max(float(np.max(np.abs(res["q"][idx] - self.q))),
                  float(np.max(np.abs(res["v"][idx] - self.v))))
        self.stats["replay_error"] = err
        scale = max(1.0, float(np.max(np.abs(self.q), initial=0.0)),
                    float(np.max(np.abs(self.v), initial=0.0)))
        if not err <= REPLAY_WARNING_RATIO * scale:
            text = (f"replay_error {err:.3g} exceeds {REPLAY_WARNING_RATIO:g} × the state scale "
                    f"{scale:.3g}: the optimal controls do not reproduce the optimal "
                    "trajectory (refine the mesh: more intervals or subintervals; or bound "
                    "the problem better: every control bounded, the initial state given)")
            self.stats["replay_warning"] = text
            warnings.warn(f"ocp: {text}", RuntimeWarning, stacklevel=2)
        return res

    # ------------------------------------------------------------------ output
    def to_json(self) -> dict:
        """The CLI contract: success, objective, iterations, replay_error,
        constraint_violation, stats, and the trajectory."""
        stats = {k: v for k, v in self.stats.items() if _jsonable(v)}
        return {"success": self.success, "objective": self.objective,
                "iterations": self.iterations, "replay_error": self.stats.get("replay_error"),
                "constraint_violation": self.stats.get("constraint_violation"),
                "final_time": float(self.t[-1] - self.t[0]), "stats": stats,
                "t": self.t.tolist(), "controls": {n: self.control(n).tolist()
                                                   for n in self.controls},
                "coordinates": {n: self.q[:, i].tolist()
                                for i, n in enumerate(self.coordinate_names)}}

    def node_controls(self) -> np.ndarray:
        """The controls (n_t, n_u) at the mesh nodes: node k takes the piecewise-constant
        control of interval min(k // S, N − 1) (the last node that of the last interval)."""
        k = np.minimum(np.arange(len(self.t)) // self.subintervals, len(self.u) - 1)
        return self.u[k] if len(self.u) else np.zeros((len(self.t), len(self.controls)))

    def to_result(self) -> Result:
        """The solution as a :class:`~casmbd.results.Result` of kind ``"ocp"`` on the mesh
        nodes, for :func:`casmbd.viz.plot_result`, :func:`casmbd.viz.animate` and the
        ``plot``/``animate`` verbs.

        With the problem at hand: q, q̇, q̈ and λ of the augmented equations
        M q̈ + C_qᵀ λ = Q_e(u) + Q_v, C_q q̈ = γ at every node under its control
        (:meth:`node_controls`), the body, marker and joint outputs, the requests, the
        actuator inputs and max |C| (``constraint_violation``); for a solution loaded from a
        file, the arrays the file holds (a file written before issue 30 holds q, q̇ and the
        controls only).
        """
        u_nodes = self.node_controls()
        stats = {k: v for k, v in self.stats.items() if _jsonable(v)}
        if self.ocp is None:
            arrays = dict(self._arrays) or {"q": self.q, "v": self.v}
            arrays.setdefault("actuator_inputs", u_nodes)
            names = dict(self._result_names) or {"coordinates": list(self.coordinate_names),
                                                 "bodies": [], "markers": [], "joints": [],
                                                 "all_joints": []}
            names.setdefault("actuators", list(self.controls))
            return Result("ocp", self.t.copy(), arrays, names, stats, self.scene)
        system = self.ocp.system
        mech = system.mechanism
        model = compile_model(system, "dynamics", mode="vm")
        n = len(self.t)
        acc, lam = np.zeros((n, model.nq)), np.zeros((n, model.nc))
        violation = np.zeros(n)
        for k in range(n):
            try:
                acc[k], lam[k] = accelerations_and_multipliers(model, self.q[k], self.v[k],
                                                               float(self.t[k]), u_nodes[k])
            except (CasmbdError, ArithmeticError, ValueError, RuntimeError,
                    np.linalg.LinAlgError) as exc:  # a failed solve's last iterate: no q̈
                reraise_interrupt(exc)
                acc[k], lam[k] = np.nan, np.nan
            if model.nc:
                violation[k] = float(np.max(np.abs(model.constraints(self.q[k],
                                                                       float(self.t[k])))))
        outputs = model.outputs(self.q, self.v, acc, self.t)
        names = {"coordinates": list(system.coordinate_names), "bodies": system.body_names,
                 "markers": list(mech.markers), "joints": system.joint_coordinate_names,
                 "all_joints": list(mech.joints), "actuators": list(self.controls),
                 **result_names(mech)}
        arrays = {"q": self.q, "v": self.v, "a": acc, **outputs, "actuator_inputs": u_nodes,
                  "constraint_violation": violation}
        return Result("ocp", self.t.copy(), arrays, names, stats, self.scene)

    def save(self, path: str | os.PathLike) -> Path:
        """The solution in one npz file, written atomically: a result file of kind ``"ocp"``
        (:meth:`to_result`, so ``casmbd plot`` and ``casmbd animate`` read it) plus the
        controls per interval ``u`` and the problem's names in its ``meta``."""
        path = Path(path)
        check_npz_name(path)
        payload = self.to_result().payload(controls=self.controls,
                                           coordinates=self.coordinate_names)
        payload["u"] = self.u

        def write(tmp: str) -> None:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **payload)

        atomic_write(path, write)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> OcpSolution:
        """A solution saved by :meth:`save` (without the problem: no expressions, no replay),
        or by casmbd before issue 30 (top-level ``q`` and ``v``)."""
        data = read_npz(path, "OCP solution")  # ResultFileError on a bad file, naming it
        try:
            meta = json.loads(str(data["meta"]))
            arrays = {k.split("/", 1)[1]: a for k, a in data.items() if k.startswith("array/")}
            q = arrays["q"] if "q" in arrays else data["q"]
            v = arrays["v"] if "v" in arrays else data["v"]
            scene = data.get("scene", np.array(""))
            return cls(data["t"], q, v, data["u"], meta["stats"], meta["controls"],
                       meta["coordinates"], scene=str(scene), arrays=arrays,
                       result_names=meta.get("names"))
        except (ValueError, KeyError, TypeError) as exc:
            raise ResultFileError(f"'{path}' is not a casmbd OCP solution file "
                                  f"({type(exc).__name__}: {exc})") from None

    def plot(self, path: str | os.PathLike | None = None):
        """States and controls against time (matplotlib figure; saved when ``path``).

        One panel per unit: the coordinates (positions [m], angles [rad]), their rates
        ([m/s], [rad/s]), then the controls per interval (piecewise constant; forces [N],
        torques [N m]) with the bounds of :meth:`Ocp.control_bounds` dashed.  The figure of
        the ``plot`` verb (joint coordinates, max |C|) is
        ``casmbd.viz.plot_result(sol.to_result())``, which ``casmbd ocp --plot`` draws."""
        import matplotlib

        if path is not None:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        states: dict[str, list[tuple[str, np.ndarray]]] = {}
        for i, name in enumerate(self.coordinate_names):
            unit = _coordinate_unit(name)
            states.setdefault(unit, []).append((name, self.q[:, i]))
        for i, name in enumerate(self.coordinate_names):
            unit = _coordinate_unit(name)
            states.setdefault(f"{unit}/s", []).append((f"{name} rate", self.v[:, i]))
        mech = self.ocp.system.mechanism if self.ocp is not None else None
        bounds = dict(getattr(self.ocp, "_control_bounds", {}) or {})
        controls: dict[str, list[int]] = {}
        for i, name in enumerate(self.controls):
            controls.setdefault(_control_unit(mech, name), []).append(i)
        n = len(states) + len(controls)
        fig, axes = plt.subplots(n, 1, sharex=True, figsize=(6.4, 1.0 + 1.9 * n), squeeze=False)
        axes = axes[:, 0]
        for ax, (unit, lines) in zip(axes, states.items(), strict=False):
            for label, y in lines:
                ax.plot(self.t, y, lw=1, label=label)
            ax.set_ylabel(f"state [{unit}]", fontsize=8)
            ax.legend(fontsize=7)
        times = self.control_times
        for ax, (unit, cols) in zip(axes[len(states):], controls.items(), strict=True):
            for i in cols:
                name = self.controls[i]
                u = np.r_[self.u[:, i], self.u[-1:, i]] if len(self.u) else np.zeros(len(times))
                ax.step(times, u, where="post", lw=1, label=f"control {name}")
                for value in bounds.get(name, ()):
                    if np.isfinite(value):
                        ax.axhline(value, color="0.4", ls="--", lw=0.8)
            ax.set_ylabel(f"control [{unit}]", fontsize=8)
            ax.legend(fontsize=7)
        axes[-1].set_xlabel("t [s]")
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
            plt.close(fig)
        return fig


def _coordinate_unit(name: str) -> str:
    """Unit of a generalized coordinate by the suffix of its name (1: Euler parameters and
    unit-vector components)."""
    suffix = name.rpartition(".")[2]
    if suffix in ("x", "y", "z", "translation", "length"):
        return "m"
    return "rad" if suffix.startswith("angle") else "1"


def _control_unit(mech, actuator: str) -> str:
    """N along a length, N m about an angle (the actuator's joint coordinate)."""
    act = getattr(mech, "actuators", {}).get(actuator) if mech is not None else None
    joint = getattr(mech, "joints", {}).get(getattr(act, "joint", None)) if act else None
    names = getattr(joint, "coordinate_names", ()) or ()
    coordinate = getattr(act, "coordinate", None) or (names[0] if names else None)
    if coordinate is None:
        return "N or N m"
    return "N m" if str(coordinate).startswith("angle") else "N"


def _jsonable(value) -> bool:
    try:
        json.dumps(value)
    except (TypeError, ValueError):
        return False
    return True
