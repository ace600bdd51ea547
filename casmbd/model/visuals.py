"""What a body looks like: the visual geometry of a URDF ``<visual>`` element, kept with the
mechanism for the 3-D view (``Mechanism.visuals``: body name → tuple of :class:`Visual`).

A visual changes nothing that is computed (no mass, no contact): the model key of a build
skips ``Mechanism.visuals`` (:mod:`casmbd.compiled.modelkey`).  Its pose is given in the
body frame of casmbd (origin at the body's centre of mass, axes the body's), so that the
view places it by r = r_G + A u like every body-fixed point (seed 001, eq. 1); the URDF
loader (:mod:`casmbd.io.urdf`) composes the link frame, the visual's ``<origin>`` and the
merge of fixed joints into that pose.  Geometry follows the URDF specification
(wiki.ros.org/urdf/XML/link): ``box`` size (lx, ly, lz), ``cylinder`` (radius, length) along
local z, ``sphere`` (radius,), ``mesh`` a file and a per-axis ``scale``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: geometry kinds of a visual
VISUAL_KINDS = ("box", "cylinder", "sphere", "mesh")


@dataclass
class Visual:
    """One visual element of a body.

    Attributes
    ----------
    kind : {"box", "cylinder", "sphere", "mesh"}
    size : tuple of float
        box (lx, ly, lz); cylinder (radius, length), axis along local z; sphere (radius,);
        mesh ().
    position : ndarray (3,)
        Origin of the visual's frame in the body frame, from the centre of mass [m].
    rotation : ndarray (3, 3)
        Axes of the visual's frame in body axes.
    filename : str or None
        A mesh: the resolved file path (None when the URI could not be resolved: the view
        names ``uri`` and falls back).
    uri : str
        A mesh: the filename as written in the URDF (``package://…``, ``file://…``, relative).
    scale : ndarray (3,)
        A mesh's scale per axis (URDF ``scale``, default 1 1 1).
    rgba : tuple of 4 floats or None
        The material colour (0..1), when the URDF gives one.
    name : str
        The visual's ``name`` attribute, or the link name with its index.
    link : str
        The URDF link it belongs to (a merged body holds the visuals of all its links).
    """

    kind: str
    size: tuple = ()
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    filename: str | None = None
    uri: str = ""
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    rgba: tuple | None = None
    name: str = ""
    link: str = ""
