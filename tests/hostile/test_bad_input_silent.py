"""Bad input that used to give a silently wrong number (issue 31, item 5).

- a run whose results hold a value that is not finite stops with an ``IntegratorError`` (flag
  ``NON_FINITE``) naming the quantity and the first time, keeping the results before it;
- a fixed-step run of a conservative mechanism whose total energy drifts by more than half
  the largest kinetic energy so far stops (flag ``ENERGY_GROWTH``), naming the energies; any
  fixed-step run whose state norm blows up stops (flag ``STATE_GROWTH``);
- an adaptive run of a conservative mechanism whose energy blows up under a loose tolerance
  (``--rtol 0.1`` on a stiff spring: 5000 J -> 4e31 J, exit 0 before) stops (flag
  ``ENERGY_GROWTH``), naming the energies and the tolerance;
- FE models are checked before every reduction: M positive definite (Cholesky, or the
  inertia of a sparse LU above DENSE_LIMIT dofs), nodes distinct, units plausible (finite,
  total mass, K_ii/M_ii); a built-in beam's length and properties within plausible ranges;
  more modes than the model can give apart are refused naming the field ``modes``;
- names that shadow time or the measure and node syntax (``time``, ``rod@tip``, ``J.angle``)
  and markers named like a body are refused where they are declared, naming the element;
  names casmbd makes itself (``"<joint>.limit"``, ``"<contact>.force"``,
  ``"<joint>.friction"``) still work.

Every case asserts the error class and that the message names the culprit; through the CLI,
exit 1 with one ``error:`` line.  Small planar scenes on CasADi's virtual machine
(``CASMBD_COMPILE=0``), so the file runs in seconds.
"""

from __future__ import annotations

import dataclasses
import pathlib

import numpy as np
import pytest
from conftest import private_cache
from scene_builders import HEAD, PENDULUM, body, entry, joint

from casmbd.analysis.dynamics.postprocess import first_non_finite
from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.integrators.invariants import energy_exchange
from casmbd.cli import main
from casmbd.errors import CasmbdError, IntegratorError, ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.model import modal_reduction
from casmbd.model.fe_beam import beam_model
from casmbd.model.fe_import import load_fe_npz, save_fe_npz
from casmbd.model.mechanism import Mechanism
from casmbd.results import Result

_vm = private_cache("cache_silent", CASMBD_COMPILE="0")


def refused(text: str, *fragments: str) -> str:
    """Load ``text``; assert a casmbd model or scene error naming every fragment."""
    with pytest.raises((ModelError, SceneError)) as info:
        loads_scene(text)
    message = str(info.value)
    assert isinstance(info.value, CasmbdError)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return message


def cli_refuses(tmp_path, capsys, text: str, *fragments: str) -> None:
    """``casmbd info`` on ``text``: exit 1, one ``error:`` line naming every fragment."""
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    code = main(["info", str(scene)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and err[0].startswith("error: "), err
    for fragment in fragments:
        assert fragment in err[0], f"{fragment!r} not in {err[0]!r}"


# ---------------------------------------------------------------------- names of time
@pytest.mark.parametrize("name", ["time", "t", "pi", "e"])
def test_parameter_named_like_time_or_a_constant_refused(name):
    refused(PENDULUM + f"\n[parameters]\n{name} = 2.0\n", f"parameter '{name}'", "reserved")


def test_parameter_time_refused_cli(tmp_path, capsys):
    cli_refuses(tmp_path, capsys, HEAD + "\n[parameters]\ntime = 2.0\n" + body("rod")
                + joint("pivot", "revolute", point="[0.0, 0.0]"), "parameter 'time'",
                "the time")


# ---------------------------------------------------------------------- '@' and '.'
SLIDER = HEAD + body("slider") + joint("slide", "prismatic", body2="slider",
                                       point="[0.5, 0.0]", axis="[1.0, 0.0]")


@pytest.mark.parametrize("char", ["@", "."])
@pytest.mark.parametrize("kind, text", [
    ("body", lambda n: HEAD + body(n) + joint("pivot", "revolute", body2=n,
                                             point="[0.0, 0.0]")),
    ("joint", lambda n: HEAD + body("rod") + joint(n, "revolute", point="[0.0, 0.0]")),
    ("marker", lambda n: PENDULUM + entry("markers", name=f'"{n}"', body='"rod"',
                                          point="[1.0, 0.0]")),
    ("force", lambda n: PENDULUM + entry("forces", name=f'"{n}"', type='"force"',
                                         body='"rod"', value="[1.0, 0.0]")),
    ("driver", lambda n: PENDULUM + entry("drivers", name=f'"{n}"', joint='"pivot"',
                                          position='"t"')),
    ("output", lambda n: PENDULUM + entry("outputs", name=f'"{n}"',
                                          value='"angle(\\"pivot\\")"')),
    ("actuator", lambda n: PENDULUM + entry("actuators", name=f'"{n}"', joint='"pivot"')),
    ("contact", lambda n: PENDULUM + entry("contacts", name=f'"{n}"', body='"rod"',
                                           point="[1.0, 0.0]")),
])
def test_reserved_character_in_a_declared_name_refused(kind, text, char):
    name = f"rod{char}tip" if char == "@" else "J.angle"
    refused(text(name), f"{kind} name '{name}'", f"must not contain '{char}'")


def test_parameter_with_a_dot_refused():
    refused(PENDULUM + '\n[parameters]\n"k.stiff" = 2.0\n', "parameter name 'k.stiff'")


def test_reserved_character_refused_cli(tmp_path, capsys):
    cli_refuses(tmp_path, capsys, HEAD + body("rod") + joint("J.angle", "revolute",
                                                             point="[0.0, 0.0]"),
                "joint name 'J.angle'", "'.'")


def test_reserved_character_refused_api():
    mech = Mechanism(gravity=(0.0, -9.81))
    with pytest.raises(ModelError, match="body name 'rod@tip': must not contain '@'"):
        mech.add_body("rod@tip", 1.0, 0.1, (0.5, 0.0))
    mech.add_body("rod", 1.0, 0.1, (0.5, 0.0))
    with pytest.raises(ModelError, match=r"joint name 'J\.angle': must not contain '\.'"):
        mech.add_revolute("J.angle", "ground", "rod", (0.0, 0.0))


def test_generated_dotted_names_still_work():
    """The names casmbd makes itself: a joint's limit, its compliant force and its friction."""
    mech = loads_scene(PENDULUM.replace('point = [0.0, 0.0]\n', 'point = [0.0, 0.0]\n'
                                        'lower = -1.0\nupper = 1.0\n'
                                        'friction = { viscous = 0.1 }\n'))
    assert "pivot.limit" in mech.contacts and "pivot.friction" in mech.forces
    mech = Mechanism(gravity=(0.0, -9.81))
    mech.add_body("rod", 1.0, 0.1, (0.5, 0.0))
    mech.add_revolute("J", "ground", "rod", (0.0, 0.0))
    mech.add_joint_limit("J", lower=-1.0, upper=1.0, model="compliant")
    assert list(mech.contacts) == ["J.limit"] and list(mech.forces) == ["J.limit.force"]


def test_conventional_dotted_names_in_code():
    """Code may name a joint's friction "<joint>.friction" as the scene reader does; the same
    form for something that is not a joint is refused."""
    mech = Mechanism(gravity=(0.0, -9.81))
    mech.add_body("rod", 1.0, 0.1, (0.5, 0.0))
    mech.add_revolute("pin", "ground", "rod", (0.0, 0.0))
    mech.add("joint_friction", "pin.friction", "pin", friction=0.1)
    with pytest.raises(ModelError, match=r"force name 'rod\.friction': must not contain"):
        mech.add("joint_friction", "rod.friction", "pin", friction=0.1)


# ---------------------------------------------------------------------- marker/body clash
def test_marker_named_like_a_body_refused():
    refused(SLIDER + entry("markers", name='"slider"', body='"slider"', point="[0.7, 0.1]"),
            "marker name 'slider'", "a body has this name", 'y("slider")')


def test_marker_named_ground_refused():
    refused(PENDULUM + entry("markers", name='"ground"', body='"rod"', point="[1.0, 0.0]"),
            "marker name 'ground'", "the ground")


def test_body_named_like_a_marker_refused_api():
    mech = Mechanism(gravity=(0.0, -9.81))
    mech.add_body("rod", 1.0, 0.1, (0.5, 0.0))
    mech.add_marker("tip", "rod", (1.0, 0.0))
    with pytest.raises(ModelError, match="body name 'tip': a marker has this name"):
        mech.add_body("tip", 1.0, 0.1, (1.5, 0.0))


def test_marker_clash_refused_cli(tmp_path, capsys):
    cli_refuses(tmp_path, capsys, SLIDER + entry("markers", name='"slider"', body='"slider"',
                                                 point="[0.7, 0.1]"), "marker name 'slider'")


# ---------------------------------------------------------------------- non-finite results
ROOT_OUTPUT = PENDULUM + entry("outputs", name='"root"', value='"sqrt(x(\\"rod\\"))"')


def test_non_finite_output_stops_the_run_naming_it():
    """sqrt(x) of the pendulum's centre: x = 0.5 cos θ turns negative near t = 0.5 s (the rod
    falls from the horizontal); the run used to end with exit 0 and null in the JSON."""
    mech = loads_scene(ROOT_OUTPUT)
    with pytest.raises(IntegratorError) as info:
        simulate(mech, t_end=2.0, steps=10, mode="vm")
    exc = info.value
    assert exc.flag == "NON_FINITE" and "outputs 'root' is nan" in str(exc)
    # the first output time at which x < 0, from the same run without the output
    free = simulate(loads_scene(PENDULUM), t_end=2.0, steps=10, mode="vm")
    k = int(np.flatnonzero(free.body("rod")["position"][:, 0] < 0.0)[0])
    assert exc.time == pytest.approx(free.t[k], abs=1e-12) and f"at t = {exc.time:.6g}" in str(exc)
    partial = exc.partial
    assert len(partial.t) >= 1 and partial.t[-1] < exc.time
    assert np.all(np.isfinite(partial.arrays["outputs"]))
    assert np.all(partial.body("rod")["position"][:, 0] >= 0.0)


def test_non_finite_output_cli(tmp_path, capsys):
    scene = tmp_path / "root.toml"
    scene.write_text(ROOT_OUTPUT)
    code = main(["simulate", str(scene), "--t-end", "2", "--steps", "10", "--mode", "vm",
                 "--json"])
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert code == 1 and len(err) == 1 and err[0].startswith("error: ")
    assert "outputs 'root'" in err[0] and "Traceback" not in captured.err


def _result(**arrays) -> Result:
    n = len(next(iter(arrays.values())))
    return Result("simulation", np.linspace(0.0, 1.0, n), arrays,
                  {"coordinates": ["slide.translation", "pin.angle"]}, {}, "")


def test_first_non_finite_names_the_first_time_and_quantity():
    q = np.zeros((5, 2))
    v = np.zeros((5, 2))
    energy = np.zeros(5)
    v[3, 1] = np.inf
    energy[2] = np.nan
    assert first_non_finite(_result(q=q, v=v, total_energy=energy)) == (
        2, "total_energy", pytest.approx(np.nan, nan_ok=True))
    energy[2] = 0.0
    q[3, 0] = np.nan  # at a tie the positions come first
    k, what, value = first_non_finite(_result(q=q, v=v, total_energy=energy))
    assert (k, what) == (3, "q 'slide.translation'") and np.isnan(value)
    q[3, 0] = 0.0
    assert first_non_finite(_result(q=q, v=v, total_energy=energy))[:2] == (3, "v 'pin.angle'")
    v[3, 1] = 0.0
    conditioning = np.full(5, np.nan)  # not evaluated: NaN by design
    assert first_non_finite(_result(q=q, v=v, constraint_conditioning=conditioning)) is None


# ---------------------------------------------------------------------- fixed-step energy
ROOT = pathlib.Path(__file__).resolve().parents[2]
SPRING = (ROOT / "tests" / "scenes" / "spring_mass.toml").read_text()


def spring(k: float, c: float = 0.0) -> str:
    """The block on a spring (m = 1 kg, x(0) = free length + 0.1 m, at rest), stiffness k."""
    return SPRING.replace("k = 100.0", f"k = {k!r}").replace("c = 0.0 ", f"c = {c!r} ")


def test_rk4_beyond_its_stability_limit_stops_naming_the_energy():
    """k = 1e9 N/m, m = 1 kg: ω = 31623 rad/s, h ω = 316 at h = 0.01 s, far beyond RK4's
    limit 2√2.  E(0) = ½ k 0.1² = 5e6 J; the first step multiplied it by ~1e17 (exit 0
    before)."""
    with pytest.raises(IntegratorError) as info:
        simulate(loads_scene(spring(1e9)), t_end=0.05, steps=5, integrator="rk4", step=0.01,
                 mode="vm")
    exc = info.value
    assert exc.flag == "ENERGY_GROWTH" and exc.time == pytest.approx(0.01)
    assert "from 5e+06 J at t = 0" in str(exc) and "fixed-step rk4 (h = 0.01)" in str(exc)
    assert len(exc.partial.t) == 1


def test_energy_growth_cli(tmp_path, capsys):
    scene = tmp_path / "stiff.toml"
    scene.write_text(spring(1e9))
    out = tmp_path / "run.npz"
    code = main(["simulate", str(scene), "--t-end", "0.05", "--steps", "5", "--integrator",
                 "abm", "--step", "0.01", "--mode", "vm", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and err[0].startswith("error: "), err
    assert "fixed-step abm" in err[0] and "total energy" in err[0]


def test_rk4_step_cli_one_error_line(tmp_path, capsys):
    """``--integrator rk4 --step 0.01`` on the 1e9 N/m spring (exit 0 with 8e7 -> 1.4e15 J
    in the issue): exit 1, one error line naming the method, step and energies."""
    scene = tmp_path / "stiff.toml"
    scene.write_text(spring(1e9))
    code = main(["simulate", str(scene), "--t-end", "0.05", "--steps", "5", "--integrator",
                 "rk4", "--step", "0.01", "--mode", "vm", "--json"])
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert code == 1 and captured.out == "" and "Traceback" not in captured.err
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert "fixed-step rk4 (h = 0.01)" in err[0] and "from 5e+06 J at t = 0" in err[0]


def test_loose_rtol_on_a_stiff_spring_stops_naming_the_energy():
    """k = 1e6 N/m, m = 1 kg (ω = 1000 rad/s), DOPRI5 at rtol 0.1, max_steps 200: the error
    control lets the oscillation grow (x reached 7e12 m at t = 1 s, E 5000 J -> 4e31 J, exit
    0 before).  Now the run stops at the first output whose energy drift exceeds 1000 × the
    initial 5000 J and half the largest kinetic energy (flag ENERGY_GROWTH)."""
    with pytest.raises(IntegratorError) as info:
        simulate(loads_scene(spring(1e6)), t_end=1.0, steps=10, rtol=0.1, max_steps=200,
                 mode="vm")
    exc = info.value
    assert exc.flag == "ENERGY_GROWTH" and "rtol = 0.1" in str(exc)
    assert "from 5000 J at t = 0" in str(exc) and "tighten --rtol" in str(exc)
    energy = exc.partial["kinetic_energy"] + exc.partial["potential_energy"]
    assert np.all(np.abs(energy - 5000.0) < 5000.0 * 1e3)   # the kept part is below the bound
    # a loose tolerance on a soft spring is no blow-up: runs, E = 0.5 J kept within 1e-3 J
    # (measured 5.8e-5 J at t = 5 s)
    soft = simulate(loads_scene(spring(100.0)), t_end=5.0, steps=50, rtol=0.1, mode="vm")
    assert np.max(np.abs(soft["kinetic_energy"] + soft["potential_energy"] - 0.5)) < 1e-3


@pytest.mark.parametrize("k", [1e6, 1e9])
def test_loose_rtol_on_a_stiff_spring_cli(tmp_path, capsys, k):
    """The issue's command, ``--rtol 0.1 --max-steps 200`` on a stiff spring: exit 1 with one
    error line (the energy blow-up at 1e6 N/m, too much work at 1e9 N/m), never exit 0."""
    scene = tmp_path / "stiff.toml"
    scene.write_text(spring(k))
    code = main(["simulate", str(scene), "--t-end", "1", "--steps", "10", "--rtol", "0.1",
                 "--max-steps", "200", "--mode", "vm", "--json"])
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert code == 1 and captured.out == "" and "Traceback" not in captured.err
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert ("total energy" if k == 1e6 else "TOO_MUCH_WORK") in err[0], err[0]


@pytest.mark.parametrize("integrator", ["rk4", "abm"])
def test_sound_fixed_step_run_passes_the_energy_check(integrator):
    """k = 1e4 N/m at h = 1e-3 s (h ω = 0.1): runs, and matches x = 1 + 0.1 cos(100 t)
    within 5e-5 m (a phase error of order (h ω)⁴ ω t = 5e-3 rad on 0.1 m; measured 1.3e-5
    for ABM4) and keeps E = 50 J within 0.05 J (measured drift 7.9e-3 J for ABM4, far below
    the check's bound of half the largest kinetic energy, 25 J)."""
    result = simulate(loads_scene(spring(1e4)), t_end=0.5, steps=50, integrator=integrator,
                      step=1e-3, mode="vm")
    x = result.body("block")["position"][:, 0]
    assert np.max(np.abs(x - (1.0 + 0.1 * np.cos(100.0 * result.t)))) < 5e-5
    energy = result["total_energy"]
    assert np.max(np.abs(energy - 50.0)) < 0.05  # E = ½ k 0.1² = 50 J


def test_damped_scene_is_not_energy_checked_but_its_blow_up_is_named():
    """With damping c = 1 N s/m the energy may change physically: not energy-checked, but the
    state norm that grows ~1e10-fold in the first step stops the run (flag STATE_GROWTH, exit 0
    with x ~ 1e40 m before); c = 0 through a parameter counts as no damper."""
    mech = loads_scene(spring(1e9, c=1.0))
    with pytest.raises(IntegratorError) as info:
        simulate(mech, t_end=0.05, steps=5, integrator="rk4", step=0.01, mode="vm")
    assert info.value.flag == "STATE_GROWTH" and info.value.time == pytest.approx(0.01)
    assert "state norm" in str(info.value) and len(info.value.partial.t) == 1
    result = simulate(loads_scene(spring(100.0)), t_end=0.1, steps=2, mode="vm")
    assert energy_exchange(loads_scene(spring(100.0)), result) == []
    assert energy_exchange(loads_scene(spring(100.0, c=1.0)), result) == ["damper 'spring'"]


def test_sound_damped_fixed_step_run_passes():
    """k = 1e4 N/m, c = 1 N s/m (ζ = 0.005), h = 1e-3 s: matches the damped oscillation
    x = 1 + 0.1 e^(−ζωt) (cos ω_d t + ζ/√(1−ζ²) sin ω_d t) within 5e-5 m."""
    result = simulate(loads_scene(spring(1e4, c=1.0)), t_end=0.5, steps=50, integrator="rk4",
                      step=1e-3, mode="vm")
    omega, zeta = 100.0, 0.005
    wd, t = omega * np.sqrt(1 - zeta**2), result.t
    exact = 1.0 + 0.1 * np.exp(-zeta * omega * t) * (np.cos(wd * t) + zeta / np.sqrt(
        1 - zeta**2) * np.sin(wd * t))
    assert np.max(np.abs(result.body("block")["position"][:, 0] - exact)) < 5e-5


def test_long_free_fall_is_no_blow_up():
    """A free fall over 1000 s reaches 4.9e6 m (a state 1e7 times its start) with a steady
    growth: not stopped, and exact (RK4 integrates a quadratic exactly; 1e-9 relative)."""
    mech = loads_scene(HEAD + body("ball", x=0.0, y=0.5))
    result = simulate(mech, t_end=1000.0, steps=10, integrator="rk4", step=1.0, mode="vm")
    y = result.body("ball")["position"][:, 1]
    assert y == pytest.approx(0.5 - 0.5 * 9.81 * result.t**2, rel=1e-9)


# ---------------------------------------------------------------------- FE models
def _beam(n: int = 6):
    """The planar spin-up beam of issue 23 (L = 10 m, 3 dofs per node), named root and tip."""
    return beam_model(10.0, n, EA=2.8e7, rhoA=1.2, EI=1.4e4)


def _saved(tmp_path, mass, model, positions=None) -> pathlib.Path:
    path = tmp_path / "part.npz"
    save_fe_npz(path, mass, model.stiffness_matrix.toarray(),
                model.positions if positions is None else positions, model.dofs_per_node,
                node_names=model.node_names)
    return path


def _indefinite(model, dof_a: int, dof_b: int) -> np.ndarray:
    """M with a coupling of two translational dofs 10× their diagonal: symmetric, positive
    diagonal (passes the import checks), indefinite (a 2×2 minor m_a m_b − c² < 0)."""
    M = model.mass_matrix.toarray()
    c = 10.0 * max(M[dof_a, dof_a], M[dof_b, dof_b])
    M[dof_a, dof_b] = M[dof_b, dof_a] = c
    assert np.linalg.eigvalsh(M).min() < 0.0 and np.all(np.diag(M) > 0.0)
    return M


@pytest.mark.parametrize("reduction", ["craig_bampton", "free"])
def test_indefinite_fe_mass_matrix_refused_before_reduction(tmp_path, reduction):
    model = _beam()
    fe = load_fe_npz(_saved(tmp_path, _indefinite(model, 3, 9), model))  # x of nodes 1 and 3
    with pytest.raises(ModelError) as info:
        modal_reduction.reduce(fe, reduction, 2, ["root", "tip"])
    message = str(info.value)
    assert "part.npz" in message and "mass matrix is not positive definite" in message
    assert "dof 9, node 3" in message  # the leading minor that includes dof 9 fails first


def test_indefinite_fe_mass_matrix_sparse_path():
    """Above DENSE_LIMIT dofs: the inertia by a sparse LU (600 elements, 1803 dofs)."""
    model = _beam(600)
    assert model.mass_matrix.shape[0] > modal_reduction.DENSE_LIMIT
    modal_reduction.check_fe_model(model)  # the sound model passes
    M = model.mass_matrix.tolil()
    c = 10.0 * M[3, 3]
    M[3, 6] = M[6, 3] = c
    bad = dataclasses.replace(model, mass_matrix=M.tocsr())
    with pytest.raises(ModelError, match="mass matrix is not positive definite"):
        modal_reduction.check_fe_model(bad)


def test_fe_nodes_all_at_one_point_refused(tmp_path):
    model = _beam()
    fe = load_fe_npz(_saved(tmp_path, model.mass_matrix.toarray(), model,
                            np.zeros_like(model.positions)))
    with pytest.raises(ModelError, match=r"all 7 nodes are at one point"):
        modal_reduction.craig_bampton(fe, 2, ["root", "tip"])


def test_fe_coincident_nodes_refused_naming_them(tmp_path):
    model = _beam()
    positions = model.positions.copy()
    positions[4] = positions[3]
    fe = load_fe_npz(_saved(tmp_path, model.mass_matrix.toarray(), model, positions))
    with pytest.raises(ModelError, match=r"node 3 and node 4 are at one position"):
        modal_reduction.free_modes(fe, 2)


def test_indefinite_fe_mass_matrix_cli(tmp_path, capsys):
    model = _beam()
    _saved(tmp_path, _indefinite(model, 3, 9), model)
    scene = tmp_path / "fe.toml"
    scene.write_text(HEAD + '\n[[bodies]]\nname = "beam"\ntype = "flexible"\n'
                     'position = [0.0, 0.0]\nmodes = 2\nreduction = "craig_bampton"\n'
                     'interfaces = ["root"]\n[bodies.fe]\nfile = "part.npz"\n')
    code = main(["info", str(scene)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and err[0].startswith("error: "), err
    assert "beam" in err[0] and "mass matrix is not positive definite" in err[0]


# ------------------------------------------------------------- implausible units and counts
TRUSS_NODES = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], float)


def truss(tmp_path, mass_scale: float = 1.0, stiffness_scale: float = 1.0) -> pathlib.Path:
    """A plane truss (two square bays with diagonals, EA = 1e6 N, 2 kg/m, 6 nodes) saved as
    ``truss.npz`` with M and K scaled."""
    K, M = np.zeros((12, 12)), np.zeros((12, 12))
    for a, b in [(0, 1), (1, 2), (3, 4), (4, 5), (0, 3), (1, 4), (2, 5), (0, 4), (1, 5)]:
        d = TRUSS_NODES[b] - TRUSS_NODES[a]
        h = np.linalg.norm(d)
        c = np.r_[-d, d] / h
        idx = [2 * a, 2 * a + 1, 2 * b, 2 * b + 1]
        K[np.ix_(idx, idx)] += 1e6 / h * np.outer(c, c)
        M[np.ix_(idx, idx)] += 2.0 * h / 6 * np.kron([[2.0, 1.0], [1.0, 2.0]], np.eye(2))
    path = tmp_path / "truss.npz"
    save_fe_npz(path, M * mass_scale, K * stiffness_scale, TRUSS_NODES, 2,
                node_names={"left": 0, "right": 5})
    return path


def truss_scene(tmp_path, **scales) -> pathlib.Path:
    truss(tmp_path, **scales)
    scene = tmp_path / "flex.toml"
    scene.write_text(HEAD + '\n[[bodies]]\nname = "bar"\ntype = "flexible"\n'
                     'position = [0.0, 0.0]\nmodes = 2\ninterfaces = ["left", "right"]\n'
                     '[bodies.fe]\nfile = "truss.npz"\n')
    return scene


def cli_file_refuses(capsys, scene: pathlib.Path, *fragments: str) -> str:
    """``casmbd simulate`` on ``scene``: exit 1, one error line naming every fragment, no
    traceback, no file written beside the scene."""
    before = sorted(p.name for p in scene.parent.iterdir())
    code = main(["simulate", str(scene), "--t-end", "0.01", "--steps", "2", "--mode", "vm",
                 "--out", str(scene.parent / "run.npz")])
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert code == 1 and "Traceback" not in captured.err, captured.err
    assert len(err) == 1 and err[0].startswith("error: "), err
    for fragment in fragments:
        assert fragment in err[0], f"{fragment!r} not in {err[0]!r}"
    assert sorted(p.name for p in scene.parent.iterdir()) == before
    return err[0]


def test_fe_model_of_implausible_units_refused(tmp_path, capsys):
    """K × 1e300 ("internal error (IndexError)" in the issue; a CVODES failure at t = 0 on
    main) and M × 1e-300 (ran, with 2e-299 kg): the FE file and the matrix are named."""
    sound = truss_scene(tmp_path)
    assert main(["info", str(sound)]) == 0
    capsys.readouterr()
    cli_file_refuses(capsys, truss_scene(tmp_path, stiffness_scale=1e300), "key 'fe'",
                     "truss.npz", "body 'bar'", "stiffness matrix K", "plausible 1e+15 rad/s")
    cli_file_refuses(capsys, truss_scene(tmp_path, mass_scale=1e-300), "key 'fe'",
                     "truss.npz", "total mass of", "kg, outside the plausible range")
    fe = load_fe_npz(truss(tmp_path, stiffness_scale=1e300))
    with pytest.raises(ModelError, match="stiffness matrix K over the mass matrix M"):
        modal_reduction.check_fe_model(fe)   # every reduction runs it
    # the sound truss's highest K_ii/M_ii: ω ≈ 1.7e3 rad/s, twelve decades inside the range
    fe = load_fe_npz(truss(tmp_path))
    ratio = fe.stiffness_matrix.diagonal() / fe.mass_matrix.diagonal()
    assert 1e5 < ratio.max() < 1e8


def beam_scene(length="10.0", EI="1.4e4", elements=10, modes=4) -> str:
    return (HEAD + '\n[[bodies]]\nname = "beam"\ntype = "flexible"\nposition = [0.0, 0.0]\n'
            f'modes = {modes}\nreduction = "craig_bampton"\ninterfaces = ["root"]\n'
            f'[bodies.beam]\nlength = {length}\nelements = {elements}\nEI = {EI}\n'
            f'EA = 2.8e7\nrhoA = 1.2\nnodes = {{ root = 0.0, tip = {length} }}\n')


@pytest.mark.parametrize("field, text, shown", [
    ("length", beam_scene(length="1e-300"), "field 'length' = 1e-300 m is outside the "
                                            "plausible range [1e-09, 1e+06] m"),
    ("EI", beam_scene(EI="1e308"), "field 'EI' = 1e+308 N·m² is outside the plausible "
                                   "range [1e-30, 1e+20] N·m²")])
def test_beam_of_implausible_length_or_stiffness_refused(tmp_path, capsys, field, text, shown):
    """Length 1e-300 m or EI 1e308 ("is the mass matrix positive definite?" before): the
    body, the field and the range are named."""
    refused(text, "beam 'beam'", shown)
    scene = tmp_path / "beam.toml"
    scene.write_text(text)
    cli_file_refuses(capsys, scene, "('beam') key 'beam'", shown)


def test_beam_element_frequency_beyond_the_plausible_refused():
    """Each property in range, the combination not: 1e4 elements of 1e-5 m with EI = 1e20 and
    rhoA = 1e-20 give 8400 EI/(rhoA h⁴) = 8.4e63 rad²/s², ω ≈ 1e32 rad/s."""
    with pytest.raises(ModelError, match=r"field 'EI' = 1e\+20 with rhoA = 1e-20 .* ω ≈ 1e32"):
        beam_model(0.1, 10_000, EA=1e-20, rhoA=1e-20, EI=1e20)
    beam_model(10.0, 10, EA=2.8e7, rhoA=1.2, EI=1.4e4)  # the spin-up beam passes


def test_more_modes_than_the_beam_can_give_refused_naming_modes(tmp_path, capsys):
    """500 Craig–Bampton modes of a 200-element beam ("zero-energy modes … (a mechanism)"
    before): the fixed-interface eigenvalues span 14.4 to 1.4e12, the lowest then fall under
    the zero-energy threshold; the message names the field ``modes`` and a count that works.
    700 modes exceed the 600 interior dofs."""
    message = refused(beam_scene(elements=200, modes=500), "key 'modes'", "500 fixed-interface "
                      "modes asked for, more than the model can give apart", "use at most")
    usable = int(message.rsplit("use at most ", 1)[1].split()[0])
    assert 100 < usable < 500
    mech = loads_scene(beam_scene(elements=200, modes=usable))   # the advice holds
    assert mech.bodies["beam"].n_modes == usable
    refused(beam_scene(elements=200, modes=700), "key 'modes'",
            "700 modes asked for but the problem has only 600 dofs")
    scene = tmp_path / "beam.toml"
    scene.write_text(beam_scene(elements=200, modes=500))
    cli_file_refuses(capsys, scene, "key 'modes'", "use at most")
    # free modes: the dofs less the rigid-body modes (15 dofs of a free 4-element beam, 3)
    free = beam_model(2.0, 4, EA=1e6, EI=50.0, rhoA=1.5)
    with pytest.raises(modal_reduction.ModesError, match="15 dofs less its 3 rigid-body "
                       "modes give at most 12 modes"):
        modal_reduction.free_modes(free, 15)
    assert modal_reduction.free_modes(free, 12).n_modes == 12


def test_non_finite_output_with_events_is_named():
    """The same check on the event path: the bouncing ball (drop from 1.1 m, centre) with an
    output sqrt(y − 0.6) that is NaN once the centre is below 0.6 m, before the first impact
    (t = √(2 · 1 m / g) = 0.452 s)."""
    text = (ROOT / "examples" / "bouncing_ball.toml").read_text() + entry(
        "outputs", name='"above"', value='"sqrt(y(\\"ball\\") - 0.6)"')
    with pytest.raises(IntegratorError) as info:
        simulate(loads_scene(text), t_end=1.0, steps=20, mode="vm")
    exc = info.value
    assert exc.flag == "NON_FINITE" and "outputs 'above' is nan" in str(exc)
    # y = 1.1 − g t²/2 < 0.6 first at t = 0.35 on the 0.05 s grid (0.319 s exactly)
    assert exc.time == pytest.approx(0.35, abs=1e-9)
