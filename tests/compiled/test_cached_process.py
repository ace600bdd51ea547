"""A cache hit in a fresh process builds nothing symbolic (issue 36 item 5, lazy loading).

The parent builds and compiles a folded pendulum chain (the default path from 32 rods on); a
new Python process then constructs the same Simulator on the same cache while counting every
``casadi.SX.sym``/``casadi.MX.sym`` call and every ``System`` constructed: no System and no SX
symbol (the three MX symbols of DOPRI5's call wrapper are of fixed size), the report must be a
cache hit, and its first run must equal the parent's to 1e-14.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import private_cache

from casmbd.compiled import codegen

ROOT = Path(__file__).resolve().parents[2]
needs_compiler = pytest.mark.skipif(codegen.find_compiler() is None,
                                    reason="no C compiler available")
cache = private_cache(autouse=False, CASMBD_PROGRESS="0", CASMBD_COMPILE=None,
                      CASMBD_CFLAGS=None)

_CHILD = """
import json, sys
import casadi
counts = {"SX.sym": 0, "MX.sym": 0, "System": 0}
def spy(kind, original):
    def wrapped(*args, **kwargs):
        counts[kind] += 1
        return original(*args, **kwargs)
    return staticmethod(wrapped)
casadi.SX.sym = spy("SX.sym", casadi.SX.sym)
casadi.MX.sym = spy("MX.sym", casadi.MX.sym)
from casmbd.system import equations
init = equations.System.__init__
def system_init(self, *args, **kwargs):
    counts["System"] += 1
    init(self, *args, **kwargs)
equations.System.__init__ = system_init
from benchmarks.chains import pendulum_chain
from casmbd.analysis.dynamics.simulate import Simulator
sim = Simulator(pendulum_chain(5), mode="compiled", formulation_options={"fold": True})
res = sim.run(0.5, 5, rtol=1e-9, atol=1e-9)
rep = sim.model.report
print(json.dumps({**counts, "cache_hit": rep.cache_hit, "compiled": rep.compiled,
                  "tip": res.marker("tip")["position"].tolist()}))
"""


@needs_compiler
def test_cache_hit_in_a_fresh_process_builds_no_expressions(cache):
    from benchmarks.chains import pendulum_chain
    from casmbd.analysis.dynamics.simulate import Simulator

    sim = Simulator(pendulum_chain(5), mode="compiled", formulation_options={"fold": True})
    assert sim.model.report.compiled and sim.formulation_name == "articulated"
    tip = np.asarray(sim.run(0.5, 5, rtol=1e-9, atol=1e-9).marker("tip")["position"])
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True,
                         cwd=ROOT, env=env, check=True, timeout=300).stdout
    child = json.loads(out.strip().splitlines()[-1])
    assert child["cache_hit"] and not child["compiled"]
    assert (child["SX.sym"], child["System"]) == (0, 0)
    # the only symbols: DOPRI5's wrapper (t, x, p) -> ẋ around the loaded dynamics, three
    # whatever the size of the model
    assert child["MX.sym"] <= 3
    np.testing.assert_allclose(np.asarray(child["tip"]), tip, rtol=0.0, atol=1e-14)
