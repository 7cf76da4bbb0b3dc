"""Writes that only start something, as an FC's drivers make them (an MPU-6050 register, the MS5611's
conversion and ADC commands), and two that no chip acknowledges (the HMC5883L behind the MPU with its
bypass off, and an empty address); then the ADC's result. Prints what each gave as JSON: the bytes
written, or the error's name. With ``every S N``: N conversion commands S seconds apart instead."""
import errno
import fcntl
import json
import os
import sys
import time

I2C_SLAVE = 0x0703
fd = os.open("/dev/i2c-1", os.O_RDWR)


def write(addr: int, data: list[int]) -> object:
    fcntl.ioctl(fd, I2C_SLAVE, addr)
    try:
        return os.write(fd, bytes(data))
    except OSError as e:
        return errno.errorcode.get(e.errno or 0, str(e))


if sys.argv[1:2] == ["every"]:
    step, n = float(sys.argv[2]), int(sys.argv[3])
    results = []
    for _ in range(n):
        results.append(write(0x77, [0x48]))
        time.sleep(step)
    print(json.dumps(results))
    sys.exit(0)
out = {"mpu_wake": write(0x68, [0x6B, 0x00]), "convert": write(0x77, [0x48])}
time.sleep(0.010)  # OSR 4096 converts in at most 9.04 ms
out["adc_command"] = write(0x77, [0x00])
fcntl.ioctl(fd, I2C_SLAVE, 0x77)
out["adc"] = os.read(fd, 3).hex()
out["hmc_behind_mpu"] = write(0x1E, [0x00, 0x70])
out["nobody"] = write(0x50, [0x00])
print(json.dumps(out))
