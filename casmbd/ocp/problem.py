"""Optimal-control problems over a mechanism: the vocabulary.

In the style of rockit (``Ocp``, ``subject_to``, ``solve``) and scipy's ``solve_ivp`` (one entry
point, a result object)::

    ocp = Ocp(mech, horizon=2.0, intervals=50)          # or horizon=FreeTime(guess=1.0)
    ocp.control_bounds("tau1", -50, 50)
    ocp.initial(shoulder=-pi/2, elbow=0, shoulder_dot=0, elbow_dot=0)
    ocp.final(shoulder=pi/2, elbow=0, shoulder_dot=0, elbow_dot=0)
    ocp.path("tip_y", upper=2.5)
    ocp.minimize("effort")                              # ∫ uᵀu dt; "time", "energy", ...
    sol = ocp.solve()                                   # OcpSolution

Every expression is a string (or a callable of the quantity dict) over the names of
:mod:`casmbd.system.named_quantities`.  The states are the model's (q, q̇) and the controls its
actuator inputs u; the closed-loop constraints C(q, t) = 0 and C_q q̇ + C_t = 0 hold at every node.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import casadi as ca

from casmbd.analysis.integrators.kinds import DEFAULT_SHOOTING_INTEGRATOR
from casmbd.analysis.integrators.kinds import names as integrator_names
from casmbd.errors import AnalysisError, ModelError
from casmbd.limits import MAX_OCP_INTERVALS, MAX_OCP_UNKNOWNS, check_count
from casmbd.model.expressions import parse_expression
from casmbd.model.needs import ALL_NEEDS, EVENT_NEEDS, Handling, check
from casmbd.ocp.methods import transcription_method
from casmbd.ocp.options import check_solver_options
from casmbd.ocp.transcription import Transcription
from casmbd.system.equations import System
from casmbd.system.named_quantities import quantities

OBJECTIVES = ("effort", "time", "energy")
DYNAMICS = ("auto", "implicit", "explicit")
GUESSES = ("linear", "simulation", "inverse")


@dataclass
class FreeTime:
    """A free final time with its initial guess and bounds [s]."""

    guess: float = 1.0
    lower: float = 1e-3
    upper: float = 1e3


PATH_POINTS = ("all", "nodes", "control_nodes")


@dataclass
class _Constraint:
    expression: str | Callable
    lower: float
    upper: float
    where: str
    at: str = "all"


@dataclass
class _Term:
    kind: str                       # "effort", "time", "energy", "lagrange", "mayer", "tracking"
    weight: float = 1.0
    expression: str | Callable | None = None
    reference: str | Callable | None = None


#: what trajectory optimisation handles (casmbd.model.needs): smooth dynamics only — the
#: transcriptions differentiate the dynamics, which impacts and switching friction are not
HANDLING = Handling(
    "trajectory optimisation (ocp)", ALL_NEEDS - EVENT_NEEDS - {"reaction_forces"},
    why=dict.fromkeys(EVENT_NEEDS, "its transcriptions need dynamics differentiable along the "
                      "horizon; impacts and stick-slip switches are not (a complementarity "
                      "formulation is not built)") | {
        "reaction_forces": "its transcriptions do not solve for the multipliers the "
                           "friction level needs"},
    instead=dict.fromkeys(EVENT_NEEDS, "model = 'compliant' contacts and stops (forces the "
                          "transcription handles), or the regularised friction law") | {
        "reaction_forces": "a constant Coulomb level (mu = 0), or inverse dynamics along a "
                           "given motion"},
    notes={"modal_coordinates": "the mesh is checked against the fastest elastic mode",
           "inputs": "the controls",
           "velocity_constraints": "C_q q̇ + C_t = 0 on every row at every mesh node and "
                                   "C_q q̈ = γ at every collocation point; C = 0 and the "
                                   "position projection on the holonomic rows only"})


@dataclass
class Ocp:
    """An optimal-control problem over a mechanism.

    Parameters
    ----------
    mechanism : Mechanism or System
    horizon : float or FreeTime
        Final time T (fixed) or a :class:`FreeTime`.
    intervals : int
        Number of control intervals N (piecewise-constant controls).
    transcription : {"radau", "legendre", "multiple_shooting"}
        Direct collocation on Radau IIA or Gauss–Legendre points of ``degree`` (default 4) on
        ``subintervals`` collocation elements per control interval (default 1; measured over
        the problems of ``ocp/``: degree 4 on one element replays to ≤ 4e-6 except the
        double-pendulum swing-up, 1.2e-4, whose unstable end pose amplifies the local error —
        its file asks for two elements, 6.7e-5 — while degree 3 on one element leaves that
        replay 2e-2 off), or multiple shooting with
        ``integrator`` ("rk4": ``steps`` fixed steps per interval with exact Hessians;
        "cvodes": CVODES with exact first-order sensitivities and a limited-memory Hessian).
    dynamics : {"auto", "implicit", "explicit"}
        How collocation states the equations of motion. ``"implicit"``: q̈ and λ are NLP
        variables at every collocation point with M q̈ + C_qᵀλ = Q, C_q q̈ = γ (nothing
        inverted; any mechanism). ``"explicit"``: q̈ = f(q, q̇, u, t) is substituted (the
        articulated-body recursion for a joint-coordinate tree, else M⁻¹Q) and, on Radau
        points, the last collocation state is the next mesh node, so the NLP is smaller than
        a hand-written ODE transcription; only for mechanisms without constraint equations.
        ``"auto"`` (default): explicit when the mechanism has no constraint equations and
        small equations of motion, else implicit
        (:func:`casmbd.ocp.dynamics.choose_dynamics`; measured in docs/ocp.md: explicit
        solves the two-coordinate trees of ``ocp/`` faster, implicit the UR5). The choice
        and its reason are in the solution's ``stats["dynamics"]`` and
        ``stats["dynamics_choice"]``.
    solver : {"ipopt", "sqpmethod"}
        The NLP solver (:data:`casmbd.ocp.options.SOLVERS`).
    solver_options : dict
        Options of the NLP solver, checked against an allow-list with types and ranges
        (:mod:`casmbd.ocp.options`: e.g. ``"ipopt.max_iter"``, ``"ipopt.tol"``; never code,
        compiler or file options) when the problem is built and again when it is solved;
        trusted code passes anything else to :meth:`solve` (``options=``), unchecked.
    compile : {"auto", False, True, "elements", "nlp", "vm"}
        How the NLP's derivatives are built (:func:`casmbd.ocp.structured.nlp_solver`;
        measured in docs/ocp.md). Each mapped element function (one collocation element or
        shooting interval, one mesh node) is differentiated once in SX and the NLP's
        gradient, Jacobian and Lagrangian Hessian are assembled from those with constant
        sparse matrices. ``"auto"`` (default): these per-element functions are compiled to C
        and cached when small (:data:`~casmbd.ocp.structured.AUTO_COMPILE_INSTRUCTIONS`) or
        already cached, else evaluated in CasADi's virtual machine — set-up in seconds at
        most. False: always the virtual machine, nothing cached. True or ``"elements"``:
        always compiled (a faster solve where the element is large, e.g. a 6-joint arm, after
        a long compilation). ``"nlp"``: the whole NLP's derivative functions generated from
        the MX graph, compiled and cached (minutes of C compilation on larger problems).
        ``"vm"``: CasADi's own derivatives of the MX graph in the virtual machine. Without a
        C compiler the compiled modes use the virtual machine.
    """

    mechanism: object
    horizon: float | FreeTime = 1.0
    intervals: int = 50
    transcription: str = "radau"
    degree: int = 4
    subintervals: int = 1
    integrator: str = DEFAULT_SHOOTING_INTEGRATOR
    steps: int = 4
    dynamics: str = "auto"
    t_start: float = 0.0
    solver: str = "ipopt"
    solver_options: dict = field(default_factory=dict)
    compile: bool | str = "auto"
    _initial: dict = field(default_factory=dict, init=False)
    _final: dict = field(default_factory=dict, init=False)
    _control_bounds: dict = field(default_factory=dict, init=False)
    _path: list = field(default_factory=list, init=False)
    _terms: list = field(default_factory=list, init=False)
    _guess: object = field(default="linear", init=False)
    _initial_given: bool = field(default=False, init=False)

    def __post_init__(self):
        check(self.mechanism.mechanism if isinstance(self.mechanism, System)
              else self.mechanism, HANDLING)
        self.system = (self.mechanism if isinstance(self.mechanism, System)
                       else System(self.mechanism))
        transcription_method(self.transcription)  # AnalysisError naming the registered ones
        if not (isinstance(self.intervals, int) and self.intervals >= 1):
            raise AnalysisError(f"ocp: intervals must be an integer >= 1, got {self.intervals!r}")
        if not (isinstance(self.subintervals, int) and self.subintervals >= 1):
            raise AnalysisError(f"ocp: subintervals must be an integer >= 1, got "
                                f"{self.subintervals!r}")
        if not (isinstance(self.steps, int) and not isinstance(self.steps, bool)
                and self.steps >= 1):  # 0 steps: the shooting map is the identity (issue 18)
            raise AnalysisError(f"ocp: steps (RK4 steps per interval) must be an integer "
                                f">= 1, got {self.steps!r}")
        if not (isinstance(self.degree, int) and 1 <= self.degree <= 9):
            raise AnalysisError(f"ocp: degree must be an integer in 1..9, got {self.degree!r}")
        self._check_size()
        if self.dynamics not in DYNAMICS:
            raise AnalysisError(f"ocp: dynamics must be one of {', '.join(DYNAMICS)}, got "
                                f"{self.dynamics!r}")
        self.solver_options = check_solver_options(self.solver, self.solver_options)
        shooting = integrator_names(shooting=True)
        if self.integrator not in shooting:
            raise AnalysisError(f"ocp: integrator must be one of {', '.join(shooting)} "
                                f"(casmbd.analysis.integrators.kinds), got {self.integrator!r}")
        if isinstance(self.horizon, FreeTime):
            h = self.horizon
            if not (0 < h.lower <= h.guess <= h.upper and math.isfinite(h.upper)):
                raise AnalysisError(f"ocp: horizon: free time needs 0 < lower <= guess <= upper "
                                    f"< inf, got {h}")
        elif not (isinstance(self.horizon, (int, float)) and math.isfinite(self.horizon)
                  and self.horizon > 0):
            raise AnalysisError(f"ocp: horizon must be a finite time > 0 or FreeTime, got "
                                f"{self.horizon!r}")
        self.names = quantities(self.system)
        self.controls = list(self.system.mechanism.actuators)
        if not self.controls:
            raise ModelError(f"ocp: mechanism '{self.system.mechanism.name}' has no actuators: "
                             "nothing to optimise (add actuators on the driven joints)")

    def _check_size(self) -> None:
        """Refuse (:class:`~casmbd.errors.LimitError`) a transcription larger than the limits of
        :mod:`casmbd.limits` before any expression is built: the intervals, and the unknowns
        intervals × points per interval × (states + inputs), the points being
        subintervals × (degree + 1) for collocation and the RK4 steps for shooting."""
        check_count("ocp: intervals", self.intervals, MAX_OCP_INTERVALS, "use fewer intervals")
        per_interval = transcription_method(self.transcription).points_per_interval(self)
        width = 2 * self.system.nq + len(self.system.mechanism.actuators)
        check_count(f"ocp: unknowns ({self.intervals:,} intervals × {per_interval} points × "
                    f"{width} states and inputs)", self.intervals * per_interval * width,
                    MAX_OCP_UNKNOWNS, "use fewer intervals, subintervals, degree or steps")

    # ------------------------------------------------------------------ vocabulary
    @property
    def free_time(self) -> bool:
        return isinstance(self.horizon, FreeTime)

    def _check_name(self, expr, where: str) -> None:
        if isinstance(expr, str) and expr.isidentifier() and expr not in self.names:
            known = ", ".join(sorted(self.names)[:40])
            raise ModelError(f"ocp {where}: unknown quantity '{expr}' (known: {known}, …)")

    def initial(self, values: Mapping[str, float] | None = None, **kwargs: float) -> Ocp:
        """Equalities at t_start, by quantity name (``shoulder=-pi/2, shoulder_dot=0``).  Once
        called (even with no names) the initial state is free apart from these equalities and
        the constraints; if never called, the scene's assembled initial state (q, q̇) is
        imposed."""
        self._initial_given = True
        for key, val in {**(values or {}), **kwargs}.items():
            self._check_name(key, "initial")
            self._initial[key] = val
        return self

    def final(self, values: Mapping[str, float] | None = None, **kwargs: float) -> Ocp:
        """Equalities at the final time, by quantity name."""
        for key, val in {**(values or {}), **kwargs}.items():
            self._check_name(key, "final")
            self._final[key] = val
        return self

    def control_bounds(self, actuator: str, lower: float = -math.inf,
                       upper: float = math.inf) -> Ocp:
        """Bounds on an actuator input."""
        if actuator not in self.controls:
            raise ModelError(f"ocp control_bounds: unknown actuator '{actuator}' (known: "
                             f"{', '.join(self.controls)})")
        if not lower <= upper:
            raise ModelError(f"ocp control_bounds '{actuator}': lower {lower} > upper {upper}")
        self._control_bounds[actuator] = (float(lower), float(upper))
        return self

    def path(self, expression: str | Callable, lower: float = -math.inf,
             upper: float = math.inf, at: str = "all") -> Ocp:
        """lower ≤ expression ≤ upper (an equality when lower == upper).

        ``at``: ``"all"`` mesh nodes and collocation points (default), ``"nodes"`` the mesh
        nodes, ``"control_nodes"`` the boundaries of the control intervals only — the choice
        for prescribing a coordinate's path with piecewise-constant controls, which can meet
        one condition per interval and degree of freedom.
        """
        self._check_name(expression, "path")
        if not lower <= upper:
            raise ModelError(f"ocp path '{expression}': lower {lower} > upper {upper}")
        if at not in PATH_POINTS:
            raise ModelError(f"ocp path '{expression}': at must be one of "
                             f"{', '.join(PATH_POINTS)}, got {at!r}")
        self._path.append(_Constraint(expression, float(lower), float(upper), "path", at))
        return self

    def minimize(self, kind: str, weight: float = 1.0, expression=None,
                 reference=None) -> Ocp:
        """Add an objective term.

        ``"effort"`` ∫ uᵀu dt; ``"time"`` T; ``"energy"`` ∫ Σ |u_i ẏ_i| dt (absolute actuator
        power, ẏ_i the rate of the actuated joint coordinate; exact by slack variables);
        ``"lagrange"`` ∫ expression dt; ``"mayer"`` expression at the final time;
        ``"tracking"`` ∫ (expression − reference(t))² dt.
        """
        if kind not in (*OBJECTIVES, "lagrange", "mayer", "tracking"):
            raise ModelError(f"ocp minimize: unknown objective '{kind}' (known: "
                             f"{', '.join(OBJECTIVES)}, lagrange, mayer, tracking)")
        if kind == "time" and not self.free_time:
            raise ModelError("ocp minimize('time') needs horizon=FreeTime(...)")
        if kind in ("lagrange", "mayer", "tracking") and expression is None:
            raise ModelError(f"ocp minimize('{kind}') needs an expression")
        if expression is not None:
            self._check_name(expression, kind)
        self._terms.append(_Term(kind, float(weight), expression, reference))
        return self

    def guess(self, kind="linear") -> Ocp:
        """Initial guess: "linear" (interpolate the boundary states), "simulation" (a forward
        simulation with zero inputs), "inverse" (inverse dynamics of the linear path, when the
        actuators can produce it) or an :class:`~casmbd.ocp.solution.OcpSolution` (warm
        start)."""
        if isinstance(kind, str) and kind not in GUESSES:
            raise ModelError(f"ocp guess: unknown kind '{kind}' (known: {', '.join(GUESSES)}, "
                             "or a previous solution)")
        self._guess = kind
        return self

    # ------------------------------------------------------------------ expressions
    def expression(self, expr, where: str) -> ca.SX:
        """An SX expression of (q, v, t, u, p) from a string or a callable of the names."""
        if callable(expr):
            out = ca.SX(expr(self.names))
        elif isinstance(expr, (int, float)):
            out = ca.SX(float(expr))
        else:
            out = ca.SX(parse_expression(str(expr), self.names, where=f"ocp {where}"))
        if out.numel() != 1:
            raise ModelError(f"ocp {where}: expression is not a scalar ({out.shape})")
        return out

    def solve(self, **options):
        """Transcribe, solve with the NLP solver and return an
        :class:`~casmbd.ocp.solution.OcpSolution`.

        ``options`` (keywords of :meth:`casmbd.ocp.transcription.Transcription.solve`):
        ``guess``, ``raise_on_failure`` and ``options`` — solver options passed to CasADi
        unchecked, for trusted Python code only (:attr:`solver_options` is checked)."""
        return Transcription(self).solve(**options)
