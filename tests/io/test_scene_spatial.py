"""Spatial scenes, results and the command line (issue 5): example scenes, JSON, npz, errors.

Every number is compared with an independent reference and a stated tolerance:

* spatial slider-crank (``examples/spatial_slider_crank.toml``): the slider travel against the
  closed form s = −d·w + √((d·w)² − |w|² + l²), w = B0 − A(φ) (1e-9 m), the crank's
  quaternion against [cos(φ/2), 0, 0, sin(φ/2)] through a full turn (sign-continuous, 1e-9),
  the driver effort against the actuator effort (1e-9 relative) and the motor's work
  ∫ τ ω dt against the change of kinetic + potential energy (Simpson, 1e-7 relative);
* spatial four-bar (``examples/spatial_four_bar.toml``): 1 degree of freedom and no redundant
  equation without its driver; the rocker angle against the closed form of
  2 ρ (d_y cos ψ + d_z sin ψ) = l² − |d|² − ρ² (1e-9 rad);
* heavy top (``examples/heavy_top.toml``): total energy, the angular momentum about the
  vertical through the tip and the spin ω·e3 conserved to 1e-8 relative over 1 s
  (rtol 1e-12, measured ≈ 5e-10); the statics reaction (0, 0, m g, 0, 0, 0) (1e-9);
* a sleeve on a cylindrical joint with a spring and a body-frame torque: z(t) =
  (m g / k)(cos √(k/m) t − 1) and the angle 2 t + (0.1 / I_z)(t − sin t) (1e-7), reported as
  ``joints[name]["coordinate"]`` and ``joints[name]["angle"]``;
* the same scenes with ``coordinates = "natural"`` give the same body positions (1e-8 m);
* JSON keys and shapes through ``python -m casmbd … --json``, npz save and reload, readable
  summaries, scene errors naming table, entry and key.
"""

from __future__ import annotations

import json
import math
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from conftest import private_cache

from casmbd import cli, info, inverse_dynamics, kinematics, results, simulate
from casmbd.errors import CasmbdError, SceneError
from casmbd.io.scene import load_scene, loads_scene
from casmbd.model.rotations import rotation_matrix

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = REPO_ROOT / "examples"
SLIDER = EXAMPLES / "spatial_slider_crank.toml"
FOUR_BAR = EXAMPLES / "spatial_four_bar.toml"
TOP = EXAMPLES / "heavy_top.toml"
PLANAR_SLIDER = EXAMPLES / "slider_crank.toml"


_cache = private_cache("cache_scene_spatial", scope="module", CASMBD_COMPILE=None)


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    status = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def run_subprocess(*argv) -> dict:
    """``python -m casmbd ARGV --json``: exit status 0, nothing on stderr, one JSON object."""
    proc = subprocess.run([sys.executable, "-m", "casmbd", *map(str, argv), "--json"],
                          cwd=REPO_ROOT, capture_output=True, text=True, timeout=300,
                          env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("\n") == 1
    return json.loads(proc.stdout)


def natural(path: pathlib.Path) -> str:
    """The scene's text with ``coordinates = "natural"`` in its [scene] table."""
    text = path.read_text(encoding="utf-8")
    text = "\n".join(line for line in text.splitlines()
                     if not line.startswith("coordinates ="))
    return text.replace("[scene]\n", '[scene]\ncoordinates = "natural"\n', 1)


# ---------------------------------------------------------------------- closed forms
def slider_travel(phi: np.ndarray, mech) -> np.ndarray:
    """Travel s(φ) of the spatial slider-crank along d from B0 (positive root)."""
    a0 = mech.joints["A"].point
    b0, d = mech.joints["slide"].point, mech.joints["slide"].axis
    r, length = float(np.linalg.norm(a0)), float(np.linalg.norm(b0 - a0))
    a = r * np.column_stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)])
    w = b0 - a
    dw = w @ d
    return -dw + np.sqrt(dw**2 - np.einsum("ij,ij->i", w, w) + length**2)


def rocker_angles(phi: np.ndarray, mech) -> np.ndarray:
    """Both roots ψ of the spatial four-bar's loop equation, shape (n, 2)."""
    a0, b0 = mech.joints["A"].point, mech.joints["B"].point
    o2 = mech.joints["rocker_bearing"].point
    rho, length = float(np.linalg.norm(b0 - o2)), float(np.linalg.norm(b0 - a0))
    a = float(np.linalg.norm(a0)) * np.column_stack([np.cos(phi), np.sin(phi),
                                                     np.zeros_like(phi)])
    d = o2 - a
    # arm (0, ρ cos ψ, ρ sin ψ) about +x from its design direction +y
    ca_, cb = 2 * rho * d[:, 1], 2 * rho * d[:, 2]
    cc = length**2 - np.einsum("ij,ij->i", d, d) - rho**2
    base, half = np.arctan2(cb, ca_), np.arccos(cc / np.hypot(ca_, cb))
    return np.column_stack([base + half, base - half])


def wrap(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def simpson(y: np.ndarray, h: float) -> float:
    assert (len(y) - 1) % 2 == 0
    return h / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())


# ---------------------------------------------------------------------- slider-crank
@pytest.fixture(scope="module")
def slider_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("spatial_npz") / "slider.npz"
    data = run_subprocess("kinematics", SLIDER, "--t-end", "1", "--steps", "40", "--out", out)
    return data, out


def test_slider_crank_json_keys_and_shapes(slider_run):
    data, _ = slider_run
    n = 41
    assert len(data["t"]) == n
    assert set(data["bodies"]) == {"crank", "rod", "slider"}
    for body in data["bodies"].values():
        assert set(body) == {"position", "quaternion", "velocity", "angular_velocity"}
        assert np.shape(body["position"]) == (n, 3)
        assert np.shape(body["quaternion"]) == (n, 4)
        assert np.shape(body["velocity"]) == (n, 3)
        assert np.shape(body["angular_velocity"]) == (n, 3)
        assert np.allclose(np.linalg.norm(body["quaternion"], axis=1), 1.0, atol=1e-12)
    assert set(data["joints"]) == {"O", "A", "B", "slide"}
    assert data["joints"]["A"] == {} and data["joints"]["B"] == {}  # no joint coordinate
    assert np.shape(data["joints"]["slide"]["coordinate"]) == (n,)
    assert np.shape(data["markers"]["crank_pin"]["position"]) == (n, 3)
    assert data["constraint_violation"] < 1e-10


def test_slider_crank_matches_closed_form(slider_run):
    data, _ = slider_run
    mech = load_scene(SLIDER)
    t = np.array(data["t"])
    phi = 2 * math.pi * t
    s = slider_travel(phi, mech)
    b0, d = mech.joints["slide"].point, mech.joints["slide"].axis
    np.testing.assert_allclose(data["joints"]["slide"]["coordinate"], s, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data["bodies"]["slider"]["position"], b0 + s[:, None] * d,
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose(wrap(np.array(data["joints"]["O"]["coordinate"]) - phi), 0.0,
                               atol=1e-10)
    # crank: rotation φ about z, quaternion sign-continuous through the full turn (ends at −1)
    quat = np.array(data["bodies"]["crank"]["quaternion"])
    expected = np.column_stack([np.cos(phi / 2), 0 * t, 0 * t, np.sin(phi / 2)])
    np.testing.assert_allclose(quat, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data["bodies"]["crank"]["angular_velocity"],
                               np.tile([0.0, 0.0, 2 * math.pi], (len(t), 1)), atol=1e-9)
    pin = r_pin = 0.1 * np.column_stack([np.cos(phi), np.sin(phi), 0 * t])
    np.testing.assert_allclose(data["markers"]["crank_pin"]["position"], pin, atol=1e-12)
    # the connecting rod keeps its length between the crank pin and the slider point
    rod = load_scene(SLIDER).joints
    length = np.linalg.norm(rod["B"].point - rod["A"].point)
    np.testing.assert_allclose(np.linalg.norm(b0 + s[:, None] * d - r_pin, axis=1), length,
                               atol=1e-12)


def test_spatial_npz_reloads(slider_run):
    data, out = slider_run
    res = results.load(out)
    assert res.dimension == 3 and res.kind == "kinematics"
    rod = res.body("rod")
    n = len(res.t)
    assert rod["position"].shape == (n, 3) and rod["quaternion"].shape == (n, 4)
    assert rod["rotation"].shape == (n, 3, 3) and rod["angular_velocity"].shape == (n, 3)
    assert rod["angular_acceleration"].shape == (n, 3)
    np.testing.assert_array_equal(rod["position"], np.array(data["bodies"]["rod"]["position"]))
    # the quaternion is the rotation matrix's own
    for k in (0, n // 3, n - 1):
        np.testing.assert_allclose(rotation_matrix(rod["quaternion"][k]), rod["rotation"][k],
                                   atol=1e-12)
    assert res.marker("crank_pin")["position"].shape == (n, 3)
    again = res.to_json()
    for key in ("t", "bodies", "joints", "markers", "constraint_violation"):
        assert again[key] == data[key]
    assert "spatial_slider_crank" in res.scene


@pytest.fixture(scope="module")
def slider_inverse():
    return inverse_dynamics(load_scene(SLIDER), t_end=0.3, steps=60)


def test_slider_crank_inverse_efforts_and_work(slider_inverse):
    """The motor (actuator) on the driven crank needs the driver's torque, and its work
    ∫ τ ω dt equals the change of kinetic + potential energy (no other source of work)."""
    res = slider_inverse
    tau = res["driver_efforts"][:, 0]
    np.testing.assert_allclose(res["actuator_efforts"][:, 0], tau, rtol=1e-9,
                               atol=1e-9 * np.max(np.abs(tau)))
    energy = res["total_energy"]
    work = simpson(tau * 2 * math.pi, float(res.t[1] - res.t[0]))
    change = energy[-1] - energy[0]
    assert abs(change) > 1e-2  # a non-trivial balance
    assert abs(work - change) <= 1e-7 * max(np.max(np.abs(energy - energy[0])), 1e-3)
    assert res["joint_reactions"].shape == (len(res.t), 4, 6)


@pytest.mark.parametrize("analysis", ["inverse", "simulate", "simulate_absolute"])
def test_slider_crank_reactions_satisfy_newton_euler(analysis, slider_inverse):
    """Every body of the spatial slider-crank obeys Newton–Euler with the reported 6-component
    reactions (action of body1 on body2 at the joint point, which moves with body2), gravity
    and the motor torque τ ẑ on the crank: m a_G = Σ ±F, Ḣ_G = Σ ±(M + (r_P − r_G) × F) + τ,
    at every time (1e-9 relative).  τ is the actuator's effort in inverse dynamics (the
    actuator produces the motion) and the driver's effort in a simulation, in the automatic
    choice of coordinates (joint) and in absolute coordinates.  The spherical joint carries
    no moment: 1e-12 of the largest reaction in absolute coordinates, 1e-10 in joint
    coordinates (its moment there is a difference of the recursion's terms, rounding
    ≈ 3e-11 measured).  Regression: reactions of several joints were scrambled across joints
    and times."""
    mech = load_scene(SLIDER)
    if analysis == "simulate_absolute":
        mech.coordinates = "absolute"
    if analysis == "inverse":
        res = slider_inverse
        torque = res["actuator_efforts"][:, 0]
    else:
        res = simulate(mech, t_end=0.3, steps=12, rtol=1e-10)
        torque = res["driver_efforts"][:, 0] + res["actuator_inputs"][:, 0]
    from casmbd.model.values import numeric

    n_t = len(res.t)
    reac = res["joint_reactions"]
    scale = float(np.max(np.abs(reac)))
    gravity = np.array([0.0, 0.0, -9.81])
    state = {name: res.body(name) for name in mech.bodies}

    def joint_point(joint) -> np.ndarray:
        body = mech.bodies[joint.body2]
        local = body.initial_rotation.T @ (joint.point - body.position)
        b = state[joint.body2]
        return b["position"] + np.einsum("nij,j->ni", b["rotation"], local)

    for name, body in mech.bodies.items():
        b = state[name]
        mass = numeric(body.mass, mech.parameters, "mass")
        values = [numeric(v, mech.parameters, "inertia") for v in body.inertia]
        ixx, iyy, izz, ixy, ixz, iyz = values + [0.0] * (6 - len(values))
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        force = np.tile(mass * gravity, (n_t, 1))
        moment = np.zeros((n_t, 3))
        for k, joint in enumerate(mech.joints.values()):
            sign = 1.0 if joint.body2 == name else -1.0 if joint.body1 == name else 0.0
            if sign:
                arm = joint_point(joint) - b["position"]
                force += sign * reac[:, k, :3]
                moment += sign * (reac[:, k, 3:] + np.cross(arm, reac[:, k, :3]))
        if name == "crank":
            moment[:, 2] += torque
        tensor = np.einsum("nij,jk,nlk->nil", b["rotation"], inertia, b["rotation"])
        omega, alpha = b["angular_velocity"], b["angular_acceleration"]
        h_dot = (np.einsum("nij,nj->ni", tensor, alpha)
                 + np.cross(omega, np.einsum("nij,nj->ni", tensor, omega)))
        np.testing.assert_allclose(force, mass * b["acceleration"], rtol=0,
                                   atol=1e-9 * scale, err_msg=name)
        np.testing.assert_allclose(moment, h_dot, rtol=0, atol=1e-9 * scale, err_msg=name)
    # the crank bearing carries bending moments, the spherical joint none
    assert np.max(np.abs(reac[:, 0, 3:5])) > 1e-3
    spherical = 1e-12 if res.stats.get("coordinates", "absolute") == "absolute" else 1e-10
    np.testing.assert_allclose(reac[:, 1, 3:], 0.0, atol=spherical * scale)


def test_inverse_cli_json_and_summary(capsys):
    status, out, err = run_cli(capsys, "inverse", SLIDER, "--t-end", "0.5", "--steps", "5",
                               "--json")
    assert status == 0, err
    data = json.loads(out)
    assert np.shape(data["joints"]["A"]["reaction"]) == (6, 6)  # [Fx, Fy, Fz, Mx, My, Mz]
    np.testing.assert_allclose(data["actuators"]["motor"]["effort"],
                               data["drivers"]["crank_speed"]["effort"], atol=1e-9)
    # a spherical joint transmits no moment
    np.testing.assert_allclose(np.array(data["joints"]["A"]["reaction"])[:, 3:], 0.0,
                               atol=1e-9)
    status, out, err = run_cli(capsys, "inverse", SLIDER, "--t-end", "0.5", "--steps", "5")
    assert status == 0, err
    assert "final quaternion" in out and "actuator motor" in out and "z [" in out


# ---------------------------------------------------------------------- four-bar
@pytest.fixture(scope="module")
def four_bar_kinematics():
    return {coords: kinematics(loads_scene(FOUR_BAR.read_text(encoding="utf-8")
                                           if coords == "absolute" else natural(FOUR_BAR),
                                           source=str(FOUR_BAR)),
                               t_end=1.0, steps=40)
            for coords in ("absolute", "natural")}


def test_four_bar_info_one_dof_without_driver(capsys, tmp_path):
    text = FOUR_BAR.read_text(encoding="utf-8")
    free = tmp_path / "free_four_bar.toml"
    text = text[:text.index("[[drivers]]")]
    free.write_text(text, encoding="utf-8")
    status, out, err = run_cli(capsys, "info", free, "--json")
    assert status == 0, err
    data = json.loads(out)  # the automatic choice: joint coordinates, one loop joint
    assert data["coordinate_choice"] == "joint" and data["degrees_of_freedom"] == 1
    assert data["coordinate_reason"].startswith("1 loop joint (B) with 4 equations")
    free.write_text(text.replace("[scene]", '[scene]\ncoordinates = "absolute"', 1),
                    encoding="utf-8")
    status, out, err = run_cli(capsys, "info", free, "--json")
    assert status == 0, err
    data = json.loads(out)
    assert data["dimension"] == 3 and data["coordinate_choice"] == "absolute"
    assert data["coordinate_reason"] == "given"
    assert data["degrees_of_freedom"] == 1 and data["rank"] == 20
    assert data["redundant_equations"] == []
    body_rows = [c for c in data["constraints"] if c["kind"] == "body"]
    assert len(body_rows) == 3 and {c["joint"] for c in body_rows} == {"crank", "coupler",
                                                                       "rocker"}
    assert {"kind": "joint", "joint": "B", "equation": "cross"} in data["constraints"]
    status, out, _ = run_cli(capsys, "info", FOUR_BAR)
    assert status == 0 and "spatial" in out and "degrees of freedom: 0" in out


def test_four_bar_natural_info(tmp_path):
    data = info(loads_scene(natural(FOUR_BAR)))
    assert data["degrees_of_freedom"] == 0 and data["redundant_equations"] == []
    assert sum(c["kind"] == "body" for c in data["constraints"]) == 18  # 6 per body
    assert data["n_coordinates"] == 36


def test_four_bar_rocker_closed_form(four_bar_kinematics):
    res = four_bar_kinematics["absolute"]
    mech = load_scene(FOUR_BAR)
    phi = 2 * math.pi * res.t
    roots = rocker_angles(phi, mech)
    branch = int(np.argmin(np.abs(wrap(roots[0]))))  # the assembled branch: ψ(0) = 0
    psi = res.joint("rocker_bearing")["coordinate"]
    assert np.ptp(psi) > 0.5  # the rocker really swings
    np.testing.assert_allclose(wrap(psi - roots[:, branch]), 0.0, atol=1e-9)


@pytest.mark.parametrize("scene", ["four_bar", "planar_slider_crank"])
def test_natural_coordinates_give_the_same_positions(scene, four_bar_kinematics):
    if scene == "four_bar":
        runs = four_bar_kinematics
    else:
        runs = {"absolute": kinematics(load_scene(PLANAR_SLIDER), t_end=1.0, steps=20),
                "natural": kinematics(loads_scene(natural(PLANAR_SLIDER)), t_end=1.0,
                                      steps=20)}
        assert runs["natural"]["q"].shape[1] == 12  # x, y, ux, uy per body
    a, b = runs["absolute"], runs["natural"]
    assert a["q"].shape[1] != b["q"].shape[1]
    np.testing.assert_allclose(b["body_positions"], a["body_positions"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(b["marker_positions"], a["marker_positions"], rtol=0,
                               atol=1e-8)
    if a.dimension == 3:
        for name in a.names["bodies"]:
            np.testing.assert_allclose(b.body(name)["quaternion"], a.body(name)["quaternion"],
                                       atol=1e-8)


# ---------------------------------------------------------------------- heavy top
def top_invariants(data: dict, mech) -> dict[str, np.ndarray]:
    """Energy, vertical angular momentum about the tip and spin, from the JSON arrays."""
    body = data["bodies"]["top"]
    rot = np.array([rotation_matrix(q) for q in body["quaternion"]])
    omega, x, v = (np.array(body[k]) for k in ("angular_velocity", "position", "velocity"))
    inertia = np.diag([mech.parameters[k] for k in ("I1", "I1", "I3")])
    h_g = np.einsum("nij,jk,nlk,nl->ni", rot, inertia, rot, omega)
    h_o = h_g + mech.parameters["m"] * np.cross(x, v)
    return {"energy": np.array(data["energy"]["total"]), "momentum_z": h_o[:, 2],
            "spin": np.einsum("ni,ni->n", omega, rot[:, :, 2])}


def test_heavy_top_conserves_energy_momentum_and_spin():
    data = run_subprocess("simulate", TOP, "--t-end", "1", "--steps", "50", "--rtol", "1e-12")
    mech = load_scene(TOP)
    assert np.shape(data["bodies"]["top"]["quaternion"]) == (51, 4)
    assert np.shape(data["joints"]["tip"]["reaction"]) == (51, 6)
    inv = top_invariants(data, mech)
    assert abs(inv["spin"][0] - 100.0) < 1e-9  # the scene's spin
    # 3e-8 of each invariant at rtol 1e-12: measured 1.8e-8 for the energy with the converged
    # augmented Lagrangian (10 corrections, default since issue 22 item 2; 5-8 corrections
    # give 1.7-1.9e-8, kkt_ode 2.5e-9; the former 4 re-factorising solves happened to give
    # 1.5e-9), momentum and spin below
    for key, values in inv.items():
        assert np.ptp(values) <= 3e-8 * abs(values[0]), (key, np.ptp(values) / abs(values[0]))
    # the top precesses: its centre of mass moves by centimetres
    pos = np.array(data["bodies"]["top"]["position"])
    assert np.ptp(pos[:, 0]) > 1e-2


def test_heavy_top_euler_angles_equal_quaternion():
    text = TOP.read_text(encoding="utf-8")
    euler = text.replace('orientation = ["cos(th0 / 2)", "sin(th0 / 2)", 0.0, 0.0]',
                         'euler_zxz = [0.0, "th0", 0.0]')
    assert euler != text
    a, b = load_scene(TOP).bodies["top"], loads_scene(euler).bodies["top"]
    np.testing.assert_allclose(b.orientation, a.orientation, atol=1e-15)


def test_heavy_top_statics_cli(capsys):
    status, out, err = run_cli(capsys, "statics", TOP, "--json", "--stable")
    assert status == 0, err
    data = json.loads(out)
    mech = load_scene(TOP)
    m, g = mech.parameters["m"], 9.81
    np.testing.assert_allclose(data["joints"]["tip"]["reaction"], [0, 0, m * g, 0, 0, 0],
                               atol=1e-9)
    assert len(data["bodies"]["top"]["quaternion"]) == 4
    # released tilted, the statics asked for a stable equilibrium descends to the hanging top
    # (centre of mass L = 0.1 m below the tip): a minimum, neutral only in the spin about the
    # vertical
    np.testing.assert_allclose(data["bodies"]["top"]["position"], [0, 0, -0.1], atol=1e-12)
    assert data["stable"] is None and data["stability"]["verdict"] == "neutral"
    assert data["search"] == "stable"
    assert len(data["stability"]["null_directions"]) == 1
    assert min(data["eigenvalues"]) >= -data["stability"]["tolerance"]
    # by default the nearest equilibrium: released 0.3 rad from upright, the upright top
    # (centre of mass L above the tip), unstable in both tilts
    status, out, err = run_cli(capsys, "statics", TOP, "--json")
    assert status == 0, err
    data = json.loads(out)
    np.testing.assert_allclose(data["bodies"]["top"]["position"], [0, 0, 0.1], atol=1e-12)
    np.testing.assert_allclose(data["joints"]["tip"]["reaction"], [0, 0, m * g, 0, 0, 0],
                               atol=1e-9)
    assert data["search"] == "nearest" and data["stability"]["verdict"] == "unstable"
    assert sum(e < -data["stability"]["tolerance"] for e in data["eigenvalues"]) == 2
    status, out, err = run_cli(capsys, "statics", TOP)
    assert status == 0, err
    assert "quaternion [" in out and "Mz" in out


def test_spatial_summaries_do_not_crash(capsys):
    for argv in (["simulate", TOP, "--t-end", "0.1", "--steps", "2"],
                 ["kinematics", FOUR_BAR, "--t-end", "0.5", "--steps", "2"],
                 ["info", TOP]):
        status, out, err = run_cli(capsys, *argv)
        assert status == 0, err
        assert "top" in out or "rocker" in out
    status, out, _ = run_cli(capsys, "simulate", TOP, "--t-end", "0.1", "--steps", "2")
    assert "final quaternion" in out and "z [" in out


# ---------------------------------------------------------------------- cylindrical joint
CYLINDER = """\
[scene]
name = "sleeve_on_rod"
dimension = 3
gravity = [0.0, 0.0, -9.81]
coordinates = "{coordinates}"

[[bodies]]
name = "sleeve"
mass = 1.0
inertia = [0.01, 0.01, 0.02]
position = [0.0, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 2.0]

[[joints]]
name = "cyl"
type = "cylindrical"
body1 = "ground"
body2 = "sleeve"
point = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]

[[forces]]
name = "spring"
type = "spring_damper"
body1 = "ground"
body2 = "sleeve"
point1 = [0.0, 0.0, 1.0]
point2 = [0.0, 0.0, 0.0]
stiffness = 100.0
free_length = 1.0

[[forces]]
name = "twist"
type = "torque"
body = "sleeve"
value = [0.0, 0.0, "0.1 * sin(t)"]
frame = "body"

[[actuators]]
name = "turn"
joint = "cyl"
coordinate = "angle"
"""


@pytest.mark.parametrize("coordinates", ["absolute", "natural"])
def test_cylindrical_joint_coordinates_in_json(coordinates, tmp_path, capsys):
    scene = tmp_path / "sleeve.toml"
    scene.write_text(CYLINDER.format(coordinates=coordinates), encoding="utf-8")
    status, out, err = run_cli(capsys, "simulate", scene, "--t-end", "1", "--steps", "20",
                               "--rtol", "1e-11", "--json")
    assert status == 0, err
    data = json.loads(out)
    t = np.array(data["t"])
    joint = data["joints"]["cyl"]
    assert set(joint) == {"coordinate", "velocity", "angle", "angle_velocity", "reaction"}
    z = 9.81 / 100.0 * (np.cos(10.0 * t) - 1.0)
    np.testing.assert_allclose(joint["coordinate"], z, atol=1e-7)
    np.testing.assert_allclose(np.array(data["bodies"]["sleeve"]["position"])[:, 2], z,
                               atol=1e-7)
    angle = 2.0 * t + 0.1 / 0.02 * (t - np.sin(t))
    np.testing.assert_allclose(wrap(np.array(joint["angle"]) - angle), 0.0, atol=1e-7)
    np.testing.assert_allclose(joint["angle_velocity"], 2.0 + 5.0 * (1 - np.cos(t)),
                               atol=1e-6)
    assert data["actuators"]["turn"]["input"] == [0.0] * len(t)


def test_cylindrical_drivers_and_result_accessors():
    """Both coordinates of a cylindrical joint driven: z = 0.1 sin t, angle = 3 t; the body's
    quaternion is [cos(3t/2), 0, 0, sin(3t/2)]."""
    text = CYLINDER.format(coordinates="absolute") + """
[[drivers]]
name = "lift"
joint = "cyl"
coordinate = "translation"
position = "0.1 * sin(t)"

[[drivers]]
name = "spin"
joint = "cyl"
coordinate = "angle"
position = "3 * t"
"""
    res = kinematics(loads_scene(text), t_end=1.0, steps=10)
    t = res.t
    j = res.joint("cyl")
    np.testing.assert_allclose(j["coordinate"], 0.1 * np.sin(t), atol=1e-12)
    np.testing.assert_allclose(j["angle"], 3 * t, atol=1e-12)
    np.testing.assert_allclose(j["angle_velocity"], 3.0, atol=1e-10)
    np.testing.assert_allclose(res.joint("cyl.angle")["coordinate"], 3 * t, atol=1e-12)
    body = res.body("sleeve")
    np.testing.assert_allclose(body["quaternion"], np.column_stack(
        [np.cos(1.5 * t), 0 * t, 0 * t, np.sin(1.5 * t)]), atol=1e-12)
    np.testing.assert_allclose(body["acceleration"][:, 2], -0.1 * np.sin(t), atol=1e-10)
    data = res.to_json()
    assert set(data["joints"]["cyl"]) == {"coordinate", "velocity", "angle", "angle_velocity"}


# ---------------------------------------------------------------------- scene errors
PENDULUM = """\
[scene]
name = "spatial_pendulum"
dimension = 3
gravity = [0.0, 0.0, -9.81]

[[bodies]]
name = "rod"
mass = 1.0
inertia = [0.1, 0.1, 0.01]
position = [0.0, 0.0, -0.5]

[[joints]]
name = "hinge"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0, 0.0]
axis = [1.0, 0.0, 0.0]
"""
BODY = PENDULUM[PENDULUM.index("[[bodies]]"):PENDULUM.index("[[joints]]")]
HINGE = PENDULUM[PENDULUM.index("[[joints]]"):]
ARM = BODY.replace('"rod"', '"arm"').replace("-0.5]", "-1.5]")
UNIVERSAL = HINGE.replace('"hinge"', '"cross"').replace('"revolute"', '"universal"').replace(
    '"ground"', '"rod"').replace('"rod"\npoint', '"arm"\npoint').replace(
    "[0.0, 0.0, 0.0]\naxis = [1.0, 0.0, 0.0]", "[0.0, 0.0, -1.0]\n{axes}")


def _replace(old: str, new: str, text: str = PENDULUM) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


ERRORS = {
    "position-2": (_replace("position = [0.0, 0.0, -0.5]", "position = [0.0, -0.5]"),
                   ["[[bodies]] entry 1 ('rod')", "'position'", "3"]),
    "inertia-4": (_replace("[0.1, 0.1, 0.01]", "[0.1, 0.1, 0.01, 0.0]"),
                  ["[[bodies]] entry 1 ('rod')", "'inertia'", "3 or 6"]),
    "inertia-negative": (_replace("[0.1, 0.1, 0.01]", "[0.1, -0.1, 0.01]"),
                         ["('rod')", "'inertia'", ">= 0"]),
    "inertia-not-definite": (_replace("[0.1, 0.1, 0.01]", "[0.1, 0.1, 0.01, 0.5, 0, 0]"),
                             ["('rod')", "'inertia'"]),
    "orientation-3": (_replace("position = [0.0, 0.0, -0.5]",
                               "position = [0.0, 0.0, -0.5]\norientation = [1.0, 0.0, 0.0]"),
                      ["('rod')", "'orientation'", "4"]),
    "orientation-not-unit": (_replace("position = [0.0, 0.0, -0.5]",
                                      "position = [0.0, 0.0, -0.5]\n"
                                      "orientation = [2.0, 0.0, 0.0, 0.0]"),
                             ["('rod')", "'orientation'", "unit quaternion"]),
    "orientation-and-euler": (_replace("position = [0.0, 0.0, -0.5]",
                                       "position = [0.0, 0.0, -0.5]\n"
                                       "orientation = [1.0, 0.0, 0.0, 0.0]\n"
                                       "euler_zxz = [0.0, 0.0, 0.0]"),
                              ["('rod')", "'orientation'", "euler_zxz"]),
    "angle-in-space": (_replace("position = [0.0, 0.0, -0.5]",
                                "position = [0.0, 0.0, -0.5]\nangle = 0.3"),
                       ["('rod')", "'angle'", "orientation"]),
    "angular-velocity-scalar": (_replace("position = [0.0, 0.0, -0.5]",
                                         "position = [0.0, 0.0, -0.5]\nangular_velocity = 1.0"),
                                ["('rod')", "'angular_velocity'", "3"]),
    "missing-axis": (_replace("axis = [1.0, 0.0, 0.0]\n", ""),
                     ["[[joints]] entry 1 ('hinge')", "'axis'", "missing"]),
    "axis-2": (_replace("axis = [1.0, 0.0, 0.0]", "axis = [1.0, 0.0]"),
               ["[[joints]] entry 1 ('hinge')", "'axis'", "3"]),
    "unknown-joint-type": (_replace('"revolute"', '"ball"'),
                           ["[[joints]] entry 1 ('hinge')", "'type'", "ball", "spherical"]),
    "bad-coordinates": (_replace("dimension = 3", 'dimension = 3\ncoordinates = "cartesian"'),
                        ["[scene]", "'coordinates'", "cartesian", "natural"]),
    "dimension-4": (_replace("dimension = 3", "dimension = 4"), ["[scene]", "'dimension'", "4"]),
    "gravity-2": (_replace("[0.0, 0.0, -9.81]", "[0.0, -9.81]"),
                  ["[scene]", "'gravity'", "3"]),
    "universal-no-axes": (PENDULUM + ARM + UNIVERSAL.format(axes=""),
                          ["[[joints]] entry 2 ('cross')", "'axes'", "missing"]),
    "universal-one-axis": (PENDULUM + ARM + UNIVERSAL.format(axes="axes = [[1.0, 0.0, 0.0]]"),
                           ["[[joints]] entry 2 ('cross')", "'axes'", "2 lists of 3"]),
    "universal-axis1-only": (PENDULUM + ARM + UNIVERSAL.format(axes="axis1 = [1.0, 0.0, 0.0]"),
                             ["('cross')", "'axis2'", "missing"]),
    "universal-both-forms": (PENDULUM + ARM + UNIVERSAL.format(
        axes="axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]\naxis1 = [1.0, 0.0, 0.0]"),
        ["('cross')", "'axis1'", "not both"]),
    "universal-not-perpendicular": (PENDULUM + ARM + UNIVERSAL.format(
        axes="axes = [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]"),
        ["[[joints]] entry 2 ('cross')", "perpendicular"]),
    "torque-scalar": (PENDULUM + '[[forces]]\nname = "motor"\ntype = "torque"\nbody = "rod"\n'
                      "value = 1.0\n", ["[[forces]] entry 1 ('motor')", "'value'", "3"]),
    "force-2": (PENDULUM + '[[forces]]\nname = "push"\ntype = "force"\nbody = "rod"\n'
                "value = [1.0, 0.0]\n", ["[[forces]] entry 1 ('push')", "'value'", "3"]),
    "driver-angle-of-body": (PENDULUM + '[[drivers]]\nname = "d"\nbody = "rod"\n'
                             'coordinate = "angle"\nposition = "t"\n',
                             ["[[drivers]] entry 1 ('d')", "'coordinate'", "x, y, z"]),
    "driver-bad-joint-coordinate": (PENDULUM + '[[drivers]]\nname = "d"\njoint = "hinge"\n'
                                    'coordinate = "translation"\nposition = "t"\n',
                                    ["[[drivers]] entry 1 ('d')", "'coordinate'", "angle"]),
    "actuator-bad-coordinate": (PENDULUM + '[[actuators]]\nname = "u"\njoint = "hinge"\n'
                                'coordinate = "spin"\n',
                                ["[[actuators]] entry 1 ('u')", "'coordinate'", "spin"]),
}
PLANAR = """\
[scene]
name = "planar_pendulum"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.1
position = [0.5, 0.0]

[[joints]]
name = "pin"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
"""
ERRORS.update({
    "planar-spherical": (_replace('"revolute"', '"spherical"', PLANAR),
                         ["[[joints]] entry 1 ('pin')", "'type'", "dimension = 3"]),
    "planar-axis": (_replace("point = [0.0, 0.0]\n", "point = [0.0, 0.0]\naxis = [0, 0, 1]\n",
                             PLANAR), ["[[joints]] entry 1 ('pin')", "'axis'"]),
    "planar-orientation": (_replace("position = [0.5, 0.0]",
                                    "position = [0.5, 0.0]\norientation = [1, 0, 0, 0]", PLANAR),
                           ["[[bodies]] entry 1 ('rod')", "'orientation'", "angle"]),
    "planar-gravity-3": (_replace("[0.0, -9.81]", "[0.0, -9.81, 0.0]", PLANAR),
                         ["[scene]", "'gravity'", "dimension"]),
    "planar-bad-coordinates": (_replace("dimension = 2", 'dimension = 2\ncoordinates = "relative"',
                                        PLANAR), ["[scene]", "'coordinates'", "'relative'"]),
})


@pytest.mark.parametrize("case", list(ERRORS), ids=list(ERRORS))
def test_scene_errors_name_table_entry_and_key(case):
    text, fragments = ERRORS[case]
    with pytest.raises(SceneError) as excinfo:
        loads_scene(text)
    message = str(excinfo.value)
    assert isinstance(excinfo.value, CasmbdError)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def test_error_scenes_are_otherwise_valid():
    """The base scenes of the error cases load (so each case fails for its own key)."""
    for text in (PENDULUM, PLANAR, PENDULUM + ARM + UNIVERSAL.format(
            axes="axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]")):
        mech = loads_scene(text)
        assert mech.bodies
    mech = loads_scene(_replace("dimension = 3", 'dimension = 3\ncoordinates = "natural"'))
    assert mech.coordinates == "natural" and mech.dimension == 3


def test_scene_error_through_cli(capsys, tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(ERRORS["missing-axis"][0], encoding="utf-8")
    status, out, err = run_cli(capsys, "info", scene, "--json")
    assert status == 1 and out == ""
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert "('hinge')" in lines[0] and "'axis'" in lines[0]


def test_simulate_python_api_result_shapes():
    """Result.body / marker / joint of a simulation in space (reactions, energy)."""
    res = simulate(load_scene(TOP), t_end=0.05, steps=5, rtol=1e-10)
    top = res.body("top")
    assert top["position"].shape == (6, 3) and top["quaternion"].shape == (6, 4)
    assert top["angular_velocity"].shape == (6, 3) and top["rotation"].shape == (6, 3, 3)
    assert res.marker("crown")["position"].shape == (6, 3)
    # the crown marker is on the symmetry axis at twice the centre of mass distance
    np.testing.assert_allclose(res.marker("crown")["position"], 2 * top["position"],
                               atol=1e-9)
    assert res["joint_reactions"].shape == (6, 1, 6)
