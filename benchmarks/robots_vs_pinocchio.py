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

Then the same robot in absolute coordinates (``check_absolute``: the state mapped from the
joint coordinates; frames, Tᵀ M_a T against ``crba``, body accelerations of the KKT forward
dynamics against Pinocchio's after ``aba``; ``--joint-only`` skips it).

Joints are matched by name (casmbd's coordinate ``joint.angle`` ↔ Pinocchio's
``model.names``); a continuous joint is (cos θ, sin θ) in Pinocchio's q (nq = 2, nv = 1).
Each robot runs in its own process with a time limit (``--timeout``), so a robot casmbd
cannot build in time is recorded as such rather than stopping the sweep.  ``--quick`` checks
two arms (UR5, Panda).  ``<mimic>`` pairs are locked at 0 in both models
(``pinocchio.buildReducedModel``; casmbd's ``locked`` on the leaders).

Robots with ``<mimic>`` pairs are then also compared *coupled* (``check_coupled``): Pinocchio's
``buildModelFromUrdf(path, mimic=True)`` (``JointModelMimic``, θ_f = multiplier θ_l + offset,
no coordinate of its own) against casmbd's gear couplings in joint coordinates.  Where casmbd
substitutes the followers (two single-coordinate tree joints: ``casmbd.system.tree``, no
follower coordinate, no gear equation) its q is Pinocchio's independent q (G = I below);
where a gear stays a constraint equation, every follower keeps its tree coordinate, and
with G the map from the independent
coordinates to casmbd's (q = G q_i + o, from the URDF's multipliers and offsets): the frames,
Gᵀ M G against ``crba``, Gᵀ τ with τ casmbd's least-norm ``inverse_dynamics`` at
(G q_i + o, G v_i, G a_i) (it checks C_q a = γ) against ``rnea``, and the independent part of
casmbd's constrained ``forward_dynamics`` (KKT with the gear equations; τ on the independent
coordinates, 0 on the followers) against M⁻¹ (τ − b) from Pinocchio's ``crba`` and
``nonLinearEffects`` — Pinocchio 4.1's ``aba`` refuses mimic joints ("This algorithm does not
support Joint Mimic type in the model").

Run: ``python -m benchmarks.robots_vs_pinocchio [--quick] [--joint-only] [--update-docs]``.
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
#: In absolute coordinates: frames, rotations, C(q_a) of the mapped state, Tᵀ M_a T, body
#: accelerations (relative).
ABSOLUTE_TOLERANCES = {"fk": 1e-12, "rot": 1e-12, "C": 1e-12, "crba": 1e-12, "aba": 1e-9}
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


def _pin_configuration(pm, names: list[str], renamed: dict | None = None):
    """q ↦ Pinocchio's q and the permutation casmbd → Pinocchio for v, a, τ (``renamed``:
    URDF → casmbd names of the reserved ones, ``Mechanism.urdf_renamed``)."""
    index = {name.rpartition(".")[0] or name: k for k, name in enumerate(names)}
    pin_names = [(renamed or {}).get(n, n) for n in pm.names]
    missing = [pin_names[j] for j in range(1, pm.njoints) if pin_names[j] not in index]
    if missing or pm.njoints - 1 != len(names):
        raise KeyError(f"joints differ: Pinocchio-only {missing}, casmbd {names}")
    order = [(index[pin_names[j]], pm.joints[j].nq) for j in range(1, pm.njoints)]

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


def check_robot(path: str | Path, states: int = 3, seed: int = 0, mode: str = "vm",
                absolute: bool = False) -> dict:
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
            ours.urdf_renamed = getattr(mech, "urdf_renamed", {})  # allegro's link_8.0
    except Exception as exc:
        rec.update(casmbd=False, error=f"{type(exc).__name__}: {exc}".splitlines()[0][:300])
        return rec
    rec.update(casmbd=True, build_s=round(time.perf_counter() - t0, 3), nc=int(ours.nc))
    if ours.nc:
        rec.update(compared=False, error=f"{ours.nc} constraint equations in joint coordinates "
                   "(mimic coupling or closed chain): M, τ are not Pinocchio's")
        return rec
    try:
        to_pin, perm = _pin_configuration(pm, list(ours.coordinate_names), ours.urdf_renamed)
    except KeyError as exc:
        rec.update(compared=False, error=str(exc)[:300])
        return rec
    prismatic = np.array(["Prismatic" in pm.joints[j].shortname()
                          for j in range(1, pm.njoints)])
    scale = np.where(prismatic[np.argsort(perm)], 0.2, 2.0)
    data = pm.createData()
    rng = np.random.default_rng(seed)
    worst = dict.fromkeys(TOLERANCES, 0.0)
    for _ in range(states):
        q = rng.uniform(-1.0, 1.0, ours.nq) * scale
        v, a = rng.uniform(-2.0, 2.0, ours.nq), rng.uniform(-2.0, 2.0, ours.nq)
        qp, vp, ap = to_pin(q), v[perm], a[perm]
        _frame_errors(worst, ours, ours.forward_kinematics(q), pm, data, qp)
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["crba"] = max(worst["crba"], _rel(ours.mass_matrix(q)[np.ix_(perm, perm)], m_pin))
        worst["rnea"] = max(worst["rnea"], _rel(ours.inverse_dynamics(q, v, a)[perm], tau))
        tau_ours = np.empty(ours.nq)
        tau_ours[perm] = tau
        worst["aba"] = max(worst["aba"], _rel(ours.forward_dynamics(q, v, tau_ours)[perm],
                                              pin.aba(pm, data, qp, vp, tau)))
    rec.update(compared=True, frames=worst.pop("frames"), states=states, errors=worst,
               passed=all(worst[k] <= tol for k, tol in TOLERANCES.items()))
    if mimic:
        rec["coupled"] = check_coupled(path, states, seed, mode)
    if absolute:
        print(json.dumps(rec), flush=True)  # the joint-coordinate record, should time run out
        rec["absolute"] = check_absolute(path, leaders, ours, pm, to_pin, perm, scale,
                                         states, seed, mode)
    return rec


def _mimic_table(path) -> dict[str, tuple[str, float, float]]:
    """Follower → (leader, multiplier, offset) of the URDF's ``<mimic>`` elements."""
    import xml.etree.ElementTree as ET

    out = {}
    for joint in ET.parse(str(path)).getroot().iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            out[joint.get("name")] = (mimic.get("joint"),
                                      float(mimic.get("multiplier", "1")),
                                      float(mimic.get("offset", "0")))
    return out


def check_coupled(path, states: int, seed: int, mode: str) -> dict:
    """The robot with its ``<mimic>`` pairs coupled (module docstring): errors of the frames,
    M, τ and q̈ in the independent coordinates against Pinocchio's mimic model."""
    import warnings

    import pinocchio as pin

    import casmbd

    try:
        pm = pin.buildModelFromUrdf(str(path), mimic=True)
    except Exception as exc:
        return {"error": f"Pinocchio (mimic=True): {exc}".splitlines()[0][:200]}
    pin_mimic = {pm.names[j] for j in range(1, pm.njoints)
                 if "Mimic" in pm.joints[j].shortname()}
    if not pin_mimic:
        return {"error": "no coupling left in Pinocchio's model (its mimic joints are fixed)"}
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ours = casmbd.compile(casmbd.load_urdf(path), mode=mode)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}".splitlines()[0][:300]}
    out: dict = {"build_s": round(time.perf_counter() - t0, 3), "nq": int(ours.nq),
                 "nc": int(ours.nc), "coupled": sorted(pin_mimic)}
    table = {f: m for f, m in _mimic_table(path).items() if f in pin_mimic}
    names = [n.rpartition(".")[0] or n for n in ours.coordinate_names]
    index = {n: k for k, n in enumerate(names)}
    free = [k for k, n in enumerate(names) if n not in table]
    # joint coordinates substitute the followers (casmbd.system.tree): no follower coordinate,
    # no gear equation, q is already independent (G = I); else every follower keeps its own
    substituted = not set(table) & set(index)
    out["substituted"] = substituted
    if (ours.nc != (0 if substituted else len(table))
            or (not substituted and set(table) - set(index))):
        return {**out, "error": f"{ours.nc} constraint equations for {len(table)} couplings"}
    g, o = np.zeros((ours.nq, len(free))), np.zeros(ours.nq)
    g[free, range(len(free))] = 1.0

    def resolve(name):  # row of G and offset of a joint (a follower of a follower too)
        if name not in table:
            return g[index[name]], o[index[name]]
        leader, ratio, offset = table[name]
        row, off = resolve(leader)
        return ratio * row, ratio * off + offset
    for name in table if not substituted else ():
        g[index[name]], o[index[name]] = resolve(name)
    joints = sorted((pm.joints[j].idx_q, j) for j in range(1, pm.njoints)
                    if pm.joints[j].nq > 0)
    if len(joints) != len(free) or any(pm.names[j] not in index for _, j in joints):
        return {**out, "error": "the independent joints differ from Pinocchio's"}
    order = [(free.index(index[pm.names[j]]), pm.joints[j].nq) for _, j in joints]
    perm = np.array([k for k, _ in order])

    def to_pin(qi):
        return np.concatenate([[np.cos(qi[k]), np.sin(qi[k])] if nq == 2 else [qi[k]]
                               for k, nq in order])
    prismatic = np.array(["Prismatic" in pm.joints[j].shortname()
                          or "JointModelP" in pm.joints[j].shortname() for _, j in joints])
    scale = np.where(prismatic[np.argsort(perm)], 0.2, 2.0)
    data = pm.createData()
    rng = np.random.default_rng(seed + 2)
    worst = dict.fromkeys(TOLERANCES, 0.0)
    for _ in range(states):
        qi = rng.uniform(-1.0, 1.0, len(free)) * scale
        vi, ai = rng.uniform(-2.0, 2.0, len(free)), rng.uniform(-2.0, 2.0, len(free))
        q, v, a = g @ qi + o, g @ vi, g @ ai
        qp, vp, ap = to_pin(qi), vi[perm], ai[perm]
        _frame_errors(worst, ours, ours.forward_kinematics(q), pm, data, qp)
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        m_red = (g.T @ ours.mass_matrix(q) @ g)[np.ix_(perm, perm)]
        worst["crba"] = max(worst["crba"], _rel(m_red, m_pin))
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["rnea"] = max(worst["rnea"], _rel((g.T @ ours.inverse_dynamics(q, v, a))[perm],
                                                tau))
        ref = np.linalg.solve(m_pin, tau - pin.nonLinearEffects(pm, data, qp, vp))
        tau_full = np.zeros(ours.nq)
        tau_full[np.array(free)[perm]] = tau
        qdd = ours.forward_dynamics(q, v, tau_full)
        worst["aba"] = max(worst["aba"], _rel(qdd[free][perm], ref))
    out.update(frames=worst.pop("frames"), errors=worst,
               passed=all(worst[k] <= tol for k, tol in TOLERANCES.items()))
    return out


def _frame_errors(worst: dict, ours, fk, pm, data, qp) -> None:
    """Largest position and rotation errors of the frames ``ours`` shares with Pinocchio's
    link frames, into ``worst["fk"]``, ``worst["rot"]`` (and their count ``worst["frames"]``)."""
    import pinocchio as pin

    pin.forwardKinematics(pm, data, qp)
    pin.updateFramePlacements(pm, data)
    pos, rot = fk
    n_body = len(ours.numeric.body_names)
    renamed = getattr(ours, "urdf_renamed", {})
    frames = {renamed.get(f.name, f.name): k for k, f in enumerate(pm.frames)
              if f.type == pin.FrameType.BODY}
    shared = [(i, name) for i, name in enumerate(ours.frame_names) if name in frames]
    for i, name in shared:
        frame = pm.frames[frames[name]]
        placement = data.oMf[frames[name]]
        point = (data.oMi[frame.parentJoint].act(pm.inertias[frame.parentJoint].lever)
                 if i < n_body else placement.translation)
        worst["fk"] = max(worst["fk"], float(np.max(np.abs(pos[i] - point))))
        worst["rot"] = max(worst["rot"], float(np.max(np.abs(rot[i] - placement.rotation))))
    worst["frames"] = len(shared)


def check_absolute(path, leaders, joint, pm, to_pin, perm, scale, states: int, seed: int,
                   mode: str) -> dict:
    """The same robot in absolute coordinates (centre of mass and Euler parameters per body).

    The state is mapped from joint coordinates: q_a from the joint model's body frames
    (checked: C(q_a) = 0), T = ∂q_a/∂q from [J_a; C_q] T = [J; 0] (J, J_a the stacked body
    Jacobians (ṙ, ω) of both models), v_a = T v.  Compared: every frame as above, Tᵀ M_a T
    against ``crba`` and the body accelerations J_a q̈_a (r̈ of the centre of mass, ω̇; the
    Euler-parameter term E(ė) ė is 0) from the KKT forward dynamics with the generalized force
    Q_a, the least-norm solution of Tᵀ Q_a = τ, against Pinocchio's after ``aba``."""
    import warnings

    import pinocchio as pin

    import casmbd
    from casmbd.compiled.model import NumericModel
    from casmbd.system import System

    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mech = casmbd.load_urdf(path, coordinates="absolute",
                                    locked=dict.fromkeys(leaders, 0.0))
            system = System(mech, coordinates="absolute")
            ours = casmbd.compile(system, mode=mode)
            cons = NumericModel(system, ("constraints", "constraint_jacobian"), mode=mode)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}".splitlines()[0][:300]}
    out: dict = {"build_s": round(time.perf_counter() - t0, 3), "nq": int(ours.nq),
                 "nc": int(ours.nc)}
    bodies = list(ours.numeric.body_names)
    if bodies != list(joint.numeric.body_names):
        return {**out, "error": "the bodies differ from the joint-coordinate model's"}
    rows = [joint.frame_names.index(b) for b in bodies]
    data = pm.createData()
    rng = np.random.default_rng(seed + 1)
    worst = dict.fromkeys(ABSOLUTE_TOLERANCES, 0.0)
    for _ in range(states):
        q = rng.uniform(-1.0, 1.0, joint.nq) * scale
        v, tau = rng.uniform(-2.0, 2.0, joint.nq), rng.uniform(-2.0, 2.0, joint.nq)
        pos, rot = joint.forward_kinematics(q)
        qa = np.concatenate([np.r_[pos[k], _euler_parameters(rot[k])] for k in rows])
        worst["C"] = max(worst["C"], float(np.max(np.abs(cons.constraints(qa, 0.0)))))
        jac = np.vstack([joint.jacobian(q, b) for b in bodies])
        jac_a = np.vstack([ours.jacobian(qa, b) for b in bodies])
        cq = cons.constraint_jacobian(qa, 0.0).toarray()
        t = np.linalg.lstsq(np.vstack([jac_a, cq]),
                            np.vstack([jac, np.zeros((cq.shape[0], joint.nq))]), rcond=None)[0]
        qp, vp = to_pin(q), v[perm]
        _frame_errors(worst, ours, ours.forward_kinematics(qa), pm, data, qp)
        m_pin = pin.crba(pm, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        m_a = (t.T @ ours.mass_matrix(qa) @ t)[np.ix_(perm, perm)]
        worst["crba"] = max(worst["crba"], _rel(m_a, m_pin))
        qdd_a = ours.forward_dynamics(qa, t @ v, np.linalg.lstsq(t.T, tau, rcond=None)[0])
        pin.forwardKinematics(pm, data, qp, vp, pin.aba(pm, data, qp, vp, tau[perm]))
        ref = []
        for b in bodies:
            j = pm.frames[pm.getFrameId(b, pin.FrameType.BODY)].parentJoint
            c, acc, w = pm.inertias[j].lever, data.a[j], data.v[j].angular
            lin = acc.linear + np.cross(acc.angular, c) + np.cross(w, data.v[j].linear
                                                                   + np.cross(w, c))
            ref.append(np.r_[data.oMi[j].rotation @ lin, data.oMi[j].rotation @ acc.angular])
        worst["aba"] = max(worst["aba"], _rel(jac_a @ qdd_a, np.concatenate(ref)))
    out.update(frames=worst.pop("frames"), errors=worst,
               passed=all(worst[k] <= tol for k, tol in ABSOLUTE_TOLERANCES.items()))
    return out


def _euler_parameters(rot: np.ndarray) -> np.ndarray:
    """(e0, e1, e2, e3), scalar first, of the rotation matrix ``rot``."""
    import pinocchio as pin

    quat = pin.Quaternion(np.asarray(rot))
    return np.array([quat.w, quat.x, quat.y, quat.z])


def _in_process(path: Path, timeout: float, mode: str, absolute: bool) -> dict:
    """:func:`check_robot` in a subprocess; after ``timeout`` s the last record it printed
    (the joint-coordinate one) with the absolute-coordinate part marked as timed out."""
    cmd = [sys.executable, "-m", "benchmarks.robots_vs_pinocchio", "--one", str(path),
           "--mode", mode] + (["--absolute"] if absolute else [])
    root = Path(__file__).resolve().parent.parent
    late = f"not done within the time limit of {timeout:g} s"
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=root)
        stdout, stderr, code = out.stdout, out.stderr, out.returncode
    except subprocess.TimeoutExpired as exc:
        stdout = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout or ""
        stderr, code = late, None
    lines = [ln for ln in stdout.splitlines() if ln.startswith("{")]
    if not lines:
        tail = (stderr.strip().splitlines() or ["no output"])[-1]
        return {"robot": str(path), "error": f"process failed: {tail[:300]}" if code else late}
    rec = json.loads(lines[-1])
    if absolute and rec.get("compared") and "absolute" not in rec:
        rec["absolute"] = {"error": late if code is None else stderr.strip()[-300:]}
    return rec


def measure(quick: bool = False, timeout: float = 120.0, mode: str = "vm",
            absolute: bool = True) -> dict:
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
        rec = _in_process(path, timeout, mode, absolute)
        rec["robot"] = str(path.relative_to(root))
        rec["wall_s"] = round(time.perf_counter() - t0, 2)
        print(json.dumps(rec), file=sys.stderr)
        records.append(rec)
    return {"pinocchio_version": pin.__version__, "mode": mode, "tolerances": TOLERANCES,
            "absolute_tolerances": ABSOLUTE_TOLERANCES, "robots": records}


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
             "the link origin `oMf`; rotation max |ΔR| against the link frame's `oMf`, for "
             "bodies and markers alike), M against `crba`, τ against "
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
    with_abs = [r for r in compared if "absolute" in r]
    if with_abs:
        ok = [r for r in with_abs if r["absolute"].get("passed")]
        lines += ["", "**Absolute coordinates** (`coordinates=\"absolute\"`: centre of mass and "
                  "Euler parameters per body, the joints as constraint equations). The state is "
                  "mapped from the joint coordinates: q_a from the body frames (C(q_a) in the "
                  "table), T = ∂q_a/∂q from [J_a; C_q] T = [J; 0] with the stacked body "
                  "Jacobians (ṙ, ω), v_a = T v; compared: every frame, Tᵀ M_a T against `crba`, "
                  "and the body accelerations (r̈ of the centre of mass, ω̇) of the KKT forward "
                  "dynamics under Q_a (least-norm solution of Tᵀ Q_a = τ) against Pinocchio's "
                  "after `aba` (relative; tolerance 1e-9, the others 1e-12). Inverse dynamics "
                  "in absolute coordinates gives efforts on the body coordinates (least-norm, "
                  "or on chosen `actuated` coordinates), not joint torques: not compared here. "
                  f"**{len(ok)} of {len(with_abs)} pass.**", "",
                  "| URDF | n_q | n_c | build [s] | C(q_a) | FK [m] | R | TᵀMT | body acc. | "
                  "pass |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
        for r in with_abs:
            a = r["absolute"]
            if "errors" not in a:
                err = re.sub(r"/\S*/robots/", "", a.get("error", "")).replace("|", "/")
                lines.append(f"| {r['robot']} | | | | {err[:200]} | | | | | **no** |")
                continue
            e = a["errors"]
            lines.append(f"| {r['robot']} | {a['nq']} | {a['nc']} | {a['build_s']:.2f} | "
                         f"{e['C']:.1e} | {e['fk']:.1e} | {e['rot']:.1e} | {e['crba']:.1e} | "
                         f"{e['aba']:.1e} | {'yes' if a['passed'] else '**no**'} |")
    coupled = [r for r in compared if "coupled" in r]
    if coupled:
        done = [r for r in coupled if "errors" in r["coupled"]]
        good = [r for r in done if r["coupled"].get("passed")]
        lines += ["", "**Mimic couplings, coupled** (not locked): Pinocchio's "
                  "`buildModelFromUrdf(path, mimic=True)` (`JointModelMimic`: the follower has no "
                  "coordinate, θ_f = multiplier θ_l + offset) against casmbd's gear couplings "
                  "(`<follower>_mimic`) in joint coordinates. A follower casmbd substitutes "
                  "(a revolute or prismatic pair in the tree: no coordinate, no equation, "
                  "n_c = 0 below) is compared directly (G = I); a gear kept as an equation "
                  "keeps the follower's tree coordinate, with G the map of the independent "
                  "coordinates to casmbd's (q = G q_i + o): frames; Gᵀ M G against `crba`; "
                  "Gᵀ τ, τ casmbd's `inverse_dynamics` at (G q_i + o, G v_i, G a_i), against "
                  "`rnea`; the independent accelerations of casmbd's `forward_dynamics` (KKT "
                  "with any gear equations) against M⁻¹ (τ − b) from Pinocchio's `crba` and "
                  "`nonLinearEffects`, because Pinocchio's `aba` refuses mimic joints (\"This "
                  "algorithm does not support Joint Mimic type in the model\"). Same tolerances "
                  f"as above. **{len(good)} of {len(done)} compared robots pass**; "
                  f"{len(coupled) - len(done)} of the {len(coupled)} robots with `<mimic>` "
                  "pairs have no coupled Pinocchio model (reasons in the table).", "",
                  "| URDF | couplings | n_q | n_c | frames | FK [m] | R | GᵀMG | Gᵀτ | q̈_i | "
                  "pass |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
                  "---: | --- |"]
        for r in coupled:
            c = r["coupled"]
            if "errors" not in c:
                err = re.sub(r"/\S*/robots/", "", c.get("error", "")).replace("|", "/")
                err = err.replace("<", "&lt;")
                lines.append(f"| {r['robot']} | | | | | {err[:200]} | | | | | not compared |")
                continue
            e = c["errors"]
            lines.append(f"| {r['robot']} | {len(c['coupled'])} | {c['nq']} | {c['nc']} | "
                         f"{c['frames']} | {e['fk']:.1e} | {e['rot']:.1e} | {e['crba']:.1e} | "
                         f"{e['rnea']:.1e} | {e['aba']:.1e} | "
                         f"{'yes' if c['passed'] else '**no**'} |")
    rest = [r for r in recs if not r.get("compared")]
    if rest:
        lines += ["", "Not compared:", "",
                  "| URDF | loaded by | reason |", "| --- | --- | --- |"]
        for r in rest:
            who = ("neither" if not r.get("pinocchio") else
                   "Pinocchio" if not r.get("casmbd") else "both")
            reason = re.sub(r"/\S*/robots/", "", r.get("error", "")).replace("|", "/")
            reason = reason.split(" (principal moments")[0].replace("<", "&lt;")
            lines.append(f"| {r['robot']} | {who} | {reason} |")
    lines += ["", ""]  # a blank line before the next section
    return "\n".join(lines)


def main(argv=None) -> int:
    from benchmarks.docs import run_study, study_parser

    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--quick", action="store_true", help="two arms (UR5, Panda)")
    parser.add_argument("--timeout", type=float, default=120.0,
                        help="seconds per robot (load, build, compare)")
    parser.add_argument("--mode", default="vm", help="casmbd.compile mode (vm, auto)")
    parser.add_argument("--joint-only", action="store_true",
                        help="no absolute-coordinate comparison")
    parser.add_argument("--absolute", action="store_true", help=argparse_suppress())
    parser.add_argument("--one", help=argparse_suppress())
    args = parser.parse_args(argv)
    if args.one:
        print(json.dumps(check_robot(args.one, mode=args.mode, absolute=args.absolute)))
        return 0
    return run_study(args, RESULTS, lambda: measure(args.quick, args.timeout, args.mode,
                                                      not args.joint_only),
                     markdown, DOC, HEAD)


def argparse_suppress():
    import argparse

    return argparse.SUPPRESS


if __name__ == "__main__":
    raise SystemExit(main())
