"""Symbolic equations of motion against finite differences, hand formulas and each other.

Every mechanism here is in absolute coordinates (set explicitly: the hand formulas, the numpy
virtual work and the user generalized force of 9 weights are written for them; joint
coordinates are checked in tests/system/test_joint_coordinates.py).

Tolerances (all stated per test):

* C_q, C_t, γ, Q_v (Lagrange) and Q_e = −∂V/∂q against central finite differences with
  h = 1e-6: 1e-6 relative to the largest entry (absolute floor 1e-8);
* Q_e of every force element against an independent numpy virtual-work implementation: 1e-12;
* mass matrix and Q_v of non-centroidal bodies against the hand formulas: 1e-14 relative;
* compiled C code against the CasADi virtual machine: 1e-12 relative;
* gravity and kinetic energy of a free body against hand formulas: 1e-14 relative.
"""

from __future__ import annotations

import json
import math
import os
import pathlib
import subprocess
import sys

import casadi as ca
import numpy as np
import pytest
from conftest import private_cache

from casmbd import Mechanism, NumericModel, System, load_scene
from casmbd.compiled import codegen
from casmbd.system.equations import SIGNATURES
from tests.symbolic_checks import Evaluator, H, assert_rel, fd_gradient

REPO = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"
N_STATES = 5

needs_compiler = pytest.mark.skipif(codegen.find_compiler() is None,
                                    reason="no C compiler available")


_cache = private_cache("casmbd_cache_equations", scope="module")


def rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def drot(theta: float) -> np.ndarray:
    """A_θ = dA/dθ."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[-s, -c], [c, -s]])


# ---------------------------------------------------------------------------- mechanisms
FB_POINTS = {"A": (0.0, 0.0), "B": (0.0, 0.2), "C": (0.6437, 0.4750), "D": (0.8, 0.0)}
SPRING = {"p1": (0.4, 0.7), "p2": (0.32, 0.34), "k": 120.0, "c": 3.5, "l0": 0.2,
          "act": lambda t: 0.5 * math.sin(3 * t)}
ROT_SPRING = {"k": 2.0, "c": 0.3, "phi0": 0.4, "act": lambda t: 0.1 * t}
BODY_FORCE_POINT = (0.7, 0.3)
USER_POINT = (0.5, 0.4)
USER_WEIGHTS = np.linspace(0.01, 0.09, 9)


def _user_point_force(ctx):
    """Viscous force at a coupler point and a torque proportional to the coupler angle."""
    return -0.8 * ctx.velocity("coupler", USER_POINT), 0.05 * ctx.angle("coupler")


def _user_generalized(ctx):
    """A generalized force vector: linear drag on every coordinate plus a time ramp."""
    return -0.1 * ctx.v + ctx.t * ca.DM(USER_WEIGHTS)


def forced_four_bar(conservative: bool = False) -> Mechanism:
    """The example four-bar (undriven) with every kind of force element.

    ``conservative`` keeps only gravity and the two springs (no damping, no actuator terms), for
    which Q_e(q, v) = −∂V/∂q.
    """
    name = "fb_conservative" if conservative else "fb_forced"
    m = Mechanism(name, gravity=(0.0, -9.81), coordinates="absolute")
    m.add_parameter("k_s", SPRING["k"])
    m.add_body("crank", 0.4, 0.4 * 0.2**2 / 12, position=(0.0, 0.1), angle=math.pi / 2)
    m.add_body("coupler", 1.4, 1.4 * 0.7**2 / 12, position=(0.32, 0.34), angle=0.4037)
    m.add_body("rocker", 1.0, 1.0 * 0.5**2 / 12, position=(0.72, 0.24), angle=1.8886)
    m.add_revolute("A", "ground", "crank", FB_POINTS["A"])
    m.add_revolute("B", "crank", "coupler", FB_POINTS["B"])
    m.add_revolute("C", "coupler", "rocker", FB_POINTS["C"])
    m.add_revolute("D", "ground", "rocker", FB_POINTS["D"])
    m.add_spring_damper("spring", "ground", "coupler", SPRING["p1"], SPRING["p2"],
                        stiffness="k_s", damping=0.0 if conservative else SPRING["c"],
                        free_length=SPRING["l0"],
                        actuator=0.0 if conservative else "0.5 * sin(3 * t)")
    m.add_rotational_spring_damper("hinge", "C", stiffness=ROT_SPRING["k"],
                                   damping=0.0 if conservative else ROT_SPRING["c"],
                                   free_angle=ROT_SPRING["phi0"],
                                   actuator=0.0 if conservative else (lambda t: 0.1 * t))
    if not conservative:
        m.add_force("push", "rocker", ("2 * cos(t)", 1.5), point=BODY_FORCE_POINT, frame="body")
        m.add_torque("motor_torque", "crank", "0.3 + 0.1 * t")
        m.add_user_force("drag", _user_point_force, body="coupler", point=USER_POINT)
        m.add_user_force("generalized", _user_generalized)
        m.add_actuator("motor", "A")
    return m


OFFSET_BODIES = {  # name: mass, inertia, centre of mass, angle, reference point s
    "arm": (2.0, 0.15, (0.3, 0.2), 0.4, (0.12, -0.05)),
    "block": (1.0, 0.02, (0.9, 0.1), -0.2, (-0.07, 0.03)),
    "tab": (0.3, 0.004, (1.0, 0.2), 0.1, (0.02, 0.04)),
}


def offset_mechanism(conservative: bool = False) -> Mechanism:
    """Non-centroidal bodies with a revolute, a distance and a rigid joint, a body-coordinate
    driver with a time expression, springs and gravity."""
    m = Mechanism("offset_conservative" if conservative else "offset", gravity=(0.7, -9.81),
                  coordinates="absolute")
    for name, (mass, inertia, pos, ang, s) in OFFSET_BODIES.items():
        m.add_body(name, mass, inertia, position=pos, angle=ang, reference_point=s)
    m.add_revolute("pivot", "ground", "arm", (0.0, 0.0))
    m.add_distance("link", "arm", "block", (0.55, 0.3), (0.85, 0.15))
    m.add_rigid("weld", "block", "tab")
    m.add_driver("lift", "0.13 + 0.05 * sin(3 * t) + 0.01 * t**2", body="block",
                 coordinate="y")
    m.add_spring_damper("spring", "arm", "tab", (0.4, 0.25), (1.05, 0.25), stiffness=40.0,
                        damping=0.0 if conservative else 1.5, free_length=0.5)
    m.add_rotational_spring_damper("coil", "pivot", stiffness=3.0, free_angle=0.2,
                                   damping=0.0 if conservative else 0.4)
    return m


def slider_crank() -> Mechanism:
    mech = load_scene(EXAMPLES / "slider_crank.toml")
    mech.coordinates = "absolute"
    return mech


BUILDERS = {"slider_crank": slider_crank, "forced_four_bar": forced_four_bar,
            "offset": offset_mechanism}


# ---------------------------------------------------------------------------- helpers
def random_states(system: System, seed: int, n: int = N_STATES):
    """(q, v, t, u) with q near the initial pose, v and u of order 1, t in [0, 2]."""
    rng = np.random.default_rng(seed)
    q0 = system.initial_coordinates()
    for _ in range(n):
        yield (q0 + rng.uniform(-0.3, 0.3, q0.size), rng.uniform(-2.0, 2.0, q0.size),
               float(rng.uniform(0.0, 2.0)), rng.uniform(-1.0, 1.0, system.u.numel()))


@pytest.fixture(scope="module", params=list(BUILDERS))
def evaluator(request):
    return Evaluator(System(BUILDERS[request.param]()))


# ---------------------------------------------------------------------------- FD checks
def test_constraint_jacobian_matches_finite_differences(evaluator):
    """C_q vs central differences of C in q (h = 1e-6): 1e-6 relative."""
    for q, _, t, _ in random_states(evaluator.system, seed=1):
        fd = fd_gradient(lambda x, t=t: evaluator.c(x, t), q)
        assert_rel(evaluator.cq(q, t), fd, 1e-6, what="C_q")


def test_constraint_time_derivative_matches_finite_differences(evaluator):
    """C_t vs central differences of C in t: 1e-6 relative."""
    for q, _, t, _ in random_states(evaluator.system, seed=2):
        fd = (evaluator.c(q, t + H) - evaluator.c(q, t - H)) / (2 * H)
        assert_rel(evaluator.ct(q, t), fd, 1e-6, what="C_t")
    if evaluator.system.mechanism.drivers:  # rheonomic: C_t is not trivially zero
        assert np.any(evaluator.ct(q, t) != 0.0)


def test_acceleration_rhs_matches_finite_differences(evaluator):
    """γ = −d/dt (C_q v + C_t) along (q + h v, t + h) with v frozen: 1e-6 relative."""
    for q, v, t, _ in random_states(evaluator.system, seed=3):
        def cdot(s, q=q, v=v, t=t):
            qs, ts = q + s * v, t + s
            return evaluator.cq(qs, ts) @ v + evaluator.ct(qs, ts)

        fd = -(cdot(H) - cdot(-H)) / (2 * H)
        assert_rel(evaluator.gamma(q, v, t), fd, 1e-6, what="gamma")


def test_quadratic_velocity_forces_match_lagrange(evaluator):
    """Q_v = ∂T/∂q − Ṁ v with ∂T/∂q and Ṁ v = d/ds M(q + s v) v by central differences."""
    nonzero = False
    for q, v, _, _ in random_states(evaluator.system, seed=4):
        dT_dq = fd_gradient(lambda x, v=v: evaluator.kinetic(x, v), q).ravel()
        mdot_v = (evaluator.mass(q + H * v) - evaluator.mass(q - H * v)) @ v / (2 * H)
        qv = evaluator.qv(q, v)
        # relative to the size of the terms that cancel, not of their (possibly zero) sum
        scale = max(np.abs(dT_dq).max(), np.abs(mdot_v).max(), 1e-2)
        assert np.max(np.abs(qv - (dT_dq - mdot_v))) <= 1e-6 * scale
        nonzero |= bool(np.any(qv != 0.0))
    centroidal = all(b.is_centroidal for b in evaluator.system.mechanism.bodies.values())
    assert nonzero != centroidal  # Q_v vanishes exactly for centroidal frames only


@pytest.mark.parametrize("builder", [forced_four_bar, offset_mechanism])
def test_conservative_forces_are_minus_potential_gradient(builder):
    """Gravity and springs: Q_e(q, v = 0, t) = −∂V/∂q by central differences, 1e-6 relative."""
    ev = Evaluator(System(builder(conservative=True)))
    zero_v = np.zeros(ev.system.nq)
    for q, v, t, u in random_states(ev.system, seed=5):
        grad_v = fd_gradient(lambda x, t=t: ev.potential(x, t), q).ravel()
        assert_rel(ev.qe(q, zero_v, t, u), -grad_v, 1e-6, what="Q_e vs -dV/dq")
        # with damping = 0 the conservative mechanism's forces do not depend on v either
        assert_rel(ev.qe(q, v, t, u), -grad_v, 1e-6, what="Q_e(v) vs -dV/dq")


# ---------------------------------------------------------------------------- virtual work
def _point(mech, q, body, point_global):
    """Independent numpy position and Jacobian of a body point given at the initial pose:
    r_P = R − A(θ) s + A(θ) u,  ∂r_P/∂R = I,  ∂r_P/∂θ = A_θ (u − s)."""
    nq = q.size
    if body == "ground":
        return np.asarray(point_global, float), np.zeros((2, nq))
    i = 3 * list(mech.bodies).index(body)
    b = mech.bodies[body]
    u = rot(b.angle).T @ (np.asarray(point_global, float) - b.position)
    th = q[i + 2]
    jac = np.zeros((2, nq))
    jac[:, i:i + 2] = np.eye(2)
    jac[:, i + 2] = drot(th) @ (u - b.reference_point)
    return q[i:i + 2] + rot(th) @ (u - b.reference_point), jac


def _angle_gradient(mech, body, nq):
    e = np.zeros(nq)
    e[3 * list(mech.bodies).index(body) + 2] = 1.0
    return e


def forced_four_bar_forces(mech, q, v, t, u):
    """Q_e of :func:`forced_four_bar` written independently with numpy (virtual work)."""
    nq = q.size
    total = np.zeros(nq)
    g = mech.gravity
    for name, body in mech.bodies.items():
        _, jac = _point(mech, q, name, body.position)
        total += jac.T @ (float(body.mass) * g)
    # translational spring-damper-actuator: f = k (l − l0) + c l̇ + a(t), Q = −f ∇l
    p1, j1 = _point(mech, q, "ground", SPRING["p1"])
    p2, j2 = _point(mech, q, "coupler", SPRING["p2"])
    d = p2 - p1
    length = np.linalg.norm(d)
    grad_l = (j2 - j1).T @ (d / length)
    f = SPRING["k"] * (length - SPRING["l0"]) + SPRING["c"] * grad_l @ v + SPRING["act"](t)
    total -= f * grad_l
    # rotational spring at C: φ = θ_rocker − θ_coupler
    grad_phi = _angle_gradient(mech, "rocker", nq) - _angle_gradient(mech, "coupler", nq)
    phi = grad_phi @ q
    moment = (ROT_SPRING["k"] * (phi - ROT_SPRING["phi0"]) + ROT_SPRING["c"] * grad_phi @ v
              + ROT_SPRING["act"](t))
    total -= moment * grad_phi
    # body-frame force on the rocker
    _, jp = _point(mech, q, "rocker", BODY_FORCE_POINT)
    th_r = q[3 * list(mech.bodies).index("rocker") + 2]
    total += jp.T @ (rot(th_r) @ np.array([2 * math.cos(t), 1.5]))
    # torque on the crank
    total += (0.3 + 0.1 * t) * _angle_gradient(mech, "crank", nq)
    # user point force + torque on the coupler
    _, ju = _point(mech, q, "coupler", USER_POINT)
    th_c = q[3 * list(mech.bodies).index("coupler") + 2]
    total += ju.T @ (-0.8 * (ju @ v)) + 0.05 * th_c * _angle_gradient(mech, "coupler", nq)
    # user generalized force
    total += -0.1 * v + t * USER_WEIGHTS
    # actuator on joint A: generalized force u along θ_crank − 0
    total += u[0] * _angle_gradient(mech, "crank", nq)
    return total


def test_applied_forces_match_independent_virtual_work():
    """Q_e of gravity, spring-damper-actuator, rotational spring, body-frame force, torque,
    user forces and an actuator vs a numpy implementation: 1e-12 relative."""
    mech = forced_four_bar()
    ev = Evaluator(System(mech))
    for q, v, t, u in random_states(ev.system, seed=6):
        assert_rel(ev.qe(q, v, t, u), forced_four_bar_forces(mech, q, v, t, u), 1e-12,
                   what="Q_e")


# ---------------------------------------------------------------------------- hand formulas
def test_mass_matrix_of_non_centroidal_bodies():
    """M_i = [[m I, −m A_θ s], [−m (A_θ s)ᵀ, I_G + m sᵀ s]] (eqs. 6.22–6.23), 1e-14 relative;
    blocks of different bodies are zero."""
    mech = offset_mechanism()
    ev = Evaluator(System(mech))
    for q, _, _, _ in random_states(ev.system, seed=7):
        expected = np.zeros((ev.system.nq, ev.system.nq))
        for k, (mass, inertia, _, _, s) in enumerate(OFFSET_BODIES.values()):
            s = np.asarray(s)
            a_s = drot(q[3 * k + 2]) @ s
            block = np.zeros((3, 3))
            block[:2, :2] = mass * np.eye(2)
            block[:2, 2] = block[2, :2] = -mass * a_s
            block[2, 2] = inertia + mass * s @ s
            expected[3 * k:3 * k + 3, 3 * k:3 * k + 3] = block
        assert_rel(ev.mass(q), expected, 1e-14, what="M")


def test_quadratic_velocity_forces_of_non_centroidal_bodies():
    """r_G = R − A s gives r̈_G = R̈ − A_θ s θ̈ + A s θ̇², so Q_v = −m J_Gᵀ (A s θ̇²)
    = −m θ̇² [A s; 0] (the rotational entry is −m θ̇² (A_θ s)ᵀ(A s)… = 0): 1e-14 relative."""
    mech = offset_mechanism()
    ev = Evaluator(System(mech))
    for q, v, _, _ in random_states(ev.system, seed=8):
        expected = np.zeros(ev.system.nq)
        for k, (mass, _, _, _, s) in enumerate(OFFSET_BODIES.values()):
            th, om = q[3 * k + 2], v[3 * k + 2]
            expected[3 * k:3 * k + 2] = -mass * om**2 * (rot(th) @ np.asarray(s))
        assert_rel(ev.qv(q, v), expected, 1e-14, what="Q_v")


def free_body(reference_point=(0.0, 0.0), name="free") -> Mechanism:
    m = Mechanism(name, gravity=(0.7, -9.81), coordinates="absolute")
    m.add_body("b", mass=2.5, inertia=0.3, position=(0.2, -0.4), angle=0.3,
               reference_point=reference_point)
    return m


def test_gravity_on_free_bodies():
    """Centroidal: Q_e = [m g; 0] exactly (1e-15).  Offset s: Q_e = [m g; −m gᵀ A_θ s]
    (the moment of the weight about R) and V = −m gᵀ (R − A s), 1e-14 relative."""
    rng = np.random.default_rng(9)
    g = np.array([0.7, -9.81])
    s = np.array([0.15, -0.08])
    centroidal = Evaluator(System(free_body()))
    offset = Evaluator(System(free_body(s, "free_offset")))
    for _ in range(N_STATES):
        q, v, t = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3), float(rng.uniform(0, 2))
        u = np.zeros(0)
        assert_rel(centroidal.qe(q, v, t, u), np.array([2.5 * g[0], 2.5 * g[1], 0.0]), 1e-15)
        expected = np.concatenate([2.5 * g, [-2.5 * g @ (drot(q[2]) @ s)]])
        assert_rel(offset.qe(q, v, t, u), expected, 1e-14, what="Q_e offset")
        r_g = q[:2] - rot(q[2]) @ s
        assert offset.potential(q, t) == pytest.approx(-2.5 * g @ r_g, rel=1e-14, abs=1e-14)


def test_kinetic_energy_of_rotating_non_centroidal_body():
    """T = ½ m |v_G|² + ½ I ω² with v_G = Ṙ − A_θ s ω (1e-14 relative)."""
    rng = np.random.default_rng(10)
    s = np.array([0.15, -0.08])
    ev = Evaluator(System(free_body(s, "free_ke")))
    for _ in range(N_STATES):
        q, v = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        v_g = v[:2] - drot(q[2]) @ s * v[2]
        expected = 0.5 * 2.5 * v_g @ v_g + 0.5 * 0.3 * v[2] ** 2
        assert ev.kinetic(q, v) == pytest.approx(expected, rel=1e-14)
    # a body spinning about its centre of mass (R moves on a circle) has T = ½ I ω² only
    th, om = 0.8, 3.0
    q = np.concatenate([rot(th) @ s, [th]])  # r_G = 0
    v = np.concatenate([om * drot(th) @ s, [om]])  # Ṙ = d/dt (A s)
    assert ev.kinetic(q, v) == pytest.approx(0.5 * 0.3 * om**2, rel=1e-14)


# ---------------------------------------------------------------------------- compiled code
ALL_FUNCTIONS = [*SIGNATURES, "outputs"]


@needs_compiler
@pytest.mark.parametrize("builder", [forced_four_bar, offset_mechanism])
def test_compiled_and_vm_agree(builder):
    """Every Function, compiled to C vs the CasADi virtual machine: 1e-12 relative."""
    system = System(builder())
    compiled = NumericModel(system, ALL_FUNCTIONS, mode="compiled")
    vm = NumericModel(system, ALL_FUNCTIONS, mode="vm")
    assert compiled.report.mode == "compiled" and vm.report.mode == "vm"
    assert set(compiled.functions) == set(vm.functions) == set(ALL_FUNCTIONS)
    rng = np.random.default_rng(12)
    p = system.parameter_values * (1 + 0.1 * rng.uniform(-1, 1, system.p.numel()))
    for q, v, t, u in random_states(system, seed=13):
        a = rng.uniform(-3, 3, system.nq)
        args = {"q": q, "v": v, "t": t, "u": u, "p": p, "a": a}
        for name in ALL_FUNCTIONS:
            fc, fv = compiled.function(name), vm.function(name)
            assert fc.name_in() == fv.name_in()
            inputs = [args[n] for n in fv.name_in()]
            out_c, out_v = fc.call(inputs), fv.call(inputs)
            assert len(out_c) == len(out_v) == fv.n_out()
            for k, (xc, xv) in enumerate(zip(out_c, out_v, strict=True)):
                assert xc.sparsity() == xv.sparsity(), (name, k)
                assert_rel(xc.full(), xv.full(), 1e-12, floor=1.0, what=f"{name}[{k}]")


@needs_compiler
def test_compiled_library_is_reused_by_another_process(tmp_path, monkeypatch):
    """A second Python process with the same CASMBD_CACHE_DIR loads the library from the cache:
    report.compiled is False and report.cache_hit is True (assertions on the report only)."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("CASMBD_CACHE_DIR", str(cache))
    monkeypatch.delenv("CASMBD_COMPILE", raising=False)
    scene = EXAMPLES / "four_bar.toml"
    first = NumericModel(load_scene(scene), "kinematics", mode="compiled")
    assert first.report.compiled is True and first.report.cache_hit is False
    script = (
        "import json, sys\n"
        f"sys.path.insert(0, {str(REPO)!r})\n"
        "from casmbd import NumericModel, load_scene\n"
        f"m = NumericModel(load_scene({str(scene)!r}), 'kinematics', mode='compiled')\n"
        "r = m.report\n"
        "print(json.dumps({'compiled': r.compiled, 'cache_hit': r.cache_hit, 'mode': r.mode,\n"
        "                  'library': r.library, 'key': r.key}))\n"
    )
    env = dict(os.environ, CASMBD_CACHE_DIR=str(cache))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, cwd=str(tmp_path), timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["compiled"] is False
    assert report["cache_hit"] is True
    assert report["mode"] == "compiled"
    assert report["library"] == first.report.library
    assert report["key"] == first.report.key
