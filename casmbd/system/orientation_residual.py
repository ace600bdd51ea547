"""The three equations of an orientation driver: a spatial body's rotation A equals A_d(t).

C = 2 axial(R_e − R_eᵀ) / (1 + tr R_e), R_e = A A_dᵀ, is the Gibbs (Rodrigues) vector
2 tan(θ/2) n of the error rotation (θ about the global axis n): the vector part of the error
quaternion r = p ⊗ p_d* divided by ½ r_0 (for a rotation matrix, axial(R − Rᵀ) = 4 r_0 r_v and
1 + tr R = 4 r_0²). It vanishes only at R_e = I, is the same for ±p, needs only A (absolute,
natural and joint coordinates alike) and at the solution δC = δπ, the global virtual rotation,
so the multipliers are the moment on the body about the global axes
(:class:`~casmbd.model.drivers.OrientationDriver`). Its Jacobian is regular for error
rotations below a half-turn (r_0 ≠ 0) and fails at θ = ±180° (1 + tr R_e → 0).
C_t and γ follow by automatic differentiation like every driver's.
"""

from __future__ import annotations

import casadi as ca

from casmbd.model.rotations import (
    euler_zxz_to_quaternion,
    quaternion_from_axis_angle,
    quaternion_multiply,
    rotation_matrix,
)
from casmbd.model.values import resolve


def prescribed_rotation(form: str, values: list[ca.SX]) -> ca.SX:
    """A_d(t) of the expressions ``values`` in ``form`` (euler_zxz, rpy or quaternion).

    * ``euler_zxz`` [φ, θ, ψ]: A_Z(φ) A_X(θ) A_Z(ψ) (seed 001, "Euler angles", eqs. 28–32);
    * ``rpy`` [roll, pitch, yaw]: URDF's fixed-axis X-Y-Z, A_Z(yaw) A_Y(pitch) A_X(roll);
    * ``quaternion`` [w, x, y, z]: A(p/|p|).
    """
    if form == "euler_zxz":
        return rotation_matrix(euler_zxz_to_quaternion(*values))
    if form == "rpy":
        roll, pitch, yaw = values
        q = quaternion_multiply(
            quaternion_multiply(quaternion_from_axis_angle(ca.DM([0, 0, 1]), yaw),
                                quaternion_from_axis_angle(ca.DM([0, 1, 0]), pitch)),
            quaternion_from_axis_angle(ca.DM([1, 0, 0]), roll))
        return rotation_matrix(q)
    p = ca.vertcat(*values)
    return rotation_matrix(p / ca.norm_2(p))


def orientation_residual(rotation: ca.SX, target: ca.SX) -> ca.SX:
    """C = 2 axial(R_e − R_eᵀ) / (1 + tr R_e), R_e = A A_dᵀ (3 × 1; module docstring)."""
    r = ca.mtimes(rotation, target.T)
    axial = ca.vertcat(r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1])
    return 2.0 * axial / (1.0 + ca.trace(r))


def half_turn_margins(system) -> tuple[list[str], ca.SX]:
    """The orientation drivers of ``system`` (by name) and r_0² = (1 + tr R_e) / 4 of each,
    the squared scalar part of its error quaternion (1 at A = A_d, 0 half a turn away, where
    C is 0/0 in floating point and its Jacobian singular)."""
    names, margins = [], []
    for driver in system.mechanism.drivers.values():
        if driver.orientation_row is None or driver.orientation_row in names:
            continue
        values = [resolve(a, system.t, system.ctx.p, f"driver '{driver.orientation_row}' "
                          f"field '{driver.form}'") for a in driver.angles]
        target = prescribed_rotation(driver.form, values)
        names.append(driver.orientation_row)
        margins.append(0.25 * (1.0 + ca.trace(ca.mtimes(system.ctx.rotation(driver.body),
                                                        target.T))))
    return names, ca.vertcat(*margins) if margins else ca.SX(0, 1)
