"""Bad input, reads (issue 31, item 1): every file casmbd reads is a regular file under a
stated size limit, checked before it is opened or read; ``.npz`` members' ``.npy`` headers
are checked against the budget before any array is allocated and unused members are never
loaded; beam element, FE node/DOF and mode counts are checked before building.

Each case asserts the casmbd error class and that the message names the file (or key) and
the limit; the CLI cases also assert exit status 1 and no traceback.  A FIFO must not block:
the reads run in a child process with a timeout.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from conftest import private_cache
from numpy.lib import format as npy_format
from scene_builders import scene_text

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.cli import main
from casmbd.errors import LimitError, ModelError, ResultFileError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.limits import MAX_SCENE_BYTES, check_regular_file, read_bounded
from casmbd.results import load

_vm = private_cache("cache_reads", CASMBD_COMPILE="0")

PENDULUM = scene_text("pinned_rod")

URDF_SCENE = """
[scene]
name = "robot"
urdf = "{urdf}"
"""


def test_dev_zero_as_urdf_is_refused_before_reading():
    with pytest.raises(SceneError, match=r"URDF file '/dev/zero' is a device.*regular files"):
        loads_scene(URDF_SCENE.format(urdf="/dev/zero"))


def test_dev_zero_as_scene_through_the_cli(capsys):
    assert main(["info", "/dev/zero"]) == 1
    err = capsys.readouterr().err
    assert "'/dev/zero' is a device" in err and "Traceback" not in err


def test_directory_as_urdf(tmp_path):
    with pytest.raises(SceneError, match="is a directory"):
        loads_scene(URDF_SCENE.format(urdf=tmp_path))


def test_oversized_urdf_names_file_and_limit(tmp_path):
    big = tmp_path / "big.urdf"
    with open(big, "wb") as fh:  # sparse: no disk used
        fh.truncate(MAX_SCENE_BYTES + 1)
    with pytest.raises(LimitError, match=r"big\.urdf.*64\.0 MB.*limit"):
        loads_scene(URDF_SCENE.format(urdf=big))


def test_read_bounded_reads_at_most_limit_plus_one(tmp_path):
    f = tmp_path / "x.txt"
    f.write_bytes(b"a" * 100)
    assert read_bounded(f, "text", 100) == b"a" * 100
    with pytest.raises(LimitError, match=r"text file .*x\.txt.*100 B"):
        check_regular_file(f, "text", 99)
    from casmbd.viz.plots import read_rows
    rows = tmp_path / "rows.csv"
    rows.write_text("method,error\nrk4,1e-6\nbdf,2e-5\n", encoding="utf-8")
    assert read_rows(rows) == [{"method": "rk4", "error": "1e-6"},
                               {"method": "bdf", "error": "2e-5"}]


_FIFO_CHILD = """
import os, sys
from casmbd.errors import CasmbdError
from casmbd.io.scene import loads_scene
from casmbd.results import load
from casmbd.model.fe_import import load_fe_npz
from casmbd.results import load
from casmbd.viz.plots import read_rows
fifo = sys.argv[1]
for call in (lambda: loads_scene('[scene]\\nname = "r"\\nurdf = "%s"\\n' % fifo),
             lambda: load_fe_npz(fifo), lambda: load(fifo), lambda: read_rows(fifo)):
    try:
        call()
    except CasmbdError as exc:
        print(type(exc).__name__, exc)
"""


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_fifo_as_urdf_fe_result_or_csv_file_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    proc = subprocess.run([sys.executable, "-c", _FIFO_CHILD, str(fifo)], cwd=root,
                          capture_output=True, text=True, timeout=60)
    lines = proc.stdout.splitlines()
    assert len(lines) == 4, proc.stdout + proc.stderr
    for line, kind in zip(lines, ("SceneError", "ModelError", "ResultFileError",
                                  "AnalysisError")):
        assert line.startswith(kind) and "is a FIFO" in line and str(fifo) in line, line


def _beam_fe(path, extra=None):
    from casmbd.model.fe_beam import beam_model
    from casmbd.model.fe_import import save_fe_npz
    fe = beam_model(1.0, 4, EA=1e6, rhoA=1.0, EI=1e3)
    save_fe_npz(path, fe.mass_matrix, fe.stiffness_matrix, fe.positions, fe.dofs_per_node)
    if extra:
        with np.load(path) as z:
            data = dict(z)
        data.update(extra)
        np.savez_compressed(path, **data)


def test_fe_npz_unused_huge_member_is_never_loaded(tmp_path, monkeypatch):
    """A 6000 × 6000 zero member (288 MB in memory, about 1.2 MB deflated; the issue's file
    had 20000 × 20000) that load_fe_npz does not use: the model loads, the same as without
    it, and no array larger than 1 MB is ever read."""
    from casmbd.model.fe_import import load_fe_npz
    path = tmp_path / "fe.npz"
    _beam_fe(path)
    ref = load_fe_npz(path)
    with (zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf,
          zf.open("junk.npy", "w", force_zip64=True) as fh):
        npy_format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False,
                                               "shape": (6000, 6000)})
        chunk = bytes(2**24)
        for _ in range(8 * 6000 * 6000 // len(chunk)):
            fh.write(chunk)
        fh.write(bytes(8 * 6000 * 6000 % len(chunk)))
    assert path.stat().st_size < 2**21
    sizes = []
    real = np.lib.format.read_array

    def spy(fp, *args, **kwargs):
        out = real(fp, *args, **kwargs)
        sizes.append(out.nbytes)
        return out
    monkeypatch.setattr(np.lib.format, "read_array", spy)
    fe = load_fe_npz(path)
    assert max(sizes) < 2**20
    np.testing.assert_array_equal(fe.mass_matrix.toarray(), ref.mass_matrix.toarray())
    assert "junk" not in fe.inputs


def test_fe_npz_member_header_over_budget(tmp_path):
    """A used member (``mass``) whose header declares (1e6, 1e6) floats: refused from the
    header, naming the member and the limit, before any allocation."""
    from casmbd.model.fe_import import load_fe_npz
    path = tmp_path / "fe.npz"
    _beam_fe(path)
    with zipfile.ZipFile(path) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    with zipfile.ZipFile(path, "w") as zf:
        for k, v in members.items():
            if k.startswith("mass_"):
                continue
            zf.writestr(k, v)
        with zf.open("mass.npy", "w") as fh:
            npy_format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False,
                                                   "shape": (10**6, 10**6)})
            fh.write(bytes(800))
    with pytest.raises(ModelError, match=r"fe\.npz.*member 'mass' declares shape "
                                         r"\(1000000, 1000000\).*forged or truncated"):
        load_fe_npz(path)


@pytest.fixture(scope="module")
def good_result(tmp_path_factory):
    """The arrays of a valid simulation result file (5 output times)."""
    path = tmp_path_factory.mktemp("good") / "good.npz"
    mech = loads_scene(PENDULUM)
    res = simulate(mech, t_end=0.2, steps=4, mode="vm")
    res.attach_scene(mech)
    res.save(path)
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def _forge(path, arrays: dict, key: str, shape) -> None:
    """``arrays`` as an npz file, with member ``key`` replaced by a bare ``.npy`` header that
    declares ``shape`` float64 over 800 bytes of zeros."""
    with zipfile.ZipFile(path, "w") as zf:
        for k, v in arrays.items():
            if k != key:
                with zf.open(k + ".npy", "w") as fh:
                    npy_format.write_array(fh, np.asanyarray(v), allow_pickle=False)
        with zf.open(key + ".npy", "w") as fh:
            npy_format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False,
                                                   "shape": tuple(shape)})
            fh.write(bytes(800))


def test_result_header_declaring_1e6_by_1e6_is_refused_before_allocation(good_result,
                                                                          tmp_path, capsys):
    """The header of member 'array/q' declares (1e6, 1e6) floats (8 TB) in a file of a few
    kB: refused from the header (it passed the old 4 GiB check of the zip sizes and ended
    in an internal MemoryError)."""
    path = tmp_path / "forged.npz"
    _forge(path, good_result, "array/q", (10**6, 10**6))
    assert path.stat().st_size < 2**16
    with pytest.raises(ResultFileError, match=r"forged\.npz.*member 'array/q' declares "
                                              r"shape \(1000000, 1000000\).*forged"):
        load(path)
    out = tmp_path / "plot.png"
    assert main(["plot", str(path), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "member 'array/q'" in err and "Traceback" not in err and not out.exists()


def test_result_arrays_over_the_budget_name_the_member_and_limit(good_result, tmp_path,
                                                                 monkeypatch):
    """Honest headers (a deflated file of a few kB) whose arrays together exceed the budget
    (CASMBD_MEMORY_BUDGET=64K here; a member of 5 × 20000 floats takes 781 KB): LimitError
    naming the member that crosses it, the limit and its source."""
    monkeypatch.setenv("CASMBD_MEMORY_BUDGET", "64K")
    path = tmp_path / "big.npz"
    arrays = dict(good_result)
    arrays["array/q"] = np.zeros((5, 20000))
    np.savez_compressed(path, **arrays)
    assert path.stat().st_size < 64 * 1024
    with pytest.raises(LimitError, match=r"big\.npz.*member 'array/q' \(shape \(5, 20000\), "
                                         r"float64\).*over the limit of 64\.0 KB "
                                         r"\(the memory budget, \$CASMBD_MEMORY_BUDGET\)"):
        load(path)


def test_animate_of_a_result_whose_scene_names_dev_zero(good_result, tmp_path, capsys):
    """The scene stored in a result file names ``urdf = "/dev/zero"``: ``animate`` refuses it
    naming the file (it used to read /dev/zero until MemoryError)."""
    arrays = dict(good_result)
    arrays["scene"] = np.array(URDF_SCENE.format(urdf="/dev/zero"))
    path = tmp_path / "res.npz"
    np.savez(path, **arrays)
    out = tmp_path / "a.gif"
    assert main(["animate", str(path), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "'/dev/zero' is a device" in err and "Traceback" not in err
    assert not out.exists()


BEAM = """
[scene]
name = "cantilever"
gravity = [0.0, -9.81]

[[bodies]]
name = "rod"
type = "flexible"
modes = {modes}
reduction = "free"
[bodies.beam]
length = 1.0
elements = {elements}
EI = 71.68
EA = 1.344e7
rhoA = 0.5024
"""


def test_ten_million_beam_elements_refused_before_building(monkeypatch):
    """``elements = 10000000`` used to grow past 3.4 GB; now refused from the count, before
    any element matrix is built."""
    from casmbd.limits import MAX_BEAM_ELEMENTS
    with pytest.raises((LimitError, SceneError),
                       match=rf"rod.*elements: 10,000,000 exceeds the limit of "
                             rf"{MAX_BEAM_ELEMENTS:,}"):
        loads_scene(BEAM.format(modes=4, elements=10_000_000))


def test_too_many_modes_refused_before_reduction():
    from casmbd.limits import MAX_MODES
    with pytest.raises((LimitError, SceneError),
                       match=rf"modes: 5,000 exceeds the limit of {MAX_MODES:,}"):
        loads_scene(BEAM.format(modes=5000, elements=4))


_CACHE_CHILD = """
import json, os, pathlib, sys
from casmbd.compiled import cache, modelkey
from casmbd.limits import MAX_RECORD_BYTES
d = pathlib.Path(sys.argv[1])
lib = d / "lib.so"
lib.write_bytes(b"x")
rec = cache.record_path(lib)
os.mkfifo(rec)                                   # the record is a FIFO
print("fifo record:", cache.check_entry(lib, "k", None))
print("fifo model record:", modelkey._read(rec, "k")[1])
os.remove(rec)
with open(rec, "wb") as fh:                      # a sparse record over the limit
    fh.truncate(MAX_RECORD_BYTES + 1)
print("big record:", cache.check_entry(lib, "k", None))
os.remove(rec)
rec.write_text(json.dumps({"format": cache.RECORD_FORMAT, "key": "k", "size": 1,
                           "sha256": cache.file_sha256(lib)}))
os.remove(lib)
os.mkfifo(lib)                                   # the library is a FIFO
print("fifo library:", cache.check_entry(lib, "k", None))
"""


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_cache_records_and_libraries_that_are_fifos_or_too_large(tmp_path):
    """Damaged cache entries are refused without blocking or reading them whole: the entry is
    rebuilt (check_entry gives the reason), as for any other damage."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    proc = subprocess.run([sys.executable, "-c", _CACHE_CHILD, str(tmp_path)], cwd=root,
                          capture_output=True, text=True, timeout=120)
    out = dict(line.split(": ", 1) for line in proc.stdout.splitlines())
    assert len(out) == 4, proc.stdout + proc.stderr
    assert "cannot be read" in out["fifo record"] and "is a FIFO" in out["fifo record"]
    assert "cannot be read" in out["fifo model record"] and "FIFO" in out["fifo model record"]
    assert "16.0 MB" in out["big record"] and "limit" in out["big record"]
    assert out["fifo library"] == "it is not a regular file"
