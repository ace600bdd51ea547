"""Inverse dynamics of a rolling disc driven along its own steady turn: the tyre forces
against the closed form (tests/model/test_rolling_disc.py states the steady motions).

The thin uniform disc (R = 0.3 m, m = 1 kg) on the joint-coordinate chain of
tests/rolling_disc_scenes.py, closed by a ``rolling_disc`` joint,
has its lean held at θ, its heading driven at Ω t and its spin at s t with
s = v/R − Ω sin θ (the axle rate ω·a = v/R), v from the steady relation
g sin θ = Ω cos θ (R Ω sin θ / 4 − 3 v / 2).  That prescribed motion is a free motion, so the
three driver efforts vanish; the contact force is F = m v Ω e_y' + m g e_z (e_y' the horizontal
axle direction): normal load m g, longitudinal 0, lateral tyre force m v Ω, and the joint's
reaction at the wheel centre is (F, (P − c) × F).
"""

from __future__ import annotations

import numpy as np
from rolling_disc_scenes import MASS, OMEGA, THETA, G, R, chain_disc, steady_speed

import casmbd


def test_driven_steady_turn_has_free_drivers_and_the_closed_form_tyre_forces():
    """Driver efforts ≤ 1e-9 (observed 1e-15); tyre forces (−λ of the joint's rows, named
    ``roll.contact``, ``roll.longitudinal``, ``roll.lateral``) m g, 0 and m v Ω, the reaction's
    force (0, m v Ω, m g) turning with the heading, its moment (P − c) × F, all to 1e-9."""
    v = steady_speed(THETA, OMEGA)
    mech = chain_disc()
    mech.add_driver("hold_lean", joint="lean", position=f"{float(THETA)!r}")
    mech.add_driver("turn", joint="yaw", position=f"{float(OMEGA)!r}*t")
    mech.add_driver("spin", joint="spin", position=f"{float(v / R - OMEGA * np.sin(THETA))!r}*t")
    res = casmbd.inverse_dynamics(mech, 2.0, 20, mode="vm")
    assert np.max(np.abs(res["driver_efforts"])) < 1e-9
    assert res.names["tyre_forces"] == ["roll.contact", "roll.longitudinal", "roll.lateral"]
    np.testing.assert_allclose(res["tyre_forces"][:, 0], MASS * G, atol=1e-9)
    np.testing.assert_allclose(res["tyre_forces"][:, 1], 0.0, atol=1e-9)
    np.testing.assert_allclose(res["tyre_forces"][:, 2], MASS * v * OMEGA, atol=1e-9)
    psi = OMEGA * res.t
    e_y = np.stack([-np.sin(psi), np.cos(psi), 0 * psi], axis=1)
    force = MASS * v * OMEGA * e_y + [0.0, 0.0, MASS * G]
    down = np.cos(THETA) * np.array([0.0, 0.0, 1.0]) - np.sin(THETA) * e_y
    reaction = res["joint_reactions"][:, res.names["all_joints"].index("roll")]
    np.testing.assert_allclose(reaction[:, :3], force, atol=1e-9)
    np.testing.assert_allclose(reaction[:, 3:], np.cross(-R * down, force), atol=1e-9)
