"""Independent reference solutions in minimal coordinates (no casmbd involved).

The functions here derive the equations of motion of two benchmark mechanisms *by hand* in
minimal (joint) coordinates, integrate them with SciPy at tolerances near machine precision and
return JSON-ready dictionaries.  They are meant to validate casmbd's redundant-coordinate forward
dynamics, so nothing in this module imports :mod:`casmbd`.

* :func:`pendulum_chain_reference` -- the planar chain of ``n`` slender rods of
  :func:`benchmarks.chains.pendulum_chain`, released horizontally at rest (absolute rod angles,
  Lagrange's equations, ``solve_ivp(method="DOP853", rtol=atol=1e-13)``).
* :func:`parallelogram_four_bar_reference` -- the unit parallelogram four-bar passing through its
  collinear (singular) pose; one coordinate, constant mass, a closed-form solution by elliptic
  integrals and an ODE cross-check.

Stored results live in ``benchmarks/reference_data/*.json`` (see :data:`REFERENCE_NAMES` and
:func:`load_reference`); regenerate them with ``python -m benchmarks.references --write``.

Example
-------
>>> ref = load_reference("pendulum_chain_n2")
>>> ref["model"]["n"], ref["settings"]["method"]
(2, 'DOP853')
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import platform
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import scipy
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import ellipkinc

__all__ = [
    "DATA_DIR",
    "REFERENCE_NAMES",
    "chain_centres",
    "chain_coefficients",
    "chain_energy",
    "chain_gravity_forces",
    "chain_mass_matrix",
    "chain_rhs",
    "chain_tip_position",
    "chain_velocity_forces",
    "dumps_reference",
    "four_bar_angle_at_time",
    "four_bar_energy",
    "four_bar_rate_squared",
    "four_bar_time_of_angle",
    "load_reference",
    "main",
    "parallelogram_four_bar_reference",
    "pendulum_chain_reference",
    "simulate_chain",
    "simulate_four_bar",
    "write_references",
]

#: Folder of the stored reference solutions.
DATA_DIR: pathlib.Path = pathlib.Path(__file__).resolve().parent / "reference_data"

#: Stored references: name -> (builder, keyword arguments).  ``parallelogram_four_bar`` is the
#: benchmark as stated (gravity, crank +1 rad/s counter-clockwise); ``..._clockwise`` is its
#: mirror image (B moving along +x at 1 m/s, as in the IFToMM/[GDLC06] statement);
#: ``..._no_gravity`` is the same mechanism without gravity.
_REFERENCE_SPECS: dict[str, tuple[str, dict[str, Any]]] = {
    "pendulum_chain_n2": ("chain", {"n": 2}),
    "pendulum_chain_n8": ("chain", {"n": 8}),
    "pendulum_chain_n32": ("chain", {"n": 32}),
    "parallelogram_four_bar": ("four_bar", {}),
    "parallelogram_four_bar_clockwise": ("four_bar", {"omega0": -1.0}),
    "parallelogram_four_bar_no_gravity": ("four_bar", {"gravity": 0.0}),
}

#: Names accepted by :func:`load_reference`.
REFERENCE_NAMES: tuple[str, ...] = tuple(_REFERENCE_SPECS)


# --------------------------------------------------------------------------------------------
# Pendulum chain: kinematics, Lagrange terms, energy
# --------------------------------------------------------------------------------------------


def _check_n(n: int) -> int:
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    return int(n)


def chain_coefficients(n: int) -> np.ndarray:
    """Dimensionless mass-matrix coefficients ``c_ij`` of an ``n``-rod chain.

    ``c_ii = 1/3 + (n - 1 - i)`` and ``c_ij = 1/2 + (n - 1 - max(i, j))`` for ``i != j``
    (0-based), so that ``M_ij = m L² c_ij cos(φ_i − φ_j)``; see :func:`pendulum_chain_reference`
    for the derivation.

    Parameters
    ----------
    n : int
        Number of rods, at least 1.

    Returns
    -------
    numpy.ndarray
        Symmetric ``(n, n)`` array.
    """
    n = _check_n(n)
    idx = np.arange(n)
    c = 0.5 + (n - 1 - np.maximum.outer(idx, idx)).astype(float)
    c[idx, idx] = 1.0 / 3.0 + (n - 1 - idx)
    return c


def chain_centres(phi: Sequence[float] | np.ndarray, length: float = 1.0) -> np.ndarray:
    """Centres of mass ``r_i = Σ_{k<i} L e(φ_k) + (L/2) e(φ_i)``, ``e(φ) = (cos φ, sin φ)``.

    Parameters
    ----------
    phi : array_like
        Absolute rod angles, shape ``(n,)``.
    length : float, optional
        Rod length ``L``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n, 2)``.
    """
    phi = np.asarray(phi, dtype=float)
    e = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    joints = length * (np.cumsum(e, axis=0) - e)  # Σ_{k<i} L e(φ_k)
    return joints + 0.5 * length * e


def chain_tip_position(phi: Sequence[float] | np.ndarray, length: float = 1.0) -> np.ndarray:
    """Free end of the last rod, ``Σ_k L e(φ_k)``.

    Parameters
    ----------
    phi : array_like
        Absolute rod angles, shape ``(n,)``.
    length : float, optional
        Rod length ``L``.

    Returns
    -------
    numpy.ndarray
        ``(x, y)``, shape ``(2,)``.
    """
    phi = np.asarray(phi, dtype=float)
    return length * np.array([math.fsum(np.cos(phi)), math.fsum(np.sin(phi))])


def chain_mass_matrix(
    phi: Sequence[float] | np.ndarray, length: float = 1.0, mass: float = 1.0
) -> np.ndarray:
    """Mass matrix ``M_ij = m L² c_ij cos(φ_i − φ_j)`` (see :func:`chain_coefficients`).

    Parameters
    ----------
    phi : array_like
        Absolute rod angles, shape ``(n,)``.
    length, mass : float, optional
        Rod length ``L`` and mass ``m``.

    Returns
    -------
    numpy.ndarray
        Symmetric positive definite ``(n, n)`` array.
    """
    phi = np.asarray(phi, dtype=float)
    return mass * length**2 * chain_coefficients(phi.size) * np.cos(phi[:, None] - phi[None, :])


def chain_velocity_forces(
    phi: Sequence[float] | np.ndarray,
    phidot: Sequence[float] | np.ndarray,
    length: float = 1.0,
    mass: float = 1.0,
) -> np.ndarray:
    """Quadratic velocity terms ``h_i = m L² Σ_j c_ij sin(φ_i − φ_j) φ̇_j²``.

    They appear on the left of ``M(φ) φ̈ + h(φ, φ̇) = Q(φ)``.

    Parameters
    ----------
    phi, phidot : array_like
        Angles and angular rates, shape ``(n,)`` each.
    length, mass : float, optional
        Rod length ``L`` and mass ``m``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n,)``.
    """
    phi = np.asarray(phi, dtype=float)
    phidot = np.asarray(phidot, dtype=float)
    s = chain_coefficients(phi.size) * np.sin(phi[:, None] - phi[None, :])
    return mass * length**2 * (s @ (phidot * phidot))


def chain_gravity_forces(
    phi: Sequence[float] | np.ndarray,
    length: float = 1.0,
    mass: float = 1.0,
    gravity: float = 9.81,
) -> np.ndarray:
    """Generalized gravity forces ``Q_i = −m g L (n − i − 1/2) cos φ_i`` (0-based ``i``).

    Parameters
    ----------
    phi : array_like
        Absolute rod angles, shape ``(n,)``.
    length, mass, gravity : float, optional
        Rod length ``L``, mass ``m`` and gravitational acceleration ``g`` (acting along −y).

    Returns
    -------
    numpy.ndarray
        Shape ``(n,)``.
    """
    phi = np.asarray(phi, dtype=float)
    n = phi.size
    return -mass * gravity * length * (n - np.arange(n) - 0.5) * np.cos(phi)


def chain_energy(
    phi: Sequence[float] | np.ndarray,
    phidot: Sequence[float] | np.ndarray,
    length: float = 1.0,
    mass: float = 1.0,
    gravity: float = 9.81,
) -> float:
    """Total mechanical energy ``½ φ̇ᵀ M φ̇ + m g L Σ_i (n − i − 1/2) sin φ_i``.

    The potential is zero in the initial (horizontal) pose.

    Parameters
    ----------
    phi, phidot : array_like
        Angles and angular rates, shape ``(n,)`` each.
    length, mass, gravity : float, optional
        Rod length, mass and gravitational acceleration.

    Returns
    -------
    float
        Kinetic plus potential energy in joules.
    """
    phi = np.asarray(phi, dtype=float)
    phidot = np.asarray(phidot, dtype=float)
    n = phi.size
    kinetic = 0.5 * phidot @ chain_mass_matrix(phi, length, mass) @ phidot
    potential = mass * gravity * length * math.fsum((n - np.arange(n) - 0.5) * np.sin(phi))
    return float(kinetic + potential)


def chain_rhs(
    n: int, length: float = 1.0, mass: float = 1.0, gravity: float = 9.81
) -> Callable[[float, np.ndarray], np.ndarray]:
    """First-order right-hand side ``f(t, [φ, φ̇]) = [φ̇, M⁻¹(Q − h)]`` for ``solve_ivp``.

    Parameters
    ----------
    n : int
        Number of rods.
    length, mass, gravity : float, optional
        Rod length, mass and gravitational acceleration.

    Returns
    -------
    callable
        ``f(t, y)`` with ``y`` of shape ``(2 n,)``.
    """
    n = _check_n(n)
    coeff = mass * length**2 * chain_coefficients(n)
    grav = mass * gravity * length * (n - np.arange(n) - 0.5)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        phi = y[:n]
        phidot = y[n:]
        diff = phi[:, None] - phi[None, :]
        m_mat = coeff * np.cos(diff)
        force = -grav * np.cos(phi) - (coeff * np.sin(diff)) @ (phidot * phidot)
        return np.concatenate([phidot, np.linalg.solve(m_mat, force)])

    return rhs


def simulate_chain(
    n: int,
    t_end: float = 2.0,
    *,
    rtol: float = 1e-13,
    atol: float = 1e-13,
    method: str = "DOP853",
    length: float = 1.0,
    mass: float = 1.0,
    gravity: float = 9.81,
    **solve_ivp_kwargs: Any,
) -> Any:
    """Integrate the chain from the horizontal rest pose ``φ = 0, φ̇ = 0``.

    Parameters
    ----------
    n : int
        Number of rods.
    t_end : float, optional
        Final time in seconds.
    rtol, atol : float, optional
        Tolerances passed to :func:`scipy.integrate.solve_ivp`.
    method : str, optional
        ``solve_ivp`` method (``"DOP853"``, ``"Radau"``, ...).
    length, mass, gravity : float, optional
        Rod length, mass and gravitational acceleration.
    **solve_ivp_kwargs
        Extra arguments for ``solve_ivp`` (``events``, ``dense_output``, ``t_eval``...).

    Returns
    -------
    scipy.integrate._ivp.ivp.OdeResult
        The ``solve_ivp`` result; ``y[:n]`` are the angles and ``y[n:]`` the rates.

    Raises
    ------
    RuntimeError
        When the integration fails.
    """
    n = _check_n(n)
    sol = solve_ivp(
        chain_rhs(n, length, mass, gravity),
        (0.0, float(t_end)),
        np.zeros(2 * n),
        method=method,
        rtol=rtol,
        atol=atol,
        **solve_ivp_kwargs,
    )
    if sol.status < 0:
        raise RuntimeError(f"chain n={n}: solve_ivp({method}) failed: {sol.message}")
    return sol


# --------------------------------------------------------------------------------------------
# Pendulum chain reference
# --------------------------------------------------------------------------------------------


def _floats(values: np.ndarray | Sequence[float]) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=float).ravel()]


def pendulum_chain_reference(
    n: int,
    t_end: float = 2.0,
    rtol: float = 1e-13,
    atol: float = 1e-13,
    *,
    length: float = 1.0,
    mass: float = 1.0,
    gravity: float = 9.81,
    verify: bool = True,
    verify_radau: bool = False,
) -> dict[str, Any]:
    r"""Reference solution of the ``n``-rod pendulum chain released horizontally at rest.

    Model
        ``n`` slender rods (length ``L``, mass ``m``, centroidal inertia ``I = m L²/12``) pinned
        end to end; rod 0 is pinned to the ground at the origin.  At ``t = 0`` the chain lies
        along +x at rest; gravity ``g`` acts along −y.  This is
        :func:`benchmarks.chains.pendulum_chain` with its ``"tip"`` marker.

    Coordinates
        Absolute rod angles ``φ_i`` (from +x, counter-clockwise), ``i = 0 … n−1``; with
        ``e(φ) = (cos φ, sin φ)`` and ``e⊥(φ) = (−sin φ, cos φ)`` the centre of rod ``i`` is

        ``r_i = Σ_{k<i} L e(φ_k) + (L/2) e(φ_i)``,  ``ṙ_i = Σ_k a_ik e⊥(φ_k) φ̇_k``,

        with ``a_ik = L`` for ``k < i``, ``L/2`` for ``k = i`` and 0 for ``k > i``.  The tip is
        ``Σ_k L e(φ_k)``.

    Kinetic energy
        ``T = Σ_i ½ m ṙ_i·ṙ_i + ½ I φ̇_i² = ½ φ̇ᵀ M(φ) φ̇`` and, since
        ``e⊥(φ_j)·e⊥(φ_k) = cos(φ_j − φ_k)``,
        ``M_jk = [Σ_i m a_ij a_ik + I δ_jk] cos(φ_j − φ_k) = m L² c_jk cos(φ_j − φ_k)``:

        * ``j = k``: rod ``j`` contributes ``L²/4``, each of the ``n−1−j`` rods beyond it ``L²``,
          plus ``I/m = L²/12``: ``c_jj = 1/4 + 1/12 + (n−1−j) = 1/3 + (n−1−j)``;
        * ``j < k``: only rods ``i ≥ k`` move with both; rod ``k`` gives ``L·L/2``, each of the
          ``n−1−k`` rods beyond it ``L·L``: ``c_jk = 1/2 + (n−1−max(j, k))``.

    Potential energy
        ``V = Σ_i m g y_i = m g L Σ_k (n − k − 1/2) sin φ_k`` (rod ``k`` lifts itself by
        ``(L/2) sin φ_k`` and the ``n−1−k`` rods beyond it by ``L sin φ_k``), so
        ``Q_k = −∂V/∂φ_k = −m g L (n − k − 1/2) cos φ_k``.

    Lagrange's equations
        ``d/dt ∂T/∂φ̇_i = Σ_j M_ij φ̈_j − m L² Σ_j c_ij sin(φ_i − φ_j)(φ̇_i − φ̇_j) φ̇_j`` and
        ``∂T/∂φ_i = −m L² Σ_j c_ij sin(φ_i − φ_j) φ̇_i φ̇_j``; the ``φ̇_i φ̇_j`` terms cancel and

        ``Σ_j M_ij φ̈_j + m L² Σ_j c_ij sin(φ_i − φ_j) φ̇_j² = −m g L (n − i − 1/2) cos φ_i``.

    Integration
        ``solve_ivp(method="DOP853", rtol, atol)`` on ``y = [φ, φ̇]`` from ``y = 0``, solving
        ``M φ̈ = Q − h`` by LU at each evaluation.  With ``verify`` the run is repeated at
        ``10 rtol, 10 atol`` and with ``verify_radau`` with ``method="Radau"`` at ``rtol, atol``;
        the tip-position differences are reported under ``"checks"``.  Energy is evaluated at
        every accepted step.

    Parameters
    ----------
    n : int
        Number of rods, at least 1.
    t_end : float, optional
        Final time in seconds (default 2).
    rtol, atol : float, optional
        DOP853 tolerances (default ``1e-13``).
    length, mass, gravity : float, optional
        Rod length (1 m), mass (1 kg) and gravitational acceleration (9.81 m/s²).
    verify : bool, optional
        Repeat the integration at ten times the tolerances (cheap; default True).
    verify_radau : bool, optional
        Repeat the integration with Radau at the same tolerances (slow: ~10-30 s).

    Returns
    -------
    dict
        JSON-ready dictionary with keys ``"name"``, ``"description"``, ``"model"``,
        ``"derivation"``, ``"settings"``, ``"results"`` (``tip_position``, ``angles``,
        ``rates``, ``energy_initial``, ``energy_final``, ``energy_drift_max``,
        ``energy_drift_relative``, ``nfev``, ``n_steps``), ``"checks"`` and ``"timing"``.

    Raises
    ------
    ValueError
        When ``n`` is not a positive integer.
    RuntimeError
        When an integration fails.
    """
    n = _check_n(n)
    start = time.perf_counter()
    sol = simulate_chain(n, t_end, rtol=rtol, atol=atol, length=length, mass=mass, gravity=gravity)
    elapsed = time.perf_counter() - start
    phi_end = sol.y[:n, -1]
    rate_end = sol.y[n:, -1]
    tip = chain_tip_position(phi_end, length)
    energies = np.array([chain_energy(y[:n], y[n:], length, mass, gravity) for y in sol.y.T])
    energy0 = energies[0]
    drift = float(np.max(np.abs(energies - energy0)))
    energy_scale = mass * gravity * length * n * n / 2.0  # |V| of the chain hanging down

    checks: dict[str, Any] = {}
    runs: list[tuple[str, str, float, float]] = []
    if verify:
        runs.append(
            (f"DOP853 rtol={10 * rtol:g} atol={10 * atol:g}", "DOP853", 10 * rtol, 10 * atol)
        )
    if verify_radau:
        runs.append((f"Radau rtol={rtol:g} atol={atol:g}", "Radau", rtol, atol))
    for label, method, rt, at in runs:
        t0 = time.perf_counter()
        other = simulate_chain(
            n,
            t_end,
            rtol=rt,
            atol=at,
            method=method,
            length=length,
            mass=mass,
            gravity=gravity,
        )
        other_tip = chain_tip_position(other.y[:n, -1], length)
        checks[label] = {
            "tip_position": _floats(other_tip),
            "tip_difference": float(np.max(np.abs(other_tip - tip))),
            "angle_difference": float(np.max(np.abs(other.y[:n, -1] - phi_end))),
            "rate_difference": float(np.max(np.abs(other.y[n:, -1] - rate_end))),
            "nfev": int(other.nfev),
            "elapsed_s": round(time.perf_counter() - t0, 4),
        }

    return {
        "name": f"pendulum_chain_n{n}",
        "description": (
            f"Planar chain of {n} slender rods pinned end to end (rod 0 to the ground at the "
            "origin), released horizontally along +x at rest under gravity along -y; state at "
            f"t = {t_end:g} s from Lagrange's equations in absolute rod angles."
        ),
        "model": {
            "n": n,
            "length": float(length),
            "mass": float(mass),
            "centroidal_inertia": float(mass * length**2 / 12.0),
            "gravity": float(gravity),
            "gravity_direction": [0.0, -1.0],
            "initial_angles": "all 0 (chain along +x)",
            "initial_rates": "all 0",
            "coordinates": "absolute rod angles phi_i from +x, counter-clockwise, 0-based i",
            "tip": "free end of rod n-1: sum_k L (cos phi_k, sin phi_k)",
        },
        "derivation": {
            "centres": "r_i = sum_{k<i} L e(phi_k) + (L/2) e(phi_i), e(a) = (cos a, sin a)",
            "mass_matrix": "M_ij = m L^2 c_ij cos(phi_i - phi_j)",
            "coefficients": "c_ii = 1/3 + (n-1-i); c_ij = 1/2 + (n-1-max(i,j)) for i != j",
            "velocity_terms": "h_i = m L^2 sum_j c_ij sin(phi_i - phi_j) phidot_j^2",
            "gravity_forces": "Q_i = -m g L (n - i - 1/2) cos phi_i",
            "equations": "M(phi) phi_ddot + h(phi, phidot) = Q(phi)",
            "energy": "E = 1/2 phidot^T M phidot + m g L sum_i (n - i - 1/2) sin phi_i",
        },
        "settings": {
            "integrator": "scipy.integrate.solve_ivp",
            "method": "DOP853",
            "rtol": float(rtol),
            "atol": float(atol),
            "t_end": float(t_end),
            "linear_solver": "numpy.linalg.solve (LU) on M(phi)",
        },
        "results": {
            "t_end": float(sol.t[-1]),
            "tip_position": _floats(tip),
            "angles": _floats(phi_end),
            "rates": _floats(rate_end),
            "energy_initial": float(energy0),
            "energy_final": float(energies[-1]),
            "energy_drift_max": drift,
            "energy_scale": float(energy_scale),
            "energy_drift_relative": drift / energy_scale,
            "nfev": int(sol.nfev),
            "n_steps": len(sol.t) - 1,
        },
        "checks": checks,
        "timing": {"elapsed_s": round(elapsed, 4)},
    }


# --------------------------------------------------------------------------------------------
# Parallelogram four-bar
# --------------------------------------------------------------------------------------------


def _four_bar_constants(
    phi0: float, omega0: float, length: float, gravity: float
) -> tuple[float, float, float]:
    """Return ``(c, a, m)``: ``φ̇² = a + 2c sin²u``, ``u = (φ − π/2)/2``, ``m = −2c/a``."""
    c = 12.0 * gravity / (5.0 * length)
    a = omega0 * omega0 + c * (math.sin(phi0) - 1.0)  # φ̇² at the top, φ = π/2
    if not a > 0.0 or omega0 == 0.0:
        raise ValueError(
            "the crank does not rotate fully (phidot^2 at phi = pi/2 would be "
            f"{a!r} <= 0); the closed form here covers the rotating regime only"
        )
    return c, a, -2.0 * c / a


def four_bar_energy(
    phi: float | np.ndarray,
    phidot: float | np.ndarray,
    length: float = 1.0,
    mass: float = 1.0,
    gravity: float = 9.81,
) -> float | np.ndarray:
    """Energy ``E = (5/6) m L² φ̇² + 2 m g L sin φ`` of the parallelogram four-bar.

    Parameters
    ----------
    phi, phidot : float or numpy.ndarray
        Crank angle and rate.
    length, mass, gravity : float, optional
        Link length and mass (all three links equal) and gravitational acceleration.

    Returns
    -------
    float or numpy.ndarray
        Kinetic plus potential energy (zero potential with all links horizontal).
    """
    return 5.0 / 6.0 * mass * length**2 * phidot * phidot + 2.0 * mass * gravity * length * np.sin(
        phi
    )


def four_bar_rate_squared(
    phi: float | np.ndarray,
    phi0: float = math.pi / 2,
    omega0: float = 1.0,
    length: float = 1.0,
    gravity: float = 9.81,
) -> float | np.ndarray:
    """Energy relation ``φ̇² = ω0² + (12 g / 5 L)(sin φ0 − sin φ)``.

    Parameters
    ----------
    phi : float or numpy.ndarray
        Crank angle.
    phi0, omega0 : float, optional
        Initial crank angle and rate.
    length, gravity : float, optional
        Link length and gravitational acceleration.

    Returns
    -------
    float or numpy.ndarray
        ``φ̇²`` on the trajectory through ``(phi0, omega0)``.
    """
    return omega0 * omega0 + 12.0 * gravity / (5.0 * length) * (math.sin(phi0) - np.sin(phi))


def four_bar_time_of_angle(
    phi: float,
    phi0: float = math.pi / 2,
    omega0: float = 1.0,
    length: float = 1.0,
    gravity: float = 9.81,
) -> float:
    """Closed-form time at which the crank reaches ``phi`` (rotating regime).

    With ``φ = π/2 + 2u``, ``φ̇² = a + 2c sin²u`` (``c = 12 g/5L``, ``a = φ̇²`` at the top), so
    ``dt = 2 du / √(a + 2c sin²u)`` and

    ``t(φ) = sgn(ω0) (2/√a) [F(u | m) − F(u0 | m)]``, ``m = −2c/a``,

    with ``F`` the incomplete elliptic integral of the first kind
    (:func:`scipy.special.ellipkinc`, negative parameter).

    Parameters
    ----------
    phi : float
        Crank angle, on the side of ``phi0`` the crank moves to.
    phi0, omega0 : float, optional
        Initial crank angle and rate.
    length, gravity : float, optional
        Link length and gravitational acceleration.

    Returns
    -------
    float
        Time in seconds.

    Raises
    ------
    ValueError
        When the crank does not rotate fully (oscillating regime).
    """
    _, a, m = _four_bar_constants(phi0, omega0, length, gravity)
    u = 0.5 * (phi - math.pi / 2)
    u0 = 0.5 * (phi0 - math.pi / 2)
    return math.copysign(2.0 / math.sqrt(a), omega0) * float(ellipkinc(u, m) - ellipkinc(u0, m))


def four_bar_angle_at_time(
    t: float,
    phi0: float = math.pi / 2,
    omega0: float = 1.0,
    length: float = 1.0,
    gravity: float = 9.81,
) -> float:
    """Crank angle at time ``t`` by inverting :func:`four_bar_time_of_angle`.

    Brent's method on a bracket from the maximum speed, polished by one Newton step
    (``dt/dφ = 1/φ̇``).

    Parameters
    ----------
    t : float
        Time in seconds, ``t >= 0``.
    phi0, omega0 : float, optional
        Initial crank angle and rate.
    length, gravity : float, optional
        Link length and gravitational acceleration.

    Returns
    -------
    float
        ``φ(t)``.
    """
    c, _, _ = _four_bar_constants(phi0, omega0, length, gravity)
    if t == 0.0:
        return float(phi0)
    sign = math.copysign(1.0, omega0)
    speed_max = math.sqrt(omega0 * omega0 + c * (math.sin(phi0) + 1.0))
    far = phi0 + sign * (1.01 * speed_max * t + 1e-3)
    lo, hi = (phi0, far) if sign > 0 else (far, phi0)

    def residual(x: float) -> float:
        return four_bar_time_of_angle(x, phi0, omega0, length, gravity) - t

    phi = brentq(residual, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
    rate = sign * math.sqrt(four_bar_rate_squared(phi, phi0, omega0, length, gravity))
    return float(phi - residual(phi) * rate)


def simulate_four_bar(
    t_end: float = 10.0,
    *,
    phi0: float = math.pi / 2,
    omega0: float = 1.0,
    length: float = 1.0,
    gravity: float = 9.81,
    rtol: float = 1e-13,
    atol: float = 1e-13,
    method: str = "DOP853",
    **solve_ivp_kwargs: Any,
) -> Any:
    """Integrate ``φ̈ = −(6 g / 5 L) cos φ`` from ``(phi0, omega0)``.

    Parameters
    ----------
    t_end : float, optional
        Final time in seconds.
    phi0, omega0 : float, optional
        Initial crank angle and rate.
    length, gravity : float, optional
        Link length and gravitational acceleration.
    rtol, atol : float, optional
        ``solve_ivp`` tolerances.
    method : str, optional
        ``solve_ivp`` method.
    **solve_ivp_kwargs
        Extra ``solve_ivp`` arguments.

    Returns
    -------
    scipy.integrate._ivp.ivp.OdeResult
        ``y[0]`` is the crank angle and ``y[1]`` its rate.

    Raises
    ------
    RuntimeError
        When the integration fails.
    """
    k = 6.0 * gravity / (5.0 * length)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], -k * math.cos(y[0])])

    sol = solve_ivp(
        rhs,
        (0.0, float(t_end)),
        [float(phi0), float(omega0)],
        method=method,
        rtol=rtol,
        atol=atol,
        **solve_ivp_kwargs,
    )
    if sol.status < 0:
        raise RuntimeError(f"four-bar: solve_ivp({method}) failed: {sol.message}")
    return sol


def _collinear_event(t: float, y: np.ndarray) -> float:
    return math.sin(y[0])


def parallelogram_four_bar_reference(
    t_end: float = 10.0,
    *,
    omega0: float = 1.0,
    gravity: float = 9.81,
    length: float = 1.0,
    mass: float = 1.0,
    rtol: float = 1e-13,
    atol: float = 1e-13,
) -> dict[str, Any]:
    r"""Reference solution of the unit parallelogram four-bar through its singular pose.

    Model
        Ground pivots ``A = (0, 0)`` and ``D = (L, 0)``; crank AB, coupler BC and rocker DC are
        slender rods of length ``L`` and mass ``m``.  At ``t = 0`` the crank is vertical
        (``φ0 = π/2``: ``B = (0, L)``, ``C = (L, L)``) and turns at ``omega0``; gravity ``g``
        along −y.  All links are horizontal (collinear, singular pose, where the four-bar can
        switch to the crossed branch) whenever ``φ`` is a multiple of π.

    Minimal coordinate (parallelogram branch)
        On the parallelogram branch the rocker angle equals the crank angle ``φ`` and the coupler
        translates (angle 0): ``B = L e(φ)``, ``C = B + (L, 0)``.  The single coordinate keeps
        the motion on that branch through every collinear pass by construction.

    Energies
        Crank and rocker rotate about fixed pivots, ``I = m L²/3`` each; the coupler translates
        with the velocity of B, ``|v| = L φ̇``::

            T = 2 · ½ (m L²/3) φ̇² + ½ m L² φ̇² = (5/6) m L² φ̇²
            V = m g (L/2) sin φ · 2 + m g L sin φ = 2 m g L sin φ

        so ``M = (5/3) m L²`` is constant and Lagrange gives ``φ̈ = −(6 g / 5 L) cos φ``.

    Closed form
        Energy conservation: ``φ̇² = ω0² + (12 g / 5 L)(sin φ0 − sin φ)``; the time to reach
        ``φ`` is an incomplete elliptic integral (:func:`four_bar_time_of_angle`), inverted
        with Brent's method (:func:`four_bar_angle_at_time`).  These are the reference values
        (``phi_end``, ``phidot_end``, ``collinear_pass_times``), accurate to a few ulps.

    ODE cross-check
        ``solve_ivp(method="DOP853", rtol, atol)`` with an event on ``sin φ = 0``; its end state,
        pass times, energy drift and the residual of the energy relation are reported with the
        suffix ``_ode``.  (At ``rtol = 1e-13`` the ODE's ``φ(10)`` is off by ~1e-11: the angle
        grows to ~33 rad and the phase error accumulates over five revolutions.)

    Parameters
    ----------
    t_end : float, optional
        Final time (default 10 s).
    omega0 : float, optional
        Initial crank rate (default +1 rad/s, counter-clockwise).  ``-1`` is the mirror image,
        ``φ_cw(t) = π − φ_ccw(t)`` (B moving along +x at 1 m/s).
    gravity : float, optional
        Gravitational acceleration along −y (default 9.81; 0 for no gravity).
    length, mass : float, optional
        Link length and mass (1 m, 1 kg).
    rtol, atol : float, optional
        DOP853 tolerances of the ODE cross-check.

    Returns
    -------
    dict
        JSON-ready dictionary with keys ``"name"``, ``"description"``, ``"model"``,
        ``"derivation"``, ``"settings"``, ``"results"`` and ``"timing"``.

    Raises
    ------
    ValueError
        When the crank does not rotate fully.
    RuntimeError
        When the integration fails.
    """
    phi0 = math.pi / 2
    _, a, m_param = _four_bar_constants(phi0, omega0, length, gravity)
    sign = math.copysign(1.0, omega0)

    start = time.perf_counter()
    phi_end = four_bar_angle_at_time(t_end, phi0, omega0, length, gravity)
    phidot_end = sign * math.sqrt(four_bar_rate_squared(phi_end, phi0, omega0, length, gravity))
    # Collinear passes: φ = kπ strictly between φ0 and φ(t_end).
    k_first = math.floor(phi0 / math.pi) + 1 if sign > 0 else math.ceil(phi0 / math.pi) - 1
    ks: list[int] = []
    k = k_first
    while (k * math.pi - phi_end) * sign < 0.0:
        ks.append(k)
        k += int(sign)
    pass_times = [four_bar_time_of_angle(kk * math.pi, phi0, omega0, length, gravity) for kk in ks]
    period = 4.0 * float(ellipkinc(math.pi / 2, m_param)) / math.sqrt(a)
    elapsed_closed = time.perf_counter() - start

    start = time.perf_counter()
    sol = simulate_four_bar(
        t_end,
        phi0=phi0,
        omega0=omega0,
        length=length,
        gravity=gravity,
        rtol=rtol,
        atol=atol,
        events=_collinear_event,
    )
    elapsed_ode = time.perf_counter() - start
    phi_ode = sol.y[0]
    rate_ode = sol.y[1]
    energy = four_bar_energy(phi_ode, rate_ode, length, mass, gravity)
    relation = rate_ode**2 - four_bar_rate_squared(phi_ode, phi0, omega0, length, gravity)
    times_ode = _floats(sol.t_events[0])
    pass_diff = (
        float(np.max(np.abs(np.asarray(times_ode) - np.asarray(pass_times))))
        if len(times_ode) == len(pass_times) and pass_times
        else None
    )

    name = "parallelogram_four_bar"
    if gravity == 0.0:
        name += "_no_gravity"
    if omega0 < 0.0:
        name += "_clockwise"
    b_end = [length * math.cos(phi_end), length * math.sin(phi_end)]
    return {
        "name": name,
        "description": (
            "Unit parallelogram four-bar (ground pivots (0,0) and (L,0), crank AB, coupler BC, "
            "rocker DC, slender rods) started with the crank vertical at "
            f"{omega0:+g} rad/s, g = {gravity:g}; crank angle at t = {t_end:g} s on the "
            "parallelogram branch and its passes through the collinear (singular) pose."
        ),
        "model": {
            "length": float(length),
            "mass": float(mass),
            "gravity": float(gravity),
            "gravity_direction": [0.0, -1.0],
            "ground_pivots": [[0.0, 0.0], [float(length), 0.0]],
            "phi0": phi0,
            "omega0": float(omega0),
            "initial_points": {"B": [0.0, float(length)], "C": [float(length), float(length)]},
            "branch": "parallelogram: rocker angle = crank angle, coupler angle = 0",
            "coordinate": "crank angle phi from +x, counter-clockwise",
        },
        "derivation": {
            "kinetic_energy": "T = 2 * 1/2 (m L^2/3) phidot^2 + 1/2 m L^2 phidot^2 "
            "= (5/6) m L^2 phidot^2",
            "potential_energy": "V = m g (L/2) sin(phi) * 2 + m g L sin(phi) = 2 m g L sin(phi)",
            "mass": "M = (5/3) m L^2 (constant)",
            "equation": "phi_ddot = -(6 g / (5 L)) cos(phi)",
            "energy_relation": "phidot^2 = omega0^2 + (12 g / (5 L)) (sin(phi0) - sin(phi))",
            "time_of_angle": "t(phi) = sgn(omega0) (2/sqrt(a)) [F(u|m) - F(u0|m)], "
            "u = (phi - pi/2)/2, a = omega0^2 + (12 g/(5 L)) (sin(phi0) - 1), "
            "m = -(24 g/(5 L)) / a, F = scipy.special.ellipkinc",
            "revolution_period": "P = 4 K(m) / sqrt(a)",
            "mirror": "omega0 -> -omega0 maps phi(t) -> pi - phi(t)",
        },
        "settings": {
            "t_end": float(t_end),
            "closed_form": "scipy.special.ellipkinc + scipy.optimize.brentq + 1 Newton step",
            "integrator": "scipy.integrate.solve_ivp",
            "method": "DOP853",
            "rtol": float(rtol),
            "atol": float(atol),
            "event": "sin(phi) = 0 (all links collinear)",
        },
        "results": {
            "phi_end": phi_end,
            "phidot_end": phidot_end,
            "rocker_angle_end": phi_end,
            "coupler_angle_end": 0.0,
            "B_end": b_end,
            "C_end": [b_end[0] + float(length), b_end[1]],
            "revolution_period": period,
            "number_of_collinear_passes": len(ks),
            "collinear_pass_angles_over_pi": ks,
            "collinear_pass_times": pass_times,
            "energy": float(four_bar_energy(phi0, omega0, length, mass, gravity)),
            "phi_end_ode": float(phi_ode[-1]),
            "phidot_end_ode": float(rate_ode[-1]),
            "phi_end_ode_error": float(phi_ode[-1] - phi_end),
            "phidot_end_ode_error": float(rate_ode[-1] - phidot_end),
            "number_of_collinear_passes_ode": len(times_ode),
            "collinear_pass_times_ode": times_ode,
            "collinear_pass_times_ode_error": pass_diff,
            "energy_drift_ode": float(np.max(np.abs(energy - energy[0]))),
            "energy_relation_error_ode": float(np.max(np.abs(relation))),
            "nfev_ode": int(sol.nfev),
        },
        "timing": {"closed_form_s": round(elapsed_closed, 5), "ode_s": round(elapsed_ode, 4)},
    }


# --------------------------------------------------------------------------------------------
# Storage
# --------------------------------------------------------------------------------------------


def _format_float(x: float) -> str:
    """17 significant digits, or the shortest repr when it has at most 6 digits (exact)."""
    if not math.isfinite(x):
        raise ValueError(f"cannot store non-finite value {x!r} in JSON")
    short = repr(x)
    mantissa = short.split("e")[0].replace("-", "").replace(".", "").lstrip("0")
    if len(mantissa) <= 6:
        return short
    text = format(x, ".17g")
    if not any(ch in text for ch in ".e"):
        text += ".0"
    return text


def _encode(obj: Any, indent: int, level: int) -> str:
    pad = " " * (indent * (level + 1))
    end = " " * (indent * level)
    if isinstance(obj, dict):
        if not obj:
            return "{}"
        items = [
            f"{pad}{json.dumps(str(k))}: {_encode(v, indent, level + 1)}" for k, v in obj.items()
        ]
        return "{\n" + ",\n".join(items) + "\n" + end + "}"
    if isinstance(obj, list | tuple):
        if not obj:
            return "[]"
        if all(isinstance(v, int | float | np.number) and not isinstance(v, bool) for v in obj):
            return "[" + ", ".join(_encode(v, indent, level + 1) for v in obj) + "]"
        items = [pad + _encode(v, indent, level + 1) for v in obj]
        return "[\n" + ",\n".join(items) + "\n" + end + "]"
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return json.dumps(obj)
    if isinstance(obj, int | np.integer):
        return str(int(obj))
    if isinstance(obj, float | np.floating):
        return _format_float(float(obj))
    raise TypeError(f"cannot encode {type(obj).__name__} as JSON")


def dumps_reference(ref: dict[str, Any], indent: int = 2) -> str:
    """Serialize a reference dictionary as JSON with 17-significant-digit floats.

    Floats whose shortest round-trip representation has at most 6 significant digits (tolerances,
    ``9.81``, ``0.5``...) are written in that form; all others with ``format(x, ".17g")``.  Both
    parse back to the identical double.

    Parameters
    ----------
    ref : dict
        JSON-ready dictionary (str keys; str, bool, None, int, float, list, dict values).
    indent : int, optional
        Spaces per nesting level.

    Returns
    -------
    str
        The JSON text, ending with a newline.
    """
    return _encode(ref, indent, 0) + "\n"


def _environment() -> dict[str, str]:
    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "machine": platform.machine(),
        "generator": "python -m benchmarks.references --write",
    }


def _compute(name: str, radau: bool) -> dict[str, Any]:
    kind, kwargs = _REFERENCE_SPECS[name]
    if kind == "chain":
        ref = pendulum_chain_reference(**kwargs, verify=True, verify_radau=radau)
    else:
        ref = parallelogram_four_bar_reference(**kwargs)
    ref["name"] = name
    ref["environment"] = _environment()
    return ref


def write_references(
    names: Sequence[str] | None = None,
    directory: str | pathlib.Path | None = None,
    radau: bool = True,
    log: Callable[[str], Any] | None = print,
) -> list[pathlib.Path]:
    """Recompute references and write them as ``<directory>/<name>.json``.

    Parameters
    ----------
    names : sequence of str, optional
        Subset of :data:`REFERENCE_NAMES` (default: all).
    directory : str or pathlib.Path, optional
        Output folder (default :data:`DATA_DIR`); created if missing.
    radau : bool, optional
        Also cross-check the chains with Radau (adds ~1 min in total).
    log : callable, optional
        Progress printer (``None`` for silence).

    Returns
    -------
    list of pathlib.Path
        The files written.

    Raises
    ------
    KeyError
        For an unknown name.
    """
    names = list(REFERENCE_NAMES if names is None else names)
    for name in names:
        if name not in _REFERENCE_SPECS:
            raise KeyError(f"unknown reference {name!r}; known: {', '.join(REFERENCE_NAMES)}")
    out_dir = pathlib.Path(DATA_DIR if directory is None else directory)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name in names:
        t0 = time.perf_counter()
        ref = _compute(name, radau)
        path = out_dir / f"{name}.json"
        path.write_text(dumps_reference(ref), encoding="utf-8")
        written.append(path)
        if log is not None:
            log(f"{name}: {_summary(ref)}  [{time.perf_counter() - t0:.2f} s] -> {path}")
    return written


def load_reference(name: str, directory: str | pathlib.Path | None = None) -> dict[str, Any]:
    """Load a stored reference solution.

    Parameters
    ----------
    name : str
        One of :data:`REFERENCE_NAMES` (``"pendulum_chain_n2"``, ``"pendulum_chain_n8"``,
        ``"pendulum_chain_n32"``, ``"parallelogram_four_bar"``, ...), with or without ``.json``.
    directory : str or pathlib.Path, optional
        Folder to read from (default :data:`DATA_DIR`).

    Returns
    -------
    dict
        The dictionary written by :func:`write_references` (see
        :func:`pendulum_chain_reference` and :func:`parallelogram_four_bar_reference`).

    Raises
    ------
    KeyError
        When no such reference is stored.
    """
    stem = name.removesuffix(".json")
    path = pathlib.Path(DATA_DIR if directory is None else directory) / f"{stem}.json"
    if not path.is_file():
        raise KeyError(f"no stored reference {stem!r} (looked for {path})")
    return json.loads(path.read_text(encoding="utf-8"))


def _summary(ref: dict[str, Any]) -> str:
    res = ref["results"]
    if "tip_position" in res:
        x, y = res["tip_position"]
        checks = ", ".join(
            f"{label}: {chk['tip_difference']:.1e}" for label, chk in ref.get("checks", {}).items()
        )
        return (
            f"tip(t={res['t_end']:g}) = ({x:.17g}, {y:.17g}), energy drift "
            f"{res['energy_drift_max']:.1e}, nfev {res['nfev']}; tip vs {checks}"
        )
    return (
        f"phi(t={ref['settings']['t_end']:g}) = {res['phi_end']:.17g}, phidot = "
        f"{res['phidot_end']:.17g}, {res['number_of_collinear_passes']} collinear passes, "
        f"ODE error {res['phi_end_ode_error']:.1e}"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print the stored references, or regenerate them with ``--write``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status.
    """
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.references", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--write", action="store_true", help="recompute and write the JSON files")
    parser.add_argument("--names", nargs="+", choices=REFERENCE_NAMES, help="subset to process")
    parser.add_argument("--output-dir", type=pathlib.Path, default=None, help="folder for --write")
    parser.add_argument("--no-radau", action="store_true", help="skip the Radau cross-checks")
    args = parser.parse_args(argv)
    if args.write:
        write_references(args.names, args.output_dir, radau=not args.no_radau)
        return 0
    status = 0
    for name in args.names or REFERENCE_NAMES:
        try:
            print(f"{name}: {_summary(load_reference(name, args.output_dir))}")
        except KeyError as exc:
            print(f"{name}: {exc.args[0]}", file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
