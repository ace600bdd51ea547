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
#: the coordinate of a spatial body's orientation driver (three rows, :class:`OrientationDriver`)
ORIENTATION = "orientation"
#: how an orientation driver states A_d(t), and how many expressions each form takes
ORIENTATION_FORMS = {"euler_zxz": 3, "rpy": 3, "quaternion": 4}
#: the rows of an orientation driver: the moment about the global x, y and z axes
ORIENTATION_ROWS = ("x", "y", "z")


@dataclass
class Driver:
    """Prescribe a joint coordinate (``joint``, with ``coordinate`` naming one of a
    multi-coordinate joint's coordinates) or a body coordinate (``body`` + ``coordinate``: x, y
    and angle in the plane, x, y and z of the reference point in space).

    ``position`` is a value of time (number, expression string over ``t`` and parameters, or
    callable ``f(t)`` / ``f(t, p)``). A spatial body's orientation is driven by three rows,
    :class:`OrientationDriver` (``Mechanism.add_driver(..., coordinate="orientation")``).
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
        known = BODY_COORDINATES[2] + ("z",) + ((ORIENTATION,) if self.orientation_row
                                                else ())
        if self.body is not None and self.coordinate not in known:
            raise ModelError(f"{where} field 'coordinate': expected one of "
                             f"{', '.join(known)}, got {self.coordinate!r}")

    #: the orientation driver this row belongs to (None for a scalar driver)
    orientation_row = None

    @property
    def target(self) -> str:
        """Human-readable name of the driven coordinate."""
        if self.joint:
            return f"joint '{self.joint}'" + (f" {self.coordinate}" if self.coordinate else "")
        return f"body '{self.body}' {self.coordinate}"


@dataclass
class OrientationDriver(Driver):
    """One of the three rows of an orientation driver: a spatial body's rotation A equals
    A_d(t) (``coordinate = "orientation"``).

    The prescribed rotation is three Z-X-Z Euler angles (``form = "euler_zxz"``, as a body's
    ``euler_zxz``: A_d = A_Z(φ) A_X(θ) A_Z(ψ)), roll-pitch-yaw (``"rpy"``, URDF's fixed-axis
    X-Y-Z: A_d = A_Z(yaw) A_Y(pitch) A_X(roll)) or a quaternion (``"quaternion"``, [w, x, y,
    z], normalised). The three equations are the Gibbs (Rodrigues) vector of the error
    rotation R_e = A A_dᵀ = rotation by θ about n (global axes),

        C = 2 axial(R_e − R_eᵀ) / (1 + tr R_e) = 2 tan(θ/2) n = 2 r_v / r_0,

    r = (r_0, r_v) the error quaternion p ⊗ p_d*: the vector part of r scaled by 2/r_0, so C
    = 0 only at R_e = I, the same for ±p, and written with A alone (every coordinate
    choice). At the solution δC = δπ (the global virtual rotation), so the multipliers are
    the moment about the global axes at the body's reference point: the effort of row
    ``axis`` is the moment component −λ (Seed 000, "Driving constraints"; seed 001,
    "Angular velocity"). The Jacobian is regular while r_0 ≠ 0, i.e. for error rotations
    below a half-turn; it fails (C → ∞) at θ = ±180°, which a solve started from the
    previous time step never approaches.

    ``position`` is the row's own expression (its angle, or its quaternion component), kept
    so that the value checks see every expression; ``angles`` holds all of them.
    """

    angles: tuple = ()
    form: str = "euler_zxz"
    axis: int = 0
    group: str = ""

    @property
    def orientation_row(self) -> str:
        """The name of the orientation driver this row belongs to."""
        return self.group

    @property
    def target(self) -> str:
        return (f"body '{self.body}' orientation ({self.form}, the rotation about "
                f"{ORIENTATION_ROWS[self.axis]})")


def orientation_rows(name: str, body: str, form: str, angles) -> list[OrientationDriver]:
    """The three :class:`OrientationDriver` rows ``<name>.x``, ``<name>.y``, ``<name>.z`` of
    an orientation driver of ``body`` (``angles``: the expressions of ``form``)."""
    where = f"driver '{name}'"
    if form not in ORIENTATION_FORMS:
        raise ModelError(f"{where}: an orientation is given as one of "
                         f"{', '.join(ORIENTATION_FORMS)}, got {form!r}")
    size = ORIENTATION_FORMS[form]
    if isinstance(angles, (str, bytes)) or not hasattr(angles, "__len__") \
            or len(angles) != size:
        raise ModelError(f"{where} field '{form}': expected {size} expressions of t, got "
                         f"{angles!r}")
    checked = tuple(check_value(a, f"{where} field '{form}' [{i}]")
                    for i, a in enumerate(angles))
    return [OrientationDriver(f"{name}.{row}", checked[min(k, size - 1)], body=body,
                              coordinate=ORIENTATION, angles=checked, form=form, axis=k,
                              group=name)
            for k, row in enumerate(ORIENTATION_ROWS)]
