"""The reference FC as STM32F405 firmware (dut/stm32, `make stm32`) flies through the STM32 tier: a
roll step in angle mode on the attitude stand, judged by the rig's criteria, with the FC's own telemetry
on USART6 (the board file's [telemetry]) and the scenario's [fc] table in its settings flash (the
board file's [eeprom] fc = true: rig/mcu/stm32_image.py with_settings). Expected values from the
scenario and the board: the roll set point the sticks command, one pulse per 2041 us period on each
motor (84 MHz / 84 / 2041), the telemetry's keys as the Linux FC writes them."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu.image import FirmwareError
from rig.mcu.stm32_image import with_settings
from tests.stm32.conftest import REPO, engine_or_skip, firmware

DURATION_S = 3.5
STEP_AT_S = 2.0
STEP_DEG = 10.0
PWM_PERIOD_S = 2041e-6
SCENARIO = f"""
[scenario]
name = "STM32 reference FC, roll step"
duration = {DURATION_S}

[vehicle]
stand = 4

[fc]
estimator = 1

[[timeline]]
t = 1.2
arm = true
mode = "angle"
sticks = {{ throttle = 0.0 }}

[[timeline]]
t = 1.5
sticks = {{ throttle = 0.5 }}

[[timeline]]
t = {STEP_AT_S}
sticks = {{ roll_deg = {STEP_DEG} }}

[[criteria]]
metric = "rise_time"
signal = "roll"
target = {STEP_DEG}
start = {STEP_AT_S}
end = {DURATION_S}
max = 0.6

[[criteria]]
metric = "overshoot"
signal = "roll"
target = {STEP_DEG}
start = {STEP_AT_S}
end = {DURATION_S}
max = 20.0
"""


def reference_fc() -> Path:
    done = subprocess.run(["make", "-s", "--no-print-directory", "INSTALLED=1", "stm32"], cwd=REPO,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return REPO / "build" / "stm32" / "fc.elf"


def test_the_reference_fc_flies_a_roll_step(tmp_path: Path) -> None:
    engine_or_skip()
    elf = reference_fc()
    scenario = tmp_path / "stm32_fc_step.toml"
    scenario.write_text(SCENARIO)
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", "stm32f405-gy86", "--firmware",
                           str(elf), str(scenario), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=600, cwd=REPO)
    assert done.returncode == 0, done.stdout + done.stderr
    out = tmp_path / "out" / "stm32_fc_step"
    r = json.loads((out / "result.json").read_text())
    assert r["verdict"] == "pass", r["error"]
    assert [m["outcome"] for m in r["measurements"]] == ["pass", "pass"]
    mcu = r["metadata"]["mcu"]
    assert mcu["twi_nacks"] == 0 and mcu["ipsr"] == 0 and mcu["cfsr"] == 0
    periods = DURATION_S / PWM_PERIOD_S
    assert all(periods - 5 <= n <= periods + 2 for n in mcu["motor_pulses"]), mcu["motor_pulses"]
    # the FC's own lines on USART6: its start-up, then "T ..." lines with the Linux FC's keys; armed by the
    # sticks at 1.2 s, and its estimate holding the commanded roll at the end (the lines whole: the USART
    # sends 50 bytes a millisecond, so the run's end may cut the last)
    raw = (out / "dut-telemetry.txt").read_text()
    text = raw[:raw.rfind("\n") + 1].splitlines()
    assert text[0] == "# fc: STM32F405 reference FC"
    assert text[1] == "# fc: configuration: flash image"
    assert "# fc: running" in text
    last = dict(kv.split("=", 1) for kv in [ln for ln in text if ln.startswith("T ")][-1].split()[1:])
    assert {"t", "roll", "pitch", "yaw", "alt", "armed", "rc", "gyro_fault", "loop_us", "max_us",
            "overruns"} <= last.keys()
    assert last["armed"] == "1" and last["rc"] == "1" and last["overruns"] == "0" and last["cfg"] == "flash"
    assert abs(float(last["roll"]) - STEP_DEG) < 1.0
    assert float(last["t"]) > DURATION_S - 0.1


def test_the_settings_go_into_the_config_section_and_only_there(tmp_path: Path) -> None:
    elf = reference_fc()
    settings = bytes(range(40))
    copy = with_settings(elf, settings, tmp_path / "fc.elf")

    def section(path: Path) -> bytes:  # binutils' reading of the section, not ours
        out = tmp_path / "section.bin"
        subprocess.run(["arm-none-eabi-objcopy", "-O", "binary", "--only-section=.fc_config", str(path),
                        str(out)], check=True)
        return out.read_bytes()

    built = section(elf)
    assert built == b"\xff" * len(built) and len(built) > len(settings)
    assert section(copy) == settings + b"\xff" * (len(built) - len(settings))
    a, b = elf.read_bytes(), copy.read_bytes()
    assert len(a) == len(b) and sum(x != y for x, y in zip(a, b, strict=True)) <= len(settings)
    with pytest.raises(FirmwareError, match="fc_config section has"):
        with_settings(elf, b"\0" * (len(built) + 1), tmp_path / "big.elf")
    # a firmware without the section boots as built
    assert with_settings(firmware("hover_rate"), settings, tmp_path / "h.elf") == firmware("hover_rate")
