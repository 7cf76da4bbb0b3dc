"""The supply-driver interface, and the one place a ``--psu`` spec becomes a driver.

A spec is ``MAKE:PORT[@BAUD]`` (``riden:/dev/ttyUSB0``, ``korad:/dev/ttyACM0@9600``; its syntax is the
scenario format's, scenarios/bench.py, as a scenario's ``[bench] psu`` says it too). Every driver
answers in volts and amps, and turns anything wrong on its wire (silence, a bad checksum, an answer
that does not parse, a model it does not know) into a :class:`PsuError` that names the supply and says
what was expected, within the driver's timeout: a supply that does not answer must never hang a run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Protocol

from rig.scenarios.bench import PsuSpec, parse_psu

#: after "off", the output is left off this long by default, so the board's capacitors drain
DEFAULT_OFF_S = 1.0
#: after "on", the output must reach this share of its set voltage within the settle time
SETTLE_SHARE = 0.9
DEFAULT_SETTLE_S = 3.0
DEFAULT_TIMEOUT_S = 0.5


class PsuError(Exception):
    """The supply did not do or say what it should have (the message says which supply and what)."""


@dataclass(frozen=True)
class Reading:
    volts: float          # measured at the output
    amps: float
    volts_set: float
    amps_limit: float     # the supply's own current limit (constant-current above it)
    output: bool
    detail: str = ""      # the driver's words on its state: "CV", "CC", "OCP tripped"

    def line(self) -> str:
        state = "on" if self.output else "off"
        extra = f", {self.detail}" if self.detail else ""
        return (f"output {state}: {self.volts:.3f} V, {self.amps:.4f} A "
                f"(set {self.volts_set:.3f} V, limit {self.amps_limit:.4f} A{extra})")


class Supply(Protocol):
    name: str  # model and port, for messages

    def identity(self) -> str: ...

    def set_voltage(self, volts: float) -> None: ...

    def set_current_limit(self, amps: float) -> None: ...

    def output(self, on: bool) -> None: ...

    def read(self) -> Reading: ...

    def measure(self) -> tuple[float, float]:
        """Volts and amps at the output, and nothing else: what a run polls at ≥ 5 Hz."""

    def close(self) -> None: ...


def open_supply(spec: str | PsuSpec, timeout: float = DEFAULT_TIMEOUT_S) -> Supply:
    """The driver for ``spec``, connected and identified (PsuError when the supply does not answer as
    its make should)."""
    s = parse_psu(spec) if isinstance(spec, str) else spec
    if s.make == "riden":
        from rig.power.riden import RidenSupply

        return RidenSupply(s.port, s.baud or RidenSupply.DEFAULT_BAUD, timeout=timeout)
    from rig.power.korad import KoradSupply

    return KoradSupply(s.port, s.baud or KoradSupply.DEFAULT_BAUD, timeout=timeout)


def power_cycle(supply: Supply, off_s: float = DEFAULT_OFF_S, settle_s: float = DEFAULT_SETTLE_S) -> Reading:
    """Output off, ``off_s`` of nothing, output on, then waits until the output stands at its set
    voltage. Returns the first reading that does; PsuError if none does within ``settle_s`` (a short,
    a current limit too low for the board's inrush, a supply in protection)."""
    power_off(supply, off_s)
    return power_on(supply, settle_s)


def power_off(supply: Supply, off_s: float = DEFAULT_OFF_S) -> None:
    supply.output(False)
    if off_s > 0:
        time.sleep(off_s)  # (the board's capacitors drain: a real wait on a real bench)


def power_on(supply: Supply, settle_s: float = DEFAULT_SETTLE_S) -> Reading:
    supply.output(True)
    deadline = time.monotonic() + settle_s
    while True:
        r = supply.read()
        if r.output and r.volts >= SETTLE_SHARE * r.volts_set:
            return r
        if time.monotonic() >= deadline:
            raise PsuError(f"{supply.name}: the output did not come up within {settle_s:g} s: "
                           f"{r.line()} (a short, a current limit below the board's inrush, or protection)")
        time.sleep(0.05)
