"""Linearized equations of motion about one state, in independent coordinates.

Seed 000 (embedding, independent coordinates) and seed 003, section 4 (curvature and local
stability).  At the configuration q the admissible position changes span the null space of the
constraint Jacobian: δq = N δz to first order, with N an orthonormal basis of ker C_q taken from
the singular value decomposition of C_q (rank tolerance relative to the largest singular value,
as in :mod:`casmbd.analysis.redundancy`).  Projecting the linearized augmented equations

    M q̈ + C_qᵀ λ = Q_e(q, v, t, u) + Q_v(q, v)

onto the tangent space (Nᵀ C_qᵀ = 0 removes δλ) gives

    M̄ δz̈ + C̄ δż + K̄ δz = B̄ δu,

    M̄ = Nᵀ M N,
    C̄ = −Nᵀ ∂(Q_e + Q_v)/∂v N,
    K̄ = −Nᵀ ∂(Q_e + Q_v − C_qᵀ λ − M a)/∂q N,
    B̄ = Nᵀ ∂Q_e/∂u,

with λ and a = q̈ the multipliers and accelerations of the KKT system at that state.  The term
∂(C_qᵀ λ)/∂q is the geometric stiffness of the constraint forces (the curvature of the constraint
manifold weighted by the reactions, seed 003 section 4): it is what makes a hanging pendulum stable
and an inverted one unstable.  Every derivative comes from CasADi's algorithmic differentiation.

At an equilibrium (v = 0, a = 0) the ``M a`` and ``Q_v`` terms vanish and these are the
classical small-oscillation matrices.  About a state that is *not* an equilibrium the matrices are
still the first-order expansion of the projected equations about that state (with the basis N
frozen at q); the eigenvalues then describe the local behaviour of the perturbation equations
only, not oscillations about a rest position.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla

from casmbd.analysis.assembly import assemble
from casmbd.analysis.checks import check_start
from casmbd.analysis.kkt import accelerations_and_multipliers
from casmbd.analysis.redundancy import RANK_RTOL, null_space_basis
from casmbd.compiled.model import NumericModel
from casmbd.errors import AnalysisError, ModelError, SingularConfigurationError
from casmbd.system.equations import System

#: Functions the linearization needs besides its own Jacobians (assembly and the KKT system)
NEEDED = ("mass_matrix", "applied_forces", "quadratic_velocity_forces", "constraints",
          "constraint_jacobian", "constraint_time_derivative", "acceleration_rhs")

#: |Im s| below this times max(1, |s|max) counts as a real eigenvalue
IMAG_RTOL = 1e-9


def _linearization_function(system: System) -> ca.Function:
    """Jacobians of the dynamics residual at (q, v, t, u, p, λ, a)."""
    lam = ca.SX.sym("lambda", system.nc)
    acc = ca.SX.sym("a", system.nq)
    q, v, u = system.q, system.v, system.u
    force = system.applied_forces + system.quadratic_velocity_forces
    # residual of M a + C_qᵀ λ = Q_e + Q_v, written as a generalized force
    resid = force - ca.mtimes(system.mass_matrix, acc)
    if system.nc:
        resid -= ca.mtimes(system.constraint_jacobian.T, lam)
    return ca.Function(
        "linearization",
        [q, v, system.t, u, system.p, lam, acc],
        [ca.densify(ca.jacobian(resid, q)), ca.densify(ca.jacobian(force, v)),
         ca.densify(ca.jacobian(system.applied_forces, u))],
        ["q", "v", "t", "u", "p", "lambda", "a"], ["dRdq", "dFdv", "dQdu"])


@dataclass
class LinearModel:
    """Linearized dynamics M̄ z̈ + C̄ ż + K̄ z = B̄ u in independent coordinates z (δq = N z).

    Attributes
    ----------
    M, C, K, B : ndarray
        Reduced mass, damping, stiffness (n_z × n_z) and input (n_z × n_u) matrices.
    A, Bss : ndarray
        State space ẋ = A x + Bss u with x = (z, ż).
    N : ndarray
        Orthonormal null-space basis of C_q at q (n_q × n_z); column k is the coordinate
        direction of z_k.
    eigenvalues : ndarray of complex
        Eigenvalues s of A (all 2 n_z of them), sorted by imaginary part then real part.
    frequencies_hz, damping_ratios : ndarray
        One entry per mode: f = |Im s| / 2π and ζ = −Re s / |s|.  Without damping
        (C̄ = 0) the n_z modes come from the generalized eigenproblem K̄ φ = ω² M̄ φ: f = ω / 2π
        and ζ = 0, or for ω² < 0 (unstable) f = 0 and ζ = −1.  With damping, every complex pair
        of eigenvalues of A is one mode; the real eigenvalues (overdamped or divergent motion)
        are sorted and paired (smallest with largest, ...) into modes with f = 0,
        ω_n = sqrt|s₁ s₂| and ζ = −(s₁ + s₂) / (2 ω_n) when s₁ s₂ > 0 (ζ > 1: overdamped),
        ζ = −1 when s₁ s₂ < 0 (a saddle: unstable) and ζ = 0 when s₁ s₂ = 0 (a rigid-body
        mode).  This pairing is exact for one degree of freedom and a convention otherwise:
        ``eigenvalues`` is the complete answer.  n_z modes in all, sorted by frequency.
    natural_frequencies_hz : ndarray
        |s| / 2π of the same modes (the undamped natural frequency ω_n / 2π of a damped mode).
    q, v, t, u : the state of the linearization.
    lam : multipliers λ of the KKT system at that state.
    coordinate_names : names of the absolute coordinates (rows of N).
    stats : dict
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    B: np.ndarray
    A: np.ndarray
    Bss: np.ndarray
    N: np.ndarray
    eigenvalues: np.ndarray
    frequencies_hz: np.ndarray
    damping_ratios: np.ndarray
    natural_frequencies_hz: np.ndarray
    q: np.ndarray
    v: np.ndarray
    t: float
    u: np.ndarray
    lam: np.ndarray
    coordinate_names: list[str]
    actuator_names: list[str]
    stats: dict = field(default_factory=dict)

    @property
    def n_dof(self) -> int:
        """Number of independent coordinates n_z."""
        return self.N.shape[1]

    @property
    def stable(self) -> bool:
        """True when no eigenvalue of A has a positive real part (beyond round-off)."""
        if self.eigenvalues.size == 0:
            return True
        scale = max(1.0, float(np.max(np.abs(self.eigenvalues))))
        return bool(np.max(self.eigenvalues.real) <= 1e-9 * scale)

    def to_json(self) -> dict:
        """Plain-Python dictionary for JSON output."""
        return {
            "frequencies_hz": self.frequencies_hz.tolist(),
            "damping_ratios": self.damping_ratios.tolist(),
            "natural_frequencies_hz": self.natural_frequencies_hz.tolist(),
            "eigenvalues": [[float(s.real), float(s.imag)] for s in self.eigenvalues],
            "stable": self.stable,
            "M": self.M.tolist(), "C": self.C.tolist(), "K": self.K.tolist(),
            "B": self.B.tolist(), "A": self.A.tolist(), "B_state": self.Bss.tolist(),
            "N": self.N.tolist(),
            "coordinates": list(self.coordinate_names),
            "actuators": list(self.actuator_names),
            "q": self.q.tolist(), "v": self.v.tolist(), "t": self.t,
            "stats": dict(self.stats),
        }


def _modes(m_bar, c_bar, k_bar, a_mat) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray]:
    """Eigenvalues of A and (f, ζ, f_n) of the modes; see :class:`LinearModel`."""
    n = m_bar.shape[0]
    if n == 0:
        empty = np.zeros(0)
        return np.zeros(0, complex), empty, empty, empty
    undamped = not np.any(c_bar)
    if undamped:
        w2 = sla.eigvals(k_bar, m_bar)
        if np.all(np.isfinite(w2)) and np.all(np.abs(w2.imag) <= IMAG_RTOL * max(
                1.0, float(np.max(np.abs(w2))))):
            w2 = np.sort(w2.real)
            omega = np.sqrt(np.abs(w2))
            freq = np.where(w2 > 0, omega, 0.0) / (2 * np.pi)
            zeta = np.where(w2 < 0, -1.0, 0.0)
            eig = np.concatenate([np.where(w2 >= 0, 1j * omega, omega),
                                  np.where(w2 >= 0, -1j * omega, -omega)])
            order = np.lexsort((eig.real, eig.imag))
            return eig[order], freq, zeta, omega / (2 * np.pi)
    eig = sla.eigvals(a_mat)
    order = np.lexsort((eig.real, eig.imag))
    eig = eig[order]
    smax = max(1.0, float(np.max(np.abs(eig))))
    tol = IMAG_RTOL * smax
    pairs = [s for s in eig if s.imag > tol]
    freq = [s.imag for s in pairs]
    mag = [abs(s) for s in pairs]
    zeta = [-s.real / abs(s) for s in pairs]
    real = np.sort([s.real for s in eig if abs(s.imag) <= tol])
    for i in range(len(real) // 2):  # nested pairing: (smallest, largest), ...
        s1, s2 = real[i], real[len(real) - 1 - i]
        prod, total = s1 * s2, s1 + s2
        if abs(s1) <= tol and abs(s2) <= tol:
            prod = 0.0  # a rigid-body pair whose zero eigenvalues round-off split to ±ε
        freq.append(0.0)
        mag.append(math.sqrt(abs(prod)))
        if prod > 0:  # overdamped (ζ > 1) or, with both roots positive, divergent (ζ < −1)
            zeta.append(-total / (2 * math.sqrt(prod)))
        else:  # saddle (ζ = −1, as for an undamped unstable mode) or rigid-body mode (ζ = 0)
            zeta.append(-1.0 if prod < 0 else 0.0)
    freq, mag, zeta = (np.array(x, dtype=float) for x in (freq, mag, zeta))
    freq /= 2 * np.pi
    order = np.argsort(freq, kind="stable")
    return eig, freq[order], zeta[order], mag[order] / (2 * np.pi)


def linearize(mechanism, q=None, v=None, t: float = 0.0, u=None, mode: str = "auto",
              rtol: float = RANK_RTOL) -> LinearModel:
    """Linearize the constrained dynamics of ``mechanism`` about the state (q, v, t, u).

    Parameters
    ----------
    mechanism : Mechanism, System or NumericModel
        A NumericModel is reused only for its System (the linearization compiles its own
        Functions, cached on disk like every model).
    q : array, optional
        Configuration; default the assembled initial configuration.  Pass an equilibrium (e.g.
        from a statics analysis) for small oscillations: q is used as given (it is not moved
        onto the constraints, only checked); the linearization about any other state is the
        first-order expansion about that state (see the module docstring).
    v : array, optional
        Velocities (default zero).
    t : float
        Time (for time-dependent forces and rheonomic drivers).
    u : array, optional
        Actuator inputs (default zero).
    mode : {"auto", "compiled", "vm"}
    rtol : float
        Relative rank tolerance of the constraint Jacobian.

    Returns
    -------
    LinearModel

    Raises
    ------
    AnalysisError
        If q violates the constraints or the reduced mass matrix is singular.
    """
    t0 = time.perf_counter()
    if isinstance(mechanism, NumericModel):
        system = mechanism.system
    elif isinstance(mechanism, System):
        system = mechanism
    else:
        system = System(mechanism)
    lin_fun = _linearization_function(system)
    model = NumericModel(system, NEEDED, mode=mode, extra=[lin_fun])
    if isinstance(mechanism, NumericModel):
        model.p[:] = mechanism.p
    t_build = time.perf_counter() - t0
    t1 = time.perf_counter()
    nq = model.nq
    t = float(t)
    if q is None:
        q = assemble(model, system.initial_coordinates(), t).q
    q = np.array(q, dtype=float).reshape(-1)
    v = np.zeros(nq) if v is None else np.array(v, dtype=float).reshape(-1)
    nu = len(system.mechanism.actuators)
    u = np.zeros(nu) if u is None else np.array(u, dtype=float).reshape(-1)
    for name, arr, size in (("q", q, nq), ("v", v, nq), ("u", u, nu)):
        if arr.shape != (size,):
            raise ModelError(f"linearize: {name} must have {size} entries, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise ModelError(f"linearize: {name} is not finite")
    check_start(model, q, v, t, u, what="linearization")  # names a NaN's culprit
    if model.nc:
        c = model.constraints(q, t)
        lengths = system.length_indices
        tol = 1e-8 * max(1.0, float(np.max(np.abs(q[lengths]), initial=0.0)))
        if not np.all(np.isfinite(c)) or float(np.max(np.abs(c))) > tol:
            raise AnalysisError(f"linearize: q violates the constraints at t = {t:g} (max |C| = "
                                f"{float(np.max(np.abs(c))):.3g}); assemble it first")
        basis, rank = null_space_basis(model.constraint_jacobian(q, t), rtol)
    else:
        basis, rank = np.eye(nq), 0
    acc, lam = accelerations_and_multipliers(model, q, v, t, u)
    outs = model.function("linearization")(q, v, t, u, model.p, lam, acc)
    d_resid_dq, d_force_dv, d_force_du = (np.asarray(o.full(), dtype=float) for o in outs)
    m_full = model.mass_matrix(q).toarray()
    m_bar = basis.T @ m_full @ basis
    c_bar = -basis.T @ d_force_dv @ basis
    k_bar = -basis.T @ d_resid_dq @ basis
    b_bar = basis.T @ d_force_du.reshape(nq, nu)
    nz = basis.shape[1]
    try:
        minv_k = np.linalg.solve(m_bar, k_bar) if nz else np.zeros((0, 0))
        minv_c = np.linalg.solve(m_bar, c_bar) if nz else np.zeros((0, 0))
        minv_b = np.linalg.solve(m_bar, b_bar) if nz else np.zeros((0, nu))
    except np.linalg.LinAlgError:
        raise SingularConfigurationError(
            f"linearize: the reduced mass matrix is singular at t = {t:g}") from None
    a_mat = np.block([[np.zeros((nz, nz)), np.eye(nz)], [-minv_k, -minv_c]])
    b_ss = np.vstack([np.zeros((nz, nu)), minv_b])
    eig, freq, zeta, fn = _modes(m_bar, c_bar, k_bar, a_mat)
    stats = {"n_coordinates": nq, "n_constraints": model.nc, "rank": rank,
             "degrees_of_freedom": nz, "n_inputs": nu,
             "acceleration_norm": float(np.linalg.norm(acc)),
             "velocity_norm": float(np.linalg.norm(v)),
             "build_seconds": t_build, "solve_seconds": time.perf_counter() - t1,
             **{k: val for k, val in model.report_dict.items() if k != "build_seconds"}}
    stats["equilibrium"] = bool(stats["velocity_norm"] == 0.0 and np.linalg.norm(
        basis.T @ (m_full @ acc)) <= 1e-9 * max(1.0, float(np.max(np.abs(m_full)))))
    return LinearModel(m_bar, c_bar, k_bar, b_bar, a_mat, b_ss, basis, eig, freq, zeta, fn,
                       q, v, t, u, lam, list(system.coordinate_names),
                       list(system.mechanism.actuators), stats)
