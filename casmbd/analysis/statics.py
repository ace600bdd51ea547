"""Static equilibrium of a constrained mechanism and its stability.

Seed 000, "Static analysis" (eqs. 6.227–6.235).  With velocities and accelerations zero the
equations of motion reduce to

    Q_e(q, 0, t) − C_qᵀ λ = 0,      C(q, t) = 0                         (6.227, 6.235)

(the quadratic-velocity forces vanish with v = 0, and so do damping forces).  Two methods:

``"augmented"``
    Damped Newton-Raphson on F(q, λ) = [Q_e − C_qᵀλ; C] = 0 in the n_q + n_c unknowns, with the
    exact Jacobian from CasADi's algorithmic differentiation,

        J = [[∂Q_e/∂q − ∂(C_qᵀλ)/∂q, −C_qᵀ], [C_q, 0]],

    factorised by sparse LU (least squares when singular) and a backtracking line search on ‖F‖.
    The initial λ is the least-squares solution of C_qᵀλ = Q_e at the assembled start.
``"reduced"``
    Newton-Raphson in the independent coordinates (eqs. 6.229–6.234): with N an orthonormal
    basis of the null space of C_q at the current q (δq = N δq_i, C_q N = 0), the reduced
    equations are Nᵀ Q_e = 0.  The step solves (Nᵀ J_qq N) δz = −Nᵀ r with r = Q_e − C_qᵀλ,
    λ the least-squares multipliers (so that Nᵀ J_qq N is the exact derivative of the reduced
    equations on the constraint manifold); the dependent coordinates are then restored by
    :func:`casmbd.analysis.assembly.assemble`.

Where the stiffness is singular ‖F‖ can be stationary away from any equilibrium (a pendulum
released horizontally); there a step along the projected net force replaces the Newton step
(:func:`_descent_step`).  Newton converges to an equilibrium near the start, not necessarily a
stable one: check :attr:`StaticsResult.stable`.

Stability: the stiffness K = −∂(Q_e − C_qᵀλ)/∂q at fixed λ (the Hessian of the Lagrangian
V + λᵀC for conservative forces) projected onto the constraint tangent space, K̄ = Nᵀ K N.
All eigenvalues > 0 (relative to the largest |eigenvalue|): stable (a strict minimum of the
potential energy on the constraint manifold); any < 0: unstable; otherwise neutral (None).
A mechanism without degrees of freedom is reported stable.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from casmbd.analysis.assembly import assemble
from casmbd.analysis.reactions import flag_undetermined
from casmbd.analysis.redundancy import null_space_basis
from casmbd.compiled.model import NumericModel
from casmbd.errors import AnalysisError, AssemblyError
from casmbd.system.descriptions import quaternions_from_matrices

METHODS = ("augmented", "reduced")
#: relative tolerance on the projected stiffness eigenvalues (times the largest |eigenvalue|)
STABILITY_RTOL = 1e-8
#: functions of the system the statics analysis needs (besides its own residual and Jacobian)
STATICS_NEEDS = ("constraints", "constraint_jacobian", "potential_energy", "outputs",
                 "joint_reactions")


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
    stats: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The JSON object of the ``casmbd statics`` command."""
        bodies = {}
        for k, name in enumerate(self.names.get("bodies", [])):
            bodies[name] = {"position": [float(x) for x in self.body_positions[k]]}
            if len(self.body_quaternions):
                bodies[name]["quaternion"] = [float(x) for x in self.body_quaternions[k]]
            else:
                bodies[name]["angle"] = float(self.body_angles[k])
        joints: dict = {name: {} for name in self.names.get("all_joints", [])}
        for k, name in enumerate(self.names.get("joints", [])):  # "joint.angle": 2nd coordinate
            joint, key = (name, "coordinate") if name in joints else name.rsplit(".", 1)
            joints.setdefault(joint, {})[key] = float(self.joint_coordinates[k])
        for k, name in enumerate(self.names.get("all_joints", [])):
            joints[name]["reaction"] = [float(x) for x in self.joint_reactions[k]]
        return {"kind": "statics", "t": float(self.t), "bodies": bodies, "joints": joints,
                "q": [float(x) for x in self.q],
                "lagrange_multipliers": [float(x) for x in self.lagrange_multipliers],
                "stable": self.stable, "iterations": int(self.iterations),
                "residual": float(self.residual),
                "residual_history": [float(x) for x in self.residual_history],
                "eigenvalues": [float(x) for x in self.eigenvalues], "method": self.method,
                "potential_energy": float(self.potential_energy), "stats": dict(self.stats)}


def statics_functions(system) -> list[ca.Function]:
    """Residual F(q, λ, t, p) = [Q_e(q, 0, t, 0) − C_qᵀλ; C] and its Jacobian ∂F/∂(q, λ)."""
    lam = ca.SX.sym("lambda", system.nc)
    qe = ca.substitute(system.applied_forces, ca.vertcat(system.v, system.u),
                       ca.SX.zeros(system.nq + system.u.numel()))
    force = qe - ca.mtimes(system.constraint_jacobian.T, lam)
    res = ca.vertcat(force, system.constraints)
    jac = ca.jacobian(res, ca.vertcat(system.q, lam))
    args, names = [system.q, lam, system.t, system.p], ["q", "lambda", "t", "p"]
    return [ca.Function("statics_residual", args, [res], names, ["F"]),
            ca.Function("statics_jacobian", args, [jac], names, ["J"]),
            ca.Function("statics_forces", args[:1] + args[2:], [qe], ["q", "t", "p"], ["Qe"])]


class _Problem:
    """Numeric evaluation of the statics equations on a :class:`NumericModel`."""

    def __init__(self, model: NumericModel, t: float):
        self.model, self.t = model, t
        self.nq, self.nc = model.nq, model.nc
        names = model.system.coordinate_names
        self.labels = ([f"equilibrium of coordinate '{n}'" for n in names]
                       + [str(lab) for lab in model.system.constraint_labels])
        self.length_idx = model.system.length_indices

    def forces(self, q) -> np.ndarray:
        return self.model._vector("statics_forces", q, self.t, self.model.p)

    def residual(self, q, lam) -> np.ndarray:
        return self.model._vector("statics_residual", q, lam, self.t, self.model.p)

    def jacobian(self, q, lam) -> sp.csc_matrix:
        return self.model._sparse("statics_jacobian", q, lam, self.t, self.model.p)

    def cq(self, q) -> np.ndarray:
        if self.nc == 0:
            return np.zeros((0, self.nq))
        return self.model.constraint_jacobian(q, self.t).toarray()

    def multipliers(self, q) -> np.ndarray:
        """Least-squares λ of C_qᵀλ = Q_e."""
        if self.nc == 0:
            return np.zeros(0)
        lam, *_ = sla.lstsq(self.cq(q).T, self.forces(q), lapack_driver="gelsd")
        return lam

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
    x, *_ = sla.lstsq(matrix.toarray(), rhs, lapack_driver="gelsd")
    return x


def _null_space(cq: np.ndarray, nq: int) -> np.ndarray:
    """Orthonormal basis of ker C_q (shared rank tolerance of :mod:`redundancy`)."""
    if cq.shape[0] == 0:
        return np.eye(nq)
    return null_space_basis(cq)[0]


def static_equilibrium(mechanism, t: float = 0.0, method: str = "augmented", tol: float = 1e-10,
                       max_iter: int = 50, mode: str = "auto") -> StaticsResult:
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
        Convergence: max |Q_e − C_qᵀλ| ≤ tol · max(1, max |Q_e(q₀)|) and
        max |C| ≤ tol · max(1, largest |x|, |y|).
    max_iter : int
        Most Newton iterations.
    mode : {"auto", "compiled", "vm"}
        How the equations are evaluated (see :class:`NumericModel`).

    Example: a rod (mass m, length L) pinned at one end at the origin, with a torsional spring
    k at the pivot and gravity −g ŷ, angle θ counter-clockwise from +x: V = m g (L/2) sin θ +
    ½ k θ², so the equilibrium solves k θ = −m g (L/2) cos θ.

    Raises
    ------
    AnalysisError
        Unknown method, or no equilibrium found within ``max_iter`` iterations or the line
        search stalled (e.g. a free body under gravity); the message gives the iterations, the
        residual and the largest residual equations.
    AssemblyError
        The start configuration cannot be assembled.
    """
    if method not in METHODS:
        raise AnalysisError(f"unknown statics method '{method}' (known: {', '.join(METHODS)})")
    if not (np.isfinite(tol) and tol > 0) or max_iter < 1:
        raise AnalysisError(f"statics: need tol > 0 and max_iter >= 1 (got {tol}, {max_iter})")
    t = float(t)
    if isinstance(mechanism, NumericModel):
        model = mechanism
    else:
        from casmbd.system.equations import System

        system = System(mechanism)
        model = NumericModel(system, STATICS_NEEDS, mode=mode, extra=statics_functions(system))
    t0 = time.perf_counter()
    prob = _Problem(model, t)
    mech = model.system.mechanism
    q = assemble(model, model.system.initial_coordinates(), t).q
    fscale = tol * max(1.0, float(np.max(np.abs(prob.forces(q)), initial=0.0)))
    lscale = tol * max(1.0, float(np.max(np.abs(q[prob.length_idx]), initial=0.0)))
    solver = _augmented if method == "augmented" else _reduced
    q, lam, it, history = solver(prob, q, fscale, lscale, max_iter)
    solve_seconds = time.perf_counter() - t0

    f = prob.residual(q, lam)
    jqq = prob.jacobian(q, lam)[:prob.nq, :prob.nq].toarray()
    n = _null_space(prob.cq(q), prob.nq)
    kbar = n.T @ (-jqq) @ n
    if np.allclose(kbar, kbar.T, rtol=1e-8, atol=1e-10 * max(1.0, np.max(np.abs(kbar),
                                                                           initial=0.0))):
        eig = np.linalg.eigvalsh(0.5 * (kbar + kbar.T))
    else:  # non-conservative forces: judge by the real parts
        eig = np.sort(np.linalg.eigvals(kbar).real)
    etol = STABILITY_RTOL * max(float(np.max(np.abs(eig), initial=0.0)), 1e-300)
    if eig.size == 0 or np.all(eig > etol):
        stable: bool | None = True
    elif np.any(eig < -etol):
        stable = False
    else:
        stable = None

    system = model.system
    all_joints = list(mech.joints)
    if all_joints:
        zero = np.zeros(prob.nq)
        u0 = np.zeros(len(mech.actuators))
        reactions = np.asarray(model.function("joint_reactions")(
            q, zero, zero, t, u0, model.p, lam)).T
        reactions = flag_undetermined(model, q[None, :], zero[None, :], zero[None, :],
                                      np.array([t]), u0[None, :], np.asarray(lam)[None, :],
                                      reactions[None], steps=[0])[0][0]
    else:
        reactions = np.zeros((0, model.system.reaction_size))
    out = model.outputs(q[None, :], np.zeros((1, prob.nq)), np.zeros((1, prob.nq)),
                        np.array([t]))
    nb = len(system.body_names)
    names = {"coordinates": system.coordinate_names, "bodies": list(system.body_names),
             "joints": list(system.joint_coordinate_names), "all_joints": all_joints}
    stats = dict(model.report_dict)
    stats.update({"solve_seconds": solve_seconds, "n_coordinates": prob.nq,
                  "n_constraints": prob.nc, "degrees_of_freedom": int(n.shape[1])})
    return StaticsResult(
        q=q, lagrange_multipliers=lam, iterations=it, residual=float(np.max(np.abs(f),
                                                                            initial=0.0)),
        residual_history=history, method=method, stable=stable, eigenvalues=eig,
        joint_reactions=reactions, t=t, potential_energy=model.potential_energy(q, t),
        names=names, body_positions=np.reshape(out["body_positions"][0], (nb, system.dimension)),
        body_angles=np.ravel(out["angle_positions"][0]) if system.dimension == 2 else
        np.zeros(0),
        body_quaternions=quaternions_from_matrices(out["rotation_matrices"][0].reshape(nb, 9))
        if system.dimension == 3 else np.zeros((0, 4)),
        joint_coordinates=np.ravel(out["joint_positions"][0]), stats=stats)


def _converged(prob: _Problem, f: np.ndarray, fscale: float, lscale: float) -> bool:
    return (float(np.max(np.abs(f[:prob.nq]), initial=0.0)) <= fscale
            and float(np.max(np.abs(f[prob.nq:]), initial=0.0)) <= lscale)


def _fail(prob: _Problem, why: str, it: int, f: np.ndarray, method: str):
    raise AnalysisError(
        f"no static equilibrium found at t = {prob.t:g} ({method} Newton): {why} after {it} "
        f"iterations, residual max |F| = {np.max(np.abs(f), initial=0.0):.3g}; largest "
        f"residuals: {prob.worst(f)}")


def _descent_step(prob: _Problem, q: np.ndarray, r: np.ndarray) -> np.ndarray | None:
    """A step along the net force in the constraint tangent space, when Newton stalls.

    ‖F‖ can have a stationary point that is not an equilibrium where the stiffness is singular
    (a pendulum released horizontally: ∂(cos θ)/∂θ = 0), and there the Newton step is useless.
    Moving along d = N Nᵀ r, the projected net force, lowers the potential energy (for
    conservative forces); the step is halved until the force still points along d at the new
    configuration (r(q + h d)·d > 0, a bracketing line search on the work), after which Newton
    resumes.  Returns None when no such step exists.
    """
    n = _null_space(prob.cq(q), prob.nq)
    d = n @ (n.T @ r)
    dmax = float(np.max(np.abs(d), initial=0.0))
    if n.shape[1] == 0 or dmax == 0.0 or not np.isfinite(dmax):
        return None
    d /= dmax
    xy = q[prob.length_idx]
    size = max(float(np.ptp(xy)) if xy.size else 0.0, float(np.max(np.abs(xy), initial=0.0)),
               1e-3)
    h = 0.2 * size
    for _ in range(12):
        try:
            qt = assemble(prob.model, q + h * d, prob.t).q
        except AssemblyError:
            qt = None
        if qt is not None:
            rt = prob.residual(qt, prob.multipliers(qt))[:prob.nq]
            if np.all(np.isfinite(rt)) and float(rt @ d) > 0.0:
                return qt
        h *= 0.5
    return None


def _augmented(prob: _Problem, q, fscale, lscale, max_iter):
    nq = prob.nq
    lam = prob.multipliers(q)
    f = prob.residual(q, lam)
    norm = float(np.linalg.norm(f))
    history = [float(np.max(np.abs(f), initial=0.0))]
    it, polished = 0, False
    while True:
        if not np.all(np.isfinite(f)):
            _fail(prob, "non-finite residual", it, np.where(np.isfinite(f), f, np.inf),
                  "augmented")
        done = _converged(prob, f, fscale, lscale)
        if done and (polished or norm == 0.0):
            break
        if it >= max_iter:
            if done:
                break
            _fail(prob, "not converged", it, f, "augmented")
        step = _solve(prob.jacobian(q, lam), -f)
        alpha, accepted = 1.0, False
        for _ in range(30):
            qt, lt = q + alpha * step[:nq], lam + alpha * step[nq:]
            ft = prob.residual(qt, lt)
            nt = float(np.linalg.norm(ft))
            if np.isfinite(nt) and (nt <= norm * (1 - 1e-4 * alpha) or (done and nt <= norm)):
                accepted = True
                break
            alpha *= 0.5
            if done:  # polishing: only a full step is worth trying
                break
        it += 1
        if not accepted:
            if done:
                it -= 1
                break
            qt = _descent_step(prob, q, f[:nq])
            if qt is None:
                _fail(prob, "line search stalled", it, f, "augmented")
            lt = prob.multipliers(qt)
            ft = prob.residual(qt, lt)
            nt = float(np.linalg.norm(ft))
        q, lam, f, norm = qt, lt, ft, nt
        history.append(float(np.max(np.abs(f), initial=0.0)))
        polished = done
    return q, lam, it, history


def _reduced(prob: _Problem, q, fscale, lscale, max_iter):
    nq = prob.nq

    def state(qq):
        lam = prob.multipliers(qq)
        return lam, prob.residual(qq, lam)

    lam, f = state(q)
    norm = float(np.linalg.norm(f[:nq]))
    history = [float(np.max(np.abs(f), initial=0.0))]
    it, polished = 0, False
    while True:
        if not np.all(np.isfinite(f)):
            _fail(prob, "non-finite residual", it, np.where(np.isfinite(f), f, np.inf),
                  "reduced")
        done = _converged(prob, f, fscale, lscale)
        if done and (polished or norm == 0.0):
            break
        if it >= max_iter:
            if done:
                break
            _fail(prob, "not converged", it, f, "reduced")
        n = _null_space(prob.cq(q), nq)
        jqq = prob.jacobian(q, lam)[:nq, :nq].toarray()
        if n.shape[1] == 0:
            dz = np.zeros(0)
        else:
            dz = _solve(sp.csc_matrix(n.T @ jqq @ n), -(n.T @ f[:nq]))
        alpha, accepted = 1.0, False
        for _ in range(30):
            try:
                qt = assemble(prob.model, q + alpha * (n @ dz), prob.t).q
            except AssemblyError:
                qt = None
            if qt is not None:
                lt, ft = state(qt)
                nt = float(np.linalg.norm(ft[:nq]))
                if np.isfinite(nt) and (nt <= norm * (1 - 1e-4 * alpha)
                                        or (done and nt <= norm)):
                    accepted = True
                    break
            alpha *= 0.5
            if done:
                break
        it += 1
        if not accepted:
            if done:
                it -= 1
                break
            qt = _descent_step(prob, q, f[:nq])
            if qt is None:
                _fail(prob, "line search stalled", it, f, "reduced")
            lt, ft = state(qt)
            nt = float(np.linalg.norm(ft[:nq]))
        q, lam, f, norm = qt, lt, ft, nt
        history.append(float(np.max(np.abs(f), initial=0.0)))
        polished = done
    return q, lam, it, history
