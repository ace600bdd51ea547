"""Import of a finite-element model (mass, stiffness, nodes) from an ``.npz`` file.

The file is read with ``numpy.load(allow_pickle=False)``: data never becomes code.  It must be
a regular file (a FIFO or device is refused before it is opened); the ``.npy`` headers of the
members below are checked before any array is read (declared sizes at most what each member
holds and :data:`~casmbd.limits.MAX_NPZ_BYTES` and the memory budget together; nodes at most
:data:`~casmbd.limits.MAX_FE_NODES`, DOFs at most :data:`~casmbd.limits.MAX_FE_DOFS`), and
members with other names are never loaded.  Keys:

``nodes``
    Node coordinates in the body frame, shape ``(n, 2)`` (plane) or ``(n, 3)`` (space) [m].
``dofs_per_node``
    Integer scalar: 2 or 3 (plane), 3 or 6 (space); dof order of
    :mod:`casmbd.model.modal` (node by node; translations, then rotations).
``mass``, ``stiffness``
    Dense ``(n_dof, n_dof)`` arrays, **or** a scipy.sparse matrix stored as the arrays
    ``scipy.sparse.save_npz`` writes, with the matrix name as prefix: ``mass_format``
    (``"csr"``, ``"csc"`` or ``"coo"``), ``mass_shape``, ``mass_data`` and ``mass_indices``,
    ``mass_indptr`` (csr/csc) or ``mass_row``, ``mass_col`` (coo); likewise ``stiffness_*``.
    :func:`save_fe_npz` writes this layout.
``node_names``, ``node_ids`` (optional)
    Unicode string array and integer array of equal length: named nodes.
``masses``, ``inertias`` (optional)
    Lumped nodal masses ``(n,)`` [kg] and rotary inertias ``(n,)`` (plane) or ``(n, 3, 3)``
    (space) [kg·m²].  Without them the lumped description is the HRZ lumping of M (Hinton,
    Rock and Zienkiewicz, "A note on mass lumping and related processes in the finite element
    method", Earthq. Eng. Struct. Dyn. 4, 1976): the diagonal of M scaled so that the nodal
    masses sum to the rigid-body mass ``r_kᵀ M r_k`` of each translation k (the nodal mass is
    the mean over the directions), rotational diagonals scaled by the mean factor.

Every malformed input raises a :class:`~casmbd.errors.ModelError` naming the file and the
field (missing keys, shapes, asymmetry beyond 1e-10 relative, non-finite entries, negative
masses, bad names).
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Mapping

import numpy as np

from casmbd.errors import ModelError
from casmbd.lazy import lazy_module
from casmbd.limits import (
    MAX_FE_DOFS,
    MAX_FE_NODES,
    MAX_NPZ_BYTES,
    check_count,
    check_npz,
    check_regular_file,
)
from casmbd.model.modal import FEModel, check_node_layout, rotational_dofs

sp = lazy_module("scipy.sparse")

__all__ = ["load_fe_npz", "save_fe_npz"]

_SYMMETRY_TOL = 1e-10


def _matrix(data: Mapping, name: str, n_dof: int, where: str):
    """Dense or sparse (save_npz layout with prefix ``name_``) matrix, validated."""
    if name in data:
        A = np.asarray(data[name])
        if A.dtype.kind not in "fiu":
            raise ModelError(f"{where}: field {name!r} must be a numeric array, "
                             f"got dtype {A.dtype}")
        A = A.astype(float)
        if A.shape != (n_dof, n_dof):
            raise ModelError(f"{where}: field {name!r} has shape {A.shape}, expected "
                             f"({n_dof}, {n_dof}) from nodes × dofs_per_node")
        vals = A
    elif f"{name}_format" in data:
        fmt = np.asarray(data[f"{name}_format"]).item()
        fmt = fmt.decode("ascii", "replace") if isinstance(fmt, bytes) else str(fmt)
        need = {"csr": ("data", "indices", "indptr"), "csc": ("data", "indices", "indptr"),
                "coo": ("data", "row", "col")}
        if fmt not in need:
            raise ModelError(f"{where}: field {name}_format must be 'csr', 'csc' or 'coo', "
                             f"got {fmt!r}")
        parts = {}
        for k in ("shape", *need[fmt]):
            key = f"{name}_{k}"
            if key not in data:
                raise ModelError(f"{where}: sparse {fmt} matrix {name!r} lacks field {key!r}")
            parts[k] = np.asarray(data[key])
            if parts[k].dtype.kind not in ("fiu" if k == "data" else "iu"):
                raise ModelError(f"{where}: field {key!r} must be numeric ("
                                 f"{'integers' if k != 'data' else 'numbers'}), got dtype "
                                 f"{parts[k].dtype}")
        shape = tuple(int(s) for s in parts["shape"].reshape(-1))
        if shape != (n_dof, n_dof):
            raise ModelError(f"{where}: field {name}_shape is {shape}, expected "
                             f"({n_dof}, {n_dof}) from nodes × dofs_per_node")
        try:
            if fmt == "coo":
                A = sp.coo_matrix((parts["data"].astype(float), (parts["row"], parts["col"])),
                                  shape=shape)
            else:
                cls = sp.csr_matrix if fmt == "csr" else sp.csc_matrix
                A = cls((parts["data"].astype(float), parts["indices"], parts["indptr"]),
                        shape=shape)
            A = sp.csr_matrix(A)
            A.check_format(full_check=True)
        except (ValueError, IndexError, TypeError) as exc:
            raise ModelError(f"{where}: sparse matrix {name!r} is malformed ({exc})") from exc
        vals = A.data
    else:
        raise ModelError(f"{where}: field {name!r} is missing (a dense array {name!r} or the "
                         f"sparse arrays {name}_format, {name}_shape, {name}_data, ...)")
    if not np.all(np.isfinite(vals)):
        raise ModelError(f"{where}: field {name!r} has non-finite entries")
    scale = float(np.abs(vals).max()) if np.size(vals) else 0.0
    if scale == 0.0:
        raise ModelError(f"{where}: field {name!r} is all zeros")
    asym = abs(A - A.T).max() if sp.issparse(A) else np.abs(A - A.T).max()
    if float(asym) > _SYMMETRY_TOL * scale:
        raise ModelError(f"{where}: field {name!r} is not symmetric (largest |A − Aᵀ| "
                         f"{float(asym):.3g} against max |A| {scale:.3g})")
    return 0.5 * (A + A.T) if not sp.issparse(A) else sp.csr_matrix(0.5 * (A + A.T))


def _hrz(M, positions: np.ndarray, d: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    """HRZ lumped nodal masses and rotary inertias from M (module docstring)."""
    n, dim = positions.shape
    diag = np.asarray(M.diagonal() if sp.issparse(M) else np.diag(M)).reshape(n, d)
    if np.any(diag < 0.0):
        i, k = np.argwhere(diag < 0.0)[0]
        raise ModelError(f"{where}: field 'mass' has a negative diagonal entry at node {i}, "
                         f"dof {k} ({diag[i, k]:.6g})")
    scales = []
    for k in range(dim):
        r = np.zeros((n, d))
        r[:, k] = 1.0
        r = r.ravel()
        total = float(r @ (M @ r))
        s = float(diag[:, k].sum())
        if total <= 0.0 or s <= 0.0:
            raise ModelError(f"{where}: field 'mass' gives a non-positive rigid-body mass "
                             f"{total:.6g} along axis {'xyz'[k]}")
        scales.append(total / s)
    masses = np.mean([scales[k] * diag[:, k] for k in range(dim)], axis=0)
    scale = float(np.mean(scales))
    rot = rotational_dofs(dim, d)
    if dim == 2:
        inertias = scale * diag[:, rot[0]] if rot else np.zeros(n)
    else:
        inertias = np.zeros((n, 3, 3))
        if rot:
            for k in range(3):
                inertias[:, k, k] = scale * diag[:, rot[k]]
    return masses, inertias


def _array(data: Mapping, key: str, where: str, kinds: str = "fiu") -> np.ndarray:
    if key not in data:
        raise ModelError(f"{where}: field {key!r} is missing")
    a = np.asarray(data[key])
    if a.dtype.kind not in kinds:
        raise ModelError(f"{where}: field {key!r} has dtype {a.dtype}, expected "
                         f"{'numbers' if 'f' in kinds else 'integers'}")
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise ModelError(f"{where}: field {key!r} has non-finite entries")
    return a


#: The members :func:`load_fe_npz` reads; any other member of the file is never loaded.
_USED_KEYS = ("nodes", "dofs_per_node", "node_names", "node_ids", "masses", "inertias",
              *(f"{m}{suffix}" for m in ("mass", "stiffness")
                for suffix in ("", "_format", "_shape", "_data", "_indices", "_indptr", "_row",
                               "_col")))


def _check_counts(headers: Mapping[str, tuple], where: str) -> None:
    """The node count from the ``nodes`` member's ``.npy`` header against
    :data:`~casmbd.limits.MAX_FE_NODES`, before any array is read (the DOF count, nodes ×
    ``dofs_per_node``, is checked against :data:`~casmbd.limits.MAX_FE_DOFS` once
    ``dofs_per_node`` is read; dense matrices are bounded by the header budget)."""
    shape = headers.get("nodes", ((),))[0]
    if shape:
        check_count(f"{where}: field 'nodes': nodes", int(shape[0]), MAX_FE_NODES,
                    "use a coarser mesh or reduce the model before import")


def load_fe_npz(path: str | os.PathLike, *, name: str | None = None) -> FEModel:
    """Read and validate an FE model from an ``.npz`` file (layout in the module docstring).

    Parameters
    ----------
    path : str or path-like
        The file; errors name it.
    name : str, optional
        Body name for messages (``"fe 'name' (file)"``).

    Returns
    -------
    FEModel
        With the file's arrays as cache-key inputs (content, not the path).
    """
    where = f"fe file {os.fspath(path)!r}" + (f" of body {name!r}" if name else "")
    if not os.path.lexists(path):
        raise ModelError(f"{where}: no such file")
    check_regular_file(path, "fe", MAX_NPZ_BYTES, ModelError)
    try:
        with zipfile.ZipFile(path) as zf:
            headers = check_npz(zf, where, _USED_KEYS, None, ModelError)
        _check_counts(headers, where)
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files if k in headers}  # unused members stay unread
    except FileNotFoundError as exc:
        raise ModelError(f"{where}: no such file") from exc
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ModelError(f"{where}: not a readable .npz file without Python objects "
                         f"({type(exc).__name__}: {exc})") from exc
    nodes = _array(data, "nodes", where).astype(float)
    if nodes.ndim != 2 or nodes.shape[0] < 1:
        raise ModelError(f"{where}: field 'nodes' must have shape (n, 2) or (n, 3), "
                         f"got {nodes.shape}")
    dpn = _array(data, "dofs_per_node", where, "iu")
    if dpn.size != 1:
        raise ModelError(f"{where}: field 'dofs_per_node' must be one integer, got shape "
                         f"{dpn.shape}")
    d = int(dpn.reshape(-1)[0])
    dim = nodes.shape[1]
    check_node_layout(dim, d, where)
    n = nodes.shape[0]
    check_count(f"{where}: degrees of freedom (nodes × dofs_per_node)", n * d, MAX_FE_DOFS,
                "use a coarser mesh or reduce the model before import")
    M = _matrix(data, "mass", n * d, where)
    K = _matrix(data, "stiffness", n * d, where)
    names: dict[str, int] = {}
    if ("node_names" in data) != ("node_ids" in data):
        raise ModelError(f"{where}: fields 'node_names' and 'node_ids' go together")
    if "node_names" in data:
        nn = np.asarray(data["node_names"])
        if nn.dtype.kind != "U" or nn.ndim != 1:
            raise ModelError(f"{where}: field 'node_names' must be a 1-D unicode string array, "
                             f"got dtype {nn.dtype} shape {nn.shape}")
        ids = _array(data, "node_ids", where, "iu").reshape(-1)
        if ids.shape != nn.shape:
            raise ModelError(f"{where}: fields 'node_names' {nn.shape} and 'node_ids' "
                             f"{ids.shape} differ in length")
        for s, i in zip(nn.tolist(), ids.tolist()):
            if not s or s in names:
                raise ModelError(f"{where}: field 'node_names': empty or repeated name {s!r}")
            if not 0 <= i < n:
                raise ModelError(f"{where}: field 'node_ids': node {s!r} has index {i}, "
                                 f"outside [0, {n})")
            names[s] = int(i)
    if "masses" in data:
        masses = _array(data, "masses", where).astype(float)
        if masses.shape != (n,):
            raise ModelError(f"{where}: field 'masses' has shape {masses.shape}, expected "
                             f"({n},)")
        if np.any(masses < 0.0):
            i = int(np.flatnonzero(masses < 0.0)[0])
            raise ModelError(f"{where}: field 'masses' is negative at node {i} "
                             f"({masses[i]:.6g})")
        want = (n,) if dim == 2 else (n, 3, 3)
        if "inertias" in data:
            inertias = _array(data, "inertias", where).astype(float)
            if inertias.shape != want:
                raise ModelError(f"{where}: field 'inertias' has shape {inertias.shape}, "
                                 f"expected {want}")
            eig = inertias if dim == 2 else np.linalg.eigvalsh(
                0.5 * (inertias + inertias.transpose(0, 2, 1)))
            if np.any(eig < 0.0):
                raise ModelError(f"{where}: field 'inertias' is negative (or not positive "
                                 "semi-definite) at a node")
        else:
            inertias = np.zeros(want)
    elif "inertias" in data:
        raise ModelError(f"{where}: field 'inertias' needs field 'masses'")
    else:
        masses, inertias = _hrz(M, nodes, d, where)
    diag = M.diagonal() if sp.issparse(M) else np.diag(M)
    if np.any(diag < 0.0):
        raise ModelError(f"{where}: field 'mass' has a negative diagonal entry at dof "
                         f"{int(np.flatnonzero(diag < 0.0)[0])}")
    inputs = {"kind": "npz", **{k: v for k, v in sorted(data.items())}}
    return FEModel(mass_matrix=M, stiffness_matrix=K, positions=nodes, dofs_per_node=d,
                   masses=masses, inertias=inertias, node_names=names, source=where,
                   inputs=inputs)


def save_fe_npz(path: str | os.PathLike, mass, stiffness, nodes, dofs_per_node: int, *,
                node_names: Mapping[str, int] | None = None, masses=None,
                inertias=None) -> None:
    """Write an FE model in the layout :func:`load_fe_npz` reads (sparse matrices in the
    ``scipy.sparse.save_npz`` arrays, prefixed ``mass_`` / ``stiffness_``)."""
    out: dict[str, np.ndarray] = {"nodes": np.asarray(nodes, dtype=float),
                                  "dofs_per_node": np.asarray(int(dofs_per_node))}
    for key, A in (("mass", mass), ("stiffness", stiffness)):
        if sp.issparse(A):
            A = sp.csr_matrix(A)
            out.update({f"{key}_format": np.asarray("csr"), f"{key}_shape": np.asarray(A.shape),
                        f"{key}_data": A.data, f"{key}_indices": A.indices,
                        f"{key}_indptr": A.indptr})
        else:
            out[key] = np.asarray(A, dtype=float)
    if node_names:
        out["node_names"] = np.asarray(list(node_names), dtype=str)
        out["node_ids"] = np.asarray(list(node_names.values()), dtype=np.int64)
    if masses is not None:
        out["masses"] = np.asarray(masses, dtype=float)
    if inertias is not None:
        out["inertias"] = np.asarray(inertias, dtype=float)
    np.savez(path, **out)
