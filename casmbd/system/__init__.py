"""Assembly layer: symbolic equations of a mechanism as CasADi Functions."""

from casmbd.system.equations import SIGNATURES, Equation, System

__all__ = ["SIGNATURES", "Equation", "System"]
