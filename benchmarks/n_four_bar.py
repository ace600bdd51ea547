"""IFToMM / UDC benchmark A02, the *N four-bar mechanism*: a chain of N parallelograms.

**Problem** (M. González, D. Dopico, U. Lugrís, J. Cuadrado, *A benchmarking system for MBS
simulation software: problem standardization and performance measurement*, Multibody System
Dynamics 16 (2006) 179–190; specification ``lim.ii.udc.es/mbsbenchmark/dist/A02/
A02_specification.xml``, 2005; listed in the IFToMM library of computational benchmark
problems, www.iftomm-multibody.org).  N four-bar windows made of 2N + 1 slender links of
L = 1 m and m = 1 kg: N + 1 *bars* pinned to the ground at (i L, 0), i = 0 … N, upright at t = 0,
and N horizontal *couplers* joining the bars' upper ends B_{i−1} and B_i.  Gravity 9.81 m/s²
along −y.  Initially the x-velocity of B0 (the top of the first bar) is 1 m/s: every bar turns
at −1 rad/s, every coupler translates at (1, 0) m/s.  The analysis is a 20 s dynamic simulation
with N = 40; the reference solution is the time history of B0 (400 output steps; allowed errors
1e-1 (low precision) and 1e-3 (high precision)).

**Singular poses.** Whenever the bars are horizontal every link lies on the ground line, the
loop equations become dependent and the mobility jumps from 1 to N + 1 (the specification's
words).  With the benchmark's energy the chain circulates (it goes over the top), so each bar
passes a horizontal pose twice per turn — 20 singular passes in 20 s.  A solver that leaves the
*parallelogram branch* there (a bar folding back while its neighbours go on) is wrong.

**Closed form on the branch**: all bars share one angle and α = θ + π/2 obeys the pendulum
equation α̈ = −k sin α; derived, solved by elliptic functions and checked by SciPy in
:mod:`benchmarks.n_four_bar_reference` (the benchmark's constants live there too).

Run ``python -m benchmarks.n_four_bar --update-docs`` (writes the section
"## N four-bar chain (IFToMM)" of docs/hard_cases.md, replacing only that section, and the
measurements to benchmarks/results/n_four_bar.json; ``--render`` rewrites the section from that
file).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.docs import coordinate_reason, heading, study_parser, update_hard_cases, used
from benchmarks.n_four_bar_reference import (
    N_BENCH,
    STEPS,
    T_END,
    G,
    b0_position,
    closed_form_angle,
    published_error,
    reference_checks,
)
from casmbd.model import Mechanism

__all__ = [
    "bar_angles",
    "bar_name",
    "coupler_angles",
    "coupler_name",
    "n_four_bar",
    "scene_text",
]

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "hard_cases.md"
RESULTS = ROOT / "benchmarks" / "results" / "n_four_bar.json"
HEAD = "## N four-bar chain (IFToMM)"
def bar_name(i: int) -> str:
    """Name of the ``i``-th bar (0-based, pinned to the ground at (i L, 0)): ``"bar{i}"``."""
    return f"bar{i}"


def coupler_name(i: int) -> str:
    """Name of the ``i``-th coupler (1-based, from B_{i−1} to B_i): ``"coupler{i}"``."""
    return f"coupler{i}"


def n_four_bar(n: int, length: float = 1.0, mass: float = 1.0, gravity: float = G,
               speed: float = 1.0) -> Mechanism:
    """The N four-bar mechanism (UDC / IFToMM benchmark A02) in its initial pose.

    Bars ``bar0`` … ``bar{n}`` (slender rods, inertia m L²/12 about the centre, body x-axis
    along the bar) stand upright on revolute joints ``A{i}`` at (i L, 0); couplers
    ``coupler1`` … ``coupler{n}`` lie horizontally at height L, pinned to the bars' tops by
    ``L{i}`` (at B_{i−1}) and ``R{i}`` (at B_i).  Marker ``"B0"`` is the top of ``bar0``.  The
    initial velocities are the benchmark's: every bar turns at −speed / L rad/s (B0 moves
    along +x at ``speed``), every coupler translates at (speed, 0).

    The mechanism has 3 (2n + 1) coordinates, 6n + 2 constraint equations and one degree of
    freedom away from the singular poses (bars horizontal), where C_q loses n ranks.

    Parameters
    ----------
    n : int
        Number of four-bar windows, at least 1 (the benchmark: 40).
    length, mass : float
        Length [m] and mass [kg] of every link (the benchmark: 1 and 1).
    gravity : float
        Gravitational acceleration along −y [m/s²].
    speed : float
        Initial x-velocity of B0 [m/s].

    Returns
    -------
    casmbd.model.Mechanism
        Named ``"n_four_bar_{n}"``.

    Raises
    ------
    ValueError
        When ``n`` is not a positive integer or ``length`` is not positive.
    """
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"n_four_bar: n must be a positive integer, got {n!r}")
    if not length > 0.0:
        raise ValueError(f"n_four_bar: length must be > 0, got {length!r}")
    n, L = int(n), float(length)
    mech = Mechanism(f"n_four_bar_{n}", gravity=(0.0, -float(gravity)))
    inertia = mass * L**2 / 12.0
    omega = -float(speed) / L
    for i in range(n + 1):
        mech.add_body(bar_name(i), mass=mass, inertia=inertia, position=(i * L, 0.5 * L),
                      angle=0.5 * math.pi, velocity=(-omega * 0.5 * L, 0.0),
                      angular_velocity=omega)
        mech.add_revolute(f"A{i}", "ground", bar_name(i), point=(i * L, 0.0))
    for i in range(1, n + 1):
        mech.add_body(coupler_name(i), mass=mass, inertia=inertia,
                      position=((i - 0.5) * L, L), velocity=(float(speed), 0.0))
        mech.add_revolute(f"L{i}", bar_name(i - 1), coupler_name(i), point=((i - 1) * L, L))
        mech.add_revolute(f"R{i}", coupler_name(i), bar_name(i), point=(i * L, L))
    mech.add_marker("B0", bar_name(0), point=(0.0, L))
    return mech


def scene_text(n: int) -> str:
    """The TOML scene of :func:`n_four_bar` with the benchmark's data.

    ``examples/n_four_bar_3.toml`` is ``scene_text(3)``.
    """
    lines = [
        f"# N four-bar mechanism (UDC / IFToMM benchmark A02) with N = {n} windows: {n + 1} bars "
        "pinned to the",
        "# ground at (i, 0), upright, and their tops joined by horizontal couplers; all links "
        "1 m, 1 kg slender",
        "# rods.  B0 (top of bar0) starts at +1 m/s along x.  Whenever the bars are horizontal "
        "every link lies",
        "# on the ground line and the mobility jumps from 1 to N + 1 (a singular "
        "configuration); the motion",
        "# must stay on the parallelogram branch: all bar angles equal, couplers level.  "
        "Generated by",
        f"# benchmarks.n_four_bar.scene_text({n}); the benchmark itself is N = 40 "
        "(benchmarks/n_four_bar.py).",
        "[scene]", f'name = "n_four_bar_{n}"', "dimension = 2", "gravity = [0.0, -9.81]", ""]
    for i in range(n + 1):
        lines += ["[[bodies]]", f'name = "{bar_name(i)}"', "mass = 1.0", 'inertia = "1/12"',
                  f"position = [{float(i)}, 0.5]", "angle = 1.5707963267948966",
                  "velocity = [0.5, 0.0]", "angular_velocity = -1.0", ""]
    for i in range(1, n + 1):
        lines += ["[[bodies]]", f'name = "{coupler_name(i)}"', "mass = 1.0",
                  'inertia = "1/12"', f"position = [{i - 0.5}, 1.0]", "angle = 0.0",
                  "velocity = [1.0, 0.0]", ""]
    lines += ["[[markers]]", 'name = "B0"', f'body = "{bar_name(0)}"', "point = [0.0, 1.0]", ""]
    joints = [(f"A{i}", "ground", bar_name(i), (float(i), 0.0)) for i in range(n + 1)]
    for i in range(1, n + 1):
        joints += [(f"L{i}", bar_name(i - 1), coupler_name(i), (float(i - 1), 1.0)),
                   (f"R{i}", coupler_name(i), bar_name(i), (float(i), 1.0))]
    for name, b1, b2, point in joints:
        lines += ["[[joints]]", f'name = "{name}"', 'type = "revolute"', f'body1 = "{b1}"',
                  f'body2 = "{b2}"', f"point = [{point[0]}, {point[1]}]", ""]
    return "\n".join(lines).rstrip() + "\n"


def bar_angles(result, n: int) -> np.ndarray:
    """Unwrapped absolute angles of bar0 … bar{n} from a casmbd result, shape (n_t, n + 1)
    (the bodies' poses: any coordinates)."""
    angles = np.column_stack([result.body(bar_name(i))["angle"] for i in range(n + 1)])
    return np.unwrap(angles, axis=0)


def coupler_angles(result, n: int) -> np.ndarray:
    """Absolute angles of coupler1 … coupler{n} in (−π, π], shape (n_t, n) (any
    coordinates)."""
    angles = np.column_stack([result.body(coupler_name(i))["angle"] for i in range(1, n + 1)])
    return np.angle(np.exp(1j * angles))


# ---------------------------------------------------------------------- benchmark
ALL_RTOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
#: (label, coordinates, formulation, formulation options (penalty given as a multiple of the
#: default), integrator, rtols, max_steps per output interval).  The default path chooses
#: nothing (``coordinates = "auto"``: for N = 40, joint coordinates with 2N loop equations on
#: 2N + 1 tree coordinates); the other rows pin absolute coordinates (the study of the
#: augmented Lagrangian through the singular passes, written for them)
DEFAULT = "default path (nothing chosen)"
ABS_AL = "absolute, augmented_lagrangian (default penalty)"
CONFIGS = (
    (DEFAULT, "auto", None, None, None, ALL_RTOLS, None),
    (ABS_AL, "absolute", None, None, None, ALL_RTOLS, None),
    ("absolute, augmented_lagrangian, penalty ×100, 8 iterations", "absolute",
     "augmented_lagrangian", {"penalty_factor": 100.0, "iterations": 8}, None,
     (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12), None),
    ("absolute, kkt_ode / adams", "absolute", "kkt_ode", None, "adams", (1e-8, 1e-10),
     50_000),
    ("absolute, index1 / idas", "absolute", "index1", None, "idas", (1e-8, 1e-10), 50_000),
)
#: the benchmark's accuracy classes for B0 (maximum error over the 400 output steps)
HIGH, LOW = 1e-3, 1e-1


def evaluate(result, n: int) -> dict:
    """Errors against the closed form, branch checks and balances of one run."""
    theta_ref = closed_form_angle(result.t, n)
    angles = bar_angles(result, n)
    b0 = result.marker("B0")["position"][:, :2]
    energy = result["total_energy"]
    return {
        "b0_error": float(np.max(np.abs(b0 - b0_position(theta_ref)))),
        "theta_error_end": float(abs(angles[-1, 0] - theta_ref[-1])),
        "theta_error": float(np.max(np.abs(angles[:, 0] - theta_ref))),
        "published_error": published_error(result.t, b0),
        "branch": float(np.max(np.abs(angles - angles[:, :1]))),
        "coupler": float(np.max(np.abs(coupler_angles(result, n)))),
        "energy0": float(energy[0]),
        "energy_drift": float(np.max(np.abs(energy - energy[0]))),
        "violation": float(np.max(result["constraint_violation"])),
        "near_singular": len(result.stats.get("near_singular_times", [])),
        "turns": float((theta_ref[0] - theta_ref[-1]) / (2 * math.pi)),
    }


def measure(config, n: int, repeat: int, slow: float) -> list[dict]:
    """Every tolerance of one configuration (build once, run ``repeat`` times each)."""
    from casmbd.analysis.dynamics.simulate import Simulator
    from casmbd.errors import CasmbdError, IntegratorError

    label, coords, formulation, options, integrator, rtols, max_steps = config
    mech = n_four_bar(n)
    if coords != "auto":
        mech.coordinates = coords
        mech.name = f"{mech.name}_{coords}"
    t0 = time.perf_counter()
    if options and "penalty_factor" in options:
        base = Simulator(mech, formulation).formulation.options["penalty"]
        options = {"penalty": options["penalty_factor"] * base,
                   **{k: v for k, v in options.items() if k != "penalty_factor"}}
    sim = Simulator(mech, formulation, formulation_options=options)
    build = time.perf_counter() - t0
    rows = []
    for rtol in rtols:
        row = {"config": label, "rtol": rtol, "formulation": sim.formulation_name,
               "coordinates": sim.model.coordinates,
               "options": {k: float(v) for k, v in sim.formulation.options.items()},
               "build_seconds": build}
        times = []
        try:
            for _ in range(repeat):
                res = sim.run(T_END, STEPS, rtol=rtol, integrator=integrator,
                              max_steps=max_steps)
                times.append(res.stats["solve_seconds"])
                if res.stats["solve_seconds"] > slow:
                    break
        except CasmbdError as exc:
            text = str(exc)
            message = (f"{exc.flag} at t = {exc.time:.4g} s" if isinstance(exc, IntegratorError)
                       else text.splitlines()[0])
            cond = text.split("conditioning σ_min/σ_max = ")
            if len(cond) > 1:
                message += f", C_q conditioning there {cond[1].split(':')[0].split(';')[0]}"
            partial = getattr(exc, "partial", None)
            if partial is not None and len(partial.t) > 1:
                kept = evaluate(partial, n)
                message += (f"; outputs kept to t = {partial.t[-1]:.4g} s, branch there "
                            f"{kept['branch']:.1e} rad")
                row["partial"] = kept
            row.update(status="failed", message=message)
            rows.append(row)
            print(f"{label:50s} rtol {rtol:.0e}  failed: {message}", flush=True)
            continue
        row.update(status="ok", steps=res.stats["steps"],
                   solve_seconds=statistics.median(times), repeats=len(times),
                   integrator=res.stats["integrator"],
                   coordinate_choice=coordinate_reason(res.stats),
                   integrator_choice=res.stats.get("integrator_choice"), **evaluate(res, n))
        rows.append(row)
        print(f"{label:50s} rtol {rtol:.0e}  B0 err {row['b0_error']:.2e}  θ err "
              f"{row['theta_error_end']:.2e}  branch {row['branch']:.1e}  steps "
              f"{row['steps']:7d}  {1e3 * row['solve_seconds']:8.1f} ms", flush=True)
    return rows


def conditioning_survey(n: int = N_BENCH, rtol: float = 1e-10) -> dict:
    """σ_r/σ_1 of the equilibrated C_q at *every* output step of a run of the augmented
    Lagrangian in absolute coordinates (casmbd's result evaluates a subset for large models)
    and its local minima."""
    from casmbd.analysis.dynamics.simulate import Simulator
    from casmbd.analysis.instant.redundancy import equilibrated_singular_values

    mech = n_four_bar(n)
    mech.coordinates = "absolute"  # the rank 6N + 2 below is the absolute description's
    mech.name = f"{mech.name}_absolute"
    sim = Simulator(mech)
    res = sim.run(T_END, STEPS, rtol=rtol)
    rank = 6 * n + 2
    cond = np.array([(lambda s: s[rank - 1] / s[0])(equilibrated_singular_values(
        sim.model.constraint_jacobian(q, float(t)))) for q, t in zip(res["q"], res.t)])
    minima = [k for k in range(1, len(cond) - 1) if cond[k] <= cond[k - 1]
              and cond[k] < cond[k + 1]]
    stats_cond = res["constraint_conditioning"]
    return {"minima": len(minima), "minima_times": [float(res.t[k]) for k in minima],
            "minima_range": (float(min(cond[minima])), float(max(cond[minima]))),
            "regular_max": float(cond.max()),
            "evaluated_by_result": int(np.sum(np.isfinite(stats_cond))),
            "reported": len(res.stats["near_singular_times"])}


def _fmt(x: float) -> str:
    return f"{x:.1e}" if x > 0 else "0"


def _cls(err: float) -> str:
    return "high" if err < HIGH else ("low" if err < LOW else "—")


def markdown(rows: list[dict], ref: dict, survey: dict, command: str) -> str:
    """The section of docs/hard_cases.md."""
    from benchmarks.work_precision import machine

    ok = [r for r in rows if r["status"] == "ok"]
    e0 = ok[0]["energy0"] if ok else float("nan")
    lines = [
        HEAD, "",
        "**Problem.** UDC / IFToMM benchmark A02, *N four-bar mechanism* (M. González, D. "
        "Dopico, U. Lugrís, J. Cuadrado, Multibody System Dynamics 16 (2006) 179–190; "
        "specification `lim.ii.udc.es/mbsbenchmark/dist/A02/A02_specification.xml`, 2005). "
        f"N = {N_BENCH} four-bar windows of 2N + 1 = {2 * N_BENCH + 1} slender links (1 m, 1 kg, "
        "m L²/12 about the centre): N + 1 bars pinned to the ground at (i, 0) m, upright at "
        "t = 0, and N horizontal couplers between their tops B_{i−1}, B_i; gravity 9.81 m/s² "
        "along −y; initial x-velocity of B0 (top of the first bar) 1 m/s; 20 s. The "
        "reference solution is the time history of B0 at 400 output steps, with allowed "
        "errors 1e-3 (high precision) and 1e-1 (low precision). Builder: "
        "`benchmarks.n_four_bar.n_four_bar(n)`; a small scene: `examples/n_four_bar_3.toml`.",
        "",
        "**Sources read.** The specification page (text above) and the reference data file "
        "`A02_solution_data.txt` (an ADAMS/Solver 2003 run by the problem's authors, B0 every "
        "0.05 s to 6 significant digits; initial state: bars at −1 rad/s, couplers at (1, 0) "
        "m/s), read from the copy in github.com/mikevignos/simEngine3D-Vignos; MBS-BOS "
        "(RehabEngGroup/MBSbenchmarksInOpenSim, `src/A02-NFourBarMechanism`) for the link "
        "inertia (thin cylinders, m L²/12). B0 at the whole seconds is stored in "
        "`PUBLISHED_B0`; at t = 20 s the published B0 is (0.410902, 0.911679) m.", "",
        "**Closed form on the parallelogram branch** (derived in "
        "`benchmarks/n_four_bar_reference.py`). "
        "All bars share one angle θ and the couplers translate, so T = ½ [(N+1)/3 + N] m L² "
        "θ̇², V = [(N+1)/2 + N] m g L sin θ, and α = θ + π/2 obeys the pendulum equation "
        "α̈ = −k sin α with k = 3g(3N+1)/(2L(4N+1)) = "
        f"{ref['k']:.6f} s⁻² for N = {N_BENCH}. The chain circulates (goes over the top): "
        f"with β = α/2, β(t) = am(K(m) − ωt | m), ω² = (E + k)/2, E = ½ (v_B0/L)² + k, "
        f"m = 2k/(E + k) = {ref['modulus']:.9f}, one turn every "
        f"{ref['period']:.6f} s. Checks: SciPy's DOP853 at rtol = atol = 1e-12 on the one-DOF "
        f"equation differs from the elliptic-function form by at most "
        f"{ref['ode_vs_closed_form']:.1e} rad over 20 s; the closed form differs from the "
        f"published ADAMS history by at most {ref['closed_form_vs_published']:.1e} m at the "
        "20 whole seconds (the published file's own accuracy: 6 digits). At t = 20 s: θ = "
        f"{ref['theta_end']:.10f} rad, B0 = ({ref['b0_end'][0]:.10f}, "
        f"{ref['b0_end'][1]:.10f}) m.", "",
        f"**Singular poses.** The bars are horizontal {ref['passes']} times in 20 s (first at "
        f"t = {ref['pass_times'][0]:.6f} s, then every half turn); there every link lies on "
        f"the ground line and C_q loses N = {N_BENCH} ranks (mobility 1 → N + 1). Evaluated "
        f"at every one of the 401 output steps of a run in absolute coordinates (augmented "
        f"Lagrangian, rtol 1e-10), σ_r/σ_1 of the equilibrated "
        f"C_q has {survey['minima']} local minima ({survey['minima_range'][0]:.1e} to "
        f"{survey['minima_range'][1]:.1e} on the 0.05 s grid, against ≤ "
        f"{survey['regular_max']:.3f} elsewhere). casmbd's result evaluates only "
        f"{survey['evaluated_by_result']} of the 401 steps for a model of this size; its "
        f"singular-pass monitor reports {survey['reported']} `near_singular_times` in that "
        "run (see findings).", "",
        f"Measured on {machine()}.", "",
        f"Command: `{command}`", "",
        "Columns: *B0 err* — max over the 401 outputs of |B0 − closed form| (x or y), with "
        "the benchmark's class (high < 1e-3 m, low < 1e-1 m); *θ(20) err* — bar0 angle at "
        "20 s against the closed form; *pub.* — max |B0 − published| at the whole seconds; "
        "*branch* — max over time of max_i |θ_i − θ_0| (all bars parallel) and *coupler* — "
        "max |coupler angle| (they translate); *ΔE* — max |E − E(0)| with E(0) = "
        f"{e0:.6f} J; *passes* — the singular passes the result reports "
        "(`stats['near_singular_times']`); solve time: integration alone, median of the "
        "repeats († a single run); atol = rtol. The *default path* chooses nothing "
        "(`n_four_bar(40)` as built); its heading names what casmbd chose (`res.stats`); the "
        "other configurations pin absolute coordinates.", ""]
    for label, *_ in CONFIGS:
        mine = [r for r in rows if r["config"] == label]
        if not mine:
            continue
        opts = next((r["options"] for r in mine if r.get("options")), {})
        extra = (f" — penalty {opts['penalty']:.3g}, {int(opts['iterations'])} iterations, "
                 f"Baumgarte α = β = {opts['alpha']:g}") if "penalty" in opts else ""
        lines += [f"**{heading(label, rows, label == DEFAULT)}**{extra}", "",
                  "| rtol | B0 err [m] | class | θ(20) err [rad] | pub. [m] | branch [rad] | "
                  "coupler [rad] | ΔE [J] | max ‖C‖ | passes | steps | solve [ms] |",
                  "| ---: | ---: | :---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
                  "---: | ---: |"]
        for r in mine:
            if r["status"] != "ok":
                lines.append(f"| {r['rtol']:.0e} | failed: {r['message']} | | | | | | | | | "
                             "| |")
                continue
            mark = "" if r["repeats"] > 1 else " †"
            lines.append(
                f"| {r['rtol']:.0e} | {_fmt(r['b0_error'])} | {_cls(r['b0_error'])} | "
                f"{_fmt(r['theta_error_end'])} | {_fmt(r['published_error'])} | "
                f"{_fmt(r['branch'])} | {_fmt(r['coupler'])} | {_fmt(r['energy_drift'])} | "
                f"{_fmt(r['violation'])} | {r['near_singular']} | {r['steps']} | "
                f"{1e3 * r['solve_seconds']:.1f}{mark} |")
        lines.append("")
    lines += [*findings(rows, ref, survey), ""]
    return "\n".join(lines) + "\n"


def findings(rows: list[dict], ref: dict, survey: dict) -> list[str]:
    """What the tables say, with the numbers taken from them."""
    def of(k: int) -> list[dict]:
        return [r for r in rows if r["config"] == CONFIGS[k][0]]

    auto = [r for r in of(0) if r["status"] == "ok"]
    default = [r for r in of(1) if r["status"] == "ok"]
    tuned = [r for r in of(2) if r["status"] == "ok"]
    failed = [r for r in of(3) + of(4) if r["status"] != "ok"]
    # runs that did not fail but left the parallelogram branch (silently wrong)
    astray = [r for r in of(3) + of(4) if r["status"] == "ok" and r["branch"] > 1e-3]
    out = ["**Findings.**", ""]

    def cheapest_high(mine: list[dict]) -> dict | None:
        high = [r for r in mine if r["b0_error"] < HIGH]
        return min(high, key=lambda r: r["solve_seconds"]) if high else None

    if auto:
        first, tight_a = auto[0], [r for r in auto if r["rtol"] <= 1e-8] or auto
        why, integ = first.get("coordinate_choice"), first.get("integrator_choice")
        text = (f"* **Default path.** With nothing chosen casmbd took {used(first)} ("
                + (f"{why}; " if why and why != first["coordinates"] else
                   f"{2 * N_BENCH} loop equations on {2 * N_BENCH + 1} tree coordinates; ")
                + ("the stiffness check keeps Adams" if integ == "default" else integ)
                + "). For rtol ≤ 1e-8 the bars stay parallel "
                f"to {max(r['branch'] for r in tight_a):.1e} rad, B0 is within "
                f"{min(r['b0_error'] for r in tight_a):.1e}–"
                f"{max(r['b0_error'] for r in tight_a):.1e} m of the closed form and the "
                f"energy within {min(r['energy_drift'] for r in tight_a):.1e}–"
                f"{max(r['energy_drift'] for r in tight_a):.1e} J; the result reports "
                f"{min(r['near_singular'] for r in auto)}–"
                f"{max(r['near_singular'] for r in auto)} singular passes "
                f"({ref['passes']} on the closed form).")
        mine, theirs = cheapest_high(auto), cheapest_high(default)
        if mine:
            text += (f" The cheapest high-precision run took "
                     f"{1e3 * mine['solve_seconds']:.0f} ms (rtol {mine['rtol']:.0e})" + (
                         f", {mine['solve_seconds'] / theirs['solve_seconds']:.2g}× the "
                         f"absolute-coordinate augmented Lagrangian's "
                         f"{1e3 * theirs['solve_seconds']:.0f} ms (rtol {theirs['rtol']:.0e})"
                         if theirs else "") + ".")
        else:
            text += " No run meets the high-precision class (B0 within 1e-3 m)."
        out.append(text)
    tight = [r for r in default if r["rtol"] <= 1e-8]
    if default and tight:
        cheapest = cheapest_high(default)
        high = [r for r in default if r["b0_error"] < HIGH]
        loose = max(default, key=lambda r: r["rtol"])
        out.append(
            f"* The augmented Lagrangian in absolute coordinates (the default before the "
            f"automatic choice of coordinates) passes all {ref['passes']} singular poses on the "
            f"parallelogram branch at every tolerance: for rtol ≤ 1e-8 the bars stay parallel "
            f"to {max(r['branch'] for r in tight):.1e} rad and the couplers level to "
            f"{max(r['coupler'] for r in tight):.1e} rad ({loose['branch']:.1e} and "
            f"{loose['coupler']:.1e} rad at rtol {loose['rtol']:.0e}; on the other branch "
            "these are O(1)). "
            + (f"It meets the benchmark's high-precision class (B0 within 1e-3 m at all 400 "
               f"steps) from rtol {max(r['rtol'] for r in high):.0e}; the cheapest such run "
               f"took {1e3 * cheapest['solve_seconds']:.0f} ms (rtol {cheapest['rtol']:.0e}). "
               if cheapest else "")
            + (("But its error does not fall below "
                f"{min(r['b0_error'] for r in tight):.1e} m (B0) and "
                f"{min(r['energy_drift'] for r in tight):.1e} J (energy) however tight rtol is "
                f"(rtol 1e-8 … {min(r['rtol'] for r in tight):.0e}): the error is made at the "
                "singular passes, not by the integrator.")
               if tight[-1]["b0_error"] > 0.3 * tight[0]["b0_error"] else
               (f"Its error falls from {tight[0]['b0_error']:.1e} m (B0) at rtol "
                f"{tight[0]['rtol']:.0e} to {tight[-1]['b0_error']:.1e} m at rtol "
                f"{tight[-1]['rtol']:.0e}.")))
    if tuned and tight:
        best = min(tuned, key=lambda r: r["b0_error"])
        tuned_tight = [r for r in tuned if r["rtol"] <= 1e-8] or tuned
        out.append(
            f"* Why: the augmented-Lagrangian iteration ({int(default[0]['options']['iterations'])}"
            f" iterations, penalty {default[0]['options']['penalty']:.3g}, 1e5 × the "
            "mass/Jacobian scale) converges on a constraint direction at the rate "
            "1/(1 + penalty σ²/m); near a singular pose the σ of the N vanishing directions "
            "goes to zero and, for chains of two or more windows, these directions carry "
            "load, so the constraint forces there are left unconverged, the Baumgarte terms "
            "pull the drift back and the energy drops at every pass. With the penalty ×100 "
            f"and 8 iterations the same formulation reaches B0 error {best['b0_error']:.1e} m "
            f"and ΔE {best['energy_drift']:.1e} J (rtol {best['rtol']:.0e}) and keeps the bars "
            f"parallel to {max(r['branch'] for r in tuned_tight):.1e} rad for rtol ≤ 1e-8, "
            f"at {tuned_tight[-1]['solve_seconds'] / tight[-1]['solve_seconds']:.1f}× the "
            f"solve time of the default penalty at rtol {tight[-1]['rtol']:.0e}. No single "
            "penalty serves both kinds of mechanism: a larger penalty raises the "
            "rounding-noise floor of regular chains at tight tolerances (docs/dynamics.md, "
            "\"Choosing the augmented-Lagrangian penalty\", `python -m benchmarks.al_penalty`), "
            "so the default penalty stays and the tighter setting is an option "
            "(tests/analysis/formulations/test_singular_chains.py follows chains of 1, 3 and 5 "
            "windows).")
    if failed:
        times = [float(r["message"].split(" at t = ")[1].split(" s")[0]) for r in failed
                 if " at t = " in r["message"]]
        jumped = [r for r in failed if r.get("partial", {}).get("branch", 0.0) > 1e-3]
        kept = [r for r in failed if "partial" in r]
        text = ("* `kkt_ode` and `index1`, which solve with the full C_q (Schur complement, "
                "index-1 Jacobian), fail at the singular passes"
                + (f" (between t = {min(times):.4g} and {max(times):.4g} s; the first pass is "
                   f"at {ref['pass_times'][0]:.4f} s)" if times else "")
                + "; the error names the failure time and the conditioning of C_q there")
        if kept and not jumped:
            text += (", and the outputs kept up to it stay on the branch (bars within "
                     f"{max(r['partial']['branch'] for r in kept):.1e} rad)")
        if jumped:
            r = jumped[0]
            text += (f". The outputs kept after {r['config']} at rtol {r['rtol']:.0e} failed "
                     f"leave the branch: its bars end {r['partial']['branch']:.1f} rad apart")
        out.append(text + ".")
    if astray:
        out.append(
            "* Not every run through a singular pose fails: "
            + "; ".join(f"{r['config']} at rtol {r['rtol']:.0e} ran to 20 s and left the "
                        f"branch (bars {r['branch']:.1f} rad apart, B0 off by "
                        f"{r['b0_error']:.1f} m, {r['near_singular']} passes reported)"
                        for r in astray)
            + ". Nothing but the branch check (or the reported passes) tells that result "
            "from a right one.")
    if survey["evaluated_by_result"] < STEPS + 1:
        text = (f"* Singular-pass monitor: for N = {N_BENCH} the result evaluates the "
                f"conditioning on {survey['evaluated_by_result']} evenly spaced steps only (a "
                "flop budget for large models), takes the local minima among them and "
                "locates each between output times (Hermite interpolation of q, bounded "
                f"minimisation). In the absolute-coordinate run of the survey it reports "
                f"{survey['reported']} of the {survey['minima']} minima found at every step")
        text += (" — all of them." if survey["reported"] == survey["minima"] else
                 (": two passes closer than the evaluated spacing merge into one minimum, "
                  "so passes are counted here from the closed form."
                  if survey["reported"] < survey["minima"] else "."))
        out.append(text)
    return out


def update_docs(section: str, path: Path = DOC) -> Path:
    """Replace this section of docs/hard_cases.md; other sections are kept as they are."""
    return update_hard_cases(HEAD, section, path)


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS, slow=10.0)
    parser.add_argument("--n", type=int, default=N_BENCH)
    args = parser.parse_args(argv)
    if args.render:
        data = json.loads(RESULTS.read_text(encoding="utf-8"))
        section = markdown(data["rows"], data["reference"], data["survey"], data["command"])
        print(f"wrote {update_docs(section)}")
        return 0
    command = ("python -m benchmarks.n_four_bar " + " ".join(
        argv if argv is not None else sys.argv[1:])).strip()
    ref = reference_checks(args.n)
    print(f"closed form vs ODE {ref['ode_vs_closed_form']:.1e}, vs published "
          f"{ref['closed_form_vs_published']:.1e}, {ref['passes']} singular passes", flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        os.environ["CASMBD_CACHE_DIR"] = cache
        survey = conditioning_survey(args.n)
        for config in CONFIGS:
            rows += measure(config, args.n, args.repeat, args.slow)
    RESULTS.write_text(json.dumps({"rows": rows, "reference": ref, "survey": survey,
                                   "command": command}, indent=1), encoding="utf-8")
    if args.update_docs:
        print(f"wrote {update_docs(markdown(rows, ref, survey, command))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
