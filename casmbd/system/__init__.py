"""Assembly layer: symbolic equations of a mechanism as CasADi Functions.

The body descriptions (:data:`casmbd.system.descriptions.DESCRIPTIONS`) register in their own
modules; this package imports every one of them (the rigid and floating ones in
:mod:`.descriptions`, the flexible ones in :mod:`.flexible_descriptions`), so the registry is
complete whenever any ``casmbd.system`` module is imported.
"""

from casmbd.system.descriptions import DESCRIPTIONS, register_description
from casmbd.system.equations import SIGNATURES, Equation, System
from casmbd.system.flexible_descriptions import FlexibleDescription

__all__ = ["DESCRIPTIONS", "SIGNATURES", "Equation", "FlexibleDescription", "System",
           "register_description"]
