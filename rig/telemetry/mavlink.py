"""MAVLink telemetry, the rig's side: what an FC streams (HEARTBEAT, ATTITUDE, SCALED_IMU, VFR_HUD,
GLOBAL_POSITION_INT, ...) read with pymavlink, the protocol's own parser generated from the published
message definitions (common.xml), so a frame the rig accepts is one any ground station accepts.

Robust to what a serial line carries: bytes outside frames and frames with a bad CRC are skipped
(counted in ``bad``); MAVLink 1 and 2 frames both read.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Final

#: HEARTBEAT base_mode bit: the vehicle is armed (MAV_MODE_FLAG_SAFETY_ARMED)
SAFETY_ARMED: Final = 128


@dataclass
class MavlinkReader:
    """Feeds bytes in pieces, returns the whole, good messages among them (pymavlink message objects:
    ``get_type()``, their fields as attributes)."""

    bad: int = 0
    _mav: Any = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        from pymavlink.dialects.v20 import common

        self._mav = common.MAVLink(None)
        self._mav.robust_parsing = True  # (garbage is skipped, not raised)

    def feed(self, data: bytes) -> list[Any]:
        got = self._mav.parse_buffer(data) or []
        good = [m for m in got if m.get_type() != "BAD_DATA"]
        self.bad += len(got) - len(good)
        return good


def armed(heartbeat: Any) -> bool:
    """Whether a HEARTBEAT says the vehicle is armed."""
    return bool(heartbeat.base_mode & SAFETY_ARMED)
