"""report.html per run (plots of attitude against setpoint, altitude, motor commands with faults and RC
loss marked; the criteria table with values, limits and margins; the run's identity) and index.html per
suite. Self-contained files that fetch nothing: inline CSS, inline SVG plots (what a viewer without
JavaScript and the PDF show) and, over them, interactive uPlot charts (reports/vendor/uplot, inlined)."""

from __future__ import annotations

import html
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rig.reports import plots as plotspec
from rig.reports.svg_plot import COLOURS, plot
from rig.reports.values import (
    fmt_limits,
    fmt_margin,
    fmt_target,
    fmt_value,
    meta_rows,
    mode_text,
    outcome_class,
    outcome_text,
    sim_times_in,
)
from rig.scenarios.criteria import METRICS, Measurement
from rig.scenarios.result import RunResult

UPLOT = Path(__file__).resolve().parent / "vendor" / "uplot"

STYLE = """body{font-family:sans-serif;margin:2em;max-width:62em}table{border-collapse:collapse}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}.pass{background:#d9ead3}
.fail{background:#f4cccc}.marginal{background:#fff2cc}.error,.interrupted{background:#fce5cd}
.not-judged{color:#666}code{font-size:90%;word-break:break-all}td.num{text-align:right;white-space:nowrap}
.small{font-size:85%;color:#444}figure.plot{margin:1em 0}.plot.live>.svg{display:none}
figure.plot svg{max-width:100%;height:auto}.uplot-lane{margin:0}
@media print{.plot.live>.svg{display:block}.plot>.live-chart{display:none}}"""


def _page(title: str, body: str, head: str = "") -> str:
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
        f"<style>{STYLE}</style>{head}</head><body>\n{body}\n</body></html>\n"
    )


def measured_text(m: Measurement) -> str:
    """What the criterion measures, in words, without repeating its name (an unnamed criterion is
    named "metric of signal" already): the metric's definition, and its target and band."""
    e = html.escape
    parts = (
        [] if m.name == f"{m.metric} of {m.signal}" else [f"{e(m.metric)} of <code>{e(m.signal)}</code>: "]
    )
    parts.append(e(METRICS[m.metric].text) if m.metric in METRICS else "")
    if fmt_target(m):
        parts.append(f"; {e(fmt_target(m))}")
    return "".join(parts)


def criteria_table(measurements: Sequence[Measurement]) -> str:
    e = html.escape
    rows = [
        "<table><tr><th>criterion</th><th>measures</th><th>window [s]</th><th>value</th><th>limits</th>"
        "<th>margin</th><th>outcome</th></tr>"
    ]
    for m in measurements:
        why = m.reason if not m.marginal else ""
        rows.append(
            f'<tr class="{outcome_class(m)}"><td>{e(m.name)}</td><td>{measured_text(m)}</td>'
            f'<td class="num">{m.start:g} – {m.end:g}</td>'
            f'<td class="num">{e(fmt_value(m.value, m.units))}</td>'
            f'<td class="num">{e(fmt_limits(m))}</td><td class="num">{e(fmt_margin(m))}</td>'
            f"<td>{e(outcome_text(m))}{': ' + e(why) if why else ''}</td></tr>"
        )
    rows.append("</table>")
    return "".join(rows)


def verdict_line(r: RunResult) -> str:
    e = html.escape
    marginal = sum(m.marginal for m in r.measurements)
    extra = f" ({marginal} marginal)" if marginal and r.verdict == "pass" else ""
    return (
        f'<p>Verdict: <b class="{r.verdict}">{r.verdict.upper()}</b>{e(extra)}'
        f"{' — ' + e(r.error) if r.error else ''}</p>"
    )


def static_plots(r: RunResult) -> list[tuple[plotspec.Plot, str]]:
    """Each plot with its SVG, faults and RC loss marked (and named in the legend only when present)."""
    s = r.signals
    marks = [(m.label, m.colour, m.spans) for m in plotspec.marks(s)] if len(s["t"]) else []
    return [
        (
            p,
            plot(
                p.title,
                s["t"],
                [(tr.label, plotspec.values(s, tr), tr.dash) for tr in p.traces],
                p.units,
                marks,
                p.lanes,
            ),
        )
        for p in plotspec.plots(s)
    ]


def marks_caption(r: RunResult) -> str:
    """" Shaded: …" naming what the plots mark, or "" when the run had nothing to mark."""
    found = plotspec.marks(r.signals) if len(r.signals["t"]) else []
    return f" Shaded: {', '.join(m.label for m in found)}." if found else ""


def fc_table(meta: Mapping[str, Any]) -> str:
    fc = meta.get("fc_config")
    if not isinstance(fc, dict) or not fc:
        return ""
    e = html.escape
    return (
        "<h2>FC configuration</h2><p class=small>The reference FC's configuration file for this run "
        "(the scenario's [fc] table over the FC's defaults).</p><table>"
        + "".join(f"<tr><th>{e(str(k))}</th><td><code>{e(str(v))}</code></td></tr>" for k, v in fc.items())
        + "</table>"
    )


def run_table(r: RunResult) -> str:
    e = html.escape
    return (
        "<table>"
        + "".join(
            f"<tr><th>{e(k)}</th><td><code>{e(v)}</code></td></tr>"
            for k, v in meta_rows(r.metadata, r.verdict)
        )
        + "</table>"
    )


def stderr_tail(r: RunResult) -> str:
    if not r.stderr.strip():
        return ""
    base = r.metadata.get("dut_clock_base_s")
    text = sim_times_in("\n".join(r.stderr.splitlines()[-30:]), float(base) if base is not None else None)
    note = (
        "<p class=small>Times the DUT prints are its own clock; [sim …] beside each is the sim time "
        "the plots use.</p>"
        if base is not None
        else ""
    )
    return f"<h2>DUT stderr (last lines)</h2>{note}<pre>{html.escape(text)}</pre>"


# ---- interactive plots ---------------------------------------------------------------------------


def _column(v: np.ndarray, step: int) -> list[float | None]:
    return [round(float(x), 4) if math.isfinite(x) else None for x in v[::step]]


def chart_data(r: RunResult) -> dict[str, Any]:
    """What the page's script draws: the time axis once, each plotted signal, the plots and the marks."""
    s = r.signals
    ps = plotspec.plots(s)
    step = max(1, len(s["t"]) // 4000)
    drawn = {tr.signal: tr for p in ps for tr in p.traces}
    return {
        "t": _column(s["t"], step),
        "signals": {n: _column(plotspec.values(s, tr), step) for n, tr in sorted(drawn.items())},
        "plots": [
            {
                "key": p.key,
                "title": p.title,
                "units": p.units,
                "lanes": p.lanes,
                "traces": [
                    {
                        "label": tr.label,
                        "signal": tr.signal,
                        "colour": COLOURS[k % len(COLOURS)],
                        "dash": [float(d) for d in tr.dash.split()],
                    }
                    for k, tr in enumerate(p.traces)
                ],
            }
            for p in ps
        ],
        "marks": [{"label": m.label, "colour": m.colour, "spans": m.spans} for m in plotspec.marks(s)]
        if len(s["t"])
        else [],
    }


SCRIPT = """(function(){
var d=JSON.parse(document.getElementById('rig-data').textContent);
if(typeof uPlot==='undefined'||!d.t.length)return;
function shade(u){var c=u.ctx;d.marks.forEach(function(m){c.fillStyle=m.colour;m.spans.forEach(function(s){
var a=u.valToPos(s[0],'x',true),b=u.valToPos(s[1],'x',true);
c.fillRect(a,u.bbox.top,Math.max(b-a,1),u.bbox.height);});});}
d.plots.forEach(function(p){
var fig=document.getElementById('plot-'+p.key);if(!fig)return;
var box=document.createElement('div');box.className='live-chart';fig.appendChild(box);
var w=Math.min(760,fig.clientWidth||760);
var groups=p.lanes?p.traces.map(function(t){return [t];}):[p.traces];
groups.forEach(function(g,i){
var last=i===groups.length-1;
var el=document.createElement('div');el.className=p.lanes?'uplot-lane':'';box.appendChild(el);
var opts={width:w,height:p.lanes?(i===0?40:0)+(last?60:0)+110:260,
title:p.lanes?(i===0?p.title+' ['+p.units+']':undefined):p.title+' ['+p.units+']',
cursor:{sync:{key:'rig'}},scales:{x:{time:false}},legend:{show:!p.lanes},
padding:[null,16,null,null],
axes:[p.lanes&&!last?{show:false}:{label:'t [s] (sim time)'},
{label:p.lanes?g[0].label+' ['+p.units+']':p.units}],
series:[{label:'t [s]'}].concat(g.map(function(t){return {label:t.label,stroke:t.colour,width:1.3,
dash:t.dash.length?t.dash:undefined,spanGaps:false};})),
hooks:{drawClear:[shade]}};
var data=[d.t].concat(g.map(function(t){return d.signals[t.signal];}));
new uPlot(opts,data,el);});
fig.classList.add('live');});})();"""


def _uplot_head() -> str:
    try:
        css = (UPLOT / "uPlot.min.css").read_text()
        js = (UPLOT / "uPlot.iife.min.js").read_text()
    except OSError:  # (a stripped install: the static plots stand alone)
        return ""
    return f"<style>{css}</style><script>{js}</script>"


def _json_script(data: object) -> str:
    text = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    return f'<script type="application/json" id="rig-data">{text}</script>'


def render(r: RunResult) -> str:
    e = html.escape
    parts = [f"<h1>{e(r.scenario.name)}</h1>", verdict_line(r)]
    if r.scenario.description:
        parts.append(f"<p>{e(r.scenario.description)}</p>")
    parts.append(
        f"<p class=small>Scenario file <code>{e(str(r.metadata.get('scenario_file') or r.scenario.stem))}"
        f"</code>; {e(mode_text(r.metadata))}; seed {e(str(r.metadata.get('seed')))}; started "
        f"{e(str(r.metadata.get('started') or '—'))} UTC on {e(str(r.metadata.get('host') or '—'))}.</p>"
    )
    parts.append("<h2>Criteria</h2>" + criteria_table(r.measurements))
    parts.append(
        "<h2>Flight</h2><p class=small>Time is sim time from 0. Dashed: setpoints; dotted: what the "
        f"DUT reported; a motor's lane starts at its first pulse.{e(marks_caption(r))} Drag across a "
        "chart to zoom, double-click to zoom out.</p>"
    )
    for p, svg in static_plots(r):
        parts.append(f'<figure class="plot" id="plot-{p.key}"><div class="svg">{svg}</div></figure>')
    parts.append("<h2>Run</h2>" + run_table(r))
    parts.append(fc_table(r.metadata))
    if r.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{e(n)}</li>" for n in r.notes) + "</ul>")
    parts.append(stderr_tail(r))
    parts.append(_json_script(chart_data(r)) + f"<script>{SCRIPT}</script>")
    return _page(r.scenario.name, "\n".join(p for p in parts if p), _uplot_head())


# ---- the suite -----------------------------------------------------------------------------------

#: the suite's identity: (metadata key, label); a value the runs do not share is shown per run
IDENTITY = (
    ("started", "started (UTC)"),
    ("host", "host"),
    ("mode", "mode"),
    ("dut_command", "DUT command"),
    ("dut_firmware", "firmware"),
    ("dut_firmware_sha256", "firmware SHA-256"),
    ("seed", "random seed"),
    ("rig_version", "rig version"),
    ("plant_fmu_sha256", "plant FMU SHA-256"),
    ("airframe", "airframe"),
)


def suite_identity(results: Sequence[RunResult]) -> list[tuple[str, str]]:
    """(label, text) rows naming what was tested, how and when, from the runs' metadata."""
    rows = []
    for key, label in IDENTITY:
        if key == "mode":
            values = [mode_text(r.metadata) for r in results]
        else:
            values = [str(r.metadata[key]) for r in results if r.metadata.get(key) not in (None, "")]
        distinct = list(dict.fromkeys(values))
        if key == "started" and values:
            text = min(values)
        elif not distinct:
            text = "—"
        elif len(distinct) == 1:
            text = distinct[0]
        elif key == "dut_command":
            text = f"{distinct[0]} (and {len(distinct) - 1} more: each run's command is in its report)"
        else:
            text = "; ".join(distinct)
        rows.append((label, text))
    return rows


def render_index(
    results: Sequence[RunResult],
    links: Sequence[str],
    not_run: Sequence[str] = (),
    extra_links: Sequence[tuple[str, str]] = (("junit.xml", "JUnit XML for CI"),),
) -> str:
    """The suite's page: what was tested and how, one row per run of this suite, and the scenarios an
    interruption left unrun."""
    e = html.escape
    counts = {v: sum(r.verdict == v for r in results) for v in ("pass", "fail", "error", "interrupted")}
    marginal = sum(m.marginal for r in results for m in r.measurements)
    summary = f"{counts['pass']} passed, {counts['fail']} failed, {counts['error']} errors of {len(results)}"
    if marginal:
        summary += f"; {marginal} marginal criteria"
    if counts["interrupted"] or not_run:
        summary += f"; interrupted, {len(not_run)} not run"
    rows = [f"<h1>Scenario suite</h1><p>{summary}.</p>"]
    rows.append(
        "<table>"
        + "".join(f"<tr><th>{e(k)}</th><td><code>{e(v)}</code></td></tr>" for k, v in suite_identity(results))
        + "</table>"
    )
    if extra_links:
        rows.append(
            "<p>" + " · ".join(f'<a href="{e(href)}">{e(text)}</a>' for href, text in extra_links) + "</p>"
        )
    rows.append(
        "<table><tr><th>scenario</th><th>file</th><th>verdict</th><th>criteria passed</th>"
        "<th>marginal</th><th>sim s</th><th>wall s</th></tr>"
    )
    for r, link in zip(results, links, strict=True):
        ok = sum(m.outcome == "pass" for m in r.measurements)
        n_marginal = sum(m.marginal for m in r.measurements)
        file = Path(str(r.metadata.get("scenario_file") or f"{r.scenario.stem}.toml")).name
        rows.append(
            f'<tr class="{r.verdict}"><td><a href="{e(link)}">{e(r.scenario.name)}</a></td>'
            f"<td><code>{e(file)}</code></td><td>{r.verdict}</td><td>{ok}/{len(r.measurements)}</td>"
            f"<td>{n_marginal or ''}</td>"
            f"<td>{float(r.metadata.get('sim_time') or 0):.1f}</td>"
            f"<td>{float(r.metadata.get('wall_time') or 0):.2f}</td></tr>"
        )
    for stem in not_run:
        rows.append(
            f'<tr class="not-judged"><td>{e(stem)}</td><td></td><td>not run</td>' + "<td></td>" * 4 + "</tr>"
        )
    rows.append("</table>")
    return _page("Scenario suite", "\n".join(rows))
