"""Exception classes of casmbd.

Every error a user can provoke with bad input derives from :class:`CasmbdError`, so that
programs can catch one class, and every message names the body, joint, field or time at fault.
"""

from __future__ import annotations


class CasmbdError(Exception):
    """Base class of every error raised by casmbd on bad input or failed analyses."""


class SceneError(CasmbdError):
    """A scene file is malformed or inconsistent; the message names table, entry and key."""


class ExpressionError(SceneError):
    """An expression string cannot be parsed or uses something that is not allowed."""


class ModelError(CasmbdError):
    """The mechanism built with the Python API is invalid (bad mass, unknown body, ...)."""


class AssemblyError(CasmbdError):
    """Newton-Raphson could not satisfy the constraints C(q, t) = 0.

    ``culprits`` lists the elements most likely at fault, best first
    (:class:`casmbd.analysis.instant.culprits.Culprit`: kind, element, hint, ...).  The ranking
    re-solves the assembly once per element, so it is computed on first use — ``str(exc)`` or
    ``exc.culprits`` — by the ``explain`` callable (returning the list and the text appended to
    the message): callers that catch the error and try another step never pay for it.
    """

    def __init__(self, message: str, culprits: list | None = None, *, explain=None):
        super().__init__(message)
        self._culprits = list(culprits or [])
        self._explain = explain

    def _resolve(self) -> None:
        if self._explain is not None:
            explain, self._explain = self._explain, None
            culprits, text = explain()
            self._culprits = list(culprits)
            self.args = (f"{self.args[0]}{text}", *self.args[1:])

    @property
    def culprits(self) -> list:
        """The elements most likely at fault, best first (empty when not ranked)."""
        self._resolve()
        return self._culprits

    def __str__(self) -> str:
        self._resolve()
        return super().__str__()

    def __reduce__(self):
        self._resolve()
        return (type(self), (str(self), self._culprits))


class RedundantConstraintError(CasmbdError):
    """The constraint Jacobian is rank deficient; ``dependent`` lists (joint, equation) pairs."""

    def __init__(self, message: str, dependent: list[tuple[str, str]] | None = None):
        super().__init__(message)
        self.dependent = list(dependent or [])


class SingularConfigurationError(CasmbdError):
    """A linear system of the analysis (Jacobian, KKT matrix) is singular at some time."""


class SingularMassMatrixError(SingularConfigurationError):
    """The mass matrix is singular at a state: motions without kinetic energy (a massless end
    link).  ``coordinates`` and ``bodies`` name them, largest share first."""

    def __init__(self, message: str, coordinates=(), bodies=()):
        super().__init__(message)
        self.coordinates, self.bodies = list(coordinates), list(bodies)

    def __reduce__(self):
        return (type(self), (self.args[0], self.coordinates, self.bodies))


class LimitError(CasmbdError):
    """An input exceeds a stated size limit of :mod:`casmbd.limits` (bodies, steps × state
    size against the memory budget, grid points, intervals, frames, dpi, ...); the message
    names the quantity, its value, the limit and what to do instead."""


class CompileError(CasmbdError):
    """Generated C code could not be compiled or loaded."""


class AnalysisError(CasmbdError):
    """An analysis cannot run on this mechanism (e.g. kinematics of an undriven mechanism)."""


class CompositionError(AnalysisError):
    """An element of the mechanism needs what the chosen analysis does not handle
    (:func:`casmbd.model.needs.check`): raised before any work, naming the element, the
    analysis, why, and what to use instead.

    Attributes
    ----------
    analysis : str
        The analysis as messages name it (``"inverse dynamics"``, ``"simulate with
        formulation 'ggl'"``).
    refused : list of (element, need)
        Every element the analysis does not handle, with its need (:data:`NEEDS`).
    """

    def __init__(self, message: str, analysis: str = "", refused=()):
        super().__init__(message)
        self.analysis = analysis
        self.refused = list(refused)


class UnknownMethodError(AnalysisError):
    """A formulation or integrator name that is not registered; the message lists the
    registered names (``choices``), so that a typo is found without reading the source.

    Attributes
    ----------
    what : str
        ``"formulation"`` or ``"integrator"``.
    name : str
        The name asked for.
    choices : tuple of str
        The registered names.
    """

    def __init__(self, what: str, name, choices):
        self.what, self.name, self.choices = what, name, tuple(choices)
        super().__init__(f"unknown {what} {name!r} (known: {', '.join(self.choices)})")


class ResultFileError(AnalysisError):
    """A result file (npz) is missing, truncated, corrupted or not written by casmbd; the
    message names the file and what is wrong with it."""


class IntegratorError(CasmbdError):
    """The time integrator failed; carries the time, the solver's flag and partial results.

    Attributes
    ----------
    time : float
        Time the integrator had reached (the last good output time if it is unknown).
    flag : str
        The solver's own return flag (e.g. ``CV_TOO_MUCH_WORK``).
    partial : casmbd.results.Result or None
        Results on the output grid up to the last time reached.
    """

    def __init__(self, message: str, time: float, flag: str, partial=None):
        super().__init__(message)
        self.time = time
        self.flag = flag
        self.partial = partial


class ConstraintViolationError(IntegratorError):
    """A simulation's position constraints are violated beyond the tolerance at an output time.

    Raised as kinematics raises its assembly failure: the message names the time, the size
    of the violation and its cause — the driver or joint the others contradict (``culprits``,
    as for an :class:`AssemblyError`, when the constraints cannot be satisfied there), or the
    equations left by a trajectory that drifted off satisfiable constraints.  ``partial``
    holds the results at the output times before the violation.
    """

    def __init__(self, message: str, time: float, flag: str = "CONSTRAINT_VIOLATION",
                 partial=None, culprits: list | None = None):
        super().__init__(message, time, flag, partial)
        self.culprits = list(culprits or [])


class OptimizationError(AnalysisError):
    """The NLP solver of an optimal-control problem did not converge.

    The message gives the solver's status, the most violated constraints and the bounds that
    bind; ``solution`` holds the last iterate (an :class:`~casmbd.ocp.solution.OcpSolution`).
    """

    def __init__(self, message: str, solution=None):
        super().__init__(message)
        self.solution = solution


class IdentificationError(AnalysisError):
    """Dynamic parameter identification cannot proceed: measurements that do not fit the
    model (a missing column, NaN, too few samples for the base parameters) or a regressor
    that does not determine the parameters asked for; the message names the file, row,
    column, joint or parameter combination at fault."""
