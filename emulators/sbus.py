"""SBUS, what an RC receiver sends a flight controller: the frame encoder and the stick names.

SBUS (Futaba, as every receiver library decodes it): 100 kbaud 8E2 inverted on the wire, which a pty
does not model; the bytes are what matters here. A frame is 25 bytes: 0x0F, sixteen 11-bit channels
packed LSB first, a flags byte (bit 0 ch17, bit 1 ch18, bit 2 frame lost, bit 3 failsafe), 0x00.
Channel values run 172..1811 with 992 at centre (the range OpenTX/EdgeTX map to -100..+100 %).

Sticks are given in units: roll, pitch, yaw in -1..1, throttle in 0..1, an arm request, a flight mode
by name and an altitude-setpoint knob (-1..1). Which channel carries which and at what value is a
ChannelMap: an FC profile makes one from its µs (scenarios/profile.py); the default is the reference
FC's: AETR (roll, pitch, throttle, yaw), the arm switch on channel 5, the altitude-hold switch on
channel 6 (mode "althold") and the knob on channel 7, each full stick 819 steps from 992.
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
#: the knobs a ChannelMap may put on extra channels, by name (-1..1 each)
KNOBS = ("alt_offset",)


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


@dataclass(frozen=True)
class ChannelMap:
    """Where an FC reads each control, in SBUS values (an FC profile's µs turned into them). Channel
    numbers are 0-based here. A stick at x (-1..1) is ``round(centre + x * travel)``, clamped to
    ``low..high``; a switch or a mode is one value; ``gestures`` hold channels at values while a stick
    gesture (arming by sticks) lasts."""

    roll: int = 0
    pitch: int = 1
    throttle: int = 2
    yaw: int = 3
    centre: float = float(RAW_CENTRE)
    travel: float = float(RAW_MAX - RAW_CENTRE)
    low: int = RAW_MIN
    high: int = RAW_MAX
    rest: int = RAW_CENTRE  # every channel no control uses
    #: the arm switch: (channel, value on, value off); None: not a switch
    arm: tuple[int, int, int] | None = (4, RAW_MAX, RAW_MIN)
    #: the mode channel and each mode's value ((name, value) pairs), the first the default; None: no channel
    mode_channel: int | None = 5
    modes: tuple[tuple[str, int], ...] = (("angle", RAW_MIN), ("althold", RAW_MAX))
    knobs: tuple[tuple[str, int], ...] = (("alt_offset", 6),)
    gestures: tuple[tuple[str, tuple[tuple[int, int], ...]], ...] = ()
    #: the sticks ("roll", "pitch", "yaw") whose channel falls as the stick rises: the FC reads them the
    #: other way round from the rig (positive pitch nose up: MultiWii reads a pitch channel above its
    #: centre as nose down)
    reversed_sticks: tuple[str, ...] = ()

    def stick(self, x: float) -> int:
        return max(self.low, min(self.high, round(self.centre + x * self.travel)))


#: the reference FC's channels (the reference profile's map: a test keeps them equal)
REFERENCE_MAP: Final = ChannelMap()

#: what a Sticks' channels are made from (Sticks.setting)
Setting = tuple[float, float, float, float, bool, str, float, str]


@dataclass
class Sticks:
    roll: float = 0.0
    pitch: float = 0.0
    throttle: float = 0.0
    yaw: float = 0.0
    arm: bool = False
    mode: str = ""  # "": the map's first (default) mode
    alt_offset: float = 0.0
    gesture: str = ""  # a stick gesture being held ("arm", "disarm"): its channels win

    def setting(self) -> Setting:
        """What the channels are made from, to compare with a frame's (an emulator sends the same
        sticks ~70 times a second: comparing these is a seventh of making the channels)."""
        return (self.roll, self.pitch, self.throttle, self.yaw, self.arm, self.mode, self.alt_offset,
                self.gesture)

    def channels(self, cmap: ChannelMap = REFERENCE_MAP) -> list[int]:
        ch = [cmap.rest] * CHANNELS
        back = cmap.reversed_sticks
        ch[cmap.roll] = cmap.stick(-self.roll if "roll" in back else self.roll)
        ch[cmap.pitch] = cmap.stick(-self.pitch if "pitch" in back else self.pitch)
        ch[cmap.yaw] = cmap.stick(-self.yaw if "yaw" in back else self.yaw)
        ch[cmap.throttle] = cmap.stick(2 * self.throttle - 1)
        if cmap.arm is not None:
            channel, on, off = cmap.arm
            ch[channel] = on if self.arm else off
        if cmap.mode_channel is not None and cmap.modes:
            value = cmap.modes[0][1]
            for name, v in cmap.modes:
                if name == self.mode:
                    value = v
            ch[cmap.mode_channel] = value
        for name, channel in cmap.knobs:
            if name == "alt_offset":
                ch[channel] = cmap.stick(self.alt_offset)
        for name, held in cmap.gestures:
            if name == self.gesture:
                for channel, v in held:
                    ch[channel] = v
        return ch
