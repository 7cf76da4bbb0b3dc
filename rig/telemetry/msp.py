"""MSP v1 (the MultiWii Serial Protocol), the rig's side: requests to poll an FC with, and the replies
read back out of whatever its port sent (garbage, torn frames and bad checksums skipped and counted).

A frame is ``$M`` and a direction (``<`` to the FC, ``>`` from it, ``!`` its error for a command it does
not know), the payload's size, the command, the payload (little-endian fields), and a checksum: the XOR
of size, command and payload. The replies decoded here are MultiWii 2.4's (Protocol.cpp):

======================  ====  ======================================================================
MSP_STATUS              101   cycle time (µs) u16, I2C errors u16, sensors u16, box flags u32, set u8
MSP_RAW_IMU             102   acc, gyro, mag: three i16 each, the FC's raw units
MSP_ATTITUDE            108   roll, pitch i16 (0.1°), heading i16 (°)
MSP_ALTITUDE            109   altitude i32 (cm), vario i16 (cm/s)
MSP_SET_RAW_RC          200   (a request: the RC channels, u16 µs each)
======================  ====  ======================================================================
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    from rig.host import Host

MSP_STATUS: Final = 101
MSP_RAW_IMU: Final = 102
MSP_ATTITUDE: Final = 108
MSP_ALTITUDE: Final = 109
MSP_SET_RAW_RC: Final = 200

#: The payload layout of each reply decoded (struct format, little-endian) and its fields' names
LAYOUTS: Final[dict[int, tuple[str, tuple[str, ...]]]] = {
    MSP_STATUS: ("<HHHIB", ("cycle_us", "i2c_errors", "sensors", "flags", "set")),
    MSP_RAW_IMU: ("<9h", ("acc_x", "acc_y", "acc_z", "gyro_x", "gyro_y", "gyro_z", "mag_x", "mag_y",
                          "mag_z")),
    MSP_ATTITUDE: ("<hhh", ("roll_decideg", "pitch_decideg", "heading_deg")),
    MSP_ALTITUDE: ("<ih", ("alt_cm", "vario_cms")),
}
#: MSP_STATUS flags: MultiWii's box bits (ARM is box 0)
FLAG_ARMED: Final = 1


def _checksum(body: bytes) -> int:
    check = 0
    for b in body:
        check ^= b
    return check


def request(command: int, payload: bytes = b"") -> bytes:
    """A request frame: ``$M<``, size, command, payload, checksum."""
    if not 0 <= command <= 255 or len(payload) > 255:
        raise ValueError(f"MSP v1: command 0..255 and at most 255 payload bytes, got {command}, "
                         f"{len(payload)} bytes")
    body = bytes([len(payload), command]) + payload
    return b"$M<" + body + bytes([_checksum(body)])


def set_raw_rc(us: list[int]) -> bytes:
    """MSP_SET_RAW_RC with the channels' pulse widths (µs, clamped to 0..65535)."""
    return request(MSP_SET_RAW_RC, b"".join(int(min(max(u, 0), 0xFFFF)).to_bytes(2, "little") for u in us))


@dataclass(frozen=True)
class Reply:
    command: int
    payload: bytes
    error: bool = False  # ``$M!``: the FC does not answer this command

    def fields(self) -> dict[str, int]:
        """The payload's fields by name (the layouts above); ValueError for another command or a payload
        of the wrong size."""
        if self.command not in LAYOUTS:
            raise ValueError(f"MSP command {self.command}: no layout known")
        fmt, names = LAYOUTS[self.command]
        if len(self.payload) != struct.calcsize(fmt):
            raise ValueError(f"MSP command {self.command}: {len(self.payload)} payload bytes, expected "
                             f"{struct.calcsize(fmt)}")
        return dict(zip(names, struct.unpack(fmt, self.payload), strict=True))


@dataclass
class ReplyReader:
    """Reads replies out of a byte stream fed in pieces; what is not a whole, good frame is skipped
    (``skipped`` bytes outside frames, ``bad`` frames with a wrong checksum)."""

    skipped: int = 0
    bad: int = 0
    _buf: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[Reply]:
        self._buf += data
        out: list[Reply] = []
        buf = self._buf
        while True:
            start = buf.find(b"$M")
            if start < 0:
                keep = 1 if buf.endswith(b"$") else 0  # (a frame's first byte, its second still to come)
                self.skipped += len(buf) - keep
                del buf[: len(buf) - keep]
                return out
            self.skipped += start
            del buf[:start]
            if len(buf) < 5:
                return out
            direction, size = buf[2], buf[3]
            if direction not in b">!":
                self.skipped += 2
                del buf[:2]
                continue
            if len(buf) < 6 + size:
                return out
            body = bytes(buf[3: 5 + size])
            if _checksum(body) != buf[5 + size]:
                self.bad += 1
                del buf[:2]  # (resynchronise: a frame may begin inside this false one)
                continue
            out.append(Reply(buf[4], bytes(buf[5: 5 + size]), error=direction == ord("!")))
            del buf[: 6 + size]


@dataclass
class MspPoll:
    """Polls an FC over MSP while a session runs (lockstep, real time, the MCU tier: any Host):
    ``host.at(t0, poll.tick)`` starts it at t0; every ``period`` seconds of sim time from then it reads
    what the port sent since its last look and writes the requests for ``commands``. Each reply is kept
    with the sim time it was read (``rows``): at most one period after the FC sent it."""

    path: str
    commands: Sequence[int] = (MSP_STATUS, MSP_ATTITUDE, MSP_RAW_IMU, MSP_ALTITUDE)
    period: float = 0.1
    reader: ReplyReader = field(default_factory=ReplyReader)
    rows: list[tuple[float, Reply]] = field(default_factory=list)
    _seen: int = 0
    _requests: bytes = b""

    def __post_init__(self) -> None:
        self._requests = b"".join(request(c) for c in self.commands)

    def tick(self, host: Host) -> None:
        t = host.now_ns * 1e-9
        self.read(host, t)
        host.serial_write(self.path, self._requests)
        host.at(t + self.period, self.tick)

    def read(self, host: Host, t: float) -> None:
        """Takes what the port sent since the last look (call it once more after the run ends)."""
        data = host.serial_output(self.path)
        new, self._seen = data[self._seen:], len(data)
        self.rows += [(t, r) for r in self.reader.feed(new)]
