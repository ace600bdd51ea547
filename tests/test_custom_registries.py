"""Kinds added by one module and its registration, from user code (issue 33, item 4), as
``examples/custom_joint.py`` shows for joints (tests/test_custom_kind.py):

* a transcription method, ``examples/custom_transcription.py`` (trapezoidal collocation,
  :func:`casmbd.ocp.methods.register_transcription`);

each run as a script would run it, then removed from its registry so that other tests see the
shipped registries only."""

from __future__ import annotations

import itertools
import pathlib
import runpy

import pytest

from casmbd.errors import AnalysisError, ModelError
from casmbd.ocp import methods

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


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
