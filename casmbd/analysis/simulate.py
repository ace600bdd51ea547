"""Forward dynamics: ``simulate`` and the reusable :class:`Simulator`.

The run is: build the formulation (:mod:`casmbd.system.formulations`) and the post-processing
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
from casmbd.analysis import integrators as integ
from casmbd.analysis.assembly import assemble
from casmbd.analysis.checks import check_consistent_start, check_start, diagnose_failure
from casmbd.analysis.kkt import (
    accelerations_and_multipliers,
    consistent_state,
    project_velocities,
)
from casmbd.analysis.reactions import flag_undetermined, multiplier_null_space
from casmbd.analysis.redundancy import (
    NEAR_SINGULAR,
    conditioning,
    equilibrated_singular_values,
    near_singular_passes,
    rank_report,
)
from casmbd.compiled.model import NumericModel, _c_name
from casmbd.errors import AnalysisError, CasmbdError, IntegratorError
from casmbd.interrupts import reraise_interrupt
from casmbd.limits import check_steps, output_values
from casmbd.model.values import resolve
from casmbd.results import Result
from casmbd.system.equations import System
from casmbd.system.formulations import (
    FORMULATIONS,
    NUMERIC_FORMULATIONS,
    build,
    post_processing,
)
from casmbd.system.subset import ConstraintSubset

#: default formulation and, per formulation, the default integrator (chosen by measurement:
#: docs/performance.md)
DEFAULT_FORMULATION = "augmented_lagrangian"
DEFAULT_INTEGRATOR = {"index1": "idas", "ggl": "idas", "kkt_ode": "adams",
                      "augmented_lagrangian": "adams", "partitioning": "adams",
                      "nullspace": "adams", "articulated": "adams"}
NUMERIC_INTEGRATORS = ("cvodes", "adams")
ODE_INTEGRATORS = ("cvodes", "adams", "rk4", "abm", "idas")
DAE_INTEGRATORS = ("idas",)


#: an ODE whose largest decay rate times the time span exceeds this is integrated with BDF
#: (CVODES) instead of Adams when no integrator is named
STIFF_STEPS = 2.0e4
#: ... and only when the decay rate exceeds this [1/s]: slower rates are mechanical modes or
#: the constraint stabilisation (Baumgarte 20 1/s), which Adams follows accurately even over
#: long runs (a 2000 s pendulum is 800x less accurate on BDF)
STIFF_RATE = 1.0e3
#: above this many states the stiffness check is skipped
STIFF_CHECK_MAX = 400

#: formulations that run with redundant constraint equations kept (minimum-norm multipliers
#: or a rank-revealing choice of independent coordinates)
KEEP_REDUNDANT = ("augmented_lagrangian", "partitioning", "nullspace")
REDUNDANCY_OPTIONS = ("auto", "remove", "minimum_norm")
#: above this many entries of C_q the dense rank check at build time is skipped
RANK_CHECK_MAX_ENTRIES = 2_000_000


def plan_redundancy(system: System, formulation: str, option: str = "auto") -> dict:
    """Find redundant constraint equations at the assembled initial pose and decide their fate.

    The rank of C_q comes from the SVD of the equilibrated matrix and the dependent rows from a
    Gram–Schmidt sweep in declaration order (:func:`casmbd.analysis.redundancy.rank_report`;
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
    from casmbd.analysis.assembly import assemble

    if option not in REDUNDANCY_OPTIONS:
        raise AnalysisError(f"redundancy must be one of {', '.join(REDUNDANCY_OPTIONS)}, "
                            f"got {option!r}")
    plan: dict = {"redundant_equations": [], "redundancy": "none", "kept_rows": None}
    if system.nc == 0:
        return plan
    if system.nc * system.nq > RANK_CHECK_MAX_ENTRIES:
        plan["redundancy"] = "not checked (C_q too large for the dense rank check)"
        return plan
    probe = NumericModel(system, "info", mode="vm")
    q = system.initial_coordinates()
    try:
        q = assemble(probe, q, 0.0).q
    except CasmbdError:
        pass  # the run's own assembly reports the failure with its context
    rep = rank_report(probe.constraint_jacobian(q, 0.0))
    plan["constraint_rank"] = rep.rank
    if not rep.dependent_rows:
        return plan
    labels = system.constraint_labels
    plan["redundant_equations"] = [str(labels[i]) for i in rep.dependent_rows]
    keeps = formulation in KEEP_REDUNDANT
    if option == "minimum_norm" and not keeps:
        raise AnalysisError(
            f"formulation '{formulation}' needs a regular KKT matrix and cannot keep the "
            f"redundant equations {', '.join(plan['redundant_equations'])}; use "
            f"redundancy='remove' or one of {', '.join(KEEP_REDUNDANT)}")
    if option == "remove" or (option == "auto" and not keeps):
        if formulation in NUMERIC_FORMULATIONS:
            plan["redundancy"] = "kept: independent coordinates chosen by rank"
            return plan
        plan["kept_rows"] = [i for i in range(system.nc) if i not in set(rep.dependent_rows)]
        plan["redundancy"] = "removed"
    else:
        plan["redundancy"] = ("minimum-norm multipliers" if formulation == "augmented_lagrangian"
                              else "kept: independent coordinates chosen by rank")
    return plan


def default_formulation(system: System) -> str:
    """The formulation used when none is named.

    ``articulated`` (the O(N) articulated-body recursion) for a tree in joint coordinates
    without constraint equations — measured faster than the KKT/LDLᵀ path on the pendulum
    chains (docs/dynamics.md, "Joint coordinates") — and :data:`DEFAULT_FORMULATION`
    otherwise.
    """
    from casmbd.system.articulated import supported

    if system.coordinates == "joint" and supported(system) is None:
        return "articulated"
    return DEFAULT_FORMULATION


def _input_expression(system: System, inputs: Mapping | None) -> ca.SX:
    """u(t, p) of the actuators: given values/expressions, zero for the others."""
    inputs = dict(inputs or {})
    names = list(system.mechanism.actuators)
    for key in inputs:
        if key not in names:
            raise AnalysisError(f"inputs: unknown actuator '{key}' (known: "
                                f"{', '.join(names) or 'none'})")
    exprs = [resolve(inputs[n], system.t, system.ctx.p, f"input of actuator '{n}'")
             if n in inputs else ca.SX(0.0) for n in names]
    return ca.vertcat(*exprs) if exprs else ca.SX(0, 1)


_FLAG = re.compile(r'returned "([A-Z_]+)"')
_AT_T = re.compile(r"t = ([-+0-9.eE]+)")


class Simulator:
    """A mechanism compiled for one formulation, ready to integrate many times.

    Parameters
    ----------
    mechanism : Mechanism or System
    formulation : str
        One of :data:`casmbd.system.formulations.FORMULATIONS` (default ``index1``).
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
        system = mechanism if isinstance(mechanism, System) else System(mechanism)
        self.formulation_name = formulation or default_formulation(system)
        if self.formulation_name not in FORMULATIONS:
            raise AnalysisError(f"unknown formulation '{self.formulation_name}' (known: "
                                f"{', '.join(FORMULATIONS)})")
        self.redundancy = plan_redundancy(system, self.formulation_name, redundancy)
        u_expr = _input_expression(system, inputs)
        self.ufun = ca.Function("actuator_inputs", [system.t, system.p], [u_expr],
                                ["t", "p"], ["u"])
        keep = self.redundancy.get("kept_rows")
        self._dyn_system = ConstraintSubset(system, keep) if keep is not None else system
        self.formulation = build(self._dyn_system, self.formulation_name, inputs=u_expr,
                                 **dict(formulation_options or {}))
        self.model = NumericModel(system, "dynamics", mode=mode,
                                  extra=[*self.formulation.functions,
                                         post_processing(system, u_expr)])
        self.system = system
        self.dyn = self.model.function(self.formulation.function.name())
        self._mode = mode
        self._solvers: dict = {}
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
        if self.formulation.kind == "ode":
            return np.zeros(0)
        keep = self.redundancy.get("kept_rows")
        if keep is not None:  # multipliers of the kept rows carrying the same C_qᵀ λ
            cq = self.model.constraint_jacobian(q, 0.0).toarray()
            lam = np.linalg.lstsq(cq[keep].T, cq.T @ lam, rcond=None)[0]
        z = [a, lam]
        if self.formulation_name == "ggl":
            z.append(np.zeros_like(lam))
        return np.concatenate(z)

    def _integrator_name(self, integrator: str | None) -> str:
        name = integrator or DEFAULT_INTEGRATOR[self.formulation_name]
        allowed = {"dae": DAE_INTEGRATORS, "ode": ODE_INTEGRATORS,
                   "numeric": NUMERIC_INTEGRATORS}[self.formulation.kind]
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
            # numeric right-hand sides are ~100x dearer: fail in seconds, not minutes
            max_steps = 20_000 if self.formulation.kind == "numeric" else 500_000
        model = self.model
        check_steps("simulation", int(steps), output_values(model.system.mechanism)
                    + 3 * model.nq + model.nc)  # LimitError before the grid is allocated
        grid = np.linspace(t_start, t_end, int(steps) + 1)
        q0 = model.system.initial_coordinates() if q0 is None else np.asarray(q0, float)
        v0 = model.system.initial_velocities() if v0 is None else np.asarray(v0, float)
        u0 = self.inputs_at(t_start)
        check_start(model, q0, v0, t_start, u0, what="simulation")  # names a NaN's culprit
        start = consistent_state(model, q0, v0, t_start, u0)
        check_consistent_start(model, start.q, start.v, start.a, t_start)
        x0 = np.concatenate([start.q, start.v])
        z0 = self._z0(start.q, start.a, start.lam)
        nq = model.nq
        choice = None
        if integrator is None and name == "adams":
            rho = self.stiffness(x0, t_start)
            if rho is not None and rho > STIFF_RATE and rho * (t_end - t_start) > STIFF_STEPS:
                name = "cvodes"
                choice = (f"cvodes (BDF): stiff, largest decay rate {rho:.3g} 1/s × "
                          f"{t_end - t_start:g} s > {STIFF_STEPS:g}")
        stats: dict = {"formulation": self.formulation_name, "integrator": name,
                       "integrator_choice": choice or ("default" if integrator is None
                                                       else "given"),
                       **{k: v for k, v in self.redundancy.items() if k != "kept_rows"},
                       "rtol": rtol, "atol": atol, "projection": projection,
                       "start_position_change": start.position_change,
                       "start_velocity_change": start.velocity_change}
        self._setup_seconds = 0.0
        t0 = time.perf_counter()
        failure = None
        captured = integ.CapturedOutput()
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
                raise
            failure = exc
        except (RuntimeError, CasmbdError) as exc:
            reraise_interrupt(exc)  # Ctrl-C is no integrator failure: no partial re-run
            if isinstance(exc, CasmbdError) and name in ("rk4", "abm"):
                raise  # no SUNDIALS re-run: a --step limit, a --projection AssemblyError
            failure = exc
        if failure is not None:
            # SUNDIALS names the failure time; on the one-call grid run it is absolute time
            when = _AT_T.search(captured.text)
            global_time = not projection and self.formulation.kind != "numeric"
            t_msg = float(when.group(1)) if when and global_time else None
            with integ.CapturedOutput():
                xs, solver_stats = self._partial(name, grid, x0, z0, rtol, atol, step,
                                                 max_steps, t_msg)
            if t_msg is not None:
                solver_stats["failure_time"] = t_msg
        solve_seconds = time.perf_counter() - t0 - self._setup_seconds
        stats.update(solver_stats)
        stats["solve_seconds"] = solve_seconds
        stats["setup_seconds"] = self._setup_seconds
        stats["build_seconds"] = self.build_seconds
        stats.update({k: v for k, v in model.report_dict.items() if k != "build_seconds"})
        n_ok = xs.shape[0]
        result = self._post(grid[:n_ok], xs[:, :nq], xs[:, nq:], stats)
        if failure is not None:
            t_fail = float(solver_stats.get("failure_time", grid[n_ok - 1]))
            match = _FLAG.search(str(failure))
            flag = match.group(1) if match else type(failure).__name__
            msg = captured.last_line or (str(failure).strip().splitlines()[-1]
                                         if str(failure).strip() else flag)
            raise IntegratorError(
                f"integrator '{name}' ({self.formulation_name}) failed at t = {t_fail:.6g} with "
                f"{flag} ({msg}); results kept up to t = {grid[n_ok - 1]:.6g} "
                f"({n_ok} of {len(grid)} output times){self._diagnose(result, t_fail)}", t_fail,
                flag,
                result)
        return result

    def _diagnose(self, result: Result, t_fail: float) -> str:
        """Rank and conditioning of C_q where a run failed: at the state extrapolated from the
        last kept output, q + h q̇ + ½ h² q̈ with h = t_fail − t_last (an estimate, accurate to
        O(h³), enough to tell a singular pose)."""
        culprits = diagnose_failure(self.model, t_fail)
        if culprits:  # a model value that is not finite where the run stopped
            return "; " + "; ".join(culprits[:3])
        if self.model.nc == 0 or not len(result.t):
            return ""
        t = float(result.t[-1])
        h = max(0.0, float(t_fail) - t) if np.isfinite(t_fail) else 0.0
        q = result["q"][-1] + h * result["v"][-1] + 0.5 * h * h * result["a"][-1]
        t += h
        rep = rank_report(self.model.constraint_jacobian(q, t))
        sigma = equilibrated_singular_values(self.model.constraint_jacobian(q, t))
        rank0 = self.redundancy.get("constraint_rank", rep.rank)
        ratio = sigma[rank0 - 1] / sigma[0] if rank0 >= 1 and sigma[0] > 0 else float("nan")
        text = (f"; at t ≈ {t:.6g} C_q has rank {rep.rank} of {rep.n_equations} equations "
                f"(regular rank {rank0}), conditioning σ_min/σ_max = {ratio:.2e}")
        if rep.rank < rank0 or ratio < NEAR_SINGULAR:
            labels = self.system.constraint_labels
            dep = ", ".join(str(labels[i]) for i in rep.dependent_rows[:4])
            text += (": a singular configuration" + (f" (dependent: {dep})" if dep else "")
                     + "; the augmented_lagrangian formulation passes singular poses")
        return text

    def stiffness(self, x0: np.ndarray, t: float) -> float | None:
        """Largest decay rate max(−Re λ) of the ODE's Jacobian at (t, x0), by one-sided
        finite differences of the compiled right-hand side (2 n_q + 1 evaluations; None for
        DAE and numeric formulations and above :data:`STIFF_CHECK_MAX` states).

        An explicit multistep method (Adams) needs about max(−Re λ) · (t_end − t_start) steps
        to stay stable whatever the tolerance; BDF does not (Hairer & Wanner, stiff problems).
        """
        if self.formulation.kind != "ode" or len(x0) > STIFF_CHECK_MAX:
            return None
        p = self._params()

        def rhs(x):
            return np.asarray(self.dyn(t, x, np.zeros(0), p, np.zeros(0))[0],
                              dtype=float).ravel()

        f0 = rhs(x0)
        if not np.all(np.isfinite(f0)):
            return None
        jac = np.empty((len(x0), len(x0)))
        for i in range(len(x0)):
            h = 1e-7 * (1.0 + abs(x0[i]))
            x = x0.copy()
            x[i] += h
            jac[:, i] = (rhs(x) - f0) / h
        if not np.all(np.isfinite(jac)):
            return None
        return float(max(0.0, np.max(-np.linalg.eigvals(jac).real, initial=0.0)))

    def _params(self, t_k: float | None = None) -> np.ndarray:
        p = self.model.p
        return p if t_k is None else np.append(p, t_k)

    def _integrate(self, name, grid, x0, z0, rtol, atol, projection, step, max_steps):
        if self.formulation.kind == "numeric":
            from casmbd.analysis import partitioning

            return partitioning.integrate(self, name, grid, x0, rtol, atol, max_steps,
                                          projection=projection)
        if projection:
            return self._interval_by_interval(name, grid, x0, z0, rtol, atol, step, max_steps,
                                              project=True)
        if name in ("rk4", "abm"):
            return self._fixed_step(name, grid, x0, step, project=False)
        if progress.enabled():  # a bar per output interval, the same steps and numbers
            clocked = self._solver(
                (name, tuple(grid), rtol, atol, max_steps, "clock"),
                lambda: self._clocked_sundials(name, grid, rtol, atol, max_steps))
            if clocked is not None:
                solver, clock = clocked
                with progress.bar(len(grid) - 1, f"{name} {self.system.mechanism.name}",
                                  "output") as pbar:
                    clock.start(pbar)
                    res = solver(x0=x0, z0=z0, p=self.model.p)
                    clock.finish()
                xs = np.vstack([x0, np.asarray(res["xf"]).T])
                return xs, self._solver_stats(solver.stats())
        solver = self._solver(
            (name, tuple(grid), rtol, atol, max_steps),
            lambda: integ.sundials(self.dyn, name, grid[0], grid[1:], rtol, atol, max_steps))
        res = solver(x0=x0, z0=z0, p=self.model.p)
        xs = np.vstack([x0, np.asarray(res["xf"]).T])
        return xs, self._solver_stats(solver.stats())

    def _clocked_sundials(self, name, grid, rtol, atol, max_steps):
        """The one-call SUNDIALS integrator on dynamics with a progress clock
        (:func:`casmbd.progress.integrator_clock`: same steps, same numbers), and the clock;
        None when the dynamics have quadratures of their own."""
        clocked = progress.integrator_clock(self.dyn, grid[1:])
        if clocked is None:
            return None
        dyn, clock = clocked
        return integ.sundials(dyn, name, grid[0], grid[1:], rtol, atol, max_steps), clock

    @staticmethod
    def _solver_stats(st: dict) -> dict:
        return {"steps": int(st.get("nsteps", 0)),
                "rhs_evaluations": int(st.get("nfevals", 0)),
                "jacobian_evaluations": int(st.get("n_call_jacF", 0)),
                "linear_setups": int(st.get("nlinsetups", 0)),
                "error_test_failures": int(st.get("netfails", 0)),
                "nonlinear_iterations": int(st.get("nniters", 0))}

    def _interval_by_interval(self, name, grid, x0, z0, rtol, atol, step, max_steps,
                              project: bool):
        interval = grid[1] - grid[0]
        nq = self.model.nq
        shifted = self._solver("shifted", lambda: integ.shifted(self.dyn))
        if name in ("rk4", "abm"):
            return self._fixed_step(name, grid, x0, step, project=True)
        solver = self._solver(
            (name, "interval", interval, rtol, atol, max_steps),
            lambda: integ.sundials(shifted, name, 0.0, [interval], rtol, atol, max_steps))

        def advance(x, z, t_k):
            r = solver(x0=x, z0=z, p=self._params(t_k))
            return (np.asarray(r["xf"]).reshape(-1), np.asarray(r["zf"]).reshape(-1),
                    self._solver_stats(solver.stats()))
        xs = [np.asarray(x0, float)]
        x, z = xs[0], z0
        with progress.bar(len(grid) - 1, f"{name} {self.system.mechanism.name}",
                          "output") as pbar:
            return self._interval_loop(advance, grid, xs, x, z, project, nq, pbar)

    def _interval_loop(self, advance, grid, xs, x, z, project, nq, pbar):
        model, totals = self.model, {}
        for k in range(len(grid) - 1):
            pbar.update()
            x, z, st = advance(x, z, grid[k])
            for key, val in st.items():
                totals[key] = totals.get(key, 0) + val
            if project:
                t = grid[k + 1]
                q = assemble(model, x[:nq], t).q
                v = project_velocities(model, q, x[nq:], t)
                x = np.concatenate([q, v])
                if self.formulation.kind == "dae":
                    a, lam = accelerations_and_multipliers(model, q, v, t, self.inputs_at(t))
                    z = self._z0(q, a, lam)
            xs.append(x)
        return np.vstack(xs), totals

    def _fixed_step(self, name, grid, x0, step, project: bool):
        """RK4 / ABM4 over the output grid in compiled chunks; optional projection.

        A non-finite state stops the run with an :class:`IntegratorError` that keeps the
        outputs before it.  The same ``n_sub`` steps of size h = interval / n_sub end on every
        output time (a requested step that does not divide the interval is shortened, see
        :func:`integrators.substeps_for`); ABM4's RK4 start-up counts among them, so the step
        sequence — and without projection the result at any time — does not depend on the
        output grid.  With projection ABM4 restarts at every output.
        """
        interval = grid[1] - grid[0]
        n_sub = integ.substeps_for(interval, step, len(grid) - 1)
        h = interval / n_sub
        runner = self._solver((name, "fixed"), lambda: integ.FixedStep(
            self.formulation.function, name, mode=self._mode,
            name=f"{_c_name(self.system.mechanism.name)}_{name}"))
        p = self.model.p
        nq, nx = self.model.nq, len(x0)
        state = runner.start(x0, grid[0], p)
        xs = [np.asarray(x0, float)]
        with progress.bar(len(grid) - 1, f"{name} {self.system.mechanism.name}",
                          "output") as pbar:
            xs, state = self._fixed_loop(runner, grid, xs, state, p, h, n_sub, nq, nx, name,
                                         project, pbar)
        return np.vstack(xs), {"steps": state.steps, "jacobian_evaluations": 0,
                               "step_size": float(h), "steps_per_output": n_sub,
                               "step_requested": step,
                               "rhs_evaluations": state.rhs_evaluations}

    def _fixed_loop(self, runner, grid, xs, state, p, h, n_sub, nq, nx, name, project,
                    pbar):
        for k in range(len(grid) - 1):
            state = runner.advance(state, p, h, n_sub)
            x = state.x(nx)
            if not np.all(np.isfinite(x)):
                partial = self._post(grid[:k + 1], np.vstack(xs)[:, :nq], np.vstack(xs)[:, nq:],
                                     {"formulation": self.formulation_name, "integrator": name})
                raise IntegratorError(
                    f"fixed-step {name} (h = {h:.3g}) produced non-finite states between "
                    f"t = {grid[k]:.6g} and {grid[k + 1]:.6g}; results kept up to "
                    f"t = {grid[k]:.6g}", grid[k + 1], "NON_FINITE", partial)
            if project:
                t = grid[k + 1]
                q = assemble(self.model, x[:nq], t).q
                x = np.concatenate([q, project_velocities(self.model, q, x[nq:], t)])
                state = runner.start(x, t, p, after=state)
            xs.append(x)
            pbar.update()
        return xs, state

    def _partial(self, name, grid, x0, z0, rtol, atol, step, max_steps,
                 t_fail: float | None = None):
        """Keep every output before the failure.

        With the failure time ``t_fail`` of a one-call grid run, the same integrator is run
        again on the outputs before ``t_fail``: SUNDIALS steps past each output and
        interpolates, so its step sequence does not depend on later outputs and the re-run
        reproduces the failed run up to its last output before ``t_fail``.  Otherwise (or if
        that re-run fails too) the run is repeated interval by interval.
        """
        if self.formulation.kind == "numeric":
            from casmbd.analysis import partitioning

            return partitioning.partial(self, name, grid, x0, rtol, atol, max_steps)
        if t_fail is not None and name not in ("rk4", "abm"):
            kept = grid[grid < t_fail]
            if len(kept) <= 1:  # failed in the first interval (or at its start)
                return np.asarray(x0, float)[None, :], {}
            try:
                solver = integ.sundials(self.dyn, name, grid[0], kept[1:], rtol, atol,
                                        max_steps)
                res = solver(x0=x0, z0=z0, p=self.model.p)
                return np.vstack([x0, np.asarray(res["xf"]).T]), {}
            except RuntimeError as exc:
                reraise_interrupt(exc)
        interval = grid[1] - grid[0]
        shifted = integ.shifted(self.dyn)
        xs = [np.asarray(x0, float)]
        x, z = xs[0], z0
        stats: dict = {}
        solver = integ.sundials(shifted, name, 0.0, [interval], rtol, atol, max_steps)
        for k in range(len(grid) - 1):
            try:
                r = solver(x0=x, z0=z, p=self._params(grid[k]))
                x = np.asarray(r["xf"]).reshape(-1)
                z = np.asarray(r["zf"]).reshape(-1)
            except RuntimeError as exc:
                reraise_interrupt(exc)
                stats["failure_time"] = grid[k] + float(solver.stats().get("tcur", 0.0))
                break
            xs.append(x)
        return np.vstack(xs), stats

    # ------------------------------------------------------------------ post-processing
    def _post_by_parts(self, grid, qs, vs):
        """Energies and constraint residuals from the model's own Functions, q̈ and λ as NaN
        (re-solved by the minimum-norm KKT solve), when the mapped ``post`` cannot be
        evaluated (the virtual machine's QR refuses a singular KKT matrix)."""
        model, n = self.model, len(grid)
        acc = np.full((n, self.system.nq), np.nan)
        lam = np.full((n, self.system.nc), np.nan)
        kin = np.array([model.kinetic_energy(qs[k], vs[k]) for k in range(n)])
        pot = np.array([model.potential_energy(qs[k], float(grid[k])) for k in range(n)])
        pos, vel = np.zeros(n), np.zeros(n)
        if self.system.nc:
            for k in range(n):
                t_k = float(grid[k])
                pos[k] = np.max(np.abs(model.constraints(qs[k], t_k)))
                vel[k] = np.max(np.abs(model.constraint_jacobian(qs[k], t_k) @ vs[k]
                                       + model.constraint_time_derivative(qs[k], t_k)))
        return acc, lam, np.full(n, np.nan), kin, pot, pos, vel

    def _post(self, grid, qs, vs, stats) -> Result:
        model, system = self.model, self.system
        n = len(grid)
        p_all = np.tile(model.p[:, None], (1, n))
        try:
            post = model.function("post").map(n)(qs.T, vs.T, grid[None, :], p_all)
            acc, lam = np.asarray(post[0]).T.copy(), np.asarray(post[1]).T.reshape(n, -1).copy()
            residual = np.asarray(post[2]).ravel()
            kin, pot, pos_viol, vel_viol = (np.asarray(x).ravel() for x in post[3:7])
        except RuntimeError as exc:  # CasADi's VM QR raises on a singular KKT matrix
            reraise_interrupt(exc)
            acc, lam, residual, kin, pot, pos_viol, vel_viol = self._post_by_parts(grid, qs, vs)
        us = np.asarray(self.ufun.map(n)(grid[None, :], p_all)).T.reshape(n, -1)
        # singular KKT matrices (redundant constraints, singular poses): minimum-norm solve
        scale = 1.0 + np.max(np.abs(np.concatenate([acc, lam], axis=1)), axis=1,
                             initial=0.0)
        finite = np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(lam), axis=1)
        redundant = bool(self.redundancy.get("redundant_equations"))
        if redundant:  # the compiled QR solve of a singular KKT matrix cannot be trusted
            singular = np.arange(n)
        else:
            singular = np.flatnonzero(~np.isfinite(residual) | ~finite
                                      | (residual > 1e-8 * np.where(finite, scale, 1.0)))
        for k in singular:
            acc[k], lam[k] = accelerations_and_multipliers(model, qs[k], vs[k], grid[k], us[k],
                                                           redundant=redundant)
        outputs = model.outputs(qs, vs, acc, grid)
        reac_f = model.function("joint_reactions").map(n)
        reac = np.asarray(reac_f(qs.T, vs.T, acc.T, grid[None, :], us.T,
                                 np.tile(model.p[:, None], (1, n)), lam.T)) \
            if system.mechanism.joints else np.zeros((3, 0))
        n_j, size = len(system.mechanism.joints), system.reaction_size
        reactions = reac.reshape(size, n, n_j).transpose(1, 2, 0) if n_j else \
            np.zeros((n, 0, size))
        if n_j and system.nc:
            first = multiplier_null_space(model.constraint_jacobian(qs[0], float(grid[0])))
            steps = range(n) if first.shape[1] else singular
            reactions, flags = flag_undetermined(model, qs, vs, acc, grid, us, lam, reactions,
                                                 steps)
            stats = {**stats, **flags}
        cond = conditioning(model, qs, grid, self.redundancy.get("constraint_rank"),
                            extra=singular)
        passes = near_singular_passes(model, grid, qs, vs, cond,
                                      self.redundancy.get("constraint_rank"))
        stats = {**stats, "min_constraint_conditioning": min(
            [float(np.nanmin(cond))] + [c for _, c in passes]) if np.any(np.isfinite(cond))
            else None, "near_singular_times": [t for t, _ in passes]}
        drivers = list(system.mechanism.drivers)
        undetermined = set(stats.get("undetermined_rows", ()))
        efforts = np.column_stack([
            np.full(n, np.nan) if system.driver_rows[d] in undetermined
            else -lam[:, system.driver_rows[d]] for d in drivers]) \
            if drivers else np.zeros((n, 0))
        names = {"coordinates": system.coordinate_names, "bodies": system.body_names,
                 "markers": list(system.mechanism.markers),
                 "joints": system.joint_coordinate_names,
                 "all_joints": list(system.mechanism.joints), "drivers": drivers,
                 "actuators": list(system.mechanism.actuators),
                 "constraints": [str(lab) for lab in system.constraint_labels]}
        arrays = {"q": qs, "v": vs, "a": acc, "lambda": lam, **outputs,
                  "joint_reactions": reactions, "driver_efforts": efforts,
                  "actuator_inputs": us, "kinetic_energy": kin, "potential_energy": pot,
                  "total_energy": kin + pot, "constraint_violation": pos_viol,
                  "velocity_violation": vel_viol, "constraint_conditioning": cond}
        return Result("simulation", grid, arrays, names, stats,
                      getattr(system.mechanism, "scene_text", "") or "")


def simulate(mechanism, t_end: float, steps: int, *, formulation: str | None = None,
             integrator: str | None = None, rtol: float = 1e-8, atol: float | None = None,
             t_start: float = 0.0, inputs: Mapping | None = None, projection: bool = False,
             step: float | None = None, mode: str = "auto",
             formulation_options: Mapping | None = None,
             max_steps: int | None = None, redundancy: str = "auto") -> Result:
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

    Returns
    -------
    Result
        ``kind == "simulation"`` with q, v, a, λ, joint reactions, driver efforts, energies,
        constraint violations and solver statistics.
    """
    if isinstance(steps, (int, np.integer)) and steps >= 1:  # before anything is built
        check_steps("simulation", int(steps), output_values(mechanism))
    sim = Simulator(mechanism, formulation, inputs=inputs, mode=mode,
                    formulation_options=formulation_options, redundancy=redundancy)
    return sim.run(t_end, steps, t_start=t_start, integrator=integrator, rtol=rtol, atol=atol,
                   projection=projection, step=step, max_steps=max_steps)
