"""One 14-byte MPU burst between two clock reads: prints the monotonic nanoseconds it took."""
import time

from smbus2 import SMBus, i2c_msg

with SMBus(1) as bus:
    w, r = i2c_msg.write(0x68, [0x3B]), i2c_msg.read(0x68, 14)
    t0 = time.monotonic_ns()
    bus.i2c_rdwr(w, r)
    t1 = time.monotonic_ns()
print(t1 - t0)
