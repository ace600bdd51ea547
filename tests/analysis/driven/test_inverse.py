"""Inverse dynamics: driver efforts against an independent Lagrange derivation."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd.analysis.driven.inverse import inverse_dynamics
from casmbd.analysis.dynamics.simulate import simulate

G = 9.81


_cache = private_cache("cache_inverse", scope="module")


def lagrange_crank_torque(theta: np.ndarray, omega: float) -> np.ndarray:
    """Crank torque of examples/slider_crank.toml at constant speed, by Lagrange's equation.

    One coordinate θ (crank angle); closed-form positions r_i(θ) and rod angle φ(θ);
    m(θ) = Σ m_i |∂r_i/∂θ|² + I_1 + I_2 (∂φ/∂θ)², V(θ) = g Σ m_i y_i, and with θ̈ = 0:
    τ = ½ m'(θ) ω² + V'(θ).  Derivatives by CasADi AD of these expressions (not casmbd's).
    """
    r, length = 0.1, 0.3
    m1, m2, m3 = 0.2, 0.6, 0.5
    i1, i2 = 0.2 * r**2 / 12, 0.6 * length**2 / 12
    th = ca.SX.sym("theta")
    phi = ca.asin(-r * ca.sin(th) / length)
    b = ca.vertcat(r * ca.cos(th), r * ca.sin(th))
    centres = [b / 2, b + length / 2 * ca.vertcat(ca.cos(phi), ca.sin(phi)),
               ca.vertcat(r * ca.cos(th) + length * ca.cos(phi), 0)]
    masses = [m1, m2, m3]
    mass = i1 + i2 * ca.jacobian(phi, th) ** 2
    pot = 0
    for mi, c in zip(masses, centres):
        d = ca.jacobian(c, th)
        mass += mi * ca.dot(d, d)
        pot += mi * G * c[1]
    tau = 0.5 * ca.jacobian(mass, th) * omega**2 + ca.jacobian(pot, th)
    f = ca.Function("tau", [th], [tau])
    return np.array([float(f(x)) for x in theta])


def test_slider_crank_torque_matches_lagrange():
    """Seed 000's slider-crank: torque from the driver multiplier = Lagrange, 1e-9 relative."""
    mech = casmbd.load_scene("examples/slider_crank.toml")
    res = inverse_dynamics(mech, 1.0, 100)
    omega = 2 * np.pi
    expected = lagrange_crank_torque(omega * res.t, omega)
    effort = res["driver_efforts"][:, 0]
    assert np.max(np.abs(effort - expected)) <= 1e-9 * np.max(np.abs(expected))


def test_inverse_matches_forward_driver_effort():
    """The same efforts and reactions come out of a forward simulation of the driven scene."""
    mech = casmbd.load_scene("examples/slider_crank.toml")
    inv = inverse_dynamics(mech, 1.0, 10)
    fwd = simulate(mech, 1.0, 10, rtol=1e-11, atol=1e-11)
    scale = np.max(np.abs(inv["driver_efforts"]))
    assert np.max(np.abs(inv["driver_efforts"] - fwd["driver_efforts"])) <= 1e-8 * scale
    assert np.max(np.abs(inv["joint_reactions"] - fwd["joint_reactions"])) <= 1e-7


def test_round_trip_two_link_arm():
    """Efforts from inverse dynamics, fed back as actuator torques, reproduce the motion
    (1e-7 in every coordinate; the open-loop arm is unstable, so this is a strict check)."""
    import sys

    sys.path.insert(0, "examples")
    from two_link_arm import round_trip

    out = round_trip(steps=400, rtol=1e-11)
    assert out["max_position_error"] <= 1e-7
    # the actuators sit on the driven joints: their efforts equal the driver efforts
    inv = out["inverse"]
    assert np.max(np.abs(inv["actuator_efforts"] - inv["driver_efforts"])) <= 1e-9


def test_sampled_driver_is_a_c2_spline(tmp_path):
    """A driver given by samples in a scene interpolates them; rates are its derivatives."""
    scene = tmp_path / "sampled.toml"
    times = np.linspace(0.0, 1.0, 11)
    values = np.sin(times)
    scene.write_text(f"""
[scene]
name = "sampled"
[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.1
position = [0.5, 0.0]
[[joints]]
name = "pivot"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
[[drivers]]
name = "path"
joint = "pivot"
position = {{ times = {json.dumps(times.tolist())}, values = {json.dumps(values.tolist())} }}
""", encoding="utf-8")
    res = casmbd.kinematics(casmbd.load_scene(scene), 1.0, 10)
    angle = res.joint("pivot")
    assert np.max(np.abs(angle["coordinate"] - values)) <= 1e-12     # interpolates the samples
    assert np.max(np.abs(angle["velocity"] - np.cos(times))) <= 1e-3  # spline of sin: O(h^4)
    assert np.max(np.abs(angle["acceleration"] + np.sin(times))) <= 5e-2


def test_actuators_that_cannot_produce_the_motion_raise():
    """An actuator on a joint the drivers do not move cannot realise the prescribed motion."""
    m = casmbd.Mechanism("wrong", gravity=(0.0, -G))
    m.add_body("a", 1.0, 1 / 12, (0.5, 0.0))
    m.add_body("b", 1.0, 1 / 12, (1.5, 0.0))
    m.add_revolute("j1", "ground", "a", (0.0, 0.0))
    m.add_revolute("j2", "a", "b", (1.0, 0.0))
    m.add_driver("d1", "0.5*t", joint="j1")
    m.add_driver("d2", "0.2*t", joint="j2")
    m.add_actuator("only_elbow", "j2")
    with pytest.raises(casmbd.AnalysisError, match="only_elbow"):
        inverse_dynamics(m, 1.0, 4)


def _lagrange_slider_driven(times: np.ndarray) -> np.ndarray:
    """Crank torque for x_slider(t) = 0.3 + 0.05 sin 2πt by Lagrange's equation in θ.

    θ(t) inverts x(θ) = r cos θ + sqrt(l² − r² sin² θ) by Newton; θ̇ = ẋ / x'(θ),
    θ̈ = (ẍ − x''(θ) θ̇²) / x'(θ); τ = m(θ) θ̈ + ½ m'(θ) θ̇² + V'(θ).  Independent of casmbd.
    """
    r, length = 0.1, 0.3
    m1, m2, m3 = 0.2, 0.6, 0.5
    i1, i2 = 0.2 * r**2 / 12, 0.6 * length**2 / 12
    th = ca.SX.sym("theta")
    phi = ca.asin(-r * ca.sin(th) / length)
    b = ca.vertcat(r * ca.cos(th), r * ca.sin(th))
    x_s = r * ca.cos(th) + length * ca.cos(phi)
    centres = [b / 2, b + length / 2 * ca.vertcat(ca.cos(phi), ca.sin(phi)), ca.vertcat(x_s, 0)]
    mass = i1 + i2 * ca.jacobian(phi, th) ** 2
    pot = 0
    for mi, c in zip((m1, m2, m3), centres):
        d = ca.jacobian(c, th)
        mass += mi * ca.dot(d, d)
        pot += mi * G * c[1]
    dx = ca.jacobian(x_s, th)
    f = ca.Function("f", [th], [x_s, dx, ca.jacobian(dx, th), mass, ca.jacobian(mass, th),
                                ca.jacobian(pot, th)])
    out = []
    theta = 1.4033482475752077
    for t in times:
        x = 0.3 + 0.05 * np.sin(2 * np.pi * t)
        xd = 0.05 * 2 * np.pi * np.cos(2 * np.pi * t)
        xdd = -0.05 * (2 * np.pi) ** 2 * np.sin(2 * np.pi * t)
        for _ in range(50):
            theta -= float(f(theta)[0] - x) / float(f(theta)[1])
        _, d1, d2, mm, dm, dv = (float(v) for v in f(theta))
        rate = xd / d1
        acc = (xdd - d2 * rate**2) / d1
        out.append(mm * acc + 0.5 * dm * rate**2 + dv)
    return np.array(out)


def test_seed_slider_crank_torque_three_ways():
    """Seed 000 eqs. 6.218–6.226: slider driven along x(t); the crank torque from the driver
    multiplier by virtual work (M2 = F_d ∂R4x/∂θ2), from the crank actuator (mixed case) and
    from Lagrange's equation agree to 1e-9 relative over the whole motion."""
    res = inverse_dynamics(casmbd.load_scene("examples/slider_crank_inverse.toml"), 1.0, 50)
    theta = res.body("crank")["angle"]
    phi = res.body("rod")["angle"]
    r, length = 0.1, 0.3
    dphi = -r * np.cos(theta) / (length * np.cos(phi))
    dx_dtheta = -r * np.sin(theta) - length * np.sin(phi) * dphi
    virtual_work = res["driver_efforts"][:, 0] * dx_dtheta
    actuator = res["actuator_efforts"][:, 0]
    lagrange = _lagrange_slider_driven(res.t)
    scale = np.max(np.abs(lagrange))
    assert np.max(np.abs(virtual_work - lagrange)) <= 1e-9 * scale
    assert np.max(np.abs(actuator - lagrange)) <= 1e-9 * scale
