"""The SUNDIALS integrators through ``casadi.integrator`` (:class:`SundialsKind`):

* ``idas`` — SUNDIALS IDAS (variable-order BDF, DAE), started consistently by
  :class:`ConsistentStart`;
* ``cvodes`` — SUNDIALS CVODES, BDF with Newton iterations (ODE formulations);
* ``adams`` — CVODES Adams–Moulton with functional iterations (non-stiff ODEs).

:func:`sundials` builds one of them by name; :class:`CapturedOutput` turns SUNDIALS'
messages into part of the error.  The package :mod:`casmbd.analysis.integrators` registers
the kinds.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.analysis.integrators.kinds import INTEGRATORS, IntegratorKind, integrator_kind
from casmbd.errors import ModelError
from casmbd.model.needs import ALL_NEEDS


class CapturedOutput:
    """Capture the solver's diagnostics inside a ``with`` block.

    CasADi routes SUNDIALS' messages ("At t = … mxstep steps taken before reaching tout")
    through Python's ``sys.stderr``; C code that bypasses it writes to file descriptor 2.
    Both are captured, so that the message (and the failure time it names) becomes part of the
    error instead of stray lines on the terminal — also when ``sys.stderr`` has been replaced
    (pytest, notebooks).

    With ``enabled=False`` nothing is redirected (``text`` stays empty): a run in compiled
    code that writes no messages (DOPRI5's blocks, the fixed-step folds) saves the temporary
    file and the two ``dup2`` (about 40 µs a run, docs/performance.md).
    """

    def __init__(self, enabled: bool = True):
        self.text = ""
        self.enabled = enabled

    def __enter__(self):
        if not self.enabled:
            return self
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
        if not self.enabled:
            return False
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


def sundials(dyn: ca.Function, plugin: str, t0: float, tout, rtol: float, atol: float,
             max_steps: int, xdot0=None) -> ca.Function:
    """A CasADi SUNDIALS integrator of the registered kind ``plugin`` from ``t0`` with outputs
    at the times ``tout`` (:meth:`SundialsKind.build`)."""
    kind = integrator_kind(plugin)
    if not isinstance(kind, SundialsKind):
        raise ModelError(f"integrator '{plugin}' is not a SUNDIALS method (use one of "
                         f"{', '.join(n for n, k in INTEGRATORS.items() if not k.fixed_step)})")
    return kind.build(dyn, t0, tout, rtol, atol, max_steps, xdot0)



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

    @property
    def newton(self) -> bool:
        """Whether the method solves a Newton system each step (BDF, IDAS) and so asks for
        the Jacobian of the dynamics; Adams with functional iteration never does."""
        return dict(self.options).get("nonlinear_solver_iteration", "newton") != "functional"

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
