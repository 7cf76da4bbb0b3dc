"""Bus topologies: GY-86 (the default) and direct.

GY-86: MPU-6050 at 0x68 and MS5611 at 0x77 on the main bus; the HMC5883L on the MPU's auxiliary bus,
answering at 0x1E on the main bus only while the MPU is in bypass (I2C_BYPASS_EN set, I2C_MST_EN
clear), and readable through the MPU's aux master into EXT_SENS_DATA. Direct: all three on the main bus.
"""

from __future__ import annotations

from dataclasses import dataclass

from rig.emulators import hmc5883l, mpu6050, ms5611
from rig.emulators.i2c_bus import I2CBus, I2CDevice

TOPOLOGIES = ("gy86", "direct")


@dataclass
class Board:
    bus: I2CBus
    mpu: mpu6050.MPU6050
    hmc: hmc5883l.HMC5883L
    baro: ms5611.MS5611


def build_board(mpu: mpu6050.MPU6050, hmc: hmc5883l.HMC5883L, baro: ms5611.MS5611,
                topology: str = "gy86", wrap: dict[str, I2CDevice] | None = None) -> Board:
    """Wires the three devices; ``wrap`` may replace a device on the bus by a wrapper (faults)."""
    if topology not in TOPOLOGIES:
        raise ValueError(f"unknown topology {topology!r}; choose one of {', '.join(TOPOLOGIES)}")
    wrap = wrap or {}
    on_bus = {"mpu": wrap.get("mpu", mpu), "hmc": wrap.get("hmc", hmc), "baro": wrap.get("baro", baro)}
    bus = I2CBus()
    bus.attach(mpu6050.ADDRESS, on_bus["mpu"])
    bus.attach(ms5611.ADDRESS, on_bus["baro"])
    if topology == "direct":
        bus.attach(hmc5883l.ADDRESS, on_bus["hmc"])
    else:
        mpu.aux[hmc5883l.ADDRESS] = on_bus["hmc"]
        bus.resolvers.append(lambda addr: on_bus["hmc"] if addr == hmc5883l.ADDRESS and mpu.bypass else None)
        bus.hidden.append(on_bus["hmc"])  # behind the MPU, the HMC still keeps time
    return Board(bus, mpu, hmc, baro)
