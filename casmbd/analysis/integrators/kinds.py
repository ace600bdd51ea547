"""Integrator kinds: the base :class:`IntegratorKind`, the registry :data:`INTEGRATORS` and
the helpers the families share.

Every integrator is built once for a uniform output interval ``h`` on shifted time τ = t − t_k:
the dynamics receive the interval start t_k as an extra parameter (:func:`shifted`), so the
same object integrates any interval (used by projection and by the error path that keeps
partial results).  Compiled step sequences are folds of a step (:func:`fixed_fold`) called on
arrays bound once (:class:`~casmbd.compiled.buffered.BufferedFunction`).

Each integrator is an :class:`IntegratorKind` in the registry :data:`INTEGRATORS` (name ->
kind, like scipy's ``solve_ivp`` ``METHODS``): what it integrates (ODE, DAE, numeric right-hand
sides), whether its step is fixed, whether it serves the optimal-control problem's multiple
shooting, and how it is built.  Simulation, the OCP and the CLI's ``--integrator`` choices read
the registry; :func:`integrator_kind` raises :class:`~casmbd.errors.UnknownMethodError` for a
name that is not in it.  The families live in modules of their own —
:mod:`~casmbd.analysis.integrators.sundials` (``idas``, ``cvodes``, ``adams``),
:mod:`~casmbd.analysis.integrators.fixed_step` (``rk4``, ``abm``) and
:mod:`~casmbd.analysis.integrators.dopri` (``dopri5``) — which build on this module; the
package :mod:`casmbd.analysis.integrators` registers their kinds, so the registry is complete
whenever any module of the package is imported.  Adding an integrator = one
:func:`register_integrator` call there.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from casmbd.analysis.integrators.invariants import check_energy_blowup
from casmbd.errors import ModelError, UnknownMethodError
from casmbd.model.needs import ALL_NEEDS, EVENT_NEEDS


def shifted(dyn: ca.Function) -> ca.Function:
    """g(τ, x, z, [p; t_k], u) = f(τ + t_k, x, z, p, u)."""
    tau = ca.MX.sym("t")
    x = ca.MX.sym("x", dyn.sparsity_in("x"))
    z = ca.MX.sym("z", dyn.sparsity_in("z"))
    p = ca.MX.sym("p", dyn.size1_in("p") + 1)
    u = ca.MX.sym("u", dyn.sparsity_in("u"))
    out = dyn(t=tau + p[-1], x=x, z=z, p=p[:-1], u=u)
    return ca.Function("shifted", [tau, x, z, p, u], [out["ode"], out["alg"], out["quad"],
                                                      out["zero"]],
                       ca.dyn_in(), ca.dyn_out())



def fixed_fold(step: ca.Function, count: int, name: str) -> ca.Function:
    """``name(s, p, h) -> s_next``: ``count`` steps of ``step(s, p, h)`` in one call.

    ``step.fold(count)`` (a loop in the generated code) with ``p`` and ``h`` (the step size,
    or any column of step controls) given once and repeated inside, so that the inputs are
    single columns bound once to numpy arrays.
    """
    s, p, h = ca.MX.sym("s", step.size1_in(0)), ca.MX.sym("p", step.sparsity_in(1)), \
        ca.MX.sym("h", step.sparsity_in(2))  # a column of step controls (DOPRI5) or h
    out = step.fold(count)(s, ca.repmat(p, 1, count), ca.repmat(h, 1, count))
    return ca.Function(name, [s, p, h], [out], ["s", "p", "h"], ["s_next"])


# ---------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class IntegratorKind:
    """What an integrator integrates and how it is used (one entry of :data:`INTEGRATORS`).

    Attributes
    ----------
    name : str
        The name users give (``--integrator``, ``simulate(integrator=...)``, ``[ocp]``).
    label : str
        The method in a few words, for messages ("BDF", "RK4").
    ode, dae, numeric : bool
        Integrates ODE formulations; semi-explicit DAEs (index 1 or GGL index 2); numeric
        right-hand sides (a :class:`casadi.Callback`, forward evaluations only).
    fixed_step : bool
        A fixed-step method run by
        :class:`~casmbd.analysis.integrators.fixed_step.FixedStep` (no tolerances; ``--step``).
    shooting : bool
        Serves the optimal-control problem's multiple shooting (:meth:`shooting_step`).
    stiff_alternative : str or None
        The integrator taken instead when none is named and the ODE is stiff (Adams -> BDF).
    compiled : bool
        An adaptive method whose steps run in compiled blocks (``runner(dyn, mode, name)``,
        :class:`casmbd.analysis.integrators.dopri.Dopri`).
    model_function_names : tuple of str
        Names of the Functions of :meth:`model_functions` (compiled with the model).
    writes_messages : bool
        The solver may write diagnostics to stderr (SUNDIALS), which a run captures
        (:class:`~casmbd.analysis.integrators.sundials.CapturedOutput`); compiled stepping
        writes none.
    """

    name: str
    label: str
    ode: bool = True
    dae: bool = False
    numeric: bool = False
    fixed_step: bool = False
    shooting: bool = False
    stiff_alternative: str | None = None
    compiled: bool = False
    #: names of the :meth:`model_functions`
    model_function_names: tuple[str, ...] = ()
    writes_messages: bool = True

    def model_functions(self, dyn: ca.Function) -> list[ca.Function]:
        """Functions of this method over the dynamics ``dyn`` worth compiling with the model
        (in its library, its translation unit shared with ``dyn``), so that a cached run
        neither builds the symbolic formulation nor compiles again; none by default."""
        return []

    @property
    def handles(self) -> frozenset:
        """The needs of elements (:mod:`casmbd.model.needs`) a run with this integrator
        meets: all but the event-driven ones (root finding on gaps between impulses)."""
        return ALL_NEEDS - EVENT_NEEDS

    #: why it does not meet the event needs, and what to use instead
    refuses = dict.fromkeys(EVENT_NEEDS, "the event-driven run uses a variable-step SUNDIALS "
                            "integrator with root finding")
    instead = dict.fromkeys(EVENT_NEEDS, "integrator 'idas', 'cvodes' or 'adams' (or the "
                            "default)")

    def integrates(self, kind: str) -> bool:
        """Whether this integrator accepts a formulation of ``kind`` ("ode", "dae",
        "numeric": :attr:`casmbd.analysis.formulations.FormulationKind.kind`)."""
        return bool(getattr(self, kind, False))

    def integrate(self, runs, grid, x0, z0, rtol: float, atol: float, projection: bool,
                  step, max_steps: int):
        """``(xs, stats)`` on the output ``grid`` for the simulator ``runs``
        (:class:`casmbd.analysis.dynamics.stepping.Stepping`): by default a SUNDIALS method, in one
        call over the grid or, with ``projection``, output interval by output interval."""
        if projection:
            return runs.interval_by_interval(self.name, grid, x0, z0, rtol, atol, step,
                                              max_steps, project=True)
        return runs.one_call(self.name, grid, x0, z0, rtol, atol, max_steps)

    def keeps_partial(self, exc: Exception) -> bool:
        """Whether the outputs before the failure ``exc`` are kept by running again."""
        return True

    def repeats_before(self, t_fail: float | None) -> bool:
        """Whether a run on the outputs before a failure at ``t_fail`` repeats the failed
        run up to them (SUNDIALS steps past each output and interpolates: its steps do not
        depend on later outputs)."""
        return t_fail is not None

    def check_energy(self, result, mechanism, truncated, params, rtol: float,
                     step_size) -> None:
        """After a run: error control, but a loose tolerance may still let the energy
        explode (:func:`~casmbd.analysis.integrators.invariants.check_energy_blowup`)."""
        check_energy_blowup(result, mechanism, f"{self.name} (rtol = {rtol:g})", truncated,
                            params)

    def shooting_step(self, f: ca.Function, x: ca.SX, u: ca.SX, t: ca.SX,
                      steps: int) -> ca.Function:
        """``ocp_step(x, u, t, h) -> (x(t + h), ∫ L dt)`` of ``f(x, u, t) -> (ẋ, L)`` over one
        shooting interval (``steps`` sub-steps for a fixed-step method); ``x``, ``u``, ``t``
        are the SX symbols ``f`` was built from (the same graph, the same rounding)."""
        raise UnknownMethodError("shooting integrator", self.name, names(shooting=True))



#: the registered integrators, name -> kind (registration order is the order of choices)
INTEGRATORS: dict[str, IntegratorKind] = {}
#: the optimal-control problem's default shooting integrator
DEFAULT_SHOOTING_INTEGRATOR = "rk4"


def register_integrator(kind: IntegratorKind) -> IntegratorKind:
    """Add ``kind`` to :data:`INTEGRATORS` under ``kind.name`` (replacing one of that name)."""
    if not (isinstance(kind, IntegratorKind) and isinstance(kind.name, str) and kind.name):
        raise ModelError(f"register_integrator: an IntegratorKind with a name, got {kind!r}")
    INTEGRATORS[kind.name] = kind
    return kind


def integrator_kind(name: str) -> IntegratorKind:
    """The registered integrator ``name``; :class:`~casmbd.errors.UnknownMethodError` listing
    the registered names otherwise."""
    try:
        return INTEGRATORS[name]
    except (KeyError, TypeError):
        raise UnknownMethodError("integrator", name, INTEGRATORS) from None


def names(**features: bool) -> list[str]:
    """Registered integrator names with the given features, e.g. ``names(dae=True)``."""
    return [n for n, k in INTEGRATORS.items()
            if all(getattr(k, key) == val for key, val in features.items())]
