"""``flexible_mass = "reduced"`` with Craig–Bampton interfaces at several nodes (issue 35, item 2).

The body mass matrix at zero deformation must be the Gram matrix of the FE mass matrix M on the
basis [T_r R_r Φ] (rigid translations, rigid rotations about the body origin with the nodal
rotational dofs, the modes), built here with numpy from the FE matrices; before, only M_ff came
from Φᵀ M Φ while the rigid and coupling invariants were lumped sums, and the matrix was
indefinite for interfaces at both ends of a beam (smallest eigenvalue −0.28 for the 8-element
beam below: "the mass matrix is singular … has no inertia").  References:

* the pinned–pinned Euler–Bernoulli beam (Blevins, *Formulas for Natural Frequency and Mode
  Shape*, 1979, table 8-1: ω_n = (nπ)² sqrt(EI/(ρA L⁴))); under a uniform load q released from
  rest undeformed, the mid-span deflection is the modal series
  w(L/2, t) = −Σ_{n odd} 4 q L⁴/(EI (nπ)⁵) sin(nπ/2) (1 − cos ω_n t) (Timoshenko, Young and
  Weaver, *Vibration Problems in Engineering*, 4th ed., §5.10), statics 5 q L⁴/(384 EI);
* Lagrange's equations of the body's own kinetic energy by AD (Q_v consistent with M(η));
* the two mass-matrix messages: "indefinite" (negative kinetic energy) and "singular"
  (massless motion).

Figures measured (2026-11-29) are in the docstrings; bounds sit about 2x above them.  Analyses
run in CasADi's virtual machine.
"""

from __future__ import annotations

import pathlib

import casadi as ca
import numpy as np
import pytest
import scipy.sparse as sp
from conftest import private_cache

import casmbd
from casmbd.analysis.instant.checks import check_mass_matrix
from casmbd.compiled.build import compile_model
from casmbd.errors import ModelError, SingularMassMatrixError
from casmbd.model.fe_beam import beam_model
from casmbd.model.modal import FEModel, ModalData
from casmbd.model.modal_reduction import reduce
from casmbd.system.floating_frame import FlexibleBody, invariants, planar_rotation
from tests.flexible_references import KANE_BEAM, chord_deflection
from tests.model.test_mass_checks import chain

_cache = private_cache("cache_reduced_mass", scope="module")
ROOT = pathlib.Path(__file__).resolve().parents[2]

L, EI, EA, RHOA = (KANE_BEAM[k] for k in ("length", "EI", "EA", "rhoA"))
G = 0.0981  # small load: the sag (1.1 mm) stays linear (end rotation 3.5e-4 rad)


# ---------------------------------------------------------------- FE models
def _truss(dim: int) -> FEModel:
    """A translation-only FE model with consistent mass: a plane Warren truss (7 nodes, 11
    bars) or a space strip of triangular prisms with one diagonal per side face (12 nodes, 30
    bars), steel-like bars; bar mass ρ A l/6 [[2, 1], [1, 2]] ⊗ 1 (linear interpolation of
    every translation component), stiffness E A/l e eᵀ."""
    if dim == 2:
        nodes = [[float(i), 0.0] for i in range(4)] + [[i + 0.5, 0.6] for i in range(3)]
        bars = [(i, i + 1) for i in range(3)] + [(4, 5), (5, 6)] + \
            [(i, 4 + i) for i in range(3)] + [(i + 1, 4 + i) for i in range(3)]
    else:
        tri = [[0.0, 0.0], [1.0, 0.0], [0.5, 0.8]]
        nodes = [[float(x), *p] for x in range(4) for p in tri]
        bars = []
        for b in range(4):
            bars += [(3 * b, 3 * b + 1), (3 * b + 1, 3 * b + 2), (3 * b, 3 * b + 2)]
        for b in range(3):
            bars += [(3 * b + k, 3 * b + 3 + k) for k in range(3)]
            bars += [(3 * b + k, 3 * b + 3 + (k + 1) % 3) for k in range(3)]
    x = np.array(nodes)
    n = len(x)
    K, M = np.zeros((dim * n, dim * n)), np.zeros((dim * n, dim * n))
    ea, rho_a = 2.0e7, 0.8
    for a, b in bars:
        d = x[b] - x[a]
        length = float(np.linalg.norm(d))
        e = d / length
        idx = np.r_[dim * a:dim * a + dim, dim * b:dim * b + dim]
        K[np.ix_(idx, idx)] += ea / length * np.kron([[1, -1], [-1, 1]], np.outer(e, e))
        M[np.ix_(idx, idx)] += rho_a * length / 6 * np.kron([[2, 1], [1, 2]], np.eye(dim))
    masses = M.sum(axis=1)[::dim]
    inertias = np.zeros(n) if dim == 2 else np.zeros((n, 3, 3))
    names = {"A": 0, "B": 3} if dim == 2 else {"A": 0, "C": 1, "B": 9}
    return FEModel(sp.csr_matrix(M), sp.csr_matrix(K), x, dim, masses, inertias, names,
                   source=f"truss {dim}d")


def _beam(dim: int, elements: int = 8) -> FEModel:
    props = {"EI": EI} if dim == 2 else {"EIy": EI, "EIz": 2 * EI, "GJ": 1.0e4, "rhoIp": 0.01}
    return beam_model(L, elements, EA=EA, rhoA=RHOA, nodes={"root": 0.0, "tip": L},
                      dimension=dim, **props)


def _full_basis(fe: FEModel, modal: ModalData) -> np.ndarray:
    """[T_r R_r Φ] in the FE dofs, written here: rigid translations, small rotations about the
    body origin (nodal translation ω × x_i, nodal rotation ω), then the modes (phi_t, phi_r)."""
    dim, d, n, m = fe.dimension, fe.dofs_per_node, fe.n_nodes, modal.n_modes
    x = fe.positions
    c = 1 if dim == 2 else 3
    rigid = np.zeros((n, d, dim + c))
    rigid[:, :dim, :dim] = np.eye(dim)
    axes = [np.array([0.0, 0.0, 1.0])] if dim == 2 else list(np.eye(3))
    x3 = np.column_stack([x, np.zeros(n)]) if dim == 2 else x
    for k, w in enumerate(axes):
        rigid[:, :dim, dim + k] = np.cross(w, x3)[:, :dim]
        if d > dim:
            rigid[:, dim + k, dim + k] = 1.0
    modes = np.zeros((n, d, m))
    modes[:, :dim] = modal.phi_t
    if d > dim:
        modes[:, dim:] = np.reshape(modal.phi_r, (n, c, m))
    return np.hstack([rigid.reshape(n * d, dim + c), modes.reshape(n * d, m)])


def _body_mass(modal: ModalData, flexible_mass: str) -> np.ndarray:
    """M(A = 1, η = 0) of casmbd's floating-frame body."""
    body = FlexibleBody(invariants(modal, flexible_mass=flexible_mass))
    zero = ca.DM.zeros(modal.n_modes)
    return np.array(ca.evalf(body.mass_matrix(ca.DM.eye(modal.dimension), zero)))


CASES = {
    "plane beam, Craig–Bampton root+tip": (lambda: _beam(2), "craig_bampton", ["root", "tip"]),
    "space beam, Craig–Bampton root+tip": (lambda: _beam(3), "craig_bampton", ["root", "tip"]),
    "plane beam, free modes": (lambda: _beam(2), "free", []),
    "plane truss (translations only), Craig–Bampton A+B": (lambda: _truss(2), "craig_bampton",
                                                           ["A", "B"]),
    "space truss (translations only), Craig–Bampton A+C+B": (lambda: _truss(3),
                                                             "craig_bampton", ["A", "C", "B"]),
    "space truss, free modes": (lambda: _truss(3), "free", []),
}


@pytest.mark.parametrize("case", list(CASES))
def test_body_mass_is_the_gram_matrix_of_the_fe_mass(case):
    """M(1, 0) with "reduced" equals [T_r R_r Φ]ᵀ M [T_r R_r Φ] from the FE matrices (measured
    ≤ 3e-15 relative; bound 1e-12) and is positive definite; "lumped" stays the lumped Gram
    matrix (positive semi-definite).  Plane and space, beams with rotational dofs and trusses
    with translations only, both reductions (4 modes)."""
    make, reduction, interfaces = CASES[case]
    fe = make()
    modal = reduce(fe, reduction, 4, interfaces)
    basis = _full_basis(fe, modal)
    gram = basis.T @ (fe.mass_matrix @ basis)
    body = _body_mass(modal, "reduced")
    assert np.max(np.abs(body - gram)) <= 1e-12 * np.max(np.abs(gram))
    assert np.max(np.abs(body - body.T)) <= 1e-14 * np.max(np.abs(gram))
    scale = 1.0 / np.sqrt(np.diag(body))
    assert np.linalg.eigvalsh(body * np.outer(scale, scale))[0] > 1e-9
    lumped = _body_mass(modal, "lumped")
    assert np.linalg.eigvalsh(lumped)[0] >= -1e-12 * np.max(np.abs(lumped))


def test_the_old_mixture_was_indefinite():
    """Why "reduced" failed with two interfaces: the lumped rigid and coupling blocks with the
    consistent M_ff = Φᵀ M Φ are no Gram matrix; for the 8-element beam with interfaces at
    both ends the smallest eigenvalue is −0.28 (16 elements: −0.018) — the tip's lateral
    constraint mode is nearly a rotation about the root, whose lumped and consistent inertias
    differ.  The consistent matrix's smallest is +7.8e-5 (a near-rigid mode, resolved)."""
    fe = _beam(2)
    modal = reduce(fe, "craig_bampton", 4, ["root", "tip"])
    mixed = _body_mass(modal, "lumped")
    n = modal.n_modes
    mixed[-n:, -n:] = modal.mass
    assert np.linalg.eigvalsh(mixed)[0] < -0.1
    assert np.linalg.eigvalsh(_body_mass(modal, "reduced"))[0] > 5e-5


def _lagrange(T, q, v):
    M = ca.hessian(T, v)[0]
    return M, ca.jacobian(T, q).T - ca.jtimes(ca.mtimes(M, v), q, v)


def _euler_xyz(phi):
    c, s = ca.cos(phi), ca.sin(phi)
    rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c[0], -s[0]), ca.horzcat(0, s[0], c[0]))
    ry = ca.vertcat(ca.horzcat(c[1], 0, s[1]), ca.horzcat(0, 1, 0), ca.horzcat(-s[1], 0, c[1]))
    rz = ca.vertcat(ca.horzcat(c[2], -s[2], 0), ca.horzcat(s[2], c[2], 0), ca.horzcat(0, 0, 1))
    return ca.mtimes([rx, ry, rz])


@pytest.mark.parametrize("dim", [2, 3])
def test_quadratic_velocity_forces_are_lagrange_of_the_reduced_mass(dim):
    """With the consistent constants (and the lumped η-dependent invariants) Q_v is still the
    exact Lagrange form of T = ½ wᵀ M(A, η) w: Bᵀ (Q_v − M Ḃ q̇) = ∂T/∂q − Ṁ q̇ by AD, with
    q = (R, θ, η) in the plane and (R, Euler x-y-z angles, η) in space (measured 2e-15
    relative; bound 1e-11)."""
    modal = reduce(_beam(dim), "craig_bampton", 3, ["root", "tip"])
    body = FlexibleBody(invariants(modal, flexible_mass="reduced"))
    n, c = modal.n_modes, 1 if dim == 2 else 3
    q, v = ca.SX.sym("q", dim + c + n), ca.SX.sym("v", dim + c + n)
    eta, etad = q[dim + c:], v[dim + c:]
    if dim == 2:
        A, omega = planar_rotation(q[2]), v[2]
    else:
        A = _euler_xyz(q[3:6])
        wt = ca.mtimes(A.T, ca.reshape(ca.jtimes(ca.vec(A), q, v), 3, 3))
        omega = ca.vertcat(wt[2, 1], wt[0, 2], wt[1, 0])
    _, Q_q = _lagrange(body.kinetic_energy(A, eta, v[:dim], omega, etad), q, v)
    w = ca.vertcat(v[:dim], omega, etad)
    B = ca.jacobian(w, v)
    M_w = body.mass_matrix(A, eta)
    Q_f = ca.mtimes(B.T, body.quadratic_velocity_forces(A, eta, omega, etad)
                    - ca.mtimes(M_w, ca.jtimes(w, q, v)))
    f = ca.Function("f", [q, v], [Q_q, Q_f])
    rng = np.random.default_rng(35)
    for _ in range(4):
        qn = np.concatenate([rng.normal(size=dim + c), 0.05 * rng.normal(size=n)])
        vn = rng.normal(size=dim + c + n)
        q_ad, q_f = (np.array(x).ravel() for x in f(qn, vn))
        assert np.max(np.abs(q_f - q_ad)) <= 1e-11 * np.max(np.abs(q_ad))


# ---------------------------------------------------------------- pinned–pinned beam
def _pinned_pinned(elements: int, mass: str, coordinates: str = "auto",
                   modes: int = 6) -> casmbd.Mechanism:
    """Kane's beam (L = 10 m, EI = 1.4e4 N m², ρA = 1.2 kg/m) pinned at the root to the ground
    and at the tip to a light slider (0.01 kg) on the x axis (no axial restraint);
    Craig–Bampton with interfaces at both pins, 6 fixed-interface modes; gravity G."""
    return casmbd.loads_scene(f"""
[scene]
name = "pinned_pinned"
dimension = 2
gravity = [0.0, {-G}]
coordinates = "{coordinates}"
[[bodies]]
name = "beam"
type = "flexible"
position = [0.0, 0.0]
modes = {modes}
reduction = "craig_bampton"
interfaces = ["root", "tip"]
flexible_mass = "{mass}"
[bodies.beam]
length = {L}
elements = {elements}
EI = {EI}
EA = {EA}
rhoA = {RHOA}
nodes = {{ root = 0.0, mid = {L / 2}, tip = {L} }}
[[bodies]]
name = "slider"
mass = 0.01
inertia = 1e-4
position = [{L}, 0.0]
[[joints]]
name = "pin1"
type = "revolute"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0]
[[joints]]
name = "pin2"
type = "revolute"
body1 = "beam"
node1 = "tip"
body2 = "slider"
point = [{L}, 0.0]
[[joints]]
name = "roller"
type = "prismatic"
body1 = "ground"
body2 = "slider"
point = [{L}, 0.0]
axis = [1.0, 0.0]
""")


def _omega(n: int) -> float:
    return (n * np.pi) ** 2 * np.sqrt(EI / (RHOA * L**4))


def _mid_span(t: np.ndarray) -> np.ndarray:
    """w(L/2, t) of the beam released from rest under q = ρA G (module docstring), 200 terms."""
    q = RHOA * G
    return -sum(4 * q * L**4 / (EI * (n * np.pi) ** 5) * np.sin(n * np.pi / 2)
                * (1 - np.cos(_omega(n) * t)) for n in range(1, 400, 2))


def test_pinned_pinned_frequencies_reduced_against_closed_form():
    """First three bending frequencies from ``linearize`` against βL = π, 2π, 3π.  "reduced"
    (consistent mass, Ritz: from above) 1.7e-5, 2.6e-4, 1.4e-3 at 8 elements and 1.2e-6,
    2.1e-5, 2.3e-4 at 16 (O(h⁴)); "lumped" −6.4e-3, −2.5e-2, −5.4e-2 and −1.6e-3, −6.4e-3,
    −1.4e-2 (O(h²)).  Natural frame coordinates give the same frequencies (measured 7e-13;
    bound 1e-9)."""
    exact = np.array([_omega(n) for n in (1, 2, 3)]) / (2 * np.pi)
    err = {}
    for elements in (8, 16):
        for mass in ("reduced", "lumped"):
            lin = casmbd.linearize(_pinned_pinned(elements, mass), mode="vm")
            err[elements, mass] = (lin.frequencies_hz[:3] - exact) / exact
    assert np.all(err[8, "reduced"] > 0) and np.all(err[16, "reduced"] > 0)
    assert np.all(err[8, "reduced"] <= [4e-5, 6e-4, 3e-3]), err[8, "reduced"]
    assert np.all(err[16, "reduced"] <= [3e-6, 5e-5, 5e-4]), err[16, "reduced"]
    for elements in (8, 16):
        assert np.all(np.abs(err[elements, "reduced"]) < np.abs(err[elements, "lumped"]) / 10)
    assert np.all(np.abs(err[8, "lumped"]) / np.abs(err[16, "lumped"]) > 3.5)  # O(h²)
    natural = casmbd.linearize(_pinned_pinned(8, "reduced", "natural"), mode="vm")
    assert natural.frequencies_hz[:3] == pytest.approx(exact * (1 + err[8, "reduced"]),
                                                       rel=1e-9)


def test_pinned_pinned_beam_simulates_with_reduced_mass():
    """The beam (8 elements) released from rest under its weight (interfaces at both pins),
    0.3 s (to the first peak): mid-span deflection against the modal series (peak 2.19e-3 m).
    "reduced": max error 4.3e-7 m (modal truncation and the integrator at rtol 1e-7; 1.6e-7 m
    at 16 elements); "lumped": 3.8e-5 m, its O(h²) lumping error (9.8e-6 m at 16 elements).
    Statics with all 21 interior modes (no truncation): "reduced" gives 5 q L⁴/(384 EI) to
    2.4e-7 relative (the consistent gravity load S1ᵀ g makes the Hermite beam nodally exact;
    6 modes: 4.6e-5, truncation), "lumped" −1.25 %."""
    errors = {}
    for mass in ("reduced", "lumped"):
        res = casmbd.simulate(_pinned_pinned(8, mass), 0.3, 15, mode="vm", rtol=1e-7)
        mid = res.node("beam@mid")["position"][:, 1]
        errors[mass] = np.max(np.abs(mid - _mid_span(res.t)))
    assert errors["reduced"] <= 1e-6, errors
    assert 2.5e-5 <= errors["lumped"] <= 6e-5, errors
    exact = -5 * RHOA * G * L**4 / (384 * EI)
    for mass, bound in (("reduced", (-2e-6, 2e-6)), ("lumped", (-0.015, -0.01))):
        stat = casmbd.static_equilibrium(_pinned_pinned(8, mass, modes=21), mode="vm")
        sag = stat.marker_positions[stat.names["markers"].index("beam@mid")][1]
        assert bound[0] <= sag / exact - 1 <= bound[1], (mass, sag / exact - 1)


def _chord_deflection(res) -> np.ndarray:
    """Distance of the rod's mid node from the chord A–B (signed, m)."""
    return chord_deflection(*(res.node(f"rod@{k}")["position"] for k in ("A", "B", "mid")))


def test_flexible_slider_crank_runs_with_reduced_mass():
    """examples/flexible_slider_crank.toml (crank 150 rad/s, steel rod 0.3 m, Craig–Bampton
    with interfaces at both pins A and B), one crank turn: refused before ("mass matrix is
    singular"), it now runs with "reduced".  Peak mid-span deflection: "reduced" 2.3132 mm
    (8 elements) and 2.3125 mm (16): converged to 3e-4; "lumped" 2.2727 mm and 2.3041 mm,
    approaching it as h².  The two mass models differ at most by 1.09e-4 m (8 elements) and
    2.7e-5 m (16): 4.1x per halving, the O(h²) lumping difference."""
    text = (ROOT / "examples" / "flexible_slider_crank.toml").read_text()
    curves = {}
    for elements in (8, 16):
        for mass in ("reduced", "lumped"):
            scene = text.replace("stiffening = false", f'flexible_mass = "{mass}"').replace(
                "elements = 8", f"elements = {elements}")
            res = casmbd.simulate(casmbd.loads_scene(scene), 2 * np.pi / 150, 42, mode="vm",
                                  rtol=1e-8)
            curves[elements, mass] = _chord_deflection(res)
    peak = {k: np.max(np.abs(v)) for k, v in curves.items()}
    assert abs(peak[8, "reduced"] / peak[16, "reduced"] - 1) <= 1e-3, peak
    assert 0.005 <= 1 - peak[8, "lumped"] / peak[16, "reduced"] <= 0.03, peak
    assert 0.0015 <= 1 - peak[16, "lumped"] / peak[16, "reduced"] <= 0.008, peak
    diff = {e: np.max(np.abs(curves[e, "reduced"] - curves[e, "lumped"])) for e in (8, 16)}
    assert diff[8] <= 2e-4 and 3.0 <= diff[8] / diff[16] <= 5.0, diff


# ---------------------------------------------------------------- messages
def test_indefinite_flexible_data_is_refused_with_its_cause():
    """Hand-made modal data whose flexible mass does not match the rigid data (M_ff / 100):
    the body's mass matrix at η = 0 is indefinite, and ``invariants`` says so, naming the body
    — not "singular"; "reduced" without the FE rigid-body data is refused naming the field."""
    modal = reduce(_beam(2), "craig_bampton", 4, ["root", "tip"])
    bad = ModalData(**{**modal.__dict__, "mass": 0.01 * modal.mass})
    with pytest.raises(ModelError, match=r"flexible body 'rod': the body mass matrix at zero "
                                         r"deformation is indefinite \(smallest eigenvalue -"):
        invariants(bad, flexible_mass="reduced", name="rod")
    bare = ModalData(**{**modal.__dict__, "rigid_coupling": None})
    with pytest.raises(ModelError, match="flexible body 'rod' field 'flexible_mass': 'reduced' "
                                         "needs the FE mass matrix's rigid-body data"):
        invariants(bare, flexible_mass="reduced", name="rod")


class _NegativeInertia:
    """A compiled model whose mass matrix has −1 kg m² on one coordinate's diagonal."""

    def __init__(self, model, coordinate: str):
        self._model, self._k = model, list(model.coordinate_names).index(coordinate)

    def __getattr__(self, name):
        return getattr(self._model, name)

    def mass_matrix(self, q):
        m = self._model.mass_matrix(q)
        m = np.array(m.todense() if sp.issparse(m) else m, float)
        m[self._k, self._k] = -1.0
        return m


def test_mass_matrix_check_says_singular_or_indefinite():
    """check_mass_matrix (start of every forward-dynamics run): a massless end link gives
    "singular … has no inertia" naming it; a negative inertia on the same link's angle gives
    "indefinite … negative kinetic energy" naming it (smallest eigenvalue −1.06 of the
    projected matrix) — two defects, two messages."""
    model = compile_model(chain("absolute", end_massless=True), "info", mode="vm")
    q = model.initial_coordinates()
    with pytest.raises(ModelError, match=r"mass matrix is singular on the constraint manifold "
                                         r".*body 'C' \(mass 0.0, inertia 0.0\) has no inertia"):
        check_mass_matrix(model, q, 0.0)
    model = compile_model(chain("absolute"), "info", mode="vm")
    check_mass_matrix(model, q, 0.0)  # the chain with masses passes
    with pytest.raises(ModelError, match=r"mass matrix is indefinite on the constraint manifold "
                                         r"\(smallest eigenvalue -.*body 'C' .*negative kinetic "
                                         r"energy. Not a massless body"):
        check_mass_matrix(_NegativeInertia(model, "C.angle"), q, 0.0)


def test_per_call_path_says_singular_or_indefinite():
    """The compiled per-call API (joint coordinates): forward dynamics of a massless end link
    raises SingularMassMatrixError "singular … has no inertia"; the same diagnosis on a mass
    matrix with a negative diagonal entry says "indefinite … negative kinetic energy", naming
    the coordinate and body."""
    model = casmbd.compile(chain("joint", end_massless=True), mode="vm")
    zero = np.zeros(model.nq)
    with pytest.raises(SingularMassMatrixError, match=r"singular at this q.*'pin2.angle' "
                                                      r"\(body 'C'.*has no inertia"):
        model.forward_dynamics(zero, zero, zero)
    load = model._load

    def negative(buf, what, q):
        load(buf, what, q)
        if buf is model._m:
            buf.view[2, 2] = -1.0

    model._load = negative
    with pytest.raises(SingularMassMatrixError, match=r"indefinite at this q \(smallest "
                                                      r"eigenvalue -.*'pin2.angle' \(body 'C'.*"
                                                      r"negative kinetic energy") as err:
        model._singular(zero, "forward_dynamics")
    assert err.value.coordinates == ["pin2.angle"] and err.value.bodies == ["C"]


@pytest.mark.parametrize("dim", [2, 3])
def test_free_fall_with_reduced_mass(dim):
    """A free beam (6 elements, Craig–Bampton root+tip, "reduced", tilted frame) under gravity:
    the consistent gravity load S1ᵀ g meets the consistent inertia, so every dof accelerates
    with g and η stays 0: at the start |η̈| and |r̈_G − g| ≤ 1e-10 g, over 0.05 s at rtol 1e-10
    |η| ≤ 1e-10 (measured 4.8e-12 in space; the static deflection under g, clamped, is
    ~1 m)."""
    g = np.array([0.0, -9.81]) if dim == 2 else np.array([0.0, 3.0, -9.81])
    gn = float(np.linalg.norm(g))
    zero = "[0.0, 0.0]" if dim == 2 else "[0.0, 0.0, 0.0]"
    pose = "angle = 0.4" if dim == 2 else "euler_zxz = [0.3, 0.5, 0.2]"
    props = f"EI = {EI}" if dim == 2 else f"EIy = {EI}\nEIz = {2 * EI}\nGJ = 1.0e4\nrhoIp = 0.01"
    scene = f"""
[scene]
name = "free_fall"
dimension = {dim}
gravity = {[float(x) for x in g]}
[[bodies]]
name = "beam"
type = "flexible"
position = {zero}
{pose}
modes = 3
reduction = "craig_bampton"
interfaces = ["root", "tip"]
flexible_mass = "reduced"
[bodies.beam]
length = {L}
elements = 6
{props}
EA = {EA}
rhoA = {RHOA}
nodes = {{ root = 0.0, tip = {L} }}
"""
    res = casmbd.simulate(casmbd.loads_scene(scene), 0.05, 2, rtol=1e-10, mode="vm")
    frame = 3 if dim == 2 else 7
    assert np.max(np.abs(res.arrays["a"][0, frame:])) <= 1e-10 * gn
    assert np.max(np.abs(res.body("beam")["acceleration"][0] - g)) <= 1e-10 * gn
    assert np.max(np.abs(res.arrays["q"][:, frame:])) <= 1e-10
