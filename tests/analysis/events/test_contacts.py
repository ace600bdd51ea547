"""Contacts and joint limits (issue 24 items 5-7) against closed forms and solve_ivp.

* bouncing ball (examples/bouncing_ball.toml): impact times t_k = t_1 (1 + 2 Σ e^j), apex
  heights e^(2k) h0 (from every sample of a flight: y − r + v_y²/2g is conserved), the rest
  (Zeno cut where a rebound would be lower than 1 nm) and the resting force m g (simulation
  and statics); npz and ``--json`` keep events and contacts;
* pendulum on a stop (examples/pendulum_stops.toml, e = 0.5): impact times against solve_ivp
  with events, rebound energies sin θ_k = sin θ_s + e^(2k) (sin θ_0 − sin θ_s), rest on the
  stop carrying m g L/2 cos(1);
* detach: a block resting on the floor, lifted by F = c t, leaves at t = m g / c;
* frictional impact of a disc (stick: tangential contact-point velocity 0; slip: P_t = μ P_n)
  and of a sphere in space (slip against the pre-impact slip direction);
* compliant contact (Hunt–Crossley / Adams IMPACT) against the hand-written 1-D ODE;
  sphere–sphere impacts exchanging momentum (e = 1);
* a spatial revolute between stops (e = 1) against solve_ivp; bad input named by element
  and key.

Tolerances are stated at each assertion; the event times of the integrator (rtol 1e-13,
Illinois root finding to 1e-13 s) are limited by the integrated positions, so late, tiny
bounces are compared as a position-equivalent |Δt| v_k.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import casmbd
from casmbd import cli, results
from casmbd.errors import AnalysisError, SceneError

_cache = private_cache("casmbd_cache_contacts", scope="module", CASMBD_COMPILE="0")

REPO = pathlib.Path(__file__).resolve().parents[3]
BALL = REPO / "examples" / "bouncing_ball.toml"
STOPS = REPO / "examples" / "pendulum_stops.toml"
G = 9.81


# ------------------------------------------------------------------ bouncing ball
def ball_impacts(count: int, h0: float = 1.0, e: float = 0.8) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form impact times t_k and impact speeds v_k = e^k sqrt(2 g h0)."""
    t1 = math.sqrt(2.0 * h0 / G)
    v1 = G * t1
    speeds = v1 * e ** np.arange(count)
    times = t1 + np.concatenate([[0.0], np.cumsum(2.0 * speeds[1:] / G)])
    return times, speeds


@pytest.fixture(scope="module")
def ball():
    mech = casmbd.load_scene(BALL)
    return mech, casmbd.simulate(mech, 5.0, 50, rtol=1e-13)


def test_ball_impact_times_apex_heights_and_rest(ball):
    _, res = ball
    e, h0, r, m = 0.8, 1.0, 0.1, 1.0
    impacts = np.array([ev["time"] for ev in res.events if ev["kind"] == "impact"])
    times, speeds = ball_impacts(len(impacts))
    err = np.abs(impacts - times)
    assert err[:20].max() < 1e-9  # measured 2.1e-10 s (rtol 1e-13)
    assert (err * speeds).max() < 1e-10  # every impact, position equivalent; measured 4.6e-11 m
    # rest: the first impact whose rebound e v_k is below sqrt(2 g 1 nm) closes the contact
    v_rest = math.sqrt(2.0 * G * 1e-9)
    n_rest = int(np.argmax(e * ball_impacts(200)[1] < v_rest))
    assert len(impacts) == n_rest + 1 == 47
    rest = [ev for ev in res.events if ev["kind"] == "contact"]
    assert len(rest) == 1 and rest[0]["element"] == "floor"
    assert abs(rest[0]["time"] - times[-1]) < 1e-7  # measured 2e-8 s
    # the Zeno point t_1 (1 + e)/(1 − e) = 4.0637 s is the rest time plus the flights not flown
    zeno = math.sqrt(2 * h0 / G) * (1 + e) / (1 - e)
    assert zeno - rest[0]["time"] == pytest.approx(2 * e * speeds[-1] / (G * (1 - e)), abs=1e-7)
    # apex heights e^(2k) h0: in a flight y − r + v_y²/(2g) is the apex height at every sample
    body = res.body("ball")
    y, vy = body["position"][:, 1], body["velocity"][:, 1]
    k = np.searchsorted(impacts, res.t)
    flying = res.t < rest[0]["time"]
    apex = y - r + vy ** 2 / (2 * G)
    assert np.abs(apex - e ** (2 * k) * h0)[flying].max() < 1e-9  # measured 8.7e-12 m
    assert len(set(k[flying])) >= 10  # samples in 10 flights or more
    # resting on the floor: y = r, the floor carries m g
    forces = res.arrays["contact_forces"][:, 0]
    assert res.names["contacts"] == ["floor"]
    np.testing.assert_allclose(forces[~flying], m * G, rtol=1e-9)
    np.testing.assert_allclose(y[~flying], r, atol=1e-12)
    assert np.all(forces[flying] == 0.0)


def test_ball_statics_rests_on_the_floor():
    """From the drop pose: no equilibrium in the air, the active set closes the floor."""
    eq = casmbd.static_equilibrium(casmbd.load_scene(BALL))
    assert eq.contacts["floor"]["normal_force"] == pytest.approx(G, rel=1e-12)
    assert eq.contacts["floor"]["gap"] == pytest.approx(0.0, abs=1e-12)


def test_ball_result_npz_and_json_keep_events(ball, tmp_path, capsys):
    _, res = ball
    path = tmp_path / "ball.npz"
    res.save(path)
    back = results.load(path)
    assert back.events == res.events
    np.testing.assert_array_equal(back.arrays["contact_forces"], res.arrays["contact_forces"])
    assert back.names["contacts"] == ["floor"]
    out = tmp_path / "cli.npz"
    status = cli.main(["simulate", str(BALL), "--t-end", "1.2", "--steps", "12", "--rtol",
                       "1e-12", "--json", "--out", str(out)])
    data = json.loads(capsys.readouterr().out)
    assert status == 0
    assert [ev["kind"] for ev in data["events"]] == ["impact", "impact"]
    times, _ = ball_impacts(2)
    np.testing.assert_allclose([ev["time"] for ev in data["events"]], times, atol=1e-9)
    assert list(data["contacts"]) == ["floor"]
    assert len(data["contacts"]["floor"]["normal_force"]) == 13
    assert results.load(out).events == data["events"]


# ------------------------------------------------------------------ pendulum on a stop
def stop_reference(count: int, e: float, theta_s: float, alpha: float) -> list[float]:
    """Impact times of θ'' = −α cos θ from θ = 0 at rest onto the stop θ_s (solve_ivp with a
    terminal event; each rebound θ̇ → −e θ̇; max_step a tenth of the coming flight)."""
    def rhs(t, y):
        return [y[1], -alpha * math.cos(y[0])]

    def hit(t, y):
        return y[0] - theta_s
    hit.terminal, hit.direction = True, -1
    t, y, times = 0.0, [0.0, 0.0], []
    for _ in range(count):
        step = 0.2 * abs(y[1]) / (alpha * math.cos(theta_s)) if y[1] else np.inf
        sol = solve_ivp(rhs, (t, t + 10.0), y, events=hit, rtol=1e-13, atol=1e-13,
                        method="DOP853", max_step=step)
        t = float(sol.t_events[0][0])
        times.append(t)
        y = [theta_s, -e * float(sol.y_events[0][0][1])]
    return times


def test_pendulum_stop_impacts_rebounds_and_rest():
    mech = casmbd.load_scene(STOPS)
    res = casmbd.simulate(mech, 2.0, 40, rtol=1e-12)
    m, length, e, theta_s = 1.0, 1.0, 0.5, -1.0
    a = length / 2
    inertia = m * length ** 2 / 12 + m * a ** 2  # about the pin
    alpha = m * G * a / inertia
    limits = [ev for ev in res.events if ev["kind"] == "limit"]
    assert {ev["element"] for ev in limits} == {"pin.limit.lower"}
    impacts = np.array([ev["time"] for ev in limits])
    ref = np.array(stop_reference(len(impacts), e, theta_s, alpha))
    # impact speeds e^k ω_1 with ω_1² = 2 α (sin 0 − sin θ_s)
    omega = math.sqrt(2 * alpha * (0.0 - math.sin(theta_s))) * e ** np.arange(len(impacts))
    err = np.abs(impacts - ref)
    assert err[:7].max() < 1e-9  # measured 2.4e-10 s
    assert (err * omega).max() < 1e-10  # every impact, angle equivalent; measured 3.9e-11
    assert len(impacts) >= 15
    rest = [ev for ev in res.events if ev["kind"] == "contact"]
    assert len(rest) == 1 and rest[0]["time"] == impacts[-1]
    # rebound "apex" angles: sin θ + θ̇²/(2α) is constant in a flight, sin θ_k after k impacts
    joint = res.joint("pin")
    theta, rate = joint["coordinate"], joint["velocity"]
    k = np.searchsorted(impacts, res.t)
    swinging = res.t < rest[0]["time"]
    top = np.sin(theta) + rate ** 2 / (2 * alpha)
    closed_form = math.sin(theta_s) + e ** (2 * k) * (0.0 - math.sin(theta_s))
    assert np.abs(top - closed_form)[swinging].max() < 1e-10  # measured 6.4e-12
    assert theta.min() >= theta_s - 1e-12
    # resting on the stop: the stop carries the gravity torque m g L/2 cos(θ_s)
    torque = m * G * a * math.cos(theta_s)
    lower = res.names["contacts"].index("pin.limit.lower")
    np.testing.assert_allclose(res.arrays["contact_forces"][~swinging, lower], torque,
                               rtol=1e-9)
    np.testing.assert_allclose(theta[~swinging], theta_s, atol=1e-12)
    eq = casmbd.static_equilibrium(mech)
    assert eq.contacts["pin.limit.lower"]["normal_force"] == pytest.approx(torque, rel=1e-10)
    assert eq.contacts["pin.limit.upper"]["normal_force"] == 0.0


@pytest.mark.parametrize("formulation", ["augmented_lagrangian", "index1", "kkt_ode"])
def test_pendulum_stop_in_absolute_coordinates(formulation):
    """The same stop with the rod in absolute coordinates (a pin constraint; the stop's gap a
    function of q through the joint angle): ODE and index-1 DAE (IDAS) formulations."""
    scene = STOPS.read_text().replace("dimension = 2", 'dimension = 2\ncoordinates = "absolute"')
    res = casmbd.simulate(casmbd.loads_scene(scene), 2.0, 40, rtol=1e-12,
                          formulation=formulation)
    impacts = np.array([ev["time"] for ev in res.events if ev["kind"] == "limit"])
    alpha = G * 0.5 / (1.0 / 3.0)
    ref = stop_reference(8, 0.5, -1.0, alpha)
    assert len(impacts) == 16
    assert np.abs(impacts[:8] - ref).max() < 2e-9  # measured 5.1e-10 to 6.6e-10 s
    lower = res.names["contacts"].index("pin.limit.lower")
    assert res.arrays["contact_forces"][-1, lower] == pytest.approx(
        G * 0.5 * math.cos(1.0), rel=1e-9)


# ------------------------------------------------------------------ detach
BLOCK = """
[scene]
name = "block"
dimension = 2
gravity = [0.0, -9.81]
[parameters]
c = 4.0
[[bodies]]
name = "block"
mass = 2.0
inertia = 0.1
position = [0.0, 0.05]
[[forces]]
name = "lift"
type = "force"
body = "block"
value = [0.0, "c * t"]
[[contacts]]
name = "floor"
type = "plane"
body = "block"
point = [0.0, 0.0]
"""


def test_block_detaches_at_m_g_over_c():
    """Put down touching (gap 0 at t = 0): the contact closes at once, carries m g − c t and
    detaches at t_d = m g / c; then y = y0 + c (t³ − 3 t_d² t + 2 t_d³)/(6 m) − g (t − t_d)²/2."""
    m, c, y0 = 2.0, 4.0, 0.05
    res = casmbd.simulate(casmbd.loads_scene(BLOCK), 8.0, 80, rtol=1e-12)
    t_d = m * G / c
    assert [ev["kind"] for ev in res.events] == ["contact", "detach"]
    assert res.events[0]["time"] == 0.0
    assert res.events[1]["element"] == "floor"
    assert abs(res.events[1]["time"] - t_d) < 1e-10  # measured 0 (4.905 s)
    t = res.t
    y = res.body("block")["position"][:, 1]
    on = (t > 0.0) & (t < t_d)
    np.testing.assert_allclose(res.arrays["contact_forces"][on, 0], m * G - c * t[on],
                               rtol=1e-9)
    np.testing.assert_allclose(y[t <= t_d], y0, atol=1e-12)
    off = t > t_d
    exact = y0 + c * (t ** 3 - 3 * t_d ** 2 * t + 2 * t_d ** 3) / (6 * m) - G * (t - t_d) ** 2 / 2
    np.testing.assert_allclose(y[off], exact[off], rtol=1e-9, atol=1e-9)
    assert np.all(res.arrays["contact_forces"][off, 0] == 0.0)


# ------------------------------------------------------------------ frictional impact
def disc_impact(mu: float, e: float, vx: float, omega: float, vy: float = -2.0):
    """A disc (m = 1, r = 0.1, I = 0.005) thrown at the floor without gravity."""
    mech = casmbd.Mechanism("disc", dimension=2, gravity=[0.0, 0.0])
    mech.add_body("disc", 1.0, 0.005, [0.0, 0.15], velocity=[vx, vy], angular_velocity=omega)
    mech.add_contact("floor", "disc", [0.0, 0.15], radius=0.1, restitution=e, friction=mu)
    res = casmbd.simulate(mech, 0.05, 5, rtol=1e-12)
    body = res.body("disc")
    return res.events, body["velocity"][-1], float(body["angular_velocity"][-1])


@pytest.mark.parametrize("mu, omega", [(1.0, 0.0), (0.05, 0.0), (0.05, 30.0), (0.3, -5.0)])
def test_disc_frictional_impact_stick_or_slip(mu, omega):
    """Rigid-body impulses: P_n = m (1+e) |v_n|; sticking needs P_t = −v_t⁻/(1/m + r²/I)
    (contact point v_t = v_x + ω r brought to 0); if |P_t| > μ P_n the disc slips with
    P_t = −μ P_n sign(v_t⁻).  Then v_x⁺ = v_x⁻ + P_t/m, ω⁺ = ω⁻ + r P_t / I."""
    m, r, inertia, e, vx, vn = 1.0, 0.1, 0.005, 0.5, 1.0, 2.0
    events, v, w = disc_impact(mu, e, vx, omega)
    vt = vx + omega * r
    p_n = m * (1 + e) * vn
    p_t = -vt / (1 / m + r * r / inertia)
    stick = abs(p_t) <= mu * p_n
    if not stick:
        p_t = -mu * p_n * math.copysign(1.0, vt)
    assert [ev["kind"] for ev in events] == ["impact", "stick" if stick else "slip"]
    assert events[0]["time"] == pytest.approx(0.05 / vn, abs=1e-12)
    np.testing.assert_allclose(v, [vx + p_t / m, e * vn], atol=1e-12)
    assert w == pytest.approx(omega + r * p_t / inertia, abs=1e-11)
    if stick:
        assert abs(v[0] + w * r) < 1e-12  # the contact point rolls off
    else:  # point-mass statement of the slip: |Δv_t| of the centre = μ (1 + e) v_n
        assert abs(v[0] - vx) == pytest.approx(mu * (1 + e) * vn, rel=1e-12)


def test_sphere_slips_against_its_slip_direction_in_space():
    """A sphere (m = 2, r = 0.1, I = 2/5 m r²) sliding in x and y onto the floor z = 0 with
    μ = 0.1: the tangential impulse −μ P_n ŝ along the unit slip velocity ŝ of the contact point."""
    m, r, e, mu = 2.0, 0.1, 0.3, 0.1
    inertia = 0.4 * m * r * r
    v0 = np.array([3.0, -4.0, -1.0])
    mech = casmbd.Mechanism("sphere", dimension=3, gravity=[0.0, 0.0, 0.0])
    mech.add_body("s", m, [inertia] * 3, [0.0, 0.0, 0.2], velocity=v0.tolist())
    mech.add_contact("floor", "s", [0.0, 0.0, 0.2], radius=r, normal=[0.0, 0.0, 1.0],
                     restitution=e, friction=mu)
    res = casmbd.simulate(mech, 0.2, 4, rtol=1e-12)
    assert [ev["kind"] for ev in res.events] == ["impact", "slip"]
    p_n = m * (1 + e) * -v0[2]
    s_hat = np.array([v0[0], v0[1], 0.0]) / 5.0
    p_t = -mu * p_n * s_hat
    body = res.body("s")
    np.testing.assert_allclose(body["velocity"][-1], [*(v0[:2] + p_t[:2] / m), -e * v0[2]],
                               atol=1e-12)
    arm = np.array([0.0, 0.0, -r])  # contact point from the centre
    np.testing.assert_allclose(body["angular_velocity"][-1], np.cross(arm, p_t) / inertia,
                               atol=1e-11)


# ------------------------------------------------------------------ compliant model
def test_compliant_drop_against_the_hand_written_ode():
    """F_n = k δ^e + STEP(δ, 0, 0, d, c) δ̇ (≥ 0) on the penetration δ = r − y of a ball dropped
    from 1 m: casmbd against solve_ivp of m ÿ = −m g + F_n."""
    scene = BALL.read_text().replace('model = "impact"', 'model = "compliant"\nstiffness = 1e6'
                                     '\nexponent = 1.5\ndamping = 50.0\npenetration = 1e-3')
    res = casmbd.simulate(casmbd.loads_scene(scene), 0.6, 1200, rtol=1e-10)
    m, r, k, ex, c, d = 1.0, 0.1, 1e6, 1.5, 50.0, 1e-3

    def rhs(t, s):
        y, v = s
        delta = r - y
        if delta <= 0.0:
            return [v, -G]
        x = min(delta / d, 1.0)
        force = max(k * delta ** ex + c * x * x * (3 - 2 * x) * -v, 0.0)
        return [v, -G + force / m]

    ref = solve_ivp(rhs, (0.0, 0.6), [1.1, 0.0], t_eval=res.t, rtol=1e-12, atol=1e-14,
                    method="DOP853", max_step=1e-4)
    y = res.body("ball")["position"][:, 1]
    pen, pen_ref = np.maximum(r - y, 0.0), np.maximum(r - ref.y[0], 0.0)
    # at most the undamped (2.5 m g (h0 + δ)/k)^(1/2.5) = 0.0144 m; 0.0130 m with damping
    assert 0.012 < pen_ref.max() < 0.0145
    assert np.count_nonzero(pen_ref) > 5  # the contact is sampled
    assert np.abs(pen - pen_ref).max() < 1e-8  # measured 7e-10 m of 0.013 m
    assert np.abs(y - ref.y[0]).max() < 1e-7  # measured 7e-9 m after the rebound
    # the compliant model has no event detection: contact/detach read off the grid
    assert [e["kind"] for e in res.events] == ["contact", "detach"]
    assert abs(res.events[0]["time"] - math.sqrt(2 * 1.0 / 9.81)) < 1e-3


def test_compliant_friction_block_decelerates_at_mu_g():
    """A block on a compliant floor at its static penetration (k δ^1.5 = m g), pushed at
    v0 = 1 m/s: regularised Coulomb friction (v_s = 1e-4 m/s) decelerates it at μ g to rest
    at t_s = v0/(μ g), x = v0 t − μ g t²/2, then x = v0²/(2 μ g)."""
    m, mu, k, v0 = 2.0, 0.4, 1e6, 1.0
    depth = (m * G / k) ** (1 / 1.5)
    mech = casmbd.Mechanism("slide", dimension=2, gravity=[0.0, -G])
    mech.add_body("block", m, 0.01, [0.0, -depth], velocity=[v0, 0.0])
    mech.add_contact("floor", "block", [0.0, -depth], model="compliant", friction=mu,
                     stiffness=k, exponent=1.5, damping=2000.0, penetration=1e-4,
                     friction_velocity=1e-4)
    res = casmbd.simulate(mech, 0.4, 40, rtol=1e-10)
    t = res.t
    t_s = v0 / (mu * G)
    exact = np.where(t < t_s, v0 * t - mu * G * t * t / 2, v0 * t_s / 2)
    pos = res.body("block")["position"]
    assert np.abs(pos[:, 0] - exact).max() < 1e-7  # measured 2.1e-9 m
    assert np.abs(pos[:, 1] + depth).max() < 1e-10  # stays at k δ^1.5 = m g: 1.3e-13 m


def test_compliant_stop_statics():
    """A rod pinned at one end resting on a compliant stop (k = 1e4 N m/rad, exponent 1):
    k δ = m g L/2 cos(θ_s − δ) at θ = θ_s − δ (brentq)."""
    mech = casmbd.Mechanism("stop", dimension=2, gravity=[0.0, -G])
    mech.add_body("rod", 1.0, 1 / 12, [0.5, 0.0])
    mech.add_revolute("pin", "ground", "rod", [0.0, 0.0])
    mech.add_joint_limit("pin", lower=-1.0, model="compliant", stiffness=1e4, exponent=1.0,
                         damping=5.0, penetration=1e-3)
    delta = brentq(lambda d: 1e4 * d - G * 0.5 * math.cos(-1.0 - d), 0.0, 0.1, xtol=1e-15)
    eq = casmbd.static_equilibrium(mech)
    assert eq.q[0] == pytest.approx(-1.0 - delta, abs=1e-12)  # θ = −1.000264909


@pytest.mark.parametrize("m2", [1.0, 3.0])
def test_two_ball_cradle(m2):
    """Ball a (m = 1, 1.5 m/s) hits ball b at rest, e = 1: v_a = (1 − m2)/(1 + m2) v,
    v_b = 2 v/(1 + m2) (equal masses exchange velocities), at t = gap / v = 0.3/1.5."""
    mech = casmbd.Mechanism("cradle", dimension=2, gravity=[0.0, 0.0])
    mech.add_body("a", 1.0, 0.004, [0.0, 0.0], velocity=[1.5, 0.0])
    mech.add_body("b", m2, 0.004 * m2, [0.5, 0.0])
    mech.add_contact("touch", "a", [0.0, 0.0], radius=0.1, body2="b", point2=[0.5, 0.0],
                     radius2=0.1, restitution=1.0)
    res = casmbd.simulate(mech, 1.0, 10, rtol=1e-12)
    assert [(ev["element"], ev["kind"]) for ev in res.events] == [("touch", "impact")]
    assert res.events[0]["time"] == pytest.approx(0.2, abs=1e-12)
    v = 1.5
    np.testing.assert_allclose(res.body("a")["velocity"][-1], [(1 - m2) / (1 + m2) * v, 0.0],
                               atol=1e-12)
    np.testing.assert_allclose(res.body("b")["velocity"][-1], [2 * v / (1 + m2), 0.0],
                               atol=1e-12)


# ------------------------------------------------------------------ spatial joint limits
def test_spatial_revolute_between_stops():
    """A rod (1 m, 1 kg) on a hinge about global y swings between stops at −0.5 and 1.0 rad
    with e = 1: impact times against solve_ivp of θ'' = m g a cos θ / I_O, energy kept."""
    m, a, length = 1.0, 0.5, 1.0
    i_c = m * length ** 2 / 12
    i_o = i_c + m * a * a
    mech = casmbd.Mechanism("hinge3d", dimension=3, gravity=[0.0, 0.0, -G])
    mech.add_body("rod", m, [1e-4, i_c, i_c], [a, 0.0, 0.0], velocity=[0.0, 0.0, 2.5],
                  angular_velocity=[0.0, -5.0, 0.0])
    mech.add_revolute("hinge", "ground", "rod", [0.0, 0.0, 0.0], axis=[0.0, 1.0, 0.0])
    mech.add_joint_limit("hinge", lower=-0.5, upper=1.0, restitution=1.0)
    res = casmbd.simulate(mech, 3.0, 30, rtol=1e-12)

    def rhs(t, y):
        return [y[1], m * G * a * math.cos(y[0]) / i_o]

    def lower(t, y):
        return y[0] + 0.5

    def upper(t, y):
        return 1.0 - y[0]
    lower.terminal = upper.terminal = True
    lower.direction = upper.direction = -1
    t, y, ref = 0.0, [0.0, -5.0], []
    while True:
        sol = solve_ivp(rhs, (t, 3.0), y, events=[lower, upper], rtol=1e-13, atol=1e-13,
                        method="DOP853")
        if sol.status != 1:
            break
        which = 0 if len(sol.t_events[0]) else 1
        t = float(sol.t_events[which][0])
        ref.append((t, f"hinge.limit.{('lower', 'upper')[which]}"))
        y = [sol.y_events[which][0][0], -sol.y_events[which][0][1]]
    assert [ev["element"] for ev in res.events] == [name for _, name in ref]
    assert len(ref) == 11 and {ev["kind"] for ev in res.events} == {"limit"}
    np.testing.assert_allclose([ev["time"] for ev in res.events], [t for t, _ in ref],
                               atol=1e-10)  # measured 2.8e-11 s
    theta = res.joint("hinge")["coordinate"]
    assert theta.min() > -0.5 and theta.max() < 1.0
    energy = res["total_energy"]
    assert np.ptp(energy) < 1e-9 * energy[0]  # measured 2e-10 J of 4.17 J


# ------------------------------------------------------------------ bad input
STOP_SCENE = STOPS.read_text()
BALL_SCENE = BALL.read_text()


@pytest.mark.parametrize("scene, words", [
    (BALL_SCENE.replace("restitution = 0.8", "restitution = 1.5"),
     ["contact 'floor'", "'restitution'", "[0, 1]"]),
    (BALL_SCENE.replace('body = "ball"', 'body = "bal"'),
     ["contact 'floor'", "'body'", "unknown body 'bal'"]),
    (BALL_SCENE.replace("friction = 0.0", "friction = -0.1"),
     ["contact 'floor'", "'friction'", ">= 0"]),
    (BALL_SCENE.replace('model = "impact"', 'model = "soft"'),
     ["contact 'floor'", "'model'", "'soft'"]),
    (BALL_SCENE.replace('type = "plane"', 'type = "box"'), ["'floor'", "'type'", "'box'"]),
    (BALL_SCENE.replace("normal = [0.0, 1.0]", "normal = [0.0, 0.0]"),
     ["contact 'floor'", "'normal'", "non-zero"]),
    (BALL_SCENE.replace("friction = 0.0", "friction = 0.0\nstiffness = 1e5"),
     ["contact 'floor'", "stiffness", "compliant"]),
    (BALL_SCENE.replace('model = "impact"', 'model = "compliant"\nstiffness = -1.0'),
     ["contact 'floor'", "'stiffness'", "> 0"]),
    (STOP_SCENE.replace("upper = 1.0", "upper = -2.0"),
     ["joint 'pin'", "'upper'", "must be > lower"]),
    (STOP_SCENE.replace("restitution = 0.5", "restitution = 2.0"),
     ["pin.limit", "'restitution'", "[0, 1]"]),
    (STOP_SCENE.replace("lower = -1.0", "").replace("upper = 1.0", ""),
     ["joint", "'pin'", "'restitution'", "'lower' or 'upper'"]),
])
def test_bad_input_names_element_and_key(scene, words):
    with pytest.raises(SceneError) as info:
        casmbd.loads_scene(scene)
    for word in words:
        assert word in str(info.value)


@pytest.mark.parametrize("scene, words", [
    (BALL_SCENE.replace('origin = [0.0, 0.0]', 'origin = [0.0, 1.05]'),
     ["contact 'floor'", "penetrates by 0.05"]),
    (STOP_SCENE.replace("lower = -1.0", "lower = 0.5"),
     ["joint limit 'pin.limit.lower'", "penetrates by 0.5"]),
])
def test_penetrating_start_is_refused(scene, words):
    with pytest.raises(AnalysisError) as info:
        casmbd.simulate(casmbd.loads_scene(scene), 0.1, 2)
    for word in words:
        assert word in str(info.value)


def test_api_checks_bodies_and_limits():
    mech = casmbd.Mechanism("api", dimension=2)
    mech.add_body("b", 1.0, 0.1, [0.0, 1.0])
    mech.add_revolute("pin", "ground", "b", [0.0, 0.0])
    with pytest.raises(casmbd.ModelError, match="contact 'c' field 'body2': unknown body"):
        mech.add_contact("c", "b", [0.0, 1.0], body2="nobody", point2=[0.0, 0.0])
    with pytest.raises(casmbd.ModelError, match="joint 'pin' field 'upper': must be > lower"):
        mech.add_joint_limit("pin", lower=1.0, upper=1.0)
    with pytest.raises(casmbd.ModelError, match=r"'pin'.*'lower' or 'upper'"):
        mech.add_joint_limit("pin")
