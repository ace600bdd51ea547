"""Writing benchmark results into the Markdown files of docs/: one section per study."""

from __future__ import annotations

from pathlib import Path


def replace_section(path: Path, head: str, section: str, preamble: str = "") -> Path:
    """Replace the section that starts with the heading line ``head`` (up to the next ``## ``
    heading) by ``section``, or append it; other sections are kept as they are.  A missing
    file is created with ``preamble``."""
    path = Path(path)
    text = path.read_text(encoding="utf-8") if path.exists() else preamble
    if head in text:
        start = text.index(head)
        nxt = text.find("\n## ", start + len(head))
        text = text[:start] + section + (text[nxt + 1:] if nxt >= 0 else "")
    else:
        text = text.rstrip() + "\n\n" + section
    path.write_text(text, encoding="utf-8")
    return path


#: The page of the hard-case studies (issue 7) and its opening, used when it is missing.
HARD_CASES = Path(__file__).resolve().parent.parent / "docs" / "hard_cases.md"
HARD_CASES_PREAMBLE = ("# Hard cases\n\nMechanisms that break simulation codes: redundant "
                       "constraints, singular configurations, stiff mechanisms, long runs "
                       "(issue 7).\n")


def update_hard_cases(head: str, section: str, path: Path = HARD_CASES) -> Path:
    """Replace the section ``head`` of docs/hard_cases.md (re-read right before writing)."""
    return replace_section(path, head, section, HARD_CASES_PREAMBLE)


def study_parser(description: str, results: Path, repeat: bool = True,
                 slow: float | None = None):
    """The command line shared by the studies: ``--repeat``, ``--slow``, ``--update-docs`` and
    ``--render`` (rewrite the section from the stored ``results`` without running)."""
    import argparse

    parser = argparse.ArgumentParser(description=description)
    if repeat:
        parser.add_argument("--repeat", type=int, default=3)
    if slow is not None:
        parser.add_argument("--slow", type=float, default=slow,
                            help="a run slower than this [s] is not repeated")
    parser.add_argument("--update-docs", action="store_true")
    parser.add_argument("--render", action="store_true",
                        help=f"no runs: rewrite the section from {results.name}")
    return parser


def run_study(args, results: Path, measure, markdown, doc: Path, head: str) -> int:
    """The body of a study's ``main``: measure (``measure()`` -> JSON-able data, stored in
    ``results``) or, with ``--render``, reload ``results``; print the section made by
    ``markdown(data)`` and, with ``--update-docs``, write it as the section ``head`` of
    ``doc``."""
    import json
    import sys

    if args.render:
        data = json.loads(Path(results).read_text())
    else:
        data = measure()
        Path(results).parent.mkdir(parents=True, exist_ok=True)
        Path(results).write_text(json.dumps(data, indent=1))
    text = markdown(data)
    print(text)
    if args.update_docs:
        replace_section(doc, head, text)
        print(f"wrote {doc}", file=sys.stderr)
    return 0


def used(row: dict) -> str:
    """What a run actually used, from its ``res.stats`` as stored in the row: coordinates,
    formulation / integrator (``cvodes`` is CVODES' BDF)."""
    integ = "cvodes (BDF)" if row["integrator"] == "cvodes" else row["integrator"]
    return f"{row['coordinates']} coordinates, {row['formulation']} / {integ}"


def heading(label: str, rows: list[dict], chose_nothing: bool) -> str:
    """A configuration's label; for one that left choices to casmbd (``chose_nothing``), with
    what its successful runs used (:func:`used`)."""
    seen = dict.fromkeys(used(r) for r in rows if r["config"] == label and r["status"] == "ok")
    return f"{label}: {'; '.join(seen)}" if chose_nothing and seen else label


def coordinate_reason(stats: dict) -> str | None:
    """Why the run has its coordinates (``stats['coordinate_reason']``; older stats kept the
    reason under ``coordinate_choice``)."""
    return stats.get("coordinate_reason", stats.get("coordinate_choice"))


def against_fastest(mine: dict | None, top: dict | None, level: str, digits: int = 2) -> str:
    """One sentence of a hard case's default-path paragraph: the default's solve time at an
    error ``level`` (e.g. "Error ≤ 1e-06 rad") against the fastest pinned configuration (rows
    with ``solve_seconds``, ``rtol``, ``config``; ``None`` where the level was not reached)."""
    if not (mine and top):
        return f" {level}: not reached."
    return (f" {level}: {1e3 * mine['solve_seconds']:.{digits}f} ms (rtol {mine['rtol']:.0e}), "
            f"{mine['solve_seconds'] / top['solve_seconds']:.2g}× the fastest pinned "
            f"configuration ({top['config']}, {1e3 * top['solve_seconds']:.{digits}f} ms).")



#: a generated figure in README.md or docs/*.md: ``<!-- fig:name -->text<!-- /fig -->``
SPAN = r"<!-- fig:(?P<name>[a-z0-9_]+) -->(?P<text>.*?)<!-- /fig -->"


def spans(text: str) -> list[tuple[str, str]]:
    """The ``(name, text)`` of every generated span (:data:`SPAN`) in ``text``, in order."""
    import re

    return [(m["name"], m["text"]) for m in re.finditer(SPAN, text, flags=re.S)]


def replace_spans(path: Path, render) -> list[str]:
    """Rewrite every generated span of ``path`` with ``render(name)`` (a name ``render``
    does not know raises ``KeyError``); returns the names whose text changed."""
    import re

    path = Path(path)
    text = path.read_text(encoding="utf-8")
    changed = []

    def sub(m):
        new = render(m["name"])
        if new != m["text"]:
            changed.append(m["name"])
        return f"<!-- fig:{m['name']} -->{new}<!-- /fig -->"

    out = re.sub(SPAN, sub, text, flags=re.S)
    if out != text:
        path.write_text(out, encoding="utf-8")
    return changed
