"""What an element needs from an analysis: the vocabulary of the composition check.

Every element kind — body, joint, driver, actuator, force element, unilateral element
(contact, joint stop) — declares in its own class the *needs* that not every analysis can
meet, as a frozenset of the names of :data:`NEEDS` (``needs``; a property where it depends on
the element's own fields, as a contact's ``model``).  A kind that needs nothing special
(holonomic constraint equations written through the context, smooth applied forces, a rigid
body) declares the empty set, explicitly:
``tests/architecture/test_composition.py`` checks that every
kind casmbd registers declares it in its own class, so a new kind cannot fall silently through
the analyses.  Each analysis declares what it handles (:mod:`casmbd.analysis.composition`),
and one check compares the two before any work.

The model layer only names the needs; what each analysis does with them is the analysis
layer's business.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from casmbd.errors import CompositionError

__all__ = ["ALL_NEEDS", "EVENT_NEEDS", "NEEDS", "Handling", "Requirement", "check",
           "requirements"]

#: need -> what it means, in the words of an error message ("… needs …")
NEEDS: dict[str, str] = {
    "events": "impacts, contact and detach at instants found by root finding "
              "(a unilateral element of the impact model)",
    "stick_slip": "switching between sticking and sliding at instants found by root finding "
                  "(the exact Coulomb law)",
    "contact_friction": "Coulomb friction at a closed contact, switched between sliding and "
                        "sticking at events",
    "reaction_forces": "a force that depends on the joint reactions (the Lagrange multipliers "
                       "solved with the accelerations)",
    "modal_coordinates": "elastic modal coordinates (a flexible body)",
    "drivers": "motion prescribed as a function of time (a driver)",
    "inputs": "actuator inputs u(t) (an actuator)",
    "velocity_constraints": "constraints on the velocities that are not derivatives of "
                            "position constraints (rolling without slipping, a knife edge: "
                            "A(q) v + b(q, t) = 0, non-holonomic)",
}


@dataclass(frozen=True)
class Requirement:
    """One need of one element: ``element`` is its kind and name as messages say it
    (``"contact 'floor'"``), ``need`` a key of :data:`NEEDS`."""

    element: str
    need: str

    @property
    def meaning(self) -> str:
        return NEEDS[self.need]


def _declared(obj, where: str) -> frozenset[str]:
    needs = frozenset(getattr(obj, "needs", frozenset()))
    unknown = needs - NEEDS.keys()
    if unknown:  # a kind declaring a need nobody knows is a programming error of that kind
        raise ValueError(f"{where}: unknown needs {sorted(unknown)} (known: {sorted(NEEDS)})")
    return needs


def requirements(mechanism) -> list[Requirement]:
    """Every need of every element of ``mechanism``, in declaration order (bodies, joints,
    drivers, actuators, force elements, unilateral elements)."""
    groups = (("body", mechanism.bodies), ("joint", mechanism.joints),
              ("driver", mechanism.drivers), ("actuator", mechanism.actuators),
              ("force", mechanism.forces), ("contact", mechanism.contacts))
    found = []
    for noun, table in groups:
        for name, element in table.items():
            kind = "joint limit" if getattr(element, "event_kind", "") == "limit" else noun
            label = f"{kind} '{name}'"
            found.extend(Requirement(label, need)
                         for need in sorted(_declared(element, label)))
    return found


#: needs that a run meets only on the event-driven path (root finding, impulses, phases)
EVENT_NEEDS = frozenset({"events", "stick_slip", "contact_friction"})


@dataclass(frozen=True)
class Handling:
    """What one analysis handles: the declaration an analysis module makes (``HANDLING``).

    Attributes
    ----------
    analysis : str
        Its name in messages (``"inverse dynamics"``).
    handles : frozenset of str
        The needs (:data:`NEEDS`) it meets.
    why : dict
        need -> why it does not meet it (for the needs it refuses).
    instead : dict
        need -> what to use instead.
    notes : dict
        need -> how it meets a need it handles in a way the user should know (stated in the
        documentation's composition table, e.g. "flexible bodies move rigidly").
    """

    analysis: str
    handles: frozenset
    why: dict = field(default_factory=dict)
    instead: dict = field(default_factory=dict)
    notes: dict = field(default_factory=dict)

    def restricted(self, analysis: str, handles, why: dict | None = None,
                   instead: dict | None = None) -> Handling:
        """This handling narrowed to ``handles`` (an option that meets fewer needs), named
        ``analysis``, with extra reasons."""
        return Handling(analysis, self.handles & frozenset(handles),
                        {**self.why, **(why or {})}, {**self.instead, **(instead or {})},
                        self.notes)

    def refusals(self, mechanism) -> list[Requirement]:
        """The requirements of ``mechanism`` this analysis does not meet."""
        return [r for r in requirements(mechanism) if r.need not in self.handles]


#: every need, for analyses that take any mechanism (drawing, info)
ALL_NEEDS = frozenset(NEEDS)


def check(mechanism, handling: Handling) -> None:
    """The composition check: refuse, before any work, a mechanism with an element whose
    needs ``handling`` does not meet — by name, with why and what to use instead.

    Raises
    ------
    CompositionError
        Naming every refused element and its need.
    """
    mechanism = mechanism if hasattr(mechanism, "bodies") else \
        getattr(mechanism, "mechanism", None)
    if not hasattr(mechanism, "bodies"):  # not a mechanism: the caller's own check names it
        return
    refused = handling.refusals(mechanism)
    if not refused:
        return
    lines = []
    for need in dict.fromkeys(r.need for r in refused):
        named = [r.element for r in refused if r.need == need]
        line = f"{', '.join(named)} need{'s' if len(named) == 1 else ''} {NEEDS[need]}"
        why = handling.why.get(need)
        line += f", which {handling.analysis} does not handle" + (f" ({why})" if why else "")
        if need in handling.instead:
            line += f"; instead: {handling.instead[need]}"
        lines.append(line)
    raise CompositionError(f"{handling.analysis}: " + "; ".join(lines),
                           handling.analysis, [(r.element, r.need) for r in refused])
