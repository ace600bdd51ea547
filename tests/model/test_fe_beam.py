"""Finite-element beam and modal reduction (issue 23, modal data) against closed forms.

Closed forms: Euler–Bernoulli cantilever and free-free beams (Blevins, *Formulas for Natural
Frequency and Mode Shape*, 1979, table 8-1): ω_k = (β_k L)² sqrt(EI / (ρA L⁴)) with
cos βL cosh βL = −1 (clamped-free) or +1 (free-free); bars: ω_k = (2k − 1) π/(2L) sqrt(EA/ρA)
(clamped-free), k π/L sqrt(EA/ρA) (free-free), torsion with GJ/ρIp; static tip deflection
P L³/(3 EI), axial P L/EA, torsion T L/GJ.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import brentq

from casmbd.errors import ModelError
from casmbd.model import modal_reduction
from casmbd.model.fe_beam import beam_model
from casmbd.model.fe_import import load_fe_npz, save_fe_npz
from casmbd.model.modal import cache_key
from casmbd.model.modal_reduction import craig_bampton, free_modes, rigid_body_modes

L, EI, EA, RHOA = 10.0, 1.4e4, 2.8e7, 1.2          # the spin-up beam of issue 23
GJ, RHOIP = 9.0e3, 3.0e-3
OMEGA0 = np.sqrt(EI / (RHOA * L**4))


def _beta(sign: float, k: int) -> float:
    """k-th root (1-based) of cos x cosh x = sign (−1 clamped-free, +1 free-free)."""
    f = lambda x: np.cos(x) * np.cosh(x) - sign  # noqa: E731
    guess = (2 * k - 1) * np.pi / 2 if sign < 0 else (2 * k + 1) * np.pi / 2
    return brentq(f, guess - 1.0, guess + 1.0, xtol=1e-14)


def _plane(n=20, **kw):
    return beam_model(L, n, EA=EA, rhoA=RHOA, EI=EI, **kw)


def _space(n=20, **kw):
    return beam_model(L, n, EA=EA, rhoA=RHOA, EIy=EI, EIz=2 * EI, GJ=GJ, rhoIp=RHOIP,
                      dimension=3, **kw)


def _clamped_static(model, load: dict[int, float]) -> np.ndarray:
    """Nodal displacements of the model clamped at node 0 under tip-node loads {dof: value}."""
    K = model.stiffness_matrix.toarray()
    d = model.dofs_per_node
    f = np.zeros(K.shape[0])
    for k, v in load.items():
        f[K.shape[0] - d + k] = v
    u = np.zeros_like(f)
    u[d:] = np.linalg.solve(K[d:, d:], f[d:])
    return u.reshape(-1, d)


def test_closed_form_roots_match_the_brief():
    # the 4-digit βL values of the brief (tolerance: their rounding, 5e-5)
    assert [_beta(-1, k) for k in (1, 2, 3)] == pytest.approx([1.8751, 4.6941, 7.8548], abs=5e-5)
    assert [_beta(1, k) for k in (1, 2)] == pytest.approx([4.7300, 7.8532], abs=5e-5)


@pytest.mark.parametrize("n", [1, 3, 20])
def test_cantilever_static_tip_deflection_exact(n):
    P = 50.0
    u = _clamped_static(_plane(n), {0: P, 1: P})
    # cubic elements: nodal values exact (relative 1e-10, rounding of the solve)
    assert u[-1, 1] == pytest.approx(P * L**3 / (3 * EI), rel=1e-10)
    assert u[-1, 2] == pytest.approx(P * L**2 / (2 * EI), rel=1e-10)
    assert u[-1, 0] == pytest.approx(P * L / EA, rel=1e-10)


def test_space_cantilever_static_both_planes_and_torsion():
    P, T = 40.0, 7.0
    u = _clamped_static(_space(4), {0: P, 1: P, 2: P, 3: T})
    tip = u[-1]
    assert tip[0] == pytest.approx(P * L / EA, rel=1e-10)
    assert tip[1] == pytest.approx(P * L**3 / (3 * 2 * EI), rel=1e-10)     # EIz = 2 EI
    assert tip[2] == pytest.approx(P * L**3 / (3 * EI), rel=1e-10)         # EIy = EI
    assert tip[3] == pytest.approx(T * L / GJ, rel=1e-10)
    # right-handed rotations: θz = dv/dx, θy = −dw/dx
    assert tip[5] == pytest.approx(P * L**2 / (2 * 2 * EI), rel=1e-10)
    assert tip[4] == pytest.approx(-P * L**2 / (2 * EI), rel=1e-10)


def test_per_element_properties_stepped_cantilever():
    # EI1 on [0, 4], EI2 on [4, 10]: δ = P/EI1 (L³ − (L−a)³)/3 + P/EI2 (L−a)³/3 (unit load)
    a, ei1, ei2, P = 4.0, 2.0e4, 0.5e4, 10.0
    lengths = [2.0, 2.0, 3.0, 3.0]
    m = beam_model(L, 4, EA=EA, rhoA=RHOA, EI=[ei1, ei1, ei2, ei2], element_lengths=lengths,
                   nodes={"root": 0.0, "step": a, "tip": L})
    assert m.node_names == {"root": 0, "step": 2, "tip": 4}
    exact = P / ei1 * (L**3 - (L - a) ** 3) / 3 + P / ei2 * (L - a) ** 3 / 3
    assert _clamped_static(m, {1: P})[-1, 1] == pytest.approx(exact, rel=1e-10)


def test_cantilever_frequencies_converge_with_elements():
    exact = np.array([_beta(-1, k) ** 2 for k in (1, 2, 3)]) * OMEGA0
    errors = {}
    for n in (5, 10, 20):
        w = craig_bampton(_plane(n), 3, ["root"]).frequencies
        errors[n] = np.abs(w - exact) / exact
    # convergence O(h⁴) for cubic elements: halving h divides the mode-1 error by > 10
    assert errors[10][0] < errors[5][0] / 10 and errors[20][0] < errors[10][0] / 10
    assert errors[20][0] < 1e-4          # the brief's criterion; measured 5.4e-8
    assert np.all(errors[20] < [1e-6, 1e-5, 1e-4])
    # consistent mass: Rayleigh–Ritz bounds from above
    assert np.all(craig_bampton(_plane(20), 3, ["root"]).frequencies > exact)


def test_free_free_bending_frequencies():
    md = free_modes(_plane(20), 2)
    exact = np.array([_beta(1, k) ** 2 for k in (1, 2)]) * OMEGA0
    assert md.frequencies == pytest.approx(exact, rel=1e-4)
    assert md.reference is None and md.reduction == "free"


def _classify(md) -> list[str]:
    """Dominant kind of each spatial mode from its nodal shape: axial, torsion, bend."""
    kinds = []
    for j in range(md.n_modes):
        parts = {"axial": np.sum(md.phi_t[:, 0, j] ** 2),
                 "bend": np.sum(md.phi_t[:, 1:, j] ** 2),
                 "torsion": np.sum(md.phi_r[:, 0, j] ** 2) * 1e-2}
        kinds.append(max(parts, key=parts.get))
    return kinds


def test_space_axial_and_torsion_frequencies():
    # linear elements: O(h²); 40 elements give ~1e-4 on the first mode (tolerance 3e-4)
    md = craig_bampton(_space(40), 30, ["root"])
    kinds = _classify(md)
    axial = md.frequencies[[k == "axial" for k in kinds]]
    tors = md.frequencies[[k == "torsion" for k in kinds]]
    assert axial[0] == pytest.approx(np.pi / (2 * L) * np.sqrt(EA / RHOA), rel=3e-4)
    assert tors[0] == pytest.approx(np.pi / (2 * L) * np.sqrt(GJ / RHOIP), rel=3e-4)
    assert tors[1] == pytest.approx(3 * np.pi / (2 * L) * np.sqrt(GJ / RHOIP), rel=3e-3)
    bend = np.sort(md.frequencies[[k == "bend" for k in kinds]])[:2]
    b1 = _beta(-1, 1) ** 2 / L**2 / np.sqrt(RHOA)
    assert bend == pytest.approx([b1 * np.sqrt(EI), b1 * np.sqrt(2 * EI)], rel=1e-4)
    free = free_modes(_space(40), 30)
    fk = _classify(free)
    assert free.frequencies[fk.index("axial")] == pytest.approx(
        np.pi / L * np.sqrt(EA / RHOA), rel=3e-4)
    assert free.frequencies[fk.index("torsion")] == pytest.approx(
        np.pi / L * np.sqrt(GJ / RHOIP), rel=3e-4)


def test_craig_bampton_root_interface_few_modes_and_orthonormal():
    md = craig_bampton(_plane(20), 4, ["root"])
    exact = np.array([_beta(-1, k) ** 2 for k in (1, 2, 3)]) * OMEGA0
    assert md.frequencies[:3] == pytest.approx(exact, rel=1e-4)
    assert np.abs(md.mass - np.eye(4)).max() < 1e-12
    assert np.abs(md.stiffness - np.diag(md.frequencies**2)).max() < 1e-12 * md.stiffness.max()
    # reference node clamped in the body frame
    assert md.reference == 0
    assert np.abs(md.phi_t[0]).max() == 0.0 and np.abs(md.phi_r[0]).max() == 0.0
    assert md.phi_t.shape == (21, 2, 4) and md.phi_r.shape == (21, 4)


def test_craig_bampton_tip_interface_static_deflection_exact():
    model = _plane(10)
    md = craig_bampton(model, 2, ["root", "tip"])
    assert md.n_modes == 2 + 3
    P = 25.0
    tip = md.node("tip")
    # reduced statics: K_r η = Φ_tipᵀ f
    eta = np.linalg.solve(md.stiffness, md.phi_t[tip, 1] * P)
    assert md.phi_t[tip, 1] @ eta == pytest.approx(P * L**3 / (3 * EI), rel=1e-9)
    assert md.phi_r[tip] @ eta == pytest.approx(P * L**2 / (2 * EI), rel=1e-9)
    # without the tip constraint modes (five fixed-interface modes) it is not exact
    fixed = craig_bampton(model, 5, ["root"])
    eta = np.linalg.solve(fixed.stiffness, fixed.phi_t[tip, 1] * P)
    assert abs(fixed.phi_t[tip, 1] @ eta / (P * L**3 / (3 * EI)) - 1.0) > 1e-4


def test_free_basis_orthogonal_to_rigid_modes():
    for model in (_plane(12), _space(8)):
        md = free_modes(model, 4)
        R = rigid_body_modes(model)
        d, dim = model.dofs_per_node, model.dimension
        rot = md.phi_r[:, None, :] if dim == 2 else md.phi_r
        Phi = np.concatenate([md.phi_t, rot], axis=1).reshape(model.n_nodes * d, -1)
        M = model.mass_matrix
        assert np.abs(R.T @ (M @ Phi)).max() < 1e-10 * np.sqrt(np.abs(R.T @ (M @ R)).max())
        assert np.abs(md.mass - np.eye(4)).max() < 1e-10
        assert np.all(md.frequencies > 0)


def test_lumped_description_and_rigid_mass():
    m = _space(8)
    md = craig_bampton(m, 2, ["root"])
    assert md.masses.sum() == pytest.approx(RHOA * L, rel=1e-13)
    assert md.masses @ md.positions[:, 0] == pytest.approx(RHOA * L**2 / 2, rel=1e-13)
    assert np.trace(md.inertias, axis1=1, axis2=2).sum() == pytest.approx(
        RHOIP * L + 2 * 8 * RHOA * (L / 8) ** 3 / 12, rel=1e-12)   # torsion + 2 bending axes
    # rigid mass from the consistent matrix: mass, first moment, inertia about the root, exact
    Rm = md.rigid_mass
    assert Rm[0, 0] == pytest.approx(RHOA * L, rel=1e-12)
    assert Rm[1, 5] == pytest.approx(RHOA * L**2 / 2, rel=1e-12)
    assert Rm[5, 5] == pytest.approx(RHOA * L**3 / 3, rel=1e-12)
    assert Rm[3, 3] == pytest.approx(RHOIP * L, rel=1e-12)
    # the lumped mass matrix: Φᵀ M Φ equals the lumped sums, and its frequencies converge too
    lm = craig_bampton(_plane(40, mass="lumped"), 2, ["root"])
    sums = (np.einsum("i,idm,idn->mn", lm.masses, lm.phi_t, lm.phi_t)
            + np.einsum("i,im,in->mn", lm.inertias, lm.phi_r, lm.phi_r))
    assert np.abs(sums - np.eye(2)).max() < 1e-12
    assert lm.frequencies[0] == pytest.approx(_beta(-1, 1) ** 2 * OMEGA0, rel=2e-3)


def test_sparse_eigensolver_path_agrees(monkeypatch):
    dense_cb, dense_free = craig_bampton(_plane(30), 4, ["root"]), free_modes(_plane(30), 4)
    monkeypatch.setattr(modal_reduction, "DENSE_LIMIT", 10)
    sparse_cb, sparse_free = craig_bampton(_plane(30), 4, ["root"]), free_modes(_plane(30), 4)
    assert sparse_cb.frequencies == pytest.approx(dense_cb.frequencies, rel=1e-9)
    assert sparse_free.frequencies == pytest.approx(dense_free.frequencies, rel=1e-9)
    assert np.abs(sparse_free.mass - np.eye(4)).max() < 1e-9


@pytest.mark.parametrize("layout", ["dense", "csr", "csc", "coo"])
def test_npz_round_trip(tmp_path, layout):
    model = _space(6, nodes={"root": 0.0, "mid": 5.0, "tip": 10.0})
    path = tmp_path / "part.npz"
    M, K = model.mass_matrix, model.stiffness_matrix
    if layout == "dense":
        save_fe_npz(path, M.toarray(), K.toarray(), model.positions, 6,
                    node_names=model.node_names)
    else:
        arrays = {"nodes": model.positions, "dofs_per_node": np.asarray(6),
                  "node_names": np.asarray(list(model.node_names)),
                  "node_ids": np.asarray(list(model.node_names.values()))}
        for name, A in (("mass", M), ("stiffness", K)):
            A = A.asformat(layout)
            sp.save_npz(tmp_path / f"{name}.npz", A)    # scipy's own arrays, prefixed
            with np.load(tmp_path / f"{name}.npz", allow_pickle=False) as z:
                arrays.update({f"{name}_{k}": z[k] for k in z.files})
        np.savez(path, **arrays)
    fe = load_fe_npz(path)
    assert fe.node_names == {"root": 0, "mid": 3, "tip": 6}
    a = craig_bampton(fe, 4, ["root", "tip"])
    b = craig_bampton(model, 4, ["root", "tip"])
    assert a.frequencies == pytest.approx(b.frequencies, rel=1e-10)
    # HRZ lumping: total mass exact, nodal masses close to the beam's tributary masses
    assert fe.masses.sum() == pytest.approx(RHOA * L, rel=1e-12)
    assert fe.masses == pytest.approx(model.masses, rel=0.05)
    # the key depends on the content, not the file
    assert load_fe_npz(path).inputs and craig_bampton(load_fe_npz(path), 4, ["root", "tip"]).key \
        == a.key


def test_cache_key():
    a = craig_bampton(_plane(6), 2, ["root"]).key
    assert a == craig_bampton(_plane(6), 2, ["root"]).key and len(a) == 64
    assert a != craig_bampton(_plane(6), 3, ["root"]).key
    assert a != craig_bampton(beam_model(L, 6, EA=EA, rhoA=RHOA, EI=EI * 1.001), 2,
                              ["root"]).key
    assert a != free_modes(_plane(6), 2).key
    S = sp.random(5, 5, density=0.5, random_state=1)
    assert cache_key(S.tocsr()) == cache_key(S.tocoo()) != cache_key(S.toarray())


def test_bad_beam_input():
    with pytest.raises(ModelError, match=r"node 'mid' at arc length 4\.1 .*nearest nodes "
                                         r"are at 4 and 4\.5"):
        beam_model(L, 20, EA=EA, rhoA=RHOA, EI=EI, nodes={"root": 0.0, "mid": 4.1})
    with pytest.raises(ModelError, match=r"node 'far'.*outside"):
        _plane(4, nodes={"far": 11.0})
    with pytest.raises(ModelError, match="EI must be finite and positive; element 2"):
        beam_model(L, 4, EA=EA, rhoA=RHOA, EI=[1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ModelError, match="rhoA must be a number or a list of 4"):
        beam_model(L, 4, EA=EA, rhoA=[1.0, 2.0], EI=EI)
    with pytest.raises(ModelError, match=r"EA .*element 0 has nan"):
        beam_model(L, 4, EA=float("nan"), rhoA=RHOA, EI=EI)
    with pytest.raises(ModelError, match="property GJ is required"):
        beam_model(L, 4, EA=EA, rhoA=RHOA, EIy=EI, EIz=EI, rhoIp=1.0, dimension=3)
    with pytest.raises(ModelError, match="elements must be a positive integer"):
        beam_model(L, 0, EA=EA, rhoA=RHOA, EI=EI)
    with pytest.raises(ModelError, match="no node named 'hub'"):
        craig_bampton(_plane(4), 2, ["hub"])
    with pytest.raises(ModelError, match="4 modes asked for but the problem has only 3"):
        craig_bampton(_plane(1), 4, ["root"])
    with pytest.raises(ModelError, match="reduction must be"):
        modal_reduction.reduce(_plane(4), "guyan", 2)


def _write(path, **arrays):
    np.savez(path, **arrays)
    return path


def test_bad_npz_input(tmp_path):
    m = _plane(3)
    good = {"nodes": m.positions, "dofs_per_node": np.asarray(3),
            "mass": m.mass_matrix.toarray(), "stiffness": m.stiffness_matrix.toarray()}
    f = tmp_path / "bad.npz"

    def fails(pattern, **change):
        arrays = {k: v for k, v in {**good, **change}.items() if v is not None}
        _write(f, **arrays)
        with pytest.raises(ModelError, match=pattern) as info:
            load_fe_npz(f)
        assert "bad.npz" in str(info.value)

    fails(r"field 'stiffness' is missing", stiffness=None)
    fails(r"field 'mass' has shape \(6, 6\), expected \(12, 12\)", mass=np.eye(6))
    asym = good["stiffness"].copy()
    asym[0, 4] += 1.0
    fails(r"field 'stiffness' is not symmetric", stiffness=asym)
    nan = good["mass"].copy()
    nan[2, 2] = np.nan
    fails(r"field 'mass' has non-finite entries", mass=nan)
    fails(r"field 'masses' is negative at node 1", masses=np.array([1.0, -1.0, 1.0, 1.0]))
    neg = good["mass"].copy()
    neg[4, 4] = -1.0
    fails(r"field 'mass' has a negative diagonal entry at node 1, dof 1", mass=neg)
    fails(r"dofs_per_node must be one of \(2, 3\)", dofs_per_node=np.asarray(6))
    fails(r"field 'nodes' must have shape", nodes=np.zeros(4))
    fails(r"'node_names' and 'node_ids' go together", node_names=np.asarray(["tip"]))
    fails(r"node 'tip' has index 9", node_names=np.asarray(["tip"]), node_ids=np.asarray([9]))
    fails(r"mass_format must be 'csr', 'csc' or 'coo'", mass=None,
          mass_format=np.asarray("bsr"))
    fails(r"sparse csr matrix 'mass' lacks field 'mass_indptr'", mass=None,
          mass_format=np.asarray("csr"), mass_shape=np.asarray([12, 12]),
          mass_data=np.ones(1), mass_indices=np.zeros(1, int))
    fails(r"sparse matrix 'mass' is malformed", mass=None,
          mass_format=np.asarray("csr"), mass_shape=np.asarray([12, 12]),
          mass_data=np.ones(2), mass_indices=np.asarray([0, 40]),
          mass_indptr=np.asarray([0] + [2] * 12))
    # objects would need pickle: refused from the member's header, data never becomes code
    np.savez(f, **{**good, "masses": np.asarray([{"a": 1}], dtype=object)})
    with pytest.raises(ModelError, match=r"bad\.npz.*member 'masses' holds Python objects"):
        load_fe_npz(f)
    # ... and a member load_fe_npz does not use is never read, objects or not (issue 31)
    np.savez(f, **good, extra=np.asarray([{"a": 1}], dtype=object))
    assert "extra" not in load_fe_npz(f).inputs
    f.write_bytes(b"not a zip file")
    with pytest.raises(ModelError, match=r"bad\.npz.*not a readable"):
        load_fe_npz(f)
    with pytest.raises(ModelError, match="no such file"):
        load_fe_npz(tmp_path / "absent.npz")


def _truss(tmp_path):
    """A plane truss (2 dofs per node, no rotations): two square bays with diagonals."""
    nodes = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], float)
    bars = [(0, 1), (1, 2), (3, 4), (4, 5), (0, 3), (1, 4), (2, 5), (0, 4), (1, 5)]
    n = len(nodes) * 2
    K, M = np.zeros((n, n)), np.zeros((n, n))
    ea, rho = 1.0e6, 2.0
    for a, b in bars:
        d = nodes[b] - nodes[a]
        h = np.linalg.norm(d)
        c = d / h
        idx = [2 * a, 2 * a + 1, 2 * b, 2 * b + 1]
        k = ea / h * np.outer(np.r_[-c, c], np.r_[-c, c])
        m = rho * h / 6 * np.kron([[2.0, 1.0], [1.0, 2.0]], np.eye(2))
        K[np.ix_(idx, idx)] += k
        M[np.ix_(idx, idx)] += m
    path = tmp_path / "truss.npz"
    save_fe_npz(path, sp.csr_matrix(M), sp.csr_matrix(K), nodes, 2,
                node_names={"left": 0, "right": 5})
    return path, K, M


def test_translation_only_model_free_modes_and_reference(tmp_path, monkeypatch):
    path, K, M = _truss(tmp_path)
    fe = load_fe_npz(path)
    lam = np.linalg.eigvalsh(np.linalg.solve(np.linalg.cholesky(M), np.linalg.solve(
        np.linalg.cholesky(M), K).T))                      # independent: L⁻¹ K L⁻ᵀ
    elastic = np.sqrt(np.sort(lam)[3:6])                   # 3 rigid-body modes in the plane
    md = free_modes(fe, 3)
    assert md.frequencies == pytest.approx(elastic, rel=1e-10)
    assert md.phi_r.shape == (6, 3) and not md.phi_r.any() and not md.inertias.any()
    assert fe.masses.sum() == pytest.approx(M.sum() / 2, rel=1e-12)   # total mass, 2 directions
    monkeypatch.setattr(modal_reduction, "DENSE_LIMIT", 4)            # deflated Lanczos path
    assert free_modes(fe, 3).frequencies == pytest.approx(elastic, rel=1e-9)
    # one translation-only node cannot hold the rotation: refused, naming the cause
    with pytest.raises(ModelError, match="clamped at its interfaces still moves freely"):
        craig_bampton(fe, 2, ["left"])
    # two interfaces: the constraint modes span the rotation about node 0; it is dropped
    two = craig_bampton(fe, 2, ["left", "right"])
    assert two.n_modes == 2 + 2 - 1 and np.all(two.frequencies > 1.0)
    Phi = two.phi_t.reshape(12, -1)
    R = rigid_body_modes(fe)
    assert np.abs(R[:, 2] @ M @ Phi).max() < 1e-10 * np.sqrt(R[:, 2] @ M @ R[:, 2])
    assert np.abs(two.phi_t[0]).max() == 0.0                 # reference translations held
