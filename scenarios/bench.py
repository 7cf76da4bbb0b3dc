"""A scenario's ``[bench]`` table: what a bench run (``rig run --bridge``) does with the bench's power
supply, and the syntax of a supply's spec, ``MAKE:PORT[@BAUD]``, which ``rig power --psu`` and
``rig run --psu`` share (the drivers are rig/power; this layer only checks what a file may say)."""

from __future__ import annotations

from dataclasses import dataclass

PSU_MAKES = ("riden", "korad")


@dataclass(frozen=True)
class PsuSpec:
    make: str
    port: str
    baud: int | None

    def __str__(self) -> str:
        return f"{self.make}:{self.port}" + (f"@{self.baud}" if self.baud else "")


def parse_psu(spec: str) -> PsuSpec:
    """``MAKE:PORT[@BAUD]`` checked; ValueError with the reason when it is not one."""
    make, sep, rest = spec.partition(":")
    if not sep or make not in PSU_MAKES or not rest:
        raise ValueError(f"{spec!r}: expected MAKE:PORT[@BAUD] with MAKE one of {', '.join(PSU_MAKES)} "
                         "(e.g. riden:/dev/ttyUSB0@115200)")
    port, at, baud_text = rest.rpartition("@") if "@" in rest else (rest, "", "")
    baud = None
    if at:
        if not baud_text.isdigit() or not 1200 <= int(baud_text) <= 4_000_000:
            raise ValueError(f"{spec!r}: the baud rate after @ is a number, 1200..4000000")
        baud = int(baud_text)
    if not port:
        raise ValueError(f"{spec!r}: no port")
    return PsuSpec(make, port, baud)


@dataclass(frozen=True)
class BenchPower:
    """``[bench]``: the supply that powers the board, power-cycled before each bench run."""

    psu: str | None = None            # MAKE:PORT[@BAUD]; None: no supply (rig run --psu may give one)
    volts: float | None = None        # set the output to this first (None: as the supply is set)
    current_limit: float | None = None  # the supply's own limit (constant current above it)
    max_current: float | None = None  # A drawn above this ends the run as an error
    off_s: float = 1.0                # the output stays off this long before it comes on again
    settle_s: float = 3.0             # and must reach 90 % of its set voltage within this
