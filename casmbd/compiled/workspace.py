"""Workspace of a compiled numeric model: the buffers and per-run state of its evaluations.

Like Pinocchio's ``Data`` next to its ``Model`` and MuJoCo's ``mjData`` next to ``mjModel``,
a :class:`Workspace` holds what changes while an analysis runs — the numpy arrays bound to the
inputs and outputs of each Function — and :class:`~casmbd.compiled.model.NumericModel` holds
what is fixed (Functions, sizes, names, parameter values).  The equations are evaluated
here, Pinocchio style (``data.mass_matrix(q)`` at the model's ``p``, as ``aba(model, data,
…)``); the model's same-named methods evaluate through its own workspace
:attr:`NumericModel.data <casmbd.compiled.model.NumericModel.data>`.  Two runs that must not
share buffers (two analyses of one model, two threads) each take their own workspace from
:meth:`NumericModel.workspace <casmbd.compiled.model.NumericModel.workspace>`; an analysis
runs on :meth:`NumericModel.with_data <casmbd.compiled.model.NumericModel.with_data>` (the
model evaluating through it), which the analyses given a NumericModel do at their entry.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from casmbd.compiled.buffered import BufferedFunction
from casmbd.lazy import lazy_module

sp = lazy_module("scipy.sparse")

if TYPE_CHECKING:  # annotations only: the model module imports this one
    from casmbd.compiled.model import NumericModel

__all__ = ["Workspace"]


class Workspace:
    """Evaluation buffers of one :class:`~casmbd.compiled.model.NumericModel`.

    Parameters
    ----------
    model : NumericModel
        The model whose Functions are evaluated; buffers are made on first use of each.

    Notes
    -----
    Each Function is called through a :class:`~casmbd.compiled.buffered.BufferedFunction`
    (``Function.buffer()``: numpy arrays bound to the inputs and outputs, which avoids the
    conversion of every argument to a CasADi matrix, 50–150 µs a call from Python against
    0.1–3 µs for the compiled code itself; docs/performance.md).  The arrays are reused from
    call to call, so a workspace serves one caller at a time; what it returns are copies,
    valid after the next call.
    """

    def __init__(self, model: NumericModel):
        self.model = model
        self._entries: dict[str, tuple] = {}

    def _entry(self, name: str) -> tuple:
        entry = self._entries.get(name)
        if entry is None:
            f = BufferedFunction(self.model.function(name))
            sparsity = f.function.sparsity_out(0)
            pattern = (np.asarray(sparsity.row(), dtype=np.int32),
                       np.asarray(sparsity.colind(), dtype=np.int32), sparsity.shape,
                       sparsity.is_dense())
            entry = (f, pattern)
            self._entries[name] = entry
        return entry

    @property
    def evaluated(self) -> list[str]:
        """Names of the Functions evaluated through this workspace (their buffers made)."""
        return list(self._entries)

    def nonzeros(self, name: str, *args) -> np.ndarray:
        """Non-zeros of output 0 of Function ``name`` at ``args`` (a copy)."""
        return self._entry(name)[0](*args)

    def vector(self, name: str, *args) -> np.ndarray:
        """Output 0 of Function ``name`` as a dense flat array."""
        nz = self.nonzeros(name, *args)
        rows, _, shape, dense = self._entries[name][1]
        if dense:
            return nz
        out = np.zeros(shape[0] * shape[1])
        out[rows] = nz
        return out

    def sparse(self, name: str, *args) -> sp.csc_matrix:
        """Output 0 of Function ``name`` as a CSC matrix of its fixed sparsity pattern."""
        nz = self.nonzeros(name, *args)
        rows, colind, shape, _ = self._entries[name][1]
        return sp.csc_matrix((nz, rows, colind), shape=shape)

    # ------------------------------------------------------------------ equations
    # (eq. numbers: /work/shared/seeds/000 planar constrained dynamics; p: the model's values)
    def constraints(self, q, t: float) -> np.ndarray:
        """C(q, t)."""
        return self.vector("constraints", q, t, self.model.p)

    def constraint_jacobian(self, q, t: float) -> sp.csc_matrix:
        """C_q(q, t) as a sparse matrix."""
        return self.sparse("constraint_jacobian", q, t, self.model.p)

    def constraint_time_derivative(self, q, t: float) -> np.ndarray:
        """C_t(q, t)."""
        return self.vector("constraint_time_derivative", q, t, self.model.p)

    def acceleration_rhs(self, q, v, t: float) -> np.ndarray:
        """γ(q, v, t) with C_q q̈ = γ."""
        return self.vector("acceleration_rhs", q, v, t, self.model.p)

    def mass_matrix(self, q) -> sp.csc_matrix:
        """M(q) as a sparse matrix."""
        return self.sparse("mass_matrix", q, self.model.p)

    def applied_forces(self, q, v, t: float, u=None) -> np.ndarray:
        """Q_e(q, v, t, u) (u = 0 when not given)."""
        u = np.zeros(self.model.nu) if u is None else u
        return self.vector("applied_forces", q, v, t, u, self.model.p)

    def input_matrix(self, q, v, t: float, u=None) -> sp.csc_matrix:
        """B = ∂Q_e/∂u (n_q × n_u)."""
        u = np.zeros(self.model.nu) if u is None else u
        return self.sparse("input_matrix", q, v, t, u, self.model.p)

    def kinetic_energy(self, q, v) -> float:
        """T = ½ vᵀ M v."""
        return float(self.vector("kinetic_energy", q, v, self.model.p)[0])

    def potential_energy(self, q, t: float) -> float:
        """V(q, t) of gravity and springs."""
        return float(self.vector("potential_energy", q, t, self.model.p)[0])

    def quadratic_velocity_forces(self, q, v) -> np.ndarray:
        """Q_v(q, v)."""
        return self.vector("quadratic_velocity_forces", q, v, self.model.p)
