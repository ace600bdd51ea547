"""A simulation's outputs from its states, and the diagnosis of a failed run.

A mixin of :class:`casmbd.analysis.simulate.Simulator`: at every output time q̈ and λ from the
sparse KKT system (a minimum-norm solve at singular points), joint reactions (seed 000, eqs.
6.145–6.151), driver efforts (−λ of the driver row), energies, constraint violations and
conditioning, collected in a :class:`~casmbd.results.Result`; and, where a run failed, the
rank and conditioning of C_q (or the model value that is not finite) for the error message.
"""

from __future__ import annotations

import numpy as np

from casmbd.analysis.checks import diagnose_failure
from casmbd.analysis.kkt import accelerations_and_multipliers
from casmbd.analysis.reactions import flag_undetermined, multiplier_null_space
from casmbd.analysis.redundancy import (
    NEAR_SINGULAR,
    conditioning,
    equilibrated_singular_values,
    near_singular_passes,
    rank_report,
    reference_equilibration,
)
from casmbd.interrupts import reraise_interrupt
from casmbd.model.measures import result_names
from casmbd.results import Result


class PostProcessing:
    """Outputs and failure diagnosis of the :class:`~casmbd.analysis.simulate.Simulator`."""

    def _diagnose(self, result: Result, t_fail: float) -> str:
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

    def _post(self, grid, qs, vs, stats) -> Result:
        # names and sizes from the model: a simulator from the cache has no System built
        model = system = self.model
        n = len(grid)
        p_all = np.tile(model.p[:, None], (1, n))
        try:
            post = model.function("post").map(n)(qs.T, vs.T, grid[None, :], p_all)
            acc, lam = np.asarray(post[0]).T.copy(), np.asarray(post[1]).T.reshape(n, -1).copy()
            residual = np.asarray(post[2]).ravel()
            kin, pot, pos_viol, vel_viol = (np.asarray(x).ravel() for x in post[3:7])
        except RuntimeError as exc:  # CasADi's VM QR raises on a singular KKT matrix
            reraise_interrupt(exc)
            acc, lam, residual, kin, pot, pos_viol, vel_viol = self._post_by_parts(grid, qs, vs)
        us = np.asarray(self.ufun.map(n)(grid[None, :], p_all)).T.reshape(n, -1)
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
        outputs = model.outputs(qs, vs, acc, grid)
        reac_f = model.function("joint_reactions").map(n)
        reac = np.asarray(reac_f(qs.T, vs.T, acc.T, grid[None, :], us.T,
                                 np.tile(model.p[:, None], (1, n)), lam.T)) \
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
        return Result("simulation", grid, arrays, names, stats,
                      getattr(system.mechanism, "scene_text", "") or "")
