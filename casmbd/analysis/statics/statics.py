"""Static equilibrium of a constrained mechanism and its stability.

Seed 000, "Static analysis" (eqs. 6.227–6.235).  With velocities and accelerations zero the
equations of motion reduce to

    Q_e(q, 0, t) − C_qᵀ λ = 0,      C(q, t) = 0                         (6.227, 6.235)

(the quadratic-velocity forces vanish with v = 0, and so do damping forces).

Which equilibrium.  By default the one nearest the start, stable or not: Newton on
F(q, λ) = 0 converges to the equilibrium whose Newton basin holds the start (normally the
nearest; not a guarantee in distance), and the globalisation
measures progress by the residual ½‖F‖², not by the potential (an inverted pendulum started
0.04 rad from upright stays upright, seed 003's five-hinged arch stays an arch); the result
says which kind it is (``stability``).  ``stable=True`` asks for a stable one: the search
descends the potential energy and ends at a local minimum; if it ends at an unstable
equilibrium (a start that already is one) it leaves it along the downhill eigenvector of K̄
(:data:`~casmbd.analysis.statics.newton.ESCAPE_STEP` in scaled units, at most
:data:`~casmbd.analysis.statics.newton.MAX_ESCAPES` times) and descends again,
and the result's ``notes`` say so.

Globalisation (both methods).  Newton alone fails on real arms: released from a pose where a
joint's gravity moment is largest the stiffness about it vanishes, the Newton step is
unbounded (a minimum-norm step of 1e11 rad was seen).  Every iteration therefore takes a
trust-region step in the tangent space of the constraints, in scaled coordinates (lengths
divided by the size of the mechanism, angles, Euler parameters and unit vectors as they are),
with g = Nᵀ Q_e the net force and K̄ = Nᵀ K N the stiffness (N a basis of ker C_q); Δ starts at
0.5, is at most 1 (radian or mechanism size) and shrinks by 4 on a poor step.

* The nearest equilibrium (default):
  :func:`casmbd.analysis.statics.trust_region.least_squares_step`,
  the Levenberg–Marquardt step of the Gauss–Newton model ½‖b − A dz‖² of ½‖F‖² with
  b = R⁻ᵀ g, A = R⁻ᵀ K̄ (N = QR; ‖R⁻ᵀ g‖ = ‖Q_e − C_qᵀλ‖ for the least-squares λ), both in the
  units of the convergence test.  It is Newton's step dz = K̄⁻¹ g, of any definiteness, when it
  fits.  A step is accepted when the decrease of ½‖F‖² (scaled) is at least 0.1 of the
  model's, or when it is the Newton step and reduces the residual.  Where the model is flat
  (Aᵀb = 0 with F ≠ 0: a pendulum released horizontally, a stationary point of ‖F‖ between
  two equilibria) one descent step on the potential (below) leaves it downhill.  If that step
  raises ‖F‖ (a local minimum of ‖F‖ that is no equilibrium, to which the residual search
  would return), or the trust region collapses (below
  :data:`~casmbd.analysis.statics.newton.STALL_RADIUS`), the rest of the search descends the
  potential, and ``notes`` say so.  A boundary step is followed by a second-order correction
  (the step of the same shift ν from the trial point, kept when it lowers ‖F‖): it settles
  the directions stiffer than ν that a straight step across a curved
  valley disturbs (110 instead of 157 iterations over the arm and arch tests).  If the
  residual search still fails (``max_iter`` spent crawling along a long, narrow valley of
  ‖F‖: the flyball governor's stiff couplers), the answer is the stable equilibrium of the
  potential descent from the same start, and the first note says so.
* A stable equilibrium (``stable=True``, and the steps above):
  :func:`casmbd.analysis.statics.trust_region.trust_region_step` minimises the quadratic model of
  the potential energy −gᵀdz + ½ dzᵀ K̄ dz within ‖dz‖ ≤ Δ.  It is Newton's step when K̄ is
  positive (semi)definite and the step fits, with a rank cut-off
  (:data:`~casmbd.analysis.statics.trust_region.RANK_RTOL` = 1e-10 relative to the largest
  eigenvalue) in the least-squares fallback.  A step is accepted when the work done by the
  applied forces along it, ½ (Q_e(q) + Q_e(q⁺))·(q⁺ − q) (= −ΔV to third order for
  conservative forces; defined for any forces), is at least 0.1 of the model's prediction, or
  when it is the Newton step and reduces the scaled residual.

``"augmented"``
    Newton on F(q, λ) = [Q_e − C_qᵀλ; C] = 0 in the n_q + n_c unknowns with the constraints
    kept as equations: the step solves the (trust-region shifted) KKT system by the null-space
    method — a minimum-norm normal step C_q dn = −C, then the tangential trust-region step —
    and λ⁺ from its first block row; no assembly.  With ν = 0 it is exactly Newton's step on F.
    A step into violated constraints is charged Σ σ_i |C_i| (σ_i = 2 max(|λ_i|, |λ⁺_i|)) in the
    acceptance test.  Near the solution the exact sparse KKT Jacobian polishes (sparse LU,
    least squares with the same rank cut-off when singular).
``"reduced"``
    Newton in the independent coordinates (eqs. 6.229–6.234): the tangential step δq = N dz,
    the dependent coordinates restored by :func:`casmbd.analysis.instant.assembly.assemble`, λ the
    least-squares multipliers.

Natural coordinates: a trial point at which some body's [u v w] has det ≤ 0 (the mirror image
that satisfies the same quadratic constraints) is rejected like a failed assembly and the
trust region shrinks; the iterate stays proper.

Result: angles reduced to (−π, π] (planar body angles, revolute/cylindrical/universal joint
angles) and Euler parameters sign-normalised (e0 ≥ 0), each only where the change leaves the
equations unchanged (not an angle carrying a rotational spring or a driver).

Stability: :func:`casmbd.analysis.statics.stability.classify_stability` on K̄ = Nᵀ K N with N an
orthonormal basis of ker C_q (unscaled, so the eigenvalues keep their meaning), the null
directions of a neutral equilibrium named by the joint coordinates (or the generalized ones
when the mechanism has none).  A mechanism without degrees of freedom is reported stable.

The room, one job a module:
:mod:`~casmbd.analysis.statics.equilibrium_problem` (the equations on a model),
:mod:`~casmbd.analysis.statics.newton` (the search), :mod:`~casmbd.analysis.statics.trust_region`
(its steps), :mod:`~casmbd.analysis.statics.stability` (the verdict),
:mod:`~casmbd.analysis.statics.report` (the result and the reports at a state),
:mod:`~casmbd.analysis.statics.resting` (contacts and stops by an active set); this module is
the entry.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from casmbd.analysis.events.events import has_events
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.checks import check_start
from casmbd.analysis.instant.independent import check_option, find_redundant
from casmbd.analysis.statics.equilibrium_problem import StaticsProblem
from casmbd.analysis.statics.newton import search
from casmbd.analysis.statics.report import StaticsResult, equilibrium_result
from casmbd.analysis.statics.resting import resting_equilibrium
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NumericModel
from casmbd.compiled.workspace import Workspace
from casmbd.errors import AnalysisError
from casmbd.model.needs import ALL_NEEDS, Handling, check
from casmbd.system.equations import System

__all__ = ["METHODS", "STATICS_NEEDS", "static_equilibrium", "statics_functions"]

METHODS = ("augmented", "reduced")
#: functions of the system the statics analysis needs (besides its own residual and Jacobian)
STATICS_NEEDS = ("constraints", "constraint_jacobian", "potential_energy", "outputs",
                 "joint_reactions")


def statics_functions(system) -> list[ca.Function]:
    """Residual F(q, λ, t, p) = [Q_e(q, 0, t, 0) − C_qᵀλ; C], its Jacobian ∂F/∂(q, λ), Q_e
    alone and the Jacobian of the joint coordinates ∂θ/∂q."""
    lam = ca.SX.sym("lambda", system.nc)
    qe = ca.substitute(system.applied_forces, ca.vertcat(system.v, system.u),
                       ca.SX.zeros(system.nq + system.u.numel()))
    force = qe - ca.mtimes(system.constraint_jacobian.T, lam)
    res = ca.vertcat(force, system.constraints)
    jac = ca.jacobian(res, ca.vertcat(system.q, lam))
    # joint coordinates (to name the null directions of a neutral equilibrium)
    joints = ca.vertcat(*[system._joint_coordinate(k) for k in system.joint_coordinate_names]) \
        if system.joint_coordinate_names else ca.SX(0, 1)
    args, names = [system.q, lam, system.t, system.p], ["q", "lambda", "t", "p"]
    return [ca.Function("statics_residual", args, [res], names, ["F"]),
            ca.Function("statics_jacobian", args, [jac], names, ["J"]),
            ca.Function("statics_forces", args[:1] + args[2:], [qe], ["q", "t", "p"], ["Qe"]),
            ca.Function("statics_joint_jacobian", args[:1] + args[2:],
                        [ca.jacobian(joints, system.q)], ["q", "t", "p"], ["Jj"])]


#: why statics refuses rows written at the velocity level (an expert's choice, docs/rolling.md)
NONHOLONOMIC_WHY = (
    "their multipliers act as forces but remove no configuration freedom: the equilibria of a "
    "non-holonomic system are not isolated (a family with one dimension per velocity row "
    "passes through each, every heading of a wheel at rest on level ground), so Newton on "
    "(q, λ) has no unique answer, and the stability of rolling motion is not decided by the "
    "potential (a rolling system can be asymptotically stable without damping)")

#: what statics handles (casmbd.model.needs): every need but velocity-level rows; contacts and
#: stops by an active set
HANDLING = Handling(
    "statics", ALL_NEEDS - {"velocity_constraints"},
    why={"velocity_constraints": NONHOLONOMIC_WHY},
    instead={"velocity_constraints": "simulate with damping to rest (the rolling rows hold "
                                     "while the forces balance), linearize --steady-motion "
                                     "about a rolling state, or a holonomic stand-in for the "
                                     "resting pose (a revolute or fixed joint at the contact)"},
    notes={"events": "closed gaps by an active set (no penetration, no pull)",
           "stick_slip": "at rest the friction is not needed: the equilibrium found is "
                         "frictionless, one of those the friction admits",
           "contact_friction": "closed contacts carry no tangential friction: the "
                               "equilibrium found is frictionless",
           "reaction_forces": "at rest the velocity-dependent friction vanishes",
           "inputs": "actuator inputs at their value at time t"})


def static_equilibrium(mechanism, t: float = 0.0, method: str = "augmented", tol: float = 1e-10,
                       max_iter: int = 100, mode: str = "auto",
                       redundancy: str = "auto", *, stable: bool = False,
                       data: Workspace | None = None) -> StaticsResult:
    """Static equilibrium configuration, multipliers, reactions and stability.

    Parameters
    ----------
    mechanism : Mechanism or NumericModel
        A NumericModel must have been built with :func:`statics_functions` as ``extra``.
    t : float
        Time at which drivers and time-dependent forces are evaluated.
    method : {"augmented", "reduced"}
        Newton on (q, λ), or on the independent coordinates (see the module docstring).
    tol : float
        Convergence: max |Q_e − C_qᵀλ| ≤ tol · max(1, max |Q_e(q₀)|) (the largest applied
        generalized force at the assembled start) and max |C| ≤ tol · max(1, largest |x|,
        |y|, |z|).
    max_iter : int
        Most trust-region iterations (rejected trial steps count).
    mode : {"auto", "compiled", "vm"}
        How the equations are evaluated (see :class:`NumericModel`).
    redundancy : {"auto", "remove"}
        Redundant constraint equations (dependent rows of C_q at the assembled start, named in
        ``stats["redundant_equations"]``) are removed and Newton runs on the independent rows,
        whose KKT matrix is regular; the multipliers of the full set are the minimum-norm
        ones, and so are the reaction components they cannot determine
        (``stats["reactions"]``, :mod:`casmbd.analysis.instant.independent`).
    stable : bool, keyword-only
        False (default): the equilibrium nearest the start, stable or not (the search is
        globalised on the residual ‖F‖); the result says which (``stability``).  True: a
        stable one (the search descends the potential energy; an unstable equilibrium it
        reaches is left along its downhill eigenvector and the descent continues); the
        result's ``notes`` say so if it still ends at an unstable one.
    data : Workspace, optional, keyword-only
        The buffers the run evaluates in (``model.workspace()`` of the NumericModel given);
        default: a workspace of its own, so that the run shares none with other users of the
        model.

    Example: a rod (mass m, length L) pinned at one end at the origin, with a torsional spring
    k at the pivot and gravity −g ŷ, angle θ counter-clockwise from +x: V = m g (L/2) sin θ +
    ½ k θ², so the equilibrium solves k θ = −m g (L/2) cos θ.

    Raises
    ------
    AnalysisError
        Unknown method, or no equilibrium found within ``max_iter`` iterations or no
        acceptable step (e.g. a free body under gravity); the message gives the iterations,
        the residual and the largest residual equations.
    AssemblyError
        The start configuration cannot be assembled.
    """
    if method not in METHODS:
        raise AnalysisError(f"unknown statics method '{method}' (known: {', '.join(METHODS)})")
    check_option(redundancy, "statics")
    if not (np.isfinite(tol) and tol > 0) or max_iter < 1:
        raise AnalysisError(f"statics: need tol > 0 and max_iter >= 1 (got {tol}, {max_iter})")
    t = float(t)
    check(mechanism, HANDLING)
    stable = bool(stable)
    if not isinstance(mechanism, NumericModel) and has_events(mechanism):
        return resting_equilibrium(mechanism, t, method, tol, max_iter, mode,
                                   solve=static_equilibrium, stable=stable)
    if isinstance(mechanism, NumericModel):
        model = mechanism.with_data(data)  # its own buffers (or those given)
    else:
        system = System(mechanism)
        model = compile_model(system, STATICS_NEEDS, mode=mode, extra=statics_functions(system))
        model = model if data is None else model.with_data(data)  # raises: another model's
    t0 = time.perf_counter()
    prob = StaticsProblem(model, t)
    q0 = model.initial_coordinates()
    check_start(model, q0, None, t, what="statics", forces=prob.forces(q0))  # names NaNs
    q = assemble(model, model.initial_coordinates(), t).q
    plan = find_redundant(model, q, t)
    if plan.removes:
        prob.restrict(plan.kept_rows)
    fscale = tol * max(1.0, float(np.max(np.abs(prob.forces(q)), initial=0.0)))
    lscale = tol * max(1.0, float(np.max(np.abs(q[prob.length_idx]), initial=0.0)))
    q, lam, it, history, notes, stability, n = search(prob, q, method, fscale, lscale,
                                                      max_iter, stable)
    solve_seconds = time.perf_counter() - t0
    f = prob.residual(q, lam)
    return equilibrium_result(model, prob, plan, q, lam, f, it, history, notes, stability,
                              n, method, stable, solve_seconds)
