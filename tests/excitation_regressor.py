"""A Lagrangian joint-torque regressor of a tree in joint coordinates, for the excitation tests.

Independent of casmbd's Newton–Euler and of h-regressor's module: each body carries the standard
parameters about its *reference frame* (origin at its nominal centre of mass, body axes), π_i = (m,
m cx, m cy, m cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz), and the Lagrangian

    L = Σ_i ½ m |ṙ_O|² + m ṙ_O · (ω × R c) + ½ ω_bᵀ I_O ω_b + m g·r_O + g · R (m c)

is linear in π (in the plane π_i = (m, m cx, m cy, Izz) and ω × x = ω (−x_y, x_x)), so τ = d/dt
∂L/∂q̇ − ∂L/∂q = Y(q, v, a) π with Y = ∂τ/∂π by AD (Khalil & Dombre, Modeling, Identification and
Control of Robots, §12.3). A joint's friction adds the columns (q̇_j, tanh(q̇_j / v_s)) for
(viscous, Coulomb).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.system.equations import System

INERTIAL = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")


def lagrangian_regressor(mechanism, joints=(), regularization=1e-3):
    """(Y Function (q, v, a) → n × p on SX, parameter names, nominal π)."""
    system = System(mechanism, coordinates="joint")
    ctx, q, v = system.ctx, system.q, system.v
    g = ca.DM(np.asarray(mechanism.gravity, float))
    lag, params, nominal, names = ca.SX(0), [], [], []
    planar = mechanism.dimension == 2
    for name in system.body_names:
        body = mechanism.bodies[name]
        r, rot = ctx.centre_of_mass(name), ctx.rotation(name)
        rdot = ca.jtimes(r, q, v)
        mass, tensor = system._mass_inertia(body)
        tensor = np.atleast_2d(np.array(ca.DM(ca.evalf(tensor))))
        if planar:  # π_i = (m, m cx, m cy, Izz)
            pi = ca.SX.sym(f"pi_{name}", 4)
            m, mc, izz = pi[0], pi[1:3], pi[3]
            omega = ca.mtimes(rot.T, ca.jtimes(rot, q, v))[1, 0]
            rc = ca.mtimes(rot, mc)
            lag += (0.5 * m * ca.dot(rdot, rdot) + omega * (rdot[1] * rc[0] - rdot[0] * rc[1])
                    + 0.5 * izz * omega ** 2 + m * ca.dot(g, r) + ca.dot(g, rc))
            nominal.append([float(ca.evalf(mass)), 0.0, 0.0, tensor[0, 0]])
            names += [f"{name}.{k}" for k in ("m", "mcx", "mcy", "Izz")]
            params.append(pi)
            continue
        pi = ca.SX.sym(f"pi_{name}", 10)
        m, mc = pi[0], pi[1:4]
        inertia = ca.vertcat(ca.horzcat(pi[4], pi[5], pi[6]), ca.horzcat(pi[5], pi[7], pi[8]),
                             ca.horzcat(pi[6], pi[8], pi[9]))
        # ω from Ṙ Rᵀ (skew), global components
        wskew = ca.mtimes(ca.jtimes(rot, q, v), rot.T)
        omega = ca.vertcat(wskew[2, 1], wskew[0, 2], wskew[1, 0])
        wb = ca.mtimes(rot.T, omega)
        lag += (0.5 * m * ca.dot(rdot, rdot) + ca.dot(rdot, ca.cross(omega, ca.mtimes(rot, mc)))
                + 0.5 * ca.mtimes([wb.T, inertia, wb]) + m * ca.dot(g, r)
                + ca.dot(g, ca.mtimes(rot, mc)))
        params.append(pi)
        nominal.append([float(ca.evalf(mass)), 0, 0, 0, tensor[0, 0], tensor[0, 1], tensor[0, 2],
                        tensor[1, 1], tensor[1, 2], tensor[2, 2]])
        names += [f"{name}.{k}" for k in INERTIAL]
    a = ca.SX.sym("a", q.numel())
    mom = ca.gradient(lag, v)
    tau = ca.mtimes(ca.jacobian(mom, q), v) + ca.mtimes(ca.jacobian(mom, v), a) \
        - ca.gradient(lag, q)
    pi = ca.vertcat(*params)
    y = ca.jacobian(tau, pi)
    cols = [y]
    for joint in joints:
        rate = ca.jtimes(ctx.joint_coordinate(joint), q, v)
        fric = ca.jacobian(ctx.joint_coordinate(joint), q).T
        cols.append(ca.horzcat(fric * rate, fric * ca.tanh(rate / regularization)))
        names += [f"{joint}.viscous", f"{joint}.coulomb"]
        nominal.append([0.0, 0.0])
    ymat = ca.horzcat(*cols)
    ymat = ca.substitute(ymat, system.ctx.t, 0.0) if ca.depends_on(ymat, system.ctx.t) else ymat
    fun = ca.Function("Y", [q, v, a], [ymat], ["q", "v", "a"], ["Y"])
    return fun, names, np.concatenate([np.ravel(x) for x in nominal])
