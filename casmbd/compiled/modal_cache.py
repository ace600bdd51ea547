"""The on-disk cache of reduced modal data (flexible bodies, issue 23).

The eigenproblem of a flexible body (:mod:`casmbd.model.modal_reduction`) depends only on its
finite-element data, the reduction, the number of modes and the interfaces; its result is kept
beside the compiled libraries as ``modes_<key>.npz`` in :func:`casmbd.compiled.cache.cache_dir`,
``key`` the SHA-256 of those inputs (:func:`casmbd.model.modal.cache_key`).  A file is written
by :func:`casmbd.atomic.atomic_write` (a temporary file renamed into place; the temporaries of
killed writers are swept), read with ``allow_pickle=False`` (data, never objects) and used only
when it holds the same key, a content hash (``digest``: SHA-256 of every other member's name,
dtype, shape and bytes) equal to that of what was read — one changed number and the file is
not used, never half-trusted —, the expected fields with consistent shapes and finite numbers;
anything else is a miss (the modes are computed again and the file replaced).  The model
layer cannot import this one: the caller passes :data:`DISK_STORE` to
:func:`casmbd.model.flexible_bodies.modal_data` (the scene reader gives it to each
``[[bodies]]`` entry); nothing is registered on import.
"""

from __future__ import annotations

import contextlib
import hashlib
import zipfile

import numpy as np

from casmbd.atomic import atomic_write
from casmbd.compiled.cache import cache_dir
from casmbd.errors import CasmbdError
from casmbd.limits import check_npz
from casmbd.model.modal import ModalData

__all__ = ["DISK_STORE", "load_modes", "save_modes"]

_ARRAYS = ("positions", "masses", "inertias", "phi_t", "phi_r", "mass", "stiffness",
           "frequencies", "rigid_mass", "rigid_coupling")


def _path(key: str):
    return cache_dir() / f"modes_{key[:32]}.npz"


def _digest(members) -> str:
    """SHA-256 of every member but ``digest`` (names, dtypes, shapes and bytes, in name order):
    the content hash that makes a file trusted as a whole, never field by field."""
    digest = hashlib.sha256()
    for name in sorted(set(members) - {"digest"}):
        arr = np.ascontiguousarray(members[name])
        digest.update(f"{name}\x00{arr.dtype.str}\x00{arr.shape}\x00".encode())
        digest.update(arr.tobytes())
    return digest.hexdigest()


def save_modes(key: str, modal: ModalData) -> None:
    """Write ``modal`` under ``key`` atomically (an unwritable cache is silently skipped:
    the modes are recomputed next time)."""
    names = list(modal.node_names)
    data = {name: np.asarray(getattr(modal, name), float) for name in _ARRAYS}
    data.update(key=np.array(key), dimension=np.array(modal.dimension),
                node_names=np.array(names, dtype=str),
                node_index=np.array([modal.node_names[n] for n in names], dtype=int),
                reduction=np.array(modal.reduction),
                reference=np.array(-1 if modal.reference is None else modal.reference),
                source=np.array(modal.source), modal_key=np.array(modal.key))
    data["digest"] = np.array(_digest(data))

    def write(tmp: str) -> None:
        with open(tmp, "wb") as handle:
            np.savez(handle, **data)

    with contextlib.suppress(OSError):
        atomic_write(_path(key), write)


def load_modes(key: str) -> ModalData | None:
    """The modal data stored under ``key``, or None (no file, another key, a malformed or
    non-finite field)."""
    path = _path(key)
    if not path.is_file():
        return None
    try:
        with zipfile.ZipFile(path) as zf:  # headers within the budget before any array
            check_npz(zf, f"modal cache file '{path}'")
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key or str(z["digest"]) != _digest(
                    {name: z[name] for name in z.files}):
                return None  # another key, or a field changed since it was written
            arrays = {name: np.array(z[name], float) for name in _ARRAYS}
            dim = int(z["dimension"])
            names = [str(n) for n in z["node_names"]]
            index = [int(i) for i in z["node_index"]]
            reference = int(z["reference"])
            extra = {k: str(z[k]) for k in ("reduction", "source", "modal_key")}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, CasmbdError):
        return None
    n_nodes = arrays["positions"].shape[0]
    n_modes = arrays["frequencies"].shape[0]
    shapes_ok = (arrays["positions"].shape == (n_nodes, dim)
                 and arrays["phi_t"].shape == (n_nodes, dim, n_modes)
                 and arrays["masses"].shape == (n_nodes,)
                 and arrays["stiffness"].shape == (n_modes, n_modes)
                 and arrays["rigid_coupling"].shape == (arrays["rigid_mass"].shape[0], n_modes)
                 and len(names) == len(index) and all(0 <= i < n_nodes for i in index))
    if not shapes_ok or not all(np.all(np.isfinite(a)) for a in arrays.values()):
        return None
    return ModalData(dimension=dim, node_names=dict(zip(names, index, strict=True)),
                     reduction=extra["reduction"],
                     reference=None if reference < 0 else reference,
                     source=extra["source"], key=extra["modal_key"], **arrays)


#: the on-disk store of modal data, as :func:`casmbd.model.flexible_bodies.modal_data` takes it
DISK_STORE = (load_modes, save_modes)
