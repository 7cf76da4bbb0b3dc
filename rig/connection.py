"""A DUT process's connection to the session: its socket, the bytes read and not yet acted on, and, in
lockstep, the mailbox its messages take in place of the socket once the session granted one at HELLO.

Why a mailbox: in lockstep every request is a round trip on the run's critical path, and through shared
memory and a futex it costs less than half of one through the socket (rig/shim/ring.h says how, and
bench/reference/roundtrip.md how much). The bytes are the same either way: the session reads them into
``buf`` and acts on them as before. The socket stays: its end is the process's end, and a byte on it
wakes the session's loop when the session sleeps in its epoll (the mailbox's own waits are in C,
rig/lockstep/mailbox.c)."""

from __future__ import annotations

import contextlib
import os
import socket
from dataclasses import dataclass, field

from rig import protocol as P
from rig.lockstep import FastPath

RECV_MAX = 1 << 18
BELLS_MAX = 4096


# eq=False: compared by identity. The loop compares each woken key's data with "listen" and "keeper",
# and a generated __eq__ ran as Python for each (about 650 calls per simulated 4 s).
@dataclass(eq=False)
class Conn:
    sock: socket.socket
    index: int
    buf: bytearray = field(default_factory=bytearray)
    hello: bool = False
    pid: int = 0
    #: the fast path that holds this connection's mailbox, once granted (None: the socket carries all)
    mailbox: FastPath | None = None

    def grant(self, fast: FastPath, reply: bytes) -> bool:
        """Sends the HELLO ``reply`` (the one that says a mailbox comes with it) with a new mailbox's
        memfd; False when none is to be had (the caller sends the plain reply, and the connection keeps
        its socket)."""
        fd = self.sock.fileno()
        try:
            memfd = fast.mailbox_open(fd)
        except OSError:  # (no memfd or mapping to be had: the socket serves, as without a mailbox)
            return False
        if memfd < 0:
            return False
        try:
            socket.send_fds(self.sock, [reply], [memfd])
            self.mailbox = fast
        except OSError:
            fast.mailbox_close(fd)  # the process is gone: its end is read next, as any other's
        finally:
            os.close(memfd)
        return True

    def send(self, data: bytes) -> None:
        """A reply. A DUT that does not take its replies (a full mailbox) or is gone gets nothing more:
        the loop sees its end, or the stall watchdog its silence. On the socket, a send that found no
        room for REPLY_TIMEOUT_S (its SO_SNDTIMEO, set at accept) shuts the connection and raises
        RepliesUnread, as the fast path's send does (rig/lockstep/reply.c, send_all)."""
        if self.mailbox is not None:
            self.mailbox.mailbox_put(self.sock.fileno(), data)
            return
        try:
            self.sock.sendall(data)
        except BlockingIOError:
            with contextlib.suppress(OSError):  # (gone meanwhile: it is closed either way)
                self.sock.shutdown(socket.SHUT_RDWR)
            raise P.RepliesUnread(P.REPLIES_UNREAD) from None
        except OSError:
            pass

    def receive(self) -> int:
        """What came, appended to ``buf``: its byte count, 0 when nothing has come, -1 when the
        connection ended and everything before its end was read. A mailbox whose ring is broken (a head
        no ring can have) raises Malformed: the session drops this connection only."""
        if self.mailbox is None:
            try:
                chunk = self.sock.recv(RECV_MAX, socket.MSG_DONTWAIT)
            except BlockingIOError:
                return 0
            except OSError:
                chunk = b""
            self.buf += chunk
            return len(chunk) if chunk else -1
        try:  # the bells (each a zero byte that woke the loop; as many as a read takes), or the end
            bells: bytes | None = self.sock.recv(BELLS_MAX, socket.MSG_DONTWAIT)
        except BlockingIOError:
            bells = None
        except OSError:
            bells = b""
        if bells and bells.count(0) != len(bells):
            raise P.Malformed("bytes other than bells on the socket of a connection with a mailbox")
        ended = bells == b""
        got = self.mailbox.mailbox_take(self.sock.fileno(), self.buf)
        if got < 0:
            raise P.Malformed("its mailbox is broken (a ring's head beyond the ring)")
        return -1 if ended and not got else got

    def release(self) -> None:
        """The mailbox unmapped (the session's run is over, or the connection is)."""
        if self.mailbox is not None:
            self.mailbox.mailbox_close(self.sock.fileno())
            self.mailbox = None

    def close(self) -> None:
        self.release()
        self.sock.close()
