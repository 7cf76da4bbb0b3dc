"""The RC stick emulator: an SBUS receiver's frames (emulators/sbus.py encodes them) sent to the flight
controller's RC port as session events in sim time."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from rig.emulators.sbus import PERIOD_S, REFERENCE_MAP, ChannelMap, Setting, Sticks, encode
from rig.scheduler import round_half_even

if TYPE_CHECKING:
    from rig.host import Host


@dataclass
class StickEmulator:
    """Sends a frame every ``period`` seconds of sim time on ``path`` while ``link`` is up. Scenarios
    change ``sticks`` (the next frame carries them) and ``link`` ("ok", "lost": no frames, as when the
    receiver loses the transmitter and stops output, "failsafe": frames with the failsafe flag).
    ``cmap``: which channel carries which control for this FC (its profile's)."""

    path: str
    period: float = PERIOD_S
    cmap: ChannelMap = REFERENCE_MAP
    sticks: Sticks = field(default_factory=Sticks)
    link: str = "ok"
    #: every frame sent: (sim time ns, channels, failsafe), for run.mcap's /rc channel (~70 a second)
    frames: list[tuple[int, tuple[int, ...], bool]] = field(default_factory=list)
    #: the last frame encoded and what it was made from (Sticks.setting, failsafe, its channels): the
    #: sticks mostly hold still between frames
    _encoded: tuple[Setting, bool, tuple[int, ...], bytes] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # (here, not as the field's default: mypyc leaves that unset; NaN equals no setting)
        self._encoded = ((math.nan, 0.0, 0.0, 0.0, False, "", 0.0, ""), False, (), b"")

    def start(self, session: Host, t: float = 0.0) -> None:
        session.at(t, lambda s: self._tick(s, t))

    def _tick(self, session: Host, t: float) -> None:
        if self.link == "lost":
            session.serial_silence(self.path)
        else:
            setting, failsafe = self.sticks.setting(), self.link == "failsafe"
            last, last_failsafe, channels, frame = self._encoded
            if setting != last or failsafe != last_failsafe:
                channels = tuple(self.sticks.channels(self.cmap))
                frame = encode(list(channels), failsafe=failsafe, frame_lost=failsafe)
                self._encoded = setting, failsafe, channels, frame
            session.serial_write(self.path, frame)
            self.frames.append((round_half_even(t * 1e9), channels, failsafe))  # (round's: 1.3 k a call)
        nxt = t + self.period
        session.at(nxt, lambda s: self._tick(s, nxt))
