"""Regenerate the pictures of docs/tutorial.md (run from the repository root).

    python docs/figures/tutorial/make_figures.py

Writes crane_simulation.png, crane.gif (steps 2) and crane_transfer.png (step 7) next to this
file, with the same commands and snippets as the tutorial, at low resolution.
"""

from __future__ import annotations

import pathlib
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import casmbd
from casmbd import cli
from casmbd.ocp import Ocp

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[2]


def step2() -> None:
    """`casmbd simulate`, `casmbd plot`, `casmbd animate` of the free swing."""
    with tempfile.TemporaryDirectory() as tmp:
        npz = str(pathlib.Path(tmp) / "crane.npz")
        for argv in (["simulate", str(ROOT / "examples/crane.toml"), "--t-end", "5",
                      "--steps", "250", "--out", npz],
                     ["plot", npz, "--kind", "joints", "--kind", "energy",
                      "--out", str(HERE / "crane_simulation.png"), "--dpi", "60"],
                     ["animate", npz, "--trace", "hook", "--max-frames", "51", "--dpi", "50",
                      "--out", str(HERE / "crane.gif")]):
            assert cli.main(argv) == 0, argv


def naive_transfer() -> casmbd.Result:
    """Step 4: the cart driven along a quintic rest-to-rest profile, the load swinging free."""
    crane = casmbd.load_scene(ROOT / "examples/crane.toml")
    s = "min(t / 2, 1)"
    crane.add_driver("move", joint="rail", position=f"10*{s}**3 - 15*{s}**4 + 6*{s}**5")
    return casmbd.Simulator(crane).run(t_end=4.0, steps=400, q0=[0, 0, 0, 0, -0.5, 0])


def optimal_transfer():
    """Step 7: the anti-sway transfer of ocp/crane_transfer.toml, built in Python."""
    crane = casmbd.load_scene(ROOT / "ocp/crane_transfer.toml")
    ocp = Ocp(crane, horizon=2.0, intervals=50)
    ocp.control_bounds("force", -9.0, 9.0)
    ocp.initial(rail=0, hinge=0, rail_dot=0, hinge_dot=0)
    ocp.final(rail=1, hinge=0, rail_dot=0, hinge_dot=0)
    ocp.path("hinge", lower=-0.2, upper=0.2)
    ocp.minimize("effort")
    sol = ocp.solve()
    return sol, sol.replay()


def step7() -> None:
    """The optimal force and swing against the naive transfer (crane_transfer.png)."""
    naive = naive_transfer()
    sol, replay = optimal_transfer()
    fig, axes = plt.subplots(3, 1, figsize=(6, 6.5), sharex=True)
    axes[0].plot(naive.t, naive["joint_positions"][:, 0], "C1", label="quintic profile")
    axes[0].plot(sol.t, sol.value("rail"), "C0", label="optimal")
    axes[0].set_ylabel("cart x [m]")
    axes[1].plot(naive.t, naive["joint_positions"][:, 1], "C1", label="quintic profile")
    axes[1].plot(sol.t, sol.value("hinge"), "C0", label="optimal (collocation)")
    axes[1].plot(replay.t, replay["joint_positions"][:, 1], "k:", label="optimal (replay)")
    for bound in (-0.2, 0.2):
        axes[1].axhline(bound, color="0.6", lw=0.8, ls="--")
    axes[1].set_ylabel("swing (hinge) [rad]")
    axes[2].plot(naive.t, naive["driver_efforts"][:, 0], "C1", label="quintic profile")
    tc = sol.control_times
    force = sol.control("force")
    axes[2].step(tc, np.append(force, force[-1]), "C0", where="post", label="optimal")
    for bound in (-9.0, 9.0):
        axes[2].axhline(bound, color="0.6", lw=0.8, ls="--")
    axes[2].set_ylabel("rail force [N]")
    # after 2 s the optimum is at rest (load hanging, zero force): nothing moves
    for ax, value in zip(axes, (1.0, 0.0, 0.0)):
        ax.plot([2.0, 4.0], [value, value], "C0--", lw=1)
    axes[2].set_xlabel("t [s]")
    for ax in axes:
        ax.axvline(2.0, color="0.8", lw=0.8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle("crane: 1 m in 2 s, quintic cart profile against the anti-sway optimum",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(HERE / "crane_transfer.png", dpi=70)


if __name__ == "__main__":
    step2()
    step7()
    print("written:", ", ".join(p.name for p in sorted(HERE.glob("crane*"))))
