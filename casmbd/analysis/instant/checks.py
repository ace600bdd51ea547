"""Finiteness and consistency checks at the start of an analysis, naming the culprit.

A NaN or an infinity in a model value (a force expression such as ``log(t)`` at t = 0, a
sampled driver queried outside its samples with ``extrapolate = "error"``) would otherwise
surface as an anonymous failure of a linear solver ("array must not contain infs or NaNs")
or as silent NaN results.  :func:`check_start` evaluates the equations once at the start
state; only when something is not finite does it look for the element behind it
(:func:`nonfinite_values`: every time-dependent value of drivers, forces and bodies,
evaluated at that time; then each force element's generalized force; then the rows), so the
check costs one evaluation of each equation on the good path.

:func:`check_consistent_start` verifies that an assembled start satisfies the constraints at
velocity and acceleration level too, C_q q̇ + C_t = 0 and C_q q̈ = γ: drivers that contradict
the joints (or each other) can agree in position at the start yet not in their rates, and a
minimum-norm solve would then hide the contradiction.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import casadi as ca
import numpy as np

from casmbd.errors import AssemblyError, ModelError
from casmbd.lazy import lazy_module
from casmbd.model.bodies import GROUND
from casmbd.model.values import Samples, resolve

sp = lazy_module("scipy.sparse")

#: value fields of force elements (a tuple value is checked component by component)
FORCE_FIELDS = ("value", "stiffness", "damping", "free_length", "free_angle", "actuator")
#: relative tolerance of the velocity- and acceleration-level consistency of a start
CONSISTENCY_RTOL = 1e-6


def _value_fields(mechanism) -> Iterator[tuple[str, str, object, int]]:
    """(element, field, value, derivative order) of every scalar value of the model."""
    for body in mechanism.bodies.values():
        yield f"body '{body.name}'", "mass", body.mass, 0
        inertia = body.inertia if isinstance(body.inertia, (list, tuple)) else (body.inertia,)
        for value in inertia:
            yield f"body '{body.name}'", "inertia", value, 0
    for driver in mechanism.drivers.values():
        for order in range(3):  # velocities and accelerations need f' and f''
            yield f"driver '{driver.name}'", "position", driver.position, order
    for force in mechanism.forces.values():
        for key in FORCE_FIELDS:
            value = getattr(force, key, None)
            if value is None or (key == "value" and not hasattr(force, "value")):
                continue
            for component in value if isinstance(value, tuple) else (value,):
                yield f"force '{force.name}'", key, component, 0


def nonfinite_values(system, t: float, p) -> list[str]:
    """Descriptions of the model values that are not finite at time ``t``.

    Every driver position (and its first two time derivatives), force value and body mass
    and inertia is evaluated at ``t`` with the parameter values ``p`` in one CasADi call.
    """
    mech = system.mechanism
    labels, exprs = [], []
    for element, key, value, order in _value_fields(mech):
        expr = resolve(value, system.t, system.ctx.p, f"{element} field '{key}'")
        for _ in range(order):
            expr = ca.jacobian(expr, system.t)
        labels.append((element, key, order, value))
        exprs.append(ca.vec(expr)[0])
    if not exprs:
        return []
    f = ca.Function("values", [system.t, system.p], [ca.vertcat(*exprs)])
    out = np.asarray(f(t, np.asarray(p, float)), float).ravel()
    found, seen = [], set()
    for (element, key, order, value), val in zip(labels, out, strict=True):
        if np.isfinite(val) or (element, key, id(value)) in seen:
            continue  # a value already named is not named again for its derivatives
        seen.add((element, key, id(value)))
        what = ("", "the first time derivative of ", "the second time derivative of ")[order]
        text = f"{what}{element} field '{key}' is {val} at t = {t:.10g}"
        if isinstance(value, Samples):
            text += (f" (outside its samples [{value.times[0]:g}, {value.times[-1]:g}] with "
                     f"extrapolate = '{value.extrapolate}')")
        elif isinstance(value, str):
            text += f" (in '{value}')"
        if text not in found:
            found.append(text)
    return found


def _element_forces(system, q, v, t: float, u, p) -> list[str]:
    """Force elements whose generalized force is not finite at (q, v, t) (diagnosis only)."""
    found = []
    for force in system.mechanism.forces.values():
        total = ca.SX.zeros(system.nq)
        for term in system._element_terms(force, system.ctx):
            if term.kind == "measure":
                total += ca.jtimes(ca.vec(term.expr), system.q, ca.vec(term.weight), True)
            elif term.kind == "torque":
                if term.body != GROUND:
                    omega = system.ctx.angular_velocity(term.body)
                    total += ca.jtimes(omega, system.v, ca.vec(term.weight), True)
            else:
                total += term.weight
        f = ca.Function("element", [system.q, system.v, system.t, system.u, system.p], [total])
        val = np.asarray(f(q, v, t, u, p), float).ravel()
        if not np.all(np.isfinite(val)):
            names = system.coordinate_names
            rows = ", ".join(f"{names[i]} = {val[i]}" for i in np.flatnonzero(
                ~np.isfinite(val))[:3])
            found.append(f"the generalized force of force '{force.name}' is not finite at "
                         f"t = {t:g} ({rows})")
    return found


def diagnose(model, t: float, q=None, v=None, u=None) -> list[str]:
    """The culprits of a non-finite evaluation at time ``t``: model values first, then (with a
    state) force elements.  Builds Functions of the symbolic ``model.system`` (a diagnostic
    after a numeric failure, see :class:`~casmbd.compiled.model.NumericModel`)."""
    system = model.system
    found = nonfinite_values(system, t, model.p)
    if not found and q is not None and model.mechanism.forces:
        v = np.zeros(model.nq) if v is None else v
        u = np.zeros(model.nu) if u is None else u
        found = _element_forces(system, q, v, t, u, model.p)
    return found


def diagnose_failure(model, t: float) -> list[str]:
    """Model values that are not finite where a time integration stopped: at ``t`` and just
    after it (an integrator stalls before a value that turns NaN, e.g. ``sqrt(0.55 - t)``)."""
    if not math.isfinite(t):
        return []
    for when in (t, t + 1e-9 * max(1.0, abs(t))):
        found = nonfinite_values(model.system, when, model.p)
        if found:
            return found
    return []


def _evaluations(model, q, v, t: float, u, every: bool = False, skip: tuple[str, ...] = ()
                 ) -> Iterator[tuple[str, str, np.ndarray, list[str]]]:
    """(function name, description, values, row labels) of each equation the model has, at
    the state (with ``every`` also those it did not compile: built in the virtual machine)."""
    coords = model.coordinate_names
    rows = [str(label) for label in model.constraint_labels]
    calls = [("constraints", "the constraints C", rows, lambda: model.constraints(q, t)),
             ("constraint_jacobian", "the constraint Jacobian C_q", rows,
              lambda: model.constraint_jacobian(q, t)),
             ("constraint_time_derivative", "C_t", rows,
              lambda: model.constraint_time_derivative(q, t)),
             ("acceleration_rhs", "the acceleration right-hand side γ", rows,
              lambda: model.acceleration_rhs(q, v, t)),
             ("mass_matrix", "the mass matrix M", coords, lambda: model.mass_matrix(q)),
             ("applied_forces", "the applied forces Q", coords,
              lambda: model.applied_forces(q, v, t, u)),
             ("quadratic_velocity_forces", "the quadratic-velocity forces", coords,
              lambda: model.quadratic_velocity_forces(q, v))]
    for name, text, labels, call in calls:
        if name not in skip and (every or name in model.functions) and \
                (labels is coords or model.nc):
            yield name, text, call(), labels


def _bad_rows(values) -> np.ndarray:
    """Rows with a non-finite entry of a vector or a sparse matrix (never densified: C_q of a
    5000-body mechanism would take gigabytes)."""
    if sp.issparse(values):
        coo = values.tocoo()
        return np.unique(coo.row[~np.isfinite(coo.data)])
    return np.flatnonzero(~np.isfinite(np.asarray(values, float)))


def check_start(model, q, v, t: float, u=None, what: str = "analysis",
                forces: np.ndarray | None = None, every: bool = False,
                skip: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Raise naming the culprit when the start state or an equation there is not finite.

    Parameters
    ----------
    model : casmbd.compiled.model.NumericModel
    q, v : array
        The start state (before assembly; v may be None for position-level analyses).
    t : float
        The start time.
    u : array, optional
        Actuator inputs (default zero).
    what : str
        The analysis, for the message.
    forces : array, optional
        Generalized forces the analysis evaluated itself at (q, v, t) (statics has its own
        function), checked with the equations.
    every : bool
        Also evaluate the equations the model did not compile (an ODE right-hand side that
        is not finite at the start: its culprit is in the forces it was compiled without).
    skip : tuple of str
        Equations not evaluated (``"mass_matrix"`` when :func:`tree_mass_positive` already
        found finite, positive pivots: M is then finite too).

    Returns
    -------
    dict
        The values evaluated, by function name (e.g. ``"mass_matrix"``: M at ``q``), for a
        later check at the same state not to evaluate them again
        (:func:`check_mass_matrix` ``mass``).

    Raises
    ------
    ModelError
        Naming the element, field and time of a non-finite model value (a force, driver,
        mass or inertia), the force element whose generalized force is not finite, or the
        coordinates of a non-finite start state.
    """
    q = np.asarray(q, float)
    v = np.zeros(model.nq) if v is None else np.asarray(v, float)
    u = np.zeros(model.nu) if u is None else np.asarray(u, float)
    names = model.coordinate_names
    for label, arr in (("coordinates", q), ("velocities", v)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise ModelError(f"{what} at t = {t:g}: the initial {label} are not finite: "
                             + ", ".join(f"{names[i]} = {arr[i]}" for i in bad[:4]))
    if not np.all(np.isfinite(u)):
        raise ModelError(f"{what} at t = {t:g}: the actuator inputs are not finite: {u}")
    evaluations = list(_evaluations(model, q, v, t, u, every, skip))
    if forces is not None:
        evaluations.append(("forces", "the generalized forces", np.asarray(forces, float),
                            names))
    for _, text, values, labels in evaluations:
        bad = _bad_rows(values)
        if not bad.size:
            continue
        culprits = diagnose(model, t, q, v, u)
        if not culprits:  # name the rows
            culprits = [f"{text} is not finite in the rows of "
                        + ", ".join(labels[i] for i in bad[:4])]
        raise ModelError(f"{what} at t = {t:g}: " + "; ".join(culprits[:4]))
    return {name: values for name, _, values, _ in evaluations}


def _worst(labels, residual: np.ndarray, count: int = 3) -> str:
    order = np.argsort(-np.abs(residual))[:count]
    floor = 1e-6 * float(np.max(np.abs(residual), initial=0.0))
    return "; ".join(f"{labels[i]} residual {residual[i]:.3g}" for i in order
                     if abs(residual[i]) > floor)


def check_consistent_start(model, q, v, a, t: float, what: str = "simulation") -> None:
    """Raise when an assembled start violates C_q q̇ + C_t = 0 or C_q q̈ = γ.

    The tolerance is :data:`CONSISTENCY_RTOL` relative to the size of the terms (‖C_q‖ ‖q̇‖
    + ‖C_t‖ at velocity level, ‖C_q‖ ‖q̈‖ + ‖γ‖ at acceleration level), with 1 as the
    smallest scale, so it does not depend on units.  With redundant but consistent equations
    (a parallelogram) both residuals vanish; with drivers that contradict the joints or each
    other in their rates they do not.

    Raises
    ------
    AssemblyError
        Naming the equations with the largest residuals (the contradicting driver among
        them) and the time.
    """
    if model.nc == 0:
        return
    labels = model.constraint_labels
    cq = model.constraint_jacobian(q, t)
    norm_cq = float(abs(cq).max()) if cq.nnz else 0.0
    ct = model.constraint_time_derivative(q, t)
    gamma = model.acceleration_rhs(q, v, t)
    for level, residual, scale in (
            ("velocity", cq @ v + ct, norm_cq * np.max(np.abs(v), initial=0.0)
             + np.max(np.abs(ct), initial=0.0)),
            ("acceleration", cq @ a - gamma, norm_cq * np.max(np.abs(a), initial=0.0)
             + np.max(np.abs(gamma), initial=0.0))):
        worst = float(np.max(np.abs(residual), initial=0.0))
        tol = CONSISTENCY_RTOL * max(1.0, float(scale))
        if not math.isfinite(worst) or worst > tol:
            raise AssemblyError(
                f"{what} at t = {t:g}: the constraints contradict each other at {level} level "
                f"(max residual {worst:.3g} > {tol:.3g}; the drivers' rates disagree with the "
                f"joints or with each other): {_worst(labels, residual)}")


#: the mass matrix on the tangent space counts as singular when its smallest eigenvalue is
#: at most this fraction of its largest
MASS_RTOL = 1e-12
#: above this many coordinates the dense check of :func:`check_mass_matrix` is skipped
MASS_CHECK_MAX = 3000


def _pivots_positive(matrix: np.ndarray) -> bool:
    """True when every Cholesky pivot of the Jacobi-scaled ``matrix`` exceeds
    :data:`MASS_RTOL`: each coordinate direction adds inertia beyond what the others
    already have, relative to its own diagonal entry.  Long chains in joint coordinates are
    badly conditioned (cond M ∝ N⁴: 4e12 for 1000 rods) yet far from singular; their pivots
    (articulated inertias over composite inertias) stay well above the bound."""
    diag = np.diag(matrix)
    if not np.all(diag > 0.0):
        return False
    scale = 1.0 / np.sqrt(diag)
    try:
        chol = np.linalg.cholesky(matrix * scale[:, None] * scale[None, :])
    except np.linalg.LinAlgError:
        return False
    return bool(np.min(np.diag(chol)) ** 2 > MASS_RTOL)


def tree_mass_positive(model, q) -> bool:
    """True when the model has the folded articulated-body pivots
    (:func:`casmbd.system.chain_pivots.folded_pivots`, a long chain in joint coordinates) and
    at ``q`` every pivot is finite and exceeds :data:`MASS_RTOL` times its diagonal entry of
    M: D_i > MASS_RTOL M_ii, the Jacobi-scaled pivots of M = Lᵀ D L eliminated from the tips
    (Featherstone 2008, §6.3), so M is positive definite — the verdict of
    :func:`check_mass_matrix` by one O(N) fold, without M.  False otherwise (no pivots
    compiled, or a pivot fails: then :func:`check_mass_matrix` decides, and names the
    bodies)."""
    if model.nc or model.nq == 0 or "articulated_pivots" not in model.functions:
        return False
    out = model.data.vector("articulated_pivots", q, model.p)
    pivots, diagonal = out[:model.nq], out[model.nq:]
    return bool(np.all(np.isfinite(out)) and np.all(diagonal > 0.0)
                and np.all(pivots > MASS_RTOL * diagonal))


def check_mass_matrix(model, q, t: float, what: str = "simulation",
                      mass=None) -> None:
    """Raise naming the bodies without mass where M is singular (or indefinite) on the
    constraint manifold.

    Forward dynamics needs the KKT matrix [[M, C_qᵀ], [C_q, 0]] non-singular, i.e. (with C_q
    of full row rank, or after its dependent rows are dropped) M positive definite on the null
    space of C_q: with N an orthonormal basis of that null space (from the SVD of C_q), the
    smallest eigenvalue of Nᵀ M N must exceed :data:`MASS_RTOL` times its largest, or every
    pivot of its Jacobi-scaled Cholesky factor exceed :data:`MASS_RTOL` (the test that holds
    for long, badly conditioned chains).  Bodies of
    zero mass or inertia are accepted by the model; this check, once at the assembled start,
    is where they matter.  The eigenvectors x = N y of the (near-)zero eigenvalues are motions
    without kinetic energy; the bodies whose coordinates carry ≥ 10 % of the largest share of
    their |x|² are named.

    A smallest eigenvalue below −:data:`MASS_RTOL` times the largest is not rounding: the
    matrix is *indefinite* (a motion with negative kinetic energy), a different defect with a
    different message naming the bodies of those motions.

    Cheap test first: when the Jacobi-scaled Cholesky pivots of M itself exceed
    :data:`MASS_RTOL` (:func:`_pivots_positive`, one dense factorisation, n³/3 flops) M is
    positive definite on the whole space, hence on the null space of C_q: no SVD of C_q, no
    projection, no eigen-decomposition.  Only when it fails does :func:`_diagnose_mass` run the
    projected test and the eigen-decomposition that names the bodies (a tree in joint
    coordinates without mass, or absolute coordinates with a massless body, take that path).

    Parameters
    ----------
    mass : array or sparse matrix, optional
        M already evaluated at ``q`` (:func:`check_start` returns it), not evaluated again.

    Raises
    ------
    ModelError
        Naming those bodies with their mass and inertia ("singular": massless motions;
        "indefinite": motions with negative kinetic energy).
    """
    if model.nq == 0 or model.nq > MASS_CHECK_MAX:
        return
    m = model.mass_matrix(q) if mass is None else mass
    m = np.asarray(m.todense() if sp.issparse(m) else m, float)
    m = 0.5 * (m + m.T)
    if _pivots_positive(m):  # positive definite on the whole space: on the manifold too
        return
    _diagnose_mass(model, m, q, t, what)


def check_mass_invertible(model, q, t: float, formulation: str) -> None:
    """Raise naming the bodies where M itself (not only on the constraint manifold) is
    singular — for a formulation that factorises M alone (``kkt_ode``: λ from the Schur
    complement C_q M⁻¹ C_qᵀ, seed 000 §6).  A thin disc or plate in natural coordinates is
    the usual case: its second moment across its plane is zero, so its natural-coordinate mass
    matrix (built from the second moments, seed 003) is singular although the KKT matrix is
    regular.

    Raises
    ------
    ModelError
        Naming the formulation, the bodies and what to use instead.
    """
    if model.nq == 0 or model.nq > MASS_CHECK_MAX:
        return
    m = model.mass_matrix(q)
    m = np.asarray(m.todense() if sp.issparse(m) else m, float)
    m = 0.5 * (m + m.T)
    if _pivots_positive(m):
        return
    try:
        _diagnose_mass(model, m, q, t, "", on_manifold=False)
    except ModelError as err:
        detail = str(err).split("mass matrix is ", 1)[-1].replace(" on the whole space", "")
        detail = detail.split("; give the body", 1)[0].split(". Not a massless", 1)[0]
        raise ModelError(
            f"simulation at t = {t:g}: formulation '{formulation}' factorises the mass matrix "
            f"alone, which is {detail} (a massless body, or a thin disc or plate in natural "
            "coordinates: no second moment across its plane); instead: formulation 'index1' or "
            "'augmented_lagrangian' (they need M regular on the constraint manifold only), "
            "or other coordinates") from None


def _diagnose_mass(model, m: np.ndarray, q, t: float, what: str,
                   on_manifold: bool = True) -> None:
    """The full test of :func:`check_mass_matrix` on the null space of C_q (SVD of C_q,
    projected pivots, then the eigen-decomposition naming the bodies); run only when M itself
    fails the cheap test.  ``on_manifold=False``: on the whole space (M itself)."""
    basis = np.eye(model.nq)
    if model.nc and on_manifold:
        cq = model.constraint_jacobian(q, t)
        cq = np.asarray(cq.todense() if sp.issparse(cq) else cq, float)
        _, s, vt = np.linalg.svd(cq)
        tol = max(cq.shape) * np.finfo(float).eps * (s[0] if s.size else 0.0)
        basis = vt[int(np.sum(s > tol)):].T
    if basis.shape[1] == 0:
        return
    projected = basis.T @ m @ basis if model.nc and on_manifold else m
    if _pivots_positive(projected):
        return
    eig, vec = np.linalg.eigh(projected)
    tol = MASS_RTOL * max(float(np.max(np.abs(eig))), np.finfo(float).tiny)
    if eig[0] > tol:
        return
    indefinite = eig[0] < -tol  # beyond rounding: negative kinetic energy, not a massless motion
    # every motion without kinetic energy (indefinite: every one with negative energy)
    x = basis @ vec[:, eig < -tol] if indefinite else basis @ vec[:, eig <= tol]
    shares, start = {}, 0
    for body, desc in model.descriptions.items():
        shares[body] = float(np.sum(x[start:start + desc.size] ** 2))
        start += desc.size
    top = max(shares.values())
    named = [b for b, w in sorted(shares.items(), key=lambda kv: -kv[1]) if w >= 0.1 * top]
    bodies = model.mechanism.bodies

    def about(name: str) -> str:
        body = bodies.get(name)
        if body is None:
            return f"'{name}'"
        return f"'{name}' (mass {body.mass}, inertia {body.inertia})"

    space = "on the constraint manifold" if on_manifold else "on the whole space"
    if indefinite:
        raise ModelError(
            f"{what} at t = {t:g}: the mass matrix is indefinite {space} "
            f"(smallest eigenvalue {eig[0]:.3g} of {float(eig[-1]):.3g}): a motion of "
            + ", ".join(f"body {about(b)}" for b in named[:4])
            + " has negative kinetic energy. Not a massless body: an inertia that is not "
            "physical (a negative mass or moment of inertia from a parameter), or a flexible "
            "body whose mass invariants do not come from one mass matrix (hand-made modal data)")
    raise ModelError(
        f"{what} at t = {t:g}: the mass matrix is singular {space} "
        f"(smallest eigenvalue {eig[0]:.3g} of {float(eig[-1]):.3g}): a motion of "
        + ", ".join(f"body {about(b)}" for b in named[:4])
        + " has no inertia; give the body mass and inertia, or attach it to bodies that have "
        "some (a massless body must be carried by its joints to bodies with mass)")
