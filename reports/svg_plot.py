"""Line plots as inline SVG: a few hundred lines of samples per trace need no plotting library, render
in any browser, and keep an acceptance report a single self-contained file that costs milliseconds to
write (a matplotlib figure costs about a second each)."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence

import numpy as np

W, H, LEFT, RIGHT, TOP, BOTTOM = 760, 220, 56, 110, 14, 28
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


def plot(
    title: str,
    t: np.ndarray,
    traces: Sequence[tuple[str, np.ndarray, str]],
    units: str,
    shade: np.ndarray | None = None,
    shade_label: str = "fault",
) -> str:
    """``traces``: (label, values, dash) with dash "" or e.g. "4 3"; ``shade``: a 0/1 signal whose
    1-intervals are shaded (faults, RC loss)."""
    pw, ph = W - LEFT - RIGHT, H - TOP - BOTTOM
    if not len(t):  # a run that ended before its first sample (a DUT that never started)
        return (
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" '
            f'font-family="sans-serif" font-size="11"><title>{html.escape(title)}</title>'
            f'<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#888"/>'
            f'<text x="{LEFT + pw / 2}" y="{TOP + ph / 2}" text-anchor="middle">{html.escape(title)}: '
            "nothing was recorded</text></svg>"
        )
    finite = [v[np.isfinite(v)] for _, v, _ in traces]
    vals = np.concatenate([f for f in finite if len(f)]) if any(len(f) for f in finite) else np.zeros(1)
    lo, hi = float(vals.min()), float(vals.max())
    if hi - lo < 1e-9:
        lo, hi = lo - 1, hi + 1
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    t0, t1 = float(t[0]), float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1

    def x(v: float) -> float:
        return LEFT + (v - t0) / (t1 - t0) * pw

    def y(v: float) -> float:
        return TOP + (hi - v) / (hi - lo) * ph

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" '
        f'font-family="sans-serif" font-size="11"><title>{html.escape(title)}</title>'
    ]
    if shade is not None and len(shade):
        edges = np.diff(np.concatenate([[0], (shade > 0.5).astype(int), [0]]))
        for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0], strict=True):
            xa, xb = x(t[a]), x(t[min(int(b), len(t) - 1)])
            out.append(
                f'<rect x="{xa:.1f}" y="{TOP}" width="{max(xb - xa, 1):.1f}" height="{ph}" '
                f'fill="#f4cccc"><title>{html.escape(shade_label)}</title></rect>'
            )
    out.append(f'<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#888"/>')
    for v in _ticks(lo, hi):
        out.append(
            f'<line x1="{LEFT}" x2="{LEFT + pw}" y1="{y(v):.1f}" y2="{y(v):.1f}" stroke="#eee"/>'
            f'<text x="{LEFT - 4}" y="{y(v) + 4:.1f}" text-anchor="end">{v:g}</text>'
        )
    for v in _ticks(t0, t1, 10):
        out.append(f'<text x="{x(v):.1f}" y="{H - 10}" text-anchor="middle">{v:g}</text>')
    out.append(
        f'<text x="{LEFT + pw / 2}" y="{H - 0}" text-anchor="middle">t [s]</text>'
        f'<text x="12" y="{TOP + ph / 2}" transform="rotate(-90 12 {TOP + ph / 2})" '
        f'text-anchor="middle">{html.escape(units)}</text>'
    )
    step = max(1, len(t) // 1500)
    for k, (label, values, dash) in enumerate(traces):
        colour = COLOURS[k % len(COLOURS)]
        pts, path = [], []
        for ti, vi in zip(t[::step], values[::step], strict=True):
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
        out.append(
            f'<line x1="{W - RIGHT + 8}" x2="{W - RIGHT + 26}" y1="{TOP + 8 + 16 * k}" '
            f'y2="{TOP + 8 + 16 * k}" stroke="{colour}" stroke-width="2"/>'
            f'<text x="{W - RIGHT + 30}" y="{TOP + 12 + 16 * k}">{html.escape(label)}</text>'
        )
    out.append("</svg>")
    return "".join(out)
