"""Correctness checks behind the scaling study (benchmarks/scaling.py); no timings.

* The generated C source of a pendulum chain grows about linearly with the number of rods.
* The articulated-body right-hand side (joint coordinates) and the KKT right-hand side in
  absolute coordinates give the same tip acceleration at a random state: two independent
  formulations, coordinate sets and kinematics.
* A second build on the same cache loads the library without running the compiler.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import private_cache

from benchmarks.scaling import mechanism
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.compiled import codegen

#: an empty compile cache for a test (so that the first build really compiles)
cache = private_cache(autouse=False, CASMBD_CFLAGS=None, CASMBD_COMPILE=None)


def _source_bytes(sim: Simulator) -> int:
    return Path(sim.model.report.library).with_suffix(".c").stat().st_size


@pytest.mark.parametrize("config", ["abs_al", "joint_aba"])
def test_source_grows_about_linearly(cache, config):
    """size(8) / size(4) of the kept C source <= 2.5 (exactly linear growth gives 2; the
    constant part of the library makes it less; a quadratic term would exceed 2.5 soon)."""
    size = {n: _source_bytes(Simulator(mechanism(n, config), mode="compiled"))
            for n in (4, 8)}
    assert size[8] > size[4]  # the measured file is the model's own source
    assert size[8] / size[4] <= 2.5, size


def _rhs(sim: Simulator, x: np.ndarray) -> np.ndarray:
    """ẋ = (q̇, q̈) from the compiled dynamics Function of a Simulator."""
    out = sim.dyn(0.0, x, np.zeros(0), sim.model.p, np.zeros(0))[0]
    return np.asarray(out, dtype=float).ravel()


@pytest.mark.parametrize("n", [2, 4, 8])
def test_articulated_and_absolute_tip_acceleration_agree(cache, n):
    """Tip acceleration from the articulated recursion (joint coordinates) equals the one of
    the KKT ODE in absolute coordinates at the same random state, to 1e-9 m/s²."""
    rng = np.random.default_rng(n)
    joint = Simulator(mechanism(n, "joint_aba"), mode="compiled")
    absolute = Simulator(mechanism(n, "abs_kkt"), "kkt_ode", mode="compiled")
    assert joint.formulation_name == "articulated"
    theta, omega = rng.uniform(-1.0, 1.0, n), rng.uniform(-2.0, 2.0, n)
    acc_joint = _rhs(joint, np.concatenate([theta, omega]))[n:]
    out_j = joint.model.outputs(theta[None], omega[None], acc_joint[None], np.zeros(1))
    tip_joint = out_j["marker_accelerations"][0]

    # the same state in absolute coordinates, from the joint model's body outputs
    pos = out_j["body_positions"][0].reshape(n, 2)
    vel = out_j["body_velocities"][0].reshape(n, 2)
    q = np.column_stack([pos, out_j["angle_positions"][0]]).ravel()
    v = np.column_stack([vel, out_j["angle_velocities"][0]]).ravel()
    model = absolute.model
    assert np.max(np.abs(model.constraints(q, 0.0))) < 1e-12  # consistent positions
    assert np.max(np.abs(model.constraint_jacobian(q, 0.0) @ v)) < 1e-12  # and velocities
    acc_abs = _rhs(absolute, np.concatenate([q, v]))[3 * n:]
    tip_abs = model.outputs(q[None], v[None], acc_abs[None], np.zeros(1))[
        "marker_accelerations"][0]
    assert np.max(np.abs(tip_abs)) > 1.0  # a genuine, non-trivial acceleration
    np.testing.assert_allclose(tip_abs, tip_joint, rtol=0, atol=1e-9)


def test_second_build_does_not_compile(cache):
    """A second Simulator of the same chain on the same cache is a cache hit: the compiler
    does not run (process-wide compile counter unchanged) and the report says so."""
    first = Simulator(mechanism(4, "abs_al"), mode="compiled")
    assert first.model.report.compiled and not first.model.report.cache_hit
    count = codegen.COMPILE_COUNT
    second = Simulator(mechanism(4, "abs_al"), mode="compiled")
    assert codegen.COMPILE_COUNT == count
    assert second.model.report.cache_hit and not second.model.report.compiled
    assert second.model.report.library == first.model.report.library


def test_targets_read_the_rows():
    """The target lines of the docs (issues 22 and 36): N = 1000 build, the cached process,
    cached load, RHS against Pinocchio's ABA (same run), solve growth — met or missed from
    the figures given."""
    from benchmarks.scaling import targets

    rows = []
    for n, build, second, rhs, pin, solve in ((100, 12.0, 0.05, 6.0, 4.0, 0.02),
                                              (1000, 45.0, 0.40, 61.0, 40.0, 0.25)):
        rows.append({"config": "joint_aba", "variant": "O2", "n": n, "status": "ok",
                     "build_total_s": build, "second_run_s": second, "import_s": 0.3,
                     "rhs_us": rhs, "pinocchio_aba_us": pin, "solve_s_per_s": solve,
                     "steps": 400, "second_compiled": False, "second_cache_hit": True})
    rows[1].update(cached_process_s=0.45, cached_process_cpu_s=0.3)
    text = "\n".join(targets(rows))
    assert "joint_aba 45.0 s (**missed** by 4.50×)" in text  # > 10 s at N = 1000 (issue 36)
    assert "joint_aba 0.45 s wall, 0.30 s CPU (wall met; CPU met)" in text  # ≤ 0.5 s
    assert "0.400 s at N = 1000" in text and "met;" in text  # second run ≤ 1 s
    assert "N = 100: 1.5, N = 1000: 1.5 (met)" in text       # RHS / ABA ≤ 2
    assert "N^1.10" in text and "(met)" in text              # 0.02 → 0.25: k = 1.097
    rows[1]["pinocchio_aba_us"] = 20.0
    assert "N = 1000: 3 (**missed**)" in "\n".join(targets(rows))
