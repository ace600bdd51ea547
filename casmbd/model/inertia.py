"""The inertia tensor of a rigid body from its moments and products, validated (numpy only).

Seed 001, "Inertia tensor", eqs. 102–105.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from casmbd.errors import ModelError

__all__ = ["inertia_tensor"]


def inertia_tensor(values: Sequence[float] | np.ndarray) -> np.ndarray:
    """Symmetric 3x3 inertia tensor from moments (and products) of inertia (numpy only).

    ``[[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]]`` as in seed 001, "Inertia tensor",
    eq. 102; the products are the tensor elements themselves (with eq. 103 they carry the
    minus sign, ``Ixy = −∫ x y dm``).  The tensor is checked for positive definiteness and for
    the triangle inequalities of eq. 105 (``Ixx + Iyy ≥ Izz`` and permutations, for the given
    diagonal and for the principal moments, within a relative 1e-12).

    Parameters
    ----------
    values : sequence of float, 3 or 6 elements
        ``[Ixx, Iyy, Izz]`` or ``[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]``.

    Returns
    -------
    numpy.ndarray, 3x3

    Raises
    ------
    ModelError
        If the length is not 3 or 6, a value is not finite, the tensor is not positive definite,
        or a triangle inequality fails; the message names the failed condition.
    """
    try:
        v = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"inertia values must be numbers, got {values!r}") from exc
    if v.size not in (3, 6):
        raise ModelError(
            "inertia needs 3 values [Ixx, Iyy, Izz] or 6 values [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], "
            f"got {v.size}"
        )
    if not np.all(np.isfinite(v)):
        raise ModelError(f"inertia values must be finite, got {v.tolist()}")
    ixx, iyy, izz = v[:3]
    ixy, ixz, iyz = v[3:] if v.size == 6 else (0.0, 0.0, 0.0)
    J = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    eig = np.linalg.eigvalsh(J)
    if not eig[0] > 0.0:
        raise ModelError(
            f"inertia tensor is not positive definite: smallest principal moment {eig[0]:.6g} "
            f"(principal moments {eig.tolist()}, values {v.tolist()})"
        )
    tol = 1e-12 * float(np.sum(eig))
    names = ("Ixx", "Iyy", "Izz")
    for label, m in (("", (ixx, iyy, izz)), ("principal ", tuple(eig))):
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            if m[j] + m[k] < m[i] - tol:
                a, b, c = (names[j], names[k], names[i]) if not label else (
                    f"I{j + 1}", f"I{k + 1}", f"I{i + 1}")
                raise ModelError(
                    f"inertia violates the {label}triangle inequality {a} + {b} >= {c} "
                    f"({m[j]:.6g} + {m[k]:.6g} < {m[i]:.6g}); no rigid body has such moments"
                )
    return J
