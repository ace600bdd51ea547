"""Physically consistent standard parameters from the base-parameter estimate.

The base parameters π_b = K π (K from the QR of the regressor,
:mod:`casmbd.analysis.identification.base_parameters`) say nothing about the directions of π
in the null space of K, and their least-squares estimate need not come from any physical
body.  This module finds standard parameters π — each body's mass m, first moment h = m c
and inertia I_O about its body frame, and each joint's viscous and Coulomb coefficients — that
are physically consistent by construction and fit the data best:

* a body's parameters are consistent iff its *pseudo-inertia*

      J = [[Σ, h], [hᵀ, m]],  Σ = ½ tr(I_O) 1 − I_O  (the second moment ∫ r rᵀ dm),

  is positive definite (Wensing, Kim & Slotine 2017, "Linear matrix inequalities for
  physically consistent inertial parameter identification", IEEE RA-L 3(1)): m > 0 and the
  inertia about the centre of mass I_C = I_O − m (|c|² 1 − c cᵀ) positive definite with its
  principal moments satisfying the triangle inequalities I₁ + I₂ > I₃ (Sousa & Cortesão
  2014, "Physical feasibility of robot base inertial parameter identification", IJRR 33(6));
* J is written J = U Uᵀ with the *log-Cholesky* factor (Rucker & Wensing 2022, "Smooth
  parameterization of rigid-body inertia", IEEE RA-L 7(2))

      U = e^α [[e^{d₁}, s₁₂, s₁₃, t₁], [0, e^{d₂}, s₂₃, t₂], [0, 0, e^{d₃}, t₃], [0, 0, 0, 1]],

  ten unconstrained numbers θ = (α, d₁, d₂, d₃, s₁₂, s₂₃, s₁₃, t₁, t₂, t₃) per body, a
  smooth bijection onto the positive-definite pseudo-inertias (m = e^{2α}); a planar body
  (m, m c_x, m c_y, I_zz) takes m = e^{2α}, c = (t₁, t₂), I_zz = m (|c|² + e^{2β});
* friction coefficients are variables with the bound ≥ 0.

The objective is the weighted residual of the base model relative to the weighted efforts,
written exactly as a quadratic form in π_b: ‖G (y − W K π)‖² = (K π − π̂_b)ᵀ W_Gᵀ W_G
(K π − π̂_b) + ‖G (y − W π̂_b)‖² (π̂_b the weighted least-squares solution), so the solve
never touches the samples:

    min_θ  (K π(θ) − π̂_b)ᵀ W_Gᵀ W_G (K π(θ) − π̂_b) / ‖G y‖² + μ ‖θ − θ_prior‖²,

the first term the squared relative change of the (weighted) torques from the least-squares
fit, the second a small pull (μ = :data:`REGULARIZATION` = 1e-8) towards the prior — the
model file's own values, in the log-Cholesky coordinates (dimensionless logarithms, offsets in
m) and the friction coefficients — that fixes the directions the data cannot see (the null
space of K) and costs about √μ of relative torque per unit change of θ.  The pull also
keeps a solution whose best fit lies on the boundary of the consistent set (a singular
pseudo-inertia: a point mass, a thin rod — at infinity in θ) at a finite θ: with μ = 1e-10
IPOPT crawled towards it for thousands of iterations on a noisy data set.  So the solve
starts with μ = 1e-8, then repeats it from the solution with μ weakened 100-fold,
:data:`REFINEMENTS` times (μ = 1e-12 at the end): a refinement whose IPOPT does not converge
(the boundary case) is dropped, the previous solution kept.  The μ of the returned set is
reported (``regularization``).  Solved by IPOPT (``casadi.nlpsol``, exact Hessian, tolerance
1e-12), started from the standard set nearest the prior that reproduces π̂_b
(π_prior + K⁺ (π̂_b − K π_prior)), projected onto the consistent set (eigenvalues of J
clipped) where it is not.

**Polish.**  IPOPT stops at a relative torque error of ~1e-7 (its tolerance on the tiny,
badly scaled objective near an exact fit).  When the least-squares estimate itself is
realisable, the step π_c + K⁺ (π̂_b − K π_c) — a change in the row space of K only, the
unidentifiable part chosen by the pull untouched — fits it exactly; it is taken when the
result is still consistent (friction coefficients within 1e-12 below zero set to zero), and
``polished`` says so.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd import interrupts
from casmbd.errors import IdentificationError

__all__ = ["REGULARIZATION", "ConsistentEstimate", "body_inertials", "consistent_parameters",
           "friction_values", "parameter_layout"]

#: weight μ of the pull towards the prior in the log-Cholesky coordinates, against the squared
#: relative torque change (module docstring)
REGULARIZATION = 1e-8
#: solves with the pull weakened 100-fold each, from the previous solution (module docstring)
REFINEMENTS = 2

SPATIAL = ("m", "mcx", "mcy", "mcz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
PLANAR = ("m", "mcx", "mcy", "Izz")
FRICTION = ("viscous", "coulomb")


@dataclass
class ConsistentEstimate:
    """Physically consistent standard parameters (module docstring).

    Attributes
    ----------
    names, values : list of str, ndarray
        The standard parameters π (names as the regressor's ``standard_parameters``).
    base_values : ndarray
        K π: the base parameters they imply.
    status : str
        IPOPT's return status.
    objective : float
        The scaled objective at the solution.
    checks : dict
        Per body: mass, centre of mass (body frame), principal moments about it and the
        smallest triangle-inequality margin min(I₁ + I₂ − I₃, …); per joint friction.
    regularization : float
        The weight μ of the pull towards the prior of the solution returned.
    polished : bool
        Whether the exact-fit step was taken (module docstring).
    """

    names: list[str]
    values: np.ndarray
    base_values: np.ndarray
    status: str
    objective: float
    checks: dict
    regularization: float = REGULARIZATION
    polished: bool = False


def parameter_layout(names: list[str]) -> tuple[dict[str, dict[str, int]],
                                                 dict[str, dict[str, int]]]:
    """Bodies → {field: index} and joints → {"viscous"/"coulomb": index} of ``names``.

    A name is ``"<element>.<field>"`` (the element's name may hold dots; the field is after
    the last one).  Every body must carry all ten spatial fields (:data:`SPATIAL`) or the
    four planar ones (:data:`PLANAR`).
    """
    bodies: dict[str, dict[str, int]] = {}
    joints: dict[str, dict[str, int]] = {}
    for k, name in enumerate(names):
        element, _, key = str(name).rpartition(".")
        if not element:
            raise IdentificationError(f"standard parameter '{name}': expected "
                                      "'<element>.<field>'")
        if key in FRICTION:
            joints.setdefault(element, {})[key] = k
        elif key in SPATIAL:
            bodies.setdefault(element, {})[key] = k
        else:
            raise IdentificationError(f"standard parameter '{name}': unknown field '{key}' "
                                      f"(known: {', '.join(SPATIAL + FRICTION)})")
    for body, fields in bodies.items():
        if set(fields) not in (set(SPATIAL), set(PLANAR)):
            raise IdentificationError(
                f"body '{body}': the standard parameters have fields {sorted(fields)}; a "
                f"spatial body needs {', '.join(SPATIAL)}, a planar one {', '.join(PLANAR)}")
    return bodies, joints


def _tensor(values, f: dict[str, int]):
    """The 3 × 3 inertia tensor I_O of a spatial body's entries (tensor entries, not
    negated products)."""
    ixx, iyy, izz = (values[f[k]] for k in ("Ixx", "Iyy", "Izz"))
    ixy, ixz, iyz = (values[f[k]] for k in ("Ixy", "Ixz", "Iyz"))
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


def body_inertials(names: list[str], values) -> dict[str, tuple[float, np.ndarray, object]]:
    """Body → (m, c, I_C): mass, centre of mass in the body frame and the inertia about it
    (a 3 × 3 tensor in body axes; planar: the scalar I_zz), from standard parameters about
    the body frame: c = h / m, I_C = I_O − m (|c|² 1 − c cᵀ) (parallel axes)."""
    values = np.asarray(values, dtype=float)
    bodies, _ = parameter_layout(names)
    out = {}
    for body, f in bodies.items():
        m = float(values[f["m"]])
        if m <= 0.0:
            raise IdentificationError(f"body '{body}': mass {m:.6g} is not positive")
        if "mcz" in f:
            c = np.array([values[f["mcx"]], values[f["mcy"]], values[f["mcz"]]]) / m
            out[body] = (m, c, _tensor(values, f) - m * (c @ c * np.eye(3) - np.outer(c, c)))
        else:
            c = np.array([values[f["mcx"]], values[f["mcy"]]]) / m
            out[body] = (m, c, float(values[f["Izz"]] - m * c @ c))
    return out


def friction_values(names: list[str], values) -> dict[str, dict[str, float]]:
    """Joint → {"viscous": c, "coulomb": F_c} of the friction entries of ``values``."""
    _, joints = parameter_layout(names)
    return {j: {k: float(values[i]) for k, i in f.items()} for j, f in joints.items()}


def _body_checks(m: float, c: np.ndarray, inertia) -> dict:
    if np.ndim(inertia) == 0:
        return {"mass": m, "com": c.tolist(), "inertia_com": float(inertia),
                "consistent": bool(m > 0.0 and inertia > 0.0)}
    moments = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
    margin = float(min(moments[0] + moments[1] - moments[2],
                       moments[0] + moments[2] - moments[1],
                       moments[1] + moments[2] - moments[0]))
    return {"mass": m, "com": c.tolist(), "principal_moments": moments.tolist(),
            "triangle_margin": margin,
            "consistent": bool(m > 0.0 and moments[0] > 0.0 and margin > 0.0)}


def physical_checks(names: list[str], values) -> dict:
    """The physical conditions of standard parameters, per body and joint (module
    docstring): mass, centre of mass, principal moments about it, triangle margin."""
    values = np.asarray(values, dtype=float)
    bodies, joints = parameter_layout(names)
    out = {"bodies": {}, "joints": {}}
    for body, f in bodies.items():
        m = float(values[f["m"]])
        if m <= 0.0:
            out["bodies"][body] = {"mass": m, "consistent": False}
            continue
        out["bodies"][body] = _body_checks(*body_inertials(
            [names[i] for i in f.values()], values[list(f.values())])[body])
    for joint, f in joints.items():
        vals = {k: float(values[i]) for k, i in f.items()}
        out["joints"][joint] = {**vals, "consistent": all(x >= 0.0 for x in vals.values())}
    out["consistent"] = all(b["consistent"] for b in out["bodies"].values()) and all(
        j["consistent"] for j in out["joints"].values())
    return out


def _pseudo_inertia(values, f) -> np.ndarray:
    """J = [[Σ, h], [hᵀ, m]] of a spatial body's entries."""
    inertia = _tensor(values, f)
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    h = np.array([values[f["mcx"]], values[f["mcy"]], values[f["mcz"]]])
    return np.block([[sigma, h[:, None]], [h[None, :], np.array([[values[f["m"]]]])]])


def _spatial_theta_of(j: np.ndarray) -> np.ndarray:
    """θ of the log-Cholesky factor U (J = U Uᵀ, U upper triangular) of a positive-definite
    pseudo-inertia: with P the exchange matrix, P J P = L Lᵀ and U = P L P."""
    p = np.eye(4)[::-1]
    u = p @ np.linalg.cholesky(p @ j @ p) @ p
    ea = u[3, 3]
    return np.array([np.log(ea), np.log(u[0, 0] / ea), np.log(u[1, 1] / ea),
                     np.log(u[2, 2] / ea), u[0, 1] / ea, u[1, 2] / ea, u[0, 2] / ea,
                     u[0, 3] / ea, u[1, 3] / ea, u[2, 3] / ea])


def _spatial_pi(theta) -> dict:
    """The ten standard parameters of θ, as expressions (J = U Uᵀ)."""
    al, d1, d2, d3, s12, s23, s13, t1, t2, t3 = (theta[k] for k in range(10))
    ea = ca.exp(al)
    u = ea * ca.vertcat(ca.horzcat(ca.exp(d1), s12, s13, t1),
                        ca.horzcat(0, ca.exp(d2), s23, t2),
                        ca.horzcat(0, 0, ca.exp(d3), t3),
                        ca.horzcat(0, 0, 0, 1))
    j = ca.mtimes(u, u.T)
    sigma = j[:3, :3]
    inertia = ca.trace(sigma) * ca.SX.eye(3) - sigma
    return {"m": j[3, 3], "mcx": j[0, 3], "mcy": j[1, 3], "mcz": j[2, 3],
            "Ixx": inertia[0, 0], "Iyy": inertia[1, 1], "Izz": inertia[2, 2],
            "Ixy": inertia[0, 1], "Ixz": inertia[0, 2], "Iyz": inertia[1, 2]}


def _planar_pi(theta) -> dict:
    al, be, t1, t2 = (theta[k] for k in range(4))
    m = ca.exp(2 * al)
    return {"m": m, "mcx": m * t1, "mcy": m * t2, "Izz": m * (t1 ** 2 + t2 ** 2
                                                                 + ca.exp(2 * be))}


def _initial_theta(values, f) -> np.ndarray:
    """θ of a body's entries, projected onto the consistent set where they are not."""
    if "mcz" in f:
        j = _pseudo_inertia(values, f)
        w, v = np.linalg.eigh(0.5 * (j + j.T))
        floor = 1e-6 * max(float(np.max(np.abs(w))), 1e-12)
        return _spatial_theta_of((v * np.maximum(w, floor)) @ v.T)
    m = max(float(values[f["m"]]), 1e-6)
    c = np.array([values[f["mcx"]], values[f["mcy"]]]) / m
    gyr = max(float(values[f["Izz"]]) / m - c @ c, 1e-6 * max(c @ c, 1e-6))
    return np.array([0.5 * np.log(m), 0.5 * np.log(gyr), c[0], c[1]])


def consistent_parameters(names: list[str], basis: np.ndarray, estimate,
                          prior: np.ndarray, regularization: float = REGULARIZATION,
                          max_iter: int = 1000) -> ConsistentEstimate:
    """Physically consistent standard parameters that fit the base estimate best.

    Parameters
    ----------
    names : list of str
        Standard parameter names (``"<body>.m"``, …, ``"<joint>.viscous"``).
    basis : ndarray (n_b, n_π)
        K: π_b = K π.
    estimate : BaseEstimate
        π̂_b and the weighted normal matrix W_Gᵀ W_G
        (:func:`~casmbd.analysis.identification.estimate.least_squares`).
    prior : ndarray (n_π,)
        The prior standard parameters (the model file's values).
    regularization : float
        μ, the weight of ‖θ − θ_prior‖² (module docstring).

    Raises
    ------
    IdentificationError
        IPOPT fails (the message gives its status); at its iteration limit the iterate,
        consistent by construction, is returned with a warning and the status.
    """
    basis = np.asarray(basis, dtype=float)
    prior = np.asarray(prior, dtype=float).reshape(-1)
    n_pi = len(names)
    if basis.shape != (len(estimate.values), n_pi) or prior.shape != (n_pi,):
        raise IdentificationError(f"consistent parameters: K is {basis.shape}, the prior has "
                                  f"{prior.shape[0]} entries, for {len(estimate.values)} base "
                                  f"and {n_pi} standard parameters")
    bodies, joints = parameter_layout(names)
    normal = 0.5 * (estimate.normal_matrix + estimate.normal_matrix.T)
    n_hat = normal / max(float(estimate.weighted_norm2), np.finfo(float).tiny)
    mu = float(regularization)
    start = prior + np.linalg.pinv(basis) @ (estimate.values - basis @ prior)

    parts, x0, lbx, target = [], [], [], []
    pi = [None] * n_pi
    for f in bodies.values():
        size = 10 if "mcz" in f else 4
        theta = ca.SX.sym(f"theta_{len(parts)}", size)
        exprs = _spatial_pi(theta) if size == 10 else _planar_pi(theta)
        for key, k in f.items():
            pi[k] = exprs[key]
        parts.append(theta)
        x0.append(_initial_theta(start, f))
        target.append(_initial_theta(prior, f))
        lbx.append(np.full(size, -np.inf))
    for f in joints.values():
        for k in f.values():
            var = ca.SX.sym(f"friction_{k}")
            pi[k] = var
            parts.append(var)
            x0.append(np.array([max(float(start[k]), 0.0)]))
            target.append(np.array([max(float(prior[k]), 0.0)]))
            lbx.append(np.zeros(1))
    x = ca.vertcat(*parts)
    pi_x = ca.vertcat(*pi)
    r = ca.mtimes(ca.DM(basis), pi_x) - ca.DM(estimate.values)
    d = x - ca.DM(np.concatenate(target))
    weight = ca.SX.sym("mu")
    objective = ca.mtimes([r.T, ca.DM(n_hat), r]) + weight * ca.sumsqr(d)
    solver = ca.nlpsol("identify_consistent", "ipopt",
                       {"x": x, "p": weight, "f": objective},
                       {"print_time": False, "ipopt": {
                           "print_level": 0, "sb": "yes", "tol": 1e-12,
                           "acceptable_tol": 1e-9, "bound_push": 1e-10,
                           "bound_frac": 1e-10, "max_iter": int(max_iter)}})
    lower = np.concatenate(lbx)

    def solve(start, mu_k):
        try:
            out = solver(x0=start, lbx=lower, p=mu_k)
        except RuntimeError as exc:
            interrupts.reraise_interrupt(exc)
            raise IdentificationError(f"consistent parameters: IPOPT failed: {exc}") \
                from None
        interrupts.check()
        return out, solver.stats().get("return_status", "?")

    sol, status = solve(np.concatenate(x0), mu)
    if status == "Maximum_Iterations_Exceeded":  # every iterate is consistent: say so
        warnings.warn(f"consistent parameters: IPOPT stopped after {max_iter} iterations; "
                      "the set returned is physically consistent but may not fit best",
                      RuntimeWarning, stacklevel=2)
    elif status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
        raise IdentificationError(f"consistent parameters: IPOPT stopped with status "
                                  f"'{status}'")
    else:
        first = mu
        for k in range(1, REFINEMENTS + 1):  # a weaker pull, from the last solution
            refined, how = solve(np.asarray(sol["x"]).reshape(-1), first * 1e-2 ** k)
            if how not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
                break  # the best fit lies on the boundary: keep the stronger pull's
            sol, status, mu = refined, how, first * 1e-2 ** k
    values = np.array(ca.Function("pi_of_x", [x], [pi_x])(sol["x"])).reshape(-1)
    polished = values + np.linalg.pinv(basis) @ (estimate.values - basis @ values)
    friction = [k for f in joints.values() for k in f.values()]
    if friction:
        level = 1e-12 * max(1.0, float(np.max(np.abs(polished[friction]))))
        near = [k for k in friction if -level <= polished[k] < 0.0]
        polished[near] = 0.0
    try:
        good = physical_checks(names, polished)["consistent"]
    except IdentificationError:
        good = False
    if good:
        values = polished
    return ConsistentEstimate(list(names), values, basis @ values, status,
                              float(sol["f"]), physical_checks(names, values), mu, bool(good))
