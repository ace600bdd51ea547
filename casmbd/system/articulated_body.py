"""The articulated-body recursion: forward dynamics of a tree in O(N) operations.

Featherstone's articulated-body algorithm written with the system's own kinematics, in global
components and centre-of-mass reference points.  A body's spatial velocity is V = (ω, ṙ_G); a
child C of body P moves as

    V_C = X_C V_P + S_C q̇_C,     A_C = X_C A_P + S_C q̈_C + c_C,

with X_C the rigid transport from P's centre of mass to C's (ω unchanged, ṙ += ω × d), S_C =
∂V_C/∂q̇_C the joint's motion subspace and c_C = J̇_C q̇ − X_C J̇_P q̇ its velocity-product
acceleration, both by AD from the recursive kinematics of :mod:`casmbd.system.tree` (seed 001,
eqs. 256–290).  Body inertia I = diag(A J Aᵀ, m 1), bias b = (ω × A J Aᵀ ω, 0) − w_applied, the
applied wrench found by virtual displacements of the body (so actuators and springs on joint
coordinates enter as equal and opposite wrenches on the two bodies).

Inward pass (leaves to root): I^A = I + Σ X_cᵀ I^a_c X_c, p^A = b + Σ X_cᵀ (p^a_c + I^a_c c_c
+ U_c D_c⁻¹ u_c) with U = I^A S, D = Sᵀ U, u = −Sᵀ p^A, I^a = I^A − U D⁻¹ Uᵀ, p^a = p^A.
Outward pass: A' = X A_P + c, q̈ = D⁻¹ (u − Uᵀ A'), A = A' + S q̈.

It applies to trees without loop joints whose joints have independent rates (revolute,
prismatic, cylindrical, universal, rigid); ball joints and floating bodies carry four Euler
parameters for three rates and stay with the Kane/LDLᵀ path.
"""

from __future__ import annotations

import casadi as ca

from casmbd.errors import ModelError
from casmbd.model.bodies import GROUND


def supported(system, mimic: bool = False) -> str | None:
    """None when the articulated-body recursion applies to ``system``, else the reason.

    ``mimic=True``: the caller's recursion takes substituted mimic followers (a motion
    subspace on the leader's coordinate: Newton–Euler and the composite-body recursions do,
    the articulated-body recursion does not)."""
    if system.local or system.coordinates != "joint":
        return "the recursion needs joint coordinates"
    if system.nc:
        return f"{system.nc} constraint equations (loop joints, drivers or Euler parameters)"
    for name, desc in system.descriptions.items():
        if desc.joint is None:
            return f"body '{name}' floats (no tree joint)"
        if desc.joint.euler_parameters:
            return f"ball joint '{desc.joint.name}' (Euler parameters)"
        if getattr(desc, "mimic", None) is not None and not mimic:
            return (f"joint '{desc.joint.name}' follows another joint (gear '{desc.mimic[0]}' "
                    "substituted): its motion subspace is on its leader's coordinate")
    # gravity and actuators give measure terms: only the force elements can be generalized
    if any(term.kind == "generalized" for force in system.mechanism.forces.values()
           for term in system._element_terms(force, system.ctx)):
        return "a user generalized force cannot be split into body wrenches"
    return None


def motion_transform(d: ca.SX, dim: int) -> ca.SX:
    """X mapping (ω, ṙ) at a point to (ω, ṙ + ω × d) at the point displaced by d."""
    if dim == 2:
        return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(-d[1], 1, 0),
                          ca.horzcat(d[0], 0, 1))
    skew = ca.vertcat(ca.horzcat(0, -d[2], d[1]), ca.horzcat(d[2], 0, -d[0]),
                      ca.horzcat(-d[1], d[0], 0))
    return ca.vertcat(ca.horzcat(ca.SX.eye(3), ca.SX.zeros(3, 3)),
                      ca.horzcat(-skew, ca.SX.eye(3)))


def articulated_accelerations(system, applied: bool = True, efforts: ca.SX | None = None
                              ) -> ca.SX:
    """q̈(q, q̇, t, u, p) of a tree by the articulated-body recursion (see module docstring).

    ``efforts``: generalized forces τ on the joint coordinates (a column of n_q), added to
    each joint's u = τ_i − Sᵀ p^A (Featherstone, Rigid Body Dynamics Algorithms, Table 7.1);
    default none.
    """
    reason = supported(system)
    if reason:
        raise ModelError(f"articulated-body recursion not applicable: {reason}")
    ctx, dim = system.ctx, system.dimension
    names = system.body_names
    desc = system.descriptions
    children: dict[str, list[str]] = {name: [] for name in names}
    for name in names:
        if desc[name].parent != GROUND:
            children[desc[name].parent].append(name)
    order: list[str] = []

    def visit(name: str) -> None:
        if name in order:
            return
        if desc[name].parent != GROUND:
            visit(desc[name].parent)
        order.append(name)

    for name in names:
        visit(name)
    tk = system.tree_kinematics
    nw = 1 if dim == 2 else 3
    xform, motion, bias_acc, inertia, bias = {}, {}, {}, {}, {}
    for name in order:
        omega = tk.twist[name][:nw]
        r_g = ctx.centre_of_mass(name)
        parent = desc[name].parent
        if parent == GROUND:
            xform[name] = None
            bias_acc[name] = tk.bias[name]
        else:
            d = r_g - ctx.centre_of_mass(parent)
            xform[name] = motion_transform(d, dim)
            bias_acc[name] = tk.bias[name] - ca.mtimes(xform[name], tk.bias[parent])
        motion[name] = tk.motion[name]
        mass, tensor = system._mass_inertia(system.mechanism.bodies[name])
        if dim == 2:
            inertia[name] = ca.diagcat(tensor, mass * ca.SX.eye(2))
            spin = ca.SX(0.0)
        else:
            rot = ctx.rotation(name)
            tensor = ca.mtimes([rot, tensor, rot.T])
            inertia[name] = ca.diagcat(tensor, mass * ca.SX.eye(3))
            spin = ca.cross(omega, ca.mtimes(tensor, omega))
        wrench = ca.SX.zeros(dim + (1 if dim == 2 else 3))
        if applied:
            wrench, _ = system._applied_wrench(name)  # (force, moment about G)
        k = dim
        bias[name] = ca.vertcat(spin - wrench[k:], -wrench[:k])
    art_inertia, art_bias, u_mat, d_inv, u_vec = {}, {}, {}, {}, {}
    for name in reversed(order):
        i_a, p_a = inertia[name], bias[name]
        for child in children[name]:
            x = xform[child]
            ia_c, pa_c = art_inertia[child], art_bias[child]
            if u_mat[child] is not None:
                ia_c = ia_c - ca.mtimes([u_mat[child], d_inv[child], u_mat[child].T])
                pa_c = pa_c + ca.mtimes([u_mat[child], d_inv[child], u_vec[child]])
            pa_c = pa_c + ca.mtimes(ia_c, bias_acc[child])
            i_a = i_a + ca.mtimes([x.T, ia_c, x])
            p_a = p_a + ca.mtimes(x.T, pa_c)
        art_inertia[name], art_bias[name] = i_a, p_a
        s = motion[name]
        if s.size2() == 0:
            u_mat[name] = d_inv[name] = u_vec[name] = None
            continue
        u_mat[name] = ca.mtimes(i_a, s)
        d_mat = ca.mtimes(s.T, u_mat[name])
        d_inv[name] = 1.0 / d_mat if d_mat.numel() == 1 else ca.inv(d_mat)
        u_vec[name] = -ca.mtimes(s.T, p_a)
        if efforts is not None:
            u_vec[name] = u_vec[name] + system.body_part(efforts, name)
    acc: dict[str, ca.SX] = {}
    qdd = {}
    for name in order:
        parent = desc[name].parent
        if parent == GROUND:
            a_prime = bias_acc[name]
        else:
            a_prime = ca.mtimes(xform[name], acc[parent]) + bias_acc[name]
        if u_mat[name] is None:
            acc[name] = a_prime
            qdd[name] = ca.SX(0, 1)
            continue
        qdd[name] = ca.mtimes(d_inv[name], u_vec[name] - ca.mtimes(u_mat[name].T, a_prime))
        acc[name] = a_prime + ca.mtimes(motion[name], qdd[name])
    return ca.vertcat(*[qdd[name] for name in names])
