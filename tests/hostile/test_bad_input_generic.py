"""Hostile inputs whose messages did not name the culprit (issue 31, the sweep's "generic" cases).

Each case asserts the error class (or the CLI's exit 1 with one error line and no traceback)
and the culprit named; the stiffness diagnosis is checked against the closed form
ω = sqrt(k/m) of a spring-mass block.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from casmbd.analysis.dynamics.simulate import Simulator, simulate
from casmbd.analysis.integrators.option_ranges import check_integrator_options
from casmbd.analysis.integrators.stiffness_culprit import diagnose_stiffness
from casmbd.cli import main
from casmbd.errors import AnalysisError, CasmbdError, IntegratorError, ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.ocp import options as ocp_options

SPRING = """\
[scene]
name = "spring_mass"
dimension = 2
gravity = [0.0, -9.81]

[parameters]
k = 100.0
m = 2.0

[[bodies]]
name = "block"
mass = "m"
inertia = "m / 100"
position = [1.1, 0.0]

[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [1.1, 0.0]
axis = [1.0, 0.0]

[[forces]]
name = "spring"
type = "spring_damper"
body1 = "ground"
body2 = "block"
point1 = [0.0, 0.0]
point2 = [1.1, 0.0]
stiffness = "k"
free_length = 1.0
"""

BALL = """\
[scene]
name = "bouncing_ball"
dimension = 2
gravity = [0.0, -9.81]

[[bodies]]
name = "ball"
mass = 1.0
inertia = 0.001
position = [0.0, 1.1]

[[contacts]]
name = "floor"
type = "plane"
body = "ball"
point = [0.0, 0.0]
normal = [0.0, 1.0]
radius = 0.1
model = "compliant"
stiffness = 1e6
"""


def cli(tmp_path, capsys, text: str, *args: str, verb: str = "simulate",
        vm: bool = True) -> str:
    """Run the CLI on scene ``text``; assert exit 1, one error line, no traceback; the line."""
    scene = tmp_path / "s.toml"
    scene.write_text(text)
    code = main([verb, str(scene), *(("--mode", "vm") if vm else ()), *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1, err
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert "Traceback" not in err[0]
    return err[0]


# ---------------------------------------------------------------------- (b) integrator options
@pytest.mark.parametrize("flags, culprit", [
    (("--t-end", "1", "--steps", "10", "--rtol", "1e-300"), "--rtol"),
    (("--t-end", "1", "--steps", "10", "--rtol", "0.9"), "--rtol"),
    (("--t-end", "1", "--steps", "10", "--atol", "1e-320"), "--atol"),
    (("--t-end", "1e-320", "--steps", "10"), "--t-end"),
    (("--t-end", "1", "--steps", "10", "--integrator", "rk4", "--step", "1e-300"), "--step"),
])
def test_integrator_option_out_of_range_names_the_option(tmp_path, capsys, flags, culprit):
    """--rtol 1e-300 and --t-end 1e-320 gave "dopri5 failed at t = 0 with TOO_SMALL_STEP"."""
    line = cli(tmp_path, capsys, SPRING, *flags)
    assert culprit in line, line


def test_option_ranges_bounds():
    """The stated bounds themselves are accepted, the next values outside refused."""
    check_integrator_options(1.0, 10, rtol=1e-14, atol=1e-30, max_steps=10_000_000)
    check_integrator_options(1.0, 10, rtol=0.5, atol=1e6)
    check_integrator_options(1e-14, 10)  # interval 1e-15 s: the floor itself
    for kwargs in ({"rtol": 9e-15}, {"rtol": 0.51}, {"atol": 9e-31}, {"atol": 2e6},
                   {"max_steps": 10_000_001}, {"step": 9e-16}):
        with pytest.raises(AnalysisError, match=next(iter(kwargs))):
            check_integrator_options(1.0, 10, **kwargs)
    with pytest.raises(AnalysisError, match="output interval"):
        check_integrator_options(1e6 + 1e-7, 10, t_start=1e6)  # 1e-8 s < 1e-12 · 1e6


# ---------------------------------------------------------------------- (c) wrong blame
def test_huge_axis_component_is_normalised_scale_safely():
    """axis [1, 1e300] is the y axis (|axis|² overflowed: "mass matrix singular … 'block'"),
    [1e-200, 0] the x axis (|axis|² underflowed to 0); zero is refused naming the field."""
    mech = loads_scene(SPRING.replace("axis = [1.0, 0.0]", "axis = [1.0, 1e300]"))
    assert mech.joints["slide"].axis.tolist() == pytest.approx([0.0, 1.0], abs=1e-15)
    mech = loads_scene(SPRING.replace("axis = [1.0, 0.0]", "axis = [1e-200, 0.0]"))
    assert mech.joints["slide"].axis.tolist() == [1.0, 0.0]
    with pytest.raises(SceneError, match=r"'slide'.*'axis'.*zero"):
        loads_scene(SPRING.replace("axis = [1.0, 0.0]", "axis = [0.0, 0.0]"))


def test_spatial_axis_normalised_scale_safely():
    from casmbd.model.spatial_joints import _unit

    assert _unit([3e300, 4e300, 0.0], "joint 'j' field 'axis'").tolist() == \
        pytest.approx([0.6, 0.8, 0.0], abs=1e-15)
    with pytest.raises(ModelError, match="'axis'"):
        _unit([0.0, 0.0, 0.0], "joint 'j' field 'axis'")


@pytest.mark.parametrize("old, new, culprits", [
    ("mass = 1.0", "mass = 1e300", ("'ball'", "'mass'", "1e+15")),
    ("mass = 1.0", "mass = 1e-300", ("'ball'", "'mass'", "1e-15")),
    ("inertia = 0.001", "inertia = 1e300", ("'ball'", "'inertia'", "1e+25")),
    ("gravity = [0.0, -9.81]", "gravity = [0.0, 1e300]", ("'gravity'", "1e+08")),
])
def test_implausible_mass_inertia_gravity_refused(old, new, culprits):
    """Mass 1e300 gave "position constraints violated by 0.0814 at t = 0.5", gravity 1e300
    "kinetic_energy is inf at t = 0.1"."""
    with pytest.raises(CasmbdError) as exc:
        loads_scene(BALL.replace(old, new))
    for culprit in culprits:
        assert culprit in str(exc.value), str(exc.value)


def test_massless_body_still_accepted():
    """Zero mass is not a plausibility refusal (the mass-matrix check judges it)."""
    mech = loads_scene(BALL.replace("mass = 1.0", "mass = 0.0"))
    assert mech.bodies["ball"].mass == 0.0


def test_linearize_result_of_another_scene_names_the_file(tmp_path, capsys):
    other = tmp_path / "ball.toml"
    other.write_text(BALL)
    out = tmp_path / "r.npz"
    assert main(["simulate", str(other), "--mode", "vm", "--t-end", "0.01", "--steps", "1",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    line = cli(tmp_path, capsys, SPRING, "--from", str(out), "--time", "0", verb="linearize")
    assert str(out) in line and "s.toml" in line and "'spring_mass'" in line, line


# ---------------------------------------------------------------------- (d) HSL solvers
@pytest.mark.parametrize("solver", ["ma27", "ma57", "ma77", "ma86", "ma97", "pardiso"])
def test_hsl_solver_without_library_refused_naming_the_library(solver):
    """ipopt.linear_solver = "ma97" without libhsl.so crashed the process with SIGSEGV."""
    found, files = ocp_options.runtime_library(solver)
    if found is not None:
        pytest.skip(f"{found} is installed here")
    with pytest.raises(AnalysisError) as exc:
        ocp_options.check_solver_options("ipopt", {"ipopt.linear_solver": solver})
    text = str(exc.value)
    assert solver in text and files[0] in text, text


# ---------------------------------------------------------------------- (a) stiffness culprit
def _frequency(text: str) -> float:
    match = re.search(r"natural frequency ([0-9.e+-]+) rad/s", text)
    assert match, text
    return float(match.group(1))


def test_loose_rtol_on_stiff_spring_names_the_spring_and_its_frequency():
    """--rtol 0.5 on k = 1e9 N/m: TOO_SMALL_STEP without a why; now the spring with
    ω = sqrt(k/m) = sqrt(1e9/2) (closed form, to the 3 digits printed) and the rtol advice."""
    mech = loads_scene(SPRING.replace("k = 100.0", "k = 1e9"))
    with pytest.raises(IntegratorError) as exc:
        simulate(mech, t_end=1.0, steps=10, mode="vm", rtol=0.5)
    text = str(exc.value)
    assert "force 'spring'" in text and "--rtol" in text, text
    assert _frequency(text) == pytest.approx(math.sqrt(1e9 / 2.0), rel=1e-3)


def test_time_singular_stiffness_named():
    """stiffness = 1/(t − 0.25): "TOO_SMALL_STEP at t = 0.25"; now the spring, its
    'stiffness' and the growth with time at the same state."""
    mech = loads_scene(SPRING.replace('stiffness = "k"', 'stiffness = "1/(t - 0.25)"'))
    with pytest.raises(IntegratorError) as exc:
        simulate(mech, t_end=0.5, steps=5, mode="vm")
    text = str(exc.value)
    assert "force 'spring'" in text and "'stiffness'" in text and "time" in text, text


@pytest.mark.parametrize("coordinates", ["auto", "absolute"])
def test_diagnosis_frequency_on_the_independent_motion(coordinates):
    """In absolute coordinates (x, y, θ with two slide equations) the spring's stiffness is
    k along x only; on the null space of C_q the frequency is sqrt(k/m) again (1 ‰: the
    4 printed digits), and the geometric stiffness of the spring (tension/length across it)
    does not leak in from the constrained directions."""
    mech = loads_scene(SPRING.replace("k = 100.0", "k = 400.0"))
    mech.coordinates = coordinates
    model = Simulator(mech, mode="vm").model
    q0, v0 = model.initial_coordinates(), model.initial_velocities()
    text = diagnose_stiffness(model, 0.0, q0, v0)
    assert "force 'spring'" in text, text
    assert _frequency(text) == pytest.approx(math.sqrt(400.0 / 2.0), rel=1e-3)


def test_huge_spring_stiffness_refused_before_the_run():
    """stiffness 1e300 gave "dopri5 failed at t = 0 with TOO_SMALL_STEP (h = 0)"."""
    mech = loads_scene(SPRING.replace("k = 100.0", "k = 1e300"))
    with pytest.raises(ModelError,
                       match=r"force 'spring' field 'stiffness'.*sqrt\(k/m\) = 7.07e\+149"):
        simulate(mech, t_end=1.0, steps=10, mode="vm")


def test_huge_free_length_refused_before_the_run():
    mech = loads_scene(SPRING.replace("free_length = 1.0", "free_length = 1e300"))
    with pytest.raises(ModelError, match=r"force 'spring' field 'free_length'.*1e\+06 m"):
        simulate(mech, t_end=1.0, steps=10, mode="vm")


def test_huge_contact_stiffness_refused_before_the_run():
    """A compliant contact of stiffness 1e300: CV_TOO_MUCH_WORK at t = 0.45 without a why."""
    mech = loads_scene(BALL.replace("stiffness = 1e6", "stiffness = 1e300"))
    with pytest.raises(ModelError, match=r"contact 'floor' field 'stiffness'"):
        simulate(mech, t_end=1.0, steps=10, mode="vm")


def test_plausible_stiffness_runs():
    """The bound is far from real springs: k = 1e9 N/m on 2 kg (ω = 2.2e4 rad/s) is accepted
    and the block oscillates about x = 1 (+ no gravity along the slide) with the closed-form
    period: x(t) = 1 + 0.1 cos(ω t)."""
    mech = loads_scene(SPRING.replace("k = 100.0", "k = 1e4"))
    res = simulate(mech, t_end=0.1, steps=10, mode="vm", rtol=1e-10)
    omega = math.sqrt(1e4 / 2.0)
    x = np.asarray(res["q"])[:, 0]
    assert x == pytest.approx(0.1 * (np.cos(omega * res.t) - 1.0), abs=1e-6)  # from 1.1


def test_urdf_huge_axis_component_is_normalised():
    """<axis xyz="1 1e300 0"> is the y axis (|axis|² overflowed to inf: a zero axis)."""
    from casmbd import loads_urdf

    text = ('<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/>'
            '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
            '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
            '<origin xyz="0 0 0"/><axis xyz="1 1e300 0"/><limit lower="-1" upper="1" '
            'effort="1" velocity="1"/></joint></robot>')
    axis = loads_urdf(text, "t.urdf").joints["j"].axis
    assert axis.tolist() == pytest.approx([0.0, 1.0, 0.0], abs=1e-15)


def test_diagnosis_of_a_flexible_body_matches_the_linearized_frequency():
    """The spin-up beam without its driver and stiffening (free hub, v = 0, no gravity): its
    elastic forces are the only stiffness, so the diagnosis's ω equals the highest natural
    frequency of ``linearize`` (an independent path: the linearized M, K and their reduced
    eigenproblem), 275.9 rad/s, to the 4 printed digits (1e-3)."""
    from pathlib import Path

    from casmbd.analysis.statics.linearize import linearize

    text = (Path(__file__).resolve().parents[2] / "examples" / "spinup_beam.toml").read_text()
    text = text[:text.index("[[drivers]]")].replace("stiffening = true", "stiffening = false")
    mech = loads_scene(text)
    omega_max = 2 * math.pi * float(np.max(linearize(mech, mode="vm").natural_frequencies_hz))
    model = Simulator(loads_scene(text), mode="vm").model
    diag = diagnose_stiffness(model, 0.0, model.initial_coordinates(),
                              model.initial_velocities())
    assert "body 'beam'" in diag and "'rhoA'" in diag, diag
    assert _frequency(diag) == pytest.approx(omega_max, rel=1e-3)


def test_sensitivity_rtol_out_of_range_names_it(tmp_path, capsys):
    """The sensitivity verb's --rtol has the same range as simulate's."""
    line = cli(tmp_path, capsys, SPRING, "--output", "x", "--param", "k", "--t-end", "1",
               "--rtol", "1e-300", verb="sensitivity", vm=False)
    assert "--rtol" in line, line


BALL_EXAMPLE = (Path(__file__).resolve().parents[2] / "examples"
                / "bouncing_ball.toml").read_text()


def test_body_position_beyond_the_plausible_range_named(tmp_path, capsys):
    """A ball at y = 1e300 with its contact sphere at y = 1.1: the body-fixed offset −1e300
    put the sphere's centre at 0 ("penetrates by 0.1"); now the body's field is named."""
    text = BALL_EXAMPLE.replace('position = [0.0, "h0 + r"]', "position = [0.0, 1e300]")
    err = cli(tmp_path, capsys, text, "--t-end", "1", "--steps", "4")
    assert "body 'ball' field 'position'" in err and "1e+09 m" in err


def test_initial_penetration_names_the_body(tmp_path, capsys):
    """h0 = −1: the ball starts 1 m inside the floor; the message names the contact, the gap
    and the body whose position to check."""
    text = BALL_EXAMPLE.replace("h0 = 1.0 ", "h0 = -1.0 ")
    err = cli(tmp_path, capsys, text, "--t-end", "1", "--steps", "4")
    assert "contact 'floor'" in err and "penetrates by 1 " in err
    assert "body 'ball': check its 'position'" in err
