"""Time integrators for the dynamics formulations.

* ``idas`` — SUNDIALS IDAS (variable-order BDF, DAE), through ``casadi.integrator``;
* ``cvodes`` — SUNDIALS CVODES, BDF with Newton iterations (ODE formulations);
* ``adams`` — CVODES Adams–Moulton with functional iterations (non-stiff ODEs);
* ``rk4`` — the classical fixed-step Runge–Kutta method of order 4 (seed 000, "Numerical
  integration");
* ``abm`` — fixed-step fourth-order Adams–Bashforth–Moulton predictor–corrector in PECE mode,
  started with three RK4 steps (seed 000, "Adams methods", eqs. 6.194–6.199).

The fixed-step methods are CasADi Functions (``mapaccum`` over steps), so the whole run is one
call into the (compiled) dynamics; they are teaching tools and independent references.

Every integrator is built once for a uniform output interval ``h`` on shifted time τ = t − t_k:
the dynamics receive the interval start t_k as an extra parameter, so the same object integrates
any interval (used by projection and by the error path that keeps partial results).
"""

from __future__ import annotations

import math

import casadi as ca

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


def _rk4_step(dyn: ca.Function):
    x = ca.MX.sym("x", dyn.size1_in("x"))
    t = ca.MX.sym("t")
    p = ca.MX.sym("p", dyn.size1_in("p"))
    h = ca.MX.sym("h")

    def f(tt, xx):
        return dyn(t=tt, x=xx, p=p)["ode"]

    k1 = f(t, x)
    k2 = f(t + h / 2, x + h / 2 * k1)
    k3 = f(t + h / 2, x + h / 2 * k2)
    k4 = f(t + h, x + h * k3)
    xt = ca.vertcat(x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + h)
    return ca.Function("rk4_step", [ca.vertcat(x, t), p, h], [xt]), f, x, t, p, h


def rk4(dyn: ca.Function, interval: float, substeps: int) -> ca.Function:
    """F(x0, p, t0) -> x after ``substeps`` RK4 steps of size interval / substeps."""
    step, *_ = _rk4_step(dyn)
    nx = dyn.size1_in("x")
    x0 = ca.MX.sym("x0", nx)
    p = ca.MX.sym("p", dyn.size1_in("p"))
    t0 = ca.MX.sym("t0")
    h = interval / substeps
    acc = step.mapaccum("rk4_steps", substeps)
    xt = acc(ca.vertcat(x0, t0), p, h)
    return ca.Function("rk4", [x0, p, t0], [xt[:nx, -1]])


def abm(dyn: ca.Function, interval: float, substeps: int) -> ca.Function:
    """F(x0, p, t0) -> x after ``substeps`` ABM4 PECE steps (RK4 start) of size interval/n."""
    nx = dyn.size1_in("x")
    step_rk, *_ = _rk4_step(dyn)
    p = ca.MX.sym("p", dyn.size1_in("p"))
    h = interval / substeps

    def f(tt, xx):
        return dyn(t=tt, x=xx, p=p)["ode"]

    # history state: x_n, t_n, f_n, f_{n-1}, f_{n-2}, f_{n-3}
    xs = ca.MX.sym("s", 5 * nx + 1)
    x, t = xs[:nx], xs[nx]
    fn, f1, f2, f3 = (xs[nx + 1 + k * nx: nx + 1 + (k + 1) * nx] for k in range(4))
    xp = x + h / 24 * (55 * fn - 59 * f1 + 37 * f2 - 9 * f3)
    xc = x + h / 24 * (9 * f(t + h, xp) + 19 * fn - 5 * f1 + f2)
    fc = f(t + h, xc)
    step = ca.Function("abm_step", [xs, p], [ca.vertcat(xc, t + h, fc, fn, f1, f2)])
    x0 = ca.MX.sym("x0", nx)
    t0 = ca.MX.sym("t0")
    if substeps < 4:
        return rk4(dyn, interval, substeps)
    hist = [ca.vertcat(x0, t0)]
    for _ in range(3):
        hist.append(step_rk(hist[-1], p, h))
    fs = [f(hk[nx], hk[:nx]) for hk in hist]
    s0 = ca.vertcat(hist[3], fs[3], fs[2], fs[1], fs[0])
    acc = step.mapaccum("abm_steps", substeps - 3)
    out = acc(s0, p)
    return ca.Function("abm", [x0, p, t0], [out[:nx, -1]])


class CapturedOutput:
    """Capture what C code (SUNDIALS) writes to file descriptor 2 inside a ``with`` block.

    The solver's own diagnostic ("At t = … the corrector convergence failed …") becomes part
    of the error message instead of stray lines on the terminal.
    """

    def __init__(self):
        self.text = ""

    def __enter__(self):
        import os
        import sys
        import tempfile

        sys.stderr.flush()
        self._file = tempfile.TemporaryFile(mode="w+b")
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        return self

    def __exit__(self, *exc):
        import os

        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._file.seek(0)
        self.text = self._file.read().decode("utf-8", "replace")
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
            "disable_internal_warnings": True}
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


def fixed_step_grid(dyn: ca.Function, method: str, interval: float, substeps: int,
                    n_intervals: int) -> ca.Function:
    """F(x0, p, t0) -> states at the n_intervals output times (one column each)."""
    one = (rk4 if method == "rk4" else abm)(dyn, interval, substeps)
    nx = dyn.size1_in("x")
    xt = ca.MX.sym("xt", nx + 1)
    p = ca.MX.sym("p", dyn.size1_in("p"))
    g = ca.Function("interval", [xt, p], [ca.vertcat(one(xt[:nx], p, xt[nx]), xt[nx] + interval)])
    acc = g.mapaccum("intervals", n_intervals)
    x0 = ca.MX.sym("x0", nx)
    t0 = ca.MX.sym("t0")
    out = acc(ca.vertcat(x0, t0), p)
    return ca.Function(method + "_grid", [x0, p, t0], [out[:nx, :]], ["x0", "p", "t0"], ["xf"])
