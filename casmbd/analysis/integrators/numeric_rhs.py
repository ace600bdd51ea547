"""Numeric right-hand sides: the CasADi bridge and the model equations they evaluate.

The numeric formulations (:mod:`casmbd.analysis.formulations.partitioning`,
:mod:`casmbd.analysis.formulations.nullspace`)
evaluate their right-hand side with numpy around the compiled model equations; SUNDIALS CVODES
integrates it through a :class:`casadi.Callback` (forward evaluation only; ``enable_fd`` lets
CasADi difference it when CVODES-BDF asks for a Jacobian — Adams with functional iteration
never does).  The model equations a right-hand side needs are bundled into two CasADi Functions
called through ``Function.buffer`` (one call ≈ 1 µs instead of ≈ 50–100 µs per model Function).
:class:`NumericOde` is the interface the driver (:mod:`casmbd.analysis.dynamics.numeric_run`) uses.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.analysis.instant.reaction_friction import has_reaction_friction
from casmbd.analysis.integrators import sundials as sun
from casmbd.compiled.buffered import BufferedFunction
from casmbd.lazy import lazy_module

sla = lazy_module("scipy.linalg")


class RhsError(Exception):
    """The right-hand side cannot be evaluated at this state (no dependent solution, singular
    or ill-conditioned dependent block, non-finite values).  Raised inside the callback it stops
    CVODES with CV_RHSFUNC_FAIL (returning NaN instead would let CVODES accept NaN steps)."""


# ---------------------------------------------------------------------------- CasADi bridge
class RhsCallback(ca.Callback):
    """ode(τ, x, t_k) = f(τ + t_k, x), evaluated by Python; derivatives by finite differences."""

    def __init__(self, name: str, nx: int, rhs):
        ca.Callback.__init__(self)
        self._nx = nx
        self._rhs = rhs
        self.calls = 0
        self.failures = 0
        self.t_last = 0.0
        self.error: Exception | None = None
        self.construct(name, {"enable_fd": True, "fd_method": "forward"})

    def get_n_in(self):
        return 3

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ("t", "x", "p")[i]

    def get_name_out(self, i):
        return "ode"

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self._nx if i == 1 else 1, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(self._nx, 1)

    def eval(self, arg):
        self.calls += 1
        t = float(arg[0]) + float(arg[2])
        self.t_last = t
        x = np.asarray(arg[1], dtype=float).reshape(-1)
        try:
            out = self._rhs(t, x)
        except (RhsError, np.linalg.LinAlgError) as exc:
            self.failures += 1
            self.error = exc
            raise
        return [out]


def callback_integrator(callback: RhsCallback, nx: int, name: str, interval: float, rtol: float,
                atol: float, max_steps: int) -> ca.Function:
    """A CVODES integrator over [0, interval] of the callback's ODE (parameter: t_k)."""
    t = ca.MX.sym("t")
    x = ca.MX.sym("x", nx)
    z = ca.MX.sym("z", 0)
    p = ca.MX.sym("p", 1)
    u = ca.MX.sym("u", 0)
    empty = ca.MX(0, 1)
    dae = ca.Function("numeric_ode", [t, x, z, p, u], [callback(t, x, p), empty, empty, empty],
                      ca.dyn_in(), ca.dyn_out())
    return sun.sundials(dae, name, 0.0, [interval], rtol, atol, max_steps)


# ---------------------------------------------------------------------------- equations
class Equations:
    """The model's equations at one state in one call into the compiled code.

    A right-hand side needs up to eight model Functions, and a CasADi call from Python costs
    tens of microseconds, so they are bundled into two MX Functions with one packed dense input
    and output that call the (compiled) model Functions inside, evaluated through CasADi's
    zero-copy ``Function.buffer`` interface: ``kinematics(q, t)`` gives C, C_q (dense) and C_t;
    ``dynamics(q, v, t)`` gives M (dense), Q_e + Q_v (with the actuator inputs u(t)), γ and C_q.
    """

    def __init__(self, sim):
        model = sim.model
        if has_reaction_friction(model):  # Q_e here has no λ: name the joints
            model.system.refuse_reaction_friction("a numeric formulation")
        self.model = model
        nq, nc, n_p = model.nq, model.nc, len(model.p)
        self.nq, self.nc = nq, nc
        f = model.function
        w = ca.MX.sym("w", nq + 1 + n_p)
        q, t, p = w[:nq], w[nq], w[nq + 1:]
        out = [f("constraints")(q, t, p),
               ca.vec(f("constraint_jacobian")(q, t, p)),
               f("constraint_time_derivative")(q, t, p)]
        self._kin = BufferedFunction(ca.Function("partitioning_kinematics", [w],
                                                  [ca.densify(ca.vertcat(*out))]))
        w = ca.MX.sym("w", 2 * nq + 1 + n_p)
        q, v, t, p = w[:nq], w[nq:2 * nq], w[2 * nq], w[2 * nq + 1:]
        u = sim.ufun(t, p)
        force = f("applied_forces")(q, v, t, u, p) + f("quadratic_velocity_forces")(q, v, p)
        out = [ca.vec(f("mass_matrix")(q, p)), force, f("acceleration_rhs")(q, v, t, p),
               ca.vec(f("constraint_jacobian")(q, t, p))]
        self._dyn = BufferedFunction(ca.Function("partitioning_dynamics", [w],
                                                  [ca.densify(ca.vertcat(*out))]))

    def kinematics(self, q: np.ndarray, t: float):
        """C, C_q (dense), C_t at (q, t)."""
        nq, nc = self.nq, self.nc
        out = self._kin.stacked(q, (t,), self.model.p)
        return (out[:nc], out[nc:nc + nc * nq].reshape((nc, nq), order="F"),
                out[nc + nc * nq:])

    def dynamics(self, q: np.ndarray, v: np.ndarray, t: float):
        """M (dense), Q_e + Q_v, γ, C_q (dense) at (q, v, t)."""
        nq, nc = self.nq, self.nc
        out = self._dyn.stacked(q, v, (t,), self.model.p)
        m_mat = out[:nq * nq].reshape((nq, nq), order="F")
        k = nq * nq
        force, gamma = out[k:k + nq], out[k + nq:k + nq + nc]
        cq = out[k + nq + nc:].reshape((nc, nq), order="F")
        return m_mat, force, gamma, cq


def solve_dense(matrix: np.ndarray, rhs: np.ndarray, what: str, t: float) -> np.ndarray:
    """Dense LU solve (LAPACK gesv: far cheaper than scipy's wrappers for small matrices)."""
    try:
        x = np.linalg.solve(matrix, rhs)
    except np.linalg.LinAlgError as exc:
        raise RhsError(f"{what} is singular at t = {t:g}") from exc
    if not np.all(np.isfinite(x)):
        raise RhsError(f"{what} is singular at t = {t:g}")
    return x


def kkt_accelerations(m_mat: np.ndarray, cq: np.ndarray, force: np.ndarray,
                      gamma: np.ndarray) -> np.ndarray:
    """q̈ of the dense KKT system (eq. 6.205); minimum-norm least squares if it is singular.

    The same equations and fallback as
    :func:`casmbd.analysis.instant.kkt.accelerations_and_multipliers`
    with dense LAPACK instead of sparse assembly, which dominates for small systems.
    """
    n, m = m_mat.shape[0], cq.shape[0]
    if m == 0:
        return np.linalg.solve(m_mat, force)
    kkt = np.zeros((n + m, n + m))
    kkt[:n, :n] = m_mat
    kkt[:n, n:] = cq.T
    kkt[n:, :n] = cq
    rhs = np.concatenate([force, gamma])
    try:
        sol = np.linalg.solve(kkt, rhs)
        if np.all(np.isfinite(sol)) and np.linalg.norm(kkt @ sol - rhs) <= \
                1e-8 * max(1.0, np.linalg.norm(rhs)):
            return sol[:n]
    except np.linalg.LinAlgError:
        pass
    sol, *_ = sla.lstsq(kkt, rhs, lapack_driver="gelsd", check_finite=False)
    return sol[:n]


class NumericOde:
    """The interface of a numeric right-hand side for :mod:`casmbd.analysis.dynamics.numeric_run`.

    The default is an ODE in the full state x = (q, v) that is never re-parametrised; the
    coordinate partitioning overrides the state reduction and the re-selection.

    Attributes
    ----------
    nx : int
        Size of the ODE state y.
    max_splits : int
        How often a failing output interval may be redone in halves after :meth:`reselect`
        (0: a failure ends the run).
    """

    nx: int = 0
    max_splits: int = 0

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def reduce(self, x: np.ndarray) -> np.ndarray:
        """The ODE state y of a full state x = (q, v)."""
        return x

    def expand(self, t: float, y: np.ndarray) -> np.ndarray:
        """The full state x = (q, v) at time t of the ODE state y."""
        return y

    def check(self, x: np.ndarray, t: float) -> None:
        """Between output intervals: re-parametrise when the current choice degrades."""

    def reselect(self, x: np.ndarray, t: float) -> None:
        """Re-parametrise at (x, t) before a failed interval is redone in halves."""

    def stats(self, coordinate_names) -> dict:
        """Formulation-specific statistics of the run."""
        return {}
