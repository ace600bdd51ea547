"""URDF ``initial`` and ``locked`` in every coordinate choice, and mimic pairs named together
(issue 30, item 4e).

* the same scene (7-axis arm with a hand, a mimic finger pair, a locked wrist, non-zero initial
  positions and rates) starts at the same body poses and velocities in joint, absolute and
  natural coordinates (1e-12), equal to an independent forward kinematics written in
  tests/io/test_urdf.py (every link frame: centres of mass of the merged bodies 1e-12 m, rotations
  1e-12; velocities against central differences of it along q̇, 1e-8);
* a small arm with a mimic offset (θ₂ = −0.5 θ₁ + 0.3) and a locked joint simulated for 0.2 s
  from non-zero initial positions and rates (rtol = atol = 1e-10) gives the same body
  trajectories in the three choices (1e-7 m and 1e-7 in the rotation matrices);
* a mimic leader and follower locked (or started) together: consistent values accepted (the
  fingers of the arm merged at the FK pose, 1e-12 m), inconsistent ones refused by a
  SceneError naming both joints, both values and the value the coupling gives;
* the first code example of docs/robots.md runs.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import casmbd
from casmbd import SceneError
from tests.io.test_urdf import ARM7, read, rnea

ROOT = Path(__file__).resolve().parents[2]
CHOICES = ("joint", "absolute", "natural")

#: non-zero initial positions (and rates) of the arm, panda_joint7 locked
ARM_INITIAL = {"panda_joint1": (0.3, 0.2), "panda_joint2": (0.4, -0.1),
               "panda_joint4": (-1.2, 0.05), "panda_joint6": 1.0,
               "panda_finger_joint1": (0.02, 0.01)}
ARM_LOCKED = {"panda_joint7": 0.3}


def _scene(tmp_path: Path, urdf: Path, coordinates: str, initial=None, locked=None) -> Path:
    """A scene file ``[scene] urdf = ...`` with ``[scene.initial]`` and ``[scene.locked]``."""
    lines = ["[scene]", f'urdf = "{urdf.resolve().as_posix()}"',
             f'coordinates = "{coordinates}"']
    for table, values in (("initial", initial), ("locked", locked)):
        if values:
            lines.append(f"[scene.{table}]")
            for name, value in values.items():
                text = (f"[{value[0]!r}, {value[1]!r}]" if isinstance(value, tuple)
                        else repr(float(value)))
                lines.append(f"{name} = {text}")
    path = tmp_path / f"{urdf.stem}_{coordinates}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _load_scene(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a scene's own notices are not under test here
        return casmbd.load_scene(path)


def _positions(values: dict) -> dict:
    return {k: (v[0] if isinstance(v, tuple) else v) for k, v in values.items()}


def _rates(values: dict) -> dict:
    return {k: (v[1] if isinstance(v, tuple) else 0.0) for k, v in values.items()}


def _reference_poses(mech, q: dict) -> dict:
    """Centre of mass and rotation of every body of ``mech`` from the independent forward
    kinematics (:func:`tests.test_urdf.rnea`): a body's links are its head link and the links
    that became markers on it; c = Σ mᵢ (pᵢ + Rᵢ cᵢ) / Σ mᵢ, R = the head link's."""
    links, _ = read(ARM7)
    _, frames = rnea(ARM7, q, {}, {})
    out = {}
    for body in mech.bodies:
        group = [body] + [m for m, marker in mech.markers.items() if marker.body == body]
        mass = sum(links[n][0] for n in group)
        com = sum(links[n][0] * (frames[n][1] + frames[n][0] @ links[n][1])
                  for n in group) / mass
        out[body] = (com, frames[body][0])
    return out


def test_arm_starts_at_the_same_pose_and_velocity_in_every_coordinate_choice(tmp_path):
    """Non-zero ``[scene.initial]`` with a locked joint and a mimic pair: the start poses and
    twists agree across the three choices (1e-12) and with the independent FK (1e-12), the
    velocities with its central differences along q̇ (h = 1e-6, 1e-8); C(q₀) = 0 (1e-14)."""
    q_ref = {**ARM_LOCKED, **_positions(ARM_INITIAL)}
    q_ref["panda_finger_joint2"] = q_ref["panda_finger_joint1"]  # the mimic follower
    rates = _rates(ARM_INITIAL)
    rates["panda_finger_joint2"] = rates["panda_finger_joint1"]
    starts = {}
    for coordinates in CHOICES:
        mech = _load_scene(_scene(tmp_path, ARM7, coordinates, ARM_INITIAL, ARM_LOCKED))
        arm = casmbd.compile(mech, coordinates=coordinates, mode="vm")
        q0, v0 = arm.numeric.initial_coordinates(), arm.numeric.initial_velocities()
        if coordinates != "joint":  # joint coordinates of a tree have only the gear row
            assert arm.nq > 20
        assert np.max(np.abs(arm.numeric.constraints(q0, 0.0)), initial=0.0) < 1e-14
        pos, rot = arm.forward_kinematics(q0)
        twist = np.array([arm.jacobian(q0, name) @ v0 for name in arm.frame_names])
        starts[coordinates] = (arm.frame_names, pos, rot, twist)
        ref = _reference_poses(mech, q_ref)
        for k, body in enumerate(mech.bodies):
            assert np.max(np.abs(pos[k] - ref[body][0])) < 1e-12, (coordinates, body)
            assert np.max(np.abs(rot[k] - ref[body][1])) < 1e-12, (coordinates, body)
        _, frames = rnea(ARM7, q_ref, {}, {})
        for name in mech.markers:  # merged links (locked, fixed): their frames
            k = arm.frame_names.index(name)
            if name in frames:
                assert np.max(np.abs(pos[k] - frames[name][1])) < 1e-12, (coordinates, name)
                assert np.max(np.abs(rot[k] - frames[name][0])) < 1e-12, (coordinates, name)
        h = 1e-6  # velocity of each centre of mass: central difference of the FK along q̇
        plus = _reference_poses(mech, {n: q_ref[n] + h * rates.get(n, 0.0) for n in q_ref})
        minus = _reference_poses(mech, {n: q_ref[n] - h * rates.get(n, 0.0) for n in q_ref})
        for k, body in enumerate(mech.bodies):
            expect = (plus[body][0] - minus[body][0]) / (2 * h)
            assert np.max(np.abs(twist[k][:3] - expect)) < 1e-8, (coordinates, body)
    names, pos, rot, twist = starts["joint"]
    for coordinates in ("absolute", "natural"):
        other = starts[coordinates]
        assert other[0] == names
        assert np.max(np.abs(other[1] - pos)) < 1e-12
        assert np.max(np.abs(other[2] - rot)) < 1e-12
        assert np.max(np.abs(other[3] - twist)) < 1e-12


# a small arm: j1 (y), j2 mimics j1 with θ₂ = −0.5 θ₁ + 0.3, j3 (x), j4 (z) locked at 0.6
_LINK = ('<link name="{n}"><inertial><origin xyz="{c}"/><mass value="{m}"/><inertia '
         'ixx="0.02" ixy="0.001" ixz="0" iyy="0.03" iyz="0.002" izz="0.025"/></inertial>'
         '</link>')
_SMALL = ('<robot name="small"><link name="base"/>'
          + _LINK.format(n="l1", c="0.2 0 0.05", m=1.5)
          + _LINK.format(n="l2", c="0.15 0.02 0", m=1.0)
          + _LINK.format(n="l3", c="0 0.1 0", m=0.7)
          + _LINK.format(n="l4", c="0.1 0.05 0", m=0.4)
          + '<joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>'
          '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/></joint>'
          '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>'
          '<origin xyz="0.4 0 0" rpy="0.2 0 0"/><axis xyz="0 1 0"/>'
          '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
          '<mimic joint="j1" multiplier="-0.5" offset="0.3"/></joint>'
          '<joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>'
          '<origin xyz="0.3 0 0"/><axis xyz="1 0 0"/></joint>'
          '<joint name="j4" type="revolute"><parent link="l3"/><child link="l4"/>'
          '<origin xyz="0 0.2 0"/><axis xyz="0 0 1"/>'
          '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>')


def test_small_arm_simulates_the_same_in_every_coordinate_choice(tmp_path):
    """Mimic offset, a locked joint and non-zero initial positions and rates: 0.2 s of
    ``simulate`` (rtol = atol = 1e-10) agree across the three choices to 1e-7 (positions in m,
    rotation matrices) at every output; the start equals the independent FK (1e-12 m)."""
    urdf = tmp_path / "small.urdf"
    urdf.write_text(_SMALL)
    initial, locked = {"j1": (0.4, 0.7), "j3": (-0.3, 0.5)}, {"j4": 0.6}
    q_ref = {"j1": 0.4, "j2": -0.5 * 0.4 + 0.3, "j3": -0.3, "j4": 0.6}
    links, _ = read(urdf)
    _, frames = rnea(urdf, q_ref, {}, {})
    runs = {}
    for coordinates in CHOICES:
        mech = _load_scene(_scene(tmp_path, urdf, coordinates, initial, locked))
        assert "j4" not in mech.joints and mech.markers["l4"].body == "l3"
        runs[coordinates] = casmbd.simulate(mech, t_end=0.2, steps=4, rtol=1e-10, atol=1e-10)
        assert runs[coordinates].stats["coordinates"] == coordinates
    for body in ("l1", "l2"):
        _, com, _ = links[body]
        expect = frames[body][1] + frames[body][0] @ com
        assert np.max(np.abs(runs["absolute"].body(body)["position"][0] - expect)) < 1e-12
    for coordinates in ("absolute", "natural"):
        for body in runs["joint"].names["bodies"]:
            ref, got = runs["joint"].body(body), runs[coordinates].body(body)
            assert np.max(np.abs(got["position"] - ref["position"])) < 1e-7, (coordinates, body)
            assert np.max(np.abs(got["rotation"] - ref["rotation"])) < 1e-7, (coordinates, body)
    moved = runs["joint"].body("l3")["position"]
    assert np.max(np.abs(moved[-1] - moved[0])) > 1e-2  # the arm does move


@pytest.mark.parametrize("coordinates", CHOICES)
def test_mimic_leader_and_follower_locked_together(tmp_path, coordinates):
    """The Panda case: ``[scene.locked]`` panda_finger_joint1 = panda_finger_joint2 = 0.03 is
    accepted (both fingers merged into the hand's body at the FK pose, 1e-12 m); 0.03 and
    0.02 are refused naming both joints, both values and the value the coupling gives."""
    locked = {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.03}
    mech = _load_scene(_scene(tmp_path, ARM7, coordinates, locked=locked))
    assert not any(j.endswith("_mimic") for j in mech.joints)
    assert {mech.markers[f].body for f in ("panda_leftfinger", "panda_rightfinger")} == \
        {"panda_link7"}
    _, frames = rnea(ARM7, locked, {}, {})
    for finger in ("panda_leftfinger", "panda_rightfinger"):
        assert np.max(np.abs(mech.markers[finger].point - frames[finger][1])) < 1e-12
    bad = {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.02}
    with pytest.raises(SceneError, match=r"locked joints 'panda_finger_joint1' = 0\.03 and "
                                         r"'panda_finger_joint2' = 0\.02 are inconsistent: "
                                         r"<mimic> couples 'panda_finger_joint2' = 1 \* "
                                         r"'panda_finger_joint1' \+ 0 gives "
                                         r"'panda_finger_joint2' = 0\.03"):
        _load_scene(_scene(tmp_path, ARM7, coordinates, locked=bad))


def test_mimic_pairs_named_together_or_alone(tmp_path):
    """θ₂ = −0.5 θ₁ + 0.3: consistent pairs accepted (to MIMIC_TOLERANCE = 1e-9 relative;
    0.1 typed for −0.5·0.4 + 0.3), inconsistent positions and rates named; a follower alone,
    or in the other table than its leader, names its leader; a chain follows its root; a cycle
    is named."""
    urdf = tmp_path / "small.urdf"
    urdf.write_text(_SMALL)

    def load(**kw):
        return casmbd.load_urdf(urdf, **kw)

    mech = load(locked={"j1": 0.4, "j2": 0.1}, coordinates="absolute")
    assert list(mech.joints) == ["j3", "j4"]
    _, frames = rnea(urdf, {"j1": 0.4, "j2": 0.1}, {}, {})
    assert np.max(np.abs(mech.markers["l2"].point - frames["l2"][1])) < 1e-12
    with pytest.raises(SceneError, match=r"locked joints 'j1' = 0\.4 and 'j2' = 0\.2 are "
                                         r"inconsistent: <mimic> couples 'j2' = -0\.5 \* 'j1' "
                                         r"\+ 0\.3 gives 'j2' = 0\.1"):
        load(locked={"j1": 0.4, "j2": 0.2})
    for coordinates in CHOICES:  # both initial: the gear holds at the start
        mech = load(initial={"j1": (0.4, 0.7), "j2": (0.1, -0.35)}, coordinates=coordinates)
        model = casmbd.NumericModel(mech, functions=["constraints"], mode="vm")
        assert np.max(np.abs(model.constraints(model.initial_coordinates(), 0.0)),
                      initial=0.0) < 1e-14
    with pytest.raises(SceneError, match=r"initial joints 'j1' = 0\.4 and 'j2' = 0\.15 are "
                                         r"inconsistent.*gives 'j2' = 0\.1"):
        load(initial={"j1": 0.4, "j2": 0.15})
    with pytest.raises(SceneError, match=r"initial joint velocities 'j1' = 0\.7 and 'j2' = 0 "
                                         r"are inconsistent.*gives 'j2' rate -0\.35"):
        load(initial={"j1": (0.4, 0.7), "j2": 0.1})
    with pytest.raises(SceneError, match=r"locked joint 'j2': <mimic> couples 'j2' = -0\.5 \* "
                                         r"'j1' \+ 0\.3; give 'j1' in \[locked\]"):
        load(locked={"j2": 0.1})
    with pytest.raises(SceneError, match=r"initial joint 'j2': .* its leader 'j1' is locked; "
                                         r"give both in \[initial\]"):
        load(locked={"j1": 0.4}, initial={"j2": 0.1})
    chain = _SMALL.replace('<origin xyz="0.3 0 0"/><axis xyz="1 0 0"/></joint>',
                           '<origin xyz="0.3 0 0"/><axis xyz="1 0 0"/>'
                           '<mimic joint="j2" multiplier="2"/></joint>')
    mech = casmbd.loads_urdf(chain, locked={"j1": 0.4})  # j3 = 2 j2 = 2 (−0.5·0.4 + 0.3)
    _, frames = rnea(urdf, {"j1": 0.4, "j2": 0.1, "j3": 0.2}, {}, {})
    assert np.max(np.abs(mech.joints["j4"].point - frames["l4"][1])) < 1e-12
    cycle = _SMALL.replace('<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/></joint>',
                           '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
                           '<mimic joint="j2"/></joint>')
    with pytest.raises(SceneError, match=r"<mimic> joints j\d -> j\d -> j\d follow each "
                                         "other in a cycle"):
        casmbd.loads_urdf(cycle)


def test_first_code_example_of_robots_md_runs(monkeypatch):
    """docs/robots.md's first ```python block, run from the repository root."""
    text = (ROOT / "docs" / "robots.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    monkeypatch.chdir(ROOT)
    scope: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        exec(compile(code, "docs/robots.md", "exec"), scope)
    mech = scope["mech"]
    assert mech.coordinates == "absolute" and "wrist_3_joint" not in mech.joints
