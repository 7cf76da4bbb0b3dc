"""The whole library passes against the reference FC in lockstep through `rig run --pdf`, its reports
are well formed and agree with each other (the acceptance PDF, read back with pdftotext, holds the
verdicts, values and hashes result.json holds), report.html works in Chromium, and a repeated run with
the same seed is identical."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from rig.reports.telemetry import read
from rig.runner import run
from rig.scenarios.schema import Gust, load
from tests.browser import chromium_page

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"


@pytest.fixture(scope="module")
def library_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """One `rig run --pdf` of the whole library, shared by the tests of its reports: (folder, stderr)."""
    out = tmp_path_factory.mktemp("library") / "reports"
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "run", "--out", str(out), "--pdf", "--operator", "A. Tester"],
        capture_output=True, text=True,
    )
    assert done.returncode == 0, done.stderr
    return out, done.stderr


def test_rig_run_passes_the_library_and_writes_every_report(library_run: tuple[Path, str]) -> None:
    out, stderr = library_run
    names = sorted(p.stem for p in LIB.glob("*.toml"))
    assert f"[{len(names)}/{len(names)}]" in stderr  # progress
    suite = ET.parse(out / "junit.xml").getroot()
    assert [s.get("name") for s in suite] == names
    assert not suite.findall(".//failure") and not suite.findall(".//error")
    index = (out / "index.html").read_text()
    for n in names:
        result = json.loads((out / n / "result.json").read_text())
        assert result["verdict"] == "pass"
        assert all(m["outcome"] == "pass" for m in result["measurements"])
        for key in (
            "rig_version",
            "plant_fmu_sha256",
            "dut_command",
            "dut_firmware_sha256",
            "scenario_sha256",
            "seed",
        ):
            assert result["metadata"][key] not in (None, "")
        cases = ET.parse(out / n / "junit.xml").getroot().findall(".//testcase")
        assert len(cases) == len(result["measurements"])
        tel = read((out / n / "telemetry.csv").read_text())
        assert abs(tel["t"][-1] - result["metadata"]["duration"]) < 0.011
        html = (out / n / "report.html").read_text()
        assert html.count("<svg") == 4 and 'Verdict: <b class="pass">PASS</b>' in html
        assert f"{n}/report.html" in index


def test_a_repeated_run_with_the_same_seed_is_identical(tmp_path: Path) -> None:
    sc = load(LIB / "hover_turbulence.toml")
    a, b = run(sc, seed=7, work_dir=tmp_path / "a"), run(sc, seed=7, work_dir=tmp_path / "b")
    c = run(sc, seed=8, work_dir=tmp_path / "c")
    assert [m.value for m in a.measurements] == [m.value for m in b.measurements]
    for k in a.signals:
        np.testing.assert_array_equal(a.signals[k], b.signals[k])
    assert not np.array_equal(a.signals["roll"], c.signals["roll"])  # the seed matters


def test_the_recorded_wind_is_the_steady_wind_and_the_gust_of_its_instant(tmp_path: Path) -> None:
    """The wind the runner gives the plant every 10 ms (rig/runner.py's _Wind), as the recorder has it,
    against the 1-cosine formula at each row's time (no turbulence: nothing random), over the gust's
    ends and its peak."""
    gust = Gust(start=0.75, duration=0.5, peak=(0.0, -6.0, 2.0))
    sc = dataclasses.replace(load(LIB / "step_roll.toml"), duration=1.6, wind=(1.0, 0.5, 0.0),
                             turbulence=0.0, gusts=(gust,), criteria=())
    r = run(sc, seed=0, work_dir=tmp_path)
    t = r.signals["t"]
    inside = (t >= gust.start - 1e-9) & (t <= gust.start + gust.duration + 1e-9)
    shape = np.where(inside, 0.5 * (1 - np.cos(2 * np.pi * (t - gust.start) / gust.duration)), 0.0)
    expected = np.hypot(np.hypot(1.0 + 0 * shape, 0.5 - 6.0 * shape), 2.0 * shape)
    assert len(t) == 161 and shape.max() == pytest.approx(1.0)
    np.testing.assert_allclose(r.signals["wind"], expected, rtol=1e-9, atol=1e-12)


def test_a_reader_that_goes_away_ends_rig_list_quietly() -> None:
    """``rig list | head``: a closed pipe ends the command with SIGPIPE's status, no traceback."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line: every write fails
    try:
        done = subprocess.run([sys.executable, "-m", "rig.cli", "list"], stdout=write_end,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert done.returncode == 141, done.stderr
    assert done.stderr == ""


# ---- the acceptance PDF, read back by pdftotext (poppler-utils), against result.json -----------------


def pdf_text(pdf: Path) -> str:
    """The PDF's text as pdftotext reads it, whitespace folded (a table cell may wrap)."""
    done = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True, check=True)
    return done.stdout


def results_of(out: Path) -> list[dict]:
    stems = json.loads((out / ".rig-run.json").read_text())
    return [json.loads((out / s / "result.json").read_text()) for s in stems]


def sections(text: str, results: list[dict]) -> dict[str, str]:
    """Each scenario's section of the PDF's text: from its numbered heading to the next one."""
    starts = [text.index(f"{k}. {r['name']}\n") for k, r in enumerate(results, 1)]
    ends = [*starts[1:], text.index("Appendix: traceability")]
    return {r["scenario"]: text[a:b] for r, a, b in zip(results, starts, ends, strict=True)}


def check_pdf_against_results(pdf: Path, results: list[dict]) -> str:
    text = pdf_text(pdf)
    words = " ".join(text.split())
    overall = "PASS" if all(r["verdict"] == "pass" for r in results) else None
    if overall:
        assert f"Overall verdict: {overall}" in words
    meta = results[0]["metadata"]
    for key in ("dut_firmware_sha256", "plant_fmu_sha256", "rig_version"):
        assert str(meta[key]) in text, key  # the cover
    for r, sec in sections(text, results).items():
        result = next(x for x in results if x["scenario"] == r)
        flat = " ".join(sec.split())
        assert f"Verdict: {result['verdict'].upper()}" in flat, r
        assert result["metadata"]["scenario_sha256"] in sec, r
        for m in result["measurements"]:
            v, why = m["value"], m.get("value_reason")
            shown = "not measured" if why == "nan" else ("never" if why == "inf" and m["units"] == "s" else
                                                          f"{v:.4g}")
            assert shown in flat, (r, m["name"], shown)
            if m["margin"] is not None:
                assert f"{m['margin']:.1f} %" in flat, (r, m["name"])
        # the outcome column, right of the margin column ("12.1 %", "8.0 % (marginal)", "n/a")
        outcomes = re.findall(r"(?:%|\(marginal\)|n/a)\s+(marginal pass|pass|fail|not judged)\b", sec)
        expected = [("marginal pass" if m["marginal"] else m["outcome"]) for m in result["measurements"]]
        assert outcomes == expected, r
    appendix = text[text.index("Appendix: traceability"):]
    for result in results:
        assert result["metadata"]["scenario_sha256"] in appendix
    return text


def test_the_acceptance_pdf_holds_what_result_json_holds(library_run: tuple[Path, str]) -> None:
    out, stderr = library_run
    pdf = out / "acceptance.pdf"
    assert pdf.read_bytes().startswith(b"%PDF-") and "acceptance report:" in stderr
    results = results_of(out)
    text = check_pdf_against_results(pdf, results)
    words = " ".join(text.split())
    assert "A. Tester" in words and "lockstep" in words
    assert "Summary" in text and "FC configuration" in text
    assert 'href="acceptance.pdf"' in (out / "index.html").read_text()
    # plots with the faults and the RC loss marked, named in the legends of those runs only
    secs = sections(text, results)
    assert "RC link lost" in secs["rc_loss_failsafe"] and "sensor fault" not in secs["rc_loss_failsafe"]
    assert "sensor fault" in secs["fault_gyro_stuck"] and "RC link lost" not in secs["fault_gyro_stuck"]
    assert "sensor fault" not in secs["step_roll"] and "RC link lost" not in secs["step_roll"]


def test_rig_report_prints_the_pdf_again_from_the_folder_alone(library_run: tuple[Path, str],
                                                              tmp_path: Path) -> None:
    """An archived run: the folder copied elsewhere, its PDF and index removed, made again by `rig report`
    from result.json and telemetry.csv alone."""
    out = tmp_path / "copy"
    shutil.copytree(library_run[0], out)
    for name in ("acceptance.pdf", "acceptance.html", "index.html"):
        (out / name).unlink()
    done = subprocess.run([sys.executable, "-m", "rig.cli", "report", str(out), "--pdf", "--operator",
                           "B. Signer"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    text = check_pdf_against_results(out / "acceptance.pdf", results_of(out))
    assert "B. Signer" in text
    assert (out / "index.html").is_file()
    bad = subprocess.run([sys.executable, "-m", "rig.cli", "report", str(tmp_path), "--pdf"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "no run's result.json" in bad.stderr


def test_the_index_and_junit_name_the_run(library_run: tuple[Path, str]) -> None:
    out = library_run[0]
    results = results_of(out)
    meta = results[0]["metadata"]
    index = (out / "index.html").read_text()
    for value in (meta["started"], meta["host"], meta["dut_firmware_sha256"], meta["plant_fmu_sha256"],
                  meta["rig_version"], "lockstep", 'href="junit.xml"'):
        assert str(value) in index, value
    assert "random seed</th><td><code>0</code>" in index
    assert all(f"<code>{r['scenario']}.toml</code>" in index for r in results)
    assert os.path.isabs(meta["dut_command"].split()[0])
    for suite in ET.parse(out / "junit.xml").getroot():
        r = next(x for x in results if x["scenario"] == suite.get("name"))
        assert suite.get("timestamp") == r["metadata"]["started"].removesuffix("+00:00")
        assert suite.get("hostname") == r["metadata"]["host"]
        props = {p.get("name"): p.get("value") for p in suite.iter("property")}
        assert props["dut_firmware_sha256"] == r["metadata"]["dut_firmware_sha256"]
        assert props["dut_program_sha256"] == r["metadata"]["dut_program_sha256"]
        assert props["mode"] == "lockstep"


def test_report_html_reads_in_words(library_run: tuple[Path, str]) -> None:
    out = library_run[0]
    rc = (out / "rc_loss_failsafe" / "report.html").read_text()
    result = json.loads((out / "rc_loss_failsafe" / "result.json").read_text())
    wall = result["metadata"]["wall_time"]
    assert f"{wall:.2f} s" in rc and repr(wall) not in rc  # units, not Python's repr
    assert "lockstep True" not in rc and ">True<" not in rc
    assert "SIGTERM: the rig stopped the DUT at the end of the scenario" in rc
    assert "<h2>FC configuration</h2>" in rc and "telemetry_path" in rc
    # the DUT's clock in its stderr, with the sim time the plots use beside it
    said = re.search(r"RC lost at t=(\d+\.\d+)", (out / "rc_loss_failsafe" / "dut-stderr.txt").read_text())
    assert said
    sim = float(said.group(1)) - result["metadata"]["dut_clock_base_s"]
    assert f"t={said.group(1)} [sim {sim:.3f} s]" in rc and abs(sim - 6.5) < 0.1  # the link is lost at 6 s
    # unnamed criteria: the name is not repeated as the measurement; the target and band are shown
    roll = (out / "step_roll" / "report.html").read_text()
    assert "<td>overshoot of roll</td><td>percent of the step beyond the target; target 10 deg</td>" in roll
    assert "band ±1 deg" in roll
    assert "sensor fault" not in roll and "RC link lost" not in roll  # nothing shaded: nothing said
    motors = roll[roll.index('id="plot-motors"'):]
    motors = motors[:motors.index("</svg>")]
    assert motors.count('fill="none" stroke="#888"') == 4  # one lane per motor


#: the pixels of a chart: how many are near a colour (uPlot draws with antialiasing)
COUNT_COLOUR = """([sel, hex]) => {
  const want = [1, 3, 5].map(i => parseInt(hex.slice(i, i + 2), 16));
  let n = 0;
  for (const c of document.querySelectorAll(sel + ' canvas')) {
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    for (let i = 0; i < d.length; i += 4)
      if (Math.abs(d[i] - want[0]) < 8 && Math.abs(d[i + 1] - want[1]) < 8
          && Math.abs(d[i + 2] - want[2]) < 8) n++;
  }
  return n;
}"""


def test_report_html_in_chromium(library_run: tuple[Path, str], tmp_path: Path) -> None:
    """Debian's Chromium through Playwright (never a downloaded browser): the interactive charts replace
    the static SVG, draw the traces and shade the RC loss only where there was one; without JavaScript
    and on paper the SVG shows; a screenshot is taken."""
    out = library_run[0]
    with chromium_page((out / "rc_loss_failsafe" / "report.html").as_uri(), 1000, 1400) as (page, errors):
        assert page.locator("figure.plot.live").count() == 4 and not errors
        assert page.locator("figure.plot .uplot").count() == 3 + 4  # three charts and four motor lanes
        assert not page.locator("#plot-attitude .svg").is_visible()
        assert page.evaluate(COUNT_COLOUR, ["#plot-altitude", "#1f77b4"]) > 200  # the altitude trace
        assert page.evaluate(COUNT_COLOUR, ["#plot-altitude", "#cfe2f3"]) > 2000  # RC link lost, shaded
        shot = tmp_path / "report.png"
        page.screenshot(path=str(shot), full_page=True)
        png = shot.read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(png[16:20], "big") == 1000
        page.emulate_media(media="print")
        assert page.locator("#plot-attitude .svg").is_visible()
        page.goto((out / "step_roll" / "report.html").as_uri())
        assert page.locator("figure.plot.live").count() == 4
        assert page.evaluate(COUNT_COLOUR, ["#plot-altitude", "#cfe2f3"]) == 0  # no RC loss, no shade
        assert page.context.browser is not None
        static = page.context.browser.new_context(java_script_enabled=False).new_page()
        static.goto((out / "step_roll" / "report.html").as_uri())
        assert static.locator("#plot-attitude .svg").is_visible() and static.locator(".uplot").count() == 0
