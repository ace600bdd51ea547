"""The start-of-run mass check is cheap on a healthy tree (issue 36: the fixed cost of a run):
no eigen-decomposition, and on a folded chain not even M — only the articulated-body pivots;
a massless body still gets its named message."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import private_cache

from benchmarks.chains import pendulum_chain
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.instant import checks
from casmbd.errors import ModelError

_cache = private_cache("cache_mass_cost")


def _spy(monkeypatch) -> list[str]:
    """Calls of the full diagnosis and of numpy's eigen-decompositions, recorded."""
    calls: list[str] = []
    diagnose, eigh = checks._diagnose_mass, np.linalg.eigh

    def spy_diagnose(*args, **kwargs):
        calls.append("diagnose")
        return diagnose(*args, **kwargs)

    def spy_eigh(*args, **kwargs):
        calls.append("eigh")
        return eigh(*args, **kwargs)

    monkeypatch.setattr(checks, "_diagnose_mass", spy_diagnose)
    monkeypatch.setattr(np.linalg, "eigh", spy_eigh)
    return calls


def _chain(n: int, tip_mass: float = 1.0):
    mech = pendulum_chain(n)
    mech.coordinates = "joint"
    mech.name = f"mass_cost_chain{n}_{tip_mass:g}"
    tip = mech.bodies[f"rod{n - 1}"]
    tip.mass, tip.inertia = tip_mass, tip_mass / 12
    return mech


@pytest.mark.parametrize("fold", [False, True])
def test_healthy_tree_run_skips_the_eigen_decomposition(monkeypatch, fold):
    """A 4-rod chain (unrolled: M and its scaled Cholesky; folded: the pivots alone, M never
    evaluated) runs without the diagnosis or an eigen-decomposition, and its tip angle after
    0.2 s equals the other path's to 1e-9."""
    sim = Simulator(_chain(4), formulation_options={"fold": fold})
    assert sim.formulation_name == "articulated"
    assert ("articulated_pivots" in sim.model.functions) == fold
    calls = _spy(monkeypatch)
    res = sim.run(0.2, 4, rtol=1e-11)
    assert calls == []
    evaluated = sim.model.data.evaluated
    assert ("mass_matrix" in evaluated) != fold
    assert ("articulated_pivots" in evaluated) == fold
    other = Simulator(_chain(4), formulation_options={"fold": not fold}).run(0.2, 4, rtol=1e-11)
    assert np.allclose(res["q"][-1], other["q"][-1], rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("fold", [False, True])
def test_massless_tip_still_named(monkeypatch, fold):
    """A chain whose tip rod has mass 0 and inertia 0: the cheap test fails, the diagnosis
    runs and names the body with the 'singular … no inertia' message."""
    sim = Simulator(_chain(4, tip_mass=0.0), formulation_options={"fold": fold})
    calls = _spy(monkeypatch)
    with pytest.raises(ModelError, match=r"singular.*'rod3'.*has no inertia"):
        sim.run(0.1, 2)
    assert "diagnose" in calls and "eigh" in calls


def test_healthy_absolute_chain_skips_the_null_space_diagnosis(monkeypatch):
    """In absolute coordinates (C_q of 6 rows) M itself passes the cheap test: no projection
    on the null space of C_q, no eigen-decomposition; the start is still checked (a run to
    0.2 s whose tip angle equals the joint-coordinate run's to 1e-8)."""
    mech = pendulum_chain(3)
    mech.coordinates = "absolute"
    mech.name = "mass_cost_abs3"
    sim = Simulator(mech)
    assert sim.model.nc == 6
    calls = _spy(monkeypatch)
    res = sim.run(0.2, 4, rtol=1e-11)
    assert calls == []  # neither the null-space diagnosis nor an eigen-decomposition
    joint = Simulator(_chain(3)).run(0.2, 4, rtol=1e-11)
    tip_abs = res["q"][-1][sim.model.coordinate_names.index("rod2.angle")]
    assert abs(tip_abs - float(np.sum(joint["q"][-1]))) < 1e-8
