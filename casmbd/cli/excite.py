"""The ``excite`` verb: an excitation trajectory for identification (docs/identification.md).

``casmbd excite SCENE|URDF --period T --acceleration A [--harmonics L] [--samples N]
[--friction viscous,coulomb] [--torque-limits] [--max-iter K] [--seed S] [--rate HZ]
[--out TRAJ.csv] [--json]``: optimises a periodic Fourier series per joint for the
conditioning of the stacked base regressor under the joints' position and velocity limits
(URDF ``<limit>``), |q̈| ≤ A and optionally |τ| ≤ effort
(:func:`casmbd.ocp.excitation.excitation_for`); prints the condition numbers and the
coefficients; ``--out`` writes one period sampled at ``--rate`` as CSV, columns ``t,
q.<coordinate>, v.<coordinate>, a.<coordinate>``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from casmbd.atomic import atomic_write
from casmbd.cli.common import load_scene_for
from casmbd.errors import AnalysisError
from casmbd.io.urdf import load_urdf
from casmbd.ocp.excitation import excitation_for


def _friction(text: str) -> tuple[str, ...]:
    return () if text.strip().lower() in ("", "none") else tuple(
        f.strip() for f in text.split(",") if f.strip())


def _cmd_excite(args) -> tuple[dict, str]:
    if args.out and Path(args.out).suffix.lower() != ".csv":
        raise AnalysisError(f"--out '{args.out}': the trajectory is written as CSV (.csv)")
    mech = load_scene_for(args)
    if Path(args.scene).suffix.lower() == ".urdf":  # the URDF's friction as identify reads it
        mech = load_urdf(args.scene, damping=True, friction=True)
    design, base = excitation_for(
        mech, period=args.period, acceleration=args.acceleration,
        friction=_friction(args.friction), harmonics=args.harmonics, samples=args.samples,
        torque_limits=args.torque_limits, mode=args.mode, seed=args.seed,
        max_iter=args.max_iter)
    traj = design.trajectory
    coords = design.coordinates
    written = None
    if args.out:
        t = np.arange(round(traj.period * args.rate)) / args.rate
        q, v, a = traj.evaluate(t)
        header = ",".join(["t"] + [f"{k}.{c}" for k in ("q", "v", "a") for c in coords])
        table = np.column_stack([t, q, v, a])
        try:
            written = atomic_write(args.out, lambda tmp: np.savetxt(
                tmp, table, delimiter=",", header=header, comments="", fmt="%.17g"))
        except OSError as exc:
            raise AnalysisError(f"cannot write --out '{args.out}': {exc.strerror or exc}") \
                from None
    data = {"model": str(args.scene), "coordinates": coords, "period": traj.period,
            "harmonics": traj.harmonics, "samples": design.samples,
            "base_parameters": len(base.names), "condition_number": design.condition,
            "initial_condition_number": design.initial_condition, "status": design.status,
            "iterations": design.iterations, "q0": traj.q0.tolist(), "a": traj.a.tolist(),
            "b": traj.b.tolist(), "written": None if written is None else str(written)}
    lines = [f"excitation of '{mech.name}': {traj.q0.size} joints, T = {traj.period:g} s, "
             f"{traj.harmonics} harmonics, {design.samples} samples, {len(base.names)} base "
             "parameters",
             f"  condition number of the stacked base regressor: {design.condition:.4g} "
             f"(random feasible start {design.initial_condition:.4g}; IPOPT {design.status}, "
             f"{design.iterations} iterations)"]
    for i, name in enumerate(coords):
        amp_a = ", ".join(f"{x:+.4g}" for x in traj.a[i])
        amp_b = ", ".join(f"{x:+.4g}" for x in traj.b[i])
        lines.append(f"  {name}: q0 {traj.q0[i]:+.6g}, a [{amp_a}], b [{amp_b}]")
    if written:
        lines.append(f"  wrote {written} (one period at {args.rate:g} Hz)")
    return data, "\n".join(lines)
