"""Requests (``[[outputs]]``) and force-element reports on result grids (issue 24 item 3).

Every request is compared with the same measure computed by hand from the result's q and v
(absolute coordinates: q = [x_G, y_G, θ] of each body; tolerance 1e-12, the same floating-point
operations in another order); the spring-damper's length, rate and force, the expression
force's value and joint friction's force likewise.  Requests appear on the grid of every
analysis that has one (simulation, kinematics, inverse dynamics), in ``--json``
(``"outputs"``, ``"forces"``), in CSV headers, in npz files (read back equal) and as the plot
kind ``outputs``.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import casmbd
from casmbd.cli import main
from casmbd.errors import SceneError
from casmbd.viz.plots import available_kinds, element_names, plot_result

SCENE = """
[scene]
name = "requested"
dimension = 2
gravity = [0.0, -9.81]
coordinates = "absolute"

[parameters]
k = 30.0
L = 1.0

[[bodies]]
name = "rod"
mass = 2.0
inertia = 0.1
position = [0.5, 0.0]

[[markers]]
name = "tip"
body = "rod"
point = [1.0, 0.0]

[[markers]]
name = "anchor"
body = "ground"
point = [1.0, 1.0]

[[joints]]
name = "J"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]

[[forces]]
name = "spring"
type = "spring_damper"
body1 = "ground"
body2 = "rod"
point1 = [1.0, 1.0]
point2 = [1.0, 0.0]
stiffness = "k"
damping = 0.4
free_length = 0.8

[[forces]]
name = "friction"
type = "joint_friction"
joint = "J"
damping = 0.05

[[forces]]
name = "pd"
type = "expression"
joint = "J"
value = "-2*angle('J') - 0.1*rate('J')"

[[outputs]]
name = "tip_x"
value = 'x("tip")'
unit = "m"

[[outputs]]
name = "tip_vy"
value = 'vy("tip")'
unit = "m/s"

[[outputs]]
name = "stretch"
value = 'distance("anchor", "tip") - 0.8'
unit = "m"

[[outputs]]
name = "tip_speed"
value = 'speed("tip")'

[[outputs]]
name = "phi"
value = 'angle_of("rod") + 0*time'
unit = "rad"

[[outputs]]
name = "omega"
value = 'omega_of("rod")'

[[outputs]]
name = "smooth"
value = 'step(angle("J"), -1, 0, 0, L) * rate("J") + dead_zone(t, 0.1, 0.2)'
"""


def _hand(res):
    """The requested measures from q, v (absolute coordinates of the rod) and t."""
    x, y, th = res["q"].T
    vx, vy, om = res["v"].T
    tip = np.column_stack([x + 0.5 * np.cos(th), y + 0.5 * np.sin(th)])
    tip_v = np.column_stack([vx - 0.5 * np.sin(th) * om, vy + 0.5 * np.cos(th) * om])
    d = tip - np.array([1.0, 1.0])
    length = np.hypot(d[:, 0], d[:, 1])
    rate = np.sum(d * tip_v, axis=1) / length
    delta = np.clip(th + 1.0, 0.0, 1.0)
    step = delta**2 * (3 - 2 * delta)
    t = res.t
    zone = np.where(t > 0.2, t - 0.2, np.where(t < 0.1, t - 0.1, 0.0))
    return {"tip_x": tip[:, 0], "tip_vy": tip_v[:, 1], "stretch": length - 0.8,
            "tip_speed": np.hypot(*tip_v.T), "phi": th, "omega": om,
            "smooth": step * om + zone}, (length, rate, 30.0 * (length - 0.8) + 0.4 * rate)


@pytest.fixture(scope="module")
def simulated():
    mech = casmbd.loads_scene(SCENE)
    return mech, casmbd.simulate(mech, 1.0, 20, rtol=1e-10)


def test_requests_equal_the_measures_computed_by_hand(simulated) -> None:
    _, res = simulated
    hand, (length, rate, tension) = _hand(res)
    assert res.names["outputs"] == list(hand)
    assert res.arrays["outputs"].shape == (21, len(hand))
    for name, values in hand.items():
        np.testing.assert_allclose(res.output(name), values, rtol=0, atol=1e-12, err_msg=name)
    spring = res.force("spring")
    np.testing.assert_allclose(spring["length"], length, rtol=0, atol=1e-12)
    np.testing.assert_allclose(spring["rate"], rate, rtol=0, atol=1e-12)
    np.testing.assert_allclose(spring["force"], tension, rtol=0, atol=1e-10)
    om, th = res["v"][:, 2], res["q"][:, 2]
    np.testing.assert_allclose(res.force("friction")["force"], -0.05 * om, atol=1e-12)
    np.testing.assert_allclose(res.force("pd")["value"], -2 * th - 0.1 * om, atol=1e-12)
    assert res.names["force_outputs"] == ["spring.length", "spring.rate", "spring.force",
                                          "friction.force", "pd.value"]
    assert res.names["force_output_units"] == ["m", "m/s", "N", "N m", "N m"]
    assert res.names["output_units"][:3] == ["m", "m/s", "m"]


def test_json_csv_npz_and_plot(simulated, tmp_path) -> None:
    _, res = simulated
    data = res.to_json()
    assert list(data["outputs"]) == res.names["outputs"]
    np.testing.assert_array_equal(data["outputs"]["tip_x"], res.output("tip_x"))
    assert data["forces"]["spring"].keys() == {"length", "rate", "force"}
    np.testing.assert_array_equal(data["forces"]["pd"]["value"], res.force("pd")["value"])
    labels = [label for label, _ in res.csv_columns()]
    assert "outputs[tip_speed]" in labels and "force_outputs[spring.force]" in labels
    loaded = casmbd.load_result(res.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(loaded.output("omega"), res.output("omega"))
    assert loaded.names["force_outputs"] == res.names["force_outputs"]
    assert "outputs" in available_kinds(res)
    fig = plot_result(res, "outputs", out=tmp_path / "outputs.png")
    ylabels = [ax.get_ylabel() for ax in fig.axes]
    assert any(label.endswith("[m]") for label in ylabels)
    assert any(label.endswith("[N m]") for label in ylabels)
    fig = plot_result(res, "outputs", elements=["spring", "tip_x"])  # by element name
    assert sorted(line.get_label() for ax in fig.axes for line in ax.get_lines()) == [
        "spring.force", "spring.length", "spring.rate", "tip_x"]
    assert {"spring", "pd", "tip_x"} <= set(element_names(res))


def test_kinematics_and_inverse_dynamics_report_requests(tmp_path) -> None:
    driven = SCENE + """
[[drivers]]
name = "turn"
joint = "J"
position = "0.3*t"
"""
    mech = casmbd.loads_scene(driven)
    for res in (casmbd.kinematics(mech, 1.0, 10), casmbd.inverse_dynamics(mech, 1.0, 10)):
        hand, (_, _, tension) = _hand(res)
        for name, values in hand.items():
            np.testing.assert_allclose(res.output(name), values, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(res.output("omega"), 0.3, atol=1e-12)
        np.testing.assert_allclose(res.force("spring")["force"], tension, atol=1e-10)
    # the CLI's npz file carries them too
    path = tmp_path / "driven.toml"
    path.write_text(driven)
    out = tmp_path / "out.npz"
    assert main(["kinematics", str(path), "--t-end", "1", "--steps", "4", "--out",
                 str(out)]) == 0
    loaded = casmbd.load_result(out)
    np.testing.assert_allclose(loaded.output("omega"), 0.3, atol=1e-12)


def test_cli_json_has_outputs_and_forces(tmp_path, capsys) -> None:
    path = tmp_path / "scene.toml"
    path.write_text(SCENE)
    code = main(["simulate", str(path), "--t-end", "0.2", "--steps", "4", "--json"])
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["outputs"]) == {"tip_x", "tip_vy", "stretch", "tip_speed", "phi", "omega",
                                    "smooth"}
    assert len(data["outputs"]["tip_x"]) == 5
    assert math.isclose(data["outputs"]["tip_x"][0], 1.0, abs_tol=1e-12)
    assert data["forces"]["friction"] == {"force": data["forces"]["friction"]["force"]}


def test_bad_requests_name_the_entry_and_key() -> None:
    for value, message in (('x("nowhere")', "unknown marker or body 'nowhere'"),
                           ('rate("K")', "unknown joint 'K'"),
                           ('distance("tip")', "takes 2 quoted names, got 1"),
                           ('speed("tip") + q', "unknown name 'q'")):
        scene = SCENE + f"\n[[outputs]]\nname = \"bad\"\nvalue = '{value}'\n"
        with pytest.raises(SceneError) as info:
            casmbd.loads_scene(scene)
        assert "[[outputs]] entry 8 ('bad') key 'value'" in str(info.value), str(info.value)
        assert message in str(info.value)
    with pytest.raises(SceneError, match=r"\[\[outputs\]\] entry 8 \('tip_x'\).*duplicate"):
        casmbd.loads_scene(SCENE + "\n[[outputs]]\nname = \"tip_x\"\nvalue = 1\n")
    with pytest.raises(SceneError, match="key 'units': unknown key"):
        casmbd.loads_scene(SCENE + "\n[[outputs]]\nname = \"u\"\nvalue = 1\nunits = \"m\"\n")


def test_python_api_requests() -> None:
    mech = casmbd.loads_scene(SCENE)
    mech.add_output("height", 'y("tip")', unit="m")
    res = casmbd.simulate(mech, 0.2, 4)
    _, y, th = res["q"].T
    np.testing.assert_allclose(res.output("height"), y + 0.5 * np.sin(th), atol=1e-12)


def test_statics_reports_requests_and_forces():
    """Statics reports the requests and force reports at the equilibrium (JSON "outputs" and
    "forces"): a rod (m = 1, L = 1) pinned at an end with a torsional spring k = 20 N m/rad
    rests where k θ = −m g (L/2) cos θ."""
    scene = """
[scene]
name = "rod_spring"
gravity = [0.0, -9.81]
[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.0833333333333333
position = [0.5, 0.0]
[[joints]]
name = "pin"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
[[forces]]
name = "spring"
type = "rotational_spring_damper"
joint = "pin"
stiffness = 20.0
[[outputs]]
name = "tip_height"
value = 'y("tip")'
[[markers]]
name = "tip"
body = "rod"
point = [1.0, 0.0]
"""
    theta = brentq(lambda th: 20.0 * th + 9.81 * 0.5 * math.cos(th), -1.5, 0.0)
    data = casmbd.static_equilibrium(casmbd.loads_scene(scene)).to_json()
    assert data["outputs"]["tip_height"] == pytest.approx(math.sin(theta), abs=1e-10)
    assert data["forces"]["spring"]["angle"] == pytest.approx(theta, abs=1e-10)
    # the reported moment resists an increase of the angle: k θ
    assert data["forces"]["spring"]["moment"] == pytest.approx(20.0 * theta, abs=1e-9)
