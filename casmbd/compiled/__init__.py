"""Compiled layer: C code generation with an on-disk cache, the one compile entry
(:func:`compile_model`, :func:`compile_blocks`), the numeric model and its workspace."""

from casmbd.compiled.buffered import BufferedFunction
from casmbd.compiled.build import compile_blocks, compile_model
from casmbd.compiled.codegen import BuildReport, cache_dir, compile_functions
from casmbd.compiled.modal_cache import load_modes, save_modes
from casmbd.compiled.model import NEEDS, NumericModel
from casmbd.compiled.workspace import Workspace

__all__ = ["NEEDS", "BufferedFunction", "BuildReport", "NumericModel", "Workspace", "cache_dir",
           "compile_blocks", "compile_functions", "compile_model", "load_modes", "save_modes"]
