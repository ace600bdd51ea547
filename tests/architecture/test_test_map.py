"""The tests mirror the package (issue 33, item 6): a feature's tests are found from its module.

The rule (tests/README.md): the tests of ``casmbd/<layer>/…`` are in ``tests/<layer>/``, those
of ``casmbd/analysis/<room>/…`` in ``tests/analysis/<room>/``; four folders hold what cuts
across the package (:data:`CROSS_CUTTING`).  These checks keep the map true: every package and
every room of ``analysis/`` has a folder of tests with at least one test file, every folder of
tests names a room that exists (a renamed room takes its tests along), no test file is left at
``tests/`` itself, and no two test files share a name (pytest's default import mode needs
unique basenames without ``__init__.py`` files).
"""

from __future__ import annotations

import collections
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "casmbd"
TESTS = ROOT / "tests"

#: folders of tests that mirror no package: what they hold
CROSS_CUTTING = {
    "hostile": "bad and hostile input across every layer (the bad_input files)",
    "architecture": "layers, registries, the composition matrix, kinds, startup, this map",
    "docs": "the snippets of README.md and docs/*.md, the tutorial's commands",
    "peers": "benchmarks/: peers, independent references, the comparison harnesses",
}


def rooms() -> list[pathlib.Path]:
    """The package's rooms, relative to ``casmbd/``: each sub-package (``model``, ``system``,
    …), and each sub-package of ``analysis`` in place of ``analysis`` itself."""
    found = []
    for package in sorted(p.parent for p in PACKAGE.glob("*/__init__.py")):
        inner = sorted(p.parent for p in package.glob("*/__init__.py"))
        found.extend(p.relative_to(PACKAGE) for p in (inner or [package]))
    return found


def folder_of_tests(module: str | pathlib.Path) -> pathlib.Path:
    """The folder of the tests of ``module`` (a path below ``casmbd/``):
    ``analysis/events/impulses.py`` -> ``tests/analysis/events``."""
    path = pathlib.Path(module)
    parts = path.relative_to("casmbd").parts if path.parts[0] == "casmbd" else path.parts
    depth = 2 if parts[0] == "analysis" else 1
    return TESTS.joinpath(*parts[:depth])


def all_test_files() -> list[pathlib.Path]:
    return sorted(TESTS.rglob("test_*.py"))


def test_every_room_has_a_folder_of_tests():
    """casmbd/<layer>/ and casmbd/analysis/<room>/ each have tests/<same path>/test_*.py."""
    assert len(rooms()) >= 15, rooms()  # 7 layers + 8 rooms of analysis when this was written
    empty = [str(room) for room in rooms()
             if not list((TESTS / room).glob("test_*.py"))]
    assert not empty, (f"rooms without tests: {empty}; put each room's tests in "
                       "tests/<the room's path below casmbd/>/ (tests/README.md)")


def test_every_module_maps_to_an_existing_folder_of_tests():
    """Every module of a room finds its tests with :func:`folder_of_tests`."""
    missing = sorted({str(folder_of_tests(path.relative_to(PACKAGE)).relative_to(ROOT))
                      for room in rooms() for path in (PACKAGE / room).glob("*.py")
                      if not folder_of_tests(path.relative_to(PACKAGE)).is_dir()})
    assert not missing, missing
    assert folder_of_tests("casmbd/analysis/events/impulses.py") == TESTS / "analysis" / "events"
    assert folder_of_tests("model/gear.py") == TESTS / "model"


def test_every_folder_of_tests_names_a_room_or_a_cross_cutting_concern():
    """A folder holding test files mirrors an existing room or is one of CROSS_CUTTING."""
    known = {room.as_posix() for room in rooms()} | set(CROSS_CUTTING)
    folders = {path.parent.relative_to(TESTS).as_posix() for path in all_test_files()}
    stray = sorted(folders - known)
    assert not stray, (f"test folders that name no room of casmbd/: {stray} (a renamed room "
                       f"takes its tests along; cross-cutting folders: {sorted(CROSS_CUTTING)})")


def test_no_test_file_at_the_top_of_tests():
    """tests/ itself holds the shared helpers and scenes only."""
    loose = sorted(p.name for p in TESTS.glob("test_*.py"))
    assert not loose, (f"{loose}: move each into the folder of the room it tests "
                       "(tests/README.md)")


def test_test_file_names_are_unique():
    """Without __init__.py files pytest imports a test file by its basename."""
    names = collections.Counter(path.name for path in all_test_files())
    assert not [name for name, count in names.items() if count > 1], names.most_common(3)
