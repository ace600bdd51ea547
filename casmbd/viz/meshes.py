"""Mesh files of URDF visuals for the 3-D view: STL, OBJ and COLLADA (DAE) through trimesh.

:func:`load_mesh` reads a file into vertices (n, 3) and triangles (m, 3), scaled per axis by
the URDF ``scale``.  It is bounded: the file must be a regular file of at most
:data:`casmbd.limits.MAX_MESH_BYTES` (checked by ``os.stat`` before it is opened: no FIFO or
device is ever read) and hold at most :data:`casmbd.limits.MAX_MESH_FACES` triangles; it is
read into memory and parsed from there, so a parser never follows a path of its own (an OBJ's
``mtllib`` and a DAE's textures are not read: the view colours meshes by the URDF material).
A scene graph (a DAE with several nodes) is flattened into one mesh with each node's
transform applied (``trimesh.load(..., force="mesh")``).  COLLADA needs pycollada
(``pip install "casmbd[view]"`` installs it with trimesh).

Any failure — a missing or unresolved file, a format other than STL/OBJ/DAE, a file trimesh
cannot parse, an empty mesh, a non-finite vertex, a face index out of range — raises
:class:`~casmbd.errors.SceneError` naming the file; the view turns it into a warning and
draws the body with its derived shapes (:mod:`casmbd.viz.view_shapes`).
"""

from __future__ import annotations

import functools
import io
import os
from pathlib import Path

import numpy as np

from casmbd.errors import LimitError, SceneError
from casmbd.interrupts import reraise_interrupt
from casmbd.limits import MAX_MESH_BYTES, MAX_MESH_FACES, read_bounded

#: mesh formats read (suffix → trimesh file type)
MESH_FORMATS = {".stl": "stl", ".obj": "obj", ".dae": "dae"}
#: the install hint of the optional viewer dependencies
VIEW_EXTRA = 'pip install "casmbd[view]"'


def _trimesh():
    """The trimesh module, or a SceneError naming the extra that installs it."""
    try:
        import trimesh  # optional dependency of the [view] extra
    except ImportError:
        raise SceneError(f"meshes need trimesh: {VIEW_EXTRA}") from None
    return trimesh


def load_mesh(path: str | os.PathLike | None, scale=(1.0, 1.0, 1.0),
              uri: str = "") -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) [m, scaled] and triangles (m, 3) of a mesh file.

    Parameters
    ----------
    path : path-like or None
        The resolved file (None: the URDF's ``uri`` could not be resolved).
    scale : 3 floats
        Per-axis scale (URDF ``<mesh scale>``).
    uri : str
        The filename as written in the URDF, for messages.

    Raises
    ------
    SceneError
        The file is missing, unresolved, not a regular file, of another format, unreadable,
        empty, non-finite or inconsistent (naming it).
    LimitError
        Larger than :data:`~casmbd.limits.MAX_MESH_BYTES` or with more than
        :data:`~casmbd.limits.MAX_MESH_FACES` triangles.
    """
    named = f" ('{uri}')" if uri and uri != str(path) else ""
    if path is None:
        raise SceneError(f"mesh '{uri}' not found (a package:// URI is resolved by searching "
                         "the URDF's parent folders for the package's folder)")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_FORMATS:
        raise SceneError(f"mesh file '{path}'{named}: format '{suffix or '(none)'}' is not "
                         f"read (STL, OBJ and DAE are)")
    scale = np.asarray(scale, float).reshape(-1)
    if scale.size != 3 or not np.all(np.isfinite(scale)):
        raise SceneError(f"mesh file '{path}'{named}: scale must be 3 finite numbers, got "
                         f"{scale.tolist()}")
    try:
        st = os.stat(path)
        stamp = (st.st_mtime_ns, st.st_size)
    except OSError:
        stamp = (0, 0)  # read_bounded names the problem
    vertices, faces = _load(str(path), stamp, MESH_FORMATS[suffix], named)
    return vertices * scale, faces.copy()


@functools.lru_cache(maxsize=64)
def _load(path: str, stamp: tuple, file_type: str, named: str) -> tuple[np.ndarray, np.ndarray]:
    """The unscaled mesh of ``path`` (cached by path, modification time and size)."""
    data = read_bounded(path, "mesh", MAX_MESH_BYTES, SceneError)
    trimesh = _trimesh()
    where = f"mesh file '{path}'{named}"
    try:
        mesh = trimesh.load(io.BytesIO(data), file_type=file_type, force="mesh",
                            process=False)
        vertices = np.asarray(mesh.vertices, dtype=float)
        faces = np.asarray(mesh.faces, dtype=np.int64)
    except Exception as exc:  # a third-party parser raises anything on a broken file
        reraise_interrupt(exc)
        if isinstance(exc, ImportError):
            needed = "pycollada" if file_type == "dae" else (exc.name or "a module")
            raise SceneError(f"{where}: reading {file_type.upper()} needs {needed} "
                             f"({VIEW_EXTRA})") from None
        raise SceneError(f"{where} cannot be read ({type(exc).__name__}: "
                         f"{str(exc)[:200]})") from None
    if vertices.ndim != 2 or vertices.shape[1:] != (3,) or faces.ndim != 2 \
            or faces.shape[1:] != (3,) or len(faces) == 0:
        raise SceneError(f"{where} holds no triangles")
    if len(faces) > MAX_MESH_FACES:
        raise LimitError(f"{where}: {len(faces)} triangles exceed the limit of "
                         f"{MAX_MESH_FACES} (casmbd.limits.MAX_MESH_FACES)")
    if not np.all(np.isfinite(vertices)):
        raise SceneError(f"{where}: a vertex is not finite")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise SceneError(f"{where}: a face refers to a vertex that does not exist")
    vertices.setflags(write=False)
    faces.setflags(write=False)
    return vertices, faces
