"""A flight-controller-shaped loop: read the IMU burst, sleep to the next 2.5 ms deadline, forever.
Argument: the MPU's CONFIG register (0: 8 kHz gyro sampling, 3: DLPF 44 Hz and 1 kHz)."""
import sys
import time

from smbus2 import SMBus

with SMBus(1) as bus:
    bus.write_byte_data(0x68, 0x6B, 0x00)
    bus.write_byte_data(0x68, 0x1A, int(sys.argv[1]))
    deadline = time.monotonic()
    while True:
        bus.read_i2c_block_data(0x68, 0x3B, 14)
        deadline += 0.0025
        time.sleep(max(0.0, deadline - time.monotonic()))
