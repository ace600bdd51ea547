"""Sweeps of event-driven scenes (issue 30, item 2: one pipeline per analysis).

A swept point runs through the same entry as ``simulate`` — phase by phase with its impacts,
contacts and stops — so every point equals ``simulate`` of the scene written with that
parameter value, to 1e-12 (the same compiled code, the same event search; serially and on two
processes or a two-worker Dask cluster), and the ball never falls through the floor (it did:
y = −3.805 at t = 1 s, every point "ok").
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

from casmbd.analysis.dynamics.simulate import Simulators, simulate
from casmbd.analysis.studies.sweep import sweep
from casmbd.io.scene import loads_scene
from casmbd.io.scene_points import scene_with

REPO = pathlib.Path(__file__).resolve().parents[3]
BALL = REPO / "examples" / "bouncing_ball.toml"
STOPS = REPO / "examples" / "pendulum_stops.toml"

cache = private_cache("casmbd_cache_sweep_events", scope="module", autouse=False,
                      CASMBD_COMPILE=None)

#: the ball pushed down by a parameter force F (so that the sweep changes the motion)
PUSHED_BALL = BALL.read_text().replace("[[contacts]]", """[[forces]]
name = "push"
type = "force"
body = "ball"
value = [0.0, "-F"]

[[contacts]]""").replace("h0 = 1.0 ", "F = 0.0\nh0 = 1.0 ")
#: the pendulum with a damper of parameter rate c at its pin
DAMPED_STOPS = STOPS.read_text() + """
[[forces]]
name = "damper"
type = "rotational_spring_damper"
joint = "pin"
damping = "c"
"""
DAMPED_STOPS = DAMPED_STOPS.replace("m = 1.0\n", "m = 1.0\nc = 0.0\n", 1)

T_END, STEPS = 1.0, 10

def _points_equal_simulate(text: str, source: str, points: list[dict], result, saved: bool):
    for i, values in enumerate(points):
        direct = simulate(loads_scene(scene_with(text, values, source)), T_END, STEPS)
        assert result.status[i] == "ok", result.errors[i]
        if saved:
            from casmbd.results import load

            point = load(result.files[i])
            np.testing.assert_allclose(point.arrays["q"], direct.arrays["q"], rtol=0,
                                       atol=1e-12)
            np.testing.assert_allclose(point.arrays["v"], direct.arrays["v"], rtol=0,
                                       atol=1e-12)
            assert [(e["element"], e["kind"]) for e in point.events] == \
                [(e["element"], e["kind"]) for e in direct.events]
            np.testing.assert_allclose([e["time"] for e in point.events],
                                       [e["time"] for e in direct.events], rtol=0, atol=1e-12)
        for k, name in enumerate(direct.names["coordinates"]):
            np.testing.assert_allclose(result[f"final:q[{name}]"][i], direct.arrays["q"][-1, k],
                                       rtol=0, atol=1e-12)


@pytest.mark.parametrize("executor", ["serial", "processes"])
def test_swept_ball_equals_simulate_and_stays_above_the_floor(cache, tmp_path, executor):
    """The ball of m = 1, 2 kg pushed by F = 0, 5, 20 N: each point = simulate (1e-12), the
    lowest point of the ball never below the floor (1e-9 m), one impact before t = 1 s at
    the closed-form time t₁ = sqrt(2 h0 / (g + F/m)) (1e-7 s at the default rtol 1e-8)."""
    points = [{"m": m, "F": f} for m in (1.0, 2.0) for f in (0.0, 5.0, 20.0)]
    mech = loads_scene(PUSHED_BALL, source="pushed_ball.toml")
    res = sweep(mech, points=points, t_end=T_END, steps=STEPS, out_dir=tmp_path,
                executor=executor, workers=2 if executor == "processes" else None)
    assert list(res.status) == ["ok"] * len(points)
    _points_equal_simulate(PUSHED_BALL, "pushed_ball.toml", points, res, saved=True)
    for i, values in enumerate(points):
        from casmbd.results import load

        point = load(res.files[i])
        y = point.arrays["q"][:, 1]
        assert np.min(y) - 0.1 > -1e-9  # the centre stays a radius above the floor
        acc = 9.81 + values["F"] / values["m"]
        impacts = [e["time"] for e in point.events if e["kind"] == "impact"]
        assert abs(impacts[0] - math.sqrt(2.0 / acc)) < 1e-7  # rtol 1e-8 (the default)


def test_swept_examples_equal_simulate_on_a_dask_cluster(cache):
    """The issue's reproduction: bouncing_ball and pendulum_stops swept over m = 1, 2 (and
    the damped pendulum over its damping rate) on two Dask workers; each point = simulate
    (1e-12); the ball's centre ends at the closed form after one bounce,
    y(1) = r + e g t₁ (1 − t₁) − g (1 − t₁)²/2 (1e-7 m at the default rtol 1e-8), the
    pendulum within its stops."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        runs = []
        for text, source, points in (
                (BALL.read_text(), str(BALL), [{"m": 1.0}, {"m": 2.0}]),
                (STOPS.read_text(), str(STOPS), [{"m": 1.0}, {"m": 2.0}]),
                (DAMPED_STOPS, "damped_stops.toml", [{"c": 0.0}, {"c": 0.2}, {"c": 1.0}])):
            res = sweep(loads_scene(text, source=source), points=points, t_end=T_END,
                        steps=STEPS, executor=cluster.scheduler_address)
            assert res.stats["executor"] == "dask"
            runs.append((text, source, points, res))
    for text, source, points, res in runs:
        _points_equal_simulate(text, source, points, res, saved=False)
    ball = runs[0][3]
    t1 = math.sqrt(2.0 / 9.81)
    y_end = 0.1 + 0.8 * 9.81 * t1 * (1.0 - t1) - 0.5 * 9.81 * (1.0 - t1) ** 2
    np.testing.assert_allclose(ball["final:q[ball.y]"], [y_end, y_end], rtol=0, atol=1e-7)
    for _, _, _, res in runs[1:]:
        assert np.all(res["final:q[pin.angle]"] >= -1.0 - 1e-9)
    damped = runs[2][3]["final:q[pin.angle]"]
    assert len(set(np.round(damped, 6))) == 3  # the damping changes the motion


def test_simulators_are_reused_across_points(cache):
    """One base simulator per process for the event-free phase: a second run at other values
    builds nothing and gives what a fresh simulate gives (1e-12)."""
    mech = loads_scene(DAMPED_STOPS, source="damped_stops.toml")
    sims = Simulators()
    first = simulate(mech, T_END, STEPS, simulators=sims)
    built = sims.built
    mech.parameters = {**mech.parameters, "c": 0.5}
    again = simulate(mech, T_END, STEPS, simulators=sims)
    assert sims.built == built and sims.reused >= 1
    fresh = simulate(loads_scene(scene_with(DAMPED_STOPS, {"c": 0.5}, "d.toml")), T_END, STEPS)
    np.testing.assert_allclose(again.arrays["q"], fresh.arrays["q"], rtol=0, atol=1e-12)
    assert np.max(np.abs(again.arrays["q"] - first.arrays["q"])) > 1e-3


def test_sweep_over_the_restitution_and_the_stop(cache):
    """Restitution coefficients and stops given by parameters are evaluated at run time: a
    sweep over them is no longer refused as load-time; each point = simulate (1e-12), the
    ball's centre after one bounce at y(1) = r + e g t₁ (1 − t₁) − g (1 − t₁)²/2 (1e-7 m),
    the pendulum never past its swept stop (1e-9 rad)."""
    ball = BALL.read_text().replace("restitution = 0.8", 'restitution = "eps"').replace(
        "m = 1.0 ", "eps = 0.8\nm = 1.0 ")
    points = [{"eps": e} for e in (0.7, 0.8, 0.9)]  # the second impact after 1 s
    res = sweep(loads_scene(ball, source="ball_e.toml"), points=points, t_end=T_END,
                steps=STEPS)
    _points_equal_simulate(ball, "ball_e.toml", points, res, saved=False)
    t1 = math.sqrt(2.0 / 9.81)
    for i, values in enumerate(points):
        y_end = 0.1 + values["eps"] * 9.81 * t1 * (1.0 - t1) - 0.5 * 9.81 * (1.0 - t1) ** 2
        assert abs(res["final:q[ball.y]"][i] - y_end) < 1e-7
    stops = STOPS.read_text().replace("lower = -1.0 ", 'lower = "stop"').replace(
        "m = 1.0\n", "m = 1.0\nstop = -1.0\n", 1)
    points = [{"stop": s} for s in (-1.2, -0.8, -0.4)]
    res = sweep(loads_scene(stops, source="stops.toml"), points=points, t_end=T_END,
                steps=STEPS, outputs=["final:q[pin.angle]", "min:q[pin.angle]"])
    _points_equal_simulate(stops, "stops.toml", points, res, saved=False)
    assert np.all(res["min:q[pin.angle]"] >= np.array([-1.2, -0.8, -0.4]) - 1e-9)


#: a block thrown up an incline, exact Coulomb friction F_c = 7 N at its slide (stick-slip
#: events); its mass a parameter: it sticks when m g sin α < F_c (m < 2.41 kg), else slides back
INCLINE = """
[scene]
name = "incline"
gravity = [0.0, -9.81]
[parameters]
mb = 2.0
[[bodies]]
name = "block"
mass = "mb"
inertia = 0.1
position = [0.0, 0.0]
velocity = ["3*cos(0.3)", "3*sin(0.3)"]
[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [0.0, 0.0]
axis = ["cos(0.3)", "sin(0.3)"]
friction = { coulomb = 7.0, stick_slip = true }
"""


def test_stick_slip_sweep_equals_simulate(cache):
    """Stick-slip joint friction is an event element too: each point (m = 1.5, 2, 3 kg; the
    last slides back) = simulate (1e-12), the events as simulate names them."""
    points = [{"mb": m} for m in (1.5, 2.0, 3.0)]
    res = sweep(loads_scene(INCLINE, source="incline.toml"), points=points, t_end=1.5,
                steps=15)
    assert list(res.status) == ["ok"] * 3
    kinds = []
    for i, values in enumerate(points):
        direct = simulate(loads_scene(scene_with(INCLINE, values, "incline.toml")), 1.5, 15)
        kinds.append([e["kind"] for e in direct.events])
        for k, name in enumerate(direct.names["coordinates"]):
            assert abs(res[f"final:q[{name}]"][i] - direct.arrays["q"][-1, k]) <= 1e-12
    assert kinds == [["stick"], ["stick"], ["slip"]]


def test_cli_sweep_of_the_issue_keeps_the_ball_above_the_floor(cache, capsys):
    """The issue's reproduction, `casmbd sweep examples/bouncing_ball.toml --param m=1,2
    --t-end 1 --steps 10 --json`: y(1) = 0.568004 m at both points (was −3.805)."""
    import json

    from casmbd import cli

    status = cli.main(["sweep", str(BALL), "--param", "m=1,2", "--t-end", "1", "--steps", "10",
                       "--json"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    data = json.loads(captured.out)
    ys = [p["outputs"]["final:q[ball.y]"] for p in data["points"]]
    assert ys == pytest.approx([0.568004, 0.568004], abs=1e-6)


def test_compliant_sweep_reports_the_events_simulate_reports(cache, tmp_path):
    """A compliant floor (Hunt-Crossley force, no event detection): the sweep runs one
    Simulator with p set per point, and each saved point carries the contact/detach events
    that simulate interpolates on its grid (same times to 1e-12) and its trajectory (1e-12)."""
    text = PUSHED_BALL.replace('model = "impact"',
                               'model = "compliant"\nstiffness = 1e5\ndamping = 200.0')
    points = [{"F": 0.0}, {"F": 5.0}]
    res = sweep(loads_scene(text, source="soft.toml"), points=points, t_end=T_END, steps=40,
                out_dir=tmp_path)
    from casmbd.results import load

    for i, values in enumerate(points):
        direct = simulate(loads_scene(scene_with(text, values, "soft.toml")), T_END, 40)
        point = load(res.files[i])
        assert [e["kind"] for e in point.events] == [e["kind"] for e in direct.events]
        assert [e["kind"] for e in direct.events][:2] == ["contact", "detach"]
        np.testing.assert_allclose([e["time"] for e in point.events],
                                   [e["time"] for e in direct.events], rtol=0, atol=1e-12)
        np.testing.assert_allclose(point.arrays["q"], direct.arrays["q"], rtol=0, atol=1e-12)


def test_statics_sweep_rests_on_the_floor_and_the_stop(cache):
    """A statics sweep of a scene with impact contacts or stops goes through the statics entry
    itself (the active set of closed gaps): the ball rests on the floor carrying m g, the
    pendulum on its stop at −1 rad carrying m g (L/2) cos 1 = 2.650 N m per kg (1e-10), each
    point = static_equilibrium of the scene at that value (1e-12).  Before, the pendulum's
    points hung straight down through the stop (−1.5708 rad, "ok") and the ball's failed."""
    from casmbd.analysis.statics.statics import static_equilibrium

    for path, coord, force in ((BALL, "ball.y", lambda m: m * 9.81),
                               (STOPS, "pin.angle",
                                lambda m: m * 9.81 * 0.5 * math.cos(1.0))):
        text = path.read_text()
        points = [{"m": 1.0}, {"m": 2.0}]
        res = sweep(loads_scene(text, source=str(path)), points=points, analysis="statics",
                    outputs=[f"final:q[{coord}]", "final:contact_forces[0]"], executor="processes",
                    workers=2)
        assert list(res.status) == ["ok", "ok"], res.errors
        for i, values in enumerate(points):
            direct = static_equilibrium(loads_scene(scene_with(text, values, str(path))))
            k = direct.names["coordinates"].index(coord)
            assert abs(res[f"final:q[{coord}]"][i] - direct.q[k]) <= 1e-12
            first = next(iter(direct.contacts.values()))["normal_force"]
            assert abs(res["final:contact_forces[0]"][i] - first) <= 1e-12
            assert abs(first - force(values["m"])) <= 1e-10
    assert np.all(res["final:q[pin.angle]"] >= -1.0 - 1e-12)
