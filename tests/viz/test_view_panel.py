"""The side panel of ``casmbd view --html`` (casmbd.viz.view_panel), without a browser: the
charts' polylines map (t, value) linearly onto the plot area (to the 0.1 px the coordinates are
written with), min-max decimation keeps at most 1000 points and every extreme, ticks are round
and inside the range, names and labels are HTML-escaped.  The page itself is tested in
headless Chromium (tests/viz/test_view_browser.py::test_html_side_panel)."""

from __future__ import annotations

import html
import re

import numpy as np
import pytest

from casmbd.viz import view_panel as vp
from casmbd.viz.view_types import Series, ViewModel


def _vm(n=51, series=None, events=()):
    t = np.linspace(0.0, 0.5, n)
    series = [Series("q", "rad", np.sin(7 * t))] if series is None else series
    return ViewModel(times=t, body_positions={}, body_wxyz={}, series=series,
                     events=list(events))


def _polylines(svg: str) -> list[np.ndarray]:
    return [np.array([[float(v) for v in xy.split(",")] for xy in pts.split()])
            for pts in re.findall(r'<polyline class="cmbd-line" points="([^"]*)"', svg)]


def test_polyline_maps_samples_linearly():
    """Every sample at x = LEFT + (t - t0) / (t1 - t0) * w, y = TOP + (hi - v) / (hi - lo) * h
    (the padded value range), to 0.05 px (coordinates written to 0.1 px)."""
    t = np.linspace(2.0, 3.0, 201)
    y = np.exp(-t) * np.cos(9 * t)
    svg = vp.chart_svg(Series("q", "m", y), t, [])
    (pts,) = _polylines(svg)
    w, h = vp.WIDTH - vp.LEFT - vp.RIGHT, vp.HEIGHT - vp.TOP - vp.BOTTOM
    lo, hi = y.min() - 0.05 * np.ptp(y), y.max() + 0.05 * np.ptp(y)
    np.testing.assert_allclose(pts[:, 0], vp.LEFT + (t - 2.0) * w, atol=0.05 + 1e-9)
    np.testing.assert_allclose(pts[:, 1], vp.TOP + (hi - y) / (hi - lo) * h, atol=0.05 + 1e-9)
    m = re.search(r'data-tmin="([^"]+)" data-tmax="([^"]+)" data-x0="(\d+)" data-w="(\d+)"', svg)
    assert (float(m[1]), float(m[2]), int(m[3]), int(m[4])) == (2.0, 3.0, vp.LEFT, w)


def test_subsample_keeps_extremes_and_at_most_1000_points():
    """5001 samples of a noisy signal with two spikes: at most 1000 kept, in time order, the
    first, the last and both spikes among them; 1000 samples or fewer are all kept."""
    rng = np.random.default_rng(1)
    y = np.cumsum(rng.normal(size=5001))
    y[1234], y[4321] = 1e3, -1e3
    idx = vp.subsample(y)
    assert len(idx) <= vp.MAX_POINTS and np.all(np.diff(idx) > 0)
    assert {0, 5000, 1234, 4321} <= set(idx.tolist())
    assert vp.subsample(y[:1000]).tolist() == list(range(1000))


def test_nan_breaks_the_line_and_empty_series_get_a_note():
    """A NaN sample splits the polyline in two (nothing drawn through it); a series without a
    finite value gets one line saying so instead of a chart."""
    t = np.linspace(0, 1, 11)
    y = t.copy()
    y[5] = np.nan
    lines = _polylines(vp.chart_svg(Series("q", "m", y), t, []))
    assert [len(p) for p in lines] == [5, 5]
    page = vp.panel_html(_vm(11, [Series("gone", "N", np.full(11, np.nan))]))
    assert "gone [N]: no finite values" in page and "<svg" not in page


@pytest.mark.parametrize("lo, hi", [(0.0, 0.5), (-2.2, 0.1), (12.630201, 12.630265),
                                    (1e6, 3e6), (0.0, 2e-5), (100.0, 100.0004)])
def test_ticks_are_round_inside_and_distinct(lo, hi):
    """2 to 8 ticks in [lo, hi], equally spaced by 1, 2 or 5 x 10^k; distinct labels (with
    an offset when the values differ only far behind the decimal point)."""
    ticks = vp.nice_ticks(lo, hi)
    assert 2 <= len(ticks) <= 8
    assert lo - 1e-12 * abs(lo) <= ticks[0] and ticks[-1] <= hi + 1e-12 * abs(hi)
    steps = np.diff(ticks)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-6)
    mant = steps[0] / 10.0 ** np.floor(np.log10(steps[0]))
    assert min(abs(mant - m) for m in (1, 2, 5, 10)) < 1e-6
    labels, offset = vp.tick_labels(ticks)
    assert len(set(labels)) == len(labels)
    if offset:
        np.testing.assert_allclose([float(x) + float(offset) for x in labels], ticks,
                                   atol=0.01 * steps[0])


def test_markup_in_names_and_labels_is_text():
    """A series name, unit, event label and title holding markup appear escaped only; the
    page holds exactly one <script> (the panel's own, constant) and no <img>."""
    evil = '<img src=x onerror="window.__pwned=1"><script>window.__pwned=2</script>'
    vm = _vm(series=[Series(evil, "<b>", np.ones(51))], events=[(0.1, evil)])
    vm.title = evil
    page = vp.panel_html(vm)
    assert page.count("<script>") == 1 and page.count("</script>") == 1
    assert "<img" not in page and "<b>" not in page
    assert html.escape(evil) in page
    assert vp.PANEL_JS in page


def test_no_panel_without_time_or_data_and_injection_point():
    """A single output time, or neither series nor events: no panel; the panel goes before
    the page's last </body>."""
    assert vp.panel_html(_vm(1)) == ""
    assert vp.panel_html(_vm(series=[])) == ""
    assert vp.panel_html(_vm(series=[], events=[(0.2, "impact")])) != ""
    page = "<html><body><p>x</p></body></html>"
    assert vp.inject_panel(page, "<i>P</i>") == "<html><body><p>x</p><i>P</i></body></html>"
    assert vp.inject_panel(page, "") == page
