"""Ignores SIGTERM, writes its pid into argv[1] (a FIFO, tests/waits.py) and spins on the clock
forever: the DUT that outlived `timeout rig exec`, and that only a kill that cannot be ignored ends."""

import os
import signal
import sys
import time

signal.signal(signal.SIGTERM, signal.SIG_IGN)
with open(sys.argv[1], "w") as f:
    f.write(f"{os.getpid()}\n")
while True:
    time.monotonic()
