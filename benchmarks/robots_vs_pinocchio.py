"""casmbd against Pinocchio on every URDF of ``example-robot-data`` (issue 21, item 5).

Every ``*.urdf`` of the package that ``pinocchio.buildModelFromUrdf`` loads (fixed base, as the
file says) is read by :func:`casmbd.load_urdf` in joint coordinates and compiled by
:func:`casmbd.compile`; at random states (q uniform in [-2, 2] rad or [-0.2, 0.2] m, v and
a uniform in [-2, 2]) the four quantities are compared with Pinocchio's:

* forward kinematics of every link frame: casmbd's body frames (centre of mass of the body
  with its merged fixed links, link axes) against ``oMi · lever`` of the Pinocchio joint's
  inertia and ``oMf`` of the link frame; casmbd's markers (links merged by fixed joints,
  frame-only links) against ``oMf`` of the link — position error in m (≤ 1e-12), rotation
  error max |ΔR| (≤ 1e-12);
* the mass matrix against ``pin.crba`` (upper triangle mirrored), max |ΔM| / max |M| ≤ 1e-12;
* inverse dynamics against ``pin.rnea``, max |Δτ| / max |τ| ≤ 1e-10;
* forward dynamics against ``pin.aba`` (τ as input), max |Δq̈| / max |q̈| ≤ 1e-9.

Joints are matched by name (casmbd's coordinate ``joint.angle`` ↔ Pinocchio's
``model.names``); a continuous joint is (cos θ, sin θ) in Pinocchio's q (nq = 2, nv = 1).
Each robot runs in its own process with a time limit (``--timeout``), so a robot casmbd
cannot build in time is recorded as such rather than stopping the sweep.  ``--quick`` checks
two arms (UR5, Panda).

Run: ``python -m benchmarks.robots_vs_pinocchio [--quick] [--update-docs]``.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results" / "robots_vs_pinocchio.json"
DOC = Path(__file__).resolve().parent.parent / "docs" / "robots.md"
HEAD = "## Checked against Pinocchio on example-robot-data"
#: Tolerances of issue 21 item 5: frames [m] and rotations, then relative M, τ, q̈.
TOLERANCES = {"fk": 1e-12, "rot": 1e-12, "crba": 1e-12, "rnea": 1e-10, "aba": 1e-9}
QUICK = ("ur_description/urdf/ur5_robot.urdf", "panda_description/urdf/panda.urdf")


def robots_dir() -> Path | None:
    """The ``robots`` folder of the installed ``example-robot-data`` (the Python module's
    ``getModelPath`` when present, else the data files of the cmeel wheel); None without it."""
    try:
        import example_robot_data as erd

        path = Path(erd.getModelPath("ur_description/urdf/ur5_robot.urdf"))
        if path.is_dir():
            return path
    except Exception:
        pass
    try:
        from importlib.metadata import PackageNotFoundError, distribution

        dist = distribution("example-robot-data")
    except (ImportError, PackageNotFoundError):
        return None
    for f in dist.files or ():
        parts = Path(str(f)).parts
        if "example-robot-data" in parts and parts[-1].endswith(".urdf"):
            k = parts.index("example-robot-data")
            folder = Path(str(dist.locate_file(Path(*parts[:k + 2]))))
            if folder.is_dir():
                return folder
    return None


def _pin_configuration(pm, names: list[str]):
    """q ↦ Pinocchio's q and the permutation casmbd → Pinocchio for v, a, τ."""
    index = {name.rpartition(".")[0] or name: k for k, name in enumerate(names)}
    missing = [pm.names[j] for j in range(1, pm.njoints) if pm.names[j] not in index]
    if missing or pm.njoints - 1 != len(names):
        raise KeyError(f"joints differ: Pinocchio-only {missing}, casmbd {names}")
    order = [(index[pm.names[j]], pm.joints[j].nq) for j in range(1, pm.njoints)]

    def convert(q):
        out = []
        for k, nq in order:
            out += [np.cos(q[k]), np.sin(q[k])] if nq == 2 else [q[k]]
        return np.array(out)
    return convert, np.array([k for k, _ in order])


def _mimic_joints(path) -> tuple[list[str], list[str]]:
    """The joints of ``<mimic>`` pairs in the URDF file: all of them, and the leaders."""
    import xml.etree.ElementTree as ET

    names, leaders = set(), set()
    for joint in ET.parse(str(path)).getroot().iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            names |= {joint.get("name"), mimic.get("joint")}
            leaders.add(mimic.get("joint"))
    return sorted(names), sorted(leaders)


def _rel(x, y) -> float:
    return float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300))


def check_robot(path: str | Path, states: int = 3, seed: int = 0, mode: str = "vm") -> dict:
    """Load ``path`` with Pinocchio and casmbd (joint coordinates) and compare at ``states``
    random states; returns the record (errors, pass/fail or the named error)."""
    import warnings

    import pinocchio as pin

    rec: dict = {"robot": str(path)}
    try:
        pm = pin.buildModelFromUrdf(str(path))
    except Exception as exc:
        rec.update(pinocchio=False, error=f"Pinocchio: {exc}".splitlines()[0][:200])
        return rec
    mimic, leaders = _mimic_joints(path)
    if mimic:  # locked at 0 in both: Pinocchio's model has no coupling
        ids = sorted({pm.getJointId(n) for n in mimic if pm.existJointName(n)})
        pm = pin.buildReducedModel(pm, ids, pin.neutral(pm))
        rec["locked"] = mimic
    rec.update(pinocchio=True, nv=int(pm.nv), njoints=int(pm.njoints - 1),
               joint_types=sorted({j.shortname() for j in pm.joints[1:]}))
    import casmbd

    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mech = casmbd.load_urdf(path, locked=dict.fromkeys(leaders, 0.0))
            ours = casmbd.compile(mech, mode=mode)
    except Exception as exc:
        rec.update(casmbd=False, error=f"{type(exc).__name__}: {exc}".splitlines()[0][:300])
        return rec
    rec.update(casmbd=True, build_s=round(time.perf_counter() - t0, 3), nc=int(ours.nc))
    if ours.nc:
        rec.update(compared=False, error=f"{ours.nc} constraint equations in joint coordinates "
                   "(mimic coupling or closed chain): M, τ are not Pinocchio's")
        return rec
    try:
        to_pin, perm = _pin_configuration(pm, list(ours.coordinate_names))
    except KeyError as exc:
        rec.update(compared=False, error=str(exc)[:300])
        return rec
    prismatic = np.array(["Prismatic" in pm.joints[j].shortname()
                          for j in range(1, pm.njoints)])
    scale = np.where(prismatic[np.argsort(perm)], 0.2, 2.0)
    data = pm.createData()
    rng = np.random.default_rng(seed)
    n_body = len(ours.numeric.body_names)
    frames = {f.name: k for k, f in enumerate(pm.frames) if f.type == pin.FrameType.BODY}
    shared = [(i, name) for i, name in enumerate(ours.frame_names) if name in frames]
    worst = dict.fromkeys(TOLERANCES, 0.0)
    for _ in range(states):
        q = rng.uniform(-1.0, 1.0, ours.nq) * scale
        v, a = rng.uniform(-2.0, 2.0, ours.nq), rng.uniform(-2.0, 2.0, ours.nq)
        qp, vp, ap = to_pin(q), v[perm], a[perm]
        pin.forwardKinematics(pm, data, qp)
        pin.updateFramePlacements(pm, data)
        pos, rot = ours.forward_kinematics(q)
        for i, name in shared:
            frame = pm.frames[frames[name]]
            placement = data.oMf[frames[name]]
            point = (data.oMi[frame.parentJoint].act(pm.inertias[frame.parentJoint].lever)
                     if i < n_body else placement.translation)
            worst["fk"] = max(worst["fk"], float(np.max(np.abs(pos[i] - point))))
            axes = (placement.rotation if i < n_body  # a marker has its body's axes
                    else data.oMi[frame.parentJoint].rotation)
            worst["rot"] = max(worst["rot"], float(np.max(np.abs(rot[i] - axes))))
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["crba"] = max(worst["crba"], _rel(ours.mass_matrix(q)[np.ix_(perm, perm)], m_pin))
        worst["rnea"] = max(worst["rnea"], _rel(ours.inverse_dynamics(q, v, a)[perm], tau))
        tau_ours = np.empty(ours.nq)
        tau_ours[perm] = tau
        worst["aba"] = max(worst["aba"], _rel(ours.forward_dynamics(q, v, tau_ours)[perm],
                                              pin.aba(pm, data, qp, vp, tau)))
    rec.update(compared=True, frames=len(shared), states=states, errors=worst,
               passed=all(worst[k] <= tol for k, tol in TOLERANCES.items()))
    return rec


def _in_process(path: Path, timeout: float, mode: str) -> dict:
    cmd = [sys.executable, "-m", "benchmarks.robots_vs_pinocchio", "--one", str(path),
           "--mode", mode]
    root = Path(__file__).resolve().parent.parent
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=root)
    except subprocess.TimeoutExpired:
        return {"robot": str(path), "pinocchio": True, "casmbd": False,
                "error": f"not built within the time limit of {timeout:g} s"}
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode or not lines:
        tail = (out.stderr.strip().splitlines() or ["no output"])[-1]
        return {"robot": str(path), "error": f"process failed: {tail[:300]}"}
    return json.loads(lines[-1])


def measure(quick: bool = False, timeout: float = 120.0, mode: str = "vm") -> dict:
    """Run every robot (or the :data:`QUICK` two) in its own process; the records, with
    paths relative to the package's ``robots`` folder."""
    import pinocchio as pin

    root = robots_dir()
    if root is None:
        raise SystemExit("example-robot-data is not installed (pip install example-robot-data)")
    paths = ([root / p for p in QUICK] if quick else sorted(root.rglob("*.urdf")))
    records = []
    for path in paths:
        t0 = time.perf_counter()
        rec = _in_process(path, timeout, mode)
        rec["robot"] = str(path.relative_to(root))
        rec["wall_s"] = round(time.perf_counter() - t0, 2)
        print(json.dumps(rec), file=sys.stderr)
        records.append(rec)
    return {"pinocchio_version": pin.__version__, "mode": mode, "tolerances": TOLERANCES,
            "robots": records}


def markdown(data: dict) -> str:
    """The docs/robots.md section: one row per URDF file."""
    recs = data["robots"]
    compared = [r for r in recs if r.get("compared")]
    passed = [r for r in compared if r.get("passed")]
    lines = [HEAD, "",
             f"`python -m benchmarks.robots_vs_pinocchio --update-docs` (Pinocchio "
             f"{data['pinocchio_version']}, casmbd mode `{data['mode']}`; raw records in "
             "benchmarks/results/robots_vs_pinocchio.json). Every URDF file of "
             "`example-robot-data` is read by `pinocchio.buildModelFromUrdf` (fixed base) and "
             "by `casmbd.load_urdf` (joint coordinates; joints matched by name, a continuous "
             "joint as (cos, sin) in Pinocchio's q; `<mimic>` pairs locked at 0 in both, "
             "`pinocchio.buildReducedModel`) and compared at 3 random states: every link frame "
             "(position in m — a body at its centre of mass against `oMi · lever`, a marker at "
             "the link origin `oMf`; rotation max |ΔR| — a body's axes against the link's, a "
             "marker's, which are its body's axes in `forward_kinematics`, against the moving "
             "link's), M against `crba`, τ against "
             "`rnea`, q̈ against `aba` (relative to the largest entry). Tolerances "
             "1e-12 m, 1e-12, 1e-12, 1e-10, 1e-9. "
             f"**{len(passed)} of {len(compared)} compared robots pass**; "
             f"{len(recs) - len(compared)} of {len(recs)} files were not compared (reasons "
             "below).", "",
             "| URDF | n_v | frames | FK [m] | R | M (crba) | τ (rnea) | q̈ (aba) | pass |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in compared:
        e = r["errors"]
        lines.append(f"| {r['robot']} | {r['nv']} | {r['frames']} | {e['fk']:.1e} | "
                     f"{e['rot']:.1e} | {e['crba']:.1e} | {e['rnea']:.1e} | {e['aba']:.1e} | "
                     f"{'yes' if r['passed'] else '**no**'} |")
    rest = [r for r in recs if not r.get("compared")]
    if rest:
        lines += ["", "Not compared:", "",
                  "| URDF | loaded by | reason |", "| --- | --- | --- |"]
        for r in rest:
            who = ("neither" if not r.get("pinocchio") else
                   "Pinocchio" if not r.get("casmbd") else "both")
            reason = re.sub(r"/\S*/robots/", "", r.get("error", "")).replace("|", "/")
            reason = reason.split(" (principal moments")[0]
            lines.append(f"| {r['robot']} | {who} | {reason} |")
    lines += ["", "Not yet: the same comparison in absolute coordinates (the state and the "
              "accelerations mapped through the joint-coordinate kinematics).", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    from benchmarks.docs import run_study, study_parser

    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--quick", action="store_true", help="two arms (UR5, Panda)")
    parser.add_argument("--timeout", type=float, default=120.0,
                        help="seconds per robot (load, build, compare)")
    parser.add_argument("--mode", default="vm", help="casmbd.compile mode (vm, auto)")
    parser.add_argument("--one", help=argparse_suppress())
    args = parser.parse_args(argv)
    if args.one:
        print(json.dumps(check_robot(args.one, mode=args.mode)))
        return 0
    return run_study(args, RESULTS, lambda: measure(args.quick, args.timeout, args.mode),
                     markdown, DOC, HEAD)


def argparse_suppress():
    import argparse

    return argparse.SUPPRESS


if __name__ == "__main__":
    raise SystemExit(main())
