"""A run whose constraints drift away is flagged, never reported as a good one (issue 23 review:
the linear spin-up beam above its first bending frequency diverged with a 1.08 m joint
violation and exited 0 with a clean summary)."""

from __future__ import annotations

import pytest
from conftest import private_cache

import casmbd
from casmbd.cli import main

_cache = private_cache(CASMBD_COMPILE="0")

SCENE = """
[scene]
name = "spin"
gravity = [0.0, 0.0]
[parameters]
Omega = 6.0
Ts = 15.0
[[bodies]]
name = "beam"
type = "flexible"
position = [0.0, 0.0]
modes = 3
interfaces = ["root"]
stiffening = {stiff}
[bodies.beam]
length = 10.0
elements = 6
EI = 1.4e4
EA = 2.8e7
rhoA = 1.2
[[joints]]
name = "hub"
type = "revolute"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0]
[[drivers]]
name = "spin"
joint = "hub"
position = "(Omega/Ts)*(min(t,Ts)**2/2 + (Ts/(2*pi))**2*(cos(2*pi*min(t,Ts)/Ts) - 1))"
"""


def test_diverging_run_is_flagged(tmp_path, capsys):
    mech = casmbd.loads_scene(SCENE.format(stiff="false"))
    with pytest.warns(RuntimeWarning, match=r"position constraints violated by .* at t = "):
        res = casmbd.simulate(mech, 12.0, 60)
    assert "drift_warning" in res.stats
    path = tmp_path / "spin.toml"
    path.write_text(SCENE.format(stiff="false"))
    with pytest.warns(RuntimeWarning, match="position constraints violated"):
        main(["simulate", str(path), "--t-end", "12", "--steps", "60"])
    assert "WARNING: position constraints violated" in capsys.readouterr().out


def test_bounded_run_is_not_flagged():
    mech = casmbd.loads_scene(SCENE.format(stiff="true"))
    res = casmbd.simulate(mech, 12.0, 60)
    assert "drift_warning" not in res.stats
    assert res.arrays["constraint_violation"].max() < 1e-6
