"""The gear (coupler) kind, c₂ − c₂⁰ = r (c₁ − c₁⁰), in every coordinate choice, planar and
spatial: a pair of pendulums on parallel pivots coupled by a gear of ratio r = −2.

Closed form: with φ the rotation of pendulum 1 from hanging, pendulum 2 turns by rφ, so
V = −m₁ g l₁ cos φ − m₂ g l₂ cos rφ and T = ½ (I₁ + r² I₂) φ̇² (I about the pivots): small
oscillations have ω² = (m₁ g l₁ + r² m₂ g l₂) / (I₁ + r² I₂); a torque T₁ on pendulum 1 holds
it at φ where T₁ = m₁ g l₁ sin φ + r m₂ g l₂ sin rφ, the gear's moment on pendulum 2 then
balancing its weight, M = m₂ g l₂ sin rφ.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import Mechanism
from casmbd.errors import ModelError, SceneError

G = 9.81
RATIO = -2.0
M1, L1, M2, L2 = 1.0, 1.0, 1.5, 0.6
PIVOT2 = 2.0
COORDINATES = ("absolute", "natural", "joint")


_cache = private_cache("cache_gear")


def gear_pair(coordinates: str, dim: int, rate: float = 0.0, torque: float | None = None,
              ratio: float = RATIO) -> Mechanism:
    """Two rods hanging from pivots at x = 0 and x = 2 (axes along z), pendulum 1 turning at
    ``rate``, pendulum 2 at ``ratio * rate``; optionally a torque on rod 1."""
    gravity = (0.0, -G) if dim == 2 else (0.0, -G, 0.0)
    m = Mechanism(f"gear_{coordinates}_{dim}", gravity=gravity, coordinates=coordinates)
    pad = () if dim == 2 else (0.0,)
    for name, px, mass, length, w in (("rod1", 0.0, M1, L1, rate),
                                      ("rod2", PIVOT2, M2, L2, ratio * rate)):
        half = 0.5 * length
        pos, vel = (px, -half, *pad), (w * half, 0.0, *pad)
        inertia = mass * length**2 / 12
        if dim == 2:
            m.add_body(name, mass=mass, inertia=inertia, position=pos, velocity=vel,
                       angular_velocity=w)
        else:
            m.add_body(name, mass=mass, inertia=[inertia, 1e-3, inertia], position=pos,
                       velocity=vel, angular_velocity=(0.0, 0.0, w))
    axis = None if dim == 2 else (0.0, 0.0, 1.0)
    m.add_revolute("pin1", "ground", "rod1", (0.0, 0.0, *pad), axis=axis)
    m.add_revolute("pin2", "ground", "rod2", (PIVOT2, 0.0, *pad), axis=axis)
    m.add_gear("gear", "pin1", "pin2", ratio=ratio)
    if torque is not None:
        m.add_torque("motor", "rod1", torque if dim == 2 else (0.0, 0.0, torque))
    return m


def omega_closed_form(ratio: float = RATIO) -> float:
    i1, i2 = M1 * L1**2 / 3, M2 * L2**2 / 3
    k1, k2 = M1 * G * L1 / 2, M2 * G * L2 / 2
    return math.sqrt((k1 + ratio**2 * k2) / (i1 + ratio**2 * i2))


@pytest.fixture(scope="module")
def runs():
    """2.5 s of the pair started at 2 rad/s (amplitudes 0.43 and 0.86 rad), every choice."""
    out = {}
    for dim in (2, 3):
        for coords in COORDINATES:
            out[dim, coords] = casmbd.simulate(gear_pair(coords, dim, rate=2.0), t_end=2.5,
                                               steps=250, rtol=1e-11)
    return out


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("coordinates", COORDINATES)
def test_gear_holds_and_energy_is_conserved(runs, dim, coordinates):
    """|Δc₂ − r Δc₁| ≤ 1e-9 rad along the run (measured ≤ 2e-11); total energy (−7.21 J,
    kinetic energy swinging by more than 1 J) constant to 1e-8 J (measured ≤ 8e-10); the
    pendulums really swing (0.44 rad)."""
    res = runs[dim, coordinates]
    assert res.names["joints"] == ["pin1", "pin2"]
    c = res["joint_positions"] - res["joint_positions"][0]
    assert np.max(np.abs(c[:, 0])) > 0.4
    assert np.max(np.abs(c[:, 1] - RATIO * c[:, 0])) < 1e-9
    energy = res["total_energy"]
    assert np.ptp(energy) < 1e-8
    assert np.ptp(res["kinetic_energy"]) > 1.0


@pytest.mark.parametrize("dim", [2, 3])
def test_coordinate_choices_agree(runs, dim):
    """Body positions and the gear's reaction agree across absolute, natural and joint
    coordinates to 1e-8 (m, N m)."""
    ref = runs[dim, "absolute"]
    for coords in ("natural", "joint"):
        out = runs[dim, coords]
        assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-8, coords
        assert np.max(np.abs(out["joint_reactions"] - ref["joint_reactions"])) < 1e-8, coords


def test_planar_and_spatial_agree(runs):
    """The spatial pair moves in the plane z = 0 exactly like the planar one (1e-8 m)."""
    planar, spatial = runs[2, "absolute"]["body_positions"], runs[3, "absolute"]["body_positions"]
    xy = spatial.reshape(len(spatial), -1, 3)
    assert np.max(np.abs(xy[:, :, 2])) < 1e-12
    assert np.max(np.abs(xy[:, :, :2].reshape(len(spatial), -1) - planar)) < 1e-8


def _period(t: np.ndarray, x: np.ndarray) -> float:
    """Mean period between upward zero crossings (linear interpolation)."""
    k = np.nonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))[0]
    times = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    return float(np.mean(np.diff(times)))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("coordinates", COORDINATES)
def test_small_oscillation_frequency(dim, coordinates):
    """Amplitude 2e-4 rad: ω = √((m₁gl₁ + r²m₂gl₂)/(I₁ + r²I₂)) = 4.63 rad/s to 1e-7
    relative (measured −1.0e-8, the size of the amplitude's own correction)."""
    omega = omega_closed_form()
    period = 2 * math.pi / omega
    mech = gear_pair(coordinates, dim, rate=1e-3)
    res = casmbd.simulate(mech, t_end=3.2 * period, steps=1600, rtol=1e-11, atol=1e-14)
    phi = res["joint_positions"][:, 0] - res["joint_positions"][0, 0]
    measured = 2 * math.pi / _period(res.t, -phi)  # φ starts rising: cross upward at T/2
    assert abs(measured / omega - 1.0) < 1e-7
    assert math.isclose(omega, 4.628, rel_tol=1e-3)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("coordinates", COORDINATES)
def test_static_reaction_of_the_gear(dim, coordinates):
    """A motor torque T₁ holds pendulum 1 at φ = 0.2 rad (pendulum 2 at −0.4 rad): the
    equilibrium φ to 1e-9 rad and the gear's moment on rod 2, m₂ g l₂ sin rφ, and its
    multiplier (−M) to 1e-9 N m."""
    phi = 0.2
    l1, l2 = L1 / 2, L2 / 2
    torque = M1 * G * l1 * math.sin(phi) + RATIO * M2 * G * l2 * math.sin(RATIO * phi)
    mech = gear_pair(coordinates, dim, torque=torque)
    res = casmbd.static_equilibrium(mech)
    assert res.stable is True
    sx = casmbd.System(mech)
    names = [str(lab) for lab in sx.constraint_labels]
    row = next((i for i, n in enumerate(names) if "gear" in n), None)
    moment = M2 * G * l2 * math.sin(RATIO * phi)
    gear = res.joint_reactions[list(mech.joints).index("gear")]
    assert np.max(np.abs(gear[:-1 if dim == 2 else 3])) < 1e-9  # no force
    assert abs(gear[-1] - moment) < 1e-9
    if coordinates == "joint":  # substituted (system/tree.py): no gear row, no multiplier
        assert row is None and sx.nq == 1
    else:
        assert abs(res.lagrange_multipliers[row] + moment) < 1e-9
    # rod 1 at φ (its centre of mass at l1 (sin φ, −cos φ)), rod 2 at rφ
    pos = res.body_positions.reshape(2, -1)
    assert np.max(np.abs(pos[0, :2] - l1 * np.array([math.sin(phi), -math.cos(phi)]))) < 1e-9
    assert np.max(np.abs(pos[1, :2] - (np.array([PIVOT2, 0.0]) + l2 * np.array(
        [math.sin(RATIO * phi), -math.cos(RATIO * phi)])))) < 1e-9


SCENE = """
[scene]
name = "gear_scene"
gravity = [0.0, -9.81]
coordinates = "{coordinates}"
[parameters]
r = -2.0
[[bodies]]
name = "rod1"
mass = 1.0
inertia = {i1}
position = [0.0, -0.5]
velocity = [1.0, 0.0]
angular_velocity = 2.0
[[bodies]]
name = "rod2"
mass = 1.5
inertia = {i2}
position = [2.0, -0.3]
velocity = [-1.2, 0.0]
angular_velocity = -4.0
[[joints]]
name = "pin1"
type = "revolute"
body1 = "ground"
body2 = "rod1"
point = [0.0, 0.0]
[[joints]]
name = "pin2"
type = "revolute"
body1 = "ground"
body2 = "rod2"
point = [2.0, 0.0]
[[joints]]
name = "gear"
type = "gear"
joint1 = "pin1"
joint2 = "pin2"
ratio = "r"
"""


def _scene(coordinates: str = "absolute", extra: str = "") -> str:
    return SCENE.format(coordinates=coordinates, i1=M1 * L1**2 / 12,
                        i2=M2 * L2**2 / 12) + extra


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_scene_gear_equals_python_gear(runs, coordinates):
    """The scene's gear (ratio an expression of a parameter) moves like the Python one
    (1e-12 m)."""
    mech = casmbd.loads_scene(_scene(coordinates))
    assert mech.joints["gear"].ratio == RATIO
    res = casmbd.simulate(mech, t_end=2.5, steps=250, rtol=1e-11)
    ref = runs[2, coordinates]
    assert np.max(np.abs(res["body_positions"] - ref["body_positions"])) < 1e-12


def test_gear_errors_name_the_field():
    """Unknown joint, a joint without coordinate, ratio 0, a bad coordinate, body keys in a
    scene gear: each names the gear and the field or key."""
    m = gear_pair("absolute", 2)
    with pytest.raises(ModelError, match=r"joint 'g2' field 'joint2'.*unknown joint 'nope'"):
        m.add_gear("g2", "pin1", "nope")
    with pytest.raises(ModelError, match=r"joint 'g3' field 'ratio': must not be 0"):
        m.add_gear("g3", "pin1", "pin2", ratio=0.0)
    with pytest.raises(ModelError, match=r"joint 'g4' field 'coordinate1'.*'translation'"):
        m.add("gear", "g4", joint1="pin1", joint2="pin2", coordinate1="translation")
    m.add_rigid("weld", "rod1", "rod2")
    with pytest.raises(ModelError, match=r"joint 'g5' field 'joint1'.*'weld'.*no joint "
                                         r"coordinate"):
        m.add_gear("g5", "weld", "pin2")
    with pytest.raises(SceneError, match=r"\('gear'\) key 'body1': unknown key"):
        casmbd.loads_scene(_scene().replace('ratio = "r"', 'ratio = "r"\nbody1 = "rod1"'))
    with pytest.raises(SceneError, match=r"\('gear'\) key 'joint2': missing required key"):
        casmbd.loads_scene(_scene().replace('joint2 = "pin2"\n', ""))


OFFSET = 0.3


def offset_pair(coordinates: str, dim: int, **kw) -> Mechanism:
    """The pair of :func:`gear_pair` with the gear c₂ − c₂⁰ = r (c₁ − c₁⁰) + δ, δ = 0.3 rad."""
    m = gear_pair(coordinates, dim, **kw)
    del m.joints["gear"]
    m.add_gear("gear", "pin1", "pin2", ratio=RATIO, offset=OFFSET)
    return m


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("coordinates", COORDINATES)
def test_gear_offset_holds_along_a_simulation(dim, coordinates):
    """Offset δ = 0.3 rad: the design pose (both hanging, c⁰ = 0) violates the gear by δ, the
    start is assembled; along 2 s the coupled coordinate is c₂ = r c₁ + δ to 1e-9 rad
    (measured ≤ 2e-11) while pendulum 1 swings (> 0.4 rad), energy constant to 1e-8 J."""
    res = casmbd.simulate(offset_pair(coordinates, dim, rate=2.0), t_end=2.0, steps=200,
                          rtol=1e-11)
    c = res["joint_positions"]  # c⁰ = 0: both rods are built hanging
    assert np.max(np.abs(c[:, 1] - RATIO * c[:, 0] - OFFSET)) < 1e-9
    assert np.max(np.abs(c[:, 0])) > 0.4
    assert abs(c[0, 1] - RATIO * c[0, 0]) > 0.29  # the offset is really there
    assert np.ptp(res["total_energy"]) < 1e-8


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("coordinates", COORDINATES)
def test_gear_offset_static_equilibrium(dim, coordinates):
    """A torque T₁ = m₁ g l₁ sin φ + r m₂ g l₂ sin(rφ + δ) holds pendulum 1 at φ = 0.2 rad,
    pendulum 2 at rφ + δ = −0.1 rad: both angles and the gear's moment m₂ g l₂ sin(rφ + δ)
    on rod 2 to 1e-9."""
    phi = 0.2
    l1, l2 = L1 / 2, L2 / 2
    phi2 = RATIO * phi + OFFSET
    torque = M1 * G * l1 * math.sin(phi) + RATIO * M2 * G * l2 * math.sin(phi2)
    mech = offset_pair(coordinates, dim, torque=torque)
    res = casmbd.static_equilibrium(mech)
    assert res.stable is True
    pos = res.body_positions.reshape(2, -1)
    assert np.max(np.abs(pos[0, :2] - l1 * np.array([math.sin(phi), -math.cos(phi)]))) < 1e-9
    assert np.max(np.abs(pos[1, :2] - (np.array([PIVOT2, 0.0]) + l2 * np.array(
        [math.sin(phi2), -math.cos(phi2)])))) < 1e-9
    gear = res.joint_reactions[list(mech.joints).index("gear")]
    assert abs(gear[-1] - M2 * G * l2 * math.sin(phi2)) < 1e-9


def test_scene_gear_offset():
    """Scene key ``offset`` (an expression) reaches the gear; a non-number is named."""
    mech = casmbd.loads_scene(_scene().replace('ratio = "r"', 'ratio = "r"\noffset = "r/4"'))
    assert mech.joints["gear"].offset == -0.5
    assert casmbd.loads_scene(_scene()).joints["gear"].offset == 0.0
    with pytest.raises(SceneError, match=r"key 'offset'"):
        casmbd.loads_scene(_scene().replace('ratio = "r"', 'ratio = "r"\noffset = [1, 2]'))
