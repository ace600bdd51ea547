"""A transcription method registered from user code: trapezoidal collocation.

Each control interval is one element [t_k, t_k + h] with the states x = (q, q̇) at its ends and
the trapezoidal rule as the defect (Betts, *Practical Methods for Optimal Control*, SIAM 2010,
sec. 4.5; second order)::

    x_{k+1} − x_k − h/2 (f(x_k, u_k, t_k) + f(x_{k+1}, u_k, t_k + h)) = 0,
    ∫ L dt ≈ Σ h/2 (L_k + L_{k+1}),

f the explicit equations of motion (``casmbd.ocp.dynamics.explicit_accelerations``: trees
without constraint equations).  Everything about the method is in the class below and its one
:func:`~casmbd.ocp.methods.register_transcription`; the variables, the mesh-node constraints,
the boundary conditions, the objective and the solve are the transcription's
(:class:`casmbd.ocp.transcription.Transcription`), the same for every method.

The demonstration: the cart-pole swing-up of ``ocp/cart_pole.toml`` (hand-written CasADi
reference 53.66) with 40 intervals, solved by this method and by Radau collocation.

Run it with ``python examples/custom_transcription.py``;
``tests/architecture/test_custom_registries.py`` runs it too.
"""

from __future__ import annotations

import pathlib

import casadi as ca
import numpy as np

from casmbd.errors import AnalysisError
from casmbd.io.ocp_table import load_ocp
from casmbd.ocp.dynamics import explicit_accelerations
from casmbd.ocp.methods import TranscriptionMethod, register_transcription
from casmbd.ocp.structured import MappedCall


class Trapezoidal(TranscriptionMethod):
    """Trapezoidal collocation: one element per control interval, explicit dynamics."""

    name = "trapezoidal"
    implicit = False      # f(x, u, t) explicit: q̈ is no NLP variable
    checks_mesh = False   # the flexible-body mesh threshold was measured for Radau

    def elements_per_interval(self, ocp) -> int:
        return 1

    def points_per_interval(self, ocp) -> int:
        return 2

    def degree(self, ocp) -> int | None:
        return None

    def build(self, tr) -> None:
        if tr.nc or tr.energy:
            raise AnalysisError("ocp: the trapezoidal transcription takes mechanisms without "
                                "constraint equations and no 'energy' objective")
        nq, nu = tr.nq, tr.nu
        acc = explicit_accelerations(tr.system)
        x0, x1 = ca.SX.sym("x0", 2 * nq), ca.SX.sym("x1", 2 * nq)
        u, tk, h = ca.SX.sym("u", nu), ca.SX.sym("tk"), ca.SX.sym("h")

        def f(x, t):
            return ca.vertcat(x[nq:], acc(x[:nq], x[nq:], u, t, tr.p))

        def lagrange(x, t):
            return tr.lagrange_fn(x[:nq], x[nq:], t, u, tr.p)

        defect = x1 - x0 - h / 2 * (f(x0, tk) + f(x1, tk + h))
        quad = h / 2 * (lagrange(x0, tk) + lagrange(x1, tk + h))
        element = ca.Function("ocp_trapezoid", [x0, x1, u, tk, h], [defect, quad])
        times = ca.horzcat(*[tr.mesh_time(k) for k in range(tr.M)])
        args = [tr.Xb[:, :-1], tr.Xb[:, 1:], tr.Ub, times, tr.h]
        g, q = element.map(tr.M)(*args)
        zeros = np.zeros(2 * nq * tr.M)
        block = tr.b.ineq(g, [f"interval {k}: trapezoid defect" for k in range(tr.M)
                              for _ in range(2 * nq)], zeros, zeros)
        tr.calls.append(MappedCall(element, tr.M, args, block, True))
        tr.quad = ca.sum2(q)
        tr.energy_terms = 0.0
        tr.add_mesh_nodes()


register_transcription(Trapezoidal(), replace=True)  # replace: the script may run twice

CART_POLE = pathlib.Path(__file__).resolve().parent.parent / "ocp" / "cart_pole.toml"


def solve(transcription: str, intervals: int = 40):
    """The cart-pole swing-up solved with ``transcription`` on ``intervals`` intervals."""
    ocp = load_ocp(CART_POLE)
    ocp.compile, ocp.intervals, ocp.transcription = False, intervals, transcription
    return ocp.solve()


if __name__ == "__main__":
    for name in ("trapezoidal", "radau"):
        sol = solve(name)
        print(f"{name:12s} objective {sol.objective:.6f}  iterations "
              f"{sol.stats['iterations']}  variables {sol.stats['variables']}")
