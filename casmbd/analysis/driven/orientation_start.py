"""Refuse a start half a turn from an orientation driver's prescription (issue 34, item 1).

An orientation driver's equations (:mod:`casmbd.system.orientation_residual`) hold for error
rotations below a half-turn; at exactly a half-turn they read 0/0, which a Newton solve may
take for a solution. After the assembly at t₀ every orientation driver's body must be within
the regular range: r_0² = (1 + tr A A_dᵀ)/4 ≥ 1e-6 (an error rotation below 179.9°).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casmbd.errors import AssemblyError
from casmbd.system.orientation_residual import half_turn_margins

#: smallest r_0² = cos²(θ/2) accepted at the start (θ < 179.89°)
MIN_MARGIN = 1e-6


def check_half_turns(model, q: np.ndarray, t: float) -> None:
    """Raise :class:`AssemblyError` naming the driver, its body and the error angle when an
    orientation driver's body is (nearly) half a turn from A_d(t) at the assembled ``q``."""
    mech = model.mechanism
    if not any(d.orientation_row is not None for d in mech.drivers.values()):
        return
    system = model.system
    names, margins = half_turn_margins(system)
    fn = ca.Function("half_turns", [system.q, system.t, system.p], [margins])
    values = np.asarray(fn(q, t, model.p)).ravel()
    for name, value in zip(names, values):
        if not np.isfinite(value) or value < MIN_MARGIN:
            body = next(d.body for d in mech.drivers.values() if d.orientation_row == name)
            angle = np.degrees(2 * np.arccos(np.sqrt(np.clip(value, 0.0, 1.0)))) \
                if np.isfinite(value) else float("nan")
            raise AssemblyError(
                f"driver '{name}' at t = {t:g}: body '{body}' starts {angle:.1f}° from the "
                "prescribed orientation; an orientation driver holds within a half-turn of "
                "it (its equations are singular at 180°): start the body near A_d(t0) (its "
                "'orientation' or 'euler_zxz', [scene.base] for a floating base)")
