"""Coulomb friction at a closed contact in space (issue 30 item 4b), as in the plane
(tests/analysis/events/test_contact_friction.py).

A closed frictional plane contact in space slides with the force −μ N v_t/|v_t| along the 2-D
tangential velocity v_t of its touching point (N the normal force, the closure's multiplier:
the DAE formulation ``index1`` is chosen) and sticks — v_t = 0, for a sphere rolling without
slipping, a non-holonomic constraint — while the holding force stays within μ N.  Closed forms
(g = 9.81; a solid sphere, I = 2/5 m r²):

* the slip velocity of a sphere on a level floor obeys dv_t/dt = −μ g (1 + m r²/I) ŝ =
  −(7/2) μ g ŝ with a constant direction ŝ, so it stops at t* = 2 |v_t0| / (7 μ g), the centre
  having decelerated at μ g along ŝ; launched without spin at v0 it then rolls at 5/7 v0 with
  ω = v/r (the bowling ball in space);
* with back- or side-spin v_t0 ≠ v0: the centre's velocity v0 − μ g ŝ t turns (a curved path)
  and the sphere rolls on at v0 − μ g ŝ t*;
* a block (a point contact under its centre of mass) launched at v0 in any direction stops
  after |v0|/(μ g) at |v0|²/(2 μ g) along v0;
* a sphere released on a plane tilted by α rolls down at 5/7 g sin α if μ ≥ 2/7 tan α (the
  friction it needs, 2/7 m g sin α, is within μ m g cos α), else slides at
  g (sin α − μ cos α).
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

_cache = private_cache("casmbd_cache_friction_space", scope="module", CASMBD_COMPILE="0")

REPO = pathlib.Path(__file__).resolve().parents[3]
G = 9.81
M, R = 2.0, 0.1
INERTIA = 0.4 * M * R * R


def _sphere(velocity, omega=(0.0, 0.0, 0.0), mu=0.5, normal=(0.0, 0.0, 1.0), radius=R):
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    centre = radius * n
    mech = casmbd.Mechanism("sphere", dimension=3, gravity=[0.0, 0.0, -G])
    mech.add_body("s", M, [INERTIA] * 3, centre.tolist(), velocity=list(velocity),
                  angular_velocity=list(omega))
    mech.add_contact("floor", "s", centre.tolist(), radius=radius, normal=n.tolist(),
                     restitution=0.0, friction=mu)
    return mech


def _kinds(res):
    return [e["kind"] for e in res.events]


def test_sphere_slides_then_rolls_at_five_sevenths():
    """v0 = 2 m/s, μ = 0.5: rolling from t* = 2 v0/(7 μ g) = 0.116499 s at 5/7 v0 with
    ω = v/r; x(t) = v0 t − μ g t²/2 before, + v* (t − t*) after (measured: t* to 1.1e-10 s)."""
    mu, v0 = 0.5, 2.0
    res = casmbd.simulate(_sphere([v0, 0.0, 0.0], mu=mu), 0.3, 30, rtol=1e-10, atol=1e-12)
    assert res.stats["formulation"] == "index1"
    assert _kinds(res) == ["contact", "slip", "stick"]
    t_star = 2.0 * v0 / (7.0 * mu * G)
    assert res.events[2]["time"] == pytest.approx(t_star, abs=1e-9)
    body = res.body("s")
    late = res.t > t_star + 1e-6
    v_star = 5.0 / 7.0 * v0
    np.testing.assert_allclose(body["velocity"][late], np.tile([v_star, 0, 0], (late.sum(), 1)),
                               atol=1e-9)
    # ω = v/r: the index-1 DAE holds v_t = 0 at the acceleration level, ω drifts by 2e-8 rad/s
    # (measured, rtol 1e-10): 1e-7 rad/s, slip velocity v − r ω within 1e-8 m/s
    np.testing.assert_allclose(body["angular_velocity"][late][:, 1], v_star / R, atol=1e-7)
    slip = body["velocity"][late][:, 0] - R * body["angular_velocity"][late][:, 1]
    assert np.max(np.abs(slip)) < 1e-8
    x_ref = np.where(res.t < t_star, v0 * res.t - 0.5 * mu * G * res.t**2,
                     v0 * t_star - 0.5 * mu * G * t_star**2 + v_star * (res.t - t_star))
    np.testing.assert_allclose(body["position"][:, 0], x_ref, atol=1e-9)
    np.testing.assert_allclose(body["position"][:, 2], R, atol=1e-10)
    forces = res.arrays["contact_forces"]  # floor: normal force, |friction force|
    assert res.names["contacts"] == ["floor", "floor"]
    np.testing.assert_allclose(forces[:, 0], M * G, rtol=1e-9)
    early = res.t < t_star - 1e-6
    np.testing.assert_allclose(forces[early, 1], mu * M * G, rtol=1e-9)
    assert np.max(np.abs(forces[late, 1])) < 1e-9  # rolling on a level floor: no friction


@pytest.mark.parametrize("velocity", [(1.2, 1.6, 0.0), (-0.6, 0.8, 0.0)])
def test_sphere_pushed_diagonally_keeps_its_direction(velocity):
    """A sphere launched along (1.2, 1.6) or (−0.6, 0.8): it stays on its line (1e-12 m) and
    rolls at 5/7 v0 from 2|v0|/(7 μ g) (1e-9)."""
    mu = 0.3
    v0 = np.array(velocity)
    speed = float(np.linalg.norm(v0))
    res = casmbd.simulate(_sphere(velocity, mu=mu), 0.4, 20, rtol=1e-10, atol=1e-12)
    assert _kinds(res) == ["contact", "slip", "stick"]
    t_star = 2.0 * speed / (7.0 * mu * G)
    assert res.events[2]["time"] == pytest.approx(t_star, abs=1e-9)
    pos = res.body("s")["position"]
    across = pos[:, :2] @ np.array([-v0[1], v0[0]]) / speed
    assert np.max(np.abs(across)) < 1e-12
    np.testing.assert_allclose(res.body("s")["velocity"][-1], [*(5.0 / 7.0 * v0[:2]), 0.0],
                               atol=1e-9)


def test_sphere_with_spin_curves_then_rolls():
    """v0 = (2, 0, 0), ω0 = (5, 0, 0) (side spin): v_t0 = v0 + ω0 × (−r n) = (2, 0.5); the slip
    direction ŝ stays fixed, the centre's velocity v0 − μ g ŝ t turns, the sphere rolls from
    t* = 2|v_t0|/(7 μ g) at v0 − μ g ŝ t* (1e-9), with v_t = 0 after."""
    mu = 0.4
    v0, w0 = np.array([2.0, 0.0, 0.0]), np.array([5.0, 0.0, 0.0])
    vt0 = v0 + np.cross(w0, [0.0, 0.0, -R])
    s_hat = vt0 / np.linalg.norm(vt0)
    t_star = 2.0 * np.linalg.norm(vt0) / (7.0 * mu * G)
    res = casmbd.simulate(_sphere(v0, w0, mu=mu), 0.4, 20, rtol=1e-10, atol=1e-12)
    assert _kinds(res) == ["contact", "slip", "stick"]
    assert res.events[2]["time"] == pytest.approx(t_star, abs=1e-9)
    body = res.body("s")
    np.testing.assert_allclose(body["velocity"][-1], v0 - mu * G * s_hat * t_star, atol=1e-9)
    early = res.t < t_star
    np.testing.assert_allclose(body["velocity"][early],
                               v0 - mu * G * np.outer(res.t[early], s_hat), atol=1e-9)
    late = res.t > t_star + 1e-6
    slip = body["velocity"][late] + np.cross(body["angular_velocity"][late], [0.0, 0.0, -R])
    assert np.max(np.abs(slip)) < 1e-8


@pytest.mark.parametrize("velocity", [(3.0, 0.0, 0.0), (1.8, -2.4, 0.0)])
def test_block_in_space_decelerates_at_mu_g(velocity):
    """A point contact under the centre of mass (a block), μ = 0.3: it stops at |v0|/(μ g)
    (1e-9 s) after |v0|²/(2 μ g) along v0 (1e-9 m), decelerating at μ g (positions 1e-9 m)."""
    mu = 0.3
    v0 = np.array(velocity)
    speed = float(np.linalg.norm(v0))
    res = casmbd.simulate(_sphere(velocity, mu=mu, radius=0.0), 1.5, 30, rtol=1e-10,
                          atol=1e-12)
    assert _kinds(res) == ["contact", "slip", "stick"]
    t_stop = speed / (mu * G)
    assert res.events[2]["time"] == pytest.approx(t_stop, abs=1e-9)
    along = np.minimum(res.t, t_stop)
    dist = speed * along - 0.5 * mu * G * along**2
    np.testing.assert_allclose(res.body("s")["position"][:, :2], np.outer(dist, v0[:2] / speed),
                               atol=1e-9)
    np.testing.assert_allclose(res.body("s")["velocity"][-1], 0.0, atol=1e-12)


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.3), (0.5, 0.1)])
def test_sphere_on_an_incline_rolls_or_slides(alpha, mu):
    """Released at rest on a plane tilted by α = 0.5 about y: it rolls down at 5/7 g sin α when
    μ ≥ 2/7 tan α = 0.156 (event ``stick``), else slides at g (sin α − μ cos α) (``slip``):
    distance along the slope 1e-9 m."""
    normal = (-math.sin(alpha), 0.0, math.cos(alpha))
    res = casmbd.simulate(_sphere([0.0, 0.0, 0.0], mu=mu, normal=normal), 0.5, 25,
                          rtol=1e-10, atol=1e-12)
    rolls = mu >= 2.0 / 7.0 * math.tan(alpha)
    assert _kinds(res) == ["contact", "stick" if rolls else "slip"]
    down = np.array([-math.cos(alpha), 0.0, -math.sin(alpha)])
    start = R * np.array(normal)
    along = (res.body("s")["position"] - start) @ down
    acc = 5.0 / 7.0 * G * math.sin(alpha) if rolls else \
        G * (math.sin(alpha) - mu * math.cos(alpha))
    np.testing.assert_allclose(along, 0.5 * acc * res.t**2, atol=1e-9)


def test_rolling_sphere_example_through_the_cli(capsys):
    """examples/rolling_sphere.toml (the issue's sphere: 2 m/s, μ = 0.5) through ``simulate
    --rtol 1e-10 --json``: stick at 2 v0/(7 μ g) (1e-9 s); ``contacts.floor`` gives the normal
    force m g and the friction force μ m g while it slides, 0 while it rolls (1e-6 N)."""
    code = cli.main(["simulate", str(REPO / "examples" / "rolling_sphere.toml"), "--t-end",
                     "0.3", "--steps", "30", "--rtol", "1e-10", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    mu, v0 = 0.5, 2.0
    t_star = 2.0 * v0 / (7.0 * mu * G)
    assert [e["kind"] for e in out["events"]] == ["contact", "slip", "stick"]
    assert out["events"][2]["time"] == pytest.approx(t_star, abs=1e-9)
    floor = out["contacts"]["floor"]
    t = np.linspace(0.0, 0.3, 31)
    np.testing.assert_allclose(floor["normal_force"], M * G, rtol=1e-6)
    np.testing.assert_allclose(np.array(floor["friction_force"])[t < t_star], mu * M * G,
                               rtol=1e-6)
    assert np.max(np.abs(np.array(floor["friction_force"])[t > t_star])) < 1e-6


PUSHED = """
[scene]
name = "pushed"
dimension = 3
gravity = [0.0, 0.0, -9.81]
[[bodies]]
name = "ball"
mass = 2.0
inertia = [0.008, 0.008, 0.008]
position = [0.0, 0.0, 0.1]
[[forces]]
name = "push"
type = "force"
body = "ball"
value = ["3 * t", "4 * t", 0.0]
[[contacts]]
name = "floor"
body = "ball"
point = [0.0, 0.0, 0.1]
radius = 0.1
normal = [0.0, 0.0, 1.0]
friction = 0.2
"""


def test_rolling_sphere_pushed_harder_starts_to_slip():
    """A sphere resting on the floor pushed at its centre by F = c t along u = (0.6, 0.8)
    (c = 5 N/s), μ = 0.2: it rolls (a = F/(7/5 m), the friction 2/7 F holding the touching
    point) until 2/7 c t = μ m g, t_s = 7 μ m g/(2 c) = 2.7468 s (event ``slip``, 1e-8 s; the
    stick → slip transition of a contact in space, sliding along the friction it needed);
    then the centre accelerates at (c t − μ m g)/m along u: the distance along u to 1e-8 m,
    the path straight (1e-9 m across; rtol 1e-12: at 1e-10 the Euler parameters of the fast
    spinning ball drift by 1e-7 in the index-1 DAE)."""
    m, mu, c = 2.0, 0.2, 5.0
    t_s = 7.0 * mu * m * G / (2.0 * c)
    res = casmbd.simulate(casmbd.loads_scene(PUSHED), 3.0, 30, rtol=1e-12, atol=1e-12)
    assert [e["kind"] for e in res.events] == ["contact", "stick", "slip"]
    assert res.events[2]["time"] == pytest.approx(t_s, abs=1e-8)
    t = res.t
    d = np.maximum(t - t_s, 0.0)
    rolled = c * np.minimum(t, t_s) ** 3 / (6.0 * 1.4 * m)
    v_s = c * t_s**2 / (2.0 * 1.4 * m)
    slid = v_s * d + (c * (t**3 - np.minimum(t, t_s) ** 3) / 6.0 - c * t_s**2 * d / 2.0) / m \
        - mu * G * d**2 / 2.0
    pos = res.body("ball")["position"][:, :2]
    np.testing.assert_allclose(pos @ np.array([0.6, 0.8]), rolled + slid, atol=1e-8)
    assert np.max(np.abs(pos @ np.array([-0.8, 0.6]))) < 1e-9
