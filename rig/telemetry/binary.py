"""An FC's MSP or MAVLink telemetry read through a run into the columns the text lines give (``t``,
``roll``, ``pitch``, ``yaw``, ``alt``, ``armed``), in the same units and signs, so that criteria on the
FC's estimates and the "never armed" judgement read every FC alike.

Conventions (docs/profiles.md, "Telemetry"): angles in degrees, roll right wing down +, pitch nose up +,
yaw (heading) clockwise from north + (either range: the error is wrapped to ±180°); altitude in metres
above the start point, up +; armed 1 or 0.

==============================  ===========================================================================
MSP (polled)                    ``MSP_ATTITUDE`` roll and pitch / 10 (0.1°), heading (°); ``MSP_ALTITUDE``
                                cm / 100; ``MSP_STATUS`` flags bit 0 (MultiWii's ARM box). A reply is
                                timed at the request it answers: the FC answers at once (within its cycle),
                                the rig reads the port a poll period later.
MAVLink (streamed)              ``ATTITUDE`` rad → °; ``VFR_HUD`` alt (m), else ``GLOBAL_POSITION_INT``
                                relative_alt (mm / 1000); ``HEARTBEAT`` base_mode bit 7 (SAFETY_ARMED). A
                                message is timed when the rig read it (at most one watch period late).
==============================  ===========================================================================

``MSP_RAW_IMU`` and ``SCALED_IMU`` are read and counted (``Watch.counts``) but fill no column: the text
lines have none to compare them with. The FC is *ready* at its first valid reply (MSP: any ``$M>``
frame with a good checksum) or first ``HEARTBEAT`` (MAVLink).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from rig.telemetry import mavlink, msp

if TYPE_CHECKING:
    from rig.host import Host

#: the columns filled, after ``t``, as the text lines name them
COLUMNS: Final = ("roll", "pitch", "yaw", "alt", "armed")
_MSP_NAMES: Final = {msp.MSP_STATUS: "MSP_STATUS", msp.MSP_RAW_IMU: "MSP_RAW_IMU",
                     msp.MSP_ATTITUDE: "MSP_ATTITUDE", msp.MSP_ALTITUDE: "MSP_ALTITUDE"}
#: how often the rig looks at a streaming (MAVLink) port, sim seconds
MAVLINK_WATCH_PERIOD: Final = 0.01


def _msp_values(reply: msp.Reply) -> dict[str, float]:
    """A reply's contribution to the columns (none for an error reply or a layout it does not fit)."""
    if reply.error or reply.command not in (msp.MSP_STATUS, msp.MSP_ATTITUDE, msp.MSP_ALTITUDE):
        return {}
    try:
        f = reply.fields()
    except ValueError:
        return {}
    if reply.command == msp.MSP_ATTITUDE:  # (MultiWii's angle[PITCH] is nose down +: the column's nose up +)
        return {"roll": f["roll_decideg"] / 10, "pitch": -f["pitch_decideg"] / 10,
                "yaw": float(f["heading_deg"])}
    if reply.command == msp.MSP_ALTITUDE:
        return {"alt": f["alt_cm"] / 100}
    return {"armed": float(bool(f["flags"] & msp.FLAG_ARMED))}


def _mavlink_values(message: Any) -> dict[str, float]:
    kind = message.get_type()
    if kind == "ATTITUDE":
        deg = 180 / math.pi
        return {"roll": message.roll * deg, "pitch": message.pitch * deg, "yaw": message.yaw * deg}
    if kind == "VFR_HUD":
        return {"alt": float(message.alt)}
    if kind == "GLOBAL_POSITION_INT":
        return {"alt": message.relative_alt / 1000}
    if kind == "HEARTBEAT":
        return {"armed": float(mavlink.armed(message))}
    return {}


@dataclass
class Watch:
    """Reads an FC's MSP (polling it) or MAVLink (listening) on ``path`` while a session runs:
    ``host.at(0.0, watch.tick)``, then ``watch.finish(host, end)`` after the run. ``rows``: (sim time,
    column, value) in the order read; ``ready_s``: the sim time of the first valid reply or heartbeat."""

    path: str
    kind: str  # "msp" | "mavlink"
    period: float
    rows: list[tuple[float, str, float]] = field(default_factory=list)
    counts: Counter[str] = field(default_factory=Counter)
    ready_s: float | None = None
    _poll: msp.MspPoll | None = None
    _mav: mavlink.MavlinkReader | None = None
    _seen: int = 0

    def __post_init__(self) -> None:
        if self.kind == "msp":
            self._poll = msp.MspPoll(self.path, period=self.period)
        elif self.kind == "mavlink":
            self._mav = mavlink.MavlinkReader()
        else:
            raise ValueError(f"telemetry kind {self.kind!r}: only msp and mavlink are watched")

    def tick(self, host: Host) -> None:
        if self._poll is not None:
            self._poll.tick(host)  # (it asks every period from now on; its replies are taken at the end)
            return
        t = host.now_ns * 1e-9
        self._read_mavlink(host, t)
        host.at(t + self.period, self.tick)

    def finish(self, host: Host, t: float) -> None:
        """Takes what the port sent after the last look (and, for MSP, every reply of the run), at the
        run's end ``t`` (sim seconds)."""
        if self._poll is not None:
            self._poll.read(host, t)
            self._take_msp()
        else:
            self._read_mavlink(host, t)

    @property
    def bad(self) -> int:
        """Frames refused (bad checksum or CRC)."""
        if self._poll is not None:
            return self._poll.reader.bad
        assert self._mav is not None
        return self._mav.bad

    def _take_msp(self) -> None:
        assert self._poll is not None
        for t_read, reply in self._poll.rows:
            t = max(0.0, t_read - self.period)  # (the request it answers went out a period earlier)
            self._note(t, _MSP_NAMES.get(reply.command, f"MSP {reply.command}"))
            for k, v in _msp_values(reply).items():
                self.rows.append((t, k, v))
        self._poll.rows.clear()

    def _read_mavlink(self, host: Host, t: float) -> None:
        assert self._mav is not None
        data = host.serial_output(self.path)
        new, self._seen = data[self._seen:], len(data)
        for m in self._mav.feed(new):
            kind = m.get_type()
            if kind == "HEARTBEAT" or self.ready_s is not None:
                self._note(t, kind)
            else:
                self.counts[kind] += 1
            for k, v in _mavlink_values(m).items():
                self.rows.append((t, k, v))

    def _note(self, t: float, kind: str) -> None:
        self.counts[kind] += 1
        if self.ready_s is None:
            self.ready_s = t

    def columns(self) -> dict[str, np.ndarray]:
        """The rows as columns: ``t`` each time anything was read, each column held from its last value
        (NaN before its first), as the text lines' columns are one row per line."""
        times = sorted({t for t, _, _ in self.rows})
        index = {t: i for i, t in enumerate(times)}
        out = {"t": np.array(times, dtype=float)}
        for name in COLUMNS:
            col = np.full(len(times), math.nan)
            for t, k, v in self.rows:
                if k == name:
                    col[index[t]] = v
            out[name] = _carry(col)
        return out


def _carry(col: np.ndarray) -> np.ndarray:
    """Each NaN replaced by the last finite value before it (NaN before the first)."""
    idx = np.where(np.isnan(col), 0, np.arange(len(col)))
    np.maximum.accumulate(idx, out=idx)
    return col[idx]  # (before the first value, index 0 is itself NaN)
