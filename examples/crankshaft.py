"""Seed 002's crankshaft: a planar piston engine built in space with revolute joints only.

A crank turns about the global z axis at O (joint ``O``); the connecting rod hangs from the
crank pin A (joint ``A``, axis z); the piston slides along the global x axis (joint ``slide``);
rod and piston are joined at P by the revolute joint ``P`` — the seed's joint between point P1
on the rod and P2 on the piston (002, "Redundant constraint equations").  Every axis is
parallel to z, so the loop moves in the plane z = 0, and of the five equations of ``P`` only
the two in-plane ones are independent: its ``z`` equation repeats what the other joints already
impose (no motion along z), its two axis equations what they impose on the orientation (turns
about z only).  The rank of C_q says so (``casmbd.info`` lists the three), the simulation runs
with them removed or with minimum-norm multipliers, and the reactions along them — the z force
and the x, y moments, in every joint of the loop, since a self-stress of that kind can circulate
around it — are flagged as undetermined and reported as the minimum-norm distribution.

Closures of the loop at P (``closure``):

``"revolute"``
    the seed's model (5 equations at P, 3 of them redundant);
``"inline"``
    the non-redundant replacement of ``P`` alone: an in-line joint along z (the rod's point P
    stays on the piston's line through P along z; 2 equations, the two in-plane ones).  A
    spherical joint plus one dot-1 condition at P is *not* non-redundant here: its ``z``
    equation is implied by the other joints as above, and no rotation is left for the dot-1
    condition to remove (the rod can only turn about z) — ``info`` names 2 redundant
    equations of such a universal joint;
``"universal"``
    the candidate "spherical + one dot-1" at P alone (a universal joint whose cross has the
    rod's in-plane normal on the rod and z on the piston): still 2 redundant equations;
``"rsup"``
    the textbook non-redundant spatial slider-crank: the crank pin A becomes a spherical joint
    and P a universal joint (spherical + one dot-1: the piston's z axis stays perpendicular to
    the rod's in-plane normal, which locks the rod's spin about its own axis).  The same
    motion; the loop closes with 5 + 3 + 5 + 4 = 17 equations on 18 coordinates, all
    independent.

``coordinates="joint"`` keeps ``O``, ``A`` and ``slide`` in the spanning tree (three joint
coordinates: crank angle, rod angle, piston travel) so that ``P`` is the loop joint; in absolute
coordinates ``P`` is declared last, so that the Gram–Schmidt sweep of the rank check names its
rows.  The scene ``examples/crankshaft.toml`` is the redundant model in joint coordinates.

Run: ``python examples/crankshaft.py`` (prints ``info`` and compares the closures).
"""

from __future__ import annotations

import math

import numpy as np

import casmbd
from casmbd.errors import ModelError

#: crank radius, rod length [m], initial crank angle [rad], initial crank speed [rad/s]
R_CRANK, L_ROD, PHI0, OMEGA0 = 0.2, 0.6, math.pi / 3, 12.0
#: masses [kg] and inertias about the centres of mass, body axes [kg m²] (slender crank and rod
#: along their body x axes, a compact piston)
MASS = {"crank": 1.0, "rod": 2.0, "piston": 1.5}
INERTIA = {"crank": [1e-4, 1.0 * R_CRANK**2 / 12, 1.0 * R_CRANK**2 / 12],
           "rod": [2e-4, 2.0 * L_ROD**2 / 12, 2.0 * L_ROD**2 / 12],
           "piston": [2e-3, 2e-3, 2e-3]}
GRAVITY = (0.0, -9.81, 0.0)
CLOSURES = ("revolute", "inline", "universal", "rsup")
TREE = ["O", "A", "slide"]
Z = np.array([0.0, 0.0, 1.0])


def geometry(phi: float = PHI0, omega: float = OMEGA0) -> dict:
    """Crank pin A, piston point P, rod angle β and the consistent velocities for crank angle
    ``phi`` and crank speed ``omega`` (in-line engine: P on the x axis).

    The rod angle follows from r sin φ + l sin β = 0 and its rate from the velocity loop
    v_P = v_A + ω_rod z × (P − A) with v_P along x.
    """
    a = R_CRANK * np.array([math.cos(phi), math.sin(phi), 0.0])
    p = np.array([a[0] + math.sqrt(L_ROD**2 - a[1] ** 2), 0.0, 0.0])
    beta = math.atan2(p[1] - a[1], p[0] - a[0])
    v_a = omega * np.cross(Z, a)
    omega_rod = -v_a[1] / (p[0] - a[0])
    v_p = v_a + omega_rod * np.cross(Z, p - a)
    return {"A": a, "P": p, "beta": beta, "v_A": v_a, "omega_rod": omega_rod, "v_P": v_p,
            "v_rod": v_a + omega_rod * np.cross(Z, (p - a) / 2)}


def _about_z(angle: float) -> tuple[float, float, float, float]:
    return (math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2))


def crankshaft(coordinates: str = "absolute", closure: str = "revolute",
               name: str | None = None) -> casmbd.Mechanism:
    """The crankshaft with the loop closed at P by ``closure`` (see the module docstring).

    Parameters
    ----------
    coordinates : {"absolute", "natural", "joint"}
    closure : {"revolute", "inline", "universal", "rsup"}
    name : str, optional
        Mechanism name (default ``crankshaft_<closure>_<coordinates>``; distinct names give
        distinct compiled code).
    """
    if closure not in CLOSURES:
        raise ModelError(f"crankshaft closure must be one of {', '.join(CLOSURES)}, "
                         f"got {closure!r}")
    g = geometry()
    a, p = g["A"], g["P"]
    m = casmbd.Mechanism(name or f"crankshaft_{closure}_{coordinates}", gravity=GRAVITY,
                         coordinates=coordinates)
    m.add_body("crank", MASS["crank"], INERTIA["crank"], position=tuple(a / 2),
               orientation=_about_z(PHI0), velocity=tuple(g["v_A"] / 2),
               angular_velocity=(0.0, 0.0, OMEGA0))
    m.add_body("rod", MASS["rod"], INERTIA["rod"], position=tuple((a + p) / 2),
               orientation=_about_z(g["beta"]), velocity=tuple(g["v_rod"]),
               angular_velocity=(0.0, 0.0, g["omega_rod"]))
    m.add_body("piston", MASS["piston"], INERTIA["piston"], position=tuple(p),
               velocity=tuple(g["v_P"]))
    m.add_marker("crank_pin", "crank", tuple(a))
    m.add_revolute("O", "ground", "crank", (0.0, 0.0, 0.0), tuple(Z))
    if closure == "rsup":
        m.add_spherical("A", "crank", "rod", tuple(a))
    else:
        m.add_revolute("A", "crank", "rod", tuple(a), tuple(Z))
    m.add_prismatic("slide", "ground", "piston", tuple(p), (1.0, 0.0, 0.0))
    if closure == "revolute":
        m.add_revolute("P", "rod", "piston", tuple(p), tuple(Z))
    elif closure == "inline":
        m.add_inline("P", "rod", "piston", tuple(p), tuple(Z))
    else:   # universal, rsup: the cross has the rod's in-plane normal and the piston's z
        normal = np.cross(Z, (p - a) / L_ROD)
        m.add_universal("P", "rod", "piston", tuple(p), tuple(normal), tuple(Z))
    if coordinates == "joint":
        m.tree = list(TREE)
    return m


def main() -> None:
    import warnings

    for coords in ("absolute", "joint"):
        for closure in CLOSURES:
            data = casmbd.info(crankshaft(coords, closure))
            red = ", ".join(f"{r['joint']}.{r['equation']}" for r in data["redundant_equations"])
            print(f"{coords:8s} {closure:8s} n_q {data['n_coordinates']:2d}  n_c "
                  f"{data['n_constraints']:2d}  rank {data['rank']:2d}  DOF "
                  f"{data['degrees_of_freedom']}  redundant: {red or 'none'}")
    ref = casmbd.simulate(crankshaft("absolute", "rsup"), t_end=1.0, steps=20, rtol=1e-12)
    for coords in ("absolute", "joint"):
        for option in ("remove", "minimum_norm"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                out = casmbd.simulate(crankshaft(coords), t_end=1.0, steps=20, rtol=1e-12,
                                      redundancy=option)
            diff = np.max(np.abs(out["body_positions"] - ref["body_positions"]))
            print(f"revolute P, {coords}, {option}: max |Δ position| against rsup {diff:.1e} m; "
                  f"undetermined reactions {out.stats['undetermined_reactions']}")


if __name__ == "__main__":
    main()
