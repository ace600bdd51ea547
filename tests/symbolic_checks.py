"""Checks shared by the tests of the symbolic equations (planar and spatial): a numpy evaluator
of a System's Functions, central differences and a relative comparison."""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd import System

#: finite-difference step of :func:`fd_gradient`
H = 1e-6


def assert_rel(actual, desired, rtol, floor=1e-2, what=""):
    """max|actual − desired| ≤ rtol · max(max|desired|, floor)."""
    actual, desired = np.asarray(actual, float), np.asarray(desired, float)
    assert actual.shape == desired.shape, (what, actual.shape, desired.shape)
    scale = max(float(np.max(np.abs(desired))) if desired.size else 0.0, floor)
    err = float(np.max(np.abs(actual - desired))) if desired.size else 0.0
    assert err <= rtol * scale, f"{what}: error {err:.3g} > {rtol:g} * {scale:.3g}"


def fd_gradient(fun, x, h=H):
    """Central differences of fun (scalar or vector valued) with respect to every entry of x:
    column j is (fun(x + h e_j) − fun(x − h e_j)) / (2 h), error O(h²)."""
    cols = []
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = h
        cols.append((np.asarray(fun(x + e)) - np.asarray(fun(x - e))) / (2 * h))
    return np.array(cols).T


class Evaluator:
    """Dense numpy evaluation of the symbolic Functions of a System (virtual machine)."""

    def __init__(self, system: System):
        self.system, self.p = system, system.parameter_values

    def __call__(self, name: str, *args) -> np.ndarray:
        return np.array(ca.DM(self.system.function(name)(*args, self.p)).full())

    def c(self, q, t):
        return self("constraints", q, t).ravel()

    def cq(self, q, t):
        return self("constraint_jacobian", q, t)

    def ct(self, q, t):
        return self("constraint_time_derivative", q, t).ravel()

    def gamma(self, q, v, t):
        return self("acceleration_rhs", q, v, t).ravel()

    def mass(self, q):
        return self("mass_matrix", q)

    def qv(self, q, v):
        return self("quadratic_velocity_forces", q, v).ravel()

    def qe(self, q, v, t, u):
        return self("applied_forces", q, v, t, u).ravel()

    def kinetic(self, q, v):
        return float(self("kinetic_energy", q, v)[0, 0])

    def potential(self, q, t):
        return float(self("potential_energy", q, t)[0, 0])

    def frames(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Centres of mass (n_b, 3) and rotation matrices (n_b, 3, 3) from the outputs."""
        nq = self.system.nq
        out = self.system.function("outputs")(q=q, v=np.zeros(nq), a=np.zeros(nq), t=0.0,
                                              p=self.p)
        return (np.asarray(out["body_positions"]).reshape(-1, 3),
                np.asarray(out["rotation_matrices"]).reshape(-1, 3, 3))
