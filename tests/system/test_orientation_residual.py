"""The orientation driver's equations (casmbd/system/orientation_residual.py) in closed form.

C(A, A_d) = 2 axial(R_e − R_eᵀ)/(1 + tr R_e), R_e = A A_dᵀ, must be the Gibbs vector
2 tan(θ/2) n of the error rotation (θ about n, global axes; 1e-12 relative), vanish at
A = A_d for any A_d, have the Jacobian I with respect to a global virtual rotation δπ at the
solution (A = exp([δπ]) A_d; central differences, 1e-9), stay regular approaching a
half-turn (Jacobian determinant > 1 at 179°) and read 0/0 at exactly 180°. The three
prescription forms agree with their matrices (1e-15).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.model.rotations import (
    euler_zxz_to_quaternion,
    quaternion_from_axis_angle,
    rotation_matrix,
)
from casmbd.system.orientation_residual import orientation_residual, prescribed_rotation


def _residual(a, a_d):
    return np.asarray(ca.DM(orientation_residual(ca.SX(a), ca.SX(a_d)))).ravel()


def _axis_angle(n, theta):
    return rotation_matrix(quaternion_from_axis_angle(np.asarray(n, float), theta))


A_D = rotation_matrix(euler_zxz_to_quaternion(0.4, 1.1, -0.7))
N = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])


def test_the_residual_is_the_gibbs_vector_of_the_error_rotation():
    for theta in (0.0, 0.3, 2.0, 3.0, -2.5):
        c = _residual(_axis_angle(N, theta) @ A_D, A_D)
        # rounding grows like 1/cos²(θ/2) (1 + tr R_e cancels): 200 at θ = 3
        assert np.max(np.abs(c - 2 * np.tan(theta / 2) * N)) <= 1e-12 * max(1, abs(c).max())
    assert np.max(np.abs(_residual(A_D, A_D))) == 0.0


def test_the_jacobian_is_the_identity_in_global_virtual_rotations():
    h = 1e-6
    jac = np.column_stack([(_residual(_axis_angle(e, h) @ A_D, A_D)
                            - _residual(_axis_angle(e, -h) @ A_D, A_D)) / (2 * h)
                           for e in np.eye(3)])
    assert np.max(np.abs(jac - np.eye(3))) <= 1e-9


def test_regular_short_of_a_half_turn_and_zero_over_zero_at_it():
    h, base = 1e-7, _axis_angle(N, np.radians(179.0)) @ A_D
    jac = np.column_stack([(_residual(_axis_angle(e, h) @ base, A_D)
                            - _residual(_axis_angle(e, -h) @ base, A_D)) / (2 * h)
                           for e in np.eye(3)])
    assert np.linalg.det(jac) > 1.0  # grows like 1/cos²(θ/2)
    r = _axis_angle(N, np.pi) @ A_D @ A_D.T
    assert np.max(np.abs(r - r.T)) <= 1e-15 and abs(1 + np.trace(r)) <= 1e-15


def test_the_prescription_forms():
    t = ca.SX.sym("t")
    for form, values, expected in (
            ("euler_zxz", [0.4, 1.1, -0.7], A_D),
            ("rpy", [0.3, -0.2, 1.0], _axis_angle([0, 0, 1], 1.0) @ _axis_angle([0, 1, 0], -0.2)
             @ _axis_angle([1, 0, 0], 0.3)),
            ("quaternion", [2.0, 0.0, 0.0, 2.0], _axis_angle([0, 0, 1], np.pi / 2))):
        fn = ca.Function("a", [t], [prescribed_rotation(form, [ca.SX(v) + 0 * t
                                                               for v in values])])
        assert np.max(np.abs(np.asarray(fn(0.0)) - expected)) <= 1e-15, form
