"""Linearization about a steady motion: cyclic coordinates removed, eigenvalues of the rest.

A *steady motion* is a motion in which some coordinates grow uniformly (a wheel's spin, the
position on the ground, the heading) while all the others and every velocity stay constant: a
bicycle or a disc rolling straight and upright at speed v (Meijaard, Papadopoulos, Ruina &
Schwab, Proc. R. Soc. A 463 (2007) 1955–1982, §4; Neimark & Fufaev, *Dynamics of Nonholonomic
Systems*, AMS 1972, ch. V).  It is not an equilibrium, so the small-oscillation analysis of
:mod:`casmbd.analysis.statics.linearize` does not apply; and a non-holonomic constraint
A(q) v + b = 0 restricts velocities, not positions, so the configuration space has more
dimensions than the velocity space.

The method (all derivatives by CasADi's algorithmic differentiation, no finite differences):

1. **The ODE.**  x = (q, v); the index-1 form of the constrained equations (seed 000, eq.
   6.138, with the velocity rows of :meth:`casmbd.system.equations.System._velocity_rows`)

       R(x, a, λ) = [M(q) a + C_qᵀ λ − Q(q, v, t, u);  C_q a − γ(q, v, t)] = 0,

   defines ẋ = f(x) = (v, a(x)).  Its Jacobian J = ∂f/∂x at x₀ follows from the implicit
   function theorem: ∂(a, λ)/∂x = −K⁻¹ ∂R/∂x, K = ∂R/∂(a, λ) the KKT matrix.
2. **The constraint manifold.**  The ODE keeps x on {C_h(q) = 0 (holonomic rows),
   C_q v + C_t = 0 (all rows, incl. the non-holonomic ones)}; its tangent space at x₀ is
   ker G, G = [[∂C_h/∂q, 0], [∂(C_q v + C_t)/∂q, C_q]], with the orthonormal basis T from the
   singular value decomposition of G.  J maps ker G into itself (the flow keeps the manifold).
3. **Cyclic coordinates, recognised exactly.**  A coordinate q_k is *cyclic* when the
   equations and the constraints do not depend on it: column k of J and of G is zero (max
   entry ≤ :data:`CYCLIC_RTOL` × the largest entry) at x₀ *and* at a second, randomly perturbed
   state (seeded, so the verdict is reproducible) — position on the plane, wheel spins.  A
   coordinate whose holonomic column is zero but on which the equations depend through the
   velocities of cyclic coordinates — the heading ψ, when x and y are world-frame
   translations: turning the machine by δψ turns the velocity (ẋ, ẏ) with it — is cyclic
   when a tangent vector ξ = e_ψ + Σ c_j e_{v_j} (v_j the velocities of ψ and of the cyclic
   coordinates) exists with J ξ in the span of the cyclic position directions: ξ is the
   generator of the symmetry (for ψ: (δψ, δẏ) = (1, v) going straight along x), found by least
   squares and accepted when its residual is ≤ :data:`CYCLIC_RTOL`.  The family of steady
   motions at other speeds gives one more such vector, ξ = (0, v₀), when J ξ is again in that
   span (a straight steady motion: the accelerations do not change with the speed).
4. **The reduced system.**  S = span{e_c (cyclic), ξ (generators)} ⊂ ker G is invariant under
   J (J S ⊂ span{e_c}) and J is nilpotent on it: those are the zero eigenvalues of the
   symmetry (uniform growth, a turned heading, another speed).  With W an orthonormal basis of
   the complement of S in ker G, the reduced matrix J_r = Wᵀ J W (the map J induces on
   ker G / S) carries the remaining eigenvalues.  For the benchmark bicycle: 9 joint coordinates,
   6 constraint rows, ker G of dimension 10, S of dimension 6 (x, y, two spins, heading,
   speed), J_r 4 × 4 — the weave, capsize and castering eigenvalues of the paper's Table 2.

Steady-motion test.  x₀ is a steady motion when every coordinate that is not cyclic has a rate
|v_k| ≤ :data:`STEADY_RTOL` · max(1, max |v|) and every acceleration |q̈_k| ≤
:data:`STEADY_RTOL` · max(1, |g|); otherwise the analysis refuses, naming the coordinate and its
rate or acceleration.  A coordinate that moves but on which the equations depend is refused
the same way: Euler parameters (absolute coordinates) change with a spin and the mass matrix
depends on them, so a rolling disc described with them has no cyclic spin — the message says to
describe it with joint coordinates (the body on prismatic x, y, z and revolute yaw, lean, pitch
or spin joints, as examples/bicycle.toml does).  A circular steady motion described with
world-frame x, y is periodic, not steady, in those coordinates (the heading rate turns (ẋ, ẏ)):
it is refused by name as well.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

from casmbd.analysis.instant.kkt import accelerations_and_multipliers, consistent_state
from casmbd.analysis.instant.redundancy import RANK_RTOL
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NumericModel
from casmbd.errors import AnalysisError, ModelError, SingularConfigurationError
from casmbd.model.needs import ALL_NEEDS, Handling, check
from casmbd.system.equations import System

#: Functions the steady-motion linearization needs besides its Jacobians
NEEDED = ("mass_matrix", "applied_forces", "quadratic_velocity_forces", "constraints",
          "constraint_jacobian", "constraint_time_derivative", "acceleration_rhs")

#: a column of J or G is zero when its largest entry is at most this times the largest entry
#: of the matrix (and likewise the residual of a symmetry generator)
CYCLIC_RTOL = 1e-9
#: steady-motion test: |v_k| ≤ STEADY_RTOL · max(1, max |v|) for the coordinates that are not
#: cyclic, |q̈_k| ≤ STEADY_RTOL · max(1, |g|) for all
STEADY_RTOL = 1e-8
#: size of the random perturbation of the second state at which cyclic columns are verified
VERIFY_PERTURBATION = 0.1

#: what the steady-motion linearization handles (casmbd.model.needs)
HANDLING = Handling(
    "steady-motion linearization",
    ALL_NEEDS - {"stick_slip", "contact_friction", "reaction_forces", "events"},
    why={"stick_slip": "the exact Coulomb law is not differentiable at the stick-slip switch",
         "contact_friction": "Coulomb friction at a closed contact is not differentiable",
         "reaction_forces": "it does not solve for the multipliers the friction level needs",
         "events": "an impact or a stop switches the equations along the motion"},
    instead={"stick_slip": "the regularised law (stick_slip = false)",
             "contact_friction": "model = 'compliant' with friction",
             "reaction_forces": "simulate with the formulation 'index1'",
             "events": "a compliant contact model, or linearize about an equilibrium"},
    notes={"velocity_constraints": "non-holonomic rows restrict the velocities only",
           "drivers": "a driven coordinate is not cyclic (its driver row depends on it): a "
                      "driver moving it makes the state not steady, refused by name"})


def velocity_row_mask(system: System) -> np.ndarray:
    """True for the rows of C that are velocity (non-holonomic) rows, False for position rows
    (``System.velocity_rows`` where the system lists them, else the rows on which the
    velocity-level expression W is not structurally zero)."""
    listed = getattr(system, "velocity_rows", None)
    if isinstance(listed, (list, tuple)):
        mask = np.zeros(system.nc, dtype=bool)
        mask[list(listed)] = True
        return mask
    rows = system._velocity_rows
    if rows is None:
        return np.zeros(system.nc, dtype=bool)
    return np.array([not ca.SX(rows[i]).is_zero() for i in range(system.nc)], dtype=bool)


def steady_motion_function(system: System) -> ca.Function:
    """The Jacobians of the index-1 residual R and of the constraint rows (module docstring).

    Outputs ``dRdq``, ``dRdv``, ``K`` (= ∂R/∂(a, λ)), ``Cq`` (C_q), ``dCdq`` (∂C/∂q, zero on
    velocity rows) and ``dWdq`` (∂(C_q v + C_t)/∂q).
    """
    nq, nc = system.nq, system.nc
    acc = ca.SX.sym("a", nq)
    lam = ca.SX.sym("lambda", nc)
    q, v = system.q, system.v
    force = system.applied_forces + system.quadratic_velocity_forces
    dyn = ca.mtimes(system.mass_matrix, acc) - force
    cq = system.constraint_jacobian if nc else ca.SX(0, nq)
    if nc:
        dyn += ca.mtimes(cq.T, lam)
        resid = ca.vertcat(dyn, ca.mtimes(cq, acc) - system.acceleration_rhs)
        cdot = ca.mtimes(cq, v) + system.constraint_time_derivative
        dcdq = ca.jacobian(system.constraints, q)
        dwdq = ca.jacobian(cdot, q)
    else:
        resid = dyn
        dcdq = dwdq = ca.SX(0, nq)
    z = ca.vertcat(acc, lam)
    outs = [ca.jacobian(resid, q), ca.jacobian(resid, v), ca.jacobian(resid, z), cq, dcdq, dwdq]
    return ca.Function("steady_motion_jacobians",
                       [q, v, system.t, system.u, system.p, acc, lam],
                       [ca.densify(o) for o in outs],
                       ["q", "v", "t", "u", "p", "a", "lambda"],
                       ["dRdq", "dRdv", "K", "Cq", "dCdq", "dWdq"])


@dataclass
class SteadyMotionModel:
    """The linearization about a steady motion (module docstring).

    Attributes
    ----------
    eigenvalues : ndarray of complex
        Eigenvalues of the reduced matrix J_r, sorted by real part then imaginary part.
    J : ndarray
        The reduced matrix J_r = Wᵀ J W.
    W : ndarray
        Orthonormal basis (2 n_q × n_r) of the reduced state space in x = (q, v).
    jacobian : ndarray
        The full Jacobian J = ∂f/∂x of the index-1 ODE at x₀.
    cyclic : list of str
        The coordinates whose columns of J and G vanish (uniform growth).
    symmetries : list of str
        The other removed directions: heading-like coordinates (with their generator), and
        ``"speed"`` for the family of steady motions at other speeds.
    remaining : list of str
        The coordinates that are not cyclic (they name the modes).
    modes : list of dict
        Per eigenvalue: ``eigenvalue`` [re, im], ``coordinate`` (the remaining coordinate
        whose position or velocity takes the largest share of the eigenvector) and
        ``participation`` (name -> share, summing to 1).
    q, v, a : the (consistent) state and its accelerations.
    coordinate_names : names of the generalized coordinates.
    stats : dict
    """

    eigenvalues: np.ndarray
    J: np.ndarray
    W: np.ndarray
    jacobian: np.ndarray
    cyclic: list[str]
    symmetries: list[str]
    remaining: list[str]
    modes: list[dict]
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    coordinate_names: list[str]
    stats: dict = field(default_factory=dict)

    @property
    def stable(self) -> bool:
        """No eigenvalue with a positive real part beyond 1e-9 · max(1, |s|max)."""
        if self.eigenvalues.size == 0:
            return True
        scale = max(1.0, float(np.max(np.abs(self.eigenvalues))))
        return bool(np.max(self.eigenvalues.real) <= 1e-9 * scale)

    def to_json(self) -> dict:
        """Plain-Python dictionary for JSON output (``eigenvalues`` as [re, im] pairs)."""
        return {
            "steady_motion": True,
            "eigenvalues": [[float(e.real), float(e.imag)] for e in self.eigenvalues],
            "stable": self.stable,
            "cyclic_coordinates": list(self.cyclic),
            "symmetries": list(self.symmetries),
            "remaining_coordinates": list(self.remaining),
            "modes": self.modes,
            "q": self.q.tolist(), "v": self.v.tolist(),
            "coordinate_names": list(self.coordinate_names),
            "stats": {k: (float(v) if isinstance(v, (np.floating, float)) else v)
                      for k, v in self.stats.items()},
        }


def _system_of(mechanism) -> System:
    if isinstance(mechanism, NumericModel):
        return mechanism.system
    if isinstance(mechanism, System):
        return mechanism
    return System(mechanism)


class _Jacobians:
    """J and G at one state, from the compiled Jacobians of R."""

    def __init__(self, model: NumericModel, holonomic: np.ndarray, q, v, t: float, u):
        nq = model.nq
        acc, lam = accelerations_and_multipliers(model, q, v, t, u)
        outs = model.function("steady_motion_jacobians")(q, v, t, u, model.p, acc, lam)
        d_rq, d_rv, kkt, cq, dcdq, dwdq = (np.asarray(o.full(), dtype=float) for o in outs)
        try:
            dz = -np.linalg.solve(kkt, np.hstack([d_rq, d_rv]))
        except np.linalg.LinAlgError:
            raise SingularConfigurationError(
                f"steady-motion linearization: the KKT matrix is singular at t = {t:g} "
                "(redundant constraint equations or a massless direction)") from None
        self.a = acc
        self.J = np.block([[np.zeros((nq, nq)), np.eye(nq)], [dz[:nq]]])
        rows = [np.hstack([dcdq[holonomic], np.zeros((int(holonomic.sum()), nq))])]
        if model.nc:
            rows.append(np.hstack([dwdq, cq]))
        self.G = np.vstack(rows) if rows else np.zeros((0, 2 * nq))


def _second_state(model: NumericModel, holonomic, qs, vs, t: float, u) -> _Jacobians:
    """J and G at a randomly perturbed state (fixed seed: the verdict is reproducible), where
    the cyclic columns are verified; a smaller perturbation where the KKT matrix is singular
    at the first one."""
    rng = np.random.default_rng(20070908)
    dq, dv = rng.standard_normal(qs.size), rng.standard_normal(vs.size)
    vscale = max(1.0, float(np.max(np.abs(vs), initial=0.0)))
    for size in (VERIFY_PERTURBATION, VERIFY_PERTURBATION / 10, VERIFY_PERTURBATION / 100):
        try:
            return _Jacobians(model, holonomic, qs + size * dq, vs + size * vscale * dv, t, u)
        except (SingularConfigurationError, np.linalg.LinAlgError):
            continue
    raise SingularConfigurationError(
        "steady-motion linearization: the KKT matrix is singular at every perturbed state "
        "tried for the verification of the cyclic coordinates (perturbations "
        f"{VERIFY_PERTURBATION:g}, {VERIFY_PERTURBATION / 10:g}, {VERIFY_PERTURBATION / 100:g})")


def _zero(column: np.ndarray, scale: float) -> bool:
    return float(np.max(np.abs(column), initial=0.0)) <= CYCLIC_RTOL * scale


def _abelian_cyclic(jac: _Jacobians, jac2: _Jacobians, nq: int) -> list[int]:
    """Coordinates whose columns of J and G vanish at both states."""
    found = []
    for k in range(nq):
        ok = True
        for jj in (jac, jac2):
            sj = max(1.0, float(np.max(np.abs(jj.J))))
            sg = max(1.0, float(np.max(np.abs(jj.G), initial=0.0)))
            if not (_zero(jj.J[:, k], sj) and _zero(jj.G[:, k], sg)):
                ok = False
        if ok:
            found.append(k)
    return found


def _generator(jac: _Jacobians, nq: int, cyclic: list[int], base: np.ndarray,
               free_velocities: list[int]) -> np.ndarray | None:
    """ξ = base + Σ c_j e_{v_j} (j in ``free_velocities``) in ker G with J ξ in the span of the
    cyclic position directions, or None (least squares, residual ≤ CYCLIC_RTOL)."""
    rows = np.setdiff1d(np.arange(2 * nq), cyclic)
    cols = [nq + j for j in free_velocities]
    lhs = np.vstack([jac.G[:, cols], jac.J[rows][:, cols]])
    rhs = -np.concatenate([jac.G @ base, jac.J[rows] @ base])
    scale = max(1.0, float(np.max(np.abs(jac.J))), float(np.max(np.abs(jac.G), initial=0.0)))
    coef = np.linalg.lstsq(lhs, rhs, rcond=None)[0] if cols else np.zeros(0)
    if float(np.max(np.abs(lhs @ coef - rhs), initial=0.0)) > CYCLIC_RTOL * scale * max(
            1.0, float(np.max(np.abs(base)))):
        return None
    xi = base.copy()
    xi[cols] += coef
    return xi


def _rate_family(jac: _Jacobians, nq: int, cyclic: list[int], coords: list[int]
                 ) -> list[np.ndarray]:
    """Velocity directions ξ = (0, δv), δv on the rates of ``coords`` only, in ker G with
    J ξ in the span of the cyclic position directions: the neighbouring steady motions at
    other rates of the cyclic coordinates (the forward speed of a rolling wheel or bicycle).
    The null space of the stacked rows, rank tolerance CYCLIC_RTOL."""
    if not coords:
        return []
    rows = np.setdiff1d(np.arange(2 * nq), cyclic)
    cols = [nq + j for j in coords]
    stacked = np.vstack([jac.G[:, cols], jac.J[rows][:, cols]])
    scale = max(1.0, float(np.max(np.abs(jac.J))), float(np.max(np.abs(jac.G), initial=0.0)))
    _, sv, vt = np.linalg.svd(stacked)
    rank = int(np.sum(sv > CYCLIC_RTOL * scale))
    family = []
    for y in vt[rank:]:
        xi = np.zeros(2 * nq)
        xi[cols] = y
        family.append(xi)
    return family


def _null_basis(matrix: np.ndarray, n: int, rtol: float) -> np.ndarray:
    if matrix.shape[0] == 0:
        return np.eye(n)
    _, s, vt = np.linalg.svd(matrix)
    rank = int(np.sum(s > rtol * max(1.0, s[0]))) if s.size else 0
    return vt[rank:].T


def _euler_hint(names: list[str], moving: list[str]) -> str:
    bodies = sorted({n.rsplit(".", 1)[0] for n in moving if re.search(r"\.e[0-3]$", n)})
    if not bodies:
        return ""
    return (f"; the Euler parameters of {', '.join(repr(b) for b in bodies)} change with the "
            "rotation and the mass matrix depends on them, so no rotation they describe can "
            "be a cyclic coordinate: describe the rotations with revolute joints in joint "
            "coordinates (coordinates = \"joint\"), a free body hung on prismatic x, y, z "
            "and revolute yaw, lean and spin (or pitch) joints on massless links, as "
            "examples/bicycle.toml does")


class SteadyMotion:
    """The steady-motion linearization of one mechanism, compiled once and evaluated at many
    states or parameter values (a sweep over the forward speed: root loci, critical speeds).

    ``SteadyMotion(m)(v=s * v1)`` linearizes about the steady motion with the velocities
    ``s * v1`` (straight rolling at speed s, v1 the velocities at 1 m/s);
    ``SteadyMotion(m)({"k": 2.0})`` sets the parameter ``k`` (masses, forces: the scene's
    initial velocities are numbers fixed when it is read); ``linearize_steady_motion(m)`` is
    ``SteadyMotion(m)()``.
    """

    def __init__(self, mechanism, mode: str = "auto", rtol: float = RANK_RTOL):
        t0 = time.perf_counter()
        self.system = system = _system_of(mechanism)
        check(system.mechanism, HANDLING)
        self.model = compile_model(system, NEEDED, mode=mode,
                                   extra=[steady_motion_function(system)])
        if isinstance(mechanism, NumericModel):
            self.model.p[:] = mechanism.p
        self.holonomic = ~velocity_row_mask(system)
        self.rtol = rtol
        self.build_seconds = time.perf_counter() - t0

    def __call__(self, parameters: dict | None = None, *, q=None, v=None, t: float = 0.0,
                 u=None) -> SteadyMotionModel:
        """Linearize about the steady motion from (q, v) (default: the initial state) at the
        given parameter values (name -> value); see :func:`linearize_steady_motion`."""
        self.model.set_parameters(**(parameters or {}))
        return _linearize(self, q, v, float(t), u)


def linearize_steady_motion(mechanism, q=None, v=None, t: float = 0.0, u=None,
                            mode: str = "auto", rtol: float = RANK_RTOL
                            ) -> SteadyMotionModel:
    """Linearize about the steady motion that starts at (q, v) (default: the scene's initial
    state, assembled and projected onto the constraints) — module docstring.

    Parameters
    ----------
    mechanism : Mechanism, System or NumericModel
    q, v : array, optional
        The state; made consistent (assembly of the positions, mass-orthogonal projection of
        the velocities) before use.  Default: the scene's initial coordinates and velocities.
    t : float
    u : array, optional
        Actuator inputs (default zero).
    mode : {"auto", "compiled", "vm"}
    rtol : float
        Relative rank tolerance of G (the tangent space).

    Returns
    -------
    SteadyMotionModel

    Raises
    ------
    AnalysisError
        The state is not a steady motion (the coordinate and its rate or acceleration named;
        with Euler parameters, which coordinates to use instead).
    SingularConfigurationError
        A singular KKT matrix.
    """
    return SteadyMotion(mechanism, mode, rtol)(q=q, v=v, t=t, u=u)


def _linearize(lin: SteadyMotion, q, v, t: float, u) -> SteadyMotionModel:
    t0 = time.perf_counter()
    system, model, holonomic, rtol = lin.system, lin.model, lin.holonomic, lin.rtol
    nq = model.nq
    names = list(system.coordinate_names)
    q0 = system.initial_coordinates() if q is None else np.asarray(q, float).reshape(-1)
    v0 = system.initial_velocities(model.p) if v is None else np.asarray(v, float).reshape(-1)
    nu = len(system.mechanism.actuators)
    u = np.zeros(nu) if u is None else np.asarray(u, float).reshape(-1)
    for label, arr, size in (("q", q0, nq), ("v", v0, nq), ("u", u, nu)):
        if arr.shape != (size,) or not np.all(np.isfinite(arr)):
            raise ModelError(f"steady-motion linearization: {label} must be {size} finite "
                             f"numbers")
    state = consistent_state(model, q0, v0, t, u)
    qs, vs = state.q, state.v
    jac = _Jacobians(model, holonomic, qs, vs, t, u)
    jac2 = _second_state(model, holonomic, qs, vs, t, u)

    cyclic = _abelian_cyclic(jac, jac2, nq)
    basis_s = [np.eye(2 * nq)[:, k] for k in cyclic]
    symmetries: list[str] = []
    hol_g = jac.G[:int(holonomic.sum()), :nq]
    g_scale = max(1.0, float(np.max(np.abs(jac.G), initial=0.0)))
    generator_coords = []
    for k in range(nq):
        if k in cyclic or not _zero(hol_g[:, k], g_scale):
            continue
        base = np.zeros(2 * nq)
        base[k] = 1.0
        xi = _generator(jac, nq, cyclic, base, sorted(set(cyclic) | {k}))
        if xi is not None:
            basis_s.append(xi)
            generator_coords.append(k)
            symmetries.append(names[k])
    for xi in _rate_family(jac, nq, cyclic, sorted(set(cyclic) | set(generator_coords))):
        basis_s.append(xi)
        symmetries.append("speed")

    # steady-motion test (module docstring)
    removed = set(cyclic) | set(generator_coords)
    v_tol = STEADY_RTOL * max(1.0, float(np.max(np.abs(vs), initial=0.0)))
    g = float(np.linalg.norm(getattr(system.mechanism, "gravity", np.zeros(3))))
    a_tol = STEADY_RTOL * max(1.0, g)
    problems = [f"coordinate '{names[k]}' moves (rate {vs[k]:.6g}) but is not cyclic"
                for k in range(nq) if k not in removed and abs(vs[k]) > v_tol]
    problems += [f"coordinate '{names[k]}' accelerates ({jac.a[k]:.6g})"
                 for k in range(nq) if abs(jac.a[k]) > a_tol]
    if problems:
        moving = [names[k] for k in range(nq) if k not in removed and abs(vs[k]) > v_tol]
        raise AnalysisError(
            f"steady-motion linearization: the initial state is not a steady motion in these "
            f"coordinates: {'; '.join(problems[:4])}"
            f"{' (and more)' if len(problems) > 4 else ''} (tolerances: rates {v_tol:.3g}, "
            f"accelerations {a_tol:.3g}; cyclic: {', '.join(names[k] for k in cyclic) or 'none'})"
            f"{_euler_hint(names, moving)}")

    tangent = _null_basis(jac.G, 2 * nq, rtol)
    if basis_s:
        stacked = np.column_stack(basis_s)
        u_s, s_s, _ = np.linalg.svd(stacked, full_matrices=False)
        s_basis = u_s[:, s_s > 1e-10 * s_s[0]]
        comp = sla.null_space((tangent.T @ s_basis).T, rcond=1e-10)
        w = tangent @ comp
    else:
        s_basis = np.zeros((2 * nq, 0))
        w = tangent
    j_red = w.T @ jac.J @ w
    # invariance checks: J S ⊂ S and J W ⊂ ker G (both exact up to round-off)
    leak = float(np.max(np.abs(w.T @ jac.J @ s_basis), initial=0.0))
    eig, vecs = np.linalg.eig(j_red) if j_red.size else (np.zeros(0, complex),
                                                         np.zeros((0, 0)))
    order = np.lexsort((eig.imag, eig.real))
    eig, vecs = eig[order], vecs[:, order]
    remaining = [names[k] for k in range(nq) if k not in removed]
    keep = [k for k in range(nq) if k not in removed]
    modes = []
    for i, s in enumerate(eig):
        x = w @ vecs[:, i]
        share = np.abs(x[keep]) + np.abs(x[[nq + k for k in keep]]) / max(1.0, abs(s))
        share = share / max(float(share.sum()), 1e-300)
        part = {remaining[j]: float(share[j]) for j in np.argsort(-share) if share[j] > 1e-3}
        modes.append({"eigenvalue": [float(s.real), float(s.imag)],
                      "coordinate": remaining[int(np.argmax(share))] if keep else None,
                      "participation": part})
    stats = {"n_coordinates": nq, "n_constraints": model.nc,
             "n_velocity_rows": int((~holonomic).sum()), "tangent_dimension": tangent.shape[1],
             "removed_dimension": s_basis.shape[1], "reduced_dimension": w.shape[1],
             "invariance_residual": leak,
             "max_rate_not_cyclic": float(max((abs(vs[k]) for k in keep), default=0.0)),
             "max_acceleration": float(np.max(np.abs(jac.a), initial=0.0)),
             "position_change": state.position_change, "velocity_change": state.velocity_change,
             "build_seconds": lin.build_seconds, "solve_seconds": time.perf_counter() - t0,
             **{k: val for k, val in model.report_dict.items() if k != "build_seconds"}}
    return SteadyMotionModel(eig, j_red, w, jac.J, [names[k] for k in cyclic], symmetries,
                             remaining, modes, qs, vs, jac.a, names, stats)


def root_locus(lin: SteadyMotion, values, state=None, parameter: str | None = None
               ) -> np.ndarray:
    """Eigenvalues of the reduced system at each of ``values`` (a root locus), one row per
    value (padded with NaN when the reduced dimension changes).

    ``state(value) -> (q, v)`` gives the steady motion at a value (for a bicycle or a disc
    rolling straight the velocities scale with the speed: ``lambda s: (None, s * v1)``);
    ``parameter`` names a scene parameter set to the value instead (the initial velocities of
    a scene are evaluated when it is loaded, so a speed parameter needs ``state``).
    """
    rows = []
    for value in values:
        q, v = state(float(value)) if state is not None else (None, None)
        pars = {parameter: float(value)} if parameter else None
        rows.append(lin(pars, q=q, v=v).eigenvalues)
    width = max((len(r) for r in rows), default=0)
    out = np.full((len(rows), width), np.nan, dtype=complex)
    for k, r in enumerate(rows):
        out[k, :len(r)] = r
    return out


def parameter_root(evaluate, lo: float, hi: float, measure, xtol: float = 1e-13) -> float:
    """The value in [lo, hi] at which ``measure(evaluate(value))`` is zero — Brent's method
    (scipy.optimize.brentq) on the exact linearization at each value.  ``evaluate(value)``
    returns the eigenvalues of the reduced system (e.g. ``lambda s: lin(q=None, v=s *
    v1).eigenvalues``), ``measure`` a real function of them that changes sign on the
    bracket: a critical speed (the weave speed, where the real part of the oscillatory pair
    vanishes; the capsize speed, where the real capsize eigenvalue does).

    Raises
    ------
    AnalysisError
        If ``measure`` has the same sign at both ends of the bracket (both values named).
    """
    def at(value: float) -> float:
        return float(measure(evaluate(value)))

    f_lo, f_hi = at(lo), at(hi)
    if not np.sign(f_lo) * np.sign(f_hi) < 0:
        raise AnalysisError(f"steady-motion root: the measure has the same sign at "
                            f"{lo:g} ({f_lo:.3g}) and {hi:g} ({f_hi:.3g})")
    return float(brentq(at, lo, hi, xtol=xtol, rtol=4 * np.finfo(float).eps, maxiter=200))
