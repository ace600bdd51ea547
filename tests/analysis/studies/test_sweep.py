"""Parameter sweeps (casmbd.analysis.studies.sweep, ``casmbd sweep``).

Acceptance of issue 10 item 5: a 20-point sweep of the spring-mass scene gives the same numbers
serially, on two local processes and on a local Dask cluster; its one failing point (a negative
mass) leaves the other 19 saved and reloadable; the points agree with the closed form
x(t) = 1 + 0.1 cos(sqrt(k/m) t); the workers load the library the calling process compiled.
"""

from __future__ import annotations

import csv
import json
import math
import os
import pathlib
import sys

import numpy as np
import pytest
from conftest import private_cache

from casmbd import cli
from casmbd.analysis.studies.sweep import load_sweep, parse_values, sweep
from casmbd.errors import AnalysisError, ModelError
from casmbd.io.scene import load_result as load
from casmbd.io.scene import load_scene, loads_scene

REPO = pathlib.Path(__file__).resolve().parents[3]
SPRING = str(REPO / "tests" / "scenes" / "spring_mass.toml")
SLIDER_CRANK = str(REPO / "examples" / "slider_crank.toml")
DOUBLE_PENDULUM = str(REPO / "examples" / "double_pendulum.toml")

#: 19 stiffnesses with m = 1 and, at index 7, a negative mass (the scene refuses it)
K_VALUES = np.linspace(40.0, 400.0, 20)
FAILING = 7
POINTS = [{"k": float(k), "m": -1.0 if i == FAILING else 1.0} for i, k in enumerate(K_VALUES)]
T_END, STEPS = 1.0, 40
NAMED = ["final:q[block.x]", "final:body.block.position.x", "max:joint.slide.velocity",
         "energy_drift", "max_constraint_violation"]


cache = private_cache("casmbd_cache_sweep", scope="module", autouse=False, CASMBD_COMPILE=None)


@pytest.fixture(scope="module")
def serial(cache, tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep_serial")
    mech = load_scene(SPRING)
    return sweep(mech, points=POINTS, t_end=T_END, steps=STEPS, outputs=NAMED, out_dir=out)


def _same(a, b):
    """Same status, messages and outputs to 1e-12 (absolute; x ~ 1, v ~ 2, energies ~ 0.5 J)."""
    assert list(a.status) == list(b.status)
    assert a.errors == b.errors
    assert a.output_names == b.output_names == NAMED
    for name in NAMED:
        np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-12, equal_nan=True)


def test_serial_sweep_records_the_failure_and_saves_the_others(serial):
    assert len(serial) == 20 and serial.failed == [FAILING]
    assert serial.stats["failed"] == 1
    msg = serial.errors[FAILING]
    assert "SceneError" in msg and "'mass'" in msg and "-1" in msg, msg
    assert np.isnan(serial.outputs[FAILING]["final:q[block.x]"])
    with pytest.raises(AnalysisError, match="point 7 has no result file"):
        serial.result(FAILING)
    # the 19 others: files exist, reload, embed the point's parameter values and reproduce the
    # tabulated outputs exactly
    for i in range(20):
        if i == FAILING:
            assert serial.files[i] is None
            continue
        assert pathlib.Path(serial.files[i]).name == f"point_{i:03d}.npz"
        res = load(serial.files[i])
        assert res.stats["sweep_point"] == POINTS[i]
        assert res.mechanism().parameters["k"] == POINTS[i]["k"]
        # q[block.x] names the absolute coordinate; the automatic choice takes the slide's
        # translation (a tree), and the sweep reads the block's x from its pose
        assert res.names["coordinates"] == ["slide.translation"]
        assert res["q"][-1, 0] == pytest.approx(res.body("block")["position"][-1, 0] - 1.1,
                                                abs=1e-12)
        assert res.body("block")["position"][-1, 0] == serial["final:q[block.x]"][i]
        assert res.body("block")["position"][-1, 0] == serial["final:body.block.position.x"][i]
    # compiled once, in this process; no compiler run during any point
    assert serial.stats["parent_build"]["compiled"] is True
    assert serial.stats["worker_compiler_runs"] == 0


def test_point_matches_the_closed_form(serial):
    """x(t) = 1 + 0.1 cos(ω t), ω = sqrt(k/m), on the whole grid of every point; measured
    max error 1.4e-7 m at rtol 1e-8 (augmented Lagrangian on Adams): bound 1e-6 m, and the
    period error this allows is ~1e-5 relative."""
    worst = 0.0
    for i in np.flatnonzero(serial.ok):
        res = serial.result(i)
        omega = math.sqrt(POINTS[i]["k"] / POINTS[i]["m"])
        exact = 1.0 + 0.1 * np.cos(omega * res.t)
        worst = max(worst, float(np.max(np.abs(res.body("block")["position"][:, 0] - exact))))
    assert worst < 1e-6
    # the energy drift is the integrator's (measured 3.3e-6 J), far below the 0.5 k A² ≥ 0.2 J
    # of the motion
    assert np.nanmax(np.abs(serial["energy_drift"])) < 1e-5


def test_table_files_round_trip(serial, tmp_path):
    out = pathlib.Path(serial.out_dir)
    again = load_sweep(out / "sweep.npz")
    _same(serial, again)
    np.testing.assert_array_equal(again["k"], K_VALUES)
    with open(out / "sweep.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 20 and rows[FAILING]["status"] == "failed"
    for i, row in enumerate(rows):
        assert float(row["k"]) == POINTS[i]["k"]
        x = float(row["final:q[block.x]"])
        assert (math.isnan(x) and i == FAILING) or x == serial["final:q[block.x]"][i]
    fig = serial.plot("k", "final:q[block.x]", out=tmp_path / "sweep.png")
    line = fig.axes[0].lines[0]
    np.testing.assert_array_equal(line.get_ydata(), serial["final:q[block.x]"][serial.ok])
    assert (tmp_path / "sweep.png").stat().st_size > 1000


def test_local_processes_give_the_same_numbers(serial, tmp_path):
    res = sweep(load_scene(SPRING), points=POINTS, t_end=T_END, steps=STEPS, outputs=NAMED,
                executor="processes", workers=2, out_dir=tmp_path)
    _same(serial, res)
    s = res.stats
    assert s["executor"] == "processes" and s["workers"] == 2
    # every worker loaded the cached library: built its engine without running the compiler
    assert 1 <= s["worker_builds"] <= 2 and s["worker_cache_hits"] == s["worker_builds"]
    assert s["worker_compiler_runs"] == 0
    assert f":{os.getpid()}" not in " ".join(s["worker_processes"])
    assert sorted(p.name for p in tmp_path.glob("point_*.npz")) == \
        [f"point_{i:03d}.npz" for i in range(20) if i != FAILING]


def test_local_dask_cluster_gives_the_same_numbers(serial):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        # by scheduler address (the sweep connects and disconnects) ...
        res = sweep(load_scene(SPRING), points=POINTS, t_end=T_END, steps=STEPS, outputs=NAMED,
                    executor=cluster.scheduler_address)
        # ... and through a Client the caller holds (the workers keep their engines)
        with distributed.Client(cluster) as client:
            mech = load_scene(SPRING)
            again = sweep(mech, points=POINTS[:4], t_end=T_END, steps=STEPS, outputs=NAMED,
                          executor=client)
    _same(serial, res)
    s = res.stats
    assert s["executor"] == "dask" and s["workers"] == 2
    assert 1 <= s["worker_builds"] <= 2 and s["worker_cache_hits"] == s["worker_builds"]
    assert s["worker_compiler_runs"] == 0
    # each worker process builds its engine once over both sweeps
    assert s["worker_builds"] + again.stats["worker_builds"] <= 2
    assert again.stats["worker_compiler_runs"] == 0
    for name in NAMED:
        np.testing.assert_array_equal(again[name], serial[name][:4])


def test_runtime_parameters_equal_a_scene_with_those_values(cache):
    """Setting p at run time = loading the scene with the value: the same generated code (a
    cache hit, no compiler run) and the same trajectory to 1e-12 (index-1 DAE, which has no
    numbers computed from the defaults at build time)."""
    from casmbd.analysis.dynamics.simulate import simulate
    from casmbd.io.scene_points import scene_with as _scene_with

    res = sweep(load_scene(SPRING), {"k": [90.0, 250.0], "m": [2.0]}, t_end=0.5, steps=10,
                formulation="index1", outputs=["final:q[block.x]"])
    text = pathlib.Path(SPRING).read_text()
    direct = simulate(loads_scene(_scene_with(text, {"k": 250.0, "m": 2.0}, SPRING)), 0.5, 10,
                      formulation="index1")
    assert direct.stats["cache_hit"] is True and direct.stats["compiled"] is False
    assert abs(direct.body("block")["position"][-1, 0] - res["final:q[block.x]"][1]) < 1e-12


def test_statics_sweep_matches_the_hanging_spring(cache, tmp_path):
    """A block hanging from a spring on a vertical slide rests at y = −(l0 + m g / k)
    (measured error 1e-16 m; bound 1e-10 m) with stiffness eigenvalue k > 0 (stable)."""
    text = pathlib.Path(SPRING).read_text().replace("[1.1, 0.0]", "[0.0, -1.1]") \
        .replace("axis = [1.0, 0.0]", "axis = [0.0, 1.0]")
    path = tmp_path / "hanging.toml"
    path.write_text(text)
    ks = [50.0, 100.0, 400.0]
    res = sweep(load_scene(path), {"k": ks}, analysis="statics")
    assert res.failed == [], res.errors
    # default outputs: the chosen coordinates (the slide's translation from y = −1.1)
    assert res.output_names[0] == "final:q[slide.translation]"
    np.testing.assert_allclose(res["final:q[slide.translation]"],
                               [1.1 - (1.0 + 9.81 / k) for k in ks], rtol=0, atol=1e-10)
    np.testing.assert_allclose(res["min_stiffness_eigenvalue"], ks, rtol=1e-9)  # K̄ = k
    # the block's pose, by body field and by its absolute-coordinate name
    res = sweep(load_scene(path), {"k": ks}, analysis="statics",
                outputs=["final:q[block.y]", "final:body.block.position.y",
                         "final:body.block.angle"])
    assert res.failed == [], res.errors
    for name in ("final:q[block.y]", "final:body.block.position.y"):
        np.testing.assert_allclose(res[name], [-(1.0 + 9.81 / k) for k in ks], rtol=0,
                                   atol=1e-10)
    np.testing.assert_array_equal(res["final:body.block.angle"], 0.0)


def test_statics_sweep_reads_spatial_body_poses(cache):
    """A spatial rod on a horizontal revolute axis (x) with a torsional spring k, released
    horizontal along y under gravity −z: the sweep's body outputs (position, quaternion) of
    each point equal static_equilibrium's body poses (1e-12), and the quaternion is a rotation
    about x by the angle θ of k θ = −m g (L/2) cos θ (1e-10 rad)."""
    from scipy.optimize import brentq

    import casmbd
    from casmbd.analysis.statics.statics import static_equilibrium

    mech = casmbd.Mechanism("spatial_spring_rod", gravity=(0.0, 0.0, -9.81))
    mech.add_parameter("k", 20.0)
    mech.add_body("rod", 1.0, [1 / 12, 1e-3, 1 / 12], (0.0, 0.5, 0.0))
    mech.add_revolute("pin", "ground", "rod", (0.0, 0.0, 0.0), axis=(1.0, 0.0, 0.0))
    mech.add_rotational_spring_damper("spring", "pin", stiffness="k")
    ks = [20.0, 50.0]
    outputs = ["final:body.rod.position.y", "final:body.rod.position.z",
               *[f"final:body.rod.quaternion.{c}" for c in "wxyz"]]
    res = sweep(mech, {"k": ks}, analysis="statics", outputs=outputs, mode="vm")
    assert res.failed == [], res.errors
    for i, k in enumerate(ks):
        mech.parameters["k"] = k
        eq = static_equilibrium(mech, mode="vm")
        got = [res[name][i] for name in outputs]
        np.testing.assert_allclose(got[:2], eq.body_positions[0, 1:], rtol=0, atol=1e-12)
        q = eq.body_quaternions[0] * np.sign(eq.body_quaternions[0, 0] * got[2])
        np.testing.assert_allclose(got[2:], q, rtol=0, atol=1e-12)
        theta = brentq(lambda th, k=k: k * th + 9.81 * 0.5 * np.cos(th), -np.pi / 2, 0.0,
                       xtol=1e-15)
        np.testing.assert_allclose(got[2:], [np.cos(theta / 2), np.sin(theta / 2), 0.0, 0.0],
                                   rtol=0, atol=1e-10)


def test_kinematics_and_inverse_sweeps_of_the_slider_crank(cache):
    """Slider position r cos θ + sqrt(l² − r² sin² θ) (r = 0.1, l = 0.3, θ = ω t) at the end;
    the inverse sweep's motor torque equals inverse_dynamics on the scene with that ω."""
    from casmbd.analysis.driven.inverse import inverse_dynamics
    from casmbd.io.scene_points import scene_with as _scene_with

    omegas = [2.0, 5.0, 9.0]
    mech = load_scene(SLIDER_CRANK)
    kin = sweep(mech, {"omega": omegas}, analysis="kinematics", t_end=0.3, steps=6,
                outputs=["final:body.slider.position.x"])
    th = np.array(omegas) * 0.3
    exact = 0.1 * np.cos(th) + np.sqrt(0.09 - 0.01 * np.sin(th) ** 2)
    # measured 2e-13 m (assembly to its tolerance); bound 1e-9 m
    np.testing.assert_allclose(kin["final:body.slider.position.x"], exact, rtol=0, atol=1e-9)
    mech = load_scene(SLIDER_CRANK)
    inv = sweep(mech, {"omega": omegas[1:2]}, analysis="inverse", t_end=0.3, steps=6,
                outputs=["max_abs:actuator_efforts[motor.effort]"])
    text = pathlib.Path(SLIDER_CRANK).read_text()
    direct = inverse_dynamics(loads_scene(_scene_with(text, {"omega": 5.0}, SLIDER_CRANK)),
                              0.3, 6)
    assert abs(np.max(np.abs(direct["actuator_efforts"])) - inv.outputs[0][0]) < 1e-12


def test_bad_input_names_the_culprit(cache, tmp_path, monkeypatch):
    with pytest.raises(ModelError, match=r"unknown parameter 'stiffness' \(known: k, m, c\)"):
        sweep(load_scene(SPRING), {"stiffness": [1.0]}, t_end=1.0, steps=2)
    # a parameter that places a body is read when the scene is loaded: refused, by name
    text = pathlib.Path(SPRING).read_text().replace("c = 0.0", "c = 0.0\nx0 = 1.1") \
        .replace("position = [1.1, 0.0]", 'position = ["x0", 0.0]')
    path = tmp_path / "placed.toml"
    path.write_text(text)
    assert load_scene(path).bodies["block"].position[0] == 1.1
    with pytest.raises(AnalysisError, match=r"parameter\(s\) 'x0' fix load-time numbers"):
        sweep(load_scene(path), {"x0": [1.2], "k": [10.0]}, t_end=1.0, steps=2)
    with pytest.raises(AnalysisError, match="REDUCTION:COLUMN"):
        sweep(load_scene(SPRING), {"k": [1.0]}, t_end=1.0, steps=2, outputs=["last:q[block.x]"])
    with pytest.raises(AnalysisError, match="needs t_end and steps"):
        sweep(load_scene(SPRING), {"k": [1.0]})
    with pytest.raises(AnalysisError, match="A:B:N"):
        parse_values("k=1:2")
    assert parse_values("k=100:1000:10") == ("k", np.linspace(100, 1000, 10).tolist())
    assert parse_values("m=1,2,3") == ("m", [1.0, 2.0, 3.0])
    # a scheduler address without dask.distributed installed
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(AnalysisError, match=r"dask.distributed is not installed"):
        mech = load_scene(SPRING)
        sweep(mech, {"k": [100.0]}, t_end=0.1, steps=2, executor="tcp://127.0.0.1:8786")


def test_cli_sweep_writes_files_that_reload(cache, tmp_path, capsys):
    out = tmp_path / "pendulum_sweep"
    status = cli.main(["sweep", DOUBLE_PENDULUM, "--param", "L=0.5:1.5:3", "--param", "m=2",
                       "--t-end", "0.3", "--steps", "6", "--out", str(out), "--json"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    data = json.loads(captured.out)
    assert data["parameters"] == ["L", "m"] and data["failed"] == 0
    assert [p["parameters"]["L"] for p in data["points"]] == [0.5, 1.0, 1.5]
    assert [p["status"] for p in data["points"]] == ["ok"] * 3
    # default outputs: the chosen coordinates, the joint angles of the tree (automatic choice;
    # both rods start horizontal, so shoulder.angle is rod1's angle)
    assert "final:q[elbow.angle]" in data["outputs"] and "energy_drift" in data["outputs"]
    for p in data["points"]:
        res = load(p["file"])
        mech = res.mechanism()  # the embedded scene carries the point's values
        assert mech.parameters == {"L": p["parameters"]["L"], "m": 2.0}
        assert res["q"][-1, 1] == p["outputs"]["final:q[elbow.angle]"]
        assert res["q"][-1, 0] == pytest.approx(res.body("rod1")["angle"][-1], abs=1e-12)
    assert (out / "sweep.csv").exists() and load_sweep(out / "sweep.npz").failed == []
    # a larger moment of inertia of the rods (L = 1.5) makes them fall more slowly
    angles = [p["outputs"]["final:q[shoulder.angle]"] for p in data["points"]]
    assert angles[0] < angles[1] < angles[2] < 0
    # text output and a usage error
    assert cli.main(["sweep", DOUBLE_PENDULUM, "--param", "m=1,2", "--t-end", "0.1",
                     "--steps", "2"]) == 0
    assert "2 points, 0 failed" in capsys.readouterr().out
    assert cli.main(["sweep", DOUBLE_PENDULUM, "--param", "q=1", "--t-end", "0.1",
                     "--steps", "2"]) == 1
    assert "unknown parameter 'q' (known: L, m)" in capsys.readouterr().err


def test_integrator_failure_is_recorded_with_its_partial_results(cache, tmp_path):
    """k = 1e6 (ω = 1000 rad/s) needs far more than 60 steps per output interval: that point
    stops with TOO_MUCH_WORK (the default DOPRI5's, or CVODES' CV_TOO_MUCH_WORK); k = 100 runs
    and is saved."""
    res = sweep(load_scene(SPRING), {"k": [100.0, 1e6]}, t_end=1.0, steps=10, max_steps=60,
                outputs=["final:q[block.x]"], out_dir=tmp_path)
    assert list(res.status) == ["ok", "failed"]
    assert "IntegratorError" in res.errors[1] and "TOO_MUCH_WORK" in res.errors[1]
    assert abs(res["final:q[block.x]"][0] - (1.0 + 0.1 * math.cos(10.0))) < 1e-6
    partial = load(tmp_path / "point_001_partial.npz")
    assert partial.stats["sweep_point"] == {"k": 1e6} and "TOO_MUCH_WORK" in \
        partial.stats["failure"]
    assert partial.t[-1] < 1.0


def test_progress_bar_counts_points_when_tqdm_is_there(cache, monkeypatch):
    """tqdm is optional: a stand-in module records the bar; without a terminal (pytest's
    captured stderr) no bar is made unless progress=True."""
    import types

    bars = []

    class FakeBar:
        def __init__(self, total, **kwargs):
            self.total, self.n, self.closed = total, 0, False
            bars.append(self)

        def update(self, n):
            self.n += n

        def close(self):
            self.closed = True

    monkeypatch.setitem(sys.modules, "tqdm", types.SimpleNamespace(tqdm=FakeBar))
    pts = {"k": [100.0, 200.0, 300.0]}
    sweep(load_scene(SPRING), pts, t_end=0.1, steps=2, outputs=["final:q[block.x]"])
    assert bars == []  # stderr is not a terminal here
    sweep(load_scene(SPRING), pts, t_end=0.1, steps=2, outputs=["final:q[block.x]"], progress=True)
    assert [(b.total, b.n, b.closed) for b in bars] == [(3, 3, True)]


def test_sweep_takes_a_mechanism_not_a_path():
    """Reading files is the caller's job (the CLI reads the scene): a path is refused, naming
    the reader to use."""
    with pytest.raises(AnalysisError, match=r"expected a Mechanism, got str .*load_scene"):
        sweep(SPRING, {"k": [1.0]}, t_end=1.0, steps=2)
