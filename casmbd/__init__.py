"""casmbd: dynamics of constrained mechanisms on CasADi.

The layers, each importing only the ones before it:

* :mod:`casmbd.model` — what the user builds (bodies, joints, forces, drivers);
* :mod:`casmbd.system` — the symbolic equations (M, Q_e, Q_v, C, C_q, C_t, γ);
* :mod:`casmbd.compiled` — generated C code, the disk cache and the numeric model;
* :mod:`casmbd.results` — the output data class :class:`Result` and its npz/CSV files;
* :mod:`casmbd.analysis` — kinematics, forward and inverse dynamics, statics, linearisation;
* :mod:`casmbd.ocp` — trajectory optimisation over the same model (collocation, shooting, IPOPT);
* :mod:`casmbd.io`, :mod:`casmbd.viz`, :mod:`casmbd.cli` — scene files, plots, the CLI.

``errors``, ``interrupts``, ``limits`` and ``progress`` sit below all; tests/test_layers.py
checks the rule.
"""

from casmbd import ocp  # noqa: F401  (casmbd.ocp.Ocp: trajectory optimisation)
from casmbd.analysis.assembly import accelerations, assemble, velocities
from casmbd.analysis.inverse import inverse_dynamics
from casmbd.analysis.kinematics import info, kinematics
from casmbd.analysis.linearize import linearize
from casmbd.analysis.sensitivity import SensitivityResult, sensitivity
from casmbd.analysis.simulate import Simulator, simulate
from casmbd.analysis.statics import static_equilibrium
from casmbd.analysis.sweep import SweepResult, sweep
from casmbd.compiled.model import NumericModel
from casmbd.compiled.robot import CompiledModel, compile
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
from casmbd.io.scene import load_scene, loads_scene
from casmbd.io.urdf import load_urdf, loads_urdf
from casmbd.model import Mechanism
from casmbd.results import Result, load, load_result
from casmbd.system import System

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
]
