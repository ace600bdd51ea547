"""Contact models: how the gaps of a unilateral element (a contact, a joint stop) act — the
``model`` of :class:`casmbd.model.contacts.Unilateral` — registered by name.

Each :class:`ContactModel` declares what it needs from an analysis (the composition check,
:mod:`casmbd.model.needs`, reads it through the element's ``needs``) and how it enters the
equations or the event machinery:

* ``"impact"`` — ``events=True``: the gaps are event functions (root finding on g, Newton's
  restitution impulses, closed phases as bilateral constraints; Pfeiffer & Glocker 1996,
  :mod:`casmbd.analysis.events`); needs ``events``, and ``contact_friction`` where a plane
  contact with friction slides or sticks in its closed phases;
* ``"compliant"`` — ``force="compliant_contact"``: a penalty force element
  (:class:`casmbd.model.contacts.CompliantContact`, ``"<name>.force"``) added with the
  element's own keys (stiffness, damping …); smooth, needs nothing special.

The analyses ask the model, never its name: :func:`acts_at_events` (which elements the event
machinery, the resting statics, the linearisation and the sensitivities treat as gaps) and
:attr:`ContactModel.force`.  The registry is complete on import; a model from user code is one
:func:`register_contact_model` (with, for a force model, its force kind registered by
:func:`casmbd.model.registry.register_force`).
"""

from __future__ import annotations

from dataclasses import dataclass

from casmbd.errors import ModelError

__all__ = ["CONTACT_MODELS", "ContactModel", "acts_at_events", "contact_model",
           "models_where", "register_contact_model"]


@dataclass(frozen=True)
class ContactModel:
    """How the gaps of a unilateral element act (its ``model``)."""

    name: str
    #: the gaps act at events: root finding, impulses, closed phases (casmbd.analysis.events)
    events: bool = False
    #: the force kind (casmbd.model.registry.FORCE_KINDS) that writes the element into the
    #: equations as the force element "<name>.force", created with the element and its own
    #: keys; None: no force element (the keys are refused)
    force: str | None = None
    #: what every element of this model needs from an analysis (casmbd.model.needs.NEEDS)
    needs: frozenset[str] = frozenset()
    #: what it needs besides where the element slides: a plane contact with friction whose
    #: closed phases carry Coulomb friction (:func:`casmbd.model.contacts.slides`)
    sliding_needs: frozenset[str] = frozenset()


#: model name -> its ContactModel; complete when this module is imported (impact, compliant)
CONTACT_MODELS: dict[str, ContactModel] = {}


def register_contact_model(model: ContactModel, *, replace: bool = False) -> ContactModel:
    """Register ``model`` under its name; a taken name is a :class:`ModelError` unless
    ``replace``."""
    if not isinstance(model, ContactModel) or not model.name.isidentifier():
        raise ModelError(f"a contact model is a ContactModel with a name, got {model!r}")
    if model.name in CONTACT_MODELS and not replace:
        raise ModelError(f"contact model '{model.name}' is already registered; pass "
                         "replace=True to replace it")
    CONTACT_MODELS[model.name] = model
    return model


def contact_model(name: str, where: str = "contact") -> ContactModel:
    """The model ``name``; an unknown one is a :class:`ModelError` naming ``where``'s field
    and the known models."""
    model = CONTACT_MODELS.get(name) if isinstance(name, str) else None
    if model is None:
        raise ModelError(f"{where} field 'model': expected one of {tuple(CONTACT_MODELS)}, "
                         f"got {name!r}")
    return model


def acts_at_events(element) -> bool:
    """Whether the gaps of the unilateral ``element`` act at events (its model's
    :attr:`ContactModel.events`)."""
    return CONTACT_MODELS[element.model].events


def models_where(predicate) -> str:
    """The models for which ``predicate(model)`` holds, as messages name them
    (``"'compliant'"``, ``"'a' or 'b'"``)."""
    return " or ".join(f"'{m.name}'" for m in CONTACT_MODELS.values() if predicate(m))


register_contact_model(ContactModel("impact", events=True, needs=frozenset({"events"}),
                                    sliding_needs=frozenset({"contact_friction"})))
register_contact_model(ContactModel("compliant", force="compliant_contact"))
