"""The STM32 tier end to end: ``rig run --mcu stm32f405-gy86 --firmware FILE`` flies our hover firmware
(tests/stm32/firmware/hover_rate.c: the gyro over I2C1 with the HAL's polling, four PWM outputs on TIM3
and TIM2) through a scenario to a result; the same seed gives the same bytes; a bad image is exit 2
before anything runs. Expected counts from the firmware's design: one register write and one 6-byte
read per PWM period of 2041 us (TIM3: 84 MHz / 84 / 2041), after half a second of ESC arming."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from rig.runner import run
from rig.scenarios.schema import load
from rig.targets.mcu import McuTarget
from tests.scenarios.test_mcap import read
from tests.stm32.conftest import REPO, engine_or_skip, firmware

DURATION_S = 2.0
PWM_PERIOD_S = 2041e-6
ARM_PERIODS = 245
SCENARIO = f"""
[scenario]
name = "STM32 hover firmware, still air"
duration = {DURATION_S}

[[criteria]]
name = "attitude inside +-10 deg"
metric = "max"
signal = "tilt"
start = 0.5
max = 10.0
"""


def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "stm32_hover.toml"
    path.write_text(SCENARIO)
    return path


def rig_run(elf: Path, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", "stm32f405-gy86", "--firmware",
                           str(elf), str(scenario(tmp_path)), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=600, cwd=REPO)


def test_the_hover_firmware_flies_a_scenario_to_a_result(tmp_path: Path) -> None:
    engine_or_skip()
    done = rig_run(firmware("hover_rate"), tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    r = json.loads((tmp_path / "out" / "stm32_hover" / "result.json").read_text())
    assert r["verdict"] == "pass", r["error"]
    meta = r["metadata"]
    assert meta["mode"] == "mcu" and meta["board"] == "stm32f405-gy86"
    mcu = meta["mcu"]
    periods = int(DURATION_S / PWM_PERIOD_S)
    # a write of GYRO_XOUT_H's address and a read of it per period: the first four transactions set it up
    assert abs(mcu["twi_transactions"] - 4 - 2 * periods) <= 2
    assert mcu["twi_nacks"] == 0 and mcu["ipsr"] == 0
    # a pulse every period on each motor, the first at the start (a few milliseconds of set-up before it)
    assert all(periods - 5 <= n <= periods + 2 for n in mcu["motor_pulses"]), mcu["motor_pulses"]
    # run.mcap's /i2c: every transaction, the gyro's reads 6 bytes from 0x43 (GYRO_XOUT_H)
    _, by_topic, _ = read(tmp_path / "out" / "stm32_hover" / "run.mcap")
    i2c = [m for _, m in by_topic["/i2c"]]
    assert len(i2c) == mcu["twi_transactions"]
    gyro = [m for m in i2c if m["address"] == 0x68 and m["register"] == 0x43 and m["read"]]
    assert len(gyro) >= periods - 1 and all(len(bytes.fromhex(m["read"])) == 6 for m in gyro)


def test_the_same_seed_gives_the_same_bytes(tmp_path: Path) -> None:
    engine_or_skip()
    sc = load(scenario(tmp_path))
    a = run(sc, McuTarget("stm32f405-gy86", firmware("hover_rate")), 3, tmp_path / "a")
    b = run(sc, McuTarget("stm32f405-gy86", firmware("hover_rate")), 3, tmp_path / "b")
    assert a.verdict == b.verdict == "pass"
    assert [m.value for m in a.measurements] == [m.value for m in b.measurements]
    assert all((a.signals[k] == b.signals[k]).all() for k in ("roll", "pitch", "pwm1", "pwm4"))
    assert a.i2c and a.i2c == b.i2c  # every transfer: its time, address, register and bytes


def test_an_avr_image_for_the_stm32_board_is_exit_2(tmp_path: Path) -> None:
    elf = tmp_path / "avr.elf"
    data = bytearray(firmware("hover_rate").read_bytes())
    data[18:20] = (83).to_bytes(2, "little")  # EM_AVR
    elf.write_bytes(bytes(data))
    done = rig_run(elf, tmp_path)
    assert done.returncode == 2
    assert "ARM (machine 40)" in done.stderr + done.stdout
