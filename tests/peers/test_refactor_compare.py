"""The refactor comparison harness (benchmarks/refactor_compare.py) finds what it must find.

No analysis runs here: records are written from hand-made answers, then compared.  Checked:
identical records compare equal (exit 0) with NaN equal to NaN; a change of one entry by
1e-15 relative, a changed shape, a changed refusal text, a missing and an extra run each make
the comparison fail (exit 1) and are named with the right figures; timing statistics and the
paths of the scene root are not recorded; the case ids are unique and the set has the stated
size.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks import refactor_compare as rc
from casmbd.results import Result


def _result(scale: float = 1.0) -> Result:
    t = np.linspace(0.0, 0.1, 11)
    q = np.ones((11, 2)) * [1.0, -0.5] * scale  # exact: scaled by 1 + eps, each entry moves
    return Result(kind="simulation", t=t, arrays={"q": q, "lambda": np.full((11, 1), np.nan)},
                  names={"coordinates": ["a", "b"]},
                  stats={"steps": 26, "solve_seconds": 0.123, "cache_hit": False,
                         "note": "scene /somewhere/scenes/x.toml"})


def _write(directory, run: str, payload: dict) -> None:
    directory.mkdir(exist_ok=True)
    case = {"id": run, "scene": "x.toml", "analysis": "simulate"}
    rc.write_npz(directory / f"{run}.npz", {"text/outcome": rc._text("result"), **payload,
                                             "text/case": rc._text(case)})


def test_record_value_keeps_arrays_drops_timings_and_paths():
    # the longer path first: /somewhere/scenes is not read as <root>/scenes
    rec = rc.record_value(_result(), {"/somewhere": "<root>", "/somewhere/scenes": "<scenes>"})
    assert np.array_equal(rec["array/arrays.q"], _result().arrays["q"])
    stats = json.loads(str(rec["text/stats"]))
    assert stats == {"steps": 26, "note": "scene <scenes>/x.toml"}  # seconds, cache_hit out


def test_identical_records_compare_equal(tmp_path, capsys):
    for side in ("a", "b"):
        _write(tmp_path / side, "run1", rc.record_value(_result(), {}))
    assert rc.compare(tmp_path / "a", tmp_path / "b", []) == 0  # NaN == NaN here
    assert "IDENTICAL: 1 of 1" in capsys.readouterr().out


def test_one_ulp_change_is_found_with_its_size(tmp_path, capsys):
    _write(tmp_path / "a", "run1", rc.record_value(_result(), {}))
    _write(tmp_path / "b", "run1", rc.record_value(_result(1.0 + 2.0 ** -52), {}))
    assert rc.compare(tmp_path / "a", tmp_path / "b", []) == 1
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("  array/arrays.q"))
    assert "differing entries (runs): array/arrays.q (1)" in out
    # 1 and -0.5 changed by one ulp: 2.2e-16 absolute and relative at most
    assert "max abs 2.22e-16" in line and "max rel 2.22e-16" in line
    assert rc.compare(tmp_path / "a", tmp_path / "b", ["array/arrays.q"]) == 0


def test_shape_text_missing_and_extra_are_differences(tmp_path, capsys):
    a = rc.record_value(_result(), {})
    b = dict(a, **{"array/arrays.q": a["array/arrays.q"][:5]})
    _write(tmp_path / "a", "run1", a)
    _write(tmp_path / "b", "run1", b)
    refusal = {"text/outcome": rc._text("refused"), "text/error_message": rc._text("no")}
    _write(tmp_path / "a", "run2", refusal)
    _write(tmp_path / "b", "run2", dict(refusal, **{"text/error_message": rc._text("No")}))
    _write(tmp_path / "a", "gone", refusal)
    _write(tmp_path / "b", "new", refusal)
    assert rc.compare(tmp_path / "a", tmp_path / "b", []) == 1
    out = capsys.readouterr().out
    assert "shape (11, 2) vs (5, 2)" in out
    assert '"no" vs "No"' in out
    assert "missing in B (1): gone" in out and "extra in B (1): new" in out


@pytest.mark.parametrize("value, expected", [
    (np.array([1.0, np.nan]), None),
    (np.array([1.0, 2.0]), "NaN in one only at 1 entries"),
])
def test_nan_is_equal_only_to_nan(value, expected):
    how = rc._array_difference(np.array([1.0, np.nan]), value)
    assert how == expected or expected in how


def test_the_set_is_fixed_and_its_ids_unique():
    runs = rc.cases(rc.ROOT)
    ids = [c["id"] for c in runs]
    assert len(ids) == len(set(ids))
    per_scene = len(rc.COORDINATES) * len(rc.FORMULATIONS) * len(rc.INTEGRATORS)
    matrix = [c for c in runs if c["analysis"] == "simulate_matrix"]
    assert len(matrix) == len(rc.MATRIX_SCENES) * per_scene == 14 * 168
    assert all(scene in rc.scene_files(rc.ROOT) for scene in rc.MATRIX_SCENES)
    assert all(scene in rc.MATRIX_SCENES or scene in rc.scene_files(rc.ROOT)
               for scene in rc.PROJECTION_SCENES)
