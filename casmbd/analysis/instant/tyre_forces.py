"""Tyre forces: the forces of the constraint rows written at the velocity level.

Rolling without slipping and knife edges write rows W = dᵀ ṙ_P (d a unit direction, P the
touching point) at the velocity level (:attr:`casmbd.system.equations.System.velocity_rows`).
Their multipliers λ are forces: C_q = dᵀ ∂r_P/∂q, so the constraint force −C_qᵀ λ (seed 000,
eq. 6.145) is the virtual work of the force −λ d at P on the joint's second body.  A rolling
joint's position row, the contact n·(P − O) = 0 of a disc or a sphere, has the same form with
d = n (the touching point is the extreme point of the wheel: d(n·P)/dt = n·ṙ_P), so −λ of it is
the normal load.  This module names them by joint and row (every row of a joint that has rows
at the velocity level: normal load, longitudinal and lateral forces of a wheel), for inverse
dynamics and simulation results.
"""

from __future__ import annotations

import numpy as np


def tyre_forces(model, lam: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """−λ of each row of a joint with rows at the velocity level (its contact row, the normal
    load, included), and its name ``"<joint>.<row label>"``.

    Parameters
    ----------
    model : NumericModel
        With ``velocity_rows`` and ``constraint_labels``.
    lam : ndarray (n_t, n_c)
        The multipliers on a time grid.

    Returns
    -------
    (forces (n_t, rows), names)
        The tyre force along each row's own direction (normal, longitudinal, lateral), in
        newtons for a row of a point velocity along a unit direction.
    """
    labels = model.constraint_labels
    rolling = {labels[i].element for i in model.velocity_rows}
    rows = [i for i, lab in enumerate(labels) if lab.kind == "joint" and lab.element in rolling]
    return -np.asarray(lam, float)[:, rows], [f"{labels[i].element}.{labels[i].label}"
                                              for i in rows]
