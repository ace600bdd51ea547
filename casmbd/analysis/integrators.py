"""Time integrators for the dynamics formulations.

* ``idas`` — SUNDIALS IDAS (variable-order BDF, DAE), through ``casadi.integrator``;
* ``cvodes`` — SUNDIALS CVODES, BDF with Newton iterations (ODE formulations);
* ``adams`` — CVODES Adams–Moulton with functional iterations (non-stiff ODEs);
* ``rk4`` — the classical fixed-step Runge–Kutta method of order 4 (seed 000, "Numerical
  integration");
* ``abm`` — fixed-step fourth-order Adams–Bashforth–Moulton predictor–corrector in PECE mode,
  started with three RK4 steps (seed 000, "Adams methods", eqs. 6.194–6.199).

The fixed-step methods run as CasADi ``fold``s of at most :data:`CHUNK` steps over the
(compiled) dynamics; they are teaching tools and independent references.

Every integrator is built once for a uniform output interval ``h`` on shifted time τ = t − t_k:
the dynamics receive the interval start t_k as an extra parameter, so the same object integrates
any interval (used by projection and by the error path that keeps partial results).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from casmbd.errors import ModelError

INTEGRATORS = ("idas", "cvodes", "adams", "rk4", "abm")


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


#: fixed steps per compiled chunk: memory of a CasADi fold grows with its length
CHUNK = 64


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
    folded over :data:`CHUNK`, 16, 4 and 1 steps; these folds are generated to C and compiled
    together (cached on disk like the model's own functions), so a chunk of steps runs without
    returning to Python or CasADi's virtual machine between steps.  ``count`` steps take at
    most 3 calls per fold size.  With ``mode="vm"`` (or when the symbolic right-hand side is
    not given) the folds run in CasADi's virtual machine.

    ABM4 starts with three RK4 steps and then carries its history across output times, so
    the run is one multistep integration, not a restart per output.
    """

    FOLDS = (CHUNK, 16, 4, 1)

    def __init__(self, dyn: ca.Function, method: str, mode: str = "vm",
                 name: str = "casmbd_fixed"):
        self.method = method
        self.nx = dyn.size1_in("x")
        rk = rk4_step(dyn)
        step = rk if method == "rk4" else abm_step(dyn)
        t, x, p = ca.MX.sym("t"), ca.MX.sym("x", self.nx), ca.MX.sym("p", dyn.size1_in("p"))
        rhs = ca.Function("rhs", [t, x, p], [dyn(t=t, x=x, p=p)["ode"]])
        folds = [_renamed(step.fold(k), f"{method}_fold{k}") for k in self.FOLDS]
        funcs = [_renamed(rk, "rk4_single"), rhs, *folds]
        self.report = None
        if mode != "vm":
            from casmbd.compiled.codegen import compile_functions

            compiled, self.report = compile_functions(funcs, name=name, mode=mode)
            funcs = [compiled[f.name()] for f in funcs]
        self.rk, self.f = funcs[0], funcs[1]
        self._folds = dict(zip(self.FOLDS, funcs[2:]))

    def start(self, x0, t0: float, p, h: float):
        """Initial chunk state; for ABM4 after three RK4 steps (returns steps used)."""
        s = np.concatenate([np.asarray(x0, float).ravel(), [t0]])
        if self.method == "rk4":
            return s, 0
        hist = [s]
        for _ in range(3):
            hist.append(np.asarray(self.rk(hist[-1], p, h)).ravel())
        fs = [np.asarray(self.f(hk[self.nx], hk[:self.nx], p)).ravel() for hk in hist]
        return np.concatenate([hist[3], fs[3], fs[2], fs[1], fs[0]]), 3

    def advance(self, s, p, h: float, count: int):
        """``count`` steps of size ``h`` from chunk state ``s``."""
        for k in self.FOLDS:
            n, count = divmod(count, k)
            for _ in range(n):
                s = np.asarray(self._folds[k](s, p, h)).ravel()
        return s


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


def substeps_for(interval: float, step: float | None) -> int:
    """Number of fixed steps per output interval for a requested step size."""
    if step is None:
        return 10
    if not (math.isfinite(step) and step > 0):
        raise ModelError(f"fixed step must be a finite number > 0, got {step}")
    return max(1, math.ceil(interval / step - 1e-9))


def sundials(dyn: ca.Function, plugin: str, t0: float, tout, rtol: float, atol: float,
             max_steps: int, xdot0=None) -> ca.Function:
    """A CasADi SUNDIALS integrator from ``t0`` with outputs at the times ``tout``.

    For IDAS, ``xdot0`` (the state derivative at a consistent start) skips IDACalcIC, which
    cannot handle index-2 systems; without it IDACalcIC computes the consistent derivatives.
    """
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": max_steps,
            "print_stats": False, "show_eval_warnings": False,
            "disable_internal_warnings": False}  # captured: CapturedOutput
    if plugin == "idas":
        name = "idas"
        # keep q̈ and λ out of the error test (they are determined by q and v)
        opts["suppress_algebraic"] = True
        if xdot0 is None:
            opts["calc_ic"] = True
        else:
            opts.update({"calc_ic": False, "init_xdot": [float(x) for x in xdot0]})
    elif plugin == "cvodes":
        name = "cvodes"
        opts.update({"linear_multistep_method": "bdf"})
    elif plugin == "adams":
        name = "cvodes"
        opts.update({"linear_multistep_method": "adams",
                     "nonlinear_solver_iteration": "functional"})
    else:  # pragma: no cover - guarded by the caller
        raise ModelError(f"unknown SUNDIALS integrator '{plugin}'")
    return ca.integrator("sim_" + plugin, name, dyn, float(t0), [float(t) for t in tout], opts)
