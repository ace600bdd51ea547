"""Every analysis on spatial mechanisms: planar motion reproduced in 3-D, formulations against
each other, linearization against closed forms, inverse dynamics against the energy balance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import Mechanism

G = 9.81


_cache = private_cache("cache3d")


def double_pendulum(dimension: int, coordinates: str = "absolute") -> Mechanism:
    """Two rods (1 m, 1 kg) in the x–y plane pinned about z, released from horizontal.

    In 3-D the rods have a small inertia about their own axis and the pins are spatial revolute
    joints about z: the motion is planar and must equal the planar model's.
    """
    gravity = (0.0, -G) if dimension == 2 else (0.0, -G, 0.0)
    m = Mechanism(f"dp{dimension}{coordinates[0]}", gravity=gravity, coordinates=coordinates)
    i_t = 1.0 / 12.0
    for k in range(2):
        pos = (k + 0.5, 0.0) if dimension == 2 else (k + 0.5, 0.0, 0.0)
        inertia = i_t if dimension == 2 else [1e-3, i_t, i_t]
        m.add_body(f"rod{k}", mass=1.0, inertia=inertia, position=pos)
    axis = None if dimension == 2 else (0.0, 0.0, 1.0)
    zero = (0.0,) * dimension
    one = (1.0,) + (0.0,) * (dimension - 1)
    m.add_revolute("shoulder", "ground", "rod0", point=zero, axis=axis)
    m.add_revolute("elbow", "rod0", "rod1", point=one, axis=axis)
    return m


@pytest.mark.parametrize("coordinates", ["absolute", "natural"])
def test_planar_motion_reproduced_in_space(coordinates):
    """A spatial double pendulum with parallel z axes moves like the planar one (1e-8 m)."""
    planar = casmbd.simulate(double_pendulum(2), t_end=2.0, steps=40, rtol=1e-12)
    spatial = casmbd.simulate(double_pendulum(3, coordinates), t_end=2.0, steps=40, rtol=1e-12)
    xy = planar["body_positions"]
    xyz = spatial["body_positions"]
    assert np.max(np.abs(xyz[:, [0, 1, 3, 4]] - xy)) < 1e-8
    assert np.max(np.abs(xyz[:, [2, 5]])) < 1e-10
    # the rotation about z equals the planar angle
    rot = spatial["rotation_matrices"].reshape(len(spatial.t), 2, 3, 3)
    angle = np.arctan2(rot[:, 1, 1, 0], rot[:, 1, 0, 0])
    diff = np.angle(np.exp(1j * (angle - planar["angle_positions"][:, 1])))
    assert np.max(np.abs(diff)) < 1e-8
    # joint reactions: planar (Fx, Fy, M) equal the spatial (Fx, Fy, Mz); the rest vanish
    rp = planar["joint_reactions"]
    rs = spatial["joint_reactions"]
    assert np.max(np.abs(rs[:, :, [0, 1, 5]] - rp)) < 1e-6
    assert np.max(np.abs(rs[:, :, [2, 3, 4]])) < 1e-6


def rssr(coordinates: str = "absolute") -> Mechanism:
    """A spatial four-bar: crank on a z pin, rocker on an x pin, a coupler with two ball joints.

    The coupler's spin about its own axis is an idle degree of freedom (two spherical ends),
    so the mechanism has 2 DOF; the crank carries an initial speed, gravity acts along −z.
    """
    m = Mechanism(f"rssr_{coordinates}", gravity=(0.0, 0.0, -G), coordinates=coordinates)
    a = np.array([0.0, 0.0, 0.0])        # crank pivot
    b = np.array([0.3, 0.0, 0.0])        # crank pin
    d = np.array([0.6, 0.5, 0.0])        # rocker pivot
    c = np.array([0.6, 0.5, 0.35])       # rocker pin
    m.add_body("crank", 1.0, [1e-3, 0.01, 0.01], (a + b) / 2, angular_velocity=(0.0, 0.0, 4.0),
               velocity=(0.0, 0.6, 0.0))
    m.add_body("coupler", 1.5, [5e-3, 0.05, 0.05], (b + c) / 2)
    m.add_body("rocker", 1.0, [0.01, 0.01, 1e-3], (c + d) / 2)
    m.add_revolute("pivot_a", "ground", "crank", point=a, axis=(0.0, 0.0, 1.0))
    m.add_spherical("ball_b", "crank", "coupler", point=b)
    m.add_spherical("ball_c", "coupler", "rocker", point=c)
    m.add_revolute("pivot_d", "ground", "rocker", point=d, axis=(1.0, 0.0, 0.0))
    return m


def test_rssr_has_two_degrees_of_freedom():
    report = casmbd.info(rssr())
    assert report["degrees_of_freedom"] == 2
    assert report["redundant_equations"] == []


@pytest.mark.parametrize("formulation", ["kkt_ode", "index1", "partitioning", "nullspace"])
def test_formulations_agree_on_a_spatial_loop(formulation):
    """All formulations reach the reference end state of the RSSR loop (1e-6 m)."""
    ref = casmbd.simulate(rssr(), t_end=0.5, steps=5, rtol=1e-11)
    out = casmbd.simulate(rssr(), t_end=0.5, steps=5, rtol=1e-9, formulation=formulation)
    assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-6
    assert np.max(out["constraint_violation"]) < 1e-6


def test_natural_coordinates_on_a_spatial_loop():
    ref = casmbd.simulate(rssr(), t_end=0.5, steps=5, rtol=1e-12)
    nat = casmbd.simulate(rssr("natural"), t_end=0.5, steps=5, rtol=1e-12)
    assert np.max(np.abs(nat["body_positions"] - ref["body_positions"])) < 1e-8


@pytest.mark.parametrize("coordinates", ["absolute", "natural"])
def test_spatial_pendulum_frequency(coordinates):
    """Compound pendulum on a horizontal revolute axis: f = √(m g d / I_O) / 2π (1e-9)."""
    m = Mechanism(f"pend_{coordinates}", gravity=(0.0, 0.0, -G), coordinates=coordinates)
    length, i_t = 1.0, 1.0 / 12.0
    m.add_body("rod", 1.0, [i_t, i_t, 1e-3], (0.0, 0.0, -length / 2))
    m.add_revolute("pin", "ground", "rod", point=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0))
    lin = casmbd.linearize(m)
    expected = math.sqrt(G * length / 2 / (i_t + length**2 / 4)) / (2 * math.pi)
    assert lin.n_dof == 1
    assert abs(lin.frequencies_hz[0] - expected) < 1e-9


def test_double_pendulum_frequencies_match_planar():
    """Hanging spatial double pendulum (z pins) has the planar model's two frequencies."""
    def hanging(dimension):
        gravity = (0.0, -G) if dimension == 2 else (0.0, -G, 0.0)
        m = Mechanism(f"hdp{dimension}", gravity=gravity)
        i_t = 1.0 / 12.0
        axis = None if dimension == 2 else (0.0, 0.0, 1.0)
        for k in range(2):
            if dimension == 2:
                m.add_body(f"rod{k}", 1.0, i_t, (0.0, -k - 0.5), angle=-math.pi / 2)
            else:
                m.add_body(f"rod{k}", 1.0, [1e-3, i_t, i_t], (0.0, -k - 0.5, 0.0),
                           euler_zxz=(-math.pi / 2, 0.0, 0.0))
        m.add_revolute("shoulder", "ground", "rod0", point=(0.0,) * dimension, axis=axis)
        m.add_revolute("elbow", "rod0", "rod1", point=(0.0, -1.0) + (0.0,) * (dimension - 2),
                       axis=axis)
        return m

    planar = casmbd.linearize(hanging(2))
    spatial = casmbd.linearize(hanging(3))
    assert np.allclose(np.sort(spatial.frequencies_hz), np.sort(planar.frequencies_hz),
                       rtol=0, atol=1e-9)


def spatial_slider_crank() -> Mechanism:
    """Crank (z pin) drives a slider along x through a rod with a ball and a universal joint."""
    m = Mechanism("ssc_inv", gravity=(0.0, 0.0, -G))
    m.add_body("crank", 1.0, [0.002, 0.01, 0.01], (0.05, 0.0, 0.0))
    m.add_body("rod", 0.8, [0.02, 0.02, 5e-4], (0.25, 0.0, 0.05))
    m.add_body("slider", 2.0, [0.01, 0.01, 0.01], (0.4, 0.0, 0.1))
    m.add_revolute("pin", "ground", "crank", point=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0))
    m.add_spherical("ball", "crank", "rod", point=(0.1, 0.0, 0.0))
    m.add_universal("cross", "rod", "slider", point=(0.4, 0.0, 0.1), axis1=(0.0, 1.0, 0.0),
                    axis2=(1.0, 0.0, -0.75))
    m.add_prismatic("guide", "ground", "slider", point=(0.4, 0.0, 0.1), axis=(1.0, 0.0, 0.0))
    m.add_driver("motor", "2*pi*t", joint="pin")
    return m


def test_spatial_inverse_dynamics_energy_balance():
    """∫ τ φ̇ dt = ΔE over a crank turn of the spatial slider-crank (Simpson, 1e-7 relative)."""
    res = casmbd.inverse_dynamics(spatial_slider_crank(), t_end=1.0, steps=400)
    tau = res.arrays["driver_efforts"][:, 0]
    power = tau * 2 * math.pi
    h = res.t[1] - res.t[0]
    work = h / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
    energy = res.arrays["kinetic_energy"] + res.arrays["potential_energy"]
    scale = float(np.max(np.abs(power))) * res.t[-1]
    assert abs(work - (energy[-1] - energy[0])) < 1e-7 * scale
    # and the instantaneous balance through the sampled energy (central differences)
    de = (energy[2:] - energy[:-2]) / (2 * h)
    assert np.max(np.abs(de - power[1:-1])) < 1e-3 * float(np.max(np.abs(power)))
    # reactions have force and moment in space
    assert res.arrays["joint_reactions"].shape == (401, 4, 6)


def test_euler_angle_output_and_singularity_warning():
    """Result.euler_angles: the X–Y–Z set of a rotation about z is (0, 0, planar angle) to
    1e-8 with no warning; the Z–X–Z set is singular there (θ = 0) and says so once, naming the
    body and the time, while still reproducing the rotation matrix to 1e-10."""
    import warnings

    from casmbd.errors import AnalysisError
    from casmbd.model import rotations

    planar = casmbd.simulate(double_pendulum(2), t_end=1.0, steps=10, rtol=1e-12)
    spatial = casmbd.simulate(double_pendulum(3), t_end=1.0, steps=10, rtol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        xyz = spatial.euler_angles("rod1", "xyz")
    assert xyz.shape == (11, 3)
    assert np.max(np.abs(xyz[:, :2])) < 1e-8
    diff = np.angle(np.exp(1j * (xyz[:, 2] - planar["angle_positions"][:, 1])))
    assert np.max(np.abs(diff)) < 1e-8
    with pytest.warns(RuntimeWarning, match=r"body 'rod1'.*ZXZ.*t = 0") as record:
        zxz = spatial.euler_angles("rod1")
    assert len(record) == 1
    rot = spatial.body("rod1")["rotation"]
    for k in range(len(zxz)):
        back = rotations.rotation_matrix(rotations.euler_zxz_to_quaternion(*zxz[k]))
        assert np.max(np.abs(np.asarray(back, dtype=float) - rot[k])) < 1e-10
    with pytest.raises(AnalysisError, match="planar"):
        planar.euler_angles("rod1")
    with pytest.raises(AnalysisError, match="sequence"):
        spatial.euler_angles("rod1", "yxz")
