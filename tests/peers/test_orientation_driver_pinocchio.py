"""A floating-base robot fully driven (base x, y, z + orientation, every joint): the driver
efforts of ``casmbd.inverse_dynamics`` against Pinocchio's ``rnea`` with
``JointModelFreeFlyer`` at the same states (issue 34, item 1).

Solo-12 (example-robot-data): the base follows a translation and a Z-X-Z rotation of t, the
12 joints sines of t. At each output time the analysis' q, q̇, q̈ are mapped to Pinocchio's
(q with the quaternion's scalar last, v = (Aᵀṙ, Aᵀω, joint rates), v̇ from q̈ = G v̇ + Ġ v) and
τ = rnea(q, v, v̇) is compared with the efforts: the base force and moment (global, at the
root link origin) turned into the root's axes, then the joint torques; 1e-10 relative to the
largest. Skipped without Pinocchio or example-robot-data.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import casmbd  # noqa: E402
from benchmarks.floating_base_vs_pinocchio import _mapping, _models, _rel  # noqa: E402
from benchmarks.robots_vs_pinocchio import robots_dir  # noqa: E402
from casmbd.model.rotations import rotation_matrix  # noqa: E402

ROOT = robots_dir()
pytestmark = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed")
ROBOT = "solo_description/robots/solo12.urdf"


def test_driven_floating_base_efforts_agree_with_pinocchio_rnea():
    path = ROOT / ROBOT
    pm, ours = _models(path)
    to_pin, perm = _mapping(pm, ours)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = casmbd.load_urdf(path, floating_base=True)
    root = ours.coordinate_names[0].rpartition(".")[0]
    for axis, expr in zip("xyz", ("0.2*sin(2*t)", "0.1*t*t", "0.3 + 0.05*cos(3*t)")):
        mech.add_driver(f"b{axis}", expr, body=root, coordinate=axis)
    mech.add_driver("brot", body=root, coordinate="orientation",
                    euler_zxz=["1.5*t", "0.3*sin(2*t)", "0.2 - 0.4*t*t"])
    for k, name in enumerate(ours.coordinate_names[7:]):
        mech.add_driver(f"d{k}", f"{0.2 + 0.05 * k}*sin({1 + 0.3 * k}*t + {0.1 * k})",
                        joint=name.rpartition(".")[0])
    res = casmbd.inverse_dynamics(mech, 1.0, 4, mode="vm")
    assert res.names["coordinates"] == ours.coordinate_names
    vmap, data = ours.velocity_map, pm.createData()
    g_cols = np.eye(ours.nv)
    worst = 0.0
    for k in range(len(res.t)):
        q, qd, qdd = res["q"][k], res["v"][k], res["a"][k]
        v = vmap.velocity_from_rates(q, qd)
        g = np.column_stack([vmap.rates_from_velocity(q, e) for e in g_cols])
        a = np.linalg.lstsq(g, qdd - vmap.rate_accelerations(q, v, np.zeros(ours.nv)),
                            rcond=None)[0]
        tau_pin = pin.rnea(pm, data, to_pin(q), v[perm], a[perm])
        rot = rotation_matrix(q[3:7])
        eff = res["driver_efforts"][k]
        tau = np.concatenate([rot.T @ eff[0:3], rot.T @ eff[3:6], eff[6:]])
        worst = max(worst, _rel(tau[perm], tau_pin))
    print(f"worst relative τ error {worst:.2e}")
    assert worst <= 1e-10, worst
    # the check can fail: the moment left in global axes is far off
    eff = res["driver_efforts"][-1]
    assert np.max(np.abs(eff[3:6] - rotation_matrix(res["q"][-1][3:7]).T @ eff[3:6])) > 1e-3
