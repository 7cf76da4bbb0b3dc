"""Whose lateness an event's was (rig/pace/late.py): the window from its due time to its start, split
over the loop's last wait (past its deadline: the host woke it late) and the work around it (the
thread's CPU: the loop's own; time it did not run: a call of its own that slept, when it switched
voluntarily, else preemption). The marks are made by hand here, so each share is known exactly; the
paced runs' own causes are checked in tests/rig/test_pace.py and tests/scenarios/test_realtime.py."""

from __future__ import annotations

import pytest

from rig.pace.late import CAUSES, LateCauses, Mark, mark

MS = 1_000_000


def loop(*, woke_ms: float, work_ms: float, cpu_ms: float, switched: bool = False) -> tuple[LateCauses, Mark]:
    """A loop that entered a wait at 0 ms for a deadline at 10 ms, returned ``woke_ms`` after it, then
    worked ``work_ms`` (``cpu_ms`` of it on the CPU) before the due event: the judge and the event's mark."""
    causes = LateCauses()
    causes.returned(Mark(-5 * MS, 0, 7))  # (the wait before: returned at -5 ms)
    causes.entering(10 * MS, Mark(0, 5 * MS, 7))
    returned = Mark(round((10 + woke_ms) * MS), 5 * MS, 8)  # (the wait itself is a voluntary switch)
    causes.returned(returned)
    now = Mark(returned.wall_ns + round(work_ms * MS), returned.cpu_ns + round(cpu_ms * MS),
               returned.voluntary + switched)
    return causes, now


@pytest.mark.parametrize(("woke_ms", "work_ms", "cpu_ms", "switched", "cause"), [
    (2.0, 0.1, 0.1, False, "host_woke_late"),   # the wait returned 2 ms past its deadline
    (0.0, 2.0, 1.9, False, "loop_busy"),        # on time, then 2 ms of the loop's own computing
    (0.0, 2.0, 0.1, True, "loop_blocked"),      # on time, then asleep in a call of its own
    (0.0, 2.0, 0.1, False, "host_preempted"),   # on time, then not run, and not by its own choice
])
def test_each_cause_is_the_largest_share_of_the_window(woke_ms: float, work_ms: float, cpu_ms: float,
                                                        switched: bool, cause: str) -> None:
    causes, now = loop(woke_ms=woke_ms, work_ms=work_ms, cpu_ms=cpu_ms, switched=switched)
    lateness = now.wall_ns - 10 * MS  # due at the deadline the wait was for
    assert causes.late(lateness, now) == cause
    assert causes.counts == {c: int(c == cause) for c in CAUSES}


def test_the_window_counts_only_what_it_overlaps() -> None:
    # woke 0.5 ms late, then 1.5 ms of work on the CPU: busy has the larger share (1.5 of 2 ms)
    causes, now = loop(woke_ms=0.5, work_ms=1.5, cpu_ms=1.5)
    assert causes.late(2 * MS, now) == "loop_busy"
    # an event due 1.2 ms before now (later than that wait's deadline): only the work is in its window
    causes, now = loop(woke_ms=3.0, work_ms=1.5, cpu_ms=1.5)
    assert causes.late(round(1.2 * MS), now) == "loop_busy"
    # an event due before the wait began: the work before the wait is in its window too
    causes2 = LateCauses()
    causes2.returned(Mark(-5 * MS, 0, 7))
    causes2.entering(-1 * MS, Mark(0, 5 * MS, 7))  # 5 ms of work, all on the CPU, entered 1 ms late
    causes2.returned(Mark(0, 5 * MS, 7))           # (a deadline past: back at once)
    assert causes2.late(4 * MS, Mark(100_000, 5 * MS, 7)) == "loop_busy"


def test_nothing_known_is_unattributed_and_a_real_mark_is_the_threads() -> None:
    causes = LateCauses()
    assert causes.late(2 * MS, Mark(10 * MS, 0, 0)) == "unattributed"
    a = mark()
    x = 0
    for k in range(200_000):  # some CPU time of this thread
        x += k
    b = mark()
    assert b.wall_ns >= a.wall_ns and b.cpu_ns >= a.cpu_ns and b.voluntary >= a.voluntary and x > 0


def test_the_events_queued_behind_a_late_one_share_its_cause() -> None:
    # the wait for 10 ms returned at 20 ms (a host's stall); events due at 10, 19.5 and 20.5 ms follow
    causes = LateCauses()
    causes.returned(Mark(-5 * MS, 0, 7))
    causes.entering(10 * MS, Mark(0, 5 * MS, 7))
    causes.returned(Mark(20 * MS, 5 * MS, 8))
    assert causes.late(10 * MS, Mark(20 * MS, 5 * MS, 8)) == "host_woke_late"
    # due at 19.5 ms, run at 21.5 ms after 1.5 ms of catch-up on the CPU: the queue behind the stall
    assert causes.late(2 * MS, Mark(round(21.5 * MS), round(6.5 * MS), 8)) == "host_woke_late"
    # due at 20.5 ms, after the loop woke: its own lateness, judged on its own (the CPU's, here)
    assert causes.late(round(1.2 * MS), Mark(round(21.7 * MS), round(6.7 * MS), 8)) == "loop_busy"
    assert causes.counts == {**dict.fromkeys(CAUSES, 0), "host_woke_late": 2, "loop_busy": 1}
    # a new wake starts a new queue
    causes.entering(22 * MS, Mark(22 * MS, 7 * MS, 8))
    causes.returned(Mark(22 * MS, 7 * MS, 9))
    assert causes.late(round(1.5 * MS), Mark(round(23.5 * MS), round(8.5 * MS), 9)) == "loop_busy"
