"""Peer codes on the work-precision problems: Exudyn and MuJoCo in the same run as casmbd.

Each function runs one peer with one method over a sweep of step sizes or tolerances and
returns rows in the format of :mod:`benchmarks.work_precision` (same keys, so the CSVs can be
merged), with the error measured against the same independent references
(:mod:`benchmarks.references`, nothing of casmbd involved).

Problems (as in :mod:`benchmarks.work_precision`)
    ``chain2``, ``chain8``, ``chain32``: planar chains of 1 m, 1 kg slender rods
    (I = m L²/12 about the centre) pinned end to end, released horizontally at rest,
    g = 9.81 along −y, t ∈ [0, 2]; error = distance of the tip from the reference tip at t = 2.
    ``fourbar``: the unit parallelogram (``examples/parallelogram.toml``), crank vertical at
    +1 rad/s, t ∈ [0, 10]; error = |crank angle(10) − reference| (unwrapped angle).

Peers and methods
    Exudyn (``pip install exudyn``)
        ``exudyn_rigidbody2d / generalized_alpha``: redundant (absolute) coordinates,
        ``NodeRigidBody2D`` + ``ObjectRigidBody2D`` and ``ObjectJointRevolute2D``, Exudyn's
        default implicit generalized-α (index 3, spectral radius 0.9, modified Newton, dense
        LU) over a step-size sweep.  ``exudyn_kinematictree / rk44`` (step sweep) and
        ``/ dopri5`` (tolerance sweep, rtol = atol): minimal coordinates
        (``ObjectKinematicTree``), chains only.  Explicit runs set
        ``computeEndOfStepAccelerations = False`` (Exudyn's documented speed-up; the
        accelerations are output only, the solution is unchanged).
    MuJoCo (``pip install mujoco``)
        Hinge chains built as MJCF strings: ``<inertial>`` mass 1 at the rod centre, diagonal
        inertia (m r²/2, m L²/12, m L²/12) with r = L/20 (only the z entry matters for hinges
        about z), capsule geoms with ``contype = conaffinity = 0``, contacts disabled, no
        damping, no armature; :func:`check_mujoco_model` checks the compiled masses, inertias
        and centres exactly.  ``mujoco / rk4`` and ``mujoco / implicitfast`` over timestep
        sweeps.  The four-bar is the open chain crank-coupler-rocker closed by an equality
        ``connect`` between a site at the rocker's free end and a world site at (1, 0):
        ``mujoco`` rows use MuJoCo's default soft constraint (solref 0.02 1, solimp
        0.9 0.95 0.001), ``mujoco_stiff`` rows the stiffened settings of :data:`STIFF`
        (MuJoCo clamps the time constant to 2 h, so it is 2 h for h > 1e-4).  ``drift`` is the
        connect gap at t = 10, ``drift_max`` the largest gap sampled every 10 ms.

Fair rules (:mod:`benchmarks.fair`)
    ``solve_seconds`` is the integration alone: Exudyn's ``SolveSteps`` (after
    ``InitializeSolver``, reported as ``setup_seconds``), MuJoCo's ``mj_step(model, data,
    nstep)`` (the step loop in C, no Python per step); best of ``repeat`` warm runs,
    the cold first run in ``cold_seconds`` (:func:`benchmarks.fair.timed`).
    ``build_seconds`` is the model construction (Exudyn: items and ``Assemble``; MuJoCo:
    MJCF compilation).  Each method's sweep runs until its error is below 1e-9 or stops
    falling, or a run exceeds the time cap (:func:`benchmarks.fair.sweep`; the reason is in
    ``sweep_stop``); time to error is interpolated log-log (:func:`best_peer_time`).
    Settings at the peers' documented best: MuJoCo's RK4, ``implicitfast`` and ``implicit``
    integrators, constraint solver tolerance 1e-12 (default 1e-8) with 200 iterations on the
    four-bar; Exudyn's generalized-α with Newton tolerances 1e-12 relative / 1e-14 absolute
    (defaults 1e-8 / 1e-10: they floor the error near 1e-8), its explicit RK44 and DOPRI5 on
    the kinematic tree.

Usage
    ``python -m benchmarks.peers [--problems chain2 chain8 ...] [--quick]
    [--csv benchmarks/results/peers.csv]``.  A peer that is not installed is skipped with a
    printed note.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from benchmarks import fair
from benchmarks.references import load_reference

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"

#: ``chain8_3d`` (the spatial chain of :mod:`benchmarks.work_precision`): MuJoCo and
#: Exudyn's kinematic tree are spatial codes, their chain models are the same; Exudyn's
#: RigidBody2D is planar and is not run on it
PROBLEMS = ["chain2", "chain8", "chain32", "fourbar", "chain8_3d"]
GRAVITY = 9.81
LENGTH = 1.0
MASS = 1.0
#: rod inertia about its centre, m L²/12 (the only entry that matters in the plane)
INERTIA = MASS * LENGTH**2 / 12.0
#: radius used for the axial inertia m r²/2 and the capsule geoms of the MuJoCo models
RADIUS = LENGTH / 20.0
T_END = {"chain": 2.0, "fourbar": 10.0}
#: a single run slower than this [s] ends a sweep (``--cap``; :data:`benchmarks.fair.RUN_CAP`)
RUN_CAP = fair.RUN_CAP

#: step sizes / tolerances, coarse to fine: (peer formulation, integrator) -> kind -> levels.
#: The lists go far below what any run reaches: :func:`benchmarks.fair.sweep` stops each
#: sweep at error 1e-9, at the method's floor or at the time cap.
_STEPS2 = fair.refine(1e-2, 2.0, 1e-7)
_STEPS10 = fair.refine(1e-2, 10.0 ** 0.5, 1e-7)
_TOLS = [10.0 ** -k for k in range(4, 15)]
LEVELS = {
    ("exudyn_rigidbody2d", "generalized_alpha"): {"chain": _STEPS10, "fourbar": _STEPS10},
    ("exudyn_kinematictree", "rk44"): {"chain": _STEPS2},
    ("exudyn_kinematictree", "dopri5"): {"chain": _TOLS},
    ("mujoco", "rk4"): {"chain": _STEPS2, "fourbar": _STEPS10},
    ("mujoco", "implicitfast"): {"chain": _STEPS10, "fourbar": _STEPS10},
    ("mujoco", "implicit"): {"chain": _STEPS10, "fourbar": _STEPS10},
    ("mujoco_stiff", "rk4"): {"fourbar": _STEPS10},
    ("mujoco_stiff", "implicitfast"): {"fourbar": _STEPS10},
    ("mujoco_stiff", "implicit"): {"fourbar": _STEPS10},
}
#: the MuJoCo constraint solver at its tightest useful setting (four-bar; default 1e-8, 100)
MUJOCO_SOLVER = {"tolerance": "1e-12", "iterations": "200"}
#: Exudyn's Newton tolerances for generalized-α (defaults 1e-8 relative, 1e-10 absolute)
EXUDYN_NEWTON = {"relativeTolerance": 1e-12, "absoluteTolerance": 1e-14}
#: integrators that take a tolerance (the others a fixed step)
ADAPTIVE = {"dopri5"}
#: stiffened MuJoCo equality settings (time constant 0.2 ms, clamped by MuJoCo to 2 h;
#: impedance 0.9999 at every violation)
STIFF = {"solref": "0.0002 1", "solimp": "0.9999 0.9999 0.001 0.5 2"}

KEYS = ["problem", "coordinates", "formulation", "integrator", "tolerance", "step", "status",
        "solve_seconds", "error", "drift", "velocity_drift", "steps", "rhs_evaluations",
        "setup_seconds", "build_seconds", "nq", "nc", "message", "peer", "peer_version",
        "drift_max", "cold_seconds", "repeats", "load", "sweep_stop"]

LABELS = {
    ("exudyn_rigidbody2d", "generalized_alpha"): "Exudyn RigidBody2D generalized-alpha",
    ("exudyn_kinematictree", "rk44"): "Exudyn KinematicTree RK44",
    ("exudyn_kinematictree", "dopri5"): "Exudyn KinematicTree DOPRI5",
    ("mujoco", "rk4"): "MuJoCo RK4",
    ("mujoco", "implicitfast"): "MuJoCo implicitfast",
    ("mujoco", "implicit"): "MuJoCo implicit",
    ("mujoco_stiff", "rk4"): "MuJoCo RK4, stiffened constraint",
    ("mujoco_stiff", "implicitfast"): "MuJoCo implicitfast, stiffened constraint",
    ("mujoco_stiff", "implicit"): "MuJoCo implicit, stiffened constraint",
}


# --------------------------------------------------------------------------------------------
# Problems and references
# --------------------------------------------------------------------------------------------


def _links(problem: str) -> int:
    """Rods of a chain problem (``chain8`` and ``chain8_3d``: 8)."""
    return int(problem[5:].removesuffix("_3d"))


def _kind(problem: str) -> str:
    if problem.startswith("chain") and problem[5:].removesuffix("_3d").isdigit():
        return "chain"
    if problem == "fourbar":
        return "fourbar"
    raise SystemExit(f"error: unknown problem {problem!r} (known: {', '.join(PROBLEMS)})")


def reference(problem: str) -> np.ndarray | float:
    """Reference tip position at t = 2 (chains) or crank angle at t = 10 (four-bar)."""
    if _kind(problem) == "chain":
        ref = load_reference(f"pendulum_chain_n{_links(problem)}")
        return np.asarray(ref["results"]["tip_position"], dtype=float)
    return float(load_reference("parallelogram_four_bar")["results"]["phi_end"])


def _import(name: str):
    """The module, or None with a printed note when it is not installed."""
    try:
        return __import__(name)
    except ImportError:
        print(f"note: {name} is not installed; its rows are skipped "
              "(pip install casmbd[bench])", file=sys.stderr)
        return None


def _timed(run: Callable[[], tuple[float, dict]], repeat: int) -> dict:
    """:func:`benchmarks.fair.timed`: cold first run apart, best of ``repeat`` warm runs."""
    return fair.timed(run, repeat)


def _row(problem: str, formulation: str, integrator: str, level: float, **values) -> dict:
    adaptive = integrator in ADAPTIVE
    row = {"problem": problem, "formulation": formulation, "integrator": integrator,
           "tolerance": level if adaptive else "", "step": "" if adaptive else level,
           "message": "", "drift": "", "velocity_drift": "", "drift_max": ""}
    row.update(values)
    return row


# --------------------------------------------------------------------------------------------
# Exudyn
# --------------------------------------------------------------------------------------------


def exudyn_rigidbody2d(problem: str):
    """Exudyn system in redundant coordinates: (SystemContainer, mbs, bodies, joints, nodes).

    ``joints`` lists ``(body_a, local_a, body_b, local_b)`` for the constraint gaps (body
    ``None``: the ground, ``local`` then a global point).
    """
    import exudyn as exu
    from exudyn.itemInterface import (
        LoadMassProportional,
        MarkerBodyMass,
        MarkerBodyPosition,
        NodeRigidBody2D,
        ObjectGround,
        ObjectJointRevolute2D,
        ObjectRigidBody2D,
    )

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    ground = mbs.AddObject(ObjectGround(referencePosition=[0.0, 0.0, 0.0]))
    half = 0.5 * LENGTH
    if _kind(problem) == "chain":
        n = _links(problem)
        # rod i: centre ((i + ½) L, 0), angle 0, at rest
        states = [(f"rod{i}", [(i + 0.5) * LENGTH, 0.0, 0.0], [0.0, 0.0, 0.0]) for i in range(n)]
        pins = [(None, [0.0, 0.0, 0.0], "rod0", [-half, 0.0, 0.0])]
        pins += [(f"rod{i - 1}", [half, 0.0, 0.0], f"rod{i}", [-half, 0.0, 0.0])
                 for i in range(1, n)]
    else:
        # examples/parallelogram.toml: crank and rocker vertical (angle π/2, turning at +1 rad/s),
        # coupler horizontal and translating at (−1, 0)
        states = [("crank", [0.0, 0.5, math.pi / 2], [-0.5, 0.0, 1.0]),
                  ("coupler", [0.5, 1.0, 0.0], [-1.0, 0.0, 0.0]),
                  ("rocker", [1.0, 0.5, math.pi / 2], [-0.5, 0.0, 1.0])]
        pins = [(None, [0.0, 0.0, 0.0], "crank", [-half, 0.0, 0.0]),
                ("crank", [half, 0.0, 0.0], "coupler", [-half, 0.0, 0.0]),
                ("coupler", [half, 0.0, 0.0], "rocker", [half, 0.0, 0.0]),
                (None, [LENGTH, 0.0, 0.0], "rocker", [-half, 0.0, 0.0])]
    bodies, nodes = {}, {}
    for name, coords, velocity in states:
        node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=coords,
                                           initialVelocities=velocity))
        body = mbs.AddObject(ObjectRigidBody2D(mass=MASS, inertia=INERTIA, nodeNumber=node))
        mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(MarkerBodyMass(
            bodyNumber=body)), loadVector=[0.0, -GRAVITY, 0.0]))
        bodies[name], nodes[name] = body, node
    joints = []
    for a, pa, b, pb in pins:
        ma = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground if a is None else bodies[a],
                                              localPosition=pa))
        mb = mbs.AddMarker(MarkerBodyPosition(bodyNumber=bodies[b], localPosition=pb))
        mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[ma, mb]))
        joints.append((None if a is None else bodies[a], pa, bodies[b], pb))
    mbs.Assemble()
    return sc, mbs, bodies, joints, nodes


def exudyn_kinematic_tree(n: int):
    """Exudyn ``ObjectKinematicTree`` of the n-rod chain: (SystemContainer, mbs, node).

    Joint i is ``RevoluteZ`` at the end of link i − 1 (offset (L, 0, 0), the first at the
    origin); its coordinate is the relative angle, so the absolute angles are the cumulative
    sums.  Link centre (L/2, 0, 0), inertia diag(m r²/2, m L²/12, m L²/12).
    """
    import exudyn as exu
    from exudyn.itemInterface import NodeGenericODE2, ObjectKinematicTree

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    node = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[0.0] * n,
                                       initialCoordinates=[0.0] * n,
                                       initialCoordinates_t=[0.0] * n,
                                       numberOfODE2Coordinates=n))
    inertia = np.diag([MASS * RADIUS**2 / 2.0, INERTIA, INERTIA])
    mbs.AddObject(ObjectKinematicTree(
        nodeNumber=node, gravity=[0.0, -GRAVITY, 0.0],
        jointTypes=[exu.JointType.RevoluteZ] * n, linkParents=list(range(-1, n - 1)),
        jointTransformations=exu.Matrix3DList([np.eye(3)] * n),
        jointOffsets=exu.Vector3DList([[0.0, 0.0, 0.0]] + [[LENGTH, 0.0, 0.0]] * (n - 1)),
        linkInertiasCOM=exu.Matrix3DList([inertia] * n),
        linkCOMs=exu.Vector3DList([[0.5 * LENGTH, 0.0, 0.0]] * n),
        linkMasses=[MASS] * n))
    mbs.Assemble()
    return sc, mbs, node


def _exudyn_settings(exu, t_end: float, level: float, adaptive: bool, explicit: bool):
    ss = exu.SimulationSettings()
    ti = ss.timeIntegration
    ti.endTime = t_end
    ti.verboseMode = 0
    ss.solution.file.write = False
    ss.solution.sensors.active = False
    if adaptive:
        ti.automaticStepSize = True
        # Exudyn's adaptive controller uses (t_end − t_start) / numberOfSteps as its *maximum*
        # step: 100 capped DOPRI5 on chain2 at 101–109 steps whatever the tolerance.  One
        # step leaves the controller free (h_max = t_end; the first step is its own estimate).
        ti.numberOfSteps = 1
        ti.absoluteTolerance = level
        ti.relativeTolerance = level
        # the automatic first step (initialStepSize 0) is h_max = t_end on the chains at rest:
        # on chain8 and chain32 DOPRI5 then "reached minStepSize" at t = 0 and took one step
        # of 2 s (tip error 11.8, every tolerance; tables before issue 36 counted it as a
        # run).  A first step of 1e-4 s is Exudyn's documented remedy.
        ti.initialStepSize = 1e-4
    else:
        ti.automaticStepSize = False
        ti.numberOfSteps = round(t_end / level)
    if explicit:
        ti.explicit.computeEndOfStepAccelerations = False
    else:
        for key, value in EXUDYN_NEWTON.items():
            setattr(ti.newton, key, value)
    return ss


def _exudyn_gaps(exu, mbs, joints) -> tuple[float, float]:
    """Euclidean norms of the stacked joint position and velocity gaps."""
    pos, vel = [], []
    for a, pa, b, pb in joints:
        def out(body, local, var):
            return np.asarray(mbs.GetObjectOutputBody(body, var, localPosition=local,
                                                      configuration=exu.ConfigurationType.Current))
        xb = out(b, pb, exu.OutputVariableType.Position)
        vb = out(b, pb, exu.OutputVariableType.Velocity)
        xa = np.asarray(pa) if a is None else out(a, pa, exu.OutputVariableType.Position)
        va = np.zeros(3) if a is None else out(a, pa, exu.OutputVariableType.Velocity)
        pos.append(xb[:2] - xa[:2])
        vel.append(vb[:2] - va[:2])
    return float(np.linalg.norm(pos)), float(np.linalg.norm(vel))


def exudyn_generalized_alpha(problem: str, levels=None, repeat: int = 3) -> list[dict]:
    """Exudyn's default generalized-α in redundant coordinates over a step-size sweep."""
    exu = _import("exudyn")
    if exu is None:
        return []
    key = ("exudyn_rigidbody2d", "generalized_alpha")
    kind = _kind(problem)
    levels = levels or LEVELS[key][kind]
    ref = reference(problem)
    t_end = T_END[kind]
    start = time.perf_counter()
    _, mbs, bodies, joints, nodes = exudyn_rigidbody2d(problem)
    build = time.perf_counter() - start

    def measure(h):
        ss = _exudyn_settings(exu, t_end, h, adaptive=False, explicit=False)

        def run(ss=ss):
            solver = exu.MainSolverImplicitSecondOrder()
            t0 = time.perf_counter()
            solver.InitializeSolver(mbs, ss)
            t1 = time.perf_counter()
            ok = solver.SolveSteps(mbs, ss)
            t2 = time.perf_counter()
            solver.FinalizeSolver(mbs, ss)
            if not ok:
                raise RuntimeError(f"Exudyn SolveSteps failed: {solver.GetErrorString()}")
            cfg = exu.ConfigurationType.Current
            if kind == "chain":
                last = bodies[f"rod{len(bodies) - 1}"]
                tip = np.asarray(mbs.GetObjectOutputBody(
                    last, exu.OutputVariableType.Position, localPosition=[0.5 * LENGTH, 0, 0],
                    configuration=cfg))[:2]
                error = float(np.linalg.norm(tip - ref))
            else:  # crank angle: reference angle π/2 plus the rotation coordinate
                q = mbs.GetNodeOutput(nodes["crank"], exu.OutputVariableType.Coordinates,
                                      configuration=cfg)
                error = abs(math.pi / 2 + float(q[2]) - ref)
            drift, vdrift = _exudyn_gaps(exu, mbs, joints)
            return t2 - t1, {"error": error, "drift": drift, "velocity_drift": vdrift,
                             "steps": int(solver.it.currentStepIndex) - 1,  # the index starts at 1
                             "rhs_evaluations": int(solver.it.newtonStepsCount),
                             "setup_seconds": t1 - t0,
                             "message": f"jacobians {int(solver.it.newtonJacobiCount)}"}

        return _measure(problem, key, t_end / ss.timeIntegration.numberOfSteps, run,
                        repeat, build, "absolute",
                        3 * len(bodies), 2 * len(joints), "Exudyn", exu.__version__)

    return _swept(levels, measure)


def exudyn_tree(problem: str, integrator: str = "dopri5", levels=None,
                repeat: int = 3) -> list[dict]:
    """Exudyn ``ObjectKinematicTree`` (minimal coordinates) with RK44 or DOPRI5; chains only."""
    exu = _import("exudyn")
    if exu is None or _kind(problem) != "chain":
        return []
    key = ("exudyn_kinematictree", integrator)
    levels = levels or LEVELS[key]["chain"]
    solver_type = {"rk44": exu.DynamicSolverType.RK44,
                   "dopri5": exu.DynamicSolverType.DOPRI5}[integrator]
    n = _links(problem)
    ref = reference(problem)
    start = time.perf_counter()
    _, mbs, node = exudyn_kinematic_tree(n)
    build = time.perf_counter() - start

    def measure(level):
        ss = _exudyn_settings(exu, T_END["chain"], level, adaptive=integrator in ADAPTIVE,
                              explicit=True)
        ss.timeIntegration.solverType = solver_type

        def run(ss=ss):
            solver = exu.MainSolverExplicit()
            t0 = time.perf_counter()
            solver.InitializeSolver(mbs, ss)
            t1 = time.perf_counter()
            ok = solver.SolveSteps(mbs, ss)
            t2 = time.perf_counter()
            solver.FinalizeSolver(mbs, ss)
            if not ok:
                raise RuntimeError(f"Exudyn SolveSteps failed: {solver.GetErrorString()}")
            q = np.asarray(mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates,
                                             configuration=exu.ConfigurationType.Current))
            phi = np.cumsum(q)  # relative joint angles -> absolute rod angles
            tip = LENGTH * np.array([np.cos(phi).sum(), np.sin(phi).sum()])
            steps = int(solver.it.currentStepIndex) - 1  # the index starts at 1
            rejected = int(solver.it.rejectedAutomaticStepSizeSteps)
            return t2 - t1, {"error": float(np.linalg.norm(tip - ref)), "steps": steps,
                             "rhs_evaluations": (steps + rejected) * solver.GetNumberOfStages(),
                             "setup_seconds": t1 - t0,
                             "message": f"rejected {rejected}" if rejected else ""}

        fixed = "" if integrator in ADAPTIVE else T_END["chain"] / ss.timeIntegration.numberOfSteps
        return _measure(problem, key, fixed or level, run, repeat, build, "joint", n, 0,
                        "Exudyn", exu.__version__)

    return _swept(levels, measure)


# --------------------------------------------------------------------------------------------
# MuJoCo
# --------------------------------------------------------------------------------------------


def _mjcf_rod() -> str:
    """Inertial and geom of one rod along the body's +x axis, joint at the body origin."""
    axial = MASS * RADIUS**2 / 2.0
    return (f'<inertial pos="{0.5 * LENGTH!r} 0 0" mass="{MASS!r}" '
            f'diaginertia="{axial!r} {INERTIA!r} {INERTIA!r}"/>'
            f'<geom type="capsule" fromto="0 0 0 {LENGTH!r} 0 0" size="{RADIUS!r}" '
            'contype="0" conaffinity="0"/>')


def _mjcf(name: str, integrator: str, step: float, world: str, extra: str = "",
          option: str = "") -> str:
    return (f'<mujoco model="{name}"><compiler angle="radian" inertiafromgeom="false"/>'
            f'<option timestep="{step!r}" integrator="{integrator}"{option} '
            f'gravity="0 {-GRAVITY!r} 0"><flag contact="disable"/></option>'
            f"<worldbody>{world}</worldbody>{extra}</mujoco>")


def mujoco_chain_xml(n: int, integrator: str = "RK4", step: float = 1e-3) -> str:
    """MJCF of the n-rod chain: nested bodies, hinges about +z (the casmbd angle sign), a site
    ``tip`` at the free end.  qpos = relative angles, all zero (horizontal) at rest."""
    opening = "".join(
        f'<body name="rod{i}" pos="{0.0 if i == 0 else LENGTH!r} 0 0">'
        f'<joint name="pin{i}" type="hinge" axis="0 0 1" damping="0" armature="0"/>'
        + _mjcf_rod() + (f'<site name="tip" pos="{LENGTH!r} 0 0"/>' if i == n - 1 else "")
        for i in range(n))
    return _mjcf(f"chain{n}", integrator, step, opening + "</body>" * n)


def mujoco_fourbar_xml(integrator: str = "RK4", step: float = 1e-3,
                       solref: str | None = None, solimp: str | None = None,
                       tolerance: str | None = None, iterations: str | None = None) -> str:
    """MJCF of the parallelogram: crank (hinge A at the origin) - coupler (hinge B) - rocker
    (hinge C), closed by ``connect`` of site ``Dr`` (rocker end) to world site ``D`` = (1, 0).

    Initial state (set by :func:`_mujoco_initial`): qpos = (π/2, −π/2, −π/2) (crank vertical,
    coupler horizontal, rocker pointing down from C to D), qvel = (1, −1, 1) (crank and rocker
    at +1 rad/s, coupler translating).  qpos[0] is the (unwrapped) crank angle.
    """
    rod = _mjcf_rod()
    hinge = 'type="hinge" axis="0 0 1" damping="0" armature="0"'
    world = (f'<site name="D" pos="{LENGTH!r} 0 0"/>'
             f'<body name="crank" pos="0 0 0"><joint name="A" {hinge}/>{rod}'
             f'<body name="coupler" pos="{LENGTH!r} 0 0"><joint name="B" {hinge}/>{rod}'
             f'<body name="rocker" pos="{LENGTH!r} 0 0"><joint name="C" {hinge}/>{rod}'
             f'<site name="Dr" pos="{LENGTH!r} 0 0"/></body></body></body>')
    attrs = (f' solref="{solref}"' if solref else "") + (f' solimp="{solimp}"' if solimp else "")
    option = ((f' tolerance="{tolerance}"' if tolerance else "")
              + (f' iterations="{iterations}"' if iterations else ""))
    return _mjcf("fourbar", integrator, step, world,
                 f'<equality><connect site1="Dr" site2="D"{attrs}/></equality>', option)


def check_mujoco_model(model) -> None:
    """Raise ``RuntimeError`` unless every moving body has exactly mass m, centre (L/2, 0, 0),
    principal frame aligned with the body and inertia (m r²/2, m L²/12, m L²/12), and the
    joints have no damping, armature, stiffness or friction loss."""
    nb = model.nbody - 1
    checks = {
        "mass": (model.body_mass[1:], np.full(nb, MASS)),
        "centre": (model.body_ipos[1:], np.tile([0.5 * LENGTH, 0.0, 0.0], (nb, 1))),
        "principal frame": (model.body_iquat[1:], np.tile([1.0, 0.0, 0.0, 0.0], (nb, 1))),
        "inertia": (model.body_inertia[1:],
                    np.tile([MASS * RADIUS**2 / 2.0, INERTIA, INERTIA], (nb, 1))),
        "damping": (model.dof_damping, np.zeros(model.nv)),
        "armature": (model.dof_armature, np.zeros(model.nv)),
        "frictionloss": (model.dof_frictionloss, np.zeros(model.nv)),
        "stiffness": (model.jnt_stiffness, np.zeros(model.njnt)),
    }
    for what, (got, want) in checks.items():
        if not np.array_equal(np.asarray(got), want):
            raise RuntimeError(f"MuJoCo model {what} differs from the benchmark's: {got} "
                               f"instead of {want}")


def _mujoco_initial(mujoco, model, data, problem: str) -> None:
    mujoco.mj_resetData(model, data)
    if problem == "fourbar":
        data.qpos[:] = [math.pi / 2, -math.pi / 2, -math.pi / 2]
        data.qvel[:] = [1.0, -1.0, 1.0]
    mujoco.mj_forward(model, data)


def _mujoco_gap(mujoco, model, data) -> tuple[float, float]:
    """Connect gap |Dr − D| and the speed of Dr (D is fixed) in the current state."""
    mujoco.mj_forward(model, data)
    gap = float(np.linalg.norm(data.site("Dr").xpos - data.site("D").xpos))
    jacp = np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacp, None, model.site("Dr").id)
    return gap, float(np.linalg.norm(jacp @ data.qvel))


def mujoco_run(problem: str, integrator: str = "rk4", stiff: bool = False, levels=None,
               repeat: int = 3) -> list[dict]:
    """MuJoCo with ``RK4`` or ``implicitfast`` over a timestep sweep (``stiff``: the four-bar
    with :data:`STIFF` constraint settings)."""
    mujoco = _import("mujoco")
    if mujoco is None or (stiff and problem != "fourbar"):
        return []
    key = ("mujoco_stiff" if stiff else "mujoco", integrator)
    kind = _kind(problem)
    levels = levels or LEVELS[key][kind]
    ref = reference(problem)
    t_end = T_END[kind]
    name = {"rk4": "RK4", "implicitfast": "implicitfast", "implicit": "implicit"}[integrator]

    def measure(level):
        nstep = round(t_end / level)
        h = t_end / nstep  # the step that lands exactly on t_end
        start = time.perf_counter()
        if kind == "chain":
            xml = mujoco_chain_xml(_links(problem), name, h)
        else:
            xml = mujoco_fourbar_xml(name, h, **(STIFF if stiff else {}), **MUJOCO_SOLVER)
        model = mujoco.MjModel.from_xml_string(xml)
        build = time.perf_counter() - start
        check_mujoco_model(model)
        data = mujoco.MjData(model)

        def run(model=model, data=data, nstep=nstep):
            t0 = time.perf_counter()
            _mujoco_initial(mujoco, model, data, problem)
            t1 = time.perf_counter()
            mujoco.mj_step(model, data, nstep)
            t2 = time.perf_counter()
            if not np.all(np.isfinite(data.qpos)):
                raise RuntimeError(f"MuJoCo diverged (non-finite qpos at t = {data.time:.4g})")
            mujoco.mj_forward(model, data)
            out = {"steps": nstep, "setup_seconds": t1 - t0,
                   "rhs_evaluations": nstep * (4 if integrator == "rk4" else 1)}
            if kind == "chain":
                out["error"] = float(np.linalg.norm(data.site("tip").xpos[:2] - ref))
            else:
                out["error"] = abs(float(data.qpos[0]) - ref)
                out["drift"], out["velocity_drift"] = _mujoco_gap(mujoco, model, data)
            return t2 - t1, out

        row = _measure(problem, key, h, run, repeat, build, "joint", model.nq,
                       3 * model.neq, "MuJoCo", mujoco.__version__)
        if kind == "fourbar" and row["status"] == "ok":
            row["drift_max"] = _mujoco_drift_max(mujoco, model, data, problem, nstep)
        return row

    return _swept(levels, measure)


def _mujoco_drift_max(mujoco, model, data, problem: str, nstep: int) -> float:
    """Largest connect gap sampled every 10 ms of a (untimed) rerun."""
    _mujoco_initial(mujoco, model, data, problem)
    chunk = max(1, round(0.01 / model.opt.timestep))
    worst, done = 0.0, 0
    while done < nstep:
        k = min(chunk, nstep - done)
        mujoco.mj_step(model, data, k)
        done += k
        worst = max(worst, _mujoco_gap(mujoco, model, data)[0])
    return worst


# --------------------------------------------------------------------------------------------
# Sweep, table, CSV
# --------------------------------------------------------------------------------------------


def _swept(levels, measure) -> list[dict]:
    """:func:`benchmarks.fair.sweep` over ``levels``, the stop reason in every row."""
    rows, stop = fair.sweep(levels, measure, cap=RUN_CAP)
    for row in rows:
        row["sweep_stop"] = stop
    print(f"{'':8s} sweep stopped: {stop}", flush=True)
    return rows


def _measure(problem, key, level, run, repeat, build, coordinates, nq, nc, peer,
             version) -> dict:
    row = _row(problem, key[0], key[1], level, build_seconds=build, coordinates=coordinates,
               nq=nq, nc=nc, peer=peer, peer_version=version)
    try:
        result = _timed(run, repeat)
        row.update(result)
        row["status"] = "ok"
    except Exception as exc:  # a peer's failure is a result, recorded with its message
        row.update({"status": "failed", "message": str(exc).splitlines()[0][:200]})
    _print_row(row)
    return row


def label(row: dict) -> str:
    """Human-readable peer method, e.g. ``"MuJoCo RK4"``."""
    return LABELS.get((row["formulation"], row["integrator"]),
                      f"{row['formulation']}/{row['integrator']}")


def _level_text(row: dict) -> str:
    return f"h={row['step']:.3g}" if row["step"] != "" else f"tol={row['tolerance']:.0e}"


def _print_row(row: dict) -> None:
    head = f"{row['problem']:8s} {label(row):42s} {_level_text(row):11s}"
    if row["status"] != "ok":
        print(f"{head} FAILED {row['message'][:90]}", flush=True)
        return
    drift = f"  drift {row['drift']:.1e}" if row["drift"] != "" else ""
    print(f"{head} {1e3 * row['solve_seconds']:10.2f} ms  error {row['error']:.2e}{drift}  "
          f"steps {row['steps']}", flush=True)


def sweep(problems, repeat: int = 3, quick: bool = False) -> list[dict]:
    """Every peer method on every problem (uninstalled peers give no rows)."""
    rows = []
    for problem in problems:
        kind = _kind(problem)

        def pick(key, kind=kind):
            levels = LEVELS[key].get(kind)
            return levels[:4] if quick else levels

        key = ("exudyn_rigidbody2d", "generalized_alpha")
        if not problem.endswith("_3d"):
            rows += exudyn_generalized_alpha(problem, pick(key), repeat)
        if kind == "chain":
            for integrator in ("rk44", "dopri5"):
                rows += exudyn_tree(problem, integrator, pick(("exudyn_kinematictree",
                                                               integrator)), repeat)
        for integrator in ("rk4", "implicitfast", "implicit"):
            rows += mujoco_run(problem, integrator, False, pick(("mujoco", integrator)), repeat)
            if kind == "fourbar":
                rows += mujoco_run(problem, integrator, True,
                                   pick(("mujoco_stiff", integrator)), repeat)
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    """Rows with the keys of :func:`benchmarks.work_precision.write_csv` plus ``peer``,
    ``peer_version`` and ``drift_max``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=KEYS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def _curves(rows, problem):
    """Each method's (error, time) points in sweep order (coarse to fine)."""
    curves: dict[str, list[tuple[float, float]]] = {}
    for row in rows:
        if row["problem"] != problem or row["status"] != "ok":
            continue
        err, sec = float(row["error"]), float(row["solve_seconds"])
        if math.isfinite(err) and err > 0.0:
            curves.setdefault(label(row), []).append((err, sec, _fineness(row)))
    return {k: [(e, s) for e, s, _ in sorted(v, key=lambda p: p[2])] for k, v in curves.items()}


def _fineness(row) -> float:
    """Sort key coarse -> fine: the step size or tolerance, negated."""
    level = row["step"] if row["step"] not in ("", None) else row["tolerance"]
    return -float(level)


def best_peer_time(rows, problem: str, error_level: float) -> tuple[float, str] | None:
    """Fastest peer time [s] reaching ``error_level`` on ``problem``, and its method.

    The fair rule (:func:`benchmarks.fair.best_time_to_error`), the same as casmbd's tables:
    each method's time to the level interpolated log-log along its sweep, the fastest
    method.  ``None``: no method reaches it down to its floor.
    """
    return fair.best_time_to_error(_curves(rows, problem), error_level)


def floors(rows, problem: str) -> dict[str, tuple[float, str]]:
    """Each method's smallest error on ``problem`` and why its sweep stopped."""
    out: dict[str, tuple[float, str]] = {}
    for row in rows:
        if row["problem"] != problem or row["status"] != "ok":
            continue
        err = float(row["error"])
        name = label(row)
        if name not in out or err < out[name][0]:
            out[name] = (err, row.get("sweep_stop", ""))
    return out


def table(rows, problems) -> str:
    """Plain-text table of every row and the best peer times at 1e-6 and 1e-9."""
    lines = [f"{'problem':8s} {'method':42s} {'tol/step':11s} {'time [ms]':>10s} "
             f"{'error':>9s} {'drift':>8s} {'drift max':>9s} {'steps':>7s}"]
    for r in rows:
        if r["status"] != "ok":
            lines.append(f"{r['problem']:8s} {label(r):42s} {_level_text(r):11s} "
                         f"FAILED {r['message'][:60]}")
            continue
        drift = f"{r['drift']:8.1e}" if r["drift"] != "" else f"{'':8s}"
        dmax = f"{r['drift_max']:9.1e}" if r["drift_max"] != "" else f"{'':9s}"
        lines.append(f"{r['problem']:8s} {label(r):42s} {_level_text(r):11s} "
                     f"{1e3 * r['solve_seconds']:10.2f} {r['error']:9.2e} {drift} {dmax} "
                     f"{r['steps']:7d}")
    lines += ["", "Fastest peer method at the error level (interpolated log-log):"]
    for problem in problems:
        for level in (1e-6, 1e-9):
            best = best_peer_time(rows, problem, level)
            lines.append(f"  {problem:8s} {level:.0e}: "
                         + (f"{1e3 * best[0]:.2f} ms ({best[1]})" if best else "not reached"))
    return "\n".join(lines)


def main(argv=None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=PROBLEMS, choices=PROBLEMS)
    parser.add_argument("--repeat", type=int, default=3, help="warm runs (best of), >= 3")
    parser.add_argument("--quick", action="store_true", help="four levels per method")
    parser.add_argument("--cap", type=float, default=fair.RUN_CAP,
                        help="a run slower than this [s] ends its sweep")
    parser.add_argument("--csv", default=str(RESULTS / "peers.csv"))
    args = parser.parse_args(argv)
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}", flush=True)
    global RUN_CAP
    RUN_CAP = args.cap
    rows = sweep(args.problems, max(3, args.repeat), args.quick)
    if rows:
        write_csv(rows, Path(args.csv))
    print()
    print(table(rows, args.problems))
    load = os.getloadavg()
    print(f"\nload average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; CSV: {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
