"""A flight-controller-shaped loop: read the IMU burst, sleep to the next 2.5 ms deadline, forever."""
import time

from smbus2 import SMBus

with SMBus(1) as bus:
    bus.write_byte_data(0x68, 0x6B, 0x00)
    deadline = time.monotonic()
    while True:
        bus.read_i2c_block_data(0x68, 0x3B, 14)
        deadline += 0.0025
        time.sleep(max(0.0, deadline - time.monotonic()))
