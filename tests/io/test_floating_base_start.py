"""Where a floating base starts: ``load_urdf(..., floating_base=True, base={...})`` and
``[scene.base]`` (issue 34 item 1).

The same robot is started at the world frame and at a base pose (A_b, r_b) with a base twist
(v_b of the root link origin, ω_b, global); at t = 0 every body must be the first carried by
the second: r = A_b r⁰ + r_b, A = A_b A⁰, ω = A_b ω⁰ + ω_b, ṙ = A_b ṙ⁰ + v_b + ω_b × (r − r_b),
in joint and absolute coordinates (1e-12).  Without gravity the total linear momentum of the
started robot stays m (A_b v⁰_G + v_b + ω_b × (r_G − r_b)) over the motion (1e-9), so the start
is a state of the dynamics, not only of the output.
"""

from __future__ import annotations

import numpy as np
import pytest

import casmbd
from casmbd.errors import SceneError
from casmbd.io.urdf import loads_urdf
from casmbd.model.rotations import euler_zxz_to_quaternion, rotation_matrix

LINK = ('<link name="{name}"><inertial><mass value="{m}"/><origin xyz="{c}"/>'
        '<inertia ixx="{i[0]}" ixy="0" ixz="0" iyy="{i[1]}" iyz="0" izz="{i[2]}"/>'
        '</inertial></link>')
ARM = ('<robot name="arm">' + LINK.format(name="base", m=3.0, c="0.1 -0.05 0.02",
                                          i=(0.2, 0.3, 0.4))
       + LINK.format(name="link1", m=1.0, c="0 0 0.25", i=(0.05, 0.05, 0.01))
       + LINK.format(name="link2", m=0.5, c="0.2 0 0", i=(0.01, 0.02, 0.02))
       + '<joint name="j1" type="revolute"><parent link="base"/><child link="link1"/>'
       '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
       '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
       '<joint name="j2" type="prismatic"><parent link="link1"/><child link="link2"/>'
       '<origin xyz="0 0 0.5" rpy="0.3 0 0"/><axis xyz="1 0 0"/>'
       '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
BASE = {"position": [1.0, -2.0, 0.5], "euler_zxz": [0.3, 0.7, -0.4],
        "velocity": [0.2, -0.1, 0.3], "angular_velocity": [0.4, -0.3, 0.6]}
INITIAL = {"j1": (0.5, 0.8), "j2": (0.1, -0.3)}


def _start(coordinates, base=None, gravity=(0.0, 0.0, -9.81), t_end=1e-6, steps=1):
    mech = loads_urdf(ARM, floating_base=True, coordinates=coordinates, initial=INITIAL,
                      base=base, gravity=gravity)
    return casmbd.simulate(mech, t_end, steps, formulation="index1", mode="vm", rtol=1e-11,
                           atol=1e-12)


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_every_body_starts_carried_by_the_base(coordinates):
    rot_b = rotation_matrix(np.asarray(euler_zxz_to_quaternion(*BASE["euler_zxz"]), float))
    r_b, v_b, w_b = (np.asarray(BASE[k], float) for k in ("position", "velocity",
                                                          "angular_velocity"))
    at_world, carried = _start(coordinates), _start(coordinates, BASE)
    for body in ("base", "link1"):
        b0, b1 = at_world.body(body), carried.body(body)
        r1 = rot_b @ b0["position"][0] + r_b
        assert np.max(np.abs(b1["position"][0] - r1)) < 1e-12
        assert np.max(np.abs(b1["rotation"][0] - rot_b @ b0["rotation"][0])) < 1e-12
        w1 = rot_b @ b0["angular_velocity"][0] + w_b
        assert np.max(np.abs(b1["angular_velocity"][0] - w1)) < 1e-12
        v1 = rot_b @ b0["velocity"][0] + v_b + np.cross(w_b, r1 - r_b)
        assert np.max(np.abs(b1["velocity"][0] - v1)) < 1e-12
    # the joints' own motion is kept: link1 turns relative to the base at j1's rate
    rel = carried.body("link1")["angular_velocity"][0] - carried.body("base")["angular_velocity"][0]
    assert np.linalg.norm(rel) == pytest.approx(0.8, abs=1e-12)


def test_momentum_of_the_started_robot_is_conserved():
    """Zero gravity: Σ m ṙ_G constant, equal to the carried start's momentum."""
    res = _start("joint", BASE, gravity=(0.0, 0.0, 0.0), t_end=0.5, steps=5)
    masses = {"base": 3.0, "link1": 1.0, "link2": 0.5}
    momentum = sum(m * res.body(b)["velocity"] for b, m in masses.items())
    assert np.max(np.abs(momentum - momentum[0])) < 1e-9
    rest = _start("joint", None, gravity=(0.0, 0.0, 0.0))
    rot_b = rotation_matrix(np.asarray(euler_zxz_to_quaternion(*BASE["euler_zxz"]), float))
    expected = sum(m * (rot_b @ rest.body(b)["velocity"][0] + np.asarray(BASE["velocity"])
                        + np.cross(BASE["angular_velocity"],
                                   rot_b @ rest.body(b)["position"][0]))
                   for b, m in masses.items())
    assert np.max(np.abs(momentum[0] - expected)) < 1e-12


def test_scene_table_and_bad_input(tmp_path):
    (tmp_path / "arm.urdf").write_text(ARM)
    head = '[scene]\nurdf = "arm.urdf"\nfloating_base = true\n'
    quat = [float(x) for x in euler_zxz_to_quaternion(*BASE["euler_zxz"])]
    table = ('[scene.base]\nposition = [1.0, -2.0, 0.5]\norientation = '
             f'{quat}\nvelocity = [0.2, -0.1, 0.3]\nangular_velocity = [0.4, -0.3, 0.6]\n')
    mech = casmbd.loads_scene(head + table, str(tmp_path / "s.toml"))
    direct = loads_urdf(ARM, floating_base=True, base=BASE)
    for name in ("base", "link1"):
        a, b = mech.bodies[name], direct.bodies[name]
        assert np.max(np.abs(np.subtract(a.start_pose()[0], b.start_pose()[0]))) < 1e-12
        assert np.max(np.abs(np.subtract(a.velocity, b.velocity))) < 1e-12
    cases = {
        '[scene]\nurdf = "arm.urdf"\n[scene.base]\nposition = [0, 0, 1]\n':
            "needs floating_base = true",
        head + "[scene.base]\nspin = [0, 0, 1]\n": "unknown key 'spin'",
        head + "[scene.base]\nposition = [0, 1]\n": "key 'position': expected 3 finite",
        head + "[scene.base]\norientation = [1, 1, 0, 0]\n": "expected a unit quaternion",
        head + "[scene.base]\norientation = [1, 0, 0, 0]\neuler_zxz = [0, 0, 0]\n":
            "'orientation' or 'euler_zxz', not both",
        '[scene]\ndimension = 3\n[scene.base]\nposition = [0, 0, 1]\n': "needs 'urdf'",
    }
    for text, match in cases.items():
        with pytest.raises(SceneError, match=match):
            casmbd.loads_scene(text, str(tmp_path / "s.toml"))
