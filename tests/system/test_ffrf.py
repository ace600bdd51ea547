"""Floating-frame equations of a modally reduced flexible body (casmbd.system.floating_frame).

Every check is against an independent computation written here: the direct sum over the lumped
nodes T = ½ Σ m_i |ṙ_i|² + ½ Σ (ω̄ + Ψ_i η̇)ᵀ J_i (ω̄ + Ψ_i η̇) differentiated by AD (Lagrange's
M = ∂²T/∂q̇², Q_v = ∂T/∂q − Ṁ q̇), casmbd's rigid-body descriptions, and conservation laws of a
free-floating body.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import solve_ivp

from casmbd.errors import ModelError
from casmbd.model.fe_beam import beam_model
from casmbd.model.mechanism import Mechanism
from casmbd.model.modal import ModalData
from casmbd.model.modal_reduction import craig_bampton
from casmbd.model.rotations import G_matrix, rotation_matrix
from casmbd.system.equations import System
from casmbd.system.floating_frame import FlexibleBody, invariants, planar_rotation

RTOL = 1e-12  # relative agreement of two exact formulations (rounding only)


def _modal(dim: int, nodes: int = 5, modes: int = 3, seed: int = 0, scale: float = 0.3,
           stiffness=None) -> ModalData:
    """Random lumped modal data: positions, masses, rotary inertias and modes."""
    rng = np.random.default_rng(seed)
    c = 1 if dim == 2 else 3
    pos = rng.normal(size=(nodes, dim))
    masses = rng.uniform(0.5, 2.0, nodes)
    if dim == 2:
        inertias = rng.uniform(0.01, 0.1, nodes)
    else:
        a = rng.normal(size=(nodes, 3, 3)) * 0.2
        inertias = a @ a.transpose(0, 2, 1) + 0.01 * np.eye(3)
    phi_t = scale * rng.normal(size=(nodes, dim, modes))
    phi_r = scale * rng.normal(size=(nodes, c, modes))
    if dim == 2:
        phi_r = phi_r[:, 0, :]
    k = np.diag(rng.uniform(1.0, 4.0, modes)) if stiffness is None else stiffness
    return ModalData(dimension=dim, positions=pos, masses=masses, inertias=inertias,
                     phi_t=phi_t, phi_r=phi_r, mass=np.eye(modes), stiffness=k,
                     frequencies=np.sqrt(np.diag(k)), node_names={"root": 0, "tip": nodes - 1},
                     reduction="free", reference=None,
                     rigid_mass=np.zeros((3, 3) if dim == 2 else (6, 6)))


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def _euler_xyz(phi):
    """A = R_x(φ1) R_y(φ2) R_z(φ3) (the test's own rotation parametrisation)."""
    c, s = ca.cos(phi), ca.sin(phi)
    rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c[0], -s[0]), ca.horzcat(0, s[0], c[0]))
    ry = ca.vertcat(ca.horzcat(c[1], 0, s[1]), ca.horzcat(0, 1, 0), ca.horzcat(-s[1], 0, c[1]))
    rz = ca.vertcat(ca.horzcat(c[2], -s[2], 0), ca.horzcat(s[2], c[2], 0), ca.horzcat(0, 0, 1))
    return ca.mtimes([rx, ry, rz])


def _direct(modal: ModalData, dim: int):
    """(q, v, A, ω̄, T) of the direct nodal sum; q = (R, θ, η) or (R, Euler xyz, η)."""
    n, c = modal.n_modes, 1 if dim == 2 else 3
    q, v = ca.SX.sym("q", dim + c + n), ca.SX.sym("v", dim + c + n)
    eta, etad = q[dim + c:], v[dim + c:]
    if dim == 2:
        A = planar_rotation(q[2])
        omega = v[2]
    else:
        A = _euler_xyz(q[3:6])
        adot = ca.reshape(ca.jtimes(ca.vec(A), q, v), 3, 3)
        wt = ca.mtimes(A.T, adot)
        omega = ca.vertcat(wt[2, 1], wt[0, 2], wt[1, 0])
    T = 0
    for i in range(modal.n_nodes):
        r = q[:dim] + ca.mtimes(A, ca.DM(modal.positions[i]) + ca.mtimes(
            ca.DM(modal.phi_t[i]), eta))
        rdot = ca.jtimes(r, q, v)
        spin = omega + ca.mtimes(ca.DM(np.reshape(modal.phi_r[i], (c, n))), etad)
        jn = ca.DM(np.reshape(modal.inertias[i], (c, c)))
        T += 0.5 * modal.masses[i] * ca.dot(rdot, rdot) + 0.5 * ca.bilin(jn, spin, spin)
    return q, v, A, omega, T


def _lagrange(T, q, v):
    M = ca.hessian(T, v)[0]
    Q = ca.jacobian(T, q).T - ca.jtimes(ca.mtimes(M, v), q, v)
    return M, Q


@pytest.mark.parametrize("dim", [2, 3])
def test_invariants_match_direct_nodal_sum(dim):
    """(b), (c): T, M and Q_v from the invariants equal the direct nodal sum by AD (1e-12)."""
    modal = _modal(dim, seed=dim)
    body = FlexibleBody(invariants(modal))
    q, v, A, omega, T_d = _direct(modal, dim)
    c = 1 if dim == 2 else 3
    eta, etad = q[dim + c:], v[dim + c:]
    M_d, Q_d = _lagrange(T_d, q, v)
    T_f = body.kinetic_energy(A, eta, v[:dim], omega, etad)
    M_w = body.mass_matrix(A, eta)
    Q_w = body.quadratic_velocity_forces(A, eta, omega, etad)
    # w = B(q) q̇; M_q = Bᵀ M_w B, Q_q = Bᵀ (Q_w − M_w Ḃ q̇)  (B = 1 in the plane)
    w = ca.vertcat(v[:dim], omega, etad)
    B = ca.jacobian(w, v)
    M_f = ca.mtimes([B.T, M_w, B])
    Q_f = ca.mtimes(B.T, Q_w - ca.mtimes(M_w, ca.jtimes(w, q, v)))
    f = ca.Function("f", [q, v], [T_d, T_f, M_d, M_f, Q_d, Q_f])
    rng = np.random.default_rng(10 + dim)
    for _ in range(5):
        qn, vn = rng.normal(size=q.numel()), rng.normal(size=v.numel())
        t_d, t_f, m_d, m_f, q_d, q_f = (np.array(x) for x in f(qn, vn))
        assert _rel(t_f, t_d) < RTOL
        assert _rel(m_f, m_d) < RTOL
        assert _rel(q_f, q_d) < RTOL
        assert _rel(m_f, m_f.T) < RTOL


def _rigid_parameters(modal: ModalData):
    """(m, c, I_G) of the lumped body with Φ = 0: centre c = S0/m (body frame), inertia about c."""
    m = modal.masses.sum()
    c = modal.masses @ modal.positions / m
    d = modal.positions - c
    if modal.dimension == 2:
        return m, c, float(modal.masses @ np.sum(d * d, axis=1) + modal.inertias.sum())
    tensor = np.einsum("i,iab->ab", modal.masses,
                       np.sum(d * d, axis=1)[:, None, None] * np.eye(3)
                       - d[:, :, None] * d[:, None, :]) + modal.inertias.sum(axis=0)
    return m, c, tensor


@pytest.mark.parametrize("modes", [0, 3])
def test_planar_rigid_limit(modes):
    """(a): with Φ = 0 (no modes), or η = η̇ = 0, the rigid block of M and Q_v equals casmbd's
    planar absolute description of the same rigid body (non-centroidal frame), 1e-12."""
    modal = _modal(2, modes=modes, seed=4)
    m, c, inertia = _rigid_parameters(modal)
    mech = Mechanism("rigid", gravity=(0.0, 0.0))
    mech.add_body("b", mass=m, inertia=inertia, position=c, reference_point=-c)
    sys_ = System(mech, "absolute")
    f_r = ca.Function("r", [sys_.q, sys_.v], [sys_.mass_matrix, sys_.quadratic_velocity_forces])
    body = FlexibleBody(invariants(modal))
    q, v = ca.SX.sym("q", 3), ca.SX.sym("v", 3)
    zero = ca.DM.zeros(modes)
    A = planar_rotation(q[2])
    f_f = ca.Function("f", [q, v], [body.mass_matrix(A, zero)[:3, :3],
                                    body.quadratic_velocity_forces(A, zero, v[2], zero)[:3]])
    rng = np.random.default_rng(3)
    for _ in range(5):
        qn, vn = rng.normal(size=3), rng.normal(size=3)
        m_r, q_r = (np.array(x) for x in f_r(qn, vn))
        m_f, q_f = (np.array(x) for x in f_f(qn, vn))
        assert _rel(m_f, m_r) < RTOL
        assert _rel(q_f, q_r) < RTOL


@pytest.mark.parametrize("modes", [0, 3])
def test_spatial_rigid_limit(modes):
    """(a): in space, the rigid blocks equal casmbd's spatial absolute (Euler-parameter)
    description on the tangent space: M_w = Nᵀ M_q N and Q_w = Nᵀ (Q_q − M_q Ṅ w) with
    q̇ = N w, ṗ = ½ G(p)ᵀ ω̄ (|p| = 1), 1e-12."""
    modal = _modal(3, modes=modes, seed=5)
    m, c, tensor = _rigid_parameters(modal)
    mech = Mechanism("rigid", gravity=(0.0, 0.0, 0.0))
    mech.add_body("b", mass=m, position=c, reference_point=-c,
                  inertia=[tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1],
                           tensor[0, 2], tensor[1, 2]])
    sys_ = System(mech, "absolute")
    f_r = ca.Function("r", [sys_.q, sys_.v], [sys_.mass_matrix, sys_.quadratic_velocity_forces])
    body = FlexibleBody(invariants(modal))
    p, om = ca.SX.sym("p", 4), ca.SX.sym("om", 3)
    zero = ca.DM.zeros(modes)
    A = rotation_matrix(p)
    f_f = ca.Function("f", [p, om], [body.mass_matrix(A, zero)[:6, :6],
                                     body.quadratic_velocity_forces(A, zero, om, zero)[:6]])
    rng = np.random.default_rng(6)
    for _ in range(5):
        pn = rng.normal(size=4)
        pn /= np.linalg.norm(pn)
        omn, rdot = rng.normal(size=3), rng.normal(size=3)
        gp = np.array(G_matrix(pn), float)
        N = np.zeros((7, 6))
        N[:3, :3] = np.eye(3)
        N[3:, 3:] = 0.5 * gp.T
        pdot = 0.5 * gp.T @ omn
        ndot_w = np.concatenate([np.zeros(3), 0.5 * np.array(G_matrix(pdot), float).T @ omn])
        qn = np.concatenate([rng.normal(size=3), pn])
        vn = np.concatenate([rdot, pdot])
        m_r, q_r = (np.array(x) for x in f_r(qn, vn))
        m_f, q_f = (np.array(x) for x in f_f(pn, omn))
        assert _rel(m_f, N.T @ m_r @ N) < RTOL
        assert _rel(q_f.ravel(), N.T @ (q_r.ravel() - m_r @ ndot_w)) < RTOL


def _free_floating(dim: int, zeta: float):
    """RHS of a free-floating body (no gravity) and its energy, linear and angular momentum.

    Plane: x = (R, θ, η, Ṙ, θ̇, η̇).  Space: x = (R, p, η, Ṙ, ω̄, η̇) with ṗ = ½ G(p)ᵀ ω̄.  The
    last state integrates the damping dissipation η̇ᵀ C η̇.  Momenta from the node sums.
    """
    modal = _modal(dim, seed=7 + dim)
    body = FlexibleBody(invariants(modal, damping_ratio=zeta))
    n, c = modal.n_modes, 1 if dim == 2 else 3
    nr = 1 if dim == 2 else 4
    x = ca.SX.sym("x", dim + nr + n + dim + c + n + 1)
    R, rot, eta = x[:dim], x[dim:dim + nr], x[dim + nr:dim + nr + n]
    w = x[dim + nr + n:-1]
    rdot, omega, etad = w[:dim], w[dim:dim + c], w[dim + c:]
    if dim == 2:
        A, rot_rate = planar_rotation(rot), omega
    else:
        A = rotation_matrix(rot / ca.norm_2(rot))
        rot_rate = 0.5 * ca.mtimes(G_matrix(rot).T, omega)
    M = body.mass_matrix(A, eta)
    force = body.quadratic_velocity_forces(A, eta, omega, etad) + body.generalized_forces(
        eta, etad)
    dissipation = ca.bilin(ca.DM(body.inv.C), etad, etad)
    rhs = ca.vertcat(rdot, rot_rate, etad, ca.solve(M, force), dissipation)
    energy = body.kinetic_energy(A, eta, rdot, omega, etad) + body.elastic_energy(eta) + x[-1]
    lin, ang = 0, 0
    for i in range(modal.n_nodes):
        r = body.node_position(i, R, A, eta)
        v = body.node_velocity(i, A, eta, rdot, omega, etad)
        lin += modal.masses[i] * v
        jn = ca.DM(np.reshape(modal.inertias[i], (c, c)))
        spin = omega + ca.mtimes(ca.DM(np.reshape(modal.phi_r[i], (c, n))), etad)
        if dim == 2:
            ang += modal.masses[i] * (r[0] * v[1] - r[1] * v[0]) + ca.mtimes(jn, spin)
        else:
            ang += modal.masses[i] * ca.cross(r, v) + ca.mtimes([A, jn, spin])
    f = ca.Function("rhs", [x], [rhs])
    g = ca.Function("inv", [x], [energy, lin, ang])
    rng = np.random.default_rng(1)
    x0 = np.zeros(x.numel())
    x0[:dim] = rng.normal(size=dim)
    x0[dim:dim + nr] = 0.4 if dim == 2 else np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm(
        [0.9, 0.1, -0.3, 0.2])
    x0[dim + nr:dim + nr + n] = 0.3 * rng.normal(size=n)
    x0[dim + nr + n:-1] = rng.normal(size=dim + c + n)
    periods = 2 * np.pi / np.sqrt(np.linalg.eigvalsh(np.linalg.solve(body.inv.M_ff, body.inv.K)))
    return f, g, x0, periods


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("zeta", [0.0, 0.05])
def test_free_floating_conservation(dim, zeta):
    """(d): a free-floating body (no gravity) keeps T + V (+ the dissipated η̇ᵀCη̇ integral),
    its linear and its angular momentum over three periods of the slowest mode: relative
    1e-8 with solve_ivp (DOP853, rtol 1e-10, atol 1e-12)."""
    f, g, x0, periods = _free_floating(dim, zeta)
    sol = solve_ivp(lambda t, x: np.array(f(x)).ravel(), (0.0, 3 * periods.max()), x0,
                    method="DOP853", rtol=1e-10, atol=1e-12)
    assert sol.success
    e0, p0, h0 = (np.array(v).ravel() for v in g(x0))
    e1, p1, h1 = (np.array(v).ravel() for v in g(sol.y[:, -1]))
    assert abs(e1[0] - e0[0]) / abs(e0[0]) < 1e-8
    assert np.linalg.norm(p1 - p0) / np.linalg.norm(p0) < 1e-8
    assert np.linalg.norm(h1 - h0) / np.linalg.norm(h0) < 1e-8
    # the motion is not trivial: the modes and the frame moved (and damping dissipated)
    assert np.linalg.norm(sol.y[:, -1] - x0) > 0.1
    if zeta:
        assert sol.y[-1, -1] > 1e-3 * e0[0]


# Southwell coefficients of a uniform cantilever rotating about its root (hub radius 0):
# ω_k² = ω_k0² + K_k Ω² for the flapping modes, ω_k0² + (K_k − 1) Ω² in the plane of rotation
# (Wright, Smith, Thresher & Wang, J. Appl. Mech. 49, 1982; Hodges & Rutkowski, AIAA J. 19,
# 1981): K_1 = 1.1933, K_2 = 6.4826.
SOUTHWELL = (1.1933, 6.4826)


def _slopes(dim: int, stiffening: bool, elements: int = 40):
    """d(ω²)/d(Ω²) at Ω → 0 of the lowest two bending modes of the spin-up beam (issue 23)."""
    L, EI, EA, rhoA = 10.0, 1.4e4, 2.8e7, 1.2
    kw = dict(EI=EI) if dim == 2 else dict(EIy=EI, EIz=EI, GJ=1e4, rhoIp=1e-3)
    fem = beam_model(L, elements, EA=EA, rhoA=rhoA, dimension=dim, mass="lumped", **kw)
    inv = invariants(craig_bampton(fem, 6, ["root"]), stiffening=stiffening)
    body, n = FlexibleBody(inv), inv.n_modes
    eta, om = ca.SX.sym("eta", n), ca.SX.sym("om")
    A = planar_rotation(0.3) if dim == 2 else ca.DM.eye(3)
    omega = om if dim == 2 else ca.vertcat(0.0, 0.0, om)
    zero = ca.DM.zeros(n)
    # the foreshortening's centrifugal term ∂ΔT/∂η at Ṙ = 0, η̇ = 0 (−s(ω̄) P_G η)
    shortening = ca.gradient(body.foreshortening_energy(A, eta, ca.DM.zeros(dim), omega, zero),
                             eta)
    q_f = body.quadratic_velocity_forces(A, eta, omega, zero)[-n:] + body.elastic_forces(
        eta, zero) + shortening
    k_eff = ca.Function("k", [eta, om], [-ca.jacobian(q_f, eta)])
    w0 = 1.8751 ** 2 * np.sqrt(EI / (rhoA * L ** 4))
    big = 1e-3 * w0
    lam0 = scipy.linalg.eigh(np.array(k_eff(zero, 0.0)), inv.M_ff, eigvals_only=True)[:2]
    lam = scipy.linalg.eigh(np.array(k_eff(zero, big)), inv.M_ff, eigvals_only=True)[:2]
    return (lam - lam0) / big ** 2, np.sqrt(lam0[0]) / w0


def test_geometric_stiffening_southwell():
    """Item 3: with the centrifugal geometric stiffness the bending frequencies of the
    rotating cantilever rise with the Southwell coefficients (40 elements: K_1 within 5e-4
    (measured 4e-5 in-plane, 2.3e-4 flapping), K_2 within 5e-3 (measured 3.6e-3); the lumped
    axial load converges as h²); without it the in-plane mode
    softens as ω_0² − Ω² and the linear model diverges above ω_0 (the spin-up failure)."""
    planar, ratio = _slopes(2, True)
    assert abs(ratio - 1.0) < 1e-3  # the first cantilever frequency, βL = 1.8751
    assert abs((planar[0] + 1.0) / SOUTHWELL[0] - 1.0) < 5e-4
    assert abs((planar[1] + 1.0) / SOUTHWELL[1] - 1.0) < 5e-3
    spatial, _ = _slopes(3, True)
    # rotation about z: the in-plane (v) mode softens, the flapping (w) mode does not
    assert abs((spatial[0] + 1.0) / SOUTHWELL[0] - 1.0) < 5e-4
    assert abs(spatial[1] / SOUTHWELL[0] - 1.0) < 5e-4
    linear, _ = _slopes(2, False)
    assert abs(linear[0] + 1.0) < 1e-2


def test_modal_damping_of_mass_normalised_modes():
    """C = diag(2 ζ_k ω_k) for mass-normalised modes (flexible_mass='reduced'), 1e-9."""
    modal = craig_bampton(beam_model(2.0, 10, EA=1e6, rhoA=2.0, EI=50.0), 4, ["root", "tip"])
    zeta = np.linspace(0.01, 0.05, modal.n_modes)
    inv = invariants(modal, damping_ratio=zeta, flexible_mass="reduced")
    expected = np.diag(2.0 * zeta * modal.frequencies)
    assert _rel(inv.C, expected) < 1e-9
    lumped = invariants(modal, damping_ratio=zeta)  # general form: modal ζ of (K, M_ff) pairs
    lam, vec = scipy.linalg.eigh(lumped.K, lumped.M_ff)
    assert _rel(np.diag(vec.T @ lumped.C @ vec), 2.0 * zeta * np.sqrt(lam)) < 1e-9


@pytest.mark.parametrize("dim", [2, 3])
def test_node_outputs(dim):
    """r_i = R + A (u_i0 + Φ_i η) against the data, ṙ_i against AD of r_i, the node frame:
    planar exact angle θ + Ψ_i η; spatial orthonormal and within |ψ|² of A (1 + ψ̃)."""
    modal = _modal(dim, seed=12)
    body = FlexibleBody(invariants(modal))
    n, c = modal.n_modes, 1 if dim == 2 else 3
    q, v, A, omega, _ = _direct(modal, dim)
    eta, etad = q[dim + c:], v[dim + c:]
    r = body.node_position("tip", q[:dim], A, eta)
    f = ca.Function("f", [q, v], [r, ca.jtimes(r, q, v),
                                  body.node_velocity("tip", A, eta, v[:dim], omega, etad),
                                  body.node_rotation("tip", A, eta),
                                  body.node_rotation("tip", A, eta, exact=False), A])
    rng = np.random.default_rng(2)
    qn, vn = 0.1 * rng.normal(size=q.numel()), rng.normal(size=v.numel())
    r_n, rdot_ad, rdot, rot, rot1, a_n = (np.array(x) for x in f(qn, vn))
    tip = modal.n_nodes - 1
    etan = qn[dim + c:]
    assert _rel(r_n.ravel(), qn[:dim] + a_n @ (modal.positions[tip] + modal.phi_t[tip] @ etan)) \
        < RTOL
    assert _rel(rdot, rdot_ad) < RTOL
    psi = np.reshape(modal.phi_r[tip], (c, n)) @ etan
    assert np.allclose(rot.T @ rot, np.eye(dim), atol=1e-14)
    if dim == 2:
        ang = qn[2] + psi[0]
        assert _rel(rot, [[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]]) < RTOL
    else:
        assert np.max(np.abs(rot - rot1)) < np.dot(psi, psi)
    with pytest.raises(ModelError, match="no node named 'mid'"):
        body.node_position("mid", q[:dim], A, eta)


@pytest.mark.parametrize(("change", "kwargs", "message"), [
    ({"masses": -np.ones(5)}, {}, "field 'masses'"),
    ({"phi_t": np.zeros((5, 2, 3, 1))}, {}, "field 'phi_t'"),
    ({"stiffness": np.full((3, 3), np.nan)}, {}, "field 'stiffness'"),
    ({"inertias": -np.ones(5)}, {}, "field 'inertias'"),
    ({}, {"damping_ratio": -0.1}, "field 'damping_ratio'"),
    ({}, {"damping_ratio": [0.1, 0.2]}, "field 'damping_ratio'"),
    ({}, {"flexible_mass": "consistent"}, "field 'flexible_mass'"),
    ({}, {"stiffening": True}, "nodes on the body x axis"),
])
def test_bad_input(change, kwargs, message):
    """Malformed modal data and options raise a ModelError naming the body and the field."""
    data = dict(_modal(2).__dict__)
    data.update(change)
    with pytest.raises(ModelError, match=f"flexible body 'beam'.*{message}"):
        invariants(ModalData(**data), name="beam", **kwargs)


def test_euler_parameter_form():
    """With Euler parameters (ω̄ = 2 G(p) ṗ) and |p| = 1, pᵀṗ = 0: Bᵀ M B equals the Hessian of
    T(A(p), 2 G ṗ) (1e-12) and Bᵀ Q_v equals AD's ∂T/∂q − Ṁ q̇ up to a multiple of the
    normalisation gradient p (projected difference 1e-12)."""
    modal = _modal(3, seed=3)
    body, n = FlexibleBody(invariants(modal)), modal.n_modes
    q, v = ca.SX.sym("q", 7 + n), ca.SX.sym("v", 7 + n)
    p, pd, eta, etad = q[3:7], v[3:7], q[7:], v[7:]
    A, om = rotation_matrix(p), 2.0 * ca.mtimes(G_matrix(p), pd)
    M, Q = _lagrange(body.kinetic_energy(A, eta, v[:3], om, etad), q, v)
    B = ca.diagcat(ca.SX.eye(3), 2.0 * G_matrix(p), ca.SX.eye(n))
    f = ca.Function("f", [q, v], [M, ca.mtimes([B.T, body.mass_matrix(A, eta), B]), Q,
                                  ca.mtimes(B.T, body.quadratic_velocity_forces(A, eta, om, etad))])
    rng = np.random.default_rng(4)
    qn, vn = rng.normal(size=7 + n), rng.normal(size=7 + n)
    qn[3:7] /= np.linalg.norm(qn[3:7])
    vn[3:7] -= qn[3:7] * np.dot(qn[3:7], vn[3:7])
    m_ad, m_f, q_ad, q_f = (np.array(x) for x in f(qn, vn))
    assert _rel(m_f, m_ad) < RTOL
    proj = np.eye(7 + n)
    proj[3:7, 3:7] -= np.outer(qn[3:7], qn[3:7])
    assert np.max(np.abs(proj @ (q_f - q_ad))) < RTOL * np.max(np.abs(q_ad))
