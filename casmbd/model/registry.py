"""The registry of element kinds: scene type name → the class that owns the kind.

A joint kind is one class (a subclass of :class:`casmbd.model.joints.Joint`) that declares its
scene type name (``kind``), the mechanism dimensions it serves (``dimensions``), its scene keys
(``scene_keys``), how it is built from the Python API (:meth:`~casmbd.model.joints.Joint.create`)
and from a scene entry (:meth:`~casmbd.model.joints.Joint.from_scene`), its constraint
equations, its tree motion in joint coordinates and its drawing hint.  Registering it here is
all the scene loader, :meth:`casmbd.model.Mechanism.add`, tree building and the drawing need:
none of them names a kind.  A force element kind (:data:`FORCE_KINDS`, a subclass of
:class:`casmbd.model.forces.ForceElement`) declares the same and its virtual-work terms.  A
body kind (:data:`BODY_KINDS`, e.g. :class:`~casmbd.model.bodies.Body`) declares its scene type
name (``[[bodies]] type``, default ``"rigid"``), its scene keys, ``create``/``from_scene``, its
drawing hint and, per coordinate choice, the key of the *description* the system layer uses
(:data:`casmbd.system.descriptions.DESCRIPTIONS`; the model layer never imports the system).

One scene name may have one class per dimension (``"revolute"`` is
:class:`~casmbd.model.joints.Revolute` in the plane and
:class:`~casmbd.model.spatial_joints.SpatialRevolute` in space), so the table maps a name to
``{dimension: class}``.  The order of registration is the order in which the names are listed
in error messages.

Example
-------
>>> from casmbd.model.registry import JOINT_KINDS
>>> sorted(JOINT_KINDS["revolute"])
[2, 3]
"""

from __future__ import annotations

from typing import TypeVar

from casmbd.errors import ModelError

#: scene type name → {dimension: joint class}
JOINT_KINDS: dict[str, dict[int, type]] = {}
#: force element type name → class (one class serves both dimensions)
FORCE_KINDS: dict[str, type] = {}
#: body type name (``[[bodies]] type``) → {dimension: body class}
BODY_KINDS: dict[str, dict[int, type]] = {}

_Kind = TypeVar("_Kind", bound=type)


def register_joint(kind: _Kind | None = None, *, replace: bool = False):
    """Register a joint class under its ``kind`` name for each of its ``dimensions``.

    Usable as a class decorator, bare (``@register_joint``) or with options
    (``@register_joint(replace=True)``: a script that may be run twice in one session).  A
    user module registers its own kinds the same way (see ``examples/custom_joint.py``).

    Parameters
    ----------
    kind : type
        A :class:`~casmbd.model.joints.Joint` subclass with class attributes ``kind`` (the
        scene type name) and ``dimensions`` (a tuple of 2 and/or 3).
    replace : bool
        Allow replacing a class already registered for that name and dimension (otherwise
        a second registration is a mistake and raises).

    Raises
    ------
    ModelError
        When the class declares no name or no valid dimension, or the name is taken.
    """
    if kind is None:
        return lambda cls: register_joint(cls, replace=replace)
    name, dims = _declared(kind, "joint")
    if name in FORCE_KINDS:
        raise ModelError(f"joint kind '{name}' ({kind.__name__}): the name is a force "
                         "element kind")
    return _register_per_dimension(JOINT_KINDS, "joint", kind, name, dims, replace)


def _declared(kind: type, noun: str) -> tuple[str, tuple[int, ...]]:
    """The ``kind`` name and ``dimensions`` a joint or body class declares, checked."""
    name = getattr(kind, "kind", None)
    dims = tuple(getattr(kind, "dimensions", ()))
    if not isinstance(name, str) or not name.isidentifier():
        raise ModelError(f"{noun} kind {kind.__name__}: class attribute 'kind' must be an "
                         f"identifier (the scene type name), got {name!r}")
    if not dims or any(d not in (2, 3) for d in dims):
        raise ModelError(f"{noun} kind '{name}' ({kind.__name__}): class attribute "
                         f"'dimensions' must list 2 and/or 3, got {dims!r}")
    return name, dims


def _register_per_dimension(registry: dict, noun: str, kind: _Kind, name: str,
                            dims: tuple[int, ...], replace: bool) -> _Kind:
    """Enter ``kind`` under ``name`` for each of ``dims`` (a taken slot needs ``replace``)."""
    table = registry.setdefault(name, {})
    for dim in dims:
        old = table.get(dim)
        if old is not None and old is not kind and not replace:
            raise ModelError(f"{noun} kind '{name}' in {dim} dimensions is already "
                             f"registered ({old.__name__}); pass replace=True to override")
        table[dim] = kind
    return kind


def register_force(kind: _Kind | None = None, *, replace: bool = False):
    """Register a force element class under its ``kind`` name (``[[forces]] type``).

    Usable as a class decorator like :func:`register_joint`; the class derives from
    :class:`casmbd.model.forces.ForceElement`.

    Raises
    ------
    ModelError
        When the class declares no name, or the name is taken (by a force element or a joint
        kind: ``Mechanism.add`` looks both up by name).
    """
    if kind is None:
        return lambda cls: register_force(cls, replace=replace)
    name = getattr(kind, "kind", None)
    if not isinstance(name, str) or not name.isidentifier():
        raise ModelError(f"force kind {kind.__name__}: class attribute 'kind' must be an "
                         f"identifier (the scene type name), got {name!r}")
    old = FORCE_KINDS.get(name)
    if name in JOINT_KINDS or (old is not None and old is not kind and not replace):
        taken = "a joint kind" if name in JOINT_KINDS else old.__name__
        raise ModelError(f"force kind '{name}' is already registered ({taken}); pass "
                         "replace=True to override a force kind")
    FORCE_KINDS[name] = kind
    return kind


def joint_kinds(dimension: int | None = None) -> list[str]:
    """Registered joint type names (all, or those available in ``dimension``)."""
    return [name for name, table in JOINT_KINDS.items()
            if dimension is None or dimension in table]


def joint_kind(name: str, dimension: int, where: str) -> type:
    """The class of joint kind ``name`` in ``dimension`` dimensions.

    Raises
    ------
    ModelError
        An unknown name (listing the registered ones) or a kind not available in this
        dimension (naming ``where``, e.g. ``joint 'hinge'``).
    """
    return _kind_in(JOINT_KINDS, "joint", name, dimension, where)


def register_body(kind: _Kind | None = None, *, replace: bool = False):
    """Register a body class under its ``kind`` name for each of its ``dimensions``.

    Usable as a class decorator like :func:`register_joint`.  The class declares ``kind`` (the
    ``[[bodies]] type`` name), ``dimensions``, ``scene_keys``, ``create``/``from_scene``,
    ``drawing`` and ``descriptions`` (coordinate choice → description key of
    :data:`casmbd.system.descriptions.DESCRIPTIONS`; ``"joint"``: the body as a floating root)
    for each coordinate choice it supports (``coordinate_choices``, default all three: a
    flexible body has absolute coordinates only).
    Body names live in their own table: ``"rigid"`` is a body and a joint kind
    (``Mechanism.add`` takes ``"body:rigid"`` for the body).

    Raises
    ------
    ModelError
        When the class declares no name, no valid dimension, no description per coordinate
        choice, or the name is taken in one of its dimensions.
    """
    if kind is None:
        return lambda cls: register_body(cls, replace=replace)
    name, dims = _declared(kind, "body")
    descriptions = getattr(kind, "descriptions", None)
    choices = getattr(kind, "coordinate_choices", ("absolute", "natural", "joint"))
    missing = [c for c in choices
               if not isinstance(descriptions, dict) or not isinstance(descriptions.get(c), str)]
    if missing:
        raise ModelError(f"body kind '{name}' ({kind.__name__}): class attribute "
                         "'descriptions' must name a description key for each coordinate "
                         f"choice (missing: {', '.join(missing)})")
    return _register_per_dimension(BODY_KINDS, "body", kind, name, dims, replace)


def body_kinds(dimension: int | None = None) -> list[str]:
    """Registered body type names (all, or those available in ``dimension``)."""
    return [name for name, table in BODY_KINDS.items()
            if dimension is None or dimension in table]


def body_kind(name: str, dimension: int, where: str) -> type:
    """The class of body kind ``name`` in ``dimension`` dimensions.

    Raises
    ------
    ModelError
        An unknown name (listing the registered ones) or a kind not available in this
        dimension (naming ``where``, e.g. ``body 'crank'``).
    """
    return _kind_in(BODY_KINDS, "body", name, dimension, where)


def _kind_in(registry: dict, noun: str, name: str, dimension: int, where: str) -> type:
    """The class registered as ``name`` for ``dimension`` in a per-dimension registry, or a
    ModelError naming ``where`` (unknown name: the registered ones; wrong dimension: which
    mechanism the kind needs)."""
    table = registry.get(name)
    if table is None:
        raise ModelError(f"{where}: unknown {noun} type {name!r} (allowed: "
                         f"{', '.join(registry)})")
    if dimension not in table:
        title = getattr(next(iter(table.values())), "title", None) or name
        space = "spatial" if dimension == 2 else "planar"
        raise ModelError(f"{where}: a {title} {noun} needs a {space} mechanism "
                         f"(dimension = {5 - dimension})")
    return table[dimension]
