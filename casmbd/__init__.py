"""casmbd: dynamics of constrained mechanisms on CasADi.

The layers, each importing only the ones before it:

* :mod:`casmbd.model` — what the user builds (bodies, joints, forces, drivers);
* :mod:`casmbd.system` — the symbolic equations (M, Q_e, Q_v, C, C_q, C_t, γ);
* :mod:`casmbd.compiled` — generated C code, the disk cache and the numeric model;
* :mod:`casmbd.analysis` — kinematics (and the other analyses);
* :mod:`casmbd.results`, :mod:`casmbd.io`, :mod:`casmbd.cli` — results, scene files, the CLI.
"""

from casmbd.analysis.assembly import accelerations, assemble, velocities
from casmbd.analysis.kinematics import info, kinematics
from casmbd.compiled.model import NumericModel
from casmbd.errors import (
    AnalysisError,
    AssemblyError,
    CasmbdError,
    CompileError,
    ExpressionError,
    ModelError,
    RedundantConstraintError,
    SceneError,
    SingularConfigurationError,
)
from casmbd.io.scene import load_scene, loads_scene
from casmbd.model import Mechanism
from casmbd.results import Result, load
from casmbd.system import System

__version__ = "0.1.0"

__all__ = ["AnalysisError", "AssemblyError", "CasmbdError", "CompileError", "ExpressionError",
           "Mechanism", "ModelError", "NumericModel", "RedundantConstraintError", "Result",
           "SceneError", "SingularConfigurationError", "System", "accelerations", "assemble",
           "info", "kinematics", "load", "load_scene", "loads_scene", "velocities"]
