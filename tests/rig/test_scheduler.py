"""Sim time without a DUT (rig/scheduler.py): the order of events, the world moved with them, the run's
limits, an event that fails, the verdict, and the clock page. Before the session was split it could be
tested only by spawning a program."""

from __future__ import annotations

import math
import os
import random
import signal
from collections.abc import Callable
from pathlib import Path

import pytest

from rig import interrupts
from rig import protocol as P
from rig.scheduler import EXIT_RIG_ERROR, EXIT_WATCHDOG, NS, Scheduler, SharedPage, Stop, round_half_even
from rig.world import World


class Host:
    """What events are called with (the session, in a run)."""

    def __init__(self) -> None:
        self.seen: list[tuple[str, int]] = []


@pytest.fixture
def world():
    w = World.at_rest(noise=False)
    yield w
    w.close()


def test_events_run_in_time_order_and_the_world_reaches_each(world: World) -> None:
    host = Host()
    sched = Scheduler(world, host, duration=10.0, sim_timeout=600.0)
    def note(name: str) -> Callable[[Host], None]:
        return lambda h: h.seen.append((name, world.time_ns))

    for name, t in (("c", 0.003), ("a", 0.001), ("b", 0.001), ("d", 0.0055)):
        sched.at(t, note(name))
    assert sched.advance(5_000_000) == 5_000_000
    # ties in order of scheduling; the world's 1 ms grid at or before the event's time
    assert host.seen == [("a", 1_000_000), ("b", 1_000_000), ("c", 3_000_000)]
    assert world.time_ns == 5_000_000 and sched.next_event_ns() == 5_500_000


def test_a_wait_for_output_wakes_at_the_event_that_wrote(world: World) -> None:
    sched = Scheduler(world, Host(), duration=10.0, sim_timeout=600.0)

    def writes(host: Host) -> None:
        sched.event_output = True  # (the session's serial_write says so)

    sched.at(0.002, lambda h: None)
    sched.at(0.004, writes)
    assert sched.advance(9_000_000, stop_on_output=True) == 4_000_000
    assert world.time_ns == 4_000_000


def test_the_duration_ends_the_run_well_and_the_timeout_as_a_watchdog(world: World) -> None:
    sched = Scheduler(world, Host(), duration=0.5, sim_timeout=600.0)
    with pytest.raises(Stop):
        sched.advance(700_000_000)
    assert sched.ended_by_duration and sched.over and sched.error is None
    assert sched.over_byte == b"\x01"  # (what the lockstep fast path reads)
    assert world.time_ns == 500_000_000  # the world stops at the end, not at the request
    assert sched.verdict(-15, 0.5, True, False, False) == ("ok", 0, None)  # stopped by the rig: fine

    w2 = World.at_rest(noise=False)
    try:
        timed = Scheduler(w2, Host(), duration=None, sim_timeout=0.2)
        with pytest.raises(Stop):
            timed.advance(300_000_000)
        assert timed.error is not None and timed.error[0] == EXIT_WATCHDOG
        assert "sim-time watchdog" in timed.error[1]
        assert timed.over and timed.over_byte == b"\x01"
    finally:
        w2.close()


def test_a_signal_during_an_event_interrupts_the_run_and_is_not_the_events_failure(world: World) -> None:
    """SIGTERM while an event runs (inside the session's loop, where a signal raises at once): the run
    is interrupted, as a signal between events interrupts it, not voided as an event that failed."""
    sched = Scheduler(world, Host(), duration=10.0, sim_timeout=600.0)
    sched.at(0.25, lambda host: os.kill(os.getpid(), signal.SIGTERM))
    with interrupts.handled(), interrupts.live(), pytest.raises(interrupts.Interrupted) as got:
        sched.advance(1 * NS)
    assert got.value.signum == signal.SIGTERM
    assert sched.error is None and sched.event_ns is None


def test_an_event_that_raises_voids_the_run_without_taking_the_rig_down(world: World) -> None:
    sched = Scheduler(world, Host(), duration=10.0, sim_timeout=600.0)

    def broken(host: Host) -> None:
        raise ZeroDivisionError("division by zero")

    sched.at(0.25, broken)
    assert not sched.over and sched.over_byte == b"\x00"
    with pytest.raises(Stop):
        sched.advance(1 * NS)
    assert sched.error == (EXIT_RIG_ERROR,
                           "event at 0.250000000 failed: ZeroDivisionError: division by zero")
    assert sched.over and sched.over_byte == b"\x01"
    assert sched.event_ns is None  # the session's "now" is the clock again


@pytest.mark.parametrize(("returncode", "reached", "duration", "expected"), [
    (0, True, None, ("ok", 0, None)),
    (3, True, None, ("failed", 3, None)),
    (-signal.SIGSEGV, True, None,
     ("error", 128 + signal.SIGSEGV, "the command was killed by SIGSEGV at sim t=1.500 s")),
    (0, True, 10.0,
     ("error", EXIT_RIG_ERROR, "the command exited early, with status 0, at sim t=1.500 s of a 10 s run")),
    (2, False, None,
     ("error", EXIT_RIG_ERROR, "the command exited with status 2 before touching the emulated devices")),
])
def test_the_verdict(world: World, returncode: int, reached: bool, duration: float | None,
                     expected: tuple[str, int, str | None]) -> None:
    sched = Scheduler(world, Host(), duration=duration, sim_timeout=600.0)
    assert sched.verdict(returncode, 1.5, reached, False, False) == expected


def test_the_clock_page_moves_forward_only_and_carries_the_end(tmp_path: Path) -> None:
    page = SharedPage(tmp_path / "shm", 8, 0, 1000, 7 * NS)
    page.set(5_000)
    page.set(4_000)  # the DUT may have read the clock on already: never back
    assert page.now() == 5_000
    raw = (tmp_path / "shm").read_bytes()
    assert int.from_bytes(raw[P.SHM_LIMIT_OFFSET:P.SHM_LIMIT_OFFSET + 8], "little") == 7 * NS


def test_the_lateness_figures_count_the_late_and_give_median_p99_and_worst(world: World) -> None:
    """Real time: each event's lateness is the wall clock at its start minus its due time (a fake wall
    clock here, which says 0.2 ms late for the first event, 2 ms for the last)."""
    walls = iter([200_000 + 1_000_000 * k for k in range(9)] + [11_000_000])
    sched = Scheduler(world, Host(), duration=10.0, sim_timeout=600.0, wall_now=lambda: next(walls))
    for k in range(10):
        sched.at(0.001 * k, lambda h: None)
    sched.advance(9_000_000)
    events, late, worst, p99, p50 = sched.lateness()
    assert sched.lateness_ns == [200_000] * 9 + [2_000_000]
    assert (events, late, worst, p99, p50) == (10, 1, 0.002, 0.0002, 0.0002)


def test_an_events_time_rounds_as_the_builtin_round_does():
    """round_half_even (the scheduler's own, cheaper round) against Python's round: halves, the floats
    next to them, negatives, event times, integers past 2**53 and past 2**63."""
    rng = random.Random(7)
    values = [0.0, -0.0, 0.5, 1.5, 2.5, -0.5, -1.5, -2.5, 0.49999999999999994, 2.0**52 + 1, 2.0**53, 2.0**64,
              -2.0**70, 1e300, 5e-324]
    for _ in range(20000):
        half = rng.randint(-10**9, 10**9) + 0.5
        values += [half, math.nextafter(half, math.inf), math.nextafter(half, -math.inf)]
        event_times = rng.randint(0, 10**6) * 0.001 * NS, rng.randint(0, 10**5) * 0.014 * NS  # (ms, SBUS)
        values += [rng.uniform(-1e12, 1e12), *event_times]
    assert [round_half_even(x) for x in values] == [round(x) for x in values]
    for bad, error in ((math.nan, ValueError), (math.inf, OverflowError), (-math.inf, OverflowError)):
        with pytest.raises(error):
            round(bad)
        with pytest.raises(error):
            round_half_even(bad)
