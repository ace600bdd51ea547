"""Transcription of an :class:`~casmbd.ocp.problem.Ocp` into a nonlinear program.

The element equations come from the problem's registered transcription method
(:mod:`casmbd.ocp.methods`: direct collocation on Radau IIA or Gauss–Legendre points of degree
d on the implicit index-1 equations of motion with q̈ and λ as variables at every collocation
point, or multiple shooting with RK4 (exact Hessians) or CVODES (exact first-order
sensitivities, limited-memory Hessian)); this class adds what every method shares: the
variables, the position and velocity constraints at every mesh node with per-interval
projection multipliers μ, ν (:mod:`casmbd.ocp.dynamics`), the boundary conditions, the
objective and the solve.  Controls are piecewise constant on the N
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
from casmbd.compiled.build import compile_model
from casmbd.errors import AnalysisError, OptimizationError
from casmbd.ocp.dynamics import choose_dynamics, node_constraints, position_projection
from casmbd.ocp.flexible_mesh import mesh_check, solver_defaults
from casmbd.ocp.guess import initial_guess
from casmbd.ocp.methods import transcription_method
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
        #: position constraints (rows not written at the velocity level): C = 0 at the nodes
        #: and the size of the position projection μ
        self.nh = len(getattr(system, "holonomic_rows", range(system.nc)))
        self.p = ca.DM(system.parameter_values)
        self.N = ocp.intervals
        #: the registered method (casmbd.ocp.methods.TRANSCRIPTIONS): what it needs and builds
        self.method = transcription_method(ocp.transcription)
        self.S = self.method.elements_per_interval(ocp)
        self.M = self.N * self.S   # collocation elements (mesh intervals)
        # MX with the element (interval) equations mapped over the mesh: derivatives built once
        # per element function, compact generated code
        kind = ca.MX
        self.b = _Builder(kind)
        self.calls: list[MappedCall] = []   # mapped functions, for structured derivatives
        self.structured = True
        self._functions()
        self._variables()
        self.method.build(self)
        self._boundary()
        self._objective()
        self.mesh = self._mesh_check()
        self.build_seconds = time.perf_counter() - t0

    def _mesh_check(self) -> dict:
        """Flexible bodies: the fastest mode against the collocation element
        (:mod:`casmbd.ocp.flexible_mesh`; the threshold is measured for Radau, so a method that is
        not collocation, multiple shooting, is not checked: ``checks_mesh``)."""
        ocp = self.ocp
        if not self.method.checks_mesh:
            return {}
        horizon = ocp.horizon.guess if ocp.free_time else float(ocp.horizon)
        return mesh_check(self.system, horizon / self.M, self.S)

    # ------------------------------------------------------------------ pieces
    def _functions(self) -> None:
        ocp, system = self.ocp, self.system
        self.explicit, self.dynamics_choice, self.acc, self.res = choose_dynamics(
            system, ocp.dynamics, self.method.implicit)
        self.node = node_constraints(system)
        self.position_projection = position_projection(system)
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

    def mesh_time(self, k: int, tau: float = 0.0):
        """t₀ + (k + τ) h: the time of mesh node k (plus τ elements)."""
        return self.ocp.t_start + (k + tau) * self.h

    def _projection(self, q, mu, nu):
        """(C_qᵀ μ, C_qᵀ ν) at q (the node function needs t only through C_t: unused here)."""
        ct = self.node(q, ca.DM.zeros(self.nq), 0.0, self.p)[2]
        return ca.mtimes(self.position_projection(q, 0.0, self.p), mu), ca.mtimes(ct, nu)

    def add_mesh_nodes(self) -> None:
        """C = 0 and C_q q̇ + C_t = 0 at every mesh node, path constraints at the nodes (and at
        the control nodes), all mapped over the nodes.

        With Radau collocation the mesh node k + 1 is the last collocation point of element
        k (:class:`~casmbd.ocp.methods.DirectCollocation`), where the element already
        imposes the ``at="all"`` path constraints with the element's control: imposing them
        at the node again would repeat the same rows (linearly dependent constraints, which
        cost IPOPT hundreds of iterations on the UR5), so at the nodes they are imposed only
        where no element point covers them: the initial node, and the first node of each
        control interval when they depend on the control (whose value changes there)."""
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
                c, cdot = self.node(q, v, t, self.p)[:2]
                exprs += [c, cdot]
                lo.append(np.zeros(self.nh + self.nc))
                hi.append(np.zeros(self.nh + self.nc))
                labels += ["position constraint"] * self.nh + ["velocity constraint"] * self.nc
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
            ts = ca.horzcat(*[self.mesh_time(k) for k in nodes])
            vals = fnode.map(len(nodes))(xs, us, ts)
            block = self.b.ineq(vals, [f"{lab} at {what} {k}" for k in nodes for lab in labels],
                                np.tile(np.concatenate(lo), len(nodes)),
                                np.tile(np.concatenate(hi), len(nodes)))
            self.calls.append(MappedCall(fnode, len(nodes), [xs, us, ts], block, False))

    def _boundary(self) -> None:
        ocp, b, nq = self.ocp, self.b, self.nq
        x0, xn = self.X[0], self.X[self.M]
        u0, un = self.U[0], self.U[self.N - 1]
        t0, tn = self.mesh_time(0), self.mesh_time(self.M)
        if ocp._initial_given:
            rows = self._fix_states(self.initial_fn, self.initial_values, 0)
            if rows:  # conditions left as rows (the others are bounds)
                b.eq(self.initial_fn(x0[:nq], x0[nq:], t0, u0, self.p)[rows]
                     - self.initial_values[rows], "initial conditions")
        else:  # the scene's consistent initial state
            start = self._scene_start()
            b.lbw[self.X_block][:2 * nq] = start
            b.ubw[self.X_block][:2 * nq] = start
        if ocp._final:
            rows = self._fix_states(self.final_fn, self.final_values, self.M)
            if rows:
                b.eq(self.final_fn(xn[:nq], xn[nq:], tn, un, self.p)[rows]
                     - self.final_values[rows], "final conditions")

    def _fix_states(self, fn: ca.Function, values: np.ndarray, node: int) -> list[int]:
        """Boundary conditions that name one state, x_i(t_node) = value, stated as bounds
        lbw = ubw = value of that component of the mesh node (IPOPT then removes the variable:
        ``fixed_variable_treatment = make_parameter``) rather than as constraint rows — what
        ``detect_simple_bounds`` does for a hand-written NLP; without constraint equations
        only (with them a fixed coordinate can leave a node's C = 0 rows dependent).  Returns
        the rows left as constraints."""
        n = int(values.size)
        if self.nc or not n:
            return list(range(n))
        x = ca.SX.sym("x", 2 * self.nq)
        out = fn(x[:self.nq], x[self.nq:], ca.SX.sym("t"), ca.SX.sym("u", self.nu), self.p)
        b, block, fixed, left = self.b, self.X_block, set(), []
        for r in range(n):
            e = out[r]
            hit = [i for i in range(2 * self.nq) if ca.is_equal(e, x[i])] \
                if e.is_symbolic() else []
            if len(hit) != 1 or hit[0] in fixed:
                left.append(r)
                continue
            fixed.add(hit[0])
            k = node * 2 * self.nq + hit[0]
            b.lbw[block][k] = b.ubw[block][k] = float(values[r])
        return left

    def _scene_start(self) -> np.ndarray:
        model = compile_model(self.system, "dynamics", mode="vm")
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
        obj = obj + self.mayer_fn(x_n[:self.nq], x_n[self.nq:], self.mesh_time(self.M),
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
        sundials = self.method.quasi_newton(ocp)
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
                "degree": self.method.degree(ocp),
                "dynamics": "explicit" if self.explicit or not self.method.implicit
                else "implicit",
                "dynamics_choice": self.dynamics_choice,
                "solver": ocp.solver, "derivatives": used,
                "compiled": bool(report and report.mode == "compiled"),
                "compile_seconds": report.compile_seconds if report else 0.0,
                "cache_hit": bool(report and report.cache_hit),
                # CasADi's timers: IPOPT's own (t_proc_total minus the callbacks) and
                # each callback's (nlp_f, nlp_g, nlp_grad_f, nlp_jac_g, nlp_hess_l)
                "timings": {k: float(v) for k, v in stats.items()
                            if k.startswith(("t_proc_", "t_wall_", "n_call_"))},
                **self.mesh}
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

