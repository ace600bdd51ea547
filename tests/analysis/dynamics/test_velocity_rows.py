"""Rows written at the velocity level (issue 37) in every forward-dynamics formulation, in the
consistent start and in the analyses that refuse them.

The Chaplygin sleigh (:mod:`nonholonomic_scenes`): a knife edge 0.4 m behind G, started at
u₀ = 0.5 m/s, ω₀ = 1.2 rad/s, has the closed form u = V tanh(λt + φ₀), ω = ω₀ cosh φ₀ /
cosh(λt + φ₀).  Every formulation that handles the need reproduces it over 2 s at rtol 1e-10
to 1e-8 (measured: index1 1.4e-9, ggl 3.6e-9, kkt_ode 4.8e-10, augmented_lagrangian 7.4e-10,
nullspace 1.6e-9), in absolute, natural and joint coordinates; the others refuse it by name.
"""

from __future__ import annotations

import numpy as np
import pytest
from nonholonomic_scenes import SLEIGH, add_knife_edge, sleigh, sleigh_closed_form, sleigh_motion

import casmbd
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.analysis.formulations import FORMULATIONS, default_formulation
from casmbd.analysis.instant.assembly import assemble
from casmbd.compiled.build import compile_model
from casmbd.errors import CompositionError
from casmbd.system.equations import System

HANDLING = [name for name, kind in FORMULATIONS.items()
            if "velocity_constraints" in kind.handles]


def test_the_formulations_that_handle_velocity_rows():
    """The declarations: every compiled DAE/ODE formulation with multipliers or a null space
    handles them; the independent-coordinate and tree-only ones do not."""
    assert set(HANDLING) == {"index1", "ggl", "kkt_ode", "augmented_lagrangian", "nullspace"}


@pytest.mark.parametrize("formulation", HANDLING)
def test_sleigh_closed_form_in_every_formulation(formulation):
    res = casmbd.simulate(sleigh(), 2.0, 20, formulation=formulation, rtol=1e-10, mode="vm")
    u, omega = sleigh_motion(res)
    u_ref, omega_ref = sleigh_closed_form(res.t)
    assert np.max(np.abs(u - u_ref)) <= 1e-8
    assert np.max(np.abs(omega - omega_ref)) <= 1e-8
    assert np.max(np.abs(res["velocity_violation"])) <= 1e-8  # the blade holds
    # energy: the blade's force does no work (m u² + I_P ω² constant)
    energy = res["kinetic_energy"]
    assert np.max(np.abs(energy - energy[0])) <= 1e-8


@pytest.mark.parametrize("coordinates", ["natural", "joint"])
def test_sleigh_in_other_coordinates_and_the_default_choice(coordinates):
    """The default formulation handles the rows (the automatic choice never picks one that
    refuses them), in natural and joint coordinates alike."""
    mech = sleigh(coordinates=coordinates)
    kind = FORMULATIONS[default_formulation(System(mech))]
    assert "velocity_constraints" in kind.handles
    res = casmbd.simulate(mech, 2.0, 10, rtol=1e-10, mode="vm")
    u, omega = sleigh_motion(res)
    u_ref, omega_ref = sleigh_closed_form(res.t)
    assert np.max(np.abs(u - u_ref)) <= 1e-8
    assert np.max(np.abs(omega - omega_ref)) <= 1e-8


@pytest.mark.parametrize("kw", [{"projection": True}, {"integrator": "rk4", "step": 1e-3}])
def test_projection_and_fixed_step(kw):
    """The projection assembles the holonomic rows and projects v onto every row: the blade
    then holds to rounding (1e-14) at every output."""
    res = casmbd.simulate(sleigh(), 1.0, 10, formulation="kkt_ode", rtol=1e-10, mode="vm",
                          **kw)
    u, omega = sleigh_motion(res)
    u_ref, omega_ref = sleigh_closed_form(res.t)
    assert np.max(np.abs(u - u_ref)) <= 1e-8 and np.max(np.abs(omega - omega_ref)) <= 1e-8
    if kw.get("projection"):
        assert np.max(np.abs(res["velocity_violation"])) <= 1e-14


@pytest.mark.parametrize("formulation,why", [("partitioning", "independent velocities"),
                                             ("articulated", "unconstrained tree")])
def test_formulations_that_refuse_name_the_joint_and_the_need(formulation, why):
    with pytest.raises(CompositionError) as info:
        casmbd.simulate(sleigh(), 0.1, 1, formulation=formulation, mode="vm")
    text = str(info.value)
    assert "joint 'knife'" in text and "non-holonomic" in text and why in text
    assert "instead" in text
    assert info.value.refused == [("joint 'knife'", "velocity_constraints")]


def test_consistent_start_projects_the_velocity_mass_orthogonally():
    """A sideslip of 0.3 m/s given at the start (inconsistent with the blade) is removed by
    the mass-orthogonal projection v = v₀ − M⁻¹Aᵀ (A M⁻¹ Aᵀ)⁻¹ (A v₀ + b), the velocity of
    least kinetic-energy change (seed 003, mass-orthogonal projections): A v = 0 to 1e-12 and
    v equal to that formula to 1e-12."""
    mech = sleigh(lateral=0.3)
    sim = Simulator(mech, "index1", mode="vm")
    res = sim.run(0.01, 1, rtol=1e-10)
    q0, v_start = res["q"][0], res["v"][0]
    model = sim.model
    a_mat = model.constraint_jacobian(q0, 0.0).toarray()
    b_vec = model.constraint_time_derivative(q0, 0.0)
    assert np.max(np.abs(a_mat @ v_start + b_vec)) <= 1e-12
    m_mat = model.mass_matrix(q0).toarray()
    v_given = model.initial_velocities()
    minv_at = np.linalg.solve(m_mat, a_mat.T)
    expected = v_given - minv_at @ np.linalg.solve(a_mat @ minv_at, a_mat @ v_given + b_vec)
    assert np.max(np.abs(v_start - expected)) <= 1e-12
    # by hand: the lateral unit l = (0, 1) at P; M = diag(m, m, I_G); the sideslip s = 0.3 of
    # G is shared between ẏ and θ̇ in the ratio 1/m : a²/I_G of the projection
    m, i_g, a = SLEIGH["m"], SLEIGH["inertia"], SLEIGH["a"]
    share = 0.3 / (1.0 / m + a * a / i_g)
    assert abs((v_given[1] - v_start[1]) - share / m) <= 1e-12
    assert abs((v_given[2] - v_start[2]) - (-a) * share / i_g) <= 1e-12
    assert res.stats["start_velocity_change"] > 0.1


def test_assembly_leaves_the_velocity_rows_out():
    """A violated distance joint next to the blade: the Newton steps are those of the
    position rows alone (minimum-norm), so the assembled pose equals the one of the same
    mechanism without the blade (1e-12); the blade's row would otherwise forbid moving P
    sideways."""
    def build(blade: bool):
        m = casmbd.Mechanism("tethered", gravity=(0.0, 0.0), coordinates="absolute")
        m.add_body("sleigh", mass=2.0, inertia=0.15, position=(0.0, 0.0))
        m.add("distance", "tether", "ground", "sleigh", (0.0, 1.0), (0.0, 0.0), length=1.3)
        if blade:
            add_knife_edge(m, "knife", "sleigh", (-0.4, 0.0), (1.0, 0.0))
        return m
    with_blade = compile_model(System(build(True)), "kinematics", mode="vm")
    without = compile_model(System(build(False)), "kinematics", mode="vm")
    assert with_blade.velocity_rows == [1] and with_blade.holonomic_rows == [0]
    q0 = with_blade.initial_coordinates()
    q_b, q_n = assemble(with_blade, q0, 0.0).q, assemble(without, q0, 0.0).q
    assert np.max(np.abs(q_b - q_n)) <= 1e-12
    assert abs(np.hypot(q_b[0], q_b[1] - 1.0) - 1.3) <= 1e-11
    assert abs(q_b[1]) > 0.2  # P moved sideways (along the blade's normal)


def test_statics_and_linearize_refuse_by_name():
    with pytest.raises(CompositionError, match=r"statics: joint 'knife' needs .*not "
                                               r"isolated.*instead: simulate"):
        casmbd.static_equilibrium(sleigh(), mode="vm")
    with pytest.raises(CompositionError, match=r"linearize: joint 'knife' needs .*instead: "
                                               r"linearize about a steady motion"):
        casmbd.linearize(sleigh(), mode="vm")


def test_info_counts_velocity_and_configuration_freedoms():
    """Three coordinates, one blade: two free velocities, three configuration freedoms."""
    data = casmbd.info(sleigh())
    assert data["degrees_of_freedom"] == 2
    assert data["configuration_degrees_of_freedom"] == 3
    assert data["velocity_rows"] == ["knife.lateral"]


def test_sensitivity_through_the_blade_equals_finite_differences():
    """∂(x, θ)(1 s)/∂m of the sleigh by IDAS forward sensitivities and by the adjoint equal
    central differences of whole index-1 runs at rtol 1e-12 (1e-6 relative)."""
    def build(mass):
        m = sleigh()
        m.add_parameter("mass", mass)
        m.bodies["sleigh"].mass = "mass"
        return m

    def run(mass):
        res = casmbd.simulate(build(mass), 1.0, 1, rtol=1e-12, formulation="index1", mode="vm")
        body = res.body("sleigh")
        return np.array([body["position"][-1, 0], body["angle"][-1]])
    h = 1e-5
    fd = (run(2.0 + h) - run(2.0 - h)) / (2 * h)
    for method in ("forward", "adjoint"):
        sens = casmbd.sensitivity(build(2.0), ["sleigh_x", "sleigh_angle"], ["mass"],
                                  t_end=1.0, method=method)
        assert np.allclose(np.ravel(sens.jacobian), fd, rtol=1e-6, atol=1e-9), method


def test_sweep_point_equals_simulate(tmp_path):
    mech = sleigh()
    mech.add_parameter("extra", 1.0)
    res = casmbd.sweep(mech, {"extra": [1.0]}, t_end=0.6, steps=6, mode="vm", out_dir=tmp_path)
    direct = casmbd.simulate(sleigh(), 0.6, 6, mode="vm")
    assert np.max(np.abs(res.result(0)["q"] - direct["q"])) <= 1e-12


def test_an_impact_keeps_the_blade():
    """The sleigh's front (a 5 cm sphere 0.3 m ahead of G) hits a wall (restitution 0.5): the
    impulse projection takes every row of C_q, so the blade's row holds after the impact
    (1e-8), energy is lost, and the event-driven run agrees between the augmented Lagrangian
    and the index-1 DAE (impact time 1e-8 s, motion 1e-8; measured 3e-11, 1.3e-9)."""
    def build():
        m = sleigh(omega0=0.3)
        m.add_contact("wall", "sleigh", point=(0.3, 0.0), radius=0.05, origin=(0.6, 0.0),
                      normal=(-1.0, 0.0), restitution=0.5)
        return m
    runs = [casmbd.simulate(build(), 1.5, 30, rtol=1e-10, mode="vm", formulation=form)
            for form in ("augmented_lagrangian", "index1")]
    for res in runs:
        assert [e["kind"] for e in res.events] == ["impact"]
        assert np.max(np.abs(res["velocity_violation"])) <= 1e-8
        assert res["kinetic_energy"][-1] < 0.5 * res["kinetic_energy"][0]
    assert abs(runs[0].events[0]["time"] - runs[1].events[0]["time"]) <= 1e-8
    assert np.max(np.abs(runs[0]["q"] - runs[1]["q"])) <= 1e-8
