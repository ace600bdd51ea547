"""Reports and plots of contacts.

Plots of results whose mechanism has no joints (a free ball, a ball on a contact): the
default kinds skip what has nothing to show instead of failing (H8's finding: `casmbd plot`
raised TypeError on any such result)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import private_cache
from scipy.optimize import brentq

import casmbd
from casmbd.cli import main

_cache = private_cache(CASMBD_COMPILE="0")

BALL = """
[scene]
name = "fall"
gravity = [0.0, -9.81]
[[bodies]]
name = "ball"
mass = 1.0
inertia = 0.004
position = [0.0, 1.1]
"""
FLOOR = """
[[contacts]]
name = "floor"
body = "ball"
point = [0.0, 1.1]
radius = 0.1
restitution = 0.5
"""


def test_plot_of_a_mechanism_without_joints(tmp_path):
    for k, text in enumerate((BALL, BALL + FLOOR)):
        scene = tmp_path / f"s{k}.toml"
        scene.write_text(text)
        npz, png = tmp_path / f"r{k}.npz", tmp_path / f"r{k}.png"
        assert main(["simulate", str(scene), "--t-end", "1", "--steps", "20",
                     "--out", str(npz)]) == 0
        assert main(["plot", str(npz), "--out", str(png)]) == 0
        assert png.stat().st_size > 1000


def test_compliant_contact_reports_gap_and_force():
    """A compliant contact reports its gap and normal force on the result grid: F_n =
    max(0, k δ^e + STEP(δ, 0, 0, d, c) δ̇), δ = −g, recomputed here from q and v."""
    k, e, c, d = 1e5, 1.5, 20.0, 1e-3
    text = BALL + FLOOR.replace("restitution = 0.5", f'model = "compliant"\nstiffness = {k}\n'
                                f"exponent = {e}\ndamping = {c}\npenetration = {d}")
    res = casmbd.simulate(casmbd.loads_scene(text), 1.0, 400, rtol=1e-10)
    names = res.names["force_outputs"]
    assert names == ["floor.force.gap", "floor.force.normal_force"]
    gap = res.body("ball")["position"][:, 1] - 0.1
    rate = -res.body("ball")["velocity"][:, 1]  # δ̇ = −ġ
    delta = np.maximum(-gap, 0.0)
    s = np.clip(delta / d, 0.0, 1.0)
    expected = np.where(delta > 0, k * delta**e + c * s * s * (3 - 2 * s) * rate, 0.0)
    expected = np.maximum(expected, 0.0)
    out = res.arrays["force_outputs"]
    assert np.max(np.abs(out[:, 0] - gap)) < 1e-12
    assert np.max(np.abs(out[:, 1] - expected)) < 1e-9 * max(1.0, expected.max())
    assert expected.max() > 50.0  # the ball did hit the floor


def test_compliant_stop_from_a_scene():
    """``limit_model = "compliant"`` with ``limit_stiffness`` …: a rod (m = 1, L = 1, pinned at
    an end) hanging against a stop at −1 rad settles where k δ = m g (L/2) cos(−1 − δ)."""
    scene = """
[scene]
name = "stop"
gravity = [0.0, -9.81]
[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.0833333333333333
position = [0.5, 0.0]
[[joints]]
name = "pin"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
lower = -1.0
limit_model = "compliant"
limit_stiffness = 200.0
limit_exponent = 1.0
limit_damping = 0.0
"""
    delta = brentq(lambda d: 200.0 * d - 9.81 * 0.5 * np.cos(-1.0 - d), 0.0, 1.0)
    res = casmbd.static_equilibrium(casmbd.loads_scene(scene))
    assert res.joint_coordinates[0] == pytest.approx(-1.0 - delta, abs=1e-10)


def test_compliant_contact_events_on_the_grid():
    """Compliant contacts list contact/detach where the reported gap changes sign (linear
    interpolation on the output grid: within one output interval of the free-fall time
    sqrt(2 h/g) for the first contact, and alternating afterwards)."""
    text = BALL + FLOOR.replace("restitution = 0.5", 'model = "compliant"\nstiffness = 1e5\n'
                                "damping = 20.0")
    res = casmbd.simulate(casmbd.loads_scene(text), 2.0, 2000)
    kinds = [e["kind"] for e in res.events]
    assert kinds[:4] == ["contact", "detach", "contact", "detach"]
    assert abs(res.events[0]["time"] - np.sqrt(2 * 1.0 / 9.81)) < 1e-3
    assert "event_times" in res.stats and res.to_json()["events"] == res.events
