"""Bad input, category "cache" (issue 18, items 2 and 7): a cache that cannot lie.

A cached library that was changed (bytes flipped), replaced by another model's library (with or
without that model's record), truncated, or left without its hash record is detected before it
is opened, reported with a RuntimeWarning, rebuilt and never used; the numbers then equal
those of the CasADi virtual machine (CASMBD_COMPILE=0) to 1e-12.  A truncated library is
loaded in a child process to prove it no longer crashes it (SIGBUS).  A read-only cache
directory, or a cache path that is a file, falls back to a private temporary cache with one
warning.  Two processes compiling the same model at once both succeed with identical numbers.
The OCP's compiled NLP library is checked the same way.  A model record (``*.model.json``) and
a modal data file (``modes_*.npz``) are verified as a whole by their content hash: one changed
number and the entry is not used (a warning for the model record, a rebuild), never
half-trusted (issue 31 item 5: a tampered record was used, its results off by 226).

The first build of each case runs in a child process, so that the library this process opens
later is the rebuilt file (a process that has a library open keeps using its copy).
"""

from __future__ import annotations

import errno
import json
import os
import pathlib
import stat
import subprocess
import sys
import tempfile
import warnings

import casadi as ca
import numpy as np
import pytest
from conftest import private_cache

from casmbd import cli
from casmbd.analysis.dynamics.simulate import Simulator, simulate
from casmbd.compiled import cache, codegen, modal_cache, modelkey
from casmbd.errors import CompileError
from casmbd.io.scene import load_scene
from casmbd.model import flexible_bodies
from casmbd.model.fe_beam import beam_model

TESTS = pathlib.Path(__file__).resolve().parents[1]
HERE = pathlib.Path(__file__).resolve().parent
ROOT = TESTS.parent
SCENE = TESTS / "scenes" / "spring_mass.toml"
NAME = "badcache"

pytestmark = pytest.mark.skipif(codegen.find_compiler() is None, reason="no C compiler")


def tiny_functions(variant: int = 0) -> list[ca.Function]:
    """Two small functions; ``variant`` 1 changes the numbers (same signatures), ``variant``
    2 the structure (another output sparsity)."""
    q = ca.SX.sym("q", 3)
    scale = 2.0 if variant == 1 else 1.0
    mass = ca.diag(ca.vertcat(1 + q[0] ** 2, 2 + scale * ca.cos(q[1]), 3 + q[2]))
    if variant == 2:
        mass[0, 1] = mass[1, 0] = q[2]
    rhs = ca.vertcat(ca.sin(q[0]) * q[1], scale * q[2] ** 3, ca.exp(-q[0]))
    return [ca.Function("mass", [q], [mass], ["q"], ["M"]),
            ca.Function("rhs", [q], [rhs, ca.sumsqr(q)], ["q"], ["f", "e"])]


def values(functions: dict[str, ca.Function]) -> list[float]:
    """All outputs at two fixed arguments, as one list of floats."""
    out: list[float] = []
    for q in ([0.3, -0.7, 0.2], [1.1, 0.4, -0.9]):
        for name in sorted(functions):
            for res in functions[name](q) if functions[name].n_out() > 1 else \
                    [functions[name](q)]:
                out += np.asarray(ca.DM(res).nonzeros(), float).tolist()
    return out


def vm_values(variant: int = 0) -> list[float]:
    return values({f.name(): f for f in tiny_functions(variant)})


def child(code: str, cache_dir: pathlib.Path, check: bool = True) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter with the cache at ``cache_dir``."""
    head = (f"import sys, json, warnings\nsys.path[:0] = [{str(ROOT)!r}, {str(TESTS)!r}, "
            f"{str(HERE)!r}]\n"
            "from casmbd.compiled import codegen\n"
            "from test_bad_input_cache import tiny_functions, values, NAME\n")
    env = {**os.environ, "CASMBD_CACHE_DIR": str(cache_dir), "CASMBD_PROGRESS": "0"}
    env.pop("CASMBD_COMPILE", None)
    proc = subprocess.run([sys.executable, "-c", head + code], capture_output=True, text=True,
                          env=env, cwd=str(ROOT), timeout=600, check=False)
    if check:
        assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


BUILD = ("funs, rep = codegen.compile_functions(tiny_functions({variant}), NAME, "
         "mode='compiled')\nprint(json.dumps({{'library': rep.library, 'hit': rep.cache_hit, "
         "'values': values(funs)}}))\n")


def prebuild(cache_dir: pathlib.Path, variant: int = 0) -> pathlib.Path:
    """Build the library of ``tiny_functions(variant)`` in a child process; its path."""
    out = json.loads(child(BUILD.format(variant=variant), cache_dir).stdout.splitlines()[-1])
    return pathlib.Path(out["library"])


def replace_bytes(path: pathlib.Path, data: bytes) -> None:
    """Put ``data`` at ``path`` as a new file (as a writer of the cache would)."""
    tmp = path.with_name(path.name + ".new")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def build_here(variant: int = 0, mode: str = "compiled"):
    """compile_functions in this process, returning (functions, report, warnings)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        funs, rep = codegen.compile_functions(tiny_functions(variant), NAME, mode=mode)
    return funs, rep, [str(w.message) for w in caught if w.category is RuntimeWarning]


_env = private_cache(CASMBD_COMPILE=None, CASMBD_CFLAGS=None, CASMBD_PROGRESS="0")


def assert_rebuilt(rep, messages, library: pathlib.Path, why: str, variant: int = 0,
                   funs=None) -> None:
    assert rep.mode == "compiled" and rep.compiled and not rep.cache_hit
    assert rep.library == str(library)
    assert len(messages) == 1, messages
    assert str(library) in messages[0] and "is not used" in messages[0]
    assert why in messages[0], messages[0]
    np.testing.assert_allclose(values(funs), vm_values(variant), rtol=0, atol=1e-12)
    assert cache.check_entry(library, rep.key, cache.signatures(tiny_functions(variant))) is None


# ----------------------------------------------------------------- tampered entries
def test_flipped_bytes_are_detected_and_rebuilt(tmp_path):
    library = prebuild(tmp_path / "cache")
    data = bytearray(library.read_bytes())
    for i in range(len(data) // 2, len(data) // 2 + 64):
        data[i] ^= 0xFF
    replace_bytes(library, bytes(data))
    funs, rep, messages = build_here()
    assert_rebuilt(rep, messages, library, "SHA-256 differs", funs=funs)


def test_another_models_library_is_detected_and_rebuilt(tmp_path):
    """Model B's library (same function names and signatures, other numbers) copied over A's:
    without the check, A would silently get B's numbers."""
    cache_dir = tmp_path / "cache"
    lib_a, lib_b = prebuild(cache_dir, 0), prebuild(cache_dir, 1)
    assert lib_a != lib_b
    assert np.max(np.abs(np.subtract(vm_values(0), vm_values(1)))) > 0.1
    replace_bytes(lib_a, lib_b.read_bytes())
    funs, rep, messages = build_here(0)
    assert_rebuilt(rep, messages, lib_a, "SHA-256 differs", funs=funs)


def test_another_models_library_with_its_record_is_detected(tmp_path):
    cache_dir = tmp_path / "cache"
    lib_a, lib_b = prebuild(cache_dir, 0), prebuild(cache_dir, 1)
    replace_bytes(lib_a, lib_b.read_bytes())
    replace_bytes(cache.record_path(lib_a), cache.record_path(lib_b).read_bytes())
    funs, rep, messages = build_here(0)
    assert_rebuilt(rep, messages, lib_a, "record is for another build", funs=funs)


def test_a_record_with_other_signatures_is_detected(tmp_path):
    library = prebuild(tmp_path / "cache")
    record_file = cache.record_path(library)
    record = json.loads(record_file.read_text())
    record["functions"]["mass"]["out"][0][2] += 1  # one more nonzero than the model has
    record_file.write_text(json.dumps(record))
    funs, rep, messages = build_here()
    assert_rebuilt(rep, messages, library, "function 'mass' differs in out", funs=funs)


def test_a_forged_record_is_caught_by_the_signatures_after_loading(tmp_path):
    """A record that vouches for another model's library (key, hash and the expected
    signatures all forged) passes the checks before loading; the loaded functions' sparsity
    gives it away and the entry is rebuilt (run in a child: it opens the forged library)."""
    cache_dir = tmp_path / "cache"
    lib_a, lib_c = prebuild(cache_dir, 0), prebuild(cache_dir, 2)
    record = json.loads(cache.record_path(lib_a).read_text())
    replace_bytes(lib_a, lib_c.read_bytes())
    record.update(sha256=cache.file_sha256(lib_a), size=lib_a.stat().st_size)
    cache.record_path(lib_a).write_text(json.dumps(record))
    proc = child("with warnings.catch_warnings(record=True) as w:\n"
                 "    warnings.simplefilter('always')\n"
                 "    funs, rep = codegen.compile_functions(tiny_functions(0), NAME, "
                 "mode='auto')\n"
                 "print(json.dumps({'mode': rep.mode, 'values': values(funs), "
                 "'warnings': [str(x.message) for x in w]}))\n", cache_dir)
    out = json.loads(proc.stdout.splitlines()[-1])
    assert any("it loads other functions: function 'mass' differs in out" in m
               for m in out["warnings"]), out["warnings"]
    # rebuilt (a process holding the forged copy open falls back to the VM): right numbers
    np.testing.assert_allclose(out["values"], vm_values(0), rtol=0, atol=1e-12)
    out2 = json.loads(child(BUILD.format(variant=0), cache_dir).stdout.splitlines()[-1])
    assert out2["hit"] is True
    np.testing.assert_allclose(out2["values"], vm_values(0), rtol=0, atol=1e-12)


def test_a_missing_record_means_rebuilt(tmp_path):
    library = prebuild(tmp_path / "cache")
    cache.record_path(library).unlink()
    funs, rep, messages = build_here()
    assert_rebuilt(rep, messages, library, "no hash record", funs=funs)


def test_a_truncated_library_does_not_crash_and_is_rebuilt(tmp_path):
    """Before: dlopen of the truncated file ended every later run with SIGBUS."""
    cache_dir = tmp_path / "cache"
    library = prebuild(cache_dir)
    replace_bytes(library, library.read_bytes()[:1000])
    proc = child(BUILD.format(variant=0), cache_dir, check=False)
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-2000:])  # -7 was SIGBUS
    assert "is not used (it is 1000 bytes, its record says" in proc.stderr
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out["hit"] is False
    np.testing.assert_allclose(out["values"], vm_values(0), rtol=0, atol=1e-12)
    assert library.stat().st_size > 1000


# ----------------------------------------------------------------- unusable cache directories
def _read_only_dir(tmp_path) -> pathlib.Path:
    if os.geteuid() != 0:
        path = tmp_path / "readonly"
        path.mkdir()
        path.chmod(stat.S_IRUSR | stat.S_IXUSR)
        return path
    # root writes through permission bits: use a read-only file system if there is one
    for candidate in ("/sys/kernel", "/sys"):
        if cache._unusable(pathlib.Path(candidate)) is not None and pathlib.Path(candidate
                                                                                 ).is_dir():
            return pathlib.Path(candidate)
    pytest.skip("running as root without a read-only directory")


@pytest.mark.parametrize("kind", ["read-only", "file", "below a file"])
def test_an_unusable_cache_directory_falls_back_to_a_private_one(tmp_path, monkeypatch, kind):
    if kind == "read-only":
        configured, why = _read_only_dir(tmp_path), "it is not writable"
    elif kind == "file":
        configured, why = tmp_path / "cachefile", "it exists and is not a directory"
        configured.write_text("not a directory")
    else:
        (tmp_path / "cachefile").write_text("not a directory")
        configured, why = tmp_path / "cachefile" / "sub", "it cannot be created"
    monkeypatch.setenv("CASMBD_CACHE_DIR", str(configured))
    monkeypatch.setattr(cache, "_FALLBACK", {})
    funs, rep, messages = build_here(mode="compiled")
    assert len(messages) == 1, messages
    assert str(configured) in messages[0] and why in messages[0]
    fallback = pathlib.Path(rep.library).parent
    assert fallback.is_relative_to(pathlib.Path(tempfile.gettempdir()))
    assert str(fallback) in messages[0]
    assert rep.mode == "compiled" and rep.compiled
    np.testing.assert_allclose(values(funs), vm_values(0), rtol=0, atol=1e-12)
    # once per process: the second build hits the private cache without a second warning
    funs, rep2, messages = build_here(mode="compiled")
    assert messages == [] and rep2.cache_hit and rep2.library == rep.library
    if kind != "read-only":
        assert (tmp_path / "cachefile").read_text() == "not a directory"


# ----------------------------------------------------------------- concurrent builds
def test_two_processes_compiling_the_same_scene_at_once(tmp_path):
    """Both succeed with identical numbers (equal to the VM's to 1e-12), no process sees a
    half-written library (no rebuild warning) and nothing temporary is left behind."""
    cache_dir = tmp_path / "cache"
    code = (f"import sys, json\nsys.path[:0] = [{str(ROOT)!r}]\n"
            "import numpy as np\nimport casmbd\n"
            "from casmbd.compiled.model import NumericModel\n"
            f"mech = casmbd.load_scene({str(SCENE)!r})\n"
            "model = NumericModel(mech, 'dynamics', mode=sys.argv[1])\n"
            "out = {}\n"
            "for name, f in sorted(model.functions.items()):\n"
            "    args = [np.linspace(0.1, 0.9, f.nnz_in(i)) for i in range(f.n_in())]\n"
            "    out[name] = [np.asarray(r).ravel().tolist() for r in f.call(args)]\n"
            "print(json.dumps({'values': out, 'compiled': model.report.compiled,"
            " 'mode': model.report.mode}))\n")
    env = {**os.environ, "CASMBD_CACHE_DIR": str(cache_dir), "CASMBD_PROGRESS": "0"}
    env.pop("CASMBD_COMPILE", None)
    procs = [subprocess.Popen([sys.executable, "-c", code, "compiled"], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              cwd=str(ROOT)) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    for proc, (_, err) in zip(procs, outs):
        assert proc.returncode == 0, err[-2000:]
        assert "is not used" not in err
    first, second = (json.loads(o.splitlines()[-1]) for o, _ in outs)
    assert first["mode"] == second["mode"] == "compiled"
    assert first["values"] == second["values"]
    vm = json.loads(subprocess.run([sys.executable, "-c", code, "vm"], env=env, text=True,
                                   capture_output=True, cwd=str(ROOT), timeout=600,
                                   check=True).stdout.splitlines()[-1])
    for name, outputs in vm["values"].items():
        for got, want in zip(first["values"][name], outputs):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert not [p for p in cache_dir.iterdir() if p.name.endswith(".tmp")]
    for library in cache_dir.glob("*.so"):
        assert cache.record_path(library).is_file()
        assert json.loads(cache.record_path(library).read_text())["sha256"] == \
            cache.file_sha256(library)


# ----------------------------------------------------------------- the OCP's NLP library
NLP = ("import casadi as ca\n"
       "x = ca.MX.sym('x', 2)\n"
       "problem = {'x': x, 'f': (x[0] - 1) ** 2 + (x[1] - 2) ** 2 + x[0] ** 4, "
       "'g': x[0] + x[1]}\n"
       "opts = {'ipopt.print_level': 0, 'print_time': False, 'ipopt.sb': 'yes'}\n")
SOLVE = ("solver, rep = codegen.compile_nlp_solver(problem, 'ipopt', opts, 'badcache_nlp')\n"
         "sol = solver(x0=[0, 0], lbg=1, ubg=1)\n"
         "print(json.dumps({'library': rep.library, 'mode': rep.mode, 'hit': rep.cache_hit,"
         " 'x': [float(v) for v in sol['x'].nonzeros()]}))\n")


def nlp_child(cache_dir: pathlib.Path, vm: bool = False, check: bool = True):
    code = ("import os\n" + ("os.environ['CASMBD_COMPILE'] = '0'\n" if vm else "")
            + NLP + SOLVE)
    proc = child(code, cache_dir, check=check)
    return proc, (json.loads(proc.stdout.splitlines()[-1]) if proc.returncode == 0 else None)


@pytest.mark.parametrize("damage", ["flipped", "truncated", "no record"])
def test_the_nlp_library_is_checked_and_rebuilt(tmp_path, damage):
    """compile_nlp_solver's library (never checked before): damaged -> RuntimeWarning,
    rebuilt, and the solution equals the virtual machine's to 1e-12."""
    cache_dir = tmp_path / "cache"
    _, first = nlp_child(cache_dir)
    library = pathlib.Path(first["library"])
    assert first["mode"] == "compiled" and not first["hit"]
    data = library.read_bytes()
    if damage == "flipped":
        replace_bytes(library, data[: len(data) // 2] + bytes(b ^ 0xFF for b in
                                                             data[len(data) // 2:][:64])
                      + data[len(data) // 2 + 64:])
        why = "its SHA-256 differs"
    elif damage == "truncated":
        replace_bytes(library, data[:2000])
        why = "it is 2000 bytes"
    else:
        cache.record_path(library).unlink()
        why = "no hash record"
    proc, second = nlp_child(cache_dir, check=False)
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-2000:])
    assert f"{library} is not used ({why}" in proc.stderr, proc.stderr[-2000:]
    assert second["mode"] == "compiled" and not second["hit"]
    _, vm = nlp_child(cache_dir, vm=True)
    np.testing.assert_allclose(second["x"], vm["x"], rtol=0, atol=1e-12)
    _, third = nlp_child(cache_dir)
    assert third["hit"]


def test_an_nlp_record_of_other_sizes_is_refused(tmp_path):
    cache_dir = tmp_path / "cache"
    _, first = nlp_child(cache_dir)
    library = pathlib.Path(first["library"])
    record = json.loads(cache.record_path(library).read_text())
    record["nlp"] = [3, 1]
    cache.record_path(library).write_text(json.dumps(record))
    proc, second = nlp_child(cache_dir)
    assert "its record is for an NLP of sizes [3, 1], not [2, 1]" in proc.stderr
    assert not second["hit"]


def test_a_compiled_mode_store_failure_is_a_compile_error(tmp_path, monkeypatch):
    """A library that cannot be stored (its path is a directory) is a CompileError naming it
    in mode="compiled", never an internal error."""
    cache_dir = tmp_path / "cache"
    library = prebuild(cache_dir)
    library.unlink()
    cache.record_path(library).unlink()
    library.mkdir()
    (library / "keep").write_text("x")
    with pytest.raises(CompileError, match=str(library)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            codegen.compile_functions(tiny_functions(0), NAME, mode="compiled")


# ----------------------------------------------------------------- records verified as a whole
def spring_run(expect_warning: str | None = None):
    """``spring_mass.toml`` simulated in compiled mode: (result, simulator, warnings)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim = Simulator(load_scene(SCENE), mode="compiled")
        res = sim.run(1.0, 20, rtol=1e-10, atol=1e-12)
    messages = [str(w.message) for w in caught if w.category is RuntimeWarning]
    return res, sim, messages


@pytest.mark.parametrize("field", ["q0", "p"])
def test_a_tampered_model_record_is_rebuilt_not_used(_env, field):
    """One number of the record's metadata changed (the start position, the parameter
    defaults), the file otherwise valid JSON of the right format and key: before, the record
    was a hit and the run started from the tampered value.  Now its content hash differs, it
    is reported and rebuilt, and the run equals the untampered one to 1e-12."""
    first, sim, messages = spring_run()
    assert messages == [] and not sim.model.report.cache_hit
    record_file = next(_env.glob("*.model.json"))
    good = json.loads(record_file.read_text())
    assert good["digest"] == modelkey.record_digest(good)
    tampered = json.loads(record_file.read_text())
    values_ = tampered["meta"]["model"][field]
    tampered["meta"]["model"][field] = [v * 1.5 + 0.25 for v in values_]
    record_file.write_text(json.dumps(tampered, sort_keys=True))
    res, sim, messages = spring_run()
    assert len(messages) == 1, messages
    assert str(record_file) in messages[0] and "is not used" in messages[0]
    assert "content hash differs" in messages[0] and "building the model again" in messages[0]
    assert "system" in sim.model.__dict__                     # built, not read from it
    for name, arr in first.arrays.items():
        np.testing.assert_allclose(res[name], arr, rtol=0, atol=1e-12, err_msg=name)
    assert json.loads(record_file.read_text()) == good        # the entry was rebuilt
    again, sim, messages = spring_run()                        # and is a clean hit again
    assert messages == [] and sim.model.report.cache_hit and "system" not in sim.model.__dict__
    np.testing.assert_allclose(again["q"], first["q"], rtol=0, atol=1e-12)


def test_a_model_record_naming_another_library_hash_is_not_used(_env):
    """The library entry's SHA-256 (covered by the digest) must be the library's own; a record
    whose digest was recomputed after the edit is still refused by that check."""
    first, _, _ = spring_run()
    record_file = next(_env.glob("*.model.json"))
    record = json.loads(record_file.read_text())
    record["libraries"][0]["sha256"] = "0" * 64
    record["digest"] = modelkey.record_digest(record)
    record_file.write_text(json.dumps(record, sort_keys=True))
    res, _, messages = spring_run()
    assert len(messages) == 1 and "SHA-256 differs from the model record's" in messages[0]
    np.testing.assert_allclose(res["q"], first["q"], rtol=0, atol=1e-12)


def test_a_tampered_modal_file_is_recomputed_not_used(_env):
    """A modal data file with one stiffness entry changed (finite, right shape, right key):
    its content hash differs, it is a miss, and the modes computed again equal the first ones
    bit for bit; the file is replaced by a good one."""
    beam = beam_model(2.0, 6, EA=1e6, EI=50.0, rhoA=1.5, nodes={"root": 0.0, "tip": 2.0})
    flexible_bodies._MODES.clear()
    first = flexible_bodies.modal_data(beam, "craig_bampton", 3, ["root", "tip"],
                                      store=modal_cache.DISK_STORE)
    path = next(_env.glob("modes_*.npz"))
    data = dict(np.load(path, allow_pickle=False))
    data["stiffness"] = data["stiffness"].copy()
    data["stiffness"][0, 0] *= 226.0
    np.savez(path, **data)
    key = str(data["key"])
    assert modal_cache.load_modes(key) is None
    flexible_bodies._MODES.clear()
    second = flexible_bodies.modal_data(beam, "craig_bampton", 3, ["root", "tip"],
                                      store=modal_cache.DISK_STORE)
    for name in ("positions", "masses", "phi_t", "phi_r", "mass", "stiffness", "frequencies"):
        assert np.array_equal(getattr(first, name), getattr(second, name)), name
    assert np.array_equal(modal_cache.load_modes(key).stiffness, first.stiffness)


# ----------------------------------------------------------------- a full file system
def full_disk(monkeypatch, directory: pathlib.Path) -> None:
    """Every text write below ``directory`` fails with ENOSPC (a 300 KiB file system that the
    probe file of ``cache_dir`` still fits on: an empty file needs no block)."""
    write_text = pathlib.Path.write_text

    def full(self, *args, **kwargs):
        if pathlib.Path(self).resolve().is_relative_to(directory.resolve()):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
        return write_text(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "write_text", full)


def test_a_full_cache_file_system_falls_back_to_the_vm(_env, monkeypatch):
    """ENOSPC while writing the C sources into the cache ("internal error (OSError): [Errno 28]"
    before): mode "auto" runs on the CasADi virtual machine with one warning naming the
    directory and the cause, numbers equal to the VM's to 1e-12; mode "compiled" is a
    CompileError naming them; nothing is left in the cache directory."""
    full_disk(monkeypatch, _env)
    funs, rep, messages = build_here(mode="auto")
    assert rep.mode == "vm" and len(messages) == 1, messages
    assert "using the CasADi virtual machine instead" in messages[0]
    assert f"cannot write in the cache directory {_env}: No space left on device" in messages[0]
    np.testing.assert_allclose(values(funs), vm_values(0), rtol=0, atol=1e-12)
    with pytest.raises(CompileError, match="No space left on device"):
        codegen.compile_functions(tiny_functions(0), NAME, mode="compiled")
    assert sorted(p.name for p in _env.iterdir()) == []


def test_a_full_cache_file_system_cli(_env, monkeypatch, capsys):
    """``casmbd simulate`` with the cache on a full file system: exit 0, one warning line, the
    result equal to the VM run's to 1e-12."""
    full_disk(monkeypatch, _env)
    with warnings.catch_warnings(record=True) as caught:  # the CLI prints each as one line
        warnings.simplefilter("always")
        code = cli.main(["simulate", str(SCENE), "--t-end", "0.5", "--steps", "5", "--json"])
    captured = capsys.readouterr()
    assert code == 0 and "Traceback" not in captured.err and "error" not in captured.err
    messages = [str(w.message) for w in caught]
    assert len(messages) == 1 and "Errno" not in messages[0], messages
    assert "No space left on device" in messages[0] and "virtual machine" in messages[0]
    out = json.loads(captured.out)
    vm = simulate(load_scene(SCENE), t_end=0.5, steps=5, mode="vm")
    np.testing.assert_allclose(np.array(out["bodies"]["block"]["position"]),
                               vm.body("block")["position"], rtol=0, atol=1e-12)
