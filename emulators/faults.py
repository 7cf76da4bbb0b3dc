"""One fault vocabulary for every device, switched on and off by sim time (after PX4's failure
injection): off (NACK), stuck, noise burst, bias step, drift, scale error, delay, intermittent,
garbage bytes. Signal faults act in the sensor models; bus faults (off, intermittent, garbage) act on
the device's presence and bytes; the battery's (a board's flight pack, rig/battery.py) act on its
terminal volts, in volts."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from rig.emulators.i2c_bus import I2CDevice

SIGNAL_KINDS = ("stuck", "noise_burst", "bias_step", "drift", "scale_error", "delay")
BUS_KINDS = ("off", "intermittent", "garbage")
KINDS = SIGNAL_KINDS + BUS_KINDS
#: What a fault acts on: the sensor models' signals (accel, gyro, mag, baro) or a device on the bus
#: (mpu, hmc, baro_bus: it stops answering, answers some of the time, or answers garbage)
SIGNAL_TARGETS = ("accel", "gyro", "mag", "baro")
BUS_TARGETS = ("mpu", "hmc", "baro_bus")
#: the flight pack's terminal volts (a board's [battery]), and the signal faults that mean something on a
#: voltage: a reading frozen, ripple, a step (a cell going bad: a negative one), a drift, a scale error (a
#: divider's resistor off); a delay does not (nothing in the pack holds an old voltage)
BATTERY_TARGETS = ("battery",)
BATTERY_KINDS = ("stuck", "noise_burst", "bias_step", "drift", "scale_error")
TARGETS = SIGNAL_TARGETS + BUS_TARGETS + BATTERY_TARGETS


_MASK64 = (1 << 64) - 1


def splitmix64(state: int) -> tuple[int, int]:
    """One step of splitmix64: (the new state, the output)."""
    state = (state + 0x9E3779B97F4A7C15) & _MASK64
    z = state
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
    return state, z ^ (z >> 31)


@dataclass(frozen=True)
class Fault:
    """``magnitude`` means: noise_burst sigma, bias_step offset, drift rate per second, scale_error
    factor, delay seconds (in the signal's units); intermittent NACKs for ``duty`` of each ``period``."""

    kind: str
    start: float
    end: float = math.inf
    magnitude: float = 0.0
    period: float = 0.1
    duty: float = 0.5

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown fault kind {self.kind!r}; known: {', '.join(KINDS)}")
        if not self.end > self.start:
            raise ValueError(f"fault {self.kind}: end ({self.end}) must be after start ({self.start})")
        if self.kind == "intermittent" and not (self.period > 0 and 0 <= self.duty <= 1):
            raise ValueError("intermittent fault needs period > 0 and 0 <= duty <= 1")
        if self.kind == "delay" and self.magnitude < 0:
            raise ValueError("delay fault needs magnitude >= 0 (seconds)")

    def active(self, t: float) -> bool:
        return self.start <= t < self.end


@dataclass(frozen=True)
class TargetedFault:
    """A fault and what it acts on: a scenario's ``[[faults]]`` entry."""

    target: str
    fault: Fault

    def __post_init__(self) -> None:
        if self.target not in TARGETS:
            raise ValueError(f"unknown fault target {self.target!r}; known: {', '.join(TARGETS)}")
        if self.target in BATTERY_TARGETS and self.fault.kind not in BATTERY_KINDS:
            raise ValueError(f"a {self.fault.kind} fault means nothing on the battery's volts; its faults: "
                             f"{', '.join(BATTERY_KINDS)}")


def fault_sets(faults: Iterable[TargetedFault], seed: int) -> dict[str, FaultSet]:
    """The faults grouped by target, each group a FaultSet with a seed of its own (derived from the
    run's seed and the fault's position, so adding a fault elsewhere changes no other's randomness)."""
    sets: dict[str, FaultSet] = {}
    for i, f in enumerate(faults):
        sets.setdefault(f.target, FaultSet(seed=seed * 1000 + 17 + i)).add(f.fault)
    return sets


@dataclass
class FaultSet:
    """The faults scheduled for one device; deterministic for a given seed."""

    faults: list[Fault] = field(default_factory=list)
    seed: int = 0
    _rng: np.random.Generator = field(init=False)
    _garbage: int = field(default=0, init=False)  # splitmix64 state of the garbage bytes
    _stuck: dict[int, tuple[float, ...]] = field(default_factory=dict)
    _history: deque[tuple[float, tuple[float, ...]]] = field(default_factory=deque)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._garbage = self.seed & _MASK64

    def add(self, fault: Fault) -> None:
        self.faults.append(fault)

    # ---- bus faults --------------------------------------------------------------------------

    def acks(self, t: float) -> bool:
        for f in self.faults:
            if not f.active(t):
                continue
            if f.kind == "off":
                return False
            if f.kind == "intermittent" and ((t - f.start) % f.period) < f.duty * f.period:
                return False
        return True

    def garble(self, t: float, data: bytes) -> bytes:
        """Random bytes in place of ``data`` while a garbage fault is on: splitmix64 seeded with the
        set's seed, one draw per byte (its top 8 bits), the stream the chip core draws too."""
        if any(f.kind == "garbage" and f.active(t) for f in self.faults):
            out = bytearray()
            for _ in range(len(data)):
                self._garbage, z = splitmix64(self._garbage)
                out.append(z >> 56)
            return bytes(out)
        return data

    # ---- signal faults -----------------------------------------------------------------------

    def apply(self, t: float, value: tuple[float, ...]) -> tuple[float, ...]:
        """The measured value with every active signal fault applied (in schedule order). Plain
        tuples: this runs for every sensor sample, and most of the time there is no fault at all."""
        if not self.faults:
            return value
        if self._has_delay:
            self._history.append((t, value))
            while len(self._history) > 2 and self._history[1][0] <= t - self._delay_horizon:
                self._history.popleft()
        out = value
        for i, f in enumerate(self.faults):
            if not f.active(t):
                self._stuck.pop(i, None)
                continue
            if f.kind == "stuck":
                out = self._stuck.setdefault(i, out)
            elif f.kind == "noise_burst":
                burst = self._rng.normal(0.0, f.magnitude, len(out)).tolist()
                out = tuple(v + n for v, n in zip(out, burst, strict=True))
            elif f.kind == "bias_step":
                out = tuple(v + f.magnitude for v in out)
            elif f.kind == "drift":
                out = tuple(v + f.magnitude * (t - f.start) for v in out)
            elif f.kind == "scale_error":
                out = tuple(v * f.magnitude for v in out)
            elif f.kind == "delay":
                past = [v for (tt, v) in self._history if tt <= t - f.magnitude]
                out = past[-1] if past else self._history[0][1]
        return out

    @property
    def _has_delay(self) -> bool:
        return any(f.kind == "delay" for f in self.faults)

    @property
    def _delay_horizon(self) -> float:
        return max(f.magnitude for f in self.faults if f.kind == "delay")


@dataclass
class FaultyDevice:
    """Wraps a bus device with its bus faults: the bus asks ``acks(t)`` before addressing it."""

    device: I2CDevice
    faults: FaultSet
    now: float = 0.0

    def acks(self, t: float) -> bool:
        return self.faults.acks(t)

    def advance_to(self, t: float) -> None:
        self.now = max(self.now, t)
        self.device.advance_to(t)

    def start(self, read: bool) -> None:
        self.device.start(read)

    def write(self, data: bytes) -> None:
        self.device.write(data)

    def read(self, n: int) -> bytes:
        return self.faults.garble(self.now, self.device.read(n))

    def stop(self) -> None:
        self.device.stop()
