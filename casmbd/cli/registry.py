"""The verbs of the ``casmbd`` command, registered by name.

A verb is one module and its registration: a function ``run(args) -> (JSON object, text)``
and how its parser is made.  :data:`VERBS` maps every verb to its ``run``;
:data:`VERB_PARSERS` holds every verb's parser (help, the function adding its own arguments,
whether it takes a scene file with ``--json``, ``--debug`` and ``--mode``).
:func:`casmbd.cli.build_parser` adds a sub-parser for every entry of :data:`VERB_PARSERS`, in
registration order, and :func:`casmbd.cli.main` runs ``VERBS[verb](args)`` with the one-line
errors, ``--json`` contract and exit statuses of every verb.

The shipped verbs are registered by :mod:`casmbd.cli` (their functions are imported when they
run, so ``casmbd info`` loads neither the OCP nor the plots; their arguments are added by
:mod:`casmbd.cli.verbs`).  How to add one: ``examples/custom_verb.py``
(``tests/architecture/test_custom_registries.py`` runs it).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass

from casmbd import analysis
from casmbd.analysis.studies.sweep_registry import Sweepable, register_sweepable
from casmbd.errors import ModelError

__all__ = ["VERBS", "VERB_PARSERS", "VerbParser", "register_verb"]

#: verb name -> ``run(args) -> (dict, str)``
VERBS: dict[str, Callable[[argparse.Namespace], tuple[dict, str]]] = {}


@dataclass(frozen=True)
class VerbParser:
    """How :func:`casmbd.cli.build_parser` makes the parser of a registered verb."""

    help: str
    #: adds the verb's own arguments to its sub-parser (None: none)
    add_arguments: Callable[[argparse.ArgumentParser], None] | None = None
    #: the verb reads a scene file: positional ``scene``, ``--json``, ``--debug``, ``--mode``
    scene: bool = True
    #: the command adds the shared arguments (``scene`` …, or ``--json`` and ``--debug``)
    #: before ``add_arguments``; False: ``add_arguments`` adds them itself, in its own order
    shared: bool = True


#: verb name -> its parser
VERB_PARSERS: dict[str, VerbParser] = {}


def register_verb(name: str, run: Callable[[argparse.Namespace], tuple[dict, str]], *,
                  help: str = "", add_arguments=None, scene: bool = True,
                  shared: bool = True, python: Callable | None = None,
                  sweep: Sweepable | None = None, replace: bool = False):
    """Register the verb ``name`` run by ``run(args)``, which returns (JSON object, text).

    ``help``, ``add_arguments``, ``scene`` and ``shared`` make its parser
    (:class:`VerbParser`).  An analysis verb also names its Python function, ``python``
    (registered in the analysis face: ``casmbd.NAME``, :func:`casmbd.analysis.register_verb`),
    and, if a parameter sweep runs it, its ``sweep``
    (:class:`~casmbd.analysis.studies.sweep_registry.Sweepable`: ``casmbd sweep --analysis
    NAME``, ``casmbd.sweep(..., analysis=NAME)``).  A taken name is a :class:`ModelError`
    unless ``replace``.  Returns ``run``.
    """
    if not (isinstance(name, str) and name.isidentifier()) or not callable(run):
        raise ModelError(f"a verb is a name and a function run(args), got {name!r}, {run!r}")
    if name in VERBS and not replace:
        raise ModelError(f"verb '{name}' is already registered; pass replace=True to "
                         "replace it")
    if python is not None:
        analysis.register_verb(name, python, replace=replace)
    if sweep is not None:
        register_sweepable(name, sweep, replace=replace)
    VERBS[name] = run
    VERB_PARSERS[name] = VerbParser(help, add_arguments, scene, shared)
    return run
