"""Chaplygin's sleigh (``knife_edge``) against its closed form: the figure of docs/rolling.md.

``python -m benchmarks.chaplygin_sleigh`` simulates the sleigh of
``tests/model/test_rolling_kinds.py`` (m = 2 kg, I = 0.3 kg m², blade a = 0.4 m behind the
centre of mass, u₀ = 1 m/s, ω₀ = 2 rad/s) for 8 s in the three coordinate choices, prints the
largest differences from the closed form (u, ω, θ; Bloch 2003 §1.7) and the relative energy
drift, and draws ``docs/figures/rolling_sleigh.png`` (the path of the centre and of the blade
point; u(t) and ω(t) with the closed form).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import casmbd
from casmbd.model import Mechanism

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "model"))
from test_rolling_kinds import (  # noqa: E402
    ATOL,
    RTOL,
    A,
    body_frame_velocities,
    planar_sleigh,
    sleigh_closed_form,
)

T_END, STEPS = 4.0, 400


def run(coordinates: str):
    mech: Mechanism = planar_sleigh(coordinates)
    return casmbd.simulate(mech, T_END, STEPS, rtol=RTOL, atol=ATOL, mode="vm")


def main() -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = {}
    for coords in ("absolute", "natural", "joint"):
        res = run(coords)
        body = res.body("sleigh")
        u, _ = body_frame_velocities(body)
        u_ref, w_ref, th_ref, _ = sleigh_closed_form(res.t)
        energy = res.arrays["total_energy"]
        print(f"{coords:9s} max|u − u*| {np.max(np.abs(u - u_ref)):.1e} m/s, "
              f"max|ω − ω*| {np.max(np.abs(body['angular_velocity'] - w_ref)):.1e} rad/s, "
              f"max|θ − θ*| {np.max(np.abs(body['angle'] - th_ref)):.1e} rad, "
              f"energy drift {np.ptp(energy) / energy[0]:.1e}")
        results[coords] = (res, body, u)
    res, body, u = results["absolute"]
    u_ref, w_ref, _, _ = sleigh_closed_form(res.t)
    pos, th = body["position"], body["angle"]
    blade = pos - A * np.column_stack([np.cos(th), np.sin(th)])
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    ax1.plot(pos[:, 0], pos[:, 1], label="centre of mass G")
    ax1.plot(blade[:, 0], blade[:, 1], "--", label="blade point P")
    ax1.set_aspect("equal")
    ax1.set_xlabel("x [m]")
    ax1.set_ylabel("y [m]")
    ax1.set_title("Chaplygin's sleigh: path")
    ax1.legend(loc="lower right")
    ax2.plot(res.t, u, label="u (simulated)")
    ax2.plot(res.t, u_ref, "k:", label="u = U tanh(κt + c₀)")
    ax2.plot(res.t, body["angular_velocity"], label="ω (simulated)")
    ax2.plot(res.t, w_ref, "k--", label="ω = √(m/J) U sech(κt + c₀)")
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel("u [m/s], ω [rad/s]")
    ax2.set_title("forward speed and turn rate vs closed form")
    ax2.legend()
    fig.tight_layout()
    out = ROOT / "docs" / "figures" / "rolling_sleigh.png"
    fig.savefig(out, dpi=90)
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
