"""The NLP solvers and solver options an optimal-control problem may name.

CasADi's ``nlpsol`` takes options that compile and load code (``jit``, ``compiler``,
``jit_options`` with a compiler command and flags), write or read any file
(``ipopt.output_file``, ``ipopt.option_file_name``), load shared libraries (``ipopt.hsllib``,
``ipopt.pardisolib``, any solver *plugin* name) or call back into Python (``iteration_callback``,
``monitor``).  A scene file is data that users download and share, so nothing in it may reach
those: :attr:`Ocp.solver_options <casmbd.ocp.problem.Ocp.solver_options>` (which a scene's
``[ocp.solver_options]`` table fills) goes through the explicit allow-list below, with a type
and a range for every option, and ``solver`` must be one of :data:`SOLVERS`.  Everything else is
refused with an error naming the key and listing what is allowed.

The ranges check meaning, not only type: IPOPT's ``obj_scaling_factor`` must be > 0 (a
negative one makes IPOPT maximise and still report ``Solve_Succeeded``), ``print_level`` is at
most 5 (higher levels print every iterate: megabytes per iteration), the derivative tests
(``derivative_test``) are refused (finite differences over every variable: minutes), and the
termination tolerances and ``bound_relax_factor`` have upper bounds so that "succeeded" still
means a feasible, optimal point (:data:`WHY` gives the reason appended to each refusal).

The allow-list applies to every ``Ocp`` — built from a scene or in Python — and is checked
again when the problem is solved (the attribute may have been changed).  Trusted Python code
that needs another option passes it to ``Ocp.solve(options={...})``, which is not checked: a
program that calls Python can run anything anyway, and no scene, result file or command-line
argument reaches that argument.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import math
import subprocess
import sys

import casadi as ca

from casmbd.errors import AnalysisError

__all__ = ["LINEAR_SOLVERS", "SOLVERS", "SOLVER_OPTIONS", "WHY", "check_solver",
           "check_solver_options"]

#: NLP solvers an ``Ocp`` may use (and that this CasADi build must provide).
SOLVERS = ("ipopt", "sqpmethod")

#: Linear solvers IPOPT may be asked for; all but MUMPS are probed before use (the HSL and
#: Pardiso ones exist only when their libraries are installed).
LINEAR_SOLVERS = ("mumps", "spral", "ma27", "ma57", "ma77", "ma86", "ma97", "pardiso")

_BIG = 1e20


def _int(lo: int, hi: int) -> tuple:
    return ("int", lo, hi)


def _real(lo: float, hi: float = _BIG, open_lo: bool = True) -> tuple:
    return ("real", lo, hi, open_lo)


def _choice(*values: str) -> tuple:
    return ("choice", values)


_POS = _real(0.0)           # a finite number > 0
_NONNEG = _real(0.0, open_lo=False)
_YESNO = _choice("yes", "no")
_BOOL = ("bool",)

_IPOPT = {
    "ipopt.max_iter": _int(0, 100_000),
    "ipopt.acceptable_iter": _int(0, 1_000_000),
    "ipopt.print_level": _int(0, 5),
    "ipopt.print_frequency_iter": _int(1, 1_000_000),
    "ipopt.limited_memory_max_history": _int(0, 100),
    "ipopt.max_soc": _int(0, 1000),
    "ipopt.tol": _real(0.0, 1e-2),                       # IPOPT: 1e-8
    "ipopt.acceptable_tol": _real(0.0, 1.0),             # 1e-6
    "ipopt.constr_viol_tol": _real(0.0, 1e-2),           # 1e-4
    "ipopt.dual_inf_tol": _real(0.0, 1e2),               # 1
    "ipopt.compl_inf_tol": _real(0.0, 1e-2),             # 1e-4
    "ipopt.acceptable_constr_viol_tol": _real(0.0, 1.0),  # 1e-2
    "ipopt.acceptable_dual_inf_tol": _POS,               # 1e10
    "ipopt.acceptable_compl_inf_tol": _real(0.0, 1.0),   # 1e-2
    "ipopt.acceptable_obj_change_tol": _NONNEG,
    "ipopt.mu_init": _POS,
    "ipopt.mu_min": _POS,
    "ipopt.mu_max": _POS,
    "ipopt.bound_push": _POS,
    "ipopt.bound_frac": _real(0.0, 0.5),
    "ipopt.bound_relax_factor": _real(0.0, 1e-4, open_lo=False),  # 1e-8
    "ipopt.warm_start_bound_push": _POS,
    "ipopt.warm_start_bound_frac": _real(0.0, 0.5),
    "ipopt.warm_start_mult_bound_push": _POS,
    "ipopt.nlp_scaling_max_gradient": _POS,
    "ipopt.obj_scaling_factor": _real(1e-8, 1e8, open_lo=False),
    "ipopt.max_cpu_time": _POS,
    "ipopt.max_wall_time": _POS,
    "ipopt.mu_strategy": _choice("monotone", "adaptive"),
    "ipopt.mu_oracle": _choice("probing", "loqo", "quality-function"),
    "ipopt.hessian_approximation": _choice("exact", "limited-memory"),
    "ipopt.limited_memory_update_type": _choice("bfgs", "sr1"),
    "ipopt.nlp_scaling_method": _choice("none", "gradient-based"),
    "ipopt.fixed_variable_treatment": _choice("make_parameter", "make_parameter_nodual",
                                              "make_constraint", "relax_bounds"),
    "ipopt.derivative_test": _choice("none"),
    "ipopt.linear_solver": ("linear_solver",),
    "ipopt.warm_start_init_point": _YESNO,
    "ipopt.sb": _YESNO,
    "ipopt.honor_original_bounds": _YESNO,
    "ipopt.check_derivatives_for_naninf": _YESNO,
    "ipopt.expect_infeasible_problem": _YESNO,
    "ipopt.recalc_y": _YESNO,
    "ipopt.print_timing_statistics": _YESNO,
    # MUMPS' pivot tolerance (0, 1): larger pivots for ill-conditioned KKT systems (flexible
    # bodies: casmbd/ocp/flexible_mesh.py sets 1e-4)
    "ipopt.mumps_pivtol": _real(0.0, 1.0),
    "print_time": _BOOL,
}

_SQPMETHOD = {
    "max_iter": _int(0, 100_000),
    "max_iter_ls": _int(0, 1000),
    "tol_pr": _real(0.0, 1e-2),     # CasADi: 1e-6
    "tol_du": _real(0.0, 1e-2),     # 1e-6
    "min_step_size": _real(0.0, 1e-2),  # 1e-10
    "hessian_approximation": _choice("exact", "limited-memory"),
    "qpsol": _choice("qpoases", "qrqp"),
    "print_header": _BOOL,
    "print_iteration": _BOOL,
    "print_status": _BOOL,
    "print_time": _BOOL,
}

#: Allowed options of each solver: name -> (kind, limits...).
SOLVER_OPTIONS = {"ipopt": _IPOPT, "sqpmethod": _SQPMETHOD}

#: Why a range is narrower than the solver's own (appended to the refusal).
WHY = {
    "ipopt.obj_scaling_factor": "a factor <= 0 turns the minimisation into a maximisation "
                                "(IPOPT minimises factor * objective) or drops the objective",
    "ipopt.print_level": "levels above 5 print every vector and matrix (megabytes per "
                         "iteration)",
    "ipopt.derivative_test": "IPOPT's finite-difference derivative tests take minutes on "
                             "an optimal-control problem; casmbd's derivatives are CasADi's "
                             "exact ones",
    "ipopt.tol": "a looser tolerance reports Solve_Succeeded far from an optimum",
    "ipopt.constr_viol_tol": "a looser tolerance accepts a trajectory that violates the "
                             "dynamics and the constraints",
    "ipopt.compl_inf_tol": "a looser tolerance accepts points that are not optimal",
    "ipopt.dual_inf_tol": "a looser tolerance accepts points that are not optimal",
    "ipopt.acceptable_tol": "a looser tolerance reports an acceptable point far from an "
                            "optimum",
    "ipopt.acceptable_constr_viol_tol": "a looser tolerance accepts a trajectory that "
                                        "violates the dynamics",
    "ipopt.acceptable_compl_inf_tol": "a looser tolerance accepts points that are not optimal",
    "ipopt.bound_relax_factor": "IPOPT relaxes every bound by this relative amount; larger "
                                "values let the solution leave its bounds",
    "ipopt.limited_memory_max_history": "each stored pair costs two vectors of every NLP "
                                        "variable",
    "ipopt.max_iter": "a bound on the run time; max_cpu_time or max_wall_time stop earlier",
    "max_iter": "a bound on the run time",
    "tol_pr": "a looser tolerance accepts a trajectory that violates the dynamics",
    "tol_du": "a looser tolerance accepts points that are not optimal",
    "min_step_size": "a larger minimum step stops the line search at the start",
}


def check_solver(solver, where: str = "ocp", error: type[Exception] = AnalysisError) -> str:
    """``solver`` if it is one of :data:`SOLVERS` provided by this CasADi build, else raise
    ``error`` naming it (a plugin name is a shared library CasADi would load)."""
    if not (isinstance(solver, str) and solver in SOLVERS):
        raise error(f"{where}: unknown NLP solver {solver!r} (allowed: {', '.join(SOLVERS)})")
    if not ca.has_nlpsol(solver):
        raise error(f"{where}: NLP solver '{solver}' is not available in this CasADi build")
    return solver


#: The shared libraries IPOPT loads at run time for a linear solver it was not linked with
#: (IPOPT 3.14: option ``hsllib``, default ``libhsl.so``, and the COIN-HSL build's
#: ``libcoinhsl.so``; ``pardisolib``, default ``libpardiso.so``).  IPOPT crashes the process
#: (SIGSEGV) when one of them is named and the library is missing, so the library is looked
#: for first and the solver probed in a child process.
RUNTIME_LIBRARIES = {**{name: ("libhsl.so", "libcoinhsl.so")
                        for name in ("ma27", "ma57", "ma77", "ma86", "ma97")},
                     "pardiso": ("libpardiso.so",)}


def runtime_library(name: str) -> tuple[str | None, tuple[str, ...]]:
    """(the library file that loads, or None; the files looked for) of linear solver ``name``
    (:data:`RUNTIME_LIBRARIES`; ``(None, ())`` for solvers built into IPOPT)."""
    files = RUNTIME_LIBRARIES.get(name, ())
    for file in files:
        for candidate in (file, ctypes.util.find_library(file[3:].split(".")[0])):
            if not candidate:
                continue
            try:
                ctypes.CDLL(candidate)
            except OSError:
                continue
            return candidate, files
    return None, files


_PROBE = """
import casadi as ca
x = ca.SX.sym("x")
s = ca.nlpsol("casmbd_probe", "ipopt", {"x": x, "f": (x - 1) ** 2},
              {"ipopt.linear_solver": %r, "ipopt.print_level": 0, "ipopt.sb": "yes",
               "print_time": False, "error_on_fail": False})
s(x0=0.0)
raise SystemExit(0 if s.stats().get("success", False) else 3)
"""


@functools.cache
def linear_solver_available(name: str) -> bool:
    """Whether IPOPT can use the linear solver ``name`` here (MUMPS ships with CasADi; the
    others are tried once on a one-variable problem: in a child process when IPOPT loads
    them from a shared library, whose absence crashes IPOPT)."""
    if name == "mumps":
        return True
    if name in RUNTIME_LIBRARIES:
        if runtime_library(name)[0] is None:
            return False
        try:
            run = subprocess.run([sys.executable, "-c", _PROBE % name], capture_output=True,
                                 timeout=60, check=False)
        except (OSError, subprocess.SubprocessError):
            return False
        return run.returncode == 0
    x = ca.SX.sym("x")
    try:
        solver = ca.nlpsol("casmbd_probe", "ipopt", {"x": x, "f": (x - 1) ** 2},
                           {"ipopt.linear_solver": name, "ipopt.print_level": 0,
                            "ipopt.sb": "yes", "print_time": False, "error_on_fail": False})
        solver(x0=0.0)
    except RuntimeError:
        return False
    return bool(solver.stats().get("success", False))


def _check_value(key: str, value, spec: tuple, where: str, error: type[Exception]):
    kind = spec[0]
    bad = f"{where}: solver option '{key}' = {value!r}:"
    if kind == "bool":
        if not isinstance(value, bool):
            raise error(f"{bad} expected true or false")
        return value
    if kind in ("choice", "linear_solver"):
        values = spec[1] if kind == "choice" else LINEAR_SOLVERS
        if not (isinstance(value, str) and value in values):
            raise error(f"{bad} expected one of {', '.join(values)}")
        if kind == "linear_solver" and not linear_solver_available(value):
            found, files = runtime_library(value)
            if files and found is None:
                raise error(f"{bad} IPOPT loads '{value}' from the shared library "
                            f"{' or '.join(files)}, and none could be loaded here (IPOPT "
                            "would crash the process); install it or use mumps")
            raise error(f"{bad} this linear solver is not available here (IPOPT refuses it; "
                        "mumps always is)")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise error(f"{bad} expected {'an integer' if kind == 'int' else 'a number'}")
    if kind == "int":
        _, lo, hi = spec
        if not isinstance(value, int) or not lo <= value <= hi:
            raise error(f"{bad} expected an integer in [{lo}, {hi}]")
        return value
    _, lo, hi, open_lo = spec
    ok = math.isfinite(value) and value <= hi and (value > lo if open_lo else value >= lo)
    if not ok:
        raise error(f"{bad} expected a finite number in {'(' if open_lo else '['}{lo:g}, "
                    f"{hi:g}]")
    return float(value)


def check_solver_options(solver: str, options, where: str = "ocp",
                         error: type[Exception] = AnalysisError) -> dict:
    """A checked copy of ``options`` for ``solver`` (see the module docstring).

    Parameters
    ----------
    solver : str
        One of :data:`SOLVERS`.
    options : mapping
        Option name -> value, e.g. ``{"ipopt.max_iter": 500}``.
    where : str
        Prefix of error messages (the scene file and table, or ``"ocp"``).
    error : exception class
        Raised on a refused option (SceneError for scene files).

    Raises
    ------
    error
        Naming the key, for an option not on the allow-list (listing the allowed ones), or a
        value of the wrong type or out of range.
    """
    check_solver(solver, where, error)
    if not isinstance(options, dict):
        raise error(f"{where}: solver options must be a table of option = value, got "
                    f"{type(options).__name__}")
    allowed = SOLVER_OPTIONS[solver]
    out = {}
    for key, value in options.items():
        spec = allowed.get(key) if isinstance(key, str) else None
        if spec is None:
            raise error(f"{where}: solver option {key!r} is not allowed for {solver} "
                        f"(allowed: {', '.join(sorted(allowed))})")
        try:
            out[key] = _check_value(key, value, spec, where, error)
        except error as exc:
            if key not in WHY:
                raise
            raise error(f"{exc} ({WHY[key]})") from None
    return out
