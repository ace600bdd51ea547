"""Linearized dynamics about an equilibrium: pendulums against closed-form frequencies."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import private_cache

import casmbd
from casmbd import cli
from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.kkt import accelerations_and_multipliers
from casmbd.analysis.statics.linearize import NEEDED, linearize, null_space_basis
from casmbd.compiled.model import NumericModel
from casmbd.errors import AnalysisError

G = 9.81
L = 1.0
MASS = 1.0


_cache = private_cache()


def pendulum(inverted: bool = False, k: float | None = None, c: float = 0.0,
             actuator: bool = False) -> casmbd.Mechanism:
    m = casmbd.Mechanism("p", gravity=(0, -G))
    sign = 1.0 if inverted else -1.0
    m.add_body("rod", MASS, MASS * L**2 / 12, (0.0, sign * L / 2), angle=sign * math.pi / 2)
    m.add_revolute("pivot", "ground", "rod", (0, 0))
    if k is not None:
        m.add_rotational_spring_damper("s", "pivot", stiffness=k, damping=c,
                                       free_angle=sign * math.pi / 2)
    if actuator:
        m.add_actuator("motor", "pivot")
    return m


def double_pendulum(k: float = 0.0, c: float = 0.0) -> casmbd.Mechanism:
    m = casmbd.Mechanism("dp", gravity=(0, -G))
    m.add_body("rod1", MASS, MASS * L**2 / 12, (0.0, -0.5), angle=-math.pi / 2)
    m.add_body("rod2", MASS, MASS * L**2 / 12, (0.0, -1.5), angle=-math.pi / 2)
    m.add_revolute("shoulder", "ground", "rod1", (0, 0))
    m.add_revolute("elbow", "rod1", "rod2", (0, -1))
    if k or c:
        m.add_rotational_spring_damper("s1", "shoulder", stiffness=k, damping=c,
                                       free_angle=-math.pi / 2)
        m.add_rotational_spring_damper("s2", "elbow", stiffness=k, damping=c)
    m.add_actuator("t1", "shoulder")
    m.add_actuator("t2", "elbow")
    return m


def test_hanging_pendulum_frequency():
    lin = linearize(pendulum())
    assert lin.n_dof == 1
    omega = math.sqrt(MASS * G * L / 2 / (MASS * L**2 / 3))
    assert lin.frequencies_hz[0] == pytest.approx(omega / (2 * math.pi), rel=1e-9)
    assert lin.damping_ratios[0] == 0.0
    assert lin.K[0, 0] / lin.M[0, 0] == pytest.approx(1.5 * G / L, rel=1e-9)
    # orthonormal basis along the admissible motion: rotation about the pivot
    assert np.linalg.norm(lin.N) == pytest.approx(1.0, rel=1e-12)
    assert lin.stable and lin.stats["equilibrium"]
    assert np.allclose(np.abs(lin.eigenvalues.imag), omega, rtol=1e-9)


def test_spring_damper_stiffness_and_damping_ratio():
    k, c = 7.0, 0.4
    lin = linearize(pendulum(k=k, c=c))
    inertia = MASS * L**2 / 3
    k_eff = k + MASS * G * L / 2
    assert lin.K[0, 0] / lin.M[0, 0] == pytest.approx(k_eff / inertia, rel=1e-9)
    assert lin.C[0, 0] / lin.M[0, 0] == pytest.approx(c / inertia, rel=1e-9)
    zeta = c / (2 * math.sqrt(k_eff * inertia))
    assert lin.damping_ratios[0] == pytest.approx(zeta, rel=1e-9)
    omega_n = math.sqrt(k_eff / inertia)
    assert lin.natural_frequencies_hz[0] == pytest.approx(omega_n / (2 * math.pi), rel=1e-9)
    assert lin.frequencies_hz[0] == pytest.approx(
        omega_n * math.sqrt(1 - zeta**2) / (2 * math.pi), rel=1e-9)
    # state-space form
    assert lin.A[1, 0] == pytest.approx(-k_eff / inertia, rel=1e-9)
    assert lin.A[1, 1] == pytest.approx(-c / inertia, rel=1e-9)
    assert lin.A[0, 1] == 1.0 and lin.A[0, 0] == 0.0


def test_overdamped_pendulum_is_one_mode():
    k, c = 1.0, 20.0
    lin = linearize(pendulum(k=k, c=c), mode="vm")
    inertia = MASS * L**2 / 3
    k_eff = k + MASS * G * L / 2
    assert lin.frequencies_hz.shape == (1,) and lin.frequencies_hz[0] == 0.0
    assert lin.damping_ratios[0] == pytest.approx(c / (2 * math.sqrt(k_eff * inertia)), rel=1e-9)
    assert lin.natural_frequencies_hz[0] == pytest.approx(
        math.sqrt(k_eff / inertia) / (2 * math.pi), rel=1e-9)
    assert lin.stable

def test_double_pendulum_matches_lagrange():
    lin = linearize(double_pendulum())
    assert lin.n_dof == 2
    m0 = MASS * L**2 * np.array([[1 / 3 + 1, 1 / 2], [1 / 2, 1 / 3]])
    k0 = MASS * G * L * np.array([[1 / 2 + 1, 0], [0, 1 / 2]])
    omega2 = np.sort(np.linalg.eigvals(np.linalg.solve(m0, k0)).real)
    expected = np.sqrt(omega2) / (2 * np.pi)
    assert np.allclose(lin.frequencies_hz, expected, rtol=1e-9, atol=0)
    assert np.all(lin.damping_ratios == 0.0)
    assert lin.A.shape == (4, 4) and lin.Bss.shape == (4, 2)


def test_inverted_pendulum_is_unstable():
    lin = linearize(pendulum(inverted=True))
    rate = math.sqrt(1.5 * G / L)
    real = sorted(s.real for s in lin.eigenvalues)
    assert real[-1] == pytest.approx(rate, rel=1e-9)
    assert real[0] == pytest.approx(-rate, rel=1e-9)
    assert np.all(lin.eigenvalues.imag == 0.0)
    assert not lin.stable
    assert lin.frequencies_hz[0] == 0.0 and lin.damping_ratios[0] == -1.0
    data = lin.to_json()
    assert max(e[0] for e in data["eigenvalues"]) == pytest.approx(rate, rel=1e-9)


@pytest.mark.parametrize(("coordinates", "angle"),
                         [("absolute", "rod.angle"), ("auto", "pivot.angle")])
def test_input_matrix_of_pivot_actuator(coordinates, angle):
    """The automatic choice takes the joint angle itself as the coordinate (a tree)."""
    mech = pendulum(k=2.0, actuator=True)
    mech.coordinates = coordinates
    lin = linearize(mech)
    # the actuator torque acts along the joint angle φ = θ_rod − θ_ground: B̄ = ∂φ/∂z = N[angle]
    assert lin.B.shape == (1, 1)
    assert len(lin.coordinate_names) == (3 if coordinates == "absolute" else 1)
    row = lin.coordinate_names.index(angle)
    assert lin.B[0, 0] == pytest.approx(lin.N[row, 0], rel=1e-12)
    assert lin.B[0, 0] ** 2 / lin.M[0, 0] == pytest.approx(3 / (MASS * L**2), rel=1e-9)
    assert lin.Bss[1, 0] == pytest.approx(lin.B[0, 0] / lin.M[0, 0], rel=1e-12)


def test_state_space_matches_finite_differences():
    """A and B against central differences of the KKT accelerations (double pendulum)."""
    mech = double_pendulum(k=3.0, c=0.5)
    lin = linearize(mech, mode="vm")
    model = NumericModel(mech, NEEDED, mode="vm")
    q0, n = lin.q, lin.N
    nz, eps = lin.n_dof, 1e-5
    fd_a = np.zeros((nz, 2 * nz))
    for j in range(nz):
        acc = []
        for s in (1, -1):
            q = assemble(model, q0 + s * eps * n[:, j], 0.0).q
            z = n.T @ (q - q0)  # the reassembled position, in z
            a, _ = accelerations_and_multipliers(model, q, np.zeros(model.nq), 0.0)
            acc.append((n.T @ a, z[j]))
        fd_a[:, j] = (acc[0][0] - acc[1][0]) / (acc[0][1] - acc[1][1])
        acc = []
        for s in (1, -1):
            a, _ = accelerations_and_multipliers(model, q0, s * eps * n[:, j], 0.0)
            acc.append(n.T @ a)
        fd_a[:, nz + j] = (acc[0] - acc[1]) / (2 * eps)
    assert np.allclose(lin.A[nz:], fd_a, rtol=1e-6, atol=1e-6)
    u_fd = np.zeros((nz, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = eps
        ap, _ = accelerations_and_multipliers(model, q0, np.zeros(model.nq), 0.0, e)
        am, _ = accelerations_and_multipliers(model, q0, np.zeros(model.nq), 0.0, -e)
        u_fd[:, j] = n.T @ (ap - am) / (2 * eps)
    assert np.allclose(lin.Bss[nz:], u_fd, rtol=1e-7, atol=1e-9)


def test_null_space_basis_orthonormal():
    cq = np.array([[1.0, 0.0, 2.0], [2.0, 0.0, 4.0]])  # rank 1, a duplicated row
    n, rank = null_space_basis(cq)
    assert rank == 1 and n.shape == (3, 2)
    assert np.allclose(n.T @ n, np.eye(2)) and np.allclose(cq @ n, 0)


def test_rejects_unassembled_configuration():
    """A pose off the constraints exists only in absolute coordinates (pinned); under the
    automatic choice the pendulum is a tree without equations and an absolute-length q is
    refused by its size."""
    mech = pendulum()
    mech.coordinates = "absolute"
    q = casmbd.System(mech).initial_coordinates() + np.array([0.1, 0.0, 0.0])
    with pytest.raises(AnalysisError, match="violates the constraints"):
        linearize(mech, q=q, mode="vm")
    with pytest.raises(casmbd.ModelError, match="q must have 1 entries, got 3"):
        linearize(pendulum(), q=q, mode="vm")


def test_cli_linearize(tmp_path, capsys):
    scene = tmp_path / "pendulum.toml"
    scene.write_text("""\
[scene]
name = "hanging"
gravity = [0.0, -9.81]

[[bodies]]
name = "rod"
mass = 1.0
inertia = 0.08333333333333333
position = [0.0, -0.5]
angle = -1.5707963267948966

[[joints]]
name = "pivot"
type = "revolute"
body1 = "ground"
body2 = "rod"
point = [0.0, 0.0]
""")
    assert cli.main(["linearize", str(scene), "--json", "--mode", "vm"]) == 0
    data = json.loads(capsys.readouterr().out)
    omega = math.sqrt(1.5 * G / L)
    assert data["frequencies_hz"][0] == pytest.approx(omega / (2 * math.pi), rel=1e-9)
    assert data["damping_ratios"] == [0.0]
    for key in ("M", "C", "K", "B", "A", "eigenvalues", "stats"):
        assert key in data
    assert cli.main(["linearize", str(scene), "--mode", "vm"]) == 0
    text = capsys.readouterr().out
    assert "Hz" in text and "hanging" in text


def test_spring_pendulum_frequency_at_the_static_equilibrium():
    """Issue 4 acceptance: torsional spring k at the pivot; at the equilibrium θ* (k θ* =
    −m g (L/2) cos θ*) the small-oscillation frequency is sqrt(V''(θ*) / (m L²/3)) with
    V'' = k − m g (L/2) sin θ* (hand formula), to 1e-9."""
    import casmbd
    from casmbd.analysis.statics.linearize import linearize
    from casmbd.analysis.statics.statics import static_equilibrium

    k, m_, length, g = 10.0, 1.0, 1.0, 9.81
    mech = casmbd.Mechanism("spring_pendulum", gravity=(0.0, -g))
    mech.add_body("rod", m_, m_ * length**2 / 12, (length / 2, 0.0))
    mech.add_revolute("pivot", "ground", "rod", (0.0, 0.0))
    mech.add_rotational_spring_damper("spring", "pivot", stiffness=k)
    eq = static_equilibrium(mech)
    theta = float(eq.body_angles[0])
    assert abs(k * theta + m_ * g * length / 2 * np.cos(theta)) <= 1e-12
    lin = linearize(mech, q=eq.q)
    omega2 = (k - m_ * g * length / 2 * np.sin(theta)) / (m_ * length**2 / 3)
    assert abs((2 * np.pi * lin.frequencies_hz[0]) ** 2 / omega2 - 1.0) <= 1e-9


def test_rigid_body_pair_is_not_a_saddle():
    """The crane's free cart gives a double zero eigenvalue that round-off splits into ±3e-9:
    it is a rigid-body mode (ζ = 0), not a saddle (ζ = −1), and the system is stable."""
    import pathlib

    scene = pathlib.Path(__file__).resolve().parents[3] / "examples" / "crane.toml"
    mech = casmbd.load_scene(scene)
    assert mech.coordinates == "absolute"  # q below: (x, y, angle) of the cart and the load
    lin = casmbd.linearize(mech, q=[0, 0, 0, 0, -0.5, 0])
    assert lin.damping_ratios[0] == 0.0 and lin.natural_frequencies_hz[0] < 1e-6
    assert 0.0 < lin.damping_ratios[1] < 0.05 and lin.stable
    # the automatic choice (joint coordinates rail, hinge; zero at the scene's pose, the load
    # swung out by 0.3 rad): the same hanging pose and the same modes
    mech = casmbd.load_scene(scene)  # the scene pins absolute coordinates (docs/tutorial.md)
    mech.coordinates = "auto"
    auto = casmbd.linearize(mech, q=[0.0, -0.3])
    assert auto.coordinate_names == ["rail.translation", "hinge.angle"]
    assert auto.damping_ratios[0] == 0.0 and auto.natural_frequencies_hz[0] < 1e-6
    assert auto.damping_ratios[1] == pytest.approx(lin.damping_ratios[1], rel=1e-9)
    assert auto.natural_frequencies_hz[1] == pytest.approx(lin.natural_frequencies_hz[1],
                                                           rel=1e-9)
    assert auto.stable


#: a mass on a linear spring-damper along a prismatic guide (issue 30, item 4j)
OSCILLATOR = """
[scene]
name = "oscillator"
dimension = 2
gravity = [0.0, 0.0]

[[bodies]]
name = "block"
mass = {m}
inertia = 0.1
position = [0.0, 0.0]

[[joints]]
name = "guide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [0.0, 0.0]
axis = [1.0, 0.0]

[[forces]]
name = "spring"
type = "spring_damper"
body1 = "ground"
body2 = "block"
point1 = [-1.0, 0.0]
point2 = [0.0, 0.0]
stiffness = {k}
damping = {c}
free_length = 1.0
"""


@pytest.mark.parametrize("c", [3.0, 0.0])
def test_damped_oscillator_natural_and_damped_frequency_and_damping_ratio(tmp_path, capsys, c):
    """m ẍ + c ẋ + k x = 0: ω_n = √(k/m), ζ = c / (2√(k m)), ω_d = ω_n √(1 − ζ²), to 1e-8
    relative, through the Python API, ``--json`` (the older keys kept, the new ones added) and
    the labelled text summary (issue 30, item 4j: the text showed ω_d labelled "frequency")."""
    m, k = 2.0, 50.0
    omega_n = math.sqrt(k / m)  # 5 rad/s
    zeta = c / (2 * math.sqrt(k * m))  # 0.15
    omega_d = omega_n * math.sqrt(1 - zeta**2)
    fn, fd = omega_n / (2 * math.pi), omega_d / (2 * math.pi)
    scene = tmp_path / "oscillator.toml"
    scene.write_text(OSCILLATOR.format(m=m, k=k, c=c))
    lin = linearize(casmbd.load_scene(str(scene)), mode="vm")
    assert lin.n_dof == 1
    assert lin.natural_frequencies_hz[0] == pytest.approx(fn, rel=1e-8)
    assert lin.damped_frequencies_hz[0] == pytest.approx(fd, rel=1e-8)
    assert lin.damping_ratios[0] == pytest.approx(zeta, rel=1e-8, abs=1e-12)

    assert cli.main(["linearize", str(scene), "--mode", "vm", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["natural_frequencies_hz"][0] == pytest.approx(fn, rel=1e-8)
    assert data["damped_frequencies_hz"][0] == pytest.approx(fd, rel=1e-8)
    assert data["frequencies_hz"] == data["damped_frequencies_hz"]  # older key, same values
    assert data["damping_ratios"][0] == pytest.approx(zeta, rel=1e-8, abs=1e-12)

    assert cli.main(["linearize", str(scene), "--mode", "vm"]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if "mode 1" in s)
    words = line.split()
    value = {label: float(words[words.index(label) + 2 if label != "ratio" else
                                words.index(label) + 1])
             for label in ("natural", "damped", "ratio")}
    assert "natural frequency" in line and "damped frequency" in line and "damping ratio" in line
    assert value["natural"] == pytest.approx(fn, rel=1e-5)  # printed to 6 digits
    assert value["damped"] == pytest.approx(fd, rel=1e-5)
    assert value["ratio"] == pytest.approx(zeta, rel=1e-3, abs=1e-12)  # printed to 4 digits
