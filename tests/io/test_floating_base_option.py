"""Floating bases without a peer (issue 34, item 1): closed forms and finite differences.

``load_urdf(path, floating_base=True)`` and ``[scene] floating_base = true`` make the root
link a free body whose seven coordinates are its frame origin and unit quaternion; the
per-call API takes Pinocchio's free-flyer velocity v = (Aᵀ ṙ, Aᵀ ω) (body axes), n_v = n_q − 1
(:mod:`casmbd.compiled.free_flyer`).  Checked here:

* ``integrate`` against the closed forms of a rotation about z (p = (cos ωt/2, 0, 0,
  sin ωt/2)) and a constant body twist (the origin on a circle of radius u/ω), 1e-14;
  ``difference`` as its inverse at large angles, 1e-12; the velocity map q̇ = G(q) v as the
  central finite difference of ``integrate``, 1e-8;
* one free link with its centre of mass off the link origin: M = [[m I, m [c]ᵀ], [m [c],
  J_G + m [c]ᵀ[c]]] (the spatial inertia at the origin, body axes), 1e-13; a centroidal
  free body: v̇ = Aᵀ g − ω × v and Euler's equations J ω̇ = −ω × J ω, 1e-12; inverse
  dynamics as the inverse of forward dynamics, 1e-11;
* the scene key and its errors; a quadrotor (hector, from example-robot-data when
  installed) in free fall: centre of mass r₀ + v₀ t + ½ g t² and the world angular
  momentum A J Aᵀ ω constant, 1e-6 relative over 1 s.
"""

from __future__ import annotations

import numpy as np
import pytest

import casmbd
from casmbd.errors import ModelError, SceneError
from casmbd.io.urdf import loads_urdf
from casmbd.model.rotations import rotation_matrix
from casmbd.system import System

LINK = ('<link name="{name}"><inertial><mass value="{m}"/><origin xyz="{c}"/>'
        '<inertia ixx="{i[0]}" ixy="0" ixz="0" iyy="{i[1]}" iyz="0" izz="{i[2]}"/>'
        '</inertial></link>')
ARM = ('<robot name="arm">' + LINK.format(name="base", m=3.0, c="0.1 -0.05 0.02",
                                          i=(0.2, 0.3, 0.4))
       + LINK.format(name="link1", m=1.0, c="0 0 0.25", i=(0.05, 0.05, 0.01))
       + '<joint name="j1" type="revolute"><parent link="base"/><child link="link1"/>'
       '<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
       '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>')


def _quat(rng):
    p = rng.normal(size=4)
    return p / np.linalg.norm(p)


@pytest.fixture(scope="module")
def vmap():
    from casmbd.compiled.free_flyer import VelocityMap
    return VelocityMap(System(loads_urdf(ARM, floating_base=True), coordinates="joint"))


def test_floating_base_mechanism_and_sizes(vmap):
    mech = loads_urdf(ARM, floating_base=True)
    assert list(mech.bodies) == ["base", "link1"]
    base = mech.bodies["base"]
    # the coordinates locate the root link frame's origin: s = −c in the body axes
    assert np.allclose(base.reference_point, [-0.1, 0.05, -0.02], atol=1e-15)
    assert vmap.nq == 8 and vmap.nv == 7
    assert vmap.velocity_names([f"c{i}" for i in range(8)]) == [
        "base.vx", "base.vy", "base.vz", "base.wx", "base.wy", "base.wz", "c7"]
    system = System(mech, coordinates="joint")
    assert np.allclose(system.initial_coordinates()[:7], [0, 0, 0, 1, 0, 0, 0], atol=1e-15)
    fixed = loads_urdf(ARM)
    assert list(fixed.bodies) == ["link1"]  # without the option the root is welded


def test_integrate_rotation_and_screw_closed_forms(vmap):
    q0 = np.array([0, 0, 0, 1, 0, 0, 0, 0.3])
    w, u, t = 1.7, 0.8, 1.3
    q1 = vmap.integrate(q0, [0, 0, 0, 0, 0, w, 0.5], t)
    assert np.max(np.abs(q1 - [0, 0, 0, np.cos(w * t / 2), 0, 0, np.sin(w * t / 2),
                               0.3 + 0.5 * t])) < 1e-14
    q2 = vmap.integrate(q0, [u, 0, 0, 0, 0, w, 0], t)  # constant body twist: a circle
    circle = u / w * np.array([np.sin(w * t), 1 - np.cos(w * t), 0])
    assert np.max(np.abs(q2[:3] - circle)) < 1e-14
    # a rotated base moves along its own axes: r₁ = r₀ + A₀ v Δt without rotation
    rng = np.random.default_rng(0)
    p = _quat(rng)
    q3 = vmap.integrate(np.r_[1, 2, 3, p, 0], [0.4, -0.2, 0.9, 0, 0, 0, 0], 0.5)
    assert np.max(np.abs(q3[:3] - ([1, 2, 3] + rotation_matrix(p) @ [0.2, -0.1, 0.45]))) \
        < 1e-14


def test_difference_inverts_integrate(vmap):
    rng = np.random.default_rng(1)
    for scale in (1e-9, 1e-3, 1.0, 2.5):  # series and closed forms, angles up to ~2.5 rad
        for _ in range(5):
            q0 = np.r_[rng.uniform(-1, 1, 3), _quat(rng), rng.uniform(-1, 1)]
            v = rng.normal(size=7)
            v[3:6] *= scale / np.linalg.norm(v[3:6])
            q1 = vmap.integrate(q0, v, 1.0)
            assert np.linalg.norm(q1[3:7]) == pytest.approx(1.0, abs=1e-15)
            assert np.max(np.abs(vmap.difference(q0, q1) - v)) < 1e-12
            back = vmap.integrate(q0, vmap.difference(q0, q1), 1.0)
            assert np.max(np.abs(back - q1)) < 1e-12
    q0 = np.r_[0, 0, 0, _quat(rng), 0]
    flipped = q0.copy()
    flipped[3:7] *= -1  # the same pose: zero difference
    assert np.max(np.abs(vmap.difference(q0, flipped))) < 1e-15


def test_velocity_map_is_the_derivative_of_integrate(vmap):
    import casadi as ca
    q_sym = ca.SX.sym("q", vmap.nq)
    gmat = ca.Function("G", [q_sym], [vmap.rates_matrix(q_sym)])
    rng = np.random.default_rng(2)
    h = 1e-5
    for _ in range(5):
        q = np.r_[rng.uniform(-1, 1, 3), _quat(rng), rng.uniform(-1, 1)]
        v = rng.normal(size=7)
        fd = (vmap.integrate(q, v, h) - vmap.integrate(q, v, -h)) / (2 * h)
        assert np.max(np.abs(fd - np.asarray(gmat(q)) @ v)) < 1e-8


def test_bad_arguments_are_named(vmap):
    with pytest.raises(ModelError, match="v: expected a vector of length 7"):
        vmap.integrate(np.zeros(8), np.zeros(8))
    with pytest.raises(ModelError, match=r"body 'base'.*quaternion is zero"):
        vmap.integrate(np.zeros(8), np.zeros(7))


def test_one_free_link_mass_matrix_closed_form():
    m, c, inertia = 2.5, np.array([0.1, -0.2, 0.05]), np.array([0.3, 0.4, 0.5])
    text = '<robot name="one">' + LINK.format(name="b", m=m, c="0.1 -0.2 0.05",
                                                i=tuple(inertia)) + '</robot>'
    model = casmbd.compile(loads_urdf(text, floating_base=True), mode="vm")
    assert (model.nq, model.nv, model.nc) == (7, 6, 0)
    skew = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
    expected = np.block([[m * np.eye(3), m * skew.T],
                         [m * skew, np.diag(inertia) + m * skew.T @ skew]])
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = np.r_[rng.uniform(-1, 1, 3), _quat(rng)]
        assert np.max(np.abs(model.mass_matrix(q) - expected)) < 1e-13
        # ω = 0: the origin falls with g whatever c: v̇ = Aᵀ g, ω̇ = 0
        v = np.r_[rng.normal(size=3), 0, 0, 0]
        a = model.forward_dynamics(q, v, np.zeros(6))
        g_body = rotation_matrix(q[3:7]).T @ [0, 0, -9.81]
        assert np.max(np.abs(a - np.r_[g_body, 0, 0, 0])) < 1e-12
        v, tau = rng.normal(size=6), rng.normal(size=6)
        acc = model.forward_dynamics(q, v, tau)
        assert np.max(np.abs(model.inverse_dynamics(q, v, acc) - tau)) < 1e-11


def test_centroidal_free_body_euler_equations():
    inertia = np.array([0.3, 0.4, 0.5])
    text = '<robot name="one">' + LINK.format(name="b", m=1.5, c="0 0 0",
                                                i=tuple(inertia)) + '</robot>'
    model = casmbd.compile(loads_urdf(text, floating_base=True), mode="vm")
    rng = np.random.default_rng(4)
    for _ in range(3):
        q = np.r_[rng.uniform(-1, 1, 3), _quat(rng)]
        v = rng.normal(size=6)
        lin, om = v[:3], v[3:]
        a = model.forward_dynamics(q, v, np.zeros(6))
        g_body = rotation_matrix(q[3:7]).T @ [0, 0, -9.81]
        assert np.max(np.abs(a[:3] - (g_body - np.cross(om, lin)))) < 1e-12
        euler = -np.cross(om, inertia * om) / inertia
        assert np.max(np.abs(a[3:] - euler)) < 1e-12
    batch = model.forward_dynamics_batch(np.tile(q, (3, 1)), np.tile(v, (3, 1)),
                                         np.zeros((3, 6)))
    assert np.max(np.abs(batch - a)) < 1e-15
    with pytest.raises(ModelError, match=r"n_q = 7 \(q\), n_v = 6"):
        model.forward_dynamics(q, np.zeros(7), np.zeros(7))


def test_scene_key(tmp_path):
    (tmp_path / "arm.urdf").write_text(ARM)
    head = '[scene]\ncoordinates = "joint"\nurdf = "arm.urdf"\n'
    mech = casmbd.loads_scene(head + "floating_base = true\n", str(tmp_path / "s.toml"))
    assert list(mech.bodies) == ["base", "link1"]
    mech = casmbd.loads_scene(head + "floating_base = false\n", str(tmp_path / "s.toml"))
    assert list(mech.bodies) == ["link1"]
    with pytest.raises(SceneError, match="key 'floating_base': expected true or false"):
        casmbd.loads_scene(head + 'floating_base = "yes"\n', str(tmp_path / "s.toml"))
    with pytest.raises(SceneError, match=r"key 'floating_base'.*needs 'urdf'"):
        casmbd.loads_scene("[scene]\ndimension = 3\nfloating_base = true\n",
                           str(tmp_path / "s.toml"))
    massless = ARM.replace('<mass value="3.0"/>', '<mass value="0"/>')
    with pytest.raises(SceneError, match=r"root link 'base'.*has no mass"):
        loads_urdf(massless, floating_base=True)
    held = ('<robot name="h"><link name="world"/><joint name="free" type="floating">'
            '<parent link="world"/><child link="b"/></joint>'
            + LINK.format(name="b", m=1.0, c="0 0 0", i=(1, 1, 1)) + '</robot>')
    with pytest.raises(SceneError, match=r"floating joint 'free' already frees the robot"):
        loads_urdf(held, floating_base=True)
    assert list(loads_urdf(held).bodies) == ["b"]  # the file's own floating joint


def _quadrotor():
    from benchmarks.robots_vs_pinocchio import robots_dir
    root = robots_dir()
    if root is None:
        pytest.skip("example-robot-data is not installed")
    return root / "hector_description/robots/quadrotor_base.urdf"


def test_quadrotor_free_fall_and_angular_momentum():
    mech = casmbd.load_urdf(_quadrotor(), floating_base=True)
    (name, body), = mech.bodies.items()
    v0, w0 = np.array([1.0, 0.5, 2.0]), np.array([0.3, -2.0, 1.0])
    body.velocity, body.angular_velocity = v0, w0
    res = casmbd.simulate(mech, 1.0, 10, rtol=1e-10)
    motion = res.body(name)
    t = np.asarray(res.t)[:, None]
    r0 = np.asarray(body.position)
    fall = r0 + v0 * t + 0.5 * np.array([0, 0, -9.81]) * t ** 2
    assert np.max(np.abs(motion["position"] - fall)) < 1e-6
    tensor = np.diag([float(x) for x in body.inertia[:3]])
    momentum = np.array([a @ tensor @ a.T @ w for a, w in
                         zip(motion["rotation"], motion["angular_velocity"])])
    h0 = tensor @ w0
    assert np.max(np.abs(momentum - h0)) < 1e-6 * np.linalg.norm(h0)
    # the spin is not trivial: the angular velocity itself precesses
    assert np.max(np.abs(motion["angular_velocity"][-1] - w0)) > 1e-2


def test_bare_urdf_floating_base_flag(tmp_path, capsys):
    """Every verb reading a scene takes a bare .urdf; ``--floating-base`` floats its root."""
    import json

    from casmbd.cli import main

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM)
    for flags, dof in (([], 1), (["--floating-base"], 7)):
        assert main(["info", str(urdf), "--json", *flags]) == 0
        out = json.loads(capsys.readouterr().out)
        assert out["degrees_of_freedom"] == dof
    assert casmbd.load_scene(urdf, floating_base=True).bodies.keys() == {"base", "link1"}
    scene = tmp_path / "s.toml"
    scene.write_text('[scene]\nurdf = "arm.urdf"\n')
    assert main(["info", str(scene), "--floating-base"]) != 0
    assert "--floating-base applies to a bare .urdf" in capsys.readouterr().err


def test_rates_conversions(vmap):
    """q̇ = G v and back; q̈ = G a + Ġ v as the central difference of q̇ along the motion
    q(t) = q ⊕ (v t + ½ a t²) (error O(h²))."""
    rng = np.random.default_rng(5)
    h = 1e-4
    for _ in range(3):
        q = np.r_[rng.uniform(-1, 1, 3), _quat(rng), rng.uniform(-1, 1)]
        v, a = rng.normal(size=7), rng.normal(size=7)
        qdot = vmap.rates_from_velocity(q, v)
        assert np.dot(qdot[3:7], q[3:7]) == pytest.approx(0.0, abs=1e-15)
        assert np.max(np.abs(vmap.velocity_from_rates(q, qdot) - v)) < 1e-14

        def rates_at(t, q=q, v=v, a=a):
            return vmap.rates_from_velocity(vmap.integrate(q, v * t + 0.5 * a * t * t), v + a * t)
        fd = (rates_at(h) - rates_at(-h)) / (2 * h)
        assert np.max(np.abs(fd - vmap.rate_accelerations(q, v, a))) < 1e-7


def test_per_call_forward_dynamics_equals_the_simulation_start(tmp_path):
    """The analyses (q̇, Euler-parameter rates) and the per-call API (free-flyer v) agree:
    the compiled v̇ mapped to q̈ = G v̇ + Ġ v equals the simulation's first acceleration, with
    a moving joint and a spinning base (1e-8)."""
    mech = loads_urdf(ARM, floating_base=True, initial={"j1": (0.4, 1.5)})
    mech.bodies["base"].angular_velocity = np.array([0.2, -0.7, 0.4])
    sim = casmbd.simulate(mech, 0.01, 1, formulation="index1", mode="vm")
    model = casmbd.compile(loads_urdf(ARM, floating_base=True), mode="vm")
    q0, vmap = sim["q"][0], model.velocity_map
    nu = vmap.velocity_from_rates(q0, sim["v"][0])
    assert np.max(np.abs(vmap.rates_from_velocity(q0, nu) - sim["v"][0])) < 1e-12
    assert np.max(np.abs(nu[3:6])) > 0.1 and abs(nu[6]) > 0.1  # the base spins, j1 moves
    acc = vmap.rate_accelerations(q0, nu, model.forward_dynamics(q0, nu, np.zeros(7)))
    assert np.max(np.abs(acc - sim["a"][0])) < 1e-8 * max(1.0, np.max(np.abs(acc)))


TWO = ('<robot name="two">' + LINK.format(name="base", m=2.0, c="0 0 0", i=(0.3, 0.4, 0.5))
       + LINK.format(name="rotor", m=1.0, c="0 0 0", i=(0.1, 0.1, 0.2))
       + '<joint name="j" type="continuous"><parent link="base"/><child link="rotor"/>'
       '<axis xyz="0 0 1"/></joint></robot>')


def test_linearize_and_statics_of_a_free_base():
    """Base and rotor on a spring k about their common axis through both centres of mass,
    no gravity: six rigid-body modes at 0 Hz and ω² = k (1/I_b + 1/I_r) (the free-free
    torsional pair, 1e-9); statics finds the equilibrium; under gravity it has none and says
    so naming the base coordinate."""
    k, i_base, i_rotor = 3.0, 0.5, 0.2
    mech = loads_urdf(TWO, floating_base=True, gravity=(0, 0, 0))
    mech.add("rotational_spring_damper", "spring", joint="j", stiffness=k)
    lin = casmbd.linearize(mech, mode="vm")
    freqs = np.sort(np.asarray(lin.frequencies_hz))
    assert lin.n_dof == 7 and np.max(np.abs(freqs[:6])) < 1e-9
    expected = np.sqrt(k * (1 / i_base + 1 / i_rotor)) / (2 * np.pi)
    assert freqs[6] == pytest.approx(expected, rel=1e-9)
    assert np.max(np.abs(casmbd.static_equilibrium(mech, mode="vm").residual)) < 1e-9
    with pytest.raises(casmbd.AnalysisError, match=r"coordinate 'base\.z'"):
        casmbd.static_equilibrium(loads_urdf(TWO, floating_base=True), mode="vm")


def test_floating_base_with_a_mimic_pair_keeps_its_coupling():
    """A <mimic> follower on a floating base: the coupling's row is kept in the free-flyer
    velocities ((C_q G) v̇ = γ − C_q Ġ v); the per-call v̇ mapped to q̈ equals `simulate`'s
    first acceleration (1e-8) and zero efforts give back a zero least-norm τ (1e-10)."""
    mimic = ARM.replace('</robot>', LINK.format(name="link2", m=0.5, c="0 0 0.1",
                                                  i=(0.01, 0.01, 0.01))
                        + '<joint name="j2" type="revolute"><parent link="link1"/>'
                        '<child link="link2"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>'
                        '<mimic joint="j1" multiplier="-0.5" offset="0.1"/>'
                        '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>')
    mech = loads_urdf(mimic, floating_base=True, initial={"j1": (0.4, 1.5)})
    sim = casmbd.simulate(mech, 0.01, 1, formulation="index1", mode="vm")
    model = casmbd.compile(loads_urdf(mimic, floating_base=True), mode="vm")
    assert model.nv == model.nq - 1 and "normalization" not in " ".join(model.constraint_labels)
    q0, vmap = sim["q"][0], model.velocity_map
    nu = vmap.velocity_from_rates(q0, sim["v"][0])
    acc = model.forward_dynamics(q0, nu, np.zeros(model.nv))
    qdd = vmap.rate_accelerations(q0, nu, acc)
    assert np.max(np.abs(qdd - sim["a"][0])) < 1e-8 * max(1.0, np.max(np.abs(qdd)))
    assert np.max(np.abs(model.inverse_dynamics(q0, nu, acc))) < 1e-10
