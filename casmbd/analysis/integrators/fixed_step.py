"""The fixed-step integrators (:class:`FixedStepKind`):

* ``rk4`` — the classical fixed-step Runge–Kutta method of order 4 (seed 000, "Numerical
  integration");
* ``abm`` — fixed-step fourth-order Adams–Bashforth–Moulton predictor–corrector in PECE mode,
  started with three RK4 steps (seed 000, "Adams methods", eqs. 6.194–6.199).

They run as compiled CasADi ``fold``s of at most :data:`CHUNK` steps over the (compiled)
dynamics, called through ``Function.buffer()`` (no argument conversion) (:class:`FixedStep`);
they are teaching tools and independent references.  The package
:mod:`casmbd.analysis.integrators` registers the kinds.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.analysis.integrators.invariants import check_energy
from casmbd.analysis.integrators.kinds import (
    IntegratorKind,
    fixed_fold,
    integrator_kind,
    names,
)
from casmbd.compiled.buffered import BufferedFunction
from casmbd.compiled.build import compile_blocks
from casmbd.errors import CasmbdError, LimitError, ModelError
from casmbd.limits import MAX_FIXED_STEPS

#: fixed steps per compiled call: memory of a CasADi fold grows with its length
CHUNK = 256


def _rhs(dyn: ca.Function, p: ca.MX):
    def f(tt, xx):
        return dyn(t=tt, x=xx, p=p)["ode"]
    return f


def rk4_step(dyn: ca.Function) -> ca.Function:
    """One classical RK4 step on the state s = (x, t): s -> s(t + h)."""
    nx = dyn.size1_in("x")
    s = ca.MX.sym("s", nx + 1)
    p = ca.MX.sym("p", dyn.size1_in("p"))
    h = ca.MX.sym("h")
    f = _rhs(dyn, p)
    x, t = s[:nx], s[nx]
    k1 = f(t, x)
    k2 = f(t + h / 2, x + h / 2 * k1)
    k3 = f(t + h / 2, x + h / 2 * k2)
    k4 = f(t + h, x + h * k3)
    return ca.Function("rk4_step", [s, p, h],
                       [ca.vertcat(x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + h)])


def abm_step(dyn: ca.Function) -> ca.Function:
    """One ABM4 PECE step on s = (x, t, f_n, f_{n-1}, f_{n-2}, f_{n-3})."""
    nx = dyn.size1_in("x")
    s = ca.MX.sym("s", 5 * nx + 1)
    p = ca.MX.sym("p", dyn.size1_in("p"))
    h = ca.MX.sym("h")
    f = _rhs(dyn, p)
    x, t = s[:nx], s[nx]
    fn, f1, f2, f3 = (s[nx + 1 + k * nx: nx + 1 + (k + 1) * nx] for k in range(4))
    xp = x + h / 24 * (55 * fn - 59 * f1 + 37 * f2 - 9 * f3)          # predict (AB4)
    xc = x + h / 24 * (9 * f(t + h, xp) + 19 * fn - 5 * f1 + f2)        # correct (AM4)
    return ca.Function("abm_step", [s, p, h],
                       [ca.vertcat(xc, t + h, f(t + h, xc), fn, f1, f2)])



class FixedStep:
    """Fixed-step RK4 or ABM4 driven in compiled chunks.

    The step (RK4, or ABM4's PECE step) is written over the symbolic right-hand side and
    folded over :data:`CHUNK`, 64, 16, 4 and 1 steps (:func:`fixed_fold`); the folds are
    generated to C and compiled with the single RK4 step and the right-hand side (cached on
    disk like the model's own functions) and called through ``Function.buffer()`` on arrays
    bound once, so a chunk of steps runs without returning to Python, CasADi's virtual machine
    or its argument conversion (about 1 µs a call instead of 50–150 µs).  ``count`` steps
    take at most 3 calls per fold size.  With ``mode="vm"`` (or when the symbolic right-hand
    side is not given) the folds run in CasADi's virtual machine.

    ABM4 starts with three RK4 steps and then carries its history across output times, so
    the run is one multistep integration, not a restart per output; the start-up steps are
    ordinary steps of the run, so they end on the output times whatever the number of steps
    per output interval (1, 2, 3 or more): the step sequence does not depend on the outputs.
    """

    FOLDS = (CHUNK, 64, 16, 4, 1)

    def __init__(self, dyn: ca.Function, method: str | FixedStepKind, mode: str = "vm",
                 name: str = "casmbd_fixed"):
        self.kind = integrator_kind(method) if isinstance(method, str) else method
        if not self.kind.fixed_step:
            raise ModelError(f"integrator '{self.kind.name}' is not a fixed-step method (use "
                             f"one of {', '.join(names(fixed_step=True))})")
        self.method = self.kind.name
        self.nx = dyn.size1_in("x")
        rk = rk4_step(dyn)
        step = self.kind.step_builder(dyn)
        t, x, p = ca.MX.sym("t"), ca.MX.sym("x", self.nx), ca.MX.sym("p", dyn.size1_in("p"))
        rhs = ca.Function("rhs", [t, x, p], [dyn(t=t, x=x, p=p)["ode"]])
        folds = [fixed_fold(step, k, f"{self.method}_fold{k}") for k in self.FOLDS]
        funcs = [_renamed(rk, "rk4_single"), rhs, *folds]
        self.report = None
        if mode != "vm":
            compiled, self.report = compile_blocks(funcs, name, mode=mode)
            funcs = [compiled[f.name()] for f in funcs]
        self.rk, self.f = funcs[0], funcs[1]
        # every call through arrays bound once: ~1 µs instead of 50-150 µs of conversion
        self._rk, self._f = BufferedFunction(self.rk), BufferedFunction(self.f)
        self._folds = {k: BufferedFunction(f) for k, f in zip(self.FOLDS, funcs[2:])}

    def start(self, x0, t0: float, p, after: FixedState | None = None) -> FixedState:
        """The state at (``x0``, ``t0``) before any step, ABM4's history still empty.

        ``after`` (the state a restart replaces, e.g. after a projection) carries its step and
        evaluation counts over, so the statistics stay those of the whole run.
        """
        s = np.concatenate([np.asarray(x0, float).ravel(), [t0]])
        st = FixedState(s, 0, 0, 0) if after is None else FixedState(
            s, 0, after.steps, after.rhs_evaluations)
        if self.kind.history:  # a multistep method: f(t0, x0) and empty history slots
            f0 = self._f(t0, s[:self.nx], p)
            st.s = np.concatenate([s, f0, np.zeros(self.kind.history * self.nx)])
            st.rhs_evaluations += 1
        return st

    def advance(self, state: FixedState, p, h: float, count: int) -> FixedState:
        """``count`` (≥ 0) steps of size ``h`` from ``state``.

        ABM4 takes its first three steps after :meth:`start` with RK4, one at a time, each
        adding f(t, x) of the new state to the history; these start-up steps are counted in
        ``count`` like any other, so they may spread over several calls (output intervals of
        one or two steps) and every call ends exactly ``count`` steps further.  A negative
        count is refused: ``divmod`` would turn it into extra steps.
        """
        count = int(count)
        if count < 0:
            raise ValueError(f"fixed-step {self.method}: negative step count {count}")
        nx, s = self.nx, state.s
        steps, evals = state.steps, state.rhs_evaluations
        known, slots = state.history, self.kind.history
        while known < slots and count > 0:  # RK4 start-up, the history grows by one f
            xt = self._rk(s[:nx + 1], p, h)
            fn = self._f(xt[nx], xt[:nx], p)
            s = np.concatenate([xt, fn, s[nx + 1: nx + 1 + slots * nx]])
            known, count, steps, evals = known + 1, count - 1, steps + 1, evals + 5
        steps += count
        evals += count * self.kind.evaluations_per_step
        for k in self.FOLDS:
            n, count = divmod(count, k)
            for _ in range(n):
                s = self._folds[k](s, p, h)
        return FixedState(s, known, steps, evals)


@dataclass
class FixedState:
    """Where a fixed-step run stands.

    Attributes
    ----------
    s : numpy.ndarray
        (x, t) for RK4; (x, t, f_n, f_{n-1}, f_{n-2}, f_{n-3}) for ABM4.
    history : int
        ABM4: steps taken since the last start (up to 3: the RK4 start-up is complete and
        the f slots are all filled); unused by RK4.
    steps, rhs_evaluations : int
        Steps taken and right-hand-side evaluations made since the first start (RK4: 4 per
        step; ABM4: 1 per start, 5 per start-up RK4 step, 2 per PECE step).
    """

    s: np.ndarray
    history: int
    steps: int
    rhs_evaluations: int

    def x(self, nx: int) -> np.ndarray:
        """A copy of the state vector x (the first ``nx`` entries)."""
        return self.s[:nx].copy()


def _renamed(f: ca.Function, name: str) -> ca.Function:
    """``f`` under another name (a wrapper calling it), for code generation."""
    args = [ca.MX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    return ca.Function(name, args, f.call(args))


def substeps_for(interval: float, step: float | None, intervals: int = 1) -> int:
    """Number of fixed steps per output interval for a requested step size.

    A step that does not divide the output interval is shortened to the largest step that
    does (``interval / ceil(interval / step)``; a step longer than the interval becomes the
    interval); the step taken is reported as ``stats["step_size"]``.  A ratio within 1e-9
    (relative) of an integer counts as that integer, so that 0.1 / 0.01 = 10.000000000000002
    gives 10 steps and not 11.  More than ``MAX_FIXED_STEPS`` steps over all ``intervals``
    output intervals is a :class:`LimitError` (``--step 1e-300`` used to run forever).
    """
    if step is None:
        return 10
    if not (math.isfinite(step) and step > 0):
        raise ModelError(f"fixed step must be a finite number > 0, got {step}")
    ratio = float(interval) / step  # a Python float: inf without a numpy warning
    if not ratio * intervals <= MAX_FIXED_STEPS:  # also inf: 1e-300 / 5e-324
        raise LimitError(f"fixed step (--step) {step:g}: {ratio * intervals:.3g} steps over "
                         f"{intervals} output intervals exceed the limit of "
                         f"{MAX_FIXED_STEPS:,} (casmbd.limits): use a larger step")
    nearest = round(ratio)
    if nearest >= 1 and abs(ratio - nearest) <= 1e-9 * nearest:
        return int(nearest)
    return max(1, math.ceil(ratio))


@dataclass(frozen=True)
class FixedStepKind(IntegratorKind):
    """A fixed-step method: its step Function and bookkeeping for :class:`FixedStep`.

    ``history`` is the number of past right-hand sides a multistep method keeps besides f_n
    (filled by RK4 start-up steps); ``evaluations_per_step`` counts right-hand sides per step.
    """

    fixed_step: bool = True
    writes_messages: bool = False
    step_builder: Callable[[ca.Function], ca.Function] = rk4_step
    history: int = 0
    evaluations_per_step: int = 4

    def integrate(self, runs, grid, x0, z0, rtol: float, atol: float, projection: bool,
                  step, max_steps: int):
        """Fixed steps in compiled chunks (:meth:`~casmbd.analysis.dynamics.stepping.Stepping.
        fixed_steps`), projected at every output with ``projection``."""
        return runs.fixed_steps(self.name, grid, x0, step, project=projection)

    def keeps_partial(self, exc: Exception) -> bool:
        """A casmbd error (a ``step`` limit, a projection's AssemblyError) is final: no
        SUNDIALS re-run."""
        return not isinstance(exc, CasmbdError)

    def repeats_before(self, t_fail: float | None) -> bool:
        """No: the re-run is interval by interval."""
        return False

    def check_energy(self, result, mechanism, truncated, params, rtol: float,
                     step_size) -> None:
        """No error control: watch the energy (:func:`~casmbd.analysis.integrators.invariants.
        check_energy`)."""
        check_energy(result, mechanism, f"fixed-step {self.name} (h = {step_size:.3g})",
                     truncated, params)

    def shooting_step(self, f: ca.Function, x: ca.SX, u: ca.SX, t: ca.SX,
                      steps: int) -> ca.Function:
        """``steps`` classical RK4 steps of (ẋ, L) (SX: exact Hessians by CasADi)."""
        if not self.shooting:
            return super().shooting_step(f, x, u, t, steps)
        hs = ca.SX.sym("h")
        xk, qk = x, 0.0
        dt = hs / steps
        for s in range(steps):
            ts = t + s * dt
            k1, l1 = f(xk, u, ts)
            k2, l2 = f(xk + dt / 2 * k1, u, ts + dt / 2)
            k3, l3 = f(xk + dt / 2 * k2, u, ts + dt / 2)
            k4, l4 = f(xk + dt * k3, u, ts + dt)
            xk = xk + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            qk = qk + dt / 6 * (l1 + 2 * l2 + 2 * l3 + l4)
        return ca.Function("ocp_step", [x, u, t, hs], [xk, qk])

