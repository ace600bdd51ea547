"""Modal reduction of a finite-element model: Craig–Bampton and free-interface normal modes.

Component mode synthesis (seed 002, "Equations of Motion with Flexible Bodies": the
deformation is a combination of "Component Mode Synthesis base vectors Φ(i)").  Sources:
R. R. Craig and M. C. C. Bampton, "Coupling of substructures for dynamic analyses", AIAA J.
6(7), 1968; Craig and Kurdila, *Fundamentals of Structural Dynamics* (2nd ed., 2006), ch. 17.

Craig–Bampton
    Interface dofs B (every dof of the interface nodes), interior dofs I.  Fixed-interface
    normal modes ``(K_II − ω² M_II) φ = 0`` (the lowest ``modes``) and static constraint modes
    ``Ψ_IB = −K_II⁻¹ K_IB`` (unit displacement of one interface dof, the others held, no load
    inside).  The rigid-body motion of a free body lies in the span of the constraint modes;
    the floating frame carries it, so the constraint modes of the *reference node* (the first
    interface) are left out: the basis is that of the body clamped at the reference node, whose
    undeformed frame is the body frame.  The basis ``T = [Φ_fixed, Ψ]`` is then orthonormalised
    by the small eigenproblem ``(Tᵀ K T) q = ω² (Tᵀ M T) q``, ``Φ = T Q``: the reduced M and K
    are ``I`` and ``diag(ω²)``, so a damping ratio applies per mode.  Zero eigenvalues of
    that problem (rigid rotations about a reference node without rotational dofs) are
    dropped.
Free-interface normal modes
    The lowest ``modes`` elastic eigenmodes of the free structure ``(K − ω² M) φ = 0``.  The
    rigid-body modes (``K R = 0``; plane: 2 translations and the rotation about z, space: 3 + 3)
    are dropped and the elastic ones explicitly mass-orthogonalised against them,
    ``φ ← φ − R (RᵀMR)⁻¹ RᵀM φ`` (the linearised mean-axis conditions ``RᵀMΦ = 0``; exact
    eigenvectors satisfy them already, the projection removes rounding), then re-normalised.

Eigenproblems up to :data:`DENSE_LIMIT` dofs use ``scipy.linalg.eigh``; larger ones
``scipy.sparse.linalg.eigsh`` in shift-invert mode at σ = 0 (for a free structure, whose K is
singular, with an inertia-relief generalised inverse that leaves the rigid modes out),
constraint modes a sparse LU of ``K_II``.

Fine meshes of slender beams are ill-conditioned (``λ_max/λ_1`` grows like the fourth power
of the number of elements): the lowest eigenvalue then carries a relative rounding error of
about ``1e-16 · λ_max/λ_1`` whatever the solver (cantilever of the tests, mode 1: 9e-7 at
1000 elements, 6e-5 at 3000); 10–200 elements are the useful range.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

from casmbd.errors import ModelError
from casmbd.lazy import lazy_module
from casmbd.limits import MAX_MODES, check_count
from casmbd.model.modal import (
    FEModel,
    ModalData,
    cache_key,
    rotational_dofs,
)

sl = lazy_module("scipy.linalg")
sp = lazy_module("scipy.sparse")
spl = lazy_module("scipy.sparse.linalg")

__all__ = ["DENSE_LIMIT", "check_fe_model", "craig_bampton", "free_modes", "reduce",
           "rigid_body_modes"]

#: Largest eigenproblem (dofs) solved densely; above it shift-invert Lanczos.
DENSE_LIMIT = 1500
#: Plausible total mass of an FE model [kg] (a MEMS part ~ 1e-12 kg, a ship ~ 1e8 kg): outside
#: it the mass matrix is in the wrong unit (or scaled by a typo of the exponent).
PLAUSIBLE_MASS = (1e-20, 1e12)
#: Highest plausible angular frequency [rad/s]: ω² = K_ii/M_ii above 1e30 (a period under a
#: femtosecond) is no structure any time step resolves — K or M in the wrong unit.
PLAUSIBLE_OMEGA = 1e15


class ModesError(ModelError):
    """More modes asked for than the model can give (the scene names the field ``modes``)."""


def rigid_body_modes(model: FEModel) -> np.ndarray:
    """Rigid-body modes R (n_dof × 3 plane, × 6 space) about the body-frame origin.

    Columns: translations along x, y (, z), then small rotations about z (plane) or x, y, z
    (space): nodal translation ``ω × x_i``, nodal rotation ``ω`` (for nodes with rotational
    dofs).
    """
    dim, d, n = model.dimension, model.dofs_per_node, model.n_nodes
    x = model.positions
    rot = rotational_dofs(dim, d)
    if dim == 2:
        R = np.zeros((n, d, 3))
        R[:, 0, 0] = 1.0
        R[:, 1, 1] = 1.0
        R[:, 0, 2] = -x[:, 1]
        R[:, 1, 2] = x[:, 0]
        if rot:
            R[:, rot[0], 2] = 1.0
        return R.reshape(n * d, 3)
    R = np.zeros((n, d, 6))
    for k in range(3):
        R[:, k, k] = 1.0
        w = np.zeros(3)
        w[k] = 1.0
        R[:, :3, 3 + k] = np.cross(w, x)
        if rot:
            R[:, rot[k], 3 + k] = 1.0
    return R.reshape(n * d, 6)


def _as_dense(A) -> np.ndarray:
    return A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)


def _deflated_inverse(K, M, R: np.ndarray, where: str) -> spl.LinearOperator:
    """A generalised inverse of a free structure's K on the complement of its rigid modes.

    ``G b = P K_S⁺ Pᵀ b``: ``Pᵀ b = b − M R (RᵀMR)⁻¹ Rᵀ b`` removes the load's resultant
    (inertia relief), ``K_S⁺`` solves with an isostatic support S (the rows of R picked by a
    pivoted QR, so that ``R_S`` is regular and ``K_SS`` complementary block positive definite)
    and ``P x = x − R (RᵀMR)⁻¹ RᵀM x`` removes the rigid part.  The rigid modes have
    eigenvalue 0 of ``G M``, the elastic ones ``1/λ`` (Géradin and Rixen, *Mechanical
    Vibrations*, 3rd ed., 2015, §4.5).
    """
    n = K.shape[0]
    _, _, piv = sl.qr(R.T, pivoting=True, mode="economic")
    support = np.sort(piv[: R.shape[1]])
    free = np.setdiff1d(np.arange(n), support)
    try:
        lu = spl.splu(sp.csc_matrix(K[free][:, free]))
    except RuntimeError as exc:
        raise ModelError(f"{where}: the structure held isostatically is still singular "
                         f"({exc}): a mechanism or a disconnected part") from exc
    MR = M @ R
    G = np.linalg.inv(R.T @ MR)

    def apply(b):
        b = np.asarray(b, dtype=float).reshape(-1)
        b = b - MR @ (G @ (R.T @ b))
        x = np.zeros(n)
        x[free] = lu.solve(b[free])
        return x - R @ (G @ (MR.T @ x))

    return spl.LinearOperator((n, n), matvec=apply, dtype=float)


def _lowest(K, M, k: int, *, where: str,
            rigid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` lowest eigenpairs of ``K φ = λ M φ``, M-normalised, ascending.

    Dense ``eigh`` up to :data:`DENSE_LIMIT` dofs (``rigid`` ignored: the rigid modes come
    first); above it shift-invert Lanczos at σ = 0, with the deflated inverse of
    :func:`_deflated_inverse` when ``rigid`` (the rigid modes of a free structure) is given,
    so that only elastic modes are returned.
    """
    n = K.shape[0]
    if k < 1:
        raise ModelError(f"{where}: at least one mode is needed, got {k}")
    if k > n:
        raise ModesError(f"{where}: {k} modes asked for but the problem has only {n} dofs: "
                         f"at most {n} modes")
    try:
        if n <= DENSE_LIMIT or k >= n - 1:
            lam, V = sl.eigh(_as_dense(K), _as_dense(M), subset_by_index=[0, k - 1])
        else:
            Ks, Ms = sp.csc_matrix(K), sp.csc_matrix(M)
            op = _deflated_inverse(Ks, Ms, rigid, where) if rigid is not None else None
            lam, V = spl.eigsh(Ks, k=k, M=Ms, sigma=0.0, which="LM", OPinv=op)
            order = np.argsort(lam)
            lam, V = lam[order], V[:, order]
            V = V / np.sqrt(np.einsum("ij,ij->j", V, Ms @ V))
    except (np.linalg.LinAlgError, sl.LinAlgError, RuntimeError, ValueError) as exc:
        raise ModelError(f"{where}: the eigenproblem failed ({exc}); is the mass matrix "
                         "positive definite on every dof?") from exc
    return lam, V


def _split(model: FEModel, Phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nodal translations (n, dim, m) and rotations ((n, m) plane, (n, 3, m) space) of Φ."""
    dim, d, n, m = model.dimension, model.dofs_per_node, model.n_nodes, Phi.shape[1]
    P = Phi.reshape(n, d, m)
    rot = rotational_dofs(dim, d)
    phi_t = P[:, :dim, :].copy()
    if dim == 2:
        phi_r = P[:, rot[0], :].copy() if rot else np.zeros((n, m))
    else:
        phi_r = P[:, list(rot), :].copy() if rot else np.zeros((n, 3, m))
    return phi_t, phi_r


def _finish(model: FEModel, Phi: np.ndarray, reduction: str, reference: int | None,
            key: str) -> ModalData:
    M, K = model.mass_matrix, model.stiffness_matrix
    Mr = Phi.T @ (M @ Phi)
    Kr = Phi.T @ (K @ Phi)
    Mr, Kr = 0.5 * (Mr + Mr.T), 0.5 * (Kr + Kr.T)
    lam = np.diag(Kr).copy()
    if np.any(lam < 0.0):
        lam = np.maximum(lam, 0.0)
    R = rigid_body_modes(model)
    rigid = R.T @ (M @ R)
    coupling = R.T @ (M @ Phi)
    phi_t, phi_r = _split(model, Phi)
    return ModalData(dimension=model.dimension, positions=model.positions.copy(),
                     masses=model.masses.copy(), inertias=model.inertias.copy(),
                     phi_t=phi_t, phi_r=phi_r, mass=Mr, stiffness=Kr,
                     frequencies=np.sqrt(lam), node_names=dict(model.node_names),
                     reduction=reduction, reference=reference,
                     rigid_mass=0.5 * (rigid + rigid.T), rigid_coupling=np.asarray(coupling),
                     source=model.source, key=key)


def fe_model_key(model: FEModel):
    """What identifies an FE model in the reduction cache key: its input files, else its
    matrices, node positions, masses, inertias and node names."""
    if model.inputs:
        return model.inputs
    return {"M": model.mass_matrix, "K": model.stiffness_matrix, "x": model.positions,
            "d": model.dofs_per_node, "m": model.masses, "J": model.inertias,
            "names": dict(model.node_names)}


def _node_label(model: FEModel, i: int) -> str:
    names = [n for n, k in model.node_names.items() if k == i]
    return f"node {i} ('{names[0]}')" if names else f"node {i}"


def check_units(model: FEModel) -> None:
    """Finite M and K, a total mass within :data:`PLAUSIBLE_MASS` and diagonal ratios
    K_ii/M_ii — Rayleigh quotients of unit vectors, so lower bounds of the largest eigenvalue
    ω²_max — within :data:`PLAUSIBLE_OMEGA`²; each refusal names the matrix and the dof."""
    src, d = model.source, model.dofs_per_node
    for field, matrix in (("mass matrix M", model.mass_matrix),
                          ("stiffness matrix K", model.stiffness_matrix)):
        values = matrix.data if sp.issparse(matrix) else np.asarray(matrix, float)
        if not np.all(np.isfinite(values)):
            raise ModelError(f"{src}: the {field} has non-finite entries (inf or NaN)")
    total = float(np.sum(model.masses))
    low, high = PLAUSIBLE_MASS
    if model.n_nodes and not low <= total <= high:
        raise ModelError(f"{src}: the mass matrix M gives a total mass of {total:.3g} kg, "
                         f"outside the plausible range [{low:g}, {high:g}] kg: check the unit "
                         "of M (its scale)")
    Md = np.asarray(sp.csr_matrix(model.mass_matrix).diagonal(), float)
    Kd = np.asarray(sp.csr_matrix(model.stiffness_matrix).diagonal(), float)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = np.where(Md > 0.0, Kd / Md, 0.0)
    if ratio.size and ratio.max() > PLAUSIBLE_OMEGA ** 2:
        dof = int(np.argmax(ratio))
        raise ModelError(f"{src}: the stiffness matrix K over the mass matrix M gives "
                         f"frequencies of at least ω = {np.sqrt(ratio[dof]):.3g} rad/s "
                         f"(K_ii/M_ii at dof {dof}, {_node_label(model, dof // d)}), beyond "
                         f"the plausible {PLAUSIBLE_OMEGA:g} rad/s: check the units of K "
                         "and M (their scales)")


def check_fe_model(model: FEModel) -> None:
    """Checks of an FE model before any reduction (every reduction runs them).

    - The units are plausible (:func:`check_units`): M and K finite, the total mass within
      :data:`PLAUSIBLE_MASS`, no diagonal ratio K_ii/M_ii above :data:`PLAUSIBLE_OMEGA`².
    - The nodes are distinct: two nodes at one position (within 1e-9 of the model's extent),
      or all nodes at one point, are refused naming them — the rigid-body modes and the
      interface frames need a model of non-zero size.
    - The mass matrix M is positive definite: a Cholesky factorisation M = L Lᵀ up to
      :data:`DENSE_LIMIT` dofs (its failure names the first dof whose leading minor is not
      positive, and its node); above, the inertia of M by a sparse LU with a symmetric
      permutation and no pivoting (Sylvester's law of inertia: the signs of U's diagonal are
      those of M's eigenvalues), a non-positive pivot refused.  The eigenproblems
      (K − ω² M) φ = 0 are only defined for M > 0 (Craig & Kurdila, §10.1).

    Raises
    ------
    ModelError
        Naming the model's source and the nodes or dof at fault.
    """
    src = model.source
    pos = np.asarray(model.positions, dtype=float)
    extent = float(np.ptp(pos, axis=0).max()) if pos.size else 0.0
    if len(pos) > 1 and extent == 0.0:
        raise ModelError(f"{src}: all {len(pos)} nodes are at one point {pos[0].tolist()}: "
                         "a model needs nodes of distinct positions")
    if len(pos) > 1:
        order = np.lexsort(pos.T[::-1])
        gaps = np.abs(np.diff(pos[order], axis=0)).max(axis=1)
        same = np.flatnonzero(gaps <= 1e-9 * extent)
        if same.size:
            i, j = sorted((int(order[same[0]]), int(order[same[0] + 1])))
            raise ModelError(f"{src}: {_node_label(model, i)} and {_node_label(model, j)} are "
                             f"at one position {pos[i].tolist()}: nodes must be distinct")
    check_units(model)
    M = model.mass_matrix
    n = M.shape[0]
    d = model.dofs_per_node
    if n <= DENSE_LIMIT:
        try:
            sl.cholesky(_as_dense(M), lower=True, check_finite=False)
            return
        except (np.linalg.LinAlgError, sl.LinAlgError) as exc:
            found = re.search(r"(\d+)-th leading minor", str(exc))
            dof = int(found.group(1)) - 1 if found else None
    else:
        try:
            lu = spl.splu(sp.csc_matrix(M), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                          options={"SymmetricMode": True})
            pivots = lu.U.diagonal()
            bad = np.flatnonzero(~(pivots > 0.0))
            if not bad.size:
                return
            dof = int(lu.perm_c[bad[0]])
        except RuntimeError:  # an exactly singular matrix
            dof = None
    where = f" (first at dof {dof}, {_node_label(model, dof // d)})" if dof is not None \
        and 0 <= dof < n else ""
    raise ModelError(f"{src}: the mass matrix is not positive definite{where}: every motion "
                     "of the model must have mass (a negative or missing mass, a sign error "
                     "or a wrong unit)")


def _node_index(model: FEModel, node: str | int, what: str) -> int:
    if isinstance(node, str):
        return model.node(node)
    if isinstance(node, bool) or not isinstance(node, int | np.integer) \
            or not 0 <= node < model.n_nodes:
        raise ModelError(f"{model.source}: {what} {node!r} is neither a node name nor a node "
                         f"index in [0, {model.n_nodes})")
    return int(node)


#: Largest ratio of the highest to the lowest eigenvalue of a modal basis for which the
#: zero-energy tests (eigenvalue ≤ 1e-9 × the largest) can tell a rigid or mechanism mode
#: from a true elastic one.
EIGENVALUE_SPAN = 1e9


def _too_many_modes(src: str, lam: np.ndarray | None, kind: str) -> None:
    """Raise :class:`ModesError` when the ``lam`` (ascending, positive) of the requested
    modes span more than :data:`EIGENVALUE_SPAN`: the lowest elastic modes then fall under the
    zero-energy threshold and look like a mechanism — the model was asked for modes it cannot
    give apart (the highest ones are mesh modes, ω ratio above 3e4)."""
    if lam is None or lam.size < 2 or not lam[0] > 0.0 \
            or lam[-1] <= EIGENVALUE_SPAN * lam[0]:
        return
    usable = int(np.count_nonzero(lam <= EIGENVALUE_SPAN * lam[0]))
    raise ModesError(f"{src}: {lam.size} {kind} modes asked for, more than the model can give "
                     f"apart: their eigenvalues span {lam[0]:.3g} to {lam[-1]:.3g} (ratio "
                     f"{lam[-1] / lam[0]:.2g} > {EIGENVALUE_SPAN:g}), the lowest then cannot "
                     f"be told from zero-energy modes; use at most {usable} modes")


def craig_bampton(model: FEModel, modes: int, interfaces: Sequence[str | int], *,
                  reference: str | int | None = None) -> ModalData:
    """Craig–Bampton basis: ``modes`` fixed-interface normal modes + the static constraint
    modes of every dof of the interface nodes other than the reference node, orthonormalised.

    Parameters
    ----------
    model : FEModel
    modes : int
        Number of fixed-interface normal modes (0 keeps only constraint modes).
    interfaces : sequence of node names or indices
        Interface nodes (where joints, forces attach); the first is the reference node unless
        ``reference`` is given (it is then added to the interfaces).
    reference : str or int, optional
        The node clamped in the body frame.

    Returns
    -------
    ModalData
        ``modes + d·(n_interfaces − 1)`` modes (d dofs per node), frequencies ascending;
        fewer when the reference node has no rotational dofs and the constraint modes span
        rigid rotations about it (dropped: the floating frame carries them).
    """
    src = model.source
    if isinstance(modes, bool) or not isinstance(modes, int | np.integer) or modes < 0:
        raise ModelError(f"{src}: modes must be a non-negative integer, got {modes!r}")
    check_fe_model(model)
    if isinstance(interfaces, str):
        interfaces = [interfaces]
    nodes = [_node_index(model, v, "interface") for v in interfaces]
    if reference is not None:
        ref = _node_index(model, reference, "reference node")
        nodes = [ref, *[i for i in nodes if i != ref]]
    if not nodes:
        raise ModelError(f"{src}: Craig–Bampton needs at least one interface node (the first "
                         "is clamped in the body frame)")
    if len(set(nodes)) != len(nodes):
        raise ModelError(f"{src}: interface nodes repeat: {list(interfaces)}")
    ref = nodes[0]
    B = np.concatenate([model.node_dofs(i) for i in nodes])
    Bc = np.concatenate([model.node_dofs(i) for i in nodes[1:]]) if len(nodes) > 1 \
        else np.zeros(0, dtype=int)
    interior = np.setdiff1d(np.arange(model.n_dof), B)
    if modes + Bc.size == 0:
        raise ModelError(f"{src}: Craig–Bampton with one interface needs modes >= 1")
    K = sp.csr_matrix(model.stiffness_matrix)
    M = sp.csr_matrix(model.mass_matrix)
    Kii = K[interior][:, interior]
    Mii = M[interior][:, interior]
    cols = []
    lam_fixed = None
    if modes:
        lam, V = _lowest(Kii, Mii, int(modes),
                         where=f"{src}: fixed-interface normal modes")
        if lam[0] <= 0.0:
            raise ModelError(f"{src}: the structure clamped at its interfaces still moves "
                             f"freely (eigenvalue {lam[0]:.3g}); add interface nodes")
        lam_fixed = lam
        F = np.zeros((model.n_dof, modes))
        F[interior] = V
        cols.append(F)
    if Bc.size:
        try:
            rhs = -K[interior][:, Bc].toarray()
            if interior.size <= DENSE_LIMIT:
                X = sl.solve(Kii.toarray(), rhs, assume_a="sym")
            else:
                X = spl.splu(sp.csc_matrix(Kii)).solve(rhs)
        except (np.linalg.LinAlgError, sl.LinAlgError, RuntimeError) as exc:
            raise ModelError(f"{src}: the interior stiffness K_II is singular ({exc}): the "
                             "structure clamped at its interfaces can still move") from exc
        if not np.all(np.isfinite(X)):
            raise ModelError(f"{src}: the interior stiffness K_II is singular: the structure "
                             "clamped at its interfaces can still move")
        C = np.zeros((model.n_dof, Bc.size))
        C[Bc, np.arange(Bc.size)] = 1.0
        C[interior] = X
        cols.append(C)
    T = np.hstack(cols)
    Mt = T.T @ (M @ T)
    Kt = T.T @ (K @ T)
    try:
        lam, Q = sl.eigh(0.5 * (Kt + Kt.T), 0.5 * (Mt + Mt.T))
    except (np.linalg.LinAlgError, sl.LinAlgError) as exc:
        raise ModelError(f"{src}: the Craig–Bampton reduced mass matrix is singular ({exc}); "
                         "do interface nodes carry mass?") from exc
    # with translation-only nodes the reference node does not hold the rotations: the basis
    # then spans rigid rotations (zero eigenvalues), which the floating frame carries; they
    # are dropped and the kept modes are M-orthogonal to them
    zero = lam <= 1e-9 * max(abs(lam[-1]), 1e-300)
    if np.any(zero):
        Z = T @ Q[:, zero]
        R = rigid_body_modes(model)
        fit = R @ np.linalg.lstsq(R, Z, rcond=None)[0]
        if np.abs(Z - fit).max() > 1e-6 * np.abs(Z).max() or zero.all():
            _too_many_modes(src, lam_fixed, "fixed-interface")
            raise ModelError(f"{src}: the Craig–Bampton basis has {int(zero.sum())} "
                             "zero-energy modes that are not rigid-body motions (a mechanism)")
        Q = Q[:, ~zero]
    key = cache_key("craig_bampton", fe_model_key(model), int(modes), nodes)
    return _finish(model, T @ Q, "craig_bampton", ref, key)


def free_modes(model: FEModel, modes: int, *, rigid_tolerance: float = 1e-8) -> ModalData:
    """Free-interface normal modes, rigid-body modes removed (module docstring).

    Parameters
    ----------
    model : FEModel
    modes : int
        Number of elastic modes kept.
    rigid_tolerance : float
        A rigid-body mode R_k counts when ``‖K R_k‖ ≤ tol · ‖K‖ · ‖R_k‖`` (max norms); only
        those are dropped (an imported model held somewhere has fewer).
    """
    src = model.source
    if isinstance(modes, bool) or not isinstance(modes, int | np.integer) or modes < 1:
        raise ModelError(f"{src}: modes must be a positive integer, got {modes!r}")
    check_fe_model(model)
    K = sp.csr_matrix(model.stiffness_matrix)
    M = sp.csr_matrix(model.mass_matrix)
    R = rigid_body_modes(model)
    knorm = float(abs(K).max()) if K.nnz else 0.0
    KR = K @ R
    keep = [j for j in range(R.shape[1])
            if np.abs(KR[:, j]).max() <= rigid_tolerance * knorm * np.abs(R[:, j]).max()]
    R = R[:, keep]
    nr = R.shape[1]
    where = f"{src}: free-interface normal modes"
    if nr and K.shape[0] > DENSE_LIMIT:
        lam, V = _lowest(K, M, int(modes), where=where, rigid=R)
        nr_found = 0
    else:
        if int(modes) + nr > K.shape[0]:
            raise ModesError(f"{where}: {int(modes)} modes asked for but the model's "
                             f"{K.shape[0]} dofs less its {nr} rigid-body modes give at most "
                             f"{K.shape[0] - nr} modes")
        lam, V = _lowest(K, M, int(modes) + nr, where=where)
        nr_found = nr
    scale = max(abs(lam[-1]), 1e-300)
    # rounding leaves the zero eigenvalues at about eps·λ_max (large for fine meshes): a
    # rigid-body mode counts when it is 1000 times below the first elastic one
    if nr_found and np.any(np.abs(lam[:nr]) > 1e-3 * abs(lam[nr])):
        raise ModelError(f"{src}: expected {nr} rigid-body modes with zero frequency, got "
                         f"eigenvalues {lam[:nr].tolist()}")
    if lam[nr_found] <= 1e-8 * scale:
        if lam[nr_found] > 0.0:
            _too_many_modes(src, lam[nr_found:], "free-interface")
        raise ModelError(f"{src}: the free structure has more zero-energy modes than its {nr} "
                         f"rigid-body modes (eigenvalue {lam[nr_found]:.3g}): a mechanism or a "
                         "disconnected part")
    Phi = V[:, nr_found:]
    if nr:
        MR = M @ R
        Phi = Phi - R @ np.linalg.solve(R.T @ MR, MR.T @ Phi)
        Phi = Phi / np.sqrt(np.einsum("ij,ij->j", Phi, M @ Phi))
    key = cache_key("free", fe_model_key(model), int(modes), float(rigid_tolerance))
    return _finish(model, Phi, "free", None, key)


def reduce(model: FEModel, reduction: str, modes: int,
           interfaces: Sequence[str | int] = ()) -> ModalData:
    """Dispatch on the scene key ``reduction``: ``"craig_bampton"`` (interfaces required) or
    ``"free"`` (interfaces ignored: joints attach at any node).  ``modes`` is checked
    against :data:`~casmbd.limits.MAX_MODES` first."""
    check_count(f"{model.source}: modes", int(modes), MAX_MODES,
                "a modal reduction needs few modes (tens)")
    if reduction == "craig_bampton":
        return craig_bampton(model, modes, interfaces)
    if reduction == "free":
        return free_modes(model, modes)
    raise ModelError(f"{model.source}: reduction must be 'craig_bampton' or 'free', "
                     f"got {reduction!r}")
