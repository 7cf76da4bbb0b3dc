"""Small helpers: devices fed by constant or scripted truth, and byte helpers."""

from __future__ import annotations

from emulators.hmc5883l import HMC5883L
from emulators.mpu6050 import MPU6050, ImuTruth
from emulators.ms5611 import MS5611, BaroTruth
from emulators.topology import Board, build_board


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


def board(script: Script, topology: str = "gy86", dlpf: bool = False) -> Board:
    return build_board(MPU6050(script.imu, dlpf=dlpf), HMC5883L(script.mag), MS5611(script.baro),
                       topology)


def s16(hi: int, lo: int) -> int:
    v = (hi << 8) | lo
    return v - 65536 if v & 0x8000 else v
