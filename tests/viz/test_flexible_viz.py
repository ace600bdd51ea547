"""Drawing flexible bodies (issue 23 item 4): the polyline through the deformed nodes.

The viz layer places node i of a flexible body at r_i = R + A (u_i0 + s Φ_i η) (seed 002,
eq. 5–26) from the coordinates q of a result.  Checked here, planar and spatial, in absolute
and natural coordinates, on short simulations of a flexible pendulum (VM, no compilation):

* the drawn nodes against the same formula written out in the test node by node (R, θ, the
  Euler parameters or the body axes and η picked from q by name; A(θ), A(p) of seed 001
  eq. 15, [u, ẑ × u] or [u v w]), to 1e-12 m;
* the named-node markers the System computed (an independent CasADi formulation of the node
  position) against the drawn nodes, to 1e-12 m, and a marker offset from a node (node-frame
  rotation A A(ψ)) against the System's marker, to 1e-12 m;
* a joint at a node: its point drawn on the node frame against the same point on the rigid
  body it joins (the constraint tolerance, 1e-8 m);
* the drawn line data of a still frame, the deformed centre of mass Σ m_i r_i / Σ m_i and a
  deformation scale (R + A (u_i0 + 10 Φ_i η)), to 1e-12 m;
* the two example scenes load, simulate briefly from the CLI and draw.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import cli
from casmbd.errors import AnalysisError
from casmbd.viz import geometry
from casmbd.viz.animation import animate, draw_frame

matplotlib = pytest.importorskip("matplotlib")

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = REPO_ROOT / "examples"

_cache = private_cache("casmbd_cache_flexible_viz", scope="module", CASMBD_COMPILE="0")

PLANAR = """
[scene]
name = "flexible_pendulum"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "beam"
type = "flexible"
position = [0.0, 0.0]
angle = 0.3
modes = 3
reduction = "craig_bampton"
interfaces = ["root", "tip"]
[bodies.beam]
length = 1.0
elements = 6
EI = 2.0
EA = 1.0e5
rhoA = 0.5
nodes = { root = 0.0, tip = 1.0 }

[[bodies]]
name = "bob"
mass = 0.2
inertia = 1e-4
position = ["cos(0.3)", "sin(0.3)"]
angle = 0.3

[[joints]]
name = "hinge"
type = "revolute"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0]

[[joints]]
name = "pin"
type = "revolute"
body1 = "bob"
body2 = "beam"
node2 = "tip"
point = ["cos(0.3)", "sin(0.3)"]

[[markers]]
name = "tag"
body = "beam"
node = "tip"
point = ["cos(0.3) - 0.1*sin(0.3)", "sin(0.3) + 0.1*cos(0.3)"]
"""

SPATIAL = """
[scene]
name = "flexible_spatial_pendulum"
dimension = 3
gravity = [0.0, 0.0, -9.81]

[[bodies]]
name = "beam"
type = "flexible"
position = [0.0, 0.0, 0.0]
euler_zxz = [0.4, 0.3, 0.0]
angular_velocity = [0.0, 0.0, 3.0]
modes = 3
reduction = "craig_bampton"
interfaces = ["root"]
[bodies.beam]
length = 1.0
elements = 6
EIy = 2.0
EIz = 3.0
GJ = 2.0
EA = 1.0e5
rhoIp = 1.0e-4
rhoA = 0.5
nodes = { root = 0.0, tip = 1.0 }

[[joints]]
name = "ball"
type = "spherical"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0, 0.0]

[[markers]]
name = "tag"
body = "beam"
node = "tip"
point = [0.5, 0.5, 0.5]
"""


def _run(text: str, natural: bool = False):
    if natural:
        text = text.replace("dimension = ", 'coordinates = "natural"\ndimension = ', 1)
    mech = casmbd.loads_scene(text)
    return casmbd.simulate(mech, t_end=0.5, steps=10).attach_scene(mech)


@pytest.fixture(scope="module")
def results():
    return {"planar": _run(PLANAR), "spatial": _run(SPATIAL),
            "planar_natural": _run(PLANAR, True), "spatial_natural": _run(SPATIAL, True)}


def reference_nodes(result, body: str, scale: float = 1.0) -> np.ndarray:
    """r_i = R + A (u_i0 + s Φ_i η) node by node, from q picked by coordinate name."""
    mech = result.mechanism()
    modal = mech.bodies[body].modal
    names = result.names["coordinates"]
    q = result.arrays["q"]

    def col(name: str) -> np.ndarray:
        return q[:, names.index(f"{body}.{name}")]

    dim = result.dimension
    ref = np.stack([col(c) for c in ("x", "y", "z")[:dim]], axis=1)
    eta = np.stack([col(f"eta{k + 1}") for k in range(modal.phi_t.shape[2])], axis=1)
    out = np.empty((len(q), len(modal.positions), dim))
    natural = f"{body}.ux" in names
    for k in range(len(q)):
        if natural and dim == 2:  # A = [u, ẑ × u] (seed 003)
            ux, uy = col("ux")[k], col("uy")[k]
            rot = np.array([[ux, -uy], [uy, ux]])
        elif natural:  # A = [u v w]
            rot = np.array([[col(f"{a}{x}")[k] for a in "uvw"] for x in "xyz"])
        elif dim == 2:
            c, s = math.cos(col("angle")[k]), math.sin(col("angle")[k])
            rot = np.array([[c, -s], [s, c]])
        else:
            e0, e1, e2, e3 = (col(f"e{j}")[k] for j in range(4))
            d = 2 * e0**2 - 1  # seed 001 eq. 15 written out, unnormalised as in the model
            rot = np.array([[d + 2 * e1**2, 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
                            [2 * (e1 * e2 + e0 * e3), d + 2 * e2**2, 2 * (e2 * e3 - e0 * e1)],
                            [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), d + 2 * e3**2]])
        for i in range(len(modal.positions)):
            u = modal.positions[i] + scale * modal.phi_t[i] @ eta[k]
            out[k, i] = ref[k] + rot @ u
    return out


@pytest.mark.parametrize("which", ["planar", "spatial", "planar_natural", "spatial_natural"])
def test_drawn_nodes_follow_the_floating_frame_formula(results, which):
    result = results[which]
    assert ("beam.ux" in result.names["coordinates"]) == which.endswith("natural")
    mech = result.mechanism()
    nodes = geometry.deformed_nodes(result)["beam"]
    expected = reference_nodes(result, "beam")
    np.testing.assert_allclose(nodes, expected, rtol=0, atol=1e-12)
    # a deformed state: the nodes are off the rigid (η = 0) positions by millimetres at least
    rigid = geometry.deformed_nodes(result, scale=1e-300)["beam"]
    assert np.abs(nodes - rigid).max() > 1e-3
    # the named-node markers (System outputs) are the drawn nodes
    for node, index in mech.bodies["beam"].modal.node_names.items():
        np.testing.assert_allclose(result.marker(f"beam@{node}")["position"], nodes[:, index],
                                   rtol=0, atol=1e-12)
    # a marker offset from the tip node turns with the node frame A A(ψ_tip)
    geo = geometry.Geometry.from_mechanism(mech)
    labels = [label for label, _ in geo.points["beam"]]
    assert geo.frames["beam"][labels.index("marker:tag")] == "beam@tip"
    tag = geometry.body_points(result)["beam"][:, labels.index("marker:tag")]
    np.testing.assert_allclose(tag, result.marker("tag")["position"], rtol=0, atol=1e-12)
    # the tag is off the tip node, so the node rotation matters
    assert np.linalg.norm(tag - nodes[:, -1], axis=1).min() > 0.09


def test_joint_at_a_node_meets_the_rigid_body(results):
    result = results["planar"]
    geo = geometry.Geometry.from_mechanism(result.mechanism())
    assert geo.joints["pin"][0] == "beam@tip"
    on_node = geometry.joint_points(result)["pin"]
    labels = [label for label, _ in geo.points["bob"]]
    on_bob = geometry.body_points(result)["bob"][:, labels.index("joint:pin")]
    assert np.abs(on_node - on_bob).max() < 1e-8
    np.testing.assert_allclose(on_node, geometry.deformed_nodes(result)["beam"][:, -1],
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("which", ["planar", "spatial_natural"])
def test_still_frame_draws_the_deformed_nodes(results, which, tmp_path):
    result = results[which]
    mech = result.mechanism()
    k = 7
    for scale in (1.0, 10.0):
        fig = draw_frame(result, index=k, deformation_scale=scale, out=tmp_path / "f.png",
                         dpi=40)
        ax = fig.axes[0]
        line = next(ln for ln in ax.get_lines() if ln.get_label() == "beam")
        spatial = which.startswith("spatial")
        data = np.array(line.get_data_3d() if spatial else line.get_data()).T
        expected = reference_nodes(result, "beam", scale)[k]
        np.testing.assert_allclose(data, expected, rtol=0, atol=1e-12)
        masses = mech.bodies["beam"].modal.masses
        dots = [ln for ln in ax.get_lines() if ln.get_marker() == "o" and ln.get_linestyle()
                == "None" and ln.get_color() == line.get_color()]
        com = np.array(dots[0].get_data_3d() if spatial else dots[0].get_data())
        np.testing.assert_allclose(com.ravel(), masses @ expected / masses.sum(), rtol=0,
                                   atol=1e-12)
        said = "deformation x10" in " ".join(t.get_text() for t in ax.texts)
        assert said == (scale == 10.0)
    if which == "planar":  # the rigid bob keeps its drawing: its joint point and centre
        anim = animate(result, max_frames=3)
        drawing = anim.casmbd_drawing
        drawing.update(k)
        bob = np.array(drawing.body_lines["bob"].get_data()).T
        labels = [label for label, _ in drawing.geo.points["bob"]]
        pin = geometry.body_points(result)["bob"][k, labels.index("joint:pin")]
        np.testing.assert_allclose(bob, [pin, result.arrays["body_positions"][k, 2:4]],
                                   rtol=0, atol=1e-12)
        anim._draw_was_started = True


def test_errors_name_the_problem(results):
    result = results["planar"]
    for bad in (0.0, -1.0, float("nan"), True):
        with pytest.raises(AnalysisError, match="deformation_scale must be a finite number"):
            draw_frame(result, deformation_scale=bad)
    arrays = {key: val for key, val in result.arrays.items() if key != "q"}
    bare = casmbd.Result(result.kind, result.t, arrays, result.names, scene=result.scene)
    with pytest.raises(AnalysisError, match=r"no coordinates 'q'.*flexible bodies beam"):
        geometry.deformed_nodes(bare)
    names = dict(result.names, coordinates=[n.replace("eta2", "zeta2")
                                            for n in result.names["coordinates"]])
    renamed = casmbd.Result(result.kind, result.t, result.arrays, names, scene=result.scene)
    with pytest.raises(AnalysisError, match=r"flexible body 'beam'.*'beam\.eta2'"):
        geometry.deformed_nodes(renamed)


@pytest.mark.parametrize("scene", ["spinup_beam", "flexible_slider_crank"])
def test_examples_simulate_and_draw_from_the_cli(scene, capsys, tmp_path):
    path = EXAMPLES / f"{scene}.toml"
    npz = tmp_path / f"{scene}.npz"
    status = cli.main(["simulate", str(path), "--t-end", "0.01", "--steps", "4", "--json",
                       "--out", str(npz)])
    out, err = capsys.readouterr()
    assert status == 0, err
    payload = json.loads(out)
    assert payload["t"][-1] == pytest.approx(0.01)
    result = casmbd.load_result(npz)
    body = "beam" if scene == "spinup_beam" else "rod"
    nodes = geometry.deformed_nodes(result)[body]
    np.testing.assert_allclose(nodes, reference_nodes(result, body), rtol=0, atol=1e-12)
    png = tmp_path / f"{scene}.png"
    status = cli.main(["animate", str(npz), "--out", str(png), "--dpi", "40"])
    capsys.readouterr()
    assert status == 0 and png.stat().st_size > 0
