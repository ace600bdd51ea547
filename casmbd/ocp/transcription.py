"""Transcription of an :class:`~casmbd.ocp.problem.Ocp` into a nonlinear program.

Direct collocation (Radau IIA or Gauss–Legendre points of degree d) on the implicit index-1
equations of motion with q̈ and λ as variables at every collocation point, the position and
velocity constraints imposed at every mesh node and per-interval projection multipliers μ, ν
(:mod:`casmbd.ocp.dynamics`); or multiple shooting with RK4 (exact Hessians) or CVODES (exact
first-order sensitivities, limited-memory Hessian).  Controls are piecewise constant on the N
intervals.  The NLP is built in MX from element and node functions mapped over the mesh
(:class:`~casmbd.ocp.structured.MappedCall`); its derivatives are assembled from per-element
SX derivatives (:mod:`casmbd.ocp.structured`) and it is solved by IPOPT (MUMPS) or any CasADi
NLP solver by name.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from casmbd import interrupts, progress
from casmbd.analysis.instant.kkt import consistent_state
from casmbd.analysis.integrators.kinds import integrator_kind
from casmbd.compiled.model import NumericModel
from casmbd.errors import AnalysisError, OptimizationError
from casmbd.ocp.dynamics import choose_dynamics, explicit_accelerations, node_constraints
from casmbd.ocp.flexible import mesh_check, solver_defaults
from casmbd.ocp.guess import initial_guess
from casmbd.ocp.options import check_solver_options
from casmbd.ocp.solution import OcpSolution
from casmbd.ocp.structured import MappedCall, check_mode, nlp_solver

IPOPT_DEFAULTS = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                  "ipopt.max_iter": 3000}


class _IterationBar(ca.Callback):
    """IPOPT's iteration callback: one progress-bar step per iteration, with the objective
    (see :mod:`casmbd.progress`; only built when bars are shown)."""

    def __init__(self, nx: int, ng: int, bar):
        ca.Callback.__init__(self)
        self.nx, self.ng, self.bar = nx, ng, bar
        self.construct("casmbd_ocp_progress", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        self.bar.update(1)
        if hasattr(self.bar, "set_postfix_str"):
            self.bar.set_postfix_str(f"objective {float(arg[1]):.6g}", refresh=False)
        return [0]


class _Builder:
    """Decision variables (matrix blocks, stacked column by column) and constraints with
    bounds, guesses and labels."""

    def __init__(self, kind):
        self.kind = kind
        self.w, self.lbw, self.ubw, self.w0, self.wlabels = [], [], [], [], []
        self.names: list[str] = []
        self.shapes: list[tuple[int, int]] = []
        self.g, self.lbg, self.ubg, self.glabels = [], [], [], []
        self.nw = 0

    def var(self, name: str, rows: int, cols: int = 1, lower=-np.inf, upper=np.inf,
            guess=0.0):
        """A block of rows × cols variables; ``lower``/``upper`` broadcast over rows."""
        sym = self.kind.sym(name, rows, cols)
        n = rows * cols
        self.w.append(sym)
        self.names.append(name)
        self.shapes.append((rows, cols))

        def fill(value):
            col = np.broadcast_to(np.asarray(value, float), (rows,))
            return np.tile(col, cols)

        self.lbw.append(fill(lower))
        self.ubw.append(fill(upper))
        self.w0.append(fill(guess))
        self.wlabels += [f"{name}[{i % rows},{i // rows}]" for i in range(n)]
        self.nw += n
        return sym, len(self.w) - 1

    def block(self, name: str) -> int:
        return self.names.index(name)

    def eq(self, expr, label, value=0.0):
        self.ineq(expr, label, value, value)

    def ineq(self, expr, label, lower, upper):
        """Constraints; ``label`` is a string or a list with one label per row."""
        expr = ca.vec(expr)
        n = expr.numel()
        if n == 0:
            return None
        self.g.append(expr)
        self.lbg.append(np.broadcast_to(np.asarray(lower, float), (n,)).copy())
        self.ubg.append(np.broadcast_to(np.asarray(upper, float), (n,)).copy())
        if isinstance(label, list):
            self.glabels += label
        else:
            self.glabels += [label if n == 1 else f"{label}[{i}]" for i in range(n)]
        return len(self.g) - 1


class Transcription:
    """The NLP of one problem; :meth:`solve` returns an OcpSolution."""

    def __init__(self, ocp):
        t0 = time.perf_counter()
        self.ocp = ocp
        system = ocp.system
        self.system = system
        self.nq, self.nc, self.nu = system.nq, system.nc, len(ocp.controls)
        self.p = ca.DM(system.parameter_values)
        self.N = ocp.intervals
        shooting_ = ocp.transcription == "multiple_shooting"
        self.S = 1 if shooting_ else ocp.subintervals
        self.M = self.N * self.S   # collocation elements (mesh intervals)
        shooting = ocp.transcription == "multiple_shooting"
        # MX with the element (interval) equations mapped over the mesh: derivatives built once
        # per element function, compact generated code
        kind = ca.MX
        self.b = _Builder(kind)
        self.calls: list[MappedCall] = []   # mapped functions, for structured derivatives
        self.structured = True
        self._functions()
        self._variables()
        if shooting:
            self._shooting()
        else:
            self._collocation()
        self._boundary()
        self._objective()
        self.mesh = self._mesh_check()
        self.build_seconds = time.perf_counter() - t0

    def _mesh_check(self) -> dict:
        """Flexible bodies: the fastest mode against the collocation element
        (:mod:`casmbd.ocp.flexible`; the threshold is measured for Radau, so multiple shooting
        is not checked)."""
        ocp = self.ocp
        if ocp.transcription == "multiple_shooting":
            return {}
        horizon = ocp.horizon.guess if ocp.free_time else float(ocp.horizon)
        return mesh_check(self.system, horizon / self.M, self.S)

    # ------------------------------------------------------------------ pieces
    def _functions(self) -> None:
        ocp, system = self.ocp, self.system
        self.explicit, self.dynamics_choice, self.acc, self.res = choose_dynamics(
            system, ocp.dynamics, ocp.transcription != "multiple_shooting")
        self.node = node_constraints(system)
        args = [system.q, system.v, system.t, system.u, system.p]
        self.args = args
        self.input_matrix = ca.Function("ocp_b", args, [system.input_matrix])

        def scalar_fn(name, exprs):
            return ca.Function(name, args, [ca.vertcat(*exprs) if exprs else ca.SX(0, 1)])

        self.path_fns = {}
        for at in ("all", "nodes", "control_nodes"):
            items = [c for c in ocp._path if c.at == at]
            self.path_fns[at] = (scalar_fn(f"ocp_path_{at}",
                                           [ocp.expression(c.expression, "path")
                                            for c in items]),
                                 np.array([c.lower for c in items]),
                                 np.array([c.upper for c in items]))
        self.initial_fn = scalar_fn("ocp_initial", [ocp.expression(k, f"initial '{k}'")
                                                    for k in ocp._initial])
        self.initial_values = np.array([float(ocp.expression(v, f"initial '{k}'"))
                                        for k, v in ocp._initial.items()])
        self.final_fn = scalar_fn("ocp_final", [ocp.expression(k, f"final '{k}'")
                                                for k in ocp._final])
        self.final_values = np.array([float(ocp.expression(v, f"final '{k}'"))
                                      for k, v in ocp._final.items()])
        lagrange = []
        for term in ocp._terms:
            if term.kind == "lagrange":
                lagrange.append(term.weight * ocp.expression(term.expression, "lagrange"))
            elif term.kind == "tracking":
                ref = ocp.expression(term.reference if term.reference is not None else 0.0,
                                     "tracking reference")
                diff = ocp.expression(term.expression, "tracking") - ref
                lagrange.append(term.weight * diff * diff)
        self.lagrange_fn = ca.Function("ocp_lagrange", args,
                                       [ca.sum1(ca.vertcat(*lagrange)) if lagrange else 0.0])
        mayer = [term.weight * ocp.expression(term.expression, "mayer")
                 for term in ocp._terms if term.kind == "mayer"]
        self.mayer_fn = ca.Function("ocp_mayer", args,
                                    [ca.sum1(ca.vertcat(*mayer)) if mayer else 0.0])
        self.energy = sum(term.weight for term in ocp._terms if term.kind == "energy")
        self.effort = sum(term.weight for term in ocp._terms if term.kind == "effort")
        self.time_weight = sum(term.weight for term in ocp._terms if term.kind == "time")
        if not ocp._terms:
            raise AnalysisError("ocp: no objective; call minimize('effort' | 'time' | …)")

    def _variables(self) -> None:
        ocp, b, nq, nu, N = self.ocp, self.b, self.nq, self.nu, self.N
        if ocp.free_time:
            h = ocp.horizon
            self.T, self.T_block = b.var("T", 1, 1, h.lower, h.upper, h.guess)
        else:
            self.T, self.T_block = ca.DM(float(ocp.horizon)), None
        self.h = self.T / self.M   # element length
        lo_u = np.array([ocp._control_bounds.get(c, (-np.inf, np.inf))[0]
                         for c in ocp.controls])
        up_u = np.array([ocp._control_bounds.get(c, (-np.inf, np.inf))[1]
                         for c in ocp.controls])
        self.Ub, self.U_block = b.var("U", nu, N, lo_u, up_u)
        self.Xb, self.X_block = b.var("X", 2 * nq, self.M + 1)
        self.X = [self.Xb[:, e] for e in range(self.M + 1)]
        self.U = [self.Ub[:, k] for k in range(N)]

    def _t(self, k: int, tau: float = 0.0):
        return self.ocp.t_start + (k + tau) * self.h

    def _projection(self, q, mu, nu):
        """(C_qᵀ μ, C_qᵀ ν) at q (the node function needs t only through C_t: unused here)."""
        ct = self.node(q, ca.DM.zeros(self.nq), 0.0, self.p)[2]
        return ca.mtimes(ct, mu), ca.mtimes(ct, nu)

    def _collocation(self) -> None:
        ocp, b, nq, nc, d = self.ocp, self.b, self.nq, self.nc, self.ocp.degree
        tau = [0.0, *ca.collocation_points(d, ocp.transcription)]
        C = np.zeros((d + 1, d + 1))
        D = np.zeros(d + 1)
        B = np.zeros(d + 1)
        for j in range(d + 1):
            coeff = np.poly1d([1.0])
            for r in range(d + 1):
                if r != j:
                    coeff *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
            D[j] = coeff(1.0)
            deriv = np.polyder(coeff)
            for r in range(d + 1):
                C[j, r] = deriv(tau[r])
            B[j] = np.polyint(coeff)(1.0)
        self.tau, self.B = tau, B
        M, nu_ = self.M, self.nu
        # Radau IIA ends on τ_d = 1: with explicit dynamics the state at the last collocation
        # point is the next mesh node itself, not a separate variable, and the continuity rows
        # x_{k+1} = Σ D_r x_r vanish (2 nq M fewer variables and constraints; measured in
        # docs/ocp.md: cart-pole 26 → 15 ms). Not with the implicit form: exact as well, but
        # IPOPT's path on the UR5 then takes 258 iterations instead of 72.
        shared = (self.explicit and ocp.transcription == "radau"
                  and abs(tau[d] - 1.0) < 1e-14)
        ncol = d - 1 if shared else d
        self.shared = shared
        self.xc_columns = ncol   # collocation states per element held in the XC block
        xcb, _ = b.var("XC", 2 * nq, ncol * M)
        na = 0 if self.explicit else nq
        ab, _ = b.var("A", na, d * M)
        lamb, _ = b.var("LAM", nc, d * M)
        mub, _ = b.var("MU", nc, M)
        nub, _ = b.var("NU", nc, M)
        slb, _ = b.var("SL", nu_ if self.energy else 0, d * M, 0.0, np.inf)
        # one element, symbolically
        xk, xk1 = ca.SX.sym("xk", 2 * nq), ca.SX.sym("xk1", 2 * nq)
        xc, a_e = ca.SX.sym("xc", 2 * nq, ncol), ca.SX.sym("a", na, d)
        lam_e, mu, nu = ca.SX.sym("lam", nc, d), ca.SX.sym("mu", nc), ca.SX.sym("nu", nc)
        sl = ca.SX.sym("sl", nu_ if self.energy else 0, d)
        u, tk, h = ca.SX.sym("u", nu_), ca.SX.sym("tk"), ca.SX.sym("h")
        rows, lo, hi, labels = [], [], [], []

        def add(expr, label, lower=0.0, upper=0.0):
            expr = ca.vec(expr)
            n = expr.numel()
            if n:
                rows.append(expr)
                lo.append(np.broadcast_to(np.asarray(lower, float), (n,)))
                hi.append(np.broadcast_to(np.asarray(upper, float), (n,)))
                labels.extend([label] * n)

        xs = [xk] + [xc[:, j] for j in range(ncol)] + ([xk1] if shared else [])
        quad = 0.0
        fn_all, lo_all, hi_all = self.path_fns["all"]
        for j in range(1, d + 1):
            x, lam = xs[j], lam_e[:, j - 1]
            q, v = x[:nq], x[nq:]
            t = tk + tau[j] * h
            a = self.acc(q, v, u, t, self.p) if self.explicit else a_e[:, j - 1]
            xp = sum(C[r, j] * xs[r] for r in range(d + 1))
            qdot, vdot = v, a
            if nc:
                ct = self.node(q, ca.SX.zeros(nq), t, self.p)[2]
                qdot, vdot = v + ca.mtimes(ct, mu), a + ca.mtimes(ct, nu)
            add(h * ca.vertcat(qdot, vdot) - xp, f"collocation point {j}")
            if not self.explicit:
                dyn, acc = self.res(q, v, a, lam, u, t, self.p)
                add(dyn, f"equations of motion at point {j}")
                add(acc, f"acceleration constraints at point {j}")
            if fn_all.numel_out(0):
                add(fn_all(q, v, t, u, self.p), f"path constraint at point {j}", lo_all, hi_all)
            quad += B[j] * h * self.lagrange_fn(q, v, t, u, self.p)
            if self.energy:
                power = u * ca.mtimes(self.input_matrix(q, v, t, u, self.p).T, v)
                add(sl[:, j - 1] - power, f"energy slack + at point {j}", 0.0, np.inf)
                add(sl[:, j - 1] + power, f"energy slack - at point {j}", 0.0, np.inf)
                quad += self.energy * B[j] * h * ca.sum1(sl[:, j - 1])
        if not shared:
            add(xk1 - sum(D[r] * xs[r] for r in range(d + 1)), "continuity")
        elem = ca.Function("ocp_element", [xk, xk1, xc, a_e, lam_e, mu, nu, sl, u, tk, h],
                           [ca.vertcat(*rows), quad])
        # all elements at once
        uel = ca.horzcat(*[self.Ub[:, e // self.S] for e in range(M)])
        tks = ca.horzcat(*[self._t(e) for e in range(M)])
        el_args = [self.Xb[:, :-1], self.Xb[:, 1:], xcb, ab, lamb, mub, nub, slb, uel, tks,
                   self.h]
        g_el, q_el = elem.map(M)(*el_args)
        n_el = len(labels)
        block = b.ineq(g_el, [f"element {e}: {lab}" for e in range(M) for lab in labels],
                       np.tile(np.concatenate(lo), M) if n_el else [],
                       np.tile(np.concatenate(hi), M) if n_el else [])
        self.calls.append(MappedCall(elem, M, el_args, block, True))
        self.quad = ca.sum2(q_el)
        self.energy_terms = 0.0
        self._nodes()

    def _nodes(self) -> None:
        """C = 0 and C_q q̇ + C_t = 0 at every mesh node, path constraints at the nodes (and at
        the control nodes), all mapped over the nodes.

        With Radau collocation the mesh node k + 1 is the last collocation point of element k
        (:meth:`_collocation`), where the element already imposes the ``at="all"`` path
        constraints with the element's control: imposing them at the node again would repeat
        the same rows (linearly dependent constraints, which cost IPOPT hundreds of iterations
        on the UR5), so at the nodes they are imposed only where no element point covers
        them: the initial node, and the first node of each control interval when they depend
        on the control (whose value changes there)."""
        nq, M, S = self.nq, self.M, self.S
        first = 0 if self.ocp._initial_given else 1  # a fixed consistent start needs none
        x, u, t = ca.SX.sym("x", 2 * nq), ca.SX.sym("u", self.nu), ca.SX.sym("t")
        q, v = x[:nq], x[nq:]
        groups = [(("nodes", "all"), range(first, M + 1), "node"),
                  (("control_nodes",), range(first * S, M + 1, S), "control node")]
        fn_all = self.path_fns["all"][0]
        if getattr(self, "shared", False) and fn_all.numel_out(0):
            on_u = ca.depends_on(fn_all(q, v, t, u, self.p), u)
            groups[0:1] = [(("nodes",), range(first, M + 1), "node"),
                           (("all",), [k for k in range(first, M + 1)
                                       if k == 0 or (on_u and k % S == 0 and k < M)], "node")]
        for kinds, nodes, what in groups:
            exprs, lo, hi, labels = [], [], [], []
            if "nodes" in kinds and self.nc:
                c, cdot, _ = self.node(q, v, t, self.p)
                exprs += [c, cdot]
                lo.append(np.zeros(2 * self.nc))
                hi.append(np.zeros(2 * self.nc))
                labels += ["position constraint"] * self.nc + ["velocity constraint"] * self.nc
            for kind in kinds:
                fn, plo, phi = self.path_fns[kind]
                if fn.numel_out(0):
                    exprs.append(fn(q, v, t, u, self.p))
                    lo.append(plo)
                    hi.append(phi)
                    labels += ["path constraint"] * len(plo)
            nodes = list(nodes)
            if not exprs or not nodes:
                continue
            fnode = ca.Function(f"ocp_{what.replace(' ', '_')}", [x, u, t], [ca.vertcat(*exprs)])
            xs = ca.horzcat(*[self.X[k] for k in nodes])
            us = ca.horzcat(*[self.U[min(k // S, self.N - 1)] for k in nodes])
            ts = ca.horzcat(*[self._t(k) for k in nodes])
            vals = fnode.map(len(nodes))(xs, us, ts)
            block = self.b.ineq(vals, [f"{lab} at {what} {k}" for k in nodes for lab in labels],
                                np.tile(np.concatenate(lo), len(nodes)),
                                np.tile(np.concatenate(hi), len(nodes)))
            self.calls.append(MappedCall(fnode, len(nodes), [xs, us, ts], block, False))

    def _shooting(self) -> None:
        ocp, b, nq, nc, N = self.ocp, self.b, self.nq, self.nc, self.N
        acc = explicit_accelerations(self.system)
        x = ca.SX.sym("x", 2 * nq)
        u = ca.SX.sym("u", self.nu)
        t = ca.SX.sym("t")
        ode = ca.vertcat(x[nq:], acc(x[:nq], x[nq:], u, t, self.p))
        quad = self.lagrange_fn(x[:nq], x[nq:], t, u, self.p)
        f = ca.Function("ocp_ode", [x, u, t], [ode, quad])
        # the registered shooting integrator (casmbd.analysis.integrators.kinds.INTEGRATORS)
        step = integrator_kind(ocp.integrator).shooting_step(f, x, u, t, ocp.steps)
        mub, _ = b.var("MU", nc, N)
        nub, _ = b.var("NU", nc, N)
        slb, _ = b.var("SL", self.nu if self.energy else 0, N, 0.0, np.inf)
        # one interval, mapped over all of them
        xk, xk1 = (ca.SX.sym("xk", 2 * nq), ca.SX.sym("xk1", 2 * nq)) \
            if step.is_a("SXFunction") else (step.mx_in(0), ca.MX.sym("xk1", 2 * nq))
        sym = type(xk)
        uk, tk, hk = sym.sym("u", self.nu), sym.sym("t"), sym.sym("h")
        mu, nu = sym.sym("mu", nc), sym.sym("nu", nc)
        sl = sym.sym("sl", self.nu if self.energy else 0)
        xend, qk = step(xk, uk, tk, hk)
        gap = xk1 - xend
        if nc:
            ct = self.node(xk1[:nq], sym.zeros(nq), tk + hk, self.p)[2]
            gap = gap - ca.vertcat(ca.mtimes(ct, mu), ca.mtimes(ct, nu))
        rows, lo, hi = [gap], [np.zeros(2 * nq)], [np.zeros(2 * nq)]
        labels = ["continuity"] * (2 * nq)
        if self.energy:
            q, v = xk[:nq], xk[nq:]
            power = uk * ca.mtimes(self.input_matrix(q, v, tk, uk, self.p).T, v)
            rows += [sl - power, sl + power]
            lo += [np.zeros(self.nu)] * 2
            hi += [np.full(self.nu, np.inf)] * 2
            labels += ["energy slack +"] * self.nu + ["energy slack -"] * self.nu
            qk = qk + self.energy * hk * ca.sum1(sl)
        interval = ca.Function("ocp_interval", [xk, xk1, uk, tk, hk, mu, nu, sl],
                               [ca.vertcat(*rows), qk])
        tks = ca.horzcat(*[self._t(k) for k in range(N)])
        int_args = [self.Xb[:, :-1], self.Xb[:, 1:], self.Ub, tks, self.h, mub, nub, slb]
        g_int, q_int = interval.map(N)(*int_args)
        block = b.ineq(g_int, [f"interval {k}: {lab}" for k in range(N) for lab in labels],
                       np.tile(np.concatenate(lo), N), np.tile(np.concatenate(hi), N))
        if interval.is_a("SXFunction"):
            self.calls.append(MappedCall(interval, N, int_args, block, True))
        else:  # an MX integrator (CVODES): no per-interval SX derivatives
            self.structured = False
        self.quad = ca.sum2(q_int)
        self.energy_terms = 0.0
        self._nodes()

    def _boundary(self) -> None:
        ocp, b, nq = self.ocp, self.b, self.nq
        x0, xn = self.X[0], self.X[self.M]
        u0, un = self.U[0], self.U[self.N - 1]
        t0, tn = self._t(0), self._t(self.M)
        if ocp._initial_given:
            b.eq(self.initial_fn(x0[:nq], x0[nq:], t0, u0, self.p) - self.initial_values,
                 "initial conditions")
        else:  # the scene's consistent initial state
            start = self._scene_start()
            b.lbw[self.X_block][:2 * nq] = start
            b.ubw[self.X_block][:2 * nq] = start
        if ocp._final:
            b.eq(self.final_fn(xn[:nq], xn[nq:], tn, un, self.p) - self.final_values,
                 "final conditions")

    def _scene_start(self) -> np.ndarray:
        model = NumericModel(self.system, "dynamics", mode="vm")
        st = consistent_state(model, self.system.initial_coordinates(),
                              self.system.initial_velocities(), self.ocp.t_start,
                              np.zeros(self.nu))
        return np.concatenate([st.q, st.v])

    def _objective(self) -> None:
        x_n = self.X[self.M]
        obj = self.energy_terms
        if self.effort:
            obj = obj + self.effort * self.h * self.S * ca.sumsqr(self.Ub)
        if self.time_weight:
            obj = obj + self.time_weight * self.T
        obj = obj + self.mayer_fn(x_n[:self.nq], x_n[self.nq:], self._t(self.M),
                                  self.U[self.N - 1], self.p)
        self.objective_rest = obj   # all but the mapped quadratures
        self.objective = self.quad + obj

    # ------------------------------------------------------------------ solve
    def solve(self, guess=None, options: dict | None = None, raise_on_failure: bool = True):
        """Solve the NLP; see :meth:`casmbd.ocp.problem.Ocp.solve`."""
        ocp, b = self.ocp, self.b
        t0 = time.perf_counter()
        w = ca.vertcat(*[ca.vec(x) for x in b.w])
        opts = dict(IPOPT_DEFAULTS) if ocp.solver == "ipopt" else {}
        opts.update(solver_defaults(self.system, ocp.solver))  # flexible bodies: pivoting
        sundials = (ocp.transcription == "multiple_shooting"
                    and not integrator_kind(ocp.integrator).fixed_step)
        if ocp.solver == "ipopt" and sundials:
            # second-order sensitivities of CVODES are costly: quasi-Newton Hessian
            opts["ipopt.hessian_approximation"] = "limited-memory"
        # checked again: the attribute may have changed since the Ocp was built
        opts.update(check_solver_options(ocp.solver, ocp.solver_options))
        opts.update(options or {})  # trusted Python callers only (see casmbd.ocp.options)
        bar = None
        if ocp.solver == "ipopt" and "iteration_callback" not in opts and progress.enabled():
            bar = progress.bar(None, f"ocp {ocp.system.mechanism.name}: IPOPT", unit="iter")
            opts["iteration_callback"] = _IterationBar(w.numel(), len(b.glabels), bar)
        if sundials:  # an MX integrator: CasADi's derivatives in the virtual machine
            mode = "vm"
        else:
            mode = check_mode(ocp.compile)
        try:
            solver, report, used = nlp_solver("casmbd_ocp", ocp.solver, w, self.objective,
                                              self.objective_rest, b.g, self.calls, opts,
                                              mode, self.structured)
        except ValueError:  # arguments not affine in the variables: no per-element structure
            solver, report, used = nlp_solver("casmbd_ocp", ocp.solver, w, self.objective,
                                              self.objective_rest, b.g, self.calls, opts,
                                              "vm")
        setup = time.perf_counter() - t0
        w0 = initial_guess(self, guess if guess is not None else ocp._guess)
        lbw, ubw = np.concatenate(b.lbw), np.concatenate(b.ubw)
        w0 = np.clip(w0, lbw, ubw)
        t1, cpu1 = time.perf_counter(), time.process_time()
        try:
            # Ctrl-C inside IPOPT ends as a solver status, not an exception: raise it (no
            # OptimizationError carrying the last iterate, nothing saved)
            with interrupts.watching():
                out = solver(x0=w0, lbx=lbw, ubx=ubw, lbg=np.concatenate(b.lbg),
                             ubg=np.concatenate(b.ubg))
                interrupts.check()
        except RuntimeError as exc:
            interrupts.reraise_interrupt(exc)
            raise
        finally:
            if bar is not None:
                bar.close()
        wall, cpu = time.perf_counter() - t1, time.process_time() - cpu1
        stats = solver.stats()
        x = np.asarray(out["x"]).ravel()
        gval = np.asarray(out["g"]).ravel()
        lbg, ubg = np.concatenate(b.lbg), np.concatenate(b.ubg)
        viol = np.maximum(np.maximum(lbg - gval, gval - ubg), 0.0)
        info = {"success": bool(stats.get("success", False)),
                "return_status": stats.get("return_status", stats.get("unified_return_status")),
                "iterations": int(stats.get("iter_count", -1)),
                "objective": float(out["f"]),
                "constraint_violation": float(np.max(viol, initial=0.0)),
                "solve_seconds": wall, "solve_cpu_seconds": cpu,
                "setup_seconds": setup + self.build_seconds,
                "build_seconds": self.build_seconds, "nlp_setup_seconds": setup,
                "variables": int(w.numel()), "constraints": len(b.glabels),
                "transcription": ocp.transcription, "intervals": self.N,
                "subintervals": self.S,
                "degree": ocp.degree if ocp.transcription != "multiple_shooting" else None,
                "dynamics": "explicit" if self.explicit or ocp.transcription
                == "multiple_shooting" else "implicit",
                "dynamics_choice": self.dynamics_choice,
                "solver": ocp.solver, "derivatives": used,
                "compiled": bool(report and report.mode == "compiled"),
                "compile_seconds": report.compile_seconds if report else 0.0,
                "cache_hit": bool(report and report.cache_hit), **self.mesh}
        sol = OcpSolution.from_transcription(self, x, info, np.asarray(out["lam_g"]).ravel(),
                                             gval)
        if not info["success"] and raise_on_failure:
            raise OptimizationError(self._failure_text(info, x, gval, viol), sol)
        return sol

    def _failure_text(self, info, x, gval, viol) -> str:
        b = self.b
        order = np.argsort(-viol)[:4]
        worst = "; ".join(f"{b.glabels[i]} (violation {viol[i]:.3g})" for i in order
                          if viol[i] > 1e-9)
        lbw, ubw = np.concatenate(b.lbw), np.concatenate(b.ubw)
        active: dict[str, int] = {}
        for i in np.flatnonzero((np.abs(x - lbw) < 1e-7 * (1 + np.abs(lbw)))
                                | (np.abs(x - ubw) < 1e-7 * (1 + np.abs(ubw)))):
            label = b.wlabels[i]
            if label.startswith("U["):
                name = self.ocp.controls[int(label[2:].split(",")[0])]
                active[f"actuator '{name}'"] = active.get(f"actuator '{name}'", 0) + 1
            elif label.startswith("T["):
                active["final time"] = 1
        binding = ", ".join(f"{k} at its bound in {n} of {self.N} intervals"
                            if k != "final time" else "final time at its bound"
                            for k, n in active.items())
        return (f"ocp: {self.ocp.solver} returned '{info['return_status']}' after "
                f"{info['iterations']} iterations (max constraint violation "
                f"{info['constraint_violation']:.3g})"
                + (f"; most violated: {worst}" if worst else "")
                + (f"; binding bounds: {binding}" if binding else ""))

