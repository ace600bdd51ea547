"""Issue 19, item 2: linearising at the static equilibrium or a stored state, and ONE
stability verdict shared by ``statics`` and ``linearize`` (casmbd.analysis.statics.stability).

Tolerances: matrices of two routes to the same state agree to 1e-9 (relative to the largest
entry; both routes evaluate the same Functions at states equal to ~1e-13), frequencies match
closed forms to 1e-9 relative (the equilibria are exact to round-off).
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
from casmbd.analysis.statics.linearize import EQUILIBRIUM_RTOL, NOT_AN_EQUILIBRIUM, linearize
from casmbd.analysis.statics.statics import static_equilibrium
from casmbd.errors import AnalysisError, ModelError

ROOT = pathlib.Path(__file__).resolve().parents[3]
TOP = str(ROOT / "examples" / "heavy_top.toml")          # spherical pendulum, released tilted
PENDULUM2 = str(ROOT / "examples" / "double_pendulum.toml")
CRANE = str(ROOT / "examples" / "crane.toml")
G = 9.81
MATRICES = ("M", "C", "K", "B", "A", "N")

ROD = """
[scene]
name = "{name}"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "rod"
mass = 1.0
inertia = "1.0 / 12"
position = [0.0, {y}]
angle = {angle}

[[joints]]
name = "pivot"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
"""


_vm = private_cache("cache_lin", CASMBD_COMPILE="0")


def run(capsys, *argv: str) -> tuple[dict, str]:
    """JSON and text output of one verb."""
    assert cli.main([*argv, "--json"]) == 0, capsys.readouterr().err
    data = json.loads(capsys.readouterr().out)
    assert cli.main(list(argv)) == 0, capsys.readouterr().err
    return data, capsys.readouterr().out


def rod_scene(tmp_path, inverted: bool) -> str:
    path = tmp_path / ("inverted.toml" if inverted else "hanging.toml")
    path.write_text(ROD.format(name=path.stem, y=0.5 if inverted else -0.5,
                               angle='"pi / 2"' if inverted else '"-pi / 2"'))
    return str(path)


def assert_same_matrices(a: dict, b, rtol: float = 1e-9) -> None:
    for key in MATRICES:
        x, y = np.asarray(a[key], float), np.asarray(getattr(b, key), float)
        assert x.shape == y.shape, key
        if x.size:
            scale = max(float(np.max(np.abs(y))), 1e-300)
            assert float(np.max(np.abs(x - y))) <= rtol * scale, key


@pytest.mark.parametrize("inverted,verdict", [(False, "stable"), (True, "unstable")])
def test_pendulum_verdicts_agree(capsys, tmp_path, inverted, verdict):
    """Hanging rod: stable, ω² = 3g/(2L) (1e-9); upright rod: unstable, rate² = 3g/(2L). The
    statics verb and the linearize verb give the same word, JSON verdict and "stable"."""
    scene = rod_scene(tmp_path, inverted)
    stat, stat_text = run(capsys, "statics", scene)
    lin, lin_text = run(capsys, "linearize", scene)
    assert stat["stability"]["verdict"] == lin["verdict"] == verdict
    assert stat["stable"] is lin["stable"] is (not inverted)
    assert lin["equilibrium"] is True and lin["residual"] <= lin["residual_tolerance"]
    assert f"): {verdict}" in stat_text.splitlines()[0]
    assert lin_text.splitlines()[0].endswith(f"1 degree of freedom, {verdict}")
    np.testing.assert_allclose(lin["stability"]["eigenvalues"],
                               stat["stability"]["eigenvalues"], rtol=1e-12)
    rate2 = 1.5 * G / 1.0
    if inverted:
        assert max(e[0] for e in lin["eigenvalues"]) == pytest.approx(math.sqrt(rate2),
                                                                       rel=1e-9)
    else:
        assert (2 * math.pi * lin["frequencies_hz"][0]) ** 2 == pytest.approx(rate2, rel=1e-9)


def hanging_top(tmp_path) -> str:
    """The heavy top released 0.3 rad from hanging (th0 = π − 0.3): its nearest equilibrium,
    which the statics search finds (issue 30), is the hanging one."""
    text = open(TOP, encoding="utf-8").read()
    assert "th0 = 0.3 " in text
    path = tmp_path / "hanging_top.toml"
    path.write_text(text.replace("th0 = 0.3 ", "th0 = 2.8415926535897931 ", 1), encoding="utf-8")
    return str(path)


def test_spherical_pendulum_is_neutral_about_the_vertical(capsys, tmp_path):
    """The top hanging from its ball joint: both verbs say neutral with ONE null direction,
    named alike, and that direction turns the body about the vertical (ω ∥ z to 1e-9, centre
    of mass still); the two swing modes have ω² = m g L / (I1 + m L²) (1e-9)."""
    top = hanging_top(tmp_path)
    stat, stat_text = run(capsys, "statics", top)
    lin, lin_text = run(capsys, "linearize", top, "--at-equilibrium")
    assert stat["stability"]["verdict"] == lin["verdict"] == "neutral"
    assert stat["stable"] is None and lin["stable"] is None
    assert len(lin["stability"]["null_directions"]) == 1
    assert lin["stability"]["null_directions"] == stat["stability"]["null_directions"]
    name = lin["stability"]["null_directions"][0]["dominant"]
    assert f"neutral (null directions: {name})" in lin_text
    assert f"neutral (null directions: {name})" in stat_text
    # the null direction, as a coordinate change, is a rotation about the vertical
    k_bar, n = np.asarray(lin["K"]), np.asarray(lin["N"])
    w, vec = np.linalg.eigh(0.5 * (k_bar + k_bar.T))
    dq = n @ vec[:, np.argmin(np.abs(w))]
    e0, e1, e2, e3 = lin["q"][3:7]
    rate = 2 * np.array([[-e1, e0, -e3, e2], [-e2, e3, e0, -e1], [-e3, -e2, e1, e0]])
    omega = rate @ dq[3:7]  # global angular velocity of the Euler-parameter change
    assert np.max(np.abs(dq[:3])) <= 1e-9 and np.max(np.abs(omega[:2])) <= 1e-9 * abs(omega[2])
    mech = casmbd.load_scene(TOP)
    m, length, i1 = (mech.parameters[k] for k in ("m", "L", "I1"))
    omega2 = m * G * length / (i1 + m * length**2)
    swing = sorted(lin["frequencies_hz"])[1:]
    np.testing.assert_allclose((2 * np.pi * np.asarray(swing)) ** 2, omega2, rtol=1e-9)
    assert sorted(lin["frequencies_hz"])[0] == 0.0
    assert sorted(lin["damping_ratios"]) == [0.0, 0.0, 0.0]  # the null mode is not a saddle


def test_cli_at_equilibrium_equals_the_python_route(capsys):
    """The top starts tilted (not an equilibrium): ``--at-equilibrium`` gives the matrices of
    ``linearize(m, q=static_equilibrium(m).q)`` and of ``linearize(m, at="equilibrium")``."""
    mech = casmbd.load_scene(TOP)
    ref = linearize(mech, q=static_equilibrium(mech).q)
    data, text = run(capsys, "linearize", TOP, "--at-equilibrium")
    assert_same_matrices(data, ref)
    assert data["about"] == "equilibrium" and data["equilibrium"] is True
    assert "about the static equilibrium (" in text
    api = linearize(casmbd.load_scene(TOP), at="equilibrium")
    assert_same_matrices(api.to_json(), ref)
    # released 0.3 rad from upright, the nearest equilibrium is the upright top: unstable
    # (issue 30: statics no longer slides into the hanging basin)
    assert api.verdict == ref.verdict == "unstable"
    assert data["q"][2] == pytest.approx(float(mech.parameters["L"]), abs=1e-12)


def test_at_a_stable_equilibrium(capsys):
    """``stable=True`` / ``--stable`` with the equilibrium: about the hanging top that
    ``static_equilibrium(m, stable=True)`` finds (matrices 1e-9), neutral about the vertical;
    without ``at="equilibrium"`` (``--at-equilibrium``) it is refused by name."""
    mech = casmbd.load_scene(TOP)
    eq = static_equilibrium(mech, stable=True)
    assert eq.body_positions[0, 2] == pytest.approx(-float(mech.parameters["L"]), abs=1e-12)
    ref = linearize(mech, q=eq.q)
    data, text = run(capsys, "linearize", TOP, "--at-equilibrium", "--stable")
    assert "neutral (null directions: " in text.splitlines()[0]
    assert_same_matrices(data, ref)
    assert data["verdict"] == ref.verdict == "neutral"
    assert_same_matrices(linearize(mech, at="equilibrium", stable=True).to_json(), ref)
    with pytest.raises(ModelError, match="stable=True goes with at='equilibrium'"):
        linearize(mech, stable=True)
    assert cli.main(["linearize", TOP, "--stable"]) == 1
    assert "--stable goes with --at-equilibrium" in capsys.readouterr().err


def test_not_an_equilibrium_has_no_verdict(capsys):
    """Linearised where it was released (tilted, at rest) the top is no equilibrium: no
    verdict, the residual named; before issue 19 this printed a stability word."""
    data, text = run(capsys, "linearize", TOP)
    assert data["equilibrium"] is False and data["verdict"] == NOT_AN_EQUILIBRIUM
    assert data["stable"] is None and data["stability"] is None
    assert data["spectrally_stable"] is None
    # the residual is the unbalanced gravity: max |M q̈| of the released top, > the tolerance
    assert data["residual"] > 1e3 * data["residual_tolerance"]
    assert data["residual_tolerance"] == pytest.approx(EQUILIBRIUM_RTOL * G, rel=1e-12)
    first = text.splitlines()[0]
    assert first.endswith(f"3 degrees of freedom, {NOT_AN_EQUILIBRIUM}")
    assert "UNSTABLE" not in text and "stable" not in text.replace("not an equilibrium", "")
    assert "force residual max |Q - Cq^T lambda|" in text and "--at-equilibrium" in text


@pytest.mark.parametrize("dimension,null", [(2, 3), (3, 6)])
def test_free_body_without_gravity_is_neutral_in_every_rigid_body_direction(dimension, null):
    """A free body, no forces: K̄ = 0, neutral in all 3 (plane) / 6 (space) directions, both
    analyses; with gravity it is no equilibrium (linearize says so, statics finds none)."""
    def free(gravity):
        m = casmbd.Mechanism(f"free{dimension}", gravity=gravity)
        if dimension == 2:
            m.add_body("box", 2.0, 0.1, (0.3, 0.4))
        else:
            m.add_body("box", 2.0, [0.1, 0.2, 0.3], (0.3, 0.4, 0.5))
        return m

    zero = (0.0,) * dimension
    lin, stat = linearize(free(zero)), static_equilibrium(free(zero))
    assert lin.verdict == stat.stability.verdict == "neutral"
    assert len(lin.stability.null_directions) == len(stat.stability.null_directions) == null
    assert lin.stability.null_coordinates() == stat.stability.null_coordinates()
    assert np.all(lin.frequencies_hz == 0.0) and np.all(lin.damping_ratios == 0.0)
    heavy = linearize(free((0.0,) * (dimension - 1) + (-G,)))
    assert heavy.verdict == NOT_AN_EQUILIBRIUM and heavy.stable is None
    assert heavy.stats["residual"] == pytest.approx(2.0 * G, rel=1e-12)
    with pytest.raises(AnalysisError, match="no static equilibrium"):
        static_equilibrium(free((0.0,) * (dimension - 1) + (-G,)))


def test_damped_pendulum_verdict_from_the_stiffness():
    """With a rotational damper the verdict is still the stiffness one (stable), the
    eigenvalues of A are a damped pair with Re s = −c / (2 I) (1e-9)."""
    m = casmbd.Mechanism("damped", gravity=(0, -G))
    m.add_body("rod", 1.0, 1.0 / 12, (0.0, -0.5), angle=-math.pi / 2)
    m.add_revolute("pivot", "ground", "rod", (0, 0))
    m.add_rotational_spring_damper("d", "pivot", stiffness=0.0, damping=0.2)
    lin = linearize(m)
    assert lin.verdict == static_equilibrium(m).stability.verdict == "stable"
    np.testing.assert_allclose(lin.eigenvalues.real, -0.2 / (2 / 3), rtol=1e-9)


def test_from_a_saved_simulation_equals_linearize_at_that_state(capsys, tmp_path):
    """``--from RESULT --time T`` takes the output nearest T (0.52 → 0.5) and gives the matrices
    of ``linearize(m, q=q(0.5), v=v(0.5), t=0.5)`` (1e-9); a moving pendulum is no equilibrium."""
    out = tmp_path / "dp.npz"
    assert cli.main(["simulate", PENDULUM2, "--t-end", "1", "--steps", "10", "--rtol", "1e-12",
                     "--out", str(out), "--json"]) == 0, capsys.readouterr().err
    capsys.readouterr()
    res = casmbd.load_result(out)
    data, text = run(capsys, "linearize", PENDULUM2, "--from", str(out), "--time", "0.52")
    assert data["t"] == pytest.approx(0.5, abs=1e-12) and data["stats"]["state_index"] == 5
    ref = linearize(casmbd.load_scene(PENDULUM2), q=res["q"][5], v=res["v"][5], t=res.t[5])
    assert_same_matrices(data, ref)
    assert data["stats"]["projection_dq"] <= 1e-10  # rtol 1e-12: already on the constraints
    assert data["verdict"] == NOT_AN_EQUILIBRIUM and data["stable"] is None
    assert "at t = 0.5 (output 5, nearest to 0.52)" in text and "max |v| =" in text
    api = linearize(casmbd.load_scene(PENDULUM2), at=res, at_time=0.52)
    assert_same_matrices(api.to_json(), ref)


def test_from_a_drifted_simulation_is_projected(capsys, tmp_path):
    """At rtol 1e-8 the stored q violates the constraints by ~3e-8 (above the 1e-8 that q=
    accepts): the stored state is moved onto them and the move is reported.  Drift needs
    constraint equations: the scene is pinned to absolute coordinates; under the automatic
    choice the double pendulum is a tree (joint angles, no equations) and nothing moves."""
    scene = tmp_path / "double_pendulum_absolute.toml"
    text = pathlib.Path(PENDULUM2).read_text()
    scene.write_text(text.replace("[scene]\n", '[scene]\ncoordinates = "absolute"\n', 1))
    out = tmp_path / "drift.npz"
    assert cli.main(["simulate", str(scene), "--t-end", "1", "--steps", "10", "--out",
                     str(out), "--json"]) == 0, capsys.readouterr().err
    capsys.readouterr()
    data, _ = run(capsys, "linearize", str(scene), "--from", str(out), "--time", "1")
    res = casmbd.load_result(out)
    assert 0.0 < data["stats"]["projection_dq"] <= 1e-6
    assert np.max(np.abs(np.asarray(data["q"]) - res["q"][-1])) == pytest.approx(
        data["stats"]["projection_dq"], rel=1e-12)
    auto = tmp_path / "auto.npz"
    assert cli.main(["simulate", PENDULUM2, "--t-end", "1", "--steps", "10", "--out",
                     str(auto), "--json"]) == 0, capsys.readouterr().err
    capsys.readouterr()
    data, _ = run(capsys, "linearize", PENDULUM2, "--from", str(auto), "--time", "1")
    assert data["coordinates"] == ["shoulder.angle", "elbow.angle"]
    assert data["stats"]["projection_dq"] == 0.0
    assert np.array_equal(data["q"], casmbd.load_result(auto)["q"][-1])


def test_from_errors_name_the_time_and_the_mismatch(capsys, tmp_path):
    out = tmp_path / "dp.npz"
    assert cli.main(["simulate", PENDULUM2, "--t-end", "1", "--steps", "4", "--out",
                     str(out), "--json"]) == 0
    capsys.readouterr()
    crane = tmp_path / "crane_auto.toml"  # the scene pins absolute coordinates: choose here
    crane.write_text(pathlib.Path(CRANE).read_text().replace('coordinates = "absolute"',
                                                            'coordinates = "auto"'))
    cases = [([PENDULUM2, "--from", str(out), "--time", "2.5"],
              "time 2.5 is outside the result's output times [0, 1] (5 outputs)"),
             ([TOP, "--from", str(out), "--time", "0.5"],
              f"result file '{out}' is not of scene"),
             ([TOP, "--from", str(out), "--time", "0.5"],
              "(it has 2 coordinates, the scene 7)"),
             ([str(crane), "--from", str(out), "--time", "0.5"],  # both in joint coordinates
              f"is not of scene '{crane}' ('crane') (its coordinate 0 is 'shoulder.angle', the "
              "scene's 'rail.translation')"),
             ([PENDULUM2, "--from", str(out)], "--from RESULT.npz and --time T go together")]
    for argv, message in cases:
        assert cli.main(["linearize", *argv]) == 1
        err = capsys.readouterr().err
        assert message in err, err
    res = casmbd.load_result(out)
    with pytest.raises(AnalysisError, match=r"time -1 is outside .*\[0, 1\]"):
        linearize(casmbd.load_scene(PENDULUM2), at=res, at_time=-1.0)
    with pytest.raises(ModelError, match=r"either at=\.\.\. or q/v"):
        linearize(casmbd.load_scene(PENDULUM2), at="equilibrium", q=res["q"][0])
    with pytest.raises(ModelError, match="at must be 'equilibrium' or a result"):
        linearize(casmbd.load_scene(PENDULUM2), at="rest")
