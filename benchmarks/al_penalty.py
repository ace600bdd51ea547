"""Penalty and iteration count of the augmented-Lagrangian formulation: error against cost.

The default formulation for closed loops iterates (M + α C_qᵀC_q) q̈ = Q − C_qᵀλᵢ + α C_qᵀγ_b,
λᵢ₊₁ = λᵢ + α (C_q q̈ − γ_b) a fixed number of times.  A direction of C_q with singular value
σ converges at the rate 1/(1 + α σ²/m) per iteration, while the rounding noise of every
right-hand side grows like cond(M + α C_qᵀC_q) ε ≈ α ε.  Chains of parallelograms near their
singular poses want a large α (their vanishing σ carry load); regular chains at tight
tolerances want a small one.  This script measures both sides of the trade-off:

* the N four-bar chain (N = 3, 4 s, four singular passes, rtol 1e-10): crank angle against
  the one-DOF reference and the spread of the bar angles;
* the 8-rod and 32-rod pendulum chains and the parallelogram four-bar of
  ``benchmarks/work_precision.py``: error against the stored references at rtol 1e-6, 1e-9,
  1e-12, with the solve time (median of ``--repeat``).

Usage::

    python -m benchmarks.al_penalty [--repeat 3] [--update-docs]

``--update-docs`` writes the section "Choosing the augmented-Lagrangian penalty" of
``docs/dynamics.md``.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np

from benchmarks.docs import replace_section
from benchmarks.n_four_bar import bar_angles, n_four_bar
from benchmarks.n_four_bar_reference import one_dof_reference
from benchmarks.work_precision import problem
from casmbd.analysis.dynamics.simulate import Simulator

ROOT = Path(__file__).resolve().parents[1]
#: (penalty factor on the default, iterations)
VARIANTS = ((1.0, 4), (1.0, 8), (10.0, 4), (10.0, 6), (30.0, 4), (100.0, 4), (100.0, 8))
TOLS = (1e-6, 1e-9, 1e-12)
HEAD = "## Choosing the augmented-Lagrangian penalty"


def _sim(mech, factor: float, iterations: int) -> Simulator:
    base = Simulator(mech, "augmented_lagrangian").formulation.options["penalty"]
    return Simulator(mech, "augmented_lagrangian",
                     formulation_options={"penalty": factor * base, "iterations": iterations})


def _timed(sim: Simulator, t_end: float, steps: int, rtol: float, repeat: int):
    times, res = [], None
    for _ in range(repeat):
        res = sim.run(t_end, steps, rtol=rtol, atol=rtol)
        times.append(res.stats["solve_seconds"])
    return res, statistics.median(times)


def singular_chain(factor: float, iterations: int, repeat: int, n: int = 3) -> dict:
    """Crank-angle error and bar-angle spread of the N four-bar chain over 4 s."""
    res, seconds = _timed(_sim(n_four_bar(n), factor, iterations), 4.0, 400, 1e-10, repeat)
    angles = bar_angles(res, n)
    theta_ref, _ = one_dof_reference(res.t, n)
    return {"angle": float(np.max(np.abs(angles[:, 0] - theta_ref))),
            "parallel": float(np.max(np.abs(angles - angles[:, :1]))), "seconds": seconds}


def regular(name: str, factor: float, iterations: int, repeat: int) -> list[tuple]:
    """(error, seconds) at each tolerance of :data:`TOLS` for a work-precision problem."""
    mech, t_end, error, _ = problem(name)
    sim = _sim(mech, factor, iterations)
    out = []
    for tol in TOLS:
        res, seconds = _timed(sim, t_end, 1, tol, repeat)
        out.append((error(res), seconds))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--update-docs", action="store_true")
    args = ap.parse_args(argv)
    head = ("| penalty × | iterations | N four-bar (N = 3): crank angle / bar spread | "
            + " | ".join(f"{p} error / ms ({', '.join(f'{t:.0e}' for t in TOLS)})"
                         for p in ("chain8", "chain32", "fourbar")) + " |")
    lines = [head, "|" + " --- |" * (3 + 3)]
    for factor, iterations in VARIANTS:
        s = singular_chain(factor, iterations, args.repeat)
        cells = [f"{factor:g}", str(iterations),
                 f"{s['angle']:.1e} / {s['parallel']:.1e} ({s['seconds'] * 1e3:.0f} ms)"]
        for name in ("chain8", "chain32", "fourbar"):
            rows = regular(name, factor, iterations, args.repeat)
            cells.append("; ".join(f"{e:.1e} / {t * 1e3:.0f}" for e, t in rows))
        lines.append("| " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    if args.update_docs:
        section = "\n".join([
            HEAD, "",
            "Measured with `python -m benchmarks.al_penalty --update-docs` (median of "
            f"{args.repeat} solves; 2-core machine, other jobs running, so read the times as "
            "±30 %). Penalty × is the factor on the default 1e5 · mean(diag M) / "
            "mean(diag C_qᵀC_q).", "",
            *lines, "",
            "A larger penalty converges the loaded, nearly singular directions of a chain of "
            "parallelograms (crank-angle error 1.7e-5 → 8e-8 rad at ×100) but raises the noise "
            "floor of every right-hand side (the 8-rod chain floors at ~1e-9 instead of "
            "~4e-12 at rtol 1e-12, and the stiff step-size control then costs 5–10× more). "
            "More iterations at the default penalty buy little. The default stays at ×1 / 4 "
            "iterations, the best choice for regular mechanisms at every tolerance; for long "
            "runs through the singular poses of multi-loop chains pass "
            "`formulation_options={\"penalty\": 100 * default, \"iterations\": 8}` "
            "(the default is `Simulator(m).formulation.options[\"penalty\"]`) and keep the "
            "tolerance at 1e-10 or looser.", ""])
        replace_section(ROOT / "docs" / "dynamics.md", HEAD, section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
