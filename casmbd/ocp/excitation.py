"""Excitation trajectories for dynamic parameter identification: periodic Fourier series
optimised for the conditioning of the stacked base regressor.

Each joint follows a finite Fourier series of fundamental pulsation ω_f = 2π / T
(Swevers, Ganseman, Tükel, De Schutter & Van Brussel, "Optimal robot excitation and
identification", IEEE Trans. Robotics and Automation 13(5), 1997, eq. 9):

    q_i(t)  = q0_i + Σ_{l=1..L} a_il/(ω_f l) sin(ω_f l t) − b_il/(ω_f l) cos(ω_f l t)
    q̇_i(t)  = Σ_l a_il cos(ω_f l t) + b_il sin(ω_f l t)
    q̈_i(t)  = Σ_l −a_il ω_f l sin(ω_f l t) + b_il ω_f l cos(ω_f l t)

so a trajectory is periodic by construction (start and end states match for any a, b, q0: the
measurement may be averaged over periods), band-limited to L ω_f (the excitation of unmodelled
dynamics is controlled) and *linear* in the decision variables x = (q0, a, b): the position,
velocity and acceleration limits at the samples are linear inequalities G x ≤ h.

The objective is the conditioning of the stacked base regressor W = [Y(q_k, q̇_k, q̈_k) B]_k over
N samples t_k = k T / N (B selects the base parameters).  The condition number
κ(W) = σ_max / σ_min is not differentiable where the extreme singular values are multiple, so
IPOPT minimises the smooth, eigenvalue-free surrogate

    f(x) = log tr(A) + log tr(A⁻¹),   A = Wᵀ W = Σ_k B ᵀ Y_kᵀ Y_k B     (n_b × n_b)

with the bounds κ(W)² ≤ tr(A) tr(A⁻¹) ≤ n_b² κ(W)² (tr A ≥ λ_max, tr A⁻¹ ≥ 1/λ_min, and each
trace is at most n_b times its largest term).  tr(A) tr(A⁻¹) = Σ_ij λ_i/λ_j is the sum of all
eigenvalue ratios, so it is scale-free like κ, smooth wherever A is regular (no eigenvalue is
computed), and penalises every small eigenvalue rather than only the smallest, which also keeps
the iterates away from the non-smooth crossings; the log makes it a sum of two terms of
comparable size.  (log det A, D-optimality, is not scale-free: it rewards amplitude and pushes
to the limits without improving κ.)  The exact κ(W) is reported before and after.

Derivatives are exact (AD through the regressor Function, the Gram matrix mapped over the
samples and a linear solve for A⁻¹); the Hessian is IPOPT's limited-memory approximation (the
exact one of log tr A⁻¹ through the regressor is dense and costs more than it saves here).
Optional torque limits |τ_k| ≤ τ_max use τ = Y(q, q̇, q̈) π at given parameters π.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg

from casmbd.analysis.identification.base_parameters import BaseParameters, base_parameters
from casmbd.analysis.identification.regressor import joint_torque_regressor
from casmbd.errors import ModelError, OptimizationError

__all__ = ["ExcitationDesign", "FourierTrajectory", "base_columns", "condition_number",
           "design_excitation", "excitation_for", "joint_limits", "random_feasible"]

#: relative pivot threshold of the column-pivoted QR that selects independent regressor columns
BASE_TOLERANCE = 1e-8
#: largest κ of the stacked base regressor at the random start (beyond: a base parameter is
#: not excited, A is numerically singular and log tr A⁻¹ meaningless)
START_CONDITION_LIMIT = 1e10
#: largest violation of a limit by the returned series, relative to the limit's range
FEASIBILITY_TOLERANCE = 1e-10
#: the exchange method's check grid: instants per period of the highest harmonic (between two
#: of them a limit can be exceeded by at most 1 − cos(π/40) ≈ 0.3 % of that harmonic's share)
CHECK_PER_HARMONIC = 40
#: the most solves of the exchange method (the last one's result is checked on the fine grid)
EXCHANGE_ROUNDS = 6


@dataclass
class FourierTrajectory:
    """q_i(t) = q0_i + Σ_l a_il/(ω_f l) sin(ω_f l t) − b_il/(ω_f l) cos(ω_f l t), ω_f = 2π/T.

    Parameters
    ----------
    period : float
        T [s].
    q0 : ndarray, shape (n,)
        Offsets (the mean position of each joint).
    a, b : ndarray, shape (n, L)
        Sine and cosine velocity amplitudes [rad/s or m/s] of the harmonics l = 1..L.
    """

    period: float
    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray

    def __post_init__(self):
        self.q0 = np.asarray(self.q0, float).ravel()
        self.a = np.atleast_2d(np.asarray(self.a, float))
        self.b = np.atleast_2d(np.asarray(self.b, float))
        if not (math.isfinite(self.period) and self.period > 0.0):
            raise ModelError(f"Fourier trajectory field 'period': must be > 0, got {self.period}")
        if self.a.shape != self.b.shape or self.a.shape[0] != self.q0.size:
            raise ModelError(f"Fourier trajectory: a {self.a.shape}, b {self.b.shape} and q0 "
                             f"({self.q0.size},) do not agree (expected (n, L), (n, L), (n,))")

    @property
    def pulsation(self) -> float:
        """ω_f = 2π / T [rad/s]."""
        return 2.0 * math.pi / self.period

    @property
    def harmonics(self) -> int:
        return self.a.shape[1]

    @property
    def vector(self) -> np.ndarray:
        """x = (q0, a row-major, b row-major), the decision variables of the design."""
        return np.concatenate([self.q0, self.a.ravel(), self.b.ravel()])

    @classmethod
    def from_vector(cls, x, n: int, harmonics: int, period: float) -> FourierTrajectory:
        x = np.asarray(x, float).ravel()
        nl = n * harmonics
        return cls(period, x[:n], x[n:n + nl].reshape(n, harmonics),
                   x[n + nl:].reshape(n, harmonics))

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, q̇, q̈) at the times ``t``, each of shape (len(t), n)."""
        t = np.atleast_1d(np.asarray(t, float))
        w = self.pulsation
        k = np.arange(1, self.harmonics + 1)  # the harmonic numbers l
        s, c = np.sin(w * np.outer(t, k)), np.cos(w * np.outer(t, k))  # (N, L)
        q = self.q0 + s @ (self.a / (w * k)).T - c @ (self.b / (w * k)).T
        v = c @ self.a.T + s @ self.b.T
        acc = -s @ (self.a * w * k).T + c @ (self.b * w * k).T
        return q, v, acc

    def samples(self, count: int) -> np.ndarray:
        """count equally spaced times over one period, t_k = k T / count (t = T excluded: it
        is t = 0 again)."""
        return np.arange(count) * (self.period / count)


def _basis_rows(period: float, harmonics: int, times: np.ndarray):
    """Matrices P, V, A (N × (1 + 2L)) with q_i(t_k) = P[k] · (q0_i, a_i, b_i), and so on:
    the per-joint linear maps of the series."""
    w = 2.0 * math.pi / period
    k = np.arange(1, harmonics + 1)  # the harmonic numbers l
    s, c = np.sin(w * np.outer(times, k)), np.cos(w * np.outer(times, k))
    one, zero = np.ones((times.size, 1)), np.zeros((times.size, 1))
    pos = np.hstack([one, s / (w * k), -c / (w * k)])
    vel = np.hstack([zero, c, s])
    acc = np.hstack([zero, -s * w * k, c * w * k])
    return pos, vel, acc


def _joint_maps(n: int, harmonics: int, basis: np.ndarray) -> list[np.ndarray]:
    """For each joint i the (N × n_x) matrix mapping x = (q0, a, b) to its samples."""
    maps = []
    for i in range(n):
        m = np.zeros((basis.shape[0], n * (1 + 2 * harmonics)))
        m[:, i] = basis[:, 0]
        m[:, n + i * harmonics:n + (i + 1) * harmonics] = basis[:, 1:1 + harmonics]
        m[:, n + n * harmonics + i * harmonics:n + n * harmonics + (i + 1) * harmonics] = \
            basis[:, 1 + harmonics:]
        maps.append(m)
    return maps


def joint_limits(mechanism) -> dict[str, np.ndarray]:
    """Position and velocity limits of a mechanism's joints, in coordinate order.

    Read from the URDF ``<limit lower upper velocity effort>`` kept on each joint
    (``urdf_limits``, :mod:`casmbd.io.urdf`) or from ``lower``/``upper``/``velocity``/``effort``
    attributes; a missing entry is ±inf.  Only single-coordinate (revolute, prismatic) joints
    are read, in the order of the mechanism's joints, which is the order of the joint
    coordinates of a tree.

    Returns
    -------
    dict with ``names`` (joint names), ``lower``, ``upper``, ``velocity``, ``effort``.
    """
    names, rows = [], []
    for joint in mechanism.joints.values():
        if len(joint.coordinate_names) != 1 or joint.body1 is None:
            continue
        got = dict(getattr(joint, "urdf_limits", {}) or {})
        for key in ("lower", "upper", "velocity", "effort"):
            if getattr(joint, key, None) is not None and key not in got:
                got[key] = getattr(joint, key)
        lo, hi = got.get("lower", -np.inf), got.get("upper", np.inf)
        if lo >= hi:  # URDF: lower = upper = 0 means unlimited (continuous)
            lo, hi = -np.inf, np.inf
        vel = got.get("velocity", np.inf) or np.inf
        eff = got.get("effort", np.inf) or np.inf
        names.append(joint.name)
        rows.append((lo, hi, vel, eff))
    arr = np.array(rows, float).reshape(-1, 4)
    return {"names": names, "lower": arr[:, 0], "upper": arr[:, 1], "velocity": arr[:, 2],
            "effort": arr[:, 3]}


def base_columns(regressor: ca.Function, n: int, *, samples: int = 200, seed: int = 0,
                 tol: float = BASE_TOLERANCE, scale=None) -> np.ndarray:
    """Indices of a set of independent regressor columns (a base), by column-pivoted QR.

    W stacks Y at ``samples`` random states (q, q̇, q̈ uniform in [−π, π], [−2, 2], [−5, 5]
    times ``scale``); a column is kept when its pivot |R_jj| exceeds ``tol`` |R_11|
    (Gautier, "Numerical calculation of the base inertial parameters of robots", J. Robotic
    Systems 8(4), 1991).  The base parameters are the kept standard ones plus the linear
    combinations of the others that the QR gives; the design needs only the columns.
    """
    rng = np.random.default_rng(seed)
    k = 1.0 if scale is None else np.asarray(scale, float)
    q = rng.uniform(-np.pi, np.pi, (samples, n)) * k
    v = rng.uniform(-2.0, 2.0, (samples, n)) * k
    acc = rng.uniform(-5.0, 5.0, (samples, n)) * k
    w = _stack(regressor, q, v, acc)
    _, r, piv = scipy.linalg.qr(w, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > tol * diag[0]))
    return np.sort(piv[:rank])


def _stack(regressor: ca.Function, q, v, acc) -> np.ndarray:
    """W = [Y(q_k, q̇_k, q̈_k)]_k stacked row-wise, (N n) × p."""
    count = q.shape[0]
    out = np.array(regressor.map(count)(q.T, v.T, acc.T))  # n × (p N)
    n, p = out.shape[0], out.shape[1] // count
    return out.reshape(n, count, p).transpose(1, 0, 2).reshape(count * n, p)


def condition_number(regressor: ca.Function, trajectory: FourierTrajectory, samples: int,
                     columns=None) -> float:
    """κ(W) = σ_max / σ_min of the stacked (base) regressor over ``samples`` equally spaced
    times of one period (2-norm, by SVD)."""
    q, v, acc = trajectory.evaluate(trajectory.samples(samples))
    w = _stack(regressor, q, v, acc)
    if columns is not None:
        w = w[:, np.asarray(columns)]
    return float(np.linalg.cond(w))


def _scalar_form(regressor: ca.Function) -> ca.Function:
    """The regressor on scalar expressions (SX) when it can be expanded (an MX Function of
    elementary operations, as h-regressor's ``symbolic``): faster to evaluate and
    differentiate; else as given (a linear solve inside, a closed chain's efforts)."""
    if regressor.is_a("SXFunction"):
        return regressor
    try:
        return regressor.expand()
    except RuntimeError:
        return regressor


def _check_feasible(traj: FourierTrajectory, times: np.ndarray, lim: _Limits, sol, lbg, ubg,
                    status: str) -> None:
    """The returned series must hold every limit at the constraint samples (to
    :data:`FEASIBILITY_TOLERANCE` relative to the limit) and the other constraints to the
    same tolerance: IPOPT stopped at its iteration limit may not be feasible."""
    q, v, acc = traj.evaluate(times)
    for values, low, high, what in ((q, lim.lower, lim.upper, "position"),
                                    (v, -lim.velocity, lim.velocity, "velocity"),
                                    (acc, -lim.acceleration, lim.acceleration,
                                     "acceleration")):
        scale = np.where(np.isfinite(high - low), np.abs(high - low), 1.0)
        excess = np.maximum(values - high, low - values) / scale
        if np.max(excess) > FEASIBILITY_TOLERANCE:
            joint = int(np.argmax(np.max(excess, axis=0)))
            raise OptimizationError(f"excitation design: IPOPT ('{status}') returned a series "
                                    f"that violates the {what} limit of joint {joint} by "
                                    f"{np.max(excess):.3g} (relative); raise 'max_iter'")
    g = np.array(sol["g"]).ravel()
    lo = np.concatenate([np.ravel(b) for b in lbg])
    hi = np.concatenate([np.ravel(b) for b in ubg])
    scale = np.maximum(np.abs(lo), np.abs(hi))
    scale = np.where(np.isfinite(scale) & (scale > 0.0), scale, 1.0)
    worst = np.max(np.maximum(g - hi, lo - g) / scale) if g.size else 0.0
    if worst > FEASIBILITY_TOLERANCE:
        raise OptimizationError(f"excitation design: IPOPT ('{status}') returned a series that "
                                f"violates a constraint (start or torque limit) by {worst:.3g} "
                                "(relative); raise 'max_iter'")


@dataclass
class _Limits:
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


def _limits(n, lower, upper, velocity, acceleration) -> _Limits:
    def vec(x, name, default):
        arr = np.full(n, default, float) if x is None else np.broadcast_to(
            np.asarray(x, float), (n,)).copy()
        if np.isnan(arr).any():
            raise ModelError(f"excitation design: '{name}' has NaN entries")
        return arr
    lim = _Limits(vec(lower, "lower", -np.inf), vec(upper, "upper", np.inf),
                  vec(velocity, "velocity", np.inf), vec(acceleration, "acceleration", np.inf))
    for i in range(n):
        if not lim.lower[i] < lim.upper[i]:
            raise ModelError(f"excitation design: joint {i}: 'lower' {lim.lower[i]} is not "
                             f"below 'upper' {lim.upper[i]}")
        if not (lim.velocity[i] > 0.0 and lim.acceleration[i] > 0.0):
            raise ModelError(f"excitation design: joint {i}: velocity and acceleration limits "
                             "must be > 0")
        if not (np.isfinite(lim.velocity[i]) or np.isfinite(lim.acceleration[i])
                or np.isfinite(lim.upper[i] - lim.lower[i])):
            raise ModelError(f"excitation design: joint {i} has no finite limit: the "
                             "conditioning is scale-free and the amplitudes would be unbounded")
    return lim


def random_feasible(n: int, harmonics: int, period: float, *, lower=None, upper=None,
                    velocity=None, acceleration=None, centre=None, fill: float = 0.9,
                    constraint_samples: int | None = None, seed: int = 0) -> FourierTrajectory:
    """A random Fourier trajectory inside the limits (the baseline and the start of the design).

    a, b are standard normal, q0 the middle of the position range (or ``centre``); the
    amplitudes are then scaled by one factor so that the largest ratio of |q − q0|, |q̇|, |q̈|
    to its allowance over ``constraint_samples`` instants (default: the exchange method's
    check grid) is ``fill``.
    """
    lim = _limits(n, lower, upper, velocity, acceleration)
    rng = np.random.default_rng(seed)
    q0 = _centre(lim, centre)
    traj = FourierTrajectory(period, q0, rng.normal(size=(n, harmonics)),
                             rng.normal(size=(n, harmonics)))
    count = constraint_samples or CHECK_PER_HARMONIC * harmonics
    q, v, acc = traj.evaluate(traj.samples(count))
    room = np.minimum(q0 - lim.lower, lim.upper - q0)
    ratio = max(np.max(np.abs(q - q0) / room), np.max(np.abs(v) / lim.velocity),
                np.max(np.abs(acc) / lim.acceleration))
    return FourierTrajectory(period, q0, traj.a * fill / ratio, traj.b * fill / ratio)


def _centre(lim: _Limits, centre) -> np.ndarray:
    if centre is not None:
        return np.asarray(centre, float).ravel().copy()
    bounded = np.isfinite(lim.lower) & np.isfinite(lim.upper)
    mid = 0.5 * (np.where(bounded, lim.lower, 0.0) + np.where(bounded, lim.upper, 0.0))
    return np.where(bounded, mid, np.clip(0.0, lim.lower, lim.upper))


def _default_constraint_samples(harmonics: int) -> int:
    """The exchange method's first grid: 6 instants per period of the highest harmonic (the
    fine grid of :data:`CHECK_PER_HARMONIC` adds the instants where a limit is exceeded)."""
    return 6 * harmonics


def _limit_rows(n: int, harmonics: int, period: float, times: np.ndarray, lim: _Limits,
                margin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joint limits at ``times`` as linear rows in x = (q0, a, b): the matrix and its
    lower and upper bounds, tightened by ``margin`` (relative)."""
    pos, vel, acc = _basis_rows(period, harmonics, times)
    rows, lo, hi = [], [], []
    tight = 1.0 - margin
    count = times.size
    for i, (mp, mv, ma) in enumerate(zip(_joint_maps(n, harmonics, pos),
                                         _joint_maps(n, harmonics, vel),
                                         _joint_maps(n, harmonics, acc))):
        span = lim.upper[i] - lim.lower[i]
        if np.isfinite(lim.lower[i]) or np.isfinite(lim.upper[i]):
            pad = margin * (span if np.isfinite(span) else 1.0)
            rows.append(mp)
            lo.append(np.full(count, lim.lower[i] + pad))
            hi.append(np.full(count, lim.upper[i] - pad))
        for m, bound in ((mv, lim.velocity[i]), (ma, lim.acceleration[i])):
            if np.isfinite(bound):
                rows.append(m)
                lo.append(np.full(count, -bound * tight))
                hi.append(np.full(count, bound * tight))
    if not rows:
        return np.zeros((0, n * (1 + 2 * harmonics))), np.zeros(0), np.zeros(0)
    return np.vstack(rows), np.concatenate(lo), np.concatenate(hi)


def _shrink_into_limits(traj: FourierTrajectory, times: np.ndarray, lim: _Limits,
                        margin: float) -> tuple[FourierTrajectory, float]:
    """The series with its amplitudes (a, b) scaled by one factor s ≤ 1 so that every limit
    holds at ``times`` with ``margin``: q − q0, q̇ and q̈ are linear in the amplitudes, so s is
    the smallest ratio of allowance to use (q0 inside the position range).  κ changes
    little (the regressor is not homogeneous in the amplitudes); stated in the result."""
    q, v, acc = traj.evaluate(times)
    d = q - traj.q0
    up = np.where(d > 0, (lim.upper - traj.q0) / np.where(d > 0, d, 1.0), np.inf)
    down = np.where(d < 0, (lim.lower - traj.q0) / np.where(d < 0, d, 1.0), np.inf)
    with np.errstate(divide="ignore"):
        vel = lim.velocity / np.abs(v)
        accel = lim.acceleration / np.abs(acc)
    factor = float(np.min([np.min(up), np.min(down), np.min(vel), np.min(accel)]))
    if not np.isfinite(factor) or factor <= 0.0:
        return traj, 1.0
    scale = min(1.0, factor * (1.0 - 2.0 * margin))
    return FourierTrajectory(traj.period, traj.q0, traj.a * scale, traj.b * scale), scale


def _violations(traj: FourierTrajectory, times: np.ndarray, lim: _Limits) -> np.ndarray:
    """The largest relative excess of any joint limit at each of ``times`` (≤ 0: inside)."""
    q, v, acc = traj.evaluate(times)
    worst = np.full(times.size, -np.inf)
    for values, low, high in ((q, lim.lower, lim.upper), (v, -lim.velocity, lim.velocity),
                              (acc, -lim.acceleration, lim.acceleration)):
        scale = np.where(np.isfinite(high - low), np.abs(high - low), 1.0)
        excess = np.maximum(values - high, low - values) / scale
        worst = np.maximum(worst, np.max(excess, axis=1))
    return worst


@dataclass
class ExcitationDesign:
    """The result of :func:`design_excitation`.

    Attributes
    ----------
    trajectory : FourierTrajectory
        The optimised series.
    initial : FourierTrajectory
        The random feasible start.
    condition, initial_condition : float
        κ(W) of the stacked base regressor over the design samples, after and before.
    columns : ndarray
        The base (independent) columns of the regressor used.
    samples : int
        N, the number of regressor samples per period.
    constraint_times : ndarray
        Where the limits are imposed.
    status : str
        IPOPT's return status; ``iterations`` its iteration count.
    """

    trajectory: FourierTrajectory
    initial: FourierTrajectory
    condition: float
    initial_condition: float
    columns: np.ndarray
    samples: int
    constraint_times: np.ndarray
    status: str
    iterations: int
    objective: float
    stats: dict = field(default_factory=dict, repr=False)
    #: the coordinate names of the joints, in order (set by :func:`excitation_for`)
    coordinates: list[str] = field(default_factory=list)


def design_excitation(regressor: ca.Function, *, period: float, harmonics: int = 5,
                      samples: int = 60, lower=None, upper=None, velocity=None,
                      acceleration=None, torque: tuple | None = None,
                      start_at_rest: bool = False, start: Sequence[float] | None = None,
                      centre: Sequence[float] | None = None, columns=None,
                      constraint_samples: int | None = None, margin: float = 1e-6,
                      seed: int = 0, max_iter: int = 300,
                      options: dict | None = None) -> ExcitationDesign:
    """Optimise a periodic Fourier excitation for the conditioning of the base regressor.

    min_x  log tr(A) + log tr(A⁻¹),  A = Σ_k B ᵀ Y(q_k, q̇_k, q̈_k)ᵀ Y(...) B  (module docstring)
    s.t.   lower ≤ q(t_j) ≤ upper,  |q̇(t_j)| ≤ velocity,  |q̈(t_j)| ≤ acceleration,
           |Y(q_j, q̇_j, q̈_j) π| ≤ τ_max (optional, at the regressor samples),
           q̇(0) = 0, q̈(0) = 0 (``start_at_rest``), q(0) = ``start`` (optional),

    with x = (q0, a, b) and t_j on a constraint grid (default 20 per period of the highest
    harmonic), solved by IPOPT (limited-memory Hessian) from :func:`random_feasible`.

    Parameters
    ----------
    regressor : casadi.Function
        Y(q, q̇, q̈) → n × p (symbolic: it is called on MX and differentiated).
    period : float
        T [s]; ω_f = 2π / T.
    harmonics : int
        L, harmonics per joint.
    samples : int
        N, regressor samples per period (the rows of W are N n).
    lower, upper, velocity, acceleration : float or array (n,)
        Limits (rad, rad/s, rad/s² or m, m/s, m/s²); ±inf or None: none.  At least one finite
        limit per joint is required (κ is scale-free, the amplitudes must be bounded).
    torque : (π, τ_max) or None
        Parameters and torque limits for |τ| ≤ τ_max at the regressor samples.
    columns : array of int or None
        Base columns of Y (default :func:`base_columns`).
    margin : float
        Relative margin the limits are tightened by, so that the returned trajectory satisfies
        them at the constraint samples despite IPOPT's feasibility tolerance.
    options : dict
        Extra ``nlpsol`` options (trusted Python code).

    Returns
    -------
    ExcitationDesign
    """
    n = regressor.size1_in(0)
    if harmonics < 1 or samples < 1:
        raise ModelError("excitation design: 'harmonics' and 'samples' must be >= 1")
    lim = _limits(n, lower, upper, velocity, acceleration)
    if columns is None:
        columns = base_columns(regressor, n)
    columns = np.asarray(columns, int)
    nb = columns.size
    if samples * n < nb:
        raise ModelError(f"excitation design: {samples} samples × {n} joints give fewer rows "
                         f"than the {nb} base parameters; raise 'samples'")
    initial = random_feasible(n, harmonics, period, lower=lim.lower, upper=lim.upper,
                              velocity=lim.velocity, acceleration=lim.acceleration,
                              centre=centre, constraint_samples=constraint_samples, seed=seed)
    start_condition = condition_number(regressor, initial, samples, columns)
    if not start_condition < START_CONDITION_LIMIT:
        raise ModelError(f"excitation design: the random start (seed {seed}) does not excite "
                         f"every one of the {nb} base parameters (κ = {start_condition:.3g}); "
                         "raise 'harmonics' or 'samples', or check the limits and columns")
    nx = n * (1 + 2 * harmonics)
    x = ca.MX.sym("x", nx)

    # regressor samples: q, q̇, q̈ (n × N) linear in x
    times = initial.samples(samples)
    pos, vel, acc = _basis_rows(period, harmonics, times)
    qm = ca.vertcat(*[ca.mtimes(ca.DM(m), x).T for m in _joint_maps(n, harmonics, pos)])
    vm = ca.vertcat(*[ca.mtimes(ca.DM(m), x).T for m in _joint_maps(n, harmonics, vel)])
    am = ca.vertcat(*[ca.mtimes(ca.DM(m), x).T for m in _joint_maps(n, harmonics, acc)])
    regressor = _scalar_form(regressor)
    sym = ca.SX if regressor.is_a("SXFunction") else ca.MX
    qs, vs, as_ = [sym.sym(s, n) for s in ("q", "v", "a")]
    yb = regressor(qs, vs, as_)[:, columns.tolist()]
    # W = [Y_b(t_1); …; Y_b(t_N)] by a map of the base regressor, then A = WᵀW as one dense
    # product: the Gram matrix is never expanded symbolically (an SX Gram of the UR5 with
    # friction, 48 × 48 sums of products of the regressor's entries, took minutes per
    # solve to evaluate or to compile)
    base = ca.Function("base_regressor", [qs, vs, as_], [yb])
    stacked = base.map("base_regressor_map", "serial", samples, [], [])(qm, vm, am)
    w_mat = ca.vertcat(*ca.horzsplit(stacked, nb))
    a_mat = ca.mtimes(w_mat.T, w_mat)
    objective = ca.log(ca.trace(a_mat)) + ca.log(ca.trace(ca.solve(a_mat, ca.DM.eye(nb), "qr")))

    # the fixed rows: the start and the torque limits
    fixed, flo, fhi = [], [], []
    if start_at_rest or start is not None:
        z = np.zeros(1)
        p0, v0, a0 = _basis_rows(period, harmonics, z)
        pairs = []
        if start_at_rest:
            pairs += [(v0, np.zeros(n)), (a0, np.zeros(n))]
        if start is not None:
            pairs.append((p0, np.asarray(start, float)))
        for basis, value in pairs:
            fixed.append(ca.vertcat(*[ca.mtimes(ca.DM(m), x)
                                      for m in _joint_maps(n, harmonics, basis)]))
            flo.append(value)
            fhi.append(value)
    tight = 1.0 - margin
    if torque is not None:
        pi, tau_max = np.asarray(torque[0], float), np.broadcast_to(
            np.asarray(torque[1], float), (n,))
        tau_fun = ca.Function("tau", [qs, vs, as_], [ca.mtimes(regressor(qs, vs, as_), pi)])
        tau = tau_fun.map(samples)(qm, vm, am)
        fixed.append(ca.vec(tau))
        flo.append(np.tile(-tau_max * tight, samples))
        fhi.append(np.tile(tau_max * tight, samples))
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
            "ipopt.hessian_approximation": "limited-memory", "ipopt.max_iter": max_iter,
            "ipopt.tol": 1e-8, "ipopt.constr_viol_tol": 1e-10, "ipopt.bound_relax_factor": 0.0}
    opts.update(options or {})

    # the joint limits by an exchange method (semi-infinite constraints, Hettich & Kortanek
    # 1993): imposed on a coarse grid, checked on a fine one, the violated instants added and
    # the problem solved again from the last solution — IPOPT's limited-memory step costs
    # grow with the number of inequality rows (measured on the UR5: 1700 rows 0.3 s per
    # iteration, 450 rows 0.03 s), and the limits then hold on the fine grid too, not only
    # at the imposed instants
    check = initial.samples(CHECK_PER_HARMONIC * harmonics)
    ctimes = initial.samples(constraint_samples or _default_constraint_samples(harmonics))
    x0, rounds, iterations = initial.vector, 0, 0
    while True:
        rounds += 1
        rows, lo, hi = _limit_rows(n, harmonics, period, ctimes, lim, margin)
        g_lin = ca.mtimes(ca.DM(rows), x) if rows.size else ca.MX(0, 1)
        lbg, ubg = [lo, *flo], [hi, *fhi]
        solver = ca.nlpsol("excitation", "ipopt",
                           {"x": x, "f": objective, "g": ca.vertcat(g_lin, *fixed)}, opts)
        sol = solver(x0=x0, lbg=np.concatenate([np.ravel(b) for b in lbg]),
                     ubg=np.concatenate([np.ravel(b) for b in ubg]))
        stats = solver.stats()
        iterations += int(stats.get("iter_count", 0))
        xs = np.array(sol["x"]).ravel()
        if not np.all(np.isfinite(xs)):
            raise OptimizationError(f"excitation design: IPOPT returned non-finite amplitudes "
                                    f"({stats.get('return_status')})")
        traj = FourierTrajectory.from_vector(xs, n, harmonics, period)
        status = str(stats.get("return_status"))
        if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level",
                          "Maximum_Iterations_Exceeded"):
            raise OptimizationError(f"excitation design: IPOPT stopped with '{status}' after "
                                    f"{stats.get('iter_count')} iterations")
        violated = check[_violations(traj, check, lim) > FEASIBILITY_TOLERANCE]
        if violated.size == 0 or rounds == EXCHANGE_ROUNDS:
            break
        ctimes = np.unique(np.concatenate([ctimes, violated]))
        x0 = xs
    scaled = 1.0
    if violated.size:  # rounds or iterations ran out: shrink the amplitudes into the limits
        traj, scaled = _shrink_into_limits(traj, np.unique(np.concatenate([ctimes, check])),
                                           lim, margin)
    _check_feasible(traj, np.unique(np.concatenate([ctimes, check])), lim, sol, lbg, ubg,
                    status)
    stats = {**stats, "exchange_rounds": rounds, "iterations_total": iterations,
             "amplitude_scale": scaled}
    return ExcitationDesign(traj, initial, condition_number(regressor, traj, samples, columns),
                            start_condition, columns,
                            samples, ctimes, status, iterations,
                            float(sol["f"]), stats)


def excitation_for(mechanism, *, period: float, acceleration, friction=("viscous", "coulomb"),
                   harmonics: int = 5, samples: int = 60, lower=None, upper=None,
                   velocity=None, torque_limits: bool = False, mode: str = "vm",
                   **options) -> tuple[ExcitationDesign, BaseParameters]:
    """:func:`design_excitation` for a mechanism: its base regressor and its joint limits.

    The regressor is :func:`~casmbd.analysis.identification.regressor.joint_torque_regressor`
    with the ``friction`` laws, reduced to the base parameters
    (:func:`~casmbd.analysis.identification.base_parameters.base_parameters`, whose
    ``symbolic`` Y_b the design differentiates).  Limits not given are read per coordinate
    from the joints (:func:`joint_limits`: the URDF ``<limit>``); URDF gives no acceleration
    limit, so ``acceleration`` is required.  ``torque_limits``: also |τ| ≤ effort at the
    nominal parameters.  Other keywords go to :func:`design_excitation`.

    Returns
    -------
    (ExcitationDesign, BaseParameters)
    """
    reg = joint_torque_regressor(mechanism, friction, mode=mode)
    if reg.nq != reg.nv or len(reg.rows) != reg.nq:
        raise ModelError(f"excitation design of '{mechanism.name}': a fixed-base tree with "
                         "an effort on every coordinate is needed (the Fourier series moves "
                         "every coordinate independently)")
    base = base_parameters(reg)
    limits = joint_limits(mechanism)
    row = {name: k for k, name in enumerate(limits["names"])}
    picked = []
    for coordinate in reg.coordinate_names:
        joint = coordinate.rsplit(".", 1)[0]
        if joint not in row:
            raise ModelError(f"excitation design: coordinate '{coordinate}' is not the "
                             "coordinate of a revolute or prismatic joint")
        picked.append(row[joint])
    def given(value, key):
        return limits[key][picked] if value is None else value
    torque = None
    if torque_limits:
        effort = limits["effort"][picked]
        if not np.all(np.isfinite(effort)):
            missing = [reg.coordinate_names[k] for k in np.flatnonzero(~np.isfinite(effort))]
            raise ModelError(f"excitation design: no effort limit for {', '.join(missing)}")
        torque = (base.values(), effort)
    design = design_excitation(base.symbolic, period=period, harmonics=harmonics,
                               samples=samples, lower=given(lower, "lower"),
                               upper=given(upper, "upper"),
                               velocity=given(velocity, "velocity"), acceleration=acceleration,
                               torque=torque, columns=np.arange(base.rank), **options)
    design.coordinates = list(reg.coordinate_names)
    return design, base
