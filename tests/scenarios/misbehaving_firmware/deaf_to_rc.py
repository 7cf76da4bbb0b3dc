"""A DUT that reads its IMU and drives its motors at 250 Hz but never opens its RC port (nor its
telemetry port): the SBUS frames the rig sends pile up unread."""

import os
import time

from smbus2 import SMBus

CHIP = "/sys/class/pwm/pwmchip0"


def write(path: str, text: str) -> None:
    with open(path, "w") as f:
        f.write(text)


bus = SMBus(1)
bus.write_byte_data(0x68, 0x6B, 0x00)  # wake the MPU-6050
for ch in range(4):
    write(f"{CHIP}/export", str(ch))
    write(f"{CHIP}/pwm{ch}/period", "2500000")
    write(f"{CHIP}/pwm{ch}/duty_cycle", "1000000")
    write(f"{CHIP}/pwm{ch}/enable", "1")
duty = [os.open(f"{CHIP}/pwm{ch}/duty_cycle", os.O_WRONLY) for ch in range(4)]
while True:
    bus.read_i2c_block_data(0x68, 0x3B, 14)
    for fd in duty:
        os.pwrite(fd, b"1100000", 0)
    time.sleep(0.004)
