"""Bad input, sweeps: an unknown output is an error before any point runs (nothing written);
a sweep whose every point fails exits with an error instead of reporting success.

Through ``casmbd.cli.main`` on the double pendulum example (parameters ``m`` and ``L``), two
points, short horizons, CasADi's virtual machine.
"""

from __future__ import annotations

import pathlib

import pytest
from conftest import private_cache

from casmbd.analysis.studies.sweep import sweep
from casmbd.cli import main
from casmbd.errors import AnalysisError
from casmbd.io.scene import load_scene

SCENE = pathlib.Path(__file__).resolve().parents[2] / "examples" / "double_pendulum.toml"


_vm = private_cache("cache_sweeps", CASMBD_COMPILE="0")


def run(argv, capsys) -> tuple[int, list[str]]:
    code = main(argv)
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and "internal error" not in captured.err
    return code, captured.err.strip().splitlines()


def sweep_args(out, *extra: str) -> list[str]:
    return ["sweep", str(SCENE), "--param", "m=1,2", "--t-end", "0.05", "--steps", "2",
            "--mode", "vm", "--out", str(out), *extra]


@pytest.mark.parametrize("output, fragments", [
    # the columns suggested are the result's: joint coordinates (the automatic choice)
    ("final:q[nope.x]", ("unknown column 'q[nope.x]'", "q[shoulder.angle]")),
    ("max:body.nope.x", ("unknown body 'nope'", "rod1, rod2")),
    ("max:body.rod1.nope", ("body 'rod1' has no 'nope'",)),
    ("max:joint.nope.coordinate", ("unknown joint 'nope'",)),
    ("foo", ("expected REDUCTION:COLUMN",)),
    ("median:q[rod1.x]", ("REDUCTION one of",)),
])
def test_unknown_output_fails_before_any_point(output, fragments, tmp_path, capsys):
    out = tmp_path / "sweep_out"
    code, err = run(sweep_args(out, "--output", output), capsys)
    assert code == 1 and len(err) == 1 and err[0].startswith("error: "), err
    assert f"output '{output}'" in err[0], err[0]
    for fragment in fragments:
        assert fragment in err[0], err[0]
    assert not out.exists()


def test_output_of_another_analysis_fails_up_front(tmp_path):
    """energy_drift of a statics sweep: named before the points run, no folder written."""
    out = tmp_path / "statics_out"
    with pytest.raises(AnalysisError, match="output 'energy_drift'") as exc:
        sweep(load_scene(SCENE), {"m": [1.0, 2.0]}, analysis="statics", outputs=["energy_drift"],
              out_dir=out, mode="vm")
    assert "no energies" in str(exc.value)
    assert not out.exists()


def test_every_point_failing_is_an_error(tmp_path, capsys):
    """m = -1 and -2: both points fail their scene check (mass must be >= 0); the sweep used to
    print its table and exit 0."""
    out = tmp_path / "sweep_out"
    argv = sweep_args(out)
    argv[argv.index("m=1,2")] = "m=-1,-2"
    code, err = run(argv, capsys)
    assert code == 1 and len(err) == 1 and err[0].startswith("error: "), err
    assert "all 2 points failed" in err[0] and "'mass'" in err[0] and "must be >= 0" in err[0]
    # the record of the failures is kept (and said so), no point result is
    assert sorted(p.name for p in out.iterdir()) == ["sweep.csv", "sweep.npz"]
    assert "sweep.csv" in err[0]


def test_some_points_failing_still_succeeds(tmp_path, capsys):
    """One good point of two: exit 0, the failed point listed in the table."""
    code, _ = run(["sweep", str(SCENE), "--param", "m=-1,1", "--t-end", "0.05", "--steps",
                   "2", "--mode", "vm"], capsys)
    assert code == 0
