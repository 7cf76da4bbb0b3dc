"""A sweep's pages for people and CI, from its rows (plain dicts: rig/sweep/work.py's): summary.html
(pass rate against each varied key, each measurement's distribution against its limits as an inline
SVG histogram, the worst runs linked to their own reports) and junit.xml (a testcase per variant)."""

from __future__ import annotations

import html
import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from typing import Any

from rig.reports.html_report import _page

#: a varied key with more distinct values than this (random mode) is shown in quantile bins
MAX_LEVELS = 12
BINS = 8
WORST = 15
HIST_W, HIST_H, HIST_BINS = 360, 120, 24


def label(row: dict[str, Any]) -> str:
    """A variant by what makes it: its values and seed."""
    parts = [f"{k}={_text(v)}" for k, v in row["values"].items()]
    return " ".join([*parts, f"seed={row['seed']}"])


def _text(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return v if isinstance(v, str) else json.dumps(v)


def failed(row: dict[str, Any]) -> list[str]:
    return [n for n, o in row.get("outcomes", {}).items() if o == "fail"]


def worst_margin(row: dict[str, Any]) -> float:
    """How far inside its limits the run's closest measurement is, as a fraction of the limit (negative:
    outside); an error sorts first."""
    if row["verdict"] not in ("pass", "fail"):
        return -math.inf
    worst = math.inf
    for name, (lo, hi) in row.get("limits", {}).items():
        v = row["measurements"].get(name)
        if v is None:
            continue
        for limit, inside in (
            (hi, (hi - v) if hi is not None else None),
            (lo, (v - lo) if lo is not None else None),
        ):
            if limit is not None and inside is not None:
                worst = min(worst, inside / max(abs(limit), 1e-9))
    return worst


# ---------------------------------------------------------------- junit


def junit(
    rows: Sequence[dict[str, Any]], scenario: str, not_run: int = 0, dut: dict[str, Any] | None = None
) -> str:
    """``dut``: the sweep's DUT (rig/sweep/store.py's dut_identity), the suite's properties."""
    root = ET.Element("testsuites", name="rig sweep")
    fails = sum(r["verdict"] == "fail" for r in rows)
    errors = sum(r["verdict"] not in ("pass", "fail") for r in rows)
    suite = ET.SubElement(
        root,
        "testsuite",
        name=f"sweep {scenario}",
        tests=str(len(rows) + not_run),
        failures=str(fails),
        errors=str(errors),
        skipped=str(not_run),
        time=f"{sum(float(r.get('wall_s') or 0) for r in rows):.3f}",
    )
    if dut:
        props = ET.SubElement(suite, "properties")
        for k, v in dut.items():
            ET.SubElement(props, "property", name=k, value=str(v))
    for r in rows:
        case = ET.SubElement(
            suite,
            "testcase",
            classname=f"sweep.{scenario}",
            name=label(r),
            time=f"{float(r.get('wall_s') or 0):.3f}",
        )
        if r["verdict"] == "fail":
            names = failed(r)
            text = "\n".join(
                f"{n} = {r['measurements'].get(n)}; limits {r.get('limits', {}).get(n)}" for n in names
            )
            ET.SubElement(case, "failure", message="; ".join(names)).text = text
        elif r["verdict"] != "pass":
            ET.SubElement(case, "error", message=str(r.get("error") or r["verdict"]))
        ET.SubElement(case, "system-out").text = f"runs/{r['id']}/report.html"
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# ---------------------------------------------------------------- summary


def _levels(rows: Sequence[dict[str, Any]], key: str) -> list[tuple[str, list[dict[str, Any]]]]:
    """The key's values, each with its runs; numbers with many values in quantile bins."""
    values = [r["values"].get(key) for r in rows]
    distinct = {json.dumps(v, sort_keys=True) for v in values}
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
    if len(distinct) <= MAX_LEVELS or not numeric:
        order = sorted(distinct, key=lambda s: json.loads(s) if numeric else s)
        return [
            (_text(json.loads(s)), [r for r in rows if json.dumps(r["values"].get(key), sort_keys=True) == s])
            for s in order
        ]
    ranked = sorted(rows, key=lambda r: r["values"][key])
    out = []
    for b in range(BINS):
        part = ranked[b * len(ranked) // BINS : (b + 1) * len(ranked) // BINS]
        if part:
            lo, hi = part[0]["values"][key], part[-1]["values"][key]
            out.append((f"{lo:.4g} … {hi:.4g}", part))
    return out


def _rate_table(rows: Sequence[dict[str, Any]], key: str) -> str:
    e = html.escape
    lines = [
        f"<h3>pass rate against <code>{e(key)}</code></h3><table><tr><th>{e(key)}</th><th>runs</th>"
        "<th>pass</th><th>fail</th><th>error</th><th>pass rate</th></tr>"
    ]
    for text, part in _levels(rows, key):
        n = len(part)
        p = sum(r["verdict"] == "pass" for r in part)
        f = sum(r["verdict"] == "fail" for r in part)
        rate = p / n if n else 0.0
        bar = (
            f'<span class="bar" style="display:inline-block;background:#2ca02c;height:0.8em;'
            f'width:{rate * 120:.0f}px"></span>'
        )
        lines.append(
            f"<tr><td>{e(text)}</td><td>{n}</td><td>{p}</td><td>{f}</td><td>{n - p - f}</td>"
            f"<td>{bar} {rate:.0%}</td></tr>"
        )
    return "".join(lines) + "</table>"


def histogram(values: Sequence[float], lo: float | None, hi: float | None, title: str) -> str:
    """An inline SVG histogram of ``values`` with the limits as red lines."""
    e = html.escape
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return f'<figure class="hist"><figcaption>{e(title)}: nothing measured</figcaption></figure>'
    a, b = min(finite), max(finite)
    for limit in (lo, hi):
        if limit is not None and math.isfinite(limit):
            a, b = min(a, limit), max(b, limit)
    if b - a < 1e-12:
        a, b = a - 0.5, b + 0.5
    pad = (b - a) * 0.05
    a, b = a - pad, b + pad
    counts = [0] * HIST_BINS
    for v in finite:
        counts[min(HIST_BINS - 1, int((v - a) / (b - a) * HIST_BINS))] += 1
    top = max(counts)
    x = lambda v: 4 + (v - a) / (b - a) * (HIST_W - 8)  # noqa: E731
    bw = (HIST_W - 8) / HIST_BINS
    bars = "".join(
        f'<rect x="{4 + i * bw:.1f}" y="{HIST_H - 18 - c / top * (HIST_H - 30):.1f}" width="{bw - 1:.1f}" '
        f'height="{c / top * (HIST_H - 30):.1f}" fill="#1f77b4"/>'
        for i, c in enumerate(counts)
        if c
    )
    marks = "".join(
        f'<line x1="{x(v):.1f}" x2="{x(v):.1f}" y1="4" y2="{HIST_H - 18}" stroke="#d62728" stroke-width="2">'
        f"<title>{e(name)} {v:g}</title></line>"
        for name, v in (("min", lo), ("max", hi))
        if v is not None and math.isfinite(v)
    )
    axis = (
        f'<text x="4" y="{HIST_H - 4}" font-size="11">{a:.4g}</text>'
        f'<text x="{HIST_W - 4}" y="{HIST_H - 4}" font-size="11" text-anchor="end">{b:.4g}</text>'
    )
    return (
        f'<figure class="hist"><svg viewBox="0 0 {HIST_W} {HIST_H}" width="{HIST_W}" height="{HIST_H}" '
        f'role="img" aria-label="{e(title)}">{bars}{marks}{axis}</svg>'
        f"<figcaption>{e(title)} ({len(finite)} runs)</figcaption></figure>"
    )


def _dut(rows: Sequence[dict[str, Any]], info: dict[str, Any]) -> str:
    """What flew the runs: the sweep's DUT and its hash, and the runs a rebuilt one flew, if any."""
    e = html.escape
    sha = info.get("dut_sha256")
    text = (
        f"<p>DUT: <code>{e(str(info.get('dut_command')))}</code>, SHA-256 "
        + (f"<code>{e(sha)}</code>" if sha else "none (not hashed)")
        + (f" (of {e(str(info['dut_firmware']))})" if info.get("dut_firmware") else "")
        + ".</p>"
    )
    others = sorted({str(r.get("dut_sha256")) for r in rows if r.get("dut_sha256") != sha})
    if others:
        n = sum(r.get("dut_sha256") != sha for r in rows)
        text += (
            f"<p><strong>{n} runs flew another build</strong> (SHA-256 "
            + ", ".join(f"<code>{e(o)}</code>" for o in others)
            + "): the DUT changed during the sweep.</p>"
        )
    return text


def summary(rows: Sequence[dict[str, Any]], info: dict[str, Any], keys: Sequence[str]) -> str:
    """The page: ``info`` says what the sweep was (scenario, mode, engine, counts of runs not done, the
    DUT: rig/sweep/store.py's dut_identity)."""
    e = html.escape
    n = len(rows)
    counts = {v: sum(r["verdict"] == v for r in rows) for v in ("pass", "fail")}
    errors = n - counts["pass"] - counts["fail"]
    parts = [
        f"<h1>Sweep of {e(str(info.get('scenario')))}</h1>",
        f"<p>{n} of {info.get('total', n)} runs done: {counts['pass']} pass, {counts['fail']} fail, "
        f"{errors} error; {e(str(info.get('mode')))} over {len(keys)} key(s) and "
        f"{info.get('seeds', 0)} seed(s), on {e(str(info.get('engine')))}. "
        f'The table: <a href="runs.parquet">runs.parquet</a>; CI: <a href="junit.xml">junit.xml</a>.</p>',
    ]
    parts.append(_dut(rows, info))
    if info.get("not_done"):
        parts.append(
            f"<p><strong>{info['not_done']} runs not done</strong> (interrupted: the same spec into the "
            "same folder runs only those).</p>"
        )
    for key in keys:
        parts.append(_rate_table(rows, key))
    parts.append("<h2>Measurements against their limits</h2>")
    names: list[str] = []
    for r in rows:
        names += [m for m in r.get("measurements", {}) if m not in names]
    for name in names:
        lim = next((r["limits"][name] for r in rows if name in r.get("limits", {})), [None, None])
        values = [r["measurements"].get(name) for r in rows if r["verdict"] in ("pass", "fail")]
        parts.append(histogram([v if v is not None else math.nan for v in values], lim[0], lim[1], name))
    worst = sorted(rows, key=worst_margin)[:WORST]
    parts.append(
        "<h2>The worst runs</h2><table><tr><th>run</th><th>verdict</th><th>closest to a limit</th>"
        "<th>failed</th></tr>"
    )
    for r in worst:
        m = worst_margin(r)
        margin = "—" if not math.isfinite(m) else f"{m:+.1%}"
        what = "; ".join(failed(r)) or (r.get("error") or "")
        parts.append(
            f'<tr><td><a href="runs/{e(r["id"])}/report.html">{e(label(r))}</a></td>'
            f'<td class="{e(r["verdict"])}">{e(r["verdict"].upper())}</td><td>{margin}</td>'
            f"<td>{e(what)}</td></tr>"
        )
    parts.append("</table>")
    return _page(f"Sweep of {info.get('scenario')}", "\n".join(parts))
