"""Statics on real robot arms (issue 18, item 5): a UR5-like 6-joint arm and a Panda-like 7-joint
arm (tests/scenes/ur_like.toml, panda_like.toml), from the zero pose, in absolute, natural and
joint coordinates, with both methods; plus the trust-region step and the stability verdict.

The hanging arm is a stable equilibrium: these runs ask for one (``stable=True``, ``--stable``:
the search descends the potential energy).  The default search (the equilibrium nearest the
zero pose, issue 30) is checked on the same arms at the end."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.statics.stability import STABILITY_RTOL, classify_stability
from casmbd.analysis.statics.statics import STATICS_NEEDS, static_equilibrium, statics_functions
from casmbd.analysis.statics.trust_region import trust_region_step
from casmbd.cli import main
from casmbd.compiled.model import NumericModel
from casmbd.io.scene import load_scene
from casmbd.system.equations import System

SCENES = {"ur_like": "tests/scenes/ur_like.toml", "panda_like": "tests/scenes/panda_like.toml"}
COORDINATES = ("absolute", "natural", "joint")
METHODS = ("augmented", "reduced")
#: joints about which gravity does no work in any pose (the honest neutral directions)
NULL_JOINTS = {"ur_like": {"shoulder_pan", "wrist_3"}, "panda_like": {"panda_joint1"}}
RTOL = 1e-10   # equilibrium residual, relative to the largest applied force at the start
ANGLE_TOL = 1e-8


_cache = private_cache("cache")


@functools.cache
def model_of(scene: str, coordinates: str) -> NumericModel:
    mech = load_scene(SCENES[scene])
    mech.coordinates = coordinates
    system = System(mech)
    return NumericModel(system, STATICS_NEEDS, mode="vm", extra=statics_functions(system))


@functools.cache
def solve(scene: str, coordinates: str, method: str, stable: bool = True):
    return static_equilibrium(model_of(scene, coordinates), method=method, stable=stable)


CASES = [(s, c, m) for s in SCENES for c in COORDINATES for m in METHODS]


@pytest.mark.parametrize("scene,coordinates,method", CASES)
def test_equilibrium_residual_and_verdict(scene, coordinates, method):
    """Q_e − C_qᵀλ = 0 to 1e-10 · max(1, max|Q_e(q₀)|) (the largest applied generalized force at
    the assembled zero pose: a gravity force or moment) and C = 0 to 1e-10 · max(1, size),
    re-evaluated here; the hanging arm is a minimum that is neutral exactly in the joints
    about which gravity does no work."""
    model = model_of(scene, coordinates)
    r = solve(scene, coordinates, method)
    q0 = assemble(model, model.initial_coordinates(), 0.0).q
    qe0 = model.vector("statics_forces", q0, 0.0, model.p)
    f = model.vector("statics_residual", r.q, r.lagrange_multipliers, 0.0, model.p)
    nq = model.nq
    assert np.max(np.abs(f[:nq])) <= RTOL * max(1.0, np.max(np.abs(qe0)))
    assert np.max(np.abs(f[nq:]), initial=0.0) <= RTOL * 1.0  # arm size < 1.1 m
    assert r.iterations <= 60
    assert r.stability.verdict == "neutral" and r.stable is None
    assert set(r.stability.null_coordinates()) == NULL_JOINTS[scene]
    assert len(r.stability.null_directions) == len(NULL_JOINTS[scene])
    assert r.eigenvalues[0] >= -r.stability.tolerance  # no downhill direction: hanging
    # principal range and sign-normalised quaternions, proper bodies
    assert np.all((r.joint_coordinates > -np.pi) & (r.joint_coordinates <= np.pi))
    assert np.all(r.body_quaternions[:, 0] >= 0.0)
    if coordinates == "natural":
        for body in model.body_names:
            k = model.coordinate_index[body] + 3
            assert np.linalg.det(r.q[k:k + 9].reshape(3, 3)) == pytest.approx(1.0, abs=1e-9)
    # the arm hangs: every centre of mass below the shoulder
    assert np.all(r.body_positions[1:, 2] < r.body_positions[0, 2] + 0.1)


def invariants(r, scene: str) -> np.ndarray:
    """Pose quantities that do not depend on the neutral joints: the angles of the other
    joints, the height and the distance from the base axis of every centre of mass."""
    names = r.names["joints"]
    free = [k for k, n in enumerate(names) if n not in NULL_JOINTS[scene]]
    pos = r.body_positions
    return np.concatenate([r.joint_coordinates[free], pos[:, 2],
                           np.hypot(pos[:, 0], pos[:, 1])])


@pytest.mark.parametrize("scene", list(SCENES))
def test_methods_and_coordinates_agree(scene):
    """Both methods reach the same equilibrium in each coordinate choice (to 1e-8).  The Panda
    reaches the same hanging pose in all three coordinate choices; the UR5 has two hanging
    minima of equal potential energy (wrist 2 at ±π/2, wrist 1 compensating — mirror images
    through the arm's vertical plane): joint coordinates reach one, absolute and natural the
    other; both are verified equilibria (previous test) and their energies agree to 1e-9 J."""
    runs = {(c, m): solve(scene, c, m) for c in COORDINATES for m in METHODS}
    for c in COORDINATES:
        a, b = invariants(runs[c, "augmented"], scene), invariants(runs[c, "reduced"], scene)
        assert np.max(np.abs(a - b)) <= ANGLE_TOL
    ref = invariants(runs["absolute", "reduced"], scene)
    assert np.max(np.abs(invariants(runs["natural", "reduced"], scene) - ref)) <= ANGLE_TOL
    joint = invariants(runs["joint", "reduced"], scene)
    if scene == "panda_like":
        assert np.max(np.abs(joint - ref)) <= ANGLE_TOL
    else:
        assert np.max(np.abs(joint - ref)) > 0.1  # the other minimum
    energies = [runs[c, m].potential_energy for c in COORDINATES for m in METHODS]
    assert np.ptp(energies) <= 1e-9


def test_trust_region_step_bounded_at_singular_stiffness():
    """Released where the stiffness vanishes but the force does not (a horizontal arm) the
    step follows the force to the trust-region boundary — never a minimum-norm 1e11 step."""
    step = trust_region_step(np.array([1.0, 0.0]), np.diag([0.0, 2.0]), radius=0.5)
    assert not step.newton and np.allclose(step.dz, [0.5, 0.0], atol=1e-12)
    # a neutral direction without force is left alone; Newton on the rest
    step = trust_region_step(np.array([0.0, 1.0]), np.diag([0.0, 2.0]), radius=1.0)
    assert step.newton and np.allclose(step.dz, [0.0, 0.5], atol=1e-15)
    # a saddle with no force along the downhill mode (hard case): the step leaves the saddle
    step = trust_region_step(np.array([0.0, 1.0]), np.diag([-1.0, 2.0]), radius=0.5)
    assert np.linalg.norm(step.dz) == pytest.approx(0.5, rel=1e-12) and abs(step.dz[0]) > 0.1
    assert step.predicted > 0.0


def test_classify_stability():
    assert classify_stability(np.diag([1.0, 2.0])).verdict == "stable"
    assert classify_stability(np.diag([-1.0, 2.0])).verdict == "unstable"
    assert classify_stability(np.zeros((0, 0))).verdict == "stable"
    # a 2-d null space given by an arbitrary rotation is named by its leading coordinates
    rot = np.array([[0.6, -0.8, 0.0], [0.8, 0.6, 0.0], [0.0, 0.0, 1.0]])
    k = rot @ np.diag([0.0, 0.0, 3.0]) @ rot.T
    tiny = STABILITY_RTOL * 3.0 * 0.5
    s = classify_stability(k + np.diag([tiny, 0.0, 0.0]), np.eye(3), ["pan", "wrist", "lift"])
    assert s.verdict == "neutral" and sorted(s.null_coordinates()) == ["pan", "wrist"]
    assert all(set(d["weights"]) == {d["dominant"]} for d in s.null_directions)
    assert s.tolerance == pytest.approx(STABILITY_RTOL * 3.0, rel=1e-12)
    # just above the tolerance it is stable
    assert classify_stability(np.diag([3.0, 3e-7, 1.0])).verdict == "stable"


@pytest.mark.parametrize("coordinates", COORDINATES)
@pytest.mark.parametrize("method", METHODS)
def test_cli_statics_arm(tmp_path, capsys, coordinates, method):
    """`casmbd statics` on the UR5-like scene in each coordinate choice and method: exit 0,
    no internal error, the neutral verdict with its joints in the JSON."""
    text = open(SCENES["ur_like"], encoding="utf-8").read().replace(
        "dimension = 3\n", f'dimension = 3\ncoordinates = "{coordinates}"\n', 1)
    scene = tmp_path / "ur.toml"
    scene.write_text(text, encoding="utf-8")
    assert main(["statics", str(scene), "--json", "--method", method, "--mode", "vm",
                 "--stable"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["search"] == "stable" and data["notes"] == []
    assert data["stable"] is None and data["stability"]["verdict"] == "neutral"
    assert {d["dominant"] for d in data["stability"]["null_directions"]} == \
        NULL_JOINTS["ur_like"]
    assert data["residual"] <= RTOL * 100.0


@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
def test_principal_range_only_where_equations_do_not_change(coordinates):
    """A rod pinned at the origin, no gravity, started at 7 rad (> π).  With a torsional
    spring of free angle 7 rad the equilibrium angle is 7 rad and must stay so (a wound
    spring differs from an unwound one); without the spring every angle is an equilibrium and
    the result is reduced to 7 − 2π."""
    def rod(spring: bool):
        m = casmbd.Mechanism(f"wound_{spring}_{coordinates}", gravity=(0.0, 0.0),
                             coordinates=coordinates)
        m.add_body("rod", 1.0, 1 / 12, (0.5 * np.cos(7.0), 0.5 * np.sin(7.0)), angle=7.0)
        m.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
        if spring:
            m.add_rotational_spring_damper("spring", "pivot", stiffness=3.0, free_angle=7.0)
        return m

    wound = static_equilibrium(rod(True), mode="vm")
    free = static_equilibrium(rod(False), mode="vm")
    assert wound.joint_coordinates[0] == pytest.approx(7.0, abs=1e-12)
    assert free.joint_coordinates[0] == pytest.approx(7.0 - 2 * np.pi, abs=1e-12)
    assert free.body_angles[0] == pytest.approx(7.0 - 2 * np.pi, abs=1e-12)
    if coordinates == "absolute":  # q itself: the body angle
        assert wound.q[2] == pytest.approx(7.0, abs=1e-12)
        assert free.q[2] == pytest.approx(7.0 - 2 * np.pi, abs=1e-12)
    assert wound.stability.verdict == "stable" and free.stability.verdict == "neutral"


@pytest.mark.parametrize("scene", list(SCENES))
def test_nearest_equilibrium_of_the_arms(scene):
    """The default search from the zero pose (joint coordinates, both methods): a verified
    equilibrium (the residual re-evaluated as above), the same one by both methods (to 1e-8),
    classified unstable (the stretched arms' nearest equilibria hold a link up), nearer the
    zero pose in joint space than the hanging minimum that ``stable=True`` finds, and of
    higher potential energy."""
    model = model_of(scene, "joint")
    q0 = assemble(model, model.initial_coordinates(), 0.0).q
    qe0 = model.vector("statics_forces", q0, 0.0, model.p)
    runs = [solve(scene, "joint", m, stable=False) for m in METHODS]
    hanging = solve(scene, "joint", "reduced")
    for r in runs:
        f = model.vector("statics_residual", r.q, r.lagrange_multipliers, 0.0, model.p)
        assert np.max(np.abs(f)) <= RTOL * max(1.0, np.max(np.abs(qe0)))
        assert r.search == "nearest" and r.notes == []
        assert r.stability.verdict == "unstable" and r.eigenvalues[0] < -r.stability.tolerance
        assert np.linalg.norm(r.joint_coordinates) < np.linalg.norm(hanging.joint_coordinates)
        assert r.potential_energy > hanging.potential_energy + 0.1
    assert np.max(np.abs(runs[0].joint_coordinates - runs[1].joint_coordinates)) <= ANGLE_TOL
