"""Readable result plots and units (issue 19, items 3 and 4).

The figures are inspected through matplotlib's objects (``plot_result`` returns the Figure):
every y axis names a unit in brackets, every panel with more than one line has a legend whose
entries are the lines' element names, quaternion components are not drawn (Euler angles are,
equal to ``Result.euler_angles`` unwrapped to 1e-12), joint angles are continuous through ±π in
space and in the plane (natural coordinates: an ``atan2`` too), an empty selection is an
AnalysisError naming the choices and writes no file, and the CLI printouts carry units.
"""

from __future__ import annotations

import math
import pathlib
import re

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import cli
from casmbd.errors import AnalysisError
from casmbd.io.scene import loads_scene
from casmbd.viz import plots

pytest.importorskip("matplotlib")

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"
UNIT = re.compile(r"\[[^\]]+\]$")  # "positions [m]", "torques [N m]"
QUATERNION = re.compile(r"\.e[0-3]$")


_vm = private_cache("cache19", CASMBD_COMPILE="0")


def _simulate(name: str, t_end: float, steps: int, text: str | None = None):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CASMBD_COMPILE", "0")
        path = EXAMPLES / f"{name}.toml"
        mech = loads_scene(text, source=name) if text else casmbd.load_scene(path)
        return casmbd.simulate(mech, t_end=t_end, steps=steps, mode="vm").attach_scene(mech)


@pytest.fixture(scope="module")
def crank3d():
    """Spatial slider-crank, one full crank turn (2π rad/s) in 20 output steps."""
    return _simulate("spatial_slider_crank", 1.0, 20)


@pytest.fixture(scope="module")
def top():
    """Heavy top spinning at about 100 rad/s: 0.2 s in 40 output steps (0.5 rad a step)."""
    return _simulate("heavy_top", 0.2, 40)


@pytest.fixture(scope="module")
def four_bar():
    return _simulate("spatial_four_bar", 0.5, 10)


@pytest.fixture(scope="module")
def crank2d_natural():
    """Planar slider-crank in natural coordinates (angles are atan2 there), one turn."""
    text = (EXAMPLES / "slider_crank.toml").read_text()
    text = text.replace("dimension = 2\n", 'dimension = 2\ncoordinates = "natural"\n', 1)
    return _simulate("slider_crank", 1.0, 20, text)


def _axes(fig):
    return [ax for ax in fig.axes if ax.get_lines()]


@pytest.mark.parametrize("which", ["crank3d", "top", "four_bar", "crank2d_natural"])
def test_every_axis_has_a_unit_and_every_multi_line_panel_a_legend(which, request):
    result = request.getfixturevalue(which)
    fig = plots.plot_result(result)
    names = set(plots.element_names(result)) | {"kinetic", "potential", "total"}
    assert 4 <= len(_axes(fig)) <= 6  # the concise default (issue 32): at most six panels
    for ax in _axes(fig):
        assert UNIT.search(ax.get_ylabel()), f"no unit on {ax.get_ylabel()!r}"
        lines = ax.get_lines()
        if len(lines) > 1:
            legend = ax.get_legend()
            assert legend is not None, f"no legend on {ax.get_ylabel()!r}"
            texts = [t.get_text() for t in legend.get_texts()]
            assert texts == [ln.get_label() for ln in lines]
            for text in texts:  # each entry names its element (body, joint, driver …)
                assert any(n in re.split(r"[ .]", text) for n in names), text
    assert fig.axes[-1].get_xlabel() == "t [s]"


@pytest.fixture(scope="module")
def crank3d_absolute():
    """The spatial slider-crank pinned to absolute coordinates (x, y, z, e0..e3 per body)."""
    text = (EXAMPLES / "spatial_slider_crank.toml").read_text()
    text = text.replace("[scene]\n", '[scene]\ncoordinates = "absolute"\n', 1)
    return _simulate("spatial_slider_crank", 1.0, 20, text=text)


#: panels of the coordinates (q), joints, efforts and reactions: absolute coordinates give the
#: bodies' positions (their quaternions drawn as Euler angles); the automatic choice gives the
#: joint coordinates O.angle [rad] and slide.translation [m] (the spherical joint A's quaternion
#: is drawn through the bodies' Euler angles)
PANELS = {"absolute": ["positions [m]", "Euler angles XYZ [rad]"],
          "auto": ["angles [rad]", "positions [m]", "Euler angles XYZ [rad]"]}


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_units_split_the_panels(request, coordinates):
    crank3d = request.getfixturevalue("crank3d_absolute" if coordinates == "absolute"
                                      else "crank3d")
    fig = plots.plot_result(crank3d, ["coordinates", "joints", "efforts", "reactions"])
    labels = [ax.get_ylabel() for ax in fig.axes]
    # in joint coordinates q's positions [m] are the slide's translation: the joint
    # translations panel repeats them and is omitted, said in one note (issue 32)
    translations = ["joint translations [m]"] if coordinates == "absolute" else []
    assert labels == [*PANELS[coordinates], "joint angles [rad]", *translations,
                      "torques [N m]", "reaction forces [N]", "reaction moments [N m]"]
    if not translations:
        assert "omitted duplicated panels: joint translations (same lines as positions)" \
            in fig.casmbd_notes
    by_label = {ax.get_ylabel(): ax for ax in fig.axes}
    moments = [ln.get_label() for ln in by_label["reaction moments [N m]"].get_lines()]
    assert moments[:3] == ["O.Mx", "O.My", "O.Mz"] and len(moments) == 12
    # the slide joint's translation is drawn in m, exactly the result's column
    slide = plots.plot_result(crank3d, "joints").axes[1].get_lines()[0]
    assert slide.get_label() == "slide"
    np.testing.assert_array_equal(slide.get_ydata(), crank3d.joint("slide")["coordinate"])


@pytest.mark.parametrize("sequence", ["xyz", "zxz"])
def test_quaternions_are_not_plotted_euler_angles_are(top, sequence):
    fig = plots.plot_result(top, "coordinates", euler=sequence)
    labels = [ln.get_label() for ax in fig.axes for ln in ax.get_lines()]
    assert not [lab for lab in labels if QUATERNION.search(lab)]
    assert labels == ["top.x", "top.y", "top.z", "top.phi", "top.theta", "top.psi"]
    euler_ax = fig.axes[1]
    assert euler_ax.get_ylabel() == f"Euler angles {sequence.upper()} [rad]"
    expected = np.unwrap(top.euler_angles("top", sequence), axis=0)
    for k, line in enumerate(euler_ax.get_lines()):
        np.testing.assert_allclose(line.get_ydata(), expected[:, k], rtol=0, atol=1e-12)
        assert np.max(np.abs(np.diff(line.get_ydata()))) < math.pi / 2
    # the top spins: psi turns by more than 2π in 0.2 s and is drawn without a jump
    spin = euler_ax.get_lines()[2].get_ydata()
    assert abs(spin[-1] - spin[0]) > 2 * math.pi


def test_singular_euler_sequence_is_named(four_bar):
    """The four-bar's bodies start at the identity, where Z–X–Z is singular."""
    fig = plots.plot_result(four_bar, "coordinates", euler="zxz")
    assert fig.casmbd_notes and "ZXZ singular for crank" in fig.casmbd_notes[0]
    assert plots.plot_result(four_bar, "coordinates", euler="xyz").casmbd_notes == []


def test_spatial_revolute_angle_is_continuous(crank3d, tmp_path):
    """Driven at 2π rad/s for 1 s: the angle passes +π once; stored, CSV and drawn alike."""
    angle = crank3d.joint("O")["coordinate"]
    assert np.max(np.abs(np.diff(angle))) < math.pi / 2
    np.testing.assert_allclose(angle, 2 * math.pi * crank3d.t, rtol=0, atol=1e-6)
    fig = plots.plot_result(crank3d, "joints")
    line = fig.axes[0].get_lines()[0]
    assert line.get_label() == "O" and fig.axes[0].get_ylabel() == "joint angles [rad]"
    np.testing.assert_allclose(line.get_ydata(), 2 * math.pi * crank3d.t, rtol=0, atol=1e-6)
    csv = np.loadtxt(crank3d.to_csv(tmp_path / "r.csv"), delimiter=",", skiprows=1)
    header = (tmp_path / "r.csv").read_text().splitlines()[0].split(",")
    column = csv[:, header.index("joint_positions[O]")]
    assert np.max(np.abs(np.diff(column))) < math.pi / 2


def test_planar_angles_are_continuous(crank2d_natural):
    result = crank2d_natural
    assert any(name.endswith(".ux") for name in result.names["coordinates"])
    angle = result.joint("O")["coordinate"]
    np.testing.assert_allclose(angle, 2 * math.pi * result.t, rtol=0, atol=1e-6)
    crank = result.body("crank")["angle"]
    assert np.max(np.abs(np.diff(crank))) < math.pi / 2
    np.testing.assert_allclose(crank, 2 * math.pi * result.t, rtol=0, atol=1e-6)
    fig = plots.plot_result(result, "coordinates")
    by_label = {ax.get_ylabel(): ax for ax in fig.axes}
    assert set(by_label) == {"positions [m]", "angles [rad]"}
    drawn = {ln.get_label(): ln.get_ydata() for ln in by_label["angles [rad]"].get_lines()}
    assert sorted(drawn) == ["crank.angle", "rod.angle", "slider.angle"]  # not ux, uy
    assert np.max(np.abs(np.diff(drawn["crank.angle"]))) < math.pi / 2


def test_empty_selection_is_an_error_naming_the_choices(top, crank3d, tmp_path):
    out = tmp_path / "x.png"
    with pytest.raises(AnalysisError, match=r"plot kind 'joints': .* no joint coordinates.*"
                                            r"kinds it can show: coordinates, reactions, "
                                            r"energy, drift"):
        plots.plot_result(top, "joints", out=out)
    with pytest.raises(AnalysisError, match=r"unknown plot kind\(s\) 'angles' \(choices: "
                                            r"coordinates, joints, efforts"):
        plots.plot_result(top, "angles", out=out)
    with pytest.raises(AnalysisError, match=r"unknown element\(s\) 'lid' \(choices: top, tip\)"):
        plots.plot_result(top, out=out, elements=["lid"])
    with pytest.raises(AnalysisError, match=r"plot kind 'joints': nothing of rod to show"):
        plots.plot_result(crank3d, "joints", out=out, elements=["rod"])
    with pytest.raises(AnalysisError, match=r"unknown Euler sequence 'yxy' \(choices: xyz, "
                                            r"zxz\)"):
        plots.plot_result(top, out=out, euler="yxy")
    assert not out.exists()
    # a selection keeps only the named elements' lines
    fig = plots.plot_result(crank3d, "reactions", elements=["slide"])
    assert [ln.get_label() for ln in fig.axes[0].get_lines()] == ["slide.Fx", "slide.Fy",
                                                                  "slide.Fz"]


def test_cli_plot_empty_selection_exits_1_without_a_file(top, tmp_path, capsys):
    res = tmp_path / "top.npz"
    top.save(res)
    out = tmp_path / "fig.png"
    for extra in (["--kind", "joints"], ["--kind", "speed"], ["--element", "lid"]):
        assert cli.main(["plot", str(res), "--out", str(out), *extra]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ")
        assert "coordinates" in err[0] or "choices: top, tip" in err[0]
        assert not out.exists()
    assert cli.main(["plot", str(res), "--out", str(out), "--euler", "zxz"]) == 0
    assert out.stat().st_size > 1000


def test_energy_change_is_not_called_drift_when_something_does_work(top, tmp_path):
    crane = _simulate("crane", 0.5, 10)
    fig = plots.plot_result(crane, "energy")
    change = fig.axes[1]
    assert change.get_ylabel() == "total − total(0) [J]"
    label = change.get_lines()[0].get_label()
    assert "damper 'hinge_damper'" in label and "not a drift" in label
    # the heavy top is conservative: the change of its total energy is numerical drift
    fig = plots.plot_result(top, "energy")
    assert fig.axes[1].get_lines()[0].get_label() == "drift of the total"
    # a driven mechanism: the driver's work
    assert "driver 'crank_speed'" in plots.plot_result(_simulate(
        "slider_crank", 0.2, 4), "energy").axes[1].get_lines()[0].get_label()


def _cli_text(capsys, *argv: str) -> str:
    assert cli.main(list(argv)) == 0, capsys.readouterr().err
    return capsys.readouterr().out


def test_cli_printouts_carry_units(capsys):
    text = _cli_text(capsys, "simulate", str(EXAMPLES / "crane.toml"), "--t-end", "0.5",
                     "--steps", "5", "--mode", "vm")
    assert re.search(r"body cart +x \[[^\]]+\] m  y \[[^\]]+\] m  angle \[[^\]]+\] rad", text)
    assert re.search(r"joint rail +coordinate \[[^\]]+\] m\n", text)
    assert re.search(r"joint hinge +coordinate \[[^\]]+\] rad\n", text)
    assert re.search(r"energy: start \S+ J, end \S+ J \(change \S+ J: work of damper "
                     r"'hinge_damper', not numerical drift\)", text)
    text = _cli_text(capsys, "simulate", str(EXAMPLES / "double_pendulum.toml"), "--t-end",
                     "0.2", "--steps", "4", "--mode", "vm")
    assert re.search(r"\(drift \S+ J\)", text)
    text = _cli_text(capsys, "inverse", str(EXAMPLES / "slider_crank_inverse.toml"),
                     "--t-end", "0.2", "--steps", "4", "--mode", "vm")
    assert re.search(r"driver slider_path +effort \[[^\]]+\] N\n", text)
    assert re.search(r"actuator crank_motor effort \[[^\]]+\] N m\n", text)
    text = _cli_text(capsys, "statics", str(EXAMPLES / "spatial_four_bar.toml"), "--mode",
                     "vm")
    assert re.search(r"joint crank_bearing coordinate \S+ rad  reaction Fx \S+ N  Fy \S+ N  "
                     r"Fz \S+ N  Mx \S+ N m  My \S+ N m  Mz \S+ N m", text)
    assert re.search(r"body crank +x \S+ m  y \S+ m  z \S+ m", text)


def test_cli_energy_change_names_what_changes_it(capsys, tmp_path):
    """The simulate summary names impact losses (with the count) and does not call a damper
    whose damping is a parameter set to 0 a source of work: that mechanism is conservative and
    its change is drift."""
    text = _cli_text(capsys, "simulate", str(EXAMPLES / "bouncing_ball.toml"), "--t-end",
                     "1.5", "--steps", "15", "--mode", "vm")
    assert re.search(r"change \S+ J: impact losses at contact 'floor' \(2 impacts, restitution "
                     r"0\.8\), not numerical drift", text)
    scene = tmp_path / "spring.toml"
    scene.write_text("""
[scene]
name = "oscillator"
dimension = 2
gravity = [0.0, 0.0]
[parameters]
k = 100.0
c = 0.0
[[bodies]]
name = "block"
mass = 1.0
inertia = 0.1
position = [1.1, 0.0]
[[joints]]
name = "rail"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [1.1, 0.0]
axis = [1.0, 0.0]
[[forces]]
name = "spring"
type = "spring_damper"
body1 = "ground"
point1 = [0.0, 0.0]
body2 = "block"
point2 = [1.1, 0.0]
stiffness = "k"
damping = "c"
free_length = 1.0
""")
    text = _cli_text(capsys, "simulate", str(scene), "--t-end", "0.5", "--steps", "5",
                     "--mode", "vm")
    assert re.search(r"\(drift \S+ J\)", text), text
