"""Waits (select, 2 s timeout) for bytes on /dev/ttyRC0, reports when they came, and answers 'pong'."""
import json
import os
import select
import time

fd = os.open("/dev/ttyRC0", os.O_RDWR | os.O_NOCTTY)
t0 = time.monotonic_ns()
ready, _, _ = select.select([fd], [], [], 2.0)
t1 = time.monotonic_ns()
data = os.read(fd, 64) if ready else b""
os.write(fd, b"pong")
time.sleep(0.1)
print(json.dumps({"waited_ns": t1 - t0, "woke_ns": t1, "data": data.decode()}))
