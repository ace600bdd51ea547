"""The articulated-body recursion folded over a planar revolute chain
(casmbd.system.chain_fold, issue 36 item 5) against the unrolled recursion
(casmbd.system.articulated_body) and through the simulator."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from benchmarks.chains import pendulum_chain
from casmbd.errors import AnalysisError
from casmbd.model import Mechanism
from casmbd.system import chain_fold
from casmbd.system.articulated_body import articulated_accelerations
from casmbd.system.equations import System


def _system(n: int) -> System:
    mech = pendulum_chain(n)
    mech.coordinates = "joint"
    return System(mech)


def test_folded_equals_unrolled_on_a_20_rod_chain():
    """q̈ of the three folds equals the unrolled recursion to 1e-12 relative to |q̈|∞ at
    random states (rates up to 2 rad/s: the velocity-product terms matter)."""
    system = _system(20)
    assert chain_fold.supported(system) is None
    unrolled = ca.Function("unrolled", [system.q, system.v, system.p],
                           [articulated_accelerations(system)])
    q, v = ca.MX.sym("q", system.nq), ca.MX.sym("v", system.nq)
    p = ca.MX.sym("p", system.p.numel())
    folded = ca.Function("folded", [q, v, p],
                         [chain_fold.folded_accelerations(system, q, v, p)])
    assert folded.n_instructions() < 40  # three fold calls, not 20 bodies unrolled
    rng = np.random.default_rng(7)
    for _ in range(5):
        qs, vs = rng.uniform(-1.5, 1.5, system.nq), rng.uniform(-2.0, 2.0, system.nq)
        want = np.asarray(unrolled(qs, vs, [])).ravel()
        got = np.asarray(folded(qs, vs, [])).ravel()
        assert np.max(np.abs(got - want)) <= 1e-12 * max(1.0, np.max(np.abs(want)))


def test_other_trees_are_not_folded():
    """A branched tree, a prismatic joint or a force element keep the unrolled recursion."""
    mech = pendulum_chain(3)
    mech.coordinates = "joint"
    mech.add_body("side", mass=1.0, inertia=0.1, position=(0.5, 1.0))
    mech.add_revolute("side_pin", "rod0", "side", point=(0.5, 0.5))
    assert chain_fold.supported(System(mech)) == "not a serial chain"
    slider = Mechanism("slider", gravity=(0.0, -9.81))
    slider.coordinates = "joint"
    slider.add_body("cart", mass=1.0, inertia=0.1, position=(0.0, 0.0))
    slider.add_prismatic("rail", "ground", "cart", point=(0.0, 0.0), axis=(1.0, 0.0))
    assert "not a plain revolute" in chain_fold.supported(System(slider))


@pytest.mark.parametrize("n", [6])
def test_simulated_chain_equals_the_unrolled_formulation(n, tmp_path, monkeypatch):
    """The folded chain (``fold=True``; by default from FOLD_MIN_BODIES bodies on) and
    ``fold=False`` give the same tip trajectory to 1e-10 m (DOPRI5 at 1e-10: the same steps
    up to rounding); a bad value of the option is a casmbd error naming it."""
    from casmbd.analysis.dynamics.simulate import Simulator

    monkeypatch.setenv("CASMBD_CACHE_DIR", str(tmp_path))
    tips = []
    for fold in (True, False):
        mech = pendulum_chain(n)
        sim = Simulator(mech, formulation_options={"fold": fold}, mode="vm")
        assert sim.formulation_name == "articulated"
        res = sim.run(0.5, 10, rtol=1e-10, atol=1e-10)
        tips.append(np.asarray(res.marker("tip")["position"], float))
    np.testing.assert_allclose(tips[0], tips[1], rtol=0.0, atol=1e-10)
    with pytest.raises(AnalysisError, match="fold"):
        Simulator(pendulum_chain(n), formulation_options={"fold": "yes"}, mode="vm")


def test_auto_folds_from_the_threshold_on():
    """``fold="auto"``: a chain below FOLD_MIN_BODIES keeps the unrolled SX right-hand side,
    one at the threshold gets the folded MX Function."""
    from casmbd.analysis.formulations.articulated import FOLD_MIN_BODIES, articulated

    small, large = _system(FOLD_MIN_BODIES - 1), _system(FOLD_MIN_BODIES)
    assert articulated(small).function.is_a("SXFunction")
    assert articulated(large).function.is_a("MXFunction")
