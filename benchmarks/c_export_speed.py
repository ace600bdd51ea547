"""Per-call time of the exported C (``casmbd export``) against Pinocchio's C++ ``rnea``/``aba``
(issue 38 item 4: target ≤ 1× Pinocchio's C++), both in a compiled loop, measured in one run.

For each robot of ``example-robot-data`` (UR5, Panda, and the 29-joint humanoid g1; fixed base
as the file says, ``<mimic>`` pairs locked at 0 on both sides as in
:mod:`benchmarks.robots_speed`):

* **casmbd**: :func:`casmbd.export_c` writes ``inverse_dynamics`` and ``forward_dynamics``;
  a C99 harness (:data:`C_HARNESS`) links the exported ``robot.c`` and ``robot_model.c``
  and calls ``robot_inverse_dynamics``/``robot_forward_dynamics`` through the public wrapper
  (argument checks and finiteness test included), compiled with ``cc -std=c99 FLAGS``;
* **Pinocchio**: a C++17 harness (:data:`CPP_HARNESS`) calls ``pinocchio::rnea`` and
  ``pinocchio::aba`` on the same states (Pinocchio's q: cos/sin of continuous joints, its
  joint order), compiled with ``c++ -std=c++17 FLAGS`` header-only — Pinocchio's templates
  instantiated in the harness with the same flags as the C side (the headers and boost of
  the ``pin`` wheel under ``site-packages/cmeel.prefix``, Eigen from the ``cmeel-eigen``
  wheel or the system) —, the model read from Pinocchio's own text serialization of the
  (reduced) model the Python binding built from the URDF (so no library compiled with other
  flags is in the timed path).

Both sides are first checked to give the same τ and q̈ at the first state (relative 1e-9);
then each loop calls the function on :data:`N_STATES` states ``reps`` times; the figure is the
best of ``--loops`` loops, in ns per call (:mod:`benchmarks.fair`: best of warm repeats, load
and versions recorded).  The flags are the same on both sides (default ``-O3
-march=native -DNDEBUG``, a release build: without ``NDEBUG`` Eigen's and Pinocchio's
assertions stay in the timed code — the exported C has none; ``--flags``).  If the C++
harness cannot be built, the reason is recorded and Pinocchio's Python binding is timed
instead, labelled as such.

Run: ``python -m benchmarks.c_export_speed [--robots ur5_robot,panda,g1_29dof_rev_1_0]
[--flags "-O3 -march=native -DNDEBUG"] [--update-docs]``: writes
``benchmarks/results/c_export_speed.json`` and, with ``--update-docs``, the section
``## Benchmark: exported C against Pinocchio's C++`` of docs/export.md.
"""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from benchmarks import fair
from benchmarks.docs import run_study, study_parser
from benchmarks.robots_vs_pinocchio import (
    _broken_mimic,
    _mimic_joints,
    _pin_configuration,
    robots_dir,
)

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "c_export_speed.json"
DOC = ROOT / "docs" / "export.md"
HEAD = "## Benchmark: exported C against Pinocchio's C++"
#: the robots (URDF stems of example-robot-data): two arms and a 29-joint humanoid
ROBOTS = ("ur5_robot", "panda", "g1_29dof_rev_1_0")
FLAGS = ("-O3", "-march=native", "-DNDEBUG")
#: distinct states per loop (cycled, so no call sees the previous call's inputs)
N_STATES = 16
#: Pinocchio's interface definitions (its CMake target's INTERFACE_COMPILE_DEFINITIONS)
PIN_DEFINES = ("-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
               "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12")

C_HARNESS = r"""#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "robot.h"

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static robot_work work;

int main(int argc, char **argv) {
  FILE *f;
  int ns, loops, l, s, k;
  long reps, r;
  double *q, *v, *x, out[robot_NV], sum = 0.0, best[2] = {1e300, 1e300};
  if (argc != 5) return 2;
  ns = atoi(argv[2]); reps = atol(argv[3]); loops = atoi(argv[4]);
  q = malloc(sizeof(double) * (size_t)ns * robot_NQ);
  v = malloc(sizeof(double) * (size_t)ns * robot_NV);
  x = malloc(sizeof(double) * (size_t)ns * robot_NV);
  f = fopen(argv[1], "rb");
  if (!f || fread(q, sizeof(double), (size_t)ns * robot_NQ, f) != (size_t)ns * robot_NQ
      || fread(v, sizeof(double), (size_t)ns * robot_NV, f) != (size_t)ns * robot_NV
      || fread(x, sizeof(double), (size_t)ns * robot_NV, f) != (size_t)ns * robot_NV)
    return 3;
  fclose(f);
  if (robot_inverse_dynamics(q, v, x, out, &work) != robot_OK) return 4;
  printf("tau");
  for (k = 0; k < robot_NV; ++k) printf(" %.17g", out[k]);
  if (robot_forward_dynamics(q, v, x, out, &work) != robot_OK) return 5;
  printf("\nqdd");
  for (k = 0; k < robot_NV; ++k) printf(" %.17g", out[k]);
  printf("\n");
  for (l = 0; l < loops; ++l) {
    double t0 = now(), t;
    for (r = 0; r < reps; ++r)
      for (s = 0; s < ns; ++s) {
        robot_inverse_dynamics(q + s * robot_NQ, v + s * robot_NV, x + s * robot_NV, out,
                               &work);
        sum += out[0];
      }
    t = (now() - t0) / ((double)reps * ns);
    if (t < best[0]) best[0] = t;
    t0 = now();
    for (r = 0; r < reps; ++r)
      for (s = 0; s < ns; ++s) {
        robot_forward_dynamics(q + s * robot_NQ, v + s * robot_NV, x + s * robot_NV, out,
                               &work);
        sum += out[0];
      }
    t = (now() - t0) / ((double)reps * ns);
    if (t < best[1]) best[1] = t;
  }
  printf("rnea_ns %.3f\naba_ns %.3f\nchecksum %.6g\n", 1e9 * best[0], 1e9 * best[1], sum);
  return 0;
}
"""

CPP_HARNESS = r"""#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/serialization.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <vector>

int main(int argc, char **argv) {
  if (argc != 6) return 2;
  pinocchio::Model model;
  model.loadFromText(argv[1]);
  pinocchio::Data data(model);
  const int ns = std::atoi(argv[3]), loops = std::atoi(argv[5]);
  const long reps = std::atol(argv[4]);
  const int nq = (int)model.nq, nv = (int)model.nv;
  std::vector<double> q((size_t)ns * nq), v((size_t)ns * nv), x((size_t)ns * nv);
  std::ifstream in(argv[2], std::ios::binary);
  in.read((char *)q.data(), sizeof(double) * q.size());
  in.read((char *)v.data(), sizeof(double) * v.size());
  in.read((char *)x.data(), sizeof(double) * x.size());
  if (!in) return 3;
  typedef Eigen::Map<const Eigen::VectorXd> Vec;
  std::vector<Vec> Q, V, X;
  for (int s = 0; s < ns; ++s) {
    Q.emplace_back(q.data() + s * nq, nq);
    V.emplace_back(v.data() + s * nv, nv);
    X.emplace_back(x.data() + s * nv, nv);
  }
  const Eigen::VectorXd tau = pinocchio::rnea(model, data, Q[0], V[0], X[0]);
  std::printf("tau");
  for (int k = 0; k < nv; ++k) std::printf(" %.17g", tau[k]);
  const Eigen::VectorXd qdd = pinocchio::aba(model, data, Q[0], V[0], X[0]);
  std::printf("\nqdd");
  for (int k = 0; k < nv; ++k) std::printf(" %.17g", qdd[k]);
  std::printf("\n");
  double sum = 0.0, best[2] = {1e300, 1e300};
  typedef std::chrono::steady_clock clock;
  for (int l = 0; l < loops; ++l) {
    auto t0 = clock::now();
    for (long r = 0; r < reps; ++r)
      for (int s = 0; s < ns; ++s) sum += pinocchio::rnea(model, data, Q[s], V[s], X[s])[0];
    double t = std::chrono::duration<double>(clock::now() - t0).count() / (double(reps) * ns);
    if (t < best[0]) best[0] = t;
    t0 = clock::now();
    for (long r = 0; r < reps; ++r)
      for (int s = 0; s < ns; ++s) sum += pinocchio::aba(model, data, Q[s], V[s], X[s])[0];
    t = std::chrono::duration<double>(clock::now() - t0).count() / (double(reps) * ns);
    if (t < best[1]) best[1] = t;
  }
  std::printf("rnea_ns %.3f\naba_ns %.3f\nchecksum %.6g\n", 1e9 * best[0], 1e9 * best[1],
              sum);
  return 0;
}
"""


def cmeel_prefix() -> Path | None:
    """``site-packages/cmeel.prefix`` of the installed ``pin`` wheel, or None."""
    try:
        import pinocchio
    except ImportError:
        return None
    for parent in Path(pinocchio.__file__).resolve().parents:
        if parent.name == "cmeel.prefix":
            return parent
    return None


def eigen_include(prefix: Path | None) -> Path | None:
    """Eigen's include folder: the ``cmeel-eigen`` wheel's, else the system's."""
    for cand in ([prefix / "include" / "eigen3"] if prefix else []) + [
            Path("/usr/include/eigen3"), Path("/usr/local/include/eigen3")]:
        if (cand / "Eigen" / "Core").exists():
            return cand
    return None


def _run(cmd: list[str], cwd: Path, timeout: float = 1800.0) -> str:
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"{shlex.join(cmd)} failed ({proc.returncode}): "
                           f"{(proc.stderr or proc.stdout)[-1500:]}")
    return proc.stdout


def build_pinocchio_harness(work: Path, flags: list[str]) -> tuple[Path | None, str]:
    """The C++ harness binary, or (None, why it cannot be built)."""
    prefix = cmeel_prefix()
    cxx = shutil.which(os.environ.get("CXX", "c++")) or shutil.which("g++")
    if prefix is None:
        return None, "Pinocchio's Python package (pin) is not installed"
    if cxx is None:
        return None, "no C++ compiler (c++/g++) on PATH"
    if not (prefix / "include" / "pinocchio" / "algorithm" / "aba.hpp").exists():
        return None, f"no Pinocchio C++ headers under {prefix / 'include'}"
    eigen = eigen_include(prefix)
    if eigen is None:
        return None, ("no Eigen headers (pip install cmeel-eigen, or apt-get install "
                      "libeigen3-dev)")
    src = work / "pin_harness.cpp"
    src.write_text(CPP_HARNESS)
    exe = work / "pin_harness"
    libdir = prefix / "lib"
    try:
        _run([cxx, "-std=c++17", *flags, *PIN_DEFINES, f"-I{prefix / 'include'}",
              f"-I{eigen}", str(src), f"-L{libdir}", "-lboost_serialization",
              f"-Wl,-rpath,{libdir}", "-o", str(exe)], work)
    except (RuntimeError, subprocess.TimeoutExpired) as exc:
        return None, f"the C++ harness does not build: {exc}"
    return exe, ""


def _compiler_version(cmd: str) -> str:
    try:
        return subprocess.run([cmd, "--version"], capture_output=True, text=True,
                              timeout=30).stdout.splitlines()[0]
    except (OSError, IndexError, subprocess.SubprocessError):
        return "?"


def _parse(out: str) -> dict:
    rec = {}
    for line in out.splitlines():
        key, *vals = line.split()
        rec[key] = [float(x) for x in vals] if key in ("tau", "qdd") else float(vals[0])
    return rec


def _reps(nv: int) -> int:
    """Calls per loop and state: about 1.5 M joint-calls per loop."""
    return max(20, int(1.5e6 / (N_STATES * nv * 40)))


def measure_robot(path: Path, work: Path, flags: list[str], pin_exe: Path | None,
                  loops: int, seed: int = 0) -> dict:
    """The record of one robot."""
    import pinocchio as pin

    import casmbd

    rec: dict = {"robot": path.stem}
    pm = pin.buildModelFromUrdf(str(path))
    mimic, leaders = _mimic_joints(path)
    if mimic:
        ids = sorted({pm.getJointId(n) for n in mimic if pm.existJointName(n)})
        pm = pin.buildReducedModel(pm, ids, pin.neutral(pm))
        rec["locked"] = mimic
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mech = casmbd.load_urdf(path, locked=dict.fromkeys(leaders, 0.0),
                                **_broken_mimic(path))
    folder = work / path.stem
    t0 = time.perf_counter()
    report = casmbd.export_c(mech, folder, functions="inverse_dynamics,forward_dynamics",
                             prefix="robot", force=True)
    rec["export_s"] = round(time.perf_counter() - t0, 2)
    rec["nv"] = report.nv
    rec["c_bytes"] = (folder / "robot_model.c").stat().st_size
    (folder / "harness.c").write_text(C_HARNESS)
    t0 = time.perf_counter()
    _run([shutil.which("cc") or "cc", "-std=c99", *flags, "harness.c", "robot.c",
          "robot_model.c", "-lm", "-o", "harness"], folder)
    rec["cc_s"] = round(time.perf_counter() - t0, 2)
    to_pin, perm = _pin_configuration(pm, report.coordinate_names,
                                      getattr(mech, "urdf_renamed", {}))
    rng = np.random.default_rng(seed)
    n = report.nq
    qs = rng.uniform(-1.0, 1.0, (N_STATES, n))
    vs, xs = rng.uniform(-2.0, 2.0, (N_STATES, n)), rng.uniform(-2.0, 2.0, (N_STATES, n))
    np.concatenate([qs.ravel(), vs.ravel(), xs.ravel()]).tofile(folder / "states.bin")
    reps = _reps(n)
    rec["reps"], rec["states"], rec["loops"] = reps, N_STATES, loops
    ours = _parse(_run([str(folder / "harness"), "states.bin", str(N_STATES), str(reps),
                        str(loops)], folder))
    rec["casmbd_ns"] = {"inverse_dynamics": ours["rnea_ns"],
                        "forward_dynamics": ours["aba_ns"]}
    pin_states = np.concatenate([np.concatenate([to_pin(q) for q in qs]),
                                 vs[:, perm].ravel(), xs[:, perm].ravel()])
    # the reference at state 0: Pinocchio's Python binding (the checks of both harnesses)
    data = pm.createData()
    qp, vp, xp = to_pin(qs[0]), vs[0][perm], xs[0][perm]
    tau = pin.rnea(pm, data, qp, vp, xp)
    qdd = pin.aba(pm, data, qp, vp, xp)
    rec["errors"] = {
        "tau": float(np.max(np.abs(np.array(ours["tau"])[perm] - tau)) / np.max(np.abs(tau))),
        "qdd": float(np.max(np.abs(np.array(ours["qdd"])[perm] - qdd)) / np.max(np.abs(qdd)))}
    if max(rec["errors"].values()) > 1e-9:
        rec["error"] = f"casmbd and Pinocchio disagree: {rec['errors']}"
    if pin_exe is not None:
        pm.saveToText(str(folder / "pin_model.txt"))
        pin_states.tofile(folder / "pin_states.bin")
        theirs = _parse(_run([str(pin_exe), "pin_model.txt", "pin_states.bin",
                              str(N_STATES), str(reps), str(loops)], folder))
        rec["pinocchio_cpp_ns"] = {"rnea": theirs["rnea_ns"], "aba": theirs["aba_ns"]}
        rec["errors"]["cpp_tau"] = float(np.max(np.abs(np.array(theirs["tau"]) - tau))
                                         / np.max(np.abs(tau)))
    else:  # the labelled fallback: Pinocchio through its Python binding
        import timeit
        states = [(to_pin(q), v[perm], x[perm]) for q, v, x in zip(qs, vs, xs)]

        def loop(fn):
            return lambda: [fn(pm, data, *s) for s in states]
        number = max(1, reps // 20)
        rec["pinocchio_python_ns"] = {
            name: min(timeit.repeat(loop(fn), number=number, repeat=loops))
            / (number * N_STATES) * 1e9
            for name, fn in (("rnea", pin.rnea), ("aba", pin.aba))}
    return rec


def measure(robots: list[str], flags: list[str], loops: int) -> dict:
    base = robots_dir()
    if base is None:
        raise SystemExit("example-robot-data is not installed (pip install example-robot-data)")
    paths = {p.stem: p for p in base.rglob("*.urdf")}
    missing = [r for r in robots if r not in paths]
    if missing:
        raise SystemExit(f"robots not found in {base}: {missing}")
    data: dict = {"date": datetime.date.today().isoformat(), "machine": platform.machine(),
                  "python": sys.version.split()[0], "versions": fair.versions(),
                  "flags": flags, "cc": _compiler_version(shutil.which("cc") or "cc"),
                  "cxx": _compiler_version(shutil.which("c++") or "c++"),
                  "load_before": fair.load(), "robots": []}
    with tempfile.TemporaryDirectory(prefix="casmbd-c-export-bench-") as tmp:
        work = Path(tmp)
        t0 = time.perf_counter()
        pin_exe, why = build_pinocchio_harness(work, flags)
        data["pinocchio_cpp"] = pin_exe is not None
        data["pinocchio_cpp_build_s"] = round(time.perf_counter() - t0, 1)
        if why:
            data["pinocchio_cpp_reason"] = why
            print(f"Pinocchio C++: {why}; timing Pinocchio's Python binding instead",
                  file=sys.stderr)
        for name in robots:
            print(f"{name} ...", file=sys.stderr, flush=True)
            try:
                data["robots"].append(measure_robot(paths[name], work, flags, pin_exe, loops))
            except (RuntimeError, subprocess.TimeoutExpired) as exc:
                data["robots"].append({"robot": name, "error": str(exc)[:500]})
    data["load_after"] = fair.load()
    return data


def _ratio(a: float | None, b: float | None) -> str:
    return f"{a / b:.2f}" if a and b else "—"


def markdown(data: dict) -> str:
    cpp = data.get("pinocchio_cpp", False)
    peer = "Pinocchio C++" if cpp else "Pinocchio (Python binding)"
    key = "pinocchio_cpp_ns" if cpp else "pinocchio_python_ns"
    flags = " ".join(data["flags"])
    lines = [
        HEAD, "",
        f"Per call, in a compiled loop on {N_STATES} random states (best of "
        f"{data['robots'][0].get('loops', '?') if data['robots'] else '?'} loops), ns: the "
        f"exported C through its public wrapper (`robot_inverse_dynamics`, "
        f"`robot_forward_dynamics`: argument checks and the finiteness test included) "
        f"against {peer}'s `rnea`/`aba`"
        + (" instantiated header-only in a C++ loop" if cpp else "") + f"; both compiled "
        f"with `{flags}` ({data['cc']}; {data['cxx']}).  The same τ and q̈ at the first "
        "state (relative error to Pinocchio's binding in the last column).  Command: "
        f"`python -m benchmarks.c_export_speed --flags \"{flags}\" --update-docs` (needs "
        "`pin` and `example-robot-data`, and Eigen's headers for the C++ side: `pip install "
        "cmeel-eigen` or the system's `libeigen3-dev`"
        + (f"; the C++ harness built in {data['pinocchio_cpp_build_s']:.0f} s" if cpp else "")
        + ").", ""]
    if not cpp:
        lines += [f"**Pinocchio's C++ was not built:** {data.get('pinocchio_cpp_reason')}; "
                  "its figures are those of the Python binding (a binding call's overhead "
                  "included), not of C++.", ""]
    lines += ["| robot | n_v | C inverse dynamics | " + peer + " rnea | ratio | "
              "C forward dynamics | " + peer + " aba | ratio | C source | export + cc | "
              "max rel. error |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in data["robots"]:
        if "casmbd_ns" not in r:
            lines.append(f"| {r['robot']} | — | {r.get('error', '?')} |  |  |  |  |  |  |  |  |")
            continue
        ours, theirs = r["casmbd_ns"], r.get(key, {})
        lines.append(
            f"| {r['robot']} | {r['nv']} | {ours['inverse_dynamics']:.0f} | "
            f"{theirs.get('rnea', float('nan')):.0f} | "
            f"{_ratio(ours['inverse_dynamics'], theirs.get('rnea'))} | "
            f"{ours['forward_dynamics']:.0f} | {theirs.get('aba', float('nan')):.0f} | "
            f"{_ratio(ours['forward_dynamics'], theirs.get('aba'))} | "
            f"{r['c_bytes'] / 1e3:.0f} kB | {r['export_s']:.1f} + {r['cc_s']:.1f} s | "
            f"{max(r['errors'].values()):.1e} |")
    v = data["versions"]
    lines += ["", f"Ratio = casmbd / Pinocchio (≤ 1: the exported C is as fast or faster).  "
              f"{data['date']}, {data['machine']}, load {data['load_before']} → "
              f"{data['load_after']} (2 cores shared); casadi {v.get('casadi', '?')}, "
              f"pinocchio {v.get('pinocchio', '?')}, example-robot-data "
              f"{v.get('example-robot-data', '?')}, casmbd {v.get('casmbd_commit', '?')}."]
    lose = [(r["robot"], f) for r in data["robots"] if "casmbd_ns" in r
            for f, p in (("inverse_dynamics", "rnea"), ("forward_dynamics", "aba"))
            if r.get(key, {}).get(p) and r["casmbd_ns"][f] > r[key][p]]
    per_call = ("Per call the exported C loses on: " + ", ".join(
        f"{rob} {f.replace('_', ' ')}" for rob, f in lose) + "." if lose else
        "Per call the exported C is faster on every robot and both functions here.")
    lines += ["", per_call + "  Where it loses: it is one model's straight-line code — "
              "its size and build time grow with the robot (the C source column; the "
              "export + cc column: `casmbd.export_c` then `cc` of the harness with these "
              "flags, on this loaded machine), and changing a mass or a length means "
              "exporting and compiling again, where Pinocchio reads any model at run time "
              "into one compiled library.  These are single-thread figures on a shared "
              "2-core machine: compare the ratios, not the absolute times."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--robots", default=",".join(ROBOTS),
                        help="comma-separated URDF stems of example-robot-data")
    parser.add_argument("--flags", default=" ".join(FLAGS),
                        help="compiler flags of both harnesses (default: -O3 -march=native "
                             "-DNDEBUG)")
    parser.add_argument("--loops", type=int, default=7, help="best of this many loops")
    args = parser.parse_args(argv)
    robots = [r for r in args.robots.split(",") if r]
    return run_study(args, RESULTS,
                     lambda: measure(robots, args.flags.split(), args.loops),
                     markdown, DOC, HEAD)


if __name__ == "__main__":
    sys.exit(main())
