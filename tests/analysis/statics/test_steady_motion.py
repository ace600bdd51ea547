"""Linearization about a steady motion (casmbd.analysis.statics.steady_motion) on a thin
uniform disc rolling upright and straight, against the closed form: with I_a = m R²/2 about the
axle and I_d = m R²/4 about a diameter, the lean φ and the heading rate obey
(I_d + m R²) φ̈ = m g R φ − (I_a + m R²)(v/R) ψ̇ and I_d ψ̈ = I_a (v/R) φ̇ (Neimark & Fufaev,
Dynamics of Nonholonomic Systems, ch. V), so the eigenvalues are s² = 4 (g R − 3 v²) / (5 R²)
and one zero (the steady turns: ψ̇ − I_a v φ / (I_d R) is conserved); upright rolling is stable
above v² = g R / 3."""

import math
from pathlib import Path

import numpy as np
import pytest

from casmbd.analysis.statics.linearize import linearize
from casmbd.analysis.statics.steady_motion import SteadyMotion, parameter_root
from casmbd.errors import AnalysisError, CompositionError
from casmbd.io.scene import load_scene

R, G = 0.5, 9.81

LINKS = "".join(f"""
[[bodies]]
name = "{name}"
mass = 0.0
inertia = [0.0, 0.0, 0.0]
position = [0.0, 0.0, {R}]
velocity = [1.0, 0.0, 0.0]
""" for name in ("lx", "ly", "lz", "lyaw", "llean"))

CHAIN = "".join(f"""
[[joints]]
name = "{name}"
type = "{kind}"
body1 = "{b1}"
body2 = "{b2}"
point = [0.0, 0.0, {R}]
axis = {axis}
""" for name, kind, b1, b2, axis in (
    ("x", "prismatic", "ground", "lx", [1, 0, 0]), ("y", "prismatic", "lx", "ly", [0, 1, 0]),
    ("z", "prismatic", "ly", "lz", [0, 0, 1]), ("yaw", "revolute", "lz", "lyaw", [0, 0, 1]),
    ("lean", "revolute", "lyaw", "llean", [1, 0, 0]),
    ("spin", "revolute", "llean", "disc", [0, 1, 0])))

DISC = f"""
[[bodies]]
name = "disc"
mass = 1.0
inertia = [{R * R / 4}, {R * R / 2}, {R * R / 4}]
position = [0.0, 0.0, {R}]
velocity = [1.0, 0.0, 0.0]
angular_velocity = [0.0, {1 / R}, 0.0]

[[joints]]
name = "contact"
type = "rolling_disc"
body1 = "ground"
body2 = "disc"
point = [0.0, 0.0, {R}]
axis = [0.0, 1.0, 0.0]
radius = {R}
normal = [0.0, 0.0, 1.0]
"""


def _scene(tmp_path, coordinates: str, links: bool):
    text = (f'[scene]\nname = "disc"\ndimension = 3\ngravity = [0.0, 0.0, {-G}]\n'
            f'coordinates = "{coordinates}"\n' + (LINKS if links else "") + DISC
            + (CHAIN if links else ""))
    path = tmp_path / f"disc_{coordinates}.toml"
    path.write_text(text)
    return load_scene(path)


@pytest.fixture(scope="module")
def disc(tmp_path_factory):
    lin = SteadyMotion(_scene(tmp_path_factory.mktemp("disc"), "joint", True), mode="vm")
    return lin, lin().v  # the scene rolls at 1 m/s


def _closed_form(v: float) -> np.ndarray:
    s2 = 4.0 * (G * R - 3.0 * v * v) / (5.0 * R * R)
    root = np.sqrt(complex(s2))
    return np.array([root, -root, 0.0])


@pytest.mark.parametrize("speed", [0.0, 0.5, 1.0, 2.0, 3.0, 6.0])
def test_upright_disc_eigenvalues(disc, speed):
    """The closed form to 1e-10 at speeds below and above the critical one."""
    lin, v1 = disc
    got = list(lin(v=speed * v1).eigenvalues)
    for want in _closed_form(speed):
        k = int(np.argmin([abs(g - want) for g in got]))
        assert abs(got.pop(k) - want) <= 1e-10


def test_critical_speed(disc):
    """v² = g R / 3, by Brent's method on s² = −s₁ s₂ (the pair of largest modulus)."""
    lin, v1 = disc

    def s_squared(e):
        pair = e[np.argsort(-np.abs(e))[:2]]
        return -float((pair[0] * pair[1]).real)

    v_c = parameter_root(lambda s: lin(v=s * v1).eigenvalues, 0.5, 3.0, s_squared)
    assert abs(v_c - math.sqrt(G * R / 3.0)) <= 1e-10


def test_reduction_names(disc):
    lin, v1 = disc
    res = lin(v=2.0 * v1)
    assert res.cyclic == ["x.translation", "y.translation", "spin.angle"]
    assert res.symmetries == ["yaw.angle", "speed"]
    assert res.remaining == ["z.translation", "lean.angle"]
    assert res.to_json()["eigenvalues"][0] == [res.eigenvalues[0].real,
                                               res.eigenvalues[0].imag]


def test_euler_parameters_refused(tmp_path):
    """Absolute coordinates: the Euler parameters change with the spin and the mass matrix
    depends on them; refused, naming them and the coordinates to use."""
    mech = _scene(tmp_path, "absolute", False)
    with pytest.raises(AnalysisError, match=r"disc\.e[0-3].*joint coordinates"):
        SteadyMotion(mech, mode="vm")()


def test_small_oscillation_form_refuses_rolling(tmp_path):
    """The equilibrium linearization refuses non-holonomic rows by name (it returned wrong
    eigenvalues about a rolling Euler-parameter disc with only a warning, issue 37)."""
    mech = _scene(tmp_path, "absolute", False)
    with pytest.raises(CompositionError, match=r"joint 'contact'.*--steady-motion"):
        linearize(mech, mode="vm")


def test_equilibrium_is_a_steady_motion():
    """At rest (no cyclic coordinate, no velocity constraint) the steady-motion eigenvalues
    are those of the small-oscillation linearization (an independent formulation: the
    reduced M̄, K̄ on ker C_q) — the double pendulum at its equilibrium, to 1e-10."""
    mech = load_scene(Path(__file__).resolve().parents[3] / "examples" / "double_pendulum.toml")
    small = linearize(mech, mode="vm", at="equilibrium")
    steady = linearize(mech, mode="vm", q=small.q, steady_motion=True)
    assert steady.cyclic == [] and steady.symmetries == []
    got = list(steady.eigenvalues)
    assert len(got) == len(small.eigenvalues) == 4
    for want in small.eigenvalues:
        k = int(np.argmin([abs(g - want) for g in got]))
        assert abs(got.pop(k) - want) <= 1e-10 * max(1.0, abs(want))
