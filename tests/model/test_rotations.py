"""Rotation utilities (casmbd.model.rotations) against identities and independent formulas.

Every test compares numbers with a stated tolerance:

* A(p) orthogonal with det 1 for random unit quaternions (1e-14);
* A(p) against Rodrigues' formula of the axis-angle rotation (1e-14);
* Shepperd's quaternion_from_matrix round trip, sign-normalized (1e-14), incl. 180° rotations;
* Z-X-Z and X-Y-Z Euler angles: round trips away from the singularity (1e-12) and a
  RuntimeWarning naming theta near it, the reconstructed rotation exact at the singularity
  (1e-12) and within 2|sin θ| (2|cos θ| for X-Y-Z) next to it;
* composition A(p ⊗ q) = A(p) A(q) (1e-14);
* E Eᵀ = I, G Gᵀ = I, E p = 0, G p = 0, A = E Gᵀ (1e-14);
* ω̃ = Ȧ Aᵀ by central differences against 2 E ṗ, and Aᵀ ω against 2 G ṗ (1e-7);
* the CasADi SX and MX paths give the numpy numbers (1e-14);
* inertia_tensor rejects bad input with ModelError naming the failed condition.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from casmbd.errors import ModelError
from casmbd.model import rotations as rot

TOL = 1e-14


def random_quaternions(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def elementary(axis: str, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def sign_normalized(p: np.ndarray) -> np.ndarray:
    return -p if p[0] < 0 else p


QUATS = random_quaternions(50)


def test_skew_is_cross_product():
    a, b = np.array([0.3, -1.2, 2.0]), np.array([1.1, 0.4, -0.7])
    S = rot.skew(a)
    assert np.max(np.abs(S @ b - np.cross(a, b))) < TOL
    assert np.max(np.abs(S + S.T)) == 0.0


def test_rotation_matrix_orthogonal_det_one():
    for p in QUATS:
        A = rot.rotation_matrix(p)
        assert A.shape == (3, 3)
        assert np.max(np.abs(A.T @ A - np.eye(3))) < TOL
        assert abs(np.linalg.det(A) - 1.0) < TOL


def test_rotation_matrix_equals_rodrigues():
    rng = np.random.default_rng(1)
    for _ in range(50):
        axis = rng.normal(size=3)
        angle = rng.uniform(-2 * math.pi, 2 * math.pi)
        p = rot.quaternion_from_axis_angle(axis, angle)
        assert abs(np.linalg.norm(p) - 1.0) < TOL
        assert np.max(np.abs(rot.rotation_matrix(p) - rodrigues(axis, angle))) < TOL
    # elementary rotations (seed 001 eqs. 19-21)
    for name, axis in (("x", [1, 0, 0]), ("y", [0, 1, 0]), ("z", [0, 0, 1])):
        A = rot.rotation_matrix(rot.quaternion_from_axis_angle(axis, 0.7))
        assert np.max(np.abs(A - elementary(name, 0.7))) < TOL


def test_quaternion_from_axis_angle_rejects_zero_axis():
    with pytest.raises(ValueError, match="non-zero"):
        rot.quaternion_from_axis_angle([0.0, 0.0, 0.0], 1.0)


def test_quaternion_from_matrix_round_trip():
    for p in QUATS:
        q = rot.quaternion_from_matrix(rot.rotation_matrix(p))
        assert q[0] >= 0.0
        assert np.max(np.abs(q - sign_normalized(p))) < TOL
    # each Shepperd branch, including half-turns (e0 = 0) and the identity
    for p in ([1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1],
              [0, 0.6, 0.8, 0], [0.1, 0.1, 0.1, 0.98]):
        p = np.asarray(p, float) / np.linalg.norm(p)
        q = rot.quaternion_from_matrix(rot.rotation_matrix(p))
        assert np.max(np.abs(rot.rotation_matrix(q) - rot.rotation_matrix(p))) < TOL
        if p[0] > 0:
            assert np.max(np.abs(q - p)) < TOL


def test_quaternion_from_matrix_rejects_non_rotation():
    with pytest.raises(ValueError, match="proper rotation"):
        rot.quaternion_from_matrix(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="3x3"):
        rot.quaternion_from_matrix(np.eye(2))


def test_composition():
    for p, q in zip(QUATS[:25], QUATS[25:]):
        pq = rot.quaternion_multiply(p, q)
        assert np.max(np.abs(rot.rotation_matrix(pq) - rot.rotation_matrix(p)
                             @ rot.rotation_matrix(q))) < TOL
        pc = rot.quaternion_conjugate(p)
        assert np.max(np.abs(rot.rotation_matrix(pc) - rot.rotation_matrix(p).T)) < TOL
        assert np.max(np.abs(rot.quaternion_multiply(p, pc) - [1, 0, 0, 0])) < TOL


def test_euler_zxz_matrix_and_round_trip():
    rng = np.random.default_rng(2)
    for _ in range(50):
        phi, psi = rng.uniform(-math.pi, math.pi, size=2)
        theta = rng.uniform(0.05, math.pi - 0.05)
        p = rot.euler_zxz_to_quaternion(phi, theta, psi)
        A_ref = elementary("z", phi) @ elementary("x", theta) @ elementary("z", psi)
        assert np.max(np.abs(rot.rotation_matrix(p) - A_ref)) < TOL
        back = rot.quaternion_to_euler_zxz(p)
        assert np.max(np.abs(np.array(back) - [phi, theta, psi])) < 1e-12


def test_euler_zxz_singularity_warns():
    for theta in (0.0, 1e-8, math.pi, math.pi - 1e-8):
        p = rot.euler_zxz_to_quaternion(0.4, theta, 0.3)
        with pytest.warns(RuntimeWarning, match="theta"):
            phi, th, psi = rot.quaternion_to_euler_zxz(p)
        assert psi == 0.0
        A = rot.rotation_matrix(rot.euler_zxz_to_quaternion(phi, th, psi))
        # exact at the singularity; near it, dropping psi costs O(|sin theta|)
        assert np.max(np.abs(A - rot.rotation_matrix(p))) < 1e-12 + 2 * abs(math.sin(theta))


def test_euler_xyz_matrix_and_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(50):
        phi, psi = rng.uniform(-math.pi, math.pi, size=2)
        theta = rng.uniform(-math.pi / 2 + 0.05, math.pi / 2 - 0.05)
        p = rot.euler_xyz_to_quaternion(phi, theta, psi)
        A_ref = elementary("x", phi) @ elementary("y", theta) @ elementary("z", psi)
        assert np.max(np.abs(rot.rotation_matrix(p) - A_ref)) < TOL
        back = rot.quaternion_to_euler_xyz(p)
        assert np.max(np.abs(np.array(back) - [phi, theta, psi])) < 1e-12


def test_euler_xyz_singularity_warns():
    for theta in (math.pi / 2, -math.pi / 2, math.pi / 2 - 1e-8):
        p = rot.euler_xyz_to_quaternion(0.4, theta, 0.3)
        with pytest.warns(RuntimeWarning, match="theta"):
            phi, th, psi = rot.quaternion_to_euler_xyz(p)
        assert psi == 0.0
        A = rot.rotation_matrix(rot.euler_xyz_to_quaternion(phi, th, psi))
        # exact at the singularity; near it, dropping psi costs O(|cos theta|)
        assert np.max(np.abs(A - rot.rotation_matrix(p))) < 1e-12 + 2 * abs(math.cos(theta))


def test_e_g_matrix_identities():
    for p in QUATS:
        E, G = rot.E_matrix(p), rot.G_matrix(p)
        assert E.shape == G.shape == (3, 4)
        assert np.max(np.abs(E @ E.T - np.eye(3))) < TOL
        assert np.max(np.abs(G @ G.T - np.eye(3))) < TOL
        assert np.max(np.abs(E @ p)) < TOL
        assert np.max(np.abs(G @ p)) < TOL
        assert np.max(np.abs(E @ G.T - rot.rotation_matrix(p))) < TOL


def test_angular_velocity_against_finite_difference():
    rng = np.random.default_rng(4)
    h = 1e-5
    for p0 in QUATS[:10]:
        w0 = rng.normal(size=3)  # body-frame angular velocity of p(t) = p0 ⊗ exp(t w0 / 2)
        nw = np.linalg.norm(w0)

        def p_of(t, p0=p0, w0=w0, nw=nw):
            return rot.quaternion_multiply(p0, rot.quaternion_from_axis_angle(w0, t * nw))

        for t in (0.0, 0.37):
            p = p_of(t)
            A = rot.rotation_matrix(p)
            Adot = (rot.rotation_matrix(p_of(t + h)) - rot.rotation_matrix(p_of(t - h))) / (2 * h)
            W = Adot @ A.T  # seed 001 eq. 39
            omega_fd = np.array([W[2, 1], W[0, 2], W[1, 0]])
            assert np.max(np.abs(W + W.T)) < 1e-7
            pdot = 0.5 * rot.quaternion_multiply(p, np.concatenate(([0.0], w0)))
            pdot_fd = (p_of(t + h) - p_of(t - h)) / (2 * h)
            assert np.max(np.abs(pdot - pdot_fd)) < 1e-7
            omega = rot.angular_velocity_global(p, pdot)
            assert np.max(np.abs(omega - omega_fd)) < 1e-7
            assert np.max(np.abs(rot.angular_velocity_global(p, pdot_fd) - omega_fd)) < 1e-7
            omega_b = rot.angular_velocity_body(p, pdot)
            assert np.max(np.abs(omega_b - w0)) < 1e-14
            assert np.max(np.abs(A.T @ omega_fd - omega_b)) < 1e-7
            # inverse map
            assert np.max(np.abs(rot.quaternion_rate(p, omega) - pdot)) < 1e-14


@pytest.mark.parametrize("kind", [ca.SX, ca.MX])
def test_symbolic_path_matches_numpy(kind):
    p, q = kind.sym("p", 4), kind.sym("q", 4)
    pd, w, a = kind.sym("pd", 4), kind.sym("w", 3), kind.sym("a", 3)
    ang = kind.sym("ang", 3)
    outs = [
        rot.rotation_matrix(p), rot.E_matrix(p), rot.G_matrix(p), rot.skew(a),
        rot.quaternion_multiply(p, q), rot.quaternion_conjugate(p),
        rot.angular_velocity_global(p, pd), rot.angular_velocity_body(p, pd),
        rot.quaternion_rate(p, w), rot.quaternion_from_axis_angle(a, ang[0]),
        rot.euler_zxz_to_quaternion(ang[0], ang[1], ang[2]),
        rot.euler_xyz_to_quaternion(ang[0], ang[1], ang[2]),
    ]
    for o in outs:
        assert isinstance(o, kind)
    f = ca.Function("f", [p, q, pd, w, a, ang], outs)
    rng = np.random.default_rng(5)
    for pv, qv in zip(QUATS[:5], QUATS[5:10]):
        pdv, wv, av = rng.normal(size=4), rng.normal(size=3), rng.normal(size=3)
        angv = rng.uniform(-3, 3, size=3)
        got = [np.array(r) for r in f(pv, qv, pdv, wv, av, angv)]
        want = [
            rot.rotation_matrix(pv), rot.E_matrix(pv), rot.G_matrix(pv), rot.skew(av),
            rot.quaternion_multiply(pv, qv), rot.quaternion_conjugate(pv),
            rot.angular_velocity_global(pv, pdv), rot.angular_velocity_body(pv, pdv),
            rot.quaternion_rate(pv, wv), rot.quaternion_from_axis_angle(av, angv[0]),
            rot.euler_zxz_to_quaternion(*angv), rot.euler_xyz_to_quaternion(*angv),
        ]
        for g, wnt in zip(got, want):
            assert np.max(np.abs(g.reshape(wnt.shape) - wnt)) < TOL


def test_symbolic_list_of_scalars():
    e = [ca.SX.sym(f"e{i}") for i in range(4)]
    A = rot.rotation_matrix(e)
    assert isinstance(A, ca.SX) and A.shape == (3, 3)
    f = ca.Function("f", [ca.vertcat(*e)], [A])
    p = QUATS[0]
    assert np.max(np.abs(np.array(f(p)) - rot.rotation_matrix(p))) < TOL


def test_inertia_tensor_valid():
    J = rot.inertia_tensor([1.0, 2.0, 2.5])
    assert np.array_equal(J, np.diag([1.0, 2.0, 2.5]))
    J = rot.inertia_tensor([2.0, 3.0, 4.0, 0.1, -0.2, 0.3])
    assert np.array_equal(J, J.T)
    assert J[0, 1] == 0.1 and J[0, 2] == -0.2 and J[1, 2] == 0.3
    # a thin plate sits on the triangle-inequality boundary (Izz = Ixx + Iyy)
    rot.inertia_tensor([1.0, 2.0, 3.0])
    # a rotated valid tensor stays valid
    C = rot.rotation_matrix(QUATS[3])
    Jr = C @ np.diag([1.0, 2.0, 2.9]) @ C.T
    out = rot.inertia_tensor([Jr[0, 0], Jr[1, 1], Jr[2, 2], Jr[0, 1], Jr[0, 2], Jr[1, 2]])
    assert np.max(np.abs(out - Jr)) < TOL


@pytest.mark.parametrize(
    ("values", "pattern"),
    [
        ([1.0, 2.0, 0.0], "not positive definite"),
        ([1.0, -2.0, 2.0], "not positive definite"),
        ([1.0, 1.0, 1.0, 2.0, 0.0, 0.0], "not positive definite"),
        ([1.0, 1.0, 3.0], r"triangle inequality Ixx \+ Iyy >= Izz"),
        ([5.0, 1.0, 2.0], r"triangle inequality Iyy \+ Izz >= Ixx"),
        ([1.0, 3.0, 1.5], r"triangle inequality Izz \+ Ixx >= Iyy"),
        ([1.0, 2.0], "3 values"),
        ([1.0, 2.0, float("nan")], "finite"),
        (["a", 1.0, 1.0], "numbers"),
    ],
)
def test_inertia_tensor_rejects(values, pattern):
    with pytest.raises(ModelError, match=pattern):
        rot.inertia_tensor(values)


def test_inertia_tensor_rejects_principal_triangle_violation():
    # diagonal satisfies the triangle inequalities, principal moments do not
    vals = [2.0, 2.0, 2.0, 0.0, 0.0, 0.95]  # principal moments 1.05, 2, 2.95 -> ok
    rot.inertia_tensor(vals)
    vals = [2.0, 2.0, 3.0, 1.0, 0.0, 0.0]  # principal 1, 3, 3: 1 + 3 >= 3 fine
    rot.inertia_tensor(vals)
    vals = [1.5, 1.5, 2.9, 1.4, 0.0, 0.0]  # principal 0.1, 2.9, 2.9 -> 0.1 + 2.9 >= 2.9 ok
    rot.inertia_tensor(vals)
    vals = [2.0, 2.0, 3.9, 1.9, 0.0, 0.0]  # diag ok (2+2 >= 3.9); principal 0.1, 3.9, 3.9
    rot.inertia_tensor(vals)
    vals = [2.5, 2.5, 4.5, 2.4, 0.0, 0.0]  # diag ok (5 >= 4.5); principal 0.1, 4.9, 4.5
    with pytest.raises(ModelError, match="principal triangle inequality"):
        rot.inertia_tensor(vals)
