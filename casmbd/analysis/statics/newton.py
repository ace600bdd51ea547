"""The trust-region Newton search of a static equilibrium (both methods).

The iteration of the module docstring of :mod:`~casmbd.analysis.statics.statics`: a
trust-region step in the tangent space of the constraints, globalised on the residual ½‖F‖²
(the equilibrium nearest the start,
:func:`~casmbd.analysis.statics.trust_region.least_squares_step`) or on the potential energy (a
stable one, :func:`~casmbd.analysis.statics.trust_region.trust_region_step`), with a
second-order correction of boundary steps and a pure Newton polish at convergence.
:func:`search` runs it, falls back to the potential descent when the residual search fails,
and leaves unstable equilibria when a stable one is asked for.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.statics.equilibrium_problem import (
    Iterate,
    StaticsProblem,
    null_space,
    principal_range,
)
from casmbd.analysis.statics.stability import Stability, classify_stability
from casmbd.analysis.statics.trust_region import RANK_RTOL, least_squares_step, trust_region_step
from casmbd.errors import AnalysisError, AssemblyError

__all__ = ["ACCEPT_RATIO", "ESCAPE_STEP", "INITIAL_RADIUS", "MAX_ESCAPES", "MAX_RADIUS",
           "NOISE_FACTOR", "STALL_RADIUS", "STALL_RTOL", "search"]

#: trust region (scaled units: radians, Euler parameters, mechanism sizes): start, largest
INITIAL_RADIUS, MAX_RADIUS = 0.5, 1.0
#: accepted when the work along the step is at least this fraction of the model's prediction
ACCEPT_RATIO = 0.1
#: eigenvalues of the reduced stiffness below NOISE_FACTOR · ‖g‖ count as zero in the step
#: (off an equilibrium they are known only to O(‖g‖); measured up to 2.4 ‖g‖ on the arms)
NOISE_FACTOR = 10.0
#: the residual search: a step predicting less than this fraction of ½‖F‖² (a stationary point
#: of ‖F‖ that is not an equilibrium) is replaced by one descent step on the potential; a
#: trust region below STALL_RADIUS hands the search over to the descent
STALL_RTOL, STALL_RADIUS = 1e-12, 1e-10
#: leaving an unstable equilibrium when a stable one is asked for: the step along the downhill
#: eigenvector (scaled units) and the most such restarts
ESCAPE_STEP, MAX_ESCAPES = 0.1, 5


def _solve(matrix: sp.spmatrix, rhs: np.ndarray) -> np.ndarray:
    """Sparse LU solution, or least squares when the matrix is singular."""
    try:
        x = spla.splu(sp.csc_matrix(matrix)).solve(rhs)
        if np.all(np.isfinite(x)) and np.linalg.norm(matrix @ x - rhs) <= 1e-8 * max(
                1.0, np.linalg.norm(rhs)):
            return x
    except RuntimeError:
        pass
    x, *_ = sla.lstsq(matrix.toarray(), rhs, cond=RANK_RTOL, lapack_driver="gelsd")
    return x


def _converged(prob: StaticsProblem, f: np.ndarray, fscale: float, lscale: float) -> bool:
    return (float(np.max(np.abs(f[:prob.nq]), initial=0.0)) <= fscale
            and float(np.max(np.abs(f[prob.nq:]), initial=0.0)) <= lscale)


def _fail(prob: StaticsProblem, why: str, it: int, f: np.ndarray, method: str):
    raise AnalysisError(
        f"no static equilibrium found at t = {prob.t:g} ({method} Newton): {why} after {it} "
        f"iterations, residual max |F| = {np.max(np.abs(f), initial=0.0):.3g}; largest "
        f"residuals: {prob.worst(f)}")


def _iterate(prob: StaticsProblem, q, method: str, fscale: float, lscale: float, max_iter: int,
             stable: bool = False):
    """The trust-region iteration of both methods (module docstring): globalised on the
    residual (``stable`` False, the equilibrium nearest the start) or on the potential energy
    (``stable`` True).  Returns (q, λ, iterations, residual history, notes)."""
    state = Iterate(prob, q, prob.multipliers(q), fscale, lscale)
    history = [float(np.max(np.abs(state.f), initial=0.0))]
    radius, it = INITIAL_RADIUS, 0
    notes: list[str] = []
    descend = stable  # the whole search descends the potential (a stable equilibrium)
    while True:
        f = state.f
        if not np.all(np.isfinite(f)):
            _fail(prob, "non-finite residual", it, np.where(np.isfinite(f), f, np.inf), method)
        if _converged(prob, f, fscale, lscale):
            polished = _polish(prob, state, method, fscale, lscale)
            if polished is not None:
                state, it = polished, it + 1
                history.append(float(np.max(np.abs(state.f), initial=0.0)))
            break
        if it >= max_iter:
            _fail(prob, "not converged", it, f, method)
        it += 1
        step, dn, n, k, kind, state = _step(prob, state, method, radius, descend, fscale, lscale,
                                            it)
        kkt = method == "augmented" and step.newton
        trial = _trial(prob, state, dn + n @ step.dz, k, kkt, fscale, lscale)
        if trial is not None and kind == "residual" and not step.newton:
            trial = _corrected(prob, trial, step.nu, fscale, lscale) or trial
        accepted, ratio = False, 0.0
        if trial is not None:
            newton_ok = step.newton and trial.norm < state.norm
            if kind == "descent":  # the fall of V (or the work of the applied forces)
                if prob.conservative:  # against the model's
                    work = prob.potential(state.q) - prob.potential(trial.q)
                else:
                    work = 0.5 * float((state.qe + trial.qe) @ (trial.q - state.q))
                if step.predicted > 0.0:
                    ratio = work / step.predicted
                else:
                    ratio = 1.0 if work >= 0.0 else -1.0
            elif step.predicted > 0.0:  # the decrease of ½‖F‖² against the model's
                ratio = 0.5 * (state.norm**2 - trial.norm**2) / step.predicted
            else:
                ratio = 1.0 if trial.norm < state.norm else -1.0
            accepted = newton_ok if kkt else (ratio >= ACCEPT_RATIO or newton_ok)
        size = float(np.linalg.norm(step.dz))
        if not accepted or (ratio < 0.25 and not step.newton):
            radius = 0.25 * min(radius, max(size, 1e-16))
        elif ratio > 0.75 and size >= 0.99 * radius:
            radius = min(2.0 * radius, MAX_RADIUS)
        if accepted and kind == "descent" and not descend and trial.norm > state.norm:
            # off a local minimum of ‖F‖ that is no equilibrium (the residual search would
            # return to it): descend the potential from here on
            descend = True
            notes.append(f"the residual has a local minimum that is no equilibrium at "
                         f"iteration {it} (max |F| = {np.max(np.abs(f), initial=0.0):.3g}); "
                         f"continued by descending the potential energy")
        if accepted:
            state = trial
        elif radius < STALL_RADIUS and not descend:
            # the residual has a local minimum that is not an equilibrium: descend instead
            descend, radius = True, INITIAL_RADIUS
            notes.append(f"the residual search stalled at iteration {it} (max |F| = "
                         f"{np.max(np.abs(f), initial=0.0):.3g}); continued by descending the "
                         f"potential energy")
        elif radius < 1e-12:
            # at the rounding floor of the equations no step is accepted any more: pure
            # Newton steps from here end it if they reach the tolerance
            for _ in range(3):
                polished = _polish(prob, state, method, fscale, lscale)
                if polished is None:
                    break
                state = polished
                if _converged(prob, state.f, fscale, lscale):
                    break
            if not _converged(prob, state.f, fscale, lscale):
                _fail(prob, "no acceptable step (trust region collapsed)", it, state.f, method)
            notes.append(f"the trust region collapsed at max |F| = "
                         f"{np.max(np.abs(f), initial=0.0):.3g}; Newton steps converged")
            history.append(float(np.max(np.abs(state.f), initial=0.0)))
            break
        history.append(float(np.max(np.abs(state.f), initial=0.0)))
    return state.q, state.lam, it, history, notes


def _step(prob: StaticsProblem, state: Iterate, method: str, radius: float, descend: bool,
          fscale: float, lscale: float, it: int):
    """The step of one iteration: (step, normal step dn, N, K, kind, state), kind "residual"
    (:func:`~casmbd.analysis.statics.trust_region.least_squares_step` on the residual) or "descent"
    (:func:`~casmbd.analysis.statics.trust_region.trust_region_step` on the potential: the whole
    search with ``descend``, else one step off a stationary point of the residual that is not
    an equilibrium).  A step that is not Newton's is taken from the constraint manifold (the
    state is assembled first when the normal step is not zero)."""
    nq = prob.nq
    for attempt in range(2):
        n, k, g, kbar = prob.tangent(state.q, state.lam)
        dn = np.zeros(nq)
        if method == "augmented" and prob.nc and attempt == 0:  # normal step C_q dn = −C
            dn_s, *_ = sla.lstsq(prob.cq(state.q) * prob.scale, -state.f[nq:], cond=RANK_RTOL,
                                 lapack_driver="gelsd")
            dn = prob.scale * dn_s
            g = g - n.T @ k @ dn
        noise = NOISE_FACTOR * np.linalg.norm(g)
        kind = "descent" if descend else "residual"
        if not descend:
            b, a, noise_b = _residual_model(n, g, kbar, noise, fscale)
            step = least_squares_step(b, a, radius, noise=noise_b)
            if step.predicted <= STALL_RTOL * 0.5 * state.norm**2 and not step.newton:
                kind = "descent"  # a stationary point of ‖F‖: leave it downhill
        if kind == "descent":
            step = trust_region_step(g, kbar, radius, noise=noise)
        if step.newton or not np.any(dn):
            return step, dn, n, k, kind, state
        try:  # globalise from the constraint manifold
            q_on = assemble(prob.model, state.q, prob.t).q
        except AssemblyError:
            _fail(prob, "the iterate left the constraint manifold", it, state.f, method)
        state = Iterate(prob, q_on, prob.multipliers(q_on), fscale, lscale)
    return step, np.zeros(nq), n, k, kind, state


def _residual_model(n: np.ndarray, g: np.ndarray, kbar: np.ndarray, noise: float,
                    fscale: float):
    """(b, A, noise) of the Gauss–Newton model ½‖b − A dz‖² of ½‖F‖²: ‖Q_e − C_qᵀλ‖ = ‖R⁻ᵀ g‖
    with N = Q R (λ the least-squares multipliers), in the units of the convergence test."""
    r_inv_t = sla.solve_triangular(np.linalg.qr(n)[1], np.eye(n.shape[1]), trans="T") \
        if n.shape[1] else np.zeros((0, 0))
    return (r_inv_t @ g / fscale, r_inv_t @ kbar / fscale,
            noise / fscale * float(np.linalg.norm(r_inv_t, 2)) if n.shape[1] else 0.0)


def _corrected(prob: StaticsProblem, trial: Iterate, nu: float, fscale, lscale) -> Iterate | None:
    """The second-order correction of a Levenberg–Marquardt step with shift ν: from the trial
    point, the step of the same ν on the model there (it settles the directions stiffer than
    ν — a stiff spring stretched by a straight step across a curved valley — and hardly moves
    the others), assembled; None if it does not lower the residual."""
    n, k, g, kbar = prob.tangent(trial.q, trial.lam)
    b, a, noise = _residual_model(n, g, kbar, NOISE_FACTOR * np.linalg.norm(g), fscale)
    step = least_squares_step(b, a, np.inf, noise=noise, shift=nu)
    corrected = _trial(prob, trial, n @ step.dz, k, False, fscale, lscale)
    return corrected if corrected is not None and corrected.norm < trial.norm else None


def _trial(prob: StaticsProblem, state: Iterate, dq, k, kkt: bool, fscale,
           lscale) -> Iterate | None:
    """The iterate after the step dq, or None (assembly failed, a mirror-image body).

    ``kkt``: the Newton step on (q, λ) of the augmented method, λ⁺ from the first block row
    of the KKT system (no assembly); otherwise the dependent coordinates are restored by
    assembly and λ⁺ is the least-squares multiplier."""
    if kkt:
        qt = state.q + dq
        lt = prob.multipliers(state.q, state.qe - k @ dq) if prob.nc else np.zeros(0)
    else:
        try:
            qt = assemble(prob.model, state.q + dq, prob.t).q
        except AssemblyError:
            return None
        lt = prob.multipliers(qt)
    if prob.improper(qt) is not None:
        return None
    trial = Iterate(prob, qt, lt, fscale, lscale)
    return trial if np.isfinite(trial.norm) else None


def _polish(prob: StaticsProblem, state: Iterate, method: str, fscale, lscale) -> Iterate | None:
    """One pure Newton step at a converged iterate, kept if it does not raise the residual."""
    if state.norm == 0.0:
        return None
    nq = prob.nq
    if method == "augmented":
        step = _solve(prob.jacobian(state.q, state.lam), -state.f)
        qt, lt = state.q + step[:nq], state.lam + step[nq:]
    else:
        n, _, g, kbar = prob.tangent(state.q, state.lam)
        step = trust_region_step(g, kbar, MAX_RADIUS, noise=NOISE_FACTOR * np.linalg.norm(g))
        if not step.newton:
            return None
        try:
            qt = assemble(prob.model, state.q + n @ step.dz, prob.t).q
        except AssemblyError:
            return None
        lt = prob.multipliers(qt)
    if prob.improper(qt) is not None:
        return None
    trial = Iterate(prob, qt, lt, fscale, lscale)
    return trial if trial.norm <= state.norm else None


def _classify(prob: StaticsProblem, q, lam) -> tuple[Stability, np.ndarray]:
    """The stability verdict at (q, λ) and the orthonormal basis N of ker C_q it used."""
    model = prob.model
    jqq = prob.jacobian(q, lam)[:prob.nq, :prob.nq].toarray()
    n = null_space(prob.cq(q), prob.nq)
    if model.joint_coordinate_names:
        directions = model.sparse("statics_joint_jacobian", q, prob.t, model.p).toarray() @ n
        labels = list(model.joint_coordinate_names)
    else:
        directions, labels = n, list(model.coordinate_names)
    return classify_stability(n.T @ (-jqq) @ n, directions, labels), n


def _leave(prob: StaticsProblem, q, lam, n: np.ndarray) -> np.ndarray:
    """A configuration off the unstable equilibrium q: a step of :data:`ESCAPE_STEP` (scaled
    units) along the eigenvector of the lowest (negative) eigenvalue of K̄, assembled; the
    potential energy falls along it (by ½ μ_min ‖δz‖² to second order)."""
    jqq = prob.jacobian(q, lam)[:prob.nq, :prob.nq].toarray()
    kbar = n.T @ (-jqq) @ n
    _, vec = np.linalg.eigh(0.5 * (kbar + kbar.T))
    dq = n @ vec[:, 0]
    dq *= ESCAPE_STEP / max(float(np.linalg.norm(dq / prob.scale)), 1e-300)
    dq *= 1.0 if dq[int(np.argmax(np.abs(dq)))] > 0.0 else -1.0  # a reproducible side
    for trial in (q + dq, q - dq):
        try:
            q_new = assemble(prob.model, trial, prob.t).q
        except AssemblyError:
            continue
        if prob.improper(q_new) is None:
            return q_new
    return q


def search(prob: StaticsProblem, q, method: str, fscale: float, lscale: float, max_iter: int,
           stable: bool):
    """The equilibrium from the assembled start q: the iteration (:func:`_iterate`) and, when
    the residual search fails, the potential descent from the same start; angles to their
    principal range; with ``stable``, unstable equilibria left along the downhill eigenvector
    (:func:`_leave`, at most :data:`MAX_ESCAPES` times).  Returns (q, λ, iterations, residual
    history, notes, stability, N)."""
    try:
        q, lam, it, history, notes = _iterate(prob, q, method, fscale, lscale, max_iter, stable)
    except AnalysisError as exc:
        if stable:
            raise
        # the residual search failed (a long, narrow valley of ‖F‖ that it crawls along):
        # a stable equilibrium from the same start, by the potential descent
        q, lam, it, history, notes = _iterate(prob, q, method, fscale, lscale, max_iter, True)
        notes.insert(0, f"the search for the nearest equilibrium failed ({exc}); this is the "
                        f"stable equilibrium the potential descent found from the same start")
    q = principal_range(prob, q, lam, fscale, lscale)
    stability, n = _classify(prob, q, lam)
    escapes = 0
    while stable and stability.verdict == "unstable" and escapes < MAX_ESCAPES \
            and it < max_iter:
        escapes += 1
        q = _leave(prob, q, lam, n)
        q, lam, more, hist, more_notes = _iterate(prob, q, method, fscale, lscale,
                                                 max_iter - it, stable)
        it, history, notes = it + more, history + hist, notes + more_notes
        q = principal_range(prob, q, lam, fscale, lscale)
        stability, n = _classify(prob, q, lam)
    if escapes:
        notes.append(f"left {escapes} unstable equilibri{'a' if escapes > 1 else 'um'} along "
                     f"the downhill eigenvector of the reduced stiffness")
    if stable and stability.verdict == "unstable":
        notes.append("a stable equilibrium was asked for, but the search ended at an unstable "
                     f"one (lowest stiffness eigenvalue {stability.eigenvalues[0]:.4g})")
    return q, lam, it, history, notes, stability, n
