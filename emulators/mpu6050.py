"""MPU-6050 accelerometer/gyro (docs/sensors.md §3): register map with reset values and exact
read-back, sleep and DEVICE_RESET, FS scaling, DLPF and sample-rate divider, coherent bursts,
INT_STATUS, FIFO with latched count, bypass and aux master, self-test. Sim time only."""

from __future__ import annotations

import ctypes
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, NamedTuple

from rig.emulators import native
from rig.emulators.dlpf import ImuSampler, sample_rate
from rig.emulators.i2c_bus import I2CDevice
from rig.emulators.registers import RegisterMap, RegisterSpec

ADDRESS: Final = 0x68
G0: Final = 9.80665
ACCEL_LSB_PER_G = (16384.0, 8192.0, 4096.0, 2048.0)
GYRO_LSB_PER_DPS = (131.0, 65.5, 32.8, 16.4)
FIFO_SIZE: Final = 1024

# Self-test: factory-trim codes and the matching actuation (docs/sensors.md §3.10). Gyro code 16 gives
# FT = 25 * 1.046**15 deg/s (+X, -Y, +Z); accel code 12 gives FT = 0.34 * (0.92/0.34)**(11/30) g.
ST_GYRO_CODE: Final = 16
ST_ACCEL_CODE: Final = 12
ST_GYRO_DPS: Final = 25.0 * 1.046 ** (ST_GYRO_CODE - 1)
ST_ACCEL_G: Final = 0.34 * (0.92 / 0.34) ** ((ST_ACCEL_CODE - 1) / 30)

SELF_TEST_X: Final = 0x0D
SELF_TEST_A: Final = 0x10
SMPLRT_DIV: Final = 0x19
CONFIG: Final = 0x1A
GYRO_CONFIG: Final = 0x1B
ACCEL_CONFIG: Final = 0x1C
FIFO_EN: Final = 0x23
I2C_MST_CTRL: Final = 0x24
I2C_MST_STATUS: Final = 0x36
INT_PIN_CFG: Final = 0x37
INT_ENABLE: Final = 0x38
INT_STATUS: Final = 0x3A
ACCEL_XOUT_H: Final = 0x3B
TEMP_OUT_H: Final = 0x41
GYRO_XOUT_H: Final = 0x43
EXT_SENS_DATA_00: Final = 0x49
SIGNAL_PATH_RESET: Final = 0x68
USER_CTRL: Final = 0x6A
PWR_MGMT_1: Final = 0x6B
PWR_MGMT_2: Final = 0x6C
FIFO_COUNT_H: Final = 0x72
FIFO_COUNT_L: Final = 0x73
FIFO_R_W: Final = 0x74
WHO_AM_I: Final = 0x75
I2C_SLV0_ADDR: Final = 0x25
I2C_SLV0_DO: Final = 0x63
I2C_MST_DELAY_CTRL: Final = 0x67
DATA_FIRST: Final = ACCEL_XOUT_H
DATA_LAST: Final = 0x60


def _self_test_regs() -> tuple[int, int, int, int]:
    xa_hi = (ST_ACCEL_CODE >> 2) & 0x7
    axis = (xa_hi << 5) | ST_GYRO_CODE
    a_lo = ST_ACCEL_CODE & 0x3
    return axis, axis, axis, (a_lo << 4) | (a_lo << 2) | a_lo


_ST = _self_test_regs()

REGISTERS = RegisterMap("MPU-6050", [
    RegisterSpec(0x0C, "PRODUCT_ID", 0x00, "r"),
    *[RegisterSpec(0x0D + i, f"SELF_TEST_{n}", _ST[i], "r") for i, n in enumerate("XYZA")],
    RegisterSpec(0x19, "SMPLRT_DIV", 0x00, "rw"),
    RegisterSpec(0x1A, "CONFIG", 0x00, "rw"),
    RegisterSpec(0x1B, "GYRO_CONFIG", 0x00, "rw"),
    RegisterSpec(0x1C, "ACCEL_CONFIG", 0x00, "rw"),
    RegisterSpec(0x23, "FIFO_EN", 0x00, "rw"),
    RegisterSpec(0x24, "I2C_MST_CTRL", 0x00, "rw"),
    *[RegisterSpec(0x25 + 3 * n + k, f"I2C_SLV{n}_{f}", 0x00, "rw")
      for n in range(4) for k, f in enumerate(("ADDR", "REG", "CTRL"))],
    *[RegisterSpec(0x31 + k, f"I2C_SLV4_{f}", 0x00, "rw" if f != "DI" else "r")
      for k, f in enumerate(("ADDR", "REG", "DO", "CTRL", "DI"))],
    RegisterSpec(0x36, "I2C_MST_STATUS", 0x00, "r"),
    RegisterSpec(0x37, "INT_PIN_CFG", 0x00, "rw"),
    RegisterSpec(0x38, "INT_ENABLE", 0x00, "rw"),
    RegisterSpec(0x3A, "INT_STATUS", 0x00, "r"),
    *[RegisterSpec(0x3B + i, n, 0x00, "r") for i, n in enumerate(
        ("ACCEL_XOUT_H", "ACCEL_XOUT_L", "ACCEL_YOUT_H", "ACCEL_YOUT_L", "ACCEL_ZOUT_H", "ACCEL_ZOUT_L",
         "TEMP_OUT_H", "TEMP_OUT_L", "GYRO_XOUT_H", "GYRO_XOUT_L", "GYRO_YOUT_H", "GYRO_YOUT_L",
         "GYRO_ZOUT_H", "GYRO_ZOUT_L"))],
    *[RegisterSpec(0x49 + i, f"EXT_SENS_DATA_{i:02d}", 0x00, "r") for i in range(24)],
    *[RegisterSpec(0x63 + n, f"I2C_SLV{n}_DO", 0x00, "rw") for n in range(4)],
    RegisterSpec(0x67, "I2C_MST_DELAY_CTRL", 0x00, "rw"),
    RegisterSpec(0x68, "SIGNAL_PATH_RESET", 0x00, "w", self_clearing=0x07),
    RegisterSpec(0x6A, "USER_CTRL", 0x00, "rw", self_clearing=0x07),
    RegisterSpec(0x6B, "PWR_MGMT_1", 0x40, "rw", self_clearing=0x80),
    RegisterSpec(0x6C, "PWR_MGMT_2", 0x00, "rw"),
    RegisterSpec(0x72, "FIFO_COUNT_H", 0x00, "r"),
    RegisterSpec(0x73, "FIFO_COUNT_L", 0x00, "r"),
    RegisterSpec(0x74, "FIFO_R_W", 0x00, "rw"),
    RegisterSpec(0x75, "WHO_AM_I", 0x68, "r"),
])


class ImuTruth(NamedTuple):
    """Physical inputs in the sensor frame: specific force (m/s²), angular rate (rad/s), die °C."""

    accel: tuple[float, float, float]
    gyro: tuple[float, float, float]
    temperature_c: float = 25.0


@dataclass
class MPU6050:
    """The device. ``source(t)`` gives ImuTruth in the sensor frame at sim time t; a source with a
    ``sample_block(times, out)`` (ImuModel) is asked for a block of samples at once. ``aux`` holds the
    devices on the auxiliary bus (the GY-86's HMC5883L), reached through bypass or the aux master."""

    source: Callable[[float], ImuTruth]
    aux: dict[int, I2CDevice] = field(default_factory=dict)
    dlpf: bool = True
    now: float = 0.0
    regs: bytearray = field(default_factory=REGISTERS.reset_bytes)
    pointer: int = 0
    fifo: deque[int] = field(default_factory=deque)
    samples: int = 0
    _snapshot: bytes = b""
    _fifo_count_latch: int = 0
    _fifo_last: int = 0

    def __post_init__(self) -> None:
        self._sampler = ImuSampler(self.source, self.dlpf)  # the samples being taken, through the DLPF
        self._encode_c = native.fast().mpu_encode
        self._regs_seen: bytearray | None = None
        self._regs_view: ctypes.c_char | None = None
        self._regs_addr = 0

    # ---- configuration decoded ----------------------------------------------------------------

    @property
    def asleep(self) -> bool:
        return bool(self.regs[PWR_MGMT_1] & 0x40)

    @property
    def bypass(self) -> bool:
        """Pass-through to the aux bus: I2C_BYPASS_EN set and I2C_MST_EN clear."""
        return bool(self.regs[INT_PIN_CFG] & 0x02) and not self.regs[USER_CTRL] & 0x20

    def sample_rate(self) -> float:
        return sample_rate(self.regs[CONFIG], self.regs[SMPLRT_DIV])

    def accel_scale(self) -> float:
        return ACCEL_LSB_PER_G[(self.regs[ACCEL_CONFIG] >> 3) & 3]

    def gyro_scale(self) -> float:
        return GYRO_LSB_PER_DPS[(self.regs[GYRO_CONFIG] >> 3) & 3]

    # ---- reset ---------------------------------------------------------------------------------

    def reset(self) -> None:
        """DEVICE_RESET / power-on: registers to defaults (asleep), FIFO empty, bypass off."""
        self.regs = REGISTERS.reset_bytes()
        self.fifo.clear()
        self._snapshot, self._fifo_count_latch, self._fifo_last = b"", 0, 0
        self._sampler.reset_filters()

    # ---- time ------------------------------------------------------------------------------

    def advance_to(self, t: float) -> None:
        if t < self.now:
            return
        sampler = self._sampler
        if self.asleep:
            self.now = t
            sampler.next_t = t
            return
        period = 1.0 / self.sample_rate()
        if sampler.next_t < self.now:
            sampler.next_t = self.now
        n = math.floor((t - sampler.next_t) / period + 1e-9) + 1 if sampler.next_t <= t else 0
        keeps_all = bool(self.regs[USER_CTRL] & 0x60)  # the FIFO or the aux master sees every sample
        while n > 0:
            used, times = sampler.take(n, period, self.regs[CONFIG], keeps_all)
            n -= used
            m = len(times)
            # a sample that a later one overwrites before anyone can see it only feeds the filters
            for i in range(m) if keeps_all else (m - 1,) if n == 0 else ():
                self.now = times[i]
                self._encode(i)
            self.regs[INT_STATUS] |= 0x01  # DATA_RDY, set whatever INT_ENABLE says (docs/sensors.md §3.7)
            self.samples += m
        self.now = t

    def _encode(self, i: int) -> None:
        """Sample ``i`` of the block into the data registers by the chip core's encoder (chip_mpu_encode:
        docs/sensors.md §2's rounding, the FS scale, self-test actuation, standby and TEMP_DIS, read from
        the registers), then the aux master and the FIFO."""
        regs = self.regs
        if regs is not self._regs_seen:  # (a reset makes a new bytearray)
            # the view keeps regs exported: resizing it would raise instead of moving the bytes
            self._regs_seen, self._regs_view = regs, ctypes.c_char.from_buffer(regs)
            self._regs_addr = ctypes.addressof(self._regs_view)
        self._encode_c(self._sampler.block_addr + 56 * i, self._regs_addr)
        if regs[USER_CTRL] & 0x20:
            self._run_aux_master()
        if regs[USER_CTRL] & 0x40:
            self._push_fifo()

    def _slaves(self) -> list[tuple[int, int, int, int, int, int]]:
        """Enabled slaves 0..3 as (n, ADDR, REG, CTRL, first EXT_SENS_DATA register, length): read
        slaves take their LEN bytes consecutively in slave order; write slaves take none. The aux
        master fills this layout and the FIFO copies it, so both read it from here."""
        out = []
        ext = EXT_SENS_DATA_00
        for n in range(4):
            addr_reg, reg, ctrl = self.regs[I2C_SLV0_ADDR + 3 * n:I2C_SLV0_ADDR + 3 * n + 3]
            if not ctrl & 0x80:
                continue
            length = min(ctrl & 0x0F, DATA_LAST + 1 - ext) if addr_reg & 0x80 else 0
            out.append((n, addr_reg, reg, ctrl, ext, length))
            ext += length
        return out

    def _run_aux_master(self) -> None:
        status = 0
        for n, addr_reg, reg, ctrl, ext, length in self._slaves():
            dev = self.aux.get(addr_reg & 0x7F)
            if dev is None:
                status |= 1 << n  # I2C_SLVn_NACK
                continue
            dev.advance_to(self.now)
            dev.start(False)
            if addr_reg & 0x80:  # read LEN bytes into EXT_SENS_DATA
                if not ctrl & 0x20:
                    dev.write(bytes([reg]))
                dev.start(True)
                self.regs[ext:ext + length] = dev.read(length)
            else:
                do = self.regs[I2C_SLV0_DO + n]
                dev.write(bytes([do]) if ctrl & 0x20 else bytes([reg, do]))
            dev.stop()
        self.regs[I2C_MST_STATUS] = status

    def _push_fifo(self) -> None:
        en = self.regs[FIFO_EN]
        record = bytearray()
        if en & 0x08:
            record += self.regs[ACCEL_XOUT_H:ACCEL_XOUT_H + 6]
        if en & 0x80:
            record += self.regs[TEMP_OUT_H:TEMP_OUT_H + 2]
        for i, bit in enumerate((0x40, 0x20, 0x10)):
            if en & bit:
                record += self.regs[GYRO_XOUT_H + 2 * i:GYRO_XOUT_H + 2 * i + 2]
        for n, _, _, _, ext, length in self._slaves():
            if n < 3 and en & (1 << n):  # FIFO_EN has SLV0..SLV2 only
                record += self.regs[ext:ext + length]
        for byte in bytes(record):  # (a copy: mypyc cannot compile a loop over a bytearray)
            if len(self.fifo) >= FIFO_SIZE:
                self.fifo.popleft()  # overflow: oldest out, newest kept
                self.regs[INT_STATUS] |= 0x10
            self.fifo.append(byte)

    # ---- bus -------------------------------------------------------------------------------

    def start(self, read: bool) -> None:
        if read:  # coherent bursts: the whole read is served from one sampling instant
            self._snapshot = bytes(self.regs[DATA_FIRST:DATA_LAST + 1])

    def stop(self) -> None:
        self._snapshot = b""

    def write(self, data: bytes) -> None:
        if not data:
            return
        self.pointer = data[0] & 0x7F
        for byte in data[1:]:
            self._write_reg(self.pointer, byte)
            if self.pointer != FIFO_R_W:
                self.pointer = self._next(self.pointer)

    @staticmethod
    def _next(r: int) -> int:
        return 0 if r >= WHO_AM_I else r + 1  # past WHO_AM_I: wrap to 0 (open point, docs/sensors.md §9)

    def _write_reg(self, r: int, value: int) -> None:
        if r == FIFO_R_W:
            if len(self.fifo) < FIFO_SIZE:
                self.fifo.append(value)
            return
        if not REGISTERS.writable(r):
            return
        if r == PWR_MGMT_1 and value & 0x80:
            self.reset()
            return
        if r == USER_CTRL:
            if value & 0x04:
                self.fifo.clear()
            if value & 0x01:  # SIG_COND_RESET clears the sensor registers
                self.regs[DATA_FIRST:GYRO_XOUT_H + 6] = bytes(GYRO_XOUT_H + 6 - DATA_FIRST)
        if r == PWR_MGMT_1 and self.asleep and not value & 0x40:
            self._sampler.next_t = self.now  # waking: sampling resumes now
        self.regs[r] = REGISTERS.masked(r, value)

    def read(self, n: int) -> bytes:
        clear_all = self.regs[INT_PIN_CFG] & 0x10
        r = self.pointer
        if self._snapshot and DATA_FIRST <= r and r + n <= DATA_LAST + 1:
            # a burst inside the data registers (the flight controller's read, every cycle): one slice
            if clear_all and n:  # (a zero-length read clocks no byte: nothing is read)
                self.regs[INT_STATUS] = 0
            self.pointer = r + n
            return self._snapshot[r - DATA_FIRST:r - DATA_FIRST + n]
        out = bytearray()
        for _ in range(n):
            r = self.pointer
            if r == FIFO_R_W:
                if self.fifo:
                    self._fifo_last = self.fifo.popleft()
                out.append(self._fifo_last)  # empty: the last byte again
                continue
            if r == FIFO_COUNT_H:
                self._fifo_count_latch = len(self.fifo)
                out.append(self._fifo_count_latch >> 8)
            elif r == FIFO_COUNT_L:
                out.append(self._fifo_count_latch & 0xFF)
            elif DATA_FIRST <= r <= DATA_LAST and self._snapshot:
                out.append(self._snapshot[r - DATA_FIRST])
            elif REGISTERS.specs.get(r) is not None and REGISTERS.specs[r].access != "w":
                out.append(self.regs[r])
            else:
                out.append(0)
            if r == INT_STATUS or clear_all:
                self.regs[INT_STATUS] = 0
            self.pointer = self._next(r)
        return bytes(out)
