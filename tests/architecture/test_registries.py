"""Formulation and integrator registries (issue 20, item 2).

Every registered formulation runs the same mechanisms and agrees with the default; unknown names
raise :class:`~casmbd.errors.UnknownMethodError` listing the registered names (the CLI keeps its
usage error, exit status 2, with the registry's choices); a formulation or integrator
registered from outside the package is selectable by name, in Python and on the command line.
"""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import cli
from casmbd.analysis.dynamics.simulate import Simulator, simulate
from casmbd.analysis.formulations import (
    FORMULATIONS,
    FormulationKind,
    Index1,
    formulation_kind,
    register_formulation,
)
from casmbd.analysis.integrators import kinds as integ
from casmbd.analysis.integrators import sundials as sun
from casmbd.analysis.integrators.fixed_step import FixedStepKind, rk4_step
from casmbd.analysis.integrators.kinds import INTEGRATORS
from casmbd.analysis.integrators.sundials import SundialsKind
from casmbd.errors import AnalysisError, ModelError, UnknownMethodError
from casmbd.ocp import Ocp
from casmbd.system import System

ROOT = pathlib.Path(__file__).resolve().parents[2]
DOUBLE_PENDULUM = str(ROOT / "examples" / "double_pendulum.toml")
G = 9.81
#: rtol = atol of the agreement runs
TOL = 1e-10


_cache = private_cache("cache_reg")


def pendulum() -> casmbd.Mechanism:
    """Slender rod pinned at one end, released horizontally (absolute coordinates: n_c = 2;
    set explicitly, the automatic choice takes the pivot angle and no equation)."""
    m = casmbd.Mechanism("pendulum", gravity=(0.0, -G), coordinates="absolute")
    m.add_body("rod", 1.0, 1.0 / 12, (0.5, 0.0))
    m.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
    return m


def _run(mech, formulation=None, integrator=None):
    return Simulator(mech, formulation, mode="vm").run(1.0, 10, integrator=integrator,
                                                       rtol=TOL, atol=TOL)


@pytest.fixture(scope="module")
def tree_reference():
    """The double pendulum in joint coordinates (a tree: the default is ``articulated``)."""
    return _run(System(casmbd.load_scene(DOUBLE_PENDULUM), coordinates="joint"))


@pytest.fixture(scope="module")
def pendulum_reference():
    return _run(pendulum())


@pytest.mark.parametrize("name", list(FORMULATIONS))
def test_every_formulation_agrees_on_a_joint_coordinate_double_pendulum(name, tree_reference):
    """q to 1e-7 rad and v to 1e-6 rad/s over 1 s against the default (articulated) at
    rtol = atol = 1e-10 (measured at most 2.2e-9 and 1.9e-8, nullspace/partitioning)."""
    res = _run(System(casmbd.load_scene(DOUBLE_PENDULUM), coordinates="joint"), name)
    assert res.stats["formulation"] == name
    assert res.stats["integrator"] == formulation_kind(name).default_integrator
    assert np.max(np.abs(res["q"] - tree_reference["q"])) < 1e-7
    assert np.max(np.abs(res["v"] - tree_reference["v"])) < 1e-6


@pytest.mark.parametrize("name", list(FORMULATIONS))
def test_every_formulation_agrees_on_an_absolute_coordinate_pendulum(name, pendulum_reference):
    """q to 1e-7, v to 1e-6 and the pivot multipliers to 1e-5 N over 1 s against the default
    (augmented_lagrangian) at rtol = atol = 1e-10.  A formulation that needs a tree in joint
    coordinates (``articulated``) refuses the absolute-coordinate pendulum by name."""
    mech = pendulum()
    try:
        res = _run(mech, name)
    except ModelError as exc:
        assert "joint coordinates" in str(exc), str(exc)
        assert not formulation_kind(name).preferred_for(System(mech))
        return
    assert res.stats["formulation"] == name
    assert np.max(np.abs(res["q"] - pendulum_reference["q"])) < 1e-7
    assert np.max(np.abs(res["v"] - pendulum_reference["v"])) < 1e-6
    assert np.max(np.abs(res["lambda"] - pendulum_reference["lambda"])) < 1e-5


def test_every_formulation_declares_a_registered_default_integrator_that_accepts_it():
    for name, kind in FORMULATIONS.items():
        assert kind.name == name
        assert INTEGRATORS[kind.default_integrator].integrates(kind.kind), name


def test_unknown_formulation_names_the_choices():
    with pytest.raises(UnknownMethodError) as info:
        Simulator(pendulum(), "index_1")
    assert isinstance(info.value, AnalysisError)
    assert info.value.choices == tuple(FORMULATIONS)
    assert str(info.value).startswith("unknown formulation 'index_1' (known: index1, ggl, ")
    for name in FORMULATIONS:
        assert name in str(info.value)
    with pytest.raises(UnknownMethodError, match=r"unknown formulation 'kkt'"):
        formulation_kind("kkt")


def test_unknown_integrator_names_the_choices():
    with pytest.raises(UnknownMethodError) as info:
        simulate(pendulum(), 1.0, 2, integrator="rk5", mode="vm")
    assert info.value.choices == tuple(INTEGRATORS) == ("idas", "cvodes", "adams", "rk4", "abm",
                                                         "dopri5")
    assert str(info.value) == ("unknown integrator 'rk5' (known: idas, cvodes, adams, rk4, "
                               "abm, dopri5)")
    with pytest.raises(UnknownMethodError, match=r"unknown integrator 'lsoda'"):
        sun.sundials(Simulator(pendulum(), "kkt_ode", mode="vm").dyn, "lsoda", 0.0, [1.0],
                       1e-8, 1e-8, 100)


def test_integrator_that_cannot_integrate_the_formulation_names_the_ones_that_can():
    with pytest.raises(AnalysisError, match=r"integrator 'adams' cannot integrate the DAE "
                                            r"formulation 'index1' \(use one of idas\)"):
        simulate(pendulum(), 1.0, 2, formulation="index1", integrator="adams", mode="vm")
    with pytest.raises(AnalysisError, match=r"cannot integrate the NUMERIC formulation "
                                            r"'nullspace' \(use one of cvodes, adams\)"):
        simulate(pendulum(), 1.0, 2, formulation="nullspace", integrator="rk4", mode="vm")


def test_ocp_shooting_integrators_come_from_the_registry():
    """Only registered kinds that serve multiple shooting are accepted (rk4, cvodes)."""
    assert integ.names(shooting=True) == ["cvodes", "rk4"]
    with pytest.raises(AnalysisError, match=r"ocp: integrator must be one of cvodes, rk4 "
                                            r"\(casmbd.analysis.integrators.kinds\), got 'abm'"):
        Ocp(pendulum(), integrator="abm")


@pytest.mark.parametrize(("option", "value"), [("--formulation", "index_1"),
                                                ("--integrator", "rk5")])
def test_cli_usage_error_lists_the_registered_choices(capsys, option, value):
    status = cli.main(["simulate", DOUBLE_PENDULUM, "--t-end", "0.1", "--steps", "2",
                       option, value])
    err = capsys.readouterr().err
    assert status == 2
    assert option in err and repr(value) in err
    registry = FORMULATIONS if option == "--formulation" else INTEGRATORS
    for name in registry:
        assert repr(name) in err, name


class Index1Copy(Index1):
    """A trivial user formulation: the index-1 DAE under another name."""

    name = "index1_copy"


def test_formulation_registered_from_outside_is_selectable(monkeypatch, capsys):
    """Registered from this test (and removed afterwards), it runs through ``simulate`` and
    the CLI's ``--formulation``, bit-identical to the formulation it copies."""
    monkeypatch.setitem(FORMULATIONS, "index1_copy", FORMULATIONS["index1"])  # restored after
    register_formulation(Index1Copy())
    assert isinstance(FORMULATIONS["index1_copy"], FormulationKind)
    copy = simulate(pendulum(), 1.0, 10, formulation="index1_copy", mode="vm")
    ref = simulate(pendulum(), 1.0, 10, formulation="index1", mode="vm")
    assert copy.stats["formulation"] == "index1_copy"
    assert copy.stats["integrator"] == "idas"
    for key in ("q", "v", "a", "lambda"):
        assert np.array_equal(copy[key], ref[key]), key
    status = cli.main(["simulate", DOUBLE_PENDULUM, "--t-end", "0.1", "--steps", "2",
                       "--formulation", "index1_copy", "--mode", "vm"])
    out = capsys.readouterr().out
    assert status == 0
    assert "index1_copy on idas" in out


def test_integrators_registered_from_outside_are_selectable(monkeypatch):
    """A SUNDIALS kind (CVODES BDF under another name) and a fixed-step kind (RK4 under
    another name) reproduce the registered originals bit for bit."""
    monkeypatch.setitem(INTEGRATORS, "bdf_copy", None)  # restored after the test
    monkeypatch.setitem(INTEGRATORS, "rk4_copy", None)
    integ.register_integrator(SundialsKind("bdf_copy", "BDF", numeric=True, plugin="cvodes",
                                           options=(("linear_multistep_method", "bdf"),)))
    integ.register_integrator(FixedStepKind("rk4_copy", "RK4", step_builder=rk4_step))
    sim = Simulator(pendulum(), "kkt_ode", mode="vm")
    for copy, original in (("bdf_copy", "cvodes"), ("rk4_copy", "rk4")):
        a = sim.run(1.0, 10, integrator=copy)
        b = sim.run(1.0, 10, integrator=original)
        assert a.stats["integrator"] == copy
        assert np.array_equal(a["q"], b["q"]) and np.array_equal(a["v"], b["v"]), copy


def test_registering_something_else_is_refused():
    with pytest.raises(ModelError, match="register_formulation: a FormulationKind"):
        register_formulation("index1")
    with pytest.raises(ModelError, match="register_integrator: an IntegratorKind"):
        integ.register_integrator("rk4")


#: every formulation casmbd ships (issue 30, item 4h)
SHIPPED = ("index1", "ggl", "kkt_ode", "augmented_lagrangian", "articulated", "nullspace",
           "partitioning")


def test_formulation_registry_is_complete_on_import_in_a_fresh_process():
    """Importing the registry's package alone registers every shipped formulation, loads no
    analysis module outside its room, and the CLI's ``--formulation`` choices are exactly the
    registry
    (issue 30, item 4h: nullspace and partitioning used to register by a side-effect import
    of the analysis layer, so a fresh CLI refused them)."""
    code = ("import sys, casmbd.analysis.formulations as f; "
            "print(','.join(f.FORMULATIONS)); "
            "print(any(m.startswith('casmbd.analysis.') and not "
            "m.startswith('casmbd.analysis.formulations') for m in sys.modules)); "
            "from casmbd import cli; "
            "sub = next(a for a in cli.build_parser()._actions if a.dest == 'verb'); "
            "act = next(a for a in sub.choices['simulate']._actions "
            "if a.dest == 'formulation'); "
            "print(','.join(act.choices)); print(','.join(f.FORMULATIONS))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, check=True).stdout.split()
    assert out[0] == ",".join(SHIPPED)
    assert out[1] == "False"
    assert out[2] == out[3] == ",".join(SHIPPED)


@pytest.mark.parametrize("name", ["nullspace", "partitioning"])
def test_fresh_cli_runs_a_numeric_formulation(name, tmp_path):
    """``python -m casmbd simulate … --formulation nullspace`` in a fresh process runs, and the
    double pendulum's end state equals the default formulation's to 1e-6 (rtol = 1e-10)."""
    def run(*extra):
        out = tmp_path / f"{extra[-1] if extra else 'default'}.npz"
        proc = subprocess.run([sys.executable, "-m", "casmbd", "simulate", DOUBLE_PENDULUM,
                               "--t-end", "0.5", "--steps", "5", "--rtol", "1e-10", "--mode",
                               "vm", "--json", "--out", str(out), *extra],
                              capture_output=True, text=True, cwd=ROOT, timeout=600)
        assert proc.returncode == 0, proc.stderr
        return json.loads(proc.stdout), casmbd.Result.load(str(out))
    info, res = run("--formulation", name)
    assert info["stats"]["formulation"] == name
    _, ref = run()
    assert np.allclose(res["q"][-1], ref["q"][-1], rtol=0, atol=1e-6)
