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
"""

import importlib

#: public verb (or its result class) -> the module that defines it
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
    "SensitivityResult": "casmbd.analysis.studies.sensitivity",
}


def __getattr__(name: str):
    """The verb ``name``, its module imported on first use (PEP 562)."""
    if name not in VERBS:
        raise AttributeError(f"module 'casmbd.analysis' has no attribute {name!r}")
    value = getattr(importlib.import_module(VERBS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(VERBS))


__all__ = sorted(VERBS)
