"""The hand-written files of a C export (:mod:`casmbd.io.c_export`): the public header
``PREFIX.h``, its wrapper ``PREFIX.c`` over CasADi's generated ``PREFIX_model.c``, the example
``main.c``, ``README.md`` and ``CMakeLists.txt``.

Every text is a function of a :class:`Spec` alone (no time, no path, no host), so the same
mechanism and options give byte-identical files.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Spec", "cmake", "example", "header", "readme", "wrapper"]


@dataclass
class Spec:
    """What the texts say: sizes, names, the functions, the work sizes."""

    prefix: str
    name: str
    functions: list[str]
    nq: int
    nv: int
    nc: int
    dimension: int
    coordinate_names: list[str]
    velocity_names: list[str]
    coordinate_units: list[str]
    velocity_units: list[str]
    frame_names: list[str]
    actuated: list[str]
    constraint_labels: list[str]
    initial_q: list[float]
    sizes: dict
    parameter_names: list[str]
    parameter_values: list[float]
    tolerance: float
    casadi_version: str
    regressor_parameters: list[str]
    regressor_rows: list[str]
    jacobian_frames: list[int]
    parameter_input: bool = False
    cmake: bool = False

    @property
    def nw(self) -> int:
        """Rows of the angular velocity: 3 in space, 1 in the plane."""
        return 3 if self.dimension == 3 else 1


def c_string(s: str) -> str:
    """A C string literal of ``s`` (UTF-8; quotes, backslashes, '?' and non-printable bytes
    escaped, so no trigraph and no encoding question)."""
    out = []
    for byte in str(s).encode("utf-8"):
        ch = chr(byte)
        if ch in '"\\?':
            out.append("\\" + ch)
        elif 0x20 <= byte < 0x7F:
            out.append(ch)
        else:
            out.append(f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def comment(s: str) -> str:
    """``s`` safe inside a C block comment (ASCII, no ``*/``)."""
    return str(s).encode("ascii", "replace").decode("ascii").replace("*/", "* /")


def _number(x: float) -> str:
    return repr(float(x))


def _array(values: list[str], per_line: int = 4) -> str:
    rows = [", ".join(values[i:i + per_line]) for i in range(0, len(values), per_line)]
    return "{\n  " + ",\n  ".join(rows) + "\n}" if rows else "{0}"


def _name_table(names: list[str], units: list[str] | None = None) -> str:
    lines = []
    for k, n in enumerate(names):
        unit = f" [{comment(units[k])}]" if units else ""
        lines.append(f" *   {k:3d}  {comment(n)}{unit}")
    return "\n".join(lines)


# ------------------------------------------------------------------ per-function facts
def _signatures(s: Spec) -> dict[str, tuple[str, str]]:
    """function -> (C parameter list, one-paragraph documentation)."""
    P = s.prefix
    tau_doc = (
        "tau[NV] = M(q) a + b(q, v): the generalized efforts along the coordinates (joint "
        "torques [N m] and forces [N]), Pinocchio's rnea."
        if not s.nc else
        "tau[NV]: the efforts S tau_a on the actuated coordinates of M a + b + C_q^T lambda = "
        "S tau_a (Shabana's sign: the constraint forces are -C_q^T lambda), zero on the "
        "others; "
        + ("every coordinate is actuated: tau is the least-norm effort, orthogonal to the "
           "constraint forces (C_q tau = 0). "
           if len(s.actuated) == s.nv else
           f"actuated: {comment(', '.join(s.actuated))}. ")
        + f"The multipliers lambda[{P}_NC] are left in w->lambda (order of "
        f"{P}_constraint_labels).  The accelerations must satisfy C_q a = gamma: a relative "
        f"violation above {P}_ACCELERATION_TOLERANCE returns {P}_ERR_INCONSISTENT.")
    fd_doc = (
        "a[NV] from M(q) a + b(q, v) = tau, by the articulated-body recursion (Pinocchio's "
        "aba) for a tree of revolute and prismatic joints, else a dense LDL^T of M."
        if not s.nc else
        "a[NV] from [M C_q^T; C_q 0] [a; lambda] = [tau - b; gamma], tau the efforts on "
        "every coordinate (a dense LDL^T of the KKT matrix, no pivoting).")
    return {
        "inverse_dynamics": (
            "const double *q, const double *v, const double *a, double *tau", tau_doc),
        "forward_dynamics": (
            "const double *q, const double *v, const double *tau, double *a",
            fd_doc + f"  A singular mass matrix gives {P}_ERR_NOT_FINITE."),
        "mass_matrix": (
            "const double *q, double *M",
            "M[NV * NV], row-major (M[i * NV + j]; symmetric, both triangles filled), "
            "Pinocchio's crba."),
        "bias_forces": (
            "const double *q, const double *v, double *b",
            "b[NV] = -Q_v - Q_e at t = 0 and actuator inputs u = 0 (Coriolis, centrifugal, "
            "gravity and the mechanism's own springs and dampers): M a + b = tau; "
            "Pinocchio's nle."),
        "forward_kinematics": (
            "const double *q, double *positions, double *rotations",
            f"positions[NFRAMES * {s.dimension}] (row k: frame k's origin, global "
            f"components [m]) and rotations[NFRAMES * {s.dimension} * {s.dimension}] "
            "(frame k's rotation matrix body-to-global, row-major: "
            f"R_k[i][j] = rotations[(k * {s.dimension} + i) * {s.dimension} + j]).  "
            f"The frames are {P}_frame_names: the bodies (origin at the centre of mass, "
            "body axes), then the markers."),
        "jacobian": (
            "const double *q, int frame, double *J",
            f"J[{s.dimension + s.nw} * NV] of frame `frame` (0 <= frame < NFRAMES, "
            f"{P}_frame_index"
            + ("" if len(s.jacobian_frames) == len(s.frame_names) else
               "; exported for " + ", ".join(comment(s.frame_names[k])
                                             for k in s.jacobian_frames)
               + " only, another frame returns ERR_ARGUMENT")
            + "), row-major: (rdot, omega) = J v, rows the linear velocity of "
            "the frame's origin then the angular velocity, global components (Pinocchio's "
            "LOCAL_WORLD_ALIGNED)."),
        "regressor": (
            "const double *q, const double *v, const double *a, double *Y",
            f"Y[{P}_NY * {P}_NPI], row-major (Y[i * {P}_NPI + j]): the efforts of the rows "
            f"{P}_regressor_rows are Y(q, v, a) pi, linear in the standard parameters pi "
            f"named in {P}_regressor_parameters (per body m, m c, inertia about the body "
            "origin; joint friction coefficients).  Independent of the model's own "
            "parameter values."),
    }


def _outputs(s: Spec) -> dict[str, list[tuple[str, str]]]:
    """function -> its output arrays (C name, size expression)."""
    P, d = s.prefix, s.dimension
    return {"inverse_dynamics": [("tau", f"{P}_NV")],
            "forward_dynamics": [("a", f"{P}_NV")],
            "mass_matrix": [("M", f"{P}_NV * {P}_NV")],
            "bias_forces": [("b", f"{P}_NV")],
            "forward_kinematics": [("positions", f"{P}_NFRAMES * {d}"),
                                   ("rotations", f"{P}_NFRAMES * {d * d}")],
            "jacobian": [("J", f"{(d + s.nw)} * {P}_NV")],
            "regressor": [("Y", f"{P}_NY * {P}_NPI")]}


def _inputs(fname: str) -> list[str]:
    return {"inverse_dynamics": ["q", "v", "a"], "forward_dynamics": ["q", "v", "tau"],
            "mass_matrix": ["q"], "bias_forces": ["q", "v"],
            "forward_kinematics": ["q"], "jacobian": ["q"],
            "regressor": ["q", "v", "a"]}[fname]


# ------------------------------------------------------------------ PREFIX.h
def header(s: Spec) -> str:
    """The public header: sizes, names, return codes, the work struct and one documented
    prototype per exported function."""
    P, U = s.prefix, s.prefix.upper()
    sz = s.sizes
    sig = _signatures(s)
    lines = [
        f"/* {P}.h -- the dynamics of the mechanism '{comment(s.name)}' as standalone C99.",
        " *",
        " * Written by `casmbd export` (the Python API: casmbd.export_c) from the mechanism's",
        f" * description: the numbers equal those of casmbd.compile(mechanism) ({P}_model.c is",
        f" * CasADi {comment(s.casadi_version)}'s C of the same expressions, with the "
        "parameter values",
        " * folded in as constants).  Depends only on the C99 standard library and libm.",
        " *",
        " * Conventions",
        " *   SI units: lengths m, angles rad, masses kg, time s; efforts N m (revolute) or N",
        " *   (prismatic).  q has NQ entries, v, a and tau NV (NV < NQ only with a floating",
        " *   base: its velocity is Pinocchio's free-flyer velocity, linear then angular, in",
        " *   the base's own axes).  Joint coordinates as casmbd.compile: a revolute joint's",
        " *   angle and a prismatic joint's displacement are zero at the design pose.",
        " *   Equations of motion M(q) a + b(q, v) = tau"
        + (" - C_q^T lambda with the constraint" if s.nc else "."),
    ]
    if s.nc:
        lines += [" *   equations C(q) = 0 (closed loops; drivers at t = 0) at the acceleration",
                  " *   level C_q a = gamma(q, v); q and v must satisfy them (no assembly here)."]
    lines += [
        " *   Matrices are dense and row-major (C order): X[i * ncols + j].",
        " *",
        " * Thread safety",
        " *   No function writes a global or static variable: calls with distinct work",
        f" *   structs ({P}_work) may run concurrently; one work struct serves one call at a",
        (" *   time.  The work struct needs no initialisation." if not s.parameter_input else
         f" *   time.  {P}_work_init sets the work struct's parameters p (once per struct)."),
        " *",
        " * Errors",
        f" *   Every function returns {P}_OK (0) or a positive code ({P}_strerror gives its",
        f" *   text): {P}_ERR_ARGUMENT (a NULL pointer, a frame index out of range),",
        f" *   {P}_ERR_NOT_FINITE (an output entry is NaN or infinite: a non-finite input, or",
        " *   a singular mass matrix in forward dynamics), "
        f"{P}_ERR_INCONSISTENT (closed chains:",
        " *   accelerations that violate C_q a = gamma), "
        f"{P}_ERR_EVALUATION (the generated code",
        " *   failed).  Outputs are written even when the code is not OK.",
        " *",
        f" * Coordinates q ({P}_coordinate_names, units):",
        _name_table(s.coordinate_names, s.coordinate_units),
    ]
    if s.velocity_names != s.coordinate_names:
        lines += [f" * Velocities v, accelerations a, efforts tau ({P}_velocity_names):",
                  _name_table(s.velocity_names, s.velocity_units)]
    lines += [f" * Frames ({P}_frame_names):", _name_table(s.frame_names)]
    if s.nc:
        lines += [f" * Constraint equations ({P}_constraint_labels):",
                  _name_table(s.constraint_labels)]
    if s.parameter_names and s.parameter_input:
        lines += [f" * Scene parameters, an input: w->p ({P}_parameter_names, defaults):",
                  "\n".join(f" *   {k:3d}  {comment(n)} = {_number(v)}" for k, (n, v)
                            in enumerate(zip(s.parameter_names, s.parameter_values)))]
    elif s.parameter_names:
        lines += [" * Scene parameters folded in as constants:",
                  "\n".join(f" *   {comment(n)} = {_number(v)}"
                            for n, v in zip(s.parameter_names, s.parameter_values))]
    lines += [
        " */",
        f"#ifndef {U}_H",
        f"#define {U}_H",
        "",
        "#include <stddef.h>",
        "",
        "#ifdef __cplusplus",
        'extern "C" {',
        "#endif",
        "",
        f"#define {P}_NQ {s.nq}  /* coordinates q */",
        f"#define {P}_NV {s.nv}  /* velocities v, accelerations a, efforts tau */",
        f"#define {P}_NC {s.nc}  /* constraint equations (closed loops, drivers) */",
        f"#define {P}_NFRAMES {len(s.frame_names)}  /* bodies, then markers */",
        f"#define {P}_DIM {s.dimension}  /* space dimension: 3 spatial, 2 planar */",
    ]
    if "regressor" in s.functions:
        lines.append(f"#define {P}_NPI {len(s.regressor_parameters)}  "
                     "/* regressor parameters pi (columns of Y) */")
        lines.append(f"#define {P}_NY {len(s.regressor_rows)}  "
                     "/* regressor rows (efforts) */")
    if s.parameter_input:
        lines.append(f"#define {P}_NP {len(s.parameter_names)}  /* scene parameters p */")
    if s.nc:
        lines.append(f"#define {P}_ACCELERATION_TOLERANCE {_number(s.tolerance)}  "
                     "/* relative violation of C_q a = gamma */")
    lines += [
        "",
        "/* return codes */",
        f"#define {P}_OK 0",
        f"#define {P}_ERR_ARGUMENT 1",
        f"#define {P}_ERR_NOT_FINITE 2",
        f"#define {P}_ERR_INCONSISTENT 3",
        f"#define {P}_ERR_EVALUATION 4",
        "",
        "/* sizes of the work arrays of the generated code (the largest over the functions) */",
        f"#define {P}_SZ_ARG {sz['arg']}",
        f"#define {P}_SZ_RES {sz['res']}",
        f"#define {P}_SZ_IW {sz['iw']}",
        f"#define {P}_SZ_W {sz['w']}",
        "",
        ("/* The caller-owned work of a call: no initialisation needed; one per thread."
         if not s.parameter_input else
         f"/* The caller-owned work of a call: {P}_work_init once, then set p freely; one "
         "per thread."),
        "   Allocate it statically, on the heap or (small models) on the stack. */",
        f"typedef struct {P}_work {{",
        f"  const double *arg[{P}_SZ_ARG];",
        f"  double *res[{P}_SZ_RES];",
        f"  long long iw[{max(1, sz['iw'])}];",
        f"  double w[{max(1, sz['w'])}];",
    ]
    if s.nc:
        lines += [f"  double lambda[{P}_NC];  /* multipliers of the last inverse_dynamics */",
                  "  double violation;  /* its relative violation of C_q a = gamma */"]
    if s.parameter_input:
        lines += [f"  double p[{P}_NP];  /* the scene's parameters ({P}_parameter_names) */"]
    lines += [
        f"}} {P}_work;",
        "",
        f"extern const char *const {P}_coordinate_names[{P}_NQ];",
        f"extern const char *const {P}_coordinate_units[{P}_NQ];  /* \"rad\", \"m\" or \"1\" */",
        f"extern const char *const {P}_velocity_names[{P}_NV];",
        f"extern const char *const {P}_frame_names[{P}_NFRAMES];",
        f"extern const double {P}_initial_q[{P}_NQ];  /* the design pose */",
    ]
    if s.nc:
        lines.append(f"extern const char *const {P}_constraint_labels[{P}_NC];")
        lines.append(f"extern const int {P}_actuated[{P}_NV];  "
                     "/* 1: the coordinate carries an effort */")
    if s.parameter_input:
        lines.append(f"extern const char *const {P}_parameter_names[{P}_NP];")
        lines.append(f"extern const double {P}_parameter_defaults[{P}_NP];  "
                     "/* the scene's values */")
    if "regressor" in s.functions:
        lines.append(f"extern const char *const {P}_regressor_parameters[{P}_NPI];")
        lines.append(f"extern const char *const {P}_regressor_rows[{P}_NY];")
    lines += [
        "",
        f"/* sizeof({P}_work), for a caller that allocates it dynamically */",
        f"size_t {P}_work_bytes(void);",
        f"/* the index of a frame name in {P}_frame_names, or -1 */",
        f"int {P}_frame_index(const char *name);",
        "/* the text of a return code */",
        f"const char *{P}_strerror(int code);",
    ]
    if s.parameter_input:
        lines += [f"/* w->p = {P}_parameter_defaults: call once per work struct before the "
                  "first call */", f"void {P}_work_init({P}_work *w);"]
    for fname in s.functions:
        params, doc = sig[fname]
        lines += ["", _wrap_comment(doc), f"int {P}_{fname}({params}, {P}_work *w);"]
    lines += ["", "#ifdef __cplusplus", '}  /* extern "C" */', "#endif", "",
              f"#endif  /* {U}_H */", ""]
    return "\n".join(lines)


def _wrap_comment(doc: str, width: int = 92) -> str:
    words, lines, line = comment(doc).split(), [], ""
    for word in words:
        if line and len(line) + 1 + len(word) > width - 3:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    lines.append(line)
    return "/* " + "\n   ".join(lines) + " */"


# ------------------------------------------------------------------ PREFIX.c
def wrapper(s: Spec) -> str:
    """The wrapper: the name tables and one checked call of the generated code per
    function."""
    P = s.prefix
    outs = _outputs(s)
    lines = [
        f"/* {P}.c -- the public functions of {P}.h over CasADi's {P}_model.c (casmbd "
        "export). */",
        f'#include "{P}.h"',
        f'#include "{P}_model.h"',
        "",
        "#include <math.h>",
        "#include <string.h>",
        "",
        f"const char *const {P}_coordinate_names[{P}_NQ] = "
        + _array([c_string(n) for n in s.coordinate_names], 3) + ";",
        f"const char *const {P}_coordinate_units[{P}_NQ] = "
        + _array([c_string(n) for n in s.coordinate_units], 8) + ";",
        f"const char *const {P}_velocity_names[{P}_NV] = "
        + _array([c_string(n) for n in s.velocity_names], 3) + ";",
        f"const char *const {P}_frame_names[{P}_NFRAMES] = "
        + _array([c_string(n) for n in s.frame_names], 3) + ";",
        f"const double {P}_initial_q[{P}_NQ] = "
        + _array([_number(x) for x in s.initial_q], 4) + ";",
    ]
    if s.nc:
        lines.append(f"const char *const {P}_constraint_labels[{P}_NC] = "
                     + _array([c_string(n) for n in s.constraint_labels], 2) + ";")
        lines.append(f"const int {P}_actuated[{P}_NV] = "
                     + _array(["1" if n in s.actuated else "0" for n in s.velocity_names], 12)
                     + ";")
    if s.parameter_input:
        lines.append(f"const char *const {P}_parameter_names[{P}_NP] = "
                     + _array([c_string(n) for n in s.parameter_names], 4) + ";")
        lines.append(f"const double {P}_parameter_defaults[{P}_NP] = "
                     + _array([_number(x) for x in s.parameter_values], 4) + ";")
    if "regressor" in s.functions:
        lines.append(f"const char *const {P}_regressor_parameters[{P}_NPI] = "
                     + _array([c_string(n) for n in s.regressor_parameters], 4) + ";")
        lines.append(f"const char *const {P}_regressor_rows[{P}_NY] = "
                     + _array([c_string(n) for n in s.regressor_rows], 3) + ";")
    lines += [
        "",
        f"size_t {P}_work_bytes(void) {{ return sizeof({P}_work); }}",
        *([f"void {P}_work_init({P}_work *w) {{",
           "  int k;",
           "  if (w == NULL) return;",
           f"  for (k = 0; k < {P}_NP; ++k) w->p[k] = {P}_parameter_defaults[k];",
           "}"] if s.parameter_input else []),
        "",
        f"int {P}_frame_index(const char *name) {{",
        "  int k;",
        "  if (name == NULL) return -1;",
        f"  for (k = 0; k < {P}_NFRAMES; ++k)",
        f"    if (strcmp(name, {P}_frame_names[k]) == 0) return k;",
        "  return -1;",
        "}",
        "",
        f"const char *{P}_strerror(int code) {{",
        "  switch (code) {",
        f'    case {P}_OK: return "ok";',
        f'    case {P}_ERR_ARGUMENT: return "bad argument (a NULL pointer or a frame index '
        'out of range)";',
        f'    case {P}_ERR_NOT_FINITE: return "an output is not finite (a non-finite input, '
        'or a singular mass matrix)";',
        f'    case {P}_ERR_INCONSISTENT: return "the accelerations violate the acceleration '
        'constraints C_q a = gamma";',
        f'    case {P}_ERR_EVALUATION: return "the generated code failed";',
        '    default: return "unknown return code";',
        "  }",
        "}",
        "",
        f"static int {P}_finite(const double *x, int n) {{",
        "  int k;",
        "  for (k = 0; k < n; ++k)",
        "    if (!isfinite(x[k])) return 0;",
        "  return 1;",
        "}",
    ]
    if "jacobian" in s.functions:
        kernels = [f"{P}_cg_jacobian_{k}" if k in s.jacobian_frames else "NULL"
                   for k in range(len(s.frame_names))]
        lines += [
            "",
            f"typedef int (*{P}_kernel)(const double **, double **, long long *, double *, "
            "int);",
            f"static {P}_kernel const {P}_jacobians[{P}_NFRAMES] = "
            + _array(kernels, 2) + ";",
        ]
    sig = _signatures(s)
    for fname in s.functions:
        params, _ = sig[fname]
        ins, res = _inputs(fname), outs[fname]
        pointers = ins + [r for r, _ in res]
        body = [
            "",
            f"int {P}_{fname}({params}, {P}_work *w) {{",
            "  if (" + " || ".join(f"{x} == NULL" for x in [*pointers, "w"]) + ")",
            f"    return {P}_ERR_ARGUMENT;",
        ]
        if fname == "jacobian":
            body += [f"  if (frame < 0 || frame >= {P}_NFRAMES || {P}_jacobians[frame] == NULL)",
                     f"    return {P}_ERR_ARGUMENT;"]
        body += [f"  w->arg[{k}] = {x};" for k, x in enumerate(ins)]
        if s.parameter_input and fname != "regressor":
            body += [f"  w->arg[{len(ins)}] = w->p;"]
        body += [f"  w->res[{k}] = {r};" for k, (r, _) in enumerate(res)]
        constrained = fname == "inverse_dynamics" and s.nc > 0
        if constrained:
            body += ["  w->res[1] = w->lambda;",
                     "  w->res[2] = &w->violation;"]
        kernel = f"{P}_jacobians[frame]" if fname == "jacobian" else f"{P}_cg_{fname}"
        body += [f"  if ({kernel}(w->arg, w->res, w->iw, w->w, 0) != 0) "
                 f"return {P}_ERR_EVALUATION;"]
        checks = [f"!{P}_finite({r}, {n})" for r, n in res]
        if constrained:
            checks += [f"!{P}_finite(w->lambda, {P}_NC)", f"!{P}_finite(&w->violation, 1)"]
        body += ["  if (" + " || ".join(checks) + f") return {P}_ERR_NOT_FINITE;"]
        if constrained:
            body += [f"  if (w->violation > {P}_ACCELERATION_TOLERANCE) "
                     f"return {P}_ERR_INCONSISTENT;"]
        body += [f"  return {P}_OK;", "}"]
        lines += body
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ main.c
def example(s: Spec) -> str:
    """An example program: the exported function (inverse dynamics when there) at the
    design pose, v = 0, a = 0, printed one entry per line."""
    P = s.prefix
    fname = "inverse_dynamics" if "inverse_dynamics" in s.functions else s.functions[0]
    ins, outs = _inputs(fname), _outputs(s)[fname]
    lines = [
        f"/* main.c -- an example of {P}.h: {fname} at the design pose {P}_initial_q",
        "   with zero velocities (and accelerations or efforts), printed one entry per line.",
        f"   Build: cc -std=c99 -O2 main.c {P}.c {P}_model.c -lm -o example && ./example */",
        "#include <stdio.h>",
        "",
        f'#include "{P}.h"',
        "",
        f"static {P}_work work;  /* static: it may be large; one per thread */",
        "",
        "int main(void) {",
    ]
    if "v" in ins:
        lines.append(f"  double v[{P}_NV] = {{0.0}};")
    for x in ins[2:]:
        lines.append(f"  double {x}[{P}_NV] = {{0.0}};")
    for r, n in outs:
        lines.append(f"  static double {r}[{n}];")
    frame = [str(s.jacobian_frames[0])] if fname == "jacobian" else []
    call_args = [f"{P}_initial_q"] + ins[1:] + frame \
        + [r for r, _ in outs] + ["&work"]
    lines += [
        "  int k, rc;",
        *([f"  {P}_work_init(&work);  /* the scene's parameter values */"]
          if s.parameter_input else []),
        f"  rc = {P}_{fname}({', '.join(call_args)});",
        f"  if (rc != {P}_OK) {{",
        f'    fprintf(stderr, "{P}_{fname}: %s\\n", {P}_strerror(rc));',
        "    return 1;",
        "  }",
    ]
    if fname == "inverse_dynamics":
        lines += [f"  for (k = 0; k < {P}_NV; ++k)",
                  f'    printf("tau %d %s %.17g\\n", k, {P}_velocity_names[k], tau[k]);']
    else:
        for r, n in outs:
            lines += [f"  for (k = 0; k < (int)({n}); ++k)",
                      f'    printf("{r} %d %.17g\\n", k, {r}[k]);']
    lines += ["  return 0;", "}", ""]
    return "\n".join(lines)


# ------------------------------------------------------------------ README.md, CMake
def readme(s: Spec) -> str:
    """How to build and call the library."""
    P = s.prefix
    sig = _signatures(s)
    rows = "\n".join(f"| {k} | `{comment(n)}` | {u} |"
                     for k, (n, u) in enumerate(zip(s.coordinate_names, s.coordinate_units)))
    frames = ", ".join(f"`{comment(n)}`" for n in s.frame_names)
    funcs = "\n".join(f"* `int {P}_{f}({sig[f][0]}, {P}_work *w);` — {sig[f][1]}"
                      for f in s.functions)
    closed = ""
    if s.nc:
        closed = (
            f"\n## Closed chains\n\nThe mechanism has {s.nc} constraint equations "
            f"(`{P}_constraint_labels`), so q has {s.nq} entries but {s.nq - s.nc} degrees of "
            "freedom (if C_q has full rank).  q and v must satisfy the constraints (the "
            "library does not assemble); `inverse_dynamics` also needs C_q a = γ and returns "
            f"`{P}_ERR_INCONSISTENT` otherwise (relative tolerance "
            f"`{P}_ACCELERATION_TOLERANCE` = {s.tolerance:g}).  Its τ acts on the actuated "
            f"coordinates (`{P}_actuated`: {', '.join(s.actuated)}); the multipliers λ are "
            "left in `w->lambda`.  Drivers are constraint rows at t = 0 like the loop "
            "closures: their efforts are among the multipliers.\n")
    params = ""
    if s.parameter_names and s.parameter_input:
        params = (f"\nThe scene's parameters are an input: `w->p` ({P}_NP values, "
                  f"`{P}_parameter_names`), set to the scene's values by `{P}_work_init(w)` "
                  "(call it once per work struct), then free to change between calls: "
                  + ", ".join(f"`{comment(n)}` = {_number(v)}"
                              for n, v in zip(s.parameter_names, s.parameter_values))
                  + ".\n")
    elif s.parameter_names:
        params = ("\nThe scene's parameters are folded in as constants: "
                  + ", ".join(f"`{comment(n)}` = {_number(v)}"
                              for n, v in zip(s.parameter_names, s.parameter_values))
                  + ".  Export again to change them.\n")
    init = f"`{P}_work_init` once" if s.parameter_input else "no initialisation"
    return f"""# {comment(s.name)}: standalone C dynamics

Written by `casmbd export` from the mechanism `{comment(s.name)}`.  The numbers equal those of
the Python API `casmbd.compile(mechanism)`; `{P}_model.c` is the C that CasADi
{comment(s.casadi_version)} generates for the same expressions, with every mass, centre of
mass, inertia and geometric value folded in as a constant.  C99, no dependency beyond the C
standard library and libm (`-lm`), no global state written.

## Files

* `{P}.h` — the public API: sizes, names, units, return codes, one documented prototype per
  function.  Read it first.
* `{P}.c` — the wrapper: argument checks, the calls of the generated code, the name tables.
* `{P}_model.c`, `{P}_model.h` — the generated code (internal).
* `main.c` — an example program.
{"* `CMakeLists.txt` — a static library and the example." + chr(10) if s.cmake else ""}
## Build

```sh
cc -std=c99 -O2 -c {P}.c {P}_model.c            # the library's objects
cc -std=c99 -O2 main.c {P}.c {P}_model.c -lm -o example
./example                                        # tau at the design pose, v = a = 0
```

or with CMake (`CMakeLists.txt`, written with `--cmake`):
`cmake -S . -B build && cmake --build build && ./build/{P}_example`.
For a control loop use `-O2` or `-O3` (optionally `-march=native`); the generated code of a
large robot takes seconds to compile.

## Sizes and names

`{P}_NQ` = {s.nq} coordinates, `{P}_NV` = {s.nv} velocities, accelerations and efforts,
`{P}_NC` = {s.nc} constraint equations, `{P}_NFRAMES` = {len(s.frame_names)} frames
({frames}).

| index | coordinate | unit |
|---|---|---|
{rows}

Units are SI: m, rad, kg, s; efforts N m (revolute) or N (prismatic).  Matrices are dense and
row-major: `X[i * ncols + j]`.
{params}{closed}
## Functions

Every function takes a caller-owned `{P}_work` ({init}; one per thread; calls with
different work structs may run concurrently) and returns `{P}_OK` (0) or an error code
(`{P}_strerror`): `{P}_ERR_ARGUMENT` (NULL pointer, frame out of range),
`{P}_ERR_NOT_FINITE` (a NaN or infinite output: a non-finite input or a singular mass matrix),
`{P}_ERR_INCONSISTENT` (closed chains: C_q a ≠ γ), `{P}_ERR_EVALUATION`.

{funcs}

## Example (`main.c`)

```c
{example(s).rstrip()}
```
"""


def cmake(s: Spec) -> str:
    """A CMakeLists.txt: the library (static) and the example."""
    P = s.prefix
    return f"""cmake_minimum_required(VERSION 3.10)
project({P} C)

set(CMAKE_C_STANDARD 99)
set(CMAKE_C_STANDARD_REQUIRED ON)
if(NOT CMAKE_BUILD_TYPE)
  set(CMAKE_BUILD_TYPE Release)
endif()

add_library({P} {P}.c {P}_model.c)
target_include_directories({P} PUBLIC ${{CMAKE_CURRENT_SOURCE_DIR}})
find_library(M_LIBRARY m)
if(M_LIBRARY)
  target_link_libraries({P} PUBLIC ${{M_LIBRARY}})
endif()

add_executable({P}_example main.c)
target_link_libraries({P}_example PRIVATE {P})
"""
