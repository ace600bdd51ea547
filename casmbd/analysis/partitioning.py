"""Forward dynamics without multipliers in the state: coordinate partitioning and null space.

Both formulations evaluate their right-hand side numerically (numpy around the compiled model
equations) and are integrated by SUNDIALS CVODES through a :class:`casadi.Callback` (forward
evaluation only; ``enable_fd`` lets CasADi difference it when CVODES-BDF asks for a Jacobian —
Adams with functional iteration never does).  One integrator object covers one output interval
[0, h] on shifted time τ = t − t_k (t_k is its parameter), so the run goes output interval by
output interval with the same object; between intervals the independent set may be re-selected
and, with ``projection=True``, q is assembled and v projected mass-orthogonally.  The model
equations needed by a right-hand side are bundled into two CasADi Functions called through
``Function.buffer`` (one call ≈ 1 µs instead of ≈ 50–100 µs per model Function).

Generalized coordinate partitioning (Wehage; seed 000, "Elimination of Lagrange multipliers" and
"Algorithm and sparse matrix implementation", eqs. 6.200–6.205)
-----------------------------------------------------------------------------------------
*Selection.*  Gaussian elimination with full (complete) pivoting on the dense C_q: at step k the
entry of largest magnitude in the remaining block is swapped into the pivot position (row and
column exchange).  After r = rank(C_q) steps the r pivot columns give a square, well-conditioned
block C_q,d; their coordinates are the *dependent* ones, the n_q − r columns never chosen as
pivots are the *independent* coordinates q_i, and the r pivot rows are the independent
equations (the other rows are redundant and are dropped).  The rank comes from
:func:`casmbd.analysis.redundancy.rank_report` (SVD of the equilibrated Jacobian), so
redundant constraints are handled.

*State and right-hand side.*  The ODE state is y = (q_i, v_i).  At each evaluation

1. q_i is set and the dependent q_d solved from C(q, t) = 0 by Newton-Raphson, warm-started
   from the previous solution.  The matrix of eq. 6.201, [C_q; I_d] δq = [−C; 0], forces
   δq_i = 0, so each iteration is the dense LU solve C_q,d δq_d = −C (independent rows);
2. the dependent velocities from the same block at the converged q (eqs. 6.202–6.204):
   C_q,d v_d = −C_t − C_q,i v_i;
3. q̈ from the KKT system of eq. 6.205 with the independent rows (:func:`kkt_accelerations`:
   the equations and minimum-norm fallback of
   :func:`casmbd.analysis.kkt.accelerations_and_multipliers`, dense), and (v_i, q̈_i) is
   returned.

*Re-selection* (seed 000, "Singular configurations").  A partition is kept while cond(C_q,d)
stays below its limit ``max(min(COND_LIMIT, COND_GROWTH·c₀), 10·c₀)`` (c₀: the value at
selection).  After every output interval the limit is checked and, if exceeded, the independent
set is chosen again at that state.  Inside an interval the right-hand side stops CVODES as soon
as the limit is exceeded or Newton fails (a set that goes bad between two checks also makes the
dependent solution jump between branches near the singular pose, which CVODES would otherwise
grind through with tiny steps); the interval is then redone from its start with a fresh
selection, in two halves with a check in between (recursively, at most ``MAX_SPLITS`` times).
At a true singular configuration (rank drop of C_q, e.g. the collinear parallelogram) no
independent set works and the run ends with an :class:`~casmbd.errors.IntegratorError`.
``stats["reselections"]`` counts the selections that changed the set.

Null-space (embedding) formulation (seed 000, "Elimination of Lagrange multipliers", SVD)
---------------------------------------------------------------------------------------
The embedding technique with an orthonormal basis from the singular value decomposition of
C_q (rows equilibrated, which leaves the null space unchanged): with C_q = U Σ Vᵀ and rank r
decided by σ > ``RANK_RTOL`` · σ_max (as in :mod:`casmbd.analysis.redundancy`), N = V[:, r:] spans
the admissible accelerations, a_p = C_q⁺ γ = V_r Σ_r⁻¹ U_rᵀ γ is the minimum-norm particular
acceleration, and the reduced equations

    Nᵀ M N z̈ = Nᵀ (Q − M a_p),        q̈ = a_p + N z̈

follow from M q̈ + C_qᵀ λ = Q since Nᵀ C_qᵀ = 0.  The state is the full (q, v).  Redundant
constraints only lower r; λ never appears.  Brauchli's mass-orthogonal projection,
q̈ = a_p + (I − M⁻¹C_qᵀ(C_q M⁻¹ C_qᵀ)⁺C_q)(M⁻¹Q − a_p), gives the same q̈ (both are the unique
acceleration with C_q q̈ = γ whose residual M q̈ − Q lies in the row space of C_q).  Like the
KKT ODE it does not stabilise the position and velocity constraints: use ``projection=True``
for long runs.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
import weakref
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.linalg as sla

from casmbd.analysis import integrators as integ
from casmbd.analysis.assembly import assemble
from casmbd.analysis.kkt import project_velocities
from casmbd.analysis.redundancy import RANK_RTOL, rank_report
from casmbd.errors import AssemblyError, IntegratorError
from casmbd.interrupts import reraise_interrupt

#: absolute limit on cond(C_q,d) before the independent set is re-selected
COND_LIMIT = 1e6
#: re-select also when cond(C_q,d) grew by this factor since the selection
COND_GROWTH = 100.0
#: how often a failing interval may be halved (after a re-selection) before giving up
MAX_SPLITS = 8
#: Newton tolerance on max |C| for the dependent coordinates, relative to the mechanism's size:
#: converged to round-off (the dependent coordinates amplify the residual by cond(C_q,d), and
#: noise in them makes CVODES crawl near singular poses) ...
NEWTON_RTOL = 1e-15
#: ... or stalled (no more progress) below this residual
NEWTON_FLOOR = 1e-11
NEWTON_MAX_ITER = 30


class _RhsError(Exception):
    """The right-hand side cannot be evaluated at this state (no dependent solution, singular
    or ill-conditioned dependent block, non-finite values).  Raised inside the callback it stops
    CVODES with CV_RHSFUNC_FAIL (returning NaN instead would let CVODES accept NaN steps)."""


# ---------------------------------------------------------------------------- CasADi bridge
class _RhsCallback(ca.Callback):
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
        except (_RhsError, np.linalg.LinAlgError) as exc:
            self.failures += 1
            self.error = exc
            raise
        return [out]


def _integrator(callback: _RhsCallback, nx: int, name: str, interval: float, rtol: float,
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
    return integ.sundials(dae, name, 0.0, [interval], rtol, atol, max_steps)


# ---------------------------------------------------------------------------- equations
class _Equations:
    """The model's equations at one state in one call into the compiled code.

    A right-hand side needs up to eight model Functions, and a CasADi call from Python costs
    tens of microseconds, so they are bundled into two MX Functions with one packed dense input
    and output that call the (compiled) model Functions inside, evaluated through CasADi's
    zero-copy ``Function.buffer`` interface: ``kinematics(q, t)`` gives C, C_q (dense) and C_t;
    ``dynamics(q, v, t)`` gives M (dense), Q_e + Q_v (with the actuator inputs u(t)), γ and C_q.
    """

    def __init__(self, sim):
        model = sim.model
        self.model = model
        nq, nc, n_p = model.nq, model.nc, len(model.p)
        self.nq, self.nc = nq, nc
        f = model.function
        w = ca.MX.sym("w", nq + 1 + n_p)
        q, t, p = w[:nq], w[nq], w[nq + 1:]
        out = [f("constraints")(q, t, p),
               ca.vec(f("constraint_jacobian")(q, t, p)),
               f("constraint_time_derivative")(q, t, p)]
        self._kin = _Buffered(ca.Function("partitioning_kinematics", [w],
                                          [ca.densify(ca.vertcat(*out))]))
        w = ca.MX.sym("w", 2 * nq + 1 + n_p)
        q, v, t, p = w[:nq], w[nq:2 * nq], w[2 * nq], w[2 * nq + 1:]
        u = sim.ufun(t, p)
        force = f("applied_forces")(q, v, t, u, p) + f("quadratic_velocity_forces")(q, v, p)
        out = [ca.vec(f("mass_matrix")(q, p)), force, f("acceleration_rhs")(q, v, t, p),
               ca.vec(f("constraint_jacobian")(q, t, p))]
        self._dyn = _Buffered(ca.Function("partitioning_dynamics", [w],
                                          [ca.densify(ca.vertcat(*out))]))

    def kinematics(self, q: np.ndarray, t: float):
        """C, C_q (dense), C_t at (q, t)."""
        nq, nc = self.nq, self.nc
        out = self._kin(q, (t,), self.model.p)
        return (out[:nc], out[nc:nc + nc * nq].reshape((nc, nq), order="F"),
                out[nc + nc * nq:])

    def dynamics(self, q: np.ndarray, v: np.ndarray, t: float):
        """M (dense), Q_e + Q_v, γ, C_q (dense) at (q, v, t)."""
        nq, nc = self.nq, self.nc
        out = self._dyn(q, v, (t,), self.model.p)
        m_mat = out[:nq * nq].reshape((nq, nq), order="F")
        k = nq * nq
        force, gamma = out[k:k + nq], out[k + nq:k + nq + nc]
        cq = out[k + nq + nc:].reshape((nc, nq), order="F")
        return m_mat, force, gamma, cq


class _Buffered:
    """A one-input, one-output dense Function called through ``Function.buffer``."""

    def __init__(self, function: ca.Function):
        self.function = function
        self._arg = np.zeros(function.nnz_in(0))
        self._res = np.zeros(function.nnz_out(0))
        self._buffer, self._trigger = function.buffer()
        self._buffer.set_arg(0, memoryview(self._arg))
        self._buffer.set_res(0, memoryview(self._res))

    def __call__(self, *pieces) -> np.ndarray:
        k = 0
        for piece in pieces:
            n = len(piece)
            self._arg[k:k + n] = piece
            k += n
        self._trigger()
        return self._res.copy()


def _solve(matrix: np.ndarray, rhs: np.ndarray, what: str, t: float) -> np.ndarray:
    """Dense LU solve (LAPACK gesv: far cheaper than scipy's wrappers for small matrices)."""
    try:
        x = np.linalg.solve(matrix, rhs)
    except np.linalg.LinAlgError as exc:
        raise _RhsError(f"{what} is singular at t = {t:g}") from exc
    if not np.all(np.isfinite(x)):
        raise _RhsError(f"{what} is singular at t = {t:g}")
    return x


def kkt_accelerations(m_mat: np.ndarray, cq: np.ndarray, force: np.ndarray,
                      gamma: np.ndarray) -> np.ndarray:
    """q̈ of the dense KKT system (eq. 6.205); minimum-norm least squares if it is singular.

    The same equations and fallback as :func:`casmbd.analysis.kkt.accelerations_and_multipliers`
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


# ---------------------------------------------------------------------------- partitioning
@dataclass
class Partition:
    """A split of the coordinates into dependent and independent ones."""

    independent: np.ndarray
    dependent: np.ndarray
    rows: np.ndarray
    condition: float

    @property
    def limit(self) -> float:
        """cond(C_q,d) beyond which the set is re-selected."""
        return max(min(COND_LIMIT, COND_GROWTH * self.condition), 10.0 * self.condition)

    def names(self, coordinate_names) -> list[str]:
        """Names of the independent coordinates."""
        return [coordinate_names[i] for i in self.independent]


def _full_pivoting(a: np.ndarray, rank: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column orders of Gaussian elimination with full pivoting (``rank`` steps)."""
    a = np.array(a, dtype=float)
    rows, cols = np.arange(a.shape[0]), np.arange(a.shape[1])
    for k in range(rank):
        sub = np.abs(a[k:, k:])
        i, j = np.unravel_index(int(np.argmax(sub)), sub.shape)
        i, j = i + k, j + k
        a[[k, i]] = a[[i, k]]
        rows[[k, i]] = rows[[i, k]]
        a[:, [k, j]] = a[:, [j, k]]
        cols[[k, j]] = cols[[j, k]]
        piv = a[k, k]
        if piv == 0.0:
            break
        a[k + 1:, k] /= piv
        a[k + 1:, k + 1:] -= np.outer(a[k + 1:, k], a[k, k + 1:])
    return rows, cols


def _block_condition(cq: np.ndarray, part: Partition) -> float:
    """cond₂ of the dependent block C_q,d (independent rows only)."""
    if part.dependent.size == 0:
        return 1.0
    with np.errstate(all="ignore"):
        c = float(np.linalg.cond(cq[np.ix_(part.rows, part.dependent)]))
    return c if np.isfinite(c) else np.inf


def select_partition(model, q: np.ndarray, t: float, rank: int | None = None) -> Partition:
    """Independent coordinates at (q, t) by LU with full pivoting of C_q (Wehage).

    ``rank`` (default: the numerical rank of C_q from
    :func:`~casmbd.analysis.redundancy.rank_report`) is the number of dependent coordinates;
    a re-selection passes the rank found at the start so that the state dimension stays fixed.
    """
    nq = model.nq
    if model.nc == 0:
        return Partition(np.arange(nq), np.zeros(0, int), np.zeros(0, int), 1.0)
    cq = model.constraint_jacobian(q, t).toarray()
    rank = rank_report(cq).rank if rank is None else int(rank)
    rows, cols = _full_pivoting(cq, rank)
    part = Partition(np.sort(cols[rank:]), np.sort(cols[:rank]), np.sort(rows[:rank]), 1.0)
    part.condition = _block_condition(cq, part)
    return part


def _length_indices(model) -> np.ndarray:
    return model.system.length_indices


class _Partitioned:
    """Right-hand side of the coordinate-partitioning ODE in y = (q_i, v_i)."""

    def __init__(self, sim, equations: _Equations, q0: np.ndarray, t0: float):
        self.sim = sim
        self.model = sim.model
        self.eq = equations
        self.nq = self.model.nq
        self.q = np.array(q0, dtype=float)      # warm start: the last dependent solution
        self.lengths = _length_indices(self.model)
        self.newton_iterations = 0
        self.set_partition(select_partition(self.model, self.q, t0))

    def set_partition(self, part: Partition) -> None:
        self.part = part
        self.dof = part.independent.size

    def condition(self, q: np.ndarray, t: float) -> float:
        """cond(C_q,d) at (q, t) for the current partition."""
        return _block_condition(self.eq.kinematics(q, t)[1], self.part)

    # -------------------------------------------------------------- kinematics
    def positions(self, qi: np.ndarray, t: float):
        """q with the given q_i and C(q, t) = 0, and C_q, C_t there (Newton, eq. 6.201).

        [C_q; I_d] δq = [−C; 0] forces δq_i = 0, so each iteration solves C_q,d δq_d = −C with
        the independent rows; warm start from the previous solution.
        """
        part = self.part
        q = self.q.copy()
        q[part.independent] = qi
        # residuals are lengths (or angles): tolerances relative to the mechanism's size
        scale = max(1.0, float(np.max(np.abs(q[self.lengths]), initial=0.0)))
        prev = np.inf
        for it in range(NEWTON_MAX_ITER + 1):
            c, cq, ct = self.eq.kinematics(q, t)
            c = c[part.rows]
            norm = float(np.max(np.abs(c), initial=0.0))
            if not np.isfinite(norm):
                raise _RhsError(f"non-finite constraints at t = {t:g}")
            # converged to round-off, or no more progress at a round-off-sized residual
            if norm <= NEWTON_RTOL * scale or (norm <= NEWTON_FLOOR * scale and
                                               norm > 0.5 * prev):
                self.q = q
                return q, cq, ct
            if it == NEWTON_MAX_ITER or (it >= 2 and norm >= prev):
                break
            q[part.dependent] += _solve(cq[np.ix_(part.rows, part.dependent)], -c,
                                        "the dependent block of C_q", t)
            prev = norm
            self.newton_iterations += 1
        raise _RhsError(f"dependent coordinates did not converge at t = {t:g} "
                        f"(max |C| = {norm:.3g})")

    def velocities(self, cq: np.ndarray, ct: np.ndarray, vi: np.ndarray, t: float) -> np.ndarray:
        """v with the given v_i and C_q v = −C_t: C_q,d v_d = −C_t − C_q,i v_i (eq. 6.202)."""
        part = self.part
        v = np.zeros(self.nq)
        v[part.independent] = vi
        if part.rows.size:
            block = cq[part.rows]
            cond = np.linalg.cond(block[:, part.dependent])
            if not cond <= part.limit:
                raise _RhsError(f"the dependent block of C_q is ill-conditioned at t = {t:g} "
                                f"(cond = {cond:.3g})")
            v[part.dependent] = _solve(block[:, part.dependent],
                                       -ct[part.rows] - block[:, part.independent] @ vi,
                                       "the dependent block of C_q", t)
        return v

    def expand(self, t: float, y: np.ndarray) -> np.ndarray:
        """Full [q; v] from y = (q_i, v_i)."""
        q, cq, ct = self.positions(y[:self.dof], t)
        return np.concatenate([q, self.velocities(cq, ct, y[self.dof:], t)])

    def reduce(self, x: np.ndarray) -> np.ndarray:
        """y = (q_i, v_i) of a full state, which becomes the warm start."""
        self.q = np.array(x[:self.nq], dtype=float)
        idx = self.part.independent
        return np.concatenate([x[:self.nq][idx], x[self.nq:][idx]])

    # -------------------------------------------------------------- ODE
    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        part = self.part
        q, cq, ct = self.positions(y[:self.dof], t)
        v = self.velocities(cq, ct, y[self.dof:], t)
        m_mat, force, gamma, cq = self.eq.dynamics(q, v, t)
        # the independent equations only: same q̈, and a regular KKT matrix with redundancy
        a = kkt_accelerations(m_mat, cq[part.rows], force, gamma[part.rows])
        if not np.all(np.isfinite(a)):
            raise _RhsError(f"non-finite accelerations at t = {t:g}")
        return np.concatenate([v[part.independent], a[part.independent]])


# ---------------------------------------------------------------------------- null space
def nullspace_solve(m_mat: np.ndarray, cq: np.ndarray, force: np.ndarray, gamma: np.ndarray,
                    rtol: float = RANK_RTOL) -> tuple[np.ndarray, int]:
    """q̈ of the embedded equations with an orthonormal SVD null-space basis, and rank(C_q).

    Rows of C_q (and γ) are equilibrated first: the null space and the solutions of
    C_q q̈ = γ do not change, and the rank test does not depend on the rows' units.
    """
    if cq.shape[0] == 0:
        return np.linalg.solve(m_mat, force), 0
    norms = np.linalg.norm(cq, axis=1)
    norms[norms == 0.0] = 1.0
    cq, gamma = cq / norms[:, None], gamma / norms
    u_mat, sigma, vt = np.linalg.svd(cq, full_matrices=True)
    smax = float(sigma[0]) if sigma.size else 0.0
    rank = int(np.sum(sigma > rtol * max(smax, 1e-300)))
    a_p = vt[:rank].T @ ((u_mat[:, :rank].T @ gamma) / sigma[:rank])
    basis = vt[rank:].T
    if basis.shape[1] == 0:
        return a_p, rank
    reduced_mass = basis.T @ m_mat @ basis
    z = np.linalg.solve(reduced_mass, basis.T @ (force - m_mat @ a_p))
    return a_p + basis @ z, rank


def nullspace_accelerations(model, q, v, t: float, u=None) -> np.ndarray:
    """q̈ of the null-space formulation at (q, v, t) from the model's (sparse) equations."""
    m_mat = model.mass_matrix(q).toarray()
    force = model.applied_forces(q, v, t, u) + model.quadratic_velocity_forces(q, v)
    if model.nc == 0:
        return nullspace_solve(m_mat, np.zeros((0, model.nq)), force, np.zeros(0))[0]
    return nullspace_solve(m_mat, model.constraint_jacobian(q, t).toarray(), force,
                           model.acceleration_rhs(q, v, t))[0]


class _Nullspace:
    """Right-hand side of the null-space ODE in x = (q, v)."""

    def __init__(self, sim, equations: _Equations):
        self.eq = equations
        self.nq = sim.model.nq
        self.rank = None

    def __call__(self, t: float, x: np.ndarray) -> np.ndarray:
        q, v = x[:self.nq], x[self.nq:]
        m_mat, force, gamma, cq = self.eq.dynamics(q, v, t)
        a, self.rank = nullspace_solve(m_mat, cq, force, gamma)
        if not np.all(np.isfinite(a)):
            raise _RhsError(f"non-finite accelerations at t = {t:g}")
        return np.concatenate([v, a])


# ---------------------------------------------------------------------------- driver
_FAILED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class _Run:
    """Output interval by output interval with one CVODES object per span length."""

    def __init__(self, sim, name, grid, x0, rtol, atol, max_steps):
        self.sim, self.model, self.nq = sim, sim.model, sim.model.nq
        self.name, self.rtol, self.atol, self.max_steps = name, rtol, atol, max_steps
        self.interval = float(grid[1] - grid[0])
        self.partitioning = sim.formulation_name == "partitioning"
        equations = _Equations(sim)
        self.reselections = 0
        if self.partitioning:
            self.ode = _Partitioned(sim, equations, x0[:self.nq], float(grid[0]))
            self.nx = 2 * self.ode.dof
        else:
            self.ode = _Nullspace(sim, equations)
            self.nx = 2 * self.nq
        self.callback = _RhsCallback("numeric_rhs_" + sim.formulation_name, self.nx,
                                     self.ode) if self.nx else None
        self.solvers: dict[int, ca.Function] = {}
        self.totals = {"steps": 0, "rhs_evaluations": 0, "jacobian_evaluations": 0,
                       "error_test_failures": 0, "nonlinear_iterations": 0}
        self.splits = 0

    # -------------------------------------------------------------- pieces
    def _solver(self, depth: int) -> ca.Function:
        if depth not in self.solvers:
            self.solvers[depth] = _integrator(self.callback, self.nx, self.name,
                                              self.interval / 2 ** depth, self.rtol, self.atol,
                                              self.max_steps)
        return self.solvers[depth]

    def _attempt(self, x: np.ndarray, t: float, depth: int) -> np.ndarray:
        """Integrate one span of length interval / 2**depth from (x, t); full state at its end."""
        t_end = t + self.interval / 2 ** depth
        y = self.ode.reduce(x) if self.partitioning else x
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
                raise _RhsError(f'{err} (CVode returned "{flag}")') from exc
            sys.stderr.write(captured.getvalue())
            _add_solver_stats(self.totals, solver.stats())
            y = np.asarray(res["xf"], dtype=float).reshape(-1)
        x_new = self.ode.expand(t_end, y) if self.partitioning else y
        if not np.all(np.isfinite(x_new)):
            raise _RhsError(f"non-finite state at t = {t_end:g}")
        return x_new

    def reselect(self, x: np.ndarray, t: float) -> None:
        """A fresh selection at (x, t); counted when the independent set changes."""
        ode = self.ode
        part = select_partition(self.model, x[:self.nq], t, ode.part.rows.size)
        if not np.array_equal(part.independent, ode.part.independent):
            self.reselections += 1
        ode.set_partition(part)

    def check(self, x: np.ndarray, t: float) -> None:
        """Re-select when cond(C_q,d) exceeds the partition's limit."""
        if self.partitioning and self.ode.part.rows.size:
            cond = self.ode.condition(x[:self.nq], t)
            if not cond <= self.ode.part.limit:
                self.reselect(x, t)

    def span(self, x: np.ndarray, t: float, depth: int = 0) -> np.ndarray:
        """One span; when it fails (partitioning only), re-select and do it in two halves."""
        try:
            return self._attempt(x, t, depth)
        except (RuntimeError, _RhsError) as exc:
            reraise_interrupt(exc)
            # the step limit is the user's: not a reason to re-select
            if not self.partitioning or depth >= MAX_SPLITS or "CV_TOO_MUCH_WORK" in str(exc):
                raise
        self.splits += 1
        self.reselect(x, t)
        half = self.interval / 2 ** (depth + 1)
        x_mid = self.span(x, t, depth + 1)
        self.check(x_mid, t + half)
        return self.span(x_mid, t + half, depth + 1)

    def stats(self, extra: dict) -> dict:
        stats = dict(self.totals)
        cb = self.callback
        stats["rhs_callback_evaluations"] = cb.calls if cb else 0
        stats["rhs_failures"] = cb.failures if cb else 0
        stats["interval_splits"] = self.splits
        if self.partitioning:
            stats["reselections"] = self.reselections
            stats["independent_coordinates"] = self.ode.part.names(
                self.sim.system.coordinate_names)
            stats["newton_iterations"] = self.ode.newton_iterations
            stats["dependent_condition"] = self.ode.part.condition
        else:
            stats["constraint_rank"] = self.ode.rank
        stats.update(extra)
        return stats


_FLAG = re.compile(r'returned "([A-Z_]+)"')


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
        except (RuntimeError, _RhsError, AssemblyError) as exc:
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
        run.check(x, t_next)
        xs.append(x)
    return np.vstack(xs), run.stats({})


def _key(name, grid, x0, rtol, atol, max_steps) -> tuple:
    return (name, np.asarray(grid, float).tobytes(), np.asarray(x0, float).tobytes(), rtol,
            atol, max_steps)


def integrate(sim, name: str, grid, x0, rtol: float, atol: float, max_steps: int,
              projection: bool = False) -> tuple[np.ndarray, dict]:
    """Integrate the ``partitioning`` or ``nullspace`` formulation of ``sim`` on ``grid``.

    Parameters
    ----------
    sim : casmbd.analysis.simulate.Simulator
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
