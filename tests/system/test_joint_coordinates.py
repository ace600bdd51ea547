"""Joint (relative) coordinates: the same trajectories, reactions and efforts as absolute and
natural coordinates, and an independent Newton–Euler recursion for a 6R arm."""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from benchmarks.chains import pendulum_chain, spatial_chain
from casmbd import Mechanism, System
from casmbd.errors import ModelError
from tests.mechanisms import triple_crank

G = 9.81
EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


_cache = private_cache("cache_joint")


def with_coordinates(mech: Mechanism, coordinates: str) -> Mechanism:
    mech.coordinates = coordinates
    mech.name = f"{mech.name}_{coordinates}"
    return mech


def test_chain_in_joint_coordinates_has_no_constraint_equation():
    system = System(with_coordinates(pendulum_chain(8), "joint"))
    assert system.nq == 8 and system.nc == 0
    assert system.coordinate_names == [f"pin{i}.angle" for i in range(8)]
    assert system.tree_joints == [f"pin{i}" for i in range(8)]


@pytest.mark.parametrize("coordinates", ["joint", "natural"])
def test_chain_trajectories_agree(coordinates):
    """8-rod chain released horizontally: body positions agree with absolute to 1e-8 m."""
    ref = casmbd.simulate(pendulum_chain(8), t_end=1.0, steps=10, rtol=1e-12)
    out = casmbd.simulate(with_coordinates(pendulum_chain(8), coordinates), t_end=1.0,
                          steps=10, rtol=1e-12)
    assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-8
    # tree reactions by the leaves-to-root recursion equal the absolute multipliers' (1e-9
    # relative to the largest reaction)
    scale = np.max(np.abs(ref["joint_reactions"]))
    assert np.max(np.abs(out["joint_reactions"] - ref["joint_reactions"])) < 1e-9 * scale


@pytest.mark.parametrize("coordinates", ["joint", "natural"])
def test_four_bar_trajectories_and_reactions_agree(coordinates):
    """The driven four-bar: positions (1e-8 m), reactions and driver efforts (1e-9 relative)."""
    ref = casmbd.simulate(casmbd.load_scene(f"{EXAMPLES}/four_bar.toml"), t_end=1.0,
                          steps=10, rtol=1e-12)
    mech = with_coordinates(casmbd.load_scene(f"{EXAMPLES}/four_bar.toml"), coordinates)
    out = casmbd.simulate(mech, t_end=1.0, steps=10, rtol=1e-12)
    assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-8
    scale = np.max(np.abs(ref["joint_reactions"]))
    assert np.max(np.abs(out["joint_reactions"] - ref["joint_reactions"])) < 1e-9 * scale
    if coordinates == "joint":
        system = System(mech)
        assert system.nq == 3 and len(system.tree_joints) == 3  # one loop joint left


def test_inverse_dynamics_with_actuators_agree():
    """Mixed inverse dynamics (driver on the slider, motor at the crank): efforts and
    reactions in joint coordinates equal the absolute ones (1e-10 relative)."""
    path = f"{EXAMPLES}/slider_crank_inverse.toml"
    ref = casmbd.inverse_dynamics(casmbd.load_scene(path), t_end=1.0, steps=20)
    out = casmbd.inverse_dynamics(with_coordinates(casmbd.load_scene(path), "joint"),
                                  t_end=1.0, steps=20)
    for key in ("actuator_efforts", "driver_efforts", "joint_reactions"):
        scale = max(1.0, float(np.max(np.abs(ref.arrays[key]))))
        assert np.max(np.abs(out.arrays[key] - ref.arrays[key])) < 1e-10 * scale, key


def test_spatial_ball_chain_agrees():
    """3 rods on ball joints (Euler parameters per joint) fall from a skewed pose."""
    def chain(coordinates):
        m = spatial_chain(3, coordinates=coordinates)
        m.name += coordinates
        m.gravity[:] = (0.0, 3.0, -G)  # out of the initial plane: a genuinely 3-D motion
        return m

    ref = casmbd.simulate(chain("absolute"), t_end=1.0, steps=10, rtol=1e-12)
    out = casmbd.simulate(chain("joint"), t_end=1.0, steps=10, rtol=1e-12)
    assert System(chain("joint")).nc == 3  # one normalisation per ball joint
    assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-8
    scale = np.max(np.abs(ref["joint_reactions"]))
    assert np.max(np.abs(out["joint_reactions"] - ref["joint_reactions"])) < 1e-8 * scale


def mixed_tree(coordinates: str) -> Mechanism:
    """A tree with every tree-joint type: revolute, universal, cylindrical, prismatic, rigid."""
    m = Mechanism(f"mixed_{coordinates}", gravity=(0.0, 0.0, -G), coordinates=coordinates)
    m.add_body("base", 2.0, [0.02, 0.03, 0.04], (0.0, 0.0, 0.1), velocity=(0.0, 0.0, 0.0),
               angular_velocity=(0.0, 0.0, 1.0))
    m.add_body("arm", 1.0, [0.01, 0.05, 0.05], (0.3, 0.0, 0.2))
    m.add_body("sleeve", 0.5, [0.01, 0.01, 0.002], (0.6, 0.0, 0.2))
    m.add_body("slider", 0.4, [0.004, 0.004, 0.004], (0.6, 0.1, 0.2))
    m.add_body("tip", 0.2, [0.001, 0.001, 0.001], (0.6, 0.2, 0.2))
    m.add_revolute("yaw", "ground", "base", point=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0))
    m.add_universal("shoulder", "base", "arm", point=(0.0, 0.0, 0.2), axis1=(0.0, 0.0, 1.0),
                    axis2=(0.0, 1.0, 0.0))
    m.add_cylindrical("wrist", "arm", "sleeve", point=(0.6, 0.0, 0.2), axis=(1.0, 0.0, 0.0))
    m.add_prismatic("rail", "sleeve", "slider", point=(0.6, 0.1, 0.2), axis=(0.0, 1.0, 0.0))
    m.add_rigid("weld", "slider", "tip")
    m.add_spring_damper("spring", "ground", "slider", (0.0, 0.5, 0.5), (0.6, 0.1, 0.2),
                        stiffness=20.0, damping=0.5)
    return m


def test_every_tree_joint_type_agrees():
    system = System(mixed_tree("joint"))
    assert system.nq == 1 + 2 + 2 + 1 and system.nc == 0
    ref = casmbd.simulate(mixed_tree("absolute"), t_end=0.5, steps=5, rtol=1e-12)
    out = casmbd.simulate(mixed_tree("joint"), t_end=0.5, steps=5, rtol=1e-12)
    assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-8
    assert np.max(np.abs(out["rotation_matrices"] - ref["rotation_matrices"])) < 1e-8
    scale = np.max(np.abs(ref["joint_reactions"]))
    assert np.max(np.abs(out["joint_reactions"] - ref["joint_reactions"])) < 1e-8 * scale


def test_floating_body_is_a_root_in_absolute_coordinates():
    m = Mechanism("free_joint", dimension=3, coordinates="joint")
    m.add_body("b", 2.0, [1.0, 2.0, 2.5], (0.0, 0.0, 0.0), angular_velocity=(0.1, 2.0, 0.1))
    system = System(m)
    assert system.nq == 7 and system.nc == 1
    out = casmbd.simulate(m, t_end=2.0, steps=4, rtol=1e-12)
    m2 = Mechanism("free_abs", dimension=3)
    m2.add_body("b", 2.0, [1.0, 2.0, 2.5], (0.0, 0.0, 0.0), angular_velocity=(0.1, 2.0, 0.1))
    ref = casmbd.simulate(m2, t_end=2.0, steps=4, rtol=1e-12)
    assert np.max(np.abs(out["rotation_matrices"] - ref["rotation_matrices"])) < 1e-9


def test_named_tree_and_bad_names():
    four_bar = casmbd.load_scene(f"{EXAMPLES}/four_bar.toml")
    four_bar.coordinates = "joint"
    loop = next(n for n in four_bar.joints if n not in System(four_bar).tree_joints)
    four_bar.tree = [loop]
    assert loop in System(four_bar).tree_joints
    four_bar.tree = ["nope"]
    with pytest.raises(ModelError, match="unknown joint 'nope'"):
        System(four_bar)
    four_bar.tree = list(four_bar.joints)  # all four pins: a cycle
    with pytest.raises(ModelError, match="close a loop"):
        System(four_bar)


# ----------------------------------------------------------------------------- 6R robot arm
AXES = np.array([[0, 0, 1], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0]], float)
LINK = 0.3
MASSES = [1.0 + 0.1 * i for i in range(6)]
INERTIA = np.array([[0.01, 0.001, 0.0], [0.001, 0.02, 0.0], [0.0, 0.0, 0.02]])


def joint_point(i: int) -> np.ndarray:
    return np.array([LINK * i, 0.0, 0.02 * i])


def com_point(i: int) -> np.ndarray:
    return np.array([LINK * i + 0.15, 0.0, 0.02 * i])


def arm(coordinates: str) -> Mechanism:
    m = Mechanism(f"arm6_{coordinates}", gravity=(0.0, 0.0, -G), coordinates=coordinates)
    parent = "ground"
    for i in range(6):
        m.add_body(f"l{i}", MASSES[i], [0.01, 0.02, 0.02, 0.001, 0.0, 0.0], com_point(i))
        m.add_revolute(f"j{i}", parent, f"l{i}", point=joint_point(i), axis=AXES[i])
        m.add_driver(f"d{i}", f"0.5*sin({i + 1}*t) + 0.1*{i}", joint=f"j{i}")
        parent = f"l{i}"
    return m


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def newton_euler_torques(phi, dphi, ddphi) -> np.ndarray:
    """Joint torques of the arm by the textbook recursion (outward kinematics, inward forces).

    Design pose: every body frame is the global frame, joint i at ``joint_point(i)`` about
    ``AXES[i]``.  Outward: A_i = A_{i−1} R(h_i, φ_i), ω_i = ω_{i−1} + ĥ_i φ̇_i,
    α_i = α_{i−1} + ĥ_i φ̈_i + ω_{i−1} × ĥ_i φ̇_i, with ĥ_i = A_{i−1} h_i, and the accelerations
    of the joint points and centres of mass by rigid-body transport.  Inward: f_i = m a_G −
    m g + f_{i+1}, n_i = I α + ω × I ω + n_{i+1} + (r_{i+1} − r_G) × f_{i+1} + (r_G − r_i) × f_i
    about the joint point; τ_i = ĥ_i · n_i.
    """
    g = np.array([0.0, 0.0, -G])
    rot = np.eye(3)
    omega = np.zeros(3)
    alpha = np.zeros(3)
    acc_prev = np.zeros(3)   # acceleration of the previous body's frame origin point
    pos_prev = np.zeros(3)   # position of that point
    origin_prev = np.zeros(3)
    frames = []
    for i in range(6):
        h = rot @ AXES[i]
        # joint point i moves with body i−1: transport from the previous reference point
        arm_j = rot @ (joint_point(i) - origin_prev)
        r_j = pos_prev + arm_j
        a_j = acc_prev + np.cross(alpha, arm_j) + np.cross(omega, np.cross(omega, arm_j))
        omega_new = omega + h * dphi[i]
        alpha = alpha + h * ddphi[i] + np.cross(omega, h * dphi[i])
        omega = omega_new
        rot = rot @ rodrigues(AXES[i], phi[i])
        arm_g = rot @ (com_point(i) - joint_point(i))
        r_g = r_j + arm_g
        a_g = a_j + np.cross(alpha, arm_g) + np.cross(omega, np.cross(omega, arm_g))
        frames.append((h, r_j, r_g, a_g, rot.copy(), omega.copy(), alpha.copy()))
        acc_prev, pos_prev, origin_prev = a_j, r_j, joint_point(i)
    torques = np.zeros(6)
    f_next, n_next, r_next = np.zeros(3), np.zeros(3), None
    for i in reversed(range(6)):
        h, r_j, r_g, a_g, rot, omega, alpha = frames[i]
        tensor = rot @ INERTIA @ rot.T
        f = MASSES[i] * (a_g - g) + f_next
        n = tensor @ alpha + np.cross(omega, tensor @ omega) + n_next
        n += np.cross(r_g - r_j, MASSES[i] * (a_g - g))
        if r_next is not None:
            n += np.cross(r_next - r_j, f_next)
        torques[i] = h @ n
        f_next, n_next, r_next = f, n, r_j
    return torques


def test_six_axis_arm_inverse_dynamics_matches_newton_euler():
    """Drive torques of a 6R arm in joint coordinates equal an independent recursion (1e-10)."""
    res = casmbd.inverse_dynamics(arm("joint"), t_end=1.0, steps=10)
    assert System(arm("joint")).nq == 6
    phi = res.arrays["joint_positions"][:, :6]
    dphi = res.arrays["joint_velocities"][:, :6]
    ddphi = res.arrays["joint_accelerations"][:, :6]
    for k in range(len(res.t)):
        tau = newton_euler_torques(phi[k], dphi[k], ddphi[k])
        assert np.max(np.abs(res.arrays["driver_efforts"][k] - tau)) < 1e-10
    ref = casmbd.inverse_dynamics(arm("absolute"), t_end=1.0, steps=10)
    assert np.max(np.abs(ref.arrays["driver_efforts"] - res.arrays["driver_efforts"])) < 1e-10


def _forced_arm() -> Mechanism:
    """The 6R arm without drivers, with a motor on j2, a rotational spring-damper on j3 and a
    body-frame torque and a point force on the last link."""
    m = arm("joint")
    m.name = "arm6_forced"
    m.drivers.clear()
    m.add_actuator("motor", "j2")
    m.add_rotational_spring_damper("spring", "j3", stiffness=12.0, damping=0.7,
                                   free_angle=0.2)
    m.add_torque("twist", "l5", (0.1, -0.2, 0.3), frame="body")
    m.add_force("push", "l5", (1.0, 2.0, -0.5), point=com_point(5) + np.array([0.05, 0.02, 0.0]))
    return m


def test_articulated_body_recursion_equals_mass_matrix_solve():
    """q̈ of the O(N) articulated-body recursion equals M⁻¹ (Q_e + Q_v) of the composite-body
    M at random states of the forced 6R arm and a planar chain (1e-10 relative)."""
    import casadi as ca

    from casmbd.system.articulated_body import articulated_accelerations

    rng = np.random.default_rng(3)
    for mech in (_forced_arm(), with_coordinates(pendulum_chain(5), "joint")):
        system = System(mech)
        args = [system.q, system.v, system.t, system.u, system.p]
        aba = ca.Function("aba", args, [articulated_accelerations(system)])
        rhs = ca.Function("rhs", args, [system.mass_matrix,
                                        system.applied_forces + system.quadratic_velocity_forces])
        for _ in range(3):
            vals = [rng.normal(size=system.nq), rng.normal(size=system.nq), 0.3,
                    rng.normal(size=system.u.numel()), system.parameter_values]
            mass, force = (np.asarray(x, dtype=float) for x in rhs(*vals))
            expected = np.linalg.solve(mass, force.ravel())
            got = np.asarray(aba(*vals), dtype=float).ravel()
            assert np.max(np.abs(got - expected)) < 1e-10 * (1 + np.max(np.abs(expected)))


def test_default_formulation_for_trees_and_energy_from_twists():
    """Trees without constraint equations default to the articulated-body recursion, loops to
    the augmented Lagrangian; both agree with kkt_ode on the trajectory (1e-9 m) and the
    kinetic energy from the recursive twists equals ½ q̇ᵀ M q̇ (1e-12 relative)."""
    from casmbd.analysis.dynamics.simulate import Simulator, default_formulation

    chain = with_coordinates(pendulum_chain(6), "joint")
    assert default_formulation(System(chain)) == "articulated"
    four_bar = with_coordinates(casmbd.load_scene(f"{EXAMPLES}/four_bar.toml"), "joint")
    assert default_formulation(System(four_bar)) == "augmented_lagrangian"
    assert default_formulation(System(pendulum_chain(3), coordinates="absolute")) == \
        "augmented_lagrangian"
    assert default_formulation(System(pendulum_chain(3))) == "articulated"  # auto: joint
    default = Simulator(chain).run(t_end=1.0, steps=10, rtol=1e-12)
    assert default.stats["formulation"] == "articulated"
    kkt = Simulator(chain, formulation="kkt_ode").run(t_end=1.0, steps=10, rtol=1e-12)
    assert np.max(np.abs(default["body_positions"] - kkt["body_positions"])) < 1e-9
    system = System(_forced_arm())
    import casadi as ca

    f = ca.Function("t", [system.q, system.v, system.p],
                    [system.kinetic_energy, 0.5 * ca.bilin(system.mass_matrix, system.v,
                                                           system.v)])
    rng = np.random.default_rng(5)
    t_twist, t_quad = (float(x) for x in f(rng.normal(size=6), rng.normal(size=6),
                                           system.parameter_values))
    assert abs(t_twist - t_quad) < 1e-12 * abs(t_quad)


@pytest.mark.parametrize("coordinates", ["absolute", "joint"])
def test_redundant_loop_reactions_are_flagged_not_zero(coordinates):
    """The self-stress of the three parallel cranks (axial forces along the cranks, (1, −2, 1))
    leaves the pin forces along the crank direction undetermined: at t = 0 (cranks vertical)
    Fy only, later Fx and Fy, reported for the minimum-norm multipliers (finite; issue 30)
    with a warning naming the joints; the pin moments are determined (zero) and at t = 0 the
    horizontal forces too (equal in both coordinate choices, 1e-9); the motion equals the
    absolute-coordinate one (1e-8 m).  The minimum-norm distribution is over the multipliers
    of the coordinate choice (every joint's in absolute coordinates, the loop joints' in joint
    coordinates), so the undetermined components are compared only within one choice."""
    # t ≤ 0.5 s: the cranks reach the horizontal singular pose at t ≈ 0.687 s (issue 7)
    ref = casmbd.simulate(triple_crank("absolute"), t_end=0.5, steps=10, rtol=1e-12)
    with pytest.warns(RuntimeWarning, match=r"cannot be determined.*'g0'"):
        out = casmbd.simulate(triple_crank(coordinates), t_end=0.5, steps=10, rtol=1e-12)
    assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-8
    reac = out["joint_reactions"]
    assert np.all(np.isfinite(reac)) and out.stats["reactions"] == "minimum_norm"
    if coordinates == "absolute":
        assert np.max(np.abs(reac - ref["joint_reactions"])) < 1e-9
    assert np.max(np.abs(reac[0, :, 0] - ref["joint_reactions"][0, :, 0])) < 1e-9
    assert np.all(np.isfinite(reac[:, :, 2])) and np.max(np.abs(reac[:, :, 2])) < 1e-9
    flags = out.stats["undetermined_reactions"]
    assert set(flags) == {"g0", "g1", "g2", "t0", "t1", "t2"}
    assert all(comps == [0, 1] for comps in flags.values())
    # a mechanism without redundancy flags nothing
    four_bar = casmbd.simulate(casmbd.load_scene(f"{EXAMPLES}/four_bar.toml"), t_end=0.2,
                               steps=4)
    assert four_bar.stats["undetermined_reactions"] == {}
    assert four_bar.stats["reactions"] == "determined"
    assert np.all(np.isfinite(four_bar["joint_reactions"]))


@pytest.mark.parametrize("coordinates", ["joint", "natural"])
def test_statics_and_linearization_agree(coordinates):
    """Static equilibrium of the hanging chain (positions 1e-9 m, reactions 1e-8 relative)
    and the natural frequencies of the double pendulum hanging down (1e-8 relative) equal
    the absolute-coordinate ones."""
    ref = casmbd.static_equilibrium(casmbd.load_scene(f"{EXAMPLES}/hanging_chain.toml"))
    out = casmbd.static_equilibrium(with_coordinates(
        casmbd.load_scene(f"{EXAMPLES}/hanging_chain.toml"), coordinates))
    assert np.max(np.abs(out.body_positions - ref.body_positions)) < 1e-9
    scale = np.max(np.abs(ref.joint_reactions))
    assert np.max(np.abs(out.joint_reactions - ref.joint_reactions)) < 1e-8 * scale
    hanging = pendulum_chain(2)
    lin_ref = casmbd.linearize(hanging, q=None)
    lin = casmbd.linearize(with_coordinates(pendulum_chain(2), coordinates))
    assert lin.n_dof == lin_ref.n_dof == 2
    assert np.allclose(np.sort(lin.frequencies_hz), np.sort(lin_ref.frequencies_hz),
                       rtol=1e-8, atol=0.0)
