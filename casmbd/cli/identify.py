"""The ``identify`` verb: dynamic parameters of a scene or URDF from measured joint data.

``casmbd identify SCENE|URDF --data MEASURED.csv [--friction viscous,coulomb] [--cutoff HZ]
[--decimate K] [--ols] [--no-consistent] [--out FILE] [--json]``: reads the samples
(:mod:`casmbd.io.measurement_csv`), identifies the base parameters by weighted least squares and
physically consistent standard parameters
(:func:`casmbd.analysis.identification.identify.identify`), prints them with their standard
deviations, the condition number and the residuals, and with ``--out`` writes the model file
with the identified masses, centres of mass, inertias and friction
(:mod:`casmbd.io.identified`: a URDF for a URDF, a scene for a scene).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from casmbd.analysis.identification.identify import identification_model, identify
from casmbd.cli.common import check_not_input, load_scene_for
from casmbd.errors import AnalysisError
from casmbd.io.identified import write_scene, write_urdf
from casmbd.io.measurement_csv import read_measurements
from casmbd.io.urdf import load_urdf


def _friction(text: str) -> tuple[str, ...]:
    return () if text.strip().lower() in ("", "none") else tuple(
        f.strip() for f in text.split(",") if f.strip())


def _cmd_identify(args) -> tuple[dict, str]:
    urdf = Path(args.scene).suffix.lower() == ".urdf"
    if args.out:
        want = ".urdf" if urdf else ".toml"
        if Path(args.out).suffix.lower() != want:
            raise AnalysisError(f"--out '{args.out}': the identified model is written as the "
                                f"input's kind, a {want} file")
        if args.no_consistent:
            raise AnalysisError("--out writes the physically consistent standard parameters: "
                                "drop --no-consistent")
    check_not_input(args, [("measurement file", args.data)])
    if urdf:
        load_scene_for(args)  # checks --out against the inputs
        mech = load_urdf(args.scene, damping=True, friction=True)
    else:
        mech = load_scene_for(args)
    model = identification_model(mech, _friction(args.friction), mode=args.mode)
    meas = read_measurements(args.data, list(model[0].rows))
    result = identify(mech, meas, friction=_friction(args.friction), cutoff=args.cutoff,
                      decimate=args.decimate, weighted=not args.ols,
                      consistent=not args.no_consistent, mode=args.mode, model=model)
    data = result.summary()
    data["model"] = str(args.scene)
    data["data"] = str(args.data)
    written = None
    if args.out:
        cons = result.consistent
        writer = write_urdf if urdf else write_scene
        try:
            written = writer(args.scene, args.out, mech, result.standard_names, cons.values,
                             result.origins)
        except OSError as exc:
            raise AnalysisError(f"cannot write --out '{args.out}': {exc.strerror or exc}") \
                from None
    data["written"] = None if written is None else str(written)
    b = result.base
    lines = [f"identified '{mech.name}' from {result.samples} samples of "
             f"{len(result.coordinates)} coordinates ({'weighted' if b.weighted else 'ordinary'}"
             f" least squares; friction: {', '.join(result.friction) or 'none'})",
             f"  condition number of the stacked base regressor: {b.condition_number:.4g}",
             f"  base parameters ({len(b.names)}):"]
    for row in data["base_parameters"]:
        rel = row["relative_std_percent"]
        lines.append(f"    {row['name']:<24} {row['value']:+.6g} ± {row['std']:.3g}"
                     + (f" ({rel:.3g} %)" if rel is not None else "")
                     + f"   = {row['expression']}")
    lines.append("  residual RMS per coordinate: " + ", ".join(
        f"{c} {r:.3g}" for c, r in data["residual_rms"].items()))
    if result.consistent is not None:
        gap = result.consistent_torque_rms
        lines.append(f"  consistent standard parameters: IPOPT {result.consistent.status}, "
                     f"physically consistent: {result.consistent.checks['consistent']}; "
                     f"torque RMS from the least-squares fit: max {float(np.max(gap)):.3g}")
    if written is not None:
        lines.append(f"  written: {written}")
    return data, "\n".join(lines)
