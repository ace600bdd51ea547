"""Bad input, sizes (issue 18, items 3 and 7): every limit of :mod:`casmbd.limits` is refused
with a named error (class, culprit and limit in the message) before any heavy work — no
equations built, nothing compiled, nothing written — and ``info`` stays right and linear on
large chains.  Small scenes, the CasADi virtual machine, no timing assertions."""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

import casmbd.analysis.driven.kinematics as kinematics_module
import casmbd.analysis.dynamics.simulate as simulate_module
from benchmarks.info_scaling import chain_scene
from casmbd import cli
from casmbd.analysis.driven.kinematics import info, kinematics
from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.instant import assembly
from casmbd.analysis.instant.redundancy import DENSE_MAX_ENTRIES, rank_report
from casmbd.analysis.studies.sweep import parse_values, sweep
from casmbd.cli import workbench as cli_workbench
from casmbd.compiled import codegen
from casmbd.errors import AnalysisError, LimitError, SceneError
from casmbd.io.scene import load_scene, loads_scene
from casmbd.limits import (
    MAX_BODIES,
    MAX_DPI,
    MAX_FIGURE_INCHES,
    MAX_FIXED_STEPS,
    MAX_FPS,
    MAX_FRAMES,
    MAX_OCP_INTERVALS,
    MAX_OCP_UNKNOWNS,
    MAX_SCENE_BYTES,
    MAX_STEPS,
    MAX_SWEEP_POINTS,
    MAX_TOML_DEPTH,
    check_memory,
    memory_budget,
    memory_per_time,
    result_counts,
)
from casmbd.ocp.problem import Ocp
from tests.mechanisms import triple_crank

REPO = pathlib.Path(__file__).resolve().parents[2]
PENDULUM = REPO / "examples" / "double_pendulum.toml"
SPRING = REPO / "tests" / "scenes" / "spring_mass.toml"
CART_POLE = REPO / "ocp" / "cart_pole.toml"


#: a private cache, the virtual machine, a fixed memory budget of 4 GiB
_vm = private_cache("cache_sizes", CASMBD_COMPILE="0", CASMBD_MEMORY_BUDGET="4G")


@pytest.fixture
def no_build(monkeypatch):
    """Fail the test if an analysis builds its equations (Simulator, NumericModel) or
    compiles; yields a check that the compiler count did not move."""
    def refuse(*args, **kwargs):
        raise AssertionError("equations were built before the limit was checked")

    monkeypatch.setattr(simulate_module, "Simulator", refuse)
    monkeypatch.setattr(kinematics_module, "_model", refuse)
    count = codegen.COMPILE_COUNT
    yield
    assert codegen.COMPILE_COUNT == count


def limit_text(limit) -> str:
    return f"{int(limit):,}"


# ---------------------------------------------------------------------- scenes
def test_toml_nested_500_deep_is_a_scene_error(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("x = " + "[" * 500 + "]" * 500 + "\n" + PENDULUM.read_text())
    with pytest.raises(SceneError, match=f"nested 500 levels deep; the limit is "
                                         f"{MAX_TOML_DEPTH}") as err:
        load_scene(path)
    assert str(path) in str(err.value)


def test_toml_nested_inline_tables_and_brackets_in_strings():
    """Inline tables count as nesting; brackets inside strings and comments do not."""
    with pytest.raises(SceneError, match="nested 100 levels"):
        loads_scene("x = " + "{a = " * 100 + "1" + "}" * 100 + "\n" + PENDULUM.read_text())
    harmless = PENDULUM.read_text().replace(
        "[parameters]", '# ' + "[" * 100 + '\n[parameters]\nlabel_text = 1.0\n', 1)
    assert len(loads_scene(harmless).bodies) == 2


def test_scene_text_too_long():
    with pytest.raises(LimitError, match=f"scene size in characters: "
                                         f"{limit_text(MAX_SCENE_BYTES + 1)} exceeds"):
        loads_scene("#" * (MAX_SCENE_BYTES + 1))


def test_too_many_bodies_in_a_scene():
    text = '[scene]\nname = "many"\n' + '[[bodies]]\nname = "b"\n' * (MAX_BODIES + 1)
    with pytest.raises(LimitError, match=rf"\[\[bodies\]\] entries: "
                                         rf"{limit_text(MAX_BODIES + 1)} exceeds the limit of "
                                         rf"{limit_text(MAX_BODIES)}"):
        loads_scene(text, "many.toml")


# ---------------------------------------------------------------------- steps and memory
def test_steps_beyond_the_cap_refused_before_any_build(no_build):
    mech = load_scene(PENDULUM)
    with pytest.raises(LimitError, match=f"simulation: steps: 1,000,000,000 exceeds the limit "
                                         f"of {limit_text(MAX_STEPS)}"):
        simulate(mech, t_end=1.0, steps=10**9)
    with pytest.raises(LimitError, match="kinematics: steps: 1,000,000,000"):
        kinematics(mech, t_end=1.0, steps=10**9)


def test_memory_budget_names_steps_estimate_budget_and_remedy(monkeypatch, no_build):
    monkeypatch.setenv("CASMBD_MEMORY_BUDGET", "1M")
    mech = load_scene(PENDULUM)
    with pytest.raises(LimitError) as err:
        simulate(mech, t_end=1.0, steps=100_000)
    text = str(err.value)
    for fragment in ("simulation: 100,001 output times", "exceeds the memory budget of 1.0 MB",
                     "$CASMBD_MEMORY_BUDGET", "use at most", "steps"):
        assert fragment in text, text
    fit = int(text.split("use at most ")[1].split(" steps")[0].replace(",", ""))
    per_time = memory_per_time(result_counts(mech))  # the one estimate (issue 31)
    assert (fit + 1) * per_time <= 2**20 < (fit + 2) * per_time  # the largest that fits


def test_memory_estimate_counts_what_a_real_result_stores():
    """The counted values per time cover what the result really stores (absolute coordinates
    assumed, issue 31; the peak memory is measured in
    tests/analysis/dynamics/test_memory_guard.py)."""
    mech = load_scene(PENDULUM)
    res = simulate(mech, t_end=0.1, steps=3)
    stored = sum(np.asarray(v).size for v in res.arrays.values()) // len(res.t)
    from casmbd.limits import output_values

    assert stored <= output_values(mech) <= 2 * stored, (output_values(mech), stored)


def test_simulate_200_bodies_million_steps_refused_by_the_cli(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(simulate_module, "Simulator", lambda *a, **k: pytest.fail("built"))
    scene = tmp_path / "chain200.toml"
    scene.write_text(chain_scene(200))
    out = tmp_path / "run.npz"
    status = cli.main(["simulate", str(scene), "--t-end", "1", "--steps", "1000000",
                       "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 1
    assert err.count("error:") == 1 and "1,000,001 output times" in err
    assert "memory budget of 4.0 GB ($CASMBD_MEMORY_BUDGET)" in err
    assert not out.exists()


@pytest.mark.parametrize("value", ["abc", "-5G", "0"])
def test_bad_memory_budget_variable(monkeypatch, value):
    monkeypatch.setenv("CASMBD_MEMORY_BUDGET", value)
    with pytest.raises(LimitError, match="CASMBD_MEMORY_BUDGET"):
        memory_budget()


def test_memory_budget_suffixes(monkeypatch):
    monkeypatch.setenv("CASMBD_MEMORY_BUDGET", "16G")
    assert memory_budget()[0] == 16 * 2**30
    monkeypatch.setenv("CASMBD_MEMORY_BUDGET", "1500")
    assert memory_budget()[0] == 1500
    assert check_memory("x", 10, 80) == 800
    with pytest.raises(LimitError, match="x: 20 output times"):
        check_memory("x", 20, 80)


# ---------------------------------------------------------------------- sweeps
def test_sweep_grid_of_ten_million_points_refused(tmp_path, no_build):
    out = tmp_path / "sweep"
    params = {"k": np.linspace(1.0, 2.0, 10_000), "c": np.linspace(0.0, 1.0, 1_000)}
    with pytest.raises(LimitError, match=f"sweep: grid points \\(k 10000 × c 1000\\): "
                                         f"10,000,000 exceeds the limit of "
                                         f"{limit_text(MAX_SWEEP_POINTS)}"):
        sweep(load_scene(SPRING), params, t_end=1.0, steps=10, out_dir=out)
    assert not out.exists()


def test_sweep_param_points_refused_before_generation():
    with pytest.raises(LimitError, match="--param 'k=0:1:10000000': points: 10,000,000"):
        parse_values("k=0:1:10000000")


def test_sweep_cli_grid_refused_nothing_written(tmp_path, capsys):
    out = tmp_path / "sweep_out"
    status = cli.main(["sweep", str(SPRING), "--param", "k=1:1000:10000", "--param",
                       "c=0:1:1000", "--t-end", "1", "--steps", "10", "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 1 and err.count("error:") == 1
    assert "sweep: grid points (k 10000 × c 1000)" in err
    assert not out.exists()


def test_sweep_per_point_memory(monkeypatch, no_build):
    monkeypatch.setenv("CASMBD_MEMORY_BUDGET", "1M")
    with pytest.raises(LimitError, match=r"sweep \(simulate\) at each point: 1,000,001 output"):
        sweep(load_scene(SPRING), {"k": [1.0, 2.0]}, t_end=1.0, steps=1_000_000)


# ---------------------------------------------------------------------- optimal control
def test_ocp_ten_million_intervals_refused():
    mech = load_scene(PENDULUM)
    with pytest.raises(LimitError, match=f"ocp: intervals: 10,000,000 exceeds the limit of "
                                         f"{limit_text(MAX_OCP_INTERVALS)}"):
        Ocp(mech, horizon=1.0, intervals=10**7)


def test_ocp_unknowns_refused():
    """50 000 intervals × 5 elements × 10 points × (4 + 2) states and inputs = 1.5e7."""
    mech = load_scene(PENDULUM)
    mech.coordinates = "joint"
    with pytest.raises(LimitError, match=rf"ocp: unknowns \(50,000 intervals × 50 points × 6 "
                                         rf"states and inputs\): 15,000,000 exceeds the limit "
                                         rf"of {limit_text(MAX_OCP_UNKNOWNS)}"):
        Ocp(mech, horizon=1.0, intervals=50_000, degree=9, subintervals=5)


def test_ocp_cli_intervals_keeps_the_limit_class(tmp_path, capsys):
    out = tmp_path / "sol.npz"
    status = cli.main(["ocp", str(CART_POLE), "--intervals", "10000000", "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 1 and err.count("error:") == 1
    assert "ocp: intervals: 10,000,000 exceeds the limit" in err and "cart_pole.toml" in err
    assert not out.exists()


# ---------------------------------------------------------------------- figures, animations
def test_dpi_of_a_million_refused_nothing_written(tmp_path):
    from casmbd.viz.plots import new_figure, save_figure

    fig, _ = new_figure()
    out = tmp_path / "fig.png"
    with pytest.raises(LimitError, match=f"dpi: 1,000,000 exceeds the limit of "
                                         f"{limit_text(MAX_DPI)}") as err:
        save_figure(fig, out, dpi=1e6)
    assert str(out) in str(err.value)
    assert not out.exists()


def test_figure_size_and_pixels_refused():
    from casmbd.viz.plots import check_figure_size, new_figure

    with pytest.raises(LimitError, match=f"width in inches: 1,000 exceeds the limit of "
                                         f"{limit_text(MAX_FIGURE_INCHES)}"):
        new_figure(figsize=(1000.0, 3.0))
    with pytest.raises(LimitError, match=r"pixels \(100 × 100 in at 2000 dpi\)"):
        check_figure_size((100.0, 100.0), 2000.0)
    with pytest.raises(LimitError, match="dpi must be a finite number"):
        check_figure_size(dpi=math.nan)


def test_animate_cli_dpi_and_frames_refused_before_simulating(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli_workbench, "simulate", lambda *a, **k: pytest.fail("simulated"))
    out = tmp_path / "a.gif"
    status = cli.main(["animate", str(PENDULUM), "--out", str(out), "--dpi", "1000000"])
    err = capsys.readouterr().err
    assert status == 1 and "dpi: 1,000,000 exceeds the limit of 2,400" in err
    status = cli.main(["animate", str(PENDULUM), "--out", str(out), "--steps", "200000"])
    err = capsys.readouterr().err
    assert status == 1
    assert f"frames (--steps + 1): 200,001 exceeds the limit of {limit_text(MAX_FRAMES)}" in err
    assert "--max-frames" in err
    assert not out.exists()


# ---------------------------------------------------------------------- info on large chains
def test_info_on_a_2000_body_chain():
    """A pendulum chain of N rods: 3N coordinates, 2N independent equations, N degrees of
    freedom (the sparse rank path; the dense one would take minutes).  Absolute coordinates:
    the automatic choice takes N joint coordinates and no equation for a chain."""
    mech = loads_scene(chain_scene(2000), "chain2000.toml")
    mech.coordinates = "absolute"
    data = info(mech)
    assert (data["n_coordinates"], data["n_constraints"]) == (6000, 4000)
    assert data["rank"] == 4000 and data["degrees_of_freedom"] == 2000
    assert data["redundant_equations"] == [] and data["assembled"]
    assert data["stats"]["mode"] == "vm" and not data["stats"]["compiled"]


def test_sparse_rank_names_the_redundant_joint_of_a_long_chain():
    """A duplicate of pin 150 in a 300-rod chain (C_q of 602 × 900, sparse path): its two
    equations — and nothing else — are dependent; 300 degrees of freedom.  Absolute
    coordinates (the sparse path needs the 600 pin equations; the automatic choice keeps the
    twin's 2 equations on 300 joint coordinates)."""
    text = chain_scene(300) + ('\n[[joints]]\nname = "twin"\ntype = "revolute"\n'
                               'body1 = "rod149"\nbody2 = "rod150"\npoint = [150.0, 0.0]\n')
    mech = loads_scene(text, "chain300.toml")
    mech.coordinates = "absolute"
    assert 602 * 900 > DENSE_MAX_ENTRIES
    data = info(mech)
    assert data["degrees_of_freedom"] == 300 and data["rank"] == 600
    assert data["redundant_equations"] == [
        {"kind": "joint", "joint": "twin", "equation": "x"},
        {"kind": "joint", "joint": "twin", "equation": "y"}]


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "joint"])
def test_sparse_and_dense_rank_agree_on_a_redundant_mechanism(coordinates):
    """The triple crank (one redundant loop equation): both methods give the same rank and
    dependent rows at the assembled pose and at a perturbed one (rank regained)."""
    from casmbd.analysis.instant.assembly import assemble
    from casmbd.compiled.model import NumericModel

    model = NumericModel(triple_crank(coordinates, name=f"tc_sizes_{coordinates}"), "info",
                         mode="vm")
    q = assemble(model, model.initial_coordinates(), 0.0).q
    bumped = q + 1e-3 * np.random.default_rng(0).standard_normal(q.size)
    for point, dependent in ((q, 1), (bumped, 0)):
        jac = model.constraint_jacobian(point, 0.0)
        dense, sparse = rank_report(jac, method="dense"), rank_report(jac, method="sparse")
        assert len(dense.dependent_rows) == dependent
        assert (sparse.rank, sparse.dependent_rows) == (dense.rank, dense.dependent_rows)


def test_sparse_rank_matches_dense_on_random_dependent_rows():
    """200 random sparse matrices with rows built as combinations of earlier ones and scaled
    by up to e^±3: identical rank and dependent rows."""
    import scipy.sparse as sp

    for seed in range(200):
        rng = np.random.default_rng(seed)
        m, n = int(rng.integers(1, 40)), int(rng.integers(3, 30))
        a = sp.random(m, n, density=rng.uniform(0.05, 0.5), random_state=seed).toarray()
        for i in range(1, m):
            if rng.random() < 0.25:
                idx = rng.choice(i, min(i, 3), replace=False)
                a[i] = rng.standard_normal(idx.size) @ a[idx]
        a *= np.exp(rng.uniform(-3, 3, (m, 1)))
        dense, sparse = rank_report(a, method="dense"), rank_report(a, method="sparse")
        assert (sparse.rank, sparse.dependent_rows) == (dense.rank, dense.dependent_rows), seed


def test_large_minimum_norm_assembly_equals_the_dense_one(monkeypatch):
    """A 150-rod chain whose first pin is driven to 0.3 rad: the sparse augmented-system
    Newton steps assemble the same pose as the dense SVD ones, to 1e-12.  Absolute
    coordinates (q[2] is rod0.angle; in joint coordinates the chain has no equation to
    assemble but the driver's)."""
    text = chain_scene(150) + '\n[[drivers]]\nname = "lift"\njoint = "pin0"\nposition = "0.3"\n'
    text = text.replace("[scene]\n", '[scene]\ncoordinates = "absolute"\n')
    dense = info(loads_scene(text, "c150.toml"))
    monkeypatch.setattr(assembly, "DENSE_MAX_ENTRIES", 0)
    sparse = info(loads_scene(text, "c150.toml"))
    assert dense["assembled"] and sparse["assembled"]
    assert sparse["initial_coordinates"][2] == pytest.approx(0.3, abs=1e-12)
    np.testing.assert_allclose(sparse["initial_coordinates"], dense["initial_coordinates"],
                               rtol=0, atol=1e-12)
    assert sparse["degrees_of_freedom"] == dense["degrees_of_freedom"] == 149


# ---------------------------------------------------------------------- fixed steps, fps
@pytest.mark.parametrize("integrator, step", [("rk4", 1e-300), ("abm", 5e-324)])
def test_fixed_step_below_the_floor(integrator, step):
    """``--step 1e-300`` used to run forever; 5e-324 ended in an internal OverflowError; both
    are below the option's floor of 1 fs (casmbd.analysis.integrators.option_ranges)."""
    mech = load_scene(PENDULUM)
    with pytest.raises(AnalysisError, match=rf"fixed step \(--step\) {step:g} s is below the "
                                            r"floor of 1e-12 s"):
        simulate(mech, t_end=1.0, steps=2, integrator=integrator, step=step)


def test_fixed_step_count_beyond_the_limit():
    """A step above the floor (1e-12 of |t| = 1e-8 s here) whose count is still absurd (1e-7 s
    over 1e4 s: 1e11 steps) is refused by the step-count limit before the run."""
    mech = load_scene(PENDULUM)
    with pytest.raises(LimitError, match=r"fixed step \(--step\) 1e-07: 1e\+11 steps over "
                                         rf"2 output intervals exceed the limit of "
                                         rf"{limit_text(MAX_FIXED_STEPS)}"):
        simulate(mech, t_end=1e4, steps=2, integrator="rk4", step=1e-7)


def test_fixed_step_error_is_not_masked_by_a_sundials_rerun():
    """A casmbd error of a fixed-step run used to be replaced by "unknown SUNDIALS
    integrator 'rk4'" from the partial-results re-run."""
    from casmbd.errors import ModelError

    mech = load_scene(PENDULUM)
    with pytest.raises(ModelError, match=r"fixed step must be a finite number > 0, got 0\.0"):
        simulate(mech, t_end=1.0, steps=2, integrator="rk4", step=0.0)


def test_animate_fps_refused_before_simulating(tmp_path, capsys, monkeypatch):
    """``--fps 1e308`` used to write a GIF of zero-duration frames and exit 0."""
    from casmbd.errors import AnalysisError
    from casmbd.viz.animation import check_fps

    monkeypatch.setattr(cli_workbench, "simulate", lambda *a, **k: pytest.fail("simulated"))
    out = tmp_path / "a.gif"
    status = cli.main(["animate", str(PENDULUM), "--out", str(out), "--fps", "1e308"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and len(err) == 1, err
    assert err[0] == (f"error: animation: fps (--fps) 1e+308 exceeds the limit of {MAX_FPS:g} "
                      "(casmbd.limits): a GIF cannot show frames shorter than 10 ms"), err[0]
    assert not out.exists()
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(AnalysisError, match=r"fps \(--fps\) must be a finite number > 0"):
            check_fps(bad)
    check_fps(MAX_FPS)  # the limit itself is allowed
