"""The ``casmbd`` command: verbs, JSON output, npz files, exit statuses and error lines.

Most tests call :func:`casmbd.cli.main` in-process (captured with ``capsys``); a few run
``python -m casmbd`` as a subprocess to check the real exit status and streams.
"""

from __future__ import annotations

import json
import math
import os
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import private_cache

from casmbd import cli, results
from casmbd.errors import CasmbdError, SceneError

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
SLIDER_CRANK = str(REPO_ROOT / "examples" / "slider_crank.toml")
DOUBLE_PENDULUM = str(REPO_ROOT / "examples" / "double_pendulum.toml")

UNKNOWN_BODY_SCENE = """\
[scene]
name = "broken"

[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.1
position = [0.5, 0.0]

[[joints]]
name = "pivot"
type = "revolute"
body1 = "ground"
body2 = "wheel"
point = [0.0, 0.0]
"""


_cache = private_cache("casmbd_cache_cli", scope="module", CASMBD_COMPILE=None)


def run(capsys, *argv: str) -> tuple[int, str, str]:
    """Run the CLI in-process; return (status, stdout, stderr)."""
    status = cli.main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def run_subprocess(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "casmbd", *argv], cwd=REPO_ROOT,
                          capture_output=True, text=True, timeout=120, env=dict(os.environ))


def assert_one_error_line(err: str, *fragments: str) -> str:
    """stderr is exactly one line ``error: …`` (no traceback) containing every fragment."""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], f"{fragment!r} not in {lines[0]!r}"
    return lines[0]


@pytest.fixture
def slider_json(capsys, tmp_path) -> tuple[dict, pathlib.Path]:
    out_file = tmp_path / "slider.npz"
    status, out, err = run(capsys, "kinematics", SLIDER_CRANK, "--t-end", "1", "--steps", "20",
                           "--json", "--out", str(out_file))
    assert status == 0, err
    assert err == ""
    assert out.count("\n") == 1  # exactly one JSON object on one line
    return json.loads(out), out_file


# ---------------------------------------------------------------------- info
def pinned_absolute(tmp_path, scene: str) -> str:
    """A copy of ``scene`` with ``coordinates = "absolute"`` (the default is the automatic
    choice)."""
    path = tmp_path / ("absolute_" + pathlib.Path(scene).name)
    text = pathlib.Path(scene).read_text()
    path.write_text(text.replace("[scene]\n", '[scene]\ncoordinates = "absolute"\n', 1))
    return str(path)


def test_info_slider_crank_json(capsys, tmp_path):
    """Automatic choice: joint coordinates of the tree O, A, slide, closed by B (2 equations)
    plus the crank driver; pinned to absolute coordinates: 9 coordinates, 9 equations."""
    status, out, err = run(capsys, "info", SLIDER_CRANK, "--json")
    assert status == 0, err
    data = json.loads(out)
    assert isinstance(data, dict)
    for key in ("coordinates", "constraints", "degrees_of_freedom", "redundant_equations"):
        assert key in data
    assert data["degrees_of_freedom"] == 0
    assert data["redundant_equations"] == []
    assert data["coordinate_choice"] == "joint"
    assert data["coordinates"] == ["O.angle", "A.angle", "slide.translation"]
    assert data["constraints"] == [
        {"kind": "joint", "joint": "B", "equation": "x"},
        {"kind": "joint", "joint": "B", "equation": "y"},
        {"kind": "driver", "joint": "crank_speed", "equation": "coordinate"}]
    status, out, err = run(capsys, "info", pinned_absolute(tmp_path, SLIDER_CRANK), "--json")
    assert status == 0, err
    data = json.loads(out)
    assert data["degrees_of_freedom"] == 0 and data["redundant_equations"] == []
    assert "slider.x" in data["coordinates"] and len(data["coordinates"]) == 9
    assert {"kind": "driver", "joint": "crank_speed", "equation": "coordinate"} in \
        data["constraints"]
    assert {"kind": "joint", "joint": "slide", "equation": "normal"} in data["constraints"]
    assert len(data["constraints"]) == 9


def test_info_double_pendulum_json(capsys):
    status, out, err = run(capsys, "info", DOUBLE_PENDULUM, "--json")
    assert status == 0, err
    data = json.loads(out)
    assert data["degrees_of_freedom"] == 2
    assert data["redundant_equations"] == []


def test_info_summary_names_coordinates_and_dof(capsys, tmp_path):
    status, out, _ = run(capsys, "info", DOUBLE_PENDULUM)
    assert status == 0
    assert "double_pendulum" in out and "joint coordinates" in out
    assert "coordinates (2): shoulder.angle, elbow.angle" in out
    assert "coordinate choice: a tree: 2 joint coordinates, no loop equations" in out
    assert "degrees of freedom: 2" in out
    status, out, _ = run(capsys, "info", pinned_absolute(tmp_path, DOUBLE_PENDULUM))
    assert status == 0
    assert "rod1.angle" in out and "rod2.x" in out and "absolute coordinates" in out
    assert "coordinate choice: given" in out
    assert "degrees of freedom: 2" in out


def test_info_subprocess_json():
    proc = run_subprocess("info", "examples/slider_crank.toml", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["degrees_of_freedom"] == 0 and data["redundant_equations"] == []


# ---------------------------------------------------------------------- kinematics
def test_kinematics_json_contract(slider_json):
    data, _ = slider_json
    t = data["t"]
    assert len(t) == 21 and t[0] == 0.0 and t[-1] == 1.0
    assert np.allclose(np.diff(t), 0.05)
    assert set(data["bodies"]) == {"crank", "rod", "slider"}
    for name in ("crank", "rod", "slider"):
        pos = np.array(data["bodies"][name]["position"])
        assert pos.shape == (21, 2)
        assert len(data["bodies"][name]["angle"]) == 21
    for name in ("O", "A", "B", "slide"):
        coordinate = data["joints"][name]["coordinate"]
        assert isinstance(coordinate, list) and len(coordinate) == 21
    assert data["constraint_violation"] < 1e-10
    assert "solve_seconds" in data["stats"] and "build_seconds" in data["stats"]
    assert data["stats"]["solve_seconds"] >= 0.0


def test_kinematics_json_values(slider_json):
    data, _ = slider_json
    slider = np.array(data["bodies"]["slider"]["position"])
    assert abs(slider[0, 0] - 0.4) <= 1e-12
    assert np.allclose(slider[:, 1], 0.0, atol=1e-12)
    # crank driven at omega * t with omega = 2 pi: one turn in one second
    crank_angle = np.array(data["joints"]["O"]["coordinate"])
    assert np.allclose(crank_angle, 2 * math.pi * np.array(data["t"]), atol=1e-10)
    # exact slider-crank position: x = r cos(phi) + sqrt(l^2 - r^2 sin^2(phi))
    phi = 2 * math.pi * np.array(data["t"])
    exact = 0.1 * np.cos(phi) + np.sqrt(0.3**2 - (0.1 * np.sin(phi)) ** 2)
    assert np.allclose(slider[:, 0], exact, atol=1e-10)


def test_kinematics_out_npz_reloads(slider_json):
    data, out_file = slider_json
    assert out_file.is_file()
    res = results.load(out_file)
    assert res.kind == "kinematics"
    np.testing.assert_array_equal(res.t, np.array(data["t"]))
    for name in ("crank", "rod", "slider"):
        b = res.body(name)
        np.testing.assert_array_equal(b["position"], np.array(data["bodies"][name]["position"]))
        np.testing.assert_array_equal(b["angle"], np.array(data["bodies"][name]["angle"]))
    np.testing.assert_array_equal(res.joint("O")["coordinate"],
                                  np.array(data["joints"]["O"]["coordinate"]))
    # the reloaded result gives the same JSON view (stats aside)
    again = res.to_json()
    for key in ("t", "bodies", "joints", "markers", "constraint_violation"):
        assert again[key] == data[key]
    assert "slider_crank" in res.scene


def test_kinematics_summary_prints_body_names(capsys):
    status, out, err = run(capsys, "kinematics", SLIDER_CRANK, "--t-end", "1", "--steps", "4")
    assert status == 0, err
    for name in ("crank", "rod", "slider"):
        assert f"body {name}" in out
    assert "joint slide" in out
    assert "5 times from 0 to 1" in out


def test_kinematics_subprocess_json(tmp_path):
    out_file = tmp_path / "sub.npz"
    proc = run_subprocess("kinematics", "examples/slider_crank.toml", "--t-end", "1",
                          "--steps", "20", "--json", "--out", str(out_file))
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert len(data["t"]) == 21
    assert abs(data["bodies"]["slider"]["position"][0][0] - 0.4) <= 1e-12
    np.testing.assert_array_equal(results.load(out_file).t, np.array(data["t"]))


# ---------------------------------------------------------------------- errors
def test_bad_scene_path(capsys, tmp_path):
    missing = tmp_path / "no_such_scene.toml"
    status, out, err = run(capsys, "info", str(missing), "--json")
    assert status == 1
    assert out == ""
    assert_one_error_line(err, "no_such_scene.toml")


def test_bad_scene_path_subprocess():
    proc = run_subprocess("kinematics", "examples/missing_scene.toml", "--t-end", "1",
                          "--steps", "4")
    assert proc.returncode == 1
    assert proc.stdout == ""
    assert_one_error_line(proc.stderr, "missing_scene.toml")


@pytest.mark.parametrize(
    ("options", "fragment"),
    [
        (["--t-end", "1", "--steps", "0"], "--steps"),
        (["--t-end", "1", "--steps", "x"], "--steps"),
        (["--steps", "4"], "--t-end"),
        (["--t-end", "-1", "--steps", "4"], "--t-end"),
        (["--t-end", "nan", "--steps", "4"], "--t-end"),
        (["--t-end", "1", "--steps", "4", "--mode", "fast"], "--mode"),
    ],
    ids=["steps-0", "steps-x", "missing-t-end", "t-end-negative", "t-end-nan", "bad-mode"],
)
def test_bad_options_exit_2(capsys, options, fragment):
    status, out, err = run(capsys, "kinematics", SLIDER_CRANK, *options)
    assert status == 2
    assert out == ""
    assert_one_error_line(err, fragment)


def test_bad_option_subprocess():
    proc = run_subprocess("kinematics", "examples/slider_crank.toml", "--t-end", "1",
                          "--steps", "0")
    assert proc.returncode == 2
    assert_one_error_line(proc.stderr, "--steps")


def test_missing_and_unknown_verb(capsys):
    status, _, err = run(capsys)
    assert status == 2
    assert_one_error_line(err, "verb")
    status, _, err = run(capsys, "teleport", SLIDER_CRANK)
    assert status == 2
    assert_one_error_line(err, "teleport")


def test_scene_with_unknown_body(capsys, tmp_path):
    scene = tmp_path / "broken.toml"
    scene.write_text(UNKNOWN_BODY_SCENE, encoding="utf-8")
    for argv in (["info", str(scene)],
                 ["kinematics", str(scene), "--t-end", "1", "--steps", "2", "--json"]):
        status, out, err = run(capsys, *argv)
        assert status == 1
        assert out == ""
        assert_one_error_line(err, "'wheel'", "'pivot'")


def test_undriven_kinematics_is_an_error(capsys):
    status, out, err = run(capsys, "kinematics", DOUBLE_PENDULUM, "--t-end", "1", "--steps", "2")
    assert status == 1 and out == ""
    assert_one_error_line(err, "degree", "double_pendulum")


def test_debug_propagates_the_exception(capsys, tmp_path):
    missing = tmp_path / "no_such_scene.toml"
    with pytest.raises(SceneError, match=re.escape(missing.name)):
        cli.main(["info", str(missing), "--debug"])
    scene = tmp_path / "broken.toml"
    scene.write_text(UNKNOWN_BODY_SCENE, encoding="utf-8")
    with pytest.raises(CasmbdError, match="wheel"):
        cli.main(["kinematics", str(scene), "--t-end", "1", "--steps", "2", "--debug"])


def test_debug_shows_traceback_subprocess():
    proc = run_subprocess("info", "examples/missing_scene.toml", "--debug")
    assert proc.returncode != 0
    assert "Traceback" in proc.stderr
    assert "SceneError" in proc.stderr and "missing_scene.toml" in proc.stderr


def test_out_is_a_directory(capsys, tmp_path):
    status, _, err = run(capsys, "kinematics", SLIDER_CRANK, "--t-end", "1", "--steps", "2",
                         "--out", str(tmp_path))
    assert status == 1
    line = assert_one_error_line(err)
    assert "internal error" not in line
    assert "--out" in line or str(tmp_path) in line


def test_absurd_step_count(capsys):
    status, _, err = run(capsys, "kinematics", SLIDER_CRANK, "--t-end", "1", "--steps",
                         "99999999999999999999")
    assert status in (1, 2)
    line = assert_one_error_line(err, "steps")
    assert "internal error" not in line


DOUBLE_PENDULUM = str(REPO_ROOT / "examples" / "double_pendulum.toml")


def test_simulate_json_contract(capsys, tmp_path):
    """simulate --json: the foundation keys plus reactions, efforts, energy and solver stats."""
    out = tmp_path / "dp.npz"
    status, stdout, _ = run(capsys, "simulate", DOUBLE_PENDULUM, "--t-end", "1", "--steps",
                            "10", "--rtol", "1e-9", "--json", "--out", str(out))
    assert status == 0
    data = json.loads(stdout)
    assert len(data["t"]) == 11 and data["t"][-1] == 1.0
    for key in ("bodies", "joints", "drivers", "energy", "constraint_violation", "stats"):
        assert key in data
    for key in ("solve_seconds", "build_seconds", "steps", "rhs_evaluations",
                "jacobian_evaluations"):
        assert key in data["stats"]
    assert len(data["joints"]["shoulder"]["reaction"]) == 11
    assert len(data["joints"]["shoulder"]["reaction"][0]) == 3
    # released at rest: the total energy stays at its initial value (zero) to the tolerance
    assert max(abs(e) for e in data["energy"]["total"]) < 1e-6
    assert data["constraint_violation"] < 1e-6
    reloaded = results.load(out)
    assert np.allclose(reloaded["total_energy"], data["energy"]["total"], rtol=0, atol=0)


def test_simulate_rejects_bad_pairing(capsys):
    status, _, err = run(capsys, "simulate", DOUBLE_PENDULUM, "--t-end", "1", "--steps", "2",
                         "--formulation", "index1", "--integrator", "rk4")
    assert status == 1
    assert_one_error_line(err, "rk4", "index1")


def test_simulate_failure_saves_partial_results(capsys, tmp_path):
    """An integrator failure: one error line with time and flag, partial results saved."""
    out = tmp_path / "partial.npz"
    status, stdout, err = run(capsys, "simulate", DOUBLE_PENDULUM, "--t-end", "5", "--steps",
                              "50", "--rtol", "1e-10", "--formulation", "kkt_ode",
                              "--integrator", "adams", "--max-steps", "60", "--out", str(out))
    assert status == 1
    line = assert_one_error_line(err, "t = ", "CV_TOO_MUCH_WORK")
    assert "partial results saved" in line
    assert stdout == ""
    partial = results.load(out)
    assert len(partial.t) < 51


def test_inverse_json_driver_effort(capsys):
    """inverse --json: driver efforts on the grid; at t = 0 the crank is horizontal and at
    rest in angular acceleration, so the torque holds the weights: g (m_c r/2 + …) > 0."""
    status, stdout, _ = run(capsys, "inverse", SLIDER_CRANK, "--t-end", "1", "--steps", "4",
                            "--json")
    assert status == 0
    data = json.loads(stdout)
    effort = data["drivers"]["crank_speed"]["effort"]
    assert len(effort) == 5
    assert effort[0] > 0
    assert abs(effort[0] - effort[-1]) < 1e-9  # periodic motion over one turn
    assert len(data["joints"]["O"]["reaction"]) == 5


def test_warnings_print_as_one_line_and_debug_keeps_the_source(tmp_path):
    """A warning on the command line is one ``warning: …`` line (here a URDF's <mimic> of a
    fixed joint, ignored); ``--debug`` keeps Python's form with the file and category."""
    urdf = tmp_path / "r.urdf"
    urdf.write_text(
        '<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
        '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        '<link name="c"/><joint name="f" type="fixed"><parent link="b"/><child link="c"/>'
        '<mimic joint="j" multiplier="1"/></joint></robot>')
    env = {**os.environ, "CASMBD_COMPILE": "0", "CASMBD_CACHE_DIR": str(tmp_path)}
    runs = [subprocess.run([sys.executable, "-m", "casmbd", "info", str(urdf), *extra],
                           capture_output=True, text=True, env=env, timeout=120)
            for extra in ([], ["--debug"])]
    plain, debug = (r.stderr.strip().splitlines() for r in runs)
    assert runs[0].returncode == 0 and runs[1].returncode == 0
    assert plain == ["warning: URDF 'r': <mimic> of a fixed joint ignored for f"]
    assert any("RuntimeWarning" in line for line in debug)
