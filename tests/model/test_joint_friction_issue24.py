"""Joint friction of issue 24 (item 4; friction parts of items 6 and 7): the scene contract
``friction = { viscous, coulomb, regularization, mu, radius, preload }`` on a ``[[joints]]``
entry, feedforward torques that include friction (inverse dynamics) against an independent
Lagrange / Newton–Euler computation, and a block on an incline with Coulomb friction
μ · normal reaction (closed forms)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from casmbd import simulate
from casmbd.analysis.driven.inverse import inverse_dynamics
from casmbd.errors import CompositionError, ModelError, SceneError
from casmbd.io.scene import load_scene, loads_scene

G = 9.81
R, L = 0.1, 0.3  # crank and rod lengths
M1, M2, M3 = 0.2, 0.6, 0.5  # crank, rod, slider masses
I1, I2 = M1 * R**2 / 12, M2 * L**2 / 12
TH0 = 1.0


def _slider_crank(friction_a: str, friction_s: str, coordinates: str = "absolute") -> str:
    """Slider-crank (crank 0.1 m, rod 0.3 m, slider on the x axis) driven by its crank angle
    θ(t) = 1 + 2 t + 0.5 sin 3t, with friction tables on the crank pin A and the slide."""
    pin = "0.1 * cos(th0) + 0.3 * cos(asin(-sin(th0) / 3))"
    return f'''
[scene]
name = "slider_crank_friction"
gravity = [0.0, -{G}]
coordinates = "{coordinates}"
[parameters]
th0 = {TH0}
[[bodies]]
name = "crank"
mass = {M1}
inertia = {I1!r}
position = ["0.05 * cos(th0)", "0.05 * sin(th0)"]
angle = "th0"
[[bodies]]
name = "rod"
mass = {M2}
inertia = {I2!r}
position = ["0.1 * cos(th0) + 0.15 * cos(asin(-sin(th0) / 3))",
            "0.1 * sin(th0) + 0.15 * sin(asin(-sin(th0) / 3))"]
angle = "asin(-sin(th0) / 3)"
[[bodies]]
name = "slider"
mass = {M3}
inertia = 1e-4
position = ["{pin}", 0.0]
[[joints]]
name = "O"
type = "revolute"
body1 = "ground"
body2 = "crank"
point = [0.0, 0.0]
[[joints]]
name = "A"
type = "revolute"
body1 = "crank"
body2 = "rod"
point = ["0.1 * cos(th0)", "0.1 * sin(th0)"]
friction = {friction_a}
[[joints]]
name = "B"
type = "revolute"
body1 = "rod"
body2 = "slider"
point = ["{pin}", 0.0]
[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "slider"
point = ["{pin}", 0.0]
axis = [1.0, 0.0]
friction = {friction_s}
[[drivers]]
name = "motor"
joint = "O"
position = "th0 + 2 * t + 0.5 * sin(3 * t)"
'''


def _cross(a, b) -> float:
    return a[0] * b[1] - a[1] * b[0]


def _independent(t: float, fa: dict, fs: dict) -> tuple[float, float, float]:
    """Crank torque, |R_A| and |N_slide| of the slider-crank, by hand (numpy only).

    Kinematics in closed form: sin φ = −(R/L) sin θ, x = R cos θ + L cos φ.  The torque from
    Lagrange's equation with the friction forces as generalized forces,
    τ = Σ_i (m_i a_Gi · ∂r_Gi/∂θ + I_i α_i ∂ω_i/∂θ) + Σ m_i g ∂y_Gi/∂θ − Q_fric,
    Q_fric = −f_A ∂ψ/∂θ − f_s ∂x/∂θ (ψ = φ − θ the pin angle, f the resisting friction
    forces); the reactions |R_A| and the slide's normal force from Newton–Euler on the three
    bodies; the reaction-proportional levels F_0 + μ r |R| make this a fixed point, iterated
    here to 1e-14.
    """
    th = TH0 + 2 * t + 0.5 * math.sin(3 * t)
    thd = 2 + 1.5 * math.cos(3 * t)
    thdd = -4.5 * math.sin(3 * t)
    k = R / L
    phi = math.asin(-k * math.sin(th))
    p1 = -k * math.cos(th) / math.cos(phi)  # dφ/dθ
    p2 = (k * math.sin(th) + math.sin(phi) * p1**2) / math.cos(phi)  # d²φ/dθ²
    phid, phidd = p1 * thd, p1 * thdd + p2 * thd**2
    c, s, cp, sp = math.cos(th), math.sin(th), math.cos(phi), math.sin(phi)
    # ∂r/∂θ and ∂²r/∂θ² of the centres of mass
    j1, h1 = 0.5 * R * np.array([-s, c]), 0.5 * R * np.array([-c, -s])
    j2 = R * np.array([-s, c]) + 0.5 * L * np.array([-sp, cp]) * p1
    h2 = R * np.array([-c, -s]) + 0.5 * L * (np.array([-cp, -sp]) * p1**2
                                             + np.array([-sp, cp]) * p2)
    xd1 = -R * s - L * sp * p1  # dx/dθ
    xd2 = -R * c - L * cp * p1**2 - L * sp * p2
    j3, h3 = np.array([xd1, 0.0]), np.array([xd2, 0.0])
    acc = [j * thdd + h * thd**2 for j, h in ((j1, h1), (j2, h2), (j3, h3))]
    psid, xdot = phid - thd, xd1 * thd  # pin and slide rates

    def resist(f: dict, rate: float, normal: float, arm: float) -> float:
        level = f.get("coulomb", 0.0) + f.get("mu", 0.0) * arm * normal
        return f.get("viscous", 0.0) * rate + level * math.tanh(rate / f["regularization"])

    pos_a = R * np.array([c, s])
    g1, g2 = 0.5 * pos_a, pos_a + 0.5 * L * np.array([cp, sp])
    pos_b = np.array([R * c + L * cp, 0.0])
    gvec = np.array([0.0, -G])
    n_a = n_s = 0.0
    for _ in range(200):
        f_a = resist(fa, psid, n_a, fa.get("radius", 1.0))
        f_s = resist(fs, xdot, n_s, 1.0)
        # Newton–Euler, unknowns [F_O (2), F_A (2), F_B (2), N, M_s, τ]; F_A on the rod from
        # the crank, F_B on the slider from the rod, pin friction torque −f_A on the rod
        a = np.zeros((9, 9))
        b = np.zeros(9)
        a[0:2, 0:2], a[0:2, 2:4] = np.eye(2), -np.eye(2)
        b[0:2] = M1 * acc[0] - M1 * gvec
        a[2, 0:2] = [-(0 - g1[1]), (0 - g1[0])]  # (O − G1) × F_O
        a[2, 2:4] = [(pos_a - g1)[1], -(pos_a - g1)[0]]  # (A − G1) × (−F_A)
        a[2, 8] = 1.0
        b[2] = I1 * thdd - f_a
        a[3:5, 2:4], a[3:5, 4:6] = np.eye(2), -np.eye(2)
        b[3:5] = M2 * acc[1] - M2 * gvec
        a[5, 2:4] = [-(pos_a - g2)[1], (pos_a - g2)[0]]
        a[5, 4:6] = [(pos_b - g2)[1], -(pos_b - g2)[0]]
        b[5] = I2 * phidd + f_a
        a[6:8, 4:6] = np.eye(2)
        a[7, 6] = 1.0
        b[6:8] = M3 * acc[2] - M3 * gvec - np.array([-f_s, 0.0])
        a[8, 7] = 1.0  # slider: no rotation, arm of F_B zero
        sol = np.linalg.solve(a, b)
        new_a, new_s = float(np.hypot(*sol[2:4])), abs(float(sol[6]))
        done = abs(new_a - n_a) + abs(new_s - n_s) <= 1e-14 * (new_a + new_s)
        n_a, n_s = new_a, new_s
        if done:
            break
    f_a = resist(fa, psid, n_a, fa.get("radius", 1.0))
    f_s = resist(fs, xdot, n_s, 1.0)
    lagrange = (sum(m * (ai @ j) for m, ai, j in ((M1, acc[0], j1), (M2, acc[1], j2),
                                                   (M3, acc[2], j3)))
                + I1 * thdd + I2 * phidd * p1
                + G * (M1 * j1[1] + M2 * j2[1] + M3 * j3[1])
                + f_a * (p1 - 1.0) + f_s * xd1)
    assert abs(lagrange - sol[8]) <= 1e-10 * max(1.0, abs(lagrange))  # both hand-written
    return lagrange, n_a, n_s


def _table(f: dict) -> str:
    return "{ " + ", ".join(f"{k} = {v!r}" for k, v in f.items()) + " }"


CASES = {
    "constant": ({"viscous": 0.01, "coulomb": 0.05, "regularization": 0.05},
                 {"viscous": 0.5, "coulomb": 0.4, "regularization": 0.05}),
    "reaction": ({"viscous": 0.01, "coulomb": 0.05, "regularization": 0.05, "mu": 0.2,
                  "radius": 0.02},
                 {"viscous": 0.5, "coulomb": 0.1, "regularization": 0.05, "mu": 0.3}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_slider_crank_feedforward_torque_with_friction(case):
    """Crank torque of the driven slider-crank with viscous + Coulomb friction at the crank
    pin and the slide (and, case "reaction", levels F_0 + μ r |R|): inverse dynamics = the
    hand-written Lagrange torque to 1e-9 relative (of max |τ|) on 41 times over 3 s, with the
    reactions |R_A| and the slide's normal force matching to 1e-9 relative."""
    fa, fs = CASES[case]
    mech = loads_scene(_slider_crank(_table(fa), _table(fs)))
    assert set(mech.forces) == {"A.friction", "slide.friction"}
    res = inverse_dynamics(mech, 3.0, 40)
    torque = res["driver_efforts"][:, 0]
    ref = np.array([_independent(t, fa, fs) for t in res.t])
    scale = np.max(np.abs(ref[:, 0]))
    assert np.max(np.abs(torque - ref[:, 0])) <= 1e-9 * scale
    names = list(mech.joints)
    reac = res["joint_reactions"]
    n_a = np.hypot(reac[:, names.index("A"), 0], reac[:, names.index("A"), 1])
    n_s = np.abs(reac[:, names.index("slide"), 1])
    assert np.max(np.abs(n_a - ref[:, 1])) <= 1e-9 * np.max(ref[:, 1])
    assert np.max(np.abs(n_s - ref[:, 2])) <= 1e-9 * np.max(ref[:, 2])
    # the friction is really in the torque: without it the torque differs by > 1 %
    plain = inverse_dynamics(loads_scene(_slider_crank("{ viscous = 0.0 }",
                                                       "{ viscous = 0.0 }")), 3.0, 40)
    assert np.max(np.abs(plain["driver_efforts"][:, 0] - torque)) >= 0.01 * scale
    if case == "reaction":
        assert 1 <= res.stats["friction_iterations"] <= 60


# ------------------------------------------------------------------ block on an incline
def _incline(alpha: float, mu: float, v0: float, vs: float = 1e-4) -> str:
    """A 2 kg block on a prismatic joint along the incline (downhill axis (cos α, −sin α)),
    gravity g, Coulomb friction μ · normal reaction (regularised with v_s), launched with
    ``v0`` along the axis (negative: uphill)."""
    ca_, sa = math.cos(alpha), math.sin(alpha)
    return f'''
[scene]
name = "incline"
gravity = [0.0, -{G}]
coordinates = "absolute"
[[bodies]]
name = "block"
mass = 2.0
inertia = 0.1
position = [0.0, 0.0]
velocity = [{v0 * ca_!r}, {-v0 * sa!r}]
angle = {-alpha!r}
[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [0.0, 0.0]
axis = [{ca_!r}, {-sa!r}]
friction = {{ mu = {mu!r}, regularization = {vs!r} }}
'''


def _run(alpha, mu, v0, t_end, steps, formulation="index1"):
    res = simulate(loads_scene(_incline(alpha, mu, v0)), t_end, steps,
                   formulation=formulation, rtol=1e-10, atol=1e-12)
    return res.t, res["joint_positions"][:, 0], res["joint_velocities"][:, 0], res


@pytest.mark.parametrize("formulation", ["index1", "ggl"])
def test_incline_slides_in_both_dae_formulations(formulation):
    """Launched downhill at 1 m/s (tan α > μ): s = v0 t + g (sin α − μ cos α) t²/2 to 1e-12 m
    with the index-1 and the GGL DAE (λ algebraic in both)."""
    alpha, mu = 0.5, 0.3
    acc = G * (math.sin(alpha) - mu * math.cos(alpha))
    t, s, _, _ = _run(alpha, mu, 1.0, 1.0, 100, formulation)
    assert np.max(np.abs(s - (t + 0.5 * acc * t**2))) <= 1e-12


def test_incline_slides_with_closed_form_acceleration():
    """tan α = 0.546 > μ = 0.3: launched downhill at 1 m/s the block slides with
    a = g (sin α − μ cos α), s = v0 t + a t²/2 to 1e-12 m over 1 s (|v| ≫ v_s: the
    regularised law is Coulomb's); the normal reaction is m g cos α to 1e-10.  From rest the
    regularised law lets it start with less friction for |v| ~ v_s: s = a t²/2 + Δv t with
    Δv = μ v_s ∫₀^∞ (1 − tanh w) / (tan α − μ tanh w) dw (3.9e-5 m/s here, the whole
    difference to 1e-8 m)."""
    from scipy.integrate import quad

    alpha, mu, vs = 0.5, 0.3, 1e-4
    acc = G * (math.sin(alpha) - mu * math.cos(alpha))
    t, s, _, res = _run(alpha, mu, 1.0, 1.0, 100)
    assert np.max(np.abs(s - (t + 0.5 * acc * t**2))) <= 1e-12
    reac = res["joint_reactions"][:, 0, :2]
    normal = reac @ np.array([math.sin(alpha), math.cos(alpha)])
    assert np.max(np.abs(np.abs(normal) - 2.0 * G * math.cos(alpha))) <= 1e-10
    t, s, _, _ = _run(alpha, mu, 0.0, 1.0, 100)
    dv = mu * vs * quad(lambda w: (1 - math.tanh(w)) / (math.tan(alpha) - mu * math.tanh(w)),
                        0.0, 50.0, epsabs=1e-14)[0]
    assert 3e-5 <= dv <= 6e-5
    assert np.max(np.abs(s[10:] - (0.5 * acc * t[10:]**2 + dv * t[10:]))) <= 1e-8


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.3), (0.3, 0.5)])
def test_incline_launched_uphill_stops(alpha, mu):
    """Launched uphill at 2 m/s, the block stops at t_s = v0 / (g (sin α + μ cos α)) after
    the distance v0² / (2 g (sin α + μ cos α)) (to 1e-8 relative; |v(t_s)| < v_s, the
    regularised law weakens for |v| ~ v_s).  Then with tan α > μ it slides back with
    g (sin α − μ cos α) (the speed at t_s + 0.5 s to 1e-4 relative: the start through v = 0
    is regularised); with tan α < μ it stays up to the regularised law's creep: the velocity
    tends to v_s artanh(tan α / μ) (7.2e-5 m/s for v_s = 1e-4, to 1e-6 relative), so it
    creeps less than 3.7e-5 m in 0.5 s."""
    v0, vs = 2.0, 1e-4
    dec = G * (math.sin(alpha) + mu * math.cos(alpha))
    t_stop, dist = v0 / dec, v0**2 / (2 * dec)
    _, s, v, _ = _run(alpha, mu, -v0, t_stop, 200)
    assert abs(s[-1] + dist) <= 1e-8 * dist
    assert abs(v[-1]) <= vs
    _, s2, v2, _ = _run(alpha, mu, -v0, t_stop + 0.5, 200)
    if math.tan(alpha) > mu:
        back = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert abs(v2[-1] - back * 0.5) <= 1e-4 * back * 0.5
    else:
        creep = vs * math.atanh(math.tan(alpha) / mu)
        assert abs(v2[-1] - creep) <= 1e-6 * creep
        assert 0.0 <= s2[-1] - s[-1] <= 0.5 * creep


# ------------------------------------------------------------------ forward dynamics (DAE)
def test_slider_crank_forward_index1_energy_balance():
    """The free slider-crank (crank spun at 20 rad/s) with reaction-proportional friction at
    the pin and the slide, integrated as the index-1 DAE (λ algebraic, so the friction uses
    it directly): the energy lost equals ∫ Σ f_j q̇_j dt with f_j rebuilt from the output
    joint rates and reactions (F_0 + μ r |R|), Simpson on 1001 points over 0.5 s, to 1e-7
    relative to the energy dissipated."""
    from scipy.integrate import simpson

    fa, fs = CASES["reaction"]
    text = _slider_crank(_table(fa), _table(fs))
    text = text[:text.index("[[drivers]]")].replace(
        'angle = "th0"\n', 'angle = "th0"\nangular_velocity = 20.0\n', 1)
    res = simulate(loads_scene(text), 0.5, 1000, formulation="index1", rtol=1e-10,
                   atol=1e-12)
    coords, joints = res.names["joints"], res.names["all_joints"]
    rate_a = res["joint_velocities"][:, coords.index("A")]
    rate_s = res["joint_velocities"][:, coords.index("slide")]
    reac = res["joint_reactions"]
    n_a = np.hypot(reac[:, joints.index("A"), 0], reac[:, joints.index("A"), 1])
    n_s = np.abs(reac[:, joints.index("slide"), 1])
    f_a = fa["viscous"] * rate_a + (fa["coulomb"] + fa["mu"] * fa["radius"] * n_a) * np.tanh(
        rate_a / fa["regularization"])
    f_s = fs["viscous"] * rate_s + (fs["coulomb"] + fs["mu"] * n_s) * np.tanh(
        rate_s / fs["regularization"])
    power = f_a * rate_a + f_s * rate_s
    lost = simpson(power, x=res.t)
    change = res["total_energy"][-1] - res["total_energy"][0]
    assert lost > 0.03
    assert abs(change + lost) <= 1e-7 * lost


# ------------------------------------------------------------------ contract and refusals
def test_scene_friction_table_is_the_api_element():
    """``friction = {...}`` on a joint entry builds the element "<joint>.friction" with the
    fields of the table (viscous -> damping, coulomb or preload -> friction)."""
    mech = loads_scene(_slider_crank(
        "{ viscous = 0.1, coulomb = 0.5 }",
        "{ preload = 0.2, mu = 0.3, regularization = 0.01 }"))
    pin, slide = mech.forces["A.friction"], mech.forces["slide.friction"]
    assert (pin.joint, pin.damping, pin.friction, pin.mu, pin.radius) == ("A", 0.1, 0.5, 0.0,
                                                                         None)
    assert (slide.joint, slide.friction, slide.mu, slide.regularization) == ("slide", 0.2, 0.3,
                                                                            0.01)
    assert pin.reaction_joint() is None and slide.reaction_joint() == "slide"


@pytest.mark.parametrize("table, message", [
    ("0.5", "expected a table"),
    ("{ viscous = 0.1, static = 1.0 }", "unknown key(s) static"),
    ("{ coulomb = 0.1, preload = 0.2 }", "not both"),
    ("{ viscous = -1.0 }", "friction.viscous"),
    ("{ mu = 0.2 }", "needs the pin/bearing radius"),
    ("{ radius = 0.01 }", "only used with 'mu' > 0"),
])
def test_scene_friction_errors_name_the_entry(table, message):
    with pytest.raises(SceneError, match="'A'") as err:
        loads_scene(_slider_crank(table, "{ viscous = 0.0 }"))
    assert message in str(err.value)


def test_prismatic_refuses_radius():
    with pytest.raises(SceneError, match="no radius"):
        loads_scene(_slider_crank("{ viscous = 0.0 }", "{ mu = 0.2, radius = 0.1 }"))


def test_reaction_friction_refused_where_not_solved():
    """ODE formulations and joint coordinates cannot give the friction its reaction: the
    error names the joint and the way out."""
    fa, fs = CASES["reaction"]
    mech = loads_scene(_slider_crank(_table(fa), _table(fs)))
    with pytest.raises(CompositionError, match=r"force 'A.friction'.*'index1'"):
        simulate(mech, 0.1, 10, formulation="kkt_ode")
    with pytest.raises((ModelError, SceneError), match=r"coordinates = 'absolute'"):
        inverse_dynamics(loads_scene(_slider_crank(_table(fa), _table(fs), "joint")), 0.1, 2)


def test_actuator_torque_equals_driver_torque_with_reaction_friction():
    """The mixed inverse problem (driver prescribes the motion, an actuator at the crank
    pivot produces it) iterates the same fixed point: the actuator torque equals the crank
    driver's effort to 1e-10 relative."""
    fa, fs = CASES["reaction"]
    mech = loads_scene(_slider_crank(_table(fa), _table(fs)))
    driven = inverse_dynamics(mech, 1.0, 20)["driver_efforts"][:, 0]
    mech.add_actuator("motor_torque", "O")
    mixed = inverse_dynamics(mech, 1.0, 20)["actuator_efforts"][:, 0]
    assert np.max(np.abs(mixed - driven)) <= 1e-10 * np.max(np.abs(driven))


def test_crank_friction_example_is_the_tested_mechanism():
    """examples/crank_friction.toml is the "reaction" case above: the same torque (1e-13)."""
    from pathlib import Path

    fa, fs = CASES["reaction"]
    path = Path(__file__).resolve().parents[2] / "examples" / "crank_friction.toml"
    example = inverse_dynamics(loads_scene(path.read_text()), 1.0, 10)["driver_efforts"]
    tested = inverse_dynamics(loads_scene(_slider_crank(_table(fa), _table(fs))), 1.0, 10)
    assert np.max(np.abs(example - tested["driver_efforts"])) <= 1e-13


@pytest.mark.parametrize("axis, loaded", [("vertical", False), ("horizontal", True)])
def test_spatial_bearing_counts_the_transverse_reaction_only(axis, loaded):
    """A 2 kg disc (I = 0.02 about its axis) spinning at 10 rad/s in a spatial revolute
    bearing through its centre, friction F_0 = 0.01 N m + μ r |R_⊥| (μ 0.1, r 0.02 m): with a
    vertical axis gravity is a thrust (axial, not counted) and ω falls at F_0 / I; with a
    horizontal axis R_⊥ = m g and ω falls at (F_0 + μ r m g) / I.  index1, 1 s: ω to 1e-6 of
    its drop (measured ≤ 1e-7 rad/s, the DAE's drift)."""
    quat = [1.0, 0.0, 0.0, 0.0] if axis == "vertical" else \
        [math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]  # body z along −y
    spin = [0.0, 0.0, 10.0] if axis == "vertical" else [0.0, -10.0, 0.0]
    direction = [0.0, 0.0, 1.0] if axis == "vertical" else [0.0, -1.0, 0.0]
    text = f'''
[scene]
name = "bearing"
dimension = 3
gravity = [0.0, 0.0, -{G}]
coordinates = "absolute"
[[bodies]]
name = "disc"
mass = 2.0
inertia = [0.01, 0.01, 0.02]
position = [0.0, 0.0, 0.0]
orientation = {quat!r}
angular_velocity = {spin!r}
[[joints]]
name = "bearing"
type = "revolute"
body1 = "ground"
body2 = "disc"
point = [0.0, 0.0, 0.0]
axis = {direction!r}
friction = {{ coulomb = 0.01, mu = 0.1, radius = 0.02, regularization = 1e-4 }}
'''
    res = simulate(loads_scene(text), 1.0, 10, formulation="index1", rtol=1e-10, atol=1e-12)
    level = 0.01 + (0.1 * 0.02 * 2.0 * G if loaded else 0.0)
    omega = res["joint_velocities"][:, 0]
    drop = level / 0.02 * res.t
    assert np.max(np.abs(omega - (10.0 - drop))) <= 1e-6 * drop[-1]


def test_reaction_friction_defaults_to_index1():
    """With friction that follows the joint reaction, a simulation without a named formulation
    takes the index-1 DAE (λ are its algebraic variables) instead of refusing: the shipped
    example runs from the CLI's defaults."""
    mech = load_scene(Path(__file__).resolve().parents[2] / "examples" / "crank_friction.toml")
    res = simulate(mech, 0.1, 5)
    assert res.stats["formulation"] == "index1"
    assert np.all(np.isfinite(res.arrays["q"]))
