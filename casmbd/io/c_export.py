"""A mechanism's dynamics as a standalone C99 library: :func:`export_c` (``casmbd export``).

The exported functions are the per-call Functions of :func:`casmbd.compile`
(:class:`~casmbd.compiled.robot.CompiledModel`, built in CasADi's virtual machine: the same
expression graphs the Python API compiles), with the mechanism's parameter values folded in
as constants (or, ``parameters="input"``, the scene's ``[parameters]`` left an input: the
work struct's ``p``), written by CasADi's :class:`casadi.CodeGenerator` as plain C99
(``casadi_real`` = ``double``, ``casadi_int`` = ``long long int``, no CasADi runtime: only
``<math.h>``), plus a hand-written wrapper (``NAME.h``/``NAME.c``: one C function per
quantity, sizes, names and return codes), a ``README.md``, an example ``main.c`` and
optionally a ``CMakeLists.txt``.
Constraint equations (closed chains, drivers) are solved in the generated code as
:class:`~casmbd.compiled.robot.CompiledModel` solves them in numpy:

* forward dynamics, ``[M C_qᵀ; C_q 0] [q̈; λ] = [τ − b; γ]`` by a dense LDLᵀ factorisation
  without pivoting (:func:`~casmbd.compiled.robot.ldl_solve`; M positive definite and C_q of
  full row rank make the factorisation exist: n positive then n_c negative pivots);
* inverse dynamics, ``M a + b + C_qᵀ λ = S τ_a`` — every coordinate actuated (the default):
  the least-norm effort ``τ = f + C_qᵀ λ``, ``(C_q C_qᵀ) λ = −C_q f`` with ``f = M a + b``
  (LDLᵀ); a chosen set of actuated coordinates as many as the degrees of freedom: the other
  (dependent) rows give ``C_{q,d}ᵀ λ = −f_d`` (square, CasADi's QR) and ``τ_a = f_a + (C_qᵀ
  λ)_a``.  The call also returns the relative violation of ``C_q a = γ`` which the wrapper
  turns into a return code, as the Python API raises.

The files depend only on the mechanism, the options and the CasADi version: no time stamp, no
path, every list in a fixed order, so the same input gives byte-identical files.
"""

from __future__ import annotations

import os
import re
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from casmbd.analysis.identification.regressor import (
    JointTorqueRegressor,
    joint_torque_regressor,
)
from casmbd.atomic import atomic_write
from casmbd.compiled.robot import compile as compile_robot
from casmbd.compiled.robot import ldl_solve
from casmbd.compiled.tree_dynamics import FUNCTION_OPTIONS
from casmbd.errors import AnalysisError, ModelError
from casmbd.io import c_export_text as text

__all__ = ["EXPORT_FUNCTIONS", "ExportReport", "export_c"]

#: the functions ``casmbd export`` can write, in the order of the files
EXPORT_FUNCTIONS: tuple[str, ...] = ("inverse_dynamics", "forward_dynamics", "mass_matrix",
                                     "bias_forces", "forward_kinematics", "jacobian",
                                     "regressor")
#: the default set (the regressor only on request: its parameters are a choice, friction)
DEFAULT_FUNCTIONS: tuple[str, ...] = EXPORT_FUNCTIONS[:6]

#: options of the code generator: self-contained C99, double precision, a fixed integer type
CODEGEN_OPTIONS = {"with_header": True, "casadi_real": "double",
                   "casadi_int": "long long int", "with_export": False}

#: relative violation of C_q a = γ above which the exported inverse dynamics returns
#: ``NAME_ERR_INCONSISTENT`` (the Python API's default ``tol``)
ACCELERATION_TOLERANCE = 1e-8

_PREFIX_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,39}\Z")


@dataclass
class ExportReport:
    """What :func:`export_c` wrote.

    Attributes
    ----------
    directory : Path
        The output directory.
    prefix : str
        The C prefix of every public symbol (``PREFIX_inverse_dynamics``, ``PREFIX_NQ``).
    functions : list of str
        The exported functions, in :data:`EXPORT_FUNCTIONS` order.
    files : list of str
        The files written, sorted.
    nq, nv, nc : int
        Coordinates, velocities (= efforts, accelerations) and constraint equations.
    coordinate_names, velocity_names, frame_names, actuated : list of str
        The names in the order of the C arrays.
    sizes : dict
        Work sizes: ``arg``, ``res``, ``iw``, ``w`` (entries of :c:type:`PREFIX_work`).
    regressor_parameters, regressor_rows : list of str
        With ``regressor``: the names of π (columns of Y) and of the efforts (rows).
    parameters : {"constant", "input"}
        How the scene's ``[parameters]`` were exported; ``parameter_names`` their names.
    """

    directory: Path
    prefix: str
    functions: list[str]
    files: list[str]
    nq: int
    nv: int
    nc: int
    coordinate_names: list[str]
    velocity_names: list[str]
    frame_names: list[str]
    actuated: list[str]
    sizes: dict = field(default_factory=dict)
    regressor_parameters: list[str] = field(default_factory=list)
    regressor_rows: list[str] = field(default_factory=list)
    parameters: str = "constant"
    parameter_names: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        """A JSON-ready summary (the object ``casmbd export --json`` prints)."""
        return {"directory": str(self.directory), "prefix": self.prefix,
                "functions": self.functions, "files": self.files, "nq": self.nq,
                "nv": self.nv, "nc": self.nc, "coordinate_names": self.coordinate_names,
                "velocity_names": self.velocity_names, "frame_names": self.frame_names,
                "actuated": self.actuated, "work_sizes": self.sizes,
                "regressor_parameters": self.regressor_parameters,
                "regressor_rows": self.regressor_rows, "parameters": self.parameters,
                "parameter_names": self.parameter_names}


def parse_functions(functions: str | Sequence[str] | None) -> list[str]:
    """The requested functions in :data:`EXPORT_FUNCTIONS` order; an unknown or repeated
    name is a :class:`ModelError` naming it and the choices."""
    if functions is None:
        return list(DEFAULT_FUNCTIONS)
    names = functions.split(",") if isinstance(functions, str) else list(functions)
    names = [str(n).strip() for n in names if str(n).strip()]
    if not names:
        raise ModelError("export: no function named (choices: "
                         f"{', '.join(EXPORT_FUNCTIONS)})")
    for name in names:
        if name not in EXPORT_FUNCTIONS:
            raise ModelError(f"export: unknown function '{name}' (choices: "
                             f"{', '.join(EXPORT_FUNCTIONS)})")
    if len(set(names)) != len(names):
        raise ModelError(f"export: function named twice in {','.join(names)}")
    return [n for n in EXPORT_FUNCTIONS if n in names]


def default_prefix(mechanism) -> str:
    """A C prefix from the mechanism's name: letters, digits and ``_``, starting with a
    letter (``model`` when nothing is left)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", str(getattr(mechanism, "name", "") or ""))
    name = name.lstrip("_0123456789")[:40]
    return name or "model"


def _check_prefix(prefix: str) -> str:
    if not isinstance(prefix, str) or not _PREFIX_RE.match(prefix):
        raise ModelError(f"export: prefix {prefix!r} is not a C identifier starting with a "
                         "letter (letters, digits and '_', at most 40 characters)")
    return prefix


def _check_directory(directory: Path, force: bool) -> None:
    """Refuse a directory that is a file, not empty (without ``force``) or not writable."""
    if directory.exists() and not directory.is_dir():
        raise AnalysisError(f"export: '{directory}' exists and is not a directory")
    if directory.is_dir() and any(directory.iterdir()) and not force:
        raise AnalysisError(f"export: directory '{directory}' is not empty; choose a new "
                            "directory or pass --force (force=True) to overwrite its files")
    try:
        directory.mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=directory, prefix=".casmbd-probe-")
        probe.close()
    except OSError as exc:
        raise AnalysisError(f"export: cannot write in directory '{directory}': "
                            f"{exc.strerror or exc}") from None


def _folded(f: ca.Function, p: np.ndarray | ca.SX) -> tuple[list[ca.SX], list[ca.SX]]:
    """Fresh symbols of the inputs of ``f`` but its last (the parameters) and its outputs at
    them: with ``p`` an array its values folded in as constants, with ``p`` a symbol left an
    input (``parameters="input"``)."""
    syms = [ca.SX.sym(f.name_in(k), f.sparsity_in(k)) for k in range(f.n_in() - 1)]
    if not isinstance(p, ca.SX):
        p = ca.DM(p.reshape(-1, 1)) if p.size else ca.DM(0, 1)
    return syms, f.call([*syms, p])


def _function(name: str, inputs, outputs, in_names, out_names,
              p: np.ndarray | ca.SX | None = None) -> ca.Function:
    """An export Function (dense outputs, shared subexpressions), with the parameter vector
    as its last input when ``p`` is a symbol."""
    if isinstance(p, ca.SX):
        inputs, in_names = [*inputs, p], [*in_names, "p"]
    return ca.Function(name, inputs, [ca.densify(o) for o in outputs], in_names, out_names,
                       dict(FUNCTION_OPTIONS))


def _unit(name: str, is_length: bool) -> str:
    """A coordinate's unit: m (a length), rad (an angle) or 1 (an Euler parameter)."""
    if is_length:
        return "m"
    return "rad" if name.endswith((".angle", ".theta", ".phi")) or "angle" in name else "1"


def _rate_unit(name: str, coordinate_units: dict[str, str]) -> str:
    """A velocity's unit: the rate of its coordinate, or a floating base's linear (m/s) or
    angular (rad/s) velocity."""
    if name in coordinate_units:
        return coordinate_units[name] + "/s"
    return "m/s" if name.endswith((".vx", ".vy", ".vz")) else "rad/s"


def _jacobian_frames(model, frames: Sequence[str] | str | None) -> list[int]:
    """Indices (in ``model.frame_names``) of the frames whose Jacobian is exported."""
    if frames is None:
        return list(range(len(model.frame_names)))
    names = [frames] if isinstance(frames, str) else list(frames)
    for name in names:
        if name not in model.frame_names:
            raise ModelError(f"export: unknown frame '{name}' for the Jacobian (bodies and "
                             f"markers: {', '.join(model.frame_names)})")
    return sorted({model.frame_names.index(n) for n in names})


def _build(model, functions: list[str], regressor, prefix: str,
           jacobian_frames: list[int], parameters: str = "constant") -> list[ca.Function]:
    """The export Functions ``PREFIX_cg_*`` (one per frame for the Jacobians); with
    ``parameters="input"`` each but the regressor takes the parameter vector p last."""
    num = model.numeric
    p = (ca.SX.sym("p", len(model.p)) if parameters == "input"
         else np.asarray(model.p, dtype=float))
    get = num.function
    nv, nc, cg = model.nv, model.nc, f"{prefix}_cg_"
    out = []
    if "inverse_dynamics" in functions:
        if not nc and len(model.actuated) == nv:
            (q, v, a), (tau,) = _folded(get("robot_id"), p)
            out.append(_function(cg + "inverse_dynamics", [q, v, a], [tau],
                                 ["q", "v", "a"], ["tau"], p))
        else:
            out.append(_constrained_inverse(model, get("robot_id_terms"), p,
                                            cg + "inverse_dynamics"))
    if "forward_dynamics" in functions:
        if not nc:
            (q, v, tau), (acc, _) = _folded(get("robot_fd"), p)
        else:
            (q, v, tau), (m, r, cq, gamma) = _folded(get("robot_kkt"), p)
            kkt = ca.blockcat([[m.reshape((nv, nv)), cq.T], [cq, ca.SX.zeros(nc, nc)]])
            acc = ldl_solve(kkt, ca.vertcat(r, gamma))[:nv]
        out.append(_function(cg + "forward_dynamics", [q, v, tau], [acc],
                             ["q", "v", "tau"], ["a"], p))
    if "mass_matrix" in functions:
        (q,), (m,) = _folded(get("robot_mass_matrix"), p)
        out.append(_function(cg + "mass_matrix", [q], [ca.vec(m.reshape((nv, nv)).T)],
                             ["q"], ["M"], p))
    if "bias_forces" in functions:
        (q, v), (b,) = _folded(get("robot_bias"), p)
        out.append(_function(cg + "bias_forces", [q, v], [b], ["q", "v"], ["b"], p))
    if "forward_kinematics" in functions:
        (q,), (pos, rot) = _folded(get("robot_fk"), p)
        out.append(_function(cg + "forward_kinematics", [q], [pos, rot], ["q"],
                             ["positions", "rotations"], p))
    if "jacobian" in functions:
        for k in jacobian_frames:
            (q,), (jac,) = _folded(get(f"robot_jacobian_{k}"), p)  # Jᵀ column-major
            out.append(_function(f"{cg}jacobian_{k}", [q], [jac], ["q"], ["J"], p))
    if "regressor" in functions:
        out.append(_regressor_function(regressor, cg + "regressor"))
    return out


def _constrained_inverse(model, terms: ca.Function, p: np.ndarray | ca.SX,
                         name: str) -> ca.Function:
    """τ, λ and the relative violation of C_q a = γ (module docstring)."""
    nv, nc = model.nv, model.nc
    (q, v, a), (f, cq, gamma) = _folded(terms, p)
    cq = cq.reshape((nc, nv)) if nc else ca.SX(0, nv)
    sel = [model.velocity_names.index(c) for c in model.actuated]
    if nc:
        resid = ca.mtimes(cq, a) - gamma
        scale = ca.fmax(ca.fmax(1.0, ca.mmax(ca.fabs(gamma))),
                        ca.mmax(ca.fabs(cq)) * ca.mmax(ca.fabs(a)))
        violation = ca.mmax(ca.fabs(resid)) / scale
    else:
        violation = ca.SX(0.0)
    if len(sel) == nv:  # least norm
        lam = -ldl_solve(ca.mtimes(cq, cq.T), ca.mtimes(cq, f)) if nc else ca.SX(0, 1)
        tau = f + ca.mtimes(cq.T, lam)
    else:
        dep = [k for k in range(nv) if k not in sel]
        if len(dep) != nc:
            raise ModelError(
                f"export: the actuated coordinates ({', '.join(model.actuated)}) are "
                f"{len(sel)}, the degrees of freedom {nv - nc} ({nv} coordinates, {nc} "
                "constraint equations): the exported inverse dynamics needs as many actuated "
                "coordinates as degrees of freedom, or every coordinate (least-norm efforts)")
        lam = ca.solve(cq[:, dep].T, -f[dep])
        full = f + ca.mtimes(cq.T, lam)
        tau = ca.vertcat(*[full[k] if k in sel else ca.SX(0.0) for k in range(nv)])
    return _function(name, [q, v, a], [tau, lam if nc else ca.SX(0, 1), violation],
                     ["q", "v", "a"], ["tau", "lambda", "violation"], p)


def _regressor_function(regressor: JointTorqueRegressor, name: str) -> ca.Function:
    """Y(q, v, a) of the regressor's symbolic Function, row-major."""
    f = regressor.symbolic
    syms = f.sx_in() if f.is_a("SXFunction") else f.mx_in()
    (y,) = f.call(syms)
    return ca.Function(name, syms, [ca.vec(ca.densify(y).T)], ["q", "v", "a"], ["Y"],
                       dict(FUNCTION_OPTIONS))


#: the start of a function definition in CasADi's C (parameters on one line, brace at the end)
_DEF_RE = re.compile(r"^((?:static )?[A-Za-z_][A-Za-z0-9_ ]*[ *]+[A-Za-z_]\w*)\(([^()]*)\) ?\{$")


def _void_casts(source: str) -> str:
    """CasADi's C with ``(void)name;`` after every function head, so that its unused
    parameters (``iw``, ``w``, ``mem``) pass ``-Wall -Wextra -Werror``."""
    lines = []
    for line in source.split("\n"):
        lines.append(line)
        match = _DEF_RE.match(line)
        if match and match.group(2).strip() not in ("", "void"):
            names = [re.findall(r"\w+", part)[-1] for part in match.group(2).split(",")]
            lines.append("  " + " ".join(f"(void){n};" for n in names))
    return "\n".join(lines)


def _generate(functions: list[ca.Function], prefix: str) -> tuple[str, str]:
    """CasADi's C source and header of ``functions`` (file stem ``PREFIX_model``)."""
    stem = f"{prefix}_model"
    gen = ca.CodeGenerator(stem, dict(CODEGEN_OPTIONS))
    for f in functions:
        gen.add(f)
    with tempfile.TemporaryDirectory(prefix="casmbd-export-") as tmp:
        gen.generate(tmp + os.sep)
        source = (Path(tmp) / f"{stem}.c").read_text(encoding="utf-8")
        header = (Path(tmp) / f"{stem}.h").read_text(encoding="utf-8")
    source = _void_casts(source)
    return source.rstrip() + "\n", header.rstrip() + "\n"


def _regressor(mechanism, actuated, friction) -> JointTorqueRegressor:
    """The joint-torque regressor of :func:`~casmbd.analysis.identification.regressor.
    joint_torque_regressor` (built in CasADi's VM; its ``symbolic`` Function is exported)."""
    return joint_torque_regressor(mechanism, friction=friction, actuated=actuated, mode="vm")


def export_c(mechanism, directory, functions: str | Sequence[str] | None = None, *,
             prefix: str | None = None, actuated: Sequence[str] | None = None,
             friction: Sequence[str] | str = (), frames: Sequence[str] | None = None,
             parameters: str = "constant", cmake: bool = False,
             force: bool = False) -> ExportReport:
    """Write the dynamics of ``mechanism`` as a standalone C99 library into ``directory``.

    Parameters
    ----------
    mechanism : Mechanism
        The description (a scene or a URDF robot), in joint coordinates as
        :func:`casmbd.compile` (closed chains: a spanning tree and loop-closure equations).
    directory : str or Path
        Output directory, created when missing; it must be empty unless ``force``.
    functions : str or sequence of str, optional
        Names of :data:`EXPORT_FUNCTIONS` (a comma-separated string or a list); default
        every one but ``regressor``.
    prefix : str, optional
        C prefix of every public symbol and file name (default: the mechanism's name made a
        C identifier).
    actuated : sequence of str, optional
        With constraint equations: the coordinates carrying the efforts of the inverse
        dynamics (as many as the degrees of freedom); default every one (least-norm
        efforts), as :func:`casmbd.compile`.
    friction : sequence of {"viscous", "coulomb"} or str
        Friction laws whose coefficients join the regressor's parameters π (default none;
        :func:`~casmbd.analysis.identification.regressor.joint_torque_regressor`).
    frames : sequence of str, optional
        The frames (bodies, markers) whose Jacobian is exported (default every one); the
        others' index gives ``PREFIX_ERR_ARGUMENT``.
    parameters : {"constant", "input"}
        The scene's ``[parameters]`` folded in as constants (default), or an input: the
        work struct's ``p`` (``PREFIX_NP`` values, set to the scene's by
        ``PREFIX_work_init``).  Masses, inertias and geometry given as numbers are constants
        either way (the regressor takes them as π).
    cmake : bool
        Also write a ``CMakeLists.txt`` (a static library and the example).
    force : bool
        Overwrite the files of a non-empty ``directory``.

    Returns
    -------
    ExportReport
        The files, sizes and names.

    Raises
    ------
    ModelError
        An unknown function name, a bad prefix, actuated coordinates that the export cannot
        use, or a mechanism :func:`casmbd.compile` refuses (named there).
    AnalysisError
        A directory that cannot be written, or is not empty without ``force``.
    """
    names = parse_functions(functions)
    prefix = _check_prefix(default_prefix(mechanism) if prefix is None else prefix)
    directory = Path(directory)
    _check_directory(directory, force)
    model = compile_robot(mechanism, mode="vm", actuated=actuated)
    jac_frames = _jacobian_frames(model, frames)
    regressor = (_regressor(mechanism, actuated, friction) if "regressor" in names else None)
    if parameters not in ("constant", "input"):
        raise ModelError(f"export: parameters must be 'constant' or 'input', got "
                         f"{parameters!r}")
    if parameters == "input" and not len(model.p):
        raise ModelError(f"export: parameters='input' but '{mechanism.name}' has no "
                         "[parameters] (masses, inertias and geometry given as numbers are "
                         "constants; the regressor takes them as an input)")
    fns = _build(model, names, regressor, prefix, jac_frames, parameters)
    source, cg_header = _generate(fns, prefix)
    sizes = {"arg": max(f.sz_arg() for f in fns), "res": max(f.sz_res() for f in fns),
             "iw": max(f.sz_iw() for f in fns), "w": max(f.sz_w() for f in fns)}
    lengths = set(int(k) for k in np.asarray(model.numeric.length_indices).ravel())
    units = [_unit(n, k in lengths) for k, n in enumerate(model.coordinate_names)]
    spec = text.Spec(
        prefix=prefix, name=str(getattr(mechanism, "name", prefix)), functions=names,
        nq=model.nq, nv=model.nv, nc=model.nc, dimension=model.dimension,
        coordinate_names=list(model.coordinate_names),
        velocity_names=list(model.velocity_names),
        coordinate_units=units,
        velocity_units=[_rate_unit(n, dict(zip(model.coordinate_names, units)))
                        for n in model.velocity_names],
        frame_names=list(model.frame_names), actuated=list(model.actuated),
        constraint_labels=list(model.constraint_labels),
        initial_q=[float(x) for x in np.asarray(model.numeric.initial_coordinates()).ravel()],
        sizes=sizes, parameter_names=list(model.numeric.parameter_names),
        parameter_values=[float(x) for x in np.asarray(model.p).ravel()],
        tolerance=ACCELERATION_TOLERANCE, casadi_version=ca.__version__,
        regressor_parameters=list(regressor.names) if regressor else [],
        regressor_rows=list(regressor.rows) if regressor else [],
        jacobian_frames=jac_frames, parameter_input=parameters == "input", cmake=cmake)
    files = {f"{prefix}_model.c": source, f"{prefix}_model.h": cg_header,
             f"{prefix}.h": text.header(spec), f"{prefix}.c": text.wrapper(spec),
             "main.c": text.example(spec), "README.md": text.readme(spec)}
    if cmake:
        files["CMakeLists.txt"] = text.cmake(spec)
    for fname in sorted(files):
        content = files[fname].encode("utf-8")
        try:
            atomic_write(directory / fname, lambda tmp, c=content: Path(tmp).write_bytes(c))
        except OSError as exc:
            raise AnalysisError(f"export: cannot write '{directory / fname}': "
                                f"{exc.strerror or exc}") from None
    return ExportReport(directory=directory, prefix=prefix, functions=names,
                        files=sorted(files), nq=model.nq, nv=model.nv, nc=model.nc,
                        coordinate_names=spec.coordinate_names,
                        velocity_names=spec.velocity_names, frame_names=spec.frame_names,
                        actuated=spec.actuated, sizes=sizes,
                        regressor_parameters=spec.regressor_parameters,
                        regressor_rows=spec.regressor_rows, parameters=parameters,
                        parameter_names=spec.parameter_names)
