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

The transports share one interface, ``CaptureTransport``, and are found by name in ``TRANSPORTS`` (as
python-can finds its interfaces): adding one is a class with a ``name``, registered with
``@transport``, and its name in emulators.pwm_capture.TRANSPORTS (the scenario format's choices).
"""

from __future__ import annotations

import functools
import os
import time
import tty
import uuid
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import serial

from rig.emulators.pwm_capture import (
    CanCodec,
    CaptureDevice,
    CaptureFrameError,
    SerialDeframer,
    decode_serial,
    encode_serial,
)
from rig.plant.variables import MOTORS

if TYPE_CHECKING:
    import can

    from rig.scenarios.schema import Capture
    from rig.session import Session



@dataclass
class CaptureStats:
    sent: int = 0
    applied: int = 0
    rejected: int = 0
    seq_gaps: int = 0
    max_quantisation_us: float = 0.0
    reasons: list[str] = field(default_factory=list)


#: One decoded report: the first motor it covers (0-based), its sequence number, the widths (µs)
Report = tuple[int, int, list[float]]


class CaptureTransport(ABC):
    """One way the capture device's frames travel to the rig: the device side sends a sample, the rig
    side receives and decodes what has arrived. A transport never trusts what arrives: a frame that
    fails its CRC or layout goes to ``reject`` with the reason, and is not applied."""

    name: ClassVar[str]

    @abstractmethod
    def __init__(self, capture: Capture) -> None: ...

    @abstractmethod
    def send(self, seq: int, widths: list[float], corrupt: Callable[[bytes], bytes]) -> int:
        """The device side: one sample as this transport's frames (``corrupt`` may flip a bit of each, as
        a bad cable would); returns what ``receive`` should wait for (frames or bytes)."""

    @abstractmethod
    def receive(self, expect: int, reject: Callable[[str], None]) -> list[Report]:
        """The rig side: the reports that arrived (waiting, up to a second, for ``expect``)."""

    @abstractmethod
    def close(self) -> None: ...


#: The transports by the name a scenario's [capture] gives (emulators.pwm_capture.TRANSPORTS)
TRANSPORTS: dict[str, type[CaptureTransport]] = {}


def transport(cls: type[CaptureTransport]) -> type[CaptureTransport]:
    """Registers a transport under its ``name`` (as python-can's interfaces are registered)."""
    TRANSPORTS[cls.name] = cls
    return cls


@transport
class CanTransport(CaptureTransport):
    """Two python-can buses on one channel, the device's and the rig's (``virtual`` on a private channel
    in CI; ``socketcan`` on a bench, where the device is real). Frames are the DBC's."""

    name = "can"

    def __init__(self, capture: Capture) -> None:
        import can  # (here, as the other CAN modules: python-can is a tenth of every rig command's start)

        self.codec = CanCodec()
        self.tx, self.rx = _open_can_pair(capture.can_interface, capture.can_channel)
        self._message = can.Message

    def send(self, seq: int, widths: list[float], corrupt: Callable[[bytes], bytes]) -> int:
        frames = self.codec.encode(seq, widths)
        for fid, data in frames:
            self.tx.send(self._message(arbitration_id=fid, data=corrupt(data), is_extended_id=False))
        return len(frames)

    def receive(self, expect: int, reject: Callable[[str], None]) -> list[Report]:
        reports: list[Report] = []
        for _ in range(expect):
            msg = self.rx.recv(timeout=1.0)
            if msg is None:
                break
            try:
                reports.append(self.codec.decode(msg.arbitration_id, bytes(msg.data)))
            except CaptureFrameError as e:
                reject(str(e))
        return reports

    def close(self) -> None:
        self.tx.shutdown()
        self.rx.shutdown()


@transport
class SerialTransport(CaptureTransport):
    """A pty pair, read with pyserial on the rig's side (on a bench, the device's USB serial port).
    Frames are COBS with a 0x00 delimiter and a CRC-16."""

    name = "serial"

    def __init__(self, capture: Capture) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.port = serial.Serial(os.ttyname(slave), timeout=0)
        os.close(slave)  # pyserial holds its own descriptor
        self.deframer = SerialDeframer()

    def send(self, seq: int, widths: list[float], corrupt: Callable[[bytes], bytes]) -> int:
        data = corrupt(encode_serial(seq, widths)[:-1]) + b"\x00"
        view = memoryview(data)
        while view:
            view = view[os.write(self.master, view):]
        return len(data)

    def receive(self, expect: int, reject: Callable[[str], None]) -> list[Report]:
        got = b""
        deadline = time.monotonic() + 1.0
        while len(got) < expect and time.monotonic() < deadline:  # a pty hands bytes over asynchronously
            got += self.port.read(expect - len(got))
        reports: list[Report] = []
        for frame in self.deframer.feed(got):
            try:
                seq, widths = decode_serial(frame)
                reports.append((0, seq, widths))
            except CaptureFrameError as e:
                reject(str(e))
        return reports

    def close(self) -> None:
        self.port.close()
        os.close(self.master)


class CaptureLink:
    """The capture device model and the rig's decoder with a transport between them, run as session
    events: every 1/rate_hz the device samples the DUT's PWM outputs and sends; the rig receives what
    arrived, counts rejected frames and sequence gaps, and applies the widths after ``latency_s``."""

    def __init__(self, capture: Capture, corrupt_every: int = 0) -> None:
        kind = TRANSPORTS.get(capture.transport)
        if kind is None:
            known = ", ".join(TRANSPORTS)
            raise ValueError(f"unknown capture transport {capture.transport!r}; known: {known}")
        self.device = CaptureDevice(capture.resolution_us, capture.rate_hz)
        self.period, self.latency = 1.0 / capture.rate_hz, capture.latency_s
        self.corrupt_every = corrupt_every
        self.st = CaptureStats()
        self.transport = kind(capture)
        self._last_seq: dict[int, int] = {}

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
        expect = self.transport.send(seq, q, self._corrupt)
        for first, seq, widths in self.transport.receive(expect, self._reject):
            last = self._last_seq.get(first)
            if last is not None and seq != (last + 1) % 256:
                self.st.seq_gaps += 1
            self._last_seq[first] = seq
            if self.latency > 0:
                session.at(t + self.latency, functools.partial(self._apply, first=first, widths=widths))
            else:
                self._apply(session, first, widths)
        nxt = t + self.period
        session.at(nxt, lambda s: self.tick(s, nxt))

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
            "transport": self.transport.name,
            "frames_sent": self.st.sent,
            "frames_applied": self.st.applied,
            "frames_rejected": self.st.rejected,
            "sequence_gaps": self.st.seq_gaps,
            "max_quantisation_us": self.st.max_quantisation_us,
            "reject_reasons": self.st.reasons,
        }

    def close(self) -> None:
        self.transport.close()


def _open_can_pair(interface: str, channel: str) -> tuple[can.BusABC, can.BusABC]:
    """The device's bus and the rig's bus on one channel. ``virtual`` gets a private channel when none
    is named, so parallel runs never hear each other; any other python-can interface (``socketcan`` on a
    bench) uses the channel given. An interface that cannot open is a clear ValueError, not a traceback
    from deep inside python-can."""
    import can

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
    link = CaptureLink(capture, corrupt_every)
    session.world.direct_pwm = False
    session.at(0.0, lambda s: link.tick(s, 0.0))
    return link
