"""Coulomb friction at a closed contact (issue 24 item 5: "contact/detach and Coulomb friction
(stick/slip) at the contact"), plane scenes.

A closed frictional plane contact slides with the force −μ N σ along the tangential velocity
of its touching point (N the normal force, the closure's multiplier: the DAE formulation
``index1`` is chosen) and sticks — its tangential position s = t·r_c + r θ held — while the
holding force stays within μ N.  Closed forms (g = 9.81):

* a block (point contact) launched at v0 on a floor stops after v0/(μ g), at v0²/(2 μ g);
* a disc (radius r, I) launched sliding without spin rolls from t* = v0 / (μ g (1 + m r²/I)) on,
  at v* = v0 − μ g t* with v* + r ω = 0 (the classic bowling-ball problem);
* a block on a plane tilted by α sticks if tan α ≤ μ, else slides down at g (sin α − μ cos α).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache

import casmbd

_cache = private_cache(CASMBD_COMPILE="0")

G = 9.81


def _scene(body: str, contact: str) -> str:
    return f"""
[scene]
name = "friction"
gravity = [0.0, -9.81]
{body}
{contact}
"""


BLOCK = """
[[bodies]]
name = "block"
mass = 2.0
inertia = 0.1
position = [0.0, 0.0]
velocity = [{vx}, {vy}]
"""
FLOOR = """
[[contacts]]
name = "floor"
body = "{body}"
point = [0.0, {y}]
radius = {r}
normal = [{nx}, {ny}]
restitution = 0.0
friction = {mu}
"""


def test_block_slides_to_a_stop():
    mu, v0 = 0.3, 3.0
    mech = casmbd.loads_scene(_scene(BLOCK.format(vx=v0, vy=0.0),
                                     FLOOR.format(body="block", y=0.0, r=0.0, nx=0.0, ny=1.0,
                                                  mu=mu)))
    res = casmbd.simulate(mech, 2.0, 100, rtol=1e-10, atol=1e-12)
    assert res.stats["formulation"] == "index1"
    assert [e["kind"] for e in res.events] == ["contact", "slip", "stick"]
    assert res.events[2]["time"] == pytest.approx(v0 / (mu * G), abs=1e-10)
    x = res.body("block")["position"][:, 0]
    assert x[-1] == pytest.approx(v0**2 / (2 * mu * G), abs=1e-9)
    forces = res.arrays["contact_forces"]  # columns: floor (normal), floor (tangential)
    sliding = res.t < v0 / (mu * G) - 1e-6  # t = 0 included: closed at the start
    assert np.allclose(forces[sliding, 0], 2.0 * G, rtol=1e-9)
    assert np.allclose(forces[sliding, 1], -mu * 2.0 * G, rtol=1e-9)


def test_disc_rolls_after_sliding():
    mu, v0, m, inertia, r = 0.3, 3.0, 2.0, 0.01, 0.1
    body = BLOCK.format(vx=v0, vy=0.0).replace('name = "block"', 'name = "disc"').replace(
        "inertia = 0.1", f"inertia = {inertia}").replace("position = [0.0, 0.0]",
                                                          f"position = [0.0, {r}]")
    mech = casmbd.loads_scene(_scene(body, FLOOR.format(body="disc", y=r, r=r, nx=0.0, ny=1.0,
                                                        mu=mu)))
    res = casmbd.simulate(mech, 1.0, 100, rtol=1e-10, atol=1e-12)
    t_roll = v0 / (mu * G * (1.0 + m * r * r / inertia))
    assert [e["kind"] for e in res.events] == ["contact", "slip", "stick"]
    assert res.events[2]["time"] == pytest.approx(t_roll, abs=1e-10)
    disc = res.body("disc")
    late = res.t > t_roll + 1e-6
    assert np.allclose(disc["velocity"][late, 0], v0 - mu * G * t_roll, atol=1e-9)
    assert np.max(np.abs(disc["velocity"][late, 0] + r * disc["angular_velocity"][late])) < 1e-9


@pytest.mark.parametrize("alpha, mu", [(0.2, 0.3), (0.4, 0.3)])
def test_block_on_a_tilted_plane(alpha, mu):
    n = (-math.sin(alpha), math.cos(alpha))
    mech = casmbd.loads_scene(_scene(BLOCK.format(vx=0.0, vy=0.0),
                                     FLOOR.format(body="block", y=0.0, r=0.0, nx=n[0],
                                                  ny=n[1], mu=mu)))
    res = casmbd.simulate(mech, 1.0, 50, rtol=1e-10, atol=1e-12)
    along = res.body("block")["position"] @ np.array([math.cos(alpha), math.sin(alpha)])
    if math.tan(alpha) <= mu:
        assert [e["kind"] for e in res.events] == ["contact", "stick"]
        assert np.max(np.abs(along)) < 1e-12
    else:
        assert [e["kind"] for e in res.events] == ["contact", "slip"]
        acc = -G * (math.sin(alpha) - mu * math.cos(alpha))  # down the plane
        assert np.max(np.abs(along - 0.5 * acc * res.t**2)) < 1e-9
