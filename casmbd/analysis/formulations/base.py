"""The formulation interface, the registry and the pieces the symbolic formulations share.

A formulation is a :class:`FormulationKind` object: it owns its name, its state layout (ODE on
x = (q, v), semi-explicit DAE with algebraic z, or a numeric right-hand side), its default
integrator, its redundancy policy (run with redundant constraint equations kept, or only with
them removed) and its initial algebraic state, and it builds a :class:`Formulation` (the
CasADi dynamics Function with the integrator signature ``(t, x, z, p, u) -> (ode, alg, quad,
zero)``).  Kinds are registered by name in :data:`FORMULATIONS` (like scipy's ``solve_ivp``
``METHODS``); :func:`formulation_kind` raises :class:`~casmbd.errors.UnknownMethodError`
listing the registered names.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from casmbd.errors import AnalysisError, ModelError, UnknownMethodError
from casmbd.system.equations import System


@dataclass
class Formulation:
    """A dynamics Function ready for an integrator, with its state layout."""

    name: str
    kind: str  # "dae", "ode" or "numeric"
    function: ca.Function
    nq: int
    nz: int
    extra: list[ca.Function] = field(default_factory=list)
    options: dict = field(default_factory=dict)

    @property
    def functions(self) -> list[ca.Function]:
        """The Functions to compile: the dynamics and, for DAEs, its exact Jacobian."""
        return [self.function, *self.extra]


class FormulationKind:
    """One forward-dynamics formulation: what the simulator needs to know about it.

    Subclass it, set the class attributes and implement :meth:`equations`; then
    :func:`register_formulation` an instance.

    Attributes
    ----------
    name : str
        The registry key (``--formulation``, ``simulate(formulation=...)``).
    kind : {"ode", "dae", "numeric"}
        ODE on x = (q, v); semi-explicit DAE (x = (q, v), algebraic z); or a right-hand side
        evaluated numerically by the analysis layer (:class:`NumericFormulation`).  The
        integrators that accept it are those whose
        :meth:`~casmbd.analysis.integrators.kinds.IntegratorKind.integrates` says so.
    layout : str
        The state layout in words, for documentation and ``info``.
    default_integrator : str
        Integrator used when none is named (measured: docs/performance.md).
    keeps_redundant : bool
        Runs with redundant constraint equations kept (minimum-norm multipliers or a
        rank-revealing choice of coordinates); otherwise they are removed first.
    removes_redundant : bool
        Whether the redundant rows can be removed from the equations it integrates (the
        numeric formulations choose their independent equations themselves: False).
    kept_redundancy : str
        What ``stats["redundancy"]`` says when the redundant equations are kept.
    max_steps : int
        The integrator steps allowed per run when none is given.
    """

    name: str = ""
    kind: str = "ode"
    layout: str = "x = (q, v)"
    default_integrator: str = "adams"
    keeps_redundant: bool = False
    removes_redundant: bool = True
    kept_redundancy: str = "kept: independent coordinates chosen by rank"
    #: the integrator steps allowed per run when ``max_steps`` is not given
    max_steps: int = 500_000
    #: factorises M alone (not only the KKT matrix): M must be regular on the whole space
    inverts_mass: bool = False
    #: the needs of elements it meets (casmbd.model.needs; by default no events and no
    #: reaction-dependent forces); ``refuses``: need -> why not; ``instead``: need -> advice
    handles: frozenset = frozenset({"modal_coordinates", "drivers", "inputs"})
    refuses: ClassVar[dict] = {
        "events": "no event-driven phases", "stick_slip": "no event-driven phases",
        "contact_friction": "no event-driven phases",
        "reaction_forces": "it does not solve for the multipliers",
        "velocity_constraints": "it does not declare that it keeps rows written at the "
                                "velocity level (A(q) v + b = 0) apart from position rows"}
    instead: ClassVar[dict] = {need: "formulation 'index1'" for need in
                     ("events", "stick_slip", "contact_friction", "reaction_forces",
                      "velocity_constraints")}

    @property
    def numeric(self) -> bool:
        """True for a right-hand side evaluated numerically (not a CasADi expression)."""
        return self.kind == "numeric"

    def equations(self, system: System, inputs: ca.SX | None = None,
                  **options) -> Formulation:
        """The dynamics Function of ``system`` (actuator inputs ``inputs`` as expressions of
        (t, p)) and the formulation's options."""
        raise NotImplementedError(f"formulation '{self.name}' builds no equations")

    def build(self, system: System, inputs: ca.SX | None = None, **options) -> Formulation:
        """:meth:`equations`, named after this kind."""
        form = self.equations(system, inputs=inputs, **options)
        form.name = self.name
        return form

    def model_functions(self, system: System, **options) -> list[ca.Function]:
        """Functions that stand in for the System's own of the same names in the compiled
        model (the folded outputs and energies of a long chain); none by default."""
        return []

    def initial_algebraic(self, a: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """The algebraic state z at a consistent start with accelerations ``a`` and
        multipliers ``lam``: (q̈, λ) for a DAE, empty otherwise."""
        return np.concatenate([a, lam]) if self.kind == "dae" else np.zeros(0)

    def ode_right_hand_side(self, function):
        """``function`` (the dynamics, or its compiled twin) when this formulation is an
        explicit ODE ẋ = f(t, x) — its q̈ then serves the post-processing of an
        unconstrained system and its Jacobian the stiffness check — else None."""
        return function if self.kind == "ode" else None

    def algebraic_state(self, accelerations_and_multipliers, kept_multipliers) -> np.ndarray:
        """The algebraic state z at a consistent state: :meth:`initial_algebraic` of
        (q̈, λ) = ``accelerations_and_multipliers()`` with λ mapped by ``kept_multipliers``
        onto the rows integrated (redundant rows removed); the empty array, with neither
        called, for a formulation without algebraic states (ODE, numeric)."""
        if self.kind != "dae":
            return np.zeros(0)
        a, lam = accelerations_and_multipliers()
        return self.initial_algebraic(a, kept_multipliers(lam))

    def hot_functions(self, names: list[str]) -> list[str] | None:
        """The compiled Functions called at every step (``names``: the dynamics and the
        integrator's own stepping), compiled at -O2; None for a numeric right-hand side,
        which calls the model's functions from Python (all at the default level)."""
        return None if self.kind == "numeric" else names

    def integrate(self, runs, name: str, grid, x0, z0, rtol: float, atol: float,
                  projection: bool, step, max_steps: int):
        """``(xs, stats)`` on the output ``grid`` from (x0, z0): the compiled dynamics of the
        simulator ``runs`` stepped by the integrator ``name``
        (:meth:`~casmbd.analysis.integrators.IntegratorKind.integrate`)."""
        return runs.integrate_compiled(name, grid, x0, z0, rtol, atol, projection, step,
                                       max_steps)

    def keep_partial(self, runs, name: str, grid, x0, z0, rtol: float, atol: float, step,
                     max_steps: int, solver_text: str, projection: bool):
        """``(xs, stats)``: the outputs before a failed :meth:`integrate` (``solver_text``:
        what the integrator printed, naming the failure time of a one-call run)."""
        return runs.partial_compiled(name, grid, x0, z0, rtol, atol, step, max_steps,
                                     solver_text, projection)

    @property
    def event_integrator(self) -> str:
        """The integrator of an event-driven run when none is named: IDAS for a DAE,
        Adams otherwise."""
        return "idas" if self.kind == "dae" else "adams"

    def refuse_events(self) -> None:
        """Raise :class:`~casmbd.errors.AnalysisError` when an event-driven run (impacts,
        stops, stick-slip) cannot use this formulation: a numeric right-hand side has no
        compiled dynamics to find roots on."""
        if self.kind not in ("ode", "dae"):
            raise AnalysisError(f"formulation '{self.name}': events need a compiled ODE or "
                                "DAE formulation (not a numeric right-hand side)")

    def failure_hint(self, flag: str, rtol: float) -> str:
        """Advice appended to an integrator failure of this formulation (the SUNDIALS
        ``flag`` at relative tolerance ``rtol``); none by default."""
        return ""

    def default_reason(self, system: System) -> str:
        """Why this formulation, taken by default for ``system`` (``stats``)."""
        return f"default: {self.name} (constraint equations: {system.nc})"

    def built_from_values(self, options: dict) -> bool:
        """Whether the equations built with ``options`` hold the parameters' values at build
        time (not only their symbols), so that a simulator serves these values only."""
        return False

    def preferred_for(self, system: System) -> bool:
        """Whether this formulation is the default for ``system`` (checked in registration
        order before :data:`DEFAULT_FORMULATION`)."""
        return False

    def __repr__(self) -> str:
        return f"<formulation {self.name!r} ({self.kind}, {self.layout})>"


#: the registered formulations, name -> kind (registration order is the order of choices)
FORMULATIONS: dict[str, FormulationKind] = {}
#: the formulation used when none is named and no kind is preferred for the system
DEFAULT_FORMULATION = "augmented_lagrangian"


def register_formulation(kind: FormulationKind) -> FormulationKind:
    """Add ``kind`` to :data:`FORMULATIONS` under ``kind.name`` (replacing one of that name).

    Users register their own formulations this way; the CLI's ``--formulation`` choices and
    ``simulate(formulation=...)`` read the registry.
    """
    if not (isinstance(kind, FormulationKind) and isinstance(kind.name, str) and kind.name):
        raise ModelError(f"register_formulation: a FormulationKind with a name, got {kind!r}")
    if kind.kind not in ("ode", "dae", "numeric"):
        raise ModelError(f"register_formulation: formulation '{kind.name}' has kind "
                         f"{kind.kind!r}, not one of ode, dae, numeric")
    FORMULATIONS[kind.name] = kind
    return kind


def formulation_kind(name: str) -> FormulationKind:
    """The registered formulation ``name``; :class:`~casmbd.errors.UnknownMethodError`
    listing the registered names otherwise."""
    try:
        return FORMULATIONS[name]
    except (KeyError, TypeError):
        raise UnknownMethodError("formulation", name, FORMULATIONS) from None


# ---------------------------------------------------------------------------- shared pieces
def symbolic_arguments(system: System) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """The symbols (t, q, v, p) of the system's equations, in that order."""
    return system.t, system.q, system.v, system.p


def baumgarte_acceleration_rhs(system: System, alpha: float, beta: float) -> ca.SX:
    """Right-hand side of the acceleration constraints with Baumgarte stabilisation,
    γ − 2α Ċ − β² C with Ċ = C_q v + C_t (Baumgarte 1972; seed 000); γ itself when α = β = 0."""
    gamma = system.acceleration_rhs
    if alpha == 0.0 and beta == 0.0:
        return gamma
    cdot = ca.mtimes(system.constraint_jacobian, system.v) + system.constraint_time_derivative
    return gamma - 2.0 * alpha * cdot - beta**2 * system.constraints


def generalized_forces(system: System, inputs: ca.SX | None, lam: ca.SX | None = None) -> ca.SX:
    """Q_e + Q_v with the actuator inputs u replaced by their expressions of (t, p).

    With reaction-proportional joint friction, Q_e = Q_e(N = 0) + G N(q, λ) needs the
    multipliers ``lam`` (a DAE's algebraic variables); an ODE formulation (``lam`` None) is
    refused naming the joints (:meth:`~casmbd.system.applied_forces.AppliedForces.
    refuse_reaction_friction`)."""
    forces = system.applied_forces + system.quadratic_velocity_forces
    if system.friction_normal_symbols:
        if lam is None:
            system.refuse_reaction_friction("this ODE formulation")
        forces = forces + ca.mtimes(system.friction_directions, system.friction_normals_of(lam))
    if system.u.numel() == 0:
        return forces
    u_expr = ca.SX.zeros(system.u.numel()) if inputs is None else inputs
    return ca.substitute(forces, system.u, u_expr)


def dae_function(name: str, t, x, z, p, ode, alg) -> ca.Function:
    """The DAE as a CasADi integrator Function (``dyn_in``/``dyn_out``: t, x, z, p, u ->
    ode, alg, quad, zero): ẋ = ode(t, x, z, p), 0 = alg(t, x, z, p), no controls."""
    u = ca.SX(0, 1) if isinstance(x, ca.SX) else ca.MX(0, 1)
    empty = ca.SX(0, 1) if isinstance(x, ca.SX) else ca.MX(0, 1)
    return ca.Function(name, [t, x, z, p, u], [ode, alg, empty, empty],
                       ca.dyn_in(), ca.dyn_out())


