"""How a simulation steps: output interval by output interval, fixed steps, partial re-runs.

A mixin of :class:`casmbd.analysis.dynamics.simulate.Simulator` (it uses the simulator's compiled
model, dynamics Function, formulation and integrator cache): the one-call SUNDIALS run with a
progress clock, the interval-by-interval SUNDIALS run (projection onto the constraints after
every output), the fixed-step RK4/ABM4 loop in compiled chunks, and the re-run that keeps the
outputs before a failure.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd import progress
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.kkt import project_velocities
from casmbd.analysis.integrators import fixed_step as fixed
from casmbd.analysis.integrators import kinds as integ
from casmbd.analysis.integrators import sundials as sun
from casmbd.compiled.build import compile_blocks
from casmbd.compiled.model import c_symbol_name
from casmbd.errors import IntegratorError
from casmbd.interrupts import reraise_interrupt

#: the largest ODE (states) whose SUNDIALS Newton methods get the exact compiled Jacobian;
#: larger ones get forward differences of the compiled right-hand side.  Measured (CVODES-BDF
#: at rtol = atol = 1e-7, docs/performance.md "Integrator steps against the right-hand
#: side"): chain8 (16 states) 5.3 µs per right-hand side with central differences, 3.7 with
#: forward differences, 3.2 exact; chain32 (64 states) 66, 26 and 76 µs: the Jacobian of the
#: 32-rod articulated-body recursion by CasADi's AD (250 000 operations expanded) costs more
#: than 65 calls of the right-hand side, and compiles in 8.6 s (100 rods: 7.8 s)
NEWTON_JACOBIAN_MAX = 32


class Stepping:
    """Integration loops of the :class:`~casmbd.analysis.dynamics.simulate.Simulator`."""

    def _params(self, t_k: float | None = None) -> np.ndarray:
        p = self.model.p
        return p if t_k is None else np.append(p, t_k)

    def sundials_dynamics(self, name: str):
        """The compiled dynamics the SUNDIALS method ``name`` integrates.

        A Newton method (CVODES-BDF, IDAS) on an ODE formulation of at most
        :data:`NEWTON_JACOBIAN_MAX` states gets the dynamics compiled with their exact
        Jacobian ``jac_<name>`` = ∂(ẋ, …)/∂(t, x, z, p, u) (CasADi's AD of the formulation's
        Function), in a library of its own built on first use and cached like the model's:
        the Newton matrix I − γ ∂f/∂x is then formed from one call instead of finite
        differences of the right-hand side.  A larger ODE gets forward differences of the
        compiled right-hand side (:meth:`_forward_difference_dynamics`; its exact Jacobian
        costs more than nx + 1 calls).  Adams (functional iteration) never asks for a
        Jacobian: it uses ``self.dyn``; so do the DAE formulations, whose compiled
        ``jac_<name>`` the model's library loads with ``enable_fd`` (central differences:
        with their exact Jacobian index1 on IDAS gives up elsewhere at singular poses,
        tests/analysis/formulations/test_singular_chains.py).
        """
        kind = integ.INTEGRATORS.get(name)
        if not getattr(kind, "newton", False) or not self.dyn.is_a("External") \
                or self.kind.ode_right_hand_side(self.dyn) is None:  # an explicit ODE only
            return self.dyn
        if self.dyn.nnz_in(1) > NEWTON_JACOBIAN_MAX:
            return self._forward_difference_dynamics()
        if "newton_dyn" not in self._solvers:
            f = self.formulation.function
            prefix = c_symbol_name(f"{self.model.name}_newton")
            functions, report = compile_blocks([f, f.jacobian()], prefix, mode=self._mode,
                                               hot=[f.name(), f"jac_{f.name()}"])
            # without enable_fd: with it CasADi prefers central differences (fwd16_<name> by
            # CentralDiff) to the library's jac_<name>
            self._solvers["newton_dyn"] = functions[f.name()] if report.library is None \
                else ca.external(f.name(), report.library)
        return self._solvers["newton_dyn"]

    def _forward_difference_dynamics(self):
        """The model's compiled dynamics loaded again with forward differences (one call per
        state and one at the point: nx + 1 calls a Jacobian) instead of CasADi's default
        central differences: on chain32 (64 states) CVODES-BDF 60 → 24 ms a run, the same
        steps; else ``self.dyn``."""
        if "forward_dyn" not in self._solvers:
            fname, found = self.dyn.name(), self.dyn
            for library in self.model.report.libraries or ():
                try:
                    found = ca.external(fname, library, {"enable_fd": True,
                                                         "fd_method": "forward"})
                    break
                except RuntimeError:  # a split model: the function is in another library
                    continue
            self._solvers["forward_dyn"] = found
        return self._solvers["forward_dyn"]

    def _clocked_sundials(self, name, grid, rtol, atol, max_steps):
        """The one-call SUNDIALS integrator on dynamics with a progress clock
        (:func:`casmbd.progress.integrator_clock`: same steps, same numbers), and the clock;
        None when the dynamics have quadratures of their own."""
        clocked = progress.integrator_clock(self.sundials_dynamics(name), grid[1:])
        if clocked is None:
            return None
        dyn, clock = clocked
        return sun.sundials(dyn, name, grid[0], grid[1:], rtol, atol, max_steps), clock

    @staticmethod
    def _solver_stats(st: dict) -> dict:
        return {"steps": int(st.get("nsteps", 0)),
                "rhs_evaluations": int(st.get("nfevals", 0)),
                "jacobian_evaluations": int(st.get("n_call_jacF", 0)),
                "linear_setups": int(st.get("nlinsetups", 0)),
                "error_test_failures": int(st.get("netfails", 0)),
                "nonlinear_iterations": int(st.get("nniters", 0))}

    def interval_by_interval(self, name, grid, x0, z0, rtol, atol, step, max_steps,
                              project: bool):
        interval = grid[1] - grid[0]
        nq = self.model.nq
        shifted = self._solver("shifted", lambda: integ.shifted(self.dyn))
        solver = self._solver(
            (name, "interval", interval, rtol, atol, max_steps),
            lambda: sun.sundials(shifted, name, 0.0, [interval], rtol, atol, max_steps))

        def advance(x, z, t_k):
            r = solver(x0=x, z0=z, p=self._params(t_k))
            return (np.asarray(r["xf"]).reshape(-1), np.asarray(r["zf"]).reshape(-1),
                    self._solver_stats(solver.stats()))
        xs = [np.asarray(x0, float)]
        x, z = xs[0], z0
        with progress.bar(len(grid) - 1, f"{name} {self.model.name}",
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
                z = self.algebraic_state_at(q, v, t)
            xs.append(x)
        return np.vstack(xs), totals

    def fixed_steps(self, name, grid, x0, step, project: bool):
        """RK4 / ABM4 over the output grid in compiled chunks; optional projection.

        A non-finite state stops the run with an :class:`IntegratorError` that keeps the
        outputs before it.  The same ``n_sub`` steps of size h = interval / n_sub end on every
        output time (a requested step that does not divide the interval is shortened, see
        :func:`integrators.substeps_for`); ABM4's RK4 start-up counts among them, so the step
        sequence — and without projection the result at any time — does not depend on the
        output grid.  With projection ABM4 restarts at every output.
        """
        interval = grid[1] - grid[0]
        n_sub = fixed.substeps_for(interval, step, len(grid) - 1)
        h = interval / n_sub
        runner = self._solver((name, "fixed"), lambda: fixed.FixedStep(
            self.formulation.function, name, mode=self._mode,
            name=f"{c_symbol_name(self.model.name)}_{name}"))
        p = self.model.p
        nq, nx = self.model.nq, len(x0)
        state = runner.start(x0, grid[0], p)
        xs = [np.asarray(x0, float)]
        with progress.bar(len(grid) - 1, f"{name} {self.model.name}",
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
                partial = self.post.outputs(grid[:k + 1], np.vstack(xs)[:, :nq],
                                            np.vstack(xs)[:, nq:],
                                            {"formulation": self.formulation_name,
                                             "integrator": name})
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

    def compiled_blocks(self, name, grid, x0, rtol, atol, max_steps, project: bool):
        """An adaptive method in compiled blocks (DOPRI5,
        :mod:`casmbd.analysis.integrators.dopri`) over the output grid, each step clipped to
        the next output; optional projection (then a restart with the same step size).  A
        failure raises an :class:`IntegratorError` that keeps the outputs before it."""
        kind = integ.INTEGRATORS[name]
        # the model's library may hold the method's block over the compiled dynamics: then no
        # symbolic formulation is built and nothing is compiled (a cached run)
        prebuilt = {n: self.model.functions[n] for n in kind.model_function_names
                    if n in self.model.functions}
        runner = self._solver((name, "compiled"), lambda: kind.runner(
            self.dyn if prebuilt else self.formulation.function, self._mode,
            f"{c_symbol_name(self.model.name)}_{name}", prebuilt))
        p, nq = self.model.p, self.model.nq
        xs = [np.asarray(x0, float)]
        k = 0
        try:
            state = runner.start(x0, grid[0], grid[-1], p, rtol, atol)
            with progress.bar(len(grid) - 1, f"{name} {self.model.name}", "output") as pbar:
                for k in range(len(grid) - 1):
                    state = runner.advance(state, p, grid[k + 1], rtol, atol, max_steps)
                    x = state.x()
                    if project:
                        t = grid[k + 1]
                        q = assemble(self.model, x[:nq], t).q
                        x = np.concatenate([q, project_velocities(self.model, q, x[nq:], t)])
                        state = runner.start(x, t, grid[-1], p, rtol, atol, after=state)
                    xs.append(x)
                    pbar.update()
        except IntegratorError as exc:
            xv = np.vstack(xs)
            partial = self.post.outputs(grid[:k + 1], xv[:, :nq], xv[:, nq:],
                                        {"formulation": self.formulation_name,
                                         "integrator": name})
            raise IntegratorError(f"{exc}; results kept up to t = {grid[k]:.6g}", exc.time,
                                  exc.flag, partial) from None
        return np.vstack(xs), state.stats()

    def _partial(self, name, grid, x0, z0, rtol, atol, step, max_steps,
                 t_fail: float | None = None):
        """Keep every output before the failure.

        With the failure time ``t_fail`` of a one-call grid run, the same integrator is run
        again on the outputs before ``t_fail``: SUNDIALS steps past each output and
        interpolates, so its step sequence does not depend on later outputs and the re-run
        reproduces the failed run up to its last output before ``t_fail``.  Otherwise (or if
        that re-run fails too) the run is repeated interval by interval.
        """
        if integ.INTEGRATORS[name].repeats_before(t_fail):
            kept = grid[grid < t_fail]
            if len(kept) <= 1:  # failed in the first interval (or at its start)
                return np.asarray(x0, float)[None, :], {}
            try:
                solver = sun.sundials(self.sundials_dynamics(name), name, grid[0],
                                      kept[1:], rtol, atol, max_steps)
                res = solver(x0=x0, z0=z0, p=self.model.p)
                return np.vstack([x0, np.asarray(res["xf"]).T]), {}
            except RuntimeError as exc:
                reraise_interrupt(exc)
        interval = grid[1] - grid[0]
        shifted = integ.shifted(self.sundials_dynamics(name))
        xs = [np.asarray(x0, float)]
        x, z = xs[0], z0
        stats: dict = {}
        solver = sun.sundials(shifted, name, 0.0, [interval], rtol, atol, max_steps)
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
