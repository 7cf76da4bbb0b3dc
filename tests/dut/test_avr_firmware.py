"""The AVR reference firmware (dut/avr) under simavr, without chips on its TWI: it builds within the
ATmega2560's memories; at start-up it says where its configuration came from (the blank EEPROM: the
defaults; a scenario's image from scenarios/eeprom.py: that image, at the AVR's loop rate; a corrupt
image: the defaults, and why) and, finding no MPU-6050, stops with no motor output. The cycle bench's
firmware formats a telemetry line from a known state, and the rig's own parser reads it back."""

from __future__ import annotations

import re
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.runner import parse_telemetry
from rig.scenarios import eeprom
from rig.scenarios.schema import load

REPO = Path(__file__).resolve().parents[2]
AVR = REPO / "build" / "avr"

@pytest.fixture(scope="module")
def built() -> str:
    done = subprocess.run(["make", "-s", "-C", str(REPO / "dut"), "avr", "avr-bench"], capture_output=True,
                          text=True, check=True)
    return done.stdout


def simavr_lines(args: list[str], until: str) -> Iterator[str]:
    """The firmware's USART0 lines under simavr (colour codes and simavr's trailing '.' removed), up to
    the first containing ``until``; simavr is ended then (the firmware itself never stops)."""
    cmd = ["stdbuf", "-oL", "simavr", "-m", "atmega2560", "-f", "16000000", *args]
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) as p:
        try:
            assert p.stdout is not None
            for raw in p.stdout:
                line = re.sub(r"\x1b\[[0-9;]*m", "", raw).rstrip("\n").rstrip(".")
                yield line
                if until in line:
                    return
            raise AssertionError(f"simavr ended before {until!r}")
        finally:
            p.kill()


def eeprom_hex(data: bytes, tmp: Path) -> Path:
    """Intel HEX at simavr's EEPROM address space (0x810000), for its -ee option."""
    ext = bytes([2, 0, 0, 4, 0x00, 0x81])
    path = tmp / "ee.hex"
    path.write_text(f":{ext.hex().upper()}{(-sum(ext)) & 0xFF:02X}\n" + eeprom.ihex(data))
    return path


def test_make_avr_reports_the_memories_against_the_mcus(built: str) -> None:
    m = re.search(r"flash (\d+) of 262144 bytes.*RAM (\d+) of 8192 bytes.*EEPROM (\d+) of 4096 bytes", built)
    assert m, built
    flash, ram, ee = map(int, m.groups())
    assert 0 < flash < 262144 and 0 < ram < 8192 - 1024
    assert ee == eeprom.size()
    assert (AVR / "fc.hex").is_file() and (AVR / "fc.eep").is_file()


def test_blank_eeprom_defaults_and_no_mpu_means_no_motor_output(built: str) -> None:
    lines = list(simavr_lines([str(AVR / "fc.elf")], until="no motor output"))
    assert any("configuration: the defaults; EEPROM image: blank" in s for s in lines), lines
    assert "# fc: MPU-6050: no answer; no motor output" in lines


def test_a_scenarios_image_configures_the_firmware(built: str, tmp_path: Path) -> None:
    sc = load(REPO / "scenarios" / "library" / "seed000_roll_stand.toml")
    ee = eeprom_hex(eeprom.image(sc.fc), tmp_path)
    lines = list(simavr_lines(["-ee", str(ee), str(AVR / "fc.hex")], until="no motor output"))
    assert "# fc: configuration: EEPROM image" in lines, lines
    assert any("est_rate_hz is over what the AVR fits: the loop runs at 75 Hz" in s for s in lines), lines


def test_a_corrupt_image_leaves_the_defaults_and_says_why(built: str, tmp_path: Path) -> None:
    data = bytearray(eeprom.image({"estimator": 1}))
    data[10] ^= 0x40
    lines = list(simavr_lines(["-ee", str(eeprom_hex(bytes(data), tmp_path)), str(AVR / "fc.hex")],
                              until="no motor output"))
    assert "# fc: configuration: the defaults; EEPROM image: crc" in lines, lines


def test_the_ekf_is_refused_on_the_avr(built: str, tmp_path: Path) -> None:
    ee = eeprom_hex(eeprom.image({"estimator": 2}), tmp_path)
    lines = list(simavr_lines(["-ee", str(ee), str(AVR / "fc.hex")], until="no motor output"))
    assert any("estimator 2 (the EKF) is not built for the AVR" in s for s in lines), lines


def test_the_firmwares_telemetry_line_is_what_the_rig_reads(built: str) -> None:
    lines = list(simavr_lines([str(AVR / "bench.elf")], until="B end"))
    tel = [s for s in lines if s.startswith("T ")]
    assert len(tel) == 1, lines
    cols, bad, nonfinite = parse_telemetry((tel[0] + "\n").encode(), 0.0)
    assert bad == 0 and not nonfinite
    assert cols["t"][0] == pytest.approx(2647.4836, abs=1e-9)  # 2^32 + 1e9 ticks of 0.5 us
    assert cols["roll"][0] == pytest.approx(5.730) and cols["pitch"][0] == pytest.approx(-11.459)
    assert cols["yaw"][0] == pytest.approx(171.887) and cols["alt"][0] == pytest.approx(-1.25)
    assert cols["armed"][0] == 1
    fields = dict(f.split("=", 1) for f in tel[0][2:].split())
    assert fields["cfg"] == "eeprom" and fields["twi_err"] == "6" and fields["sbus_bad"] == "13"
    assert all(re.fullmatch(r"B \w+ \d+", s) for s in lines if s.startswith("B ") and s != "B end")
