"""The critical speed of an upright rolling disc by the steady-motion linearization
(:mod:`casmbd.analysis.statics.steady_motion`) against its closed form.

A uniform thin disc (mass m, radius R, A = m R²/4 about a diameter, C = m R²/2 about the
axle) rolling upright at speed v on a horizontal plane: linearised in the lean θ, Newton–Euler
about the centre gives (A + m R²) θ̈ = (m g R − C (C + m R²) v² / (A R²)) θ (Neimark & Fufaev,
*Dynamics of Nonholonomic Systems*, AMS 1972; O'Reilly, Nonlinear Dynamics 10 (1996)
287–305), i.e. θ̈ = λ² θ with

    λ² = 4 g / (5 R) − 12 v² / (5 R²),

so the lean eigenvalues are ±λ: a real pair (falling) below the critical speed v_c² = g R / 3
and an imaginary pair (stable wobble) above it.  The disc is the wheel of a chain in joint
coordinates (massless links on prismatic x, y, z and revolute yaw, lean; the wheel on its
spin axle) closed by a ``rolling_disc`` joint, as examples/bicycle.toml describes a bicycle:
x, y and the spin are cyclic, the heading a symmetry, and the reduced system keeps the lean
pair and a zero eigenvalue (the turning steady motions nearby).  Runs in CasADi's VM.
"""

from __future__ import annotations

import numpy as np
import pytest
from rolling_disc_scenes import V_CRIT, chain_disc, lean_rate_squared

from casmbd.analysis.statics.steady_motion import SteadyMotion, parameter_root


@pytest.fixture(scope="module")
def steady():
    lin = SteadyMotion(chain_disc(), mode="vm")
    base = lin()
    return lin, base.v  # the state's velocities at 1 m/s: they scale with the speed


def test_cyclic_coordinates_and_modes(steady):
    lin, _ = steady
    one = lin()
    assert one.cyclic == ["x.translation", "y.translation", "spin.angle"]
    assert "yaw.angle" in one.symmetries
    assert "lean.angle" in one.remaining


@pytest.mark.parametrize("factor", [0.5, 0.8, 1.2, 2.0, 3.0])
def test_lean_eigenvalues_equal_the_closed_form(steady, factor):
    """The reduced eigenvalues are {±λ, 0} with λ² of the closed form, to 1e-10 · max(1, |λ|)
    (observed ≤ 6e-15), at 0.5 to 3 times the critical speed."""
    lin, v1 = steady
    speed = factor * V_CRIT
    eig = lin(q=None, v=speed * v1).eigenvalues
    lam = np.sqrt(complex(lean_rate_squared(speed)))
    assert len(eig) == 3
    left = list(eig)
    for value in (-lam, lam, 0.0):  # each expected eigenvalue matched to the nearest one
        k = int(np.argmin([abs(e - value) for e in left]))
        assert abs(left.pop(k) - value) < 1e-10 * max(1.0, abs(lam)), (value, eig)
    assert lin(q=None, v=speed * v1).stable == (factor > 1)


def test_critical_speed_is_sqrt_g_r_over_3(steady):
    """Where the lean pair turns from real to imaginary: tr(J_r²) = 2 λ² changes sign; Brent's
    method on the exact linearization finds v_c = √(g R / 3) to 1e-10 (relative; observed
    6e-16)."""
    lin, v1 = steady

    def trace_of_square(eig):
        return float(np.sum(eig ** 2).real)

    root = parameter_root(lambda s: lin(q=None, v=s * v1).eigenvalues, 0.5 * V_CRIT,
                          1.5 * V_CRIT, trace_of_square)
    assert abs(root / V_CRIT - 1.0) < 1e-10
