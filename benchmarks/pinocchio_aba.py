"""casmbd's compiled articulated-body right-hand side against Pinocchio's ABA, measured in one
run (issue 9 target: per-RHS cost ≤ 2× Pinocchio's ABA).

Models: the pendulum chains of :mod:`benchmarks.chains` (N slender rods of 1 m and 1 kg,
revolute joints, gravity) in joint coordinates, N = 2, 8, 32, twice:

* *planar*: casmbd's planar chain (its recursion carries 3-component planar spatial vectors)
  against a Pinocchio model of the same chain with ``JointModelRZ`` joints (Pinocchio's 6-D
  spatial algebra; it has no planar mode);
* *spatial*: casmbd's chain built in space (:func:`benchmarks.work_precision.chain_in_space`,
  revolute joints about −y, 6-D recursion) against Pinocchio with
  ``JointModelRevoluteUnaligned`` about −y: the same computation in both.

Each pair is first checked to give the same accelerations (casmbd against ``pinocchio.aba`` at
a random state, relative 1e-9), then timed under the fair rules (:mod:`benchmarks.fair`: best
of timeit repeats after a first call): per call, casmbd through its public method
``CompiledModel.forward_dynamics(q, v, tau)`` (``casmbd.compile(mechanism)``, what a user
calls; argument checks and copies included) against ``pinocchio.aba(model, data, q, v, tau)``
through its binding; for the record also casmbd's bare compiled ``articulated`` right-hand
side through ``casadi.Function.buffer()`` (no Python method, parameters bound once — not a
user's path).  Batch: ``CompiledModel.forward_dynamics_batch`` over :data:`N_BATCH` states
against Pinocchio's own batch API ``pinocchio.abaInParallel`` (a ``ModelPool``; one thread,
like casmbd's serial compiled map, and two threads).

Run ``python -m benchmarks.pinocchio_aba --update-docs`` (``pip install .[bench]`` for
``pin``): writes ``benchmarks/results/pinocchio_aba.json`` and the section
``## Right-hand side against Pinocchio's ABA`` of ``docs/performance.md``.
"""

from __future__ import annotations

import datetime
import pathlib
import platform
import sys

import numpy as np

from benchmarks import fair
from benchmarks.bench_equations import buffer_evaluator
from benchmarks.docs import run_study, study_parser
from benchmarks.fair import time_per_call

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "pinocchio_aba.json"
DOC = ROOT / "docs" / "performance.md"
HEAD = "## Right-hand side against Pinocchio's ABA"
SIZES = (2, 8, 32)
#: states per batch call
N_BATCH = 1000


def pinocchio_chain(n: int, spatial: bool, length: float = 1.0, mass: float = 1.0,
                    gravity: float = 9.81):
    """Pinocchio model of the chain: rods along +x, joint i at (i L, 0, 0) of its parent."""
    import pinocchio as pin

    model = pin.Model()
    if spatial:
        model.gravity.linear = np.array([0.0, 0.0, -gravity])
        radius = length / 20.0
        rot = np.diag([mass * radius**2 / 2.0, mass * length**2 / 12.0,
                       mass * length**2 / 12.0])
    else:
        model.gravity.linear = np.array([0.0, -gravity, 0.0])
        rot = np.diag([0.0, mass * length**2 / 12.0, mass * length**2 / 12.0])
    parent = 0
    for i in range(n):
        placement = pin.SE3(np.eye(3), np.array([0.0 if i == 0 else length, 0.0, 0.0]))
        joint = (pin.JointModelRevoluteUnaligned(np.array([0.0, -1.0, 0.0])) if spatial
                 else pin.JointModelRZ())
        parent = model.addJoint(parent, joint, placement, f"pin{i}")
        model.appendBodyToJoint(parent, pin.Inertia(mass, np.array([length / 2, 0.0, 0.0]),
                                                    rot), pin.SE3.Identity())
    return model


def _chain(n: int, spatial: bool):
    from benchmarks.chains import pendulum_chain
    from benchmarks.work_precision import chain_in_space

    mech = chain_in_space(n, "joint") if spatial else pendulum_chain(n)
    if not spatial:
        mech.coordinates = "joint"
    return mech


def casmbd_rhs(n: int, spatial: bool):
    """(compiled right-hand side, parameter vector) of casmbd's articulated formulation."""
    from casmbd.analysis.dynamics.simulate import Simulator

    sim = Simulator(_chain(n, spatial), "articulated")
    return sim.dyn, np.asarray(sim.model.p, dtype=float)


def measure(n: int, spatial: bool) -> dict:
    import pinocchio as pin

    import casmbd

    f, p = casmbd_rhs(n, spatial)
    ours = casmbd.compile(_chain(n, spatial), coordinates="joint")
    model = pinocchio_chain(n, spatial)
    data = model.createData()
    rng = np.random.default_rng(n)
    q, v = rng.uniform(-1.0, 1.0, n), rng.uniform(-1.0, 1.0, n)
    tau = np.zeros(n)
    args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
    args[1][:] = np.concatenate([q, v])
    args[3][:] = p
    trigger, outs = buffer_evaluator(f, args)
    trigger()
    theirs = np.asarray(pin.aba(model, data, q, v, tau)).copy()
    scale = max(1.0, float(np.max(np.abs(theirs))))
    diff = max(float(np.max(np.abs(outs[0][n:2 * n] - theirs))),
               float(np.max(np.abs(ours.forward_dynamics(q, v, tau) - theirs)))) / scale
    if not diff < 1e-9:
        raise RuntimeError(f"N = {n} ({'spatial' if spatial else 'planar'}): accelerations "
                           f"differ by {diff:.2e} (relative)")
    # batch: casmbd's compiled map against Pinocchio's ModelPool + abaInParallel
    qs, vs = rng.uniform(-1.0, 1.0, (N_BATCH, n)), rng.uniform(-1.0, 1.0, (N_BATCH, n))
    taus = np.zeros((N_BATCH, n))
    pool = pin.ModelPool(model, 2)
    qt, vt, tt = (np.asfortranarray(x.T) for x in (qs, vs, taus))
    out_t = np.zeros((n, N_BATCH), order="F")
    pin.abaInParallel(1, pool, qt, vt, tt, out_t)
    bdiff = float(np.max(np.abs(ours.forward_dynamics_batch(qs, vs, taus) - out_t.T))) / max(
        1.0, float(np.max(np.abs(out_t))))
    if not bdiff < 1e-9:
        raise RuntimeError(f"N = {n}: batch accelerations differ by {bdiff:.2e}")
    return {"N": n, "model": "spatial" if spatial else "planar", "accel_rel_diff": diff,
            "casmbd_us": time_per_call(lambda: ours.forward_dynamics(q, v, tau)),
            "casmbd_buffer_us": time_per_call(trigger),
            "pinocchio_us": time_per_call(lambda: pin.aba(model, data, q, v, tau)),
            "n_batch": N_BATCH,
            "casmbd_batch_us": time_per_call(
                lambda: ours.forward_dynamics_batch(qs, vs, taus)) / N_BATCH,
            "pinocchio_batch_1_us": time_per_call(
                lambda: pin.abaInParallel(1, pool, qt, vt, tt, out_t)) / N_BATCH,
            "pinocchio_batch_2_us": time_per_call(
                lambda: pin.abaInParallel(2, pool, qt, vt, tt, out_t)) / N_BATCH,
            "pinocchio_version": pin.__version__}


def run(sizes) -> dict:
    import casadi

    rows = []
    for spatial in (False, True):
        for n in sizes:
            r = measure(n, spatial)
            print(f"{r['model']:8s} N={n:3d} casmbd {r['casmbd_us']:8.3f} µs  pinocchio "
                  f"{r['pinocchio_us']:8.3f} µs  batch {r['casmbd_batch_us']:7.3f} / "
                  f"{r['pinocchio_batch_1_us']:7.3f} µs  accel diff {r['accel_rel_diff']:.1e}",
                  flush=True)
            rows.append(r)
    info = {"date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "cpu": platform.processor() or platform.machine(),
            "python": platform.python_version(), "casadi": casadi.__version__,
            "load average": " ".join(f"{x:.2f}" for x in __import__("os").getloadavg()),
            "versions": fair.versions()}
    return {"info": info, "rows": rows,
            "command": "python -m benchmarks.pinocchio_aba --update-docs"}


def markdown(data: dict) -> str:
    rows, info = data["rows"], data["info"]
    version = rows[0]["pinocchio_version"] if rows else "?"
    lines = [HEAD, "",
             f"Generated by `benchmarks/pinocchio_aba.py` (`{data['command']}`), "
             f"{info['date']}, Python {info['python']}, CasADi {info['casadi']}, Pinocchio "
             f"{version}, load average {info['load average']}.", "",
             "The pendulum chains in joint coordinates, µs per call, best of timeit repeats "
             "(`benchmarks/fair.py`). *casmbd*: its public per-call method "
             "`CompiledModel.forward_dynamics(q, v, tau)` (`casmbd.compile(mechanism)`; what a "
             "user calls, argument checks and copies included) against `pinocchio.aba` "
             "through its binding; *buffer*: casmbd's bare compiled `articulated` right-hand "
             "side through `casadi.Function.buffer()` (parameters bound once, no Python "
             "method: not a user's path, for the record). Batch: µs per state over "
             f"{rows[0].get('n_batch', '?') if rows else '?'} states, "
             "`forward_dynamics_batch` (compiled `Function.map`, one thread) against "
             "Pinocchio's own batch API `abaInParallel` (a `ModelPool`) with one and two "
             "threads. Both first give the same accelerations at a random state (column *q̈ "
             "diff*, relative). *planar*: casmbd's planar recursion (3-component vectors) "
             "against Pinocchio's 6-D one with `JointModelRZ` (Pinocchio has no planar mode); "
             "*spatial*: the chain built in space (revolute joints about −y, 6-D recursion on "
             "both sides). Target: ≤ 2× Pinocchio.", "",
             "| model | N | casmbd [µs] | Pinocchio `aba` [µs] | ratio | buffer [µs] | "
             "batch casmbd [µs/state] | `abaInParallel` 1 thread | 2 threads | batch ratio "
             "(1 thread) | q̈ diff |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        if "casmbd_batch_us" not in r:   # results written before the fair rules
            r = {**r, "casmbd_buffer_us": r["casmbd_us"], "casmbd_batch_us": float("nan"),
                 "pinocchio_batch_1_us": float("nan"), "pinocchio_batch_2_us": float("nan")}
        lines.append(f"| {r['model']} | {r['N']} | {r['casmbd_us']:.3f} | "
                     f"{r['pinocchio_us']:.3f} | {r['casmbd_us'] / r['pinocchio_us']:.2f} | "
                     f"{r['casmbd_buffer_us']:.3f} | {r['casmbd_batch_us']:.3f} | "
                     f"{r['pinocchio_batch_1_us']:.3f} | {r['pinocchio_batch_2_us']:.3f} | "
                     f"{r['casmbd_batch_us'] / r['pinocchio_batch_1_us']:.2f} | "
                     f"{r['accel_rel_diff']:.0e} |")
    slopes = []
    for model in dict.fromkeys(r["model"] for r in rows):
        rs = sorted((r for r in rows if r["model"] == model), key=lambda r: r["N"])
        if len(rs) >= 2:
            a, z = rs[-2], rs[-1]
            dn = z["N"] - a["N"]
            ours = (z["casmbd_us"] - a["casmbd_us"]) / dn
            theirs = (z["pinocchio_us"] - a["pinocchio_us"]) / dn
            slopes.append(f"{model} {1e3 * ours:.0f} ns against {1e3 * theirs:.0f} ns "
                          f"(ratio {ours / theirs:.2f}, N = {a['N']} → {z['N']})")
    worst = max(rows, key=lambda r: r["casmbd_us"] / r["pinocchio_us"])
    lines += ["", f"Largest ratio: {worst['casmbd_us'] / worst['pinocchio_us']:.2f} "
              f"({worst['model']}, N = {worst['N']}); the target ≤ 2 is "
              + ("met on every row." if all(r["casmbd_us"] <= 2 * r["pinocchio_us"]
                                           for r in rows) else "missed on some rows.")
              + " Both per-call figures include a Python call into compiled code (casmbd's "
              "method with its argument checks and copies, Pinocchio's binding with its "
              "argument conversion), which dominates at small N. The cost per added body, "
              "free of that constant: "
              + "; ".join(slopes) + ".", ""]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--sizes", nargs="+", type=int, default=list(SIZES))
    parser.add_argument("--n-batch", type=int, default=N_BATCH)
    args = parser.parse_args(argv)
    globals()["N_BATCH"] = args.n_batch
    if not args.render:
        try:
            import pinocchio  # noqa: F401
        except ImportError:
            print("pinocchio is not installed (pip install .[bench]): skipped",
                  file=sys.stderr)
            return 0
    return run_study(args, RESULTS, lambda: run(tuple(args.sizes)), markdown, DOC, HEAD)

if __name__ == "__main__":
    raise SystemExit(main())
