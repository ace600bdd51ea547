"""Markers with a frame (issue 21 item 1): A_marker(t) = A_body(t) Aᵦ(0)ᵀ A_m(0) in space,
θ_body + θ_m − θᵦ in the plane, and URDF frame links' markers carry the link frame."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import Mechanism, loads_urdf
from casmbd.errors import ModelError
from casmbd.model.rotations import euler_zxz_to_quaternion, rotation_matrix

_cache = private_cache("cache_mk")


def zxz(phi, theta, psi) -> np.ndarray:
    """A_z(φ) A_x(θ) A_z(ψ) written out (seed 001, eq. 32)."""
    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    return rz(phi) @ rx(theta) @ rz(psi)


@pytest.mark.parametrize("coordinates", ["absolute", "joint", "natural"])
def test_spatial_marker_rotation_follows_the_body(coordinates):
    """A tilted body swinging on a revolute joint: its marker with an orientation has
    A_m(t) = A_b(t) A_b(0)ᵀ A_m(0) at every output (1e-12), A_m(0) = the given Z-X-Z frame,
    the quaternion gives the same matrix (1e-7), a marker without orientation has the body's
    rotation, and a ground marker keeps its frame."""
    body0, mark0 = (0.3, 0.4, 0.5), (1.0, 0.7, -0.2)
    mech = Mechanism("swing", dimension=3, gravity=[0.0, 0.0, -9.81], coordinates=coordinates)
    mech.add_body("b", 2.0, [0.1, 0.2, 0.15], [0.0, 0.5, 0.0], euler_zxz=body0)
    mech.add_revolute("pin", "ground", "b", [0.0, 0.0, 0.0], axis=[1.0, 0.0, 0.0])
    mech.add_marker("plain", "b", [0.0, 0.6, 0.1])
    mech.add_marker("tool", "b", [0.0, 0.7, 0.0], euler_zxz=mark0)
    mech.add_marker("fixed", "ground", [1.0, 0.0, 0.0],
                    orientation=euler_zxz_to_quaternion(*mark0))
    out = casmbd.simulate(mech, t_end=0.8, steps=8, rtol=1e-10)
    rb = out.body("b")["rotation"]
    tool = out.marker("tool")
    assert np.ptp(out.joint("pin")["coordinate"]) > 0.5  # it really turns
    offset = zxz(*body0).T @ zxz(*mark0)
    for k in range(len(out.t)):
        assert np.max(np.abs(tool["rotation"][k] - rb[k] @ offset)) < 1e-12
        # the quaternion is of the nearest rotation: Euler parameters integrated in absolute
        # coordinates are unit only to the integrator's tolerance (measured 1.9e-9)
        assert np.max(np.abs(rotation_matrix(tool["quaternion"][k]) - tool["rotation"][k])) \
            < 1e-7
    assert np.max(np.abs(tool["rotation"][0] - zxz(*mark0))) < 1e-12
    assert np.max(np.abs(out.marker("plain")["rotation"] - rb)) < 1e-12
    assert np.max(np.abs(out.marker("fixed")["rotation"] - zxz(*mark0))) < 1e-12
    csv_labels = out._labels("marker_rotations", out.arrays["marker_rotations"])
    assert csv_labels[9] == "marker_rotations[tool.A11]"
    assert csv_labels[-1] == "marker_rotations[fixed.A33]"
    assert len(out.to_json()["markers"]["tool"]["quaternion"]) == len(out.t)


def test_planar_marker_angle():
    """θ_marker = θ_body + 0.4 − 0.1 on a swinging pendulum (1e-12); without an angle it is
    the body's."""
    mech = Mechanism("pend", gravity=[0.0, -9.81])
    mech.add_body("rod", 1.0, 0.1, [0.5, 0.0], angle=0.1)
    mech.add_revolute("pin", "ground", "rod", [0.0, 0.0])
    mech.add_marker("tip", "rod", [1.0, 0.0], angle=0.4)
    mech.add_marker("mid", "rod", [0.5, 0.0])
    out = casmbd.simulate(mech, t_end=0.5, steps=5)
    theta = out.body("rod")["angle"]
    assert np.ptp(theta) > 0.3
    assert np.max(np.abs(out.marker("tip")["angle"] - (theta + 0.3))) < 1e-12
    assert np.max(np.abs(out.marker("mid")["angle"] - theta)) < 1e-12


def test_planar_marker_angle_is_continuous_in_natural_coordinates():
    """A rod spinning without gravity (ω = 10 rad/s over 2 s: 3 turns) in natural coordinates,
    where angles come from atan2: the marker angle is unwrapped like the body angle and stays
    θ_body + 0.3 (1e-8 rad), and the body angle is θ0 + ω t to 1e-6 rad (the integration
    error of the default formulation in natural coordinates: 1.8e-7 measured)."""
    mech = Mechanism("spin", gravity=[0.0, 0.0], coordinates="natural")
    mech.add_body("rod", 1.0, 0.1, [0.5, 0.0], angle=0.1, angular_velocity=10.0)
    mech.add_marker("tip", "rod", [1.0, 0.0], angle=0.4)
    out = casmbd.simulate(mech, t_end=2.0, steps=80, rtol=1e-10)
    theta = out.body("rod")["angle"]
    tip = out.marker("tip")["angle"]
    assert np.max(np.abs(np.diff(tip))) < 1.0  # no 2π jump
    assert np.max(np.abs(tip - (theta + 0.3))) < 1e-8
    assert np.max(np.abs(theta - (0.1 + 10.0 * out.t))) < 1e-6


def test_marker_orientation_errors_name_the_marker():
    mech = Mechanism("m", dimension=3)
    mech.add_body("b", 1.0, [1.0, 1.0, 1.0], [0.0, 0.0, 0.0])
    with pytest.raises(ModelError, match=r"marker 'a' field 'orientation'.*unit quaternion"):
        mech.add_marker("a", "b", [0.0, 0.0, 0.0], orientation=[2.0, 0.0, 0.0, 0.0])
    with pytest.raises(ModelError, match=r"marker 'c' field 'angle'.*spatial markers"):
        mech.add_marker("c", "b", [0.0, 0.0, 0.0], angle=0.3)


def rpy(r, p, y) -> np.ndarray:
    """URDF rpy: R = R_z(y) R_y(p) R_x(r)."""
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


ARM = ('<robot name="arm"><link name="base"/>'
       '<link name="l1"><inertial><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" '
       'iyy="0.1" iyz="0" izz="0.05"/></inertial></link><link name="flange"/><link name="tool0"/>'
       '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
       '<origin xyz="0 0 0.3" rpy="0.2 -0.3 0.5"/><axis xyz="0 0 1"/>'
       '<limit lower="-3" upper="3" effort="10" velocity="1"/></joint>'
       '<joint name="f" type="fixed"><parent link="l1"/><child link="flange"/>'
       '<origin xyz="0.1 0 0.4" rpy="0.7 0.1 -0.4"/></joint>'
       '<joint name="t" type="fixed"><parent link="flange"/><child link="tool0"/>'
       '<origin xyz="0 0 0.1" rpy="-1.1 0.6 2.0"/></joint></robot>')


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_urdf_flange_marker_frame(coordinates):
    """The merged frame links are markers with the link frame: at the zero pose the flange's
    rotation is R(rpy j1) R(rpy f) and the tool's R(rpy j1) R(rpy f) R(rpy t) (1e-12)."""
    mech = loads_urdf(ARM, "arm.urdf", coordinates=coordinates)
    out = casmbd.simulate(mech, t_end=0.01, steps=1)
    flange = rpy(0.2, -0.3, 0.5) @ rpy(0.7, 0.1, -0.4)
    tool = flange @ rpy(-1.1, 0.6, 2.0)
    assert np.max(np.abs(out.marker("flange")["rotation"][0] - flange)) < 1e-12
    assert np.max(np.abs(out.marker("tool0")["rotation"][0] - tool)) < 1e-12


def test_scene_marker_orientation_keys():
    """``[[markers]]`` ``euler_zxz`` (space) is read into the marker's frame; a planar key in
    space is refused naming the entry."""
    text = (Path(__file__).resolve().parents[2] / "examples" / "bricard.toml").read_text()
    mech = casmbd.loads_scene(text.replace('body = "rod2"\n', 'body = "rod2"\n'
                                           'euler_zxz = [0.1, 0.2, 0.3]\n', 1), "b.toml")
    marker = next(iter(mech.markers.values()))
    assert np.max(np.abs(rotation_matrix(marker.orientation) - zxz(0.1, 0.2, 0.3))) < 1e-14
    with pytest.raises(casmbd.SceneError, match=r"\[\[markers\]\] entry 1.*spatial markers"):
        casmbd.loads_scene(text.replace('body = "rod2"\n', 'body = "rod2"\nangle = 0.3\n', 1),
                           "b.toml")
