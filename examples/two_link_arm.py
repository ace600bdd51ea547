"""Two-link arm following a spline trajectory: feedforward torques and their round trip.

1. Joint trajectories are given as samples and interpolated by C² cubic splines (drivers).
2. Inverse dynamics gives the torques of the two joint actuators along the motion.
3. The torques, again as splines, drive a forward simulation of the arm without drivers; the
   arm reproduces the prescribed motion (to the integrator's tolerance).

Run: ``python examples/two_link_arm.py``.
"""

from __future__ import annotations

import numpy as np

import casmbd
from casmbd.analysis.driven.inverse import inverse_dynamics
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.model.values import Samples

T_END = 2.0


def arm(with_drivers: bool, sampled: bool = True) -> casmbd.Mechanism:
    """Two 1 m / 1 kg slender links from a shoulder at the origin (gravity −y).

    With ``sampled`` the joint paths are 41 samples joined by C² cubic splines (a path as it
    comes from a planner); otherwise the same quintic ramp as an expression of t.
    """
    m = casmbd.Mechanism("two_link_arm", gravity=(0.0, -9.81))
    m.add_body("upper", 1.0, 1 / 12, (0.5, 0.0))
    m.add_body("fore", 1.0, 1 / 12, (1.5, 0.0))
    m.add_revolute("shoulder", "ground", "upper", (0.0, 0.0))
    m.add_revolute("elbow", "upper", "fore", (1.0, 0.0))
    m.add_marker("hand", "fore", (2.0, 0.0))
    m.add_actuator("shoulder_motor", "shoulder")
    m.add_actuator("elbow_motor", "elbow")
    if with_drivers and sampled:
        times = np.linspace(0.0, T_END, 41)
        s = times / T_END
        ramp = s**3 * (10 - 15 * s + 6 * s**2)          # smooth 0 -> 1 (zero rate and accel.)
        m.add_driver("shoulder_path", Samples(times, -1.2 * ramp), joint="shoulder")
        m.add_driver("elbow_path", Samples(times, 0.9 * ramp), joint="elbow")
    elif with_drivers:
        ramp = f"(t/{T_END})**3 * (10 - 15*(t/{T_END}) + 6*(t/{T_END})**2)"
        m.add_driver("shoulder_path", f"-1.2 * {ramp}", joint="shoulder")
        m.add_driver("elbow_path", f"0.9 * {ramp}", joint="elbow")
    return m


def round_trip(steps: int = 400, rtol: float = 1e-11, sampled: bool = False) -> dict:
    """Inverse dynamics, then forward dynamics with the torques: the largest position error.

    The torques are sampled on the output grid and splined again; with a sampled (spline)
    path the torques have kinks at the path's knots (its third derivative jumps), so their
    spline converges like h² instead of h⁴ — use a fine grid, or a smooth path.
    """
    inv = inverse_dynamics(arm(with_drivers=True, sampled=sampled), T_END, steps)
    torques = {name: Samples(inv.t, inv["actuator_efforts"][:, k], name=name)
               for k, name in enumerate(inv.names["actuators"])}
    sim = Simulator(arm(with_drivers=False), inputs=torques)
    fwd = sim.run(T_END, steps, rtol=rtol, atol=rtol, q0=inv["q"][0], v0=inv["v"][0])
    return {"inverse": inv, "forward": fwd,
            "max_position_error": float(np.max(np.abs(fwd["q"] - inv["q"]))),
            "max_hand_error": float(np.max(np.abs(fwd.marker("hand")["position"]
                                                  - inv.marker("hand")["position"])))}


if __name__ == "__main__":
    out = round_trip(sampled=True, steps=1600)
    inv = out["inverse"]
    for k, name in enumerate(inv.names["actuators"]):
        tau = inv["actuator_efforts"][:, k]
        print(f"{name:15s} torque from {tau.min():+.3f} to {tau.max():+.3f} N m")
    print(f"round trip: largest coordinate error {out['max_position_error']:.2e}, "
          f"hand error {out['max_hand_error']:.2e} m")
