"""Line plots as inline SVG: a few hundred lines of samples per trace need no plotting library, render
in any browser, and keep an acceptance report a single self-contained file that costs milliseconds to
write (a matplotlib figure costs about a second each)."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence

import numpy as np

W, H, LEFT, RIGHT, TOP, BOTTOM = 760, 220, 56, 110, 14, 34
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b")


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    span = hi - lo
    step = 10 ** math.floor(math.log10(span / n)) if span > 0 else 1.0
    for m in (1, 2, 5, 10):
        if span / (step * m) <= n:
            step *= m
            break
    first = math.ceil(lo / step) * step
    return [first + k * step for k in range(int((hi - first) / step + 1e-9) + 1)]


#: Samples a trace keeps per plot: a bucket's smallest and largest of BUCKETS across the plot's
#: 594 px, so about one point per pixel column, and no peak lost (a criterion's max is on the plot)
BUCKETS = 400


def extremes(values: np.ndarray, buckets: int = BUCKETS) -> np.ndarray:
    """Indices of the samples to draw: all of them when they are few, else each bucket's smallest and
    largest finite value in time order, and a bucket's first non-finite sample (a gap stays a gap).

    The buckets as the rows of one array (the last padded with samples that are neither finite nor
    there): a loop over them cost a report about 2 ms a trace (65 ms of a sweep run's 127 ms flight),
    this about a tenth. Ties go to the first sample, as a bucket's own argmin and argmax give."""
    n = len(values)
    if n <= 2 * buckets:
        return np.arange(n)
    size = math.ceil(n / buckets)
    rows = math.ceil(n / size)
    padded = np.zeros(rows * size)
    padded[:n] = values
    is_finite = np.zeros(rows * size, dtype=bool)
    is_finite[:n] = np.isfinite(values)
    there = (np.arange(rows * size) < n).reshape(rows, size)
    vals, finite = padded.reshape(rows, size), is_finite.reshape(rows, size)
    start = np.arange(rows) * size
    gap = there & ~finite
    some_gap, some_finite = gap.any(axis=1), finite.any(axis=1)
    keep = [
        (start + gap.argmax(axis=1))[some_gap],
        (start + np.where(finite, vals, np.inf).argmin(axis=1))[some_finite],
        (start + np.where(finite, vals, -np.inf).argmax(axis=1))[some_finite],
    ]
    return np.unique(np.concatenate(keep))


def _empty(title: str) -> str:
    pw, ph = W - LEFT - RIGHT, H - TOP - BOTTOM
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" '
        f'font-family="sans-serif" font-size="11"><title>{html.escape(title)}</title>'
        f'<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#888"/>'
        f'<text x="{LEFT + pw / 2}" y="{TOP + ph / 2}" text-anchor="middle">{html.escape(title)}: '
        "nothing was recorded</text></svg>"
    )


def _range(values: Sequence[np.ndarray]) -> tuple[float, float]:
    finite = [v[np.isfinite(v)] for v in values]
    vals = np.concatenate([f for f in finite if len(f)]) if any(len(f) for f in finite) else np.zeros(1)
    lo, hi = float(vals.min()), float(vals.max())
    if hi - lo < 1e-9:
        lo, hi = lo - 1, hi + 1
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


def plot(
    title: str,
    t: np.ndarray,
    traces: Sequence[tuple[str, np.ndarray, str]],
    units: str,
    marks: Sequence[tuple[str, str, Sequence[tuple[float, float]]]] = (),
    lanes: bool = False,
) -> str:
    """``traces``: (label, values, dash) with dash "" or e.g. "4 3"; ``marks``: (label, fill colour,
    [start, end) intervals of t) shaded behind the traces and named in the legend (sensor faults, RC
    loss); ``lanes``: each trace in its own lane with its own scale, sharing the time axis."""
    if not len(t):  # a run that ended before its first sample (a DUT that never started)
        return _empty(title)
    n_lanes = len(traces) if lanes else 1
    lane_h = (H - TOP - BOTTOM) if not lanes else 70
    height = TOP + BOTTOM + lane_h * n_lanes + 6 * (n_lanes - 1)
    legend = len(traces) + len(marks)
    height = max(height, TOP + 16 * legend + 8)
    pw = W - LEFT - RIGHT
    t0, t1 = float(t[0]), float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1

    def x(v: float) -> float:
        return LEFT + (min(max(v, t0), t1) - t0) / (t1 - t0) * pw

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{height}" viewBox="0 0 {W} {height}" '
        f'font-family="sans-serif" font-size="11"><title>{html.escape(title)}</title>'
    ]
    groups = [[k] for k in range(len(traces))] if lanes else [list(range(len(traces)))]
    for lane, members in enumerate(groups):
        top = TOP + lane * (lane_h + 6)
        lo, hi = _range([traces[k][1] for k in members])

        def y(v: float, top: float = top, lo: float = lo, hi: float = hi) -> float:
            return top + (hi - v) / (hi - lo) * lane_h

        for label, colour, intervals in marks:
            for a, b in intervals:
                out.append(
                    f'<rect x="{x(a):.1f}" y="{top}" width="{max(x(b) - x(a), 1):.1f}" height="{lane_h}" '
                    f'fill="{colour}"><title>{html.escape(label)}</title></rect>'
                )
        out.append(f'<rect x="{LEFT}" y="{top}" width="{pw}" height="{lane_h}" fill="none" stroke="#888"/>')
        for v in _ticks(lo, hi, 5 if not lanes else 3):
            out.append(
                f'<line x1="{LEFT}" x2="{LEFT + pw}" y1="{y(v):.1f}" y2="{y(v):.1f}" stroke="#eee"/>'
                f'<text x="{LEFT - 4}" y="{y(v) + 4:.1f}" text-anchor="end">{v:g}</text>'
            )
        for k in members:
            label, values, dash = traces[k]
            colour = COLOURS[k % len(COLOURS)]
            pts: list[str] = []
            path: list[list[str]] = []
            keep = extremes(values)
            for ti, vi in zip(t[keep], values[keep], strict=True):
                if math.isfinite(vi):
                    pts.append(f"{x(ti):.1f},{y(vi):.1f}")
                elif pts:
                    path.append(pts)
                    pts = []
            if pts:
                path.append(pts)
            for p in path:
                out.append(
                    f'<polyline fill="none" stroke="{colour}" stroke-width="1.3" '
                    f'{f"stroke-dasharray={chr(34)}{dash}{chr(34)} " if dash else ""}points="{" ".join(p)}"/>'
                )
    bottom = height - BOTTOM
    for v in _ticks(t0, t1, 10):
        out.append(f'<text x="{x(v):.1f}" y="{bottom + 14}" text-anchor="middle">{v:g}</text>')
    mid = TOP + (bottom - TOP) / 2
    out.append(
        f'<text x="{LEFT + pw / 2}" y="{height - 4}" text-anchor="middle">t [s] (sim time)</text>'
        f'<text x="12" y="{mid}" transform="rotate(-90 12 {mid})" '
        f'text-anchor="middle">{html.escape(units)}</text>'
    )
    for k, (label, _, dash) in enumerate(traces):
        colour = COLOURS[k % len(COLOURS)]
        out.append(
            f'<line x1="{W - RIGHT + 8}" x2="{W - RIGHT + 26}" y1="{TOP + 8 + 16 * k}" '
            f'y2="{TOP + 8 + 16 * k}" stroke="{colour}" stroke-width="2"'
            f"{f' stroke-dasharray={chr(34)}{dash}{chr(34)}' if dash else ''}/>"
            f'<text x="{W - RIGHT + 30}" y="{TOP + 12 + 16 * k}">{html.escape(label)}</text>'
        )
    for j, (label, colour, _) in enumerate(marks):
        k = len(traces) + j
        out.append(
            f'<rect x="{W - RIGHT + 8}" y="{TOP + 2 + 16 * k}" width="18" height="11" fill="{colour}"/>'
            f'<text x="{W - RIGHT + 30}" y="{TOP + 12 + 16 * k}">{html.escape(label)}</text>'
        )
    out.append("</svg>")
    return "".join(out)
