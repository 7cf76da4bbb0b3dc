"""SBUS, what an RC receiver sends a flight controller: the frame encoder and the stick names.

SBUS (Futaba, as every receiver library decodes it): 100 kbaud 8E2 inverted on the wire, which a pty
does not model; the bytes are what matters here. A frame is 25 bytes: 0x0F, sixteen 11-bit channels
packed LSB first, a flags byte (bit 0 ch17, bit 1 ch18, bit 2 frame lost, bit 3 failsafe), 0x00.
Channel values run 172..1811 with 992 at centre (the range OpenTX/EdgeTX map to -100..+100 %).

Sticks are given in units: roll, pitch, yaw in -1..1, throttle in 0..1, switches as bool. The channel
order is AETR (roll, pitch, throttle, yaw), then the arm switch (ch5), the altitude-hold switch (ch6)
and an altitude-setpoint knob (ch7, -1..1, centre = hold where engaged), as the reference FC reads them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

HEADER: Final = 0x0F
FOOTER: Final = 0x00
FLAG_FRAME_LOST: Final = 0x04
FLAG_FAILSAFE: Final = 0x08
RAW_MIN: Final = 172
RAW_CENTRE: Final = 992
RAW_MAX: Final = 1811
CHANNELS: Final = 16
PERIOD_S: Final = 0.014  # SBUS "normal" mode; 7 ms in high-speed mode

STICKS = ("roll", "pitch", "throttle", "yaw", "arm", "alt_hold", "alt_offset")


def unit_to_raw(x: float) -> int:
    """-1..1 to the 11-bit channel value (clamped to what a transmitter sends)."""
    return max(RAW_MIN, min(RAW_MAX, round(RAW_CENTRE + x * (RAW_MAX - RAW_CENTRE))))


def encode(channels: list[int], frame_lost: bool = False, failsafe: bool = False) -> bytes:
    if len(channels) != CHANNELS or any(not 0 <= c < 2048 for c in channels):
        raise ValueError("SBUS needs 16 channels of 0..2047")
    acc = 0
    for i, c in enumerate(channels):
        acc |= c << (11 * i)
    flags = (FLAG_FRAME_LOST if frame_lost else 0) | (FLAG_FAILSAFE if failsafe else 0)
    return bytes([HEADER]) + acc.to_bytes(22, "little") + bytes([flags, FOOTER])


FRAME_BYTES: Final = 25


def decode(frame: bytes) -> tuple[list[int], int]:
    """A frame's 16 channels and its flags byte; ValueError for bytes that are not one frame (a bridge
    re-encodes what the host decoded, so the two must be exact inverses)."""
    if len(frame) != FRAME_BYTES or frame[0] != HEADER or frame[-1] != FOOTER:
        raise ValueError(f"not an SBUS frame: {frame.hex()}")
    acc = int.from_bytes(frame[1:23], "little")
    return [(acc >> (11 * i)) & 0x7FF for i in range(CHANNELS)], frame[23]


@dataclass
class Sticks:
    roll: float = 0.0
    pitch: float = 0.0
    throttle: float = 0.0
    yaw: float = 0.0
    arm: bool = False
    alt_hold: bool = False
    alt_offset: float = 0.0

    def setting(self) -> tuple[float, float, float, float, bool, bool, float]:
        """What the channels are made from, to compare with a frame's (an emulator sends the same
        sticks ~70 times a second: comparing these is a seventh of making the channels)."""
        return self.roll, self.pitch, self.throttle, self.yaw, self.arm, self.alt_hold, self.alt_offset

    def channels(self) -> list[int]:
        ch = [RAW_CENTRE] * CHANNELS
        ch[0], ch[1], ch[3] = unit_to_raw(self.roll), unit_to_raw(self.pitch), unit_to_raw(self.yaw)
        ch[2] = unit_to_raw(2 * self.throttle - 1)
        ch[4] = RAW_MAX if self.arm else RAW_MIN
        ch[5] = RAW_MAX if self.alt_hold else RAW_MIN
        ch[6] = unit_to_raw(self.alt_offset)
        return ch
