"""Analyses of a :class:`~casmbd.model.Mechanism`, in rooms (docs/architecture.md).

This module is the face of the layer: the verbs below, each loaded from its room on first use
(PEP 562), so ``import casmbd.analysis`` alone imports no room.  The rooms, lowest floor first
(a room imports only its own and lower floors; tests/architecture/test_layers.py):

* :mod:`.instant` — one instant: assembly, KKT, redundancy, independent equations, culprits,
  first-evaluation checks, reactions, joint friction;
* :mod:`.integrators` — integrator kinds and registry, Dormand–Prince, numeric right-hand sides,
  option ranges, the diagnosis of a failed integration;
* :mod:`.formulations` — every forward-dynamics formulation and its registry;
  :mod:`.events` — event-driven simulation (contacts, joint stops, stick-slip, impacts);
* :mod:`.driven` — kinematics and inverse dynamics; :mod:`.dynamics` — the simulator;
  :mod:`.statics` — statics, resting contacts, stability, linearisation;
* :mod:`.studies` — parameter sweeps and sensitivities.

The face is also the registry of the analysis verbs' Python names (complete on import, no room
imported): :data:`VERBS` names each verb's function (``casmbd.analysis.NAME`` and
``casmbd.NAME``, :func:`register_verb`); the verbs a parameter sweep runs are those of
:data:`casmbd.analysis.studies.sweep_registry.SWEEPABLE`.  A verb from user code is one module
and one registration, :func:`casmbd.cli.registry.register_verb` with ``python=`` and
``sweep=`` (it registers here, in the sweep's registry and in the CLI):
``examples/custom_verb.py``.
"""

import importlib

from casmbd.errors import ModelError

#: public verb (or its result class) -> the module that defines it (imported on first use), or
#: the object itself (a verb registered from user code, :func:`register_verb`)
VERBS = {
    "assemble": "casmbd.analysis.instant.assembly",
    "velocities": "casmbd.analysis.instant.assembly",
    "accelerations": "casmbd.analysis.instant.assembly",
    "info": "casmbd.analysis.driven.kinematics",
    "kinematics": "casmbd.analysis.driven.kinematics",
    "inverse_dynamics": "casmbd.analysis.driven.inverse",
    "simulate": "casmbd.analysis.dynamics.simulate",
    "Simulator": "casmbd.analysis.dynamics.simulate",
    "static_equilibrium": "casmbd.analysis.statics.statics",
    "linearize": "casmbd.analysis.statics.linearize",
    "sweep": "casmbd.analysis.studies.sweep",
    "SweepResult": "casmbd.analysis.studies.sweep",
    "sensitivity": "casmbd.analysis.studies.sensitivity",
    "identify": "casmbd.analysis.identification.identify",
    "SensitivityResult": "casmbd.analysis.studies.sensitivity",
}


def register_verb(name: str, function, *, replace: bool = False):
    """Register the analysis verb ``name``: ``function`` becomes ``casmbd.analysis.NAME`` and
    ``casmbd.NAME``.  A taken name is a :class:`~casmbd.errors.ModelError` unless
    ``replace``.  Returns ``function``."""
    if not (isinstance(name, str) and name.isidentifier()) or not callable(function):
        raise ModelError(f"an analysis verb is a name and a function, got {name!r}, "
                         f"{function!r}")
    if name in VERBS and not replace:
        raise ModelError(f"analysis verb '{name}' is already registered; pass replace=True "
                         "to replace it")
    VERBS[name] = function
    globals().pop(name, None)  # a replaced verb's cached function
    return function


def unregister_verb(name: str) -> None:
    """Forget the verb ``name`` registered from user code (a test's clean-up)."""
    VERBS.pop(name, None)
    globals().pop(name, None)


def __getattr__(name: str):
    """The verb ``name``, its module imported on first use (PEP 562)."""
    if name not in VERBS:
        raise AttributeError(f"module 'casmbd.analysis' has no attribute {name!r}")
    where = VERBS[name]
    value = getattr(importlib.import_module(where), name) if isinstance(where, str) else where
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(VERBS))


__all__ = sorted(VERBS)  # the shipped verbs (those of user code are reached by name)
