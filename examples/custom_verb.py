"""A command-line verb registered from user code: ``casmbd mass_properties SCENE``.

The total mass m = Σ m_i of the scene's bodies and their centre of mass r_G = Σ m_i r_i / m in
the design pose (each body's ``position`` is its centre of mass; masses given as expressions
take the parameters' values).  A verb is one module and one
:func:`~casmbd.cli.registry.register_verb`:

* the command line: ``run(args) -> (JSON object, text)``, its help and its own arguments; the
  parser's scene argument, ``--json`` (exactly one JSON object on stdout), ``--debug``, the
  one-line errors and the exit statuses are the command's (:func:`casmbd.cli.main`), the same
  for every verb;
* the Python name, ``python=``: :func:`mass_properties` becomes ``casmbd.mass_properties``;
* the sweep, ``sweep=``: a :class:`~casmbd.analysis.studies.sweep_registry.Sweepable` saying
  how to build the analysis once (nothing to compile here), run it at one point of the
  parameters (a one-instant :class:`~casmbd.results.Result` whose ``stats`` hold the scalars)
  and which scalar outputs it offers — so ``casmbd sweep SCENE --param k=1:3:5 --analysis
  mass_properties`` and ``casmbd.sweep(mech, {"k": …}, analysis="mass_properties")`` run it
  (serially or on a Dask cluster that imports this module; worker processes import the
  functions by module name, so a script run with ``runpy`` sweeps serially).

Run it with ``python examples/custom_verb.py SCENE [--json] [--body NAME ...]``;
``tests/architecture/test_custom_registries.py`` runs it too.
"""

from __future__ import annotations

import sys

import numpy as np

from casmbd import cli
from casmbd.analysis.studies.sweep_registry import Engine, Sweepable
from casmbd.cli.registry import register_verb
from casmbd.errors import ModelError
from casmbd.io.scene import load_scene
from casmbd.model import Mechanism
from casmbd.model.needs import ALL_NEEDS, Handling
from casmbd.model.values import numeric
from casmbd.results import Result


def mass_properties(mech: Mechanism, bodies: list[str] | None = None) -> dict:
    """Total mass and centre of mass of ``bodies`` (default all) of ``mech``."""
    names = list(mech.bodies) if not bodies else bodies
    unknown = [n for n in names if n not in mech.bodies]
    if unknown:
        raise ModelError(f"mass_properties: no body {', '.join(map(repr, unknown))} (bodies: "
                         f"{', '.join(mech.bodies)})")
    masses = np.array([numeric(mech.bodies[n].mass, mech.parameters, f"body '{n}' mass")
                       for n in names])  # a number, or an expression of the parameters
    positions = np.array([np.asarray(mech.bodies[n].position, float) for n in names])
    total = float(masses.sum())
    return {"bodies": names, "mass": total,
            "centre_of_mass": (masses @ positions / total).tolist()}


def _run(args) -> tuple[dict, str]:
    data = mass_properties(load_scene(args.scene), args.body)
    text = (f"mass {data['mass']:.6g} kg, centre of mass "
            f"[{', '.join(f'{x:.6g}' for x in data['centre_of_mass'])}] m "
            f"({len(data['bodies'])} bodies)")
    return data, text


def _arguments(p) -> None:
    p.add_argument("--body", action="append", default=None,
                   help="only this body (repeatable; default every body)")


# ---- the sweep: built once (nothing compiled), run at each point's parameter values
#: the scalar outputs a sweep of this verb offers (read from the point's Result.stats)
OUTPUTS = ("mass", "centre_of_mass_x", "centre_of_mass_y", "centre_of_mass_z")


def _build(mech: Mechanism, mode: str) -> Engine:
    return Engine(mech, None, mode)  # no compiled model: the point's p go to run()


def _run_point(engine: Engine, p: dict, t_end, steps) -> Result:
    engine.mechanism.parameters = p
    data = mass_properties(engine.mechanism)
    com = np.asarray(data["centre_of_mass"])
    return Result("mass_properties", np.zeros(1), {"centre_of_mass": com[None, :]},
                  {"bodies": data["bodies"]},
                  {"mass": data["mass"], **dict(zip(OUTPUTS[1:], com.tolist()))})


def _outputs(result: Result) -> list[str]:
    return list(OUTPUTS)


def _handling(options) -> Handling:
    return Handling("mass properties", ALL_NEEDS)  # reads masses and positions only


SWEEP = Sweepable(_build, _run_point, _outputs, _handling, time_grid=False, outputs=OUTPUTS)

register_verb("mass_properties", _run, help="total mass and centre of mass of the bodies",
              add_arguments=_arguments, python=mass_properties, sweep=SWEEP,
              replace=True)  # replace: the script may run twice

if __name__ == "__main__":
    sys.exit(cli.main(["mass_properties", *sys.argv[1:]]))
