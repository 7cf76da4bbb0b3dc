"""Register maps described as data (after Zephyr's sensor emulators): reset value, access, write
mask, self-clearing bits. One generic test sweeps every register of every device from these tables."""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Sim times (seconds) closer than this are the same instant. The chips' clocks are running sums of
#: floats, the chip core's whole nanoseconds (emulators/chips/): an HMC5883L result due 6 ms after an
#: MPU-6050 sample and the MPU's sixth sample after it are the same instant, though the two float sums
#: can differ in the last bit.
SAME_INSTANT = 1e-12


@dataclass(frozen=True)
class RegisterSpec:
    addr: int
    name: str
    reset: int
    access: str                 # "rw", "r" (writes ignored) or "w" (reads as 0)
    write_mask: int = 0xFF      # bits that store what is written; others read 0
    self_clearing: int = 0x00   # bits that act when written and read back 0


class RegisterMap:
    """The registers of one device; addresses not listed read 0 and ignore writes."""

    def __init__(self, device: str, specs: list[RegisterSpec], size: int = 0x80) -> None:
        self.device = device
        self.specs = {s.addr: s for s in specs}
        self.by_name = {s.name: s for s in specs}
        self.size = max(size, max(self.specs) + 1)

    def reset_bytes(self) -> bytearray:
        regs = bytearray(self.size)
        for s in self.specs.values():
            regs[s.addr] = s.reset
        return regs

    def writable(self, addr: int) -> bool:
        spec = self.specs.get(addr)
        return spec is not None and spec.access in ("rw", "w")

    def masked(self, addr: int, value: int) -> int:
        """What a register stores when ``value`` is written."""
        spec = self.specs[addr]
        return value & spec.write_mask & ~spec.self_clearing & 0xFF


def round_half_away(x: float) -> int:
    """Quantisation rule of docs/sensors.md §2: round half away from zero."""
    return int(math.copysign(math.floor(abs(x) + 0.5), x))
