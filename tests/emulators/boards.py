"""Small helpers: devices fed by constant or scripted truth, and byte helpers. Boards are made of the
Python chips or of the chip core, as ``IMPL`` says (tests/emulators/conftest.py runs each test with
both)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from rig.emulators.chips.board import build_chip_board
from rig.emulators.faults import FaultSet, FaultyDevice
from rig.emulators.hmc5883l import HMC5883L
from rig.emulators.i2c_bus import I2CDevice
from rig.emulators.mpu6050 import MPU6050, ImuTruth
from rig.emulators.ms5611 import MS5611, BaroTruth
from rig.emulators.topology import build_board

IMPLS = ("python", "core")
IMPL = "python"


class Script:
    """Mutable truth: tests change attributes between transfers."""

    def __init__(self) -> None:
        self.accel = (0.0, 0.0, 9.80665)
        self.gyro = (0.0, 0.0, 0.0)
        self.temperature = 25.0
        self.field = (0.25, 0.0, 0.433)
        self.pressure = 101325.0

    def imu(self, t: float) -> ImuTruth:
        return ImuTruth(self.accel, self.gyro, self.temperature)

    def mag(self, t: float) -> tuple[float, float, float]:
        return self.field

    def baro(self, t: float) -> BaroTruth:
        return BaroTruth(self.pressure, self.temperature)


def make_board(imu: Callable[[float], ImuTruth], mag: Callable[[float], tuple[float, float, float]],
               baro: Callable[[float], BaroTruth], topology: str = "gy86", dlpf: bool = True,
               bus_faults: Mapping[str, FaultSet] | None = None, impl: str | None = None,
               **baro_options: Any) -> Any:
    """A board of the Python chips or of the chip core (``impl``, default IMPL) with these sources;
    ``bus_faults`` by device ("mpu", "hmc", "baro"); ``baro_options`` are MS5611's."""
    if (impl or IMPL) == "core":
        seed = baro_options.pop("seed", 0)
        return build_chip_board(imu, mag, baro, topology, dlpf=dlpf, faults=bus_faults, baro_seed=seed,
                                **baro_options)
    mpu, hmc, ms = MPU6050(imu, dlpf=dlpf), HMC5883L(mag), MS5611(baro, **baro_options)
    devices: dict[str, I2CDevice] = {"mpu": mpu, "hmc": hmc, "baro": ms}
    wrap: dict[str, I2CDevice] = {k: FaultyDevice(devices[k], fs) for k, fs in (bus_faults or {}).items()}
    return build_board(mpu, hmc, ms, topology, wrap=wrap)


def board(script: Script, topology: str = "gy86", dlpf: bool = False) -> Any:
    return make_board(script.imu, script.mag, script.baro, topology, dlpf)


def s16(hi: int, lo: int) -> int:
    v = (hi << 8) | lo
    return v - 65536 if v & 0x8000 else v
