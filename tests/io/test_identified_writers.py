"""The writers of identified models (casmbd.io.identified): a URDF whose <inertial> and
<dynamics> change and nothing else, a scene whose bodies and joint friction change; each
reloads to a model whose inverse dynamics is that of the identified parameters (1e-12)."""

from __future__ import annotations

import re

import identification_models as arm
import numpy as np
import pytest

import casmbd
from casmbd.analysis.identification.identify import identification_model
from casmbd.errors import IdentificationError
from casmbd.io.identified import write_scene, write_urdf
from casmbd.io.scene import load_scene, loads_scene
from casmbd.io.urdf import load_urdf

LAWS = ("viscous", "coulomb")


def _states(n: int, dof: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-2, 2, (n, dof)) for _ in range(3))


def _strip(text: str) -> str:
    text = re.sub(r"<inertial>.*?</inertial>", "", text, flags=re.S)
    return re.sub(r"\s*<dynamics[^>]*/>", "", text)


def test_urdf_writer_round_trip(tmp_path):
    """The true arm's parameters (in the model's frames) written into the model's URDF: the
    reloaded file's inverse dynamics equals the true arm's and Y π_true at 20 random states
    to 1e-12 of the largest torque; outside <inertial> and <dynamics> the text is unchanged."""
    truth, model = arm.ur5_truth(), arm.ur5_model()
    reg, _ = identification_model(model, LAWS, mode="vm")
    pi = arm.true_parameters(truth, reg)
    out = write_urdf(arm.UR5, tmp_path / "identified.urdf", model, reg.names, pi,
                     reg.parameters.origins)
    written = out.read_text()
    original = open(arm.UR5).read()
    assert _strip(written) == _strip(original)
    assert written.count("<inertial>") == original.count("<inertial>")
    reloaded = casmbd.compile(load_urdf(out, damping=True, friction=True), mode="vm")
    true_robot = casmbd.compile(truth, mode="vm")
    for q, v, a in zip(*_states(20, 6), strict=True):
        tau = true_robot.inverse_dynamics(q, v, a)
        scale = np.max(np.abs(tau))
        assert np.max(np.abs(reloaded.inverse_dynamics(q, v, a) - tau)) < 1e-12 * scale
        assert np.max(np.abs(reg(q, v, a) @ pi - tau)) < 1e-12 * scale


SCENE = """# a planar two-link arm (comments kept)
[scene]
name = "planar_2r"
dimension = 2
gravity = [0.0, -9.81]

[parameters]
m1 = {m1}

[[bodies]]
name = "link1"   # the first link
mass = "m1"
inertia = 0.05
position = [
    0.3,
    0.02,
]

[[bodies]]
name = "link2"
mass = {m2}
inertia = 0.02
position = [{x2}, -0.01]

[[joints]]
name = "shoulder"
type = "revolute"
body1 = "ground"
body2 = "link1"
point = [0.0, 0.0]
{f1}

[[joints]]
name = "elbow"
type = "revolute"
body1 = "link1"
body2 = "link2"
point = [0.7, 0.0]

[[forces]]
name = "elbow_friction"
type = "joint_friction"
joint = "elbow"
damping = {d2}
friction = {c2}
"""


def _scene(m1=2.0, m2=1.2, x2=0.95, f1="friction = { viscous = 0.3, coulomb = 0.8 }",
           d2=0.2, c2=0.5):
    return SCENE.format(m1=m1, m2=m2, x2=x2, f1=f1, d2=d2, c2=c2)


def test_scene_writer_round_trip(tmp_path):
    """A model with other masses, another centre of mass of link 2 and no shoulder friction
    gets the true values written: its inverse dynamics then equals the true scene's and
    Y π_true (1e-12); comments, the [parameters] table and the joints stay."""
    truth = loads_scene(_scene())
    source = tmp_path / "model.toml"
    source.write_text(_scene(m1=2.6, m2=1.0, x2=0.9, f1="", d2=0.0, c2=0.0))
    model = load_scene(source)
    reg, _ = identification_model(model, LAWS, mode="vm")
    pi = arm.true_parameters(truth, reg, model)
    out = write_scene(source, tmp_path / "identified.toml", model, reg.names, pi,
                      reg.parameters.origins)
    text = out.read_text()
    assert "# the first link" in text and "m1 = 2.6" in text and "friction = {" in text
    reloaded = casmbd.compile(loads_scene(text), mode="vm")
    true_robot = casmbd.compile(truth, mode="vm")
    for q, v, a in zip(*_states(20, 2), strict=True):
        tau = true_robot.inverse_dynamics(q, v, a)
        scale = np.max(np.abs(tau))
        assert np.max(np.abs(reloaded.inverse_dynamics(q, v, a) - tau)) < 1e-12 * scale
        assert np.max(np.abs(reg(q, v, a) @ pi - tau)) < 1e-12 * scale


def test_writers_refuse_by_name(tmp_path):
    """A non-physical mass; a scene whose bodies come from a URDF."""
    model = loads_scene(_scene())
    reg, _ = identification_model(model, LAWS, mode="vm")
    pi = reg.parameters.values.copy()
    pi[reg.names.index("link2.m")] = -1.0
    source = tmp_path / "s.toml"
    source.write_text(_scene())
    with pytest.raises(IdentificationError, match="body 'link2': mass"):
        write_scene(source, tmp_path / "o.toml", model, reg.names, pi, reg.parameters.origins)
    wrapped = tmp_path / "robot.toml"
    wrapped.write_text(f'[scene]\nname = "r"\ndimension = 3\nurdf = "{arm.UR5}"\n')
    with pytest.raises(IdentificationError, match=r"identify the \.urdf file"):
        write_scene(wrapped, tmp_path / "o2.toml", model, reg.names,
                    reg.parameters.values, reg.parameters.origins)


def test_spatial_scene_writer_round_trip(tmp_path):
    """The UR-like scene (bodies rotated from the world axes) as the model, with another mass
    and centre of mass of the upper arm and the wrist 1: the true values written reload to
    the true scene's inverse dynamics (1e-12 of the largest torque at 20 random states)."""
    import pathlib

    text = (pathlib.Path(arm.UR5).parent / "ur_like.toml").read_text()
    truth = loads_scene(text)
    wrong = text.replace("mass = 8.393", "mass = 7.5").replace(
        "position = [-0.2125, -0.11336, 0.089159]", "position = [-0.2, -0.1, 0.1]").replace(
        "position = [-0.81725, -0.10735, 0.072819]", "position = [-0.8, -0.1, 0.07]")
    source = tmp_path / "ur_model.toml"
    source.write_text(wrong)
    model = load_scene(source)
    reg, _ = identification_model(model, LAWS, mode="vm")
    pi = arm.true_parameters(truth, reg, model)
    out = write_scene(source, tmp_path / "ur_identified.toml", model, reg.names, pi,
                      reg.parameters.origins)
    reloaded = casmbd.compile(load_scene(out), mode="vm")
    true_robot = casmbd.compile(truth, mode="vm")
    for q, v, a in zip(*_states(20, 6), strict=True):
        tau = true_robot.inverse_dynamics(q, v, a)
        scale = np.max(np.abs(tau))
        assert np.max(np.abs(reloaded.inverse_dynamics(q, v, a) - tau)) < 1e-12 * scale
        assert np.max(np.abs(reg(q, v, a) @ pi - tau)) < 1e-12 * scale


def test_urdf_writer_merged_links_and_mimic(tmp_path):
    """A 7-axis arm whose last link carries a flange and a hand through fixed joints, and a
    mimic finger pair: the body's identified inertia goes whole into its first link, the
    merged links lose their <inertial>; the reloaded file's inverse dynamics equals the true
    arm's (1e-12 at 10 random states)."""
    import pathlib

    urdf = str(pathlib.Path(arm.UR5).parent / "arm7_gripper.urdf")
    truth = load_urdf(urdf)
    model = load_urdf(urdf, links={"panda_link3": {"mass": 4.0}})
    reg, _ = identification_model(model, LAWS, mode="vm")
    pi = arm.true_parameters(truth, reg, model)
    out = write_urdf(urdf, tmp_path / "arm7.urdf", model, reg.names, pi,
                     reg.parameters.origins)
    merged = [m for m, mk in model.markers.items() if mk.body == "panda_link7"]
    assert {"panda_link8", "panda_hand"} <= set(merged)
    text = out.read_text()
    for link in merged:
        block = re.search(rf'<link name="{link}"\s*/?>(.*?)(</link>|$)', text, re.S)
        assert block is None or "<inertial>" not in block.group(1).split("<link")[0], link
    reloaded = casmbd.compile(load_urdf(out, damping=True, friction=True), mode="vm")
    true_robot = casmbd.compile(truth, mode="vm")
    for q, v, a in zip(*_states(10, reloaded.nq, seed=3), strict=True):
        q, v, a = 0.5 * q, 0.5 * v, 0.5 * a
        tau = true_robot.inverse_dynamics(q, v, a)
        assert np.max(np.abs(reloaded.inverse_dynamics(q, v, a) - tau)) < 1e-12 * np.max(
            np.abs(tau))
