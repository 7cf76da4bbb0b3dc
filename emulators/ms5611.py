"""MS5611-01BA03 barometer: command state machine in sim time, PROM with CRC-4, and the exact inverse of
the datasheet compensation (docs/sensors.md §5).

The inverse is what makes the emulator honest: a client doing the datasheet's integer maths (floor
semantics, second-order terms) decodes exactly the pascal and the 0.01 °C the plant asked for. The
"float" encoding aims at the middle of the real-valued target instead, for float clients (ArduPilot).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Final

import numpy as np

from rig.emulators.registers import SAME_INSTANT

ADDRESS: Final = 0x77  # CSB low; 0x76 with CSB high
#: docs/sensors.md §5.4/§5.5 recommended default: datasheet coefficients, word 7 = 0x0103 (CRC 0x3, non-zero).
DEFAULT_PROM = (0x0000, 40127, 36924, 23317, 23282, 33464, 28312, 0x0103)
OSR = (256, 512, 1024, 2048, 4096)
#: Conversion times per OSR index (s): typical and maximum columns of docs/sensors.md §5.3.
CONVERSION_TYPICAL = (0.54e-3, 1.06e-3, 2.08e-3, 4.13e-3, 8.22e-3)
CONVERSION_MAX = (0.60e-3, 1.17e-3, 2.28e-3, 4.54e-3, 9.04e-3)
#: Pressure noise (RMS, Pa) per OSR index, docs/sensors.md §5.3.
NOISE_PA = (6.5, 4.2, 2.7, 1.8, 1.2)

CMD_RESET: Final = 0x1E
CMD_ADC_READ: Final = 0x00


def crc4(words: tuple[int, ...] | list[int]) -> int:
    """AN520 CRC-4 over the eight PROM words (word 7's low byte excluded), docs/sensors.md §5.5."""
    w = list(words)
    w[7] &= 0xFF00
    rem = 0
    for word in w:
        for byte in (word >> 8, word & 0xFF):
            rem ^= byte
            for _ in range(8):
                rem = ((rem << 1) ^ 0x3000) & 0xFFFF if rem & 0x8000 else (rem << 1) & 0xFFFF
    return (rem >> 12) & 0xF


def with_crc(words: tuple[int, ...]) -> tuple[int, ...]:
    """The PROM with word 7's low nibble set to its CRC."""
    w = list(words)
    w[7] = (w[7] & 0xFFF0) | crc4(w)
    return tuple(w)


def _terms(prom: tuple[int, ...], d2: int) -> tuple[int, int, int]:
    """TEMP, OFF and SENS for a D2, second-order terms applied (datasheet integer flow, floor
    semantics as Linux and Crazyflie: Python's >> on negative numbers)."""
    c1, c2, c3, c4, c5, c6 = prom[1:7]
    dt = d2 - (c5 << 8)
    temp = 2000 + ((dt * c6) >> 23)
    off = (c2 << 16) + ((c4 * dt) >> 7)
    sens = (c1 << 15) + ((c3 * dt) >> 8)
    if temp < 2000:
        t2 = (dt * dt) >> 31
        off2 = 5 * (temp - 2000) ** 2 >> 1
        sens2 = 5 * (temp - 2000) ** 2 >> 2
        if temp < -1500:
            off2 += 7 * (temp + 1500) ** 2
            sens2 += 11 * (temp + 1500) ** 2 >> 1
        temp -= t2
        off -= off2
        sens -= sens2
    return temp, off, sens


def compensate(prom: tuple[int, ...], d1: int, d2: int) -> tuple[int, int]:
    """Datasheet compensation with both second-order tiers: (TEMP in 0.01 °C, P in Pa)."""
    temp, off, sens = _terms(prom, d2)
    return temp, (((d1 * sens) >> 21) - off) >> 15


def _temp_of(prom: tuple[int, ...], d2: int) -> int:
    return _terms(prom, d2)[0]


@lru_cache(maxsize=4096)
def encode_temperature(prom: tuple[int, ...], temp_centi: int) -> int:
    """D2 in the middle of the bucket that decodes to ``temp_centi`` (0.01 °C); for the two values
    inside −40…85 °C that no D2 reaches (docs/sensors.md §5.10), the nearest reachable one's bucket."""
    top = (1 << 24) - 2

    def first_at_least(target: int) -> int:
        lo, hi = 1, top
        while lo < hi:
            mid = (lo + hi) // 2
            if _temp_of(prom, mid) >= target:
                hi = mid
            else:
                lo = mid + 1
        return lo

    lo = first_at_least(temp_centi)
    if _temp_of(prom, lo) != temp_centi:  # unreachable: take the neighbour below if it is closer
        below = _temp_of(prom, lo - 1)
        if lo > 1 and temp_centi - below <= _temp_of(prom, lo) - temp_centi:
            temp_centi = below
            lo = first_at_least(below)
        else:
            temp_centi = _temp_of(prom, lo)
    hi = first_at_least(temp_centi + 1) - 1
    return (lo + hi) // 2


def encode_pressure(prom: tuple[int, ...], d2: int, pressure_pa: int) -> int:
    """D1 in the middle of the window that decodes (with this D2) to exactly ``pressure_pa``."""
    _, off, sens = _terms(prom, d2)
    a = off + (pressure_pa << 15)
    d1_min = -((-a << 21) // sens)
    d1_max = (((a + 32768) << 21) - 1) // sens
    return (d1_min + d1_max) // 2


def encode_float(prom: tuple[int, ...], pressure_pa: float, temp_c: float) -> tuple[int, int]:
    """(D1, D2) aimed at the real-valued targets, for clients that compensate in floating point."""
    c5, c6 = prom[5], prom[6]
    if temp_c >= 20.0:
        d2 = round((c5 << 8) + (100.0 * temp_c - 2000.0) * (1 << 23) / c6)
    else:
        d2 = encode_temperature(prom, round(100.0 * temp_c))
    _, off, sens = _terms(prom, d2)
    d1 = round((off + pressure_pa * 32768.0) * (1 << 21) / sens)
    return d1, d2


def encode(prom: tuple[int, ...], pressure_pa: float, temp_c: float,
           mode: str = "integer") -> tuple[int, int]:
    """(D1, D2) for a physical pressure and temperature; ValueError outside the sensor's range."""
    if not (1000.0 <= pressure_pa <= 120000.0 and -40.0 <= temp_c <= 85.0):
        raise ValueError(f"MS5611 range is 1000..120000 Pa and -40..85 degC, not {pressure_pa} Pa "
                         f"{temp_c} degC")
    if mode == "float":
        d1, d2 = encode_float(prom, pressure_pa, temp_c)
    else:
        d2 = encode_temperature(prom, round(100.0 * temp_c))
        d1 = encode_pressure(prom, d2, round(pressure_pa))
    return d1, d2


@dataclass
class BaroTruth:
    pressure_pa: float
    temperature_c: float


@dataclass
class MS5611:
    """The device. ``source(t)`` gives the physical pressure and temperature at sim time t; it is
    sampled when a conversion completes. Out-of-range truth is clamped to the sensor's range."""

    source: Callable[[float], BaroTruth]
    prom: tuple[int, ...] = DEFAULT_PROM
    timing: str = "typical"          # or "max" to stress drivers
    encoding: str = "integer"        # or "float"
    osr_noise: bool = False          # add the datasheet RMS noise of the chosen OSR
    seed: int = 0
    now: float = 0.0
    _state: str = "idle"             # idle | converting | done
    _kind: str = "D1"
    _osr: int = 0
    _t_done: float = 0.0
    _corrupt: bool = False
    _result: int = 0
    _response: bytes = b""
    _rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)

    # ---- time ------------------------------------------------------------------------------

    def advance_to(self, t: float) -> None:
        if t < self.now:
            return
        self.now = t
        if self._state == "converting" and t >= self._t_done - SAME_INSTANT:
            self._finish()

    def _finish(self) -> None:
        truth = self.source(self._t_done)
        p = min(max(truth.pressure_pa, 1000.0), 120000.0)
        temp = min(max(truth.temperature_c, -40.0), 85.0)
        if self.osr_noise:
            p = min(max(p + self._rng.normal(0.0, NOISE_PA[self._osr]), 1000.0), 120000.0)
        d1, d2 = encode(self.prom, p, temp, self.encoding)
        value = d1 if self._kind == "D1" else d2
        if self._corrupt:  # disturbed by an early ADC read or a second convert: "incorrect result"
            value ^= 0x5A5A
        self._result = min(max(value, 1), 0xFFFFFE)
        self._state = "done"

    # ---- bus ---------------------------------------------------------------------------------

    def start(self, read: bool) -> None:
        pass

    def stop(self) -> None:
        pass

    def write(self, data: bytes) -> None:
        if not data:  # SMBus quick write (i2cdetect): acknowledged, no command
            return
        self._command(data[0])  # trailing bytes (MultiWii's 0x1E 0x00) are ignored

    def _command(self, cmd: int) -> None:
        if cmd == CMD_RESET:
            self._state, self._response, self._corrupt = "idle", b"", False
        elif cmd == CMD_ADC_READ:
            if self._state == "done":
                self._response = self._result.to_bytes(3, "big")
                self._state = "idle"
            else:
                if self._state == "converting":
                    self._corrupt = True
                self._response = b"\x00\x00\x00"
        elif 0xA0 <= cmd <= 0xAE and cmd % 2 == 0:
            self._response = self.prom[(cmd - 0xA0) // 2].to_bytes(2, "big")
        elif cmd & 0xE1 == 0x40 and (cmd >> 1) & 0x7 <= 4:  # 0x40..0x48, 0x50..0x58
            if self._state == "converting":
                self._corrupt = True
            else:
                self._corrupt = False
            self._kind = "D2" if cmd & 0x10 else "D1"
            self._osr = (cmd >> 1) & 0x7
            table = CONVERSION_MAX if self.timing == "max" else CONVERSION_TYPICAL
            self._t_done = self.now + table[self._osr]
            self._state = "converting"
            self._response = b""
        # anything else is not a command: ignored

    def read(self, n: int) -> bytes:
        out = self._response[:n] + bytes(max(0, n - len(self._response)))
        self._response = self._response[n:]
        return out
