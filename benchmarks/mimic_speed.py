"""Mimic joints on the fast path (issue 34, item 2): the Franka Panda as shipped, per call and
per batch sample, beside Pinocchio in one run.

The robot: ``panda_description/urdf/panda.urdf`` of example-robot-data, fingers coupled by
``<mimic>``.  casmbd reads it with :func:`casmbd.load_urdf` (joint coordinates: the follower
finger substituted, q_f = r q_l + δ, 8 coordinates, no constraint equation,
:mod:`casmbd.system.tree`) and compiles it (``casmbd.compile``, mode ``compiled``); for the
record, the same robot with the gear kept as a constraint equation
(``mechanism.substitute_gears = False``: 9 coordinates, 1 equation, the KKT / least-squares
path of before).  Pinocchio: ``buildModelFromUrdf(path, mimic=True)`` (``JointModelMimic``, 8
coordinates) for ``rnea`` and ``crba``; its ``aba`` refuses mimic joints, so forward dynamics
is timed against ``aba`` on the uncoupled model (``mimic=False``, 9 coordinates: the cost of
the same tree without coupling) and against ``crba`` + ``nonLinearEffects`` + a numpy solve on
the coupled one.  Both sides are first checked (M, τ, q̈ against Pinocchio's coupled model,
1e-12 / 1e-10 / 1e-9 relative).

Timing rule, both sides alike: the same K random states, a warm loop over them, best of R
repeats, µs per call (per sample for the batch methods: casmbd's ``*_batch`` over the K
states in one call against a Python loop of Pinocchio calls over them).

Run ``python -m benchmarks.mimic_speed --update-docs``: writes
``benchmarks/results/mimic_speed.json`` and the section ``## Mimic joints on the fast path``
of ``docs/robots.md``.
"""

from __future__ import annotations

import datetime
import os
import pathlib
import platform
import re
import time
import warnings

import numpy as np

import casmbd
from benchmarks.docs import run_study, study_parser
from benchmarks.fair import best_per_call, best_per_sample
from benchmarks.robots_vs_pinocchio import robots_dir

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "mimic_speed.json"
DOC = ROOT / "docs" / "robots.md"
HEAD = "## Mimic joints on the fast path"
PANDA = "panda_description/urdf/panda.urdf"
#: issue 34's targets: per call ≤ 1.2× aba / rnea, batch ≤ 0.5× a Pinocchio loop
TARGET_CALL, TARGET_BATCH = 1.2, 0.5


def fd_instructions(path) -> dict:
    """CasADi instructions of the Panda's ``robot_fd`` (q̈ and Σ q̈, ``cse``) by the
    articulated-body recursion with the finger group and by the dense LDLᵀ of the reduced M."""
    import casadi as ca

    from casmbd.compiled.robot import ldl_solve
    from casmbd.compiled.spatial_recursions import SpatialTree
    from casmbd.compiled.tree_dynamics import FUNCTION_OPTIONS
    from casmbd.system.equations import System

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        system = System(casmbd.load_urdf(path), coordinates="joint")
    q, v, p = system.q, system.v, system.p
    tau = ca.SX.sym("tau", system.nq)
    tree = SpatialTree(system, q)
    bias = tree.inverse_dynamics(v, ca.SX.zeros(system.nq))
    out = {}
    for key, qdd in (("articulated", tree.forward_dynamics(v, tau)),
                     ("dense", ldl_solve(tree.mass_matrix(), tau - bias))):
        qdd = ca.densify(qdd)
        out[key] = ca.Function("robot_fd", [q, v, tau, p], [qdd, ca.sum1(qdd)],
                               FUNCTION_OPTIONS).n_instructions()
    return out


def measure(states: int = 200, repeats: int = 30) -> dict:
    import pinocchio as pin

    path = robots_dir() / PANDA
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        ours = casmbd.compile(casmbd.load_urdf(path), mode="compiled")
        build = time.perf_counter() - t0
        mech = casmbd.load_urdf(path)
        mech.substitute_gears = False
        old = casmbd.compile(mech, mode="compiled")
        # the same tree without the coupling (the <mimic> element removed): 9 coordinates
        text = re.sub(r"<mimic[^>]*/>", "", path.read_text())
        tree = casmbd.compile(casmbd.loads_urdf(text, str(path)), mode="compiled")
    coupled = pin.buildModelFromUrdf(str(path), mimic=True)
    free = pin.buildModelFromUrdf(str(path))
    dc, df = coupled.createData(), free.createData()
    names = [n.rpartition(".")[0] for n in ours.coordinate_names]
    perm = np.array([names.index(coupled.names[j]) for j in range(1, coupled.njoints)
                     if coupled.joints[j].nq > 0])
    finger = names.index("panda_finger_joint1")
    rng = np.random.default_rng(0)
    q, v, w = (rng.uniform(-1.0, 1.0, (states, ours.nq)) for _ in range(3))
    q[:, finger] = rng.uniform(0.0, 0.04, states)
    qp, vp, wp = q[:, perm], v[:, perm], w[:, perm]
    # the uncoupled model's states: the follower finger at its leader's values (ratio 1)
    fnames = [free.names[j] for j in range(1, free.njoints)]
    full = [names.index(n if n in names else "panda_finger_joint1") for n in fnames]
    qf, vf, wf = q[:, full], v[:, full], w[:, full]
    # the constrained model's states (9 coordinates, the follower's equal to its leader's)
    onames = [n.rpartition(".")[0] for n in old.coordinate_names]
    ofull = [names.index(n if n in names else "panda_finger_joint1") for n in onames]
    qo, vo = q[:, ofull], v[:, ofull]
    wo = np.zeros((states, old.nq))
    wo[:, [onames.index(n) for n in names]] = w

    check = {"crba": 0.0, "rnea": 0.0, "aba": 0.0}
    for k in range(0, states, 20):
        m = pin.crba(coupled, dc, qp[k])
        m = np.triu(m) + np.triu(m, 1).T
        tau = pin.rnea(coupled, dc, qp[k], vp[k], wp[k])
        ref = np.linalg.solve(m, wp[k] - pin.nonLinearEffects(coupled, dc, qp[k], vp[k]))
        rel = [(ours.mass_matrix(q[k])[np.ix_(perm, perm)], m, "crba"),
               (ours.inverse_dynamics(q[k], v[k], w[k])[perm], tau, "rnea"),
               (ours.forward_dynamics(q[k], v[k], w[k])[perm], ref, "aba")]
        for got, exp, key in rel:
            check[key] = max(check[key], float(np.max(np.abs(got - exp)) / np.max(np.abs(exp))))

    def pin_fd_coupled(a, b, c):
        m = pin.crba(coupled, dc, a)
        return np.linalg.solve(np.triu(m) + np.triu(m, 1).T,
                               c - pin.nonLinearEffects(coupled, dc, a, b))

    r = repeats
    call = {
        "fd": best_per_call(ours.forward_dynamics, list(zip(q, v, w)), r),
        "fd_constrained": best_per_call(old.forward_dynamics, list(zip(qo, vo, wo)), r),
        "aba_uncoupled": best_per_call(lambda a, b, c: pin.aba(free, df, a, b, c),
                                       list(zip(qf, vf, wf)), r),
        "pin_fd_coupled": best_per_call(pin_fd_coupled, list(zip(qp, vp, wp)), r),
        "id": best_per_call(ours.inverse_dynamics, list(zip(q, v, w)), r),
        "rnea": best_per_call(lambda a, b, c: pin.rnea(coupled, dc, a, b, c),
                              list(zip(qp, vp, wp)), r),
        "rnea_uncoupled": best_per_call(lambda a, b, c: pin.rnea(free, df, a, b, c),
                                        list(zip(qf, vf, wf)), r),
        "fd_tree": best_per_call(tree.forward_dynamics, list(zip(qf, vf, wf)), r),
        "id_tree": best_per_call(tree.inverse_dynamics, list(zip(qf, vf, wf)), r),
        "mass": best_per_call(ours.mass_matrix, [(x,) for x in q], r),
        "crba": best_per_call(lambda a: pin.crba(coupled, dc, a), [(x,) for x in qp], r),
    }
    batch = {
        "fd": best_per_sample(ours.forward_dynamics_batch, (q, v, w), r),
        "id": best_per_sample(ours.inverse_dynamics_batch, (q, v, w), r),
        "fd_tree": best_per_sample(tree.forward_dynamics_batch, (qf, vf, wf), r),
        "id_tree": best_per_sample(tree.inverse_dynamics_batch, (qf, vf, wf), r),
        "aba_loop": call["aba_uncoupled"],
        "rnea_loop": call["rnea"],
    }
    # Pinocchio's own batch API (issue 36: the fair peer of a compiled map): a ModelPool and
    # abaInParallel / rneaInParallel, one thread, over column-major (n, K) arrays; aba on the
    # uncoupled tree (it refuses mimic joints), rnea on the coupled model where the pool
    # takes it, else on the uncoupled tree too (named in the record)
    def per_sample_cols(fn, arrays):  # arrays are (n, K): best_per_sample divides by n
        return best_per_sample(fn, arrays, r) * len(arrays[0]) / states

    cols = [np.asfortranarray(x.T) for x in (qf, vf, wf)]
    out = np.zeros((free.nv, states), order="F")
    pool_free = pin.ModelPool(free, 1)
    batch["aba_parallel"] = per_sample_cols(
        lambda a, b, c: pin.abaInParallel(1, pool_free, a, b, c, out), cols)
    try:
        pool_c = pin.ModelPool(coupled, 1)
        cc = [np.asfortranarray(x.T) for x in (qp, vp, wp)]
        out_c = np.zeros((coupled.nv, states), order="F")
        pin.rneaInParallel(1, pool_c, *cc, out_c)
        batch["rnea_parallel"] = per_sample_cols(
            lambda a, b, c: pin.rneaInParallel(1, pool_c, a, b, c, out_c), cc)
        batch["rnea_parallel_model"] = "mimic"
    except Exception:  # the pool refuses the coupled model: the uncoupled tree
        batch["rnea_parallel"] = per_sample_cols(
            lambda a, b, c: pin.rneaInParallel(1, pool_free, a, b, c, out), cols)
        batch["rnea_parallel_model"] = "uncoupled"
    return {"date": datetime.date.today().isoformat(), "machine": platform.processor()
            or platform.machine(), "cpus": os.cpu_count(), "pinocchio": pin.__version__,
            "states": states, "repeats": repeats, "nq": ours.nq, "nc": ours.nc,
            "nq_constrained": old.nq, "nc_constrained": old.nc, "build_s": round(build, 2),
            "check": check, "call": call, "batch": batch,
            "fd_instructions": fd_instructions(path)}


def markdown(d: dict) -> str:
    c, b = d["call"], d["batch"]

    def row(what, mine, peer, peer_name, target):
        ratio = mine / peer
        verdict = "met" if ratio <= target else "**missed**"
        return (f"| {what} | {mine:.2f} | {peer_name} {peer:.2f} | {ratio:.2f}× | "
                f"≤ {target}× {verdict} |")

    lines = [
        HEAD, "",
        f"`python -m benchmarks.mimic_speed --update-docs` (Pinocchio {d['pinocchio']}, "
        f"{d['date']}, {d['cpus']} cores shared; raw record benchmarks/results/mimic_speed.json). "
        "The Franka Panda as shipped (example-robot-data `panda.urdf`, the fingers coupled by "
        f"`<mimic>`): casmbd substitutes the follower in joint coordinates ({d['nq']} "
        f"coordinates, {d['nc']} constraint equations; before: {d['nq_constrained']} "
        f"coordinates and {d['nc_constrained']} gear equation), so `forward_dynamics`, "
        "`inverse_dynamics` and the `*_batch` methods are compiled Functions (no numpy solve, "
        "no Python loop). Checked first against Pinocchio's coupled model "
        f"(`buildModelFromUrdf(path, mimic=True)`): M {d['check']['crba']:.1e}, τ "
        f"{d['check']['rnea']:.1e}, q̈ {d['check']['aba']:.1e} (relative).", "",
        f"Timing rule, both sides: the same {d['states']} random states, a warm loop over "
        f"them, best of {d['repeats']} repeats; µs per call, or per sample for the batch "
        "methods (casmbd's `*_batch` in one call against a Python loop of Pinocchio calls "
        "and, since issue 36, against Pinocchio's own batch API `abaInParallel` / "
        "`rneaInParallel` with a `ModelPool`, one thread). "
        "Pinocchio 4.1's `aba` refuses mimic joints, so forward dynamics is set against `aba` "
        "on the same tree uncoupled (`mimic=False`, 9 coordinates) — and, for the record, "
        "against Pinocchio's own coupled route (`crba` + `nonLinearEffects` + a numpy solve).", "",
        "| quantity | casmbd µs | Pinocchio µs | ratio | target |",
        "|---|---|---|---|---|",
        row("forward dynamics, per call", c["fd"], c["aba_uncoupled"], "`aba` (uncoupled)",
            TARGET_CALL),
        row("inverse dynamics, per call", c["id"], c["rnea"], "`rnea` (mimic)", TARGET_CALL),
        row("mass matrix, per call", c["mass"], c["crba"], "`crba` (mimic)", TARGET_CALL),
        row("forward dynamics, batch per sample", b["fd"], b["aba_loop"], "loop of `aba`",
            TARGET_BATCH),
        row("inverse dynamics, batch per sample", b["id"], b["rnea_loop"], "loop of `rnea`",
            TARGET_BATCH),
        *([row("forward dynamics, batch per sample", b["fd"], b["aba_parallel"],
               "`abaInParallel` (1 thread, uncoupled)", TARGET_BATCH),
           row("inverse dynamics, batch per sample", b["id"], b["rnea_parallel"],
               f"`rneaInParallel` (1 thread, {b['rnea_parallel_model']})", TARGET_BATCH)]
          if "aba_parallel" in b else []),
        "",
        f"For the record: the constrained form of before (gear equation, numpy KKT solve per "
        f"call) {c['fd_constrained']:.2f} µs per forward-dynamics call; Pinocchio's coupled "
        f"forward dynamics through `crba` + `nonLinearEffects` + `numpy.linalg.solve` "
        f"{c['pin_fd_coupled']:.2f} µs; `rnea` on the uncoupled tree "
        f"{c['rnea_uncoupled']:.2f} µs. casmbd's build (load, System, C code, compile): "
        f"{d['build_s']} s (a warm cache hit after the first).", "",
        "The coupling itself costs nothing on this path: the same tree *without* the "
        "`<mimic>` element (9 independent coordinates) takes "
        f"{c['fd_tree']:.2f} µs (forward) and {c['id_tree']:.2f} µs (inverse) per call, "
        f"{b['fd_tree']:.2f} and {b['id_tree']:.2f} µs per batch sample — against "
        f"{c['fd']:.2f}, {c['id']:.2f}, {b['fd']:.2f} and {b['id']:.2f} with the coupling "
        "substituted. Forward dynamics is the articulated-body recursion with the two "
        "fingers as one joint of one coordinate on two children of `panda_hand` "
        "(casmbd/compiled/spatial_recursions.py; a follower on another parent than its "
        "leader's keeps the dense LDLᵀ of the reduced M): "
        f"{d['fd_instructions']['articulated']} CasADi instructions against "
        f"{d['fd_instructions']['dense']} for that LDLᵀ with the CRBA and RNEA it needs "
        "(the path before: 1.34 µs per batch sample, 0.58× the loop of `aba`).",
    ]
    missed = [name for name, mine, peer, t in (
        ("forward dynamics per call", c["fd"], c["aba_uncoupled"], TARGET_CALL),
        ("inverse dynamics per call", c["id"], c["rnea"], TARGET_CALL),
        ("forward batch", b["fd"], b["aba_loop"], TARGET_BATCH),
        ("inverse batch", b["id"], b["rnea_loop"], TARGET_BATCH),
        *((("forward batch against abaInParallel", b["fd"], b["aba_parallel"], TARGET_BATCH),
           ("inverse batch against rneaInParallel", b["id"], b["rnea_parallel"],
            TARGET_BATCH)) if "aba_parallel" in b else ())) if mine / peer > t]
    lines += ["", ("**Targets missed** in this run: " + ", ".join(missed) + ".") if missed
              else "Every target (issue 34 item 2; the batch ones also against Pinocchio's "
              "batch API, issue 36) is met in this run."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--states", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, lambda: measure(args.states, args.repeats), markdown,
                     DOC, HEAD)


if __name__ == "__main__":
    raise SystemExit(main())
