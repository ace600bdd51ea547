"""The rolling kinds of casmbd.model.rolling (issue 37) against closed forms.

* Chaplygin's sleigh (``knife_edge``; Bloch, *Nonholonomic Mechanics and Control*, 2003,
  §1.7; Neimark & Fufaev 1972, ch. 1): the blade at distance a behind the centre of mass G
  along the body axis e₁.  With u the forward and w the lateral velocity of G and ω the
  angular velocity, the constraint is w = a ω and the equations of motion
  m (u̇ − ω w) = 0, m (ẇ + ω u) = F, I ω̇ = −a F give u̇ = a ω², ω̇ = −m a u ω / J with
  J = I + m a².  The energy E = ½ m u² + ½ J ω² is constant, so with U² = 2E/m,
  κ = a m U / J and tanh c₀ = u₀/U:

      u(t) = U tanh(κ t + c₀),   ω(t) = sgn(ω₀) √(m/J) U sech(κ t + c₀),
      θ(t) = θ₀ + sgn(ω₀) (√(J/m)/a) [gd(κ t + c₀) − gd(c₀)],   gd x = atan(sinh x),

  and the blade's lateral force F = m (ẇ + ω u) is −λ (the multiplier of the row W = v_P·l).
* The rolling sphere on an incline of angle α (Routh; uniform ball, I = 2/5 m R²): the centre
  accelerates down the slope at 5/7 g sin α whatever it does across the slope, and its spin
  about the plane's normal stays constant (the contact force passes through the centre).
* The planar rolling disc on an incline: a = 2/3 g sin α for a uniform disc (I = ½ m R²).

Every run in the three coordinate choices, CasADi's virtual machine (no compile).
"""

from __future__ import annotations

import numpy as np
import pytest

import casmbd
from casmbd.errors import ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.model import Mechanism

COORDINATES = ("absolute", "natural", "joint")
RTOL, ATOL = 1e-11, 1e-12

# the sleigh
M, INERTIA, A = 2.0, 0.3, 0.4
U0, W0 = 1.0, 2.0


def sleigh_closed_form(t: np.ndarray):
    """u(t), ω(t), θ(t) and the blade's lateral force F(t) of Chaplygin's sleigh."""
    j = INERTIA + M * A * A
    energy = 0.5 * M * U0**2 + 0.5 * j * W0**2
    big_u = np.sqrt(2.0 * energy / M)
    kappa = A * M * big_u / j
    c0 = np.arctanh(U0 / big_u)
    x = kappa * t + c0
    u = big_u * np.tanh(x)
    w = np.sign(W0) * np.sqrt(M / j) * big_u / np.cosh(x)
    theta = np.sign(W0) * np.sqrt(j / M) / A * (np.arctan(np.sinh(x)) - np.arctan(np.sinh(c0)))
    wdot = -M * A * u * w / j
    force = M * (A * wdot + w * u)  # m (ẇ + ω u) with w_lat = a ω
    return u, w, theta, force


def planar_sleigh(coordinates: str) -> Mechanism:
    mech = Mechanism("sleigh", dimension=2, coordinates=coordinates)
    mech.add_body("sleigh", M, INERTIA, [0.0, 0.0], angle=0.0, velocity=[U0, A * W0],
                  angular_velocity=W0)
    mech.add("knife_edge", "blade", "ground", "sleigh", point=[-A, 0.0], axis=[1.0, 0.0])
    return mech


def body_frame_velocities(body: dict) -> tuple[np.ndarray, np.ndarray]:
    """(u, w): the centre's velocity along and across the planar body axis."""
    th, vel = body["angle"], body["velocity"]
    return (vel[:, 0] * np.cos(th) + vel[:, 1] * np.sin(th),
            -vel[:, 0] * np.sin(th) + vel[:, 1] * np.cos(th))


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_chaplygin_sleigh_follows_its_closed_form(coordinates):
    """u, ω, θ to 1e-8 over 3 s (u goes from 1 to 1.28, ω from 2 to 0.53); the blade's
    point never slips sideways (w = a ω to 1e-8); the energy is constant to 1e-9; the
    multiplier is minus the closed-form lateral force to 1e-7."""
    res = casmbd.simulate(planar_sleigh(coordinates), 3.0, 30, rtol=RTOL, atol=ATOL,
                          mode="vm")
    body = res.body("sleigh")
    u, w = body_frame_velocities(body)
    u_ref, omega_ref, theta_ref, force_ref = sleigh_closed_form(res.t)
    assert np.max(np.abs(u - u_ref)) < 1e-8
    assert np.max(np.abs(body["angular_velocity"] - omega_ref)) < 1e-8
    assert np.max(np.abs(body["angle"] - theta_ref)) < 1e-8
    assert np.max(np.abs(w - A * body["angular_velocity"])) < 1e-8
    energy = res.arrays["total_energy"]
    assert np.ptp(energy) < 1e-9 * energy[0]
    assert u_ref[-1] > 1.25 and omega_ref[-1] < 0.6  # the motion is not trivial
    row = res.names["constraints"].index("joint 'blade' equation 'lateral'")
    assert np.max(np.abs(res.arrays["lambda"][:, row] + force_ref)) < 1e-7
    # the joint reaction: the force F e₂ on the sleigh at the blade point, no moment there
    th = body["angle"]
    lateral = np.column_stack([-np.sin(th), np.cos(th)])
    reaction = res.arrays["joint_reactions"][:, 0, :]
    assert np.max(np.abs(reaction[:, :2] - force_ref[:, None] * lateral)) < 1e-7
    assert np.max(np.abs(reaction[:, 2])) < 1e-9


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_spatial_knife_edge_is_the_planar_sleigh(coordinates):
    """A spatial body held on the ground plane by a planar joint, with a spatial knife edge
    (normal +z): the same closed form to 1e-8."""
    mech = Mechanism("sleigh3d", gravity=(0.0, 0.0, -9.81), coordinates=coordinates)
    mech.add_body("sleigh", M, [0.1, 0.2, INERTIA], [0.0, 0.0, 0.0],
                  velocity=[U0, A * W0, 0.0], angular_velocity=[0.0, 0.0, W0])
    mech.add("planar", "floor", "ground", "sleigh", [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    mech.add("knife_edge", "blade", "ground", "sleigh", point=[-A, 0.0, 0.0],
             axis=[1.0, 0.0, 0.0], normal=[0.0, 0.0, 1.0])
    res = casmbd.simulate(mech, 3.0, 30, rtol=RTOL, atol=ATOL, mode="vm")
    body = res.body("sleigh")
    rot = body["rotation"]
    e1 = rot[:, :, 0]
    vel = body["velocity"]
    u = np.einsum("ij,ij->i", vel, e1)
    u_ref, omega_ref, _, _ = sleigh_closed_form(res.t)
    assert np.max(np.abs(u - u_ref)) < 1e-8
    assert np.max(np.abs(body["angular_velocity"][:, 2] - omega_ref)) < 1e-8


# the rolling sphere on an incline
G, ALPHA, R, MASS = 9.81, 0.3, 0.2, 1.5
NORMAL = np.array([-np.sin(ALPHA), 0.0, np.cos(ALPHA)])
UPHILL = np.array([np.cos(ALPHA), 0.0, np.sin(ALPHA)])


def ball_on_incline(coordinates: str, spin: float, across: float) -> Mechanism:
    """A uniform ball on the incline, spinning at ``spin`` about the normal and rolling
    across the slope (+y) at ``across``."""
    centre = R * NORMAL
    roll = across / R / np.cross(UPHILL, NORMAL)[1]  # v_c = R ω × n along +y
    omega = spin * NORMAL + roll * UPHILL
    mech = Mechanism("ball", gravity=(0.0, 0.0, -G), coordinates=coordinates)
    inertia = 0.4 * MASS * R * R
    mech.add_body("ball", MASS, [inertia] * 3, centre,
                  velocity=R * np.cross(omega, NORMAL), angular_velocity=omega)
    mech.add("rolling_sphere", "roll", "ground", "ball", point=centre, radius=R,
             origin=[0.0, 0.0, 0.0], normal=NORMAL)
    return mech


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_rolling_sphere_on_an_incline(coordinates):
    """Down the slope s = −½ (5/7) g sin α t² to 1e-9, across it y = v t to 1e-9, the spin
    about the normal constant to 1e-7, no slip (ṙ_c − R ω × n) to 1e-9, the height to
    1e-12, the energy to 1e-8 (relative)."""
    spin, across = 3.0, 0.5
    res = casmbd.simulate(ball_on_incline(coordinates, spin, across), 2.0, 20, rtol=RTOL,
                          atol=ATOL, mode="vm")
    body, t = res.body("ball"), res.t
    pos, omega, vel = body["position"], body["angular_velocity"], body["velocity"]
    downhill = (pos - R * NORMAL) @ UPHILL
    assert np.max(np.abs(downhill + 0.5 * 5.0 / 7.0 * G * np.sin(ALPHA) * t**2)) < 1e-9
    assert np.max(np.abs(pos[:, 1] - across * t)) < 1e-9
    assert np.max(np.abs(omega @ NORMAL - spin)) < 1e-7
    assert np.max(np.abs(vel - R * np.cross(omega, NORMAL))) < 1e-9
    assert np.max(np.abs(pos @ NORMAL - R)) < 1e-12
    energy = res.arrays["total_energy"]
    assert np.ptp(energy) < 1e-8 * np.max(res.arrays["kinetic_energy"])
    # the reaction on the ball, about its centre: N n + f t (N = m g cos α, f = 2/7 m g sin α
    # up the slope: m a = m g sin α − f with a = 5/7 g sin α), moment (−R n) × F
    force = MASS * G * (np.cos(ALPHA) * NORMAL + 2.0 / 7.0 * np.sin(ALPHA) * UPHILL)
    reaction = res.arrays["joint_reactions"][:, 0, :]
    assert np.max(np.abs(reaction[:, :3] - force)) < 1e-8
    assert np.max(np.abs(reaction[:, 3:] - np.cross(-R * NORMAL, force))) < 1e-8


def test_a_spinning_ball_on_level_ground_keeps_spinning():
    """On level ground a ball spinning about the vertical, at rest otherwise, stays there
    spinning (angular velocity to 1e-8, the centre to 1e-10)."""
    mech = Mechanism("top", gravity=(0.0, 0.0, -G))
    inertia = 0.4 * MASS * R * R
    mech.add_body("ball", MASS, [inertia] * 3, [0.0, 0.0, R], angular_velocity=[0, 0, 7.0])
    mech.add("rolling_sphere", "roll", "ground", "ball", point=[0.0, 0.0, R], radius=R)
    res = casmbd.simulate(mech, 1.0, 10, rtol=RTOL, atol=ATOL, mode="vm")
    body = res.body("ball")
    assert np.max(np.abs(body["angular_velocity"] - [0.0, 0.0, 7.0])) < 1e-8
    assert np.max(np.abs(body["position"] - [0.0, 0.0, R])) < 1e-10


# the planar rolling disc
def disc_on_incline(coordinates: str, speed: float = 0.4) -> Mechanism:
    normal = np.array([-np.sin(ALPHA), np.cos(ALPHA)])
    centre = R * normal
    mech = Mechanism("disc", gravity=(0.0, -G), coordinates=coordinates)
    mech.add_body("disc", MASS, 0.5 * MASS * R * R, centre, angle=0.3,
                  velocity=list(speed * UPHILL[[0, 2]]), angular_velocity=-speed / R)
    mech.add("rolling_disc", "roll", "ground", "disc", point=centre, radius=R, normal=normal,
             axis=[0.0, 0.0, 1.0])
    return mech


@pytest.mark.parametrize("coordinates", COORDINATES)
def test_planar_rolling_disc_on_an_incline(coordinates):
    """s = v₀ t − ½ (2/3) g sin α t² to 1e-9 (the disc rolls up, stops and rolls back down),
    s + R (θ − θ₀) = 0 to 1e-9, the energy to 1e-8 (relative); the joint's coordinates are
    s and θ."""
    res = casmbd.simulate(disc_on_incline(coordinates), 2.0, 100, rtol=RTOL, atol=ATOL,
                          mode="vm")
    body, t = res.body("disc"), res.t
    normal = np.array([-np.sin(ALPHA), np.cos(ALPHA)])
    s = (body["position"] - R * normal) @ UPHILL[[0, 2]]
    assert np.max(np.abs(s - (0.4 * t - 0.5 * 2.0 / 3.0 * G * np.sin(ALPHA) * t**2))) < 1e-9
    assert np.max(np.abs(s + R * (body["angle"] - 0.3))) < 1e-9
    energy = res.arrays["total_energy"]
    assert np.ptp(energy) < 1e-8 * np.max(res.arrays["kinetic_energy"])
    # the reaction on the disc, about its centre: N n + f t, f = 1/3 m g sin α up the slope
    force = MASS * G * (np.cos(ALPHA) * normal + np.sin(ALPHA) / 3.0 * UPHILL[[0, 2]])
    arm = -R * normal
    reaction = res.arrays["joint_reactions"][:, 0, :]
    assert np.max(np.abs(reaction[:, :2] - force)) < 1e-8
    assert np.max(np.abs(reaction[:, 2] - (arm[0] * force[1] - arm[1] * force[0]))) < 1e-8
    joint = res.joint("roll")
    assert np.max(np.abs(joint["coordinate"] - s)) < 1e-9
    assert np.max(np.abs(joint["angle"] - body["angle"])) < 1e-9


def test_planar_rolling_disc_is_holonomic():
    """Two position rows, no velocity rows: the kind needs nothing special, and DOF = 1."""
    mech = disc_on_incline("absolute")
    joint = mech.joints["roll"]
    assert joint.needs == frozenset() and not hasattr(joint, "velocity_equations")
    info = casmbd.info(mech)
    assert info["degrees_of_freedom"] == 1


SCENE = """
[scene]
dimension = {dim}
gravity = {gravity}
[[bodies]]
name = "b"
mass = 1.0
inertia = {inertia}
position = {position}
[[joints]]
name = "j"
body1 = "ground"
body2 = "b"
{joint}
"""


def scene(dim: int, joint: str) -> str:
    if dim == 2:
        return SCENE.format(dim=2, gravity="[0.0, -9.81]", inertia="0.01",
                            position="[0.0, 0.1]", joint=joint)
    return SCENE.format(dim=3, gravity="[0.0, 0.0, -9.81]", inertia="[0.004, 0.004, 0.004]",
                        position="[0.0, 0.0, 0.1]", joint=joint)


def test_scene_keys_build_each_kind():
    disc = loads_scene(scene(2, 'type = "rolling_disc"\npoint = [0.0, 0.1]\nradius = 0.1\n'
                                'origin = [0.0, 0.0]\nnormal = [0.0, 1.0]\naxis = [0.0, 0.0, 1.0]'))
    assert type(disc.joints["j"]).__name__ == "PlanarRollingDisc"
    knife = loads_scene(scene(2, 'type = "knife_edge"\npoint = [0.0, 0.1]\naxis = [1.0, 0.0]'))
    assert knife.joints["j"].velocity_labels == ("lateral",)
    ball = loads_scene(scene(3, 'type = "rolling_sphere"\npoint = [0.0, 0.0, 0.1]\n'
                                'radius = 0.1'))
    assert ball.joints["j"].labels == ("contact", "slip_1", "slip_2")
    assert ball.joints["j"].velocity_labels == ("slip_1", "slip_2")
    knife3 = loads_scene(scene(3, 'type = "knife_edge"\npoint = [0.0, 0.0, 0.0]\n'
                                  'axis = [1.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]'))
    assert knife3.joints["j"].needs == frozenset({"velocity_constraints"})


@pytest.mark.parametrize(("dim", "joint", "message"), [
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.1]\nradius = -0.1', "field 'radius'"),
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.1]', "key 'radius': missing"),
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.3]\nradius = 0.1', "field 'point'"),
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.1]\nradius = 0.1\nnormal = [0.0, 0.0]',
     "field 'normal'"),
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.1]\nradius = 0.1\naxis = [1.0, 0.0, 0.0]',
     "field 'axis'"),
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.1]\nradius = 0.1\naxis = [0.0, 1.0]',
     "key 'axis'"),
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.1]\nradius = 0.1\norigin = [0.0]',
     "key 'origin'"),
    (2, 'type = "rolling_disc"\npoint = [0.0, 0.1]\nradius = 0.1\nspeed = 1.0',
     "key 'speed': unknown key"),
    (2, 'type = "knife_edge"\npoint = [0.0, 0.1]\naxis = [0.0, 0.0]', "field 'axis'"),
    (2, 'type = "knife_edge"\naxis = [1.0, 0.0]', "key 'point': missing"),
    (2, 'type = "knife_edge"\npoint = [0.0, 0.1]', "key 'axis': missing"),
    (2, 'type = "knife_edge"\npoint = [0.0, 0.1]\naxis = [1.0, 0.0]\nnormal = [0.0, 1.0]',
     "field 'normal'"),
    (3, 'type = "knife_edge"\npoint = [0.0, 0.0, 0.1]\naxis = [0.0, 0.0, 2.0]',
     "field 'axis'"),
    (3, 'type = "knife_edge"\npoint = [0.0, 0.0, 0.1]\naxis = [1.0, 0.0, 0.0]\n'
        'normal = [0.0, 0.0, "x"]', "key 'normal'"),
    (3, 'type = "rolling_sphere"\npoint = [0.0, 0.0, 0.1]\nradius = 0.0', "field 'radius'"),
    (3, 'type = "rolling_sphere"\npoint = [0.0, 0.0, 0.1]\nradius = 0.2', "field 'point'"),
    (3, 'type = "rolling_sphere"\npoint = [0.0, 0.0, 0.1]\nradius = 0.1\n'
        'normal = [0.0, 0.0, 0.0]', "field 'normal'"),
    (3, 'type = "rolling_sphere"\npoint = [0.0, 0.0, 0.1]\nradius = 0.1\naxis = [1, 0, 0]',
     "key 'axis': unknown key"),
    (2, 'type = "rolling_sphere"\npoint = [0.0, 0.1]\nradius = 0.1', "key 'type'"),
])
def test_bad_input_is_named(dim, joint, message):
    """Every field of the three kinds refused by name: the entry ('j') and the field."""
    with pytest.raises(SceneError) as err:
        loads_scene(scene(dim, joint))
    text = str(err.value)
    assert "'j'" in text and message in text, text


def test_python_api_names_the_joint_and_field():
    mech = Mechanism("m", gravity=(0.0, 0.0, -9.81))
    mech.add_body("ball", 1.0, [0.004] * 3, [0.0, 0.0, 0.1])
    with pytest.raises(ModelError, match="joint 'r' field 'radius'"):
        mech.add("rolling_sphere", "r", "ground", "ball", point=[0, 0, 0.1], radius=np.nan)
    with pytest.raises(ModelError, match="joint 'r' field 'body2'"):
        mech.add("rolling_sphere", "r", "ground", "cart", point=[0, 0, 0.1], radius=0.1)
    with pytest.raises(ModelError, match="joint 'r': body1 and body2"):
        mech.add("knife_edge", "r", "ball", "ball", point=[0, 0, 0.1], axis=[1, 0, 0])
    assert "r" not in mech.joints


def test_only_the_slip_rows_are_velocity_rows():
    """The rolling sphere's ``contact`` row is a position row (assembly, projections and
    stabilisation keep it); ``slip_1`` and ``slip_2`` are velocity rows."""
    system = casmbd.System(ball_on_incline("absolute", 0.0, 0.0))
    labels = [str(lab) for lab in system.constraint_labels]
    assert [labels[i] for i in system.velocity_rows] == [
        "joint 'roll' equation 'slip_1'", "joint 'roll' equation 'slip_2'"]
    assert "joint 'roll' equation 'contact'" in [labels[i] for i in system.holonomic_rows]


def test_the_rolling_body_is_not_the_ground_and_the_axle_is_z():
    mech = Mechanism("m", dimension=2)
    mech.add_body("disc", 1.0, 0.005, [0.0, 0.1])
    with pytest.raises(ModelError, match="joint 'r' field 'body2': the disc must be a moving"):
        mech.add("rolling_disc", "r", "disc", "ground", point=[0, 0.1], radius=0.1)
    with pytest.raises(ModelError, match="joint 'r' field 'body2': the body carrying the blade"):
        mech.add("knife_edge", "r", "disc", "ground", point=[0, 0.1], axis=[1, 0])
    with pytest.raises(ModelError, match="joint 'r' field 'axis': in the plane the axle"):
        mech.add("rolling_disc", "r", "ground", "disc", [0, 0.1], ["z", 0, 1], 0.1)
    with pytest.raises(ModelError, match="joint 'r' field 'axis': in the plane the axle"):
        mech.add("rolling_disc", "r", "ground", "disc", [0, 0.1], 0.1)
    with pytest.raises(ModelError, match="joint 'r' field 'radius': missing"):
        mech.add("rolling_disc", "r", "ground", "disc", [0, 0.1])
    joint = mech.add("rolling_disc", "r", "ground", "disc", [0, 0.1], [0, 0, -1], 0.1)
    assert joint.radius == 0.1 and not mech.joints["r"].needs


DECK = 0.7  # m/s: the support's uniform velocity along x


def on_deck(kind: str) -> Mechanism:
    """The sleigh, the planar disc or the ball on a deck (body1) driven along x at 0.7 m/s:
    relative to the deck each moves as on the ground (Galilean invariance)."""
    dim = 3 if kind == "ball" else 2
    z = (0.0,) * (dim - 2)
    gravity = (0.0, 0.0, -G) if dim == 3 else ((0.0, 0.0) if kind == "sleigh" else (0.0, -G))
    mech = Mechanism(kind, gravity=gravity, coordinates="absolute")
    mech.add_body("deck", 5.0, 1.0 if dim == 2 else [1.0] * 3, (0.0, -1.0, *z),
                  velocity=(DECK, 0.0, *z))
    mech.add("prismatic", "rail", "ground", "deck", (0.0, -1.0, *z), (1.0, 0.0, *z))
    mech.add_driver("push", joint="rail", position=f"{DECK}*t")
    if kind == "sleigh":
        mech.add_body("sleigh", M, INERTIA, [0.0, 0.0], velocity=[U0 + DECK, A * W0],
                      angular_velocity=W0)
        mech.add("knife_edge", "blade", "deck", "sleigh", point=[-A, 0.0], axis=[1.0, 0.0])
    elif kind == "disc":
        mech.add_body("disc", MASS, 0.5 * MASS * R * R, (0.0, R), velocity=(DECK + 0.4, 0.0),
                      angular_velocity=-0.4 / R)
        mech.add("rolling_disc", "roll", "deck", "disc", point=(0.0, R), radius=R)
    else:
        mech.add_body("ball", MASS, [0.4 * MASS * R * R] * 3, (0.0, 0.0, R),
                      velocity=(DECK + 0.3, 0.0, 0.0), angular_velocity=(0.0, 0.3 / R, 2.0))
        mech.add("rolling_sphere", "roll", "deck", "ball", point=(0.0, 0.0, R), radius=R)
    return mech


@pytest.mark.parametrize("kind", ["sleigh", "disc", "ball"])
def test_a_moving_support_carries_the_rolling_body(kind):
    """On the deck moving at 0.7 m/s: the sleigh's u and ω relative to the deck follow the
    closed form (1e-8); the disc and the ball roll on at their speed relative to the deck
    (level: 0.4 and 0.3 m/s, no slip relative to the deck, 1e-9)."""
    res = casmbd.simulate(on_deck(kind), 2.0, 20, rtol=RTOL, atol=ATOL, mode="vm")
    t = res.t
    body = res.body(kind)
    rel = body["velocity"].copy()
    rel[:, 0] -= DECK
    if kind == "sleigh":
        th = body["angle"]
        u = rel[:, 0] * np.cos(th) + rel[:, 1] * np.sin(th)
        u_ref, omega_ref, _, _ = sleigh_closed_form(t)
        assert np.max(np.abs(u - u_ref)) < 1e-8
        assert np.max(np.abs(body["angular_velocity"] - omega_ref)) < 1e-8
    elif kind == "disc":
        assert np.max(np.abs(body["position"][:, 0] - (DECK + 0.4) * t)) < 1e-9
        assert np.max(np.abs(rel[:, 0] + R * body["angular_velocity"])) < 1e-9
    else:
        omega = body["angular_velocity"]
        assert np.max(np.abs(body["position"][:, 0] - (DECK + 0.3) * t)) < 1e-9
        slip = rel - R * np.cross(omega, [0.0, 0.0, 1.0])
        assert np.max(np.abs(slip)) < 1e-9
        assert np.max(np.abs(omega[:, 2] - 2.0)) < 1e-8


def test_mechanism_wrappers_add_the_kinds():
    mech = Mechanism("m", gravity=(0.0, 0.0, -9.81))
    mech.add_body("ball", 1.0, [0.004] * 3, [0.0, 0.0, 0.1])
    mech.add_marker("c", "ball", [0.0, 0.0, 0.1])
    assert isinstance(mech.add_rolling_sphere("r", "ground", "ball", [0, 0, 0.1], 0.1),
                      casmbd.model.RollingSphere)
    assert mech.add_knife_edge("k", "ground", "ball", [0, 0, 0.1], [1, 0, 0]).labels == \
        ("lateral",)
    joint = mech.add_velocity_constraint("v", "ground", "ball", ["vz('c')"], ["height"])
    assert joint.labels == ("height",)


@pytest.mark.parametrize("blade", [-A, A])
def test_straight_sleigh_linearised_about_its_steady_motion(blade):
    """Straight at u: ω̇ = −m a u ω / J linearised (a the blade's distance behind G) — one
    eigenvalue −m a u/(I + m a²) after the cyclic x, y, θ are removed (1e-10): stable with the
    blade behind, unstable (the sleigh turns round) with it in front."""
    speed = 1.5
    mech = Mechanism("sleigh", dimension=2)
    mech.add_body("sleigh", M, INERTIA, [0.0, 0.0], velocity=[speed, 0.0])
    mech.add("knife_edge", "blade", "ground", "sleigh", point=[blade, 0.0], axis=[1.0, 0.0])
    lin = casmbd.linearize(mech, steady_motion=True, mode="vm")
    a = -blade
    expected = -M * a * speed / (INERTIA + M * a * a)
    eig = np.asarray(lin.eigenvalues)
    assert eig.shape == (1,) and abs(eig[0] - expected) < 1e-10
