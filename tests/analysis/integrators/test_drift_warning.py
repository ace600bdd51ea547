"""A run whose position constraints are violated beyond the tolerance stops with a named error,
never reported as a good one (issue 23 review: the linear spin-up beam above its first bending
frequency diverged with a 1.08 m joint violation and exited 0 with a clean summary; issue 30,
item 4k: a driven non-Grashof crank only warned "position constraints violated by 0.106",
exited 0 and saved the file).  The contract, as kinematics: a
:class:`~casmbd.errors.ConstraintViolationError` naming the time and the driver or joint, exit
status 1, the results before the violation kept (``exc.partial``, ``--out``)."""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache
from flexible_references import spinup_scene

import casmbd
from casmbd.analysis.dynamics.postprocess import DRIFT_LIMIT
from casmbd.cli import main
from casmbd.errors import ConstraintViolationError, IntegratorError

_cache = private_cache(CASMBD_COMPILE="0")

ROOT = pathlib.Path(__file__).resolve().parents[3]
#: the crank-rocker of examples/four_bar.toml with the coupler pin B typed at (0, 0.6): a
#: 0.6 m crank that cannot turn (non-Grashof), driven at one turn per second from π/2
NON_GRASHOF = (ROOT / "examples" / "four_bar.toml").read_text().replace(
    "point = [0.0, 0.2]", "point = [0.0, 0.6]")
#: the crank angles the loop allows, ±acos((a² + g² − (b + c)²) / (2 a g)) (cosine rule at
#: the limit position where coupler and rocker are aligned)
CRANK, GROUND = 0.6, 0.8
COUPLER, ROCKER = math.hypot(0.6437, 0.475 - 0.6), math.hypot(0.8 - 0.6437, 0.475)
LIMIT = math.acos((CRANK**2 + GROUND**2 - (COUPLER + ROCKER) ** 2) / (2 * CRANK * GROUND))
#: the time the driver (π/2 + 2π t) reaches it: 0.0569 s
T_LIMIT = (LIMIT - math.pi / 2) / (2 * math.pi)


def test_diverging_run_stops_naming_the_equations_and_keeps_the_results(tmp_path, capsys):
    """The spin-up beam above its first bending frequency: the constraints could be satisfied,
    the trajectory left them; the error names the time and the largest residual (the hub's
    driver), the results before it are kept and satisfy the joints."""
    mech = casmbd.loads_scene(spinup_scene(6.0))
    with pytest.raises(ConstraintViolationError, match=r"position constraints violated by "
                                                       r".* at t = ") as info:
        casmbd.simulate(mech, 12.0, 60)
    exc = info.value
    assert isinstance(exc, IntegratorError)  # sweeps and the CLI treat it as a failed run
    assert "driver 'spin'" in str(exc) and "trajectory left them" in str(exc)
    part = exc.partial
    assert part.t[-1] < exc.time <= 12.0
    assert part["q"].shape == (len(part.t), mech_nq(part))
    assert part.arrays["constraint_violation"].max() < DRIFT_LIMIT
    path = tmp_path / "spin.toml"
    path.write_text(spinup_scene(6.0))
    out = tmp_path / "spin.npz"
    status = main(["simulate", str(path), "--t-end", "12", "--steps", "60", "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 1 and err.startswith("error: simulation: position constraints violated")
    saved = casmbd.Result.load(str(out))
    assert np.array_equal(saved.t, part.t)


def mech_nq(result) -> int:
    return len(result.names["coordinates"])


def test_bounded_run_passes():
    mech = casmbd.loads_scene(spinup_scene(6.0, stiffening=True))
    res = casmbd.simulate(mech, 12.0, 60)
    assert res.arrays["constraint_violation"].max() < 1e-6


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_non_grashof_crank_stops_naming_the_driver(tmp_path, capsys, coordinates):
    """``simulate`` on the driven non-Grashof crank: exit 1, stderr names the driver
    'crank_drive' and the first output time past the limit position (T_LIMIT = 0.0569 s:
    t = 0.1 on a 0.05 s grid), the joint it contradicts and the crank range the loop allows
    (±1.9282 rad, to 1e-3 as kinematics); --out holds the outputs up to t = 0.05 < T_LIMIT,
    which satisfy the joints.  The Python API raises the same error with the ranked culprits."""
    scene = tmp_path / "non_grashof.toml"
    scene.write_text(NON_GRASHOF.replace('dimension = 2',
                                         f'dimension = 2\ncoordinates = "{coordinates}"'))
    out = tmp_path / "partial.npz"
    status = main(["simulate", str(scene), "--t-end", "1", "--steps", "20", "--out", str(out)])
    captured = capsys.readouterr()
    err = captured.err
    assert status == 1, captured.out
    assert err.startswith("error: simulation: position constraints violated") and \
        err.count("\n") == 1, err
    assert "at t = 0.1 " in err and "most likely culprit: driver 'crank_drive'" in err, err
    assert "joint 'C'" in err and f"partial results saved to {out}" in err
    saved = casmbd.Result.load(str(out))
    assert saved.t[-1] == pytest.approx(0.05) and saved.t[-1] < T_LIMIT < 0.1
    assert saved.arrays["constraint_violation"].max() < 1e-6
    assert "crank_drive" in saved.stats["failure"]

    with pytest.raises(ConstraintViolationError) as info:
        casmbd.simulate(casmbd.load_scene(str(scene)), 1.0, 20)
    exc = info.value
    assert exc.time == pytest.approx(0.1)
    assert exc.culprits[0].element == "crank_drive" and exc.culprits[0].kind == "driver"
    low, high = (float(x) for x in exc.culprits[0].hint.split("from ")[1].split(",")[0]
                 .split(" to "))
    assert abs(low + LIMIT) < 1e-3 and abs(high - LIMIT) < 1e-3
    assert np.array_equal(exc.partial.t, saved.t)


def test_event_driven_run_stops_naming_the_driver_too():
    """The same crank with a stop on its rocker (never reached: ±3 rad) runs the event-driven
    path; it stops the same way, naming 'crank_drive' at t = 0.1 with the results before."""
    mech = casmbd.loads_scene(NON_GRASHOF)
    mech.add_joint_limit("D", lower=-3.0, upper=3.0)
    with pytest.raises(ConstraintViolationError) as info:
        casmbd.simulate(mech, 1.0, 20)
    exc = info.value
    assert exc.time == pytest.approx(0.1)
    assert exc.culprits[0].element == "crank_drive"
    assert exc.partial.t[-1] == pytest.approx(0.05)
