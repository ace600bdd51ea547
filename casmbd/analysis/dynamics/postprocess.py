"""A simulation's outputs from its states, and the diagnosis of a failed run.

A collaborator of :class:`casmbd.analysis.dynamics.simulate.Simulator` (its ``post``), built on the
compiled model, the redundancy plan and the inputs Function: at every output time q̈ and λ from the
sparse KKT system (a minimum-norm solve at singular points), joint reactions (seed 000, eqs.
6.145–6.151), driver efforts (−λ of the driver row), energies, constraint violations and
conditioning, collected in a :class:`~casmbd.results.Result`; and, where a run failed, the
rank and conditioning of C_q (or the model value that is not finite) for the error message.

A run whose position constraints are violated beyond the tolerance at an output time,
max |C| > :data:`DRIFT_LIMIT` · size (size: the largest |coordinate| of a body's centre of mass
so far, at least 1 m), stops with a :class:`~casmbd.errors.ConstraintViolationError` naming
the first such time and the cause — as kinematics does: the assembly C(q, t) = 0 is tried at
that time from the last good output, and when it fails its ranked culprits (the driver asking
for a pose the joints forbid, the joint it contradicts) are named; when it succeeds the
trajectory drifted off constraints that could be satisfied (a diverging model, tolerances far
too loose) and the equations with the largest residuals are named.  The results before that
time are kept (``exc.partial``).
"""

from __future__ import annotations

import numpy as np

from casmbd.analysis.instant.assembly import assemble
from casmbd.analysis.instant.checks import diagnose_failure
from casmbd.analysis.instant.kkt import accelerations_and_multipliers
from casmbd.analysis.instant.redundancy import (
    NEAR_SINGULAR,
    conditioning,
    equilibrated_singular_values,
    near_singular_passes,
    rank_report,
    reference_equilibration,
)
from casmbd.analysis.instant.tyre_forces import tyre_forces
from casmbd.analysis.instant.undetermined_reactions import flag_undetermined, multiplier_null_space
from casmbd.errors import (
    AssemblyError,
    CasmbdError,
    ConstraintViolationError,
    IntegratorError,
)
from casmbd.interrupts import reraise_interrupt
from casmbd.model.measures import result_names
from casmbd.results import Result

#: position constraint violation, relative to the mechanism's size (the largest |coordinate| of
#: a body's centre of mass so far, at least 1 m), above which a run stops: its trajectory no
#: longer satisfies the joints
DRIFT_LIMIT = 1e-3


def first_violation(result: Result) -> tuple[int, float] | None:
    """The first output index whose position constraint violation max |C| exceeds
    :data:`DRIFT_LIMIT` · size (or is not finite), and that size; None when there is none."""
    viol = result.arrays.get("constraint_violation")
    if viol is None or not viol.size:
        return None
    positions = result.arrays.get("body_positions")
    if positions is None or not positions.size:
        reach = np.zeros(len(viol))
    else:
        reach = np.nanmax(np.abs(positions.reshape(len(viol), -1)), axis=1, initial=0.0)
    size = np.maximum(1.0, np.fmax.accumulate(np.nan_to_num(reach, nan=0.0, posinf=0.0)))
    bad = np.flatnonzero(~np.isfinite(viol) | (viol > DRIFT_LIMIT * size))
    return (int(bad[0]), float(size[bad[0]])) if bad.size else None


#: the names (in ``Result.names``) of the columns of result arrays, by array name or prefix
_COLUMNS = {"q": "coordinates", "v": "coordinates", "a": "coordinates",
            "lambda": "constraints", "body": "bodies", "angle": "bodies", "marker": "markers",
            "joint": "joints", "node": "nodes"}
#: arrays that hold NaN by design (not evaluated there)
_NAN_BY_DESIGN = frozenset({"constraint_conditioning"})
#: arrays of the user's own expressions (a value that is not finite is the expression's)
USER_ARRAYS = frozenset({"outputs", "force_outputs"})


def _column_name(result: Result, key: str, col: int, n_cols: int) -> str:
    """``key`` and the name of its column ``col``: ``"v 'slide.translation'"``,
    ``"body_positions 'block' [1]"``, ``"outputs 'root'"``; the bare key for one column."""
    labels = result.names.get(key) or result.names.get(_COLUMNS.get(key, "")) \
        or result.names.get(_COLUMNS.get(key.split("_")[0], ""), [])
    labels = [str(x) for x in labels] if isinstance(labels, (list, tuple)) else []
    if labels and n_cols == len(labels):
        return f"{key} '{labels[col]}'"
    if labels and n_cols % len(labels) == 0:  # several components per named item
        per = n_cols // len(labels)
        return f"{key} '{labels[col // per]}' [{col % per}]"
    return key if n_cols == 1 else f"{key} [{col}]"


def first_non_finite(result: Result) -> tuple[int, str, float] | None:
    """The first output index at which a result array holds a value that is not finite, the
    quantity (array and column, e.g. ``"v 'slide.translation'"``) and the value; None when
    every value is finite.  At a tie the states q, v come first, then q̈, λ and the arrays
    derived from them."""
    n_t = len(result.t)
    first = None
    order = ["q", "v", "a", "lambda"] + [k for k in result.arrays
                                         if k not in ("q", "v", "a", "lambda")]
    for key in order:
        arr = result.arrays.get(key)
        if key in _NAN_BY_DESIGN or not isinstance(arr, np.ndarray) or arr.ndim < 1 \
                or arr.shape[0] != n_t or not arr.size or arr.dtype.kind != "f":
            continue
        flat = arr.reshape(n_t, -1)
        bad_rows = np.flatnonzero(~np.all(np.isfinite(flat), axis=1))
        if bad_rows.size and (first is None or bad_rows[0] < first[0]):
            k = int(bad_rows[0])
            col = int(np.flatnonzero(~np.isfinite(flat[k]))[0])
            first = (k, _column_name(result, key, col, flat.shape[1]), float(flat[k, col]))
    return first


def truncated(result: Result, n: int) -> Result:
    """``result`` at its first ``n`` output times (arrays along time sliced, events after the
    last kept time dropped): the partial results of a run stopped after them."""
    n_t = len(result.t)
    arrays = {k: (a[:n] if getattr(a, "ndim", 0) >= 1 and a.shape[0] == n_t else a)
              for k, a in result.arrays.items()}
    t_last = float(result.t[n - 1])
    return Result(result.kind, result.t[:n].copy(), arrays, dict(result.names),
                  dict(result.stats), result.scene,
                  [e for e in result.events if float(e.get("time", 0.0)) <= t_last])


class PostProcessing:
    """Outputs and failure diagnosis of a simulation on the compiled ``model`` (a
    :class:`~casmbd.compiled.model.NumericModel`), with the ``redundancy`` plan of
    :func:`~casmbd.analysis.dynamics.simulate.plan_redundancy` and the inputs Function ``ufun``
    u(t, p); the :class:`~casmbd.analysis.dynamics.simulate.Simulator`'s ``post``."""

    def __init__(self, model, redundancy: dict, ufun):
        self.model, self.redundancy, self.ufun = model, redundancy, ufun
        self._maps: dict = {}  # (name, n) -> the Function mapped over n points, made once

    def _mapped(self, f, n: int):
        """``f.map(n)``, made once per (Function, n): a run of the same length reuses it
        (CasADi's map is ~45 µs to make, what a short run costs in all)."""
        key = (f.name(), n)
        mapped = self._maps.get(key)
        if mapped is None:
            if len(self._maps) > 32:
                self._maps.clear()
            mapped = self._maps[key] = f.map(n)
        return mapped

    def diagnose(self, result: Result, t_fail: float) -> str:
        """Rank and conditioning of C_q where a run failed: at the state extrapolated from the
        last kept output, q + h q̇ + ½ h² q̈ with h = t_fail − t_last (an estimate, accurate to
        O(h³), enough to tell a singular pose)."""
        culprits = diagnose_failure(self.model, t_fail)
        if culprits:  # a model value that is not finite where the run stopped
            return "; " + "; ".join(culprits[:3])
        if self.model.nc == 0 or not len(result.t):
            return ""
        t = float(result.t[-1])
        h = max(0.0, float(t_fail) - t) if np.isfinite(t_fail) else 0.0
        q = result["q"][-1] + h * result["v"][-1] + 0.5 * h * h * result["a"][-1]
        t += h
        rep = rank_report(self.model.constraint_jacobian(q, t))
        # scaled like the conditioning monitor: by the factors of the run's first step
        sigma = equilibrated_singular_values(
            self.model.constraint_jacobian(q, t),
            reference_equilibration(self.model, result["q"], result.t))
        rank0 = self.redundancy.get("constraint_rank", rep.rank)
        ratio = sigma[rank0 - 1] / sigma[0] if rank0 >= 1 and sigma[0] > 0 else float("nan")
        text = (f"; at t ≈ {t:.6g} C_q has rank {rep.rank} of {rep.n_equations} equations "
                f"(regular rank {rank0}), conditioning σ_min/σ_max = {ratio:.2e}")
        if rep.rank < rank0 or ratio < NEAR_SINGULAR:
            labels = self.model.constraint_labels
            dep = ", ".join(str(labels[i]) for i in rep.dependent_rows[:4])
            text += (": a singular configuration" + (f" (dependent: {dep})" if dep else "")
                     + "; the augmented_lagrangian formulation passes singular poses")
        return text

    def check_violation(self, result: Result) -> None:
        """Stop a run whose position constraints are violated beyond the tolerance
        (:func:`first_violation`): a :class:`~casmbd.errors.ConstraintViolationError` naming
        the time, the size and the driver or joint at fault, with the results before it."""
        found = first_violation(result)
        if found is None:
            return
        k, size = found
        viol = float(result.arrays["constraint_violation"][k])
        t = float(result.t[k])
        n_kept = max(k, 1)
        cause, culprits = self._violation_cause(result, k)
        partial = truncated(result, n_kept)
        partial.stats["failure_time"] = t
        raise ConstraintViolationError(
            f"simulation: position constraints violated by {viol:.3g} at t = {t:.6g} "
            f"(> {DRIFT_LIMIT:g} × size {size:.3g}); results kept up to t = "
            f"{result.t[n_kept - 1]:.6g} ({n_kept} of {len(result.t)} output times){cause}",
            t, partial=partial, culprits=culprits)

    def check_finite(self, result: Result) -> None:
        """Stop a run whose results hold a value that is not finite (:func:`first_non_finite`):
        an :class:`~casmbd.errors.IntegratorError` (flag ``NON_FINITE``) naming the quantity
        and the first such output time, with the results before it; never a silent NaN."""
        found = first_non_finite(result)
        if found is None:
            return
        k, what, value = found
        t = float(result.t[k])
        n_kept = max(k, 1)
        partial = truncated(result, n_kept)
        partial.stats["failure_time"] = t
        hint = ("its expression is not finite there" if what.split(" ")[0] in USER_ARRAYS
                else "a stiff model under a loose tolerance (tighten --rtol, raise "
                "--max-steps) or a diverging model")
        raise IntegratorError(
            f"simulation: {what} is {value} at t = {t:.6g}, the first value that is not "
            f"finite; results kept up to t = {result.t[n_kept - 1]:.6g} ({n_kept} of "
            f"{len(result.t)} output times): {hint}", t, "NON_FINITE", partial=partial)

    def _violation_cause(self, result: Result, k: int) -> tuple[str, list]:
        """Why the constraints are violated at output ``k``: the assembly at that time from
        the last good output, extrapolated (q + h q̇ + ½ h² q̈, as kinematics guesses); its
        failure names the culprits, its success means the trajectory drifted off."""
        model = self.model
        t = float(result.t[k])
        j = max(k - 1, 0)
        h = t - float(result.t[j])
        q, v, a = (np.asarray(result[key][j], float) for key in ("q", "v", "a"))
        guess = q + h * v + 0.5 * h * h * a
        if not np.all(np.isfinite(guess)):
            guess = q
        try:
            assemble(model, guess, t)
        except AssemblyError as exc:
            return f". The joints and drivers cannot be satisfied there: {exc}", exc.culprits
        except CasmbdError as exc:
            return f". {exc}", []
        q_k = np.asarray(result["q"][k], float)
        residual = np.asarray(model.constraints(q_k, t), float) if np.all(np.isfinite(q_k)) \
            else np.full(model.nc, np.nan)
        labels = model.constraint_labels
        order = np.argsort(-np.nan_to_num(np.abs(residual), nan=np.inf))[:3]
        worst = "; ".join(f"{labels[i]} residual {residual[i]:.3g}" for i in order)
        return (f". The joints and drivers can be satisfied at t = {t:.6g}, but the trajectory "
                f"left them (a diverging model, or tolerances too loose): largest residuals "
                f"{worst}", [])

    def _post_by_parts(self, grid, qs, vs):
        """Energies and constraint residuals from the model's own Functions, q̈ and λ as NaN
        (re-solved by the minimum-norm KKT solve), when the mapped ``post`` cannot be
        evaluated (the virtual machine's QR refuses a singular KKT matrix)."""
        model, n = self.model, len(grid)
        acc = np.full((n, model.nq), np.nan)
        lam = np.full((n, model.nc), np.nan)
        kin = np.array([model.kinetic_energy(qs[k], vs[k]) for k in range(n)])
        pot = np.array([model.potential_energy(qs[k], float(grid[k])) for k in range(n)])
        pos, vel = np.zeros(n), np.zeros(n)
        if model.nc:
            for k in range(n):
                t_k = float(grid[k])
                pos[k] = np.max(np.abs(model.constraints(qs[k], t_k)))
                vel[k] = np.max(np.abs(model.constraint_jacobian(qs[k], t_k) @ vs[k]
                                       + model.constraint_time_derivative(qs[k], t_k)))
        return acc, lam, np.full(n, np.nan), kin, pot, pos, vel

    def outputs(self, grid, qs, vs, stats) -> Result:
        # names and sizes from the model: a simulator from the cache has no System built
        model = system = self.model
        n = len(grid)
        p_all = np.tile(model.p[:, None], (1, n))
        try:
            post = self._mapped(model.function("post"), n)(qs.T, vs.T, grid[None, :], p_all)
            acc, lam = np.asarray(post[0]).T.copy(), np.asarray(post[1]).T.reshape(n, -1).copy()
            residual = np.asarray(post[2]).ravel()
            kin, pot, pos_viol, vel_viol = (np.asarray(x).ravel() for x in post[3:7])
        except RuntimeError as exc:  # CasADi's VM QR raises on a singular KKT matrix
            reraise_interrupt(exc)
            acc, lam, residual, kin, pot, pos_viol, vel_viol = self._post_by_parts(grid, qs, vs)
        us = np.asarray(self._mapped(self.ufun, n)(grid[None, :], p_all)).T.reshape(n, -1)
        # singular KKT matrices (redundant constraints, singular poses): minimum-norm solve
        scale = 1.0 + np.max(np.abs(np.concatenate([acc, lam], axis=1)), axis=1,
                             initial=0.0)
        finite = np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(lam), axis=1)
        redundant = bool(self.redundancy.get("redundant_equations"))
        if redundant:  # the compiled QR solve of a singular KKT matrix cannot be trusted
            singular = np.arange(n)
        else:
            singular = np.flatnonzero(~np.isfinite(residual) | ~finite
                                      | (residual > 1e-8 * np.where(finite, scale, 1.0)))
        for k in singular:
            acc[k], lam[k] = accelerations_and_multipliers(model, qs[k], vs[k], grid[k], us[k],
                                                           redundant=redundant)
        outputs = model.outputs(qs, vs, acc, grid, self._mapped(model.function("outputs"), n))
        reac = np.asarray(self._mapped(model.function("joint_reactions"), n)(
            qs.T, vs.T, acc.T, grid[None, :], us.T, np.tile(model.p[:, None], (1, n)),
            lam.T)) \
            if system.mechanism.joints else np.zeros((3, 0))
        n_j, size = len(system.mechanism.joints), system.reaction_size
        reactions = reac.reshape(size, n, n_j).transpose(1, 2, 0) if n_j else \
            np.zeros((n, 0, size))
        if n_j and system.nc:
            first = multiplier_null_space(model.constraint_jacobian(qs[0], float(grid[0])))
            steps = range(n) if first.shape[1] else singular
            reactions, flags = flag_undetermined(model, qs, vs, acc, grid, us, lam, reactions,
                                                 steps)
            stats = {**stats, **flags}
        cond = conditioning(model, qs, grid, self.redundancy.get("constraint_rank"),
                            extra=singular)
        passes = near_singular_passes(model, grid, qs, vs, cond,
                                      self.redundancy.get("constraint_rank"))
        stats = {**stats, "min_constraint_conditioning": min(
            [float(np.nanmin(cond))] + [c for _, c in passes]) if np.any(np.isfinite(cond))
            else None, "near_singular_times": [t for t, _ in passes]}
        drivers = list(system.mechanism.drivers)
        # λ is minimum-norm (flag_undetermined): two drivers on one coordinate share the effort
        efforts = np.column_stack([-lam[:, system.driver_rows[d]] for d in drivers]) \
            if drivers else np.zeros((n, 0))
        names = {"coordinates": system.coordinate_names, "bodies": system.body_names,
                 "markers": list(system.mechanism.markers),
                 "joints": system.joint_coordinate_names,
                 "all_joints": list(system.mechanism.joints), "drivers": drivers,
                 "actuators": list(system.mechanism.actuators),
                 "constraints": [str(lab) for lab in system.constraint_labels],
                 **result_names(system.mechanism)}  # requests and force reports
        arrays = {"q": qs, "v": vs, "a": acc, "lambda": lam, **outputs,
                  "joint_reactions": reactions, "driver_efforts": efforts,
                  "actuator_inputs": us, "kinetic_energy": kin, "potential_energy": pot,
                  "total_energy": kin + pot, "constraint_violation": pos_viol,
                  "velocity_violation": vel_viol, "constraint_conditioning": cond}
        if getattr(model, "velocity_rows", None):  # rolling rows: their forces, by row
            arrays["tyre_forces"], names["tyre_forces"] = tyre_forces(model, lam)
        return Result("simulation", grid, arrays, names, stats).attach_scene(system.mechanism)
