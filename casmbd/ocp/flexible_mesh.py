"""Optimal control of mechanisms with flexible bodies: the mesh against the fastest mode and
IPOPT's pivot tolerance.

A flexible body (:mod:`casmbd.model.flexible_bodies`) brings elastic modes into the equations
of motion, and when the body is driven through a joint at a node its fastest mode is that of
the *coupled* system, far above the body's own (fixed-interface) frequencies: the hub-driven
beam of ``tests/ocp/test_ocp_flexible.py`` (10 m, EI = 1.4e4 N m², ρA = 1.2 kg/m, two
Craig–Bampton modes at 3.7 and 22 rad/s) has coupled modes at 15.6 and 71.9 rad/s.  Two things
then go wrong in a collocation transcription (measured on that problem, T = 4 s, 40 intervals,
minimum effort weighted 1e-4):

* **The linear solver's inertia.**  The Lagrangian Hessian is ≈ 2 w h on the controls and
  nearly zero on the modal accelerations, the Jacobian holds the mass (408 kg m²) and the modal
  stiffness (567 N m): the KKT matrix's smallest eigenvalue is 9e-8 against 569 (the reduced
  Hessian is positive definite, the Jacobian of full rank — no LICQ failure).  With MUMPS's
  default pivot tolerance 1e-6 the inertia it reports is wrong, IPOPT adds δ_w ≈ 3…20 to the
  Hessian at every iteration (``lg(rg)`` 0.5…1.3), its steps shrink to 1e-6 and the dual
  infeasibility stays at 1.8e-5 for thousands of iterations.  With a pivot tolerance of 1e-4
  the same NLP converges in 8 iterations: :func:`solver_defaults` sets
  ``ipopt.mumps_pivtol`` = :data:`FLEXIBLE_MUMPS_PIVTOL` for mechanisms with flexible bodies
  (``Ocp.solve(options=...)`` overrides it).
* **The mesh.**  Radau IIA on elements with ω h = 7.2 for the fastest mode damps that mode
  numerically, and the optimiser exploits the discretisation error: the solution's replay
  (the simulated controls) is 17 off.  :func:`mesh_check` compares ω_max h with
  :data:`MESH_OMEGA_H` and warns, naming the body and the subintervals that resolve it:
  replay error 0.09 at ω h = 1.8 (4 subintervals), 8.4e-4 at 0.9 (8 subintervals).  The
  threshold is measured for Radau collocation; multiple shooting is not checked (RK4 with 20
  steps per interval, ω h = 0.36, still replays 0.24 off).

The fastest mode is that of the mechanism linearised about its scene start, at rest, with the
inputs zero: ω² the largest eigenvalue of (Zᵀ K Z, Zᵀ M Z), K = −∂Q/∂q (elastic, gravity and
applied-force stiffness; the constraint forces' λ ∂C_qᵀ/∂q omitted), Z a basis of the null
space of C_q — the constrained linear vibration problem (Géradin & Cardona, *Flexible Multibody
Dynamics*, Wiley 2001, ch. 11; Shabana, *Dynamics of Multibody Systems*, 3rd ed., ch. 5).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.linalg

from casmbd.model.flexible_bodies import is_flexible

__all__ = ["FLEXIBLE_MUMPS_PIVTOL", "MESH_OMEGA_H", "FastestMode", "fastest_mode",
           "flexible_bodies", "mesh_check", "solver_defaults"]

#: IPOPT's MUMPS pivot tolerance for mechanisms with flexible bodies (IPOPT's default 1e-6
#: misjudges the KKT inertia there; see the module docstring).
FLEXIBLE_MUMPS_PIVTOL = 1e-4

#: Largest ω_max h (fastest mode × collocation element length) accepted without a warning:
#: replay error 8.4e-4 at ω h = 0.9, 0.09 at 1.8, 17 at 7.2 (degree-4 Radau, the module
#: docstring's beam).
MESH_OMEGA_H = 1.0


@dataclass(frozen=True)
class FastestMode:
    """The fastest mode of the linearised, constrained mechanism.

    Attributes
    ----------
    omega : float
        Its circular frequency ω_max [rad/s].
    body : str
        The body whose coordinates carry the largest share of the mode's kinetic energy.
    """

    omega: float
    body: str


def flexible_bodies(system) -> list[str]:
    """Names of the mechanism's flexible bodies (empty for a rigid mechanism)."""
    return [name for name, body in system.mechanism.bodies.items() if is_flexible(body)]


def fastest_mode(system) -> FastestMode | None:
    """The fastest mode of ``system`` linearised about its scene start (at rest, inputs zero).

    ω² is the largest eigenvalue magnitude of Zᵀ K Z y = ω² Zᵀ M Z y with K = −∂Q/∂q at
    (q₀, q̇ = 0, u = 0, t = 0) and Z an orthonormal basis of the null space of C_q(q₀).  None
    when the mechanism has no degree of freedom.
    """
    q, v, u, t, p = system.q, system.v, system.u, system.t, system.p
    forces = system.applied_forces + system.quadratic_velocity_forces
    parts = [system.mass_matrix, -ca.jacobian(forces, q)]
    parts.append(system.constraint_jacobian if system.nc else ca.SX(0, system.nq))
    fn = ca.Function("ocp_linearised", [q, v, u, t, p], parts)
    mass, stiff, cq = (np.array(a, dtype=float) for a in fn(
        system.initial_coordinates(), np.zeros(system.nq), np.zeros(system.u.numel()), 0.0,
        system.parameter_values))
    z = scipy.linalg.null_space(cq) if cq.shape[0] else np.eye(system.nq)
    if z.shape[1] == 0:
        return None
    lam, vec = scipy.linalg.eig(z.T @ stiff @ z, z.T @ mass @ z)
    finite = np.isfinite(lam)
    if not finite.any():
        return None
    k = int(np.argmax(np.where(finite, np.abs(lam), -1.0)))
    shape = z @ np.real(vec[:, k])
    energy = {name: float(shape[system.body_slice(name)]
                          @ mass[system.body_slice(name), system.body_slice(name)]
                          @ shape[system.body_slice(name)])
              for name in getattr(system, "descriptions", {})}
    body = max(energy, key=energy.get) if energy else "?"
    return FastestMode(math.sqrt(abs(lam[k].real)), body)


def mesh_check(system, element: float, subintervals: int) -> dict:
    """For a mechanism with flexible bodies: ω_max, ω_max h and, when ω_max h exceeds
    :data:`MESH_OMEGA_H`, a ``RuntimeWarning`` naming the body and the subintervals per
    control interval that bring ω_max h below it.  Empty for a rigid mechanism.

    Parameters
    ----------
    system : System
    element : float
        The collocation element h = T / (intervals × subintervals) [s] (the guess for a free
        final time).
    subintervals : int
        The current collocation elements per control interval.

    Returns
    -------
    dict
        ``fastest_mode_rad_s``, ``fastest_mode_body``, ``fastest_mode_omega_h`` (for the
        solution's statistics).
    """
    if not flexible_bodies(system):
        return {}
    mode = fastest_mode(system)
    if mode is None:
        return {}
    omega_h = mode.omega * element
    if omega_h > MESH_OMEGA_H:
        need = math.ceil(subintervals * omega_h / MESH_OMEGA_H)
        warnings.warn(
            f"ocp: body '{mode.body}': the fastest mode of the linearised mechanism "
            f"({mode.omega:.4g} rad/s, period {2 * math.pi / mode.omega:.3g} s) is not resolved "
            f"by collocation elements of {element:.3g} s (ω h = {omega_h:.3g} > "
            f"{MESH_OMEGA_H:g}): the solution follows the discretisation error (see its "
            f"replay) and IPOPT may stall; use subintervals={need} or more intervals",
            RuntimeWarning, stacklevel=5)
    return {"fastest_mode_rad_s": mode.omega, "fastest_mode_body": mode.body,
            "fastest_mode_omega_h": omega_h}


def solver_defaults(system, solver: str) -> dict:
    """Solver options for mechanisms with flexible bodies (before the user's own):
    ``ipopt.mumps_pivtol`` = :data:`FLEXIBLE_MUMPS_PIVTOL` with IPOPT; nothing otherwise."""
    if solver == "ipopt" and flexible_bodies(system):
        return {"ipopt.mumps_pivtol": FLEXIBLE_MUMPS_PIVTOL}
    return {}
