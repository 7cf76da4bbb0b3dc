"""The reports' pieces without a DUT: margins and marginal passes (in result.json, JUnit, report.html,
the index and the acceptance PDF), what the plots draw and name, the metadata in words, the vendored
uPlot as its README pins it, and a report folder read back."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import re
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from rig.reports import acceptance, html_report, junit, pdf, result_json, telemetry
from rig.reports.load import read_folder
from rig.reports.values import META, fmt_margin, mode_text, returncode_text, sim_times_in
from rig.scenarios.criteria import Measurement, margin_pct, measure
from rig.scenarios.result import RunResult
from rig.scenarios.schema import load
from rig.scenarios.signals import SIGNALS

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"
UPLOT = Path(__file__).resolve().parents[2] / "reports" / "vendor" / "uplot"


@pytest.mark.parametrize(
    ("value", "lo", "hi", "margin"),
    [
        (4.0, None, 5.0, 20.0),  # 1 inside a limit of 5
        (5.5, None, 5.0, -10.0),  # outside: negative
        (-1.2, -1.5, None, 20.0),  # a lower limit: distance over |limit|
        (1.0, 0.0, 10.0, 10.0),  # a limit of 0 with another: the band's width stands in
        (9.0, 0.0, 10.0, 10.0),
        (0.0, None, 0.0, None),  # a limit of 0 alone has no percentage
        (math.nan, None, 5.0, None),
        (math.inf, None, 5.0, None),
    ],
)
def test_margin_is_the_distance_inside_the_nearer_limit(
    value: float, lo: float | None, hi: float | None, margin: float | None
) -> None:
    got = margin_pct(value, lo, hi)
    assert (got is None) if margin is None else got == pytest.approx(margin)


def criterion(
    values: list[float], hi: float, marginal_pct: float = 10.0, signal: str = "tilt"
) -> Measurement:
    t = np.arange(len(values)) * 0.01
    return measure(
        "c",
        "max",
        signal,
        t,
        np.array(values),
        0.0,
        1.0,
        None,
        None,
        None,
        hi,
        "deg",
        marginal_pct=marginal_pct,
    )


def test_a_pass_within_ten_percent_of_a_limit_is_marginal() -> None:
    close, clear, over = criterion([0.0, 4.6], 5.0), criterion([0.0, 4.4], 5.0), criterion([5.2], 5.0)
    assert (close.outcome, close.marginal) == ("pass", True) and close.margin == pytest.approx(8.0)
    assert "marginal" in close.reason
    assert (clear.outcome, clear.marginal) == ("pass", False) and clear.margin == pytest.approx(12.0)
    assert (over.outcome, over.marginal) == ("fail", False) and over.margin == pytest.approx(-4.0)
    assert criterion([0.0, 4.6], 5.0, marginal_pct=0.0).marginal is False  # the criterion's own band
    assert criterion([1.0], 1.0, signal="on_ground").margin is None  # a state: yes or no
    assert fmt_margin(close) == "8.0 % (marginal)" and fmt_margin(clear) == "12.0 %"


def a_run(measurements: list[Measurement], t_end: float = 2.0, **signals: np.ndarray) -> RunResult:
    t = np.arange(0.0, t_end, 0.01)
    s = {name: np.zeros(len(t)) for name in SIGNALS} | {"t": t, "rc_link": np.ones(len(t))}
    s.update(signals)
    meta = {
        "rig_version": "0.1.0",
        "scenario_sha256": "ab" * 32,
        "seed": 3,
        "started": "2026-11-23T10:00:00+00:00",
        "host": "bench-7",
        "mode": "lockstep",
        "dut_firmware": "the program /opt/fw/fc",
        "dut_firmware_sha256": "cd" * 32,
        "plant_fmu_sha256": "ef" * 32,
        "sim_time": t_end,
        "wall_time": 0.5,
        "dut_returncode": -15,
        "dut_clock_base_s": 1000.0,
    }
    verdict = "pass" if all(m.outcome == "pass" for m in measurements) else "fail"
    return RunResult(load(LIB / "step_roll.toml"), verdict, None, measurements, s, meta, 0, "", [])


def test_a_marginal_pass_is_marked_in_every_report(tmp_path: Path) -> None:
    close, clear = criterion([0.0, 4.6], 5.0), criterion([0.0, 1.0], 5.0)
    r = a_run([close, clear])
    data = json.loads(result_json.render(r))
    assert data["verdict"] == "pass" and data["marginal"] == ["c"]
    assert [m["marginal"] for m in data["measurements"]] == [True, False]
    assert data["measurements"][0]["margin"] == pytest.approx(8.0)
    cases = ET.fromstring(junit.render([r])).findall(".//testcase")
    assert [c.find("properties/property[@name='marginal']") is not None for c in cases] == [True, False]
    assert not ET.fromstring(junit.render([r])).findall(".//failure")
    page = html_report.render(r)
    assert '<tr class="marginal">' in page and "marginal pass" in page and "8.0 % (marginal)" in page
    assert "(1 marginal)" in page
    assert "1 marginal criteria" in html_report.render_index([r], ["a/report.html"])
    # on paper, beside a failed run: the marginal pass, the plain pass and the failure, in order
    failed = a_run([criterion([5.2], 5.0)])
    src, out = tmp_path / "a.html", tmp_path / "a.pdf"
    src.write_text(acceptance.render([r, failed]))
    pdf.html_to_pdf(src, out)
    text = subprocess.run(
        ["pdftotext", "-layout", str(out), "-"], capture_output=True, text=True, check=True
    ).stdout
    assert re.search(r"8\.0 % \(marginal\)\s+marginal pass", text) and re.search(r"-4\.0 %\s+fail", text)
    assert re.findall(r"%(?: \(marginal\))?\s+(marginal pass|pass|fail)\b", text) == [
        "marginal pass",
        "pass",
        "fail",
    ]
    words = " ".join(text.split())
    assert "Overall verdict: FAIL" in words and "1 of 2 scenarios passed, 1 failed" in words


def test_the_dut_command_is_recorded_with_absolute_paths(tmp_path: Path) -> None:
    from rig.targets.process import absolute_command

    (tmp_path / "fw").write_text("")
    (tmp_path / "fc.conf").write_text("")
    cmd = absolute_command(["./fw", "fc.conf", "-c", "x=1", "python3", "/abs/fc"], tmp_path)
    assert cmd == [str(tmp_path / "fw"), str(tmp_path / "fc.conf"), "-c", "x=1", "python3", "/abs/fc"]


def test_plots_name_only_what_they_show() -> None:
    nan = np.full(200, math.nan)
    quiet = html_report.render(
        a_run([criterion([1.0], 5.0)], est_roll=nan, est_pitch=nan, est_yaw=nan, est_alt=nan)
    )
    assert "(DUT)" not in quiet.split("<script")[0]  # no telemetry: no DUT legend entry
    assert "sensor fault" not in quiet and "RC link lost" not in quiet and "Shaded" not in quiet
    fault = np.zeros(200)
    fault[50:80] = 1
    link = np.ones(200)
    link[120:] = 0
    loud = html_report.render(a_run([criterion([1.0], 5.0)], fault=fault, rc_link=link))
    assert "roll (DUT)" in loud and "Shaded: sensor fault, RC link lost." in loud
    svg = loud[loud.index('id="plot-yaw"') :]
    svg = svg[: svg.index("</svg>")]
    # one fault span at 0.5–0.8 s and the RC loss from 1.2 s to the end (2 s), on a 760 px axis
    assert svg.count('fill="#f4cccc"><title>sensor fault') == 1 and svg.count("<title>RC link lost") == 1
    data = html_report.chart_data(a_run([], fault=fault, rc_link=link))
    assert [m["spans"] for m in data["marks"]] == [((0.5, 0.8),), ((1.2, 2.0),)]


def test_the_metadata_reads_in_words() -> None:
    assert "normal stop" in returncode_text(-15, "pass") and "normal stop" not in returncode_text(
        -15, "error"
    )
    assert returncode_text(0, "pass").startswith("0 (the DUT exited by itself")
    assert mode_text({"mode": "lockstep"}) == "lockstep" and mode_text({"lockstep": False}) == "real time"
    # the bench bridge, as its session's link figures name it, nested or beside the mode
    figures = {
        "bridge": "/dev/ttyACM0",
        "bridge_id": "vbridge",
        "protocol": 1,
        "core_version": "0.3",
        "firmware_sha256_8": "1a2b3c4d",
        "samples_sent": 4000,
        "link": {"bytes": 9},
    }
    want = "bridge (bench: port /dev/ttyACM0, id vbridge, protocol 1, core 0.3, firmware 1a2b3c4d)"
    assert mode_text({"mode": "bridge", "bridge": figures}) == want
    assert mode_text({"mode": "bridge", **figures}) == want
    assert mode_text({"mode": "bridge"}) == "bridge"
    assert sim_times_in("fc: RC lost at t=1006.495: failsafe", 1000.0) == (
        "fc: RC lost at t=1006.495 [sim 6.495 s]: failsafe"
    )
    label, lateness = META["realtime_lateness"]
    late = {"events": 1719, "late_over_1ms": 24, "max_s": 0.0048583, "p99_s": 0.00107594}
    assert lateness(late) == "24 of 1719 scheduled events over 1 ms late; worst 4.86 ms, p99 1.08 ms"
    host = {"waits": 1153, "wait_p99_s": 0.000187, "wait_max_s": 0.0016, "steal_s": 0.97}
    assert label == "real-time lateness" and lateness({**late, **host}) == (
        "24 of 1719 scheduled events over 1 ms late; worst 4.86 ms, p99 1.08 ms; the loop's waits woke p99 "
        "0.19 ms late, worst 1.6 ms; the hypervisor took 0.97 s of the host's CPUs"
    )
    causes = {"host_woke_late": 5, "host_preempted": 1, "loop_busy": 2, "loop_blocked": 0, "unattributed": 0}
    assert lateness({**late, **host, "late_causes": causes}).endswith(
        "; late by cause: host woke late 5, host preempted 1, loop busy 2"
    )


def test_the_vendored_uplot_is_the_pinned_one_and_inlined() -> None:
    readme = (UPLOT / "README.md").read_text()
    for name in ("uPlot.iife.min.js", "uPlot.min.css"):
        digest = hashlib.sha256((UPLOT / name).read_bytes()).hexdigest()
        assert f"`{name}` | `package/dist/{name}`, unchanged, sha256 `{digest}`" in readme
    assert "MIT" in (UPLOT / "LICENSE").read_text()
    page = html_report.render(a_run([criterion([1.0], 5.0)]))
    assert "uPlot" in page and not re.search(r"""(src|href)=["']?https?:""", page)  # nothing fetched


def test_a_report_folder_reads_back(tmp_path: Path) -> None:
    r = a_run([criterion([0.0, 4.6], 5.0)])
    (tmp_path / "step_roll").mkdir()
    (tmp_path / "step_roll" / "result.json").write_text(result_json.render(r))
    (tmp_path / "step_roll" / "telemetry.csv").write_text(telemetry.render(r.signals))
    (tmp_path / ".rig-run.json").write_text('["step_roll", "later"]')
    [back], not_run = read_folder(tmp_path)
    assert not_run == ["later"] and back.verdict == "pass" and back.scenario.name == r.scenario.name
    assert back.measurements == r.measurements
    np.testing.assert_allclose(back.signals["t"], r.signals["t"])
    assert telemetry.read(telemetry.render({"t": np.zeros(0)}))["t"].shape == (0,)  # an empty run


def test_the_docs_show_a_page_of_the_acceptance_pdf() -> None:
    """docs/acceptance-report-page.png (`make docs-images`): a PNG of an A4 page, named by the docs."""
    png = (Path(__file__).resolve().parents[2] / "docs" / "acceptance-report-page.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png[12:16] == b"IHDR"
    width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    assert width >= 600 and height / width == pytest.approx(297 / 210, rel=0.01)
    docs = Path(__file__).resolve().parents[2] / "docs"
    assert "acceptance-report-page.png" in (docs / "scenarios.md").read_text()


def test_a_plot_keeps_every_peak_of_a_long_trace() -> None:
    """The SVG draws about one point per pixel column (a long run's PDF stays small) and never drops
    a bucket's extremes: a one-sample spike survives, and so does a gap."""
    from rig.reports.svg_plot import BUCKETS, extremes

    v = np.sin(np.arange(6000) * 0.01)
    v[4321], v[100:130] = 9.0, math.nan
    keep = extremes(v)
    assert len(keep) <= 3 * BUCKETS and 4321 in keep and np.nanmax(v[keep]) == 9.0
    assert np.isnan(v[keep]).any() and np.all(np.diff(keep) > 0)
    assert np.array_equal(extremes(v[:500]), np.arange(500))  # short: every sample


def _extremes_bucket_by_bucket(values: np.ndarray, buckets: int) -> np.ndarray:
    """extremes' docstring read literally, one bucket at a time (a second implementation)."""
    n = len(values)
    if n <= 2 * buckets:
        return np.arange(n)
    size = math.ceil(n / buckets)
    keep: list[int] = []
    for a in range(0, n, size):
        seg = values[a:a + size]
        finite = np.isfinite(seg)
        if not finite.all():
            keep.append(a + int(np.argmin(finite)))
        if finite.any():
            keep.append(a + int(np.argmin(np.where(finite, seg, np.inf))))
            keep.append(a + int(np.argmax(np.where(finite, seg, -np.inf))))
    return np.unique(keep)


def test_a_plots_samples_are_those_a_bucket_by_bucket_reading_keeps() -> None:
    """Random traces with gaps, infinities, ties and lengths that leave the last bucket short."""
    from rig.reports.svg_plot import extremes

    rng = np.random.default_rng(3)
    for n in (801, 1000, 1013, 4000, 6001, 20011):
        v = np.round(rng.normal(size=n), 1)  # (rounded: ties within buckets)
        v[rng.integers(0, n, n // 50)] = math.nan
        v[rng.integers(0, n, 5)] = math.inf
        v[rng.integers(0, n, 5)] = -math.inf
        v[n // 3:n // 3 + 200] = math.nan  # whole buckets of gap
        for buckets in (400, 37):
            want = _extremes_bucket_by_bucket(v, buckets)
            got = extremes(v, buckets)
            assert got.dtype == want.dtype and np.array_equal(got, want), (n, buckets)


def test_telemetry_csv_is_the_csv_module_s_writing_of_its_rows() -> None:
    """telemetry.csv's rows are written by hand: the same text as the csv module's writer of the same
    fields (``%.6g``, NaN empty), over every magnitude, -0.0, infinities and NaN here and throughout."""
    rng = np.random.default_rng(5)
    n = 500
    signals = {"t": np.arange(n) * 0.01}
    for k, name in enumerate(n for n in SIGNALS if n != "t"):
        col = rng.standard_normal(n) * 10.0 ** rng.integers(-12, 12, n)
        col[rng.random(n) < 0.05] = [-0.0, np.inf, -np.inf, np.nan][k % 4]
        if k % 6 == 5:
            col[:] = np.nan
        signals[name] = col
    want = io.StringIO()
    writer = csv.writer(want, lineterminator="\n")
    writer.writerow(["t[s]"] + [f"{n}[{SIGNALS[n].units}]" for n in signals if n != "t"])
    for k in range(n):
        values = [float(signals[s][k]) for s in signals]
        writer.writerow(["" if math.isnan(v) else format(v, ".6g") for v in values])
    text = telemetry.render(signals)
    assert text == want.getvalue()
    assert ",," in text and "inf" in text and "-0," in text and "e-" in text
    with pytest.raises(ValueError):
        telemetry.render({**signals, "roll": signals["roll"][:-1]})


def test_non_finite_values_are_null_with_a_reason_in_result_json(tmp_path: Path) -> None:
    """result.json is strict JSON (RFC 8259 has no NaN or Infinity): a value that is not a finite number
    is null, and ``value_reason`` says which it was; read back as that float."""
    import dataclasses

    base = criterion([0.0, 1.0], 5.0)
    kinds = [dataclasses.replace(base, name=n, value=v, outcome="not judged")
             for n, v in (("nan", math.nan), ("inf", math.inf), ("-inf", -math.inf))]
    r = a_run([base, *kinds])
    text = result_json.render(r)

    def refuse(word: str) -> None:
        raise ValueError(f"{word} in strict JSON")

    data = json.loads(text, parse_constant=refuse)  # (Python's reader would take NaN; JSON has none)
    got = [(m["name"], m["value"], m.get("value_reason")) for m in data["measurements"]]
    assert got == [("c", 1.0, None), ("nan", None, "nan"), ("inf", None, "inf"), ("-inf", None, "-inf")]
    (tmp_path / "step_roll").mkdir()
    (tmp_path / "step_roll" / "result.json").write_text(text)
    (tmp_path / ".rig-run.json").write_text('["step_roll"]\n')
    [back], _ = read_folder(tmp_path)
    values = [m.value for m in back.measurements]
    assert values[:1] == [1.0] and math.isnan(values[1]) and values[2:] == [math.inf, -math.inf]
