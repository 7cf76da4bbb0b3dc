"""One generic sweep over every register of every device, driven by the register maps as data."""

from __future__ import annotations

import pytest

from rig.emulators import hmc5883l, mpu6050
from rig.emulators.i2c_bus import I2CBus, read, write
from tests.emulators.boards import Script, board

DEVICES = [(mpu6050.REGISTERS, 0x68), (hmc5883l.REGISTERS, 0x1E)]
# Registers whose writes act (resets, FIFO port, mode changes that trigger measurements): swept
# separately in the device tests.
ACTIVE = {"PWR_MGMT_1", "USER_CTRL", "FIFO_R_W", "SIGNAL_PATH_RESET", "MODE", "CRA"}


def fresh(addr: int) -> I2CBus:
    b = board(Script(), topology="direct").bus
    return b


@pytest.mark.parametrize(("regmap", "addr"), DEVICES, ids=["mpu6050", "hmc5883l"])
def test_every_register_resets_reads_back_and_respects_access(regmap, addr):
    bus = fresh(addr)
    for spec in regmap.specs.values():
        if spec.name.startswith(("FIFO_COUNT", "INT_STATUS", "DATA_", "STATUS")):
            continue
        got = bus.transfer([write(addr, spec.addr), read(addr, 1)], 0.0)[0][0]
        expect = 0 if spec.access == "w" else spec.reset
        assert got == expect, f"{regmap.device} {spec.name} reset"
        if spec.name in ACTIVE:
            continue
        for value in (0xFF, 0xA5, 0x00):
            bus.transfer([write(addr, spec.addr, value)], 0.0)
            got = bus.transfer([write(addr, spec.addr), read(addr, 1)], 0.0)[0][0]
            if spec.access == "rw":
                want = value & spec.write_mask & ~spec.self_clearing
            elif spec.access == "w":
                want = 0
            else:
                want = spec.reset
            assert got == want, f"{regmap.device} {spec.name} after writing 0x{value:02x}"


def test_mpu_checked_registers_keep_every_bit():
    # ArduPilot re-reads these and flags a fault if a bit differs (CONFIG 0x41 keeps bit 6).
    bus = fresh(0x68)
    for reg, value in ((0x19, 0x00), (0x1A, 0x41), (0x1B, 0x18), (0x1C, 0x18), (0x23, 0xF8)):
        bus.transfer([write(0x68, reg, value)], 0.0)
        assert bus.transfer([write(0x68, reg), read(0x68, 1)], 0.0)[0][0] == value
