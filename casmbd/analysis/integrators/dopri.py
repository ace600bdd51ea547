"""Dormand–Prince 5(4): an adaptive explicit Runge–Kutta method stepping in compiled code.

The method (Dormand & Prince 1980; Hairer, Nørsett & Wanner, *Solving Ordinary Differential
Equations I*, §II.4–II.5, tables 5.2 and code DOPRI5): seven stages, the last one evaluated at
the new point and reused as the first stage of the next step (FSAL, 6 right-hand sides per
attempted step), the fifth-order solution x₅ = x + h Σ bᵢ kᵢ propagated and the embedded
fourth-order solution used only for the error estimate e = h Σ (bᵢ − b̂ᵢ) kᵢ, measured as

    err = sqrt( (1/n) Σ_i ( e_i / (atol + rtol · max(|x_i|, |x₅,i|)) )² ).

A step is accepted when err ≤ 1.  The step-size controller is Hairer's PI controller
(HNW I eq. 4.13 / II eq. IV.2.43 with β = 0.04, α = 0.2 − 0.75 β):

    h_new = h · clip( 0.9 · err^(−α) · err_old^β, 0.2, 5 ),

after a rejection h_new = h · max(0.2, 0.9 · err^(−α)) and no growth on the next accepted step.
The first step comes from Hairer's heuristic (HNW I §II.4, "Starting step size").

One *attempted* step is a CasADi Function; it is folded (:func:`integrators.fixed_fold`) into
blocks of :data:`BLOCKS` = 64, 16 and 4 attempts, each attempt clipped to the next output time
(h ← t_out − t when t + 1.01 h ≥ t_out, so outputs are hit exactly, no dense output), and an
attempt once t has reached t_out does nothing (a short-circuit ``if_else``: no right-hand
side is evaluated), so the block sizes change the number of calls, never the steps.  The
blocks and the start (Hairer's first step, :func:`dopri_start`) are generated to C with the
model (:meth:`DopriKind.model_functions`: in the model's library, one translation unit with
the right-hand side they call) and called through ``Function.buffer()`` like
:class:`integrators.FixedStep`: no Python per step, only one call per block —
:meth:`Dopri.advance` takes the largest block not longer than the attempts left to the output
time at the current step size — and one for the start.  The one right-hand side outside
the compiled code is a restart's k₁ after a projection (one call of the dynamics).  Per
right-hand-side evaluation the stepping costs 1.1–1.2× the bare compiled function on the
pendulum chains (docs/performance.md, "Integrator steps against the right-hand side").

Why blocks and not one Function over the whole run: CasADi's graphs have no while loop, so
an adaptive march with an unknown number of attempts is a fixed-length fold with masking;
a masked attempt costs a branch and a copy of the state, and the block chosen is no longer
than the attempts left, so few are wasted; the Python call per block is ~1–2 µs, against up
to 64 × 6 right-hand sides.
Exact results and adaptivity are those of the step-by-step method: the same attempts in the
same order (tests/analysis/integrators/test_dopri_fused.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.analysis.integrators.kinds import (
    IntegratorKind,
    fixed_fold,
)
from casmbd.compiled.buffered import BufferedFunction
from casmbd.compiled.build import compile_blocks
from casmbd.errors import IntegratorError

# Butcher tableau of DOPRI5 (HNW I, table 5.2)
_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
_A = ((),
      (1 / 5,),
      (3 / 40, 9 / 40),
      (44 / 45, -56 / 15, 32 / 9),
      (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
      (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
      (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84))
#: b − b̂: fifth-order weights minus the embedded fourth-order weights (stage 7 = FSAL stage)
_E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)

SAFETY, FAC_MIN, FAC_MAX = 0.9, 0.2, 5.0
BETA = 0.04
ALPHA = 0.2 - 0.75 * BETA
#: attempts per compiled call, the block sizes compiled (the attempts after t_out cost a
#: branch and a copy of the state): :meth:`Dopri.advance` calls the largest block not longer
#: than the attempts left to t_out (estimated (t_out − t) / h), so a long output interval
#: takes few calls from Python and a short one wastes few attempts
BLOCKS = (64, 16, 4)
#: the block of the previous releases (one size), kept as the reference of the tests
BLOCK = 16
#: the state after the x and k₁ parts: t, h, err_old, last_rejected, accepted, rejected, failed
_TAIL = 7


def dopri_step(dyn: ca.Function) -> ca.Function:
    """One DOPRI5 step of fixed size, no control: ``(x, t, h, k1, p) -> (x5, e, k7)``.

    ``k1`` = f(t, x); ``x5`` the fifth-order solution at t + h, ``e`` the error estimate
    h Σ (bᵢ − b̂ᵢ) kᵢ and ``k7`` = f(t + h, x5), the next step's k₁.
    """
    nx = dyn.size1_in("x")
    x, k1 = ca.MX.sym("x", nx), ca.MX.sym("k1", nx)
    t, h, p = ca.MX.sym("t"), ca.MX.sym("h"), ca.MX.sym("p", dyn.size1_in("p"))
    ks = [k1]
    for i in range(1, 7):
        xi = x + h * sum(a * k for a, k in zip(_A[i], ks) if a != 0.0)
        if i == 6:
            x5 = xi
        ks.append(dyn(t=t + _C[i] * h, x=xi, p=p)["ode"])
    e = h * sum(c * k for c, k in zip(_E, ks) if c != 0.0)
    return ca.Function("dopri_step", [x, t, h, k1, p], [x5, e, ks[6]],
                       ["x", "t", "h", "k1", "p"], ["x5", "e", "k7"])


def dopri_attempt(dyn: ca.Function) -> ca.Function:
    """One attempted step with error control: ``(s, p, c) -> s_next``, c = (t_out, rtol, atol).

    s = (x, k₁, t, h, err_old, last_rejected, accepted, rejected, failed).  An attempt when
    t ≥ t_out or after a failure returns s unchanged without evaluating anything; a rejected
    attempt keeps x, t and k₁ (still valid: FSAL) and shrinks h; an h below 16 ε |t| (or
    1e-290) sets ``failed``.
    """
    nx = dyn.size1_in("x")
    step = dopri_step(dyn)
    s = ca.MX.sym("s", 2 * nx + _TAIL)
    p, c = ca.MX.sym("p", dyn.size1_in("p")), ca.MX.sym("c", 3)
    x, k1 = s[:nx], s[nx:2 * nx]
    t, h_prop, err_old, last_rej, n_acc, n_rej, failed = (s[2 * nx + i] for i in range(_TAIL))
    t_out, rtol, atol = c[0], c[1], c[2]
    rem = t_out - t
    clipped = t + 1.01 * h_prop >= t_out
    h = ca.if_else(clipped, rem, h_prop)
    x5, e, k7 = step(x, t, h, k1, p)
    err = ca.sqrt(ca.sumsqr(e / (atol + rtol * ca.fmax(ca.fabs(x), ca.fabs(x5)))) / nx)
    err = ca.if_else(err < 1e300, err, 1e300)  # NaN or inf: a rejection with the largest cut
    accept = err <= 1.0
    fac11 = err ** ALPHA
    fac = ca.fmax(1 / FAC_MAX, ca.fmin(1 / FAC_MIN, fac11 / err_old ** BETA / SAFETY))
    h_acc = h / fac
    h_acc = ca.if_else(last_rej, ca.fmin(h_acc, h), h_acc)  # no growth right after a reject
    h_acc = ca.if_else(clipped, ca.fmax(h_acc, h_prop), h_acc)  # a clipped step keeps its h
    h_rej = h / ca.fmin(1 / FAC_MIN, fac11 / SAFETY)
    h_new = ca.if_else(accept, h_acc, h_rej)
    t_new = ca.if_else(accept, ca.if_else(clipped, t_out, t + h), t)
    fail = h_new < ca.fmax(16 * np.finfo(float).eps * ca.fabs(t_new), 1e-290)
    tried = ca.vertcat(ca.if_else(accept, x5, x), ca.if_else(accept, k7, k1), t_new, h_new,
                       ca.if_else(accept, ca.fmax(err, 1e-4), err_old), 1 - accept,
                       n_acc + accept, n_rej + 1 - accept, fail)
    done = ca.logic_or(t >= t_out, failed > 0)
    out = ca.if_else(done, s, tried, True)  # short circuit: no stage evaluated when done
    return ca.Function("dopri_attempt", [s, p, c], [out], ["s", "p", "c"], ["s_next"])


def dopri_start(dyn: ca.Function) -> ca.Function:
    """The packed state at the start, first step by Hairer's heuristic, compiled:
    ``(x0, p, c) -> s``, c = (t0, t_end, rtol, atol).

    HNW I §II.4 ("Starting step size"): with sc = atol + rtol |x₀| and the root mean square
    norm ‖·‖, d₀ = ‖x₀‖, d₁ = ‖f₀‖, h₀ = 0.01 d₀ / d₁ (1e-6 when d₀ or d₁ < 1e-5), capped by
    t_end − t₀; one explicit Euler step gives d₂ = ‖f(t₀ + h₀, x₀ + h₀ f₀) − f₀‖ / h₀ and
    h = min(100 h₀, (0.01 / max(d₁, d₂))^(1/5), t_end − t₀) (max(1e-6, 10⁻³ h₀) when
    max(d₁, d₂) ≤ 1e-15).  Two right-hand sides; the same arithmetic as
    :func:`first_step` (NumPy), to rounding.
    """
    nx = dyn.size1_in("x")
    x0, p, c = ca.MX.sym("x0", nx), ca.MX.sym("p", dyn.size1_in("p")), ca.MX.sym("c", 4)
    t0, t_end, rtol, atol = c[0], c[1], c[2], c[3]
    f0 = dyn(t=t0, x=x0, p=p)["ode"]
    sc = atol + rtol * ca.fabs(x0)
    n = max(nx, 1)
    d0, d1 = ca.sqrt(ca.sumsqr(x0 / sc) / n), ca.sqrt(ca.sumsqr(f0 / sc) / n)
    h0 = ca.if_else(ca.logic_or(d0 < 1e-5, d1 < 1e-5), 1e-6, 0.01 * d0 / d1)
    h0 = ca.fmin(h0, t_end - t0)
    f1 = dyn(t=t0 + h0, x=x0 + h0 * f0, p=p)["ode"]
    d2 = ca.sqrt(ca.sumsqr((f1 - f0) / sc) / n) / h0
    big = ca.fmax(d1, d2)
    h1 = ca.if_else(big <= 1e-15, ca.fmax(1e-6, h0 * 1e-3), (0.01 / big) ** 0.2)
    h = ca.fmin(ca.fmin(100 * h0, h1), t_end - t0)
    s = ca.vertcat(x0, f0, t0, h, 1e-4, 0, 0, 0, 0)
    return ca.Function(START_NAME, [x0, p, c], [s], ["x0", "p", "c"], ["s"])


def first_step(f, x0: np.ndarray, f0: np.ndarray, t0: float, t_end: float, p, rtol: float,
               atol: float) -> float:
    """Hairer's starting step (see :func:`dopri_start`) in NumPy, ``f(t, x, p)`` the
    right-hand side: the reference of the compiled start."""
    sc = atol + rtol * np.abs(x0)
    d0, d1 = _wrms(x0, sc), _wrms(f0, sc)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_end - t0)
    f1 = f(t0 + h0, x0 + h0 * f0, p)
    d2 = _wrms(f1 - f0, sc) / h0
    big = max(d1, d2)
    h1 = max(1e-6, h0 * 1e-3) if big <= 1e-15 else (0.01 / big) ** 0.2
    return min(100 * h0, h1, t_end - t0)


@dataclass
class DopriState:
    """Where a DOPRI5 run stands: the packed state ``s`` (see :func:`dopri_attempt`) and the
    right-hand sides evaluated outside the compiled blocks (start heuristic, restarts)."""

    s: np.ndarray
    nx: int
    extra_evaluations: int = 0

    def x(self) -> np.ndarray:
        """A copy of the state vector x."""
        return self.s[:self.nx].copy()

    @property
    def t(self) -> float:
        return float(self.s[2 * self.nx])

    @property
    def h(self) -> float:
        return float(self.s[2 * self.nx + 1])

    def counts(self) -> tuple[int, int]:
        """(accepted, rejected) attempts so far."""
        return int(self.s[2 * self.nx + 4]), int(self.s[2 * self.nx + 5])

    @property
    def failed(self) -> bool:
        return bool(self.s[2 * self.nx + 6])

    def stats(self) -> dict:
        """``steps`` (accepted), ``rejected``, ``error_test_failures`` (= rejected) and
        ``rhs_evaluations`` (6 per attempt with FSAL, plus those of starts and restarts)."""
        acc, rej = self.counts()
        return {"steps": acc, "rejected": rej, "error_test_failures": rej,
                "jacobian_evaluations": 0,
                "rhs_evaluations": 6 * (acc + rej) + self.extra_evaluations}


def _wrms(v: np.ndarray, scale: np.ndarray) -> float:
    return float(np.sqrt(np.mean((v / scale) ** 2))) if len(v) else 0.0


class Dopri:
    """DOPRI5 of the ODE ``dyn`` run in compiled blocks of attempted steps.

    Parameters
    ----------
    dyn : casadi.Function
        The ODE formulation's dynamics (inputs t, x, p; output ode).
    mode : {"vm", "auto", "compiled"}
        ``"vm"`` runs the blocks in CasADi's virtual machine; otherwise they are compiled with
        :func:`casmbd.compiled.build.compile_blocks` (cached on disk).
    name : str
        Library name (a C identifier).
    functions : dict, optional
        The blocks and the start already compiled (with the model: ``name -> Function``);
        those missing are generated (and compiled unless ``mode="vm"``).
    blocks : tuple of int
        The block sizes (attempts per call), default :data:`BLOCKS`; ``(BLOCK,)`` is the
        single block of the previous releases.  The sizes change the number of calls, not
        the steps: an attempt once t = t_out does nothing.
    compiled_start : bool
        Hairer's first step by the compiled :func:`dopri_start` (one call); ``False``: in
        NumPy (:func:`first_step`, two right-hand sides called from Python), as before.
    """

    def __init__(self, dyn: ca.Function, mode: str = "vm", name: str = "casmbd_dopri5",
                 functions: dict | None = None, blocks: tuple[int, ...] = BLOCKS,
                 compiled_start: bool = True):
        self.nx = dyn.size1_in("x")
        self.report = None
        functions = dict(functions or {})
        wanted = [block_name(k) for k in blocks] + [START_NAME]
        if not all(n in functions for n in wanted):  # not compiled with the model
            t, x, p = ca.MX.sym("t"), ca.MX.sym("x", self.nx), \
                ca.MX.sym("p", dyn.size1_in("p"))
            rhs = ca.Function(RHS_NAME, [t, x, p], [dyn(t=t, x=x, p=p)["ode"]],
                              ["t", "x", "p"], ["ode"])  # a restart's k1, compiled too
            funcs = [*model_functions(dyn, blocks), rhs]
            if mode != "vm":
                compiled, self.report = compile_blocks(funcs, name, mode=mode)
                funcs = [compiled[f.name()] for f in funcs]
            functions.update({f.name(): f for f in funcs})
        #: block size -> its compiled call, largest first
        self.blocks = sorted(blocks, reverse=True)
        self._blocks = {k: BufferedFunction(functions[block_name(k)]) for k in self.blocks}
        self._block = self._blocks[self.blocks[0]]
        self._start = BufferedFunction(functions[START_NAME]) if compiled_start else None
        # f(t, x, p) through a compiled function's own buffer: the right-hand side compiled
        # with the blocks, or the dynamics compiled with the model (its z and u stay zero)
        f = functions.get(RHS_NAME, dyn)
        self._dyn = BufferedFunction(f)
        self._slots = [f.index_in(n) for n in ("t", "x", "p")]
        self._ode = f.index_out("ode")
        #: compiled calls made (blocks and starts), for the statistics
        self.calls = 0

    def start(self, x0, t0: float, t_end: float, p, rtol: float, atol: float,
              after: DopriState | None = None) -> DopriState:
        """The state at (``x0``, ``t0``): k₁ = f(t0, x0) and the first step.

        Without ``after`` the first step is Hairer's heuristic (HNW I §II.4): h₀ = 0.01 ‖x₀‖ /
        ‖f₀‖, one explicit Euler step to estimate ‖f'‖, then h = min(100 h₀, (0.01 /
        max(‖f₀‖, ‖f'‖))^(1/5)), capped by t_end − t0.  With ``after`` (a restart, e.g. after
        a projection) its step size and counts carry over.
        """
        x0 = np.asarray(x0, float).ravel()
        if not np.all(np.isfinite(x0)):
            bad = np.flatnonzero(~np.isfinite(x0))
            raise IntegratorError(f"dopri5: the state at t = {t0:.6g} is not finite (entries "
                                  f"{bad[:5].tolist()}: {x0[bad[:5]].tolist()})", t0,
                                  "NON_FINITE")
        if after is None and self._start is not None:  # Hairer's start, compiled
            s = self._start(x0, p, np.array([t0, t_end, rtol, atol], float))
            self.calls += 1
            return self._checked(DopriState(s, self.nx, 2), t0)
        f0 = self._f(t0, x0, p)
        self._checked(DopriState(np.concatenate([x0, f0]), self.nx), t0)
        tail = np.zeros(_TAIL)
        tail[0] = t0
        if after is None:
            tail[1] = first_step(self._f, x0, f0, t0, t_end, p, rtol, atol)
            tail[2], extra = 1e-4, 2
        else:
            tail[1:] = after.s[2 * self.nx + 1:]
            extra = after.extra_evaluations + 1
        return DopriState(np.concatenate([x0, f0, tail]), self.nx, extra)

    def _f(self, t: float, x: np.ndarray, p) -> np.ndarray:
        """f(t, x, p): the ODE's right-hand side (a copy)."""
        inputs = self._dyn.inputs
        for slot, value in zip(self._slots, (t, x, p)):
            inputs[slot][...] = value
        self._dyn.evaluate()
        return self._dyn.outputs[self._ode].copy()

    def _checked(self, state: DopriState, t0: float) -> DopriState:
        """``state`` if its k₁ = f(t0, x0) is finite, else an IntegratorError."""
        if not np.all(np.isfinite(state.s[self.nx:2 * self.nx])):
            raise IntegratorError(f"dopri5: the right-hand side at t = {t0:.6g} is not "
                                  f"finite", t0, "NON_FINITE")
        return state

    def advance(self, state: DopriState, p, t_out: float, rtol: float, atol: float,
                max_steps: int) -> DopriState:
        """Attempted steps from ``state`` until t = ``t_out`` exactly.

        Raises
        ------
        IntegratorError
            The step size underflows (flag ``TOO_SMALL_STEP``) or more than ``max_steps``
            attempts in this call, i.e. output interval (``TOO_MUCH_WORK``, checked after
            each block), naming the time reached.
        """
        c = np.array([t_out, rtol, atol])
        s, start = state.s, sum(state.counts())
        nx, smallest = self.nx, self.blocks[-1]
        while True:
            h = float(s[2 * nx + 1])  # attempts left at the current h (NaN: the smallest)
            left = (t_out - float(s[2 * nx])) / h if h > 0 else 0.0
            size = next((k for k in self.blocks if k <= left), smallest)
            s = self._blocks[size](s, p, c)
            self.calls += 1
            state = DopriState(s, self.nx, state.extra_evaluations)
            if state.t >= t_out:
                return state
            if state.failed:
                raise IntegratorError(
                    f"dopri5 failed at t = {state.t:.6g} with TOO_SMALL_STEP (step size "
                    f"underflow, h = {state.h:.3g})", state.t, "TOO_SMALL_STEP")
            if sum(state.counts()) - start > max_steps:  # per output, like SUNDIALS' mxstep
                raise IntegratorError(
                    f"dopri5 failed at t = {state.t:.6g} with TOO_MUCH_WORK (more than "
                    f"{max_steps} steps (max_steps) in the output interval ending at "
                    f"t = {t_out:.6g})", state.t, "TOO_MUCH_WORK")


#: name of the compiled start (:func:`dopri_start`)
START_NAME = "dopri5_start"
#: name of the right-hand side compiled with blocks built apart from the model
RHS_NAME = "dopri5_rhs"


def block_name(size: int) -> str:
    """The name of the block of ``size`` attempts (compiled with the model or on its own)."""
    return f"dopri5_block{size}"


#: name of the block of the previous releases' single size
BLOCK_NAME = block_name(BLOCK)


def dopri_block(dyn: ca.Function, size: int = BLOCK,
                attempt: ca.Function | None = None) -> ca.Function:
    """``size`` attempted steps of ``dyn``: ``(s, p, c) -> s_next`` (see
    :func:`dopri_attempt`; ``attempt`` shared between blocks generates its C once)."""
    return fixed_fold(attempt or dopri_attempt(dyn), size, block_name(size))


def model_functions(dyn: ca.Function, blocks: tuple[int, ...] = BLOCKS) -> list[ca.Function]:
    """The blocks of ``blocks`` attempts (one attempt Function shared) and the start."""
    attempt = dopri_attempt(dyn)
    return [*(dopri_block(dyn, k, attempt) for k in blocks), dopri_start(dyn)]


@dataclass(frozen=True)
class DopriKind(IntegratorKind):
    """An adaptive explicit Runge–Kutta method run by :class:`Dopri` in compiled blocks."""

    compiled: bool = True
    writes_messages: bool = False
    model_function_names: tuple[str, ...] = (*(block_name(k) for k in BLOCKS), START_NAME)

    def model_functions(self, dyn: ca.Function) -> list[ca.Function]:
        """The blocks of attempted steps and the start, compiled in the model's library
        beside ``dyn`` (:func:`model_functions`)."""
        return model_functions(dyn)

    def integrate(self, runs, grid, x0, z0, rtol: float, atol: float, projection: bool,
                  step, max_steps: int):
        """Adaptive steps in compiled blocks (:meth:`~casmbd.analysis.dynamics.stepping.Stepping.
        compiled_blocks`), projected at every output with ``projection``."""
        return runs.compiled_blocks(self.name, grid, x0, rtol, atol, max_steps, projection)

    def runner(self, dyn: ca.Function, mode: str, name: str,
               functions: dict | None = None) -> Dopri:
        """The compiled stepping of ``dyn`` (built once per simulator); with the blocks and
        the start among the model's compiled ``functions`` (then ``dyn`` should be the
        compiled dynamics), nothing is generated or compiled."""
        return Dopri(dyn, mode=mode, name=name, functions=functions)
