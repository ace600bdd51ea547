"""Coordinate partitioning (Wehage) and null-space (embedding) formulations.

Tolerances (all runs at rtol = atol = 1e-10):

* against the ``kkt_ode`` reference with the same Adams integrator: positions to 1e-7,
  velocities to 1e-7 · max(1, max |v|) (both are off the exact solution by ~1e-8 … 2e-7 after
  1 s, see the report);
* CVODES-BDF runs (finite-difference Jacobian of the Python right-hand side) are compared to the
  same Adams reference to 1e-6 / 1e-5 · max(1, max |v|): BDF's global error at rtol 1e-10 is ten
  times Adams' for every formulation, ``kkt_ode`` included;
* the horizontally released pendulum is back at angle 0 after the period
  T = 4·sqrt((2/3) L/g)·K(m = 1/2) to 1e-7;
* the double pendulum conserves its energy to 1e-7 relative (Adams, and BDF for partitioning;
  1e-6 for null space with BDF, which does not stabilise the constraints).

The mechanisms are built in absolute coordinates (x, y, angle per body: the q columns, the
partition's coordinate names and the equation counts below are theirs); the automatic choice
(joint coordinates) is checked by :func:`test_automatic_choice_four_bar`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import private_cache
from scipy.special import ellipk

from casmbd import Mechanism
from casmbd.analysis.dynamics.simulate import Simulator, simulate
from casmbd.analysis.formulations import partitioning as part
from casmbd.analysis.instant.kkt import accelerations_and_multipliers
from casmbd.errors import IntegratorError

G = 9.81
FORMULATIONS = ("partitioning", "nullspace")


_cache = private_cache("casmbd_cache_partitioning", scope="module")


# ---------------------------------------------------------------------------- mechanisms
def pendulum(name: str = "part_pendulum", coordinates: str = "absolute") -> Mechanism:
    """Uniform rod of length 1 pinned at one end, released horizontally."""
    m = Mechanism(name, gravity=(0.0, -G), coordinates=coordinates)
    m.add_body("rod", 1.0, 1 / 12, (0.5, 0.0))
    m.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
    return m


def double_pendulum(coordinates: str = "absolute") -> Mechanism:
    """Two unit rods: the first horizontal, the second hanging from its tip."""
    m = Mechanism("part_double_pendulum", gravity=(0.0, -G), coordinates=coordinates)
    m.add_body("a", 1.0, 1 / 12, (0.5, 0.0))
    m.add_body("b", 1.0, 1 / 12, (1.0, -0.5), angle=-math.pi / 2)
    m.add_revolute("o", "ground", "a", (0.0, 0.0))
    m.add_revolute("k", "a", "b", (1.0, 0.0))
    return m


def four_bar(name: str = "part_four_bar", coordinates: str = "absolute") -> Mechanism:
    """Crank-rocker under gravity: ground pivots (0, 0) and (0.8, 0), crank 0.2 vertical."""
    m = Mechanism(name, gravity=(0.0, -G), coordinates=coordinates)
    b, c, d = np.array([0.0, 0.2]), np.array([0.6437388, 0.47495519]), np.array([0.8, 0.0])
    m.add_body("crank", 0.4, 0.4 * 0.2**2 / 12, (0.0, 0.1), angle=math.pi / 2)
    m.add_body("coupler", 1.4, 1.4 * 0.7**2 / 12, tuple((b + c) / 2),
               angle=math.atan2(*(c - b)[::-1]))
    m.add_body("rocker", 1.0, 1.0 * 0.5**2 / 12, tuple((c + d) / 2),
               angle=math.atan2(*(c - d)[::-1]))
    m.add_revolute("A", "ground", "crank", (0.0, 0.0))
    m.add_revolute("B", "crank", "coupler", tuple(b))
    m.add_revolute("C", "coupler", "rocker", tuple(c))
    m.add_revolute("D", "ground", "rocker", tuple(d))
    return m


def parallelogram(coordinates: str = "absolute") -> Mechanism:
    """Unit parallelogram four-bar, crank vertical at +1 rad/s: collinear every half turn."""
    m = Mechanism("part_parallelogram", gravity=(0.0, -G), coordinates=coordinates)
    m.add_body("crank", 1.0, 1 / 12, (0.0, 0.5), angle=math.pi / 2, velocity=(-0.5, 0.0),
               angular_velocity=1.0)
    m.add_body("coupler", 1.0, 1 / 12, (0.5, 1.0), velocity=(-1.0, 0.0))
    m.add_body("rocker", 1.0, 1 / 12, (1.0, 0.5), angle=math.pi / 2, velocity=(-0.5, 0.0),
               angular_velocity=1.0)
    m.add_revolute("A", "ground", "crank", (0.0, 0.0))
    m.add_revolute("B", "crank", "coupler", (0.0, 1.0))
    m.add_revolute("C", "coupler", "rocker", (1.0, 1.0))
    m.add_revolute("D", "ground", "rocker", (1.0, 0.0))
    return m


MECHANISMS = {"double_pendulum": (double_pendulum, 10), "four_bar": (four_bar, 20)}


@pytest.fixture(scope="module")
def references():
    """kkt_ode (Adams, rtol 1e-10) over 1 s, per mechanism."""
    return {}


def _reference(references, key):
    if key not in references:
        build, steps = MECHANISMS[key]
        references[key] = simulate(build(), 1.0, steps, formulation="kkt_ode",
                                   integrator="adams", rtol=1e-10)
    return references[key]


# ---------------------------------------------------------------------------- accuracy
@pytest.mark.parametrize("key", list(MECHANISMS))
@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize("integrator", ["adams", "cvodes"])
def test_matches_kkt_ode(references, key, formulation, integrator):
    ref = _reference(references, key)
    build, steps = MECHANISMS[key]
    res = simulate(build(), 1.0, steps, formulation=formulation, integrator=integrator,
                   rtol=1e-10)
    tol_q = 1e-7 if integrator == "adams" else 1e-6
    tol_v = (1e-7 if integrator == "adams" else 1e-5) * max(1.0, np.max(np.abs(ref["v"])))
    assert res["q"].shape == ref["q"].shape
    assert np.max(np.abs(res["q"] - ref["q"])) < tol_q
    assert np.max(np.abs(res["v"] - ref["v"])) < tol_v
    # q̈ (post-processed from the KKT system at the output states) follows q and v
    scale_a = max(1.0, np.max(np.abs(ref["a"])))
    assert np.max(np.abs(res["a"] - ref["a"])) < (1e-6 if integrator == "adams" else 1e-5) * scale_a
    st = res.stats
    assert st["formulation"] == formulation and st["steps"] > 0
    assert st["rhs_evaluations"] > 0
    if integrator == "adams":
        assert st["jacobian_evaluations"] == 0
    else:
        assert st["jacobian_evaluations"] > 0
    if formulation == "partitioning":
        # the dependent coordinates are solved from C = 0 at every output
        assert np.max(res["constraint_violation"]) < 1e-12
        assert np.max(res["velocity_violation"]) < 1e-12
        assert isinstance(st["reselections"], int)
        assert len(st["independent_coordinates"]) == (1 if key == "four_bar" else 2)


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_automatic_choice_four_bar(references, formulation):
    """The automatic choice takes the joint angles A, B, D (C closes the loop, 2 equations);
    both formulations give the bodies' positions of the absolute-coordinate kkt_ode reference
    to 1e-7 m (measured 7.5e-9 partitioning, 8.8e-9 null space, Adams, rtol 1e-10)."""
    ref = _reference(references, "four_bar")
    res = simulate(four_bar(coordinates="auto"), 1.0, 20, formulation=formulation,
                   integrator="adams", rtol=1e-10)
    assert res.names["coordinates"] == ["A.angle", "B.angle", "D.angle"]
    for body in ("crank", "coupler", "rocker"):
        assert np.max(np.abs(res.body(body)["position"] - ref.body(body)["position"])) < 1e-7
    if formulation == "partitioning":
        assert len(res.stats["independent_coordinates"]) == 1
        assert res.stats["independent_coordinates"][0] in res.names["coordinates"]
        assert np.max(res["constraint_violation"]) < 1e-12


def test_pendulum_period():
    """Released horizontally, the rod is back at angle 0 after one period."""
    period = 4.0 * math.sqrt((2.0 / 3.0) * 1.0 / G) * ellipk(0.5)
    for formulation in FORMULATIONS:
        res = simulate(pendulum(), period, 20, formulation=formulation, integrator="adams",
                       rtol=1e-10)
        q = res["q"]
        assert abs(q[-1, 2]) < 1e-7, formulation
        assert abs(q[-1, 0] - 0.5) < 1e-7 and abs(q[-1, 1]) < 1e-7
        assert abs(q[10, 2] + math.pi) < 1e-7          # hanging on the other side at T/2
        if formulation == "partitioning":
            assert res.stats["independent_coordinates"] == ["rod.angle"]


@pytest.mark.parametrize("formulation,integrator,tol", [
    ("partitioning", "adams", 1e-7), ("partitioning", "cvodes", 1e-7),
    ("nullspace", "adams", 1e-7), ("nullspace", "cvodes", 1e-6)])
def test_double_pendulum_energy(formulation, integrator, tol):
    res = simulate(double_pendulum(), 2.0, 20, formulation=formulation, integrator=integrator,
                   rtol=1e-10)
    energy = res["total_energy"]
    assert np.max(np.abs(energy - energy[0])) / abs(energy[0]) < tol


def test_reselection_double_pendulum():
    """Full pivoting first picks (b.y, b.angle); b.y stops determining the pose when rod a passes
    the vertical, and the run switches to the two angles."""
    sim = Simulator(double_pendulum(), "partitioning")
    q0 = sim.system.initial_coordinates()
    first = part.select_partition(sim.model, q0, 0.0)
    assert first.names(sim.system.coordinate_names) == ["b.y", "b.angle"]
    res = sim.run(2.0, 20, integrator="adams", rtol=1e-10)
    assert res.stats["reselections"] >= 1
    assert res.stats["independent_coordinates"] == ["a.angle", "b.angle"]
    assert np.max(res["constraint_violation"]) < 1e-12


def test_four_bar_selection_and_conditioning():
    """The crank angle is chosen and stays well conditioned over the crank's full turn."""
    sim = Simulator(four_bar(), "partitioning")
    res = sim.run(2.0, 20, integrator="adams", rtol=1e-10)
    assert res.stats["independent_coordinates"] == ["crank.angle"]
    assert res.stats["reselections"] == 0
    assert res["q"][:, 2].max() > 2 * math.pi          # the crank turns over
    assert res.stats["dependent_condition"] < 100


def test_parallelogram_through_singular_poses():
    """The collinear poses (t ≈ 0.71 s and 1.22 s) are true singularities: C_q loses rank.
    Partitioning steps across them by re-selecting between the crank and rocker angles and stays
    on the parallelogram branch (the coupler does not rotate); the KKT and null-space ODEs, whose
    minimum-norm solutions do not see the branches, may leave it."""
    res = simulate(parallelogram(), 1.5, 15, formulation="partitioning", integrator="adams",
                   rtol=1e-10)
    assert res["q"][-1, 2] > 2 * math.pi                 # past the second collinear pose
    assert np.max(np.abs(res["q"][:, 5])) < 1e-9         # coupler angle
    assert np.max(np.abs(res["q"][:, 2] - res["q"][:, 8])) < 1e-9   # crank = rocker angle
    assert res.stats["reselections"] >= 1
    energy = res["total_energy"]
    assert np.max(np.abs(energy - energy[0])) < 1e-6 * max(1.0, abs(energy[0]))


# ---------------------------------------------------------------------------- special cases
@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_redundant_constraints(formulation):
    """A duplicated pivot makes C_q rank deficient; both formulations give the plain motion."""
    plain = simulate(pendulum(), 1.0, 10, formulation="kkt_ode", integrator="adams",
                     rtol=1e-10)
    m = pendulum("part_pendulum_redundant")
    m.add_revolute("pivot2", "ground", "rod", (0.0, 0.0))
    res = simulate(m, 1.0, 10, formulation=formulation, integrator="adams", rtol=1e-10)
    assert np.max(np.abs(res["q"] - plain["q"])) < 1e-7
    if formulation == "nullspace":
        assert res.stats["constraint_rank"] == 2
    else:
        assert res.stats["independent_coordinates"] == ["rod.angle"]


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_driven_four_bar(formulation):
    """Zero degrees of freedom: partitioning reduces to position analysis at the outputs."""
    m = four_bar("part_four_bar_driven")
    m.add_driver("drive", "pi / 2 + 2 * pi * t", joint="A")
    ref = simulate(m, 0.5, 10, formulation="kkt_ode", integrator="adams", rtol=1e-10)
    res = simulate(m, 0.5, 10, formulation=formulation, integrator="adams", rtol=1e-10)
    assert np.max(np.abs(res["q"] - ref["q"])) < 1e-7
    assert np.max(np.abs(res["q"][:, 2] - (math.pi / 2 + 2 * math.pi * res.t))) < 1e-7
    if formulation == "partitioning":
        assert res.stats["independent_coordinates"] == [] and res.stats["steps"] == 0


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_actuator_inputs(formulation):
    m = pendulum("part_pendulum_actuated")
    m.add_actuator("motor", "pivot")
    inputs = {"motor": "2 * sin(3 * t)"}
    ref = simulate(m, 1.0, 10, formulation="kkt_ode", integrator="adams", rtol=1e-10,
                   inputs=inputs)
    res = simulate(m, 1.0, 10, formulation=formulation, integrator="adams", rtol=1e-10,
                   inputs=inputs)
    assert np.max(np.abs(res["q"] - ref["q"])) < 1e-7


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_projection(formulation):
    res = simulate(double_pendulum(), 1.0, 10, formulation=formulation, integrator="adams",
                   rtol=1e-10, projection=True)
    assert res.stats["projection"] is True
    assert np.max(res["constraint_violation"]) < 1e-10
    assert np.max(res["velocity_violation"]) < 1e-10


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_failure_keeps_partial_results(formulation):
    with pytest.raises(IntegratorError) as info:
        simulate(double_pendulum(), 1.0, 10, formulation=formulation, integrator="adams",
                 rtol=1e-10, max_steps=30)
    err = info.value
    assert err.flag == "CV_TOO_MUCH_WORK"
    assert 0.0 <= err.time <= 1.0
    assert err.partial is not None and len(err.partial.t) < 11
    assert err.partial.t[-1] <= err.time


def test_nullspace_equals_kkt_and_brauchli():
    """SVD null-space q̈ = KKT q̈ = Brauchli's mass-orthogonal projection, at a moving state."""
    sim = Simulator(four_bar(), "nullspace")
    model = sim.model
    res = sim.run(0.3, 3, integrator="adams", rtol=1e-10)
    q, v, t = res["q"][-1], res["v"][-1], float(res.t[-1])
    a_kkt, _ = accelerations_and_multipliers(model, q, v, t)
    a_null = part.nullspace_accelerations(model, q, v, t)
    m_mat = model.mass_matrix(q).toarray()
    cq = model.constraint_jacobian(q, t).toarray()
    force = model.applied_forces(q, v, t) + model.quadratic_velocity_forces(q, v)
    gamma = model.acceleration_rhs(q, v, t)
    m_inv = np.linalg.inv(m_mat)
    a_free = m_inv @ force
    a_brauchli = a_free - m_inv @ cq.T @ np.linalg.pinv(cq @ m_inv @ cq.T) @ (cq @ a_free - gamma)
    scale = max(1.0, np.max(np.abs(a_kkt)))
    assert np.max(np.abs(a_null - a_kkt)) < 1e-9 * scale
    assert np.max(np.abs(a_brauchli - a_kkt)) < 1e-9 * scale
    assert np.max(np.abs(cq @ a_null - gamma)) < 1e-9 * scale


def test_full_pivoting_selection():
    """Pivot columns are dependent, the others independent; redundant rows are dropped."""
    m = pendulum("part_pendulum_redundant")
    m.add_revolute("pivot2", "ground", "rod", (0.0, 0.0))
    sim = Simulator(m, "partitioning")
    model = sim.model
    q = sim.system.initial_coordinates()
    sel = part.select_partition(model, q, 0.0)
    assert list(sel.independent) == [2] and list(sel.dependent) == [0, 1]
    assert sel.rows.size == 2
    assert 1.0 <= sel.condition < 10.0
    rows, cols = part._full_pivoting(np.array([[1.0, 2.0, 0.0], [0.0, 0.5, 3.0]]), 2)
    assert list(cols[:2]) == [2, 1] and list(rows[:2]) == [1, 0]
