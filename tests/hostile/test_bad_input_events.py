"""Bad input on the event path (impacts, contact, detach): the same named errors as a smooth
run, never an anonymous CVODES failure, and partial results kept.

Every case asserts the error class, the culprit (element, field) and the time; the partial
results of an integrator failure are compared with the closed form of the motion up to the
failure, and ``--out`` is written with them as on the smooth path.  A ball of radius 0.1 m
dropped from 1 m onto a floor (``examples/bouncing_ball.toml``) on CasADi's virtual machine
(``CASMBD_COMPILE=0``): each case runs in about a second.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.events.guards import zeno_guard
from casmbd.cli import main
from casmbd.errors import CasmbdError, IntegratorError, ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.model.contacts import PlaneContact
from casmbd.results import load

_vm = private_cache("cache_bad_events", CASMBD_COMPILE="0")

BALL = (pathlib.Path(__file__).resolve().parents[2] / "examples" /
        "bouncing_ball.toml").read_text()
G = 9.81


def ball(*swaps: tuple[str, str], extra: str = "") -> str:
    """The bouncing ball with text replacements ``(old, new)`` and ``extra`` appended."""
    text = BALL
    for old, new in swaps:
        assert old in text, old
        text = text.replace(old, new)
    return text + extra


PUSH = '\n[[forces]]\nname = "push"\ntype = "force"\nbody = "ball"\n' \
       'value = ["1/(t - 0.5)", 0.0]\n'


def cli(tmp_path, capsys, text: str, *args: str) -> tuple[int, str, pathlib.Path]:
    """Run ``simulate`` on the scene ``text`` with --out; (exit code, the error line (the last
    on stderr, after warnings only), the --out path)."""
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    out = tmp_path / "run.npz"
    code = main(["simulate", str(scene), "--mode", "vm", "--out", str(out), *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert err and err[-1].startswith("error: ") and "Traceback" not in "".join(err)
    # no SUNDIALS lines ("At t = …", "The above warning has been issued mxhnil times")
    assert all(line.startswith("warning: ") for line in err[:-1]), err
    return code, err[-1], out


# ---------------------------------------------------------------------- pre-run checks
def test_massless_ball_named_before_the_run():
    """The smooth path's mass-matrix check runs with contacts too (was CV_FIRST_RHSFUNC_ERR)."""
    mech = loads_scene(ball(("m = 1.0 ", "m = 0.0 ")))
    with pytest.raises(ModelError) as exc:
        simulate(mech, t_end=1.0, steps=10, mode="vm")
    message = str(exc.value)
    assert "body 'ball'" in message and "mass matrix is singular" in message
    assert "t = 0" in message


def test_overflowing_weight_named_before_the_run(tmp_path, capsys):
    """m g = 1e308 × 9.81 overflows: the finiteness check names the row (was
    CV_FIRST_RHSFUNC_ERR); nothing is written."""
    code, err, out = cli(tmp_path, capsys, ball(("m = 1.0 ", "m = 1e308 ")), "--t-end", "1",
                         "--steps", "10")
    assert code == 1 and "applied forces Q is not finite" in err and "ball.y" in err
    assert "at t = 0" in err and not out.exists()


# ---------------------------------------------------------------------- integrator failures
def test_singular_force_named_with_partial_results(tmp_path, capsys):
    """A force 1/(t − 0.5) along x: CV_TOO_MUCH_WORK in the event loop becomes an
    IntegratorError naming the force, its field and t = 0.5; the partial results (saved with
    --out) follow the closed form v_x = ln(1 − 2t), x = −t − (0.5 − t) ln(1 − 2t) (m = 1) to
    1e-6 relative, and keep the first impact at t₁ = sqrt(2 h0 / g)."""
    code, err, out = cli(tmp_path, capsys, ball(extra=PUSH), "--t-end", "1", "--steps", "10",
                         "--max-steps", "20000")  # the stall fails in 0.5 s, not 8 s
    assert code == 1
    for fragment in ("integrator 'adams'", "CV_TOO_MUCH_WORK", "force 'push' field 'value'",
                     "t = 0.5", "partial results saved"):
        assert fragment in err, (fragment, err)
    res = load(out)
    t = res.t
    assert t[-1] < 0.5 and t[-1] > 0.45 and np.allclose(t[:5], [0.0, 0.1, 0.2, 0.3, 0.4])
    assert "failure" in res.stats
    vx = res["v"][:, 0]
    x = res["q"][:, 0]
    # rtol 1e-8 of the run; 1e-6 relative near the singularity (4e-7 measured at t = 0.475),
    # x to 1e-7 (6e-8 measured)
    np.testing.assert_allclose(vx, np.log(1 - 2 * t), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(x, -t - (0.5 - t) * np.log(1 - 2 * t), rtol=1e-6, atol=1e-7)
    impacts = [e["time"] for e in res.events if e["kind"] == "impact"]
    assert impacts and impacts[0] == pytest.approx(math.sqrt(2 * 1.0 / G), abs=1e-7)


def test_singular_force_api_error_carries_time_and_partial():
    mech = loads_scene(ball(extra=PUSH))
    with pytest.raises(IntegratorError) as exc:
        simulate(mech, t_end=1.0, steps=10, mode="vm", max_steps=20_000)
    assert exc.value.flag == "CV_TOO_MUCH_WORK"
    assert 0.45 < exc.value.time < 0.5
    assert exc.value.partial is not None and exc.value.partial.t[-1] == exc.value.time


def test_huge_gravity_refused_naming_the_field(tmp_path, capsys):
    """Gravity 1e308 ended in CV_ILL_INPUT at t = 0 (an IntegratorError with the start saved);
    it is now beyond the plausible 1e8 m/s² (casmbd.model.mechanism.GRAVITY_MAX) and refused
    when the scene is read, naming the field; nothing is written."""
    code, err, out = cli(tmp_path, capsys, ball(("gravity = [0.0, -9.81]",
                                                 "gravity = [0.0, -1e308]")),
                         "--t-end", "1", "--steps", "10")
    assert code == 1 and "'gravity'" in err and "1e+08" in err, err
    assert not out.exists()


# ---------------------------------------------------------------------- contact normals
def test_huge_normal_is_normalised():
    """normal = [0, 1e300] is the direction [0, 1] (|n|² overflowed to inf and the normal to
    zero: "the initial pose penetrates by 0.1"); the first impact comes at sqrt(2 h0 / g)."""
    mech = loads_scene(ball(("normal = [0.0, 1.0]", "normal = [0.0, 1e300]")))
    assert mech.contacts["floor"].normal.tolist() == [0.0, 1.0]
    mech = loads_scene(ball(("normal = [0.0, 1.0]", "normal = [1e-300, 1e-300]")))
    np.testing.assert_allclose(mech.contacts["floor"].normal, [0.5 ** 0.5] * 2, rtol=1e-15)
    mech = loads_scene(ball(("normal = [0.0, 1.0]", "normal = [0.0, 1e300]")))
    res = simulate(mech, t_end=0.5, steps=5, mode="vm")
    impacts = [e["time"] for e in res.events if e["kind"] == "impact"]
    assert impacts == [pytest.approx(math.sqrt(2 * 1.0 / G), abs=1e-7)]


@pytest.mark.parametrize("normal, said", [("[0.0, 0.0]", "must be a non-zero vector"),
                                          ("[0.0, nan]", "must be a finite number"),
                                          ("[inf, 1.0]", "must be a finite number")])
def test_zero_or_nonfinite_normal_refused(normal, said):
    with pytest.raises(CasmbdError) as exc:
        loads_scene(ball(("normal = [0.0, 1.0]", f"normal = {normal}")))
    message = str(exc.value)
    assert "'floor'" in message and "normal" in message and said in message


def test_nonfinite_normal_refused_by_the_api():
    with pytest.raises(ModelError) as exc:
        PlaneContact(name="floor", body="ball", point=[0.0, 1.1], radius=0.1,
                     normal=[0.0, float("nan")])
    assert "contact 'floor' field 'normal': must be finite" in str(exc.value)


# ---------------------------------------------------------------------- max_events, rest
T1 = math.sqrt(2 * 1.0 / G)  # the first impact of the ball dropped from h0 = 1 m
ELASTIC = ("restitution = 0.8", "restitution = 1.0")


def test_max_events_on_the_cli_keeps_the_results(tmp_path, capsys):
    """e = 1, t_end = 1e6 (the output grid is far coarser than the bounces): the run stops
    after --max-events 50 (was 10000 events in 163 s, then nothing kept) with the results up
    to the last event: 50 impacts at t_k = (2k − 1) t₁ (1e-6 relative) and the energy m g h0
    of the last state (1e-5 relative: the event location's error over 50 impacts)."""
    code, err, out = cli(tmp_path, capsys, ball(ELASTIC), "--t-end", "1e6", "--steps", "10",
                         "--max-events", "50")
    assert code == 1
    for fragment in ("more than 50 events", "--max-events", "--rest-velocity",
                     "results kept up to t = 44.70", "partial results saved"):
        assert fragment in err, (fragment, err)
    res = load(out)
    impacts = [e["time"] for e in res.events if e["kind"] == "impact"]
    # the period drifts by 1.6e-7 relative (rtol 1e-8 per flight, 50 flights)
    np.testing.assert_allclose(impacts, (2 * np.arange(1, 51) - 1) * T1, rtol=1e-6)
    assert res.t[-1] == pytest.approx(99 * T1, rel=1e-6)
    energy = 0.5 * res["v"][-1, 1] ** 2 + G * (res["q"][-1, 1] - 0.1)
    assert energy == pytest.approx(G * 1.0, rel=1e-5)


def test_max_events_from_the_scene():
    mech = loads_scene(ball(ELASTIC, extra="\n[simulation]\nmax_events = 20\n"))
    with pytest.raises(IntegratorError) as exc:
        simulate(mech, t_end=100.0, steps=4, mode="vm")
    assert exc.value.flag == "MAX_EVENTS" and "more than 20 events" in str(exc.value)
    assert exc.value.time == pytest.approx(41 * T1, rel=1e-6)  # the 21st impact
    partial = exc.value.partial
    assert len([e for e in partial.events if e["kind"] == "impact"]) == 20
    assert partial.t[-1] == pytest.approx(39 * T1, rel=1e-6)
    # the argument wins over the scene
    res = simulate(mech, t_end=10.0, steps=4, mode="vm", max_events=100)
    assert len(res.events) == 11  # impacts at (2k − 1) t₁ < 10 s: k = 1 … 11


def rest_impacts(events) -> tuple[list[float], list[float]]:
    return ([e["time"] for e in events if e["kind"] == "impact"],
            [e["time"] for e in events if e["kind"] == "contact"])


# impact k at t₁ (1 + 2 (e + … + e^(k-1))); rebound speeds e^k sqrt(2 g h0) fall below 1 m/s
# at k = 7 (0.8^7 · 4.429 = 0.93): the contact closes there
REST_TIMES = T1 * np.array([1 + 2 * sum(0.8 ** j for j in range(1, k)) for k in range(1, 8)])


def test_rest_velocity_on_the_cli(tmp_path, capsys):
    scene = tmp_path / "ball.toml"
    scene.write_text(BALL)
    code = main(["simulate", str(scene), "--mode", "vm", "--t-end", "5", "--steps", "10",
                 "--rest-velocity", "1", "--json"])
    assert code == 0
    impacts, contacts = rest_impacts(json.loads(capsys.readouterr().out)["events"])
    np.testing.assert_allclose(impacts, REST_TIMES, atol=1e-6)
    assert contacts == [impacts[-1]]  # the 7th impact closes it


def test_rest_velocity_from_the_scene():
    mech = loads_scene(ball(extra="\n[simulation]\nrest_velocity = 1.0\n"))
    impacts, contacts = rest_impacts(simulate(mech, t_end=5.0, steps=10, mode="vm").events)
    np.testing.assert_allclose(impacts, REST_TIMES, atol=1e-6)
    assert len(contacts) == 1


@pytest.mark.parametrize("table, key, said", [
    ("max_events = 0", "max_events", "expected an integer in [1, 10000000]"),
    ("max_events = 1.5", "max_events", "expected an integer"),
    ("max_events = true", "max_events", "expected an integer"),
    ("max_events = 100000000", "max_events", "expected an integer in [1, 10000000]"),
    ("rest_velocity = -1.0", "rest_velocity", "expected a finite number >= 0"),
    ("rest_velocity = nan", "rest_velocity", "expected a finite number >= 0"),
    ('rest_velocity = "fast"', "rest_velocity", "expected a finite number >= 0"),
    ("max_event = 5", "max_event", "unknown key")])
def test_bad_simulation_table(table, key, said):
    with pytest.raises(SceneError) as exc:
        loads_scene(ball(extra=f"\n[simulation]\n{table}\n"))
    message = str(exc.value)
    assert f"[simulation] key '{key}'" in message and said in message


@pytest.mark.parametrize("flag, value", [("--max-events", "0"), ("--max-events", "x"),
                                         ("--rest-velocity", "-1"),
                                         ("--rest-velocity", "inf")])
def test_bad_event_flags(tmp_path, capsys, flag, value):
    scene = tmp_path / "ball.toml"
    scene.write_text(BALL)
    code = main(["simulate", str(scene), "--t-end", "1", "--steps", "2", flag, value])
    err = capsys.readouterr().err
    assert code == 2 and flag in err and "Traceback" not in err


# ---------------------------------------------------------------------- Zeno guard
def bounce_times(e: float, count: int, t1: float = T1) -> list[float]:
    """Impact k at t₁ (1 + 2 (e + … + e^(k−1))): the bouncing ball of restitution e."""
    return [t1 * (1 + 2 * sum(e ** j for j in range(1, k))) for k in range(1, count + 1)]


def test_zeno_guard_finds_the_accumulation_point():
    """On the ball's impact times (e = 0.5) the guard waits until the intervals are below the
    given one, then predicts t* = t₁ (1 + e) / (1 − e) to 1e-12 s."""
    times: list[float] = []
    found = [zeno_guard(times, t, interval=1e-4) for t in bounce_times(0.5, 20)]
    first = next(k for k, f in enumerate(found) if f)
    assert 2 * T1 * 0.5 ** first < 1e-4 <= 2 * T1 * 0.5 ** (first - 1)  # its interval
    assert found[first][0] == pytest.approx(T1 * 1.5 / 0.5, abs=1e-12)
    assert "ratio 0.5" in found[first][1]


@pytest.mark.parametrize("times", [bounce_times(1.0, 30),  # e = 1: no accumulation
                                   bounce_times(0.8, 11),  # too few impacts
                                   list(np.cumsum(0.5 ** np.arange(20) * (1 + 0.3 * (
                                       np.arange(20) % 2)))),  # ratios 0.65, 0.38: not one
                                   ])
def test_zeno_guard_quiet(times):
    record: list[float] = []
    assert not any(zeno_guard(record, t, interval=1e9) for t in times)


def test_zeno_stop_keeps_the_results(tmp_path, capsys):
    """With the rest velocity 0 the ball's impacts accumulate (exactly at t₁ (1 + e)/(1 − e) =
    4.06371 s; the located impacts drift to 4.0632 as their intervals reach 1e-7 s): the run
    stops naming the contact and the accumulation point (1e-3 s), and keeps its results: the
    output times before it and the impacts at their closed-form times (first 20 to 1e-5 s)."""
    code, err, out = cli(tmp_path, capsys, BALL, "--t-end", "5", "--steps", "10",
                         "--rest-velocity", "0")
    assert code == 1 and "Zeno behaviour: the impacts of 'floor' accumulate at t ≈ 4.06" in err
    assert "--rest-velocity" in err and "partial results saved" in err
    t_star = float(err.split("accumulate at t ≈ ")[1].split()[0])
    assert t_star == pytest.approx(T1 * 1.8 / 0.2, abs=1e-3)
    res = load(out)
    assert np.allclose(res.t[:9], np.arange(9) * 0.5) and 4.06 < res.t[-1] < t_star
    impacts = [e["time"] for e in res.events if e["kind"] == "impact"]
    # the event location's error accumulates: 7e-6 s at the 20th impact
    np.testing.assert_allclose(impacts[:20], bounce_times(0.8, 20), atol=1e-5)


def test_rest_velocity_per_contact_wins_over_the_run():
    """A [[contacts]] entry's rest_velocity = 1 m/s closes the floor at the 7th impact, also
    when the run's rest velocity is 0."""
    mech = loads_scene(ball(("friction = 0.0", "friction = 0.0\nrest_velocity = 1.0")))
    assert mech.contacts["floor"].rest_velocity == 1.0
    impacts, contacts = rest_impacts(simulate(mech, t_end=5.0, steps=10, mode="vm",
                                              rest_velocity=0.0).events)
    np.testing.assert_allclose(impacts, REST_TIMES, atol=1e-6)
    assert contacts == [impacts[-1]]


@pytest.mark.parametrize("value, said", [("-1.0", "must be >= 0"),
                                         ("nan", "must be a finite number")])
def test_bad_rest_velocity_per_contact(value, said):
    with pytest.raises(SceneError) as exc:
        loads_scene(ball(("friction = 0.0", f"friction = 0.0\nrest_velocity = {value}")))
    assert "'floor'" in str(exc.value) and "rest_velocity" in str(exc.value)
    assert said in str(exc.value)


def test_rest_velocity_refused_on_a_compliant_contact():
    text = ball(('model = "impact"', 'model = "compliant"\nstiffness = 1e5'),
                ("friction = 0.0", "friction = 0.0\nrest_velocity = 1.0"))
    with pytest.raises(SceneError) as exc:
        loads_scene(text)
    assert "contact 'floor' field 'rest_velocity': applies to model = 'impact'" in str(exc.value)
