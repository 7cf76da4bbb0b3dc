"""A Linux DUT's board chosen where runs are started (rig run, the API, the pytest plugin, the
service): how many sysfs PWM channels it has and how its I2C bus is wired, with clear refusals of
values no board has."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pydantic
import pytest

from rig import api
from rig.service.app import RunRequest, dut_of
from tests.rig.helpers import DUTS
from tests.short_scenario import SHORT_BENCH


def test_rig_run_gives_the_dut_fourteen_channels_and_the_direct_wiring(tmp_path: Path) -> None:
    scenario = tmp_path / "short.toml"
    scenario.write_text(SHORT_BENCH)
    r = api.run(scenario, dut=[sys.executable, str(DUTS / "board_probe.py")], out=tmp_path / "out",
                pwm_channels=14, topology="direct", wall_timeout=120.0)
    seen = json.loads((r.run_dir / "dut-stdout.txt").read_text())
    # HMC5883L identification registers A, B, C read "H43" (datasheet, table 2)
    assert seen == {"npwm": 14, "compass": "H43"}
    assert r.metadata["pwm_channels"] == 14 and r.metadata["topology"] == "direct"


def test_by_default_the_compass_hides_behind_the_mpu(tmp_path: Path) -> None:
    scenario = tmp_path / "short.toml"
    scenario.write_text(SHORT_BENCH)
    r = api.run(scenario, dut=[sys.executable, str(DUTS / "board_probe.py")], out=tmp_path / "out",
                wall_timeout=120.0)
    seen = json.loads((r.run_dir / "dut-stdout.txt").read_text())
    assert seen == {"npwm": 8, "compass": "No such device or address"}   # ENXIO: nobody at 0x1E
    assert "pwm_channels" not in r.metadata


@pytest.mark.parametrize(("options", "said"), [
    ({"pwm_channels": 0}, "^pwm_channels must be between 1 and 16, got 0"),
    ({"pwm_channels": 17}, "^pwm_channels must be between 1 and 16, got 17"),
    ({"topology": "star"}, "argument topology: invalid choice: 'star'"),
    ({"topology": "direct", "bridge": "virtual"}, "not with bridge or mcu"),
])
def test_the_api_refuses_a_board_no_dut_has(tmp_path: Path, options: dict[str, object], said: str) -> None:
    with pytest.raises(api.RigError, match=said):
        api.run("seed000_roll_stand", out=tmp_path / "out", **options)  # type: ignore[arg-type]
    assert not (tmp_path / "out").exists()


def test_rig_exec_and_the_pytest_plugin_refuse_with_exit_2(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--pwm-channels", "17", "--", "true"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "--pwm-channels must be between 1 and 16, got 17" in r.stderr
    r = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--rig-pwm-channels", "20",
                        str(tmp_path)], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert r.returncode == 4 and "--rig-pwm-channels must be between 1 and 16, got 20" in r.stderr  # usage


def test_the_services_run_request_carries_the_board() -> None:
    req = RunRequest(scenarios=["step_roll"], dut={"command": "./fc"}, pwm_channels=14, topology="direct")
    assert dut_of(req) == {"command": "./fc", "pwm_channels": "14", "topology": "direct"}
    for bad in ({"pwm_channels": 17}, {"pwm_channels": 0}, {"topology": "star"}):
        with pytest.raises(pydantic.ValidationError):
            RunRequest(scenarios=["step_roll"], **bad)


def test_the_services_worker_flies_the_board_it_was_asked_for(tmp_path: Path) -> None:
    from rig.service.db import Db
    from rig.service.store import Store
    from rig.service.worker import command

    db = Db(tmp_path / "rig.sqlite")
    store = Store(tmp_path, db)
    req = RunRequest(scenarios=["step_roll"], pwm_channels=14, topology="direct")
    run = {"mode": "lockstep", "scenarios": ["step_roll"], "seed": 0, "dut": dut_of(req), "versions": {}}
    cmd, _ = command(run, tmp_path / "out", store)
    assert cmd[cmd.index("--pwm-channels") + 1] == "14" and cmd[cmd.index("--topology") + 1] == "direct"
