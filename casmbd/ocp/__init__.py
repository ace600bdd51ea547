"""Trajectory optimisation of mechanisms: the same closed-loop model, IPOPT, exact derivatives.

:class:`Ocp` states the problem over a mechanism (horizon, bounds, boundary conditions, path
constraints, objectives), :mod:`casmbd.ocp.transcription` turns it into an NLP (direct
collocation or multiple shooting) and :class:`OcpSolution` holds the result.
"""

from casmbd.ocp.problem import FreeTime, Ocp
from casmbd.ocp.solution import OcpSolution

__all__ = ["FreeTime", "Ocp", "OcpSolution"]
