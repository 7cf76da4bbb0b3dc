"""report.html per run (plots of attitude against setpoint, altitude, motor commands with faults and RC
loss shaded; the criteria table; the metadata) and index.html per suite. Self-contained files: inline
SVG and CSS, no scripts, nothing fetched."""

from __future__ import annotations

import html
from collections.abc import Sequence

import numpy as np

from plant.variables import MOTORS
from reports.svg_plot import plot
from reports.values import fmt_limits, fmt_value
from scenarios.result import RunResult

STYLE = """body{font-family:sans-serif;margin:2em;max-width:60em}table{border-collapse:collapse}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}.pass{background:#d9ead3}.fail{background:#f4cccc}
.error,.interrupted{background:#fce5cd}.not-judged{color:#666}code{font-size:90%}"""


def _page(title: str, body: str) -> str:
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
        f"<style>{STYLE}</style></head><body>\n{body}\n</body></html>\n"
    )


def render(r: RunResult) -> str:
    s, e = r.signals, html.escape
    t = s["t"]
    shade = np.maximum(s["fault"], 1 - s["rc_link"])
    parts = [
        f"<h1>{e(r.scenario.name)}</h1>",
        f'<p>Verdict: <b class="{r.verdict}">{r.verdict.upper()}</b>'
        f"{' — ' + e(r.error) if r.error else ''}</p>",
    ]
    if r.scenario.description:
        parts.append(f"<p>{e(r.scenario.description)}</p>")
    parts.append(
        "<h2>Criteria</h2><table><tr><th>criterion</th><th>measurement</th><th>value</th>"
        "<th>limits</th><th>window [s]</th><th>outcome</th></tr>"
    )
    for m in r.measurements:
        parts.append(
            f'<tr class="{m.outcome.replace(" ", "-")}"><td>{e(m.name)}</td>'
            f"<td>{e(m.metric)} of <code>{e(m.signal)}</code>"
            f"</td><td>{e(fmt_value(m.value, m.units))}</td><td>{e(fmt_limits(m))}</td>"
            f"<td>{m.start:g} – {m.end:g}</td>"
            f"<td>{m.outcome}{': ' + e(m.reason) if m.reason else ''}</td></tr>"
        )
    parts.append("</table><h2>Flight</h2><p>Shaded: a sensor fault active or the RC link down.</p>")
    parts.append(
        plot(
            "roll and pitch against setpoint",
            t,
            [
                ("roll", s["roll"], ""),
                ("roll sp", s["roll_sp"], "4 3"),
                ("pitch", s["pitch"], ""),
                ("pitch sp", s["pitch_sp"], "4 3"),
                ("roll (DUT)", s["est_roll"], "1 2"),
            ],
            "deg",
            shade,
        )
    )
    parts.append(plot("yaw", t, [("yaw", s["yaw"], ""), ("yaw (DUT)", s["est_yaw"], "1 2")], "deg", shade))
    parts.append(plot("altitude", t, [("alt", s["alt"], ""), ("alt (DUT)", s["est_alt"], "1 2")], "m", shade))
    parts.append(
        plot("motor commands", t, [(f"motor {m}", s[f"pwm{m}"], "") for m in range(1, MOTORS + 1)], "µs",
             shade)
    )
    parts.append("<h2>Run</h2><table>")
    for k, v in r.metadata.items():
        parts.append(f"<tr><th>{e(k)}</th><td><code>{e(str(v))}</code></td></tr>")
    parts.append("</table>")
    if r.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{e(n)}</li>" for n in r.notes) + "</ul>")
    if r.stderr.strip():
        parts.append(
            f"<h2>DUT stderr (last lines)</h2><pre>{e(chr(10).join(r.stderr.splitlines()[-30:]))}</pre>"
        )
    return _page(r.scenario.name, "\n".join(parts))


def render_index(results: Sequence[RunResult], links: Sequence[str], not_run: Sequence[str] = ()) -> str:
    """The suite's page: one row per run of this suite, and the scenarios an interruption left unrun."""
    e = html.escape
    counts = {v: sum(r.verdict == v for r in results) for v in ("pass", "fail", "error", "interrupted")}
    summary = f"{counts['pass']} passed, {counts['fail']} failed, {counts['error']} errors of {len(results)}"
    if counts["interrupted"] or not_run:
        summary += f"; interrupted, {len(not_run)} not run"
    rows = [
        f"<h1>Scenario suite</h1><p>{summary}.</p><table><tr><th>scenario</th><th>verdict</th>"
        "<th>criteria passed</th><th>sim s</th><th>wall s</th></tr>"
    ]
    for r, link in zip(results, links, strict=True):
        ok = sum(m.outcome == "pass" for m in r.measurements)
        rows.append(
            f'<tr class="{r.verdict}"><td><a href="{e(link)}">{e(r.scenario.name)}</a></td>'
            f"<td>{r.verdict}</td><td>{ok}/{len(r.measurements)}</td>"
            f"<td>{float(r.metadata.get('sim_time') or 0):.1f}</td>"
            f"<td>{float(r.metadata.get('wall_time') or 0):.2f}</td></tr>"
        )
    for stem in not_run:
        rows.append(f'<tr class="not-judged"><td>{e(stem)}</td><td>not run</td>' + "<td></td>" * 3 + "</tr>")
    rows.append("</table>")
    return _page("Scenario suite", "\n".join(rows))
