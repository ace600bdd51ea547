"""Structured NLP derivatives (casmbd/ocp/structured.py, issue 22 item 4): the gradient,
constraint Jacobian and Lagrangian Hessian assembled from per-element SX derivative functions
equal CasADi's own derivatives of the MX graph (an independent differentiation of the same
NLP), on every kind of element the transcriptions build; the derivative modes reach the same
optimum; the compiled element functions are cached."""

from __future__ import annotations

import pathlib

import casadi as ca
import numpy as np
import pytest
from conftest import private_cache

from casmbd.errors import AnalysisError
from casmbd.io.ocp_table import load_ocp
from casmbd.ocp.structured import MappedCall, _affine, nlp_solver
from casmbd.ocp.transcription import IPOPT_DEFAULTS, Transcription

OCP = pathlib.Path(__file__).resolve().parents[2] / "ocp"


_cache = private_cache("cache_st")


def _solvers(ocp):
    tr = Transcription(ocp)
    b = tr.b
    w = ca.vertcat(*[ca.vec(x) for x in b.w])
    out = {}
    for mode in ("auto", "vm"):
        out[mode] = nlp_solver("t", "ipopt", w, tr.objective, tr.objective_rest, b.g,
                               tr.calls, dict(IPOPT_DEFAULTS), mode, tr.structured)
    return tr, w.numel(), sum(int(g.numel()) for g in b.g), out


VARIANTS = {
    "cart-pole, fixed T, effort": ("cart_pole.toml", {}),
    "cart-pole, energy + tracking, 2 elements": ("cart_pole.toml", {"subintervals": 2}),
    "cart-pole, RK4 shooting": ("cart_pole.toml", {"transcription": "multiple_shooting",
                                                    "integrator": "rk4", "steps": 2}),
    "double pendulum, free T": ("double_pendulum_min_time.toml", {}),
    "four-bar, loop, free T": ("four_bar_min_time.toml", {}),
    "slider-crank, loop, control-node path": ("slider_crank_cycle.toml", {}),
    "cart-pole, explicit dynamics, Legendre": ("cart_pole.toml", {"dynamics": "explicit",
                                                                  "transcription": "legendre"}),
}


@pytest.mark.parametrize("label", list(VARIANTS))
def test_structured_derivatives_equal_casadi_derivatives(label):
    """At a random point (x ∈ [-1, 1], multipliers ∈ [-1, 1], σ = 0.7): f, g, ∇f, ∂g/∂x and
    the upper triangle of ∇²L from the per-element functions equal those CasADi derives from
    the MX graph to 1e-10 relative to the largest entry (measured ≤ 4e-17)."""
    name, overrides = VARIANTS[label]
    ocp = load_ocp(OCP / name)
    ocp.intervals = 6
    for key, value in overrides.items():
        setattr(ocp, key, value)
    if "energy" in label:
        ocp.minimize("energy", 0.5)
        ocp.minimize("tracking", 2.0, expression="hinge", reference="t")
    _, nx, ng, solvers = _solvers(ocp)
    assert solvers["auto"][2].startswith("structured") and solvers["vm"][2].endswith("MX")
    rng = np.random.default_rng(3)
    x, lam = rng.uniform(-1, 1, nx), rng.uniform(-1, 1, ng)
    got = {k: s.get_function for k, (s, _, _) in solvers.items()}
    for fname, args in (("nlp_f", (x, [])), ("nlp_g", (x, [])), ("nlp_grad_f", (x, [])),
                        ("nlp_jac_g", (x, [])), ("nlp_hess_l", (x, [], 0.7, lam))):
        ours, ref = got["auto"](fname)(*args), got["vm"](fname)(*args)
        ours = ours if isinstance(ours, (list, tuple)) else [ours]
        ref = ref if isinstance(ref, (list, tuple)) else [ref]
        for a, b in zip(ours, ref):
            a, b = np.array(ca.DM(a)), np.array(ca.DM(b))
            if fname == "nlp_hess_l":
                a, b = np.triu(a), np.triu(b)
            scale = max(1.0, np.max(np.abs(b)))
            assert np.max(np.abs(a - b)) <= 1e-10 * scale, (label, fname)


def test_derivative_modes_reach_the_same_optimum():
    """The swing-up on 10 intervals: structured derivatives in the virtual machine
    (``compile=False``), compiled per-element functions (``"elements"``; the second process-like
    solve loads them through the element index, nothing differentiated or compiled),
    ``"auto"`` (small elements: compiled, here found in the cache) and CasADi's MX derivatives
    reach the same optimum (1e-8 relative) and controls (1e-6)."""
    sols = {}
    for mode in (False, "elements", "elements", "auto", "vm"):
        ocp = load_ocp(OCP / "double_pendulum_swingup.toml")
        ocp.intervals, ocp.subintervals, ocp.compile = 10, 1, mode
        sols.setdefault(mode, []).append(ocp.solve())
    ref = sols["vm"][0]
    for mode, runs in sols.items():
        for sol in runs:
            assert abs(sol.objective - ref.objective) < 1e-8 * abs(ref.objective), mode
            np.testing.assert_allclose(sol.u, ref.u, atol=1e-6)
    assert sols[False][0].stats["derivatives"] == "structured, virtual machine"
    assert not sols[False][0].stats["compiled"]
    first, again = sols["elements"]
    if first.stats["compiled"]:  # a C compiler is there (CASMBD_COMPILE not 0)
        assert first.stats["derivatives"] == "structured, compiled elements"
        assert again.stats["cache_hit"] and again.stats["compile_seconds"] == 0.0
        auto = sols["auto"][0].stats
        assert auto["derivatives"] == "structured, compiled elements" and auto["cache_hit"]


def test_element_index_refuses_a_changed_library(tmp_path, monkeypatch):
    """The index that maps element functions to their compiled library is only followed when
    the library passes the cache's checks: after its bytes change, nothing is loaded from it
    (and the next solve builds it again, with the same optimum)."""
    import casmbd.ocp.structured as st

    monkeypatch.setenv("CASMBD_CACHE_DIR", str(tmp_path))
    ocp = load_ocp(OCP / "cart_pole.toml")
    ocp.intervals, ocp.compile = 4, "elements"
    first = ocp.solve()
    if not first.stats["compiled"]:
        pytest.skip("no C compiler (or CASMBD_COMPILE=0)")
    tr = Transcription(ocp)
    key = st._element_key(tr.calls)
    names = [f"casmbd_ocp_{key[:12]}_d{i}_{k}" for i in range(len(tr.calls))
             for k in st._KINDS]
    assert st._load_indexed("casmbd_ocp", key, names) is not None
    libraries = sorted(tmp_path.glob("casmbd_ocp_el_*.so"))
    assert libraries
    with open(libraries[0], "ab") as handle:
        handle.write(b"\0")
    assert st._load_indexed("casmbd_ocp", key, names) is None
    with pytest.warns(RuntimeWarning, match="not used"):
        again = ocp.solve()
    assert abs(again.objective - first.objective) < 1e-12 * first.objective


def test_unknown_mode_and_non_affine_arguments_are_refused():
    ocp = load_ocp(OCP / "cart_pole.toml")
    ocp.intervals, ocp.compile = 4, "fast"
    with pytest.raises(AnalysisError, match=r"compile = 'fast'.*'elements'"):
        ocp.solve()
    w = ca.MX.sym("w", 3)
    z = ca.SX.sym("z")
    call = MappedCall(ca.Function("f", [z], [z]), 3, [ca.transpose(w * w)], 0, False)
    with pytest.raises(ValueError, match="not affine"):
        _affine(call, w, 3)
