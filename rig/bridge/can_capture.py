"""The motors of a bench run read from a CAN capture device instead of the bridge's link (docs/bench.md
"Capture over CAN"): the DBC's PWM_CAPTURE frames (emulators/pwm_capture.dbc), decoded and checked
by the same CanCodec the lockstep capture uses.

On a bench the interface is SocketCAN (``socketcan:can0``) or a USB adapter speaking slcan
(``slcan:/dev/ttyACM1``). With ``--bridge virtual`` the channel ``vbridge`` names the virtual bridge's
own CAN pty, where the bridge core's capture frames come out as an slcan adapter would hand them over:
python-can's real ``slcan`` interface reads them, since these machines have no vcan.

Nothing that arrives is trusted: a line the interface cannot parse, an unknown id, a bad length or CRC
is counted and dropped; a gap in a frame's sequence byte is counted.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import can
import serial
from can.interfaces.slcan import slcanBus

from rig.bridge.port import BridgeError
from rig.emulators.pwm_capture import CanCodec, CaptureFrameError
from rig.plant.variables import MOTORS
from rig.world import World


class BatchedSlcan(slcanBus):
    """python-can's slcan interface, its port read a batch at a time.

    Its own ``_read`` takes one byte per pyserial ``read`` (a select and a read each, and, with the
    1 ms port timeout it opens with, a millisecond's wait whenever no line was whole): polled from the
    real-time loop, reading the capture frames cost 315 us a poll and 445 us a frame, 30 % of the loop's
    time, and made 60 % of its events over 1 ms late. Here what the port holds is read at once and the
    next line is cut from it; the lines are parsed by the interface as they were (``_recv_internal``)."""

    def _read(self, timeout: float | None) -> str | None:
        buf = self._buffer
        end = _line_end(buf)
        if end < 0:
            try:
                waiting = self.serialPortOrig.in_waiting
                if waiting:
                    buf += self.serialPortOrig.read(waiting)
            except (serial.SerialException, OSError) as e:
                raise can.CanOperationError(f"Could not read from serial device: {e}") from e
            end = _line_end(buf)
            if end < 0:  # (a wait asked for: the interface's own, byte by byte)
                return super()._read(timeout) if timeout is None or timeout > 0 else None
        line = bytes(buf[:end + 1])
        del buf[:end + 1]
        try:
            return line.decode()
        except UnicodeDecodeError as e:  # (as the interface's own read fails on such a line)
            raise can.CanOperationError(f"Could not read from serial device: {e}") from e


def _line_end(buf: bytearray) -> int:
    """Where the first slcan line (ended by CR, or BEL for an error) ends in ``buf``; -1: none yet."""
    cr, bel = buf.find(slcanBus._OK), buf.find(slcanBus._ERROR)
    return bel if cr < 0 else cr if bel < 0 else min(cr, bel)


#: the channel that means "the virtual bridge's CAN pty"
VBRIDGE_CHANNEL = "vbridge"
MAX_FRAMES_PER_POLL = 256  # a poll never spends longer than this on a flood


@dataclass
class CanFigures:
    frames: int = 0
    applied: int = 0
    rejected: int = 0
    seq_gaps: int = 0
    reasons: list[str] = field(default_factory=list)

    def as_dict(self, interface: str, channel: str) -> dict[str, object]:
        return {"interface": interface, "channel": channel, "frames": self.frames, "applied": self.applied,
                "rejected": self.rejected, "seq_gaps": self.seq_gaps, "reject_reasons": self.reasons}


def parse(spec: str) -> tuple[str, str]:
    """``INTERFACE:CHANNEL`` (``socketcan:can0``, ``slcan:/dev/ttyACM1``, ``slcan:vbridge``)."""
    interface, sep, channel = spec.partition(":")
    if not (interface and sep and channel):
        raise ValueError(f"expected INTERFACE:CHANNEL (e.g. socketcan:can0 or slcan:vbridge), got {spec!r}")
    return interface, channel


class CanPulses:
    """A python-can bus the capture frames arrive on; ``poll`` applies what came to the world's motors."""

    def __init__(self, interface: str, channel: str) -> None:
        self.interface, self.channel = interface, channel
        self.codec = CanCodec()
        self.figures = CanFigures()
        self._last_seq: dict[int, int] = {}
        # slcan waits 2 s after opening by default, for adapters that reset on open (a pty needs none),
        # and reads its port with a 1 ms timeout, which a poll here never waits for
        try:
            self.bus: can.BusABC
            if interface == "slcan":
                self.bus = BatchedSlcan(channel=channel, sleep_after_open=0.0, timeout=0.0)
            else:
                self.bus = can.Bus(interface=interface, channel=channel)
        except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as e:
            raise BridgeError(f"capture over CAN: cannot open {interface!r} channel {channel!r}: {e}") from e

    def poll(self, world: World, to_pwm_us: float = 1.0) -> None:
        """Applies the frames that came; ``to_pwm_us``: the ESC protocol's scale into the plant's PWM
        microseconds (rig/bridge/esc.py; OneShot125: 8)."""
        for _ in range(MAX_FRAMES_PER_POLL):
            try:
                msg = self.bus.recv(timeout=0.0)
            except (ValueError, IndexError, can.CanError) as e:  # a line the interface could not parse
                self._reject(f"unreadable frame: {type(e).__name__}: {e}")
                continue
            if msg is None:
                return
            self.figures.frames += 1
            try:
                first, seq, widths = self.codec.decode(msg.arbitration_id, bytes(msg.data))
            except CaptureFrameError as e:
                self._reject(str(e))
                continue
            last = self._last_seq.get(first)
            if last is not None and seq != (last + 1) % 256:
                self.figures.seq_gaps += 1
            self._last_seq[first] = seq
            for k, w in enumerate(widths):
                if first + k < MOTORS:
                    world.set_motor(first + k, w * to_pwm_us)
            self.figures.applied += 1

    def _reject(self, reason: str) -> None:
        self.figures.rejected += 1
        if len(self.figures.reasons) < 10:
            self.figures.reasons.append(reason)

    def close(self) -> None:
        self.bus.shutdown()
