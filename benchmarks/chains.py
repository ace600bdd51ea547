"""Parametric test mechanisms for benchmarks and scaling tests.

The main entry point is :func:`pendulum_chain`, an N-link planar pendulum whose size is a single
integer, so that the cost of building, compiling and evaluating the equations can be measured as
a function of the number of bodies.

Example
-------
>>> mech = pendulum_chain(3)
>>> len(mech.bodies), len(mech.joints), list(mech.markers)
(3, 3, ['tip'])
"""

from __future__ import annotations

from casmbd.model import Mechanism

__all__ = ["body_name", "joint_name", "pendulum_chain", "spatial_chain"]


def body_name(i: int) -> str:
    """Name of the ``i``-th rod (0-based) of a :func:`pendulum_chain`: ``"rod{i}"``."""
    return f"rod{i}"


def joint_name(i: int) -> str:
    """Name of the ``i``-th pin (0-based) of a :func:`pendulum_chain`: ``"pin{i}"``.

    ``pin0`` connects the ground to ``rod0``; ``pin{i}`` connects ``rod{i-1}`` to ``rod{i}``.
    """
    return f"pin{i}"


def pendulum_chain(
    n: int, length: float = 1.0, mass: float = 1.0, gravity: float = 9.81
) -> Mechanism:
    """N slender rods pinned end to end, hanging from the ground at the origin.

    At rest the chain lies horizontally along +x: rod ``i`` (named ``"rod{i}"``, 0-based) has its
    centre of mass at ``((i + 0.5) * length, 0)``, angle 0, and the inertia of a slender rod about
    its centre, ``mass * length**2 / 12``.  Revolute joint ``"pin0"`` pins ``rod0`` to the ground
    at the origin and ``"pin{i}"`` pins ``rod{i-1}`` to ``rod{i}`` at ``(i * length, 0)``.  A
    marker ``"tip"`` sits on the free end of the last rod, at ``(n * length, 0)``.  Gravity is
    ``(0, -gravity)``.

    The mechanism has ``3 n`` coordinates, ``2 n`` constraint equations and ``n`` degrees of
    freedom; the mass matrix is diagonal (centroidal frames) and the constraint Jacobian has
    ``8 n - 4`` structural non-zeros.

    Parameters
    ----------
    n : int
        Number of rods, at least 1.
    length : float, optional
        Length of every rod in metres (default 1).
    mass : float, optional
        Mass of every rod in kilograms (default 1).
    gravity : float, optional
        Magnitude of the gravitational acceleration, acting along −y (default 9.81).

    Returns
    -------
    casmbd.model.Mechanism
        The mechanism, named ``"chain{n}"``.

    Raises
    ------
    ValueError
        When ``n`` is not a positive integer or ``length`` is not positive.
    """
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"pendulum_chain: n must be a positive integer, got {n!r}")
    if not length > 0.0:
        raise ValueError(f"pendulum_chain: length must be > 0, got {length!r}")
    n = int(n)
    mech = Mechanism(f"chain{n}", gravity=(0.0, -float(gravity)))
    inertia = mass * length**2 / 12.0
    previous = "ground"
    for i in range(n):
        body = body_name(i)
        mech.add_body(body, mass=mass, inertia=inertia, position=((i + 0.5) * length, 0.0))
        mech.add_revolute(joint_name(i), previous, body, point=(i * length, 0.0))
        previous = body
    mech.add_marker("tip", previous, point=(n * length, 0.0))
    return mech


def spatial_chain(n: int, length: float = 1.0, mass: float = 1.0, gravity: float = 9.81,
                  coordinates: str = "absolute") -> Mechanism:
    """N slender rods joined by spherical joints, hanging from the ground: a spatial chain.

    Rod ``i`` lies along +x with its centre at ``((i + 0.5) length, 0, 0)``; ``"pin0"`` is a
    spherical joint to the ground at the origin and ``"pin{i}"`` joins ``rod{i-1}`` and
    ``rod{i}`` at ``(i length, 0, 0)``.  The inertia is that of a rod of radius length/20
    (``I_xx = m r²/2``, ``I_yy = I_zz = m (3 r² + L²)/12``) so that the spin about the rod axis
    is a genuine degree of freedom.  Gravity is ``(0, 0, −gravity)``; a marker ``"tip"`` sits
    on the free end.  The chain has ``3 n`` degrees of freedom; with Euler parameters
    ``7 n`` coordinates and ``4 n`` constraint equations (natural coordinates: ``12 n`` and
    ``9 n``).
    """
    if int(n) < 1:
        raise ValueError(f"spatial_chain needs n >= 1, got {n!r}")
    n = int(n)
    radius = length / 20.0
    i_axis = mass * radius**2 / 2.0
    i_trans = mass * (3.0 * radius**2 + length**2) / 12.0
    mech = Mechanism(f"spatial_chain{n}", gravity=(0.0, 0.0, -gravity), coordinates=coordinates)
    for i in range(n):
        mech.add_body(body_name(i), mass=mass, inertia=[i_axis, i_trans, i_trans],
                      position=((i + 0.5) * length, 0.0, 0.0))
        mech.add_spherical(joint_name(i), "ground" if i == 0 else body_name(i - 1),
                           body_name(i), point=(i * length, 0.0, 0.0))
    mech.add_marker("tip", body_name(n - 1), (n * length, 0.0, 0.0))
    return mech
