"""A second implementation of the shim's side of the mailbox (rig/shim/ring.h), from its documented
layout, on a connection of its own beside the shim's.

    mailbox_client.py wrap     300 transfers of about 8 KB each way: both rings wrap twice
    mailbox_client.py broken   the memfd cannot be shrunk; a head no ring can have: the session must
                               drop this connection only
    mailbox_client.py flood    I2C requests put without end, their replies never read, no bell rung:
                               the session must still end the run by its wall-time watchdog
    mailbox_client.py nofd     the memfd not taken (as a process at its limit of open files loses it),
                               then a request on the socket: the session must drop this connection

Prints what it saw, then reads WHO_AM_I through the shim (smbus2) to show the session still serves.
"""
import ctypes
import mmap
import os
import socket
import struct
import sys

from smbus2 import SMBus

HEADER = struct.Struct("<IHHQ")
RING = 1 << 20
UP, DOWN = 64, 128                      # the two rings' counters: head, tail (u64), seq, sleeping (u32)
UP_DATA, DOWN_DATA = 192, 192 + RING
WAKE_SEQ, SESSION_STATE = 568, 572      # in the clock page
POLL, FUTEX = 0, 2
SYS_FUTEX, FUTEX_WAIT, FUTEX_WAKE = 202, 0, 1

libc = ctypes.CDLL(None, use_errno=True)
libc.syscall.restype = ctypes.c_long


class Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


# the shared counters through ctypes: one load or store each (struct's pack_into and unpack_from move
# them a byte at a time, and the other side would see a counter half written)
def u64(mm: mmap.mmap, at: int) -> int:
    return int(ctypes.c_uint64.from_buffer(mm, at).value)


def u32(mm: mmap.mmap, at: int) -> int:
    return int(ctypes.c_uint32.from_buffer(mm, at).value)


def set64(mm: mmap.mmap, at: int, value: int) -> None:
    ctypes.c_uint64.from_buffer(mm, at).value = value


def set32(mm: mmap.mmap, at: int, value: int) -> None:
    ctypes.c_uint32.from_buffer(mm, at).value = value


def address(mm: mmap.mmap, at: int) -> int:
    return ctypes.addressof(ctypes.c_uint32.from_buffer(mm, at))


fd = os.open(os.environ["RIG_SHM"], os.O_RDWR)
page = mmap.mmap(fd, 4096)
os.close(fd)
sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
sock.connect(os.environ["RIG_SOCKET"])
sock.sendall(HEADER.pack(12, 1, 0, u64(page, 16)) + struct.pack("<III", 5, os.getpid(), 1))
if sys.argv[1] == "nofd":
    reply = sock.recv(HEADER.size + 4)   # (no room for the descriptor: the kernel closes it)
    assert reply[HEADER.size:] == struct.pack("<I", 1), reply
    sock.sendall(HEADER.pack(0, 4, 0, 0))
    print("closed" if sock.recv(1) == b"" else "open")
    with SMBus(1) as bus:
        print(hex(bus.read_byte_data(0x68, 0x75)))
    sys.exit()
reply, fds, _, _ = socket.recv_fds(sock, HEADER.size + 4, 1)
assert reply[HEADER.size:] == struct.pack("<I", 1) and len(fds) == 1, (reply, fds)  # granted
box = mmap.mmap(fds[0], 192 + 2 * RING)
try:
    os.ftruncate(fds[0], 0)
    print("shrunk")
except PermissionError:
    print("sealed")
os.close(fds[0])
assert box[:8] == b"MAILBOX1" and u64(box, 8) == RING
head = tail = 0


def wake_session() -> None:
    set32(page, WAKE_SEQ, (u32(page, WAKE_SEQ) + 1) & 0xFFFFFFFF)
    state = u32(page, SESSION_STATE)
    if state == FUTEX:
        libc.syscall(SYS_FUTEX, ctypes.c_void_p(address(page, WAKE_SEQ)), FUTEX_WAKE, 1, None, None, 0)
    elif state == POLL and sys.argv[1] != "flood":  # (flood: as if the session never slept in its loop)
        sock.send(b"\0")


def put(data: bytes) -> None:
    global head
    while head + len(data) - u64(box, UP + 8) > RING:  # no room: the session has not read enough yet
        wake_session()
    for i, byte_run in enumerate((data[:RING - head % RING], data[RING - head % RING:])):
        at = UP_DATA + (head % RING if i == 0 else 0)
        box[at:at + len(byte_run)] = byte_run
    head += len(data)
    set64(box, UP, head)
    wake_session()


def take(n: int) -> bytes:
    global tail
    while u64(box, DOWN) - tail < n:  # asleep on the ring's futex, 10 ms at most at a time
        seen = u32(box, DOWN + 16)
        set32(box, DOWN + 20, 1)
        if u64(box, DOWN) - tail < n:
            libc.syscall(SYS_FUTEX, ctypes.c_void_p(address(box, DOWN + 16)), FUTEX_WAIT, seen,
                         ctypes.byref(Timespec(0, 10_000_000)), None, 0)
        set32(box, DOWN + 20, 0)
    at = tail % RING
    data = bytes(box[DOWN_DATA + at:DOWN_DATA + min(at + n, RING)])
    data += bytes(box[DOWN_DATA:DOWN_DATA + n - len(data)])
    tail += n
    set64(box, DOWN + 8, tail)
    return data


def request(msgs: list[tuple[int, int, int]], written: bytes) -> bytes:
    payload = struct.pack("<HH", 1, len(msgs))
    payload += b"".join(struct.pack("<HHHH", a, f, n, 0) for a, f, n in msgs) + written
    return HEADER.pack(len(payload), 2, 0, u64(page, 16)) + payload


def transfer(msgs: list[tuple[int, int, int]], written: bytes) -> tuple[int, bytes]:
    put(request(msgs, written))
    length, mtype, status, _ = HEADER.unpack(take(HEADER.size))
    assert mtype == 2, mtype
    return status, take(length)


def note(length: int) -> None:
    put(HEADER.pack(length, 5, 0, u64(page, 16)) + b"p" * length)


if sys.argv[1] == "wrap":
    # each lap of each ring, one message's header is placed across the ring's end: a NOTE (no reply)
    # pads the up ring, a read's length the down ring
    good_reads = absent_writes = across_up = across_down = 0
    for i in range(300):
        # the read's length that puts the next reply's header across the end; or, short of that, one that
        # leaves that length for the next read
        want = (RING - 2 - HEADER.size - tail) % RING
        length = want if 1 <= want <= 8192 else min(8192, max(1, want - 4096 - 2 * HEADER.size))
        to_end = RING - head % RING
        if HEADER.size + 2 <= to_end < 2 * 8192:
            note(to_end - HEADER.size - 2)                  # the next header starts 2 bytes before the end
        across_up += RING - head % RING < HEADER.size
        status, data = transfer([(0x68, 0, 1), (0x68, 1, length)], b"\x75")
        good_reads += status == 0 and len(data) == length and data[0] == 0x68
        pattern = bytes((i + k) % 251 for k in range(8000))
        across_down += RING - tail % RING < HEADER.size
        status, data = transfer([(0x50, 0, 8000)], pattern)
        absent_writes += status != 0 and data == b""
    print("reads", good_reads, "absent", absent_writes, "up", head, "down", tail, "across", across_up,
          across_down)
elif sys.argv[1] == "flood":
    who_am_i = request([(0x68, 0, 1), (0x68, 1, 1)], b"\x75")
    while True:
        put(who_am_i)
else:
    set64(box, UP, 1 << 40)
    wake_session()
    print("closed" if sock.recv(1) == b"" else "open")
with SMBus(1) as bus:
    print(hex(bus.read_byte_data(0x68, 0x75)))
