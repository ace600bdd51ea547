"""Every verb of the ``casmbd`` command on a shipped example (issue 10 acceptance): it exits
with 0, its JSON parses and its output files exist and reload to the numbers it printed."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import cli

ROOT = pathlib.Path(__file__).resolve().parents[2]
SLIDER = str(ROOT / "examples" / "slider_crank.toml")
INVERSE = str(ROOT / "examples" / "slider_crank_inverse.toml")
PENDULUM = str(ROOT / "examples" / "double_pendulum.toml")
CHAIN = str(ROOT / "examples" / "hanging_chain.toml")
SPRING = str(ROOT / "tests" / "scenes" / "spring_mass.toml")


_cache = private_cache("cache_verbs")


def run_json(capsys, *argv: str) -> dict:
    assert cli.main([*argv, "--json"]) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


def test_every_verb_is_covered():
    """A new verb must be added to this file."""
    covered = {"info", "kinematics", "inverse", "statics", "linearize", "simulate", "ocp",
               "plot", "animate", "sweep", "sensitivity", "bench", "identify",
               "export",  # export: tests/io/test_c_export.py
               "excite",  # excite: tests/cli/test_cli_excite.py
               "view"}  # view: tests/viz/test_view_cli.py and tests/viz/test_view_browser.py
    assert set(cli.VERBS) == covered


def test_info_statics_linearize(capsys):
    assert run_json(capsys, "info", SLIDER)["degrees_of_freedom"] == 0
    statics = run_json(capsys, "statics", CHAIN)
    assert statics["residual"] < 1e-10 and statics["stable"] is True
    lin = run_json(capsys, "linearize", PENDULUM)
    mass = np.asarray(lin["M"], dtype=float)
    assert mass.shape[0] == mass.shape[1] == 2  # two degrees of freedom
    np.testing.assert_allclose(mass, mass.T, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(mass) > 0)


@pytest.mark.parametrize("verb,scene", [("kinematics", SLIDER), ("inverse", INVERSE),
                                        ("simulate", PENDULUM)])
def test_result_verbs_write_files_that_reload(capsys, tmp_path, verb, scene):
    out = tmp_path / f"{verb}.npz"
    data = run_json(capsys, verb, scene, "--t-end", "0.5", "--steps", "10", "--out", str(out))
    res = casmbd.load_result(out)
    assert len(res.t) == 11 and res.t[-1] == pytest.approx(0.5)
    assert res.mechanism().name == casmbd.load_scene(scene).name
    np.testing.assert_allclose(res["q"][-1], np.asarray(data["q"][-1] if "q" in data
                                                        else res["q"][-1]), rtol=0, atol=1e-12)
    csv_path = res.to_csv(tmp_path / f"{verb}.csv")
    assert csv_path.stat().st_size > 0


def test_plot_and_animate_write_images(capsys, tmp_path):
    from PIL import Image

    res_path = tmp_path / "sim.npz"
    run_json(capsys, "simulate", PENDULUM, "--t-end", "0.2", "--steps", "4", "--out",
             str(res_path))
    png = tmp_path / "fig.png"
    run_json(capsys, "plot", str(res_path), "--out", str(png))
    with Image.open(png) as img:
        assert img.size[0] > 100
    gif = tmp_path / "anim.gif"
    data = run_json(capsys, "animate", SLIDER, "--t-end", "0.2", "--steps", "4", "--out",
                    str(gif))
    with Image.open(gif) as img:
        assert img.n_frames == data["frames"] == 5


def test_sweep_and_sensitivity(capsys, tmp_path):
    from casmbd.analysis.studies.sweep import load_sweep

    data = run_json(capsys, "sweep", SPRING, "--param", "k=50:100:2", "--t-end", "0.2",
                    "--steps", "4", "--out", str(tmp_path / "sw"))
    assert data["failed"] == 0 and len(data["points"]) == 2
    table = load_sweep(tmp_path / "sw" / "sweep.npz")
    assert len(table.status) == 2
    sens = run_json(capsys, "sensitivity", SLIDER, "--output", "slider_x", "--t-end", "0.1")
    assert "omega" in sens["outputs"]["slider_x"]["derivatives"]


def test_ocp_writes_a_solution_that_reloads(capsys, tmp_path):
    from casmbd.ocp.solution import OcpSolution

    out = tmp_path / "sol.npz"
    data = run_json(capsys, "ocp", str(ROOT / "ocp" / "cart_pole.toml"), "--intervals", "10",
                    "--no-replay", "--out", str(out))
    assert data["success"] is True
    assert OcpSolution.load(out).stats["objective"] == pytest.approx(data["objective"],
                                                                      rel=1e-12)
