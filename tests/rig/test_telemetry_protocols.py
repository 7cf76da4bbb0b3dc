"""The rig's MSP and MAVLink readers (rig/telemetry/msp.py, mavlink.py) against independent truth:
MSP frames built here byte by byte from MultiWii's published layout, MAVLink frames packed by
pymavlink; both fed with garbage around them, torn into pieces and damaged."""

from __future__ import annotations

import random
import struct

import pytest
from pymavlink.dialects.v20 import common

from rig.telemetry import msp
from rig.telemetry.mavlink import MavlinkReader, armed


def frame(direction: bytes, cmd: int, payload: bytes) -> bytes:
    """MultiWii's MSP v1: '$', 'M', direction, size, command, payload, XOR of size, command, payload."""
    check = len(payload) ^ cmd
    for b in payload:
        check ^= b
    return b"$M" + direction + bytes([len(payload), cmd]) + payload + bytes([check])


def test_requests_are_the_published_bytes():
    assert msp.request(101) == b"$M<\x00\x65\x65"
    assert msp.request(108) == bytes([0x24, 0x4D, 0x3C, 0x00, 0x6C, 0x6C])
    rc = msp.set_raw_rc([1500, 1000, 2000, 1234])
    assert rc == frame(b"<", 200, struct.pack("<4H", 1500, 1000, 2000, 1234))
    with pytest.raises(ValueError):
        msp.request(256)


STATUS = struct.pack("<HHHIB", 4000, 2, 7, 0b1011, 0)
ATTITUDE = struct.pack("<hhh", -123, 45, -170)
IMU = struct.pack("<9h", 1, -2, 512, 10, -20, 30, 100, -200, 300)
ALTITUDE = struct.pack("<ih", -250, 33)


def test_replies_decode_by_the_published_layouts():
    reader = msp.ReplyReader()
    got = reader.feed(frame(b">", 101, STATUS) + frame(b">", 108, ATTITUDE) + frame(b">", 102, IMU)
                      + frame(b">", 109, ALTITUDE))
    assert [r.command for r in got] == [101, 108, 102, 109]
    assert got[0].fields() == {"cycle_us": 4000, "i2c_errors": 2, "sensors": 7, "flags": 11, "set": 0}
    assert got[0].fields()["flags"] & msp.FLAG_ARMED
    assert got[1].fields() == {"roll_decideg": -123, "pitch_decideg": 45, "heading_deg": -170}
    assert got[2].fields()["acc_z"] == 512 and got[2].fields()["mag_x"] == 100
    assert got[3].fields() == {"alt_cm": -250, "vario_cms": 33}
    assert reader.skipped == 0 and reader.bad == 0


def test_garbage_torn_frames_bad_checksums_and_error_frames() -> None:
    good = frame(b">", 108, ATTITUDE)
    damaged = bytearray(frame(b">", 101, STATUS))
    damaged[-1] ^= 0xFF
    stream = (b"\x00$$M\xff# fc: text\n" + bytes(damaged) + b"$M<\x00\x65\x65" + good
              + frame(b"!", 42, b"") + good)
    rng = random.Random(1)
    reader = msp.ReplyReader()
    got: list[msp.Reply] = []
    i = 0
    while i < len(stream):  # in random pieces, as a serial port delivers them
        n = rng.randint(1, 7)
        got += reader.feed(stream[i: i + n])
        i += n
    assert [(r.command, r.error) for r in got] == [(108, False), (42, True), (108, False)]
    assert got[0].fields()["heading_deg"] == -170
    assert reader.bad == 1 and reader.skipped > 0
    with pytest.raises(ValueError, match="payload bytes"):
        msp.Reply(101, b"\x00").fields()


def test_the_mavlink_reader_takes_pymavlinks_frames_through_garbage():
    sender = common.MAVLink(None, srcSystem=1, srcComponent=1)
    hb = sender.heartbeat_encode(2, 0, 1 | 16 | 128, 4, 3).pack(sender)
    att = sender.attitude_encode(1234, 0.1, -0.2, 3.0, 0.01, 0.02, 0.03).pack(sender)
    bad = bytearray(att)
    bad[-1] ^= 0xFF
    # (a false frame start in the garbage would take the bytes after it as its frame, as in any MAVLink
    # parser: the garbage here has none)
    stream = b"# fc: running\n" + hb + bytes(bad) + att
    reader = MavlinkReader()
    got = []
    for k in range(0, len(stream), 5):
        got += reader.feed(stream[k: k + 5])
    assert [m.get_type() for m in got] == ["HEARTBEAT", "ATTITUDE"]
    assert armed(got[0]) and got[1].time_boot_ms == 1234 and got[1].pitch == pytest.approx(-0.2)
    assert reader.bad >= 1


def test_msp_attitude_becomes_the_columns_signs() -> None:
    """MultiWii 2.4's MSP_ATTITUDE sends its att.angle: angle[PITCH] = atan2(EstG.Y, ...) with the
    accelerometer's pitch axis pointing backwards (def.h GY_86: accADC[PITCH] = -Y, the chip's Y
    forward), so a nose-down attitude is positive, as its mixer's pitch (front motors - pitch) is. The
    columns' est_pitch is nose up +: 4.5 deg nose down (45 in 0.1 deg) is -4.5; roll keeps its sign."""
    from rig.telemetry.binary import _msp_values

    reply = msp.ReplyReader().feed(frame(b">", 108, ATTITUDE))[0]
    assert _msp_values(reply) == {"roll": -12.3, "pitch": -4.5, "yaw": -170.0}
