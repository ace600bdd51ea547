"""A run whose constraints drift away is flagged, never reported as a good one (issue 23 review:
the linear spin-up beam above its first bending frequency diverged with a 1.08 m joint
violation and exited 0 with a clean summary)."""

from __future__ import annotations

import pytest
from conftest import private_cache
from flexible_references import spinup_scene

import casmbd
from casmbd.cli import main

_cache = private_cache(CASMBD_COMPILE="0")

def test_diverging_run_is_flagged(tmp_path, capsys):
    mech = casmbd.loads_scene(spinup_scene(6.0))
    with pytest.warns(RuntimeWarning, match=r"position constraints violated by .* at t = "):
        res = casmbd.simulate(mech, 12.0, 60)
    assert "drift_warning" in res.stats
    path = tmp_path / "spin.toml"
    path.write_text(spinup_scene(6.0))
    with pytest.warns(RuntimeWarning, match="position constraints violated"):
        main(["simulate", str(path), "--t-end", "12", "--steps", "60"])
    assert "WARNING: position constraints violated" in capsys.readouterr().out


def test_bounded_run_is_not_flagged():
    mech = casmbd.loads_scene(spinup_scene(6.0, stiffening=True))
    res = casmbd.simulate(mech, 12.0, 60)
    assert "drift_warning" not in res.stats
    assert res.arrays["constraint_violation"].max() < 1e-6
