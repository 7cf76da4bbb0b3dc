"""The host's end of the bridge link: a serial port (pyserial: a NUCLEO's ST-LINK virtual COM port, a
USB-serial adapter, or the virtual bridge's pty) carrying the frames of rig/bridge/link.py.

Why its own module: the real-time session must never block on the link. Every read here is bounded by
a deadline the caller gives, and a link that stops talking is an error with a reason, raised within
``silent_after_s`` (the bridge sends STATUS several times a second and answers every TIME_SYNC, so half a
second without a frame means it is gone). A port that hangs up (the bridge was unplugged, the virtual
bridge died) is an error at once.
"""

from __future__ import annotations

import os
import secrets
import select
import time
from collections.abc import Callable, Sequence

import serial

from rig.bridge.link import Decoded, Receiver, encode, encode_flat
from rig.bridge.messages import PROTOCOL_VERSION, Message

BAUDRATE = 2_000_000
SILENT_AFTER_S = 0.5


class BridgeError(RuntimeError):
    """The bridge cannot be used (wrong protocol, no answer) or the link died; the message says why."""


class BridgePort:
    def __init__(self, path: str, baudrate: int = BAUDRATE, silent_after_s: float = SILENT_AFTER_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        try:
            self._ser = serial.Serial(path, baudrate=baudrate, timeout=0, write_timeout=1.0, exclusive=True)
        except (serial.SerialException, OSError) as e:
            raise BridgeError(f"cannot open the bridge's port {path}: {e}") from e
        self.path = path
        self._fd: int = self._ser.fileno()
        self.rx = Receiver("up")
        self.sent = 0
        self.bytes_down = 0
        self.bytes_up = 0
        self._seq = 0
        self._clock = clock
        self.silent_after_s = silent_after_s
        self.last_rx = clock()

    def fileno(self) -> int:
        return int(self._ser.fileno())

    def send(self, name: str, **values: object) -> None:
        self._write(name, encode(name, self._seq, **values))

    def send_flat(self, msg: Message, flat: Sequence[object]) -> None:
        """``send`` from the field values in table order, arrays spread (link.encode_flat)."""
        self._write(msg.name, encode_flat(msg, self._seq, flat))

    def _write(self, name: str, frame: bytes) -> None:
        self._seq = (self._seq + 1) & 0xFF
        try:
            # straight to the descriptor (pyserial opened it non-blocking): pyserial's write waits for
            # room after every write, one more system call and its Python per frame, on the real-time
            # loop's thousands a second; only what did not fit goes through it (its write timeout)
            try:
                done = os.write(self._fd, frame)
            except BlockingIOError:
                done = 0
            if done < len(frame):
                self._ser.write(frame[done:])
        except (serial.SerialException, OSError) as e:
            raise BridgeError(f"the link to the bridge on {self.path} failed sending {name}: {e}") from e
        self.sent += 1
        self.bytes_down += len(frame)

    def poll(self, timeout_s: float = 0.0) -> list[Decoded]:
        """The messages that arrived, waiting at most ``timeout_s`` for the first bytes; BridgeError when
        the port hung up or nothing valid came for ``silent_after_s``."""
        fd = self.fileno()
        ready, _, _ = select.select([fd], [], [], max(0.0, timeout_s))
        msgs: list[Decoded] = []
        if ready:
            try:
                data = os.read(fd, 65536)
            except OSError as e:  # EIO: the other end of a pty closed; a USB adapter unplugged
                raise BridgeError(f"the bridge on {self.path} hung up ({e.strerror})") from e
            if not data:
                raise BridgeError(f"the bridge on {self.path} hung up")
            self.bytes_up += len(data)
            msgs = self.rx.feed(data)
        now = self._clock()
        if msgs:
            self.last_rx = now
        elif now - self.last_rx > self.silent_after_s:
            raise BridgeError(f"the bridge on {self.path} sent no valid frame for "
                              f"{now - self.last_rx:.2f} s ({self.rx.bad} bad frames)")
        return msgs

    def hello(self, timeout_s: float = 1.0) -> Decoded:
        """Starts a session: the bridge's HELLO_REPLY, which must speak our protocol."""
        nonce = secrets.randbits(32)
        self.send("HELLO", version=PROTOCOL_VERSION, nonce=nonce)
        deadline = self._clock() + timeout_s
        self.last_rx = self._clock()
        while (left := deadline - self._clock()) > 0:
            for m in self.poll(min(left, 0.05)):
                if m.name == "HELLO_REPLY" and m.values["nonce"] == nonce:
                    if m.values["version"] != PROTOCOL_VERSION:
                        raise BridgeError(f"the bridge on {self.path} speaks protocol {m.values['version']}, "
                                          f"the rig {PROTOCOL_VERSION}: update one of them")
                    return m
        raise BridgeError(f"no bridge answered on {self.path} within {timeout_s:.1f} s "
                          f"({self.rx.ok} frames, {self.rx.bad} bad)")

    def close(self) -> None:
        self._ser.close()
        self._fd = -1  # (send writes to it directly: never to a number the process has reused since)

    def figures(self) -> dict[str, object]:
        return {"frames_sent": self.sent, "frames_received": self.rx.ok, "frames_bad": self.rx.bad,
                "seq_gaps": self.rx.seq_gaps, "bytes_down": self.bytes_down, "bytes_up": self.bytes_up,
                "bad_reasons": list(self.rx.reasons)}


def bridge_id(reply: Decoded) -> str:
    """The bridge's name from its HELLO_REPLY (NUL-padded ASCII; anything else shown escaped)."""
    raw = bytes(reply.values["bridge_id"])  # type: ignore[call-overload]
    return raw.rstrip(b"\0").decode("ascii", "backslashreplace")
