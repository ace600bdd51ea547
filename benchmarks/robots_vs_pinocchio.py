"""casmbd against Pinocchio on every URDF of ``example-robot-data`` (issues 21 and 34).

Every ``*.urdf`` of the package that ``pinocchio.buildModelFromUrdf`` loads (fixed base, as the
file says) is read by :func:`casmbd.load_urdf` in joint coordinates and compiled by
:func:`casmbd.compile`; at random states (q uniform in [-2, 2] rad or [-0.2, 0.2] m, v and
a uniform in [-2, 2]) the four quantities are compared with Pinocchio's:

* forward kinematics of every link frame: casmbd's body frames (centre of mass of the body
  with its merged fixed links, link axes) against ``oMi · lever`` of the Pinocchio joint's
  inertia and ``oMf`` of the link frame; casmbd's markers (links merged by fixed joints,
  frame-only links) against ``oMf`` of the link — position error in m (≤ 1e-12), rotation
  error max |ΔR| (≤ 1e-12);
* the Jacobian (ṙ, ω) of every such frame against ``getFrameJacobian(…,
  LOCAL_WORLD_ALIGNED)`` moved to the frame's point, max |ΔJ| (entries in m and 1; ≤ 1e-12);
* the mass matrix against ``pin.crba`` (upper triangle mirrored), max |ΔM| / max |M| ≤ 1e-12;
* inverse dynamics against ``pin.rnea``, max |Δτ| / max |τ| ≤ 1e-10;
* forward dynamics against ``pin.aba`` (τ as input), the condition-scaled error
  (max |Δq̈| / max |q̈|) / max(1, κ₂(M) / 10⁶) ≤ 1e-9 (:func:`condition_scaled`; the raw
  relative error and κ₂(M) are recorded too).

Then the same robot in absolute coordinates (``check_absolute``: the state mapped from the
joint coordinates; frames, Tᵀ M_a T against ``crba``, body accelerations of the KKT forward
dynamics against Pinocchio's after ``aba``; ``--coordinates joint`` skips it).  With
``--base floating`` (``check_floating``) the robot on a free-flyer base too:
``load_urdf(path, floating_base=True)`` against ``JointModelFreeFlyer`` in joint coordinates
(and absolute ones, the state mapped the same way), recorded as "not available" where this
casmbd's ``load_urdf`` has no ``floating_base``.

Joints are matched by name (casmbd's coordinate ``joint.angle`` ↔ Pinocchio's
``model.names``); a continuous joint is (cos θ, sin θ) in Pinocchio's q (nq = 2, nv = 1).
Each robot runs in its own process with a time limit (``--timeout``), so a robot casmbd
cannot build in time is recorded as such rather than stopping the sweep.  ``--quick`` checks
two arms (UR5, Panda).  ``<mimic>`` pairs are locked at 0 in both models
(``pinocchio.buildReducedModel``; casmbd's ``locked`` on the leaders).

Robots with ``<mimic>`` pairs are then also compared *coupled* (``check_coupled``): Pinocchio's
``buildModelFromUrdf(path, mimic=True)`` (``JointModelMimic``, θ_f = multiplier θ_l + offset,
no coordinate of its own) against casmbd's gear couplings in joint coordinates (every follower
keeps its tree coordinate, one gear equation each; or, substituted, no coordinate and no
equation: then G = I).  With G the map from the independent
coordinates to casmbd's (q = G q_i + o, from the URDF's multipliers and offsets): the frames,
Gᵀ M G against ``crba``, Gᵀ τ with τ casmbd's least-norm ``inverse_dynamics`` at
(G q_i + o, G v_i, G a_i) (it checks C_q a = γ) against ``rnea``, and the independent part of
casmbd's constrained ``forward_dynamics`` (KKT with the gear equations; τ on the independent
coordinates, 0 on the followers) against M⁻¹ (τ − b) from Pinocchio's ``crba`` and
``nonLinearEffects`` — Pinocchio 4.1's ``aba`` refuses mimic joints ("This algorithm does not
support Joint Mimic type in the model").

Run: ``python -m benchmarks.robots_vs_pinocchio [--quick | --robots PATTERNS]
[--coordinates joint,absolute] [--base fixed,floating] [--update-docs]`` (``--robots
ur5,tiago_dual``: parts of the paths or globs under the package's ``robots/``).  CI runs the
subset of ``tests/peers/test_robots_vs_pinocchio.py``.
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
#: Tolerances of issue 34 (acceptance): frames [m] and rotations, Jacobians (entries in m and
#: 1, absolute), then relative M, τ, and the condition-scaled q̈ (:func:`condition_scaled`).
TOLERANCES = {"fk": 1e-12, "rot": 1e-12, "jac": 1e-12, "crba": 1e-12, "rnea": 1e-10,
              "aba": 1e-9}
#: In absolute coordinates: frames, rotations, C(q_a) of the mapped state, Jacobians J_a T,
#: Tᵀ M_a T, body accelerations (relative, condition-scaled).
ABSOLUTE_TOLERANCES = {"fk": 1e-12, "rot": 1e-12, "C": 1e-12, "jac": 1e-12, "crba": 1e-12,
                       "aba": 1e-9}
#: Condition number of M up to which the q̈ tolerance is the plain relative 1e-9
#: (:func:`condition_scaled`).
KAPPA_REF = 1e6
#: The base options: welded to the ground as the file says, or a free-flyer root.
BASES = ("fixed", "floating")
COORDINATES = ("joint", "absolute")
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
    """The joints of ``<mimic>`` pairs in the URDF file: all of them, and the leaders (a
    ``<mimic>`` naming no joint of the file is left out: :func:`_broken_mimic`)."""
    import xml.etree.ElementTree as ET

    root = ET.parse(str(path)).getroot()
    known = {joint.get("name") for joint in root.iter("joint")}
    names, leaders = set(), set()
    for joint in root.iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None and mimic.get("joint") in known:
            names |= {joint.get("name"), mimic.get("joint")}
            leaders.add(mimic.get("joint"))
    return sorted(names), sorted(leaders)


def _broken_mimic(path) -> dict:
    """The documented option for a file whose ``<mimic>`` names an unknown joint
    (alex_psyonic_hands): ``ignore_mimic`` = those followers, independent joints as in
    Pinocchio's model without ``mimic=True``; {} for a sound file."""
    import xml.etree.ElementTree as ET

    root = ET.parse(str(path)).getroot()
    known = {joint.get("name") for joint in root.iter("joint")}
    broken = sorted(joint.get("name") for joint in root.iter("joint")
                    if joint.find("mimic") is not None
                    and joint.find("mimic").get("joint") not in known)
    return {"ignore_mimic": broken} if broken else {}


def _rel(x, y) -> float:
    return float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300))


def condition_scaled(rel: float, kappa: float) -> float:
    r"""The condition-scaled forward-dynamics error: e = rel / max(1, κ₂(M) / κ_ref).

    ``rel`` is max |q̈ − q̈_Pinocchio| / max |q̈_Pinocchio|, κ₂(M) the 2-norm condition number
    of the mass matrix (Pinocchio's ``crba``) at the state, κ_ref = :data:`KAPPA_REF` = 1e6.
    Solving M q̈ = τ − b by any backward-stable method (casmbd's LDLᵀ, Pinocchio's ABA) leaves
    a relative error of order κ₂(M) ε (ε = 2.2e-16; Higham, *Accuracy and Stability of
    Numerical Algorithms*, 2nd ed., §7.1), so neither side can be held to 1e-9 when κ₂(M) ε
    approaches it.  The test e ≤ 1e-9 is the plain relative 1e-9 for κ₂(M) ≤ 1e6 (where
    κ₂ ε ≤ 2.2e-10) and rel ≤ 1e-9 κ₂(M) / 1e6 ≈ 4.5 κ₂(M) ε beyond it."""
    return float(rel / max(1.0, kappa / KAPPA_REF))


def _aba_error(worst: dict, rel: float, kappa: float) -> None:
    """Record one state's q̈ error: the condition-scaled ``aba``, the raw ``aba_rel`` and the
    largest κ₂(M) ``cond`` (``worst`` keeps the largest of each)."""
    worst["aba"] = max(worst["aba"], condition_scaled(rel, kappa))
    worst["aba_rel"] = max(worst.get("aba_rel", 0.0), rel)
    worst["cond"] = max(worst.get("cond", 0.0), float(kappa))


def _split(worst: dict, tolerances: dict) -> dict:
    """The record fields of ``worst``: errors (the compared quantities), the raw q̈ error and
    κ₂(M), pass/fail."""
    extra = {k: worst.pop(k) for k in ("aba_rel", "cond") if k in worst}
    return {"errors": worst, **extra,
            "passed": all(worst[k] <= tol for k, tol in tolerances.items())}


def _mass(pm, data, qp) -> np.ndarray:
    """Pinocchio's full symmetric mass matrix (``crba`` fills the upper triangle)."""
    import pinocchio as pin

    m = pin.crba(pm, data, qp)
    return np.triu(m) + np.triu(m, 1).T


def check_robot(path: str | Path, states: int = 3, seed: int = 0, mode: str = "vm",
                absolute: bool = False, bases: tuple[str, ...] = ("fixed",)) -> dict:
    """Load ``path`` with Pinocchio and casmbd (joint coordinates) and compare at ``states``
    random states; returns the record (errors, pass/fail or the named error).  With
    ``absolute`` the absolute-coordinate comparison too (``rec["absolute"]``); with
    ``"floating"`` in ``bases`` the free-flyer comparison (``rec["floating"]``, one record per
    coordinate set; also for a file whose fixed-base model casmbd refuses, such as a bare
    quadrotor).  The fixed-base joint-coordinate comparison always runs: the absolute one maps
    its states from it."""
    rec = _check_fixed(path, states, seed, mode, absolute)
    if "floating" in bases and rec.get("pinocchio"):
        print(json.dumps(rec), flush=True)  # the fixed-base record, should time run out
        _, leaders = _mimic_joints(path)
        rec["floating"] = {c: check_floating(path, leaders, c, states, seed, mode)
                           for c in (("joint", "absolute") if absolute else ("joint",))}
    return rec


def _check_fixed(path, states: int, seed: int, mode: str, absolute: bool) -> dict:
    """The fixed-base part of :func:`check_robot`."""
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
    rec.update(_broken_mimic(path))  # the documented option the file needs, recorded
    rec.update(pinocchio=True, nv=int(pm.nv), njoints=int(pm.njoints - 1),
               joint_types=sorted({j.shortname() for j in pm.joints[1:]}))
    import casmbd

    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mech = casmbd.load_urdf(path, locked=dict.fromkeys(leaders, 0.0),
                                    **_broken_mimic(path))
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
        _jacobian_errors(worst, ours, pm, data, qp,
                         lambda frame, q=q: ours.jacobian(q, frame)[:, perm])
        m_pin = _mass(pm, data, qp)
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["crba"] = max(worst["crba"], _rel(ours.mass_matrix(q)[np.ix_(perm, perm)], m_pin))
        worst["rnea"] = max(worst["rnea"], _rel(ours.inverse_dynamics(q, v, a)[perm], tau))
        tau_ours = np.empty(ours.nq)
        tau_ours[perm] = tau
        _aba_error(worst, _rel(ours.forward_dynamics(q, v, tau_ours)[perm],
                               pin.aba(pm, data, qp, vp, tau)), np.linalg.cond(m_pin))
    rec.update(compared=True, frames=worst.pop("frames"), states=states,
               **_split(worst, TOLERANCES))
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
    M, τ and q̈ in the independent coordinates against Pinocchio's mimic model.  casmbd's
    followers either keep their coordinate with one gear equation each, or (a model whose
    coordinates are the independent ones, no constraint equation) are substituted, q_f =
    r q_l + offset, inside the model: then G = I and casmbd's q, v, τ are Pinocchio's."""
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
    substituted = ours.nc == 0 and not set(table) & set(index)
    out["followers"] = "substituted" if substituted else "gear equations"
    if substituted:  # the followers have no coordinate: q = q_i (G = I, o = 0)
        table = {}
    elif ours.nc != len(table) or set(table) - set(index):
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
        _jacobian_errors(worst, ours, pm, data, qp,
                         lambda frame, q=q: (ours.jacobian(q, frame) @ g)[:, perm])
        m_pin = _mass(pm, data, qp)
        m_red = (g.T @ ours.mass_matrix(q) @ g)[np.ix_(perm, perm)]
        worst["crba"] = max(worst["crba"], _rel(m_red, m_pin))
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["rnea"] = max(worst["rnea"], _rel((g.T @ ours.inverse_dynamics(q, v, a))[perm],
                                                tau))
        ref = np.linalg.solve(m_pin, tau - pin.nonLinearEffects(pm, data, qp, vp))
        tau_full = np.zeros(ours.nq)
        tau_full[np.array(free)[perm]] = tau
        qdd = ours.forward_dynamics(q, v, tau_full)
        _aba_error(worst, _rel(qdd[free][perm], ref), np.linalg.cond(m_pin))
    out.update(frames=worst.pop("frames"), **_split(worst, TOLERANCES))
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


def _jacobian_errors(worst: dict, ours, pm, data, qp, jacobian) -> None:
    """Largest |ΔJ| of the frames ``ours`` shares with Pinocchio's link frames, into
    ``worst["jac"]``.  ``jacobian(frame)`` is casmbd's J with its columns in Pinocchio's v
    order; Pinocchio's is ``getFrameJacobian(…, LOCAL_WORLD_ALIGNED)`` of the link frame (the
    velocity of its origin, ω in world axes), moved for a body to its centre of mass
    c (J_c = J_o − [c − o]× J_ω: v_c = v_o + ω × (c − o)), the point of casmbd's body frame."""
    import pinocchio as pin

    pin.computeJointJacobians(pm, data, qp)
    pin.updateFramePlacements(pm, data)
    n_body = len(ours.numeric.body_names)
    frames = {f.name: k for k, f in enumerate(pm.frames) if f.type == pin.FrameType.BODY}
    for i, name in enumerate(ours.frame_names):
        if name not in frames:
            continue
        fid = frames[name]
        ref = pin.getFrameJacobian(pm, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        if i < n_body:
            parent = pm.frames[fid].parentJoint
            d = data.oMi[parent].act(pm.inertias[parent].lever) - data.oMf[fid].translation
            ref = np.vstack([ref[:3] - _skew(d) @ ref[3:], ref[3:]])
        worst["jac"] = max(worst.get("jac", 0.0), float(np.max(np.abs(jacobian(name) - ref))))


def _skew(d: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])


def check_absolute(path, leaders, joint, pm, to_pin, perm, scale, states: int, seed: int,
                   mode: str, sample=None, floating: bool = False) -> dict:
    """The same robot in absolute coordinates (centre of mass and Euler parameters per body).

    The state is mapped from joint coordinates: q_a from the joint model's body frames (a
    body's position coordinates moved to its reference point where that is not the centre of
    mass; checked: C(q_a) = 0), T = ∂q_a/∂q from [J_a; C_q] T = [J; 0] (J, J_a the stacked
    body Jacobians (ṙ, ω) of both models), v_a = T v.  Compared: every frame as above,
    Tᵀ M_a T against ``crba`` and the body accelerations J_a q̈_a (r̈ of the centre of mass,
    ω̇; the Euler-parameter term E(ė) ė is 0; for a body described at a point r other than
    its centre of mass c, plus v_aᵀ (∂²c/∂q_a²) v_a, :func:`_second_derivative`) from the KKT
    forward dynamics with the generalized force Q_a, the least-norm solution of Tᵀ Q_a = τ,
    against Pinocchio's after ``aba``.

    ``sample(rng)`` gives the joint-coordinate state (q, v, τ) (default: q uniform times
    ``scale``, v and τ uniform in [-2, 2]); ``floating`` loads the free-flyer model
    (``floating_base=True``; ``joint`` is then the floating joint-coordinate model)."""
    import warnings

    import pinocchio as pin

    import casmbd
    from casmbd.compiled.model import NumericModel
    from casmbd.system import System

    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            extra = {"floating_base": True} if floating else {}
            mech = casmbd.load_urdf(path, coordinates="absolute", **_broken_mimic(path),
                                    locked=dict.fromkeys(leaders, 0.0), **extra)
            system = System(mech, coordinates="absolute")
            ours = casmbd.compile(system, mode=mode)
            ours.urdf_renamed = getattr(mech, "urdf_renamed", {})  # allegro's link_8.0
            cons = NumericModel(system, ("constraints", "constraint_jacobian"), mode=mode)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}".splitlines()[0][:300]}
    out: dict = {"build_s": round(time.perf_counter() - t0, 3), "nq": int(ours.nq),
                 "nc": int(ours.nc)}
    bodies = list(ours.numeric.body_names)
    if bodies != list(joint.numeric.body_names):
        return {**out, "error": "the bodies differ from the joint-coordinate model's"}
    rows = [joint.frame_names.index(b) for b in bodies]
    arows = [ours.frame_names.index(b) for b in bodies]
    data = pm.createData()
    rng = np.random.default_rng(seed + 1)
    worst = dict.fromkeys(ABSOLUTE_TOLERANCES, 0.0)
    if sample is None:
        def sample(rng):
            return (rng.uniform(-1.0, 1.0, joint.nq) * scale,
                    rng.uniform(-2.0, 2.0, joint.nq), rng.uniform(-2.0, 2.0, joint.nq))
    for _ in range(states):
        q, v, tau = sample(rng)
        pos, rot = joint.forward_kinematics(q)
        qa = np.concatenate([np.r_[pos[k], _euler_parameters(rot[k])] for k in rows])
        # a body whose coordinates are a reference point r other than its centre of mass c
        # (a floating root: its link frame's origin): c = r + A(e) s' is affine in r, so one
        # evaluation at r = c gives the offset (0 for a body described at its centre of mass)
        shift = ours.forward_kinematics(qa)[0][arows] - pos[rows]
        qa.reshape(-1, 7)[:, :3] -= shift
        worst["C"] = max(worst["C"], float(np.max(np.abs(cons.constraints(qa, 0.0)))))
        jac = np.vstack([joint.jacobian(q, b) for b in bodies])
        jac_a = np.vstack([ours.jacobian(qa, b) for b in bodies])
        cq = cons.constraint_jacobian(qa, 0.0).toarray()
        t = np.linalg.lstsq(np.vstack([jac_a, cq]),
                            np.vstack([jac, np.zeros((cq.shape[0], len(v)))]), rcond=None)[0]
        qp, vp = to_pin(q), v[perm]
        _frame_errors(worst, ours, ours.forward_kinematics(qa), pm, data, qp)
        _jacobian_errors(worst, ours, pm, data, qp,
                         lambda frame, qa=qa, t=t: (ours.jacobian(qa, frame) @ t)[:, perm])
        m_pin = _mass(pm, data, qp)
        m_a = (t.T @ ours.mass_matrix(qa) @ t)[np.ix_(perm, perm)]
        worst["crba"] = max(worst["crba"], _rel(m_a, m_pin))
        qdd_a = ours.forward_dynamics(qa, t @ v, np.linalg.lstsq(t.T, tau, rcond=None)[0])
        pin.forwardKinematics(pm, data, qp, vp, pin.aba(pm, data, qp, vp, tau[perm]))
        ref = []
        back = {v: k for k, v in getattr(ours, "urdf_renamed", {}).items()}  # casmbd → URDF
        for b in bodies:
            j = pm.frames[pm.getFrameId(back.get(b, b), pin.FrameType.BODY)].parentJoint
            c, acc, w = pm.inertias[j].lever, data.a[j], data.v[j].angular
            lin = acc.linear + np.cross(acc.angular, c) + np.cross(w, data.v[j].linear
                                                                   + np.cross(w, c))
            ref.append(np.r_[data.oMi[j].rotation @ lin, data.oMi[j].rotation @ acc.angular])
        acc = (jac_a @ qdd_a).reshape(-1, 6)
        moved = np.any(shift != 0.0, axis=1)  # bodies described at a point r ≠ c
        if moved.any():  # their J̇_a v_a = v_aᵀ (∂²c/∂q_a²) v_a, ≠ 0
            acc[moved, :3] += _second_derivative(ours, qa, t @ v, np.array(arows)[moved])
        _aba_error(worst, _rel(acc.ravel(), np.concatenate(ref)), np.linalg.cond(m_pin))
    out.update(frames=worst.pop("frames"), **_split(worst, ABSOLUTE_TOLERANCES))
    return out


def _floating_available() -> bool:
    """Whether this casmbd's :func:`casmbd.load_urdf` has the ``floating_base`` option."""
    import inspect

    import casmbd

    return "floating_base" in inspect.signature(casmbd.load_urdf).parameters


def check_floating(path, leaders, coordinates: str, states: int, seed: int,
                   mode: str) -> dict:
    """The robot on a free-flyer base: ``casmbd.load_urdf(path, floating_base=True)`` against
    ``pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())``.

    casmbd's base coordinates are taken as documented by ``load_urdf``: the root link frame's
    origin, then its unit quaternion [w, x, y, z], before the joint coordinates (Pinocchio's
    q: origin, [x, y, z, w]).  The velocity convention is not assumed: with A, B the blocks of
    the root link's Jacobian (ṙ, ω) on the six base velocities of casmbd and Pinocchio (whose
    free-flyer velocity is (v, ω) in the root frame), v_Pin = T v with T = B⁻¹ A on the base
    and the identity on the joints.  Compared: every frame, J T against casmbd's J, Tᵀ M_Pin T
    against M; where T is the identity (to 1e-12, Pinocchio's convention) also τ against
    ``rnea`` and q̈ against ``aba``, else τ and q̈ are not compared (they need Ṫ v).  In
    absolute coordinates: the frames and C(q_a) of the mapped state, the Jacobians and
    Tᵀ M_a T through the joint-coordinate floating model as in :func:`check_absolute`."""
    import warnings

    import pinocchio as pin

    import casmbd

    if not _floating_available():
        return {"error": "not available: casmbd.load_urdf has no floating_base option here"}
    try:
        pm = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
        mimic, _ = _mimic_joints(path)
        if mimic:
            ids = sorted({pm.getJointId(n) for n in mimic if pm.existJointName(n)})
            pm = pin.buildReducedModel(pm, ids, pin.neutral(pm))
    except Exception as exc:
        return {"error": f"Pinocchio (free-flyer): {exc}".splitlines()[0][:200]}
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mech = casmbd.load_urdf(path, floating_base=True, **_broken_mimic(path),
                                    locked=dict.fromkeys(leaders, 0.0))
            ours = casmbd.compile(mech, mode=mode)
            ours.urdf_renamed = getattr(mech, "urdf_renamed", {})  # allegro's link_8.0
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}".splitlines()[0][:300]}
    nv = int(getattr(ours, "nv", ours.nq))
    out: dict = {"build_s": round(time.perf_counter() - t0, 3), "nq": int(ours.nq), "nv": nv,
                 "nc": int(ours.nc)}
    names = [n.rpartition(".")[0] or n for n in ours.coordinate_names]
    renamed = getattr(mech, "urdf_renamed", {})  # URDF → casmbd names (allegro's joint_0.0)
    pin_names = {renamed.get(pm.names[j], pm.names[j]): j for j in range(2, pm.njoints)}
    base = [k for k, n in enumerate(names) if n not in pin_names]
    if base != list(range(7)) or nv != ours.nq - 1 or ours.nc:
        return {**out, "error": f"unexpected layout: base coordinates {base} (expected the "
                "first 7), n_v = n_q − 1 and no constraint equations expected"}
    joints = sorted((pm.joints[j].idx_v, j) for j in pin_names.values())
    index = {n: k for k, n in enumerate(names)}
    # casmbd q index of each Pinocchio joint
    jq = [index[renamed.get(pm.names[j], pm.names[j])] for _, j in joints]
    kinds = [pm.joints[j].nq for _, j in joints]
    perm = np.r_[0:6, np.array(jq, dtype=int) - 1]  # casmbd v index per Pinocchio v index

    def to_pin(q):
        return np.concatenate([q[:3], q[[4, 5, 6, 3]]] + [
            [np.cos(q[k]), np.sin(q[k])] if n == 2 else [q[k]] for k, n in zip(jq, kinds)])
    root = pm.frames[[f.parentJoint == 1 and f.type == pin.FrameType.BODY
                      for f in pm.frames].index(True)].name
    data = pm.createData()
    rng = np.random.default_rng(seed + 3)
    worst = dict.fromkeys(TOLERANCES, 0.0)
    worst["T"] = 0.0
    samples = []  # the states, for the absolute coordinates
    for _ in range(states):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        q = np.r_[rng.uniform(-1.0, 1.0, 3), quat, rng.uniform(-2.0, 2.0, ours.nq - 7)]
        v, a = rng.uniform(-2.0, 2.0, nv), rng.uniform(-2.0, 2.0, nv)
        qp = to_pin(q)
        pin.computeJointJacobians(pm, data, qp)
        pin.updateFramePlacements(pm, data)
        fid = pm.getFrameId(root, pin.FrameType.BODY)
        centre = data.oMi[1].act(pm.inertias[1].lever) - data.oMf[fid].translation
        j_pin = pin.getFrameJacobian(pm, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        j_pin = np.vstack([j_pin[:3] - _skew(centre) @ j_pin[3:], j_pin[3:]])
        t = np.eye(nv)
        t[:6, :6] = np.linalg.solve(j_pin[:, :6], ours.jacobian(q, root)[:, :6])
        worst["T"] = max(worst["T"], float(np.max(np.abs(t - np.eye(nv)))))
        samples.append((q, v, rng.uniform(-2.0, 2.0, nv)))
        tp = t[np.ix_(perm, perm)]
        fk = ours.forward_kinematics(q)
        _frame_errors(worst, ours, fk, pm, data, qp)
        _jacobian_errors(worst, ours, pm, data, qp,
                         lambda frame, q=q: ours.jacobian(q, frame)[:, perm])
        m_pin = _mass(pm, data, qp)
        m_ours = ours.mass_matrix(q)[np.ix_(perm, perm)]
        worst["crba"] = max(worst["crba"], _rel(m_ours, tp.T @ m_pin @ tp))
        if worst["T"] > 1e-12:
            continue
        vp, ap = v[perm], a[perm]
        tau = pin.rnea(pm, data, qp, vp, ap)
        worst["rnea"] = max(worst["rnea"], _rel(ours.inverse_dynamics(q, v, a)[perm], tau))
        tau_ours = np.empty(nv)
        tau_ours[perm] = tau
        _aba_error(worst, _rel(ours.forward_dynamics(q, v, tau_ours)[perm],
                               pin.aba(pm, data, qp, vp, tau)), np.linalg.cond(m_pin))
    out["frames"] = worst.pop("frames")
    if worst["T"] > 1e-12:
        out["note"] = ("the base velocity is not Pinocchio's (v, ω) in the root frame: "
                       "τ and q̈ not compared")
        worst.pop("rnea"), worst.pop("aba")
    out.update(_split(worst, {k: v for k, v in TOLERANCES.items() if k in worst}))
    if coordinates == "absolute":
        if "note" in out:
            return {**out, "error": "absolute coordinates not compared: " + out["note"]}
        samples_iter = iter(samples)
        return check_absolute(path, leaders, ours, pm, to_pin, perm, None, states, seed, mode,
                              sample=lambda rng: next(samples_iter), floating=True)
    return out


def _second_derivative(ours, qa: np.ndarray, va: np.ndarray, frames) -> np.ndarray:
    """d²/ds² c(q_a + s v_a) at s = 0 of the points of ``frames`` (casmbd's forward
    kinematics): the central second difference, Richardson-extrapolated from h = 1e-2 and
    5e-3 (error O(h⁴); exact where c is quadratic in q_a, as r + A(e) s' with casmbd's
    Euler-parameter A(e); rounding ≈ ε |c| / h² ≈ 1e-11)."""
    def point(s):
        return ours.forward_kinematics(qa + s * va)[0][frames]

    def second(h):
        return (point(h) - 2.0 * point(0.0) + point(-h)) / h ** 2
    return (4.0 * second(5e-3) - second(1e-2)) / 3.0


def _euler_parameters(rot: np.ndarray) -> np.ndarray:
    """(e0, e1, e2, e3), scalar first, of the rotation matrix ``rot``."""
    import pinocchio as pin

    quat = pin.Quaternion(np.asarray(rot))
    return np.array([quat.w, quat.x, quat.y, quat.z])


def _in_process(path: Path, timeout: float, mode: str, absolute: bool,
                bases: tuple[str, ...] = ("fixed",)) -> dict:
    """:func:`check_robot` in a subprocess; after ``timeout`` s the last record it printed
    (the joint-coordinate one) with the parts not done marked as timed out."""
    cmd = [sys.executable, "-m", "benchmarks.robots_vs_pinocchio", "--one", str(path),
           "--mode", mode, "--coordinates", "joint,absolute" if absolute else "joint",
           "--base", ",".join(bases)]
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
    missing = {"error": late if code is None else stderr.strip()[-300:]}
    if absolute and rec.get("compared") and "absolute" not in rec:
        rec["absolute"] = missing
    if "floating" in bases and rec.get("pinocchio") and "floating" not in rec:
        rec["floating"] = {"joint": missing}
    return rec


def select(root: Path, robots: str | None) -> list[Path]:
    """The URDF files under ``root`` named by ``robots``: comma-separated patterns, each a
    glob (``ur_description/*``) or a part of the path relative to ``root`` (``tiago_dual``);
    every file without ``robots``."""
    import fnmatch

    paths = sorted(root.rglob("*.urdf"))
    if not robots:
        return paths
    patterns = [p.strip() for p in robots.split(",") if p.strip()]
    chosen = [p for p in paths if any(
        fnmatch.fnmatch(str(p.relative_to(root)), pat) or pat in str(p.relative_to(root))
        for pat in patterns)]
    if not chosen:
        raise SystemExit(f"--robots {robots!r}: no URDF file of {root} matches")
    return chosen


def measure(quick: bool = False, timeout: float = 120.0, mode: str = "vm",
            absolute: bool = True, robots: str | None = None,
            bases: tuple[str, ...] = ("fixed",)) -> dict:
    """Run every robot (or the :data:`QUICK` two, or those of ``robots``) in its own process;
    the records, with paths relative to the package's ``robots`` folder."""
    import pinocchio as pin

    root = robots_dir()
    if root is None:
        raise SystemExit("example-robot-data is not installed (pip install example-robot-data)")
    paths = [root / p for p in QUICK] if quick else select(root, robots)
    records = []
    for path in paths:
        t0 = time.perf_counter()
        rec = _in_process(path, timeout, mode, absolute, bases)
        rec["robot"] = str(path.relative_to(root))
        rec["wall_s"] = round(time.perf_counter() - t0, 2)
        print(json.dumps(rec), file=sys.stderr)
        records.append(rec)
    return {"pinocchio_version": pin.__version__, "mode": mode, "tolerances": TOLERANCES,
            "absolute_tolerances": ABSOLUTE_TOLERANCES, "kappa_ref": KAPPA_REF,
            "coordinates": ["joint", "absolute"] if absolute else ["joint"],
            "bases": list(bases), "selection": "quick" if quick else robots or "all",
            "robots": records}


def markdown(data: dict) -> str:
    """The docs/robots.md section: one row per URDF file."""
    recs = data["robots"]
    compared = [r for r in recs if r.get("compared")]
    passed = [r for r in compared if r.get("passed")]
    command = "python -m benchmarks.robots_vs_pinocchio --update-docs"
    if data.get("selection", "all") == "quick":
        command += " --quick"
    elif data.get("selection", "all") != "all":
        command += f" --robots '{data['selection']}'"
    if "coordinates" in data:
        command += f" --coordinates {','.join(data['coordinates'])}"
    if "bases" in data:
        command += f" --base {','.join(data['bases'])}"
    lines = [HEAD, "",
             f"`{command}` (Pinocchio "
             f"{data['pinocchio_version']}, casmbd mode `{data['mode']}`; raw records in "
             "benchmarks/results/robots_vs_pinocchio.json). Every URDF file of "
             "`example-robot-data` is read by `pinocchio.buildModelFromUrdf` (fixed base) and "
             "by `casmbd.load_urdf` (joint coordinates; joints matched by name, a continuous "
             "joint as (cos, sin) in Pinocchio's q; `<mimic>` pairs locked at 0 in both, "
             "`pinocchio.buildReducedModel`) and compared at 3 random states: every link frame "
             "(position in m — a body at its centre of mass against `oMi · lever`, a marker at "
             "the link origin `oMf`; rotation max |ΔR| against the link frame's `oMf`, for "
             "bodies and markers alike), every frame's Jacobian (ṙ, ω) against "
             "`getFrameJacobian(…, LOCAL_WORLD_ALIGNED)` moved to the frame's point (max |ΔJ|, "
             "entries in m and 1), M against `crba`, τ against `rnea` (relative to the largest "
             "entry), q̈ against `aba`: the relative error and κ₂(M), the largest over the "
             "states, and the condition-scaled error e = rel / max(1, κ₂(M) / 10⁶) (the plain "
             "relative error up to κ₂(M) = 10⁶, where κ₂ ε ≤ 2.2e-10; beyond it the "
             "tolerance grows as 1e-9 κ₂ / 10⁶ ≈ 4.5 κ₂ ε, the rounding error any backward-"
             "stable solve, Pinocchio's included, is entitled to). Tolerances 1e-12 m, 1e-12, "
             "1e-12, 1e-12, 1e-10, and 1e-9 on e. "
             f"**{len(passed)} of {len(compared)} compared robots pass**; "
             f"{len(recs) - len(compared)} of {len(recs)} files were not compared (reasons "
             "below). CI runs a representative subset (tests/peers/test_robots_vs_pinocchio.py: "
             "UR5, Panda locked and coupled, Solo-12, TIAGo dual; a skip fails there).", "",
             "| URDF | n_v | frames | FK [m] | R | J | M (crba) | τ (rnea) | q̈ rel. | κ₂(M) | "
             "q̈ (aba) e | pass |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in compared:
        e = r["errors"]
        lines.append(f"| {r['robot']} | {r['nv']} | {r['frames']} | {e['fk']:.1e} | "
                     f"{e['rot']:.1e} | {_num(e.get('jac'))} | {e['crba']:.1e} | "
                     f"{e['rnea']:.1e} | {_num(r.get('aba_rel'))} | {_num(r.get('cond'))} | "
                     f"{e['aba']:.1e} | {'yes' if r['passed'] else '**no**'} |")
    with_abs = [r for r in compared if "absolute" in r]
    if with_abs:
        ok = [r for r in with_abs if r["absolute"].get("passed")]
        lines += ["", "**Absolute coordinates** (`coordinates=\"absolute\"`: centre of mass and "
                  "Euler parameters per body, the joints as constraint equations). The state is "
                  "mapped from the joint coordinates: q_a from the body frames (C(q_a) in the "
                  "table), T = ∂q_a/∂q from [J_a; C_q] T = [J; 0] with the stacked body "
                  "Jacobians (ṙ, ω), v_a = T v; compared: every frame, its Jacobian J_a T against "
                  "Pinocchio's, Tᵀ M_a T against `crba`, "
                  "and the body accelerations (r̈ of the centre of mass, ω̇) of the KKT forward "
                  "dynamics under Q_a (least-norm solution of Tᵀ Q_a = τ) against Pinocchio's "
                  "after `aba` (relative, condition-scaled as above; tolerance 1e-9, the "
                  "others 1e-12). Inverse dynamics "
                  "in absolute coordinates gives efforts on the body coordinates (least-norm, "
                  "or on chosen `actuated` coordinates), not joint torques: not compared here. "
                  f"**{len(ok)} of {len(with_abs)} pass.**", "",
                  "| URDF | n_q | n_c | build [s] | C(q_a) | FK [m] | R | J_a T | TᵀMT | "
                  "body acc. e | "
                  "pass |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
                  "---: | --- |"]
        for r in with_abs:
            a = r["absolute"]
            if "errors" not in a:
                err = re.sub(r"/\S*/robots/", "", a.get("error", "")).replace("|", "/")
                lines.append(f"| {r['robot']} | | | | {err[:200]} | | | | | | **no** |")
                continue
            e = a["errors"]
            lines.append(f"| {r['robot']} | {a['nq']} | {a['nc']} | {a['build_s']:.2f} | "
                         f"{e['C']:.1e} | {e['fk']:.1e} | {e['rot']:.1e} | "
                         f"{_num(e.get('jac'))} | {e['crba']:.1e} | "
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
                  "| URDF | couplings | n_q | n_c | frames | FK [m] | R | J G | GᵀMG | Gᵀτ | "
                  "q̈_i e | pass |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
                  "---: | ---: | ---: | --- |"]
        for r in coupled:
            c = r["coupled"]
            if "errors" not in c:
                err = re.sub(r"/\S*/robots/", "", c.get("error", "")).replace("|", "/")
                err = err.replace("<", "&lt;")
                lines.append(f"| {r['robot']} | | | | | {err[:200]} | | | | | | not compared |")
                continue
            e = c["errors"]
            lines.append(f"| {r['robot']} | {len(c['coupled'])} | {c['nq']} | {c['nc']} | "
                         f"{c['frames']} | {e['fk']:.1e} | {e['rot']:.1e} | "
                         f"{_num(e.get('jac'))} | {e['crba']:.1e} | "
                         f"{e['rnea']:.1e} | {e['aba']:.1e} | "
                         f"{'yes' if c['passed'] else '**no**'} |")
    floating = [r for r in recs if "floating" in r]
    if floating:
        lines += _floating_section(floating)
    elif "floating" not in data.get("bases", ["fixed"]):
        lines += ["", "**Floating base**: not part of this run (`--base fixed,floating` compares "
                  "`load_urdf(path, floating_base=True)` with Pinocchio's `JointModelFreeFlyer`; "
                  "with a casmbd whose `load_urdf` has no `floating_base` the rows say \"not "
                  "available\")."]
    rest = [r for r in recs if not r.get("compared")]
    if rest:
        lines += ["", "Not compared (fixed base):", "",
                  "| URDF | loaded by | reason |", "| --- | --- | --- |"]
        for r in rest:
            who = ("neither" if not r.get("pinocchio") else
                   "Pinocchio" if not r.get("casmbd") else "both")
            reason = re.sub(r"/\S*/robots/", "", r.get("error", "")).replace("|", "/")
            reason = reason.split(" (principal moments")[0].replace("<", "&lt;")
            lines.append(f"| {r['robot']} | {who} | {reason} |")
    lines += ["", ""]  # a blank line before the next section
    return "\n".join(lines)


def _choices(text: str, allowed: tuple[str, ...], option: str) -> tuple[str, ...]:
    got = tuple(dict.fromkeys(t.strip() for t in text.split(",") if t.strip()))
    bad = [t for t in got if t not in allowed]
    if bad or not got:
        raise SystemExit(f"{option} {text!r}: a comma-separated list of {', '.join(allowed)}")
    return got


def _num(x) -> str:
    return "" if x is None else f"{x:.1e}"


def _floating_section(records: list[dict]) -> list[str]:
    """The free-flyer rows of :func:`markdown` (one per robot and coordinate set)."""
    rows, done, good = [], 0, 0
    for r in records:
        for coords, f in r["floating"].items():
            if "errors" not in f:
                err = re.sub(r"/\S*/robots/", "", f.get("error", "")).replace("|", "/")
                rows.append(f"| {r['robot']} | {coords} | | | {err[:200]} | | | | | | | |")
                continue
            done += 1
            good += bool(f["passed"])
            e = f["errors"]
            rows.append(f"| {r['robot']} | {coords} | {f['nq']} | {f.get('nv', f['nq'])} | "
                        f"{_num(e.get('T'))} | {_num(e.get('C'))} | {e['fk']:.1e} | "
                        f"{e['rot']:.1e} | {_num(e.get('jac'))} | {e['crba']:.1e} | "
                        f"{_num(e.get('rnea'))} | {_num(e.get('aba'))} | "
                        f"{'yes' if f['passed'] else '**no**'} |")
    return ["", "**Floating base** (`casmbd.load_urdf(path, floating_base=True)` against "
            "`buildModelFromUrdf(path, JointModelFreeFlyer())`; casmbd's base coordinates "
            "the root link frame's origin and unit quaternion [w, x, y, z], Pinocchio's "
            "[x, y, z, w]). The velocity convention is measured, not assumed: T maps casmbd's "
            "six base velocities to Pinocchio's (v, ω) in the root frame through the root "
            "link's Jacobian (column T: max |T − I|; where it is not the identity, only the "
            "frames, J T and Tᵀ M T are compared). In absolute coordinates the state is "
            "mapped from the floating joint-coordinate model as above. "
            f"**{good} of {done} compared pass.**", "",
            "| URDF | coordinates | n_q | n_v | T | C(q_a) | FK [m] | R | J | M | τ | q̈ e | "
            "pass |",
            "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
            "--- |", *rows]


def main(argv=None) -> int:
    from benchmarks.docs import run_study, study_parser

    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--quick", action="store_true", help="two arms (UR5, Panda)")
    parser.add_argument("--robots", help="comma-separated globs or parts of the paths under "
                        "example-robot-data's robots/ (default: every URDF file)")
    parser.add_argument("--coordinates", default="joint,absolute",
                        help="joint, absolute or joint,absolute (default); the joint "
                             "coordinates are always built (the others map their states)")
    parser.add_argument("--base", default="fixed,floating",
                        help="fixed, floating or fixed,floating (default); floating needs "
                             "load_urdf(..., floating_base=True), else recorded as not "
                             "available")
    parser.add_argument("--timeout", type=float, default=120.0,
                        help="seconds per robot (load, build, compare)")
    parser.add_argument("--mode", default="vm", help="casmbd.compile mode (vm, auto)")
    parser.add_argument("--joint-only", action="store_true",
                        help="the same as --coordinates joint")
    parser.add_argument("--one", help=argparse_suppress())
    args = parser.parse_args(argv)
    coordinates = ("joint",) if args.joint_only else _choices(args.coordinates, COORDINATES,
                                                              "--coordinates")
    bases = _choices(args.base, BASES, "--base")
    absolute = "absolute" in coordinates
    if args.one:
        print(json.dumps(check_robot(args.one, mode=args.mode, absolute=absolute,
                                     bases=bases)))
        return 0
    return run_study(args, RESULTS, lambda: measure(args.quick, args.timeout, args.mode,
                                                      absolute, args.robots, bases),
                     markdown, DOC, HEAD)


def argparse_suppress():
    import argparse

    return argparse.SUPPRESS


if __name__ == "__main__":
    raise SystemExit(main())
