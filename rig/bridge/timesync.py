"""The host's estimate of the bridge's clock (docs/design.md §8 "Time").

Why: the host stamps every sample with the bridge time at which it becomes valid, and reads the
bridge's pulse capture times back, so it needs a map between its own monotonic clock and the bridge's
free-running microsecond clock that holds to a few microseconds over a run. The two clocks run at
slightly different rates (crystals differ by tens of ppm: 50 ppm is 3 ms a minute), so an offset alone
drifts out of true within seconds; the map is a line, offset and drift.

How: a two-way exchange (as NTP and PTP do). The host sends TIME_SYNC at host time t1; the bridge notes
its clock when the probe arrives (rx) and when the reply leaves (tx); the host receives the reply at
t4. The bridge instant (rx + tx) / 2 is taken to be the host instant (t1 + t4) / 2, wrong by at most
half the round trip's asymmetry, so only the exchanges with the smallest round trips are believed:
the line is fitted by least squares through the fastest half of the recent window. A probe whose round
trip exceeds the window's by far (a host that was descheduled) moves nothing.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass

NS_PER_US = 1000


@dataclass(frozen=True)
class Exchange:
    """One probe and its reply: host times in ns, bridge times in µs."""

    t1_ns: int
    rx_us: int
    tx_us: int
    t4_ns: int

    @property
    def rtt_ns(self) -> int:
        """The round trip on the wire: the host's wait less the bridge's own turnaround."""
        return (self.t4_ns - self.t1_ns) - (self.tx_us - self.rx_us) * NS_PER_US

    @property
    def host_mid_ns(self) -> float:
        return (self.t1_ns + self.t4_ns) / 2

    @property
    def bridge_mid_us(self) -> float:
        return (self.rx_us + self.tx_us) / 2


class ClockMap:
    """bridge_us ≈ offset_us + (1 + drift) · (host_ns − ref_ns) / 1000, refitted at every exchange.

    ``window`` exchanges are kept (at 10 Hz, 6.4 s: long enough to see a drift of a few ppm, short
    enough to follow a crystal warming up). Until two exchanges came, the drift is taken as zero.
    """

    def __init__(self, window: int = 64) -> None:
        if window < 2:
            raise ValueError("a clock map needs a window of at least 2 exchanges")
        self._window: deque[Exchange] = deque(maxlen=window)
        self.ref_ns = 0
        self.offset_us = 0.0
        self.drift = 0.0  # bridge seconds per host second, less one
        self.exchanges = 0
        self.rejected = 0

    @property
    def ready(self) -> bool:
        return self.exchanges > 0

    @property
    def drift_ppm(self) -> float:
        return self.drift * 1e6

    def rtts_ns(self) -> list[int]:
        return [e.rtt_ns for e in self._window]

    def add(self, e: Exchange) -> bool:
        """Takes one exchange; False (and counted) when it cannot be true: a reply before its probe, a
        bridge that answered before it received, or a round trip shorter than the bridge's turnaround."""
        if e.t4_ns < e.t1_ns or e.tx_us < e.rx_us or e.rtt_ns < 0:
            self.rejected += 1
            return False
        self._window.append(e)
        self.exchanges += 1
        self._fit()
        return True

    def _fit(self) -> None:
        fastest = sorted(self._window, key=lambda e: e.rtt_ns)[: max(2, (len(self._window) + 1) // 2)]
        if len(fastest) < 2:  # one exchange: an offset, no drift yet
            e = fastest[0]
            self.ref_ns, self.drift = round(e.host_mid_ns), 0.0
            self.offset_us = e.bridge_mid_us - (e.host_mid_ns - self.ref_ns) / NS_PER_US
            return
        ref = round(statistics.fmean(e.host_mid_ns for e in fastest))
        xs = [(e.host_mid_ns - ref) / NS_PER_US for e in fastest]  # host µs from the reference
        ys = [e.bridge_mid_us for e in fastest]
        mx, my = statistics.fmean(xs), statistics.fmean(ys)
        sxx = sum((x - mx) ** 2 for x in xs)
        slope = 1.0 if sxx == 0 else sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sxx
        self.ref_ns, self.drift = ref, slope - 1.0
        self.offset_us = my - slope * mx

    def to_bridge_us(self, host_ns: int) -> float:
        """The bridge's clock at this host instant."""
        return self.offset_us + (1.0 + self.drift) * (host_ns - self.ref_ns) / NS_PER_US

    def to_host_ns(self, bridge_us: float) -> float:
        """The host instant at which the bridge's clock reads ``bridge_us``."""
        return self.ref_ns + (bridge_us - self.offset_us) * NS_PER_US / (1.0 + self.drift)

    def figures(self) -> dict[str, float | int]:
        """For result.json: where the map stands and how good its exchanges were."""
        rtts = sorted(self.rtts_ns())
        return {
            "exchanges": self.exchanges,
            "rejected": self.rejected,
            "offset_us": self.offset_us,
            "drift_ppm": self.drift_ppm,
            "rtt_p50_us": rtts[len(rtts) // 2] / NS_PER_US if rtts else 0.0,
            "rtt_max_us": rtts[-1] / NS_PER_US if rtts else 0.0,
        }
