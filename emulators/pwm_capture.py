"""The PWM capture device and its frame codecs.

On a bench, a small MCU measures the four ESC pulse widths and reports them to the rig; in CI the same
device is modelled here, so the frames it sends really travel (over a python-can bus or a pty) and the
rig's decoder is the one a bench uses. The model samples the DUT's outputs every 1/rate_hz seconds,
quantises them to resolution_us (a timer tick) and stamps a sequence counter.

Two frame formats (docs/design.md §6):
* CAN: two classic frames, PWM_CAPTURE_12 and PWM_CAPTURE_34, laid out in ``pwm_capture.dbc`` (read
  with cantools): pulse widths in 0.1 µs, an 8-bit sequence counter and a CRC-16/CCITT-FALSE over the
  identifier and data bytes 0..5, because a frame corrupted between the device and the rig's decoder
  (a bad gateway, a buggy bridge) passes the CAN controller's own CRC.
* Serial: payload = seq (u8), channel count (u8), widths (u16 little endian, 0.1 µs), then the CRC-16
  (big endian); COBS-encoded (the ``cobs`` package) and ended by 0x00.

Decoders never trust the bytes: a frame that fails its CRC, its COBS decoding or its layout raises
CaptureFrameError; callers count it and keep the previous command.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass
from pathlib import Path

from cobs import cobs

DBC_PATH = Path(__file__).with_name("pwm_capture.dbc")
#: The ways the frames travel, one per frame format above (rig/capture.py has a transport for each)
TRANSPORTS = ("can", "serial")
UNIT_US = 0.1
CHANNELS = 4


class CaptureFrameError(ValueError):
    """A frame that must not be applied."""


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF): check value 0x29B1 for b"123456789"."""
    return binascii.crc_hqx(data, 0xFFFF)


def quantise(width_us: float, resolution_us: float) -> float:
    return round(width_us / resolution_us) * resolution_us


@dataclass
class CaptureDevice:
    resolution_us: float = 1.0
    rate_hz: float = 400.0
    seq: int = 0

    def sample(self, widths_us: list[float]) -> tuple[int, list[float]]:
        """One report: the sequence number and the quantised widths."""
        seq = self.seq
        self.seq = (self.seq + 1) % 256
        return seq, [quantise(w, self.resolution_us) for w in widths_us]


# ---- serial ------------------------------------------------------------------------------------------


def encode_serial(seq: int, widths_us: list[float]) -> bytes:
    payload = struct.pack(
        f"<BB{len(widths_us)}H", seq, len(widths_us), *(round(w / UNIT_US) for w in widths_us)
    )
    return cobs.encode(payload + struct.pack(">H", crc16(payload))) + b"\x00"


def decode_serial(frame: bytes) -> tuple[int, list[float]]:
    """One frame without its 0x00 delimiter."""
    try:
        raw = cobs.decode(frame)
    except cobs.DecodeError as e:
        raise CaptureFrameError(f"COBS: {e}") from None
    if len(raw) < 4:
        raise CaptureFrameError(f"frame of {len(raw)} bytes is too short")
    payload, (crc,) = raw[:-2], struct.unpack(">H", raw[-2:])
    if crc16(payload) != crc:
        raise CaptureFrameError(f"CRC mismatch (computed {crc16(payload):#06x}, sent {crc:#06x})")
    seq, n = payload[0], payload[1]
    if n > 16 or len(payload) != 2 + 2 * n:
        raise CaptureFrameError(f"layout: {n} channels in {len(payload)} bytes")
    return seq, [v * UNIT_US for v in struct.unpack(f"<{n}H", payload[2:])]


class SerialDeframer:
    """Splits a byte stream at 0x00 delimiters; keeps a partial frame for the next chunk."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        self._buf += data
        *frames, rest = bytes(self._buf).split(b"\x00")
        self._buf = bytearray(rest)
        return [f for f in frames if f]


# ---- CAN ---------------------------------------------------------------------------------------------


class CanCodec:
    """The DBC's two messages; the CRC covers what cantools leaves to the application."""

    def __init__(self, dbc: Path = DBC_PATH) -> None:
        import cantools  # (here: cantools is a tenth of a second of every rig command's start)

        db = cantools.database.load_file(str(dbc))
        assert isinstance(db, cantools.database.can.Database)  # (a DBC file is a CAN database)
        self.db = db
        self.messages = [
            self.db.get_message_by_name("PWM_CAPTURE_12"),
            self.db.get_message_by_name("PWM_CAPTURE_34"),
        ]
        self.ids = {m.frame_id: k for k, m in enumerate(self.messages)}

    @staticmethod
    def _crc(frame_id: int, data: bytes) -> int:
        return crc16(frame_id.to_bytes(2, "big") + data[:6])

    def encode(self, seq: int, widths_us: list[float]) -> list[tuple[int, bytes]]:
        frames = []
        for k, msg in enumerate(self.messages):
            a, b = widths_us[2 * k], widths_us[2 * k + 1]
            values = {f"PWM{2 * k + 1}": a, f"PWM{2 * k + 2}": b, "SEQ": seq, "RESERVED": 0, "CRC16": 0}
            data = bytearray(msg.encode(values))
            data[6:8] = self._crc(msg.frame_id, bytes(data)).to_bytes(2, "little")
            frames.append((msg.frame_id, bytes(data)))
        return frames

    def decode(self, frame_id: int, data: bytes) -> tuple[int, int, list[float]]:
        """(first channel index, seq, widths) of one frame."""
        k = self.ids.get(frame_id)
        if k is None:
            raise CaptureFrameError(f"unknown CAN id {frame_id:#x}")
        if len(data) != 8:
            raise CaptureFrameError(f"CAN id {frame_id:#x}: {len(data)} data bytes, expected 8")
        decoded = self.messages[k].decode(bytes(data), scaling=True, decode_choices=False)
        assert isinstance(decoded, dict)
        sig = {name: float(v) for name, v in decoded.items() if isinstance(v, int | float)}
        if self._crc(frame_id, data) != int(sig["CRC16"]):
            raise CaptureFrameError(f"CAN id {frame_id:#x}: CRC mismatch")
        return 2 * k, int(sig["SEQ"]), [sig[f"PWM{2 * k + 1}"], sig[f"PWM{2 * k + 2}"]]
