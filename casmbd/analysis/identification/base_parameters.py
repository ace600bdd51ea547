"""Base parameters: the identifiable linear combinations of the standard parameters.

Some columns of the regressor Y are zero at every state (a parameter without effect, e.g. the
mass of the first link of a fixed-base arm on its vertical axis) and others are linear
combinations of the rest at every state (the mass of a link and the first moments of its
parent regroup).  The base parameters are a minimal set of combinations π_b = K π with
Y π = Y_b π_b for all (q, v, a) (Gautier & Khalil, "Direct calculation of minimum set of
inertial parameters of serial robots", IEEE Trans. Robotics and Automation 6(3), 1990;
Gautier, "Numerical calculation of the base inertial parameters of robots", J. Robotic
Systems 8(4), 1991; Khalil & Dombre 2002, §10.3).

Numerically (Gautier 1991): stack Y at N random states consistent with the constraints,
W = [Y(x_1); …; Y(x_N)], and factor W P = Q R by QR with column pivoting (LAPACK ``geqp3``).
The rank r is the number of diagonal entries |R_ii| > τ |R_11| with the stated relative
tolerance τ (default :data:`RANK_TOLERANCE`).  With R = [R_1 R_2; 0 R_22] (R_1 r × r) the
first r pivoted columns are independent and the others are W_2 = W_1 R_1⁻¹ R_2 (up to R_22,
below the tolerance), so

    π_b = π_1 + R_1⁻¹ R_2 π_2,   K = [1  R_1⁻¹ R_2] Pᵀ,   Y_b = Y[:, base columns].

Random states make a structural dependency exact and an accidental one improbable; the gap
between the smallest kept and the largest dropped |R_ii| is reported (``gap``), so a
tolerance close to a genuine entry shows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla

from casmbd.analysis.identification.parameters import StandardParameters
from casmbd.analysis.identification.regressor import JointTorqueRegressor, joint_torque_regressor
from casmbd.errors import AnalysisError, ModelError

__all__ = ["RANK_TOLERANCE", "BaseParameters", "base_parameters", "random_states"]

#: default relative rank tolerance τ: |R_ii| ≤ τ |R_11| counts as zero (a structural
#: dependency leaves |R_ii| near machine precision times the column scales, ~1e-15; genuine
#: ones on a 6-axis arm stay above 1e-4)
RANK_TOLERANCE = 1e-8
#: coefficients of K below this (relative to 1) are printed as absent in the expressions
PRINT_TOLERANCE = 1e-10


@dataclass
class BaseParameters:
    """The base parameters of a regressor (module docstring).

    Attributes
    ----------
    standard : StandardParameters
        The standard parameters π (columns of Y).
    indices : ndarray of int
        The base columns: π_b's leading parameter in π, in pivot order.
    names : list of str
        The names of those columns (π_b[i] = π[indices[i]] + the regrouped ones).
    K : ndarray, shape (r, n_π)
        π_b = K π.
    rank : int
    tolerance : float
        The relative rank tolerance τ used.
    diagonal : ndarray
        |R_ii| / |R_11| of the pivoted QR (length min(N n_rows, n_π)).
    gap : float
        Smallest kept over largest dropped |R_ii| (inf when nothing was dropped).
    samples : int
        Number of random states stacked.
    expressions : list of str
        Each π_b[i] written in the standard parameters (``"link2.m + 0.425 link3.m"``).
    symbolic : casadi.Function
        Y_b(q, v, a) before compilation (for embedding: an OCP, the C export).
    """

    standard: StandardParameters
    indices: np.ndarray
    names: list[str]
    K: np.ndarray
    rank: int
    tolerance: float
    diagonal: np.ndarray
    gap: float
    samples: int
    expressions: list[str] = field(default_factory=list)
    symbolic: ca.Function | None = None

    def values(self, pi=None) -> np.ndarray:
        """π_b = K π (default the nominal π)."""
        pi = self.standard.values if pi is None else np.asarray(pi, float)
        return self.K @ pi

    def regressor(self, y) -> np.ndarray:
        """Y_b: the base columns of Y (one state or stacked)."""
        return np.asarray(y, float)[..., self.indices]

    def __len__(self) -> int:
        return self.rank


def _expression(row: np.ndarray, names: list[str]) -> str:
    parts = []
    for coef, name in zip(row, names, strict=True):
        if abs(coef) <= PRINT_TOLERANCE:
            continue
        sign = "-" if coef < 0 else "+"
        mag = abs(coef)
        term = name if abs(mag - 1.0) <= PRINT_TOLERANCE else f"{mag:.10g} {name}"
        parts.append(f"{sign} {term}")
    text = " ".join(parts)
    return text[2:] if text.startswith("+ ") else text


def random_states(reg: JointTorqueRegressor, n: int, seed: int | None = 0,
                  scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """N random states (q, v, a), each of shape (N, ·), consistent with the constraints.

    Scalar coordinates uniform in ±π·scale about the design pose (q₀ + U), velocities and
    accelerations uniform in ±scale; a floating base's quaternion uniform on the sphere.  With
    constraint equations q is brought onto C(q) = 0 by Gauss–Newton (minimum-norm steps from
    the perturbed design pose), v is drawn in the null space of C_q and a is the minimum-norm
    solution of C_q a = γ plus a null-space part.

    Raises
    ------
    AnalysisError
        When Gauss–Newton does not reach C = 0 (to 1e-12) from a perturbed pose.
    """
    rng = np.random.default_rng(seed)
    kin = reg.kinematics
    q0 = reg.initial_coordinates
    nq, nv = reg.nq, reg.nv
    floating = reg.floating_blocks
    scalar = np.ones(nq, bool)
    for start in floating:
        scalar[start:start + 7] = False
    qs, vs, accs = np.zeros((n, nq)), np.zeros((n, nv)), np.zeros((n, nv))
    closed = kin is not None
    for k in range(n):
        q = q0.copy()
        spread = (0.3 if closed else math.pi) * scale
        q[scalar] += rng.uniform(-spread, spread, int(scalar.sum()))
        for start in floating:
            q[start:start + 3] += rng.uniform(-1.0, 1.0, 3) * scale
            quat = rng.normal(size=4)
            q[start + 3:start + 7] = quat / np.linalg.norm(quat)
        v = rng.uniform(-scale, scale, nv)
        a = rng.uniform(-scale, scale, nv)
        if closed:
            for _ in range(50):
                c = np.asarray(kin(q, np.zeros(nv))[0], float).ravel()
                if np.max(np.abs(c), initial=0.0) <= 1e-13:
                    break
                jac_q = np.asarray(kin(q, np.zeros(nv))[3], float)
                q = q - np.linalg.lstsq(jac_q, c, rcond=None)[0]
                for start in floating:
                    q[start + 3:start + 7] /= np.linalg.norm(q[start + 3:start + 7])
            c, jac, _, _ = (np.asarray(x, float) for x in kin(q, np.zeros(nv)))
            if np.max(np.abs(c), initial=0.0) > 1e-12:
                raise AnalysisError(f"base parameters: random state {k}: Gauss-Newton did not "
                                    f"assemble the mechanism (|C| = {np.max(np.abs(c)):.3g})")
            _, sv, vt = np.linalg.svd(jac)
            rank = int(np.sum(sv > 1e-10 * max(sv.max(initial=0.0), 1.0)))
            null = vt[rank:].T
            v = null @ rng.uniform(-scale, scale, null.shape[1])
            gamma = np.asarray(kin(q, v)[2], float).ravel()
            a = np.linalg.lstsq(jac, gamma, rcond=None)[0] + null @ rng.uniform(
                -scale, scale, null.shape[1])
        qs[k], vs[k], accs[k] = q, v, a
    return qs, vs, accs


def base_parameters(regressor_or_mechanism, *, samples: int | None = None,
                    tolerance: float = RANK_TOLERANCE, seed: int | None = 0,
                    **regressor_options) -> BaseParameters:
    """The base parameters by QR with column pivoting of a random stacked regressor.

    Parameters
    ----------
    regressor_or_mechanism : JointTorqueRegressor or Mechanism
        A regressor of :func:`~casmbd.analysis.identification.regressor.
        joint_torque_regressor`, or a mechanism (its regressor built with
        ``regressor_options``: ``friction``, ``frame``, ``mode`` …).
    samples : int, optional
        Random states to stack (default ⌈3 n_π / n_rows⌉ + 20).
    tolerance : float
        Relative rank tolerance τ (module docstring; default :data:`RANK_TOLERANCE`).
    seed : int or None
        Seed of the random states.

    Returns
    -------
    BaseParameters
        Base columns, K with π_b = K π, rank, diagonal, gap, expressions, Y_b.

    Raises
    ------
    ModelError
        A tolerance outside (0, 1), fewer than one sample.
    """
    reg = regressor_or_mechanism
    if not isinstance(reg, JointTorqueRegressor):
        reg = joint_torque_regressor(reg, **regressor_options)
    elif regressor_options:
        raise ModelError(f"base_parameters: options {sorted(regressor_options)} apply when "
                         "a mechanism is given, not a regressor")
    if not (isinstance(tolerance, (int, float)) and 0.0 < tolerance < 1.0):
        raise ModelError(f"base_parameters: tolerance must be in (0, 1), got {tolerance!r}")
    n_pi, n_rows = len(reg.names), len(reg.rows)
    if samples is None:
        samples = math.ceil(3 * n_pi / max(n_rows, 1)) + 20
    if not (isinstance(samples, (int, np.integer)) and samples >= 1):
        raise ModelError(f"base_parameters: samples must be a positive integer, got "
                         f"{samples!r}")
    qs, vs, accs = random_states(reg, int(samples), seed)
    stacked = reg.stacked(qs, vs, accs)
    _, r_mat, perm = sla.qr(stacked, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r_mat))
    top = diag[0] if diag.size and diag[0] > 0 else 1.0
    rel = diag / top
    rank = int(np.sum(rel > tolerance)) if diag.size and diag[0] > 0 else 0
    gap = (rel[rank - 1] / rel[rank]) if 0 < rank < rel.size and rel[rank] > 0 else math.inf
    r1, r2 = r_mat[:rank, :rank], r_mat[:rank, rank:]
    coupling = sla.solve_triangular(r1, r2) if rank else np.zeros((0, n_pi - rank))
    k_mat = np.zeros((rank, n_pi))
    k_mat[:, perm[:rank]] = np.eye(rank)
    k_mat[:, perm[rank:]] = coupling
    indices = np.asarray(perm[:rank], dtype=int)
    names = [reg.names[i] for i in indices]
    q, v, a = (ca.MX.sym(s, n) for s, n in (("q", reg.nq), ("v", reg.nv), ("a", reg.nv)))
    y_b = reg.symbolic(q, v, a)[:, [int(i) for i in indices]]
    symbolic = ca.Function("base_regressor", [q, v, a], [y_b], ["q", "v", "a"], ["Yb"])
    return BaseParameters(reg.parameters, indices, names, k_mat, rank, float(tolerance), rel,
                          float(gap), int(samples),
                          [_expression(row, reg.names) for row in k_mat], symbolic)
