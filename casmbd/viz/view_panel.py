"""The side panel of the ``--html`` file (:mod:`casmbd.viz.view_html`): plots and events.

viser's scene serializer records scene messages only, so the live page's side panel (uPlot
charts, event list) cannot be recorded.  This module writes a small panel of our own that
:func:`inject_panel` places after viser's client, before ``</body>``:

* one inline SVG chart per :attr:`ViewModel.series <casmbd.viz.view_types.ViewModel.series>`
  with finite values, drawn here: the values as a polyline (at most :data:`MAX_POINTS` points:
  the first and last samples and the smallest and largest of each of ``MAX_POINTS / 2``
  equal index buckets, so that peaks survive), axes with a few round ticks, the unit in the
  title, the events as dashed vertical lines, and a red cursor line with a dot on the curve
  at the player's time;
* the events, time and label; clicking one sets the player's time to it (and pauses);
* a button that hides and shows the panel.

The player's time is read from viser's playback bar (viser/client/src/FilePlayback.tsx):
its time slider (``role="slider"``, ``aria-valuenow`` = the recording's clock, full
precision), else its time field (``input[inputmode=decimal]``, shown to 0.1 s).  The
recording's clock is the result's time minus the first output time (``data-t0``).  The page
polls it once per animation frame (``requestAnimationFrame``) and moves the cursors when it
changes.  An event's time is set by writing the time field and firing an ``input`` event, as
typing does (the player pauses); the field then has the focus, and leaving it would commit
its shown value (the time rounded to 0.1 s), so the panel takes the focus away without the
player seeing it.  The recording restarts when its time reaches its duration (viser's loop), so
an event at the last output time is set just before it.

The script is one constant string: the data reach the page only as HTML-escaped text and
numeric attributes (a series named ``<script>`` is shown as text, never run).  No network,
no WebGL: DOM and SVG only.
"""

from __future__ import annotations

import html
import itertools
import math

import numpy as np

from casmbd.viz.view_types import Series, ViewModel

#: most points drawn per series
MAX_POINTS = 1000
#: most events listed (and drawn on the charts)
MAX_EVENTS = 200
#: chart size and plot-area margins [CSS px]; the SVG is drawn at 1:1 (user unit = px)
WIDTH, HEIGHT = 300, 130
LEFT, RIGHT, TOP, BOTTOM = 54, 10, 14, 22


def subsample(values: np.ndarray, max_points: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most ``max_points`` samples of ``values`` that keep its shape: all of
    them when few enough, else the first, the last, and the arg-min and arg-max of each of
    ``(max_points - 2) // 2`` equal index buckets (min-max decimation), in time order."""
    y = np.asarray(values, float)
    n = len(y)
    if n <= max_points:
        return np.arange(n)
    buckets = max((max_points - 2) // 2, 1)
    edges = np.linspace(0, n, buckets + 1).astype(int)
    keep = [0, n - 1]
    for a, b in itertools.pairwise(edges):
        seg = y[a:b]
        finite = np.isfinite(seg)
        if b <= a or not finite.any():
            continue
        w = np.where(finite, seg, np.nan)
        keep += [a + int(np.nanargmin(w)), a + int(np.nanargmax(w))]
    return np.unique(keep)


def nice_ticks(lo: float, hi: float, count: int = 4) -> list[float]:
    """About ``count`` round tick values (1, 2, 5 x 10^k steps) within [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else []
    raw = (hi - lo) / max(count, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step - 1e-9) * step
    ticks = []
    v = first
    while v <= hi + 1e-9 * step:
        ticks.append(0.0 if abs(v) < 1e-12 * step else v)
        v = first + len(ticks) * step
    return ticks


def _y_range(y: np.ndarray) -> tuple[float, float]:
    """The plotted value range: the finite extremes padded by 5 %, or ±10 % (±1 at 0) around
    a constant."""
    lo, hi = float(np.nanmin(y)), float(np.nanmax(y))
    if hi - lo <= 1e-12 * max(abs(lo), abs(hi), 1e-300):
        pad = 0.1 * abs(lo) if lo != 0.0 else 1.0
        return lo - pad, hi + pad
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


def tick_labels(ticks: list[float]) -> tuple[list[str], str]:
    """Labels of evenly spaced ``ticks`` with as many decimals as their step needs, and an
    offset ("" or e.g. "+12.63") when the labels would be too long (a small variation on a
    large value, such as an energy conserved to 1e-6): the labels are then ``tick - offset``."""
    if len(ticks) < 2:
        return [f"{v:.4g}" for v in ticks], ""
    step = ticks[1] - ticks[0]
    big = max(abs(v) for v in ticks)
    if big >= 1e5 or big < 1e-3:
        labels = [f"{v:.3g}" for v in ticks]
    else:
        dec = max(0, -math.floor(math.log10(step) + 1e-9))
        labels = [f"{v:.{dec}f}" for v in ticks]
    if len(set(labels)) == len(labels) and max(map(len, labels)) <= 8:
        return labels, ""
    off = ticks[0]
    return [f"{v - off:.3g}" for v in ticks], f"{off:+.10g}"


def chart_svg(s: Series, times: np.ndarray, events: list[tuple[float, str]],
              dark: bool = False) -> str:
    """The SVG chart of series ``s`` on ``times`` (see the module docstring)."""
    t = np.asarray(times, float)
    y = np.asarray(s.values, float)
    tmin, tmax = float(t[0]), float(t[-1])
    span = tmax - tmin if tmax > tmin else 1.0
    pw, ph = WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM
    ylo, yhi = _y_range(y)

    def px(tv: float) -> float:
        return LEFT + (tv - tmin) / span * pw

    def py(v: float) -> float:
        return TOP + (yhi - v) / (yhi - ylo) * ph

    fg, grid = ("#ccc", "#444") if dark else ("#333", "#ddd")
    parts = [f'<svg class="cmbd-chart" width="{WIDTH}" height="{HEIGHT}" '
             f'viewBox="0 0 {WIDTH} {HEIGHT}" data-tmin="{tmin!r}" data-tmax="{tmax!r}" '
             f'data-x0="{LEFT}" data-w="{pw}" xmlns="http://www.w3.org/2000/svg">']
    ticks = nice_ticks(ylo, yhi)
    labels, offset = tick_labels(ticks)
    for v, lab in zip(ticks, labels):
        yy = py(v)
        parts.append(f'<line x1="{LEFT}" x2="{LEFT + pw}" y1="{yy:.1f}" y2="{yy:.1f}" '
                     f'stroke="{grid}"/><text x="{LEFT - 4}" y="{yy + 3:.1f}" '
                     f'text-anchor="end">{lab}</text>')
    if offset:
        parts.append(f'<text class="cmbd-offset" x="{LEFT}" y="{TOP - 4}">'
                     f"{offset}</text>")
    ticks = nice_ticks(tmin, tmax)
    labels, offset = tick_labels(ticks)
    for v, lab in zip(ticks, labels):
        xx = px(v)
        parts.append(f'<line x1="{xx:.1f}" x2="{xx:.1f}" y1="{TOP + ph}" y2="{TOP + ph + 4}" '
                     f'stroke="{fg}"/><text x="{xx:.1f}" y="{TOP + ph + 15}" '
                     f'text-anchor="middle">{lab}</text>')
    if offset:
        parts.append(f'<text x="{LEFT}" y="{HEIGHT - 1}">{offset} s</text>')
    parts.append(f'<text x="2" y="{TOP + ph + 15}">t [s]</text>')
    parts.append(f'<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" '
                 f'stroke="{fg}"/>')
    for te, _ in events[:MAX_EVENTS]:
        if tmin <= te <= tmax:
            xx = px(float(te))
            parts.append(f'<line class="cmbd-event" x1="{xx:.1f}" x2="{xx:.1f}" y1="{TOP}" '
                         f'y2="{TOP + ph}" stroke="#e8a33d" stroke-dasharray="3,3"/>')
    idx = subsample(y)
    bad = np.cumsum(~np.isfinite(y))  # a non-finite sample between two kept ones breaks
    runs, run = [], []
    for a, i in enumerate(idx):
        if not np.isfinite(y[i]) or (run and bad[i] != bad[idx[a - 1]]):
            if run:
                runs.append(run)
            run = []
        if np.isfinite(y[i]):
            run.append(f"{px(t[i]):.1f},{py(y[i]):.1f}")
    if run:
        runs.append(run)
    for r in runs:
        parts.append(f'<polyline class="cmbd-line" points="{" ".join(r)}" fill="none" '
                     'stroke="#1f77b4" stroke-width="1.5"/>')
    parts.append(f'<line class="cmbd-cursor" x1="{LEFT}" x2="{LEFT}" y1="{TOP}" '
                 f'y2="{TOP + ph}" stroke="#d62728" stroke-width="1"/>'
                 '<circle class="cmbd-dot" r="3.5" cx="-10" cy="-10" fill="#d62728"/>')
    parts.append("</svg>")
    return "".join(parts)


PANEL_CSS = """
#cmbd-panel{position:fixed;top:8px;right:8px;z-index:20;width:318px;
 max-height:calc(100vh - 72px);overflow-y:auto;padding:6px 8px;border-radius:6px;
 font:12px/1.35 system-ui,sans-serif;background:var(--cmbd-bg);color:var(--cmbd-fg);
 box-shadow:0 1px 8px rgba(0,0,0,.2)}
#cmbd-panel.cmbd-hidden{display:none}
#cmbd-toggle{position:fixed;top:8px;right:334px;z-index:21;font:12px system-ui,sans-serif;
 padding:3px 8px;border-radius:4px;border:1px solid #999;background:var(--cmbd-bg);
 color:var(--cmbd-fg);cursor:pointer}
#cmbd-toggle.cmbd-collapsed{right:8px}
#cmbd-panel h4{margin:6px 0 2px;font-size:12px;font-weight:600;word-break:break-all}
#cmbd-panel svg text{font-size:10px;fill:var(--cmbd-fg)}
#cmbd-panel ol{margin:2px 0;padding-left:22px}
#cmbd-panel button.cmbd-ev{font:inherit;padding:0 4px;margin-right:4px;cursor:pointer;
 border:1px solid #bbb;border-radius:3px;background:transparent;color:inherit}
#cmbd-panel .cmbd-note{opacity:.7;margin:2px 0}
"""

#: the panel's behaviour; a constant: no data is ever formatted into it
PANEL_JS = r"""
(function () {
  var panel = document.getElementById('cmbd-panel');
  var toggle = document.getElementById('cmbd-toggle');
  if (!panel) return;
  var t0 = parseFloat(panel.dataset.t0), dur = parseFloat(panel.dataset.duration);
  toggle.addEventListener('click', function () {
    var hide = !panel.classList.contains('cmbd-hidden');
    panel.classList.toggle('cmbd-hidden', hide);
    toggle.classList.toggle('cmbd-collapsed', hide);
    toggle.textContent = hide ? 'Show plots' : 'Hide plots';
  });
  var charts = Array.prototype.map.call(panel.querySelectorAll('svg.cmbd-chart'), function (s) {
    var pts = [];
    s.querySelectorAll('polyline.cmbd-line').forEach(function (p, k) {
      p.getAttribute('points').trim().split(/\s+/).forEach(function (xy, j) {
        var v = xy.split(',');
        pts.push([parseFloat(v[0]), parseFloat(v[1]), k > 0 && j === 0]);
      });
    });
    return {tmin: parseFloat(s.dataset.tmin), tmax: parseFloat(s.dataset.tmax),
            x0: parseFloat(s.dataset.x0), w: parseFloat(s.dataset.w), pts: pts,
            cursor: s.querySelector('.cmbd-cursor'), dot: s.querySelector('.cmbd-dot')};
  });
  function timeField() { return document.querySelector('input[inputmode="decimal"]'); }
  // the player's clock [s]: the slider's aria-valuenow (full precision), else the field
  function playerTime() {
    var s = document.querySelector('[role="slider"][aria-valuenow]');
    if (s) {
      var v = parseFloat(s.getAttribute('aria-valuenow'));
      if (isFinite(v)) return v;
    }
    var f = timeField();
    if (f) { var u = parseFloat(f.value); if (isFinite(u)) return u; }
    return null;
  }
  function yAt(pts, x) {
    if (!pts.length || x < pts[0][0] - 0.05 || x > pts[pts.length - 1][0] + 0.05) return null;
    var lo = 0, hi = pts.length - 1;
    while (hi - lo > 1) { var m = (lo + hi) >> 1; if (pts[m][0] <= x) lo = m; else hi = m; }
    var a = pts[lo], b = pts[hi];
    if (b[2] && x > a[0]) return x - a[0] < b[0] - x ? a[1] : null;
    if (b[0] <= a[0]) return a[1];
    var r = Math.min(Math.max((x - a[0]) / (b[0] - a[0]), 0), 1);
    return a[1] + r * (b[1] - a[1]);
  }
  var last = null;
  function frame() {
    var tau = playerTime();
    if (tau !== null && tau !== last) {
      last = tau;
      var t = t0 + tau;
      charts.forEach(function (c) {
        var span = c.tmax > c.tmin ? c.tmax - c.tmin : 1;
        var x = c.x0 + Math.min(Math.max((t - c.tmin) / span, 0), 1) * c.w;
        c.cursor.setAttribute('x1', x.toFixed(2));
        c.cursor.setAttribute('x2', x.toFixed(2));
        var y = yAt(c.pts, x);
        c.dot.setAttribute('cx', y === null ? -10 : x.toFixed(2));
        c.dot.setAttribute('cy', y === null ? -10 : y.toFixed(2));
      });
      panel.dataset.time = String(t);
    }
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
  // go to an event: write the player's time field as typing does (it pauses the player)
  panel.addEventListener('click', function (e) {
    var b = e.target.closest && e.target.closest('button.cmbd-ev');
    var f = timeField();
    if (!b || !f) return;
    var tau = Math.max(parseFloat(b.dataset.t) - t0, 0);
    if (dur > 0) tau = Math.min(tau, dur - 1e-6);
    var set = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, 'value').set;
    set.call(f, tau.toFixed(6));
    f.dispatchEvent(new Event('input', {bubbles: true}));
    // the field takes the focus (its caret is placed); leaving it would commit the shown
    // value (rounded to 0.1 s) as the time: leave it without telling the player
    if (document.activeElement === f) {
      var stop = function (ev) { if (ev.target === f) ev.stopImmediatePropagation(); };
      window.addEventListener('focusout', stop, true);
      window.addEventListener('blur', stop, true);
      f.blur();
      window.removeEventListener('focusout', stop, true);
      window.removeEventListener('blur', stop, true);
    }
  });
})();
"""


def panel_html(vm: ViewModel, *, dark_mode: bool = False) -> str:
    """The panel's HTML (styles, toggle button, charts, events, script), or "" when there is
    nothing to show: a single output time, or neither series nor events."""
    times = np.asarray(vm.times, float)
    if len(times) < 2 or not (vm.series or vm.events):
        return ""
    esc = html.escape
    t0 = float(times[0])
    duration = float(np.sum(np.maximum(np.diff(times), 0.0)))
    bg, fg = ("rgba(30,31,36,.93)", "#ddd") if dark_mode else ("rgba(255,255,255,.93)", "#222")
    events = [(float(t), str(lab)) for t, lab in vm.events]
    out = [f"<style>#cmbd-panel,#cmbd-toggle{{--cmbd-bg:{bg};--cmbd-fg:{fg}}}{PANEL_CSS}"
           "</style>",
           '<button id="cmbd-toggle" type="button">Hide plots</button>',
           f'<div id="cmbd-panel" data-t0="{t0!r}" data-duration="{duration!r}">']
    if vm.title:
        out.append(f"<h4>{esc(vm.title)}</h4>")
    for s in vm.series:
        label = f"{s.name} [{s.unit}]" if s.unit else s.name
        y = np.asarray(s.values, float)
        if len(y) != len(times) or not np.isfinite(y).any():
            out.append(f'<p class="cmbd-note">{esc(label)}: no finite values</p>')
            continue
        out.append(f'<div class="cmbd-plot"><h4>{esc(label)}</h4>'
                   f"{chart_svg(s, times, events, dark_mode)}</div>")
    if events:
        out.append(f"<h4>Events ({len(events)})</h4><ol>")
        for t, lab in events[:MAX_EVENTS]:
            out.append(f'<li><button class="cmbd-ev" type="button" data-t="{t!r}" '
                       f'title="go to this event">t = {t:.6g} s</button>{esc(lab)}</li>')
        out.append("</ol>")
        if len(events) > MAX_EVENTS:
            out.append(f'<p class="cmbd-note">… {len(events) - MAX_EVENTS} more</p>')
    out.append(f"</div><script>{PANEL_JS}</script>")
    return "".join(out)


def inject_panel(page: str, panel: str) -> str:
    """``page`` with ``panel`` inserted before its last ``</body>`` (after viser's client)."""
    if not panel:
        return page
    end = page.rfind("</body>")
    if end < 0:
        return page + panel
    return page[:end] + panel + page[end:]
