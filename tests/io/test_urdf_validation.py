"""URDF model checks at load and the repairs and overrides of issue 34, item 4
(:mod:`casmbd.io.urdf_checks`; the named singular-mass-matrix error of
:mod:`casmbd.compiled.robot`).

Numbers checked: the repaired inertia's principal moments against the closed-form projection
(1e-12 relative) and against every physical tensor of a random sample (none nearer), the
triangle inequality of every repaired tensor; overridden mass, centre of mass and inertia
through the mass matrix of a revolute joint, M = Izz + m d² (1e-12); a link renamed from
``ground`` or a revolute joint without ``<limit>`` against the same robot written otherwise
(mass matrices equal to 1e-14); the massless end link's named error and its override's
forward dynamics (M q̈ + b = τ to 1e-12).  The example-robot-data files (romeo_small,
alex_psyonic_hands, romeo) are used when installed, skipped cleanly otherwise.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

import casmbd
from casmbd import SceneError, loads_urdf
from casmbd.errors import SingularMassMatrixError
from casmbd.io.scene import loads_scene
from casmbd.io.urdf_checks import nearest_physical_inertia
from casmbd.model.bodies import check_inertia

_INERTIA = ('<inertial><origin xyz="{com}"/><mass value="{m}"/><inertia ixx="{ixx}" ixy="0" '
            'ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/></inertial>')


def _link(name, m=1.0, com="0 0 0", ixx=1.0, iyy=1.0, izz=1.0):
    return f'<link name="{name}">' + _INERTIA.format(m=m, com=com, ixx=ixx, iyy=iyy,
                                                      izz=izz) + "</link>"


def _joint(name, parent, child, kind="continuous", axis="0 0 1", xyz="0 0 0", extra=""):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child '
            f'link="{child}"/><origin xyz="{xyz}"/><axis xyz="{axis}"/>{extra}</joint>')


def _robot(*parts, name="r"):
    return f'<robot name="{name}">' + "".join(parts) + "</robot>"


def _quiet(text, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return loads_urdf(text, "t.urdf", **options)


def _tensor(body):
    ixx, iyy, izz, ixy, ixz, iyz = body.inertia
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], float)


# ------------------------------------------------------------------ the projection
def test_nearest_physical_inertia_closed_form_and_minimal():
    """λ = (1, 1, 3) violates λ₃ ≤ λ₁ + λ₂ by e = 1: the projection onto the face moves each
    moment by e/3, (4/3, 4/3, 8/3), at distance e/√3; (−1, 2, 2) goes to (0, 2, 2) (both
    faces active), distance 1.  Random rotated tensors: the repair passes check_inertia, keeps
    the principal axes (I' I = I I'), and no physical tensor of a sample is nearer."""
    fixed, before, after = nearest_physical_inertia(np.diag([1.0, 1.0, 3.0]))
    assert np.allclose(after, [4 / 3, 4 / 3, 8 / 3], rtol=1e-12, atol=0)
    assert abs(np.linalg.norm(after - before) - 1 / np.sqrt(3)) < 1e-12
    assert np.allclose(fixed, np.diag([4 / 3, 4 / 3, 8 / 3]), rtol=1e-12, atol=1e-15)
    _, _, after = nearest_physical_inertia(np.diag([-1.0, 2.0, 2.0]))
    assert np.allclose(after, [0.0, 2.0, 2.0], atol=1e-12)
    rng = np.random.default_rng(3)
    for _ in range(20):
        rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        lam = rng.uniform(-0.5, 3.0, 3)
        tensor = rot @ np.diag(lam) @ rot.T
        fixed, before, after = nearest_physical_inertia(tensor)
        check_inertia([fixed[0, 0], fixed[1, 1], fixed[2, 2], fixed[0, 1], fixed[0, 2],
                       fixed[1, 2]])
        s = np.sort(after)
        assert s[2] <= s[0] + s[1] + 1e-12 * s.sum() and s[0] >= 0.0
        assert np.linalg.norm(fixed @ tensor - tensor @ fixed) < 1e-12 * np.sum(np.abs(lam))
        # sample physical moments (Σ = diag(σ) ≥ 0, λᵢ = tr Σ − σᵢ): none nearer
        sigma = rng.uniform(0.0, 3.0, (4000, 3))
        sample = sigma.sum(axis=1, keepdims=True) - sigma
        dist = np.linalg.norm(np.sort(sample, axis=1) - np.sort(before), axis=1)
        assert dist.min() >= np.linalg.norm(after - before) - 1e-12


# ------------------------------------------------------------------ inertia check and repair
_BAD = _robot(_link("a"), _link("b", m=2.0, ixx=0.1, iyy=0.1, izz=0.3),
              _joint("j", "a", "b", axis="0 0 1"))


def test_impossible_inertia_refused_at_load_naming_the_link():
    with pytest.raises(SceneError, match=r"link 'b' <inertia>: inertia violates the triangle "
                                         r"inequality Ixx \+ Iyy >= Izz.*inertia = \"repair\""):
        loads_urdf(_BAD, "t.urdf")
    with pytest.raises(SceneError, match=r"inertia: expected one of 'check', 'repair'"):
        loads_urdf(_BAD, "t.urdf", inertia="fix")


def test_inertia_repair_projects_and_warns():
    """Izz = 0.3 > Ixx + Iyy = 0.2 by e = 0.1: repaired to (0.1 + e/3, 0.1 + e/3, 0.3 − e/3),
    mass and centre of mass unchanged; M of the revolute joint about z through the centre of
    mass is the repaired Izz."""
    with pytest.warns(RuntimeWarning, match=r"inertia = \"repair\": link 'b' principal moments "
                                            r"\[0.1, 0.1, 0.3\] -> \[0.133333, 0.133333, "
                                            r"0.266667\]"):
        mech = loads_urdf(_BAD, "t.urdf", inertia="repair")
    e = 0.1
    body = mech.bodies["b"]
    assert np.allclose(np.linalg.eigvalsh(_tensor(body)), [0.1 + e / 3, 0.1 + e / 3,
                                                           0.3 - e / 3], rtol=1e-12, atol=0)
    assert body.mass == 2.0 and np.allclose(body.position, 0.0)
    mech.validate()
    model = casmbd.compile(mech)
    assert abs(model.mass_matrix([0.0])[0, 0] - (0.3 - e / 3)) < 1e-12


def test_check_is_on_the_merged_body():
    """Link b alone violates the triangle inequality, but welded (fixed joint) to c of mass
    1 kg 0.5 m off along z it is a physical body (as Pinocchio merges it): loads without a
    warning.  With c massless the merge stays unphysical; the repair gives the body the
    nearest physical tensor of the merge."""
    welded = _robot(_link("a"), _link("b", m=2.0, ixx=0.1, iyy=0.1, izz=0.3),
                    _link("c", m=1.0, com="0 0 0.5", ixx=0.01, iyy=0.01, izz=0.01),
                    _joint("j", "a", "b"), _joint("w", "b", "c", kind="fixed"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mech = loads_urdf(welded, "t.urdf")
    mech.validate()
    merged = _tensor(mech.bodies["b"])
    d1, d2 = 0.5 / 3, 0.5 * 2 / 3  # the centre of mass 1/3 of 0.5 m from b toward c
    shift = 2 * d1 ** 2 + d2 ** 2  # parallel axes: Σ mᵢ dᵢ² about x and y
    expect = np.diag([0.11 + shift, 0.11 + shift, 0.31])
    assert np.allclose(merged, expect, rtol=1e-12, atol=1e-15)
    bare = welded.replace('<mass value="1.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" '
                          'iyz="0" izz="0.01"/>', '<mass value="0"/><inertia ixx="0" ixy="0" '
                          'ixz="0" iyy="0" iyz="0" izz="0"/>')
    with pytest.raises(SceneError, match=r"link 'b' \(with the links welded to it: c\) "
                                         r"<inertia>"):
        loads_urdf(bare, "t.urdf")
    with pytest.warns(RuntimeWarning, match="link 'b' .with the links welded to it: c."):
        mech = loads_urdf(bare, "t.urdf", inertia="repair")
    target = nearest_physical_inertia(np.diag([0.1, 0.1, 0.3]))[0]
    assert np.allclose(_tensor(mech.bodies["b"]), target, rtol=1e-12, atol=1e-15)


# ------------------------------------------------------------------ per-link overrides
def test_link_overrides_mass_com_inertia():
    """links = {b: mass 3, com (0.2, 0, 0), inertia [0.1, 0.2, 0.25]}: the file's impossible
    inertia is replaced before the check; M of the joint about z at the origin is
    Izz + m d² = 0.25 + 3·0.04 (1e-12).  A key left out keeps the file's value."""
    mech = _quiet(_BAD, links={"b": {"mass": 3.0, "com": [0.2, 0.0, 0.0],
                                     "inertia": [0.1, 0.2, 0.25]}})
    body = mech.bodies["b"]
    assert body.mass == 3.0 and np.allclose(body.position, [0.2, 0.0, 0.0], atol=1e-15)
    model = casmbd.compile(mech)
    assert abs(model.mass_matrix([0.0])[0, 0] - (0.25 + 3.0 * 0.04)) < 1e-12
    only_mass = _quiet(_BAD, inertia="repair", links={"b": {"mass": 5.0}})
    assert only_mass.bodies["b"].mass == 5.0
    assert np.allclose(np.linalg.eigvalsh(_tensor(only_mass.bodies["b"])),
                       [0.1 + 0.1 / 3, 0.1 + 0.1 / 3, 0.3 - 0.1 / 3], rtol=1e-12)


@pytest.mark.parametrize("links, match", [
    ({"z": {"mass": 1.0}}, r"links.z: unknown link 'z' \(links: a, b\)"),
    ({"b": {"mas": 1.0}}, r"links.b: unknown key\(s\) 'mas'"),
    ({"b": {"mass": -1.0}}, r"links.b.mass: must be >= 0"),
    ({"b": {"mass": "x"}}, r"links.b.mass: expected a finite number"),
    ({"b": {"com": [0, 0]}}, r"links.b.com: expected a list of 3 finite numbers"),
    ({"b": {"inertia": [1, 1, 3]}}, r"links.b.inertia: inertia violates the triangle"),
    ({"b": {"inertia": [1, 1, float("nan")]}}, r"links.b.inertia: expected a list of 3 or 6"),
])
def test_link_override_errors_are_named(links, match):
    with pytest.raises(SceneError, match=match):
        loads_urdf(_BAD, "t.urdf", links=links)


# ------------------------------------------------------------------ mimic
_MIMIC = _robot(_link("a"), _link("b"), _link("c", com="0.5 0 0"), _joint("j", "a", "b"),
                _joint("f", "a", "c", xyz="1 0 0",
                       extra='<mimic joint="{leader}" multiplier="2"/>'))


def test_broken_mimic_refused_then_ignored():
    """A <mimic> naming an unknown joint (alex_psyonic_hands) is refused suggesting
    ignore_mimic; with it the follower is an independent joint (two coordinates, no gear);
    a valid <mimic> ignored by name likewise, kept otherwise (a gear)."""
    broken = _MIMIC.format(leader="nope")
    with pytest.raises(SceneError, match=r"joint 'f' <mimic> attribute 'joint': unknown joint "
                                         r"'nope' \(load with ignore_mimic = true"):
        loads_urdf(broken, "t.urdf")
    for ignore in (True, ["f"]):
        with pytest.warns(RuntimeWarning, match=r"<mimic> ignored for f \(ignore_mimic\): "
                                                "each is an independent joint"):
            mech = loads_urdf(broken, "t.urdf", ignore_mimic=ignore)
        assert list(mech.joints) == ["j", "f"]
        model = casmbd.compile(mech)
        assert model.nq == 2 and model.nc == 0
        m = model.mass_matrix([0.0, 0.0])
        assert np.allclose(m, np.diag([1.0, 1.25]), rtol=1e-12)  # Izz, Izz + m 0.5²
    valid = _MIMIC.format(leader="j")
    assert "f_mimic" in loads_urdf(valid, "t.urdf").joints
    with pytest.warns(RuntimeWarning, match="<mimic> ignored for f"):
        assert "f_mimic" not in loads_urdf(valid, "t.urdf", ignore_mimic=["f"]).joints
    with pytest.raises(SceneError, match=r"ignore_mimic: joint\(s\) 'j' have no <mimic>"):
        loads_urdf(valid, "t.urdf", ignore_mimic=["j"])
    with pytest.raises(SceneError, match=r"ignore_mimic: expected true, false or a list"):
        loads_urdf(valid, "t.urdf", ignore_mimic="f")


# ------------------------------------------------------------------ names, limits
def test_link_named_ground_keeps_its_frame_and_moves():
    """A root link named ground becomes the marker ground_link at the origin (it was dropped);
    a moving link named ground is the body ground_link, with the mass matrix of the same robot
    with the link named x (1e-14)."""
    root = _robot('<link name="ground"/>', _link("b", com="0.3 0 0"),
                  _joint("j", "ground", "b", axis="0 0 1"))
    with pytest.warns(RuntimeWarning, match="names casmbd reserves renamed: 'ground' -> "
                                            "'ground_link'"):
        mech = loads_urdf(root, "t.urdf")
    assert mech.markers["ground_link"].body == "ground"
    fk, _ = casmbd.compile(mech).forward_kinematics([0.4])
    assert np.allclose(fk[1], 0.0, atol=1e-15)  # frames: b, ground_link
    moving = _robot('<link name="a"/>', _link("ground", com="0.3 0 0"), _link("c", com="0 0.2 0"),
                    _joint("j", "a", "ground", axis="0 0 1"),
                    _joint("k", "ground", "c", xyz="0.5 0 0", axis="0 0 1"))
    with pytest.warns(RuntimeWarning, match="'ground' -> 'ground_link'"):
        mech = loads_urdf(moving, "t.urdf")
    assert set(mech.bodies) == {"ground_link", "c"}
    same = _quiet(moving.replace('"ground"', '"x"'))
    q = [0.3, -0.7]
    m1 = casmbd.compile(mech).mass_matrix(q)
    m2 = casmbd.compile(same).mass_matrix(q)
    assert np.allclose(m1, m2, rtol=1e-14, atol=1e-14) and m1[0, 0] > 1.0


def test_names_with_reserved_characters_are_renamed():
    """allegro's link_8.0 and joint_8.0: '.' becomes '_' (a suffix if taken), the <mimic>
    leader and the locked and initial keys follow (either name); the start angle of the
    renamed joint is its tree coordinate."""
    text = _robot(_link("a"), _link("l.1", com="0.2 0 0"), _link("l_1", com="0.2 0 0"),
                  _link("c@2", com="0.1 0 0"),
                  _joint("j.1", "a", "l.1"), _joint("k", "a", "l_1", xyz="1 0 0"),
                  _joint("m", "l.1", "c@2", xyz="0.5 0 0", extra='<mimic joint="j.1"/>'))
    with pytest.warns(RuntimeWarning, match=r"'l.1' -> 'l_1_2', 'c@2' -> 'c_2', 'j.1' -> "
                                            r"'j_1'"):
        mech = loads_urdf(text, "t.urdf", initial={"j.1": 0.25})
    assert set(mech.bodies) == {"l_1_2", "l_1", "c_2"} and "m_mimic" in mech.joints
    model = casmbd.compile(mech)
    assert model.coordinate_names[:2] == ["j_1.angle", "k.angle"]
    assert abs(mech.joints["j_1"].tree_initial()[0] - 0.25) < 1e-15
    locked = _quiet(text, locked={"j_1": 0.1})
    assert "j_1" not in locked.joints and "l_1_2" not in locked.bodies
    for key in ("l.1", "l_1_2"):  # an override by either name
        assert _quiet(text, links={key: {"mass": 3.0}}).bodies["l_1_2"].mass == 3.0
    for key in ("m", ["m"]):
        assert "m_mimic" not in _quiet(text, ignore_mimic=True if key == "m" else key).joints


def test_revolute_without_limit_loads_with_a_warning():
    text = _robot(_link("a"), _link("b", com="0.2 0 0"), _joint("j", "a", "b", kind="revolute"))
    with pytest.warns(RuntimeWarning, match="joint 'j': a revolute joint without <limit>"):
        mech = loads_urdf(text, "t.urdf")
    assert mech.joints["j"].urdf_limits == {} and mech.joints["j"].urdf_type == "revolute"
    cont = _quiet(text.replace('"revolute"', '"continuous"'))
    assert abs(casmbd.compile(mech).mass_matrix([0.1])[0, 0]
               - casmbd.compile(cont).mass_matrix([0.1])[0, 0]) < 1e-14


# ------------------------------------------------------------------ no moving body
_QUAD = _robot(_link("base_link", m=1.5, ixx=0.01, iyy=0.01, izz=0.02), name="quad")


def test_no_moving_body_refused_at_load_suggesting_floating_base(tmp_path):
    with pytest.raises(SceneError, match=r"URDF 'quad': no moving body: every link is welded "
                                         r"to the ground \(1 link, no joints\).*floating_base "
                                         "= true"):
        loads_urdf(_QUAD, "t.urdf")
    path = tmp_path / "quad.urdf"
    path.write_text(_QUAD)
    out = subprocess.run([sys.executable, "-m", "casmbd", "info", str(path)],
                         capture_output=True, text=True, timeout=300,
                         env={**os.environ, "CASMBD_COMPILE": "0"})
    assert out.returncode != 0
    assert "floating_base = true" in out.stderr and "[[bodies]]" not in out.stderr


# ------------------------------------------------------------------ massless end links
_ARM = _robot('<link name="base"/>', _link("l1", com="0 0.3 0", ixx=0.1, iyy=0.1, izz=0.1),
              '<link name="l2"/>', _joint("j1", "base", "l1", axis="1 0 0"),
              _joint("j2", "l1", "l2", xyz="0 0.5 0", axis="1 0 0"))


def test_massless_end_link_warns_at_load_and_forward_dynamics_names_it():
    """l2 has no inertial: the load warns naming j2 and l2; M[1, 1] = 0 exactly; forward
    dynamics (one state and batch) raises SingularMassMatrixError naming j2.angle and l2
    instead of returning inf.  With links = {l2: mass 0.5 at 0.1 m, inertia} the warning is
    gone and M q̈ + b = τ holds (1e-12)."""
    with pytest.warns(RuntimeWarning, match=r"massless end links: joint 'j2' moves only l2: "
                                            "no inertia about the joint axis"):
        mech = loads_urdf(_ARM, "t.urdf")
    model = casmbd.compile(mech)
    zero = np.zeros(2)
    assert model.mass_matrix(zero)[1, 1] == 0.0
    with pytest.raises(SingularMassMatrixError, match=r"forward_dynamics: the mass matrix is "
                                                      r"singular.*'j2.angle' \(body 'l2'") as err:
        model.forward_dynamics(zero, zero, zero)
    assert err.value.coordinates == ["j2.angle"] and err.value.bodies == ["l2"]
    assert isinstance(err.value, casmbd.CasmbdError)
    with pytest.raises(SingularMassMatrixError, match=r"forward_dynamics_batch \(state 0\)"):
        model.forward_dynamics_batch(np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2)))
    assert np.all(np.isfinite(model.inverse_dynamics(zero, zero, zero)))  # unaffected
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fixed = loads_urdf(_ARM, "t.urdf", links={"l2": {"mass": 0.5, "com": [0, 0.1, 0],
                                                         "inertia": [1e-3, 1e-3, 1e-3]}})
    model = casmbd.compile(fixed)
    q, v, tau = np.array([0.3, -0.2]), np.array([0.5, 1.0]), np.array([0.1, -0.05])
    a = model.forward_dynamics(q, v, tau)
    resid = model.mass_matrix(q) @ a + model.bias_forces(q, v) - tau
    assert np.max(np.abs(resid)) < 1e-12


def test_massless_mimic_pair_names_the_singular_motion():
    """Two massless links coupled by <mimic> (romeo's fingers).  In joint coordinates the
    follower is substituted (a tree: the compiled LDLᵀ meets a zero pivot); with the gear kept
    as a constraint (``substitute_gears = False``) forward dynamics goes through the KKT solve,
    which numpy finds singular.  Both errors name the leader's coordinate."""
    text = _robot(_link("a"), _link("b", com="0.2 0 0"), '<link name="c"/>', '<link name="d"/>',
                  _joint("j", "a", "b"), _joint("k", "b", "c", xyz="0.4 0 0"),
                  _joint("f", "b", "d", xyz="0 0.4 0", extra='<mimic joint="k"/>'))
    with pytest.warns(RuntimeWarning, match="joint 'k' moves only c"):
        mech = loads_urdf(text, "t.urdf")
    model = casmbd.compile(mech)
    assert model.nc == 0 and "f.angle" not in model.coordinate_names  # substituted
    zero = np.zeros(model.nq)
    with pytest.raises(SingularMassMatrixError, match="has no inertia") as err:
        model.forward_dynamics(zero, zero, zero)
    assert set(err.value.coordinates) == {"k.angle"}
    mech.substitute_gears = False  # the gear as a constraint equation: the KKT path
    model = casmbd.compile(mech)
    assert model.nc == 1
    zero = np.zeros(model.nq)
    with pytest.raises(SingularMassMatrixError, match="on the null space of the constraint "
                                                      "Jacobian") as err:
        model.forward_dynamics(zero, zero, zero)
    assert set(err.value.coordinates) == {"k.angle", "f.angle"}


# ------------------------------------------------------------------ scene keys
def test_scene_keys_inertia_links_ignore_mimic(tmp_path):
    (tmp_path / "r.urdf").write_text(_robot(
        _link("a"), _link("b", m=2.0, ixx=0.1, iyy=0.1, izz=0.3), _link("c"),
        _joint("j", "a", "b"), _joint("f", "a", "c", xyz="1 0 0",
                                      extra='<mimic joint="nope"/>')))
    scene = ('[scene]\nurdf = "r.urdf"\ninertia = "repair"\nignore_mimic = ["f"]\n'
             '[scene.links.c]\nmass = 1.0\ncom = [0.1, 0.0, 0.0]\ninertia = [0.01, 0.01, 0.01]\n')
    with pytest.warns(RuntimeWarning):
        mech = loads_scene(scene, str(tmp_path / "s.toml"))
    assert mech.bodies["c"].mass == 1.0
    assert abs(np.linalg.eigvalsh(_tensor(mech.bodies["b"]))[2] - (0.3 - 0.1 / 3)) < 1e-12
    with pytest.raises(SceneError, match=r"\[scene\] key 'urdf' \('r.urdf'\): links.c.mass"):
        loads_scene(scene.replace("mass = 1.0", "mass = -1.0"), str(tmp_path / "s.toml"))
    with pytest.raises(SceneError, match="key 'inertia': needs 'urdf'"):
        loads_scene('[scene]\ndimension = 3\ninertia = "repair"\n', "s.toml")


# ------------------------------------------------------------------ example-robot-data
def _robots():
    try:
        from benchmarks.robots_vs_pinocchio import robots_dir
    except ImportError:
        return None
    return robots_dir()


ROOT = _robots()
needs_erd = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed")


@needs_erd
def test_published_files_load_with_the_documented_options():
    """romeo_small: refused naming RShoulderYawLink, loads with inertia = "repair" with every
    body physical; alex_psyonic_hands: refused naming the broken <mimic>, loads with
    ignore_mimic; romeo as shipped warns of its massless fingers."""
    small = ROOT / "romeo_description/urdf/romeo_small.urdf"
    with pytest.raises(SceneError, match="link 'RShoulderYawLink' <inertia>"):
        casmbd.load_urdf(small)
    with pytest.warns(RuntimeWarning, match="RShoulderYawLink"):
        casmbd.load_urdf(small, inertia="repair").validate()
    alex = ROOT / "alex_description/urdf/alex_psyonic_hands.urdf"
    with pytest.raises(SceneError, match="<mimic> attribute 'joint': unknown joint"):
        casmbd.load_urdf(alex)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        casmbd.load_urdf(alex, ignore_mimic=True, inertia="repair").validate()
    with pytest.warns(RuntimeWarning, match="massless end links: joint 'LHand'"):
        casmbd.load_urdf(ROOT / "romeo_description/urdf/romeo.urdf")
