"""``casmbd identify``: the JSON contract, the written URDF and scene reload to the identified
inverse dynamics (1e-12), bad input as one named ``error:`` line."""

from __future__ import annotations

import json

import identification_models as arm
import numpy as np
import pytest

import casmbd
from casmbd import cli
from casmbd.analysis.identification.identify import identification_model
from casmbd.io.urdf import load_urdf

COORDS = ["shoulder_pan_joint.angle", "shoulder_lift_joint.angle", "elbow_joint.angle",
          "wrist_1_joint.angle", "wrist_2_joint.angle", "wrist_3_joint.angle"]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("identify")
    truth = arm.ur5_truth()
    t = np.arange(0.0, 10.0, 0.01)
    q, v, a = arm.arm_trajectory(t, 6, seed=1)
    tau = arm.inverse_dynamics(truth, q, v, a)
    full = arm.to_csv(folder / "measured.csv", t, COORDS, q, tau, v, a)
    return dict(folder=folder, truth=truth, full=full, t=t, q=q, v=v, a=a, tau=tau)


def _run(capsys, *argv):
    code = cli.main([*argv, "--mode", "vm", "--json"])
    out, err = capsys.readouterr()
    return code, out, err


def test_identify_urdf_writes_a_model_with_the_identified_dynamics(capsys, data):
    """One JSON object (base parameters with σ, condition number, residuals, the consistent
    set, the file written); the written URDF reloads (with its <dynamics>) to inverse
    dynamics equal to Y π_c of the consistent parameters printed, at 10 random states, to
    1e-12 of the largest torque; noise-free data: residuals below 1e-9 N m."""
    out_file = data["folder"] / "identified.urdf"
    code, out, err = _run(capsys, "identify", arm.UR5, "--data", str(data["full"]),
                          "--out", str(out_file))
    assert code == 0, err
    obj = json.loads(out)
    assert obj["written"] == str(out_file) and out_file.exists()
    assert len(obj["base_parameters"]) == 48 and obj["condition_number"] > 1
    assert max(obj["residual_rms"].values()) < 1e-9
    assert obj["consistent"]["checks"]["consistent"] is True
    row = obj["base_parameters"][0]
    assert set(row) == {"name", "expression", "value", "std", "relative_std_percent"}
    model = load_urdf(arm.UR5, damping=True, friction=True)
    reg, _ = identification_model(model, ("viscous", "coulomb"), mode="vm")
    pi = np.array([obj["consistent"]["parameters"][n] for n in reg.names])
    robot = casmbd.compile(load_urdf(out_file, damping=True, friction=True), mode="vm")
    rng = np.random.default_rng(0)
    for _ in range(10):
        q, v, a = (rng.uniform(-2, 2, 6) for _ in range(3))
        tau = reg(q, v, a) @ pi
        assert np.max(np.abs(robot.inverse_dynamics(q, v, a) - tau)) < 1e-12 * np.max(
            np.abs(tau))


def test_identify_positions_only_and_text_output(capsys, data):
    """q and τ only: --cutoff filters and differentiates (the text summary names the
    condition number and the base parameters); without --cutoff: a named error."""
    t = np.arange(0.0, 10.0, 0.002)
    q, v, a = arm.arm_trajectory(t, 6, seed=1)
    tau = arm.inverse_dynamics(data["truth"], q, v, a)
    path = arm.to_csv(data["folder"] / "q_only.csv", t, COORDS, q, tau)
    code = cli.main(["identify", arm.UR5, "--data", str(path), "--cutoff", "8",
                     "--decimate", "2", "--no-consistent", "--mode", "vm"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "condition number of the stacked base regressor" in out
    assert "base parameters (48)" in out
    code, out, err = _run(capsys, "identify", arm.UR5, "--data", str(path))
    assert code != 0 and out == ""
    assert err.count("error:") == 1 and "--cutoff" in err


def test_identify_bad_input_named(capsys, data):
    """Too few samples; a joint that does not move (its friction and the combinations it
    carries undetermined, named); a NaN (file, line, column); --out of the wrong kind."""
    folder = data["folder"]
    few = arm.to_csv(folder / "few.csv", data["t"][:5], COORDS, data["q"][:5],
                     data["tau"][:5], data["v"][:5], data["a"][:5])
    code, out, err = _run(capsys, "identify", arm.UR5, "--data", str(few))
    assert code != 0 and out == "" and err.count("error:") == 1
    assert "30 equations for 48 base parameters" in err
    q, v, a = data["q"].copy(), data["v"].copy(), data["a"].copy()
    q[:, 5], v[:, 5], a[:, 5] = 0.3, 0.0, 0.0
    still = arm.to_csv(folder / "still.csv", data["t"], COORDS, q, data["tau"], v, a)
    code, out, err = _run(capsys, "identify", arm.UR5, "--data", str(still))
    assert code != 0 and out == "" and "undetermined combination" in err and "wrist_3_joint" in err
    bad = data["full"].read_text().splitlines()
    fields = bad[7].split(",")
    fields[3] = "nan"
    bad[7] = ",".join(fields)
    nan_file = folder / "nan.csv"
    nan_file.write_text("\n".join(bad) + "\n")
    code, out, err = _run(capsys, "identify", arm.UR5, "--data", str(nan_file))
    assert code != 0 and out == "" and "line 8 column 'q.elbow_joint.angle'" in err
    code, out, err = _run(capsys, "identify", arm.UR5, "--data", str(data["full"]),
                          "--out", str(folder / "x.toml"))
    assert code != 0 and out == "" and "a .urdf file" in err


PLANAR = """# planar two-link arm
[scene]
name = "planar_2r"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "link1"
mass = {m1}
inertia = 0.05
position = [0.3, 0.02]

[[bodies]]
name = "link2"
mass = 1.2
inertia = 0.02
position = [0.95, -0.01]

[[joints]]
name = "shoulder"
type = "revolute"
body1 = "ground"
body2 = "link1"
point = [0.0, 0.0]
friction = {{ viscous = {c1} }}

[[joints]]
name = "elbow"
type = "revolute"
body1 = "link1"
body2 = "link2"
point = [0.7, 0.0]
"""


def test_identify_scene_viscous_only(capsys, tmp_path):
    """A planar scene, --friction viscous: the written scene reloads to the true scene's
    inverse dynamics (1e-9 of the largest torque: noise-free, the consistent set is polished
    to the exact fit) and its shoulder friction is the true 0.3 N m s (1e-9)."""
    from casmbd.io.scene import load_scene, loads_scene

    truth = loads_scene(PLANAR.format(m1=2.0, c1=0.3))
    source = tmp_path / "model.toml"
    source.write_text(PLANAR.format(m1=2.5, c1=0.0))
    t = np.arange(0.0, 10.0, 0.01)
    q, v, a = arm.arm_trajectory(t, 2, seed=4)
    tau = arm.inverse_dynamics(truth, q, v, a)
    csv = arm.to_csv(tmp_path / "m.csv", t, ["shoulder.angle", "elbow.angle"], q, tau, v, a)
    out_file = tmp_path / "identified.toml"
    code, out, err = _run(capsys, "identify", str(source), "--data", str(csv),
                          "--friction", "viscous", "--out", str(out_file))
    assert code == 0, err
    obj = json.loads(out)
    assert obj["friction"] == ["viscous"] and len(obj["base_parameters"]) == 8
    assert obj["consistent"]["parameters"]["shoulder.viscous"] == pytest.approx(0.3, abs=1e-9)
    reloaded = casmbd.compile(load_scene(out_file), mode="vm")
    true_robot = casmbd.compile(truth, mode="vm")
    rng = np.random.default_rng(1)
    for _ in range(10):
        x = [rng.uniform(-2, 2, 2) for _ in range(3)]
        tau_true = true_robot.inverse_dynamics(*x)
        assert np.max(np.abs(reloaded.inverse_dynamics(*x) - tau_true)) < 1e-9 * np.max(
            np.abs(tau_true))
