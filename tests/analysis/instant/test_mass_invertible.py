"""A formulation that factorises M alone (``kkt_ode``) refuses, by name, a mass matrix that is
singular on the whole space but regular on the constraint manifold — a thin disc in natural
coordinates (its second moment across its plane is zero) — instead of failing inside the
integrator at its first call; the formulations that need M regular on the manifold only run
the same scene and agree with absolute coordinates."""

import numpy as np
import pytest
from rolling_disc_scenes import OMEGA, THETA, disc, steady_speed

import casmbd
from casmbd.errors import ModelError


def test_kkt_ode_names_the_lamina_and_the_way_out():
    mech = disc(THETA, OMEGA, steady_speed(THETA, OMEGA), coordinates="natural")
    with pytest.raises(ModelError) as err:
        casmbd.simulate(mech, 0.2, 4, formulation="kkt_ode", mode="vm")
    text = str(err.value)
    assert "'kkt_ode'" in text and "body 'wheel'" in text and "singular" in text
    assert "index1" in text


def test_index1_runs_the_lamina_in_natural_coordinates():
    """Same motion as in absolute coordinates (centre positions to 1e-7 over 0.2 s)."""
    v = steady_speed(THETA, OMEGA)
    nat = casmbd.simulate(disc(THETA, OMEGA, v, coordinates="natural"), 0.2, 4,
                          formulation="index1", mode="vm", rtol=1e-10, atol=1e-10)
    ab = casmbd.simulate(disc(THETA, OMEGA, v, coordinates="absolute"), 0.2, 4,
                         formulation="index1", mode="vm", rtol=1e-10, atol=1e-10)
    a, b = nat.body("wheel")["position"], ab.body("wheel")["position"]
    assert np.max(np.abs(a - b)) <= 1e-7
