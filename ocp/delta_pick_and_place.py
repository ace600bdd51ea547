"""Delta robot pick-and-place as optimal-control problems (issue 8).

The 3-RUU Delta of ``examples/delta_robot.py`` (seed 003, §5.2; ``docs/delta_robot.md``) in
joint coordinates: the spanning tree ground → upper1 → fore1 → hand and the two other legs
leaves the wrists 2 and 3 as loop joints, 11 coordinates, 8 constraint equations, 3 DOF —
instead of 49 Euler-parameter coordinates and 46 equations.  Motors ``motor1..3`` on the
shoulders, |τ_i| ≤ ``TORQUE`` N m.  The hand moves from the pick point ``START`` to the place
point ``GOAL`` of the example (0.32 m across, same height), at rest at both ends.

Variants
--------
``time``
    Minimum time T (free final time), bang-bang drive moments.
``energy``
    Minimum actuator energy ∫ Σ |τ_i θ̇_i| dt over the example's T = 0.6 s (the absolute
    mechanical power: braking is not recovered).

On the 10-interval grid the minimum-time variant converges with degree-3 collocation
(``--degree 3``: T* = 0.191494 s in 18–28 iterations, depending on the guess); with the
default degree 4 IPOPT crawls
(T = 0.1949 s after 300 iterations and still creeping down, the dual infeasibility near
2e-6: not converged, 450 s in the virtual machine).  The 6-interval grid of the tests converges
with either degree.

``--obstacle`` adds a bar along y over the straight path: the hand keeps out of the ellipse
(x/0.05)² + ((z + 0.78)/0.06)² ≥ 1 in the x–z plane (top at z = −0.72 m, 3 cm above the
pick and place points) at every mesh node and collocation point, so the hand is lifted over it.

The Delta's constraint Hessians make a large C file (the whole NLP at ``-O2`` did not finish in
600 s), so the NLP's per-element derivatives run in CasADi's virtual machine by default
(``--compile`` compiles and caches them).

Run::

    python ocp/delta_pick_and_place.py --variant time [--obstacle] [--json]
    python ocp/delta_pick_and_place.py --variant energy --obstacle --json

``--json`` prints the keys of ``casmbd ocp --json`` ("success", "objective", "iterations",
"replay_error", "constraint_violation", "final_time", "stats", "t", "controls",
"coordinates").
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

from casmbd.ocp import FreeTime, Ocp
from casmbd.system.equations import System

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent / "examples"))
import delta_robot

START, GOAL = delta_robot.START, delta_robot.GOAL
TORQUE = 5.0                 # drive moment bound [N m] (static moments at START: ≤ 1.17 N m)
T_ENERGY = delta_robot.T_MOVE
#: obstacle: centre (x, z) and half-axes (x, z) of the keep-out ellipse [m]
OBSTACLE = (0.0, -0.78, 0.05, 0.06)
VARIANTS = ("time", "energy")


def obstacle_expression(obstacle=OBSTACLE) -> str:
    """The keep-out condition's left side: ≥ 1 outside the ellipse."""
    xc, zc, rx, rz = obstacle
    return f"((hand_x - ({xc})) / {rx})**2 + ((hand_z - ({zc})) / {rz})**2"


def build(variant: str = "time", obstacle: bool = False, intervals: int = 20,
          subintervals: int = 1, compile: bool = False, torque: float = TORQUE,
          degree: int | None = None) -> Ocp:
    """The pick-and-place :class:`~casmbd.ocp.Ocp` of one variant (``degree``: of the Radau
    collocation; None keeps the library default)."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    system = System(delta_robot.delta_robot(name="delta_pick_and_place"), coordinates="joint")
    horizon = FreeTime(0.4, 0.05, 2.0) if variant == "time" else T_ENERGY
    ocp = Ocp(system, horizon=horizon, intervals=intervals, subintervals=subintervals,
              compile=compile, **({} if degree is None else {"degree": degree}))
    for arm in delta_robot.ARMS:
        ocp.control_bounds(f"motor{arm}", -torque, torque)
    rest = {"hand_vx": 0.0, "hand_vy": 0.0, "hand_vz": 0.0}
    ocp.initial(hand_x=START[0], hand_y=START[1], hand_z=START[2], **rest)
    ocp.final(hand_x=GOAL[0], hand_y=GOAL[1], hand_z=GOAL[2], **rest)
    if obstacle:
        ocp.path(obstacle_expression(), lower=1.0)
    ocp.minimize(variant)
    return ocp


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", choices=VARIANTS, default="time")
    parser.add_argument("--obstacle", action="store_true", help="lift the hand over a bar")
    parser.add_argument("--intervals", type=int, default=20)
    parser.add_argument("--subintervals", type=int, default=1)
    parser.add_argument("--degree", type=int, default=None,
                        help="Radau degree (default: the library's, 4)")
    parser.add_argument("--compile", action="store_true",
                        help="compile the per-element derivative functions to C (cached)")
    parser.add_argument("--no-replay", action="store_true")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    ocp = build(args.variant, args.obstacle, args.intervals, args.subintervals, args.compile,
                degree=args.degree)
    sol = ocp.solve()
    if not args.no_replay:
        sol.replay()
    if args.json:
        print(json.dumps(sol.to_json()))
        return 0
    s = sol.stats
    print(f"Delta pick-and-place, minimum {args.variant}"
          + (" over the obstacle" if args.obstacle else "")
          + f": {s['return_status']} after {s['iterations']} iterations, objective "
          f"{sol.objective:.8g}, final time {sol.t[-1]:.6g} s")
    print(f"  {s['intervals']} intervals × {s['subintervals']} elements, {s['variables']} "
          f"variables, max constraint violation {s['constraint_violation']:.3g}, replay error "
          f"{s.get('replay_error', float('nan')):.3g}")
    print(f"  setup {s['setup_seconds']:.3g} s, NLP solve {s['solve_seconds']:.3g} s")
    top = np.max(sol.value("hand_z"))
    print(f"  highest hand z {top:.4f} m; drive moments in "
          f"[{sol.u.min():+.4g}, {sol.u.max():+.4g}] N m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
