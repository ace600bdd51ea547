"""Start-up cost: ``import casmbd`` and ``casmbd info`` on a cached scene (issue 22, item 6).

Each figure is the fastest of ``--repeat`` fresh processes (the machine is shared; the fastest
run is the one least disturbed).  *import* is measured inside the child (``time.perf_counter``
around the import statement, the interpreter's own start excluded); *process* is the wall time
of the whole child as the parent sees it (``python -c …``, interpreter start included).
``casmbd info SCENE`` runs once first so that the scene's compiled library is cached, then
``--repeat`` times as ``python -m casmbd info SCENE`` (the installed ``casmbd`` script does the
same).  The children run with Python's bytecode cache (a private ``PYTHONPYCACHEPREFIX``, filled
first), as after an installation, also where the shell sets ``PYTHONDONTWRITEBYTECODE``.
*modules* counts the ``casmbd.*`` modules and all modules loaded after the statement.

Run ``python -m benchmarks.startup [--repeat 10] [--update-docs]``.
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "startup.json"
DOC = ROOT / "docs" / "performance.md"
HEAD = "## Start-up: `import casmbd` and `casmbd info`"

#: (label, statement) measured in a fresh interpreter
IMPORTS = (
    ("import casadi, numpy (baseline)", "import casadi, numpy"),
    ("import casmbd", "import casmbd"),
    ("import casmbd; casmbd.Mechanism (first use)", "import casmbd; casmbd.Mechanism"),
    ("import casmbd.cli", "import casmbd.cli"),
)
#: scenes for ``casmbd info`` (cached after a first run)
SCENES = ("examples/double_pendulum.toml", "tests/scenes/ur_like.toml")
#: the issue's targets [s]
IMPORT_TARGET, INFO_TARGET = 0.4, 1.0

_CHILD = """
import sys, time, json
t0 = time.perf_counter()
{statement}
dt = time.perf_counter() - t0
print(json.dumps({{"seconds": dt, "casmbd": sum(m.startswith("casmbd") for m in sys.modules),
                  "modules": len(sys.modules)}}))
"""


#: the children's environment: Python's bytecode cache on (in a private directory), as after
#: an installation; set by :func:`measure`
_ENV: dict = {}


def _cpu_children() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def _child(args: list[str]) -> tuple[float, str, float]:
    """Wall time, stdout and processor time (user + system) of one child process."""
    c0, t0 = _cpu_children(), time.perf_counter()
    out = subprocess.run(args, capture_output=True, text=True, check=True, cwd=ROOT,
                         timeout=300, env=_ENV or None).stdout
    return time.perf_counter() - t0, out, _cpu_children() - c0


def measure(repeat: int = 10) -> dict:
    # PYTHONDONTWRITEBYTECODE=1 (some CI and sandbox shells) would compile the ~100 casmbd
    # modules from source in every process (~0.2 s): measure what an installation gives
    _ENV.clear()
    _ENV.update({k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"})
    _ENV["PYTHONPYCACHEPREFIX"] = tempfile.mkdtemp(prefix="casmbd_pycache_")
    _child([sys.executable, "-c", "import casmbd.cli, casmbd.viz, casmbd.ocp"])  # fill it
    rows = []
    for label, statement in IMPORTS:
        runs = []
        for _ in range(repeat):
            wall, out, cpu = _child([sys.executable, "-c", _CHILD.format(statement=statement)])
            runs.append({**json.loads(out.strip().splitlines()[-1]), "process": wall,
                         "cpu": cpu})
        best = {**min(runs, key=lambda r: r["seconds"]),
                "process": min(r["process"] for r in runs), "cpu": min(r["cpu"] for r in runs)}
        rows.append({"what": label, **best})
        print(f"{label}: import {best['seconds']:.3f} s, process {best['process']:.3f} s "
              f"(CPU {best['cpu']:.3f} s), {best['casmbd']} casmbd modules, "
              f"{best['modules']} modules", flush=True)
    info = []
    for scene in SCENES:
        cmd = [sys.executable, "-m", "casmbd", "info", scene]
        _child(cmd)  # fills the cache
        runs = [_child(cmd) for _ in range(repeat)]
        wall, cpu = min(r[0] for r in runs), min(r[2] for r in runs)
        info.append({"scene": scene, "wall": wall, "cpu": cpu})
        print(f"casmbd info {scene}: {wall:.3f} s (CPU {cpu:.3f} s)", flush=True)
    return {"date": time.strftime("%Y-%m-%d"), "python": sys.version.split()[0],
            "repeat": repeat, "imports": rows, "info": info}


def markdown(data: dict) -> str:
    lines = [
        HEAD, "",
        "Written by `python -m benchmarks.startup --update-docs` "
        f"({data['date']}, Python {data['python']}, fastest of {data['repeat']} fresh "
        "processes on a shared 2-core machine, bytecode cached as after an installation). "
        "*import*: the statement timed inside the child "
        "(interpreter start excluded); *process*: the whole `python -c …` child; *casmbd "
        "modules* / *modules*: loaded after the statement. `import casmbd` loads only "
        "`casmbd.errors`: the public names (`casmbd.simulate`, `from casmbd import Mechanism`, "
        "…) import their modules on first use (PEP 562 `__getattr__` in `casmbd/__init__.py`; "
        "tests/architecture/test_startup.py checks the module list), and scipy.optimize is "
        "imported by the "
        "functions that use it; the CLI imports a verb's module when the verb runs. *CPU*: "
        "user + system time of the child (`getrusage`), the wall time it would take alone on "
        "an idle core. Target (issue 22): `import casmbd` ≤ "
        f"{IMPORT_TARGET:g} s; `casmbd info SCENE` on a cached scene ≤ {INFO_TARGET:g} s.", "",
        "| statement | import [s] | process [s] | process CPU [s] | casmbd modules | modules |",
        "|---|---:|---:|---:|---:|---:|"]
    for r in data["imports"]:
        lines.append(f"| `{r['what']}` | {r['seconds']:.3f} | {r['process']:.3f} | "
                     f"{r.get('cpu', float('nan')):.3f} | {r['casmbd']} | {r['modules']} |")
    lines += ["", "| command (cached scene) | wall [s] | CPU [s] |", "|---|---:|---:|"]
    for r in data["info"]:
        lines.append(f"| `casmbd info {r['scene']}` | {r['wall']:.3f} | "
                     f"{r.get('cpu', float('nan')):.3f} |")
    imp = next(r for r in data["imports"] if r["what"] == "import casmbd")
    worst = max(r["wall"] for r in data["info"])
    worst_cpu = max(r.get("cpu", math.nan) for r in data["info"])
    shared = "" if worst <= INFO_TARGET or not worst_cpu <= INFO_TARGET else (
        "; its processor time is within it: the wall time waited for a shared core")
    lines += ["", f"`import casmbd`: {imp['seconds']:.3f} s (target ≤ {IMPORT_TARGET:g}: "
              f"{'met' if imp['seconds'] <= IMPORT_TARGET else 'not met'}); slowest `casmbd "
              f"info` {worst:.3f} s wall, {worst_cpu:.3f} s CPU (target ≤ {INFO_TARGET:g} s "
              f"wall: {'met' if worst <= INFO_TARGET else 'not met'} in this run{shared})."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    from benchmarks.docs import run_study, study_parser

    parser = study_parser(__doc__.splitlines()[0], RESULTS)
    args = parser.parse_args(argv)
    if args.repeat == 3:  # the shared default is for solves; start-up needs more samples
        args.repeat = 10
    return run_study(args, RESULTS, lambda: measure(args.repeat), markdown, DOC, HEAD)


if __name__ == "__main__":
    raise SystemExit(main())
