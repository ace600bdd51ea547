"""Long run: the IFToMM / UDC simple pendulum (benchmark A01) against its exact solution.

``benchmarks/long_pendulum.py``: a 1 kg mass on a massless 1 m link (a distance joint to the
bob's centre of mass), released at rest from the horizontal.  The exact motion is
x = 2L√m sn(u) dn(u), y = −L(1 − 2m sn²(u)), u = K(m) − √(g/L) t, m = 1/2.  The benchmark runs
2 000 s (docs/hard_cases.md, "Long run"); the tests run 100 s (≈ 42 periods) at the
benchmark's output spacing of 0.5 s.

Measured over 100 s at rtol 1e-10: default formulation, position error 1.6e-6 m, energy drift
2.4e-7 J, ‖C‖ ≤ 5e-10; kkt_ode with projection, 3.8e-7 m and 1.7e-7 J.  Bounds: 5–10×.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache
from scipy.integrate import solve_ivp

from benchmarks.long_pendulum import (
    PUBLISHED_END,
    exact_position,
    exact_velocity,
    pendulum_period,
    simple_pendulum,
)
from casmbd.analysis.dynamics.simulate import simulate

G = 9.81
T_END = 100.0
STEPS = 200


_cache = private_cache("cache_long_run", scope="module")


def test_exact_solution_against_scipy_and_published():
    """The elliptic-function solution against DOP853 (rtol = atol = 1e-12) on φ̈ = −(g/L) sin φ
    over 20 s (≤ 1e-10 m, measured 8.6e-12), its velocity against central differences, its
    energy, and the benchmark's published position at 2000 s (6 digits, mirrored: ≤ 1e-6 m)."""
    t = np.linspace(0.0, 20.0, 41)
    sol = solve_ivp(lambda _t, y: (y[1], -G * math.sin(y[0])), (0.0, 20.0),
                    (0.5 * math.pi, 0.0), method="DOP853", t_eval=t, rtol=1e-12, atol=1e-12)
    phi = sol.y[0]
    ode = np.column_stack([np.sin(phi), -np.cos(phi)])
    assert np.max(np.abs(exact_position(t) - ode)) <= 1e-10
    h = 1e-5
    fd = (exact_position(t + h) - exact_position(t - h)) / (2 * h)
    assert np.max(np.abs(fd - exact_velocity(t))) <= 1e-8
    energy = 0.5 * np.sum(exact_velocity(t) ** 2, axis=1) + G * exact_position(t)[:, 1]
    assert np.max(np.abs(energy)) <= 1e-13
    assert pendulum_period() == pytest.approx(4 * 1.854074677301372 / math.sqrt(G), rel=1e-14)
    assert np.max(np.abs(exact_position([2000.0])[0] - PUBLISHED_END)) <= 1e-6


@pytest.mark.parametrize(("formulation", "projection", "pos_tol", "energy_tol", "c_tol"), [
    (None, False, 1e-5, 2e-6, 1e-8),
    ("kkt_ode", True, 3e-6, 1.5e-6, 1e-10),
])
def test_hundred_seconds_match_the_elliptic_solution(formulation, projection, pos_tol,
                                                     energy_tol, c_tol):
    """100 s at rtol 1e-10: the mass's position against the exact solution at all 201 output
    times, energy drift |E − E(0)| [J], the constraint, and the bob's own rotation, which the
    distance joint at its centre of mass leaves exactly at rest."""
    res = simulate(simple_pendulum(), T_END, STEPS, formulation=formulation, rtol=1e-10,
                   projection=projection)
    bob = res.body("bob")
    assert np.max(np.abs(bob["position"][:, :2] - exact_position(res.t))) <= pos_tol
    energy = res["total_energy"]
    assert abs(energy[0]) <= 1e-12  # released at the pivot's height, at rest
    assert np.max(np.abs(energy - energy[0])) <= energy_tol
    assert np.max(res["constraint_violation"]) <= c_tol
    assert np.max(np.abs(bob["angle"])) <= 1e-12


def test_builder_rejects_bad_input():
    with pytest.raises(ValueError, match="must be > 0"):
        simple_pendulum(inertia=0.0)
