"""Forward dynamics: ``simulate`` and the reusable :class:`Simulator`.

The run is: build the formulation (:mod:`casmbd.analysis.formulations`) and the post-processing
Functions, compiled together into one cached library; find a consistent start (assemble q,
project v mass-orthogonally, solve the KKT system for q̈ and λ — reported in ``stats``);
integrate on the output grid in one call of the chosen integrator; then, at every output time,
q̈ and λ from the sparse KKT system, joint reactions (seed 000, eqs. 6.145–6.151), driver
efforts (−λ of the driver row: the generalized force the driver exerts along its coordinate),
kinetic and potential energy, and the position and velocity constraint violations.
"""

from __future__ import annotations

import re
import time
from collections.abc import Mapping

import casadi as ca
import numpy as np

from casmbd import progress
from casmbd.analysis.dynamics import numeric_run
from casmbd.analysis.dynamics.build_cache import INPUTS_FUNCTION, CachedBuild, input_expression
from casmbd.analysis.dynamics.postprocess import PostProcessing, truncated
from casmbd.analysis.dynamics.stepping import Stepping
from casmbd.analysis.events.events import MAX_EVENTS, compliant_events, has_events, simulate_events
from casmbd.analysis.formulations import (
    DEFAULT_FORMULATION,
    FORMULATIONS,
    FormulationKind,
    default_formulation,
    formulation_kind,
    post_processing,
)
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.checks import (
    check_consistent_start,
    check_mass_invertible,
    check_mass_matrix,
    check_start,
    diagnose_failure,
    tree_mass_positive,
)
from casmbd.analysis.instant.independent import find_redundant
from casmbd.analysis.instant.kkt import accelerations_and_multipliers, consistent_state
from casmbd.analysis.integrators import kinds as integ
from casmbd.analysis.integrators import sundials as sun
from casmbd.analysis.integrators.option_ranges import check_integrator_options
from casmbd.analysis.integrators.stiffness_culprit import (
    check_plausible_elements,
    diagnose_stiffness,
)
from casmbd.compiled.buffered import BufferedFunction
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NEEDS
from casmbd.errors import AnalysisError, CasmbdError, IntegratorError, UnknownMethodError
from casmbd.interrupts import reraise_interrupt
from casmbd.limits import check_steps
from casmbd.model.contacts import slides
from casmbd.model.needs import ALL_NEEDS, EVENT_NEEDS, Handling, check
from casmbd.results import Result
from casmbd.system.equations import System
from casmbd.system.subset import ConstraintSubset

# The formulations (name, state layout, default integrator, redundancy policy, initial
# algebraic state) are objects in casmbd.analysis.formulations.FORMULATIONS and the integrators
# in casmbd.analysis.integrators.kinds.INTEGRATORS: nothing here switches on their names.
__all__ = ["DEFAULT_FORMULATION", "Simulator", "Simulators", "default_formulation",
           "plan_redundancy", "simulate"]


#: an ODE whose largest decay rate times the time span exceeds this is integrated with BDF
#: (CVODES) instead of Adams when no integrator is named
STIFF_STEPS = 2.0e4
#: ... and only when the decay rate exceeds this [1/s]: slower rates are mechanical modes or
#: the constraint stabilisation (Baumgarte 20 1/s), which Adams follows accurately even over
#: long runs (a 2000 s pendulum is 800x less accurate on BDF)
STIFF_RATE = 1.0e3
#: above this many states the stiffness check is skipped
STIFF_CHECK_MAX = 400

REDUNDANCY_OPTIONS = ("auto", "remove", "minimum_norm")
#: above this many entries of C_q the dense rank check at build time is skipped
RANK_CHECK_MAX_ENTRIES = 2_000_000


def plan_redundancy(system: System, formulation: str, option: str = "auto") -> dict:
    """Find redundant constraint equations at the assembled initial pose and decide their fate.

    The rank of C_q comes from the SVD of the equilibrated matrix and the dependent rows from a
    Gram–Schmidt sweep in declaration order (:func:`casmbd.analysis.instant.redundancy.rank_report`;
    seed 000, Gaussian elimination with full pivoting; seed 002, redundant constraint
    equations).  Options:

    ``"remove"``
        drop the dependent rows from the equations the integrator sees
        (:class:`~casmbd.system.subset.ConstraintSubset`); every formulation.
    ``"minimum_norm"``
        keep every equation; the augmented Lagrangian's multipliers stay in the range of C_q,
        i.e. they are the minimum-norm multipliers (seed 002's orthogonalisation), and
        ``partitioning``/``nullspace`` choose independent coordinates by rank.  Other
        formulations need a regular KKT matrix and are refused.
    ``"auto"``
        ``minimum_norm`` for the formulations that accept it, ``remove`` for the others.

    Returns
    -------
    dict
        ``redundant_equations`` (labels), ``redundancy`` (what was done), ``kept_rows`` (row
        indices for a removal, else None), and ``constraint_rank``.
    """
    if option not in REDUNDANCY_OPTIONS:
        raise AnalysisError(f"redundancy must be one of {', '.join(REDUNDANCY_OPTIONS)}, "
                            f"got {option!r}")
    plan: dict = {"redundant_equations": [], "redundancy": "none", "kept_rows": None}
    if system.nc == 0:
        return plan
    if system.nc * system.nq > RANK_CHECK_MAX_ENTRIES:
        plan["redundancy"] = "not checked (C_q too large for the dense rank check)"
        return plan
    probe = compile_model(system, "info", mode="vm")
    q = system.initial_coordinates()
    try:
        q = assemble(probe, q, 0.0).q
    except CasmbdError:
        pass  # the run's own assembly reports the failure with its context
    rows = find_redundant(probe, q, 0.0)  # the rows every analysis removes (independent.py)
    plan["constraint_rank"] = rows.constraint_rank
    if not rows.removes:
        return plan
    plan["redundant_equations"] = list(rows.redundant_equations)
    kind = formulation if isinstance(formulation, FormulationKind) else \
        formulation_kind(formulation)
    if option == "minimum_norm" and not kind.keeps_redundant:
        keepers = [n for n, k in FORMULATIONS.items() if k.keeps_redundant]
        raise AnalysisError(
            f"formulation '{kind.name}' needs a regular KKT matrix and cannot keep the "
            f"redundant equations {', '.join(plan['redundant_equations'])}; use "
            f"redundancy='remove' or one of {', '.join(keepers)}")
    if option == "remove" or (option == "auto" and not kind.keeps_redundant):
        if not kind.removes_redundant:
            plan["redundancy"] = kind.kept_redundancy
            return plan
        plan["kept_rows"] = list(rows.kept_rows)
        plan["redundancy"] = "removed"
    else:
        plan["redundancy"] = kind.kept_redundancy
    return plan




_FLAG = re.compile(r'returned "([A-Z_]+)"')
_AT_T = re.compile(r"t = ([-+0-9.eE]+)")


class Simulator(Stepping, CachedBuild):
    """A mechanism compiled for one formulation, ready to integrate many times.

    Parameters
    ----------
    mechanism : Mechanism or System
    formulation : str
        A name registered in :data:`casmbd.analysis.formulations.FORMULATIONS` (default:
        :func:`~casmbd.analysis.formulations.default_formulation`); another name raises
        :class:`~casmbd.errors.UnknownMethodError` listing the registered ones.
    inputs : mapping, optional
        Actuator name -> value (number, expression string of ``t`` and parameters, callable).
    mode : str
        Compilation mode ("auto", "compiled", "vm").
    formulation_options : mapping, optional
        e.g. ``{"alpha": 5.0, "beta": 10.0}`` (Baumgarte), ``{"penalty": 1e8}``.
    """

    def __init__(self, mechanism, formulation: str | None = None, inputs: Mapping | None = None,
                 mode: str = "auto", formulation_options: Mapping | None = None,
                 redundancy: str = "auto"):
        t0 = time.perf_counter()
        self._mode, self._solvers = mode, {}
        # a model record of the same description: no System, no code (dynamics.build_cache)
        if self._from_cache(mechanism, formulation, inputs, mode, formulation_options,
                            redundancy):
            #: outputs and failure diagnosis (analysis.postprocess)
            self.post = PostProcessing(self.model, self.redundancy, self.ufun)
            self.build_seconds = time.perf_counter() - t0
            return
        system = mechanism if isinstance(mechanism, System) else System(mechanism)
        self.formulation_name = formulation or default_formulation(system)
        #: the registered formulation (UnknownMethodError listing the choices otherwise)
        self.kind = formulation_kind(self.formulation_name)
        #: why this formulation: "given" or the default rule (articulated for trees)
        self.formulation_reason = "given" if formulation else \
            self.kind.default_reason(system)
        self.redundancy = plan_redundancy(system, self.kind, redundancy)
        u_expr = input_expression(system, inputs)
        self.ufun = ca.Function(INPUTS_FUNCTION, [system.t, system.p], [u_expr],
                                ["t", "p"], ["u"])
        keep = self.redundancy.get("kept_rows")
        self._dyn_system = ConstraintSubset(system, keep) if keep is not None else system
        self.formulation = self.kind.build(self._dyn_system, inputs=u_expr,
                                           **dict(formulation_options or {}))
        # an ODE of an unconstrained system gives q̈ to the post-processing (no M solve)
        ode = self.kind.ode_right_hand_side(self.formulation.function)
        # the default integrator's own compiled stepping (DOPRI5's block) goes into the
        # model's library, in one translation unit with the dynamics it calls
        stepping = integ.INTEGRATORS.get(self.kind.default_integrator)
        steps = stepping.model_functions(ode) if ode is not None and stepping is not None \
            and mode != "vm" and stepping.integrates("ode") else []
        hot = [f.name() for f in [*self.formulation.functions, *steps]]
        # q̈ of an unconstrained ODE from its own right-hand side: no M, Q_e, Q_v compiled
        needs = "ode_dynamics" if ode is not None and system.nc == 0 else "dynamics"
        # the formulation's stand-ins for the System's own (a long chain's folded outputs)
        own = {f.name(): f for f in self.kind.model_functions(
            system, **dict(formulation_options or {}))}
        needs = [n for n in NEEDS[needs] if n not in own]
        energies = (own["kinetic_energy"], own["potential_energy"]) \
            if "kinetic_energy" in own else None
        self.model = compile_model(system, needs, mode=mode,
                                   extra=[*self.formulation.functions, *steps, *own.values(),
                                          post_processing(system, u_expr, ode, energies),
                                          self.ufun],
                                   hot=self.kind.hot_functions(hot))  # per step: -O2
        self.system = system
        self.dyn = self.model.function(self.formulation.function.name())
        self.ufun = self.model.function(INPUTS_FUNCTION)
        #: outputs and failure diagnosis (analysis.postprocess)
        self.post = PostProcessing(self.model, self.redundancy, self.ufun)
        self._remember()  # the model record for the next run (analysis.build_cache)
        self.build_seconds = time.perf_counter() - t0

    def _solver(self, key, factory):
        """Integrator objects are built once per (method, grid, tolerances) and reused."""
        if key not in self._solvers:
            t0 = time.perf_counter()
            self._solvers[key] = factory()
            self._setup_seconds += time.perf_counter() - t0
        return self._solvers[key]

    # ------------------------------------------------------------------ helpers
    def inputs_at(self, t: float) -> np.ndarray:
        """Actuator inputs u(t)."""
        return np.asarray(self.ufun(t, self.model.p)).reshape(-1)

    def _z0(self, q: np.ndarray, a: np.ndarray, lam: np.ndarray) -> np.ndarray:
        return self.kind.algebraic_state(lambda: (a, lam),
                                         lambda lam: self._kept_multipliers(q, lam))

    def algebraic_state_at(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The formulation's algebraic state at (q, v, t) (q̈ and λ from the KKT system)."""
        return self.kind.algebraic_state(
            lambda: accelerations_and_multipliers(self.model, q, v, t, self.inputs_at(t)),
            lambda lam: self._kept_multipliers(q, lam))

    def _kept_multipliers(self, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
        keep = self.redundancy.get("kept_rows")
        if keep is not None:  # multipliers of the kept rows carrying the same C_qᵀ λ
            cq = self.model.constraint_jacobian(q, 0.0).toarray()
            lam = np.linalg.lstsq(cq[keep].T, cq.T @ lam, rcond=None)[0]
        return lam

    def _ode_accelerations(self, t: float):
        """q̈(q, v) at ``t`` from the ODE right-hand side of an unconstrained system whose
        model has no compiled forces (``NEEDS["ode_dynamics"]``), else None."""
        if self.kind.ode_right_hand_side(self.dyn) is None or self.model.nc or \
                "quadratic_velocity_forces" in self.model.functions:
            return None
        nq, p, rhs = self.model.nq, self.model.p, self._rhs_buffer()

        def accelerations(q, v):
            x = np.concatenate([q, v])
            return np.asarray(rhs(t, x, np.zeros(0), p, np.zeros(0)),
                              dtype=float).ravel()[nq:]
        return accelerations

    def _rhs_buffer(self):
        """The ODE right-hand side called through its bound buffers
        (:class:`~casmbd.compiled.buffered.BufferedFunction`: no conversion of every
        argument to a CasADi matrix, tens of µs a call), made once; its output 0."""
        rhs = self.__dict__.get("_rhs_buffered")
        if rhs is None:
            rhs = self._rhs_buffered = _buffered_call(self.dyn)
        return rhs

    def _integrator_name(self, integrator: str | None) -> str:
        name = integrator or self.kind.default_integrator
        if name not in integ.INTEGRATORS:
            raise UnknownMethodError("integrator", name, integ.INTEGRATORS)
        allowed = [n for n, k in integ.INTEGRATORS.items()
                   if k.integrates(self.formulation.kind)]
        if name not in allowed:
            raise AnalysisError(f"integrator '{name}' cannot integrate the "
                                f"{self.formulation.kind.upper()} formulation "
                                f"'{self.formulation_name}' (use one of {', '.join(allowed)})")
        return name

    # ------------------------------------------------------------------ run
    def run(self, t_end: float, steps: int, t_start: float = 0.0,
            integrator: str | None = None, rtol: float = 1e-8, atol: float | None = None,
            q0=None, v0=None, projection: bool = False, step: float | None = None,
            max_steps: int | None = None) -> Result:
        """Integrate from ``t_start`` to ``t_end`` with ``steps`` + 1 output times.

        Raises
        ------
        IntegratorError
            With the time, the solver's flag and message, and the results up to that time.
        """
        if not (isinstance(steps, (int, np.integer)) and steps >= 1):
            raise AnalysisError(f"steps must be an integer >= 1, got {steps!r}")
        if not (np.isfinite(t_end) and np.isfinite(t_start) and t_end > t_start):
            raise AnalysisError(f"t_end must be finite and > t_start = {t_start}, got {t_end!r}")
        for key, val in (("rtol", rtol), ("atol", atol if atol is not None else rtol)):
            if not (np.isfinite(val) and val > 0):
                raise AnalysisError(f"{key} must be a finite number > 0, got {val!r}")
        atol = rtol if atol is None else atol
        name = self._integrator_name(integrator)
        if max_steps is None:
            max_steps = self.kind.max_steps
        model = self.model
        # LimitError before the grid is allocated: the estimate of simulate() (one message)
        check_steps("simulation", int(steps), model.mechanism)
        grid = np.linspace(t_start, t_end, int(steps) + 1)
        q0 = model.initial_coordinates() if q0 is None else np.asarray(q0, float)
        v0 = model.initial_velocities() if v0 is None else np.asarray(v0, float)
        u0 = self.inputs_at(t_start)
        ode_acc = self._ode_accelerations(t_start)
        # a long chain's articulated-body pivots: M > 0 without M (O(N), not O(N²))
        healthy = tree_mass_positive(model, q0)
        evaluated = check_start(model, q0, v0, t_start, u0, what="simulation",  # NaN culprit
                                every=ode_acc is not None
                                and not np.all(np.isfinite(ode_acc(q0, v0))),
                                skip=("mass_matrix",) if healthy else ())
        if not healthy:  # names the bodies without mass where M is singular (at the
            # assembled start; M of check_start reused when the assembly did not move q0)
            q_asm = assemble(model, q0, t_start).q
            check_mass_matrix(model, q_asm, t_start,
                              mass=evaluated.get("mass_matrix") if np.array_equal(q_asm, q0)
                              else None)
        if self.kind.inverts_mass and not healthy:  # λ from C_q M⁻¹ C_qᵀ: M itself regular
            check_mass_invertible(model, q0, t_start, self.formulation_name)
        start = consistent_state(model, q0, v0, t_start, u0, accelerations=ode_acc)
        check_consistent_start(model, start.q, start.v, start.a, t_start)
        x0 = np.concatenate([start.q, start.v])
        z0 = self._z0(start.q, start.a, start.lam)
        nq = model.nq
        choice = None
        stiff = integ.INTEGRATORS[name].stiff_alternative
        if integrator is None and stiff is not None:
            rho = self.stiffness(x0, t_start)
            if rho is not None and rho > STIFF_RATE and rho * (t_end - t_start) > STIFF_STEPS:
                name = stiff
                choice = (f"{stiff} ({integ.INTEGRATORS[stiff].label}): stiff, largest decay "
                          f"rate {rho:.3g} 1/s × {t_end - t_start:g} s > {STIFF_STEPS:g}")
        stats: dict = {"coordinates": model.coordinates,
                       "coordinate_choice": model.coordinates,
                       "coordinate_reason": model.coordinate_reason,
                       "formulation": self.formulation_name,
                       "formulation_choice": self.formulation_reason, "integrator": name,
                       "integrator_choice": choice or ("default" if integrator is None
                                                       else "given"),
                       **{k: v for k, v in self.redundancy.items() if k != "kept_rows"},
                       "rtol": rtol, "atol": atol, "projection": projection,
                       "start_position_change": start.position_change,
                       "start_velocity_change": start.velocity_change}
        self._setup_seconds = 0.0
        t0, cpu0 = time.perf_counter(), time.thread_time()  # thread_time: no waiting counted
        failure = None
        # compiled stepping writes no messages: no capture (~40 µs) unless a projection runs
        captured = sun.CapturedOutput(integ.INTEGRATORS[name].writes_messages or projection)
        try:
            with captured:
                xs, solver_stats = self._integrate(name, grid, x0, z0, rtol, atol, projection,
                                                   step, max_steps)
        except IntegratorError as exc:
            reraise_interrupt(exc)
            if exc.partial is not None:  # fixed-step runs keep their own partial results
                exc.partial.stats.update(stats)
                culprits = diagnose_failure(model, exc.time)
                if culprits:  # a model value that is not finite where the run stopped
                    raise IntegratorError(f"{exc}; " + "; ".join(culprits[:3]), exc.time,
                                          exc.flag, exc.partial) from None
                stiff = self._stiffness_culprit(exc.partial, exc.time, rtol, t_end)
                if stiff:  # the element whose stiffness or singularity stopped the run
                    raise IntegratorError(f"{exc}{stiff}", exc.time, exc.flag,
                                          exc.partial) from None
                raise
            failure = exc
        except (RuntimeError, CasmbdError) as exc:
            reraise_interrupt(exc)  # Ctrl-C is no integrator failure: no partial re-run
            if not integ.INTEGRATORS[name].keeps_partial(exc):
                raise  # no SUNDIALS re-run: a --step limit, a --projection AssemblyError
            failure = exc
        if failure is not None:
            with sun.CapturedOutput():
                xs, solver_stats = self.kind.keep_partial(self, name, grid, x0, z0, rtol,
                                                          atol, step, max_steps,
                                                          captured.text, projection)
        solve_seconds = time.perf_counter() - t0 - self._setup_seconds
        stats.update(solver_stats)
        stats["solve_seconds"] = solve_seconds
        stats["solve_cpu_seconds"] = time.thread_time() - cpu0  # set-up included, if any
        stats["setup_seconds"] = self._setup_seconds
        stats["build_seconds"] = self.build_seconds
        stats.update({k: v for k, v in model.report_dict.items() if k != "build_seconds"})
        n_ok = xs.shape[0]
        result = self.post.outputs(grid[:n_ok], xs[:, :nq], xs[:, nq:], stats)
        if failure is None:  # a value that is not finite: stops naming it and the time
            self.post.check_finite(result)
            mech = model.mechanism  # the energy: watched as the integrator needs
            params = dict(zip(mech.parameters, np.ravel(model.p), strict=False)) \
                if len(np.ravel(model.p)) == len(mech.parameters) else None
            integ.INTEGRATORS[name].check_energy(result, mech, truncated, params, rtol,
                                                 stats.get("step_size", step))
        self.post.check_violation(result)  # beyond the tolerance: stops naming the culprit
        if failure is not None:
            t_fail = float(solver_stats.get("failure_time", grid[n_ok - 1]))
            match = _FLAG.search(str(failure))
            flag = match.group(1) if match else type(failure).__name__
            msg = captured.last_line or (str(failure).strip().splitlines()[-1]
                                         if str(failure).strip() else flag)
            why = self.post.diagnose(result, t_fail)
            if not why or why.startswith("; at t ≈"):  # no non-finite value: the stiffest
                why = self._stiffness_culprit(result, t_fail, rtol, t_end) + why
            raise IntegratorError(
                f"integrator '{name}' ({self.formulation_name}) failed at t = {t_fail:.6g} with "
                f"{flag} ({msg}); results kept up to t = {grid[n_ok - 1]:.6g} "
                f"({n_ok} of {len(grid)} output times){why}"
                f"{self.kind.failure_hint(flag, rtol)}", t_fail,
                flag,
                result)
        return result

    def _stiffness_culprit(self, result, t_fail: float, rtol: float, t_end: float) -> str:
        """The element behind a failure at ``t_fail`` from the last kept state of ``result``
        (:func:`~casmbd.analysis.integrators.stiffness_culprit.diagnose_stiffness`; "" when
        none)."""
        try:
            q, v, t = result["q"], result["v"], result.t
        except (KeyError, AttributeError, TypeError):
            return ""
        if not len(t):
            return ""
        return diagnose_stiffness(self.model, t_fail, q[-1], v[-1], t_start=float(t[0]),
                                  q0=q[0], v0=v[0], rtol=rtol, t_end=t_end)

    def stiffness(self, x0: np.ndarray, t: float) -> float | None:
        """Largest decay rate max(−Re λ) of the ODE's Jacobian at (t, x0), by one-sided
        finite differences of the compiled right-hand side (2 n_q + 1 evaluations, the 2 n_q
        perturbed ones in one call of the right-hand side mapped over them; None for DAE and
        numeric formulations and above :data:`STIFF_CHECK_MAX` states).

        An explicit multistep method (Adams) needs about max(−Re λ) · (t_end − t_start) steps
        to stay stable whatever the tolerance; BDF does not (Hairer & Wanner, stiff problems).
        """
        if self.kind.ode_right_hand_side(self.dyn) is None or len(x0) > STIFF_CHECK_MAX:
            return None
        p, call = self._params(), self._rhs_buffer()

        def rhs(x):
            return np.asarray(call(t, x, np.zeros(0), p, np.zeros(0)), dtype=float).ravel()

        f0 = rhs(x0)
        if not np.all(np.isfinite(f0)):
            return None
        nx = len(x0)
        h = 1e-7 * (1.0 + np.abs(x0))
        perturbed = np.repeat(x0[:, None], nx, axis=1)
        perturbed[np.arange(nx), np.arange(nx)] += h  # column i: x0 + h_i e_i
        columns = self.__dict__.get("_rhs_columns")
        if columns is None or columns[0] != nx:
            columns = self._rhs_columns = (nx, _buffered_call(self.dyn.map(nx), nx))
        values = np.asarray(columns[1](t, perturbed, np.zeros(0), p, np.zeros(0)),
                            dtype=float).reshape((nx, nx), order="F")
        jac = (values - f0[:, None]) / h[None, :]
        if not np.all(np.isfinite(jac)):
            return None
        return float(max(0.0, np.max(-np.linalg.eigvals(jac).real, initial=0.0)))

    def _integrate(self, name, grid, x0, z0, rtol, atol, projection, step, max_steps):
        """The formulation's run (:meth:`FormulationKind.integrate`): on the compiled
        dynamics by the integrator (:meth:`integrate_compiled`) or a numeric right-hand
        side (:meth:`integrate_numeric`)."""
        return self.kind.integrate(self, name, grid, x0, z0, rtol, atol, projection, step,
                                   max_steps)

    def integrate_compiled(self, name, grid, x0, z0, rtol, atol, projection, step,
                           max_steps):
        """The compiled dynamics stepped by the integrator's kind
        (:meth:`~casmbd.analysis.integrators.IntegratorKind.integrate`)."""
        return integ.INTEGRATORS[name].integrate(self, grid, x0, z0, rtol, atol, projection,
                                                 step, max_steps)

    def integrate_numeric(self, name, grid, x0, rtol, atol, max_steps, projection):
        """A numeric right-hand side (:func:`casmbd.analysis.dynamics.numeric_run.integrate`)."""
        return numeric_run.integrate(self, name, grid, x0, rtol, atol, max_steps,
                                     projection=projection)

    def partial_numeric(self, name, grid, x0, rtol, atol, max_steps):
        """The outputs of a numeric run before its failure."""
        return numeric_run.partial(self, name, grid, x0, rtol, atol, max_steps)

    def partial_compiled(self, name, grid, x0, z0, rtol, atol, step, max_steps,
                         solver_text: str, projection: bool):
        """The outputs of a compiled run before its failure (:meth:`_partial`)."""
        # SUNDIALS names the failure time; on the one-call grid run it is absolute time
        when = _AT_T.search(solver_text)
        t_msg = float(when.group(1)) if when and not projection else None
        xs, solver_stats = self._partial(name, grid, x0, z0, rtol, atol, step, max_steps,
                                         t_msg)
        if t_msg is not None:
            solver_stats["failure_time"] = t_msg
        return xs, solver_stats

    def one_call(self, name, grid, x0, z0, rtol, atol, max_steps):
        """A SUNDIALS method over the whole output grid in one call (a progress bar per
        output interval when enabled: the same steps and numbers)."""
        if progress.enabled():  # a bar per output interval, the same steps and numbers
            clocked = self._solver(
                (name, tuple(grid), rtol, atol, max_steps, "clock"),
                lambda: self._clocked_sundials(name, grid, rtol, atol, max_steps))
            if clocked is not None:
                solver, clock = clocked
                with progress.bar(len(grid) - 1, f"{name} {self.model.name}",
                                  "output") as pbar:
                    clock.start(pbar)
                    res = solver(x0=x0, z0=z0, p=self.model.p)
                    clock.finish()
                xs = np.vstack([x0, np.asarray(res["xf"]).T])
                return xs, self._solver_stats(solver.stats())
        solver = self._solver(
            (name, tuple(grid), rtol, atol, max_steps),
            lambda: sun.sundials(self.sundials_dynamics(name), name, grid[0], grid[1:], rtol,
                                 atol, max_steps))
        res = solver(x0=x0, z0=z0, p=self.model.p)
        xs = np.vstack([x0, np.asarray(res["xf"]).T])
        return xs, self._solver_stats(solver.stats())


def _buffered_call(function: ca.Function, columns: int = 1):
    """``function``'s output 0 (its non-zeros) at positional inputs, through its bound
    buffers when its inputs and outputs are dense (:class:`BufferedFunction`), else by a
    CasADi call.  As with a CasADi call, an empty input stands for zeros; with ``columns``
    (a Function mapped over that many points) an input of one point's size is repeated."""
    buffered = BufferedFunction.of(function)
    if buffered is function:
        return lambda *args: np.asarray(function(*args)[0], dtype=float).ravel(order="F")
    sizes = [a.size for a in buffered.inputs]

    def call(*args):
        full = []
        for size, arg in zip(sizes, args, strict=False):
            arg = np.asarray(arg, dtype=float)
            if arg.size == 0:
                arg = np.zeros(size)
            elif arg.size * columns == size:
                arg = np.tile(arg.ravel(order="F"), columns)
            full.append(arg)
        return buffered(*full)
    return call


#: what forward dynamics handles: every need, each formulation and integrator its own share
#: (:func:`simulate_handling`)
HANDLING = Handling("simulate", ALL_NEEDS)


def simulate_handling(formulation: str | None = None, integrator: str | None = None,
                      projection: bool = False, step: float | None = None) -> Handling:
    """What a simulation with these options handles (:mod:`casmbd.model.needs`): the needs
    that the named formulation (:attr:`FormulationKind.handles`) and integrator
    (:attr:`IntegratorKind.handles`) both meet; projection and a fixed step leave out the
    event-driven needs (the event-driven run is variable-step).  Unnamed choices are made
    by the simulator among those that handle the mechanism."""
    handling = HANDLING
    if formulation is not None:
        kind = formulation_kind(formulation)
        handling = handling.restricted(f"simulate with formulation '{formulation}'",
                                       kind.handles, kind.refuses, kind.instead)
    if integrator is not None:
        kind = integ.integrator_kind(integrator)
        joined = " and" if formulation is not None else " with"
        handling = handling.restricted(f"{handling.analysis}{joined} integrator '{integrator}'",
                                       kind.handles, kind.refuses, kind.instead)
    if projection or step is not None:
        what = "projection" if projection else "a fixed 'step'"
        handling = handling.restricted(
            f"{handling.analysis} with {what}", ALL_NEEDS - EVENT_NEEDS,
            dict.fromkeys(EVENT_NEEDS, "the event-driven run is variable-step and keeps the "
                          "contact rows itself"),
            dict.fromkeys(EVENT_NEEDS, "no 'projection' and no 'step' (or model = "
                          "'compliant')"))
    return handling


def event_formulation(mechanism, formulation: str | None) -> str | None:
    """The formulation of an event-driven run: the one given, else ``index1`` when a closed
    contact slides (its friction μ N follows the multipliers), else the default."""
    if formulation is None and any(slides(c) for c in mechanism.contacts.values()):
        return "index1"
    return formulation


class Simulators:
    """The simulators of the event-driven run, kept across runs of one mechanism at other
    parameter values (a parameter sweep: one per process).

    The event-driven run asks for one :class:`Simulator` per set of closed gaps, each of a
    variant of the mechanism with closure joints (and contact slide forces) added; a variant
    is named by its joints and forces, whose load-time numbers a sweep keeps fixed.  A
    simulator found again gets the parameter values of the mechanism it is asked for (its
    ``model.p``), so that a run equals a fresh :func:`simulate`.  The augmented Lagrangian's
    default penalty is computed from the parameter values at build time: such a simulator is
    kept for these values only.
    """

    #: most simulators kept
    MAX = 32

    def __init__(self, formulation: str | None = None, inputs: Mapping | None = None,
                 mode: str = "auto", formulation_options: Mapping | None = None,
                 redundancy: str = "auto"):
        self.options = (formulation, inputs, mode, formulation_options, redundancy)
        self._found: dict[tuple, Simulator] = {}
        #: simulators built, and found again
        self.built = self.reused = 0

    def _key(self, mech, by_values: bool) -> tuple:
        values = tuple(float(v) if isinstance(v, (int, float)) else repr(v)
                       for v in mech.parameters.values()) if by_values else ()
        return (mech.name, tuple(mech.joints), tuple(mech.forces), values)

    def __call__(self, mech) -> Simulator:
        formulation, inputs, mode, formulation_options, redundancy = self.options
        for by_values in (False, True):
            sim = self._found.get(self._key(mech, by_values))
            if sim is not None:
                sim.model.set_parameters(**{n: v for n, v in mech.parameters.items()
                                            if n in sim.model.parameter_names})
                self.reused += 1
                return sim
        sim = Simulator(mech, formulation, inputs=inputs, mode=mode,
                        formulation_options=formulation_options, redundancy=redundancy)
        self.built += 1
        by_values = sim.kind.built_from_values(dict(formulation_options or {}))
        while len(self._found) >= self.MAX:  # oldest first
            self._found.pop(next(iter(self._found)))
        self._found[self._key(mech, by_values)] = sim
        return sim


def simulate(mechanism, t_end: float, steps: int, *, formulation: str | None = None,
             integrator: str | None = None, rtol: float = 1e-8, atol: float | None = None,
             t_start: float = 0.0, inputs: Mapping | None = None, projection: bool = False,
             step: float | None = None, mode: str = "auto",
             formulation_options: Mapping | None = None,
             max_steps: int | None = None, redundancy: str = "auto",
             simulators: Simulators | None = None, max_events: int | None = None,
             rest_velocity: float | None = None) -> Result:
    """Forward dynamics of a mechanism on a uniform output grid (one entry point).

    Parameters
    ----------
    mechanism : Mechanism
    t_end, steps : float, int
        ``steps + 1`` output times from ``t_start`` to ``t_end`` inclusive.
    formulation : str
        ``augmented_lagrangian`` (default), ``kkt_ode``, ``index1``, ``ggl`` (compiled), or
        ``partitioning``, ``nullspace`` (numeric right-hand sides; ``adams``/``cvodes`` only).
    integrator : str
        ``idas``, ``cvodes``, ``adams``, ``rk4``, ``abm`` (default per formulation).
    rtol, atol : float
        Tolerances of the variable-step integrators.
    inputs : mapping
        Actuator inputs by name (number, expression of ``t``, callable).
    projection : bool
        Project q onto C = 0 and v onto C_q v + C_t = 0 at every output time.
    step : float
        Step size of the fixed-step integrators (default: output interval / 10).
    redundancy : {"auto", "remove", "minimum_norm"}
        What to do with redundant constraint equations (:func:`plan_redundancy`); the
        result's ``stats`` give ``redundant_equations`` and ``redundancy``.
    max_events, rest_velocity : int, float, optional
        The event-driven run's bound on the number of events (default
        :data:`~casmbd.analysis.events.events.MAX_EVENTS`) and the rebound speed below which a
        contact closes instead of bouncing (default sqrt(2 g · 1 nm)); default: the scene's
        ``[simulation]`` table.  No effect without impacts or stick-slip friction.
    simulators : Simulators, optional
        The event-driven run's simulators kept from earlier runs of this mechanism at other
        parameter values (a sweep; built with the same options as this call).

    Returns
    -------
    Result
        ``kind == "simulation"`` with q, v, a, λ, joint reactions, driver efforts, energies,
        constraint violations and solver statistics.
    """
    if isinstance(steps, (int, np.integer)) and steps >= 1:  # before anything is built
        check_steps("simulation", int(steps), mechanism)
    check_integrator_options(t_end, steps, t_start=t_start, rtol=rtol,
                             atol=rtol if atol is None else atol, step=step,
                             max_steps=max_steps)
    check(mechanism, simulate_handling(formulation, integrator, projection, step))
    check_plausible_elements(mechanism)  # sqrt(k/m) and free lengths no unit makes sensible
    if has_events(mechanism):  # impacts, contact and detach: phase by phase
        formulation = event_formulation(mechanism, formulation)
        if simulators is None:
            simulators = Simulators(formulation, inputs, mode, formulation_options, redundancy)
        table = getattr(mechanism, "scene_data", None)
        table = table.get("simulation") if isinstance(table, dict) else None
        table = table if isinstance(table, dict) else {}  # checked by the scene reader
        result = simulate_events(
            mechanism, t_end, steps, integrator=integrator, rtol=rtol, atol=atol,
            t_start=t_start, max_steps=max_steps, simulator_factory=simulators,
            max_events=table.get("max_events", MAX_EVENTS) if max_events is None
            else max_events,
            rest_velocity=table.get("rest_velocity") if rest_velocity is None
            else rest_velocity)
        # beyond the tolerance the run stops naming the culprit, as without events (the
        # base simulator is the one of the open phases, kept by ``simulators``)
        simulators(mechanism).post.check_finite(result)
        simulators(mechanism).post.check_violation(result)
        return result
    sim = Simulator(mechanism, formulation, inputs=inputs, mode=mode,
                    formulation_options=formulation_options, redundancy=redundancy)
    result = sim.run(t_end, steps, t_start=t_start, integrator=integrator, rtol=rtol,
                     atol=atol, projection=projection, step=step, max_steps=max_steps)
    compliant_events(result, mechanism)
    return result
