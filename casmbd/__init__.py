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

from casmbd.errors import (
    AnalysisError,
    AssemblyError,
    CasmbdError,
    CompileError,
    ExpressionError,
    IntegratorError,
    ModelError,
    RedundantConstraintError,
    SceneError,
    SingularConfigurationError,
)

#: public name -> the module that defines it, imported when the name is first used (PEP 562):
#: ``import casmbd`` loads only the error classes, so a script or ``casmbd --version`` starts
#: without CasADi's compiled layer, scipy, the analyses or the OCP; ``casmbd.simulate`` and
#: ``from casmbd import simulate`` import :mod:`casmbd.analysis.dynamics.simulate` on first use
_LAZY = {
    "accelerations": "casmbd.analysis.instant.assembly",
    "assemble": "casmbd.analysis.instant.assembly",
    "velocities": "casmbd.analysis.instant.assembly",
    "inverse_dynamics": "casmbd.analysis.driven.inverse",
    "info": "casmbd.analysis.driven.kinematics", "kinematics": "casmbd.analysis.driven.kinematics",
    "linearize": "casmbd.analysis.statics.linearize",
    "SensitivityResult": "casmbd.analysis.studies.sensitivity",
    "sensitivity": "casmbd.analysis.studies.sensitivity",
    "Simulator": "casmbd.analysis.dynamics.simulate",
    "simulate": "casmbd.analysis.dynamics.simulate",
    "static_equilibrium": "casmbd.analysis.statics.statics",
    "SweepResult": "casmbd.analysis.studies.sweep", "sweep": "casmbd.analysis.studies.sweep",
    "NumericModel": "casmbd.compiled.model",
    "CompiledModel": "casmbd.compiled.robot", "compile": "casmbd.compiled.robot",
    "load_scene": "casmbd.io.scene", "loads_scene": "casmbd.io.scene",
    "load_urdf": "casmbd.io.urdf", "loads_urdf": "casmbd.io.urdf",
    "Mechanism": "casmbd.model",
    "Result": "casmbd.results", "load": "casmbd.io.scene", "load_result": "casmbd.io.scene",
    "System": "casmbd.system",
    "view": "casmbd.viz.view_server",
}
#: subpackages reached as attributes (``casmbd.ocp.Ocp`` after a bare ``import casmbd``)
_SUBMODULES = ("analysis", "cli", "compiled", "io", "model", "ocp", "results", "system", "viz")


def __getattr__(name: str):
    """Import the module of a public name on first use (PEP 562) and keep the value.

    ``load``/``load_result`` are :func:`casmbd.io.scene.load_result`: the result they read
    carries the scene reader :meth:`Result.mechanism` uses (passed in, never registered).
    """
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"casmbd.{name}")
    else:
        raise AttributeError(f"module 'casmbd' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY) | set(_SUBMODULES))


__version__ = "0.1.0"

__all__ = [
    "AnalysisError",
    "AssemblyError",
    "CasmbdError",
    "CompileError",
    "CompiledModel",
    "ExpressionError",
    "IntegratorError",
    "Mechanism",
    "ModelError",
    "NumericModel",
    "RedundantConstraintError",
    "Result",
    "SceneError",
    "SensitivityResult",
    "Simulator",
    "SingularConfigurationError",
    "SweepResult",
    "System",
    "accelerations",
    "assemble",
    "compile",
    "info",
    "inverse_dynamics",
    "kinematics",
    "linearize",
    "load",
    "load_result",
    "load_scene",
    "load_urdf",
    "loads_scene",
    "loads_urdf",
    "sensitivity",
    "simulate",
    "static_equilibrium",
    "sweep",
    "velocities",
    "view",
]
