"""A CasADi Function called on NumPy arrays bound once (``Function.buffer()``).

The one wrapper of ``Function.buffer()`` in casmbd: the workspace of a model
(:class:`~casmbd.compiled.workspace.Workspace`), the integrators' right-hand sides and fused
step blocks, the event loop's integrators and gap functions and the robot interface all call
their Functions through a :class:`BufferedFunction`.  Binding the arrays once avoids the
conversion of every argument to a CasADi matrix and back (50–150 µs a call from Python, a
keyword call of an integrator ~190 µs of which ~70 µs conversions, against 0.1–3 µs for a
small compiled Function; docs/performance.md).  The evaluation is the Function's own, so the
numbers are those of a direct call, and failures raise the same RuntimeError.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

__all__ = ["BufferedFunction"]


class BufferedFunction:
    """A CasADi Function whose inputs and outputs live in NumPy arrays it reads and writes in
    place.

    Parameters
    ----------
    function : casadi.Function
        The Function (compiled or in the virtual machine).
    inputs : sequence of numpy.ndarray or None, optional
        Arrays to bind to the inputs instead of new ones (``None`` entries: a new array of
        zeros); float64 and contiguous, ``function.nnz_in(i)`` entries.  An array bound here
        is read at every call (e.g. a model's parameter vector ``p``, so that a change of a
        parameter applies at once).

    Attributes
    ----------
    function : casadi.Function
        The wrapped Function.
    inputs, outputs : list of numpy.ndarray
        The bound arrays: the non-zeros (column-major) of each input and output.

    Notes
    -----
    Each call copies its arguments into :attr:`inputs` (inputs not given keep their last
    values, zero at first), evaluates, and returns copies of the outputs, so results stay
    valid after the next call.  The arrays are reused by every call: a BufferedFunction
    serves one caller at a time.
    """

    def __init__(self, function: ca.Function,
                 inputs: Sequence[np.ndarray | None] | None = None):
        self.function = function
        given = list(inputs or [])
        given += [None] * (function.n_in() - len(given))
        self.inputs = [np.zeros(function.nnz_in(i)) if a is None else a
                       for i, a in enumerate(given)]
        self.outputs = [np.zeros(function.nnz_out(i)) for i in range(function.n_out())]
        self._buffer, self.evaluate = function.buffer()
        for i, a in enumerate(self.inputs):
            self._buffer.set_arg(i, memoryview(a))
        for i, a in enumerate(self.outputs):
            self._buffer.set_res(i, memoryview(a))
        self._index = {n: i for i, n in enumerate(function.name_in())}
        self._shape = [(function.size2_out(i), function.size1_out(i))
                       for i in range(function.n_out())]

    @classmethod
    def of(cls, function):
        """``function`` buffered when it is a CasADi Function with dense inputs and outputs
        (so that :meth:`all` can shape the outputs), else ``function`` itself (e.g. a
        :class:`~casmbd.analysis.integrators.sundials.ConsistentStart`)."""
        if isinstance(function, ca.Function) and \
                all(function.sparsity_in(i).is_dense() for i in range(function.n_in())) and \
                all(function.sparsity_out(i).is_dense() for i in range(function.n_out())):
            return cls(function)
        return function

    def _set(self, args, named) -> None:
        for bound, value in zip(self.inputs, args):
            bound[...] = value if np.ndim(value) < 2 else np.ravel(value, order="F")
        for name, value in named.items():
            self.inputs[self._index[name]][...] = np.ravel(value, order="F")

    def __call__(self, *args) -> np.ndarray:
        """The non-zeros of output 0 (a copy) at the positional inputs ``args``."""
        self._set(args, {})
        self.evaluate()
        return self.outputs[0].copy()

    def all(self, *args, **named) -> list[np.ndarray]:
        """Every output, shaped like ``DM.full()`` (dense Functions), at the positional or
        named inputs."""
        self._set(args, named)
        self.evaluate()
        return [o.reshape(shape).T.copy() for o, shape in zip(self.outputs, self._shape,
                                                               strict=True)]

    def stacked(self, *pieces) -> np.ndarray:
        """The non-zeros of output 0 (a copy) with input 0 filled by ``pieces`` one after
        the other (a Function of one stacked input: no concatenation per call)."""
        bound, k = self.inputs[0], 0
        for piece in pieces:
            n = len(piece)
            bound[k:k + n] = piece
            k += n
        self.evaluate()
        return self.outputs[0].copy()

    def stats(self) -> dict:
        """The Function's statistics of the last call (an integrator's steps)."""
        return self._buffer.stats()
