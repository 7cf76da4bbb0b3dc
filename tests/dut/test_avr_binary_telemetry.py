"""The AVR reference firmware's MSP and MAVLink telemetry and stick arming, flown under the MCU tier
(simavr, the emulated GY-86) with its options in the EEPROM image: MAVLink decoded by pymavlink, MSP
against MultiWii's published byte layout (tests/dut/test_binary_telemetry.py writes it out)."""

from __future__ import annotations

import math
import struct
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common

from rig.targets import TELEMETRY_PATH
from rig.world import World
from tests.dut.test_binary_telemetry import frames, msp_replies, msp_request, standard_raw, sticks

REPO = Path(__file__).resolve().parents[2]
ELF = REPO / "build" / "avr" / "fc.elf"


@pytest.fixture(scope="module")
def firmware() -> Path:
    subprocess.run(["make", "-s", "-C", str(REPO / "dut"), "avr"], capture_output=True, check=True)
    return ELF


def fly(firmware: Path, fc: dict[str, Any], duration: float,
        events: list[tuple[float, Callable[[Any], None]]]) -> bytes:
    from rig.targets.mcu import McuTarget

    session = McuTarget("mega2560-gy86", firmware).session(World.at_rest(), duration, fc, 600.0)
    for t, fn in events:
        session.at(t, fn)
    outcome = session.run()
    assert outcome.verdict == "ok", outcome.error
    return session.serial_output(TELEMETRY_PATH)


def test_the_avr_answers_msp_and_arms_by_sticks(firmware: Path) -> None:
    low, right = standard_raw(-1), standard_raw(1)
    plan = frames(0.5, 2.0, lambda t: sticks(low, 992)) + frames(2.0, 3.3, lambda t: sticks(low, right))

    def poll(data: bytes) -> Callable[[Any], None]:
        return lambda s: s.serial_write(TELEMETRY_PATH, data)

    polls = [(1.9, msp_request(101)), (3.4, msp_request(101) + msp_request(108) + msp_request(109))]
    out = fly(firmware, {"telemetry_proto": 1, "arming": 1, "arm_hold_s": 1.0}, 3.6,
              plan + [(t, poll(d)) for t, d in polls])
    replies = msp_replies(out)
    status = [struct.unpack("<HHHIB", p) for c, p in replies if c == 101]
    assert [s[3] & 1 for s in status] == [0, 1]  # disarmed; armed after 1 s of throttle low, yaw right
    assert all(s[2] == 0b111 and 0 < s[0] < 6670 for s in status)  # its slot is 6.67 ms
    (roll, pitch, _heading), = [struct.unpack("<hhh", p) for c, p in replies if c == 108]
    assert abs(roll) < 20 and abs(pitch) < 20  # 0.1 deg: level within 2 degrees
    (alt_cm, _vario), = [struct.unpack("<ih", p) for c, p in replies if c == 109]
    assert abs(alt_cm) < 100


def test_the_avr_streams_mavlink_that_pymavlink_reads(firmware: Path) -> None:
    out = fly(firmware, {"telemetry_proto": 2}, 3.5, [])
    start = out.find(b"\xfd")  # (the start-up messages are text lines, before the loop's stream)
    messages = common.MAVLink(None).parse_buffer(out[start:])  # raises on a bad frame
    assert messages
    kinds = {m.get_type() for m in messages}
    assert {"HEARTBEAT", "ATTITUDE", "SCALED_IMU", "VFR_HUD"} <= kinds and "BAD_DATA" not in kinds
    attitude = [m for m in messages if m.get_type() == "ATTITUDE"]
    assert all(abs(a.roll) < math.radians(2) and abs(a.pitch) < math.radians(2) for a in attitude)
    imu = [m for m in messages if m.get_type() == "SCALED_IMU"]
    assert all(abs(m.zacc + 1000) < 40 for m in imu)
    beats = [m for m in messages if m.get_type() == "HEARTBEAT"]
    assert beats and all(not b.base_mode & 128 and b.type == 2 for b in beats)
