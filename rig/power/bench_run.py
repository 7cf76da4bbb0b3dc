"""The bench supply around one bench run: switched off before the bridge link starts, on again once
the bridge is configured (so the board boots into chips that answer), then polled while the run
lasts; its volts and amps join the run's telemetry, and a draw over the scenario's ``max_current``
ends the run as an error (docs/power.md)."""

from __future__ import annotations

import threading
import time
from typing import Final

import numpy as np

from rig.power.supply import PsuError, Reading, Supply, open_supply, power_off, power_on
from rig.scenarios.bench import BenchPower

POLL_S: Final = 0.1  # 10 Hz asked; a Korad's pauses between commands make it about 8


class PsuMonitor:
    """Polls the supply in a thread of its own (its serial round trips never hold up the run's loop)."""

    def __init__(self, supply: Supply, max_amps: float | None, period_s: float = POLL_S) -> None:
        self.supply, self.max_amps, self.period_s = supply, max_amps, period_s
        self.samples: list[tuple[float, float, float]] = []  # (monotonic s, volts, amps)
        self.problem: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True, name="psu")

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def latest(self) -> tuple[float, float, float] | None:
        return self.samples[-1] if self.samples else None

    def _loop(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            try:
                volts, amps = self.supply.measure()
            except PsuError as e:
                self.problem = f"the bench supply stopped answering: {e}"
                return
            now = time.monotonic()
            self.samples.append((now, volts, amps))
            if self.max_amps is not None and amps > self.max_amps:
                self.problem = (f"over-current: the board drew {amps:.3f} A, over the limit of "
                                f"{self.max_amps:g} A ([bench] max_current)")
                return
            next_t += self.period_s
            self._stop.wait(max(0.0, next_t - time.monotonic()))


class PsuRun:
    """One run's use of the supply: ``prepare`` (open, set, off), ``switch_on`` (from the bench session,
    once the bridge is configured), ``sample`` (a session event), ``close``."""

    def __init__(self, power: BenchPower, timeout: float = 0.5) -> None:
        self.power, self.timeout = power, timeout
        self.supply: Supply | None = None
        self.monitor: PsuMonitor | None = None
        self.on_reading: Reading | None = None
        self.events: list[tuple[str, float]] = []  # what was done to the supply, with monotonic times
        self.rows: list[tuple[float, float, float]] = []  # (sim s, volts, amps) as the run saw them

    def prepare(self) -> None:
        assert self.power.psu is not None
        self.supply = open_supply(self.power.psu, self.timeout)
        if self.power.volts is not None:
            self.supply.set_voltage(self.power.volts)
        if self.power.current_limit is not None:
            self.supply.set_current_limit(self.power.current_limit)
        self.events.append(("off", time.monotonic()))
        power_off(self.supply, self.power.off_s)

    def switch_on(self) -> None:
        assert self.supply is not None
        self.events.append(("on", time.monotonic()))
        self.on_reading = power_on(self.supply, self.power.settle_s)
        self.events.append(("up", time.monotonic()))
        self.monitor = PsuMonitor(self.supply, self.power.max_current)
        self.monitor.start()

    def sample(self, sim_s: float) -> str | None:
        """Records the latest reading at this sim time; the problem that must end the run, if any."""
        if self.monitor is None:
            return None
        last = self.monitor.latest()
        if last is not None:
            self.rows.append((sim_s, last[1], last[2]))
        return self.monitor.problem

    def close(self) -> None:
        if self.monitor is not None:
            self.monitor.stop()
        if self.supply is not None:
            self.supply.close()

    def signals(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """psu_volts and psu_amps on the run's grid, each held from the last reading at or before."""
        if not self.rows:
            return {"psu_volts": np.full(len(t), np.nan), "psu_amps": np.full(len(t), np.nan)}
        a = np.array(self.rows)
        k = np.searchsorted(a[:, 0], t, side="right") - 1
        out = {}
        for col, name in ((1, "psu_volts"), (2, "psu_amps")):
            v = a[np.clip(k, 0, None), col]
            out[name] = np.where(k >= 0, v, np.nan)
        return out

    def figures(self) -> dict[str, object]:
        """For result.json's metadata."""
        samples = self.monitor.samples if self.monitor else []
        span = samples[-1][0] - samples[0][0] if len(samples) > 1 else 0.0
        return {
            "psu": self.power.psu,
            "supply": self.supply.identity() if self.supply else None,
            "off_s": self.power.off_s,
            "on": self.on_reading.line() if self.on_reading else None,
            "max_current": self.power.max_current,
            "samples": len(samples),
            "rate_hz": (len(samples) - 1) / span if span > 0 else None,
            "peak_amps": max((s[2] for s in samples), default=None),
            "sequence": [name for name, _ in self.events],
        }
