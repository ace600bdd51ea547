"""A planar two-link arm written by hand from its Lagrangian (CasADi AD), independent of
casmbd's equations: the regressor Y(q, v, a) with τ = Y π for the identification tests.

Link i turns about joint i (joint 1 at the origin, joint 2 at l₁ along link 1); each link's
parameters are about its joint, in the link frame (x along the link): m, m c_x, m c_y, I_zz
(the names of :mod:`casmbd.analysis.identification.parameters`, planar), then each joint's
viscous and Coulomb coefficients (casmbd's law τ_f = F_v q̇ + F_c tanh(q̇ / v_s)).
Gravity g = 9.81 along −y.

T_i = ½ m |ṗ_i|² + ṗ_i · (φ̇_i k × R_i h_i) + ½ I_O φ̇_i², V_i = m g y_i + g (R_i h_i)_y,
τ = d/dt ∂L/∂q̇ − ∂L/∂q + τ_f.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

L1 = 0.7
G = 9.81
V_S = 1e-3
NAMES = [f"link{i}.{k}" for i in (1, 2) for k in ("m", "mcx", "mcy", "Izz")] + [
    f"j{i}.{k}" for i in (1, 2) for k in ("viscous", "coulomb")]
#: physically consistent true parameters: masses, centres of mass (0.3, 0.02) and (0.25,
#: −0.01), centroidal inertias 0.05 and 0.02, friction
TRUE = np.array([2.0, 2.0 * 0.3, 2.0 * 0.02, 0.05 + 2.0 * (0.3 ** 2 + 0.02 ** 2),
                 1.2, 1.2 * 0.25, -1.2 * 0.01, 0.02 + 1.2 * (0.25 ** 2 + 0.01 ** 2),
                 0.3, 0.8, 0.2, 0.5])


def _regressor_function() -> ca.Function:
    q, v, a = ca.SX.sym("q", 2), ca.SX.sym("v", 2), ca.SX.sym("a", 2)
    pi = ca.SX.sym("pi", 12)
    phi = [q[0], q[0] + q[1]]
    p = [ca.vertcat(0, 0), L1 * ca.vertcat(ca.cos(q[0]), ca.sin(q[0]))]
    lag = 0
    for i in range(2):
        m, hx, hy, izz = (pi[4 * i + k] for k in range(4))
        rot = ca.vertcat(ca.horzcat(ca.cos(phi[i]), -ca.sin(phi[i])),
                         ca.horzcat(ca.sin(phi[i]), ca.cos(phi[i])))
        h = ca.mtimes(rot, ca.vertcat(hx, hy))
        pd = ca.jtimes(p[i], q, v)
        wd = ca.jtimes(phi[i], q, v)
        kin = 0.5 * m * ca.dot(pd, pd) + ca.dot(pd, wd * ca.vertcat(-h[1], h[0])) \
            + 0.5 * izz * wd ** 2
        pot = m * G * p[i][1] + G * h[1]
        lag += kin - pot
    dl_dv = ca.gradient(lag, v)
    tau = ca.jtimes(dl_dv, q, v) + ca.jtimes(dl_dv, v, a) - ca.gradient(lag, q)
    tau += ca.vertcat(pi[8] * v[0] + pi[9] * ca.tanh(v[0] / V_S),
                      pi[10] * v[1] + pi[11] * ca.tanh(v[1] / V_S))
    return ca.Function("y2r", [q, v, a], [ca.jacobian(tau, pi)])


Y_FUNCTION = _regressor_function()


def regressor(q, v, a) -> np.ndarray:
    """Y at N states, shape (N, 2, 12)."""
    f = Y_FUNCTION.map(len(q))
    y = np.asarray(f(np.asarray(q).T, np.asarray(v).T, np.asarray(a).T))  # 2 × 12N
    return y.reshape(2, len(q), 12).transpose(1, 0, 2)


def fourier_trajectory(t, seed: int = 0, harmonics: int = 5, f0: float = 0.1):
    """q, q̇, q̈ of a finite Fourier series (Swevers et al. 1997) with seeded coefficients."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * f0 * np.arange(1, harmonics + 1)
    q, v, a = (np.zeros((len(t), 2)) for _ in range(3))
    for j in range(2):
        sa, sb = rng.normal(0, 0.5, harmonics) / np.arange(1, harmonics + 1), \
            rng.normal(0, 0.5, harmonics) / np.arange(1, harmonics + 1)
        s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
        q[:, j] = s @ (sa / w) - c @ (sb / w) + rng.normal(0, 0.3)
        v[:, j] = c @ sa + s @ sb
        a[:, j] = -s @ (sa * w) + c @ (sb * w)
    return q, v, a


def base_basis(tol: float = 1e-9):
    """K (n_b × 12) and P (12 × n_b) with Y P = Y_b and π_b = K π, by QR with column
    pivoting of Y stacked at random states (Gautier 1990): π_b = π₁ + R₁⁻¹ R₂ π₂."""
    from scipy.linalg import qr

    rng = np.random.default_rng(7)
    q, v, a = (rng.uniform(-2, 2, (200, 2)) for _ in range(3))
    w = regressor(q, v, a).reshape(400, 12)
    _, r, perm = qr(w, pivoting=True, mode="economic")
    rank = int(np.sum(np.abs(np.diag(r)) > tol * abs(r[0, 0])))
    beta = np.linalg.solve(r[:rank, :rank], r[:rank, rank:])
    k = np.zeros((rank, 12))
    k[:, perm[:rank]] = np.eye(rank)
    k[:, perm[rank:]] = beta
    p = np.zeros((12, rank))
    p[perm[:rank], np.arange(rank)] = 1.0
    return k, p


# ------------------------------------------------------------------ the UR-type arm (URDF)
UR5 = str(__import__("pathlib").Path(__file__).resolve().parent / "scenes" / "ur5_arm.urdf")
#: friction (viscous, Coulomb) of the "true" arm, the URDF's own on shoulder_pan (0.5, 0.1)
UR5_FRICTION = {"shoulder_lift_joint": (0.4, 0.6), "elbow_joint": (0.3, 0.5),
                "wrist_1_joint": (0.1, 0.2), "wrist_2_joint": (0.08, 0.15),
                "wrist_3_joint": (0.05, 0.1)}


def ur5_truth():
    """The "real" arm: the URDF's inertials and friction on every joint."""
    from casmbd.io.urdf import load_urdf

    mech = load_urdf(UR5, damping=True, friction=True)
    for joint, (c, f) in UR5_FRICTION.items():
        mech.add("joint_friction", f"{joint}_true", joint, damping=c, friction=f)
    return mech


def ur5_model():
    """The model to identify: wrong masses of two links, no friction."""
    from casmbd.io.urdf import load_urdf

    return load_urdf(UR5, links={"upper_arm_link": {"mass": 7.0},
                                 "forearm_link": {"mass": 3.0}})


def arm_trajectory(t, n: int, seed: int, harmonics: int = 5, f0: float = 0.1,
                   amplitude: float = 0.4):
    """q, q̇, q̈ (N × n) of a finite Fourier series (Swevers et al. 1997), seeded."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * f0 * np.arange(1, harmonics + 1)
    q, v, a = (np.zeros((len(t), n)) for _ in range(3))
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    for j in range(n):
        sa = rng.normal(0, amplitude, harmonics) / np.arange(1, harmonics + 1)
        sb = rng.normal(0, amplitude, harmonics) / np.arange(1, harmonics + 1)
        q[:, j] = s @ (sa / w) - c @ (sb / w) + rng.normal(0, 0.3)
        v[:, j] = c @ sa + s @ sb
        a[:, j] = -s @ (sa * w) + c @ (sb * w)
    return q, v, a


def inverse_dynamics(mech, q, v, a):
    """τ at each sample by casmbd's compiled inverse dynamics (CasADi's VM)."""
    import casmbd

    robot = casmbd.compile(mech, mode="vm")
    return np.array([robot.inverse_dynamics(q[k], v[k], a[k]) for k in range(len(q))])


def true_parameters(truth, reg, model=None):
    """π of ``truth`` in the order and frames of the regressor ``reg`` of ``model`` (each
    body's origin O at the model's reference point: the truth's centre of mass is written
    relative to it, c = A₀ᵀ (r_G,truth − r_G,model) − o, by the parallel-axis theorem)."""
    from casmbd.analysis.identification.parameters import (
        inertial_parameters,
        standard_parameters,
    )

    joints = [fc.joint for fc in reg.parameters.friction_coordinates]
    sp = standard_parameters(truth, reg.parameters.friction, friction_joints=joints)
    values = sp.as_dict()
    if model is not None:
        dim = truth.dimension
        for name, body in truth.bodies.items():
            ref = model.bodies[name]
            rot = np.asarray(ref.initial_rotation, float)
            c = rot.T @ (np.asarray(body.position, float) - np.asarray(ref.position, float)) \
                - reg.parameters.origins[name]
            block = sp.values[sp.body_block(name)]
            mass = block[0]
            c_own = block[1:dim + 1] / mass  # the truth's own offset (zero: centroidal)
            if dim == 2:
                i_c = block[3] - mass * (c_own @ c_own)
            else:
                i_o = np.array([[block[4], block[5], block[6]], [block[5], block[7], block[8]],
                                [block[6], block[8], block[9]]])
                i_c = i_o - mass * ((c_own @ c_own) * np.eye(3) - np.outer(c_own, c_own))
            new = inertial_parameters(mass, c, i_c, dim)
            for key, val in zip(reg.parameters.names[reg.parameters.body_block(name)], new,
                                strict=True):
                values[key] = float(val)
    return np.array([values[name] for name in reg.names])


def to_csv(path, t, names, q, tau, v=None, a=None):
    """A measurement CSV (casmbd.io.measurement_csv) of the samples."""
    cols = ["t"] + [f"q.{c}" for c in names]
    data = [t[:, None], q]
    if v is not None:
        cols += [f"v.{c}" for c in names] + [f"a.{c}" for c in names]
        data += [v, a]
    cols += [f"tau.{c}" for c in names]
    data.append(tau)
    np.savetxt(path, np.hstack(data), delimiter=",", header=",".join(cols), comments="",
               fmt="%.17g")
    return path
