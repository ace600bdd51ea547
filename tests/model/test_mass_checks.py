"""Massless bodies (issue 21 item 3): accepted by the model, refused by forward dynamics only
where the mass matrix is singular on the constraint manifold, with the body named."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import Mechanism
from casmbd.errors import ModelError

G = 9.81
LA, LB, LC = 0.8, 0.5, 0.6
MA, MC = 2.0, 3.0


_cache = private_cache("cache_mass")


def chain(coordinates: str = "joint", end_massless: bool = False) -> Mechanism:
    """Planar chain A–B–C hanging from the ground at the origin, horizontal at the start; B
    (or, with ``end_massless``, C alone) has mass 0 and inertia 0."""
    mech = Mechanism("massless_chain", gravity=[0.0, -G], coordinates=coordinates)
    mech.add_body("A", MA, MA * LA ** 2 / 12, [LA / 2, 0.0])
    mb = 1.0 if end_massless else 0.0
    mech.add_body("B", mb, mb * LB ** 2 / 12, [LA + LB / 2, 0.0])
    mc = 0.0 if end_massless else MC
    mech.add_body("C", mc, mc * LC ** 2 / 12, [LA + LB + LC / 2, 0.0])
    mech.add_revolute("pin0", "ground", "A", [0.0, 0.0])
    mech.add_revolute("pin1", "A", "B", [LA, 0.0])
    mech.add_revolute("pin2", "B", "C", [LA + LB, 0.0])
    return mech


def closed_form_accelerations(phi, dphi) -> np.ndarray:
    """φ̈ of the chain in the absolute angles (φA, φB, φC) by Lagrange's equations written by
    hand: p_A = LA/2 e(φA), p_C = LA e(φA) + LB e(φB) + LC/2 e(φC); B carries nothing.
    M = Σ m Jᵀ J + I eᵀ e, M φ̈ = Σ m Jᵀ (g + Σ l φ̇² e(φ)) (J̇ φ̇ = −Σ l φ̇² e(φ))."""
    def e(a):
        return np.array([np.cos(a), np.sin(a)])

    def eperp(a):
        return np.array([-np.sin(a), np.cos(a)])

    g = np.array([0.0, -G])
    lever_a = [(0, LA / 2)]
    lever_c = [(0, LA), (1, LB), (2, LC / 2)]
    m = np.zeros((3, 3))
    rhs = np.zeros(3)
    for mass, inertia, levers, k in ((MA, MA * LA ** 2 / 12, lever_a, 0),
                                     (MC, MC * LC ** 2 / 12, lever_c, 2)):
        jac = np.zeros((2, 3))
        for i, length in levers:
            jac[:, i] += length * eperp(phi[i])
        centripetal = -sum(length * dphi[i] ** 2 * e(phi[i]) for i, length in levers)
        m += mass * jac.T @ jac
        m[k, k] += inertia
        rhs += mass * jac.T @ (g - centripetal)
    return np.linalg.solve(m, rhs)


def test_massless_middle_link_matches_closed_form():
    """Joint coordinates, B massless between A and C: M is positive definite; the body angular
    accelerations at every output equal the hand-written Lagrange equations (1e-9 rel.)."""
    out = casmbd.simulate(chain("joint"), t_end=0.6, steps=6, rtol=1e-10)
    phi = np.column_stack([out.body(b)["angle"] for b in "ABC"])
    dphi = np.column_stack([out.body(b)["angular_velocity"] for b in "ABC"])
    ddphi = np.column_stack([out.body(b)["angular_acceleration"] for b in "ABC"])
    assert np.ptp(phi[:, 0]) > 0.3  # the chain really swings
    for k in range(len(out.t)):
        ref = closed_form_accelerations(phi[k], dphi[k])
        assert np.max(np.abs(ddphi[k] - ref)) < 1e-9 * np.max(np.abs(ref))


def test_massless_middle_link_absolute_agrees_with_joint():
    """The same chain in absolute coordinates (M singular, yet positive definite on the null
    space of C_q): positions agree with joint coordinates (1e-7 m)."""
    ref = casmbd.simulate(chain("joint"), t_end=0.6, steps=6, rtol=1e-11)
    out = casmbd.simulate(chain("absolute"), t_end=0.6, steps=6, rtol=1e-11)
    assert np.max(np.abs(out["body_positions"] - ref["body_positions"])) < 1e-7


def test_free_massless_body_in_absolute_coordinates_is_named():
    mech = chain("absolute")
    mech.add_body("loose", 0.0, 0.0, [5.0, 5.0])
    with pytest.raises(ModelError, match=r"singular.*'loose'") as info:
        casmbd.simulate(mech, t_end=0.1, steps=2)
    assert "'A'" not in str(info.value) and "'C'" not in str(info.value)


@pytest.mark.parametrize("coordinates", ["joint", "absolute"])
def test_massless_end_link_is_named(coordinates):
    with pytest.raises(ModelError, match=r"singular.*'C' \(mass 0.0, inertia 0.0\)") as info:
        casmbd.simulate(chain(coordinates, end_massless=True), t_end=0.1, steps=2)
    assert "'A'" not in str(info.value) and "'B'" not in str(info.value)


def test_massless_subtree_names_both():
    """B and C massless, only A carries mass: both are named."""
    mech = chain("joint")
    mech.bodies["C"].mass, mech.bodies["C"].inertia = 0.0, 0.0
    with pytest.raises(ModelError, match=r"singular.*body 'B'.*body 'C'|singular.*'C'.*'B'"):
        casmbd.simulate(mech, t_end=0.1, steps=2)


def test_inverse_dynamics_of_massless_end_link_works():
    """Inverse dynamics needs no positive definite M: a driven chain with massless B and C
    gives the torques of A and B alone at rest (1e-9)."""
    mech = chain("joint", end_massless=True)
    for k in range(3):
        mech.add_driver(f"d{k}", 0.0, joint=f"pin{k}")
    out = casmbd.inverse_dynamics(mech, t_end=0.2, steps=2)
    efforts = out["driver_efforts"]
    mb = mech.bodies["B"].mass
    assert np.max(np.abs(np.abs(efforts[:, 0]) - G * (MA * LA / 2 + mb * (LA + LB / 2)))) < 1e-9
    assert np.max(np.abs(np.abs(efforts[:, 1]) - G * mb * LB / 2)) < 1e-9
    assert np.max(np.abs(efforts[:, 2])) < 1e-9


@pytest.mark.parametrize("field, values, text", [
    ("mass", (-1.0, 0.1), "'mass': must be >= 0"),
    ("inertia", (1.0, -0.1), "'inertia': must be >= 0"),
])
def test_negative_mass_and_inertia_refused(field, values, text):
    mech = Mechanism("bad")
    with pytest.raises(ModelError, match=text):
        mech.add_body("b", values[0], values[1], [0.0, 0.0])


@pytest.mark.parametrize("inertia, ok", [
    ([0.0, 0.0, 0.0], True),
    ([0.0, 1.0, 1.0], True),  # thin rod along x
    ([1.0, 1.0, 3.0], False),  # positive definite, triangle inequality fails
    ([1.0, 1.0, 1.0, 2.0, 0.0, 0.0], False),  # indefinite
])
def test_spatial_inertia_semidefinite(inertia, ok):
    mech = Mechanism("s", dimension=3)
    mech.add_body("b", 1.0, inertia, [0.0, 0.0, 0.0])
    if ok:
        mech.validate()
    else:
        with pytest.raises(ModelError, match="inertia"):
            mech.validate()
