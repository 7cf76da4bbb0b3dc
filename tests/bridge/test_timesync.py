"""The host's map of the bridge's clock against clocks whose truth is known: a bridge clock with a set
offset and drift, and a link whose delays each way are drawn (asymmetric, heavy-tailed) or set."""

from __future__ import annotations

import random

import pytest

from rig.bridge.timesync import ClockMap, Exchange

OFFSET_US = 123_456_789.0  # the bridge booted long before the host started counting
DRIFT = 47e-6  # its crystal runs 47 ppm fast


def bridge_us(host_ns: float) -> float:
    return OFFSET_US + (1 + DRIFT) * host_ns / 1000


def exchange(t1_ns: int, up_ns: int, down_ns: int, turnaround_us: int = 20) -> Exchange:
    """The probe leaves at t1, takes ``up_ns`` to the bridge, the reply ``down_ns`` back."""
    rx = int(bridge_us(t1_ns + up_ns))
    tx = rx + turnaround_us
    host_at_tx = t1_ns + up_ns + turnaround_us * 1000 / (1 + DRIFT)
    return Exchange(t1_ns, rx, tx, round(host_at_tx + down_ns))


def test_symmetric_link_gives_the_clock_exactly() -> None:
    m = ClockMap()
    for i in range(20):
        assert m.add(exchange(1_000_000_000 + i * 100_000_000, 150_000, 150_000))
    assert m.drift_ppm == pytest.approx(DRIFT * 1e6, abs=1.0)  # µs steps over the fit's ~2 s
    for host in (1_000_000_000, 2_500_000_000, 2_900_000_000):
        assert m.to_bridge_us(host) == pytest.approx(bridge_us(host), abs=2.0)  # the µs truncation of rx
    assert m.figures()["rtt_p50_us"] == pytest.approx(300, abs=2)


@pytest.mark.parametrize("seed", range(5))
def test_jittery_asymmetric_link_stays_within_its_bound(seed: int) -> None:
    """Each exchange's midpoint is wrong by at most half its round trip; a least-squares line through
    points within ±E of the truth stays within ±2E over their span. E is half the largest round trip
    the fit believed (the fastest half of the window)."""
    rnd = random.Random(seed)
    m = ClockMap(window=64)
    t = 5_000_000_000
    for _ in range(64):
        up = 80_000 + int(rnd.expovariate(1 / 60_000))
        down = 80_000 + int(rnd.expovariate(1 / 200_000))  # the host's side is slower and noisier
        assert m.add(exchange(t, up, down))
        t += 100_000_000
    believed = sorted(m.rtts_ns())[:32]
    bound_us = 2 * (believed[-1] / 2) / 1000 + 2
    for host in range(5_000_000_000, t, 50_000_000):
        assert abs(m.to_bridge_us(host) - bridge_us(host)) <= bound_us
    assert abs(m.drift_ppm - DRIFT * 1e6) < 2 * bound_us / 6.4  # µs over the window's 6.4 s: ppm


def test_a_descheduled_host_moves_nothing() -> None:
    m = ClockMap()
    t = 0
    for _ in range(16):
        m.add(exchange(t, 100_000, 100_000))
        t += 100_000_000
    before = (m.offset_us, m.drift, m.ref_ns)
    m.add(exchange(t, 100_000, 40_000_000))  # the reply sat 40 ms in a queue
    assert m.to_bridge_us(t) == pytest.approx(
        before[0] + (1 + before[1]) * (t - before[2]) / 1000, abs=1.0)


def test_impossible_exchanges_are_refused_and_counted() -> None:
    m = ClockMap()
    assert not m.add(Exchange(t1_ns=1000, rx_us=5, tx_us=6, t4_ns=500))  # reply before probe
    assert not m.add(Exchange(t1_ns=0, rx_us=10, tx_us=5, t4_ns=100_000))  # sent before received
    assert not m.add(Exchange(t1_ns=0, rx_us=0, tx_us=1000, t4_ns=10_000))  # turnaround > the wait
    assert (m.rejected, m.exchanges, m.ready) == (3, 0, False)


def test_the_two_directions_invert() -> None:
    m = ClockMap()
    m.add(exchange(0, 100_000, 100_000))
    assert m.drift == 0.0  # one exchange: no drift yet
    for i in range(1, 10):
        m.add(exchange(i * 100_000_000, 100_000, 130_000))
    for host in (0, 123_456_789, 10**12):
        assert m.to_host_ns(m.to_bridge_us(host)) == pytest.approx(host, abs=1e-3)


def test_a_window_of_one_is_refused() -> None:
    with pytest.raises(ValueError, match="at least 2"):
        ClockMap(window=1)
