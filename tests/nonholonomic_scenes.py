"""Small non-holonomic scenes for the velocity-constraint tests (issue 37, item 1).

The scenes use the shipped ``knife_edge`` kind (:mod:`casmbd.model.rolling`): the velocity of
a body point P across a body-fixed blade direction a is zero, l·ṙ_P = 0 with l = R(90°) a
(Neimark & Fufaev 1972, the Chaplygin sleigh), one row written at the velocity level.

The Chaplygin sleigh: a body of mass m and central inertia I_G whose knife edge at P lies a
distance ``a`` behind G along the body axis e.  With u the speed of P along e and ω the turning
rate, u̇ = a ω², ω̇ = −(m a / I_P) u ω (I_P = I_G + m a²); m u² + I_P ω² = m V² is conserved, so

    u(t) = V tanh(λ t + φ₀),   ω(t) = ω₀ cosh φ₀ / cosh(λ t + φ₀),   λ = m a V / I_P,

with tanh φ₀ = u₀ / V (Neimark & Fufaev, ch. II; Bloch, *Nonholonomic Mechanics and
Control*, §1.7).
"""

from __future__ import annotations

import numpy as np

import casmbd


def add_knife_edge(mech, name: str, body: str, point, direction):
    """A planar knife edge on ``body`` against the ground (the shipped kind ``knife_edge``)."""
    return mech.add("knife_edge", name, "ground", body, point, direction)


#: the sleigh of the tests: m, I_G, a (knife a behind G), u₀, ω₀
SLEIGH = {"m": 2.0, "inertia": 0.15, "a": 0.4, "u0": 0.5, "omega0": 1.2}


def sleigh(coordinates: str = "absolute", u0: float | None = None,
           omega0: float | None = None, lateral: float = 0.0, **extra):
    """The Chaplygin sleigh at the origin heading along x, G moving at u₀ e + a ω₀ e⊥
    (+ ``lateral`` e⊥ of inconsistent sideslip, for the projection test)."""
    s = {**SLEIGH, **extra}
    u0 = s["u0"] if u0 is None else u0
    omega0 = s["omega0"] if omega0 is None else omega0
    m = casmbd.Mechanism("sleigh", gravity=(0.0, 0.0), coordinates=coordinates)
    m.add_body("sleigh", mass=s["m"], inertia=s["inertia"], position=(0.0, 0.0),
               velocity=(u0, s["a"] * omega0 + lateral), angular_velocity=omega0)
    add_knife_edge(m, "knife", "sleigh", (-s["a"], 0.0), (1.0, 0.0))
    return m


def sleigh_closed_form(t, u0: float | None = None, omega0: float | None = None, **extra):
    """(u, ω) of the Chaplygin sleigh at times ``t`` (module docstring)."""
    s = {**SLEIGH, **extra}
    u0 = s["u0"] if u0 is None else u0
    omega0 = s["omega0"] if omega0 is None else omega0
    i_p = s["inertia"] + s["m"] * s["a"] ** 2
    big_v = np.sqrt(u0**2 + i_p / s["m"] * omega0**2)
    lam = s["m"] * s["a"] * big_v / i_p
    phi0 = np.arctanh(u0 / big_v)
    phi = lam * np.asarray(t, float) + phi0
    return big_v * np.tanh(phi), omega0 * np.cosh(phi0) / np.cosh(phi)


def sleigh_rates(q, v, a: float | None = None):
    """(u, ω) of the sleigh from absolute coordinates q = (x, y, θ), v = (ẋ, ẏ, θ̇): the speed
    of P along the body axis and the turning rate."""
    a = SLEIGH["a"] if a is None else a
    q, v = np.atleast_2d(q), np.atleast_2d(v)
    theta = q[:, 2]
    return v[:, 0] * np.cos(theta) + v[:, 1] * np.sin(theta), v[:, 2]


def sleigh_motion(result, a: float | None = None):
    """(u, ω) of the sleigh body in a result (any coordinates): the speed of P along the body
    axis and the turning rate, from the body's centre velocity, angle and angular velocity."""
    a = SLEIGH["a"] if a is None else a
    body = result.body("sleigh")
    theta, omega = body["angle"], body["angular_velocity"]
    vel = body["velocity"]
    return vel[:, 0] * np.cos(theta) + vel[:, 1] * np.sin(theta), omega
