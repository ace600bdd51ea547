"""Kinematic analysis against closed forms, finite differences and rank analysis.

Every test compares numbers with a stated tolerance:

* slider-crank: slider x, ẋ, ẍ, rod angle and rate, crank-pin marker against closed forms
  derived by hand below (1e-10 absolute);
* four-bar example: loop closure (≤ 1e-12), crank angle = driver (1e-12), velocities and
  accelerations against fourth-order central differences of the computed history (1e-7
  relative to the amplitude), rocker/coupler angles and centres of mass against an independent
  circle-intersection solution (1e-10);
* assembly from perturbed coordinates (1e-10) and with a fixed coordinate (kept bit-exactly);
* degrees of freedom and redundant equations from the rank of C_q;
* npz save/load round trip (bit-exact).
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

from casmbd import (
    Mechanism,
    NumericModel,
    System,
    assemble,
    info,
    kinematics,
    load,
    load_scene,
)

REPO = pathlib.Path(__file__).resolve().parents[3]
EXAMPLES = REPO / "examples"


_cache = private_cache("casmbd_cache_kinematics", scope="module")


# ---------------------------------------------------------------------------- slider-crank
R_CRANK, L_ROD, OMEGA = 0.1, 0.3, 2.0 * math.pi


def slider_crank_api() -> Mechanism:
    """The slider-crank of examples/slider_crank.toml built with the Python API."""
    m = Mechanism("slider_crank_api", gravity=(0.0, -9.81))
    m.add_parameter("omega", OMEGA)
    m.add_body("crank", mass=0.2, inertia="0.2 * 0.1**2 / 12", position=(0.05, 0.0))
    m.add_body("rod", mass=0.6, inertia="0.6 * 0.3**2 / 12", position=(0.25, 0.0))
    m.add_body("slider", mass=0.5, inertia=1e-4, position=(0.4, 0.0))
    m.add_marker("crank_pin", "crank", (0.1, 0.0))
    m.add_revolute("O", "ground", "crank", (0.0, 0.0))
    m.add_revolute("A", "crank", "rod", (0.1, 0.0))
    m.add_revolute("B", "rod", "slider", (0.4, 0.0))
    m.add_prismatic("slide", "ground", "slider", (0.4, 0.0), axis=(1.0, 0.0))
    m.add_driver("crank_speed", "omega * t", joint="O")
    m.add_actuator("motor", "O")
    return m


def slider_closed_form(theta, r=R_CRANK, rod=L_ROD, w=OMEGA):
    """Slider x and its exact time derivatives for θ = ω t (hand derivation).

    x = r cosθ + D with D = sqrt(l² − r² sin²θ).  With f = r² sinθ cosθ = dD²/dθ / (−2):
    dD/dθ = −f / D, so ẋ = −r ω sinθ − ω f / D and, with df/dθ = r² cos 2θ,
    ẍ = −r ω² cosθ − ω² (r² cos 2θ / D + f² / D³).
    """
    s, c = np.sin(theta), np.cos(theta)
    d = np.sqrt(rod**2 - r**2 * s**2)
    f = r**2 * s * c
    x = r * c + d
    xd = -r * w * s - w * f / d
    xdd = -r * w**2 * c - w**2 * (r**2 * np.cos(2.0 * theta) / d + f**2 / d**3)
    return x, xd, xdd


@pytest.fixture(scope="module", params=["api", "scene"])
def slider_crank_result(request):
    if request.param == "api":
        mech = slider_crank_api()
    else:
        mech = load_scene(EXAMPLES / "slider_crank.toml")
    return kinematics(mech, t_end=1.0, steps=200)


def test_closed_form_derivatives_are_consistent():
    """The hand-derived ẋ, ẍ agree with central differences of x(θ(t)) (1e-8 relative)."""
    t = np.linspace(0.013, 0.987, 37)
    h = 1e-5
    x_p, xd_p, _ = slider_closed_form(OMEGA * (t + h))
    x_m, xd_m, _ = slider_closed_form(OMEGA * (t - h))
    _, xd, xdd = slider_closed_form(OMEGA * t)
    np.testing.assert_allclose((x_p - x_m) / (2 * h), xd, rtol=0, atol=1e-8 * np.abs(xd).max())
    np.testing.assert_allclose((xd_p - xd_m) / (2 * h), xdd, rtol=0,
                               atol=1e-8 * np.abs(xdd).max())


def test_slider_crank_slider_closed_form(slider_crank_result):
    res = slider_crank_result
    assert res.t.shape == (201,)
    theta = OMEGA * res.t
    x, xd, xdd = slider_closed_form(theta)
    slider = res.body("slider")
    np.testing.assert_allclose(slider["position"][:, 0], x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slider["position"][:, 1], 0.0, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slider["velocity"][:, 0], xd, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slider["velocity"][:, 1], 0.0, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slider["acceleration"][:, 0], xdd, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slider["acceleration"][:, 1], 0.0, rtol=0, atol=1e-10)
    # the prismatic joint coordinate is the displacement from x = 0.4
    slide = res.joint("slide")
    np.testing.assert_allclose(slide["coordinate"], x - 0.4, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slide["velocity"], xd, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slide["acceleration"], xdd, rtol=0, atol=1e-10)
    assert np.max(res["constraint_violation"]) <= 1e-12


def test_slider_crank_crank_rod_and_marker(slider_crank_result):
    res = slider_crank_result
    theta = OMEGA * res.t
    s, c = np.sin(theta), np.cos(theta)
    crank = res.body("crank")
    np.testing.assert_allclose(crank["angle"], theta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(crank["angular_velocity"], OMEGA, rtol=0, atol=1e-12)
    np.testing.assert_allclose(crank["angular_acceleration"], 0.0, rtol=0, atol=1e-10)
    joint_o = res.joint("O")
    np.testing.assert_allclose(joint_o["coordinate"], theta, rtol=0, atol=1e-12)

    # rod angle φ = −asin(r sinθ / l); φ̇ = −r ω cosθ / D with D = sqrt(l² − r² sin²θ)
    rod = res.body("rod")
    d = np.sqrt(L_ROD**2 - R_CRANK**2 * s**2)
    np.testing.assert_allclose(rod["angle"], -np.arcsin(R_CRANK * s / L_ROD), rtol=0, atol=1e-10)
    np.testing.assert_allclose(rod["angular_velocity"], -R_CRANK * OMEGA * c / d, rtol=0,
                               atol=1e-10)
    # rod centre of mass = midpoint of the crank pin and the slider pin
    x, _, _ = slider_closed_form(theta)
    mid = np.column_stack([(R_CRANK * c + x) / 2, R_CRANK * s / 2])
    np.testing.assert_allclose(rod["position"], mid, rtol=0, atol=1e-10)

    # crank pin marker: r (cosθ, sinθ), r ω (−sinθ, cosθ), −r ω² (cosθ, sinθ)
    pin = res.marker("crank_pin")
    np.testing.assert_allclose(pin["position"], R_CRANK * np.column_stack([c, s]), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(pin["velocity"], R_CRANK * OMEGA * np.column_stack([-s, c]),
                               rtol=0, atol=1e-11)
    np.testing.assert_allclose(pin["acceleration"],
                               -R_CRANK * OMEGA**2 * np.column_stack([c, s]), rtol=0, atol=1e-10)


def test_slider_crank_api_and_scene_are_identical():
    """Both builders give the same equations: histories agree to 1e-14."""
    a = kinematics(slider_crank_api(), t_end=0.25, steps=10)
    b = kinematics(load_scene(EXAMPLES / "slider_crank.toml"), t_end=0.25, steps=10)
    for key in ("q", "v", "a", "marker_positions"):
        np.testing.assert_allclose(a[key], b[key], rtol=0, atol=1e-14)


# ---------------------------------------------------------------------------- four-bar
FOUR_BAR_POINTS = {  # global pin locations at the initial pose of examples/four_bar.toml
    "A": np.array([0.0, 0.0]), "B": np.array([0.0, 0.2]),
    "C": np.array([0.6437, 0.4750]), "D": np.array([0.8, 0.0]),
}
ROCKER_ANGLE0 = 1.8886
COUPLER_ANGLE0 = 0.4037


def circle_intersection(b, d, l_bc, l_dc, sign):
    """Point C with |C − B| = l_bc and |C − D| = l_dc; ``sign`` picks the branch.

    Independent position solution of the four-bar (intersection of two circles).
    """
    bd = d - b
    dist = np.linalg.norm(bd, axis=-1, keepdims=True)
    e = bd / dist
    a = (l_bc**2 - l_dc**2 + dist**2) / (2.0 * dist)
    h = np.sqrt(l_bc**2 - a**2)
    perp = np.stack([-e[..., 1], e[..., 0]], axis=-1)
    return b + a * e + sign * h * perp


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def four_bar_closed_form(crank_angle):
    """Rocker and coupler body angles of the example for crank body angle(s) ``crank_angle``."""
    p = FOUR_BAR_POINTS
    l_ab = np.linalg.norm(p["B"] - p["A"])
    l_bc = np.linalg.norm(p["C"] - p["B"])
    l_dc = np.linalg.norm(p["C"] - p["D"])
    bd0, bc0 = p["D"] - p["B"], p["C"] - p["B"]
    sign = np.sign(bd0[0] * bc0[1] - bd0[1] * bc0[0])  # C lies left of B→D initially
    # crank body angle π/2 has B straight above A
    crank_angle = np.atleast_1d(crank_angle)
    phi = crank_angle - math.pi / 2 + math.atan2(*(p["B"] - p["A"])[::-1])
    b = p["A"] + l_ab * np.column_stack([np.cos(phi), np.sin(phi)])
    c = circle_intersection(b, np.broadcast_to(p["D"], b.shape), l_bc, l_dc, sign)
    dc, dc0 = c - p["D"], p["C"] - p["D"]
    bc = c - b
    rocker = ROCKER_ANGLE0 + wrap(np.arctan2(dc[:, 1], dc[:, 0]) - math.atan2(dc0[1], dc0[0]))
    coupler = COUPLER_ANGLE0 + wrap(np.arctan2(bc[:, 1], bc[:, 0]) - math.atan2(bc0[1], bc0[0]))
    return rocker, coupler, b, c


def test_four_bar_closed_form_reproduces_initial_pose():
    """Sanity of the independent solution: at the initial crank angle it gives the scene pose."""
    rocker, coupler, b, c = four_bar_closed_form(math.pi / 2)
    np.testing.assert_allclose(b[0], FOUR_BAR_POINTS["B"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(c[0], FOUR_BAR_POINTS["C"], rtol=0, atol=1e-12)
    assert rocker[0] == pytest.approx(ROCKER_ANGLE0, abs=1e-12)
    assert coupler[0] == pytest.approx(COUPLER_ANGLE0, abs=1e-12)


@pytest.fixture(scope="module")
def four_bar_fine():
    return kinematics(load_scene(EXAMPLES / "four_bar.toml"), t_end=1.0, steps=1000)


def test_four_bar_loop_closure_and_driver(four_bar_fine):
    res = four_bar_fine
    assert np.max(res["constraint_violation"]) <= 1e-12
    crank = res.body("crank")
    np.testing.assert_allclose(crank["angle"], math.pi / 2 + 2 * math.pi * res.t, rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(crank["angular_velocity"], 2 * math.pi, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.joint("A")["coordinate"], math.pi / 2 + 2 * math.pi * res.t,
                               rtol=0, atol=1e-12)
    # angles and centres of mass vs the circle-intersection solution (pins B, C)
    rocker, coupler, b, c = four_bar_closed_form(crank["angle"])
    np.testing.assert_allclose(res.body("rocker")["angle"], rocker, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res.body("coupler")["angle"], coupler, rtol=0, atol=1e-10)
    p = FOUR_BAR_POINTS
    for body, pin, pin0, angle, angle0, g0 in (
            ("coupler", b, p["B"], coupler, COUPLER_ANGLE0, (0.32, 0.34)),
            ("rocker", c, p["C"], rocker, ROCKER_ANGLE0, (0.72, 0.24))):
        arm = np.asarray(g0) - pin0  # pin → centre of mass at the initial pose, rotated rigidly
        da = angle - angle0
        expected = pin + np.column_stack([np.cos(da) * arm[0] - np.sin(da) * arm[1],
                                          np.sin(da) * arm[0] + np.cos(da) * arm[1]])
        np.testing.assert_allclose(res.body(body)["position"], expected, rtol=0, atol=1e-10)
    # coupler_mid marker = coupler centre of mass in this scene
    np.testing.assert_allclose(res.marker("coupler_mid")["position"],
                               res.body("coupler")["position"], rtol=0, atol=1e-14)


def test_four_bar_rocker_angle_closed_form_over_the_turn(four_bar_fine):
    """Rocker angle vs the circle-intersection solution at every one of the 1001 times."""
    res = four_bar_fine
    rocker, _, _, _ = four_bar_closed_form(math.pi / 2 + 2 * math.pi * res.t)
    err = np.abs(res.body("rocker")["angle"] - rocker)
    assert err.max() <= 1e-10, err.max()
    # the rocker really swings (not a trivially constant answer)
    assert np.ptp(rocker) > 0.5


def _central(values, t):
    """Fourth-order central difference (−f₊₂ + 8 f₊₁ − 8 f₋₁ + f₋₂) / 12h on a uniform grid."""
    h = t[1] - t[0]
    return (-values[4:] + 8 * values[3:-1] - 8 * values[1:-3] + values[:-4]) / (12 * h)


def test_four_bar_velocities_match_finite_differences(four_bar_fine):
    """q̇ and q̈ vs fourth-order central differences of q and q̇ on h = 1e-3 s.

    Tolerance 1e-7 relative to the amplitude max|q̇| (max|q̈|): the truncation error
    h⁴ |q⁽⁵⁾| / 30 is about 2e-9 relative here, the position tolerance of Newton (1e-12) divided
    by h adds ~1e-9.  (The second-order stencil would leave ~6e-6 of truncation error.)
    """
    res = four_bar_fine
    t, q, v, a = res.t, res["q"], res["v"], res["a"]
    np.testing.assert_allclose(_central(q, t), v[2:-2], rtol=0, atol=1e-7 * np.abs(v).max())
    np.testing.assert_allclose(_central(v, t), a[2:-2], rtol=0, atol=1e-7 * np.abs(a).max())
    # outputs (centres of mass, angles, markers, joint coordinates) as well
    for key in ("body", "angle", "marker", "joint"):
        pos, vel, acc = (res[f"{key}_{s}"] for s in ("positions", "velocities", "accelerations"))
        np.testing.assert_allclose(_central(pos, t), vel[2:-2], rtol=0,
                                   atol=1e-7 * np.abs(vel).max())
        np.testing.assert_allclose(_central(vel, t), acc[2:-2], rtol=0,
                                   atol=1e-7 * np.abs(acc).max())


# ---------------------------------------------------------------------------- assembly
def four_bar_api(crank_angle: float = 1.2, driver: bool = True, name: str = "fb_api"):
    """A crank-rocker four-bar (0.2, 0.7, 0.5, ground 0.8) built at an exact configuration."""
    a0, d0 = np.array([0.0, 0.0]), np.array([0.8, 0.0])
    b = a0 + 0.2 * np.array([math.cos(crank_angle), math.sin(crank_angle)])
    c = circle_intersection(b, d0, 0.7, 0.5, 1.0)

    def link(p, q):
        return dict(position=(p + q) / 2, angle=math.atan2(*(q - p)[::-1]))

    m = Mechanism(name, gravity=(0.0, -9.81))
    m.add_body("crank", 0.4, 0.4 * 0.2**2 / 12, **link(a0, b))
    m.add_body("coupler", 1.4, 1.4 * 0.7**2 / 12, **link(b, c))
    m.add_body("rocker", 1.0, 1.0 * 0.5**2 / 12, **link(d0, c))
    m.add_revolute("A", "ground", "crank", a0)
    m.add_revolute("B", "crank", "coupler", b)
    m.add_revolute("C", "coupler", "rocker", c)
    m.add_revolute("D", "ground", "rocker", d0)
    if driver:
        m.add_driver("drive", f"{crank_angle!r} + 2 * pi * t", joint="A")
    return m


def test_assembly_from_perturbed_coordinates():
    mech = four_bar_api(driver=True, name="fb_assembly")
    model = NumericModel(mech, "kinematics")
    q_exact = System(mech).initial_coordinates()
    assert np.max(np.abs(model.constraints(q_exact, 0.0))) <= 1e-15
    rng = np.random.default_rng(7)
    for _ in range(3):
        q0 = q_exact + rng.uniform(-0.03, 0.03, size=q_exact.size)
        rep = assemble(model, q0, 0.0)
        assert rep.residual <= 1e-11
        assert rep.iterations >= 1
        np.testing.assert_allclose(rep.q, q_exact, rtol=0, atol=1e-10)
        np.testing.assert_allclose(rep.change, rep.q - q0, rtol=0, atol=0)


def test_assembly_keeps_fixed_coordinate_exactly():
    """Undriven four-bar: with fixed=['crank.angle'] the crank angle is kept bit-exactly and
    the rest is the closed-form configuration of that crank angle (1e-10)."""
    mech = four_bar_api(crank_angle=1.2, driver=False, name="fb_fixed")
    mech.coordinates = "absolute"  # q = (x, y, angle) of crank, coupler, rocker
    model = NumericModel(mech, "kinematics")
    target = 1.2 + 0.25
    reference = four_bar_api(crank_angle=target, driver=False, name="fb_ref")
    reference.coordinates = "absolute"
    ref = System(reference).initial_coordinates()
    q0 = System(mech).initial_coordinates()
    q0[2] = target  # new crank angle, every other coordinate is now off
    rng = np.random.default_rng(11)
    q0[[0, 1, 3, 4, 5, 6, 7, 8]] += rng.uniform(-0.01, 0.01, size=8)
    rep = assemble(model, q0, 0.0, fixed=["crank.angle"])
    assert rep.q[2] == target
    assert rep.change[2] == 0.0
    assert np.max(np.abs(model.constraints(rep.q, 0.0))) <= 1e-11
    np.testing.assert_allclose(rep.q, ref, rtol=0, atol=1e-10)
    # without fixing it, the minimum-norm Newton iteration is free to move the crank angle
    free = assemble(model, q0, 0.0)
    assert free.q[2] != target
    # the automatic choice: joint angles A, B, D (zero at the built pose), C closes the loop;
    # the closed-form joint angles of the target are differences of the bodies' angles
    auto = four_bar_api(crank_angle=1.2, driver=False, name="fb_fixed_auto")
    model = NumericModel(auto, "kinematics")
    assert model.coordinate_names == ["A.angle", "B.angle", "D.angle"]
    th0, th = System(mech).initial_coordinates()[2::3], ref[2::3]  # crank, coupler, rocker
    expected = [th[0] - th0[0], (th[1] - th[0]) - (th0[1] - th0[0]), th[2] - th0[2]]
    q0 = np.array([0.25, -0.01, 0.01])
    rep = assemble(model, q0, 0.0, fixed=["A.angle"])
    assert rep.q[0] == 0.25 and rep.change[0] == 0.0
    assert np.max(np.abs(model.constraints(rep.q, 0.0))) <= 1e-11
    np.testing.assert_allclose(rep.q, expected, rtol=0, atol=1e-10)


# ---------------------------------------------------------------------------- rank analysis
def parallelogram(extra_link: bool = True, driver: bool = False) -> Mechanism:
    """Parallelogram four-bar; the optional third parallel link makes one equation redundant."""
    a = 0.4 * np.array([math.cos(1.1), math.sin(1.1)])
    o1, o2, o3 = np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([0.5, 0.0])
    p_a, p_b, p_e = o1 + a, o2 + a, o3 + a
    ang = math.atan2(a[1], a[0])
    m = Mechanism("parallelogram")
    m.add_body("link1", 1.0, 0.02, position=(o1 + p_a) / 2, angle=ang)
    m.add_body("coupler", 1.0, 0.1, position=(p_a + p_b) / 2, angle=0.0)
    m.add_body("link2", 1.0, 0.02, position=(o2 + p_b) / 2, angle=ang)
    m.add_revolute("O1", "ground", "link1", o1)
    m.add_revolute("JA", "link1", "coupler", p_a)
    m.add_revolute("JB", "coupler", "link2", p_b)
    m.add_revolute("O2", "ground", "link2", o2)
    if extra_link:
        m.add_body("link3", 1.0, 0.02, position=(o3 + p_e) / 2, angle=ang)
        m.add_revolute("O3", "ground", "link3", o3)
        m.add_revolute("JE", "link3", "coupler", p_e)
    if driver:
        m.add_driver("drive", "1.1 + t", joint="O1")
    return m


#: (n_coordinates, n_constraints, rank) of the double pendulum, slider-crank and four-bar:
#: absolute coordinates 3 per body; the automatic choice takes joint coordinates (the double
#: pendulum is a tree; the slider-crank and the four-bar close one loop with 2 equations, plus
#: the slider-crank's driver)
SIZES = {"absolute": [(6, 4, 4), (9, 9, 9), (9, 8, 8)],
         "auto": [(2, 0, 0), (3, 3, 3), (3, 2, 2)]}


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_degrees_of_freedom_of_examples(coordinates):
    mechs = [load_scene(EXAMPLES / "double_pendulum.toml"),
             load_scene(EXAMPLES / "slider_crank.toml"),
             four_bar_api(driver=False, name="fb_info")]
    for mech in mechs:
        mech.coordinates = coordinates
    dp, sc, fb = (info(m) for m in mechs)
    assert dp["degrees_of_freedom"] == 2
    assert (dp["n_coordinates"], dp["n_constraints"], dp["rank"]) == SIZES[coordinates][0]
    assert sc["degrees_of_freedom"] == 0
    assert (sc["n_coordinates"], sc["n_constraints"], sc["rank"]) == SIZES[coordinates][1]
    assert sc["redundant_equations"] == []
    assert fb["degrees_of_freedom"] == 1
    assert (fb["n_coordinates"], fb["n_constraints"], fb["rank"]) == SIZES[coordinates][2]
    assert fb["redundant_equations"] == []


@pytest.mark.parametrize(("coordinates", "sizes"), [("absolute", (12, 12, 11)),
                                                    ("auto", (4, 4, 3))])
def test_parallelogram_redundant_link(coordinates, sizes):
    """Absolute: 4 bodies x 3 coordinates, 6 revolute joints x 2 equations; the automatic
    choice: joint angles O1, JA, O2, O3 with JB and JE closing two loops (4 equations)."""
    mechs = [parallelogram(extra_link=False), parallelogram(extra_link=True)]
    for mech in mechs:
        mech.coordinates = coordinates
    base = info(mechs[0])
    assert base["degrees_of_freedom"] == 1 and base["redundant_equations"] == []
    rep = info(mechs[1])
    assert (rep["n_coordinates"], rep["n_constraints"], rep["rank"]) == sizes
    assert rep["degrees_of_freedom"] == 1
    assert len(rep["redundant_equations"]) == 1
    red = rep["redundant_equations"][0]
    assert red["kind"] == "joint" and red["joint"] == "JE"
    assert red["equation"] in ("x", "y")


def test_kinematics_of_redundant_parallelogram_removes_and_names_the_equation():
    """The redundant equation of the extra link (JE, later in declaration order) is removed
    and named (issue 30, 4a); the motion is that of the parallelogram without the extra link
    (1e-12) and every equation, the removed one included, holds."""
    red = kinematics(parallelogram(extra_link=True, driver=True), t_end=0.1, steps=2)
    assert red.stats["redundancy"] == "removed"
    assert len(red.stats["redundant_equations"]) == 1
    assert red.stats["redundant_equations"][0].startswith("joint 'JE'")
    assert np.max(red["constraint_violation"]) < 1e-12
    res = kinematics(parallelogram(extra_link=False, driver=True), t_end=0.1, steps=2)
    assert res.stats["redundant_equations"] == [] and res.stats["redundancy"] == "none"
    np.testing.assert_allclose(res.body("coupler")["angle"], 0.0, rtol=0, atol=1e-12)
    for body in ("link1", "coupler", "link2"):
        np.testing.assert_allclose(red.body(body)["angle"], res.body(body)["angle"], rtol=0,
                                   atol=1e-12)


# ---------------------------------------------------------------------------- results files
def test_result_save_load_round_trip(tmp_path, slider_crank_result):
    res = slider_crank_result
    path = res.save(tmp_path / "sub" / "slider.npz")
    assert path.exists()
    back = load(path)
    assert back.kind == res.kind == "kinematics"
    assert back.t.dtype == res.t.dtype and np.array_equal(back.t, res.t)
    assert set(back.arrays) == set(res.arrays)
    for key, arr in res.arrays.items():
        assert back.arrays[key].dtype == arr.dtype, key
        assert back.arrays[key].shape == arr.shape, key
        assert np.array_equal(back.arrays[key], arr), key
    assert back.names == res.names
    assert back.stats == res.stats
    assert back.scene == res.scene
    np.testing.assert_array_equal(back.body("slider")["acceleration"],
                                  res.body("slider")["acceleration"])
    assert not list(path.parent.glob(".tmp_*"))
