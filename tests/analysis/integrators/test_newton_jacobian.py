"""The SUNDIALS Newton methods use the exact compiled Jacobian (issue 36, item 4).

CVODES-BDF and IDAS form the Newton matrix from ∂f/∂x of the dynamics.  The ODE formulations
of at most :data:`~casmbd.analysis.dynamics.stepping.NEWTON_JACOBIAN_MAX` states get their
dynamics compiled with the ``jac_<name>`` companion in a library of their own, on first use
by a Newton method, loaded so that CasADi calls it (with ``enable_fd`` CasADi prefers central
differences of the right-hand side); larger ones get forward differences.

The checks: the compiled Jacobian equals central differences of the compiled right-hand side
(step 1e-6 (1 + |x_i|), truncation ≈ 1e-12 · f''') to 1e-6 relative to its largest entry; the
integrator's Newton-matrix Function calls ``jac_<name>`` and no finite-difference Function; a
run with it ends where the same integrator on the finite-difference path ends, to 1e-7 at
rtol = atol = 1e-10 (both are that accurate; measured difference ≈ 1e-10).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import private_cache

from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.integrators import sundials as sun

_cache = private_cache("cache_newton_jacobian", scope="module")

#: relative agreement of the compiled Jacobian with central differences
JAC_RTOL = 1e-6
#: final-state agreement of the exact-Jacobian and finite-difference runs at rtol 1e-10
RUN_TOL = 1e-7


def _chain3():
    from benchmarks.chains import pendulum_chain

    mech = pendulum_chain(3)
    mech.name = "newton_jacobian_chain3"
    return mech


@pytest.fixture(scope="module")
def chain():
    return Simulator(_chain3())


def _called(solver: ca.Function) -> list[str]:
    """The Functions the integrator's Newton-matrix Function (``jacF``) calls."""
    g = solver.get_function("jacF")
    return [g.instruction_MX(i).which_function().name() for i in range(g.n_instructions())
            if g.instruction_MX(i).op() == ca.OP_CALL]


def _state(sim, seed):
    rng = np.random.default_rng(seed)
    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    return x0 + 0.3 * rng.standard_normal(x0.shape)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_jacobian_equals_central_differences(chain, seed):
    dyn = chain.sundials_dynamics("cvodes")
    assert dyn is not chain.dyn and dyn.is_a("External")
    nx = dyn.nnz_in(1)
    x = _state(chain, seed)
    args = [0.0, x, np.zeros(0), chain.model.p, np.zeros(dyn.nnz_in(4))]
    jac = dyn.jacobian()
    assert jac.name() == f"jac_{dyn.name()}" and jac.is_a("External")
    exact = np.asarray(jac(*args, *dyn(*args))[1], float)  # jac_ode_x
    fd = np.empty((nx, nx))
    for i in range(nx):
        h = 1e-6 * (1.0 + abs(x[i]))
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        fp = np.asarray(chain.dyn(0.0, xp, *args[2:])[0], float).ravel()
        fm = np.asarray(chain.dyn(0.0, xm, *args[2:])[0], float).ravel()
        fd[:, i] = (fp - fm) / (2 * h)
    scale = np.max(np.abs(exact))
    assert scale > 1.0  # gravity and the coupling make ∂q̈/∂q of order g / l
    assert np.max(np.abs(exact - fd)) <= JAC_RTOL * scale


def test_newton_matrix_calls_the_compiled_jacobian(chain):
    for sim, plugin in ((chain, "cvodes"), (chain, "idas")):
        dyn = sim.sundials_dynamics(plugin)
        solver = sun.sundials(dyn, plugin, 0.0, [0.1], 1e-8, 1e-8, 1000,
                              xdot0=np.zeros(dyn.nnz_in(1)))
        called = _called(solver)
        assert f"jac_{dyn.name()}" in called, (plugin, called)
        assert not any(n.startswith(("fwd", "adj")) for n in called), (plugin, called)
    # Adams (functional iteration) needs no Jacobian: the model's dynamics as compiled
    assert chain.sundials_dynamics("adams") is chain.dyn


@pytest.mark.parametrize("plugin", ["cvodes", "idas"])
def test_run_with_exact_jacobian_matches_finite_difference_path(chain, plugin):
    grid = np.linspace(0.0, 2.0, 5)
    res = chain.run(2.0, 4, integrator=plugin, rtol=1e-10, atol=1e-10)
    x0 = np.concatenate([chain.model.initial_coordinates(), chain.model.initial_velocities()])
    xdot0 = np.asarray(chain.dyn(0.0, x0, np.zeros(0), chain.model.p,
                                 np.zeros(chain.dyn.nnz_in(4)))[0], float).ravel()
    fd_path = sun.sundials(chain.dyn, plugin, 0.0, grid[1:], 1e-10, 1e-10, 10 ** 5,
                           xdot0=xdot0)
    assert "jac_" not in " ".join(_called(fd_path))  # the previous path really differs
    xs = np.asarray(fd_path(x0=x0, z0=np.zeros(0), p=chain.model.p)["xf"], float)
    nq = chain.model.nq
    assert np.max(np.abs(res["q"][-1] - xs[:nq, -1])) <= RUN_TOL
    assert np.max(np.abs(res["v"][-1] - xs[nq:, -1])) <= RUN_TOL


def test_larger_odes_get_forward_differences(monkeypatch):
    """Above NEWTON_JACOBIAN_MAX states (lowered here to 4 for the 6-state chain) the Newton
    matrix is forward differences of the compiled right-hand side (nx + 1 calls, not CasADi's
    default central differences), and the run ends within RUN_TOL of the exact-Jacobian run."""
    from casmbd.analysis.dynamics import stepping

    exact = Simulator(_chain3()).run(2.0, 4, integrator="cvodes", rtol=1e-10, atol=1e-10)
    monkeypatch.setattr(stepping, "NEWTON_JACOBIAN_MAX", 4)
    sim = Simulator(_chain3())
    dyn = sim.sundials_dynamics("cvodes")
    assert dyn is not sim.dyn and dyn.name() == sim.dyn.name()
    solver = sun.sundials(dyn, "cvodes", 0.0, [0.1], 1e-8, 1e-8, 1000)
    g = solver.get_function("jacF")
    kinds = {g.instruction_MX(i).which_function().class_name()
             for i in range(g.n_instructions()) if g.instruction_MX(i).op() == ca.OP_CALL}
    assert "ForwardDiff" in kinds and "CentralDiff" not in kinds, kinds
    res = sim.run(2.0, 4, integrator="cvodes", rtol=1e-10, atol=1e-10)
    assert np.max(np.abs(res["q"][-1] - exact["q"][-1])) <= RUN_TOL
    assert np.max(np.abs(res["v"][-1] - exact["v"][-1])) <= RUN_TOL
