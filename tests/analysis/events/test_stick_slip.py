"""Exact Coulomb friction on a joint (issue 24 item 4: "exact stick-slip (switching between stuck
and sliding modes at events)"): ``friction = { coulomb = F_c, stick_slip = true }``.

A block of mass m on a prismatic joint up an incline of angle α, launched uphill at v0, with a
constant friction level F_c (closed forms, g = 9.81):

* uphill it decelerates at d = g sin α + F_c/m and stops at t_s = v0/d after v0²/(2 d);
* if m g sin α ≤ F_c it stays there (event ``stick``), the joint carrying m g sin α;
* else it slides back at a = g sin α − F_c/m (event ``slip`` at t_s): x(t) = x_s − a (t − t_s)²/2;
* a stuck block pushed up the incline by F(t) = k t slips when k t − m g sin α = F_c.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache

import casmbd

_cache = private_cache(CASMBD_COMPILE="0")

ALPHA, G, M, V0 = 0.3, 9.81, 2.0, 3.0
SCENE = """
[scene]
name = "incline"
gravity = [0.0, -9.81]
[parameters]
alpha = 0.3
[[bodies]]
name = "block"
mass = 2.0
inertia = 0.1
position = [0.0, 0.0]
velocity = ["{v0}*cos(alpha)", "{v0}*sin(alpha)"]
[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [0.0, 0.0]
axis = ["cos(alpha)", "sin(alpha)"]
friction = {{ coulomb = {fc}, stick_slip = true }}
"""


def _run(fc, v0=V0, t_end=1.5, extra=""):
    mech = casmbd.loads_scene(SCENE.format(fc=fc, v0=v0) + extra)
    return casmbd.simulate(mech, t_end, 150, rtol=1e-12, atol=1e-12)


def test_sticks_where_friction_holds():
    fc = 7.0  # > m g sin α = 5.798
    res = _run(fc)
    dec = G * math.sin(ALPHA) + fc / M
    assert [e["kind"] for e in res.events] == ["stick"]
    assert res.events[0]["time"] == pytest.approx(V0 / dec, abs=1e-10)
    x = res.joint("slide")["coordinate"]
    assert x[-1] == pytest.approx(V0**2 / (2 * dec), abs=1e-9)
    assert np.all(np.abs(res.joint("slide")["velocity"][res.t > V0 / dec + 1e-6]) < 1e-9)
    # stuck: the joint's friction carries the weight's component along the incline
    held = res.arrays["contact_forces"][-1, 0]
    assert held == pytest.approx(M * G * math.sin(ALPHA), rel=1e-9)
    assert res.arrays["contact_forces"][0, 0] == pytest.approx(-fc)  # sliding up: −F_c


def test_slides_back_where_it_cannot():
    fc = 4.0
    res = _run(fc)
    dec = G * math.sin(ALPHA) + fc / M
    t_s, x_s = V0 / dec, V0**2 / (2 * dec)
    acc = G * math.sin(ALPHA) - fc / M
    assert [e["kind"] for e in res.events] == ["slip"]
    assert res.events[0]["time"] == pytest.approx(t_s, abs=1e-10)
    late = res.t > t_s
    x = res.joint("slide")["coordinate"][late]
    assert np.max(np.abs(x - (x_s - 0.5 * acc * (res.t[late] - t_s) ** 2))) < 1e-8
    assert res.arrays["contact_forces"][-1, 0] == pytest.approx(fc)  # sliding down: +F_c


def test_stuck_block_slips_under_a_growing_push():
    fc, k = 7.0, 10.0  # F = k t up the incline: slips at k t = F_c + m g sin α
    push = f"""
[[forces]]
name = "push"
type = "force"
body = "block"
value = ["{k}*t*cos(alpha)", "{k}*t*sin(alpha)"]
"""
    res = _run(fc, v0=0.0, t_end=2.0, extra=push)
    kinds = [e["kind"] for e in res.events]
    assert kinds[:2] == ["stick", "slip"]
    t_slip = (fc + M * G * math.sin(ALPHA)) / k
    assert res.events[1]["time"] == pytest.approx(t_slip, abs=1e-9)
    # after slipping: m x'' = k t − m g sin α − F_c, from rest at t_slip
    late = res.t > t_slip
    tau = res.t[late] - t_slip
    x_cf = k * tau**3 / (6 * M)  # the net force grows as k (t − t_slip)
    assert np.max(np.abs(res.joint("slide")["coordinate"][late] - x_cf)) < 1e-8


def test_needs_a_constant_level():
    bad = SCENE.format(fc=7.0, v0=0.0).replace("coulomb = 7.0, stick_slip = true",
                                                "mu = 0.3, stick_slip = true")
    with pytest.raises(casmbd.SceneError, match="stick_slip"):
        casmbd.loads_scene(bad)
