"""``casmbd linearize SCENE --steady-motion``: one JSON object with the reduced eigenvalues as
[re, im] pairs, the modes named by the remaining coordinates; the benchmark bicycle at 4 m/s
against Table 2 of Meijaard et al. (2007); refusals by name."""

import json
from pathlib import Path

import numpy as np

from casmbd import cli

ROOT = Path(__file__).resolve().parents[2]
BICYCLE = str(ROOT / "examples" / "bicycle.toml")
#: Table 2 of the paper at v = 4 m/s
TABLE2_V4 = [-12.15861426576450, -1.42944427361326, 0.41325331521125 - 3.07910818603206j,
             0.41325331521125 + 3.07910818603206j]


def test_steady_motion_json(capsys):
    assert cli.main(["linearize", BICYCLE, "--steady-motion", "--mode", "vm", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    got = np.array([complex(re, im) for re, im in data["eigenvalues"]])
    assert len(got) == 4
    assert max(min(abs(got - w)) for w in TABLE2_V4) <= 1e-10
    assert data["cyclic_coordinates"] == ["x.translation", "y.translation",
                                          "rear_axle.angle", "front_axle.angle"]
    assert data["symmetries"] == ["yaw.angle", "speed"]
    assert {m["coordinate"] for m in data["modes"]} <= {"roll.angle", "steer.angle"}
    assert data["stable"] is False  # the weave grows at 4 m/s


def test_steady_motion_text(capsys):
    assert cli.main(["linearize", BICYCLE, "--steady-motion", "--mode", "vm"]) == 0
    out = capsys.readouterr().out
    assert "cyclic x.translation, y.translation, rear_axle.angle, front_axle.angle" in out
    assert "+0.4132533152 +3.079108186i" in out


def test_small_oscillation_form_refused(capsys):
    """Without --steady-motion the rolling rows are refused by name, with what to use."""
    assert cli.main(["linearize", BICYCLE, "--mode", "vm", "--json"]) != 0
    err = capsys.readouterr().err
    assert "'rear_contact'" in err and "'front_contact'" in err and "--steady-motion" in err
