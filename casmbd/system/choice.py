"""Automatic choice of generalized coordinates (``coordinates = "auto"``, the default).

When neither the scene nor the call names the coordinates, casmbd takes them from the
mechanism's structure (issue 22, item 1; the measurements are in docs/performance.md):

* **joint coordinates** when a spanning tree of the joint graph exists
  (:func:`casmbd.system.tree.tree_descriptions`: every tree joint a kind with tree coordinates)
  and the joints left out of the tree — the loop closures — bring no more equations than the
  tree has coordinates (``n_loop ≤ n_tree``: a tree or a few loops).  A tree then has no
  constraint equation at all and is integrated by the articulated-body recursion (O(N) per
  right-hand side, seed 001); a few loops keep a handful of equations on few coordinates.
  On every benchmark problem this is the fastest choice at both error levels (chain2, chain8,
  chain32, the spatial chain: articulated; the four-bar: 3 coordinates and 2 equations
  against 9 and 8 in absolute coordinates).
* **absolute coordinates** otherwise: a tree that cannot be built (a joint kind without tree
  coordinates in the only possible tree) or many loops (a truss, a lattice), where the
  joint-space mass matrix turns dense and the loop equations long while absolute
  coordinates keep M block-diagonal and every equation local (seed 000) — and a mechanism
  of more than :data:`JOINT_LIMIT` tree coordinates with loops or Euler parameters (ball
  joints, floating bodies): its joint-coordinate code (the dense joint-space mass matrix of
  the KKT or Kane path) grows like N², while absolute coordinates build in linear time.
  A tree the articulated-body recursion integrates has no such limit: its right-hand side,
  outputs, reactions and mass-matrix function are O(N) code (a 1000-rod chain builds in
  seconds in the virtual machine, docs/performance.md, "Scaling to a thousand bodies").

Natural coordinates are never chosen automatically: they are a modelling choice (constant
mass matrix, seed 003), not a speed one.
"""

from __future__ import annotations

from dataclasses import dataclass

from casmbd.errors import ModelError
from casmbd.system.tree import tree_descriptions

__all__ = ["AUTO", "JOINT_LIMIT", "CoordinateChoice", "choose_coordinates"]

#: the value of ``coordinates`` that asks casmbd to choose
AUTO = "auto"
#: the most tree coordinates for which the automatic choice takes joint coordinates when the
#: mechanism has loops or Euler parameters (their generated code grows like N²: measured
#: limit between 100 and 300 rods, module docstring); plain trees have no limit
JOINT_LIMIT = 150


@dataclass
class CoordinateChoice:
    """The coordinates chosen for a mechanism and why (reported by ``info`` and the stats)."""

    coordinates: str
    reason: str
    descriptions: dict | None = None
    tree_joints: list | None = None


def choose_coordinates(mechanism) -> CoordinateChoice:
    """Joint coordinates for trees and few loops, else absolute coordinates (module docstring).

    Returns the joint-coordinate descriptions it built (so that the system does not build them
    twice) when it chooses joint coordinates.  A body kind that supports absolute coordinates
    only (a flexible body: frame + modal coordinates) makes the choice absolute.
    """
    only_absolute = [name for name, body in mechanism.bodies.items()
                     if "joint" not in getattr(body, "coordinate_choices", ("joint",))]
    if only_absolute:
        shown = ", ".join(only_absolute[:3]) + (" …" if len(only_absolute) > 3 else "")
        return CoordinateChoice("absolute", f"flexible bodies ({shown}) carry frame and modal "
                                "coordinates (no joint coordinates through them): absolute "
                                "coordinates")
    follows = [name for name, force in mechanism.forces.items()
               if "reaction_forces" in getattr(force, "needs", ())]
    if follows:
        return CoordinateChoice("absolute", f"friction that follows the joint reactions "
                                f"({', '.join(follows[:3])}): absolute coordinates, whose "
                                "multipliers give every joint's reaction")
    try:
        descriptions, absorbed = tree_descriptions(mechanism, getattr(mechanism, "tree", None))
    except ModelError as exc:
        return CoordinateChoice("absolute", f"no spanning tree of joint coordinates ({exc})")
    n_tree = sum(d.size for d in descriptions.values())
    loops = [j for name, j in mechanism.joints.items() if name not in absorbed]
    n_loop = sum(len(j.labels) for j in loops)
    recursion = not loops and all(d.joint is not None and not d.joint.euler_parameters
                                  for d in descriptions.values())
    if n_tree > JOINT_LIMIT and not recursion:
        return CoordinateChoice(
            "absolute", f"{n_tree} tree coordinates > {JOINT_LIMIT} (the joint-coordinate code "
            "with loops or Euler parameters grows like N²; absolute coordinates build in "
            "linear time)")
    if n_loop > n_tree:
        return CoordinateChoice(
            "absolute", f"{len(loops)} loop joints with {n_loop} equations on {n_tree} tree "
            "coordinates (many loops: absolute coordinates keep M block-diagonal)")
    if not loops:
        why = f"a tree: {n_tree} joint coordinates, no loop equations"
    else:
        why = (f"{len(loops)} loop joint{'s' if len(loops) > 1 else ''} "
               f"({', '.join(j.name for j in loops)}) with {n_loop} "
               f"equation{'s' if n_loop != 1 else ''} on {n_tree} tree coordinates")
    return CoordinateChoice("joint", why, descriptions, absorbed)
