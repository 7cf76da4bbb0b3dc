"""HMC5883L magnetometer: pointer rules, continuous/single/idle timing, RDY and LOCK, gain latency,
−4096 on overflow, bias self-test (docs/sensors.md §4). Driven by bus messages and sim time only."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final

from rig.emulators.registers import SAME_INSTANT, RegisterMap, RegisterSpec, round_half_away

ADDRESS: Final = 0x1E
GAINS = (1370, 1090, 820, 660, 440, 390, 330, 230)  # LSB/Ga by CRB.GN, docs/sensors.md §4.5
RATES_HZ = (0.75, 1.5, 3.0, 7.5, 15.0, 30.0, 75.0, 75.0)  # CRA.DO (7 reserved: treated as 75 Hz)
SINGLE_S: Final = 6e-3  # single measurement duration (datasheet examples wait 6 ms)
POWER_ON_S: Final = 0.056  # power-on single measurement: data valid ~56 ms after power-up
BIAS_GA = (1.16, 1.08, 1.16)  # bias-strap field in (X, Z, Y) register order, docs/sensors.md §4.9
OVERFLOW: Final = -4096
CRA: Final = 0x00
CRB: Final = 0x01
MODE: Final = 0x02
DATA: Final = 0x03
STATUS: Final = 0x09
ID_A: Final = 0x0A

REGISTERS = RegisterMap("HMC5883L", [
    RegisterSpec(0x00, "CRA", 0x10, "rw", write_mask=0x7F),
    RegisterSpec(0x01, "CRB", 0x20, "rw", write_mask=0xE0),
    RegisterSpec(0x02, "MODE", 0x01, "rw", write_mask=0x03),
    *[RegisterSpec(0x03 + i, f"DATA_{n}", 0x00, "r")
      for i, n in enumerate(("X_MSB", "X_LSB", "Z_MSB", "Z_LSB", "Y_MSB", "Y_LSB"))],
    RegisterSpec(0x09, "STATUS", 0x00, "r"),
    RegisterSpec(0x0A, "ID_A", 0x48, "r"),
    RegisterSpec(0x0B, "ID_B", 0x34, "r"),
    RegisterSpec(0x0C, "ID_C", 0x33, "r"),
])


def next_pointer(r: int, status_wraps_to_data: bool = False) -> int:
    """Pointer after accessing register r (docs/sensors.md §4.2): 8 -> 3, >= 12 -> 0, else r + 1."""
    if r == 8 or (r == 9 and status_wraps_to_data):
        return 3
    if r >= 12:
        return 0
    return r + 1


@dataclass
class HMC5883L:
    """The device. ``source(t)`` gives the magnetic field (gauss) in the sensor frame (x, y, z)."""

    source: Callable[[float], tuple[float, float, float]]
    status_wraps_to_data: bool = False  # open point: pointer after 0x09 (default 9 -> 10)
    now: float = 0.0
    regs: bytearray = field(default_factory=REGISTERS.reset_bytes)
    pointer: int = 0
    _next_t: float | None = POWER_ON_S   # when the next measurement completes
    _gain_effective: int = GAINS[1]
    _bitmap: int = 0                     # data bytes read since the last result (bits 0..5)
    _held: bytes | None = None           # result held back while LOCK is set
    _writing: bool = False
    _measured: int = 0                   # measurements completed (for tests and faults)

    def reset(self) -> None:
        """Power-on state; a single measurement completes POWER_ON_S later."""
        self.regs = REGISTERS.reset_bytes()
        self.pointer, self._bitmap, self._held = 0, 0, None
        self._gain_effective = GAINS[1]
        self._next_t = self.now + POWER_ON_S

    # ---- time ------------------------------------------------------------------------------

    @property
    def mode(self) -> int:
        return self.regs[MODE] & 0x03

    def _period(self) -> float:
        return 1.0 / RATES_HZ[(self.regs[CRA] >> 2) & 0x7]

    def advance_to(self, t: float) -> None:
        if t < self.now:
            return
        while self._next_t is not None and self._next_t <= t + SAME_INSTANT:
            self.now = self._next_t
            self._measure()
            if self.mode == 0:
                self._next_t += self._period()
            else:  # single: back to idle
                self.regs[MODE] = (self.regs[MODE] & ~0x03) | 0x03
                self._next_t = None
        self.now = t

    def _measure(self) -> None:
        gain = self._gain_effective
        self._gain_effective = GAINS[self.regs[CRB] >> 5]  # a new gain counts from the next one
        bias = self.regs[CRA] & 0x03
        if bias in (1, 2):
            sign = 1.0 if bias == 1 else -1.0
            xzy = [sign * b for b in BIAS_GA]
        else:
            x, y, z = self.source(self.now)
            xzy = [x, z, y]
        data = bytearray()
        for value in xzy:
            raw = round_half_away(value * gain)
            raw = OVERFLOW if not -2048 <= raw <= 2047 else raw
            data += (raw & 0xFFFF).to_bytes(2, "big")
        self._measured += 1
        if self._bitmap and self._bitmap != 0x3F:  # LOCK: hold the result until the read completes
            self._held = bytes(data)
            return
        self._place(bytes(data))

    def _place(self, data: bytes) -> None:
        self.regs[DATA:DATA + 6] = data
        self._bitmap, self._held = 0, None
        self.regs[STATUS] = 0x01  # RDY

    # ---- bus -------------------------------------------------------------------------------

    def start(self, read: bool) -> None:
        self._writing = not read

    def stop(self) -> None:
        pass

    def write(self, data: bytes) -> None:
        if not data:
            return
        self.pointer = data[0] & 0xFF
        for byte in data[1:]:
            self._write_reg(self.pointer, byte)
            self.pointer = next_pointer(self.pointer, self.status_wraps_to_data)

    def _write_reg(self, r: int, value: int) -> None:
        if not REGISTERS.writable(r):
            return
        self.regs[r] = REGISTERS.masked(r, value)
        if r in (CRA, MODE):  # measurement configuration changed: LOCK clears, timing restarts
            self._bitmap, self._held = 0, None
            self.regs[STATUS] &= ~0x02
            if self.mode == 0:
                self._next_t = self.now + 2 * self._period()
            elif self.mode == 1:
                self._next_t = self.now + SINGLE_S
                self.regs[STATUS] &= ~0x01
            else:
                self._next_t = None

    def read(self, n: int) -> bytes:
        out = bytearray()
        for _ in range(n):
            r = self.pointer
            if r == STATUS:
                locked = self._bitmap not in (0, 0x3F)
                out.append((self.regs[STATUS] & 0x01) | (0x02 if locked else 0))
            else:
                out.append(self.regs[r] if r < len(self.regs) else 0)
            if DATA <= r < DATA + 6:
                self._bitmap |= 1 << (r - DATA)
                if self._bitmap == 0x3F:
                    self.regs[STATUS] &= ~0x01  # all six read: RDY clears
                    if self._held is not None:
                        self._place(self._held)
            self.pointer = next_pointer(r, self.status_wraps_to_data)
        return bytes(out)
