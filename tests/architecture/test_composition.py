"""The composition matrix (issue 30): every element kind × every analysis — it works, or it is
refused by name before any work.

Generated from the registries: every registered joint, force and body kind must have a
canonical scene (``composition_scenes.KIND_VARIANTS``) and must declare its needs
(:mod:`casmbd.model.needs`); every analysis declares what it handles (``HANDLING``).  Cells
the declarations refuse must raise :class:`~casmbd.errors.CompositionError` from the real
entry point, naming the element; cells they accept must run and reproduce an independent
check:

* ``simulate``: the same motion in every coordinate choice the scene takes (absolute,
  natural, joint — three independent sets of equations), body positions to 1e-6 m;
* ``kinematics`` / ``inverse`` (driven scenes): the kinematic motion is the forward
  dynamics of the driven mechanism (body positions to 1e-7 m, constraints to 1e-10), and
  inverse dynamics ∘ forward = identity — the driver efforts of inverse dynamics equal those
  the forward simulation needs to impose the same motion, to 1e-6 relative;
* ``statics`` / ``linearize``: the (stable) equilibrium has zero forward-dynamics
  accelerations with the same verdict, and the same natural frequencies in every coordinate
  choice (1e-6); resting on a contact or stop, linearize refuses by name;
* ``sensitivity``: = central differences of whole ``simulate`` runs (1e-5);
* ``compile``: the per-call forward dynamics = the simulation's first accelerations (1e-8);
* ``plot``/``animate``: a picture and a frame of every element kind (each kind once);
* ``sweep``: a swept point equals ``simulate`` of the same scene and value to rounding;
* ``ocp``: the optimal controls replayed by ``simulate`` give the same motion (1e-3 rad), and
  a compliant stop is in the optimised dynamics (the flexible beam's mesh:
  ``tests/ocp/test_ocp_flexible.py``).

``docs/composition.md`` is generated from the same declarations (``python
tests/composition_table.py`` rewrites it); the test below fails when it is stale.
"""

from __future__ import annotations

import numpy as np
import pytest
from composition_scenes import KIND_VARIANTS, VARIANTS
from composition_table import ANALYSES, table

import casmbd
from casmbd.analysis.dynamics.simulate import simulate_handling
from casmbd.analysis.formulations import FORMULATIONS
from casmbd.analysis.integrators.kinds import INTEGRATORS
from casmbd.errors import CasmbdError, CompositionError
from casmbd.model.contacts import JointLimit, PlaneContact, SphereContact
from casmbd.model.drivers import Driver
from casmbd.model.forces import Actuator
from casmbd.model.needs import NEEDS
from casmbd.model.registry import BODY_KINDS, FORCE_KINDS, JOINT_KINDS

CELLS = [(v, d) for v, (_, dims, _) in VARIANTS.items() for d in dims]


def _declares(cls) -> bool:
    """``needs`` declared by the class or a casmbd class between it and the generic base."""
    return any("needs" in vars(k) for k in cls.__mro__ if k is not object)


def _casmbd_kinds():
    for table_ in (JOINT_KINDS, BODY_KINDS):
        for name, per_dim in table_.items():
            for cls in per_dim.values():
                if cls.__module__.startswith("casmbd."):
                    yield ("rigid_body" if table_ is BODY_KINDS and name == "rigid" else name,
                           cls)
    for name, cls in FORCE_KINDS.items():
        if cls.__module__.startswith("casmbd."):
            yield name, cls


@pytest.mark.parametrize("kind,cls", list(_casmbd_kinds()), ids=lambda x: getattr(x, "__name__", x))
def test_every_kind_declares_its_needs_and_has_a_canonical_scene(kind, cls):
    assert _declares(cls), f"{cls.__name__} declares no 'needs' (casmbd.model.needs)"
    assert kind in KIND_VARIANTS, f"kind '{kind}' has no canonical scene in the matrix"


def test_every_element_class_and_method_declares():
    for cls in (PlaneContact, SphereContact, JointLimit, Driver, Actuator):
        assert _declares(cls), cls.__name__
    for kind in FORMULATIONS.values():
        assert kind.handles <= NEEDS.keys(), kind.name
    for kind in INTEGRATORS.values():
        assert kind.handles <= NEEDS.keys(), kind.name
    for handling in ANALYSES.values():
        assert handling.handles <= NEEDS.keys(), handling.analysis


def test_docs_table_is_generated():
    from pathlib import Path
    path = Path(__file__).resolve().parents[2] / "docs" / "composition.md"
    assert path.read_text() == table(), "docs/composition.md is stale: python " \
        "tests/composition_table.py"


# ----------------------------------------------------------------------------- refusals
def _entry(analysis, mech):
    """The real entry point of ``analysis`` on ``mech``, with a tiny problem."""
    if analysis == "kinematics":
        return casmbd.kinematics(mech, 0.1, 2, mode="vm")
    if analysis == "inverse":
        return casmbd.inverse_dynamics(mech, 0.1, 2, mode="vm")
    if analysis == "linearize":
        return casmbd.linearize(mech, mode="vm")
    if analysis == "sensitivity":
        return casmbd.sensitivity(mech, ["link.x"], t_end=0.1)
    if analysis == "ocp":
        from casmbd.ocp import Ocp
        return Ocp(mech, horizon=0.5, intervals=2)
    if analysis == "compile":
        return casmbd.compile(mech, mode="vm")
    raise AssertionError(analysis)


def _scene(variant, dim, analysis):
    build, _, driven = VARIANTS[variant]
    return build(dim, driven=driven and analysis in ("kinematics", "inverse"))


REFUSAL_CELLS = [(v, d, a) for v, d in CELLS for a in
                 ("kinematics", "inverse", "linearize", "sensitivity", "ocp", "compile")
                 if ANALYSES[a].refusals(_scene(v, d, a))]


@pytest.mark.parametrize("variant,dim,analysis", REFUSAL_CELLS)
def test_refused_cells_are_named_before_any_work(variant, dim, analysis):
    mech = _scene(variant, dim, analysis)
    refused = ANALYSES[analysis].refusals(mech)
    with pytest.raises(CompositionError) as info:
        _entry(analysis, mech)
    for r in refused:
        assert r.element in str(info.value)
    assert info.value.refused == [(r.element, r.need) for r in refused]


@pytest.mark.parametrize("variant,dim", CELLS)
def test_simulate_options_refuse_by_name(variant, dim):
    """Every formulation × integrator: a run the declarations refuse raises the named error
    before anything is built; the others are accepted by the check."""
    build, _, _ = VARIANTS[variant]
    mech = build(dim)
    for form in FORMULATIONS:
        for integ in INTEGRATORS:
            handling = simulate_handling(form, integ)
            refused = handling.refusals(mech)
            if not refused:
                continue
            with pytest.raises(CompositionError, match=f"formulation '{form}'"):
                casmbd.simulate(mech, 0.05, 1, formulation=form, integrator=integ, mode="vm")


# ----------------------------------------------------------------------------- numeric cells
def _positions(res):
    return np.asarray(res.arrays["body_positions"], dtype=float)


@pytest.mark.parametrize("variant,dim", CELLS)
def test_simulate_agrees_across_coordinate_choices(variant, dim):
    build, _, _ = VARIANTS[variant]
    runs = {}
    for coords in ("absolute", "natural", "joint"):
        try:
            mech = build(dim, coordinates=coords)
            runs[coords] = casmbd.simulate(mech, 0.2, 4, rtol=1e-10, mode="vm")
        except CasmbdError as exc:  # a coordinate choice the scene cannot take: named
            assert "coordinates" in str(exc) or "coordinate" in str(exc), exc
    assert runs, "no coordinate choice ran"
    ref = _positions(next(iter(runs.values())))
    assert np.all(np.isfinite(ref))
    for coords, res in runs.items():
        assert np.max(np.abs(_positions(res) - ref)) <= 1e-6, coords


DRIVEN = [(v, d) for v, d in CELLS if VARIANTS[v][2]
          and not ANALYSES["inverse"].refusals(VARIANTS[v][0](d, driven=True))]


@pytest.mark.parametrize("variant,dim", DRIVEN)
def test_inverse_of_forward_is_identity(variant, dim):
    """In every coordinate choice the scene takes; the driver efforts (a joint's torque or
    force, whatever the coordinates) also agree across the choices (1e-6 relative)."""
    build, _, _ = VARIANTS[variant]
    efforts = {}
    for coords in _coordinates(variant, dim):
        mech = build(dim, driven=True, coordinates=coords)
        kin = casmbd.kinematics(mech, 0.4, 4, mode="vm")
        try:
            inv = casmbd.inverse_dynamics(mech, 0.4, 4, mode="vm")
        except CasmbdError as exc:  # a coordinate choice the element cannot take: named
            assert "coordinates" in str(exc), exc
            continue
        sim = casmbd.simulate(mech, 0.4, 4, rtol=1e-11, atol=1e-11, formulation="index1",
                              mode="vm")
        assert np.max(np.abs(kin["q"] - inv["q"])) == 0.0
        # kinematics = the forward dynamics of the driven mechanism (another set of equations)
        assert np.max(np.abs(_positions(kin) - _positions(sim))) <= 1e-7, coords
        assert np.max(kin["constraint_violation"]) <= 1e-10, coords
        scale = max(1.0, float(np.max(np.abs(inv["driver_efforts"]))))
        assert np.max(np.abs(sim["driver_efforts"] - inv["driver_efforts"])) <= 1e-6 * scale
        efforts[coords] = inv["driver_efforts"]
    ref = next(iter(efforts.values()))
    for coords, eff in efforts.items():
        assert np.max(np.abs(eff - ref)) <= 1e-6 * max(1.0, float(np.max(np.abs(ref)))), coords


SWEPT = ["revolute", "stop_impact", "contact_impact", "joint_friction_stick_slip",
         "contact_compliant"]


@pytest.mark.parametrize("variant", SWEPT)
def test_sweep_point_equals_simulate(variant, tmp_path):
    build, _, _ = VARIANTS[variant]
    mech = build(2)
    mech.add_parameter("extra", 1.0)
    res = casmbd.sweep(mech, {"extra": [1.0]}, t_end=0.6, steps=6, mode="vm",
                       out_dir=tmp_path)
    point = res.result(0)
    direct = casmbd.simulate(build(2), 0.6, 6, mode="vm")
    assert np.max(np.abs(_positions(point) - _positions(direct))) <= 1e-12


def test_needs_named_in_messages():
    mech = VARIANTS["contact_impact"][0](2)
    with pytest.raises(CompositionError, match=r"contact 'floor' needs impacts.*instead: "):
        casmbd.inverse_dynamics(mech, 0.1, 2)


def _coordinates(variant, dim):
    """The coordinate choices the canonical scene takes (a refusal of one names it)."""
    build = VARIANTS[variant][0]
    taken = []
    for coords in ("absolute", "natural", "joint"):
        try:
            casmbd.System(build(dim, coordinates=coords))
            taken.append(coords)
        except CasmbdError as exc:
            assert "coordinate" in str(exc), exc
    return taken


LINEAR = [(v, d) for v, d in CELLS if not ANALYSES["linearize"].refusals(VARIANTS[v][0](d))
          and v not in ("contact_impact", "contact_compliant", "prismatic", "cylindrical",
                        "inline", "planar")]  # no equilibrium: falls, slides


@pytest.mark.parametrize("variant,dim", LINEAR)
def test_statics_and_linearize_agree_across_coordinate_choices(variant, dim):
    """Statics' (stable) equilibrium is one for forward dynamics too (linearize's KKT
    accelerations vanish there: another path through the equations), with the same verdict;
    and the natural frequencies about it are the same in every coordinate choice (1e-6
    relative).  A start exactly between two equilibria (a horizontal rod) may reach either
    with the nearest-equilibrium search, so the stable search fixes one pose for the three."""
    build = VARIANTS[variant][0]
    spectra = {}
    for coords in _coordinates(variant, dim):
        mech = build(dim, coordinates=coords)
        eq = casmbd.static_equilibrium(mech, mode="vm", stable=True)  # one pose for all
        closed = [name for name, c in (eq.contacts or {}).items() if c["normal_force"] > 0.0]
        if closed:  # resting on a contact or stop: linearize refuses it by name
            with pytest.raises(CompositionError, match=closed[0]):
                casmbd.linearize(mech, q=eq.q, mode="vm")
            continue
        lin = casmbd.linearize(mech, q=eq.q, mode="vm")
        assert lin.stats["equilibrium"], coords
        if eq.stability is not None and lin.stability is not None:
            assert eq.stability.verdict == lin.stability.verdict
        spectra[coords] = np.sort(np.asarray(lin.natural_frequencies_hz, dtype=float))
    ref = next(iter(spectra.values()), None)
    for coords, freq in spectra.items():
        assert freq.shape == ref.shape, coords
        assert np.allclose(freq, ref, rtol=1e-6, atol=1e-9), (coords, freq, ref)


COMPILED = [(v, d) for v, d in CELLS if not ANALYSES["compile"].refusals(VARIANTS[v][0](d))
            and v not in ("user",)]  # a user force of t: the per-call bias is at t = 0


@pytest.mark.parametrize("variant,dim", COMPILED)
def test_compiled_forward_dynamics_equals_the_simulation_start(variant, dim):
    """The per-call API's forward dynamics at the initial state = the accelerations the
    simulation starts with, in every coordinate choice the scene takes (1e-8)."""
    build = VARIANTS[variant][0]
    for coords in _coordinates(variant, dim):
        mech = build(dim, coordinates=coords)
        sim = casmbd.simulate(mech, 0.01, 1, formulation="index1", mode="vm")
        model = casmbd.compile(build(dim, coordinates=coords), coordinates=coords, mode="vm")
        q0, vmap = sim["q"][0], model.velocity_map  # a free body: free-flyer v (n_v)
        nu = vmap.velocity_from_rates(q0, sim["v"][0])
        acc = vmap.rate_accelerations(q0, nu, model.forward_dynamics(q0, nu, np.zeros(model.nv)))
        scale = max(1.0, float(np.max(np.abs(acc))))
        assert np.max(np.abs(acc - sim["a"][0])) <= 1e-8 * scale, coords


#: each kind once (its plane scene where it has one): the drawing is the kind's, not the
#: dimension's, and a figure costs 0.6 s
DRAWN = [(v, dims[0]) for v, (_, dims, _) in VARIANTS.items()]


@pytest.mark.parametrize("variant,dim", DRAWN)
def test_plot_and_animate_draw_every_element(variant, dim, tmp_path):
    """plot and animate take every element kind: a picture file, and a frame of the
    animation whose drawing holds every body."""
    from casmbd.viz.animation import draw_frame
    from casmbd.viz.plots import plot_result
    build = VARIANTS[variant][0]
    res = casmbd.simulate(build(dim), 0.2, 2, mode="vm")
    plot_result(res, out=tmp_path / "p.png")
    assert (tmp_path / "p.png").stat().st_size > 1000
    fig = draw_frame(res, 1, mechanism=build(dim))
    assert fig is not None


def _stop_pendulum(model: str, stop: bool = True):
    m = casmbd.Mechanism("ocp_stop", gravity=(0.0, -9.81), coordinates="joint")
    m.add_body("link", mass=1.0, inertia=1.0 / 12, position=(0.5, 0.0))
    m.add_revolute("pin", "ground", "link", point=(0.0, 0.0))
    m.add_actuator("motor", "pin")
    if stop:
        kw = {"stiffness": 1e3, "damping": 0.0} if model == "compliant" else {}
        m.add_joint_limit("pin", upper=0.5, model=model, **kw)
    return m


def test_ocp_takes_compliant_stops_and_refuses_impact_stops():
    """Trajectory optimisation handles a compliant stop (a force): the optimal motion ends
    0.03 rad into it, and its controls replayed by ``simulate`` (which includes the stop)
    reach the target (replay error < 1e-3 rad), while the same controls on the pendulum
    without the stop miss it by more than ten times the replay error — the stop force was in
    the optimised dynamics.  The impact model is refused by name, naming the compliant one."""
    from casmbd.ocp import Ocp
    ocp = Ocp(_stop_pendulum("compliant"), horizon=1.0, intervals=20)
    ocp.control_bounds("motor", -20, 20)
    ocp.initial(pin=0.0, pin_dot=0.0).final(pin=0.53, pin_dot=0.0)
    ocp.minimize("effort")
    sol = ocp.solve()
    sol.replay()
    assert sol.stats["replay_error"] < 1e-3
    import casadi as ca
    edges = np.asarray(sol.control_times, dtype=float)[1:-1]
    held = sol.control("motor")
    free = casmbd.simulate(_stop_pendulum("compliant", stop=False), 1.0, 20, rtol=1e-10,
                           inputs={"motor": lambda t: ca.pw_const(t, ca.DM(edges),
                                                                  ca.DM(held))})
    assert abs(free["q"][-1, 0] - 0.53) > 10 * sol.stats["replay_error"]
    with pytest.raises(CompositionError, match=r"joint limit 'pin.limit'.*compliant"):
        Ocp(_stop_pendulum("impact"), horizon=1.0, intervals=20)


# ----------------------------------------------------------------------------- the CLI
CLI_SCENES = {"bouncing_ball": False, "pendulum_stops": False, "crank_friction": True,
              "spinup_beam": True, "slider_crank": True}
CLI_VERBS = {"kinematics": ["--t-end", "0.1", "--steps", "2"],
             "inverse": ["--t-end", "0.1", "--steps", "2"],
             "simulate": ["--t-end", "0.1", "--steps", "2"],
             "statics": [], "linearize": ["--at-equilibrium"]}


@pytest.mark.parametrize("scene", list(CLI_SCENES))
def test_cli_cells(scene, capsys):
    """The same cells through the command line: a refused verb exits 1 with one ``error:``
    line naming the element and the way out; an accepted one prints one JSON object."""
    import json
    from pathlib import Path

    from casmbd.cli import main
    path = str(Path(__file__).resolve().parents[2] / "examples" / f"{scene}.toml")
    mech = casmbd.load_scene(path)
    for verb, args in CLI_VERBS.items():
        refused = ANALYSES[verb].refusals(mech)
        if not refused and verb in ("kinematics", "inverse") and not CLI_SCENES[scene]:
            continue  # an undriven scene: kinematics refuses it for its degrees of freedom
        status = main([verb, path, *args, "--json"])
        out, err = capsys.readouterr()
        if refused:
            assert status == 1, (verb, out, err)
            lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
            assert len(lines) == 1 and "instead:" in lines[0], err
            assert all(r.element in lines[0] for r in refused), lines[0]
        elif verb == "linearize" and "closed at the operating point" in err:
            assert status == 1  # resting on a contact or stop: refused by name at run time
        else:
            assert status == 0, (verb, err)
            json.loads(out)


SENSITIVE = [(v, d) for v, d in CELLS
             if not ANALYSES["sensitivity"].refusals(VARIANTS[v][0](d))]


def _probed(variant, dim, tau):
    """The canonical scene with a parameter torque ``tau`` on its first body."""
    mech = VARIANTS[variant][0](dim)
    mech.add_parameter("tau", tau)
    body = next(iter(mech.bodies))
    mech.add_torque("probe", body, value="tau" if dim == 2 else (0.0, 0.0, "tau"))
    return mech


@pytest.mark.parametrize("variant,dim", SENSITIVE)
def test_sensitivity_equals_finite_differences_of_whole_runs(variant, dim):
    """d q_n(0.6 s)/d tau (q_n the last coordinate) by the sensitivity analysis (across
    impacts: the jump at each) =
    central differences of two whole ``simulate`` runs (h = 1e-4, rtol 1e-11): 1e-5
    relative to max(1, |dq/dtau|)."""
    from casmbd.system.named_quantities import identifier
    mech = _probed(variant, dim, 0.3)
    name = identifier(casmbd.System(mech).coordinate_names[-1])
    res = casmbd.sensitivity(mech, [name], ["tau"], t_end=0.6)
    h = 1e-4
    ends = [casmbd.simulate(_probed(variant, dim, 0.3 + s * h), 0.6, 6, rtol=1e-11,
                            atol=1e-11, mode="vm")["q"][-1, -1] for s in (1, -1)]
    fd = (ends[0] - ends[1]) / (2 * h)
    exact = float(res.jacobian[0, 0])
    assert abs(exact - fd) <= 1e-5 * max(1.0, abs(fd)), (exact, fd)


def test_a_scene_changed_in_python_is_swept_as_changed(tmp_path):
    """A mechanism read from a scene and then changed in Python (a torque added) is swept as
    it is: each point equals ``simulate`` of the changed mechanism (1e-12), not of the text
    read again (the torque was dropped silently before)."""
    from pathlib import Path
    path = Path(__file__).resolve().parents[2] / "examples" / "pendulum_stops.toml"
    mech = casmbd.load_scene(str(path))
    mech.add_torque("push", "rod", value=3.0)
    res = casmbd.sweep(mech, {"m": [1.0]}, t_end=1.0, steps=10, out_dir=tmp_path)
    direct = casmbd.simulate(mech, 1.0, 10)
    assert np.max(np.abs(res.result(0)["q"] - direct["q"])) <= 1e-12
    assert abs(direct["q"][-1, 0] - res.result(0)["q"][-1, 0]) <= 1e-12


OCP_CELLS = [(v, d) for v, d in CELLS if v != "flexible"  # its mesh: tests/ocp/test_ocp_flexible.py
             and "pin" in VARIANTS[v][0](d).joints
             and not ANALYSES["ocp"].refusals(VARIANTS[v][0](d))]


@pytest.mark.parametrize("variant,dim", OCP_CELLS)
def test_ocp_replays_through_simulate(variant, dim):
    """Trajectory optimisation on every element kind it handles (a motor at the pin, least
    effort to stop the swing at 0.5 s): its optimal controls replayed by ``simulate`` give the
    same motion (replay error < 1e-3 rad; the transcription's dynamics are the simulator's)."""
    from casmbd.ocp import Ocp
    mech = VARIANTS[variant][0](dim)
    if "motor" not in mech.actuators:
        mech.add_actuator("motor", "pin")
    ocp = Ocp(mech, horizon=0.5, intervals=10, compile=False)
    ocp.control_bounds("motor", -50, 50)
    if not mech.drivers:  # a driven pendulum has no motion left to choose
        ocp.final(pin_dot=0.0)
    ocp.minimize("effort")
    sol = ocp.solve()
    sol.replay()
    assert sol.stats["replay_error"] < 1e-3
