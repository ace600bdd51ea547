"""Static equilibrium: torsional-spring pendulum against brentq, stability, failures, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import private_cache
from scipy.optimize import brentq

import casmbd
from casmbd.analysis.statics.statics import static_equilibrium
from casmbd.cli import main
from casmbd.errors import AnalysisError
from casmbd.io.scene import load_scene

G = 9.81
CHAIN = "examples/hanging_chain.toml"


_cache = private_cache()


def pendulum(k: float = 0.0, up: bool | None = None) -> casmbd.Mechanism:
    """Rod L = 1 m, m = 1 kg pinned at the origin; horizontal, hanging (up=False) or inverted."""
    m = casmbd.Mechanism("p", gravity=(0, -G))
    if up is None:
        m.add_body("rod", 1.0, 1 / 12, (0.5, 0.0))
    else:
        s = 1.0 if up else -1.0
        m.add_body("rod", 1.0, 1 / 12, (0.0, 0.5 * s), angle=s * np.pi / 2)
    m.add_revolute("pivot", "ground", "rod", (0, 0))
    if k:
        m.add_rotational_spring_damper("spring", "pivot", stiffness=k)
    return m


#: the metric of the unit tangent of the pendulum's constraint manifold: absolute coordinates
#: (x, y, θ) have the tangent (−(L/2) sin θ, (L/2) cos θ, 1) / √(1 + (L/2)²); the automatic
#: choice takes the joint angle θ alone (a tree), whose unit tangent is 1
METRIC = {"absolute": 1 + 0.5 ** 2, "natural": 1 + 0.5 ** 2, "auto": 1.0}


def coordinate_checks(r, coordinates: str, n_bodies: int = 1) -> None:
    """q is (x, y, θ) per body in absolute coordinates, the joint angles under "auto"."""
    if coordinates == "absolute":
        assert len(r.q) == 3 * n_bodies
        assert np.allclose(r.q.reshape(-1, 3)[:, :2], r.body_positions, atol=1e-14)
        assert np.allclose(r.q.reshape(-1, 3)[:, 2], r.body_angles, atol=1e-14)
    else:
        assert len(r.q) == n_bodies and r.names["coordinates"][0].endswith(".angle")
        assert len(r.lagrange_multipliers) == 0  # a tree: no constraint equation


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
@pytest.mark.parametrize("method", ["augmented", "reduced"])
@pytest.mark.parametrize("k", [2.0, 10.0, 100.0])
def test_torsional_spring_pendulum(method, k, coordinates):
    """θ counter-clockwise from +x, gravity −y: V = m g (L/2) sin θ + ½ k θ², so V'(θ) = 0 gives
    k θ = −m g (L/2) cos θ (the spring moment −kθ balances the gravity moment −m g (L/2) cos θ).
    For k > m g L/2 the root in (−π/2, 0) is unique."""
    mass, length = 1.0, 1.0
    ref = brentq(lambda th: k * th + mass * G * length / 2 * np.cos(th), -np.pi / 2, 0.0,
                 xtol=1e-15, rtol=4 * np.finfo(float).eps)
    mech = pendulum(k)
    mech.coordinates = coordinates
    r = static_equilibrium(mech, method=method, mode="vm")
    assert r.method == method
    coordinate_checks(r, coordinates)
    assert abs(r.body_angles[0] - ref) < 1e-12
    assert np.allclose(r.body_positions[0], 0.5 * np.array([np.cos(ref), np.sin(ref)]),
                       atol=1e-12)
    assert r.residual < 1e-10 and r.iterations <= 20
    # reaction: the pin carries the weight and no moment (the spring is a force element)
    assert np.allclose(r.joint_reactions[0], [0.0, mass * G, 0.0], atol=1e-9)
    assert r.stable is True
    # V''(θ) = k − m g (L/2) sin θ > 0 over the metric of the unit tangent, K̄ = V''(θ) / METRIC
    expected = (k - mass * G * length / 2 * np.sin(ref)) / METRIC[coordinates]
    assert r.eigenvalues == pytest.approx([expected], rel=1e-9)


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
@pytest.mark.parametrize("method", ["augmented", "reduced"])
def test_hanging_stable_inverted_unstable(method, coordinates):
    results = []
    for up in (False, True):
        mech = pendulum(up=up)
        mech.coordinates = coordinates
        results.append(static_equilibrium(mech, method=method, mode="vm"))
    down, up = results
    for r, sign in ((down, -1.0), (up, 1.0)):
        assert r.residual < 1e-10
        coordinate_checks(r, coordinates)
        assert np.allclose(r.body_positions[0], [0.0, 0.5 * sign], atol=1e-12)
        assert np.allclose(r.joint_reactions[0], [0.0, G, 0.0], atol=1e-9)
        assert r.iterations <= 1  # the initial pose is already the equilibrium
    # V''(θ) = ∓ m g L/2 over the metric of the unit tangent
    metric = METRIC[coordinates]
    assert down.stable is True and down.eigenvalues[0] == pytest.approx(G / 2 / metric)
    assert up.stable is False and up.eigenvalues[0] == pytest.approx(-G / 2 / metric)


@pytest.mark.parametrize("method", ["augmented", "reduced"])
def test_free_body_has_no_equilibrium(method):
    m = casmbd.Mechanism("free", gravity=(0, -G))
    m.add_body("b", 1.0, 0.1, (0.0, 0.0))
    with pytest.raises(AnalysisError) as exc:
        static_equilibrium(m, method=method, max_iter=10, mode="vm")
    msg = str(exc.value)
    assert "residual" in msg and "b.y" in msg and "iterations" in msg


@pytest.mark.parametrize("method", ["augmented", "reduced"])
def test_double_pendulum_from_horizontal(method):
    """Released horizontally the stiffness is singular (Newton alone stalls); the descent step
    moves it off, and Newton then converges to an equilibrium with both rods vertical."""
    r = static_equilibrium(load_scene("examples/double_pendulum.toml"), method=method,
                           mode="vm")
    assert r.residual < 1e-9
    assert np.allclose(np.cos(r.body_angles), 0.0, atol=1e-9)
    assert r.joint_reactions[0, 1] == pytest.approx(2 * G, abs=1e-9)
    y1, y2 = r.body_positions[:, 1]
    assert r.stable is bool(y1 < 0 and y2 < y1)  # stable only hanging down


def test_unknown_method():
    with pytest.raises(AnalysisError, match="unknown statics method"):
        static_equilibrium(pendulum(5.0), method="bogus", mode="vm")


@pytest.mark.parametrize("method", ["augmented", "reduced"])
def test_hanging_chain(method):
    mech = load_scene(CHAIN)
    r = static_equilibrium(mech, method=method, mode="auto")
    assert r.residual < 1e-9 and r.stable is True
    assert len(r.eigenvalues) == 1 and r.eigenvalues[0] > 0
    total = sum(float(b.mass) for b in mech.bodies.values())
    # vertical force of the ground on the chain (reaction = action of body1 on body2)
    lift = 0.0
    for k, joint in enumerate(mech.joints.values()):
        if joint.body1 == "ground":
            lift += r.joint_reactions[k, 1]
        elif joint.body2 == "ground":
            lift -= r.joint_reactions[k, 1]
    assert lift == pytest.approx(total * G, abs=1e-9)
    # both methods find the same equilibrium
    other = static_equilibrium(mech, method="reduced" if method == "augmented" else "augmented",
                               mode="vm")
    assert np.allclose(r.q, other.q, atol=1e-10)


def test_cli_statics_json(capsys, tmp_path):
    """The multipliers are those of the chosen coordinates' equations: under the automatic
    choice the chain is a tree of three rods closed by knee_2 (2 equations on 3 joint
    angles); pinned to absolute coordinates, 4 revolute joints give 8 equations."""
    assert main(["statics", CHAIN, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    for key in ("bodies", "joints", "lagrange_multipliers", "stable", "iterations", "residual",
                "eigenvalues", "method", "stats"):
        assert key in data
    assert data["stable"] is True and data["method"] == "augmented"
    assert set(data["bodies"]) == {"rod1", "rod2", "rod3"}
    assert set(data["bodies"]["rod1"]) == {"position", "angle"}
    assert set(data["joints"]) == {"anchor_a", "knee_1", "knee_2", "anchor_b"}
    assert {"coordinate", "reaction"} <= set(data["joints"]["anchor_a"])
    assert len(data["joints"]["anchor_a"]["reaction"]) == 3
    assert len(data["lagrange_multipliers"]) == 2
    assert data["stats"]["coordinates"] == "joint"
    assert data["stats"]["coordinate_reason"] == ("1 loop joint (knee_2) with 2 equations on 3 "
                                                  "tree coordinates")
    pinned = tmp_path / "chain_absolute.toml"
    text = open(CHAIN).read()
    pinned.write_text(text.replace("[scene]\n", '[scene]\ncoordinates = "absolute"\n', 1))
    assert main(["statics", str(pinned), "--json", "--mode", "vm"]) == 0
    absolute = json.loads(capsys.readouterr().out)
    assert len(absolute["lagrange_multipliers"]) == 8
    assert absolute["stats"]["coordinate_reason"] == "given"
    for body in ("rod1", "rod2", "rod3"):
        assert np.allclose(absolute["bodies"][body]["position"],
                           data["bodies"][body]["position"], atol=1e-9)
    assert main(["statics", CHAIN, "--method", "reduced"]) == 0
    assert "stable" in capsys.readouterr().out


def test_cli_statics_error(tmp_path, capsys):
    scene = tmp_path / "free.toml"
    scene.write_text('[scene]\nname = "free"\ndimension = 2\ngravity = [0.0, -9.81]\n\n'
                     '[[bodies]]\nname = "b"\nmass = 1.0\ninertia = 0.1\nposition = [0.0, 0.0]\n')
    assert main(["statics", str(scene), "--mode", "vm"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "residual" in err[0]


def test_five_hinged_arch_is_the_unstable_mirror_of_the_hanging_chain():
    """Seed 003 §5.3: the hanging four-rod chain is a stable equilibrium; mirrored upwards it
    is still an equilibrium (the arch) and unstable, with a real positive eigenvalue."""
    import sys

    sys.path.insert(0, "examples")
    from five_hinged_arch import study

    out = study()
    assert out["hanging"].stable is True
    assert out["arch"].stable is False
    mirrored = out["hanging_points"] * np.array([1.0, -1.0])
    assert np.max(np.abs(out["arch_points"] - mirrored)) <= 1e-9
    growth = max(e.real for e in out["arch_linear"].eigenvalues)
    assert growth > 1.0


# --- issue 30, item 4f: the equilibrium nearest the start, stable or not ------------------

ARCH = "examples/five_hinged_arch.toml"
ARCH_SPAN = 2.5


def tilted_pendulum(offset: float, coordinates: str) -> casmbd.Mechanism:
    """The rod of :func:`pendulum` at θ = π/2 + ``offset`` (``offset`` rad from upright)."""
    th = np.pi / 2 + offset
    m = casmbd.Mechanism(f"tilted_{coordinates}", gravity=(0, -G), coordinates=coordinates)
    m.add_body("rod", 1.0, 1 / 12, (0.5 * np.cos(th), 0.5 * np.sin(th)), angle=th)
    m.add_revolute("pivot", "ground", "rod", (0, 0))
    return m


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "auto"])
@pytest.mark.parametrize("method", ["augmented", "reduced"])
def test_inverted_pendulum_near_upright_stays_upright(method, coordinates):
    """Started 0.04 rad from upright the nearest equilibrium is upright (θ = π/2 to 1e-10),
    classified unstable with K̄ = −m g (L/2) over the tangent metric (1e-9); before issue 30
    the potential-descending search returned the hanging pose.  ``stable=True`` asks for a
    stable one: hanging (θ = −π/2 to 1e-10), K̄ = +m g (L/2) / metric."""
    mech = tilted_pendulum(0.04, coordinates)
    up = static_equilibrium(mech, method=method, mode="vm")
    assert abs(up.body_angles[0] - np.pi / 2) < 1e-10
    assert np.allclose(up.body_positions[0], [0.0, 0.5], atol=1e-10)
    assert up.search == "nearest" and up.notes == []
    assert up.stability.verdict == "unstable" and up.stable is False
    metric = METRIC[coordinates]
    assert up.eigenvalues == pytest.approx([-G / 2 / metric], rel=1e-9)
    assert np.allclose(up.joint_reactions[0], [0.0, G, 0.0], atol=1e-9)
    assert up.residual < 1e-10 and up.iterations <= 6
    down = static_equilibrium(mech, method=method, mode="vm", stable=True)
    assert abs(down.body_angles[0] + np.pi / 2) < 1e-10
    assert down.search == "stable" and down.stability.verdict == "stable"
    assert down.eigenvalues == pytest.approx([G / 2 / metric], rel=1e-9)


@pytest.mark.parametrize("method", ["augmented", "reduced"])
def test_stable_search_leaves_an_exactly_upright_start(method):
    """Placed exactly upright (an equilibrium) the default stays (unstable); ``stable=True``
    leaves it along the downhill eigenvector and descends to the hanging pose (1e-10),
    saying so in ``notes``."""
    mech = pendulum(up=True)
    assert static_equilibrium(mech, method=method, mode="vm").stability.verdict == "unstable"
    r = static_equilibrium(mech, method=method, mode="vm", stable=True)
    assert abs(r.body_angles[0] + np.pi / 2) < 1e-10 and r.stable is True
    assert r.notes == ["left 1 unstable equilibrium along the downhill eigenvector of the "
                       "reduced stiffness"]


def arch_angles(mass_ratio: float = 1.0) -> tuple[float, float]:
    """The arch of unit rods between pivots ARCH_SPAN apart, outer rods of mass m_o, inner
    ones m_i = ``mass_ratio`` · m_o: with H the horizontal thrust, moments about the near
    hinge of an inner rod (no shear at the apex, by symmetry) and about a ground pivot of the
    two rods of one side give tan θ_i = m_i g / (2H) and tan θ_o = (m_o + 2 m_i) g / (2H), and
    the span closes with cos θ_o + cos θ_i = span / 2.  Returns (θ_o, θ_i), the rise of the
    outer and inner rods (tan θ_o = 3 tan θ_i for equal rods)."""
    ratio = (1.0 + 2.0 * mass_ratio) / mass_ratio
    inner = brentq(lambda x: np.cos(np.arctan(ratio * np.tan(x))) + np.cos(x) - ARCH_SPAN / 2,
                   1e-6, np.pi / 2 - 1e-6, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return float(np.arctan(ratio * np.tan(inner))), float(inner)


def arch_variant(coordinates: str | None = None, rise: float | None = None):
    text = open(ARCH, encoding="utf-8").read()
    if rise is not None:
        text = text.replace("alpha = 1.0471975511965976", f"alpha = {rise!r}", 1)
    mech = casmbd.loads_scene(text)
    if coordinates:
        mech.coordinates = coordinates
    return mech


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "auto"])
@pytest.mark.parametrize("method", ["augmented", "reduced"])
def test_seed003_arch_stays_an_arch(method, coordinates):
    """Seed 003 §5.3, started from the symmetric polygon rising at π/3 (0.08 rad off): the
    arch, rod angles (θ_o, θ_i, −θ_i, −θ_o) of :func:`arch_angles` to 1e-10, unstable in both
    directions; the horizontal thrust at A is m g / (2 tan θ_i) (1e-9).  ``stable=True``
    descends to the hanging chain, its mirror image (angles negated, 1e-10), whose stiffness
    eigenvalues are the arch's negated (V changes sign under the mirror, 1e-9).  Before
    issue 30 the default returned the hanging chain."""
    outer, inner = arch_angles()
    mech = arch_variant(coordinates)
    arch = static_equilibrium(mech, method=method, mode="vm")
    expected = np.array([outer, inner, -inner, -outer])
    assert np.max(np.abs(arch.body_angles - expected)) < 1e-10
    assert arch.stability.verdict == "unstable" and arch.search == "nearest"
    assert np.all(arch.eigenvalues < -arch.stability.tolerance)
    thrust = G / (2 * np.tan(inner))
    assert arch.joint_reactions[0, :2] == pytest.approx([thrust, 2 * G], rel=1e-9)
    hanging = static_equilibrium(mech, method=method, mode="vm", stable=True)
    assert np.max(np.abs(hanging.body_angles + expected)) < 1e-10
    assert hanging.stability.verdict == "stable"
    assert np.sort(-hanging.eigenvalues) == pytest.approx(np.sort(arch.eigenvalues), rel=1e-9)


def lopsided_arch(left: float, right: float) -> casmbd.Mechanism:
    """The arch's four unit rods through a consistent asymmetric polygon: the outer rods rise
    at ``left`` and ``right``, the apex hinge where the unit circles about their upper ends
    meet (the upper intersection)."""
    import sys

    sys.path.insert(0, "examples")
    from five_hinged_arch import chain

    p1 = np.array([np.cos(left), np.sin(left)])
    p3 = np.array([ARCH_SPAN - np.cos(right), np.sin(right)])
    mid, d = 0.5 * (p1 + p3), p3 - p1
    h = np.sqrt(1.0 - 0.25 * d @ d)
    p2 = mid + h * np.array([-d[1], d[0]]) / np.linalg.norm(d)
    return chain(np.array([[0.0, 0.0], p1, p2, p3, [ARCH_SPAN, 0.0]]), "lopsided_arch")


@pytest.mark.parametrize("left,right", [(0.75, 0.75), (0.9, 0.9), (1.25, 1.25), (1.0, 1.2),
                                        (0.8, 1.1)])
def test_arch_from_farther_and_lopsided_starts(left, right):
    """From symmetric starts up to 0.38 rad off and from lopsided ones (outer rods rising at
    different angles) the default search finds the arch (1e-10), unstable."""
    outer, inner = arch_angles()
    expected = np.array([outer, inner, -inner, -outer])
    if left == right:
        mech = arch_variant(rise=left)
    else:
        mech = lopsided_arch(left, right)
    r = static_equilibrium(mech, mode="vm")
    assert np.max(np.abs(r.body_angles - expected)) < 1e-10 and r.stable is False


def test_statics_sweep_nearest_and_stable():
    """A statics sweep over the inner rods' mass takes ``stable`` like
    ``static_equilibrium``: the arches (closed form per mass ratio, 1e-10) by default, the
    hanging chains (angles negated) with ``stable=True``."""
    from casmbd.analysis.studies.sweep import sweep

    masses = [0.5, 1.0, 2.0]
    expected = np.array([arch_angles(m) for m in masses])
    for stable, sign in ((False, 1.0), (True, -1.0)):
        res = sweep(casmbd.load_scene(ARCH), {"m_inner": masses}, analysis="statics",
                    outputs=["final:body.rod0.angle", "final:body.rod1.angle"], mode="vm",
                    stable=stable)
        assert res.failed == [], res.errors
        np.testing.assert_allclose(res["final:body.rod0.angle"], sign * expected[:, 0],
                                   rtol=0, atol=1e-10)
        np.testing.assert_allclose(res["final:body.rod1.angle"], sign * expected[:, 1],
                                   rtol=0, atol=1e-10)


def test_cli_statics_nearest_and_stable(capsys):
    """`casmbd statics` on the arch scene: the arch (nearest, unstable) in the JSON and the
    text; `--stable`: the hanging chain (stable), the search named in both."""
    outer, inner = arch_angles()
    assert main(["statics", ARCH, "--json", "--mode", "vm"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["search"] == "nearest" and data["notes"] == []
    assert data["stable"] is False and data["stability"]["verdict"] == "unstable"
    assert data["bodies"]["rod0"]["angle"] == pytest.approx(outer, abs=1e-10)
    assert data["bodies"]["rod2"]["angle"] == pytest.approx(-inner, abs=1e-10)
    assert main(["statics", ARCH, "--json", "--mode", "vm", "--stable"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["search"] == "stable" and data["stable"] is True
    assert data["bodies"]["rod0"]["angle"] == pytest.approx(-outer, abs=1e-10)
    assert main(["statics", ARCH, "--mode", "vm"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert "the nearest to the initial configuration" in first and first.endswith("unstable")
    assert main(["statics", ARCH, "--mode", "vm", "--stable"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert "a stable one asked for" in first and first.endswith("stable")


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_residual_minimum_that_is_no_equilibrium_hands_over_to_descent(coordinates):
    """Rod with a torsional spring k = 1 N m/rad (free angle 0) under gravity: the net moment
    g(θ) = −k θ − m g (L/2) cos θ has a negative local maximum at θ₀ = 3π − asin(k/(m g L/2))
    = 9.219 rad (g = −4.42 N m): a local minimum of ‖F‖ that is no equilibrium.  Started
    there, the residual search cannot leave it; the search descends the potential instead
    (said in ``notes``) to the equilibrium below, g(θ*) = 0 in (3.5, 4.5) (brentq, 1e-10),
    stable.  No equilibrium lies between (cos θ = −kθ/(m g L/2) needs θ ≤ 4.905)."""
    c = G * 0.5
    start = 3 * np.pi - np.arcsin(1.0 / c)
    m = casmbd.Mechanism(f"wound_rod_{coordinates}", gravity=(0, -G), coordinates=coordinates)
    m.add_body("rod", 1.0, 1 / 12, (0.5 * np.cos(start), 0.5 * np.sin(start)), angle=start)
    m.add_revolute("pivot", "ground", "rod", (0, 0))
    m.add_rotational_spring_damper("spring", "pivot", stiffness=1.0)
    ref = brentq(lambda th: -th - c * np.cos(th), 3.5, 4.5, xtol=1e-15,
                 rtol=4 * np.finfo(float).eps)
    r = static_equilibrium(m, mode="vm")
    assert r.joint_coordinates[0] == pytest.approx(ref, abs=1e-10)
    assert r.stability.verdict == "stable" and len(r.notes) == 1
    assert "local minimum that is no equilibrium" in r.notes[0]


def test_residual_search_that_fails_falls_back_to_the_stable_search():
    """The flyball governor at rest (examples/flyball_governor.toml, stiff coupler springs
    8e5 N/m): the arms' fall is a long, narrow, curved valley of ‖F‖ that the residual
    search crawls along (100 iterations, residual still 35).  The result is then the stable
    equilibrium of the potential descent from the same start — identical to
    ``stable=True`` (q to 1e-12) — and the first note says so."""
    mech = casmbd.load_scene("examples/flyball_governor.toml")
    r = static_equilibrium(mech, mode="vm")
    ref = static_equilibrium(mech, mode="vm", stable=True)
    assert np.max(np.abs(r.q - ref.q)) <= 1e-12 and r.residual < 1e-9
    assert r.notes and r.notes[0].startswith("the search for the nearest equilibrium failed")
    assert "not converged after 100 iterations" in r.notes[0]
    assert r.stability.verdict == ref.stability.verdict == "neutral"


def test_least_squares_step():
    """The residual step: Newton's step for an indefinite stiffness (towards a saddle) when
    it fits; else on the trust-region boundary, decreasing the model; no step where the
    model is flat (Aᵀb = 0), which the statics iteration leaves by a descent step."""
    from casmbd.analysis.statics.trust_region import least_squares_step

    a, b = np.diag([-2.0, 1.0]), np.array([0.2, 0.1])
    step = least_squares_step(b, a, radius=1.0)
    assert step.newton and np.allclose(step.dz, [-0.1, 0.1], atol=1e-15)
    assert step.predicted == pytest.approx(0.5 * b @ b, rel=1e-12)
    step = least_squares_step(10 * b, a, radius=0.5)
    assert not step.newton and np.linalg.norm(step.dz) == pytest.approx(0.5, rel=1e-10)
    assert 0.0 < step.predicted < 0.5 * 100 * b @ b
    step = least_squares_step(np.array([1.0]), np.zeros((1, 1)), radius=0.5)
    assert not np.any(step.dz) and step.predicted == 0.0
    # a given shift: dz = (AᵀA + ν I)⁻¹ Aᵀ b
    step = least_squares_step(b, a, radius=np.inf, shift=3.0)
    assert np.allclose(step.dz, np.linalg.solve(a.T @ a + 3.0 * np.eye(2), a.T @ b),
                       atol=1e-15)
