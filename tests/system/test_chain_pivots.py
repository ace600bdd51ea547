"""The folded articulated-body pivots of a planar revolute chain
(casmbd.system.chain_pivots, issue 36: the cheap test of check_mass_matrix) against the
factorisation of the unrolled mass matrix."""

from __future__ import annotations

import casadi as ca
import numpy as np

from benchmarks.chains import pendulum_chain
from casmbd.system.chain_pivots import folded_pivots
from casmbd.system.equations import System


def test_pivots_are_the_leaf_first_ldl_of_m():
    """D_i equal the pivots of M = Lᵀ D L eliminated from the tip (Cholesky of M in reversed
    order, squared diagonal) and the second half equals diag M, to 1e-10 relative, at random
    configurations of a 15-rod chain."""
    mech = pendulum_chain(15)
    mech.coordinates = "joint"
    system = System(mech)
    mass = ca.Function("m", [system.q, system.p], [system.mass_matrix])
    pivots = folded_pivots(system)
    rng = np.random.default_rng(3)
    for _ in range(4):
        q = rng.uniform(-1.5, 1.5, system.nq)
        m = np.asarray(ca.DM(mass(q, [])).full())
        rev = m[::-1, ::-1]
        want = np.diag(np.linalg.cholesky(rev))[::-1] ** 2
        got = np.asarray(pivots(q, [])).ravel()
        n = system.nq
        assert np.allclose(got[:n], want, rtol=1e-10, atol=0.0)
        assert np.allclose(got[n:], np.diag(m), rtol=1e-10, atol=0.0)
        assert np.all(got[:n] > 0.0)
