"""The compiled numeric model: the runnable counterpart of a symbolic :class:`System`.

Like Pinocchio's ``Model``/``Data`` split, :class:`NumericModel` holds only what runs: the
compiled (or virtual-machine) CasADi Functions an analysis asked for, their sparsity patterns,
and the parameter values.  Matrices come back as ``scipy.sparse`` CSC matrices built from the
fixed sparsity pattern of the generated code.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterable

import casadi as ca
import numpy as np
import scipy.sparse as sp

from casmbd.compiled.codegen import BuildReport, compile_functions
from casmbd.errors import ModelError
from casmbd.system.equations import System

#: Functions each analysis needs; nothing else is generated or compiled for it.
NEEDS: dict[str, tuple[str, ...]] = {
    "info": ("constraints", "constraint_jacobian"),
    "kinematics": ("constraints", "constraint_jacobian", "constraint_time_derivative",
                   "acceleration_rhs", "outputs"),
    "dynamics": ("mass_matrix", "applied_forces", "quadratic_velocity_forces", "constraints",
                 "constraint_jacobian", "constraint_time_derivative", "acceleration_rhs",
                 "kinetic_energy", "potential_energy", "outputs", "joint_reactions",
                 "input_matrix"),
}


def _c_name(name: str) -> str:
    out = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return "casmbd_" + out[:40]


class NumericModel:
    """Compiled equations of a mechanism, built only for the requested Functions.

    Parameters
    ----------
    system : System or Mechanism
        The symbolic equations (a Mechanism is wrapped in a System).
    functions : iterable of str or str
        Names of the Functions to build (see :data:`casmbd.system.SIGNATURES`, plus
        ``"outputs"``) or the name of an analysis in :data:`NEEDS`.
    mode : {"auto", "compiled", "vm"}
        Compile to C (with on-disk cache), or use CasADi's virtual machine.
    extra : iterable of casadi.Function
        Further Functions compiled into the same library (e.g. a dynamics formulation).
    """

    def __init__(self, system, functions: Iterable[str] | str = "kinematics",
                 mode: str = "auto", extra: Iterable[ca.Function] = ()):
        t0 = time.perf_counter()
        self.system = system if isinstance(system, System) else System(system)
        names = NEEDS.get(functions, (functions,)) if isinstance(functions, str) else functions
        names = list(dict.fromkeys(names))
        symbolic = [self.system.function(n) for n in names] + list(extra)
        t1 = time.perf_counter()
        self.functions, self.report = compile_functions(
            symbolic, name=_c_name(self.system.mechanism.name), mode=mode)
        t2 = time.perf_counter()
        self.symbolic_seconds = t1 - t0
        self.build_seconds = t2 - t0
        self.p = self.system.parameter_values.copy()
        self.nq, self.nc = self.system.nq, self.system.nc
        self._patterns = {n: f.sparsity_out(0) for n, f in self.functions.items()}
        self._buffers: dict = {}

    # ------------------------------------------------------------------ bookkeeping
    @property
    def report_dict(self) -> dict:
        """Build statistics for result files and JSON output."""
        r: BuildReport = self.report
        return {"build_seconds": self.build_seconds, "symbolic_seconds": self.symbolic_seconds,
                "codegen_seconds": r.codegen_seconds, "compile_seconds": r.compile_seconds,
                "load_seconds": r.load_seconds, "compiled": r.compiled,
                "cache_hit": r.cache_hit, "mode": r.mode}

    def function(self, name: str) -> ca.Function:
        """The (compiled) Function ``name``; raise if it was not built for this model."""
        try:
            return self.functions[name]
        except KeyError:
            raise ModelError(f"function '{name}' was not built for this analysis (built: "
                             f"{', '.join(self.functions)})") from None

    def set_parameters(self, **values: float) -> None:
        """Change parameter values by name."""
        names = list(self.system.mechanism.parameters)
        for key, val in values.items():
            if key not in names:
                raise ModelError(f"unknown parameter '{key}' (known: {', '.join(names)})")
            self.p[names.index(key)] = float(val)

    def _eval(self, name: str, *args) -> np.ndarray:
        """Non-zeros of output 0 of ``name``, evaluated through a preallocated buffer.

        ``Function.buffer()`` binds numpy arrays to the inputs and outputs, which avoids the
        conversion of every argument to a CasADi matrix (50–150 µs a call from Python
        against 0.1–3 µs for the compiled code itself; docs/performance.md).
        """
        entry = self._buffers.get(name)
        if entry is None:
            f = self.function(name)
            buf, trigger = f.buffer()
            ins = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
            outs = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
            for i, arr in enumerate(ins):
                buf.set_arg(i, memoryview(arr))
            for i, arr in enumerate(outs):
                buf.set_res(i, memoryview(arr))
            sparsity = f.sparsity_out(0)
            pattern = (np.asarray(sparsity.row(), dtype=np.int32),
                       np.asarray(sparsity.colind(), dtype=np.int32), sparsity.shape,
                       sparsity.is_dense())
            entry = (buf, trigger, ins, outs, pattern)
            self._buffers[name] = entry
        buf, trigger, ins, outs, _ = entry
        for arr, val in zip(ins, args):
            arr[:] = np.ravel(val) if np.ndim(val) else val
        trigger()
        return outs[0].copy()

    def _vector(self, name: str, *args) -> np.ndarray:
        nz = self._eval(name, *args)
        rows, _, shape, dense = self._buffers[name][4]
        if dense:
            return nz
        out = np.zeros(shape[0] * shape[1])
        out[rows] = nz
        return out

    def _sparse(self, name: str, *args) -> sp.csc_matrix:
        nz = self._eval(name, *args)
        rows, colind, shape, _ = self._buffers[name][4]
        return sp.csc_matrix((nz, rows, colind), shape=shape)

    # ------------------------------------------------------------------ equations
    def constraints(self, q, t: float) -> np.ndarray:
        """C(q, t)."""
        return self._vector("constraints", q, t, self.p)

    def constraint_jacobian(self, q, t: float) -> sp.csc_matrix:
        """C_q(q, t) as a sparse matrix."""
        return self._sparse("constraint_jacobian", q, t, self.p)

    def constraint_time_derivative(self, q, t: float) -> np.ndarray:
        """C_t(q, t)."""
        return self._vector("constraint_time_derivative", q, t, self.p)

    def acceleration_rhs(self, q, v, t: float) -> np.ndarray:
        """γ(q, v, t) with C_q q̈ = γ."""
        return self._vector("acceleration_rhs", q, v, t, self.p)

    def mass_matrix(self, q) -> sp.csc_matrix:
        """M(q) as a sparse matrix."""
        return self._sparse("mass_matrix", q, self.p)

    def applied_forces(self, q, v, t: float, u=None) -> np.ndarray:
        """Q_e(q, v, t, u)."""
        u = np.zeros(len(self.system.mechanism.actuators)) if u is None else u
        return self._vector("applied_forces", q, v, t, u, self.p)

    def input_matrix(self, q, v, t: float, u=None) -> sp.csc_matrix:
        """B = ∂Q_e/∂u (n_q × n_u)."""
        u = np.zeros(len(self.system.mechanism.actuators)) if u is None else u
        return self._sparse("input_matrix", q, v, t, u, self.p)

    def kinetic_energy(self, q, v) -> float:
        """T = ½ vᵀ M v."""
        return float(self._vector("kinetic_energy", q, v, self.p)[0])

    def potential_energy(self, q, t: float) -> float:
        """V(q, t) of gravity and springs."""
        return float(self._vector("potential_energy", q, t, self.p)[0])

    def quadratic_velocity_forces(self, q, v) -> np.ndarray:
        """Q_v(q, v)."""
        return self._vector("quadratic_velocity_forces", q, v, self.p)

    def outputs(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, t: np.ndarray) -> dict:
        """Body, marker and joint outputs at many time points in one mapped call.

        ``q``, ``v``, ``a`` have shape (n_t, n_q); every output has time as first axis.
        """
        f = self.function("outputs")
        n = len(t)
        if n == 0:
            raise ModelError("outputs: no time points")
        res = f.map(n)(q.T, v.T, a.T, np.reshape(t, (1, n)), np.tile(self.p[:, None], (1, n)))
        res = res if isinstance(res, (list, tuple)) else [res]
        out = {name: np.asarray(res[i]).T for i, name in enumerate(f.name_out())}
        self._unwrap_angles(out)
        return out

    def _unwrap_angles(self, out: dict) -> None:
        """Make angle outputs continuous in time (``numpy.unwrap`` along the grid, in place).

        A spatial joint angle is an ``atan2`` (and a planar angle in natural coordinates
        too), which jumps by 2π where it passes ±π; the result's joint angles (revolute,
        universal, cylindrical ``.angle``) and planar body angles (``angle_positions``) are
        unwrapped so that plots, CSV and JSON are continuous.  They start in (−π, π] and stay
        correct while an angle changes by less than π between outputs.  Planar absolute and
        joint coordinates give exact continuous angles and are left alone.
        """
        system = self.system
        if system.dimension == 2 and system.coordinates != "natural":
            return  # angle coordinates and their differences: continuous already, exact
        joints = system.mechanism.joints
        cols = []
        for k, key in enumerate(system.joint_coordinate_names):
            name, _, coord = key.partition(".")
            names = getattr(joints.get(name), "coordinate_names", ())
            if (coord or (names[0] if names else "")).startswith("angle"):
                cols.append(k)
        if cols and "joint_positions" in out and out["joint_positions"].shape[0] > 1:
            out["joint_positions"][:, cols] = np.unwrap(out["joint_positions"][:, cols], axis=0)
        if "angle_positions" in out and out["angle_positions"].shape[0] > 1:
            out["angle_positions"] = np.unwrap(out["angle_positions"], axis=0)
