"""Time integrators for the dynamics formulations.

* ``idas`` — SUNDIALS IDAS (variable-order BDF, DAE), through ``casadi.integrator``;
* ``cvodes`` — SUNDIALS CVODES, BDF with Newton iterations (ODE formulations);
* ``adams`` — CVODES Adams–Moulton with functional iterations (non-stiff ODEs);
* ``rk4`` — the classical fixed-step Runge–Kutta method of order 4 (seed 000, "Numerical
  integration");
* ``abm`` — fixed-step fourth-order Adams–Bashforth–Moulton predictor–corrector in PECE mode,
  started with three RK4 steps (seed 000, "Adams methods", eqs. 6.194–6.199).

The fixed-step methods run as compiled CasADi ``fold``s of at most :data:`CHUNK` steps over
the (compiled) dynamics, called through ``Function.buffer()`` (no argument conversion); they
are teaching tools and independent references.

Every integrator is built once for a uniform output interval ``h`` on shifted time τ = t − t_k:
the dynamics receive the interval start t_k as an extra parameter, so the same object integrates
any interval (used by projection and by the error path that keeps partial results).

Each integrator is an :class:`IntegratorKind` in the registry :data:`INTEGRATORS` (name ->
kind, like scipy's ``solve_ivp`` ``METHODS``): what it integrates (ODE, DAE, numeric right-hand
sides), whether its step is fixed, whether it serves the optimal-control problem's multiple
shooting, and how it is built.  Simulation, the OCP and the CLI's ``--integrator`` choices read
the registry; :func:`integrator_kind` raises :class:`~casmbd.errors.UnknownMethodError` for a
name that is not in it.  Adding an integrator = one :func:`register_integrator` call here, or
in the package :mod:`casmbd.analysis.integrators` for a kind in a module of its own (``dopri5``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.analysis.integrators.invariants import check_energy, check_energy_blowup
from casmbd.compiled.codegen import compile_functions
from casmbd.compiled.workspace import buffered
from casmbd.errors import CasmbdError, LimitError, ModelError, UnknownMethodError
from casmbd.limits import MAX_FIXED_STEPS
from casmbd.model.needs import ALL_NEEDS, EVENT_NEEDS


def shifted(dyn: ca.Function) -> ca.Function:
    """g(τ, x, z, [p; t_k], u) = f(τ + t_k, x, z, p, u)."""
    tau = ca.MX.sym("t")
    x = ca.MX.sym("x", dyn.sparsity_in("x"))
    z = ca.MX.sym("z", dyn.sparsity_in("z"))
    p = ca.MX.sym("p", dyn.size1_in("p") + 1)
    u = ca.MX.sym("u", dyn.sparsity_in("u"))
    out = dyn(t=tau + p[-1], x=x, z=z, p=p[:-1], u=u)
    return ca.Function("shifted", [tau, x, z, p, u], [out["ode"], out["alg"], out["quad"],
                                                      out["zero"]],
                       ca.dyn_in(), ca.dyn_out())


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


def fixed_fold(step: ca.Function, count: int, name: str) -> ca.Function:
    """``name(s, p, h) -> s_next``: ``count`` steps of ``step(s, p, h)`` in one call.

    ``step.fold(count)`` (a loop in the generated code) with ``p`` and ``h`` (the step size,
    or any column of step controls) given once and repeated inside, so that the inputs are
    single columns bound once to numpy arrays.
    """
    s, p, h = ca.MX.sym("s", step.size1_in(0)), ca.MX.sym("p", step.sparsity_in(1)), \
        ca.MX.sym("h", step.sparsity_in(2))  # a column of step controls (DOPRI5) or h
    out = step.fold(count)(s, ca.repmat(p, 1, count), ca.repmat(h, 1, count))
    return ca.Function(name, [s, p, h], [out], ["s", "p", "h"], ["s_next"])


class _Buffered:
    """A Function called on numpy arrays bound once (``Function.buffer()``): the arguments
    are copied into the bound arrays, and the first output is returned as a new array."""

    def __init__(self, f: ca.Function):
        self._args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self._trigger, self._outs = buffered(f, self._args)

    def __call__(self, *args) -> np.ndarray:
        for bound, val in zip(self._args, args):
            bound[...] = val
        self._trigger()
        return self._outs[0].copy()


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
            compiled, self.report = compile_functions(funcs, name=name, mode=mode)
            funcs = [compiled[f.name()] for f in funcs]
        self.rk, self.f = funcs[0], funcs[1]
        # every call through arrays bound once: ~1 µs instead of 50-150 µs of conversion
        self._rk, self._f = _Buffered(self.rk), _Buffered(self.f)
        self._folds = {k: _Buffered(f) for k, f in zip(self.FOLDS, funcs[2:])}

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


class CapturedOutput:
    """Capture the solver's diagnostics inside a ``with`` block.

    CasADi routes SUNDIALS' messages ("At t = … mxstep steps taken before reaching tout")
    through Python's ``sys.stderr``; C code that bypasses it writes to file descriptor 2.
    Both are captured, so that the message (and the failure time it names) becomes part of the
    error instead of stray lines on the terminal — also when ``sys.stderr`` has been replaced
    (pytest, notebooks).
    """

    def __init__(self):
        self.text = ""

    def __enter__(self):
        import io
        import os
        import sys
        import tempfile

        sys.stderr.flush()
        self._stream, self._saved_stream = io.StringIO(), sys.stderr
        sys.stderr = self._stream
        self._file = tempfile.TemporaryFile(mode="w+b")
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        return self

    def __exit__(self, *exc):
        import os
        import sys

        os.dup2(self._saved, 2)
        os.close(self._saved)
        sys.stderr = self._saved_stream
        self._file.seek(0)
        self.text = self._stream.getvalue() + self._file.read().decode("utf-8", "replace")
        self._file.close()
        return False

    @property
    def last_line(self) -> str:
        """The last non-empty captured line."""
        lines = [ln.strip() for ln in self.text.splitlines() if ln.strip()]
        return lines[-1] if lines else ""


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


def sundials(dyn: ca.Function, plugin: str, t0: float, tout, rtol: float, atol: float,
             max_steps: int, xdot0=None) -> ca.Function:
    """A CasADi SUNDIALS integrator of the registered kind ``plugin`` from ``t0`` with outputs
    at the times ``tout`` (:meth:`SundialsKind.build`)."""
    kind = integrator_kind(plugin)
    if not isinstance(kind, SundialsKind):
        raise ModelError(f"integrator '{plugin}' is not a SUNDIALS method (use one of "
                         f"{', '.join(n for n, k in INTEGRATORS.items() if not k.fixed_step)})")
    return kind.build(dyn, t0, tout, rtol, atol, max_steps, xdot0)


# ---------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class IntegratorKind:
    """What an integrator integrates and how it is used (one entry of :data:`INTEGRATORS`).

    Attributes
    ----------
    name : str
        The name users give (``--integrator``, ``simulate(integrator=...)``, ``[ocp]``).
    label : str
        The method in a few words, for messages ("BDF", "RK4").
    ode, dae, numeric : bool
        Integrates ODE formulations; semi-explicit DAEs (index 1 or GGL index 2); numeric
        right-hand sides (a :class:`casadi.Callback`, forward evaluations only).
    fixed_step : bool
        A fixed-step method run by :class:`FixedStep` (no tolerances; ``--step``).
    shooting : bool
        Serves the optimal-control problem's multiple shooting (:meth:`shooting_step`).
    stiff_alternative : str or None
        The integrator taken instead when none is named and the ODE is stiff (Adams -> BDF).
    compiled : bool
        An adaptive method whose steps run in compiled blocks (``runner(dyn, mode, name)``,
        :class:`casmbd.analysis.integrators.dopri.Dopri`).
    model_function_names : tuple of str
        Names of the Functions of :meth:`model_functions` (compiled with the model).
    """

    name: str
    label: str
    ode: bool = True
    dae: bool = False
    numeric: bool = False
    fixed_step: bool = False
    shooting: bool = False
    stiff_alternative: str | None = None
    compiled: bool = False
    #: names of the :meth:`model_functions`
    model_function_names: tuple[str, ...] = ()

    def model_functions(self, dyn: ca.Function) -> list[ca.Function]:
        """Functions of this method over the dynamics ``dyn`` worth compiling with the model
        (in its library, its translation unit shared with ``dyn``), so that a cached run
        neither builds the symbolic formulation nor compiles again; none by default."""
        return []

    @property
    def handles(self) -> frozenset:
        """The needs of elements (:mod:`casmbd.model.needs`) a run with this integrator
        meets: all but the event-driven ones (root finding on gaps between impulses)."""
        return ALL_NEEDS - EVENT_NEEDS

    #: why it does not meet the event needs, and what to use instead
    refuses = dict.fromkeys(EVENT_NEEDS, "the event-driven run uses a variable-step SUNDIALS "
                            "integrator with root finding")
    instead = dict.fromkeys(EVENT_NEEDS, "integrator 'idas', 'cvodes' or 'adams' (or the "
                            "default)")

    def integrates(self, kind: str) -> bool:
        """Whether this integrator accepts a formulation of ``kind`` ("ode", "dae",
        "numeric": :attr:`casmbd.analysis.formulations.FormulationKind.kind`)."""
        return bool(getattr(self, kind, False))

    def integrate(self, runs, grid, x0, z0, rtol: float, atol: float, projection: bool,
                  step, max_steps: int):
        """``(xs, stats)`` on the output ``grid`` for the simulator ``runs``
        (:class:`casmbd.analysis.dynamics.stepping.Stepping`): by default a SUNDIALS method, in one
        call over the grid or, with ``projection``, output interval by output interval."""
        if projection:
            return runs.interval_by_interval(self.name, grid, x0, z0, rtol, atol, step,
                                              max_steps, project=True)
        return runs.one_call(self.name, grid, x0, z0, rtol, atol, max_steps)

    def keeps_partial(self, exc: Exception) -> bool:
        """Whether the outputs before the failure ``exc`` are kept by running again."""
        return True

    def repeats_before(self, t_fail: float | None) -> bool:
        """Whether a run on the outputs before a failure at ``t_fail`` repeats the failed
        run up to them (SUNDIALS steps past each output and interpolates: its steps do not
        depend on later outputs)."""
        return t_fail is not None

    def check_energy(self, result, mechanism, truncated, params, rtol: float,
                     step_size) -> None:
        """After a run: error control, but a loose tolerance may still let the energy
        explode (:func:`~casmbd.analysis.integrators.invariants.check_energy_blowup`)."""
        check_energy_blowup(result, mechanism, f"{self.name} (rtol = {rtol:g})", truncated,
                            params)

    def shooting_step(self, f: ca.Function, x: ca.SX, u: ca.SX, t: ca.SX,
                      steps: int) -> ca.Function:
        """``ocp_step(x, u, t, h) -> (x(t + h), ∫ L dt)`` of ``f(x, u, t) -> (ẋ, L)`` over one
        shooting interval (``steps`` sub-steps for a fixed-step method); ``x``, ``u``, ``t``
        are the SX symbols ``f`` was built from (the same graph, the same rounding)."""
        raise UnknownMethodError("shooting integrator", self.name, names(shooting=True))


def _index2(dyn: ca.Function) -> bool:
    """Whether some algebraic equation of ``dyn`` does not depend on z (structurally): the
    DAE is then of index 2 or more (GGL's position and velocity constraints)."""
    try:
        sp = dyn.sparsity_jac("z", "alg")
    except RuntimeError:
        return False
    return len(set(sp.get_triplet()[0])) < sp.size1()


class ConsistentStart:
    """An IDAS integrator that starts every call from a consistent derivative, by construction.

    IDAS integrates the residual F(t, y, ẏ) = (f(t, x, z) − ẋ, g(t, x, z)) and needs a
    consistent start F(t0, y0, ẏ0) = 0.  The caller gives x0 = (q, v) and z0 = (q̈, λ) from
    the KKT solve at t0 (seed 000, eq. 6.138), so g(t0, x0, z0) = 0 to rounding; this object
    completes the start with ẋ0 = f(t0, x0, z0), evaluated by the same dynamics Function
    IDAS evaluates, so that the differential rows of F vanish exactly.  IDAS is then built
    with ``calc_ic = False`` and ``init_xdot = ẋ0``: its own initial-condition calculation
    (IDACalcIC, a damped Newton iteration with a line search) is never run.  Started from a
    point that is already consistent, that line search has nothing left to reduce but
    rounding error, and whether it then fails (IDA_LINESEARCH_FAIL at t = 0) depended on the
    CPU's rounding (issue 30: an 8-rod chain at rtol 1e-11 failed on AMD EPYC, passed on
    Intel).  CasADi fixes ``init_xdot`` when the integrator is built, so one integrator is
    built per distinct start (about 1 ms) and the last :data:`KEEP` are kept.

    The algebraic variables get the absolute tolerance max(atol, :data:`ALGEBRAIC_FLOOR` ·
    (1 + ‖z0‖∞)) (``abstolv``).  They are outside IDAS's error test already
    (``suppress_algebraic``: q̈ and λ follow from q and v), but IDAS's Newton convergence test
    weighs them too, and z can be resolved no better than the rounding of the KKT solve,
    κ · ε · ‖z‖: where that floor reaches the tolerance the corrector cannot converge at any
    step size (IDA_CONV_FAIL at t = 0, h = 1e-18) — or converges, depending on the last bit.
    The 8-rod chain at rtol = atol = 1e-11 (‖z0‖∞ = 15.8): with atol 1e-11 on z one start in
    five perturbed by 1e-14 fails, with 1.7e-11 the unperturbed start fails, from 1.7e-10
    on every start passes (measured 2026-11-28); 1e-9 · (1 + ‖z0‖∞) = 1.7e-8 leaves a factor
    100, and moves the tip at t = 2 s by < 1e-9.  The differential states keep the
    tolerances asked for.

    Called like a CasADi integrator (``solver(x0=…, z0=…, p=…)``, ``solver.stats()``).
    """

    #: integrators kept, one per distinct ẋ0 (a re-run from the same start reuses its own)
    KEEP = 8
    #: absolute tolerance of the algebraic variables relative to 1 + ‖z0‖∞: far above the
    #: rounding of a KKT solve (κ · ε ≈ 1e-12 for the 8-rod chain) up to κ ≈ 4e6
    ALGEBRAIC_FLOOR = 1e-9
    #: the same for an index-2 system (algebraic rows that do not depend on z: GGL's C = 0 and
    #: C_q v + C_t = 0), whose multipliers IDAS's corrector resolves only to rounding / h²:
    #: the four-bar (absolute coordinates, ‖z0‖∞ = 11.1) integrates from 1e-7 on at rtol
    #: 1e-8 and from 1e-6 on at rtol 1e-10, and fails below (measured 2026-11-28)
    INDEX2_ALGEBRAIC_FLOOR = 1e-5

    def __init__(self, dyn: ca.Function, name: str, plugin: str, t0: float, tout,
                 opts: dict):
        self.dyn, self.name, self.plugin = dyn, name, plugin
        self.t0, self.tout = float(t0), [float(t) for t in tout]
        self.opts = {**opts, "calc_ic": False}
        self._built: dict[bytes, ca.Function] = {}
        self._last: ca.Function | None = None
        self.floor = self.INDEX2_ALGEBRAIC_FLOOR if _index2(dyn) else self.ALGEBRAIC_FLOOR

    def derivative(self, x0, z0, p) -> np.ndarray:
        """ẋ0 = f(t0, x0, z0, p): the differential right-hand side at the start."""
        u = np.zeros(self.dyn.size1_in("u"))
        out = self.dyn(t=self.t0, x=ca.DM(x0), z=ca.DM(z0), p=ca.DM(p), u=u)
        return np.asarray(out["ode"], dtype=float).reshape(-1)

    def residual(self, x0, z0, p, xdot0=None) -> tuple[np.ndarray, np.ndarray]:
        """F(t0, y0, ẏ0) split into the differential rows f − ẋ0 and the algebraic rows g
        (``xdot0`` defaults to :meth:`derivative`)."""
        u = np.zeros(self.dyn.size1_in("u"))
        out = self.dyn(t=self.t0, x=ca.DM(x0), z=ca.DM(z0), p=ca.DM(p), u=u)
        f = np.asarray(out["ode"], dtype=float).reshape(-1)
        xdot = f if xdot0 is None else np.asarray(xdot0, float).reshape(-1)
        return f - xdot, np.asarray(out["alg"], dtype=float).reshape(-1)

    def algebraic_tolerance(self, z0) -> float:
        """The absolute tolerance of the algebraic variables started from ``z0``."""
        z0 = np.asarray(z0, dtype=float).reshape(-1)
        scale = 1.0 + float(np.max(np.abs(z0), initial=0.0)) if np.all(np.isfinite(z0)) \
            else 1.0
        return max(float(self.opts["abstol"]), self.floor * scale)

    def solver(self, xdot0: np.ndarray, z_tol: float | None = None) -> ca.Function:
        """The CasADi IDAS integrator started with ``init_xdot = xdot0`` and the algebraic
        variables' absolute tolerance ``z_tol`` (built once per pair)."""
        key = np.ascontiguousarray(np.append(xdot0, z_tol or 0.0), dtype=float).tobytes()
        solver = self._built.get(key)
        if solver is None:
            if len(self._built) >= self.KEEP:
                self._built.pop(next(iter(self._built)))
            opts = dict(self.opts)
            if np.all(np.isfinite(xdot0)):
                opts["init_xdot"] = [float(x) for x in xdot0]
            nx, nz = self.dyn.size1_in("x"), self.dyn.size1_in("z")
            if z_tol is not None and nz:
                opts["abstolv"] = [float(opts["abstol"])] * nx + [float(z_tol)] * nz
            solver = self._built[key] = ca.integrator(self.name, self.plugin, self.dyn,
                                                      self.t0, self.tout, opts)
        return solver

    def __call__(self, x0=None, z0=None, p=None, **kwargs):
        x0 = np.zeros(self.dyn.size1_in("x")) if x0 is None else x0
        z0 = np.zeros(self.dyn.size1_in("z")) if z0 is None else z0
        p = np.zeros(self.dyn.size1_in("p")) if p is None else p
        self._last = self.solver(self.derivative(x0, z0, p), self.algebraic_tolerance(z0))
        return self._last(x0=x0, z0=z0, p=p, **kwargs)

    def stats(self) -> dict:
        """The statistics of the last call (empty before the first)."""
        return self._last.stats() if self._last is not None else {}


@dataclass(frozen=True)
class SundialsKind(IntegratorKind):
    """A SUNDIALS method through ``casadi.integrator``: CasADi plugin and its options."""

    plugin: str = "cvodes"
    options: tuple = ()

    @property
    def handles(self) -> frozenset:
        """Every need: SUNDIALS' root finding serves the event-driven run."""
        return ALL_NEEDS

    def build(self, dyn: ca.Function, t0: float, tout, rtol: float, atol: float,
              max_steps: int, xdot0=None) -> ca.Function:
        """A CasADi integrator of ``dyn`` from ``t0`` with outputs at the times ``tout``.

        A DAE method (IDAS) never runs IDACalcIC: it starts from ``xdot0`` when given, else
        it is a :class:`ConsistentStart`, which takes ẋ0 = f(t0, x0, z0) from the
        dynamics at each call's own start (the caller's z0 comes from the KKT solve).
        """
        opts = {"reltol": rtol, "abstol": atol, "max_num_steps": max_steps,
                "print_stats": False, "show_eval_warnings": False,
                "disable_internal_warnings": False}  # captured: CapturedOutput
        opts.update(dict(self.options))
        if self.dae:
            if xdot0 is None:  # ẋ0 from each call's own (x0, z0): no IDACalcIC
                return ConsistentStart(dyn, "sim_" + self.name, self.plugin, t0, tout, opts)
            opts.update({"calc_ic": False, "init_xdot": [float(x) for x in xdot0]})
        return ca.integrator("sim_" + self.name, self.plugin, dyn, float(t0),
                             [float(t) for t in tout], opts)

    def shooting_step(self, f: ca.Function, x: ca.SX, u: ca.SX, t: ca.SX,
                      steps: int) -> ca.Function:
        """One shooting interval on normalised time τ ∈ [0, 1] (rtol = atol = 1e-10), with
        exact first-order sensitivities; an MX Function."""
        if not self.shooting:
            return super().shooting_step(f, x, u, t, steps)
        nx, nu = x.numel(), u.numel()
        hs = ca.SX.sym("h")
        tau = ca.SX.sym("tau")
        ode_s, quad_s = f(x, u, t + tau * hs)
        dae = {"x": x, "p": ca.vertcat(u, t, hs), "t": tau, "ode": hs * ode_s,
               "quad": hs * quad_s}
        integ = ca.integrator("ocp_" + self.name, self.plugin, dae, 0.0, 1.0,
                              {"abstol": 1e-10, "reltol": 1e-10, **dict(self.options)})
        xm, um, tm, hm = (ca.MX.sym(n, s) for n, s in
                          (("x", nx), ("u", nu), ("t", 1), ("h", 1)))
        out = integ(x0=xm, p=ca.vertcat(um, tm, hm))
        return ca.Function("ocp_step", [xm, um, tm, hm], [out["xf"], out["qf"]])


@dataclass(frozen=True)
class FixedStepKind(IntegratorKind):
    """A fixed-step method: its step Function and bookkeeping for :class:`FixedStep`.

    ``history`` is the number of past right-hand sides a multistep method keeps besides f_n
    (filled by RK4 start-up steps); ``evaluations_per_step`` counts right-hand sides per step.
    """

    fixed_step: bool = True
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


#: the registered integrators, name -> kind (registration order is the order of choices)
INTEGRATORS: dict[str, IntegratorKind] = {}
#: the optimal-control problem's default shooting integrator
DEFAULT_SHOOTING_INTEGRATOR = "rk4"


def register_integrator(kind: IntegratorKind) -> IntegratorKind:
    """Add ``kind`` to :data:`INTEGRATORS` under ``kind.name`` (replacing one of that name)."""
    if not (isinstance(kind, IntegratorKind) and isinstance(kind.name, str) and kind.name):
        raise ModelError(f"register_integrator: an IntegratorKind with a name, got {kind!r}")
    INTEGRATORS[kind.name] = kind
    return kind


def integrator_kind(name: str) -> IntegratorKind:
    """The registered integrator ``name``; :class:`~casmbd.errors.UnknownMethodError` listing
    the registered names otherwise."""
    try:
        return INTEGRATORS[name]
    except (KeyError, TypeError):
        raise UnknownMethodError("integrator", name, INTEGRATORS) from None


def names(**features: bool) -> list[str]:
    """Registered integrator names with the given features, e.g. ``names(dae=True)``."""
    return [n for n, k in INTEGRATORS.items()
            if all(getattr(k, key) == val for key, val in features.items())]


register_integrator(SundialsKind(
    "idas", "BDF", dae=True, plugin="idas",
    # keep q̈ and λ out of the error test (they are determined by q and v)
    options=(("suppress_algebraic", True),)))
register_integrator(SundialsKind(
    "cvodes", "BDF", numeric=True, shooting=True, plugin="cvodes",
    options=(("linear_multistep_method", "bdf"),)))
register_integrator(SundialsKind(
    "adams", "Adams–Moulton", numeric=True, plugin="cvodes", stiff_alternative="cvodes",
    options=(("linear_multistep_method", "adams"), ("nonlinear_solver_iteration", "functional"))))
register_integrator(FixedStepKind("rk4", "RK4", shooting=True, step_builder=rk4_step,
                                  evaluations_per_step=4))
register_integrator(FixedStepKind("abm", "ABM4", step_builder=abm_step, history=3,
                                  evaluations_per_step=2))
# Dormand–Prince 5(4) builds on this module (casmbd.analysis.integrators.dopri); the package
# casmbd.analysis.integrators registers it, so this module imports no other of its room
