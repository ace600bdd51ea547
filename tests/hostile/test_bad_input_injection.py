"""Bad input, category "injection" (issue 18, items 1 and 7): nothing in a scene file, a result
file or a command-line argument compiles code, starts a process, loads a library or writes a
file the user did not ask for.

Every case asserts the error class, the culprit named in the message and that the payload left
no trace (a marker file the payload would create, an output file it would write).  The payloads
are real: :func:`test_control_the_jit_payload_runs_when_given_to_casadi_directly` shows that
the same options handed to CasADi directly do run the shell command, so the refusals below are
not vacuous.
"""

from __future__ import annotations

import pathlib
import re

import casadi as ca
import numpy as np
import pytest
from conftest import private_cache

from casmbd import cli
from casmbd.compiled import codegen
from casmbd.compiled.model import NumericModel
from casmbd.errors import AnalysisError, CasmbdError, ExpressionError, SceneError
from casmbd.io.ocp_table import load_ocp
from casmbd.io.scene import load_scene
from casmbd.model.expressions import parse_expression
from casmbd.ocp import Ocp
from casmbd.ocp.options import SOLVER_OPTIONS

ROOT = pathlib.Path(__file__).resolve().parents[2]

# a block on a slide pushed by one actuator: the smallest OCP there is (2 intervals)
SCENE = """
[scene]
name = "{name}"
gravity = [0.0, 0.0]
coordinates = "joint"

[[bodies]]
name = "block"
mass = {mass}
inertia = 0.1
position = [0.0, 0.0]

[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "block"
point = [0.0, 0.0]
axis = [1.0, 0.0]

[[actuators]]
name = "push"
joint = "slide"

[ocp]
horizon = 1.0
intervals = 2
degree = 2
objective = "effort"
{ocp_extra}

[ocp.initial]
slide = 0.0
slide_dot = 0.0

[ocp.final]
slide = 1.0
slide_dot = 0.0
"""


def write_scene(tmp_path, ocp_extra: str = "", name: str = "slider", mass: str = "1.0"
                ) -> pathlib.Path:
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(ocp_extra=ocp_extra, name=name, mass=mass))
    return path


_env = private_cache(CASMBD_COMPILE="0", CASMBD_PROGRESS="0")


def jit_options(marker: pathlib.Path) -> dict:
    """CasADi options that make ``nlpsol`` run ``touch marker`` through the shell."""
    return {"jit": True, "compiler": "shell",
            "jit_options": {"compiler": f"touch {marker}; true", "verbose": False}}


def toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{ " + ", ".join(f'"{k}" = {toml_value(v)}' for k, v in value.items()) + " }"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(value)


def options_table(options: dict) -> str:
    return "[ocp.solver_options]\n" + "\n".join(f'"{k}" = {toml_value(v)}'
                                                for k, v in options.items())


# ----------------------------------------------------------------- solver options
def test_control_the_jit_payload_runs_when_given_to_casadi_directly(tmp_path):
    """The payload of the next test is live: passed to casadi.nlpsol it runs the shell."""
    marker = tmp_path / "marker"
    x = ca.SX.sym("x")
    with pytest.raises(RuntimeError):  # the "compiler" made no library, but it ran
        ca.nlpsol("s", "ipopt", {"x": x, "f": (x - 1) ** 2},
                  {**jit_options(marker), "print_time": False})
    assert marker.exists()


@pytest.mark.parametrize("key", ["jit", "compiler", "jit_options"])
def test_jit_and_compiler_options_in_a_scene_are_refused(tmp_path, key):
    marker = tmp_path / "marker"
    options = jit_options(marker)
    # the refused key first, the rest after it
    ordered = {key: options[key], **{k: v for k, v in options.items() if k != key}}
    path = write_scene(tmp_path, options_table(ordered))
    with pytest.raises(SceneError, match=rf"\[ocp\.solver_options\]: solver option '{key}' "
                                         r"is not allowed for ipopt \(allowed: .*ipopt\.tol"):
        load_ocp(path)
    assert not marker.exists()


@pytest.mark.parametrize("key", ["ipopt.output_file", "ipopt.option_file_name",
                                 "ipopt.hsllib", "ipopt.pardisolib"])
def test_file_and_library_options_are_refused(tmp_path, key):
    target = tmp_path / "written_by_ipopt.txt"
    path = write_scene(tmp_path, options_table({key: str(target), "ipopt.file_print_level": 5}))
    with pytest.raises(SceneError, match=rf"solver option '{re.escape(key)}' is not allowed"):
        load_ocp(path)
    assert not target.exists()


@pytest.mark.parametrize("key, value", [
    ("iteration_callback", "casmbd"), ("monitor", "nlp_f"), ("expand", True),
    ("common_options", {"jit": True}), ("specific_options", {"nlp_f": {"jit": True}}),
    ("ipopt.file_print_level", 5), ("error_on_fail", False), ("verbose", True),
    ("max_iter", 5),  # an sqpmethod option: not one of ipopt's
])
def test_internal_and_foreign_options_are_refused(tmp_path, key, value):
    path = write_scene(tmp_path, options_table({key: value}))
    with pytest.raises(SceneError, match=rf"solver option '{re.escape(key)}' is not allowed"):
        load_ocp(path)


@pytest.mark.parametrize("key, value, why", [
    ("ipopt.max_iter", -1, r"expected an integer in \[0, 100000\]"),
    ("ipopt.max_iter", 10**6, r"expected an integer in \[0, 100000\]"),
    ("ipopt.max_iter", 2.5, r"expected an integer"),
    ("ipopt.max_iter", "500", r"expected an integer"),
    ("ipopt.max_iter", True, r"expected an integer"),
    ("ipopt.tol", 0.0, r"expected a finite number in \(0, 0\.01\]"),
    ("ipopt.tol", "nan", r"expected a number"),
    ("ipopt.max_cpu_time", float("inf"), r"expected a finite number"),
    ("ipopt.bound_frac", 0.9, r"expected a finite number in \(0, 0\.5\]"),
    ("ipopt.print_level", 13, r"expected an integer in \[0, 5\]"),
    ("ipopt.mu_strategy", "fast", r"expected one of monotone, adaptive"),
    ("ipopt.linear_solver", "custom", r"expected one of mumps, spral"),
    ("ipopt.linear_solver", "../../tmp/libevil", r"expected one of mumps"),
    ("ipopt.warm_start_init_point", True, r"expected one of yes, no"),
    ("print_time", "yes", r"expected true or false"),
])
def test_option_values_are_type_and_range_checked(tmp_path, key, value, why):
    path = write_scene(tmp_path, options_table({key: value}))
    with pytest.raises(SceneError, match=rf"solver option '{re.escape(key)}' = .*: {why}"):
        load_ocp(path)


# options whose meaning subverts the result (issue 31): refused with the key, the allowed range
# and the reason, when the scene is read, before anything is solved
@pytest.mark.parametrize("solver, key, value, allowed, why", [
    ("ipopt", "ipopt.obj_scaling_factor", -1.0, r"\[1e-08, 1e\+08\]", "maximisation"),
    ("ipopt", "ipopt.obj_scaling_factor", 0.0, r"\[1e-08, 1e\+08\]", "maximisation"),
    ("ipopt", "ipopt.print_level", 12, r"\[0, 5\]", "megabytes"),
    ("ipopt", "ipopt.print_level", 6, r"\[0, 5\]", "megabytes"),
    ("ipopt", "ipopt.derivative_test", "second-order", "expected one of none", "minutes"),
    ("ipopt", "ipopt.derivative_test", "first-order", "expected one of none", "minutes"),
    ("ipopt", "ipopt.tol", 1.0, r"\(0, 0\.01\]", "Solve_Succeeded"),
    ("ipopt", "ipopt.constr_viol_tol", 1e3, r"\(0, 0\.01\]", "violates"),
    ("ipopt", "ipopt.acceptable_tol", 1e20, r"\(0, 1\]", "acceptable point"),
    ("ipopt", "ipopt.bound_relax_factor", 1.0, r"\[0, 0\.0001\]", "leave its bounds"),
    ("ipopt", "ipopt.limited_memory_max_history", 1000, r"\[0, 100\]", "two vectors"),
    ("ipopt", "ipopt.max_iter", 10**6, r"\[0, 100000\]", "run time"),
    ("sqpmethod", "tol_pr", 1.0, r"\(0, 0\.01\]", "violates"),
    ("sqpmethod", "min_step_size", 1.0, r"\(0, 0\.01\]", "line search"),
])
def test_options_that_subvert_the_result_are_refused(tmp_path, capsys, solver, key, value,
                                                      allowed, why):
    extra = f'solver = "{solver}"\n' + options_table({key: value})
    path = write_scene(tmp_path, extra)
    with pytest.raises(SceneError, match=rf"\[ocp\.solver_options\]: solver option "
                                         rf"'{re.escape(key)}' = .*{allowed}.*{why}"):
        load_ocp(path)
    # the CLI: exit 1, one error line naming the option, nothing on stdout, nothing written
    out = tmp_path / "sol.npz"
    assert cli.main(["ocp", str(path), "--json", "--mode", "vm", "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and key in lines[0], lines
    assert not out.exists()
    # and the Python API (AnalysisError) before any solve
    (tmp_path / "py").mkdir()
    mech = load_scene(write_scene(tmp_path / "py"))
    with pytest.raises(AnalysisError, match=rf"'{re.escape(key)}' = .*{allowed}"):
        Ocp(mech, intervals=2, solver=solver, solver_options={key: value})


def test_objective_scaling_within_range_leaves_the_optimum_unchanged(tmp_path):
    """An allowed obj_scaling_factor (10) is a scaling only: the same objective and controls
    as IPOPT's default 1 (relative 1e-6), and both the closed form: with one constant push u1
    on [0, 0.5] s and u2 on [0.5, 1] s, rest to rest (u2 = -u1) over 1 m gives x(1) = u1/4,
    so u1 = 4 N and the effort integral is 16 N² s."""
    objectives, controls = [], []
    for factor in (1.0, 10.0):
        folder = tmp_path / f"f{factor:g}"
        folder.mkdir()
        ocp = load_ocp(write_scene(folder, options_table({"ipopt.obj_scaling_factor": factor,
                                                          "ipopt.tol": 1e-10})))
        ocp.compile = False
        sol = ocp.solve()
        objectives.append(sol.objective)
        controls.append(sol.control("push"))
    assert objectives[1] == pytest.approx(objectives[0], rel=1e-6)
    np.testing.assert_allclose(controls[1], controls[0], rtol=1e-5, atol=1e-6)
    assert objectives[0] == pytest.approx(16.0, rel=1e-8)


def test_an_unavailable_linear_solver_is_refused(tmp_path):
    """HSL's MA27 is a name IPOPT knows but whose library this CasADi build lacks (checked by
    a probe); were it present, the option would be accepted."""
    from casmbd.ocp.options import linear_solver_available

    if linear_solver_available("ma27"):
        pytest.skip("HSL is installed here")
    path = write_scene(tmp_path, options_table({"ipopt.linear_solver": "ma27"}))
    with pytest.raises(SceneError, match=r"'ipopt\.linear_solver' = 'ma27': (this linear "
                                         r"solver is not available|IPOPT loads 'ma27' from "
                                         r"the shared library libhsl\.so)"):
        load_ocp(path)


@pytest.mark.parametrize("solver", ["../../../tmp/evil", "knitro", "qpoases", "IPOPT", 7])
def test_unknown_solver_names_are_refused(tmp_path, solver):
    """A solver name is a plugin library CasADi would look for and load."""
    path = write_scene(tmp_path, f"solver = {toml_value(solver)}")
    with pytest.raises(SceneError, match=rf"\[ocp\] key 'solver': unknown NLP solver "
                                         rf"{re.escape(repr(solver))} \(allowed: ipopt, "
                                         r"sqpmethod\)"):
        load_ocp(path)


def test_allowed_options_reach_the_solver(tmp_path):
    """An allowed option is passed on: max_iter = 0 stops IPOPT at its (infeasible) start;
    without it the problem solves."""
    options = {"ipopt.max_iter": 0, "ipopt.tol": 1e-10, "ipopt.mu_strategy": "adaptive"}
    ocp = load_ocp(write_scene(tmp_path, options_table(options)))
    assert ocp.solver_options == options
    ocp.compile = False
    sol = ocp.solve(raise_on_failure=False)
    assert sol.stats["iterations"] == 0
    assert sol.stats["return_status"] == "Maximum_Iterations_Exceeded"


def test_every_allowed_option_is_accepted_by_its_solver():
    """The allow-list holds no name CasADi/IPOPT would reject (one value per option)."""
    sample = {"int": lambda spec: spec[1] + 1 if spec[1] + 1 <= spec[2] else spec[1],
              "real": lambda spec: min(0.25, spec[2]) if spec[1] >= 0 else 1.0,
              "choice": lambda spec: spec[1][0], "bool": lambda spec: False,
              "linear_solver": lambda spec: "mumps"}
    x = ca.SX.sym("x")
    for solver, table in SOLVER_OPTIONS.items():
        opts = {k: sample[spec[0]](spec) for k, spec in table.items()}
        if solver == "ipopt":
            opts.update({"ipopt.print_level": 0, "ipopt.derivative_test": "none",
                         "ipopt.mu_min": 1e-11, "ipopt.mu_max": 1e5})
        else:
            opts.update({"print_header": False, "print_iteration": False,
                         "print_status": False})
        ca.nlpsol("check", solver, {"x": x, "f": (x - 1) ** 2}, opts)  # raises if unknown


def test_python_api_options_are_checked_too(tmp_path):
    """Ocp(solver_options=...) and a later assignment to the attribute go through the same
    allow-list (AnalysisError naming the key); the file IPOPT would write is not written."""
    mech = load_scene(write_scene(tmp_path))
    with pytest.raises(AnalysisError, match="solver option 'jit' is not allowed"):
        Ocp(mech, intervals=2, solver_options={"jit": True})
    with pytest.raises(AnalysisError, match="unknown NLP solver 'knitro'"):
        Ocp(mech, intervals=2, solver="knitro")
    target = tmp_path / "ipopt.out"
    ocp = Ocp(mech, horizon=1.0, intervals=2, degree=2, compile=False)
    ocp.initial(slide=0.0, slide_dot=0.0).final(slide=1.0, slide_dot=0.0).minimize("effort")
    ocp.solver_options = {"ipopt.output_file": str(target)}
    with pytest.raises(AnalysisError, match=r"solver option 'ipopt\.output_file' is not allowed"):
        ocp.solve()
    assert not target.exists()


def test_cli_ocp_refuses_the_payload_with_one_error_line(tmp_path, capsys):
    marker = tmp_path / "marker"
    path = write_scene(tmp_path, options_table(jit_options(marker)))
    code = cli.main(["ocp", str(path), "--out", str(tmp_path / "sol.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0
    assert len(err) == 1 and err[0].startswith("error: ")
    assert "solver option 'jit' is not allowed" in err[0]
    assert not marker.exists()
    assert not (tmp_path / "sol.npz").exists()


# ----------------------------------------------------------------- expressions
PAYLOADS = [
    ("__import__('os').system('touch {marker}')", "__import__"),
    ("().__class__.__bases__[0].__subclasses__()", "__class__"),
    ("t.__class__", "__class__"),
    ("(lambda: 0)()", "lambda"),
    ("__builtins__", "__builtins__"),
    ("open('{marker}', 'w')", "open"),
    ("eval('1')", "eval"),
    ("exec('x = 1')", "exec"),
    ("[x for x in (1, 2)]", "for"),
    ("sin.__globals__", "__globals__"),
    ("getattr(t, 'real')", "getattr"),
    ("f'{{t}}'", "f'"),
    ("sin(t, x=1)", "sin(t, x=1)"),
    ("t if 1 else 2", "if"),
    ("(t := 1)", ":="),
]


@pytest.mark.parametrize("text, culprit", PAYLOADS)
def test_expression_payloads_are_refused(tmp_path, text, culprit):
    marker = tmp_path / "marker"
    text = text.format(marker=marker)
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, {"t": ca.SX.sym("t")}, where="[[drivers]] 'd' key 'position'")
    message = str(info.value)
    assert message.startswith("[[drivers]] 'd' key 'position'")
    assert culprit in message
    assert not marker.exists()


@pytest.mark.parametrize("text, why", [
    ("1+" * 6000 + "1", "too long"),
    ("(" * 500 + "1" + ")" * 500, "too deeply nested"),
    ("-" * 5000 + "1", "too deeply nested"),
    ("sin(" * 200 + "1" + ")" * 200, "too deeply nested"),
    ("9" * 400 + ".0**9" * 50, "too long|not finite|cannot evaluate|too deeply"),
])
def test_pathological_expressions_are_refused(text, why):
    with pytest.raises(ExpressionError, match=why):
        parse_expression(text, {"t": ca.SX.sym("t")}, where="expr")


def test_expression_payload_in_a_scene_names_body_and_key(tmp_path):
    marker = tmp_path / "marker"
    path = write_scene(tmp_path, mass=toml_value(f"__import__('os').system('touch {marker}')"))
    with pytest.raises(SceneError, match=r"'block'.*'mass'.*__import__"):
        load_scene(path)
    assert not marker.exists()


def test_expression_payload_in_an_ocp_expression(tmp_path):
    marker = tmp_path / "marker"
    path = write_scene(tmp_path, "mayer = " + toml_value(f"open('{marker}', 'w')"))
    with pytest.raises(CasmbdError, match="open"):
        load_ocp(path).solve()
    assert not marker.exists()


# ----------------------------------------------------------------- names used in file names
@pytest.mark.parametrize("name", ["../../escaped/x", "a/b\\\\c", ".hidden", "x; touch y"])
def test_scene_names_never_leave_the_cache_directory(tmp_path, monkeypatch, name):
    """The scene name prefixes the cached library's file name and C symbols; path separators,
    dots and shell characters are replaced, so every file stays in the cache directory."""
    if codegen.find_compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CASMBD_COMPILE", "1")
    cache = tmp_path / "cache"
    mech = load_scene(write_scene(tmp_path, name=name))
    model = NumericModel(mech, "kinematics", mode="compiled")
    library = pathlib.Path(model.report.library)
    assert library.parent == cache
    assert re.fullmatch(r"casmbd_[A-Za-z0-9_]+_[0-9a-f]{16}\.so", library.name)
    outside = {p for p in tmp_path.rglob("*") if cache not in p.parents and p != cache}
    assert outside == {tmp_path / "scene.toml"}


@pytest.mark.parametrize("name", ["../x", "a/b", "x.so", "", "x y"])
def test_library_names_must_be_c_identifiers(name):
    x = ca.SX.sym("x")
    with pytest.raises(ValueError, match="C identifier"):
        codegen.compile_functions([ca.Function("f", [x], [x])], name, mode="compiled")
    with pytest.raises(ValueError, match="C identifier"):
        codegen.compile_nlp_solver({"x": x, "f": x * x, "g": x}, "ipopt", {}, name=name)


# ----------------------------------------------------------------- result files
class _Payload:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        import os

        return (os.system, (f"touch {self.marker}",))


def test_a_result_file_with_a_pickled_object_is_not_unpickled(tmp_path):
    """np.load runs with allow_pickle=False: an object array in a result file (whose
    unpickling would run a shell command) is an error naming the file."""
    from casmbd.results import load

    marker = tmp_path / "marker"
    path = tmp_path / "evil.npz"
    np.savez(path, meta=np.array([_Payload(marker)], dtype=object), t=np.zeros(2))
    with pytest.raises(AnalysisError, match=re.escape(str(path))):
        load(path)
    assert not marker.exists()


def test_no_code_from_data_in_the_sources():
    """No np.load with allow_pickle=True, eval, exec, marshal or unpickling of files anywhere
    in casmbd; the only pickle.loads is the sweep's of bytes its own parent process made."""
    hits = []
    pattern = re.compile(r"allow_pickle\s*=\s*True|(?<!def )\beval\(|\bexec\(|\bmarshal\b|"
                         r"pickle\.loads?\(|\bImporter\(|os\.system|shell\s*=\s*True")
    for path in sorted((ROOT / "casmbd").rglob("*.py")):
        for number, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#", 1)[0]
            if pattern.search(code):
                hits.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert len(hits) == 1, hits
    assert hits[0].startswith("casmbd/analysis/studies/sweep.py:"), hits
    assert hits[0].endswith('mech = pickle.loads(spec["mechanism"])'), hits


def test_bench_never_runs_a_benchmarks_folder_of_the_current_directory(tmp_path, monkeypatch):
    """``casmbd bench`` runs the suite of the checkout holding the running casmbd only: a
    ``benchmarks/`` folder in a downloaded working directory is not imported or run."""
    import subprocess

    evil = tmp_path / "benchmarks"
    evil.mkdir()
    marker = tmp_path / "marker"
    (evil / "__init__.py").write_text("")
    (evil / "__main__.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    seen = {}

    def fake_run(cmd, cwd=None, **kwargs):
        seen["cwd"] = pathlib.Path(cwd).resolve()
        return subprocess.CompletedProcess(cmd, 0, '{"ok": true}\n', "")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(subprocess, "run", fake_run)
    assert cli.main(["bench", "--quick", "--json"]) == 0
    assert seen["cwd"] == pathlib.Path(cli.__file__).resolve().parents[2]  # casmbd/cli/__init__.py
    assert seen["cwd"] != tmp_path.resolve()
    assert not marker.exists()
