"""Times N MPU-6050 burst reads with the real monotonic clock (a raw syscall, which the shim does not
see), so the numbers are wall time even under lockstep. Prints JSON."""
import ctypes
import json
import os
import sys

from smbus2 import SMBus, i2c_msg

SYS_CLOCK_GETTIME = {"x86_64": 228, "aarch64": 113}[os.uname().machine]
libc = ctypes.CDLL(None, use_errno=True)


class Timespec(ctypes.Structure):
    _fields_ = [("sec", ctypes.c_long), ("nsec", ctypes.c_long)]


ts = Timespec()


def now_ns() -> int:
    libc.syscall(SYS_CLOCK_GETTIME, 1, ctypes.byref(ts))
    return ts.sec * 1_000_000_000 + ts.nsec


n = int(sys.argv[1])
rtts = []
with SMBus(1) as bus:
    bus.write_byte_data(0x68, 0x6B, 0x00)
    w, r = i2c_msg.write(0x68, [0x3B]), i2c_msg.read(0x68, 14)
    start = now_ns()
    for _ in range(n):
        t0 = now_ns()
        bus.i2c_rdwr(w, r)
        rtts.append(now_ns() - t0)
    total = now_ns() - start
rtts.sort()
print(json.dumps({"p50_us": rtts[n // 2] / 1e3, "p99_us": rtts[n * 99 // 100] / 1e3,
                  "tx_per_s": n / total * 1e9}))
