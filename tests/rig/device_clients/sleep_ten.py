"""Sleeps 10 s; prints how much monotonic and wall-calendar time it saw pass."""
import json
import time

m0, w0 = time.monotonic_ns(), time.time_ns()
time.sleep(10)
print(json.dumps({"monotonic_ns": time.monotonic_ns() - m0, "time_ns": time.time_ns() - w0}))
