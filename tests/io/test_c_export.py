"""``casmbd export`` / :func:`casmbd.export_c` (issue 38 items 3 and 4): the exported C99 is
compiled here with the system's ``cc -std=c99 -Wall -Wextra -Werror -pedantic`` and called
through ctypes at random states; it must agree with the Python API
(``casmbd.compile(mechanism)``) to 1e-13 relative (max-norm of the difference over the
max-norm of the reference) for every function, on a UR-type arm (tree: Featherstone's
recursions) and on a four-bar (closed chain: KKT forward dynamics, least-norm and actuated
inverse dynamics).  Also: ``main.c`` builds and prints the Python API's τ; a second export
is byte-identical; the sources include nothing beyond the C standard library and libm and
the library holds no writable global; bad input is named."""

from __future__ import annotations

import ctypes
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import casmbd
from casmbd import cli
from casmbd.analysis.identification.regressor import joint_torque_regressor
from casmbd.errors import AnalysisError, ModelError
from casmbd.io.c_export import export_c
from casmbd.system import System

ROOT = Path(__file__).resolve().parents[2]
UR = ROOT / "tests" / "scenes" / "ur_like.toml"
FOUR_BAR = ROOT / "examples" / "four_bar.toml"
CC = shutil.which("cc")
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2"]
TOL = 1e-13

needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler 'cc' on PATH")


def _rel(x, ref) -> float:
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    assert x.shape == ref.shape, (x.shape, ref.shape)
    return float(np.max(np.abs(x - ref)) / max(np.max(np.abs(ref)), 1e-300))


def _four_bar():
    """examples/four_bar.toml without its crank driver: 3 joint coordinates, the 2
    loop-closure equations of joint C, one degree of freedom."""
    mech = casmbd.load_scene(FOUR_BAR)
    mech.drivers.clear()
    return mech


class Library:
    """The exported C of ``directory`` compiled into a shared library, called via ctypes."""

    def __init__(self, directory: Path, prefix: str, nv: int, dim: int):
        lib = directory / f"lib{prefix}.so"
        subprocess.run([CC, *CFLAGS, "-shared", "-fPIC", f"{prefix}.c", f"{prefix}_model.c",
                        "-lm", "-o", lib.name], cwd=directory, check=True,
                       capture_output=True, text=True)
        self.lib, self.prefix, self.nv, self.dim = ctypes.CDLL(str(lib)), prefix, nv, dim
        self.fn("work_bytes").restype = ctypes.c_size_t
        self.work = ctypes.create_string_buffer(self.fn("work_bytes")())

    def fn(self, name):
        return getattr(self.lib, f"{self.prefix}_{name}")

    def call(self, name, *args, outs=(), extra=()):
        arrays = [np.ascontiguousarray(a, dtype=float) for a in args]
        results = [np.full(n, np.nan) for n in outs]
        ptr = [a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in arrays + results]
        rc = self.fn(name)(*ptr[:len(arrays)], *extra, *ptr[len(arrays):], self.work)
        return rc, results


@pytest.fixture(scope="module")
def ur(tmp_path_factory):
    mech = casmbd.load_scene(UR)
    out = tmp_path_factory.mktemp("ur") / "c"
    report = export_c(mech, out, cmake=True)
    model = casmbd.compile(mech)
    return mech, report, model, Library(out, report.prefix, report.nv, 3) if CC else None


@pytest.fixture(scope="module")
def four_bar(tmp_path_factory):
    mech = _four_bar()
    out = tmp_path_factory.mktemp("four_bar") / "c"
    report = export_c(mech, out, prefix="fb")
    numeric = casmbd.NumericModel(System(_four_bar(), coordinates="joint"), "dynamics",
                                  mode="vm")
    return mech, report, casmbd.compile(mech), numeric, (
        Library(out, "fb", report.nv, 2) if CC else None)


@needs_cc
def test_ur_arm_every_function_agrees_with_the_python_api(ur):
    """inverse/forward dynamics, M, b, frame placements and every frame Jacobian at 6 random
    states of the UR-type arm: 1e-13 relative (measured: bit for bit)."""
    _, report, model, lib = ur
    nv, nf = report.nv, len(report.frame_names)
    rng = np.random.default_rng(38)
    for _ in range(6):
        q, v = rng.uniform(-np.pi, np.pi, nv), rng.uniform(-2.0, 2.0, nv)
        tau, acc = rng.uniform(-20.0, 20.0, nv), rng.uniform(-5.0, 5.0, nv)
        rc, (out,) = lib.call("inverse_dynamics", q, v, acc, outs=[nv])
        assert rc == 0 and _rel(out, model.inverse_dynamics(q, v, acc)) <= TOL
        rc, (out,) = lib.call("forward_dynamics", q, v, tau, outs=[nv])
        assert rc == 0 and _rel(out, model.forward_dynamics(q, v, tau)) <= TOL
        rc, (out,) = lib.call("mass_matrix", q, outs=[nv * nv])
        assert rc == 0 and _rel(out.reshape(nv, nv), model.mass_matrix(q)) <= TOL
        rc, (out,) = lib.call("bias_forces", q, v, outs=[nv])
        assert rc == 0 and _rel(out, model.bias_forces(q, v)) <= TOL
        rc, (pos, rot) = lib.call("forward_kinematics", q, outs=[3 * nf, 9 * nf])
        ref_pos, ref_rot = model.forward_kinematics(q)
        assert rc == 0 and _rel(pos.reshape(nf, 3), ref_pos) <= TOL
        assert _rel(rot.reshape(nf, 3, 3), ref_rot) <= TOL
        for k, frame in enumerate(report.frame_names):
            rc, (jac,) = lib.call("jacobian", q, outs=[6 * nv], extra=[ctypes.c_int(k)])
            assert rc == 0 and _rel(jac.reshape(6, nv), model.jacobian(q, frame)) <= TOL


@needs_cc
def test_ur_arm_return_codes(ur):
    """NULL pointers and a frame out of range: ERR_ARGUMENT (1); a NaN input:
    ERR_NOT_FINITE (2); frame names found by name; the codes' texts."""
    _, report, _, lib = ur
    nv = report.nv
    z = np.zeros(nv)
    tau = np.zeros(nv)
    dp = tau.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
    assert lib.fn("inverse_dynamics")(None, dp, dp, dp, lib.work) == 1
    assert lib.fn("inverse_dynamics")(dp, dp, dp, dp, None) == 1
    for bad in (-1, len(report.frame_names)):
        rc, _ = lib.call("jacobian", z, outs=[6 * nv], extra=[ctypes.c_int(bad)])
        assert rc == 1
    q = z.copy()
    q[1] = np.nan
    assert lib.call("forward_dynamics", q, z, z, outs=[nv])[0] == 2
    lib.fn("frame_index").argtypes = [ctypes.c_char_p]
    assert lib.fn("frame_index")(b"forearm") == report.frame_names.index("forearm")
    assert lib.fn("frame_index")(b"no_such_frame") == -1
    lib.fn("strerror").restype = ctypes.c_char_p
    assert b"NULL pointer" in lib.fn("strerror")(1)


@needs_cc
def test_main_c_builds_and_prints_the_gravity_torques(ur, tmp_path):
    """main.c (and the CMake-free one-line build of the README) prints τ at the design pose
    with v = a = 0 (%.17g: exact), equal to the Python API's to 1e-13."""
    _, report, model, _ = ur
    work = tmp_path / "c"
    shutil.copytree(report.directory, work)
    P = report.prefix
    subprocess.run([CC, *CFLAGS, "main.c", f"{P}.c", f"{P}_model.c", "-lm", "-o", "example"],
                   cwd=work, check=True, capture_output=True, text=True)
    out = subprocess.run([str(work / "example")], check=True, capture_output=True,
                         text=True).stdout.split("\n")
    rows = [line.split() for line in out if line.startswith("tau ")]
    assert [r[2] for r in rows] == report.velocity_names
    tau = np.array([float(r[3]) for r in rows])
    ref = model.inverse_dynamics(np.zeros(6), np.zeros(6), np.zeros(6))
    assert np.max(np.abs(ref)) > 10.0  # gravity holds the stretched arm: not a zero check
    assert _rel(tau, ref) <= TOL


@needs_cc
def test_four_bar_closed_chain_agrees_with_the_python_api(four_bar, tmp_path):
    """Four-bar at 4 assembled states with consistent velocities: the KKT forward dynamics
    and the least-norm inverse dynamics (and its multipliers), and the planar M, b, frame
    placements and Jacobians (a marker among the frames) against ``casmbd.compile``
    (1e-13 relative; measured ≤ 1.1e-14), inconsistent accelerations give
    ERR_INCONSISTENT (3); with the crank actuated (an export of its own) τ is the crank
    torque that drives the forward dynamics."""
    mech, report, model, numeric, lib = four_bar
    assert (report.nq, report.nv, report.nc) == (3, 3, 2)
    rng = np.random.default_rng(4)
    q = casmbd.assemble(numeric, numeric.initial_coordinates(), 0.0).q
    for _ in range(4):
        v = casmbd.velocities(numeric, q, 0.0, v_guess=rng.uniform(-2.0, 2.0, 3))
        tau = rng.uniform(-1.0, 1.0, 3)
        rc, (acc,) = lib.call("forward_dynamics", q, v, tau, outs=[3])
        ref = model.forward_dynamics(q, v, tau)
        assert rc == 0 and _rel(acc, ref) <= TOL
        rc, (eff,) = lib.call("inverse_dynamics", q, v, ref, outs=[3])
        ref_tau, ref_lam = model.inverse_dynamics(q, v, ref, return_multipliers=True)
        assert rc == 0 and _rel(eff, ref_tau) <= TOL
        assert _rel(_multipliers(lib, report), ref_lam) <= TOL
        assert lib.call("inverse_dynamics", q, v, ref + np.array([1.0, 0.0, 0.0]), outs=[3])[0] == 3
        rc, (m,) = lib.call("mass_matrix", q, outs=[9])
        assert rc == 0 and _rel(m.reshape(3, 3), model.mass_matrix(q)) <= TOL
        rc, (b,) = lib.call("bias_forces", q, v, outs=[3])
        assert rc == 0 and _rel(b, model.bias_forces(q, v)) <= TOL
        nf = len(report.frame_names)  # planar: 2-vectors, 2×2 rotations, 3×n_v Jacobians
        rc, (pos, rot) = lib.call("forward_kinematics", q, outs=[2 * nf, 4 * nf])
        ref_pos, ref_rot = model.forward_kinematics(q)
        assert rc == 0 and _rel(pos.reshape(nf, 2), ref_pos) <= TOL
        assert _rel(rot.reshape(nf, 2, 2), ref_rot) <= TOL
        for k, frame in enumerate(report.frame_names):
            rc, (jac,) = lib.call("jacobian", q, outs=[9], extra=[ctypes.c_int(k)])
            assert rc == 0 and _rel(jac.reshape(3, 3), model.jacobian(q, frame)) <= TOL
        q = casmbd.assemble(numeric, q + rng.uniform(-0.3, 0.3, 3), 0.0).q
    crank = tmp_path / "crank"
    export_c(mech, crank, prefix="fbc", actuated=["A.angle"])
    lib_c = Library(crank, "fbc", 3, 2)
    v = casmbd.velocities(numeric, q, 0.0, v_guess=np.ones(3))
    acc = model.forward_dynamics(q, v, np.array([0.7, 0.0, 0.0]))
    rc, (eff,) = lib_c.call("inverse_dynamics", q, v, acc, outs=[3])
    ref = casmbd.compile(mech, actuated=["A.angle"], mode="vm").inverse_dynamics(q, v, acc)
    assert rc == 0 and _rel(eff, ref) <= TOL and abs(eff[0] - 0.7) < 1e-12
    assert np.all(eff[1:] == 0.0)


@needs_cc
def test_regressor_agrees_with_the_python_api_and_closes_on_the_inverse_dynamics(tmp_path):
    """The exported Y(q, v, a) (row-major n_rows × n_π) against ``joint_torque_regressor``
    (1e-13 relative): the UR-type arm with viscous and Coulomb friction at 4 random states,
    the four-bar (least-norm rows, CasADi's QR in the generated code) at 3 assembled states;
    and Y π with the nominal π equals the exported inverse dynamics (1e-12: an independent
    formulation, Newton–Euler in π against Featherstone's recursion)."""
    rng = np.random.default_rng(12)
    mech = casmbd.load_scene(UR)
    report = export_c(mech, tmp_path / "ur", functions="regressor,inverse_dynamics",
                      friction="viscous,coulomb", prefix="urr")
    reg = joint_torque_regressor(mech, friction=("viscous", "coulomb"), mode="vm")
    assert report.regressor_parameters == reg.names and report.regressor_rows == reg.rows
    npi, ny = len(reg.names), len(reg.rows)
    assert (npi, ny) == (6 * 10 + 2 * 6, 6)
    lib = Library(tmp_path / "ur", "urr", 6, 3)
    nominal = np.array(reg.parameters.values, dtype=float)
    nominal[60:] = 0.0  # the scene has no friction
    for _ in range(4):
        q, v, a = (rng.uniform(-2.0, 2.0, 6) for _ in range(3))
        rc, (y,) = lib.call("regressor", q, v, a, outs=[ny * npi])
        assert rc == 0 and _rel(y.reshape(ny, npi), reg(q, v, a)) <= TOL
        rc, (tau,) = lib.call("inverse_dynamics", q, v, a, outs=[6])
        assert rc == 0 and _rel(y.reshape(ny, npi) @ nominal, tau) <= 1e-12
    mech = _four_bar()
    report = export_c(mech, tmp_path / "fb", functions="regressor", prefix="fbr")
    reg = joint_torque_regressor(mech, mode="vm")
    lib = Library(tmp_path / "fb", "fbr", 3, 2)
    numeric = casmbd.NumericModel(System(_four_bar(), coordinates="joint"), "dynamics",
                                  mode="vm")
    model = casmbd.compile(mech, mode="vm")
    q = casmbd.assemble(numeric, numeric.initial_coordinates(), 0.0).q
    for _ in range(3):
        v = casmbd.velocities(numeric, q, 0.0, v_guess=rng.uniform(-2.0, 2.0, 3))
        a = model.forward_dynamics(q, v, rng.uniform(-1.0, 1.0, 3))
        rc, (y,) = lib.call("regressor", q, v, a, outs=[3 * len(reg.names)])
        assert rc == 0 and _rel(y.reshape(3, -1), reg(q, v, a)) <= TOL
        q = casmbd.assemble(numeric, q + rng.uniform(-0.3, 0.3, 3), 0.0).q


@needs_cc
def test_scene_parameters_as_an_input(tmp_path):
    """``parameters="input"`` (examples/double_pendulum.toml: L and m): after
    ``PREFIX_work_init`` the work struct's p holds the scene's values and the functions equal
    the Python API; with p changed to (L, m) = (1.5, 2.0) they equal the Python API after
    ``set_parameters`` (1e-13): M, τ, q̈ and the frame positions.  A mechanism without
    [parameters] is refused by name."""
    mech = casmbd.load_scene(ROOT / "examples" / "double_pendulum.toml")
    report = export_c(mech, tmp_path / "dp", prefix="dp", parameters="input")
    lib = Library(tmp_path / "dp", "dp", 2, 2)
    model = casmbd.compile(mech, mode="vm")
    names = list(model.numeric.parameter_names)
    assert sorted(names) == ["L", "m"]
    lib.fn("work_init")(lib.work)
    sz = report.sizes
    offset = 8 * (sz["arg"] + sz["res"] + max(1, sz["iw"]) + max(1, sz["w"]))
    p = np.frombuffer(lib.work, dtype=float, count=2, offset=offset)
    assert np.array_equal(p, model.p)
    q, v, x = (np.random.default_rng(5).uniform(-2.0, 2.0, 2) for _ in range(3))
    masses = []
    for values in ({}, {"L": 1.5, "m": 2.0}):
        if values:
            model.numeric.set_parameters(**values)
            p[:] = [values[n] for n in names]
        rc, (m,) = lib.call("mass_matrix", q, outs=[4])
        masses.append(m)
        assert rc == 0 and _rel(m.reshape(2, 2), model.mass_matrix(q)) <= TOL
        rc, (tau,) = lib.call("inverse_dynamics", q, v, x, outs=[2])
        assert rc == 0 and _rel(tau, model.inverse_dynamics(q, v, x)) <= TOL
        rc, (acc,) = lib.call("forward_dynamics", q, v, x, outs=[2])
        assert rc == 0 and _rel(acc, model.forward_dynamics(q, v, x)) <= TOL
        nf = len(report.frame_names)
        rc, (pos, _) = lib.call("forward_kinematics", q, outs=[2 * nf, 4 * nf])
        assert rc == 0 and _rel(pos.reshape(nf, 2), model.forward_kinematics(q)[0]) <= TOL
    assert _rel(masses[1], masses[0]) > 1.0  # m L² scales by 4.5: p is used
    with pytest.raises(ModelError, match="has no \\[parameters\\]"):
        export_c(casmbd.load_scene(UR), tmp_path / "ur", parameters="input")


def _multipliers(lib, report) -> np.ndarray:
    """``w->lambda`` of the work struct: after the 8-byte members arg, res, iw and w."""
    sz = report.sizes
    offset = 8 * (sz["arg"] + sz["res"] + max(1, sz["iw"]) + max(1, sz["w"]))
    return np.frombuffer(lib.work, dtype=float, count=report.nc, offset=offset).copy()


@needs_cc
def test_generated_code_is_self_contained_and_has_no_writable_globals(ur):
    """Only <math.h>, <string.h>, <stddef.h> (and <stdio.h> in main.c) are included; the
    compiled objects define no data or bss symbols (no global state: thread safety)."""
    _, report, _, _ = ur
    allowed = {"<math.h>", "<string.h>", "<stddef.h>", "<stdio.h>",
               f'"{report.prefix}.h"', f'"{report.prefix}_model.h"'}
    for path in report.directory.glob("*.[ch]"):
        includes = {line.split()[1] for line in path.read_text().splitlines()
                    if line.startswith("#include")}
        assert includes <= allowed, (path.name, includes - allowed)
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("no nm to list the symbols")
    # non-PIC objects: const tables in .rodata (R/r), writable data would be B/b/D/d/C/G/S
    subprocess.run([CC, *CFLAGS, "-fno-pic", "-c", f"{report.prefix}.c",
                    f"{report.prefix}_model.c"], cwd=report.directory, check=True,
                   capture_output=True, text=True)
    symbols = subprocess.run([nm, f"{report.prefix}.o", f"{report.prefix}_model.o"],
                             cwd=report.directory, check=True, capture_output=True,
                             text=True).stdout.splitlines()
    kinds = {line.split()[-2] for line in symbols if len(line.split()) == 3}
    assert {"T", "R"} <= kinds or {"T", "r"} <= kinds, kinds
    assert not kinds & set("BbDdCGgSs"), [s for s in symbols if s.split()[-2] in "BbDdCGgSs"]


@needs_cc
def test_jacobian_of_named_frames(ur, tmp_path):
    """``frames=``: the Jacobians of the named frames only, equal to the Python API's
    (1e-13); another frame's index returns ERR_ARGUMENT; main.c
    of a Jacobian-only export prints the first exported frame's J."""
    mech, _, model, _ = ur
    report = export_c(mech, tmp_path / "j", functions="jacobian", prefix="arm",
                      frames=["wrist_3", "upper_arm"])
    lib = Library(tmp_path / "j", "arm", 6, 3)
    q = np.random.default_rng(3).uniform(-2.0, 2.0, 6)
    for k, frame in enumerate(report.frame_names):
        rc, (jac,) = lib.call("jacobian", q, outs=[36], extra=[ctypes.c_int(k)])
        if frame in ("wrist_3", "upper_arm"):
            assert rc == 0 and _rel(jac.reshape(6, 6), model.jacobian(q, frame)) <= TOL
        else:
            assert rc == 1
    subprocess.run([CC, *CFLAGS, "main.c", "arm.c", "arm_model.c", "-lm", "-o", "example"],
                   cwd=tmp_path / "j", check=True, capture_output=True, text=True)
    out = subprocess.run([str(tmp_path / "j" / "example")], check=True, capture_output=True,
                         text=True).stdout.split()
    jac0 = np.array([float(x) for x in out[2::3]])
    q0 = np.zeros(6)
    assert _rel(jac0.reshape(6, 6), model.jacobian(q0, "upper_arm")) <= TOL
    with pytest.raises(ModelError, match="unknown frame 'tool0'"):
        export_c(mech, tmp_path / "k", functions="jacobian", frames=["tool0"])


def test_export_is_byte_identical_and_order_free(tmp_path):
    """Two exports of the same scene (the functions listed in another order), and a third by
    ``python -m casmbd export`` in another process, give the same bytes in every file."""
    mech = casmbd.load_scene(UR)
    a = export_c(mech, tmp_path / "a", functions="inverse_dynamics,mass_matrix,jacobian",
                 cmake=True)
    b = export_c(casmbd.load_scene(UR), tmp_path / "b",
                 functions=["jacobian", "mass_matrix", "inverse_dynamics"], cmake=True)
    # and from another process, through the command line
    subprocess.run([sys.executable, "-m", "casmbd", "export", str(UR), "--c",
                    str(tmp_path / "c"), "--functions", "mass_matrix,jacobian,inverse_dynamics",
                    "--cmake"], check=True, capture_output=True, text=True, cwd=ROOT,
                   timeout=300)
    assert a.files == b.files == sorted(p.name for p in (tmp_path / "c").iterdir())
    for name in a.files:
        first = (tmp_path / "a" / name).read_bytes()
        assert first == (tmp_path / "b" / name).read_bytes(), name
        assert first == (tmp_path / "c" / name).read_bytes(), name


def test_bad_input_is_named(tmp_path):
    """Unknown or repeated function, bad prefix, non-empty directory without force, a
    directory under a file, actuated coordinates of the wrong number."""
    mech = _four_bar()
    with pytest.raises(ModelError, match="unknown function 'mass'"):
        export_c(mech, tmp_path / "x", functions="inverse_dynamics,mass")
    with pytest.raises(ModelError, match="named twice"):
        export_c(mech, tmp_path / "x", functions="jacobian,jacobian")
    with pytest.raises(ModelError, match="prefix '9lives'"):
        export_c(mech, tmp_path / "x", prefix="9lives")
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("mine")
    with pytest.raises(AnalysisError, match=f"directory '{full}' is not empty"):
        export_c(mech, full)
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(AnalysisError, match="cannot write in directory"):
        export_c(mech, blocker / "sub")
    with pytest.raises(ModelError, match="as many actuated coordinates as degrees"):
        export_c(mech, tmp_path / "y", actuated=["A.angle", "B.angle"])
    assert (full / "keep.txt").read_text() == "mine"


def test_cli_export(capsys, tmp_path):
    """``casmbd export SCENE --c DIR --json``: one JSON object naming the files; an unknown
    function and a non-empty directory: exit 1 with one ``error:`` line naming them."""
    out = tmp_path / "c"
    assert cli.main(["export", str(UR), "--c", str(out), "--functions",
                     "inverse_dynamics,forward_dynamics", "--prefix", "arm", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["files"] == ["README.md", "arm.c", "arm.h", "arm_model.c", "arm_model.h",
                             "main.c"]
    assert data["functions"] == ["inverse_dynamics", "forward_dynamics"]
    assert (data["nq"], data["nv"], data["nc"]) == (6, 6, 0)
    assert sorted(p.name for p in out.iterdir()) == data["files"]
    assert cli.main(["export", str(UR), "--c", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not empty" in err[0] and "--force" in err[0]
    assert cli.main(["export", str(UR), "--c", str(tmp_path / "d"), "--functions",
                     "inverse_dynamics,rnea"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown function 'rnea'" in err[0]
