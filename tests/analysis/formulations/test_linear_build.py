"""Post-processing without the joint-space mass matrix (issue 22 item 3): for a system
without constraint equations q̈ comes from the formulation's ODE right-hand side, and equals
the solve of M q̈ = Q of the general post-processing."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from benchmarks.chains import pendulum_chain
from casmbd.analysis.formulations import formulation_kind, post_processing
from casmbd.compiled import codegen
from casmbd.system.equations import System


@pytest.mark.parametrize("formulation", ["articulated", "kkt_ode"])
def test_post_from_the_ode_equals_the_kkt_solve(formulation):
    mech = pendulum_chain(6)
    mech.coordinates = "joint"
    system = System(mech)
    assert system.nc == 0
    ode = formulation_kind(formulation).build(system).function
    general, from_ode = post_processing(system), post_processing(system, None, ode)
    rng = np.random.default_rng(3)
    p = system.parameter_values
    for _ in range(3):
        q, v, t = rng.normal(size=system.nq), rng.normal(size=system.nq), rng.uniform()
        want, got = general(q, v, t, p), from_ode(q, v, t, p)
        acc = np.asarray(want[0]).ravel()
        # M q̈ = Q by QR against the recursion: cond(M) of a 6-rod chain ~1e3
        np.testing.assert_allclose(np.asarray(got[0]).ravel(), acc, rtol=0,
                                   atol=1e-11 * np.max(np.abs(acc)))
        for k in (3, 4):  # kinetic and potential energy: the same expressions
            assert float(got[k]) == float(want[k])
        assert float(got[2]) == 0.0 and np.asarray(got[1]).size == 0


def _c_bytes(function) -> int:
    generator = casadi.CodeGenerator("size.c", dict(codegen._CODEGEN_OPTIONS))
    generator.add(function)
    return len(generator.dump())


def test_post_code_grows_linearly_with_the_ode():
    """Generated C of ``post`` for 16 and 32 rods in joint coordinates: x2.05 from the
    articulated ODE (measured), x2.8 with the dense M and its QR solve (measured)."""
    sizes = {}
    for n in (16, 32):
        mech = pendulum_chain(n)
        mech.coordinates = "joint"
        system = System(mech)
        ode = formulation_kind("articulated").build(system).function
        sizes[n] = (_c_bytes(post_processing(system)),
                    _c_bytes(post_processing(system, None, ode)))
    assert sizes[32][1] / sizes[16][1] <= 2.2
    assert sizes[32][0] / sizes[16][0] >= 2.5


def test_constrained_systems_keep_the_kkt_solve():
    mech = pendulum_chain(3)
    mech.coordinates = "absolute"
    system = System(mech)
    ode = formulation_kind("kkt_ode").build(system).function
    post = post_processing(system, None, ode)
    q, v = system.initial_coordinates(), np.zeros(system.nq)
    lam = np.asarray(post(q, v, 0.0, system.parameter_values)[1]).ravel()
    assert lam.size == system.nc and np.max(np.abs(lam)) > 1.0  # the pins carry the weight


def test_initial_rates_at_rest_without_the_twist_jacobian():
    """Joint coordinates, bodies at rest: the model's initial q̇ is 0 without building the
    symbolic Jacobian of the twists, and equals the System's minimiser; a moving body still
    goes through the System (the minimiser of the kinetic energy of the difference)."""
    from casmbd.compiled.model import NumericModel

    mech = pendulum_chain(5)
    mech.coordinates = "joint"
    system = System(mech)
    model = NumericModel(system, "info", mode="vm")
    np.testing.assert_array_equal(model.initial_velocities(), np.zeros(5))
    np.testing.assert_allclose(system.initial_velocities(), 0.0, atol=1e-15)
    mech.bodies["rod2"].angular_velocity = 0.7
    system = System(mech)
    model = NumericModel(system, "info", mode="vm")
    rates = model.initial_velocities()
    np.testing.assert_allclose(rates, system.initial_velocities(), rtol=0, atol=1e-15)
    assert np.max(np.abs(rates)) > 0.1
