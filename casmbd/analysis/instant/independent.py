"""Redundant constraint equations in every analysis: found, removed, named (as Adams does).

Seed 002 ("Redundant constraint equations"): a closed loop may write more equations than it
imposes conditions — a Cardan shaft on two revolute bearings writes 5 + 4 + 5 = 14 joint
equations for the 11 conditions that leave one degree of freedom.  C_q is then rank deficient
everywhere, the KKT matrix and C_qᵀ are singular and the multipliers are not unique.

The analyses that solve with C_q (kinematics, inverse dynamics, statics, linearize) therefore

1. find the dependent rows of C_q at the assembled start pose, in declaration order
   (:func:`casmbd.analysis.instant.redundancy.rank_report`, as ``info`` does: the later of two
   equivalent equations is named);
2. run on the independent rows only (:class:`IndependentRows`, the numeric counterpart of
   :class:`casmbd.system.subset.ConstraintSubset`): near the start pose they have the same
   solution set, and C_q of the kept rows has full row rank, so every solve is regular;
3. name the removed equations in the result (``stats["redundant_equations"]``,
   ``stats["redundancy"]``);
4. give the multipliers of the full set as the minimum-norm ones (:func:`minimum_norm`):
   λ of the kept rows, scattered into the full set with zeros on the removed rows, solves
   C_qᵀ λ = f; so does every λ + N z (C_qᵀ N = 0), and λ − N Nᵀ λ is the one of least norm
   (seed 002's orthogonalisation).  The reaction components N cannot change are determined
   and come out exactly; the others are the minimum-norm distribution of the self-stress
   (:func:`casmbd.analysis.instant.undetermined_reactions.flag_undetermined`,
   ``stats["reactions"]``).

Options (``redundancy=``), as for :func:`casmbd.analysis.dynamics.simulate.plan_redundancy`:
``"auto"`` and ``"remove"`` remove the dependent rows (these analyses solve with a regular
C_q only); ``"minimum_norm"`` — keeping every equation in the solves — is the simulation
formulations' alternative and is refused here with that explanation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from casmbd.analysis.instant.redundancy import rank_report
from casmbd.analysis.instant.undetermined_reactions import multiplier_null_space
from casmbd.errors import AnalysisError, RedundantConstraintError

__all__ = ["REDUNDANCY_OPTIONS", "IndependentRows", "RowPlan", "check_option",
           "check_removed", "find_redundant", "minimum_norm", "scatter"]

#: a removed equation whose residual exceeds this, times max(1, the largest |length
#: coordinate|), is not implied by the kept ones (the linearize check of a given q)
REMOVED_RESIDUAL_RTOL = 1e-8

REDUNDANCY_OPTIONS = ("auto", "remove", "minimum_norm")


def check_option(option: str, analysis: str) -> None:
    """Refuse an unknown option, and ``"minimum_norm"`` (the solves here need a regular C_q)."""
    if option not in REDUNDANCY_OPTIONS:
        raise AnalysisError(f"{analysis}: redundancy must be one of "
                            f"{', '.join(REDUNDANCY_OPTIONS)}, got {option!r}")
    if option == "minimum_norm":
        raise AnalysisError(
            f"{analysis}: redundancy='minimum_norm' (keep every equation) is an option of "
            f"simulate's formulations; {analysis} solves with a regular constraint Jacobian and "
            f"removes the redundant equations (redundancy='auto' or 'remove'); its "
            f"multipliers and reactions are the minimum-norm ones either way")


@dataclass
class RowPlan:
    """The dependent rows of C_q at one pose and the rows kept.

    Attributes
    ----------
    kept_rows, removed_rows : list of int
        Row indices of the full C (increasing).
    redundant_equations : list of str
        Labels of the removed rows (``"joint 'out_bearing' equation 'y'"``).
    constraint_rank : int
        rank C_q at the pose.
    """

    kept_rows: list[int]
    removed_rows: list[int] = field(default_factory=list)
    redundant_equations: list[str] = field(default_factory=list)
    constraint_rank: int = 0

    @property
    def removes(self) -> bool:
        """Whether any row is removed."""
        return bool(self.removed_rows)

    def stats(self) -> dict:
        """What the result says: the removed equations, what was done and the rank."""
        return {"redundant_equations": list(self.redundant_equations),
                "redundancy": "removed" if self.removes else "none",
                "constraint_rank": int(self.constraint_rank)}


def find_redundant(model, q: np.ndarray, t: float) -> RowPlan:
    """The dependent rows of C_q(q, t) in declaration order (``info``'s sweep) and the rest."""
    if model.nc == 0:
        return RowPlan([], constraint_rank=0)
    rep = rank_report(model.constraint_jacobian(q, t))
    removed = list(rep.dependent_rows)
    labels = model.constraint_labels
    gone = set(removed)
    return RowPlan([i for i in range(model.nc) if i not in gone], removed,
                   [str(labels[i]) for i in removed], rep.rank)


class IndependentRows:
    """A :class:`~casmbd.compiled.model.NumericModel` seen through the rows ``keep`` of C.

    C, C_q, C_t and γ (and ``nc``, ``constraint_labels``) are those of the kept rows; every
    other attribute is the model's (M, Q_e, outputs, reactions, the compiled Functions), so
    nothing is rebuilt.  ``full`` is the model itself.
    """

    def __init__(self, model, keep):
        self._model = model
        self.keep = [int(i) for i in keep]

    def __getattr__(self, name):
        return getattr(self._model, name)

    @property
    def full(self):
        """The model with every equation."""
        return self._model

    @property
    def nc(self) -> int:
        return len(self.keep)

    @property
    def constraint_labels(self) -> list:
        labels = self._model.constraint_labels
        return [labels[i] for i in self.keep]

    @property
    def velocity_rows(self) -> list[int]:
        """The kept rows written at the velocity level, as indices of the kept rows."""
        vel = set(getattr(self._model, "velocity_rows", ()))
        return [k for k, i in enumerate(self.keep) if i in vel]

    @property
    def holonomic_rows(self) -> list[int]:
        vel = set(self.velocity_rows)
        return [k for k in range(len(self.keep)) if k not in vel]

    def constraints(self, q, t: float) -> np.ndarray:
        return self._model.constraints(q, t)[self.keep]

    def constraint_jacobian(self, q, t: float):
        return self._model.constraint_jacobian(q, t)[self.keep, :]

    def constraint_time_derivative(self, q, t: float) -> np.ndarray:
        return self._model.constraint_time_derivative(q, t)[self.keep]

    def acceleration_rhs(self, q, v, t: float) -> np.ndarray:
        return self._model.acceleration_rhs(q, v, t)[self.keep]


def scatter(values: np.ndarray, rows, size: int) -> np.ndarray:
    """A vector (or rows of a matrix, along the last axis) of ``size`` zeros with ``values``
    at ``rows``."""
    values = np.asarray(values, dtype=float)
    out = np.zeros((*values.shape[:-1], size))
    out[..., list(rows)] = values
    return out


def minimum_norm(jacobian, lam: np.ndarray) -> np.ndarray:
    """λ − N Nᵀ λ: the multipliers of least norm among λ + N z, C_qᵀ N = 0 (N orthonormal,
    :func:`casmbd.analysis.instant.undetermined_reactions.multiplier_null_space`).  Equal to λ
    when C_q has full row rank."""
    null = multiplier_null_space(jacobian)
    lam = np.asarray(lam, dtype=float)
    return lam - null @ (null.T @ lam) if null.shape[1] else lam.copy()


def check_removed(model, plan: RowPlan, q: np.ndarray, t: float, what: str) -> None:
    """Raise :class:`~casmbd.errors.RedundantConstraintError` when a removed equation does not
    hold at (q, t).

    Rows that depend on others at the start pose are consequences of them only if the
    dependence persists: two drivers on one coordinate, θ = t and θ = 2t, agree at t = 0 and
    contradict afterwards.  The removed rows are therefore checked wherever the analysis
    reports a configuration, and a violation is named — never a result that silently
    ignores an equation.
    """
    if not plan.removes:
        return
    resid = np.abs(model.constraints(q, t)[plan.removed_rows])
    lengths = getattr(model, "length_indices", [])
    tol = REMOVED_RESIDUAL_RTOL * max(1.0, float(np.max(np.abs(q[lengths]), initial=0.0)))
    bad = [k for k, r in enumerate(resid) if not r <= tol]
    if bad:
        labels = model.constraint_labels
        rows = [plan.removed_rows[k] for k in bad]
        text = ", ".join(f"{labels[i]} (residual {resid[k]:.3g})"
                         for k, i in zip(bad, rows, strict=True))
        raise RedundantConstraintError(
            f"{what} at t = {t:g}: the equations removed as redundant at the start are "
            f"violated: {text}; they are not consequences of the others (contradicting "
            f"drivers or joints); make the mechanism consistent or remove them",
            [(labels[i].element, labels[i].label) for i in rows])
