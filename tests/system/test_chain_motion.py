"""Outputs and energies of a planar revolute chain folded over the bodies
(casmbd.system.chain_motion, issue 36 item 5) against the body-by-body expressions and,
through the simulator, fold=True against fold=False."""

from __future__ import annotations

import numpy as np

from benchmarks.chains import pendulum_chain
from casmbd.analysis.dynamics.simulate import Simulator
from casmbd.system import chain_motion, chain_reactions
from casmbd.system.equations import System


def _system(n: int) -> System:
    mech = pendulum_chain(n)
    mech.coordinates = "joint"
    return System(mech)


def _close(got, want, what):
    got, want = np.asarray(got, float).ravel(), np.asarray(want, float).ravel()
    scale = max(1.0, float(np.max(np.abs(want), initial=0.0)))
    assert got.shape == want.shape, what
    assert np.max(np.abs(got - want), initial=0.0) <= 1e-12 * scale, what


def test_folded_outputs_and_energies_equal_the_unrolled_ones_on_24_rods():
    """Every output (bodies, angles, tip marker, joints: positions, velocities,
    accelerations) and T, V equal the System's expressions to 1e-12 relative to the
    largest entry, at random states with rates up to 2 rad/s and random q̈."""
    system = _system(24)
    assert chain_motion.supported(system) is None
    unrolled = system.outputs_function()
    folded = chain_motion.folded_outputs(system)
    assert folded.name_out() == unrolled.name_out()
    kin, pot = chain_motion.folded_energies(system)
    p = system.parameter_values
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v, a = (rng.uniform(-2.0, 2.0, system.nq) for _ in range(3))
        for name, got, want in zip(unrolled.name_out(), folded(q, v, a, 0.2, p),
                                   unrolled(q, v, a, 0.2, p)):
            _close(got, want, name)
        _close(kin(q, v, p), system.function("kinetic_energy")(q, v, p), "T")
        _close(pot(q, 0.2, p), system.function("potential_energy")(q, 0.2, p), "V")


def test_folded_reactions_and_mass_matrix_equal_the_unrolled_ones_on_24_rods():
    """The backward Newton–Euler fold: every joint reaction (F_x, F_y, M) and every entry
    of M equal the System's Functions to 1e-12 relative to the largest entry; M is
    symmetric to the same tolerance (it is built column by column, not symmetrised)."""
    system = _system(24)
    unrolled_r = system.reactions_function()
    folded_r = chain_reactions.folded_reactions(system)
    folded_m = chain_reactions.folded_mass_matrix(system)
    p, u, lam = system.parameter_values, np.zeros(system.u.numel()), np.zeros(system.nc)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q, v, a = (rng.uniform(-2.0, 2.0, system.nq) for _ in range(3))
        _close(folded_r(q, v, a, 0.0, u, p, lam), unrolled_r(q, v, a, 0.0, u, p, lam),
               "reactions")
        m = np.asarray(folded_m(q, p))
        _close(m, system.function("mass_matrix")(q, p).full(), "M")
        _close(m, m.T, "M symmetric")


def test_simulation_folded_equals_unrolled_on_32_rods():
    """simulate: fold=True and fold=False give the same q, every output, the energies and
    the joint reactions to 1e-12 relative (DOPRI5 at rtol 1e-9: the same steps when the
    right-hand sides agree to rounding)."""
    mech = pendulum_chain(32)
    runs = {}
    for fold in (True, False):
        sim = Simulator(mech, "articulated", formulation_options={"fold": fold})
        runs[fold] = sim.run(0.2, 4, rtol=1e-9)
    folded, unrolled = runs[True], runs[False]
    assert folded.arrays.keys() == unrolled.arrays.keys()
    for key in ("q", "v", "a", "body_positions", "body_velocities", "body_accelerations",
                "angle_positions", "marker_positions", "marker_accelerations",
                "joint_velocities", "kinetic_energy", "potential_energy",
                "joint_reactions"):
        _close(folded[key], unrolled[key], key)


def _irregular_chain(n: int) -> System:
    """Rods of different masses, inertias, lengths and initial angles, reference points off
    the centres of mass, joints declared child first every third body, markers with angles."""
    from casmbd.model import Mechanism

    mech = Mechanism("irregular", gravity=(0.3, -9.81))
    mech.coordinates = "joint"
    mech.add_parameter("m_mid", 1.3)
    mech.add_parameter("j_mid", 0.2)
    rng = np.random.default_rng(11)
    joint, parent = np.zeros(2), "ground"
    for k in range(n):
        length, angle = rng.uniform(0.5, 1.5), rng.uniform(-1.0, 1.0)
        axis = np.array([np.cos(angle), np.sin(angle)])
        centre = joint + 0.5 * length * axis
        mass, inertia = rng.uniform(0.5, 2.0), rng.uniform(0.05, 0.3)
        if k == n // 2:  # the mass and inertia of one body are parameters
            mass, inertia = "2 * m_mid", "j_mid"
        mech.add_body(f"b{k}", mass=mass, inertia=inertia,
                      position=tuple(centre), angle=float(rng.uniform(-0.5, 0.5)),
                      reference_point=tuple(centre + 0.1 * axis))
        bodies = (f"b{k}", parent) if k % 3 == 2 else (parent, f"b{k}")
        mech.add_revolute(f"j{k}", *bodies, point=tuple(joint))
        mech.add_marker(f"m{k}", f"b{k}", point=tuple(joint + 0.8 * length * axis),
                        angle=float(rng.uniform(-1.0, 1.0)))
        joint, parent = joint + length * axis, f"b{k}"
    return System(mech)


def test_irregular_chain_folds_to_the_same_numbers():
    """Outputs, T, V, reactions and M of an irregular 12-body chain (see _irregular_chain:
    the per-body data differ, reaction signs follow each joint's body order, one body's
    mass and inertia are parameters, evaluated away from their defaults) equal the
    unrolled Functions to 1e-12."""
    system = _irregular_chain(12)
    assert chain_motion.supported(system) is None
    unrolled = system.outputs_function()
    folded = chain_motion.folded_outputs(system)
    kin, pot = chain_motion.folded_energies(system)
    p, u, lam = 1.5 * system.parameter_values, np.zeros(system.u.numel()), np.zeros(system.nc)
    assert p.size == 2
    q, v, a = (np.random.default_rng(2).uniform(-2.0, 2.0, system.nq) for _ in range(3))
    for name, got, want in zip(unrolled.name_out(), folded(q, v, a, 0.0, p),
                               unrolled(q, v, a, 0.0, p)):
        _close(got, want, name)
    _close(kin(q, v, p), system.function("kinetic_energy")(q, v, p), "T")
    _close(pot(q, 0.0, p), system.function("potential_energy")(q, 0.0, p), "V")
    _close(chain_reactions.folded_reactions(system)(q, v, a, 0.0, u, p, lam),
           system.reactions_function()(q, v, a, 0.0, u, p, lam), "reactions")
    _close(chain_reactions.folded_mass_matrix(system)(q, p),
           system.function("mass_matrix")(q, p).full(), "M")
