"""The statics problem: the equations F(q, λ) = [Q_e − C_qᵀλ; C] = 0 evaluated on a model.

Seed 000, "Static analysis" (eqs. 6.227–6.235): with velocities and accelerations zero the
equations of motion reduce to Q_e(q, 0, t) − C_qᵀ λ = 0, C(q, t) = 0.  :class:`StaticsProblem`
evaluates them (residual, sparse Jacobian, the applied forces, least-squares multipliers, the
tangent space N of ker C_q in scaled coordinates with the stiffness K̄ = Nᵀ K N) on the compiled
functions of :func:`~casmbd.analysis.statics.statics.statics_functions`, optionally on the
independent constraint rows only; :class:`Iterate` is one iterate (q, λ, F) of the search, and
:func:`principal_range` brings the angles of a solution to (−π, π].
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from casmbd.analysis.instant.independent import IndependentRows, scatter
from casmbd.analysis.instant.redundancy import null_space_basis
from casmbd.analysis.statics.trust_region import RANK_RTOL
from casmbd.compiled.model import NumericModel
from casmbd.model.forces import ForceElement
from casmbd.system.descriptions import SpatialNatural

__all__ = ["Iterate", "StaticsProblem", "null_space", "principal_range", "wrap"]

#: coordinate names that are angles (reduced to the principal range)
_ANGLE_NAMES = ("angle", "angle1", "angle2")


class StaticsProblem:
    """Numeric evaluation of the statics equations on a :class:`NumericModel`."""

    def __init__(self, model: NumericModel, t: float):
        self.model, self.t = model, t
        self.nq, self.nc = model.nq, model.nc
        self.keep: list[int] | None = None  # all rows, unless :meth:`restrict`ed
        names = model.coordinate_names
        self.labels = ([f"equilibrium of coordinate '{n}'" for n in names]
                       + [str(lab) for lab in model.constraint_labels])
        self.length_idx = model.length_indices
        pos = np.array([np.ravel(b.position) for b in model.mechanism.bodies.values()]
                       or [np.zeros(model.dimension)], float)
        #: the size of the mechanism: lengths are measured in it by the trust region
        self.size = max(float(np.max(np.ptp(pos, axis=0))), float(np.max(np.abs(pos))), 1e-3)
        self.scale = np.ones(self.nq)
        self.scale[self.length_idx] = self.size
        #: every applied force keeps its work in V, but for a damper part that vanishes at rest:
        #: a descent step is then measured by the exact fall of V, not by the trapezoidal
        #: work of the forces, which misjudges long steps across a stiff spring
        mech = model.mechanism
        self.conservative = not mech.actuators and all(
            f.energy_exchange() is None
            or (f.energy_exchange() == "damper" and type(f).potential is not ForceElement.potential)
            for f in mech.forces.values())
        self.angles, self.quaternions, self.frames = [], [], []
        for body, desc in model.descriptions.items():
            base = model.coordinate_index[body]
            natural = "Natural" in type(desc).__name__
            for k, name in enumerate(desc.names):
                if name in _ANGLE_NAMES and not natural:
                    self.angles.append(base + k)
                if name == "e0" and tuple(desc.names[k:k + 4]) == ("e0", "e1", "e2", "e3"):
                    self.quaternions.append(base + k)
            if isinstance(desc, SpatialNatural):
                self.frames.append((body, base + 3))

    def potential(self, q: np.ndarray) -> float:
        """V(q) at the problem's time."""
        return float(self.model.potential_energy(q, self.t))

    def restrict(self, keep: list[int]) -> None:
        """Solve with the constraint rows ``keep`` only (the redundant ones removed,
        :mod:`casmbd.analysis.instant.independent`): λ has their size, the residual and the KKT
        Jacobian their rows, so that the Newton matrix is regular."""
        self.full = self.model
        self.model = IndependentRows(self.model, keep)
        self.keep, self.nc = list(keep), len(keep)
        self._rows = np.concatenate([np.arange(self.nq), self.nq + np.asarray(keep, int)])
        self.labels = [self.labels[i] for i in self._rows]

    def _lam(self, lam) -> np.ndarray:
        return lam if self.keep is None else scatter(lam, self.keep, self.full.nc)

    def forces(self, q) -> np.ndarray:
        return self.model.vector("statics_forces", q, self.t, self.model.p)

    def residual(self, q, lam) -> np.ndarray:
        f = self.model.vector("statics_residual", q, self._lam(lam), self.t, self.model.p)
        return f if self.keep is None else f[self._rows]

    def jacobian(self, q, lam) -> sp.csc_matrix:
        jac = self.model.sparse("statics_jacobian", q, self._lam(lam), self.t, self.model.p)
        return jac if self.keep is None else jac[self._rows, :][:, self._rows]

    def cq(self, q) -> np.ndarray:
        if self.nc == 0:
            return np.zeros((0, self.nq))
        return self.model.constraint_jacobian(q, self.t).toarray()

    def multipliers(self, q, rhs: np.ndarray | None = None) -> np.ndarray:
        """Least-squares λ of C_qᵀλ = Q_e (or = ``rhs``), with the rank cut-off."""
        if self.nc == 0:
            return np.zeros(0)
        lam, *_ = sla.lstsq(self.cq(q).T, self.forces(q) if rhs is None else rhs,
                            cond=RANK_RTOL, lapack_driver="gelsd")
        return lam

    def improper(self, q) -> str | None:
        """The first natural-coordinate body whose [u v w] is not a proper rotation."""
        for body, k in self.frames:
            if np.linalg.det(np.reshape(q[k:k + 9], (3, 3))) <= 0.0:  # rows u, v, w
                return body
        return None

    def tangent(self, q, lam):
        """(N, K, g, K̄) with N a basis of ker C_q orthonormal in the scaled coordinates."""
        cq = self.cq(q)
        ns = null_space_basis(cq * self.scale)[0] if self.nc else np.eye(self.nq)
        n = self.scale[:, None] * ns
        k = -self.jacobian(q, lam)[:self.nq, :self.nq].toarray()
        return n, k, n.T @ self.forces(q), n.T @ k @ n

    def worst(self, f: np.ndarray, count: int = 3) -> str:
        order = [i for i in np.argsort(-np.abs(f))[:count] if f[i] != 0] or [0]
        return "; ".join(f"{self.labels[i]} residual {f[i]:.3g}" for i in order)


def null_space(cq: np.ndarray, nq: int) -> np.ndarray:
    """Orthonormal basis of ker C_q (shared rank tolerance of :mod:`redundancy`)."""
    if cq.shape[0] == 0:
        return np.eye(nq)
    return null_space_basis(cq)[0]


def wrap(angle: float) -> float:
    """The angle in (−π, π]."""
    return float(angle - 2.0 * np.pi * np.ceil((angle - np.pi) / (2.0 * np.pi)))


def principal_range(prob: StaticsProblem, q, lam, fscale: float, lscale: float) -> np.ndarray:
    """Angles to (−π, π], Euler parameters to e0 ≥ 0 — each only if the equations do not
    change (by more than the convergence tolerance): an angle that carries a rotational
    spring or a driver keeps its value."""
    f0 = prob.residual(q, lam)
    for k in prob.angles + prob.quaternions:
        trial = q.copy()
        if k in prob.quaternions:
            block = trial[k:k + 4]
            lead = block[np.flatnonzero(np.abs(block) > 0.0)[:1]]
            if block[0] > 0.0 or (block[0] == 0.0 and np.all(lead >= 0.0)):
                continue
            trial[k:k + 4] = -block
        else:
            if -np.pi < q[k] <= np.pi:
                continue
            trial[k] = wrap(q[k])
        diff = np.abs(prob.residual(trial, lam) - f0)
        if np.max(diff[:prob.nq], initial=0.0) <= fscale and \
                np.max(diff[prob.nq:], initial=0.0) <= lscale:
            q = trial
    return q


class Iterate:
    """An iterate (q, λ, F) with the scaled residual norm that the Newton test compares."""

    def __init__(self, prob: StaticsProblem, q, lam, fscale: float, lscale: float):
        self.q, self.lam = q, lam
        self.f = prob.residual(q, lam)
        self.qe = prob.forces(q)
        w = np.concatenate([np.full(prob.nq, 1.0 / fscale), np.full(prob.nc, 1.0 / lscale)])
        self.norm = float(np.linalg.norm(self.f * w))
