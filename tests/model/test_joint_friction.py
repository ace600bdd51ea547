"""The ``joint_friction`` force element (casmbd/model/joint_friction.py): viscous damping and
smooth Coulomb friction Q_j = −c q̇_j − F_c tanh(q̇_j / v_s) on a joint coordinate, and the URDF
``damping`` / ``friction`` switches that add it."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import simpson

import casmbd
from casmbd import loads_urdf, simulate
from casmbd.errors import ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.model.joint_friction import REGULARIZATION
from casmbd.system.equations import System

G = 9.81


def _pendulum(gravity: float = G, **fields) -> casmbd.Mechanism:
    """Slender rod (1 kg, 1 m) pinned at one end, horizontal at rest, with a joint element."""
    m = casmbd.Mechanism("pendulum", gravity=(0.0, -gravity), coordinates="joint")
    m.add_body("rod", 1.0, 1.0 / 12.0, (0.5, 0.0))
    m.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
    m.add("joint_friction", "loss", "pivot", **fields)
    return m


def _applied(mech: casmbd.Mechanism, coordinates: str, q, v) -> np.ndarray:
    s = System(mech, coordinates)
    f = s.function("applied_forces")
    args = {"q": q, "v": v, "t": 0.0, "u": np.zeros(0), "p": s.parameter_values}
    return np.array(ca.DM(f.call({n: args[n] for n in f.name_in()})[f.name_out()[0]])).ravel()


def test_viscous_damping_energy_decay_rate():
    """Pendulum with c = 0.3 only: E(t) − E(0) = −∫ c θ̇² dt at the outputs (Simpson on 2001
    points, 1e-6 relative to the dissipated energy), and Q_e ᵀ v = −c θ̇² by direct
    evaluation (gravity off) to 1e-12."""
    c = 0.3
    mech = _pendulum(damping=c)
    assert mech.forces["loss"].energy_exchange() == "damper"
    res = simulate(mech, 2.0, 2000, rtol=1e-11, atol=1e-12)
    energy = res["total_energy"]
    omega = res.body("rod")["angular_velocity"]
    lost = np.array([simpson(c * omega[:k + 1] ** 2, x=res.t[:k + 1])
                     for k in (500, 1000, 2000)])
    change = energy[[500, 1000, 2000]] - energy[0]
    assert np.max(np.abs(change + lost)) / lost[-1] <= 1e-6, (change, lost)
    free = _pendulum(gravity=0.0, damping=c)
    for rate in (-2.0, 0.4, 3.0):
        q = _applied(free, "joint", [0.3], [rate])
        assert abs(q[0] * rate + c * rate**2) <= 1e-12 * c * rate**2


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_coulomb_friction_closed_form(coordinates):
    """Friction F_c = 2 only, gravity off: the generalized force on θ is −F_c tanh(θ̇/v_s)
    (1e-12) and lies within F_c (1 − tanh(|θ̇|/v_s)) of −F_c sign(θ̇) for |θ̇| ≫ v_s."""
    fc, vs = 2.0, 1e-2
    mech = _pendulum(gravity=0.0, friction=fc, regularization=vs)
    s = System(mech, coordinates)
    q0 = s.initial_coordinates()
    for rate in (-0.5, -0.05, 0.03, 1.0):
        v = np.array(s.initial_velocities(), float) * 0.0
        if coordinates == "joint":
            v[0] = rate
        else:  # rod body coordinates (x, y, θ): centre velocity rate·(−sin, cos)·0.5 at θ=0
            v[:] = [0.0, 0.5 * rate, rate]
        qe = _applied(mech, coordinates, q0, v)
        power = float(qe @ v)  # = Q_θ θ̇ in any coordinates
        q_theta = power / rate
        assert abs(q_theta + fc * np.tanh(rate / vs)) <= 1e-12 * fc
        assert abs(q_theta + fc * np.sign(rate)) <= fc * (1 - np.tanh(abs(rate) / vs)) + 1e-12
    assert mech.forces["loss"].energy_exchange() == "damper"
    assert _pendulum().forces["loss"].energy_exchange() is None
    assert _pendulum().forces["loss"].regularization == REGULARIZATION


_SLIDER = ('<robot name="s"><link name="base"/><link name="cart"><inertial><mass value="{m}"/>'
           '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
           '<joint name="slide" type="prismatic"><parent link="base"/><child link="cart"/>'
           '<axis xyz="1 0 0"/><limit lower="-10" upper="10" effort="1" velocity="9"/>'
           '<dynamics damping="{c}" friction="0.7"/></joint></robot>')


def test_urdf_prismatic_damping_exponential_decay():
    """A 2 kg slider with <dynamics damping="0.8"> and v0 = 1.5 (gravity across the axis):
    v(t) = v0 exp(−c t / m) to 1e-6 at every output."""
    m, c, v0 = 2.0, 0.8, 1.5
    mech = loads_urdf(_SLIDER.format(m=m, c=c), "s.urdf", damping=True,
                      initial={"slide": (0.0, v0)})
    element = mech.forces["slide_damping"]
    assert (element.kind, element.damping, element.friction) == ("joint_friction", c, 0.0)
    res = simulate(mech, 2.0, 40, rtol=1e-11, atol=1e-12)
    exact = v0 * np.exp(-c * res.t / m)
    vel = res.joint("slide")["velocity"]
    assert np.max(np.abs(vel - exact)) / v0 <= 1e-6


def test_urdf_switches():
    """Switches off: no element; friction only: F_c from <dynamics friction>, c = 0."""
    text = _SLIDER.format(m=1.0, c=0.4)
    assert not loads_urdf(text, "s.urdf").forces
    both = loads_urdf(text, "s.urdf", damping=True, friction=True).forces["slide_damping"]
    assert (both.damping, both.friction) == (0.4, 0.7)
    only = loads_urdf(text, "s.urdf", friction=True).forces
    assert list(only) == ["slide_friction"]
    assert (only["slide_friction"].damping, only["slide_friction"].friction) == (0.0, 0.7)


def test_named_errors():
    mech = _pendulum()
    with pytest.raises(ModelError, match="force 'x' field 'joint': unknown joint 'nope'"):
        mech.add("joint_friction", "x", "nope", damping=1.0)
    with pytest.raises(ModelError, match="force 'x' field 'damping': must be >= 0"):
        mech.add("joint_friction", "x", "pivot", damping=-1.0)
    with pytest.raises(ModelError, match="force 'x' field 'friction': must be >= 0"):
        mech.add("joint_friction", "x", "pivot", friction=-0.1)
    with pytest.raises(ModelError, match="force 'x' field 'regularization': must be > 0"):
        mech.add("joint_friction", "x", "pivot", friction=1.0, regularization=0.0)
    with pytest.raises(ModelError, match="force 'x' field 'coordinate'"):
        mech.add("joint_friction", "x", "pivot", coordinate="translation")
    mech.add_body("box", 1.0, 1.0, (2.0, 0.0))
    mech.add_fixed("weld", "box")
    with pytest.raises(ModelError, match=r"'joint': joint 'weld' \(fixed\) has no joint coord"):
        mech.add("joint_friction", "x", "weld", damping=1.0)


_SCENE = ('[scene]\nname = "p"\ngravity = [0.0, 0.0]\ncoordinates = "joint"\n'
          '[[bodies]]\nname = "rod"\nmass = 1.0\ninertia = 0.1\nposition = [0.5, 0.0]\n'
          '[[joints]]\nname = "pivot"\ntype = "revolute"\nbody1 = "ground"\nbody2 = "rod"\n'
          'point = [0.0, 0.0]\n[[forces]]\nname = "loss"\ntype = "joint_friction"\n'
          'joint = "pivot"\n{keys}')


def test_scene_entry_and_switch_errors():
    """A [[forces]] entry gives the same Q as the Python build (1e-12); a negative value, an
    unknown key and ``friction`` without ``urdf`` are named errors."""
    mech = loads_scene(_SCENE.format(keys='damping = 0.2\nfriction = 1.5\n'
                                          'regularization = 0.05\n'))
    python = _pendulum(gravity=0.0, damping=0.2, friction=1.5, regularization=0.05)
    for rate in (-1.0, 0.02):
        q = _applied(mech, "joint", [0.0], [rate])[0]
        assert abs(q - _applied(python, "joint", [0.0], [rate])[0]) <= 1e-12
        assert abs(q + 0.2 * rate + 1.5 * np.tanh(rate / 0.05)) <= 1e-12
    with pytest.raises(SceneError, match=r"'loss'.*'friction'"):
        loads_scene(_SCENE.format(keys="friction = -1.0\n"))
    with pytest.raises(SceneError, match="stiffness"):
        loads_scene(_SCENE.format(keys="stiffness = 1.0\n"))
    with pytest.raises(SceneError, match=r"need 'urdf' \(so does 'friction'\)"):
        loads_scene(_SCENE.format(keys="").replace("coordinates = ",
                                                   "friction = true\ncoordinates = ", 1))


def test_urdf_scene_friction_switch(tmp_path):
    """``[scene] friction = true`` next to ``urdf`` adds the friction element; a non-boolean
    value is a named error."""
    (tmp_path / "s.urdf").write_text(_SLIDER.format(m=1.0, c=0.4))
    head = '[scene]\nurdf = "s.urdf"\ndimension = 3\nfriction = {}\n'
    (tmp_path / "a.toml").write_text(head.format("true"))
    forces = casmbd.load_scene(tmp_path / "a.toml").forces
    assert list(forces) == ["slide_friction"] and forces["slide_friction"].friction == 0.7
    (tmp_path / "b.toml").write_text(head.format("1"))
    with pytest.raises(SceneError, match="key 'friction': expected true or false"):
        casmbd.load_scene(tmp_path / "b.toml")
