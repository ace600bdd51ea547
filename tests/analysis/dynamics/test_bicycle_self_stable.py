"""The benchmark bicycle (examples/bicycle.toml, Meijaard et al. 2007) simulated nonlinearly at
5 m/s, inside the self-stable range (4.29 < v < 6.02 m/s, Table 2 (a) of the paper): from a roll
rate of 0.5 rad/s it returns toward upright, while its energy stays constant (rolling without
slipping does no work and there is no damping) to 1e-9 relative."""

from pathlib import Path

import numpy as np
import pytest

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.io.scene import loads_scene

SCENE = Path(__file__).resolve().parents[3] / "examples" / "bicycle.toml"


def _perturbed() -> str:
    """The scene at v = 5 m/s with every body given a roll rate of 0.5 rad/s about x (the
    start projects it onto the constraints)."""
    text = SCENE.read_text().replace("v = 4.0 ", "v = 5.0 ", 1)
    for name in ("rear_frame", "front_frame"):
        text = text.replace(f'name = "{name}"', f'name = "{name}"\nangular_velocity = '
                            '[0.5, 0.0, 0.0]', 1)
    for radius in ("0.3", "0.35"):
        text = text.replace(f'angular_velocity = [0.0, "v / {radius}", 0.0]',
                            f'angular_velocity = [0.5, "v / {radius}", 0.0]')
    assert text.count("[0.5, ") == 4
    return text


@pytest.mark.parametrize("formulation", ["index1", "augmented_lagrangian"])
def test_returns_upright_energy_constant(formulation):
    mech = loads_scene(_perturbed(), source="bicycle at 5 m/s")
    res = simulate(mech, 8.0, 160, formulation=formulation, rtol=1e-11, atol=1e-12,
                   mode="vm")
    names = res.names["coordinates"]
    roll = res["q"][:, names.index("roll.angle")]
    steer = res["q"][:, names.index("steer.angle")]
    last = res.t >= 7.0
    # the lean grows to about 0.01 rad, then decays (slowest mode: capsize, -0.32 1/s)
    assert np.max(np.abs(roll)) > 0.005
    assert np.max(np.abs(roll[last])) < 0.15 * np.max(np.abs(roll))
    assert np.max(np.abs(steer[last])) < 0.15 * np.max(np.abs(steer))
    energy = res["total_energy"]
    assert np.max(np.abs(energy - energy[0])) <= 1e-9 * abs(energy[0])
    # the forward speed stays near 5 m/s (the rear wheel's spin rate times its radius)
    spin = res["v"][:, names.index("rear_axle.angle")]
    assert np.all(np.abs(np.abs(spin) * 0.3 - 5.0) < 0.01)
