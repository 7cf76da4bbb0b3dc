"""A DUT that flies nothing useful but reports telemetry the hard way: each line in three writes with a
sleep between (so the session reads them across several requests), and its altitude as NaN after 1 s.
It reads the IMU and drives its motors at idle, so the run is a flight."""

import math
import os
import time

from smbus2 import SMBus

CHIP = "/sys/class/pwm/pwmchip0"
bus = SMBus(1)
for ch in range(4):
    for attr, value in (("export", str(ch)), (f"pwm{ch}/period", "2500000"),
                        (f"pwm{ch}/duty_cycle", "1000000"), (f"pwm{ch}/enable", "1")):
        with open(f"{CHIP}/{attr}" if attr == "export" else f"{CHIP}/{attr}", "w") as f:
            f.write(value)
tel = os.open("/dev/ttyTEL0", os.O_WRONLY)
t0 = time.monotonic()
while True:
    bus.read_i2c_block_data(0x68, 0x3B, 14)
    t = time.monotonic()
    alt = math.nan if t - t0 > 1.0 else 0.0
    line = f"T t={t:.4f} roll=1.500 pitch=-0.500 yaw=0.000 alt={alt:.3f} armed=0\n".encode()
    for part in (line[:5], line[5:30], line[30:]):
        os.write(tel, part)
        time.sleep(0.001)
    time.sleep(0.01)
