"""The acceptance report: one printable HTML page (acceptance.html) that reports/pdf.py prints to
acceptance.pdf. A cover (the firmware, the rig, the mode, the date, an operator field, the overall
verdict), a summary table, one section per scenario (criteria with value, limits and margin; the plots
with faults and RC loss marked) and a traceability appendix (scenario files and their hashes, seeds,
the FC configuration). Static SVG only: nothing on paper needs a script."""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path

from rig.reports.html_report import criteria_table, marks_caption, static_plots, suite_identity
from rig.reports.values import meta_rows, mode_text, sim_times_in
from rig.scenarios.criteria import MARGINAL_PCT
from rig.scenarios.result import RunResult

PAGE = """@page{size:A4;margin:16mm 14mm 18mm 14mm;
@bottom-left{content:"Acceptance test report: TITLE";font:8pt sans-serif;color:#555}
@bottom-right{content:"page " counter(page) " of " counter(pages);font:8pt sans-serif;color:#555}}"""
STYLE = """body{font-family:"DejaVu Sans",sans-serif;font-size:9.5pt;margin:0;color:#000}
h1{font-size:22pt;margin:0 0 4mm}h2{font-size:14pt;margin:6mm 0 2mm}h3{font-size:11pt;margin:4mm 0 1mm}
table{border-collapse:collapse;width:100%;margin:1mm 0 3mm;font-size:8.5pt}
td,th{border:0.5pt solid #999;padding:2px 5px;text-align:left;vertical-align:top}
th{background:#f2f2f2}code,.hash{font-family:"DejaVu Sans Mono",monospace;font-size:8pt}
td.num{text-align:right;white-space:nowrap}.pass{background:#d9ead3}.fail{background:#f4cccc}
.marginal{background:#fff2cc}.error,.interrupted{background:#fce5cd}.not-judged{color:#555}
.small{font-size:8pt;color:#333}section.run,.appendix,.summary{break-before:page}
figure.plot{margin:1mm 0;break-inside:avoid}figure.plot svg{width:100%;height:auto}
tr{break-inside:avoid}.cover{height:240mm;display:flex;flex-direction:column}
.verdict{font-size:30pt;font-weight:bold;padding:4mm 6mm;display:inline-block;margin:6mm 0}
.sign td{height:12mm}pre{white-space:pre-wrap;font-size:7.5pt}"""


def overall(results: Sequence[RunResult], not_run: Sequence[str] = ()) -> str:
    """PASS only when every scenario ran and passed; an error or an interruption outranks a failure."""
    verdicts = {r.verdict for r in results}
    if "interrupted" in verdicts or not_run:
        return "interrupted"
    if "error" in verdicts:
        return "error"
    return "fail" if "fail" in verdicts else "pass"


def _firmware_name(results: Sequence[RunResult]) -> str:
    for r in results:
        fw = str(r.metadata.get("dut_firmware") or "")
        for prefix in ("the program ", "the script "):
            if fw.startswith(prefix):
                return Path(fw[len(prefix) :].split(" that ")[0]).name
        if fw:
            return fw
    return "unknown"


def _worst_margin(r: RunResult) -> str:
    margins = [m.margin for m in r.measurements if m.margin is not None and m.outcome == "pass"]
    return f"{min(margins):.1f} %" if margins else "—"


def render(
    results: Sequence[RunResult], not_run: Sequence[str] = (), operator: str = "", title: str = ""
) -> str:
    e = html.escape
    verdict = overall(results, not_run)
    firmware = _firmware_name(results)
    title = title or f"{firmware}"
    counts = {v: sum(r.verdict == v for r in results) for v in ("pass", "fail", "error", "interrupted")}
    marginal = sum(m.marginal for r in results for m in r.measurements)
    count_text = (
        f"{counts['pass']} of {len(results) + len(not_run)} scenarios passed, {counts['fail']} failed, "
        f"{counts['error'] + counts['interrupted']} ended in error"
        + (f", {len(not_run)} not run" if not_run else "")
        + f"; {marginal} criteria passed within {MARGINAL_PCT:g} % of a limit (marginal)"
    )
    ident = dict(suite_identity(results))
    cover = [
        '<div class="cover">',
        "<p class=small>Quadrotor hardware-in-the-loop rig</p>",
        "<h1>Acceptance test report</h1>",
        f"<h2>Firmware: {e(firmware)}</h2>",
        "<table>",
        *(
            f"<tr><th>{e(label)}</th><td class={'hash' if 'SHA' in label else ''}>{e(ident[label])}</td></tr>"
            for label in (
                "firmware",
                "firmware SHA-256",
                "DUT command",
                "rig version",
                "plant FMU SHA-256",
                "airframe",
                "mode",
                "started (UTC)",
                "host",
                "random seed",
            )
        ),
        f"<tr><th>operator</th><td>{e(operator) or '&nbsp;'}</td></tr>",
        "</table>",
        f'<div>Overall verdict: <span class="verdict {verdict}">{verdict.upper()}</span></div>',
        f"<p>{e(count_text)}.</p>",
        '<table class="sign"><tr><th style="width:25%">operator (name)</th><td>'
        f"{e(operator) or '&nbsp;'}</td></tr><tr><th>signature</th><td></td></tr>"
        "<tr><th>date</th><td></td></tr>"
        "<tr><th>customer acceptance</th><td></td></tr></table>",
        "</div>",
    ]
    summary = [
        '<div class="summary"><h2>Summary</h2><table><tr><th>scenario</th><th>file</th><th>verdict</th>'
        "<th>criteria passed</th><th>marginal</th><th>smallest margin</th><th>sim s</th></tr>"
    ]
    for r in results:
        ok = sum(m.outcome == "pass" for m in r.measurements)
        summary.append(
            f'<tr class="{r.verdict}"><td>{e(r.scenario.name)}</td>'
            f"<td><code>{e(r.scenario.path.name)}</code></td>"
            f"<td>{r.verdict.upper()}</td><td class=num>{ok}/{len(r.measurements)}</td>"
            f"<td class=num>{sum(m.marginal for m in r.measurements) or ''}</td>"
            f"<td class=num>{_worst_margin(r)}</td>"
            f"<td class=num>{float(r.metadata.get('sim_time') or 0):.1f}</td></tr>"
        )
    for stem in not_run:
        summary.append(
            f'<tr class="not-judged"><td>{e(stem)}</td><td></td><td>NOT RUN</td>' + "<td></td>" * 4 + "</tr>"
        )
    summary.append(
        "</table><p class=small>Margin: how far a value lies inside its nearer limit, in % of that "
        f"limit; a value that passes closer than {MARGINAL_PCT:g} % (or the criterion's own marginal band) "
        "is "
        "marginal. n/a: a limit of 0 or a yes/no state, which has no percentage.</p></div>"
    )
    sections = []
    for k, r in enumerate(results, 1):
        sec = [
            f'<section class="run"><h2>{k}. {e(r.scenario.name)}</h2>',
            f'<p>Verdict: <b class="{r.verdict}">{r.verdict.upper()}</b>'
            f"{' — ' + e(r.error) if r.error else ''}</p>",
        ]
        if r.scenario.description:
            sec.append(f"<p>{e(r.scenario.description)}</p>")
        sec.append(
            f"<p class=small>Scenario <code>{e(r.scenario.path.name)}</code>, SHA-256 "
            f"<span class=hash>{e(r.scenario.sha256)}</span>; {e(mode_text(r.metadata))}; seed "
            f"{e(str(r.metadata.get('seed')))}.</p>"
        )
        sec.append("<h3>Criteria</h3>" + criteria_table(r.measurements))
        sec.append(
            "<h3>Flight</h3><p class=small>Sim time from 0. Dashed: setpoints; dotted: the DUT's own "
            f"estimates; a motor's lane starts at its first pulse.{marks_caption(r)}</p>"
        )
        sec += [f'<figure class="plot">{svg}</figure>' for _, svg in static_plots(r)]
        if r.notes:
            sec.append("<h3>Notes</h3><ul>" + "".join(f"<li>{e(n)}</li>" for n in r.notes) + "</ul>")
        if r.verdict in ("error", "interrupted") and r.stderr.strip():
            base = r.metadata.get("dut_clock_base_s")
            tail = sim_times_in(
                "\n".join(r.stderr.splitlines()[-15:]), float(base) if base is not None else None
            )
            sec.append(f"<h3>DUT stderr (last lines)</h3><pre>{e(tail)}</pre>")
        sec.append("</section>")
        sections.append("".join(sec))
    appendix = [
        '<div class="appendix"><h2>Appendix: traceability</h2><h3>Scenario files</h3><table><tr><th>scenario'
        "</th><th>file and SHA-256</th><th>seed</th></tr>"
    ]
    for r in results:
        appendix.append(
            f"<tr><td>{e(r.scenario.stem)}</td><td><code>{e(str(r.scenario.path))}</code><br>"
            f"<span class=hash>{e(r.scenario.sha256)}</span></td>"
            f"<td class=num>{e(str(r.metadata.get('seed')))}</td></tr>"
        )
    appendix.append("</table>")
    appendix.append(_fc_appendix(results))
    appendix.append("<h3>Each run</h3>")
    for r in results:
        appendix.append(
            f"<h3>{e(r.scenario.stem)}</h3><table>"
            + "".join(
                f"<tr><th style='width:28%'>{e(k)}</th><td><code>{e(v)}</code></td></tr>"
                for k, v in meta_rows(r.metadata, r.verdict)
            )
            + "</table>"
        )
    appendix.append("</div>")
    css_title = "".join(c if c.isalnum() or c in " ._-+()" else " " for c in title)
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>Acceptance test report: {e(title)}</title><style>{PAGE.replace('TITLE', css_title)}"
        f"{STYLE}</style></head><body>\n"
        + "\n".join([*cover, *summary, *sections, *appendix])
        + "\n</body></html>\n"
    )


def _fc_appendix(results: Sequence[RunResult]) -> str:
    """The reference FC's configuration: the values every run shared once, then what differed."""
    e = html.escape
    configs: dict[str, dict[str, object]] = {
        r.scenario.stem: r.metadata["fc_config"]
        for r in results
        if isinstance(r.metadata.get("fc_config"), dict)
    }
    if not configs:
        return (
            "<h3>FC configuration</h3><p>None recorded: the DUT was not the reference FC (a scenario's "
            "[fc] table configures only the reference FC).</p>"
        )
    keys = list(dict.fromkeys(k for c in configs.values() for k in c))
    common = [
        k
        for k in keys
        if len({str(c.get(k, "")) for c in configs.values()}) == 1 and all(k in c for c in configs.values())
    ]
    out = [
        "<h3>FC configuration</h3><p class=small>The reference FC's configuration file, key by key: the "
        "values every run used, then each run's own.</p><table><tr><th>key</th><th>value</th></tr>"
    ]
    first = next(iter(configs.values()))
    out += [f"<tr><td><code>{e(k)}</code></td><td><code>{e(str(first[k]))}</code></td></tr>" for k in common]
    out.append("</table>")
    for stem, c in configs.items():
        own = [k for k in c if k not in common]
        if own:
            out.append(
                f"<p><b>{e(stem)}</b>: "
                + ", ".join(f"<code>{e(k)} = {e(str(c[k]))}</code>" for k in own)
                + "</p>"
            )
    return "".join(out)
