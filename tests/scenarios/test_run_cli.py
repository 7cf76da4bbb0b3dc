"""`rig run` as a user runs it when things go wrong: DUTs that never fly, bad options, two runs into one
folder, Ctrl-C and SIGTERM. Every report is written, nothing outlives the run, exit codes say what
happened (0 pass, 1 fail, 2 bad usage, 3 error, 128+N a signal)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from rig.run_cmd import ReportFolder
from tests.waits import pid_fifo, read_pid, wait_gone

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"
#: stand-in firmware, each with the misbehaviour a test needs
DUTS = Path(__file__).resolve().parent / "misbehaving_firmware"
PY = sys.executable

SHORT = """[scenario]
name = "short {name}"
duration = 2.0
[[timeline]]
t = 1.2
sticks = {{ arm = true, throttle = 0.0 }}
[[criteria]]
name = "level"
metric = "max"
signal = "tilt"
max = 5.0
{extra}
"""


def scenario(tmp: Path, name: str, extra: str = "") -> Path:
    path = tmp / f"{name}.toml"
    path.write_text(SHORT.format(name=name, extra=extra))
    return path


def rig_run(*args: str | Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PY, "-m", "rig.cli", "run", *map(str, args)], capture_output=True, text=True,
                          timeout=300, env=env)


def private_tmp(tmp_path: Path) -> dict[str, str]:
    """An environment whose temporary files land in a folder of the test's own, to see what is left."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    return {**os.environ, "TMPDIR": str(tmp)}


def pdf_text(pdf: Path) -> str:
    return subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True,
                          check=True).stdout


def read_result(out: Path, stem: str) -> dict:
    return json.loads((out / stem / "result.json").read_text())


@pytest.mark.parametrize(("dut", "said"), [
    ("/no/such/prog", "command not found: /no/such/prog"),
    ("true", "without touching the emulated devices"),
    ("sh -c 'kill -SEGV $$'", "SIGSEGV"),
    (f"{PY} -c 'import time; time.sleep(30)'", "never read a sensor"),
])
def test_a_dut_that_never_flies_is_an_error_row_and_every_report_is_written(tmp_path: Path, dut: str,
                                                                             said: str) -> None:
    a, b = scenario(tmp_path, "a"), scenario(tmp_path, "b")
    out = tmp_path / "out"
    done = rig_run(a, b, "--dut", dut, "--out", out)
    assert done.returncode == 3, done.stderr
    assert "Traceback" not in done.stderr
    assert "[2/2]" in done.stderr  # the second scenario still ran
    suite = ET.parse(out / "junit.xml").getroot()
    assert [s.get("errors") for s in suite] == ["1", "1"]
    index = (out / "index.html").read_text()
    assert index.count('class="error"') == 2
    for stem in ("a", "b"):
        result = read_result(out, stem)
        assert result["verdict"] == "error" and said in result["error"], result["error"]
        assert {m["outcome"] for m in result["measurements"]} == {"not judged"}
        report = (out / stem / "report.html").read_text()
        assert 'class="pass"' not in report  # an error run shows no passed criterion
        assert (out / stem / "telemetry.csv").is_file()


def test_a_dut_that_stalls_is_ended_by_the_wall_timeout(tmp_path: Path) -> None:
    out = tmp_path / "out"
    fifo = pid_fifo(tmp_path / "pid")
    dut = f"{PY} {DUTS / 'stall_after_one_read.py'} {fifo}"
    proc = subprocess.Popen([PY, "-m", "rig.cli", "run", str(scenario(tmp_path, "a")), "--dut", dut,
                             "--out", str(out), "--wall-timeout", "2"], stderr=subprocess.PIPE, text=True)
    pid = read_pid(fifo)
    stderr = proc.communicate(timeout=120)[1]
    assert proc.returncode == 3, stderr
    assert "wall-time watchdog" in read_result(out, "a")["error"]
    assert wait_gone(pid, timeout=0)


def test_the_reference_fc_refusing_its_configuration_is_reported_in_its_own_words(tmp_path: Path) -> None:
    """A rule between two keys is the FC's to check (rig validate checks each key): its message is the
    run's error, not a guess about static linking."""
    sc = scenario(tmp_path, "a", "[fc]\nest_rate_hz = 250\nctrl_rate_hz = 300")
    out = tmp_path / "out"
    done = rig_run(sc, "--out", out)
    assert done.returncode == 3, done.stderr
    error = read_result(out, "a")["error"]
    assert "exited with status 2" in error and "ctrl_rate_hz (300) must be at most est_rate_hz (250)" in error
    assert "statically linked" not in error


@pytest.mark.parametrize(("args", "says"), [
    (["step_roll", "--can", "bogus:can9"], "cannot open CAN interface 'bogus'"),
    (["step_roll", "no_such_scenario"], "no_such_scenario: no such file, and no library scenario"),
    (["step_roll", "--dut", "''"], "--dut is empty"),
])
def test_every_option_and_scenario_is_checked_before_anything_runs(tmp_path: Path, args: list[str],
                                                                   says: str) -> None:
    out = tmp_path / "out"
    done = rig_run(*args, "--out", out)
    assert done.returncode == 2, done.stderr
    assert says in done.stderr
    assert not (out / "step_roll").exists() and not (out / "index.html").exists()


def test_a_bad_file_among_good_ones_stops_the_suite_before_it_starts(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('[scenario]\nname = "x"\nduration = 2\n[vehicle]\nmass = -1\n')
    second = scenario(tmp_path, "second", "[fc]\nestimater = 1")
    out = tmp_path / "out"
    done = rig_run("step_roll", bad, second, "--out", out)
    assert done.returncode == 2
    assert "vehicle.mass: the plant refuses it: mass must be > 0" in done.stderr
    # every problem, not only the first
    assert "fc.estimater: unknown key; did you mean 'estimator'?" in done.stderr
    assert not (out / "step_roll").exists()


def test_pdf_without_a_chromium_is_refused_before_anything_runs(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = rig_run(scenario(tmp_path, "a"), "--out", out, "--pdf",
                   env={**os.environ, "RIG_CHROMIUM": "no-such-chromium"})
    assert done.returncode == 2 and "--pdf: no chromium on PATH" in done.stderr
    assert not (out / "a").exists()


def test_a_second_run_into_a_busy_folder_is_refused_naming_the_first(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with ReportFolder(out):  # another rig run holds it
        done = rig_run(scenario(tmp_path, "a"), "--out", out)
    assert done.returncode == 2
    assert f"--out {out} is in use by another rig run (pid {os.getpid()})" in done.stderr
    assert not (out / "a").exists()


def test_the_folder_holds_one_run_only(tmp_path: Path) -> None:
    """A second run into the folder replaces the first one's reports: no stale scenario folder beside a
    smaller index, and the index lists its own runs."""
    a, b = scenario(tmp_path, "a"), scenario(tmp_path, "b")
    out = tmp_path / "out"
    assert rig_run(a, b, "--out", out).returncode == 0
    (out / "notes-of-mine.txt").write_text("kept")  # not the rig's: left alone
    assert rig_run(b, "--out", out, "--seed", "7").returncode == 0
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["b"]
    assert read_result(out, "b")["metadata"]["seed"] == 7
    index = (out / "index.html").read_text()
    assert "b/report.html" in index and "a/report.html" not in index
    assert (out / "notes-of-mine.txt").read_text() == "kept"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_the_run_writes_the_reports_and_leaves_nothing(tmp_path: Path, sig: int) -> None:
    fifo = pid_fifo(tmp_path / "pid")
    dut = f"{PY} {DUTS / 'stall_after_one_read.py'} {fifo}"
    out = tmp_path / "out"
    env = private_tmp(tmp_path)
    proc = subprocess.Popen([PY, "-m", "rig.cli", "run", str(scenario(tmp_path, "a")),
                             str(scenario(tmp_path, "b")), "--dut", dut, "--out", str(out), "--pdf"],
                            stderr=subprocess.PIPE, text=True, env=env)
    pid = read_pid(fifo)  # the DUT is up: the rig is in its run
    proc.send_signal(sig)
    stderr = proc.communicate(timeout=60)[1]
    assert proc.returncode == 128 + sig, stderr
    assert "Traceback" not in stderr
    assert "0 passed, 0 failed, 0 errors, 1 interrupted in " in stderr  # the summary counts it
    result = read_result(out, "a")
    assert result["verdict"] == "interrupted" and signal.Signals(sig).name in result["error"]
    assert (out / "a" / "report.html").is_file() and (out / "junit.xml").is_file()
    index = (out / "index.html").read_text()
    assert "not run" in index and ">b<" in index  # the scenario the signal kept from running
    words = " ".join(pdf_text(out / "acceptance.pdf").split())  # the PDF of what finished, printed
    assert "Overall verdict: INTERRUPTED" in words and "b NOT RUN" in words
    assert wait_gone(pid, timeout=0)  # the DUT is gone
    assert list((tmp_path / "tmp").iterdir()) == []  # no session folder, socket or shared page left


def test_an_interpreted_dut_is_identified_by_its_script(tmp_path: Path) -> None:
    import hashlib

    script = DUTS / "deaf_to_rc.py"
    out = tmp_path / "out"
    rig_run(scenario(tmp_path, "a"), "--dut", f"{PY} {script}", "--out", out)
    meta = read_result(out, "a")["metadata"]
    assert meta["dut_firmware_sha256"] == hashlib.sha256(script.read_bytes()).hexdigest()
    assert str(script) in meta["dut_firmware"]
    assert meta["dut_program_sha256"] != meta["dut_firmware_sha256"]  # the interpreter is recorded apart


def test_an_errored_run_shows_no_pass_row_in_any_report(tmp_path: Path) -> None:
    """A DUT that never flies: every criterion "not judged", and no report (report.html, index.html,
    junit.xml, the acceptance PDF as pdftotext reads it) shows a passed row or an overall pass."""
    out = tmp_path / "out"
    done = rig_run(scenario(tmp_path, "a"), "--dut", "true", "--out", out, "--pdf")
    assert done.returncode == 3, done.stderr
    report = (out / "a" / "report.html").read_text()
    assert 'class="pass"' not in report and 'class="marginal"' not in report
    assert '<tr class="not-judged">' in report
    index = (out / "index.html").read_text()
    assert '<tr class="error">' in index and '<tr class="pass">' not in index
    assert "<testcase" in (out / "junit.xml").read_text() and "<error" in (out / "junit.xml").read_text()
    text = pdf_text(out / "acceptance.pdf")
    words = " ".join(text.split())
    assert "Overall verdict: ERROR" in words and "Verdict: ERROR" in words
    assert "not judged" in words and "without touching the emulated devices" in words
    assert not re.search(r"\bpass\b", text, re.I), [ln for ln in text.splitlines() if "pass" in ln.lower()]
