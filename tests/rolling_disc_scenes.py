"""Builders of the spatial rolling disc's validations (tests/model/test_rolling_disc.py,
tests/analysis/statics/test_rolling_disc_critical_speed.py,
tests/analysis/driven/test_rolling_disc_inverse.py, benchmarks/rolling_disc.py).

A uniform thin disc of mass m and radius R: A = m R²/4 about a diameter, C = m R²/2 about the
axle.  Its steady turns satisfy g sin θ = Ω cos θ (R Ω sin θ / 4 − 3 v / 2) (θ lean, Ω heading
rate, v = R ω·a; derived in tests/model/test_rolling_disc.py), and upright rolling at speed v
has the lean eigenvalues ±λ, λ² = 4 g / (5 R) − 12 v² / (5 R²).
"""

from __future__ import annotations

import numpy as np

import casmbd

R, MASS, G = 0.3, 1.0, 9.81
A_DIA, C_AX = MASS * R * R / 4, MASS * R * R / 2
THETA, OMEGA = 0.3, 2.0  # lean (rad) and heading rate (rad/s) of the steady turn
V_CRIT = np.sqrt(G * R / 3)  # critical speed of upright rolling


def steady_speed(theta: float, omega: float) -> float:
    """v of the steady turn at lean θ and heading rate Ω (module docstring), solved for v:
    v = (2/3) (R Ω sin θ / 4 − g tan θ / Ω)."""
    return 2.0 / 3.0 * (R * omega * np.sin(theta) / 4 - G * np.tan(theta) / omega)


def disc(theta: float, omega: float, v: float, coordinates: str = "absolute",
         lean_rate: float = 0.0) -> casmbd.Mechanism:
    """The disc touching the ground at the origin, rolling along +x, leaning by ``theta`` (its
    top towards −y), its axle a = (0, cos θ, sin θ), with centre velocity (v, 0, 0) and
    angular velocity (v/R) a + Ω cos θ d + lean_rate x̂, d = (0, −sin θ, cos θ)."""
    mech = casmbd.Mechanism("disc", gravity=(0.0, 0.0, -G), coordinates=coordinates)
    a = np.array([0.0, np.cos(theta), np.sin(theta)])
    d = np.array([0.0, -np.sin(theta), np.cos(theta)])
    centre = R * d
    mech.add_body("wheel", mass=MASS, inertia=[A_DIA, C_AX, A_DIA], position=centre,
                  velocity=(v, 0.0, 0.0),
                  angular_velocity=(v / R) * a + omega * np.cos(theta) * d +
                  np.array([lean_rate, 0.0, 0.0]),
                  orientation=[np.cos(theta / 2), np.sin(theta / 2), 0.0, 0.0])
    mech.add_rolling_disc("roll", "ground", "wheel", point=centre, radius=R, axis=a,
                          origin=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0))
    return mech


def motion(res) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lean θ = asin(a·e_z), heading ψ of the rolling direction a × e_z (unwrapped) and the
    angular velocity about the axle ω·a on the grid."""
    body = res.body("wheel")
    axle = body["rotation"][:, :, 1]  # the axle is the body's y axis
    lean = np.arcsin(axle[:, 2])
    rolling = np.cross(axle, [0.0, 0.0, 1.0])
    heading = np.unwrap(np.arctan2(rolling[:, 1], rolling[:, 0]))
    spin = np.einsum("ij,ij->i", body["angular_velocity"], axle)
    return lean, heading, spin


def upright(v: float, lean_rate: float) -> casmbd.Mechanism:
    """The disc upright at speed v along x, its lean rate started at ``lean_rate`` (an angular
    velocity about x; the start's mass-orthogonal projection onto the rolling constraints
    keeps A/(A + m R²) = 1/5 of it as the lean rate)."""
    return disc(0.0, 0.0, v, lean_rate=lean_rate)




def lean_rate_squared(v: float) -> float:
    """λ² of the upright disc at speed v (module docstring)."""
    return 4 * G / (5 * R) - 12 * v * v / (5 * R * R)


def chain_disc() -> casmbd.Mechanism:
    """The upright disc rolling along +x at 1 m/s on a chain of joint coordinates."""
    mech = casmbd.Mechanism("disc", gravity=(0.0, 0.0, -G), coordinates="joint")
    centre, v = (0.0, 0.0, R), 1.0
    for name in ("link_x", "link_y", "link_z", "link_yaw", "link_lean"):
        mech.add_body(name, mass=0.0, inertia=[0.0, 0.0, 0.0], position=centre,
                      velocity=(v, 0.0, 0.0))
    mech.add_body("wheel", mass=MASS, inertia=[A_DIA, C_AX, A_DIA], position=centre,
                  velocity=(v, 0.0, 0.0), angular_velocity=(0.0, v / R, 0.0))
    mech.add_prismatic("x", "ground", "link_x", centre, (1.0, 0.0, 0.0))
    mech.add_prismatic("y", "link_x", "link_y", centre, (0.0, 1.0, 0.0))
    mech.add_prismatic("z", "link_y", "link_z", centre, (0.0, 0.0, 1.0))
    mech.add_revolute("yaw", "link_z", "link_yaw", centre, axis=(0.0, 0.0, 1.0))
    mech.add_revolute("lean", "link_yaw", "link_lean", centre, axis=(1.0, 0.0, 0.0))
    mech.add_revolute("spin", "link_lean", "wheel", centre, axis=(0.0, 1.0, 0.0))
    mech.add_rolling_disc("roll", "ground", "wheel", point=centre, radius=R,
                          axis=(0.0, 1.0, 0.0), normal=(0.0, 0.0, 1.0))
    return mech
