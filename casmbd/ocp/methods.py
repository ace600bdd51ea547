"""Transcription methods of an optimal-control problem, registered by name.

A transcription method is one object, like rockit's ``MultipleShooting`` and
``DirectCollocation``: it says how many mesh elements a control interval holds, how many
points it costs (the size limit), whether the dynamics may stay implicit (q̈ and λ as NLP
variables), whether the flexible-body mesh check applies, whether its derivatives need the
quasi-Newton Hessian, and it writes the element equations of
:class:`~casmbd.ocp.transcription.Transcription` (:meth:`TranscriptionMethod.build`).  The
transcription asks its method and never branches on the name.

Registered here, so :data:`TRANSCRIPTIONS` is complete when this module is imported:

* ``radau``, ``legendre`` — :class:`DirectCollocation` on Radau IIA or Gauss–Legendre points of
  degree d (``ca.collocation_points``) with ``subintervals`` elements per control interval;
* ``multiple_shooting`` — :class:`MultipleShooting` with a registered shooting integrator
  (``casmbd.analysis.integrators``: RK4 with exact Hessians, CVODES with first-order
  sensitivities and a limited-memory Hessian).

How to add one: a subclass with ``name`` and :meth:`~TranscriptionMethod.build`, registered
with :func:`register_transcription` (``tests/architecture/test_custom_registries.py`` adds
trapezoidal collocation from ``examples/custom_transcription.py``).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.analysis.integrators import integrator_kind
from casmbd.errors import AnalysisError, ModelError
from casmbd.ocp.dynamics import explicit_accelerations
from casmbd.ocp.structured import MappedCall

__all__ = ["TRANSCRIPTIONS", "DirectCollocation", "MultipleShooting", "TranscriptionMethod",
           "register_transcription", "transcription_method"]


class TranscriptionMethod:
    """How a problem becomes an NLP; subclasses set :attr:`name` and :meth:`build`."""

    #: the name an :class:`~casmbd.ocp.problem.Ocp` and a scene's ``[ocp] transcription`` give
    name: str = ""
    #: the equations of motion may stay implicit (q̈, λ as NLP variables at the points) —
    #: collocation; False: explicit accelerations (shooting integrates an ODE)
    implicit: bool = True
    #: the flexible-body check of the mesh against the fastest mode
    #: (:func:`casmbd.ocp.flexible_mesh.mesh_check`, measured for collocation) applies
    checks_mesh: bool = True

    def elements_per_interval(self, ocp) -> int:
        """Mesh elements per control interval (the ``S`` of the transcription)."""
        return ocp.subintervals

    def points_per_interval(self, ocp) -> int:
        """Points per control interval counted by the size limit
        (:data:`casmbd.limits.MAX_OCP_UNKNOWNS`)."""
        return ocp.subintervals * (ocp.degree + 1)

    def degree(self, ocp) -> int | None:
        """The polynomial degree reported in the solution's statistics (None: none)."""
        return ocp.degree

    def quasi_newton(self, ocp) -> bool:
        """True when the element functions are MX (a SUNDIALS integrator): IPOPT then uses a
        limited-memory Hessian and the derivatives run in CasADi's virtual machine."""
        return False

    def build(self, tr) -> None:
        """Add the element equations, their variables and the mapped quadrature ``tr.quad``
        to the transcription ``tr`` (then the mesh-node constraints:
        ``tr.add_mesh_nodes()``)."""
        raise NotImplementedError


class DirectCollocation(TranscriptionMethod):
    """Direct collocation on the points ``scheme`` (``"radau"`` or ``"legendre"``) of degree
    d: Lagrange polynomials through τ₀ = 0 and the d points, h ẋ(τ_j) = Σ_r C_rj x_r at each
    point, continuity x_{k+1} = Σ_r D_r x_r, quadrature weights B_j (seed: Biegler,
    *Nonlinear Programming*, SIAM 2010, ch. 10)."""

    def __init__(self, scheme: str):
        self.name = self.scheme = scheme

    def build(self, tr) -> None:
        b, nq, nc, d = tr.b, tr.nq, tr.nc, tr.ocp.degree
        tau = [0.0, *ca.collocation_points(d, self.scheme)]
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
        tr.tau, tr.B = tau, B
        M, nu_ = tr.M, tr.nu
        # Radau IIA ends on τ_d = 1: with explicit dynamics the state at the last collocation
        # point is the next mesh node itself, not a separate variable, and the continuity rows
        # x_{k+1} = Σ D_r x_r vanish (2 nq M fewer variables and constraints; measured in
        # docs/ocp.md: cart-pole 26 → 15 ms). Not with the implicit form: exact as well, but
        # IPOPT's path on the UR5 then takes 258 iterations instead of 72.
        shared = (tr.explicit and self.scheme == "radau"
                  and abs(tau[d] - 1.0) < 1e-14)
        ncol = d - 1 if shared else d
        tr.shared = shared
        tr.xc_columns = ncol   # collocation states per element held in the XC block
        xcb, _ = b.var("XC", 2 * nq, ncol * M)
        na = 0 if tr.explicit else nq
        ab, _ = b.var("A", na, d * M)
        lamb, _ = b.var("LAM", nc, d * M)
        mub, _ = b.var("MU", tr.nh, M)
        nub, _ = b.var("NU", nc, M)
        slb, _ = b.var("SL", nu_ if tr.energy else 0, d * M, 0.0, np.inf)
        # one element, symbolically
        xk, xk1 = ca.SX.sym("xk", 2 * nq), ca.SX.sym("xk1", 2 * nq)
        xc, a_e = ca.SX.sym("xc", 2 * nq, ncol), ca.SX.sym("a", na, d)
        lam_e, mu, nu = ca.SX.sym("lam", nc, d), ca.SX.sym("mu", tr.nh), ca.SX.sym("nu", nc)
        sl = ca.SX.sym("sl", nu_ if tr.energy else 0, d)
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
        fn_all, lo_all, hi_all = tr.path_fns["all"]
        for j in range(1, d + 1):
            x, lam = xs[j], lam_e[:, j - 1]
            q, v = x[:nq], x[nq:]
            t = tk + tau[j] * h
            a = tr.acc(q, v, u, t, tr.p) if tr.explicit else a_e[:, j - 1]
            xp = sum(C[r, j] * xs[r] for r in range(d + 1))
            qdot, vdot = v, a
            if nc:
                ct = tr.node(q, ca.SX.zeros(nq), t, tr.p)[2]
                cht = tr.position_projection(q, t, tr.p)
                qdot, vdot = v + ca.mtimes(cht, mu), a + ca.mtimes(ct, nu)
            add(h * ca.vertcat(qdot, vdot) - xp, f"collocation point {j}")
            if not tr.explicit:
                dyn, acc = tr.res(q, v, a, lam, u, t, tr.p)
                add(dyn, f"equations of motion at point {j}")
                add(acc, f"acceleration constraints at point {j}")
            if fn_all.numel_out(0):
                add(fn_all(q, v, t, u, tr.p), f"path constraint at point {j}", lo_all, hi_all)
            quad += B[j] * h * tr.lagrange_fn(q, v, t, u, tr.p)
            if tr.energy:
                power = u * ca.mtimes(tr.input_matrix(q, v, t, u, tr.p).T, v)
                add(sl[:, j - 1] - power, f"energy slack + at point {j}", 0.0, np.inf)
                add(sl[:, j - 1] + power, f"energy slack - at point {j}", 0.0, np.inf)
                quad += tr.energy * B[j] * h * ca.sum1(sl[:, j - 1])
        if not shared:
            add(xk1 - sum(D[r] * xs[r] for r in range(d + 1)), "continuity")
        elem = ca.Function("ocp_element", [xk, xk1, xc, a_e, lam_e, mu, nu, sl, u, tk, h],
                           [ca.vertcat(*rows), quad])
        # all elements at once
        uel = ca.horzcat(*[tr.Ub[:, e // tr.S] for e in range(M)])
        tks = ca.horzcat(*[tr.mesh_time(e) for e in range(M)])
        el_args = [tr.Xb[:, :-1], tr.Xb[:, 1:], xcb, ab, lamb, mub, nub, slb, uel, tks,
                   tr.h]
        g_el, q_el = elem.map(M)(*el_args)
        n_el = len(labels)
        block = b.ineq(g_el, [f"element {e}: {lab}" for e in range(M) for lab in labels],
                       np.tile(np.concatenate(lo), M) if n_el else [],
                       np.tile(np.concatenate(hi), M) if n_el else [])
        tr.calls.append(MappedCall(elem, M, el_args, block, True))
        tr.quad = ca.sum2(q_el)
        tr.energy_terms = 0.0
        tr.add_mesh_nodes()


class MultipleShooting(TranscriptionMethod):
    """Multiple shooting: the registered shooting integrator over each control interval,
    continuity x_{k+1} = Φ(x_k, u_k) (plus the projection C_qᵀ μ, C_qᵀ ν)."""

    name = "multiple_shooting"
    implicit = False
    checks_mesh = False

    def elements_per_interval(self, ocp) -> int:
        return 1

    def points_per_interval(self, ocp) -> int:
        return ocp.steps

    def degree(self, ocp) -> int | None:
        return None

    def quasi_newton(self, ocp) -> bool:
        return not integrator_kind(ocp.integrator).fixed_step

    def build(self, tr) -> None:
        ocp, b, nq, nc, N = tr.ocp, tr.b, tr.nq, tr.nc, tr.N
        acc = explicit_accelerations(tr.system)
        x = ca.SX.sym("x", 2 * nq)
        u = ca.SX.sym("u", tr.nu)
        t = ca.SX.sym("t")
        ode = ca.vertcat(x[nq:], acc(x[:nq], x[nq:], u, t, tr.p))
        quad = tr.lagrange_fn(x[:nq], x[nq:], t, u, tr.p)
        f = ca.Function("ocp_ode", [x, u, t], [ode, quad])
        # the registered shooting integrator (casmbd.analysis.integrators.INTEGRATORS)
        step = integrator_kind(ocp.integrator).shooting_step(f, x, u, t, ocp.steps)
        mub, _ = b.var("MU", tr.nh, N)
        nub, _ = b.var("NU", nc, N)
        slb, _ = b.var("SL", tr.nu if tr.energy else 0, N, 0.0, np.inf)
        # one interval, mapped over all of them
        xk, xk1 = (ca.SX.sym("xk", 2 * nq), ca.SX.sym("xk1", 2 * nq)) \
            if step.is_a("SXFunction") else (step.mx_in(0), ca.MX.sym("xk1", 2 * nq))
        sym = type(xk)
        uk, tk, hk = sym.sym("u", tr.nu), sym.sym("t"), sym.sym("h")
        mu, nu = sym.sym("mu", tr.nh), sym.sym("nu", nc)
        sl = sym.sym("sl", tr.nu if tr.energy else 0)
        xend, qk = step(xk, uk, tk, hk)
        gap = xk1 - xend
        if nc:
            ct = tr.node(xk1[:nq], sym.zeros(nq), tk + hk, tr.p)[2]
            cht = tr.position_projection(xk1[:nq], tk + hk, tr.p)
            gap = gap - ca.vertcat(ca.mtimes(cht, mu), ca.mtimes(ct, nu))
        rows, lo, hi = [gap], [np.zeros(2 * nq)], [np.zeros(2 * nq)]
        labels = ["continuity"] * (2 * nq)
        if tr.energy:
            q, v = xk[:nq], xk[nq:]
            power = uk * ca.mtimes(tr.input_matrix(q, v, tk, uk, tr.p).T, v)
            rows += [sl - power, sl + power]
            lo += [np.zeros(tr.nu)] * 2
            hi += [np.full(tr.nu, np.inf)] * 2
            labels += ["energy slack +"] * tr.nu + ["energy slack -"] * tr.nu
            qk = qk + tr.energy * hk * ca.sum1(sl)
        interval = ca.Function("ocp_interval", [xk, xk1, uk, tk, hk, mu, nu, sl],
                               [ca.vertcat(*rows), qk])
        tks = ca.horzcat(*[tr.mesh_time(k) for k in range(N)])
        int_args = [tr.Xb[:, :-1], tr.Xb[:, 1:], tr.Ub, tks, tr.h, mub, nub, slb]
        g_int, q_int = interval.map(N)(*int_args)
        block = b.ineq(g_int, [f"interval {k}: {lab}" for k in range(N) for lab in labels],
                       np.tile(np.concatenate(lo), N), np.tile(np.concatenate(hi), N))
        if interval.is_a("SXFunction"):
            tr.calls.append(MappedCall(interval, N, int_args, block, True))
        else:  # an MX integrator (CVODES): no per-interval SX derivatives
            tr.structured = False
        tr.quad = ca.sum2(q_int)
        tr.energy_terms = 0.0
        tr.add_mesh_nodes()


#: name -> transcription method, in registration order (the first is the default)
TRANSCRIPTIONS: dict[str, TranscriptionMethod] = {}


def register_transcription(method: TranscriptionMethod, *,
                           replace: bool = False) -> TranscriptionMethod:
    """Register ``method`` under ``method.name`` (a :class:`ModelError` when the name is taken,
    unless ``replace``); returns it."""
    if not isinstance(method, TranscriptionMethod) or not method.name:
        raise ModelError(f"a transcription method is a named TranscriptionMethod, got "
                         f"{method!r}")
    if method.name in TRANSCRIPTIONS and not replace:
        raise ModelError(f"transcription '{method.name}' is already registered; pass "
                         "replace=True to replace it")
    TRANSCRIPTIONS[method.name] = method
    return method


def transcription_method(name: str) -> TranscriptionMethod:
    """The registered method ``name`` (an :class:`AnalysisError` listing the known ones)."""
    try:
        return TRANSCRIPTIONS[name]
    except (KeyError, TypeError):
        raise AnalysisError(f"ocp: unknown transcription '{name}' (known: "
                            f"{', '.join(TRANSCRIPTIONS)})") from None


for _method in (DirectCollocation("radau"), DirectCollocation("legendre"), MultipleShooting()):
    register_transcription(_method)
