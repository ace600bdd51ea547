"""casmbd: dynamics of constrained mechanisms on CasADi.

The layers, each importing only the ones before it:

* :mod:`casmbd.model` — what the user builds (bodies, joints, forces, drivers);
* :mod:`casmbd.system` — the symbolic equations (M, Q_e, Q_v, C, C_q, C_t, γ);
* :mod:`casmbd.compiled` — generated C code, the disk cache and the numeric model;
* :mod:`casmbd.results` — the output data class :class:`Result` and its npz/CSV files;
* :mod:`casmbd.analysis` — kinematics, forward and inverse dynamics, statics, linearisation;
* :mod:`casmbd.ocp` — trajectory optimisation over the same model (collocation, shooting, IPOPT);
* :mod:`casmbd.io`, :mod:`casmbd.viz`, :mod:`casmbd.cli` — scene files, plots, the CLI.

``errors``, ``interrupts``, ``limits`` and ``progress`` sit below all;
tests/architecture/test_layers.py checks the rule.
"""

import importlib

# the error classes, re-exported (the rest of ``__all__``: :data:`_LAZY` and the analysis verbs)
from casmbd.errors import AnalysisError as AnalysisError
from casmbd.errors import AssemblyError as AssemblyError
from casmbd.errors import CasmbdError as CasmbdError
from casmbd.errors import CompileError as CompileError
from casmbd.errors import ExpressionError as ExpressionError
from casmbd.errors import IntegratorError as IntegratorError
from casmbd.errors import ModelError as ModelError
from casmbd.errors import RedundantConstraintError as RedundantConstraintError
from casmbd.errors import SceneError as SceneError
from casmbd.errors import SingularConfigurationError as SingularConfigurationError

#: public name -> the module that defines it, imported when the name is first used (PEP 562):
#: ``import casmbd`` loads only the error classes, so a script or ``casmbd --version`` starts
#: without CasADi's compiled layer, scipy, the analyses or the OCP.  The analysis verbs
#: (``casmbd.simulate``, ``from casmbd import sweep`` …) are not listed here: they are those of
#: the analysis face's registry, :data:`casmbd.analysis.VERBS` (read on first use, a verb's
#: module imported on its first use), so that a verb registered there is ``casmbd.NAME`` too
_LAZY = {
    "NumericModel": "casmbd.compiled.model",
    "CompiledModel": "casmbd.compiled.robot", "compile": "casmbd.compiled.robot",
    "load_scene": "casmbd.io.scene", "loads_scene": "casmbd.io.scene",
    "load_urdf": "casmbd.io.urdf", "loads_urdf": "casmbd.io.urdf",
    "load_mjcf": "casmbd.io.mjcf",
    "export_c": "casmbd.io.c_export",
    "Mechanism": "casmbd.model",
    "Result": "casmbd.results", "load": "casmbd.io.scene", "load_result": "casmbd.io.scene",
    "System": "casmbd.system",
    "view": "casmbd.viz.view_server",
}
#: subpackages reached as attributes (``casmbd.ocp.Ocp`` after a bare ``import casmbd``)
_SUBMODULES = ("analysis", "cli", "compiled", "io", "model", "ocp", "results", "system", "viz")


def _analysis_verbs() -> dict:
    """The analysis face's registry of verbs, :data:`casmbd.analysis.VERBS` (its module
    imports no room)."""
    return importlib.import_module("casmbd.analysis").VERBS


def __getattr__(name: str):
    """Import the module of a public name on first use (PEP 562) and keep the value.

    ``load``/``load_result`` are :func:`casmbd.io.scene.load_result`: the result they read
    carries the scene reader :meth:`Result.mechanism` uses (passed in, never registered).
    ``__all__`` is computed (the analysis verbs are the face's registry's).
    """
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"casmbd.{name}")
    elif name == "__all__":
        return sorted({*_ERRORS, *_LAZY, *_analysis_verbs()})
    elif not name.startswith("__") and name in _analysis_verbs():
        value = getattr(importlib.import_module("casmbd.analysis"), name)
        if not isinstance(_analysis_verbs()[name], str):  # registered from user code: it
            return value                                  # may be replaced, not kept here
    else:
        raise AttributeError(f"module 'casmbd' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY) | set(_SUBMODULES) | set(_analysis_verbs()))


__version__ = "0.1.0"

#: the error classes
_ERRORS = ("AnalysisError", "AssemblyError", "CasmbdError", "CompileError", "ExpressionError",
           "IntegratorError", "ModelError", "RedundantConstraintError", "SceneError",
           "SingularConfigurationError")
