"""The whole library passes against the reference FC in lockstep through `rig run`, its reports are
well formed and agree with each other, and a repeated run with the same seed is identical."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from reports.telemetry import read
from rig.runner import run
from scenarios.schema import load

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"


def test_rig_run_passes_the_library_and_writes_every_report(tmp_path: Path) -> None:
    out = tmp_path / "reports"
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "run", "--out", str(out)], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    names = sorted(p.stem for p in LIB.glob("*.toml"))
    assert f"[{len(names)}/{len(names)}]" in done.stderr  # progress
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
