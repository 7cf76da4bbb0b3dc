"""The pytest plugin through real pytest in a subprocess, loaded by its installed entry point (as a
firmware team's `pip install` registers it): collection, a passing and a failing item, -n 2, the JUnit
properties, the `rig` fixture, a bad scenario file."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from importlib.metadata import entry_points
from pathlib import Path

from rig.targets import REFERENCE_FC
from tests.api import LIBRARY, SHORT, failing_copy
from tests.mcu import conftest as mcu
from tests.waits import pid_fifo, read_pid, wait_gone

DUTS = Path(__file__).resolve().parents[1] / "scenarios" / "misbehaving_firmware"

avr_fc = mcu.avr_fc  # (the MCU tier's fixture: build/avr/fc.elf, brought up to date by make)


def own_env() -> dict[str, str]:
    """This environment without pytest-xdist's worker variables: a pytest started from a test that runs
    under ``make test``'s xdist would otherwise take itself for a worker (and write under out/gwN)."""
    return {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_XDIST_")}


def pytest_run(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """pytest in ``cwd`` (its own rootdir: not this repository's configuration), with no cache."""
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--rootdir", str(cwd),
                           *args], cwd=cwd, capture_output=True, text=True, timeout=300, env=own_env())


def test_the_entry_point_is_installed():
    assert [e.value for e in entry_points(group="pytest11") if e.name == "rig"] == ["rig.pytest_plugin"]


def test_collects_the_library_one_item_per_file(tmp_path):
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "x"\n')  # not a scenario: not collected
    done = pytest_run(tmp_path, "--collect-only", "-q", str(LIBRARY), str(tmp_path))
    assert done.returncode == 0, done.stdout + done.stderr
    items = [line for line in done.stdout.splitlines() if "::" in line]
    stems = sorted(p.stem for p in LIBRARY.glob("*.toml"))
    assert sorted(i.split("::")[1] for i in items) == stems
    assert all(i.split("::")[0].endswith(".toml") for i in items)


def test_passing_and_failing_items_with_junit_properties(tmp_path):
    shutil.copy(SHORT, tmp_path)
    failing_copy(tmp_path)
    junit = tmp_path / "junit.xml"
    stale = tmp_path / "out" / "old_run"  # a previous session's run, listed as rig run lists its runs
    stale.mkdir(parents=True)
    (stale / "result.json").write_text("{}")
    (tmp_path / "out" / ".rig-run.json").write_text('["old_run"]')
    done = pytest_run(tmp_path, str(tmp_path), "--rig-seed", "5", "--rig-out", "out", f"--junitxml={junit}")
    out = done.stdout
    assert done.returncode == 1, out + done.stderr
    assert "1 failed, 1 passed" in out
    # the failing item: its criteria table (value, limits, margin) and its report's path
    assert "scenario roll_stand_too_strict (Seed 000: roll stand recovery from -70 deg): FAIL with seed 5" \
        in out
    table = [line for line in out.splitlines() if "overshoot after release" in line and "FAIL" in line]
    assert table, out
    value, units, low, high, margin, outcome = table[0].split()[-6:]
    assert (units, low, high, outcome) == ("%", "-", "0.001", "FAIL"), table[0]
    assert float(value) > 0.001 and float(margin) < 0, table[0]  # outside its limit, by a negative margin
    header = [line.split() for line in out.splitlines() if line.strip().startswith("criterion")]
    # (once in the failure's section; with CI set, pytest repeats it whole in the short summary)
    assert header and all(h == ["criterion", "value", "units", "min", "max", "margin", "%", "outcome"]
                          for h in header), header
    report = tmp_path / "out" / "roll_stand_too_strict" / "report.html"
    assert f"report: {report}" in out and report.is_file()
    assert "Traceback" not in out
    # --junitxml: seed, scenario and firmware SHA-256 as properties of each test case
    cases = {c.get("name"): c for c in ET.parse(junit).getroot().iter("testcase")}
    assert set(cases) == {"seed000_roll_stand", "roll_stand_too_strict"}
    # (the hashes of the bytes, taken here: the scenario files as written, the reference FC the items fly)
    fc = hashlib.sha256(REFERENCE_FC.read_bytes()).hexdigest()
    for name, case in cases.items():
        props = {p.get("name"): p.get("value") for p in case.iter("property")}
        assert props["seed"] == "5"
        written = (tmp_path / f"{name}.toml").read_bytes()
        assert props["scenario_sha256"] == hashlib.sha256(written).hexdigest()
        assert props["firmware_sha256"] == fc
    assert cases["roll_stand_too_strict"].find("failure") is not None
    assert cases["seed000_roll_stand"].find("failure") is None
    # the items' folder is a report folder of this session's runs only: rig report reads it
    assert not stale.exists()
    report = subprocess.run([sys.executable, "-m", "rig.cli", "report", str(tmp_path / "out")],
                            capture_output=True, text=True, timeout=60)
    assert report.returncode == 0, report.stderr
    index = (tmp_path / "out" / "index.html").read_text()
    assert "roll_stand_too_strict/report.html" in index and "seed000_roll_stand/report.html" in index


def test_xdist_one_folder_per_worker(tmp_path):
    for stem in ("a_roll_stand", "b_roll_stand"):
        shutil.copy(SHORT, tmp_path / f"{stem}.toml")
    done = pytest_run(tmp_path, str(tmp_path), "-n", "2", "--rig-out", "out")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "2 passed" in done.stdout
    runs = sorted((tmp_path / "out").glob("*/*/result.json"))
    assert sorted(p.parent.name for p in runs) == ["a_roll_stand", "b_roll_stand"]
    assert {p.parents[1].name for p in runs} <= {"gw0", "gw1"}
    assert not list((tmp_path / "out").glob("*_roll_stand"))  # nothing outside a worker's folder


def stale_run(folder: Path, stem: str) -> Path:
    """A previous session's run in ``folder``, listed as rig run and the plugin list their runs."""
    (folder / stem).mkdir(parents=True)
    (folder / stem / "result.json").write_text("{}")
    (folder / ".rig-run.json").write_text(json.dumps([stem]))
    return folder / stem


def rig_report(out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", "report", str(out)], capture_output=True,
                          text=True, timeout=60)


def test_a_scenario_with_a_fault_runs_compiled(tmp_path):
    """Reading a scenario imports the fault classes: before the hot modules ran compiled, the compiled
    session rejected the source-imported faults ("TargetedFault object expected")."""
    done = pytest_run(tmp_path, str(LIBRARY / "fault_mag_nack.toml"), "--rig-out", "out")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 passed" in done.stdout


def test_a_new_session_removes_the_previous_sessions_runs_with_or_without_workers(tmp_path):
    shutil.copy(SHORT, tmp_path / "a_roll_stand.toml")
    out = tmp_path / "out"
    plain = stale_run(out, "plain_session_run")  # a plain session's, at the root
    worker = stale_run(out / "gw3", "worker_run")  # a `-n 4` session's, in a worker's folder
    done = pytest_run(tmp_path, str(tmp_path), "-n", "2", "--rig-out", "out")
    assert done.returncode == 0, done.stdout + done.stderr
    assert not plain.exists() and not worker.parent.exists()
    (run,) = out.glob("gw*/a_roll_stand/result.json")
    # rig report indexes no earlier run at the root: this session's runs are in the workers' folders
    assert rig_report(out).returncode != 0 and not (out / "index.html").exists()
    assert rig_report(run.parents[1]).returncode == 0

    done = pytest_run(tmp_path, str(tmp_path), "--rig-out", "out")  # and a plain session after it
    assert done.returncode == 0, done.stdout + done.stderr
    assert not run.exists() and not list(out.glob("gw*"))
    assert rig_report(out).returncode == 0
    assert "a_roll_stand/report.html" in (out / "index.html").read_text()


def test_rig_fixture_and_marker(tmp_path):
    (tmp_path / "test_mine.py").write_text('''
import pytest

@pytest.mark.rig_scenario("seed000_roll_stand", seeds=[0, 1])
def test_roll_stand(rig, scenario, seed):
    result = rig.run(scenario, seed=seed)
    assert result.passed, rig.explain(result)
    assert result.seed == seed
    assert result.telemetry.num_rows > 700
    assert result.run_dir.is_relative_to(rig.out)

def test_validate(rig):
    assert rig.validate("seed000_roll_stand") == []
''')
    junit = tmp_path / "junit.xml"
    done = pytest_run(tmp_path, "-v", "--rig-out", "out", f"--junitxml={junit}")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "test_roll_stand[seed000_roll_stand-seed0] PASSED" in done.stdout
    assert "test_roll_stand[seed000_roll_stand-seed1] PASSED" in done.stdout
    assert "3 passed" in done.stdout
    props = ET.parse(junit).getroot().iter("property")
    seeds = sorted(p.get("value") for p in props if p.get("name") == "seed")
    assert seeds == ["0", "1"]


def test_bad_scenario_file_is_a_collection_error_naming_the_key(tmp_path):
    (tmp_path / "typo.toml").write_text(SHORT.read_text().replace("roll0 = ", "rol0 = "))
    done = pytest_run(tmp_path, str(tmp_path))
    assert done.returncode == 2, done.stdout + done.stderr
    assert "ERROR collecting typo.toml" in done.stdout
    assert "bad scenario file:" in done.stdout and "vehicle.rol0: unknown key" in done.stdout
    assert "Traceback" not in done.stdout


def test_rig_mcu_runs_the_image_and_names_its_hash(tmp_path, avr_fc):
    shutil.copy(SHORT, tmp_path)
    junit = tmp_path / "junit.xml"
    done = pytest_run(tmp_path, str(tmp_path), "--rig-mcu", "mega2560-gy86", "--rig-firmware", str(avr_fc),
                      f"--junitxml={junit}")
    assert done.returncode == 0, done.stdout + done.stderr
    props = {p.get("name"): p.get("value") for p in ET.parse(junit).getroot().iter("property")}
    assert props["firmware_sha256"] == hashlib.sha256(avr_fc.read_bytes()).hexdigest()
    result = json.loads((Path(props["report"]) / "result.json").read_text())
    assert result["metadata"]["mode"] == "mcu"


def test_a_bad_rig_firmware_is_one_line_in_a_fixture_test_too(tmp_path):
    (tmp_path / "test_fixture.py").write_text(
        "def test_flies(rig):\n    assert rig.run('seed000_roll_stand').passed\n")
    (tmp_path / "not-an-image.hex").write_text("hello\n")
    done = pytest_run(tmp_path, str(tmp_path), "--rig-mcu", "mega2560-gy86", "--rig-firmware",
                      str(tmp_path / "not-an-image.hex"))
    assert done.returncode == 1, done.stdout + done.stderr
    [line] = [x for x in done.stdout.splitlines() if x.startswith("rig: ")]
    assert line.startswith("rig: mcu: ") and "neither an AVR ELF nor an Intel HEX file" in line, line
    assert "Traceback" not in done.stdout and "api.py" not in done.stdout, done.stdout


def test_rig_mcu_without_firmware_stops_pytest(tmp_path):
    done = pytest_run(tmp_path, str(tmp_path), "--rig-mcu", "mega2560-gy86")
    assert done.returncode == 4, done.stdout + done.stderr  # pytest's usage error
    assert "--rig-mcu needs --rig-firmware FILE" in done.stderr


def test_rig_eeprom_starts_the_image_from_it(tmp_path):
    """The eeprom_count firmware (tests/mcu/firmware) counts its boots in EEPROM byte 0: started from 9,
    its run's eeprom.bin holds 10. (It drives no motor: the item fails as hung, the EEPROM is written.)"""
    shutil.copy(SHORT, tmp_path)
    (tmp_path / "start.bin").write_bytes(bytes([9]))
    junit = tmp_path / "junit.xml"
    done = pytest_run(tmp_path, str(tmp_path), "--rig-mcu", "mega2560-gy86", "--rig-firmware",
                      str(mcu.firmware("eeprom_count", "atmega2560")), "--rig-eeprom",
                      str(tmp_path / "start.bin"), f"--junitxml={junit}")
    assert done.returncode == 1, done.stdout + done.stderr
    props = {p.get("name"): p.get("value") for p in ET.parse(junit).getroot().iter("property")}
    assert (Path(props["report"]) / "eeprom.bin").read_bytes()[:6] == bytes([10]) + b"saved"
    alone = pytest_run(tmp_path, str(tmp_path), "--rig-eeprom", str(tmp_path / "start.bin"))
    assert alone.returncode == 4 and "--rig-eeprom goes with --rig-mcu BOARD" in alone.stderr


def test_ctrl_c_stops_the_dut_and_pytest_and_keeps_the_run(tmp_path):
    fifo = pid_fifo(tmp_path / "pid")
    shutil.copy(SHORT, tmp_path)
    dut = f"{sys.executable} {DUTS / 'stall_after_one_read.py'} {fifo}"
    proc = subprocess.Popen([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--rootdir",
                             str(tmp_path), str(tmp_path), "--rig-dut", dut, "--rig-out", "out"],
                            cwd=tmp_path, stdout=subprocess.PIPE, text=True, env=own_env())
    pid = read_pid(fifo)  # the DUT is up: the item is in its run
    proc.send_signal(signal.SIGINT)
    stdout = proc.communicate(timeout=60)[0]
    assert proc.returncode == 2, stdout  # pytest's "interrupted"
    assert "KeyboardInterrupt" in stdout and "the run's files are in" in stdout
    assert wait_gone(pid, timeout=0)  # the DUT is gone
    result = json.loads((tmp_path / "out" / "seed000_roll_stand" / "result.json").read_text())
    assert result["verdict"] == "interrupted" and "SIGINT" in result["error"]
