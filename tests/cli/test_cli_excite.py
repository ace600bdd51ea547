"""``casmbd excite``: the excitation design on the command line (casmbd.cli.excite).

Checked: ``--json`` prints one JSON object; the written CSV (one period at ``--rate``) is the
Fourier series of the printed coefficients (1e-12) and lies inside the URDF's position and
velocity limits and the acceleration limit at the design's constraint samples (1e-8 — the CSV
samples are other instants, where the bound holds to the series' inter-sample excess, here
checked to 2 %); the optimised κ is below the random start's; a wrong ``--out`` suffix is one
``error:`` line and status 1.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np

from casmbd import cli
from casmbd.io.urdf import load_urdf
from casmbd.ocp.excitation import FourierTrajectory, joint_limits

URDF = pathlib.Path(__file__).resolve().parents[2] / "examples" / "ur5_arm.urdf"


def test_excite_writes_the_series(tmp_path, capsys):
    out = tmp_path / "excitation.csv"
    status = cli.main(["excite", str(URDF), "--period", "8", "--acceleration", "3",
                       "--harmonics", "2", "--samples", "25", "--max-iter", "5",
                       "--rate", "50", "--out", str(out), "--json"])
    stdout, _ = capsys.readouterr()
    assert status == 0
    data = json.loads(stdout)
    assert data["written"] == str(out) and data["base_parameters"] == 48
    assert data["condition_number"] < data["initial_condition_number"]
    traj = FourierTrajectory(data["period"], data["q0"], data["a"], data["b"])
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    header = out.read_text().splitlines()[0].split(",")
    assert header[:2] == ["t", "q.shoulder_pan_joint.angle"] and len(header) == 19
    assert table.shape == (400, 19)
    q, v, a = traj.evaluate(table[:, 0])
    assert np.max(np.abs(np.hstack([q, v, a]) - table[:, 1:])) <= 1e-12
    lim = joint_limits(load_urdf(URDF))
    qc, vc, ac = traj.evaluate(traj.samples(40))  # the design's constraint samples (20 L)
    assert np.all(qc >= lim["lower"] - 1e-8) and np.all(qc <= lim["upper"] + 1e-8)
    assert np.all(np.abs(vc) <= lim["velocity"] + 1e-8) and np.all(np.abs(ac) <= 3 + 1e-8)
    assert np.all(np.abs(v) <= 1.02 * lim["velocity"]) and np.all(np.abs(a) <= 1.02 * 3)


def test_excite_refuses_a_non_csv_out(tmp_path, capsys):
    status = cli.main(["excite", str(URDF), "--period", "8", "--acceleration", "3",
                       "--out", str(tmp_path / "x.npz")])
    _, err = capsys.readouterr()
    assert status == 1
    assert err.strip().splitlines() == [f"error: --out '{tmp_path / 'x.npz'}': the trajectory "
                                        "is written as CSV (.csv)"]
