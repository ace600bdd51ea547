"""The one-DOF reference of the N four-bar mechanism (UDC / IFToMM benchmark A02) on its
parallelogram branch, and the benchmark's published history (``benchmarks/n_four_bar.py``).

**Closed form on the branch** (no casmbd involved).  On the parallelogram branch
all bars share one angle θ (from +x, counter-clockwise) and the couplers translate, each point
moving like a bar tip.  With J_bar = m L²/3 about the pivot::

    T = ½ [ (N+1) m L²/3 + N m L² ] θ̇²,     V = m g L [ (N+1)/2 + N ] sin θ,

so, for α = θ + π/2 (measured from hanging down)::

    α̈ = −k sin α,   k = 3 g (3N + 1) / (2 L (4N + 1)),

a simple pendulum.  Its energy E = ½ α̇² − k cos α exceeds k (it circulates), and with β = α/2::

    β̇² = ω² (1 − m sin² β),   ω² = (E + k)/2,   m = 2k / (E + k) < 1,
    β(t) = am(K(m) − ω t | m)            (α(0) = π, α̇(0) = −v_B0 / L),

with the Jacobi amplitude am (``scipy.special.ellipj``'s ``ph``) and K the complete elliptic
integral of the first kind.  :func:`one_dof_reference` integrates the one-DOF equation with
SciPy (DOP853, rtol = atol = 1e-12, an independent check of the closed form) and
:func:`closed_form_angle` evaluates the elliptic solution.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk

__all__ = [
    "N_BENCH",
    "PUBLISHED_B0",
    "STEPS",
    "T_END",
    "G",
    "b0_position",
    "closed_form_angle",
    "one_dof_rate",
    "one_dof_reference",
    "published_error",
    "reference_checks",
    "singular_pass_times",
]

N_BENCH = 40
T_END = 20.0
STEPS = 400
G = 9.81

#: B0 (x, y) [m] of the benchmark's reference solution at whole seconds (A02_solution_data.txt,
#: an ADAMS/Solver 2003 run by the problem's authors printed to 6 significant digits every
#: 0.05 s; read from the copy in github.com/mikevignos/simEngine3D-Vignos,
#: testExamples/N-4barMechanism)
PUBLISHED_B0 = {
    1.0: (-1.15357e-01, -9.93324e-01),
    2.0: (3.44663e-02, 9.99406e-01),
    3.0: (-3.38518e-01, -9.40960e-01),
    4.0: (6.93421e-02, 9.97593e-01),
    5.0: (-5.40191e-01, -8.41543e-01),
    6.0: (1.05037e-01, 9.94468e-01),
    7.0: (-7.09615e-01, -7.04590e-01),
    8.0: (1.41958e-01, 9.89873e-01),
    9.0: (-8.40387e-01, -5.41987e-01),
    10.0: (1.80513e-01, 9.83573e-01),
    11.0: (-9.30615e-01, -3.65999e-01),
    12.0: (2.21098e-01, 9.75252e-01),
    13.0: (-9.82240e-01, -1.87630e-01),
    14.0: (2.64098e-01, 9.64496e-01),
    15.0: (-9.99878e-01, -1.56064e-02),
    16.0: (3.09869e-01, 9.50779e-01),
    17.0: (-9.89581e-01, 1.43979e-01),
    18.0: (3.58724e-01, 9.33444e-01),
    19.0: (-9.57773e-01, 2.87527e-01),
    20.0: (4.10902e-01, 9.11679e-01),
}


# ---------------------------------------------------------------------- one-DOF reference
def one_dof_rate(n: int, length: float = 1.0, gravity: float = G) -> float:
    """k of α̈ = −k sin α on the parallelogram branch: 3 g (3n + 1) / (2 L (4n + 1)) [1/s²].

    From T = ½ [(n+1) m L²/3 + n m L²] θ̇² and V = m g L [(n+1)/2 + n] sin θ (the bars turn
    about their pivots, the couplers translate with the bar tips); the mass cancels.
    """
    return 3.0 * gravity * (3 * n + 1) / (2.0 * length * (4 * n + 1))


def closed_form_angle(t, n: int, length: float = 1.0, gravity: float = G,
                      speed: float = 1.0) -> np.ndarray:
    """Bar angle θ(t) (from +x, counter-clockwise, unwrapped) by Jacobi elliptic functions.

    θ = 2 β − π/2 with β(t) = am(K(m) − ω t | m), ω² = (E + k)/2, m = 2k/(E + k),
    E = ½ (speed/L)² + k (the energy per unit J of α̈ = −k sin α at α = π).  The argument is
    reduced modulo 2K (am(u + 2K) = am(u) + π) so that long times keep full accuracy.

    Raises
    ------
    ValueError
        When the energy does not make the chain circulate (E ≤ k, m ≥ 1).
    """
    k = one_dof_rate(n, length, gravity)
    energy = 0.5 * (speed / length) ** 2 + k
    m = 2.0 * k / (energy + k)
    if not m < 1.0:
        raise ValueError("closed_form_angle: the chain does not circulate (m >= 1)")
    w = math.sqrt(0.5 * (energy + k))
    kk = float(ellipk(m))
    u = kk - w * np.asarray(t, dtype=float)
    turns = np.floor(u / (2.0 * kk))
    ph = ellipj(u - 2.0 * kk * turns, m)[3]
    return 2.0 * (ph + math.pi * turns) - 0.5 * math.pi


def one_dof_reference(t, n: int, length: float = 1.0, gravity: float = G,
                      speed: float = 1.0, rtol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """θ(t), θ̇(t) of α̈ = −k sin α integrated by SciPy (DOP853, rtol = atol = ``rtol``).

    Initial state θ(0) = π/2 (bars upright), θ̇(0) = −speed / L.
    """
    k = one_dof_rate(n, length, gravity)
    t = np.asarray(t, dtype=float)
    sol = solve_ivp(lambda _t, y: (y[1], -k * math.cos(y[0])), (0.0, float(t[-1])),
                    (0.5 * math.pi, -speed / length), method="DOP853", t_eval=t, rtol=rtol,
                    atol=rtol)
    return sol.y[0], sol.y[1]


def b0_position(theta, length: float = 1.0) -> np.ndarray:
    """B0 = L (cos θ, sin θ), shape (n_t, 2)."""
    theta = np.asarray(theta, dtype=float)
    return length * np.column_stack([np.cos(theta), np.sin(theta)])


def singular_pass_times(n: int, t_end: float = T_END, length: float = 1.0,
                        gravity: float = G, speed: float = 1.0) -> np.ndarray:
    """Times where the bars are horizontal (cos θ = ±1, θ ≡ 0 mod π) on the closed form."""
    from scipy.optimize import brentq

    grid = np.linspace(0.0, t_end, 20001)
    theta = closed_form_angle(grid, n, length, gravity, speed)
    s = np.sin(theta)
    out = []
    for k in np.flatnonzero(np.sign(s[:-1]) * np.sign(s[1:]) < 0):
        out.append(brentq(lambda t: math.sin(float(closed_form_angle(t, n, length, gravity,
                                                                        speed))),
                          grid[k], grid[k + 1], xtol=1e-13))
    return np.array(out)


def published_error(t: np.ndarray, b0: np.ndarray) -> float:
    """Largest |B0 − published| (x or y) at the whole seconds of :data:`PUBLISHED_B0`."""
    worst = 0.0
    for tt, xy in PUBLISHED_B0.items():
        k = int(np.argmin(np.abs(t - tt)))
        if abs(t[k] - tt) < 1e-9:
            worst = max(worst, float(np.max(np.abs(b0[k] - np.asarray(xy)))))
    return worst


def reference_checks(n: int = N_BENCH) -> dict:
    """The closed form against SciPy's one-DOF integration and the published history."""
    t = np.linspace(0.0, T_END, STEPS + 1)
    theta_cf = closed_form_angle(t, n)
    theta_ode, _ = one_dof_reference(t, n)
    published = published_error(t, b0_position(theta_cf))
    passes = singular_pass_times(n)
    k = one_dof_rate(n)
    energy = 0.5 + k
    return {"ode_vs_closed_form": float(np.max(np.abs(theta_ode - theta_cf))),
            "closed_form_vs_published": published, "passes": len(passes),
            "pass_times": [float(x) for x in passes], "k": k,
            "modulus": 2 * k / (energy + k),
            "period": 2 * float(ellipk(2 * k / (energy + k))) / math.sqrt(0.5 * (energy + k)),
            "b0_end": [float(v) for v in b0_position(theta_cf[-1:])[0]],
            "theta_end": float(theta_cf[-1])}
