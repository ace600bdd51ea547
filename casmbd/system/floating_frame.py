"""Floating-frame equations of a modally reduced flexible body (lumped-mass invariants).

A flexible body carries a body frame (origin R, rotation A) and modal coordinates η.  Node i of
the lumped model (mass m_i, rotary inertia J_i about the node, body axes) sits at

    r_i = R + A u_i,   u_i = u_i0 + Φ_i η,                       (seed 002, eq. 5–26)

with Φ_i the nodal translations and Ψ_i the nodal small rotations of the component-mode-synthesis
base vectors (:class:`casmbd.model.modal.ModalData`: ``positions``, ``phi_t``, ``phi_r``).  With
the body-frame angular velocity ω̄ (ω = A ω̄; the plane: ω̄ = θ̇) the node velocity is
ṙ_i = Ṙ + A (ω̄ × u_i + Φ_i η̇) and the node frame turns with ω̄ + Ψ_i η̇ (body axes), so

    T = ½ Σ m_i |ṙ_i|² + ½ Σ (ω̄ + Ψ_i η̇)ᵀ J_i (ω̄ + Ψ_i η̇) = ½ wᵀ M(A, η) w,
    w = (Ṙ, ω̄, η̇)

(Shabana, *Dynamics of Multibody Systems*, 4th ed., 2013, ch. 5, the floating frame of
reference formulation; the rotary term is the first-order nodal rotation, exact in the plane).
Seed 002 decomposes M and the right-hand side "over a basis of invariant terms, which are computed
only once in the generation pass ... using a lumped mass approach" (eqs. 5–29 to 5–34).  The set
used here (d = 2 or 3 the dimension, n the number of modes, Φ_ik the column k of Φ_i):

=========  ==============================  ==========================================
invariant  definition                      use
=========  ==============================  ==========================================
m          Σ m_i                           M_RR = m 1
S0, S1     Σ m_i u_i0,  Σ m_i Φ_i          S(η) = S0 + S1 η (first moment)
P0         Σ m_i u_i0 u_i0ᵀ                P(η) = Σ m_i u_i u_iᵀ (pseudo-inertia)
P1[k]      Σ m_i u_i0 Φ_ikᵀ                  = P0 + Σ η_k (P1[k] + P1[k]ᵀ)
P2[k, l]   Σ m_i Φ_ik Φ_ilᵀ                    + Σ η_k η_l P2[k, l];  I_θθ = tr P 1 − P
Q0, Q1     Σ m_i u_i0 × Φ_ik,               I_θf(η) = Σ m_i ũ_i Φ_i = Q0 + Σ η_l Q1[l]
           Σ m_i Φ_il × Φ_ik
M_ff       Σ m_i Φ_iᵀ Φ_i = tr P2          flexible mass (or ModalData.mass)
J_r, J_Ψ   Σ J_i,  Σ J_i Ψ_i                rotary parts of M_ωω, M_ωf
Ψ J Ψ      Σ Ψ_iᵀ J_i Ψ_i                   rotary part of M_ff
=========  ==============================  ==========================================

(Shabana's Ī_θθ, Ī_θf, S̄, S̄_f; Q0, Q1 are the antisymmetric parts of P1, P2, kept separate for
clarity.)  The mass matrix in w = (Ṙ, ω̄, η̇) is

    M = [[m 1,  −A S̃(η),           A S1        ],
         [ ·,   I_θθ(η) + J_r,      I_θf(η) + J_Ψ],
         [ ·,   ·,                  M_ff + ΨJΨ  ]]

and the quadratic-velocity forces (M ẇ = Q_v + Q_e; Kane's generalized inertia forces of the
nodes, with b_i = ω̄ × (ω̄ × u_i) + 2 ω̄ × Φ_i η̇, W_k = Σ m_i u_i Φ_ikᵀ = P1[k] + Σ η_l P2[l, k],
D = Σ m_i u̇_i u_iᵀ = Σ η̇_k W_kᵀ, G = Σ η̇_l Q1[l]) are

    Q_R = −A (ω̄ × (ω̄ × S) + 2 ω̄ × S1 η̇)
    Q_ω = −ω̄ × (I_θθ ω̄) − 2 (tr D ω̄ − D ω̄) − ω̄ × (J_r ω̄ + J_Ψ η̇)
    Q_f,k = −(ω̄ᵀ W_k ω̄ − |ω̄|² tr W_k) − 2 (Gᵀ ω̄)_k

(Shabana, ch. 5, Newton–Euler form, written with the lumped invariants; the rotary part by the
Euler–Poincaré form d/dt ∂T/∂ω̄ + ω̄ × ∂T/∂ω̄ of T's rotary term).  In the plane, ω̄ = θ̇ ẑ,
x × y becomes the scalar x_x y_y − x_y y_x and u⊥ = ẑ × u:

    M = [[m 1, A S⊥, A S1], [·, tr P + J_r, I_θf + J_Ψ], [·, ·, M_ff + ΨJΨ]]
    Q_R = A (θ̇² S − 2 θ̇ (S1 η̇)⊥),  Q_θ = −2 θ̇ tr D,  Q_f = θ̇² tr W − 2 θ̇ Gᵀ,

which are Lagrange's M = ∂²T/∂q̇² and Q_v = ∂T/∂q − Ṁ q̇ for q = (R, θ, η).  In space w is not a
coordinate rate: with ω̄ = B(q) q̇ for a rotation parametrisation q, M_q = Bᵀ M B and
Q_v,q = Bᵀ (Q_v − M Ḃ q̇) (checked in tests/system/test_ffrf.py with Euler angles).  For Euler
parameters (ω̄ = 2 G(p) ṗ, B = diag(1, 2G, 1)) Ḃ q̇ = 0 (G(ṗ) ṗ = 0): on |p| = 1, Bᵀ M B equals
the Hessian of T(A(p), 2 G ṗ) exactly, and Bᵀ Q_v differs from AD's ∂T/∂q − Ṁ q̇ only along p,
which the normalisation constraint's multiplier absorbs (also checked in the tests).

``flexible_mass = "reduced"`` (issue 35): the η-independent and η-linear-coefficient inertia
come from the FE mass matrix M instead of the lumped nodes, through the rigid-body modes of the
mesh about the body origin (translations T_r, rotations R_r with the nodal rotational dofs;
ModalData.rigid_mass = [T_r R_r]ᵀ M [T_r R_r], ModalData.rigid_coupling = [T_r R_r]ᵀ M Φ):

    m 1 = T_rᵀ M T_r,  −S̃0 (plane S0⊥) = T_rᵀ M R_r,  I0 = R_rᵀ M R_r,
    S1 = T_rᵀ M Φ,     M_ωf(0) = R_rᵀ M Φ,            M_ff = Φᵀ M Φ,

so that M(A = 1, η = 0) = [T_r R_r Φ]ᵀ M [T_r R_r Φ], the Gram matrix of one mass metric,
positive definite for a basis of full rank (Shabana, ch. 5, the consistent-mass invariants
Ī_θθ = ∫ρ ũᵀũ, S̄_f = ∫ρ S dV).  Mixing lumped rigid and coupling invariants with the
consistent M_ff is not a Gram matrix and is indefinite when constraint modes carry rigid-like
motion (a tip constraint mode of a beam with interfaces at both ends turns about the root).
The η-dependent parts stay lumped: P1, P2 and Q1 (the change of the inertia tensor and of the
coupling with the deformation, zero at η = 0) are the lumped sums, which keeps Q_v the exact
Lagrange (plane) and Euler–Poincaré (space) forces of that M(η): the differences
I0 − (tr P0 1 − P0) and M_ωf(0) − Q0 are carried in J_r and J_Ψ, the only constants besides
P0 and Q0 through which they enter.  S(η) = S0 + S1 η is the exact consistent first moment
(gravity acts on it: the consistent modal gravity load S1ᵀ g).

Elastic and damping forces: Q_f += −K η − C η̇ with C = M_ff V diag(2 ζ_k ω_k) Vᵀ M_ff, V the
M_ff-normalised eigenvectors of (K, M_ff) — diag(2 ζ_k ω_k) for mass-normalised modes.

Geometric stiffness from every axial load (``stiffening``; issue 23 item 1, widened in issue 35
item 1): second-order axial kinematics, the foreshortening of Kane, Ryan & Banerjee (J. Guid.
Control Dyn. 10(2), 1987, the spin-up beam) and of Wallrapp's geometric-stiffening terms
(Wallrapp & Wiedemann, Nonlinear Dyn. 34, 2003; Schwertassek & Wallrapp, *Dynamik flexibler
Mehrkörpersysteme*, 1999, §6.6).  The linear modal model has no bending stiffness from axial
load: a beam spun above its first bending frequency diverges, and a column under an end load
never buckles.  For a beam whose nodes lie on the body x axis (u_i0 = x_i e_x) a node does not
keep its axial position when the beam bends: the arc between the reference node (the node at the
frame origin, x = 0, or the node nearest to it) and node i keeps its length, so

    ū_i(η) = u_i0 + Φ_i η + d_i(η),   d_i = −½ (ηᵀ F_i η) e_x,
    F_i = ± Σ_{elements e between the reference node and node i} Φ_eᵀ g_e Φ_e

(+ for nodes at larger x, − for nodes at smaller x: both move toward the reference), with g_e
the slope kernel ∫ w'ᵀ w' dx of the element's lateral interpolation, exact for it — Hermite
(Przemieniecki, *Theory of Matrix Structural Analysis*, 1968, §15.2; Cook et al., *Concepts
and Applications of Finite Element Analysis*, 4th ed., ch. 18)

    g_e = 1/(30 h) [[36, 3h, −36, 3h], [3h, 4h², −3h, −h²], [−36, −3h, 36, −3h],
                    [3h, −h², −3h, 4h²]]   on (v_1, θ_1, v_2, θ_2)

in each bending plane ((v, θz) and (w, −θy)), or 1/h [[1, −1], [−1, 1]] on v for nodes without
rotations — the geometric stiffness of the element per unit axial force.  Every consumer of a node
position (joints, markers, forces and springs at nodes, node outputs) gets r_i = R + A ū_i(η), so
the reaction of a joint at a node and an applied nodal force give their geometric stiffness
exactly, by AD (λᵀ C_qq, ∂(J_iᵀ F)/∂q: a column under an end load P sees −P F_tip).  Inertial
loads enter through the kinetic energy of the foreshortened nodes, T = T_lin + ΔT,

    ΔT = ½ Σ m_i (|w_i + c_i|² − |w_i|²),   w_i = v̄_R + ω̄ × (u_i0 + Φ_i η) + Φ_i η̇,
    c_i = ω̄ × d_i + ḋ_i,   v̄_R = Aᵀ Ṙ   (body axes),

exact for the lumped nodes and summed over them (:meth:`FlexibleBody.foreshortening_energy`).
Its part of second order in (η, η̇) is the invariant form

    ΔT₂ = v̄_R · (ω̄ × e_x σ + e_x σ̇) + s(ω̄) π,
    σ = −½ ηᵀ S_G η,  π = −½ ηᵀ P_G η,  S_G = Σ m_i F_i,  P_G = Σ m_i x_i F_i,

s = θ̇² (plane) or ω̄_y² + ω̄_z² (space) ((ω̄ × u_i0) · ḋ_i = 0 on the axis): the Ṙ terms give
the axial load of the frame's acceleration, −s(ω̄) P_G η the centrifugal geometric stiffness,
equal to the former K_G1 = Σ_e K_G,e(N̂_e) with N̂_e = Σ_{outboard j} m_j x_j
(P_G = Σ_e g_e Σ_{outboard} m_j x_j).  ΔT₂ alone would do for the linearisation, but its mass
matrix is not of the form Jᵀ diag(m) J: the O(η) terms of the Ṙ–η̇ block are kept and those of
the η̇–η̇ block (order 3 in T) dropped, and M turned indefinite at modal coordinates of 1e-2
(millimetres on the 1 m pendulum of tests/system/test_geometric_stiffness.py); the node sums
cost N (n² + 2 d n) operations and keep M positive semi-definite at any η.  The mass
matrix of ΔT (its Hessian in the velocities) and its quadratic-velocity forces
∂ΔT/∂q − (∂²ΔT/∂q̇∂q) q̇ come by AD in the body's coordinates
(:mod:`casmbd.system.flexible_descriptions`).  Gravity acts on the first moment of the
foreshortened nodes, S(η) = S0 + S1 η + σ e_x.  Not covered: the second-order rotations of the
nodes (rotary inertia J_i), meshes off the body x axis (an imported FE model's own
geometric-stiffness matrices).

Everything here is a CasADi SX expression of symbols the caller gives; the invariants are DM
constants, so the expressions are built once and AD does the rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.errors import ModelError
from casmbd.lazy import lazy_module
from casmbd.model.modal import ModalData
from casmbd.model.rotations import rotation_matrix

__all__ = ["FlexibleBody", "Invariants", "foreshortening_matrices", "invariants",
           "planar_rotation"]

sla = lazy_module("scipy.linalg")

FLEXIBLE_MASS = ("lumped", "reduced")


@dataclass(frozen=True, eq=False)
class Invariants:
    """The lumped-mass invariants of one flexible body (module docstring for the definitions).

    ``d`` = dimension, ``c`` = 1 (plane) or 3 (space) rotation components, ``n`` = modes.
    With ``flexible_mass = "reduced"`` the mass, S0 and S1 are those of the FE mass matrix and
    J_r, J_psi carry the rotary inertia plus the difference between the consistent and lumped
    I0 and M_ωf(0) (module docstring); the other sums stay lumped.

    Attributes
    ----------
    dimension : int
    mass : float
        Σ m_i [kg].
    S0 : (d,) ; S1 : (d, n)
        First moments Σ m_i u_i0, Σ m_i Φ_i.
    P0 : (d, d) ; P1 : (d, d, n) ; P2 : (d, d, n, n)
        Pseudo-inertia invariants: P1[:, :, k] = Σ m_i u_i0 Φ_ikᵀ,
        P2[:, :, k, l] = Σ m_i Φ_ik Φ_ilᵀ.
    Q0 : (c, n) ; Q1 : (c, n, n)
        Q0[:, k] = Σ m_i u_i0 × Φ_ik, Q1[:, k, l] = Σ m_i Φ_il × Φ_ik.
    J_r : (c, c) ; J_psi : (c, n) ; psi_j_psi : (n, n)
        Rotary inertia invariants Σ J_i, Σ J_i Ψ_i, Σ Ψ_iᵀ J_i Ψ_i.
    M_ff : (n, n)
        Flexible mass used (lumped Σ m_i Φ_iᵀΦ_i + ΨJΨ, or ModalData.mass).
    K, C : (n, n)
        Reduced stiffness and modal damping.
    K_G1 : (n, n) or None
        Centrifugal geometric stiffness per unit s(ω̄), P_G = Σ m_i x_i F_i (None: no
        stiffening).
    positions : (N, d) ; phi_t : (N, d, n) ; phi_r : (N, c, n)
        Node data for the node outputs.
    node_names : dict[str, int]
    """

    dimension: int
    mass: float
    S0: np.ndarray
    S1: np.ndarray
    P0: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    Q0: np.ndarray
    Q1: np.ndarray
    J_r: np.ndarray
    J_psi: np.ndarray
    psi_j_psi: np.ndarray
    M_ff: np.ndarray
    K: np.ndarray
    C: np.ndarray
    K_G1: np.ndarray | None
    positions: np.ndarray
    phi_t: np.ndarray
    phi_r: np.ndarray
    node_names: dict
    foreshortening: np.ndarray | None = None
    S_G: np.ndarray | None = None
    node_masses: np.ndarray | None = None

    @property
    def n_modes(self) -> int:
        """Number of modal coordinates."""
        return int(self.S1.shape[1])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b along axis 1 (shape (N, d, ...)); (N, 1, ...) scalar cross in the plane."""
    if a.shape[1] == 3:
        return np.cross(a, b, axis=1)
    return (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])[:, None]


def _array(value, shape: tuple, where: str) -> np.ndarray:
    try:
        arr = np.asarray(value, float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{where}: expected numbers of shape {shape}") from exc
    if arr.shape != shape:
        raise ModelError(f"{where}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{where}: non-finite value")
    return arr


def _checked(modal: ModalData, where: str) -> tuple[np.ndarray, ...]:
    """(u0, m, J, Φ, Ψ, K, M_reduced) of ``modal`` with shapes and values checked."""
    dim = modal.dimension
    if dim not in (2, 3):
        raise ModelError(f"{where} field 'dimension': expected 2 or 3, got {dim!r}")
    u0 = np.asarray(modal.positions, float)
    if u0.ndim != 2 or u0.shape[1] != dim:
        raise ModelError(f"{where} field 'positions': expected shape (nodes, {dim}), "
                         f"got {u0.shape}")
    nn, c = u0.shape[0], 1 if dim == 2 else 3
    phi = np.asarray(modal.phi_t, float)
    if phi.ndim != 3 or phi.shape[:2] != (nn, dim):
        raise ModelError(f"{where} field 'phi_t': expected shape ({nn}, {dim}, modes), "
                         f"got {phi.shape}")
    n = phi.shape[2]
    u0 = _array(u0, (nn, dim), f"{where} field 'positions'")
    phi = _array(phi, (nn, dim, n), f"{where} field 'phi_t'")
    psi = _array(modal.phi_r, (nn, n) if dim == 2 else (nn, 3, n), f"{where} field 'phi_r'")
    psi = psi.reshape(nn, c, n)
    m = _array(modal.masses, (nn,), f"{where} field 'masses'")
    jn = _array(modal.inertias, (nn,) if dim == 2 else (nn, 3, 3), f"{where} field 'inertias'")
    jn = jn.reshape(nn, c, c)
    if np.any(m < 0.0) or m.sum() <= 0.0:
        raise ModelError(f"{where} field 'masses': nodal masses must be >= 0 with a positive sum")
    if np.any(np.linalg.eigvalsh(0.5 * (jn + jn.transpose(0, 2, 1))) < -1e-12 * max(
            1.0, float(np.abs(jn).max()))):
        raise ModelError(f"{where} field 'inertias': a nodal rotary inertia is not positive "
                         "semi-definite")
    k = _array(modal.stiffness, (n, n), f"{where} field 'stiffness'")
    mr = _array(modal.mass, (n, n), f"{where} field 'mass'")
    return u0, m, jn, phi, psi, 0.5 * (k + k.T), 0.5 * (mr + mr.T)


def _damping(K: np.ndarray, M: np.ndarray, ratio, where: str) -> np.ndarray:
    """C = M V diag(2 ζ_k ω_k) Vᵀ M, V the M-normalised eigenvectors of K V = M V Λ."""
    n = K.shape[0]
    zeta = np.broadcast_to(np.asarray(ratio, float), (n,)) if np.ndim(ratio) == 0 else \
        np.asarray(ratio, float)
    if zeta.shape != (n,) or not np.all(np.isfinite(zeta)) or np.any(zeta < 0.0):
        raise ModelError(f"{where} field 'damping_ratio': expected a number >= 0 or {n} of them, "
                         f"got {ratio!r}")
    if not np.any(zeta) or n == 0:
        return np.zeros((n, n))
    lam, vec = sla.eigh(K, M)
    omega = np.sqrt(np.clip(lam, 0.0, None))
    mv = M @ vec
    return mv @ np.diag(2.0 * zeta * omega) @ mv.T


def _foreshortening(u0, phi, psi, where: str) -> np.ndarray:
    """F_i (N, n, n) of d_i = −½ (ηᵀ F_i η) e_x for a beam along the body x axis (module
    docstring): the slope kernels g_e summed from the reference node (nearest to x = 0)."""
    dim, n = u0.shape[1], phi.shape[2]
    scale = max(1.0, float(np.abs(u0).max()))
    if np.any(np.abs(u0[:, 1:]) > 1e-12 * scale):
        raise ModelError(f"{where}: geometric stiffening needs the nodes on the body x axis "
                         "(a beam along x; the geometric stiffness of other meshes is not "
                         "built)")
    order = np.argsort(u0[:, 0], kind="stable")
    x = u0[order, 0]
    if np.any(np.diff(x) <= 0.0):
        raise ModelError(f"{where}: geometric stiffening needs distinct node positions along x")
    hermite = np.any(psi)
    planes = [(1, 2, 1.0)] if dim == 2 else [(1, 2, 1.0), (2, 1, -1.0)]
    kernels = []
    for j in range(len(x) - 1):
        h, a, b = x[j + 1] - x[j], order[j], order[j + 1]
        ge = np.zeros((n, n))
        for trans, rot, sign in planes:
            if hermite:
                ke = 1.0 / (30.0 * h) * np.array(
                    [[36, 3 * h, -36, 3 * h], [3 * h, 4 * h * h, -3 * h, -h * h],
                     [-36, -3 * h, 36, -3 * h], [3 * h, -h * h, -3 * h, 4 * h * h]])
                rrow = 0 if dim == 2 else rot
                basis = np.vstack([phi[a, trans], sign * psi[a, rrow], phi[b, trans],
                                   sign * psi[b, rrow]])
            else:
                ke = 1.0 / h * np.array([[1.0, -1.0], [-1.0, 1.0]])
                basis = np.vstack([phi[a, trans], phi[b, trans]])
            ge += basis.T @ ke @ basis
        kernels.append(0.5 * (ge + ge.T))
    ref = int(np.argmin(np.abs(x)))
    F = np.zeros((len(x), n, n))
    for j in range(ref, len(x) - 1):  # outward to larger x: shortening toward the reference
        F[order[j + 1]] = F[order[j]] + kernels[j]
    for j in range(ref - 1, -1, -1):  # to smaller x: the opposite sign
        F[order[j]] = F[order[j + 1]] - kernels[j]
    return F


def foreshortening_matrices(modal: ModalData, name: str = "flexible body") -> np.ndarray:
    """F_i (N, n, n) of the foreshortening d_i = −½ (ηᵀ F_i η) e_x of a beam along the body x
    axis (module docstring), for drawing and checks.

    Raises
    ------
    ModelError
        Malformed modal data, nodes off the x axis.
    """
    where = f"flexible body '{name}'"
    u0, _, _, phi, psi, _, _ = _checked(modal, where)
    return _foreshortening(u0, phi, psi, where)


def _consistent_rigid(modal: ModalData, P0: np.ndarray, Q0: np.ndarray, where: str):
    """(m, S0, S1, J_r, J_Ψ) of ``flexible_mass = "reduced"`` from ModalData.rigid_mass and
    rigid_coupling (module docstring): J_r = I0 − (tr P0 1 − P0), J_Ψ = M_ωf(0) − Q0 carry
    the difference to the lumped P0, Q0 so that M(1, 0) = [T_r R_r Φ]ᵀ M [T_r R_r Φ]."""
    dim, n = modal.dimension, Q0.shape[1]
    nr = 3 if dim == 2 else 6
    if getattr(modal, "rigid_coupling", None) is None:
        raise ModelError(f"{where} field 'flexible_mass': 'reduced' needs the FE mass "
                         "matrix's rigid-body data (ModalData.rigid_mass and rigid_coupling, "
                         "from casmbd.model.modal_reduction); these modal data have none")
    rigid = _array(modal.rigid_mass, (nr, nr), f"{where} field 'rigid_mass'")
    coupling = _array(modal.rigid_coupling, (nr, n), f"{where} field 'rigid_coupling'")
    rigid = 0.5 * (rigid + rigid.T)
    t, r = slice(0, dim), slice(dim, nr)
    mass = float(np.trace(rigid[t, t])) / dim
    scale = max(abs(mass), 1e-300)
    tol = 1e-8
    if mass <= 0.0 or np.abs(rigid[t, t] - mass * np.eye(dim)).max() > tol * scale:
        raise ModelError(f"{where} field 'rigid_mass': the FE mass matrix does not give one "
                         f"positive mass in every direction (T_rᵀ M T_r = "
                         f"{np.array2string(rigid[t, t], precision=4)}): not a rigid-body mass")
    mtr = rigid[t, r]
    if dim == 2:  # T_rᵀ M R_z = S0⊥ = (−S0_y, S0_x)
        S0 = np.array([mtr[1, 0], -mtr[0, 0]])
        J_r = rigid[r, r] - np.trace(P0)
    else:  # T_rᵀ M R_r = −S̃0: antisymmetric
        lever = max(1.0, float(np.abs(modal.positions).max()))
        if np.abs(mtr + mtr.T).max() > tol * scale * lever:
            raise ModelError(f"{where} field 'rigid_mass': the translation–rotation block of "
                             "the FE mass matrix is not antisymmetric (not the first moment of "
                             "a rigid body)")
        skew = 0.5 * (mtr - mtr.T)
        S0 = np.array([skew[1, 2], skew[2, 0], skew[0, 1]])
        J_r = rigid[r, r] - (np.trace(P0) * np.eye(3) - P0)
    return mass, S0, coupling[t].copy(), 0.5 * (J_r + J_r.T), coupling[r] - Q0


#: a body mass matrix at η = 0 is indefinite when its Jacobi-scaled smallest eigenvalue is
#: below minus this (rounding of a Gram matrix stays far above)
INDEFINITE_RTOL = 1e-10


def _check_definite(mass, S0, S1, P0, Q0, J_r, J_psi, M_ff, flexible_mass: str,
                    where: str) -> None:
    """Refuse invariants whose body mass matrix M(1, 0) (module docstring) is indefinite: a
    negative eigenvalue of the Jacobi-scaled matrix below −:data:`INDEFINITE_RTOL` (a zero one,
    a massless motion, is left to the mechanism's check: joints may carry it)."""
    d = S0.shape[0]
    if d == 2:
        m_rw = np.array([[-S0[1]], [S0[0]]])
        m_ww = np.atleast_2d(np.trace(P0) + J_r)
    else:
        m_rw = -np.array([[0.0, -S0[2], S0[1]], [S0[2], 0.0, -S0[0]], [-S0[1], S0[0], 0.0]])
        m_ww = np.trace(P0) * np.eye(3) - P0 + J_r
    m_wf = Q0 + J_psi
    full = np.block([[mass * np.eye(d), m_rw, S1], [m_rw.T, m_ww, m_wf],
                     [S1.T, m_wf.T, M_ff]])
    diag = np.diag(full)
    if np.any(diag <= 0.0):
        return  # a massless direction: singular at worst, the mechanism's check names it
    scaled = full / np.sqrt(np.outer(diag, diag))
    eig = np.linalg.eigvalsh(0.5 * (scaled + scaled.T))
    if eig[0] < -INDEFINITE_RTOL:
        raise ModelError(
            f"{where}: the body mass matrix at zero deformation is indefinite (smallest "
            f"eigenvalue {eig[0]:.3g} of the Jacobi-scaled matrix, flexible_mass = "
            f"'{flexible_mass}'): a motion with negative kinetic energy, not a massless one. "
            "The rigid-body, coupling and flexible mass invariants do not come from one mass "
            "matrix (modal data whose 'mass' does not match its nodal masses and modes, or "
            "'rigid_mass'/'rigid_coupling' from another mesh)")


def invariants(modal: ModalData, *, damping_ratio=0.0, flexible_mass: str = "lumped",
               stiffening: bool = False, name: str = "flexible body") -> Invariants:
    """Compute the lumped-mass invariants of a flexible body once, with numpy.

    Parameters
    ----------
    modal : casmbd.model.modal.ModalData
        Node positions, masses, rotary inertias, modes (translations ``phi_t``, rotations
        ``phi_r``), reduced stiffness and mass.
    damping_ratio : float or array_like (n,)
        Modal damping ratio ζ per mode (C = diag(2 ζ_k ω_k) for mass-normalised modes).
    flexible_mass : {"lumped", "reduced"}
        The lumped model (every invariant a sum over the nodes, M_ff = Σ m_i Φ_iᵀΦ_i +
        Σ Ψ_iᵀ J_i Ψ_i; the default) or the FE mass matrix for the inertia at η = 0: m, S0,
        I0, S1, M_ωf(0) from ModalData.rigid_mass and rigid_coupling and M_ff =
        ModalData.mass (Φᵀ M Φ, the identity for mass-normalised modes; consistent with the
        reduced frequencies); the η-dependent invariants P1, P2, Q1 stay lumped (module
        docstring).
    stiffening : bool
        Second-order axial kinematics (foreshortening, module docstring): the geometric
        stiffness of every axial load (beam along the body x axis).
    name : str
        Body name for messages.

    Returns
    -------
    Invariants

    Raises
    ------
    ModelError
        Malformed modal data (naming the body and field), a bad damping ratio or
        ``flexible_mass``, stiffening of nodes off the x axis, "reduced" without the FE
        rigid-body data, a body mass matrix at η = 0 that is indefinite.
    """
    where = f"flexible body '{name}'"
    if flexible_mass not in FLEXIBLE_MASS:
        raise ModelError(f"{where} field 'flexible_mass': expected one of {FLEXIBLE_MASS}, got "
                         f"{flexible_mass!r}")
    u0, m, jn, phi, psi, K, m_red = _checked(modal, where)
    S0 = m @ u0
    S1 = np.einsum("i,iak->ak", m, phi)
    P0 = np.einsum("i,ia,ib->ab", m, u0, u0)
    P1 = np.einsum("i,ia,ibk->abk", m, u0, phi)
    P2 = np.einsum("i,iak,ibl->abkl", m, phi, phi)
    u0e = np.broadcast_to(u0[:, :, None], phi.shape)
    Q0 = np.einsum("i,iak->ak", m, _cross(u0e, phi))
    # Q1[:, k, l] = Σ m_i Φ_il × Φ_ik
    Q1 = np.einsum("i,iakl->akl", m, _cross(phi[:, :, None, :], phi[:, :, :, None]))
    J_r = jn.sum(axis=0)
    J_psi = np.einsum("iab,ibk->ak", jn, psi)
    psi_j_psi = np.einsum("iak,iab,ibl->kl", psi, jn, psi)
    lumped = np.einsum("aakl->kl", P2) + psi_j_psi
    M_ff = 0.5 * (lumped + lumped.T) if flexible_mass == "lumped" else m_red
    if M_ff.size and np.linalg.eigvalsh(M_ff)[0] <= 0.0:
        raise ModelError(f"{where}: the flexible mass matrix ({flexible_mass}) is not positive "
                         "definite (a mode moves no mass)")
    mass = float(m.sum())
    if flexible_mass == "reduced":
        mass, S0, S1, J_r, J_psi = _consistent_rigid(modal, P0, Q0, where)
    _check_definite(mass, S0, S1, P0, Q0, J_r, J_psi, M_ff, flexible_mass, where)
    C = _damping(K, M_ff, damping_ratio, where)
    F = _foreshortening(u0, phi, psi, where) if stiffening else None
    K_G1 = np.einsum("i,i,ikl->kl", m, u0[:, 0], F) if stiffening else None
    S_G = np.einsum("i,ikl->kl", m, F) if stiffening else None
    return Invariants(modal.dimension, mass, S0, S1, P0, P1, P2, Q0, Q1, J_r, J_psi,
                      psi_j_psi, M_ff, K, C, K_G1, u0, phi, psi,
                      dict(getattr(modal, "node_names", {}) or {}), foreshortening=F, S_G=S_G,
                      node_masses=m if stiffening else None)


def planar_rotation(theta) -> ca.SX:
    """A(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]."""
    c, s = ca.cos(theta), ca.sin(theta)
    return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))


def _dm(arr: np.ndarray) -> ca.DM:
    return ca.DM(np.asarray(arr, float))


def _flat(arr: np.ndarray) -> ca.DM:
    """A (…, n) array as the DM (prod(…), n) whose columns are the column-major slices."""
    arr = np.asarray(arr, float)
    return _dm(arr.reshape(int(np.prod(arr.shape[:-1])), arr.shape[-1], order="F"))


def _perp(vec):
    return ca.vertcat(-vec[1], vec[0])


class FlexibleBody:
    """CasADi expressions of a flexible body in a floating frame (module docstring).

    Inputs are SX expressions: ``A`` the rotation matrix (2×2 or 3×3, body → global), ``eta``
    and ``etadot`` (n), ``Rdot`` (d), ``omega`` the body-frame angular velocity ω̄ (a scalar θ̇
    in the plane, 3 in space).  Velocity order w = (Ṙ, ω̄, η̇), size d + c + n.

    Parameters
    ----------
    inv : Invariants
        From :func:`invariants`.
    """

    def __init__(self, inv: Invariants):
        self.inv = inv
        self.dimension = d = inv.dimension
        self.rotations = c = 1 if d == 2 else 3
        self.n_modes = n = inv.n_modes
        self.size = d + c + n
        self._S0, self._S1 = _dm(inv.S0), _dm(inv.S1)
        self._P0, self._P1 = _dm(inv.P0), _flat(inv.P1)
        # W-part: column k = vec Σ_l P2[:, :, l, k] η_l  → contract P2ᵀ(k, l) over l
        self._P2 = _flat(inv.P2.transpose(0, 1, 3, 2).reshape(d, d, n, n))
        self._Q0, self._Q1 = _dm(inv.Q0), _flat(inv.Q1)
        self._trace = _dm(np.eye(d).reshape(1, -1))
        self._Jr, self._Jpsi, self._Mff = _dm(inv.J_r), _dm(inv.J_psi), _dm(inv.M_ff)
        self._K, self._C = _dm(inv.K), _dm(inv.C)
        self.stiffening = inv.foreshortening is not None
        if self.stiffening:
            self._SG = _dm(inv.S_G)
        self._node_sums = None

    # ------------------------------------------------------------------ invariant sums
    def _first_moment(self, eta) -> ca.SX:
        """S(η) = S0 + S1 η."""
        return self._S0 + ca.mtimes(self._S1, eta)

    def first_moment(self, eta) -> ca.SX:
        """Σ m_i ū_i(η) = S0 + S1 η (+ σ(η) e_x with stiffening): the first moment of the
        (foreshortened) nodes, on which gravity acts."""
        first = self._first_moment(eta)
        if not self.stiffening:
            return first
        return first + ca.vertcat(self._axial_sum(self._SG, eta), ca.SX(self.dimension - 1, 1))

    @staticmethod
    def _axial_sum(F, eta) -> ca.SX:
        """−½ ηᵀ F η."""
        return -0.5 * ca.bilin(F, eta, eta)

    def _w_matrix(self, eta) -> ca.SX:
        """(d², n): column k = vec W_k, W_k = P1[k] + Σ_l η_l P2[l, k]."""
        d, n = self.dimension, self.n_modes
        if n == 0:
            return ca.SX(d * d, 0)
        return self._P1 + ca.reshape(ca.mtimes(self._P2, eta), d * d, n)

    def pseudo_inertia(self, eta) -> ca.SX:
        """P(η) = Σ m_i u_i u_iᵀ = P0 + Σ η_k (P1[k] + P1[k]ᵀ) + Σ η_k η_l P2[k, l]."""
        d = self.dimension
        if self.n_modes == 0:
            return ca.SX(self._P0)
        lin = ca.reshape(ca.mtimes(self._P1, eta), d, d)
        quad = ca.reshape(ca.mtimes(ca.reshape(ca.mtimes(self._P2, eta), d * d, self.n_modes),
                                    eta), d, d)
        return self._P0 + lin + lin.T + quad

    def _coupling(self, eta) -> ca.SX:
        """I_θf(η) = Σ m_i ũ_i Φ_i = Q0 + Σ_l η_l Q1[:, :, l] (c × n)."""
        c, n = self.rotations, self.n_modes
        if n == 0:
            return ca.SX(c, 0)
        return self._Q0 + ca.reshape(ca.mtimes(self._Q1, eta), c, n)

    # ------------------------------------------------------------------ inertia
    def mass_matrix(self, A, eta) -> ca.SX:
        """M(A, η) in w = (Ṙ, ω̄, η̇) (module docstring), symmetric, size d + c + n; of the
        linear kinematics (T_lin: the foreshortening's ΔT is added by the descriptions)."""
        d, inv = self.dimension, self.inv
        S = self._first_moment(eta)
        P = self.pseudo_inertia(eta)
        if d == 2:
            m_rw = ca.mtimes(A, _perp(S))
            m_ww = ca.trace(P) + self._Jr
        else:
            m_rw = -ca.mtimes(A, ca.skew(S))
            m_ww = ca.trace(P) * ca.SX.eye(3) - P + self._Jr
        m_rf = ca.mtimes(A, self._S1)
        m_wf = self._coupling(eta) + self._Jpsi
        top = ca.horzcat(inv.mass * ca.SX.eye(d), m_rw, m_rf)
        mid = ca.horzcat(m_rw.T, m_ww, m_wf)
        bot = ca.horzcat(m_rf.T, m_wf.T, ca.SX(self._Mff))
        return ca.vertcat(top, mid, bot)

    def kinetic_energy(self, A, eta, Rdot, omega, etadot) -> ca.SX:
        """T = ½ wᵀ M(A, η) w with w = (Ṙ, ω̄, η̇) (+ ΔT with stiffening: module docstring)."""
        w = ca.vertcat(Rdot, omega, etadot)
        lin = 0.5 * ca.bilin(self.mass_matrix(A, eta), w, w)
        if not self.stiffening:
            return lin
        return lin + self.foreshortening_energy(A, eta, Rdot, omega, etadot)

    def quadratic_velocity_forces(self, A, eta, omega, etadot) -> ca.SX:
        """Q_v(A, η, ω̄, η̇) with M ẇ = Q_v + Q_e (module docstring; size d + c + n), of T_lin.

        In the plane these are Lagrange's ∂T/∂q − Ṁ q̇ for q = (R, θ, η).
        """
        S = self._first_moment(eta)
        wm = self._w_matrix(eta)
        tr_w = ca.mtimes(self._trace, wm)  # (1, n)
        s1e = ca.mtimes(self._S1, etadot)
        g = ca.reshape(ca.mtimes(self._Q1, etadot), self.rotations, self.n_modes) \
            if self.n_modes else ca.SX(self.rotations, 0)
        tr_d = ca.mtimes(tr_w, etadot)
        if self.dimension == 2:
            th = omega
            q_r = ca.mtimes(A, th ** 2 * S - 2.0 * th * _perp(s1e))
            q_w = -2.0 * th * tr_d
            q_f = th ** 2 * tr_w.T - 2.0 * th * g.T
            return ca.vertcat(q_r, q_w, q_f)
        om = omega
        P = self.pseudo_inertia(eta)
        inertia = ca.trace(P) * ca.SX.eye(3) - P
        dmat = ca.reshape(ca.mtimes(wm, etadot), 3, 3).T if self.n_modes else ca.SX(3, 3)
        q_r = -ca.mtimes(A, ca.cross(om, ca.cross(om, S)) + 2.0 * ca.cross(om, s1e))
        spin = ca.mtimes(inertia + self._Jr, om) + ca.mtimes(self._Jpsi, etadot)
        q_w = -ca.cross(om, spin) - 2.0 * (tr_d * om - ca.mtimes(dmat, om))
        oo = ca.vec(ca.mtimes(om, om.T))
        q_f = -(ca.mtimes(wm.T, oo) - ca.dot(om, om) * tr_w.T) - 2.0 * ca.mtimes(g.T, om)
        return ca.vertcat(q_r, q_w, q_f)

    # ------------------------------------------------------------------ elastic forces
    def stiffening_factor(self, omega) -> ca.SX:
        """s(ω̄) = θ̇² (plane) or ω̄_y² + ω̄_z² (space) = |ω̄ × e_x|²."""
        if self.dimension == 2:
            return omega ** 2
        return omega[1] ** 2 + omega[2] ** 2

    def _transport(self, eta, omega, etadot) -> ca.SX:
        """Σ m_i c_i = ω̄ × e_x σ + e_x σ̇ (body axes): ∂ΔT/∂v̄_R."""
        sigma = self._axial_sum(self._SG, eta)
        sigma_dot = -ca.bilin(self._SG, eta, etadot)
        if self.dimension == 2:
            return ca.vertcat(sigma_dot, omega * sigma)
        return ca.vertcat(sigma_dot, omega[2] * sigma, -omega[1] * sigma)

    def foreshortening_energy(self, A, eta, Rdot, omega, etadot) -> ca.SX:
        """ΔT = ½ Σ m_i (|w_i + c_i|² − |w_i|²), exact for the lumped nodes (module docstring;
        w_i = v̄_R + ω̄ × (u_i0 + Φ_i η) + Φ_i η̇ the linear node velocity, c_i = ω̄ × d_i + ḋ_i,
        both in body axes); its second-order part is v̄_R · (ω̄ × e_x σ + e_x σ̇) + s(ω̄) π.
        Zero without stiffening."""
        if not self.stiffening:
            return ca.SX(0.0)
        inv, d, n = self.inv, self.dimension, self.n_modes
        count = inv.positions.shape[0]
        if self._node_sums is None:
            self._node_sums = (_dm(inv.foreshortening.reshape(count * n, n)),
                               _dm(inv.phi_t.reshape(count * d, n)), _dm(inv.positions.T),
                               _dm(inv.node_masses))
        F, phi, u0, mass = self._node_sums
        slopes = ca.reshape(ca.mtimes(F, eta), n, count)     # column i: F_i η
        delta = -0.5 * ca.mtimes(slopes.T, eta)              # δ_i, d_i = δ_i e_x
        delta_dot = -ca.mtimes(slopes.T, etadot)
        u = u0 + ca.reshape(ca.mtimes(phi, eta), d, count)
        rel = ca.reshape(ca.mtimes(phi, etadot), d, count)
        vbar = ca.mtimes(A.T, Rdot)
        if d == 2:
            w_x = vbar[0] - omega * u[1, :] + rel[0, :]
            w_y = vbar[1] + omega * u[0, :] + rel[1, :]
            along = omega * w_y                              # w_i · (ω̄ × e_x)
        else:
            om = omega
            w_x = vbar[0] + om[1] * u[2, :] - om[2] * u[1, :] + rel[0, :]
            w_y = vbar[1] + om[2] * u[0, :] - om[0] * u[2, :] + rel[1, :]
            w_z = vbar[2] + om[0] * u[1, :] - om[1] * u[0, :] + rel[2, :]
            along = om[2] * w_y - om[1] * w_z
        per_node = (along.T * delta + w_x.T * delta_dot
                    + 0.5 * (self.stiffening_factor(omega) * delta ** 2 + delta_dot ** 2))
        return ca.dot(mass, per_node)

    def elastic_forces(self, eta, etadot) -> ca.SX:
        """Q_f = −K η − C η̇ (the geometric stiffness comes from the kinematics: module
        docstring)."""
        return -ca.mtimes(self._K, eta) - ca.mtimes(self._C, etadot)

    def elastic_energy(self, eta) -> ca.SX:
        """V = ½ ηᵀ K η."""
        return 0.5 * ca.bilin(self._K, eta, eta)

    def generalized_forces(self, eta, etadot) -> ca.SX:
        """Elastic and damping forces padded to the size of w (zeros on Ṙ, ω̄)."""
        return ca.vertcat(ca.SX(self.dimension + self.rotations, 1),
                          self.elastic_forces(eta, etadot))

    # ------------------------------------------------------------------ nodes
    def _node(self, node) -> int:
        if isinstance(node, str):
            if node not in self.inv.node_names:
                raise ModelError(f"flexible body: no node named {node!r}; named nodes: "
                                 f"{sorted(self.inv.node_names)}")
            return int(self.inv.node_names[node])
        count = self.inv.positions.shape[0]
        if not (isinstance(node, int | np.integer) and 0 <= node < count):
            raise ModelError(f"flexible body: node {node!r} is not a node name or an index "
                             f"0..{count - 1}")
        return int(node)

    def node_shortening(self, node, eta) -> ca.SX:
        """d_i = −½ (ηᵀ F_i η) e_x, the foreshortening (zero without stiffening)."""
        if not self.stiffening:
            return ca.SX(self.dimension, 1)
        F = _dm(self.inv.foreshortening[self._node(node)])
        return ca.vertcat(self._axial_sum(F, eta), ca.SX(self.dimension - 1, 1))

    def node_offset(self, node, eta) -> ca.SX:
        """ū_i = u_i0 + Φ_i η (+ d_i with stiffening) (body frame)."""
        i = self._node(node)
        offset = _dm(self.inv.positions[i]) + ca.mtimes(_dm(self.inv.phi_t[i]), eta)
        return offset + self.node_shortening(i, eta) if self.stiffening else offset

    def node_position(self, node, R, A, eta) -> ca.SX:
        """r_i = R + A (u_i0 + Φ_i η)  (seed 002, eq. 5–26)."""
        return R + ca.mtimes(A, self.node_offset(node, eta))

    def node_velocity(self, node, A, eta, Rdot, omega, etadot) -> ca.SX:
        """ṙ_i = Ṙ + A (ω̄ × ū_i + Φ_i η̇ + ḋ_i)."""
        i = self._node(node)
        u = self.node_offset(i, eta)
        spin = omega * _perp(u) if self.dimension == 2 else ca.cross(omega, u)
        rel = ca.mtimes(_dm(self.inv.phi_t[i]), etadot)
        if self.stiffening:  # ḋ_i = −(ηᵀ F_i η̇) e_x
            rate = -ca.bilin(_dm(self.inv.foreshortening[i]), eta, etadot)
            rel += ca.vertcat(rate, ca.SX(self.dimension - 1, 1))
        return Rdot + ca.mtimes(A, spin + rel)

    def node_rotation_vector(self, node, eta) -> ca.SX:
        """ψ_i = Ψ_i η: the node's small rotation in body axes (an angle in the plane)."""
        i = self._node(node)
        return ca.mtimes(_dm(self.inv.phi_r[i]), eta)

    def node_rotation(self, node, A, eta, exact: bool = True) -> ca.SX:
        """Rotation matrix of the node frame (node → global).

        Plane: A(θ) A(ψ_i), exact.  Space: ``exact=False`` gives the first-order A (1 + ψ̃_i);
        ``exact=True`` the orthonormal A A(p), p = (1, ψ_i/2)/|(1, ψ_i/2)| (Euler parameters of
        the Gibbs vector ψ_i/2: rotation angle 2 atan(|ψ|/2) = |ψ| − |ψ|³/12 + …, equal to
        exp(ψ̃_i) to second order and smooth at ψ = 0).
        """
        psi = self.node_rotation_vector(node, eta)
        if self.dimension == 2:
            return ca.mtimes(A, planar_rotation(psi))
        if not exact:
            return ca.mtimes(A, ca.SX.eye(3) + ca.skew(psi))
        p = ca.vertcat(1.0, 0.5 * psi)
        return ca.mtimes(A, rotation_matrix(p / ca.norm_2(p)))

    def node_angular_velocity(self, node, A, omega, etadot) -> ca.SX:
        """Global angular velocity of the node frame A (ω̄ + Ψ_i η̇) (plane: θ̇ + Ψ_i η̇)."""
        i = self._node(node)
        rel = omega + ca.mtimes(_dm(self.inv.phi_r[i]), etadot)
        return rel if self.dimension == 2 else ca.mtimes(A, rel)

    def linear_momentum(self, A, eta, Rdot, omega, etadot) -> ca.SX:
        """p = ∂T/∂Ṙ = m Ṙ + M_Rω ω̄ + A S1 η̇ (+ ∂ΔT/∂Ṙ with stiffening)."""
        w = ca.vertcat(Rdot, omega, etadot)
        lin = ca.mtimes(self.mass_matrix(A, eta)[:self.dimension, :], w)
        if not self.stiffening:
            return lin
        return lin + ca.mtimes(A, self._transport(eta, omega, etadot))
