"""Identification of a mechanism's dynamic parameters from measured joint data.

:func:`identify` runs the whole chain on a :class:`~casmbd.model.Mechanism` (loading files is
the caller's: :func:`casmbd.io.measurement_csv.read_measurements`, the ``casmbd identify`` verb):

1. the samples (t, q, q̇, q̈, τ), filtered and differentiated when asked
   (:func:`~casmbd.analysis.identification.measurements.prepare`);
2. the regressor Y(q, q̇, q̈) at every sample with τ = Y π
   (:func:`~casmbd.analysis.identification.regressor.joint_torque_regressor`; π the bodies'
   standard inertial parameters about their body frames and the joints' friction
   coefficients) and the base parameters π_b = K π, Y_b = the base columns of Y (the
   identifiable combinations,
   :func:`~casmbd.analysis.identification.base_parameters.base_parameters`);
3. the weighted least-squares estimate of π_b with its standard deviations, the condition
   number of the stacked Y_b and the residual per joint (with a low-pass and Coulomb friction,
   the rows near each joint's velocity reversals are left out:
   :func:`~casmbd.analysis.identification.measurements.velocity_reversals`)
   (:func:`~casmbd.analysis.identification.estimate.least_squares`);
4. physically consistent standard parameters π_c near the model's own values that fit the
   data best (:func:`~casmbd.analysis.identification.consistent.consistent_parameters`), and
   how far their torques are from the least-squares ones: the RMS per joint of
   Y_b (K π_c − π̂_b) over the samples.

Scope: mechanisms whose efforts are the generalized forces on every coordinate — trees in
joint coordinates with a fixed base (the regressor's rows are the coordinates, the CSV's
``tau.`` columns).  Floating bases and closed chains (efforts on a subset, multipliers) have
regressors (:mod:`~casmbd.analysis.identification.regressor`) but no measurement format
here yet: they are refused by name.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casmbd.analysis.identification.base_parameters import base_parameters
from casmbd.analysis.identification.consistent import (
    ConsistentEstimate,
    consistent_parameters,
)
from casmbd.analysis.identification.estimate import BaseEstimate, least_squares
from casmbd.analysis.identification.measurements import (
    Measurements,
    prepare,
    velocity_reversals,
)
from casmbd.analysis.identification.parameters import check_friction_laws
from casmbd.analysis.identification.regressor import joint_torque_regressor
from casmbd.errors import IdentificationError, ModelError
from casmbd.system.equations import System

__all__ = ["Identification", "identification_model", "identify"]


@dataclass
class Identification:
    """The outcome of :func:`identify`.

    Attributes
    ----------
    base : BaseEstimate
        π̂_b, σ, condition number, residuals per joint.
    base_expressions : list of str
        Each base parameter as a combination of standard ones.
    consistent : ConsistentEstimate or None
        Physically consistent standard parameters (None when not asked).
    consistent_torque_rms : ndarray or None
        RMS per joint of Y_b (K π_c − π̂_b) over the samples: how far the consistent set's
        torques are from the least-squares ones.
    standard_names : list of str
        Names of π.
    prior : ndarray
        The model's own π.
    origins : dict
        Each body's origin of π relative to its centre of mass (body axes).
    basis : ndarray
        K (n_b × n_π).
    coordinates : list of str
        The coordinates (rows of τ).
    samples : int
        Samples used (after filtering, edges and decimation).
    friction : tuple of str
        The friction laws identified.
    """

    base: BaseEstimate
    base_expressions: list[str]
    consistent: ConsistentEstimate | None
    consistent_torque_rms: np.ndarray | None
    standard_names: list[str]
    prior: np.ndarray
    origins: dict
    basis: np.ndarray
    coordinates: list[str]
    samples: int
    friction: tuple[str, ...]

    def summary(self) -> dict:
        """A JSON-ready dict: base parameters with σ and relative %, condition number,
        residual RMS per joint, the consistent set and its checks."""
        b = self.base
        rel = b.relative_std
        out = {
            "samples": int(self.samples),
            "coordinates": list(self.coordinates),
            "friction": list(self.friction),
            "weighted": b.weighted,
            "condition_number": float(b.condition_number),
            "base_parameters": [
                {"name": n, "expression": e, "value": float(v), "std": float(s),
                 "relative_std_percent": (float(r) if np.isfinite(r) else None)}
                for n, e, v, s, r in zip(b.names, self.base_expressions, b.values, b.std, rel,
                                         strict=True)],
            "residual_rms": dict(zip(self.coordinates, map(float, b.residual_rms),
                                     strict=True)),
            "joint_sigma": dict(zip(self.coordinates, map(float, b.joint_sigma),
                                    strict=True)),
        }
        if self.consistent is not None:
            c = self.consistent
            out["consistent"] = {
                "status": c.status,
                "regularization": float(c.regularization),
                "polished": bool(c.polished),
                "parameters": dict(zip(c.names, map(float, c.values), strict=True)),
                "torque_rms_from_least_squares": dict(zip(
                    self.coordinates, map(float, self.consistent_torque_rms), strict=True)),
                "checks": c.checks,
            }
        return out


def identification_model(mechanism, friction=("viscous", "coulomb"), mode: str = "auto"):
    """The regressor and base parameters of ``mechanism`` for :func:`identify` (built once,
    reusable for several experiments): ``(regressor, base)``.

    Raises
    ------
    IdentificationError
        A mechanism whose efforts are not the generalized forces of every coordinate
        (floating base, closed chain, drivers: module docstring), or that the regressor
        refuses (a force not linear in π), with its reason.
    """
    laws = check_friction_laws(friction)
    try:
        reg = joint_torque_regressor(mechanism, laws, mode=mode)
    except ModelError as exc:
        raise IdentificationError(f"identification of '{mechanism.name}': {exc}") from None
    loops = System(mechanism, coordinates="joint").nc if reg.nq == reg.nv else 0
    if reg.nq != reg.nv or list(reg.rows) != list(reg.coordinate_names) or loops:
        why = ("a floating base" if reg.nq != reg.nv else
               f"efforts on {', '.join(reg.rows)} rather than every coordinate (drivers)"
               if list(reg.rows) != list(reg.coordinate_names) else
               f"{loops} loop-closure equations (a closed chain: its efforts would be the "
               "least-norm ones, not the motors')")
        raise IdentificationError(
            f"identification of '{mechanism.name}': {why}; measurement files hold q and τ "
            "of every coordinate of a fixed-base tree (identify the open-chain robot)")
    return reg, base_parameters(reg)


def identify(mechanism, measurements: Measurements, friction=("viscous", "coulomb"),
             cutoff: float | None = None, decimate: int = 1, weighted: bool = True,
             consistent: bool = True, mode: str = "auto", model=None) -> Identification:
    """Identify the base and physically consistent standard parameters (module docstring).

    Parameters
    ----------
    mechanism : Mechanism
        The model whose parameters are identified; its own values are the prior of the
        consistent solve.
    measurements : Measurements
        Samples on the model's coordinates (``measurements.coordinates`` in the model's
        order: :attr:`CompiledModel.coordinate_names <casmbd.compiled.robot.CompiledModel>`).
    friction : str or sequence of {"viscous", "coulomb"}
        Friction laws identified on every joint (default both; ``()`` none).
    cutoff : float, optional
        Low-pass cut-off [Hz] (required without measured v and a).
    decimate : int
        Keep every ``decimate``-th sample after filtering.
    weighted : bool
        Gautier's per-joint weighting (default) or ordinary least squares.
    consistent : bool
        Also solve for physically consistent standard parameters (IPOPT).
    mode : {"auto", "compiled", "vm"}
        The regressor's evaluation (compiled C or CasADi's VM).
    model : tuple, optional
        ``identification_model(mechanism, friction)``, to reuse across experiments.
    """
    reg, base = model if model is not None else identification_model(mechanism, friction,
                                                                      mode)
    names = list(reg.rows)
    if list(measurements.coordinates) != names:
        raise IdentificationError(
            f"{measurements.source}: the samples are on the coordinates "
            f"{', '.join(measurements.coordinates)}; the model's are {', '.join(names)}")
    t, q, v, a, tau = prepare(measurements, cutoff=cutoff, decimate=decimate)
    n = len(names)
    mask = None
    if cutoff is not None and "coulomb" in reg.parameters.friction:
        mask = ~velocity_reversals(t, v, 1.0 / cutoff)
    y_full = reg.stacked(q, v, a).reshape(len(t), n, -1)
    y_b = base.regressor(y_full)
    est = least_squares(y_b, tau, base.names, names, weighted=weighted,
                        source=measurements.source, mask=mask)
    params = reg.parameters
    cons, gap = None, None
    if consistent:
        cons = consistent_parameters(params.names, base.K, est, params.values)
        delta = y_b.reshape(len(t) * n, -1) @ (cons.base_values - est.values)
        delta = delta.reshape(len(t), n) * (1.0 if mask is None else mask)
        used = np.maximum(len(t) if mask is None else np.sum(mask, axis=0), 1)
        gap = np.sqrt(np.sum(delta ** 2, axis=0) / used)
    return Identification(est, list(base.expressions), cons, gap, list(params.names),
                          params.values.copy(), dict(params.origins), base.K, names,
                          len(t), tuple(params.friction))
