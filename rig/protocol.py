"""The session's side of the shim protocol (``rig/shim/protocol.h`` is the other; a test checks that the
numbers agree). Parsing here never trusts its input: anything that does not fit raises ``Malformed``
with a message that says what was wrong, and the session drops only that connection.
"""

from __future__ import annotations

import struct
from typing import Final

PROTOCOL_VERSION: Final = 5
MAX_PAYLOAD: Final = 65536

HEADER = struct.Struct("<IHHQ")  # len, type, status, t_ns
MSG_HELLO: Final = 1
MSG_I2C: Final = 2
MSG_PWM: Final = 3
MSG_WAIT: Final = 4
MSG_NOTE: Final = 5
MSG_I2C_WRITE: Final = 6  # notice: a write the session promised to acknowledge (SHM_ACK)
MSG_STALL: Final = 7  # notice: text naming a DUT thread that spins; the run ends as a stall does
MSG_NAMES = {MSG_HELLO: "HELLO", MSG_I2C: "I2C", MSG_PWM: "PWM", MSG_WAIT: "WAIT", MSG_NOTE: "NOTE",
             MSG_I2C_WRITE: "I2C_WRITE", MSG_STALL: "STALL"}
#: Requests get one reply; notices get none.
REQUESTS = frozenset({MSG_HELLO, MSG_I2C, MSG_WAIT})

HELLO_MSG = struct.Struct("<II")       # version, pid
HELLO_FLAGS_MSG = struct.Struct("<III")  # version, pid, flags
HELLO_MAILBOX: Final = 1               # flags: the process would take a mailbox (rig/shim/ring.h)
HELLO_GRANTED = struct.Struct("<I")    # the reply's payload when a mailbox comes with it: HELLO_MAILBOX
I2C_HEAD = struct.Struct("<HH")        # bus, nmsgs
I2C_MSG = struct.Struct("<HHHH")       # addr, flags, len, reserved
I2C_M_RD: Final = 0x0001
I2C_M_TEN: Final = 0x0010
I2C_M_RECV_LEN: Final = 0x0400
I2C_RDWR_MAX_MSGS: Final = 42
I2C_MAX_LEN: Final = 8192

PWM_MSG = struct.Struct("<HHHHQ")      # chip, channel, attr, reserved, value
PWM_EXPORT: Final = 1
PWM_UNEXPORT: Final = 2
PWM_PERIOD: Final = 3
PWM_DUTY: Final = 4
PWM_ENABLE: Final = 5
PWM_POLARITY: Final = 6
PWM_ATTR_NAMES = {PWM_EXPORT: "export", PWM_UNEXPORT: "unexport", PWM_PERIOD: "period",
                  PWM_DUTY: "duty_cycle", PWM_ENABLE: "enable", PWM_POLARITY: "polarity"}

WAIT_MSG = struct.Struct("<QII")       # wake_ns, kind, zero
WAIT_FOREVER: Final = 2**64 - 1
WAIT_SLEEP: Final = 1
WAIT_POLL: Final = 2
WAIT_AHEAD: Final = 3  # AHEAD: a notice, the shim moved the clock
WAKE_DEADLINE: Final = 0
WAKE_EVENT: Final = 1
WAKE_SLICE: Final = 2

SHM_MAGIC: Final = 0x31304D4853474952  # "RIGSHM01"
#: the session's promises in the clock page: a write of one message to addr on bus before until_ns is
#: acknowledged (protocol.h struct rig_ack), ACK_MAX of them from SHM_ACKS_OFFSET
SHM_ACK = struct.Struct("<HHIQ")  # bus, addr, reserved, until_ns
ACK_MAX: Final = 4
PWM_MAX: Final = 16
# magic, version, npwm, sim_ns, quantum_ns, epoch_ns, mono_base_ns
SHM_HEAD = struct.Struct("<QIIQQQQ")
SHM_PWM = struct.Struct("<QQIIII")     # period_ns, duty_ns, exported, enabled, inversed, reserved
SHM_SIZE: Final = 4096
SIM_NS_OFFSET: Final = 16
SHM_LIMIT_OFFSET: Final = 560  # limit_ns, after the PWM states
SHM_WAKE_OFFSET: Final = 568  # wake_seq, then session_state (the mailboxes' futex, rig/shim/ring.h)
SHM_ACKS_OFFSET: Final = 576  # the promises (SHM_ACK)


class Malformed(ValueError):
    """Bytes on the socket that are not a message of this protocol."""


#: How long a reply may wait for room on the DUT's socket (its SO_SNDTIMEO). A process under the shim
#: reads each reply before it asks again, so a send waits at all only once a socket buffer (about 200
#: KiB) of replies lies unread: a process that writes requests and never reads, which would otherwise
#: hold the session's loop in send for good (no watchdog, no signal could end the rig).
REPLY_TIMEOUT_S: Final = 2.0
REPLIES_UNREAD: Final = (f"it left a socket buffer of replies unread for {REPLY_TIMEOUT_S:g} s (requests "
                         "written, replies never read)")


class RepliesUnread(Malformed):
    """A connection whose process does not take its replies; closed as a malformed one's is."""


class Header:
    """One message's header. A plain class, not a NamedTuple: one is built per message, and compiled
    (rig/compiled.py) a plain class is a native one, built without a Python-level ``__new__``; a
    NamedTuple stays an interpreted class and cost about a sixth of an FC cycle."""

    __slots__ = ("length", "type", "status", "t_ns")

    def __init__(self, length: int, type: int, status: int, t_ns: int) -> None:
        self.length, self.type, self.status, self.t_ns = length, type, status, t_ns

    @staticmethod
    def parse(data: bytes | bytearray | memoryview, offset: int = 0) -> Header:
        """The header at ``offset`` (``data`` holds at least HEADER.size bytes from there)."""
        length, mtype, status, t_ns = HEADER.unpack_from(data, offset)
        if mtype not in MSG_NAMES:
            raise Malformed(f"unknown message type {mtype}")
        if length > MAX_PAYLOAD:
            raise Malformed(f"{MSG_NAMES[mtype]} payload of {length} bytes exceeds {MAX_PAYLOAD}")
        return Header(length, mtype, status, t_ns)


def reply(mtype: int, t_ns: int, payload: bytes = b"", status: int = 0) -> bytes:
    return HEADER.pack(len(payload), mtype, status, t_ns) + payload


class I2CMessage:
    """One message of an I2C request (a plain class for the reason Header is one)."""

    __slots__ = ("addr", "flags", "length", "data")

    def __init__(self, addr: int, flags: int, length: int, data: bytes) -> None:
        self.addr, self.flags, self.length = addr, flags, length
        self.data = data  # the bytes of a write; empty for a read

    @property
    def read(self) -> bool:
        return bool(self.flags & I2C_M_RD)


def parse_i2c(payload: bytes) -> tuple[int, list[I2CMessage]]:
    """A transfer request: (bus, messages). Structure is checked here; meaning (NACKs) by the bus."""
    if len(payload) < I2C_HEAD.size:
        raise Malformed(f"I2C request of {len(payload)} bytes is shorter than its head")
    bus, n = I2C_HEAD.unpack_from(payload)
    if not 1 <= n <= I2C_RDWR_MAX_MSGS:
        raise Malformed(f"I2C request with {n} messages (1..{I2C_RDWR_MAX_MSGS} allowed)")
    at = I2C_HEAD.size + n * I2C_MSG.size
    if len(payload) < at:
        raise Malformed(f"I2C request announces {n} messages but carries {len(payload)} bytes")
    msgs: list[I2CMessage] = []
    for i in range(n):
        addr, flags, length, _ = I2C_MSG.unpack_from(payload, I2C_HEAD.size + i * I2C_MSG.size)
        if length > I2C_MAX_LEN:
            raise Malformed(f"I2C message {i} of {length} bytes exceeds {I2C_MAX_LEN}")
        data = b""
        if not flags & I2C_M_RD:
            data = bytes(payload[at:at + length])
            if len(data) != length:
                raise Malformed(f"I2C write message {i} announces {length} bytes, {len(data)} present")
            at += length
        msgs.append(I2CMessage(addr, flags, length, data))
    if at != len(payload):
        raise Malformed(f"I2C request has {len(payload) - at} bytes after its last message")
    return bus, msgs


def parse_promised_write(payload: bytes) -> tuple[int, list[I2CMessage]]:
    """An I2C_WRITE notice: a transfer as parse_i2c's, which must be what a promise covers (one plain
    write of a byte or more)."""
    bus, msgs = parse_i2c(payload)
    if len(msgs) != 1 or msgs[0].flags or not msgs[0].length:
        raise Malformed("I2C_WRITE notice that is not one plain write of a byte or more")
    return bus, msgs


def parse_hello(payload: bytes) -> tuple[int, int, int]:
    """HELLO's version, pid and flags (0 when it has none: a client that knows no mailbox)."""
    if len(payload) == HELLO_FLAGS_MSG.size:
        version, pid, flags = HELLO_FLAGS_MSG.unpack(payload)
        return version, pid, flags
    version, pid = parse_fixed(payload, HELLO_MSG, "HELLO")
    return version, pid, 0


def parse_fixed(payload: bytes, shape: struct.Struct, what: str) -> tuple[int, ...]:
    if len(payload) != shape.size:
        raise Malformed(f"{what} payload of {len(payload)} bytes (expected {shape.size})")
    return shape.unpack(payload)
