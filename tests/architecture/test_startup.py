"""Light start: ``import casmbd`` loads the error classes only; the public names load their
modules on first use (PEP 562 ``__getattr__`` in ``casmbd/__init__.py``).

Each check runs in a fresh interpreter, so that modules other tests imported do not count; the
checks compare module names, never timings (docs/performance.md, *Start-up*, has the times).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import casmbd
from casmbd.results import Result

#: modules that ``import casmbd`` must not load (the OCP, plotting, distribution, SLSQP)
HEAVY = ("casmbd.ocp", "casmbd.analysis", "casmbd.compiled", "matplotlib", "dask",
         "distributed", "tqdm", "scipy.optimize", "scipy.sparse")


def _fresh(code: str) -> str:
    """stdout of ``code`` run by a new interpreter."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, check=True).stdout.strip()


def _loaded(statement: str, names) -> list[str]:
    code = (f"import sys\n{statement}\n"
            f"print(__import__('json').dumps(sorted(m for m in {tuple(names)!r} "
            f"if m in sys.modules)))")
    return json.loads(_fresh(code))


def test_import_casmbd_loads_no_heavy_module():
    assert _loaded("import casmbd", HEAVY) == []


def test_import_casmbd_loads_only_the_error_classes():
    """The casmbd modules after ``import casmbd``: the package and casmbd.errors (2)."""
    out = json.loads(_fresh("import sys, json, casmbd; print(json.dumps(sorted("
                            "m for m in sys.modules if m.startswith('casmbd'))))"))
    assert out == ["casmbd", "casmbd.errors"]


def test_the_cli_loads_no_optimizer_or_plotting():
    """The command line (``casmbd info`` …) loads no scipy.optimize, matplotlib or dask: those
    are imported by the functions that use them (a failed assembly's diagnosis, a plot); the
    verbs' modules are imported when their verb runs, so building the parser loads neither the
    OCP, the simulation, the sweeps nor the animation code."""
    assert _loaded("import casmbd.cli", ("scipy.optimize", "matplotlib", "dask", "casmbd.ocp",
                                         "casmbd.analysis.dynamics.simulate",
                                         "casmbd.analysis.studies.sweep",
                                         "casmbd.viz.animation", "casmbd.cli.analyses")) == []


def test_info_loads_only_the_info_verb(tmp_path):
    """``casmbd info`` (the CLI's main, in a fresh interpreter) imports the info verb's module
    and none of the other verbs'."""
    code = ("import sys, io, contextlib, casmbd.cli\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    status = casmbd.cli.main(['info', 'examples/double_pendulum.toml', '--mode', "
            "'vm'])\n"
            "print(status, sorted(m for m in ('casmbd.cli.info', 'casmbd.cli.analyses', "
            "'casmbd.cli.workbench', 'casmbd.cli.optimal', 'casmbd.ocp') if m in sys.modules))")
    root = __import__("pathlib").Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True, cwd=root).stdout.strip()
    assert out == "0 ['casmbd.cli.info']"


def test_every_verb_names_an_existing_handler():
    """Each lazy entry of ``casmbd.cli.VERBS`` names a function of its module."""
    import importlib

    import casmbd.cli as cli

    assert len(cli.VERBS) == 16  # + identify, export, excite (issue 38)
    for verb, run in cli.VERBS.items():
        module, name = run.handler
        handler = getattr(importlib.import_module(module), name)
        assert callable(handler) and run.__name__ == name, verb


def test_every_public_name_resolves_to_its_module_object():
    """``casmbd.X`` and ``from casmbd import X`` give the object of the defining module, for
    every name of ``__all__`` (the analysis verbs through the analysis face's registry); it is
    then cached in the package namespace."""
    import casmbd.analysis as face

    assert len(casmbd.__all__) == 40  # 37 + load_mjcf (issue 34) + identify, export_c (issue 38)
    for name in casmbd.__all__:
        value = getattr(casmbd, name)
        module = (sys.modules[casmbd._LAZY[name]] if name in casmbd._LAZY
                  else sys.modules[face.VERBS[name]] if name in face.VERBS else casmbd.errors)
        assert value is getattr(module, name), name
        assert casmbd.__dict__[name] is value, name
    assert set(casmbd.__all__) <= set(dir(casmbd))
    from casmbd import Mechanism, simulate  # noqa: F401

    assert simulate is sys.modules["casmbd.analysis.dynamics.simulate"].simulate
    assert casmbd.ocp.Ocp is sys.modules["casmbd.ocp.problem"].Ocp


def test_unknown_attribute_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no_such_name"):
        casmbd.no_such_name  # noqa: B018
    assert not hasattr(casmbd, "__wrapped__")


def test_a_saved_result_reads_its_scene_after_a_bare_import(tmp_path):
    """``Result.mechanism()`` needs a scene reader, which :mod:`casmbd.results` (below
    :mod:`casmbd.io`) cannot import: ``casmbd.load`` (:func:`casmbd.io.scene.load_result`)
    passes it in, in a fresh interpreter (nothing else imported); a result read by the bare
    ``casmbd.results.load`` carries none and says how to pass one (nothing registers it)."""
    scene = ('[scene]\nname = "one_body"\n\n[[bodies]]\nname = "b"\nmass = 2.5\n'
             'inertia = 0.1\nposition = [0.0, 0.0]\n')
    path = tmp_path / "r.npz"
    Result(kind="simulation", t=np.array([0.0, 1.0]), arrays={}, names={},
           scene=scene).save(path)
    code = (f"import casmbd\nmech = casmbd.load({str(path)!r}).mechanism()\n"
            f"print(mech.name, mech.bodies['b'].mass)")
    assert _fresh(code) == "one_body 2.5"
    code = ("import casmbd.results, casmbd.io.scene\n"
            f"res = casmbd.results.load({str(path)!r})\n"
            "try:\n    res.mechanism()\nexcept casmbd.errors.AnalysisError as exc:\n"
            "    print('refused:', exc)\n"
            "print(res.mechanism(casmbd.io.scene.loads_scene).bodies['b'].mass)")
    out = _fresh(code).splitlines()
    assert out[0].startswith("refused:") and "casmbd.loads_scene" in out[0]
    assert out[1] == "2.5"
