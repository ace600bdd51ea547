"""Plots that show what matters (issue 32, item 2).

The default figure of every shipped example and analysis has at most six panels, each with a
line of finite data, a unit and no legend label twice, and no two panels drawing the same
lines; panels of rounding noise and empty panels are left out on one printed line each (the
noise judged against the problem's scale: a moment against the largest force × the
mechanism's size); flexible bodies get their modal coordinates and node deflections (equal to
the result's columns); requests are drawn under their own names and units; impact losses and
friction work are labelled as such; angles in rad reported by force elements are unwrapped
like joint angles.  Figures are inspected through matplotlib's objects (Agg), not images.
"""

from __future__ import annotations

import importlib.util
import math
import pathlib
import re
import sys
import warnings

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import cli
from casmbd.io.scene import loads_scene
from casmbd.viz import plot_select, plots

pytest.importorskip("matplotlib")

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"
UNIT = re.compile(r"\[[^\]]+\]$")
T_END, STEPS = 0.3, 30

_vm = private_cache("cache32plots", CASMBD_COMPILE="0")

#: analyses beyond ``simulate`` of the examples whose drivers fix every degree of freedom
_INVERSE = ("slider_crank_inverse", "four_bar", "spatial_four_bar", "cardan_shaft",
            "flexible_slider_crank", "spinup_beam", "crank_friction", "slider_crank",
            "spatial_slider_crank")
_KINEMATICS = ("slider_crank", "four_bar", "spatial_slider_crank")
#: the examples without a scene file: the URDF arm, the delta robot and two-link arm scripts
_SCRIPTS = [("ur5_arm", "urdf"), ("delta_robot", "script"), ("two_link_arm", "script")]
CASES = ([(p.stem, "simulate") for p in sorted(EXAMPLES.glob("*.toml"))]
         + [(n, "inverse") for n in _INVERSE] + [(n, "kinematics") for n in _KINEMATICS]
         + _SCRIPTS)

_RESULTS: dict = {}


def _run(name: str, analysis: str = "simulate", t_end: float = T_END, steps: int = STEPS,
         text: str | None = None):
    key = (name, analysis, t_end, steps, text)
    if key not in _RESULTS:
        with pytest.MonkeyPatch.context() as mp:
            mp.setenv("CASMBD_COMPILE", "0")
            mech = loads_scene(text, source=name) if text else \
                casmbd.load_scene(EXAMPLES / f"{name}.toml")
            run = {"simulate": casmbd.simulate, "inverse": casmbd.inverse_dynamics,
                   "kinematics": casmbd.kinematics}[analysis]
            _RESULTS[key] = run(mech, t_end=t_end, steps=steps, mode="vm").attach_scene(mech)
    return _RESULTS[key]


def _script(name: str):
    """A result of an example without a scene file, and its mechanism."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CASMBD_COMPILE", "0")
        if name == "ur5_arm":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # its <visual> meshes are not read
                mech = casmbd.load_urdf(EXAMPLES / "ur5_arm.urdf")
            return casmbd.simulate(mech, t_end=0.2, steps=10, mode="vm"), mech
        spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        mp.setitem(sys.modules, spec.name, module)
        spec.loader.exec_module(module)
        if name == "delta_robot":
            mech = module.delta_robot(path=module.gate_path)
            return casmbd.inverse_dynamics(mech, t_end=0.2, steps=10, mode="vm"), mech
        mech = module.arm(True)
        return casmbd.inverse_dynamics(mech, t_end=0.5, steps=20, mode="vm"), mech


@pytest.mark.parametrize(("name", "analysis"), CASES, ids=[f"{n}-{a}" for n, a in CASES])
def test_default_figure_is_concise_and_full(name, analysis):
    if analysis in ("urdf", "script"):
        result, mech = _script(name)
        fig = plots.plot_result(result, mechanism=mech)
    else:
        fig = plots.plot_result(_run(name, analysis))
    assert 1 <= len(fig.axes) <= plot_select.MAX_PANELS, fig.casmbd_panels
    seen = []
    for ax in fig.axes:
        assert UNIT.search(ax.get_ylabel()), ax.get_ylabel()
        drawn = [ln for ln in ax.get_lines() if not ln.get_label().startswith("_")]
        assert drawn, f"empty panel {ax.get_ylabel()!r}"
        assert any(np.isfinite(ln.get_ydata()).any() for ln in drawn), ax.get_ylabel()
        labels = [ln.get_label() for ln in drawn]
        assert len(labels) == len(set(labels)), f"{ax.get_ylabel()}: {labels}"
        if ax.get_legend() is not None:
            texts = [t.get_text() for t in ax.get_legend().get_texts()]
            assert len(texts) == len(set(texts)), texts
        # no panel of exact zeros, none repeating the lines of an earlier panel
        assert max(np.nanmax(np.abs(ln.get_ydata())) for ln in drawn) > 0, ax.get_ylabel()
        data = sorted(tuple(np.round(ln.get_ydata(), 12)) for ln in drawn)
        assert data not in seen, f"{ax.get_ylabel()} repeats an earlier panel"
        seen.append(data)
    assert fig.axes[-1].get_xlabel() == "t [s]"


def test_panel_counts_of_the_old_default_are_cut():
    """The slider-crank's simulation drew 11 panels (q's angles and positions, the joints'
    angles and translations, the torque, reaction forces and moments, two energy panels, two
    constraint panels); the default keeps the joints, the torque, the energies and max |C|."""
    fig = plots.plot_result(_run("slider_crank"))
    assert fig.casmbd_panels == ["joint angles [rad]", "joint translations [m]",
                                 "torques [N m]", "energy [J]", "total − total(0) [J]",
                                 "max |C| [m, rad or 1]"]
    assert fig.casmbd_notes[-2].startswith("not drawn by default (at most 6 panels): max "
                                           "|C_q v + C_t|")
    assert fig.casmbd_notes[-1] == "more with --what: drift, coordinates, reactions"
    every = plots.plot_result(_run("slider_crank"), list(plots.available_kinds(
        _run("slider_crank"))))
    assert len(every.axes) > 6  # everything is still there by --what


def test_noise_panel_is_dropped_with_one_line(tmp_path, capsys):
    """The flexible slider-crank's planar revolute reaction moments are rounding noise
    (|M| ≤ 1e-14 N m beside forces of ~2000 N on a 0.45 m mechanism: 1e-9 × F L ≈ 1e-6 N m)."""
    result = _run("flexible_slider_crank")
    moments = result.arrays["joint_reactions"][:, :, 2]
    forces = np.abs(result.arrays["joint_reactions"][:, :, :2]).max()
    size = np.abs(result.arrays["body_positions"]).max()
    assert np.abs(moments).max() <= plot_select.NOISE * forces * size  # independent check
    fig = plots.plot_result(result, "reactions")
    assert fig.casmbd_panels == ["reaction forces [N]"]
    noise = [n for n in fig.casmbd_notes if "rounding noise" in n]
    assert len(noise) == 1 and "reaction moments (max" in noise[0]
    # a panel of real values survives next to it: the spin-up beam's tiny hub angle
    # (1.8e-4 rad) is motion, not noise; its body frame x, y (≤ 1e-27 m) are noise
    beam = _run("spinup_beam", t_end=0.5, steps=50)
    fig = plots.plot_result(beam, "coordinates")
    assert "angles [rad]" in fig.casmbd_panels and "positions [m]" not in fig.casmbd_panels
    # the CLI prints the line once
    saved = tmp_path / "beam.npz"
    beam.save(saved)
    assert cli.main(["plot", str(saved), "--what", "coordinates", "--out",
                     str(tmp_path / "b.png")]) == 0
    out = capsys.readouterr().out
    assert len([ln for ln in out.splitlines() if "rounding noise" in ln]) == 1
    assert re.search(r"note: omitted 1 panel of rounding noise \(every value ≤ 1e-09 × the "
                     r"problem's scale of its unit\): positions \(max \S+ m against", out)


def test_empty_panels_are_omitted_with_the_reason(tmp_path, capsys):
    """max |C| of the bouncing ball (no constraint) is 0 at every output time: omitted and
    said; the figure keeps what is there."""
    fig = plots.plot_result(_run("bouncing_ball"))
    assert "max |C| [m, rad or 1]" not in fig.casmbd_panels
    empty = [n for n in fig.casmbd_notes if n.startswith("omitted") and "empty" in n]
    assert len(empty) == 1
    assert "max |C| (zero at every output time: no constraint equations)" in empty[0]
    # reactions of NaN (a run that did not compute them) are said to be so
    result = _run("four_bar")
    result = casmbd.results.Result(result.kind, result.t,
                                   {**result.arrays, "joint_reactions": np.full_like(
                                       result.arrays["joint_reactions"], np.nan)},
                                   result.names, result.stats, result.scene)
    fig = plots.plot_result(result, ["joints", "reactions"])
    assert fig.casmbd_panels == ["joint angles [rad]"]
    assert any("reaction forces (not a number at every output time" in n
               for n in fig.casmbd_notes)


def test_flexible_body_has_modal_and_deflection_panels():
    beam = _run("spinup_beam", t_end=0.5, steps=50)
    fig = plots.plot_result(beam)
    by_label = {ax.get_ylabel(): ax for ax in fig.axes}
    modal = by_label["modal coordinates η [kg^½ m]"]
    names = beam.names["coordinates"]
    for line in modal.get_lines():
        np.testing.assert_array_equal(line.get_ydata(),
                                      beam.arrays["q"][:, names.index(line.get_label())])
    assert [ln.get_label() for ln in modal.get_lines()] == [f"beam.eta{k}" for k in range(1, 5)]
    nodes = {ln.get_label(): ln.get_ydata()
             for ln in by_label["node deflections Φ_i η [m]"].get_lines()}
    np.testing.assert_array_equal(nodes["beam@tip.y"], beam.node("beam@tip")["deflection"][:, 1])
    assert np.abs(nodes["beam@tip.y"]).max() > 1e-4  # the beam bends as it spins up
    # the body angle is drawn once (it was drawn twice: q's and the body angle again)
    angles = [ln.get_label() for ax in plots.plot_result(beam, "coordinates").axes
              for ln in ax.get_lines()]
    assert angles.count("beam.angle") == 1
    with pytest.raises(casmbd.AnalysisError, match="no flexible body"):
        plots.plot_result(_run("four_bar"), "flexible")


def test_requests_are_plotted_under_their_names():
    result = _run("pd_pendulum")
    fig = plots.plot_result(result, "outputs")
    by_label = {ax.get_ylabel(): ax for ax in fig.axes}
    assert {"tip_height [m]", "tracking_error [rad]", "slider_energy [J]", "pd.value [N m]",
            "cubic.value [N]"} == set(by_label)
    line = by_label["tip_height [m]"].get_lines()[0]
    np.testing.assert_array_equal(line.get_ydata(), result.output("tip_height"))
    assert by_label["tip_height [m]"].get_legend() is None  # the axis names it
    # the default figure draws the requests too
    assert "tip_height [m]" in plots.plot_result(result).casmbd_panels


def test_impact_losses_and_friction_work_are_not_drift():
    ball = _run("bouncing_ball", t_end=0.6, steps=30)  # first impact at sqrt(2 h0 / g) = 0.45 s
    assert [e["kind"] for e in ball.events] == ["impact"]
    notes = plots.plot_result(ball).casmbd_notes
    assert any("contact forces (zero at every output time; impacts are impulses at events (1 "
               "here), not forces on the output grid)" in n for n in notes)
    label = plots.plot_result(ball, "energy").axes[1].get_lines()[0].get_label()
    assert label == ("energy change: impact losses at contact 'floor' (1 impact, "
                     "restitution 0.8) (not a drift)")
    # the loss is the closed form ½ (1 − e²) m v² at the impact: 0.36 × m g h0 = 3.53 J
    total = ball["total_energy"]
    assert total[-1] - total[0] == pytest.approx(-0.36 * 9.81 * 1.0, rel=1e-6)
    label = plots.plot_result(_run("crank_friction"), "energy").axes[1].get_lines()[0]
    assert "friction work of 'A.friction'" in label.get_label()
    assert "drift" not in label.get_label().replace("not a drift", "")


SPIN = """
[scene]
name = "spinning_damper"
dimension = 3
coordinates = "absolute"
gravity = [0.0, 0.0, -9.81]

[[bodies]]
name = "rotor"
mass = 1.0
inertia = [0.01, 0.01, 0.01]
position = [0.0, 0.0, 0.0]
angular_velocity = [20.0, 0.0, 0.0]

[[joints]]
name = "bearing"
type = "revolute"
body1 = "ground"
body2 = "rotor"
point = [0.0, 0.0, 0.0]
axis = [1.0, 0.0, 0.0]

[[forces]]
name = "drag"
type = "rotational_spring_damper"
joint = "bearing"
damping = 0.001
"""


def test_rotational_damper_angle_is_unwrapped_like_the_joint_angle():
    """A rotor at 20 rad/s for 0.5 s turns 10 rad (passes +π and 3π); the damper reports its
    joint's angle (an atan2 in absolute coordinates): continuous and equal to the joint's."""
    result = _run("spinning_damper", t_end=0.5, steps=50, text=SPIN)
    angle = result.force("drag")["angle"]
    joint = result.joint("bearing")["coordinate"]
    assert np.max(np.abs(np.diff(angle))) < math.pi / 2
    np.testing.assert_allclose(angle, joint, rtol=0, atol=1e-12)
    # c = 0.001 N m s on J = 0.01 kg m²: ω = 20 exp(−0.1 t), φ = 200 (1 − exp(−0.1 t))
    np.testing.assert_allclose(angle, 200 * (1 - np.exp(-0.1 * result.t)), rtol=0,
                               atol=1e-6)
    fig = plots.plot_result(result, "outputs")
    line = next(ln for ax in fig.axes for ln in ax.get_lines()
                if ln.get_label() == "drag.angle")
    assert np.max(np.abs(np.diff(line.get_ydata()))) < math.pi / 2
