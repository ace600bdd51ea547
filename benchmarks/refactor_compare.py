"""Proof that a refactor changes no result: record every array of a fixed comparison set, compare.

``--record DIR [--repo CHECKOUT]`` runs the comparison set through the Python API of the
package in ``CHECKOUT`` (default: this script's own checkout) and writes one ``.npz`` per run
into ``DIR``, named by a stable case id, plus ``DIR/manifest.json`` (the commit, the versions,
the per-run wall times, never compared).  The runs are made by worker processes started with
``PYTHONPATH=CHECKOUT``, so ``import casmbd`` is that checkout's package; the scene files and
this script are always those of the script's own checkout (``--scenes-root``), so two
checkouts are compared on the same inputs.  Everything runs on CasADi's virtual machine
(``mode="vm"``, ``CASMBD_COMPILE=0``) with one BLAS thread.

``--compare DIR_A DIR_B`` counts the runs whose every array is identical
(``numpy.array_equal`` with NaN equal to NaN; texts equal), the different ones (each differing
array with its largest absolute and relative difference), the missing and the extra ones,
prints a table by analysis and exits with status 1 on any difference.

The comparison set (``cases``):

* every scene file ``examples/*.toml``, ``examples/*.urdf``, ``tests/scenes/*.toml``,
  ``tests/scenes/*.urdf`` × the analyses ``simulate`` (default formulation, integrator and
  coordinates of the scene), ``kinematics``, ``inverse`` (inverse dynamics), ``statics``
  (``method="augmented"``), ``statics_reduced`` (``method="reduced"``), ``linearize`` (about
  the initial state) and ``linearize_eq`` (about the static equilibrium).  Every analysis is
  tried on every scene: where it does not apply (a kinematic analysis of a scene with free
  degrees of freedom, statics of a scene with impacts ...) the refusal — error class and
  message — is the recorded result, and must be identical too;
* for :data:`MATRIX_SCENES` (7 planar and 7 spatial scenes without events): ``simulate`` ×
  every formulation × every integrator × every coordinate choice (:data:`FORMULATIONS`,
  :data:`INTEGRATORS`, :data:`COORDINATES`; fixed lists, so the set does not depend on which
  names a registry offers in a fresh process), the refused combinations with their message;
* for :data:`PROJECTION_SCENES`: ``simulate`` with ``projection=True`` × every formulation ×
  every integrator in the scene's own coordinates.

What is recorded per run: for a :class:`~casmbd.results.Result` the time grid, every array,
the names, the events, the scene text and the statistics; for the statics and linearization
results every field; for a refusal the error class and message; and the warnings the run
issued.  Statistics that measure time (keys ending in ``seconds``) or the disk cache
(``cache_hit``) are left out: they differ between two runs of one checkout.  Paths of the scene
root and of the checkout are replaced by ``<scenes>`` and ``<casmbd>`` in every text.

Run ``python -m benchmarks.refactor_compare --record /tmp/a --repo /path/to/main``, then
``--record /tmp/b`` (this checkout) and ``--compare /tmp/a /tmp/b`` (docs/architecture.md,
"Proving a refactor changes no result").
"""

from __future__ import annotations

import argparse
import dataclasses
import enum
import fnmatch
import json
import os
import re
import select
import subprocess
import sys
import tempfile
import time
import tomllib
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
#: scene files of the set, globbed relative to the scenes root
SCENE_GLOBS = ("examples/*.toml", "examples/*.urdf", "tests/scenes/*.toml",
               "tests/scenes/*.urdf")
#: analyses tried on every scene
ANALYSES = ("simulate", "kinematics", "inverse", "statics", "statics_reduced", "linearize",
            "linearize_eq")
#: studies tried on every scene with a ``[parameters]`` table
STUDIES = ("sweep", "sensitivity")
#: the formulation × integrator × coordinate matrix (fixed lists: the names registered on
#: 16db669; a name a checkout does not know is recorded as its refusal)
FORMULATIONS = ("index1", "ggl", "kkt_ode", "augmented_lagrangian", "articulated",
                "nullspace", "partitioning")
INTEGRATORS = ("idas", "cvodes", "adams", "rk4", "abm", "dopri5")
COORDINATES = ("auto", "absolute", "natural", "joint")
#: scenes of the matrix: 7 planar and 7 spatial, without events
MATRIX_SCENES = (
    "examples/double_pendulum.toml", "examples/slider_crank.toml",
    "examples/parallelogram.toml", "examples/pd_pendulum.toml",
    "examples/crank_friction.toml", "examples/flexible_slider_crank.toml",
    "tests/scenes/spring_mass.toml",
    "examples/heavy_top.toml", "examples/spatial_four_bar.toml",
    "examples/spatial_slider_crank.toml", "examples/cardan_shaft.toml",
    "examples/bricard.toml", "examples/crankshaft.toml", "examples/ur5_arm.urdf",
)
#: scenes of the projection runs (scene's own coordinates)
PROJECTION_SCENES = ("examples/slider_crank.toml", "examples/parallelogram.toml",
                     "examples/spatial_four_bar.toml", "examples/heavy_top.toml")
#: the output grid of every run: short, so that the whole set records in minutes
T_END, STEPS = 0.1, 10
#: longer runs where the events of the scene happen later (at least one event)
T_END_SCENE = {"examples/bouncing_ball.toml": 1.0, "examples/pendulum_stops.toml": 1.0,
               "examples/rolling_sphere.toml": 0.5}
#: statistics keys left out of the record (they measure time or the disk cache)
VOLATILE_KEY = re.compile(r"(seconds|_wall|elapsed)$|^cache_hit$")
#: result fields left out (a sweep's per-point worker host:pid and timings)
VOLATILE_FIELDS = ("point_stats",)
#: a run that takes longer than this is stopped and recorded as a timeout [s]
CASE_TIMEOUT = 300.0


# ======================================================================== the set
def scene_files(scenes_root: Path) -> list[str]:
    """Scene files of the set, as paths relative to the scenes root, sorted."""
    found = set()
    for pattern in SCENE_GLOBS:
        found.update(p.relative_to(scenes_root).as_posix() for p in scenes_root.glob(pattern))
    return sorted(found)


def case_id(scene: str, analysis: str, *options: str) -> str:
    """Stable file name of a run: ``examples-four_bar.toml-simulate`` and so on."""
    return "-".join([scene.replace("/", "-"), analysis, *options])


def has_parameters(path: Path) -> bool:
    """Whether a scene file declares a ``[parameters]`` table (read without casmbd)."""
    if path.suffix != ".toml":
        return False
    with open(path, "rb") as fh:
        return bool(tomllib.load(fh).get("parameters"))


def cases(scenes_root: Path) -> list[dict]:
    """Every run of the comparison set, in a fixed order (by scene, then as listed)."""
    out = []
    for scene in scene_files(scenes_root):
        for analysis in ANALYSES:
            out.append({"id": case_id(scene, analysis), "scene": scene, "analysis": analysis})
        if has_parameters(scenes_root / scene):
            for analysis in STUDIES:
                out.append({"id": case_id(scene, analysis), "scene": scene,
                            "analysis": analysis})
        if scene in MATRIX_SCENES:
            for coords in COORDINATES:
                for form in FORMULATIONS:
                    for integ in INTEGRATORS:
                        out.append({"id": case_id(scene, "simulate", coords, form, integ),
                                    "scene": scene, "analysis": "simulate_matrix",
                                    "coordinates": coords, "formulation": form,
                                    "integrator": integ})
        if scene in PROJECTION_SCENES:
            for form in FORMULATIONS:
                for integ in INTEGRATORS:
                    out.append({"id": case_id(scene, "simulate", "projection", form, integ),
                                "scene": scene, "analysis": "simulate_projection",
                                "formulation": form, "integrator": integ})
    return out


# ======================================================================== the worker
def _clean_text(text: str, paths: dict[str, str]) -> str:
    for path in sorted(paths, key=len, reverse=True):  # /a/b before /a
        text = text.replace(path, paths[path])
    return text


def _jsonable(value, paths):
    """Plain JSON of a value; floats keep every bit (``repr`` round-trips), timing keys
    are left out of every dictionary."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v, paths) for k, v in value.items()
                if not VOLATILE_KEY.search(str(k))}
    if isinstance(value, (list, tuple, set, frozenset)):
        items = sorted(value, key=repr) if isinstance(value, (set, frozenset)) else value
        return [_jsonable(v, paths) for v in items]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist(), paths)
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if np.isfinite(v) else repr(v)
    if isinstance(value, (complex, np.complexfloating)):
        return [_jsonable(value.real, paths), _jsonable(value.imag, paths)]
    if isinstance(value, enum.Enum):
        return str(value.value)
    if isinstance(value, str):
        return _clean_text(value, paths)
    if value is None:
        return None
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _jsonable(getattr(value, f.name), paths)
                for f in dataclasses.fields(value)}
    if hasattr(value, "to_json"):
        return _jsonable(value.to_json(), paths)
    return f"<{type(value).__name__}>"  # never an address: repr could hold one


def _text(value) -> np.ndarray:
    return np.array(json.dumps(value, sort_keys=True, ensure_ascii=False))


def _numeric(value) -> bool:
    return (isinstance(value, np.ndarray) and value.dtype.kind in "biufc") or \
        isinstance(value, (bool, int, float, complex, np.number, np.bool_))


def record_value(obj, paths: dict[str, str]) -> dict[str, np.ndarray]:
    """The arrays and texts of an analysis's answer, flat: ``array/<name>`` bit-exact arrays,
    ``text/<name>`` JSON texts."""
    out: dict[str, np.ndarray] = {}
    if hasattr(obj, "arrays") and hasattr(obj, "t"):  # a Result
        out["array/t"] = np.asarray(obj.t)
        for name, arr in obj.arrays.items():
            out[f"array/arrays.{name}"] = np.asarray(arr)
        out["text/kind"] = _text(obj.kind)
        out["text/names"] = _text(_jsonable(obj.names, paths))
        out["text/stats"] = _text(_jsonable(obj.stats, paths))
        out["text/events"] = _text(_jsonable(getattr(obj, "events", []), paths))
        out["text/scene"] = _text(_clean_text(getattr(obj, "scene", ""), paths))
        return out
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            if f.name in VOLATILE_FIELDS:
                continue
            if isinstance(value, np.ndarray) and value.dtype.names:  # a structured array
                for name in value.dtype.names:
                    out[f"array/{f.name}.{name}"] = np.asarray(value[name])
            elif _numeric(value):
                out[f"array/{f.name}"] = np.asarray(value)
            else:
                out[f"text/{f.name}"] = _text(_jsonable(value, paths))
        return out
    out["text/value"] = _text(_jsonable(obj, paths))
    return out


def run_case(case: dict, scenes_root: Path) -> object:
    """Run one case through casmbd's public API and return its answer (or raise)."""
    import casmbd  # the checkout's package (PYTHONPATH)

    mech = casmbd.load_scene(case["scene"])
    t_end = T_END_SCENE.get(case["scene"], T_END)
    analysis = case["analysis"]
    if analysis == "simulate":
        return casmbd.simulate(mech, t_end, STEPS, mode="vm")
    if analysis == "kinematics":
        return casmbd.kinematics(mech, t_end, STEPS, mode="vm")
    if analysis == "inverse":
        return casmbd.inverse_dynamics(mech, t_end, STEPS, mode="vm")
    if analysis == "statics":
        return casmbd.static_equilibrium(mech, mode="vm")
    if analysis == "statics_reduced":
        return casmbd.static_equilibrium(mech, method="reduced", mode="vm")
    if analysis == "linearize":
        return casmbd.linearize(mech, mode="vm")
    if analysis == "linearize_eq":
        return casmbd.linearize(mech, mode="vm", at="equilibrium")
    if analysis == "sweep":  # the first parameter at its value and 5 % above, serially
        name, value = next(iter(mech.parameters.items()))
        return casmbd.sweep(mech, {name: [value, 1.05 * value]}, analysis="simulate",
                            t_end=t_end, steps=STEPS, mode="vm", executor="serial",
                            progress=False)
    if analysis == "sensitivity":  # the first body's x at t_end, every parameter
        return casmbd.sensitivity(mech, f"{next(iter(mech.bodies))}_x", t_end=t_end)
    if analysis == "simulate_matrix":
        mech.coordinates = case["coordinates"]
        return casmbd.simulate(mech, t_end, STEPS, mode="vm", formulation=case["formulation"],
                               integrator=case["integrator"])
    if analysis == "simulate_projection":
        return casmbd.simulate(mech, t_end, STEPS, mode="vm", formulation=case["formulation"],
                               integrator=case["integrator"], projection=True)
    raise ValueError(f"unknown analysis {analysis!r}")


def worker(case_file: Path, out_dir: Path, scenes_root: Path) -> int:
    """Run the cases of ``case_file`` one after the other, each into ``out_dir/<id>.npz``;
    print ``start <id>`` and ``done <id> <seconds>`` so that the parent can time them out."""
    import warnings

    import casmbd
    from casmbd.errors import CasmbdError

    package = str(Path(casmbd.__file__).resolve().parent.parent)
    # the scene root wins where the package is the scenes' own checkout: a scene's path reads
    # the same whichever checkout runs it
    paths = {package: "<casmbd>", str(scenes_root): "<scenes>"}
    os.chdir(scenes_root)
    for case in json.loads(case_file.read_text()):
        print(f"start {case['id']}", flush=True)
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                payload = record_value(run_case(case, scenes_root), paths)
                payload["text/outcome"] = _text("result")
            except Exception as exc:  # every failure is a recorded outcome
                refused = isinstance(exc, CasmbdError)
                payload = {"text/outcome": _text("refused" if refused else "exception"),
                           "text/error_class": _text(type(exc).__name__),
                           "text/error_message": _text(_clean_text(str(exc), paths))}
        payload["text/warnings"] = _text([[w.category.__name__,
                                           _clean_text(str(w.message), paths)]
                                          for w in caught])
        payload["text/case"] = _text(case)
        write_npz(out_dir / f"{case['id']}.npz", payload)
        print(f"done {case['id']} {time.perf_counter() - t0:.3f}", flush=True)
    return 0


def write_npz(path: Path, payload: dict[str, np.ndarray]) -> None:
    """Write atomically (a temporary name, then a rename)."""
    tmp = path.with_suffix(".tmp.npz")
    with open(tmp, "wb") as fh:
        np.savez(fh, **payload)
    os.replace(tmp, path)


# ======================================================================== the parent
def _git(repo: Path, *args: str) -> str:
    try:
        return subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True,
                              timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def _env(repo: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update({"PYTHONPATH": str(repo), "CASMBD_COMPILE": "0", "OMP_NUM_THREADS": "1",
                "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONHASHSEED": "0"})
    return env


def _run_worker(todo: list[dict], out_dir: Path, repo: Path, scenes_root: Path,
                times: dict[str, float]) -> tuple[str | None, str]:
    """Run a worker on ``todo``; return the case it was stopped in (or None) and why."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as fh:
        json.dump(todo, fh)
        case_file = Path(fh.name)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", str(case_file),
           str(out_dir), "--scenes-root", str(scenes_root)]
    proc = subprocess.Popen(cmd, env=_env(repo), cwd=str(scenes_root), text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, bufsize=1)
    current, started, why = None, time.monotonic(), ""
    try:
        while True:
            ready, _, _ = select.select([proc.stdout], [], [], 1.0)
            if ready:
                line = proc.stdout.readline()
                if not line:
                    break
                word, *rest = line.split()
                if word == "start":
                    current, started = rest[0], time.monotonic()
                elif word == "done":
                    times[rest[0]] = float(rest[1])
                    current = None
            elif current is not None and time.monotonic() - started > CASE_TIMEOUT:
                proc.kill()  # the worker this function started, by its handle
                why = f"timeout: no result after {CASE_TIMEOUT:.0f} s"
                break
        code = proc.wait()
        if current is not None and not why:
            why = f"worker died with exit status {code}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        case_file.unlink(missing_ok=True)
    return current, why


def _matches(run: str, globs: list[str]) -> bool:
    return any(fnmatch.fnmatch(run, pattern) for pattern in globs)


def record(out_dir: Path, repo: Path, scenes_root: Path, only: list[str] | None = None) -> int:
    """Record the comparison set of ``repo``'s package into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    all_cases = cases(scenes_root)
    if only:  # these runs again, the others of an earlier record kept
        all_cases = [c for c in all_cases if _matches(c["id"], only)]
    for old in out_dir.glob("*.npz"):
        if not only or _matches(old.stem, only):
            old.unlink()
    times: dict[str, float] = {}
    t0 = time.perf_counter()
    by_scene: dict[str, list[dict]] = defaultdict(list)
    for case in all_cases:
        by_scene[case["scene"]].append(case)
    for k, (scene, todo) in enumerate(by_scene.items()):
        s0 = time.perf_counter()
        while todo:
            stopped, why = _run_worker(todo, out_dir, repo, scenes_root, times)
            if stopped is None:
                break
            ids = [c["id"] for c in todo]
            case = todo[ids.index(stopped)]
            write_npz(out_dir / f"{stopped}.npz",
                      {"text/outcome": _text("crash"), "text/error_class": _text("crash"),
                       "text/error_message": _text(why), "text/case": _text(case)})
            todo = todo[ids.index(stopped) + 1:]
        print(f"[{k + 1}/{len(by_scene)}] {scene}: {len(by_scene[scene])} runs, "
              f"{time.perf_counter() - s0:.1f} s", flush=True)
    wall = took = time.perf_counter() - t0
    probe = subprocess.run([sys.executable, "-c", "import casmbd, casadi, numpy, scipy, sys;"
                            "print(casmbd.__file__, casadi.__version__, numpy.__version__, "
                            "scipy.__version__, sys.version.split()[0])"],
                           env=_env(repo), cwd=str(scenes_root), capture_output=True,
                           text=True).stdout.split()
    counts = defaultdict(int)  # every run in DIR, also those kept from an earlier record
    for case in cases(scenes_root):
        if (out_dir / f"{case['id']}.npz").exists():
            counts[case["analysis"]] += 1
    old = out_dir / "manifest.json"
    if only and old.exists():  # a partial record: the earlier runs' times kept
        earlier = json.loads(old.read_text())
        times = {**earlier.get("case_seconds", {}), **times}
        wall += earlier.get("wall_seconds", 0.0)
    manifest = {
        "repo": str(repo), "commit": _git(repo, "rev-parse", "HEAD"),
        "dirty": bool(_git(repo, "status", "--porcelain", "--untracked-files=no")),
        "scenes_root": str(scenes_root), "casmbd": probe[0] if probe else "",
        "versions": dict(zip(("casadi", "numpy", "scipy", "python"), probe[1:])),
        "runs": sum(counts.values()), "runs_by_analysis": dict(counts),
        "wall_seconds": wall, "last_only": only,
        "case_seconds": times,
    }
    (out_dir / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    outcomes = defaultdict(int)
    for case in all_cases:
        with np.load(out_dir / f"{case['id']}.npz") as data:
            outcomes[json.loads(str(data["text/outcome"]))] += 1
    print(f"recorded {len(all_cases)} runs of {repo} ({manifest['commit'][:7]}"
          f"{', dirty' if manifest['dirty'] else ''}) into {out_dir} in {took:.0f} s: "
          + ", ".join(f"{n} {k}" for k, n in sorted(outcomes.items())))
    print(f"{out_dir} holds {sum(counts.values())} runs: "
          + ", ".join(f"{k} {n}" for k, n in counts.items()))
    return 0


# ======================================================================== comparison
def _load(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def _array_difference(a: np.ndarray, b: np.ndarray) -> str | None:
    """None when identical (NaN equal to NaN), else how they differ."""
    if a.shape != b.shape:
        return f"shape {a.shape} vs {b.shape}"
    if a.dtype.kind in "biufc" and b.dtype.kind in "biufc":
        if np.array_equal(a, b, equal_nan=a.dtype.kind in "fc" and b.dtype.kind in "fc"):
            return None
        x, y = a.astype(complex if "c" in a.dtype.kind + b.dtype.kind else float), \
            b.astype(complex if "c" in a.dtype.kind + b.dtype.kind else float)
        nan = np.isnan(x) != np.isnan(y)
        both = ~(np.isnan(x) | np.isnan(y))
        diff = np.abs(x - y)[both]
        scale = np.maximum(np.abs(x), np.abs(y))[both]
        abs_d = float(diff.max()) if diff.size else 0.0
        rel = diff / np.where(scale > 0, scale, 1.0)
        rel_d = float(rel.max()) if rel.size else 0.0
        return (f"max abs {abs_d:.3g}, max rel {rel_d:.3g}"
                + (f", NaN in one only at {int(nan.sum())} entries" if nan.any() else ""))
    if a.dtype != b.dtype or not np.array_equal(a, b):
        return "text differs"
    return None


def _text_difference(a: str, b: str) -> str:
    try:
        x, y = json.loads(a), json.loads(b)
    except ValueError:
        return "text differs"
    if isinstance(x, dict) and isinstance(y, dict):
        keys = sorted(k for k in set(x) | set(y) if x.get(k, "<absent>") != y.get(k, "<absent>"))
        return "keys " + ", ".join(
            f"{k}: {json.dumps(x.get(k, '<absent>'))[:60]} vs "
            f"{json.dumps(y.get(k, '<absent>'))[:60]}" for k in keys[:6]) + \
            (f" (+{len(keys) - 6} more)" if len(keys) > 6 else "")
    return f"{json.dumps(x)[:100]} vs {json.dumps(y)[:100]}"


def _rooted(text: str) -> str:
    """``text`` with both path tokens as one: a record made with the scenes of another tree
    (``<scenes>``) and one made in the checkout itself (``<casmbd>``) name the same files."""
    return text.replace("<scenes>", "<root>").replace("<casmbd>", "<root>")


def compare_runs(a: dict[str, np.ndarray], b: dict[str, np.ndarray],
                 ignore: list[str]) -> list[tuple[str, str]]:
    """Differences between two runs: (key, how), empty when identical."""
    out = []
    for key in sorted(set(a) | set(b)):
        if any(fnmatch.fnmatch(key, pat) for pat in ignore):
            continue
        if key not in a or key not in b:
            out.append((key, "only in " + ("A" if key in a else "B")))
            continue
        if key.startswith("array/"):
            how = _array_difference(a[key], b[key])
        else:  # a path under the scene root or the checkout: the same file either way
            ta, tb = (_rooted(str(x[key])) for x in (a, b))
            how = None if ta == tb else _text_difference(ta, tb)
        if how:
            out.append((key, how))
    return out


def compare(dir_a: Path, dir_b: Path, ignore: list[str], details: int = 40) -> int:
    """Compare two records; print the table; 1 on any difference, missing or extra run."""
    ids_a = {p.stem for p in dir_a.glob("*.npz") if not p.name.endswith(".tmp.npz")}
    ids_b = {p.stem for p in dir_b.glob("*.npz") if not p.name.endswith(".tmp.npz")}
    rows: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    different: dict[str, list] = {}
    outcome = defaultdict(int)
    for run in sorted(ids_a | ids_b):
        a = _load(dir_a / f"{run}.npz") if run in ids_a else None
        b = _load(dir_b / f"{run}.npz") if run in ids_b else None
        case = json.loads(str((a or b)["text/case"]))
        row = rows[case["analysis"]]
        if a is None:
            row["extra"] += 1
            continue
        if b is None:
            row["missing"] += 1
            continue
        diffs = compare_runs(a, b, ignore)
        if diffs:
            row["different"] += 1
            different[run] = diffs
        else:
            row["identical"] += 1
            outcome[json.loads(str(a["text/outcome"]))] += 1
    cols = ("identical", "different", "missing", "extra")
    print(f"A = {dir_a}\nB = {dir_b}" + (f"\nignored keys: {', '.join(ignore)}" if ignore
                                          else ""))
    for name, d in (("A", dir_a), ("B", dir_b)):
        man = d / "manifest.json"
        if man.exists():
            m = json.loads(man.read_text())
            print(f"{name}: {m.get('repo')} {m.get('commit', '')[:7]}"
                  f"{' (dirty)' if m.get('dirty') else ''}, {m.get('versions')}")
    print(f"\n{'analysis':<22}" + "".join(f"{c:>11}" for c in cols))
    total = defaultdict(int)
    for name in sorted(rows):
        print(f"{name:<22}" + "".join(f"{rows[name][c]:>11}" for c in cols))
        for c in cols:
            total[c] += rows[name][c]
    print(f"{'total':<22}" + "".join(f"{total[c]:>11}" for c in cols))
    print("identical runs by outcome: " + ", ".join(f"{n} {k}" for k, n in
                                                    sorted(outcome.items())))
    if different:
        keys = defaultdict(int)
        for diffs in different.values():
            for key, _ in diffs:
                keys[key] += 1
        print("\ndiffering entries (runs): " + ", ".join(
            f"{k} ({n})" for k, n in sorted(keys.items(), key=lambda x: -x[1])))
    for k, (run, diffs) in enumerate(different.items()):
        if k == details:
            print(f"\n... {len(different) - details} more differing runs (--details N)")
            break
        print(f"\n{run}:")
        for key, how in diffs:
            print(f"  {key}: {how}")
    for label, ids in (("missing in B", ids_a - ids_b), ("extra in B", ids_b - ids_a)):
        if ids:
            print(f"\n{label} ({len(ids)}): " + ", ".join(sorted(ids)[:20])
                  + (", ..." if len(ids) > 20 else ""))
    bad = total["different"] + total["missing"] + total["extra"]
    print(f"\n{'IDENTICAL' if not bad else 'DIFFERENT'}: {total['identical']} of "
          f"{sum(total.values())} runs identical")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--record", metavar="DIR", type=Path,
                      help="record the comparison set into DIR")
    what.add_argument("--compare", nargs=2, metavar=("DIR_A", "DIR_B"), type=Path,
                      help="compare two records")
    what.add_argument("--list", action="store_true", help="print the case ids and counts")
    what.add_argument("--worker", nargs=2, metavar=("CASES", "DIR"), type=Path,
                      help=argparse.SUPPRESS)
    parser.add_argument("--repo", type=Path, default=ROOT,
                        help="checkout whose casmbd package runs the set (default: this one)")
    parser.add_argument("--scenes-root", type=Path, default=ROOT,
                        help="checkout whose scene files make the set (default: this one)")
    parser.add_argument("--only", action="append", metavar="GLOB",
                        help="record again only the case ids matching, keep the other runs "
                        "of DIR (repeatable)")
    parser.add_argument("--ignore", action="append", default=[], metavar="KEY_GLOB",
                        help="leave out keys matching, e.g. 'text/warnings' (repeatable)")
    parser.add_argument("--details", type=int, default=40, metavar="N",
                        help="list the differences of at most N runs (default 40)")
    args = parser.parse_args(argv)
    scenes_root = args.scenes_root.resolve()
    if args.worker:
        return worker(args.worker[0], args.worker[1], scenes_root)
    if args.list:
        counts = defaultdict(int)
        for case in cases(scenes_root):
            print(case["id"])
            counts[case["analysis"]] += 1
        print(dict(counts), sum(counts.values()), file=sys.stderr)
        return 0
    if args.record:
        return record(args.record.resolve(), args.repo.resolve(), scenes_root, args.only)
    return compare(args.compare[0], args.compare[1], args.ignore, args.details)


if __name__ == "__main__":
    sys.exit(main())
