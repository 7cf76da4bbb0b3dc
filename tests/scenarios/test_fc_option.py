"""``--fc PROFILE`` wherever a DUT is chosen: the run records the profile and its SHA-256 (result.json,
JUnit, report.html, run.mcap), a bad name stops everything before it flies (exit 2, with a
suggestion), the API, the pytest plugin, sweeps and the service take it. The SHA-256 expected is
hashlib's of the shipped file."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from mcap.reader import make_reader

from rig.scenarios import profile as profiles
from rig.service.app import RunRequest, fc_problems
from rig.service.db import Db
from rig.service.store import Store
from rig.service.worker import command
from rig.sweep import store
from tests.api import SHORT
from tests.api.test_pytest_plugin import pytest_run

PY = sys.executable
MULTIWII = profiles.PROFILES / "multiwii-2.4.toml"
REFERENCE = profiles.PROFILES / "reference.toml"


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_a_run_records_its_profile_everywhere(tmp_path: Path) -> None:
    from rig import api

    r = api.run(SHORT, out=tmp_path, fc="reference")
    assert r.verdict == "pass", r.error
    meta = json.loads((r.run_dir / "result.json").read_text())["metadata"]
    assert (meta["fc_profile"], meta["fc_profile_sha256"]) == ("reference", sha(REFERENCE))
    assert meta["fc_profile_file"] == str(REFERENCE)
    props = {p.get("name"): p.get("value") for p in ET.parse(r.run_dir / "junit.xml").iter("property")}
    assert (props["fc_profile"], props["fc_profile_sha256"]) == ("reference", sha(REFERENCE))
    html = (r.run_dir / "report.html").read_text()
    assert "FC profile SHA-256" in html and sha(REFERENCE) in html
    with open(r.run_dir / "run.mcap", "rb") as f:
        meta_records = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    assert json.loads(meta_records["result"]["fc_profile_sha256"]) == sha(REFERENCE)


def test_a_bad_profile_stops_the_suite_before_anything_flies(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = subprocess.run([PY, "-m", "rig.cli", "run", str(SHORT), "--fc", "multiwii-24", "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "did you mean 'multiwii-2.4'" in done.stderr and "Traceback" not in done.stderr
    assert not (out / SHORT.stem).exists()
    bad = tmp_path / "bad.toml"
    bad.write_text('[arming]\nmethod = "swtich"\n')
    done = subprocess.run([PY, "-m", "rig.cli", "validate", "--fc", str(bad)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 2 and f"{bad}: arming.method" in done.stderr, done.stderr
    done = subprocess.run([PY, "-m", "rig.cli", "validate", "--fc", "multiwii-2.4"], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0 and "profile multiwii-2.4" in done.stdout, done.stderr


def test_exec_refuses_a_bad_profile_in_words(tmp_path: Path) -> None:
    done = subprocess.run([PY, "-m", "rig.cli", "exec", "--fc", "arducopter", "--", "true"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "did you mean 'arducopter-4'" in done.stderr, done.stderr


def test_the_pytest_plugin_takes_rig_fc(tmp_path: Path) -> None:
    (tmp_path / SHORT.name).write_text(SHORT.read_text())
    junit = tmp_path / "junit.xml"
    done = pytest_run(tmp_path, str(tmp_path), "--rig-fc", "reference", "--rig-out", "out",
                      f"--junitxml={junit}")
    assert done.returncode == 0, done.stdout + done.stderr
    props = {p.get("name"): p.get("value") for p in ET.parse(junit).iter("property")}
    assert (props["fc_profile"], props["fc_profile_sha256"]) == ("reference", sha(REFERENCE))


def test_a_sweep_s_dut_includes_its_profile() -> None:
    ref, mw = store.dut_identity(None), store.dut_identity(None, fc=str(MULTIWII))
    assert ref["fc_profile_sha256"] == sha(REFERENCE) and mw["fc_profile_sha256"] == sha(MULTIWII)
    assert not store.same_dut(ref, mw)  # (a sweep folder flown under one profile is not resumed by another)


def test_the_service_flies_shipped_profiles_only(tmp_path: Path) -> None:
    assert fc_problems("multiwii-2.4") == []
    assert "did you mean 'multiwii-2.4'" in fc_problems("multiwii")[0]
    assert "no shipped FC profile '/etc/passwd'" in fc_problems("/etc/passwd")[0]
    assert RunRequest(scenarios=["step_roll"], fc="multiwii-2.4").fc == "multiwii-2.4"

    db = Db(tmp_path / "rig.sqlite")
    try:
        run = {"mode": "lockstep", "scenarios": ["step_roll"], "seed": 0, "versions": {},
               "dut": {"fc": "multiwii-2.4"}}
        cmd, _ = command(run, tmp_path / "run", Store(tmp_path, db))
    finally:
        db.close()
    assert cmd[cmd.index("--fc") + 1] == "multiwii-2.4"


def test_a_sweep_the_fc_cannot_fly_is_refused_before_it_runs(tmp_path: Path) -> None:
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nscenario = "step_altitude"\nseeds = 2\n')
    out = tmp_path / "out"
    done = subprocess.run([PY, "-m", "rig.cli", "sweep", str(spec), "--out", str(out), "--fc",
                           "multiwii-2.4"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "has no alt_offset channel" in done.stderr, done.stderr
    assert not (out / "runs").exists()


def test_a_scenario_the_fc_cannot_fly_is_skipped_not_failed(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = subprocess.run([PY, "-m", "rig.cli", "run", "step_altitude", "--fc", "multiwii-2.4", "--out",
                           str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr  # neither a pass nor a failure
    assert "SKIPPED" in done.stderr and "1 skipped" in done.stderr
    assert "has no alt_offset channel" in done.stderr
    result = json.loads((out / "step_altitude" / "result.json").read_text())
    assert result["verdict"] == "skipped" and "has no alt_offset channel" in result["error"]
    suite = ET.parse(out / "junit.xml").getroot().find("testsuite")
    assert suite is not None and suite.get("skipped") == str(len(result["measurements"]))
    assert suite.get("failures") == "0" and suite.get("errors") == "0"
