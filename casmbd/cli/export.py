"""The ``export`` verb: a mechanism's dynamics as a standalone C99 library
(:func:`casmbd.io.c_export.export_c`; docs/export.md)."""

from __future__ import annotations

from casmbd.cli.common import load_scene_for
from casmbd.io.c_export import export_c


def _names(text: str | None) -> list[str] | None:
    return None if text is None else [n.strip() for n in text.split(",") if n.strip()]


def _cmd_export(args) -> tuple[dict, str]:
    mech = load_scene_for(args)
    report = export_c(mech, args.c, functions=args.functions, prefix=args.prefix,
                      actuated=_names(args.actuated), friction=_names(args.friction) or (),
                      frames=_names(args.frames), parameters=args.parameters,
                      cmake=args.cmake, force=args.force)
    data = report.to_json()
    lines = [f"exported '{mech.name}' as C99 to {report.directory} (prefix {report.prefix}): "
             f"n_q = {report.nq}, n_v = {report.nv}, n_c = {report.nc}, "
             f"{len(report.frame_names)} frames",
             f"  functions: {', '.join(report.functions)}",
             f"  files: {', '.join(report.files)}",
             f"  build: cd {report.directory} && cc -std=c99 -O2 main.c {report.prefix}.c "
             f"{report.prefix}_model.c -lm -o example && ./example"]
    return data, "\n".join(lines)
