"""Events that compose (issue 30 item 4c): stick-slip joint friction with stops, several
contacts closing at one instant, any output grid.

* A rod on a pin with a stop at −1 rad (e = 0.5) and exact Coulomb friction F_c = 0.5 N m
  (``stick_slip``): ``simulate --t-end 1 --steps 20`` ended in "cannot reshape array of size 2
  into shape (3)": the phase with the stop *and* the stuck friction closed chose its own
  coordinates (two loop equations on one joint coordinate: absolute), the event rows stayed in
  joint coordinates.  Now every grid gives the same events, against a piecewise solve_ivp of
  I θ̈ = −m g L/2 cos θ − F_c σ with θ̇ → −e θ̇ at the stop and σ = sign θ̇; the rod rests on
  the stop carrying m g L/2 cos 1 (the stop holds the joint: friction at rest is then
  indeterminate, the stop takes the load).
* A three-ball cradle whose two gaps close at the same instant: both are named (``impact``),
  with the velocities of Newton's law on both gaps.
* A seeded fuzz test: random scenes (pendulum with stops and stick-slip friction, cradle,
  frictional disc, frictional sphere in space; restitution, friction, spin drawn) × random
  output grids, checking the invariants: no exception, gaps ≥ −1e-9, events sorted, the total
  energy never increases (1e-8 relative: no element adds energy, e ≤ 1), and at the times the
  grids share the same positions (1e-6 m) and the same events (1e-6 s).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import private_cache
from scipy.integrate import solve_ivp

import casmbd
from casmbd import cli

_cache = private_cache("casmbd_cache_events_compose", scope="module", CASMBD_COMPILE="0")

G = 9.81
PENDULUM = """
[scene]
name = "pendulum_stop_friction"
gravity = [0.0, -9.81]
[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.08333333333333333
position = [0.5, 0.0]
[[joints]]
name = "pin"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
lower = -1.0
restitution = 0.5
friction = { coulomb = 0.5, stick_slip = true }
"""


def pendulum_reference(t_end: float, e=0.5, fc=0.5, stop=-1.0, count=12):
    """Event times and kinds of the rod (m = 1, L = 1, I_O = 1/3) by solve_ivp (DOP853,
    rtol 1e-13) between events: the stop (θ = stop: θ̇ → −e θ̇, σ follows) and θ̇ = 0 (stick
    if |m g L/2 cos θ| ≤ F_c, else slip)."""
    inertia, torque = 1.0 / 3.0, lambda th: -G * 0.5 * math.cos(th)
    t, th, om, sigma = 0.0, 0.0, 0.0, -1.0
    out = [(0.0, "slip")]

    def rhs(_, y, s):
        return [y[1], (torque(y[0]) - fc * s) / inertia]

    def hit(_, y, s):
        return y[0] - stop

    def halt(_, y, s):
        return y[1]

    hit.terminal = halt.terminal = True
    hit.direction, halt.direction = -1, sigma
    while t < t_end and len(out) < count:
        halt.direction = -sigma  # σ θ̇ falls through 0
        sol = solve_ivp(rhs, (t, t_end), [th, om], args=(sigma,), method="DOP853",
                        rtol=1e-13, atol=1e-13, events=[hit, halt])
        if sol.status != 1:
            break
        if sol.t_events[0].size:
            t, (th, om) = float(sol.t_events[0][0]), sol.y_events[0][0]
            om = -e * om
            out += [(t, "limit"), (t, "slip")]
            sigma = math.copysign(1.0, om)
        else:
            t, (th, om) = float(sol.t_events[1][0]), sol.y_events[1][0]
            if abs(torque(th)) <= fc:
                out.append((t, "stick"))
                break
            sigma = math.copysign(1.0, torque(th))
            out.append((t, "slip"))
    return out


@pytest.mark.parametrize("steps", [10, 20, 100])
def test_stick_slip_with_a_stop_any_grid(steps):
    """The reproduction of issue 30 (20 steps failed): the first 10 events within 1e-9 s of
    the piecewise solve_ivp reference (measured 2e-12 … 9e-12 s at rtol 1e-12)."""
    mech = casmbd.loads_scene(PENDULUM)
    res = casmbd.simulate(mech, 1.0, steps, rtol=1e-12, atol=1e-12)
    ref = pendulum_reference(1.0)
    got = [(e["time"], e["kind"]) for e in res.events]
    assert [k for _, k in got[:10]] == [k for _, k in ref[:10]]
    np.testing.assert_allclose([t for t, _ in got[:10]], [t for t, _ in ref[:10]], atol=1e-9)


def test_stick_slip_with_a_stop_rests_on_the_stop(tmp_path, capsys):
    """Through the CLI (``--steps 20``, the failing grid): exit 0, one JSON object; after the
    bounces die out the stop carries m g L/2 cos 1 = 2.650183 N m (1e-9 relative) and the
    friction nothing (the stop holds the joint)."""
    scene = tmp_path / "stop_friction.toml"
    scene.write_text(PENDULUM)
    code = cli.main(["simulate", str(scene), "--t-end", "3", "--steps", "20", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["events"][-1]["kind"] == "contact"
    assert out["contacts"]["pin.limit"]["normal_force"][-1] == \
        pytest.approx(G * 0.5 * math.cos(1.0), rel=1e-9)
    assert out["contacts"]["pin.friction"]["normal_force"][-1] == 0.0


def test_stick_slip_with_a_stop_statics_equals_the_rest():
    """Statics of the same rod (before: a RecursionError, the variant without contacts still
    had events): it rests on the stop, θ = −1, the stop carrying m g L/2 cos 1 — what the
    simulation ends in (1e-9 relative)."""
    eq = casmbd.static_equilibrium(casmbd.loads_scene(PENDULUM))
    assert eq.q[0] == pytest.approx(-1.0, abs=1e-12)
    assert eq.contacts["pin.limit"]["normal_force"] == \
        pytest.approx(G * 0.5 * math.cos(1.0), rel=1e-9)


def _cradle(e=1.0, v_c=1.5):
    mech = casmbd.Mechanism("cradle", dimension=2, gravity=[0.0, 0.0])
    mech.add_body("a", 1.0, 0.004, [0.0, 0.0], velocity=[1.5, 0.0])
    mech.add_body("b", 1.0, 0.004, [0.5, 0.0])
    mech.add_body("c", 1.0, 0.004, [1.0, 0.0], velocity=[-v_c, 0.0])
    mech.add_contact("ab", "a", [0.0, 0.0], radius=0.1, body2="b", point2=[0.5, 0.0],
                     radius2=0.1, restitution=e)
    mech.add_contact("bc", "b", [0.5, 0.0], radius=0.1, body2="c", point2=[1.0, 0.0],
                     radius2=0.1, restitution=e)
    return mech


@pytest.mark.parametrize("steps", [3, 7, 10])
def test_cradle_gaps_closing_together_are_both_named(steps):
    """a (1.5 m/s) and c (−1.5 m/s) reach b at rest at t = 0.3/1.5 = 0.2 s: both gaps are named;
    Newton's law on both (e = 1, equal masses): v_a = −1.5, v_b = 0, v_c = 1.5 (1e-12)."""
    res = casmbd.simulate(_cradle(), 1.0, steps, rtol=1e-12)
    assert sorted((e["element"], e["kind"]) for e in res.events) == \
        [("ab", "impact"), ("bc", "impact")]
    assert all(e["time"] == pytest.approx(0.2, abs=1e-12) for e in res.events)
    for body, v in (("a", -1.5), ("b", 0.0), ("c", 1.5)):
        np.testing.assert_allclose(res.body(body)["velocity"][-1], [v, 0.0], atol=1e-12)


def _box(dimension, corners, mu=0.3, drop=0.02, vx=1.0):
    """A box (m = 1) with point contacts at ``corners`` (body points at 0.05 below its centre)
    dropped flat from ``drop`` above the floor while moving at vx."""
    if dimension == 2:
        mech = casmbd.Mechanism("box", dimension=2, gravity=[0.0, -G])
        mech.add_body("box", 1.0, 0.01, [0.0, 0.05 + drop], velocity=[vx, 0.0])
        for k, x in enumerate(corners):
            mech.add_contact(f"c{k}", "box", [x, drop], radius=0.0, restitution=0.0,
                             friction=mu)
    else:
        mech = casmbd.Mechanism("box", dimension=3, gravity=[0.0, 0.0, -G])
        mech.add_body("box", 1.0, [0.01] * 3, [0.0, 0.0, 0.05 + drop], velocity=[vx, 0.0, 0.0])
        for k, (x, y) in enumerate(corners):
            mech.add_contact(f"c{k}", "box", [x, y, drop], normal=[0.0, 0.0, 1.0], radius=0.0,
                             restitution=0.0, friction=mu)
    return mech


CORNERS = [(0.1, 0.1), (0.1, -0.1), (-0.1, 0.1), (-0.1, -0.1)]


@pytest.mark.parametrize("dimension, corners, drop", [
    (2, [-0.1, 0.1], 0.02), (2, [-0.1, 0.0, 0.1], 0.02), (3, CORNERS, 0.02), (3, CORNERS, 0.0)])
def test_box_lands_on_several_contacts_slides_and_stops(dimension, corners, drop):
    """A box dropped flat (from 0.02 m, or put down touching) at vx = 1 m/s, μ = 0.3, e = 0, on
    2 or 3 contacts in the plane, 4 corners in space (the last two statically indeterminate):
    every contact is named at the impact t₁ = sqrt(2 drop/g) (``impact`` and ``contact``, or
    ``contact`` alone when put down; 1e-8 s); the impulse leaves vx⁺ = 1 − μ g t₁ (Coulomb on
    the impulse level), then the box slides at μ g and every contact sticks at
    t₁ + vx⁺/(μ g) (1e-8 s) — all together, holding nothing at rest (1e-9 N), the normal forces
    the minimum-norm split m g/n (1e-9 relative), at x = vx t₁ + vx⁺²/(2 μ g) (1e-9 m)."""
    mu, n = 0.3, len(corners)
    res = casmbd.simulate(_box(dimension, corners, mu, drop=drop), 0.5, 10, rtol=1e-10)
    t1 = math.sqrt(2.0 * drop / G)
    vx = 1.0 - mu * G * t1
    t_stop = t1 + vx / (mu * G)
    names = [f"c{k}" for k in range(n)]
    kinds = (("impact", t1),) if drop else ()
    for kind, when in (*kinds, ("contact", t1), ("stick", t_stop)):
        hits = [e for e in res.events if e["kind"] == kind]
        assert sorted(e["element"] for e in hits) == names, kind
        np.testing.assert_allclose([e["time"] for e in hits], when, atol=1e-8)
    forces = res.arrays["contact_forces"]  # n normal columns, then n friction columns
    np.testing.assert_allclose(forces[-1, :n], G / n, rtol=1e-9)
    assert np.max(np.abs(forces[-1, n:])) < 1e-9
    assert res.body("box")["position"][-1][0] == \
        pytest.approx(1.0 * t1 + vx**2 / (2.0 * mu * G), abs=1e-9)


LIFTED = """
[scene]
name = "lifted"
gravity = [0.0, -9.81]
[[bodies]]
name = "block"
mass = 2.0
inertia = 0.1
position = [0.0, 0.05]
[[forces]]
name = "lift"
type = "force"
body = "block"
value = [0.0, "4 * t"]
[[contacts]]
name = "left"
body = "block"
point = [-0.1, 0.0]
[[contacts]]
name = "right"
body = "block"
point = [0.1, 0.0]
"""


@pytest.mark.parametrize("steps", [7, 80])
def test_block_lifted_off_two_contacts_detaches_from_both(steps):
    """A block put down on two contacts and lifted at its centre by F = c t (c = 4 N/s): both
    close at t = 0, carry (m g − c t)/2 each (1e-9 relative) and both detach at m g/c = 4.905 s
    (1e-10 s; before, the second one, whose force starts at zero after the first opened, was
    never released); then y = y0 + c (t³ − 3 t_d² t + 2 t_d³)/(6 m) − g (t − t_d)²/2 (1e-9)."""
    m, c, y0 = 2.0, 4.0, 0.05
    res = casmbd.simulate(casmbd.loads_scene(LIFTED), 8.0, steps, rtol=1e-12)
    t_d = m * G / c
    assert [(e["element"], e["kind"]) for e in res.events] == [
        ("left", "contact"), ("right", "contact"), ("left", "detach"), ("right", "detach")]
    np.testing.assert_allclose([e["time"] for e in res.events], [0, 0, t_d, t_d], atol=1e-10)
    t = res.t
    on = t < t_d
    np.testing.assert_allclose(res.arrays["contact_forces"][on], np.column_stack(
        [(m * G - c * t[on]) / 2] * 2), rtol=1e-9)
    off = t > t_d
    y = res.body("block")["position"][:, 1]
    exact = y0 + c * (t**3 - 3 * t_d**2 * t + 2 * t_d**3) / (6 * m) - G * (t - t_d) ** 2 / 2
    np.testing.assert_allclose(y[off], exact[off], rtol=1e-9, atol=1e-9)
    assert np.all(res.arrays["contact_forces"][off] == 0.0)


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_pinned_rod_rests_on_a_frictional_floor(coordinates):
    """A rod (1 m, 1 kg) pinned at one end falls from the horizontal onto a frictional floor
    (μ = 0.5, e = 0) with a 0.05 m sphere at its tip, with exact stick-slip friction at the pin
    (F_c = 0.3 N m): the pin and the floor lock it, the friction rows are held (no slip events
    while it rests — before, one at every output time on some grids; in joint coordinates the
    contact's friction was refused).  At rest (sin θ = −0.55) the floor carries m g/2 and the
    pin the other half (1e-9), in joint and absolute coordinates; the first impact at the
    time of a solve_ivp of I θ̈ = −m g L/2 cos θ + F_c (1e-9 s)."""
    mech = casmbd.Mechanism("rod_floor", dimension=2, gravity=[0.0, -G], coordinates=coordinates)
    mech.add_body("rod", 1.0, 1.0 / 12.0, [0.5, 0.0])
    mech.add_revolute("pin", "ground", "rod", [0.0, 0.0])
    mech.add("joint_friction", "pin.friction", "pin", friction=0.3, stick_slip=True)
    mech.add_contact("floor", "rod", [1.0, 0.0], radius=0.05, origin=[0.0, -0.6],
                     restitution=0.0, friction=0.5)
    res = casmbd.simulate(mech, 1.0, 10, rtol=1e-12, atol=1e-12)
    assert [(e["element"], e["kind"]) for e in res.events] == [
        ("pin.friction", "slip"), ("floor", "impact"), ("floor", "contact")]

    def hit(_, y):
        return math.sin(y[0]) + 0.55

    hit.terminal, hit.direction = True, -1
    sol = solve_ivp(lambda _, y: [y[1], (-G * 0.5 * math.cos(y[0]) + 0.3) * 3.0], (0.0, 1.0),
                    [0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-13, events=hit)
    assert res.events[1]["time"] == pytest.approx(float(sol.t_events[0][0]), abs=1e-9)
    # floor normal force, pin friction, floor friction
    np.testing.assert_allclose(res.arrays["contact_forces"][-1], [G / 2, 0.0, 0.0], atol=1e-9)
    pin = res.names["all_joints"].index("pin")
    np.testing.assert_allclose(res.arrays["joint_reactions"][-1, pin, :2], [0.0, G / 2],
                               atol=1e-9)


# ------------------------------------------------------------------ fuzz
def _pendulum(rng):
    e, fc = rng.choice([0.0, 0.5, 1.0]), rng.choice([0.0, 0.3, 0.5, 6.0])
    upper = bool(rng.integers(2))
    mech = casmbd.Mechanism("pendulum", dimension=2, gravity=[0.0, -G])
    mech.add_body("rod", 1.0, 1.0 / 12.0, [0.5, 0.0])
    mech.add_revolute("pin", "ground", "rod", [0.0, 0.0])
    mech.add_joint_limit("pin", lower=-1.0, upper=0.3 if upper else None, restitution=e)
    if fc:
        mech.add("joint_friction", "pin.friction", "pin", friction=fc, stick_slip=True)

    def gaps(res):
        th = res.joint("pin")["coordinate"]
        return np.concatenate([th + 1.0, 0.3 - th if upper else []])
    return mech, gaps, 1.5


def _cradle_fuzz(rng):
    e, v_c = rng.choice([0.8, 1.0]), rng.choice([0.0, 1.2, 1.5])

    def gaps(res):
        x = {b: res.body(b)["position"][:, 0] for b in "abc"}
        return np.concatenate([x["b"] - x["a"] - 0.2, x["c"] - x["b"] - 0.2])
    return _cradle(e, v_c), gaps, 0.6


def _disc(rng):
    e, mu, spin = rng.choice([0.0, 0.5]), rng.choice([0.05, 0.3, 1.0]), rng.choice([-10.0, 10.0])
    mech = casmbd.Mechanism("disc", dimension=2, gravity=[0.0, -G])
    mech.add_body("disc", 1.0, 0.005, [0.0, 0.3], velocity=[1.0, 0.0], angular_velocity=spin)
    mech.add_contact("floor", "disc", [0.0, 0.3], radius=0.1, restitution=e, friction=mu)
    return mech, lambda res: res.body("disc")["position"][:, 1] - 0.1, 1.0


def _sphere(rng):
    e, mu, spin = rng.choice([0.0, 0.5]), rng.choice([0.1, 0.3]), rng.choice([0.0, 10.0])
    mech = casmbd.Mechanism("sphere", dimension=3, gravity=[0.0, 0.0, -G])
    mech.add_body("s", 1.0, [0.004] * 3, [0.0, 0.0, 0.3], velocity=[1.0, 0.5, 0.0],
                  angular_velocity=[spin, 0.0, 0.0])
    mech.add_contact("floor", "s", [0.0, 0.0, 0.3], radius=0.1, normal=[0.0, 0.0, 1.0],
                     restitution=e, friction=mu)
    return mech, lambda res: res.body("s")["position"][:, 2] - 0.1, 1.0


def _box_fuzz(rng):
    dimension, mu = int(rng.choice([2, 3])), rng.choice([0.1, 0.3, 1.0])
    corners = [-0.1, 0.0, 0.1] if dimension == 2 else \
        CORNERS
    mech = _box(dimension, corners, mu, drop=rng.choice([0.0, 0.02]), vx=rng.choice([0.5, 1.0]))
    return mech, lambda res: res.body("box")["position"][:, dimension - 1] - 0.05, 0.6


def _rod_on_floor(rng):
    """A rod pinned at one end (stick-slip friction at the pin or none) whose tip (a 0.05 m
    sphere) strikes a frictional floor 0.6 m below the pin: the pin and the floor lock the rod
    once it rests (the friction rows held)."""
    fc, mu, e = rng.choice([0.0, 0.3]), rng.choice([0.0, 0.5]), rng.choice([0.0, 0.5])
    mech = casmbd.Mechanism("rod_floor", dimension=2, gravity=[0.0, -G])
    mech.add_body("rod", 1.0, 1.0 / 12.0, [0.5, 0.0])
    mech.add_revolute("pin", "ground", "rod", [0.0, 0.0])
    if fc:
        mech.add("joint_friction", "pin.friction", "pin", friction=fc, stick_slip=True)
    mech.add_contact("floor", "rod", [1.0, 0.0], radius=0.05, origin=[0.0, -0.6],
                     restitution=e, friction=mu)
    return mech, lambda res: np.sin(res.joint("pin")["coordinate"]) + 0.55, 1.5


def _box_hit(rng):
    """A box sliding on two frictional floor contacts (μ drawn) hit head-on by a heavy ball
    (e drawn): the impact reverses the slip of both contacts."""
    mu, e = rng.choice([0.1, 0.3]), rng.choice([0.5, 1.0])
    mech = _box(2, [-0.1, 0.1], mu, drop=0.0)
    mech.add_body("ball", 3.0, 0.003, [0.2, 0.05], velocity=[-3.0, 0.0])
    mech.add_contact("hit", "box", [0.0, 0.05], radius=0.05, body2="ball",
                     point2=[0.2, 0.05], radius2=0.05, restitution=e)
    return mech, lambda res: res.body("box")["position"][:, 1] - 0.05, 0.5


SCENES = [_pendulum, _cradle_fuzz, _disc, _sphere, _box_fuzz, _rod_on_floor, _box_hit]


@pytest.mark.parametrize("seed", range(42))
def test_fuzz_grids_and_combinations(seed):
    """One seeded scene (kind by seed, its elements drawn) on four output grids of 2 … 120
    steps: the invariants of the module docstring."""
    rng = np.random.default_rng(seed)
    make = SCENES[seed % len(SCENES)]
    grids = sorted({int(n) for n in rng.integers(2, 121, size=4)})
    runs = {}
    for steps in grids:
        mech, gaps, t_end = make(np.random.default_rng(seed))  # the same scene per grid
        res = casmbd.simulate(mech, t_end, steps, rtol=1e-10)
        assert np.min(gaps(res)) >= -1e-9, (steps, np.min(gaps(res)))
        times = [e["time"] for e in res.events]
        assert times == sorted(times)
        energy = res.arrays["total_energy"]
        assert np.all(np.diff(energy) <= 1e-8 * (1.0 + np.abs(energy[:-1]))), steps
        runs[steps] = res
    first = runs[grids[0]]
    for steps in grids[1:]:
        res = runs[steps]
        common = math.gcd(grids[0], steps)  # t = t_end j / common on both grids
        a = first.arrays["body_positions"][:: grids[0] // common]
        b = res.arrays["body_positions"][:: steps // common]
        np.testing.assert_allclose(a, b, atol=1e-6)
        assert [(e["element"], e["kind"]) for e in res.events] == \
            [(e["element"], e["kind"]) for e in first.events]
        np.testing.assert_allclose([e["time"] for e in res.events],
                                   [e["time"] for e in first.events], atol=1e-6)
