"""Named quantities of a mechanism for optimal-control expressions.

Bounds, boundary conditions, path constraints and objectives of an optimal-control problem are
written with names that read like the mechanism, all valid identifiers of the expression parser
(:mod:`casmbd.model.expressions`):

=====================  ==========================================================
``<joint>``            joint coordinate (a cylindrical joint's angle: ``<joint>_angle``)
``<joint>_dot``        its rate
``<marker>_x`` …       marker position components (``_x``, ``_y``, ``_z``)
``<marker>_vx`` …      marker velocity components
``<body>_x`` …         centre-of-mass position components
``<body>_vx`` …        centre-of-mass velocity components
``<body>_angle``       planar body angle; ``<body>_omega`` its rate (plane only)
``<coordinate>``       every generalized coordinate by its name with ``.`` → ``_`` (``rod_x``
                       is then the same as the body's; joint coordinates ``pin0_angle``)
``<actuator>``         actuator input u
``t``                  time; model parameters by name
=====================  ==========================================================

A joint coordinate name takes precedence over a generalized coordinate of the same spelling.
"""

from __future__ import annotations

import re

import casadi as ca

from casmbd.errors import ModelError

_AXES = ("x", "y", "z")


def identifier(name: str) -> str:
    """``name`` as an expression identifier: characters other than letters, digits and ``_``
    become ``_``."""
    out = re.sub(r"\W", "_", name)
    return out if not out[:1].isdigit() else f"_{out}"


def quantities(system) -> dict[str, ca.SX]:
    """Name → SX expression of (q, v, t, p, u) for every quantity listed in the module doc."""
    ctx, mech = system.ctx, system.mechanism
    q, v = system.q, system.v
    dim = system.dimension
    out: dict[str, ca.SX] = {}

    def add(name: str, expr) -> None:
        key = identifier(name)
        if key in out:
            return
        out[key] = expr

    for joint_key in system.joint_coordinate_names:
        expr = system._joint_coordinate(joint_key)
        add(joint_key, expr)
        add(f"{joint_key}_dot", ca.jtimes(expr, q, v))
    for name, marker in mech.markers.items():
        pos = ctx.position(marker.body, marker.point)
        vel = ca.jtimes(pos, q, v)
        for k in range(dim):
            add(f"{name}_{_AXES[k]}", pos[k])
            add(f"{name}_v{_AXES[k]}", vel[k])
    for name in system.body_names:
        pos = ctx.centre_of_mass(name)
        vel = ca.jtimes(pos, q, v)
        for k in range(dim):
            add(f"{name}_{_AXES[k]}", pos[k])
            add(f"{name}_v{_AXES[k]}", vel[k])
        if dim == 2:
            angle = ctx.angle(name)
            add(f"{name}_angle", angle)
            add(f"{name}_omega", ca.jtimes(angle, q, v))
    for k, cname in enumerate(system.coordinate_names):
        add(cname, q[k])
        add(f"{cname}_dot", v[k])
    for k, name in enumerate(mech.actuators):
        if identifier(name) in out:
            raise ModelError(f"actuator '{name}': its name is also a quantity of the mechanism; "
                             "rename it for optimal control")
        out[identifier(name)] = system.u[k]
    for k, name in enumerate(mech.parameters):
        out.setdefault(identifier(name), system.p[k])
    out["t"] = system.t
    return out
