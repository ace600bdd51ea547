"""scipy's submodules load on first use (casmbd.lazy, issue 36 item 5): importing the simulator
loads none of them, so a cached process that only loads a compiled model does not pay their
0.2 s; the stand-in gives the module's own objects.  Module names are compared, never times."""

from __future__ import annotations

import json
import subprocess
import sys

import scipy.linalg
import scipy.sparse.linalg

from casmbd import lazy


def test_the_simulator_module_loads_no_scipy():
    code = ("import sys, json\nimport casmbd.analysis.dynamics.simulate\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True).stdout.strip().splitlines()[-1]
    assert json.loads(out) == []


def test_the_stand_in_is_the_module():
    assert lazy.lazy_module("scipy.linalg") is scipy.linalg  # imported: the module itself
    stand_in = lazy._LazyModule("scipy.sparse.linalg")  # as before the first import
    assert stand_in.splu is scipy.sparse.linalg.splu
    assert stand_in.__name__ == "scipy.sparse.linalg"
