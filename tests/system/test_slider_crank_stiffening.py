"""Issue 35 item 3: the flexible slider-crank's steady mid-span deflection against a
geometrically exact reference, for a 10 mm and a 20 mm steel rod.

The mechanism (:data:`tests.flexible_references.SLIDER_CRANK_ROD`): rigid crank 0.152 m driven
at 150 rad/s, connecting rod 0.304 m of circular section (E = 2.07e11 Pa, ρ = 7870 kg/m³),
slider of half the rod's mass on the x axis, no gravity, start from the rigid translation at a
vertical crank.  Damping: stiffness-proportional on the deformation, β = 2 ζ/ω1 with ζ = 0.05
and ω1 the first pinned–pinned bending frequency — the co-rotational reference applies β K_l
to each element's deformation rates, casmbd gets the modal ratios ζ_k = β ω_k/2 of its rod
modes (:func:`tests.flexible_references.slider_crank_damping`), so that its modal damping is
exactly β K_red (checked below).

Reference: :func:`tests.flexible_references.corotational_slider_crank` (Crisfield
co-rotational Euler–Bernoulli elements, lumped masses, Radau rtol 1e-7), stored in
``tests/data/slider_crank_reference.npz`` (``python -m tests.flexible_references``, about
25 minutes on a loaded machine).  Its checks (2026-11-29): mesh 8 → 16 → 32 elements
1.34683 → 1.35845 → 1.36137 mm (10 mm rod), 0.33711 → 0.34025 mm (20 mm); Richardson (h²)
of 16 and 32 elements 1.362337 mm against Exudyn's ANCF cable converged at 16–32 elements and
h = 2.5e-5 s, 1.362343 mm; energy balance
T + U + D − W to 2.6e-8 J of 73 J (tests/peers/test_flexible_references.py); E × 1e4: the
slider on the rigid mechanism's x(t) to 1.1e-9 m.

casmbd: the rod a built-in beam of the same 8 elements and lumped masses (so the two differ by
the kinematics of the deformation and the modal truncation only), Craig–Bampton with
interfaces at both pins and 4 fixed-interface modes, ``stiffening = true``; CVODES (BDF), rtol
1e-9, to 0.4 s (9.5 crank turns, the transient decayed: the steady maximum changes by < 1e-4
relative from one turn to the next).  Measured: 1.34648 mm (−0.025 %) and 0.33698 mm
(−0.039 %); before issue 35 (linear floating frame) +13.3 % and +2.7 %.  Figures in
docs/flexible.md.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

import casmbd
from casmbd.model.fe_beam import beam_model
from casmbd.model.modal_reduction import craig_bampton
from casmbd.system.floating_frame import invariants
from tests.flexible_references import (
    SLIDER_CRANK_REFERENCE,
    SLIDER_CRANK_ROD,
    chord_deflection,
    pinned_frequency,
    rod_section,
    slider_crank_damping,
    slider_crank_scene,
    steady_deflection,
)

ELEMENTS, MODES, T_END = 8, 4, 0.4

@pytest.fixture(scope="module")
def reference():
    path = pathlib.Path(__file__).resolve().parent.parent / SLIDER_CRANK_REFERENCE
    return dict(np.load(path))


def _casmbd_deflection(diameter: float, stiffening: bool) -> tuple[np.ndarray, np.ndarray]:
    mech = casmbd.loads_scene(slider_crank_scene(diameter, elements=ELEMENTS, modes=MODES,
                                                 stiffening=stiffening))
    # CasADi's virtual machine: 2–3 s a rod, against ~25 s of a cold C compile (CI's case)
    res = casmbd.simulate(mech, T_END, round(T_END / 1e-4), integrator="cvodes",
                          rtol=1e-9, mode="vm")
    m = {k: res.marker(f"rod@{k}")["position"] for k in ("A", "B", "mid")}
    return res.t, chord_deflection(m["A"], m["B"], m["mid"])


def test_damping_is_the_references_operator():
    """The modal ratios of slider_crank_damping make casmbd's C = M V diag(2ζω) Vᵀ M equal
    to β K_red (1e-9 relative), β = 2 · 0.05/ω1: the reference's damping operator on the
    modes; 5 % on the pinned–pinned bending mode by construction."""
    d = 0.01
    sec = rod_section(d)
    L = SLIDER_CRANK_ROD["length"]
    fe = beam_model(L, ELEMENTS, EA=sec["EA"], rhoA=sec["rhoA"], EI=sec["EI"], mass="lumped",
                    nodes={"A": 0.0, "mid": L / 2.0, "B": L})
    modal = craig_bampton(fe, MODES, ["A", "B"])
    inv = invariants(modal, damping_ratio=slider_crank_damping(d, elements=ELEMENTS,
                                                               modes=MODES))
    beta = 2.0 * 0.05 / pinned_frequency(sec)
    K = np.asarray(modal.stiffness)
    assert np.abs(inv.C - beta * K).max() <= 1e-9 * np.abs(beta * K).max()


def test_reference_is_steady_and_mesh_converged(reference):
    """The stored reference: periodic at its end (steady maximum of the last two crank turns
    within 1e-4 relative) and the 8-element value within 1.5 % of the 16-element one."""
    for d in (10, 20):
        steady = reference[f"d{d}_e8_steady"]
        assert abs(reference[f"d{d}_e8_steady_before"] - steady) <= 1e-4 * steady
        assert abs(reference[f"d{d}_e16_steady"] - steady) <= 0.015 * steady


@pytest.mark.parametrize("diameter", [0.01, 0.02])
def test_steady_midspan_deflection_within_one_percent(reference, diameter):
    """casmbd (stiffening = true) within 1 % of the co-rotational reference's steady maximum
    |mid-span deflection| over the last crank turn (same mesh, same output times)."""
    key = f"d{round(diameter * 1e3)}_e{ELEMENTS}"
    t, defl = _casmbd_deflection(diameter, True)
    ref = float(reference[f"{key}_steady"])
    got = steady_deflection(t, defl)
    assert np.allclose(t[-len(reference[f"{key}_t"]):], reference[f"{key}_t"], atol=1e-9)
    assert abs(got - ref) <= 0.01 * ref, (got, ref, got / ref - 1.0)
