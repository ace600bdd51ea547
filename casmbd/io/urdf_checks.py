"""URDF model checks at load, and the repairs and overrides for what published files get wrong.

:func:`prepare` runs on the parsed robot before the mechanism is built, :func:`check_built` on
the built mechanism; every refusal is a :class:`~casmbd.errors.SceneError` naming the link or
joint and the attribute, every repair a ``RuntimeWarning`` naming the change.

* **Per-link overrides** (``links = {NAME: {mass, com, inertia}}``): replace the file's
  ``<inertial>`` values of a link before any check: ``mass`` in kg, ``com`` the centre of mass in
  the link frame (m), ``inertia`` = [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (kg m²,
  the tensor elements, about the centre of mass in the *link* axes).  A key left out keeps the
  file's value; an overriding inertia must itself be physical.
* **Physical inertias.**  A tensor I (about the centre of mass) is that of a rigid body iff
  I = tr(Σ) 1 − Σ with Σ = ∫ r rᵀ dm positive semi-definite, i.e. its principal moments
  λ₁, λ₂, λ₃ satisfy the triangle inequalities λᵢ ≤ λⱼ + λₖ (which imply λᵢ ≥ 0; seed 001,
  eq. 105).  Checked on each body, the merge of a link and the links welded to it (fixed or
  locked joints), as the dynamics sees it: with ``inertia = "check"`` (default) a body that
  violates them (beyond the rounding that :func:`casmbd.model.bodies.check_inertia` accepts) is
  refused naming its link and ``<inertia>``; with ``inertia = "repair"`` its tensor is replaced
  by :func:`nearest_physical_inertia`:
  the same principal axes, the principal moments projected (Euclidean) onto the polyhedral cone
  {λ : λᵢ ≤ λⱼ + λₖ} — for the usual single violation λ₃ > λ₁ + λ₂ by e this moves λ₁ and λ₂
  up and λ₃ down by e/3 each (a flat body, λ₃ = λ₁ + λ₂), the mass and centre of mass unchanged
  — with a warning naming the link and the moments before and after.
* **Mimic joints.**  ``ignore_mimic = True`` (every ``<mimic>``) or a list of follower joints:
  the follower becomes an independent joint, with a warning.  A ``<mimic>`` naming an unknown
  joint is refused, suggesting ``ignore_mimic``.
* **Reserved names.**  casmbd's fixed frame is the body ``ground``; a link of that name is
  renamed ``ground_link`` (``ground_link_2``, … if taken) with a warning, so that its frame
  stays a marker (root or welded link) or a body (moving link) under that name.  Link and joint
  names with ``.`` or ``@`` (allegro's ``link_8.0``; casmbd reserves them for generated parts
  and node attachments) get ``_`` instead.  ``locked`` and ``initial`` accept either name.
* **No moving body** (every link welded to the ground, as a bare quadrotor file): refused at
  load naming the robot, suggesting ``floating_base = true``.
* **Massless end links.**  A moving joint whose subtree has no mass (prismatic) or no inertia
  about the joint axis, Σ aᵀ Iₗ a + mₗ |a × (cₗ − p)|² = 0 over the subtree's links (revolute,
  continuous; axis a through p at the design pose), leaves the mass matrix singular: loaded
  (kinematics and inverse dynamics are fine) with a warning naming the joints and links;
  forward dynamics then refuses naming them (:mod:`casmbd.compiled.robot`, simulate).
"""

from __future__ import annotations

import dataclasses
import itertools
import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from casmbd.errors import ModelError, SceneError
from casmbd.io.urdf_tree import MOVING, Robot, merge
from casmbd.model.bodies import GROUND, INERTIA_ROUNDING, check_inertia
from casmbd.model.mechanism import RESERVED_CHARACTERS

#: the ``inertia`` option: refuse an impossible inertia, or project it to the nearest physical one
INERTIA_MODES = ("check", "repair")
#: keys of a per-link override
LINK_KEYS = ("mass", "com", "inertia")
#: the name a link called ``ground`` gets (``ground`` is casmbd's fixed frame)
GROUND_LINK = "ground_link"
#: a subtree with less inertia about its joint axis than this (kg m²), or no mass on a
#: prismatic joint, counts as massless
MASSLESS = INERTIA_ROUNDING

_CONE = np.array([[1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])  # A λ ≤ 0


def nearest_physical_inertia(tensor: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The physical inertia tensor nearest to ``tensor`` (same principal axes).

    The principal moments λ (``eigh``) are projected in the Euclidean norm onto the cone
    {λ : A λ ≤ 0} of the triangle inequalities λᵢ − λⱼ − λₖ ≤ 0 (which imply λ ≥ 0): the
    projection onto the span of the face {aᵢᵀ λ = 0, i ∈ S} is λ − A_Sᵀ (A_S A_Sᵀ)⁻¹ A_S λ; of the
    2³ active sets the feasible candidate nearest to λ is the projection (a closed convex cone is
    the union of its faces).  The tensor is V diag(λ') Vᵀ.

    Returns
    -------
    tensor, before, after : ndarray
        The repaired 3 × 3 tensor and the principal moments before and after (ascending).
    """
    sym = 0.5 * (np.asarray(tensor, float) + np.asarray(tensor, float).T)
    lam, vec = np.linalg.eigh(sym)
    scale = max(float(np.sum(np.abs(lam))), INERTIA_ROUNDING)
    best, dist = np.zeros(3), float(np.sum(lam ** 2))
    for size in range(4):
        for rows in itertools.combinations(range(3), size):
            a = _CONE[list(rows)]
            cand = lam - a.T @ np.linalg.solve(a @ a.T, a @ lam) if size else lam.copy()
            if np.all(_CONE @ cand <= 1e-14 * scale):
                d = float(np.sum((cand - lam) ** 2))
                if d < dist:
                    best, dist = cand, d
    best = np.maximum(best, 0.0)
    return vec @ np.diag(best) @ vec.T, lam, best


def _fmt(values) -> str:
    return "[" + ", ".join(f"{float(x):.6g}" for x in values) + "]"


def _values(tensor: np.ndarray) -> list[float]:
    """[Ixx, Iyy, Izz, Ixy, Ixz, Iyz] of a tensor."""
    return [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]


def _override(robot: Robot, links: Mapping) -> None:
    """Apply the per-link overrides (in place on copies of the links)."""
    if not isinstance(links, Mapping):
        raise SceneError(f"links: expected a table of link name = {{mass, com, inertia}}, got "
                         f"{links!r}")
    for name, table in links.items():
        where = f"links.{name}"
        if name not in robot.links:
            raise SceneError(f"{where}: unknown link '{name}' (links: "
                             f"{', '.join(list(robot.links)[:20])})")
        if not isinstance(table, Mapping) or not table:
            raise SceneError(f"{where}: expected a table with keys {', '.join(LINK_KEYS)}")
        extra = sorted(set(table) - set(LINK_KEYS))
        if extra:
            raise SceneError(f"{where}: unknown key(s) {', '.join(map(repr, extra))} (allowed: "
                             f"{', '.join(LINK_KEYS)})")
        link = dataclasses.replace(robot.links[name])
        if "mass" in table:
            mass = table["mass"]
            if isinstance(mass, bool) or not isinstance(mass, (int, float)) or \
                    not np.isfinite(mass):
                raise SceneError(f"{where}.mass: expected a finite number (kg), got {mass!r}")
            mass = float(mass)
            if mass < 0.0:
                raise SceneError(f"{where}.mass: must be >= 0, got {mass:g}")
            link.mass = mass
        if "com" in table:
            link.com = np.array(_number_list(table["com"], f"{where}.com", (3,)))
        if "inertia" in table:
            vals = _number_list(table["inertia"], f"{where}.inertia", (3, 6))
            try:
                link.inertia = check_inertia(vals)
            except ModelError as exc:
                raise SceneError(f"{where}.inertia: {exc}") from None
        robot.links[name] = link


def _number_list(value, where: str, sizes: tuple[int, ...]) -> list[float]:
    ok = isinstance(value, Sequence) and not isinstance(value, str) and len(value) in sizes
    out = []
    if ok:
        for x in value:
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x):
                ok = False
                break
            out.append(float(x))
    if not ok:
        what = " or ".join(str(s) for s in sizes)
        raise SceneError(f"{where}: expected a list of {what} finite numbers, got {value!r}")
    return out


def check_inertias(robot: Robot, group: Mapping[str, str], design: dict,
                   mode: str = "check") -> Robot:
    """The robot with every body's inertia physical: refused (``check``) or repaired
    (``repair``) where the merged inertia of a body's links (:func:`casmbd.io.urdf_tree.merge`,
    global axes at the design pose) is one that no rigid body has.

    A file's link may be unphysical on its own and still belong to a physical body once merged
    with the links welded to it (as Pinocchio merges them; tiago's antenna links): the check is
    on the bodies.  The repair adds ΔI = I' − I (I' = :func:`nearest_physical_inertia` of I) to
    the body's first link, in its axes (merging is linear in the tensors), so the body gets I'.
    """
    if mode not in INERTIA_MODES:
        raise SceneError(f"inertia: expected one of {', '.join(map(repr, INERTIA_MODES))}, got "
                         f"{mode!r}")
    members: dict[str, list[str]] = {}
    for lname in robot.links:
        if group[lname] != GROUND:
            members.setdefault(group[lname], []).append(lname)
    repaired = []
    for body, names in members.items():
        parts = []
        for lname in names:
            rot, pos = design[lname]
            link = robot.links[lname]
            parts.append((link.mass, pos + rot @ link.com, rot @ link.inertia @ rot.T))
        mass, _, tensor = merge(parts)
        if mass <= 0.0:
            tensor = sum(part[2] for part in parts)
        others = [n for n in names if n != body]
        what = f"link '{body}'" + (f" (with the links welded to it: {', '.join(others[:3])}"
                                   + (", ..." if len(others) > 3 else "") + ")"
                                   if others else "")
        try:
            check_inertia(_values(tensor))
            continue
        except ModelError as exc:
            if mode == "check":
                raise SceneError(
                    f"URDF '{robot.name}': {what} <inertia>: {exc}; correct the file, give "
                    f"the link's inertia (links = {{{body} = {{inertia = [...]}}}}) or load "
                    "with inertia = \"repair\" (the nearest physical inertia)") from None
        fixed, before, after = nearest_physical_inertia(tensor)
        rot = design[body][0]
        head = robot.links[body]
        robot.links[body] = dataclasses.replace(
            head, inertia=head.inertia + rot.T @ (fixed - tensor) @ rot)
        repaired.append(f"{what} principal moments {_fmt(before)} -> {_fmt(after)} kg m²")
    if repaired:
        warnings.warn(f"URDF '{robot.name}': inertia = \"repair\": " + "; ".join(repaired)
                      + " (the nearest tensor satisfying the triangle inequalities, same "
                      "principal axes, mass and centre of mass)", RuntimeWarning, stacklevel=3)
    return robot


def _mimics(robot: Robot, ignore) -> None:
    """Drop the ignored ``<mimic>`` elements (with a warning); refuse unknown leaders."""
    followers = [j.name for j in robot.joints.values() if j.mimic is not None]
    if isinstance(ignore, bool):
        dropped = followers if ignore else []
    elif isinstance(ignore, Sequence) and not isinstance(ignore, str) and all(
            isinstance(n, str) for n in ignore):
        unknown = [n for n in ignore if n not in followers]
        if unknown:
            raise SceneError(f"ignore_mimic: joint(s) {', '.join(map(repr, unknown))} have no "
                             f"<mimic> (mimic joints: {', '.join(followers) or 'none'})")
        dropped = list(dict.fromkeys(ignore))
    else:
        raise SceneError(f"ignore_mimic: expected true, false or a list of joint names, got "
                         f"{ignore!r}")
    for name in dropped:
        robot.joints[name] = dataclasses.replace(robot.joints[name], mimic=None)
    if dropped:
        warnings.warn(f"URDF '{robot.name}': <mimic> ignored for {', '.join(dropped)} "
                      "(ignore_mimic): each is an independent joint", RuntimeWarning,
                      stacklevel=4)
    for joint in robot.joints.values():
        if joint.mimic is not None and joint.mimic[0] not in robot.joints:
            raise SceneError(f"joint '{joint.name}' <mimic> attribute 'joint': unknown joint "
                             f"'{joint.mimic[0]}' (load with ignore_mimic = true, or "
                             f"ignore_mimic = [\"{joint.name}\"], to make the follower an "
                             "independent joint)")


def _free_name(name: str, taken) -> str:
    new, k = name, 1
    while new in taken:
        k += 1
        new = f"{name}_{k}"
    return new


def rename_reserved(robot: Robot) -> dict[str, str]:
    """Rename (in place) the links and joints whose names casmbd reserves: a link ``ground``
    becomes :data:`GROUND_LINK`, the characters of
    :data:`casmbd.model.mechanism.RESERVED_CHARACTERS` (``.``, ``@``) become ``_`` (a suffix
    ``_2``, … if the name is taken), with one warning.  Returns old → new names."""
    taken = set(robot.links) | set(robot.joints)
    renamed: dict[str, str] = {}
    for table in (robot.links, robot.joints):
        for name in table:
            new = GROUND_LINK if table is robot.links and name == GROUND else name
            for char in RESERVED_CHARACTERS:
                new = new.replace(char, "_")
            if new != name:
                renamed[name] = _free_name(new, taken)
                taken.add(renamed[name])
    if not renamed:
        return renamed
    robot.links = {renamed.get(n, n): dataclasses.replace(link, name=renamed.get(n, n))
                   for n, link in robot.links.items()}
    robot.joints = {renamed.get(n, n): dataclasses.replace(
        j, name=renamed.get(n, n), parent=renamed.get(j.parent, j.parent),
        child=renamed.get(j.child, j.child),
        mimic=None if j.mimic is None else (renamed.get(j.mimic[0], j.mimic[0]), *j.mimic[1:]))
        for n, j in robot.joints.items()}
    robot.root = renamed.get(robot.root, robot.root)
    text = ", ".join(f"'{a}' -> '{b}'" for a, b in list(renamed.items())[:8])
    warnings.warn(f"URDF '{robot.name}': names casmbd reserves renamed: {text}"
                  + (f" and {len(renamed) - 8} more" if len(renamed) > 8 else "")
                  + f" ('{GROUND}' is the fixed frame; '.' and '@' separate generated parts)",
                  RuntimeWarning, stacklevel=4)
    return renamed


def prepare(robot: Robot, inertia: str = "check", links: Mapping | None = None,
            ignore_mimic: bool | Sequence[str] = False) -> Robot:
    """A copy of the parsed robot with reserved names renamed (:func:`rename_reserved`, old →
    new in ``robot.renamed``; ``links`` and ``ignore_mimic`` take either name), the overrides
    applied and the ignored ``<mimic>`` dropped; the inertias are checked on the merged bodies
    (:func:`check_inertias`).

    Raises
    ------
    SceneError
        An unknown link or key in ``links``, a malformed value, an unknown ``inertia`` mode,
        a ``<mimic>`` of an unknown joint not ignored.
    """
    if inertia not in INERTIA_MODES:
        raise SceneError(f"inertia: expected one of {', '.join(map(repr, INERTIA_MODES))}, got "
                         f"{inertia!r}")
    robot = dataclasses.replace(robot, links=dict(robot.links), joints=dict(robot.joints))
    robot.renamed = new = rename_reserved(robot)  # every option accepts either name
    if links:
        _override(robot, {new.get(k, k): v for k, v in links.items()}
                  if isinstance(links, Mapping) else links)
    if isinstance(ignore_mimic, (list, tuple)):
        ignore_mimic = [new.get(n, n) if isinstance(n, str) else n for n in ignore_mimic]
    _mimics(robot, ignore_mimic)
    return robot


def _subtree_inertia(robot: Robot, joint, design: dict, below: dict) -> float:
    """Inertia of the links below ``joint`` about its axis (revolute), or their mass
    (prismatic), at the design pose (module docstring)."""
    rot, pos = design[joint.child]
    axis = rot @ joint.axis
    total = 0.0
    for lname in below[joint.child]:
        link = robot.links[lname]
        if joint.type == "prismatic":
            total += link.mass
            continue
        r_l, p_l = design[lname]
        arm = np.cross(axis, p_l + r_l @ link.com - pos)
        total += float(axis @ r_l @ link.inertia @ r_l.T @ axis) + link.mass * float(arm @ arm)
    return total


def massless_joints(robot: Robot, locked: Mapping, design: dict) -> dict[str, list[str]]:
    """Moving joints (not locked, not mimic followers) whose motion carries no inertia: joint →
    the links it moves.  A leader counts its followers' subtrees too."""
    children: dict[str, list[str]] = {}
    for joint in robot.joints.values():
        children.setdefault(joint.parent, []).append(joint.child)
    below: dict[str, list[str]] = {}
    for joint in reversed(robot.order()):
        below[joint.child] = [joint.child] + [x for c in children.get(joint.child, [])
                                              for x in below[c]]
    moving = [j for j in robot.order() if j.type in MOVING and j.name not in locked]
    empty = {j.name for j in moving if _subtree_inertia(robot, j, design, below) <= MASSLESS}
    out = {}
    for joint in moving:
        if joint.mimic is not None or joint.name not in empty:
            continue
        followers = [f.name for f in moving if f.mimic is not None and f.mimic[0] == joint.name]
        if all(f in empty for f in followers):
            out[joint.name] = below[joint.child]
    return out


def check_built(robot: Robot, mech, locked: Mapping, design: dict) -> None:
    """Refuse a mechanism without a moving body; warn of massless end links (module
    docstring)."""
    if not mech.bodies:
        kinds = sorted({j.type for j in robot.joints.values()})
        raise SceneError(
            f"URDF '{robot.name}': no moving body: every link is welded to the ground "
            f"({len(robot.links)} link{'s' if len(robot.links) != 1 else ''}, "
            + (f"joints of type {', '.join(kinds)}" if kinds else "no joints")
            + (f", locked {', '.join(locked)}" if locked else "")
            + "); a free-flying or legged robot (a quadrotor) needs a free root: load it with "
              "floating_base = true ([scene]; load_urdf(..., floating_base=True))")
    found = massless_joints(robot, locked, design)
    if found:
        text = "; ".join(f"joint '{j}' moves only {', '.join(links[:4])}"
                         + (f" and {len(links) - 4} more" if len(links) > 4 else "")
                         for j, links in list(found.items())[:6])
        more = f" (and {len(found) - 6} more joints)" if len(found) > 6 else ""
        warnings.warn(
            f"URDF '{robot.name}': massless end links: {text}{more}: no inertia about the "
            "joint axis (no mass on a prismatic joint), so the mass matrix is singular and "
            "forward dynamics will "
            "refuse it (kinematics and inverse dynamics are unaffected); give the links "
            "inertia (links = {NAME = {mass = ..., inertia = [...]}}) or lock the joints",
            RuntimeWarning, stacklevel=3)
