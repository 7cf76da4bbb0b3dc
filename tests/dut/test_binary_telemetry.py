"""The reference FC's options (its config file) for flying as third-party FCs do: MSP and MAVLink
telemetry, MultiWii's stick arming and its SBUS scale. The Linux FC under the rig, checked against
independent truth: MSP frames against the byte layout MultiWii publishes (written out here), MAVLink
against pymavlink (generated from the published common.xml), the SBUS scale against MultiWii's
formula."""

from __future__ import annotations

import math
import struct
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common

from rig.session import Session
from rig.telemetry.msp import MspPoll
from tests.dut.test_reference_fc import REPO, run_fc, telemetry

TEL, RC = "/dev/ttyTEL0", "/dev/ttyRC0"


@pytest.fixture(scope="module")
def fc() -> Path:
    subprocess.run(["make", "-s", "-C", str(REPO / "dut")], check=True)
    return REPO / "build" / "dut" / "fc"


# ---- SBUS frames, written here: 0x0F, 16 channels of 11 bits LSB first, flags, 0x00 ----------------


def sbus_frame(channels: list[int]) -> bytes:
    acc = sum(c << (11 * i) for i, c in enumerate(channels))
    return b"\x0f" + acc.to_bytes(22, "little") + b"\x00\x00"


def standard_raw(x: float) -> int:
    """A stick position -1..1 as a transmitter's SBUS value (172..1811, centre 992)."""
    return max(172, min(1811, round(992 + x * 819.5)))


def frames(start: float, end: float, channels: Callable[[float], list[int]]) -> list[tuple[float, Callable]]:
    """An SBUS frame every 14 ms from start to end, each carrying channels(t)."""
    out = []
    for k in range(int((end - start) / 0.014)):
        t = start + 0.014 * k

        def send(s: Session, data: bytes = sbus_frame(channels(t))) -> None:
            s.serial_write(RC, data)

        out.append((t, send))
    return out


def sticks(throttle: int, yaw: int, arm: int = 172) -> list[int]:
    """AETR: roll, pitch centred; then throttle, yaw, the arm switch (low), the rest centred."""
    return [992, 992, throttle, yaw, arm] + [992] * 11


# ---- MSP, as MultiWii publishes it: $M< size cmd payload xor / $M> size cmd payload xor -------------


def msp_request(cmd: int) -> bytes:
    return b"$M<" + bytes([0, cmd, cmd])  # (size 0: the checksum is 0 ^ cmd)


def msp_replies(data: bytes) -> list[tuple[int, bytes]]:
    """Every well-formed reply ($M>) in order; asserts that each checksum is right."""
    out, i = [], 0
    while (i := data.find(b"$M>", i)) >= 0:
        size, cmd = data[i + 3], data[i + 4]
        payload = data[i + 5: i + 5 + size]
        check = size ^ cmd
        for b in payload:
            check ^= b
        assert data[i + 5 + size] == check, data[i:].hex()
        out.append((cmd, payload))
        i += 6 + size
    return out


def test_msp_answers_status_attitude_imu_and_altitude_and_stick_arming(tmp_path: Path, fc: Path) -> None:
    conf = (f"rc_path = {RC}\ntelemetry_path = {TEL}\ntelemetry_proto = 1\narming = 1\n"
            "arm_hold_s = 1.0\n")
    low, right, left, centre = standard_raw(-1), standard_raw(1), standard_raw(-1), 992
    plan = frames(1.1, 2.0, lambda t: sticks(low, centre))          # throttle low, nothing else
    plan += frames(2.0, 2.6, lambda t: sticks(low, right))          # yaw right, 0.6 s: too short
    plan += frames(2.6, 2.8, lambda t: sticks(low, centre))
    plan += frames(2.8, 4.2, lambda t: sticks(low, right))          # yaw right, 1.4 s: arms at 3.8
    plan += frames(4.2, 4.6, lambda t: sticks(low, centre))
    plan += frames(4.6, 5.9, lambda t: sticks(low, left))           # yaw left, 1.3 s: disarms at 5.6

    polls: list[tuple[float, bytes]] = [
        (1.9, msp_request(101)), (2.7, msp_request(101)), (4.4, msp_request(101)),
        (4.4, msp_request(108) + msp_request(102) + msp_request(109)),
        (4.45, b"\x00garbage$M<\x00\x65\x00" + msp_request(101)),   # a bad checksum: no answer
        (4.5, msp_request(42)),                                      # not answered: an error frame
        (5.95, msp_request(101)),
    ]

    def poll(data: bytes) -> Callable[[Session], None]:
        return lambda s: s.serial_write(TEL, data)

    events = plan + [(t, poll(d)) for t, d in polls]
    session, outcome, _, err = run_fc(tmp_path, fc, conf, duration=6.0, serial=(RC, TEL), events=events)
    assert outcome.verdict == "ok", (outcome.error, err)
    out = session.serial_output(TEL)
    replies = msp_replies(out)
    status = [struct.unpack("<HHHIB", p) for c, p in replies if c == 101]
    assert len(status) == 5  # four polls and the one after the damaged request
    armed = [s[3] & 1 for s in status]
    assert armed == [0, 0, 1, 1, 0]  # not yet, too short, armed, still, disarmed by yaw left
    for cycle_us, _i2c_errors, sensors, flags, current_set in status:
        assert sensors == 0b111 and flags & 2 and current_set == 0  # acc, baro, mag; angle mode
        assert 0 < cycle_us < 4000
    att = [struct.unpack("<hhh", p) for c, p in replies if c == 108]
    imu = [struct.unpack("<9h", p) for c, p in replies if c == 102]
    alt = [struct.unpack("<ih", p) for c, p in replies if c == 109]
    assert len(att) == len(imu) == len(alt) == 1
    roll, pitch, heading = att[0]
    assert abs(roll) < 10 and abs(pitch) < 10 and -180 <= heading <= 180   # level: under 1 degree
    acc, gyro = imu[0][:3], imu[0][3:6]
    assert abs(acc[0]) < 20 and abs(acc[1]) < 20 and acc[2] == pytest.approx(512, abs=20)  # 1 g = 512
    assert all(abs(g) < 20 for g in gyro)  # at rest: under 5 deg/s
    assert abs(alt[0][0]) < 50 and abs(alt[0][1]) < 50  # cm, cm/s: on the ground
    assert out.count(b"$M!") == 1 and b"$M!\x00\x2a\x2a" in out  # the error frame for command 42


def test_mavlink_stream_decodes_with_pymavlink(tmp_path: Path, fc: Path) -> None:
    conf = f"rc_path = {RC}\ntelemetry_path = {TEL}\ntelemetry_proto = 2\n"
    arm_switch = standard_raw(1)
    plan = frames(1.1, 2.5, lambda t: sticks(standard_raw(-1), 992))
    plan += frames(2.5, 4.0, lambda t: sticks(standard_raw(-1), 992, arm=arm_switch))  # armed at 2.5
    session, outcome, _, err = run_fc(tmp_path, fc, conf, duration=4.0, serial=(RC, TEL), events=plan)
    assert outcome.verdict == "ok", (outcome.error, err)
    data = session.serial_output(TEL)
    mav = common.MAVLink(None)  # raises on a bad frame: the stream must hold none
    messages = mav.parse_buffer(data)
    assert messages is not None
    kinds = [m.get_type() for m in messages]
    assert "BAD_DATA" not in kinds
    beats = [m for m in messages if m.get_type() == "HEARTBEAT"]
    assert len(beats) == 3  # once a second over the 3 s the loop ran
    assert all(b.type == 2 and b.mavlink_version == 3 and b.custom_mode == 0 for b in beats)
    assert [bool(b.base_mode & 128) for b in beats] == [False, False, True]  # MAV_MODE_FLAG_SAFETY_ARMED
    assert [b.system_status for b in beats] == [3, 3, 4]                  # STANDBY, then ACTIVE
    attitude = [m for m in messages if m.get_type() == "ATTITUDE"]
    assert all(abs(a.roll) < math.radians(1) and abs(a.pitch) < math.radians(1) for a in attitude)
    times = [a.time_boot_ms for a in attitude]
    assert all(b - a == 20 for a, b in zip(times, times[1:], strict=False))  # every 5th cycle of 250 Hz
    assert times[-1] - times[0] > 2800  # none missing over the ~2.9 s the loop ran
    imu = [m for m in messages if m.get_type() == "SCALED_IMU"]
    assert imu and all(abs(m.zacc + 1000) < 30 and abs(m.xacc) < 30 for m in imu)  # 1 g up: -1000 mG FRD
    field = [(m.xmag, m.ymag, m.zmag) for m in imu]
    assert all(400 < math.dist(f, (0, 0, 0)) < 600 for f in field)  # the plant's 0.5 G Earth field
    hud = [m for m in messages if m.get_type() == "VFR_HUD"]
    assert hud and all(abs(h.alt) < 0.5 for h in hud)
    seqs = [m.get_seq() for m in messages]
    assert all((b - a) % 256 == 1 for a, b in zip(seqs, seqs[1:], strict=False))


def test_multiwii_sbus_scale_is_its_rx_cpps(tmp_path: Path, fc: Path) -> None:
    """MultiWii 2.4's RX.cpp reads SBUS as raw / 2 + 988 us, then moves it a quarter further from 1500
    (integer steps): right yaw at raw 1660 is 1818 + 79 = 1897 us, short of its 1900 us arming
    threshold (MAXCHECK), so the gesture never arms; a transmitter's full right yaw, 1811, is 1893 + 98 =
    1991 us, and it arms."""
    def mw_us(raw: int) -> int:  # RX.cpp, written out
        us = raw // 2 + 988
        return us - (1500 - us) // 4 if us < 1500 else us + (us - 1500) // 4

    assert mw_us(1660) == 1897 and mw_us(1811) == 1991 and mw_us(172) == 968 < 1100
    conf = f"rc_path = {RC}\ntelemetry_path = {TEL}\nsbus_map = 1\narming = 1\narm_hold_s = 0.5\n"
    plan = frames(1.1, 2.5, lambda t: sticks(standard_raw(-1), 1660))    # 1897 us: never arms
    plan += frames(2.5, 3.5, lambda t: sticks(standard_raw(-1), 1811))   # 1991 us: arms at 3.0
    session, outcome, _, err = run_fc(tmp_path, fc, conf, duration=3.5, serial=(RC, TEL), events=plan)
    assert outcome.verdict == "ok", (outcome.error, err)
    rows = telemetry(session, TEL)
    assert all(r["armed"] == 0 for r in rows if r["t"] < 2.9)
    assert rows[-1]["armed"] == 1


def test_the_rigs_msp_poll_reads_the_fc_through_a_run(tmp_path: Path, fc: Path) -> None:
    """rig/telemetry/msp.py's MspPoll against the FC: each poll's replies, with the time they were read."""
    poll = MspPoll(TEL, period=0.25)
    conf = f"telemetry_path = {TEL}\ntelemetry_proto = 1\n"
    session, outcome, _, err = run_fc(tmp_path, fc, conf, duration=3.0, serial=(TEL,),
                                      events=[(1.5, poll.tick)])
    assert outcome.verdict == "ok", (outcome.error, err)
    poll.read(session, 3.0)
    polls = [round(1.5 + 0.25 * k, 6) for k in range(6)]  # 1.5 .. 2.75: each answered by the next look
    by_time: dict[float, list[int]] = {}
    for t, reply in poll.rows:
        by_time.setdefault(round(t, 6), []).append(reply.command)
    assert sorted(by_time) == polls[1:] + [3.0]
    assert all(cmds == [101, 108, 102, 109] for cmds in by_time.values())
    assert poll.reader.skipped == 0 and poll.reader.bad == 0
    attitude = [r.fields() for _, r in poll.rows if r.command == 108]
    assert all(abs(a["roll_decideg"]) < 10 for a in attitude)
