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

**Closed form on the branch** (derived here; no casmbd involved).  On the parallelogram branch
all bars share one angle θ (from +x, counter-clockwise) and the couplers translate, each point
moving like a bar tip.  With J_bar = m L²/3 about the pivot::

    T = ½ [ (N+1) m L²/3 + N m L² ] θ̇²,     V = m g L [ (N+1)/2 + N ] sin θ,

so, for α = θ + π/2 (measured from hanging down)::

    α̈ = −k sin α,   k = 3 g (3N + 1) / (2 L (4N + 1)),

a simple pendulum.  Its energy E = ½ α̇² − k cos α exceeds k (it circulates), and with β = α/2::

    β̇² = ω² (1 − m sin² β),   ω² = (E + k)/2,   m = 2k / (E + k) < 1,
    β(t) = am(K(m) − ω t | m)            (α(0) = π, α̇(0) = −v_B0 / L),

with the Jacobi amplitude am (``scipy.special.ellipj``'s ``ph``) and K the complete elliptic
integral of the first kind.  :func:`one_dof_reference` integrates the one-DOF equation with
SciPy (DOP853, rtol = atol = 1e-12, an independent check of the closed form) and
:func:`closed_form_angle` evaluates the elliptic solution.

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
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk

from benchmarks.docs import study_parser, update_hard_cases
from casmbd.model import Mechanism

__all__ = ["b0_position", "bar_angles", "bar_name", "closed_form_angle", "coupler_angles",
           "coupler_name", "n_four_bar", "one_dof_rate", "one_dof_reference", "scene_text",
           "singular_pass_times"]

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "hard_cases.md"
RESULTS = ROOT / "benchmarks" / "results" / "n_four_bar.json"
HEAD = "## N four-bar chain (IFToMM)"
N_BENCH = 40
T_END = 20.0
STEPS = 400
G = 9.81

#: B0 (x, y) [m] of the benchmark's reference solution at whole seconds (A02_solution_data.txt,
#: an ADAMS/Solver 2003 run by the problem's authors printed to 6 significant digits every
#: 0.05 s; read from the copy in github.com/mikevignos/simEngine3D-Vignos,
#: testExamples/N-4barMechanism)
PUBLISHED_B0 = {
    1.0: (-1.15357e-01, -9.93324e-01),
    2.0: (3.44663e-02, 9.99406e-01),
    3.0: (-3.38518e-01, -9.40960e-01),
    4.0: (6.93421e-02, 9.97593e-01),
    5.0: (-5.40191e-01, -8.41543e-01),
    6.0: (1.05037e-01, 9.94468e-01),
    7.0: (-7.09615e-01, -7.04590e-01),
    8.0: (1.41958e-01, 9.89873e-01),
    9.0: (-8.40387e-01, -5.41987e-01),
    10.0: (1.80513e-01, 9.83573e-01),
    11.0: (-9.30615e-01, -3.65999e-01),
    12.0: (2.21098e-01, 9.75252e-01),
    13.0: (-9.82240e-01, -1.87630e-01),
    14.0: (2.64098e-01, 9.64496e-01),
    15.0: (-9.99878e-01, -1.56064e-02),
    16.0: (3.09869e-01, 9.50779e-01),
    17.0: (-9.89581e-01, 1.43979e-01),
    18.0: (3.58724e-01, 9.33444e-01),
    19.0: (-9.57773e-01, 2.87527e-01),
    20.0: (4.10902e-01, 9.11679e-01),
}


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


# ---------------------------------------------------------------------- one-DOF reference
def one_dof_rate(n: int, length: float = 1.0, gravity: float = G) -> float:
    """k of α̈ = −k sin α on the parallelogram branch: 3 g (3n + 1) / (2 L (4n + 1)) [1/s²].

    From T = ½ [(n+1) m L²/3 + n m L²] θ̇² and V = m g L [(n+1)/2 + n] sin θ (the bars turn
    about their pivots, the couplers translate with the bar tips); the mass cancels.
    """
    return 3.0 * gravity * (3 * n + 1) / (2.0 * length * (4 * n + 1))


def closed_form_angle(t, n: int, length: float = 1.0, gravity: float = G,
                      speed: float = 1.0) -> np.ndarray:
    """Bar angle θ(t) (from +x, counter-clockwise, unwrapped) by Jacobi elliptic functions.

    θ = 2 β − π/2 with β(t) = am(K(m) − ω t | m), ω² = (E + k)/2, m = 2k/(E + k),
    E = ½ (speed/L)² + k (the energy per unit J of α̈ = −k sin α at α = π).  The argument is
    reduced modulo 2K (am(u + 2K) = am(u) + π) so that long times keep full accuracy.

    Raises
    ------
    ValueError
        When the energy does not make the chain circulate (E ≤ k, m ≥ 1).
    """
    k = one_dof_rate(n, length, gravity)
    energy = 0.5 * (speed / length) ** 2 + k
    m = 2.0 * k / (energy + k)
    if not m < 1.0:
        raise ValueError("closed_form_angle: the chain does not circulate (m >= 1)")
    w = math.sqrt(0.5 * (energy + k))
    kk = float(ellipk(m))
    u = kk - w * np.asarray(t, dtype=float)
    turns = np.floor(u / (2.0 * kk))
    ph = ellipj(u - 2.0 * kk * turns, m)[3]
    return 2.0 * (ph + math.pi * turns) - 0.5 * math.pi


def one_dof_reference(t, n: int, length: float = 1.0, gravity: float = G,
                      speed: float = 1.0, rtol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """θ(t), θ̇(t) of α̈ = −k sin α integrated by SciPy (DOP853, rtol = atol = ``rtol``).

    Initial state θ(0) = π/2 (bars upright), θ̇(0) = −speed / L.
    """
    k = one_dof_rate(n, length, gravity)
    t = np.asarray(t, dtype=float)
    sol = solve_ivp(lambda _t, y: (y[1], -k * math.cos(y[0])), (0.0, float(t[-1])),
                    (0.5 * math.pi, -speed / length), method="DOP853", t_eval=t, rtol=rtol,
                    atol=rtol)
    return sol.y[0], sol.y[1]


def b0_position(theta, length: float = 1.0) -> np.ndarray:
    """B0 = L (cos θ, sin θ), shape (n_t, 2)."""
    theta = np.asarray(theta, dtype=float)
    return length * np.column_stack([np.cos(theta), np.sin(theta)])


def bar_angles(result, n: int) -> np.ndarray:
    """Unwrapped absolute angles of bar0 … bar{n} from a casmbd result, shape (n_t, n + 1)."""
    names = result.names["coordinates"]
    cols = [names.index(f"{bar_name(i)}.angle") for i in range(n + 1)]
    return np.unwrap(result["q"][:, cols], axis=0)


def coupler_angles(result, n: int) -> np.ndarray:
    """Absolute angles of coupler1 … coupler{n}, shape (n_t, n)."""
    names = result.names["coordinates"]
    cols = [names.index(f"{coupler_name(i)}.angle") for i in range(1, n + 1)]
    return result["q"][:, cols]


# ---------------------------------------------------------------------- benchmark
#: (label, formulation, formulation options (penalty given as a multiple of the default),
#: integrator, rtols, max_steps per output interval)
CONFIGS = (
    ("default (augmented_lagrangian / adams)", None, None, None,
     (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12), None),
    ("augmented_lagrangian, penalty ×100, 8 iterations", "augmented_lagrangian",
     {"penalty_factor": 100.0, "iterations": 8}, None,
     (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12), None),
    ("kkt_ode / adams", "kkt_ode", None, None, (1e-8, 1e-10), 50_000),
    ("index1 / idas", "index1", None, None, (1e-8, 1e-10), 50_000),
)
#: the benchmark's accuracy classes for B0 (maximum error over the 400 output steps)
HIGH, LOW = 1e-3, 1e-1


def singular_pass_times(n: int, t_end: float = T_END, length: float = 1.0,
                        gravity: float = G, speed: float = 1.0) -> np.ndarray:
    """Times where the bars are horizontal (cos θ = ±1, θ ≡ 0 mod π) on the closed form."""
    from scipy.optimize import brentq

    grid = np.linspace(0.0, t_end, 20001)
    theta = closed_form_angle(grid, n, length, gravity, speed)
    s = np.sin(theta)
    out = []
    for k in np.flatnonzero(np.sign(s[:-1]) * np.sign(s[1:]) < 0):
        out.append(brentq(lambda t: math.sin(float(closed_form_angle(t, n, length, gravity,
                                                                        speed))),
                          grid[k], grid[k + 1], xtol=1e-13))
    return np.array(out)


def _published_error(t: np.ndarray, b0: np.ndarray) -> float:
    """Largest |B0 − published| (x or y) at the whole seconds of :data:`PUBLISHED_B0`."""
    worst = 0.0
    for tt, xy in PUBLISHED_B0.items():
        k = int(np.argmin(np.abs(t - tt)))
        if abs(t[k] - tt) < 1e-9:
            worst = max(worst, float(np.max(np.abs(b0[k] - np.asarray(xy)))))
    return worst


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
        "published_error": _published_error(result.t, b0),
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
    from casmbd.analysis.simulate import Simulator
    from casmbd.errors import CasmbdError, IntegratorError

    label, formulation, options, integrator, rtols, max_steps = config
    mech = n_four_bar(n)
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
                   integrator=res.stats["integrator"], **evaluate(res, n))
        rows.append(row)
        print(f"{label:50s} rtol {rtol:.0e}  B0 err {row['b0_error']:.2e}  θ err "
              f"{row['theta_error_end']:.2e}  branch {row['branch']:.1e}  steps "
              f"{row['steps']:7d}  {1e3 * row['solve_seconds']:8.1f} ms", flush=True)
    return rows


def conditioning_survey(n: int = N_BENCH, rtol: float = 1e-10) -> dict:
    """σ_r/σ_1 of the equilibrated C_q at *every* output step of a default run (casmbd's
    result evaluates a subset for large models) and its local minima."""
    from casmbd.analysis.redundancy import equilibrated_singular_values
    from casmbd.analysis.simulate import Simulator

    sim = Simulator(n_four_bar(n))
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


def reference_checks(n: int = N_BENCH) -> dict:
    """The closed form against SciPy's one-DOF integration and the published history."""
    t = np.linspace(0.0, T_END, STEPS + 1)
    theta_cf = closed_form_angle(t, n)
    theta_ode, _ = one_dof_reference(t, n)
    published = _published_error(t, b0_position(theta_cf))
    passes = singular_pass_times(n)
    k = one_dof_rate(n)
    energy = 0.5 + k
    return {"ode_vs_closed_form": float(np.max(np.abs(theta_ode - theta_cf))),
            "closed_form_vs_published": published, "passes": len(passes),
            "pass_times": [float(x) for x in passes], "k": k,
            "modulus": 2 * k / (energy + k),
            "period": 2 * float(ellipk(2 * k / (energy + k))) / math.sqrt(0.5 * (energy + k)),
            "b0_end": [float(v) for v in b0_position(theta_cf[-1:])[0]],
            "theta_end": float(theta_cf[-1])}


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
        "**Closed form on the parallelogram branch** (derived in `benchmarks/n_four_bar.py`). "
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
        f"at every one of the 401 output steps of a default run, σ_r/σ_1 of the equilibrated "
        f"C_q has {survey['minima']} local minima ({survey['minima_range'][0]:.1e} to "
        f"{survey['minima_range'][1]:.1e} on the 0.05 s grid, against ≤ "
        f"{survey['regular_max']:.3f} elsewhere). casmbd's result evaluates only "
        f"{survey['evaluated_by_result']} of the 401 steps for a model of this size and "
        f"reports {survey['reported']} `near_singular_times` (see findings).", "",
        f"Measured on {machine()}.", "",
        f"Command: `{command}`", "",
        "Columns: *B0 err* — max over the 401 outputs of |B0 − closed form| (x or y), with "
        "the benchmark's class (high < 1e-3 m, low < 1e-1 m); *θ(20) err* — bar0 angle at "
        "20 s against the closed form; *pub.* — max |B0 − published| at the whole seconds; "
        "*branch* — max over time of max_i |θ_i − θ_0| (all bars parallel) and *coupler* — "
        "max |coupler angle| (they translate); *ΔE* — max |E − E(0)| with E(0) = "
        f"{e0:.6f} J; solve time: integration alone, median of the repeats († a single run); "
        "atol = rtol.", ""]
    for label, *_ in CONFIGS:
        mine = [r for r in rows if r["config"] == label]
        if not mine:
            continue
        opts = next((r["options"] for r in mine if r.get("options")), {})
        extra = (f" — penalty {opts['penalty']:.3g}, {int(opts['iterations'])} iterations, "
                 f"Baumgarte α = β = {opts['alpha']:g}") if "penalty" in opts else ""
        lines += [f"**{label}**{extra}", "",
                  "| rtol | B0 err [m] | class | θ(20) err [rad] | pub. [m] | branch [rad] | "
                  "coupler [rad] | ΔE [J] | max ‖C‖ | steps | solve [ms] |",
                  "| ---: | ---: | :---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
                  "---: |"]
        for r in mine:
            if r["status"] != "ok":
                lines.append(f"| {r['rtol']:.0e} | failed: {r['message']} | | | | | | | | | |")
                continue
            mark = "" if r["repeats"] > 1 else " †"
            lines.append(
                f"| {r['rtol']:.0e} | {_fmt(r['b0_error'])} | {_cls(r['b0_error'])} | "
                f"{_fmt(r['theta_error_end'])} | {_fmt(r['published_error'])} | "
                f"{_fmt(r['branch'])} | {_fmt(r['coupler'])} | {_fmt(r['energy_drift'])} | "
                f"{_fmt(r['violation'])} | {r['steps']} | "
                f"{1e3 * r['solve_seconds']:.1f}{mark} |")
        lines.append("")
    lines += [*findings(rows, ref, survey), ""]
    return "\n".join(lines) + "\n"


def findings(rows: list[dict], ref: dict, survey: dict) -> list[str]:
    """What the tables say, with the numbers taken from them."""
    def of(k: int) -> list[dict]:
        return [r for r in rows if r["config"] == CONFIGS[k][0]]

    default = [r for r in of(0) if r["status"] == "ok"]
    tuned = [r for r in of(1) if r["status"] == "ok"]
    failed = [r for r in of(2) + of(3) if r["status"] != "ok"]
    out = ["**Findings.**", ""]
    tight = [r for r in default if r["rtol"] <= 1e-8]
    if default and tight:
        high = [r for r in default if r["b0_error"] < HIGH]
        cheapest = min(high, key=lambda r: r["solve_seconds"]) if high else None
        loose = max(default, key=lambda r: r["rtol"])
        out.append(
            f"* The default formulation passes all {ref['passes']} singular poses on the "
            f"parallelogram branch at every tolerance: for rtol ≤ 1e-8 the bars stay parallel "
            f"to {max(r['branch'] for r in tight):.1e} rad and the couplers level to "
            f"{max(r['coupler'] for r in tight):.1e} rad ({loose['branch']:.1e} and "
            f"{loose['coupler']:.1e} rad at rtol {loose['rtol']:.0e}; on the other branch "
            "these are O(1)). "
            + (f"It meets the benchmark's high-precision class (B0 within 1e-3 m at all 400 "
               f"steps) from rtol {max(r['rtol'] for r in high):.0e}; the cheapest such run "
               f"took {1e3 * cheapest['solve_seconds']:.0f} ms (rtol {cheapest['rtol']:.0e}). "
               if cheapest else "")
            + "But its error does not fall below "
            f"{min(r['b0_error'] for r in tight):.1e} m (B0) and "
            f"{min(r['energy_drift'] for r in tight):.1e} J (energy) however tight rtol is "
            f"(rtol 1e-8 … {min(r['rtol'] for r in tight):.0e}): the error is made at the "
            "singular passes, not by the integrator.")
    if tuned:
        best = min(tuned, key=lambda r: r["b0_error"])
        tuned_tight = [r for r in tuned if r["rtol"] <= 1e-8] or tuned
        out.append(
            "* Why: the augmented-Lagrangian iteration (four iterations, penalty 1e5 × "
            "mass/Jacobian scale) converges on a constraint direction at the rate "
            "1/(1 + penalty σ²/m); near a singular pose the σ of the N vanishing directions "
            "goes to zero and, for chains of two or more windows, these directions carry "
            "load, so the constraint forces there are left unconverged, the Baumgarte terms "
            "pull the drift back and the energy drops at every pass. With the penalty ×100 "
            f"and 8 iterations the same formulation reaches B0 error {best['b0_error']:.1e} m "
            f"and ΔE {best['energy_drift']:.1e} J (rtol {best['rtol']:.0e}) and keeps the bars "
            f"parallel to {max(r['branch'] for r in tuned_tight):.1e} rad for rtol ≤ 1e-8, "
            f"at {tuned_tight[-1]['solve_seconds'] / tight[-1]['solve_seconds']:.1f}× the "
            f"solve time of the default at rtol {tight[-1]['rtol']:.0e}. No single default serves "
            "both kinds of mechanism: a larger penalty raises the rounding-noise floor of "
            "regular chains at tight tolerances (docs/dynamics.md, \"Choosing the "
            "augmented-Lagrangian penalty\", `python -m benchmarks.al_penalty`), so the "
            "default stays and the tighter setting is an option. (A single "
            "parallelogram does not show the effect: with the default formulation the "
            "N = 1 chain's crank angle is within 6.4e-8 rad of the closed form after 4 s, "
            "N = 3 and 5 are off by 1.7e-5 rad; tests/test_singular_chains.py.)")
    if failed:
        times = [float(r["message"].split(" at t = ")[1].split(" s")[0]) for r in failed
                 if " at t = " in r["message"]]
        jumped = [r for r in failed if r.get("partial", {}).get("branch", 0.0) > 1e-3]
        text = (f"* `kkt_ode` and `index1`, which solve with the full C_q (Schur complement, "
                f"index-1 Jacobian), fail at the singular passes (between t = {min(times):.4g} "
                f"and {max(times):.4g} s; the first pass is at {ref['pass_times'][0]:.4f} s). "
                "casmbd then read no failure time and reported the last output time and the "
                "conditioning there (fixed since: SUNDIALS' own \"At t = …\" is captured and "
                "the outputs are kept from the failed run itself, cut before that time)")
        if jumped:
            r = jumped[0]
            text += (f". Worse, after {r['config']} at rtol {r['rtol']:.0e} failed, the "
                     "interval-by-interval re-run that keeps the outputs went on past the "
                     f"pose and left the branch: its bars end {r['partial']['branch']:.1f} rad "
                     "apart (the re-run that keeps the outputs is now the failed grid run, "
                     "which stops before the failure)")
        out.append(text + ".")
    if survey["evaluated_by_result"] < STEPS + 1:
        out.append(
            f"* `near_singular_times` reported {survey['reported']} passes for N = {N_BENCH}: "
            f"the result evaluates the conditioning on {survey['evaluated_by_result']} evenly "
            "spaced steps only (a flop budget for large models) and looks for minima whose "
            "grid neighbours are both evaluated, so none qualify; evaluated everywhere, the "
            f"{survey['minima']} minima are there (above). Passes are counted here from the "
            "closed form.")
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
