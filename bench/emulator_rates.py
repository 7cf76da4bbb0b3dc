"""In-process emulator rates (printed, never asserted): transactions per second for a 14-byte MPU-6050
burst, an HMC5883L 6-byte read and an MS5611 convert + ADC read, and the cost of one sample update of
all three devices. Usage: python bench/emulator_rates.py [--n N]."""

from __future__ import annotations

import argparse
import time

from rig.compiled import install, status

install()  # the compiled hot modules, before they are imported
from rig.emulators.hmc5883l import HMC5883L  # noqa: E402
from rig.emulators.i2c_bus import I2CBus, read, write  # noqa: E402
from rig.emulators.mpu6050 import MPU6050  # noqa: E402
from rig.emulators.ms5611 import MS5611  # noqa: E402
from rig.emulators.sensor_models import AxisErrors, BaroModel, ImuModel, MagModel  # noqa: E402
from rig.emulators.topology import build_board  # noqa: E402

TRUTH = {"fx": 0.1, "fy": -0.2, "fz": -9.80665, "p": 0.01, "q": -0.02, "r": 0.03, "temperature": 15.0,
         "mag_x": 0.25, "mag_y": 0.0, "mag_z": 0.433, "pressure": 101325.0}


def make_board():
    noisy = AxisErrors(noise_density=0.002, bias_random_walk=1e-4)
    b = build_board(MPU6050(ImuModel(lambda t: TRUTH, accel=noisy, gyro=noisy)),
                    HMC5883L(MagModel(lambda t: TRUTH)), MS5611(BaroModel(lambda t: TRUTH, noise_pa=1.0)),
                    "direct")
    b.bus.transfer([write(0x68, 0x6B, 0x00), write(0x68, 0x1A, 0x01), write(0x1E, 0x02, 0x00)], 0.0)
    return b


def rate(fn, n):
    start = time.perf_counter()
    for k in range(n):
        fn(k)
    return n / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20000)
    n = parser.parse_args().n
    b = make_board()
    bus = b.bus
    t0 = 1.0
    mpu_burst = [write(0x68, 0x3B), read(0x68, 14)]
    hmc_read = [write(0x1E, 0x03), read(0x1E, 6)]
    baro_bus = I2CBus()  # alone, so that advancing time does not also run MPU samples
    baro_bus.attach(0x77, MS5611(BaroModel(lambda t: TRUTH, noise_pa=1.0)))
    rates = {
        "MPU-6050 14-byte burst": rate(lambda k: bus.transfer(mpu_burst, t0), n),
        "HMC5883L 6-byte read": rate(lambda k: bus.transfer(hmc_read, t0), n),
        "MS5611 convert + ADC read": rate(
            lambda k: (baro_bus.transfer([write(0x77, 0x48)], t0 + k * 0.01),
                       baro_bus.transfer([write(0x77, 0x00), read(0x77, 3)], t0 + k * 0.01 + 0.009)), n),
    }
    # One sample update of all three: advance 1 ms (one MPU sample at 1 kHz), with the HMC at 75 Hz
    # continuous and an MS5611 conversion finishing now and then.
    b2 = make_board()
    b2.bus.transfer([write(0x1E, 0x00, 0x18)], 0.0)
    update = rate(lambda k: b2.bus.advance_to(1.0 + k * 1e-3), n)
    print(f"emulator rates (in-process; {status()}):")
    for name, r in rates.items():
        print(f"  {name:28s} {r:10,.0f} transactions/s  {1e6 / r:7.1f} us each")
    print(f"  {'sample update, all three':28s} {update:10,.0f} updates/s      {1e6 / update:7.1f} us each "
          "(1 ms of sim time: one MPU sample with noise models)")


if __name__ == "__main__":
    main()
