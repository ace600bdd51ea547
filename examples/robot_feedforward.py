"""UR5-type arm: feedforward joint torques for a Cartesian straight-line move of the tool flange.

1. The tool flange ``ee_link`` (a marker: the URDF's fixed-joint link) moves 0.3 m along the
   global y axis in 1.5 s with a quintic time law s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (zero velocity and
   acceleration at both ends), its orientation held fixed at the start orientation.
2. Inverse kinematics, position *and* fixed orientation (6 equations, 6 joints), by damped
   Newton on the compiled ``forward_kinematics`` and ``jacobian``:
   Δq = Jᵀ (J Jᵀ + μ² 1)⁻¹ e, e = (p_d − p, −vee(skew(R R_dᵀ))), μ = 1e-8, from the previous
   sample's solution.
3. Velocities and accelerations by analytic differentiation of the IK (J = [J_v; J_ω] in global
   components, ω_d = 0): J q̇ = (ṗ_d, 0) and J q̈ = (p̈_d, 0) − J̇ q̇, with J̇ q̇ a central
   difference of J along q̇ (J(q + h q̇) − J(q − h q̇)) q̇ / 2h, h = 1e-6.
4. Joint torques τ = M(q) q̈ + b(q, q̇) by the compiled Newton–Euler ``inverse_dynamics``.
5. Check: the compiled forward dynamics (LDLᵀ of M) with these torques gives back q̈.

Run: ``python examples/robot_feedforward.py`` (``--samples N`` to change the time grid).
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

import casmbd

URDF = pathlib.Path(__file__).with_name("ur5_arm.urdf")
FRAME = "ee_link"                                   # the tool flange (a marker)
Q_START = np.array([0.0, -1.2, 1.6, -1.9, -1.57, 0.3])  # start pose (rad), away from singularities
DISPLACEMENT = np.array([0.0, 0.3, 0.0])            # straight line, m
DURATION = 1.5                                      # s


def quintic(t: float, duration: float) -> tuple[float, float, float]:
    """s, ṡ, s̈ of the quintic law s(τ) = 10τ³ − 15τ⁴ + 6τ⁵, τ = t / T."""
    x = t / duration
    s = x**3 * (10 - 15 * x + 6 * x**2)
    ds = 30 * x**2 * (1 - x) ** 2 / duration
    dds = 60 * x * (1 - x) * (1 - 2 * x) / duration**2
    return s, ds, dds


def _vee_skew(a: np.ndarray) -> np.ndarray:
    """vee of the skew part of a 3 × 3 matrix, = sin θ n for a rotation Exp(θ n)."""
    return 0.5 * np.array([a[2, 1] - a[1, 2], a[0, 2] - a[2, 0], a[1, 0] - a[0, 1]])


def pose(arm, q: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Position and rotation (body → global) of frame row ``k``."""
    pos, rot = arm.forward_kinematics(q)
    return pos[k], rot[k]


def solve_ik(arm, q0: np.ndarray, p_d: np.ndarray, r_d: np.ndarray, k: int,
             tol: float = 1e-13, max_iter: int = 50, mu: float = 1e-8) -> tuple[np.ndarray, float]:
    """Damped Newton on the flange pose; returns q and the final residual norm |e|."""
    q = q0.copy()
    for _ in range(max_iter):
        p, r = pose(arm, q, k)
        e = np.concatenate([p_d - p, -_vee_skew(r @ r_d.T)])
        res = float(np.linalg.norm(e))
        if res <= tol:
            return q, res
        jac = arm.jacobian(q, FRAME)
        q = q + jac.T @ np.linalg.solve(jac @ jac.T + mu**2 * np.eye(6), e)
    p, r = pose(arm, q, k)
    return q, float(np.linalg.norm(np.concatenate([p_d - p, _vee_skew(r @ r_d.T)])))


def run(samples: int = 151, mode: str = "auto") -> dict:
    """The move on ``samples`` equally spaced times; returns the arrays and the check figures."""
    mech = casmbd.load_urdf(str(URDF))
    arm = casmbd.compile(mech, coordinates="joint", mode=mode)
    k = arm.frame_names.index(FRAME)
    p0, r0 = pose(arm, Q_START, k)
    times = np.linspace(0.0, DURATION, samples)
    n = arm.nq
    qs, vs, acc = (np.zeros((samples, n)) for _ in range(3))
    ik_res = np.zeros(samples)
    q, h = Q_START.copy(), 1e-6
    for i, t in enumerate(times):
        s, ds, dds = quintic(t, DURATION)
        q, ik_res[i] = solve_ik(arm, q, p0 + s * DISPLACEMENT, r0, k)
        jac = arm.jacobian(q, FRAME)
        v = np.linalg.solve(jac, np.concatenate([ds * DISPLACEMENT, np.zeros(3)]))
        jdot_v = (arm.jacobian(q + h * v, FRAME) - arm.jacobian(q - h * v, FRAME)) @ v / (2 * h)
        a = np.linalg.solve(jac, np.concatenate([dds * DISPLACEMENT, np.zeros(3)]) - jdot_v)
        qs[i], vs[i], acc[i] = q, v, a
    tau = arm.inverse_dynamics_batch(qs, vs, acc)
    # checks: the flange on the line, on the time law, with its orientation; q̈ reproduced
    points = np.array([pose(arm, qi, k)[0] for qi in qs])
    rots = np.array([pose(arm, qi, k)[1] for qi in qs])
    u = DISPLACEMENT / np.linalg.norm(DISPLACEMENT)
    rel = points - p0
    line_dev = float(np.max(np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)))
    target = p0 + np.outer([quintic(t, DURATION)[0] for t in times], DISPLACEMENT)
    path_err = float(np.max(np.linalg.norm(points - target, axis=1)))
    rot_err = float(np.max(np.abs(rots - r0)))
    acc_fd = arm.forward_dynamics_batch(qs, vs, tau)
    limits = [mech.joints[c.split(".")[0]].urdf_limits.get("effort", np.inf)
              for c in arm.coordinate_names]
    return {"t": times, "q": qs, "v": vs, "a": acc, "tau": tau, "names": arm.coordinate_names,
            "effort_limits": np.array(limits, dtype=float), "ik_residual": ik_res,
            "line_deviation": line_dev, "path_error": path_err, "orientation_error": rot_err,
            "acc_error": float(np.max(np.abs(acc_fd - acc))),
            "acc_fd_vs_diff": float(np.max(np.abs(np.gradient(vs, times, axis=0)[1:-1]
                                                  - acc[1:-1])))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=151)
    out = run(ap.parse_args().samples)
    print(f"flange {FRAME}: {np.linalg.norm(DISPLACEMENT):.2f} m along y in {DURATION} s "
          f"(quintic), orientation fixed; {len(out['t'])} samples")
    print(f"{'joint':<22}{'max |tau| [N m]':>16}{'effort limit':>14}{'max |qdot|':>12}")
    for j, name in enumerate(out["names"]):
        print(f"{name.split('.')[0]:<22}{np.max(np.abs(out['tau'][:, j])):16.4g}"
              f"{out['effort_limits'][j]:14.1f}{np.max(np.abs(out['v'][:, j])):12.4f}")
    print(f"IK residual max      {np.max(out['ik_residual']):.1e}")
    print(f"line deviation max   {out['line_deviation']:.1e} m")
    print(f"path error max       {out['path_error']:.1e} m")
    print(f"orientation error    {out['orientation_error']:.1e}")
    print(f"forward dynamics: |qdd(tau) - qdd| max {out['acc_error']:.1e} rad/s^2")
    print(f"qdd against a finite difference of qdot: {out['acc_fd_vs_diff']:.1e} rad/s^2")


if __name__ == "__main__":
    main()
