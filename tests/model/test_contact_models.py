"""Contact models are a registry (:mod:`casmbd.model.contact_models`, issue 33 item 4): each
model says what it needs (the composition check reads it through the element's ``needs``) and
how it acts (the event machinery or a force element); the analyses ask the model, never its
name.  Shown by two models registered from user code that act as the shipped ones: their
runs equal the shipped models' runs number for number."""

from __future__ import annotations

import numpy as np
import pytest
from composition_scenes import VARIANTS

import casmbd
from casmbd.errors import CompositionError, ModelError
from casmbd.model import contact_models
from casmbd.model.contact_models import CONTACT_MODELS, ContactModel, register_contact_model
from casmbd.model.needs import NEEDS
from casmbd.model.registry import FORCE_KINDS


def test_every_model_declares_needs_and_has_canonical_scenes():
    """Needs are names of casmbd.model.needs.NEEDS, a force model's kind is registered, and
    every model has a contact and a stop scene in the composition matrix."""
    assert list(CONTACT_MODELS) == ["impact", "compliant"]
    for name, model in CONTACT_MODELS.items():
        assert model.needs | model.sliding_needs <= NEEDS.keys(), name
        assert model.force is None or model.force in FORCE_KINDS, name
        assert model.events != (model.force is not None), name  # one way of acting
        assert f"contact_{name}" in VARIANTS and f"stop_{name}" in VARIANTS, name


@pytest.fixture
def custom_models():
    """'soft' acts as 'compliant' (a penalty force), 'plastic' as 'impact' (events)."""
    register_contact_model(ContactModel("soft", force="compliant_contact"))
    register_contact_model(ContactModel("plastic", events=True, needs=frozenset({"events"}),
                                        sliding_needs=frozenset({"contact_friction"})))
    yield
    CONTACT_MODELS.pop("soft")
    CONTACT_MODELS.pop("plastic")


def _ball(model: str, **keys):
    """A ball (r = 0.1 m) dropped from 0.3 m onto a floor, planar."""
    m = casmbd.Mechanism(f"ball_{model}", gravity=(0.0, -9.81))
    m.add_body("ball", mass=1.0, inertia=0.004, position=(0.0, 0.3))
    m.add_contact("floor", "ball", point=(0.0, 0.3), radius=0.1, origin=(0.0, 0.0),
                  normal=(0.0, 1.0), model=model, **keys)
    return m


def test_a_force_model_from_user_code_runs_as_compliant(custom_models):
    """model = 'soft' (force kind compliant_contact): the same force element, needs nothing,
    and a simulation over 0.5 s (k = 1e5 N/m, c = 50 N s/m) equals the compliant model's to
    1e-12 m, with the same grid-found contact and detach events (1e-12 s)."""
    runs = []
    for model in ("compliant", "soft"):
        mech = _ball(model, stiffness=1e5, damping=50.0)
        assert mech.contacts["floor"].needs == frozenset()
        assert "floor.force" in mech.forces
        runs.append(casmbd.simulate(mech, 0.5, 100))
    ref, soft = runs
    assert np.abs(soft["q"] - ref["q"]).max() <= 1e-12
    assert ref.events and len(soft.events) == len(ref.events)
    for a, b in zip(ref.events, soft.events):
        assert a["kind"] == b["kind"] and abs(a["time"] - b["time"]) <= 1e-12


def test_an_event_model_from_user_code_runs_as_impact(custom_models):
    """model = 'plastic' (events): needs events, refused by inverse dynamics (named), and its
    run with e = 0.5 equals the impact model's: the impact at t = sqrt(2·0.2/g) = 0.201929 s
    (1e-7 s), the same events and positions (1e-12)."""
    runs = []
    for model in ("impact", "plastic"):
        mech = _ball(model, restitution=0.5)
        assert mech.contacts["floor"].needs == frozenset({"events"})
        runs.append(casmbd.simulate(mech, 0.5, 50))
    ref, plastic = runs
    first = ref.events[0]
    assert first["kind"] == "impact"
    assert first["time"] == pytest.approx(np.sqrt(2 * 0.2 / 9.81), abs=1e-7)
    assert [(e["kind"], e["element"]) for e in plastic.events] == \
        [(e["kind"], e["element"]) for e in ref.events]
    assert np.allclose([e["time"] for e in plastic.events], [e["time"] for e in ref.events],
                       rtol=0, atol=1e-12)
    assert np.abs(plastic["q"] - ref["q"]).max() <= 1e-12
    with pytest.raises(CompositionError, match="contact 'floor'"):
        casmbd.inverse_dynamics(_ball("plastic", restitution=0.5), t_end=0.1, steps=2)


def test_model_messages_come_from_the_registry(custom_models):
    """An unknown model names the registered ones; keys of a force model given to an event
    model, and a rest velocity given to a force model, name the models they apply to."""
    with pytest.raises(ModelError, match=r"field 'model': expected one of \('impact', "
                                         r"'compliant', 'soft', 'plastic'\), got 'bogus'"):
        _ball("bogus")
    with pytest.raises(ModelError, match=r"stiffness apply to model = 'compliant' or 'soft'"):
        _ball("plastic", stiffness=1e5)
    with pytest.raises(ModelError, match=r"applies to model = 'impact' or 'plastic'"):
        _ball("soft", stiffness=1e5, rest_velocity=0.1)
    with pytest.raises(ModelError, match="already registered"):
        register_contact_model(ContactModel("soft"))
    with pytest.raises(ModelError, match="a contact model is a ContactModel"):
        register_contact_model("soft")
    assert contact_models.contact_model("soft").force == "compliant_contact"


def test_shipped_messages_are_unchanged():
    with pytest.raises(ModelError, match=r"expected one of \('impact', 'compliant'\), got "
                                         r"'bogus'"):
        _ball("bogus")
    with pytest.raises(ModelError, match=r"stiffness apply to model = 'compliant'$"):
        _ball("impact", stiffness=1e5)
    with pytest.raises(ModelError, match=r"applies to model = 'impact'$"):
        _ball("compliant", stiffness=1e5, rest_velocity=0.1)
