"""Translation units of casmbd.compiled.codegen (casmbd.compiled.units, issue 22 item 3):
which functions share a unit and at which flags, and the parallel build of many units into
one library, whose functions evaluate as the originals do."""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from casmbd.compiled import codegen, units
from casmbd.errors import CompileError

needs_compiler = pytest.mark.skipif(codegen.find_compiler() is None,
                                    reason="no C compiler available")


def functions() -> list[casadi.Function]:
    x = casadi.SX.sym("x", 3)
    return [casadi.Function("rhs", [x], [casadi.sin(x) * x[0]]),
            casadi.Function("post", [x], [casadi.dot(x, x), casadi.exp(x[1])]),
            casadi.Function("energy", [x], [casadi.sum1(casadi.cos(x))])]


def test_plan_flags_and_grouping(monkeypatch):
    fs = functions()
    plan = units.plan(fs, codegen._generate_template, None, ["-O2"], {"rhs"})
    # small: one unit per flag set, hot at the default flags, the rest cold
    assert [([f.name() for f in u[0]], u[2]) for u in plan] == \
        [(["rhs"], ["-O2"]), (["post", "energy"], list(units.COLD_FLAGS))]
    assert [u[2] for u in units.plan(fs, codegen._generate_template, None, ["-O2"], None)] \
        == [["-O2"]]  # nothing named hot: all optimised, one unit
    chosen = units.plan(fs, codegen._generate_template, ["-O3"], ["-O3"], {"rhs"})
    assert [u[2] for u in chosen] == [["-O3"]]  # chosen flags win
    monkeypatch.setattr(units, "SPLIT_SOURCE", 0)  # large: one unit per function
    plan = units.plan(fs, codegen._generate_template, None, ["-O2"], {"rhs"})
    assert [[f.name() for f in u[0]] for u in plan] == [["rhs"], ["post"], ["energy"]]
    assert [u[2] for u in plan] == [["-O2"], list(units.COLD_FLAGS), list(units.COLD_FLAGS)]
    monkeypatch.setattr(units, "LARGE_SOURCE", 0)  # above LARGE_SOURCE: cold even if hot
    assert {tuple(u[2]) for u in units.plan(fs, codegen._generate_template, None, ["-O2"],
                                            None)} == {units.COLD_FLAGS}


@needs_compiler
def test_units_compile_in_parallel_into_one_library(tmp_path, monkeypatch):
    monkeypatch.setenv("CASMBD_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("CASMBD_CFLAGS", raising=False)
    monkeypatch.setattr(units, "SPLIT_SOURCE", 0)
    fs = functions()
    out, report = codegen.compile_functions(fs, "units_test", mode="compiled", hot={"rhs"})
    assert report.compiled and len(report.libraries) == 1
    x = np.array([0.3, -1.2, 2.5])
    for f in fs:
        for got, want in zip(out[f.name()].call([x]), f.call([x]), strict=True):
            np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-15,
                                       atol=1e-15)
    _, report = codegen.compile_functions(fs, "units_test", mode="compiled", hot={"rhs"})
    assert report.cache_hit and not report.compiled
    # other flags for the same functions are another build
    _, other = codegen.compile_functions(fs, "units_test", mode="compiled")
    assert other.compiled and other.key != report.key


@needs_compiler
def test_a_failing_unit_names_its_command(tmp_path):
    good = tmp_path / "good.c"
    good.write_text("int f(void) { return 1; }\n")
    bad = tmp_path / "bad.c"
    bad.write_text("int g(void) { return syntax error; }\n")
    cc = codegen.find_compiler()
    commands = [[*cc, "-c", str(src), "-o", str(src.with_suffix(".o"))] for src in (good, bad)]
    logs = [src.with_suffix(".log") for src in (good, bad)]
    with pytest.raises(CompileError, match=r"bad\.c"):
        units.compile_objects(commands, logs, timeout=60.0)
    (tmp_path / "good.o").unlink(missing_ok=True)
    units.compile_objects(commands[:1], logs[:1], timeout=60.0)
    assert (tmp_path / "good.o").exists()


def test_a_batch_shares_the_unit_of_its_function(monkeypatch):
    """Split units without hot functions: a ``map`` of a listed Function is compiled with it
    (its C once), the others alone."""
    fs = functions()
    batch = fs[0].map("rhs_batch", "serial", 4, [], [])
    monkeypatch.setattr(units, "SPLIT_SOURCE", 0)
    plan = units.plan([*fs, batch], codegen._generate_template, None, ["-O2"], None)
    assert [[f.name() for f in u[0]] for u in plan] == [["rhs", "rhs_batch"], ["post"],
                                                         ["energy"]]
    # rhs's body written once: the shared unit is shorter than the two units alone
    together, gen = plan[0][1], codegen._generate_template
    assert len(together) < len(gen([fs[0]])) + len(gen([batch]))
    assert together.count("sin(") == gen([batch]).count("sin(") >= 1


def test_a_large_per_call_library_gets_the_bulk_flags(monkeypatch):
    """Without hot functions, above BULK_SOURCE bytes of C in all, the default flags give way
    to BULK_FLAGS (-O1 with strict aliasing); hot functions, chosen flags and the size rules
    of one function keep theirs."""
    fs = functions()
    gen = codegen._generate_template
    total = sum(len(gen([f])) for f in fs)
    monkeypatch.setattr(units, "BULK_SOURCE", total - 1)  # just above it
    assert units.BULK_FLAGS == ("-O1", "-fstrict-aliasing")
    assert [u[2] for u in units.plan(fs, gen, None, ["-O2"], None)] == [list(units.BULK_FLAGS)]
    assert [u[2] for u in units.plan(fs, gen, None, ["-O2"], {"rhs"})] == \
        [["-O2"], list(units.COLD_FLAGS)]  # an integrator's library: as before
    assert [u[2] for u in units.plan(fs, gen, ["-O3"], ["-O3"], None)] == [["-O3"]]
    monkeypatch.setattr(units, "SPLIT_SOURCE", 0)
    sizes = [len(gen([f])) for f in fs]
    monkeypatch.setattr(units, "MEDIUM_SOURCE", sorted(sizes)[-2])  # the largest alone above
    assert sorted(sizes)[-2] < max(sizes)
    assert [u[2] for u in units.plan(fs, gen, None, ["-O2"], None)] == \
        [list(units.MEDIUM_FLAGS if n == max(sizes) else units.BULK_FLAGS) for n in sizes]
    monkeypatch.setattr(units, "MEDIUM_SOURCE", max(sizes))
    monkeypatch.setattr(units, "BULK_SOURCE", total)  # at it: the default flags
    assert [u[2] for u in units.plan(fs, gen, None, ["-O2"], None)] == [["-O2"]] * 3


def test_output_guards_merge_per_run():
    """Consecutive stores guarded by the same res[i] share one test; other lines, and runs
    of another output, stay as they were."""
    text = ("  a0=0.;\n"
            "  if (res[0]!=0) res[0][0]=a0;\n"
            "  if (res[0]!=0) res[0][1]=a0;\n"
            "  if (res[1]!=0) res[1][0]=a1;\n"
            "  a2=sin(a1);\n"
            "  if (res[0]!=0) res[0][2]=a2;\n"
            "  if (res[0]!=0) casadi_copy(w0, 3, res[0]);\n"
            "  if (res[0]!=0) { res[0][3]=a2; }\n")
    assert codegen._merge_output_guards(text) == (
        "  a0=0.;\n"
        "  if (res[0]!=0) {res[0][0]=a0; res[0][1]=a0;}\n"
        "  if (res[1]!=0) res[1][0]=a1;\n"
        "  a2=sin(a1);\n"
        "  if (res[0]!=0) {res[0][2]=a2; casadi_copy(w0, 3, res[0]);}\n"
        "  if (res[0]!=0) { res[0][3]=a2; }\n")


@needs_compiler
def test_merged_guards_compile_to_the_same_numbers(tmp_path, monkeypatch):
    """A dense output with structural zeros (a Jacobian-like 6 x 8 block) and a second
    output, compiled from the merged C: equal to the CasADi virtual machine to rounding, and
    a null output pointer still skips its stores."""
    monkeypatch.setenv("CASMBD_CACHE_DIR", str(tmp_path))
    x = casadi.SX.sym("x", 8)
    jac = casadi.densify(casadi.jacobian(casadi.vertcat(casadi.sin(x[:3]), x[3] * x[4],
                                                        casadi.cos(x[5]), x[0] * x[7]), x))
    f = casadi.Function("guarded", [x], [jac, casadi.sum1(x)])
    template = codegen._generate_template([f])
    assert template.count("if (res[0]!=0)") < 48 // 4  # 48 stores, a few runs
    out, _ = codegen.compile_functions([f], "guards_test", mode="compiled")
    xv = np.linspace(-1.0, 1.3, 8)
    for got, want in zip(out["guarded"].call([xv]), f.call([xv]), strict=True):
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-15, atol=0)
    buf, trigger = out["guarded"].buffer()
    buf.set_arg(0, memoryview(xv))
    total = np.zeros(1)
    buf.set_res(1, memoryview(total))  # res[0] left null
    trigger()
    assert total[0] == pytest.approx(xv.sum(), rel=1e-15)


def test_callers_of_a_small_hot_function_get_their_own_unit(monkeypatch):
    """A caller of a hot function shares its unit only when the hot C exceeds SHARE_SOURCE:
    a folded right-hand side is small, its caller (``post`` with the unrolled energies) is
    then compiled alone at the cold flags, repeating the hot C."""
    x = casadi.SX.sym("x", 3)
    rhs = casadi.Function("rhs", [x], [casadi.sin(x) * x[0]])
    xm = casadi.MX.sym("x", 3)
    post = casadi.Function("post", [xm], [rhs(xm) + casadi.exp(xm)])
    monkeypatch.setattr(units, "SPLIT_SOURCE", 0)
    gen = codegen._generate_template
    monkeypatch.setattr(units, "SHARE_SOURCE", 0)
    shared = units.plan([rhs, post], gen, None, ["-O2"], {"rhs"})
    assert [([f.name() for f in u[0]], u[2]) for u in shared] == [(["rhs", "post"], ["-O2"])]
    monkeypatch.setattr(units, "SHARE_SOURCE", 10**9)
    alone = units.plan([rhs, post], gen, None, ["-O2"], {"rhs"})
    assert [([f.name() for f in u[0]], u[2]) for u in alone] == \
        [(["rhs"], ["-O2"]), (["post"], list(units.COLD_FLAGS))]
