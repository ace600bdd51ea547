"""MJCF import (casmbd/io/mjcf.py) against MuJoCo itself.

The models in tests/io/mjcf/ are compiled by MuJoCo and loaded by ``casmbd.load_mjcf``; at
random states (MuJoCo's ``qpos``, ``qvel``, mapped to casmbd's joint coordinates by
:func:`casmbd.io.mjcf.from_mujoco`: v = B qvel, q̈ = B qacc + c) the rigid-body parts agree
with ``mj_forward`` run with contacts and the constraint solver disabled:

* mass matrix  Bᵀ M B = qM (``mj_fullM``)                       1e-12 relative to max |qM|;
* bias         Bᵀ (M c + b) = qfrc_bias − qfrc_passive          1e-10 relative (b holds the
  joint dampers, which MuJoCo counts as passive forces, so both sides carry them once);
* acceleration B⁺ (q̈ − c) = qacc (τ = 0)                       1e-9 relative to max |qacc|;
* inverse dynamics Bᵀ τ = qfrc_inverse (``mj_inverse``)           1e-10 relative;
* every body's centre of mass and frame, every site and every geom drawn as a visual
  against ``xipos``, ``xmat``, ``site_xpos``, ``site_xmat``, ``geom_xpos``, ``geom_xmat``
                                                                1e-12.

The closed loop (``<equality connect>``): MuJoCo's equality is soft (solref/solimp, and it is
a constraint of its solver), casmbd's is exact.  So the tree parts are compared as above, the
closure against MuJoCo's own constraint rows (residual ``efc_pos`` and Jacobian ``efc_J``,
1e-12), and the exact constrained acceleration against the KKT solution built from MuJoCo's
pieces (qM, qfrc_bias, efc_J; J̇ qvel by a central difference of efc_J along
``mj_integratePos``, h = 1e-5, whose error ~h² + ε/h sets the tolerance 1e-8 relative);
finally, at rest, MuJoCo's own soft solution is reproduced as the KKT solution regularised by
its ``efc_R`` (1e-9) and casmbd's as the same with R = 0 (1e-9): the two differ only by
MuJoCo's softness (solimp 0.9999 in these files; measured 2e-5 relative for the connect,
1.3e-2 for the weld, whose rotational rows MuJoCo regularises more).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from casmbd.errors import ModelError, SceneError

mujoco = pytest.importorskip("mujoco")

import casmbd  # noqa: E402
from casmbd.io.mjcf import from_mujoco, load_mjcf  # noqa: E402

HERE = Path(__file__).resolve().parent / "mjcf"
MODELS = ("double_pendulum", "arm7", "four_bar", "free_body", "welded")
LOOPS = {"four_bar": 3, "welded": 6}  # models closed by an equality -> its rows


@pytest.fixture(scope="module")
def loaded():
    """name -> (mechanism, compiled model, MjModel with contacts and constraints off)."""
    out = {}
    for name in MODELS:
        path = HERE / f"{name}.xml"
        mech = load_mjcf(path)
        model = mujoco.MjModel.from_xml_path(str(path))
        model.opt.disableflags |= (mujoco.mjtDisableBit.mjDSBL_CONTACT
                                   | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        out[name] = (mech, casmbd.compile(mech, coordinates="joint"), model)
    return out


def _random_state(model, rng):
    qpos = model.qpos0 + 0.4 * rng.standard_normal(model.nq)
    for j in range(model.njnt):  # unit quaternions of free and ball joints
        if model.jnt_type[j] in (mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL):
            a = model.jnt_qposadr[j] + (3 if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE
                                        else 0)
            qpos[a:a + 4] /= np.linalg.norm(qpos[a:a + 4])
    return qpos, 1.5 * rng.standard_normal(model.nv)


def _mujoco_at(model, qpos, qvel):
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    try:
        mujoco.mj_fullM(model, data, full)  # MuJoCo 4: (m, d, dst)
    except TypeError:
        mujoco.mj_fullM(model, full, data.qM)  # MuJoCo 3: (m, dst, M)
    return data, full


@pytest.mark.parametrize("name", MODELS)
def test_rigid_body_dynamics_agree_with_mujoco(loaded, name):
    mech, arm, model = loaded[name]
    rng = np.random.default_rng(34)
    for _ in range(3):
        qpos, qvel = _random_state(model, rng)
        data, full = _mujoco_at(model, qpos, qvel)
        q, v, bmat, c = from_mujoco(mech, arm.coordinate_names, qpos, qvel,
                                  velocity_map=arm.velocity_map)
        mass = arm.mass_matrix(q)
        scale = np.abs(full).max()
        assert np.abs(bmat.T @ mass @ bmat - full).max() <= 1e-12 * scale
        bias = bmat.T @ (mass @ c + arm.bias_forces(q, v))
        want = data.qfrc_bias - data.qfrc_passive
        assert np.abs(bias - want).max() <= 1e-10 * max(1.0, np.abs(want).max())
        if name in LOOPS:
            continue  # the loop is closed in casmbd, open here: compared below
        qdd = arm.forward_dynamics(q, v, np.zeros(arm.nv))
        qacc = np.linalg.lstsq(bmat, qdd - c, rcond=None)[0]
        assert np.abs(qacc - data.qacc).max() <= 1e-9 * max(1.0, np.abs(data.qacc).max())


@pytest.mark.parametrize("name", [m for m in MODELS if m not in LOOPS])
def test_inverse_dynamics_agree_with_mj_inverse(loaded, name):
    """Bᵀ τ = qfrc_inverse (``mj_inverse``, constraints off) at a random (q, v, qacc): casmbd's
    τ = M a + b − C_qᵀ λ with a = B qacc + c, and C_q B = 0 for the Euler-parameter
    normalisations and the armature gears, so Bᵀ τ = Bᵀ (M a + b); 1e-10 relative."""
    mech, arm, model = loaded[name]
    rng = np.random.default_rng(3)
    qpos, qvel = _random_state(model, rng)
    qacc = rng.standard_normal(model.nv)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.qacc[:] = qpos, qvel, qacc
    mujoco.mj_inverse(model, data)
    q, v, bmat, c = from_mujoco(mech, arm.coordinate_names, qpos, qvel,
                                  velocity_map=arm.velocity_map)
    tau = arm.inverse_dynamics(q, v, bmat @ qacc + c)
    want = data.qfrc_inverse
    assert np.abs(bmat.T @ tau - want).max() <= 1e-10 * max(1.0, np.abs(want).max())


def _head(model, body: int) -> int:
    """The nearest body with joints at or above ``body`` (0: the world)."""
    while body and model.body_jntnum[body] == 0:
        body = model.body_parentid[body]
    return body


@pytest.mark.parametrize("name", MODELS)
def test_frames_and_sites_agree_with_mujoco(loaded, name):
    mech, arm, model = loaded[name]
    qpos, qvel = _random_state(model, np.random.default_rng(7))
    data, _ = _mujoco_at(model, qpos, qvel)
    q = from_mujoco(mech, arm.coordinate_names, qpos, qvel,
                                  velocity_map=arm.velocity_map)[0]
    pos, rot = arm.forward_kinematics(q)
    row = {f: i for i, f in enumerate(arm.frame_names)}
    for b in range(1, model.nbody):
        body = model.body(b).name
        if body in mech.bodies:  # centre of mass of the body and the bodies welded to it
            group = [k for k in range(b, model.nbody) if _head(model, k) == b]
            mass = model.body_mass[group]
            com = mass @ data.xipos[group] / mass.sum()
            assert np.abs(pos[row[body]] - com).max() <= 1e-12
        assert np.abs(rot[row[body]].reshape(3, 3) - data.xmat[b].reshape(3, 3)).max() \
            <= 1e-12
        if body in mech.markers:  # a welded body: its frame origin
            assert np.abs(pos[row[body]] - data.xpos[b]).max() <= 1e-12
    drawn = {v.name: (body, v) for body, vs in mech.visuals.items() for v in vs}
    assert len(drawn) == sum(model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE)
    for g in range(model.ngeom):  # geoms drawn: placed by the body, r_G + A u, axes A R_v
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        body, vis = drawn[model.geom(g).name or f"geom{g}"]
        axes = rot[row[body]].reshape(3, 3)
        assert np.abs(pos[row[body]] + axes @ vis.position - data.geom_xpos[g]).max() <= 1e-12
        assert np.abs(axes @ vis.rotation - data.geom_xmat[g].reshape(3, 3)).max() <= 1e-12
    for s in range(model.nsite):
        site = model.site(s).name
        assert np.abs(pos[row[site]] - data.site_xpos[s]).max() <= 1e-12
        assert np.abs(rot[row[site]].reshape(3, 3) - data.site_xmat[s].reshape(3, 3)).max() \
            <= 1e-12


def _loop_model(name):
    model = mujoco.MjModel.from_xml_path(str(HERE / f"{name}.xml"))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    return model


def _closure_rows(model, qpos, qvel=None):
    """MuJoCo's equality rows at qpos: residual efc_pos and Jacobian efc_J."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    data.qvel[:] = 0.0 if qvel is None else qvel
    mujoco.mj_forward(model, data)
    rows = int(np.sum(data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY))
    assert rows in LOOPS.values() and data.nefc == rows  # the equality's rows only
    return (data, data.efc_pos[:rows].copy(),
            data.efc_J[:rows * model.nv].reshape(rows, model.nv).copy())


def _closed_state(model, seed):
    """A pose where MuJoCo's equality holds (Gauss–Newton on its own residual) and a velocity
    in the null space of its Jacobian."""
    rng = np.random.default_rng(seed)
    qpos = model.qpos0.copy()
    mujoco.mj_integratePos(model, qpos, 0.2 * rng.standard_normal(model.nv), 1.0)
    for _ in range(40):
        _, residual, jac = _closure_rows(model, qpos)
        mujoco.mj_integratePos(model, qpos, -np.linalg.pinv(jac) @ residual, 1.0)
    _, residual, jac = _closure_rows(model, qpos)
    assert np.abs(residual).max() <= 1e-14
    rows = jac.shape[0]
    qvel = np.linalg.svd(jac)[2][rows:].T @ rng.standard_normal(model.nv - rows)
    return qpos, qvel


def test_connect_closure_agrees_with_mujoco_constraint_rows(loaded):
    """casmbd's spherical closure C = r_P(coupler) − r_P(rocker) is MuJoCo's connect residual,
    its Jacobian C_q B MuJoCo's efc_J, at a state where the loop is open."""
    mech, arm, _ = loaded["four_bar"]
    model = _loop_model("four_bar")
    qpos, qvel = _random_state(model, np.random.default_rng(5))
    _, residual, jac = _closure_rows(model, qpos)
    assert np.abs(residual).max() > 1e-2  # the loop is open here: the residual means something
    q, _, bmat, _ = from_mujoco(mech, arm.coordinate_names, qpos, qvel,
                                  velocity_map=arm.velocity_map)
    assert np.abs(arm.numeric.constraints(q, 0.0) - residual).max() <= 1e-12
    cq = arm.numeric.constraint_jacobian(q, 0.0).toarray()
    assert np.abs(cq @ bmat - jac).max() <= 1e-12


@pytest.mark.parametrize("name", sorted(LOOPS))
def test_closed_loop_acceleration_agrees_with_mujoco_pieces(name):
    """The exact constrained acceleration: casmbd's KKT solve against the one built from
    MuJoCo's qM, qfrc_bias and efc_J (J̇ qvel by central differences); the weld's rows
    (MuJoCo: position and quaternion error) and casmbd's rigid joint span the same space."""
    mech = load_mjcf(HERE / f"{name}.xml")
    arm = casmbd.compile(mech, coordinates="joint")
    model = _loop_model(name)
    qpos, qvel = _closed_state(model, 11)
    _, _, jac = _closure_rows(model, qpos)
    rows = jac.shape[0]
    q, v, bmat, c = from_mujoco(mech, arm.coordinate_names, qpos, qvel,
                                  velocity_map=arm.velocity_map)
    rates_b = from_mujoco(mech, arm.coordinate_names, qpos, qvel)[2]  # C_q acts on q̇
    cq = arm.numeric.constraint_jacobian(q, 0.0).toarray() @ rates_b

    def projector(mat):
        basis = np.linalg.svd(mat)[2][:rows]
        return basis.T @ basis

    assert np.linalg.matrix_rank(cq, 1e-9) == rows
    assert np.abs(projector(cq) - projector(jac)).max() <= 1e-12
    h = 1e-5

    def jac_at(t):
        moved = qpos.copy()
        mujoco.mj_integratePos(model, moved, qvel, t)
        return _closure_rows(model, moved)[2]

    jdot_v = (jac_at(h) - jac_at(-h)) / (2 * h) @ qvel
    data, full = _mujoco_at(model, qpos, qvel)
    n = model.nv
    kkt = np.block([[full, jac.T], [jac, np.zeros((rows, rows))]])
    exact = np.linalg.solve(kkt, np.concatenate([-(data.qfrc_bias - data.qfrc_passive),
                                                 -jdot_v]))[:n]
    qacc = np.linalg.lstsq(bmat, arm.forward_dynamics(q, v, np.zeros(arm.nv)) - c,
                           rcond=None)[0]
    assert np.abs(qacc - exact).max() <= 1e-8 * np.abs(exact).max()
    # at rest, MuJoCo's own soft solution is the regularised KKT solution with its efc_R,
    # qacc = a₀ + M⁻¹ Jᵀ f, f = −(J M⁻¹ Jᵀ + R)⁻¹ (J a₀ − a_ref); casmbd's is that with R = 0
    data, full = _mujoco_at(model, qpos, np.zeros(n))
    q, v, bmat, c = from_mujoco(mech, arm.coordinate_names, qpos, np.zeros(n),
                                  velocity_map=arm.velocity_map)
    rest = np.linalg.lstsq(bmat, arm.forward_dynamics(q, v, np.zeros(arm.nv)) - c,
                           rcond=None)[0]
    inverse = np.linalg.inv(full)
    free = -inverse @ (data.qfrc_bias - data.qfrc_passive)
    jac = data.efc_J[:rows * n].reshape(rows, n)
    for reg, want in ((np.diag(data.efc_R[:rows]), data.qacc), (0.0, rest)):
        force = -np.linalg.solve(jac @ inverse @ jac.T + reg,
                                 jac @ free - data.efc_aref[:rows])
        soft = free + inverse @ jac.T @ force
        assert np.abs(soft - want).max() <= 1e-9 * np.abs(want).max()


def test_actuators_keep_mujocos_joint_force(loaded):
    """u = gear·gain·ctrl: MuJoCo's qfrc_actuator at a control equals casmbd's actuator input
    on its joint; ctrlrange and forcerange become the bounds of u."""
    mech, _, model = loaded["arm7"]
    data = mujoco.MjData(model)
    ctrl = np.array([0.3, -0.7, 0.4])
    data.ctrl[:] = ctrl
    mujoco.mj_forward(model, data)
    for k, act in enumerate(mech.actuators.values()):
        dof = model.jnt_dofadr[model.joint(act.joint).id]
        force = np.clip(act.mjcf_gear * ctrl[k], *act.bounds)
        assert force == pytest.approx(data.qfrc_actuator[dof], rel=1e-14)
    assert mech.actuators["m1"].bounds == (-100.0, 100.0)
    assert mech.actuators["m2"].mjcf_gear == 160.0
    assert mech.actuators["m_extend"].bounds == (-50.0, 50.0)


def test_mapping_of_the_arm():
    """Multi-joint bodies become chained massless frames; a joint-less body merges into its
    parent and stays a marker; dampers become joint_friction elements; armature a rotor of
    inertia a about its axle, geared 1:1 to the joint (its share of qM is checked above)."""
    mech = load_mjcf(HERE / "arm7.xml")
    assert list(mech.bodies) == ["base", "shoulder", "upper", "elbow", "forearm__j5",
                                 "forearm", "wrist__j6", "wrist", "j2__rotor", "extend__rotor",
                                 "j6__rotor", "j7__rotor"]  # armature: rotors geared 1:1
    assert mech.bodies["forearm__j5"].mass == 0.0
    assert {"tool", "wrist_site", "tcp"} <= set(mech.markers)
    assert mech.forces["extend_damping"].damping == 2.0
    assert mech.forces["j6_damping"].damping == 0.05  # the 'wrist' default class
    assert mech.joints["j1"].mjcf_range == (-3.0, 3.0)
    assert tuple(mech.bodies["j6__rotor"].inertia) == (0.02, 0.01, 0.01)  # class "wrist"
    gear = mech.joints["extend__armature"]
    assert (gear.joint1, gear.joint2, gear.ratio) == ("extend", "extend__rotor_joint", 1.0)
    assert mech.bodies["extend__rotor"].mass == 0.5  # a slide's: a point mass normal to g
    assert abs(mech.joints["extend__rotor_joint"].axis @ mech.gravity) <= 1e-15
    wrist = mujoco.MjModel.from_xml_path(str(HERE / "arm7.xml"))
    wid, tid = wrist.body("wrist").id, wrist.body("tool").id
    assert mech.bodies["wrist"].mass == pytest.approx(
        wrist.body_mass[wid] + wrist.body_mass[tid], rel=1e-15)


# ---------------------------------------------------------------- refused, by name
_REFUSED = {
    "tendon": ("<tendon><fixed name='t'><joint joint='a' coef='1'/></fixed></tendon>",
               "tendon 't'"),
    "armature": ("", "joint 'a' attribute 'armature'", "type='ball' armature='0.1'"),
    "frictionloss": ("", "joint 'a' attribute 'frictionloss'", "frictionloss='0.1'"),
    "stiffness": ("", "joint 'a' attribute 'stiffness'", "stiffness='3'"),
    "servo": ("<actuator><position name='p' joint='a' kp='10'/></actuator>",
              "actuator 'p' attribute 'biastype'"),
    "site": ("<actuator><motor name='s' site='s'/></actuator>",
             "actuator 's' attribute 'site'"),
    "joint_equality": ("<equality><joint name='e' joint1='a' joint2='b'/></equality>",
                       "equality 'e'"),
    "nested_free": ("", "m.xml': Error: free joint can only be used on top level\nElement "
                    "name 'l3'", "",  # MuJoCo's own message
                    "<body name='l3'><freejoint name='f'/><geom size='0.1'/></body>"),
}


@pytest.mark.parametrize("case", sorted(_REFUSED))
def test_unmappable_parts_are_refused_by_name(tmp_path, case):
    extra, match, *more = _REFUSED[case]
    attr, child = (*more, "", "")[:2]
    xml = (f"<mujoco><worldbody><body name='l1'><joint name='a' axis='0 1 0' {attr}/>"
           f"<geom size='0.1' mass='1'/><site name='s'/>{child}<body name='l2' pos='0 0 -1'>"
           "<joint name='b' axis='0 1 0'/><geom size='0.1' mass='1'/></body></body>"
           f"</worldbody>{extra}</mujoco>")
    path = tmp_path / "m.xml"
    path.write_text(xml)
    with pytest.raises(SceneError, match=match):
        load_mjcf(path)


def test_bad_files_and_flags(loaded, tmp_path, monkeypatch):
    with pytest.raises(SceneError, match="not found"):
        load_mjcf(tmp_path / "missing.xml")
    (tmp_path / "bad.xml").write_text("<mujoco><worldbody><body>")
    with pytest.raises(SceneError, match=r"MJCF file .*bad\.xml"):
        load_mjcf(tmp_path / "bad.xml")
    (tmp_path / "g.xml").write_text("<mujoco><worldbody><body name='ground'><joint/>"
                                    "<geom size='.1'/></body></worldbody></mujoco>")
    with pytest.raises(SceneError, match=r"body 'ground'.*reserved"):
        load_mjcf(tmp_path / "g.xml")
    (tmp_path / "still.xml").write_text("<mujoco><worldbody><body name='b'><geom size='.1'/>"
                                        "</body></worldbody></mujoco>")
    with pytest.raises(SceneError, match=r"still\.xml': no body moves"):
        load_mjcf(tmp_path / "still.xml")
    flags = (HERE / "double_pendulum.xml").read_text().replace(
        '<option gravity="0 0 -9.81"/>',
        '<option gravity="0 0 -9.81"><flag gravity="disable" damper="disable"/></option>')
    (tmp_path / "flags.xml").write_text(flags)
    off = load_mjcf(tmp_path / "flags.xml")
    assert tuple(off.gravity) == (0.0, 0.0, 0.0) and not off.forces
    mech, arm, _ = loaded["double_pendulum"]
    with pytest.raises(ModelError, match="nq = 2 and qvel of length nv = 2, got 3 and 2"):
        from_mujoco(mech, arm.coordinate_names, [0.0] * 3, [0.0] * 2)
    with pytest.raises(ModelError, match="joint coordinates"):
        from_mujoco(mech, ["link1.x"], [0.0] * 2, [0.0] * 2)
    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(SceneError, match=r"casmbd\[mjcf\]"):
        load_mjcf(HERE / "arm7.xml")


def test_equalities_must_hold_in_the_design_pose(tmp_path):
    """A weld whose relpose is not met at qpos0 is refused with the gap; an inactive equality
    is left out with a warning."""
    arm = ("<mujoco><worldbody><body name='a'><joint name='j' axis='0 1 0'/>"
           "<geom size='0.1' mass='1'/></body><body name='b' pos='1 0 0'><joint name='k' "
           "axis='0 1 0'/><geom size='0.1' mass='1'/></body></worldbody><equality>{}"
           "</equality></mujoco>")
    path = tmp_path / "w.xml"
    path.write_text(arm.format("<weld name='w' body1='a' body2='b' relpose='0.5 0 0 1 0 0 0'/>"))
    with pytest.raises(SceneError, match=r"equality 'w' \(weld\): body 'b' is 0\.5 "):
        load_mjcf(path)
    path.write_text(arm.format("<connect name='c' body1='a' body2='b' anchor='1 0 0' "
                               "active='false'/>"))
    with pytest.warns(RuntimeWarning, match="equality 'c' is inactive"):
        mech = load_mjcf(path)
    assert "c" not in mech.joints


# ---------------------------------------------------------------- scene files and CLI
def test_scene_key_and_bare_xml(tmp_path):
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "dp.xml").write_text((HERE / "double_pendulum.xml").read_text())
    scene = tmp_path / "s.toml"
    scene.write_text('[scene]\nmjcf = "robot/dp.xml"\ncoordinates = "joint"\n'
                     'gravity = [0, 0, -3.0]\ndamping = false\n'
                     '[[drivers]]\nname = "bend"\njoint = "elbow"\nposition = "0.2*t"\n')
    mech = casmbd.load_scene(scene)  # the other tables name the file's joints and bodies
    assert list(mech.joints) == ["shoulder", "elbow"] and not mech.forces
    assert mech.drivers["bend"].joint == "elbow" and mech.tree == ["shoulder", "elbow"]
    assert tuple(mech.gravity) == (0.0, 0.0, -3.0)
    bare = casmbd.load_scene(HERE / "double_pendulum.xml")
    assert "shoulder_damping" in bare.forces and tuple(bare.gravity) == (0.0, 0.0, -9.81)
    scene.write_text('[scene]\nmjcf = "robot/dp.xml"\ndimension = 2\n')
    with pytest.raises(SceneError, match="dimension"):
        casmbd.load_scene(scene)
    scene.write_text('[scene]\nmjcf = "robot/dp.xml"\n[scene.locked]\nelbow = 0.1\n')
    with pytest.raises(SceneError, match=r"'locked'.*'mjcf'"):
        casmbd.load_scene(scene)


def test_cli_info_on_a_bare_xml():
    out = subprocess.run([sys.executable, "-W", "ignore", "-m", "casmbd", "info",
                          str(HERE / "arm7.xml"), "--json"], capture_output=True, text=True,
                         timeout=600, env={**os.environ, "CASMBD_COMPILE": "0"})
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["degrees_of_freedom"] == 8
