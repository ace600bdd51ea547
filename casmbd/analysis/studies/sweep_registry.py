"""The registry of the analyses a parameter sweep runs (complete on import, no analysis
imported): :data:`SWEEPABLE` maps a verb to its :class:`Sweepable` — how to build it once per
process, run it at one point, its options and its scalar outputs.

The shipped entries name the module attribute that defines them (``"module:NAME"``, imported
when a sweep runs: :mod:`casmbd.analysis.studies.sweep_analyses`), so that the command line
lists the choices (``casmbd sweep --analysis``) without loading the analyses; an entry
registered from user code is the object itself (:func:`register_sweepable`, usually through
:func:`casmbd.cli.registry.register_verb`'s ``sweep=``: ``examples/custom_verb.py``).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from casmbd.errors import AnalysisError, ModelError

__all__ = ["SWEEPABLE", "Engine", "Sweepable", "register_sweepable", "sweepable",
           "unregister_sweepable"]


@dataclass
class Engine:
    """One analysis of one mechanism built once per process (:attr:`Sweepable.build`)."""

    #: the process's own copy of the mechanism (its ``parameters`` are the defaults)
    mechanism: Any
    #: the compiled model whose runtime inputs ``p`` the sweep sets at every point
    #: (:attr:`casmbd.compiled.model.NumericModel.p`); None: the analysis compiles nothing
    model: Any
    mode: str = "auto"
    #: whatever else the analysis keeps across points (a Simulator, …)
    state: Any = None


@dataclass(frozen=True)
class Sweepable:
    """How a sweep runs one analysis.

    ``build(mechanism, mode, **build_options) -> Engine`` once per process;
    ``run(engine, p, t_end, steps, **run_options) -> Result`` at every point, after the sweep
    set ``engine.model.p`` to the point's values (``p``: every parameter's value, by name).
    ``default_outputs(result)`` names the scalar outputs of ``sweep(outputs=None)``;
    ``handling(options)`` what the analysis handles with the sweep's options
    (:class:`casmbd.model.needs.Handling`, the composition check before any work).  The
    functions must be importable (module level) for the process and Dask executors.
    """

    build: Callable[..., Engine]
    run: Callable[..., Any]
    default_outputs: Callable[[Any], list[str]]
    handling: Callable[[Mapping], Any]
    #: options given to ``build`` (the others of ``sweep(**options)`` go to ``run``)
    build_options: tuple[str, ...] = ()
    run_options: tuple[str, ...] = ()
    #: the analysis runs on a time grid (``t_end`` and ``steps`` required)
    time_grid: bool = True
    #: named scalar outputs read from ``Result.stats`` (besides ``REDUCTION:COLUMN``,
    #: ``energy_drift`` and ``max_constraint_violation``)
    outputs: tuple[str, ...] = ()


#: verb -> its Sweepable, or ``"module:NAME"`` where it is defined (imported on first use)
SWEEPABLE: dict[str, Sweepable | str] = {
    "simulate": "casmbd.analysis.studies.sweep_analyses:SIMULATE",
    "kinematics": "casmbd.analysis.studies.sweep_analyses:KINEMATICS",
    "inverse": "casmbd.analysis.studies.sweep_analyses:INVERSE",
    "statics": "casmbd.analysis.studies.sweep_analyses:STATICS",
}


def register_sweepable(name: str, spec: Sweepable, *, replace: bool = False) -> Sweepable:
    """Let a sweep run the verb ``name`` (``sweep(..., analysis=name)``, ``casmbd sweep
    --analysis name``).  A taken name is a :class:`~casmbd.errors.ModelError` unless
    ``replace``."""
    if not (isinstance(name, str) and name.isidentifier()) or not isinstance(spec, Sweepable):
        raise ModelError(f"a sweepable analysis is a name and a Sweepable, got {name!r}, "
                         f"{spec!r}")
    if name in SWEEPABLE and not replace:
        raise ModelError(f"sweepable analysis '{name}' is already registered; pass "
                         "replace=True to replace it")
    SWEEPABLE[name] = spec
    return spec


def unregister_sweepable(name: str) -> None:
    """Forget the sweepable analysis ``name`` (a test's clean-up)."""
    SWEEPABLE.pop(name, None)


def sweepable(name: str) -> Sweepable:
    """The :class:`Sweepable` of ``name`` (its module imported on first use); an unknown name
    is an :class:`~casmbd.errors.AnalysisError` naming the known ones."""
    entry = SWEEPABLE.get(name) if isinstance(name, str) else None
    if entry is None:
        raise AnalysisError(f"sweep: unknown analysis {name!r} (known: "
                            f"{', '.join(SWEEPABLE)})")
    if isinstance(entry, str):
        module, _, attr = entry.partition(":")
        entry = getattr(importlib.import_module(module), attr)
    return entry
