"""The driver of the numeric formulations: output interval by output interval on CVODES.

One integrator object covers one output interval [0, h] on shifted time τ = t − t_k (t_k is its
parameter), so the run goes output interval by output interval with the same object; between
intervals the right-hand side may re-parametrise (the coordinate partitioning re-selects its
independent set: :meth:`~casmbd.analysis.integrators.numeric_rhs.NumericOde.check`) and, with
``projection=True``, q is assembled and v projected mass-orthogonally.  A failing interval is
redone from its start after a re-selection, in two halves with a check in between (recursively,
at most ``NumericOde.max_splits`` times).  The right-hand side of a built-in numeric kind
comes from :data:`RIGHT_HAND_SIDES` (keyed by the system layer's kind class), that of a user's
kind from its :meth:`~casmbd.analysis.formulations.NumericFormulation.right_hand_side`, so the
driver does not know which numeric formulation it runs.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
import weakref

import casadi as ca
import numpy as np

from casmbd.analysis.formulations import Nullspace, Partitioning, nullspace, partitioning
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.kkt import project_velocities
from casmbd.analysis.integrators.numeric_rhs import (
    Equations,
    RhsCallback,
    RhsError,
    callback_integrator,
)
from casmbd.errors import AssemblyError, IntegratorError
from casmbd.interrupts import reraise_interrupt

#: the numeric right-hand sides of the built-in numeric kinds (declared, and registered in
#: FORMULATIONS, by the system layer), kind class -> builder ``(sim, equations, x0, t0)``
RIGHT_HAND_SIDES = {Partitioning: partitioning.right_hand_side,
                    Nullspace: nullspace.right_hand_side}

_FAILED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_FLAG = re.compile(r'returned "([A-Z_]+)"')


class _Run:
    """Output interval by output interval with one CVODES object per span length."""

    def __init__(self, sim, name, grid, x0, rtol, atol, max_steps):
        self.sim, self.model, self.nq = sim, sim.model, sim.model.nq
        self.name, self.rtol, self.atol, self.max_steps = name, rtol, atol, max_steps
        self.interval = float(grid[1] - grid[0])
        build = RIGHT_HAND_SIDES.get(type(sim.kind), sim.kind.right_hand_side)
        self.ode = build(sim, Equations(sim), x0, float(grid[0]))
        self.nx = self.ode.nx
        self.callback = RhsCallback("numeric_rhs_" + sim.formulation_name, self.nx,
                                    self.ode) if self.nx else None
        self.solvers: dict[int, ca.Function] = {}
        self.totals = {"steps": 0, "rhs_evaluations": 0, "jacobian_evaluations": 0,
                       "error_test_failures": 0, "nonlinear_iterations": 0}
        self.splits = 0

    # -------------------------------------------------------------- pieces
    def _solver(self, depth: int) -> ca.Function:
        if depth not in self.solvers:
            self.solvers[depth] = callback_integrator(self.callback, self.nx, self.name,
                                                      self.interval / 2 ** depth, self.rtol,
                                                      self.atol, self.max_steps)
        return self.solvers[depth]

    def _attempt(self, x: np.ndarray, t: float, depth: int) -> np.ndarray:
        """Integrate one span of length interval / 2**depth from (x, t); full state at its end."""
        t_end = t + self.interval / 2 ** depth
        y = self.ode.reduce(x)
        if self.nx:
            solver = self._solver(depth)
            self.callback.error = None
            captured = io.StringIO()
            try:
                # a Python exception in the callback is printed by CasADi: keep it quiet
                with contextlib.redirect_stderr(captured):
                    res = solver(x0=y, p=t)
            except RuntimeError as exc:
                reraise_interrupt(exc)
                err = self.callback.error
                if err is None:
                    sys.stderr.write(captured.getvalue())
                    raise
                match = _FLAG.search(str(exc))
                flag = match.group(1) if match else "CV_RHSFUNC_FAIL"
                raise RhsError(f'{err} (CVode returned "{flag}")') from exc
            sys.stderr.write(captured.getvalue())
            _add_solver_stats(self.totals, solver.stats())
            y = np.asarray(res["xf"], dtype=float).reshape(-1)
        x_new = self.ode.expand(t_end, y)
        if not np.all(np.isfinite(x_new)):
            raise RhsError(f"non-finite state at t = {t_end:g}")
        return x_new

    def span(self, x: np.ndarray, t: float, depth: int = 0) -> np.ndarray:
        """One span; when it fails, re-select and do it in two halves (if the right-hand side
        allows splits)."""
        try:
            return self._attempt(x, t, depth)
        except (RuntimeError, RhsError) as exc:
            reraise_interrupt(exc)
            # the step limit is the user's: not a reason to re-select
            if depth >= self.ode.max_splits or "CV_TOO_MUCH_WORK" in str(exc):
                raise
        self.splits += 1
        self.ode.reselect(x, t)
        half = self.interval / 2 ** (depth + 1)
        x_mid = self.span(x, t, depth + 1)
        self.ode.check(x_mid, t + half)
        return self.span(x_mid, t + half, depth + 1)

    def stats(self, extra: dict) -> dict:
        stats = dict(self.totals)
        cb = self.callback
        stats["rhs_callback_evaluations"] = cb.calls if cb else 0
        stats["rhs_failures"] = cb.failures if cb else 0
        stats["interval_splits"] = self.splits
        stats.update(self.ode.stats(self.sim.system.coordinate_names))
        stats.update(extra)
        return stats


def _project(model, x: np.ndarray, t: float) -> np.ndarray:
    nq = model.nq
    q = assemble(model, x[:nq], t).q
    v = project_velocities(model, q, x[nq:], t)
    return np.concatenate([q, v])


def _add_solver_stats(totals: dict, st: dict) -> None:
    for key, src in (("steps", "nsteps"), ("rhs_evaluations", "nfevals"),
                     ("jacobian_evaluations", "n_call_jacF"),
                     ("error_test_failures", "netfails"),
                     ("nonlinear_iterations", "nniters")):
        totals[key] += int(st.get(src, 0))


def _run(sim, name, grid, x0, rtol, atol, max_steps, projection: bool, keep_partial: bool):
    grid = np.asarray(grid, dtype=float)
    x = np.array(x0, dtype=float)
    run = _Run(sim, name, grid, x, rtol, atol, max_steps)
    xs = [x]
    for k in range(len(grid) - 1):
        t_k, t_next = float(grid[k]), float(grid[k + 1])
        try:
            x_new = run.span(x, t_k)
            if projection:
                x_new = _project(run.model, x_new, t_next)
        except (RuntimeError, RhsError, AssemblyError) as exc:
            reraise_interrupt(exc)  # Ctrl-C: no partial results kept for a re-run
            t_fail = min(max(run.callback.t_last, t_k), t_next) if run.callback else t_k
            stats = run.stats({"failure_time": t_fail})
            if keep_partial:
                return np.vstack(xs), stats
            _FAILED[sim] = (_key(name, grid, x0, rtol, atol, max_steps), np.vstack(xs), stats)
            if isinstance(exc, RuntimeError):
                raise
            match = _FLAG.search(str(exc))
            raise IntegratorError(str(exc), t_fail, match.group(1) if match else
                                  type(exc).__name__, None) from exc
        x = x_new
        run.ode.check(x, t_next)
        xs.append(x)
    return np.vstack(xs), run.stats({})


def _key(name, grid, x0, rtol, atol, max_steps) -> tuple:
    return (name, np.asarray(grid, float).tobytes(), np.asarray(x0, float).tobytes(), rtol,
            atol, max_steps)


def integrate(sim, name: str, grid, x0, rtol: float, atol: float, max_steps: int,
              projection: bool = False) -> tuple[np.ndarray, dict]:
    """Integrate the numeric formulation of ``sim`` (``partitioning``, ``nullspace``) on ``grid``.

    Parameters
    ----------
    sim : casmbd.analysis.dynamics.simulate.Simulator
    name : {"cvodes", "adams"}
        CVODES BDF (finite-difference Jacobian of the callback) or Adams with functional
        iteration.
    grid : array
        Uniform output times; ``x0 = [q0; v0]`` is a consistent state at ``grid[0]``.
    projection : bool
        Project q (assembly) and v (mass-orthogonal) onto the constraints after every interval.

    Returns
    -------
    xs : array, shape (len(grid), 2 n_q)
        Full [q; v] at the output times.
    stats : dict
        ``steps``, ``rhs_evaluations``, ``jacobian_evaluations``, ``error_test_failures``,
        ``nonlinear_iterations`` (CVODES counters summed over the intervals),
        ``rhs_callback_evaluations`` (including finite differences), ``rhs_failures``,
        ``interval_splits``; for partitioning ``reselections``, ``independent_coordinates``
        (names, last set), ``newton_iterations`` and ``dependent_condition`` (cond(C_q,d) at
        the last selection); for null space ``constraint_rank``.

    Raises
    ------
    RuntimeError
        The CasADi/CVODES failure message (the caller then calls :func:`partial`).
    IntegratorError
        When the right-hand side itself fails (no dependent solution, ill-conditioned block
        even after re-selection and halving): flag ``CV_RHSFUNC_FAIL``.
    """
    return _run(sim, name, grid, x0, rtol, atol, max_steps, projection, keep_partial=False)


def partial(sim, name: str, grid, x0, rtol: float, atol: float,
            max_steps: int) -> tuple[np.ndarray, dict]:
    """The outputs up to the interval where the integration fails; ``stats["failure_time"]``.

    Re-uses the outputs of a failed :func:`integrate` call with the same arguments instead of
    integrating again.
    """
    key = _key(name, grid, x0, rtol, atol, max_steps)
    cached = _FAILED.pop(sim, None)
    if cached is not None and cached[0] == key:
        return cached[1], cached[2]
    return _run(sim, name, grid, x0, rtol, atol, max_steps, projection=False, keep_partial=True)
