"""Markers at the nodes of flexible bodies, node deflections in every result, and the text
summaries' node and ``[[outputs]]`` lines (issue 30, item 4d).

The beam is Kane's spin-up beam (tests/flexible_references.py: L = 10 m, EI = 1.4e4 N m²,
EA = 2.8e7 N, ρA = 1.2 kg/m), 8 elements, 4 Craig–Bampton modes with the root and the tip as
interfaces.  References:

* cantilever with a tip load P (Timoshenko & Gere, *Mechanics of Materials*, app. G): tip
  deflection −P L³/(3 EI), tip slope −P L²/(2 EI), mid-span deflection −5 P L³/(48 EI).  Cubic
  Hermite elements reproduce them exactly at the nodes and the static constraint mode of the
  tip interface spans the static response, so the reduced model has no modal-truncation error
  here: the statics tests bound the relative error by 1e-9 (measured 2e-13);
* a marker at a node, in dynamics: the node position r_i = R + A(θ) (u_i0 + Φ_i η) and frame
  angle θ + Ψ_i η evaluated with numpy from the result's q and the body's modal data (seed 002,
  eq. 5–26), an offset marker r_P = r_i + A(θ + ψ_i) A(θ0)ᵀ (P − r_i0): equal to 1e-12;
* rigid motion (kinematics, inverse dynamics: the modes held at zero) of a beam turned about
  its root by a driver θ = ω t: the tip at (L cos θ, L sin θ), deflections exactly zero.

Every analysis runs in CasADi's virtual machine (``mode="vm"``).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import casmbd
from casmbd.cli import main
from casmbd.errors import ModelError, SceneError
from casmbd.model.mechanism import Mechanism
from tests.conftest import private_cache
from tests.flexible_references import KANE_BEAM

_cache = private_cache("cache_flexible_markers", scope="module")

L, EI, EA, RHOA = (KANE_BEAM[k] for k in ("length", "EI", "EA", "rhoA"))
P = 100.0  # tip load [N]
TIP = -P * L**3 / (3 * EI)          # −2.380952 m
SLOPE = -P * L**2 / (2 * EI)        # −0.357143 rad
MID = -5 * P * L**3 / (48 * EI)     # −0.744048 m
OFFSET = 1.0  # the offset marker sits 1 m above the tip at the initial pose


def _beam(dim: int = 2, angle: float = 0.0) -> str:
    zero = "[0.0, 0.0]" if dim == 2 else "[0.0, 0.0, 0.0]"
    props = f"EI = {EI}" if dim == 2 else f"EIy = {EI}\nEIz = {2 * EI}\nGJ = 1.0e4\nrhoIp = 0.01"
    pose = f"angle = {angle}" if dim == 2 else ""
    return f"""
[[bodies]]
name = "beam"
type = "flexible"
position = {zero}
{pose}
modes = 4
interfaces = ["root", "tip"]
[bodies.beam]
length = {L}
elements = 8
{props}
EA = {EA}
rhoA = {RHOA}
nodes = {{ root = 0.0, mid = {L / 2}, tip = {L} }}
"""


def _markers(dim: int, angle: float = 0.0, frame_angle: float = 0.2) -> str:
    """m_tip at the tip node (no point), m_off 1 m off the tip (normal to the beam at the
    initial pose) and, in the plane, m_frame at the tip with its own frame angle."""
    if dim == 2:
        off = [L * np.cos(angle) - OFFSET * np.sin(angle), L * np.sin(angle)
               + OFFSET * np.cos(angle)]
        frame = f"""
[[markers]]
name = "m_frame"
body = "beam"
node = "tip"
angle = {angle + frame_angle}
"""
    else:
        off, frame = [L, 0.0, OFFSET], ""
    return f"""
[[markers]]
name = "m_tip"
body = "beam"
node = "tip"

[[markers]]
name = "m_off"
body = "beam"
node = "tip"
point = {[float(x) for x in off]}
{frame}
[[outputs]]
name = "tip_y"
value = '{"y" if dim == 2 else "z"}("m_tip")'
unit = "m"
"""


def _cantilever(dim: int = 2, coordinates: str = "absolute") -> str:
    load = f"[0.0, {-P}]" if dim == 2 else f"[0.0, 0.0, {-P}]"
    slope = """
[[outputs]]
name = "tip_slope"
value = 'angle_of("m_tip")'
unit = "rad"
""" if dim == 2 else ""
    zero = "[0.0, 0.0]" if dim == 2 else "[0.0, 0.0, 0.0]"
    return f"""
[scene]
name = "cantilever"
dimension = {dim}
gravity = {zero}
coordinates = "{coordinates}"
{_beam(dim)}
[[joints]]
name = "clamp"
type = "fixed"
body = "beam"
node = "root"

[[forces]]
name = "load"
type = "force"
body = "beam"
node = "tip"
value = {load}
{_markers(dim)}{slope}"""


def _marker(res, name: str) -> np.ndarray:
    return res.marker_positions[res.names["markers"].index(name)]


@pytest.mark.parametrize("coordinates", ["absolute", "natural"])
def test_cantilever_node_marker_statics(coordinates, tmp_path, capsys):
    """Statics of the planar cantilever: the marker at the tip node sits at (L, −P L³/(3 EI)),
    its frame turned by −P L²/(2 EI) (request ``angle_of``), the offset marker at
    r_tip + A(ψ) (0, 1); the nodes' deflections (body axes) are the closed forms at the root,
    mid-span and tip (relative error bound 1e-9, measured 2e-13; no modal-truncation error,
    module docstring); ``statics --json`` has them under ``nodes`` and ``markers``, the text
    summary lists them and the requests' values."""
    scene = _cantilever(coordinates=coordinates)
    mech = casmbd.loads_scene(scene)
    res = casmbd.static_equilibrium(mech, mode="vm")
    tip = _marker(res, "m_tip")
    assert tip == pytest.approx([L, TIP], rel=1e-9)
    assert np.array_equal(tip, _marker(res, "beam@tip"))  # the node's own marker
    psi = SLOPE
    assert _marker(res, "m_off") == pytest.approx(
        [L - OFFSET * np.sin(psi), TIP + OFFSET * np.cos(psi)], rel=1e-9)

    data = res.to_json()
    assert data["outputs"]["tip_y"] == pytest.approx(TIP, rel=1e-9)
    assert data["outputs"]["tip_slope"] == pytest.approx(SLOPE, rel=1e-9)
    nodes = data["nodes"]
    assert list(nodes) == ["beam@root", "beam@mid", "beam@tip"] == res.names["nodes"]
    for name, deflection, slope in (("beam@root", 0.0, 0.0), ("beam@mid", MID, None),
                                    ("beam@tip", TIP, SLOPE)):
        node = nodes[name]
        assert node["deflection"][0] == pytest.approx(0.0, abs=1e-9 * abs(TIP))  # no stretch
        assert node["deflection"][1] == pytest.approx(deflection, rel=1e-9, abs=1e-12)
        if slope is not None:
            assert node["rotation"] == pytest.approx(slope, rel=1e-9, abs=1e-12)
        assert node["position"] == data["markers"][name]["position"]
    assert data["markers"]["m_tip"]["position"] == nodes["beam@tip"]["position"]

    path = tmp_path / "cantilever.toml"
    path.write_text(scene)
    assert main(["statics", str(path), "--json", "--mode", "vm"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["nodes"]["beam@tip"]["deflection"][1] == pytest.approx(TIP, rel=1e-9)
    assert out["markers"]["m_tip"]["position"][1] == pytest.approx(TIP, rel=1e-9)
    assert out["outputs"]["tip_y"] == pytest.approx(TIP, rel=1e-9)
    assert main(["statics", str(path), "--mode", "vm"]) == 0
    text = capsys.readouterr().out
    tip_line = next(line for line in text.splitlines() if line.startswith("  beam@tip "))
    assert tip_line.split()[1] == f"{abs(TIP):.6g}" and f"{TIP:+.6g}]" in tip_line
    mid_line = next(line for line in text.splitlines() if line.startswith("  beam@mid "))
    assert f"{MID:+.6g}]" in mid_line
    assert f"{TIP:+.6g}  m" in next(line for line in text.splitlines()
                                    if line.startswith("  tip_y "))
    assert f"{SLOPE:+.6g}  rad" in next(line for line in text.splitlines()
                                        if line.startswith("  tip_slope "))


def test_spatial_cantilever_node_marker_statics():
    """Spatial cantilever, load −P along z: bending about the body y axis, stiffness EIy,
    tip deflection −P L³/(3 EIy) (bound 1e-9 relative), slope about y +P L²/(2 EIy) (the
    section turns nose-down: a positive rotation about y takes x to −z); the offset marker 1 m
    above the tip follows the node frame: r_tip + A(ψ) (0, 0, 1)."""
    mech = casmbd.loads_scene(_cantilever(dim=3))
    res = casmbd.static_equilibrium(mech, mode="vm")
    data = res.to_json()
    node = data["nodes"]["beam@tip"]
    assert node["deflection"] == pytest.approx([0.0, 0.0, TIP], rel=1e-9, abs=1e-9 * abs(TIP))
    assert node["rotation"] == pytest.approx([0.0, -SLOPE, 0.0], rel=1e-9,
                                             abs=1e-9 * abs(SLOPE))
    assert _marker(res, "m_tip") == pytest.approx([L, 0.0, TIP], rel=1e-9, abs=1e-12)
    # the node frame turned by ψ = (0, θy, 0) (exact rotation, angle 2 atan(|ψ|/2))
    angle = 2 * np.arctan(-SLOPE / 2)
    assert _marker(res, "m_off") == pytest.approx(
        [L + OFFSET * np.sin(angle), 0.0, TIP + OFFSET * np.cos(angle)], rel=1e-9, abs=1e-12)
    assert data["outputs"]["tip_y"] == pytest.approx(TIP, rel=1e-9)


_PENDULUM = f"""
[scene]
name = "flexible_pendulum"
dimension = 2
gravity = [0.0, -9.81]
{_beam(2, angle=0.3)}
[[joints]]
name = "hub"
type = "revolute"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0]
{_markers(2, angle=0.3)}
[[outputs]]
name = "frame_angle"
value = 'angle_of("m_frame")'
unit = "rad"
"""


def _node_by_numpy(mech, q: np.ndarray, names: list[str], node: str):
    """(r_i, θ + ψ_i) of a node from q: r_i = R + A(θ) (u_i0 + Φ_i η) (seed 002, eq. 5–26)."""
    body = mech.bodies["beam"]
    modal, i = body.modal, body.modal.node_names[node]
    frame = q[:, [names.index(f"beam.{c}") for c in ("x", "y", "angle")]]
    eta = q[:, [k for k, n in enumerate(names) if n.startswith("beam.eta")]]
    local = modal.positions[i][None, :] + eta @ modal.phi_t[i].T
    c, s = np.cos(frame[:, 2]), np.sin(frame[:, 2])
    r = frame[:, :2] + np.column_stack([c * local[:, 0] - s * local[:, 1],
                                        s * local[:, 0] + c * local[:, 1]])
    return r, frame[:, 2] + eta @ np.atleast_2d(modal.phi_r[i]).T[:, 0], eta @ modal.phi_t[i].T


def test_node_marker_follows_the_node_in_simulation(tmp_path, capsys):
    """A flexible pendulum released at 0.3 rad (the beam swings and bends under gravity):
    the marker at the tip node equals the node position R + A(θ)(u0 + Φ η) computed with numpy
    from q, to 1e-12 m at every output; the offset marker is r_tip + A(θ + ψ) A(θ0)ᵀ (P − r0)
    and the marker frame's angle θ + ψ + 0.2 (its own angle at the design pose 0.5 minus the
    body's 0.3), to 1e-12; ``Result.node`` gives the same deflection Φ_i η; the CLI's JSON has
    ``nodes`` and ``outputs``, the summary the node and request lines with their values."""
    mech = casmbd.loads_scene(_PENDULUM)
    res = casmbd.simulate(mech, t_end=0.6, steps=12, mode="vm")
    q, names = res["q"], res.names["coordinates"]
    r_tip, theta_tip, defl = _node_by_numpy(mech, q, names, "tip")
    assert np.ptp(res.body("beam")["angle"]) > 0.2          # it swings
    assert np.max(np.abs(defl[:, 1])) > 1e-3                  # and bends
    assert np.max(np.abs(res.marker("m_tip")["position"] - r_tip)) <= 1e-12
    assert np.max(np.abs(res.node("beam@tip")["position"] - r_tip)) <= 1e-12
    assert np.max(np.abs(res.node("beam@tip")["deflection"] - defl)) <= 1e-12
    rel = np.array([-OFFSET * np.sin(0.3), OFFSET * np.cos(0.3)])  # P − r_tip0
    local = np.array([[np.cos(0.3), np.sin(0.3)], [-np.sin(0.3), np.cos(0.3)]]) @ rel
    c, s = np.cos(theta_tip), np.sin(theta_tip)
    r_off = r_tip + np.column_stack([c * local[0] - s * local[1], s * local[0] + c * local[1]])
    assert np.max(np.abs(res.marker("m_off")["position"] - r_off)) <= 1e-12
    assert np.max(np.abs(res.output("frame_angle") - (theta_tip + 0.2))) <= 1e-12
    assert np.max(np.abs(res.marker("m_frame")["angle"] - (theta_tip + 0.2))) <= 1e-12
    assert np.max(np.abs(res.output("tip_y") - r_tip[:, 1])) <= 1e-12

    path = tmp_path / "pendulum.toml"
    path.write_text(_PENDULUM)
    args = ["simulate", str(path), "--t-end", "0.6", "--steps", "12", "--mode", "vm"]
    assert main([*args, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["nodes"]) == {"beam@root", "beam@mid", "beam@tip"}
    assert set(out["nodes"]["beam@tip"]) == {"position", "deflection", "rotation"}
    assert np.max(np.abs(np.array(out["markers"]["m_tip"]["position"]) - r_tip)) <= 1e-9
    assert out["outputs"]["tip_y"][-1] == pytest.approx(r_tip[-1, 1], abs=1e-9)
    assert main(args) == 0
    text = capsys.readouterr().out
    tip_line = next(line for line in text.splitlines() if line.startswith("  beam@tip "))
    assert tip_line.split()[2] == f"{np.linalg.norm(defl[-1]):.6g}"  # |u| at the end
    assert f"[{defl[-1, 0]:+.4g}, {defl[-1, 1]:+.4g}]" in tip_line
    assert next(line for line in text.splitlines()
                if line.startswith("  tip_y ")).split()[2] == f"{r_tip[-1, 1]:+.6g}"  # end
    assert "  frame_angle " in text


_DRIVEN = _PENDULUM.replace('name = "flexible_pendulum"', 'name = "flexible_crank"') + """
[[drivers]]
name = "turn"
joint = "hub"
position = "0.3 + 0.5*t"
"""


@pytest.mark.parametrize("analysis", ["kinematics", "inverse_dynamics"])
def test_node_marker_in_rigid_motion(analysis):
    """Kinematics and inverse dynamics run the rigid motion (modes held at zero): a driver
    turns the beam about its root, θ = 0.3 + 0.5 t; the tip-node marker is at L (cos θ, sin θ)
    and the frame marker's angle θ + 0.2 to 1e-12, the node deflections exactly 0, the
    requests on the grid."""
    mech = casmbd.loads_scene(_DRIVEN)
    res = getattr(casmbd, analysis)(mech, t_end=1.0, steps=4, mode="vm")
    theta = 0.3 + 0.5 * res.t
    exact = L * np.column_stack([np.cos(theta), np.sin(theta)])
    assert np.max(np.abs(res.marker("m_tip")["position"] - exact)) <= 1e-12
    assert np.max(np.abs(res.node("beam@tip")["position"] - exact)) <= 1e-12
    assert np.max(np.abs(res.output("frame_angle") - (theta + 0.2))) <= 1e-12
    for name in res.names["nodes"]:
        assert not np.any(res.node(name)["deflection"]) and not np.any(
            res.node(name)["rotation"])
    data = res.to_json()
    assert set(data["nodes"]) == {"beam@root", "beam@mid", "beam@tip"}
    assert data["outputs"]["tip_y"] == pytest.approx(list(exact[:, 1]), abs=1e-12)


def test_node_csv_columns_and_saved_result(tmp_path):
    """The node arrays are labelled in CSV (``node_deflections[beam@tip.y]``,
    ``node_rotations[beam@tip.angle]``) and survive save/load."""
    mech = casmbd.loads_scene(_PENDULUM)
    res = casmbd.simulate(mech, t_end=0.2, steps=2, mode="vm")
    labels = [label for label, _ in res.csv_columns()]
    assert "node_deflections[beam@tip.y]" in labels
    assert "node_rotations[beam@tip.angle]" in labels
    assert "node_positions[beam@mid.x]" in labels
    back = casmbd.load_result(res.save(tmp_path / "run.npz"))
    assert np.array_equal(back.node("beam@tip")["deflection"],
                          res.node("beam@tip")["deflection"])


def test_node_marker_python_api_and_errors():
    """``Mechanism.add_marker(name, body, node=...)``: the point defaults to the node's
    undeformed position; the errors name the marker, the field and the known nodes."""
    mech = casmbd.loads_scene(_cantilever())
    marker = mech.add_marker("py_tip", "beam", node="tip")
    assert marker.body == "beam@tip" and marker.point == pytest.approx([L, 0.0])
    marker = mech.add_marker("py_off", "beam", (L, 2.0), node="tip")
    assert marker.point == pytest.approx([L, 2.0])
    with pytest.raises(ModelError, match=r"marker 'bad'.*no node 'nose'.*mid, root, tip"):
        mech.add_marker("bad", "beam", node="nose")
    with pytest.raises(ModelError, match="marker 'bad2' field 'point': missing"):
        mech.add_marker("bad2", "beam")
    with pytest.raises(ModelError, match="marker 'bad3' field 'body'"):
        mech.add_marker("bad3", "beam@tip", node="tip")
    rigid = Mechanism("rigid")
    rigid.add_body("rod", mass=1.0, inertia=0.1, position=(0.5, 0.0))
    with pytest.raises(ModelError, match="body 'rod' is rigid"):
        rigid.add_marker("m", "rod", node="tip")
    res = casmbd.static_equilibrium(mech, mode="vm")
    assert _marker(res, "py_tip") == pytest.approx([L, TIP], rel=1e-9)

    scene = _cantilever().replace('name = "m_tip"\nbody = "beam"\nnode = "tip"',
                                  'name = "m_tip"\nbody = "rod"\nnode = "tip"')
    with pytest.raises(SceneError, match=r"\[\[markers\]\] entry 1 \('m_tip'\).*unknown body"):
        casmbd.loads_scene(scene)
    scene = _cantilever().replace('name = "m_tip"\nbody = "beam"\nnode = "tip"',
                                  'name = "m_tip"\nbody = "beam"')
    with pytest.raises(SceneError, match=r"\('m_tip'\) key 'point': missing required key"):
        casmbd.loads_scene(scene)


_RIGID = """
[scene]
name = "pendulum"
gravity = [0.0, -9.81]

[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.0833333333333
position = [0.5, 0.0]

[[markers]]
name = "end"
body = "rod"
point = [1.0, 0.0]

[[joints]]
name = "pin"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]

[[forces]]
name = "hold"
type = "torque"
body = "rod"
value = 4.905

[[outputs]]
name = "end_height"
value = 'y("end")'
unit = "m"
"""


def test_rigid_scene_summaries_list_outputs(tmp_path, capsys):
    """Rigid scenes too: the text summaries of ``statics`` and ``simulate`` list the requests.
    A rod (m = 1 kg, L = 1 m) on a pin held horizontal by a torque m g L/2: statics puts the
    end at height 0 (a static equilibrium exactly where it starts, bound 1e-9), the simulation
    keeps it there."""
    path = tmp_path / "pendulum.toml"
    path.write_text(_RIGID)
    assert main(["statics", str(path), "--mode", "vm", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["outputs"]["end_height"] == pytest.approx(0.0, abs=1e-9)
    assert "nodes" not in out
    assert main(["statics", str(path), "--mode", "vm"]) == 0
    text = capsys.readouterr().out
    line = next(line for line in text.splitlines() if line.startswith("  end_height "))
    assert abs(float(line.split()[1])) <= 1e-9 and line.endswith(" m")
    assert main(["simulate", str(path), "--t-end", "0.5", "--steps", "5", "--mode", "vm"]) == 0
    text = capsys.readouterr().out
    line = next(line for line in text.splitlines() if line.startswith("  end_height "))
    final = float(line.split()[2])  # start, end, min, t_min, max, t_max, unit
    assert abs(final) <= 1e-6 and line.endswith(" m")
    assert "node deflection" not in text


def test_statics_sweep_reports_nodes_and_markers(tmp_path, capsys):
    """A statics sweep over the tip load: the node's deflection and the node marker's
    position per point are −P L³/(3 EI) for P = 100 and 200 N (bound 1e-9 relative)."""
    scene = _cantilever().replace("[scene]", "[parameters]\nPl = 100.0\n\n[scene]").replace(
        f"value = [0.0, {-P}]", 'value = [0.0, "-Pl"]')
    path = tmp_path / "cantilever.toml"
    path.write_text(scene)
    deflection, marker = "final:node_deflections[beam@tip.y]", "final:marker.m_tip.position.y"
    assert main(["sweep", str(path), "--analysis", "statics", "--param", "Pl=100,200",
                 "--output", deflection, "--output", marker, "--mode", "vm", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for point in out["points"]:
        exact = -point["parameters"]["Pl"] * L**3 / (3 * EI)
        assert point["outputs"][deflection] == pytest.approx(exact, rel=1e-9)
        assert point["outputs"][marker] == pytest.approx(exact, rel=1e-9)
