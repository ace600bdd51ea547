"""Compiled layer: C code generation with an on-disk cache, and the numeric model."""

from casmbd.compiled.codegen import BuildReport, cache_dir, compile_functions
from casmbd.compiled.modal_cache import load_modes, save_modes
from casmbd.compiled.model import NEEDS, NumericModel

__all__ = ["NEEDS", "BuildReport", "NumericModel", "cache_dir", "compile_functions",
           "load_modes", "save_modes"]
