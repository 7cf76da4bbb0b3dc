"""Talking to a firmware during a run: a scenario's [[serial]] sends (raw hex, or an MSP v1 command
checksummed) reach its USART at their time, and criteria on a USART judge what came back ("a line
matching R before t", "an MSP reply to command c"). The msp_calib firmware answers MSP_ACC_CALIBRATION
(205) as MultiWii does and keeps the accelerometer it read in EEPROM: the frames expected here are
written from MultiWii's published MSP v1 format, not from the rig's encoder."""

from __future__ import annotations

import json
import re
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from rig.scenarios import schema
from rig.scenarios.schema import ScenarioError
from rig.telemetry.msp import request
from rig.uart_criteria import matching_lines, replies
from tests.mcu.conftest import REPO, firmware

#: a Mega 2560 with a GY-86, four ESCs on timers 3 and 4, and neither RC input nor telemetry
BOARD = """
[board]
name = "mega-msp"
mcu = "atmega2560"
clock_hz = 16_000_000
[sensors]
bus = "twi"
topology = "gy86"
[[motors]]
motor = 1
pin = "PE4"
timer = 3
channel = "B"
[[motors]]
motor = 2
pin = "PE5"
timer = 3
channel = "C"
[[motors]]
motor = 3
pin = "PE3"
timer = 3
channel = "A"
[[motors]]
motor = 4
pin = "PH3"
timer = 4
channel = "A"
"""

SCENARIO = """
[scenario]
name = "msp calibration"
duration = 0.6
[sensors]
noise = false
[[serial]]
t = 0.3
uart = 0
msp = 205
[[serial]]
t = 0.4
uart = 0
hex = "24 4d 3c 00 64 64"    # MSP_IDENT by hand: $M< 0 100 checksum 100
[[criteria]]
name = "booted"
uart = 0
line = "^# mpu 0x68$"
end = 0.05
[[criteria]]
uart = 0
line = "^# baro 0x77$"
end = 0.05
[[criteria]]
uart = 0
msp_reply = 205
start = 0.3
end = 0.35
[[criteria]]
uart = 0
line = "acc calibrated"
start = 0.3
[[criteria]]
uart = 0
msp_reply = 100
start = 0.4
[[criteria]]
name = "never asked"
uart = 0
msp_reply = 101
"""


def test_msp_frames_are_multiwiis() -> None:
    """MultiWii's MSP v1: $M<, size, command, payload, XOR of size, command and payload."""
    assert request(205) == b"$M<\x00\xcd\xcd"
    assert request(200, bytes([0xDC, 0x05])) == b"$M<\x02\xc8\xdc\x05" + bytes([2 ^ 200 ^ 0xDC ^ 0x05])
    stream = b"noise$M>\x00\xcd\xcd$M>\x01\x64\x07\x00" + b"$M>\x00\x65\x65"  # (the second: a bad checksum)
    assert replies([(1, stream[:12]), (2, stream[12:])], 205) == [1]
    assert replies([(1, stream)], 100) == [] and replies([(7, stream)], 101) == [7]
    lines = matching_lines([(5, b"# a\r\nhal"), (9, b"f\n# b")], "^(# a|half)$")
    assert lines == [(5, "# a"), (9, "half")]


def test_a_scenario_talks_msp_to_the_firmware_and_judges_its_replies(tmp_path: Path) -> None:
    board = tmp_path / "mega-msp.toml"
    board.write_text(BOARD)
    scenario = tmp_path / "msp.toml"
    scenario.write_text(SCENARIO)
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", str(board), "--firmware",
                           str(firmware("msp_calib", "atmega2560")), str(scenario), "--out",
                           str(tmp_path / "out")],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    assert done.returncode == 1, done.stdout + done.stderr  # (only "never asked" fails)
    run = tmp_path / "out" / "msp"
    result = json.loads((run / "result.json").read_text())
    by_name = {m["name"]: m for m in result["measurements"]}
    assert [m["outcome"] for m in result["measurements"]] == ["pass"] * 5 + ["fail"]
    assert by_name["booted"]["value"] < 0.05
    # the reply comes after the request's 6 bytes at 115200 8N1 (87 us each), within a 1 ms step
    assert 0.3 < by_name["an MSP reply to 205 on USART0"]["value"] <= 0.302
    assert 0.4 < by_name["an MSP reply to 100 on USART0"]["value"] <= 0.402
    assert "no MSP reply to command 101 on USART 0" in by_name["never asked"]["reason"]
    # the calibration is in the EEPROM as it ended: the accelerometer at rest, level, with noise off,
    # reads 1 g on Z: 16384 LSB/g at the MPU-6050's power-on range of +-2 g (its datasheet)
    x, y, z, mark = struct.unpack_from("<hhhc", (run / "eeprom.bin").read_bytes())
    assert mark == b"C" and abs(x) < 200 and abs(y) < 200 and abs(z - 16384) < 300


@pytest.mark.parametrize(
    ("table", "words"),
    [("[[serial]]\nt = 0.1\nuart = 0\n", "expected either hex (raw bytes) or msp"),
     ("[[serial]]\nt = 0.1\nuart = 0\nhex = \"4g\"\n", "serial[0].hex: expected bytes in hex"),
     ("[[serial]]\nt = 0.1\nuart = 0\nmsp = 300\n", "serial[0].msp: expected a number in 0..255"),
     ("[[criteria]]\nuart = 0\nline = \"(\"\n", "criteria[1].line: not a regular expression"),
     ("[[criteria]]\nuart = 0\nmsp_reply = 5\nmax = 1\n", "criteria[1].max: a criterion on a USART")],
)
def test_bad_serial_tables_name_the_key(tmp_path: Path, table: str, words: str) -> None:
    path = tmp_path / "s.toml"
    path.write_text("[scenario]\nduration = 1\n[[criteria]]\nmetric = \"max\"\nsignal = \"roll\"\nmax = 5\n"
                    + table)
    with pytest.raises(ScenarioError, match=re.escape(words)):
        schema.load(path)


PROFILE_BAUD_SCENARIO = """
[scenario]
name = "msp at the profile's baud"
duration = 0.5
[sensors]
noise = false
[[serial]]
t = 0.3
uart = 0
msp = 100
[[criteria]]
uart = 0
msp_reply = 100
start = 0.3
"""


def test_a_profiles_telemetry_usart_and_baud_replace_the_boards(tmp_path: Path) -> None:
    """The board file wires USART0 for the reference FC's 500000 baud; the FC flown (msp_calib, as
    MultiWii, at 115200) is described by a profile whose telemetry is "usart0" at 115200: the scenario's
    MSP request (sent at the USART's baud) gets its reply, and no byte is a frame error."""
    board = tmp_path / "mega-tel.toml"
    board.write_text(BOARD + '[telemetry]\nuart = 0\nbaud = 500_000\nformat = "text"\n')
    profile = tmp_path / "mw.toml"
    profile.write_text((REPO / "scenarios" / "profiles" / "multiwii-2.4.toml").read_text())
    scenario = tmp_path / "baud.toml"
    scenario.write_text(PROFILE_BAUD_SCENARIO)
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", str(board), "--firmware",
                           str(firmware("msp_calib", "atmega2560")), "--fc", str(profile), str(scenario),
                           "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    result = json.loads((tmp_path / "out" / "baud" / "result.json").read_text())
    assert result["metadata"]["mcu"]["uarts"]["0"]["frame_errors"] == 0
    # a USART the MCU lacks, or a baud no USART makes at 16 MHz, is the profile's error before the run
    for key, bad, words in (("port", '"usart7"', "has USART 0, 1, 2, 3 only, not 7"),
                            ("baud", "3_000_000", "telemetry.baud: 3000000 baud is over 3% off")):
        profile.write_text(re.sub(rf"(?m)^{key} = .*$", f"{key} = {bad}", profile.read_text(), count=1))
        done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", str(board), "--firmware",
                               str(firmware("msp_calib", "atmega2560")), "--fc", str(profile),
                               str(scenario), "--out", str(tmp_path / "out")],
                              capture_output=True, text=True, cwd=REPO, timeout=300)
        assert done.returncode == 2 and words in done.stderr, done.stderr
        profile.write_text((REPO / "scenarios" / "profiles" / "multiwii-2.4.toml").read_text())
