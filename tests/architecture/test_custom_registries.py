"""Kinds added by one module and its registration, from user code (issue 33, item 4), as
``examples/custom_joint.py`` shows for joints (tests/model/test_custom_kind.py):

* a transcription method, ``examples/custom_transcription.py`` (trapezoidal collocation,
  :func:`casmbd.ocp.methods.register_transcription`);
* an analysis verb, ``examples/custom_verb.py`` (``casmbd mass_properties``,
  ``casmbd.mass_properties``, swept by ``casmbd sweep --analysis mass_properties``: one
  :func:`casmbd.cli.registry.register_verb`);
* a contact shape, ``examples/custom_contact.py`` (a sphere against a fixed dome,
  :func:`casmbd.model.contacts.register_contact_shape`);

each run as a script would run it, then removed from its registry so that other tests see the
shipped registries only."""

from __future__ import annotations

import itertools
import json
import pathlib
import runpy

import numpy as np
import pytest

import casmbd
from casmbd import analysis, cli
from casmbd.analysis.studies import sweep_registry
from casmbd.cli import registry
from casmbd.errors import AnalysisError, ModelError
from casmbd.model import contacts
from casmbd.ocp import methods

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture(scope="module")
def trapezoidal():
    before = dict(methods.TRANSCRIPTIONS)
    space = runpy.run_path(str(EXAMPLES / "custom_transcription.py"),
                           run_name="custom_transcription_example")
    yield space
    methods.TRANSCRIPTIONS.clear()
    methods.TRANSCRIPTIONS.update(before)


def test_a_transcription_is_one_class_and_its_registration(trapezoidal):
    assert list(methods.TRANSCRIPTIONS) == ["radau", "legendre", "multiple_shooting",
                                            "trapezoidal"]
    with pytest.raises(ModelError, match="already registered"):
        methods.register_transcription(trapezoidal["Trapezoidal"]())
    with pytest.raises(AnalysisError, match=r"unknown transcription 'bogus'.*trapezoidal"):
        methods.transcription_method("bogus")


def test_trapezoidal_collocation_converges_at_second_order(trapezoidal):
    """Cart-pole swing-up (ocp/cart_pole.toml): the trapezoidal optimum on N = 20, 40, 80
    intervals against Radau collocation (degree 4) on 160: the differences 2.79, 0.694,
    0.156 shrink by 4.0 and 4.5 per halving (second order: 4; asserted between 3 and 6), and
    at N = 80 the two agree to 0.3 % (measured 0.29 %)."""
    solve = trapezoidal["solve"]
    reference = solve("radau", 160).objective
    sols = [solve("trapezoidal", n) for n in (20, 40, 80)]
    assert all(s.stats["transcription"] == "trapezoidal" and s.stats["success"]
               and s.stats["degree"] is None for s in sols)
    errors = [s.objective - reference for s in sols]
    assert all(e > 0 for e in errors)
    for coarse, fine in itertools.pairwise(errors):
        assert 3.0 < coarse / fine < 6.0, errors
    assert errors[-1] < 3e-3 * reference


@pytest.fixture(scope="module")
def mass_verb():
    space = runpy.run_path(str(EXAMPLES / "custom_verb.py"), run_name="custom_verb_example")
    yield space
    registry.VERBS.pop("mass_properties")
    registry.VERB_PARSERS.pop("mass_properties")
    analysis.unregister_verb("mass_properties")
    sweep_registry.unregister_sweepable("mass_properties")


SCENE = """[scene]
name = "three"
dimension = 3

[parameters]
k = 1.5

[[bodies]]
name = "a"
mass = 1.0
inertia = [0.1, 0.1, 0.1]
position = [0.0, 0.0, 0.0]

[[bodies]]
name = "b"
mass = "2 * k"
inertia = [0.1, 0.1, 0.1]
position = [1.0, 2.0, 0.0]

[[bodies]]
name = "c"
mass = 2.0
inertia = [0.1, 0.1, 0.1]
position = [0.0, -1.0, 4.0]
"""


def test_a_verb_is_one_function_and_its_registration(mass_verb, tmp_path, capsys):
    """``casmbd mass_properties``: m = 1 + 2·1.5 + 2 = 6 kg and r_G = (1·0 + 3·1 + 2·0,
    1·0 + 3·2 − 2·1, 1·0 + 3·0 + 2·4) / 6 = (0.5, 0.6667, 1.3333) m (1e-12); ``--body``
    restricts the sum; --json prints exactly one JSON object; a wrong body is one ``error:``
    line (exit 1), an unknown option a usage error (exit 2); ``--help`` lists the verb."""
    scene = tmp_path / "three.toml"
    scene.write_text(SCENE)
    assert cli.main(["mass_properties", str(scene), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["mass"] == pytest.approx(6.0, abs=1e-12)
    assert data["centre_of_mass"] == pytest.approx([0.5, 4.0 / 6.0, 8.0 / 6.0], abs=1e-12)
    assert cli.main(["mass_properties", str(scene), "--json", "--body", "b",
                     "--body", "c"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["mass"] == pytest.approx(5.0, abs=1e-12)
    assert data["centre_of_mass"] == pytest.approx([0.6, 0.8, 1.6], abs=1e-12)
    assert cli.main(["mass_properties", str(scene), "--body", "nope"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no body 'nope'" in err[0]
    assert cli.main(["mass_properties", str(scene), "--bogus"]) == 2
    capsys.readouterr()
    assert "mass_properties" in cli.build_parser().format_help()
    with pytest.raises(ModelError, match="already registered"):
        registry.register_verb("mass_properties", mass_verb["_run"])


def _closed_form(k: float) -> tuple[float, np.ndarray]:
    """m = 1 + 2k + 2 and r_G = (2k·(1, 2, 0) + 2·(0, −1, 4)) / m for SCENE's bodies."""
    m = 3.0 + 2.0 * k
    return m, (2.0 * k * np.array([1.0, 2.0, 0.0]) + 2.0 * np.array([0.0, -1.0, 4.0])) / m


def test_a_verb_is_also_its_python_name_and_sweepable(mass_verb, tmp_path, capsys):
    """The same registration makes ``casmbd.mass_properties`` (the example's function) and a
    sweepable analysis: ``sweep(mech, {"k": [0.5, 1.5, 3, 7]}, analysis="mass_properties")``
    gives at every point what calling the function at that k gives (1e-14 relative: the same
    arithmetic) and the closed form m = 3 + 2k, r_G = (2k, 4k − 2, 8) / m (1e-12); the CLI's
    ``casmbd sweep --analysis mass_properties --json`` prints the same numbers, and a name
    the verb does not offer is refused before any point runs."""
    scene = tmp_path / "three.toml"
    scene.write_text(SCENE)
    assert casmbd.mass_properties is mass_verb["mass_properties"]
    assert casmbd.analysis.mass_properties is mass_verb["mass_properties"]
    assert "mass_properties" in casmbd.__all__
    mech = casmbd.load_scene(scene)
    ks = [0.5, 1.5, 3.0, 7.0]
    res = casmbd.sweep(mech, {"k": ks}, analysis="mass_properties")
    assert res.analysis == "mass_properties" and res.failed == []
    assert res.output_names == list(mass_verb["OUTPUTS"])
    for i, k in enumerate(ks):
        one = casmbd.load_scene(scene)
        one.parameters["k"] = k
        direct = mass_verb["mass_properties"](one)
        assert res["mass"][i] == pytest.approx(direct["mass"], rel=1e-14)
        swept = [res[f"centre_of_mass_{a}"][i] for a in "xyz"]
        assert swept == pytest.approx(direct["centre_of_mass"], rel=1e-14, abs=1e-15)
        m, com = _closed_form(k)
        assert res["mass"][i] == pytest.approx(m, abs=1e-12)
        assert swept == pytest.approx(com, abs=1e-12)
    assert mech.parameters == {"k": 1.5}  # the caller's values stay
    assert cli.main(["sweep", str(scene), "--param", "k=0.5,7", "--analysis",
                     "mass_properties", "--output", "mass", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["analysis"] == "mass_properties" and data["outputs"] == ["mass"]
    assert [pt["outputs"]["mass"] for pt in data["points"]] == pytest.approx([4.0, 17.0],
                                                                             abs=1e-12)
    with pytest.raises(AnalysisError, match="output 'energy'"):
        casmbd.sweep(mech, {"k": ks}, analysis="mass_properties", outputs=["energy"])
    with pytest.raises(AnalysisError, match=r"unknown analysis 'bogus'.*mass_properties"):
        casmbd.sweep(mech, {"k": ks}, analysis="bogus")


@pytest.fixture(scope="module")
def dome():
    space = runpy.run_path(str(EXAMPLES / "custom_contact.py"), run_name="custom_contact_example")
    yield space
    contacts.CONTACT_SHAPES.pop("dome")


def test_a_contact_shape_is_one_class_and_its_registration(dome):
    """A ball (r = 0.1 m) dropped from 0.9 m above a dome (R = 1 m) with e = 0.5: the impact at
    t_i = sqrt(2 · 0.9 / g) = 0.428353 s (1e-7 s) and the height at 0.6 s after the rebound
    y = 1.1 + e g t_i (t − t_i) − g (t − t_i)² / 2 = 1.316128 m (1e-6 m; measured 1e-7:
    the integrator's tolerance); the scene and the Python build give the same run (0)."""
    assert list(contacts.CONTACT_SHAPES) == ["plane", "sphere", "dome"]
    scene = casmbd.loads_scene(dome["SCENE"])
    res = casmbd.simulate(scene, t_end=0.6, steps=60, mode="vm")
    same = casmbd.simulate(dome["python_mechanism"](), t_end=0.6, steps=60, mode="vm")
    np.testing.assert_array_equal(res["q"], same["q"])
    g, e = 9.81, 0.5
    t_i = np.sqrt(2 * 0.9 / g)
    impacts = [ev["time"] for ev in res.events if ev["kind"] == "impact"]
    assert len(impacts) == 1 and impacts[0] == pytest.approx(t_i, abs=1e-7)
    t = res.t[-1] - t_i
    y = 1.1 + e * g * t_i * t - g * t * t / 2
    assert res.body("ball")["position"][-1, 1] == pytest.approx(y, abs=1e-6)
    with pytest.raises(casmbd.SceneError, match=r"unknown contact type 'cone'.*dome"):
        casmbd.loads_scene(dome["SCENE"].replace('type = "dome"', 'type = "cone"'))
    with pytest.raises(ModelError, match="already registered"):
        contacts.register_contact_shape(dome["DomeContact"])
