"""The host's side of the bridge link's framing (docs/design.md §8 "Link"): messages of the table in
rig/bridge/messages.py as COBS frames with a CRC-16/CCITT-FALSE and a sequence byte.

Nothing that arrives is trusted: a frame that fails its COBS decoding, its CRC, its length, or names a
message that does not exist or goes the other way is counted with its reason and dropped, never
handed on; a sequence byte that skips counts a gap (frames were lost on the wire). The bridge's decoder
(bridge/core/link.c) follows the same rules, and tests hold the two against each other.
"""

from __future__ import annotations

import binascii
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field

from cobs import cobs

from rig.bridge.messages import BY_ID, BY_NAME, MAX_FRAME, Direction, Message

CRC = struct.Struct(">H")


class LinkError(ValueError):
    """A frame that must not be acted on; the message says why."""


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: check value 0x29B1 for b"123456789"."""
    return binascii.crc_hqx(data, 0xFFFF)


def pack(name: str, seq: int, **values: object) -> bytes:
    """The message's raw frame (type, seq, body, CRC) before COBS."""
    msg = BY_NAME[name]
    if not values.keys() <= msg.field_names:
        raise ValueError(f"{name} has no field(s) {sorted(set(values) - msg.field_names)}")
    flat: list[object] = []
    for f in msg.fields:
        if f.count == 1:
            flat.append(values.get(f.name, 0))
            continue
        v = values.get(f.name, ())
        if isinstance(v, str):
            v = v.encode()
        if not isinstance(v, bytes | list | tuple):
            raise ValueError(f"{name}.{f.name}: expected {f.count} values, got {v!r}")
        if len(v) > f.count:
            raise ValueError(f"{name}.{f.name}: {len(v)} values, at most {f.count}")
        flat += v
        if len(v) < f.count:
            flat += [0] * (f.count - len(v))
    return _raw(msg, seq, flat)


def _raw(msg: Message, seq: int, flat: Sequence[object]) -> bytes:
    raw = bytes((msg.id, seq & 0xFF)) + msg.layout.pack(*flat)
    return raw + CRC.pack(crc16(raw))


def encode(name: str, seq: int, **values: object) -> bytes:
    """One message as it goes on the wire: COBS, then the 0x00 delimiter."""
    return cobs.encode(pack(name, seq, **values)) + b"\x00"


def encode_flat(msg: Message, seq: int, flat: Sequence[object]) -> bytes:
    """What ``encode`` makes, from the field values in table order with arrays spread (``struct.error``
    when they do not fit the layout): the stream's samples, thousands a second on the real-time loop,
    skip the checks by name that ``pack`` makes for every other message."""
    return cobs.encode(_raw(msg, seq, flat)) + b"\x00"


@dataclass
class Decoded:
    name: str
    seq: int
    values: dict[str, object]


def unpack(raw: bytes, direction: Direction) -> Decoded:
    """A raw frame (COBS already undone) as a message going ``direction``; LinkError if it is not one."""
    if len(raw) < 4:
        raise LinkError(f"a frame of {len(raw)} bytes is shorter than type, seq and CRC")
    if crc16(raw[:-2]) != CRC.unpack_from(raw, len(raw) - 2)[0]:
        raise LinkError("CRC mismatch")
    msg: Message | None = BY_ID.get(raw[0])
    if msg is None:
        raise LinkError(f"unknown message type 0x{raw[0]:02x}")
    if msg.direction != direction:
        raise LinkError(f"{msg.name} goes {msg.direction}, not {direction}")
    body = raw[2:-2]
    if len(body) != msg.layout.size:
        raise LinkError(f"{msg.name}: {len(body)} body bytes, expected {msg.layout.size}")
    flat = list(msg.layout.unpack(body))
    values: dict[str, object] = {}
    for f in msg.fields:
        if f.count > 1:
            values[f.name], flat = flat[:f.count], flat[f.count:]
        else:
            values[f.name] = flat.pop(0)
    return Decoded(msg.name, raw[1], values)


@dataclass
class Receiver:
    """Turns the bytes of one direction into messages, frame by frame, whatever the chunking."""

    direction: Direction
    ok: int = 0
    bad: int = 0
    seq_gaps: int = 0
    reasons: list[str] = field(default_factory=list)  # the first few, for the report
    _buf: bytearray = field(default_factory=bytearray)
    _last_seq: int | None = None

    def feed(self, data: bytes) -> list[Decoded]:
        out = []
        self._buf += data
        while (end := self._buf.find(0)) >= 0:
            frame = bytes(self._buf[:end])
            del self._buf[:end + 1]
            if not frame:
                continue  # an idle delimiter
            try:
                msg = unpack(cobs.decode(frame), self.direction)
            except (cobs.DecodeError, LinkError) as e:
                self._reject(str(e) if isinstance(e, LinkError) else f"COBS: {e}")
                continue
            if self._last_seq is not None and msg.seq != (self._last_seq + 1) & 0xFF:
                self.seq_gaps += 1
            self._last_seq = msg.seq
            self.ok += 1
            out.append(msg)
        if len(self._buf) > 2 * MAX_FRAME:  # no delimiter for longer than any frame: noise
            self._reject(f"{len(self._buf)} bytes without a frame delimiter")
            self._buf.clear()
        return out

    def _reject(self, why: str) -> None:
        self.bad += 1
        if len(self.reasons) < 10:
            self.reasons.append(why)
