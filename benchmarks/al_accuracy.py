"""Accuracy and cost of the ODE formulations' accelerations (issue 22, item 2).

For the benchmark problems of :mod:`benchmarks.work_precision` in each coordinate choice:

* the largest relative error max|q̈ − q̈*| / max|q̈*| of the augmented Lagrangian (default
  penalty; 4 iterations and the default: 10 with the shared factorisation, 4 above
  ``SYMBOLIC_LIMIT``) and of ``kkt_ode`` at random consistent states, against q̈* of
  the dense KKT system solved by numpy (least squares, refined with the residual accumulated in
  extended precision) with the formulation's own γ (Baumgarte α = β = 20 for the augmented
  Lagrangian, none for ``kkt_ode``);
* the cost of one right-hand side: the dynamics Function generated as C, compiled with
  ``gcc -O2`` and called 20 000 times in a loop by a C driver (best of 7 blocks), so that no
  Python or integrator time is counted.

Usage::

    python -m benchmarks.al_accuracy [--states 20] [--no-cost]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from benchmarks.work_precision import problem
from casmbd.analysis.formulations import build
from casmbd.analysis.formulations.base import baumgarte_acceleration_rhs, generalized_forces
from casmbd.system.equations import System

CASES = (("fourbar", "absolute"), ("fourbar", "natural"), ("fourbar", "joint"),
         ("chain8", "absolute"), ("chain8", "natural"), ("chain32", "absolute"),
         ("chain8_3d", "absolute"), ("chain8_3d", "natural"))
#: (label, formulation, options, Baumgarte α = β of its γ)
VARIANTS = (("AL, 4 iterations", "augmented_lagrangian", {"iterations": 4}, 20.0),
            ("AL, default", "augmented_lagrangian", {}, 20.0),
            ("kkt_ode", "kkt_ode", {}, 0.0))


def _rank(cq: np.ndarray) -> int:
    sv = np.linalg.svd(cq, compute_uv=False)
    return int(np.sum(sv > 1e-2 * sv[0])) if sv.size else 0


def consistent_states(system: System, scale: float, count: int, seed: int = 7):
    """``count`` states (q, q̇) with |C| ≤ 1e-13 and C_q q̇ + C_t = 0, away from singular
    poses (as many singular values of C_q above 1e-2 of the largest as at the design pose).

    q: Newton's method (least-squares steps) from the design pose plus ``scale`` times a
    standard normal vector; q̇: a standard normal vector projected onto the constraints.
    """
    rng = np.random.default_rng(seed)
    parts = ca.Function("c", [system.q, system.t, system.p],
                        [system.constraints, system.constraint_jacobian,
                         system.constraint_time_derivative])
    p = system.parameter_values

    def assemble(q):
        for _ in range(50):
            c, cq, _ = (np.asarray(x) for x in parts(q, 0.0, p))
            if c.size == 0:
                break
            q = q - np.linalg.lstsq(cq, c.ravel(), rcond=None)[0]
        return q

    rank = _rank(np.asarray(parts(assemble(system.initial_coordinates()), 0.0, p)[1]))
    states = []
    while len(states) < count:
        q = assemble(system.initial_coordinates() + scale * rng.standard_normal(system.nq))
        c, cq, ct = (np.asarray(x) for x in parts(q, 0.0, p))
        v = rng.standard_normal(system.nq)
        if system.nc:
            if not (np.all(np.isfinite(q)) and np.max(np.abs(c)) <= 1e-13
                    and _rank(cq) == rank):
                continue
            v = v - np.linalg.lstsq(cq, cq @ v + ct.ravel(), rcond=None)[0]
        states.append((q, v))
    return states


def exact_acceleration(system: System, q, v, baumgarte: float) -> np.ndarray:
    """q̈ of the dense KKT system [M C_qᵀ; C_q 0] [q̈; λ] = [Q; γ_b] (least squares, then three
    refinement steps with the residual accumulated in extended precision)."""
    f = ca.Function("kkt", [system.q, system.v, system.t, system.p],
                    [system.mass_matrix, generalized_forces(system, None),
                     system.constraint_jacobian,
                     baumgarte_acceleration_rhs(system, baumgarte, baumgarte)])
    m, forces, cq, gamma = (np.asarray(x) for x in f(q, v, 0.0, system.parameter_values))
    nc = system.nc
    kkt = np.block([[m, cq.reshape(nc, -1).T], [cq.reshape(nc, -1), np.zeros((nc, nc))]])
    rhs = np.concatenate([forces.ravel(), gamma.ravel()])
    x = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
    wide = kkt.astype(np.longdouble)
    for _ in range(3):
        residual = (wide @ x.astype(np.longdouble) - rhs.astype(np.longdouble)).astype(float)
        x = x - np.linalg.lstsq(kkt, residual, rcond=None)[0]
    return x[:system.nq]


def acceleration(system: System, form, q, v) -> np.ndarray:
    """q̈ from a formulation's dynamics Function (CasADi's virtual machine)."""
    out = form.function(0.0, np.concatenate([q, v]), [], system.parameter_values, [])[0]
    return np.asarray(out).ravel()[system.nq:]


_DRIVER = r'''
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "dyn.h"
int main(void) {
  casadi_int n_arg, n_res, n_iw, n_w;
  %(fn)s_work(&n_arg, &n_res, &n_iw, &n_w);
  const casadi_real** arg = malloc((n_arg + 8) * sizeof(casadi_real*));
  casadi_real** res = malloc((n_res + 8) * sizeof(casadi_real*));
  casadi_int* iw = malloc((n_iw + 1) * sizeof(casadi_int));
  casadi_real* w = malloc((n_w + 1) * sizeof(casadi_real));
  static casadi_real x[%(nx)d] = {%(x)s}; static casadi_real p[%(np)d + 1] = {%(p)s};
  static casadi_real ode[%(nx)d]; casadi_real t = 0.0; double best = 1e30, sum = 0.0;
  arg[0] = &t; arg[1] = x; arg[2] = 0; arg[3] = p; arg[4] = 0;
  res[0] = ode; res[1] = 0; res[2] = 0; res[3] = 0;
  for (int r = 0; r < 7; ++r) {
    struct timespec a, b; clock_gettime(CLOCK_MONOTONIC, &a);
    for (int k = 0; k < 20000; ++k) { %(fn)s(arg, res, iw, w, 0); sum += ode[%(nx)d - 1]; }
    clock_gettime(CLOCK_MONOTONIC, &b);
    double us = ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / 2e7;
    if (us < best) best = us;
  }
  printf("%%.4f %%g\n", best, sum);
  return 0;
}
'''


def microseconds_per_rhs(function: ca.Function, x: np.ndarray, p: np.ndarray) -> float:
    """Best-of-7 µs per call of the compiled (gcc -O2) ``function`` at state ``x``."""
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator("dyn.c", {"with_header": True})
        gen.add(function)
        gen.generate(tmp + os.sep)
        values = {"nx": len(x), "x": ", ".join(repr(float(a)) for a in x), "np": len(p),
                  "p": ", ".join(repr(float(a)) for a in p) or "0", "fn": function.name()}
        Path(tmp, "main.c").write_text(_DRIVER % values, encoding="utf-8")
        exe = str(Path(tmp, "run"))
        subprocess.run(["gcc", "-O2", "-o", exe, str(Path(tmp, "main.c")),
                        str(Path(tmp, "dyn.c")), "-lm"], check=True)
        out = subprocess.run([exe], capture_output=True, text=True, check=True).stdout
    return float(out.split()[0])


def measure(states: int, cost: bool) -> list[str]:
    """Markdown table rows, one per problem and coordinate choice."""
    rows = []
    for pname, coords in CASES:
        system = System(problem(pname, coords)[0], coords)
        forms = [(label, build(system, name, **opts), alpha)
                 for label, name, opts, alpha in VARIANTS]
        scale = 0.05 if pname.endswith("_3d") else 0.3
        errors = {label: 0.0 for label, _, _ in forms}
        for q, v in consistent_states(system, scale, states):
            exact = {a: exact_acceleration(system, q, v, a) for a in {f[2] for f in forms}}
            for label, form, alpha in forms:
                got = acceleration(system, form, q, v)
                err = np.max(np.abs(got - exact[alpha])) / np.max(np.abs(exact[alpha]))
                errors[label] = max(errors[label], float(err))
        cells = [f"{errors[label]:.1e}" for label, _, _ in forms]
        if cost:
            q, v = consistent_states(system, 0.0, 1)[0]
            x = np.concatenate([q, v])
            cells += [f"{microseconds_per_rhs(form.function, x, system.parameter_values):.2f}"
                      for _, form, _ in forms]
        row = f"| {pname} | {coords} | {system.nq} | {system.nc} | " + " | ".join(cells) + " |"
        print(row, flush=True)
        rows.append(row)
    return rows


def main(argv=None) -> int:
    """Command-line entry point: print the markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=20)
    parser.add_argument("--no-cost", action="store_true", help="skip the compiled timings")
    args = parser.parse_args(argv)
    labels = [v[0] for v in VARIANTS]
    head = ["problem", "coordinates", "nq", "nc"] + [f"max rel. error, {lab}" for lab in labels]
    if not args.no_cost:
        head += [f"µs/RHS, {lab}" for lab in labels]
    print("| " + " | ".join(head) + " |")
    print("|" + " --- |" * len(head))
    measure(args.states, not args.no_cost)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
