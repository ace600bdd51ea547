"""The compiled numeric model: the runnable counterpart of a symbolic :class:`System`.

Like Pinocchio's ``Model``/``Data`` and MuJoCo's ``mjModel``/``mjData``, :class:`NumericModel`
holds what is fixed — the compiled (or virtual-machine) CasADi Functions an analysis asked
for, the sizes, the names of coordinates, equations and elements, and the parameter values
(in one place, :attr:`NumericModel.p`) — and a :class:`~casmbd.compiled.workspace.Workspace`
holds the evaluation buffers.  Matrices come back as ``scipy.sparse`` CSC matrices built from
the fixed sparsity pattern of the generated code.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterable

import casadi as ca
import numpy as np

from casmbd.compiled.codegen import BuildReport, compile_functions
from casmbd.compiled.workspace import Workspace
from casmbd.errors import ModelError
from casmbd.lazy import lazy_module
from casmbd.model.measures import result_names
from casmbd.system.equations import SIGNATURES, Equation, System

sp = lazy_module("scipy.sparse")

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
#: an ODE formulation of a system without constraint equations (the articulated recursion)
#: takes q̈ from its own right-hand side: no Q_e, Q_v or B is compiled for it (built on
#: first use in the virtual machine, see :class:`_Functions`); M stays, for the check that
#: names bodies without inertia
NEEDS["ode_dynamics"] = tuple(n for n in NEEDS["dynamics"] if n not in (
    "applied_forces", "quadratic_velocity_forces", "input_matrix"))


class _Functions(dict):
    """The model's Functions by name; a known equation that was not built for the model is
    built on first use from the model's System, in CasADi's virtual machine (``name in``
    stays False until then, so diagnostics can tell what was compiled)."""

    def __init__(self, functions: dict, model: NumericModel) -> None:
        super().__init__(functions)
        self._model = model

    def __missing__(self, name: str) -> ca.Function:
        from_system = name in ("outputs", "joint_reactions") or name in SIGNATURES
        if not from_system:
            raise KeyError(name)
        function = self._model.system.function(name)
        self[name] = function
        return function


def c_symbol_name(name: str) -> str:
    """The C identifier prefix of a mechanism's generated code: ``casmbd_`` and the first 40
    characters of ``name`` with every character outside [A-Za-z0-9_] replaced by ``_``."""
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
    hot : iterable of str, optional
        The Functions evaluated often (an integrator's right-hand side): only these are
        optimised, the others compiled at ``-O0`` (see
        :func:`~casmbd.compiled.codegen.compile_functions`); default: all optimised.

    Notes
    -----
    What an analysis reads from here, and what it may not:

    * sizes (:attr:`nq`, :attr:`nc`, :attr:`nu`), names (:attr:`coordinate_names`,
      :attr:`constraint_labels`, :attr:`joint_coordinate_names`, :attr:`body_names`,
      :attr:`parameter_names`), :attr:`length_indices`, :attr:`reaction_size`, the initial
      state (:meth:`initial_coordinates`, :meth:`initial_velocities`), the parameter values
      :attr:`p` (the one source of truth: :meth:`set_parameters` or ``model.p[:] = …``; the
      mechanism's ``parameters`` are the defaults the model was built with) and the
      evaluation methods;
    * the :attr:`mechanism` for its description (element names, markers, drivers,
      actuators, initial body poses) — never for parameter values;
    * :attr:`system`, the symbolic equations, only to build *new* CasADi Functions from
      symbolic expressions after a numeric failure (the diagnostics of
      :mod:`casmbd.analysis.instant.checks` and :mod:`casmbd.analysis.instant.culprits`).  Code
      that builds
      Functions as its main job (formulations, statics and linearisation Functions, the OCP
      transcription) takes the :class:`System` explicitly and hands them in as ``extra``.

    Build one with :func:`casmbd.compiled.build.compile_model` (the one compile entry;
    nothing outside :mod:`casmbd.compiled` calls this constructor).  Evaluations go through
    :attr:`data`, a :class:`~casmbd.compiled.workspace.Workspace` made with the model, which
    has the same equation methods; a caller that must not share buffers with others takes
    its own from :meth:`workspace`, and an analysis runs on :meth:`with_data` (this model
    evaluating through that workspace), so that two analyses of one model never write each
    other's buffers.
    """

    def __init__(self, system, functions: Iterable[str] | str = "kinematics",
                 mode: str = "auto", extra: Iterable[ca.Function] = (),
                 hot: Iterable[str] | None = None):
        t0 = time.perf_counter()
        system = system if isinstance(system, System) else System(system)
        #: the symbolic equations; only for diagnostics that build new Functions (see Notes)
        self.system = system
        names = NEEDS.get(functions, (functions,)) if isinstance(functions, str) else functions
        names = list(dict.fromkeys(names))
        symbolic = [system.function(n) for n in names] + list(extra)
        t1 = time.perf_counter()
        functions, self.report = compile_functions(
            symbolic, name=c_symbol_name(system.mechanism.name), mode=mode,
            hot=None if hot is None else set(hot))
        self.functions = _Functions(functions, self)
        t2 = time.perf_counter()
        self.symbolic_seconds = t1 - t0
        self.build_seconds = t2 - t0
        #: the description the model was built from (names, markers, drivers, actuators)
        self.mechanism = system.mechanism
        self.name: str = system.mechanism.name
        self.dimension: int = system.dimension
        #: coordinate choice: "absolute", "natural" or "joint"
        self.coordinates: str = system.coordinates
        #: why these coordinates ("given" or the automatic choice's reason)
        self.coordinate_reason: str = getattr(system, "coordinate_reason", "given")
        self.nq, self.nc = system.nq, system.nc
        self.nu: int = len(system.mechanism.actuators)
        self.parameter_names: list[str] = list(system.mechanism.parameters)
        #: parameter values, the runtime input p of every Function (the one source of truth)
        self.p = system.parameter_values.copy()
        self.coordinate_names: list[str] = list(system.coordinate_names)
        self.constraint_labels: list[Equation] = list(system.constraint_labels)
        self.joint_coordinate_names: list[str] = list(system.joint_coordinate_names)
        self.body_names: list[str] = list(system.body_names)
        #: layout of q: each body's coordinate description and the index of its first entry
        self.descriptions: dict = dict(system.descriptions)
        self.coordinate_index: dict[str, int] = dict(system.ctx.index)
        self.length_indices: np.ndarray = system.length_indices
        self.reaction_size: int = system.reaction_size
        #: rows of C of each joint and of each driver
        self.joint_rows: dict[str, list[int]] = {k: list(v) for k, v in
                                                 system.joint_rows.items()}
        self.driver_rows: dict[str, int] = dict(system.driver_rows)
        #: rows of C written at the velocity level (non-holonomic; System.velocity_rows)
        self.velocity_rows: list[int] = list(system.velocity_rows)
        self._q0 = system.initial_coordinates()
        self._v0 = system.initial_velocities() if system.local else None
        self._v0_at: tuple[list[float], np.ndarray] | None = None
        #: evaluation buffers of the model's own methods (see :meth:`workspace`)
        self.data = Workspace(self)

    # ------------------------------------------------------------------ cached builds
    #: attributes that a model loaded by :meth:`from_record` takes from its System, built on
    #: first use (only diagnostics and statics read them)
    _LAZY = ("system", "descriptions", "coordinate_index")

    def record(self) -> dict:
        """What :meth:`from_record` needs to stand in for this model without a System
        (JSON-ready; see :mod:`casmbd.compiled.modelkey`)."""
        v0 = self._v0 if self._v0 is not None else self.initial_velocities()
        return {"name": self.name, "dimension": self.dimension, "coordinates": self.coordinates,
                "nq": self.nq, "nc": self.nc, "nu": self.nu,
                "parameter_names": self.parameter_names, "p": self.p.tolist(),
                "coordinate_names": self.coordinate_names,
                "constraint_labels": [[e.kind, e.element, e.label]
                                      for e in self.constraint_labels],
                "joint_coordinate_names": self.joint_coordinate_names,
                "body_names": self.body_names, "length_indices": self.length_indices.tolist(),
                "reaction_size": self.reaction_size, "joint_rows": self.joint_rows,
                "driver_rows": self.driver_rows, "velocity_rows": self.velocity_rows,
                "q0": self._q0.tolist(),
                "v0": v0.tolist(), "v0_local": self._v0 is not None,
                "coordinate_reason": self.coordinate_reason}

    @classmethod
    def from_record(cls, mechanism, functions: dict[str, ca.Function], report: BuildReport,
                    record: dict, seconds: float = 0.0) -> NumericModel:
        """A model of ``mechanism`` from loaded ``functions`` and the :meth:`record` of the
        build that made them, without building a System (built on first use of
        :attr:`system`, :attr:`descriptions` or :attr:`coordinate_index`)."""
        self = cls.__new__(cls)
        self.functions, self.report = _Functions(functions, self), report
        self.symbolic_seconds, self.build_seconds = 0.0, seconds
        self.mechanism = mechanism
        self.name, self.dimension = record["name"], int(record["dimension"])
        self.coordinates = record["coordinates"]
        self.coordinate_reason = record["coordinate_reason"]
        self.nq, self.nc, self.nu = int(record["nq"]), int(record["nc"]), int(record["nu"])
        self.parameter_names = list(record["parameter_names"])
        self.p = np.array(record["p"], dtype=float).reshape(-1)
        self.coordinate_names = list(record["coordinate_names"])
        self.constraint_labels = [Equation(*lab) for lab in record["constraint_labels"]]
        self.joint_coordinate_names = list(record["joint_coordinate_names"])
        self.body_names = list(record["body_names"])
        self.length_indices = np.array(record["length_indices"], dtype=int)
        self.reaction_size = int(record["reaction_size"])
        self.joint_rows = {k: list(v) for k, v in record["joint_rows"].items()}
        self.driver_rows = dict(record["driver_rows"])
        self.velocity_rows = [int(i) for i in record.get("velocity_rows", ())]
        self._q0 = np.array(record["q0"], dtype=float).reshape(-1)
        v0 = np.array(record["v0"], dtype=float).reshape(-1)
        self._v0 = v0 if record["v0_local"] else None
        self._v0_at = None if record["v0_local"] else (list(record["p"]), v0)
        self.data = Workspace(self)
        return self

    def __getattr__(self, name: str):
        # only reached when the attribute is missing: a model from a record builds its System
        # (a model with its own data (:meth:`with_data`) takes it from the model it views)
        origin = self.__dict__.get("_origin")
        if origin is not None and name in NumericModel._LAZY:
            return getattr(origin, name)
        if name in NumericModel._LAZY and "mechanism" in self.__dict__:
            system = self.__dict__.get("system")
            if system is None:  # the mechanism's own choice, then checked
                system = System(self.mechanism)
                if system.coordinates != self.coordinates:
                    system = System(self.mechanism, self.coordinates)
                self.__dict__["system"] = system
            self.descriptions = dict(system.descriptions)
            self.coordinate_index = dict(system.ctx.index)
            return self.__dict__[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

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
        """The (compiled) Function ``name``; a known equation that was not compiled for this
        model is built in the virtual machine on first use; raise for any other name."""
        try:
            return self.functions[name]  # a known equation not built: virtual machine
        except KeyError:
            raise ModelError(f"function '{name}' was not built for this analysis (built: "
                             f"{', '.join(self.functions)})") from None

    def workspace(self) -> Workspace:
        """A new :class:`~casmbd.compiled.workspace.Workspace` (buffers) for this model."""
        return Workspace(self.__dict__.get("_origin", self))

    def with_data(self, data: Workspace | None = None) -> NumericModel:
        """This model evaluating through ``data`` (default: a new :meth:`workspace`).

        A shallow copy that shares every fixed part — the Functions, sizes, names, the
        mechanism and the parameter array :attr:`p` itself (a change of a parameter applies to
        both) — and has ``data`` as its :attr:`data`.  An analysis takes one at its entry
        (``model = model.with_data(data)``) and hands it to the instant solvers it calls
        (assembly, KKT, projections), so that every evaluation of the run writes its own
        buffers: two analyses of one model never share them (Pinocchio's ``aba(model, data,
        …)`` with the data carried by the model the solvers receive).

        Raises
        ------
        ModelError
            When ``data`` is the workspace of another model.
        """
        origin = self.__dict__.get("_origin", self)
        if data is None:
            data = Workspace(origin)
        elif data.model is not origin:
            raise ModelError(f"with_data: the workspace belongs to another model than "
                             f"'{self.name}' (take one from model.workspace())")
        view = object.__new__(type(self))
        view.__dict__.update(self.__dict__)
        view._origin, view.data = origin, data
        return view

    @property
    def holonomic_rows(self) -> list[int]:
        """Rows of C that are position constraints (all but :attr:`velocity_rows`)."""
        vel = set(self.velocity_rows)
        return [i for i in range(self.nc) if i not in vel]

    @property
    def parameters(self) -> dict[str, float]:
        """Current parameter values by name (from :attr:`p`)."""
        return {name: float(self.p[k]) for k, name in enumerate(self.parameter_names)}

    def set_parameters(self, **values: float) -> None:
        """Change parameter values by name."""
        names = self.parameter_names
        for key, val in values.items():
            if key not in names:
                raise ModelError(f"unknown parameter '{key}' (known: {', '.join(names)})")
            self.p[names.index(key)] = float(val)

    def initial_coordinates(self) -> np.ndarray:
        """Stacked q from the bodies' initial poses (approximate, before assembly)."""
        return self._q0.copy()

    def initial_velocities(self) -> np.ndarray:
        """Stacked q̇ from the bodies' initial velocities, at the current parameter values
        (joint coordinates map body velocities through J(q₀, p); see
        :meth:`System.initial_velocities <casmbd.system.equations.System.initial_velocities>`)."""
        if self._v0 is not None:
            return self._v0.copy()
        if self._v0_at is not None and self._v0_at[0] == self.p.tolist():
            return self._v0_at[1].copy()
        if all(not np.any(getattr(body, key, 0.0)) for body in self.mechanism.bodies.values()
               for key in ("velocity", "angular_velocity")):
            # bodies at rest: q̇ = 0 minimises the kinetic energy of the difference (and the
            # least squares), without the symbolic Jacobian of every twist (O(N²) for a tree)
            return np.zeros(self.nq)
        return self.system.initial_velocities(self.p)

    def vector(self, name: str, *args) -> np.ndarray:
        """Output 0 of Function ``name`` (built with this model) as a dense flat array."""
        return self.data.vector(name, *args)

    def sparse(self, name: str, *args) -> sp.csc_matrix:
        """Output 0 of Function ``name`` (built with this model) as a sparse matrix."""
        return self.data.sparse(name, *args)

    _vector = vector  # the names analyses used before the workspace split
    _sparse = sparse

    # ------------------------------------------------------------------ equations
    # evaluated through the model's own workspace :attr:`data`; an analysis takes its own
    # (:meth:`workspace`) and calls the same-named methods of that
    def constraints(self, q, t: float) -> np.ndarray:
        """C(q, t)."""
        return self.data.constraints(q, t)

    def constraint_jacobian(self, q, t: float) -> sp.csc_matrix:
        """C_q(q, t) as a sparse matrix."""
        return self.data.constraint_jacobian(q, t)

    def constraint_time_derivative(self, q, t: float) -> np.ndarray:
        """C_t(q, t)."""
        return self.data.constraint_time_derivative(q, t)

    def acceleration_rhs(self, q, v, t: float) -> np.ndarray:
        """γ(q, v, t) with C_q q̈ = γ."""
        return self.data.acceleration_rhs(q, v, t)

    def mass_matrix(self, q) -> sp.csc_matrix:
        """M(q) as a sparse matrix."""
        return self.data.mass_matrix(q)

    def applied_forces(self, q, v, t: float, u=None) -> np.ndarray:
        """Q_e(q, v, t, u)."""
        return self.data.applied_forces(q, v, t, u)

    def input_matrix(self, q, v, t: float, u=None) -> sp.csc_matrix:
        """B = ∂Q_e/∂u (n_q × n_u)."""
        return self.data.input_matrix(q, v, t, u)

    def kinetic_energy(self, q, v) -> float:
        """T = ½ vᵀ M v."""
        return self.data.kinetic_energy(q, v)

    def potential_energy(self, q, t: float) -> float:
        """V(q, t) of gravity and springs."""
        return self.data.potential_energy(q, t)

    def quadratic_velocity_forces(self, q, v) -> np.ndarray:
        """Q_v(q, v)."""
        return self.data.quadratic_velocity_forces(q, v)

    def outputs(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, t: np.ndarray,
                mapped: ca.Function | None = None) -> dict:
        """Body, marker and joint outputs at many time points in one mapped call.

        ``q``, ``v``, ``a`` have shape (n_t, n_q); every output has time as first axis.
        ``mapped``: the outputs Function already mapped over the n_t points (kept by the
        caller from run to run), else mapped here.
        """
        f = self.function("outputs")
        n = len(t)
        if n == 0:
            raise ModelError("outputs: no time points")
        mapped = f.map(n) if mapped is None else mapped
        res = mapped(q.T, v.T, a.T, np.reshape(t, (1, n)), np.tile(self.p[:, None], (1, n)))
        res = res if isinstance(res, (list, tuple)) else [res]
        out = {name: np.asarray(res[i]).T for i, name in enumerate(f.name_out())}
        self._unwrap_angles(out)
        return out

    def _unwrap_angles(self, out: dict) -> None:
        """Make angle outputs continuous in time (``numpy.unwrap`` along the grid, in place).

        A spatial joint angle is an ``atan2`` (and a planar angle in natural coordinates
        too), which jumps by 2π where it passes ±π; the result's joint angles (revolute,
        universal, cylindrical ``.angle``) and planar body angles (``angle_positions``) are
        unwrapped, and planar marker angles (``marker_angles``) too, and every request and
        force report in rad (a rotational spring-damper's ``angle`` is its joint's angle), so
        that plots, CSV and JSON are continuous.  They start in (−π, π] and stay
        correct while an angle changes by less than π between outputs.  Planar absolute and
        joint coordinates give exact continuous angles and are left alone.
        """
        if self.dimension == 2 and self.coordinates != "natural":
            return  # angle coordinates and their differences: continuous already, exact
        joints = self.mechanism.joints
        cols = []
        for k, key in enumerate(self.joint_coordinate_names):
            name, _, coord = key.partition(".")
            names = getattr(joints.get(name), "coordinate_names", ())
            if (coord or (names[0] if names else "")).startswith("angle"):
                cols.append(k)
        if cols and "joint_positions" in out and out["joint_positions"].shape[0] > 1:
            out["joint_positions"][:, cols] = np.unwrap(out["joint_positions"][:, cols], axis=0)
        for key in ("angle_positions", "marker_angles"):  # planar body and marker angles
            if key in out and out[key].shape[0] > 1:
                out[key] = np.unwrap(out[key], axis=0)
        names = result_names(self.mechanism)  # requests and force reports in rad alike
        for key, units in (("outputs", "output_units"), ("force_outputs", "force_output_units")):
            cols = [k for k, unit in enumerate(names.get(units, [])) if unit == "rad"]
            if cols and key in out and out[key].shape[0] > 1 and out[key].ndim == 2:
                out[key][:, cols] = np.unwrap(out[key][:, cols], axis=0)
