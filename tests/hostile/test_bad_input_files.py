"""Bad input, files: result files that are truncated, corrupted, not npz, or not casmbd's.

Each variant goes through the CLI (``casmbd plot`` and ``casmbd animate``, via
``casmbd.cli.main``): exit status 1, exactly one ``error:`` line naming the file and what is
wrong, no traceback, and no figure written.  The library call raises
:class:`~casmbd.errors.ResultFileError`.
"""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from conftest import private_cache
from scene_builders import scene_text

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.cli import main
from casmbd.errors import AnalysisError, ResultFileError
from casmbd.io.scene import load_result as load
from casmbd.io.scene import loads_scene

SCENE = scene_text("pinned_rod")


_vm = private_cache("cache_files", CASMBD_COMPILE="0")


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> bytes:
    """The bytes of a valid simulation result (5 output times)."""
    path = tmp_path_factory.mktemp("good") / "good.npz"
    mech = loads_scene(SCENE)
    res = simulate(mech, t_end=0.2, steps=4, mode="vm")
    res.attach_scene(mech)
    res.save(path)
    return path.read_bytes()


def _arrays(good: bytes, tmp_path) -> dict:
    src = tmp_path / "src.npz"
    src.write_bytes(good)
    with np.load(src) as data:
        return {k: data[k] for k in data.files}


def _npz(path, arrays: dict) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def make(kind: str, good: bytes, path) -> str:
    """Write the bad variant ``kind`` to ``path``; return a fragment its error must contain."""
    if kind == "truncated":
        path.write_bytes(good[: len(good) // 2])
        return "truncated or corrupted"
    if kind == "corrupted":
        data = bytearray(good)
        for i in range(len(data) // 3, 2 * len(data) // 3, 7):
            data[i] ^= 0xFF
        path.write_bytes(bytes(data))
        return "cannot read result file"
    if kind == "empty":
        path.write_bytes(b"")
        return "it is empty"
    if kind == "text":
        path.write_text("t,q\n0,1\n")
        return "not a zip archive"
    if kind == "zip_not_npz":
        with zipfile.ZipFile(path, "w") as zf:
            zf.writestr("readme.txt", "hello")
        return "not an npz file (members readme.txt)"
    arrays = _arrays(good, path.parent)
    if kind == "object_array":
        arrays["array/q"] = np.array([{"a": 1}] * len(arrays["t"]), dtype=object)
        _npz(path, arrays)
        return "object arrays"
    if kind == "no_meta":
        del arrays["meta"]
        _npz(path, arrays)
        return "no 'meta' entry"
    if kind == "no_t":
        del arrays["t"]
        _npz(path, arrays)
        return "no time grid 't'"
    if kind == "meta_not_json":
        arrays["meta"] = np.array("{kind: simulation")
        _npz(path, arrays)
        return "not JSON"
    if kind == "meta_missing_names":
        arrays["meta"] = np.array(json.dumps({"kind": "simulation", "stats": {}}))
        _npz(path, arrays)
        return "'names'"
    if kind == "t_nan":
        arrays["t"] = arrays["t"].copy()
        arrays["t"][2] = np.nan
        _npz(path, arrays)
        return "'t' must be"
    if kind == "short_array":
        arrays["array/q"] = arrays["array/q"][:2]
        _npz(path, arrays)
        return "array 'q'"
    raise AssertionError(kind)


KINDS = ["truncated", "corrupted", "empty", "text", "zip_not_npz", "object_array", "no_meta",
         "no_t", "meta_not_json", "meta_missing_names", "t_nan", "short_array"]


@pytest.mark.parametrize("kind", KINDS)
def test_library_load_raises_result_file_error(kind, good, tmp_path):
    path = tmp_path / f"{kind}.npz"
    fragment = make(kind, good, path)
    with pytest.raises(ResultFileError) as exc:
        load(path)
    assert isinstance(exc.value, AnalysisError)
    assert f"{kind}.npz" in str(exc.value) and fragment in str(exc.value), str(exc.value)


@pytest.mark.parametrize("verb, suffix", [("plot", ".png"), ("animate", ".gif")])
@pytest.mark.parametrize("kind", KINDS)
def test_cli_bad_result_file(kind, verb, suffix, good, tmp_path, capsys):
    path = tmp_path / f"{kind}.npz"
    fragment = make(kind, good, path)
    out = tmp_path / f"figure{suffix}"
    code = main([verb, str(path), "--out", str(out)])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 1
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert f"{kind}.npz" in lines[0] and fragment in lines[0], lines[0]
    assert "Traceback" not in captured.err and "internal error" not in captured.err
    assert not out.exists()
    assert {p.name for p in tmp_path.iterdir()} <= {f"{kind}.npz", "src.npz"}


def test_cli_missing_result_file(tmp_path, capsys):
    out = tmp_path / "figure.png"
    code = main(["plot", str(tmp_path / "nowhere.npz"), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "nowhere.npz" in err[0] and "not found" in err[0]
    assert not out.exists()


def test_good_file_still_loads(good, tmp_path):
    """The checks accept what casmbd writes: 5 times, q of 1 coordinate (the pivot angle:
    the automatic choice takes joint coordinates for the pendulum; 3 in absolute ones)."""
    path = tmp_path / "good.npz"
    path.write_bytes(good)
    res = load(path)
    assert res.kind == "simulation" and res["q"].shape == (5, 1)
    assert res.names["coordinates"] == ["pivot.angle"]
    assert res.mechanism().name == "pendulum"
