"""Figures quoted in README.md and docs/*.md, generated from ``benchmarks/results/``.

A quoted figure sits in a generated span ``<!-- fig:name -->…<!-- /fig -->``
(:data:`benchmarks.docs.SPAN`); its text is :func:`render` of ``name``, computed from the
results file the benchmark that measured it wrote (:data:`FIGURES`: the file, the command
that writes it, the function that renders it).  ``python -m benchmarks.figures`` rewrites
every span of :data:`PAGES`; tests/docs/test_readme_figures.py checks that every span equals
its results file, so a re-measured benchmark whose figures were not regenerated fails the
test (issue 36 item 2).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

from benchmarks.docs import replace_spans, spans

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
#: pages whose generated spans :func:`main` rewrites (and the test checks)
PAGES = (ROOT / "README.md", ROOT / "docs" / "flexible.md")


def _load(name: str) -> dict:
    return json.loads((RESULTS / name).read_text(encoding="utf-8"))


def _sci(x: float) -> str:
    """``7.7e-7`` (one decimal, no zero padding of the exponent)."""
    mantissa, exponent = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _g(x: float) -> str:
    """``2.5e-6`` (``%g`` without zero padding of the exponent)."""
    text = f"{x:g}"
    if "e" not in text:
        return text
    mantissa, exponent = text.split("e")
    return f"{mantissa}e{int(exponent)}"


def _ms(seconds: float) -> str:
    return f"{seconds:.2f} s" if seconds >= 1.0 else f"{1e3 * seconds:.0f} ms"


def pinocchio_per_call(data: dict) -> str:
    """casmbd's ``forward_dynamics`` per call over ``pinocchio.aba`` on the UR5 URDF."""
    model = next(m for m in data["models"] if m["model"] == "ur5_arm.urdf")
    row = next(r for r in model["rows"] if r["method"] == "forward dynamics")
    return f"{row['casmbd_us'] / row['pinocchio_us']:.1f}×"


def flexible_agreement(data: dict) -> str:
    """Largest difference of Exudyn's FFRF and casmbd's linear tip deflection (same modes)."""
    ffrf = data["spinup"]["omega_2"]["exudyn_ffrf_10"]
    return f"{_sci(ffrf['max_diff_casmbd_linear_10_npz'])} m"


def _time_to_error(data: dict, level: str) -> tuple[float | None, float | None]:
    best = data["slider_crank"]["time_to_error"][level]
    if isinstance(best.get("casmbd"), dict):  # results written before the fair rules
        best = {k: (v["seconds"] if v else None) for k, v in best.items()}
    return best.get("casmbd"), best.get("exudyn")


def flexible_speedup(data: dict) -> str:
    """Exudyn / casmbd time to a 1e-6 m mid-span deflection error (slider-crank)."""
    ours, theirs = _time_to_error(data, "1e-06")
    return f"{theirs / ours:.0f}×" if ours and theirs else "— (not reached)"


def flexible_time_to_error(data: dict) -> str:
    """The time-to-error table of docs/flexible.md (interpolated log-log, fair rules)."""
    lines = ["", "| error ≤ | casmbd (default path) | Exudyn | Exudyn / casmbd |",
             "|---|---|---|---|"]
    for level in data["slider_crank"]["time_to_error"]:
        ours, theirs = _time_to_error(data, level)
        ratio = f"{theirs / ours:.1f}" if ours and theirs else "—"
        label = _sci(float(level)).replace(".0e", "e")
        lines.append(f"| {label} m | {_ms(ours) if ours else 'not reached'} | "
                     f"{_ms(theirs) if theirs else 'not reached'} | {ratio} |")
    return "\n".join(lines) + "\n"


def flexible_convergence(data: dict) -> str:
    """Exudyn's three finest mid-span deflection errors and their step sizes."""
    rows = sorted((r for r in data["slider_crank"]["rows"] if r["code"] == "exudyn"),
                  key=lambda r: -r["h"])[-3:]
    errs = ", ".join(_sci(r["err_deflection"]) for r in rows)
    steps = ", ".join(_g(r["h"]) for r in rows)
    return f"{errs} m at h = {steps} s"


def chain100_cache(data: dict) -> str:
    """Cold build and cached second process of the 100-rod chain on the default path."""
    row = next(r for r in data["rows"] if r["config"] == "joint_aba" and r["n"] == 100
               and r.get("variant", "O2") == "O2")
    return f"{row['build_wall_s']:.1f} s, then {row['second_run_s']:.2f} s"


def c_export_ratio(data: dict) -> str:
    """The range over robots of the exported C's time per call over Pinocchio C++'s
    (inverse dynamics / ``rnea``, forward dynamics / ``aba``)."""
    ratios = [r["casmbd_ns"][ours] / r["pinocchio_cpp_ns"][theirs] for r in data["robots"]
              for ours, theirs in (("inverse_dynamics", "rnea"), ("forward_dynamics", "aba"))
              if r.get("pinocchio_cpp_ns")]
    return f"{min(ratios):.2f}–{max(ratios):.2f}×"


def bicycle_table2(data: dict) -> str:
    """Largest distance of the bicycle's eigenvalues from Meijaard et al.'s Table 2."""
    return _sci(data["table2_max_deviation"])


def bicycle_speeds(data: dict) -> str:
    """Largest distance of the weave and capsize speeds from the paper's."""
    return _sci(max(data["weave_speed_deviation"], data["capsize_speed_deviation"]))


#: name -> (results file, command that writes it, renderer)
FIGURES: dict[str, tuple[str, str, Callable[[dict], str]]] = {
    "pinocchio_per_call": ("numeric_api.json", "python -m benchmarks.numeric_api "
                           "--update-docs", pinocchio_per_call),
    "flexible_agreement": ("flexible_exudyn.json", "python -m benchmarks.flexible_exudyn "
                           "--update-docs", flexible_agreement),
    "flexible_speedup": ("flexible_exudyn.json", "python -m benchmarks.flexible_exudyn "
                         "--update-docs", flexible_speedup),
    "flexible_time_to_error": ("flexible_exudyn.json", "python -m benchmarks.flexible_exudyn "
                               "--update-docs", flexible_time_to_error),
    "flexible_convergence": ("flexible_exudyn.json", "python -m benchmarks.flexible_exudyn "
                             "--update-docs", flexible_convergence),
    "chain100_cache": ("scaling.json", "python -m benchmarks.scaling --update-docs",
                       chain100_cache),
    "c_export_ratio": ("c_export_speed.json", "python -m benchmarks.c_export_speed "
                       "--update-docs", c_export_ratio),
    "bicycle_table2": ("bicycle_root_locus.json", "python -m benchmarks.bicycle_root_locus",
                       bicycle_table2),
    "bicycle_speeds": ("bicycle_root_locus.json", "python -m benchmarks.bicycle_root_locus",
                       bicycle_speeds),
}


def render(name: str) -> str:
    """The text of the span ``name`` from its results file."""
    results, _, fn = FIGURES[name]
    return fn(_load(results))


def main(argv=None) -> int:
    """Rewrite the generated spans of :data:`PAGES` (``--check``: only report stale ones)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if a span differs from its results file, write nothing")
    args = parser.parse_args(argv)
    stale = []
    for page in PAGES:
        if args.check:
            text = page.read_text(encoding="utf-8")
            stale += [f"{page.name}:{n}" for n, t in spans(text) if render(n) != t]
        else:
            for name in replace_spans(page, render):
                print(f"{page.relative_to(ROOT)}: {name} regenerated from "
                      f"benchmarks/results/{FIGURES[name][0]}")
    if stale:
        print("stale figures: " + ", ".join(stale), file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
