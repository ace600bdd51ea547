"""Linearized equations of motion about one state, in independent coordinates.

Seed 000 (embedding, independent coordinates) and seed 003, section 4 (curvature and local
stability).  At the configuration q the admissible position changes span the null space of the
constraint Jacobian: δq = N δz to first order, with N an orthonormal basis of ker C_q taken from
the singular value decomposition of C_q (rank tolerance relative to the largest singular value,
as in :mod:`casmbd.analysis.instant.redundancy`).  Projecting the linearized augmented equations

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

Where.  ``linearize(m)`` expands about the assembled initial configuration at rest,
``linearize(m, q=..., v=...)`` about a given state, ``linearize(m, at="equilibrium")`` about
the static equilibrium that :func:`casmbd.analysis.statics.statics.static_equilibrium` finds from
the initial configuration (at time t, inputs zero), and ``linearize(m, at=result, at_time=T)``
about the state (q, v, and the stored actuator inputs) a result holds at its output time
*nearest* T.  Nearest, not interpolated: a stored state satisfies the constraints (to the
integrator's accuracy), an interpolated one in general does not, and the linearization
needs a configuration on the constraint manifold.  The stored state is then moved onto the
constraints (q by :func:`~casmbd.analysis.instant.assembly.assemble`, v by the mass-orthogonal
projection), because an integrator at rtol 1e-8 leaves |C| ≈ 3e-8, above the 1e-8 that
``q=`` accepts; ``stats["projection_dq"]``, ``["projection_dv"]`` say by how much, and
``stats["state_time"]`` is the output time used.

Equilibrium test.  The state is an equilibrium when max |v| ≤ :data:`EQUILIBRIUM_RTOL`
(m/s or rad/s) and the force residual ‖Q − C_qᵀλ‖∞ = ‖M q̈‖∞ (Q = Q_e + Q_v, λ and q̈ from
the KKT system) is at most :data:`EQUILIBRIUM_RTOL` · max(1, ‖Q‖∞) — the form of the
convergence test of the statics analysis, 100 times looser than its default, so that its
equilibria always pass.  A rheonomic driver (C_tt ≠ 0) gives q̈ ≠ 0 and hence no equilibrium.

Stability verdict: ONE classification, shared with statics.  At an equilibrium
:func:`casmbd.analysis.statics.stability.classify_stability` judges the reduced stiffness K̄ (the
same matrix statics judges: at v = 0, q̈ = 0 the ``M a`` and ``Q_v`` terms vanish, so K̄ is
the Hessian of the Lagrangian on the tangent space), with its stated tolerance and the null
directions named by the joint coordinates (else the generalized ones), exactly as statics
does.  Why K̄ and not the eigenvalues of A: a conservative system's linearization has purely
imaginary eigenvalues ±iω when it is stable, a neutral direction gives a double zero that
round-off splits into ±ε (a "positive real part" of 1e-9 or a spurious "stable"), and the
sign pattern of K̄ is what the static question asks.  With damping (C̄ from damping forces;
at v = 0 there are no gyroscopic terms, as Q_v is quadratic in v) the K̄ verdict still
decides: by the Kelvin–Tait–Chetaev theorem dissipation cannot stabilise a direction with
negative stiffness, and with full dissipation a positive definite K̄ is asymptotically stable.
Non-symmetric K̄ (non-conservative forces) is judged by the real parts of its eigenvalues
(divergence, not flutter).  The eigenvalues of A are reported alongside; :attr:`LinearModel.
stable` keeps the older spectral test (no eigenvalue of A with positive real part), which
calls a neutral equilibrium stable.  Away from an equilibrium there is no verdict:
``stability`` is None, ``verdict`` is "not an equilibrium" and ``stable`` is None.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla

from casmbd.analysis.events.event_rows import EventRows
from casmbd.analysis.events.events import has_events
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.checks import check_start
from casmbd.analysis.instant.independent import (
    IndependentRows,
    check_option,
    find_redundant,
    minimum_norm,
    scatter,
)
from casmbd.analysis.instant.kkt import accelerations_and_multipliers, project_velocities
from casmbd.analysis.instant.redundancy import RANK_RTOL, null_space_basis
from casmbd.analysis.statics.report import state_reports, state_summary
from casmbd.analysis.statics.stability import STABILITY_RTOL, Stability, classify_stability
from casmbd.analysis.statics.statics import STATICS_NEEDS, static_equilibrium, statics_functions
from casmbd.analysis.statics.steady_motion import SteadyMotionModel, linearize_steady_motion
from casmbd.compiled.build import compile_model
from casmbd.compiled.model import NumericModel
from casmbd.errors import AnalysisError, CompositionError, ModelError, SingularConfigurationError
from casmbd.model.contact_models import acts_at_events
from casmbd.model.measures import result_names
from casmbd.model.needs import ALL_NEEDS, Handling, check
from casmbd.system.equations import System

#: Functions the linearization needs besides its own Jacobians (assembly and the KKT system)
NEEDED = ("mass_matrix", "applied_forces", "quadratic_velocity_forces", "constraints",
          "constraint_jacobian", "constraint_time_derivative", "acceleration_rhs")

#: |Im s| below this times max(1, |s|max) counts as a real eigenvalue
IMAG_RTOL = 1e-9
#: equilibrium test: max |v| ≤ EQUILIBRIUM_RTOL and ‖Q − C_qᵀλ‖∞ ≤ EQUILIBRIUM_RTOL ·
#: max(1, ‖Q‖∞) (see the module docstring)
EQUILIBRIUM_RTOL = 1e-8
#: verdict reported instead of a stability verdict away from an equilibrium
NOT_AN_EQUILIBRIUM = "not an equilibrium"


def _linearization_function(system: System) -> ca.Function:
    """Jacobians of the dynamics residual at (q, v, t, u, p, λ, a)."""
    lam = ca.SX.sym("lambda", system.nc)
    acc = ca.SX.sym("a", system.nq)
    q, v, u = system.q, system.v, system.u
    # friction that follows the reactions: refused by the composition check (HANDLING)
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


def _joint_jacobian_function(system: System) -> ca.Function:
    """∂θ/∂q of the joint coordinates θ: names the null directions of a neutral equilibrium
    (the same function as the statics analysis's ``statics_joint_jacobian``)."""
    names = system.joint_coordinate_names
    joints = ca.vertcat(*[system._joint_coordinate(k) for k in names]) if names \
        else ca.SX(0, 1)
    return ca.Function("stability_joint_jacobian", [system.q, system.t, system.p],
                       [ca.jacobian(joints, system.q)], ["q", "t", "p"], ["Jj"])


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
        For one degree of freedom M̄ z̈ + C̄ ż + K̄ z = 0: ω_n = √(K̄/M̄), ζ = C̄ / (2√(K̄ M̄)) and
        the damped frequency ω_d = ω_n √(1 − ζ²) = 2π f (:attr:`damped_frequencies_hz`).
    q, v, t, u : the state of the linearization.
    lam : multipliers λ of the KKT system at that state.
    coordinate_names : names of the absolute coordinates (rows of N).
    stats : dict
        Besides counts and timings: ``equilibrium`` (bool), ``residual`` (‖Q − C_qᵀλ‖∞),
        ``residual_tolerance``, ``velocity_norm`` (max |v|), ``about`` ("initial",
        "state", "equilibrium" or "result"), ``state_time`` (for a result), ``statics_*``
        (for ``at="equilibrium"``).
    stability : Stability or None
        The verdict of :func:`casmbd.analysis.statics.stability.classify_stability` on K̄ (the one
        statics gives), None when the state is not an equilibrium.
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
    stability: Stability | None = None
    #: requests, force reports and named nodes at the state ("outputs": name -> value,
    #: "forces", "nodes"), as statics gives them at its equilibrium
    reports: dict = field(default_factory=dict)
    #: the text summary's values at the state
    #: (:func:`casmbd.analysis.statics.report.state_summary`)
    summary: dict = field(default_factory=dict)

    @property
    def damped_frequencies_hz(self) -> np.ndarray:
        """The damped frequency ω_d / 2π = |Im s| / 2π of every mode (:attr:`frequencies_hz`,
        named for what it is; equal to the natural frequency when undamped)."""
        return self.frequencies_hz

    @property
    def n_dof(self) -> int:
        """Number of independent coordinates n_z."""
        return self.N.shape[1]

    @property
    def equilibrium(self) -> bool:
        """Whether the state is an equilibrium (see the module docstring for the test)."""
        return bool(self.stats.get("equilibrium", False))

    @property
    def verdict(self) -> str:
        """"stable", "unstable" or "neutral" (the verdict statics gives), or "not an
        equilibrium"."""
        return self.stability.verdict if self.stability is not None else NOT_AN_EQUILIBRIUM

    def why_not_equilibrium(self) -> str:
        """Why the state is not an equilibrium (the velocity, the force residual against its
        tolerance), or "" at an equilibrium."""
        s = self.stats
        why = [f"max |v| = {s['velocity_norm']:.3g} is not 0"] \
            if s.get("velocity_norm", 0.0) > EQUILIBRIUM_RTOL else []
        if s.get("residual", 0.0) > s.get("residual_tolerance", np.inf):
            why.append(f"force residual max |Q - Cq^T lambda| = {s['residual']:.3g} > "
                       f"{s['residual_tolerance']:.3g}")
        return "; ".join(why)

    @property
    def stable(self) -> bool | None:
        """The spectral test: True when no eigenvalue of A has a positive real part (beyond
        round-off), None away from an equilibrium.

        A neutral equilibrium (a zero eigenvalue) passes it; :attr:`verdict` and
        :attr:`stability` are the classification shared with statics.
        """
        if not self.equilibrium:
            return None
        if self.eigenvalues.size == 0:
            return True
        scale = max(1.0, float(np.max(np.abs(self.eigenvalues))))
        return bool(np.max(self.eigenvalues.real) <= 1e-9 * scale)

    def to_json(self) -> dict:
        """Plain-Python dictionary for JSON output.

        ``"stable"`` is the shared verdict in the statics analysis's form (true stable,
        false unstable, null neutral or not an equilibrium), ``"verdict"`` its word,
        ``"stability"`` the classification (or null), ``"spectrally_stable"`` :attr:`stable`.
        Per mode: ``"natural_frequencies_hz"`` (undamped, ω_n / 2π),
        ``"damped_frequencies_hz"`` (ω_d / 2π) and ``"damping_ratios"`` (ζ);
        ``"frequencies_hz"`` is the damped frequency under its older name (kept).
        """
        return {
            "equilibrium": self.equilibrium,
            "residual": float(self.stats.get("residual", float("nan"))),
            "residual_tolerance": float(self.stats.get("residual_tolerance", float("nan"))),
            "verdict": self.verdict,
            "stable": self.stability.stable if self.stability is not None else None,
            "stability": self.stability.to_json() if self.stability is not None else None,
            "spectrally_stable": self.stable,
            "about": self.stats.get("about"),
            "frequencies_hz": self.frequencies_hz.tolist(),
            "damping_ratios": self.damping_ratios.tolist(),
            "natural_frequencies_hz": self.natural_frequencies_hz.tolist(),
            "damped_frequencies_hz": self.damped_frequencies_hz.tolist(),
            "eigenvalues": [[float(s.real), float(s.imag)] for s in self.eigenvalues],
            "M": self.M.tolist(), "C": self.C.tolist(), "K": self.K.tolist(),
            "B": self.B.tolist(), "A": self.A.tolist(), "B_state": self.Bss.tolist(),
            "N": self.N.tolist(),
            "coordinates": list(self.coordinate_names),
            "actuators": list(self.actuator_names),
            "q": self.q.tolist(), "v": self.v.tolist(), "t": self.t,
            "stats": dict(self.stats),
            **self.reports, **({"summary": self.summary} if self.summary else {}),
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
            # a neutral direction's ω² = 0 comes out as ±1e-16: a rigid-body mode (ζ = 0),
            # with the stability classification's tolerance
            w2[np.abs(w2) <= STABILITY_RTOL * max(float(np.max(np.abs(w2))), 1e-300)] = 0.0
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


def stored_state(times, q, v, coordinates: list[str], expected: list[str],
                 at_time: float) -> tuple[int, float, np.ndarray, np.ndarray]:
    """The stored state at the output time nearest ``at_time`` (see the module docstring).

    Parameters
    ----------
    times : array (n_t,)
        Output times of the result.
    q, v : arrays (n_t, n_q)
        Stored coordinates and velocities.
    coordinates : list of str
        The result's coordinate names.
    expected : list of str
        The coordinate names of the mechanism to linearize (the result must be of that scene).
    at_time : float

    Returns
    -------
    (index, time, q, v)

    Raises
    ------
    AnalysisError
        When ``at_time`` lies outside the output times (naming it and the range), or the
        result's coordinates are not the mechanism's (naming the count or the first mismatch).
    """
    times = np.asarray(times, dtype=float).reshape(-1)
    if list(coordinates) != list(expected):
        if len(coordinates) != len(expected):
            why = f"it has {len(coordinates)} coordinates, the scene {len(expected)}"
        else:
            k = next(i for i, (a, b) in enumerate(zip(coordinates, expected)) if a != b)
            why = f"its coordinate {k} is '{coordinates[k]}', the scene's '{expected[k]}'"
        raise AnalysisError(f"linearize: the result is not of this scene ({why})")
    if times.size == 0:
        raise AnalysisError("linearize: the result holds no output times")
    at_time = float(at_time)
    slack = 1e-9 * max(1.0, float(np.max(np.abs(times))))
    if not (np.isfinite(at_time) and times[0] - slack <= at_time <= times[-1] + slack):
        raise AnalysisError(f"linearize: time {at_time:g} is outside the result's output times "
                            f"[{times[0]:g}, {times[-1]:g}] ({times.size} outputs)")
    k = int(np.argmin(np.abs(times - at_time)))
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    if q.shape != (times.size, len(expected)) or v.shape != q.shape:
        raise AnalysisError(f"linearize: the result's q and v have shapes {q.shape}, "
                            f"{v.shape}, not ({times.size}, {len(expected)})")
    return k, float(times[k]), q[k].copy(), v[k].copy()


def _from_result(result, system: System, at_time, u):
    """(q, v, t, u, stats) of a result's stored state (duck-typed: ``.t``, ``.names``,
    ``[key]``; the analysis layer does not import :mod:`casmbd.results`)."""
    if at_time is None:
        raise ModelError("linearize: at=<result> needs at_time, the output time to use")
    names = getattr(result, "names", {}) or {}
    try:
        stored_q, stored_v = result["q"], result["v"]
    except KeyError as exc:
        raise AnalysisError(f"linearize: the result holds no '{exc.args[0]}' array") from None
    k, t, q, v = stored_state(result.t, stored_q, stored_v, list(names.get("coordinates", [])),
                              list(system.coordinate_names), at_time)
    nu = len(system.mechanism.actuators)
    if u is None and nu:
        try:
            inputs = np.asarray(result["actuator_inputs"], dtype=float)
        except KeyError:
            inputs = None
        if inputs is not None and inputs.shape == (len(result.t), nu):
            u = inputs[k]
    return q, v, t, u, {"about": "result", "state_index": k, "state_time": t,
                        "requested_time": float(at_time)}


#: a gap at most this is closed [m or rad] (as statics' active set)
CLOSED_GAP = 1e-9

#: what linearization handles (casmbd.model.needs): no switching friction, no friction that
#: follows the reactions; impact-model contacts and stops only where their gaps are open
HANDLING = Handling(
    "linearize", ALL_NEEDS - {"stick_slip", "contact_friction", "reaction_forces",
                              "velocity_constraints"},
    why={"velocity_constraints": "its model M̄ z̈ + C̄ ż + K̄ z = B̄ u takes δq and δv in one "
                                 "tangent space (ker C_q), while rows A(q) v + b = 0 restrict "
                                 "the velocities more than the positions (δq in ker C_hq, "
                                 "δv in ker C_q): that first-order model is not built",
         "stick_slip": "the exact Coulomb law is not differentiable at the stick-slip switch",
         "contact_friction": "Coulomb friction at a closed contact is not differentiable",
         "reaction_forces": "it does not solve for the multipliers the friction level needs"},
    instead={"velocity_constraints": "linearize about a steady motion (steady_motion=True, "
                                     "--steady-motion: the cyclic coordinates removed), or "
                                     "simulate",
             "stick_slip": "the regularised law (stick_slip = false)",
             "contact_friction": "model = 'compliant' with friction",
             "reaction_forces": "simulate with the formulation 'index1', or inverse dynamics"},
    notes={"events": "gaps open at the operating point do not act on small motions; a gap "
                     "closed there is refused by name",
           "inputs": "B̄ maps the inputs"})


def _closed_gaps(system: System, q: np.ndarray, v: np.ndarray, t: float, p) -> None:
    """Refuse an operating point at which a gap of an impact-model element is closed (a
    resting contact acts on small motions one-sidedly: no linear model exists)."""
    elements = [c for c in system.mechanism.contacts.values() if acts_at_events(c)]
    if not elements:
        return
    rows = EventRows(system, elements)
    gaps = rows(q, v, t, np.asarray(p, dtype=float))[0]
    closed = [rows.label(k) for k in range(len(gaps)) if gaps[k] <= CLOSED_GAP]
    if closed:
        raise CompositionError(
            f"linearize: {', '.join(closed)} closed at the operating point (gap <= "
            f"{CLOSED_GAP:g}): a resting contact or stop acts one-sidedly, so no linear model "
            "of the small motions exists; instead: model = 'compliant' (a force, linearized "
            "with the rest), or an operating point with the gap open", "linearize",
            [(label, "events") for label in closed])


def _at_equilibrium(mechanism, system: System, t: float, mode: str, stable: bool = False):
    """(q, stats) of the static equilibrium found from the initial configuration (the
    nearest one, or a stable one with ``stable``)."""
    if has_events(system.mechanism):  # resting contacts: the active set of statics
        eq = static_equilibrium(system.mechanism, t=t, mode=mode, stable=stable)
        return eq.q, {"about": "equilibrium", "statics_iterations": int(eq.iterations),
                      "statics_residual": float(eq.residual),
                      "statics_verdict": eq.stability.verdict if eq.stability else None}
    statics = compile_model(system, STATICS_NEEDS, mode=mode, extra=statics_functions(system))
    if isinstance(mechanism, NumericModel):
        statics.p[:] = mechanism.p
    eq = static_equilibrium(statics, t=t, mode=mode, stable=stable)
    return eq.q, {"about": "equilibrium", "statics_iterations": int(eq.iterations),
                  "statics_residual": float(eq.residual),
                  "statics_verdict": eq.stability.verdict if eq.stability else None}


def linearize(mechanism, q=None, v=None, t: float = 0.0, u=None, mode: str = "auto",
              rtol: float = RANK_RTOL, *, at=None, at_time: float | None = None,
              redundancy: str = "auto", stable: bool = False, steady_motion: bool = False
              ) -> LinearModel | SteadyMotionModel:
    """Linearize the constrained dynamics of ``mechanism`` about the state (q, v, t, u).

    Parameters
    ----------
    mechanism : Mechanism, System or NumericModel
        A NumericModel is reused only for its System and parameter values (the linearization
        compiles its own Functions, cached on disk like every model).
    q : array, optional
        Configuration; default the assembled initial configuration.  It is used as given
        (not moved onto the constraints, only checked); about a state that is not an
        equilibrium the result is the first-order expansion there and carries no stability
        verdict (see the module docstring).
    v : array, optional
        Velocities (default zero).
    t : float
        Time (for time-dependent forces and rheonomic drivers); with ``at="equilibrium"``
        the time of the statics analysis; ignored with ``at=<result>`` (the stored time).
    u : array, optional
        Actuator inputs (default zero; with ``at=<result>`` the stored inputs).
    mode : {"auto", "compiled", "vm"}
    rtol : float
        Relative rank tolerance of the constraint Jacobian.
    at : {None, "equilibrium"} or Result, keyword-only
        ``"equilibrium"``: about the static equilibrium
        (:func:`casmbd.analysis.statics.statics.static_equilibrium` from the initial configuration,
        v = 0, u = 0; same as ``q=static_equilibrium(m, t=t).q``).  A result (of
        :func:`casmbd.simulate` …, or :func:`casmbd.load_result`): about its stored q, v at the
        output time nearest ``at_time`` (the result must be of the same scene).  Not
        together with ``q`` or ``v``.
    at_time : float, optional
        The time wanted with ``at=<result>``.
    redundancy : {"auto", "remove"}, keyword-only
        Redundant constraint equations (dependent rows of C_q at q, named in
        ``stats["redundant_equations"]``) are removed from the KKT solve for q̈ and λ, and λ of
        the full set is the minimum-norm one (:mod:`casmbd.analysis.instant.independent`).  N spans
        ker C_q either way, and K̄ does not depend on which λ of the full set is used where the
        redundancy persists around q: Nᵀ ∂(C_qᵀ z)/∂q N = −Nᵀ C_qᵀ ∂z/∂q = 0 for C_qᵀ z ≡ 0.
    stable : bool, keyword-only
        With ``at="equilibrium"``: about a stable equilibrium (``static_equilibrium(m,
        stable=True)``) instead of the one nearest the initial configuration.
    steady_motion : bool, keyword-only
        Linearize about the steady motion that starts at (q, v) (default: the scene's initial
        state) with the cyclic coordinates removed:
        :func:`casmbd.analysis.statics.steady_motion.linearize_steady_motion`, which returns a
        :class:`~casmbd.analysis.statics.steady_motion.SteadyMotionModel`.  A mechanism with
        non-holonomic (velocity) constraints is linearized only this way: the independent
        positions of the small-oscillation form do not exist for it, and it is refused by
        name otherwise.

    Returns
    -------
    LinearModel (SteadyMotionModel with ``steady_motion=True``)

    Raises
    ------
    AnalysisError
        If q violates the constraints, the static equilibrium is not found, or ``at_time``
        is outside the result's times or the result is of another scene (named).
    SingularConfigurationError
        If the reduced mass matrix is singular.
    ModelError
        Bad sizes or non-finite q, v, u; ``at`` together with q or v; unknown ``at``.
    """
    t0 = time.perf_counter()
    check_option(redundancy, "linearize")
    if isinstance(mechanism, NumericModel):
        system = mechanism.system
    elif isinstance(mechanism, System):
        system = mechanism
    else:
        system = System(mechanism)
    t = float(t)
    if steady_motion:
        if at is not None or at_time is not None or stable:
            raise ModelError("linearize: steady_motion=True linearizes about (q, v) or the "
                             "initial state; not with at=, at_time= or stable=")
        return linearize_steady_motion(mechanism, q=q, v=v, t=t, u=u, mode=mode, rtol=rtol)
    check(system.mechanism, HANDLING)
    about = {"about": "initial" if q is None and v is None else "state"}
    if at is not None:
        if q is not None or v is not None:
            raise ModelError("linearize: give either at=... or q/v, not both")
        if isinstance(at, str) and at == "equilibrium":
            if u is not None and np.any(np.asarray(u, dtype=float) != 0.0):
                raise ModelError("linearize: at='equilibrium' is the equilibrium with zero "
                                 "inputs; u must be zero")
            q, about = _at_equilibrium(mechanism, system, t, mode, stable)
        elif isinstance(at, str) or not hasattr(at, "t"):
            raise ModelError(f"linearize: at must be 'equilibrium' or a result, got {at!r}")
        else:
            q, v, t, u, about = _from_result(at, system, at_time, u)
    elif at_time is not None:
        raise ModelError("linearize: at_time needs at=<result>")
    if stable and not (isinstance(at, str) and at == "equilibrium"):
        raise ModelError("linearize: stable=True goes with at='equilibrium'")
    lin_fun = _linearization_function(system)
    model = compile_model(system, NEEDED, mode=mode,
                          extra=[lin_fun, _joint_jacobian_function(system)])
    if isinstance(mechanism, NumericModel):
        model.p[:] = mechanism.p
    t_build = time.perf_counter() - t0
    t1 = time.perf_counter()
    nq = model.nq
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
    if about["about"] == "result":  # onto the constraints: an integrator drifts off them
        q0, v0 = q, v
        q = assemble(model, q0, t).q
        v = project_velocities(model, q, v0, t)
        about["projection_dq"] = float(np.max(np.abs(q - q0), initial=0.0))
        about["projection_dv"] = float(np.max(np.abs(v - v0), initial=0.0))
    check_start(model, q, v, t, u, what="linearization")  # names a NaN's culprit
    _closed_gaps(system, q, v, t, model.p)
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
    plan = find_redundant(model, q, t)
    if plan.removes:  # a regular KKT matrix on the independent rows; λ least-norm
        acc, lam = accelerations_and_multipliers(IndependentRows(model, plan.kept_rows),
                                                 q, v, t, u)
        lam = minimum_norm(model.constraint_jacobian(q, t),
                           scatter(lam, plan.kept_rows, model.nc))
    else:
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
    # equilibrium test (module docstring): v = 0 and Q − C_qᵀλ = M q̈ = 0, relative to Q
    force = model.applied_forces(q, v, t, u) + model.quadratic_velocity_forces(q, v)
    residual = float(np.max(np.abs(m_full @ acc), initial=0.0))
    res_tol = EQUILIBRIUM_RTOL * max(1.0, float(np.max(np.abs(force), initial=0.0)))
    v_norm = float(np.max(np.abs(v), initial=0.0))
    equilibrium = bool(v_norm <= EQUILIBRIUM_RTOL and residual <= res_tol)
    stability = _classify(model, system, q, t, basis, k_bar) if equilibrium else None
    stats = {"n_coordinates": nq, "n_constraints": model.nc, "rank": rank,
             "degrees_of_freedom": nz, "n_inputs": nu,
             "acceleration_norm": float(np.linalg.norm(acc)),
             "velocity_norm": v_norm, "residual": residual, "residual_tolerance": res_tol,
             "equilibrium": equilibrium, **about, **plan.stats(),
             "build_seconds": t_build, "solve_seconds": time.perf_counter() - t1,
             **{k: val for k, val in model.report_dict.items() if k != "build_seconds"}}
    reports, summary = _state_reports(model, system.mechanism, q, v, acc, t)
    return LinearModel(m_bar, c_bar, k_bar, b_bar, a_mat, b_ss, basis, eig, freq, zeta, fn,
                       q, v, t, u, lam, list(system.coordinate_names),
                       list(system.mechanism.actuators), stats, stability, reports, summary)


def _state_reports(model: NumericModel, mech, q, v, acc, t: float) -> tuple[dict, dict]:
    """The requests (``[[outputs]]``), force reports and named nodes at the operating point
    (q, v, q̈, t), and their summary (:func:`casmbd.analysis.statics.report.state_summary`); the
    outputs Function is evaluated only when the mechanism has requests or named nodes."""
    names = result_names(mech)
    if not ("outputs" in names or "nodes" in names):
        return {}, {}
    out = model.outputs(q[None, :], v[None, :], np.asarray(acc, dtype=float)[None, :],
                        np.array([t]))
    reports = state_reports(mech, out)
    return reports, state_summary(reports, names)


def _classify(model: NumericModel, system: System, q, t: float, basis: np.ndarray,
              k_bar: np.ndarray) -> Stability:
    """The statics analysis's classification of K̄: null directions named by the joint
    coordinates, else by the generalized coordinates."""
    if system.joint_coordinate_names:
        directions = model._sparse("stability_joint_jacobian", q, t, model.p).toarray() @ basis
        labels = list(system.joint_coordinate_names)
    else:
        directions, labels = basis, list(system.coordinate_names)
    return classify_stability(k_bar, directions, labels)
