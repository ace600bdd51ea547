"""CasADi Functions evaluated through their ``FunctionBuffer`` (the event loop's many small
calls, issue 31)."""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["Buffered"]


class Buffered:
    """A CasADi Function evaluated through its ``FunctionBuffer``: inputs and outputs live in
    NumPy arrays the Function reads and writes in place, so that a call costs the evaluation
    and not the conversions of the Python wrapper (a keyword call of an integrator took
    ~190 µs, ~70 µs of it conversions; a gap function ~85 µs for a few flops).  The same
    evaluation as the Function's own call, so the same numbers; failures raise the same
    RuntimeError.  Dense inputs and outputs only (:meth:`of` falls back to the Function)."""

    def __init__(self, f: ca.Function):
        self.f = f
        self._buf, self._eval = f.buffer()
        self._in = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self._out = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        for i, a in enumerate(self._in):
            self._buf.set_arg(i, memoryview(a))
        for i, a in enumerate(self._out):
            self._buf.set_res(i, memoryview(a))
        self._index = {n: i for i, n in enumerate(f.name_in())}
        self._shape = [(f.size2_out(i), f.size1_out(i)) for i in range(f.n_out())]

    @classmethod
    def of(cls, f):
        """``f`` buffered when it is a CasADi Function with dense inputs and outputs, else
        ``f`` itself (a :class:`~casmbd.analysis.integrators.sundials.ConsistentStart`)."""
        if isinstance(f, ca.Function) and \
                all(f.sparsity_in(i).is_dense() for i in range(f.n_in())) and \
                all(f.sparsity_out(i).is_dense() for i in range(f.n_out())):
            return cls(f)
        return f

    def __call__(self, *args, **kwargs) -> list[np.ndarray]:
        """The outputs (arrays shaped like ``DM.full()``) at the positional or named
        inputs (the others zero)."""
        for a, value in zip(self._in, args):
            a[:] = np.ravel(value, order="F")
        for name, value in kwargs.items():
            self._in[self._index[name]][:] = np.ravel(value, order="F")
        self._eval()
        return [o.reshape(shape).T.copy() for o, shape in zip(self._out, self._shape,
                                                               strict=True)]

    def stats(self) -> dict:
        return self._buf.stats()
