"""A system seen through an independent subset of its constraint equations.

Seed 002 ("Redundant constraint equations"): a revolute joint closing a spatial loop may write
five equations of which only two are independent; the KKT matrix is then singular and the
Schur complement C_q M⁻¹ C_qᵀ cannot be factorised.  Removing the dependent rows (found by the
rank-revealing factorisation of :mod:`casmbd.analysis.redundancy` at the assembled
configuration) leaves a full-rank set with the same solution set near that configuration, so the
formulations that need a regular KKT matrix (``kkt_ode``, ``index1``, ``ggl``) can run.

:class:`ConstraintSubset` exposes the kept rows of C, C_q, C_t and γ under the names the
formulations use and delegates everything else (M, Q_e, Q_v, outputs) to the full
:class:`~casmbd.system.equations.System`.  Post-processing keeps working on the full system, so
results list every equation; the multipliers of the full set are then the minimum-norm ones and
the reactions that depend on the split are flagged as undetermined
(:mod:`casmbd.analysis.reactions`).
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
