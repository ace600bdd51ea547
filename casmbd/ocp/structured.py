"""NLP derivatives assembled from per-element derivative functions.

A transcription is a few small functions (one collocation element or shooting interval, one
mesh node) *mapped* over the mesh, plus a handful of boundary and objective terms.  Letting
CasADi differentiate the mapped MX graph gives derivative functions that sweep the whole
element once per colour of the NLP's Jacobian or Hessian; expanding the whole NLP to SX
(``expand=True``) gives sparse derivatives but differentiates every element copy, so its
set-up grows with the mesh (10 s for the 6-joint arm of ``ocp/ur5_min_time.toml``).

Here each mapped function F(z) → (g_e, q_e) is differentiated *once*, in SX:

    J_e(z) = ∂g_e/∂z,   ∇q_e(z),   H_e(z, λ_e, σ) = ∇²_z (σ q_e + λ_eᵀ g_e),

and, since the arguments of every copy are affine in the NLP variables w, z_e = A_e w + c_e
(states, controls and collocation variables are slices of w; t_k = t₀ + k T/M and h = T/M are
linear in a free final time T), the NLP's derivatives follow by the chain rule with constant
sparse matrices:

    ∂g/∂w = blockdiag(J_e) A,   ∇f = Σ_e A_eᵀ ∇q_e + ∇f_r,
    ∇²L = Aᵀ blockdiag(H_e) A + ∇²(σ f_r + λ_rᵀ g_r),

where the remainder (f_r, g_r: boundary conditions, Mayer, effort and time terms) is small
and differentiated in SX as a whole.  These are passed to ``nlpsol`` as its ``grad_f``,
``jac_g`` and ``hess_lag`` functions.  The derivative functions are the only large
expressions, of the size of one element: they run in CasADi's virtual machine, or are
compiled to C (small translation units) and cached (:func:`compile_blocks`).
"""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
import platform
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from casmbd.compiled import cache
from casmbd.compiled.build import compile_blocks
from casmbd.compiled.codegen import BuildReport, compile_nlp_solver
from casmbd.errors import AnalysisError

__all__ = ["MODES", "MappedCall", "check_mode", "derivative_functions", "nlp_solver",
           "structured_nlp_functions"]


@dataclass
class MappedCall:
    """One function mapped over ``n`` copies whose arguments are affine in the NLP variables.

    ``function`` is an SX function whose first output is the column of constraint rows of one
    copy and whose optional second output is a scalar added to the objective; ``args`` are the
    arguments given to ``function.map(n)`` (a single-copy argument is broadcast);
    ``g_block`` the index of its stacked constraint block among the NLP's blocks (None when
    the rows are not constraints) and ``quad`` whether output 1 enters the objective.
    """

    function: ca.Function
    n: int
    args: list
    g_block: int | None
    quad: bool


def derivative_functions(call: MappedCall, name: str) -> list[ca.Function]:
    """The SX functions of one copy of ``call.function``, z the vec'd inputs stacked:
    ``name_g`` z ↦ g_e, ``name_q`` z ↦ q_e, ``name_jac`` z ↦ J_e, ``name_grad`` z ↦ ∇q_e
    and ``name_hess`` (z, λ_e, σ) ↦ H_e (full symmetric)."""
    f = call.function
    syms = [ca.SX.sym(f"z{i}", f.sparsity_in(i)) for i in range(f.n_in())]
    z = ca.vertcat(*[ca.vec(s) for s in syms])
    outs = f.call(syms)
    g = outs[0] if call.g_block is not None else ca.SX(0, 1)
    q = outs[1] if call.quad else ca.SX(1, 1)
    lam, sigma = ca.SX.sym("lam", g.numel()), ca.SX.sym("sigma")
    lagrangian = sigma * q + (ca.dot(lam, g) if g.numel() else 0)
    return [ca.Function(f"{name}_g", [z], [g]),
            ca.Function(f"{name}_q", [z], [q]),
            ca.Function(f"{name}_jac", [z], [ca.jacobian(g, z)]),
            ca.Function(f"{name}_grad", [z], [ca.gradient(q, z)]),
            ca.Function(f"{name}_hess", [z, lam, sigma], [ca.hessian(lagrangian, z)[0]])]


def _affine(call: MappedCall, w: ca.MX, nw: int) -> tuple[ca.DM, ca.DM, int]:
    """(A, c, nz): the stacked arguments of all copies, vec(Z) = A w + c, Z = [z_1 … z_n]."""
    f, n = call.function, call.n
    blocks = []
    for i, arg in enumerate(call.args):
        r, c = f.size1_in(i), f.size2_in(i)
        arg = ca.MX(arg) if not isinstance(arg, ca.MX) else arg
        if arg.size2() == c and n > 1:
            arg = ca.repmat(arg, 1, n)
        if arg.shape != (r, c * n):
            raise ValueError(f"argument {i} of {f.name()}: shape {arg.shape}, expected "
                             f"{(r, c * n)}")
        blocks.append(ca.reshape(ca.densify(arg), r * c, n))
    nz = sum(f.numel_in(i) for i in range(f.n_in()))
    z = ca.vec(ca.vertcat(*blocks)) if blocks else ca.MX(0, 1)
    jac = ca.jacobian(z, w)
    if ca.depends_on(jac, w):
        raise ValueError(f"arguments of {f.name()} are not affine in the NLP variables")
    fn = ca.Function("affine", [w], [jac, z])
    a, c0 = fn(ca.DM.zeros(nw))
    return ca.sparsify(a), ca.DM(c0), nz


def _scatter(blocks: ca.Sparsity, n: int, nz: int, a: ca.DM, hessian: bool
             ) -> tuple[ca.Sparsity, ca.DM]:
    """(sparsity of P, S) with nonzeros(P) = S nonzeros(B), B = [B_1 … B_n] of sparsity
    ``blocks``: P = blockdiag(B_e) A (``hessian`` False) or the upper triangle of
    Aᵀ blockdiag(B_e) A (True).  Every row of A has at most one nonzero (each argument entry
    is one variable times a constant, plus a constant), so each nonzero of B lands in one
    entry of P; otherwise the product is formed symbolically."""
    arow, acol = (np.asarray(v, dtype=int) for v in a.sparsity().get_triplet())
    if len(np.unique(arow)) != len(arow):
        return _scatter_symbolic(blocks, n, nz, a, hessian)
    colmap = np.full(a.size1(), -1)
    coef = np.zeros(a.size1())
    colmap[arow] = acol
    coef[arow] = np.asarray(a.nonzeros(), float)
    row, col = (np.asarray(v, dtype=int) for v in blocks.get_triplet())
    k = np.arange(len(row))
    if hessian:
        src = (col // nz) * nz + row
        i, j, c = colmap[src], colmap[col], coef[src] * coef[col]
        keep = (i >= 0) & (j >= 0) & (i <= j)
        shape = (a.size2(), a.size2())
    else:
        i, j, c = (col // nz) * blocks.size1() + row, colmap[col], coef[col]
        keep = j >= 0
        shape = (blocks.size1() * n, a.size2())
    i, j, c, k = i[keep], j[keep], c[keep], k[keep]
    lin, inverse = np.unique(j * shape[0] + i, return_inverse=True)
    sp = ca.Sparsity.triplet(shape[0], shape[1], (lin % shape[0]).tolist(),
                             (lin // shape[0]).tolist())
    s = ca.DM.triplet(inverse.tolist(), k.tolist(), ca.DM(c), len(lin), blocks.nnz())
    return sp, s


def _scatter_symbolic(blocks: ca.Sparsity, n: int, nz: int, a: ca.DM, hessian: bool
                      ) -> tuple[ca.Sparsity, ca.DM]:
    """:func:`_scatter` for any constant A, by a symbolic product."""
    v = ca.SX.sym("v", blocks.nnz())
    b = ca.SX(blocks, v)
    bd = ca.diagcat(*ca.horzsplit(b, nz)) if n > 1 else b
    prod = ca.mtimes(a.T, ca.mtimes(bd, a)) if hessian else ca.mtimes(bd, a)
    prod = ca.SX(ca.triu(prod) if hessian else prod)
    sp = prod.sparsity()
    s = ca.evalf(ca.jacobian(ca.vec(prod.nz[:]), v)) if sp.nnz() else ca.DM(0, blocks.nnz())
    return sp, ca.sparsify(s)


def structured_nlp_functions(w: ca.MX, g_blocks: list, objective_rest, calls: list,
                             derivatives: list[list[ca.Function]]) -> dict:
    """The NLP min f = Σ q + f_r s.t. g = vertcat(g_blocks) in a fresh variable x (same
    order as ``w``) with its ``grad_f``, ``jac_g`` and ``hess_lag`` functions for ``nlpsol``,
    given the mapped ``calls`` and their ``derivatives`` (:func:`derivative_functions`,
    possibly compiled).  Returns ``{"problem": {"x", "f", "g"}, "options": {...}}``.

    Raises
    ------
    ValueError
        When an argument of a mapped call is not affine in ``w``.
    """
    nw = w.numel()
    x = ca.MX.sym("x", nw)
    p = ca.MX.sym("p", 0, 1)
    lam_f = ca.MX.sym("lam_f")
    sizes = [int(b.numel()) for b in g_blocks]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    lam_g = ca.MX.sym("lam_g", int(offsets[-1]))
    mapped = {c.g_block: i for i, c in enumerate(calls) if c.g_block is not None}
    # the remainder (boundary conditions, Mayer, effort, time), differentiated whole in SX
    rest = [i for i in range(len(g_blocks)) if i not in mapped]
    rest_fn = ca.Function("ocp_rest", [w], [ca.vertcat(*[g_blocks[i] for i in rest])
                                            if rest else ca.MX(0, 1),
                                            ca.MX(objective_rest)]).expand()
    xs = ca.SX.sym("x", nw)
    g_r, f_r = rest_fn(xs)
    lam_r, sig = ca.SX.sym("lam_r", g_r.numel()), ca.SX.sym("sigma")
    lam_rest = ca.vertcat(*[lam_g[int(offsets[i]):int(offsets[i + 1])] for i in rest]) \
        if rest else ca.MX(0, 1)
    g_rest, f_val = ca.Function("ocp_rest_fg", [xs], [g_r, f_r])(x)
    jac_r = ca.Function("ocp_rest_jac", [xs], [ca.jacobian(g_r, xs)])(x)
    grad = ca.Function("ocp_rest_grad", [xs], [ca.gradient(f_r, xs)])(x)
    hess = ca.Function("ocp_rest_hess", [xs, lam_r, sig],
                       [ca.triu(ca.hessian(sig * f_r + ca.dot(lam_r, g_r), xs)[0])]
                       )(x, lam_rest, lam_f)
    g_rows: dict[int, ca.MX] = {}
    jac_rows: dict[int, ca.MX] = {}
    for call, (fg, fq, fjac, fgrad, fhess) in zip(calls, derivatives):
        a, c0, nz = _affine(call, w, nw)
        n = call.n
        zmat = ca.reshape(ca.mtimes(a, x) + c0, nz, n)
        if call.g_block is not None:
            k = call.g_block
            g_rows[k] = ca.vec(fg.map(n)(zmat))
            ng = fg.numel_out(0)
            jall = fjac.map(n)(zmat)
            sp, s = _scatter(jall.sparsity(), n, nz, a, False)
            jac_rows[k] = ca.MX(sp, ca.mtimes(s, ca.vec(jall.nz[:]))) if sp.nnz() \
                else ca.MX(ng * n, nw)
            lam_e = ca.reshape(lam_g[int(offsets[k]):int(offsets[k + 1])], ng, n)
        else:
            lam_e = ca.MX(0, n)
        if call.quad:
            f_val = f_val + ca.sum2(fq.map(n)(zmat))
            grad = grad + ca.mtimes(a.T, ca.vec(fgrad.map(n)(zmat)))
        hall = fhess.map(n)(zmat, lam_e, lam_f)
        sp, s = _scatter(hall.sparsity(), n, nz, a, True)
        if sp.nnz():
            hess = hess + ca.MX(sp, ca.mtimes(s, ca.vec(hall.nz[:])))
    cuts = [0, *np.cumsum([sizes[i] for i in rest]).astype(int).tolist()]
    rest_rows = ca.vertsplit(g_rest, cuts) if rest else []
    rest_jac = ca.vertsplit(jac_r, cuts) if rest else []
    where = {i: j for j, i in enumerate(rest)}
    g_val = ca.vertcat(*[g_rows[i] if i in g_rows else rest_rows[where[i]]
                         for i in range(len(g_blocks))]) if g_blocks else ca.MX(0, 1)
    jac = ca.vertcat(*[jac_rows[i] if i in jac_rows else rest_jac[where[i]]
                       for i in range(len(g_blocks))]) if g_blocks else ca.MX(0, nw)
    return {"problem": {"x": x, "f": f_val, "g": g_val},
            "options": {
                "grad_f": ca.Function("nlp_grad_f", [x, p], [f_val, grad],
                                      ["x", "p"], ["f", "grad_f_x"]),
                "jac_g": ca.Function("nlp_jac_g", [x, p], [g_val, jac],
                                     ["x", "p"], ["g", "jac_g_x"]),
                "hess_lag": ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [hess],
                                        ["x", "p", "lam_f", "lam_g"],
                                        ["triu_hess_gamma_x_x"])}}


#: How the NLP's derivatives are evaluated, by :attr:`Ocp.compile <casmbd.ocp.problem.Ocp>`.
MODES = {"auto": "structured, compiled if small", False: "structured, virtual machine",
         True: "structured, compiled elements", "elements": "structured, compiled elements",
         "nlp": "compiled NLP", "vm": "virtual machine, MX"}


def check_mode(value) -> str | bool:
    """``value`` if it is a key of :data:`MODES` (``compile`` of an Ocp), else an
    AnalysisError naming it."""
    if isinstance(value, bool) or (isinstance(value, str) and value in MODES):
        return value
    raise AnalysisError(f"ocp: compile = {value!r}: expected one of "
                        f"{', '.join(repr(k) for k in MODES)}")


#: ``compile="auto"`` compiles the per-element derivative functions with the default flags
#: when they hold at most this many SX instructions in all (about 2 s of ``cc -O2`` on the
#: shared 2-core machine of docs/ocp.md: cart-pole 1.6k, double pendulum 8.4k) …
AUTO_COMPILE_INSTRUCTIONS = 20_000
#: … at ``-O0`` up to this many (the four-bar's 37k and the slider-crank's 34k: 4.4–4.6 s at
#: a load average of 10, against 8.7 s at ``-O2``) and evaluates them in the virtual machine
#: above (the UR5's 580k: over a minute of ``cc``).
AUTO_COMPILE_O0_INSTRUCTIONS = 60_000
#: Bumped when the derivative functions built for the same element functions change.
_DERIVATIVES_FORMAT = "casmbd-ocp-derivatives-1"
_KINDS = ("g", "q", "jac", "grad", "hess")


def _element_key(calls: list) -> str:
    """SHA-256 of what the derivative functions are made from: the element functions
    (CasADi's exact serialization), their roles, CasADi, the platform and the compiler
    settings that reach the library."""
    digest = hashlib.sha256()
    for part in (_DERIVATIVES_FORMAT, ca.__version__, platform.platform(),
                 os.environ.get("CC", ""), os.environ.get("CASMBD_CFLAGS", "")):
        digest.update(part.encode() + b"\x1e")
    for call in calls:
        digest.update(call.function.serialize().encode())
        digest.update(repr((call.quad, call.g_block is None)).encode() + b"\x1e")
    return digest.hexdigest()


def _index_path(name: str, key: str) -> pathlib.Path:
    return cache.cache_dir() / f"{name}_{key[:16]}.index.json"


def _load_indexed(name: str, key: str, names: list[str]) -> dict | None:
    """The compiled derivative functions ``names`` recorded under the element ``key``, each
    library verified by :func:`casmbd.compiled.cache.check_entry` (size, SHA-256, build key,
    signatures) before it is opened and the loaded signatures compared again; None when
    anything is missing or does not match (then they are built again)."""
    path = _index_path(name, key)
    try:
        index = json.loads(cache.read_record_text(path))
    except (OSError, ValueError):
        return None
    if not isinstance(index, dict) or index.get("key") != key:
        return None
    out = {}
    for entry in index.get("libraries", []):
        library = path.parent / str(entry.get("file", ""))
        expected = entry.get("functions") or {}
        if library.parent != path.parent or cache.check_entry(
                library, str(entry.get("key")), expected) is not None:
            return None
        try:
            loaded = {n: ca.external(n, str(library), {"enable_fd": True}) for n in expected}
        except RuntimeError:
            return None
        if cache.differences(cache.signatures(loaded.values()), expected):
            return None
        out.update(loaded)
    return out if sorted(out) == sorted(names) else None


def _compiled_derivatives(calls: list, name: str, key: str, derivatives: list,
                          flags: list[str] | None = None):
    """(derivatives compiled by :func:`compile_blocks` with ``flags`` and loaded, report,
    compiled?); the libraries are then indexed under the element ``key``
    (:func:`_load_indexed`)."""
    flat = [f for group in derivatives for f in group]
    loaded, report = compile_blocks(flat, f"{name}_el", flags=flags)
    if report.mode != "compiled":
        return derivatives, report, False
    entries = []
    for library in report.libraries or (report.library,):
        record = cache.read_record(pathlib.Path(library))
        entries.append({"file": os.path.basename(library), "key": record.get("key"),
                        "functions": record.get("functions", {})})
    try:
        cache.write_atomic(_index_path(name, key), json.dumps(
            {"key": key, "libraries": entries}, sort_keys=True))
    except OSError:
        pass  # the libraries stay usable, found by the generated code's key
    return [[loaded[f.name()] for f in group] for group in derivatives], report, True


def nlp_solver(name: str, plugin: str, w: ca.MX, objective, objective_rest, g_blocks: list,
               calls: list, options: dict, mode, structured: bool = True):
    """The NLP solver of a transcription and how it was built.

    ``mode`` (:data:`MODES`): False — derivatives assembled from the per-element SX
    derivative functions (:func:`structured_nlp_functions`) in CasADi's virtual machine;
    True/``"elements"`` — the same with those functions compiled to C and cached
    (:func:`casmbd.compiled.build.compile_blocks`, indexed under the element functions'
    serialization so that a later process loads them without differentiating);
    ``"auto"`` — compiled when already cached or small (:data:`AUTO_COMPILE_INSTRUCTIONS`,
    at ``-O0`` up to :data:`AUTO_COMPILE_O0_INSTRUCTIONS`), else in the virtual machine;
    ``"nlp"`` — the whole NLP's derivative functions generated from the MX graph, compiled
    and cached (:func:`casmbd.compiled.codegen.compile_nlp_solver`); ``"vm"`` — CasADi's own
    derivatives of the MX graph in the virtual machine.  Without structure (an MX integrator
    in a shooting interval, ``structured`` False) the structured modes fall back to ``"vm"``.

    Returns
    -------
    solver : casadi.Function
    report : BuildReport or None
        Of the compilation, if any.
    used : str
        The description of :data:`MODES` that applies.
    """
    g = ca.vertcat(*g_blocks) if g_blocks else ca.MX(0, 1)
    problem = {"x": w, "f": objective, "g": g}
    if mode == "nlp":
        solver, report = compile_nlp_solver(problem, plugin, options, name=name)
        return solver, report, MODES["nlp"] if report.mode == "compiled" else MODES["vm"]
    if mode == "vm" or not structured:
        return ca.nlpsol(name, plugin, problem, options), None, MODES["vm"]
    report, compiled, hit = None, False, None
    key = _element_key(calls) if mode is not False else ""
    stem = f"{name}_{key[:12]}" if key else name
    names = [[f"{stem}_d{i}_{k}" for k in _KINDS] for i in range(len(calls))]
    if key and os.environ.get("CASMBD_COMPILE", "1") != "0":
        start = time.perf_counter()
        hit = _load_indexed(name, key, [n for group in names for n in group])
    if hit is not None:  # compiled before: loaded, nothing differentiated or generated
        derivatives, compiled = [[hit[n] for n in group] for group in names], True
        report = BuildReport(mode="compiled", cache_hit=True, compiled=False,
                             codegen_seconds=0.0, compile_seconds=0.0,
                             load_seconds=time.perf_counter() - start,
                             library=str(_index_path(name, key)), key=key)
    else:
        derivatives = [derivative_functions(c, f"{stem}_d{i}") for i, c in enumerate(calls)]
        size = sum(f.n_instructions() for group in derivatives for f in group)
        flags = None
        if mode == "auto" and size > AUTO_COMPILE_INSTRUCTIONS \
                and not os.environ.get("CASMBD_CFLAGS", "").strip():
            flags = ["-O0"]
        if mode in (True, "elements") or (mode == "auto"
                                          and size <= AUTO_COMPILE_O0_INSTRUCTIONS):
            derivatives, report, compiled = _compiled_derivatives(calls, name, key,
                                                                  derivatives, flags)
    built = structured_nlp_functions(w, g_blocks, objective_rest, calls, derivatives)
    solver = ca.nlpsol(name, plugin, built["problem"], {**options, **built["options"]})
    return solver, report, MODES[True] if compiled else MODES[False]
