"""The ``partitioning`` formulation: forward dynamics in independent coordinates.

Its right-hand side is evaluated numerically (numpy around the compiled model equations,
:mod:`casmbd.analysis.integrators.numeric_rhs`) and integrated by SUNDIALS CVODES output interval
by output
interval (:mod:`casmbd.analysis.dynamics.numeric_run`); between intervals the independent set may be
re-selected and, with ``projection=True``, q is assembled and v projected mass-orthogonally.
The null-space formulation, the other numeric one, is :mod:`casmbd.analysis.formulations.nullspace`.

Generalized coordinate partitioning (Wehage; seed 000, "Elimination of Lagrange multipliers" and
"Algorithm and sparse matrix implementation", eqs. 6.200–6.205)
-----------------------------------------------------------------------------------------
*Selection.*  Gaussian elimination with full (complete) pivoting on the dense C_q: at step k the
entry of largest magnitude in the remaining block is swapped into the pivot position (row and
column exchange).  After r = rank(C_q) steps the r pivot columns give a square, well-conditioned
block C_q,d; their coordinates are the *dependent* ones, the n_q − r columns never chosen as
pivots are the *independent* coordinates q_i, and the r pivot rows are the independent
equations (the other rows are redundant and are dropped).  The rank comes from
:func:`casmbd.analysis.instant.redundancy.rank_report` (SVD of the equilibrated Jacobian), so
redundant constraints are handled.

*State and right-hand side.*  The ODE state is y = (q_i, v_i).  At each evaluation

1. q_i is set and the dependent q_d solved from C(q, t) = 0 by Newton-Raphson, warm-started
   from the previous solution.  The matrix of eq. 6.201, [C_q; I_d] δq = [−C; 0], forces
   δq_i = 0, so each iteration is the dense LU solve C_q,d δq_d = −C (independent rows);
2. the dependent velocities from the same block at the converged q (eqs. 6.202–6.204):
   C_q,d v_d = −C_t − C_q,i v_i;
3. q̈ from the KKT system of eq. 6.205 with the independent rows (:func:`kkt_accelerations`:
   the equations and minimum-norm fallback of
   :func:`casmbd.analysis.instant.kkt.accelerations_and_multipliers`, dense), and (v_i, q̈_i) is
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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casmbd.analysis.formulations.nullspace import nullspace_accelerations, nullspace_solve
from casmbd.analysis.instant.redundancy import rank_report
from casmbd.analysis.integrators.numeric_rhs import (
    Equations,
    NumericOde,
    RhsError,
    kkt_accelerations,
)
from casmbd.analysis.integrators.numeric_rhs import solve_dense as _solve

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
    :func:`~casmbd.analysis.instant.redundancy.rank_report`) is the number of dependent coordinates;
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
    return model.length_indices


class _Partitioned(NumericOde):
    """Right-hand side of the coordinate-partitioning ODE in y = (q_i, v_i)."""

    max_splits = MAX_SPLITS

    def __init__(self, sim, equations: Equations, q0: np.ndarray, t0: float):
        self.sim = sim
        self.model = sim.model
        self.eq = equations
        self.nq = self.model.nq
        self.q = np.array(q0, dtype=float)      # warm start: the last dependent solution
        self.lengths = _length_indices(self.model)
        self.newton_iterations = 0
        self.reselections = 0
        self.set_partition(select_partition(self.model, self.q, t0))
        self.nx = 2 * self.dof

    def set_partition(self, part: Partition) -> None:
        self.part = part
        self.dof = part.independent.size

    def condition(self, q: np.ndarray, t: float) -> float:
        """cond(C_q,d) at (q, t) for the current partition."""
        return _block_condition(self.eq.kinematics(q, t)[1], self.part)

    def reselect(self, x: np.ndarray, t: float) -> None:
        """A fresh selection at (x, t); counted when the independent set changes."""
        part = select_partition(self.model, x[:self.nq], t, self.part.rows.size)
        if not np.array_equal(part.independent, self.part.independent):
            self.reselections += 1
        self.set_partition(part)

    def check(self, x: np.ndarray, t: float) -> None:
        """Re-select when cond(C_q,d) exceeds the partition's limit."""
        if self.part.rows.size:
            cond = self.condition(x[:self.nq], t)
            if not cond <= self.part.limit:
                self.reselect(x, t)

    def stats(self, coordinate_names) -> dict:
        return {"reselections": self.reselections,
                "independent_coordinates": self.part.names(coordinate_names),
                "newton_iterations": self.newton_iterations,
                "dependent_condition": self.part.condition}

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
                raise RhsError(f"non-finite constraints at t = {t:g}")
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
        raise RhsError(f"dependent coordinates did not converge at t = {t:g} "
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
                raise RhsError(f"the dependent block of C_q is ill-conditioned at t = {t:g} "
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
            raise RhsError(f"non-finite accelerations at t = {t:g}")
        return np.concatenate([v[part.independent], a[part.independent]])


def right_hand_side(sim, equations: Equations, x0, t0: float) -> _Partitioned:
    """The numeric ODE of the ``partitioning`` kind
    (:class:`casmbd.analysis.formulations.Partitioning`) for the simulator ``sim``."""
    return _Partitioned(sim, equations, np.asarray(x0, float)[:sim.model.nq], t0)


__all__ = ["Partition", "kkt_accelerations", "nullspace_accelerations", "nullspace_solve",
           "right_hand_side", "select_partition"]
