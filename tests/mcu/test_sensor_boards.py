"""Sensor boards beside the GY-86: a GY-521 (an MPU-6050 alone on the bus, nothing behind it) at 0x68 or,
its AD0 pin high, at 0x69 (the MPU-6050 datasheet: "the LSB bit of the 7 bit address is determined by
the logic level on pin AD0"), on boards with neither RC input nor telemetry. The msp_calib firmware
probes 0x68, then 0x69, then an MS5611 at 0x77, and says on USART0 what answered."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu import board
from rig.mcu.board import BoardError
from tests.mcu.conftest import REPO, firmware

SCENARIO = """
[scenario]
name = "who answers"
duration = 0.2
[[criteria]]
name = "the MPU answered"
uart = 0
line = "^# mpu {address}$"
end = 0.05
[[criteria]]
name = "motors pulsed"
metric = "max"
signal = "pwm1"
min = 990
max = 1010
"""


def test_the_shipped_gy521_board_has_the_mpu_alone_and_no_rc_or_telemetry() -> None:
    nano = board.load("nano328-gy521")
    assert nano.topology == "gy521" and nano.mpu_address == 0x68 and nano.mcu.name == "atmega328p"
    assert nano.rc is None and nano.telemetry_uart is None


@pytest.mark.parametrize(("mcu", "address", "nacks"), [("atmega328p", 0x68, 1), ("atmega2560", 0x69, 2)])
def test_a_gy521_answers_at_its_address_and_nothing_else_does(tmp_path: Path, mcu: str, address: int,
                                                               nacks: int) -> None:
    """At 0x68 the probe of 0x77 is the one NACK; at 0x69 the probe of 0x68 is another. The ESC pulses
    are msp_calib's 2000 counts at 2 MHz: 1000 us."""
    text = board.find("nano328-gy521").read_text()
    if mcu == "atmega2560":  # (the Mega's timer 3 pins, where msp_calib pulses on the 2560)
        text = text.replace('"atmega328p"', '"atmega2560"')
        text = text.replace("mpu_address = 0x68", "mpu_address = 0x69")
        for old, new in (('"PB1"', '"PE3"'), ('"PB2"', '"PE4"'), ('"PB3"', '"PE5"'), ('"PD3"', '"PH3"')):
            text = text.replace(old, new, 1)
        text = text.replace('timer = 1\nchannel = "A"', 'timer = 3\nchannel = "A"')
        text = text.replace('timer = 1\nchannel = "B"', 'timer = 3\nchannel = "B"')
        text = text.replace('timer = 2\nchannel = "A"', 'timer = 3\nchannel = "C"')
        text = text.replace('timer = 2\nchannel = "B"', 'timer = 4\nchannel = "A"')
    path = tmp_path / "board.toml"
    path.write_text(text)
    scenario = tmp_path / "who.toml"
    scenario.write_text(SCENARIO.format(address=f"{address:#04x}"))
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", str(path), "--firmware",
                           str(firmware("msp_calib", mcu)), str(scenario), "--out",
                           str(tmp_path / "out")],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    result = json.loads((tmp_path / "out" / "who" / "result.json").read_text())
    assert result["metadata"]["bus_problems"]["address_nacks"] == nacks


@pytest.mark.parametrize(
    ("change", "key", "words"),
    [(("mpu_address = 0x68", "mpu_address = 0x6A"), "sensors.mpu_address", "0x68 (AD0 low) or 0x69"),
     (('topology = "gy521"', 'topology = "gy512"'), "sensors.topology",
      "expected one of gy86, direct, gy521")],
)
def test_sensor_board_mistakes_name_the_key(tmp_path: Path, change: tuple[str, str], key: str,
                                            words: str) -> None:
    path = tmp_path / "b.toml"
    path.write_text(board.find("nano328-gy521").read_text().replace(*change))
    with pytest.raises(BoardError) as e:
        board.load(path)
    assert e.value.key == key and words in str(e.value)
