"""Tests of casmbd.compiled.codegen: C code generation, compilation, loading and caching."""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import warnings

import casadi
import numpy as np
import pytest
from conftest import private_cache

from casmbd.compiled import codegen
from casmbd.compiled.codegen import BuildReport, cache_dir, compile_functions
from casmbd.errors import CompileError

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
TESTS_DIR = pathlib.Path(__file__).resolve().parents[1]
HERE = pathlib.Path(__file__).resolve().parent

needs_compiler = pytest.mark.skipif(
    codegen.find_compiler() is None, reason="no C compiler available"
)


def make_functions(scale: float = 1.0) -> list[casadi.Function]:
    """Build a small set of SX functions: sparse 6x6 mass matrix, vector and Jacobian.

    ``scale`` changes the expressions (not the structure) to get a different model.
    """
    q = casadi.SX.sym("q", 4)
    qd = casadi.SX.sym("qd", 4)
    c0, s0 = casadi.cos(q[0]), casadi.sin(q[0])
    block_a = casadi.blockcat(
        [
            [2.0 + c0, scale * s0 * q[1], 0.1 * q[2]],
            [scale * s0 * q[1], 3.0 + q[1] ** 2, 0],
            [0.1 * q[2], 0, 1.5 + casadi.exp(-(q[3] ** 2))],
        ]
    )
    block_a = casadi.sparsify(block_a)
    block_b = casadi.diag(casadi.vertcat(1.0 + q[0] ** 2, 4.0 + scale * c0, 0.5 + q[3]))
    mass = casadi.diagcat(block_a, block_b)
    mass_fun = casadi.Function("mass_matrix", [q], [mass], ["q"], ["M"])

    h = casadi.vertcat(
        scale * s0 * qd[0] * qd[1],
        c0 * qd[2] ** 2 - q[1],
        casadi.tanh(q[2]) * qd[3],
        q[3] * qd[0] + casadi.sqrt(1.0 + q[1] ** 2),
    )
    energy = 0.5 * casadi.dot(qd, qd) * (1.0 + scale * q[0] ** 2)
    vec_fun = casadi.Function("bias_forces", [q, qd], [h, energy], ["q", "qd"], ["h", "T"])

    jac_fun = casadi.Function(
        "bias_jacobian", [q, qd], [casadi.jacobian(h, q)], ["q", "qd"], ["dh_dq"]
    )
    return [mass_fun, vec_fun, jac_fun]


def assert_same_function(original: casadi.Function, compiled: casadi.Function, seed: int) -> None:
    """Assert equal interface and equal values (1e-12) on 20 random inputs."""
    assert compiled.name() == original.name()
    assert compiled.name_in() == original.name_in()
    assert compiled.name_out() == original.name_out()
    for i in range(original.n_in()):
        assert compiled.sparsity_in(i) == original.sparsity_in(i)
    for i in range(original.n_out()):
        assert compiled.sparsity_out(i) == original.sparsity_out(i)
    rng = np.random.default_rng(seed)
    for _ in range(20):
        args = {
            name: rng.uniform(-2.0, 2.0, original.sparsity_in(i).nnz())
            for i, name in enumerate(original.name_in())
        }
        expected = original.call(args)
        actual = compiled.call(args)
        for name in original.name_out():
            assert actual[name].sparsity() == expected[name].sparsity()
            np.testing.assert_allclose(
                np.array(actual[name].nonzeros()),
                np.array(expected[name].nonzeros()),
                rtol=0.0,
                atol=1e-12,
            )


#: every test has an empty cache; nothing steers the builds
isolated_cache = private_cache(CASMBD_COMPILE=None, CASMBD_CFLAGS=None)


def test_cache_dir_locations(tmp_path, monkeypatch, isolated_cache):
    assert cache_dir() == isolated_cache
    assert isolated_cache.is_dir()
    monkeypatch.delenv("CASMBD_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "casmbd"
    assert (tmp_path / "xdg" / "casmbd").is_dir()
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "casmbd"


@needs_compiler
def test_compiled_matches_vm(isolated_cache):
    functions = make_functions()
    count = codegen.COMPILE_COUNT
    loaded, report = compile_functions(functions, "cg_test_model", mode="compiled")
    assert isinstance(report, BuildReport)
    assert report.mode == "compiled"
    assert report.compiled and not report.cache_hit
    assert codegen.COMPILE_COUNT == count + 1
    assert report.compile_seconds > 0.0
    assert set(loaded) == {"mass_matrix", "bias_forces", "bias_jacobian"}
    for seed, original in enumerate(functions):
        assert loaded[original.name()] is not original
        assert_same_function(original, loaded[original.name()], seed)
    # the mass matrix really is sparse (block diagonal with structural zeros)
    mass_sparsity = loaded["mass_matrix"].sparsity_out(0)
    assert mass_sparsity.size() == (6, 6)
    assert mass_sparsity.nnz() < 36

    library = pathlib.Path(report.library)
    assert library.parent == isolated_cache
    assert library.name == f"cg_test_model_{report.key[:16]}.so"
    source = library.with_suffix(".c")
    assert source.is_file()
    assert "mass_matrix" in source.read_text()
    # nothing half-written is left behind
    assert not [p for p in isolated_cache.iterdir() if p.name.endswith(".tmp")]


@needs_compiler
def test_symbol_prefix_matches_direct_generation():
    functions = make_functions()
    _, report = compile_functions(functions, "cg_prefix", mode="compiled")
    stem = f"cg_prefix_{report.key[:16]}"
    generator = casadi.CodeGenerator(f"{stem}.c", dict(codegen._CODEGEN_OPTIONS))
    for function in functions:
        generator.add(function)
    kept = pathlib.Path(report.library).with_suffix(".c").read_text()
    # CasADi's own C, with its runs of output stores under one test each
    assert kept == codegen._merge_output_guards(generator.dump())
    assert codegen._PREFIX_MARKER not in kept


@needs_compiler
def test_second_call_same_process_hits_cache():
    _, first = compile_functions(make_functions(), "cg_cache", mode="compiled")
    count = codegen.COMPILE_COUNT
    loaded, second = compile_functions(make_functions(), "cg_cache", mode="compiled")
    assert second.cache_hit and not second.compiled
    assert second.mode == "compiled"
    assert second.compile_seconds == 0.0
    assert second.key == first.key
    assert second.library == first.library
    assert codegen.COMPILE_COUNT == count
    for seed, original in enumerate(make_functions()):
        assert_same_function(original, loaded[original.name()], seed)


@needs_compiler
def test_second_process_hits_cache(isolated_cache):
    _, first = compile_functions(make_functions(), "cg_process", mode="compiled")
    script = (
        "import json, sys, dataclasses\n"
        f"sys.path[:0] = [{str(REPO_ROOT)!r}, {str(TESTS_DIR)!r}, {str(HERE)!r}]\n"
        "from casmbd.compiled import codegen\n"
        "from test_codegen import make_functions\n"
        "funs, report = codegen.compile_functions(make_functions(), 'cg_process',"
        " mode='compiled')\n"
        "assert codegen.COMPILE_COUNT == 0\n"
        "print(json.dumps(dataclasses.asdict(report)))\n"
    )
    env = dict(os.environ, CASMBD_CACHE_DIR=str(isolated_cache))
    result = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=env,
        cwd=str(REPO_ROOT),
        timeout=300,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["cache_hit"] is True
    assert report["compiled"] is False
    assert report["mode"] == "compiled"
    assert report["key"] == first.key
    assert report["library"] == first.library


@needs_compiler
def test_changed_function_gets_new_key():
    old_functions = make_functions(1.0)
    new_functions = make_functions(2.0)
    old_loaded, old_report = compile_functions(old_functions, "cg_change", mode="compiled")
    count = codegen.COMPILE_COUNT
    new_loaded, new_report = compile_functions(new_functions, "cg_change", mode="compiled")
    assert new_report.key != old_report.key
    assert new_report.library != old_report.library
    assert new_report.compiled and not new_report.cache_hit
    assert codegen.COMPILE_COUNT == count + 1
    # both libraries export functions of the same names; each keeps its own code
    for seed, (old, new) in enumerate(zip(old_functions, new_functions)):
        assert_same_function(old, old_loaded[old.name()], seed)
        assert_same_function(new, new_loaded[new.name()], seed)
    q = np.array([0.3, -0.7, 0.2, 0.9])
    assert float(old_loaded["mass_matrix"](q)[0, 1]) != float(new_loaded["mass_matrix"](q)[0, 1])


@needs_compiler
def test_flags_are_part_of_the_key(monkeypatch):
    _, default = compile_functions(make_functions(), "cg_flags", mode="compiled")
    _, explicit = compile_functions(make_functions(), "cg_flags", mode="compiled", flags=["-O0"])
    monkeypatch.setenv("CASMBD_CFLAGS", "-O1 -g")
    _, from_env = compile_functions(make_functions(), "cg_flags", mode="compiled")
    assert len({default.key, explicit.key, from_env.key}) == 3
    assert explicit.compiled and from_env.compiled


def test_vm_mode_returns_originals():
    functions = make_functions()
    count = codegen.COMPILE_COUNT
    loaded, report = compile_functions(functions, "cg_vm", mode="vm")
    assert report.mode == "vm"
    assert not report.compiled and not report.cache_hit
    assert report.library is None
    assert codegen.COMPILE_COUNT == count
    for function in functions:
        assert loaded[function.name()] is function


def test_casmbd_compile_zero_forces_vm(monkeypatch):
    monkeypatch.setenv("CASMBD_COMPILE", "0")
    functions = make_functions()
    count = codegen.COMPILE_COUNT
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded, report = compile_functions(functions, "cg_env_vm")
    assert report.mode == "vm"
    assert codegen.COMPILE_COUNT == count
    assert all(loaded[f.name()] is f for f in functions)


@pytest.mark.parametrize("how", ["environment", "helper"])
def test_missing_compiler(monkeypatch, how):
    if how == "environment":
        monkeypatch.setenv("CC", "/nonexistent/bin/no-such-cc")
        monkeypatch.setenv("PATH", "")
        assert codegen.find_compiler() is None
    else:
        monkeypatch.setattr(codegen, "find_compiler", lambda: None)
    functions = make_functions()
    count = codegen.COMPILE_COUNT
    with pytest.warns(RuntimeWarning, match="no C compiler"):
        loaded, report = compile_functions(functions, "cg_nocc", mode="auto")
    assert report.mode == "vm"
    assert not report.compiled and report.library is None
    assert all(loaded[f.name()] is f for f in functions)
    with pytest.raises(CompileError, match="no C compiler"):
        compile_functions(functions, "cg_nocc", mode="compiled")
    assert codegen.COMPILE_COUNT == count


@needs_compiler
def test_compiler_failure(monkeypatch, isolated_cache):
    monkeypatch.setenv("CASMBD_CFLAGS", "-this-flag-does-not-exist")
    functions = make_functions()
    with pytest.raises(CompileError) as info:
        compile_functions(functions, "cg_fail", mode="compiled")
    message = str(info.value)
    assert "this-flag-does-not-exist" in message
    assert "exit code" in message
    assert not list(isolated_cache.glob("cg_fail_*"))
    assert not [p for p in isolated_cache.iterdir() if p.name.endswith(".tmp")]

    with pytest.warns(RuntimeWarning, match="this-flag-does-not-exist"):
        loaded, report = compile_functions(functions, "cg_fail", mode="auto")
    assert report.mode == "vm"
    assert all(loaded[f.name()] is f for f in functions)


@needs_compiler
def test_compiler_timeout_becomes_compile_error(monkeypatch):
    class FakeCompiler:
        def __init__(self, command, **kwargs):
            self.command, self.pid, self.returncode, self.calls = command, -1, None, 0

        def communicate(self, timeout=None):
            self.calls += 1
            if self.calls == 1:
                raise subprocess.TimeoutExpired(self.command, timeout)
            return "", ""

    monkeypatch.setattr(codegen.subprocess, "Popen", FakeCompiler)
    monkeypatch.setattr(codegen.os, "killpg", lambda pid, sig: None)
    with pytest.raises(CompileError, match="timed out"):
        compile_functions(make_functions(), "cg_timeout", mode="compiled")


def test_invalid_arguments():
    functions = make_functions()
    with pytest.raises(ValueError, match="mode"):
        compile_functions(functions, mode="fast")
    with pytest.raises(ValueError, match="C identifier"):
        compile_functions(functions, "bad-name", mode="vm")
    with pytest.raises(ValueError, match="at least one"):
        compile_functions([], mode="vm")
    with pytest.raises(ValueError, match="duplicate"):
        compile_functions([functions[0], functions[0]], mode="vm")
    with pytest.raises(TypeError, match=r"casadi\.Function"):
        compile_functions([functions[0], "not a function"], mode="vm")


def test_compiler_timeout_ends_the_compilers_children(tmp_path, monkeypatch):
    """A compiler that outlives COMPILE_TIMEOUT is killed with its whole process group (gcc's
    cc1 child would otherwise run on), and the error says it timed out."""
    import os
    import time

    from casmbd.compiled import codegen
    from casmbd.errors import CompileError

    pidfile = tmp_path / "child.pid"
    monkeypatch.setattr(codegen, "COMPILE_TIMEOUT", 0.5)
    command = ["sh", "-c", f"sleep 30 & echo $! > {pidfile}; wait"]
    with pytest.raises(CompileError, match="timed out"):
        codegen._run_compiler(command, tmp_path / "x.c", tmp_path / "x.so")
    child = int(pidfile.read_text())
    for _ in range(50):  # the kill is immediate; give the kernel a moment to reap
        try:
            os.kill(child, 0)
        except ProcessLookupError:
            break
        time.sleep(0.05)
    else:
        pytest.fail(f"child {child} of the timed-out compiler is still running")
    assert not list(tmp_path.glob("*.so.tmp"))


def test_nlp_compile_failure_falls_back_to_the_virtual_machine(tmp_path, monkeypatch):
    """As compile_functions in "auto" mode: a failed NLP compile warns and solves in the VM
    (min (x−1)² + (y−2)² s.t. x + y = 1 → x = 0, y = 1)."""
    import casadi as ca

    from casmbd.compiled import codegen
    from casmbd.errors import CompileError

    def broken(*args, **kwargs):
        raise CompileError("no luck")

    monkeypatch.setenv("CASMBD_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(codegen, "_run_compiler", broken)
    x = ca.MX.sym("x", 2)
    problem = {"x": x, "f": (x[0] - 1) ** 2 + (x[1] - 2) ** 2, "g": x[0] + x[1]}
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes"}
    with pytest.warns(RuntimeWarning, match="virtual machine"):
        solver, report = codegen.compile_nlp_solver(problem, "ipopt", opts, "cg_nlp_fail")
    assert report.mode == "vm" and not report.compiled
    sol = solver(x0=[0, 0], lbg=1, ubg=1)
    assert np.allclose(np.asarray(sol["x"]).ravel(), [0.0, 1.0], atol=1e-8)
