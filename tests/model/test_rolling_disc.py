"""The spatial rolling disc (``rolling_disc``, :mod:`casmbd.model.rolling_disc`) against closed
forms: a uniform thin disc of mass m and radius R (moments of inertia A = m R²/4 about a
diameter, C = m R²/2 about the axle) rolling without slipping on a horizontal plane.

Steady turning (O'Reilly, "The dynamics of rolling disks and sliding disks", Nonlinear Dynamics
10 (1996) 287–305; Neimark & Fufaev, *Dynamics of Nonholonomic Systems*, AMS 1972):
with θ the lean from the upright, Ω the heading (precession) rate and v = R ω_a the speed of
the centre (ω_a = ω·a the angular velocity about the axle a), the steady motions satisfy

    m g R sin θ = Ω cos θ (A Ω sin θ − (C + m R²) ω_a),

derived here by Newton–Euler about the centre in the frame (t, a, d) that turns at Ω about the
vertical (d = the disc's upward in-plane direction, t = a × d the direction of rolling): the
contact force F = m v Ω e_y + m g e_z (the centre's circular acceleration and the weight) has
the moment −R d × F = Ω e_z × H about the centre, H = C ω_a a + A Ω cos θ d.  For the uniform
disc: g sin θ = Ω cos θ (R Ω sin θ / 4 − 3 v / 2).

Upright rolling at speed v (the same Newton–Euler, linearised in the lean): the lean obeys
(A + m R²) θ̈ = (m g R − C (C + m R²) v² / (A R²)) θ, so for the uniform disc
θ̈ = λ² θ with λ² = 4 g / (5 R) − 12 v² / (5 R²): upright rolling is stable above the critical
speed v_c² = g R / 3 (oscillation at ω = √(−λ²)) and falls below (growth at λ).

Every run uses CasADi's virtual machine (no compile) and lasts a fraction of a second.
"""

from __future__ import annotations

import numpy as np
import pytest
from rolling_disc_scenes import (
    A_DIA,
    C_AX,
    MASS,
    OMEGA,
    THETA,
    G,
    R,
    disc,
    motion,
    steady_speed,
    upright,
)

import casmbd
from casmbd.errors import ModelError, SceneError
from casmbd.io.scene import loads_scene


def run(mech, t_end=3.0, steps=30, formulation="index1", rtol=1e-12):
    return casmbd.simulate(mech, t_end, steps, formulation=formulation, mode="vm", rtol=rtol,
                           atol=1e-12)


# ----------------------------------------------------------------------- steady turning
STEADY_CELLS = [(c, f) for c in ("absolute", "joint", "natural")
                for f in ("index1", "kkt_ode", "augmented_lagrangian")
                # a thin disc is a lamina: its constant natural-coordinate mass matrix is
                # singular (no second moment along the axle), which kkt_ode inverts
                if (c, f) != ("natural", "kkt_ode")]


@pytest.mark.parametrize("coordinates,formulation", STEADY_CELLS)
def test_steady_turning_stays_steady(coordinates, formulation):
    """Started on the closed-form relation, lean, heading rate and spin stay constant: |θ − θ₀|
    and |ω·a − v/R| within 1e-8 and |ψ − Ω t| within 1e-8 over 3 s (rtol 1e-12; observed
    ≤ 7e-9), in Euler parameters (absolute), with the disc a floating root of joint
    coordinates and in natural coordinates; the constraints hold to 1e-9 (observed ≤ 5e-11)."""
    v = steady_speed(THETA, OMEGA)
    res = run(disc(THETA, OMEGA, v, coordinates), formulation=formulation)
    lean, heading, spin = motion(res)
    assert res.stats["coordinates"] == coordinates
    assert np.max(np.abs(lean - THETA)) < 1e-8
    assert np.max(np.abs(heading - OMEGA * res.t)) < 1e-8
    assert np.max(np.abs(spin - v / R)) < 1e-8
    assert np.max(res["constraint_violation"]) < 1e-9
    assert np.max(res["velocity_violation"]) < 1e-9


def test_steady_turning_with_ggl():
    """The GGL index-2 DAE (IDAS) keeps the turn steady too, at its workable tolerances
    rtol = atol = 1e-10 (at atol 1e-12 its corrector fails at t = 0, as it does for pendulum
    chains: the iteration matrix grows like 1/h²): lean and spin within 1e-6, heading within
    1e-5 over 3 s (observed 1.1e-7, 1.0e-6), energy within 1e-7 (observed 1.3e-8)."""
    v = steady_speed(THETA, OMEGA)
    res = casmbd.simulate(disc(THETA, OMEGA, v), 3.0, 30, formulation="ggl", mode="vm",
                          rtol=1e-10, atol=1e-10)
    lean, heading, spin = motion(res)
    energy = res["total_energy"]
    assert np.max(np.abs(lean - THETA)) < 1e-6
    assert np.max(np.abs(spin - v / R)) < 1e-6
    assert np.max(np.abs(heading - OMEGA * res.t)) < 1e-5
    assert np.max(np.abs(energy / energy[0] - 1.0)) < 1e-7


def test_off_the_relation_is_not_steady():
    """The same start with Ω 5 % too fast for its speed is no steady motion: the lean swings
    by more than 1e-3 rad within 3 s (10⁵ times the steady test's tolerance)."""
    v = steady_speed(THETA, OMEGA)
    lean, _, _ = motion(run(disc(THETA, 1.05 * OMEGA, v)))
    assert np.max(np.abs(lean - THETA)) > 1e-3


def test_steady_turning_tyre_forces_and_reaction():
    """The contact force of the steady turn is F = m v Ω e_y' + m g e_z (e_y' the horizontal
    axle direction, turning at Ω): the multipliers give N = −λ_contact = m g,
    F_long = −λ_longitudinal = 0 and F_lat = −λ_lateral = m v Ω (1e-9); the reaction at the
    wheel centre is F and the moment (P − c) × F, P − c = −R d (1e-9), in both choices."""
    v = steady_speed(THETA, OMEGA)
    for coordinates in ("absolute", "joint"):
        res = run(disc(THETA, OMEGA, v, coordinates), t_end=1.0, steps=4)
        labels = res.names["constraints"]
        rows = [labels.index(f"joint 'roll' equation '{lab}'")
                for lab in ("contact", "longitudinal", "lateral")]
        tyre = -res["lambda"][:, rows]
        np.testing.assert_allclose(tyre[:, 0], MASS * G, atol=1e-9)
        np.testing.assert_allclose(tyre[:, 1], 0.0, atol=1e-9)
        np.testing.assert_allclose(tyre[:, 2], MASS * v * OMEGA, atol=1e-9)
        psi = OMEGA * res.t
        e_y = np.stack([-np.sin(psi), np.cos(psi), 0 * psi], axis=1)
        force = MASS * v * OMEGA * e_y + [0.0, 0.0, MASS * G]
        down = np.cos(THETA) * np.array([0, 0, 1.0]) - np.sin(THETA) * e_y  # = d
        reaction = res["joint_reactions"][:, 0, :]
        np.testing.assert_allclose(reaction[:, :3], force, atol=1e-9)
        np.testing.assert_allclose(reaction[:, 3:], np.cross(-R * down, force), atol=1e-9)


@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
def test_turning_on_a_moving_deck(coordinates):
    """The plane on a moving body (body1 = a deck driven along x at u = 0.7 m/s, its origin
    elsewhere on the plane): by Galilean invariance the wheel turns steadily as on the ground,
    its centre displaced by u t (1e-8) and its reaction the same (1e-7)."""
    u, v = 0.7, steady_speed(THETA, OMEGA)
    mech = casmbd.Mechanism("deck", gravity=(0.0, 0.0, -G), coordinates=coordinates)
    a = np.array([0.0, np.cos(THETA), np.sin(THETA)])
    d = np.array([0.0, -np.sin(THETA), np.cos(THETA)])
    mech.add_body("deck", mass=5.0, inertia=[1.0, 1.0, 1.0], position=(0.0, 0.0, -0.1),
                  velocity=(u, 0.0, 0.0))
    mech.add_prismatic("rail", "ground", "deck", point=(0.0, 0.0, -0.1), axis=(1.0, 0.0, 0.0))
    mech.add_driver("move", joint="rail", position=f"{u}*t")
    mech.add_body("wheel", mass=MASS, inertia=[A_DIA, C_AX, A_DIA], position=R * d,
                  velocity=(v + u, 0.0, 0.0), angular_velocity=(v / R) * a +
                  OMEGA * np.cos(THETA) * d,
                  orientation=[np.cos(THETA / 2), np.sin(THETA / 2), 0.0, 0.0])
    mech.add_rolling_disc("roll", "deck", "wheel", point=R * d, radius=R, axis=a,
                          origin=(1.0, 2.0, 0.0), normal=(0.0, 0.0, 1.0))
    res = run(mech)
    ref = run(disc(THETA, OMEGA, v, coordinates))
    shift = res.body("wheel")["position"] - ref.body("wheel")["position"]
    np.testing.assert_allclose(shift, np.outer(res.t, [u, 0.0, 0.0]), atol=1e-8)
    k = res.names["all_joints"].index("roll")
    np.testing.assert_allclose(res["joint_reactions"][:, k], ref["joint_reactions"][:, 0],
                               atol=1e-7)


# ----------------------------------------------------------------------- free rolling
@pytest.mark.parametrize("formulation,tol", [("augmented_lagrangian", 1e-10),
                                             ("index1", 1e-9), ("kkt_ode", 1e-9)])
def test_free_rolling_conserves_energy_and_keeps_the_constraints(formulation, tol):
    """A wobbling, turning disc off any steady motion (lean 0.4 rad, lean rate 1.5 rad/s):
    rolling is workless, so the total energy stays at its start over 3 s (rtol 1e-13), to
    1e-10 relative with the default augmented Lagrangian (observed 1.7e-11, whose
    stabilisation keeps the rows within 1e-11) and 1e-9 with the unstabilised index-1 DAE and
    KKT ODE (observed ≤ 6e-10, their drift of the rows dominating); the contact stays closed
    and the contact point does not slip (position and velocity rows within ``tol``); absolute
    and joint coordinates give the same motion of the centre (1e-7)."""
    runs = {}
    for coordinates in ("absolute", "joint"):
        res = run(disc(0.4, 1.0, 1.2, coordinates, lean_rate=1.5), steps=60,
                  formulation=formulation, rtol=1e-13)
        energy = res["total_energy"]
        assert np.max(np.abs(energy / energy[0] - 1.0)) < tol
        assert np.max(res["constraint_violation"]) < tol
        assert np.max(res["velocity_violation"]) < tol
        lean, _, _ = motion(res)
        assert np.ptp(lean) > 0.1  # it does wobble
        runs[coordinates] = res.body("wheel")["position"]
    np.testing.assert_allclose(runs["absolute"], runs["joint"], atol=1e-7)


# ----------------------------------------------------------------------- critical speed
@pytest.mark.parametrize("factor", [1.2, 0.8])
def test_critical_speed_of_upright_rolling(factor):
    """v_c² = g R / 3: at 1.2 v_c the lean oscillates at ω = √(−λ²), at 0.8 v_c it grows as
    sinh(λ t), λ² = 4 g / (5 R) − 12 v² / (5 R²) (module docstring); the lean after a kick
    of lean rate θ̇₀ follows θ̇₀ sin(ω t)/ω (resp. θ̇₀ sinh(λ t)/λ) to 1e-4 of its largest
    value over 2 s (the kick keeps it linear: |θ| < 1e-3).  Checked by simulation (the
    steady-motion linearisation is another helper's)."""
    v = factor * np.sqrt(G * R / 3)
    kick = 1e-5
    res = run(upright(v, 5 * kick), t_end=2.0, steps=200, rtol=1e-11)
    lean, _, _ = motion(res)
    lam2 = 4 * G / (5 * R) - 12 * v * v / (5 * R * R)
    if factor > 1:
        assert lam2 < 0
        rate = np.sqrt(-lam2)
        expected = kick * np.sin(rate * res.t) / rate
    else:
        assert lam2 > 0
        rate = np.sqrt(lam2)
        expected = kick * np.sinh(rate * res.t) / rate
    assert np.max(np.abs(lean)) < 1e-3
    np.testing.assert_allclose(lean, expected, atol=1e-4 * np.max(np.abs(expected)))


def test_falls_below_and_stays_up_above_the_critical_speed():
    """The same kick (lean rate 2e-3 rad/s) over 4 s: at 0.8 v_c the disc falls past 0.05 rad;
    at 1.2 v_c it stays within 1e-3 rad of the upright."""
    vc = np.sqrt(G * R / 3)
    slow, _, _ = motion(run(upright(0.8 * vc, 1e-2), t_end=4.0, steps=40, rtol=1e-10))
    fast, _, _ = motion(run(upright(1.2 * vc, 1e-2), t_end=4.0, steps=40, rtol=1e-10))
    assert np.max(np.abs(slow)) > 0.05
    assert np.max(np.abs(fast)) < 1e-3


# ----------------------------------------------------------------------- bad input
def _mech():
    mech = casmbd.Mechanism("bad", gravity=(0.0, 0.0, -G))
    mech.add_body("wheel", mass=1.0, inertia=[A_DIA, C_AX, A_DIA], position=(0.0, 0.0, R))
    return mech


GOOD = {"point": (0.0, 0.0, R), "axis": (0.0, 1.0, 0.0), "radius": R,
        "origin": (0.0, 0.0, 0.0), "normal": (0.0, 0.0, 1.0)}


@pytest.mark.parametrize("change,field,words", [
    ({"radius": 0.0}, "radius", "must be > 0"),
    ({"radius": -0.3}, "radius", "must be > 0"),
    ({"radius": float("nan")}, "radius", "finite"),
    ({"axis": (0.0, 0.0, 2.0)}, "axis", "along the plane's normal"),
    ({"axis": (0.0, 0.0, 0.0)}, "axis", "zero vector"),
    ({"normal": (0.0, 0.0, 0.0)}, "normal", "zero vector"),
    ({"point": (0.0, 0.0, 0.35)}, "point", "0.05 above the plane"),
    ({"point": (0.0, 0.0, -R)}, "point", "below the plane"),
    ({"point": (0.0, 0.0)}, "point", "3 numbers"),
    ({"origin": (0.0, 0.0, 0.01)}, "point", "below the plane"),
])
def test_bad_input_is_named(change, field, words):
    mech = _mech()
    with pytest.raises(ModelError) as err:
        mech.add_rolling_disc("roll", "ground", "wheel", **{**GOOD, **change})
    assert f"joint 'roll' field '{field}'" in str(err.value)
    assert words in str(err.value)


def test_bad_bodies_are_named():
    mech = _mech()
    with pytest.raises(ModelError, match=r"joint 'roll' field 'body2'.*moving body"):
        mech.add_rolling_disc("roll", "wheel", "ground", **GOOD)
    with pytest.raises(ModelError, match=r"joint 'roll' field 'body1'.*unknown body 'floor'"):
        mech.add_rolling_disc("roll", "floor", "wheel", **GOOD)
    planar = casmbd.Mechanism("flat", gravity=(0.0, -G))
    planar.add_body("wheel", mass=1.0, inertia=0.1, position=(0.0, R))
    if 2 not in casmbd.model.JOINT_KINDS["rolling_disc"]:  # the planar kind is another's
        with pytest.raises(ModelError, match=r"joint 'roll'.*spatial mechanism"):
            planar.add("rolling_disc", "roll", "ground", "wheel", point=(0.0, R), radius=R)


SCENE = """
[scene]
name = "disc"
dimension = 3
gravity = [0.0, 0.0, -9.81]

[[bodies]]
name = "rear_wheel"
mass = 1.0
inertia = [0.0225, 0.045, 0.0225]
position = [0.0, 0.0, 0.3]
velocity = [1.0, 0.0, 0.0]
angular_velocity = [0.0, 3.3333333333333335, 0.0]

[[joints]]
name = "rear_contact"
type = "rolling_disc"
body1 = "ground"
body2 = "rear_wheel"
point = [0.0, 0.0, 0.3]
axis = [0.0, 1.0, 0.0]
radius = 0.3
origin = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
"""


def test_scene_contract_loads_and_rolls():
    """The scene of the issue's contract: an upright wheel rolling at 1 m/s goes 1 m in 1 s
    at constant height (1e-9), its normal load is m g."""
    mech = loads_scene(SCENE)
    joint = mech.joints["rear_contact"]
    assert joint.needs == frozenset({"velocity_constraints"})
    res = run(mech, t_end=1.0, steps=4)
    pos = res.body("rear_wheel")["position"]
    np.testing.assert_allclose(pos[:, 0], res.t, atol=1e-9)
    np.testing.assert_allclose(pos[:, 2], 0.3, atol=1e-9)
    np.testing.assert_allclose(res["joint_reactions"][:, 0, 2], 9.81, atol=1e-9)


@pytest.mark.parametrize("line,key,words", [
    ("radius = 0.3", "radius", "missing required key"),
    ("axis = [0.0, 1.0, 0.0]", "axis", "missing required key"),
])
def test_scene_keys_are_named(line, key, words):
    with pytest.raises(SceneError, match=f"key '{key}': {words}"):
        loads_scene(SCENE.replace(line, ""))


def test_origin_and_normal_default_to_the_xy_plane():
    mech = loads_scene(SCENE.replace("origin = [0.0, 0.0, 0.0]", "")
                       .replace("normal = [0.0, 0.0, 1.0]", ""))
    joint = mech.joints["rear_contact"]
    np.testing.assert_array_equal(joint.origin, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(joint.normal, [0.0, 0.0, 1.0])


def test_unknown_scene_key_is_named():
    with pytest.raises(SceneError) as err:
        loads_scene(SCENE.replace("radius = 0.3", "radius = 0.3\ntyre = 1.0"))
    assert "'rear_contact'" in str(err.value) and "'tyre'" in str(err.value)
