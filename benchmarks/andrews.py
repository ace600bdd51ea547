"""Andrews' squeezing mechanism: speed against error at t = 0.03 s.

``examples/andrews.toml`` (seven bodies in absolute coordinates — the scene pins them —, ten
revolute joints, the spring c0 = 4530 N/m, the drive torque mom = 0.033 N m) is integrated to
t = 0.03 s at a ladder of tolerances with

* the scene's defaults: no formulation or integrator named (``augmented_lagrangian``; the
  stiffness check keeps CVODES-Adams); the label says what was used (``res.stats``),
* ``augmented_lagrangian`` with CVODES-BDF (is the problem stiff for Adams?),
* ``kkt_ode`` with CVODES-Adams,
* ``index1`` with IDAS,
* and the default path without the scene's ``coordinates`` line (``coordinates = "auto"``:
  joint coordinates, 7 tree angles and 3 loop joints), nothing else chosen,

and every run is compared with two references: the **published** one (Test Set for IVP Solvers,
problem "andrews": PSIDE at rtol = atol = 1e-14) and an **independent** one computed here from
the published seven-angle equations (Hairer & Wanner VII.7, test-set ``andrews.f``) in 80-bit
long double by classical RK4 with Richardson extrapolation (:func:`long_double_reference`;
``--recompute-reference`` reruns it, about 2 minutes).  The table gives the largest error of the
seven angles, integrator steps, the solve time (median of ``--repeat`` runs) and the largest
constraint violation.  The wall time of a default run (``steps = 100`` output intervals, default
rtol 1e-8) is reported with and without building the
:class:`~casmbd.analysis.dynamics.simulate.Simulator`
(from the compile cache, and from an empty cache).

Run ``python -m benchmarks.andrews --update-docs`` (writes the section "## Andrews' squeezing
mechanism" of docs/hard_cases.md, replacing only that section, and the measurements to
benchmarks/results/andrews.json; ``--render`` rewrites the section from that file).
"""

from __future__ import annotations

import itertools
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.docs import (
    against_fastest,
    coordinate_reason,
    heading,
    study_parser,
    update_hard_cases,
    used,
)

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "examples" / "andrews.toml"
DOC = ROOT / "docs" / "hard_cases.md"
RESULTS = ROOT / "benchmarks" / "results" / "andrews.json"
HEAD = "## Andrews' squeezing mechanism"
T_END = 0.03
RTOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14)
#: (label, coordinates, formulation, integrator); coordinates None: the scene's (absolute),
#: "auto": casmbd chooses; formulation and integrator None: the defaults (the label of the
#: table says what they were)
SCENE_DEFAULTS = "absolute (the scene's), default formulation and integrator"
AUTO = "automatic coordinates, default formulation and integrator"
CONFIGS = (
    (SCENE_DEFAULTS, None, None, None),
    ("absolute, augmented_lagrangian / cvodes (BDF)", None, "augmented_lagrangian", "cvodes"),
    ("absolute, kkt_ode / adams", None, "kkt_ode", "adams"),
    ("absolute, index1 / idas", None, "index1", "idas"),
    (AUTO, "auto", None, None),
)
#: variants of the default formulation at the tightest tolerances: (label, options; the
#: penalty as a factor of the default one)
AL_VARIANTS = (("default options", {}), ("8 iterations", {"iterations": 8}),
               ("16 iterations", {"iterations": 16}), ("penalty × 0.1", {"penalty": 0.1}),
               ("penalty × 10", {"penalty": 10.0}))
AL_RTOLS = (1e-12, 1e-13, 1e-14)
BODIES = [f"body{k}" for k in range(1, 8)]
ANGLE_NAMES = ("β", "Θ", "γ", "Φ", "δ", "Ω", "ε")

#: published initial angles (β, Θ, γ, Φ, δ, Ω, ε), test set andrews.f (30 digits)
Q0_TEXT = ("-0.0617138900142764496358948458001", "0", "0.455279819163070380255912382449",
           "0.222668390165885884674473185609", "0.487364979543842550225598953530",
           "-0.222668390165885884674473185609", "1.23054744454982119249735015568")
#: published reference at t = 0.03 (test set andrews.f, subroutine SOLN: PSIDE, rtol = atol =
#: 1e-14, Cray C90 double precision)
Q_REF = np.array([0.1581077119629904e+2, -0.1575637105984298e+2, 0.4082224013073101e-1,
                  -0.5347301163226948e+0, 0.5244099658805304e+0, 0.5347301163226948e+0,
                  0.1048080741042263e+1])
#: independent reference: :func:`long_double_reference`, RK4 on 8000 and 16000 steps,
#: extrapolated (``--recompute-reference``); 4000/8000 steps extrapolate to values 8e-13 away,
#: 16000/32000 (a separate run) to values 2e-14 away
Q_LD = np.array([15.81077119515372763, -15.756371058411865772, 0.0408222401196461018,
                 -0.5347301163420790809, 0.5244099658799540384, 0.5347301163420790813,
                 1.0480807410419380374])
#: published data (test set andrews.f / Hairer & Wanner VII.7), as decimal strings
DATA = dict(
    m1=".04325", m2=".00365", m3=".02373", m4=".00706", m5=".07050", m6=".00706", m7=".05498",
    i1="2.194e-6", i2="4.410e-7", i3="5.255e-6", i4="5.667e-7", i5="1.169e-5", i6="5.667e-7",
    i7="1.912e-5", xa="-.06934", ya="-.00227", xb="-.03635", yb=".03273", xc=".014", yc=".072",
    d="28e-3", da="115e-4", e="2e-2", ea="1421e-5", rr="7e-3", ra="92e-5", ss="35e-3",
    sa="1874e-5", sb="1043e-5", sc="18e-3", sd="2e-2", ta="2308e-5", tb="916e-5", u="4e-2",
    ua="1228e-5", ub="449e-5", zf="2e-2", zt="4e-2", fa="1421e-5", mom="33e-3", c0="4530",
    l0="7785e-5")


def published_angles(res) -> np.ndarray:
    """(n_t, 7) published angles β, Θ, γ, Φ, δ, Ω, ε from the absolute body angles a1..a7:
    β = a1, Θ = a2 − a1, γ = a3, Φ = a4 − a5, δ = a5, Ω = a6 − a7, ε = a7."""
    a = [res.body(b)["angle"] for b in BODIES]
    return np.stack([a[0], a[1] - a[0], a[2], a[3] - a[4], a[4], a[5] - a[6], a[6]], axis=-1)


# ---------------------------------------------------------------- independent reference
def _published_rhs(dtype):
    """Right-hand side y' = (v, q̈) of the published equations (Hairer & Wanner VII.7, eq. 7.11;
    test set andrews.f): M(q) q̈ = f(q, v) − Gᵀλ, G q̈ = γ − 2α G v − α² g with Baumgarte
    α = 20 (the exact solution is unchanged), solved by Gaussian elimination in ``dtype``."""
    p = {k: dtype(v) for k, v in DATA.items()}
    m1, m2, m3, m4, m5, m6, m7 = (p[f"m{k}"] for k in range(1, 8))
    i1, i2, i3, i4, i5, i6, i7 = (p[f"i{k}"] for k in range(1, 8))
    rr, ra, d, da, e, ea = p["rr"], p["ra"], p["d"], p["da"], p["e"], p["ea"]
    ss, sa, sb, sc, sd = p["ss"], p["sa"], p["sb"], p["sc"], p["sd"]
    ta, tb, u, ua, ub, zf, zt, fa = (p[k] for k in ("ta", "tb", "u", "ua", "ub", "zf", "zt",
                                                    "fa"))
    alpha = dtype(20)

    def combo(*idx):
        out = np.zeros(7, dtype=dtype)
        out[list(idx)] = 1
        return out

    # g: sums of a·cos(φ) or a·sin(φ), φ a sum of angles (0 β, 1 Θ, 2 γ, 3 Φ, 4 δ, 5 Ω, 6 ε)
    terms = []
    for row in (0, 2, 4):
        terms += [(row, rr, np.cos, combo(0)), (row, -d, np.cos, combo(0, 1)),
                  (row + 1, rr, np.sin, combo(0)), (row + 1, -d, np.sin, combo(0, 1))]
    terms += [(0, -ss, np.sin, combo(2)), (1, ss, np.cos, combo(2)),
              (2, -e, np.sin, combo(3, 4)), (2, -zt, np.cos, combo(4)),
              (3, e, np.cos, combo(3, 4)), (3, -zt, np.sin, combo(4)),
              (4, -zf, np.cos, combo(5, 6)), (4, -u, np.sin, combo(6)),
              (5, -zf, np.sin, combo(5, 6)), (5, u, np.cos, combo(6))]
    g_const = np.array([-p["xb"], -p["yb"], -p["xa"], -p["ya"], -p["xa"], -p["ya"]])

    def rhs(y):
        q, v = y[:7], y[7:]
        s, c = np.sin(q), np.cos(q)
        mm = np.zeros((7, 7), dtype=dtype)
        mm[0, 0] = m1 * ra**2 + m2 * (rr**2 - 2 * da * rr * c[1] + da**2) + i1 + i2
        mm[1, 0] = mm[0, 1] = m2 * (da**2 - da * rr * c[1]) + i2
        mm[1, 1] = m2 * da**2 + i2
        mm[2, 2] = m3 * (sa**2 + sb**2) + i3
        mm[3, 3] = m4 * (e - ea) ** 2 + i4
        mm[4, 3] = mm[3, 4] = m4 * ((e - ea) ** 2 + zt * (e - ea) * s[3]) + i4
        mm[4, 4] = (m4 * (zt**2 + 2 * zt * (e - ea) * s[3] + (e - ea) ** 2)
                    + m5 * (ta**2 + tb**2) + i4 + i5)
        mm[5, 5] = m6 * (zf - fa) ** 2 + i6
        mm[6, 5] = mm[5, 6] = m6 * ((zf - fa) ** 2 - u * (zf - fa) * s[5]) + i6
        mm[6, 6] = (m6 * ((zf - fa) ** 2 - 2 * u * (zf - fa) * s[5] + u**2)
                    + m7 * (ua**2 + ub**2) + i6 + i7)
        xd = sd * c[2] + sc * s[2] + p["xb"]
        yd = sd * s[2] - sc * c[2] + p["yb"]
        length = np.sqrt((xd - p["xc"]) ** 2 + (yd - p["yc"]) ** 2)
        force = -p["c0"] * (length - p["l0"]) / length
        fx, fy = force * (xd - p["xc"]), force * (yd - p["yc"])
        f = np.array([
            p["mom"] - m2 * da * rr * v[1] * (v[1] + 2 * v[0]) * s[1],
            m2 * da * rr * v[0] ** 2 * s[1],
            fx * (sc * c[2] - sd * s[2]) + fy * (sd * c[2] + sc * s[2]),
            m4 * zt * (e - ea) * v[4] ** 2 * c[3],
            -m4 * zt * (e - ea) * v[3] * (v[3] + 2 * v[4]) * c[3],
            -m6 * u * (zf - fa) * v[6] ** 2 * c[5],
            m6 * u * (zf - fa) * v[5] * (v[5] + 2 * v[6]) * c[5]], dtype=dtype)
        g, jac, gam = g_const.copy(), np.zeros((6, 7), dtype=dtype), np.zeros(6, dtype=dtype)
        for row, a, trig, cmb in terms:
            phi, rate = cmb @ q, cmb @ v
            val = a * trig(phi)
            der = -a * np.sin(phi) if trig is np.cos else a * np.cos(phi)
            g[row] += val
            jac[row] += der * cmb
            gam[row] += val * rate * rate          # γ = −(d/dt G) v: −(a trig φ)'' + G q̈
        kkt = np.zeros((13, 13), dtype=dtype)
        kkt[:7, :7], kkt[:7, 7:], kkt[7:, :7] = mm, jac.T, jac
        b = np.concatenate([f, gam - 2 * alpha * (jac @ v) - alpha**2 * g])
        for k in range(13):                        # Gaussian elimination, partial pivoting
            piv = k + int(np.argmax(np.abs(kkt[k:, k])))
            kkt[[k, piv]], b[[k, piv]] = kkt[[piv, k]], b[[piv, k]]
            fac = kkt[k + 1:, k] / kkt[k, k]
            kkt[k + 1:, k:] -= np.outer(fac, kkt[k, k:])
            b[k + 1:] -= fac * b[k]
        x = np.zeros(13, dtype=dtype)
        for k in range(12, -1, -1):
            x[k] = (b[k] - kkt[k, k + 1:] @ x[k + 1:]) / kkt[k, k]
        return np.concatenate([v, x[:7]])

    return rhs


def rk4_published(steps: int, dtype=np.longdouble) -> np.ndarray:
    """The seven angles at t = 0.03 by classical RK4 with ``steps`` equal steps."""
    rhs = _published_rhs(dtype)
    h = dtype("0.03") / steps
    y = np.zeros(14, dtype=dtype)
    y[:7] = [dtype(x) for x in Q0_TEXT]
    for _ in range(steps):
        k1 = rhs(y)
        k2 = rhs(y + h / 2 * k1)
        k3 = rhs(y + h / 2 * k2)
        k4 = rhs(y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y[:7]


def long_double_reference(steps=(4000, 8000, 16000),
                          dtype=np.longdouble) -> tuple[np.ndarray, float]:
    """Independent reference: the published equations in 80-bit long double (or ``dtype``),
    RK4 on ``steps`` (each twice the previous), Richardson-extrapolated (16 y_{2N} − y_N)/15.

    Returns the extrapolation from the two finest grids and the largest difference from the
    extrapolation of the two before (an error estimate)."""
    ys = [rk4_published(n, dtype) for n in steps]
    ext = [(16 * b - a) / 15 for a, b in itertools.pairwise(ys)]
    return ext[-1], float(np.max(np.abs(ext[-1] - ext[-2]))) if len(ext) > 1 else float("nan")


# ---------------------------------------------------------------------------- casmbd runs
def measure(config, repeat: int) -> list[dict]:
    """Every tolerance of one configuration: errors, steps, median solve time, or failure."""
    from casmbd.analysis.dynamics.simulate import Simulator
    from casmbd.errors import CasmbdError, IntegratorError
    from casmbd.io.scene import load_scene

    label, coordinates, formulation, integrator = config
    mech = load_scene(SCENE)
    if coordinates is not None:
        mech.coordinates = coordinates
        mech.name = f"{mech.name}_{coordinates}"
    sim = Simulator(mech, formulation)
    rows = []
    for rtol in RTOLS:
        row = {"config": label, "rtol": rtol, "formulation": sim.formulation_name,
               "coordinates": sim.model.coordinates}
        times = []
        try:
            for _ in range(repeat):
                res = sim.run(T_END, 1, rtol=rtol, integrator=integrator)
                times.append(res.stats["solve_seconds"])
        except CasmbdError as exc:
            message = (f"{exc.flag} at t = {exc.time:.3g} s" if isinstance(exc, IntegratorError)
                       else str(exc).splitlines()[0])
            row.update(status="failed", message=message)
            rows.append(row)
            print(f"{label:42s} rtol {rtol:.0e}  failed: {message}", flush=True)
            continue
        final = published_angles(res)[-1]
        row.update(status="ok", angles=final.tolist(),
                   err_pub=float(np.max(np.abs(final - Q_REF))),
                   err_ld=float(np.max(np.abs(final - Q_LD))),
                   steps=res.stats["steps"], solve_seconds=statistics.median(times),
                   violation=float(np.max(res["constraint_violation"])),
                   integrator=res.stats["integrator"],
                   coordinate_choice=coordinate_reason(res.stats),
                   integrator_choice=res.stats.get("integrator_choice"))
        rows.append(row)
        print(f"{label:42s} rtol {rtol:.0e}  err pub {row['err_pub']:.2e}  ld "
              f"{row['err_ld']:.2e}  steps {row['steps']:6d}  "
              f"{1e3 * row['solve_seconds']:8.2f} ms", flush=True)
    return rows


def al_variants() -> list[dict]:
    """The augmented Lagrangian's floor (the scene's absolute coordinates): more iterations,
    other penalties (one run each)."""
    from casmbd.analysis.dynamics.simulate import Simulator
    from casmbd.io.scene import load_scene

    base = Simulator(load_scene(SCENE)).formulation.options["penalty"]
    rows = []
    for label, options in AL_VARIANTS:
        opts = dict(options)
        if "penalty" in opts:
            opts["penalty"] *= base
        sim = Simulator(load_scene(SCENE), formulation_options=opts)
        for rtol in AL_RTOLS:
            final = published_angles(sim.run(T_END, 1, rtol=rtol))[-1]
            rows.append({"variant": label, "rtol": rtol, "penalty": sim.formulation.options[
                "penalty"], "iterations": sim.formulation.options["iterations"],
                "err_ld": float(np.max(np.abs(final - Q_LD)))})
            print(f"{label:24s} rtol {rtol:.0e}  err ld {rows[-1]['err_ld']:.2e}", flush=True)
    return rows


def default_run_timing(repeat: int) -> dict:
    """Wall time of ``simulate``'s default run of the scene (100 output intervals, rtol 1e-8;
    nothing chosen but the scene's absolute coordinates): the run alone, scene loading +
    Simulator build from the compile cache + run, and the same from an empty cache (code
    generation and C compilation included); medians of ``repeat``."""
    from casmbd.analysis.dynamics.simulate import Simulator
    from casmbd.io.scene import load_scene

    def one(cache: str | None) -> tuple[float, float, float, float, object]:
        if cache is not None:
            os.environ["CASMBD_CACHE_DIR"] = cache
        t0 = time.perf_counter()
        sim = Simulator(load_scene(SCENE))
        t1 = time.perf_counter()
        res = sim.run(T_END, 100)
        t2 = time.perf_counter()
        return t1 - t0, t2 - t1, res.stats["solve_seconds"], res.stats["setup_seconds"], res

    warm = os.environ["CASMBD_CACHE_DIR"]
    one(None)                                        # fill the cache
    hot = [one(None) for _ in range(repeat)]
    cold = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as empty:
            cold.append(one(empty))
    os.environ["CASMBD_CACHE_DIR"] = warm
    res = hot[-1][4]
    return {"run": statistics.median(r[1] for r in hot),
            "solve": statistics.median(r[2] for r in hot),
            "setup": statistics.median(r[3] for r in hot),
            "build_cached": statistics.median(r[0] for r in hot),
            "build_cold": statistics.median(r[0] for r in cold),
            "total_cached": statistics.median(r[0] + r[1] for r in hot),
            "total_cold": statistics.median(r[0] + r[1] for r in cold),
            "steps": res.stats["steps"], "rtol": res.stats["rtol"],
            "coordinates": res.stats["coordinates"], "formulation": res.stats["formulation"],
            "integrator": res.stats["integrator"],
            "err_pub": float(np.max(np.abs(published_angles(res)[-1] - Q_REF))),
            "err_ld": float(np.max(np.abs(published_angles(res)[-1] - Q_LD))),
            "repeat": repeat}


# ---------------------------------------------------------------------------- the section
def _fmt(x: float) -> str:
    return f"{x:.1e}" if x > 0 else "0"


def markdown(rows: list[dict], timing: dict, variants: list[dict], command: str) -> str:
    """The section of docs/hard_cases.md."""
    from benchmarks.work_precision import machine

    kkt_best = min(r["err_ld"] for r in rows if r["config"] == CONFIGS[2][0]
                   and r["status"] == "ok")
    lines = [
        HEAD, "",
        "**Problem.** Seven rigid bodies in the plane, joined by frictionless revolute joints "
        "into a mechanism with one degree of freedom, driven by a constant torque on the "
        "crank and loaded by a stiff spring; no gravity; starts at rest; t ∈ [0, 0.03] s "
        "(the crank turns 2.5 times). E. Hairer, G. Wanner, *Solving Ordinary Differential "
        "Equations II*, 2nd ed., Springer 1996, section VII.7 (after Giles 1978 and Manning "
        "1981); also the IFToMM benchmark problem \"Andrew's mechanism\" (its page was not "
        "reachable from here). "
        "The data and reference values used here are those of the **Test Set for IVP "
        "Solvers** (F. Mazzia, C. Magherini, F. Iavernaro, University of Bari, release 2.3, "
        "2006 — after W. Lioen, J. de Swart, CWI, 1999), problem `andrews`, file "
        "`src/problems/andrews.f` (revision 1.2, 2006; read from copies of the file in public "
        "repositories; the same data are in the R package deTestSet, `ex_andrews`).", "",
        "| quantity | value (SI) |", "| --- | --- |",
        "| masses m1…m7 | 0.04325, 0.00365, 0.02373, 0.00706, 0.07050, 0.00706, 0.05498 |",
        "| inertias i1…i7 | 2.194e-6, 4.410e-7, 5.255e-6, 5.667e-7, 1.169e-5, 5.667e-7, "
        "1.912e-5 |",
        "| fixed points | O = (0, 0), A = (xa, ya) = (−0.06934, −0.00227), B = (xb, yb) = "
        "(−0.03635, 0.03273), C = (xc, yc) = (0.014, 0.072) |",
        "| lengths | rr = 0.007, ra = 0.00092, d = 0.028, da = 0.0115, e = 0.02, ea = 0.01421, "
        "ss = 0.035, sa = 0.01874, sb = 0.01043, sc = 0.018, sd = 0.02, ta = 0.02308, "
        "tb = 0.00916, u = 0.04, ua = 0.01228, ub = 0.00449, zf = 0.02, zt = 0.04, "
        "fa = 0.01421 |",
        "| spring | c0 = 4530 N/m, free length l0 = 0.07785 m, from D on body 3 to C |",
        "| drive | mom = 0.033 N m on body 1 |",
        "| initial angles | β = −0.0617138900142764496358948458001, Θ = 0, "
        "γ = 0.455279819163070380255912382449, Φ = 0.222668390165885884674473185609, "
        "δ = 0.487364979543842550225598953530, Ω = −Φ, "
        "ε = 1.23054744454982119249735015568; all rates zero |", "",
        "| reference at t = 0.03 | " + " | ".join(ANGLE_NAMES) + " |",
        "| --- |" + " ---: |" * 7,
        "| published (PSIDE, rtol = atol = 1e-14) | "
        + " | ".join(f"{x:.16g}" for x in Q_REF) + " |",
        "| independent (long double, below) | "
        + " | ".join(f"{x:.16g}" for x in Q_LD) + " |", "",
        "**Scene.** `examples/andrews.toml`: absolute coordinates (x, y, angle of each centre "
        "of mass), ten revolute joints (O, F, B, A for bodies 5 and 7, H, G, and three at the "
        "common point E: bodies 2–3, 2–4, 2–6), the spring as a `spring_damper` (stiffness "
        "c0, free length l0, no damping), the drive as a constant `torque`. Each body's "
        "initial `angle` is its published absolute angle, so β = a1, Θ = a2 − a1, γ = a3, "
        "Φ = a4 − a5, δ = a5, Ω = a6 − a7, ε = a7 (a_k: the angle of body k). The joint "
        "points follow the published constraint equations g(q) = 0; the centres of mass of "
        "bodies 2, 4, 6 lie where the published mass matrix puts them (da from F, e − ea "
        "from H, zf − fa from G, towards E). The published model fixes only the distances "
        "of the centres of mass of bodies 1, 3, 5, 7 from their fixed pivots (without "
        "gravity only m r² + I enters); the directions in the scene are our choice and do "
        "not change the motion. The published multipliers λ1…λ6 are the forces of body 2 "
        "on bodies 3, 4, 6 at E (joint reactions E23, E24, E26).", "",
        "**Checks** (tests/analysis/dynamics/test_andrews.py): the assembly from a perturbed guess "
        "with β held "
        "returns the published initial angles to 1e-12 rad; the initial accelerations "
        "(β̈ = 14222.44…, Θ̈ = −10666.83…, the rest 0) and multipliers (98.567…, −6.123…) "
        "equal the published ones to 1e-9 relative; at t = 0.03 the angles, angular "
        "velocities and multipliers equal the published reference to 1e-8 rad, 1e-8 and "
        "1e-6 relative; the kinetic plus spring energy grows by the drive's work mom·Δβ to "
        "1e-9 J; the error falls at least 10× per 100× tighter rtol; `kkt_ode` at rtol 1e-13 "
        "equals the independent solution below to 1e-10 rad.", "",
        "**Two references.** Every formulation stops improving at about 1.2–1.4e-9 rad "
        "against the published values, always in β and Θ (≈ 15.8 rad); the other five "
        "angles agree to 2e-11. To see whose error that is, the published seven-angle "
        "equations (M(q) q̈ = f − Gᵀλ, g(q) = 0 with the test set's M, f, G) were integrated "
        "separately from casmbd, in 80-bit long double, by classical RK4"
        " with Richardson extrapolation (`benchmarks/andrews.py`, "
        "`long_double_reference`: 8000 and 16000 steps; 4000/8000 extrapolate to values "
        "8e-13 rad away, 16000/32000 to values 2e-14 rad away; the same computation in "
        "double precision agrees to 1e-12). "
        "This independent solution differs from the published one by "
        f"{np.max(np.abs(Q_LD - Q_REF)):.2e} rad (β by "
        f"{Q_LD[0] - Q_REF[0]:.2e}, Θ by {Q_LD[1] - Q_REF[1]:.2e}), and casmbd's `kkt_ode` "
        f"converges to it ({_fmt(kkt_best)} rad, table below). So, as solutions of the published "
        "equations, the published β and Θ are off by about 1.4e-9 rad (10 significant "
        "digits of the 16 printed); the column *err ind* measures against the independent "
        "solution.", "",
        f"Measured on {machine()}.", "", f"Command: `{command}`", "",
        "*err pub*, *err ind*: largest error of the seven angles at t = 0.03 against the "
        "published and the independent reference; one output interval; solve time: the "
        "integration alone (`stats['solve_seconds']`), median of 3 runs; atol = rtol; "
        "max ‖C‖: largest position-constraint violation. Times of a few milliseconds are "
        "noisy on this shared machine (another benchmark ran at the same time). The scene "
        "pins absolute coordinates (`coordinates = \"absolute\"`: its tests and this study "
        "are written for them); the last configuration drops that line and leaves every "
        "choice to casmbd. Headings of configurations that name nothing say what was used "
        "(`res.stats`).", ""]
    for label, *_ in CONFIGS:
        mine = [r for r in rows if r["config"] == label]
        lines += [f"**{heading(label, rows, label in (SCENE_DEFAULTS, AUTO))}**", "",
                  "| rtol | err pub [rad] | err ind [rad] | steps | solve [ms] | max ‖C‖ [m] |",
                  "| ---: | ---: | ---: | ---: | ---: | ---: |"]
        for r in mine:
            if r["status"] != "ok":
                lines.append(f"| {r['rtol']:.0e} | failed: {r['message']} | | | | |")
                continue
            lines.append(f"| {r['rtol']:.0e} | {_fmt(r['err_pub'])} | {_fmt(r['err_ld'])} | "
                         f"{r['steps']} | {1e3 * r['solve_seconds']:.2f} | "
                         f"{_fmt(r['violation'])} |")
        lines.append("")
    lines += ["Cheapest run within a target error against the independent reference:", "",
              "| configuration | ≤ 1e-4 | ≤ 1e-6 | ≤ 1e-8 | ≤ 1e-10 |",
              "| --- | ---: | ---: | ---: | ---: |"]
    for label, *_ in CONFIGS:
        cells = []
        for target in (1e-4, 1e-6, 1e-8, 1e-10):
            hits = [r for r in rows if r["config"] == label and r["status"] == "ok"
                    and r["err_ld"] <= target]
            best = min(hits, key=lambda r: r["solve_seconds"], default=None)
            cells.append(f"{1e3 * best['solve_seconds']:.2f} ms (rtol {best['rtol']:.0e})"
                         if best else "not reached")
        named = heading(label, rows, label in (SCENE_DEFAULTS, AUTO))
        lines.append(f"| {named} | " + " | ".join(cells) + " |")
    lines += ["", "Variants of the augmented Lagrangian (the scene's absolute coordinates; err "
              "ind [rad], one run each):", "",
              "| variant | penalty | iterations | "
              + " | ".join(f"rtol {r:.0e}" for r in AL_RTOLS) + " |",
              "| --- | ---: | ---: |" + " ---: |" * len(AL_RTOLS)]
    for label, _ in AL_VARIANTS:
        mine = [v for v in variants if v["variant"] == label]
        lines.append(f"| {label} | {mine[0]['penalty']:.4g} | {mine[0]['iterations']:g} | "
                     + " | ".join(_fmt(v["err_ld"]) for v in mine) + " |")
    lines += ["", *findings(rows, timing, variants), ""]
    return "\n".join(lines) + "\n"


def findings(rows: list[dict], timing: dict, variants: list[dict]) -> list[str]:
    """What the tables say, with the numbers taken from them."""
    def of(k: int) -> list[dict]:
        return [r for r in rows if r["config"] == CONFIGS[k][0] and r["status"] == "ok"]

    default, al_bdf, kkt, idx1, auto = (of(k) for k in range(5))
    best = {k: min(rs, key=lambda r: r["err_ld"]) for k, rs in
            (("default", default), ("kkt", kkt), ("index1", idx1))}
    at = {k: {r["rtol"]: r for r in rs} for k, rs in
          (("default", default), ("bdf", al_bdf), ("kkt", kkt), ("index1", idx1))}
    ladder = [at["default"][r] for r in (1e-4, 1e-6, 1e-8, 1e-10)]
    factors = [a["err_pub"] / b["err_pub"] for a, b in itertools.pairwise(ladder)]
    ratios = [at["index1"][r]["steps"] / at["default"][r]["steps"] for r in at["index1"]
              if r in at["default"]]
    failed = [r for r in rows if r["status"] != "ok" and r["config"] == CONFIGS[3][0]]
    floor = [v["err_ld"] for v in variants]
    al = f"The scene's defaults ({used(default[0])})"
    lines = ["**Findings.**", ""]
    lines.append(
        f"* {al}, self-convergence: per 100× tighter rtol (1e-4 → 1e-6 → "
        "1e-8 → 1e-10) the error falls by " + ", ".join(f"{f:.0f}×" for f in factors)
        + f", reaching {_fmt(ladder[-1]['err_pub'])} rad at rtol 1e-10. Its best against the "
        f"independent reference is {_fmt(best['default']['err_ld'])} rad (rtol "
        f"{best['default']['rtol']:.0e}); the variants above (more iterations, other "
        f"penalties) reach {min(floor):.1e}–{max(floor):.1e} rad at rtol 1e-12…1e-14"
        + (" — a floor none of them lowers, consistent with rounding noise of the "
           "ill-conditioned M + α C_qᵀC_q in every right-hand side (docs/performance.md)."
           if best["default"]["err_ld"] > 10 * best["kkt"]["err_ld"] else
           f", as close as `kkt_ode` ({_fmt(best['kkt']['err_ld'])} rad)."))
    text = (f"* `kkt_ode` / Adams converges furthest: {_fmt(best['kkt']['err_ld'])} rad "
            f"against the independent reference at rtol {best['kkt']['rtol']:.0e} "
            f"({best['kkt']['steps']} steps, {1e3 * best['kkt']['solve_seconds']:.1f} ms) — "
            "the casmbd scene and the published equations describe the same motion to that "
            f"level. `index1` / IDAS (BDF) takes {min(ratios):.1f}–{max(ratios):.1f}× the "
            f"steps of the augmented Lagrangian and reaches {_fmt(best['index1']['err_ld'])} "
            "rad")
    if failed:
        tols = ", ".join(f"{r['rtol']:.0e}" for r in failed)
        text += f"; it fails at rtol {tols} ({failed[0]['message']})"
    lines.append(text + ".")
    d8, b8 = at["default"][1e-8], at["bdf"][1e-8]
    lines.append(
        f"* Not stiff for Adams: the spring (c0 = 4530 N/m) does not bound the Adams step; "
        f"at rtol 1e-8 BDF takes {b8['steps']} steps against Adams' {d8['steps']} with the "
        f"same formulation and is {b8['solve_seconds'] / d8['solve_seconds']:.0f}× slower. "
        "(The test set calls the problem non-stiff; its difficulty is the index-3 "
        "constraints and the fast crank, 1140 rad/s at t = 0.03.) The stiffness check of "
        "the default integrator agrees: " + ("it keeps Adams." if d8.get("integrator_choice")
                                             == "default" else
                                             f"\"{d8.get('integrator_choice')}\"."))
    if auto:
        first = auto[0]
        text = (f"* **Without the scene's `coordinates` line** casmbd takes {used(first)} "
                f"({first.get('coordinate_choice')}).")
        for target in (1e-6, 1e-8):
            fast = {c[0]: min((r for r in of(k) if r["err_ld"] <= target), default=None,
                              key=lambda r: r["solve_seconds"]) for k, c in enumerate(CONFIGS)}
            mine, top = fast.pop(AUTO), min((r for r in fast.values() if r), default=None,
                                            key=lambda r: r["solve_seconds"])
            text += against_fastest(mine, top, f"Error ≤ {target:.0e} rad", digits=2)
        best_auto = min(auto, key=lambda r: r["err_ld"])
        text += (f" Its best against the independent reference: {_fmt(best_auto['err_ld'])} rad "
                 f"(rtol {best_auto['rtol']:.0e}).")
        lines.append(text)
    lines.append(
        f"* A default run of the scene (`simulate(load_scene(...), t_end=0.03, steps=100)`, "
        f"rtol {timing['rtol']:.0e}: {timing.get('coordinates', 'absolute')} coordinates, "
        f"{timing.get('formulation', 'augmented_lagrangian')} / "
        f"{timing.get('integrator', 'adams')}; {timing['steps']} steps, error "
        f"{_fmt(timing['err_pub'])} rad) takes {1e3 * timing['run']:.0f} ms of wall time "
        f"without building the Simulator ({1e3 * timing['solve']:.1f} ms of it integration, "
        f"{1e3 * timing['setup']:.0f} ms creating the CVODES integrator, the rest the "
        "consistent start and post-processing at the 101 output times), "
        f"{1e3 * timing['total_cached']:.0f} ms with scene loading and Simulator build from "
        f"the compile cache ({1e3 * timing['build_cached']:.0f} ms of build), and "
        f"{timing['total_cold']:.2f} s from an empty cache (code generation and C "
        f"compilation: {timing['build_cold']:.2f} s of build); medians of {timing['repeat']}.")
    return lines


def update_docs(section: str, path: Path = DOC) -> Path:
    """Replace this section of docs/hard_cases.md; other sections are kept as they are."""
    return update_hard_cases(HEAD, section, path)


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS)
    parser.add_argument("--recompute-reference", action="store_true",
                        help="rerun the long-double reference (RK4 on 4000, 8000, 16000 steps, "
                             "about 2 minutes) and print it")
    args = parser.parse_args(argv)
    if args.recompute_reference:
        t0 = time.perf_counter()
        ref, spread = long_double_reference()
        print("independent reference at t = 0.03 (long double):")
        for name, val, stored in zip(ANGLE_NAMES, ref, Q_LD):
            print(f"  {name} = {np.format_float_positional(val, precision=19)}  "
                  f"(stored: {float(stored - val):+.1e})")
        print(f"two extrapolations differ by {spread:.1e}")
        double, _ = long_double_reference((4000, 8000), np.float64)
        print(f"the same in double precision (4000, 8000 steps) differs by "
              f"{float(np.max(np.abs(double - ref))):.1e}; {time.perf_counter() - t0:.0f} s")
        return 0
    if args.render:
        data = json.loads(RESULTS.read_text(encoding="utf-8"))
        section = markdown(data["rows"], data["timing"], data["variants"], data["command"])
        print(f"wrote {update_docs(section)}")
        return 0
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        os.environ["CASMBD_CACHE_DIR"] = cache
        for config in CONFIGS:
            rows += measure(config, args.repeat)
        variants = al_variants()
        timing = default_run_timing(args.repeat)
    print(f"default run: {1e3 * timing['run']:.1f} ms (build excluded), "
          f"{1e3 * timing['total_cached']:.1f} ms (cached build included), "
          f"{timing['total_cold']:.2f} s (compilation included)")
    command = "python -m benchmarks.andrews " + " ".join(
        argv if argv is not None else sys.argv[1:])
    RESULTS.write_text(json.dumps({"rows": rows, "variants": variants, "timing": timing,
                                   "command": command.strip()}, indent=1), encoding="utf-8")
    if args.update_docs:
        print(f"wrote {update_docs(markdown(rows, timing, variants, command.strip()))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
