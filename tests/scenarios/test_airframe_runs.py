"""Airframes where a vehicle is chosen: `[vehicle] airframe =` in a scenario, `--airframe` on rig run,
exec and sweep, the API; every report names the airframe, and says when it is the seed's inconsistent
one. The reference FC flies the 450-class airframe."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from rig.scenarios.schema import ScenarioError, load
from tests.suite_rules import NOT_BUILT

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"
PY = sys.executable
REFERENCE_FC = Path(__file__).resolve().parents[2] / "build" / "dut" / "fc"

SCENARIO = """[scenario]
name = "on an airframe"
duration = 2.0
[vehicle]
{vehicle}
[[criteria]]
name = "level"
metric = "max"
signal = "tilt"
max = 5.0
"""


def rig(command: str, *args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PY, "-m", "rig.cli", command, *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def _scenario(tmp_path: Path, vehicle: str) -> Path:
    path = tmp_path / "on_airframe.toml"
    path.write_text(SCENARIO.format(vehicle=vehicle))
    return path


def test_a_scenario_names_its_airframe_and_its_vehicle_keys_apply_on_top(tmp_path):
    sc = load(_scenario(tmp_path, 'airframe = "f450"\nmass = 1.5'))
    assert sc.airframe.name == "f450"
    params = sc.plant_params()
    assert params["mass"] == 1.5 and params["Ixx"] == 0.0211  # the scenario's mass, the F450's inertia
    assert load(LIB / "step_roll.toml").airframe.name == "seed-001"  # the default


def test_a_scenario_with_an_unknown_airframe_is_refused_with_a_suggestion(tmp_path):
    with pytest.raises(ScenarioError, match="vehicle.airframe: .*did you mean 'f450'"):
        load(_scenario(tmp_path, 'airframe = "f45"'))


def test_an_airframe_file_beside_the_scenario_is_found_from_the_scenario(tmp_path):
    (tmp_path / "mine.toml").write_text(
        '[airframe]\nname = "mine"\nsource = "weighed and swung on a bifilar pendulum, lab notes 2026"\n'
        "[params]\nmass = 0.9\nIxx = 0.008\nIyy = 0.008\nIzz = 0.015\n")
    sc = load(_scenario(tmp_path, 'airframe = "mine.toml"'))
    assert sc.airframe.name == "mine" and sc.plant_params()["mass"] == 0.9


def test_vehicle_keys_that_break_the_triangle_on_the_airframe_are_refused(tmp_path):
    with pytest.raises(ScenarioError, match="vehicle.Izz: the plant refuses it: Izz must be <= Ixx"):
        load(_scenario(tmp_path, 'airframe = "f450"\nIzz = 0.05'))


@pytest.mark.usefixtures("fmu_path")
def test_the_reference_fc_flies_the_450_class_airframe_and_the_reports_say_which(tmp_path):
    if not REFERENCE_FC.is_file():
        pytest.skip(f"{NOT_BUILT}the reference FC (make dut)")
    out = tmp_path / "out"
    done = rig("run", "step_roll", "--airframe", "f450", "--out", out)
    assert done.returncode == 0, done.stdout + done.stderr  # every step_roll criterion, on the F450
    result = json.loads((out / "step_roll" / "result.json").read_text())
    meta = result["metadata"]
    assert meta["airframe"].startswith("f450 (450-class") and "inconsistent" not in meta["airframe"]
    assert len(meta["airframe_sha256"]) == 64
    props = {p.get("name"): p.get("value") for p in ET.parse(out / "junit.xml").iter("property")}
    assert props["airframe"] == meta["airframe"]
    assert "f450" in (out / "step_roll" / "report.html").read_text()


@pytest.mark.usefixtures("fmu_path")
def test_a_run_on_the_seeds_airframe_says_it_is_physically_inconsistent(tmp_path):
    if not REFERENCE_FC.is_file():
        pytest.skip(f"{NOT_BUILT}the reference FC (make dut)")
    out = tmp_path / "out"
    rig("run", "step_roll", "--out", out)
    meta = json.loads((out / "step_roll" / "result.json").read_text())["metadata"]
    assert meta["airframe"].startswith("seed-001") and "physically inconsistent" in meta["airframe"]
    assert "physically inconsistent" in (out / "step_roll" / "report.html").read_text()
    assert "physically inconsistent" in (out / "index.html").read_text()  # the suite's identity too


@pytest.mark.parametrize("command", ["run", "sweep", "exec"])
def test_a_bad_airframe_is_a_usage_error_on_every_command(tmp_path, command):
    bad = tmp_path / "bad.toml"
    bad.write_text('[airframe]\nname = "bad"\nsource = "a made-up frame, 2026"\n'
                   "[params]\nIxx = 0.001\nIyy = 0.001\nIzz = 0.01\n")
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nscenario = "step_roll"\n')
    words = {"run": ["step_roll", "--out", tmp_path / "out"], "sweep": [spec, "--out", tmp_path / "out"],
             "exec": ["--duration", "1", "--", "true"]}[command]
    done = rig(command, "--airframe", bad, *words)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "Izz must be <= Ixx + Iyy" in done.stderr
    done = rig(command, "--airframe", "nosuch", *words)
    assert done.returncode == 2 and "no such airframe" in done.stderr


@pytest.mark.usefixtures("fmu_path")
def test_the_api_flies_an_airframe(tmp_path):
    if not REFERENCE_FC.is_file():
        pytest.skip(f"{NOT_BUILT}the reference FC (make dut)")
    from rig import api

    result = api.run("step_roll", airframe="racer-250", out=tmp_path)
    assert result.metadata["airframe"].startswith("racer-250 (250-class")


@pytest.mark.usefixtures("fmu_path")
def test_a_sweep_flies_every_variant_on_the_airframe(tmp_path):
    if not REFERENCE_FC.is_file():
        pytest.skip(f"{NOT_BUILT}the reference FC (make dut)")
    _scenario(tmp_path, "mass = 1.5")
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nscenario = "on_airframe.toml"\nseeds = 1\n'
                    '[[sweep.vary]]\nkey = "environment.wind"\nvalues = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]\n')
    done = rig("sweep", spec, "--airframe", "f450", "--out", tmp_path / "out", "--jobs", "1")
    assert done.returncode in (0, 1), done.stdout + done.stderr
    results = sorted((tmp_path / "out" / "runs").glob("*/result.json"))
    assert len(results) == 2
    for path in results:
        meta = json.loads(path.read_text())["metadata"]
        assert meta["airframe"].startswith("f450")
