"""PWM capture links: the capture device model's frames travel over a real transport to the rig's
decoder, which turns them into the plant's motor commands after the configured latency.

* ``can``: a python-can bus (``virtual`` in CI: two bus objects on one private channel, the device's
  and the rig's; on a bench the rig's side is ``socketcan``/``can0`` and the device is real).
* ``serial``: a pty pair opened with pyserial on the rig's side (on a bench, the device's USB serial
  port).

The link runs as session events in sim time: every 1/rate_hz the device samples the DUT's PWM outputs
and sends; the rig receives what arrived, rejects and counts bad frames, counts sequence gaps, and
schedules the decoded widths ``latency_s`` later. ``corrupt_every`` (tests) flips one bit in every
n-th frame after encoding, as a bad cable or bridge would.
"""

from __future__ import annotations

import os
import time
import tty
import uuid
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import can
import serial

from emulators.pwm_capture import (
    CanCodec,
    CaptureDevice,
    CaptureFrameError,
    SerialDeframer,
    decode_serial,
    encode_serial,
)
from plant.variables import MOTORS

if TYPE_CHECKING:
    from rig.session import Session
    from scenarios.schema import Capture



@dataclass
class CaptureStats:
    sent: int = 0
    applied: int = 0
    rejected: int = 0
    seq_gaps: int = 0
    max_quantisation_us: float = 0.0
    reasons: list[str] = field(default_factory=list)


class CaptureLink:
    def __init__(
        self,
        transport: str,
        resolution_us: float,
        rate_hz: float,
        latency_s: float,
        corrupt_every: int = 0,
        can_interface: str = "virtual",
        can_channel: str = "",
    ) -> None:
        self.device = CaptureDevice(resolution_us, rate_hz)
        self.period, self.latency = 1.0 / rate_hz, latency_s
        self.corrupt_every = corrupt_every
        self.st = CaptureStats()
        self.transport = transport
        self._last_seq: dict[int, int] = {}
        if transport == "can":
            self.codec = CanCodec()
            self.tx, self.rx = _open_can_pair(can_interface, can_channel)
        elif transport == "serial":
            self.master, slave = os.openpty()
            tty.setraw(slave)
            self.port = serial.Serial(os.ttyname(slave), timeout=0)
            os.close(slave)  # pyserial holds its own descriptor
            self.deframer = SerialDeframer()
        else:
            raise ValueError(f"unknown capture transport {transport!r}")

    # ---- device side ------------------------------------------------------------------------------

    def _corrupt(self, data: bytes) -> bytes:
        self.st.sent += 1
        if self.corrupt_every and self.st.sent % self.corrupt_every == 0:
            b = bytearray(data)
            b[len(b) // 2] ^= 0x10
            return bytes(b)
        return data

    def tick(self, session: Session, t: float) -> None:
        widths = [session.world.pwm[m].pulse_us() for m in range(MOTORS)]
        seq, q = self.device.sample(widths)
        self.st.max_quantisation_us = max(
            self.st.max_quantisation_us, max(abs(a - b) for a, b in zip(q, widths, strict=True))
        )
        if self.transport == "can":
            for fid, data in self.codec.encode(seq, q):
                self.tx.send(can.Message(arbitration_id=fid, data=self._corrupt(data), is_extended_id=False))
        else:
            data = self._corrupt(encode_serial(seq, q)[:-1]) + b"\x00"
            view = memoryview(data)
            while view:
                view = view[os.write(self.master, view) :]
        self._receive(session, t, expect=2 if self.transport == "can" else len(data))
        nxt = t + self.period
        session.at(nxt, lambda s: self.tick(s, nxt))

    # ---- rig side ---------------------------------------------------------------------------------

    def _receive(self, session: Session, t: float, expect: int) -> None:
        decoded: list[tuple[int, int, list[float]]] = []
        if self.transport == "can":
            for _ in range(expect):
                msg = self.rx.recv(timeout=1.0)
                if msg is None:
                    break
                try:
                    decoded.append(self.codec.decode(msg.arbitration_id, bytes(msg.data)))
                except CaptureFrameError as e:
                    self._reject(str(e))
        else:
            got = b""
            deadline = time.monotonic() + 1.0
            while len(got) < expect and time.monotonic() < deadline:  # a pty hands bytes over asynchronously
                got += self.port.read(expect - len(got))
            for frame in self.deframer.feed(got):
                try:
                    seq, widths = decode_serial(frame)
                    decoded.append((0, seq, widths))
                except CaptureFrameError as e:
                    self._reject(str(e))
        for first, seq, widths in decoded:
            last = self._last_seq.get(first)
            if last is not None and seq != (last + 1) % 256:
                self.st.seq_gaps += 1
            self._last_seq[first] = seq
            if self.latency > 0:
                session.at(t + self.latency, lambda s, f=first, w=widths: self._apply(s, f, w))
            else:
                self._apply(session, first, widths)

    def _reject(self, reason: str) -> None:
        self.st.rejected += 1
        if len(self.st.reasons) < 10:
            self.st.reasons.append(reason)

    def _apply(self, session: Session, first: int, widths: list[float]) -> None:
        for k, w in enumerate(widths):
            if first + k < MOTORS:
                session.world.set_motor(first + k, w)
        self.st.applied += 1

    def stats(self) -> dict[str, object]:
        return {
            "transport": self.transport,
            "frames_sent": self.st.sent,
            "frames_applied": self.st.applied,
            "frames_rejected": self.st.rejected,
            "sequence_gaps": self.st.seq_gaps,
            "max_quantisation_us": self.st.max_quantisation_us,
            "reject_reasons": self.st.reasons,
        }

    def close(self) -> None:
        if self.transport == "can":
            self.tx.shutdown()
            self.rx.shutdown()
        else:
            self.port.close()
            os.close(self.master)


def _open_can_pair(interface: str, channel: str) -> tuple[can.BusABC, can.BusABC]:
    """The device's bus and the rig's bus on one channel. ``virtual`` gets a private channel when none
    is named, so parallel runs never hear each other; any other python-can interface (``socketcan`` on a
    bench) uses the channel given. An interface that cannot open is a clear ValueError, not a traceback
    from deep inside python-can."""
    if interface == "virtual" and not channel:
        channel = f"rig-capture-{uuid.uuid4().hex}"
    opened: list[can.BusABC] = []
    try:
        for _ in range(2):
            opened.append(can.Bus(interface=interface, channel=channel, receive_own_messages=False))
    except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as e:
        for bus in opened:
            bus.shutdown()
        raise ValueError(
            f"PWM capture: cannot open CAN interface {interface!r} channel {channel!r}: {e}"
        ) from e
    return opened[0], opened[1]


def check_can(interface: str, channel: str) -> None:
    """Opens and closes the capture's CAN pair once, so a bad interface is found before anything runs
    (ValueError, as at run time)."""
    for bus in _open_can_pair(interface, channel):
        bus.shutdown()


def install_capture(session: Session, capture: Capture, corrupt_every: int = 0) -> CaptureLink | None:
    """Puts a capture link between the DUT's PWM outputs and the plant; None for the direct path."""
    if capture.transport == "direct":
        return None
    link = CaptureLink(
        capture.transport,
        capture.resolution_us,
        capture.rate_hz,
        capture.latency_s,
        corrupt_every,
        capture.can_interface,
        capture.can_channel,
    )
    session.world.direct_pwm = False
    session.at(0.0, lambda s: link.tick(s, 0.0))
    return link
