"""URDF import (casmbd.load_urdf, [scene] urdf, .urdf on the CLI) against an independent
recursive Newton–Euler written here (global-frame recursion over the URDF tree, fixed joints
as joints that do not move, no merging): inverse-dynamics torques τ = M q̈ − Q_e − Q_v at random
(q, q̇, q̈) to 1e-10 relative, link frames to 1e-12 m; the fixed-joint merge against a hand
computation; named errors for malformed files."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import casmbd
from casmbd import SceneError, load_urdf, loads_urdf

SCENES = Path(__file__).parents[1] / "scenes"
UR5 = SCENES / "ur5_arm.urdf"
ARM7 = SCENES / "arm7_gripper.urdf"
G = np.array([0.0, 0.0, -9.81])


# ---------------------------------------------------------------- the independent reference
def _vec(text, default):
    return np.array([float(x) for x in text.split()]) if text else np.array(default, float)


def _rpy(r, p, y):
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _rot(axis, angle):
    kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def read(path):
    """Links {name: (m, com, I in link axes)} and joints in file order (a minimal reader)."""
    root = ET.parse(path).getroot()
    links = {}
    for el in root.findall("link"):
        ine = el.find("inertial")
        if ine is None:
            links[el.get("name")] = (0.0, np.zeros(3), np.zeros((3, 3)))
            continue
        org = ine.find("origin")
        rot = _rpy(*_vec(org.get("rpy") if org is not None else None, [0, 0, 0]))
        com = _vec(org.get("xyz") if org is not None else None, [0, 0, 0])
        i = {k: float(ine.find("inertia").get(k)) for k in
             ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
        t = np.array([[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]],
                      [i["ixz"], i["iyz"], i["izz"]]])
        links[el.get("name")] = (float(ine.find("mass").get("value")), com, rot @ t @ rot.T)
    joints = []
    for el in root.findall("joint"):
        org = el.find("origin")
        ax = el.find("axis")
        joints.append(dict(name=el.get("name"), type=el.get("type"),
                           parent=el.find("parent").get("link"),
                           child=el.find("child").get("link"),
                           rot=_rpy(*_vec(org.get("rpy"), [0, 0, 0])),
                           xyz=_vec(org.get("xyz"), [0, 0, 0]),
                           axis=_vec(ax.get("xyz") if ax is not None else None, [1, 0, 0])))
    return links, joints


def rnea(path, q, v, a, planes=None):
    """τ of every moving joint (dict) and the link frames {link: (R, p)}.

    A planar joint's q, v, a and τ are 3-vectors (x, y, θ): the child frame is the parent's,
    then the joint origin, then the translation x e₁ + y e₂ in the plane, then the rotation θ
    about the axis; ``planes`` gives its in-plane directions (e₁, e₂) in the joint frame."""
    links, joints = read(path)
    planes = planes or {}
    children = {j["child"] for j in joints}
    root = next(n for n in links if n not in children)
    st = {root: (np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3), -G)}  # R p ω ω̇ a
    order = []
    pending = list(joints)
    while pending:
        for j in list(pending):
            if j["parent"] in st:
                pending.remove(j)
                order.append(j)
                rp, pp, wp, dwp, ap = st[j["parent"]]
                zero = np.zeros(3) if j["type"] == "planar" else 0.0
                qi, vi, ai = (q.get(j["name"], zero), v.get(j["name"], zero),
                              a.get(j["name"], zero))
                moving = j["type"] in ("revolute", "continuous", "prismatic", "planar")
                rot0 = rp @ j["rot"]
                h = rot0 @ j["axis"]
                if j["type"] == "planar":  # (x, y, θ): in-plane slide u, then the turn
                    e12 = rot0 @ np.column_stack(planes.get(j["name"], np.eye(3)[:2]))
                    (x, y, qi), (vx, vy, vi), (ax, ay, ai) = qi, vi, ai
                    slide, slide_v, slide_a = e12 @ [x, y], e12 @ [vx, vy], e12 @ [ax, ay]
                    rot = rot0 @ _rot(j["axis"], qi)
                    pos = pp + rp @ j["xyz"] + slide
                elif j["type"] == "prismatic":
                    rot, pos = rot0, pp + rp @ j["xyz"] + h * qi
                else:
                    rot = rot0 @ (_rot(j["axis"], qi) if moving else np.eye(3))
                    pos = pp + rp @ j["xyz"]
                r = pos - pp
                acc = ap + np.cross(dwp, r) + np.cross(wp, np.cross(wp, r))
                w, dw = wp.copy(), dwp.copy()
                if j["type"] == "prismatic":
                    acc = acc + 2 * np.cross(wp, h * vi) + h * ai
                if j["type"] == "planar":
                    acc = acc + 2 * np.cross(wp, slide_v) + slide_a
                if moving and j["type"] != "prismatic":
                    w = wp + h * vi
                    dw = dwp + h * ai + np.cross(wp, h * vi)
                st[j["child"]] = (rot, pos, w, dw, acc)
    force = {}
    for name, (m, com, inertia) in links.items():
        rot, pos, w, dw, acc = st[name]
        d = rot @ com
        ac = acc + np.cross(dw, d) + np.cross(w, np.cross(w, d))
        ig = rot @ inertia @ rot.T
        f = m * ac
        force[name] = [f, ig @ dw + np.cross(w, ig @ w) + np.cross(d, f)]  # N about origin
    tau = {}
    for j in reversed(order):
        fc, nc = force[j["child"]]
        pc, pp = st[j["child"]][1], st[j["parent"]][1]
        h = st[j["parent"]][0] @ j["rot"] @ j["axis"]
        if j["type"] == "planar":
            e12 = st[j["parent"]][0] @ j["rot"] @ np.column_stack(
                planes.get(j["name"], np.eye(3)[:2]))
            tau[j["name"]] = np.array([e12[:, 0] @ fc, e12[:, 1] @ fc, h @ nc])
        elif j["type"] in ("revolute", "continuous"):
            tau[j["name"]] = h @ nc
        elif j["type"] == "prismatic":
            tau[j["name"]] = h @ fc
        force[j["parent"]][0] = force[j["parent"]][0] + fc
        force[j["parent"]][1] = force[j["parent"]][1] + nc + np.cross(pc - pp, fc)
    return tau, {n: (s[0], s[1]) for n, s in st.items()}


def load(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_urdf(path, **kw)


def _joint_names(model):
    return [n.split(".")[0] for n in model.coordinate_names]


# ---------------------------------------------------------------- dynamics and kinematics
@pytest.mark.parametrize("path, locked", [(UR5, {}), (ARM7, {}),
                                          (ARM7, {"panda_joint7": 0.3, "panda_joint2": -0.4})])
def test_inverse_dynamics_and_frames_match_newton_euler(path, locked):
    mech = load(path, locked=locked)
    model = casmbd.NumericModel(mech, functions=["mass_matrix", "applied_forces",
                                                 "quadratic_velocity_forces", "outputs"])
    names = _joint_names(model)
    # the <mimic> follower (ratio 1, offset 0 in this file) is substituted in joint
    # coordinates: it moves with its leader, and its torque adds to the leader's
    follows = {j.joint2: j.joint1 for j in mech.joints.values() if j.kind == "gear"}
    assert not set(follows) & set(names)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v, a = (rng.uniform(-1.5, 1.5, len(names)) for _ in range(3))
        if path == ARM7:
            q[names.index("panda_finger_joint1")] = 0.02

        def full(x):
            values = dict(zip(names, x))
            return {**values, **{f: values[lead] for f, lead in follows.items()}}

        tau = model.mass_matrix(q) @ a - model.applied_forces(q, v, 0.0) \
            - model.quadratic_velocity_forces(q, v)
        ref, frames = rnea(path, {**locked, **full(q)}, full(v), full(a))
        expect = np.array([ref[n] + sum(ref[f] for f, lead in follows.items() if lead == n)
                           for n in names])
        assert np.max(np.abs(tau - expect)) <= 1e-10 * np.max(np.abs(expect))
        out = model.outputs(q[None], v[None], a[None], np.zeros(1))
        for k, body in enumerate(model.body_names):
            rot = out["rotation_matrices"][0, 9 * k:9 * k + 9].reshape(3, 3)
            rot_ref, pos_ref = frames[body]
            b = mech.bodies[body]
            origin = out["body_positions"][0, 3 * k:3 * k + 3] \
                + rot @ b.local(_design_origin(path, body, locked))
            assert np.max(np.abs(rot - rot_ref)) < 1e-12
            assert np.max(np.abs(origin - pos_ref)) < 1e-12
        assert len(mech.markers) == len(read(path)[0]) - len(mech.bodies)
        for k, marker in enumerate(mech.markers):
            pos = out["marker_positions"][0, 3 * k:3 * k + 3]
            assert np.max(np.abs(pos - frames[marker][1])) < 1e-12


def _design_origin(path, link, locked):
    return rnea(path, locked, {}, {})[1][link][1]


def test_absolute_coordinates_energy_and_constraints_match():
    """Absolute coordinates: C(q) = 0 at the reference pose, T and V equal the reference's."""
    mech = load(UR5, coordinates="absolute")
    model = casmbd.NumericModel(mech, functions=["constraints", "kinetic_energy",
                                                 "potential_energy"])
    links, _ = read(UR5)
    rng = np.random.default_rng(5)
    qj, vj = rng.uniform(-1, 1, 6), rng.uniform(-1, 1, 6)
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
    _, frames = rnea(UR5, dict(zip(names, qj)), {}, {})
    eps = 1e-6
    _, frames_p = rnea(UR5, dict(zip(names, qj + eps * vj)), {}, {})
    _, frames_m = rnea(UR5, dict(zip(names, qj - eps * vj)), {}, {})
    q = np.zeros(model.nq)
    v = np.zeros(model.nq)
    kinetic = potential = 0.0
    for name in model.body_names:
        i = model.coordinate_index[name]
        m, com, inertia = links[name]
        (rot, pos), (rp, pp), (rm, pm) = frames[name], frames_p[name], frames_m[name]
        body = mech.bodies[name]
        rot0 = body.initial_rotation
        design = rnea(UR5, {}, {}, {})[1][name]
        arm = rot0.T @ (design[1] - body.position)  # link origin in body axes
        rb = rot @ design[0].T @ rot0  # body rotation
        q[i:i + 3] = pos - rb @ arm
        quat = casmbd.model.rotations.quaternion_from_matrix(rb)
        rbp, rbm = rp @ design[0].T @ rot0, rm @ design[0].T @ rot0
        qp = casmbd.model.rotations.quaternion_from_matrix(rbp)
        qm = casmbd.model.rotations.quaternion_from_matrix(rbm)
        q[i + 3:i + 7] = quat
        v[i:i + 3] = ((pp - rbp @ arm) - (pm - rbm @ arm)) / (2 * eps)
        v[i + 3:i + 7] = (qp - qm) / (2 * eps)
        c = pos + rot @ com
        cdot = ((pp + rp @ com) - (pm + rm @ com)) / (2 * eps)
        wskew = (rp - rm) / (2 * eps) @ rot.T
        w = np.array([wskew[2, 1], wskew[0, 2], wskew[1, 0]])
        ig = rot @ inertia @ rot.T
        kinetic += 0.5 * m * cdot @ cdot + 0.5 * w @ ig @ w
        potential -= m * G @ c
    assert np.max(np.abs(model.constraints(q, 0.0))) < 1e-12
    assert abs(model.kinetic_energy(q, v) - kinetic) < 1e-7 * kinetic  # central differences
    assert abs(model.potential_energy(q, 0.0) - potential) < 1e-12 * abs(potential) + 1e-12


# ---------------------------------------------------------------- merge, mimic, options
def test_fixed_joint_merge_by_hand():
    """panda_link7 + flange (panda_link8) + hand: mass, centre of mass, inertia (global)."""
    mech = load(ARM7)
    links, _ = read(ARM7)
    _, frames = rnea(ARM7, {}, {}, {})
    parts = []
    for name in ("panda_link7", "panda_link8", "panda_hand", "panda_hand_tcp"):
        m, com, inertia = links[name]
        rot, pos = frames[name]
        parts.append((m, pos + rot @ com, rot @ inertia @ rot.T))
    mass = sum(p[0] for p in parts)
    com = sum(p[0] * p[1] for p in parts) / mass
    tensor = sum(p[2] + p[0] * ((p[1] - com) @ (p[1] - com) * np.eye(3)
                                - np.outer(p[1] - com, p[1] - com)) for p in parts)
    body = mech.bodies["panda_link7"]
    assert abs(body.mass - mass) < 1e-12 and abs(mass - (0.735 + 0.1 + 0.73)) < 1e-12
    assert np.max(np.abs(body.position - com)) < 1e-12
    rot = body.initial_rotation
    assert np.max(np.abs(rot - frames["panda_link7"][0])) < 1e-12
    got = rot @ casmbd.model.inertia.inertia_tensor(body.inertia) @ rot.T
    assert np.max(np.abs(got - tensor)) < 1e-12
    assert mech.markers["panda_hand_tcp"].body == "panda_link7"


def test_mimic_gear_limits_damping_locked_initial():
    mech = load(ARM7, damping=True, locked={"panda_joint7": 0.3},
                initial={"panda_joint2": (0.4, 0.5), "panda_finger_joint1": 0.01})
    gear = mech.joints["panda_finger_joint2_mimic"]
    assert (gear.joint1, gear.joint2, gear.ratio) == ("panda_finger_joint1",
                                                      "panda_finger_joint2", 1.0)
    assert mech.joints["panda_joint4"].urdf_limits == {"lower": -3.0718, "upper": -0.0698,
                                                      "effort": 87.0, "velocity": 2.175}
    assert mech.forces["panda_joint1_damping"].damping == 0.2
    assert "panda_joint7" not in mech.joints and "panda_link7" not in mech.bodies
    assert mech.markers["panda_link7"].body == "panda_link6"
    model = casmbd.NumericModel(mech, functions=["constraints", "outputs"])
    q0, v0 = model.initial_coordinates(), model.initial_velocities()
    names = _joint_names(model)
    assert q0[names.index("panda_joint2")] == 0.4
    assert "panda_finger_joint2" not in names  # substituted: it follows its leader
    out = model.outputs(q0[None], v0[None], 0.0 * v0[None], np.zeros(1))["joint_positions"]
    assert abs(out[0, list(model.joint_coordinate_names).index("panda_finger_joint2")]
               - 0.01) < 1e-15  # the output, measured from the bodies' poses
    assert abs(v0[names.index("panda_joint2")] - 0.5) < 1e-12
    assert np.max(np.abs(np.delete(v0, names.index("panda_joint2")))) < 1e-12
    assert model.constraints(q0, 0.0).size == 0  # no gear row left
    mech.substitute_gears = False  # the gear as a constraint: C = 0 at the start
    model = casmbd.NumericModel(mech, functions=["constraints"])
    q0, names = model.initial_coordinates(), _joint_names(model)
    assert q0[names.index("panda_finger_joint2")] == 0.01
    assert np.max(np.abs(model.constraints(q0, 0.0))) < 1e-14
    ur = load(UR5)
    assert ur.joints["shoulder_pan_joint"].urdf_dynamics == {"damping": 0.5, "friction": 0.1}
    assert not ur.forces  # damping off by default


def test_visual_elements_are_kept_without_a_notice():
    """<visual> elements are kept for the 3-D view (issue 32), no longer ignored with a
    warning: the two mesh visuals of the UR5 file, on the ground (the base, welded to the
    world) and on the shoulder, with their package:// URIs, which do not resolve here (the
    view draws those bodies with derived shapes and says so); <collision> is not used."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mech = load_urdf(UR5)
    assert {body: [(v.kind, v.uri, v.filename) for v in vis]
            for body, vis in mech.visuals.items()} == {
        "ground": [("mesh", "package://ur_description/meshes/ur5/visual/base.dae", None)],
        "shoulder_link": [("mesh", "package://ur_description/meshes/ur5/visual/shoulder.dae",
                           None)]}


# ---------------------------------------------------------------- errors
_TWO = ('<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>{}'
        '</robot>')
_J = ('<joint name="j" type="{t}"><parent link="{p}"/><child link="{c}"/>'
      '<origin xyz="{xyz}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" '
      'velocity="1"/></joint>')


@pytest.mark.parametrize("text, match", [
    (_TWO.format(_J.format(t="revolute", p="a", c="b", xyz="0 0 x")),
     "joint 'j' <origin> attribute 'xyz': expected 3 numbers"),
    (_TWO.format(_J.format(t="revolute", p="a", c="b", xyz="0 0")),
     "joint 'j' <origin> attribute 'xyz': expected 3 finite numbers"),
    (_TWO.format(_J.format(t="hinge", p="a", c="b", xyz="0 0 0")),
     "joint 'j' attribute 'type': unknown joint type 'hinge'"),
    (_TWO.format(_J.format(t="revolute", p="a", c="z", xyz="0 0 0")),
     "joint 'j' <child> attribute 'link': unknown link 'z'"),
    (_TWO.format(""), "several root links"),
    (_TWO.format(_J.format(t="revolute", p="a", c="b", xyz="0 0 0")
                 + _J.format(t="revolute", p="b", c="a", xyz="0 0 0").replace('"j"', '"k"')),
     "cycle"),
    (_TWO.format(_J.format(t="revolute", p="a", c="b", xyz="0 0 0")).replace(
        '<mass value="1"/>', "<mass/>"), "link 'b' <mass>: missing attribute 'value'"),
    ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x "y">]><robot name="r"/>', "DOCTYPE"),
    ("<robot><link name='a'>", "malformed XML"),
    (_TWO.format(_J.format(t="planar", p="a", c="b", xyz="0 0 0")).replace(
        'axis xyz="0 0 1"', 'axis xyz="0 0 0"'), r"joint 'j' <axis> attribute 'xyz': zero axis"),
])
def test_malformed_files_give_named_errors(text, match):
    with pytest.raises(SceneError, match=match):
        loads_urdf(text, "t.urdf")


_MASSLESS = ('<robot name="m"><link name="base"/><link name="l1"/>{l2}'
             '<joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>'
             '<axis xyz="1 0 0"/></joint>'
             '<joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>'
             '<origin xyz="0 0.5 0"/><axis xyz="1 0 0"/></joint></robot>')


def test_massless_link_on_a_moving_joint_loads_and_simulates():
    """l1 has no <inertial> and carries l2 (mass 2, centre of mass 0.3 m out, Ixx 0.05): from
    rest along y under gravity −z, Lagrange's equations at t = 0 give φ̈2 = 0 and
    φ̈1 = −g / L1 (L1 = 0.5 m; the massless link's tip falls freely), i.e. θ̈1 = −g/L1,
    θ̈2 = +g/L1 (1e-9); with l2 massless too, forward dynamics names it."""
    l2 = ('<link name="l2"><inertial><origin xyz="0 0.3 0"/><mass value="2"/><inertia '
          'ixx="0.05" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.05"/></inertial></link>')
    mech = loads_urdf(_MASSLESS.format(l2=l2), "m.urdf")
    assert mech.bodies["l1"].mass == 0.0
    out = casmbd.simulate(mech, t_end=0.05, steps=1)
    g = -mech.gravity[2]
    assert abs(out.joint("j1")["acceleration"][0] + g / 0.5) < 1e-9
    assert abs(out.joint("j2")["acceleration"][0] - g / 0.5) < 1e-9
    bare = loads_urdf(_MASSLESS.format(l2='<link name="l2"/>'), "m.urdf")
    with pytest.raises(casmbd.errors.ModelError, match=r"singular.*'l2'"):
        casmbd.simulate(bare, t_end=0.05, steps=1)


def test_rounding_in_published_inertias_and_mimic_of_fixed_joints():
    """Two features of published files that Pinocchio accepts (example-robot-data): a
    near-zero inertia with a principal moment of -5.4e-20 kg m² (iCub's r_hip_2) loads as the
    zero tensor it is meant to be, while -1e-6 kg m² is still refused naming the link; a
    <mimic> whose joints are fixed (Talos' gripper in its reduced files) is ignored with one
    warning, the rest of the robot loads."""
    tiny = _TWO.format(_J.format(t="revolute", p="a", c="b", xyz="0 0 0")).replace(
        'ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"',
        'ixx="1e-20" ixy="1e-19" ixz="0" iyy="1e-20" iyz="0" izz="1e-20"')
    assert np.linalg.eigvalsh([[1e-20, 1e-19, 0], [1e-19, 1e-20, 0], [0, 0, 1e-20]])[0] < 0
    loads_urdf(tiny, "t.urdf").validate()  # the check every analysis runs first
    bad = tiny.replace('ixy="1e-19"', 'ixy="1e-6"')
    with pytest.raises(SceneError,  # at load (casmbd.io.urdf_checks), naming the link
                       match=r"link 'b' <inertia>.*not positive semi-definite"):
        loads_urdf(bad, "t.urdf")
    fixed = (_TWO.format(_J.format(t="revolute", p="a", c="b", xyz="0 0 0")
                         + '<link name="c"/><joint name="f" type="fixed"><parent link="b"/>'
                         '<child link="c"/><mimic joint="j" multiplier="1"/></joint>'))
    with pytest.warns(RuntimeWarning, match="<mimic> of a fixed joint ignored for f"):
        mech = loads_urdf(fixed, "t.urdf")
    assert list(mech.joints) == ["j"]


# ---------------------------------------------------------------- scene files and CLI
def test_cli_info_on_a_bare_urdf():
    out = subprocess.run([sys.executable, "-W", "ignore", "-m", "casmbd", "info", str(UR5),
                          "--json"], capture_output=True, text=True, timeout=600,
                         env={**os.environ, "CASMBD_COMPILE": "0"})
    assert out.returncode == 0, out.stderr
    info = json.loads(out.stdout)
    assert info["degrees_of_freedom"] == 6


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_scene_with_urdf_drivers_and_damping_inverse_dynamics(tmp_path, coordinates):
    """Every joint driven, q_i = a_i + b_i sin(2t): the driver efforts equal the Newton–Euler
    torques plus the viscous damping d θ̇ of shoulder_pan (``damping = true``)."""
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "ur5.urdf").write_text(UR5.read_text())
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
    amp, mid = np.linspace(0.3, 0.8, 6), np.linspace(-0.5, 0.6, 6)
    drivers = "".join(f'[[drivers]]\nname = "d{i}"\njoint = "{n}"\n'
                      f'position = "{float(mid[i])!r} + {float(amp[i])!r}*sin(2*t)"\n'
                      for i, n in enumerate(names))
    scene = tmp_path / "arm.toml"
    scene.write_text('[scene]\nurdf = "robot/ur5.urdf"\ndimension = 3\ndamping = true\n'
                     f'coordinates = "{coordinates}"\n' + drivers)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = casmbd.load_scene(scene)
    result = casmbd.inverse_dynamics(mech, 1.0, 4, mode="vm")
    for k, t in enumerate(result["t"]):
        q = mid + amp * np.sin(2 * t)
        v, a = 2 * amp * np.cos(2 * t), -4 * amp * np.sin(2 * t)
        ref, _ = rnea(UR5, dict(zip(names, q)), dict(zip(names, v)), dict(zip(names, a)))
        expect = np.array([ref[n] for n in names])
        expect[0] += 0.5 * v[0]
        got = result["driver_efforts"][k]
        assert np.max(np.abs(got - expect)) <= 1e-9 * np.max(np.abs(expect))


def test_scene_with_urdf_and_driver(tmp_path):
    rel = Path("../" * len(tmp_path.parts)).joinpath(*UR5.resolve().parts[1:])
    scene = tmp_path / "arm.toml"
    scene.write_text(f'[scene]\nurdf = "{rel.as_posix()}"\n'  # dimension 3 by default
                     'coordinates = "joint"\n[scene.initial]\nelbow_joint = 0.5\n'
                     '[[drivers]]\nname = "d"\njoint = "shoulder_pan_joint"\n'
                     'position = "0.3*t"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = casmbd.load_scene(scene)
    assert mech.name == "arm" and len(mech.bodies) == 6 and "d" in mech.drivers
    assert mech.joints["elbow_joint"].tree_initial()[0] == 0.5
    with pytest.raises(SceneError, match=r"'urdf' is spatial \(dimension = 3\)"):
        casmbd.loads_scene('[scene]\nurdf = "x.urdf"\ndimension = 2\n', str(scene))
    with pytest.raises(SceneError, match="'initial', 'locked' and 'damping' need 'urdf'"):
        casmbd.loads_scene('[scene]\ndimension = 3\n[scene.initial]\nj = 1.0\n', str(scene))
    with pytest.raises(SceneError, match=r"key 'urdf'.*not found"):
        casmbd.loads_scene('[scene]\nurdf = "nope.urdf"\ndimension = 3\n', str(scene))


def test_floating_joint_leaves_the_child_free():
    text = ('<robot name="f"><link name="world"/><joint name="free" type="floating">'
            '<parent link="world"/><child link="b"/><origin xyz="0 0 1" rpy="0.3 0 0"/></joint>'
            '<link name="b"><inertial><mass value="2"/><origin xyz="0.1 0 0"/>'
            '<inertia ixx="1" ixy="0" ixz="0" iyy="2" iyz="0" izz="3"/></inertial></link>'
            '</robot>')
    for coordinates in ("joint", "absolute"):
        mech = loads_urdf(text, coordinates=coordinates)
        assert not mech.joints and list(mech.bodies) == ["b"]
        body = mech.bodies["b"]
        assert np.max(np.abs(body.position - [0.1, 0.0, 1.0])) < 1e-15
        assert np.max(np.abs(body.initial_rotation - _rpy(0.3, 0, 0))) < 1e-15
        model = casmbd.NumericModel(mech, functions=["mass_matrix"], mode="vm")
        assert model.nq == 7
        mass = model.mass_matrix(model.initial_coordinates()).toarray()
        assert np.max(np.abs(mass[:3, :3] - 2.0 * np.eye(3))) < 1e-14


def _rpy_of(rot):
    """(roll, pitch, yaw) of R = Rz(y) Ry(p) Rx(r) (at pitch ±π/2: yaw 0)."""
    pitch = -math.asin(min(1.0, max(-1.0, rot[2, 0])))
    if abs(rot[2, 0]) > 1.0 - 1e-12:
        return math.atan2(-rot[1, 2], rot[1, 1]), pitch, 0.0
    return math.atan2(rot[2, 1], rot[2, 2]), pitch, math.atan2(rot[1, 0], rot[0, 0])


def test_ur5_urdf_equals_the_dh_scene_ur_like(tmp_path):
    """tests/scenes/ur_like.toml (UR5 from its DH parameters, at its zero pose) and the UR5 URDF
    kinematics with ur_like's masses, centres of mass and inertias written as URDF inertials:
    the URDF's zero pose is the DH one turned by π about z (base_link vs. DH base frame), joint
    axes and angles agree, so M(q) and Q(q, q̇) agree at every state (1e-10 relative)."""
    dh = casmbd.load_scene(SCENES / "ur_like.toml")
    dh.coordinates = "joint"
    turn = np.diag([-1.0, -1.0, 1.0])
    text = UR5.read_text().replace("1.570796325", repr(math.pi / 2))  # UR's file: π/2 − 2e-9
    (tmp_path / "ur5.urdf").write_text(text)
    _, frames = rnea(tmp_path / "ur5.urdf", {}, {}, {})
    for body, link in zip(dh.bodies.values(), ["shoulder_link", "upper_arm_link",
                                                "forearm_link", "wrist_1_link",
                                                "wrist_2_link", "wrist_3_link"], strict=True):
        rot_l, pos_l = frames[link]
        xyz = rot_l.T @ (turn @ body.position - pos_l)
        rpy = _rpy_of(rot_l.T @ turn @ body.initial_rotation)
        ixx, iyy, izz = (repr(float(x)) for x in body.inertia[:3])
        xyz, rpy = (" ".join(repr(float(x)) for x in vec) for vec in (xyz, rpy))
        block = (f'<inertial><mass value="{float(body.mass)!r}"/><origin xyz="{xyz}" '
                 f'rpy="{rpy}"/><inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" '
                 f'izz="{izz}"/></inertial>')
        start = text.index(f'<link name="{link}">')
        i, j = text.index("<inertial>", start), text.index("</inertial>", start)
        text = text[:i] + block + text[j + len("</inertial>"):]
    (tmp_path / "ur5.urdf").write_text(text)
    arm = load(tmp_path / "ur5.urdf")
    needs = ["mass_matrix", "applied_forces", "quadratic_velocity_forces"]
    models = [casmbd.NumericModel(m, functions=needs, mode="vm") for m in (dh, arm)]
    rng = np.random.default_rng(11)
    for _ in range(5):
        q, v = rng.uniform(-2, 2, 6), rng.uniform(-2, 2, 6)
        mass = [m.mass_matrix(q).toarray() for m in models]
        force = [m.applied_forces(q, v, 0.0) + m.quadratic_velocity_forces(q, v)
                 for m in models]
        assert np.max(np.abs(mass[0] - mass[1])) <= 1e-10 * np.max(np.abs(mass[0]))
        assert np.max(np.abs(force[0] - force[1])) <= 1e-10 * np.max(np.abs(force[0]))


# ---------------------------------------------------------------- mimic offsets
_LINK = ('<link name="{n}"><inertial><origin xyz="{c}"/><mass value="{m}"/><inertia '
         'ixx="0.02" ixy="0.001" ixz="0" iyy="0.03" iyz="0.002" izz="0.025"/></inertial>'
         '</link>')
_MIMIC = ('<robot name="mim"><link name="base"/>'
          + _LINK.format(n="l1", c="0.2 0 0.05", m=1.5) + _LINK.format(n="l2", c="0.15 0.02 0",
                                                                        m=1.0)
          + _LINK.format(n="l3", c="0 0.1 0", m=0.7)
          + '<joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>'
          '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/></joint>'
          '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>'
          '<origin xyz="0.4 0 0" rpy="0.2 0 0"/><axis xyz="0 1 0"/>'
          '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
          '<mimic joint="j1" multiplier="{r}" offset="{d}"/></joint>'
          '<joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>'
          '<origin xyz="0.3 0 0"/><axis xyz="1 0 0"/></joint></robot>')
MIMIC_R, MIMIC_D = -0.5, 0.3


def test_mimic_offset_inverse_dynamics_match_newton_euler(tmp_path):
    """θ_j2 = −0.5 θ_j1 + 0.3 (URDF <mimic offset>): the follower starts at r θ_j1,0 + δ with
    rate r θ̇_j1,0 (C = 0 at the start, 1e-14); j1 and j3 driven, q_i = a_i + b_i sin(2t):
    the driver efforts equal the Newton–Euler torques with the follower's angle applied,
    τ_j1 + r τ_j2 and τ_j3 (1e-9 relative)."""
    path = tmp_path / "mimic.urdf"
    path.write_text(_MIMIC.format(r=MIMIC_R, d=MIMIC_D))
    mech = load(path, initial={"j1": (0.4, 0.7)})
    gear = mech.joints["j2_mimic"]
    assert (gear.ratio, gear.offset) == (MIMIC_R, MIMIC_D)
    mech.substitute_gears = False  # the gear as a constraint (substituted: test_mimic_subst…)
    model = casmbd.NumericModel(mech, functions=["constraints"])
    q0, v0 = model.initial_coordinates(), model.initial_velocities()
    names = _joint_names(model)
    assert q0[names.index("j2")] == MIMIC_R * 0.4 + MIMIC_D
    assert abs(v0[names.index("j2")] - MIMIC_R * 0.7) < 1e-14
    assert np.max(np.abs(model.constraints(q0, 0.0))) < 1e-14
    mech.add_driver("d1", "0.4 + 0.6*sin(2*t)", joint="j1")
    mech.add_driver("d3", "-0.2 + 0.5*sin(2*t)", joint="j3")
    result = casmbd.inverse_dynamics(mech, 1.0, 4, mode="vm")
    for k, t in enumerate(result["t"]):
        q1, q3 = 0.4 + 0.6 * math.sin(2 * t), -0.2 + 0.5 * math.sin(2 * t)
        v1, v3 = 1.2 * math.cos(2 * t), math.cos(2 * t)
        a1, a3 = -2.4 * math.sin(2 * t), -2.0 * math.sin(2 * t)
        ref, _ = rnea(path, {"j1": q1, "j2": MIMIC_R * q1 + MIMIC_D, "j3": q3},
                      {"j1": v1, "j2": MIMIC_R * v1, "j3": v3},
                      {"j1": a1, "j2": MIMIC_R * a1, "j3": a3})
        expect = np.array([ref["j1"] + MIMIC_R * ref["j2"], ref["j3"]])
        got = result["driver_efforts"][k]
        assert np.max(np.abs(got - expect)) <= 1e-9 * np.max(np.abs(expect))
        assert abs(got[0] - (ref["j1"] - MIMIC_R * ref["j3"])) > 1e-3  # τ_j2 ≠ 0 matters


def test_mimic_offset_locked_leader_and_absolute_coordinates(tmp_path):
    """A locked leader locks its follower at r v + δ (any coordinates; the frames equal the
    Newton–Euler frames at θ_j2 = r v + δ to 1e-12 m); in absolute and natural coordinates a
    free leader's offset starts the follower at δ (the bodies' start pose; C = 0 there to
    1e-14)."""
    path = tmp_path / "mimic.urdf"
    path.write_text(_MIMIC.format(r=MIMIC_R, d=MIMIC_D))
    for coordinates in ("joint", "absolute"):
        mech = load(path, locked={"j1": 0.5}, coordinates=coordinates)
        assert list(mech.joints) == ["j3"]
        _, frames = rnea(path, {"j1": 0.5, "j2": MIMIC_R * 0.5 + MIMIC_D}, {}, {})
        assert np.max(np.abs(mech.markers["l2"].point - frames["l2"][1])) < 1e-12
        assert np.max(np.abs(mech.joints["j3"].point - frames["l3"][1])) < 1e-12
    for coordinates in ("absolute", "natural"):
        model = casmbd.NumericModel(load(path, coordinates=coordinates),
                                    functions=["constraints"])
        assert np.max(np.abs(model.constraints(model.initial_coordinates(), 0.0))) < 1e-14
    path.write_text(_MIMIC.format(r=MIMIC_R, d=0.0))
    assert load(path, coordinates="absolute").joints["j2_mimic"].offset == 0.0


# ---------------------------------------------------------------- planar joints
_INERTIAL = ('<inertial><origin xyz="{c}" rpy="{r}"/><mass value="{m}"/><inertia ixx="{i[0]}" '
             'ixy="{i[3]}" ixz="{i[4]}" iyy="{i[1]}" iyz="{i[5]}" izz="{i[2]}"/></inertial>')
_PLANAR = ('<robot name="pl"><link name="base"/>'
           '<link name="l1">' + _INERTIAL.format(c="0.1 0 0.05", r="0 0 0", m=1.5,
                                                 i=(0.02, 0.03, 0.025, 0.001, 0, 0.002))
           + '</link><link name="l2">' + _INERTIAL.format(
               c="0.05 0.1 0", r="0.1 0.2 0.3", m=1.0, i=(0.03, 0.02, 0.04, 0.002, 0.001, 0))
           + '</link><link name="l3">' + _INERTIAL.format(
               c="0 0.1 0.02", r="0 0 0", m=0.7, i=(0.01, 0.012, 0.008, 0, 0, 0))
           + '</link><joint name="j1" type="continuous"><parent link="base"/>'
           '<child link="l1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/></joint>'
           '<joint name="p" type="planar"><parent link="l1"/><child link="l2"/>'
           '<origin xyz="0.3 0 0.2" rpy="0.3 -0.2 0.5"/><axis xyz="0 0.6 0.8"/></joint>'
           '<joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>'
           '<origin xyz="0.2 0.1 0"/><axis xyz="1 0 0"/></joint></robot>')
_PLANAR_NAMES = ["j1", "p", "p.y", "p.angle", "j3"]


def _planar_reference(path, mech, q, v, a):
    """Newton–Euler τ in the order (j1, p.x, p.y, p.angle, j3) and the frames; the planar
    joint's in-plane directions are the joint's f, g (global at the URDF zero) in its frame."""
    joint = mech.joints["p"]
    rot = rnea(path, {}, {}, {})[1]["l2"][0]
    planes = {"p": (rot.T @ joint.f, rot.T @ joint.g)}

    def split(x):
        return {"j1": x[0], "p": np.asarray(x[1:4]), "j3": x[4]}

    tau, frames = rnea(path, split(q), split(v), split(a), planes)
    return np.array([tau["j1"], *tau["p"], tau["j3"]]), frames


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_planar_joint_inverse_dynamics_match_newton_euler(tmp_path, coordinates):
    """A planar joint (axis (0, 0.6, 0.8) in a turned joint frame) between two revolute
    joints: the link frames at a random state equal the Newton–Euler frames (1e-12 m), and with
    every coordinate driven, q_i = a_i + b_i sin(2t), the driver efforts equal the Newton–Euler
    generalized forces (e₁·f, e₂·f, h·n for the planar joint; 1e-9 relative)."""
    path = tmp_path / "planar.urdf"
    path.write_text(_PLANAR)
    mech = load(path, coordinates=coordinates)
    joint = mech.joints["p"]
    assert type(joint).kind == "planar" and joint.coordinate_names == ("x", "y", "angle")
    _, zero = rnea(path, {}, {}, {})
    assert np.max(np.abs(joint.axis - zero["l1"][0] @ _rpy(0.3, -0.2, 0.5) @ [0, 0.6, 0.8])) \
        < 1e-15
    if coordinates == "joint":
        model = casmbd.NumericModel(mech, functions=["outputs"])
        q = np.array([0.4, 0.1, -0.2, 0.7, -0.5])
        out = model.outputs(q[None], q[None], q[None], np.zeros(1))
        _, frames = _planar_reference(path, mech, q, q, q)
        for k, body in enumerate(model.body_names):
            got = out["rotation_matrices"][0, 9 * k:9 * k + 9].reshape(3, 3)
            assert np.max(np.abs(got - frames[body][0])) < 1e-12
        k = model.body_names.index("l2")
        com = frames["l2"][1] + frames["l2"][0] @ np.array([0.05, 0.1, 0.0])
        assert np.max(np.abs(out["body_positions"][0, 3 * k:3 * k + 3] - com)) < 1e-12
    amp, mid = np.linspace(0.2, 0.6, 5), np.linspace(-0.4, 0.5, 5)
    for i, (name, coord) in enumerate([("j1", None), ("p", "x"), ("p", "y"), ("p", "angle"),
                                       ("j3", None)]):
        mech.add_driver(f"d{i}", f"{float(mid[i])!r} + {float(amp[i])!r}*sin(2*t)",
                        joint=name, coordinate=coord)
    result = casmbd.inverse_dynamics(mech, 1.0, 4, mode="vm")
    assert result.names["joints"][:4] == _PLANAR_NAMES[:4]
    for k, t in enumerate(result["t"]):
        q, v, a = (mid + amp * np.sin(2 * t), 2 * amp * np.cos(2 * t),
                   -4 * amp * np.sin(2 * t))
        expect, _ = _planar_reference(path, mech, q, v, a)
        got = result["driver_efforts"][k]
        assert np.max(np.abs(got - expect)) <= 1e-9 * np.max(np.abs(expect))
    with pytest.raises(SceneError, match=r"initial joint 'p': a planar joint has no single"):
        load(path, initial={"p": 0.1})


@pytest.mark.peer("pinocchio")
def test_planar_joint_against_pinocchio(tmp_path):
    """The planar chain with axis 0 0 1 against Pinocchio's ``JointModelPlanar`` (whose URDF
    parser ignores ``<axis>``: always the joint frame's xy plane) when ``pinocchio`` is
    importable.  Pinocchio's planar velocity is (v_x, v_y) in the turned child frame and ω, so
    v_p = T q̇ with T = diag(1, R(θ)ᵀ B⁻¹, 1, 1), B the map of Pinocchio's in-plane axes onto
    casmbd's (f, g): link frames (1e-12), M = Tᵀ M_p T against ``crba`` (1e-12 relative), and
    q̈ from casmbd's forward dynamics under τ = Tᵀ τ_p against ``aba``, a_p = T q̈ + Ṫ q̇
    (1e-9 relative)."""
    pin = pytest.importorskip("pinocchio")
    path = tmp_path / "planar_z.urdf"
    path.write_text(_PLANAR.replace('axis xyz="0 0.6 0.8"', 'axis xyz="0 0 1"'))
    pm = pin.buildModelFromUrdf(str(path))
    data = pm.createData()
    mech = load(path)
    ours = casmbd.compile(mech, mode="vm")
    joint = mech.joints["p"]
    frame = rnea(path, {}, {}, {})[1]["l2"][0]  # the joint frame at the URDF zero
    b = np.array([[joint.f @ frame[:, 0], joint.f @ frame[:, 1]],
                  [joint.g @ frame[:, 0], joint.g @ frame[:, 1]]])
    rng = np.random.default_rng(7)
    for _ in range(3):
        q, v = rng.uniform(-1.5, 1.5, 5), rng.uniform(-2, 2, 5)
        c, s = math.cos(q[3]), math.sin(q[3])
        rot_t = np.array([[c, s], [-s, c]])
        t = np.eye(5)
        t[1:3, 1:3] = rot_t @ np.linalg.inv(b)
        t_dot = np.zeros((5, 5))
        t_dot[1:3, 1:3] = v[3] * np.array([[-s, c], [-c, -s]]) @ np.linalg.inv(b)
        qp = np.r_[math.cos(q[0]), math.sin(q[0]), np.linalg.solve(b, q[1:3]), c, s,
                   math.cos(q[4]), math.sin(q[4])]
        vp = t @ v
        pin.forwardKinematics(pm, data, qp)
        pin.updateFramePlacements(pm, data)
        pos, rot = ours.forward_kinematics(q)
        for link in ("l1", "l2", "l3"):
            k, fid = ours.frame_names.index(link), pm.getFrameId(link)
            parent = pm.frames[fid].parentJoint
            assert np.max(np.abs(rot[k] - data.oMf[fid].rotation)) < 1e-12
            com = data.oMi[parent].act(pm.inertias[parent].lever)
            assert np.max(np.abs(pos[k] - com)) < 1e-12
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        mass = ours.mass_matrix(q)
        assert np.max(np.abs(mass - t.T @ m_pin @ t)) < 1e-12 * np.max(np.abs(mass))
        tau_p = rng.uniform(-2, 2, 5)
        acc_p = pin.aba(pm, data, qp, vp, tau_p)
        acc = t @ ours.forward_dynamics(q, v, t.T @ tau_p) + t_dot @ v
        assert np.max(np.abs(acc - acc_p)) < 1e-9 * np.max(np.abs(acc_p))
