"""Bad input, numbers: NaN/inf values named (element, field, time), sampled drivers outside
their samples, and drivers that contradict the joints.

Every case asserts the error class and that the message names the culprit; the sampled-driver
cases compare the continued trajectory with its closed form.  Small planar scenes on CasADi's
virtual machine (``CASMBD_COMPILE=0``), so the file runs in seconds.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import private_cache
from scene_builders import HEAD, PENDULUM, body, entry, joint

from casmbd.analysis.driven.inverse import inverse_dynamics
from casmbd.analysis.driven.kinematics import kinematics
from casmbd.analysis.dynamics.simulate import simulate
from casmbd.analysis.statics.linearize import linearize
from casmbd.analysis.statics.statics import static_equilibrium
from casmbd.cli import main
from casmbd.errors import AssemblyError, IntegratorError, ModelError, SceneError
from casmbd.io.scene import loads_scene
from casmbd.model.values import Samples

_vm = private_cache("cache_numbers", CASMBD_COMPILE="0")


def force(value_toml: str, name: str = "push") -> str:
    """The pendulum with a point force ``value`` (TOML text) on its rod."""
    return PENDULUM + entry("forces", name=f'"{name}"', type='"force"', body='"rod"',
                            value=value_toml)


def driven(position_toml: str) -> str:
    """The pendulum with its pivot driven by ``position`` (TOML text)."""
    return PENDULUM + entry("drivers", name='"spin"', joint='"pivot"', position=position_toml)


def assert_names(exc_info, *fragments: str) -> str:
    message = str(exc_info.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return message


# ---------------------------------------------------------------------- NaN/inf at t = 0
@pytest.mark.parametrize("expr, shown", [("log(t)", "-inf"), ("1/t", "inf"),
                                         ("sqrt(-1)", "nan")])
def test_force_expression_not_finite_at_start_simulate(expr, shown):
    mech = loads_scene(force(f'["{expr}", 0.0]'))
    with pytest.raises(ModelError) as exc:
        simulate(mech, t_end=0.1, steps=2, mode="vm")
    assert_names(exc, "force 'push'", "field 'value'", f"is {shown} at t = 0", expr)


@pytest.mark.parametrize("analysis", ["statics", "linearize"])
def test_force_expression_not_finite_statics_and_linearize(analysis):
    mech = loads_scene(force('["log(t)", 0.0]'))
    run = static_equilibrium if analysis == "statics" else linearize
    with pytest.raises(ModelError) as exc:
        run(mech, mode="vm")
    assert_names(exc, "force 'push'", "'value'", "t = 0")


def test_spring_stiffness_not_finite_names_the_field():
    text = PENDULUM + entry("forces", name='"coil"', type='"rotational_spring_damper"',
                            joint='"pivot"', stiffness='"log(t)"', damping="0.0")
    with pytest.raises(ModelError) as exc:
        simulate(loads_scene(text), t_end=0.1, steps=2, mode="vm")
    assert_names(exc, "force 'coil'", "field 'stiffness'", "t = 0")


def test_inverse_dynamics_names_force_not_finite_later():
    """A force finite at the start that turns -inf at t = 0.5: named with that time."""
    text = driven('"t"') + entry("forces", name='"push"', type='"force"', body='"rod"',
                                 value='["log(0.5 - t)", 0.0]')
    with pytest.raises(ModelError) as exc:
        inverse_dynamics(loads_scene(text), t_end=1.0, steps=10, mode="vm")
    assert_names(exc, "inverse dynamics at t = 0.5", "force 'push'", "-inf")


@pytest.mark.parametrize("coordinates, shown", [("absolute", "rod.x = -inf"),
                                                 ("auto", "pivot.angle = nan")])
def test_user_force_not_finite_names_the_element(coordinates, shown):
    """A Python user force (no value field to evaluate) that is -inf at t = 0: the element is
    named from its own generalized force.  In absolute coordinates the force's row is rod.x;
    in the automatic choice (joint coordinates) it is projected on the pivot angle,
    J^T F = -0.5 sin(0) (-inf) = nan."""
    import casadi as ca

    from casmbd.model import Mechanism

    mech = Mechanism("user", gravity=[0.0, -9.81], coordinates=coordinates)
    mech.add_body("rod", mass=1.0, inertia=0.1, position=[0.5, 0.0])
    mech.add_revolute("pivot", "ground", "rod", [0.0, 0.0])
    mech.add_user_force("wild", lambda ctx: ca.vertcat(ca.log(ctx.t), 0.0), body="rod")
    with pytest.raises(ModelError) as exc:
        simulate(mech, t_end=0.1, steps=2, mode="vm")
    assert_names(exc, "simulation at t = 0", "force 'wild'", "not finite", shown)


@pytest.mark.parametrize("expr", ['"log(t)"', '"sqrt(-1)"'])
def test_driver_position_not_finite_at_start(expr):
    with pytest.raises(AssemblyError) as exc:
        kinematics(loads_scene(driven(expr)), t_end=1.0, steps=2, mode="vm")
    assert_names(exc, "driver 'spin'", "field 'position'", "t = 0")


def test_driver_derivative_not_finite_at_start():
    """t**t is finite at 0 but its rate is not: the derivative is named."""
    with pytest.raises(AssemblyError) as exc:
        kinematics(loads_scene(driven('"t**t"')), t_end=1.0, steps=2, mode="vm")
    assert_names(exc, "first time derivative of driver 'spin'", "t = 0")


def test_driver_not_finite_later_in_kinematics():
    with pytest.raises(AssemblyError) as exc:
        kinematics(loads_scene(driven('"sqrt(0.55 - t)"')), t_end=1.0, steps=10, mode="vm")
    assert_names(exc, "t = 0.6", "driver 'spin'", "nan")


@pytest.mark.parametrize("integrator", ["adams", "rk4"])
def test_force_not_finite_during_simulation_names_time(integrator):
    """log(0.5 - t): the run stops with an IntegratorError at t = 0.5 naming the force, and
    the kept results are finite and end before 0.5."""
    mech = loads_scene(force('["log(0.5 - t)", 0.0]'))
    with pytest.raises(IntegratorError) as exc:
        simulate(mech, t_end=1.0, steps=10, integrator=integrator, mode="vm")
    assert_names(exc, "force 'push'", "field 'value'")
    assert abs(exc.value.time - 0.5) <= 1e-9
    partial = exc.value.partial
    assert partial.t[-1] < 0.5 and np.all(np.isfinite(partial["q"]))


def test_scene_rejects_nan_mass_and_velocity_expressions():
    """Load-time values (mass, initial velocity) are named when the scene is read."""
    with pytest.raises(SceneError) as exc:
        loads_scene(HEAD + body("rod", mass='"log(0)"') + joint("pivot", "revolute",
                                                                  point="[0.0, 0.0]"))
    assert_names(exc, "('rod')", "'mass'", "-inf")
    with pytest.raises(SceneError) as exc:
        loads_scene(HEAD + body("rod", velocity='["sqrt(-1)", 0.0]')
                    + joint("pivot", "revolute", point="[0.0, 0.0]"))
    assert_names(exc, "('rod')", "'velocity'", "nan")


def test_cli_nan_force_one_error_line_and_no_file(tmp_path, capsys):
    scene = tmp_path / "nan.toml"
    scene.write_text(force('["log(t)", 0.0]'))
    out = tmp_path / "run.npz"
    code = main(["simulate", str(scene), "--t-end", "0.1", "--steps", "2", "--mode", "vm",
                 "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and err[0].startswith("error: ")
    assert "force 'push'" in err[0] and "Traceback" not in err[0]
    assert not out.exists()


# ---------------------------------------------------------------------- sampled drivers
TIMES = [0.0, 0.25, 0.5, 0.75, 1.0]


def sampled(values, extrapolate: str | None = None) -> str:
    extra = f', extrapolate = "{extrapolate}"' if extrapolate else ""
    return driven(f"{{ times = {TIMES}, values = {list(values)}{extra} }}")


def test_samples_hold_after_last_sample_by_default():
    """f(t) = t² sampled on [0, 1]: after 1 s the coordinate holds f(1) = 1 with zero velocity
    and acceleration (it dropped to 0 before); inside, the cubic spline reproduces t² and 2t to
    1e-9."""
    res = kinematics(loads_scene(sampled([t * t for t in TIMES])), t_end=2.0, steps=8, mode="vm")
    j = res.joint("pivot")
    t = res.t
    inside, after = t <= 1.0, t > 1.0
    assert np.max(np.abs(j["coordinate"][inside] - t[inside] ** 2)) <= 1e-9
    assert np.max(np.abs(j["velocity"][inside] - 2 * t[inside])) <= 1e-9
    assert np.max(np.abs(j["coordinate"][after] - 1.0)) <= 1e-12
    assert np.max(np.abs(j["velocity"][after])) <= 1e-12
    assert np.max(np.abs(j["acceleration"][after])) <= 1e-12


def test_samples_linear_continues_value_and_slope():
    """extrapolate = "linear": f(1) + f'(1) (t − 1) = 1 + 2 (t − 1) after the last sample (to
    1e-9), velocity 2, acceleration 0."""
    res = kinematics(loads_scene(sampled([t * t for t in TIMES], "linear")), t_end=2.0, steps=8,
                     mode="vm")
    j = res.joint("pivot")
    after = res.t > 1.0
    assert np.max(np.abs(j["coordinate"][after] - (1.0 + 2.0 * (res.t[after] - 1.0)))) <= 1e-9
    assert np.max(np.abs(j["velocity"][after] - 2.0)) <= 1e-9
    assert np.max(np.abs(j["acceleration"][after])) <= 1e-12


def test_samples_error_names_driver_and_time():
    with pytest.raises(AssemblyError) as exc:
        kinematics(loads_scene(sampled(TIMES, "error")), t_end=2.0, steps=8, mode="vm")
    assert_names(exc, "t = 1.25", "driver 'spin'", "outside its samples [0, 1]")


def test_samples_hold_before_first_sample_and_velocity_at_ends():
    """Python API: before the first sample the first value holds; at the first and last sample
    the velocity is the spline's (not halved by a min/max clamp)."""
    import casadi as ca

    s = Samples(TIMES, [t * t for t in TIMES])
    tau = ca.SX.sym("t")
    f = ca.Function("f", [tau], [s(tau), ca.jacobian(s(tau), tau)])
    for t, value, rate in ((-0.5, 0.0, 0.0), (0.0, 0.0, 0.0), (1.0, 1.0, 2.0), (1.5, 1.0, 0.0)):
        got = [float(x) for x in f(t)]
        assert abs(got[0] - value) <= 1e-9 and abs(got[1] - rate) <= 1e-9, (t, got)


def test_samples_unknown_extrapolation_is_named():
    with pytest.raises(SceneError) as exc:
        loads_scene(sampled(TIMES, "cubic"))
    assert_names(exc, "('spin')", "'position'", "'extrapolate'", "'cubic'")


# ---------------------------------------------------------------------- contradictory drivers
WELDED = (HEAD + body("block")
          + entry("joints", name='"weld"', type='"fixed"', body='"block"'))


def push(position_toml: str) -> str:
    return WELDED + entry("drivers", name='"push"', body='"block"', coordinate='"x"',
                          position=position_toml)


def test_driver_contradicting_weld_in_position():
    """x = 0.82 for a block welded at x = 0.5: the assembly error names the driver first and
    prints the residuals.  In absolute coordinates the least-squares iterate splits the 0.32 m
    between the driver and the weld (-0.16 each); in the automatic choice (joint coordinates)
    the weld is a tree joint that leaves no coordinate, so the driver keeps all of it (-0.32)
    and the hint gives the only x the joints allow."""
    mech = loads_scene(push("0.82"))
    mech.coordinates = "absolute"
    with pytest.raises(AssemblyError) as exc:
        kinematics(mech, t_end=1.0, steps=2, mode="vm")
    message = assert_names(exc, "driver 'push' equation 'x' residual -0.16",
                           "joint 'weld' equation 'x' residual -0.16")
    assert message.index("driver 'push'") < message.index("joint 'weld'")
    with pytest.raises(AssemblyError) as exc:
        kinematics(loads_scene(push("0.82")), t_end=1.0, steps=2, mode="vm")
    assert_names(exc, "driver 'push' asks for body 'block' x = 0.82 at t = 0",
                 "allow only body 'block' x at most 0.5",
                 "driver 'push' equation 'x' residual -0.32")


@pytest.mark.parametrize("position, level", [('"0.5 + t"', "velocity"),
                                             ('"0.5 + t**2"', "acceleration")])
def test_simulation_start_with_contradicting_driver_rates(position, level):
    """Agrees with the weld at t = 0 in position but not in rate: the simulation used to run
    with minimum-norm multipliers and end with |C| = 1; now an AssemblyError at the start.
    In the automatic choice (joint coordinates) the welded block has no coordinate at all:
    the augmented-Lagrangian penalty used to fail on the empty mass matrix (numpy ValueError)."""
    with pytest.raises(AssemblyError) as exc:
        simulate(loads_scene(push(position)), t_end=1.0, steps=4, mode="vm")
    assert_names(exc, "t = 0", f"{level} level", "driver 'push'", "residual")


def test_two_drivers_disagreeing_in_rate():
    text = (driven('"t"') + entry("drivers", name='"spin2"', body='"rod"',
                                  coordinate='"angle"', position='"2*t"'))
    with pytest.raises(AssemblyError) as exc:
        simulate(loads_scene(text), t_end=1.0, steps=4, mode="vm")
    assert_names(exc, "driver 'spin2'", "driver 'spin'", "residual 0.5")


def test_driver_unreachable_later_in_kinematics():
    """The rod's centre (0.5 m from the pivot) driven to x = 0.4 + 0.2 t leaves its reach at
    t = 0.5: kinematics stops at the first output after it, naming the equations (absolute
    coordinates: the driver and the pivot; the automatic choice, joint coordinates: the pivot
    is the tree, the driver is named with the range |x| <= 0.5 the pivot allows)."""
    text = (HEAD + body("rod", x=0.4, y=0.3, angle="0.6435")
            + joint("pivot", "revolute", point="[0.0, 0.0]")
            + entry("drivers", name='"reach"', body='"rod"', coordinate='"x"',
                    position='"0.4 + 0.2*t"'))
    mech = loads_scene(text)
    mech.coordinates = "absolute"
    with pytest.raises(AssemblyError) as exc:
        kinematics(mech, t_end=1.0, steps=10, mode="vm")
    assert_names(exc, "t = 0.6", "joint 'pivot'", "residual")
    with pytest.raises(AssemblyError) as exc:
        kinematics(loads_scene(text), t_end=1.0, steps=10, mode="vm")
    message = assert_names(exc, "t = 0.6", "driver 'reach' asks for body 'rod' x = 0.52",
                           "residual")
    low, high = (float(x) for x in
                 message.split("x from ")[1].split(",")[0].split(" to "))
    assert abs(low + 0.5) < 1e-3 and abs(high - 0.5) < 1e-3, message
