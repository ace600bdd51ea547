"""Per-call cost of casmbd's numeric API (``casmbd.compile``) beside Pinocchio, in one run
(issue 21, item 4: per call ≤ 1.5× ``pinocchio.aba``/``rnea`` from Python, batch ≤ 0.5×
Pinocchio's batch).

Model: the UR5-like arm of tests/scenes/ur_like.toml (spatial 6R) in joint coordinates.  The
Pinocchio model is built from the same numbers by :func:`pinocchio_model` (a revolute tree
of casmbd → Pinocchio joints placed in world-aligned frames at the joint points of the zero
pose, ``JointModelRevoluteUnaligned`` about the scene's axes, inertias rotated to world axes
about the centres of mass) and first checked: M against ``crba`` and τ against ``rnea`` at
random states to 1e-10 relative, q̈ against ``aba`` to 1e-9.

Timed from Python, µs per call, best of timeit repeats (:func:`benchmarks.fair.time_per_call`):
casmbd's ``forward_dynamics``, ``inverse_dynamics``, ``mass_matrix``, ``bias_forces``,
``forward_kinematics`` and ``jacobian`` (end body) against ``pin.aba``, ``pin.rnea``,
``pin.crba``, ``pin.nonLinearEffects``, ``pin.forwardKinematics`` and
``pin.computeJointJacobian`` + nothing else (LOCAL frame; the world-aligned one costs an
extra rotation); and per sample, casmbd's ``forward_dynamics_batch`` /
``inverse_dynamics_batch`` over N samples against Pinocchio's own batch API
``pin.abaInParallel`` / ``pin.rneaInParallel`` (a ``ModelPool``, one thread; the Python loop
of ``pin.aba`` / ``pin.rnea`` is recorded beside it as ``pinocchio_loop_us``).

Run ``python -m benchmarks.numeric_api --update-docs`` (``pip install .[bench]`` for ``pin``):
writes ``benchmarks/results/numeric_api.json`` and the section ``## Per-call numeric API
against Pinocchio`` of ``docs/performance.md``.  Without ``pin`` only casmbd's column is
measured.
"""

from __future__ import annotations

import datetime
import os
import pathlib
import platform
import time

import numpy as np

import casmbd
from benchmarks.docs import run_study, study_parser
from benchmarks.fair import time_per_call

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "numeric_api.json"
DOC = ROOT / "docs" / "performance.md"
HEAD = "## Per-call numeric API against Pinocchio"
SCENE = ROOT / "tests" / "scenes" / "ur_like.toml"
URDF = ROOT / "tests" / "scenes" / "ur5_arm.urdf"
N_BATCH = 1000


def _rotation(e) -> np.ndarray:
    """Rotation matrix of the unit quaternion (e0, e1, e2, e3), scalar first."""
    e0, e1, e2, e3 = np.asarray(e, dtype=float) / np.linalg.norm(e)
    return np.array([
        [1 - 2 * (e2**2 + e3**2), 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
        [2 * (e1 * e2 + e0 * e3), 1 - 2 * (e1**2 + e3**2), 2 * (e2 * e3 - e0 * e1)],
        [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), 1 - 2 * (e1**2 + e2**2)]])


def pinocchio_model(mech):
    """Pinocchio model of a casmbd revolute tree (spatial, numeric masses) at its zero pose."""
    import pinocchio as pin

    model = pin.Model()
    model.gravity.linear = np.asarray(mech.gravity, dtype=float)
    ids, points = {"ground": 0}, {"ground": np.zeros(3)}
    pending = list(mech.joints.values())
    while pending:
        joint = next(j for j in pending if j.body1 in ids)
        pending.remove(joint)
        point = np.asarray(joint.point, dtype=float)
        axis = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
        placement = pin.SE3(np.eye(3), point - points[joint.body1])
        jid = model.addJoint(ids[joint.body1], pin.JointModelRevoluteUnaligned(axis),
                             placement, joint.name)
        body = mech.bodies[joint.body2]
        rot = _rotation(body.orientation)
        vals = [float(x) for x in body.inertia]
        off = vals[3:] if len(vals) == 6 else [0.0, 0.0, 0.0]
        tensor = np.array([[vals[0], off[0], off[1]], [off[0], vals[1], off[2]],
                           [off[1], off[2], vals[2]]])
        model.appendBodyToJoint(jid, pin.Inertia(float(body.mass), np.asarray(
            body.position, dtype=float) - point, rot @ tensor @ rot.T), pin.SE3.Identity())
        ids[joint.body2], points[joint.body2] = jid, point
    return model


def pinocchio_configuration(pin_model, names: list[str]):
    """q ↦ Pinocchio's configuration vector: casmbd's joint angles (named ``joint`` or
    ``joint.angle``) in Pinocchio's joint order; a continuous joint (nq = 2) as (cos, sin)."""
    index = {name.partition(".")[0]: k for k, name in enumerate(names)}
    order = [(index[pin_model.names[j]], pin_model.joints[j].nq)
             for j in range(1, pin_model.njoints)]

    def convert(q):
        out = []
        for k, nq in order:
            out += [np.cos(q[k]), np.sin(q[k])] if nq == 2 else [q[k]]
        return np.array(out)
    return convert, np.array([k for k, _ in order])


def _check(ours, pin_model, to_pin, perm, rng) -> dict:
    import pinocchio as pin

    data = pin_model.createData()
    worst = {"M": 0.0, "tau": 0.0, "qdd": 0.0}
    for _ in range(5):
        q, v, a = (rng.uniform(-2.0, 2.0, ours.nq) for _ in range(3))
        qp, vp, ap = to_pin(q), v[perm], a[perm]
        m_pin = pin.crba(pin_model, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        for key, x, y in (("M", ours.mass_matrix(q)[np.ix_(perm, perm)], m_pin),
                          ("tau", ours.inverse_dynamics(q, v, a)[perm],
                           pin.rnea(pin_model, data, qp, vp, ap)),
                          ("qdd", ours.forward_dynamics(q, v, a)[perm],
                           pin.aba(pin_model, data, qp, vp, ap))):
            worst[key] = max(worst[key], float(np.max(np.abs(x - y)) / np.max(np.abs(y))))
    for key, tol in (("M", 1e-10), ("tau", 1e-10), ("qdd", 1e-9)):
        if not worst[key] < tol:
            raise RuntimeError(f"casmbd and Pinocchio differ in {key} by {worst[key]:.1e}")
    return worst


def measure(label: str, mech, pin_builder, n_batch: int) -> dict:
    """Check and time one arm: casmbd's model of ``mech`` against ``pin_builder()``."""
    try:
        import pinocchio as pin
    except ImportError:
        pin = None
    t0 = time.perf_counter()
    ours = casmbd.compile(mech, coordinates="joint", mode="auto")
    build = time.perf_counter() - t0
    rng = np.random.default_rng(21)
    n = ours.nq
    q, v, a = (rng.uniform(-1.0, 1.0, n) for _ in range(3))
    qs, vs, accs = (rng.uniform(-1.0, 1.0, (n_batch, n)) for _ in range(3))
    end = ours.frame_names[len(ours.numeric.body_names) - 1]
    rows = [("forward dynamics", lambda: ours.forward_dynamics(q, v, a)),
            ("inverse dynamics", lambda: ours.inverse_dynamics(q, v, a)),
            ("mass matrix", lambda: ours.mass_matrix(q)),
            ("bias forces", lambda: ours.bias_forces(q, v)),
            ("forward kinematics", lambda: ours.forward_kinematics(q)),
            ("jacobian", lambda: ours.jacobian(q, end))]
    out = {"model": label, "rows": [], "batch": [], "check": None, "build_s": build,
           "mode": ours.numeric.report.mode}
    theirs = {}
    if pin is not None:
        pm = pin_builder()
        data = pm.createData()
        to_pin, perm = pinocchio_configuration(pm, ours.coordinate_names)
        out["check"] = _check(ours, pm, to_pin, perm, rng)
        qp, vp, ap = to_pin(q), v[perm], a[perm]
        qps = [to_pin(x) for x in qs]
        jid = pm.njoints - 1
        theirs = {"forward dynamics": ("aba", lambda: pin.aba(pm, data, qp, vp, ap)),
                  "inverse dynamics": ("rnea", lambda: pin.rnea(pm, data, qp, vp, ap)),
                  "mass matrix": ("crba", lambda: pin.crba(pm, data, qp)),
                  "bias forces": ("nonLinearEffects",
                                  lambda: pin.nonLinearEffects(pm, data, qp, vp)),
                  "forward kinematics": ("forwardKinematics",
                                         lambda: pin.forwardKinematics(pm, data, qp)),
                  "jacobian": ("computeJointJacobian",
                               lambda: pin.computeJointJacobian(pm, data, qp, jid))}
        out["pinocchio_version"] = pin.__version__
    for name, fn in rows:
        row = {"method": name, "casmbd_us": time_per_call(fn)}
        if name in theirs:
            row["pinocchio"], pfn = theirs[name]
            row["pinocchio_us"] = time_per_call(pfn)
        out["rows"].append(row)
        print(label, row, flush=True)
    batches = [("forward_dynamics_batch", lambda: ours.forward_dynamics_batch(qs, vs, accs),
                "aba", lambda: [pin.aba(pm, data, x, y, z) for x, y, z in zip(qps, vs, accs)]),
               ("inverse_dynamics_batch", lambda: ours.inverse_dynamics_batch(qs, vs, accs),
                "rnea", lambda: [pin.rnea(pm, data, x, y, z) for x, y, z in zip(qps, vs, accs)])]
    parallel = {}
    if pin is not None and hasattr(pin, "abaInParallel"):
        # Pinocchio's own batch API (the fair peer of a compiled map; issue 36): a ModelPool
        # and abaInParallel / rneaInParallel over column-major (n, N) arrays, one thread
        pool = pin.ModelPool(pm, 1)
        qt, vt, at = (np.asfortranarray(np.array(x).T) for x in (qps, vs, accs))
        res = np.zeros((pm.nv, n_batch), order="F")
        parallel = {"aba": lambda: pin.abaInParallel(1, pool, qt, vt, at, res),
                    "rnea": lambda: pin.rneaInParallel(1, pool, qt, vt, at, res)}
    for name, fn, plabel, pfn in batches:
        row = {"method": name, "casmbd_us": time_per_call(fn) / n_batch}
        if pin is not None:
            if plabel in parallel:
                row["pinocchio"] = f"{plabel}InParallel (1 thread)"
                row["pinocchio_us"] = time_per_call(parallel[plabel]) / n_batch
                row["pinocchio_loop_us"] = time_per_call(pfn) / n_batch
            else:
                row["pinocchio"] = f"Python loop of {plabel}"
                row["pinocchio_us"] = time_per_call(pfn) / n_batch
        out["batch"].append(row)
        print(label, row, flush=True)
    return out


def run(n_batch: int) -> dict:
    import casadi

    try:
        import pinocchio as pin
    except ImportError:
        pin = None
    scene = casmbd.load_scene(SCENE)
    models = [measure("ur_like.toml", scene, lambda: pinocchio_model(scene), n_batch)]
    if URDF.exists() and hasattr(casmbd, "load_urdf"):
        models.append(measure("ur5_arm.urdf", casmbd.load_urdf(URDF),
                              lambda: pin.buildModelFromUrdf(str(URDF)), n_batch))
    out = {"models": models, "pinocchio_version": models[0].get("pinocchio_version")}
    out["info"] = {"date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
                   "cpu": platform.processor() or platform.machine(),
                   "python": platform.python_version(), "casadi": casadi.__version__,
                   "load average": " ".join(f"{x:.2f}" for x in os.getloadavg()),
                   "n_batch": n_batch, "mode": models[0]["mode"]}
    out["command"] = "python -m benchmarks.numeric_api --update-docs"
    return out


def markdown(data: dict) -> str:
    info = data["info"]
    lines = [HEAD, "",
             f"Generated by `benchmarks/numeric_api.py` (`{data['command']}`), {info['date']}, "
             f"Python {info['python']}, CasADi {info['casadi']}, Pinocchio "
             f"{data.get('pinocchio_version') or '(not installed)'}, casmbd mode "
             f"`{info['mode']}`, load average {info['load average']}.", "",
             "Two UR5-type arms (6 revolute joints) in joint coordinates: *ur_like.toml* "
             "(tests/scenes/ur_like.toml; Pinocchio's model built from the same numbers by "
             "`pinocchio_model` in the benchmark) and *ur5_arm.urdf* (tests/scenes/ur5_arm.urdf, "
             "read by `casmbd.load_urdf` and by `pinocchio.buildModelFromUrdf`). "
             "`model = casmbd.compile(mechanism)` (docs/robots.md, *Per-call numeric API*) "
             "against Pinocchio, both called from Python with numpy arrays, µs per call (best "
             "of timeit repeats, `benchmarks/fair.py`); the batch rows are µs per sample over "
             f"{info['n_batch']} samples (casmbd: compiled `Function.map` over chunks of 64 "
             "samples; Pinocchio: its own batch API `abaInParallel` / `rneaInParallel` with a "
             "`ModelPool`, one thread — results written before issue 36 compared with a "
             "Python loop, named in the Pinocchio column). Pinocchio's *jacobian* is "
             "`computeJointJacobian` (LOCAL frame at the last joint), casmbd's the "
             "world-aligned Jacobian of the last body's centre of mass.", ""]
    checks = [f"{m['model']}: M against `crba` {m['check']['M']:.0e}, τ against `rnea` "
              f"{m['check']['tau']:.0e}, q̈ against `aba` {m['check']['qdd']:.0e}"
              for m in data["models"] if m.get("check")]
    if checks:
        lines += ["Same results first (largest relative difference at 5 random states): "
                  + "; ".join(checks) + ".", ""]
    lines += ["| model | method | casmbd [µs] | Pinocchio | Pinocchio [µs] | ratio | target |",
              "| --- | --- | ---: | --- | ---: | ---: | ---: |"]
    verdicts = []
    for m in data["models"]:
        for group, target in ((m["rows"], 1.5), (m["batch"], 0.5)):
            for r in group:
                ratio = (r["casmbd_us"] / r["pinocchio_us"] if "pinocchio_us" in r
                         else float("nan"))
                lines.append(f"| {m['model']} | {r['method']} | {r['casmbd_us']:.3f} | "
                             f"{r.get('pinocchio', '—')} | "
                             f"{r.get('pinocchio_us', float('nan')):.3f} | {ratio:.2f} | "
                             f"≤ {target} |")
                if r["method"] in ("forward dynamics", "inverse dynamics") or target == 0.5:
                    verdicts.append((f"{m['model']} {r['method']}", ratio, ratio <= target))
    lines += ["", "Targets (issue 21: per call ≤ 1.5× `aba`/`rnea`, batch ≤ 0.5× Pinocchio's "
              "batch): "
              + "; ".join(f"{m} {x:.2f} ({'met' if ok else 'missed'})"
                          for m, x, ok in verdicts) + ". "
        "casmbd's figure includes copying the arguments into the bound buffers and the "
        "result out (so callers never alias the buffers): with the Python method call and "
        "the length checks that is about 0.6–1.0 µs of each figure, the compiled code itself "
        "0.1–0.9 µs. Pinocchio's `forwardKinematics` returns nothing (the placements stay in "
        "its `data.oMi`), casmbd's `forward_kinematics` returns new arrays of the positions "
        "and rotations of every body and marker.", ""]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--n-batch", type=int, default=N_BATCH)
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, lambda: run(args.n_batch), markdown, DOC, HEAD)


if __name__ == "__main__":
    raise SystemExit(main())
