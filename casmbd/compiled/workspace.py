"""Workspace of a compiled numeric model: the buffers and per-run state of its evaluations.

Like Pinocchio's ``Data`` next to its ``Model`` and MuJoCo's ``mjData`` next to ``mjModel``,
a :class:`Workspace` holds what changes while an analysis runs — the numpy arrays bound to the
inputs and outputs of each Function — and :class:`~casmbd.compiled.model.NumericModel` holds
what is fixed (Functions, sizes, names, parameter values).  Two runs that must not share
buffers (two threads, or a run nested in another) each take their own workspace from
:meth:`NumericModel.workspace <casmbd.compiled.model.NumericModel.workspace>`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

if TYPE_CHECKING:  # annotations only: the model module imports this one
    from casmbd.compiled.model import NumericModel

__all__ = ["Workspace", "buffered"]


def buffered(f, inputs: list[np.ndarray]) -> tuple:
    """Zero-copy evaluation of CasADi Function ``f`` through ``Function.buffer()``.

    ``inputs`` are float64 arrays of ``f.nnz_in(i)`` entries, bound (not copied) to the
    inputs; returns ``(trigger, outputs)``: calling ``trigger()`` runs ``f`` on the current
    contents of ``inputs`` and writes the non-zeros of each output into ``outputs`` (arrays
    allocated here).  The arrays are reused by every call; the buffer object is kept alive by
    the trigger.
    """
    buf, trigger = f.buffer()
    outputs = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
    for i, arr in enumerate(inputs):
        buf.set_arg(i, memoryview(arr))
    for i, arr in enumerate(outputs):
        buf.set_res(i, memoryview(arr))
    trigger.buffer_owner = buf  # keep the buffer alive as long as the trigger
    return trigger, outputs


class Workspace:
    """Evaluation buffers of one :class:`~casmbd.compiled.model.NumericModel`.

    Parameters
    ----------
    model : NumericModel
        The model whose Functions are evaluated; buffers are made on first use of each.

    Notes
    -----
    ``Function.buffer()`` binds numpy arrays to the inputs and outputs, which avoids the
    conversion of every argument to a CasADi matrix (50–150 µs a call from Python against
    0.1–3 µs for the compiled code itself; docs/performance.md).  The arrays are reused from
    call to call, so a workspace serves one caller at a time.
    """

    def __init__(self, model: NumericModel):
        self.model = model
        self._entries: dict[str, tuple] = {}

    def _entry(self, name: str) -> tuple:
        entry = self._entries.get(name)
        if entry is None:
            f = self.model.function(name)
            ins = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
            trigger, outs = buffered(f, ins)
            buf = trigger.buffer_owner
            sparsity = f.sparsity_out(0)
            pattern = (np.asarray(sparsity.row(), dtype=np.int32),
                       np.asarray(sparsity.colind(), dtype=np.int32), sparsity.shape,
                       sparsity.is_dense())
            entry = (buf, trigger, ins, outs, pattern)
            self._entries[name] = entry
        return entry

    def nonzeros(self, name: str, *args) -> np.ndarray:
        """Non-zeros of output 0 of Function ``name`` at ``args`` (a copy)."""
        _, trigger, ins, outs, _ = self._entry(name)
        for arr, val in zip(ins, args):
            arr[:] = np.ravel(val) if np.ndim(val) else val
        trigger()
        return outs[0].copy()

    def vector(self, name: str, *args) -> np.ndarray:
        """Output 0 of Function ``name`` as a dense flat array."""
        nz = self.nonzeros(name, *args)
        rows, _, shape, dense = self._entries[name][4]
        if dense:
            return nz
        out = np.zeros(shape[0] * shape[1])
        out[rows] = nz
        return out

    def sparse(self, name: str, *args) -> sp.csc_matrix:
        """Output 0 of Function ``name`` as a CSC matrix of its fixed sparsity pattern."""
        nz = self.nonzeros(name, *args)
        rows, colind, shape, _ = self._entries[name][4]
        return sp.csc_matrix((nz, rows, colind), shape=shape)
