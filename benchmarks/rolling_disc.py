"""The spatial rolling disc (``rolling_disc``) against its closed forms: the figure of
docs/rolling.md.

``python -m benchmarks.rolling_disc`` (a few seconds, CasADi's VM)

* simulates the steady turn of ``tests/model/test_rolling_disc.py`` (uniform thin disc,
  R = 0.3 m, lean θ = 0.3 rad, heading rate Ω = 2 rad/s, v from
  g sin θ = Ω cos θ (R Ω sin θ / 4 − 3 v / 2)) for 6 s, and the same start with Ω 5 % too
  fast, printing the largest lean, heading and spin deviations;
* linearises the upright disc about its steady motion at speeds 0.1–3 m/s
  (:mod:`casmbd.analysis.statics.steady_motion`, the disc on the joint-coordinate chain of
  ``tests/rolling_disc_scenes.py``) and prints the largest
  distance of the lean eigenvalues from ±√(4 g/(5 R) − 12 v²/(5 R²));
* draws ``docs/figures/rolling_disc.png``: the centre's and the contact point's paths of both
  turns, and the eigenvalues against speed with the closed form and v_c = √(g R / 3).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import casmbd

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from rolling_disc_scenes import (  # noqa: E402
    OMEGA,
    THETA,
    V_CRIT,
    chain_disc,
    disc,
    lean_rate_squared,
    motion,
    steady_speed,
)

from casmbd.analysis.statics.steady_motion import SteadyMotion  # noqa: E402

T_END, STEPS = 6.0, 600


def turn(omega: float):
    v = steady_speed(THETA, OMEGA)
    return casmbd.simulate(disc(THETA, omega, v), T_END, STEPS, formulation="index1",
                           mode="vm", rtol=1e-12, atol=1e-12)


def main() -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    v = steady_speed(THETA, OMEGA)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for omega, style, label in ((OMEGA, "-", "steady (closed form)"),
                                (1.05 * OMEGA, "--", "Ω 5 % too fast")):
        res = turn(omega)
        lean, heading, spin = motion(res)
        print(f"{label:22s} max|θ − θ₀| {np.max(np.abs(lean - THETA)):.1e} rad, "
              f"max|ψ − Ω t| {np.max(np.abs(heading - OMEGA * res.t)):.1e} rad, "
              f"max|ω·a − v/R| {np.max(np.abs(spin - v / 0.3)):.1e} rad/s")
        pos = res.body("wheel")["position"]
        ax1.plot(pos[:, 0], pos[:, 1], style, label=f"centre, {label}")
    ax1.set_aspect("equal")
    ax1.set_xlabel("x [m]")
    ax1.set_ylabel("y [m]")
    ax1.set_title(f"turning disc: lean {THETA} rad, Ω = {OMEGA} rad/s")
    ax1.legend(loc="lower right", fontsize=8)

    lin = SteadyMotion(chain_disc(), mode="vm")
    v1 = lin().v
    speeds = np.linspace(0.1, 3.0, 59)
    worst = 0.0
    for s in speeds:
        eig = lin(q=None, v=s * v1).eigenvalues
        lam = np.sqrt(complex(lean_rate_squared(s)))
        worst = max(worst, min(abs(eig - lam)), min(abs(eig + lam)))
        ax2.plot([s] * len(eig), eig.real, "b.", ms=4)
        ax2.plot([s] * len(eig), eig.imag, "r.", ms=4)
    print(f"steady-motion eigenvalues vs closed form, 59 speeds: max distance {worst:.1e}")
    fine = np.linspace(0.1, 3.0, 400)
    lam2 = lean_rate_squared(fine)
    ax2.plot(fine, np.sqrt(np.clip(lam2, 0, None)), "k-", lw=0.8, label="±λ (closed form)")
    ax2.plot(fine, -np.sqrt(np.clip(lam2, 0, None)), "k-", lw=0.8)
    ax2.plot(fine, np.sqrt(np.clip(-lam2, 0, None)), "k--", lw=0.8, label="±ω (closed form)")
    ax2.plot(fine, -np.sqrt(np.clip(-lam2, 0, None)), "k--", lw=0.8)
    ax2.axvline(V_CRIT, color="grey", lw=0.8)
    ax2.text(V_CRIT + 0.03, 6, "v_c = √(gR/3)", fontsize=8)
    ax2.plot([], [], "b.", label="Re λ (steady_motion)")
    ax2.plot([], [], "r.", label="Im λ (steady_motion)")
    ax2.set_xlabel("speed v [m/s]")
    ax2.set_ylabel("eigenvalue [1/s]")
    ax2.set_title("upright disc: lean eigenvalues")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    out = ROOT / "docs" / "figures" / "rolling_disc.png"
    fig.savefig(out, dpi=90)
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
