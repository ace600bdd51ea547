"""The Delta robot of Clavel (seed 003, §5.2) as a 3-RUU mechanism of rigid bodies.

Model
-----
Base = ground.  Three upper arms turn about horizontal revolute axes tangent to a circle of
radius ``a`` (azimuths 0°, 120°, 240°); each forearm joins its arm at the elbow and the hand
(a small platform of radius ``b``) by universal joints.  The real robot keeps the hand's
orientation with a parallelogram per forearm; here each forearm is one rod with

* at the elbow, a universal joint: axis 1 on the arm parallel to the arm's revolute axis t_i,
  axis 2 on the forearm n_i = t_i × d_i / |t_i × d_i| (d_i the forearm direction), and
* at the hand, a universal joint with the same axes: axis 1 = n_i on the forearm, axis 2 = t_i
  on the hand.

The leg's joint axes are then t, t, n, n, t (the classical translational 3-RUU, a "Tsai"
leg): each leg transmits one constraint couple along t_i × n_i (the forearm direction projected
on the arm's plane of motion), and three independent couples leave the hand three
translations and no rotation — exactly the Delta's kinematics, without the parallelograms'
static indeterminacy (seed 003: four times statically indeterminate).  7 bodies × 7 Euler
coordinates = 49 coordinates, 7 + 3·(5 + 4 + 4) = 46 constraints, 3 DOF.

Analyses
--------
* Inverse kinematics in closed form (the elbow is on a circle, the forearm length gives a
  quadratic in tan(θ/2)); it builds a consistent initial pose for any hand position and is
  checked against :func:`casmbd.kinematics` with drivers on the hand x, y, z.
* A gate-shaped pick-and-place path (up, across, down; overlapping phases, each a polynomial
  time law with zero rate, acceleration, jerk, … at its ends) prescribed by the hand drivers;
  actuators on the three base revolute joints; :func:`casmbd.inverse_dynamics` gives the drive
  moments (the mixed case).
* Round trip: the hand drivers removed, the drive moments splined (C² cubic B-splines,
  :class:`casmbd.model.values.Samples`) as actuator inputs, forward simulation from the same
  initial state: the hand follows the path.
* Statics: the drive moments at rest equal the closed-form gravity balance by virtual work;
  in motion they equal Lagrange's equations written in the hand coordinates
  (:func:`lagrange_drive_moments`, independent of casmbd's equations).

Run: ``python examples/delta_robot.py`` (prints the checks and writes
``docs/figures/delta_robot.png``).
"""

from __future__ import annotations

import math
import pathlib
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

import casmbd
from casmbd.errors import AnalysisError
from casmbd.model.rotations import quaternion_from_matrix
from casmbd.model.values import Samples

G = 9.81
ARMS = ("1", "2", "3")


@dataclass(frozen=True)
class Geometry:
    """Dimensions [m] and masses [kg] of the robot (light carbon rods, small hand)."""

    a: float = 0.20             # distance of the arm axes from the centre
    b: float = 0.05             # distance of the hand's universal joints from the hand centre
    upper: float = 0.30         # upper arm (base axis to elbow)
    fore: float = 0.80          # forearm (elbow to hand joint)
    m_hand: float = 0.30
    m_upper: float = 0.20
    m_fore: float = 0.10
    rod_radius: float = 0.01    # for the rods' axial moment of inertia


GEOMETRY = Geometry()
AZIMUTHS = np.radians([0.0, 120.0, 240.0])

# pick-and-place: from START up by LIFT, across to GOAL, down; T_MOVE seconds
START = np.array([-0.15, -0.05, -0.75])
GOAL = np.array([0.15, 0.05, -0.75])
LIFT = 0.06
T_MOVE = 0.6
#: phases as fractions of T_MOVE: up, across, down (overlapping: rounded corners)
PHASES = ((0.0, 0.4), (0.2, 0.8), (0.6, 1.0))
#: the time law's order: zero derivatives up to ORDER at both ends (degree 2·ORDER + 1)
ORDER = 3


# ----------------------------------------------------------------------------- geometry
def arm_frames(i: int, geom: Geometry = GEOMETRY):
    """Radial unit vector e_i, axis t_i (tangential, horizontal) and base point B_i = a e_i."""
    phi = AZIMUTHS[i]
    e = np.array([math.cos(phi), math.sin(phi), 0.0])
    t = np.array([-math.sin(phi), math.cos(phi), 0.0])
    return e, t, geom.a * e


def elbow(i: int, theta: float, geom: Geometry = GEOMETRY) -> np.ndarray:
    """Elbow point E_i = B_i + L1 (cos θ e_i − sin θ z): θ is the arm's angle below the
    horizontal, a positive rotation about t_i."""
    e, _, base = arm_frames(i, geom)
    return base + geom.upper * (math.cos(theta) * e - math.sin(theta) * np.array([0, 0, 1.0]))


def inverse_kinematics(position, geom: Geometry = GEOMETRY) -> np.ndarray:
    """Arm angles θ_1..3 [rad, below the horizontal] for a hand centre ``position``.

    With Q = P + (b − a) e_i (hand joint H_i relative to the arm axis B_i), q_r = Q·e_i,
    q_z = Q·z, the forearm length |H_i − E_i| = L2 reads

        q_r cos θ − q_z sin θ = K,   K = (|Q|² + L1² − L2²) / (2 L1),

    and with u = tan(θ/2) the quadratic (K + q_r) u² + 2 q_z u + (K − q_r) = 0.  The root
    u = (K − q_r) / (√D − q_z), D = q_r² + q_z² − K², is the elbow-out branch (the arm near the
    horizontal, the elbow outside the forearm's foot), written without cancellation.

    Raises
    ------
    AnalysisError
        When the position is out of reach of an arm (D < 0), naming the arm.
    """
    p = np.asarray(position, float)
    out = np.zeros(3)
    for i in range(3):
        e, _, _ = arm_frames(i, geom)
        q = p + (geom.b - geom.a) * e
        q_r, q_z = float(q @ e), float(q[2])
        k = (q @ q + geom.upper**2 - geom.fore**2) / (2 * geom.upper)
        disc = q_r**2 + q_z**2 - k**2
        if disc < 0.0:
            raise AnalysisError(f"Delta inverse kinematics: hand position {p.tolist()} is out "
                                f"of reach of arm {ARMS[i]} (discriminant {disc:.3g})")
        out[i] = 2.0 * math.atan((k - q_r) / (math.sqrt(disc) - q_z))
    return out


def _frame(x_axis: np.ndarray, y_axis: np.ndarray) -> np.ndarray:
    """Quaternion of the body frame with the given (orthonormal) x and y axes."""
    return quaternion_from_matrix(np.column_stack([x_axis, y_axis, np.cross(x_axis, y_axis)]))


def _rod(mass: float, length: float, radius: float) -> list[float]:
    """Principal inertia of a slender rod along its body x axis."""
    transverse = mass * length**2 / 12 + mass * radius**2 / 4
    return [mass * radius**2 / 2, transverse, transverse]


# ----------------------------------------------------------------------------- the model
def _component(path, k: int):
    """t ↦ path(t)[k] as a one-argument callable (a driver's value)."""
    def value(t):
        return path(t)[k]
    return value


def delta_robot(position=START, geom: Geometry = GEOMETRY, path=None,
                actuators: bool = True, name: str = "delta_robot") -> casmbd.Mechanism:
    """The 3-RUU Delta robot assembled with its hand centre at ``position`` (at rest).

    Bodies ``hand``, ``upper1..3``, ``fore1..3``; joints ``shoulder1..3`` (revolute, ground →
    upper arm, coordinate = arm angle θ_i − θ_i(0)), ``elbow1..3`` and ``wrist1..3``
    (universal).  ``path``: a callable t ↦ (x, y, z) of CasADi expressions; it adds the hand
    drivers ``hand_x``, ``hand_y``, ``hand_z``.  ``actuators`` adds ``motor1..3`` on the
    shoulders (drive moments about t_i, positive lowering the arm).
    """
    p = np.asarray(position, float)
    theta = inverse_kinematics(p, geom)
    # absolute coordinates (Euler parameters), as the module docstring and docs/delta_robot.md
    # count them; the automatic choice would take joint coordinates (11, 8 loop equations)
    m = casmbd.Mechanism(name, gravity=(0.0, 0.0, -G), coordinates="absolute")
    r_hand = geom.b
    m.add_body("hand", geom.m_hand, [geom.m_hand * r_hand**2 / 4, geom.m_hand * r_hand**2 / 4,
                                     geom.m_hand * r_hand**2 / 2], p)
    for i, arm in enumerate(ARMS):
        e, t, base = arm_frames(i, geom)
        knee = elbow(i, theta[i], geom)
        foot = p + geom.b * e
        up_dir = (knee - base) / geom.upper
        fore_dir = (foot - knee) / np.linalg.norm(foot - knee)
        n = np.cross(t, fore_dir)
        n /= np.linalg.norm(n)
        m.add_body(f"upper{arm}", geom.m_upper, _rod(geom.m_upper, geom.upper, geom.rod_radius),
                   (base + knee) / 2, orientation=_frame(up_dir, t))
        m.add_body(f"fore{arm}", geom.m_fore, _rod(geom.m_fore, geom.fore, geom.rod_radius),
                   (knee + foot) / 2, orientation=_frame(fore_dir, n))
        m.add_revolute(f"shoulder{arm}", "ground", f"upper{arm}", base, t)
        m.add_universal(f"elbow{arm}", f"upper{arm}", f"fore{arm}", knee, t, n)
        m.add_universal(f"wrist{arm}", f"fore{arm}", "hand", foot, n, t)
        if actuators:
            m.add_actuator(f"motor{arm}", f"shoulder{arm}")
    if path is not None:
        for k, axis in enumerate("xyz"):
            m.add_driver(f"hand_{axis}", _component(path, k), body="hand", coordinate=axis)
    return m


# ----------------------------------------------------------------------------- the path
def _clip01(s):
    if isinstance(s, (ca.SX, ca.MX, ca.DM)):
        return ca.fmin(ca.fmax(s, 0.0), 1.0)
    return np.clip(s, 0.0, 1.0)


def time_law(s, order: int = ORDER):
    """Smooth step 0 → 1 on s ∈ [0, 1] with zero derivatives 1..``order`` at both ends.

    The polynomial of degree 2k + 1 (k = ``order``): s^(k+1) Σ_j C(k+j, j) (1 − s)^j (k = 2:
    the quintic 10 s³ − 15 s⁴ + 6 s⁵, k = 3: the 7th-order law 35 s⁴ − 84 s⁵ + 70 s⁶ − 20 s⁷).
    """
    s = _clip01(s)
    return s ** (order + 1) * sum(math.comb(order + j, j) * (1 - s) ** j
                                  for j in range(order + 1))


def gate_path(t, t_move: float = T_MOVE, start=START, goal=GOAL, lift: float = LIFT,
              order: int = ORDER):
    """Hand centre (x, y, z) at time t: up by ``lift``, across, down, phases overlapping.

    Works on floats, numpy arrays and CasADi expressions (for the drivers).
    """
    (u0, u1), (a0, a1), (d0, d1) = ((t_move * lo, t_move * hi) for lo, hi in PHASES)
    up = time_law((t - u0) / (u1 - u0), order)
    across = time_law((t - a0) / (a1 - a0), order)
    down = time_law((t - d0) / (d1 - d0), order)
    x = start[0] + (goal[0] - start[0]) * across
    y = start[1] + (goal[1] - start[1]) * across
    z = start[2] + (goal[2] - start[2]) * across + lift * (up - down)
    return x, y, z


def path_samples(times: np.ndarray, **kw) -> np.ndarray:
    """The gate path on a time grid, (n_t, 3)."""
    return np.column_stack([np.broadcast_to(np.asarray(c, float), times.shape)
                            for c in gate_path(times, **kw)])


# ----------------------------------------------------------------------------- analyses
def hand_index(result) -> slice:
    """Columns of the hand's centre in ``body_positions`` (spatial: 3 per body)."""
    i = result.names["bodies"].index("hand")
    return slice(3 * i, 3 * i + 3)


def arm_angles(result, position=START, geom: Geometry = GEOMETRY) -> np.ndarray:
    """Absolute arm angles θ (n_t, 3): shoulder coordinates plus the initial angles."""
    cols = [result.names["joints"].index(f"shoulder{arm}") for arm in ARMS]
    return result["joint_positions"][:, cols] + inverse_kinematics(position, geom)


def ik_check(steps: int = 60, t_move: float = T_MOVE, order: int = ORDER) -> dict:
    """Arm angles from :func:`casmbd.kinematics` (hand drivers) against the closed form."""
    path = lambda t: gate_path(t, t_move, order=order)  # noqa: E731
    kin = casmbd.kinematics(delta_robot(path=path, actuators=False,
                                        name="delta_robot_kinematics"), t_move, steps)
    theta_kin = arm_angles(kin)
    theta_ik = np.array([inverse_kinematics(p) for p in path_samples(kin.t, t_move=t_move,
                                                                          order=order)])
    rot = kin["rotation_matrices"][:, 9 * kin.names["bodies"].index("hand"):][:, :9]
    return {"result": kin, "theta_kinematics": theta_kin, "theta_closed_form": theta_ik,
            "max_angle_error": float(np.max(np.abs(theta_kin - theta_ik))),
            "max_hand_rotation": float(np.max(np.abs(rot - np.eye(3).ravel())))}


def inverse(steps: int, t_move: float = T_MOVE, order: int = ORDER, mode: str = "auto"):
    """Drive moments along the gate path (inverse dynamics, mixed case): hand drivers x, y, z,
    actuators ``motor1..3`` on the shoulders; ``actuator_efforts`` holds the moments."""
    path = lambda t: gate_path(t, t_move, order=order)  # noqa: E731
    return casmbd.inverse_dynamics(delta_robot(path=path), t_move, steps, mode=mode)


def round_trip(steps: int = 1200, rtol: float = 1e-12, t_move: float = T_MOVE,
               order: int = ORDER, formulation: str | None = None,
               integrator: str | None = None, mode: str = "vm", inv=None) -> dict:
    """Inverse dynamics on ``steps`` intervals, then forward dynamics driven by the splined
    drive moments from the same initial state; the hand's largest position error [m].

    The moments are sampled on the inverse-dynamics grid and interpolated by C² cubic
    B-splines (:class:`~casmbd.model.values.Samples`); the error falls like h⁴–h⁵ with the
    sampling interval h until the integrator's tolerance ``rtol`` (= ``atol``) limits it.
    Every new set of samples is new code: the CasADi virtual machine (``mode="vm"``) starts in
    a fraction of a second where compiling the formulation takes several seconds, which one
    integration of 0.6 s does not repay.
    """
    t0 = time.perf_counter()
    if inv is None:
        inv = inverse(steps, t_move, order)
    t_inv = time.perf_counter() - t0
    moments = {name: Samples(inv.t, inv["actuator_efforts"][:, k], name=name)
               for k, name in enumerate(inv.names["actuators"])}
    t0 = time.perf_counter()
    sim = casmbd.Simulator(delta_robot(name="delta_robot_forward"), formulation,
                           inputs=moments, mode=mode)
    fwd = sim.run(t_move, len(inv.t) - 1, rtol=rtol, atol=rtol, integrator=integrator,
                  q0=inv["q"][0], v0=inv["v"][0])
    t_fwd = time.perf_counter() - t0
    hand = fwd["body_positions"][:, hand_index(fwd)]
    target = path_samples(fwd.t, t_move=t_move, order=order)
    return {"inverse": inv, "forward": fwd,
            "max_hand_error": float(np.max(np.abs(hand - target))),
            "max_coordinate_error": float(np.max(np.abs(fwd["q"] - inv["q"]))),
            "inverse_seconds": t_inv, "forward_seconds": t_fwd,
            "forward_solve_seconds": fwd.stats["solve_seconds"],
            "steps": fwd.stats.get("steps")}


def static_moments_closed_form(position, geom: Geometry = GEOMETRY) -> np.ndarray:
    """Drive moments holding the robot at rest at ``position``, by virtual work.

    For a virtual hand translation δP the arm angles change by δθ_i = J_i · δP with
    J_i = ∂θ_i/∂P = (H_i − E_i) / ((H_i − E_i) · ∂E_i/∂θ_i) (from |H_i − E_i|² = L2²,
    ∂E_i/∂θ_i = −L1 (sin θ e_i + cos θ z)).  The potential energy is
    V = g [(m_H + 3 m_F / 2) z_P + Σ (m_U + m_F)/2 · z_Ei],  z_Ei = −L1 sin θ_i (the rods'
    centres halfway), and Σ τ_i δθ_i = δV for all δP gives

        τ_i = −g (m_U + m_F)/2 · L1 cos θ_i + [J⁻ᵀ g (m_H + 3 m_F/2) z]_i .
    """
    p = np.asarray(position, float)
    theta = inverse_kinematics(p, geom)
    jac = np.zeros((3, 3))
    for i in range(3):
        e, _, _ = arm_frames(i, geom)
        d = p + geom.b * e - elbow(i, theta[i], geom)
        d_elbow = -geom.upper * (math.sin(theta[i]) * e + math.cos(theta[i]) * np.array([0, 0, 1]))
        jac[i] = d / (d @ d_elbow)
    platform = np.linalg.solve(jac.T, G * (geom.m_hand + 1.5 * geom.m_fore) * np.array([0, 0, 1]))
    return -G * (geom.m_upper + geom.m_fore) / 2 * geom.upper * np.cos(theta) + platform


def lagrange_drive_moments(times, t_move: float = T_MOVE, order: int = ORDER,
                           geom: Geometry = GEOMETRY) -> np.ndarray:
    """Drive moments along the gate path from Lagrange's equations in the hand coordinates P.

    Independent of casmbd's equations: every body's pose is a closed-form function of P
    (:func:`inverse_kinematics` written in CasADi: θ_i(P), elbows E_i, forearm frames
    [d_i, n_i, d_i × n_i] with n_i = t_i × d_i / |t_i × d_i|), the angular velocities from
    skew(ω) = Ṙ Rᵀ, the kinetic energy T(P, Ṗ) and potential V(P) summed over the bodies.  With
    L = T − V and the virtual work Σ τ_i δθ_i = τᵀ J δP (J = ∂θ/∂P),

        Jᵀ τ = ∂²L/∂Ṗ² P̈ + ∂²L/∂Ṗ∂P Ṗ − ∂L/∂P     (Lagrange's equations, seed 000),

    the derivatives by CasADi's automatic differentiation, P(t) from :func:`gate_path`.
    """
    pos, vel = ca.SX.sym("P", 3), ca.SX.sym("Pd", 3)
    z = np.array([0.0, 0.0, 1.0])
    kin, pot, thetas = 0, geom.m_hand * G * pos[2], []
    kin += 0.5 * geom.m_hand * ca.dot(vel, vel)
    upper_j = _rod(geom.m_upper, geom.upper, geom.rod_radius)
    fore_j = np.diag(_rod(geom.m_fore, geom.fore, geom.rod_radius))
    for i in range(3):
        e, t, base = arm_frames(i, geom)
        q = pos + (geom.b - geom.a) * e
        q_r, q_z = ca.dot(q, e), q[2]
        k = (ca.dot(q, q) + geom.upper**2 - geom.fore**2) / (2 * geom.upper)
        theta = 2 * ca.atan((k - q_r) / (ca.sqrt(q_r**2 + q_z**2 - k**2) - q_z))
        thetas.append(theta)
        knee = base + geom.upper * (ca.cos(theta) * e - ca.sin(theta) * z)
        foot = pos + geom.b * e
        rate = ca.jtimes(theta, pos, vel)
        c_up = (base + knee) / 2
        v_up = ca.jtimes(c_up, pos, vel)
        kin += 0.5 * geom.m_upper * ca.dot(v_up, v_up) + 0.5 * upper_j[1] * rate**2
        pot += geom.m_upper * G * c_up[2]
        d = (foot - knee) / geom.fore
        n = ca.cross(ca.DM(t), d)
        n = n / ca.norm_2(n)
        rot = ca.horzcat(d, n, ca.cross(d, n))
        rot_dot = ca.reshape(ca.jtimes(ca.vec(rot), pos, vel), 3, 3)
        w = rot_dot @ rot.T
        omega_body = rot.T @ ca.vertcat(w[2, 1], w[0, 2], w[1, 0])
        c_fore = (knee + foot) / 2
        v_fore = ca.jtimes(c_fore, pos, vel)
        kin += (0.5 * geom.m_fore * ca.dot(v_fore, v_fore)
                + 0.5 * ca.dot(omega_body, ca.DM(fore_j) @ omega_body))
        pot += geom.m_fore * G * c_fore[2]
    lag = kin - pot
    jac = ca.jacobian(ca.vertcat(*thetas), pos)
    dl_dv = ca.gradient(lag, vel)
    acc = ca.SX.sym("Pdd", 3)
    lhs = ca.jacobian(dl_dv, vel) @ acc + ca.jacobian(dl_dv, pos) @ vel - ca.gradient(lag, pos)
    tau = ca.solve(jac.T, lhs)
    time_ = ca.SX.sym("t")
    path = ca.vertcat(*gate_path(time_, t_move, order=order))
    path_v = ca.jacobian(path, time_)
    path_a = ca.jacobian(path_v, time_)
    f_tau = ca.Function("tau", [pos, vel, acc], [tau])
    f_path = ca.Function("path", [time_], [path, path_v, path_a])
    out = []
    for t_k in np.asarray(times, float):
        p_k, v_k, a_k = f_path(t_k)
        out.append(np.asarray(f_tau(p_k, v_k, a_k)).ravel())
    return np.array(out)


def static_moments_inverse_dynamics(position, steps: int = 2, mode: str = "auto") -> np.ndarray:
    """Drive moments (n_t, 3) at rest from :func:`casmbd.inverse_dynamics` (hand drivers
    holding ``position``), on ``steps`` + 1 times of 0.1 s."""
    p = np.asarray(position, float)
    mech = delta_robot(p, path=lambda t: (p[0] + 0 * t, p[1] + 0 * t, p[2] + 0 * t),
                       name="delta_robot_static")
    return casmbd.inverse_dynamics(mech, 0.1, steps, mode=mode)["actuator_efforts"]


# ----------------------------------------------------------------------------- script
def figure(inv, trip: dict, path: pathlib.Path) -> None:
    """Hand path (3-D and side view) and drive moments."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 4.4))
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    hand = inv["body_positions"][:, hand_index(inv)]
    ax.plot(*hand.T, "k-", lw=2, label="hand path")
    theta = inverse_kinematics(START)
    for i in range(3):
        e, _, base = arm_frames(i)
        foot = START + GEOMETRY.b * e
        ax.plot(*np.array([base, elbow(i, theta[i]), foot]).T, "-o", ms=3, color=f"C{i}")
    corners = START + GEOMETRY.b * np.array([arm_frames(i)[0] for i in (0, 1, 2, 0)])
    ax.plot(*corners.T, "k-", lw=1)
    circle = np.linspace(0, 2 * np.pi, 61)
    ax.plot(GEOMETRY.a * np.cos(circle), GEOMETRY.a * np.sin(circle), 0 * circle, "k:")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_box_aspect((1, 1, 1.4))
    ax.view_init(elev=18, azim=-20)
    ax.set_title("3-RUU Delta: start pose, path")
    ax2 = fig.add_subplot(1, 3, 2)
    s = np.hypot(hand[:, 0] - START[0], hand[:, 1] - START[1])
    ax2.plot(s, hand[:, 2], "k-")
    ax2.set_xlabel("horizontal travel [m]")
    ax2.set_ylabel("z [m]")
    ax2.set_title(f"gate path, {T_MOVE:g} s")
    ax2.grid(alpha=0.3)
    ax3 = fig.add_subplot(1, 3, 3)
    for k, name in enumerate(inv.names["actuators"]):
        ax3.plot(inv.t, inv["actuator_efforts"][:, k], label=name)
    ax3.set_xlabel("t [s]")
    ax3.set_ylabel("drive moment [N m]")
    ax3.set_title(f"round trip: hand error {trip['max_hand_error']:.1e} m")
    ax3.legend()
    ax3.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(convergence: bool = False) -> None:
    """Print the checks and write the figure; ``convergence`` adds the grid/tolerance table."""
    t0 = time.perf_counter()
    info = casmbd.info(delta_robot())
    print(f"model: {info['n_coordinates']} coordinates, {info['n_constraints']} constraints, "
          f"rank {info['rank']}, {info['degrees_of_freedom']} DOF, "
          f"{len(info['redundant_equations'])} redundant equations "
          f"({time.perf_counter() - t0:.1f} s)")
    t0 = time.perf_counter()
    ik = ik_check(steps=120)
    print(f"IK vs kinematics (121 times): largest arm-angle difference "
          f"{ik['max_angle_error']:.1e} rad, hand rotation-matrix deviation "
          f"{ik['max_hand_rotation']:.1e} ({time.perf_counter() - t0:.1f} s)")
    tau_id = static_moments_inverse_dynamics(START)[0]
    tau_cf = static_moments_closed_form(START)
    print(f"static drive moments at {START.tolist()}: inverse dynamics "
          f"{np.array2string(tau_id, precision=6)} N m, virtual work "
          f"{np.array2string(tau_cf, precision=6)} N m, difference "
          f"{np.max(np.abs(tau_id - tau_cf)):.1e} N m")
    steps, rtol = 1200, 1e-12
    trip = round_trip(steps=steps, rtol=rtol)
    inv = trip["inverse"]
    peak = np.max(np.abs(inv["actuator_efforts"]), axis=0)
    hand_acc = inv["body_accelerations"][:, hand_index(inv)]
    print(f"gate path: {T_MOVE:g} s, peak hand speed "
          f"{np.max(np.linalg.norm(inv['body_velocities'][:, hand_index(inv)], axis=1)):.2f}"
          f" m/s, peak hand acceleration {np.max(np.linalg.norm(hand_acc, axis=1)):.1f} m/s²")
    lagrange = lagrange_drive_moments(inv.t[::10])
    print(f"drive moments vs Lagrange's equations in the hand coordinates "
          f"({len(lagrange)} times): largest difference "
          f"{np.max(np.abs(inv['actuator_efforts'][::10] - lagrange)):.1e} N m")
    print("peak drive moments: " + ", ".join(
        f"{n} {v:.3f} N m" for n, v in zip(inv.names["actuators"], peak, strict=True)))
    print(f"round trip ({steps} intervals, rtol = atol = {rtol:g}): hand error "
          f"{trip['max_hand_error']:.1e} m (coordinates {trip['max_coordinate_error']:.1e}); "
          f"inverse dynamics {trip['inverse_seconds']:.1f} s, forward "
          f"{trip['forward_seconds']:.1f} s (integration {trip['forward_solve_seconds']:.2f} s, "
          f"{trip['steps']} steps)")
    if convergence:
        print("convergence (default formulation, VM): intervals, rtol, hand error, forward s")
        for n in (150, 300, 600, 1200):
            base = inverse(n)
            for tol in (1e-10, 1e-12):
                r = round_trip(n, tol, inv=base)
                print(f"  {n:5d}  {tol:7.0e}  {r['max_hand_error']:.1e} m  "
                      f"{r['forward_seconds']:.2f} s")
    out = pathlib.Path(__file__).resolve().parent.parent / "docs" / "figures" / "delta_robot.png"
    figure(inv, trip, out)
    print(f"figure: {out}")


if __name__ == "__main__":
    import sys

    main(convergence="--convergence" in sys.argv[1:])
