"""Outputs and energies of a planar revolute chain folded over the bodies: the forward
kinematics (positions, velocities, accelerations) written once per body and applied N times
by CasADi's ``mapaccum``, as :mod:`casmbd.system.chain_fold` does for the right-hand side.

Written out body by body (:meth:`casmbd.system.outputs.Outputs.outputs_function`,
:attr:`casmbd.system.equations.System.kinetic_energy`, ``potential_energy``) a 1000-rod
chain gives 4.0 MB of C for the outputs and 1.3 MB for the energies, compiled at ``-O0`` in
most of its cold build; folded, the arithmetic is generated once.

One step of the fold (root to tip) carries the parent's rotation A_P, centre of mass r_P,
its velocity and acceleration ṙ_P, r̈_P, angle θ_P, rate ω_P and angular acceleration α_P.
With the joint's design data (:class:`casmbd.system.tree.TreeJointDescription`:
a = J₀ − r_P0, b = r_C0 − J₀, A_P0ᵀ, A_C0, the angle offset θ₀), B = A_P A_P0ᵀ, the joint
point J = r_P + B a, e = r_C − J, ρ = J − r_P and ω × d = (−ω d_y, ω d_x):

    A_C = B R(q) A_C0,   r_C = J + B R(q) b,   θ_C = θ_P + θ₀ + q,
    ω_C = ω_P + q̇,      α_C = α_P + q̈,
    ṙ_C = ṙ_P + ω_P × ρ + ω_C × e,
    r̈_C = r̈_P + α_P × ρ − ω_P² ρ + α_C × e − ω_C² e

(seed 001, eqs. 256–290; Featherstone, *Rigid Body Dynamics Algorithms*, 2008, sec. 2.9).
A marker at d (body frame, about G) moves as r_G + A d, ṙ_G + ω × (A d),
r̈_G + α × (A d) − ω² A d.  The energies are sums over the folded columns:
T = Σ ½ (m |ṙ_G|² + J ω²), V = −Σ m g·r_G.
``tests/system/test_chain_motion.py`` checks every output and both energies against the
body-by-body expressions to 1e-12.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.system.chain_fold import chain_order
from casmbd.system.chain_fold import supported as fold_supported
from casmbd.system.requests import output_groups

__all__ = ["folded_energies", "folded_outputs", "motion", "supported"]

_CARRY = 17  # vec(A) (4), r (2), ṙ (2), r̈ (2), θ, ω, α, ρ = J − r_P (2), e = r − J (2)


def supported(system) -> str | None:
    """None when the folded outputs and energies apply to ``system`` (a chain the
    right-hand side folds, :func:`casmbd.system.chain_fold.supported`, with no requests or
    force reports and no marker on the ground), else the reason."""
    reason = fold_supported(system)
    if reason:
        return reason
    if output_groups(system):
        return "output requests or force reports (written body by body)"
    for m in system.mechanism.markers.values():
        if m.body not in system.descriptions:
            return f"marker '{m.name}' is not on a body of the chain"
    return None


def _cross(w, d):
    return ca.vertcat(-w * d[1], w * d[0])


def _rot(angle):
    c, s = ca.cos(angle), ca.sin(angle)
    return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))


def _motion_step() -> ca.Function:
    """One body of the fold: the parent's motion (carry) and the joint's data in, the
    body's motion out (module notes)."""
    carry = ca.SX.sym("parent", _CARRY)
    data = ca.SX.sym("data", 16)  # q, q̇, q̈, vec(A_P0ᵀ), vec(A_C0), a, b, θ₀
    a_p, r_p = ca.reshape(carry[:4], 2, 2), carry[4:6]
    rd_p, rdd_p = carry[6:8], carry[8:10]
    th_p, w_p, al_p = carry[10], carry[11], carry[12]
    q, qd, qdd = data[0], data[1], data[2]
    p0t, c0 = ca.reshape(data[3:7], 2, 2), ca.reshape(data[7:11], 2, 2)
    a, b, th0 = data[11:13], data[13:15], data[15]
    base = ca.mtimes(a_p, p0t)
    rel = _rot(q)
    rho = ca.mtimes(base, a)
    joint = r_p + rho
    r_c = r_p + ca.mtimes(base, a + ca.mtimes(rel, b))
    e = r_c - joint
    a_c = ca.mtimes(base, ca.mtimes(rel, c0))
    w_c, al_c = w_p + qd, al_p + qdd
    rd_c = rd_p + _cross(w_p, rho) + _cross(w_c, e)
    rdd_c = rdd_p + _cross(al_p, rho) - w_p**2 * rho + _cross(al_c, e) - w_c**2 * e
    out = ca.vertcat(ca.vec(a_c), r_c, rd_c, rdd_c, th_p + th0 + q, w_c, al_c, rho, e)
    return ca.Function("chain_motion", [carry, data], [out])


def _joint_data(system, order) -> np.ndarray:
    """16 − 3 rows of design data per body (module notes), a column per body."""
    desc = system.descriptions
    return np.array([np.concatenate([
        np.asarray(desc[k].rot_p0_t, float).ravel(order="F"),
        np.asarray(desc[k].rot_c0, float).ravel(order="F"),
        np.asarray(desc[k].point - desc[k].pos_p0, float),
        np.asarray(desc[k].pos_c0 - desc[k].point, float),
        [float(desc[k].angle_offset)]]) for k in order]).T


def motion(system, q, v, a) -> ca.MX:
    """The bodies' motion, a column per body in chain order: rows vec(A) (0–3), r_G (4–5),
    ṙ_G (6–7), r̈_G (8–9), θ, ω, α (10–12), ρ = J − r_P (13–14), e = r_G − J (15–16)."""
    order = chain_order(system)
    index = [system.ctx.index[name] for name in order]
    data = ca.vertcat(q[index].T, v[index].T, a[index].T, ca.DM(_joint_data(system, order)))
    start = ca.DM([1, 0, 0, 1] + [0] * (_CARRY - 4))
    return _motion_step().mapaccum("chain_motion_fold", len(order))(start, data)


def mass_rows(system, p: ca.MX) -> tuple[ca.MX, ca.MX]:
    """Masses and inertias of the bodies in chain order, two rows (expressions of p)."""
    order = chain_order(system)
    expr = ca.horzcat(*[ca.vertcat(*system._mass_inertia(system.mechanism.bodies[k]))
                        for k in order])
    both = ca.Function("chain_masses", [system.p], [expr])(p)
    return both[0, :], both[1, :]


def folded_energies(system) -> tuple[ca.Function, ca.Function]:
    """``kinetic_energy(q, v, p) -> T`` and ``potential_energy(q, t, p) -> V`` of a chain
    (:func:`supported`) as sums over the folded motion (module notes); the signatures of
    :data:`casmbd.system.equations.SIGNATURES`."""
    q, v = ca.MX.sym("q", system.nq), ca.MX.sym("v", system.nq)
    t, p = ca.MX.sym("t"), ca.MX.sym("p", system.p.numel())
    zero = ca.MX.zeros(system.nq)
    mass, inertia = mass_rows(system, p)
    moving = motion(system, q, v, zero)
    rd, w = moving[6:8, :], moving[11, :]
    kin = 0.5 * (ca.dot(mass, ca.sum1(rd * rd)) + ca.dot(inertia, w * w))
    still = motion(system, q, zero, zero)
    gravity = ca.DM(np.asarray(system.mechanism.gravity, float)).T
    pot = -ca.dot(mass, ca.mtimes(gravity, still[4:6, :]))
    return (ca.Function("kinetic_energy", [q, v, p], [kin], ["q", "v", "p"], ["T"]),
            ca.Function("potential_energy", [q, t, p], [pot], ["q", "t", "p"], ["V"]))


def _marker_group(system, order, motion) -> tuple[list, ca.MX]:
    """Marker positions, velocities, accelerations (stacked per marker) and angles."""
    ctx, mech = system.ctx, system.mechanism
    pos, vel, acc, ang = [], [], [], []
    for m in mech.markers.values():
        col = motion[:, order.index(m.body)]
        rot = ca.reshape(col[:4], 2, 2)
        d = ca.mtimes(rot, ca.DM(np.asarray(ctx.local(m.body, m.point), float)))
        w, al = col[11], col[12]
        pos.append(col[4:6] + d)
        vel.append(col[6:8] + _cross(w, d))
        acc.append(col[8:10] + _cross(al, d) - w**2 * d)
        ang.append(col[10] + float(m.offset(mech.attachment(m.body))))
    stack = [ca.vertcat(*x) for x in (pos, vel, acc)]
    return stack, ca.vertcat(*ang)


def folded_outputs(system) -> ca.Function:
    """``outputs(q, v, a, t, p)`` of a chain (:func:`supported`): the outputs, names and
    layout of :meth:`casmbd.system.outputs.Outputs.outputs_function`, the body and marker
    groups from the folded motion; the joint coordinates (one angle difference each) are
    written out as there."""
    order = chain_order(system)
    qm, vm, am = (ca.MX.sym(s, system.nq) for s in ("q", "v", "a"))
    tm, pm = ca.MX.sym("t"), ca.MX.sym("p", system.p.numel())
    bodies = motion(system, qm, vm, am)
    if order != list(system.body_names):  # the outputs list bodies in declaration order
        bodies = bodies[:, [order.index(b) for b in system.body_names]]
    names, exprs = [], []
    for label, rows in (("body_", (slice(4, 6), slice(6, 8), slice(8, 10))),
                        ("angle_", (10, 11, 12))):
        exprs += [ca.reshape(bodies[r, :], -1, 1) for r in rows]
        names += [label + "positions", label + "velocities", label + "accelerations"]
    markers, marker_angles = _marker_group(system, list(system.body_names), bodies) \
        if system.mechanism.markers else ([ca.MX(0, 1)] * 3, None)
    exprs += markers
    names += ["marker_positions", "marker_velocities", "marker_accelerations"]
    exprs += _joint_group(system, qm, vm, am, tm, pm)
    names += ["joint_positions", "joint_velocities", "joint_accelerations"]
    if marker_angles is not None:
        exprs.append(marker_angles)
        names.append("marker_angles")
    return ca.Function("outputs", [qm, vm, am, tm, pm], exprs, ["q", "v", "a", "t", "p"],
                       names)


def _joint_group(system, qm, vm, am, tm, pm) -> list[ca.MX]:
    """Joint coordinates and their rates as in the unrolled outputs (SX, O(1) per joint)."""
    a = ca.SX.sym("a", system.nq)
    jc = [system._joint_coordinate(j) for j in system.joint_coordinate_names]
    expr = ca.vertcat(*jc) if jc else ca.SX(0, 1)
    vel = ca.jtimes(expr, system.q, system.v)
    acc = ca.jtimes(expr, system.q, a) + ca.jtimes(vel, system.q, system.v)
    f = ca.Function("chain_joint_outputs", [system.q, system.v, a, system.t, system.p],
                    [expr, vel, acc])
    return list(f(qm, vm, am, tm, pm))
