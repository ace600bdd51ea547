"""The compiled model and its workspace (issue 20 item 4: Model and Data).

:class:`~casmbd.compiled.model.NumericModel` holds what is fixed — Functions, sizes, names and
the parameter values in one place — and a :class:`~casmbd.compiled.workspace.Workspace` holds
the evaluation buffers.  These tests check that the accessors say what the symbolic System
says, that two workspaces do not share buffers, and that the model's ``p`` is the one source
of the parameter values (the mechanism keeps its defaults).
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from casmbd.compiled.model import NumericModel
from casmbd.compiled.workspace import Workspace
from casmbd.errors import ModelError
from casmbd.io.scene import load_scene
from casmbd.system import System

REPO = pathlib.Path(__file__).resolve().parents[2]
DOUBLE_PENDULUM = str(REPO / "examples" / "double_pendulum.toml")
SLIDER_CRANK = str(REPO / "examples" / "slider_crank.toml")


def _model(path: str, coordinates: str) -> tuple[System, NumericModel]:
    mech = load_scene(path)
    mech.coordinates = coordinates
    system = System(mech)
    return system, NumericModel(system, "dynamics", mode="vm")


@pytest.mark.parametrize("coordinates", ["absolute", "natural", "joint"])
def test_accessors_are_the_systems(coordinates):
    system, model = _model(SLIDER_CRANK, coordinates)
    assert model.coordinate_names == system.coordinate_names
    assert model.constraint_labels == system.constraint_labels
    assert model.joint_coordinate_names == system.joint_coordinate_names
    assert model.body_names == system.body_names
    assert model.joint_rows == system.joint_rows
    assert model.driver_rows == system.driver_rows
    assert (model.nq, model.nc, model.nu) == (system.nq, system.nc, len(system.u.nonzeros()))
    assert model.reaction_size == system.reaction_size == 3
    np.testing.assert_array_equal(model.length_indices, system.length_indices)
    # exact: the same numbers, copied when the model is built
    np.testing.assert_array_equal(model.initial_coordinates(), system.initial_coordinates())
    np.testing.assert_array_equal(model.initial_velocities(), system.initial_velocities())
    assert model.parameter_names == list(system.mechanism.parameters)


def test_workspaces_do_not_share_buffers():
    _, model = _model(DOUBLE_PENDULUM, "joint")
    rng = np.random.default_rng(3)
    q1, q2 = rng.standard_normal(model.nq), rng.standard_normal(model.nq)
    v1, v2 = rng.standard_normal(model.nq), rng.standard_normal(model.nq)
    m1, m2 = model.mass_matrix(q1).toarray(), model.mass_matrix(q2).toarray()
    f1 = model.quadratic_velocity_forces(q1, v1)
    first, second = model.workspace(), model.workspace()
    assert isinstance(first, Workspace) and first is not model.data
    a = first.sparse("mass_matrix", q1, model.p)
    b = second.sparse("mass_matrix", q2, model.p)
    # a second workspace's evaluation leaves the first one's result alone (bit-identical)
    np.testing.assert_array_equal(a.toarray(), m1)
    np.testing.assert_array_equal(b.toarray(), m2)
    np.testing.assert_array_equal(first.vector("quadratic_velocity_forces", q1, v1, model.p),
                                  f1)
    np.testing.assert_array_equal(second.vector("quadratic_velocity_forces", q2, v2, model.p),
                                  model.quadratic_velocity_forces(q2, v2))
    assert np.max(np.abs(m1 - m2)) > 1e-3  # the two states differ: the test can fail


def test_parameters_live_in_the_model():
    mech = load_scene(DOUBLE_PENDULUM)
    model = NumericModel(mech, "dynamics", mode="vm")
    q = model.initial_coordinates()
    model.set_parameters(m=2.5)
    assert model.parameters == {"L": 1.0, "m": 2.5}
    assert mech.parameters == {"L": 1.0, "m": 1.0}  # the defaults stay the mechanism's
    heavy = load_scene(DOUBLE_PENDULUM)
    heavy.parameters["m"] = 2.5
    expected = NumericModel(heavy, "dynamics", mode="vm").mass_matrix(q).toarray()
    np.testing.assert_array_equal(model.mass_matrix(q).toarray(), expected)  # exact
    np.testing.assert_allclose(expected, 2.5 * NumericModel(load_scene(DOUBLE_PENDULUM),
                                                            "dynamics", mode="vm")
                               .mass_matrix(q).toarray(), rtol=1e-14, atol=0)
    with pytest.raises(ModelError, match="unknown parameter 'mass'"):
        model.set_parameters(mass=1.0)


def test_joint_coordinate_initial_velocities_at_the_models_parameters():
    """Joint coordinates map body velocities through J(q0, p): evaluated at the model's p."""
    mech = load_scene(DOUBLE_PENDULUM)
    mech.coordinates = "joint"
    mech.bodies["rod2"].angular_velocity = 1.0  # about the elbow at (1, 0): G moves at (0, 0.5)
    mech.bodies["rod2"].velocity = np.array([0.0, 0.5])
    system = System(mech)
    model = NumericModel(system, "kinematics", mode="vm")
    rates = model.initial_velocities()
    np.testing.assert_allclose(rates, system.initial_velocities(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rates, system.initial_velocities(model.p), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rates, [0.0, 1.0], rtol=0, atol=1e-12)  # shoulder, elbow
