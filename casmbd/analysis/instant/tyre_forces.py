"""Tyre forces: the forces of the constraint rows written at the velocity level.

Rolling without slipping and knife edges write rows W = dᵀ ṙ_P (d a unit direction, P the
touching point) at the velocity level (:attr:`casmbd.system.equations.System.velocity_rows`).
Their multipliers λ are forces: C_q = dᵀ ∂r_P/∂q, so the constraint force −C_qᵀ λ (seed 000,
eq. 6.145) is the virtual work of the force −λ d at P on the joint's second body.  This module
names them by joint and row, for inverse dynamics and simulation results.
"""

from __future__ import annotations

import numpy as np


def tyre_forces(model, lam: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """−λ of each row written at the velocity level, and its name ``"<joint>.<row label>"``.

    Parameters
    ----------
    model : NumericModel
        With ``velocity_rows`` and ``constraint_labels``.
    lam : ndarray (n_t, n_c)
        The multipliers on a time grid.

    Returns
    -------
    (forces (n_t, rows), names)
        The tyre force along each row's own direction (lateral, longitudinal), in newtons
        for a row of a point velocity along a unit direction.
    """
    rows = list(model.velocity_rows)
    labels = model.constraint_labels
    return -np.asarray(lam, float)[:, rows], [f"{labels[i].element}.{labels[i].label}"
                                              for i in rows]
