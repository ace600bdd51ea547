"""A system seen through an independent subset of its constraint equations.

Seed 002 ("Redundant constraint equations"): a revolute joint closing a spatial loop may write
five equations of which only two are independent; the KKT matrix is then singular and the
Schur complement C_q M⁻¹ C_qᵀ cannot be factorised.  Removing the dependent rows (found by the
rank-revealing factorisation of :mod:`casmbd.analysis.instant.redundancy` at the assembled
configuration) leaves a full-rank set with the same solution set near that configuration, so the
formulations that need a regular KKT matrix (``kkt_ode``, ``index1``, ``ggl``) can run.

:class:`ConstraintSubset` exposes the kept rows of C, C_q, C_t and γ under the names the
formulations use and delegates everything else (M, Q_e, Q_v, outputs) to the full
:class:`~casmbd.system.equations.System`.  Post-processing keeps working on the full system, so
results list every equation; the multipliers of the full set are then the minimum-norm ones and
the reactions that depend on the split are flagged as undetermined
(:mod:`casmbd.analysis.instant.undetermined_reactions`).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import casadi as ca

from casmbd.errors import ModelError


class ConstraintSubset:
    """The rows ``keep`` of a system's constraint equations; all else is the system's.

    Parameters
    ----------
    system : System
    keep : sequence of int
        Row indices of C to keep, increasing.
    """

    def __init__(self, system, keep: Sequence[int]):
        keep = [int(i) for i in keep]
        if any(i < 0 or i >= system.nc for i in keep) or keep != sorted(set(keep)):
            raise ModelError(f"constraint subset: rows {keep} are not increasing indices below "
                             f"{system.nc}")
        self._system = system
        self.keep = keep
        self.removed = [i for i in range(system.nc) if i not in set(keep)]

    def __getattr__(self, name):
        return getattr(self._system, name)

    @property
    def full(self):
        """The full system."""
        return self._system

    @property
    def nc(self) -> int:
        return len(self.keep)

    @property
    def constraint_labels(self) -> list:
        labels = self._system.constraint_labels
        return [labels[i] for i in self.keep]

    @property
    def velocity_rows(self) -> list[int]:
        """The kept rows written at the velocity level, as indices of the subset."""
        vel = set(self._system.velocity_rows)
        return [k for k, i in enumerate(self.keep) if i in vel]

    @property
    def holonomic_rows(self) -> list[int]:
        vel = set(self.velocity_rows)
        return [k for k in range(self.nc) if k not in vel]

    @cached_property
    def position_jacobian(self) -> ca.SX:
        return self._system.position_jacobian[self.keep, :]

    @cached_property
    def constraints(self) -> ca.SX:
        return self._system.constraints[self.keep]

    @cached_property
    def constraint_jacobian(self) -> ca.SX:
        return self._system.constraint_jacobian[self.keep, :]

    @cached_property
    def constraint_time_derivative(self) -> ca.SX:
        return self._system.constraint_time_derivative[self.keep]

    @cached_property
    def acceleration_rhs(self) -> ca.SX:
        return self._system.acceleration_rhs[self.keep]

    def minimum_norm_multipliers(self, lam: ca.SX) -> ca.SX:
        """The multipliers of every row (n_c of the full system) with the constraint force of
        the kept rows' ``lam`` and the least norm.  With C_q = [C_k; C_d] and the removed rows
        dependent, C_d = E C_k with E = (C_d C_kᵀ)(C_k C_kᵀ)⁻¹, C_qᵀ λ = C_kᵀ (λ_k + Eᵀ λ_d) is
        the force C_kᵀ lam when λ_k = lam − Eᵀ λ_d; the least |λ|² gives
        λ_d = (I + E Eᵀ)⁻¹ E lam (the distribution the post-processing reports, e.g. the four
        corners of a box on the floor carrying a quarter of its weight each)."""
        full = [ca.SX(0.0)] * self._system.nc
        if not self.removed:
            for k, row in enumerate(self.keep):
                full[row] = lam[k]
            return ca.vertcat(*full) if full else ca.SX(0, 1)
        jac = self._system.constraint_jacobian
        c_k, c_d = jac[self.keep, :], jac[self.removed, :]
        e_mat = ca.solve(ca.mtimes(c_k, c_k.T), ca.mtimes(c_k, c_d.T)).T
        lam_d = ca.solve(ca.SX.eye(len(self.removed)) + ca.mtimes(e_mat, e_mat.T),
                         ca.mtimes(e_mat, lam))
        lam_k = lam - ca.mtimes(e_mat.T, lam_d)
        for k, row in enumerate(self.keep):
            full[row] = lam_k[k]
        for k, row in enumerate(self.removed):
            full[row] = lam_d[k]
        return ca.vertcat(*full)

    def friction_normals_of(self, lam: ca.SX) -> ca.SX:
        """N of reaction-proportional friction from the kept rows' multipliers ``lam``, with
        the minimum-norm distribution over every row (:meth:`minimum_norm_multipliers`): a
        statically indeterminate set of closed contacts shares its load as the reported
        reactions do, not as the independent subset would (which made one corner of a sliding
        box pull and its friction too large)."""
        return self._system.friction_normals_of(self.minimum_norm_multipliers(lam))
