"""Scenes shared by several test files: the files of ``tests/scenes/`` and TOML builders.

A scene that two test files need lives here or in ``tests/scenes/`` (tests/README.md), never
copied inline: ``scene_text("pinned_rod")`` is the text of ``tests/scenes/pinned_rod.toml``;
the builders write ``[[bodies]]``/``[[joints]]``/any ``[[table]]`` entries from TOML value texts
(the bad-input tests edit one key of a known-good scene).  A scene moved here keeps its text, so
its tests keep their numbers (and the line numbers of their error messages).
"""

from __future__ import annotations

import pathlib

#: the shared scene files
SCENES = pathlib.Path(__file__).resolve().parent / "scenes"


def scene_text(name: str) -> str:
    """The text of the shared scene ``tests/scenes/<name>.toml``."""
    return (SCENES / f"{name}.toml").read_text(encoding="utf-8")


# ---------------------------------------------------------------------- scene builders
HEAD = '[scene]\nname = "bad"\ngravity = [0.0, -9.81]\n'


def body(name: str, x: float = 0.5, y: float = 0.0, **fields: str) -> str:
    """A [[bodies]] entry; ``fields`` override or add keys (values are TOML text)."""
    keys = {"name": f'"{name}"', "mass": "1.0", "inertia": "0.1", "position": f"[{x}, {y}]"}
    keys.update(fields)
    return "\n[[bodies]]\n" + "".join(f"{k} = {v}\n" for k, v in keys.items() if v is not None)


def joint(name: str, jtype: str, body1: str = "ground", body2: str = "rod", **fields: str) -> str:
    """A [[joints]] entry (values of ``fields`` are TOML text)."""
    keys = {"name": f'"{name}"', "type": f'"{jtype}"', "body1": f'"{body1}"',
            "body2": f'"{body2}"'}
    keys.update(fields)
    return "\n[[joints]]\n" + "".join(f"{k} = {v}\n" for k, v in keys.items() if v is not None)


def entry(table: str, **fields: str) -> str:
    """Any array-of-tables entry (values are TOML text)."""
    return f"\n[[{table}]]\n" + "".join(f"{k} = {v}\n" for k, v in fields.items())


#: the pinned rod of ``tests/scenes/pinned_rod.toml`` named "bad", built from the builders
PIVOT = joint("pivot", "revolute", point="[0.0, 0.0]")
PENDULUM = HEAD + body("rod") + PIVOT
