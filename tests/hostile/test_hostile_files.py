"""Hostile input, files (issue 31 item 6): ``--out`` never replaces an input, the suffix decides
the format (``.npz``, ``.csv``, others refused), and a save killed half-way leaves nothing
behind for long.

Every refusal asserts the error class or exit status 1 with one ``error:`` line naming the file,
and that nothing was written (the inputs byte for byte unchanged, no new file in the folder).
"""

from __future__ import annotations

import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import private_cache

from casmbd import cli
from casmbd.compiled import modal_cache
from casmbd.errors import ResultFileError
from casmbd.io.scene import load_scene
from casmbd.model import modal_reduction
from casmbd.model.fe_beam import beam_model
from casmbd.model.fe_import import save_fe_npz
from casmbd.results import (
    STALE_TEMP_SECONDS,
    TEMP_PREFIX,
    atomic_write,
    remove_stale_temporaries,
)
from casmbd.results import load as load_result

ROOT = pathlib.Path(__file__).resolve().parents[2]
PENDULUM = ROOT / "examples" / "double_pendulum.toml"
URDF = ROOT / "tests" / "scenes" / "ur5_arm.urdf"

_env = private_cache(CASMBD_COMPILE="0", CASMBD_PROGRESS="0")


def run(capsys, *argv) -> tuple[int, str, str]:
    code = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_error(err: str) -> str:
    lines = err.strip().splitlines()
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1 and "Traceback" not in err, err
    return errors[0]


def snapshot(folder: pathlib.Path) -> dict:
    """Every file below ``folder`` (hidden ones too) with its bytes."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


@pytest.fixture
def scene(tmp_path) -> pathlib.Path:
    path = tmp_path / "dp.toml"
    shutil.copy(PENDULUM, path)
    return path


# ------------------------------------------------------------------ --out is never an input
@pytest.mark.parametrize("spelling", ["same", "dotdot", "symlink", "hardlink"])
def test_out_never_replaces_the_scene(tmp_path, scene, capsys, monkeypatch, spelling):
    """``simulate dp.toml --out dp.toml`` (and the same file under another name: ``sub/..``,
    a symbolic or a hard link) is refused before anything runs; the scene is unchanged."""
    (tmp_path / "sub").mkdir()
    out = {"same": scene, "dotdot": tmp_path / "sub" / ".." / "dp.toml"}.get(spelling)
    if spelling == "symlink":
        out = tmp_path / "link.npz"
        out.symlink_to(scene)
    elif spelling == "hardlink":
        out = tmp_path / "hard.npz"
        os.link(scene, out)
    before = snapshot(tmp_path)
    code, stdout, err = run(capsys, "simulate", scene, "--t-end", "0.1", "--steps", "2",
                            "--mode", "vm", "--json", "--out", out)
    assert code == 1 and stdout == ""
    line = one_error(err)
    assert f"--out '{out}' is the scene file '{scene}'" in line and "nothing written" in line
    assert snapshot(tmp_path) == before


def test_out_never_replaces_the_urdf_the_scene_reads(tmp_path, capsys):
    """A URDF named ``robot.csv`` read by the scene: ``--out robot.csv`` is refused after the
    scene is read (the URDF is known only then), before the analysis."""
    shutil.copy(URDF, tmp_path / "robot.csv")
    scene = tmp_path / "arm.toml"
    scene.write_text('[scene]\nname = "arm"\ncoordinates = "joint"\nurdf = "robot.csv"\n')
    before = snapshot(tmp_path)
    code, stdout, err = run(capsys, "simulate", scene, "--t-end", "0.01", "--steps", "2",
                            "--mode", "vm", "--out", tmp_path / "robot.csv")
    assert code == 1 and stdout == ""
    assert "is the URDF file" in one_error(err) and "robot.csv" in one_error(err)
    assert snapshot(tmp_path) == before


def test_out_never_replaces_the_fe_model_the_scene_reads(tmp_path, capsys):
    """A flexible body's ``[bodies.fe] file = "bar.npz"``: ``--out bar.npz`` is refused,
    naming the body; the FE file is unchanged."""
    # a plane truss (2 dofs per node): two square bays with diagonals, pinned at both ends
    nodes = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], float)
    K, M = np.zeros((12, 12)), np.zeros((12, 12))
    for a, b in [(0, 1), (1, 2), (3, 4), (4, 5), (0, 3), (1, 4), (2, 5), (0, 4), (1, 5)]:
        d = nodes[b] - nodes[a]
        h = np.linalg.norm(d)
        c = np.r_[-d, d] / h
        idx = [2 * a, 2 * a + 1, 2 * b, 2 * b + 1]
        K[np.ix_(idx, idx)] += 1e6 / h * np.outer(c, c)
        M[np.ix_(idx, idx)] += 2.0 * h / 6 * np.kron([[2.0, 1.0], [1.0, 2.0]], np.eye(2))
    save_fe_npz(tmp_path / "bar.npz", sp.csr_matrix(M), sp.csr_matrix(K), nodes, 2,
                node_names={"left": 0, "right": 5})
    scene = tmp_path / "flex.toml"
    scene.write_text('[scene]\nname = "flex"\ngravity = [0.0, 0.0]\n\n[[bodies]]\n'
                     'name = "bar"\ntype = "flexible"\nposition = [0.0, 0.0]\nmodes = 2\n'
                     'interfaces = ["left", "right"]\n[bodies.fe]\nfile = "bar.npz"\n')
    assert run(capsys, "info", scene)[0] == 0             # a scene that loads
    before = snapshot(tmp_path)
    code, _, err = run(capsys, "simulate", scene, "--t-end", "0.01", "--steps", "2",
                       "--mode", "vm", "--out", tmp_path / "bar.npz")
    assert code == 1
    line = one_error(err)
    assert f"--out '{tmp_path / 'bar.npz'}' is the FE model of body 'bar'" in line, line
    assert snapshot(tmp_path) == before


def test_animate_never_replaces_the_urdf_the_scene_reads(tmp_path, capsys):
    """``animate arm.toml --out robot.png`` with ``urdf = "robot.png"``: before, the still frame
    replaced the URDF (exit 0); now one error line names the URDF file, nothing is written."""
    shutil.copy(URDF, tmp_path / "robot.png")
    scene = tmp_path / "arm.toml"
    scene.write_text('[scene]\nname = "arm"\ncoordinates = "joint"\nurdf = "robot.png"\n')
    before = snapshot(tmp_path)
    code, stdout, err = run(capsys, "animate", scene, "--t-end", "0.01", "--steps", "2",
                            "--mode", "vm", "--out", tmp_path / "robot.png")
    assert code == 1 and stdout == ""
    line = one_error(err)
    assert f"--out '{tmp_path / 'robot.png'}' is the URDF file" in line, line
    assert "nothing written" in line
    assert snapshot(tmp_path) == before


def test_plot_and_animate_never_replace_the_result_they_read(tmp_path, scene, capsys):
    result = tmp_path / "run.npz"
    code, _, err = run(capsys, "simulate", scene, "--t-end", "0.1", "--steps", "2",
                       "--mode", "vm", "--out", result)
    assert code == 0, err
    before = snapshot(tmp_path)
    for verb, arg in (("plot", result), ("animate", result)):
        code, stdout, err = run(capsys, verb, arg, "--out", result, "--json")
        assert code == 1 and stdout == ""
        line = one_error(err)
        assert f"--out '{result}' is the" in line and "nothing written" in line, line
    assert snapshot(tmp_path) == before


# ------------------------------------------------------------------ the suffix decides
def test_out_csv_writes_csv_and_npz_writes_npz(tmp_path, scene, capsys):
    """``--out run.csv`` is a CSV file (header, one column per scalar series, 17 significant
    digits): its numbers equal those of ``--out run.npz`` exactly (the same simulation, the
    VM is deterministic), and the npz file is a zip archive."""
    args = ("simulate", scene, "--t-end", "0.2", "--steps", "4", "--mode", "vm")
    assert run(capsys, *args, "--out", tmp_path / "run.csv")[0] == 0
    assert run(capsys, *args, "--out", tmp_path / "RUN.NPZ")[0] == 0
    text = (tmp_path / "run.csv").read_text()
    assert not text.startswith("PK")                      # not a zip (npz) archive
    header = text.splitlines()[0].split(",")
    table = np.loadtxt(tmp_path / "run.csv", delimiter=",", skiprows=1)
    res = load_result(tmp_path / "RUN.NPZ")
    assert (tmp_path / "RUN.NPZ").read_bytes()[:2] == b"PK"
    assert header[0] == "t" and table.shape == (5, len(header))
    np.testing.assert_array_equal(table[:, 0], res.t)
    q = res["q"]
    for k, name in enumerate(res.names["coordinates"]):
        np.testing.assert_array_equal(table[:, header.index(f"q[{name}]")], q[:, k])
    np.testing.assert_array_equal(table[:, header.index("total_energy")], res["total_energy"])


@pytest.mark.parametrize("name", ["run.txt", "run", "run.npz.bak", "run.json"])
def test_other_suffixes_are_refused_by_name(tmp_path, scene, capsys, name):
    before = snapshot(tmp_path)
    code, stdout, err = run(capsys, "simulate", scene, "--t-end", "0.1", "--steps", "2",
                            "--mode", "vm", "--json", "--out", tmp_path / name)
    assert code == 1 and stdout == ""
    line = one_error(err)
    assert f"--out '{tmp_path / name}': unknown suffix" in line and ".npz" in line
    assert snapshot(tmp_path) == before


def test_result_save_and_to_csv_refuse_the_other_suffix(tmp_path):
    from casmbd.analysis.driven.kinematics import kinematics

    mech = load_scene(ROOT / "examples" / "slider_crank.toml")
    res = kinematics(mech, t_end=0.1, steps=2, mode="vm")
    for name in ("run.csv", "run"):
        with pytest.raises(ResultFileError, match=rf"'{tmp_path / name}': a result file is "
                                                  r"written as \.npz"):
            res.save(tmp_path / name)
    with pytest.raises(ResultFileError, match=rf"'{tmp_path / 'run.npz'}': to_csv writes a "
                                              r"\.csv file"):
        res.to_csv(tmp_path / "run.npz")
    assert list(tmp_path.iterdir()) == []
    res.to_csv(tmp_path / "run.csv")                      # the CSV has its own method
    assert (tmp_path / "run.csv").read_text().startswith("t,")


# ------------------------------------------------------------------ interrupted saves
KILLED_SAVE = """
import sys, time
from casmbd.results import atomic_write
def write(tmp):
    with open(tmp, "wb") as fh:
        fh.write(b"x" * 1_000_000)
        fh.flush()
        print(tmp, flush=True)
        time.sleep(600)
atomic_write(sys.argv[1], write)
"""


def start_save(target: pathlib.Path) -> tuple[subprocess.Popen, pathlib.Path]:
    """A process stopped inside a save of ``target``: its temporary file exists."""
    proc = subprocess.Popen([sys.executable, "-c", KILLED_SAVE, str(target)],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT)
    tmp = pathlib.Path(proc.stdout.readline().strip())
    assert tmp.name.startswith(TEMP_PREFIX) and tmp.stat().st_size == 1_000_000
    return proc, tmp


def test_a_killed_save_leaves_nothing_after_the_next_save(tmp_path, scene, capsys):
    """SIGKILL during a save leaves its temporary file (no ``finally`` runs); the next save in
    that folder — here the CLI's ``simulate --out`` — removes it.  The temporary file of a
    save still running and a hidden file of another program are kept."""
    killed, stale = start_save(tmp_path / "big.npz")
    killed.send_signal(signal.SIGKILL)
    killed.wait(timeout=60)
    assert stale.exists() and not (tmp_path / "big.npz").exists()
    running, live = start_save(tmp_path / "other.npz")
    try:
        foreign = tmp_path / ".tmp_abc123.npz"            # not atomic_write's name: not ours
        foreign.write_bytes(b"keep")
        code, _, err = run(capsys, "simulate", scene, "--t-end", "0.1", "--steps", "2",
                           "--mode", "vm", "--out", tmp_path / "run.npz")
        assert code == 0, err
        assert not stale.exists()
        assert live.exists() and foreign.exists()
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
            [".tmp_abc123.npz", live.name, "dp.toml", "run.npz"])
    finally:
        running.kill()
        running.wait(timeout=60)
    assert remove_stale_temporaries(tmp_path) == [live]   # its process is gone now


def test_old_temporaries_of_another_host_are_removed_by_age(tmp_path):
    """A shared folder: a temporary file of another host (its process cannot be probed) is
    removed once older than STALE_TEMP_SECONDS (24 h), not before."""
    other = tmp_path / f"{TEMP_PREFIX}00000000-12345-abcd.npz"
    young = tmp_path / f"{TEMP_PREFIX}00000000-12346-abcd.npz"
    for path in (other, young):
        path.write_bytes(b"partial")
    old = time.time() - STALE_TEMP_SECONDS - 60
    os.utime(other, (old, old))
    atomic_write(tmp_path / "r.csv", lambda tmp: pathlib.Path(tmp).write_text("t\n0\n"))
    assert not other.exists() and young.exists()
    assert (tmp_path / "r.csv").read_text() == "t\n0\n"


def test_temporaries_of_older_versions_are_removed_by_age_only(tmp_path):
    """Older versions named their temporaries ``.tmp_`` + 8 characters + the target's suffix
    (``tempfile.mkstemp(prefix=".tmp_")``), with no host or process in the name: such a file
    older than 24 h is removed by the next save; a young one, and every name that is not
    exactly that pattern (6 characters, upper case, another or no suffix, a directory), are
    kept."""
    old = time.time() - STALE_TEMP_SECONDS - 60
    stale = [tmp_path / ".tmp_k3x9_a2b.npz", tmp_path / ".tmp_0abcdefg.csv",
             tmp_path / ".tmp_zz_zz_zz.png"]
    young = tmp_path / ".tmp_q1w2e3r4.npz"
    kept = [tmp_path / ".tmp_abc123.npz", tmp_path / ".tmp_k3x9_a2b.toml",
            tmp_path / ".tmp_K3X9_A2B.npz", tmp_path / ".tmp_k3x9_a2bc.npz",
            tmp_path / "tmp_k3x9_a2b.npz", tmp_path / ".tmp_zz_zz_zz"]
    for path in (*stale, young, *kept):
        path.write_bytes(b"partial")
    folder = tmp_path / ".tmp_abcdefgh.npz"
    folder.mkdir()
    for path in (*stale, *kept, folder):
        os.utime(path, (old, old))
    atomic_write(tmp_path / "r.npz", lambda tmp: pathlib.Path(tmp).write_bytes(b"done"))
    assert not any(p.exists() for p in stale)
    assert young.exists() and folder.is_dir() and all(p.exists() for p in kept)


def test_modal_cache_writes_are_atomic_and_swept(tmp_path, monkeypatch):
    """The modal data files of the compiled cache are written by the same ``atomic_write``:
    a save interrupted inside the write (Ctrl-C) leaves no file behind, and a save removes the
    temporaries a killed writer left in the cache directory."""
    cache = tmp_path / "modalcache"
    cache.mkdir()
    monkeypatch.setenv("CASMBD_CACHE_DIR", str(cache))
    modal = modal_reduction.free_modes(beam_model(2.0, 4, EA=1e6, EI=50.0, rhoA=1.5), 2)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    with monkeypatch.context() as mp:
        mp.setattr(modal_cache.np, "savez", interrupted)
        with pytest.raises(KeyboardInterrupt):
            modal_cache.save_modes("c" * 64, modal)
    assert list(cache.iterdir()) == []
    killed, stale = start_save(cache / "modes_x.npz")
    killed.send_signal(signal.SIGKILL)
    killed.wait(timeout=60)
    assert stale.exists()
    modal_cache.save_modes("c" * 64, modal)
    assert [p.name for p in cache.iterdir()] == [f"modes_{'c' * 32}.npz"]
    np.testing.assert_array_equal(modal_cache.load_modes("c" * 64).stiffness, modal.stiffness)


SLIDER_OCP = """
[scene]
name = "slider"
gravity = [0.0, 0.0]
coordinates = "joint"

[[bodies]]
name = "block"
mass = 1.0
inertia = 0.1
position = [0.0, 0.0]

[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [0.0, 0.0]
axis = [1.0, 0.0]

[[actuators]]
name = "push"
joint = "slide"

[ocp]
horizon = 1.0
intervals = 2
degree = 2
objective = "effort"

[ocp.initial]
slide = 0.0
slide_dot = 0.0

[ocp.final]
slide = 1.0
slide_dot = 0.0
"""


def test_ocp_out_csv_and_plot_onto_the_scene(tmp_path, capsys):
    """``ocp --out sol.csv`` writes the solution's result on the mesh nodes as CSV (it starts
    at rest at 0 and ends at rest at 1 m, to IPOPT's tolerance, pushed by ±4 N: the closed
    form of the 2-interval problem); ``--plot`` onto the scene and
    ``--out`` = ``--plot`` are refused before the solve, nothing written."""
    scene = tmp_path / "slider.toml"
    scene.write_text(SLIDER_OCP)
    before = snapshot(tmp_path)
    for extra in (["--plot", scene], ["--out", tmp_path / "a.npz", "--plot", tmp_path / "a.npz"]):
        code, stdout, err = run(capsys, "ocp", scene, "--mode", "vm", "--no-replay", "--json",
                                *extra)
        assert code == 1 and stdout == ""
        line = one_error(err)
        assert ("is the scene file" in line or "name the same file" in line), line
    assert snapshot(tmp_path) == before
    code, _, err = run(capsys, "ocp", scene, "--mode", "vm", "--no-replay",
                       "--out", tmp_path / "sol.csv")
    assert code == 0, err
    header = (tmp_path / "sol.csv").read_text().splitlines()[0].split(",")
    table = np.loadtxt(tmp_path / "sol.csv", delimiter=",", skiprows=1, ndmin=2)
    x = table[:, header.index("joint_positions[slide]")]
    v = table[:, header.index("joint_velocities[slide]")]
    u = table[:, header.index("actuator_inputs[push.input]")]
    assert table[0, 0] == 0.0 and table[-1, 0] == pytest.approx(1.0, abs=1e-12)
    assert abs(x[0]) < 1e-9 and abs(v[0]) < 1e-9
    assert x[-1] == pytest.approx(1.0, abs=1e-6) and abs(v[-1]) < 1e-6
    # the closed form: a constant push u1 on [0, 0.5] s, u2 = -u1 after; x(1) = u1/4 = 1 m
    assert np.abs(u).max() == pytest.approx(4.0, rel=1e-6)
