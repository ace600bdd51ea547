"""The parallelogram four-bar at error 1e-9: where the error comes from (issue 22, item 2).

The work-precision problem ``fourbar`` (:mod:`benchmarks.work_precision`: crank angle at
t = 10 s after ten collinear, singular passes) measured piece by piece:

1. **The reference.**  The closed form (elliptic integral inverted by Brent's method,
   :func:`benchmarks.references.four_bar_angle_at_time`) against SciPy's DOP853 and Radau on the
   one-degree-of-freedom equation φ̈ = −(6 g / 5 L) cos φ, and casmbd's IDAS formulations
   (``index1``, ``ggl``), which stop at the first passes.
2. **The right-hand side on the exact trajectory** φ = π + δ (crank, coupler and rocker from
   the closed form): max |q̈ − q̈*| of the augmented Lagrangian without and with the
   refinement near singular poses (``refine``, the default).
3. **The crank error at t = 10 s** against rtol (atol = rtol): absolute and joint coordinates,
   unrefined and default, Adams and DOPRI5, and fixed-step RK4 (unrefined).
4. **Loose tolerances**: the median and largest error over eight runs of different output
   counts (the step sequence changes): unrefined, refined at any state and the default
   (refined at consistent states only).

Usage::

    python -m benchmarks.fourbar_floor [--update-docs] [--render]

writes the section "## Parallelogram four-bar at error 1e-9" of docs/hard_cases.md.
"""

from __future__ import annotations

import math
import os
import statistics
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import casmbd
from benchmarks.docs import HARD_CASES, run_study, study_parser
from benchmarks.references import (
    four_bar_angle_at_time,
    four_bar_rate_squared,
    load_reference,
)
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.formulations.augmented_lagrangian import REFINE, REFINE_DRIFT
from casmbd.errors import CasmbdError

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "fourbar_floor.json"
HEAD = "## Parallelogram four-bar at error 1e-9"
G, T_END = 9.81, 10.0
COMMAND = "python -m benchmarks.fourbar_floor --update-docs"


def _mechanism(coordinates: str):
    mech = casmbd.load_scene(ROOT / "examples" / "parallelogram.toml")
    mech.coordinates = coordinates
    return mech


def _error(res, phi_ref: float) -> float:
    diff = float(res.body("crank")["angle"][-1]) - phi_ref
    return abs((diff + math.pi) % (2.0 * math.pi) - math.pi)


def reference_checks() -> dict:
    """Closed form against SciPy (DOP853, Radau) on the one-DOF ODE and casmbd's IDAS runs."""
    phi_ref = float(load_reference("parallelogram_four_bar")["results"]["phi_end"])
    closed = four_bar_angle_at_time(T_END)
    k = 6.0 * G / 5.0
    out = {"phi_end": phi_ref, "closed_form_now": closed}
    for method, tol in (("DOP853", 1e-13), ("Radau", 1e-12)):
        sol = solve_ivp(lambda t, y: [y[1], -k * math.cos(y[0])], (0.0, T_END),
                        [math.pi / 2, 1.0], method=method, rtol=tol, atol=tol)
        out[f"{method} rtol {tol:g}"] = float(sol.y[0, -1] - phi_ref)
    for form, tol in (("index1", 1e-12), ("ggl", 1e-12), ("index1", 1e-6), ("ggl", 1e-6)):
        for coords in ("absolute", "joint"):
            key = f"{form}/idas {coords} rtol {tol:g}"
            try:
                res = Simulator(_mechanism(coords), form).run(T_END, 1, integrator="idas",
                                                              rtol=tol, atol=tol)
                out[key] = f"error {_error(res, phi_ref):.1e}"
            except CasmbdError as exc:
                text = str(exc)
                out[key] = text[text.find("failed at"):].split(" (")[0]
    return out


def rhs_bias() -> list[dict]:
    """max |q̈ − q̈*| on the exact trajectory at φ = π + δ, joint coordinates (A, B, D)."""
    rows = []
    for label, opts in (("refine 0", {"refine": 0}), (f"default (refine {REFINE})", {})):
        sim = Simulator(_mechanism("joint"), "augmented_lagrangian", formulation_options=opts)
        f = sim.formulation.function
        row = {"variant": label}
        for delta in (1e-2, 2e-3, 1e-3, 1e-4, 1e-6):
            phi = math.pi + delta
            rate, acc = math.sqrt(four_bar_rate_squared(phi)), -(6.0 * G / 5.0) * math.cos(phi)
            s = phi - math.pi / 2
            x = [s, -s, s, rate, -rate, rate]
            got = np.asarray(f(0.0, x, [], [], [])[0]).ravel()[3:]
            row[f"{delta:g}"] = float(np.max(np.abs(got - [acc, -acc, acc])))
        rows.append(row)
    return rows


NONE = {"refine": 0}
CASES = [("absolute", NONE, "adams"), ("absolute", NONE, "dopri5"), ("joint", NONE, "adams"),
         ("joint", NONE, "dopri5"), ("joint", {}, "adams"), ("joint", {}, "dopri5"),
         ("absolute", {}, "adams")]
TIGHT = [1e-10, 1e-11, 1e-12, 1e-13, 1e-14]
LOOSE = [1e-6, 1e-7, 1e-8, 1e-9]


def sweeps(phi_ref: float) -> dict:
    """Crank error at t = 10 s against rtol; fixed-step RK4; loose-tolerance spread."""
    tight, fixed, loose = [], [], []
    for coords, opts, integrator in CASES:
        sim = Simulator(_mechanism(coords), "augmented_lagrangian", formulation_options=opts)
        row = {"coordinates": coords, "refine": sim.formulation.options["refine"],
               "integrator": integrator}
        for tol in TIGHT:
            res = sim.run(T_END, 1, integrator=integrator, rtol=tol, atol=tol)
            row[f"{tol:g}"] = (_error(res, phi_ref), int(res.stats["steps"]),
                               float(res.stats["solve_seconds"]))
        tight.append(row)
    for coords in ("absolute", "joint"):
        sim = Simulator(_mechanism(coords), "augmented_lagrangian", formulation_options=NONE)
        row = {"coordinates": coords}
        for h in (1e-3, 5e-4, 2.5e-4, 1.25e-4):
            res = sim.run(T_END, 1, integrator="rk4", step=h)
            row[f"{h:g}"] = _error(res, phi_ref)
        fixed.append(row)
    for label, opts in (("refine 0", NONE),
                        (f"refine {REFINE} at any state", {"refine_drift": None}),
                        (f"default (refine {REFINE}, drift ≤ {REFINE_DRIFT:g})", {})):
        sim = Simulator(_mechanism("joint"), "augmented_lagrangian", formulation_options=opts)
        row = {"variant": label}
        for tol in LOOSE:
            errs = [_error(sim.run(T_END, n, rtol=tol, atol=tol), phi_ref)
                    for n in (1, 2, 3, 4, 5, 7, 9, 11)]
            row[f"{tol:g}"] = (statistics.median(errs), max(errs))
        loose.append(row)
    return {"tight": tight, "rk4": fixed, "loose": loose}


def measure() -> dict:
    """Every table of the section (JSON-ready)."""
    checks = reference_checks()
    return {"reference": checks, "bias": rhs_bias(), **sweeps(checks["phi_end"]),
            "load": [round(x, 2) for x in os.getloadavg()]}


def markdown(data: dict) -> str:
    """The section of docs/hard_cases.md."""
    ref = data["reference"]
    lines = [HEAD, "",
             "**Problem.** The work-precision problem `fourbar` (`examples/parallelogram.toml`, "
             "benchmarks/work_precision.py): the unit parallelogram four-bar, crank vertical at "
             "+1 rad/s, error = |crank angle(10 s) − closed form|; ten collinear (singular) "
             "passes, where C_q loses one rank. Before this study every coordinate choice "
             "stopped short of error 1e-9 in the sweep (rtol down to 1e-12).", "",
             f"Command: `{COMMAND}` (load average {data['load'][0]:.2f}; times are upper "
             "bounds).", "",
             "**The reference is not the floor.** Closed form φ(10) = "
             f"{ref['phi_end']:.14f} rad; " + "; ".join(
                 f"{k}: {v:+.1e} rad" for k, v in ref.items()
                 if k.startswith(("DOP853", "Radau"))) + ". casmbd's IDAS formulations give "
             "no tight comparison: " + "; ".join(
                 f"{k}: {v}" for k, v in ref.items() if "/idas" in k) + " (index1 stops at a "
             "pass; ggl fails at the start at rtol 1e-12 also on the regular "
             "2-rod chain, a separate limit, and passes at rtol 1e-6).", "",
             "**The right-hand side on the exact trajectory** (joint coordinates, max |q̈ − q̈*| "
             "in rad/s² at φ = π + δ; q̈* from φ̈ = −(6g/5L) cos φ, |q̈*| = 11.8):", "",
             "| augmented Lagrangian | " + " | ".join(
                 f"δ = {k}" for k in data["bias"][0] if k != "variant") + " |",
             "| --- |" + " ---: |" * (len(data["bias"][0]) - 1)]
    for row in data["bias"]:
        lines.append(f"| {row['variant']} | " + " | ".join(
            f"{v:.1e}" for k, v in row.items() if k != "variant") + " |")
    lines += ["", "**Crank error at t = 10 s** (error / steps / solve ms; atol = rtol):", "",
              "| coordinates | refine | integrator | " + " | ".join(
                  f"rtol {t:g}" for t in TIGHT) + " |",
              "| --- | ---: | --- |" + " --- |" * len(TIGHT)]
    for row in data["tight"]:
        lines.append(f"| {row['coordinates']} | {row['refine']} | {row['integrator']} | "
                     + " | ".join(f"{e:.1e} / {s} / {1e3 * t:.0f}"
                                  for e, s, t in (row[f"{tol:g}"] for tol in TIGHT)) + " |")
    lines += ["", "Fixed-step RK4 on the unrefined right-hand side (crank error):", "",
              "| coordinates | " + " | ".join(f"h = {k}" for k in data["rk4"][0]
                                             if k != "coordinates") + " |",
              "| --- |" + " ---: |" * (len(data["rk4"][0]) - 1)]
    for row in data["rk4"]:
        lines.append(f"| {row['coordinates']} | " + " | ".join(
            f"{v:.1e}" for k, v in row.items() if k != "coordinates") + " |")
    lines += ["", "Loose tolerances, joint coordinates, Adams: median / largest crank error "
              "over eight runs (1, 2, 3, 4, 5, 7, 9, 11 output intervals):", "",
              "| augmented Lagrangian | " + " | ".join(f"rtol {t:g}" for t in LOOSE) + " |",
              "| --- |" + " ---: |" * len(LOOSE)]
    for row in data["loose"]:
        lines.append(f"| {row['variant']} | " + " | ".join(
            f"{m:.1e} / {x:.1e}" for m, x in (row[f"{t:g}"] for t in LOOSE)) + " |")
    lines += ["", "**Findings.**", "",
              "* The reference is exact to ~1e-11 rad; the floor is in casmbd.",
              "* Absolute coordinates: the right-hand side is exact to ≈ 1e-13 relative through "
              "the passes (the singular direction carries no load there: "
              "tests/analysis/formulations/test_al_accuracy"
              ".py, benchmarks/al_accuracy.py) and RK4 and DOPRI5 converge cleanly (DOPRI5 "
              "below 1e-9 from rtol 1e-11); with Adams the error is 1e2–1e4 × rtol, made at the "
              "passes, and falls below 1e-9 only from rtol 1e-13 — the work-precision sweep "
              "stopped at 1e-12 and now goes on to 1e-14 for this problem.",
              "* Joint coordinates (the default path): the cut joint C carries the coupler's "
              "load along the collinear links, the augmented Lagrangian's unconverged singular "
              "direction leaves q̈ off by ≈ σ Δλ within |δ| ≲ 1e-2 rad of each pass, and "
              "without refinement the error floors at 1e-8 whatever the integrator (Adams, "
              "DOPRI5, RK4). The refinement (default since this study: "
              f"{REFINE} more corrections where the last two say the iteration is not done and "
              f"the drift is ≤ {REFINE_DRIFT:g}; idle and bit-identical at regular poses) "
              "narrows the window (δ = 1e-3: 3e-3 → 0; δ = 1e-4: 2.4e-3 → 1.2e-3) and the "
              "default path reaches 1e-9 from rtol 1e-12 "
              "(tests/analysis/formulations/test_al_refine.py).",
              "* The drift gate keeps loose tolerances as they were: refined at any state, the "
              "narrower window is a sharper feature for the integrator and states that far off "
              "the constraints get resolved along the unconverged direction (last table).",
              "* CVODES-Adams stays erratic through the passes (absolute coordinates at rtol "
              "1e-13: 2.8e-10 unrefined, 1.2e-9 with the refinement, which changes nothing "
              "there but the rounding); DOPRI5 converges monotonically."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    args = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False).parse_args(argv)
    return run_study(args, RESULTS, measure, markdown, HARD_CASES, HEAD)


if __name__ == "__main__":
    raise SystemExit(main())
