"""The planar joint kind (space): a plate on a tilted planar joint to the ground under gravity
and a point force, against the Newton–Euler equations projected on the joint's three motions.

Closed form at the design pose (θ = 0) with rates (ẋ, ẏ, θ̇): the centre of mass is
r_G = P + x f + y g + Rot(h, θ) u (u = r_G0 − P), so a_G = ẍ f + ÿ g + θ̈ h × u − θ̇² u_⊥
(u_⊥ the part of u normal to h) and α·h = θ̈.  Projecting m a_G = F and
I α + ω × I ω = M_G on the virtual motions (f, 0), (g, 0), (h × u, h):

    m ẍ + m f·(h×u) θ̈ = f·F',   m ÿ + m g·(h×u) θ̈ = g·F',
    m (h×u)·f ẍ + m (h×u)·g ÿ + (m |h×u|² + hᵀ I h) θ̈ = (h×u)·F' + h·M_G,

F' = m g⃗ + F_ext + m θ̇² u_⊥, M_G = (r_F − r_G) × F_ext (h·(ω × I ω) = 0 for ω = θ̇ h).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import Mechanism
from casmbd.errors import ModelError, SceneError

COORDINATES = ("joint", "absolute", "natural")
MASS = 2.0
INERTIA = np.array([[0.05, 0.004, -0.003], [0.004, 0.08, 0.002], [-0.003, 0.002, 0.06]])
COM = np.array([0.3, -0.2, 1.0])
POINT = np.array([0.1, 0.1, 0.9])
AXIS = np.array([0.2, 1.0, 0.5]) / np.linalg.norm([0.2, 1.0, 0.5])
GRAVITY = np.array([0.0, 0.0, -9.81])
FORCE, FORCE_AT = np.array([3.0, -1.0, 2.0]), np.array([0.5, 0.0, 1.1])
RATES = np.array([0.4, -0.3, 1.5])  # ẋ, ẏ, θ̇


_cache = private_cache("cache_pl")


def plate(coordinates: str, rates=RATES) -> Mechanism:
    m = Mechanism(f"plate_{coordinates}", gravity=GRAVITY, dimension=3, coordinates=coordinates)
    joint_dirs = casmbd.model.spatial_joints.triad(AXIS)
    f, g, h = joint_dirs
    u = COM - POINT
    m.add_body("plate", MASS, [INERTIA[0, 0], INERTIA[1, 1], INERTIA[2, 2], INERTIA[0, 1],
                               INERTIA[0, 2], INERTIA[1, 2]], COM,
               velocity=rates[0] * f + rates[1] * g + rates[2] * np.cross(h, u),
               angular_velocity=rates[2] * h)
    m.add("planar", "slide", "ground", "plate", POINT, AXIS)
    m.add_force("push", "plate", FORCE.tolist(), point=FORCE_AT)
    return m


def closed_form(f, g, h, rates=RATES) -> np.ndarray:
    """(ẍ, ÿ, θ̈) at the design pose (module docstring)."""
    u = COM - POINT
    hu = np.cross(h, u)
    u_perp = u - (u @ h) * h
    force = MASS * GRAVITY + FORCE + MASS * rates[2] ** 2 * u_perp
    moment = np.cross(FORCE_AT - COM, FORCE)
    mat = np.array([[MASS, 0.0, MASS * f @ hu], [0.0, MASS, MASS * g @ hu],
                    [MASS * hu @ f, MASS * hu @ g, MASS * hu @ hu + h @ INERTIA @ h]])
    rhs = np.array([f @ force, g @ force, hu @ force + h @ moment])
    return np.linalg.solve(mat, rhs)


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_accelerations_match_the_closed_form(coordinates):
    """(ẍ, ÿ, θ̈) at t = 0 to 1e-10 (m/s², rad/s²); the rates start as given (1e-12)."""
    mech = plate(coordinates)
    joint = mech.joints["slide"]
    assert np.allclose([joint.f @ AXIS, joint.g @ AXIS, np.cross(joint.f, joint.g) @ AXIS],
                       [0, 0, 1], atol=1e-15)
    expect = closed_form(joint.f, joint.g, joint.h)
    res = casmbd.simulate(mech, t_end=0.01, steps=1, rtol=1e-12, atol=1e-14)
    assert res.names["joints"] == ["slide", "slide.y", "slide.angle"]
    acc = res["joint_accelerations"][0]
    assert np.max(np.abs(acc - expect)) < 1e-10, (acc, expect)
    assert np.max(np.abs(res["joint_velocities"][0] - RATES)) < 1e-12
    assert np.max(np.abs(expect)) > 1.0 and abs(expect[2]) > 1.0


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_motion_stays_in_the_plane(coordinates):
    """Over 1 s the constraints hold (≤ 1e-9), the plate's axis stays parallel to h and its
    point in the plane (1e-9); without the force the energy is constant (1e-8 J)."""
    mech = plate(coordinates)
    del mech.forces["push"]
    res = casmbd.simulate(mech, t_end=1.0, steps=100, rtol=1e-11)
    assert np.max(res["constraint_violation"]) < 1e-9
    assert np.ptp(res["total_energy"]) < 1e-8
    assert np.ptp(res["joint_positions"][:, 2]) > 1.0  # it really turns
    rot = res["rotation_matrices"].reshape(-1, 3, 3)
    assert np.max(np.abs(rot @ AXIS - AXIS)) < 1e-9
    com = res["body_positions"]
    point = com - rot @ (COM - POINT)
    assert np.max(np.abs((point - POINT) @ AXIS)) < 1e-9


def test_coordinate_choices_agree():
    """Joint, absolute and natural coordinates give the same motion over 1 s (1e-8 m)."""
    runs = {c: casmbd.simulate(plate(c), t_end=1.0, steps=50, rtol=1e-11)
            for c in COORDINATES}
    for c in ("absolute", "natural"):
        assert np.max(np.abs(runs[c]["body_positions"] - runs["joint"]["body_positions"])) \
            < 1e-8
        assert np.max(np.abs(runs[c]["joint_positions"] - runs["joint"]["joint_positions"])) \
            < 1e-8


@pytest.mark.parametrize("formulation", ["articulated", "augmented_lagrangian"])
def test_joint_coordinates_in_both_formulations(formulation):
    """The three rates are independent: the articulated-body recursion serves the plate in
    joint coordinates (as does the augmented Lagrangian), both at the closed form (1e-10)."""
    mech = plate("joint")
    joint = mech.joints["slide"]
    res = casmbd.simulate(mech, t_end=0.01, steps=1, formulation=formulation, rtol=1e-12,
                          atol=1e-14)
    expect = closed_form(joint.f, joint.g, joint.h)
    assert np.max(np.abs(res["joint_accelerations"][0] - expect)) < 1e-10


def test_driver_and_scene_and_errors():
    """Drivers on x and on the angle (the angle's wrapped residual) hold them; the scene build
    equals the Python build; named errors for a planar joint in the plane and a bad key."""
    mech = plate("joint")
    mech.add_driver("dx", "0.2*t", joint="slide", coordinate="x")
    mech.add_driver("da", "3*t", joint="slide", coordinate="angle")
    res = casmbd.simulate(mech, t_end=1.0, steps=10, rtol=1e-11)
    assert np.max(np.abs(res["joint_positions"][:, 0] - 0.2 * res.t)) < 1e-9
    wrapped = np.angle(np.exp(1j * 3 * res.t))
    assert np.max(np.abs(res["joint_positions"][:, 2] - wrapped)) < 1e-9
    scene = ('[scene]\nname = "p"\ndimension = 3\ngravity = [0, 0, -9.81]\n'
             '[[bodies]]\nname = "plate"\nmass = 2.0\ninertia = [0.05, 0.08, 0.06, 0.004, '
             '-0.003, 0.002]\nposition = [0.3, -0.2, 1.0]\n'
             '[[joints]]\nname = "slide"\ntype = "planar"\nbody1 = "ground"\nbody2 = "plate"\n'
             f'point = {POINT.tolist()}\naxis = [0.2, 1.0, 0.5]\n')
    from_scene = casmbd.loads_scene(scene).joints["slide"]
    python = plate("joint", rates=np.zeros(3)).joints["slide"]
    for key in ("point", "axis", "f", "g", "h"):
        assert np.max(np.abs(getattr(from_scene, key) - getattr(python, key))) < 1e-15
    with pytest.raises(SceneError, match=r"\('slide'\) key 'angle': unknown key \(allowed: axis"):
        casmbd.loads_scene(scene + "angle = 1.0\n")
    flat = Mechanism("flat")
    flat.add_body("b", 1.0, 1.0, (0.0, 0.0))
    with pytest.raises(ModelError, match="planar"):
        flat.add("planar", "p", "ground", "b", (0.0, 0.0), (0.0, 0.0, 1.0))
    with pytest.raises(ModelError, match=r"joint 'q' field 'axis': must not be the zero"):
        plate("joint").add("planar", "q", "ground", "plate", POINT, (0.0, 0.0, 0.0))
