"""Sleeps 1 s, then at once looks at /dev/ttyRC0 without waiting (select with timeout 0, then a
non-blocking read) and reports what was there. A sleep that went ahead of the session (WAIT AHEAD) must
not hide the bytes an event wrote during it."""
import json
import os
import select
import time

fd = os.open("/dev/ttyRC0", os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
t0 = time.monotonic_ns()
time.sleep(1.0)
ready, _, _ = select.select([fd], [], [], 0)
try:
    data = os.read(fd, 64)
except BlockingIOError:
    data = b""
print(json.dumps({"ready": bool(ready), "data": data.decode(), "slept_ns": time.monotonic_ns() - t0}))
