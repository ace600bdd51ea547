"""Mimic joints substituted in joint coordinates against the same robot with its gears kept as
constraint equations (``mechanism.substitute_gears = False``; no peer needed).

The robot (inline URDF): j1 revolute; j2 revolute following j1 with θ₂ = −0.5 θ₁ + 0.3; j4
revolute following j2 (a chain: θ₄ = 2 θ₂ − 0.1, resolved to j1); j3 continuous; a prismatic
finger pair p2 = 1.5 p1 + 0.01 on the last link.  With q_full = G q + o (G constant, the
followers' rows r e_lᵀ) the substituted model must give, to rounding (1e-12 relative):
M = Gᵀ M_f G, b = Gᵀ b_f, τ = Gᵀ (M_f G a + b_f), q̈ with G q̈ = the constrained q̈ (τ on the
independent coordinates), frames and J G; the batch methods equal the single calls; joint
outputs report every follower's position; inverse dynamics of a driven motion gives the same
driver efforts and joint reactions (the gears' columns as the multipliers give them); statics
the same equilibrium; a short simulation the same motion (to the integrator's tolerance).
"""

from __future__ import annotations

import numpy as np
import pytest

import casmbd
from casmbd.io.urdf import loads_urdf

_I = ('<inertial><origin xyz="{c}" rpy="{r}"/><mass value="{m}"/><inertia ixx="{i[0]}" '
      'ixy="{i[3]}" ixz="{i[4]}" iyy="{i[1]}" iyz="{i[5]}" izz="{i[2]}"/></inertial>')
_LIM = '<limit lower="-3" upper="3" effort="10" velocity="5"/>'


def _link(name, c, m, i, r="0 0 0"):
    return f'<link name="{name}">' + _I.format(c=c, r=r, m=m, i=i) + "</link>"


def _joint(name, kind, parent, child, xyz, rpy, axis, mimic=""):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child '
            f'link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>{_LIM}'
            f"{mimic}</joint>")


URDF = ('<robot name="mimics"><link name="base"/>'
        + _link("l1", "0.1 0 0.05", 1.5, (0.02, 0.03, 0.025, 0.001, 0, 0.002))
        + _link("l2", "0.05 0.1 0", 1.0, (0.03, 0.02, 0.04, 0.002, 0.001, 0), "0.1 0.2 0.3")
        + _link("l4", "0.02 0 0.1", 0.6, (0.01, 0.02, 0.015, 0, 0.001, 0))
        + _link("l3", "0 0.1 0.02", 0.7, (0.01, 0.012, 0.008, 0, 0, 0))
        + _link("f1", "0 0.01 0.02", 0.1, (1e-4, 2e-4, 1.5e-4, 0, 0, 0))
        + _link("f2", "0 -0.01 0.02", 0.15, (1e-4, 2e-4, 1.5e-4, 0, 0, 0))
        + _joint("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1")
        + _joint("j2", "revolute", "l1", "l2", "0.4 0 0", "0.2 0 0", "0 1 0",
                 '<mimic joint="j1" multiplier="-0.5" offset="0.3"/>')
        + _joint("j4", "revolute", "l1", "l4", "0 0.2 0.1", "0 0.3 0", "1 0 0",
                 '<mimic joint="j2" multiplier="2" offset="-0.1"/>')
        + _joint("j3", "continuous", "l2", "l3", "0.3 0 0", "0 0 0", "1 0 0")
        + _joint("p1", "prismatic", "l3", "f1", "0 0 0.1", "0 0 0", "0 1 0")
        + _joint("p2", "prismatic", "l3", "f2", "0 0 0.1", "0 0 0", "0 -1 0",
                 '<mimic joint="p1" multiplier="1.5" offset="0.01"/>')
        + "</robot>")

#: follower -> (independent leader, ratio, offset) after the chain j4 → j2 → j1 is resolved
FOLLOWS = {"j2": ("j1", -0.5, 0.3), "j4": ("j1", -1.0, 0.5), "p2": ("p1", 1.5, 0.01)}
TOL = 1e-12


def _pair(**options):
    sub = loads_urdf(URDF, **options)
    con = loads_urdf(URDF, **options)
    con.substitute_gears = False
    return sub, con


@pytest.fixture(scope="module")
def models():
    sub, con = _pair()
    return casmbd.compile(sub, mode="vm"), casmbd.compile(con, mode="vm")


def _map(m_sub, m_con):
    """G, o with q_con = G q_sub + o (coordinates matched by joint name)."""
    ind = [n.split(".")[0] for n in m_sub.coordinate_names]
    full = [n.split(".")[0] for n in m_con.coordinate_names]
    g, o = np.zeros((len(full), len(ind))), np.zeros(len(full))
    for i, name in enumerate(full):
        lead, ratio, offset = FOLLOWS.get(name, (name, 1.0, 0.0))
        g[i, ind.index(lead)], o[i] = ratio, offset
    return g, o


def _close(a, b, tol=TOL):
    scale = max(1.0, float(np.max(np.abs(b), initial=0.0)))
    assert np.max(np.abs(np.asarray(a) - b), initial=0.0) <= tol * scale, \
        np.max(np.abs(np.asarray(a) - b))


def test_followers_leave_the_coordinates(models):
    sub, con = models
    assert sub.nc == 0 and con.nc == 3
    assert [n.split(".")[0] for n in sub.coordinate_names] == ["j1", "j3", "p1"]
    assert "robot_fd_batch" in sub._calls and "robot_kkt" not in sub._calls


def test_per_call_quantities_equal_the_constrained_form(models):
    sub, con = models
    g, o = _map(sub, con)
    rng = np.random.default_rng(7)
    for _ in range(3):
        q, v, a, tau = (rng.uniform(-1, 1, sub.nq) for _ in range(4))
        qf, vf, af = g @ q + o, g @ v, g @ a
        m_f = con.mass_matrix(qf)
        b_f = con.bias_forces(qf, vf)
        _close(sub.mass_matrix(q), g.T @ m_f @ g)
        _close(sub.bias_forces(q, v), g.T @ b_f)
        _close(sub.inverse_dynamics(q, v, a), g.T @ (m_f @ af + b_f))
        # the constrained q̈ with the efforts on the independent coordinates (none on a
        # follower), Gᵀ τ_f = τ
        tau_f = np.zeros(con.nq)
        tau_f[[con.coordinate_names.index(n) for n in sub.coordinate_names]] = tau
        _close(g @ sub.forward_dynamics(q, v, tau), con.forward_dynamics(qf, vf, tau_f))
        pos, rot = sub.forward_kinematics(q)
        pos_f, rot_f = con.forward_kinematics(qf)
        _close(pos, pos_f)
        _close(rot, rot_f)
        for frame in sub.frame_names:
            _close(sub.jacobian(q, frame), con.jacobian(qf, frame) @ g)


def test_batch_equals_single_calls(models):
    sub, _ = models
    rng = np.random.default_rng(3)
    q, v, w = (rng.uniform(-1, 1, (70, sub.nq)) for _ in range(3))  # two chunks
    fd = sub.forward_dynamics_batch(q, v, w)
    inv = sub.inverse_dynamics_batch(q, v, w)
    for k in (0, 41, 69):
        _close(fd[k], sub.forward_dynamics(q[k], v[k], w[k]), 1e-14)
        _close(inv[k], sub.inverse_dynamics(q[k], v[k], w[k]), 1e-14)


def _drive(mech):
    mech.add_driver("d1", "0.4 + 0.6*sin(2*t)", joint="j1")
    mech.add_driver("d3", "-0.2 + 0.5*sin(3*t)", joint="j3")
    mech.add_driver("dp", "0.01 + 0.02*sin(t)", joint="p1")
    return mech


def test_inverse_dynamics_efforts_reactions_and_joint_outputs():
    """Driven j1, j3, p1: the driver efforts, every joint's reaction (the gears' columns
    included: the follower's axial share, −λ about (along) its axis) and the followers'
    joint positions r q_l + δ agree with the multiplier form to rounding."""
    sub, con = (_drive(m) for m in _pair(initial={"j1": 0.4, "p1": 0.01}))
    r_sub = casmbd.inverse_dynamics(sub, 1.0, 4, mode="vm")
    r_con = casmbd.inverse_dynamics(con, 1.0, 4, mode="vm")
    _close(r_sub["driver_efforts"], r_con["driver_efforts"], 1e-10)
    _close(r_sub["joint_reactions"], r_con["joint_reactions"], 1e-10)
    gears = [k for k, name in enumerate(sub.joints) if name.endswith("_mimic")]
    assert len(gears) == 3 and r_sub["joint_reactions"].shape[1:] == (len(sub.joints), 6)
    for k in gears:  # the gears carry load (the comparison is not of zeros)
        assert np.max(np.abs(r_sub["joint_reactions"][:, k])) > 1e-3
    _close(r_sub["joint_positions"], r_con["joint_positions"], 1e-10)
    jp = r_sub["joint_positions"]
    cols = casmbd.System(sub).joint_coordinate_names
    t = r_sub["t"]
    lead = 0.4 + 0.6 * np.sin(2 * t)
    _close(jp[:, cols.index("j2")], -0.5 * lead + 0.3, 1e-10)
    _close(jp[:, cols.index("j4")], -1.0 * lead + 0.5, 1e-10)


def test_statics_linearize_and_simulation_agree():
    """Statics of the driven robot (joint positions, reactions with the gears' columns, to
    1e-10), the linearization about the start (eigenvalues, 1e-8) and 0.3 s of free motion
    (rtol 1e-10: joint and body positions to 1e-7)."""
    sub, con = (_drive(m) for m in _pair(initial={"j1": 0.4, "p1": 0.01}))
    s_sub = casmbd.static_equilibrium(sub, t=0.3, mode="vm")
    s_con = casmbd.static_equilibrium(con, t=0.3, mode="vm")
    _close(s_sub.joint_coordinates, s_con.joint_coordinates, 1e-10)
    _close(s_sub.joint_reactions, s_con.joint_reactions, 1e-10)
    sub, con = _pair(initial={"j1": (0.3, 0.5), "j3": (0.2, -1.0), "p1": (0.005, 0.1)})
    lin_sub, lin_con = (casmbd.linearize(m, mode="vm") for m in (sub, con))
    ev_sub, ev_con = (np.sort_complex(np.asarray(x.eigenvalues)) for x in (lin_sub, lin_con))
    assert ev_sub.shape == ev_con.shape == (6,)
    _close(ev_sub, ev_con, 1e-8)
    r_sub = casmbd.simulate(sub, 0.3, 6, rtol=1e-10, mode="vm")
    r_con = casmbd.simulate(con, 0.3, 6, rtol=1e-10, mode="vm")
    _close(r_sub["joint_positions"], r_con["joint_positions"], 1e-7)
    _close(r_sub["body_positions"], r_con["body_positions"], 1e-7)


def test_leader_below_its_follower():
    """j1 (at the root) follows the prismatic j3 two links below it, θ₁ = 0.7 s₃ + 0.2: the
    follower's pose depends on a descendant's coordinate; M, τ, q̈ through G to 1e-12 and the
    reactions and driver efforts of a driven motion to 1e-10."""
    urdf = ('<robot name="below"><link name="base"/>'
            + _link("l1", "0.1 0 0.05", 1.5, (0.02, 0.03, 0.025, 0.001, 0, 0.002))
            + _link("l2", "0.05 0.1 0", 1.0, (0.03, 0.02, 0.04, 0.002, 0.001, 0),
                    "0.1 0.2 0.3")
            + _link("l3", "0 0.1 0.02", 0.7, (0.01, 0.012, 0.008, 0, 0, 0))
            + _joint("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1",
                     '<mimic joint="j3" multiplier="0.7" offset="0.2"/>')
            + _joint("j2", "revolute", "l1", "l2", "0.4 0 0", "0.2 0 0", "0 1 0")
            + _joint("j3", "prismatic", "l2", "l3", "0.3 0 0", "0 0 0", "1 0 0")
            + "</robot>")
    sub, con = loads_urdf(urdf), loads_urdf(urdf)
    con.substitute_gears = False
    m_sub, m_con = casmbd.compile(sub, mode="vm"), casmbd.compile(con, mode="vm")
    assert [n.split(".")[0] for n in m_sub.coordinate_names] == ["j2", "j3"]
    g, o = np.array([[0.0, 0.7], [1.0, 0.0], [0.0, 1.0]]), np.array([0.2, 0.0, 0.0])
    rng = np.random.default_rng(11)
    for _ in range(3):
        q, v, w = (rng.uniform(-1, 1, 2) for _ in range(3))
        qf, vf = g @ q + o, g @ v
        m_f, b_f = m_con.mass_matrix(qf), m_con.bias_forces(qf, vf)
        _close(m_sub.mass_matrix(q), g.T @ m_f @ g)
        _close(m_sub.inverse_dynamics(q, v, w), g.T @ (m_f @ g @ w + b_f))
        _close(g @ m_sub.forward_dynamics(q, v, w), m_con.forward_dynamics(qf, vf, np.r_[0, w]))
    for mech in (sub, con):
        mech.add_driver("d2", "0.3*sin(t)", joint="j2")
        mech.add_driver("d3", "0.1*sin(2*t)", joint="j3")
    r_sub, r_con = (casmbd.inverse_dynamics(m, 1.0, 3, mode="vm") for m in (sub, con))
    _close(r_sub["joint_reactions"], r_con["joint_reactions"], 1e-10)
    _close(r_sub["driver_efforts"], r_con["driver_efforts"], 1e-10)
