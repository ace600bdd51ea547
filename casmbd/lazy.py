"""Modules imported on first use: scipy's submodules for the casmbd modules that need them
only in some of their functions.

``import scipy.sparse`` and ``scipy.linalg`` take about 0.2 s (their array-API layer pulls in
numpy.f2py and numpy.testing); at the top of thirteen casmbd modules they made every process
pay it, also the cached process that only loads a compiled model (issue 36, item 5).
``sp = lazy_module("scipy.sparse")`` binds a stand-in that imports the module at the first
attribute access (``sp.csc_matrix``).
"""

from __future__ import annotations

import importlib
import sys
from types import ModuleType

__all__ = ["lazy_module"]


class _LazyModule(ModuleType):
    """Stand-in for a module not imported yet (see :func:`lazy_module`)."""

    def __getattr__(self, attr: str):
        return getattr(importlib.import_module(self.__name__), attr)


def lazy_module(name: str) -> ModuleType:
    """The module ``name`` when it is imported already, else a stand-in that imports it at
    the first attribute access."""
    return sys.modules.get(name) or _LazyModule(name)
