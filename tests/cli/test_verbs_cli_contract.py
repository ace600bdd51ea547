"""The command line's contract is fixed: every verb's arguments (names, defaults, choices, help,
order) and its ``--help`` text are those recorded in ``tests/cli/data/cli_help.json`` from main
before the verbs' parsers moved into their registrations (issue 33, item 4).

The structured record is compared on every Python; the rendered ``--help`` texts (argparse's
layout changes between Python versions) on the Python that recorded them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from casmbd import cli
from casmbd.cli.registry import VERB_PARSERS, VERBS

RECORD = json.loads((Path(__file__).parent / "data" / "cli_help.json").read_text())


def _actions(p) -> list[dict]:
    """The arguments of parser ``p`` as recorded (argparse's own attributes)."""
    out = []
    for a in p._actions:
        default = a.default
        if not isinstance(default, (str, int, float, bool, type(None))):
            default = repr(default)
        out.append({"option_strings": list(a.option_strings), "dest": a.dest,
                    "default": default,
                    "choices": list(a.choices) if a.choices is not None else None,
                    "required": a.required, "help": a.help, "metavar": a.metavar,
                    "nargs": a.nargs, "type": getattr(a.type, "__name__", None),
                    "action": type(a).__name__})
    return out


def _subparsers():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "verb")
    return sub


def _help(argv, capsys) -> str:
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 0
    return capsys.readouterr().out


def test_every_verb_is_registered_with_its_parser():
    """build_parser makes exactly the registered verbs, in the recorded order."""
    assert list(VERBS) == RECORD["order"]
    assert list(VERB_PARSERS) == RECORD["order"]
    sub = _subparsers()
    assert list(sub.choices) == RECORD["order"]
    assert {c.dest: c.help for c in sub._choices_actions} == RECORD["verb_help"]


@pytest.mark.parametrize("verb", RECORD["order"])
def test_arguments_are_unchanged(verb):
    """Names, destinations, defaults, choices, types, help and order of every argument."""
    assert _actions(_subparsers().choices[verb]) == RECORD["arguments"][verb]


@pytest.mark.skipif(tuple(RECORD["python"]) != sys.version_info[:2],
                    reason="argparse's layout is Python's; recorded on Python "
                           f"{'.'.join(map(str, RECORD['python']))}")
@pytest.mark.parametrize("verb", ["", *RECORD["order"]])
def test_help_text_is_unchanged(verb, capsys, monkeypatch):
    """``casmbd --help`` and ``casmbd VERB --help`` character for character (100 columns)."""
    monkeypatch.setenv("COLUMNS", "100")
    argv = ["--help"] if not verb else [verb, "--help"]
    assert _help(argv, capsys) == RECORD["help_text"][verb]


def test_help_is_the_same_through_python_m():
    """The fixture's texts are what a user sees: ``python -m casmbd sweep --help``."""
    env = {**os.environ, "COLUMNS": "100"}
    out = subprocess.run([sys.executable, "-m", "casmbd", "sweep", "--help"],
                         capture_output=True, text=True, env=env, timeout=120,
                         cwd=Path(__file__).parents[2])
    assert out.returncode == 0
    if tuple(RECORD["python"]) == sys.version_info[:2]:
        assert out.stdout == RECORD["help_text"]["sweep"]
    else:
        assert "--analysis {simulate,kinematics,inverse,statics}" in out.stdout
