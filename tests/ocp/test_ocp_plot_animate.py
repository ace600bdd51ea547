"""OCP solutions through ``plot`` and ``animate``; the OCP figure with one unit per panel
(issue 30, item 4g: ``casmbd plot``/``animate`` on a saved OCP solution failed with "'meta'
has no str 'kind'"; ``casmbd ocp --plot`` labelled its axes "coordinates" and "controls").

A saved solution is a result file of kind "ocp" (:meth:`OcpSolution.to_result`) with the
controls per interval beside it; its body positions are checked against the double
pendulum's forward kinematics in closed form."""

from __future__ import annotations

import json
import pathlib

import matplotlib
import numpy as np
import pytest
from conftest import private_cache

from casmbd import cli
from casmbd.io.ocp_table import load_ocp
from casmbd.ocp.solution import OcpSolution
from casmbd.results import load
from casmbd.viz.plots import plot_result

matplotlib.use("Agg")

ROOT = pathlib.Path(__file__).resolve().parents[2]
SWINGUP = ROOT / "ocp" / "double_pendulum_swingup.toml"
L = 1.0  # the scene's rod length

_cache = private_cache()


@pytest.fixture(scope="module")
def solution():
    ocp = load_ocp(SWINGUP)
    ocp.intervals, ocp.subintervals, ocp.compile = 10, 1, False
    sol = ocp.solve()
    assert sol.success
    return sol


@pytest.fixture(scope="module")
def saved(solution, tmp_path_factory):
    out = tmp_path_factory.mktemp("ocp") / "sol.npz"
    solution.save(out)
    return out


def test_saved_solution_is_a_result_with_closed_form_body_positions(solution, saved):
    """r_upper = L/2 e(θ₁), r_lower = L e(θ₁) + L/2 e(θ₁ + θ₂), tip = L e(θ₁) + L e(θ₁ + θ₂)
    with e(φ) = (cos φ, sin φ), from the joint angles at every node, to 1e-12; the controls per
    node are the interval's; the file still loads as an OcpSolution."""
    res = load(saved)
    assert res.kind == "ocp" and np.array_equal(res.t, solution.t)
    th1, th2 = solution.q[:, 0], solution.q[:, 1]
    assert res.names["coordinates"][:2] == solution.coordinate_names[:2]

    def e(phi):
        return np.column_stack([np.cos(phi), np.sin(phi)])

    upper, lower = 0.5 * L * e(th1), L * e(th1) + 0.5 * L * e(th1 + th2)
    bodies = res.names["bodies"]
    pos = res["body_positions"]
    assert np.max(np.abs(pos[:, 2 * bodies.index("upper"):][:, :2] - upper)) < 1e-12
    assert np.max(np.abs(pos[:, 2 * bodies.index("lower"):][:, :2] - lower)) < 1e-12
    assert np.max(np.abs(res.marker("tip")["position"]
                         - (L * e(th1) + L * e(th1 + th2)))) < 1e-12
    u = res["actuator_inputs"]
    assert np.array_equal(u[:-1], solution.u)  # one element per interval: node k, interval k
    assert np.array_equal(u[-1], solution.u[-1])
    back = OcpSolution.load(saved)
    assert np.array_equal(back.q, solution.q) and np.array_equal(back.u, solution.u)
    assert back.controls == solution.controls and back.stats["objective"] == solution.objective


def test_plot_and_animate_of_a_saved_solution(saved, tmp_path, capsys):
    for argv, out in ((["plot", str(saved)], tmp_path / "plot.png"),
                      (["animate", str(saved)], tmp_path / "anim.gif"),
                      (["animate", str(saved)], tmp_path / "frame.png")):
        status = cli.main([*argv, "--out", str(out), "--json"])
        captured = capsys.readouterr()
        assert status == 0, captured.err
        assert out.is_file() and out.stat().st_size > 1000, out
        json.loads(captured.out)


def test_plot_panels_carry_units(solution, tmp_path, capsys):
    """The OCP figure (``ocp --plot``, and ``plot`` of the saved file) has one unit per
    panel: the joint angles in rad, the actuators' torques in N m."""
    fig = plot_result(solution.to_result(), ["coordinates", "efforts"])
    labels = [ax.get_ylabel() for ax in fig.axes if ax.get_ylabel()]
    assert labels == ["angles [rad]", "controls: torques [N m]"], labels
    figure = tmp_path / "ocp.png"
    status = cli.main(["ocp", str(SWINGUP), "--intervals", "10", "--mode", "vm", "--no-replay",
                       "--plot", str(figure)])
    assert status == 0, capsys.readouterr().err
    assert figure.is_file() and figure.stat().st_size > 1000


def test_default_ocp_figure_has_states_controls_and_bounds(solution, saved):
    """Issue 32: the OCP figure names its units on every axis, draws the states (q and q̇)
    and the controls in separate panels, the controls piecewise constant per interval, and the
    control bounds of [ocp.controls] (tau1, tau2 in [-50, 50] N m) as dashed lines."""
    for result in (solution.to_result(), load(saved)):
        fig = plot_result(result)
        labels = [ax.get_ylabel() for ax in fig.axes]
        assert labels == ["states: joint angles [rad]", "states: joint rates [rad/s]",
                          "controls: torques [N m]"], labels
        assert all(label.endswith("]") for label in labels)
        controls = fig.axes[2]
        drawn = {ln.get_label(): ln for ln in controls.get_lines()}
        assert {"control tau1", "control tau2"} <= set(drawn)
        assert drawn["control tau1"].get_drawstyle() == "steps-post"
        np.testing.assert_array_equal(drawn["control tau1"].get_ydata(),
                                      solution.node_controls()[:, 0])
        bounds = sorted(float(ln.get_ydata()[0]) for ln in controls.get_lines()
                        if ln.get_label().startswith("_bound"))
        assert bounds == [-50.0, 50.0]
        legend = [t.get_text() for t in controls.get_legend().get_texts()]
        assert legend == ["control tau1", "control tau2"]  # bounds: one note, no entries
        # the double pendulum in joint coordinates has no constraint: max |C| is said empty
        assert any("max |C| (zero at every output time" in n for n in fig.casmbd_notes)


def test_solution_file_of_the_older_layout_still_plots(solution, tmp_path, capsys):
    """A file written before issue 30 (top-level t, q, v, u and meta without 'kind') loads as
    an OcpSolution and plots its coordinates and controls; animating it names the missing
    scene."""
    old = tmp_path / "old.npz"
    meta = {"stats": {"objective": solution.objective, "success": True, "iterations": 1},
            "controls": solution.controls, "coordinates": solution.coordinate_names}
    np.savez(old, t=solution.t, q=solution.q, v=solution.v, u=solution.u,
             meta=np.array(json.dumps(meta)))
    assert np.array_equal(OcpSolution.load(old).q, solution.q)
    figure = tmp_path / "old.png"
    assert cli.main(["plot", str(old), "--out", str(figure)]) == 0, capsys.readouterr().err
    assert figure.is_file()
    status = cli.main(["animate", str(old), "--out", str(tmp_path / "old.gif")])
    assert status == 1 and "holds no scene text" in capsys.readouterr().err


def test_solution_plot_has_units_states_controls_and_bounds(solution, tmp_path):
    """``OcpSolution.plot``: states (angles [rad], rates [rad/s]) and controls (torques
    [N m], piecewise constant per interval) in separate panels, the ±50 N m bounds dashed."""
    import matplotlib.pyplot as plt

    fig = solution.plot(tmp_path / "sol.png")
    try:
        labels = [ax.get_ylabel() for ax in fig.axes]
        assert labels == ["state [rad]", "state [rad/s]", "control [N m]"], labels
        controls = fig.axes[2]
        drawn = {ln.get_label(): ln for ln in controls.get_lines()}
        np.testing.assert_array_equal(drawn["control tau1"].get_ydata()[:-1], solution.u[:, 0])
        bounds = sorted(float(ln.get_ydata()[0]) for ln in controls.get_lines()
                        if ln.get_linestyle() == "--")
        assert bounds == [-50.0, -50.0, 50.0, 50.0]  # tau1 and tau2
        assert (tmp_path / "sol.png").stat().st_size > 1000
    finally:
        plt.close(fig)
