"""A DUT that reads the IMU once, writes its pid into argv[1] (a FIFO, tests/waits.py), and then blocks
outside the emulated devices (a read on a pipe nobody writes): the run stays in the session's wait loop
until a watchdog, a signal or the test ends it."""

import os
import sys

from smbus2 import SMBus

SMBus(1).read_byte_data(0x68, 0x75)
with open(sys.argv[1], "w") as f:
    f.write(f"{os.getpid()}\n")
r, _ = os.pipe()
os.read(r, 1)
