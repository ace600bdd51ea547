"""Figures quoted in README.md and docs/flexible.md equal their results files (issue 36 item 2).

Every generated span ``<!-- fig:name -->…<!-- /fig -->`` must (1) name a figure of
benchmarks/figures.py, (2) read exactly what that figure renders from its results file in
benchmarks/results/, number for number.  A benchmark re-run without
``python -m benchmarks.figures`` fails here; so does a figure edited by hand.
"""

from __future__ import annotations

import re

import pytest

from benchmarks import figures
from benchmarks.docs import spans

NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def _numbers(text: str) -> list[float]:
    return [float(x) for x in NUMBER.findall(text)]


@pytest.mark.parametrize("page", figures.PAGES, ids=lambda p: p.name)
def test_every_quoted_figure_equals_its_results_file(page):
    found = spans(page.read_text(encoding="utf-8"))
    assert found, f"{page.name} has no generated figure spans"
    for name, text in found:
        assert name in figures.FIGURES, f"{page.name}: unknown figure {name!r}"
        want = figures.render(name)
        # the numbers first (the message names the figure and the results file), then the text
        assert _numbers(text) == _numbers(want), (
            f"{page.name}: figure {name} reads {text.strip()!r}, benchmarks/results/"
            f"{figures.FIGURES[name][0]} gives {want.strip()!r}; run "
            f"`{figures.FIGURES[name][1]}` or `python -m benchmarks.figures`")
        assert text == want, f"{page.name}: figure {name}: {text!r} != {want!r}"
        assert _numbers(text), f"{page.name}: figure {name} quotes no number"


def test_readme_quotes_the_stale_figures_of_issue_36_only_through_spans():
    # the figures issue 36 found stale must not appear outside a generated span again
    text = (figures.ROOT / "README.md").read_text(encoding="utf-8")
    outside = re.sub(r"<!-- fig:[a-z0-9_]+ -->.*?<!-- /fig -->", "", text, flags=re.S)
    for phrase in ("100-rod chain: ", "error 48×", "0.6× `pinocchio.aba`"):
        assert phrase not in outside
    for name in ("chain100_cache", "flexible_speedup", "flexible_agreement",
                 "pinocchio_per_call"):
        assert f"<!-- fig:{name} -->" in text


def test_span_rewriting_replaces_only_the_span(tmp_path):
    from benchmarks.docs import replace_spans

    page = tmp_path / "p.md"
    page.write_text("a <!-- fig:x -->1.0<!-- /fig --> b <!-- fig:y -->2<!-- /fig -->\n")
    changed = replace_spans(page, {"x": "3.5", "y": "2"}.__getitem__)
    assert changed == ["x"]
    assert page.read_text() == "a <!-- fig:x -->3.5<!-- /fig --> b <!-- fig:y -->2<!-- /fig -->\n"
