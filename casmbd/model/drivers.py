"""Drivers: rheonomic constraints C(q, t) = s(q) − f(t) that prescribe a coordinate in time.

Seed 000, "Driving constraints": a driving constraint adds one equation whose multiplier gives
the effort (force or torque) needed to impose the motion (section "Inverse dynamics").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from casmbd.errors import ModelError
from casmbd.model.values import Value, check_value

BODY_COORDINATES = {2: ("x", "y", "angle"), 3: ("x", "y", "z")}


@dataclass
class Driver:
    """Prescribe a joint coordinate (``joint``, with ``coordinate`` naming one of a
    multi-coordinate joint's coordinates) or a body coordinate (``body`` + ``coordinate``: x, y
    and angle in the plane, x, y and z of the reference point in space).

    ``position`` is a value of time (number, expression string over ``t`` and parameters, or
    callable ``f(t)`` / ``f(t, p)``).
    """

    name: str
    position: Value
    joint: str | None = None
    body: str | None = None
    #: what it needs from an analysis (casmbd.model.needs)
    needs: ClassVar[frozenset[str]] = frozenset({"drivers"})

    coordinate: str | None = None

    def __post_init__(self):
        where = f"driver '{self.name}'"
        self.position = check_value(self.position, f"{where} field 'position'")
        if (self.joint is None) == (self.body is None):
            raise ModelError(f"{where}: give either 'joint' or 'body' + 'coordinate'")
        known = BODY_COORDINATES[2] + ("z",)
        if self.body is not None and self.coordinate not in known:
            raise ModelError(f"{where} field 'coordinate': expected one of "
                             f"{', '.join(known)}, got {self.coordinate!r}")

    @property
    def target(self) -> str:
        """Human-readable name of the driven coordinate."""
        if self.joint:
            return f"joint '{self.joint}'" + (f" {self.coordinate}" if self.coordinate else "")
        return f"body '{self.body}' {self.coordinate}"
