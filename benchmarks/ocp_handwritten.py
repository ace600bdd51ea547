"""Hand-written CasADi baselines of the issue-8 reference problems (independent of casmbd).

Each problem is written the way one writes it by hand with CasADi's ``Opti`` stack: the
equations of motion in closed form from the Lagrangian, explicit accelerations
q̈ = M(q)⁻¹ (τ − c(q, q̇) − g(q)), direct collocation on Radau IIA points of degree 3 (one
element per control interval, the CasADi ``direct_collocation`` example), piecewise-constant
controls, N = 50, ``expand=True``, IPOPT with MUMPS at its default tolerance, and a guess that
interpolates the boundary states linearly (controls 0).  The boundary conditions are those of
``ocp/cart_pole.toml``, ``ocp/double_pendulum_swingup.toml`` and
``ocp/double_pendulum_min_time.toml``, so the optimal objectives must equal casmbd's.

* **cart-pole** (``cart_pole``): cart 1 kg on a horizontal rail, point mass 0.1 kg on a massless
  0.5 m rod (casmbd's scene gives the bob an inertia of 1e-6 kg m² about its centre; the same
  value is used here), |u| ≤ 20 N, T = 2 s, min ∫ u² dt; from hanging at rest at x = 0 to upright
  at rest at x = 0.  Lagrangian with x the cart position and θ the rod angle from the downward
  vertical (counter-clockwise)::

      [m_c + m_p        m_p l cos θ ] [ẍ]   [u + m_p l θ̇² sin θ]
      [m_p l cos θ   m_p l² + I_p  ] [θ̈] = [  −m_p g l sin θ  ]

* **double-pendulum swing-up** (``double_pendulum_swingup``): two uniform rods m = 1 kg,
  L = 1 m, I = m L²/12, joint torques |τ| ≤ 50 N m at the shoulder and the elbow, θ₁ absolute
  from +x, θ₂ relative, T = 2 s, min ∫ τᵀτ dt, from θ = (−π/2, 0) to (π/2, 0) at rest
  (Spong, Hutchinson and Vidyasagar, *Robot Modeling and Control*, 2006, eq. 7.87 with
  l_c = L/2)::

      M₁₁ = 2 I + m l_c² + m (L² + l_c² + 2 L l_c cos θ₂)
      M₁₂ = I + m (l_c² + L l_c cos θ₂),   M₂₂ = I + m l_c²
      c = m L l_c sin θ₂ [−(2 θ̇₁ θ̇₂ + θ̇₂²), θ̇₁²]
      g = m g [(l_c + L) cos θ₁ + l_c cos(θ₁ + θ₂), l_c cos(θ₁ + θ₂)]

* **minimum-time double pendulum** (``double_pendulum_min_time``): the same pendulum with
  |τ| ≤ 20 N m and free T ∈ [0.1, 5] s (guess 1 s), min T.

Reference values from the issue: 53.66, 59.03 and T* = 0.7194 s.
"""

from __future__ import annotations

import math
import pathlib
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

G = 9.81
#: Number of control intervals and collocation degree of every baseline.
INTERVALS = 50
DEGREE = 3
#: With ``repeat`` above 1 short solves are repeated until they add up to this many seconds
#: (at most ``MAX_SOLVES``), as in :mod:`benchmarks.ocp_problems`.
MIN_SOLVE_SECONDS = 0.5
MAX_SOLVES = 25
#: ``detect_simple_bounds``: rows of ``g`` that bound one variable (the control and final-time
#: bounds, the boundary states) go to IPOPT as variable bounds, as a hand-written NLP states
#: them (issue 36: minimum-time 52 → 26 iterations); casmbd states them as bounds itself.
IPOPT_OPTIONS = {"expand": True, "print_time": False, "ipopt.print_level": 0,
                 "ipopt.sb": "yes", "ipopt.max_iter": 3000, "detect_simple_bounds": True}
#: The UR5's own IPOPT options (``ocp/ur5_min_time.toml``'s ``[ocp.solver_options]``).
UR5_OPTIONS = {"ipopt.tol": 1e-10, "ipopt.bound_relax_factor": 0.0}


@dataclass
class Baseline:
    """Figures of one hand-written solve."""

    name: str
    objective: float
    iterations: int
    success: bool
    setup_seconds: float          # Opti problem build + solver construction (expand)
    solve_seconds: float          # wall time of the solver Function call (IPOPT)
    solve_cpu_seconds: float      # process CPU time of that call
    ipopt_wall_seconds: float     # IPOPT's own t_wall_total (nan if not reported)
    callback_seconds: float       # of the solve: wall time in the NLP's f, g, ∇f, J_g, ∇²L
    final_time: float
    variables: int
    constraints: int


def cart_pole_rhs(m_cart: float = 1.0, m_pole: float = 0.1, length: float = 0.5,
                  inertia: float = 1e-6) -> Callable:
    """ẋ = f(x, u) of the cart-pole, x = (x, θ, ẋ, θ̇), θ = 0 hanging down."""
    def f(x, u):
        th, xd, thd = x[1], x[2], x[3]
        mpl = m_pole * length
        m = ca.vertcat(ca.horzcat(m_cart + m_pole, mpl * ca.cos(th)),
                       ca.horzcat(mpl * ca.cos(th), m_pole * length**2 + inertia))
        rhs = ca.vertcat(u[0] + mpl * thd**2 * ca.sin(th), -mpl * G * ca.sin(th))
        return ca.vertcat(xd, thd, ca.solve(m, rhs))
    return f


def double_pendulum_rhs(m: float = 1.0, length: float = 1.0) -> Callable:
    """ẋ = f(x, τ) of two uniform rods, x = (θ₁, θ₂, θ̇₁, θ̇₂), θ₁ from +x, θ₂ relative."""
    lc, inertia = length / 2, m * length**2 / 12

    def f(x, tau):
        th1, th2, w1, w2 = x[0], x[1], x[2], x[3]
        c2 = ca.cos(th2)
        m11 = 2 * inertia + m * lc**2 + m * (length**2 + lc**2 + 2 * length * lc * c2)
        m12 = inertia + m * (lc**2 + length * lc * c2)
        m22 = inertia + m * lc**2
        mass = ca.vertcat(ca.horzcat(m11, m12), ca.horzcat(m12, m22))
        h = m * length * lc * ca.sin(th2)
        cor = ca.vertcat(-h * (2 * w1 * w2 + w2**2), h * w1**2)
        grav = m * G * ca.vertcat((lc + length) * ca.cos(th1) + lc * ca.cos(th1 + th2),
                                  lc * ca.cos(th1 + th2))
        return ca.vertcat(w1, w2, ca.solve(mass, tau - cor - grav))
    return f


def radau_matrices(degree: int = DEGREE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points τ (with 0), derivative matrix C and end-point weights D of the Lagrange basis on
    [0, 1] through 0 and the Radau IIA points (CasADi's ``direct_collocation.py`` example)."""
    tau = np.append(0.0, ca.collocation_points(degree, "radau"))
    c = np.zeros((degree + 1, degree + 1))
    d = np.zeros(degree + 1)
    for j in range(degree + 1):
        p = np.poly1d([1.0])
        for r in range(degree + 1):
            if r != j:
                p *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        d[j] = p(1.0)
        dp = np.polyder(p)
        for r in range(degree + 1):
            c[j, r] = dp(tau[r])
    return tau, c, d


def collocation_problem(f: Callable, nx: int, nu: int, x_start, x_end, u_bound: float,
                        horizon: float | None, objective: str, t_guess: float = 1.0,
                        t_bounds: tuple[float, float] = (0.1, 5.0),
                        intervals: int = INTERVALS, degree: int = DEGREE):
    """The Opti problem (radau collocation, piecewise-constant controls, linear guess).

    ``horizon`` None means a free final time T (variable, ``t_bounds``, guess ``t_guess``);
    ``objective`` is "effort" (Σ h |u_k|², i.e. ∫ uᵀu dt) or "time" (T).
    Returns (opti, T expression or value).
    """
    tau, cmat, dvec = radau_matrices(degree)
    xs_, us_ = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    f = ca.Function("f", [xs_, us_], [f(xs_, us_)])   # symbolic 2×2 solve in SX
    x_start, x_end = np.asarray(x_start, float), np.asarray(x_end, float)
    opti = ca.Opti()
    if horizon is None:
        T = opti.variable()
        opti.subject_to(opti.bounded(t_bounds[0], T, t_bounds[1]))
        opti.set_initial(T, t_guess)
    else:
        T = horizon
    h = T / intervals
    X = opti.variable(nx, intervals + 1)
    U = opti.variable(nu, intervals)
    cost = 0
    for k in range(intervals):
        xc = opti.variable(nx, degree)
        opti.set_initial(X[:, k], x_start + k / intervals * (x_end - x_start))
        for j in range(degree):
            s = (k + tau[j + 1]) / intervals
            opti.set_initial(xc[:, j], x_start + s * (x_end - x_start))
        xs = ca.horzcat(X[:, k], xc)
        for j in range(1, degree + 1):
            xp = ca.mtimes(xs, cmat[:, j])
            opti.subject_to(h * f(xs[:, j], U[:, k]) == xp)
        opti.subject_to(X[:, k + 1] == ca.mtimes(xs, dvec))
        opti.subject_to(opti.bounded(-u_bound, U[:, k], u_bound))
        if objective == "effort":
            cost = cost + h * ca.sumsqr(U[:, k])
    opti.set_initial(X[:, intervals], x_end)
    opti.set_initial(U, 0.0)
    opti.subject_to(X[:, 0] == x_start)
    opti.subject_to(X[:, intervals] == x_end)
    opti.minimize(T if objective == "time" else cost)
    return opti, T


# ------------------------------------------------------------------------------ UR5 arm
UR5_URDF = pathlib.Path(__file__).resolve().parent.parent / "examples" / "ur5_arm.urdf"


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    """URDF's fixed-axis roll–pitch–yaw rotation R = R_z(y) R_y(p) R_x(r)."""
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def ur5_chain(path=UR5_URDF) -> list[dict]:
    """The revolute joints of the serial UR5 URDF, base to tip: origin (p, R) in the parent
    link, axis, and the child link's mass, centre of mass and inertia about it (link frame)."""
    root = ET.parse(path).getroot()
    links = {}
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        origin = inertial.find("origin")
        xyz = [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None
                                  else "0 0 0").split()]
        rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None
                                  else "0 0 0").split()]
        i = inertial.find("inertia").attrib
        inertia = np.array([[float(i["ixx"]), float(i["ixy"]), float(i["ixz"])],
                            [float(i["ixy"]), float(i["iyy"]), float(i["iyz"])],
                            [float(i["ixz"]), float(i["iyz"]), float(i["izz"])]])
        rot = _rpy(*rpy)
        links[link.get("name")] = {"mass": float(inertial.find("mass").get("value")),
                                   "com": np.array(xyz), "inertia": rot @ inertia @ rot.T}
    chain = []
    for joint in root.iter("joint"):
        if joint.get("type") not in ("revolute", "continuous"):
            continue  # the fixed world and end-effector joints carry no mass here
        origin = joint.find("origin")
        chain.append({"name": joint.get("name"),
                      "p": np.array([float(v) for v in origin.get("xyz").split()]),
                      "R": _rpy(*[float(v) for v in origin.get("rpy").split()]),
                      "axis": np.array([float(v) for v in joint.find("axis").get("xyz").split()]),
                      **links[joint.find("child").get("link")]})
    return chain


def _axis_rotation(axis: np.ndarray, q):
    """Rodrigues: R = I + sin q [a]× + (1 − cos q) [a]×² for a unit axis a."""
    k = ca.DM([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return ca.DM.eye(3) + ca.sin(q) * k + (1 - ca.cos(q)) * ca.mtimes(k, k)


def ur5_inverse_dynamics(chain: list[dict] | None = None, gravity=(0.0, 0.0, -G)) -> Callable:
    """τ = RNEA(q, q̇, q̈) of the serial chain (Luh, Walker and Paul 1980; Craig, *Introduction
    to Robotics*, 3rd ed., §6.5): outward ω, ω̇, the links' origin and centre-of-mass
    accelerations (gravity as a base acceleration −g), inward forces and moments, τ_i = a_iᵀ n_i,
    in each link's frame."""
    chain = chain or ur5_chain()

    def rnea(q, v, a):
        w = wd = ca.DM.zeros(3)
        acc = -ca.DM(gravity)
        frames = []
        for i, j in enumerate(chain):
            rot = ca.mtimes(ca.DM(j["R"]), _axis_rotation(j["axis"], q[i]))  # child → parent
            axis = ca.DM(j["axis"])
            acc = ca.mtimes(rot.T, acc + ca.cross(wd, ca.DM(j["p"]))
                            + ca.cross(w, ca.cross(w, ca.DM(j["p"]))))
            w_in = ca.mtimes(rot.T, w)
            w = w_in + axis * v[i]
            wd = ca.mtimes(rot.T, wd) + axis * a[i] + ca.cross(w_in, axis * v[i])
            c, inertia = ca.DM(j["com"]), ca.DM(j["inertia"])
            ac = acc + ca.cross(wd, c) + ca.cross(w, ca.cross(w, c))
            force = j["mass"] * ac
            moment = ca.mtimes(inertia, wd) + ca.cross(w, ca.mtimes(inertia, w))
            frames.append((rot, c, force, moment))
        f = n = ca.DM.zeros(3)
        tau = [None] * len(chain)
        rot_child, p_child = ca.DM.eye(3), ca.DM.zeros(3)
        for i in reversed(range(len(chain))):
            rot, c, force, moment = frames[i]
            f_child = ca.mtimes(rot_child, f)
            n = moment + ca.cross(c, force) + ca.mtimes(rot_child, n) \
                + ca.cross(p_child, f_child)
            f = force + f_child
            tau[i] = ca.dot(ca.DM(chain[i]["axis"]), n)
            rot_child, p_child = rot, ca.DM(chain[i]["p"])
        return ca.vertcat(*tau)
    return rnea


def implicit_collocation_problem(rnea: Callable, nq: int, x_start, x_end, u_lower, u_upper,
                                 v_limit, t_guess: float, t_bounds: tuple[float, float],
                                 intervals: int, degree: int, start: dict | None = None):
    """Minimum time with the equations of motion as constraints (casmbd's implicit form):
    Radau collocation of degree d on one element per interval, at every point
    h [q̇; q̈] = Σ C_rj x_r, RNEA(q, q̇, q̈) = u with q̈ variables, |q̇| ≤ v_limit; continuity
    x_{k+1} = Σ D_r x_r; linear guess, zero controls and accelerations, or the arrays of
    ``start`` ("T", "X" (2nq, N+1), "U" (nq, N), "XC" (2nq, dN), "A" (nq, dN)) if given."""
    tau, cmat, dvec = radau_matrices(degree)
    qs, vs, as_ = (ca.SX.sym(n, nq) for n in ("q", "v", "a"))
    f = ca.Function("rnea", [qs, vs, as_], [rnea(qs, vs, as_)])
    x_start, x_end = np.asarray(x_start, float), np.asarray(x_end, float)
    opti = ca.Opti()
    T = opti.variable()
    opti.subject_to(opti.bounded(t_bounds[0], T, t_bounds[1]))
    opti.set_initial(T, t_guess)
    h = T / intervals
    X = opti.variable(2 * nq, intervals + 1)
    U = opti.variable(nq, intervals)
    vmax = np.asarray(v_limit, float)
    opti.subject_to(opti.bounded(-vmax, X[nq:, 0], vmax))
    for k in range(intervals):
        xc = opti.variable(2 * nq, degree)
        acc = opti.variable(nq, degree)
        opti.set_initial(X[:, k], x_start + k / intervals * (x_end - x_start))
        for j in range(degree):
            s = (k + tau[j + 1]) / intervals
            opti.set_initial(xc[:, j], x_start + s * (x_end - x_start))
        xs = ca.horzcat(X[:, k], xc)
        for j in range(1, degree + 1):
            xp = ca.mtimes(xs, cmat[:, j])
            q, v, a = xs[:nq, j], xs[nq:, j], acc[:, j - 1]
            opti.subject_to(h * ca.vertcat(v, a) == xp)
            opti.subject_to(f(q, v, a) == U[:, k])
            opti.subject_to(opti.bounded(-vmax, v, vmax))
        opti.subject_to(X[:, k + 1] == ca.mtimes(xs, dvec))
        opti.subject_to(opti.bounded(np.asarray(u_lower), U[:, k], np.asarray(u_upper)))
        if start is not None:
            opti.set_initial(xc, start["XC"][:, k * degree:(k + 1) * degree])
            opti.set_initial(acc, start["A"][:, k * degree:(k + 1) * degree])
    opti.set_initial(X[:, intervals], x_end)
    opti.set_initial(U, 0.0)
    if start is not None:
        opti.set_initial(T, start["T"])
        opti.set_initial(X, start["X"])
        opti.set_initial(U, start["U"])
    opti.subject_to(X[:, 0] == x_start)
    opti.subject_to(X[:, intervals] == x_end)
    opti.minimize(T)
    return opti, T


#: ``ocp/ur5_min_time.toml``: rest to rest between two working poses, URDF effort and velocity
#: limits, T ∈ [0.1, 5] s (guess 1.5 s), radau d=4 on 12 intervals.
UR5_START = [0.0, -1.2, 1.6, -1.9, -1.57, 0.0]
UR5_END = [1.5, -0.6, 1.0, -1.5, -1.57, 1.0]


def build(name: str):
    """The Opti problem of ``name`` (see :data:`PROBLEMS`)."""
    if name == "cart_pole":
        return collocation_problem(cart_pole_rhs(), 4, 1, [0, 0, 0, 0], [0, math.pi, 0, 0],
                                   20.0, 2.0, "effort")
    if name == "double_pendulum_swingup":
        return collocation_problem(double_pendulum_rhs(), 4, 2, [-math.pi / 2, 0, 0, 0],
                                   [math.pi / 2, 0, 0, 0], 50.0, 2.0, "effort")
    if name == "double_pendulum_min_time":
        return collocation_problem(double_pendulum_rhs(), 4, 2, [-math.pi / 2, 0, 0, 0],
                                   [math.pi / 2, 0, 0, 0], 20.0, None, "time", t_guess=1.0)
    if name == "ur5_min_time":
        chain = ur5_chain()
        return implicit_collocation_problem(
            ur5_inverse_dynamics(chain), 6, UR5_START + [0.0] * 6, UR5_END + [0.0] * 6,
            [-150.0] * 3 + [-28.0] * 3, [150.0] * 3 + [28.0] * 3, [3.15] * 3 + [3.2] * 3,
            t_guess=1.5, t_bounds=(0.1, 5.0), intervals=12, degree=4)
    raise KeyError(f"no hand-written baseline named '{name}' (known: {', '.join(PROBLEMS)})")


#: Baselines by the stem of the matching problem file in ocp/, with the issue's value.
PROBLEMS: dict[str, float] = {"cart_pole": 53.66, "double_pendulum_swingup": 59.03,
                              "double_pendulum_min_time": 0.7194,
                              "ur5_min_time": 0.528529}


def solve(name: str, repeat: int = 1) -> Baseline:
    """Build and solve the baseline ``name`` ``repeat`` times from the same guess (more when
    the solves are short: :data:`MIN_SOLVE_SECONDS`).

    *setup*: building the Opti problem and the solver from its ``x``, ``f``, ``g`` (what
    ``Opti.solve`` does: ``nlpsol`` with expansion to SX and the derivative graphs); *solve*:
    the median wall time of the solver Function calls (IPOPT's own ``t_wall_total`` too) and
    their median process CPU time.
    """
    start = time.perf_counter()
    opti, T = build(name)
    problem = {"x": opti.x, "f": opti.f, "g": opti.g}
    extra = UR5_OPTIONS if name == "ur5_min_time" else {}
    solver = ca.nlpsol("baseline", "ipopt", problem,
                       {**IPOPT_OPTIONS, **extra, "record_time": True})
    arg = {"x0": opti.value(opti.x, opti.initial()), "lbg": ca.evalf(opti.lbg),
           "ubg": ca.evalf(opti.ubg)}
    setup = time.perf_counter() - start
    walls, cpus, ipopt_walls, callbacks = [], [], [], []
    while len(walls) < max(1, repeat) or (repeat > 1 and sum(walls) < MIN_SOLVE_SECONDS
                                          and len(walls) < MAX_SOLVES):
        t0, c0 = time.perf_counter(), time.process_time()
        out = solver(**arg)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        stats = solver.stats()
        ipopt_walls.append(float(stats.get("t_wall_total", math.nan)))
        callbacks.append(sum(float(v) for k, v in stats.items()
                             if k.startswith("t_wall_nlp_")))
    x = out["x"]
    final_time = float(ca.Function("T", [opti.x], [T])(x)) if isinstance(T, ca.MX) else T
    return Baseline(name=name, objective=float(out["f"]), iterations=int(stats["iter_count"]),
                    success=bool(stats["success"]), setup_seconds=setup,
                    solve_seconds=float(np.median(walls)),
                    solve_cpu_seconds=float(np.median(cpus)),
                    ipopt_wall_seconds=float(np.median(ipopt_walls)),
                    callback_seconds=float(np.median(callbacks)),
                    final_time=float(final_time), variables=int(opti.nx),
                    constraints=int(opti.ng))


if __name__ == "__main__":
    for key in PROBLEMS:
        b = solve(key, repeat=3)
        print(f"{key}: objective {b.objective:.6g} (issue {PROBLEMS[key]}), "
              f"{b.iterations} iterations, setup {b.setup_seconds:.3g} s, "
              f"solve {b.solve_seconds:.3g} s (IPOPT t_wall {b.ipopt_wall_seconds:.3g} s)")
