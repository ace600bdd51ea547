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
(:data:`ESCAPE_STEP` in scaled units, at most :data:`MAX_ESCAPES` times) and descends again,
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
  would return), or the trust region collapses (below :data:`STALL_RADIUS`), the rest of the
  search descends the potential, and ``notes`` say so.  A boundary step is followed by a
  second-order correction (the step of the same shift ν from the trial point, kept when it
  lowers ‖F‖): it settles the directions stiffer than ν that a straight step across a curved
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
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from casmbd.analysis.events.events import has_events
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.checks import check_start
from casmbd.analysis.instant.independent import (
    IndependentRows,
    check_option,
    check_removed,
    find_redundant,
    minimum_norm,
    scatter,
)
from casmbd.analysis.instant.reactions import flag_undetermined
from casmbd.analysis.instant.redundancy import null_space_basis
from casmbd.analysis.statics.resting import resting_equilibrium
from casmbd.analysis.statics.stability import STABILITY_RTOL, Stability, classify_stability
from casmbd.analysis.statics.trust_region import RANK_RTOL, least_squares_step, trust_region_step
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NumericModel
from casmbd.compiled.workspace import Workspace
from casmbd.errors import AnalysisError, AssemblyError
from casmbd.model.forces import ForceElement
from casmbd.model.measures import result_names
from casmbd.model.needs import ALL_NEEDS, Handling, check
from casmbd.system.descriptions import SpatialNatural, quaternions_from_matrices
from casmbd.system.equations import System

__all__ = ["METHODS", "STABILITY_RTOL", "StaticsResult", "static_equilibrium",
           "statics_functions"]

METHODS = ("augmented", "reduced")
#: functions of the system the statics analysis needs (besides its own residual and Jacobian)
STATICS_NEEDS = ("constraints", "constraint_jacobian", "potential_energy", "outputs",
                 "joint_reactions")
#: trust region (scaled units: radians, Euler parameters, mechanism sizes): start, largest
INITIAL_RADIUS, MAX_RADIUS = 0.5, 1.0
#: accepted when the work along the step is at least this fraction of the model's prediction
ACCEPT_RATIO = 0.1
#: eigenvalues of the reduced stiffness below NOISE_FACTOR · ‖g‖ count as zero in the step
#: (off an equilibrium they are known only to O(‖g‖); measured up to 2.4 ‖g‖ on the arms)
NOISE_FACTOR = 10.0
#: the residual search: a step predicting less than this fraction of ½‖F‖² (a stationary point
#: of ‖F‖ that is not an equilibrium) is replaced by one descent step on the potential; a
#: trust region below STALL_RADIUS hands the search over to the descent
STALL_RTOL, STALL_RADIUS = 1e-12, 1e-10
#: leaving an unstable equilibrium when a stable one is asked for: the step along the downhill
#: eigenvector (scaled units) and the most such restarts
ESCAPE_STEP, MAX_ESCAPES = 0.1, 5
#: coordinate names that are angles (reduced to the principal range)
_ANGLE_NAMES = ("angle", "angle1", "angle2")


@dataclass
class StaticsResult:
    """A static equilibrium configuration.

    Attributes
    ----------
    q : ndarray (n_q,)
    lagrange_multipliers : ndarray (n_c,)
    iterations : int
        Newton iterations taken.
    residual : float
        max |F| at the solution (forces and constraint residuals).
    residual_history : list of float
        max |F| at the start and after every iteration.
    method : str
    stable : bool or None
        True (stable), False (unstable) or None (neutral: a zero eigenvalue).
    eigenvalues : ndarray
        Eigenvalues of the projected stiffness K̄ = Nᵀ K N, ascending.
    stability : Stability
        The verdict, its eigenvalue tolerance and, when neutral, the named null directions
        (:func:`casmbd.analysis.statics.stability.classify_stability`).
    search : {"nearest", "stable"}
        What was looked for: the equilibrium nearest the start (default) or a stable one.
    notes : list of str
        What the search did that matters for the answer (empty normally).
    body_angles, body_quaternions : ndarray
        Planar angles (n_bodies,) or spatial unit quaternions (n_bodies, 4).
    joint_reactions : ndarray (n_joints, 3 or 6)
        (F_x, F_y, M) or (F, M) of each joint, action of body1 on body2 (see
        :meth:`casmbd.system.equations.System.reactions_function`).
    """

    q: np.ndarray
    lagrange_multipliers: np.ndarray
    iterations: int
    residual: float
    residual_history: list
    method: str
    stable: bool | None
    eigenvalues: np.ndarray
    joint_reactions: np.ndarray
    t: float = 0.0
    potential_energy: float = 0.0
    names: dict = field(default_factory=dict)
    body_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    body_angles: np.ndarray = field(default_factory=lambda: np.zeros(0))
    body_quaternions: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    joint_coordinates: np.ndarray = field(default_factory=lambda: np.zeros(0))
    marker_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    #: requests and force-element reports at the equilibrium ("outputs": name -> value,
    #: "forces": element -> quantity -> value), as in the JSON of the grid analyses
    reports: dict = field(default_factory=dict)
    #: closed contacts and stops: name -> {"normal_force", "gap"}
    #: (:func:`casmbd.analysis.statics.resting.resting_equilibrium`)
    contacts: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    stability: Stability | None = None
    #: "nearest" (the equilibrium nearest the start, stable or not: the default) or "stable"
    #: (a stable one asked for: the search descends the potential energy)
    search: str = "nearest"
    #: what the search did that the caller should know (a stall handed over to the descent,
    #: an unstable equilibrium left, a stable one asked for and not found)
    notes: list = field(default_factory=list)
    #: the text summary's values at the equilibrium: requests with their units and named
    #: nodes' deflections (:func:`state_summary`)
    summary: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The JSON object of the ``casmbd statics`` command."""
        bodies = {}
        for k, name in enumerate(self.names.get("bodies", [])):
            bodies[name] = {"position": [float(x) for x in self.body_positions[k]]}
            if len(self.body_quaternions):
                bodies[name]["quaternion"] = [float(x) for x in self.body_quaternions[k]]
            else:
                bodies[name]["angle"] = float(self.body_angles[k])
            modal = [float(x) for x, c in zip(self.q, self.names.get("coordinates", []),
                                              strict=False) if c.startswith(f"{name}.eta")]
            if modal:  # a flexible body's modal coordinates η
                bodies[name]["modal_coordinates"] = modal
        markers = {name: {"position": [float(x) for x in self.marker_positions[k]]}
                   for k, name in enumerate(self.names.get("markers", []))}
        joints: dict = {name: {} for name in self.names.get("all_joints", [])}
        for k, name in enumerate(self.names.get("joints", [])):  # "joint.angle": 2nd coordinate
            joint, key = (name, "coordinate") if name in joints else name.rsplit(".", 1)
            joints.setdefault(joint, {})[key] = float(self.joint_coordinates[k])
        for k, name in enumerate(self.names.get("all_joints", [])):
            joints[name]["reaction"] = [float(x) for x in self.joint_reactions[k]]
        return {"kind": "statics", "t": float(self.t), "bodies": bodies, "joints": joints,
                "markers": markers,
                "q": [float(x) for x in self.q],
                "lagrange_multipliers": [float(x) for x in self.lagrange_multipliers],
                "stable": self.stable, "iterations": int(self.iterations),
                "residual": float(self.residual),
                "residual_history": [float(x) for x in self.residual_history],
                "eigenvalues": [float(x) for x in self.eigenvalues], "method": self.method,
                "search": self.search, "notes": list(self.notes),
                "potential_energy": float(self.potential_energy), "stats": dict(self.stats),
                "stability": self.stability.to_json() if self.stability else None,
                **({"contacts": self.contacts} if self.contacts else {}),
                **self.reports, **({"summary": self.summary} if self.summary else {})}


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


class _Problem:
    """Numeric evaluation of the statics equations on a :class:`NumericModel`."""

    def __init__(self, model: NumericModel, t: float):
        self.model, self.t = model, t
        self.nq, self.nc = model.nq, model.nc
        self.keep: list[int] | None = None  # all rows, unless :meth:`restrict`ed
        names = model.coordinate_names
        self.labels = ([f"equilibrium of coordinate '{n}'" for n in names]
                       + [str(lab) for lab in model.constraint_labels])
        self.length_idx = model.length_indices
        pos = np.array([np.ravel(b.position) for b in model.mechanism.bodies.values()]
                       or [np.zeros(model.dimension)], float)
        #: the size of the mechanism: lengths are measured in it by the trust region
        self.size = max(float(np.max(np.ptp(pos, axis=0))), float(np.max(np.abs(pos))), 1e-3)
        self.scale = np.ones(self.nq)
        self.scale[self.length_idx] = self.size
        #: every applied force keeps its work in V, but for a damper part that vanishes at rest:
        #: a descent step is then measured by the exact fall of V, not by the trapezoidal
        #: work of the forces, which misjudges long steps across a stiff spring
        mech = model.mechanism
        self.conservative = not mech.actuators and all(
            f.energy_exchange() is None
            or (f.energy_exchange() == "damper" and type(f).potential is not ForceElement.potential)
            for f in mech.forces.values())
        self.angles, self.quaternions, self.frames = [], [], []
        for body, desc in model.descriptions.items():
            base = model.coordinate_index[body]
            natural = "Natural" in type(desc).__name__
            for k, name in enumerate(desc.names):
                if name in _ANGLE_NAMES and not natural:
                    self.angles.append(base + k)
                if name == "e0" and tuple(desc.names[k:k + 4]) == ("e0", "e1", "e2", "e3"):
                    self.quaternions.append(base + k)
            if isinstance(desc, SpatialNatural):
                self.frames.append((body, base + 3))

    def potential(self, q: np.ndarray) -> float:
        """V(q) at the problem's time."""
        return float(self.model.potential_energy(q, self.t))

    def restrict(self, keep: list[int]) -> None:
        """Solve with the constraint rows ``keep`` only (the redundant ones removed,
        :mod:`casmbd.analysis.instant.independent`): λ has their size, the residual and the KKT
        Jacobian their rows, so that the Newton matrix is regular."""
        self.full = self.model
        self.model = IndependentRows(self.model, keep)
        self.keep, self.nc = list(keep), len(keep)
        self._rows = np.concatenate([np.arange(self.nq), self.nq + np.asarray(keep, int)])
        self.labels = [self.labels[i] for i in self._rows]

    def _lam(self, lam) -> np.ndarray:
        return lam if self.keep is None else scatter(lam, self.keep, self.full.nc)

    def forces(self, q) -> np.ndarray:
        return self.model.vector("statics_forces", q, self.t, self.model.p)

    def residual(self, q, lam) -> np.ndarray:
        f = self.model.vector("statics_residual", q, self._lam(lam), self.t, self.model.p)
        return f if self.keep is None else f[self._rows]

    def jacobian(self, q, lam) -> sp.csc_matrix:
        jac = self.model.sparse("statics_jacobian", q, self._lam(lam), self.t, self.model.p)
        return jac if self.keep is None else jac[self._rows, :][:, self._rows]

    def cq(self, q) -> np.ndarray:
        if self.nc == 0:
            return np.zeros((0, self.nq))
        return self.model.constraint_jacobian(q, self.t).toarray()

    def multipliers(self, q, rhs: np.ndarray | None = None) -> np.ndarray:
        """Least-squares λ of C_qᵀλ = Q_e (or = ``rhs``), with the rank cut-off."""
        if self.nc == 0:
            return np.zeros(0)
        lam, *_ = sla.lstsq(self.cq(q).T, self.forces(q) if rhs is None else rhs,
                            cond=RANK_RTOL, lapack_driver="gelsd")
        return lam

    def improper(self, q) -> str | None:
        """The first natural-coordinate body whose [u v w] is not a proper rotation."""
        for body, k in self.frames:
            if np.linalg.det(np.reshape(q[k:k + 9], (3, 3))) <= 0.0:  # rows u, v, w
                return body
        return None

    def tangent(self, q, lam):
        """(N, K, g, K̄) with N a basis of ker C_q orthonormal in the scaled coordinates."""
        cq = self.cq(q)
        ns = null_space_basis(cq * self.scale)[0] if self.nc else np.eye(self.nq)
        n = self.scale[:, None] * ns
        k = -self.jacobian(q, lam)[:self.nq, :self.nq].toarray()
        return n, k, n.T @ self.forces(q), n.T @ k @ n

    def worst(self, f: np.ndarray, count: int = 3) -> str:
        order = [i for i in np.argsort(-np.abs(f))[:count] if f[i] != 0] or [0]
        return "; ".join(f"{self.labels[i]} residual {f[i]:.3g}" for i in order)


def _solve(matrix: sp.spmatrix, rhs: np.ndarray) -> np.ndarray:
    """Sparse LU solution, or least squares when the matrix is singular."""
    try:
        x = spla.splu(sp.csc_matrix(matrix)).solve(rhs)
        if np.all(np.isfinite(x)) and np.linalg.norm(matrix @ x - rhs) <= 1e-8 * max(
                1.0, np.linalg.norm(rhs)):
            return x
    except RuntimeError:
        pass
    x, *_ = sla.lstsq(matrix.toarray(), rhs, cond=RANK_RTOL, lapack_driver="gelsd")
    return x


def _null_space(cq: np.ndarray, nq: int) -> np.ndarray:
    """Orthonormal basis of ker C_q (shared rank tolerance of :mod:`redundancy`)."""
    if cq.shape[0] == 0:
        return np.eye(nq)
    return null_space_basis(cq)[0]


#: what statics handles (casmbd.model.needs): every need; contacts and stops by an active set
HANDLING = Handling(
    "statics", ALL_NEEDS,
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
    prob = _Problem(model, t)
    mech = model.mechanism
    q0 = model.initial_coordinates()
    check_start(model, q0, None, t, what="statics", forces=prob.forces(q0))  # names NaNs
    q = assemble(model, model.initial_coordinates(), t).q
    plan = find_redundant(model, q, t)
    if plan.removes:
        prob.restrict(plan.kept_rows)
    fscale = tol * max(1.0, float(np.max(np.abs(prob.forces(q)), initial=0.0)))
    lscale = tol * max(1.0, float(np.max(np.abs(q[prob.length_idx]), initial=0.0)))
    try:
        q, lam, it, history, notes = _iterate(prob, q, method, fscale, lscale, max_iter, stable)
    except AnalysisError as exc:
        if stable:
            raise
        # the residual search failed (a long, narrow valley of ‖F‖ that it crawls along):
        # a stable equilibrium from the same start, by the potential descent
        q, lam, it, history, notes = _iterate(prob, q, method, fscale, lscale, max_iter, True)
        notes.insert(0, f"the search for the nearest equilibrium failed ({exc}); this is the "
                        f"stable equilibrium the potential descent found from the same start")
    q = _principal_range(prob, q, lam, fscale, lscale)
    stability, n = _classify(prob, q, lam)
    escapes = 0
    while stable and stability.verdict == "unstable" and escapes < MAX_ESCAPES \
            and it < max_iter:
        escapes += 1
        q = _leave(prob, q, lam, n)
        q, lam, more, hist, more_notes = _iterate(prob, q, method, fscale, lscale,
                                                  max_iter - it, stable)
        it, history, notes = it + more, history + hist, notes + more_notes
        q = _principal_range(prob, q, lam, fscale, lscale)
        stability, n = _classify(prob, q, lam)
    if escapes:
        notes.append(f"left {escapes} unstable equilibri{'a' if escapes > 1 else 'um'} along "
                     f"the downhill eigenvector of the reduced stiffness")
    if stable and stability.verdict == "unstable":
        notes.append("a stable equilibrium was asked for, but the search ended at an unstable "
                     f"one (lowest stiffness eigenvalue {stability.eigenvalues[0]:.4g})")
    solve_seconds = time.perf_counter() - t0
    f = prob.residual(q, lam)

    check_removed(model, plan, q, t, "statics")
    if plan.removes:  # the least-norm multipliers of the full set
        lam = minimum_norm(model.constraint_jacobian(q, t), scatter(lam, plan.kept_rows,
                                                                    model.nc))
    all_joints = list(mech.joints)
    flags: dict = {}
    if all_joints:
        zero = np.zeros(prob.nq)
        u0 = np.zeros(len(mech.actuators))
        reactions = np.asarray(model.function("joint_reactions")(
            q, zero, zero, t, u0, model.p, lam)).T
        lams = np.asarray(lam, dtype=float)[None, :].copy()
        reactions, flags = flag_undetermined(model, q[None, :], zero[None, :], zero[None, :],
                                             np.array([t]), u0[None, :], lams,
                                             reactions[None], steps=[0])
        reactions, lam = reactions[0], lams[0]
        flags.pop("redundant_steps", None)
        flags.pop("undetermined_rows", None)
    else:
        reactions = np.zeros((0, model.reaction_size))
    out = model.outputs(q[None, :], np.zeros((1, prob.nq)), np.zeros((1, prob.nq)),
                        np.array([t]))
    nb = len(model.body_names)
    names = {"coordinates": model.coordinate_names, "bodies": list(model.body_names),
             "joints": list(model.joint_coordinate_names), "all_joints": all_joints,
             "markers": list(mech.markers),
             **{k: v for k, v in result_names(mech).items() if k == "nodes"}}
    stats = dict(model.report_dict)
    stats.update({"coordinates": model.coordinates, "coordinate_choice": model.coordinates,
                  "coordinate_reason": model.coordinate_reason,
                  "solve_seconds": solve_seconds, "n_coordinates": prob.nq,
                  "n_constraints": model.nc, "degrees_of_freedom": int(n.shape[1]),
                  "search": "stable" if stable else "nearest", **plan.stats(), **flags})
    joint_coordinates = np.ravel(out["joint_positions"][0]).copy()
    for k in _periodic_joint_outputs(mech, model.joint_coordinate_names):
        joint_coordinates[k] = _wrap(joint_coordinates[k])
    reports = state_reports(mech, out)
    quats = np.zeros((0, 4))
    if model.dimension == 3:
        quats = quaternions_from_matrices(out["rotation_matrices"][0].reshape(nb, 9))
        quats *= np.where(quats[:, :1] < 0.0, -1.0, 1.0)  # e0 >= 0
    return StaticsResult(
        q=q, lagrange_multipliers=lam, iterations=it,
        residual=float(np.max(np.abs(f), initial=0.0)), residual_history=history,
        method=method, stable=stability.stable, eigenvalues=stability.eigenvalues,
        joint_reactions=reactions, t=t, potential_energy=model.potential_energy(q, t),
        names=names, body_positions=np.reshape(out["body_positions"][0], (nb, model.dimension)),
        body_angles=np.array([_wrap(a) for a in np.ravel(out["angle_positions"][0])])
        if model.dimension == 2 else np.zeros(0), body_quaternions=quats,
        joint_coordinates=joint_coordinates, stats=stats, stability=stability,
        marker_positions=np.reshape(out["marker_positions"][0], (-1, model.dimension)),
        reports=reports, search="stable" if stable else "nearest", notes=notes,
        summary=state_summary(reports, result_names(mech)))


def _classify(prob: _Problem, q, lam) -> tuple[Stability, np.ndarray]:
    """The stability verdict at (q, λ) and the orthonormal basis N of ker C_q it used."""
    model = prob.model
    jqq = prob.jacobian(q, lam)[:prob.nq, :prob.nq].toarray()
    n = _null_space(prob.cq(q), prob.nq)
    if model.joint_coordinate_names:
        directions = model.sparse("statics_joint_jacobian", q, prob.t, model.p).toarray() @ n
        labels = list(model.joint_coordinate_names)
    else:
        directions, labels = n, list(model.coordinate_names)
    return classify_stability(n.T @ (-jqq) @ n, directions, labels), n


def _leave(prob: _Problem, q, lam, n: np.ndarray) -> np.ndarray:
    """A configuration off the unstable equilibrium q: a step of :data:`ESCAPE_STEP` (scaled
    units) along the eigenvector of the lowest (negative) eigenvalue of K̄, assembled; the
    potential energy falls along it (by ½ μ_min ‖δz‖² to second order)."""
    jqq = prob.jacobian(q, lam)[:prob.nq, :prob.nq].toarray()
    kbar = n.T @ (-jqq) @ n
    _, vec = np.linalg.eigh(0.5 * (kbar + kbar.T))
    dq = n @ vec[:, 0]
    dq *= ESCAPE_STEP / max(float(np.linalg.norm(dq / prob.scale)), 1e-300)
    dq *= 1.0 if dq[int(np.argmax(np.abs(dq)))] > 0.0 else -1.0  # a reproducible side
    for trial in (q + dq, q - dq):
        try:
            q_new = assemble(prob.model, trial, prob.t).q
        except AssemblyError:
            continue
        if prob.improper(q_new) is None:
            return q_new
    return q


def state_reports(mech, out: dict) -> dict:
    """Requests (``outputs``), force reports (``forces``) and flexible bodies' named nodes
    (``nodes``: position, deflection and rotation relative to the undeformed body frame) at one
    state (the equilibrium; linearize's operating point), from the outputs Function's groups
    evaluated there (:mod:`casmbd.system.requests`)."""
    names = result_names(mech)
    reports: dict = {}
    if "outputs" in out:
        values = np.ravel(out["outputs"][0])
        reports["outputs"] = {n: float(v) for n, v in zip(names["outputs"], values,
                                                            strict=True)}
    if "force_outputs" in out:
        forces: dict = {}
        values = np.ravel(out["force_outputs"][0])
        for label, v in zip(names["force_outputs"], values, strict=True):
            element, _, quantity = label.rpartition(".")
            forces.setdefault(element, {})[quantity] = float(v)
        reports["forces"] = forces
    if "node_positions" in out:  # flexible bodies' named nodes (casmbd.system.requests)
        dim = mech.dimension
        rdim = 1 if dim == 2 else 3
        pos, defl, rot = (np.ravel(out[f"node_{k}"][0])
                          for k in ("positions", "deflections", "rotations"))
        reports["nodes"] = {
            name: {"position": [float(x) for x in pos[dim * i:dim * i + dim]],
                   "deflection": [float(x) for x in defl[dim * i:dim * i + dim]],
                   "rotation": float(rot[i]) if dim == 2 else
                   [float(x) for x in rot[rdim * i:rdim * i + rdim]]}
            for i, name in enumerate(names["nodes"])}
    return reports


def state_summary(reports: dict, names: dict) -> dict:
    """The text summaries' values at one state (an equilibrium, an operating point), in the
    form :meth:`casmbd.results.Result.summary` gives on a grid: ``{"outputs": {name: {"unit",
    "value"}}, "node_deflections": {name: {"unit": "m", "value": |u_i|, "deflection": u_i}}}``
    from the ``reports`` of :func:`state_reports` (u_i = Φ_i η, the node's elastic displacement
    relative to its undeformed position, body axes; seed 002, eq. 5–26); {} when there is
    neither."""
    out: dict = {}
    units = dict(zip(names.get("outputs", []), names.get("output_units", []), strict=False))
    if reports.get("outputs"):
        out["outputs"] = {name: {"unit": units.get(name, ""), "value": value}
                          for name, value in reports["outputs"].items()}
    if reports.get("nodes"):
        out["node_deflections"] = {
            name: {"unit": "m", "value": float(np.linalg.norm(node["deflection"])),
                   "deflection": list(node["deflection"])}
            for name, node in reports["nodes"].items()}
    return out


def _converged(prob: _Problem, f: np.ndarray, fscale: float, lscale: float) -> bool:
    return (float(np.max(np.abs(f[:prob.nq]), initial=0.0)) <= fscale
            and float(np.max(np.abs(f[prob.nq:]), initial=0.0)) <= lscale)


def _fail(prob: _Problem, why: str, it: int, f: np.ndarray, method: str):
    raise AnalysisError(
        f"no static equilibrium found at t = {prob.t:g} ({method} Newton): {why} after {it} "
        f"iterations, residual max |F| = {np.max(np.abs(f), initial=0.0):.3g}; largest "
        f"residuals: {prob.worst(f)}")


def _wrap(angle: float) -> float:
    """The angle in (−π, π]."""
    return float(angle - 2.0 * np.pi * np.ceil((angle - np.pi) / (2.0 * np.pi)))


def _periodic_joint_outputs(mech, names: list[str]) -> list[int]:
    """Indices of the reported joint coordinates that are free angles: revolute angles and
    cylindrical ``.angle`` of joints without a rotational spring or a driver (whose winding
    matters)."""
    wound = {f.wound_joint() for f in mech.forces.values()} - {None}
    wound |= {d.joint for d in mech.drivers.values() if d.joint is not None}
    out = []
    for k, name in enumerate(names):
        joint, _, coord = name.partition(".")
        declared = mech.joints[joint].coordinate_names
        if joint not in wound and (coord or (declared[0] if declared else "")) == "angle":
            out.append(k)
    return out


def _principal_range(prob: _Problem, q, lam, fscale: float, lscale: float) -> np.ndarray:
    """Angles to (−π, π], Euler parameters to e0 ≥ 0 — each only if the equations do not
    change (by more than the convergence tolerance): an angle that carries a rotational
    spring or a driver keeps its value."""
    f0 = prob.residual(q, lam)
    for k in prob.angles + prob.quaternions:
        trial = q.copy()
        if k in prob.quaternions:
            block = trial[k:k + 4]
            lead = block[np.flatnonzero(np.abs(block) > 0.0)[:1]]
            if block[0] > 0.0 or (block[0] == 0.0 and np.all(lead >= 0.0)):
                continue
            trial[k:k + 4] = -block
        else:
            if -np.pi < q[k] <= np.pi:
                continue
            trial[k] = _wrap(q[k])
        diff = np.abs(prob.residual(trial, lam) - f0)
        if np.max(diff[:prob.nq], initial=0.0) <= fscale and \
                np.max(diff[prob.nq:], initial=0.0) <= lscale:
            q = trial
    return q


class _State:
    """An iterate (q, λ, F) with the scaled residual norm that the Newton test compares."""

    def __init__(self, prob: _Problem, q, lam, fscale: float, lscale: float):
        self.q, self.lam = q, lam
        self.f = prob.residual(q, lam)
        self.qe = prob.forces(q)
        w = np.concatenate([np.full(prob.nq, 1.0 / fscale), np.full(prob.nc, 1.0 / lscale)])
        self.norm = float(np.linalg.norm(self.f * w))


def _iterate(prob: _Problem, q, method: str, fscale: float, lscale: float, max_iter: int,
             stable: bool = False):
    """The trust-region iteration of both methods (module docstring): globalised on the
    residual (``stable`` False, the equilibrium nearest the start) or on the potential energy
    (``stable`` True).  Returns (q, λ, iterations, residual history, notes)."""
    state = _State(prob, q, prob.multipliers(q), fscale, lscale)
    history = [float(np.max(np.abs(state.f), initial=0.0))]
    radius, it = INITIAL_RADIUS, 0
    notes: list[str] = []
    descend = stable  # the whole search descends the potential (a stable equilibrium)
    while True:
        f = state.f
        if not np.all(np.isfinite(f)):
            _fail(prob, "non-finite residual", it, np.where(np.isfinite(f), f, np.inf), method)
        if _converged(prob, f, fscale, lscale):
            polished = _polish(prob, state, method, fscale, lscale)
            if polished is not None:
                state, it = polished, it + 1
                history.append(float(np.max(np.abs(state.f), initial=0.0)))
            break
        if it >= max_iter:
            _fail(prob, "not converged", it, f, method)
        it += 1
        step, dn, n, k, kind, state = _step(prob, state, method, radius, descend, fscale, lscale,
                                            it)
        kkt = method == "augmented" and step.newton
        trial = _trial(prob, state, dn + n @ step.dz, k, kkt, fscale, lscale)
        if trial is not None and kind == "residual" and not step.newton:
            trial = _corrected(prob, trial, step.nu, fscale, lscale) or trial
        accepted, ratio = False, 0.0
        if trial is not None:
            newton_ok = step.newton and trial.norm < state.norm
            if kind == "descent":  # the fall of V (or the work of the applied forces)
                if prob.conservative:  # against the model's
                    work = prob.potential(state.q) - prob.potential(trial.q)
                else:
                    work = 0.5 * float((state.qe + trial.qe) @ (trial.q - state.q))
                if step.predicted > 0.0:
                    ratio = work / step.predicted
                else:
                    ratio = 1.0 if work >= 0.0 else -1.0
            elif step.predicted > 0.0:  # the decrease of ½‖F‖² against the model's
                ratio = 0.5 * (state.norm**2 - trial.norm**2) / step.predicted
            else:
                ratio = 1.0 if trial.norm < state.norm else -1.0
            accepted = newton_ok if kkt else (ratio >= ACCEPT_RATIO or newton_ok)
        size = float(np.linalg.norm(step.dz))
        if not accepted or (ratio < 0.25 and not step.newton):
            radius = 0.25 * min(radius, max(size, 1e-16))
        elif ratio > 0.75 and size >= 0.99 * radius:
            radius = min(2.0 * radius, MAX_RADIUS)
        if accepted and kind == "descent" and not descend and trial.norm > state.norm:
            # off a local minimum of ‖F‖ that is no equilibrium (the residual search would
            # return to it): descend the potential from here on
            descend = True
            notes.append(f"the residual has a local minimum that is no equilibrium at "
                         f"iteration {it} (max |F| = {np.max(np.abs(f), initial=0.0):.3g}); "
                         f"continued by descending the potential energy")
        if accepted:
            state = trial
        elif radius < STALL_RADIUS and not descend:
            # the residual has a local minimum that is not an equilibrium: descend instead
            descend, radius = True, INITIAL_RADIUS
            notes.append(f"the residual search stalled at iteration {it} (max |F| = "
                         f"{np.max(np.abs(f), initial=0.0):.3g}); continued by descending the "
                         f"potential energy")
        elif radius < 1e-12:
            # at the rounding floor of the equations no step is accepted any more: pure
            # Newton steps from here end it if they reach the tolerance
            for _ in range(3):
                polished = _polish(prob, state, method, fscale, lscale)
                if polished is None:
                    break
                state = polished
                if _converged(prob, state.f, fscale, lscale):
                    break
            if not _converged(prob, state.f, fscale, lscale):
                _fail(prob, "no acceptable step (trust region collapsed)", it, state.f, method)
            notes.append(f"the trust region collapsed at max |F| = "
                         f"{np.max(np.abs(f), initial=0.0):.3g}; Newton steps converged")
            history.append(float(np.max(np.abs(state.f), initial=0.0)))
            break
        history.append(float(np.max(np.abs(state.f), initial=0.0)))
    return state.q, state.lam, it, history, notes


def _step(prob: _Problem, state: _State, method: str, radius: float, descend: bool,
          fscale: float, lscale: float, it: int):
    """The step of one iteration: (step, normal step dn, N, K, kind, state), kind "residual"
    (:func:`~casmbd.analysis.statics.trust_region.least_squares_step` on the residual) or "descent"
    (:func:`~casmbd.analysis.statics.trust_region.trust_region_step` on the potential: the whole
    search with ``descend``, else one step off a stationary point of the residual that is not
    an equilibrium).  A step that is not Newton's is taken from the constraint manifold (the
    state is assembled first when the normal step is not zero)."""
    nq = prob.nq
    for attempt in range(2):
        n, k, g, kbar = prob.tangent(state.q, state.lam)
        dn = np.zeros(nq)
        if method == "augmented" and prob.nc and attempt == 0:  # normal step C_q dn = −C
            dn_s, *_ = sla.lstsq(prob.cq(state.q) * prob.scale, -state.f[nq:], cond=RANK_RTOL,
                                 lapack_driver="gelsd")
            dn = prob.scale * dn_s
            g = g - n.T @ k @ dn
        noise = NOISE_FACTOR * np.linalg.norm(g)
        kind = "descent" if descend else "residual"
        if not descend:
            b, a, noise_b = _residual_model(n, g, kbar, noise, fscale)
            step = least_squares_step(b, a, radius, noise=noise_b)
            if step.predicted <= STALL_RTOL * 0.5 * state.norm**2 and not step.newton:
                kind = "descent"  # a stationary point of ‖F‖: leave it downhill
        if kind == "descent":
            step = trust_region_step(g, kbar, radius, noise=noise)
        if step.newton or not np.any(dn):
            return step, dn, n, k, kind, state
        try:  # globalise from the constraint manifold
            q_on = assemble(prob.model, state.q, prob.t).q
        except AssemblyError:
            _fail(prob, "the iterate left the constraint manifold", it, state.f, method)
        state = _State(prob, q_on, prob.multipliers(q_on), fscale, lscale)
    return step, np.zeros(nq), n, k, kind, state


def _residual_model(n: np.ndarray, g: np.ndarray, kbar: np.ndarray, noise: float,
                    fscale: float):
    """(b, A, noise) of the Gauss–Newton model ½‖b − A dz‖² of ½‖F‖²: ‖Q_e − C_qᵀλ‖ = ‖R⁻ᵀ g‖
    with N = Q R (λ the least-squares multipliers), in the units of the convergence test."""
    r_inv_t = sla.solve_triangular(np.linalg.qr(n)[1], np.eye(n.shape[1]), trans="T") \
        if n.shape[1] else np.zeros((0, 0))
    return (r_inv_t @ g / fscale, r_inv_t @ kbar / fscale,
            noise / fscale * float(np.linalg.norm(r_inv_t, 2)) if n.shape[1] else 0.0)


def _corrected(prob: _Problem, trial: _State, nu: float, fscale, lscale) -> _State | None:
    """The second-order correction of a Levenberg–Marquardt step with shift ν: from the trial
    point, the step of the same ν on the model there (it settles the directions stiffer than
    ν — a stiff spring stretched by a straight step across a curved valley — and hardly moves
    the others), assembled; None if it does not lower the residual."""
    n, k, g, kbar = prob.tangent(trial.q, trial.lam)
    b, a, noise = _residual_model(n, g, kbar, NOISE_FACTOR * np.linalg.norm(g), fscale)
    step = least_squares_step(b, a, np.inf, noise=noise, shift=nu)
    corrected = _trial(prob, trial, n @ step.dz, k, False, fscale, lscale)
    return corrected if corrected is not None and corrected.norm < trial.norm else None


def _trial(prob: _Problem, state: _State, dq, k, kkt: bool, fscale, lscale) -> _State | None:
    """The iterate after the step dq, or None (assembly failed, a mirror-image body).

    ``kkt``: the Newton step on (q, λ) of the augmented method, λ⁺ from the first block row
    of the KKT system (no assembly); otherwise the dependent coordinates are restored by
    assembly and λ⁺ is the least-squares multiplier."""
    if kkt:
        qt = state.q + dq
        lt = prob.multipliers(state.q, state.qe - k @ dq) if prob.nc else np.zeros(0)
    else:
        try:
            qt = assemble(prob.model, state.q + dq, prob.t).q
        except AssemblyError:
            return None
        lt = prob.multipliers(qt)
    if prob.improper(qt) is not None:
        return None
    trial = _State(prob, qt, lt, fscale, lscale)
    return trial if np.isfinite(trial.norm) else None


def _polish(prob: _Problem, state: _State, method: str, fscale, lscale) -> _State | None:
    """One pure Newton step at a converged iterate, kept if it does not raise the residual."""
    if state.norm == 0.0:
        return None
    nq = prob.nq
    if method == "augmented":
        step = _solve(prob.jacobian(state.q, state.lam), -state.f)
        qt, lt = state.q + step[:nq], state.lam + step[nq:]
    else:
        n, _, g, kbar = prob.tangent(state.q, state.lam)
        step = trust_region_step(g, kbar, MAX_RADIUS, noise=NOISE_FACTOR * np.linalg.norm(g))
        if not step.newton:
            return None
        try:
            qt = assemble(prob.model, state.q + n @ step.dz, prob.t).q
        except AssemblyError:
            return None
        lt = prob.multipliers(qt)
    if prob.improper(qt) is not None:
        return None
    trial = _State(prob, qt, lt, fscale, lscale)
    return trial if trial.norm <= state.norm else None
