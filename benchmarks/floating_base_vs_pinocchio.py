"""Floating bases against Pinocchio's free-flyer on example-robot-data (issue 34, item 1).

Each robot is read by ``casmbd.load_urdf(path, floating_base=True)`` (joint coordinates,
compiled by :func:`casmbd.compile`, mode ``vm``) and by
``pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())``.  The conventions map
exactly (:mod:`casmbd.compiled.free_flyer`): Pinocchio's q = (x, y, z, qx, qy, qz, qw, joints)
is casmbd's (x, y, z, e0, e1, e2, e3, joints) with the scalar part last, both velocities are
the root's body-frame (``LOCAL``) linear and angular velocity then the joint rates (joints
matched by name; a continuous joint is (cos θ, sin θ) in Pinocchio's q).  At random states (a
random unit quaternion, base position in ±1 m, joints in ±2 rad, v and a in ±2): every link
frame (position in m, rotation max |ΔR|; casmbd's body frames at the centre of mass against
``oMi · lever``), M against ``crba`` (relative to max |M|), τ against ``rnea``, v̇ against
``aba`` (relative; divided by cond(M)/1e4 when that exceeds 1), each frame's Jacobian
against ``getFrameJacobian(…, LOCAL_WORLD_ALIGNED)`` (shifted to the centre of mass for
casmbd's body frames), ``integrate`` (Δt = 0.3) and ``difference`` against Pinocchio's.

Run: ``python -m benchmarks.floating_base_vs_pinocchio [--update-docs]`` (about a minute).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np

from benchmarks.robots_vs_pinocchio import _frame_errors, robots_dir

RESULTS = Path(__file__).resolve().parent / "results" / "floating_base_vs_pinocchio.json"
DOC = Path(__file__).resolve().parent.parent / "docs" / "robots.md"
HEAD = "## Floating bases checked against Pinocchio"
#: legged robots, humanoids and the two quadrotors of example-robot-data
ROBOTS = ("solo_description/robots/solo12.urdf", "solo_description/robots/solo.urdf",
          "bolt_description/robots/bolt.urdf",
          "anymal_b_simple_description/robots/anymal.urdf",
          "anymal_c_simple_description/urdf/anymal.urdf", "a1_description/urdf/a1.urdf",
          "go1_description/urdf/go1.urdf", "hyq_description/robots/hyq_no_sensors.urdf",
          "simple_humanoid_description/urdf/simple_humanoid.urdf",
          "talos_data/robots/talos_reduced.urdf", "iris_description/robots/iris_simple.urdf",
          "hector_description/robots/quadrotor_base.urdf")
TOL = {"fk": 1e-12, "rot": 1e-12, "crba": 1e-12, "rnea": 1e-10, "aba": 1e-9, "J": 1e-12,
       "integrate": 1e-12, "difference": 1e-12}


def _rel(x, y) -> float:
    return float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300))


def _models(path):
    import pinocchio as pin

    import casmbd

    pm = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = casmbd.load_urdf(path, floating_base=True)
    ours = casmbd.compile(mech, mode="vm")
    return pm, ours


def _mapping(pm, ours):
    """casmbd q ↦ Pinocchio q, and the permutation of v (casmbd → Pinocchio)."""
    block = ours.velocity_map.blocks
    if len(block) != 1 or block[0].q != 0 or block[0].v != 0:
        raise ValueError(f"expected one floating root first, got {block}")
    joints = ours.coordinate_names[7:]
    names = [pm.names[j] for j in range(2, pm.njoints)]
    index = {n.rpartition(".")[0]: k for k, n in enumerate(joints)}
    if sorted(index) != sorted(names):
        raise KeyError(f"joints differ: casmbd {joints}, Pinocchio {names}")
    order = [(index[pm.names[j]], pm.joints[j].nq) for j in range(2, pm.njoints)]

    def to_pin(q):
        out = [*q[0:3], *q[4:7], q[3]]
        for k, nq in order:
            out += [np.cos(q[7 + k]), np.sin(q[7 + k])] if nq == 2 else [q[7 + k]]
        return np.array(out)
    perm = np.concatenate([np.arange(6), 6 + np.array([k for k, _ in order], dtype=int)])
    return to_pin, perm


def _random_state(rng, ours):
    quat = rng.normal(size=4)
    q = np.concatenate([rng.uniform(-1, 1, 3), quat / np.linalg.norm(quat),
                        rng.uniform(-2, 2, ours.nq - 7)])
    return q, rng.uniform(-2, 2, ours.nv), rng.uniform(-2, 2, ours.nv)


def compare(path, states: int = 3, seed: int = 0) -> dict:
    """Largest errors of casmbd against Pinocchio's free-flyer model at random states."""
    import pinocchio as pin

    pm, ours = _models(path)
    if (ours.nq, ours.nv, ours.nc) != (pm.nq, pm.nv, 0):
        raise ValueError(f"sizes differ: casmbd (nq, nv, nc) = {(ours.nq, ours.nv, ours.nc)}, "
                         f"Pinocchio (nq, nv) = {(pm.nq, pm.nv)}")
    to_pin, perm = _mapping(pm, ours)
    data = pm.createData()
    rng = np.random.default_rng(seed)
    worst = dict.fromkeys(TOL, 0.0)
    worst["nv"] = ours.nv
    frames = {f.name: k for k, f in enumerate(pm.frames) if f.type == pin.FrameType.BODY}
    n_body = len(ours.numeric.body_names)
    for _ in range(states):
        q, v, a = _random_state(rng, ours)
        qp, vp, ap = to_pin(q), v[perm], a[perm]
        fk = ours.forward_kinematics(q)
        _frame_errors(worst, ours, fk, pm, data, qp)
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        m_ours = ours.mass_matrix(q)[np.ix_(perm, perm)]
        worst["crba"] = max(worst["crba"], _rel(m_ours, m_pin))
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["rnea"] = max(worst["rnea"], _rel(ours.inverse_dynamics(q, v, a)[perm], tau))
        tau_ours = np.empty(ours.nv)
        tau_ours[perm] = tau
        scale = max(1.0, np.linalg.cond(m_pin) / 1e4)
        worst["aba"] = max(worst["aba"], _rel(ours.forward_dynamics(q, v, tau_ours)[perm],
                                              pin.aba(pm, data, qp, vp, tau)) / scale)
        pin.computeJointJacobians(pm, data, qp)
        pin.updateFramePlacements(pm, data)
        for i, name in enumerate(ours.frame_names):
            if name not in frames:
                continue
            fid = frames[name]
            jac = pin.getFrameJacobian(pm, data, fid, pin.LOCAL_WORLD_ALIGNED)
            if i < n_body:  # casmbd's body frame is at the centre of mass: shift the point
                d = fk[0][i] - data.oMf[fid].translation
                skew = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
                jac = np.vstack([jac[:3] - skew @ jac[3:], jac[3:]])
            worst["J"] = max(worst["J"], _rel(ours.jacobian(q, name)[:, perm], jac))
        q1 = ours.integrate(q, v, 0.3)
        worst["integrate"] = max(worst["integrate"], float(np.max(np.abs(
            to_pin(q1) - pin.integrate(pm, qp, 0.3 * vp)))))
        dv = ours.difference(q, q1)
        worst["difference"] = max(worst["difference"], float(np.max(np.abs(
            dv[perm] - pin.difference(pm, qp, to_pin(q1))))))
    return worst


def measure(states: int = 3, seed: int = 3) -> dict:
    import pinocchio as pin

    root = robots_dir()
    rows = []
    for robot in ROBOTS:
        row = {"robot": robot}
        t0 = time.perf_counter()
        try:
            worst = compare(root / robot, states=states, seed=seed)
        except Exception as exc:  # a robot that does not load is recorded, not fatal
            row["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0][:300]
        else:
            row.update(frames=int(worst.pop("frames")), errors=worst,
                       nv=int(worst.pop("nv")),
                       passed=all(worst[k] <= tol for k, tol in TOL.items()))
        row["seconds"] = round(time.perf_counter() - t0, 2)
        rows.append(row)
    return {"pinocchio": pin.__version__, "states": states, "seed": seed, "robots": rows}


def markdown(data: dict) -> str:
    rows = data["robots"]
    passed = sum(1 for r in rows if r.get("passed"))
    out = [HEAD, "",
           f"`python -m benchmarks.floating_base_vs_pinocchio --update-docs` (Pinocchio "
           f"{data['pinocchio']}, casmbd mode `vm`, {data['states']} random states per robot; "
           "raw records in benchmarks/results/floating_base_vs_pinocchio.json). Each robot of "
           "example-robot-data below is read by `casmbd.load_urdf(path, floating_base=True)` "
           "and by `pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())`, q and "
           "v mapped as in [Floating bases](#floating-bases) (the same numbers, the quaternion's "
           "scalar last in Pinocchio's q); compared: every link frame, M (`crba`), τ (`rnea`), "
           "v̇ (`aba`), every frame's Jacobian (`getFrameJacobian(…, LOCAL_WORLD_ALIGNED)`), "
           "`integrate` and `difference` (benchmarks/floating_base_vs_pinocchio.py). "
           "Tolerances 1e-12 (frames in m and rotation, M, J, integrate, difference; M and J "
           "relative to their largest entry), 1e-10 (τ, relative), 1e-9 (v̇, relative, scaled "
           f"by cond(M)/1e4 when larger). **{passed} of {len(rows)} robots pass**; "
           "tests/peers/test_floating_base.py runs solo12 and bolt.", "",
           "| URDF | n_v | frames | FK [m] | R | M | τ | v̇ | J | integrate | difference "
           "| pass |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        name = r["robot"].split("/")[-1]
        if "errors" not in r:
            out.append(f"| {name} | | | {r.get('error', '')} | | | | | | | | no |")
            continue
        e = r["errors"]
        cells = " | ".join(f"{e[k]:.1e}" for k in ("fk", "rot", "crba", "rnea", "aba", "J",
                                                     "integrate", "difference"))
        out.append(f"| {r['robot'].split('/')[0]}/{name} | {r['nv']} | {r['frames']} | "
                   f"{cells} | {'yes' if r['passed'] else '**no**'} |")
    return "\n".join(out) + "\n\n"


def main(argv=None) -> int:
    from benchmarks.docs import run_study, study_parser

    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, measure, markdown, DOC, HEAD)


if __name__ == "__main__":
    raise SystemExit(main())
