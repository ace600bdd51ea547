"""Kinematics and inverse dynamics with rows written at the velocity level (issue 37).

A cart on a knife edge at its centre G, driven at the velocity level: x(t) = t and the heading
θ(t) = 0.5 sin t prescribed, y left to the blade.  The blade's row ẏ cos θ − ẋ sin θ = 0 is
a velocity equation (three velocity equations for three coordinates) and the position y is
decided by the path: y(t) = ∫₀ᵗ tan(0.5 sin s) ds, the quadrature the kinematic analysis
must reproduce by integrating q̇ = v(q, t) between output times (1e-10).

The tyre force by hand: the blade pushes G along its normal n = (−sin θ, cos θ) with F; the
x driver acts along x only, so m ÿ = F cos θ, and ÿ = θ̇ / cos²θ (from ẏ = tan θ), hence
F = m θ̇ / cos³θ = m · 0.5 cos t / cos³(0.5 sin t) — the ``tyre_forces`` column of the blade
(−λ of its row, :func:`casmbd.analysis.driven.inverse.tyre_forces`), to 1e-10.
"""

from __future__ import annotations

import numpy as np
from nonholonomic_scenes import add_knife_edge
from scipy.integrate import quad

import casmbd

MASS = 1.5


def _cart(coordinates: str = "absolute"):
    m = casmbd.Mechanism("cart", gravity=(0.0, 0.0), coordinates=coordinates)
    m.add_body("cart", mass=MASS, inertia=0.1, position=(0.0, 0.0))
    add_knife_edge(m, "blade", "cart", (0.0, 0.0), (1.0, 0.0))
    m.add_driver("ahead", body="cart", coordinate="x", position="t")
    m.add_driver("steer", body="cart", coordinate="angle", position="0.5*sin(t)")
    return m


def test_kinematics_follows_the_path_the_blade_decides():
    res = casmbd.kinematics(_cart(), 2.0, 10, mode="vm")
    y = res.body("cart")["position"][:, 1]
    ref = [quad(lambda s: np.tan(0.5 * np.sin(s)), 0.0, t, epsabs=1e-14, epsrel=1e-14)[0]
           for t in res.t]
    assert np.max(np.abs(y - ref)) <= 1e-10
    assert res.stats["constraint_rank"] == 3  # the blade's row counts as a velocity equation
    # the velocities satisfy every row, the blade's included
    vel = res.body("cart")["velocity"]
    theta = res.body("cart")["angle"]
    assert np.max(np.abs(vel[:, 1] * np.cos(theta) - vel[:, 0] * np.sin(theta))) <= 1e-12


def test_inverse_dynamics_reports_the_tyre_force_by_row():
    inv = casmbd.inverse_dynamics(_cart(), 2.0, 10, mode="vm")
    assert inv.names["tyre_forces"] == ["blade.lateral"]
    t = inv.t
    by_hand = MASS * 0.5 * np.cos(t) / np.cos(0.5 * np.sin(t)) ** 3
    assert np.max(np.abs(inv["tyre_forces"][:, 0] - by_hand)) <= 1e-10
    # the tyre force is −λ of the blade's row (the first row of C: joints before drivers)
    assert np.array_equal(inv["tyre_forces"][:, 0], -inv["lambda"][:, 0])


def test_tyre_forces_agree_across_coordinate_choices():
    """The same force in natural and joint coordinates (another set of equations), 1e-9."""
    ref = casmbd.inverse_dynamics(_cart(), 1.0, 4, mode="vm")["tyre_forces"]
    for coordinates in ("natural", "joint"):
        got = casmbd.inverse_dynamics(_cart(coordinates), 1.0, 4, mode="vm")["tyre_forces"]
        assert np.max(np.abs(got - ref)) <= 1e-9, coordinates


def test_tyre_forces_survive_the_result_file(tmp_path):
    inv = casmbd.inverse_dynamics(_cart(), 1.0, 2, mode="vm")
    path = inv.save(tmp_path / "inv.npz")
    back = casmbd.results.load(path)
    assert back.names["tyre_forces"] == ["blade.lateral"]
    assert np.array_equal(back["tyre_forces"], inv["tyre_forces"])
