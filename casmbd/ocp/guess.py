"""Initial guesses for a transcription: boundary-state interpolation, forward simulation,
inverse dynamics of the interpolated path, or a previous solution (warm start)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.analysis.dynamics.simulate import simulate
from casmbd.compiled.build import compile_model
from casmbd.errors import AnalysisError, CasmbdError
from casmbd.ocp.solution import OcpSolution


def boundary_state(tr, which: str, start: np.ndarray, continuation: int = 8) -> np.ndarray:
    """A state (q, q̇) meeting C = 0, C_q q̇ + C_t = 0 and the named initial/final conditions
    in the least-squares sense, by Gauss–Newton from ``start`` (for the guess only).

    The named values are approached in ``continuation`` equal steps from their values at
    ``start`` (a full step from far away can land a closed loop on another assembly branch or
    wind its angles by whole turns: the four-bar's half crank turn did)."""
    nq = tr.nq
    x = ca.SX.sym("x", 2 * nq)
    t = tr.ocp.t_start + (0.0 if which == "initial" else _horizon(tr))
    u = ca.DM.zeros(tr.nu)
    parts = []
    if tr.nc:
        c, cdot = tr.node(x[:nq], x[nq:], t, tr.p)[:2]
        parts += [c, cdot]
    fn, values = ((tr.initial_fn, tr.initial_values) if which == "initial"
                  else (tr.final_fn, tr.final_values))
    if values.size:
        parts.append(fn(x[:nq], x[nq:], t, u, tr.p) - values)
    if not parts:
        return start
    target = ca.SX.sym("target", values.size)
    if values.size:
        parts[-1] = parts[-1] + values - target
    res = ca.vertcat(*parts)
    f = ca.Function("gn", [x, target], [res, ca.jacobian(res, x)])
    xk = np.array(start, dtype=float)
    if values.size:
        here = np.asarray(fn(xk[:nq], xk[nq:], t, u, tr.p), dtype=float).ravel()
        targets = [here + s * (values - here) for s in np.linspace(0, 1, continuation + 1)[1:]]
    else:
        targets = [values]
    for goal in targets:
        xk = _gauss_newton(f, xk, goal)
    return xk


def _gauss_newton(f, xk: np.ndarray, *args) -> np.ndarray:
    """Minimum-norm Gauss–Newton steps on the residual ``f(x, *args) -> (r, ∂r/∂x)``."""
    for _ in range(50):
        r, j = (np.asarray(v, dtype=float) for v in f(xk, *args))
        r = r.ravel()
        if np.max(np.abs(r), initial=0.0) < 1e-12:
            break
        step = np.linalg.lstsq(j, -r, rcond=None)[0]
        xk = xk + step
        if np.max(np.abs(step)) < 1e-14:
            break
    return xk


def _projector(tr):
    """x ↦ the nearby state meeting C = 0 and C_q q̇ + C_t = 0 (minimum-norm Gauss–Newton from
    x; identity without constraints): the interpolated guess of a closed loop kept on its
    constraint manifold."""
    if not tr.nc:
        return lambda x, t: x
    f = _manifold_residual(tr)
    return lambda xs, ts: _gauss_newton(f, np.asarray(xs, dtype=float), ts)


def _manifold_residual(tr) -> ca.Function:
    """``(x, t) -> (r, ∂r/∂x)`` with r = (C, C_q q̇ + C_t): the distance of a state from the
    constraint manifold, for the projections of the guess."""
    nq = tr.nq
    x, t = ca.SX.sym("x", 2 * nq), ca.SX.sym("t")
    c, cdot = tr.node(x[:nq], x[nq:], t, tr.p)[:2]
    res = ca.vertcat(c, cdot)
    return ca.Function("project", [x, t], [res, ca.jacobian(res, x)])


def _batch_projector(tr, iterations: int = 8):
    """Many states projected at once: ``iterations`` minimum-norm Newton steps
    x ← x − Jᵀ (J Jᵀ)⁻¹ r on r = (C, C_q q̇ + C_t), in one mapped CasADi call over all points
    (one Python call instead of one per point and step: the four-bar's 201 guess states took
    0.27 s point by point).  Returns ``(xs, ts) -> (projected, converged)``; points whose
    residual is not below 1e-12 (or whose J Jᵀ is singular) are left to :func:`_projector`."""
    rj = _manifold_residual(tr)
    x, t = ca.MX.sym("x", 2 * tr.nq), ca.MX.sym("t")
    xk = x
    for _ in range(iterations):
        r, j = rj(xk, t)
        xk = xk - ca.mtimes(j.T, ca.solve(ca.mtimes(j, j.T), r, "qr"))
    r, _ = rj(xk, t)
    newton = ca.Function("project_newton", [x, t], [xk, ca.norm_inf(r)])

    def project(xs: np.ndarray, ts: np.ndarray):
        xs, ts = np.atleast_2d(np.asarray(xs, float)), np.asarray(ts, float).ravel()
        out, err = newton.map(len(ts))(xs.T, ts[None, :])
        out, err = np.asarray(out, float).T, np.asarray(err, float).ravel()
        return out, np.isfinite(err) & (err < 1e-12) & np.all(np.isfinite(out), axis=1)
    return project


def _states(tr, kind):
    """Boundary states and the state function x(s), s ∈ [0, 1] (fraction of the horizon)."""
    system = tr.system
    scene = np.concatenate([system.initial_coordinates(), system.initial_velocities()])
    if tr.ocp._initial_given:
        x_start = boundary_state(tr, "initial", scene)
    else:
        x_start = tr._scene_start()
    x_end = boundary_state(tr, "final", x_start) if tr.ocp._final else x_start
    return x_start, x_end


def _horizon(tr) -> float:
    h = tr.ocp.horizon
    return float(h.guess) if tr.ocp.free_time else float(h)


def initial_guess(tr, kind) -> np.ndarray:
    """The vector w0 for ``kind`` ("linear", "simulation", "inverse" or an OcpSolution)."""
    if isinstance(kind, OcpSolution):
        return _warm(tr, kind)
    x_start, x_end = _states(tr, kind)
    T = _horizon(tr)
    if kind == "simulation":
        state = _simulated(tr, x_start, T)
    else:
        project = _projector(tr)
        memo: dict[float, np.ndarray] = {}

        def state(s):
            if s in memo:
                return memo[s]
            return project((1.0 - s) * x_start + s * x_end, tr.ocp.t_start + s * T)

        fractions = _fill_fractions(tr) if tr.nc else []
        if fractions:  # the states _fill asks for, projected in one call
            xs = np.array([(1.0 - f) * x_start + f * x_end for f in fractions])
            done, ok = _batch_projector(tr)(xs, tr.ocp.t_start + np.asarray(fractions) * T)
            memo.update((f, xk) for f, xk, good in zip(fractions, done, ok, strict=True)
                        if good)
    if kind == "inverse":
        controls, mults = _inverse(tr, state, T)
    else:
        controls = mults = None
    return _fill(tr, T, state, controls, mults, kind == "simulation")


def _point_fraction(tr, c: int, per: int | None = None) -> float:
    """Horizon fraction s of collocation point column ``c`` (element c // per, point
    c % per) of a block with ``per`` columns per element (default the degree d; the XC block
    of Radau collocation holds d − 1, its last point being the next mesh node)."""
    per = per or tr.ocp.degree
    taus = getattr(tr, "tau", [0.0])
    return (c // per + taus[c % per + 1]) / tr.M


def _fill_fractions(tr) -> list[float]:
    """The horizon fractions s at which :func:`_fill` evaluates the states: the mesh nodes
    e / M and the collocation points (:func:`_point_fraction`)."""
    out = [e / tr.M for e in range(tr.M + 1)]
    if "XC" in tr.b.names:
        cols = tr.b.shapes[tr.b.block("XC")][1]
        out += [_point_fraction(tr, c, tr.xc_columns) for c in range(cols)]
    return list(dict.fromkeys(out))


def _fill(tr, T, state, controls=None, mults=None, accelerations=False) -> np.ndarray:
    """w0 from x(s), u(s), λ(s) of the horizon fraction s (blocks of the transcription)."""
    nq, M, N = tr.nq, tr.M, tr.N
    blocks = []
    for name, (rows, cols), w0 in zip(tr.b.names, tr.b.shapes, tr.b.w0, strict=True):
        val = w0.reshape(cols, rows).copy()
        if name == "T":
            val[:] = T
        elif name == "X":
            for e in range(cols):
                val[e] = state(e / M)
        elif name == "XC":
            for c in range(cols):
                val[c] = state(_point_fraction(tr, c, tr.xc_columns))
        elif name == "U" and controls is not None:
            for k in range(cols):
                val[k] = controls((k + 0.5) / N)
        elif name == "LAM" and mults is not None and rows:
            for c in range(cols):
                val[c] = mults(_point_fraction(tr, c))
        elif name == "A" and accelerations and rows:
            for c in range(cols):
                s = _point_fraction(tr, c)
                ds = 1e-4
                lo, hi = max(s - ds, 0.0), min(s + ds, 1.0)
                val[c] = (state(hi)[nq:] - state(lo)[nq:]) / ((hi - lo) * T)
        blocks.append(val.ravel())
    return np.concatenate(blocks) if blocks else np.zeros(0)


def _simulated(tr, x_start, T):
    """x(s) of a forward simulation with zero inputs (linear interpolation between outputs)."""
    nq = tr.nq
    try:
        res = simulate(tr.system, t_end=tr.ocp.t_start + T, t_start=tr.ocp.t_start,
                       steps=4 * tr.N, rtol=1e-8)
    except CasmbdError as exc:
        raise AnalysisError(f"ocp guess 'simulation': the forward simulation failed: {exc}") \
            from None
    grid = (res.t - res.t[0]) / T
    xs = np.hstack([res["q"], res["v"]])
    xs[0, :] = x_start if len(x_start) == 2 * nq else xs[0, :]

    def state(s):
        return np.array([np.interp(s, grid, xs[:, i]) for i in range(2 * nq)])

    return state


def _inverse(tr, state, T):
    """u(s), λ(s) from [B  −C_qᵀ] [u; λ] = M q̈ − Q along the guessed path (least squares):
    gravity compensation for a linear path."""
    model = compile_model(tr.system, "dynamics", mode="vm")
    nq, nc = tr.nq, tr.nc
    samples = np.linspace(0.0, 1.0, 2 * tr.N + 1)
    us, lams = [], []
    ds = 1e-4
    for s in samples:
        x = state(s)
        q, v = x[:nq], x[nq:]
        a = (state(min(s + ds, 1.0))[nq:] - state(max(s - ds, 0.0))[nq:]) / (
            (min(s + ds, 1.0) - max(s - ds, 0.0)) * T)
        t = tr.ocp.t_start + s * T
        u0 = np.zeros(tr.nu)
        b = model.input_matrix(q, v, t, u0).toarray()
        rhs = (model.mass_matrix(q) @ a - model.applied_forces(q, v, t, u0)
               - model.quadratic_velocity_forces(q, v))
        mat = b if not nc else np.hstack([b, -model.constraint_jacobian(q, t).toarray().T])
        sol = np.linalg.lstsq(mat, rhs, rcond=None)[0]
        us.append(sol[:tr.nu])
        lams.append(sol[tr.nu:] if nc else np.zeros(0))
    us, lams = np.array(us), np.array(lams)

    def interp(arr):
        return lambda s: np.array([np.interp(s, samples, arr[:, i])
                                   for i in range(arr.shape[1])])

    return interp(us), interp(lams)


def _warm(tr, sol) -> np.ndarray:
    """A previous solution: its variables when the structure matches, else its states and
    controls interpolated onto the new mesh."""
    if (sol.w is not None and len(sol.w) == tr.b.nw and sol.names == tr.b.names):
        return np.array(sol.w, dtype=float)
    span = sol.t[-1] - sol.t[0]
    grid = (sol.t - sol.t[0]) / span
    xs = np.hstack([sol.q, sol.v])
    tc = (sol.control_times[:-1] + sol.control_times[1:]) / 2.0
    tc = (tc - sol.t[0]) / span

    def state(s):
        return np.array([np.interp(s, grid, xs[:, i]) for i in range(xs.shape[1])])

    def controls(s):
        return np.array([np.interp(s, tc, sol.u[:, i]) for i in range(sol.u.shape[1])])

    return _fill(tr, span, state, controls)
