"""A command-line verb registered from user code: ``casmbd mass_properties SCENE``.

The total mass m = Σ m_i of the scene's bodies and their centre of mass r_G = Σ m_i r_i / m in
the design pose (each body's ``position`` is its centre of mass; masses given as expressions
take the parameters' values).  A verb is one function
``run(args) -> (JSON object, text)`` and one :func:`~casmbd.cli.registry.register_verb` naming
its help and its own arguments; the parser's scene argument, ``--json`` (exactly one JSON
object on stdout), ``--debug``, the one-line errors and the exit statuses are the command's
(:func:`casmbd.cli.main`), the same for every verb.  Its Python face is the function it runs
(:func:`mass_properties` below).

Run it with ``python examples/custom_verb.py SCENE [--json] [--body NAME ...]``;
``tests/architecture/test_custom_registries.py`` runs it too.
"""

from __future__ import annotations

import sys

import numpy as np

from casmbd import cli
from casmbd.cli.registry import register_verb
from casmbd.errors import ModelError
from casmbd.io.scene import load_scene
from casmbd.model import Mechanism
from casmbd.model.values import numeric


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


register_verb("mass_properties", _run, help="total mass and centre of mass of the bodies",
              add_arguments=_arguments, replace=True)  # replace: the script may run twice

if __name__ == "__main__":
    sys.exit(cli.main(["mass_properties", *sys.argv[1:]]))
