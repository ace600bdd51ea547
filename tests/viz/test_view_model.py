"""The data of the 3-D view (issue 32, item 1): casmbd.viz.view_model.

Poses against the results they come from (positions equal, quaternions rotating like the
stored rotation matrices, to 1e-12), shapes against the quantities they are derived from
(the equivalent-inertia box's principal moments, rel 1e-12), URDF visuals against an
independent forward kinematics of the URDF text (a mesh vertex lands where the link frame and
the visual's <origin> put it, 1e-12), flexible nodes against casmbd.viz.geometry, and the
sources: a mechanism (its assembled initial pose), results of each analysis, an OCP
solution (closed-form double-pendulum positions) and its file.  No browser, no viser.
"""

from __future__ import annotations

import math
import pathlib
import warnings

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.errors import AnalysisError
from casmbd.io.scene import load_scene
from casmbd.io.urdf import resolve_mesh
from casmbd.ocp.solution import OcpSolution
from casmbd.viz.geometry import deformed_nodes
from casmbd.viz.meshes import load_mesh
from casmbd.viz.view_model import (
    Shape,
    ViewModel,
    quaternions_from_rotations,
    view_model,
)

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
ARM = ROOT / "tests" / "robots" / "mesh_arm" / "mesh_arm.urdf"

_cache = private_cache("view_model", scope="module", CASMBD_COMPILE="0")


def rotation(wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of unit quaternions (n, 4) (seed 001, eq. 15)."""
    w, x, y, z = np.asarray(wxyz, float).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)],
        -2)


def rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def check_quaternions(vm: ViewModel) -> None:
    """Unit to 1e-14 and no sign flip between consecutive samples (q_k · q_(k-1) > 0)."""
    for name, q in vm.body_wxyz.items():
        assert q.shape == (len(vm.times), 4), name
        assert np.max(np.abs(np.linalg.norm(q, axis=1) - 1.0)) < 1e-14, name
        if len(q) > 1:
            assert np.min(np.einsum("ki,ki->k", q[1:], q[:-1])) > 0.0, name


@pytest.fixture(scope="module")
def pendulum():
    mech = load_scene(EXAMPLES / "double_pendulum.toml")
    return mech, casmbd.simulate(mech, t_end=2.0, steps=200).attach_scene(mech)


@pytest.fixture(scope="module")
def top():
    mech = load_scene(EXAMPLES / "heavy_top.toml")
    return mech, casmbd.simulate(mech, t_end=1.0, steps=200).attach_scene(mech)


# ---------------------------------------------------------------- poses
def test_planar_poses_are_the_results_in_the_plane_z_0(pendulum):
    """x, y of every body equal the result's body_positions exactly (1e-12), z = 0; the
    quaternions rotate about z by the stored angle: R(q) = [[cos θ, −sin θ, 0], …] to 1e-12."""
    mech, res = pendulum
    vm = view_model(res)
    assert vm.planar and np.array_equal(vm.times, res.t)
    assert list(vm.body_positions) == list(mech.bodies)
    check_quaternions(vm)
    for name in mech.bodies:
        body = res.body(name)
        assert np.max(np.abs(vm.body_positions[name][:, :2] - body["position"])) < 1e-12
        assert np.all(vm.body_positions[name][:, 2] == 0.0)
        c, s = np.cos(body["angle"]), np.sin(body["angle"])
        expected = np.zeros((len(c), 3, 3))
        expected[:, 0, 0], expected[:, 0, 1], expected[:, 1, 0], expected[:, 1, 1] = c, -s, s, c
        expected[:, 2, 2] = 1.0
        assert np.max(np.abs(rotation(vm.body_wxyz[name]) - expected)) < 1e-12
    assert vm.traces and all(np.all(tr[:, 2] == 0.0) for tr in vm.traces.values())
    tip = next(iter(vm.traces))
    assert np.max(np.abs(vm.traces[tip][:, :2] - res.marker(tip)["position"])) < 1e-12


def test_spatial_poses_rotate_like_the_results_matrices(top):
    """The heavy top spins through many turns: positions equal the result's (1e-12), the
    quaternions are unit, never flip sign between outputs, and R(q) is the stored rotation
    matrix A: its orthogonal polar factor to 1e-12 (scipy.linalg.polar; the integrator keeps
    |p| = 1 of the Euler parameters only to its tolerance, so A itself is a rotation to
    max |AᵀA − I| ≈ 1e-7, and R(q) is that close to A)."""
    from scipy.linalg import polar

    mech, res = top
    vm = view_model(res)
    assert not vm.planar
    check_quaternions(vm)
    for name in mech.bodies:
        body = res.body(name)
        assert np.max(np.abs(vm.body_positions[name] - body["position"])) < 1e-12
        stored = body["rotation"]
        nearest = np.array([polar(a)[0] for a in stored])
        assert np.max(np.abs(rotation(vm.body_wxyz[name]) - nearest)) < 1e-12
        defect = np.max(np.abs(np.einsum("kji,kjl->kil", stored, stored) - np.eye(3)))
        assert np.max(np.abs(rotation(vm.body_wxyz[name]) - stored)) <= defect + 1e-14
    spin = np.unwrap(2 * np.arctan2(vm.body_wxyz["top"][:, 3], vm.body_wxyz["top"][:, 0]))
    assert abs(spin[-1] - spin[0]) > 4 * math.pi  # it did turn: the sign test had work to do


def test_quaternions_of_a_turning_body_are_continuous_where_shepperd_switches_cases():
    """A body turning 3 times about a tilted axis: Shepperd's largest-component case changes
    along the way; the quaternions stay sign-continuous and give back the matrices (1e-15)."""
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    angles = np.linspace(0.0, 6 * math.pi, 721)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    mats = np.array([np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * k @ k for a in angles])
    q = quaternions_from_rotations(mats)
    assert np.max(np.abs(rotation(q) - mats)) < 1e-14
    assert np.min(np.einsum("ki,ki->k", q[1:], q[:-1])) > 0.99
    assert abs(q[0, 0] - 1.0) < 1e-15 and abs(q[-1, 0] + 1.0) < 1e-14  # 3 turns: q → −q


def test_max_frames_keeps_first_last_and_event_times():
    mech = load_scene(EXAMPLES / "bouncing_ball.toml")
    res = casmbd.simulate(mech, t_end=2.0, steps=400).attach_scene(mech)
    assert res.events
    vm = view_model(res, max_frames=10)
    assert vm.times[0] == res.t[0] and vm.times[-1] == res.t[-1]
    assert 10 <= len(vm.times) <= 10 + len(res.events)
    for event in res.events:
        nearest = res.t[np.argmin(np.abs(res.t - event["time"]))]
        assert nearest in vm.times
    for bad in (0, "10", True, 2.5):
        with pytest.raises(AnalysisError, match="max_frames must be an integer >= 1"):
            view_model(res, max_frames=bad)
    assert np.array_equal(view_model(res, max_frames=1).times[:1], res.t[:1])
    assert [t for t, _ in vm.events] == [e["time"] for e in res.events]
    assert all(label == "floor impact" for _, label in vm.events)
    k = np.searchsorted(res.t, vm.times)
    assert np.array_equal(vm.body_positions["ball"][:, :2], res.body("ball")["position"][k])
    # the ball is a sphere of the contact's radius, on the floor plane
    assert [(s.kind, s.size, s.source) for s in vm.shapes] == [("sphere", (0.1,), "contact")]
    assert [(p.point.tolist(), p.normal.tolist()) for p in vm.planes] == [
        ([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])]
    assert vm.frames == []  # no joint, no marker (the renderer draws every body's axes)


# ---------------------------------------------------------------- sources
def test_a_mechanism_is_one_frame_at_its_assembled_initial_pose():
    """The four-bar's crank angle is given; the other links take the assembled pose, as the
    simulation starts from it (1e-9: both assemble to their own tolerance)."""
    mech = load_scene(EXAMPLES / "four_bar.toml")
    vm = view_model(mech)
    assert np.array_equal(vm.times, [0.0])
    start = casmbd.simulate(mech, t_end=1e-3, steps=1)
    for name in mech.bodies:
        assert np.max(np.abs(vm.body_positions[name][0, :2]
                             - start.body(name)["position"][0])) < 1e-9
    check_quaternions(vm)
    assert {f.name for f in vm.frames if f.kind == "joint"} == set(mech.joints)
    assert {f.name for f in vm.frames if f.kind == "marker"} == set(mech.markers)
    assert all(s.kind == "capsule" and s.source == "joints" for s in vm.shapes)


def test_statics_and_inverse_results(pendulum):
    mech, _ = pendulum
    equilibrium = casmbd.static_equilibrium(mech)
    with pytest.raises(AnalysisError, match="pass its mechanism"):
        view_model(equilibrium)
    vm = view_model(equilibrium, mech)
    assert len(vm.times) == 1
    for k, name in enumerate(mech.bodies):
        assert np.max(np.abs(vm.body_positions[name][0, :2]
                             - equilibrium.body_positions[k])) < 1e-12
    crank = load_scene(EXAMPLES / "slider_crank_inverse.toml")
    inverse = casmbd.inverse_dynamics(crank, t_end=0.1, steps=10).attach_scene(crank)
    vm = view_model(inverse)
    assert len(vm.times) == 11
    for name in crank.bodies:
        assert np.max(np.abs(vm.body_positions[name][:, :2]
                             - inverse.body(name)["position"])) < 1e-12


def test_a_sweep_and_unknown_sources_are_refused():
    with pytest.raises(AnalysisError, match="cannot view a str"):
        view_model("scene.toml")


@pytest.fixture(scope="module")
def swing_up():
    from casmbd.io.ocp_table import load_ocp

    ocp = load_ocp(ROOT / "ocp" / "double_pendulum_swingup.toml")
    ocp.intervals, ocp.subintervals, ocp.compile = 10, 1, False
    sol = ocp.solve()
    assert sol.success
    return sol


def test_an_ocp_solution_and_its_file(swing_up, tmp_path):
    """Body positions in closed form from the joint angles, r_upper = L/2 e(θ₁),
    r_lower = L e(θ₁) + L/2 e(θ₁ + θ₂) (L = 1 m), to 1e-12, from the solution, its saved file,
    and a file holding only q and v (written before issue 30: poses computed from q)."""
    th1, th2 = swing_up.q[:, 0], swing_up.q[:, 1]

    def e(phi):
        return np.column_stack([np.cos(phi), np.sin(phi)])

    upper, lower = 0.5 * e(th1), e(th1) + 0.5 * e(th1 + th2)
    path = swing_up.save(tmp_path / "sol.npz")
    loaded = OcpSolution.load(path)
    bare = OcpSolution(swing_up.t, swing_up.q, swing_up.v, swing_up.u, swing_up.stats,
                              swing_up.controls, swing_up.coordinate_names,
                              scene=swing_up.scene)
    for source in (swing_up, loaded, bare):
        vm = view_model(source)
        assert np.array_equal(vm.times, swing_up.t)
        assert np.max(np.abs(vm.body_positions["upper"][:, :2] - upper)) < 1e-12
        assert np.max(np.abs(vm.body_positions["lower"][:, :2] - lower)) < 1e-12
        check_quaternions(vm)
    assert "body_positions" not in bare.to_result().arrays  # the q path was taken
    controls = {s.name: s for s in view_model(swing_up).series if s.name.endswith("(input)")}
    assert list(controls) == [f"{c} (input)" for c in swing_up.controls]
    for k, name in enumerate(swing_up.controls):
        assert controls[f"{name} (input)"].unit == "N m"
        assert np.array_equal(controls[f"{name} (input)"].values, swing_up.node_controls()[:, k])


# ---------------------------------------------------------------- shapes
def test_inertia_box_reproduces_the_principal_moments():
    """The equivalent-inertia box of each UR5 link (full tensors with products, principal
    axes off the body axes): m (l_2² + l_3²)/12 … in the box axes, rotated back, is the body's
    inertia tensor (rel 1e-12)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the UR5 file's meshes are not shipped
        mech = casmbd.load_urdf(ROOT / "tests" / "scenes" / "ur5_arm.urdf")
        vm = view_model(mech)
    boxes = {s.body: s for s in vm.shapes if s.source == "inertia"}
    assert set(boxes) == set(mech.bodies)
    checked = 0
    for name, body in mech.bodies.items():
        box = boxes[name]
        assert box.kind == "box"
        lx, ly, lz = box.size
        if min(box.size) <= 0.05 * max(box.size) + 1e-15:
            continue  # a thin link drawn at the minimum ratio (module docstring)
        m = float(body.mass)
        moments = m / 12.0 * np.array([ly**2 + lz**2, lx**2 + lz**2, lx**2 + ly**2])
        rot = rotation(box.wxyz[None])[0]
        tensor = rot @ np.diag(moments) @ rot.T
        ixx, iyy, izz, *prod = (float(v) for v in body.inertia)
        ixy, ixz, iyz = prod if prod else (0.0, 0.0, 0.0)
        given = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        assert np.max(np.abs(tensor - given)) < 1e-12 * np.max(np.abs(given))
        checked += 1
    assert checked >= 4


def test_rods_join_the_joint_points_and_planar_discs_have_the_polar_moment(pendulum):
    mech, res = pendulum
    vm = view_model(res)
    rods = [s for s in vm.shapes if s.kind == "capsule"]
    assert {s.body for s in rods} == set(mech.bodies)
    for s in rods:  # each rod's ends are two of the body's joint or marker points
        r = rotation(s.wxyz[None])[0]
        ends = [s.position + sign * 0.5 * s.size[1] * r[:, 2] for sign in (-1, 1)]
        points = [np.append(mech.bodies[s.body].local(j.point), 0.0)
                  for j in mech.joints.values() if s.body in (j.body1, j.body2)]
        points += [np.append(mech.bodies[s.body].local(m.point), 0.0)
                   for m in mech.markers.values() if m.body == s.body]
        for end in ends:
            assert min(np.linalg.norm(end - p) for p in points) < 1e-12
    ball = load_scene(EXAMPLES / "bouncing_ball.toml")
    ball.contacts.clear()  # no contact sphere: the disc of the polar moment, r = √(2 I/m)
    (disc,) = view_model(ball).shapes
    assert disc.kind == "cylinder" and abs(disc.size[0] - math.sqrt(2 * 0.4 * 0.1**2)) < 1e-15


def test_mesh_robot_visuals_land_where_the_urdf_puts_them():
    """mesh_arm.urdf (tests/robots): an STL, an OBJ and a COLLADA mesh (mm, scale 0.001) and
    primitives, materials inline and by name.  Vertex counts are trimesh's own; a vertex of
    each mesh, placed by the view (r_G + A (p + R v)), is where the URDF's zero-pose forward
    kinematics put it (written here with Rz, Ry, Rx), to 1e-12."""
    trimesh = pytest.importorskip("trimesh", reason='the [view] extra: pip install "casmbd[view]"')
    pytest.importorskip("collada", reason="reading DAE needs pycollada (the [view] extra)")

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every visual loads, no notice
        mech = load_scene(ARM)
        vm = view_model(mech)
    assert vm.notes == []
    shapes = {s.name: s for s in vm.shapes}
    assert {name: (s.body, s.kind) for name, s in shapes.items()} == {
        "ground.plate": ("ground", "box"), "link1.visual1": ("link1", "mesh"),
        "link2.visual1": ("link2", "mesh"), "link2.elbow_cap": ("link2", "cylinder"),
        "link3.visual1": ("link3", "mesh"), "link3.tool.visual1": ("link3", "sphere")}
    assert all(s.source == "urdf-visual" for s in vm.shapes)
    meshes = ARM.parent / "meshes"
    for name, file, scale in (("link1.visual1", "link1.stl", 1.0),
                              ("link2.visual1", "link2.obj", 1.0),
                              ("link3.visual1", "link3.dae", 1e-3)):
        ref = trimesh.load(meshes / file, force="mesh", process=False)
        assert shapes[name].vertices.shape == ref.vertices.shape
        assert np.array_equal(shapes[name].faces, ref.faces)
        assert np.max(np.abs(shapes[name].vertices - scale * ref.vertices)) < 1e-15
    assert shapes["link3.visual1"].color == (204, 26, 26) and shapes["link3.visual1"].opacity \
        == pytest.approx(0.9)
    assert shapes["link2.elbow_cap"].color == (26, 51, 204)  # the named material "blue"
    assert shapes["ground.plate"].size == (0.2, 0.2, 0.05)

    def placed(shape: Shape, v) -> np.ndarray:
        if shape.body == "ground":
            pos, rot = np.zeros(3), np.eye(3)
        else:
            pos, rot = vm.body_positions[shape.body][0], rotation(vm.body_wxyz[shape.body])[0]
        return pos + rot @ (shape.position + rotation(shape.wxyz[None])[0] @ v)

    # the link frames at the URDF zero (joint origins composed)
    r1, p1 = np.eye(3), np.array([0, 0, 0.05])
    r2, p2 = r1 @ rz(0.4), p1 + r1 @ np.array([0, 0, 0.3])
    r3, p3 = r2 @ ry(0.2), p2 + r2 @ np.array([0.3, 0, 0])
    corner = np.array([0.15, 0.025, 0.025])  # a corner of the OBJ box
    expected = {"link2.visual1": (corner, p2 + r2 @ np.array([0.15, 0, 0]) + r2 @ rx(0.3)
                                  @ corner)}
    top = np.array([0.04, 0.0, 0.15])  # a point of the STL cylinder's top rim
    expected["link1.visual1"] = (top, p1 + np.array([0, 0, 0.15]) + top)
    apex = np.array([0.0, 0.0, 0.2])  # the cone's apex (200 mm): at the tool frame's origin
    expected["link3.visual1"] = (apex, p3 + r3 @ np.array([0.2, 0, 0]))
    for name, (v, world) in expected.items():
        verts = shapes[name].vertices
        assert np.min(np.linalg.norm(verts - v, axis=1)) < 1e-7  # v is a vertex (STL: float32)
        k = int(np.argmin(np.linalg.norm(verts - v, axis=1)))
        exact = verts[k]
        frame_expected = world + (exact - v) if name != "link2.visual1" else \
            world + r2 @ rx(0.3) @ (exact - v)
        if name == "link3.visual1":
            frame_expected = world + r3 @ ry(math.pi / 2) @ (exact - v)
        assert np.max(np.abs(placed(shapes[name], exact) - frame_expected)) < 1e-12, name
    tool = shapes["link3.tool.visual1"]
    assert np.max(np.abs(placed(tool, np.zeros(3)) - (p3 + r3 @ np.array([0.2, 0, 0])))) < 1e-12
    assert np.max(np.abs(placed(shapes["ground.plate"], np.zeros(3))
                         - np.array([0, 0, 0.025]))) < 1e-15


def test_a_mesh_that_does_not_load_is_named_and_the_body_falls_back(tmp_path):
    """A broken mesh file (garbage bytes), a missing one and a FIFO: one warning naming the
    files, the bodies drawn with derived shapes; the view still opens."""
    import os

    text = ARM.read_text()
    folder = tmp_path / "mesh_arm"  # the package of the package:// URIs
    (folder / "meshes").mkdir(parents=True)
    (folder / "meshes" / "link1.stl").write_bytes(b"solid broken\n this is not an stl\n")
    os.mkfifo(folder / "meshes" / "link3.dae")
    (folder / "mesh_arm.urdf").write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = load_scene(folder / "mesh_arm.urdf")
    with pytest.warns(RuntimeWarning, match="visual\\(s\\) not drawn") as rec:
        vm = view_model(mech)
    assert len(rec) == 1
    assert any("link1.stl" in n for n in vm.notes)
    assert any("link2.obj" in n and "not found" in n for n in vm.notes)  # package: this dir
    assert any("link3.dae" in n and "FIFO" in n for n in vm.notes)
    by_body = {}
    for s in vm.shapes:
        by_body.setdefault(s.body, set()).add(s.source)
    # link1 (broken STL) and link3 (FIFO) take the derived shapes, link2 (OBJ missing) too
    for body in ("link1", "link2", "link3"):
        assert by_body[body] == {"joints", "inertia"} or by_body[body] == {"inertia"}, body
    assert by_body["ground"] == {"urdf-visual"}  # the base's box still drawn


def test_package_uris_resolve_by_searching_parent_folders(tmp_path):
    pkg = tmp_path / "ws" / "src" / "my_robot"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "meshes").mkdir()
    (pkg / "meshes" / "a.stl").write_bytes(b"")
    source = str(pkg / "urdf" / "r.urdf")
    assert resolve_mesh("package://my_robot/meshes/a.stl", source) == str(pkg / "meshes"
                                                                          / "a.stl")
    assert resolve_mesh("package://other/meshes/a.stl", source) is None
    assert resolve_mesh("package://my_robot/../my_robot/meshes/a.stl", source) is None
    assert resolve_mesh("../meshes/a.stl", source) == str(pkg / "urdf" / ".." / "meshes"
                                                           / "a.stl")
    assert resolve_mesh("file:///x/y.stl", source) == "/x/y.stl"


def test_mesh_limits_and_formats(tmp_path):
    bad = tmp_path / "m.ply"
    bad.write_bytes(b"ply")
    with pytest.raises(casmbd.errors.SceneError, match=r"format '\.ply' is not read"):
        load_mesh(bad)
    with pytest.raises(casmbd.errors.SceneError, match="not found"):
        load_mesh(tmp_path / "missing.stl")
    with pytest.raises(casmbd.errors.SceneError, match="is a directory"):
        (tmp_path / "d.stl").mkdir()
        load_mesh(tmp_path / "d.stl")


# ---------------------------------------------------------------- flexible bodies
def test_flexible_nodes_are_the_geometry_deformed_nodes():
    """The spin-up beam: (n_t, n_nodes, 3) deformed nodes with the deformation scale, equal to
    casmbd.viz.geometry.deformed_nodes (1e-12), z = 0; edges join consecutive nodes; the node
    frames that carry joints or markers move with their node."""
    mech = load_scene(EXAMPLES / "spinup_beam.toml")
    res = casmbd.simulate(mech, t_end=0.5, steps=20).attach_scene(mech)
    for scale in (1.0, 25.0):
        vm = view_model(res, deformation_scale=scale)
        ref = deformed_nodes(res, scale=scale)["beam"]
        assert vm.flexible["beam"].shape == (len(res.t), ref.shape[1], 3)
        assert np.max(np.abs(vm.flexible["beam"][:, :, :2] - ref)) < 1e-12
        assert np.all(vm.flexible["beam"][:, :, 2] == 0.0)
    n = ref.shape[1]
    assert np.array_equal(vm.flexible_edges["beam"], np.column_stack([np.arange(n - 1),
                                                                      np.arange(1, n)]))
    assert not [s for s in vm.shapes if s.body == "beam"]
    tip = res.node("beam@tip")["position"]
    assert np.max(np.abs(view_model(res).body_positions["beam@tip"][:, :2] - tip)) < 1e-12
    with pytest.raises(AnalysisError, match="deformation_scale"):
        view_model(res, deformation_scale=0.0)


# ---------------------------------------------------------------- forces, series
def test_force_arrows_and_series():
    """A spring pulling a mass: the arrow on the mass is −f (r_mass − r_anchor)/|…| at the
    attachment point, f the reported tension; requests appear under their own names."""
    mech = load_scene(ROOT / "tests" / "scenes" / "spring_mass.toml")
    res = casmbd.simulate(mech, t_end=0.5, steps=20).attach_scene(mech)
    vm = view_model(res, forces=True)
    assert set(vm.forces) == {"spring@block"}  # the ground end carries no arrow
    point, vec = vm.forces["spring@block"]
    tension = res.force("spring")["force"]
    block_xy = res.body("block")["position"]
    assert np.max(np.abs(point[:, :2] - block_xy)) < 1e-12 and np.all(point[:, 2] == 0.0)
    unit = block_xy / np.linalg.norm(block_xy, axis=1, keepdims=True)  # anchor at the origin
    assert np.max(np.abs(vec[:, :2] + tension[:, None] * unit)) < 1e-12
    assert np.max(np.abs(tension)) > 1.0  # the spring does pull
    anchor, block = vm.links["spring"][:, 0], vm.links["spring"][:, 1]
    assert np.all(anchor == 0.0)  # the spring's ground end: the origin
    assert np.max(np.abs(block[:, :2] - res.body("block")["position"])) < 1e-12
    length = np.linalg.norm(block - anchor, axis=1)
    assert np.max(np.abs(length - res.force("spring")["length"])) < 1e-12
    assert vm.series and vm.series[0].name == "total energy" and vm.series[0].unit == "J"
    assert all(len(s.values) == len(vm.times) for s in vm.series)
    assert [(s.name, s.unit) for s in vm.series] == [("total energy", "J"), ("slide", "m")]
    assert np.array_equal(vm.series[1].values, res.joint("slide")["coordinate"])
    assert not view_model(res).forces  # only when asked


def test_missing_optional_readers_are_named(tmp_path, monkeypatch):
    """Without pycollada trimesh cannot read DAE (trimesh 5.2 imports it to parse COLLADA):
    the error names it and the extra; without trimesh no mesh is read, naming the extra."""
    import shutil
    import sys

    dae = tmp_path / "cone.dae"
    shutil.copy(ARM.parent / "meshes" / "link3.dae", dae)
    monkeypatch.setitem(sys.modules, "collada", None)
    with pytest.raises(casmbd.errors.SceneError,
                       match=r"reading DAE needs pycollada \(pip install \"casmbd\[view\]\"\)"):
        load_mesh(dae)
    stl = tmp_path / "a.stl"
    shutil.copy(ARM.parent / "meshes" / "link1.stl", stl)
    monkeypatch.setitem(sys.modules, "trimesh", None)
    with pytest.raises(casmbd.errors.SceneError, match=r"meshes need trimesh"):
        load_mesh(stl)


def test_contact_normal_force_arrows():
    """The ball resting on the floor (statics): N n = (0, m g) at the touching point (0, 0),
    1e-12; the compliant model's reported normal force along the normal at r_c − r n."""
    mech = load_scene(EXAMPLES / "bouncing_ball.toml")
    vm = view_model(casmbd.static_equilibrium(mech), mech, forces=True)
    point, vec = vm.forces["floor"]
    assert np.max(np.abs(point)) < 1e-12
    assert np.max(np.abs(vec - [0.0, 9.81, 0.0])) < 1e-12
    text = (EXAMPLES / "bouncing_ball.toml").read_text().replace('model = "impact"',
                                                                 'model = "compliant"')
    soft = casmbd.loads_scene(text)
    res = casmbd.simulate(soft, t_end=0.6, steps=60).attach_scene(soft)
    vm = view_model(res, forces=True)
    (name,) = vm.forces
    point, vec = vm.forces[name]
    force = next(v for k, v in res.force(next(iter(soft.forces))).items() if k == "normal_force")
    assert np.max(force) > 1.0  # it touched the floor
    assert np.max(np.abs(vec[:, 1] - force)) < 1e-12 and np.all(vec[:, [0, 2]] == 0.0)
    ball = res.body("ball")["position"]
    assert np.max(np.abs(point[:, :2] - (ball - [0.0, 0.1]))) < 1e-12
    assert vm.notes == []


def test_a_malformed_visual_is_left_out_with_a_warning_naming_the_link():
    """Visuals change nothing that is computed: a box with two sizes, a geometry casmbd does
    not know and a mesh without a filename are each named (link, element, attribute) and left
    out; the robot loads and its well-formed visual stays."""
    text = ARM.read_text().replace('<box size="0.2 0.2 0.05"/></geometry>\n      <material',
                                   '<box size="0.2 0.2"/></geometry>\n      <material')
    text = text.replace('<sphere radius="0.03"/>', '<capsule radius="0.03" length="0.1"/>')
    text = text.replace('<mesh filename="meshes/link1.stl"/>', '<mesh/>')
    with pytest.warns(RuntimeWarning) as rec:
        mech = casmbd.loads_urdf(text, str(ARM))
    messages = [str(w.message) for w in rec]
    assert any("link 'base_link' <visual> number 1 <box> attribute 'size'" in m
               for m in messages)
    assert any("link 'tool' <visual> number 1 <geometry>: unknown geometry <capsule>" in m
               for m in messages)
    assert any("link 'link1' <visual> number 1 <mesh>: missing attribute 'filename'" in m
               for m in messages)
    assert "ground" not in mech.visuals and "link1" not in mech.visuals
    assert [v.kind for v in mech.visuals["link3"]] == ["mesh"]
    assert [v.kind for v in mech.visuals["link2"]] == ["mesh", "cylinder"]


def test_a_scene_naming_a_urdf_relative_to_itself_reloads_from_a_result_anywhere(
        tmp_path, monkeypatch):
    """ocp/ur5_min_time.toml names ../examples/ur5_arm.urdf: the scene text a result embeds
    holds the absolute path, so `casmbd view` of its solution works from any folder (before,
    Result.mechanism() looked for the URDF relative to the working folder); the scene's
    tables are otherwise unchanged."""
    import tomllib

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = load_scene(ROOT / "ocp" / "ur5_min_time.toml")
    data = tomllib.loads(mech.scene_text)
    assert data["scene"]["urdf"] == str(ROOT / "examples" / "ur5_arm.urdf")
    original = tomllib.loads((ROOT / "ocp" / "ur5_min_time.toml").read_text())
    original["scene"]["urdf"] = data["scene"]["urdf"]
    assert data == original
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        again = casmbd.Result("x", np.zeros(1), {}, {"bodies": []}, {},
                              mech.scene_text).mechanism(casmbd.loads_scene)
    assert list(again.bodies) == list(mech.bodies)
