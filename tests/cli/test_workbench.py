"""Workbench (issue 10): plots, animations, result files (npz with the scene, CSV), CLI verbs.

Figures are rendered with matplotlib's Agg canvas.  Numbers are compared wherever a figure or a
file carries them: plotted line data against the result's arrays, CSV columns against the arrays
(1e-12), drawn marker points (numpy rotation of body-fixed vectors) against the marker positions
the compiled System computed (an independent formulation of the same point), joint points seen
from both bodies of a joint against each other (the constraint tolerance).
"""

from __future__ import annotations

import csv
import json
import pathlib
import shutil

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import cli
from casmbd.errors import AnalysisError
from casmbd.results import atomic_write
from casmbd.viz import geometry, plots
from casmbd.viz.animation import animate, draw_frame, save_animation

matplotlib = pytest.importorskip("matplotlib")
Image = pytest.importorskip("PIL.Image")

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
SLIDER_CRANK = REPO_ROOT / "examples" / "slider_crank.toml"
SPATIAL_SLIDER_CRANK = REPO_ROOT / "examples" / "spatial_slider_crank.toml"


_cache = private_cache("casmbd_cache_workbench", scope="module", CASMBD_COMPILE=None)


@pytest.fixture(scope="module")
def planar():
    """Slider-crank simulated for 0.5 s (20 steps) with its scene text embedded."""
    mech = casmbd.load_scene(SLIDER_CRANK)
    return casmbd.simulate(mech, t_end=0.5, steps=20).attach_scene(mech)


@pytest.fixture(scope="module")
def spatial():
    """Spatial slider-crank: kinematics over 0.5 s (10 steps)."""
    mech = casmbd.load_scene(SPATIAL_SLIDER_CRANK)
    return casmbd.kinematics(mech, t_end=0.5, steps=10).attach_scene(mech)


def no_temporaries(folder: pathlib.Path) -> None:
    left = [p.name for p in folder.iterdir() if p.name.startswith(".tmp_")]
    assert not left, f"temporary files left behind: {left}"


# ---------------------------------------------------------------------- plots
@pytest.mark.parametrize("kind", [k for k in plots.KINDS
                                  if k not in ("outputs", "flexible", "contacts")])
def test_every_plot_kind_renders_the_result_arrays(planar, kind, tmp_path):
    """Every plot kind of the slider-crank (which has no requests or force elements; the
    ``outputs`` kind is drawn in tests/system/test_requests.py)."""
    out = tmp_path / f"{kind}.png"
    fig = plots.plot_result(planar, kind, out=out, dpi=50)
    assert out.stat().st_size > 1000
    with Image.open(out) as im:  # a PNG of the figure's size in pixels
        assert im.size == tuple(round(x * 50) for x in fig.get_size_inches())
    no_temporaries(tmp_path)
    # the first line of the panel carries the first series of the result exactly
    line = fig.axes[0].get_lines()[0]
    np.testing.assert_array_equal(line.get_xdata(), planar.t)
    first = {"coordinates": planar["q"][:, 0], "joints": planar["joint_positions"][:, 0],
             "efforts": planar["driver_efforts"][:, 0],
             "reactions": planar["joint_reactions"][:, 0, 0],
             "energy": planar["kinetic_energy"],
             "drift": np.where(planar["constraint_violation"] > 0,
                               planar["constraint_violation"], np.nan)}[kind]
    np.testing.assert_array_equal(np.asarray(line.get_ydata(), float), first)
    # coordinates: the automatic choice's 3 (O.angle, A.angle, slide.translation; 9 absolute)
    # reactions: the forces only, the planar joints' moments are 0 or rounding noise and
    # omitted with a note (issue 32)
    n_lines = {"coordinates": 3, "joints": 4, "efforts": 2, "reactions": 8, "energy": 4,
               "drift": 2}[kind]  # over the kind's panels (one unit each); energy: + change
    assert sum(len(ax.get_lines()) for ax in fig.axes) == n_lines


def test_plot_result_all_kinds_and_errors(planar, spatial, tmp_path):
    fig = plots.plot_result(planar, plots.available_kinds(planar), out=tmp_path / "all.pdf")
    labels = [ax.get_ylabel() for ax in fig.axes]  # every kind, split by unit
    # q: the joint angles O, A, then the slide's translation (automatic choice); the joint
    # translation repeats q's positions and the planar reaction moments are zero or rounding
    # noise: omitted, said in the notes (issue 32)
    assert labels == ["angles [rad]", "positions [m]", "joint angles [rad]",
                      "torques [N m]",  # driver, motor at O
                      "reaction forces [N]", "energy [J]",
                      "total − total(0) [J]", "max |C| [m, rad or 1]",
                      "max |C_q v + C_t| [m/s, rad/s or 1/s]"]
    assert any("reaction moments" in n for n in fig.casmbd_notes)
    assert any("joint translations (same lines as positions)" in n for n in fig.casmbd_notes)
    # the default: the motion (joint coordinates), efforts, energies and max |C|
    assert plots.plot_result(planar).casmbd_panels == [
        "joint angles [rad]", "joint translations [m]", "torques [N m]", "energy [J]",
        "total − total(0) [J]", "max |C| [m, rad or 1]"]
    assert (tmp_path / "all.pdf").read_bytes()[:4] == b"%PDF"
    with pytest.raises(AnalysisError, match=r"unknown plot kind.*'speed'"):
        plots.plot_result(planar, "speed")
    with pytest.raises(AnalysisError, match="kinematics result holds no 'total_energy'"):
        plots.plot_result(spatial, "energy")
    assert "energy" not in plots.available_kinds(spatial)


def test_work_precision_from_rows_and_csv(tmp_path):
    rows = [{"method": "adams", "time": 0.01, "error": 1e-4},
            {"method": "adams", "time": 0.03, "error": 1e-7},
            {"method": "bdf", "time": 0.02, "error": 1e-5},
            {"method": "bdf", "time": 0.05, "error": 0.0},   # exact: not on a log axis
            {"method": "rk4", "time": "nan", "error": 1e-3}]  # failed run
    fig = plots.plot_work_precision(rows, tmp_path / "wp.png")
    lines = fig.axes[0].get_lines()
    assert [ln.get_label() for ln in lines] == ["adams", "bdf"]
    np.testing.assert_array_equal(lines[0].get_xdata(), [0.01, 0.03])
    np.testing.assert_array_equal(lines[0].get_ydata(), [1e-4, 1e-7])
    assert fig.axes[0].get_xscale() == "log" and fig.axes[0].get_yscale() == "log"
    path = tmp_path / "wp.csv"
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, ["method", "time", "error"])
        writer.writeheader()
        writer.writerows(rows)
    fig2 = plots.plot_work_precision(path, tmp_path / "wp2.png")
    np.testing.assert_array_equal(fig2.axes[0].get_lines()[1].get_ydata(), [1e-5])
    # the benchmark CSV's column names
    bench = [{"formulation": "kkt_ode", "integrator": "adams", "solve_seconds": "0.1",
              "error": "1e-6"}]
    fig3 = plots.plot_work_precision(bench, method=("formulation", "integrator"),
                                     time="solve_seconds")
    assert fig3.axes[0].get_lines()[0].get_label() == "kkt_ode/adams"
    with pytest.raises(AnalysisError, match="no column 'method'"):
        plots.plot_work_precision(bench)
    with pytest.raises(AnalysisError, match="no work-precision row"):
        plots.plot_work_precision(rows[3:])


# ---------------------------------------------------------------------- geometry, frames
@pytest.mark.parametrize("which", ["planar", "spatial"])
def test_drawn_points_match_the_system(which, planar, spatial):
    """Marker points placed by numpy (r_G + A u) equal the System's marker outputs, and every
    revolute/spherical joint point seen from body1 equals the one seen from body2."""
    result = planar if which == "planar" else spatial
    mech = result.mechanism()
    pts = geometry.body_points(result)
    geo = geometry.Geometry.from_mechanism(mech)
    labels = [label for label, _ in geo.points["crank"]]
    drawn = pts["crank"][:, labels.index("marker:crank_pin")]
    # the same point through two formulations: rounding only
    np.testing.assert_allclose(drawn, result.marker("crank_pin")["position"], rtol=0,
                               atol=1e-12)
    # joint A (crank-rod): the constraint holds to the analyses' tolerance (1e-8 m)
    on_crank = pts["crank"][:, labels.index("joint:A")]
    rod_labels = [label for label, _ in geo.points["rod"]]
    on_rod = pts["rod"][:, rod_labels.index("joint:A")]
    gap = np.abs(on_crank - on_rod).max()
    assert gap < 1e-8
    np.testing.assert_allclose(geometry.joint_points(result)["A"], on_rod, atol=0)
    # a crank of 0.1 m: the pin stays 0.1 m from the bearing O at the origin
    np.testing.assert_allclose(np.linalg.norm(drawn, axis=1), 0.1, atol=1e-8)


def test_still_frame_planar_and_spatial(planar, spatial, tmp_path):
    fig = draw_frame(planar, index=5, ghosts=3, trace="crank_pin", out=tmp_path / "p.png",
                     dpi=50)
    trace = next(ln for ln in fig.axes[0].get_lines() if ln.get_color() == "0.2")
    np.testing.assert_array_equal(trace.get_xdata(), planar.marker("crank_pin")["position"]
                                  [:6, 0])
    fig3 = draw_frame(spatial, time=0.25, out=tmp_path / "s.png", dpi=50)
    assert fig3.axes[0].name == "3d"
    for name in ("p.png", "s.png"):
        assert (tmp_path / name).stat().st_size > 1000
    with pytest.raises(AnalysisError, match=r"unknown marker.*nowhere"):
        draw_frame(planar, trace="nowhere")
    no_temporaries(tmp_path)


def test_animation_gif_frames(spatial, tmp_path):
    anim = animate(spatial, max_frames=4)
    out = save_animation(anim, tmp_path / "s.gif", dpi=40)
    with Image.open(out) as im:
        assert im.n_frames == 4
    no_temporaries(tmp_path)
    if shutil.which("ffmpeg") is None:
        with pytest.raises(AnalysisError, match="MP4 needs ffmpeg"):
            save_animation(animate(spatial, max_frames=2), tmp_path / "s.mp4")
        assert not (tmp_path / "s.mp4").exists()


# ---------------------------------------------------------------------- CLI
def run(capsys, *argv: str) -> tuple[int, str, str]:
    status = cli.main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_animate_scene_writes_gif(capsys, tmp_path):
    out = tmp_path / "slider_crank.gif"
    status, stdout, err = run(capsys, "animate", str(SLIDER_CRANK), "--t-end", "0.5",
                              "--steps", "12", "--out", str(out), "--trace", "crank_pin",
                              "--json")
    assert status == 0, err
    data = json.loads(stdout)
    with Image.open(out) as im:  # N + 1 output times, one frame each
        assert im.n_frames == 13 == data["frames"]
    assert data["t_end"] == pytest.approx(0.5, abs=1e-12)
    no_temporaries(tmp_path)


def test_cli_plot_and_animate_saved_result(capsys, tmp_path):
    npz = tmp_path / "run.npz"
    status, _, err = run(capsys, "simulate", str(SLIDER_CRANK), "--t-end", "0.2", "--steps",
                         "10", "--out", str(npz))
    assert status == 0, err
    fig = tmp_path / "run.png"
    status, stdout, err = run(capsys, "plot", str(npz), "--kind", "energy", "--kind",
                              "reactions", "--out", str(fig), "--json")
    assert status == 0, err
    assert json.loads(stdout)["kinds"] == ["energy", "reactions"]
    assert fig.stat().st_size > 1000
    status, stdout, err = run(capsys, "plot", str(npz), "--out", str(tmp_path / "all.png"))
    assert status == 0 and "(6 panels: joint angles [rad]; joint translations [m]" in stdout
    status, stdout, err = run(capsys, "animate", str(npz), "--out", str(tmp_path / "f.png"))
    assert status == 0, err
    assert (tmp_path / "f.png").stat().st_size > 1000
    # errors: one line naming the culprit
    status, _, err = run(capsys, "plot", str(tmp_path / "missing.npz"), "--out",
                         str(tmp_path / "x.png"))
    assert status == 1 and err.startswith("error: cannot read result file") and "missing.npz" \
        in err
    status, _, err = run(capsys, "animate", str(npz), "--out", str(tmp_path / "x.avi"))
    assert status == 1 and "unknown suffix '.avi'" in err
    no_temporaries(tmp_path)


# ---------------------------------------------------------------------- result files
@pytest.fixture(scope="module")
def planar_absolute():
    """The slider-crank of ``planar`` in absolute coordinates (virtual machine, no scene)."""
    mech = casmbd.load_scene(SLIDER_CRANK)
    mech.coordinates = "absolute"
    return casmbd.simulate(mech, t_end=0.5, steps=20, mode="vm")


#: columns named by the coordinates and the equations, and their index in q/v and lambda:
#: joint coordinates O, A, slide with B's 2 loop equations and the driver (automatic choice),
#: or x, y, angle per body with 8 joint equations and the driver (absolute)
CSV_COLUMNS = {"auto": {"q[O.angle]": ("q", 0), "v[slide.translation]": ("v", 2),
                        "lambda[B.y]": ("lambda", 1),
                        "lambda[crank_speed.coordinate]": ("lambda", 2)},
               "absolute": {"q[crank.angle]": ("q", 2), "v[slider.x]": ("v", 6),
                            "lambda[crank_speed.coordinate]": ("lambda", 8)}}


@pytest.mark.parametrize("coordinates", ["auto", "absolute"])
def test_csv_export_reloads_to_the_arrays(request, coordinates, tmp_path):
    planar = request.getfixturevalue("planar" if coordinates == "auto" else "planar_absolute")
    path = planar.to_csv(tmp_path / "run.csv")
    with open(path, newline="") as fh:
        header = next(csv.reader(fh))
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    assert table.shape == (len(planar.t), len(header))
    col = {name: table[:, k] for k, name in enumerate(header)}
    checks = {name: planar[key][:, k] for name, (key, k) in CSV_COLUMNS[coordinates].items()}
    checks |= {"t": planar.t,
               "body_positions[rod.y]": planar["body_positions"][:, 3],
               "angle_positions[rod.angle]": planar["angle_positions"][:, 1],
               "marker_positions[crank_pin.x]": planar["marker_positions"][:, 0],
               "joint_positions[slide]": planar["joint_positions"][:, 3],
               "joint_reactions[A.Fy]": planar["joint_reactions"][:, 1, 1],
               "joint_reactions[slide.M]": planar["joint_reactions"][:, 3, 2],
               "driver_efforts[crank_speed.effort]": planar["driver_efforts"][:, 0],
               "total_energy": planar["total_energy"]}
    for name, expected in checks.items():
        np.testing.assert_allclose(col[name], expected, rtol=1e-12, atol=1e-12,
                                   err_msg=name)
    # every series is there: one column per scalar component of every array on the grid
    n_cols = 1 + sum(int(np.prod(a.shape[1:])) for a in planar.arrays.values())
    assert len(header) == n_cols == len(set(header))
    # and every value is the array's, in storage order
    flat = np.concatenate([a.reshape(len(planar.t), -1) for a in planar.arrays.values()],
                          axis=1)
    np.testing.assert_allclose(table[:, 1:], flat, rtol=1e-12, atol=1e-12)
    no_temporaries(tmp_path)


def test_npz_reload_and_embedded_scene(planar, tmp_path):
    path = planar.save(tmp_path / "run.npz")
    again = casmbd.load_result(path)
    assert casmbd.Result.load(path).kind == again.kind == "simulation"
    assert set(again.arrays) == set(planar.arrays)
    for key, arr in planar.arrays.items():
        np.testing.assert_array_equal(again.arrays[key], arr, err_msg=key)
    np.testing.assert_array_equal(again.t, planar.t)
    assert again.names == planar.names
    assert again.scene == SLIDER_CRANK.read_text()
    # the embedded scene re-loads to the same mechanism: coordinates and initial pose
    mech = again.mechanism()
    original = casmbd.System(casmbd.load_scene(SLIDER_CRANK))
    system = casmbd.System(mech)
    assert system.coordinate_names == original.coordinate_names == planar.names["coordinates"]
    np.testing.assert_array_equal(system.initial_coordinates(),
                                  original.initial_coordinates())
    # the scene's start is assembled (crank horizontal): the run starts there
    np.testing.assert_allclose(planar["q"][0], system.initial_coordinates(), atol=1e-12)
    no_temporaries(tmp_path)


def test_result_without_scene_names_the_fix(planar):
    bare = casmbd.Result(planar.kind, planar.t, planar.arrays, planar.names)
    with pytest.raises(AnalysisError, match="holds no scene text"):
        bare.mechanism()
    # with the mechanism passed explicitly the drawing works
    pts = geometry.body_points(bare, planar.mechanism())
    np.testing.assert_array_equal(pts["rod"], geometry.body_points(planar)["rod"])


def test_atomic_write_leaves_no_temporary_file(tmp_path):
    target = tmp_path / "data.txt"
    atomic_write(target, lambda tmp: pathlib.Path(tmp).write_text("first"))
    assert target.read_text() == "first"

    def failing(tmp):
        pathlib.Path(tmp).write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, failing)
    assert target.read_text() == "first"  # the old file is intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.txt"]


def test_python_api_results_embed_the_scene(tmp_path):
    """simulate / kinematics / inverse_dynamics called from Python embed the scene text of a
    loaded scene, so a saved result re-loads its mechanism (same coordinates, same start)."""
    mech = casmbd.load_scene(REPO_ROOT / "examples" / "slider_crank.toml")
    for res in (casmbd.simulate(mech, 0.1, 2), casmbd.kinematics(mech, t_end=0.1, steps=2)):
        again = casmbd.load_result(res.save(tmp_path / f"{res.kind}.npz")).mechanism()
        assert again.name == mech.name
        np.testing.assert_array_equal(casmbd.System(again).initial_coordinates(),
                                      casmbd.System(mech).initial_coordinates())
    inv = casmbd.load_scene(REPO_ROOT / "examples" / "slider_crank_inverse.toml")
    assert casmbd.inverse_dynamics(inv, t_end=0.1, steps=2).scene == inv.scene_text
